//! Events caught: subscriptions (catch events, boundaries, event-based gateways, event
//! sub-processes, start events) and their triggering. What throws is in `throws.rs`,
//! transactions and compensation in `compensation.rs`.

use executive_model::{EventDefinition, NodeId, NodeKind, Scope};

use crate::eval;
use crate::io::{Action, Entry, InstanceId, ScopeId, TimerKey, TokenId, Trigger, WaitId};
use crate::run::{Run, triggers_of};
use crate::state::{At, On, ScopeKind, Wait};
use crate::value::Vars;

/// Where a thrown error or escalation is caught.
pub(crate) enum Catcher {
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
    pub(crate) fn subscribe_def(
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

    pub(crate) fn arm(
        &mut self,
        w: WaitId,
        due: crate::io::Millis,
        left: Option<u32>,
        firing: u32,
    ) {
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
        self.record(instance, || Entry::TimerStarted {
            timer: key,
            node,
            due,
        });
        self.out.push(Action::StartTimer {
            timer: key,
            at: due,
        });
    }

    /// After a subscription fired and stays: re-arms a repeating timer, or drops a spent one.
    pub(crate) fn rearm(&mut self, w: WaitId) {
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
        self.record(wait.instance, || Entry::Caught {
            what,
            name: name.into(),
            node: wait.node,
        });
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
                        self.record(wait.instance, || Entry::Left {
                            node: at_node,
                            token: t,
                        });
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
                            self.record(wait.instance, || Entry::Took { flow: f });
                        }
                        self.record(wait.instance, || Entry::Entered {
                            node: wait.node,
                            token: t,
                        });
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
    pub(crate) fn forget(&mut self, w: WaitId) {
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

    pub(crate) fn rearm_or_keep(&mut self, w: WaitId) {
        if self.game.is_some_and(|g| !g.timers) {
            // A token game triggers by hand: the subscription stays.
            return;
        }
        if matches!(self.s.waits.get(&w).map(|w| &w.on), Some(On::Timer { .. })) {
            self.rearm(w);
        }
    }

    /// Runs event sub-process `esp` inside `scope`, started by `start`.
    pub(crate) fn run_event_subprocess(
        &mut self,
        scope: ScopeId,
        esp: NodeId,
        start: NodeId,
        vars: Vars,
    ) {
        let et = self.spawn(scope, esp, None);
        let child = self.open_scope(et, ScopeKind::SubProcess(esp), vars);
        if self.trace_moves {
            let instance = self.s.scopes[&scope].instance;
            self.record(instance, || Entry::Entered {
                node: esp,
                token: et,
            });
        }
        self.spawn(child, start, None);
        for n in self.implicit_starts(Scope::SubProcess(esp)) {
            self.spawn(child, n, None);
        }
    }
}
