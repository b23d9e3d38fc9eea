//! The studio's HTTP routes: the page, and the API of each part in its own file — missions,
//! requirements, validation and catalogues (`missions.rs`), verification (`verify.rs`), the
//! token games (`games.rs`), the followed missions (`ops.rs`), the ground desk (`ground.rs`),
//! record replay (`replay.rs`), timer previews (`timer.rs`). Every refusal this code makes is JSON `{"error": "..."}` with a
//! status that says whose fault it is (axum's own rejections of a malformed path are plain
//! text).

use std::sync::Arc;

use axum::Router;
use axum::extract::{DefaultBodyLimit, Extension, Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Json, Response};
use axum::routing::{get, post};
use executive_model::Options;
use serde_json::json;

use crate::files::FileError;
use crate::{Studio, assets};

mod games;
mod ground;
mod missions;
mod ops;
mod replay;
mod timer;
mod verify;

/// The routes of `studio`.
pub fn router(studio: Studio) -> Router {
    // A model is read only up to the loader's own limit; a larger body is refused by axum.
    let limit = Options::default().limits.max_bytes + 1;
    Router::new()
        .route(
            "/",
            get(|headers: HeaderMap| async move { page("index.html", &headers) }),
        )
        // Browsers ask for it unprompted; there is none.
        .route("/favicon.ico", get(|| async { StatusCode::NO_CONTENT }))
        .route("/api/missions", get(missions::list))
        .route(
            "/api/missions/{name}",
            get(missions::read).put(missions::write),
        )
        .route("/api/validate", post(missions::validate_text))
        .route("/api/validate/{name}", post(missions::validate_named))
        .route("/api/catalogues", get(missions::catalogues))
        .route(
            "/api/requirements/{name}",
            get(missions::read_requirements).put(missions::write_requirements),
        )
        .route("/api/verify/{name}", post(verify::verify))
        .route("/api/ops/executives", get(ops::executives))
        .route("/api/ops/{mission}/model", get(ops::model))
        .route("/api/ops/{mission}/state", get(ops::state))
        .route("/api/ops/{mission}/events", get(ops::events))
        .route("/api/ops/{mission}/timeline", get(ops::timeline))
        .route("/api/ground", get(ground::desk))
        .route("/api/ground/{number}", post(ground::answer))
        .route("/api/replay", post(replay::replay))
        .route("/api/timer", post(timer::preview))
        .route("/api/simulate", post(games::start))
        .route("/api/simulate/{id}", post(games::act).delete(games::end))
        .route(
            "/{file}",
            get(
                |Path(file): Path<String>, headers: HeaderMap| async move { page(&file, &headers) },
            ),
        )
        .layer(DefaultBodyLimit::max(limit))
        .layer(Extension(Arc::new(games::Games::default())))
        .with_state(Arc::new(studio))
}

pub(super) type Shared = State<Arc<Studio>>;

pub(super) fn refuse(status: StatusCode, why: impl std::fmt::Display) -> Response {
    tracing::warn!(status = status.as_u16(), "refused: {why}");
    (status, Json(json!({ "error": why.to_string() }))).into_response()
}

pub(super) fn file_error(e: FileError) -> Response {
    let status = match e {
        FileError::BadName(_) => StatusCode::BAD_REQUEST,
        FileError::Missing(_) => StatusCode::NOT_FOUND,
        FileError::Io { .. } => StatusCode::INTERNAL_SERVER_ERROR,
    };
    refuse(status, e)
}

/// A file of the page: gzipped when the browser takes gzip, and revalidated by its entity tag
/// (the files keep their names from build to build, so a browser asks each time and gets
/// `304 Not Modified` while the page is the same).
fn page(file: &str, headers: &HeaderMap) -> Response {
    let Some(a) = assets::get(file) else {
        return refuse(StatusCode::NOT_FOUND, format!("no page file `{file}`"));
    };
    let matches = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == a.tag || t.trim() == "*"));
    let cache = [
        (header::ETAG, a.tag),
        (header::CACHE_CONTROL, "no-cache"),
        (header::VARY, "Accept-Encoding"),
    ];
    if matches {
        return (StatusCode::NOT_MODIFIED, cache).into_response();
    }
    let gzip = headers
        .get(header::ACCEPT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| {
            v.split(',')
                .any(|e| e.split(';').next().is_some_and(|e| e.trim() == "gzip"))
        });
    if gzip {
        (
            cache,
            [
                (header::CONTENT_TYPE, a.kind),
                (header::CONTENT_ENCODING, "gzip"),
            ],
            a.gzipped,
        )
            .into_response()
    } else {
        (cache, [(header::CONTENT_TYPE, a.kind)], a.bytes).into_response()
    }
}
