//! The mission directory: listing, reading and atomically writing `*.bpmn` files by name, and
//! each mission's requirements file beside it (`<stem>.req.toml`).

use std::path::{Path, PathBuf};

/// Why a mission file operation was refused or failed.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The name is not a plain `*.bpmn` file name.
    #[error("`{0}` is not a mission file name: a name like `europa.bpmn`, no directories")]
    BadName(String),
    /// No such file.
    #[error("no mission `{0}`")]
    Missing(String),
    /// The file system refused.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// One mission file of the directory.
#[derive(Debug, serde::Serialize)]
pub struct Entry {
    /// Its file name.
    pub name: String,
    /// Its size in bytes.
    pub bytes: u64,
}

/// The path of mission `name` in `dir`, if `name` is a plain `*.bpmn` file name: no
/// separators, no `..`, not hidden, nothing outside `dir`.
pub fn path(dir: &Path, name: &str) -> Result<PathBuf, FileError> {
    let plain = !name.is_empty()
        && name.len() <= 200
        && name.ends_with(".bpmn")
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ' '))
        && !name.contains("..");
    if plain {
        Ok(dir.join(name))
    } else {
        Err(FileError::BadName(name.to_owned()))
    }
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> FileError + '_ {
    move |source| FileError::Io {
        path: path.to_owned(),
        source,
    }
}

/// The `*.bpmn` files of `dir`, by name.
pub async fn list(dir: &Path) -> Result<Vec<Entry>, FileError> {
    let mut out = Vec::new();
    let mut entries = tokio::fs::read_dir(dir).await.map_err(io(dir))?;
    while let Some(e) = entries.next_entry().await.map_err(io(dir))? {
        let name = e.file_name().to_string_lossy().into_owned();
        if path(dir, &name).is_err() {
            continue;
        }
        let meta = e.metadata().await.map_err(io(&e.path()))?;
        if meta.is_file() {
            out.push(Entry {
                name,
                bytes: meta.len(),
            });
        }
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(out)
}

/// The requirements file of mission `name`: `<stem>.req.toml` beside it, as `trace verify`
/// reads by default.
pub fn requirements(dir: &Path, name: &str) -> Result<PathBuf, FileError> {
    Ok(path(dir, name)?.with_extension("req.toml"))
}

/// The bytes of mission `name`.
pub async fn read(dir: &Path, name: &str) -> Result<Vec<u8>, FileError> {
    read_at(&path(dir, name)?, name).await
}

/// The bytes of mission `name`'s requirements file.
pub async fn read_requirements(dir: &Path, name: &str) -> Result<Vec<u8>, FileError> {
    read_at(&requirements(dir, name)?, name).await
}

async fn read_at(p: &Path, name: &str) -> Result<Vec<u8>, FileError> {
    match tokio::fs::read(p).await {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(FileError::Missing(name.to_owned()))
        }
        r => r.map_err(io(p)),
    }
}

/// Writes mission `name` atomically: a temporary file in `dir`, flushed, renamed over it.
pub async fn write(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), FileError> {
    write_at(&path(dir, name)?, bytes).await
}

/// Writes mission `name`'s requirements file atomically.
pub async fn write_requirements(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), FileError> {
    write_at(&requirements(dir, name)?, bytes).await
}

async fn write_at(p: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let file_name = p
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let tmp = p.with_file_name(format!(".{file_name}.saving"));
    let file = async {
        tokio::fs::write(&tmp, bytes).await?;
        tokio::fs::File::open(&tmp).await?.sync_all().await?;
        tokio::fs::rename(&tmp, p).await
    };
    if let Err(e) = file.await {
        let _ = tokio::fs::remove_file(&tmp).await;
        return Err(io(p)(e));
    }
    tracing::info!(file = %p.display(), bytes = bytes.len(), "saved");
    Ok(())
}
