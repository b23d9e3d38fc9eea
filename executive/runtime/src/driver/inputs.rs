//! What comes into the driver: whether the run has ended or waits, the next due timer, each
//! connector report turned into an engine input, answers and letters applied, and every input
//! stepped and committed before its actions are performed.

use super::*;

impl Driver {
    pub(super) fn finished(&self) -> bool {
        let i = &self.engine.state().instances;
        !i.is_empty() && i.values().all(|i| i.outcome.is_some()) && self.quiet_link()
    }

    /// What the run waits for now.
    pub(super) fn assess(&self) -> Assessment {
        let s = self.engine.state();
        let unstarted: Vec<_> = self
            .unstarted
            .iter()
            .copied()
            .filter(|p| !s.instances.values().any(|i| i.process == *p))
            .collect();
        let held = |k: TaskKey| {
            if self.flights.contains_key(&k) {
                Some(Ok(()))
            } else {
                self.refused.get(&k).map(|why| Err(why.clone()))
            }
        };
        crate::waiting::assess(&self.g, s, self.outside, &held, &unstarted)
    }

    /// The next thing due on the virtual clock, as an input (the clock moves to it).
    pub(super) fn due_event(&mut self) -> Option<Event> {
        match self.agenda.as_ref()?.advance()? {
            Due::Timer(timer) => Some(Event::TimerFired { timer }),
            Due::Goal { answer, .. } => answer().and_then(|r| self.event_of(r)),
        }
    }

    /// How far (wall time) an awaited thing is, if known: a timer's or a scripted answer's
    /// deadline.
    pub(super) fn distance(&self, item: &Item) -> Option<Duration> {
        match &item.what {
            What::Timer { due } => Some(self.clock.wall_delay(*due)),
            What::Task { task, .. } | What::UserTask { task } => {
                let goal = &self.flights.get(task)?.goal_id;
                let due = self.agenda.as_ref()?.goal_due(goal)?;
                Some(self.clock.wall_delay(due))
            }
            _ => None,
        }
    }

    /// Tells new incidents at once, and, when only outside things (or far ones) are awaited,
    /// what the run waits for: at once when that starts or changes, then every
    /// `report_every`. Returns when to look again (wall time).
    pub(super) fn watch(&mut self, a: &Assessment) -> Option<tokio::time::Instant> {
        for i in &a.incidents {
            if self
                .told
                .insert((i.instance, i.element.clone(), i.message.clone()))
            {
                tracing::warn!(instance = i.instance, element = %i.element, message = %i.message, "incident");
                eprintln!("{i}");
            }
        }
        let now = std::time::Instant::now();
        let mission_now = self.clock.now().max(self.last_at);
        self.since
            .retain(|k, _| a.awaited.iter().any(|i| &i.key == k));
        for i in &a.awaited {
            self.since
                .entry(i.key.clone())
                .or_insert((mission_now, now));
        }
        let every = self.report_every?;
        // Busy: something is due soon, or a task on an outside system is young.
        let mut recheck: Option<std::time::Instant> = None;
        let mut busy = false;
        for i in &a.awaited {
            match (self.distance(i), &i.what) {
                (Some(d), _) => busy |= d < SOON,
                (None, What::Task { .. }) => {
                    let (_, seen) = self.since[&i.key];
                    if now.duration_since(seen) < SOON {
                        busy = true;
                        let at = seen + SOON;
                        recheck = Some(recheck.map_or(at, |r| r.min(at)));
                    }
                }
                _ => {}
            }
        }
        if busy || a.awaited.is_empty() {
            self.reported = None;
            return recheck.map(tokio::time::Instant::from_std);
        }
        let listed: Vec<String> = a
            .awaited
            .iter()
            .filter(|i| i.what != What::Join)
            .map(|i| i.key.clone())
            .collect();
        let due = match &self.reported {
            Some((at, before)) => *before != listed || now.duration_since(*at) >= every,
            None => true,
        };
        if due {
            eprintln!(
                "waiting (mission time {}) for:",
                crate::waiting::mission_time(mission_now)
            );
            for i in a.awaited.iter().filter(|i| i.what != What::Join) {
                let since = crate::waiting::mission_time(self.since[&i.key].0);
                tracing::info!(
                    what = i.kind(),
                    element = %i.element,
                    name = i.name.as_deref().unwrap_or_default(),
                    instance = i.instance,
                    since = %since,
                    "waiting for {}",
                    i.describe()
                );
                let scripted = match &i.what {
                    What::Task { task, .. } | What::UserTask { task } => self
                        .flights
                        .get(task)
                        .and_then(|f| self.agenda.as_ref()?.goal_due(&f.goal_id))
                        .map(|t| {
                            format!(
                                ", the script answers at {}",
                                crate::waiting::mission_time(t)
                            )
                        }),
                    _ => None,
                };
                eprintln!(
                    "  {}, since {since}{}",
                    i.describe(),
                    scripted.unwrap_or_default()
                );
            }
            self.reported = Some((now, listed));
        }
        self.reported
            .as_ref()
            .map(|(at, _)| tokio::time::Instant::from_std(*at + every))
    }

    /// The input a connector report stands for, if any. Reports of goals no longer in flight
    /// (a result after an abort, a duplicate) are dropped.
    pub(super) fn event_of(&mut self, report: Report) -> Option<Event> {
        let task_of = |goals: &HashMap<String, TaskKey>, id: &str| goals.get(id).copied();
        match report {
            Report::Data { key, value } => match serde_json::from_value::<Value>(value) {
                Ok(value) => Some(Event::DataChanged { key, value }),
                Err(e) => {
                    tracing::warn!(key, error = %e, "system data ignored");
                    None
                }
            },
            Report::Clock { mission_ms, speed } => {
                self.set_clock(SystemClock::new(mission_ms, speed));
                None
            }
            Report::Accepted { goal_id } => {
                let task = task_of(&self.goals, &goal_id)?;
                if let Some(f) = self.flights.get_mut(&task) {
                    let first = !f.acked;
                    f.acked = true;
                    self.acked.extend(f.mark.take());
                    // The goal runs from now: the watchdog counts from here.
                    if first {
                        self.arm_watchdog(task);
                    }
                }
                self.note("accepted", task, &goal_id, serde_json::json!({}));
                None
            }
            Report::Feedback {
                goal_id,
                progress_pct,
                fields,
            } => {
                let task = task_of(&self.goals, &goal_id)?;
                let body = serde_json::json!({ "progress_pct": progress_pct, "fields": fields });
                if let Some(f) = self.flights.get_mut(&task) {
                    f.feedback = Some(body.clone());
                }
                self.note("feedback", task, &goal_id, body);
                None
            }
            r @ (Report::Letter { .. } | Report::Delivered { .. } | Report::Peer { .. }) => {
                self.fleet_report(r);
                None
            }
            Report::Canceled { goal_id } => {
                tracing::debug!(goal_id, "goal cancelled");
                None
            }
            Report::Answer {
                goal_id,
                fields,
                operator,
                verdict,
            } => {
                let task = match self.goals.get(&goal_id) {
                    Some(t) if self.flights.get(t).is_some_and(|f| f.user) => *t,
                    _ => {
                        let same =
                            serde_json::from_value::<Vars>(serde_json::Value::Object(fields)).ok();
                        verdict.give(match self.answered.get(&goal_id) {
                            Some((by, answer))
                                if *by == operator && same.as_ref() == Some(answer) =>
                            {
                                Ok(())
                            }
                            Some((by, _)) => {
                                Err(format!("user task `{goal_id}` is closed: answered by {by}"))
                            }
                            None => Err(format!("no open user task has goal id `{goal_id}`")),
                        });
                        return None;
                    }
                };
                match serde_json::from_value::<Vars>(serde_json::Value::Object(fields)) {
                    Ok(answer) => self.answers.push((
                        goal_id,
                        Event::UserTaskAnswered {
                            task,
                            answer,
                            operator,
                        },
                        verdict,
                    )),
                    Err(e) => verdict.give(Err(format!("the answer's values do not convert: {e}"))),
                }
                None
            }
            Report::Done { goal_id, outputs } => {
                let task = self.goals.remove(&goal_id)?;
                let flight = self.flights.remove(&task)?;
                let vars: Vars = outputs
                    .into_iter()
                    .filter_map(|(k, v)| Some((k, serde_json::from_value(v).ok()?)))
                    .collect();
                Some(if flight.user {
                    let operator = match vars.get("operator") {
                        Some(Value::String(s)) => s.clone(),
                        _ => self.connectors.list[flight.connector].name().to_owned(),
                    };
                    Event::UserTaskAnswered {
                        task,
                        answer: vars,
                        operator,
                    }
                } else {
                    Event::TaskCompleted { task, output: vars }
                })
            }
            Report::Failed {
                goal_id,
                code,
                message,
            } => {
                let task = self.goals.remove(&goal_id)?;
                self.flights.remove(&task);
                Some(Event::TaskFailed {
                    task,
                    code,
                    message,
                })
            }
        }
    }

    /// A line of the execution record about a goal, written by the executive (not a step).
    pub(super) fn note(
        &mut self,
        kind: &str,
        task: TaskKey,
        goal_id: &str,
        body: serde_json::Value,
    ) {
        if let Err(e) = self.record.activity(
            kind,
            &task.to_string(),
            goal_id,
            self.clock.now(),
            wall_ms(),
            body,
        ) {
            tracing::warn!(error = %e, "record line not written");
        }
    }

    /// Operators' answers, one step each: the verdict goes back once the step is committed
    /// (applied) or refused by the engine (nothing changed) — a task closed meanwhile by a
    /// boundary event refuses the answer.
    pub(super) fn apply_answers(&mut self) -> Result<(), RunError> {
        for (goal_id, event, verdict) in std::mem::take(&mut self.answers) {
            // Out of flight first, so closing the answered task withdraws it from no station.
            let task = self.goals.remove(&goal_id);
            let flight = task.and_then(|t| self.flights.remove(&t));
            let applied = match &event {
                Event::UserTaskAnswered {
                    operator, answer, ..
                } => Some((operator.clone(), answer.clone())),
                _ => None,
            };
            let refused = self
                .feed_all(vec![event])?
                .pop()
                .flatten()
                .map(|r| r.to_string());
            match refused {
                None => {
                    self.answered.extend(applied.map(|a| (goal_id, a)));
                    verdict.give(Ok(()));
                }
                Some(reason) => {
                    if let (Some(task), Some(flight)) = (task, flight) {
                        self.goals.insert(goal_id, task);
                        self.flights.insert(task, flight);
                    }
                    verdict.give(Err(reason));
                }
            }
        }
        Ok(())
    }

    /// Inputs stepped in order, committed together (one flush), then acted on. Returns, per
    /// input, why the engine refused it (`None`: stepped).
    pub(super) fn feed_all(
        &mut self,
        events: Vec<Event>,
    ) -> Result<Vec<Option<Rejected>>, RunError> {
        let mut steps = Vec::with_capacity(events.len());
        let mut refusals = Vec::with_capacity(events.len());
        for event in events {
            if let Event::TimerFired { timer } = &event {
                self.timers.remove(timer);
            }
            let input = Input {
                seq: self.seq + 1,
                at: self.clock.now().max(self.last_at),
                event,
            };
            match self.engine.step(input.clone()) {
                Ok(actions) => {
                    self.seq = input.seq;
                    self.last_at = input.at;
                    steps.push((input, actions));
                    refusals.push(None);
                }
                Err(rejected) => {
                    // A timer firing just after the step that disarmed it, or a result racing
                    // the cancel of its task, is a race the engine settles: not news.
                    if matches!(
                        rejected,
                        Rejected::UnknownTimer(_)
                            | Rejected::UnknownTask(_)
                            | Rejected::AlreadyDelivered(_)
                    ) {
                        tracing::debug!(%rejected, "input refused (a harmless race)");
                    } else {
                        tracing::warn!(%rejected, "input refused");
                    }
                    if let Event::TaskCompleted { task, .. }
                    | Event::TaskFailed { task, .. }
                    | Event::UserTaskAnswered { task, .. } = &input.event
                    {
                        self.refused
                            .insert(*task, format!("its result was refused: {rejected}"));
                    }
                    refusals.push(Some(rejected));
                }
            }
        }
        if steps.is_empty() {
            return Ok(refusals);
        }
        self.store.commit_batch(&steps)?;
        let mut snapshot = false;
        for (input, actions) in steps {
            snapshot |= input.seq.is_multiple_of(self.snapshot_every);
            for (i, a) in actions.into_iter().enumerate() {
                self.perform(input.seq, i, a)?;
            }
        }
        if snapshot {
            // First the goals no system has acknowledged, then the snapshot after which their
            // dispatches are no longer replayed (a crash between the two only sends more again).
            let unacked: Vec<TaskKey> = self
                .flights
                .iter()
                .filter(|(_, f)| !f.acked)
                .map(|(task, _)| *task)
                .collect();
            let unacked = serde_json::to_string(&unacked).unwrap_or_else(|_| "[]".to_owned());
            self.store.set_meta(UNACKED, &unacked)?;
            if let Some(p) = &self.post {
                self.store.set_meta(fleet::UNSENT, &p.unsent_json())?;
            }
            self.store.snapshot(self.seq, self.engine.state())?;
        }
        Ok(refusals)
    }

    /// Marks the dispatches whose goals were acknowledged as done (flushed with the next
    /// commit: a mark lost in a crash only sends a goal again). A dispatch whose step was
    /// pruned since is covered by the snapshot's list instead.
    pub(super) fn mark_acked(&mut self) -> Result<(), RunError> {
        for (seq, index) in std::mem::take(&mut self.acked) {
            match self.store.done(seq, index) {
                Err(StoreError::UnknownAction { .. }) => {
                    tracing::debug!(seq, index, "acknowledged dispatch already pruned");
                }
                other => other?,
            }
        }
        Ok(())
    }
}
