//! Transactions cancelled and compensation: the handlers of completed activities run newest
//! first, and the thrower waits for them when it asks to.

use executive_model::{EventDefinition, NodeId, NodeKind, Scope, SubProcessKind};

use crate::io::{Entry, ScopeId, TokenId, Trigger};
use crate::run::{Run, triggers_of};
use crate::state::{At, Compensable, CompensationRun, Handler, ScopeKind};
use crate::value::Vars;
use compact_str::CompactString;

impl Run<'_> {
    /// A cancel end event inside a transaction: the transaction is cancelled, its completed
    /// activities are compensated, then its cancel boundary event is taken.
    pub(crate) fn cancel_transaction(&mut self, t: TokenId) {
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
        let node = Some(self.s.tokens[&t].node);
        self.record(instance, || Entry::Thrown {
            what: Trigger::Cancel,
            name: CompactString::default(),
            node,
        });
        self.cancel_scope(scope);
        if let Some(b) = boundary {
            self.record(instance, || Entry::Caught {
                what: Trigger::Cancel,
                name: CompactString::default(),
                node: b,
            });
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
    pub(crate) fn handlers(&self, list: &[Compensable], only: Option<NodeId>) -> Vec<Handler> {
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
    pub(crate) fn compensate(&mut self, t: TokenId, activity: Option<NodeId>) -> bool {
        let tok = &self.s.tokens[&t];
        let (scope, instance, node) = (tok.scope, tok.instance, tok.node);
        self.record(instance, || Entry::Thrown {
            what: Trigger::Compensation,
            name: activity
                .map(|a| CompactString::from(self.g.node(a).id.as_str()))
                .unwrap_or_default(),
            node: Some(node),
        });
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
    pub(crate) fn run_handlers(
        &mut self,
        waiter: TokenId,
        scope: ScopeId,
        mut handlers: Vec<Handler>,
    ) {
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
                self.record(instance, || Entry::Left {
                    node: n,
                    token: waiter,
                });
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
                    self.record(instance, || Entry::Entered {
                        node: esp,
                        token: et,
                    });
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
    pub(crate) fn resume_waiter(&mut self, w: TokenId) {
        let Some(tok) = self.s.tokens.get_mut(&w) else {
            return;
        };
        tok.at = At::Ready;
        self.leave(w);
    }
}
