//! What goes out of the driver: each committed action performed (a goal dispatched, a timer
//! armed, a message sent, a record line written), the present state for monitors, and the
//! goals and user tasks built from the model for the connectors.

use super::*;

impl Driver {
    /// Performs one action; `index` `usize::MAX` for re-commands (nothing to mark done).
    pub(super) fn perform(&mut self, seq: u64, index: usize, a: Action) -> Result<(), RunError> {
        match a {
            a @ (Action::DispatchTask { .. } | Action::OpenUserTask { .. }) => {
                // Done when the system acknowledges the goal (`Report::Accepted`), not now.
                let mark = (index != usize::MAX).then_some((seq, index as u32));
                self.command_of(a, false, mark);
                return Ok(());
            }
            Action::CancelTask { task } | Action::CloseUserTask { task } => {
                if let Some(f) = self.flights.remove(&task) {
                    self.goals.remove(&f.goal_id);
                    self.connectors.list[f.connector].abort(&f.goal_id);
                }
            }
            Action::StartTimer { timer, at } => self.arm(timer, at),
            Action::CancelTimer { timer } => {
                if let Some((_, Some(h))) = self.timers.remove(&timer) {
                    h.abort();
                }
                if let Some(a) = &self.agenda {
                    a.cancel_timer(timer);
                }
            }
            Action::Record(r) => self
                .record
                .write(seq, index, wall_ms(), &r)
                .map_err(|e| RunError::Io(e.to_string()))?,
            Action::SendMessage(m)
                if m.flow.is_some()
                    && m.number.is_some()
                    && m.to.as_ref().is_some_and(|to| {
                        self.post.as_ref().is_some_and(|p| p.peers.contains(to))
                    }) =>
            {
                let Outgoing {
                    name,
                    payload,
                    to,
                    flow,
                    correlation,
                    number,
                } = *m;
                // All there: the guard checked.
                let (Some(to), Some(flow), Some(number), Some(post)) =
                    (to, flow, number, self.post.as_mut())
                else {
                    return Ok(());
                };
                let letter =
                    post.letter(&self.mission, number, to, flow, name, correlation, &payload);
                let mark = (index != usize::MAX).then_some((seq, index as u32));
                crash_point("message-committed");
                let line = serde_json::json!({"seq": seq, "idx": index, "key": letter.key,
                    "to": letter.to, "flow": letter.flow, "name": letter.name});
                post.send(letter, mark);
                self.fleet_line("message_sent", line);
                // Done once its receiver gives a verdict.
                return Ok(());
            }
            Action::SendMessage(m) => {
                let Outgoing { name, payload, .. } = *m;
                match self.connectors.config.route(&name) {
                    Some(route) => {
                        let payload = serde_json::to_value(&payload).unwrap_or_default();
                        self.connectors.list[route.connector].notify(&route.action, payload);
                    }
                    None => {
                        tracing::info!(%name, "message sent out of the mission (no connector routes it)")
                    }
                }
            }
            Action::InstanceFinished { instance, outcome } => {
                tracing::info!(instance = instance.0, ?outcome, "instance finished");
            }
        }
        if index != usize::MAX {
            self.store.done(seq, index as u32)?;
        }
        Ok(())
    }

    /// The present state for a remote monitor.
    pub(super) fn snapshot(&self) -> serde_json::Value {
        let in_flight = self
            .flights
            .iter()
            .map(|(task, f)| {
                let node = self.engine.state().tokens.get(&task.token).map(|t| t.node);
                let mut v = serde_json::json!({"task": task.to_string(), "goal": f.goal_id,
                    "resource": f.resource, "user_task": f.user, "feedback": f.feedback,
                    "element": node.map(|n| self.g.node(n).id.as_str()),
                    "name": node.map(|n| self.g.node(n).label())});
                if f.user
                    && let Some(due) = self.deadline(*task)
                {
                    v["deadline_ms"] = serde_json::json!(due);
                }
                v
            })
            .collect();
        let mut state =
            crate::monitor::snapshot(&self.mission, &self.engine, self.last_at, in_flight);
        // What each connector refused (garbage, unknown goals, mistyped data, …), so an
        // operator sees that something on the bus is talking nonsense.
        let dropped: serde_json::Map<String, serde_json::Value> = self
            .connectors
            .list
            .iter()
            .map(|c| (c.name().to_owned(), serde_json::json!(c.dropped())))
            .collect();
        state["dropped"] = serde_json::Value::Object(dropped);
        state["reboots"] = serde_json::json!(self.reboots);
        // The mission clock now, and how fast it runs, so a page counts down to deadlines.
        state["clock"] =
            serde_json::json!({ "now_ms": self.clock.now(), "speed": self.clock.speed() });
        if let Some(p) = &self.post {
            state["fleet"] = p.state();
        }
        state
    }

    /// Arms (or re-arms) a timer for mission time `at` on the current clock.
    pub(super) fn arm(&mut self, timer: TimerKey, at: Millis) {
        if let Some(a) = &self.agenda {
            a.cancel_timer(timer);
            a.push(at, Due::Timer(timer));
            self.timers.insert(timer, (at, None));
            return;
        }
        let delay = self.clock.wall_delay(at);
        let tx = self.tx.clone();
        let h = tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            let _ = tx.send(Event::TimerFired { timer });
        });
        if let Some((_, Some(old))) = self.timers.insert(timer, (at, Some(h))) {
            old.abort();
        }
    }

    /// Switches to a system's clock; armed timers are re-armed against it.
    /// Systems report their clock several times a second; timers are re-armed only when the
    /// report disagrees with the clock in use (another speed, or drift beyond 10 ms of wall
    /// time).
    pub(super) fn set_clock(&mut self, clock: SystemClock) {
        let drift = (self.clock.now() - clock.now()).abs() as f64;
        if self.clock.speed() == clock.speed && drift <= 10.0 * clock.speed.max(1.0) {
            return;
        }
        self.clock = Box::new(clock);
        let armed: Vec<(TimerKey, Millis)> =
            self.timers.iter().map(|(k, (at, _))| (*k, *at)).collect();
        for (timer, at) in armed {
            self.arm(timer, at);
        }
    }

    /// The goal of a user task: which task (element id and name), the variables the
    /// operator sees, and the deadline — the earliest timer boundary on the task (mission
    /// time), when it has one.
    pub(super) fn user_goal(
        &self,
        task: TaskKey,
        node: executive_model::NodeId,
        context: Vars,
    ) -> Vars {
        let n = self.g.node(node);
        let mut goal = Vars::from([
            ("task".to_owned(), Value::String(n.id.clone())),
            ("name".to_owned(), Value::String(n.label().to_owned())),
            ("context".to_owned(), Value::Map(context)),
        ]);
        if let Some(due) = self.deadline(task) {
            goal.insert("deadline_ms".to_owned(), Value::Int(due));
        }
        goal
    }

    /// When the earliest timer boundary on a task fires (mission time), if it has one.
    pub(super) fn deadline(&self, task: TaskKey) -> Option<Millis> {
        self.engine
            .state()
            .waits
            .values()
            .filter(|w| w.token == Some(task.token))
            .filter_map(|w| match w.on {
                executive_engine::On::Timer { due, .. } => Some(due),
                _ => None,
            })
            .min()
    }

    /// The resource a user task is routed by: its binding's, else its element id.
    pub(super) fn user_resource(&self, node: executive_model::NodeId) -> String {
        match &self.g.node(node).kind {
            executive_model::NodeKind::Task(t) => {
                t.binding.as_ref().and_then(|b| b.resource.as_deref())
            }
            _ => None,
        }
        .unwrap_or(&self.g.node(node).id)
        .to_owned()
    }

    /// After a restart: asks the system about a command performed before the crash.
    pub(super) fn reconcile(&mut self, a: Action) {
        if let Some(task) = self.command_of(a, true, None)
            && let Some(f) = self.flights.get_mut(&task)
        {
            f.acked = true;
            self.arm_watchdog(task);
        }
    }

    /// A dispatch or a user task, sent (or, `reconcile`, asked about) through its connector;
    /// `mark` is the dispatch's place in the store, marked done once the system acknowledges
    /// the goal. Returns the task.
    pub(super) fn command_of(
        &mut self,
        a: Action,
        reconcile: bool,
        mark: Option<(u64, u32)>,
    ) -> Option<TaskKey> {
        match a {
            Action::DispatchTask {
                task,
                node,
                request,
            } => {
                let g = Arc::clone(&self.g);
                let resource = executive_engine::resource(&g, node);
                self.command(task, resource, request, false, reconcile, mark);
                Some(task)
            }
            Action::OpenUserTask {
                task,
                node,
                context,
            } => {
                let resource = self.user_resource(node);
                let fields = self.user_goal(task, node, context);
                self.command(task, &resource, fields, true, reconcile, mark);
                Some(task)
            }
            _ => None,
        }
    }

    /// Hands a command to the connector its resource routes to (idempotent by key). A
    /// resource no connector serves fails the task with `NO_CONNECTOR`.
    pub(super) fn command(
        &mut self,
        task: TaskKey,
        resource: &str,
        fields: Vars,
        user: bool,
        reconcile: bool,
        mark: Option<(u64, u32)>,
    ) {
        if self.flights.contains_key(&task) {
            return;
        }
        let goal_id = connector_api::keys::goal_id(
            &self.mission,
            task.instance.0,
            task.token.0,
            task.attempt,
        );
        let Some(route) = self.connectors.config.route(resource) else {
            let _ = self.tx.send(Event::TaskFailed {
                task,
                code: connector_api::wire::codes::NO_CONNECTOR.to_owned(),
                message: format!("no connector serves resource `{resource}`"),
            });
            return;
        };
        let fields = match serde_json::to_value(&fields) {
            Ok(serde_json::Value::Object(m)) => m,
            _ => Default::default(),
        };
        let command = Command {
            goal_id: goal_id.clone(),
            action: route.action,
            fields,
        };
        self.goals.insert(goal_id.clone(), task);
        self.flights.insert(
            task,
            Flight {
                connector: route.connector,
                goal_id,
                resource: resource.to_owned(),
                user,
                feedback: None,
                mark,
                acked: false,
                command: command.clone(),
            },
        );
        let c = &mut self.connectors.list[route.connector];
        if reconcile {
            c.reconcile(command);
        } else {
            c.execute(command);
        }
    }
}
