//! `POST /api/timer`: a timer definition as the panel holds it, previewed (`crate::timers`).

use axum::body::Bytes;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};

use super::refuse;

/// What the page sends: the definition's element (`timeDate`, `timeDuration`, `timeCycle`),
/// its text, and optionally the mission time it would start at.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Ask {
    kind: String,
    value: String,
    #[serde(default)]
    from_ms: Option<i64>,
}

/// The preview, or 422 with the executive's own reason for refusing the value.
pub(super) async fn preview(body: Bytes) -> Response {
    let ask: Ask = match serde_json::from_slice(&body) {
        Ok(a) => a,
        Err(e) => return refuse(StatusCode::BAD_REQUEST, format!("not a timer: {e}")),
    };
    let Some(kind) = crate::timers::kind(&ask.kind) else {
        return refuse(
            StatusCode::BAD_REQUEST,
            format!(
                "`{}` is not a timer definition (timeDate, timeDuration or timeCycle)",
                ask.kind
            ),
        );
    };
    match crate::timers::preview(kind, &ask.value, ask.from_ms) {
        Ok(p) => Json(p).into_response(),
        Err(why) => refuse(StatusCode::UNPROCESSABLE_ENTITY, why),
    }
}
