//! What a state of the timed exploration holds — the engine's state, a clock zone, the energy,
//! the tasks, timers and readings in flight, what the requirements have seen — and how states
//! are compared, joined and extrapolated.

use super::*;

/// A task in flight (its clock counts how long it has run): what it has spent and costs, and
/// the vehicle whose battery it draws from.
#[derive(Clone, Debug)]
pub(super) struct Running {
    pub(super) node: NodeId,
    pub(super) spent: Span,
    pub(super) cost: TaskCost,
    pub(super) vehicle: usize,
}

/// An armed timer (its clock counts since it was armed): its element and duration, ms.
#[derive(Clone, Copy, Debug)]
pub(super) struct Timer {
    pub(super) node: NodeId,
    pub(super) dur: f64,
}

/// What a clock of a state's zone measures.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Clock {
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
    pub(super) fn layout(&self) -> (u8, u32, &str) {
        match self {
            Clock::Time => (0, 0, ""),
            Clock::Task(n, _) => (1, n.0, ""),
            Clock::Timer(n, _) => (2, n.0, ""),
            Clock::Read(v) => (3, 0, v),
        }
    }
}

/// A battery reading a variable holds: its bounds, what it reads, the greatest draw since it
/// was taken (its clock counts how long ago) and whose battery. It keeps the energy used tied
/// to what was read — used now is used then plus at least the idle draw and at most the
/// greatest draw since — which a decision on the reading narrows and a join of states does not
/// undo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Read {
    pub(super) value: Span,
    pub(super) kind: Reading,
    pub(super) peak: f64,
    pub(super) vehicle: usize,
}

impl Read {
    /// The energy used when it was read, Wh.
    pub(super) fn used(&self, cap: f64) -> Span {
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

/// What a battery reading of `kind` says when `used` Wh of `cap` are used: the energy left, Wh,
/// or the state of charge, %.
pub(super) fn reading(cap: f64, used: Span, kind: Reading) -> Span {
    let left = Span {
        lo: cap - used.hi,
        hi: cap - used.lo,
    };
    match kind {
        Reading::EnergyWh => left,
        Reading::SocPct => Span {
            lo: 100.0 * left.lo / cap,
            hi: 100.0 * left.hi / cap,
        },
    }
}

/// Narrows each vehicle's energy used by what its readings say it was then. `None`: nothing
/// is left.
pub(super) fn remember(cx: &Ctx, c: &mut Node) -> Option<()> {
    for (var, r) in &c.readings {
        let v = r.vehicle;
        let idle = cx.idle(v);
        let running = c
            .running
            .values()
            .filter(|x| x.vehicle == v)
            .fold(Span::point(0.0), |s, x| s.plus(x.spent));
        let (lo, hi) = c.zone.bounds(c.clock(&Clock::Read(var.clone())));
        let then = r.used(cx.capacity(v));
        // Used now lies in these bounds; what the running activities drew is apart.
        let e = &mut c.energy[v];
        e.lo = e.lo.max(then.lo + idle * lo / HOUR_MS - running.hi);
        e.hi = e.hi.min(then.hi + r.peak * hi / HOUR_MS - running.lo);
    }
    for e in &mut c.energy {
        if e.lo > e.hi + 1e-6 {
            return None;
        }
        e.hi = e.hi.max(e.lo);
    }
    Some(())
}

/// Three-valued truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(super) enum Tri {
    No,
    Maybe,
    Yes,
}

impl Tri {
    pub(super) fn of(b: bool) -> Tri {
        if b { Tri::Yes } else { Tri::No }
    }
    pub(super) fn not(self) -> Tri {
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
pub(super) struct Via {
    pub(super) from: usize,
    pub(super) label: String,
    pub(super) spent: Option<Span>,
}

/// One state of the search.
#[derive(Clone)]
pub(super) struct Node {
    pub(super) state: State,
    /// The clocks' zone, clock `i + 1` measuring `clocks[i]` (kept in [`Clock`] order).
    pub(super) zone: Zone,
    pub(super) clocks: Vec<Clock>,
    /// Energy used so far by the idle draw and the activities that ended, Wh, per vehicle (the
    /// running ones' is theirs until they end: see [`Node::used`]).
    pub(super) energy: Vec<Span>,
    /// The vehicles whose battery is empty: they do nothing more (the run is over when every
    /// vehicle's is, [`Node::dead`]).
    pub(super) empty: BTreeSet<usize>,
    pub(super) running: BTreeMap<TaskKey, Running>,
    pub(super) timers: BTreeMap<TimerKey, Timer>,
    pub(super) readings: BTreeMap<String, Read>,
    /// Free cycle-continuing choices taken, by (scope activation, deciding element).
    pub(super) loops: BTreeMap<(ScopeId, NodeId), u8>,
    pub(super) done: BTreeSet<NodeId>,
    pub(super) counts: BTreeMap<NodeId, u8>,
    pub(super) signals: BTreeSet<String>,
    pub(super) errors: BTreeSet<String>,
    /// Per `eventually` requirement: reached on this path.
    pub(super) reached: Vec<Tri>,
    /// The run is over: every vehicle's battery is empty.
    pub(super) dead: bool,
    pub(super) via: Option<Via>,
}

impl Node {
    /// The zone index of a clock (0, the zero clock, if it has none).
    pub(super) fn clock(&self, c: &Clock) -> usize {
        self.clocks.iter().position(|x| x == c).map_or(0, |i| i + 1)
    }

    /// Energy vehicle `v` has used so far, Wh: the idle draw, the activities that ended and
    /// what the running ones have drawn.
    pub(super) fn used(&self, v: usize) -> Span {
        self.running
            .values()
            .filter(|r| r.vehicle == v)
            .fold(self.energy[v], |e, r| e.plus(r.spent))
    }

    /// Energy the mission has used so far, Wh: every vehicle's.
    pub(super) fn total(&self) -> Span {
        (0..self.energy.len()).fold(Span::point(0.0), |e, v| e.plus(self.used(v)))
    }

    /// Every vehicle's energy used so far, by name (none for a mission of one battery).
    pub(super) fn by_vehicle(&self, cx: &Ctx) -> BTreeMap<String, Span> {
        if self.energy.len() < 2 {
            return BTreeMap::new();
        }
        (0..self.energy.len())
            .map(|v| (cx.costs.name(v).to_owned(), self.used(v)))
            .collect()
    }

    /// Whether the mission is over: every instance has ended, or belongs to a vehicle whose
    /// battery is empty.
    pub(super) fn over(&self, cx: &Ctx) -> bool {
        self.state.instances.values().all(|i| {
            i.outcome.is_some()
                || self
                    .empty
                    .contains(&cx.costs.owner.get(&i.process).copied().unwrap_or(0))
        })
    }

    /// Mission time now, ms.
    pub(super) fn t(&self) -> Span {
        let (lo, hi) = self.zone.bounds(1);
        Span { lo, hi }
    }

    /// Adds a clock reading 0 now.
    pub(super) fn start_clock(&mut self, c: Clock) {
        self.clocks.push(c);
        self.zone.add();
    }

    /// Drops a clock.
    pub(super) fn stop_clock(&mut self, c: &Clock) {
        let k = self.clock(c);
        if k > 0 {
            self.clocks.remove(k - 1);
            self.zone.remove(k);
        }
    }

    /// Puts the clocks in [`Clock`] order, so that states of one key line up.
    pub(super) fn sort_clocks(&mut self) {
        let mut order: Vec<usize> = (0..self.clocks.len()).collect();
        order.sort_by(|a, b| self.clocks[*a].cmp(&self.clocks[*b]));
        let mut zone_order = vec![0];
        zone_order.extend(order.iter().map(|i| i + 1));
        self.zone.reorder(&zone_order);
        self.clocks = order.iter().map(|i| self.clocks[*i].clone()).collect();
    }
}

pub(super) struct Ctx<'a> {
    pub(super) g: &'a Arc<ProcessGraph>,
    pub(super) costs: &'a Costs,
    /// Each element's vehicle, by node index.
    pub(super) vehicle: Vec<usize>,
    pub(super) hold: BTreeSet<NodeId>,
    pub(super) codes: Vec<String>,
    /// The start events by which the outside starts a process.
    pub(super) starts: Vec<(executive_model::ProcessId, NodeId)>,
    pub(super) limits: TimedLimits,
    /// Elements the requirements count, with the count they saturate at.
    pub(super) counted: BTreeMap<NodeId, u8>,
    /// Elements, signals and error codes the requirements read (the rest is not kept: it
    /// would tell apart states no requirement can).
    pub(super) watched: BTreeSet<NodeId>,
    pub(super) signals: BTreeSet<String>,
    pub(super) errors: BTreeSet<String>,
    /// Replaying one run: every activity at its greatest (`true`) or least power.
    pub(super) pick: Option<bool>,
    /// Beyond this mission time (the greatest a requirement names), times are all alike.
    pub(super) horizon: f64,
    /// Following one observed run: its results carry their data and the engine decides.
    pub(super) data: bool,
}

/// What can happen next: its label, the input (`None`: a battery runs out), when, and its
/// element.
pub(super) struct Next {
    pub(super) label: String,
    pub(super) event: Option<Event>,
    pub(super) when: When,
    pub(super) node: Option<NodeId>,
}

/// When a step can come.
#[derive(Clone, Debug)]
pub(super) enum When {
    /// At once (a decision).
    Now,
    /// Once the clock has reached the least (a task's least duration, a timer's).
    After(Clock, f64),
    /// Any time (an answer, a message).
    Any,
    /// A vehicle's battery runs out: this long from now at the least.
    Dies(usize, f64),
}

impl Ctx<'_> {
    /// The engine on `state`; the pools of the vehicles `empty` run nothing more (a message for
    /// them goes nowhere).
    pub(super) fn engine(&self, state: State, empty: &BTreeSet<usize>) -> Engine {
        let mut e = Engine::restore(Arc::clone(self.g), state);
        if !empty.is_empty() {
            e = e.with_remote(
                self.costs
                    .owner
                    .iter()
                    .filter(|(_, v)| empty.contains(v))
                    .filter_map(|(p, v)| Some((*p, self.costs.vehicles[*v].pool.clone()?)))
                    .collect(),
            );
        }
        // Following a run with its data is running the engine as the executive does.
        if !self.data {
            let game = e.game();
            game.decide = true;
            game.hold = self.hold.clone();
            // Every instance a count written as a number starts draws time and energy.
            game.instances = u64::MAX;
        }
        e
    }

    /// Vehicle `v`'s battery capacity, Wh.
    pub(super) fn capacity(&self, v: usize) -> f64 {
        self.costs.vehicles[v].battery.capacity_wh
    }

    /// Vehicle `v`'s idle draw, W.
    pub(super) fn idle(&self, v: usize) -> f64 {
        self.costs.vehicles[v].battery.idle_w
    }

    /// The vehicle an element belongs to.
    pub(super) fn vehicle_of(&self, node: NodeId) -> usize {
        self.vehicle.get(node.0 as usize).copied().unwrap_or(0)
    }

    pub(super) fn power(&self, p: (f64, f64)) -> Span {
        match self.pick {
            Some(true) => Span::point(p.1),
            Some(false) => Span::point(p.0),
            None => Span { lo: p.0, hi: p.1 },
        }
    }

    /// Vehicle `v`'s draw now, W: idle plus every running activity's (none once its battery
    /// is empty).
    pub(super) fn rate(&self, n: &Node, v: usize) -> Span {
        if n.empty.contains(&v) {
            return Span::point(0.0);
        }
        n.running
            .values()
            .filter(|t| t.vehicle == v)
            .fold(Span::point(self.idle(v)), |r, t| {
                r.plus(self.power(t.cost.power_envelope()))
            })
    }
}

/// Whether state `from`'s way back to the start passes through state `o`.
pub(super) fn descends(nodes: &[Node], mut from: usize, o: usize) -> bool {
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

/// What two states of one key must agree on to be compared or joined: their clocks (by what
/// they measure, not by the engine's ids) and readings.
pub(super) fn layout(n: &Node) -> Vec<(u8, u32, &str)> {
    n.clocks.iter().map(Clock::layout).collect()
}

/// Whether `a` (seen) covers `b` (the same layout): every clock valuation, energy and reading
/// of `b` is one of `a`'s.
pub(super) fn covers(a: &Node, b: &Node) -> bool {
    let spent = |n: &Node| -> Vec<Span> {
        n.clocks
            .iter()
            .filter_map(|k| match k {
                Clock::Task(_, key) => n.running.get(key).map(|r| r.spent),
                _ => None,
            })
            .collect()
    };
    a.zone.includes(&b.zone)
        && a.energy.iter().zip(&b.energy).all(|(x, y)| x.contains(y))
        && spent(a).iter().zip(spent(b)).all(|(x, y)| x.contains(&y))
        && a.readings.len() == b.readings.len()
        && a.readings
            .values()
            .zip(b.readings.values())
            .all(|(x, y)| x.value.contains(&y.value) && x.peak >= y.peak)
}

/// Makes mission time beyond the greatest a requirement names one value (the usual
/// extrapolation of timed automata, exact for every requirement): a cycle driven by time (a
/// monitor polling every hour) then reaches states it has seen.
pub(super) fn extrapolate(cx: &Ctx, n: &mut Node) {
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
            Clock::Read(var) => {
                let v = n.readings.get(var).map_or(0, |r| r.vehicle);
                cx.capacity(v) * HOUR_MS / cx.idle(v).max(1e-9)
            }
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
pub(super) fn join(o: &mut Node, c: &Node) {
    o.zone.join(&c.zone);
    for (x, y) in o.energy.iter_mut().zip(&c.energy) {
        *x = x.hull(*y);
    }
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
pub(super) fn key(cx: &Ctx, n: &Node) -> String {
    let loops: Vec<(String, u8)> = n
        .loops
        .iter()
        .map(|((_, node), c)| (cx.g.node(*node).id.clone(), *c))
        .collect();
    format!(
        "{}|{loops:?}|{:?}|{:?}|{:?}|{:?}|{:?}|{}|{:?}",
        crate::explore::shape(cx.g, &n.state, &cx.starts),
        n.done,
        n.counts,
        n.signals,
        n.errors,
        n.reached,
        n.dead,
        n.empty
    )
}
