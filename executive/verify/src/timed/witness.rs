//! Counterexamples: the way to a suspect state replayed as one run at concrete times and
//! powers, kept only if that run violates the requirement.

use super::*;

/// The labels of the steps to a state.
pub(super) fn labels(nodes: &[Node], mut at: usize) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(v) = &nodes[at].via {
        out.push(v.label.clone());
        at = v.from;
    }
    out.reverse();
    out
}

/// One step of a run as a counterexample shows it.
pub(super) fn step(cx: &Ctx, n: &Node, label: &str, node: Option<NodeId>) -> TraceStep {
    let step = node.map(|node| {
        let el = cx.g.node(node);
        let phase = label.rsplit('.').next().unwrap_or("");
        crate::promela::Step {
            element: el.id.clone(),
            name: el.label().to_owned(),
            path: String::new(),
            phase: if phase.starts_with("fail[") {
                phase.to_owned()
            } else {
                phase.split('[').next().unwrap_or("").to_owned()
            },
            activity: el.is_activity(),
        }
    });
    TraceStep {
        marker: label.to_owned(),
        step,
        cycle_start: false,
        resources: Some(Resources {
            activity_wh: n.via.as_ref().and_then(|v| v.spent),
            ..Resources::of(cx, n)
        }),
    }
}

/// Replays the way to a suspect state as one run, to see whether a real run violates
/// requirement `k`: every activity at its greatest power and duration (`late`) or its least,
/// each step at one moment. The way's choices guide the run — its branches, failures, answers
/// and timers are taken as soon as they can come next — while what must happen meanwhile (a
/// timer due, a decision the data makes) happens when due. The run's steps, with the tasks'
/// starts, if it violates the requirement.
pub(super) fn replay(
    cx: &Ctx,
    r: &Requirement,
    k: usize,
    reqs: &[&Requirement],
    labels: &[String],
    late: bool,
) -> Option<Vec<TraceStep>> {
    let dbg = |why: &str| tracing::debug!(requirement = %r.name, late, "replay stops: {why}");
    let Ok(mut n) = start(cx, reqs) else {
        dbg("no start");
        return None;
    };
    let mut steps = Vec::new();
    let starts = |before: &Node, after: &Node, steps: &mut Vec<TraceStep>| {
        for (key, t) in &after.running {
            if !before.running.contains_key(key) {
                let id = &cx.g.node(t.node).id;
                steps.push(step(cx, after, &format!("{id}.start"), Some(t.node)));
            }
        }
    };
    let empty = Node {
        running: BTreeMap::new(),
        ..n.clone()
    };
    starts(&empty, &n, &mut steps);
    let violates = |n: &Node, lasting: f64| match &r.form {
        Form::Always(e) => eval(cx, n, e, lasting, &r.atoms) == Tri::No,
        _ => false,
    };
    let mut guide = 0;
    for _ in 0..RUN_STEPS {
        let next = successors(cx, &n);
        let running = !n.over(cx);
        if next.is_empty() || !running || n.dead {
            break;
        }
        // Each step possible now, with when it comes in this run.
        let mut options: Vec<(Next, Zone, usize, f64)> = Vec::new();
        for x in next {
            if let Some((z, wait)) = elapse(cx, &n, &x.when) {
                let (lo, hi) = z.bounds(wait);
                let d = if late && hi.is_finite() { hi } else { lo };
                options.push((x, z, wait, d));
            }
        }
        // The guide's next choice that can come now (looking a little ahead), else what is
        // due first.
        let ahead = labels.len().min(guide + 40);
        let wanted = (guide..ahead).find_map(|i| {
            options
                .iter()
                .position(|o| o.0.label == labels[i])
                .map(|p| (i, p))
        });
        let pick = match wanted {
            Some((i, p)) => {
                guide = i + 1;
                p
            }
            None => {
                // What comes first; of those, a completion before a failure and a named branch
                // before the default one (the run does what the mission is for).
                // Played late, the ground never answers and no message comes unless the way
                // says so (their timeouts fire instead), as long as something else can happen.
                let waits = |o: &(Next, Zone, usize, f64)| {
                    late && (matches!(o.0.when, When::Any)
                        || matches!(&o.0.when, When::After(Clock::Task(_, k), _)
                            if n.running.get(k).is_some_and(|r| r.cost.duration_ms.1.is_infinite())))
                };
                if options.iter().any(|o| !waits(o)) {
                    options.retain(|o| !waits(o));
                }
                let soonest = options.iter().map(|o| o.3).fold(f64::INFINITY, f64::min);
                let rank = |x: &Next| match &x.event {
                    Some(Event::TaskFailed { .. }) => 2,
                    Some(Event::BranchTaken { token, flows }) => {
                        n.state.tokens.get(token).map_or(0, |t| {
                            u8::from(
                                flows
                                    .iter()
                                    .any(|f| cx.g.node(t.node).default_flow == Some(*f)),
                            )
                        })
                    }
                    _ => 0,
                };
                options
                    .iter()
                    .enumerate()
                    .filter(|(_, o)| o.3 <= soonest)
                    .min_by_key(|(_, o)| rank(&o.0))
                    .map(|(i, _)| i)?
            }
        };
        let (x, mut z, wait, d) = options.swap_remove(pick);
        // Not later than anything else must come.
        let d = options
            .iter()
            .map(|o| o.1.bounds(o.2).1)
            .fold(d, f64::min)
            .max(z.bounds(wait).0);
        z.at_most(wait, d);
        z.at_least(wait, d);
        if !z.close() {
            dbg(&format!("{} at {d} is not possible", x.label));
            return None;
        }
        if violates(&n, d) {
            return Some(steps);
        }
        let Some(mut c) = take(cx, &n, &x, z, wait) else {
            dbg(&format!(
                "{} cannot be taken after {} steps",
                x.label,
                steps.len()
            ));
            return None;
        };
        observe(cx, reqs, &mut c);
        c.via = Some(Via {
            from: 0,
            label: x.label.clone(),
            spent: c.via.and_then(|v| v.spent),
        });
        steps.push(step(cx, &c, &x.label, x.node));
        starts(&n, &c, &mut steps);
        n = c;
        if violates(&n, 0.0) {
            return Some(steps);
        }
    }
    let ended = n.dead || n.over(cx) || successors(cx, &n).is_empty();
    tracing::debug!(
        requirement = %r.name,
        late,
        steps = steps.len(),
        guided = guide,
        ended,
        energy_wh = n.total().hi,
        "replayed"
    );
    let violated = match &r.form {
        Form::Eventually(_) => ended && n.reached[k] == Tri::No,
        _ => false,
    };
    violated.then_some(steps)
}
