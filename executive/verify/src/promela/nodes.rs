//! One template per kind of flow node: events, gateways (data-decided where declared data
//! allows), activities with their boundaries, failures and loops.

use super::*;

/// The flows and the activity slots upstream of a flow ([`Tr::upstream`]).
type Upstream = (BTreeSet<usize>, BTreeSet<usize>);

impl Tr<'_> {
    /// An exclusive split decided by declared data: each outgoing flow with its exact guard
    /// (the first condition that holds, in order; the default when none does). `None` when a
    /// condition reads anything undeclared.
    pub(super) fn data_guards(&self, n: NodeId) -> Option<Vec<(FlowId, String)>> {
        let node = self.g.node(n);
        if node.outgoing.len() < 2 || self.vars.is_empty() {
            return None;
        }
        let mut earlier: Vec<String> = Vec::new();
        let mut out = Vec::new();
        for f in &node.outgoing {
            if Some(*f) == node.default_flow {
                continue;
            }
            let cond = match &self.g.flow(*f).condition {
                Some(c) => crate::data::expression(&c.cel_text().ok()?, &self.vars)?,
                None => "true".to_owned(),
            };
            let mut guard: Vec<String> = earlier.iter().map(|e| format!("!{e}")).collect();
            guard.push(cond.clone());
            out.push((*f, format!("({})", guard.join(" && "))));
            earlier.push(cond);
        }
        if let Some(d) = node.default_flow {
            let none: Vec<String> = earlier.iter().map(|e| format!("!{e}")).collect();
            out.push((
                d,
                if none.is_empty() {
                    "true".to_owned()
                } else {
                    format!("({})", none.join(" && "))
                },
            ));
        }
        Some(out)
    }

    /// What completing `n` does to declared data: script assignments (exact where they
    /// translate, else any value of the range) and task outputs (any value).
    pub(super) fn data_effects(&self, n: NodeId) -> Vec<String> {
        let mut out = Vec::new();
        if self.vars.is_empty() {
            return out;
        }
        if let NodeKind::Task(t) = &self.g.node(n).kind {
            if let Some(assignments) = t.script.as_ref().and_then(|s| s.assignments.as_ref()) {
                for (name, e) in assignments {
                    if let Some(k) = self.vars.get(name) {
                        out.extend(crate::data::assign(
                            name,
                            k,
                            e.cel_text()
                                .ok()
                                .and_then(|t| crate::data::expression(&t, &self.vars)),
                        ));
                    }
                }
            }
            if let Some(b) = &t.binding {
                for o in &b.outputs {
                    if let Some(k) = self.vars.get(&o.target) {
                        out.extend(crate::data::assign(&o.target, k, None));
                    }
                }
            }
        }
        out
    }

    /// The link catch event named `name` in the scope of `throw` (the engine's choice: the
    /// first in the scope).
    fn link_catch(&self, throw: NodeId, name: &str) -> Option<NodeId> {
        self.g
            .scope_nodes(self.g.node(throw).scope)
            .iter()
            .copied()
            .find(|m| {
                matches!(&self.g.node(*m).kind, NodeKind::Catch(ce)
                    if ce.triggers.iter().any(|d| matches!(d, EventDefinition::Link(l) if l == name)))
            })
    }

    pub(super) fn node(&mut self, c: usize, n: NodeId) {
        let node = self.g.node(n);
        let (ins, outs) = (node.incoming.clone(), node.outgoing.clone());
        match &node.kind {
            NodeKind::Start(_) => {
                self.passes(c, n);
                self.message_start(c, n);
            }
            NodeKind::Boundary(_) => self.passes(c, n),
            NodeKind::End(defs) => {
                for f in ins {
                    let m = self.marker(c, n, "end");
                    let mut alt = Alt {
                        throw: executive_engine::throws(defs),
                        ..Alt::default()
                    };
                    self.take(c, f, &mut alt);
                    self.ending = Some(c);
                    self.throw(c, n, defs, &mut alt);
                    self.ending = None;
                    self.push(&m, alt);
                }
                self.resume(c, n);
            }
            NodeKind::Throw(defs) => {
                // A link throw: the token goes on at the link catch event of the same name in
                // the same scope, as the engine moves it (none: the token stays, as the engine's
                // incident leaves it).
                let link = defs.iter().find_map(|d| match d {
                    EventDefinition::Link(name) => Some(self.link_catch(n, name)),
                    _ => None,
                });
                if let Some(None) = link {
                    return;
                }
                for f in ins {
                    let m = self.marker(c, n, "");
                    let mut alt = Alt {
                        throw: executive_engine::throws(defs),
                        ..Alt::default()
                    };
                    self.take(c, f, &mut alt);
                    if let Some(Some(target)) = link {
                        let on = self.g.node(target).outgoing.clone();
                        self.put_all(c, &on, &mut alt);
                    } else {
                        // The token moves on before what the throw does takes effect: a
                        // signal that interrupts the thrower's own scope withdraws it too.
                        let mut thrown = Alt::default();
                        if self.throw(c, n, defs, &mut thrown) {
                            self.put_all(c, &outs, &mut alt);
                        }
                        alt.effect.extend(thrown.effect);
                    }
                    self.push(&m, alt);
                }
                self.resume(c, n);
            }
            NodeKind::Catch(ce) => {
                // A signal is heard when thrown, a message from the model when sent.
                let signal_only = ce
                    .triggers
                    .iter()
                    .all(|t| matches!(t, EventDefinition::Signal(_)))
                    || inner_message(self.g, n);
                for f in ins {
                    let from = self.g.flow(f).source;
                    let gateway = matches!(&self.g.node(from).kind,
                        NodeKind::Gateway(gw) if matches!(gw.kind, GatewayKind::EventBased { .. }));
                    if signal_only {
                        continue; // heard only when a signal is thrown
                    }
                    // Behind an event-based gateway, the shortest of its timers fires first.
                    if gateway
                        && let Some(d) = fixed_duration(self.g.node(n))
                        && self.g.node(from).outgoing.iter().any(|o| {
                            fixed_duration(self.g.node(self.g.flow(*o).target))
                                .is_some_and(|other| other < d)
                        })
                    {
                        continue;
                    }
                    let m = self.marker(c, n, "fire");
                    let mut alt = Alt {
                        outside: true,
                        ..Alt::default()
                    };
                    if gateway {
                        let a = self.a(c, from);
                        alt.guard.push(format!("act[{a}]"));
                        alt.effect.push(format!("act[{a}] = 0"));
                    } else {
                        self.take(c, f, &mut alt);
                    }
                    self.put_all(c, &outs, &mut alt);
                    self.push(&m, alt);
                }
            }
            NodeKind::Gateway(gw) => self.gateway(c, n, gw.kind, &ins, &outs),
            NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_) => {
                self.activity(c, n, &ins, &outs);
                if is_event_sub(self.g, n) {
                    self.event_sub(c, n);
                }
            }
        }
    }

    /// A send task has sent its message once it completes: its receivers in the model get it
    /// in that step.
    fn sent(&mut self, n: NodeId, alt: &mut Alt) {
        if matches!(&self.g.node(n).kind, NodeKind::Task(t) if t.kind == TaskKind::Send) {
            self.send_along(n, alt);
        }
    }

    pub(super) fn gateway(
        &mut self,
        c: usize,
        n: NodeId,
        kind: GatewayKind,
        ins: &[FlowId],
        outs: &[FlowId],
    ) {
        let cyclic = |t: &Self, f: FlowId| t.reaches(t.g.flow(f).target, n);
        match kind {
            GatewayKind::Parallel => {
                let m = self.marker(c, n, "");
                let mut alt = Alt::default();
                for f in ins {
                    self.take(c, *f, &mut alt);
                }
                if ins.len() > 1 {
                    self.joining.push(alt.guard.join(" && "));
                }
                self.put_all(c, outs, &mut alt);
                self.push(&m, alt);
            }
            GatewayKind::Exclusive if self.data_guards(n).is_some() => {
                // Decided by declared data, as the engine does: the first condition that
                // holds (in document order), else the default flow. Data bounds the cycles.
                let guards = self.data_guards(n).unwrap_or_default();
                for fi in ins {
                    for (fo, guard) in &guards {
                        let label = self.g.flow(*fo).id.clone();
                        let m = self.marker(c, n, &format!("take[{label}]"));
                        let mut alt = Alt::default();
                        self.take(c, *fi, &mut alt);
                        alt.guard.push(guard.clone());
                        self.put(c, *fo, &mut alt);
                        self.push(&m, alt);
                    }
                }
            }
            GatewayKind::Exclusive | GatewayKind::Complex => {
                // Branches that lead back here are bounded; when every branch does, one (the
                // default, else the first) stays free so the choice can always be made.
                let exit = outs.iter().any(|f| !cyclic(self, *f));
                let free = (!exit)
                    .then(|| self.g.node(n).default_flow.or(outs.first().copied()))
                    .flatten();
                for fi in ins {
                    for fo in outs {
                        let label = self.g.flow(*fo).id.clone();
                        let m = self.marker(c, n, &format!("take[{label}]"));
                        let mut alt = Alt::default();
                        self.take(c, *fi, &mut alt);
                        if Some(*fo) != free && cyclic(self, *fo) {
                            self.bound(c, n, &mut alt);
                        }
                        self.put(c, *fo, &mut alt);
                        self.push(&m, alt);
                    }
                    if outs.is_empty() {
                        let m = self.marker(c, n, "");
                        let mut alt = Alt::default();
                        self.take(c, *fi, &mut alt);
                        self.push(&m, alt);
                    }
                }
            }
            GatewayKind::Inclusive if ins.len() > 1 => {
                // Non-local join (§13.4.3): fire when some incoming flow is marked and no token
                // can still arrive on the empty ones — a token upstream of an empty flow waits
                // for it unless a path of sequence flows also leads it to a marked one, as the
                // engine decides (its `incoming_reached`).
                let m = self.marker(c, n, "join");
                let mut alt = Alt::default();
                // A token on a flow that has not arrived yet (of the next wave) is one that
                // can still arrive.
                let marked: Vec<String> = ins
                    .iter()
                    .map(|f| format!("ARRIVED({})", self.f(c, *f)))
                    .collect();
                alt.guard.push(format!("({})", marked.join(" || ")));
                // What can reach each incoming flow along sequence flows (and links) alone.
                let along: Vec<(usize, Upstream)> = ins
                    .iter()
                    .map(|f| (self.f(c, *f), self.upstream(c, *f, n, false)))
                    .collect();
                for f in ins {
                    let i = self.f(c, *f);
                    let (flows, acts) = self.upstream(c, *f, n, true);
                    // A token at `place` waits for flow `i` unless it can reach a marked one.
                    let exempt = |place: usize, act: bool| -> String {
                        along
                            .iter()
                            .filter(|(j, (fl, ac))| {
                                *j != i
                                    && if act {
                                        ac.contains(&place)
                                    } else {
                                        fl.contains(&place)
                                    }
                            })
                            .map(|(j, _)| format!(" || ARRIVED({j})"))
                            .collect()
                    };
                    let mut empty: Vec<String> = vec![format!("tok[{i}] == 0")];
                    empty.extend(
                        flows
                            .iter()
                            .map(|u| format!("(tok[{u}] == 0{})", exempt(*u, false))),
                    );
                    empty.extend(
                        acts.iter()
                            .map(|a| format!("(!act[{a}]{})", exempt(*a, true))),
                    );
                    alt.guard
                        .push(format!("(ARRIVED({i}) || ({}))", empty.join(" && ")));
                    alt.effect.push(format!(
                        "if :: ARRIVED({i}) -> tok[{i}]--; gen[{i}] = 0 :: else -> skip fi"
                    ));
                }
                self.joining.push(alt.guard.join(" && "));
                self.put_all(c, outs, &mut alt);
                self.push(&m, alt);
            }
            GatewayKind::Inclusive => {
                let Some(fi) = ins.first().copied() else {
                    return;
                };
                let exit = outs.iter().any(|f| !cyclic(self, *f));
                for mask in 1u32..(1 << outs.len()) {
                    let single = mask.count_ones() == 1 && mask & 1 == 1;
                    let chosen: Vec<FlowId> = outs
                        .iter()
                        .enumerate()
                        .filter(|(k, _)| mask & (1 << k) != 0)
                        .map(|(_, f)| *f)
                        .collect();
                    let names: Vec<String> =
                        chosen.iter().map(|f| self.g.flow(*f).id.clone()).collect();
                    let m = self.marker(c, n, &format!("take[{}]", names.join("+")));
                    let mut alt = Alt::default();
                    self.take(c, fi, &mut alt);
                    if (exit || !single) && chosen.iter().any(|f| cyclic(self, *f)) {
                        self.bound(c, n, &mut alt);
                    }
                    self.put_all(c, &chosen, &mut alt);
                    self.push(&m, alt);
                }
            }
            GatewayKind::EventBased { .. } => {
                // Like an activity that does not count its instances, the armed gateway keeps
                // the flow it was reached by: a second token along it while it waits is unsafe
                // (the engine arms it twice; the translation keeps one).
                let a = self.a(c, n);
                for fi in ins {
                    let m = self.marker(c, n, "arm");
                    let mut alt = Alt::default();
                    self.take(c, *fi, &mut alt);
                    self.enter_along(c, a, ins, *fi, &mut alt);
                    alt.effect.push(format!("act[{a}] = 1"));
                    alt.effect.extend(self.listening(n));
                    self.push(&m, alt);
                }
            }
        }
    }

    /// Enters an element that keeps the flow each token came by (`busy[]`, `ENTER`) along `f`:
    /// with none of it running (`act[a] == 0`), what a withdrawal left counted is zeroed first
    /// (a withdrawal zeroes only `act[]`).
    fn enter_along(&self, c: usize, a: usize, ins: &[FlowId], f: FlowId, alt: &mut Alt) {
        let stale: Vec<String> = ins
            .iter()
            .map(|i| format!("busy[{}] = 0", self.f(c, *i)))
            .collect();
        alt.effect.push(format!(
            "if :: act[{a}] == 0 -> {} :: else -> skip fi",
            stale.join("; ")
        ));
        alt.effect.push(format!("ENTER({})", self.f(c, f)));
    }

    /// Pushes `alt` (marked `m`), the end of one instance of an activity: once per flow an
    /// instance may have come by (`ways_in`), or as it is when the activity does not count them.
    fn push_per_way_in(&mut self, m: &str, alt: Alt, ways_in: &[usize]) {
        if ways_in.is_empty() {
            return self.push(m, alt);
        }
        for i in ways_in {
            let mut one = alt.clone();
            one.guard.push(format!("busy[{i}] > 0"));
            one.effect.push(format!("busy[{i}]--"));
            self.push(m, one);
        }
    }

    /// Flows and activity slots from which `flow` can still receive a token, not passing
    /// through the join `join` (static, like fbpmn's `PreEdges`): along sequence flows and
    /// links (a link catch is reached from the link throws of its name in its scope) and, with
    /// `boundaries`, from an activity through its boundary events.
    pub(super) fn upstream(
        &self,
        c: usize,
        flow: FlowId,
        join: NodeId,
        boundaries: bool,
    ) -> Upstream {
        let g = self.g;
        let (mut flows, mut acts) = (BTreeSet::new(), BTreeSet::new());
        let mut seen = BTreeSet::new();
        let mut stack = vec![g.flow(flow).source];
        while let Some(n) = stack.pop() {
            if n == join || !seen.insert(n) {
                continue;
            }
            let node = g.node(n);
            if let Some(a) = self.act_ix.get(&(c, n)) {
                acts.insert(*a);
            }
            for f in &node.incoming {
                flows.insert(self.f(c, *f));
                stack.push(g.flow(*f).source);
            }
            match &node.kind {
                NodeKind::Boundary(b) if boundaries => stack.push(b.attached_to),
                NodeKind::Catch(k) => {
                    for name in k.triggers.iter().filter_map(|d| match d {
                        EventDefinition::Link(l) => Some(l),
                        _ => None,
                    }) {
                        stack.extend(g.scope_nodes(node.scope).iter().copied().filter(|t| {
                            matches!(&g.node(*t).kind, NodeKind::Throw(defs)
                                if defs.iter().any(|d| matches!(d, EventDefinition::Link(l) if l == name)))
                        }));
                    }
                }
                _ => {}
            }
        }
        (flows, acts)
    }

    pub(super) fn activity(&mut self, c: usize, n: NodeId, ins: &[FlowId], outs: &[FlowId]) {
        /// How an activity is entered: along an incoming flow, or asked for (`pend[k]`) — a
        /// compensation handler by itself, an event sub-process at the start event that fired.
        #[derive(Clone, Copy)]
        enum Entry {
            Flow(FlowId),
            Asked(usize, NodeId),
        }
        let node = self.g.node(n);
        let a = self.a(c, n);
        let (body, child): (Option<Option<NodeId>>, Option<usize>) = match &node.kind {
            NodeKind::SubProcess(_) => (Some(Some(n)), None),
            NodeKind::CallActivity(ca) => match &ca.called {
                Some(Called::Process(_)) => {
                    let cc = self.child(c, n);
                    (cc.map(|_| None), cc)
                }
                _ => (None, None),
            },
            _ => (None, None),
        };
        let body_ctx = child.unwrap_or(c);
        let mi = match &node.looping {
            Some(Looping::MultiInstance(mi)) => Some(mi.as_ref()),
            _ => None,
        };
        // Parallel instances of a task: `act[a]` counts the instances still running.
        // (The bodies of a parallel sub-process or called process run one after another, as
        // a sequential loop: each instance's marking is the one body's.)
        let parallel = mi
            .filter(|mi| !mi.sequential && body.is_none())
            .map(|mi| self.instances(mi));
        // The instances may end before all have completed (a completion condition, or a
        // complex behaviour that stops them).
        let early = mi.is_some_and(|mi| {
            mi.completion.is_some() || mi.behavior == executive_model::MiBehavior::Complex
        });
        // A count the model writes as a number runs exactly that many instances, as the engine
        // runs them (up to `MAX_INSTANCES`), unless they may end early.
        let exact = node
            .looping
            .as_ref()
            .and_then(|l| l.literal_count())
            .filter(|_| !early)
            .map(|k| k.min(MAX_INSTANCES));
        // Completing instances throw the activity's behaviour event to its signal boundaries.
        let behaviour: Vec<NodeId> = match mi {
            Some(mi) if mi.behavior != executive_model::MiBehavior::All => node
                .boundaries
                .iter()
                .copied()
                .filter(|b| {
                    matches!(&self.g.node(*b).kind, NodeKind::Boundary(be)
                    if be.triggers.iter().any(|t| matches!(t, EventDefinition::Signal(_))))
                })
                .collect(),
            _ => Vec::new(),
        };
        let fails = match &node.kind {
            // A receive task waits for its message; nothing it runs can fail.
            NodeKind::Task(t) => !matches!(
                t.kind,
                TaskKind::User | TaskKind::Script | TaskKind::Receive
            ),
            NodeKind::CallActivity(_) => outside(self.g, n),
            _ => false,
        };
        // A failure may be caught by any error catcher: the activity's own boundaries, then
        // those around it (each may be the one that catches some code).
        let mut catchers = Vec::new();
        if fails {
            let any_error = |t: &[EventDefinition]| {
                t.iter().any(|d| matches!(d, EventDefinition::Error { .. }))
            };
            for b in &node.boundaries {
                if let NodeKind::Boundary(be) = &self.g.node(*b).kind
                    && any_error(&be.triggers)
                {
                    catchers.push((
                        0,
                        Catch::Boundary {
                            c,
                            holder: n,
                            b: *b,
                        },
                    ));
                }
            }
            catchers.extend(
                self.catchers(c, n, &any_error)
                    .into_iter()
                    .map(|(l, x)| (l + 1, x)),
            );
        }
        let catchers = self.reachable(catchers);
        // A task nothing can interrupt is one step (start and completion folded: fewer
        // interleavings, the same reachable markings between steps). A task run outside whose
        // scope something may withdraw is not: the engine enters it in its wave, before a
        // throw of that wave acts, so its start is a step of its own.
        if body.is_none()
            && node.boundaries.is_empty()
            && node.looping.is_none()
            && catchers.is_empty()
            && !self.pend_ix.contains_key(&(c, n))
            && !self.observe.contains(&Atom::Running(n))
            && !(outside(self.g, n) && self.withdrawable(c, n))
        {
            self.folded.insert(n);
            for f in ins {
                let m = self.marker(c, n, "run");
                let mut alt = Alt {
                    outside: outside(self.g, n),
                    ..Alt::default()
                };
                self.take(c, *f, &mut alt);
                alt.effect.extend(self.data_effects(n));
                alt.effect.extend(self.completed(c, n));
                self.put_all(c, outs, &mut alt);
                self.sent(n, &mut alt);
                self.push(&m, alt);
            }
            return;
        }
        // Start (or activate): along an incoming flow, or when asked for (a compensation
        // handler; an event sub-process, at the start event that fired).
        let mut entries: Vec<Entry> = ins.iter().map(|f| Entry::Flow(*f)).collect();
        if let Some(k) = self.pend_ix.get(&(c, n)) {
            entries.push(Entry::Asked(*k, n));
        }
        if let NodeKind::SubProcess(sp) = &node.kind
            && is_event_sub(self.g, n)
        {
            for s in &sp.nodes {
                if matches!(self.g.node(*s).kind, NodeKind::Start(_))
                    && let Some(k) = self.pend_ix.get(&(c, *s))
                {
                    entries.push(Entry::Asked(*k, *s));
                }
            }
        }
        // A task without a loop, entered only along its flows, counts its instances and the
        // flow each came by (`ENTER`).
        let counted =
            body.is_none() && node.looping.is_none() && !self.pend_ix.contains_key(&(c, n));
        let ways_in: Vec<usize> = if counted {
            ins.iter().map(|f| self.f(c, *f)).collect()
        } else {
            Vec::new()
        };
        for entry in entries {
            let phase = if body.is_some() { "activate" } else { "start" };
            let m = self.marker(c, n, phase);
            let mut alt = Alt::default();
            match entry {
                Entry::Flow(f) => self.take(c, f, &mut alt),
                Entry::Asked(k, _) => {
                    alt.guard.push(format!("pend[{k}] > 0"));
                    alt.effect.push(format!("pend[{k}]--"));
                }
            }
            // No instance at all (a count of 0): the activity completes at once.
            let none = parallel == Some(0) || (parallel.is_none() && exact == Some(0));
            // An instance keeps the flow it was entered by until it ends, as the engine's token
            // does: a second token entering along that flow while it runs is unsafe. Beside a
            // task another instance starts; a sub-process, loop or multi-instance activity
            // runs its body once for both (the translation has one marking per scope).
            if let Entry::Flow(f) = entry
                && !none
            {
                self.enter_along(c, a, ins, f, &mut alt);
            }
            match parallel {
                _ if none => {
                    alt.effect.extend(self.data_effects(n));
                    self.put_all(c, outs, &mut alt);
                    self.push(&m, alt);
                    continue;
                }
                Some(k) if k > 1 && exact.is_some() => alt.effect.push(format!("act[{a}] = {k}")),
                Some(k) if k > 1 => {
                    let choose: Vec<String> =
                        (1..=k).map(|i| format!(":: act[{a}] = {i}")).collect();
                    alt.effect.push(format!("if {} fi", choose.join(" ")));
                }
                // A task counts its instances (up to two).
                _ if counted => {
                    alt.effect.push(format!(
                        "if :: act[{a}] < 2 -> act[{a}]++ :: else -> skip fi"
                    ));
                }
                _ => alt.effect.push(format!("act[{a}] = 1")),
            }
            alt.effect.extend(self.listening(n));
            // A loop's bodies are counted per start of the loop.
            if node.looping.is_some()
                && let Some(k) = self.cnt_ix.get(&(c, n))
            {
                alt.effect.push(format!("reps[{k}] = 0"));
            }
            // Non-interrupting boundaries count their firings per activation.
            for b in &node.boundaries {
                if !interrupting(self.g, *b)
                    && let Some(k) = self.cnt_ix.get(&(c, *b))
                {
                    alt.effect.push(format!("reps[{k}] = 0"));
                }
            }
            match (body, entry) {
                // An event sub-process starts at the start event that fired.
                (Some(scope), Entry::Asked(_, start)) if start != n => {
                    self.reset(body_ctx, scope, &mut alt);
                    self.start_implicit(body_ctx, scope, &mut alt);
                    self.arrive(body_ctx, start, &mut alt);
                }
                (Some(scope), _) => self.start_body(body_ctx, scope, &mut alt),
                _ => {}
            }
            self.push(&m, alt);
        }
        // Completion: a task whenever the system answers; a scope once nothing runs inside.
        let done_guard = match body {
            Some(scope) => format!("act[{a}] && {}", self.idle_inside(body_ctx, scope)),
            None => format!("act[{a}]"),
        };
        // The ways out of a running activity (completion, a caught failure, a boundary event):
        // those that lead back to it are bounded, except completion when every way leads
        // back (so the activity can always end).
        let spontaneous: Vec<NodeId> = node
            .boundaries
            .iter()
            .copied()
            .filter(|b| match &self.g.node(*b).kind {
                NodeKind::Boundary(_) if inner_message(self.g, *b) => false,
                NodeKind::Boundary(be) => be.triggers.iter().any(|t| {
                    matches!(
                        t,
                        EventDefinition::Timer(_)
                            | EventDefinition::Message(_)
                            | EventDefinition::Conditional(_)
                    )
                }),
                _ => false,
            })
            .chain(behaviour.iter().copied())
            .collect();
        let back = |t: &Self, b: NodeId, to: NodeId| t.leads_back(&t.g.node(b).outgoing, to);
        let completes_back = self.leads_back(outs, n);
        let exit = !completes_back
            || catchers.iter().any(|x| match x {
                Catch::Boundary { holder, b, .. } => !back(self, *b, *holder),
                Catch::EventSub { .. } => true,
            })
            || spontaneous
                .iter()
                .any(|b| interrupting(self.g, *b) && !back(self, *b, n));
        let choices = !catchers.is_empty() || !spontaneous.is_empty();
        // Bodies one after another, exactly as many as the model writes (`exact`), where
        // completion does not count the cycles itself.
        let bodies = exact.filter(|_| parallel.is_none() && !(choices && exit && completes_back));
        if parallel.is_some() {
            // One instance of several completes; the last one completes the activity.
            let m = self.marker(c, n, "complete-instance");
            let mut alt = Alt {
                outside: outside(self.g, n),
                ..Alt::default()
            };
            alt.guard.push(format!("act[{a}] > 1"));
            alt.effect.push(format!("act[{a}]--"));
            self.push(&m, alt);
        } else if node.looping.is_some() {
            let m = self.marker(c, n, "repeat");
            let mut alt = Alt {
                outside: body.is_none() && outside(self.g, n),
                ..Alt::default()
            };
            alt.guard.push(done_guard.clone());
            match (bodies, self.cnt_ix.get(&(c, n))) {
                (Some(k), Some(r)) => {
                    alt.guard.push(format!("reps[{r}] + 1 < {k}"));
                    alt.effect.push(format!("reps[{r}]++"));
                }
                _ => self.bound(c, n, &mut alt),
            }
            if let Some(scope) = body {
                self.start_body(body_ctx, scope, &mut alt);
            }
            self.push(&m, alt);
        }
        let m = self.marker(c, n, "complete");
        let mut alt = Alt {
            outside: body.is_none() && outside(self.g, n),
            ..Alt::default()
        };
        if choices && exit && completes_back {
            // Another way out leaves the cycle.
            self.bound(c, n, &mut alt);
        }
        alt.guard.push(done_guard);
        if let (Some(k), Some(r)) = (bodies, self.cnt_ix.get(&(c, n))) {
            alt.guard.push(format!("reps[{r}] + 1 == {k}"));
        }
        if parallel.is_some() && !early {
            alt.guard.push(format!("act[{a}] == 1"));
        }
        // One instance of a task ends (the one that came by the flow chosen); the others run on.
        let one_ends = if counted {
            format!("act[{a}]--")
        } else {
            format!("act[{a}] = 0")
        };
        alt.effect.push(one_ends.clone());
        alt.effect.extend(self.data_effects(n));
        alt.effect.extend(self.completed(c, n));
        self.sent(n, &mut alt);
        self.put_all(c, outs, &mut alt);
        self.push_per_way_in(&m, alt, &ways_in);
        // A system's failure, caught by a boundary here or around.
        {
            for catch in catchers {
                let b = catch.node();
                let m = self.marker(c, n, &format!("fail[{}]", self.g.node(b).id));
                let mut alt = Alt {
                    outside: true,
                    ..Alt::default()
                };
                alt.guard.push(format!("act[{a}]"));
                if let Catch::Boundary { c: cc, holder, b } = catch
                    && back(self, b, holder)
                {
                    self.bound(cc, b, &mut alt);
                }
                alt.effect.push(one_ends.clone());
                let code = self
                    .triggers(b)
                    .iter()
                    .find_map(|t| match t {
                        EventDefinition::Error { error, .. } => {
                            Some(error.and_then(|e| self.g.errors[e.index()].code.clone()))
                        }
                        _ => None,
                    })
                    .flatten();
                alt.effect.extend(self.error_observed(code.as_deref()));
                self.caught(catch, &mut alt);
                self.push_per_way_in(&m, alt, &ways_in);
            }
        }
        // Timers, messages and conditions on the boundary may fire while the activity runs.
        // Timers armed together fire in the order of their durations: a longer one on the same
        // activity never fires once a shorter interrupting one has ended the activity.
        let shortest = spontaneous
            .iter()
            .filter(|b| interrupting(self.g, **b) && !behaviour.contains(b))
            .filter_map(|b| fixed_duration(self.g.node(*b)))
            .min();
        for b in spontaneous {
            if let (Some(d), Some(min)) = (fixed_duration(self.g.node(b)), shortest)
                && d > min
            {
                continue;
            }
            let m = self.marker(c, b, "fire");
            let mut alt = Alt {
                outside: true,
                ..Alt::default()
            };
            alt.guard.push(format!("act[{a}]"));
            if interrupting(self.g, b) && !behaviour.contains(&b) {
                if back(self, b, n) {
                    self.bound(c, b, &mut alt);
                }
                self.cancel(c, n, &mut alt);
                alt.effect
                    .extend(ways_in.iter().map(|i| format!("busy[{i}] = 0")));
            } else if let Some(k) = self.cnt_ix.get(&(c, b)).copied() {
                // Beside the running activity: a duration timer once per activation, anything
                // else (messages, conditions, cycles) a bounded number of times.
                // A behaviour event: `One` once, `None` and `Complex` once per instance.
                let once = fixed_duration(self.g.node(b)).is_some()
                    || (behaviour.contains(&b)
                        && mi.is_some_and(|mi| mi.behavior == executive_model::MiBehavior::One));
                let limit = if once {
                    1
                } else if behaviour.contains(&b) {
                    parallel.map_or(u32::from(self.bounds.loops) + 1, |k| k as u32)
                } else {
                    u32::from(self.bounds.loops) + 1
                };
                alt.guard.push(format!("reps[{k}] < {limit}"));
                alt.effect.push(format!("reps[{k}]++"));
            }
            self.arrive(c, b, &mut alt);
            self.push(&m, alt);
        }
    }
}
