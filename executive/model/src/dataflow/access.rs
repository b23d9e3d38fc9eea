//! What each node of the model reads and writes: the expressions evaluated as a token
//! arrives, leaves or waits there, and the names its outputs, scripts, payloads and declarations
//! write ([`Writes`]), for the analyses of `dataflow.rs`.

use std::collections::BTreeMap;

use super::*;

/// The names an expression reads as variables.
pub(super) fn reads(e: &Expression) -> Vec<String> {
    e.required()
}

/// A task's or call activity's binding.
pub(super) fn binding<'g>(
    g: &'g ProcessGraph,
    n: &'g Node,
) -> Option<&'g crate::binding::TaskBinding> {
    match &n.kind {
        NodeKind::Task(t) => t.binding.as_ref(),
        NodeKind::CallActivity(c) => match &c.called {
            Some(Called::GlobalTask(id)) => g.global_tasks.get(id).and_then(|t| t.binding.as_ref()),
            _ => c.binding.as_ref(),
        },
        _ => None,
    }
}

/// Expressions a node reads when a token enters it.
pub(super) fn entry_reads(n: &Node) -> Vec<&Expression> {
    let mut out = Vec::new();
    match &n.kind {
        NodeKind::Task(t) => {
            if let Some(b) = &t.binding {
                out.extend(b.inputs.iter().map(|i| &i.source));
            }
        }
        NodeKind::CallActivity(c) => {
            if let Some(b) = &c.binding {
                out.extend(b.inputs.iter().map(|i| &i.source));
            }
        }
        NodeKind::Gateway(gw) => out.extend(gw.activation.iter()),
        _ => {}
    }
    if let Some(d) = &n.data {
        for a in &d.input_associations {
            out.extend(a.transformation.iter());
            out.extend(a.assignments.iter().map(|(e, _)| e));
        }
    }
    out
}

/// Conditions a node waits for (conditional events).
pub(super) fn conditions(n: &Node) -> Vec<&Expression> {
    let triggers = match &n.kind {
        NodeKind::Catch(c) => &c.triggers,
        NodeKind::Boundary(b) => &b.triggers,
        NodeKind::Start(s) => &s.triggers,
        _ => return Vec::new(),
    };
    triggers.iter().filter_map(conditional).collect()
}

/// Expressions a node reads after a pass of its body.
pub(super) fn exit_reads(n: &Node) -> Vec<&Expression> {
    let mut out = Vec::new();
    match &n.looping {
        Some(Looping::Standard {
            condition: Some(c), ..
        }) => out.push(c),
        Some(Looping::MultiInstance(mi)) => {
            out.extend(mi.completion.iter());
            out.extend(mi.output_element.iter());
            out.extend(mi.complex.iter());
        }
        _ => {}
    }
    if let NodeKind::SubProcess(SubProcess {
        kind: SubProcessKind::AdHoc {
            completion: Some(c),
            ..
        },
        ..
    }) = &n.kind
    {
        out.push(c);
    }
    out
}

pub(super) fn conditional(d: &EventDefinition) -> Option<&Expression> {
    match d {
        EventDefinition::Conditional(e) => Some(e),
        _ => None,
    }
}

/// What each node writes when a token leaves it.
pub(super) struct Writes {
    pub(super) at: Vec<Names>,
    /// Names written anywhere inside each sub-process or process (its event sub-processes,
    /// boundaries and compensation handlers may see any of them).
    pub(super) inside_node: BTreeMap<NodeId, Names>,
    pub(super) inside_process: Vec<Names>,
    /// Declared data objects and properties of each scope.
    pub(super) declared_node: BTreeMap<NodeId, Names>,
    pub(super) declared_process: Vec<Names>,
}

impl Writes {
    pub(super) fn of(g: &ProcessGraph, cx: &Context<'_>) -> Writes {
        let mut at = vec![Names::default(); g.nodes.len()];
        for (i, n) in g.nodes.iter().enumerate() {
            at[i] = node_writes(g, NodeId(i as u32), n, cx);
        }
        let mut inside_node: BTreeMap<NodeId, Names> = BTreeMap::new();
        let mut inside_process = vec![Names::default(); g.processes.len()];
        for (i, n) in g.nodes.iter().enumerate() {
            let w = &at[i];
            let mut scope = n.scope;
            loop {
                match scope {
                    Scope::Process(p) => {
                        inside_process[p.index()].add(w);
                        break;
                    }
                    Scope::SubProcess(s) => {
                        inside_node.entry(s).or_default().add(w);
                        scope = g.node(s).scope;
                    }
                }
            }
        }
        let names = |items: &[DataItem]| {
            let mut n = Names::default();
            for d in items {
                if let Some(name) = d.name.as_deref().filter(|s| !s.trim().is_empty()) {
                    n.insert(name);
                }
            }
            n
        };
        let declared_process = g
            .processes
            .iter()
            .map(|p| {
                let mut n = names(&p.properties);
                n.add(&names(&p.data_objects));
                n
            })
            .collect();
        let declared_node = g
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(i, n)| match &n.kind {
                NodeKind::SubProcess(s) => Some((NodeId(i as u32), names(&s.data_objects))),
                _ => None,
            })
            .collect();
        Writes {
            at,
            inside_node,
            inside_process,
            declared_node,
            declared_process,
        }
    }

    /// Whether `n` writes `var`.
    pub(super) fn writes(&self, n: NodeId, var: &str) -> bool {
        self.at[n.index()].named(var)
    }
}

pub(super) fn node_writes(g: &ProcessGraph, id: NodeId, n: &Node, cx: &Context<'_>) -> Names {
    let mut w = Names::default();
    let payload = |defs: &[EventDefinition]| {
        defs.iter()
            .any(|d| matches!(d, EventDefinition::Message(_)))
    };
    let caught = |defs: &[EventDefinition], w: &mut Names| {
        for d in defs {
            if let EventDefinition::Error {
                code_variable,
                message_variable,
                ..
            } = d
            {
                for v in [code_variable, message_variable].into_iter().flatten() {
                    w.insert(v);
                }
            }
        }
    };
    match &n.kind {
        NodeKind::Start(s) => {
            if payload(&s.triggers) {
                w.all = true;
            }
            caught(&s.triggers, &mut w);
        }
        NodeKind::Catch(c) if payload(&c.triggers) => w.all = true,
        NodeKind::Boundary(b) => {
            if payload(&b.triggers) {
                w.all = true;
            }
            caught(&b.triggers, &mut w);
        }
        NodeKind::Task(t) => {
            let outputs = t.binding.as_ref().filter(|b| !b.outputs.is_empty());
            for o in outputs.iter().flat_map(|b| &b.outputs) {
                w.insert(&o.target);
            }
            let data_out = n
                .data
                .as_ref()
                .is_some_and(|d| !d.outputs.is_empty() || !d.output_associations.is_empty());
            let dispatched = t.binding.as_ref().is_some_and(|b| b.resource.is_some())
                || matches!(
                    t.kind,
                    TaskKind::Service | TaskKind::User | TaskKind::BusinessRule | TaskKind::Send
                );
            match t.kind {
                TaskKind::Receive => w.all = true,
                TaskKind::Script => match &t.script {
                    Some(Script {
                        assignments: Some(a),
                        ..
                    }) => {
                        for (target, _) in a {
                            w.insert(target);
                        }
                    }
                    // A script the engine does not read runs elsewhere and may set anything.
                    _ => w.all = true,
                },
                _ if outputs.is_none() && dispatched && !data_out => match (cx.results)(id) {
                    Some(fields) => {
                        for f in &fields {
                            w.insert(f);
                        }
                    }
                    None => w.all = true,
                },
                _ => {}
            }
        }
        NodeKind::CallActivity(c) => {
            if let Some(b) = binding(g, n) {
                for o in &b.outputs {
                    w.insert(&o.target);
                }
            }
            let all_out = c.binding.as_ref().is_some_and(|b| b.all_out);
            if all_out || matches!(c.called, Some(Called::GlobalTask(_))) {
                // What the called process (or global task) writes; computed from its nodes.
                w.all |= match &c.called {
                    Some(Called::Process(p)) => {
                        let mut inner = Names::default();
                        for (j, m) in g.nodes.iter().enumerate() {
                            if g.process_of(NodeId(j as u32)) == *p && j != id.index() {
                                // One level: a name the callee's own nodes write.
                                inner.add(&shallow_writes(m));
                            }
                        }
                        let all = inner.all;
                        inner.all = false;
                        w.add(&inner);
                        all
                    }
                    _ => true,
                };
            }
        }
        _ => {}
    }
    if let Some(Looping::MultiInstance(mi)) = &n.looping
        && let Some(o) = &mi.output_collection
    {
        w.insert(o);
    }
    if let Some(d) = &n.data {
        for a in &d.output_associations {
            if let Some(DataRef::Variable(v)) = &a.target {
                w.insert(v);
            }
            for (_, to) in &a.assignments {
                w.insert(to);
            }
        }
    }
    w
}

/// What a node of a called process writes, without asking for catalogues: used for a call
/// activity that passes every variable out.
pub(super) fn shallow_writes(n: &Node) -> Names {
    let mut w = Names::default();
    match &n.kind {
        NodeKind::Task(t) => match (&t.binding, &t.script) {
            (Some(b), _) if !b.outputs.is_empty() => {
                for o in &b.outputs {
                    w.insert(&o.target);
                }
            }
            (
                _,
                Some(Script {
                    assignments: Some(a),
                    ..
                }),
            ) => {
                for (target, _) in a {
                    w.insert(target);
                }
            }
            _ if matches!(t.kind, TaskKind::Plain | TaskKind::Manual) => {}
            _ => w.all = true,
        },
        NodeKind::CallActivity(_) => w.all = true,
        NodeKind::Start(StartEvent { triggers, .. })
        | NodeKind::Catch(CatchEvent { triggers, .. })
        | NodeKind::Boundary(BoundaryEvent { triggers, .. }) => {
            for d in triggers {
                match d {
                    EventDefinition::Message(_) => w.all = true,
                    EventDefinition::Error {
                        code_variable,
                        message_variable,
                        ..
                    } => {
                        for v in [code_variable, message_variable].into_iter().flatten() {
                            w.insert(v);
                        }
                    }
                    _ => {}
                }
            }
        }
        _ => {}
    }
    if let Some(Looping::MultiInstance(mi)) = &n.looping
        && let Some(o) = &mi.output_collection
    {
        w.insert(o);
    }
    w
}

/// What the event sub-processes directly in each scope may write.
pub(super) fn event_writes(g: &ProcessGraph, w: &Writes) -> BTreeMap<Scope, Names> {
    let mut out: BTreeMap<Scope, Names> = BTreeMap::new();
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        if matches!(&n.kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event))
            && let Some(x) = w.inside_node.get(&id)
        {
            out.entry(n.scope).or_default().add(x);
        }
    }
    out
}
