//! Catalogues and connectors configurations read from files, for the tools that work without
//! the running systems (`trace verify`'s costs, the studio's TRACE panel, `trace templates`).

use std::path::PathBuf;

use connector_api::{Catalogue, ConnectorsConfig};

/// Why a catalogue or connectors file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CatalogueError {
    /// The file or directory could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a catalogue (`docs/protocol.md` §3).
    #[error("{path}: not a catalogue: {source}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why.
        source: serde_json::Error,
    },
    /// The catalogue's server id is not one plain name.
    #[error("{path}: the server id is not a plain name: {reason}")]
    Server {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The connectors configuration is not one (`deploy/connectors.toml`).
    #[error("{path}: not a connectors configuration: {reason}")]
    Connectors {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// The catalogues in `paths`: each a catalogue JSON file, or a directory whose `*.json` files
/// are catalogues.
pub fn read(paths: &[PathBuf]) -> Result<Vec<Catalogue>, CatalogueError> {
    let io = |path: &std::path::Path| {
        let path = path.to_owned();
        move |source| CatalogueError::Io { path, source }
    };
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut inner: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(io(p))?
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|f| f.extension().is_some_and(|x| x == "json"))
                .collect();
            inner.sort();
            files.extend(inner);
        } else {
            files.push(p.clone());
        }
    }
    files
        .iter()
        .map(|f| {
            let text = std::fs::read_to_string(f).map_err(io(f))?;
            let cat: Catalogue =
                serde_json::from_str(&text).map_err(|source| CatalogueError::Parse {
                    path: f.clone(),
                    source,
                })?;
            // The server id names keys and files (`trace templates`): one plain chunk.
            connector_api::keys::check_chunk(&cat.server).map_err(|e| CatalogueError::Server {
                path: f.clone(),
                reason: e.to_string(),
            })?;
            Ok(cat)
        })
        .collect()
}

/// Reads a connectors configuration (`deploy/connectors.toml`) as `trace run` does.
pub fn read_connectors(path: &std::path::Path) -> Result<ConnectorsConfig, CatalogueError> {
    let text = std::fs::read_to_string(path).map_err(|source| CatalogueError::Io {
        path: path.to_owned(),
        source,
    })?;
    let dir = path.parent().unwrap_or(std::path::Path::new(""));
    crate::connectors::parse_config(&text)
        .map(|c| c.beside(dir))
        .map_err(|reason| CatalogueError::Connectors {
            path: path.to_owned(),
            reason,
        })
}

/// The catalogues the connectors make themselves (ROS 2's, from the actions' definitions), for
/// the studio and `trace templates`; one that cannot be made is logged and left out.
pub fn generated(config: &ConnectorsConfig) -> Vec<Catalogue> {
    config
        .connectors
        .iter()
        .filter_map(ros2_catalogue)
        .collect()
}

/// A ROS 2 connector's catalogue, from its actions' definitions (`None` for other kinds, or,
/// logged, when the definitions cannot be read).
fn ros2_catalogue(c: &connector_api::ConnectorConfig) -> Option<Catalogue> {
    if c.kind != connector_api::Kind::Ros2 {
        return None;
    }
    connector_ros2::catalogue_of(c)
        .inspect_err(|e| {
            tracing::error!(connector = c.name, error = %e, "no catalogue from the ROS 2 definitions");
        })
        .ok()
}

/// Each configured connector's catalogue, by its server id (`None`: none known, or a scripted
/// connector, which serves anything).
pub fn served(config: &ConnectorsConfig, catalogues: &[Catalogue]) -> Vec<Option<Catalogue>> {
    config
        .connectors
        .iter()
        .map(|c| match c.kind {
            connector_api::Kind::Script => None,
            connector_api::Kind::Zenoh => {
                catalogues.iter().find(|k| k.server == c.server()).cloned()
            }
            // Generated from the actions' definitions, as the connector serves it.
            connector_api::Kind::Ros2 => ros2_catalogue(c),
        })
        .collect()
}
