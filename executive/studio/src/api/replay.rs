//! Replay of an execution record on the model the page holds (`executive_runtime::replay`): the
//! engine's state after every step, for the page to scrub through.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};
use executive_model::Options;
use serde_json::json;

use super::{Shared, refuse};
use crate::checks;

/// What the page sends: the model as it holds it, and the record's text.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplayBody {
    model: String,
    record: String,
}

/// Replays the record on the model: `{frames: [{seq, mission_ms, what, tokens, ended}]}`, or
/// 422 naming the first step that does not fit (a record of another model, a broken line).
pub(super) async fn replay(State(s): Shared, body: Bytes) -> Response {
    let body: ReplayBody = match serde_json::from_slice(&body) {
        Ok(b) => b,
        Err(e) => {
            return refuse(
                StatusCode::BAD_REQUEST,
                format!("not a replay request: {e}"),
            );
        }
    };
    let studio = Arc::clone(&s);
    let job = tokio::task::spawn_blocking(move || {
        let loaded = checks::load(&studio.dir, body.model.as_bytes(), &Options::default());
        let Some(graph) = loaded.graph else {
            let first = loaded
                .errors()
                .next()
                .map_or_else(|| "not a BPMN model".to_owned(), |d| d.message.clone());
            return Err(format!("the model is invalid: {first}"));
        };
        executive_runtime::replay::replay(Arc::new(graph), &body.record).map_err(|e| e.to_string())
    })
    .await;
    match job {
        Ok(Ok(frames)) => Json(json!({ "frames": frames })).into_response(),
        Ok(Err(why)) => refuse(StatusCode::UNPROCESSABLE_ENTITY, why),
        Err(e) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the replay failed: {e}"),
        ),
    }
}
