//! The JSON payloads of the activity protocol (`docs/protocol.md` § Payloads). Every payload
//! carries the protocol version in its encoding schema (`application/json;trace.goal/1`) and is
//! refused, never trusted, when it does not parse.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// The protocol version in every encoding schema.
pub const VERSION: u32 = 1;

/// Fields of a goal, a result or feedback: a JSON object.
pub type Fields = Map<String, Value>;

/// A goal's state, on the server and as the client last saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Status {
    /// The server took the goal; it has not started.
    Accepted,
    /// The activity is running.
    Executing,
    /// A cancel was accepted; the activity is winding down.
    Canceling,
    /// Terminal: done, with outputs.
    Succeeded,
    /// Terminal: stopped after a cancel request.
    Canceled,
    /// Terminal: the activity failed (error code and message).
    Aborted,
    /// Terminal: the server refused the goal (reply to `goal` only).
    Rejected,
    /// Terminal, client side only: the server vanished or forgot the goal.
    Lost,
    /// Reply to `state` only: the server does not know the goal.
    Unknown,
}

impl Status {
    /// A goal in this state will not change again.
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            Status::Succeeded
                | Status::Canceled
                | Status::Aborted
                | Status::Rejected
                | Status::Lost
        )
    }
}

/// Error codes the protocol itself raises (systems declare their own in the catalogue). Every
/// one may be caught by a model's error boundary without being declared (`docs/protocol.md` §9).
pub mod codes {
    /// The server went away during the goal and did not come back within the grace period, or
    /// forgot the goal.
    pub const CONNECTOR_LOST: &str = "CONNECTOR_LOST";
    /// The server refused the goal (a `REJECTED` goal reply, a `reply_err`, or a result with
    /// status `REJECTED`).
    pub const REJECTED: &str = "REJECTED";
    /// A goal or result field could not be converted to the declared type, or a `SUCCEEDED`
    /// result lacks outputs its catalogue entry declares.
    pub const TYPE_MISMATCH: &str = "TYPE_MISMATCH";
    /// No connector serves the task's resource.
    pub const NO_CONNECTOR: &str = "NO_CONNECTOR";
    /// A server that serves the action never acknowledged the goal within the connector's
    /// `accept_within_ms` (the goal was re-sent with backoff until then).
    pub const NOT_ACCEPTED: &str = "NOT_ACCEPTED";
    /// The server's answers about the goal could not be understood (unparseable replies, a
    /// terminal status without its result, …) even after asking again a bounded number of times.
    pub const PROTOCOL_ERROR: &str = "PROTOCOL_ERROR";
    /// The server aborted the goal without an error code (`ABORTED` with no `error`, or an
    /// empty `error.code`).
    pub const ABORTED: &str = "ABORTED";
    /// The goal ran past its action's declared maximum duration by the connector's margin, and
    /// the server, asked for the goal's state, did not end it (the executive's watchdog).
    pub const OVERRUN: &str = "OVERRUN";
    /// Every protocol-level code, for load-time checks (a boundary may catch them undeclared).
    pub const ALL: [&str; 8] = [
        CONNECTOR_LOST,
        REJECTED,
        TYPE_MISMATCH,
        NO_CONNECTOR,
        NOT_ACCEPTED,
        PROTOCOL_ERROR,
        ABORTED,
        OVERRUN,
    ];
}

/// `get …/goal/<goal_id>` payload.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Goal {
    /// The goal id (also the last key chunk): `<mission>.<instance>.<token>.<attempt>`.
    pub goal_id: String,
    /// The goal's fields, typed per the catalogue.
    #[serde(default)]
    pub fields: Fields,
    /// Who sent it (executive instance), for the server's log.
    #[serde(default)]
    pub client: String,
}

/// Reply to a goal (also to a repeated goal: the goal's current status).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GoalReply {
    /// The goal id.
    pub goal_id: String,
    /// Current status (`REJECTED` when refused).
    pub status: Status,
    /// Why it was rejected.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The result, when the goal already ended (a repeat after completion).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<ResultMsg>,
}

/// `get …/cancel/<goal_id>` payload (optional: an empty payload is a cancel without reason).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CancelRequest {
    /// Why, for the people at the server ("answered by ana at station-b", "withdrawn: the
    /// approval window closed").
    pub reason: String,
}

/// `get …/answer/<goal_id>` payload: an operator's answer to a user task, sent by a ground
/// station to the executive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Answer {
    /// The user task's goal id (also the last key chunk).
    pub goal_id: String,
    /// The answer's fields, typed per the catalogue's `result`.
    pub fields: Fields,
    /// Who answered (recorded in the execution record).
    pub operator: String,
    /// From which ground station.
    pub station: String,
}

/// Reply to `answer`: whether it was applied, or why not. Exactly one answer per user task
/// is applied; every other is refused with the reason.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnswerReply {
    /// The goal id.
    pub goal_id: String,
    /// The answer closed the task.
    pub applied: bool,
    /// Why it was refused (unknown or closed task, missing field, wrong type, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// Reply to `cancel`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum CancelReply {
    /// The cancel was taken; `CANCELING` then a terminal status follow on `status`.
    Accepted,
    /// The server does not know the goal.
    UnknownGoal,
    /// The goal had already ended.
    Terminated,
}

/// Reply to `state`: a snapshot, never blocking.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateReply {
    /// The goal id.
    pub goal_id: String,
    /// Its status (`UNKNOWN` if the server never saw it).
    pub status: Status,
    /// The result once terminal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<ResultMsg>,
    /// The goal's last status sequence number.
    pub seq: u64,
}

/// On `…/status`: one transition.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StatusMsg {
    /// The goal id.
    pub goal_id: String,
    /// The new status.
    pub status: Status,
    /// Per goal, one more for each transition.
    pub seq: u64,
    /// Free text (the error code when `ABORTED`).
    #[serde(default)]
    pub text: String,
}

/// On `…/feedback`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeedbackMsg {
    /// The goal id.
    pub goal_id: String,
    /// Progress, 0–100, if the activity knows it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub progress_pct: Option<f64>,
    /// Activity-specific fields (catalogue `feedback`).
    #[serde(default)]
    pub fields: Fields,
}

/// On `…/result`, in `state` and goal replies: how a goal ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResultMsg {
    /// The goal id.
    pub goal_id: String,
    /// `SUCCEEDED`, `CANCELED` or `ABORTED`.
    pub status: Status,
    /// Outputs (when `SUCCEEDED`; partial effects may be reported when `CANCELED`).
    #[serde(default)]
    pub outputs: Fields,
    /// The failure (when `ABORTED`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<Failure>,
}

/// An activity's failure: a code the model's error boundaries catch, and a message for people.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Failure {
    /// Error code, e.g. `TOOL_STUCK` (declared in the catalogue).
    pub code: String,
    /// Human-readable detail.
    #[serde(default)]
    pub message: String,
}

/// On `<root>/tm/<source>/<channel>`: one telemetry sample, a set of named values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Telemetry {
    /// Mission time of the sample, milliseconds since the epoch.
    pub mission_ms: i64,
    /// Values by data key (`battery_soc_pct`, …).
    pub values: Fields,
}

/// `get <root>/fleet/<to>/message/<key>` payload: a message along a message flow, sent by
/// the executive of pool `from` to the executive of pool `to` (`docs/protocol.md` §8c). Sent
/// again until a reply gives its verdict; the key makes a repetition harmless.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Letter {
    /// `<sender's mission id>.m<number>`: unique per sender, the same on every resend (also
    /// the last key chunk).
    pub key: String,
    /// The sending pool's id.
    pub from: String,
    /// The receiving pool's id.
    pub to: String,
    /// The message flow's id (the same model on both sides).
    pub flow: String,
    /// The message name.
    pub name: String,
    /// The sender's value of the message's correlation key, if the message has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation: Option<Value>,
    /// The message's fields.
    pub payload: Fields,
}

/// Reply to a [`Letter`]: committed by its receiver (now, or before: a resend), or refused
/// with the reason; either is final and the sender stops sending.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LetterReply {
    /// The letter's key.
    pub key: String,
    /// The receiver committed it.
    pub applied: bool,
    /// Why it was refused (no such flow, its target does not wait for it, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// The encoding schema suffix for a payload type, e.g. `trace.goal/1`.
pub fn schema(kind: &str) -> String {
    format!("trace.{kind}/{VERSION}")
}

/// A payload that does not parse: named by what it should have been and why.
#[derive(Debug, thiserror::Error)]
#[error("malformed {what} payload on {key}: {reason}")]
pub struct Malformed {
    /// What was expected (`goal`, `status`, …).
    pub what: &'static str,
    /// The key it arrived on.
    pub key: String,
    /// The parse error.
    pub reason: String,
}

/// Parses a payload of type `T`, naming the key and the problem when it fails. Payloads over
/// `limit` bytes are refused before parsing.
pub fn parse<T: serde::de::DeserializeOwned>(
    what: &'static str,
    key: &str,
    bytes: &[u8],
) -> Result<T, Malformed> {
    const LIMIT: usize = 4 << 20;
    if bytes.len() > LIMIT {
        return Err(Malformed {
            what,
            key: key.to_owned(),
            reason: format!("{} bytes is over the {LIMIT}-byte limit", bytes.len()),
        });
    }
    serde_json::from_slice(bytes).map_err(|e| Malformed {
        what,
        key: key.to_owned(),
        reason: e.to_string(),
    })
}

/// One mission clock report (`<root>/tm/<source>/clock`): the system's mission time when it
/// published, and how many mission ms pass per wall ms (0: the clock is held).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockReading {
    /// Mission time, ms since the epoch.
    pub mission_ms: i64,
    /// Mission ms per wall ms.
    pub speed: f64,
}

/// Why a clock report is not believed (`docs/protocol.md` §5.4).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ClockRefusal {
    /// The speed is negative, infinite or not a number.
    #[error("speed {0} is not a finite number ≥ 0")]
    BadSpeed(f64),
    /// Mission time went backwards.
    #[error("mission time went back from {last} to {next} ms")]
    Backwards {
        /// The last report believed.
        last: i64,
        /// This report.
        next: i64,
    },
    /// Mission time moved further than the declared speed allows in the wall time that passed.
    #[error(
        "mission time jumped {jump} ms ahead in {wall_ms} ms of wall time; at speed {speed} at \
         most {allowed} ms are plausible"
    )]
    Jump {
        /// How far this report is ahead of the last one believed.
        jump: i64,
        /// Wall time since the last report believed arrived.
        wall_ms: u128,
        /// The faster of the two reports' speeds.
        speed: f64,
        /// The largest advance believed.
        allowed: i64,
    },
}

/// The plausibility rule for a mission clock report, a pure function so any side can apply
/// it: `last` is the last report believed (`None`: this is the first, believed as it is),
/// `wall` the wall time since `last` arrived, `slack` the wall-time tolerance for delivery
/// jitter. A report is believed when its speed is a finite number ≥ 0, its mission time is
/// not before `last`'s (monotonic), and it is at most `(wall + slack) × speed` ahead of
/// `last`, with the faster of the two speeds (a clock that starts runs at its new speed).
pub fn check_clock(
    last: Option<ClockReading>,
    next: ClockReading,
    wall: std::time::Duration,
    slack: std::time::Duration,
) -> Result<(), ClockRefusal> {
    if !next.speed.is_finite() || next.speed < 0.0 {
        return Err(ClockRefusal::BadSpeed(next.speed));
    }
    let Some(last) = last else {
        return Ok(());
    };
    if next.mission_ms < last.mission_ms {
        return Err(ClockRefusal::Backwards {
            last: last.mission_ms,
            next: next.mission_ms,
        });
    }
    let speed = last.speed.max(next.speed);
    let allowed = ((wall + slack).as_secs_f64() * 1000.0 * speed).min(i64::MAX as f64) as i64;
    let jump = next.mission_ms.saturating_sub(last.mission_ms);
    if jump > allowed {
        return Err(ClockRefusal::Jump {
            jump,
            wall_ms: wall.as_millis(),
            speed,
            allowed,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_round_trip_and_garbage_is_named() {
        let r = ResultMsg {
            goal_id: "m.1.2.1".into(),
            status: Status::Aborted,
            outputs: Fields::new(),
            error: Some(Failure {
                code: "TOOL_STUCK".into(),
                message: "tool stuck at 12 cm".into(),
            }),
        };
        let text = serde_json::to_string(&r).unwrap();
        assert!(text.contains(r#""status":"ABORTED""#), "{text}");
        assert_eq!(
            parse::<ResultMsg>("result", "k", text.as_bytes()).unwrap(),
            r
        );
        let e = parse::<ResultMsg>("result", "trace/act/s/a/result", b"\xff{").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("malformed result payload on trace/act/s/a/result")
        );
        let e = parse::<Goal>("goal", "k", br#"{"goal_id":"g","extra":1}"#).unwrap_err();
        assert!(e.reason.contains("unknown field"), "{e}");
    }

    #[test]
    fn clock_reports_are_monotonic_and_bounded_by_their_speed() {
        use std::time::Duration;
        let at = |mission_ms, speed| ClockReading { mission_ms, speed };
        let slack = Duration::from_millis(1000);
        let second = Duration::from_secs(1);
        assert_eq!(check_clock(None, at(5, 1.0), second, slack), Ok(()));
        assert!(matches!(
            check_clock(None, at(5, f64::NAN), second, slack),
            Err(ClockRefusal::BadSpeed(_))
        ));
        assert!(matches!(
            check_clock(None, at(5, -1.0), second, slack),
            Err(ClockRefusal::BadSpeed(_))
        ));
        // One second of wall time at speed 1: up to 2 s ahead (with the slack), never back.
        let last = Some(at(10_000, 1.0));
        assert_eq!(check_clock(last, at(10_000, 1.0), second, slack), Ok(()));
        assert_eq!(check_clock(last, at(12_000, 1.0), second, slack), Ok(()));
        assert!(matches!(
            check_clock(last, at(9_999, 1.0), second, slack),
            Err(ClockRefusal::Backwards {
                last: 10_000,
                next: 9_999
            })
        ));
        // An hour ahead is refused, and the reason says how much was plausible.
        let e = check_clock(last, at(10_000 + 3_600_000, 1.0), second, slack).unwrap_err();
        assert!(matches!(e, ClockRefusal::Jump { allowed: 2000, .. }), "{e}");
        assert!(e.to_string().contains("at most 2000 ms"), "{e}");
        // A held clock (speed 0) that starts: bounded by the new speed.
        let held = Some(at(10_000, 0.0));
        assert_eq!(
            check_clock(held, at(10_000 + 150_000, 100.0), second, slack),
            Ok(())
        );
        assert!(check_clock(held, at(10_000 + 250_000, 100.0), second, slack).is_err());
    }
}
