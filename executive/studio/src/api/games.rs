//! The token games in play (`crate::simulate`), one per page.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Extension, Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};
use executive_model::Options;
use serde_json::json;

use super::{Shared, refuse};
use crate::checks;
use crate::simulate::{Act, Simulation};

/// The token games being played, by id; the oldest goes when there are too many.
#[derive(Default)]
pub(super) struct Games {
    next: std::sync::atomic::AtomicU64,
    playing: std::sync::Mutex<std::collections::BTreeMap<u64, Game>>,
}

/// At most this many games at once (one per page, in practice).
const MAX_GAMES: usize = 16;

pub(super) type Played = Extension<Arc<Games>>;

/// Starts a token game of the model in the body (loaded as a sketch may be: the token game
/// plays drawings that `trace run` would refuse, such as tasks without an action): `{id, view}`.
pub(super) async fn start(State(s): Shared, Extension(games): Played, body: Bytes) -> Response {
    let studio = Arc::clone(&s);
    let loaded = tokio::task::spawn_blocking(move || {
        let options = Options {
            token_game: true,
            script_connector: true,
            ..Options::default()
        };
        checks::load(&studio.dir, &body, &options)
    })
    .await;
    let loaded = match loaded {
        Ok(l) => l,
        Err(e) => {
            return refuse(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("loading failed: {e}"),
            );
        }
    };
    let Some(graph) = loaded.graph else {
        let first = loaded.errors().next().map_or_else(
            || "not a BPMN model".to_owned(),
            |d| format!("{} (line {})", d.message, d.line),
        );
        return refuse(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("the model cannot be played: {first}"),
        );
    };
    let game = match tokio::task::spawn_blocking(move || Simulation::start(Arc::new(graph))).await {
        Ok(Ok(g)) => g,
        Ok(Err(e)) => return refuse(StatusCode::UNPROCESSABLE_ENTITY, e),
        Err(e) => {
            return refuse(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("the start failed: {e}"),
            );
        }
    };
    let view = game.view();
    let id = games
        .next
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        + 1;
    let Ok(mut playing) = games.playing.lock() else {
        return poisoned();
    };
    while playing.len() >= MAX_GAMES {
        playing.pop_first();
    }
    playing.insert(id, Arc::new(std::sync::Mutex::new(game)));
    tracing::info!(id, "token game started");
    Json(json!({ "id": id, "view": view })).into_response()
}

/// One act of the player (`{"act": "complete", "element": "Task_1"}`, see
/// [`crate::simulate::Act`]): the view after it, or 422 naming what did not fit (the game is
/// unchanged then) with the view as it is.
pub(super) async fn act(Extension(games): Played, Path(id): Path<u64>, body: Bytes) -> Response {
    let act = match serde_json::from_slice::<serde_json::Value>(&body)
        .map_err(|e| crate::simulate::SimError::BadAct {
            element: "?".into(),
            reason: e.to_string(),
        })
        .and_then(Act::from_json)
    {
        Ok(a) => a,
        Err(e) => return refuse(StatusCode::BAD_REQUEST, e),
    };
    let game = match games.playing.lock() {
        Ok(playing) => playing.get(&id).cloned(),
        Err(_) => return poisoned(),
    };
    let Some(game) = game else {
        return refuse(
            StatusCode::NOT_FOUND,
            format!("no token game {id}: start one"),
        );
    };
    // An act may run long (a model that loops until the engine's bound): off the async
    // threads, holding only this game.
    let played = tokio::task::spawn_blocking(move || {
        let mut game = game.lock().unwrap_or_else(|p| p.into_inner());
        let done = game.act(act);
        (done, game.view())
    })
    .await;
    match played {
        Ok((Ok(()), view)) => Json(json!({ "view": view })).into_response(),
        Ok((Err(e), view)) => {
            tracing::warn!(id, "act refused: {e}");
            (
                StatusCode::UNPROCESSABLE_ENTITY,
                Json(json!({ "error": e.to_string(), "view": view })),
            )
                .into_response()
        }
        Err(e) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the act failed: {e}"),
        ),
    }
}

/// Ends a token game.
pub(super) async fn end(Extension(games): Played, Path(id): Path<u64>) -> Response {
    let removed = games.playing.lock().map(|mut p| p.remove(&id).is_some());
    match removed {
        Ok(true) => StatusCode::NO_CONTENT.into_response(),
        Ok(false) => refuse(StatusCode::NOT_FOUND, format!("no token game {id}")),
        Err(_) => poisoned(),
    }
}

/// One game, locked while an act runs.
type Game = Arc<std::sync::Mutex<Simulation>>;

fn poisoned() -> Response {
    refuse(
        StatusCode::INTERNAL_SERVER_ERROR,
        "the games' table is poisoned",
    )
}
