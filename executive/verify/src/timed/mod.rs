//! Timed exploration: the requirements that read time or energy, checked over every run of the
//! executive's own engine with each task's duration and power bounded by the catalogues
//! ([`crate::resources`]).
//!
//! **Method.** The engine runs in token-game mode as in [`crate::explore`], and every state
//! carries a clock zone — a difference-bound matrix over mission time, each running task, each
//! armed timer and the age of each battery reading (`crate::zone`) — and bounds on the energy
//! used. A step can come next only while nothing pending has passed its latest moment: a task
//! ends between its least and greatest duration (for the outcome it has), a timer fires exactly
//! when due, a ground answer or a message comes any time, the battery runs out between the
//! earliest and latest moment the draws allow. So a timer fires when its time has come, not
//! whenever, and a mission ends when its battery is empty (it is never recharged). Energy grows
//! with the idle draw and each running task's power envelope; when a task ends, its outcome's own
//! power counts. A condition comparing a battery reading with a number (`battery_soc_pct < 30.0`)
//! is decided from the reading's bounds when both ends agree, and narrows the reading when the
//! run takes a branch — which, through the reading's age, bounds the energy used from then on; a
//! condition over script data the engine holds is evaluated; every other condition is a free
//! choice. A free choice that continues a cycle (a branch or a caught failure leading back) is
//! bounded per scope activation as in the Spin translation (`--loops`); cycles driven by time (a
//! monitor polling every hour) run until time or energy ends them.
//!
//! States with the same engine shape and the same observations are joined (the smallest zone
//! and bounds holding both) and explored again, mission time beyond the largest a requirement
//! names is extrapolated (exact for the requirements, as in timed automata), and energy that
//! keeps growing in a cycle climbs a ladder of twentieths of the capacity: the search is finite
//! and small (Europa: a few hundred states). The bounds are sound — every real run within the
//! declared costs lies inside the bounds of the states it passes — so a requirement **holds**
//! when no state can violate it. A state that may violate it is not enough for **VIOLATED**:
//! the way to it is replayed as one run, each step at one moment and every activity at its
//! greatest (then least) power and duration, guided by the way's choices, and only a run that
//! violates the requirement is reported, as the counterexample, with the time and energy of each
//! step. Otherwise the verdict is **incomplete** and says why.
//!
//! Why this and not the alternatives: Spin with bounded counters would put minutes of mission
//! time over weeks into PROMELA's state vector, multiplying the states by the times; a priced
//! timed automaton checker (UPPAAL CORA, PRISM's priced models) would need a translation to keep
//! in step with the engine, the same drift the differential test watches for in Spin's. Here the
//! engine's own semantics (boundaries, sub-processes, signals, terminate) are explored with no
//! translation, and the zone keeps timers exact where intervals per clock would not (a timer
//! armed when a reading was taken fires exactly one period after it). The price is that joined
//! states relate energy to time only through the readings, so a property that needs that
//! relation elsewhere can stay incomplete.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;

use connector_api::cost::Reading;
use executive_engine::{
    Action, At, Engine, Entry, Event, Input, On, Outcome as EngineOutcome, ScopeId, State, TaskKey,
    TimerKey, Trigger, Value, Vars,
};
use executive_model::{GatewayKind, NodeId, NodeKind, ProcessGraph};
use serde::Serialize;

use crate::requirements::{Atom, Cmp, Expr, Form, Quantity, Requirement};
use crate::resources::{Costs, TaskCost};
use crate::spin::{Outcome, TraceStep, Verdict};
use crate::zone::Zone;

mod follow;
mod judge;
mod state;
mod step;
mod witness;

pub use follow::{Bound, Observed, follow};
use judge::*;
use state::*;
use step::*;
use witness::*;

const HOUR_MS: f64 = 3_600_000.0;

/// A closed interval (`hi` may be infinite).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Span {
    /// The least.
    pub lo: f64,
    /// The greatest.
    pub hi: f64,
}

impl Span {
    fn point(x: f64) -> Span {
        Span { lo: x, hi: x }
    }
    fn contains(&self, o: &Span) -> bool {
        self.lo <= o.lo && o.hi <= self.hi
    }
    fn plus(self, o: Span) -> Span {
        Span {
            lo: self.lo + o.lo,
            hi: self.hi + o.hi,
        }
    }
    fn times(self, rate: Span) -> Span {
        Span {
            lo: self.lo * rate.lo,
            hi: if self.hi == 0.0 || rate.hi == 0.0 {
                0.0
            } else {
                self.hi * rate.hi
            },
        }
    }
    fn hull(self, o: Span) -> Span {
        Span {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
}

/// Time and energy at one step of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Resources {
    /// Mission time since the start, ms.
    pub time_ms: Span,
    /// Energy used since the start, idle draw included, Wh (every vehicle's).
    pub energy_wh: Span,
    /// Energy of the activity that ended at this step, Wh.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub activity_wh: Option<Span>,
    /// Each vehicle's energy used, Wh, by pool (a mission costed per pool).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub vehicles: BTreeMap<String, Span>,
}

impl Resources {
    /// What a state shows.
    fn of(cx: &Ctx, n: &Node) -> Resources {
        Resources {
            time_ms: n.t(),
            energy_wh: n.total(),
            activity_wh: None,
            vehicles: n.by_vehicle(cx),
        }
    }

    /// The smallest bounds holding both.
    fn hull(self, o: &Resources) -> Resources {
        let mut vehicles = self.vehicles;
        for (k, s) in &o.vehicles {
            vehicles
                .entry(k.clone())
                .and_modify(|x| *x = x.hull(*s))
                .or_insert(*s);
        }
        Resources {
            time_ms: self.time_ms.hull(o.time_ms),
            energy_wh: self.energy_wh.hull(o.energy_wh),
            activity_wh: None,
            vehicles,
        }
    }
}

/// What the timed exploration found.
#[derive(Clone, Debug, Serialize)]
pub struct Timed {
    /// Each timed requirement's verdict.
    pub properties: Vec<Outcome>,
    /// States explored.
    pub states: usize,
    /// When runs end (mission time, ms) and the energy they have used by then, over all runs.
    pub end: Option<Resources>,
}

/// How far the exploration may go.
#[derive(Clone, Copy, Debug)]
pub struct TimedLimits {
    /// How often a free choice that continues a cycle may repeat per scope activation.
    pub loops: u8,
    /// States explored at most (then the verdicts not yet certain are `incomplete`).
    pub max_states: usize,
}

impl Default for TimedLimits {
    fn default() -> Self {
        TimedLimits {
            loops: 1,
            max_states: 400_000,
        }
    }
}

/// Checks the timed requirements of `reqs` (those whose [`Form::timed`]) on `g`.
pub fn check(
    g: Arc<ProcessGraph>,
    costs: &Costs,
    reqs: &[Requirement],
    limits: TimedLimits,
) -> Timed {
    let started = std::time::Instant::now();
    let reqs: Vec<&Requirement> = reqs.iter().filter(|r| r.form.timed()).collect();
    let mut cx = context(&g, costs, &reqs, limits);
    let mut out = Timed {
        properties: Vec::new(),
        states: 0,
        end: None,
    };
    let root = match start(&cx, &reqs) {
        Ok(root) => root,
        Err(why) => {
            for r in &reqs {
                out.properties.push(outcome(
                    r,
                    Verdict::Incomplete(format!("the mission does not start: {why}")),
                    0,
                    started,
                    Vec::new(),
                ));
            }
            return out;
        }
    };
    // Per requirement: states that may violate it, with the energy used there.
    let mut suspects: Vec<Vec<(usize, f64)>> = vec![Vec::new(); reqs.len()];
    let mut complete = true;
    let mut nodes = vec![root];
    let mut joins = vec![0u32];
    let mut seen: HashMap<String, Vec<usize>> = HashMap::new();
    let mut stack = vec![0usize];
    while let Some(at) = stack.pop() {
        let n = nodes[at].clone();
        let next = if n.dead {
            Vec::new()
        } else {
            successors(&cx, &n)
        };
        // How long this state can last: until something pending must have happened.
        let lasting = if next.is_empty() {
            0.0
        } else {
            elapse(&cx, &n, &When::Any).map_or(0.0, |(z, w)| z.bounds(w).1)
        };
        for (k, r) in reqs.iter().enumerate() {
            if let Form::Always(expr) = &r.form
                && eval(&cx, &n, expr, lasting, &r.atoms) != Tri::Yes
            {
                suspects[k].push((at, n.total().hi));
            }
        }
        let running = !n.over(&cx);
        if next.is_empty() || !running {
            // A run ends here: the mission is over, stuck, or the batteries are empty.
            let res = Resources::of(&cx, &n);
            out.end = Some(match out.end.take() {
                None => res,
                Some(o) => o.hull(&res),
            });
            for (k, r) in reqs.iter().enumerate() {
                if matches!(r.form, Form::Eventually(_)) && n.reached[k] != Tri::Yes {
                    suspects[k].push((at, n.total().hi));
                }
            }
            continue;
        }
        for x in next {
            let Some((z, wait)) = elapse(&cx, &n, &x.when) else {
                continue;
            };
            let Some(mut c) = take(&cx, &n, &x, z, wait) else {
                continue;
            };
            c.via = Some(Via {
                from: at,
                label: x.label,
                spent: c.via.and_then(|v| v.spent),
            });
            observe(&cx, &reqs, &mut c);
            let key = key(&cx, &c);
            let list = seen.entry(key).or_default();
            // One state per key and layout: a state that covers this one ends the path; one
            // that does not is joined with it (the smallest zone and intervals holding both)
            // and explored again.
            if let Some(&o) = list.iter().find(|&&o| layout(&nodes[o]) == layout(&c)) {
                if covers(&nodes[o], &c) {
                    continue;
                }
                let mut joined = nodes[o].clone();
                join(&mut joined, &c);
                // The state remembers the way to its worst contributor (the most energy), the
                // run a counterexample replays — unless that way passes through itself.
                if c.total().hi > nodes[o].total().hi
                    && let Some(v) = &c.via
                    && !descends(&nodes, v.from, o)
                {
                    joined.via = c.via.clone();
                }
                joins[o] += 1;
                for v in 0..joined.energy.len() {
                    let e = &mut joined.energy[v];
                    if joins[o] > WIDEN && e.hi > nodes[o].energy[v].hi {
                        // Energy that keeps growing climbs a ladder of twentieths of the
                        // capacity (a cycle that spends energy converges in at most twenty
                        // rounds); what the readings say narrows it again.
                        let cap = cx.capacity(v);
                        let step = cap / 20.0;
                        e.hi = (((e.hi / step).floor() + 1.0) * step).min(cap);
                    }
                }
                let _ = remember(&cx, &mut joined);
                nodes[o] = joined;
                stack.push(o);
                continue;
            }
            if nodes.len() >= limits.max_states {
                complete = false;
                break;
            }
            list.push(nodes.len());
            nodes.push(c);
            joins.push(0);
            stack.push(nodes.len() - 1);
        }
        if !complete {
            break;
        }
    }
    out.states = nodes.len();
    for (k, r) in reqs.iter().enumerate() {
        // The worst suspects first; each path replayed as one run with every activity at its
        // greatest power and as late as it can be, then at its least and as early.
        let mut list = std::mem::take(&mut suspects[k]);
        list.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut once = BTreeSet::new();
        list.retain(|s| once.insert(s.0));
        for (at, _) in list.iter().take(3) {
            let n = &nodes[*at];
            let l = labels(&nodes, *at);
            tracing::debug!(
                requirement = %r.name,
                state = at,
                time_h = ?(n.t().lo / HOUR_MS, n.t().hi / HOUR_MS),
                energy_wh = ?(n.total().lo, n.total().hi),
                dead = n.dead,
                last = ?&l[l.len().saturating_sub(8)..],
                "may violate"
            );
        }
        let mut witness = None;
        'found: for (at, _) in list.iter().take(WITNESS_TRIES) {
            let labels = labels(&nodes, *at);
            for late in [true, false] {
                cx.pick = Some(late);
                if let Some(steps) = replay(&cx, r, k, &reqs, &labels, late) {
                    witness = Some(steps);
                    break 'found;
                }
            }
        }
        cx.pick = None;
        let (verdict, steps) = match witness {
            Some(steps) => (Verdict::Violated, steps),
            None if !complete => (
                Verdict::Incomplete(format!(
                    "{} states explored, the bound (raise --max-states or lower --loops)",
                    nodes.len()
                )),
                Vec::new(),
            ),
            None if !list.is_empty() => (
                Verdict::Incomplete(format!(
                    "the time and energy bounds allow a violation on {} states, but no single \
                     run replayed shows one",
                    list.len()
                )),
                Vec::new(),
            ),
            None => (Verdict::Holds, Vec::new()),
        };
        out.properties
            .push(outcome(r, verdict, nodes.len(), started, steps));
    }
    out
}

/// What the requirements `reqs` read of batteries the costs do not have, one line each: a
/// vehicle's (`energy_left of "Scout"`) when the mission is costed with one battery, and the
/// mission's (no `of`) when it is costed per vehicle.
pub fn vehicles(reqs: &[Requirement], costs: &Costs) -> Vec<String> {
    fn walk<'e>(e: &'e Expr, out: &mut Vec<(Quantity, &'e Option<String>)>) {
        match e {
            Expr::Quantity(q, _, _, pool) => out.push((*q, pool)),
            Expr::Not(x) => walk(x, out),
            Expr::And(a, b) | Expr::Or(a, b) => {
                walk(a, out);
                walk(b, out);
            }
            _ => {}
        }
    }
    fn form<'e>(f: &'e Form, out: &mut Vec<(Quantity, &'e Option<String>)>) {
        match f {
            Form::Eventually(e) | Form::Always(e) => walk(e, out),
            Form::After(a, f) => {
                walk(a, out);
                form(f, out);
            }
            Form::When(e, c) => {
                walk(e, out);
                if let Some(c) = c {
                    walk(c, out);
                }
            }
        }
    }
    let pools: Vec<String> = costs
        .vehicles
        .iter()
        .filter_map(|v| v.pool.as_ref().map(|p| format!("\"{p}\"")))
        .collect();
    let mut out = Vec::new();
    for r in reqs {
        let mut read = Vec::new();
        form(&r.form, &mut read);
        for (q, pool) in read {
            if q == Quantity::Time {
                continue;
            }
            let known = costs.vehicles.iter().any(|v| v.pool == *pool);
            match pool {
                _ if known => {}
                Some(p) => out.push(format!(
                    "requirement `{}` reads the battery of pool `{p}`, but the mission is costed \
                     with one battery for every pool: give each pool its connectors \
                     (--connectors {p}=FILE)",
                    r.name
                )),
                None => out.push(format!(
                    "requirement `{}` reads energy without naming a vehicle, and each pool has its \
                     own battery: say whose (`energy_left of {}`)",
                    r.name,
                    pools.first().map_or("\"POOL\"", String::as_str)
                )),
            }
        }
    }
    out.dedup();
    out
}

/// Joins of one state after which its energy is widened.
const WIDEN: u32 = 3;

/// Suspect paths replayed as single runs, worst first, before a verdict is `incomplete`.
const WITNESS_TRIES: usize = 8;

/// Steps a replayed run may take (weeks of a monitor polling hourly).
const RUN_STEPS: usize = 30_000;

fn context<'a>(
    g: &'a Arc<ProcessGraph>,
    costs: &'a Costs,
    reqs: &[&Requirement],
    limits: TimedLimits,
) -> Ctx<'a> {
    let atoms = || reqs.iter().flat_map(|r| &r.atoms);
    Ctx {
        g,
        costs,
        vehicle: (0..g.nodes.len() as u32)
            .map(|i| costs.vehicle_of(g, NodeId(i)))
            .collect(),
        hold: (0..g.nodes.len() as u32)
            .map(NodeId)
            .filter(|n| crate::promela::outside(g, *n))
            .collect(),
        codes: crate::explore::codes(g),
        starts: crate::explore::outside_starts(g),
        limits,
        counted: atoms()
            .filter_map(|a| match a {
                Atom::Count(n, bound) => Some((*n, *bound)),
                _ => None,
            })
            .collect(),
        watched: atoms()
            .filter_map(|a| match a {
                Atom::Done(n) => Some(*n),
                _ => None,
            })
            .collect(),
        signals: atoms()
            .filter_map(|a| match a {
                Atom::Signal(s) => Some(s.clone()),
                _ => None,
            })
            .collect(),
        errors: atoms()
            .filter_map(|a| match a {
                Atom::Error(c) => Some(c.clone()),
                _ => None,
            })
            .collect(),
        pick: None,
        horizon: reqs
            .iter()
            .flat_map(|r| quantities(&r.form))
            .filter(|(q, _)| *q == Quantity::Time)
            .map(|(_, x)| x + 1.0)
            .fold(0.0, f64::max),
        data: false,
    }
}

/// The quantities a statement compares, with the amounts.
fn quantities(f: &Form) -> Vec<(Quantity, f64)> {
    fn walk(e: &Expr, out: &mut Vec<(Quantity, f64)>) {
        match e {
            Expr::Quantity(q, _, x, _) => out.push((*q, *x)),
            Expr::Not(x) => walk(x, out),
            Expr::And(a, b) | Expr::Or(a, b) => {
                walk(a, out);
                walk(b, out);
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    match f {
        Form::Eventually(e) | Form::Always(e) => walk(e, &mut out),
        Form::After(a, f) => {
            walk(a, &mut out);
            out.extend(quantities(f));
        }
        Form::When(e, c) => {
            walk(e, &mut out);
            if let Some(c) = c {
                walk(c, &mut out);
            }
        }
    }
    out
}

/// The mission started: every primary process, at time zero with full batteries.
fn start(cx: &Ctx, reqs: &[&Requirement]) -> Result<Node, String> {
    let mut root = Node {
        state: State::default(),
        zone: Zone::new(),
        clocks: Vec::new(),
        energy: vec![Span::point(0.0); cx.costs.vehicles.len()],
        empty: BTreeSet::new(),
        running: BTreeMap::new(),
        timers: BTreeMap::new(),
        readings: BTreeMap::new(),
        loops: BTreeMap::new(),
        done: BTreeSet::new(),
        counts: BTreeMap::new(),
        signals: BTreeSet::new(),
        errors: BTreeSet::new(),
        reached: vec![Tri::No; reqs.len()],
        dead: false,
        via: None,
    };
    root.start_clock(Clock::Time);
    let mut e = cx.engine(State::default(), &BTreeSet::new());
    for p in cx.g.primary_processes() {
        let seq = e.state().last_seq + 1;
        let actions = e
            .step(Input {
                seq,
                at: 0,
                event: Event::InstanceStarted {
                    process: cx.g.process(p).id.clone(),
                    vars: Vars::new(),
                    start: None,
                },
            })
            .map_err(|r| r.to_string())?;
        note(cx, &mut root, &actions);
    }
    root.state = e.state().clone();
    settle(cx, &mut root);
    observe(cx, reqs, &mut root);
    Ok(root)
}

fn outcome(
    r: &Requirement,
    verdict: Verdict,
    states: usize,
    started: std::time::Instant,
    counterexample: Vec<TraceStep>,
) -> Outcome {
    Outcome {
        name: r.name.clone(),
        description: r.says.clone(),
        verdict,
        states: states as u64,
        transitions: 0,
        seconds: started.elapsed().as_secs_f64(),
        detail: Some("timed exploration of the engine with the catalogues' costs".into()),
        counterexample,
    }
}

#[cfg(test)]
mod tests;
