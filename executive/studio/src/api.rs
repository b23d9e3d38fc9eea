//! The studio's HTTP routes: the page, the mission files, validation and the catalogues.
//! Every refusal is JSON `{"error": "..."}` with a status that says whose fault it is.

use std::path::PathBuf;
use std::sync::Arc;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Json, Response};
use axum::routing::{get, post};
use executive_model::{Loaded, Options, Severity, load_bundle};
use serde_json::json;

use crate::files::{self, FileError};
use crate::{Studio, assets};

/// The routes of `studio`.
pub fn router(studio: Studio) -> Router {
    // A model is read only up to the loader's own limit; a larger body is refused by axum.
    let limit = Options::default().limits.max_bytes + 1;
    Router::new()
        .route("/", get(|| async { page("index.html") }))
        // Browsers ask for it unprompted; there is none.
        .route("/favicon.ico", get(|| async { StatusCode::NO_CONTENT }))
        .route("/api/missions", get(list))
        .route("/api/missions/{name}", get(read).put(write))
        .route("/api/validate", post(validate_text))
        .route("/api/validate/{name}", post(validate_named))
        .route("/api/catalogues", get(catalogues))
        .route(
            "/{file}",
            get(|Path(file): Path<String>| async move { page(&file) }),
        )
        .layer(DefaultBodyLimit::max(limit))
        .with_state(Arc::new(studio))
}

type Shared = State<Arc<Studio>>;

fn refuse(status: StatusCode, why: impl std::fmt::Display) -> Response {
    tracing::warn!(status = status.as_u16(), "refused: {why}");
    (status, Json(json!({ "error": why.to_string() }))).into_response()
}

fn file_error(e: FileError) -> Response {
    let status = match e {
        FileError::BadName(_) => StatusCode::BAD_REQUEST,
        FileError::Missing(_) => StatusCode::NOT_FOUND,
        FileError::Io { .. } => StatusCode::INTERNAL_SERVER_ERROR,
    };
    refuse(status, e)
}

fn page(file: &str) -> Response {
    match assets::get(file) {
        Some((bytes, kind)) => ([(header::CONTENT_TYPE, kind)], bytes).into_response(),
        None => refuse(StatusCode::NOT_FOUND, format!("no page file `{file}`")),
    }
}

async fn list(State(s): Shared) -> Response {
    match files::list(&s.dir).await {
        Ok(entries) => Json(entries).into_response(),
        Err(e) => file_error(e),
    }
}

async fn read(State(s): Shared, Path(name): Path<String>) -> Response {
    match files::read(&s.dir, &name).await {
        Ok(bytes) => ([(header::CONTENT_TYPE, "application/xml")], bytes).into_response(),
        Err(e) => file_error(e),
    }
}

/// Saves a mission. A model with errors is saved (a drawing in progress), one that is not BPMN
/// at all is refused and the file left as it was.
async fn write(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
    if let Err(e) = files::path(&s.dir, &name) {
        return file_error(e);
    }
    let (verdict, diagnostics) = check(&s, body.clone()).await;
    if verdict == "unreadable" {
        return (
            StatusCode::UNPROCESSABLE_ENTITY,
            Json(json!({
                "error": format!("{name} was not saved: it is not a BPMN model"),
                "diagnostics": diagnostics,
            })),
        )
            .into_response();
    }
    match files::write(&s.dir, &name, &body).await {
        Ok(()) => Json(json!({ "saved": name, "verdict": verdict })).into_response(),
        Err(e) => file_error(e),
    }
}

async fn validate_text(State(s): Shared, body: Bytes) -> Response {
    let (verdict, diagnostics) = check(&s, body).await;
    Json(json!({ "verdict": verdict, "diagnostics": diagnostics })).into_response()
}

/// As `/api/validate`, for the model of file `name` (which need not exist yet).
async fn validate_named(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
    if let Err(e) = files::path(&s.dir, &name) {
        return file_error(e);
    }
    validate_text(State(s), body).await
}

async fn catalogues(State(s): Shared) -> Response {
    Json(&s.catalogues).into_response()
}

/// `trace validate` on `bytes` — the same verdict and diagnostics — with imports read from
/// the mission directory (plain file names only).
async fn check(studio: &Studio, bytes: Bytes) -> (&'static str, serde_json::Value) {
    let dir = studio.dir.clone();
    let loaded = tokio::task::spawn_blocking(move || load(&dir, &bytes)).await;
    let Ok(loaded) = loaded else {
        return ("unreadable", json!([]));
    };
    let verdict = if loaded.unreadable() {
        "unreadable"
    } else if loaded.graph.is_some()
        && !loaded
            .diagnostics
            .iter()
            .any(|d| d.severity == Severity::Error)
    {
        "valid"
    } else {
        "invalid"
    };
    (verdict, json!(loaded.diagnostics))
}

fn load(dir: &std::path::Path, bytes: &[u8]) -> Loaded {
    let options = Options::default();
    let max = options.limits.max_bytes;
    let mut resolve = |location: &str| -> Result<Vec<u8>, String> {
        // Imports may be any file of the directory (not only missions), nothing outside it.
        if location.contains(['/', '\\']) || location.starts_with('.') {
            return Err(format!(
                "`{location}`: the studio reads imports from the mission directory only"
            ));
        }
        let p: PathBuf = dir.join(location);
        let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        if bytes.len() > max {
            return Err(format!(
                "{} is {} bytes; the limit is {max}",
                p.display(),
                bytes.len()
            ));
        }
        Ok(bytes)
    };
    load_bundle(bytes, &options, &mut resolve)
}
