//! The connector contract (paper §3.1): what the executive asks of a connector and what a
//! connector reports back. A connector never blocks the executive: commands return at once and
//! everything that happens later arrives as a [`Report`] on the channel the connector was given.

use std::collections::BTreeMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::{Deserialize, Serialize};
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
    /// A message from the executive of another pool (a fleet): the executive steps it and
    /// gives its verdict once committed (or refused), which is the sender's acknowledgement.
    Letter {
        /// The message.
        letter: crate::wire::Letter,
        /// Where the executive's verdict goes.
        verdict: Verdict,
    },
    /// The receiver of a message this executive sent gave its verdict: `None` applied (now or
    /// before), or the reason it was refused. The message is not sent again.
    Delivered {
        /// The letter's key.
        key: String,
        /// Why it was refused, if it was.
        refused: Option<String>,
    },
    /// The executive of another pool appeared, went, or ended its part.
    Peer {
        /// The pool's id.
        pool: String,
        /// Its state now.
        state: PeerState,
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

/// The state of another pool's executive, from its liveliness token.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PeerState {
    /// Its part of the mission runs.
    Running,
    /// Its part has ended and every message it sent was acknowledged (it stays done when it
    /// leaves afterwards).
    Done,
    /// It went away while running (stopped or crashed): its messages wait for its return.
    Absent,
}

/// The executive's verdict on an [`Report::Answer`] or a [`Report::Letter`]: `Ok` once the
/// answer or message is committed, `Err(reason)` when it was refused (nothing changed). Given at
/// most once.
#[derive(Clone)]
pub struct Verdict(Arc<Mutex<Option<Giver>>>);

/// Where a verdict goes.
enum Giver {
    /// To a task that waits for it.
    Channel(oneshot::Sender<Result<(), String>>),
    /// Into a call made where the verdict is given (see [`Verdict::call`]).
    Call(Call),
}

/// A call that receives the verdict, or `None` when no verdict will come.
struct Call(Option<Box<Heard>>);

/// What a [`Verdict::call`] makes with the verdict.
type Heard = dyn FnOnce(Option<Result<(), String>>) + Send;

impl Drop for Call {
    fn drop(&mut self) {
        if let Some(call) = self.0.take() {
            call(None);
        }
    }
}

impl Verdict {
    /// A verdict slot and the receiver the sender of the answer waits on.
    pub fn new() -> (Verdict, oneshot::Receiver<Result<(), String>>) {
        let (tx, rx) = oneshot::channel();
        (Verdict(Arc::new(Mutex::new(Some(Giver::Channel(tx))))), rx)
    }

    /// A verdict that makes `call` with it where it is given, with no task woken in between:
    /// a reply sent straight from the executive's step. `call` gets `None` if the verdict is
    /// dropped without being given (the executive stops).
    pub fn call(call: impl FnOnce(Option<Result<(), String>>) + Send + 'static) -> Verdict {
        Verdict(Arc::new(Mutex::new(Some(Giver::Call(Call(Some(
            Box::new(call),
        )))))))
    }

    /// Gives the verdict (later calls do nothing).
    pub fn give(&self, verdict: Result<(), String>) {
        let giver = self.0.lock().unwrap_or_else(|p| p.into_inner()).take();
        match giver {
            Some(Giver::Channel(tx)) => {
                let _ = tx.send(verdict);
            }
            Some(Giver::Call(mut call)) => {
                if let Some(call) = call.0.take() {
                    call(Some(verdict));
                }
            }
            None => {}
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

/// How long a connector waits, how often it asks again and how loudly it refuses: every wait
/// has an end (`docs/protocol.md` §4.4). Durations are in ms so the struct reads from TOML;
/// every field has a default.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// A goal sent to a server that serves its action but never acknowledges it fails with
    /// `NOT_ACCEPTED` this long after it was first sent (30 000).
    pub accept_within_ms: u64,
    /// The first pause before an unacknowledged goal is sent again, or a server is asked
    /// again about an answer that could not be understood; it doubles after each try (200).
    pub retry_first_ms: u64,
    /// The longest pause between two tries (5 000).
    pub retry_max_ms: u64,
    /// Answers about one goal that could not be understood before it fails with
    /// `PROTOCOL_ERROR` (5).
    pub unreadable_max: u32,
    /// Dropped messages are logged at most once per key this often, with a count of the
    /// others (10 000).
    pub drop_log_every_ms: u64,
    /// Wall-time tolerance on a mission clock report's advance (1 000; see
    /// [`crate::wire::check_clock`]).
    pub clock_slack_ms: u64,
    /// The watchdog: mission time a goal may run past its action's declared maximum duration
    /// before the executive asks its state (off unless set: `60000` is a minute).
    pub overrun_margin_ms: Option<u64>,
    /// The maximum assumed for an action whose catalogue declares no upper bound on its
    /// duration, mission ms (86 400 000, a day; 0: no watchdog for such actions).
    pub overrun_default_ms: u64,
    /// How long, wall time, the server has to end the goal once asked its state at the
    /// watchdog's deadline, before the goal fails with `OVERRUN` (10 000).
    pub overrun_state_wait_ms: u64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            accept_within_ms: 30_000,
            retry_first_ms: 200,
            retry_max_ms: 5_000,
            unreadable_max: 5,
            drop_log_every_ms: 10_000,
            clock_slack_ms: 1_000,
            overrun_margin_ms: None,
            overrun_default_ms: 86_400_000,
            overrun_state_wait_ms: 10_000,
        }
    }
}

impl Limits {
    /// The pauses between tries: `retry_first_ms`, doubling, capped at `retry_max_ms`.
    pub fn pauses(&self) -> impl Iterator<Item = Duration> + use<> {
        let first = self.retry_first_ms.max(1);
        let max = self.retry_max_ms.max(first);
        std::iter::successors(Some(first), move |p| Some((p * 2).min(max)))
            .map(Duration::from_millis)
    }

    /// The most times one goal can be sent before `accept_within_ms` ends it, whatever the
    /// server does: the first send, then one after each pause of the schedule that still ends
    /// within the deadline (queries that take time only make it fewer). A liveliness
    /// appearance of the server also sends at once; this bound assumes none.
    pub fn max_sends(&self) -> u32 {
        let mut elapsed = Duration::ZERO;
        let deadline = Duration::from_millis(self.accept_within_ms);
        let mut sends = 1;
        for pause in self.pauses() {
            elapsed += pause;
            if elapsed > deadline {
                break;
            }
            sends += 1;
        }
        sends
    }
}

/// What a connector refused and dropped instead of reporting (garbage payloads, messages for
/// goals it does not run, mistyped feedback or telemetry, implausible clock reports, …), for
/// the operator: each drop is also logged at warn (rate-limited).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Dropped {
    /// All drops since the connector started.
    pub total: u64,
    /// Drops by reason (`garbage`, `unknown_goal`, `duplicate`, `late`, `invalid_status`,
    /// `mistyped`, `implausible_clock`, `unreadable_reply`).
    pub by_reason: BTreeMap<String, u64>,
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

    /// What the connector has refused and dropped so far (none for connectors that cannot
    /// receive anything unexpected).
    fn dropped(&self) -> Dropped {
        Dropped::default()
    }
}

/// Where connectors send their reports.
pub type Reports = UnboundedSender<Report>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retries_back_off_and_bound_the_sends() {
        let l = Limits::default();
        let pauses: Vec<u64> = l.pauses().take(8).map(|d| d.as_millis() as u64).collect();
        assert_eq!(pauses, [200, 400, 800, 1600, 3200, 5000, 5000, 5000]);
        // 0.2 + 0.4 + 0.8 + 1.6 + 3.2 + 5 × 4 = 26.2 s ≤ 30 s < 31.2 s: ten sends at most.
        assert_eq!(l.max_sends(), 10);
        let l: Limits = serde_json::from_str(r#"{"accept_within_ms": 1000}"#).unwrap();
        assert_eq!(l.max_sends(), 3);
        assert!(serde_json::from_str::<Limits>(r#"{"accept_within": 1}"#).is_err());
    }

    #[test]
    fn a_called_verdict_is_given_once_or_said_undecided_when_dropped() {
        let heard = Arc::new(Mutex::new(Vec::new()));
        let verdict = |heard: &Arc<Mutex<Vec<_>>>| {
            let heard = Arc::clone(heard);
            Verdict::call(move |v| heard.lock().unwrap().push(v))
        };
        let given = verdict(&heard);
        let copy = given.clone();
        given.give(Err("refused".into()));
        copy.give(Ok(()));
        drop((given, copy));
        assert_eq!(*heard.lock().unwrap(), [Some(Err("refused".to_owned()))]);
        let dropped = verdict(&heard);
        drop(dropped.clone());
        assert_eq!(
            heard.lock().unwrap().len(),
            1,
            "a clone left is still undecided"
        );
        drop(dropped);
        assert_eq!(heard.lock().unwrap().last(), Some(&None));
    }
}
