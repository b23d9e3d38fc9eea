//! The studio's HTTP routes: the page, the mission files, validation and the catalogues.
//! Every refusal is JSON `{"error": "..."}` with a status that says whose fault it is.

use std::sync::Arc;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Extension, Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Json, Response};
use axum::routing::{get, post};
use executive_model::Options;
use serde_json::json;

use crate::files::{self, FileError};
use crate::simulate::{Act, Simulation};
use crate::{Studio, assets, checks};

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
            "/api/requirements/{name}",
            get(read_requirements).put(write_requirements),
        )
        .route("/api/verify/{name}", post(verify))
        .route("/api/ops/executives", get(ops_executives))
        .route("/api/ops/{mission}/model", get(ops_model))
        .route("/api/ops/{mission}/state", get(ops_state))
        .route("/api/ops/{mission}/events", get(ops_events))
        .route("/api/simulate", post(simulate_start))
        .route(
            "/api/simulate/{id}",
            post(simulate_act).delete(simulate_end),
        )
        .route(
            "/{file}",
            get(|Path(file): Path<String>| async move { page(&file) }),
        )
        .layer(DefaultBodyLimit::max(limit))
        .layer(Extension(Arc::new(Games::default())))
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
async fn run_check(studio: &Arc<Studio>, body: Bytes) -> Result<checks::Report, Response> {
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

async fn validate_text(State(s): Shared, body: Bytes) -> Response {
    match run_check(&s, body).await {
        Ok(report) => Json(report).into_response(),
        Err(e) => e,
    }
}

/// As `/api/validate`, for the model of file `name` (which need not exist yet).
async fn validate_named(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
    if let Err(e) = files::path(&s.dir, &name) {
        return file_error(e);
    }
    validate_text(State(s), body).await
}

/// Every catalogue known, each with `"source": "live" | "file"`; the running systems are
/// asked again first.
async fn catalogues(State(s): Shared) -> Response {
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
async fn read_requirements(State(s): Shared, Path(name): Path<String>) -> Response {
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
async fn write_requirements(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
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

/// What the page sends to verify: the model and the requirements as they are in the page.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct VerifyBody {
    model: String,
    #[serde(default)]
    requirements: Option<String>,
    /// Also explore the engine itself (`trace verify --native`).
    #[serde(default)]
    native: bool,
    /// `trace verify --loops` (1 to 3 here: more is for the command line).
    #[serde(default = "one")]
    loops: u8,
}

fn one() -> u8 {
    1
}

/// One verification at a time: Spin is CPU-bound and each mission has one work directory.
static VERIFYING: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// `trace verify` (Spin, and with `native` the engine's own exploration) on the model and
/// requirements the page holds for mission `name`: the same report, counterexamples included.
/// An invalid model, an element the translation refuses or a requirement that does not
/// compile is 422 with the reason; Spin failing is 500.
async fn verify(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
    let model_path = match files::path(&s.dir, &name) {
        Ok(p) => p,
        Err(e) => return file_error(e),
    };
    let body: VerifyBody = match serde_json::from_slice(&body) {
        Ok(b) => b,
        Err(e) => {
            return refuse(
                StatusCode::BAD_REQUEST,
                format!("not a verify request: {e}"),
            );
        }
    };
    if !(1..=3).contains(&body.loops) {
        return refuse(
            StatusCode::BAD_REQUEST,
            format!("loops {} is not 1 to 3", body.loops),
        );
    }
    let req_path = model_path.with_extension("req.toml");
    let _one = VERIFYING.lock().await;
    let studio = Arc::clone(&s);
    let job = tokio::task::spawn_blocking(move || {
        let loaded = checks::load(&studio.dir, body.model.as_bytes(), &Options::default());
        executive::verify::verify_loaded(executive::verify::Job {
            mission: name,
            loaded,
            requirements: body
                .requirements
                .filter(|t| !t.trim().is_empty())
                .map(|t| (req_path, t)),
            dir: executive::verify::default_work_dir(&model_path),
            loops: body.loops,
            depth: 1_000_000,
            native: body.native,
        })
    })
    .await;
    match job {
        Ok(Ok(report)) => Json(report).into_response(),
        Ok(Err(e @ executive::verify::VerifyError::Spin(_))) => {
            refuse(StatusCode::INTERNAL_SERVER_ERROR, e)
        }
        Ok(Err(e)) => refuse(StatusCode::UNPROCESSABLE_ENTITY, e),
        Err(e) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the verification failed: {e}"),
        ),
    }
}

/// The token games being played, by id; the oldest goes when there are too many.
#[derive(Default)]
struct Games {
    next: std::sync::atomic::AtomicU64,
    playing: std::sync::Mutex<std::collections::BTreeMap<u64, Simulation>>,
}

/// At most this many games at once (one per page, in practice).
const MAX_GAMES: usize = 16;

type Played = Extension<Arc<Games>>;

/// Starts a token game of the model in the body (loaded as a sketch may be: the token game
/// plays drawings that `trace run` would refuse, such as tasks without an action): `{id, view}`.
async fn simulate_start(State(s): Shared, Extension(games): Played, body: Bytes) -> Response {
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
    let game = match Simulation::start(Arc::new(graph)) {
        Ok(g) => g,
        Err(e) => return refuse(StatusCode::UNPROCESSABLE_ENTITY, e),
    };
    let view = game.view();
    let id = games
        .next
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        + 1;
    let Ok(mut playing) = games.playing.lock() else {
        return refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            "the games' table is poisoned",
        );
    };
    while playing.len() >= MAX_GAMES {
        playing.pop_first();
    }
    playing.insert(id, game);
    tracing::info!(id, "token game started");
    Json(json!({ "id": id, "view": view })).into_response()
}

/// One act of the player (`{"act": "complete", "element": "Task_1"}`, see
/// [`crate::simulate::Act`]): the view after it, or 422 naming what did not fit (the game is
/// unchanged then) with the view as it is.
async fn simulate_act(Extension(games): Played, Path(id): Path<u64>, body: Bytes) -> Response {
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
    let Ok(mut playing) = games.playing.lock() else {
        return refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            "the games' table is poisoned",
        );
    };
    let Some(game) = playing.get_mut(&id) else {
        return refuse(
            StatusCode::NOT_FOUND,
            format!("no token game {id}: start one"),
        );
    };
    match game.act(act) {
        Ok(()) => Json(json!({ "view": game.view() })).into_response(),
        Err(e) => {
            tracing::warn!(id, "act refused: {e}");
            (
                StatusCode::UNPROCESSABLE_ENTITY,
                Json(json!({ "error": e.to_string(), "view": game.view() })),
            )
                .into_response()
        }
    }
}

/// Ends a token game.
async fn simulate_end(Extension(games): Played, Path(id): Path<u64>) -> Response {
    let removed = games.playing.lock().map(|mut p| p.remove(&id).is_some());
    match removed {
        Ok(true) => StatusCode::NO_CONTENT.into_response(),
        Ok(false) => refuse(StatusCode::NOT_FOUND, format!("no token game {id}")),
        Err(_) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            "the games' table is poisoned",
        ),
    }
}

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

/// Every executive seen on the network: `[{mission, alive, returns}]`.
async fn ops_executives(State(s): Shared) -> Response {
    match joined(&s, None) {
        Ok(live) => Json(live.executives()).into_response(),
        Err((status, why)) => refuse(status, why),
    }
}

/// The BPMN XML of the model a mission runs, as its executive serves it.
async fn ops_model(State(s): Shared, Path(mission): Path<String>) -> Response {
    let live = match joined(&s, Some(&mission)) {
        Ok(l) => l,
        Err((status, why)) => return refuse(status, why),
    };
    match live.model(&mission).await {
        Ok(xml) => ([(header::CONTENT_TYPE, "application/xml")], xml).into_response(),
        Err(e) => ask_error(e),
    }
}

/// A mission's present state (`docs/protocol.md` §8b), as its executive answers it.
async fn ops_state(State(s): Shared, Path(mission): Path<String>) -> Response {
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
async fn ops_events(State(s): Shared, Path(mission): Path<String>) -> Response {
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
