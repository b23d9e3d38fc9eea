//! The action server library: serves a system's actions and its catalogue over the activity
//! protocol with the right semantics (idempotent goals by id, typed goal checks, cancel,
//! non-blocking state, status/feedback/result streams, liveliness per action, an optional
//! persistent goal table), so no system re-implements the protocol.
//!
//! The application receives [`Request`]s (a new goal, a cancel) and answers through the
//! [`GoalHandle`]: `executing`, `feedback`, then one of `succeed`, `abort`, `canceled`.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};

use connector_api::wire::{
    self, CancelReply, Failure, FeedbackMsg, Fields, Goal, GoalReply, ResultMsg, StateReply,
    StatusMsg,
};
use connector_api::{Catalogue, Channel, Keys, Status};
use serde::{Deserialize, Serialize};
use tokio::sync::mpsc;
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::CongestionControl;
use zenoh::query::{Query, Queryable};
use zenoh::{Session, Wait};

use crate::codec::{encoding, json};

/// Decides whether to take a goal that passed the type checks (e.g. "the arm is busy").
pub type AcceptFn = Arc<dyn Fn(&str, &Fields) -> Result<(), String> + Send + Sync>;

/// How to serve.
#[derive(Clone)]
pub struct ServerOptions {
    /// Key builder (root).
    pub keys: Keys,
    /// What is served; `catalogue.server` is the server id in every key.
    pub catalogue: Catalogue,
    /// Where the goal table is kept across restarts (`None`: in memory only).
    pub store: Option<sled::Tree>,
    /// Extra acceptance rule after the type checks.
    pub accept: Option<AcceptFn>,
    /// This server's instance, when several serve the same server id at once (ground
    /// stations): each announces its actions under its own liveliness token.
    pub instance: Option<String>,
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// A Zenoh declaration failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The goal table could not be read.
    #[error("goal table: {0}")]
    Store(String),
    /// A server or action name cannot be a key chunk.
    #[error(transparent)]
    Name(#[from] connector_api::keys::BadChunk),
}

/// What the application is asked to do.
#[derive(Debug)]
pub enum Request {
    /// Run this goal (already accepted).
    Goal(GoalHandle),
    /// Stop this goal; answer with [`GoalHandle::canceled`] (or finish it if too late). The
    /// reason, when the canceller gave one, is for the people at the server.
    Cancel(GoalHandle, Option<String>),
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct Entry {
    action: String,
    fields: Fields,
    status: Status,
    seq: u64,
    #[serde(default)]
    reason: Option<String>,
    #[serde(default)]
    result: Option<ResultMsg>,
}

struct Inner {
    session: Session,
    keys: Keys,
    catalogue: Catalogue,
    table: Mutex<BTreeMap<String, Entry>>,
    store: Option<sled::Tree>,
    accept: Option<AcceptFn>,
    requests: mpsc::UnboundedSender<Request>,
}

/// One goal, as the application sees it.
#[derive(Clone)]
pub struct GoalHandle {
    /// The goal id.
    pub goal_id: String,
    /// The action.
    pub action: String,
    /// The goal's fields (checked against the catalogue).
    pub fields: Fields,
    inner: Arc<Inner>,
}

impl std::fmt::Debug for GoalHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalHandle")
            .field("goal_id", &self.goal_id)
            .field("action", &self.action)
            .finish()
    }
}

/// A running action server; dropping it undeclares everything.
pub struct ActionServer {
    inner: Arc<Inner>,
    _queryables: Vec<Queryable<()>>,
    _tokens: Vec<LivelinessToken>,
}

impl Inner {
    fn server(&self) -> &str {
        &self.catalogue.server
    }

    fn table(&self) -> MutexGuard<'_, BTreeMap<String, Entry>> {
        // A panic elsewhere while holding the lock leaves a consistent map (every update is
        // one insert), so a poisoned lock is still usable.
        self.table.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn persist(&self, goal_id: &str, entry: &Entry) {
        if let Some(tree) = &self.store {
            let done = tree
                .insert(goal_id.as_bytes(), json(entry))
                .and_then(|_| tree.flush());
            if let Err(e) = done {
                tracing::error!(goal_id, error = %e, "goal table write failed");
            }
        }
    }

    fn status_msg(goal_id: &str, e: &Entry, text: &str) -> StatusMsg {
        StatusMsg {
            goal_id: goal_id.to_owned(),
            status: e.status,
            seq: e.seq,
            text: text.to_owned(),
        }
    }

    /// Moves a goal to `status` (refused from a terminal state); returns the status message.
    fn transition(
        &self,
        goal_id: &str,
        status: Status,
        text: &str,
        result: Option<ResultMsg>,
    ) -> Option<(String, StatusMsg, Option<ResultMsg>)> {
        let mut table = self.table();
        let e = table.get_mut(goal_id)?;
        if e.status.is_terminal() {
            tracing::warn!(goal_id, from = ?e.status, to = ?status, "goal already ended; transition ignored");
            return None;
        }
        e.status = status;
        e.seq += 1;
        e.result = result.clone();
        let entry = e.clone();
        drop(table);
        self.persist(goal_id, &entry);
        Some((
            entry.action.clone(),
            Inner::status_msg(goal_id, &entry, text),
            result,
        ))
    }

    /// Publishes a transition; a result goes first, since the client waits on it and the
    /// status is for observers.
    async fn publish(&self, action: &str, status: StatusMsg, result: Option<ResultMsg>) {
        let server = self.server();
        let mut puts = Vec::with_capacity(2);
        if let Some(r) = result {
            puts.push((Channel::Result, json(&r), "result"));
        }
        puts.push((Channel::Status, json(&status), "status"));
        for (channel, body, kind) in puts {
            if let Err(e) = self
                .session
                .put(self.keys.stream(server, action, channel), body)
                .encoding(encoding(kind))
                .congestion_control(CongestionControl::Block)
                .express(true)
                .await
            {
                tracing::warn!(error = %e, kind, "not published");
            }
        }
    }

    fn publish_now(&self, action: &str, status: &StatusMsg) {
        let k = self.keys.stream(self.server(), action, Channel::Status);
        if let Err(e) = self
            .session
            .put(k, json(status))
            .encoding(encoding("status"))
            .congestion_control(CongestionControl::Block)
            .express(true)
            .wait()
        {
            tracing::warn!(error = %e, "status not published");
        }
    }

    fn handle(self: &Arc<Inner>, goal_id: &str, e: &Entry) -> GoalHandle {
        GoalHandle {
            goal_id: goal_id.to_owned(),
            action: e.action.clone(),
            fields: e.fields.clone(),
            inner: Arc::clone(self),
        }
    }

    /// `…/<action>/goal/<goal_id>`.
    fn on_goal(self: &Arc<Inner>, query: &Query) {
        let key = query.key_expr().as_str().to_owned();
        let (action, goal_id) = match self.parse_key(&key) {
            Ok(p) => p,
            Err(e) => return refuse(query, &e),
        };
        let bytes = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let goal: Goal = match wire::parse("goal", &key, &bytes) {
            Ok(g) => g,
            Err(e) => return refuse(query, &e.to_string()),
        };
        if goal.goal_id != goal_id {
            return refuse(
                query,
                &format!(
                    "goal_id `{}` in the payload differs from the key's `{goal_id}`",
                    goal.goal_id
                ),
            );
        }
        let mut table = self.table();
        if let Some(e) = table.get(&goal_id) {
            // A repeat (a resend after a timeout, an executive restart): same answer, no
            // second run.
            let reply = GoalReply {
                goal_id: goal_id.clone(),
                status: e.status,
                reason: e.reason.clone(),
                result: e.result.clone(),
            };
            drop(table);
            tracing::debug!(goal_id, "repeated goal answered with its current status");
            return reply_json(query, "goal_reply", &reply);
        }
        let spec = self.catalogue.action(&action);
        let verdict = match spec {
            None => Err(format!("action `{action}` is not served")),
            Some(spec) => spec
                .check_goal(&goal.fields)
                .and_then(|()| match &self.accept {
                    Some(accept) => accept(&action, &goal.fields),
                    None => Ok(()),
                }),
        };
        let (status, reason) = match &verdict {
            Ok(()) => (Status::Accepted, None),
            Err(r) => (Status::Rejected, Some(r.clone())),
        };
        let entry = Entry {
            action: action.clone(),
            fields: goal.fields,
            status,
            seq: 1,
            reason: reason.clone(),
            result: None,
        };
        table.insert(goal_id.clone(), entry.clone());
        drop(table);
        self.persist(&goal_id, &entry);
        reply_json(
            query,
            "goal_reply",
            &GoalReply {
                goal_id: goal_id.clone(),
                status,
                reason: reason.clone(),
                result: None,
            },
        );
        self.publish_now(
            &action,
            &Inner::status_msg(&goal_id, &entry, reason.as_deref().unwrap_or("")),
        );
        if status == Status::Accepted {
            tracing::info!(goal_id, action, client = goal.client, "goal accepted");
            let _ = self
                .requests
                .send(Request::Goal(self.handle(&goal_id, &entry)));
        } else {
            tracing::info!(goal_id, action, reason, "goal rejected");
        }
    }

    /// `…/<action>/cancel/<goal_id>`.
    fn on_cancel(self: &Arc<Inner>, query: &Query) {
        let key = query.key_expr().as_str().to_owned();
        let (_, goal_id) = match self.parse_key(&key) {
            Ok(p) => p,
            Err(e) => return refuse(query, &e),
        };
        let reason = match query.payload().map(|p| p.to_bytes()) {
            Some(bytes) if !bytes.is_empty() => {
                match wire::parse::<wire::CancelRequest>("cancel", &key, &bytes) {
                    Ok(r) => Some(r.reason),
                    Err(e) => return refuse(query, &e.to_string()),
                }
            }
            _ => None,
        };
        let (answer, first) = match self.table().get(&goal_id).map(|e| e.status) {
            None => (CancelReply::UnknownGoal, false),
            Some(s) if s.is_terminal() => (CancelReply::Terminated, false),
            Some(s) => (CancelReply::Accepted, s != Status::Canceling),
        };
        reply_json(query, "cancel_reply", &answer);
        // A repeated cancel is answered again but asks the application only once.
        if first
            && let Some((action, status, _)) =
                self.transition(&goal_id, Status::Canceling, "cancel requested", None)
        {
            self.publish_now(&action, &status);
            let handle = self.table().get(&goal_id).map(|e| self.handle(&goal_id, e));
            if let Some(h) = handle {
                let _ = self.requests.send(Request::Cancel(h, reason));
            }
        }
    }

    /// `…/<action>/state/<goal_id>`, or a wildcard for every goal.
    fn on_state(self: &Arc<Inner>, query: &Query) {
        let key = query.key_expr().as_str().to_owned();
        let parts: Vec<&str> = key.rsplitn(4, '/').collect();
        let (id, action) = match parts.as_slice() {
            [id, _state, action, _] => (*id, *action),
            _ => return refuse(query, &format!("`{key}` is not a state key")),
        };
        let wild = |c: &str| c == "*" || c == "**";
        let table = self.table();
        let mut replies = Vec::new();
        if wild(id) || wild(action) {
            for (gid, e) in table.iter() {
                if (wild(id) || gid == id) && (wild(action) || e.action == action) {
                    replies.push((e.action.clone(), state_of(gid, Some(e))));
                }
            }
        } else {
            replies.push((action.to_owned(), state_of(id, table.get(id))));
        }
        drop(table);
        for (action, state) in replies {
            let k = self
                .keys
                .goal(self.server(), &action, Channel::State, &state.goal_id);
            if let Err(e) = query
                .reply(k, json(&state))
                .encoding(encoding("state_reply"))
                .wait()
            {
                tracing::warn!(error = %e, "state reply failed");
            }
        }
    }

    /// The action and goal id of a goal/cancel/state key.
    fn parse_key(&self, key: &str) -> Result<(String, String), String> {
        let parts: Vec<&str> = key.rsplitn(4, '/').collect();
        match parts.as_slice() {
            [id, _, action, _] if connector_api::keys::check_chunk(id).is_ok() => {
                Ok(((*action).to_owned(), (*id).to_owned()))
            }
            _ => Err(format!("`{key}` does not name one goal")),
        }
    }
}

fn state_of(goal_id: &str, e: Option<&Entry>) -> StateReply {
    match e {
        Some(e) => StateReply {
            goal_id: goal_id.to_owned(),
            status: e.status,
            result: e.result.clone(),
            seq: e.seq,
        },
        None => StateReply {
            goal_id: goal_id.to_owned(),
            status: Status::Unknown,
            result: None,
            seq: 0,
        },
    }
}

fn reply_json<T: Serialize>(query: &Query, kind: &str, value: &T) {
    if let Err(e) = query
        .reply(query.key_expr().clone(), json(value))
        .encoding(encoding(kind))
        .wait()
    {
        tracing::warn!(error = %e, "reply failed");
    }
}

fn refuse(query: &Query, reason: &str) {
    tracing::warn!(key = %query.key_expr(), reason, "request refused");
    if let Err(e) = query.reply_err(reason.to_owned()).wait() {
        tracing::warn!(error = %e, "error reply failed");
    }
}

impl ActionServer {
    /// Declares the queryables, the catalogue and one liveliness token per action. Goals in
    /// the persistent table stay answerable (`state`, repeated `goal`) across restarts.
    pub async fn start(
        session: &Session,
        opts: ServerOptions,
    ) -> Result<(ActionServer, mpsc::UnboundedReceiver<Request>), ServerError> {
        let server = opts.catalogue.server.clone();
        connector_api::keys::check_chunk(&server)?;
        for a in &opts.catalogue.actions {
            connector_api::keys::check_chunk(&a.name)?;
        }
        let mut table = BTreeMap::new();
        if let Some(tree) = &opts.store {
            for item in tree.iter() {
                let (k, v) = item.map_err(|e| ServerError::Store(e.to_string()))?;
                let id = String::from_utf8_lossy(&k).into_owned();
                match serde_json::from_slice::<Entry>(&v) {
                    Ok(e) => {
                        table.insert(id, e);
                    }
                    Err(e) => {
                        return Err(ServerError::Store(format!("entry `{id}` is damaged: {e}")));
                    }
                }
            }
        }
        let (tx, rx) = mpsc::unbounded_channel();
        let inner = Arc::new(Inner {
            session: session.clone(),
            keys: opts.keys.clone(),
            catalogue: opts.catalogue.clone(),
            table: Mutex::new(table),
            store: opts.store,
            accept: opts.accept,
            requests: tx,
        });
        let z = |e: zenoh::Error| ServerError::Zenoh(e.to_string());
        let mut queryables = Vec::new();
        for (channel, f) in [
            (Channel::Goal, Inner::on_goal as fn(&Arc<Inner>, &Query)),
            (Channel::Cancel, Inner::on_cancel),
            (Channel::State, Inner::on_state),
        ] {
            let me = Arc::clone(&inner);
            let ke = format!("{}/act/{server}/*/{channel}/*", opts.keys.root());
            queryables.push(
                session
                    .declare_queryable(ke)
                    .complete(true)
                    .callback(move |q| f(&me, &q))
                    .await
                    .map_err(z)?,
            );
        }
        let cat = json(&opts.catalogue);
        let cat_key = opts.keys.catalogue(&server);
        let own = cat_key.clone();
        queryables.push(
            session
                .declare_queryable(cat_key)
                .complete(true)
                .callback(move |q| {
                    // On the server's own key, not the query's: a query for every catalogue
                    // (`…/cat/*`) gets each on its server's key, which access control allows.
                    if let Err(e) = q
                        .reply(own.clone(), cat.clone())
                        .encoding(encoding("catalogue"))
                        .wait()
                    {
                        tracing::warn!(error = %e, "catalogue reply failed");
                    }
                })
                .await
                .map_err(z)?,
        );
        let mut tokens = Vec::new();
        if let Some(i) = &opts.instance {
            connector_api::keys::check_chunk(i)?;
        }
        for a in &opts.catalogue.actions {
            let token = match &opts.instance {
                Some(i) => opts.keys.alive_action_by(&server, &a.name, i),
                None => opts.keys.alive_action(&server, &a.name),
            };
            tokens.push(session.liveliness().declare_token(token).await.map_err(z)?);
        }
        tracing::info!(
            server,
            actions = opts.catalogue.actions.len(),
            "action server up"
        );
        Ok((
            ActionServer {
                inner,
                _queryables: queryables,
                _tokens: tokens,
            },
            rx,
        ))
    }

    /// Goals accepted before a restart that had not ended: the application resumes or aborts
    /// them.
    pub fn unfinished(&self) -> Vec<GoalHandle> {
        let table = self.inner.table();
        table
            .iter()
            .filter(|(_, e)| !e.status.is_terminal())
            .map(|(id, e)| self.inner.handle(id, e))
            .collect()
    }

    /// The status of a goal the server knows.
    pub fn status(&self, goal_id: &str) -> Option<Status> {
        self.inner.table().get(goal_id).map(|e| e.status)
    }
}

impl GoalHandle {
    /// The goal's current status.
    pub fn status(&self) -> Status {
        self.inner
            .table()
            .get(&self.goal_id)
            .map_or(Status::Unknown, |e| e.status)
    }

    async fn finish(&self, status: Status, text: &str, result: Option<ResultMsg>) -> bool {
        match self.inner.transition(&self.goal_id, status, text, result) {
            Some((action, msg, result)) => {
                self.inner.publish(&action, msg, result).await;
                true
            }
            None => false,
        }
    }

    /// The activity started.
    pub async fn executing(&self) -> bool {
        self.finish(Status::Executing, "", None).await
    }

    /// Progress report (not persisted; throttle it in the application).
    pub async fn feedback(&self, progress_pct: Option<f64>, fields: Fields) {
        let msg = FeedbackMsg {
            goal_id: self.goal_id.clone(),
            progress_pct,
            fields,
        };
        let k = self
            .inner
            .keys
            .stream(self.inner.server(), &self.action, Channel::Feedback);
        if let Err(e) = self
            .inner
            .session
            .put(k, json(&msg))
            .encoding(encoding("feedback"))
            .express(true)
            .await
        {
            tracing::debug!(error = %e, "feedback not published");
        }
    }

    /// Success with outputs. False if the goal had already ended.
    pub async fn succeed(&self, outputs: Fields) -> bool {
        let r = ResultMsg {
            goal_id: self.goal_id.clone(),
            status: Status::Succeeded,
            outputs,
            error: None,
        };
        self.finish(Status::Succeeded, "", Some(r)).await
    }

    /// Failure with an error code the model's boundaries catch.
    pub async fn abort(&self, code: &str, message: &str) -> bool {
        let r = ResultMsg {
            goal_id: self.goal_id.clone(),
            status: Status::Aborted,
            outputs: Fields::new(),
            error: Some(Failure {
                code: code.to_owned(),
                message: message.to_owned(),
            }),
        };
        self.finish(Status::Aborted, code, Some(r)).await
    }

    /// Stopped after a cancel, with any partial effects as outputs.
    pub async fn canceled(&self, partial: Fields) -> bool {
        let r = ResultMsg {
            goal_id: self.goal_id.clone(),
            status: Status::Canceled,
            outputs: partial,
            error: None,
        };
        self.finish(Status::Canceled, "", Some(r)).await
    }
}
