//! Events thrown: throw and end events (each acting at the end of its wave), errors and
//! escalations propagating to their catchers, signals broadcast, links, terminate.

use executive_model::{EventDefinition, NodeId, NodeKind, Scope, SubProcessKind};

use crate::events::Catcher;
use crate::io::{Entry, InstanceId, Outcome, ScopeId, TokenId, Trigger, WaitId};
use crate::run::{Run, triggers_of};
use crate::state::{At, On, ScopeKind};
use crate::value::{Value, Vars};

/// A throw or end event with these definitions throws (anything but a link or none), and so
/// acts at the end of its wave (`docs/engine-semantics.md`, "Within a step"). The verifier's
/// translation orders its throws by the same rule.
pub fn throws(defs: &[EventDefinition]) -> bool {
    !defs.iter().all(|d| matches!(d, EventDefinition::Link(_)))
}

impl Run<'_> {
    /// A throw — message, signal, error, escalation, compensation, cancel, terminate — takes
    /// effect after the other tokens of its wave have arrived (`docs/engine-semantics.md`,
    /// "Within a step"): the thrower is put back once behind them, still before the next wave,
    /// so parallel branches that moved with it reach their catch events and enter their
    /// activities first, and what they start moves after the throw. A link is a jump, not a
    /// throw.
    pub(crate) fn defer_throw(&mut self, t: TokenId, defs: &[EventDefinition]) -> bool {
        if !throws(defs) || self.throw_now.remove(&t) {
            return false;
        }
        let wave = self.wave;
        // Every other token of the wave, a thrower put back before it included: throwers act
        // in the order they arrived.
        let behind = self.ready.iter().any(|(u, w)| {
            *w <= wave && *u != t && self.s.tokens.get(u).is_some_and(|tok| tok.at == At::Ready)
        });
        if !behind {
            return false;
        }
        self.throw_now.insert(t);
        // Behind the last token of its wave, before the first of a later one (the queue stays
        // ordered by wave).
        let at = self
            .ready
            .iter()
            .position(|(_, w)| *w > wave)
            .unwrap_or(self.ready.len());
        self.ready.insert(at, (t, wave));
        true
    }

    /// An end event.
    pub(crate) fn end_event(&mut self, t: TokenId, defs: &[EventDefinition]) {
        if self.defer_throw(t, defs) {
            return;
        }
        let node = self.s.tokens[&t].node;
        for d in defs {
            if !self.s.tokens.contains_key(&t) {
                return;
            }
            match d {
                EventDefinition::Terminate => return self.terminate(t),
                EventDefinition::Error { error, .. } => {
                    let (code, message) = self.error_code(*error);
                    return self.throw_error(t, &code, &message, false);
                }
                EventDefinition::Cancel => return self.cancel_transaction(t),
                EventDefinition::Compensate { activity, .. } => {
                    if self.compensate(t, *activity) {
                        return;
                    }
                }
                _ => self.throw_one(t, node, d),
            }
        }
        if self.s.tokens.contains_key(&t) {
            self.leave(t);
        }
    }

    /// An intermediate throw event.
    pub(crate) fn throw_event(&mut self, t: TokenId, defs: &[EventDefinition]) {
        if self.defer_throw(t, defs) {
            return;
        }
        let node = self.s.tokens[&t].node;
        for d in defs {
            if !self.s.tokens.contains_key(&t) {
                return;
            }
            match d {
                EventDefinition::Link(name) => return self.link(t, name),
                EventDefinition::Compensate { activity, wait } => {
                    if self.compensate(t, *activity) && *wait {
                        return;
                    }
                }
                _ => self.throw_one(t, node, d),
            }
        }
        if self
            .s
            .tokens
            .get(&t)
            .is_some_and(|tok| tok.at != At::Compensating)
        {
            self.leave(t);
        }
    }

    /// Throws a message, signal or escalation.
    pub(crate) fn throw_one(&mut self, t: TokenId, node: NodeId, d: &EventDefinition) {
        let tok = &self.s.tokens[&t];
        let (instance, scope) = (tok.instance, tok.scope);
        match d {
            EventDefinition::Message(m) => {
                let name = self.message_name(*m);
                let payload = self.visible_vars(scope);
                self.send_message(instance, Some(node), scope, name, payload);
            }
            // A token game's anonymous signal goes to the nearest catcher up the scope chain,
            // like an escalation; with none there, it is broadcast.
            EventDefinition::Signal(None)
                if self.game.is_some()
                    && self.find_catcher(t, Trigger::Signal, "", false).is_some() =>
            {
                self.throw_up(t, Trigger::Signal, "");
            }
            EventDefinition::Signal(s) => {
                let name = self.signal_name(*s);
                self.broadcast(instance, Some(node), &name);
            }
            EventDefinition::Escalation(e) => {
                let code = self.escalation_code(*e);
                self.throw_escalation(t, &code);
            }
            _ => {}
        }
    }

    pub(crate) fn error_code(&self, e: Option<executive_model::ErrorId>) -> (String, String) {
        match e.map(|e| &self.g.errors[e.index()]) {
            Some(err) => (
                err.code.clone().unwrap_or_else(|| err.id.clone()),
                err.name.clone().unwrap_or_default(),
            ),
            None => (String::new(), String::new()),
        }
    }

    pub(crate) fn escalation_code(&self, e: Option<executive_model::EscalationId>) -> String {
        e.map(|e| &self.g.escalations[e.index()])
            .map(|x| x.code.clone().unwrap_or_else(|| x.id.clone()))
            .unwrap_or_default()
    }

    pub(crate) fn catches(&self, d: &EventDefinition, what: Trigger, code: &str) -> bool {
        // Compared in place: this runs for every boundary on every throw.
        match (d, what) {
            (EventDefinition::Error { error, .. }, Trigger::Error) => error.is_none_or(|e| {
                let x = &self.g.errors[e.index()];
                x.code.as_deref().unwrap_or(&x.id) == code
            }),
            (EventDefinition::Signal(None), Trigger::Signal) => true,
            (EventDefinition::Escalation(e), Trigger::Escalation) => e.is_none_or(|e| {
                let x = &self.g.escalations[e.index()];
                x.code.as_deref().unwrap_or(&x.id) == code
            }),
            _ => false,
        }
    }

    /// The catcher of an error or escalation thrown by token `t` (`own`: also the boundaries of
    /// `t`'s own activity, for a failing task). Specific catchers win over catch-alls at the
    /// same level.
    pub(crate) fn find_catcher(
        &self,
        t: TokenId,
        what: Trigger,
        code: &str,
        own: bool,
    ) -> Option<Catcher> {
        let g = self.g;
        let tok = self.s.tokens.get(&t)?;
        let boundary_of = |activity: NodeId| -> Option<NodeId> {
            let boundaries = &g.node(activity).boundaries;
            let catching = |b: &&NodeId, specific: bool| {
                triggers_of(g, **b)
                    .iter()
                    .any(|d| (!specific || !is_catch_all(d)) && self.catches(d, what, code))
            };
            boundaries
                .iter()
                .find(|b| catching(b, true))
                .or_else(|| boundaries.iter().find(|b| catching(b, false)))
                .copied()
        };
        if own && let Some(b) = boundary_of(tok.node) {
            return Some(Catcher::Boundary(t, b));
        }
        let mut scope = tok.scope;
        // Leaving an event sub-process, its siblings are not asked: an event sub-process does
        // not catch what it throws itself (a rethrow goes to the enclosing scope's parent).
        let mut from_event_sub = false;
        loop {
            let sc = self.s.scopes.get(&scope)?;
            let element = match sc.kind {
                ScopeKind::Process(p) => Some(Scope::Process(p)),
                ScopeKind::SubProcess(n) => Some(Scope::SubProcess(n)),
                _ => None,
            };
            if !from_event_sub
                && let Some(el) = element
                && let Some(start) = self.event_subprocess_start(el, what, code)
            {
                return Some(Catcher::EventSub(scope, start));
            }
            from_event_sub = matches!(sc.kind, ScopeKind::SubProcess(n)
                if matches!(&g.node(n).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event)));
            let owner = sc.owner?;
            let otok = self.s.tokens.get(&owner)?;
            if !from_event_sub && let Some(b) = boundary_of(otok.node) {
                return Some(Catcher::Boundary(owner, b));
            }
            scope = sc.parent?;
        }
    }

    pub(crate) fn event_subprocess_start(
        &self,
        el: Scope,
        what: Trigger,
        code: &str,
    ) -> Option<NodeId> {
        let g = self.g;
        let mut all = None;
        for &n in g.scope_nodes(el) {
            let NodeKind::SubProcess(sp) = &g.node(n).kind else {
                continue;
            };
            if !matches!(sp.kind, SubProcessKind::Event) {
                continue;
            }
            for &s in &sp.nodes {
                if let NodeKind::Start(st) = &g.node(s).kind {
                    for d in &st.triggers {
                        if self.catches(d, what, code) {
                            if !is_catch_all(d) {
                                return Some(s);
                            }
                            all = all.or(Some(s));
                        }
                    }
                }
            }
        }
        all
    }

    /// Throws a BPMN error from token `t`.
    pub(crate) fn throw_error(&mut self, t: TokenId, code: &str, message: &str, own: bool) {
        let Some(tok) = self.s.tokens.get(&t) else {
            return;
        };
        let (instance, node) = (tok.instance, tok.node);
        self.record(instance, || Entry::Thrown {
            what: Trigger::Error,
            name: code.into(),
            node: Some(node),
        });
        match self.find_catcher(t, Trigger::Error, code, own) {
            Some(Catcher::Boundary(owner, b)) => {
                let scope = self.s.tokens[&owner].scope;
                self.record(instance, || Entry::Caught {
                    what: Trigger::Error,
                    name: code.into(),
                    node: b,
                });
                self.error_variables(scope, b, code, message);
                self.withdraw(owner);
                self.spawn(scope, b, None);
            }
            Some(Catcher::EventSub(scope, start)) => {
                self.record(instance, || Entry::Caught {
                    what: Trigger::Error,
                    name: code.into(),
                    node: start,
                });
                self.clear_scope(scope, false);
                let mut vars = Vars::new();
                self.error_vars_into(&mut vars, start, code, message);
                let Scope::SubProcess(esp) = self.g.node(start).scope else {
                    return;
                };
                self.run_event_subprocess(scope, esp, start, vars);
            }
            None => self.finish_instance(
                instance,
                Outcome::Failed {
                    code: code.to_owned(),
                    message: message.to_owned(),
                },
            ),
        }
    }

    /// A task failed: the error goes to its boundaries first.
    pub(crate) fn task_error(&mut self, t: TokenId, code: &str, message: &str) {
        self.throw_error(t, code, message, true);
    }

    pub(crate) fn error_variables(
        &mut self,
        scope: ScopeId,
        node: NodeId,
        code: &str,
        message: &str,
    ) {
        let mut vars = Vars::new();
        self.error_vars_into(&mut vars, node, code, message);
        for (k, v) in vars {
            self.set_var(scope, &k, v);
        }
    }

    pub(crate) fn error_vars_into(&self, vars: &mut Vars, node: NodeId, code: &str, message: &str) {
        for d in triggers_of(self.g, node) {
            if let EventDefinition::Error {
                code_variable,
                message_variable,
                ..
            } = d
            {
                if let Some(c) = code_variable {
                    vars.insert(c.clone(), Value::from(code));
                }
                if let Some(m) = message_variable {
                    vars.insert(m.clone(), Value::from(message));
                }
            }
        }
    }

    /// Throws an escalation from token `t`; the token may be withdrawn by an interrupting
    /// catcher.
    pub(crate) fn throw_escalation(&mut self, t: TokenId, code: &str) {
        self.throw_up(t, Trigger::Escalation, code);
    }

    /// Throws an escalation (or, in a token game, an anonymous signal) to the nearest catcher
    /// up the scope chain; the token may be withdrawn by an interrupting catcher.
    pub(crate) fn throw_up(&mut self, t: TokenId, what: Trigger, code: &str) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (instance, node) = (tok.instance, tok.node);
        self.record(instance, || Entry::Thrown {
            what,
            name: code.into(),
            node: Some(node),
        });
        match self.find_catcher(t, what, code, false) {
            Some(Catcher::Boundary(owner, b)) => {
                let scope = self.s.tokens[&owner].scope;
                self.record(instance, || Entry::Caught {
                    what,
                    name: code.into(),
                    node: b,
                });
                let interrupting =
                    matches!(&g.node(b).kind, NodeKind::Boundary(x) if x.interrupting);
                if interrupting {
                    self.withdraw(owner);
                }
                self.spawn(scope, b, None);
            }
            Some(Catcher::EventSub(scope, start)) => {
                self.record(instance, || Entry::Caught {
                    what,
                    name: code.into(),
                    node: start,
                });
                let interrupting =
                    matches!(&g.node(start).kind, NodeKind::Start(s) if s.interrupting);
                if interrupting {
                    self.clear_scope(scope, false);
                }
                let Scope::SubProcess(esp) = g.node(start).scope else {
                    return;
                };
                self.run_event_subprocess(scope, esp, start, Vars::new());
            }
            None => {
                if what == Trigger::Escalation
                    && let Some(i) = self.s.instances.get_mut(&instance)
                {
                    i.uncaught_escalations.push(code.to_owned());
                }
            }
        }
    }

    /// Top-level start events (of executable processes this engine runs) matching `pred`.
    pub(crate) fn start_events_on(
        &self,
        pred: impl Fn(&EventDefinition, &Self) -> bool,
    ) -> Vec<(executive_model::ProcessId, NodeId)> {
        let g = self.g;
        let mut out = Vec::new();
        for (i, p) in g.processes.iter().enumerate() {
            let remote = self
                .remote
                .contains_key(&executive_model::ProcessId(i as u32));
            if (!p.executable && self.game.is_none()) || remote {
                continue;
            }
            for &n in &p.nodes {
                match &g.node(n).kind {
                    NodeKind::Start(s) if s.triggers.iter().any(|d| pred(d, self)) => {
                        out.push((executive_model::ProcessId(i as u32), n));
                    }
                    // A receive task with `instantiate` and no incoming flow starts the process.
                    NodeKind::Task(t)
                        if t.instantiate
                            && g.node(n).incoming.is_empty()
                            && pred(&EventDefinition::Message(t.message), self) =>
                    {
                        out.push((executive_model::ProcessId(i as u32), n));
                    }
                    _ => {}
                }
            }
        }
        out
    }

    /// Starts a new instance at a triggered start event.
    pub(crate) fn start_instance_at(
        &mut self,
        process: executive_model::ProcessId,
        start: NodeId,
        vars: Vars,
        what: Trigger,
        name: &str,
    ) -> InstanceId {
        let (instance, root) = self.open_instance(process, vars, None);
        self.record(instance, || Entry::Caught {
            what,
            name: name.into(),
            node: start,
        });
        self.subscribe_event_subprocesses(root, Scope::Process(process));
        let t = self.spawn(root, start, None);
        for n in self.implicit_starts(Scope::Process(process)) {
            if n != start {
                self.spawn(root, n, None);
            }
        }
        if self.g.node(start).is_activity() {
            // An instantiating receive task: its message has arrived.
            if let Some(tok) = self.s.tokens.get_mut(&t) {
                tok.at = At::Catching;
            }
            if self.trace_moves {
                self.record(instance, || Entry::Entered {
                    node: start,
                    token: t,
                });
            }
            self.subscribe_boundaries(t);
            self.complete_activity(t);
        }
        instance
    }

    /// Broadcasts a signal to every waiting catcher and every process that starts on it.
    pub(crate) fn broadcast(&mut self, instance: InstanceId, node: Option<NodeId>, name: &str) {
        if let Some(_i) = self.s.instances.get(&instance) {
            self.record(instance, || Entry::Thrown {
                what: Trigger::Signal,
                name: name.into(),
                node,
            });
        }
        // Inner scopes first (an event sub-process hears the signal before a boundary event
        // of its enclosing sub-process interrupts it); within a scope the non-interrupting
        // catchers before the interrupting ones (every catcher waiting when the signal is
        // thrown catches it, whatever the document order); then in subscription order.
        let g = self.g;
        let interrupting = |n: NodeId| match &g.node(n).kind {
            NodeKind::Start(s) => s.interrupting,
            NodeKind::Boundary(b) => b.interrupting,
            _ => false,
        };
        let depth = |mut s: ScopeId| {
            let mut d = 0usize;
            while let Some(p) = self.s.scopes.get(&s).and_then(|x| x.parent) {
                d += 1;
                s = p;
            }
            d
        };
        let mut waits: Vec<(std::cmp::Reverse<usize>, bool, WaitId)> = self
            .s
            .waits
            .iter()
            .filter(|(_, w)| matches!(&w.on, On::Signal(n) if n == name))
            .map(|(id, w)| (std::cmp::Reverse(depth(w.scope)), interrupting(w.node), *id))
            .collect();
        waits.sort();
        let waits: Vec<WaitId> = waits.into_iter().map(|(_, _, w)| w).collect();
        let starts = self.start_events_on(
            |d, r| matches!(d, EventDefinition::Signal(s) if r.signal_name(*s) == name),
        );
        for w in waits {
            self.trigger(w, Trigger::Signal, name.to_owned(), &Vars::new());
        }
        for (process, start) in starts {
            self.start_instance_at(process, start, Vars::new(), Trigger::Signal, name);
        }
    }

    /// A link throw: the token continues at the link catch event of the same name.
    pub(crate) fn link(&mut self, t: TokenId, name: &str) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, instance) = (tok.node, tok.instance);
        let target = g.scope_nodes(g.node(node).scope).iter().copied().find(|n| {
            matches!(&g.node(*n).kind, NodeKind::Catch(c) if c.triggers.iter().any(|d| matches!(d, EventDefinition::Link(l) if l == name)))
        });
        let Some(target) = target else {
            return self.incident(
                t,
                format!("no link catch event named `{name}` in this scope"),
            );
        };
        if self.trace_moves {
            self.record(instance, || Entry::Left { node, token: t });
        }
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.node = target;
            tok.via = None;
        }
        if self.trace_moves {
            self.record(instance, || Entry::Entered {
                node: target,
                token: t,
            });
        }
        self.leave(t);
    }

    /// A terminate end event: everything in the scope stops; the scope completes.
    pub(crate) fn terminate(&mut self, t: TokenId) {
        let tok = &self.s.tokens[&t];
        let (scope, instance) = (tok.scope, tok.instance);
        let root = self
            .s
            .scopes
            .get(&scope)
            .is_some_and(|s| s.parent.is_none());
        self.clear_scope(scope, false);
        if root {
            self.finish_instance(instance, Outcome::Terminated);
        } else {
            self.complete_scope(scope);
        }
    }
}

fn is_catch_all(d: &EventDefinition) -> bool {
    matches!(
        d,
        EventDefinition::Error { error: None, .. } | EventDefinition::Escalation(None)
    )
}
