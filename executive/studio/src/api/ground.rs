//! The studio's ground station: its desk of open user tasks, and answers from the page.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};
use serde_json::json;

use super::{Shared, refuse};
use crate::Studio;

/// The studio's ground station, or why there is none.
fn station(
    s: &Studio,
) -> Result<&Arc<ground_station::station::Station>, (StatusCode, &'static str)> {
    s.ground.as_ref().ok_or((
        StatusCode::SERVICE_UNAVAILABLE,
        "this studio is not a ground station (start it with --station NAME)",
    ))
}

/// The open user tasks of the studio's ground station, each with its form (the answer's typed
/// fields), context and deadline (as text, and in mission ms); the last tasks closed, with who
/// or what closed them; and the station's last event lines.
pub(super) async fn desk(State(s): Shared) -> Response {
    let st = match station(&s) {
        Ok(st) => st,
        Err((status, why)) => return refuse(status, why),
    };
    let desk = st.desk();
    let tasks: Vec<serde_json::Value> = desk
        .list()
        .map(|t| {
            let form = st.forms().action(&t.handle.action);
            json!({
                "number": t.number,
                "task": t.task(),
                "name": t.name(),
                "action": t.handle.action,
                "context": t.context(),
                "deadline": t.deadline(),
                "deadline_ms": t.handle.fields.get("deadline_ms"),
                "answering": t.answering,
                "form": form.map(|f| json!({ "description": f.description, "fields": f.result })),
            })
        })
        .collect();
    let closed: Vec<_> = desk.closed().collect();
    Json(json!({ "station": st.id, "tasks": tasks, "closed": closed, "log": st.log() }))
        .into_response()
}

/// What the page sends to answer a task.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct AnswerBody {
    operator: String,
    fields: connector_api::Fields,
}

/// Answers open task `number` as `operator` at this station: the fields are checked against
/// the task's form first (422 naming the field), then sent to the executive, which judges it
/// like any station's answer; the reply says whether it was applied and why not.
pub(super) async fn answer(State(s): Shared, Path(number): Path<u32>, body: Bytes) -> Response {
    let st = match station(&s) {
        Ok(st) => Arc::clone(st),
        Err((status, why)) => return refuse(status, why),
    };
    let body: AnswerBody = match serde_json::from_slice(&body) {
        Ok(b) => b,
        Err(e) => return refuse(StatusCode::BAD_REQUEST, format!("not an answer: {e}")),
    };
    let operator = body.operator.trim();
    if operator.is_empty()
        || operator.len() > 64
        || !operator
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
    {
        return refuse(
            StatusCode::UNPROCESSABLE_ENTITY,
            "the operator's name must be 1 to 64 letters, digits, `-`, `_` or `.`",
        );
    }
    let action = match st.desk().get(number) {
        Some(t) => t.handle.action.clone(),
        None => return refuse(StatusCode::NOT_FOUND, format!("no open task {number}")),
    };
    let Some(form) = st.forms().action(&action).cloned() else {
        return refuse(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("task {number}: no form for `{action}`"),
        );
    };
    if let Err(why) = form.check_result(&body.fields) {
        return refuse(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("task {number}: {why}"),
        );
    }
    let applied = st.answer(number, body.fields, operator).await;
    let said: Vec<String> = st
        .log()
        .into_iter()
        .filter(|l| l.starts_with(&format!("task {number} ")))
        .collect();
    Json(json!({ "applied": applied, "said": said })).into_response()
}
