//! The running missions, followed for the operations view (`crate::ops`).

use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Json, Response};

use super::{Shared, refuse};
use crate::Studio;

/// The studio's Zenoh membership for following `mission` (when given), or why not: offline,
/// or a mission id that is not one key chunk (it must name one executive, no wildcard).
fn joined<'a>(
    s: &'a Studio,
    mission: Option<&str>,
) -> Result<&'a Arc<crate::live::Live>, (StatusCode, String)> {
    let live = s.live.as_ref().ok_or_else(|| {
        (
            StatusCode::SERVICE_UNAVAILABLE,
            "the studio is offline (--offline): it follows no mission".to_owned(),
        )
    })?;
    if let Some(m) = mission {
        connector_api::keys::check_chunk(m)
            .map_err(|e| (StatusCode::BAD_REQUEST, format!("mission `{m}`: {e}")))?;
    }
    Ok(live)
}

fn ask_error(e: crate::ops::AskError) -> Response {
    let status = match e {
        crate::ops::AskError::NoAnswer(_) => StatusCode::GATEWAY_TIMEOUT,
        crate::ops::AskError::Zenoh(_) => StatusCode::BAD_GATEWAY,
    };
    refuse(status, e)
}

/// Every executive seen on the network: `[{mission, alive, reboots}]`.
pub(super) async fn executives(State(s): Shared) -> Response {
    match joined(&s, None) {
        Ok(live) => Json(live.executives()).into_response(),
        Err((status, why)) => refuse(status, why),
    }
}

/// The BPMN XML of the model a mission runs, as its executive serves it.
pub(super) async fn model(State(s): Shared, Path(mission): Path<String>) -> Response {
    let live = match joined(&s, Some(&mission)) {
        Ok(l) => l,
        Err((status, why)) => return refuse(status, why),
    };
    match live.model(&mission).await {
        // XML from the network: never run as a page of the studio's origin.
        Ok(xml) => (
            [
                (header::CONTENT_TYPE, "application/xml"),
                (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
                (header::CONTENT_SECURITY_POLICY, "sandbox"),
            ],
            xml,
        )
            .into_response(),
        Err(e) => ask_error(e),
    }
}

/// A mission's present state (`docs/protocol.md` §8b), as its executive answers it.
pub(super) async fn state(State(s): Shared, Path(mission): Path<String>) -> Response {
    let live = match joined(&s, Some(&mission)) {
        Ok(l) => l,
        Err((status, why)) => return refuse(status, why),
    };
    match live.state(&mission).await {
        Ok(state) => Json(state).into_response(),
        Err(e) => ask_error(e),
    }
}

/// Follows a mission as server-sent events: `state` (the present, first and after each burst
/// of record lines), `record` (each line newer than the last state), `gone` and `back` (the
/// executive stopped, or came back after a restart).
pub(super) async fn events(State(s): Shared, Path(mission): Path<String>) -> Response {
    use axum::response::sse::{Event, KeepAlive, Sse};
    let live = match joined(&s, Some(&mission)) {
        Ok(l) => l,
        Err((status, why)) => return refuse(status, why),
    };
    let happenings = match live.follow(&mission).await {
        Ok(h) => h,
        Err(e) => return refuse(StatusCode::BAD_GATEWAY, e),
    };
    let events = futures_util::stream::unfold(happenings, |mut rx| async move {
        let event = match rx.recv().await? {
            crate::ops::Happening::State(v) => Event::default().event("state").data(v.to_string()),
            crate::ops::Happening::Line(l) => Event::default().event("record").data(l.to_string()),
            // Never empty data: a browser drops an event whose data is empty (the SSE rules).
            crate::ops::Happening::Gone => Event::default().event("gone").data("{}"),
            crate::ops::Happening::Back => Event::default().event("back").data("{}"),
        };
        Some((Ok::<_, std::convert::Infallible>(event), rx))
    });
    Sse::new(events)
        .keep_alive(KeepAlive::default())
        .into_response()
}

/// The mission's timeline so far: the page `trace timeline` writes, drawn from the record its
/// executive serves (`<root>/exec/<mission>/history`); bars tell the embedding page which
/// element they are when clicked.
pub(super) async fn timeline(State(s): Shared, Path(mission): Path<String>) -> Response {
    let live = match joined(&s, Some(&mission)) {
        Ok(l) => l,
        Err((status, why)) => return refuse(status, why),
    };
    let record = match live.history(&mission).await {
        Ok(r) => r,
        Err(e) => return ask_error(e),
    };
    let t = executive_runtime::timeline::build(record.lines().map(str::to_owned));
    match executive_runtime::timeline::page(&t, &mission) {
        Ok(html) => ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], html).into_response(),
        Err(e) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("no timeline: {e}"),
        ),
    }
}
