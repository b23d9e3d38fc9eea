//! BPMN → PROMELA: one global token marking (`tok[]` per sequence flow, `act[]` per running
//! activity — a count for a parallel multi-instance task —, armed event-based gateway or waiting
//! compensation throw) and one guarded atomic step per BPMN transition, each starting with a
//! `@@BPMN <element>` marker so a Spin trail reads back as BPMN steps
//! (`../shared/design/verification.md` §2, scheme A). Besides: `comp[]` marks completed
//! compensable activities, `pend[]` an event sub-process or compensation handler asked for and
//! not yet entered (entering is its own step, so a dead one is seen as dead), `starts[]` counts
//! the instances of processes started by an event (`eventsubs.rs`, `compensation.rs`).
//!
//! Abstractions: conditions are nondeterministic choices; timers, messages and conditional events
//! may fire whenever they are armed; a service task may fail with any error some catcher around
//! it catches (a catcher behind one that takes the same code, or behind a catch-all, never
//! fires). Every choice that continues a cycle (a gateway branch or a boundary that leads back
//! to where it came from) is bounded per scope activation, so every run is finite. Called
//! processes are inlined per call site. What the translation does not cover is refused with the
//! element named — never dropped.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write;

use executive_model::{
    Called, EventDefinition, FlowId, GatewayKind, Looping, NodeId, NodeKind, ProcessGraph,
    ProcessId, Scope, SubProcessKind, TaskKind,
};
use serde::Serialize;

use crate::requirements::Atom;

mod compensation;
mod emit;
mod events;
mod eventsubs;
mod nodes;
mod refusals;

/// An element the translation does not cover, and why.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, thiserror::Error)]
#[error("`{element}`: {reason}")]
pub struct Refusal {
    /// The BPMN element id.
    pub element: String,
    /// Why it is not translated.
    pub reason: String,
}

/// Bounds of the abstraction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bounds {
    /// How often a cycle-continuing choice (or a loop body) may repeat per scope activation.
    pub loops: u8,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds { loops: 1 }
    }
}

/// What a step marker stands for.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Step {
    /// The BPMN element id.
    pub element: String,
    /// Its name (or id).
    pub name: String,
    /// The call activities it runs under (`ExcavateCall/`), empty at top level.
    pub path: String,
    /// What happened: `start`, `complete`, `fire`, `take`, `activate`, `end`, …
    pub phase: String,
    /// The element is an activity (task, sub-process, call activity).
    pub activity: bool,
}

/// The PROMELA model and how to read its markers back.
#[derive(Clone, Debug)]
pub struct Translation {
    /// The PROMELA text.
    pub promela: String,
    /// Marker → step.
    pub steps: BTreeMap<String, Step>,
    /// Every activity occurrence (`path` + element id) with its name.
    pub activities: BTreeMap<String, String>,
    /// The model throws a signal that something catches (the lost-signal check applies).
    pub signals: bool,
    /// PROMELA line → the marker of the step written on it.
    pub lines: BTreeMap<usize, String>,
    /// Activities entered inside another step's branch: witness `k` (the statement
    /// `entry = k`, first of the branch, which pan names when no run takes it) → the marker.
    pub witnesses: Vec<String>,
    /// Per observed atom (in the order given), the PROMELA expression that reads it.
    pub atoms: Vec<String>,
}

/// Marking a flow in the safety model: a second token is an assertion violation (unsafe), and
/// the search goes on with both tokens, as the engine keeps both (counted up to two: a third
/// on one flow is where the count stops). The token is of the next wave (`gen` 2): it arrives
/// once the wave that made it ready is over (`docs/engine-semantics.md`, "Within a step").
const SAFETY_PUT: &str = "#define PUT(f) assert(tok[f] == 0); if :: tok[f] < 2 -> tok[f]++ :: else -> skip fi; gen[f] = 2";
/// Marking a flow in the LTL model: a second token only raises `unsafe`, so claims are judged
/// on their own.
const LTL_PUT: &str = "#define PUT(f) if :: tok[f] > 0 -> unsafe = 1 :: else -> skip fi; if :: tok[f] < 2 -> tok[f]++ :: else -> skip fi; gen[f] = 2";
/// A task (not folded into one step) entered along flow `f`: the instance keeps the flow it came
/// by (`busy[f]`) until it ends, as the engine's token does, so a second token entering along the
/// same flow while it runs is unsafe, as a second token on the flow is. Another instance
/// starts beside it (counted up to two), as in the engine. A withdrawal zeroes only the task's
/// `act[]` (fewer statements in the steps that clear a scope): entering a task with none
/// running first zeroes its `busy[]`.
const SAFETY_ENTER: &str =
    "#define ENTER(f) assert(busy[f] == 0); if :: busy[f] < 2 -> busy[f]++ :: else -> skip fi";
/// [`SAFETY_ENTER`] in the LTL model: the second entry only raises `unsafe`.
const LTL_ENTER: &str = "#define ENTER(f) if :: busy[f] > 0 -> unsafe = 1 :: else -> skip fi; if :: busy[f] < 2 -> busy[f]++ :: else -> skip fi";

impl Translation {
    /// The model for LTL claims (same lines, flows marked without assertions).
    pub fn ltl_model(&self) -> String {
        self.promela
            .replacen(SAFETY_PUT, LTL_PUT, 1)
            .replacen(SAFETY_ENTER, LTL_ENTER, 1)
    }
}

/// What lies inside a scope: its flows, activity slots, cycle counters and compensation marks.
#[derive(Default)]
struct Inside {
    flows: Vec<usize>,
    acts: Vec<usize>,
    cnts: Vec<usize>,
    comps: Vec<usize>,
    pends: Vec<usize>,
}

/// What catches a throw: a boundary event of an enclosing activity, or an event sub-process of
/// an enclosing scope (named by its start event).
#[derive(Clone, Copy, Debug)]
enum Catch {
    Boundary { c: usize, holder: NodeId, b: NodeId },
    EventSub { c: usize, start: NodeId },
}

impl Catch {
    /// The catching node: the boundary event, or the event sub-process's start event.
    fn node(&self) -> NodeId {
        match self {
            Catch::Boundary { b, .. } => *b,
            Catch::EventSub { start, .. } => *start,
        }
    }

    /// The catch stops what was caught (the activity, or the scope's other work).
    fn interrupting(&self, g: &ProcessGraph) -> bool {
        match self {
            Catch::Boundary { b, .. } => interrupting(g, *b),
            Catch::EventSub { start, .. } => {
                !matches!(&g.node(*start).kind, NodeKind::Start(st) if !st.interrupting)
            }
        }
    }
}

/// `n` is an event sub-process.
pub(crate) fn is_event_sub(g: &ProcessGraph, n: NodeId) -> bool {
    matches!(&g.node(n).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event))
}

/// A calling context: a primary process, or a called process inlined at one call site.
struct Ctx {
    process: ProcessId,
    call: Option<(usize, NodeId)>,
    path: String,
}

/// One guarded step.
#[derive(Clone, Default)]
struct Alt {
    guard: Vec<String>,
    effect: Vec<String>,
    /// Something outside answers (a system, the ground, time): it happens only once nothing
    /// inside can move, as the engine runs each step to quiescence.
    outside: bool,
    /// A throw or end event that throws: it acts at the end of its wave, once no other step
    /// of the wave can move (`SETTLING`).
    throw: bool,
}

struct Tr<'g> {
    g: &'g ProcessGraph,
    bounds: Bounds,
    ctxs: Vec<Ctx>,
    nodes_of: HashMap<ProcessId, Vec<NodeId>>,
    flow_ix: HashMap<(usize, FlowId), usize>,
    flow_names: Vec<String>,
    act_ix: HashMap<(usize, NodeId), usize>,
    act_names: Vec<String>,
    cnt_ix: HashMap<(usize, NodeId), usize>,
    cnt_names: Vec<String>,
    /// Completed compensable activities (`comp[]`), per context.
    comp_ix: HashMap<(usize, NodeId), usize>,
    comp_names: Vec<String>,
    /// Processes started by a message, signal or condition: how often each start fired
    /// (`starts[]`).
    start_ix: HashMap<(usize, NodeId), usize>,
    /// Activities entered when something asks (`pend[]`): compensation handlers by their node,
    /// event sub-processes by their start event.
    pend_ix: HashMap<(usize, NodeId), usize>,
    /// Compensation waiters: the waiter's slot and the handlers it waits for (all idle).
    waiters: Vec<(usize, String)>,
    alts: Vec<String>,
    steps: BTreeMap<String, Step>,
    /// Markers of activities entered inside another step, by witness (`entry = k`).
    witnesses: Vec<String>,
    refusals: Vec<Refusal>,
    lost_check: bool,
    observe: Vec<Atom>,
    /// Tasks translated as one step (start and completion folded).
    folded: BTreeSet<NodeId>,
    /// Declared bounded variables.
    vars: crate::data::Variables,
    /// Nodes that start with their scope, having no incoming flow (the engine's implicit start).
    implicit: BTreeSet<NodeId>,
    /// The guards of the steps inside a wave (neither outside nor throws): one of them holds
    /// while the wave is still arriving (`SETTLING`).
    settling: Vec<String>,
    /// The guards of the throw steps (`THROWING`).
    throwing: Vec<String>,
    /// The guards of the joins: a join whose tokens have all arrived passes them on within the
    /// step, before anything outside is heard (`MOVED`).
    joining: Vec<String>,
    /// Events a token is put at before it moves on, one wave later (the engine spawns it at
    /// the event): the start events of sub-processes, event sub-processes and called processes
    /// as their scope opens, and boundary events as they fire. A slot each in `tok[]`.
    arrive_slot: HashMap<(usize, NodeId), usize>,
    /// The context of the end event whose throw is being written: its process is still
    /// active while it throws, though its last token was just taken (§13.5.6).
    ending: Option<usize>,
}

/// Most instances of one activity whose count the model writes as a number
/// (`Looping::literal_count`) the translation and the exploration run: a larger count is cut to
/// it (the instances differ only in when each completes, and three already interleave every way
/// two completions can with the rest).
pub(crate) const MAX_INSTANCES: u64 = 3;

impl Tr<'_> {
    /// How many instances a parallel multi-instance activity starts: its literal cardinality
    /// (at most [`MAX_INSTANCES`]), else any number from one to the loop bound plus one, as a
    /// sequential one repeats.
    fn instances(&self, mi: &executive_model::MultiInstance) -> u64 {
        mi.literal_count()
            .map_or(u64::from(self.bounds.loops) + 1, |n| n.min(MAX_INSTANCES))
    }
}

/// The length of a node's timer, when it is a fixed duration.
pub(crate) fn fixed_duration(node: &executive_model::Node) -> Option<u64> {
    match &node.kind {
        NodeKind::Boundary(b) => fixed_duration_of(&b.triggers),
        NodeKind::Catch(c) => fixed_duration_of(&c.triggers),
        _ => None,
    }
}

/// The length of a timer among `defs`, when it is a fixed duration.
pub(crate) fn fixed_duration_of(defs: &[EventDefinition]) -> Option<u64> {
    defs.iter().find_map(|d| match d {
        EventDefinition::Timer(t) => match &t.value {
            executive_model::timer::TimerValue::Fixed(
                executive_model::timer::TimerSpec::Duration(d),
            ) => Some(d.approx_millis()),
            _ => None,
        },
        _ => None,
    })
}

/// The node's work is done outside the executive (a system, the ground): a task other than a
/// script task, or a call of a global task that is not a script. The engine's token game holds
/// exactly these for the explorer; the translation waits for them with `QUIET`.
pub(crate) fn outside(g: &ProcessGraph, n: NodeId) -> bool {
    match &g.node(n).kind {
        NodeKind::Task(t) => t.kind != TaskKind::Script,
        NodeKind::CallActivity(ca) => match &ca.called {
            Some(Called::GlobalTask(id)) => g
                .global_tasks
                .get(id)
                .is_some_and(|t| t.kind != TaskKind::Script),
            _ => false,
        },
        _ => false,
    }
}

/// Whether `n` hears its message only from elements of the model (§9.3: the message flows
/// drawn to a receiver name who sends to it): it catches messages only, message flows end at
/// it, and each starts at an element of one of the model's processes, not at a pool. Such a
/// catch event, boundary event or start event is fired by those senders' throws, never from
/// outside — so a collaboration is verified as a whole, and a receiver whose senders never
/// send is stuck (the engine runs every pool's process in one model and delivers the same way).
pub(crate) fn inner_message(g: &ProcessGraph, n: NodeId) -> bool {
    let node = g.node(n);
    let triggers = match &node.kind {
        NodeKind::Catch(ce) => &ce.triggers,
        NodeKind::Boundary(be) => &be.triggers,
        NodeKind::Start(st) => &st.triggers,
        _ => return false,
    };
    if triggers.is_empty()
        || !triggers
            .iter()
            .all(|d| matches!(d, EventDefinition::Message(_)))
    {
        return false;
    }
    let mut flows = g
        .collaborations
        .iter()
        .flat_map(|c| &c.message_flows)
        .filter(|m| m.target == node.id)
        .peekable();
    flows.peek().is_some() && flows.all(|m| g.node_by_id(&m.source).is_some())
}

/// The start event is one the outside fires: a message or condition start (a signal start
/// hears the model's own signals instead).
pub(crate) fn started_from_outside(g: &ProcessGraph, n: NodeId) -> bool {
    matches!(&g.node(n).kind, NodeKind::Start(st) if st.triggers.iter().any(
        |d| matches!(d, EventDefinition::Message(_) | EventDefinition::Conditional(_))))
}

/// Can `from` reach `to` along sequence flows and attached boundaries (same process)?
pub(crate) fn reaches(g: &ProcessGraph, from: NodeId, to: NodeId) -> bool {
    let mut seen = BTreeSet::new();
    let mut stack = vec![from];
    while let Some(n) = stack.pop() {
        if n == to {
            return true;
        }
        if !seen.insert(n) {
            continue;
        }
        let node = g.node(n);
        stack.extend(node.outgoing.iter().map(|f| g.flow(*f).target));
        stack.extend(node.boundaries.iter().copied());
        // Leaving a sub-process continues after it.
        if let Scope::SubProcess(s) = node.scope
            && matches!(node.kind, NodeKind::End(_))
        {
            stack.push(s);
        }
    }
    false
}

/// A boundary event that interrupts its activity (every other node: `true`).
pub(crate) fn interrupting(g: &ProcessGraph, b: NodeId) -> bool {
    !matches!(&g.node(b).kind, NodeKind::Boundary(be) if !be.interrupting)
}

/// One `unheard` flag per signal, and one for unnamed signals.
fn signal_slots(g: &ProcessGraph) -> usize {
    g.signals.len() + 1
}

/// Translates a validated model, instrumented for the atoms requirements read, with the
/// declared bounded variables kept exactly.
pub fn translate(
    g: &ProcessGraph,
    bounds: Bounds,
    observe: &[Atom],
    vars: &crate::data::Variables,
) -> Result<Translation, Vec<Refusal>> {
    let mut t = Tr {
        g,
        bounds,
        ctxs: Vec::new(),
        nodes_of: HashMap::new(),
        flow_ix: HashMap::new(),
        flow_names: Vec::new(),
        act_ix: HashMap::new(),
        act_names: Vec::new(),
        cnt_ix: HashMap::new(),
        cnt_names: Vec::new(),
        comp_ix: HashMap::new(),
        comp_names: Vec::new(),
        start_ix: HashMap::new(),
        pend_ix: HashMap::new(),
        waiters: Vec::new(),
        alts: Vec::new(),
        steps: BTreeMap::new(),
        witnesses: Vec::new(),
        refusals: Vec::new(),
        lost_check: false,
        observe: observe.to_vec(),
        folded: BTreeSet::new(),
        settling: Vec::new(),
        throwing: Vec::new(),
        joining: Vec::new(),
        ending: None,
        arrive_slot: HashMap::new(),
        vars: vars.clone(),
        implicit: implicit_nodes(g),
    };
    for id in (0..g.nodes.len() as u32).map(NodeId) {
        t.nodes_of.entry(g.process_of(id)).or_default().push(id);
    }
    t.contexts();
    t.slots();
    t.refuse_unsupported();
    if !t.refusals.is_empty() {
        return Err(t.refusals);
    }
    for c in 0..t.ctxs.len() {
        for n in t.nodes(c) {
            t.node(c, n);
        }
    }
    t.lost_check = t.signal_listened();
    if !t.refusals.is_empty() {
        return Err(t.refusals);
    }
    Ok(t.finish())
}

/// Every node that starts with its scope without a start event, in every process and
/// sub-process (`executive_engine::implicit_starts`, asked once per scope).
fn implicit_nodes(g: &ProcessGraph) -> BTreeSet<NodeId> {
    let scopes = (0..g.processes.len() as u32)
        .map(|p| Scope::Process(ProcessId(p)))
        .chain(
            (0..g.nodes.len() as u32)
                .map(NodeId)
                .filter(|n| matches!(g.node(*n).kind, NodeKind::SubProcess(_)))
                .map(Scope::SubProcess),
        );
    scopes
        .flat_map(|s| executive_engine::implicit_starts(g, s))
        .collect()
}

fn refusal(element: &str, reason: impl Into<String>) -> Refusal {
    Refusal {
        element: element.to_owned(),
        reason: reason.into(),
    }
}

impl<'g> Tr<'g> {
    fn nodes(&self, c: usize) -> Vec<NodeId> {
        self.nodes_of
            .get(&self.ctxs[c].process)
            .cloned()
            .unwrap_or_default()
    }

    /// Primary processes, then one context per call site (recursion refused).
    fn contexts(&mut self) {
        for p in self.g.primary_processes() {
            self.ctxs.push(Ctx {
                process: p,
                call: None,
                path: String::new(),
            });
        }
        let mut i = 0;
        while i < self.ctxs.len() {
            for n in self.nodes(i) {
                let node = self.g.node(n);
                if let NodeKind::CallActivity(ca) = &node.kind
                    && let Some(Called::Process(p)) = &ca.called
                {
                    let mut chain = Some(i);
                    let mut recursive = false;
                    while let Some(k) = chain {
                        recursive |= self.ctxs[k].process == *p;
                        chain = self.ctxs[k].call.map(|(pc, _)| pc);
                    }
                    if recursive {
                        self.refusals.push(refusal(
                            &node.id,
                            "a recursive call cannot be inlined (bound the recursion in the model)",
                        ));
                        continue;
                    }
                    let path = format!("{}{}/", self.ctxs[i].path, node.id);
                    self.ctxs.push(Ctx {
                        process: *p,
                        call: Some((i, n)),
                        path,
                    });
                }
            }
            i += 1;
        }
    }

    /// Indices for flows, activity slots and cycle counters in every context.
    fn slots(&mut self) {
        let handlers: BTreeSet<NodeId> = self
            .g
            .nodes
            .iter()
            .filter_map(|m| m.compensation_handler)
            .collect();
        // Activities without incoming flow start with their scope (implicit start).
        let implicit: BTreeSet<NodeId> = self
            .implicit
            .iter()
            .copied()
            .filter(|n| self.g.node(*n).is_activity())
            .collect();
        for c in 0..self.ctxs.len() {
            let nodes = self.nodes(c);
            let set: BTreeSet<NodeId> = nodes.iter().copied().collect();
            for (i, f) in self.g.flows.iter().enumerate() {
                if set.contains(&f.source) {
                    self.flow_ix
                        .insert((c, FlowId(i as u32)), self.flow_names.len());
                    self.flow_names
                        .push(format!("{}{}", self.ctxs[c].path, f.id));
                }
            }
            for &n in &nodes {
                let node = self.g.node(n);
                let opens =
                    matches!(node.scope, Scope::SubProcess(_)) || self.ctxs[c].call.is_some();
                if (matches!(node.kind, NodeKind::Start(_)) && opens)
                    || matches!(node.kind, NodeKind::Boundary(_))
                {
                    self.arrive_slot.insert((c, n), self.flow_names.len());
                    self.flow_names
                        .push(format!("{}{} (arrived)", self.ctxs[c].path, node.id));
                }
                let slot = match &node.kind {
                    NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_) => true,
                    NodeKind::Gateway(gw) => matches!(gw.kind, GatewayKind::EventBased { .. }),
                    // A compensation throw or a cancel end waits for the handlers it started.
                    NodeKind::Throw(defs) | NodeKind::End(defs) => defs.iter().any(|d| {
                        matches!(
                            d,
                            EventDefinition::Compensate { .. } | EventDefinition::Cancel
                        )
                    }),
                    _ => false,
                };
                if slot {
                    self.act_ix.insert((c, n), self.act_names.len());
                    self.act_names
                        .push(format!("{}{}", self.ctxs[c].path, node.id));
                }
                let decision = match &node.kind {
                    NodeKind::Gateway(_) | NodeKind::Boundary(_) => true,
                    _ => node.is_activity(),
                };
                if decision {
                    self.cnt_ix.insert((c, n), self.cnt_names.len());
                    self.cnt_names
                        .push(format!("{}{}", self.ctxs[c].path, node.id));
                }
                if self.compensable(n) {
                    self.comp_ix.insert((c, n), self.comp_names.len());
                    self.comp_names
                        .push(format!("{}{}", self.ctxs[c].path, node.id));
                }
                let handler =
                    (node.for_compensation && !is_event_sub(self.g, n)) || handlers.contains(&n);
                let asked = handler
                    || implicit.contains(&n)
                    || matches!(node.scope, Scope::SubProcess(e) if is_event_sub(self.g, e))
                        && matches!(node.kind, NodeKind::Start(_));
                if asked {
                    let k = self.pend_ix.len();
                    self.pend_ix.insert((c, n), k);
                }
                if self.ctxs[c].call.is_none() && self.event_start(n) {
                    let k = self.start_ix.len();
                    self.start_ix.insert((c, n), k);
                }
            }
        }
    }

    fn f(&self, c: usize, f: FlowId) -> usize {
        self.flow_ix[&(c, f)]
    }

    fn a(&self, c: usize, n: NodeId) -> usize {
        self.act_ix[&(c, n)]
    }

    fn marker(&mut self, c: usize, n: NodeId, phase: &str) -> String {
        let node = self.g.node(n);
        let path = self.ctxs[c].path.clone();
        let m = if phase.is_empty() {
            format!("{path}{}", node.id)
        } else {
            format!("{path}{}.{phase}", node.id)
        };
        self.steps.entry(m.clone()).or_insert(Step {
            element: node.id.clone(),
            name: node.label().to_owned(),
            path,
            phase: if phase.is_empty() {
                "pass".to_owned()
            } else {
                phase.to_owned()
            },
            activity: node.is_activity(),
        });
        m
    }

    /// Effects that count an element's completion for the requirements that observe it.
    fn observed(&self, element: &str, phase: &str) -> Vec<String> {
        let completes = !(phase == "start"
            || phase == "leave"
            || phase == "activate"
            || phase == "arm"
            || phase.starts_with("fail["));
        self.observe
            .iter()
            .enumerate()
            .filter_map(|(k, a)| match a {
                Atom::Done(n) if completes && self.g.node(*n).id == element => {
                    Some(format!("obs{k} = 1"))
                }
                Atom::Count(n, bound) if completes && self.g.node(*n).id == element => Some(
                    format!("if :: obs{k} < {bound} -> obs{k}++ :: else -> skip fi"),
                ),
                _ => None,
            })
            .collect()
    }

    fn push(&mut self, marker: &str, mut alt: Alt) {
        let guard = alt.guard.join(" && ");
        if alt.outside {
            alt.guard.insert(0, "QUIET".to_owned());
        } else if alt.throw {
            self.throwing.push(guard);
            alt.guard.push("!SETTLING".to_owned());
        } else if !guard.is_empty() {
            self.settling.push(guard);
        }
        if let Some(st) = self.steps.get(marker) {
            let more = self.observed(&st.element, &st.phase);
            alt.effect.extend(more);
        }
        let guard = if alt.guard.is_empty() {
            "true".to_owned()
        } else {
            alt.guard.join(" && ")
        };
        let mut line = format!(":: atomic {{ {guard} -> printf(\"@@BPMN {marker}\\n\")");
        for e in alt.effect {
            let _ = write!(line, "; {e}");
        }
        line.push_str(" }");
        self.alts.push(line);
    }

    fn put(&self, c: usize, f: FlowId, alt: &mut Alt) {
        alt.effect.push(format!("PUT({})", self.f(c, f)));
        let target = self.g.flow(f).target;
        if matches!(self.g.node(target).kind, NodeKind::Catch(_)) {
            alt.effect.extend(self.listening(target));
        }
    }

    /// Takes the token on flow `f` (the step needs it).
    fn take(&self, c: usize, f: FlowId, alt: &mut Alt) {
        let i = self.f(c, f);
        alt.guard.push(format!("ARRIVED({i})"));
        alt.effect.push(format!("tok[{i}]--; gen[{i}] = 0"));
    }

    fn put_all(&self, c: usize, flows: &[FlowId], alt: &mut Alt) {
        for f in flows {
            self.put(c, *f, alt);
        }
    }

    /// Bounds a choice that continues a cycle: at most `loops` times per scope activation.
    fn bound(&self, c: usize, decision: NodeId, alt: &mut Alt) {
        if let Some(k) = self.cnt_ix.get(&(c, decision)) {
            alt.guard.push(format!("reps[{k}] < {}", self.bounds.loops));
            alt.effect.push(format!("reps[{k}]++"));
        }
    }

    fn reaches(&self, from: NodeId, to: NodeId) -> bool {
        reaches(self.g, from, to)
    }

    /// Does any of `flows` lead back to `to`?
    fn leads_back(&self, flows: &[FlowId], to: NodeId) -> bool {
        flows
            .iter()
            .any(|f| self.reaches(self.g.flow(*f).target, to))
    }

    fn within(&self, n: NodeId, s: NodeId) -> bool {
        let mut scope = self.g.node(n).scope;
        loop {
            match scope {
                Scope::SubProcess(p) if p == s => return true,
                Scope::SubProcess(p) => scope = self.g.node(p).scope,
                Scope::Process(_) => return false,
            }
        }
    }

    /// Flows, activity slots and counters inside sub-process `s` (or everything of context
    /// `c` when `s` is `None`), including called processes inlined there.
    fn contents(&self, c: usize, s: Option<NodeId>) -> Inside {
        let mut inside = Inside::default();
        for n in self.nodes(c) {
            if s.is_some_and(|s| !self.within(n, s)) {
                continue;
            }
            let node = self.g.node(n);
            for f in &node.outgoing {
                inside.flows.push(self.f(c, *f));
            }
            if let Some(k) = self.arrive_slot.get(&(c, n)) {
                inside.flows.push(*k);
            }
            if let Some(a) = self.act_ix.get(&(c, n)) {
                inside.acts.push(*a);
            }
            if let Some(k) = self.cnt_ix.get(&(c, n)) {
                inside.cnts.push(*k);
            }
            if let Some(k) = self.comp_ix.get(&(c, n)) {
                inside.comps.push(*k);
            }
            if let Some(k) = self.pend_ix.get(&(c, n)) {
                inside.pends.push(*k);
            }
            if matches!(node.kind, NodeKind::CallActivity(_))
                && let Some(cc) = self.child(c, n)
            {
                let more = self.contents(cc, None);
                inside.flows.extend(more.flows);
                inside.acts.extend(more.acts);
                inside.cnts.extend(more.cnts);
                inside.comps.extend(more.comps);
                inside.pends.extend(more.pends);
            }
        }
        inside
    }

    fn child(&self, c: usize, call: NodeId) -> Option<usize> {
        self.ctxs.iter().position(|x| x.call == Some((c, call)))
    }

    /// Zeroes everything inside an activity (and the activity itself).
    fn cancel(&self, c: usize, activity: NodeId, alt: &mut Alt) {
        let inner = match &self.g.node(activity).kind {
            NodeKind::SubProcess(_) => Some(self.contents(c, Some(activity))),
            NodeKind::CallActivity(_) => self.child(c, activity).map(|cc| self.contents(cc, None)),
            _ => None,
        };
        if let Some(inside) = inner {
            self.clear(&inside, alt);
        }
        alt.effect.push(format!("act[{}] = 0", self.a(c, activity)));
    }

    /// Zeroes the flows and activity slots of `inside`.
    fn clear(&self, inside: &Inside, alt: &mut Alt) {
        alt.effect.extend(
            inside
                .flows
                .iter()
                .map(|f| format!("tok[{f}] = 0; gen[{f}] = 0")),
        );
        alt.effect
            .extend(inside.acts.iter().map(|a| format!("act[{a}] = 0")));
        alt.effect
            .extend(inside.pends.iter().map(|k| format!("pend[{k}] = 0")));
    }

    fn idle_inside(&self, c: usize, s: Option<NodeId>) -> String {
        let inside = self.contents(c, s);
        let mut parts: Vec<String> = inside
            .flows
            .iter()
            .map(|f| format!("tok[{f}] == 0"))
            .collect();
        parts.extend(inside.acts.iter().map(|a| format!("!act[{a}]")));
        parts.extend(inside.pends.iter().map(|k| format!("pend[{k}] == 0")));
        if parts.is_empty() {
            "true".to_owned()
        } else {
            format!("({})", parts.join(" && "))
        }
    }

    /// Counters and compensation marks inside a scope reset, as a new activation of it starts.
    fn reset(&self, c: usize, s: Option<NodeId>, alt: &mut Alt) {
        let inside = self.contents(c, s);
        alt.effect
            .extend(inside.cnts.iter().map(|k| format!("reps[{k}] = 0")));
        alt.effect
            .extend(inside.comps.iter().map(|k| format!("comp[{k}] = 0")));
    }

    /// `n` starts with its scope, having no incoming flow (the engine's implicit start).
    fn implicit(&self, n: NodeId) -> bool {
        self.implicit.contains(&n)
    }

    /// Asks for the activities of a scope that start with it (implicit start).
    fn start_implicit(&self, c: usize, s: Option<NodeId>, alt: &mut Alt) {
        let scope = match s {
            Some(s) => Scope::SubProcess(s),
            None => Scope::Process(self.ctxs[c].process),
        };
        for n in executive_engine::implicit_starts(self.g, scope) {
            if let Some(k) = self.pend_ix.get(&(c, n)) {
                alt.effect.push(format!("pend[{k}]++"));
            }
        }
    }

    /// Starts a scope's body: counters reset, none starts' outgoing flows marked, activities
    /// without incoming flow asked for.
    fn start_body(&mut self, c: usize, s: Option<NodeId>, alt: &mut Alt) {
        self.reset(c, s, alt);
        self.start_implicit(c, s, alt);
        let starts: Vec<NodeId> = self
            .nodes(c)
            .into_iter()
            .filter(|n| {
                let node = self.g.node(*n);
                let here = match s {
                    Some(s) => node.scope == Scope::SubProcess(s),
                    None => matches!(node.scope, Scope::Process(_)),
                };
                here && matches!(&node.kind, NodeKind::Start(st) if st.triggers.iter().all(|t| matches!(t, EventDefinition::Timer(_))))
            })
            .collect();
        for st in starts {
            self.arrive(c, st, alt);
        }
    }

    /// A token is put at event `n` (a start event as its scope opens, a boundary event as it
    /// fires): on its slot, to move on in the next wave. The first primary process's start,
    /// with nothing beside it, moves at once.
    fn arrive(&self, c: usize, n: NodeId, alt: &mut Alt) {
        match self.arrive_slot.get(&(c, n)) {
            Some(k) => alt.effect.push(format!("PUT({k})")),
            None => {
                let outs = self.g.node(n).outgoing.clone();
                self.put_all(c, &outs, alt);
            }
        }
    }

    /// The step of an event whose token arrived on its slot: it moves on.
    fn passes(&mut self, c: usize, n: NodeId) {
        let Some(k) = self.arrive_slot.get(&(c, n)).copied() else {
            return;
        };
        let m = self.marker(c, n, "leave");
        let mut alt = Alt::default();
        alt.guard.push(format!("ARRIVED({k})"));
        alt.effect.push(format!("tok[{k}]--; gen[{k}] = 0"));
        let outs = self.g.node(n).outgoing.clone();
        self.put_all(c, &outs, &mut alt);
        self.push(&m, alt);
    }

    // ----- catchers -----
}
