//! The executive's side of the activity protocol: a [`Connector`] that sends goals to one
//! server over Zenoh and turns its status, feedback and results into [`Report`]s.
//!
//! Presence comes from the per-action liveliness tokens: a goal for an action nobody serves
//! waits for the token, a server that vanishes while goals run gets `grace` to come back
//! before those goals fail with `CONNECTOR_LOST`, and when it comes back every goal in flight
//! is reconciled with a `state` query — so a result published while the link was down is
//! recovered rather than lost.
//!
//! Every wait has an end ([`Limits`]): a goal a serving server never acknowledges is sent
//! again with backoff and fails with `NOT_ACCEPTED` after `accept_within_ms`; an answer that
//! cannot be understood (a reply that does not parse, a terminal status without its result, a
//! result whose status is not terminal) makes the connector ask again — the goal for a goal
//! not yet acknowledged, `state` otherwise — with backoff, and after `unreadable_max` such
//! answers the goal fails with `PROTOCOL_ERROR`. Data is typed at the door: results, feedback
//! and telemetry are checked against the catalogue, clock reports for plausibility, and
//! whatever is refused is logged and counted ([`crate::drops`]) instead of reaching the engine.
//!
//! A connector configured with `answers` talks to ground stations instead: goals and cancels
//! go to every station, and operators' answers arrive as `answer` queries that are checked
//! (open task, form, then the engine) and answered with the verdict — the first valid answer
//! wins, and the other stations are told who answered.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use crate::replies::replies;
use connector_api::contract::{BoxFuture, Dropped, Limits};
use connector_api::wire::{
    self, Answer, AnswerReply, CancelReply, CancelRequest, ClockReading, FeedbackMsg, Goal,
    GoalReply, ResultMsg, StateReply, StatusMsg, Telemetry, codes,
};
use connector_api::{
    ActionSpec, Catalogue, Channel, Command, Connector, ConnectorConfig, ConnectorError, Fields,
    Keys, Report, Reports, Status, Verdict,
};
use serde_json::Value;
use tokio::sync::{Notify, watch};
use zenoh::Session;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, Query, QueryTarget, Queryable};
use zenoh::sample::{Sample, SampleKind};

use crate::codec::{encoding, json};
use crate::drops::{Drops, Reason};

/// How a Zenoh connector behaves.
#[derive(Clone, Debug)]
pub struct ClientOptions {
    /// Key builder (root).
    pub keys: Keys,
    /// The connector's configuration (server, data keys, grace period).
    pub config: ConnectorConfig,
    /// Who we are, sent with every goal (for the server's log).
    pub client: String,
    /// The mission id every goal id starts with (answers are received for these only).
    pub mission: String,
    /// How long `catalogue()` waits for the server to appear.
    pub catalogue_wait: Duration,
    /// How long one goal, state or cancel query may take.
    pub query_timeout: Duration,
}

#[derive(Debug)]
struct Flight {
    command: Command,
    /// The server has acknowledged the goal (or had it before a restart).
    acked: bool,
    /// The task sending the goal until it is acknowledged; notified to send at once (the
    /// server appeared) or to stop.
    sending: Option<Arc<Notify>>,
    /// How many times the goal was sent since its `NOT_ACCEPTED` deadline was armed.
    sends: u32,
    /// The `NOT_ACCEPTED` deadline runs (armed at the first send to a serving server).
    deadline_armed: bool,
    /// A task is asking the server again about an answer it could not understand.
    asking: bool,
    /// Answers about the goal not understood since the last one that was.
    unreadable: u32,
}

/// How a goal that is no longer in flight ended here, to tell a late or repeated message
/// about it from a message about a goal never run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ended {
    /// Its outcome was reported from the result stream (or a failure decided here).
    Reported,
    /// Its outcome was reported from a goal or state reply: the same result may still arrive
    /// on the stream.
    FromReply,
    /// The executive aborted it: a `CANCELED` status and result are still to come.
    Aborted,
}

/// Goals remembered as ended, so late messages about them are recognised.
const ENDED_KEPT: usize = 4096;

/// A user task no longer open.
struct Closed {
    /// Why, for the stations whose answers come late.
    why: String,
    /// The answer applied (`operator@station` and its fields): the same answer sent again —
    /// a station that never heard the verdict — is confirmed, not refused.
    applied: Option<(String, Fields)>,
}

#[derive(Default)]
struct State {
    flights: HashMap<String, Flight>,
    /// Per served action, the liveliness tokens announcing it (one per server instance).
    alive: HashMap<String, HashSet<String>>,
    /// Per action: bumped on every appearance, so a pending grace timer knows it is stale.
    generation: HashMap<String, u64>,
    /// Cancels not yet answered: goal id → action.
    cancels: HashMap<String, String>,
    last_data: HashMap<String, Value>,
    /// Ground stations: why a user task is no longer open, for refusing late answers.
    closed: HashMap<String, Closed>,
    /// Ground stations: answers being decided (their replies are sent before closing).
    answering: Vec<tokio::task::JoinHandle<()>>,
    /// Goals that ended recently, and how (bounded: the oldest are forgotten).
    ended: HashMap<String, Ended>,
    ended_order: VecDeque<String>,
    /// The last mission clock report believed, and when it arrived.
    clock: Option<(ClockReading, Instant)>,
}

impl State {
    fn served(&self, action: &str) -> bool {
        self.alive.get(action).is_some_and(|t| !t.is_empty())
    }

    fn end(&mut self, goal_id: &str, how: Ended) {
        if self.ended.insert(goal_id.to_owned(), how).is_none() {
            self.ended_order.push_back(goal_id.to_owned());
            if self.ended_order.len() > ENDED_KEPT
                && let Some(old) = self.ended_order.pop_front()
            {
                self.ended.remove(&old);
            }
        }
    }

    /// Takes a goal out of flight (its outcome is about to be reported); `None` if another
    /// path already did.
    fn land(&mut self, goal_id: &str, how: Ended) -> Option<Flight> {
        let flight = self.flights.remove(goal_id)?;
        if let Some(wake) = &flight.sending {
            wake.notify_one();
        }
        self.end(goal_id, how);
        Some(flight)
    }
}

struct Shared {
    opts: ClientOptions,
    limits: Limits,
    session: Session,
    reports: Reports,
    rt: tokio::runtime::Handle,
    state: Mutex<State>,
    catalogue: Mutex<Option<Catalogue>>,
    drops: Drops,
    /// Answers are decided one at a time, so a second answer to a task sees it closed (and by
    /// whom) rather than racing the first to the executive.
    answer_turn: tokio::sync::Mutex<()>,
}

/// A connector to one server over the Zenoh activity protocol.
pub struct ZenohConnector {
    shared: Arc<Shared>,
    subscribers: Vec<Subscriber<()>>,
    answers: Option<Queryable<()>>,
}

fn payload(sample: &Sample) -> Vec<u8> {
    sample.payload().to_bytes().into_owned()
}

/// A status as it is written on the wire (`EXECUTING`).
fn status_name(status: Status) -> String {
    match serde_json::to_value(status) {
        Ok(Value::String(s)) => s,
        _ => format!("{status:?}"),
    }
}

/// The goal id a payload that does not parse still names, if any (to attribute garbage).
fn goal_id_in(bytes: &[u8]) -> String {
    serde_json::from_slice::<Value>(bytes)
        .ok()
        .and_then(|v| v.get("goal_id")?.as_str().map(str::to_owned))
        .unwrap_or_default()
}

/// Which stream a message came on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stream {
    Status,
    Feedback,
    Result,
}

impl Stream {
    fn name(self) -> &'static str {
        match self {
            Stream::Status => "status",
            Stream::Feedback => "feedback",
            Stream::Result => "result",
        }
    }
}

/// Where a result came from: the result stream, or a goal or state reply (which we asked for).
#[derive(Clone, Copy, Debug)]
enum Source<'k> {
    Stream(&'k str),
    Reply(&'k str),
}

impl Source<'_> {
    fn key(&self) -> &str {
        match self {
            Source::Stream(k) | Source::Reply(k) => k,
        }
    }
}

/// What one goal query achieved.
#[derive(Debug)]
enum Sent {
    /// The goal was acknowledged, or ended (reported, or handed to the asking task).
    Settled,
    /// No usable answer: send it again after a pause (the reason, for the log).
    Unanswered(String),
}

/// What one state query achieved.
#[derive(Debug, PartialEq, Eq)]
enum Asked {
    /// Understood: the goal runs, or its outcome was reported.
    Settled,
    /// Not understood (counted): ask again after a pause.
    Again,
}

/// How a result ends its goal.
enum Outcome {
    Done(connector_api::Fields),
    Failed(String, String),
    Canceled,
}

impl Shared {
    fn server(&self) -> &str {
        self.opts.config.server()
    }

    fn name(&self) -> &str {
        &self.opts.config.name
    }

    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn spec(&self, action: &str) -> Option<ActionSpec> {
        self.catalogue
            .lock()
            .ok()
            .and_then(|c| c.as_ref()?.action(action).cloned())
    }

    /// Goal ids of this mission start with `<mission>.`; others belong to another executive
    /// sharing the server, and their messages are none of our business.
    fn ours(&self, goal_id: &str) -> bool {
        goal_id
            .strip_prefix(self.opts.mission.as_str())
            .is_some_and(|rest| rest.starts_with('.'))
    }

    /// Queries reach every server instance (ground stations) or the best-matching one.
    fn target(&self) -> QueryTarget {
        if self.opts.config.answers {
            QueryTarget::All
        } else {
            QueryTarget::BestMatching
        }
    }

    fn report(&self, r: Report) {
        if self.reports.send(r).is_err() {
            tracing::debug!("report dropped: the executive is stopping");
        }
    }

    fn fail(&self, goal_id: &str, code: &str, message: String) {
        // A system's own error codes are mission events (the record has them); protocol
        // failures are the operator's concern.
        if codes::ALL.contains(&code) {
            tracing::warn!(connector = self.name(), goal_id, code, %message, "goal failed");
        } else {
            tracing::info!(connector = self.name(), goal_id, code, %message, "goal failed");
        }
        self.report(Report::Failed {
            goal_id: goal_id.to_owned(),
            code: code.to_owned(),
            message,
        });
    }

    /// Takes the goal out of flight and fails it, unless another path ended it first.
    fn land_failed(&self, goal_id: &str, code: &str, message: String) {
        if self.state().land(goal_id, Ended::Reported).is_some() {
            self.fail(goal_id, code, message);
        }
    }

    /// A message on a stream names a goal that is not in flight: expected after the goal
    /// ended here (a status after the result, anything after an abort), otherwise dropped.
    fn stray(&self, key: &str, stream: Stream, goal_id: &str) {
        if !self.ours(goal_id) {
            return tracing::debug!(
                key,
                goal_id,
                "{} of another mission's goal ignored",
                stream.name()
            );
        }
        let ended = {
            let mut s = self.state();
            let ended = s.ended.get(goal_id).copied();
            if ended == Some(Ended::FromReply) && stream == Stream::Result {
                // The stream's copy of a result already taken from a reply; a third is not.
                s.ended.insert(goal_id.to_owned(), Ended::Reported);
            }
            ended
        };
        let what = stream.name();
        match (ended, stream) {
            (Some(Ended::Aborted), _)
            | (Some(Ended::Reported | Ended::FromReply), Stream::Status)
            | (Some(Ended::FromReply), Stream::Result) => {
                tracing::debug!(key, goal_id, "{what} of an ended goal ignored");
            }
            (Some(_), Stream::Result) => self.drops.drop(
                Reason::Duplicate,
                key,
                what,
                goal_id,
                "the goal's outcome was already reported",
            ),
            (Some(_), _) => self.drops.drop(
                Reason::Late,
                key,
                what,
                goal_id,
                "feedback after the goal's outcome was reported",
            ),
            (None, _) => self.drops.drop(
                Reason::UnknownGoal,
                key,
                what,
                goal_id,
                "no goal with this id is in flight here",
            ),
        }
    }

    /// A goal ended (result stream, goal or state reply): validated, then reported once (the
    /// flight is removed). A result that cannot end a goal (a non-terminal status) is refused
    /// and the server asked again. Returns whether the result was understood. A ground
    /// station's task closes only through an answer query, never through a published result.
    fn deliver(self: &Arc<Self>, r: ResultMsg, source: Source<'_>) -> bool {
        if self.opts.config.answers {
            tracing::debug!(
                goal_id = r.goal_id,
                "ground result ignored: answers close tasks"
            );
            return true;
        }
        let key = source.key();
        // The lock is released before the match: `stray` takes it again.
        let in_flight = self
            .state()
            .flights
            .get(&r.goal_id)
            .map(|f| f.command.action.clone());
        let action = match in_flight {
            Some(action) => action,
            None => {
                match source {
                    Source::Stream(key) => self.stray(key, Stream::Result, &r.goal_id),
                    Source::Reply(key) => {
                        tracing::debug!(key, goal_id = r.goal_id, "reply for an ended goal");
                    }
                }
                return true;
            }
        };
        let outcome = match r.status {
            Status::Succeeded => match self.spec(&action) {
                Some(spec) => {
                    let missing = spec.missing_outputs(&r.outputs);
                    if !missing.is_empty() {
                        let list: Vec<String> = missing
                            .iter()
                            .map(|(path, t)| format!("`{path}` ({t})"))
                            .collect();
                        Outcome::Failed(
                            codes::TYPE_MISMATCH.to_owned(),
                            format!(
                                "the SUCCEEDED result of `{action}` lacks outputs its catalogue \
                                 entry declares: {}",
                                list.join(", ")
                            ),
                        )
                    } else if let Err(e) = spec.check_result(&r.outputs) {
                        Outcome::Failed(
                            codes::TYPE_MISMATCH.to_owned(),
                            format!(
                                "the result of `{action}` does not match its catalogue entry: {e}"
                            ),
                        )
                    } else {
                        Outcome::Done(r.outputs)
                    }
                }
                None => Outcome::Done(r.outputs),
            },
            Status::Aborted => match r.error {
                Some(f) if !f.code.trim().is_empty() => Outcome::Failed(f.code, f.message),
                other => {
                    let detail = other
                        .map(|f| f.message)
                        .filter(|m| !m.is_empty())
                        .map_or_else(String::new, |m| format!(": {m}"));
                    Outcome::Failed(
                        codes::ABORTED.to_owned(),
                        format!(
                            "`{}` aborted the goal without an error code{detail}",
                            self.server()
                        ),
                    )
                }
            },
            Status::Canceled => Outcome::Canceled,
            Status::Rejected => Outcome::Failed(
                codes::REJECTED.to_owned(),
                r.error
                    .map(|f| f.message)
                    .filter(|m| !m.is_empty())
                    .unwrap_or_else(|| format!("`{}` rejected the goal", self.server())),
            ),
            other @ (Status::Accepted
            | Status::Executing
            | Status::Canceling
            | Status::Unknown
            | Status::Lost) => {
                let why = format!(
                    "a result must be SUCCEEDED, CANCELED, ABORTED or REJECTED, not {}",
                    status_name(other)
                );
                self.drops
                    .drop(Reason::InvalidStatus, key, "result", &r.goal_id, &why);
                match source {
                    // Anyone may publish on a stream: what it says does not count against
                    // the server; the server is asked instead.
                    Source::Stream(_) => self.recheck(&r.goal_id),
                    Source::Reply(_) => {
                        self.not_understood(&r.goal_id, why);
                    }
                }
                return false;
            }
        };
        let how = match source {
            Source::Stream(_) => Ended::Reported,
            Source::Reply(_) => Ended::FromReply,
        };
        if self.state().land(&r.goal_id, how).is_none() {
            return true;
        }
        match outcome {
            Outcome::Done(outputs) => self.report(Report::Done {
                goal_id: r.goal_id,
                outputs,
            }),
            Outcome::Failed(code, message) => self.fail(&r.goal_id, &code, message),
            Outcome::Canceled => self.report(Report::Canceled { goal_id: r.goal_id }),
        }
        true
    }

    /// An answer about a goal could not be understood: counted, and after
    /// `unreadable_max` of them the goal fails with `PROTOCOL_ERROR`; until then the server
    /// is asked again (`state` once the goal is acknowledged, else the goal's sender goes
    /// on). Returns whether the goal was given up.
    fn not_understood(self: &Arc<Self>, goal_id: &str, why: String) -> bool {
        let (tries, acked, sending) = {
            let mut s = self.state();
            let Some(f) = s.flights.get_mut(goal_id) else {
                return true;
            };
            f.unreadable += 1;
            (f.unreadable, f.acked, f.sending.is_some())
        };
        let max = self.limits.unreadable_max.max(1);
        if tries >= max {
            self.land_failed(
                goal_id,
                codes::PROTOCOL_ERROR,
                format!(
                    "{tries} answers of `{}` about the goal could not be understood; the last: \
                     {why}",
                    self.server()
                ),
            );
            return true;
        }
        tracing::warn!(
            connector = self.name(),
            goal_id,
            attempt = tries,
            of = max,
            reason = %why,
            "answer not understood; asking the server again"
        );
        if acked {
            self.start_asking(goal_id);
        } else if !sending {
            self.start_sending(goal_id);
        }
        false
    }

    /// Something on a stream about a goal could not be used: the server is asked for the goal's
    /// `state` (once acknowledged), without counting it against `unreadable_max` — what any
    /// process can publish must not end a goal (§4.4).
    fn recheck(self: &Arc<Self>, goal_id: &str) {
        if self.state().flights.get(goal_id).is_some_and(|f| f.acked) {
            self.start_asking(goal_id);
        }
    }

    /// An answer about the goal was understood: the count of those that were not restarts.
    fn understood(&self, goal_id: &str) {
        if let Some(f) = self.state().flights.get_mut(goal_id) {
            f.unreadable = 0;
        }
    }

    /// Starts sending a goal until it is acknowledged (or wakes the sender to send at once).
    fn start_sending(self: &Arc<Self>, goal_id: &str) {
        let wake = {
            let mut s = self.state();
            let Some(action) = s.flights.get(goal_id).map(|f| f.command.action.clone()) else {
                return;
            };
            let served = s.served(&action);
            let Some(f) = s.flights.get_mut(goal_id) else {
                return;
            };
            if f.acked || !served {
                return;
            }
            if let Some(wake) = &f.sending {
                wake.notify_one();
                return;
            }
            let wake = Arc::new(Notify::new());
            f.sending = Some(Arc::clone(&wake));
            wake
        };
        self.rt
            .spawn(Arc::clone(self).send_loop(goal_id.to_owned(), wake));
    }

    /// Sends a goal, and again after each pause of the backoff schedule (or at once when
    /// woken: the server appeared), while it is unacknowledged and its action served.
    async fn send_loop(self: Arc<Shared>, goal_id: String, wake: Arc<Notify>) {
        let mut pauses = self.limits.pauses();
        loop {
            let (command, attempt, arm) = {
                let mut s = self.state();
                let served = s
                    .flights
                    .get(&goal_id)
                    .is_some_and(|f| s.served(&f.command.action));
                let Some(f) = s.flights.get_mut(&goal_id) else {
                    return;
                };
                if f.acked || !served {
                    // Acknowledged, or nobody serves it now: the token's return sends it again.
                    f.sending = None;
                    return;
                }
                f.sends += 1;
                let arm = !f.deadline_armed;
                f.deadline_armed = true;
                (f.command.clone(), f.sends, arm)
            };
            if arm {
                self.arm_accept_deadline(&command);
            }
            if attempt > 1 {
                tracing::warn!(
                    connector = self.name(),
                    goal_id,
                    action = command.action,
                    attempt,
                    "goal not acknowledged yet; sent again"
                );
            }
            match self.send_once(&command).await {
                Sent::Settled => {
                    if let Some(f) = self.state().flights.get_mut(&goal_id) {
                        f.sending = None;
                    }
                    return;
                }
                Sent::Unanswered(why) => {
                    tracing::debug!(goal_id, attempt, why, "goal not acknowledged");
                }
            }
            let pause = pauses
                .next()
                .unwrap_or(Duration::from_millis(self.limits.retry_max_ms));
            tokio::select! {
                () = tokio::time::sleep(pause) => {}
                () = wake.notified() => {}
            }
        }
    }

    /// `accept_within_ms` after its first send, a goal the server (still serving the action)
    /// has not acknowledged fails with `NOT_ACCEPTED`. If nobody serves the action by then,
    /// the grace period decides instead, and the next send arms a new deadline.
    fn arm_accept_deadline(self: &Arc<Self>, command: &Command) {
        let me = Arc::clone(self);
        let goal_id = command.goal_id.clone();
        let action = command.action.clone();
        let within = Duration::from_millis(self.limits.accept_within_ms);
        self.rt.spawn(async move {
            tokio::time::sleep(within).await;
            let sends = {
                let mut s = me.state();
                let served = s.served(&action);
                match s.flights.get_mut(&goal_id) {
                    Some(f) if !f.acked && served => f.sends,
                    Some(f) if !f.acked => {
                        f.deadline_armed = false;
                        f.sends = 0;
                        return;
                    }
                    _ => return,
                }
            };
            me.land_failed(
                &goal_id,
                codes::NOT_ACCEPTED,
                format!(
                    "`{}` serves `{action}` but did not accept the goal within {} ms (sent {sends} \
                     times)",
                    me.server(),
                    within.as_millis()
                ),
            );
        });
    }

    /// Sends a goal once (the server answers a repeat with the goal's current status).
    async fn send_once(self: &Arc<Self>, command: &Command) -> Sent {
        let key = self.opts.keys.goal(
            self.server(),
            &command.action,
            Channel::Goal,
            &command.goal_id,
        );
        let goal = Goal {
            goal_id: command.goal_id.clone(),
            fields: command.fields.clone(),
            client: self.opts.client.clone(),
        };
        let replies = match self
            .session
            .get(&key)
            .payload(json(&goal))
            .encoding(encoding("goal"))
            .target(self.target())
            .consolidation(ConsolidationMode::None)
            .timeout(self.opts.query_timeout)
            .with(replies())
            .await
        {
            Ok(r) => r,
            Err(e) => return Sent::Unanswered(format!("the goal query could not be sent: {e}")),
        };
        let Ok(reply) = replies.recv_async().await else {
            // Nobody answered (routing not converged yet, or the server just left).
            return Sent::Unanswered("nobody answered the goal query".to_owned());
        };
        enum Bad {
            Unreadable(String),
            Refused(String),
        }
        let reply = match reply.result() {
            Ok(sample) => wire::parse::<GoalReply>("goal reply", &key, &payload(sample))
                .map_err(|e| Bad::Unreadable(e.to_string())),
            Err(err) => Err(Bad::Refused(
                String::from_utf8_lossy(&err.payload().to_bytes()).into_owned(),
            )),
        };
        if self.opts.config.answers {
            // Every station replies; the task is open if any station took it.
            let mut replies_left = Vec::new();
            while let Ok(more) = replies.recv_async().await {
                if let Ok(sample) = more.result()
                    && let Ok(r) = wire::parse::<GoalReply>("goal reply", &key, &payload(sample))
                {
                    replies_left.push(r);
                }
            }
            if let Some(taken) = replies_left
                .into_iter()
                .find(|r| r.status != Status::Rejected && r.goal_id == command.goal_id)
            {
                return self.on_goal_reply(&key, command, taken);
            }
        }
        match reply {
            Ok(r) => self.on_goal_reply(&key, command, r),
            Err(Bad::Refused(text)) if text == "Timeout" => {
                Sent::Unanswered("the goal query timed out".to_owned())
            }
            Err(Bad::Refused(text)) => {
                self.land_failed(
                    &command.goal_id,
                    codes::REJECTED,
                    format!("`{}` refused the goal: {text}", self.server()),
                );
                Sent::Settled
            }
            Err(Bad::Unreadable(why)) => self.unreadable_goal_reply(&key, command, why),
        }
    }

    fn unreadable_goal_reply(self: &Arc<Self>, key: &str, command: &Command, why: String) -> Sent {
        self.drops.drop(
            Reason::UnreadableReply,
            key,
            "goal reply",
            &command.goal_id,
            &why,
        );
        if self.not_understood(&command.goal_id, why.clone()) {
            Sent::Settled
        } else {
            Sent::Unanswered(why)
        }
    }

    fn on_goal_reply(self: &Arc<Self>, key: &str, command: &Command, r: GoalReply) -> Sent {
        if r.goal_id != command.goal_id {
            let why = format!("the reply names goal `{}`", r.goal_id);
            return self.unreadable_goal_reply(key, command, why);
        }
        match r.status {
            Status::Rejected => {
                self.land_failed(
                    &r.goal_id,
                    codes::REJECTED,
                    r.reason.unwrap_or_else(|| "rejected".to_owned()),
                );
                Sent::Settled
            }
            Status::Unknown | Status::Lost => {
                let why = format!("a goal reply cannot say {}", status_name(r.status));
                self.unreadable_goal_reply(key, command, why)
            }
            s if s.is_terminal() => {
                // The server took the goal, and it has ended already.
                self.acked(&r.goal_id);
                if self.opts.config.answers {
                    return Sent::Settled;
                }
                match r.result {
                    Some(result) if result.goal_id == r.goal_id && result.status == s => {
                        self.deliver(result, Source::Reply(key));
                    }
                    other => {
                        let why = match other {
                            Some(res) => format!(
                                "a {} goal reply carries the result of goal `{}` with status {}",
                                status_name(s),
                                res.goal_id,
                                status_name(res.status)
                            ),
                            None => format!("a {} goal reply without its result", status_name(s)),
                        };
                        self.drops.drop(
                            Reason::UnreadableReply,
                            key,
                            "goal reply",
                            &r.goal_id,
                            &why,
                        );
                        self.not_understood(&r.goal_id, why);
                    }
                }
                Sent::Settled
            }
            _ => {
                self.understood(&r.goal_id);
                self.acked(&r.goal_id);
                Sent::Settled
            }
        }
    }

    fn acked(&self, goal_id: &str) {
        let first = match self.state().flights.get_mut(goal_id) {
            Some(f) if !f.acked => {
                f.acked = true;
                if let Some(wake) = &f.sending {
                    wake.notify_one();
                }
                true
            }
            _ => false,
        };
        if first {
            self.report(Report::Accepted {
                goal_id: goal_id.to_owned(),
            });
        }
    }

    /// Asks the server what became of a goal. Ground stations are sent the goal again
    /// instead: any station may hold it, and a repeated goal is harmless.
    async fn reconcile(self: Arc<Shared>, command: Command) {
        if self.opts.config.answers {
            self.send_once(&command).await;
            return;
        }
        if self.ask_state(&command).await == Asked::Again {
            self.start_asking(&command.goal_id);
        }
    }

    /// Starts asking the server for a goal's state with backoff, until an answer is
    /// understood, the goal ends, or nobody serves the action (its return reconciles).
    fn start_asking(self: &Arc<Self>, goal_id: &str) {
        if self.opts.config.answers {
            return;
        }
        {
            let mut s = self.state();
            let Some(f) = s.flights.get_mut(goal_id) else {
                return;
            };
            if f.asking {
                return;
            }
            f.asking = true;
        }
        self.rt.spawn(Arc::clone(self).ask_loop(goal_id.to_owned()));
    }

    async fn ask_loop(self: Arc<Shared>, goal_id: String) {
        for pause in self.limits.pauses() {
            tokio::time::sleep(pause).await;
            let command = {
                let mut s = self.state();
                let served = s
                    .flights
                    .get(&goal_id)
                    .is_some_and(|f| s.served(&f.command.action));
                match s.flights.get_mut(&goal_id) {
                    Some(f) if served => f.command.clone(),
                    Some(f) => {
                        f.asking = false;
                        return;
                    }
                    None => return,
                }
            };
            if self.ask_state(&command).await == Asked::Settled {
                let mut s = self.state();
                match s.flights.get_mut(&goal_id) {
                    // Nothing new was misunderstood while we asked.
                    Some(f) if f.unreadable == 0 => {
                        f.asking = false;
                        return;
                    }
                    Some(_) => {}
                    None => return,
                }
            }
        }
    }

    /// One `state` query about an acknowledged goal.
    async fn ask_state(self: &Arc<Self>, command: &Command) -> Asked {
        let goal_id = command.goal_id.as_str();
        let key = self.opts.keys.goal(
            self.server(),
            &command.action,
            Channel::State,
            &command.goal_id,
        );
        let unreadable = |why: String| {
            self.drops
                .drop(Reason::UnreadableReply, &key, "state reply", goal_id, &why);
            self.not_understood(goal_id, why);
            Asked::Again
        };
        let replies = match self
            .session
            .get(&key)
            .consolidation(ConsolidationMode::None)
            .timeout(self.opts.query_timeout)
            .with(replies())
            .await
        {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!(key, error = %e, "state query not sent");
                self.not_understood(goal_id, format!("the state query could not be sent: {e}"));
                return Asked::Again;
            }
        };
        let Ok(reply) = replies.recv_async().await else {
            let served = self.state().served(&command.action);
            if !served {
                tracing::debug!(key, "no answer to the state query; waiting for the server");
                return Asked::Settled;
            }
            return unreadable("nobody answered the state query".to_owned());
        };
        let sample = match reply.result() {
            Ok(sample) => sample,
            Err(e) => {
                let text = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                return unreadable(format!("the server refused the state query: {text}"));
            }
        };
        let s = match wire::parse::<StateReply>("state reply", &key, &payload(sample)) {
            Ok(s) => s,
            Err(e) => return unreadable(e.to_string()),
        };
        if s.goal_id != command.goal_id {
            return unreadable(format!("the state reply names goal `{}`", s.goal_id));
        }
        match s.status {
            Status::Unknown => {
                self.land_failed(
                    goal_id,
                    codes::CONNECTOR_LOST,
                    format!(
                        "`{}` does not know goal `{goal_id}` of `{}`: it was lost",
                        self.server(),
                        command.action
                    ),
                );
                Asked::Settled
            }
            Status::Lost => unreadable("a state reply cannot say LOST".to_owned()),
            Status::Rejected if s.result.is_none() => {
                self.land_failed(
                    goal_id,
                    codes::REJECTED,
                    format!("`{}` reports the goal as rejected", self.server()),
                );
                Asked::Settled
            }
            status if status.is_terminal() => match s.result {
                Some(r) if r.goal_id == s.goal_id => {
                    if self.deliver(r, Source::Reply(&key)) {
                        Asked::Settled
                    } else {
                        Asked::Again
                    }
                }
                Some(r) => unreadable(format!(
                    "the state reply carries the result of goal `{}`",
                    r.goal_id
                )),
                None => unreadable(format!(
                    "a {} state reply without its result",
                    status_name(status)
                )),
            },
            status => {
                tracing::debug!(goal_id, status = ?status, "goal still running");
                self.understood(goal_id);
                self.acked(goal_id);
                Asked::Settled
            }
        }
    }

    async fn cancel(self: Arc<Shared>, goal_id: String, action: String, reason: Option<String>) {
        let key = self
            .opts
            .keys
            .goal(self.server(), &action, Channel::Cancel, &goal_id);
        let mut get = self.session.get(&key);
        if let Some(reason) = reason {
            get = get
                .payload(json(&CancelRequest { reason }))
                .encoding(encoding("cancel"));
        }
        let replies = match get
            .target(self.target())
            .consolidation(ConsolidationMode::None)
            .timeout(self.opts.query_timeout)
            .with(replies())
            .await
        {
            Ok(r) => r,
            Err(e) => return tracing::warn!(key, error = %e, "cancel not sent"),
        };
        // Ground stations all reply; any other server once.
        while let Ok(reply) = replies.recv_async().await {
            let sample = match reply.result() {
                Ok(sample) => sample,
                Err(e) => {
                    let text = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                    self.drops.drop(
                        Reason::UnreadableReply,
                        &key,
                        "cancel reply",
                        &goal_id,
                        &format!("the server refused the cancel: {text}"),
                    );
                    continue;
                }
            };
            self.state().cancels.remove(&goal_id);
            match wire::parse::<CancelReply>("cancel reply", &key, &payload(sample)) {
                Ok(r) => tracing::info!(goal_id, reply = ?r, "cancel answered"),
                Err(e) => self.drops.drop(
                    Reason::UnreadableReply,
                    &key,
                    "cancel reply",
                    &goal_id,
                    &e.to_string(),
                ),
            }
        }
    }

    /// `…/answer/<goal_id>` from a ground station: replies with the verdict.
    async fn on_answer(self: Arc<Shared>, query: Query) {
        let reply = self.answer(&query).await;
        match &reply.reason {
            None => tracing::info!(goal_id = reply.goal_id, "answer applied"),
            Some(reason) => tracing::info!(goal_id = reply.goal_id, reason, "answer refused"),
        }
        if let Err(e) = query
            .reply(query.key_expr().clone(), json(&reply))
            .encoding(encoding("answer_reply"))
            .await
        {
            tracing::warn!(error = %e, "answer reply failed");
        }
    }

    /// Checks an answer (payload, open task, form), hands it to the executive and waits for
    /// its verdict. The first applied answer closes the task at every other station.
    async fn answer(self: &Arc<Shared>, query: &Query) -> AnswerReply {
        let key = query.key_expr().as_str();
        let goal_id = Keys::last_chunk(key).to_owned();
        let refused = |reason: String| AnswerReply {
            goal_id: goal_id.clone(),
            applied: false,
            reason: Some(reason),
        };
        let bytes = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let a = match wire::parse::<Answer>("answer", key, &bytes) {
            Ok(a) => a,
            Err(e) => return refused(e.to_string()),
        };
        if a.goal_id != goal_id {
            return refused(format!(
                "the answer names goal `{}` but was sent for `{goal_id}`",
                a.goal_id
            ));
        }
        if a.operator.trim().is_empty() || a.station.trim().is_empty() {
            return refused("an answer must name its operator and station".to_owned());
        }
        let operator = format!("{}@{}", a.operator, a.station);
        let _turn = self.answer_turn.lock().await;
        let action = {
            let s = self.state();
            match (s.flights.get(&goal_id), s.closed.get(&goal_id)) {
                (Some(f), _) => f.command.action.clone(),
                (None, Some(c)) if c.applied == Some((operator.clone(), a.fields.clone())) => {
                    tracing::info!(goal_id, operator, "answer repeated; it was applied");
                    return AnswerReply {
                        goal_id,
                        applied: true,
                        reason: None,
                    };
                }
                (None, Some(c)) => {
                    return refused(format!("user task `{goal_id}` is closed: {}", c.why));
                }
                // Not a task of this run: the executive judges it from what it knows (a task
                // answered before it restarted).
                (None, None) => match self.opts.keys.action_of(key) {
                    Some(action) => action.to_owned(),
                    None => return refused(format!("no open user task has goal id `{goal_id}`")),
                },
            }
        };
        if let Some(Err(e)) = self.spec(&action).map(|s| s.check_result(&a.fields)) {
            return refused(format!(
                "the answer does not fit the form of `{action}`: {e}"
            ));
        }
        let (verdict, decided) = Verdict::new();
        self.report(Report::Answer {
            goal_id: goal_id.clone(),
            fields: a.fields.clone(),
            operator: operator.clone(),
            verdict,
        });
        match decided.await {
            Ok(Ok(())) => {
                let why = format!("answered by {operator}");
                {
                    let mut s = self.state();
                    s.land(&goal_id, Ended::Reported);
                    s.closed.insert(
                        goal_id.clone(),
                        Closed {
                            why: why.clone(),
                            applied: Some((operator.clone(), a.fields)),
                        },
                    );
                }
                // Every other station drops the task, then the winner hears it won.
                Arc::clone(self)
                    .cancel(goal_id.clone(), action, Some(why))
                    .await;
                AnswerReply {
                    goal_id,
                    applied: true,
                    reason: None,
                }
            }
            Ok(Err(reason)) => refused(reason),
            Err(_) => refused("the executive is stopping; the answer was not applied".to_owned()),
        }
    }

    /// Liveliness of one action changed.
    fn on_liveliness(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let Some(action) = self.opts.keys.action_of(key).map(str::to_owned) else {
            return;
        };
        let mut s = self.state();
        let generation = {
            let g = s.generation.entry(action.clone()).or_default();
            *g += 1;
            *g
        };
        match sample.kind() {
            SampleKind::Put => {
                tracing::info!(connector = self.name(), action, key, "action served");
                s.alive
                    .entry(action.clone())
                    .or_default()
                    .insert(key.to_owned());
                let (sent, unsent): (Vec<_>, Vec<_>) = s
                    .flights
                    .values()
                    .filter(|f| f.command.action == action)
                    .map(|f| (f.acked, f.command.clone()))
                    .partition(|(acked, _)| *acked);
                let cancels: Vec<String> = s
                    .cancels
                    .iter()
                    .filter(|(_, a)| **a == action)
                    .map(|(g, _)| g.clone())
                    .collect();
                drop(s);
                for (_, c) in unsent {
                    self.start_sending(&c.goal_id);
                }
                for (_, c) in sent {
                    self.rt.spawn(Arc::clone(self).reconcile(c));
                }
                for g in cancels {
                    self.rt
                        .spawn(Arc::clone(self).cancel(g, action.clone(), None));
                }
            }
            SampleKind::Delete => {
                tracing::warn!(
                    connector = self.name(),
                    action,
                    key,
                    "action no longer served"
                );
                if let Some(tokens) = s.alive.get_mut(&action) {
                    tokens.remove(key);
                }
                let running =
                    !s.served(&action) && s.flights.values().any(|f| f.command.action == action);
                drop(s);
                if running {
                    self.start_grace(action, generation);
                }
            }
        }
    }

    /// After the grace period, goals of an action still unserved fail with `CONNECTOR_LOST`.
    fn start_grace(self: &Arc<Shared>, action: String, generation: u64) {
        let me = Arc::clone(self);
        let grace = Duration::from_millis(self.opts.config.grace_ms);
        self.rt.spawn(async move {
            tokio::time::sleep(grace).await;
            let lost: Vec<String> = {
                let mut s = me.state();
                if s.served(&action) || s.generation.get(&action) != Some(&generation) {
                    return;
                }
                let ids: Vec<String> = s
                    .flights
                    .iter()
                    .filter(|(_, f)| f.command.action == action)
                    .map(|(id, _)| id.clone())
                    .collect();
                for id in &ids {
                    s.land(id, Ended::Reported);
                }
                ids
            };
            for id in lost {
                me.fail(
                    &id,
                    codes::CONNECTOR_LOST,
                    format!(
                        "`{}` stopped serving `{action}` and did not return within {} ms",
                        me.server(),
                        grace.as_millis()
                    ),
                );
            }
        });
    }

    fn on_status(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        let m = match wire::parse::<StatusMsg>("status", key, &bytes) {
            Ok(m) => m,
            Err(e) => {
                return self.drops.drop(
                    Reason::Garbage,
                    key,
                    "status",
                    &goal_id_in(&bytes),
                    &e.to_string(),
                );
            }
        };
        if !self.state().flights.contains_key(&m.goal_id) {
            return self.stray(key, Stream::Status, &m.goal_id);
        }
        match m.status {
            Status::Accepted | Status::Executing | Status::Canceling => self.acked(&m.goal_id),
            Status::Unknown | Status::Lost => self.drops.drop(
                Reason::InvalidStatus,
                key,
                "status",
                &m.goal_id,
                &format!("a server never publishes {}", status_name(m.status)),
            ),
            // Ended: the result is published before the status, so normally it has ended the
            // goal already. It has not: ask for it (the result may have been lost).
            _ if !self.opts.config.answers => {
                self.acked(&m.goal_id);
                self.start_asking(&m.goal_id);
            }
            _ => {}
        }
    }

    fn on_feedback(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        let m = match wire::parse::<FeedbackMsg>("feedback", key, &bytes) {
            Ok(m) => m,
            Err(e) => {
                return self.drops.drop(
                    Reason::Garbage,
                    key,
                    "feedback",
                    &goal_id_in(&bytes),
                    &e.to_string(),
                );
            }
        };
        let Some(action) = self
            .state()
            .flights
            .get(&m.goal_id)
            .map(|f| f.command.action.clone())
        else {
            return self.stray(key, Stream::Feedback, &m.goal_id);
        };
        let refused = match (m.progress_pct, self.spec(&action)) {
            (Some(p), _) if !(0.0..=100.0).contains(&p) => {
                Some(format!("progress_pct {p} is outside 0–100"))
            }
            (_, Some(spec)) => spec.check_feedback(&m.fields).err(),
            (_, None) => None,
        };
        if let Some(why) = refused {
            return self
                .drops
                .drop(Reason::Mistyped, key, "feedback", &m.goal_id, &why);
        }
        self.report(Report::Feedback {
            goal_id: m.goal_id,
            progress_pct: m.progress_pct,
            fields: m.fields,
        });
    }

    fn on_result(self: &Arc<Shared>, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let bytes = payload(sample);
        match wire::parse::<ResultMsg>("result", key, &bytes) {
            Ok(r) => {
                self.deliver(r, Source::Stream(key));
            }
            Err(e) => {
                let goal_id = goal_id_in(&bytes);
                self.drops
                    .drop(Reason::Garbage, key, "result", &goal_id, &e.to_string());
                // A result naming one of our goals that we cannot read: the server is asked
                // (anyone may publish on the stream, so it counts for nothing by itself).
                self.recheck(&goal_id);
            }
        }
    }

    fn on_telemetry(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let t = match wire::parse::<Telemetry>("telemetry", key, &payload(sample)) {
            Ok(t) => t,
            Err(e) => {
                return self
                    .drops
                    .drop(Reason::Garbage, key, "telemetry", "", &e.to_string());
            }
        };
        let config = &self.opts.config;
        if config.clock && Keys::last_chunk(key) == "clock" {
            self.on_clock(key, &t);
        }
        let catalogue = self
            .catalogue
            .lock()
            .ok()
            .and_then(|c| c.clone())
            .unwrap_or_default();
        for k in &config.data {
            let Some(v) = t.values.get(k) else { continue };
            let mut s = self.state();
            if let Err(why) = catalogue.check_telemetry(k, v, s.last_data.get(k)) {
                drop(s);
                self.drops
                    .drop(Reason::Mistyped, key, "telemetry", "", &why);
                continue;
            }
            let changed = match (s.last_data.get(k), config.deadband.get(k)) {
                (None, _) => true,
                (Some(old), Some(band)) => match (old.as_f64(), v.as_f64()) {
                    (Some(a), Some(b)) => (a - b).abs() >= *band,
                    _ => old != v,
                },
                (Some(old), None) => old != v,
            };
            if changed {
                s.last_data.insert(k.clone(), v.clone());
                drop(s);
                self.report(Report::Data {
                    key: k.clone(),
                    value: v.clone(),
                });
            }
        }
    }

    /// A mission clock report: believed only if plausible after the last one believed
    /// ([`wire::check_clock`]).
    fn on_clock(&self, key: &str, t: &Telemetry) {
        let Some(speed) = t.values.get("speed").and_then(Value::as_f64) else {
            return self.drops.drop(
                Reason::ImplausibleClock,
                key,
                "clock report",
                "",
                "a clock report needs a number `speed`",
            );
        };
        let reading = ClockReading {
            mission_ms: t.mission_ms,
            speed,
        };
        let now = Instant::now();
        let verdict = {
            let mut s = self.state();
            let last = s.clock;
            let wall = last.map_or(Duration::ZERO, |(_, at)| now.duration_since(at));
            let verdict = wire::check_clock(
                last.map(|(r, _)| r),
                reading,
                wall,
                Duration::from_millis(self.limits.clock_slack_ms),
            );
            if verdict.is_ok() {
                s.clock = Some((reading, now));
            }
            verdict
        };
        match verdict {
            Ok(()) => self.report(Report::Clock {
                mission_ms: t.mission_ms,
                speed,
            }),
            Err(e) => self.drops.drop(
                Reason::ImplausibleClock,
                key,
                "clock report",
                "",
                &e.to_string(),
            ),
        }
    }
}

impl ZenohConnector {
    /// Subscribes to the server's liveliness, streams and (if configured) telemetry, with the
    /// default [`Limits`]. Call inside a tokio runtime; reports go to `reports`.
    pub async fn new(
        session: &Session,
        opts: ClientOptions,
        reports: Reports,
    ) -> Result<ZenohConnector, ConnectorError> {
        ZenohConnector::with_limits(session, opts, Limits::default(), reports).await
    }

    /// [`ZenohConnector::new`] with chosen [`Limits`] (how long goals may stay unacknowledged,
    /// the retry backoff, the drop log's rate, the clock's slack).
    pub async fn with_limits(
        session: &Session,
        opts: ClientOptions,
        limits: Limits,
        reports: Reports,
    ) -> Result<ZenohConnector, ConnectorError> {
        connector_api::keys::check_chunk(opts.config.server())
            .map_err(|e| ConnectorError::Transport(e.to_string()))?;
        let shared = Arc::new(Shared {
            session: session.clone(),
            reports,
            rt: tokio::runtime::Handle::current(),
            state: Mutex::new(State::default()),
            catalogue: Mutex::new(None),
            drops: Drops::new(
                &opts.config.name,
                Duration::from_millis(limits.drop_log_every_ms),
            ),
            limits,
            answer_turn: tokio::sync::Mutex::new(()),
            opts,
        });
        let z = |e: zenoh::Error| ConnectorError::Transport(e.to_string());
        let keys = &shared.opts.keys;
        let server = shared.server().to_owned();
        let mut subscribers = Vec::new();
        type Handler = fn(&Arc<Shared>, &Sample);
        let streams: [(String, Handler); 3] = [
            (keys.streams_of(&server, Channel::Status), Shared::on_status),
            (
                keys.streams_of(&server, Channel::Feedback),
                Shared::on_feedback,
            ),
            (keys.streams_of(&server, Channel::Result), Shared::on_result),
        ];
        for (ke, f) in streams {
            let me = Arc::clone(&shared);
            subscribers.push(
                session
                    .declare_subscriber(ke)
                    .callback(move |s| f(&me, &s))
                    .await
                    .map_err(z)?,
            );
        }
        if !shared.opts.config.data.is_empty() || shared.opts.config.clock {
            let me = Arc::clone(&shared);
            subscribers.push(
                session
                    .declare_subscriber(keys.telemetry_of(&server))
                    .callback(move |s| me.on_telemetry(&s))
                    .await
                    .map_err(z)?,
            );
        }
        let me = Arc::clone(&shared);
        subscribers.push(
            session
                .liveliness()
                .declare_subscriber(keys.alive_actions_of(&server))
                .history(true)
                .callback(move |s| me.on_liveliness(&s))
                .await
                .map_err(z)?,
        );
        let answers = if shared.opts.config.answers {
            let me = Arc::clone(&shared);
            let ke = keys.answers_of(&server, &shared.opts.mission);
            Some(
                session
                    .declare_queryable(ke)
                    .complete(true)
                    .callback(move |q| {
                        let handle = me.rt.spawn(Arc::clone(&me).on_answer(q));
                        let mut s = me.state();
                        s.answering.retain(|h| !h.is_finished());
                        s.answering.push(handle);
                    })
                    .await
                    .map_err(z)?,
            )
        } else {
            None
        };
        Ok(ZenohConnector {
            shared,
            subscribers,
            answers,
        })
    }

    /// What this connector has dropped so far, updated on every drop (for monitors, and for
    /// tests to wait on).
    pub fn drops(&self) -> watch::Receiver<Dropped> {
        self.shared.drops.watch()
    }

    fn track(&self, command: &Command, acked: bool) -> bool {
        let mut s = self.shared.state();
        s.flights
            .entry(command.goal_id.clone())
            .or_insert_with(|| Flight {
                command: command.clone(),
                acked,
                sending: None,
                sends: 0,
                deadline_armed: false,
                asking: false,
                unreadable: 0,
            });
        let alive = s.served(&command.action);
        let generation = s.generation.get(&command.action).copied().unwrap_or(0);
        drop(s);
        if !alive {
            // Not served (yet): the liveliness appearance sends it; if nobody serves it within
            // the grace period it is lost.
            self.shared.start_grace(command.action.clone(), generation);
        }
        alive
    }
}

impl Connector for ZenohConnector {
    fn name(&self) -> &str {
        self.shared.name()
    }

    fn catalogue(&mut self) -> BoxFuture<'_, Result<Option<Catalogue>, ConnectorError>> {
        Box::pin(async move {
            let sh = &self.shared;
            let key = sh.opts.keys.catalogue(sh.server());
            let deadline = tokio::time::Instant::now() + sh.opts.catalogue_wait;
            let mut pause = Duration::from_millis(20);
            loop {
                // Every server of the key is asked: a server killed without a word (over QUIC,
                // nothing tells its router before the lease ends) still looks declared, and
                // the one that replaced it must be heard.
                let replies = sh
                    .session
                    .get(&key)
                    .target(QueryTarget::All)
                    .consolidation(ConsolidationMode::None)
                    .timeout(sh.opts.query_timeout)
                    .with(replies())
                    .await
                    .map_err(|e| ConnectorError::Transport(e.to_string()))?;
                let mut answer = None;
                while let Ok(reply) = replies.recv_async().await {
                    match reply.result() {
                        Ok(sample) => {
                            answer = Some(payload(sample));
                            break;
                        }
                        // Zenoh's own error when nobody replied in time: ask again.
                        Err(e) if e.payload().to_bytes().as_ref() == b"Timeout" => {}
                        Err(e) => {
                            return Err(ConnectorError::Protocol {
                                system: sh.server().to_owned(),
                                reason: String::from_utf8_lossy(&e.payload().to_bytes())
                                    .into_owned(),
                            });
                        }
                    }
                }
                if let Some(bytes) = answer {
                    let cat: Catalogue = wire::parse("catalogue", &key, &bytes).map_err(|e| {
                        ConnectorError::Protocol {
                            system: sh.server().to_owned(),
                            reason: e.to_string(),
                        }
                    })?;
                    if let Ok(mut c) = sh.catalogue.lock() {
                        *c = Some(cat.clone());
                    }
                    return Ok(Some(cat));
                }
                // Discovery is still converging, or the server is not up yet.
                if tokio::time::Instant::now() + pause > deadline {
                    return Err(ConnectorError::Timeout {
                        system: sh.server().to_owned(),
                        waited: sh.opts.catalogue_wait,
                        what: format!("its catalogue on `{key}`"),
                    });
                }
                tokio::time::sleep(pause).await;
                pause = (pause * 2).min(Duration::from_millis(500));
            }
        })
    }

    fn execute(&mut self, command: Command) {
        if self.shared.state().flights.contains_key(&command.goal_id) {
            return;
        }
        if self.track(&command, false) {
            self.shared.start_sending(&command.goal_id);
        }
    }

    fn reconcile(&mut self, command: Command) {
        if self.track(&command, true) {
            self.shared
                .rt
                .spawn(Arc::clone(&self.shared).reconcile(command));
        }
    }

    fn abort(&mut self, goal_id: &str) {
        let mut s = self.shared.state();
        let Some(flight) = s.land(goal_id, Ended::Aborted) else {
            return;
        };
        let action = flight.command.action;
        s.cancels.insert(goal_id.to_owned(), action.clone());
        let reason = self.shared.opts.config.answers.then(|| {
            let r = "withdrawn by the mission (a boundary event or the end of its scope)";
            s.closed.insert(
                goal_id.to_owned(),
                Closed {
                    why: r.to_owned(),
                    applied: None,
                },
            );
            r.to_owned()
        });
        let alive = s.served(&action);
        drop(s);
        if alive {
            self.shared.rt.spawn(Arc::clone(&self.shared).cancel(
                goal_id.to_owned(),
                action,
                reason,
            ));
        }
    }

    fn notify(&mut self, name: &str, payload: Value) {
        let key = self
            .shared
            .opts
            .keys
            .notification(self.shared.server(), name);
        let session = self.shared.session.clone();
        self.shared.rt.spawn(async move {
            if let Err(e) = session
                .put(&key, json(&payload))
                .encoding(encoding("notification"))
                .congestion_control(CongestionControl::Block)
                .await
            {
                tracing::warn!(key, error = %e, "notification not sent");
            }
        });
    }

    fn close(&mut self) -> BoxFuture<'_, ()> {
        Box::pin(async move {
            if let Some(q) = self.answers.take()
                && let Err(e) = q.undeclare().await
            {
                tracing::debug!(error = %e, "undeclare failed");
            }
            // Answers being decided still get their replies (the last answer of a mission ends
            // it, and its station must hear that it was applied).
            let answering = std::mem::take(&mut self.shared.state().answering);
            let deadline = tokio::time::Instant::now() + self.shared.opts.query_timeout;
            for h in answering {
                if tokio::time::timeout_at(deadline, h).await.is_err() {
                    tracing::warn!("an answer's reply was not sent before closing");
                    break;
                }
            }
            for s in self.subscribers.drain(..) {
                if let Err(e) = s.undeclare().await {
                    tracing::debug!(error = %e, "undeclare failed");
                }
            }
        })
    }

    fn dropped(&self) -> Dropped {
        self.shared.drops.counts()
    }
}
