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
//!
//! Rooms: this file holds the connector, its state and the [`Connector`] calls; a goal's life
//! cycle is in `client/goals.rs`, the answers in `client/answers.rs`, presence in
//! `client/presence.rs`, the server's streams, telemetry and clock in `client/streams.rs`.

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

mod answers;
mod goals;
mod presence;
mod streams;

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
            let began = tokio::time::Instant::now();
            let deadline = began + sh.opts.catalogue_wait;
            let mut pause = Duration::from_millis(20);
            // Said at once after a few seconds, then every half minute, for as long as it waits.
            let mut say_at = began + Duration::from_secs(5);
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
                let now = tokio::time::Instant::now();
                if now >= say_at {
                    tracing::warn!(
                        system = sh.server(),
                        key = %key,
                        waited_s = (now - began).as_secs(),
                        "waiting for the system's catalogue: nothing starts until it answers"
                    );
                    say_at = now + Duration::from_secs(30);
                }
                if now + pause > deadline {
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
