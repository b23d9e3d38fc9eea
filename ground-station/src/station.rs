//! The station on Zenoh: serves the forms as the `ground` server (one more server of the
//! activity protocol, announced per station so several can run), opens each user task on the
//! desk, answers by policy where the policy says so, sends operators' answers, and closes tasks
//! the mission withdrew or another station answered.
//!
//! Everything the station does is printed as one line per event (`task 3 open: …`,
//! `task 3 answered: …`, `task 3 refused: …`, `task 3 closed: …`), for the operator and for
//! tools that follow the station's output.

use std::io::Write;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use connector_api::wire::Answer;
use connector_api::{Catalogue, Fields, Keys};
use connector_zenoh::{ActionServer, Request, ServerError, ServerOptions};
use tokio::sync::mpsc;
use zenoh::Session;
use zenoh::liveliness::LivelinessToken;

use crate::desk::Desk;
use crate::policy::{Decision, Policy};

/// How long an answer waits for the executive's verdict: the answer's round trip, the commit,
/// and the cancel's round trip to every station that comes before the verdict — two round
/// trips, seconds each on a slow link to the lander.
const VERDICT_WAIT: Duration = Duration::from_secs(30);

/// After no executive answered: the first pause before the answer is sent again; it doubles
/// up to [`RETRY_MAX`]. The answer is sent again while its task is on the desk: an executive
/// that restarts judges it then (an answer it already applied is confirmed, not applied twice).
const RETRY_FIRST: Duration = Duration::from_millis(200);
const RETRY_MAX: Duration = Duration::from_secs(5);

/// How many event lines [`Station::log`] keeps.
pub const LOG_LINES: usize = 200;

/// A running ground station.
pub struct Station {
    session: Session,
    keys: Keys,
    forms: Arc<Catalogue>,
    /// This station's id (key chunk), recorded with every answer it sends.
    pub id: String,
    desk: Mutex<Desk>,
    /// Answers the tasks it has rules for, those reopened after a restart included.
    policy: Option<Arc<Policy>>,
    /// Tasks kept in the store from before a restart, reopened when serving starts.
    resumed: Mutex<Vec<connector_zenoh::GoalHandle>>,
    /// Told when a task whose answer is out is withdrawn: that answer's wait looks at why.
    withdrawals: tokio::sync::Notify,
    /// The last event lines said, for views other than the terminal.
    log: Mutex<std::collections::VecDeque<String>>,
    _server: ActionServer,
    _alive: LivelinessToken,
}

impl std::fmt::Debug for Station {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Station").field("id", &self.id).finish()
    }
}

/// Prints one event line and flushes (the output may be a pipe or a terminal).
pub fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

impl Station {
    /// Serves the forms as station `id`, answering by `policy` where it has a rule; the
    /// receiver yields the tasks and withdrawals. Tasks kept in `store` from before a restart
    /// are reopened on the desk when [`Station::serve`] starts, and the policy answers them
    /// like new ones.
    pub async fn start(
        session: &Session,
        keys: Keys,
        forms: Arc<Catalogue>,
        id: String,
        store: Option<sled::Tree>,
        policy: Option<Arc<Policy>>,
    ) -> Result<(Arc<Station>, mpsc::UnboundedReceiver<Request>), ServerError> {
        connector_api::keys::check_chunk(&id)?;
        let (server, requests) = ActionServer::start(
            session,
            ServerOptions {
                keys: keys.clone(),
                catalogue: (*forms).clone(),
                store,
                accept: None,
                instance: Some(id.clone()),
            },
        )
        .await?;
        let alive = session
            .liveliness()
            .declare_token(keys.alive("ground", &id))
            .await
            .map_err(|e| ServerError::Zenoh(e.to_string()))?;
        let resumed = Mutex::new(server.unfinished());
        let station = Arc::new(Station {
            session: session.clone(),
            keys,
            forms,
            id,
            desk: Mutex::new(Desk::default()),
            policy,
            resumed,
            withdrawals: tokio::sync::Notify::new(),
            log: Mutex::default(),
            _server: server,
            _alive: alive,
        });
        Ok((station, requests))
    }

    /// Says an event line and keeps it in the log.
    fn tell(&self, line: String) {
        say(&line);
        let mut log = self.log.lock().unwrap_or_else(|p| p.into_inner());
        if log.len() == LOG_LINES {
            log.pop_front();
        }
        log.push_back(line);
    }

    /// The last event lines said (at most [`LOG_LINES`]), oldest first: `task 3 open: …`,
    /// `task 3 closed: answered by ana@console`, …
    pub fn log(&self) -> Vec<String> {
        self.log
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .cloned()
            .collect()
    }

    /// The desk of open tasks.
    pub fn desk(&self) -> MutexGuard<'_, Desk> {
        self.desk.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The forms served.
    pub fn forms(&self) -> &Catalogue {
        &self.forms
    }

    /// Handles tasks and withdrawals until the server stops.
    pub async fn serve(self: Arc<Self>, mut requests: mpsc::UnboundedReceiver<Request>) {
        let resumed = std::mem::take(&mut *self.resumed.lock().unwrap_or_else(|p| p.into_inner()));
        for h in resumed {
            self.open(h).await;
        }
        while let Some(r) = requests.recv().await {
            match r {
                Request::Goal(h) => self.open(h).await,
                Request::Cancel(h, reason) => {
                    let why = reason.unwrap_or_else(|| "withdrawn".to_owned());
                    let closed = {
                        let mut desk = self.desk();
                        match desk.by_goal(&h.goal_id) {
                            // Our own answer's verdict decides (it may be the winner).
                            Some(t) if t.answering => {
                                t.withdrawn = Some(why.clone());
                                self.withdrawals.notify_waiters();
                                None
                            }
                            Some(_) => desk.close(&h.goal_id, &why),
                            None => None,
                        }
                    };
                    if let Some(t) = closed {
                        h.canceled(Fields::new()).await;
                        self.tell(format!("task {} closed: {why}", t.number));
                    }
                }
            }
        }
    }

    async fn open(self: &Arc<Self>, h: connector_zenoh::GoalHandle) {
        h.executing().await;
        let (number, line) = match self.desk().open(h.clone()) {
            Some(t) => (t.number, t.line()),
            None => return,
        };
        self.tell(format!("task {number} open: {line}"));
        let Some(policy) = self.policy.clone() else {
            return;
        };
        match policy.decide(&h.action, &h.fields) {
            Decision::Leave => {}
            Decision::Silent => self.tell(format!(
                "task {number} left to the model's timer (policy: silent)"
            )),
            Decision::Answer { fields: Err(e), .. } => {
                self.tell(format!("task {number} not answered by policy: {e}"))
            }
            Decision::Answer {
                delay,
                fields: Ok(fields),
            } => {
                let me = Arc::clone(self);
                tokio::spawn(async move {
                    tokio::time::sleep(delay).await;
                    if me.desk().get(number).is_some() {
                        me.answer(number, fields, &policy.operator).await;
                    }
                });
            }
        }
    }

    /// Sends an answer to open task `number` and reports the verdict; `true` if applied.
    pub async fn answer(&self, number: u32, fields: Fields, operator: &str) -> bool {
        let picked = match self.desk().get_mut(number) {
            Some(t) if t.answering => Err("an answer to it is already with the executive"),
            Some(t) => {
                t.answering = true;
                Ok((
                    t.handle.goal_id.clone(),
                    t.handle.action.clone(),
                    t.handle.clone(),
                ))
            }
            None => Err("no open task has this number"),
        };
        let (goal_id, action, handle) = match picked {
            Ok(p) => p,
            Err(why) => {
                self.tell(format!("task {number} refused: {why}"));
                return false;
            }
        };
        let answer = Answer {
            goal_id: goal_id.clone(),
            fields: fields.clone(),
            operator: operator.to_owned(),
            station: self.id.clone(),
        };
        let sent = self.judged(number, &action, &answer).await;
        match sent {
            Ok(r) if r.applied => {
                self.desk()
                    .close(&goal_id, &format!("answered by {operator}@{}", self.id));
                handle.succeed(fields).await;
                self.tell(format!(
                    "task {number} answered: applied ({operator}@{})",
                    self.id
                ));
                true
            }
            Ok(r) => {
                let reason = r.reason.unwrap_or_else(|| "refused".to_owned());
                self.tell(format!("task {number} refused: {reason}"));
                self.not_applied(number, &handle).await;
                false
            }
            Err(e) => {
                self.tell(format!("task {number} refused: {e}"));
                self.not_applied(number, &handle).await;
                false
            }
        }
    }

    /// Sends the answer until the executive judges it: while no executive answers (it is
    /// down, restarting, or the link is cut), again with backoff, saying so — as long as the
    /// task is on the desk and not withdrawn; a withdrawal that names this answer is its verdict.
    async fn judged(
        &self,
        number: u32,
        action: &str,
        answer: &Answer,
    ) -> Result<connector_api::wire::AnswerReply, connector_zenoh::AnswerError> {
        let mut pause = RETRY_FIRST;
        let mine = format!("answered by {}@{}", answer.operator, self.id);
        let applied = || connector_api::wire::AnswerReply {
            goal_id: answer.goal_id.clone(),
            applied: true,
            reason: None,
        };
        let withdrawn_as_mine = || {
            self.desk()
                .get_mut(number)
                .is_some_and(|t| t.withdrawn.as_deref() == Some(mine.as_str()))
        };
        loop {
            let send = connector_zenoh::send_answer(
                &self.session,
                &self.keys,
                &self.forms.server,
                action,
                answer,
                VERDICT_WAIT,
            );
            // The executive closes a task for every station with who answered it
            // (`docs/protocol.md` §8a): our own name there is our verdict, even when the reply
            // itself is lost (the last answer of a mission ends it, and the executive leaves).
            let mine_withdrawn = async {
                loop {
                    let told = self.withdrawals.notified();
                    if withdrawn_as_mine() {
                        return;
                    }
                    told.await;
                }
            };
            let sent = tokio::select! {
                sent = send => sent,
                () = mine_withdrawn => return Ok(applied()),
            };
            let e = match sent {
                Err(e @ connector_zenoh::AnswerError::NoExecutive(_)) => e,
                judged => return judged,
            };
            // Withdrawn for anyone else's answer, or by the mission: ours was not applied.
            let still = self
                .desk()
                .get_mut(number)
                .is_some_and(|t| t.withdrawn.is_none());
            if !still {
                return Err(e);
            }
            self.tell(format!(
                "task {number} answer pending: {e}; sending it again in {:.1} s",
                pause.as_secs_f64()
            ));
            tokio::time::sleep(pause).await;
            pause = (pause * 2).min(RETRY_MAX);
        }
    }

    /// Our answer was not applied: the task is open again, unless it was withdrawn meanwhile.
    async fn not_applied(&self, number: u32, handle: &connector_zenoh::GoalHandle) {
        let withdrawn = {
            let mut desk = self.desk();
            let why = desk.get_mut(number).and_then(|t| {
                t.answering = false;
                t.withdrawn.take()
            });
            if let Some(why) = &why {
                desk.close(&handle.goal_id, why);
            }
            why
        };
        if let Some(why) = withdrawn {
            handle.canceled(Fields::new()).await;
            self.tell(format!("task {number} closed: {why}"));
        }
    }
}
