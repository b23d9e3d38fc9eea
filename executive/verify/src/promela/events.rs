//! Throwing and catching: error and escalation catchers found statically, signal broadcast and
//! lost signals, terminate.

use super::*;

impl Tr<'_> {
    /// Checks run when `n` starts listening: a signal it catches that was thrown with nobody
    /// listening was thrown too early, and is lost.
    pub(super) fn listening(&self, n: NodeId) -> Vec<String> {
        let node = self.g.node(n);
        let mut signals = Vec::new();
        let mut add = |defs: &[EventDefinition]| {
            for d in defs {
                if let EventDefinition::Signal(s) = d {
                    signals.push(*s);
                }
            }
        };
        match &node.kind {
            NodeKind::Catch(ce) => add(&ce.triggers),
            NodeKind::Gateway(_) => {
                for f in &node.outgoing {
                    if let NodeKind::Catch(ce) = &self.g.node(self.g.flow(*f).target).kind {
                        add(&ce.triggers);
                    }
                }
            }
            _ => {
                for b in &node.boundaries {
                    if let NodeKind::Boundary(be) = &self.g.node(*b).kind {
                        add(&be.triggers);
                    }
                }
            }
        }
        signals
            .into_iter()
            .map(|s| {
                let (k, name) = match s {
                    Some(s) => (s.index(), self.g.signals[s.index()].name.clone()),
                    None => (self.g.signals.len(), "(unnamed)".to_owned()),
                };
                format!(
                    "if :: unheard[{k}] -> printf(\"@@LOST signal {name}\\n\"); lost = 1 :: else -> skip fi"
                )
            })
            .collect()
    }

    /// The boundary that catches a throw from node `n` in context `c`: the innermost enclosing
    /// activity (sub-process, or call activity in a calling context) with a matching boundary.
    pub(super) fn catcher(
        &self,
        c: usize,
        n: NodeId,
        matches: &dyn Fn(&BoundaryEvent) -> bool,
    ) -> Option<(usize, NodeId, NodeId)> {
        let (mut c, mut scope) = (c, self.g.node(n).scope);
        loop {
            let holder = match scope {
                Scope::SubProcess(s) => {
                    scope = self.g.node(s).scope;
                    s
                }
                Scope::Process(_) => {
                    let (pc, call) = self.ctxs[c].call?;
                    c = pc;
                    scope = self.g.node(call).scope;
                    call
                }
            };
            for b in &self.g.node(holder).boundaries {
                if let NodeKind::Boundary(be) = &self.g.node(*b).kind
                    && matches(be)
                {
                    return Some((c, holder, *b));
                }
            }
        }
    }

    pub(super) fn error_matches(
        &self,
        thrown: Option<executive_model::ErrorId>,
        be: &BoundaryEvent,
    ) -> bool {
        be.triggers.iter().any(|t| match t {
            EventDefinition::Error { error: None, .. } => true,
            EventDefinition::Error { error: Some(e), .. } => thrown.is_some_and(|x| {
                x == *e
                    || (self.g.errors[x.index()].code.is_some()
                        && self.g.errors[x.index()].code == self.g.errors[e.index()].code)
            }),
            _ => false,
        })
    }

    pub(super) fn escalation_matches(
        &self,
        thrown: Option<executive_model::EscalationId>,
        be: &BoundaryEvent,
    ) -> bool {
        be.triggers.iter().any(|t| match t {
            EventDefinition::Escalation(None) => true,
            EventDefinition::Escalation(Some(e)) => thrown.is_some_and(|x| {
                x == *e
                    || (self.g.escalations[x.index()].code.is_some()
                        && self.g.escalations[x.index()].code == self.g.escalations[e.index()].code)
            }),
            _ => false,
        })
    }

    /// A caught throw: the catching activity is cancelled and its boundary fires.
    pub(super) fn caught(&mut self, c: usize, holder: NodeId, b: NodeId, alt: &mut Alt) {
        // A non-interrupting boundary starts its path beside the activity, which runs on.
        if interrupting(self.g, b) {
            self.cancel(c, holder, alt);
        }
        let outs = self.g.node(b).outgoing.clone();
        self.put_all(c, &outs, alt);
        let m = self.marker(c, b, "fire");
        alt.effect.push(format!("printf(\"@@BPMN {m}\\n\")"));
        let id = self.g.node(b).id.clone();
        alt.effect.extend(self.observed(&id, "fire"));
    }

    /// A signal thrown: every listener armed now hears it, in one step; none → lost.
    pub(super) fn broadcast(&mut self, signal: Option<executive_model::SignalId>, alt: &mut Alt) {
        let same = |d: &EventDefinition| matches!(d, EventDefinition::Signal(s) if *s == signal);
        let mut listeners = 0;
        alt.effect.push("heard = 0".to_owned());
        let name = signal.map(|s| self.g.signals[s.index()].name.clone());
        for (k, a) in self.observe.iter().enumerate() {
            if matches!(a, Atom::Signal(x) if Some(x) == name.as_ref()) {
                alt.effect.push(format!("sig{k} = 1"));
            }
        }
        for c in 0..self.ctxs.len() {
            for n in self.nodes(c) {
                let node = self.g.node(n);
                match &node.kind {
                    NodeKind::Catch(ce) if ce.triggers.iter().any(same) => {
                        let after_gateway = node.incoming.iter().any(|f| {
                            matches!(&self.g.node(self.g.flow(*f).source).kind,
                                NodeKind::Gateway(gw) if matches!(gw.kind, GatewayKind::EventBased { .. }))
                        });
                        let m = self.marker(c, n, "hear");
                        let outs = node.outgoing.clone();
                        let mut fire = Alt::default();
                        self.put_all(c, &outs, &mut fire);
                        for f in node.incoming.clone() {
                            let (cond, take) = if after_gateway {
                                let gw = self.g.flow(f).source;
                                let a = self.a(c, gw);
                                (format!("act[{a}]"), format!("act[{a}] = 0"))
                            } else {
                                let i = self.f(c, f);
                                (format!("tok[{i}] > 0"), format!("tok[{i}]--"))
                            };
                            listeners += 1;
                            fire.effect.extend(self.observed(&node.id, "hear"));
                            alt.effect.push(format!(
                                "if :: {cond} -> printf(\"@@BPMN {m}\\n\"); {take}; {}; heard = 1 :: else -> skip fi",
                                fire.effect.join("; ")
                            ));
                        }
                    }
                    NodeKind::Boundary(be) if be.triggers.iter().any(same) => {
                        let holder = be.attached_to;
                        let mut fire = Alt::default();
                        self.caught(c, holder, n, &mut fire);
                        listeners += 1;
                        alt.effect.push(format!(
                            "if :: act[{}] -> {}; heard = 1 :: else -> skip fi",
                            self.a(c, holder),
                            fire.effect.join("; ")
                        ));
                    }
                    _ => {}
                }
            }
        }
        if listeners > 0 {
            let (k, name) = match signal {
                Some(s) => (s.index(), self.g.signals[s.index()].name.clone()),
                None => (self.g.signals.len(), "(unnamed)".to_owned()),
            };
            alt.effect.push(format!(
                "if :: !heard -> printf(\"@@UNHEARD signal {name}\\n\"); unheard[{k}] = 1 :: else -> skip fi"
            ));
        }
    }

    /// Effects marking an error code as met (`None`: a catch-all, which may be any code).
    pub(super) fn error_observed(&self, code: Option<&str>) -> Vec<String> {
        self.observe
            .iter()
            .enumerate()
            .filter(|(_, a)| matches!(a, Atom::Error(x) if code.is_none_or(|c| c == x)))
            .map(|(k, _)| format!("err{k} = 1"))
            .collect()
    }

    pub(super) fn signal_listened(&self) -> bool {
        self.alts.iter().any(|a| a.contains("unheard["))
    }

    /// What a throw (intermediate or end) does besides consuming its token; `false` when the
    /// token's path ends there (caught by an interrupting boundary, or a failure).
    pub(super) fn throw(
        &mut self,
        c: usize,
        n: NodeId,
        defs: &[EventDefinition],
        alt: &mut Alt,
    ) -> bool {
        let mut go_on = true;
        for d in defs {
            match d {
                EventDefinition::Signal(s) => self.broadcast(*s, alt),
                EventDefinition::Error { error, .. } => {
                    let e = *error;
                    let code = e.and_then(|e| self.g.errors[e.index()].code.clone());
                    alt.effect.extend(self.error_observed(code.as_deref()));
                    match self.catcher(c, n, &|be| self.error_matches(e, be)) {
                        Some((cc, holder, b)) => self.caught(cc, holder, b, alt),
                        None => alt.effect.push("failed = 1; CLEAR_ALL".to_owned()),
                    }
                    go_on = false;
                }
                EventDefinition::Escalation(e) => {
                    let e = *e;
                    if let Some((cc, holder, b)) =
                        self.catcher(c, n, &|be| self.escalation_matches(e, be))
                    {
                        go_on &= !interrupting(self.g, b);
                        self.caught(cc, holder, b, alt);
                    }
                }
                EventDefinition::Terminate => {
                    let scope = match self.g.node(n).scope {
                        Scope::SubProcess(s) => Some(s),
                        Scope::Process(_) => None,
                    };
                    let (flows, acts, _) = self.contents(c, scope);
                    alt.effect
                        .extend(flows.iter().map(|f| format!("tok[{f}] = 0")));
                    alt.effect
                        .extend(acts.iter().map(|a| format!("act[{a}] = 0")));
                    if scope.is_none() && self.ctxs[c].call.is_none() {
                        alt.effect.push("terminated = 1".to_owned());
                    }
                    go_on = false;
                }
                _ => {}
            }
        }
        go_on
    }

    // ----- nodes -----
}
