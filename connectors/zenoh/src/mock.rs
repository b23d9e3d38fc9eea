//! A mock system: serves a catalogue with scripted behaviour per action (duration, outputs,
//! failures on chosen attempts, feedback, hanging until cancelled), through the same
//! [`ActionServer`] real systems use. For trying a mission against its catalogue before the
//! real system exists, for tests, and for the protocol benchmark.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use connector_api::{Catalogue, Fields};
use serde::Deserialize;
use tokio::sync::{mpsc, watch};

use crate::server::{GoalHandle, Request};

/// How one action behaves.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Behaviour {
    /// Wall time the activity takes.
    #[serde(default)]
    pub duration_ms: u64,
    /// Result fields on success.
    #[serde(default)]
    pub outputs: Fields,
    /// Abort with this code …
    #[serde(default)]
    pub fail: Option<String>,
    /// … on these attempts (the goal id's last chunk; all attempts if empty).
    #[serde(default)]
    pub fail_attempts: Vec<u32>,
    /// Feedback messages sent while running, evenly spaced.
    #[serde(default)]
    pub feedback: u32,
    /// Never finishes on its own (only a cancel ends it).
    #[serde(default)]
    pub hang: bool,
}

/// A mock system's definition file: the catalogue and each action's behaviour.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MockSpec {
    /// What is served.
    pub catalogue: Catalogue,
    /// Behaviour by action name (actions not listed succeed at once with no outputs).
    #[serde(default)]
    pub behaviour: BTreeMap<String, Behaviour>,
    /// Publish a mission clock on `<root>/tm/<server>/clock` every 50 ms.
    #[serde(default)]
    pub clock: Option<MockClock>,
}

/// A mock mission clock: starts at `start_ms` and runs `speed` times faster than wall time.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MockClock {
    /// Mission time at start, ms since the epoch.
    pub start_ms: i64,
    /// Mission ms per wall ms.
    pub speed: f64,
}

/// Publishes the mock clock until the session closes.
pub async fn publish_clock(
    session: zenoh::Session,
    keys: connector_api::Keys,
    server: String,
    clock: MockClock,
) {
    let t0 = std::time::Instant::now();
    let key = keys.telemetry(&server, "clock");
    loop {
        let mission_ms =
            clock.start_ms + (t0.elapsed().as_secs_f64() * 1000.0 * clock.speed) as i64;
        let sample = connector_api::wire::Telemetry {
            mission_ms,
            values: serde_json::json!({ "speed": clock.speed })
                .as_object()
                .cloned()
                .unwrap_or_default(),
        };
        if session
            .put(&key, crate::codec::json(&sample))
            .encoding(crate::codec::encoding("telemetry"))
            .await
            .is_err()
        {
            return;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Runs goals as the spec says until the request channel closes.
pub async fn run(
    spec: MockSpec,
    mut requests: mpsc::UnboundedReceiver<Request>,
    resume: Vec<GoalHandle>,
) {
    let cancels: Arc<Mutex<HashMap<String, watch::Sender<bool>>>> = Arc::default();
    let spawn = |h: GoalHandle| {
        let b = spec.behaviour.get(&h.action).cloned().unwrap_or_default();
        let (tx, rx) = watch::channel(false);
        cancels
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(h.goal_id.clone(), tx);
        tokio::spawn(goal(h, b, rx));
    };
    for h in resume {
        spawn(h);
    }
    while let Some(r) = requests.recv().await {
        match r {
            Request::Goal(h) => spawn(h),
            Request::Cancel(h, _) => {
                if let Some(tx) = cancels
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .remove(&h.goal_id)
                {
                    let _ = tx.send(true);
                }
            }
        }
    }
}

async fn goal(h: GoalHandle, b: Behaviour, mut cancel: watch::Receiver<bool>) {
    h.executing().await;
    let steps = b.feedback.max(1);
    let step = Duration::from_millis(b.duration_ms / u64::from(steps));
    for i in 0..steps {
        let waited = async {
            if b.hang {
                std::future::pending::<()>().await;
            }
            tokio::time::sleep(step).await;
        };
        let cancelled = tokio::select! {
            () = waited => false,
            r = cancel.wait_for(|c| *c) => r.is_ok(),
        };
        if cancelled {
            h.canceled(Fields::new()).await;
            return;
        }
        if b.feedback > 0 {
            let pct = 100.0 * f64::from(i + 1) / f64::from(steps);
            h.feedback(Some(pct), Fields::new()).await;
        }
    }
    let attempt = connector_api::keys::goal_attempt(&h.goal_id);
    match &b.fail {
        Some(code) if b.fail_attempts.is_empty() || b.fail_attempts.contains(&attempt) => {
            h.abort(code, &format!("{} failed (scripted)", h.action))
                .await;
        }
        _ => {
            h.succeed(b.outputs).await;
        }
    }
}
