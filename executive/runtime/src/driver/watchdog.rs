//! The watchdog: no task waits without end on a system that accepted its goal and went silent
//! (on for a connector whose `limits.overrun_margin_ms` is set). A goal is due, counted from
//! its acknowledgement (or from the restart that asked about it), by its action's declared
//! maximum duration (the catalogue's `cost`, resolved for the goal's fields;
//! `limits.overrun_default_ms` when none is declared) plus `limits.overrun_margin_ms`, in
//! mission time, and at least a second of wall time. Then the executive asks the system for the
//! goal's state (an unanswered state query counts as an answer it could not understand, §4.4 of
//! `docs/protocol.md`); if the goal has not ended `overrun_state_wait_ms` (wall time) later, the
//! task fails with `OVERRUN`, which a boundary may catch, and the system is sent a cancel.

use std::time::Duration;

use connector_api::Kind;
use executive_engine::{Event, TaskKey};

use super::Driver;

/// One watchdog stage due for a goal.
pub(super) struct Watch {
    task: TaskKey,
    goal_id: String,
    /// 1: ask the state; 2: fail with `OVERRUN`.
    stage: u8,
}

impl Driver {
    /// Arms the watchdog of the goal of `task`, just acknowledged by its system (a goal not yet
    /// acknowledged has `accept_within_ms`; user tasks, ground stations and the scripted
    /// connector have none).
    pub(super) fn arm_watchdog(&self, task: TaskKey) {
        let Some(f) = self.flights.get(&task).filter(|f| !f.user) else {
            return;
        };
        let (connector, command) = (f.connector, &f.command);
        let cfg = &self.connectors.config.connectors[connector];
        if cfg.kind == Kind::Script || cfg.answers {
            return;
        }
        let limits = &cfg.limits;
        let Some(margin) = limits.overrun_margin_ms else {
            return;
        };
        let fields = &command.fields;
        let declared = self
            .connectors
            .catalogues
            .get(connector)
            .and_then(Option::as_ref)
            .and_then(|c| c.action(&command.action))
            .and_then(|a| a.cost.as_ref())
            .and_then(|cost| {
                cost.duration_s
                    .range(|f| Ok(fields.get(f).and_then(serde_json::Value::as_f64)))
                    .ok()
            })
            .map(|(_, hi)| hi * 1000.0)
            .filter(|hi| hi.is_finite());
        let most = match declared {
            Some(ms) => ms,
            None if limits.overrun_default_ms > 0 => limits.overrun_default_ms as f64,
            None => return,
        };
        let due = self.clock.now() + most as i64 + margin as i64;
        // At least a second of wall time: a fast mission clock must not outrun the transport.
        let delay = self.clock.wall_delay(due).max(Duration::from_secs(1));
        self.watch_later(task, command.goal_id.clone(), 1, delay);
    }

    fn watch_later(&self, task: TaskKey, goal_id: String, stage: u8, delay: Duration) {
        let tx = self.watch_tx.clone();
        tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            let _ = tx.send(Watch {
                task,
                goal_id,
                stage,
            });
        });
    }

    /// A watchdog stage is due: nothing if the goal has ended since.
    pub(super) fn on_watch(&mut self, w: Watch) {
        let Some(f) = self.flights.get(&w.task).filter(|f| f.goal_id == w.goal_id) else {
            return;
        };
        let connector = f.connector;
        let limits = self.connectors.config.connectors[connector].limits.clone();
        if w.stage == 1 {
            tracing::warn!(
                goal = w.goal_id,
                resource = f.resource,
                "the goal ran past its action's declared maximum duration; asking the system for its state"
            );
            let command = f.command.clone();
            self.connectors.list[connector].reconcile(command);
            let wait = Duration::from_millis(limits.overrun_state_wait_ms);
            self.watch_later(w.task, w.goal_id, 2, wait);
            return;
        }
        let resource = f.resource.clone();
        self.flights.remove(&w.task);
        self.goals.remove(&w.goal_id);
        self.connectors.list[connector].abort(&w.goal_id);
        let message = format!(
            "`{resource}` ran past its declared maximum duration by more than {} ms of mission time, and the system did not end it within {} ms of being asked its state (the system is sent a cancel)",
            limits.overrun_margin_ms.unwrap_or_default(),
            limits.overrun_state_wait_ms
        );
        tracing::warn!(goal = w.goal_id, "{message}");
        let _ = self.tx.send(Event::TaskFailed {
            task: w.task,
            code: connector_api::wire::codes::OVERRUN.to_owned(),
            message,
        });
    }
}
