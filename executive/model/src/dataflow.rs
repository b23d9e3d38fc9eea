//! Data flow before flight: is every variable an expression reads written before it?
//!
//! The rule (`docs/engine-semantics.md`, "Variables before flight"): a name an expression reads
//! must hold a value when the expression is evaluated, on every path of tokens that reaches
//! it. CEL fails on a name that has none ("undeclared reference"); FEEL reads it as null.
//!
//! Two analyses run over one graph of the model's control flow, to a fixed point:
//! - **may**: the names some path may have written (union where paths meet). A name outside it
//!   is read on no path ([`Finding::Unwritten`]). It over-approximates wherever the model
//!   leaves the order open, so that it never calls a written name unwritten: an event
//!   sub-process may run at any time in its scope, a boundary event may interrupt an activity
//!   after anything inside it ran, a compensation handler runs after anything in its process,
//!   and a write this analysis cannot name (a message's payload, a task's result of unknown
//!   fields, a script in a foreign language) may write any name.
//! - **must**: the names every path has written (intersection where paths meet; union at a
//!   parallel join, which all its branches reach). A name in *may* but not in *must* is read
//!   on some paths only ([`Finding::Sometimes`]).
//!
//! Written means: an output mapping's target, a script's assignment, a data output
//! association, a multi-instance output collection, a caught error's code or message
//! variable, a call activity's outputs, a message's payload (signals carry none), a dispatched
//! task's result (every field, when the task maps none), a declared data object or property,
//! the process's start variables, and the engine's own (`loopCounter`, `nrOfInstances`, … inside a loop, the
//! multi-instance element variable). System data (the connectors' telemetry) is read by name
//! too; the caller knows which names it has.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use crate::graph::*;
use crate::{Expression, Program};

mod access;
use access::*;

/// What the analysis is told from outside the model.
pub struct Context<'a> {
    /// Start variables given to every primary process (besides the declared ones).
    pub start: &'a BTreeSet<String>,
    /// A dispatched task's result fields (top-level names), when its catalogue is known;
    /// `None` means any name.
    pub results: &'a dyn Fn(NodeId) -> Option<Vec<String>>,
}

/// Where an expression is read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Site {
    /// A node's expression (input, condition of an event, script, loop, …).
    Node(NodeId),
    /// A sequence flow's condition.
    Flow(FlowId),
}

/// A read that is not always preceded by a write.
#[derive(Clone, Debug)]
pub enum Finding {
    /// No path writes the name before it is read.
    Unwritten {
        /// Where it is read.
        site: Site,
        /// The name.
        var: String,
        /// The expression that reads it.
        expression: String,
        /// The expression is FEEL (which reads a missing name as null instead of failing).
        feel: bool,
        /// The node nearest to the read that writes the name, but not before it.
        writer: Option<NodeId>,
    },
    /// Some paths reach the read without writing the name.
    Sometimes {
        /// Where it is read.
        site: Site,
        /// The name.
        var: String,
        /// The expression that reads it.
        expression: String,
        /// The expression is FEEL.
        feel: bool,
        /// One path from the start that reaches the read without writing it.
        path: Vec<NodeId>,
    },
}

impl Finding {
    /// The name read.
    pub fn var(&self) -> &str {
        match self {
            Finding::Unwritten { var, .. } | Finding::Sometimes { var, .. } => var,
        }
    }
}

/// The names the engine itself defines inside a loop or multi-instance activity.
pub const LOOP_VARIABLES: [&str; 4] = [
    "loopCounter",
    "nrOfInstances",
    "nrOfActiveInstances",
    "nrOfCompletedInstances",
];

thread_local! {
    /// The names of the analysis under way, numbered: sets of names are bit sets over them
    /// (a model of ten thousand tasks has as many names; sets of strings per vertex would not
    /// fit in memory). Reset by each analysis.
    static NAMES: std::cell::RefCell<(Vec<String>, std::collections::HashMap<String, usize>)> =
        std::cell::RefCell::default();
}

fn intern(name: &str) -> usize {
    NAMES.with(|n| {
        let (list, index) = &mut *n.borrow_mut();
        if let Some(i) = index.get(name) {
            return *i;
        }
        list.push(name.to_owned());
        index.insert(name.to_owned(), list.len() - 1);
        list.len() - 1
    })
}

fn known(name: &str) -> Option<usize> {
    NAMES.with(|n| n.borrow().1.get(name).copied())
}

fn reset_names() {
    NAMES.with(|n| *n.borrow_mut() = Default::default());
}

/// A set of names, or every name (`all`; in a *must* set: after a write this analysis cannot
/// name, every name is taken as written).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Names {
    all: bool,
    bits: Vec<u64>,
}

impl Names {
    fn every() -> Names {
        Names {
            all: true,
            bits: Vec::new(),
        }
    }

    /// Whether the set names `n` itself (not through `all`).
    fn named(&self, n: &str) -> bool {
        known(n).is_some_and(|i| {
            self.bits
                .get(i / 64)
                .is_some_and(|w| w & (1 << (i % 64)) != 0)
        })
    }

    fn has(&self, n: &str) -> bool {
        self.all || self.named(n)
    }

    fn add(&mut self, other: &Names) {
        self.all |= other.all;
        if self.bits.len() < other.bits.len() {
            self.bits.resize(other.bits.len(), 0);
        }
        for (a, b) in self.bits.iter_mut().zip(&other.bits) {
            *a |= b;
        }
    }

    fn insert(&mut self, n: &str) {
        let i = intern(first_segment(n));
        if self.bits.len() <= i / 64 {
            self.bits.resize(i / 64 + 1, 0);
        }
        self.bits[i / 64] |= 1 << (i % 64);
    }

    /// The names in the set (not `all`).
    fn names(&self) -> Vec<String> {
        NAMES.with(|n| {
            let list = &n.borrow().0;
            (0..self.bits.len() * 64)
                .filter(|i| self.bits[i / 64] & (1 << (i % 64)) != 0)
                .filter_map(|i| list.get(i).cloned())
                .collect()
        })
    }

    fn trimmed(mut self) -> Names {
        while self.bits.last() == Some(&0) {
            self.bits.pop();
        }
        self
    }
}

/// Where paths meet: the names both have written.
fn meet(a: Names, b: &Names) -> Names {
    match (a.all, b.all) {
        (true, _) => b.clone(),
        (false, true) => a,
        _ => Names {
            all: false,
            bits: a.bits.iter().zip(&b.bits).map(|(x, y)| x & y).collect(),
        }
        .trimmed(),
    }
}

/// At a parallel join: the names either has written.
fn join(mut a: Names, b: &Names) -> Names {
    a.add(b);
    a
}

/// The variable a path such as `site.id` or `list[0]` writes.
fn first_segment(path: &str) -> &str {
    let end = path.find(['.', '[']).unwrap_or(path.len());
    path[..end].trim()
}

/// The vertices of the control-flow graph: each node's entry and exit, each process's entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum V {
    In(NodeId),
    Out(NodeId),
    Entry(ProcessId),
}

struct Cfg {
    /// Predecessors of each vertex, with whether the edge passes only the call's inputs.
    preds: BTreeMap<V, Vec<Pred>>,
    succs: BTreeMap<V, Vec<V>>,
}

#[derive(Clone, Copy)]
enum Pred {
    /// The state flows unchanged.
    Plain(V),
    /// A call activity's entry into the called process: only what it passes in.
    Call(NodeId),
}

/// Checks every read of the model; findings in the order of the graph's nodes and flows.
pub fn check(g: &ProcessGraph, cx: &Context<'_>) -> Vec<Finding> {
    reset_names();
    let cfg = build(g);
    let writes = Writes::of(g, cx);
    let (may, must) = solve(g, &cfg, &writes, cx);
    let concurrent = concurrent_writes(g, &cfg, &writes);
    let mut out = Vec::new();
    let mut report = |site: Site, at: &Names, sure: &Names, e: &Expression, here: NodeId| {
        for var in reads(e) {
            if at.has(&var) {
                if !sure.has(&var) {
                    out.push(Finding::Sometimes {
                        site: site.clone(),
                        var: var.clone(),
                        expression: e.source.clone(),
                        feel: matches!(e.program(), Program::Feel(_)),
                        path: unwritten_path(g, &cfg, &writes, here, &var),
                    });
                }
                continue;
            }
            out.push(Finding::Unwritten {
                site: site.clone(),
                var: var.clone(),
                expression: e.source.clone(),
                feel: matches!(e.program(), Program::Feel(_)),
                writer: nearest_writer(g, &writes, here, &var),
            });
        }
    };
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        let Some(at_in) = may.get(&V::In(id)) else {
            continue; // never reached
        };
        // What branches running beside this node may have written.
        let mut at_in = at_in.clone();
        if let Some(c) = concurrent.get(&id) {
            at_in.add(c);
        }
        let at_in = &at_in;
        let sure_in = must.get(&V::In(id)).cloned().unwrap_or_default();
        let (mut at, mut sure) = (at_in.clone(), sure_in);
        // Inside a loop, the engine's own names and the element variable.
        if let Some(l) = &n.looping {
            for v in LOOP_VARIABLES {
                at.insert(v);
                sure.insert(v);
            }
            if let Looping::MultiInstance(mi) = l {
                if let Some(e) = &mi.input_element {
                    at.insert(e);
                    sure.insert(e);
                }
                let before = [&mi.cardinality, &mi.input_collection];
                for e in before.into_iter().flatten() {
                    report(Site::Node(id), at_in, &sure, e, id);
                }
            }
        }
        for e in entry_reads(n) {
            report(Site::Node(id), &at, &sure, e, id);
        }
        // A condition waited for is evaluated again whenever data changes: anything its
        // process writes may have been written by then.
        let waited = conditions(n);
        if !waited.is_empty() {
            let mut seen = at.clone();
            seen.add(&writes.inside_process[g.process_of(id).index()]);
            for e in waited {
                report(Site::Node(id), &seen, &sure, e, id);
            }
        }
        // Scripts see their own earlier assignments.
        if let NodeKind::Task(Task {
            script:
                Some(Script {
                    assignments: Some(a),
                    ..
                }),
            ..
        }) = &n.kind
        {
            let (mut at, mut sure) = (at.clone(), sure.clone());
            for (target, e) in a {
                report(Site::Node(id), &at, &sure, e, id);
                at.insert(target);
                sure.insert(target);
            }
        }
        // Output mappings see the result's fields and the targets before them.
        if let Some(b) = binding(g, n) {
            let results = match &n.kind {
                NodeKind::Task(_) => (cx.results)(id),
                _ => None,
            };
            if let Some(fields) = results {
                let (mut at, mut sure) = (at.clone(), sure.clone());
                for f in &fields {
                    at.insert(f);
                    sure.insert(f);
                }
                for o in &b.outputs {
                    report(Site::Node(id), &at, &sure, &o.source, id);
                    at.insert(&o.target);
                    sure.insert(&o.target);
                }
            }
        }
        // Loop conditions and completion conditions are read after a pass.
        if let Some(out_may) = may.get(&V::Out(id)) {
            let mut out_may = out_may.clone();
            if let Some(c) = concurrent.get(&id) {
                out_may.add(c);
            }
            let out_may = &out_may;
            let mut after = out_may.clone();
            let mut sure_after = must.get(&V::Out(id)).cloned().unwrap_or_default();
            for v in LOOP_VARIABLES {
                after.insert(v);
                sure_after.insert(v);
            }
            for e in exit_reads(n) {
                report(Site::Node(id), &after, &sure_after, e, id);
            }
            for f in &n.outgoing {
                if let Some(c) = &g.flow(*f).condition {
                    let sure_out = must.get(&V::Out(id)).cloned().unwrap_or_default();
                    report(Site::Flow(*f), out_may, &sure_out, c, id);
                }
            }
        }
    }
    out
}

/// For each node that may run beside other branches, what those branches may write. Tokens
/// split to run at once at a parallel, inclusive or complex gateway, several outgoing flows, a
/// non-interrupting boundary, several nodes starting a scope or a parallel multi-instance
/// body; every node reachable from such a split may see anything written by any node of its
/// process reachable from one. An over-approximation, linear in the model, so that no read a
/// concurrent branch may satisfy is called unwritten.
fn concurrent_writes(g: &ProcessGraph, cfg: &Cfg, w: &Writes) -> BTreeMap<NodeId, Names> {
    let mut forks: Vec<V> = Vec::new();
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        let split = match &n.kind {
            NodeKind::Gateway(gw) => match gw.kind {
                GatewayKind::Exclusive => false,
                GatewayKind::EventBased { parallel } => parallel,
                _ => n.outgoing.len() > 1,
            },
            _ => n.outgoing.len() > 1,
        };
        let beside = n
            .boundaries
            .iter()
            .any(|b| matches!(&g.node(*b).kind, NodeKind::Boundary(be) if !be.interrupting));
        if split || beside {
            forks.extend([V::Out(id), V::In(id)]);
        }
        let parallel_body =
            matches!(&n.looping, Some(Looping::MultiInstance(mi)) if !mi.sequential);
        if parallel_body && matches!(n.kind, NodeKind::SubProcess(_)) {
            forks.push(V::In(id));
        }
        if let NodeKind::SubProcess(s) = &n.kind
            && cfg.succs.get(&V::In(id)).is_some_and(|v| v.len() > 1)
            && !s.nodes.is_empty()
        {
            forks.push(V::In(id));
        }
    }
    for p in 0..g.processes.len() {
        let e = V::Entry(ProcessId(p as u32));
        if cfg.succs.get(&e).is_some_and(|v| v.len() > 1) {
            forks.push(e);
        }
    }
    // Everything reachable from a split, per process: one search from all splits at once.
    let mut seen: BTreeSet<V> = forks.into_iter().collect();
    let mut queue: VecDeque<V> = seen.iter().copied().collect();
    let mut nodes = BTreeSet::new();
    while let Some(v) = queue.pop_front() {
        if let V::In(n) | V::Out(n) = v {
            nodes.insert(n);
        }
        for s in cfg.succs.get(&v).into_iter().flatten() {
            if !matches!(s, V::Entry(_)) && seen.insert(*s) {
                queue.push_back(*s);
            }
        }
    }
    let mut written = vec![Names::default(); g.processes.len()];
    for n in &nodes {
        written[g.process_of(*n).index()].add(&w.at[n.index()]);
    }
    nodes
        .into_iter()
        .map(|n| (n, written[g.process_of(n).index()].clone()))
        .collect()
}

/// The control-flow graph of the whole model.
fn build(g: &ProcessGraph) -> Cfg {
    let mut cfg = Cfg {
        preds: BTreeMap::new(),
        succs: BTreeMap::new(),
    };
    let edge = |cfg: &mut Cfg, from: Pred, to: V| {
        let src = match from {
            Pred::Plain(v) => v,
            Pred::Call(c) => V::In(c),
        };
        cfg.preds.entry(to).or_default().push(from);
        cfg.succs.entry(src).or_default().push(to);
    };
    // A scope's entry leads to the nodes that start in it.
    let starts = |nodes: &[NodeId]| -> Vec<NodeId> {
        nodes
            .iter()
            .copied()
            .filter(|n| {
                let node = g.node(*n);
                node.incoming.is_empty()
                    && !node.for_compensation
                    && !matches!(node.kind, NodeKind::Boundary(_))
                    && !matches!(&node.kind, NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::Event))
                    && !matches!(&node.kind, NodeKind::Catch(c)
                        if c.triggers.iter().any(|d| matches!(d, EventDefinition::Link(_))))
            })
            .collect()
    };
    let event_subs = |nodes: &[NodeId]| -> Vec<NodeId> {
        nodes
            .iter()
            .copied()
            .filter(|n| matches!(&g.node(*n).kind, NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::Event)))
            .collect()
    };
    for (p, proc_) in g.processes.iter().enumerate() {
        let entry = V::Entry(ProcessId(p as u32));
        for s in starts(&proc_.nodes) {
            edge(&mut cfg, Pred::Plain(entry), V::In(s));
        }
        for e in event_subs(&proc_.nodes) {
            edge(&mut cfg, Pred::Plain(entry), V::In(e));
        }
    }
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        match &n.kind {
            NodeKind::SubProcess(s) if !s.nodes.is_empty() => {
                for st in starts(&s.nodes) {
                    edge(&mut cfg, Pred::Plain(V::In(id)), V::In(st));
                }
                for e in event_subs(&s.nodes) {
                    edge(&mut cfg, Pred::Plain(V::In(id)), V::In(e));
                }
                // Its end: the inner nodes where tokens stop.
                for m in &s.nodes {
                    let inner = g.node(*m);
                    let event_sub = matches!(&inner.kind, NodeKind::SubProcess(x) if matches!(x.kind, SubProcessKind::Event));
                    if inner.outgoing.is_empty() && !event_sub && !inner.for_compensation {
                        edge(&mut cfg, Pred::Plain(V::Out(*m)), V::Out(id));
                    }
                }
            }
            NodeKind::CallActivity(CallActivity {
                called: Some(Called::Process(p)),
                ..
            }) => {
                edge(&mut cfg, Pred::Call(id), V::Entry(*p));
                edge(&mut cfg, Pred::Plain(V::In(id)), V::Out(id));
            }
            NodeKind::Boundary(b) => {
                edge(&mut cfg, Pred::Plain(V::In(b.attached_to)), V::In(id));
                edge(&mut cfg, Pred::Plain(V::In(id)), V::Out(id));
            }
            _ => edge(&mut cfg, Pred::Plain(V::In(id)), V::Out(id)),
        }
        for f in &n.outgoing {
            edge(&mut cfg, Pred::Plain(V::Out(id)), V::In(g.flow(*f).target));
        }
        if let Some(h) = n.compensation_handler {
            edge(&mut cfg, Pred::Plain(V::Out(id)), V::In(h));
        }
        // A link throw leads to the catches of its name in the same process.
        if let NodeKind::Throw(defs) = &n.kind {
            for d in defs {
                if let EventDefinition::Link(name) = d {
                    let p = g.process_of(id);
                    for (j, m) in g.nodes.iter().enumerate() {
                        let mid = NodeId(j as u32);
                        if let NodeKind::Catch(c) = &m.kind
                            && c.triggers
                                .iter()
                                .any(|t| matches!(t, EventDefinition::Link(l) if l == name))
                            && g.process_of(mid) == p
                        {
                            edge(&mut cfg, Pred::Plain(V::Out(id)), V::In(mid));
                        }
                    }
                }
            }
        }
    }
    cfg
}

/// The enclosing scopes of a node, innermost first.
fn scopes(g: &ProcessGraph, n: NodeId) -> Vec<Scope> {
    let mut out = Vec::new();
    let mut s = g.node(n).scope;
    loop {
        out.push(s);
        match s {
            Scope::Process(_) => return out,
            Scope::SubProcess(p) => s = g.node(p).scope,
        }
    }
}

/// The may and must states of every vertex reached.
fn solve(
    g: &ProcessGraph,
    cfg: &Cfg,
    w: &Writes,
    cx: &Context<'_>,
) -> (BTreeMap<V, Names>, BTreeMap<V, Names>) {
    let primary = g.primary_processes();
    let mut may: BTreeMap<V, Names> = BTreeMap::new();
    let mut must: BTreeMap<V, Names> = BTreeMap::new();
    let events = event_writes(g, w);
    let mut queue: VecDeque<V> = VecDeque::new();
    // Every process entry starts the search: a primary one with the start variables, one
    // started by an event (a message start's payload is a write of its own) likewise; one
    // only called gets what its callers pass.
    for p in 0..g.processes.len() {
        queue.push_back(V::Entry(ProcessId(p as u32)));
    }
    let called = g.called_processes();
    let mut rounds = 0usize;
    let limit = 64 * (g.nodes.len() + g.processes.len() + 1) * 2 + 1024;
    while let Some(v) = queue.pop_front() {
        rounds += 1;
        if rounds > limit {
            break; // a bound: never reached on a finite lattice, kept against surprises
        }
        let (new_may, new_must) =
            transfer(g, cfg, w, cx, v, (&may, &must), &primary, &called, &events);
        let Some(new_may) = new_may else { continue };
        let changed = may.get(&v) != Some(&new_may) || must.get(&v) != Some(&new_must);
        if changed {
            may.insert(v, new_may);
            must.insert(v, new_must);
            for s in cfg.succs.get(&v).into_iter().flatten() {
                queue.push_back(*s);
            }
        }
    }
    (may, must)
}

#[allow(clippy::too_many_arguments)]
fn transfer(
    g: &ProcessGraph,
    cfg: &Cfg,
    w: &Writes,
    cx: &Context<'_>,
    v: V,
    (may, must): (&BTreeMap<V, Names>, &BTreeMap<V, Names>),
    primary: &[ProcessId],
    called: &BTreeSet<ProcessId>,
    events: &BTreeMap<Scope, Names>,
) -> (Option<Names>, Names) {
    let mut m = Names::default();
    let mut reached = false;
    let mut sure: Option<Names> = None;
    let parallel_join = matches!(v, V::In(n) if matches!(&g.node(n).kind,
        NodeKind::Gateway(gw) if gw.kind == GatewayKind::Parallel) && g.node(n).incoming.len() > 1);
    if let V::Entry(p) = v
        && (primary.contains(&p) || !called.contains(&p))
    {
        // Started with the start variables (a called process also by its callers, below).
        reached = true;
        let mut s = Names::default();
        for x in cx.start {
            m.insert(x);
            s.insert(x);
        }
        sure = Some(s);
    }
    for pred in cfg.preds.get(&v).into_iter().flatten() {
        let (pm, ps) = match *pred {
            Pred::Plain(u) => {
                let Some(pm) = may.get(&u) else { continue };
                (pm.clone(), must.get(&u).cloned().unwrap_or_default())
            }
            Pred::Call(c) => {
                let Some(pm) = may.get(&V::In(c)) else {
                    continue;
                };
                let ps = must.get(&V::In(c)).cloned().unwrap_or_default();
                let b = binding(g, g.node(c));
                let data_in = g
                    .node(c)
                    .data
                    .as_ref()
                    .is_some_and(|d| !d.inputs.is_empty());
                let all = b.is_some_and(|b| b.all_in)
                    || (!data_in && b.is_none_or(|b| b.inputs.is_empty()));
                let mut cm = if all { pm.clone() } else { Names::default() };
                let mut cs = if all { ps } else { Names::default() };
                for i in b.iter().flat_map(|b| &b.inputs) {
                    cm.insert(&i.target);
                    cs.insert(&i.target);
                }
                if let Some(d) = &g.node(c).data {
                    for p in &d.inputs {
                        cm.insert(&p.name);
                        cs.insert(&p.name);
                    }
                }
                (cm, cs)
            }
        };
        reached = true;
        m.add(&pm);
        sure = Some(match sure {
            None => ps,
            Some(s) if parallel_join => join(s, &ps),
            Some(s) => meet(s, &ps),
        });
    }
    if !reached {
        return (None, Names::default());
    }
    let mut sure = sure.unwrap_or_default();
    match v {
        V::Entry(p) => {
            let declared = &w.declared_process[p.index()];
            m.add(declared);
            sure.add(declared);
        }
        V::Out(n) => {
            let wn = &w.at[n.index()];
            m.add(wn);
            sure.add(wn);
            if wn.all {
                sure = Names::every();
            }
        }
        V::In(n) => {
            // Entering a scope declares its data objects; anything its event sub-processes,
            // boundaries or handlers may see was possibly written inside.
            if let Some(d) = w.declared_node.get(&n) {
                m.add(d);
                sure.add(d);
            }
            let node = g.node(n);
            let sees_scope = matches!(&node.kind, NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::Event))
                || node.for_compensation;
            if sees_scope {
                match node.scope {
                    Scope::Process(p) => m.add(&w.inside_process[p.index()]),
                    Scope::SubProcess(s) => {
                        if let Some(x) = w.inside_node.get(&s) {
                            m.add(x);
                        }
                    }
                }
            }
            if let NodeKind::Boundary(b) = &node.kind
                && let Some(x) = w.inside_node.get(&b.attached_to)
            {
                m.add(x);
            }
            // Non-interrupting event sub-processes of every enclosing scope may have run.
            for s in scopes(g, n) {
                if let Some(x) = events.get(&s) {
                    m.add(x);
                }
            }
        }
    }
    (Some(m.trimmed()), sure.trimmed())
}

/// The writer of `var` nearest to `at` (fewest flows away, either direction).
fn nearest_writer(g: &ProcessGraph, w: &Writes, at: NodeId, var: &str) -> Option<NodeId> {
    let mut seen = BTreeSet::from([at]);
    let mut queue = VecDeque::from([at]);
    while let Some(n) = queue.pop_front() {
        if n != at && w.writes(n, var) {
            return Some(n);
        }
        let node = g.node(n);
        let next = node
            .incoming
            .iter()
            .map(|f| g.flow(*f).source)
            .chain(node.outgoing.iter().map(|f| g.flow(*f).target))
            .chain(node.boundaries.iter().copied())
            .chain(match (&node.kind, node.scope) {
                (NodeKind::Boundary(b), _) => Some(b.attached_to),
                (_, Scope::SubProcess(p)) => Some(p),
                _ => None,
            })
            .chain(match &node.kind {
                NodeKind::SubProcess(s) => s.nodes.clone(),
                _ => Vec::new(),
            });
        for m in next {
            if seen.insert(m) {
                queue.push_back(m);
            }
        }
    }
    // Not connected: any writer in the model.
    (0..g.nodes.len())
        .map(|i| NodeId(i as u32))
        .find(|n| w.writes(*n, var))
}

/// One path of nodes from a start to `at` on which nothing writes `var`.
fn unwritten_path(g: &ProcessGraph, cfg: &Cfg, w: &Writes, at: NodeId, var: &str) -> Vec<NodeId> {
    // Backwards from the read, through vertices that do not write the name.
    let mut back: BTreeMap<V, V> = BTreeMap::new();
    let mut queue = VecDeque::from([V::In(at)]);
    let mut seen = BTreeSet::from([V::In(at)]);
    while let Some(v) = queue.pop_front() {
        if let V::Entry(_) = v {
            let mut path = Vec::new();
            let mut cur = v;
            while let Some(next) = back.get(&cur) {
                if let V::In(n) = next
                    && path.last() != Some(n)
                {
                    path.push(*n);
                }
                cur = *next;
            }
            return path;
        }
        for p in cfg.preds.get(&v).into_iter().flatten() {
            let u = match *p {
                Pred::Plain(u) => u,
                Pred::Call(c) => V::In(c),
            };
            let writes = match u {
                V::Out(n) => w.writes(n, var) || w.at[n.index()].all,
                _ => false,
            };
            if !writes && seen.insert(u) {
                back.insert(u, v);
                queue.push_back(u);
            }
        }
    }
    let _ = g;
    Vec::new()
}

/// Names close to `name` among `known` (at most two edits), nearest first.
pub fn near<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    known
        .into_iter()
        .filter(|k| *k != name)
        .map(|k| (edits(name, k), k))
        .filter(|(d, k)| *d <= 2.min(k.chars().count() / 2))
        .min()
        .map(|(_, k)| k)
}

fn edits(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for j in 0..b.len() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != b[j]))
                .min(row[j] + 1)
                .min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// Every name the model writes or declares anywhere (for "did you mean").
pub fn written_names(g: &ProcessGraph) -> BTreeSet<String> {
    reset_names();
    let cx = Context {
        start: &BTreeSet::new(),
        results: &|_| Some(Vec::new()),
    };
    let w = Writes::of(g, &cx);
    let mut out = BTreeSet::new();
    for n in
        w.at.iter()
            .chain(&w.declared_process)
            .chain(w.declared_node.values())
    {
        out.extend(n.names());
    }
    out
}
