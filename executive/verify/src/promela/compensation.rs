//! Compensation and cancelled transactions.
//!
//! A compensable activity (one with a compensation handler, or a sub-process with something
//! compensable inside or a compensation event sub-process) sets its mark `comp[k]` when it
//! completes; a new activation of its scope clears it. A compensation throw (intermediate or
//! end) in a scope — in an event sub-process: the scope that sits in — starts the handlers of
//! the marked activities there (or only the one its `activityRef` names), clearing their
//! marks: a task's handler; for a sub-process its compensation event sub-process, else the
//! handlers of its own marked activities, then its own handler. The thrower waits in its slot
//! until all handlers it may have started are idle (unless `waitForCompletion` is false).
//!
//! The engine runs the handlers one after another, newest first; the translation starts them
//! together and lets them interleave, which covers every order (Spin may over-approximate).
//!
//! A cancel end event cancels the nearest enclosing transaction, starts the handlers of the
//! transaction's marked activities, waits for them, then takes the transaction's cancel
//! boundary event (without one, the path ends there).

use super::*;

impl Tr<'_> {
    /// `n` may need compensating once completed.
    pub(super) fn compensable(&self, n: NodeId) -> bool {
        let node = self.g.node(n);
        if !node.is_activity() || node.for_compensation || is_event_sub(self.g, n) {
            return false;
        }
        node.compensation_handler.is_some()
            || match &node.kind {
                NodeKind::SubProcess(sp) => {
                    self.compensation_start(n).is_some()
                        || sp.nodes.iter().any(|m| self.compensable(*m))
                }
                _ => false,
            }
    }

    /// The compensation start event of the event sub-process directly inside sub-process `sp`.
    fn compensation_start(&self, sp: NodeId) -> Option<NodeId> {
        self.event_sub_starts(Scope::SubProcess(sp))
            .into_iter()
            .find(|s| {
                matches!(&self.g.node(*s).kind, NodeKind::Start(st)
                if st.triggers.iter().any(|d| matches!(d, EventDefinition::Compensate { .. })))
            })
    }

    /// The compensable activities a compensation thrown at `n` compensates (its `activity`
    /// only, if named).
    fn compensation_targets(&self, n: NodeId, activity: Option<NodeId>) -> Vec<NodeId> {
        let mut scope = self.g.node(n).scope;
        if let Scope::SubProcess(e) = scope
            && is_event_sub(self.g, e)
        {
            scope = self.g.node(e).scope;
        }
        self.direct(scope)
            .into_iter()
            .filter(|m| activity.is_none_or(|a| a == *m))
            .collect()
    }

    /// The compensable activities directly in `scope`.
    fn direct(&self, scope: Scope) -> Vec<NodeId> {
        self.g
            .scope_nodes(scope)
            .iter()
            .copied()
            .filter(|m| self.compensable(*m))
            .collect()
    }

    /// The handlers compensating `targets` may start (activities and compensation event
    /// sub-processes), for the waiter's guard.
    fn handlers(&self, targets: &[NodeId]) -> Vec<NodeId> {
        let mut out = Vec::new();
        for &t in targets {
            if matches!(self.g.node(t).kind, NodeKind::SubProcess(_)) {
                match self
                    .compensation_start(t)
                    .and_then(|s| self.event_sub_of(s))
                {
                    Some(e) => out.push(e),
                    None => out.extend(self.handlers(&self.direct(Scope::SubProcess(t)))),
                }
            }
            out.extend(self.g.node(t).compensation_handler);
        }
        out
    }

    /// Effects starting the handlers of the marked activities among `targets`.
    fn compensate(&mut self, c: usize, targets: &[NodeId], alt: &mut Alt) {
        for &t in targets {
            let Some(k) = self.comp_ix.get(&(c, t)).copied() else {
                continue;
            };
            let mut inner = Alt::default();
            inner.effect.push(format!("comp[{k}] = 0"));
            if matches!(self.g.node(t).kind, NodeKind::SubProcess(_)) {
                match self.compensation_start(t) {
                    Some(start) => {
                        self.ask(c, start, &mut inner);
                        self.fired(c, start, &mut inner);
                    }
                    None => {
                        let inside = self.direct(Scope::SubProcess(t));
                        self.compensate(c, &inside, &mut inner);
                    }
                }
            }
            if let Some(h) = self.g.node(t).compensation_handler {
                self.ask(c, h, &mut inner);
            }
            alt.effect.push(format!(
                "if :: comp[{k}] -> {} :: else -> skip fi",
                inner.effect.join("; ")
            ));
        }
    }

    /// The guard that every handler in `handlers` is idle.
    fn handlers_idle(&self, c: usize, handlers: &[NodeId]) -> String {
        let mut parts: Vec<String> = handlers
            .iter()
            .map(|h| match self.pend_ix.get(&(c, *h)) {
                Some(k) => format!("!act[{}] && pend[{k}] == 0", self.a(c, *h)),
                None => self.esp_idle(c, *h),
            })
            .collect();
        parts.sort();
        parts.dedup();
        if parts.is_empty() {
            "true".to_owned()
        } else {
            parts.join(" && ")
        }
    }

    /// A compensation thrown at `n` (context `c`): handlers started; `true` if the token waits
    /// in `n`'s slot for them.
    pub(super) fn compensation_thrown(
        &mut self,
        c: usize,
        n: NodeId,
        activity: Option<NodeId>,
        wait: bool,
        alt: &mut Alt,
    ) -> bool {
        let targets = self.compensation_targets(n, activity);
        self.compensate(c, &targets, alt);
        let waits = wait || matches!(self.g.node(n).kind, NodeKind::End(_));
        if waits {
            alt.effect.push(format!("act[{}] = 1", self.a(c, n)));
        }
        waits
    }

    /// A cancel end event at `n`: the enclosing transaction cancelled, its handlers started,
    /// the end event waiting for them.
    pub(super) fn cancelled(&mut self, c: usize, n: NodeId, alt: &mut Alt) {
        let Some(t) = self.transaction_of(n) else {
            return;
        };
        let targets = self.direct(Scope::SubProcess(t));
        self.cancel(c, t, alt);
        self.compensate(c, &targets, alt);
        alt.effect.push(format!("act[{}] = 1", self.a(c, n)));
    }

    /// The nearest transaction around `n` (in its process).
    pub(super) fn transaction_of(&self, n: NodeId) -> Option<NodeId> {
        let mut scope = self.g.node(n).scope;
        while let Scope::SubProcess(s) = scope {
            if matches!(&self.g.node(s).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Transaction))
            {
                return Some(s);
            }
            scope = self.g.node(s).scope;
        }
        None
    }

    /// The step that lets a waiting compensation throw or cancel end go on once its handlers
    /// are idle: a throw continues on its outgoing flows, a cancel end takes the transaction's
    /// cancel boundary, a compensation end is done.
    pub(super) fn resume(&mut self, c: usize, n: NodeId) {
        let g = self.g;
        let node = g.node(n);
        let defs: &[EventDefinition] = match &node.kind {
            NodeKind::Throw(d) | NodeKind::End(d) => d,
            _ => return,
        };
        let Some(a) = self.act_ix.get(&(c, n)).copied() else {
            return;
        };
        let mut targets = Vec::new();
        let mut cancel = None;
        let mut waits = matches!(node.kind, NodeKind::End(_));
        for d in defs {
            match d {
                EventDefinition::Compensate { activity, wait } => {
                    targets.extend(self.compensation_targets(n, *activity));
                    waits |= *wait;
                }
                EventDefinition::Cancel => {
                    cancel = self.transaction_of(n);
                    if let Some(t) = cancel {
                        targets.extend(self.direct(Scope::SubProcess(t)));
                    }
                }
                _ => {}
            }
        }
        if !waits && cancel.is_none() {
            return;
        }
        let handlers = self.handlers(&targets);
        let idle = self.handlers_idle(c, &handlers);
        self.waiters.push((a, idle.clone()));
        let m = self.marker(c, n, "compensated");
        let mut alt = Alt::default();
        alt.guard.push(format!("act[{a}]"));
        alt.guard.push(idle);
        alt.effect.push(format!("act[{a}] = 0"));
        match (cancel, &node.kind) {
            (Some(t), _) => {
                let boundary = self.g.node(t).boundaries.iter().copied().find(|b| {
                    self.triggers(*b)
                        .iter()
                        .any(|d| matches!(d, EventDefinition::Cancel))
                });
                if let Some(b) = boundary {
                    let outs = self.g.node(b).outgoing.clone();
                    self.put_all(c, &outs, &mut alt);
                    let mb = self.marker(c, b, "fire");
                    alt.effect.push(format!("printf(\"@@BPMN {mb}\\n\")"));
                    let id = self.g.node(b).id.clone();
                    alt.effect.extend(self.observed(&id, "fire"));
                }
            }
            (None, NodeKind::Throw(_)) => {
                let outs = node.outgoing.clone();
                self.put_all(c, &outs, &mut alt);
            }
            _ => {}
        }
        self.push(&m, alt);
    }

    /// The compensation mark a completing activity sets.
    pub(super) fn completed(&self, c: usize, n: NodeId) -> Option<String> {
        self.comp_ix.get(&(c, n)).map(|k| format!("comp[{k}] = 1"))
    }
}
