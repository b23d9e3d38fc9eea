//! Scopes: opening and starting them, completing them, cancelling them, ending instances.

use executive_model::{EventDefinition, NodeId, NodeKind, ProcessId, Scope, SubProcessKind};

use crate::io::{Action, Entry, InstanceId, Outcome, ScopeId, TokenId};
use crate::run::Run;
use crate::state::{At, ScopeKind, ScopeState};
use crate::value::Vars;

impl Run<'_> {
    /// Opens a child scope run by token `owner`.
    pub(crate) fn open_scope(&mut self, owner: TokenId, kind: ScopeKind, vars: Vars) -> ScopeId {
        let id = ScopeId(self.mint());
        let tok = &self.s.tokens[&owner];
        let (instance, parent) = (tok.instance, tok.scope);
        self.s.scopes.insert(
            id,
            ScopeState {
                instance,
                parent: Some(parent),
                owner: Some(owner),
                kind,
                vars,
                compensable: thin_vec::ThinVec::new(),
                ending: false,
                tokens: Default::default(),
                waits: thin_vec::ThinVec::new(),
            },
        );
        if let Some(tok) = self.s.tokens.get_mut(&owner) {
            tok.at = At::Scope(id);
        }
        id
    }

    /// Opens the root scope of a new instance of `process`. `id` is the process's id as an
    /// input named it, if one did (recorded as it is, instead of a copy of the model's).
    pub(crate) fn open_instance(
        &mut self,
        process: ProcessId,
        vars: Vars,
        id: Option<String>,
    ) -> (InstanceId, ScopeId) {
        let instance = InstanceId(self.mint());
        let root = ScopeId(self.mint());
        self.s.instances.insert(
            instance,
            crate::state::Instance {
                process,
                root: Some(root),
                outcome: None,
                uncaught_escalations: Vec::new(),
                incidents: Vec::new(),
            },
        );
        self.s.scopes.insert(
            root,
            ScopeState {
                instance,
                parent: None,
                owner: None,
                kind: ScopeKind::Process(process),
                vars: vars.clone(),
                compensable: thin_vec::ThinVec::new(),
                ending: false,
                tokens: Default::default(),
                waits: thin_vec::ThinVec::new(),
            },
        );
        let name = id.unwrap_or_else(|| self.g.process(process).id.clone());
        self.record(instance, || Entry::InstanceStarted {
            process: name,
            vars,
        });
        (instance, root)
    }

    /// Starts a process scope at `start`, or at its first none start event (each start event
    /// is an independent way in), or, without start events, at every node without incoming flow.
    pub(crate) fn start_process_scope(
        &mut self,
        scope: ScopeId,
        process: ProcessId,
        start: Option<NodeId>,
    ) {
        self.subscribe_event_subprocesses(scope, Scope::Process(process));
        let element = Scope::Process(process);
        let first_none_start = || {
            self.g.scope_nodes(element).iter().copied().find(
                |n| matches!(&self.g.node(*n).kind, NodeKind::Start(s) if s.triggers.is_empty()),
            )
        };
        let first = start.or_else(first_none_start).filter(|s| {
            self.g.node(*s).incoming.is_empty()
                && matches!(self.g.node(*s).kind, NodeKind::Start(_))
        });
        let implicit = self.implicit_starts(element);
        // A named start that is neither goes first.
        let named = start.filter(|s| Some(*s) != first && !implicit.contains(s));
        self.start_at(scope, named.into_iter().chain(first).chain(implicit));
    }

    /// Starts a sub-process scope.
    pub(crate) fn start_scope(&mut self, scope: ScopeId, node: NodeId) {
        self.subscribe_event_subprocesses(scope, Scope::SubProcess(node));
        let starts = self.start_nodes(Scope::SubProcess(node));
        self.start_at(scope, starts);
    }

    fn start_at(&mut self, scope: ScopeId, starts: impl IntoIterator<Item = NodeId>) {
        let mut none = true;
        for n in starts {
            self.spawn(scope, n, None);
            none = false;
        }
        if none {
            // Nothing to run: the scope is complete at once.
            self.complete_scope(scope);
        }
    }

    /// A scope has no token left: it completes, and its owner moves on.
    pub(crate) fn complete_scope(&mut self, scope: ScopeId) {
        let Some(sc) = self.s.scopes.get_mut(&scope) else {
            return;
        };
        if sc.ending {
            return;
        }
        sc.ending = true;
        let waits = std::mem::take(&mut sc.waits);
        for w in waits {
            self.unsubscribe(w);
        }
        let Some(sc) = self.s.scopes.remove(&scope) else {
            return;
        };
        let Some(owner) = sc.owner else {
            self.finish_instance(sc.instance, Outcome::Completed);
            return;
        };
        let Some(tok) = self.s.tokens.get(&owner) else {
            return;
        };
        let node = tok.node;
        match sc.kind {
            ScopeKind::Body(_) => self.body_done(owner, scope, &sc.vars),
            ScopeKind::Process(_) => {
                // A called process: map its outputs back into the caller.
                let out = sc.vars;
                let binding = match &self.g.node(node).kind {
                    NodeKind::CallActivity(c) => c.binding.as_ref(),
                    _ => None,
                };
                let declared = binding.is_some_and(|b| !b.outputs.is_empty() || b.all_out);
                if declared || self.has_data_outputs(node) {
                    if binding.is_some_and(|b| b.all_out) {
                        let caller = self.s.tokens[&owner].scope;
                        for (k, v) in &out {
                            self.set_var(caller, k, v.clone());
                        }
                    }
                    if let Err(e) = self.apply_outputs(owner, &out) {
                        return self.incident(owner, e);
                    }
                }
                self.complete_activity(owner);
            }
            ScopeKind::SubProcess(n) => {
                let event = matches!(&self.g.node(n).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event));
                if event {
                    // An event sub-process run ends; its token has nowhere to go.
                    if self.trace_moves {
                        let instance = sc.instance;
                        self.record(instance, || Entry::Left {
                            node: n,
                            token: owner,
                        });
                    }
                    self.consume(owner);
                } else {
                    // Its completed activities stay compensable, through the sub-process.
                    let keep = !sc.compensable.is_empty()
                        || self.compensation_event_sub(n).is_some()
                        || self.g.node(n).compensation_handler.is_some();
                    if keep {
                        let parent = self.s.tokens[&owner].scope;
                        if let Some(p) = self.s.scopes.get_mut(&parent) {
                            p.compensable.push(crate::state::Compensable {
                                node: n,
                                inner: sc.compensable,
                            });
                        }
                    }
                    self.complete_activity(owner);
                }
            }
        }
    }

    /// Withdraws a token: cancels its task, user task, child scope or loop bodies, and removes
    /// it without completing anything.
    pub(crate) fn withdraw(&mut self, t: TokenId) {
        let Some(tok) = self.s.tokens.get(&t) else {
            return;
        };
        let (at, node, instance) = (tok.at.clone(), tok.node, tok.instance);
        match at {
            At::Task(key) => {
                self.record(instance, || Entry::Cancelled { task: key });
                self.out.push(Action::CancelTask { task: key });
            }
            At::UserTask(key) => self.out.push(Action::CloseUserTask { task: key }),
            At::Scope(child) => self.cancel_scope(child),
            At::Looping(l) => {
                for child in l.running {
                    self.cancel_scope(child);
                }
            }
            _ => {}
        }
        if self.trace_moves {
            self.record(instance, || Entry::Withdrawn { node, token: t });
        }
        self.drop_waits(t);
        self.unpark(t);
        if let Some(tok) = self.s.tokens.remove(&t)
            && let Some(sc) = self.s.scopes.get_mut(&tok.scope)
        {
            sc.tokens.remove(&t);
        }
    }

    /// Cancels a scope and everything in it (no completion).
    pub(crate) fn cancel_scope(&mut self, scope: ScopeId) {
        let Some(sc) = self.s.scopes.get_mut(&scope) else {
            return;
        };
        sc.ending = true;
        let waits = std::mem::take(&mut sc.waits);
        for w in waits {
            self.unsubscribe(w);
        }
        for t in self.tokens_in(scope) {
            self.withdraw(t);
        }
        self.s.scopes.remove(&scope);
    }

    /// Withdraws every token of a scope but keeps the scope open (interrupting events,
    /// terminate).
    pub(crate) fn clear_scope(&mut self, scope: ScopeId, keep_subscriptions: bool) {
        if !keep_subscriptions && let Some(sc) = self.s.scopes.get_mut(&scope) {
            let waits = std::mem::take(&mut sc.waits);
            for w in waits {
                self.unsubscribe(w);
            }
        }
        for t in self.tokens_in(scope) {
            self.withdraw(t);
        }
    }

    /// Ends an instance: cancels whatever still runs, reports the outcome.
    pub(crate) fn finish_instance(&mut self, instance: InstanceId, outcome: Outcome) {
        let Some(inst) = self.s.instances.get_mut(&instance) else {
            return;
        };
        if inst.outcome.is_some() {
            return;
        }
        inst.outcome = Some(outcome.clone());
        let root = inst.root.take();
        let uncaught_escalations = inst.uncaught_escalations.clone();
        if let Some(root) = root {
            self.cancel_scope(root);
        }
        self.ready.retain(|(t, _)| self.s.tokens.contains_key(t));
        self.record(instance, || Entry::InstanceFinished {
            outcome: outcome.clone(),
            uncaught_escalations,
        });
        self.out
            .push(Action::InstanceFinished { instance, outcome });
    }

    /// Subscribes the message, signal, timer and conditional starts of the event
    /// sub-processes directly inside `element`.
    pub(crate) fn subscribe_event_subprocesses(&mut self, scope: ScopeId, element: Scope) {
        let g = self.g;
        for &n in g.scope_nodes(element) {
            let NodeKind::SubProcess(sp) = &g.node(n).kind else {
                continue;
            };
            if !matches!(sp.kind, SubProcessKind::Event) {
                continue;
            }
            for &start in &sp.nodes {
                if let NodeKind::Start(s) = &g.node(start).kind {
                    for (i, d) in s.triggers.iter().enumerate() {
                        if matches!(
                            d,
                            EventDefinition::Message(_)
                                | EventDefinition::Signal(_)
                                | EventDefinition::Timer(_)
                                | EventDefinition::Conditional(_)
                        ) {
                            self.subscribe_scope(scope, start, d, i);
                        }
                    }
                }
            }
        }
    }
}

impl Run<'_> {
    /// The compensation start event of an event sub-process directly inside sub-process `sp`.
    pub(crate) fn compensation_event_sub(&self, sp: NodeId) -> Option<NodeId> {
        let g = self.g;
        g.scope_nodes(Scope::SubProcess(sp)).iter().find_map(|&n| match &g.node(n).kind {
            NodeKind::SubProcess(esp) if matches!(esp.kind, SubProcessKind::Event) => {
                esp.nodes.iter().copied().find(|s| {
                    matches!(&g.node(*s).kind, NodeKind::Start(st)
                        if st.triggers.iter().any(|d| matches!(d, EventDefinition::Compensate { .. })))
                })
            }
            _ => None,
        })
    }
}
