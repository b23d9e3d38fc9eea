//! `trace verify` on the model and requirements the page holds.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};
use executive_model::Options;

use super::{Shared, file_error, refuse};
use crate::{checks, files};

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
static VERIFYING: std::sync::LazyLock<Arc<tokio::sync::Mutex<()>>> =
    std::sync::LazyLock::new(Arc::default);

/// `trace verify` (Spin, and with `native` the engine's own exploration) on the model and
/// requirements the page holds for mission `name`: the same report, counterexamples included.
/// An invalid model, an element the translation refuses or a requirement that does not
/// compile is 422 with the reason; Spin failing is 500.
pub(super) async fn verify(State(s): Shared, Path(name): Path<String>, body: Bytes) -> Response {
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
    let req_path = match files::requirements(&s.dir, &name) {
        Ok(p) => p,
        Err(e) => return file_error(e),
    };
    // Held by the verification itself: a page that goes away does not free it while Spin runs.
    let one = Arc::clone(&VERIFYING).lock_owned().await;
    let studio = Arc::clone(&s);
    let job = tokio::task::spawn_blocking(move || {
        let _one = one;
        let loaded = checks::load(&studio.dir, body.model.as_bytes(), &Options::default());
        executive_runtime::verify::verify_loaded(executive_runtime::verify::Job {
            mission: name,
            loaded,
            requirements: body
                .requirements
                .filter(|t| !t.trim().is_empty())
                .map(|t| (req_path, t)),
            dir: executive_runtime::verify::default_work_dir(&model_path),
            loops: body.loops,
            depth: 1_000_000,
            native: body.native,
            systems: match &studio.connectors {
                Some(config) => Ok(vec![executive_runtime::verify::Systems {
                    pool: None,
                    source: "the studio's connectors (--connectors)".into(),
                    config: config.clone(),
                    catalogues: executive_runtime::catalogues::served(config, &studio.catalogues()),
                }]),
                None => Err("the studio knows no connectors (--connectors)".into()),
            },
            max_states: 400_000,
        })
    })
    .await;
    match job {
        Ok(Ok(report)) => Json(report).into_response(),
        Ok(Err(e @ executive_runtime::verify::VerifyError::Spin(_))) => {
            refuse(StatusCode::INTERNAL_SERVER_ERROR, e)
        }
        Ok(Err(e)) => refuse(StatusCode::UNPROCESSABLE_ENTITY, e),
        Err(e) => refuse(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the verification failed: {e}"),
        ),
    }
}
