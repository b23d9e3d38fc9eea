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

    /// Everything that may catch a throw from node `n` in context `c`, innermost first, as the
    /// engine looks: at each enclosing scope its event sub-processes (not those beside the
    /// thrower's own event sub-process), then the boundary events of the activity that holds
    /// the scope (a sub-process, or the call activity of a called process). Each with its level.
    pub(super) fn catchers(
        &self,
        c: usize,
        n: NodeId,
        matches: &dyn Fn(&[EventDefinition]) -> bool,
    ) -> Vec<(usize, Catch)> {
        let mut out = Vec::new();
        let (mut c, mut scope) = (c, self.g.node(n).scope);
        let mut beside = false;
        for level in 0.. {
            if !beside {
                for start in self.event_sub_starts(scope) {
                    if let NodeKind::Start(st) = &self.g.node(start).kind
                        && matches(&st.triggers)
                    {
                        out.push((level, Catch::EventSub { c, start }));
                    }
                }
            }
            let holder = match scope {
                Scope::SubProcess(s) => {
                    scope = self.g.node(s).scope;
                    s
                }
                Scope::Process(_) => {
                    let Some((pc, call)) = self.ctxs[c].call else {
                        break;
                    };
                    c = pc;
                    scope = self.g.node(call).scope;
                    call
                }
            };
            beside = is_event_sub(self.g, holder);
            for b in &self.g.node(holder).boundaries {
                if let NodeKind::Boundary(be) = &self.g.node(*b).kind
                    && matches(&be.triggers)
                {
                    out.push((level, Catch::Boundary { c, holder, b: *b }));
                }
            }
        }
        out
    }

    /// What catches a throw from `n`: the innermost catcher, a specific one before a catch-all
    /// at the same level (the engine's choice).
    pub(super) fn catcher(
        &self,
        c: usize,
        n: NodeId,
        matches: &dyn Fn(&[EventDefinition]) -> bool,
    ) -> Option<Catch> {
        let all = self.catchers(c, n, matches);
        let level = all.first()?.0;
        let here = all.iter().filter(|(l, _)| *l == level).map(|(_, x)| *x);
        let specific = here.clone().find(|x| {
            self.triggers(x.node()).iter().any(|d| {
                matches!(
                    d,
                    EventDefinition::Error { error: Some(_), .. }
                        | EventDefinition::Escalation(Some(_))
                )
            })
        });
        specific.or_else(|| here.clone().next())
    }

    /// The error catchers (innermost first) that some code reaches: a code is caught by the
    /// first catcher of it, a specific one before a catch-all of the same level, so a catcher
    /// behind one that catches the same code, or behind a catch-all, never fires.
    pub(super) fn reachable(&self, mut chain: Vec<(usize, Catch)>) -> Vec<Catch> {
        // The code an error catcher catches (`None`: any).
        let code = |x: &Catch| -> Option<String> {
            self.triggers(x.node()).iter().find_map(|t| match t {
                EventDefinition::Error { error: Some(e), .. } => {
                    let e = &self.g.errors[e.index()];
                    Some(e.code.clone().unwrap_or_else(|| e.id.clone()))
                }
                _ => None,
            })
        };
        chain.sort_by_key(|(level, x)| (*level, code(x).is_none()));
        let mut out = Vec::new();
        let mut caught = BTreeSet::new();
        let mut all = false;
        for (_, x) in chain {
            if all {
                break;
            }
            match code(&x) {
                Some(k) => {
                    if caught.insert(k) {
                        out.push(x);
                    }
                }
                None => {
                    // A catch-all takes every code not caught before it.
                    all = true;
                    out.push(x);
                }
            }
        }
        out
    }

    /// The event definitions of a catching node (a boundary or a start event).
    pub(super) fn triggers(&self, n: NodeId) -> &[EventDefinition] {
        match &self.g.node(n).kind {
            NodeKind::Boundary(be) => &be.triggers,
            NodeKind::Start(st) => &st.triggers,
            _ => &[],
        }
    }

    pub(super) fn error_matches(
        &self,
        thrown: Option<executive_model::ErrorId>,
        triggers: &[EventDefinition],
    ) -> bool {
        triggers.iter().any(|t| match t {
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
        triggers: &[EventDefinition],
    ) -> bool {
        triggers.iter().any(|t| match t {
            EventDefinition::Escalation(None) => true,
            EventDefinition::Escalation(Some(e)) => thrown.is_some_and(|x| {
                x == *e
                    || (self.g.escalations[x.index()].code.is_some()
                        && self.g.escalations[x.index()].code == self.g.escalations[e.index()].code)
            }),
            _ => false,
        })
    }

    /// A caught throw: by a boundary (the catching activity is cancelled if it interrupts, and
    /// the boundary fires) or by an event sub-process (which starts).
    pub(super) fn caught(&mut self, catch: Catch, alt: &mut Alt) {
        match catch {
            Catch::Boundary { c, holder, b } => self.boundary_fires(c, holder, b, alt),
            Catch::EventSub { c, start } => self.start_event_sub(c, start, alt, true),
        }
    }

    /// A boundary event fires: an interrupting one cancels its activity.
    pub(super) fn boundary_fires(&mut self, c: usize, holder: NodeId, b: NodeId, alt: &mut Alt) {
        // A non-interrupting boundary starts its path beside the activity, which runs on.
        if interrupting(self.g, b) {
            self.cancel(c, holder, alt);
        }
        self.arrive(c, b, alt);
        let m = self.marker(c, b, "fire");
        alt.effect.push(format!("printf(\"@@BPMN {m}\\n\")"));
        let id = self.g.node(b).id.clone();
        alt.effect.extend(self.observed(&id, "fire"));
    }

    /// A message sent by `n`: each receiver its message flows name in the model
    /// ([`inner_message`]) takes it in the same step if it waits for it now — a catch event
    /// with a token before it, an event-based gateway's branch, a boundary on a running
    /// activity, a message start event of an idle process — else it is lost, as the engine
    /// keeps no message for a receiver that does not wait (correlation is not modelled: any
    /// waiting receiver of the flow takes it).
    pub(super) fn send_along(&mut self, n: NodeId, alt: &mut Alt) {
        let source = self.g.node(n).id.clone();
        let targets: Vec<NodeId> = self
            .g
            .collaborations
            .iter()
            .flat_map(|c| &c.message_flows)
            .filter(|m| m.source == source)
            .filter_map(|m| self.g.node_by_id(&m.target))
            .filter(|t| inner_message(self.g, *t))
            .collect();
        for t in targets {
            for c in 0..self.ctxs.len() {
                if !self.nodes(c).contains(&t) {
                    continue;
                }
                match &self.g.node(t).kind {
                    NodeKind::Catch(_) => {
                        let effects = self.hear_catch(c, t, "take");
                        alt.effect.extend(effects);
                    }
                    NodeKind::Boundary(be) => {
                        let effect = self.hear_boundary(c, t, be.attached_to);
                        alt.effect.push(effect);
                    }
                    NodeKind::Start(_) => {
                        if let Some(effect) = self.start_on_message(c, t) {
                            alt.effect.push(effect);
                        }
                    }
                    _ => {}
                }
            }
        }
    }

    /// The effects by which catch event `n` of context `c` hears what was thrown, if a token
    /// waits before it (on an incoming flow, or at the event-based gateway before it): one
    /// guarded effect per incoming flow, each setting `heard`.
    fn hear_catch(&mut self, c: usize, n: NodeId, phase: &str) -> Vec<String> {
        let node = self.g.node(n);
        let after_gateway = node.incoming.iter().any(|f| {
            matches!(&self.g.node(self.g.flow(*f).source).kind,
                NodeKind::Gateway(gw) if matches!(gw.kind, GatewayKind::EventBased { .. }))
        });
        let m = self.marker(c, n, phase);
        let outs = node.outgoing.clone();
        let id = node.id.clone();
        let mut fire = Alt::default();
        self.put_all(c, &outs, &mut fire);
        let mut out = Vec::new();
        for f in self.g.node(n).incoming.clone() {
            let (cond, take) = if after_gateway {
                let gw = self.g.flow(f).source;
                let a = self.a(c, gw);
                (format!("act[{a}]"), format!("act[{a}] = 0"))
            } else {
                let i = self.f(c, f);
                // A catch event waits once its token has arrived (not one of the next wave).
                // Taken as `= 0`, not `--`: pan's unreached `-1)` marks a step's own take
                // (`spin.rs`, `unreached`), and this one is a branch inside another step.
                (
                    format!("ARRIVED({i})"),
                    format!("tok[{i}] = 0; gen[{i}] = 0"),
                )
            };
            fire.effect.extend(self.observed(&id, phase));
            out.push(format!(
                "if :: {cond} -> printf(\"@@BPMN {m}\\n\"); {take}; {}; heard = 1 :: else -> skip fi",
                fire.effect.join("; ")
            ));
        }
        out
    }

    /// The effect by which boundary event `b` on `holder` (context `c`) fires if its activity
    /// runs, setting `heard`.
    fn hear_boundary(&mut self, c: usize, b: NodeId, holder: NodeId) -> String {
        let mut fire = Alt::default();
        self.boundary_fires(c, holder, b, &mut fire);
        format!(
            "if :: act[{}] -> {}; heard = 1 :: else -> skip fi",
            self.a(c, holder),
            fire.effect.join("; ")
        )
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
        // The engine's order (`docs/engine-semantics.md`, Signals): inner scopes first, within
        // a scope the non-interrupting catchers before the interrupting ones, then (where the
        // engine takes the order they began waiting) the document order; processes started by
        // the signal last.
        let mut heard: Vec<(std::cmp::Reverse<usize>, bool, usize, NodeId)> = Vec::new();
        for c in 0..self.ctxs.len() {
            for n in self.nodes(c) {
                let node = self.g.node(n);
                let (scope, interrupting) = match &node.kind {
                    NodeKind::Catch(ce) if ce.triggers.iter().any(same) => (node.scope, false),
                    NodeKind::Start(st) if st.triggers.iter().any(same) => {
                        match self.event_sub_of(n) {
                            Some(esp) => (self.g.node(esp).scope, st.interrupting),
                            None => (node.scope, true),
                        }
                    }
                    NodeKind::Boundary(be) if be.triggers.iter().any(same) => {
                        (node.scope, be.interrupting)
                    }
                    _ => continue,
                };
                let depth =
                    if self.event_sub_of(n).is_none() && matches!(node.kind, NodeKind::Start(_)) {
                        0
                    } else {
                        self.depth(c, scope) + 1
                    };
                heard.push((std::cmp::Reverse(depth), interrupting, c, n));
            }
        }
        heard.sort_by_key(|&(depth, interrupting, _, _)| (depth, interrupting));
        for (_, _, c, n) in heard {
            match &self.g.node(n).kind {
                NodeKind::Catch(_) => {
                    let effects = self.hear_catch(c, n, "hear");
                    listeners += effects.len();
                    alt.effect.extend(effects);
                }
                NodeKind::Start(_) => {
                    listeners += usize::from(self.signal_start(c, n, alt));
                }
                NodeKind::Boundary(be) => {
                    listeners += 1;
                    let effect = self.hear_boundary(c, n, be.attached_to);
                    alt.effect.push(effect);
                }
                _ => {}
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

    /// How deeply `scope` of context `c` nests, as the engine counts the scopes a catcher
    /// waits in: one per enclosing sub-process and per call activity.
    fn depth(&self, c: usize, mut scope: Scope) -> usize {
        let mut d = 0;
        while let Scope::SubProcess(sp) = scope {
            d += 1;
            scope = self.g.node(sp).scope;
        }
        match self.ctxs[c].call {
            Some((parent, call)) => d + 1 + self.depth(parent, self.g.node(call).scope),
            None => d,
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
                EventDefinition::Message(_) => self.send_along(n, alt),
                EventDefinition::Error { error, .. } => {
                    let e = *error;
                    let code = e.and_then(|e| self.g.errors[e.index()].code.clone());
                    alt.effect.extend(self.error_observed(code.as_deref()));
                    match self.catcher(c, n, &|t| self.error_matches(e, t)) {
                        Some(catch) => self.caught(catch, alt),
                        None => {
                            // Nothing catches it: the instance fails — the process it was
                            // thrown in and every process that one called. Other processes
                            // (another pool's, one started by a message) run on, as in the
                            // engine.
                            let mut root = c;
                            while let Some((caller, _)) = self.ctxs[root].call {
                                root = caller;
                            }
                            let inside = self.contents(root, None);
                            self.clear(&inside, alt);
                            alt.effect.push("failed = 1".to_owned());
                        }
                    }
                    go_on = false;
                }
                EventDefinition::Escalation(e) => {
                    let e = *e;
                    if let Some(catch) = self.catcher(c, n, &|t| self.escalation_matches(e, t)) {
                        go_on &= !catch.interrupting(self.g);
                        self.caught(catch, alt);
                    }
                }
                EventDefinition::Compensate { activity, wait } => {
                    go_on &= !self.compensation_thrown(c, n, *activity, *wait, alt);
                }
                EventDefinition::Cancel => {
                    self.cancelled(c, n, alt);
                    go_on = false;
                }
                EventDefinition::Terminate => {
                    let scope = match self.g.node(n).scope {
                        Scope::SubProcess(s) => Some(s),
                        Scope::Process(_) => None,
                    };
                    let inside = self.contents(c, scope);
                    self.clear(&inside, alt);
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

    /// Whether something inside the model may withdraw a token at `n` (context `c`): a
    /// terminate or cancel end event, or an interrupting event sub-process, in a scope around
    /// it; an interrupting boundary event, or a completion condition, on an activity around it;
    /// an error end event anywhere (uncaught, it ends the whole run).
    pub(super) fn withdrawable(&self, c: usize, n: NodeId) -> bool {
        let ends = |kind: &NodeKind, what: &dyn Fn(&EventDefinition) -> bool| matches!(kind, NodeKind::End(defs) if defs.iter().any(what));
        if self
            .g
            .nodes
            .iter()
            .any(|m| ends(&m.kind, &|d| matches!(d, EventDefinition::Error { .. })))
        {
            return true;
        }
        let (mut c, mut scope) = (c, self.g.node(n).scope);
        loop {
            let interrupting_sub = self
                .event_sub_starts(scope)
                .iter()
                .any(|s| matches!(&self.g.node(*s).kind, NodeKind::Start(st) if st.interrupting));
            let ending = self.g.scope_nodes(scope).iter().any(|m| {
                ends(&self.g.node(*m).kind, &|d| {
                    matches!(d, EventDefinition::Terminate | EventDefinition::Cancel)
                })
            });
            if interrupting_sub || ending {
                return true;
            }
            let holder = match scope {
                Scope::SubProcess(s) => {
                    scope = self.g.node(s).scope;
                    s
                }
                Scope::Process(_) => {
                    let Some((pc, call)) = self.ctxs[c].call else {
                        return false;
                    };
                    c = pc;
                    scope = self.g.node(call).scope;
                    call
                }
            };
            let node = self.g.node(holder);
            let completion = matches!(&node.looping,
                Some(Looping::MultiInstance(mi)) if mi.completion.is_some());
            if completion || node.boundaries.iter().any(|b| interrupting(self.g, *b)) {
                return true;
            }
        }
    }

    // ----- nodes -----
}
