//! Timed exploration: the requirements that read time or energy, checked over every run of the
//! executive's own engine with each task's duration and power bounded by the catalogues
//! ([`crate::resources`]).
//!
//! **Method.** The engine runs in token-game mode as in [`crate::explore`], and every state
//! carries intervals: the mission time of its last event, the energy the finished activities
//! used, and for everything pending the window in which it can happen — a task between its
//! start plus its least and its start plus its greatest duration, a timer at its deadline (which
//! inherits the uncertainty of when it was armed), a ground answer or a message at any time, the
//! battery running out between the earliest and the latest moment the draws allow. An event can
//! come next only if it can happen before everything else pending must have happened; taking it
//! narrows the time to that overlap. So a timer fires when its time has come given the elapsed
//! time, not whenever, and a mission ends when its battery is empty (the battery is never
//! recharged). A condition that compares a battery reading with a number (`battery_soc_pct <
//! 30.0`) is decided from the reading's bounds when both ends agree, a condition over script
//! data the engine holds is evaluated, and every other condition is a free choice; a free choice
//! that continues a cycle (a branch or a caught failure leading back) is bounded per scope
//! activation, as in the Spin translation (`--loops`), while cycles driven by time (a monitor
//! polling every hour) run until time or energy ends them.
//!
//! This is an interval abstraction of a priced timed automaton (the model UPPAAL CORA checks)
//! explored path by path: intervals are kept per path, never widened, and states whose
//! intervals lie inside those of an equal state already seen are dropped. It was chosen over
//! Spin with bounded counters (time in minutes over weeks of mission makes PROMELA's state
//! vectors and search depth explode) and over zones (difference-bound matrices relate clocks
//! exactly, but energy is a cost over them, which zones alone do not bound): it reuses the
//! engine's real semantics (boundaries, sub-processes, signals) with no translation, its bounds
//! are sound (every real run lies inside the intervals of the path it takes), and the price is
//! the usual direction of an over-approximation — a counterexample's order of events may need
//! times the intervals allow one by one but not together. A verdict is `holds` only when no
//! state can violate the requirement; `VIOLATED` when a path certainly violates it (the worst
//! such run by energy is the counterexample); otherwise, or when the state bound is hit,
//! `incomplete`.

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
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Resources {
    /// Mission time since the start, ms.
    pub time_ms: Span,
    /// Energy used since the start, idle draw included, Wh.
    pub energy_wh: Span,
    /// Energy of the activity that ended at this step, Wh.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub activity_wh: Option<Span>,
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

/// A task in flight (its clock counts how long it has run): what it has spent and costs.
#[derive(Clone, Debug)]
struct Running {
    node: NodeId,
    spent: Span,
    cost: TaskCost,
}

/// An armed timer (its clock counts since it was armed): its element and duration, ms.
#[derive(Clone, Copy, Debug)]
struct Timer {
    node: NodeId,
    dur: f64,
}

/// What a clock of a state's zone measures.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Clock {
    /// Mission time.
    Time,
    /// How long a task has run.
    Task(NodeId, TaskKey),
    /// How long ago a timer was armed.
    Timer(NodeId, TimerKey),
    /// How long ago a battery reading was taken (by variable).
    Read(String),
}

impl Clock {
    /// What states of one key must agree on to be compared (not the engine's ids).
    fn layout(&self) -> (u8, u32, &str) {
        match self {
            Clock::Time => (0, 0, ""),
            Clock::Task(n, _) => (1, n.0, ""),
            Clock::Timer(n, _) => (2, n.0, ""),
            Clock::Read(v) => (3, 0, v),
        }
    }
}

/// A battery reading a variable holds: its bounds, what it reads and the greatest draw since
/// it was taken (its clock counts how long ago). It keeps the energy used tied to what was
/// read — used now is used then plus at least the idle draw and at most the greatest draw
/// since — which a decision on the reading narrows and a join of states does not undo.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Read {
    value: Span,
    kind: Reading,
    peak: f64,
}

impl Read {
    /// The energy used when it was read, Wh.
    fn used(&self, cap: f64) -> Span {
        match self.kind {
            Reading::SocPct => Span {
                lo: cap * (1.0 - self.value.hi / 100.0),
                hi: cap * (1.0 - self.value.lo / 100.0),
            },
            Reading::EnergyWh => Span {
                lo: cap - self.value.hi,
                hi: cap - self.value.lo,
            },
        }
    }
}

/// Narrows the energy used by what each reading says it was then. `None`: nothing is left.
fn remember(cx: &Ctx, c: &mut Node) -> Option<()> {
    let idle = cx.costs.battery.idle_w;
    let running = c
        .running
        .values()
        .fold(Span::point(0.0), |s, r| s.plus(r.spent));
    for (var, r) in &c.readings {
        let (lo, hi) = c.zone.bounds(c.clock(&Clock::Read(var.clone())));
        let then = r.used(cx.capacity());
        // Used now lies in these bounds; what the running activities drew is apart.
        c.energy.lo = c.energy.lo.max(then.lo + idle * lo / HOUR_MS - running.hi);
        c.energy.hi = c
            .energy
            .hi
            .min(then.hi + r.peak * hi / HOUR_MS - running.lo);
    }
    if c.energy.lo > c.energy.hi + 1e-6 {
        return None;
    }
    c.energy.hi = c.energy.hi.max(c.energy.lo);
    Some(())
}

/// Three-valued truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Tri {
    No,
    Maybe,
    Yes,
}

impl Tri {
    fn of(b: bool) -> Tri {
        if b { Tri::Yes } else { Tri::No }
    }
    fn not(self) -> Tri {
        match self {
            Tri::No => Tri::Yes,
            Tri::Maybe => Tri::Maybe,
            Tri::Yes => Tri::No,
        }
    }
}

/// How a state was reached: the state before, the step's label, and the energy
/// of the activity that ended.
#[derive(Clone, Debug)]
struct Via {
    from: usize,
    label: String,
    spent: Option<Span>,
}

/// One state of the search.
#[derive(Clone)]
struct Node {
    state: State,
    /// The clocks' zone, clock `i + 1` measuring `clocks[i]` (kept in [`Clock`] order).
    zone: Zone,
    clocks: Vec<Clock>,
    /// Energy used so far by the idle draw and the activities that ended, Wh (the running
    /// ones' is theirs until they end: see [`Node::total`]).
    energy: Span,
    running: BTreeMap<TaskKey, Running>,
    timers: BTreeMap<TimerKey, Timer>,
    readings: BTreeMap<String, Read>,
    /// Free cycle-continuing choices taken, by (scope activation, deciding element).
    loops: BTreeMap<(ScopeId, NodeId), u8>,
    done: BTreeSet<NodeId>,
    counts: BTreeMap<NodeId, u8>,
    signals: BTreeSet<String>,
    errors: BTreeSet<String>,
    /// Per `eventually` requirement: reached on this path.
    reached: Vec<Tri>,
    dead: bool,
    via: Option<Via>,
}

impl Node {
    /// The zone index of a clock (0, the zero clock, if it has none).
    fn clock(&self, c: &Clock) -> usize {
        self.clocks.iter().position(|x| x == c).map_or(0, |i| i + 1)
    }

    /// Energy used so far, Wh: the idle draw, the activities that ended and what the running
    /// ones have drawn.
    fn total(&self) -> Span {
        self.running
            .values()
            .fold(self.energy, |e, r| e.plus(r.spent))
    }

    /// Mission time now, ms.
    fn t(&self) -> Span {
        let (lo, hi) = self.zone.bounds(1);
        Span { lo, hi }
    }

    /// Adds a clock reading 0 now.
    fn start_clock(&mut self, c: Clock) {
        self.clocks.push(c);
        self.zone.add();
    }

    /// Drops a clock.
    fn stop_clock(&mut self, c: &Clock) {
        let k = self.clock(c);
        if k > 0 {
            self.clocks.remove(k - 1);
            self.zone.remove(k);
        }
    }

    /// Puts the clocks in [`Clock`] order, so that states of one key line up.
    fn sort_clocks(&mut self) {
        let mut order: Vec<usize> = (0..self.clocks.len()).collect();
        order.sort_by(|a, b| self.clocks[*a].cmp(&self.clocks[*b]));
        let mut zone_order = vec![0];
        zone_order.extend(order.iter().map(|i| i + 1));
        self.zone.reorder(&zone_order);
        self.clocks = order.iter().map(|i| self.clocks[*i].clone()).collect();
    }
}

struct Ctx<'a> {
    g: &'a Arc<ProcessGraph>,
    costs: &'a Costs,
    hold: BTreeSet<NodeId>,
    codes: Vec<String>,
    limits: TimedLimits,
    /// Elements the requirements count, with the count they saturate at.
    counted: BTreeMap<NodeId, u8>,
    /// Elements, signals and error codes the requirements read (the rest is not kept: it
    /// would tell apart states no requirement can).
    watched: BTreeSet<NodeId>,
    signals: BTreeSet<String>,
    errors: BTreeSet<String>,
    /// Replaying one run: every activity at its greatest (`true`) or least power.
    pick: Option<bool>,
    /// Beyond this mission time (the greatest a requirement names), times are all alike.
    horizon: f64,
    /// Following one observed run: its results carry their data and the engine decides.
    data: bool,
}

/// What can happen next: its label, the input (`None`: the battery runs out), when, and its
/// element.
struct Next {
    label: String,
    event: Option<Event>,
    when: When,
    node: Option<NodeId>,
}

/// When a step can come.
#[derive(Clone, Debug)]
enum When {
    /// At once (a decision).
    Now,
    /// Once the clock has reached the least (a task's least duration, a timer's).
    After(Clock, f64),
    /// Any time (an answer, a message).
    Any,
    /// The battery runs out: this long from now at the least.
    Dies(f64),
}

impl Ctx<'_> {
    fn engine(&self, state: State) -> Engine {
        let mut e = Engine::restore(Arc::clone(self.g), state);
        // Following a run with its data is running the engine as the executive does.
        if !self.data {
            let game = e.game();
            game.decide = true;
            game.hold = self.hold.clone();
        }
        e
    }

    fn capacity(&self) -> f64 {
        self.costs.battery.capacity_wh
    }

    fn power(&self, p: (f64, f64)) -> Span {
        match self.pick {
            Some(true) => Span::point(p.1),
            Some(false) => Span::point(p.0),
            None => Span { lo: p.0, hi: p.1 },
        }
    }

    /// The draw now, W: idle plus every running activity's.
    fn rate(&self, n: &Node) -> Span {
        n.running
            .values()
            .fold(Span::point(self.costs.battery.idle_w), |r, t| {
                r.plus(self.power(t.cost.power_envelope()))
            })
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
        let running = n.state.instances.values().any(|i| i.outcome.is_none());
        if next.is_empty() || !running {
            // A run ends here: the mission is over, stuck, or the battery is empty.
            let res = Resources {
                time_ms: n.t(),
                energy_wh: n.total(),
                activity_wh: None,
            };
            out.end = Some(match out.end {
                None => res,
                Some(o) => Resources {
                    time_ms: o.time_ms.hull(res.time_ms),
                    energy_wh: o.energy_wh.hull(res.energy_wh),
                    activity_wh: None,
                },
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
                if c.energy.hi > nodes[o].energy.hi
                    && let Some(v) = &c.via
                    && !descends(&nodes, v.from, o)
                {
                    joined.via = c.via.clone();
                }
                joins[o] += 1;
                if joins[o] > WIDEN && joined.energy.hi > nodes[o].energy.hi {
                    // Energy that keeps growing climbs a ladder of twentieths of the capacity
                    // (a cycle that spends energy converges in at most twenty rounds); what
                    // the readings say narrows it again.
                    let step = cx.capacity() / 20.0;
                    joined.energy.hi =
                        (((joined.energy.hi / step).floor() + 1.0) * step).min(cx.capacity());
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
                energy_wh = ?(n.energy.lo, n.energy.hi),
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

/// Whether state `from`'s way back to the start passes through state `o`.
fn descends(nodes: &[Node], mut from: usize, o: usize) -> bool {
    for _ in 0..nodes.len() {
        if from == o {
            return true;
        }
        match &nodes[from].via {
            Some(v) => from = v.from,
            None => return false,
        }
    }
    true
}

/// One step of a run observed outside the verifier (a flight): its label as the exploration
/// names steps (`Task.complete`, `Task.fail[CODE]`, `Timer.fire`), when it happened (mission
/// time since the start, ms), the result it carried, and the energy used by then if a reading
/// says.
#[derive(Clone, Debug)]
pub struct Observed {
    /// The step.
    pub label: String,
    /// A task's result or a ground answer (the data the run's decisions read).
    pub output: Vars,
    /// When, ms since the start.
    pub at_ms: f64,
    /// Energy used by then, Wh, when the step reads the battery.
    pub energy_wh: Option<f64>,
}

/// What the verifier bounds for one observed step, given the run before it.
#[derive(Clone, Debug, Serialize)]
pub struct Bound {
    /// The step.
    pub label: String,
    /// When it could have come, ms since the start.
    pub window_ms: Span,
    /// When it came.
    pub at_ms: f64,
    /// Energy used by then, Wh (every activity so far anywhere within its declared power).
    pub energy_wh: Span,
    /// The most the activities still running have drawn so far, and those that ended at this
    /// same moment, Wh: a system that charges an activity's energy when it ends reads up to
    /// this much less.
    pub in_flight_wh: f64,
    /// The energy used by then as the run read it, if it did.
    pub measured_wh: Option<f64>,
}

/// Follows one observed run through the engine with the costs: for each step, the window in
/// which the verifier says it could come and the energy it says was used by then. The run's
/// data goes to the engine, which makes the run's decisions itself (so loops over data run as
/// often as they did). `Err` names the first step the model and costs do not allow (a step not
/// possible then, or not at that time): a disagreement between the costs and the system. A run
/// that goes on after its battery is certainly empty (a simulator that does not stop there) is
/// followed up to that point.
pub fn follow(g: Arc<ProcessGraph>, costs: &Costs, run: &[Observed]) -> Result<Vec<Bound>, String> {
    let limits = TimedLimits {
        loops: u8::MAX,
        max_states: 0,
    };
    let mut cx = context(&g, costs, &[], limits);
    // One run keeps its exact times, and its data.
    cx.horizon = f64::INFINITY;
    cx.data = true;
    let mut n = start(&cx, &[])?;
    let mut out = Vec::new();
    // What activities ending at the current moment spent (their order against a reading at the
    // same moment is the system's).
    let mut moment = (0.0, 0.0);
    for (i, o) in run.iter().enumerate() {
        let now = n.t().lo;
        let mut offered: Vec<Next> = successors(&cx, &n);
        // A code no boundary names is offered as the one a catch-all catches.
        let code = o
            .label
            .split_once(".fail[")
            .map(|(task, c)| (task.to_owned(), c.trim_end_matches(']').to_owned()));
        let found = offered.iter().position(|x| x.label == o.label).or_else(|| {
            let (task, _) = code.as_ref()?;
            let any = format!("{task}.fail[UNNAMED_FAILURE]");
            offered.iter().position(|x| x.label == any)
        });
        let Some(x) = found else {
            let names: Vec<&str> = offered.iter().map(|x| x.label.as_str()).collect();
            let tokens: Vec<String> = n
                .state
                .tokens
                .values()
                .map(|t| format!("{} {:?}", g.node(t.node).id, t.at))
                .collect();
            let incidents: Vec<&String> = n
                .state
                .instances
                .values()
                .flat_map(|i| i.incidents.iter().map(|(_, why)| why))
                .collect();
            return Err(format!(
                "step {} `{}` at {} ms is not possible then; possible: {names:?}; tokens at \
                 {tokens:?}; incidents {incidents:?}",
                i + 1,
                o.label,
                o.at_ms
            ));
        };
        let mut x = offered.swap_remove(x);
        if let (Some(Event::TaskFailed { code: c, .. }), Some((_, real))) = (&mut x.event, &code) {
            c.clone_from(real);
        }
        if let Some(Event::TaskCompleted { task, .. }) = x.event {
            // The result's data; a ground decision is an answer.
            let user = n
                .state
                .tokens
                .values()
                .any(|t| matches!(t.at, At::UserTask(k) if k == task));
            x.event = Some(if user {
                Event::UserTaskAnswered {
                    task,
                    answer: o.output.clone(),
                    operator: "follow".into(),
                }
            } else {
                Event::TaskCompleted {
                    task,
                    output: o.output.clone(),
                }
            });
        }
        let x = &x;
        let Some((mut z, wait)) = elapse(&cx, &n, &x.when) else {
            return Err(format!("step {} `{}` cannot come next", i + 1, o.label));
        };
        let (lo, hi) = z.bounds(wait);
        let window = Span {
            lo: now + lo,
            hi: now + hi,
        };
        let d = o.at_ms - now;
        if d > death(&cx, &n).hi + 1.0 {
            break;
        }
        // Mission time is kept in ms: a millisecond either way is rounding.
        if d < lo - 1.0 || d > hi + 1.0 {
            return Err(format!(
                "step {} `{}` came at {} ms, outside {:.0}..{:.0} ms",
                i + 1,
                o.label,
                o.at_ms,
                window.lo,
                window.hi
            ));
        }
        let d = d.clamp(lo, hi);
        z.at_most(wait, d);
        z.at_least(wait, d);
        if !z.close() {
            return Err(format!("step {} `{}`: no time fits", i + 1, o.label));
        }
        let c = take(&cx, &n, x, z, wait)
            .ok_or_else(|| format!("step {} `{}` cannot be taken then", i + 1, o.label))?;
        if o.at_ms != moment.0 {
            moment = (o.at_ms, 0.0);
        }
        moment.1 += c.via.as_ref().and_then(|v| v.spent).map_or(0.0, |s| s.hi);
        out.push(Bound {
            label: o.label.clone(),
            window_ms: window,
            at_ms: o.at_ms,
            energy_wh: c.total(),
            in_flight_wh: c.running.values().map(|r| r.spent.hi).sum::<f64>() + moment.1,
            measured_wh: o.energy_wh,
        });
        n = c;
    }
    Ok(out)
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
        hold: (0..g.nodes.len() as u32)
            .map(NodeId)
            .filter(|n| crate::promela::outside(g, *n))
            .collect(),
        codes: crate::explore::codes(g),
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
            Expr::Quantity(q, _, x) => out.push((*q, *x)),
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

/// The mission started: every primary process, at time zero with a full battery.
fn start(cx: &Ctx, reqs: &[&Requirement]) -> Result<Node, String> {
    let mut root = Node {
        state: State::default(),
        zone: Zone::new(),
        clocks: Vec::new(),
        energy: Span::point(0.0),
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
    let mut e = cx.engine(State::default());
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

/// What two states of one key must agree on to be compared or joined: their clocks (by what
/// they measure, not by the engine's ids) and readings.
fn layout(n: &Node) -> Vec<(u8, u32, &str)> {
    n.clocks.iter().map(Clock::layout).collect()
}

/// Whether `a` (seen) covers `b` (the same layout): every clock valuation, energy and reading
/// of `b` is one of `a`'s.
fn covers(a: &Node, b: &Node) -> bool {
    a.zone.includes(&b.zone)
        && a.energy.contains(&b.energy)
        && a.readings.len() == b.readings.len()
        && a.readings
            .values()
            .zip(b.readings.values())
            .all(|(x, y)| x.value.contains(&y.value) && x.peak >= y.peak)
}

/// Makes mission time beyond the greatest a requirement names one value (the usual
/// extrapolation of timed automata, exact for every requirement): a cycle driven by time (a
/// monitor polling every hour) then reaches states it has seen.
fn extrapolate(cx: &Ctx, n: &mut Node) {
    // A single run keeps its exact times (they are what its counterexample shows).
    if cx.pick.is_some() {
        return;
    }
    let (lo, hi) = n.zone.bounds(1);
    if hi > cx.horizon || lo > cx.horizon {
        n.zone.forget(1, cx.horizon);
    }
    for (i, c) in n.clocks.iter().enumerate() {
        // Readings' ages past what the battery could last, tasks that never end on their own:
        // no bound compares with more.
        let ceiling = match c {
            Clock::Read(_) => cx.capacity() * HOUR_MS / cx.costs.battery.idle_w.max(1e-9),
            Clock::Task(_, k) => match n.running.get(k) {
                Some(r) if r.cost.duration_ms.1.is_infinite() => r.cost.duration_ms.0,
                _ => continue,
            },
            _ => continue,
        };
        let (lo, hi) = n.zone.bounds(i + 1);
        if hi > ceiling || lo > ceiling {
            n.zone.forget(i + 1, ceiling);
        }
    }
}

/// Joins `c` into `o` (the same key and layout): the smallest zone holding both, the hull of
/// the energies and readings.
fn join(o: &mut Node, c: &Node) {
    o.zone.join(&c.zone);
    o.energy = o.energy.hull(c.energy);
    let spent: Vec<Span> = c
        .clocks
        .iter()
        .filter_map(|k| match k {
            Clock::Task(_, key) => c.running.get(key).map(|r| r.spent),
            _ => None,
        })
        .collect();
    let keys: Vec<TaskKey> = o
        .clocks
        .iter()
        .filter_map(|k| match k {
            Clock::Task(_, key) => Some(*key),
            _ => None,
        })
        .collect();
    for (key, theirs) in keys.iter().zip(spent) {
        if let Some(r) = o.running.get_mut(key) {
            r.spent = r.spent.hull(theirs);
        }
    }
    for (k, r) in o.readings.iter_mut() {
        if let Some(x) = c.readings.get(k) {
            r.value = r.value.hull(x.value);
            r.peak = r.peak.max(x.peak);
        }
    }
}

/// What must be equal for one state to cover or join another.
fn key(cx: &Ctx, n: &Node) -> String {
    let loops: Vec<(String, u8)> = n
        .loops
        .iter()
        .map(|((_, node), c)| (cx.g.node(*node).id.clone(), *c))
        .collect();
    format!(
        "{}|{loops:?}|{:?}|{:?}|{:?}|{:?}|{:?}|{}",
        crate::explore::shape(cx.g, &n.state),
        n.done,
        n.counts,
        n.signals,
        n.errors,
        n.reached,
        n.dead
    )
}

/// Everything that can happen next, with how long from now.
fn successors(cx: &Ctx, n: &Node) -> Vec<Next> {
    let g = cx.g;
    let s = &n.state;
    let mut out = Vec::new();
    // A mission that is over waits for nothing, not even its battery.
    if s.instances.values().all(|i| i.outcome.is_some()) {
        return out;
    }
    // Decisions are instantaneous: while a gateway decides, nothing else happens.
    for (tid, t) in &s.tokens {
        if !matches!(t.at, At::Deciding) {
            continue;
        }
        let node = g.node(t.node);
        let exclusive =
            matches!(&node.kind, NodeKind::Gateway(gw) if gw.kind == GatewayKind::Exclusive);
        let count = node.outgoing.len().min(6);
        let decided = decide(cx, n, t.node, t.scope);
        for mask in 1u32..(1 << count) {
            if exclusive && mask.count_ones() != 1 {
                continue;
            }
            let flows: Vec<_> = (0..count)
                .filter(|k| mask & (1 << k) != 0)
                .map(|k| node.outgoing[k])
                .collect();
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
            let names: Vec<&str> = flows.iter().map(|f| g.flow(*f).id.as_str()).collect();
            out.push(Next {
                label: format!("{}.take[{}]", node.id, names.join("+")),
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
            for c in &cx.codes {
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
    for (wid, w) in &s.waits {
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
            On::Message(..) | On::Condition { .. } | On::Manual => out.push(Next {
                label,
                event: Some(Event::WaitTriggered { wait: *wid }),
                when: When::Any,
                node: Some(w.node),
            }),
            _ => {}
        }
    }
    let die = death(cx, n);
    if die.lo.is_finite() {
        out.push(Next {
            label: "battery empty".into(),
            event: None,
            when: When::Dies(die.lo),
            node: None,
        });
    }
    out
}

/// Whether taking flow `f` out of `node` can lead back to it.
fn back(cx: &Ctx, node: NodeId, f: executive_model::FlowId) -> bool {
    crate::promela::reaches(cx.g, cx.g.flow(f).target, node)
}

/// Whether a choice of `flows` at `node` continues a cycle, and so counts against the loop
/// bound: some flow leads back — except that when every flow of the node does, one (the
/// default, else the first) stays free so the choice can always be made, as in the Spin
/// translation.
fn bounded(cx: &Ctx, node: NodeId, flows: &[executive_model::FlowId]) -> bool {
    let n = cx.g.node(node);
    let exit = n.outgoing.iter().any(|f| !back(cx, node, *f));
    let free = (!exit)
        .then(|| n.default_flow.or(n.outgoing.first().copied()))
        .flatten();
    flows.iter().any(|f| back(cx, node, *f) && Some(*f) != free)
}

/// How long from now the battery runs out, ms: the least and the greatest draw using what is
/// left.
fn death(cx: &Ctx, n: &Node) -> Span {
    let rate = cx.rate(n);
    let left = Span {
        lo: (cx.capacity() - n.total().hi).max(0.0),
        hi: (cx.capacity() - n.total().lo).max(0.0),
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
fn elapse(cx: &Ctx, n: &Node, when: &When) -> Option<(Zone, usize)> {
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
        z.at_most(wait, death(cx, n).hi);
        match when {
            When::After(c, least) => z.at_least(n.clock(c), *least),
            When::Dies(least) => z.at_least(wait, *least),
            _ => {}
        }
    }
    z.close().then_some((z, wait))
}

/// The energy of drawing `power` W for `d` ms, Wh.
fn wh(d: Span, power: Span) -> Span {
    let e = d.times(power);
    Span {
        lo: e.lo / HOUR_MS,
        hi: e.hi / HOUR_MS,
    }
}

/// Takes step `x` in zone `z` (from [`elapse`], its clock `wait` measuring the wait): the
/// engine steps, the clocks follow. `None`: no run takes it.
fn take(cx: &Ctx, n: &Node, x: &Next, mut z: Zone, wait: usize) -> Option<Node> {
    let (lo, hi) = z.bounds(wait);
    let d = Span { lo, hi };
    z.remove(wait);
    let mut c = n.clone();
    c.zone = z;
    let rate = cx.rate(n);
    c.energy = n.energy.plus(wh(d, Span::point(cx.costs.battery.idle_w)));
    c.energy.lo = c.energy.lo.min(cx.capacity());
    c.energy.hi = c.energy.hi.min(cx.capacity());
    for r in c.running.values_mut() {
        r.spent = r.spent.plus(wh(d, cx.power(r.cost.power_envelope())));
    }
    for r in c.readings.values_mut() {
        r.peak = r.peak.max(rate.hi);
    }
    remember(cx, &mut c)?;
    let Some(event) = x.event.clone() else {
        c.energy = Span::point(cx.capacity());
        for r in c.running.values_mut() {
            r.spent = Span::point(0.0);
        }
        c.dead = true;
        return Some(c);
    };
    let mut e = cx.engine(n.state.clone());
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
        c.energy = c.energy.plus(own);
        c.stop_clock(&Clock::Task(r.node, key));
        spent = Some(own);
        let energy = c.total();
        let cap = cx.capacity();
        for (var, reading) in &r.cost.reads {
            let value = match reading {
                Reading::EnergyWh => Span {
                    lo: cap - energy.hi,
                    hi: cap - energy.lo,
                },
                Reading::SocPct => Span {
                    lo: 100.0 * (cap - energy.hi) / cap,
                    hi: 100.0 * (cap - energy.lo) / cap,
                },
            };
            c.stop_clock(&Clock::Read(var.clone()));
            c.start_clock(Clock::Read(var.clone()));
            c.readings.insert(
                var.clone(),
                Read {
                    value,
                    kind: *reading,
                    peak: 0.0,
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
                    .any(|f| crate::promela::reaches(cx.g, cx.g.flow(*f).target, b.attached_to))
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
fn decide(
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
        // A reading is compared with one threshold (monotone), or the choice stays free.
        let comparisons = ["<", ">", "=="]
            .iter()
            .map(|op| cond.text.matches(op).count())
            .sum::<usize>();
        if readings.len() > 1 || (readings.len() == 1 && comparisons != 1) {
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
fn note(cx: &Ctx, c: &mut Node, actions: &[Action]) {
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
            } if cx.signals.contains(name) => {
                c.signals.insert(name.clone());
            }
            Entry::Caught {
                what: Trigger::Error,
                name,
                ..
            } if cx.errors.contains(name) => {
                c.errors.insert(name.clone());
            }
            _ => {}
        }
    }
}

/// An element completed or was passed: done, and counted up to the bound a requirement needs.
fn count(cx: &Ctx, c: &mut Node, node: NodeId) {
    if cx.watched.contains(&node) {
        c.done.insert(node);
    }
    if let Some(bound) = cx.counted.get(&node) {
        let k = c.counts.entry(node).or_default();
        *k = (*k + 1).min(*bound);
    }
}

/// Brings the clocks in line with the engine state: tasks that started now run from now,
/// timers armed now count from now, and what the engine dropped is gone (a cancelled
/// activity's energy so far stays used, at most).
fn settle(cx: &Ctx, c: &mut Node) {
    let mut running = BTreeMap::new();
    let tokens: Vec<(TaskKey, NodeId)> = c
        .state
        .tokens
        .values()
        .filter_map(|t| match t.at {
            At::Task(k) | At::UserTask(k) => Some((k, t.node)),
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
        c.energy = c.energy.plus(Span {
            lo: 0.0,
            hi: r.spent.hi,
        });
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
            On::Timer { key, due, .. } => Some((key, w.node, due as f64)),
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

/// Updates what each `eventually` requirement has seen on this path.
fn observe(cx: &Ctx, reqs: &[&Requirement], c: &mut Node) {
    for (k, r) in reqs.iter().enumerate() {
        if let Form::Eventually(e) = &r.form
            && c.reached[k] != Tri::Yes
        {
            c.reached[k] = c.reached[k].max(eval(cx, c, e, 0.0, &r.atoms));
        }
    }
}

/// A quantity over the state's life: from now until `lasting` ms later.
fn quantity(cx: &Ctx, n: &Node, q: Quantity, lasting: f64) -> Span {
    let cap = cx.capacity();
    let energy = Span {
        lo: n.total().lo,
        hi: (n.total().hi + cx.rate(n).hi * lasting / HOUR_MS).min(cap),
    };
    match q {
        Quantity::Time => Span {
            lo: n.t().lo,
            hi: n.t().hi + lasting,
        },
        Quantity::Energy => energy,
        Quantity::EnergyLeftWh => Span {
            lo: cap - energy.hi,
            hi: cap - energy.lo,
        },
        Quantity::EnergyLeftPct => Span {
            lo: 100.0 * (cap - energy.hi) / cap,
            hi: 100.0 * (cap - energy.lo) / cap,
        },
    }
}

/// Three-valued: whether `e` holds in `n` (over the `lasting` ms it may last).
fn eval(cx: &Ctx, n: &Node, e: &Expr, lasting: f64, atoms: &[Atom]) -> Tri {
    match e {
        Expr::Not(x) => eval(cx, n, x, lasting, atoms).not(),
        Expr::And(a, b) => eval(cx, n, a, lasting, atoms).min(eval(cx, n, b, lasting, atoms)),
        Expr::Or(a, b) => eval(cx, n, a, lasting, atoms).max(eval(cx, n, b, lasting, atoms)),
        Expr::Word(w) => {
            let mut outcomes = n.state.instances.values().map(|i| &i.outcome);
            Tri::of(match w.as_str() {
                "ended" => n.dead || outcomes.all(|o| o.is_some()),
                "failed" => outcomes.any(|o| matches!(o, Some(EngineOutcome::Failed { .. }))),
                _ => outcomes.any(|o| matches!(o, Some(EngineOutcome::Terminated))),
            })
        }
        Expr::Quantity(q, op, x) => {
            // Sums of floating-point draws: equal to a millionth is equal.
            let v = quantity(cx, n, *q, lasting);
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
fn atom(n: &Node, e: &Expr, atoms: &[Atom]) -> bool {
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

/// The labels of the steps to a state.
fn labels(nodes: &[Node], mut at: usize) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(v) = &nodes[at].via {
        out.push(v.label.clone());
        at = v.from;
    }
    out.reverse();
    out
}

/// One step of a run as a counterexample shows it.
fn step(cx: &Ctx, n: &Node, label: &str, node: Option<NodeId>) -> TraceStep {
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
            time_ms: n.t(),
            energy_wh: n.total(),
            activity_wh: n.via.as_ref().and_then(|v| v.spent),
        }),
    }
}

/// Replays the way to a suspect state as one run, to see whether a real run violates
/// requirement `k`: every activity at its greatest power and duration (`late`) or its least,
/// each step at one moment. The way's choices guide the run — its branches, failures, answers
/// and timers are taken as soon as they can come next — while what must happen meanwhile (a
/// timer due, a decision the data makes) happens when due. The run's steps, with the tasks'
/// starts, if it violates the requirement.
fn replay(
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
        let running = n.state.instances.values().any(|i| i.outcome.is_none());
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
        // due first (a completion before a failure, the default branch first).
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
    let ended = n.dead
        || n.state.instances.values().all(|i| i.outcome.is_some())
        || successors(cx, &n).is_empty();
    tracing::debug!(
        requirement = %r.name,
        late,
        steps = steps.len(),
        guided = guide,
        ended,
        energy_wh = n.energy.hi,
        "replayed"
    );
    let violated = match &r.form {
        Form::Eventually(_) => ended && n.reached[k] == Tri::No,
        _ => false,
    };
    violated.then_some(steps)
}

fn asserted<'g>(
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
fn comparison(text: &str) -> Option<(String, Cmp, f64)> {
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
fn refine(cx: &Ctx, c: &mut Node, cond: &executive_model::Expression, holds: bool) -> Option<()> {
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

#[cfg(test)]
#[path = "timed_tests.rs"]
mod tests;
