//! The connector contract (paper §3.1): what the executive asks of a connector and what a
//! connector reports back. A connector never blocks the executive: commands return at once and
//! everything that happens later arrives as a [`Report`] on the channel the connector was given.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::Value;
use tokio::sync::mpsc::UnboundedSender;
use tokio::sync::oneshot;

use crate::catalogue::Catalogue;
use crate::wire::Fields;

/// A command to run one task attempt on a system.
#[derive(Clone, Debug, PartialEq)]
pub struct Command {
    /// The goal id: stable across executive restarts, unique per attempt; repeating a command
    /// with the same id is harmless.
    pub goal_id: String,
    /// The action to call.
    pub action: String,
    /// The goal's fields.
    pub fields: Fields,
}

/// Something that happened on a system.
#[derive(Clone, Debug, PartialEq)]
pub enum Report {
    /// The system took the goal.
    Accepted {
        /// Which goal.
        goal_id: String,
    },
    /// Progress of a running goal.
    Feedback {
        /// Which goal.
        goal_id: String,
        /// Progress 0–100, if known.
        progress_pct: Option<f64>,
        /// Activity-specific fields.
        fields: Fields,
    },
    /// The goal succeeded with these outputs.
    Done {
        /// Which goal.
        goal_id: String,
        /// Result fields.
        outputs: Fields,
    },
    /// The goal failed: the code is what the model's error boundaries match.
    Failed {
        /// Which goal.
        goal_id: String,
        /// Error code (`TOOL_STUCK`, `CONNECTOR_LOST`, `REJECTED`, …).
        code: String,
        /// Detail for people.
        message: String,
    },
    /// The goal stopped after an abort.
    Canceled {
        /// Which goal.
        goal_id: String,
    },
    /// A system data value changed (past the configured deadband).
    Data {
        /// Data key (`battery_soc_pct`).
        key: String,
        /// New value.
        value: Value,
    },
    /// An operator answered a user task (ground stations): the executive applies it if the
    /// task is still open and the answer fits, and gives its verdict to the sender.
    Answer {
        /// Which goal (user task).
        goal_id: String,
        /// The answer's fields (already checked against the catalogue).
        fields: Fields,
        /// Who answered, for the execution record (`ana@station-b`).
        operator: String,
        /// Where the executive's verdict goes.
        verdict: Verdict,
    },
    /// The system's mission clock: mission time `mission_ms` at the moment of the report,
    /// running `speed` times faster than wall time.
    Clock {
        /// Mission time, ms since the epoch.
        mission_ms: i64,
        /// Mission ms per wall ms.
        speed: f64,
    },
}

/// The executive's verdict on an [`Report::Answer`]: `Ok` once the answer is committed,
/// `Err(reason)` when it was refused (nothing changed). Given at most once.
#[derive(Clone)]
pub struct Verdict(Arc<Mutex<Option<VerdictSender>>>);

type VerdictSender = oneshot::Sender<Result<(), String>>;

impl Verdict {
    /// A verdict slot and the receiver the sender of the answer waits on.
    pub fn new() -> (Verdict, oneshot::Receiver<Result<(), String>>) {
        let (tx, rx) = oneshot::channel();
        (Verdict(Arc::new(Mutex::new(Some(tx)))), rx)
    }

    /// Gives the verdict (later calls do nothing).
    pub fn give(&self, verdict: Result<(), String>) {
        let tx = self.0.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(tx) = tx {
            let _ = tx.send(verdict);
        }
    }
}

impl std::fmt::Debug for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Verdict")
    }
}

impl PartialEq for Verdict {
    fn eq(&self, other: &Verdict) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Why a connector could not do what it was asked (not a task failure: those are reports).
#[derive(Debug, thiserror::Error)]
pub enum ConnectorError {
    /// The system did not answer in time.
    #[error("{system} did not answer within {waited:?}: {what}")]
    Timeout {
        /// Which system.
        system: String,
        /// How long we waited.
        waited: Duration,
        /// What for.
        what: String,
    },
    /// The system answered with something we cannot use.
    #[error("{system} answered badly: {reason}")]
    Protocol {
        /// Which system.
        system: String,
        /// What was wrong.
        reason: String,
    },
    /// The transport failed.
    #[error("transport: {0}")]
    Transport(String),
}

/// A boxed future, so connectors of different kinds live behind one trait object.
pub type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// The plug-in between the executive and one system (or middleware).
pub trait Connector: Send {
    /// The connector's configured name.
    fn name(&self) -> &str;

    /// The actions the system serves (asked before a mission loads); `None` when the
    /// connector has no catalogue (the scripted connector accepts anything).
    fn catalogue(&mut self) -> BoxFuture<'_, Result<Option<Catalogue>, ConnectorError>>;

    /// Starts a goal. Idempotent by goal id. Outcomes arrive as reports.
    fn execute(&mut self, command: Command);

    /// After an executive restart: finds out what became of a goal sent before the crash —
    /// still running (keep waiting), finished (its result is reported), unknown to the system
    /// (`CONNECTOR_LOST`).
    fn reconcile(&mut self, command: Command);

    /// Aborts a goal (an interrupting boundary event, a terminate); `Canceled` follows.
    fn abort(&mut self, goal_id: &str);

    /// Pushes a notification from the mission to the system.
    fn notify(&mut self, name: &str, payload: Value);

    /// Stops: undeclares everything (also done on drop).
    fn close(&mut self) -> BoxFuture<'_, ()>;
}

/// Where connectors send their reports.
pub type Reports = UnboundedSender<Report>;
