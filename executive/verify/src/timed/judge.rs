//! The requirements evaluated on a state, three-valued over its bounds.

use super::*;

/// Updates what each `eventually` requirement has seen on this path.
pub(super) fn observe(cx: &Ctx, reqs: &[&Requirement], c: &mut Node) {
    for (k, r) in reqs.iter().enumerate() {
        if let Form::Eventually(e) = &r.form
            && c.reached[k] != Tri::Yes
        {
            c.reached[k] = c.reached[k].max(eval(cx, c, e, 0.0, &r.atoms));
        }
    }
}

/// A quantity of vehicle `v` over the state's life: from now until `lasting` ms later.
pub(super) fn quantity(cx: &Ctx, n: &Node, q: Quantity, v: usize, lasting: f64) -> Span {
    let cap = cx.capacity(v);
    let used = n.used(v);
    let energy = Span {
        lo: used.lo,
        hi: (used.hi + cx.rate(n, v).hi * lasting / HOUR_MS).min(cap),
    };
    match q {
        Quantity::Time => Span {
            lo: n.t().lo,
            hi: n.t().hi + lasting,
        },
        Quantity::Energy => energy,
        Quantity::EnergyLeftWh => reading(cap, energy, Reading::EnergyWh),
        Quantity::EnergyLeftPct => reading(cap, energy, Reading::SocPct),
    }
}

/// Three-valued: whether `e` holds in `n` (over the `lasting` ms it may last).
pub(super) fn eval(cx: &Ctx, n: &Node, e: &Expr, lasting: f64, atoms: &[Atom]) -> Tri {
    match e {
        Expr::Not(x) => eval(cx, n, x, lasting, atoms).not(),
        Expr::And(a, b) => eval(cx, n, a, lasting, atoms).min(eval(cx, n, b, lasting, atoms)),
        Expr::Or(a, b) => eval(cx, n, a, lasting, atoms).max(eval(cx, n, b, lasting, atoms)),
        Expr::Word(w) => {
            let mut outcomes = n.state.instances.values().map(|i| &i.outcome);
            Tri::of(match w.as_str() {
                "ended" => n.dead || n.over(cx),
                "failed" => outcomes.any(|o| matches!(o, Some(EngineOutcome::Failed { .. }))),
                _ => outcomes.any(|o| matches!(o, Some(EngineOutcome::Terminated))),
            })
        }
        Expr::Quantity(q, op, x, pool) => {
            let vehicle = pool
                .as_deref()
                .and_then(|p| {
                    cx.costs
                        .vehicles
                        .iter()
                        .position(|v| v.pool.as_deref() == Some(p))
                })
                .unwrap_or(0);
            // Sums of floating-point draws: equal to a millionth is equal.
            let v = quantity(cx, n, *q, vehicle, lasting);
            let fine = |y: f64| (y * 1e6).round() / 1e6;
            let v = Span {
                lo: fine(v.lo),
                hi: fine(v.hi),
            };
            let inside = v.lo <= *x && *x <= v.hi;
            match op {
                Cmp::Eq if v.lo == v.hi => Tri::of(v.lo == *x),
                Cmp::Eq => Tri::of(false).max(if inside { Tri::Maybe } else { Tri::No }),
                Cmp::Ne if v.lo == v.hi => Tri::of(v.lo != *x),
                Cmp::Ne => {
                    if inside {
                        Tri::Maybe
                    } else {
                        Tri::Yes
                    }
                }
                _ => match (op.holds(v.lo, *x), op.holds(v.hi, *x)) {
                    (true, true) => Tri::Yes,
                    (false, false) => Tri::No,
                    _ => Tri::Maybe,
                },
            }
        }
        Expr::Atom(_) | Expr::Count(..) => Tri::of(atom(n, e, atoms)),
    }
}

pub(super) fn atom(n: &Node, e: &Expr, atoms: &[Atom]) -> bool {
    match e {
        Expr::Atom(k) => match atoms.get(*k) {
            Some(Atom::Done(x)) => n.done.contains(x),
            Some(Atom::Running(x)) => n.state.tokens.values().any(|t| {
                t.node == *x
                    && matches!(
                        t.at,
                        At::Task(_) | At::UserTask(_) | At::Scope(_) | At::Looping(_)
                    )
            }),
            Some(Atom::Signal(s)) => n.signals.contains(s),
            Some(Atom::Error(c)) => n.errors.contains(c),
            _ => false,
        },
        Expr::Count(k, op, m) => match atoms.get(*k) {
            Some(Atom::Count(x, _)) => {
                op.holds(f64::from(n.counts.get(x).copied().unwrap_or(0)), *m as f64)
            }
            _ => false,
        },
        _ => false,
    }
}
