//! Events: subscriptions and their triggering, throw and end events, errors, escalations,
//! signals, messages, links, terminate, transactions and compensation.

use executive_model::{EventDefinition, NodeId, NodeKind, Scope, SubProcessKind};

use crate::eval;
use crate::io::{Action, Entry, InstanceId, Outcome, ScopeId, TimerKey, TokenId, Trigger, WaitId};
use crate::run::{Run, triggers_of};
use crate::state::{At, Compensable, CompensationRun, Handler, On, ScopeKind, Wait};
use crate::value::{Value, Vars};

/// Where a thrown error or escalation is caught.
enum Catcher {
    /// A boundary event on the activity of this token.
    Boundary(TokenId, NodeId),
    /// An event sub-process start inside this scope.
    EventSub(ScopeId, NodeId),
}

impl Run<'_> {
    /// Subscribes a waiting token to one subscription.
    pub(crate) fn subscribe(&mut self, t: TokenId, node: NodeId, on: On) -> WaitId {
        let tok = &self.s.tokens[&t];
        let (instance, scope) = (tok.instance, tok.scope);
        let id = WaitId(self.mint());
        self.s.waits.insert(
            id,
            Wait {
                instance,
                node,
                token: Some(t),
                scope,
                on,
            },
        );
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.waits.push(id);
        }
        id
    }

    /// Subscribes to event definition `i` of `node` for token `t` (or, without a token, for the
    /// event sub-process starts of `scope`).
    fn subscribe_def(
        &mut self,
        t: Option<TokenId>,
        scope: ScopeId,
        node: NodeId,
        def: &EventDefinition,
        i: usize,
    ) {
        let on = match def {
            EventDefinition::Message(m) => On::Message(self.message_name(*m), None),
            EventDefinition::Signal(s) => On::Signal(self.signal_name(*s)),
            EventDefinition::Conditional(_) => On::Condition {
                trigger: i,
                last: false,
            },
            EventDefinition::Timer(_) => On::Timer {
                key: TimerKey {
                    instance: InstanceId(0),
                    wait: crate::io::WaitId(0),
                    firing: 0,
                },
                due: 0,
                left: None,
            },
            _ => return,
        };
        let w = match t {
            Some(t) => self.subscribe(t, node, on),
            None => {
                let instance = self.s.scopes[&scope].instance;
                let id = WaitId(self.mint());
                self.s.waits.insert(
                    id,
                    Wait {
                        instance,
                        node,
                        token: None,
                        scope,
                        on,
                    },
                );
                if let Some(sc) = self.s.scopes.get_mut(&scope) {
                    sc.waits.push(id);
                }
                id
            }
        };
        if let EventDefinition::Timer(timer) = def {
            let lookup_scope = t
                .and_then(|t| self.s.tokens.get(&t))
                .map_or(scope, |t| t.scope);
            match eval::deadline(timer, self.now, &|n| self.lookup(lookup_scope, n)) {
                Ok((due, left)) => self.arm(w, due, left, 1),
                // A token game's timers without a value fire only when triggered.
                Err(_) if self.game.is_some() => self.arm(w, crate::io::Millis::MAX, Some(0), 1),
                Err(e) => {
                    self.unsubscribe(w);
                    if let Some(t) = t {
                        self.incident(t, format!("timer: {e}"));
                    }
                }
            }
        }
    }

    fn arm(&mut self, w: WaitId, due: crate::io::Millis, left: Option<u32>, firing: u32) {
        let Some(wait) = self.s.waits.get_mut(&w) else {
            return;
        };
        let key = TimerKey {
            instance: wait.instance,
            wait: w,
            firing,
        };
        wait.on = On::Timer { key, due, left };
        let (instance, node) = (wait.instance, wait.node);
        self.record(
            instance,
            Entry::TimerStarted {
                timer: key,
                node,
                due,
            },
        );
        self.out.push(Action::StartTimer {
            timer: key,
            at: due,
        });
    }

    /// After a subscription fired and stays: re-arms a repeating timer, or drops a spent one.
    fn rearm(&mut self, w: WaitId) {
        let Some(wait) = self.s.waits.get(&w).cloned() else {
            return;
        };
        let On::Timer { key, due, left } = wait.on else {
            return;
        };
        let timer = triggers_of(self.g, wait.node).iter().find_map(|d| match d {
            EventDefinition::Timer(t) => Some(t),
            _ => None,
        });
        let next = timer.and_then(|t| eval::next_deadline(t, due));
        match (left, next) {
            (Some(0), _) | (_, None) => {
                self.s.waits.remove(&w);
                if let Some(t) = wait.token
                    && let Some(tok) = self.s.tokens.get_mut(&t)
                {
                    tok.waits.retain(|x| *x != w);
                }
            }
            (left, Some(next)) => self.arm(w, next, left.map(|l| l - 1), key.firing + 1),
        }
    }

    pub(crate) fn signal_name(&self, s: Option<executive_model::SignalId>) -> String {
        s.map(|s| self.g.signals[s.index()].name.clone())
            .unwrap_or_default()
    }

    /// Subscribes the boundary events of the activity token `t`.
    pub(crate) fn subscribe_boundaries(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        for &b in &g.node(node).boundaries {
            let triggers = triggers_of(g, b);
            for (i, d) in triggers.iter().enumerate() {
                self.subscribe_def(Some(t), scope, b, d, i);
            }
            if triggers.is_empty() && self.game.is_some() {
                self.subscribe(t, b, On::Manual);
            }
        }
    }

    /// Subscribes an event sub-process start of `scope`.
    pub(crate) fn subscribe_scope(
        &mut self,
        scope: ScopeId,
        start: NodeId,
        def: &EventDefinition,
        i: usize,
    ) {
        self.subscribe_def(None, scope, start, def, i);
    }

    /// A token reaches an intermediate catch event.
    pub(crate) fn catch_event(&mut self, t: TokenId, node: NodeId, triggers: &[EventDefinition]) {
        let scope = self.s.tokens[&t].scope;
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Catching;
        }
        for (i, d) in triggers.iter().enumerate() {
            self.subscribe_def(Some(t), scope, node, d, i);
        }
        if triggers.is_empty() && self.game.is_some() {
            self.subscribe(t, node, On::Manual);
        }
        if self
            .s
            .tokens
            .get(&t)
            .is_some_and(|tok| tok.waits.is_empty() && tok.at == At::Catching)
        {
            // Nothing to wait for (none event): pass through.
            self.leave(t);
        }
    }

    /// An event-based gateway: wait for the first event of its targets.
    pub(crate) fn event_gateway(&mut self, t: TokenId) {
        let g = self.g;
        let node = self.s.tokens[&t].node;
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Catching;
        }
        let scope = self.s.tokens[&t].scope;
        for &f in &g.node(node).outgoing {
            let target = g.flow(f).target;
            match &g.node(target).kind {
                NodeKind::Catch(c) => {
                    for (i, d) in c.triggers.iter().enumerate() {
                        self.subscribe_def(Some(t), scope, target, d, i);
                    }
                }
                NodeKind::Task(task) if task.kind == executive_model::TaskKind::Receive => {
                    let name = self.message_name(task.message);
                    self.subscribe(t, target, On::Message(name, None));
                }
                _ => {}
            }
        }
    }

    /// A subscription fired.
    pub(crate) fn trigger(&mut self, w: WaitId, what: Trigger, name: String, payload: &Vars) {
        let g = self.g;
        let Some(wait) = self.s.waits.get(&w).cloned() else {
            return;
        };
        let node = g.node(wait.node);
        self.record(
            wait.instance,
            Entry::Caught {
                what,
                name,
                node: wait.node,
            },
        );
        match &node.kind {
            NodeKind::Boundary(b) => {
                let Some(owner) = wait.token else { return };
                let Some(scope) = self.s.tokens.get(&owner).map(|t| t.scope) else {
                    return;
                };
                for (k, v) in payload {
                    self.set_var(scope, k, v.clone());
                }
                if b.interrupting {
                    self.forget(w);
                    self.withdraw(owner);
                } else {
                    self.rearm_or_keep(w);
                }
                self.spawn(scope, wait.node, None);
            }
            NodeKind::Start(s) => {
                let scope = wait.scope;
                let Scope::SubProcess(esp) = node.scope else {
                    return;
                };
                if s.interrupting {
                    self.forget(w);
                    self.clear_scope(scope, false);
                } else {
                    self.rearm_or_keep(w);
                }
                self.run_event_subprocess(scope, esp, wait.node, payload.clone());
            }
            _ => {
                let Some(t) = wait.token else { return };
                let Some(tok) = self.s.tokens.get(&t) else {
                    return;
                };
                let (scope, at_node) = (tok.scope, tok.node);
                for (k, v) in payload {
                    self.set_var(scope, k, v.clone());
                }
                // A repeating timer on an intermediate catch passes a token on at each firing.
                if let On::Timer { left, .. } = wait.on
                    && at_node == wait.node
                    && left != Some(0)
                    && matches!(node.kind, NodeKind::Catch(_))
                {
                    self.rearm(w);
                    if self.s.waits.contains_key(&w) {
                        let copy = self.spawn(scope, wait.node, None);
                        if let Some(c) = self.s.tokens.get_mut(&copy) {
                            c.at = At::Catching;
                        }
                        self.leave(copy);
                        return;
                    }
                }
                // A parallel multiple catch event waits for all its triggers.
                if matches!(&node.kind, NodeKind::Catch(c) if c.parallel_multiple)
                    && at_node == wait.node
                {
                    self.s.waits.remove(&w);
                    let left = self.s.tokens.get_mut(&t).map(|tok| {
                        tok.waits.retain(|x| *x != w);
                        tok.waits.len()
                    });
                    if left.unwrap_or(0) > 0 {
                        return;
                    }
                }
                self.forget(w);
                self.drop_waits(t);
                if at_node != wait.node {
                    // An event-based gateway: move to the target that fired.
                    if self.trace_moves {
                        self.record(
                            wait.instance,
                            Entry::Left {
                                node: at_node,
                                token: t,
                            },
                        );
                    }
                    let flow = g
                        .node(at_node)
                        .outgoing
                        .iter()
                        .copied()
                        .find(|f| g.flow(*f).target == wait.node);
                    if let Some(tok) = self.s.tokens.get_mut(&t) {
                        tok.node = wait.node;
                        tok.via = flow;
                    }
                    if self.trace_moves {
                        if let Some(f) = flow {
                            self.record(wait.instance, Entry::Took { flow: f });
                        }
                        self.record(
                            wait.instance,
                            Entry::Entered {
                                node: wait.node,
                                token: t,
                            },
                        );
                    }
                }
                if node.is_activity() {
                    self.complete_activity(t);
                } else {
                    self.leave(t);
                }
            }
        }
    }

    /// Removes a subscription that has just fired (its timer needs no cancelling).
    fn forget(&mut self, w: WaitId) {
        let Some(wait) = self.s.waits.remove(&w) else {
            return;
        };
        if let Some(t) = wait.token
            && let Some(tok) = self.s.tokens.get_mut(&t)
        {
            tok.waits.retain(|x| *x != w);
        }
        if let Some(sc) = self.s.scopes.get_mut(&wait.scope) {
            sc.waits.retain(|x| *x != w);
        }
    }

    fn rearm_or_keep(&mut self, w: WaitId) {
        if self.game.is_some() {
            // A token game triggers by hand: the subscription stays.
            return;
        }
        if matches!(self.s.waits.get(&w).map(|w| &w.on), Some(On::Timer { .. })) {
            self.rearm(w);
        }
    }

    /// Runs event sub-process `esp` inside `scope`, started by `start`.
    fn run_event_subprocess(&mut self, scope: ScopeId, esp: NodeId, start: NodeId, vars: Vars) {
        let et = self.spawn(scope, esp, None);
        let child = self.open_scope(et, ScopeKind::SubProcess(esp), vars);
        if self.trace_moves {
            let instance = self.s.scopes[&scope].instance;
            self.record(
                instance,
                Entry::Entered {
                    node: esp,
                    token: et,
                },
            );
        }
        self.spawn(child, start, None);
        for n in self.implicit_starts(Scope::SubProcess(esp)) {
            self.spawn(child, n, None);
        }
    }

    /// A throw — message, signal, error, escalation, compensation, cancel, terminate — takes
    /// effect after the other tokens of its wave have arrived (`docs/engine-semantics.md`,
    /// "Within a step"): the thrower is put back once behind them, so parallel branches that
    /// moved with it reach their catch events and enter their activities first, and what they
    /// start moves after the throw. A link is a jump, not a throw.
    fn defer_throw(&mut self, t: TokenId, defs: &[EventDefinition]) -> bool {
        if !defs.iter().any(|d| !matches!(d, EventDefinition::Link(_))) || self.throw_now.remove(&t)
        {
            return false;
        }
        let wave = self.wave;
        let behind = self.ready.iter().any(|(u, w)| {
            *w <= wave
                && *u != t
                && !self.throw_now.contains(u)
                && self.s.tokens.get(u).is_some_and(|tok| tok.at == At::Ready)
        });
        if !behind {
            return false;
        }
        self.throw_now.insert(t);
        self.ready.push_back((t, wave));
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
    fn throw_one(&mut self, t: TokenId, node: NodeId, d: &EventDefinition) {
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

    fn error_code(&self, e: Option<executive_model::ErrorId>) -> (String, String) {
        match e.map(|e| &self.g.errors[e.index()]) {
            Some(err) => (
                err.code.clone().unwrap_or_else(|| err.id.clone()),
                err.name.clone().unwrap_or_default(),
            ),
            None => (String::new(), String::new()),
        }
    }

    fn escalation_code(&self, e: Option<executive_model::EscalationId>) -> String {
        e.map(|e| &self.g.escalations[e.index()])
            .map(|x| x.code.clone().unwrap_or_else(|| x.id.clone()))
            .unwrap_or_default()
    }

    fn catches(&self, d: &EventDefinition, what: Trigger, code: &str) -> bool {
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
    fn find_catcher(&self, t: TokenId, what: Trigger, code: &str, own: bool) -> Option<Catcher> {
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

    fn event_subprocess_start(&self, el: Scope, what: Trigger, code: &str) -> Option<NodeId> {
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
        self.record(
            instance,
            Entry::Thrown {
                what: Trigger::Error,
                name: code.to_owned(),
                node: Some(node),
            },
        );
        match self.find_catcher(t, Trigger::Error, code, own) {
            Some(Catcher::Boundary(owner, b)) => {
                let scope = self.s.tokens[&owner].scope;
                self.record(
                    instance,
                    Entry::Caught {
                        what: Trigger::Error,
                        name: code.to_owned(),
                        node: b,
                    },
                );
                self.error_variables(scope, b, code, message);
                self.withdraw(owner);
                self.spawn(scope, b, None);
            }
            Some(Catcher::EventSub(scope, start)) => {
                self.record(
                    instance,
                    Entry::Caught {
                        what: Trigger::Error,
                        name: code.to_owned(),
                        node: start,
                    },
                );
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

    fn error_variables(&mut self, scope: ScopeId, node: NodeId, code: &str, message: &str) {
        let mut vars = Vars::new();
        self.error_vars_into(&mut vars, node, code, message);
        for (k, v) in vars {
            self.set_var(scope, &k, v);
        }
    }

    fn error_vars_into(&self, vars: &mut Vars, node: NodeId, code: &str, message: &str) {
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
    fn throw_escalation(&mut self, t: TokenId, code: &str) {
        self.throw_up(t, Trigger::Escalation, code);
    }

    /// Throws an escalation (or, in a token game, an anonymous signal) to the nearest catcher
    /// up the scope chain; the token may be withdrawn by an interrupting catcher.
    fn throw_up(&mut self, t: TokenId, what: Trigger, code: &str) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (instance, node) = (tok.instance, tok.node);
        self.record(
            instance,
            Entry::Thrown {
                what,
                name: code.to_owned(),
                node: Some(node),
            },
        );
        match self.find_catcher(t, what, code, false) {
            Some(Catcher::Boundary(owner, b)) => {
                let scope = self.s.tokens[&owner].scope;
                self.record(
                    instance,
                    Entry::Caught {
                        what,
                        name: code.to_owned(),
                        node: b,
                    },
                );
                let interrupting =
                    matches!(&g.node(b).kind, NodeKind::Boundary(x) if x.interrupting);
                if interrupting {
                    self.withdraw(owner);
                }
                self.spawn(scope, b, None);
            }
            Some(Catcher::EventSub(scope, start)) => {
                self.record(
                    instance,
                    Entry::Caught {
                        what,
                        name: code.to_owned(),
                        node: start,
                    },
                );
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
        let (instance, root) = self.open_instance(process, vars);
        self.record(
            instance,
            Entry::Caught {
                what,
                name: name.to_owned(),
                node: start,
            },
        );
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
                self.record(
                    instance,
                    Entry::Entered {
                        node: start,
                        token: t,
                    },
                );
            }
            self.subscribe_boundaries(t);
            self.complete_activity(t);
        }
        instance
    }

    /// Broadcasts a signal to every waiting catcher and every process that starts on it.
    pub(crate) fn broadcast(&mut self, instance: InstanceId, node: Option<NodeId>, name: &str) {
        if let Some(_i) = self.s.instances.get(&instance) {
            self.record(
                instance,
                Entry::Thrown {
                    what: Trigger::Signal,
                    name: name.to_owned(),
                    node,
                },
            );
        }
        // Inner scopes first (an event sub-process hears the signal before a boundary event
        // of its enclosing sub-process interrupts it), then in subscription order.
        let depth = |mut s: ScopeId| {
            let mut d = 0usize;
            while let Some(p) = self.s.scopes.get(&s).and_then(|x| x.parent) {
                d += 1;
                s = p;
            }
            d
        };
        let mut waits: Vec<(std::cmp::Reverse<usize>, WaitId)> = self
            .s
            .waits
            .iter()
            .filter(|(_, w)| matches!(&w.on, On::Signal(n) if n == name))
            .map(|(id, w)| (std::cmp::Reverse(depth(w.scope)), *id))
            .collect();
        waits.sort();
        let waits: Vec<WaitId> = waits.into_iter().map(|(_, w)| w).collect();
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
    fn link(&mut self, t: TokenId, name: &str) {
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
            self.record(instance, Entry::Left { node, token: t });
        }
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.node = target;
            tok.via = None;
        }
        if self.trace_moves {
            self.record(
                instance,
                Entry::Entered {
                    node: target,
                    token: t,
                },
            );
        }
        self.leave(t);
    }

    /// A terminate end event: everything in the scope stops; the scope completes.
    fn terminate(&mut self, t: TokenId) {
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

    /// A cancel end event inside a transaction: the transaction is cancelled, its completed
    /// activities are compensated, then its cancel boundary event is taken.
    fn cancel_transaction(&mut self, t: TokenId) {
        let g = self.g;
        // The nearest enclosing transaction (the cancel end may sit in one of its event
        // sub-processes).
        let mut scope = self.s.tokens[&t].scope;
        while let Some(sc) = self.s.scopes.get(&scope) {
            let is_transaction = matches!(sc.kind, ScopeKind::SubProcess(n)
                if matches!(&g.node(n).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Transaction)));
            match sc.parent {
                Some(p) if !is_transaction => scope = p,
                _ => break,
            }
        }
        let Some(sc) = self.s.scopes.get(&scope) else {
            return;
        };
        let (owner, mut handlers) = (sc.owner, self.handlers(&sc.compensable, None));
        let Some(owner) = owner else {
            return self.incident(t, "a cancel end event outside a transaction".to_owned());
        };
        // A compensation throw inside the transaction may be running: its handler is cancelled
        // with the rest, but the handlers it had not started yet still have to run (their
        // activities completed before anything now in `compensable`).
        for o in self.tokens_in(scope) {
            if let Some(run) = self.s.tokens.get(&o).and_then(|x| x.compensating.as_ref()) {
                handlers.extend(run.rest.iter().cloned());
            }
        }
        let end_node = self.s.tokens[&t].node;
        let onode = self.s.tokens[&owner].node;
        let parent = self.s.tokens[&owner].scope;
        let boundary = g.node(onode).boundaries.iter().copied().find(|b| {
            triggers_of(g, *b)
                .iter()
                .any(|d| matches!(d, EventDefinition::Cancel))
        });
        let instance = self.s.tokens[&t].instance;
        self.record(
            instance,
            Entry::Thrown {
                what: Trigger::Cancel,
                name: String::new(),
                node: Some(self.s.tokens[&t].node),
            },
        );
        self.cancel_scope(scope);
        if let Some(b) = boundary {
            self.record(
                instance,
                Entry::Caught {
                    what: Trigger::Cancel,
                    name: String::new(),
                    node: b,
                },
            );
        }
        self.withdraw(owner);
        // Without a cancel boundary the transaction still rolls back; its path then ends (the
        // waiter stands on the cancel end event, which has no outgoing flow).
        let waiter = self.spawn(parent, boundary.unwrap_or(end_node), None);
        self.run_handlers(waiter, parent, handlers);
    }

    /// Compensation handlers for the completed activities in `list`, newest first; a completed
    /// sub-process is compensated by its compensation event sub-process, else by compensating
    /// its own completed activities.
    fn handlers(&self, list: &[Compensable], only: Option<NodeId>) -> Vec<Handler> {
        let mut out = Vec::new();
        for c in list
            .iter()
            .rev()
            .filter(|c| only.is_none_or(|a| a == c.node))
        {
            let handler = self.g.node(c.node).compensation_handler;
            if !matches!(self.g.node(c.node).kind, NodeKind::SubProcess(_)) {
                out.extend(handler.map(Handler::Activity));
                continue;
            }
            // A sub-process: its inner compensation first (its compensation event
            // sub-process, else its own completed activities), then its handler.
            match self.compensation_event_sub(c.node) {
                Some(start) => out.push(Handler::EventSub(start, c.inner.clone())),
                None => out.extend(self.handlers(&c.inner, None)),
            }
            out.extend(handler.map(Handler::Activity));
            out.push(Handler::Done(c.node));
        }
        out
    }

    /// A compensation throw: runs the handlers of the scope's completed activities, newest
    /// first; true if the thrower now waits for them.
    fn compensate(&mut self, t: TokenId, activity: Option<NodeId>) -> bool {
        let tok = &self.s.tokens[&t];
        let (scope, instance, node) = (tok.scope, tok.instance, tok.node);
        self.record(
            instance,
            Entry::Thrown {
                what: Trigger::Compensation,
                name: activity
                    .map(|a| self.g.node(a).id.clone())
                    .unwrap_or_default(),
                node: Some(node),
            },
        );
        // Thrown inside an event sub-process: compensate the scope the event sub-process is in.
        let mut target = scope;
        while let Some(sc) = self.s.scopes.get(&target) {
            match (sc.kind, sc.parent) {
                (ScopeKind::SubProcess(n), Some(p))
                    if sc.compensable.is_empty()
                        && matches!(&self.g.node(n).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event)) =>
                {
                    target = p;
                }
                _ => break,
            }
        }
        let list = self.s.scopes[&target].compensable.clone();
        let handlers = self.handlers(&list, activity);
        if let Some(sc) = self.s.scopes.get_mut(&target) {
            sc.compensable
                .retain(|c| activity.is_some_and(|a| a != c.node));
        }
        if handlers.is_empty() {
            return false;
        }
        self.run_handlers(t, target, handlers);
        true
    }

    /// Runs compensation handlers one after another in `scope`; then `waiter` moves on.
    fn run_handlers(&mut self, waiter: TokenId, scope: ScopeId, mut handlers: Vec<Handler>) {
        if let Some(w) = self.s.tokens.get_mut(&waiter) {
            w.at = At::Compensating;
        }
        if handlers.is_empty() {
            return self.resume_waiter(waiter);
        }
        let mut first = handlers.remove(0);
        while let Handler::Done(n) = first {
            if self.trace_moves
                && let Some(instance) = self.s.tokens.get(&waiter).map(|t| t.instance)
            {
                self.record(
                    instance,
                    Entry::Left {
                        node: n,
                        token: waiter,
                    },
                );
            }
            if handlers.is_empty() {
                return self.resume_waiter(waiter);
            }
            first = handlers.remove(0);
        }
        let run = CompensationRun {
            waiter: Some(waiter),
            rest: handlers,
        };
        let h = match first {
            Handler::Activity(node) => self.spawn(scope, node, None),
            Handler::Done(_) => return,
            Handler::EventSub(start, inner) => {
                let Scope::SubProcess(esp) = self.g.node(start).scope else {
                    return self.resume_waiter(waiter);
                };
                let et = self.spawn(scope, esp, None);
                let child = self.open_scope(et, ScopeKind::SubProcess(esp), Vars::new());
                if let Some(sc) = self.s.scopes.get_mut(&child) {
                    sc.compensable = inner;
                }
                if self.trace_moves
                    && let Some(instance) = self.s.scopes.get(&scope).map(|s| s.instance)
                {
                    self.record(
                        instance,
                        Entry::Entered {
                            node: esp,
                            token: et,
                        },
                    );
                }
                self.spawn(child, start, None);
                et
            }
        };
        if let Some(tok) = self.s.tokens.get_mut(&h) {
            tok.compensating = Some(Box::new(run));
        }
    }

    /// A compensation handler finished: start the next one, or let the waiter move on.
    pub(crate) fn compensation_step(&mut self, scope: ScopeId, run: CompensationRun) {
        match run.waiter {
            Some(w) if self.s.tokens.contains_key(&w) => {
                if run.rest.is_empty() {
                    self.resume_waiter(w);
                } else {
                    let target = if self.s.scopes.contains_key(&scope) {
                        scope
                    } else {
                        self.s.tokens[&w].scope
                    };
                    self.run_handlers(w, target, run.rest);
                }
            }
            _ => {}
        }
    }

    /// The compensation a token waited for is over: it moves on (an end event is left, which
    /// consumes it).
    fn resume_waiter(&mut self, w: TokenId) {
        let Some(tok) = self.s.tokens.get_mut(&w) else {
            return;
        };
        tok.at = At::Ready;
        self.leave(w);
    }
}

fn is_catch_all(d: &EventDefinition) -> bool {
    matches!(
        d,
        EventDefinition::Error { error: None, .. } | EventDefinition::Escalation(None)
    )
}
