//! The mission files, their requirements, validation and the catalogues.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Json, Response};
use serde_json::json;

use super::{Shared, file_error, refuse};
use crate::files::{self, FileError};
use crate::{Studio, checks};

pub(super) async fn list(State(s): Shared) -> Response {
    match files::list(&s.dir).await {
        Ok(entries) => Json(entries).into_response(),
        Err(e) => file_error(e),
    }
}

pub(super) async fn read(State(s): Shared, Path(name): Path<String>) -> Response {
    match files::read(&s.dir, &name).await {
        Ok(bytes) => ([(header::CONTENT_TYPE, "application/xml")], bytes).into_response(),
        Err(e) => file_error(e),
    }
}

/// Saves a mission. A model with errors is saved (a drawing in progress), one that is not BPMN
/// at all is refused and the file left as it was.
pub(super) async fn write(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
    if let Err(e) = files::path(&s.dir, &name) {
        return file_error(e);
    }
    let report = match run_check(&s, body.clone()).await {
        Ok(r) => r,
        Err(e) => return e,
    };
    if report.verdict == "unreadable" {
        return (
            StatusCode::UNPROCESSABLE_ENTITY,
            Json(json!({
                "error": format!("{name} was not saved: it is not a BPMN model"),
                "diagnostics": report.diagnostics,
            })),
        )
            .into_response();
    }
    match files::write(&s.dir, &name, &body).await {
        Ok(()) => Json(json!({ "saved": name, "verdict": report.verdict })).into_response(),
        Err(e) => file_error(e),
    }
}

/// The checks of [`checks::check`] off the async threads (a large model takes a while).
pub(super) async fn run_check(
    studio: &Arc<Studio>,
    body: Bytes,
) -> Result<checks::Report, Response> {
    let studio = Arc::clone(studio);
    tokio::task::spawn_blocking(move || checks::check(&studio, &body))
        .await
        .map_err(|e| {
            refuse(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("the check failed: {e}"),
            )
        })
}

pub(super) async fn validate_text(State(s): Shared, body: Bytes) -> Response {
    match run_check(&s, body).await {
        Ok(report) => Json(report).into_response(),
        Err(e) => e,
    }
}

/// As `/api/validate`, for the model of file `name` (which need not exist yet).
pub(super) async fn validate_named(
    State(s): Shared,
    Path(name): Path<String>,
    body: Bytes,
) -> Response {
    if let Err(e) = files::path(&s.dir, &name) {
        return file_error(e);
    }
    validate_text(State(s), body).await
}

/// Every catalogue known, each with `"source": "live" | "file"`; the running systems are
/// asked again first.
pub(super) async fn catalogues(State(s): Shared) -> Response {
    if let Some(live) = &s.live {
        live.ask().await;
    }
    let list: Vec<serde_json::Value> = s
        .sourced()
        .into_iter()
        .map(|(c, source)| {
            let mut v = json!(c);
            v["source"] = json!(source);
            v
        })
        .collect();
    Json(list).into_response()
}

/// The requirements file of mission `name` (`<stem>.req.toml`), as text.
pub(super) async fn read_requirements(State(s): Shared, Path(name): Path<String>) -> Response {
    match files::read_requirements(&s.dir, &name).await {
        Ok(bytes) => ([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], bytes).into_response(),
        // A mission without requirements yet is normal: no warning.
        Err(FileError::Missing(_)) => (
            StatusCode::NOT_FOUND,
            Json(json!({ "error": format!("mission `{name}` has no requirements file yet") })),
        )
            .into_response(),
        Err(e) => file_error(e),
    }
}

/// Saves the requirements file of mission `name`; it must be text (it is checked when verified,
/// against the model of that moment).
pub(super) async fn write_requirements(
    State(s): Shared,
    Path(name): Path<String>,
    body: Bytes,
) -> Response {
    if std::str::from_utf8(&body).is_err() {
        return refuse(
            StatusCode::UNPROCESSABLE_ENTITY,
            "requirements must be UTF-8 text",
        );
    }
    match files::write_requirements(&s.dir, &name, &body).await {
        Ok(()) => Json(json!({ "saved": name })).into_response(),
        Err(e) => file_error(e),
    }
}
