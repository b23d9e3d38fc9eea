//! BPMN → PROMELA: one global token marking (`tok[]` per sequence flow, `act[]` per running
//! activity or armed event-based gateway) and one guarded atomic step per BPMN transition, each
//! starting with a `@@BPMN <element>` marker so a Spin trail reads back as BPMN steps
//! (`../shared/design/verification.md` §2, scheme A).
//!
//! Abstractions: conditions are nondeterministic choices; timers, messages and conditional events
//! may fire whenever they are armed; a service task may fail with any error some boundary around
//! it catches. Every choice that continues a cycle (a gateway branch or a boundary that leads back
//! to where it came from) is bounded per scope activation, so every run is finite. Called
//! processes are inlined per call site. What the translation does not cover is refused with the
//! element named — never dropped.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write;

use executive_model::{
    BoundaryEvent, Called, EventDefinition, FlowId, GatewayKind, Looping, NodeId, NodeKind,
    ProcessGraph, ProcessId, Scope, SubProcessKind, TaskKind,
};
use serde::Serialize;

use crate::requirements::Atom;

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
    /// Per observed atom (in the order given), the PROMELA expression that reads it.
    pub atoms: Vec<String>,
}

/// Marking a flow in the safety model: a second token is an assertion violation (unsafe).
const SAFETY_PUT: &str = "#define PUT(f) assert(tok[f] == 0); tok[f] = 1";
/// Marking a flow in the LTL model: a second token only raises `unsafe`, so claims are judged
/// on their own.
const LTL_PUT: &str = "#define PUT(f) if :: tok[f] > 0 -> unsafe = 1 :: else -> tok[f] = 1 fi";

impl Translation {
    /// The model for LTL claims (same lines, flows marked without assertions).
    pub fn ltl_model(&self) -> String {
        self.promela.replacen(SAFETY_PUT, LTL_PUT, 1)
    }
}

/// A calling context: a primary process, or a called process inlined at one call site.
struct Ctx {
    process: ProcessId,
    call: Option<(usize, NodeId)>,
    path: String,
}

/// One guarded step.
#[derive(Default)]
struct Alt {
    guard: Vec<String>,
    effect: Vec<String>,
    /// Something outside answers (a system, the ground, time): it happens only once nothing
    /// inside can move, as the engine runs each step to quiescence.
    outside: bool,
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
    alts: Vec<String>,
    steps: BTreeMap<String, Step>,
    refusals: Vec<Refusal>,
    lost_check: bool,
    observe: Vec<Atom>,
    /// Tasks translated as one step (start and completion folded).
    folded: BTreeSet<NodeId>,
    /// Declared bounded variables.
    vars: crate::data::Variables,
}

/// The length of a node's timer, when it is a fixed duration.
pub(crate) fn fixed_duration(node: &executive_model::Node) -> Option<u64> {
    let defs: &[EventDefinition] = match &node.kind {
        NodeKind::Boundary(b) => &b.triggers,
        NodeKind::Catch(c) => &c.triggers,
        _ => return None,
    };
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

fn me_signals(g: &ProcessGraph) -> usize {
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
        alts: Vec::new(),
        steps: BTreeMap::new(),
        refusals: Vec::new(),
        lost_check: false,
        observe: observe.to_vec(),
        folded: BTreeSet::new(),
        vars: vars.clone(),
    };
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        t.nodes_of.entry(g.process_of(id)).or_default().push(id);
        let _ = n;
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
                let slot = match &node.kind {
                    NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_) => true,
                    NodeKind::Gateway(gw) => matches!(gw.kind, GatewayKind::EventBased { .. }),
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
            }
        }
    }

    fn refuse_unsupported(&mut self) {
        let g = self.g;
        for n in g.nodes.iter() {
            let no = |r: &str| refusal(&n.id, r);
            let bad = match &n.kind {
                NodeKind::Start(s) => {
                    let in_event_sub = matches!(n.scope, Scope::SubProcess(p)
                        if matches!(&g.node(p).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event)));
                    if in_event_sub {
                        None // refused with its event sub-process
                    } else if s
                        .triggers
                        .iter()
                        .any(|t| !matches!(t, EventDefinition::Timer(_)))
                    {
                        Some(no("start events triggered by messages, signals or conditions are not translated (a none or timer start is)"))
                    } else {
                        None
                    }
                }
                NodeKind::End(defs) => defs
                    .iter()
                    .find(|d| {
                        matches!(
                            d,
                            EventDefinition::Cancel
                                | EventDefinition::Compensate { .. }
                                | EventDefinition::Link(_)
                        )
                    })
                    .map(|d| no(&format!("{} on an end event is not translated", d.element_name()))),
                NodeKind::Throw(defs) => defs
                    .iter()
                    .find(|d| matches!(d, EventDefinition::Compensate { .. } | EventDefinition::Link(_)))
                    .map(|d| no(&format!("{} on a throw event is not translated", d.element_name()))),
                NodeKind::Catch(c) if c.parallel_multiple => Some(no(
                    "parallel-multiple catch events (every trigger needed) are not translated",
                )),
                NodeKind::Catch(c) => c
                    .triggers
                    .iter()
                    .find(|d| matches!(d, EventDefinition::Link(_) | EventDefinition::Error { .. } | EventDefinition::Escalation(_) | EventDefinition::Compensate { .. }))
                    .map(|d| no(&format!("{} on a catch event is not translated", d.element_name()))),
                NodeKind::Boundary(b) => {
                    if b.parallel_multiple {
                        Some(no("parallel-multiple boundary events are not translated"))
                    } else if !b.interrupting {
                        Some(no("non-interrupting boundary events are not translated yet"))
                    } else if b.triggers.iter().any(|d| {
                        matches!(d, EventDefinition::Compensate { .. } | EventDefinition::Cancel)
                    }) {
                        Some(no("compensation and cancel boundaries are not translated"))
                    } else {
                        None
                    }
                }
                NodeKind::Gateway(gw) => match gw.kind {
                    GatewayKind::Complex => Some(no("complex gateways are not translated")),
                    GatewayKind::EventBased { .. } if gw.instantiate => {
                        Some(no("instantiating event-based gateways are not translated"))
                    }
                    GatewayKind::EventBased { .. } => n
                        .outgoing
                        .iter()
                        .map(|f| g.node(g.flow(*f).target))
                        .find(|t| !matches!(t.kind, NodeKind::Catch(_)))
                        .map(|t| {
                            refusal(
                                &t.id,
                                "an event-based gateway leading to a receive task is not translated",
                            )
                        }),
                    GatewayKind::Inclusive
                        if n.incoming.len() > 1 && n.outgoing.len() > 1 =>
                    {
                        Some(no("an inclusive gateway that both joins and splits is not translated (split it in two)"))
                    }
                    GatewayKind::Inclusive if n.outgoing.len() > 6 => {
                        Some(no("an inclusive split with more than 6 outgoing flows is not translated"))
                    }
                    _ => None,
                },
                NodeKind::SubProcess(s) => match s.kind {
                    SubProcessKind::Embedded => None,
                    SubProcessKind::Event => Some(no("event sub-processes are not translated yet")),
                    SubProcessKind::Transaction => Some(no("transactions are not translated")),
                    SubProcessKind::AdHoc { .. } => Some(no("ad-hoc sub-processes are not translated")),
                },
                NodeKind::CallActivity(c) if c.called.is_none() => {
                    Some(no("the called element is not in the model"))
                }
                _ => None,
            };
            if let Some(r) = bad {
                self.refusals.push(r);
                continue;
            }
            if n.is_activity() {
                if n.for_compensation || n.compensation_handler.is_some() {
                    self.refusals.push(no("compensation is not translated"));
                } else if n.start_quantity != 1 || n.completion_quantity != 1 {
                    self.refusals.push(no(
                        "start or completion quantities other than 1 are not translated",
                    ));
                } else if let Some(Looping::MultiInstance(mi)) = &n.looping
                    && mi.behavior != executive_model::MiBehavior::All
                {
                    self.refusals.push(no(
                        "multi-instance behaviours that throw events (None, One, Complex) are not translated",
                    ));
                } else if let Some(Looping::MultiInstance(mi)) = &n.looping
                    && !mi.sequential
                {
                    self.refusals.push(no(
                        "parallel multi-instance is not translated (sequential is, as a bounded loop)",
                    ));
                } else if n.outgoing.iter().any(|f| g.flow(*f).condition.is_some()) {
                    self.refusals.push(no(
                        "conditional sequence flows leaving an activity are not translated (use a gateway)",
                    ));
                }
                if let NodeKind::SubProcess(s) = &n.kind
                    && matches!(s.kind, SubProcessKind::Embedded)
                    && !s.nodes.iter().any(|m| {
                        matches!(&g.node(*m).kind, NodeKind::Start(st) if st.triggers.is_empty())
                    })
                {
                    self.refusals
                        .push(no("a sub-process without a none start event is not translated"));
                }
            }
            if let NodeKind::Task(t) = &n.kind
                && t.kind == TaskKind::Receive
                && t.instantiate
            {
                self.refusals
                    .push(no("instantiating receive tasks are not translated"));
            }
        }
        for c in &self.g.collaborations {
            if let Some(m) = c.message_flows.first() {
                self.refusals.push(refusal(
                    &m.id,
                    "message flows between pools are not translated yet",
                ));
            }
        }
    }

    // ----- names and slots -----

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
        if alt.outside {
            alt.guard.insert(0, "QUIET".to_owned());
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

    fn put_all(&self, c: usize, flows: &[FlowId], alt: &mut Alt) {
        for f in flows {
            self.put(c, *f, alt);
        }
    }

    /// The node's work is done outside the executive (a system, the ground): a task other
    /// than a script task, or a call of a global task.
    fn outside(&self, n: NodeId) -> bool {
        match &self.g.node(n).kind {
            NodeKind::Task(t) => t.kind != TaskKind::Script,
            NodeKind::CallActivity(ca) => match &ca.called {
                Some(Called::GlobalTask(id)) => self
                    .g
                    .global_tasks
                    .get(id)
                    .is_some_and(|t| t.kind != TaskKind::Script),
                _ => false,
            },
            _ => false,
        }
    }

    /// A token on a flow into `n` waits there (for an event, the other branches of a join,
    /// or a system running a task folded into one step) rather than moving on in the step.
    fn waits_at(&self, n: NodeId) -> bool {
        let node = self.g.node(n);
        match &node.kind {
            NodeKind::Catch(_) => true,
            NodeKind::Gateway(gw) => {
                node.incoming.len() > 1
                    && matches!(gw.kind, GatewayKind::Parallel | GatewayKind::Inclusive)
            }
            NodeKind::Task(_) | NodeKind::CallActivity(_) => {
                self.outside(n) && self.folded.contains(&n)
            }
            _ => false,
        }
    }

    /// Nothing inside can move: every token waits, no scope is done but not yet left.
    fn quiet(&self) -> String {
        let mut parts = Vec::new();
        for ((c, f), i) in &self.flow_ix {
            if !self.waits_at(self.g.flow(*f).target) {
                let _ = c;
                parts.push(format!("tok[{i}] == 0"));
            }
        }
        parts.sort();
        for ((c, n), a) in &self.act_ix {
            let scope = match &self.g.node(*n).kind {
                NodeKind::SubProcess(_) => Some((*c, Some(*n))),
                NodeKind::CallActivity(_) => self.child(*c, *n).map(|cc| (cc, None)),
                _ => None,
            };
            if let Some((bc, s)) = scope {
                parts.push(format!("!(act[{a}] && {})", self.idle_inside(bc, s)));
            }
        }
        if parts.is_empty() {
            "true".to_owned()
        } else {
            parts.join(" && ")
        }
    }

    /// Checks run when `n` starts listening: a signal it catches that was thrown with nobody
    /// listening was thrown too early, and is lost.
    fn listening(&self, n: NodeId) -> Vec<String> {
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

    /// Bounds a choice that continues a cycle: at most `loops` times per scope activation.
    fn bound(&self, c: usize, decision: NodeId, alt: &mut Alt) {
        if let Some(k) = self.cnt_ix.get(&(c, decision)) {
            alt.guard.push(format!("reps[{k}] < {}", self.bounds.loops));
            alt.effect.push(format!("reps[{k}]++"));
        }
    }

    /// Can `from` reach `to` along sequence flows and attached boundaries (same process)?
    fn reaches(&self, from: NodeId, to: NodeId) -> bool {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from];
        while let Some(n) = stack.pop() {
            if n == to {
                return true;
            }
            if !seen.insert(n) {
                continue;
            }
            let node = self.g.node(n);
            stack.extend(node.outgoing.iter().map(|f| self.g.flow(*f).target));
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

    /// An exclusive split decided by declared data: each outgoing flow with its exact guard
    /// (the first condition that holds, in order; the default when none does). `None` when a
    /// condition reads anything undeclared.
    fn data_guards(&self, n: NodeId) -> Option<Vec<(FlowId, String)>> {
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
                Some(c) => crate::data::expression(&c.text, &self.vars)?,
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
    fn data_effects(&self, n: NodeId) -> Vec<String> {
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
                            crate::data::expression(&e.text, &self.vars),
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
    fn contents(&self, c: usize, s: Option<NodeId>) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
        let (mut flows, mut acts, mut cnts) = (Vec::new(), Vec::new(), Vec::new());
        for n in self.nodes(c) {
            if s.is_some_and(|s| !self.within(n, s)) {
                continue;
            }
            let node = self.g.node(n);
            for f in &node.outgoing {
                flows.push(self.f(c, *f));
            }
            if let Some(a) = self.act_ix.get(&(c, n)) {
                acts.push(*a);
            }
            if let Some(k) = self.cnt_ix.get(&(c, n)) {
                cnts.push(*k);
            }
            if matches!(node.kind, NodeKind::CallActivity(_))
                && let Some(cc) = self.child(c, n)
            {
                let (f2, a2, k2) = self.contents(cc, None);
                flows.extend(f2);
                acts.extend(a2);
                cnts.extend(k2);
            }
        }
        (flows, acts, cnts)
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
        if let Some((flows, acts, _)) = inner {
            alt.effect
                .extend(flows.iter().map(|f| format!("tok[{f}] = 0")));
            alt.effect
                .extend(acts.iter().map(|a| format!("act[{a}] = 0")));
        }
        alt.effect.push(format!("act[{}] = 0", self.a(c, activity)));
    }

    fn idle_inside(&self, c: usize, s: Option<NodeId>) -> String {
        let (flows, acts, _) = self.contents(c, s);
        let mut parts: Vec<String> = flows.iter().map(|f| format!("tok[{f}] == 0")).collect();
        parts.extend(acts.iter().map(|a| format!("!act[{a}]")));
        if parts.is_empty() {
            "true".to_owned()
        } else {
            format!("({})", parts.join(" && "))
        }
    }

    /// Starts a scope's body: counters reset, none starts' outgoing flows marked.
    fn start_body(&mut self, c: usize, s: Option<NodeId>, alt: &mut Alt) {
        let (_, _, cnts) = self.contents(c, s);
        alt.effect
            .extend(cnts.iter().map(|k| format!("reps[{k}] = 0")));
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
            let outs = self.g.node(st).outgoing.clone();
            self.put_all(c, &outs, alt);
        }
    }

    // ----- catchers -----

    /// The boundary that catches a throw from node `n` in context `c`: the innermost enclosing
    /// activity (sub-process, or call activity in a calling context) with a matching boundary.
    fn catcher(
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

    fn error_matches(&self, thrown: Option<executive_model::ErrorId>, be: &BoundaryEvent) -> bool {
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

    fn escalation_matches(
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
    fn caught(&mut self, c: usize, holder: NodeId, b: NodeId, alt: &mut Alt) {
        self.cancel(c, holder, alt);
        let outs = self.g.node(b).outgoing.clone();
        self.put_all(c, &outs, alt);
        let m = self.marker(c, b, "fire");
        alt.effect.push(format!("printf(\"@@BPMN {m}\\n\")"));
        let id = self.g.node(b).id.clone();
        alt.effect.extend(self.observed(&id, "fire"));
    }

    /// A signal thrown: every listener armed now hears it, in one step; none → lost.
    fn broadcast(&mut self, signal: Option<executive_model::SignalId>, alt: &mut Alt) {
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
    fn error_observed(&self, code: Option<&str>) -> Vec<String> {
        self.observe
            .iter()
            .enumerate()
            .filter(|(_, a)| matches!(a, Atom::Error(x) if code.is_none_or(|c| c == x)))
            .map(|(k, _)| format!("err{k} = 1"))
            .collect()
    }

    fn signal_listened(&self) -> bool {
        self.alts.iter().any(|a| a.contains("unheard["))
    }

    /// What a throw (intermediate or end) does besides consuming its token; `false` when the
    /// token's path ends there (caught by an interrupting boundary, or a failure).
    fn throw(&mut self, c: usize, n: NodeId, defs: &[EventDefinition], alt: &mut Alt) -> bool {
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
                        self.caught(cc, holder, b, alt);
                        go_on = false;
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

    fn node(&mut self, c: usize, n: NodeId) {
        let node = self.g.node(n);
        let (ins, outs) = (node.incoming.clone(), node.outgoing.clone());
        match &node.kind {
            NodeKind::Start(_) | NodeKind::Boundary(_) => {}
            NodeKind::End(defs) => {
                for f in ins {
                    let m = self.marker(c, n, "end");
                    let mut alt = Alt::default();
                    alt.guard.push(format!("tok[{}] > 0", self.f(c, f)));
                    alt.effect.push(format!("tok[{}]--", self.f(c, f)));
                    self.throw(c, n, defs, &mut alt);
                    self.push(&m, alt);
                }
            }
            NodeKind::Throw(defs) => {
                for f in ins {
                    let m = self.marker(c, n, "");
                    let mut alt = Alt::default();
                    alt.guard.push(format!("tok[{}] > 0", self.f(c, f)));
                    alt.effect.push(format!("tok[{}]--", self.f(c, f)));
                    if self.throw(c, n, defs, &mut alt) {
                        self.put_all(c, &outs, &mut alt);
                    }
                    self.push(&m, alt);
                }
            }
            NodeKind::Catch(ce) => {
                let signal_only = ce
                    .triggers
                    .iter()
                    .all(|t| matches!(t, EventDefinition::Signal(_)));
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
                        alt.guard.push(format!("tok[{}] > 0", self.f(c, f)));
                        alt.effect.push(format!("tok[{}]--", self.f(c, f)));
                    }
                    self.put_all(c, &outs, &mut alt);
                    self.push(&m, alt);
                }
            }
            NodeKind::Gateway(gw) => self.gateway(c, n, gw.kind, &ins, &outs),
            NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_) => {
                self.activity(c, n, &ins, &outs)
            }
        }
    }

    fn gateway(&mut self, c: usize, n: NodeId, kind: GatewayKind, ins: &[FlowId], outs: &[FlowId]) {
        let cyclic = |t: &Self, f: FlowId| t.reaches(t.g.flow(f).target, n);
        match kind {
            GatewayKind::Parallel => {
                let m = self.marker(c, n, "");
                let mut alt = Alt::default();
                for f in ins {
                    let i = self.f(c, *f);
                    alt.guard.push(format!("tok[{i}] > 0"));
                    alt.effect.push(format!("tok[{i}]--"));
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
                        let i = self.f(c, *fi);
                        alt.guard.push(format!("tok[{i}] > 0"));
                        alt.guard.push(guard.clone());
                        alt.effect.push(format!("tok[{i}]--"));
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
                        let i = self.f(c, *fi);
                        alt.guard.push(format!("tok[{i}] > 0"));
                        alt.effect.push(format!("tok[{i}]--"));
                        if Some(*fo) != free && cyclic(self, *fo) {
                            self.bound(c, n, &mut alt);
                        }
                        self.put(c, *fo, &mut alt);
                        self.push(&m, alt);
                    }
                    if outs.is_empty() {
                        let m = self.marker(c, n, "");
                        let mut alt = Alt::default();
                        let i = self.f(c, *fi);
                        alt.guard.push(format!("tok[{i}] > 0"));
                        alt.effect.push(format!("tok[{i}]--"));
                        self.push(&m, alt);
                    }
                }
            }
            GatewayKind::Inclusive if ins.len() > 1 => {
                // Non-local join: fire when some incoming flow is marked and no token can still
                // arrive on the empty ones (nothing upstream of them is marked).
                let m = self.marker(c, n, "join");
                let mut alt = Alt::default();
                let marked: Vec<String> = ins
                    .iter()
                    .map(|f| format!("tok[{}] > 0", self.f(c, *f)))
                    .collect();
                alt.guard.push(format!("({})", marked.join(" || ")));
                for f in ins {
                    let i = self.f(c, *f);
                    let (flows, acts) = self.upstream(c, *f, n);
                    let mut empty: Vec<String> =
                        flows.iter().map(|u| format!("tok[{u}] == 0")).collect();
                    empty.extend(acts.iter().map(|a| format!("!act[{a}]")));
                    if !empty.is_empty() {
                        alt.guard
                            .push(format!("(tok[{i}] > 0 || ({}))", empty.join(" && ")));
                    }
                    alt.effect.push(format!(
                        "if :: tok[{i}] > 0 -> tok[{i}]-- :: else -> skip fi"
                    ));
                }
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
                    let i = self.f(c, fi);
                    alt.guard.push(format!("tok[{i}] > 0"));
                    alt.effect.push(format!("tok[{i}]--"));
                    if (exit || !single) && chosen.iter().any(|f| cyclic(self, *f)) {
                        self.bound(c, n, &mut alt);
                    }
                    self.put_all(c, &chosen, &mut alt);
                    self.push(&m, alt);
                }
            }
            GatewayKind::EventBased { .. } => {
                for fi in ins {
                    let m = self.marker(c, n, "arm");
                    let mut alt = Alt::default();
                    let i = self.f(c, *fi);
                    alt.guard.push(format!("tok[{i}] > 0"));
                    alt.effect.push(format!("tok[{i}]--"));
                    alt.effect.push(format!("act[{}] = 1", self.a(c, n)));
                    alt.effect.extend(self.listening(n));
                    self.push(&m, alt);
                }
            }
        }
    }

    /// Flows and activity slots from which `flow` can still receive a token, not passing
    /// through the join `join` (static, like fbpmn's `PreEdges`).
    fn upstream(&self, c: usize, flow: FlowId, join: NodeId) -> (BTreeSet<usize>, BTreeSet<usize>) {
        let (mut flows, mut acts) = (BTreeSet::new(), BTreeSet::new());
        let mut seen = BTreeSet::new();
        let mut stack = vec![self.g.flow(flow).source];
        while let Some(n) = stack.pop() {
            if n == join || !seen.insert(n) {
                continue;
            }
            let node = self.g.node(n);
            if let Some(a) = self.act_ix.get(&(c, n)) {
                acts.insert(*a);
            }
            for f in &node.incoming {
                flows.insert(self.f(c, *f));
                stack.push(self.g.flow(*f).source);
            }
            if let NodeKind::Boundary(b) = &node.kind {
                stack.push(b.attached_to);
            }
        }
        (flows, acts)
    }

    fn activity(&mut self, c: usize, n: NodeId, ins: &[FlowId], outs: &[FlowId]) {
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
        let fails = match &node.kind {
            NodeKind::Task(t) => !matches!(t.kind, TaskKind::User | TaskKind::Script),
            NodeKind::CallActivity(_) => self.outside(n),
            _ => false,
        };
        let mut catchers = Vec::new();
        if fails {
            for b in &node.boundaries {
                if let NodeKind::Boundary(be) = &self.g.node(*b).kind
                    && be
                        .triggers
                        .iter()
                        .any(|t| matches!(t, EventDefinition::Error { .. }))
                {
                    catchers.push((c, n, *b));
                }
            }
            let mut probe = (c, n);
            while let Some(found) = self.catcher(probe.0, probe.1, &|be| {
                be.triggers
                    .iter()
                    .any(|t| matches!(t, EventDefinition::Error { .. }))
            }) {
                catchers.push(found);
                probe = (found.0, found.1);
            }
        }
        // A task nothing can interrupt is one step (start and completion folded: fewer
        // interleavings, the same reachable markings between steps).
        if body.is_none()
            && node.boundaries.is_empty()
            && node.looping.is_none()
            && catchers.is_empty()
            && !self.observe.contains(&Atom::Running(n))
        {
            self.folded.insert(n);
            for f in ins {
                let m = self.marker(c, n, "run");
                let mut alt = Alt {
                    outside: self.outside(n),
                    ..Alt::default()
                };
                let i = self.f(c, *f);
                alt.guard.push(format!("tok[{i}] > 0"));
                alt.effect.push(format!("tok[{i}]--"));
                alt.effect.extend(self.data_effects(n));
                self.put_all(c, outs, &mut alt);
                self.push(&m, alt);
            }
            return;
        }
        // Start (or activate).
        for f in ins {
            let phase = if body.is_some() { "activate" } else { "start" };
            let m = self.marker(c, n, phase);
            let mut alt = Alt::default();
            let i = self.f(c, *f);
            alt.guard.push(format!("tok[{i}] > 0"));
            alt.effect.push(format!("tok[{i}]--"));
            alt.effect.push(format!("act[{a}] = 1"));
            alt.effect.extend(self.listening(n));
            // A loop's bodies are counted per start of the loop.
            if node.looping.is_some()
                && let Some(k) = self.cnt_ix.get(&(c, n))
            {
                alt.effect.push(format!("reps[{k}] = 0"));
            }
            if let Some(scope) = body {
                self.start_body(body_ctx, scope, &mut alt);
            }
            self.push(&m, alt);
        }
        // Completion: a task whenever the system answers; a scope once nothing runs inside.
        let done_guard = match body {
            Some(scope) => format!("act[{a}] && {}", self.idle_inside(body_ctx, scope)),
            None => format!("act[{a}]"),
        };
        if node.looping.is_some() {
            let m = self.marker(c, n, "repeat");
            let mut alt = Alt {
                outside: body.is_none() && self.outside(n),
                ..Alt::default()
            };
            alt.guard.push(done_guard.clone());
            self.bound(c, n, &mut alt);
            if let Some(scope) = body {
                self.start_body(body_ctx, scope, &mut alt);
            }
            self.push(&m, alt);
        }
        // The ways out of a running activity (completion, a caught failure, a boundary event):
        // those that lead back to it are bounded, except completion when every way leads
        // back (so the activity can always end).
        let spontaneous: Vec<NodeId> = node
            .boundaries
            .iter()
            .copied()
            .filter(|b| match &self.g.node(*b).kind {
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
            .collect();
        let back = |t: &Self, b: NodeId, to: NodeId| t.leads_back(&t.g.node(b).outgoing, to);
        let completes_back = self.leads_back(outs, n);
        let exit = !completes_back
            || catchers.iter().any(|(_, h, b)| !back(self, *b, *h))
            || spontaneous.iter().any(|b| !back(self, *b, n));
        let choices = !catchers.is_empty() || !spontaneous.is_empty();
        let m = self.marker(c, n, "complete");
        let mut alt = Alt {
            outside: body.is_none() && self.outside(n),
            ..Alt::default()
        };
        if choices && exit && completes_back {
            // Another way out leaves the cycle.
            self.bound(c, n, &mut alt);
        }
        alt.guard.push(done_guard);
        alt.effect.push(format!("act[{a}] = 0"));
        alt.effect.extend(self.data_effects(n));
        self.put_all(c, outs, &mut alt);
        self.push(&m, alt);
        // A system's failure, caught by a boundary here or around.
        {
            for (cc, holder, b) in catchers {
                let m = self.marker(c, n, &format!("fail[{}]", self.g.node(b).id));
                let mut alt = Alt {
                    outside: true,
                    ..Alt::default()
                };
                alt.guard.push(format!("act[{a}]"));
                if back(self, b, holder) {
                    self.bound(cc, b, &mut alt);
                }
                alt.effect.push(format!("act[{a}] = 0"));
                let code = match &self.g.node(b).kind {
                    NodeKind::Boundary(be) => be.triggers.iter().find_map(|t| match t {
                        EventDefinition::Error { error, .. } => {
                            Some(error.and_then(|e| self.g.errors[e.index()].code.clone()))
                        }
                        _ => None,
                    }),
                    _ => None,
                }
                .flatten();
                alt.effect.extend(self.error_observed(code.as_deref()));
                self.caught(cc, holder, b, &mut alt);
                self.push(&m, alt);
            }
        }
        // Timers, messages and conditions on the boundary may fire while the activity runs.
        // Timers armed together fire in the order of their durations: a longer one on the same
        // activity never fires while a shorter interrupting one is armed with it.
        let shortest = spontaneous
            .iter()
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
            if back(self, b, n) {
                self.bound(c, b, &mut alt);
            }
            self.cancel(c, n, &mut alt);
            let outs = self.g.node(b).outgoing.clone();
            self.put_all(c, &outs, &mut alt);
            self.push(&m, alt);
        }
    }

    fn finish(self) -> Translation {
        let mut p = String::new();
        let nf = self.flow_names.len().max(1);
        let na = self.act_names.len().max(1);
        let nc = self.cnt_names.len().max(1);
        let _ = writeln!(
            p,
            "/* Generated by trace verify from the BPMN model: one global marking, one atomic step per BPMN transition. */"
        );
        let _ = writeln!(p, "/* Flows (tok[]): */");
        for (i, f) in self.flow_names.iter().enumerate() {
            let _ = writeln!(p, "/*   {i:>4} {f} */");
        }
        let _ = writeln!(p, "/* Activities and armed gateways (act[]): */");
        for (i, a) in self.act_names.iter().enumerate() {
            let _ = writeln!(p, "/*   {i:>4} {a} */");
        }
        let _ = writeln!(p, "byte tok[{nf}];\nbool act[{na}];\nbyte reps[{nc}];");
        let _ = writeln!(p, "bool heard, lost, unsafe, failed, terminated, ended;");
        let _ = writeln!(p, "bool unheard[{}];", me_signals(self.g));
        p.push_str(&crate::data::declarations(&self.vars));
        // The executive starts the primary processes one after another, each running until it
        // waits, before anything from outside is heard.
        let primaries = self.ctxs.iter().filter(|c| c.call.is_none()).count();
        let _ = writeln!(p, "byte started = 1;");
        let _ = writeln!(p, "#define MOVED ({})", self.quiet());
        let _ = writeln!(p, "#define QUIET (started == {primaries} && MOVED)");
        let mut atoms = Vec::new();
        for (k, a) in self.observe.iter().enumerate() {
            match a {
                Atom::Done(_) => {
                    let _ = writeln!(p, "bool obs{k};");
                    atoms.push(format!("obs{k}"));
                }
                Atom::Count(..) => {
                    let _ = writeln!(p, "byte obs{k};");
                    atoms.push(format!("obs{k}"));
                }
                Atom::Signal(_) => {
                    let _ = writeln!(p, "bool sig{k};");
                    atoms.push(format!("sig{k}"));
                }
                Atom::Error(_) => {
                    let _ = writeln!(p, "bool err{k};");
                    atoms.push(format!("err{k}"));
                }
                Atom::Running(n) => {
                    let slots: Vec<String> = self
                        .act_ix
                        .iter()
                        .filter(|((_, m), _)| m == n)
                        .map(|(_, i)| format!("act[{i}]"))
                        .collect();
                    atoms.push(if slots.is_empty() {
                        "false".to_owned()
                    } else {
                        format!("({})", slots.join(" || "))
                    });
                }
            }
        }
        let _ = writeln!(p, "{SAFETY_PUT}");
        let mut idle: Vec<String> = (0..self.flow_names.len())
            .map(|i| format!("tok[{i}] == 0"))
            .collect();
        idle.extend((0..self.act_names.len()).map(|i| format!("!act[{i}]")));
        let idle = if idle.is_empty() {
            "true".to_owned()
        } else {
            idle.join(" && ")
        };
        let _ = writeln!(p, "#define IDLE ({idle})");
        let mut clear: Vec<String> = (0..self.flow_names.len())
            .map(|i| format!("tok[{i}] = 0"))
            .collect();
        clear.extend((0..self.act_names.len()).map(|i| format!("act[{i}] = 0")));
        let _ = writeln!(
            p,
            "#define CLEAR_ALL {}",
            if clear.is_empty() {
                "skip".to_owned()
            } else {
                clear.join("; ")
            }
        );
        let _ = writeln!(p, "active proctype Mission() {{");
        // Initial marking: the first primary process's none (or timer) starts; the next ones
        // start in turn once everything before them waits.
        let mut me = self;
        let firsts: Vec<usize> = (0..me.ctxs.len())
            .filter(|c| me.ctxs[*c].call.is_none())
            .collect();
        let mut later = Vec::new();
        for (k, c) in firsts.iter().enumerate() {
            let mut init = Alt::default();
            me.start_body(*c, None, &mut init);
            let e = init.effect.join("; ");
            let e = if e.is_empty() { "skip".to_owned() } else { e };
            if k == 0 {
                let _ = writeln!(p, "  atomic {{ printf(\"@@BPMN start\\n\"); {e} }};");
            } else {
                let id = me.g.process(me.ctxs[*c].process).id.clone();
                later.push(format!(
                    ":: atomic {{ started == {k} && MOVED -> printf(\"@@BPMN start {id}\\n\"); started++; {e} }}"
                ));
            }
        }
        me.alts.extend(later);
        let _ = writeln!(p, "  do");
        let mut lines = BTreeMap::new();
        for a in &me.alts {
            if let Some(m) = a.split("@@BPMN ").nth(1).and_then(|r| r.split('\\').next()) {
                lines.insert(p.lines().count() + 1, m.to_owned());
            }
            let _ = writeln!(p, "  {a}");
        }
        let _ = writeln!(
            p,
            "  :: started == {primaries} && IDLE -> break\n  od;\n  ended = 1;\n  printf(\"@@BPMN ended\\n\")\n}}"
        );
        let activities = me
            .steps
            .values()
            .filter(|s| s.activity)
            .map(|s| (format!("{}{}", s.path, s.element), s.name.clone()))
            .collect();
        Translation {
            promela: p,
            steps: me.steps,
            activities,
            signals: me.lost_check,
            lines,
            atoms,
        }
    }
}
