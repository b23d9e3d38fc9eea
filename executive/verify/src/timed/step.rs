//! One step of the timed exploration: what can happen next and when, taking it (the engine
//! steps, the clocks and the energy follow), decisions read from the data or the battery, and the
//! loop bound on free choices.

use super::*;

/// Everything that can happen next, with how long from now.
pub(super) fn successors(cx: &Ctx, n: &Node) -> Vec<Next> {
    let g = cx.g;
    let s = &n.state;
    let mut out = Vec::new();
    // A mission that is over waits for nothing, not even its battery.
    if n.over(cx) {
        return out;
    }
    // A vehicle whose battery is empty does nothing more.
    let idle = |node: NodeId| n.empty.contains(&cx.vehicle_of(node));
    // Decisions are instantaneous: while a gateway decides, nothing else happens.
    for (tid, t) in &s.tokens {
        if !matches!(t.at, At::Deciding) || idle(t.node) {
            continue;
        }
        let decided = decide(cx, n, t.node, t.scope);
        for flows in crate::explore::branches(g, t.node) {
            if let Some(d) = &decided
                && *d != flows
            {
                continue;
            }
            // A free choice that leads back is bounded per scope activation.
            if decided.is_none()
                && bounded(cx, t.node, &flows)
                && n.loops.get(&(t.scope, t.node)).copied().unwrap_or(0) >= cx.limits.loops
            {
                continue;
            }
            out.push(Next {
                label: crate::explore::take_label(g, t.node, &flows),
                event: Some(Event::BranchTaken { token: *tid, flows }),
                when: When::Now,
                node: Some(t.node),
            });
        }
        return out;
    }
    for (key, r) in &n.running {
        let Some(tok) = s
            .tokens
            .values()
            .find(|t| matches!(&t.at, At::Task(k) | At::UserTask(k) if k == key))
        else {
            continue;
        };
        let id = &g.node(r.node).id;
        let clock = Clock::Task(r.node, *key);
        let after = |c: &TaskCost| When::After(clock.clone(), c.duration_ms.0);
        out.push(Next {
            label: format!("{id}.complete"),
            event: Some(Event::TaskCompleted {
                task: *key,
                output: Vars::new(),
            }),
            when: after(&r.cost),
            node: Some(r.node),
        });
        if matches!(tok.at, At::Task(_)) {
            // The codes its action can fail with (a code no boundary names stands for the rest,
            // the protocol's among them, which a catch-all catches).
            let codes = cx.codes.iter().filter(|c| {
                c.as_str() == crate::explore::UNNAMED
                    || r.cost.codes.as_ref().is_none_or(|k| k.contains(*c))
            });
            for c in codes {
                out.push(Next {
                    label: format!("{id}.fail[{c}]"),
                    event: Some(Event::TaskFailed {
                        task: *key,
                        code: c.clone(),
                        message: String::new(),
                    }),
                    when: after(r.cost.outcome(Some(c))),
                    node: Some(r.node),
                });
            }
        }
    }
    // The outside starts a process with a message or condition start once per run, while it is
    // idle (as in the untimed exploration and the translation).
    for (start, label, event) in crate::explore::starts_now(g, s, &cx.starts) {
        if idle(start) {
            continue;
        }
        out.push(Next {
            label,
            event: Some(event),
            when: When::Any,
            node: Some(start),
        });
    }
    for (wid, w) in &s.waits {
        // A non-interrupting event sub-process runs one instance at a time (as in the
        // untimed exploration and the translation).
        if crate::explore::running_beside(g, s, w) || idle(w.node) {
            continue;
        }
        let label = format!("{}.fire", g.node(w.node).id);
        match w.on {
            On::Timer { key, .. } => {
                if let Some(t) = n.timers.get(&key) {
                    out.push(Next {
                        label,
                        event: Some(Event::TimerFired { timer: key }),
                        when: When::After(Clock::Timer(t.node, key), t.dur),
                        node: Some(w.node),
                    });
                }
            }
            // A message the model's own senders send comes with their step.
            On::Message(..) if crate::promela::inner_message(g, w.node) => {}
            On::Message(..) | On::Condition { .. } | On::Manual => out.push(Next {
                label,
                event: Some(Event::WaitTriggered { wait: *wid }),
                when: When::Any,
                node: Some(w.node),
            }),
            _ => {}
        }
    }
    for v in 0..cx.costs.vehicles.len() {
        let die = death(cx, n, v);
        if die.lo.is_finite() {
            out.push(Next {
                label: match cx.costs.vehicles[v].pool.as_deref() {
                    Some(pool) if cx.costs.vehicles.len() > 1 => format!("battery empty: {pool}"),
                    _ => "battery empty".into(),
                },
                event: None,
                when: When::Dies(v, die.lo),
                node: None,
            });
        }
    }
    out
}

/// Whether taking flow `f` out of `node` can lead back to it.
pub(super) fn back(cx: &Ctx, node: NodeId, f: executive_model::FlowId) -> bool {
    crate::promela::reaches(cx.g, cx.g.flow(f).target, node)
}

/// Whether a choice of `flows` at `node` continues a cycle, and so counts against the loop
/// bound: some flow leads back — except that when every flow of the node does, one (the
/// default, else the first) stays free so the choice can always be made, as in the Spin
/// translation.
pub(super) fn bounded(cx: &Ctx, node: NodeId, flows: &[executive_model::FlowId]) -> bool {
    let n = cx.g.node(node);
    let exit = n.outgoing.iter().any(|f| !back(cx, node, *f));
    let free = (!exit)
        .then(|| n.default_flow.or(n.outgoing.first().copied()))
        .flatten();
    flows.iter().any(|f| back(cx, node, *f) && Some(*f) != free)
}

/// How long from now vehicle `v`'s battery runs out, ms: the least and the greatest draw using
/// what is left (never, once it is empty).
pub(super) fn death(cx: &Ctx, n: &Node, v: usize) -> Span {
    if n.empty.contains(&v) {
        return Span::point(f64::INFINITY);
    }
    let rate = cx.rate(n, v);
    let left = reading(cx.capacity(v), n.used(v), Reading::EnergyWh);
    let left = Span {
        lo: left.lo.max(0.0),
        hi: left.hi.max(0.0),
    };
    let over = |wh: f64, w: f64| {
        if w > 0.0 {
            wh * HOUR_MS / w
        } else {
            f64::INFINITY
        }
    };
    Span {
        lo: over(left.lo, rate.hi),
        hi: over(left.hi, rate.lo),
    }
}

/// The zone in which step `x` comes next (time passes as long as nothing pending is overdue,
/// then `x`'s own guard), with a clock that measured the wait; `None` if it cannot come next.
pub(super) fn elapse(cx: &Ctx, n: &Node, when: &When) -> Option<(Zone, usize)> {
    let mut z = n.zone.clone();
    let wait = z.add();
    if !matches!(when, When::Now) {
        z.up();
        // Nothing pending passes its latest moment: tasks their greatest duration (any outcome),
        // timers their deadline, the battery its last drop.
        for (i, c) in n.clocks.iter().enumerate() {
            let most = match c {
                Clock::Task(_, k) => n.running.get(k).map(|r| {
                    r.cost
                        .errors
                        .values()
                        .map(|e| e.duration_ms.1)
                        .fold(r.cost.duration_ms.1, f64::max)
                }),
                Clock::Timer(_, k) => n.timers.get(k).map(|t| t.dur),
                _ => None,
            };
            if let Some(most) = most {
                z.at_most(i + 1, most);
            }
        }
        for v in 0..cx.costs.vehicles.len() {
            z.at_most(wait, death(cx, n, v).hi);
        }
        match when {
            When::After(c, least) => z.at_least(n.clock(c), *least),
            When::Dies(_, least) => z.at_least(wait, *least),
            _ => {}
        }
    }
    z.close().then_some((z, wait))
}

/// The energy of drawing `power` W for `d` ms, Wh.
pub(super) fn wh(d: Span, power: Span) -> Span {
    let e = d.times(power);
    Span {
        lo: e.lo / HOUR_MS,
        hi: e.hi / HOUR_MS,
    }
}

/// Takes step `x` in zone `z` (from [`elapse`], its clock `wait` measuring the wait): the
/// engine steps, the clocks follow. `None`: no run takes it.
pub(super) fn take(cx: &Ctx, n: &Node, x: &Next, mut z: Zone, wait: usize) -> Option<Node> {
    let (lo, hi) = z.bounds(wait);
    let d = Span { lo, hi };
    z.remove(wait);
    let mut c = n.clone();
    c.zone = z;
    for (v, e) in c.energy.iter_mut().enumerate() {
        if !n.empty.contains(&v) {
            let cap = cx.capacity(v);
            *e = e.plus(wh(d, Span::point(cx.idle(v))));
            e.lo = e.lo.min(cap);
            e.hi = e.hi.min(cap);
        }
    }
    for r in c.running.values_mut() {
        r.spent = r.spent.plus(wh(d, cx.power(r.cost.power_envelope())));
    }
    for r in c.readings.values_mut() {
        r.peak = r.peak.max(cx.rate(n, r.vehicle).hi);
    }
    remember(cx, &mut c)?;
    let Some(event) = x.event.clone() else {
        let When::Dies(v, _) = x.when else {
            return None;
        };
        empty(cx, &mut c, v);
        return Some(c);
    };
    let mut e = cx.engine(n.state.clone(), &n.empty);
    let seq = n.state.last_seq + 1;
    let (ending, code) = match &event {
        Event::TaskCompleted { task, .. } | Event::UserTaskAnswered { task, .. } => {
            (Some(*task), None)
        }
        Event::TaskFailed { task, code, .. } => (Some(*task), Some(code.clone())),
        _ => (None, None),
    };
    let failing = code.is_some();
    let (branch, asserted) = match &event {
        Event::BranchTaken { token, flows } => match n.state.tokens.get(token) {
            Some(tk) => (
                Some((
                    tk.scope,
                    tk.node,
                    bounded(cx, tk.node, flows),
                    decide(cx, n, tk.node, tk.scope).is_none(),
                )),
                asserted(cx.g, tk.node, flows),
            ),
            None => (None, Vec::new()),
        },
        _ => (None, Vec::new()),
    };
    let actions = e
        .step(Input {
            seq,
            at: c.t().lo as i64,
            event,
        })
        .ok()?;
    let after = e.state().clone();
    // A failure nothing catches ends the mission as failed: tasks fail only with codes some
    // boundary catches (as in the Spin translation); a run followed fails as it did.
    if failing
        && !cx.data
        && after
            .instances
            .values()
            .any(|i| matches!(i.outcome, Some(EngineOutcome::Failed { .. })))
    {
        return None;
    }
    for (cond, holds) in asserted {
        refine(cx, &mut c, cond, holds)?;
    }
    let mut spent = None;
    if let Some(key) = ending
        && let Some(r) = c.running.remove(&key)
    {
        // Ended, its outcome is known: its energy is the time it ran at that outcome's power.
        let (lo, hi) = c.zone.bounds(c.clock(&Clock::Task(r.node, key)));
        let power = cx.power(r.cost.outcome(code.as_deref()).power_w);
        let own = wh(Span { lo, hi }, power);
        let v = r.vehicle;
        c.energy[v] = c.energy[v].plus(own);
        c.stop_clock(&Clock::Task(r.node, key));
        spent = Some(own);
        let energy = c.used(v);
        for (var, kind) in &r.cost.reads {
            let value = reading(cx.capacity(v), energy, *kind);
            c.stop_clock(&Clock::Read(var.clone()));
            c.start_clock(Clock::Read(var.clone()));
            c.readings.insert(
                var.clone(),
                Read {
                    value,
                    kind: *kind,
                    peak: 0.0,
                    vehicle: v,
                },
            );
        }
    }
    // A free branch that leads back counts against the loop bound.
    if let Some((scope, node, back, free)) = branch
        && back
        && free
    {
        let k = c.loops.entry((scope, node)).or_default();
        *k = k.saturating_add(1);
    }
    // So does a caught failure whose boundary leads back to its activity.
    if failing {
        for a in &actions {
            if let Action::Record(r) = a
                && let Entry::Caught {
                    what: Trigger::Error,
                    node,
                    ..
                } = &r.entry
                && let NodeKind::Boundary(b) = &cx.g.node(*node).kind
                && cx
                    .g
                    .node(*node)
                    .outgoing
                    .iter()
                    .any(|f| back(cx, b.attached_to, *f))
            {
                let scope = after
                    .tokens
                    .values()
                    .find(|t| cx.g.node(t.node).scope == cx.g.node(*node).scope)
                    .map_or(ScopeId(0), |t| t.scope);
                let k = c.loops.entry((scope, *node)).or_default();
                if *k >= cx.limits.loops {
                    return None;
                }
                *k += 1;
            }
        }
    }
    note(cx, &mut c, &actions);
    c.state = after;
    settle(cx, &mut c);
    extrapolate(cx, &mut c);
    c.via = Some(Via {
        from: 0,
        label: String::new(),
        spent,
    });
    Some(c)
}

/// The flows a gateway takes when its conditions can be decided: script data the engine holds,
/// battery readings at both ends of their bounds.
pub(super) fn decide(
    cx: &Ctx,
    n: &Node,
    gateway: NodeId,
    scope: ScopeId,
) -> Option<Vec<executive_model::FlowId>> {
    let g = cx.g;
    let node = g.node(gateway);
    let NodeKind::Gateway(gw) = &node.kind else {
        return None;
    };
    if !matches!(gw.kind, GatewayKind::Exclusive | GatewayKind::Inclusive) {
        return None;
    }
    // The variables the gateway sees: its scope's, then the enclosing ones'.
    let mut vars = Vars::new();
    let mut at = Some(scope);
    while let Some(id) = at {
        let sc = n.state.scopes.get(&id)?;
        for (k, v) in &sc.vars {
            vars.entry(k.clone()).or_insert_with(|| v.clone());
        }
        at = sc.parent;
    }
    let value = |cond: &executive_model::Expression| -> Option<bool> {
        let readings: Vec<&String> = cond
            .variables
            .iter()
            .filter(|v| n.readings.contains_key(*v))
            .collect();
        // A reading decides only a condition comparing it with a number (monotone, and what
        // `refine` narrows by); in any other condition the choice stays free.
        let simple = comparison(&cond.text).is_some_and(|(var, _, _)| readings == [&var]);
        if readings.len() > 1 || (readings.len() == 1 && !simple) {
            return None;
        }
        let at = |x: Option<f64>| -> Option<bool> {
            let mut v = vars.clone();
            if let (Some(name), Some(x)) = (readings.first(), x) {
                v.insert((*name).clone(), Value::from(x));
            }
            if cond.variables.iter().any(|k| !v.contains_key(k)) {
                return None;
            }
            match executive_engine::evaluate(cond, 0, &v) {
                Ok(Value::Bool(b)) => Some(b),
                _ => None,
            }
        };
        match readings.first() {
            None => at(None),
            Some(name) => {
                let r = n.readings[*name].value;
                let (a, b) = (at(Some(r.lo))?, at(Some(r.hi))?);
                (a == b).then_some(a)
            }
        }
    };
    let mut taken = Vec::new();
    let mut default = None;
    for f in &node.outgoing {
        let flow = g.flow(*f);
        if node.default_flow == Some(*f) {
            default = Some(*f);
            continue;
        }
        match &flow.condition {
            None => taken.push(*f),
            Some(c) => {
                if value(c)? {
                    taken.push(*f);
                }
            }
        }
    }
    if gw.kind == GatewayKind::Exclusive {
        taken.truncate(1);
    }
    if taken.is_empty() {
        taken.extend(default);
    }
    (!taken.is_empty()).then_some(taken)
}

/// Records what the step did: elements done and counted, signals thrown, errors caught.
pub(super) fn note(cx: &Ctx, c: &mut Node, actions: &[Action]) {
    for a in actions {
        let Action::Record(r) = a else { continue };
        match &r.entry {
            Entry::Left { node, .. } => count(cx, c, *node),
            Entry::Entered { node, .. } if matches!(cx.g.node(*node).kind, NodeKind::End(_)) => {
                count(cx, c, *node);
            }
            Entry::Thrown {
                what: Trigger::Signal,
                name,
                ..
            } if cx.signals.contains(name.as_str()) => {
                c.signals.insert(name.to_string());
            }
            Entry::Caught {
                what: Trigger::Error,
                name,
                ..
            } if cx.errors.contains(name.as_str()) => {
                c.errors.insert(name.to_string());
            }
            _ => {}
        }
    }
}

/// An element completed or was passed: done, and counted up to the bound a requirement needs.
pub(super) fn count(cx: &Ctx, c: &mut Node, node: NodeId) {
    if cx.watched.contains(&node) {
        c.done.insert(node);
    }
    if let Some(bound) = cx.counted.get(&node) {
        let k = c.counts.entry(node).or_default();
        *k = (*k + 1).min(*bound);
    }
}

/// Vehicle `v`'s battery is empty: it has used all of it and does nothing more — its tasks
/// and timers are dropped (with their clocks), its readings forgotten. The run is over once
/// every vehicle's is.
pub(super) fn empty(cx: &Ctx, c: &mut Node, v: usize) {
    c.energy[v] = Span::point(cx.capacity(v));
    c.empty.insert(v);
    c.dead = c.empty.len() == cx.costs.vehicles.len();
    for r in c.running.values_mut().filter(|r| r.vehicle == v) {
        r.spent = Span::point(0.0);
    }
    if c.dead {
        return;
    }
    let gone: Vec<String> = c
        .readings
        .iter()
        .filter(|(_, r)| r.vehicle == v)
        .map(|(k, _)| k.clone())
        .collect();
    for var in gone {
        c.readings.remove(&var);
        c.stop_clock(&Clock::Read(var));
    }
    settle(cx, c);
}

/// Brings the clocks in line with the engine state: tasks that started now run from now,
/// timers armed now count from now, and what the engine dropped is gone (a cancelled
/// activity's energy so far stays used, at most). A vehicle whose battery is empty runs
/// nothing.
pub(super) fn settle(cx: &Ctx, c: &mut Node) {
    let mut running = BTreeMap::new();
    let empty = c.empty.clone();
    let idle = |node: NodeId| empty.contains(&cx.vehicle_of(node));
    let tokens: Vec<(TaskKey, NodeId)> = c
        .state
        .tokens
        .values()
        .filter_map(|t| match t.at {
            At::Task(k) | At::UserTask(k) if !idle(t.node) => Some((k, t.node)),
            _ => None,
        })
        .collect();
    for (k, node) in tokens {
        let r = match c.running.remove(&k) {
            Some(r) => r,
            None => {
                c.start_clock(Clock::Task(node, k));
                Running {
                    node,
                    vehicle: cx.vehicle_of(node),
                    spent: Span::point(0.0),
                    cost: cx
                        .costs
                        .tasks
                        .get(&node)
                        .cloned()
                        .unwrap_or_else(|| TaskCost {
                            duration_ms: (0.0, 0.0),
                            ..TaskCost::open()
                        }),
                }
            }
        };
        running.insert(k, r);
    }
    // Cancelled: what they drew until then stays used, or less (a system may stop charging a
    // cancelled activity before the cancel reaches it).
    for (k, r) in std::mem::take(&mut c.running) {
        if !c.empty.contains(&r.vehicle) {
            c.energy[r.vehicle] = c.energy[r.vehicle].plus(Span {
                lo: 0.0,
                hi: r.spent.hi,
            });
        }
        c.stop_clock(&Clock::Task(r.node, k));
    }
    c.running = running;
    let at = c.t().lo;
    let mut timers = BTreeMap::new();
    let waits: Vec<(TimerKey, NodeId, f64)> = c
        .state
        .waits
        .values()
        .filter_map(|w| match w.on {
            On::Timer { key, due, .. } if !idle(w.node) => Some((key, w.node, due as f64)),
            _ => None,
        })
        .collect();
    for (key, node, due) in waits {
        let timer = match c.timers.remove(&key) {
            Some(t) => t,
            None => {
                // The engine armed it at `at`: it fires its duration after now.
                c.start_clock(Clock::Timer(node, key));
                Timer {
                    node,
                    dur: (due - at).max(0.0),
                }
            }
        };
        timers.insert(key, timer);
    }
    for (k, t) in std::mem::take(&mut c.timers) {
        c.stop_clock(&Clock::Timer(t.node, k));
    }
    c.timers = timers;
    c.sort_clocks();
    let scopes = &c.state.scopes;
    c.loops.retain(|(scope, _), _| scopes.contains_key(scope));
}

pub(super) fn asserted<'g>(
    g: &'g ProcessGraph,
    gateway: NodeId,
    flows: &[executive_model::FlowId],
) -> Vec<(&'g executive_model::Expression, bool)> {
    let node = g.node(gateway);
    let exclusive =
        matches!(&node.kind, NodeKind::Gateway(gw) if gw.kind == GatewayKind::Exclusive);
    let first = node.outgoing.iter().position(|f| flows.contains(f));
    let default = node.default_flow.is_some_and(|d| flows.contains(&d));
    let mut out = Vec::new();
    for (i, f) in node.outgoing.iter().enumerate() {
        let Some(cond) = &g.flow(*f).condition else {
            continue;
        };
        if Some(*f) == node.default_flow {
            continue;
        }
        let taken = flows.contains(f);
        if taken {
            out.push((cond, true));
        } else if default || !exclusive || first.is_some_and(|k| i < k) {
            out.push((cond, false));
        }
    }
    out
}

/// `var OP number` (or `number OP var`) with a comparison, as (var, op, number).
pub(super) fn comparison(text: &str) -> Option<(String, Cmp, f64)> {
    for (op, cmp, flipped) in [
        ("<=", Cmp::Le, Cmp::Ge),
        (">=", Cmp::Ge, Cmp::Le),
        ("<", Cmp::Lt, Cmp::Gt),
        (">", Cmp::Gt, Cmp::Lt),
    ] {
        if let Some((a, b)) = text.split_once(op) {
            let (a, b) = (a.trim(), b.trim());
            let ident =
                |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            return match (a.parse::<f64>(), b.parse::<f64>()) {
                (Err(_), Ok(k)) if ident(a) => Some((a.to_owned(), cmp, k)),
                (Ok(k), Err(_)) if ident(b) => Some((b.to_owned(), flipped, k)),
                _ => None,
            };
        }
    }
    None
}

/// Narrows a state by a condition a decision asserts (`holds`): a battery reading compared
/// with a number narrows the reading, and so the energy used then and now ([`remember`]).
/// `None`: no run can take this choice.
pub(super) fn refine(
    cx: &Ctx,
    c: &mut Node,
    cond: &executive_model::Expression,
    holds: bool,
) -> Option<()> {
    let Some((var, op, k)) = comparison(&cond.text) else {
        return Some(());
    };
    let Some(read) = c.readings.get_mut(&var) else {
        return Some(());
    };
    let op = match (holds, op) {
        (true, op) => op,
        (false, Cmp::Lt) => Cmp::Ge,
        (false, Cmp::Le) => Cmp::Gt,
        (false, Cmp::Gt) => Cmp::Le,
        (false, _) => Cmp::Lt,
    };
    let v = &mut read.value;
    match op {
        Cmp::Lt | Cmp::Le => v.hi = v.hi.min(k),
        _ => v.lo = v.lo.max(k),
    }
    // Rounding apart, an empty reading means no run takes this choice.
    if v.lo > v.hi + 1e-6 {
        return None;
    }
    v.hi = v.hi.max(v.lo);
    remember(cx, c)
}
