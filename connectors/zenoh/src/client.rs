//! The executive's side of the activity protocol: a [`Connector`] that sends goals to one
//! server over Zenoh and turns its status, feedback and results into [`Report`]s.
//!
//! Presence comes from the per-action liveliness tokens: a goal for an action nobody serves
//! waits for the token, a server that vanishes while goals run gets `grace` to come back
//! before those goals fail with `CONNECTOR_LOST`, and when it comes back every goal in flight
//! is reconciled with a `state` query — so a result published while the link was down is
//! recovered rather than lost.
//!
//! A connector configured with `answers` talks to ground stations instead: goals and cancels
//! go to every station, and operators' answers arrive as `answer` queries that are checked
//! (open task, form, then the engine) and answered with the verdict — the first valid answer
//! wins, and the other stations are told who answered.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use connector_api::contract::BoxFuture;
use connector_api::wire::{
    self, Answer, AnswerReply, CancelReply, CancelRequest, FeedbackMsg, Goal, GoalReply, ResultMsg,
    StateReply, StatusMsg, Telemetry, codes,
};
use connector_api::{
    Catalogue, Channel, Command, Connector, ConnectorConfig, ConnectorError, Keys, Report, Reports,
    Status, Verdict,
};
use serde_json::Value;
use zenoh::Session;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, Query, QueryTarget, Queryable};
use zenoh::sample::{Sample, SampleKind};

use crate::codec::{encoding, json};

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
    closed: HashMap<String, String>,
    /// Ground stations: answers being decided (their replies are sent before closing).
    answering: Vec<tokio::task::JoinHandle<()>>,
}

impl State {
    fn served(&self, action: &str) -> bool {
        self.alive.get(action).is_some_and(|t| !t.is_empty())
    }
}

struct Shared {
    opts: ClientOptions,
    session: Session,
    reports: Reports,
    rt: tokio::runtime::Handle,
    state: Mutex<State>,
    catalogue: Mutex<Option<Catalogue>>,
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

    /// A goal ended: reported once (the flight is removed), duplicates ignored. A ground
    /// station's task closes only through an answer query, never through a published result.
    fn deliver(&self, r: ResultMsg) {
        if self.opts.config.answers {
            return tracing::debug!(
                goal_id = r.goal_id,
                "ground result ignored: answers close tasks"
            );
        }
        let Some(flight) = self.state().flights.remove(&r.goal_id) else {
            return;
        };
        match r.status {
            Status::Succeeded => {
                let spec = self
                    .catalogue
                    .lock()
                    .ok()
                    .and_then(|c| c.as_ref()?.action(&flight.command.action).cloned());
                match spec.map(|s| s.check_result(&r.outputs)) {
                    Some(Err(e)) => self.fail(
                        &r.goal_id,
                        codes::TYPE_MISMATCH,
                        format!(
                            "the result of `{}` does not match its catalogue entry: {e}",
                            flight.command.action
                        ),
                    ),
                    _ => self.report(Report::Done {
                        goal_id: r.goal_id,
                        outputs: r.outputs,
                    }),
                }
            }
            Status::Aborted => {
                let (code, message) = r.error.map_or(("ABORTED".to_owned(), String::new()), |f| {
                    (f.code, f.message)
                });
                self.fail(&r.goal_id, &code, message);
            }
            Status::Canceled => self.report(Report::Canceled { goal_id: r.goal_id }),
            other => self.fail(
                &r.goal_id,
                codes::CONNECTOR_LOST,
                format!("the server ended the goal with status {other:?}"),
            ),
        }
    }

    /// Sends (or re-sends: the server answers a repeat with the goal's current status) a goal.
    async fn send(self: Arc<Shared>, command: Command) {
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
            .await
        {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!(key, error = %e, "goal not sent; retried when the server reappears");
                return;
            }
        };
        let Ok(reply) = replies.recv_async().await else {
            // Nobody answered (routing not converged yet, or the server just left): the next
            // liveliness appearance re-sends the same goal id.
            tracing::debug!(key, "no server answered the goal");
            self.clone().retry_later(command);
            return;
        };
        let reply = match reply.result() {
            Ok(sample) => wire::parse::<GoalReply>("goal reply", &key, &payload(sample))
                .map_err(|e| e.to_string()),
            Err(err) => Err(String::from_utf8_lossy(&err.payload().to_bytes()).into_owned()),
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
            if let Some(taken) = replies_left.iter().find(|r| r.status != Status::Rejected) {
                return self.on_goal_reply(taken.clone());
            }
        }
        match reply {
            Ok(r) => self.on_goal_reply(r),
            Err(text) if text == "Timeout" => {
                tracing::warn!(key, "goal timed out; retrying");
                self.clone().retry_later(command);
            }
            Err(text) => {
                self.state().flights.remove(&command.goal_id);
                self.fail(
                    &command.goal_id,
                    codes::REJECTED,
                    format!("`{}` refused the goal: {text}", self.server()),
                );
            }
        }
    }

    /// Re-sends a goal shortly if it is still unacknowledged and its action is served.
    fn retry_later(self: Arc<Shared>, command: Command) {
        let rt = self.rt.clone();
        rt.spawn(async move {
            tokio::time::sleep(Duration::from_millis(100)).await;
            let again = {
                let s = self.state();
                s.served(&command.action)
                    && s.flights.get(&command.goal_id).is_some_and(|f| !f.acked)
            };
            if again {
                self.send(command).await;
            }
        });
    }

    fn on_goal_reply(&self, r: GoalReply) {
        match r.status {
            Status::Rejected => {
                if self.state().flights.remove(&r.goal_id).is_some() {
                    self.fail(
                        &r.goal_id,
                        codes::REJECTED,
                        r.reason.unwrap_or_else(|| "rejected".to_owned()),
                    );
                }
            }
            s if s.is_terminal() => {
                if let Some(result) = r.result {
                    self.deliver(result);
                }
            }
            _ => self.acked(&r.goal_id),
        }
    }

    fn acked(&self, goal_id: &str) {
        let first = match self.state().flights.get_mut(goal_id) {
            Some(f) if !f.acked => {
                f.acked = true;
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
            return self.send(command).await;
        }
        let key = self.opts.keys.goal(
            self.server(),
            &command.action,
            Channel::State,
            &command.goal_id,
        );
        let replies = match self
            .session
            .get(&key)
            .consolidation(ConsolidationMode::None)
            .timeout(self.opts.query_timeout)
            .await
        {
            Ok(r) => r,
            Err(e) => return tracing::warn!(key, error = %e, "state query failed"),
        };
        let Ok(reply) = replies.recv_async().await else {
            return tracing::debug!(key, "no answer to the state query; waiting for the server");
        };
        let Ok(sample) = reply.result() else {
            return tracing::warn!(key, "the server refused the state query");
        };
        match wire::parse::<StateReply>("state reply", &key, &payload(sample)) {
            Err(e) => tracing::warn!(error = %e, "ignored"),
            Ok(s) if s.status == Status::Unknown => {
                if self.state().flights.remove(&command.goal_id).is_some() {
                    self.fail(
                        &command.goal_id,
                        codes::CONNECTOR_LOST,
                        format!(
                            "`{}` does not know goal `{}` of `{}`: it was lost",
                            self.server(),
                            command.goal_id,
                            command.action
                        ),
                    );
                }
            }
            Ok(s) if s.status.is_terminal() => {
                if let Some(r) = s.result {
                    self.deliver(r);
                }
            }
            Ok(s) => {
                tracing::debug!(goal_id = s.goal_id, status = ?s.status, "goal still running");
                self.acked(&s.goal_id);
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
        let Ok(replies) = get
            .target(self.target())
            .consolidation(ConsolidationMode::None)
            .timeout(self.opts.query_timeout)
            .await
        else {
            return;
        };
        // Ground stations all reply; any other server once.
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            self.state().cancels.remove(&goal_id);
            match wire::parse::<CancelReply>("cancel reply", &key, &payload(sample)) {
                Ok(r) => tracing::info!(goal_id, reply = ?r, "cancel answered"),
                Err(e) => tracing::warn!(error = %e, "ignored"),
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
        let _turn = self.answer_turn.lock().await;
        let action = {
            let s = self.state();
            match s.flights.get(&goal_id) {
                Some(f) => f.command.action.clone(),
                None => {
                    return refused(match s.closed.get(&goal_id) {
                        Some(why) => format!("user task `{goal_id}` is closed: {why}"),
                        None => format!("no open user task has goal id `{goal_id}`"),
                    });
                }
            }
        };
        let spec = self
            .catalogue
            .lock()
            .ok()
            .and_then(|c| c.as_ref()?.action(&action).cloned());
        if let Some(Err(e)) = spec.map(|s| s.check_result(&a.fields)) {
            return refused(format!(
                "the answer does not fit the form of `{action}`: {e}"
            ));
        }
        let operator = format!("{}@{}", a.operator, a.station);
        let (verdict, decided) = Verdict::new();
        self.report(Report::Answer {
            goal_id: goal_id.clone(),
            fields: a.fields,
            operator: operator.clone(),
            verdict,
        });
        match decided.await {
            Ok(Ok(())) => {
                let why = format!("answered by {operator}");
                {
                    let mut s = self.state();
                    s.flights.remove(&goal_id);
                    s.closed.insert(goal_id.clone(), why.clone());
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
                    self.rt.spawn(Arc::clone(self).send(c));
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
                    s.flights.remove(id);
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

    fn on_status(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        match wire::parse::<StatusMsg>("status", key, &payload(sample)) {
            Ok(m) if matches!(m.status, Status::Accepted | Status::Executing) => {
                self.acked(&m.goal_id)
            }
            Ok(_) => {}
            Err(e) => tracing::warn!(error = %e, "ignored"),
        }
    }

    fn on_feedback(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        match wire::parse::<FeedbackMsg>("feedback", key, &payload(sample)) {
            Ok(m) if self.state().flights.contains_key(&m.goal_id) => {
                self.report(Report::Feedback {
                    goal_id: m.goal_id,
                    progress_pct: m.progress_pct,
                    fields: m.fields,
                })
            }
            Ok(_) => {}
            Err(e) => tracing::warn!(error = %e, "ignored"),
        }
    }

    fn on_result(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        match wire::parse::<ResultMsg>("result", key, &payload(sample)) {
            Ok(r) => self.deliver(r),
            Err(e) => tracing::warn!(error = %e, "ignored"),
        }
    }

    fn on_telemetry(&self, sample: &Sample) {
        let key = sample.key_expr().as_str();
        let t = match wire::parse::<Telemetry>("telemetry", key, &payload(sample)) {
            Ok(t) => t,
            Err(e) => return tracing::warn!(error = %e, "ignored"),
        };
        let config = &self.opts.config;
        if config.clock
            && Keys::last_chunk(key) == "clock"
            && let Some(speed) = t.values.get("speed").and_then(Value::as_f64)
        {
            self.report(Report::Clock {
                mission_ms: t.mission_ms,
                speed,
            });
        }
        for k in &config.data {
            let Some(v) = t.values.get(k) else { continue };
            let mut s = self.state();
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
}

impl ZenohConnector {
    /// Subscribes to the server's liveliness, streams and (if configured) telemetry. Call
    /// inside a tokio runtime; reports go to `reports`.
    pub async fn new(
        session: &Session,
        opts: ClientOptions,
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
            answer_turn: tokio::sync::Mutex::new(()),
            opts,
        });
        let z = |e: zenoh::Error| ConnectorError::Transport(e.to_string());
        let keys = &shared.opts.keys;
        let server = shared.server().to_owned();
        let mut subscribers = Vec::new();
        type Handler = fn(&Shared, &Sample);
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

    fn track(&self, command: &Command, acked: bool) -> bool {
        let mut s = self.shared.state();
        s.flights.entry(command.goal_id.clone()).or_insert(Flight {
            command: command.clone(),
            acked,
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
                let replies = sh
                    .session
                    .get(&key)
                    .consolidation(ConsolidationMode::None)
                    .timeout(sh.opts.query_timeout)
                    .await
                    .map_err(|e| ConnectorError::Transport(e.to_string()))?;
                if let Ok(reply) = replies.recv_async().await {
                    let sample = reply.result().map_err(|e| ConnectorError::Protocol {
                        system: sh.server().to_owned(),
                        reason: String::from_utf8_lossy(&e.payload().to_bytes()).into_owned(),
                    })?;
                    let cat: Catalogue =
                        wire::parse("catalogue", &key, &payload(sample)).map_err(|e| {
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
            self.shared.rt.spawn(Arc::clone(&self.shared).send(command));
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
        let Some(flight) = s.flights.remove(goal_id) else {
            return;
        };
        let action = flight.command.action;
        s.cancels.insert(goal_id.to_owned(), action.clone());
        let reason = self.shared.opts.config.answers.then(|| {
            let r = "withdrawn by the mission (a boundary event or the end of its scope)";
            s.closed.insert(goal_id.to_owned(), r.to_owned());
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
}
