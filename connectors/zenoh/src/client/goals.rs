//! A goal's life cycle on the executive's side: sent until acknowledged (with backoff, failing
//! with `NOT_ACCEPTED`), its result delivered once and typed against the catalogue, answers it
//! cannot understand counted towards `PROTOCOL_ERROR`, its `state` asked when a result is
//! owed, reconciled after a restart, and cancelled.

use super::*;

impl Shared {
    /// A message on a stream names a goal that is not in flight: expected after the goal
    /// ended here (a status after the result, anything after an abort), otherwise dropped.
    pub(super) fn stray(&self, key: &str, stream: Stream, goal_id: &str) {
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
    pub(super) fn deliver(self: &Arc<Self>, r: ResultMsg, source: Source<'_>) -> bool {
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
    pub(super) fn not_understood(self: &Arc<Self>, goal_id: &str, why: String) -> bool {
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
    pub(super) fn recheck(self: &Arc<Self>, goal_id: &str) {
        if self.state().flights.get(goal_id).is_some_and(|f| f.acked) {
            self.start_asking(goal_id);
        }
    }

    /// An answer about the goal was understood: the count of those that were not restarts.
    pub(super) fn understood(&self, goal_id: &str) {
        if let Some(f) = self.state().flights.get_mut(goal_id) {
            f.unreadable = 0;
        }
    }

    /// Starts sending a goal until it is acknowledged (or wakes the sender to send at once).
    pub(super) fn start_sending(self: &Arc<Self>, goal_id: &str) {
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
    pub(super) async fn send_loop(self: Arc<Shared>, goal_id: String, wake: Arc<Notify>) {
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
    pub(super) fn arm_accept_deadline(self: &Arc<Self>, command: &Command) {
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
    pub(super) async fn send_once(self: &Arc<Self>, command: &Command) -> Sent {
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

    pub(super) fn unreadable_goal_reply(
        self: &Arc<Self>,
        key: &str,
        command: &Command,
        why: String,
    ) -> Sent {
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

    pub(super) fn on_goal_reply(
        self: &Arc<Self>,
        key: &str,
        command: &Command,
        r: GoalReply,
    ) -> Sent {
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

    pub(super) fn acked(&self, goal_id: &str) {
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
    pub(super) async fn reconcile(self: Arc<Shared>, command: Command) {
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
    pub(super) fn start_asking(self: &Arc<Self>, goal_id: &str) {
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

    pub(super) async fn ask_loop(self: Arc<Shared>, goal_id: String) {
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
    pub(super) async fn ask_state(self: &Arc<Self>, command: &Command) -> Asked {
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

    pub(super) async fn cancel(
        self: Arc<Shared>,
        goal_id: String,
        action: String,
        reason: Option<String>,
    ) {
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
}
