//! TRACE Studio: the mission composer, served on loopback by `trace studio [DIR]`.
//!
//! A planner opens, draws, checks, verifies, plays and saves the BPMN mission files of one
//! directory in the browser: bpmn-js's modeler and properties panel, a TRACE panel that writes
//! the `trace:task` binding from the systems' catalogues (live over Zenoh, or from files), every
//! diagnostic of `trace validate` and of `trace run`'s catalogue check on the element it
//! concerns, `trace verify` with counterexamples replayed on the diagram, and the token game on
//! the engine. Ground operators follow running missions on their diagram and answer their
//! decisions (the operations view).
//!
//! - [`files`]: the mission directory — names are plain `*.bpmn` file names, never paths, and
//!   a save is atomic (a temporary file renamed over the old one).
//! - [`api`]: the HTTP routes (axum on the executive's tokio) — the page, `GET/PUT
//!   /api/missions/{name}` and `/api/requirements/{name}`, `POST /api/validate`, `GET
//!   /api/catalogues`, `POST /api/validate/{name}`, `POST /api/verify/{name}`, `POST
//!   /api/simulate`, `POST|DELETE /api/simulate/{id}`, `POST /api/replay`, `GET /api/ops/...`
//!   (executives, model, state, events, timeline) and `/api/ground[/{number}]`.
//! - [`simulate`]: the token game on the engine.
//! - [`checks`]: what a check reports — `trace validate`'s diagnostics and, given the
//!   connectors, `trace run`'s check against the catalogues, through the executive's library.
//! - [`live`]: the catalogues the running systems serve, over Zenoh.
//! - [`ops`]: the running missions followed live (state, record, presence) for the
//!   operations view.
//! - [`templates`]: Camunda element templates from the same catalogues (`trace templates`).
//! - The page itself is built from pinned npm packages by `build.rs` (`web/`, see there) and
//!   embedded in the binary; nothing third-party is committed.
//!
//! axum is the HTTP server because it is the well-kept router on tokio (already the
//! executive's runtime), with only its `http1`, `tokio` and `json` features.

pub mod api;
mod assets;
pub mod checks;
pub mod files;
pub mod live;
pub mod ops;
pub mod simulate;
#[cfg(test)]
mod simulate_tests;
pub mod templates;

/// The npm packages the page is built from, as `build.rs` installed them: for tests that bundle
/// pages of their own from the same pinned packages (the differential test against
/// bpmn-js-token-simulation, `tests/simulator/`).
pub const NODE_MODULES: &str = env!("TRACE_STUDIO_NODE_MODULES");
#[cfg(test)]
mod templates_tests;
#[cfg(test)]
mod tests;
pub mod timers;

use std::net::SocketAddr;
use std::path::PathBuf;

use connector_api::{Catalogue, ConnectorsConfig};

/// What one studio serves.
#[derive(Clone, Debug)]
pub struct Studio {
    /// The directory of mission files.
    pub dir: PathBuf,
    /// The catalogues read from files, which the TRACE panel offers actions from.
    pub catalogues: Vec<Catalogue>,
    /// The connectors `trace run` would load (`deploy/connectors.toml`): with them, every check
    /// also runs `trace run`'s check of the tasks against the catalogues.
    pub connectors: Option<ConnectorsConfig>,
    /// The studio's place on the Zenoh network, when it joined one: the catalogues the
    /// running systems serve.
    pub live: Option<std::sync::Arc<live::Live>>,
    /// The ground station the page answers user tasks through, when the studio is one
    /// (`trace studio --station NAME`).
    pub ground: Option<std::sync::Arc<ground_station::station::Station>>,
}

/// Where a catalogue the studio offers came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// Served now by a running system.
    Live,
    /// Read from a file.
    File,
}

impl Studio {
    /// The catalogues known now, with where each came from: every live one, then the files
    /// of servers not heard live.
    pub fn sourced(&self) -> Vec<(Catalogue, Source)> {
        let mut out: Vec<(Catalogue, Source)> = self
            .live
            .iter()
            .flat_map(|l| l.heard())
            .map(|c| (c, Source::Live))
            .collect();
        for c in &self.catalogues {
            if !out.iter().any(|(k, _)| k.server == c.server) {
                out.push((c.clone(), Source::File));
            }
        }
        out
    }

    /// The catalogues known now (see [`Studio::sourced`]).
    pub fn catalogues(&self) -> Vec<Catalogue> {
        self.sourced().into_iter().map(|(c, _)| c).collect()
    }
}

/// Why the studio could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The mission directory is not one.
    #[error("{0}: not a directory of missions")]
    NoDirectory(PathBuf),
    /// The address is not on this machine's loopback and other interfaces were not allowed.
    #[error(
        "{0} is not a loopback address: the studio has no authentication (pass --public to serve {0} anyway)"
    )]
    NotLoopback(SocketAddr),
    /// The socket could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
}

/// A bound studio, ready to serve.
pub struct Bound {
    listener: tokio::net::TcpListener,
    studio: Studio,
}

impl Bound {
    /// Where it listens (the port chosen when 0 was asked for).
    pub fn addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Serves until the task is dropped or the listener fails.
    pub async fn serve(self) -> std::io::Result<()> {
        axum::serve(self.listener, api::router(self.studio)).await
    }
}

/// Binds `addr` for `studio`; an address that is not loopback is refused unless `public`.
pub async fn bind(studio: Studio, addr: SocketAddr, public: bool) -> Result<Bound, StartError> {
    if !studio.dir.is_dir() {
        return Err(StartError::NoDirectory(studio.dir));
    }
    if !public && !addr.ip().is_loopback() {
        return Err(StartError::NotLoopback(addr));
    }
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|source| StartError::Bind { addr, source })?;
    Ok(Bound { listener, studio })
}

pub use executive_runtime::catalogues::{CatalogueError, read as read_catalogues, read_connectors};

/// Whether the page was built from the npm packages (false: the fallback page saying how).
pub fn has_page() -> bool {
    assets::get("app.js").is_some()
}
