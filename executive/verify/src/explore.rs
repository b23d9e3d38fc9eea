//! Native exploration: the executive's own engine, driven through every interleaving of what the
//! outside can do — each task in flight completes or fails with each error code something
//! catches, each armed timer, message or condition fires, each diverging gateway takes each of
//! its branches — under the same abstractions as the PROMELA translation (no data; conditions
//! chosen; timers untimed; the outside starts a process once per run; a non-interrupting event
//! sub-process, and a process started by an event, runs one instance at a time; the outside
//! fires a non-interrupting boundary event or event sub-process start at most [`REPEATS`] times
//! per activation), with no translation in between. It checks the
//! built-in properties on the engine's real semantics and gives the end events each run can
//! reach, so the Spin verdicts can be cross-checked against it (the differential test).
//!
//! States are compared by their shape — which elements hold tokens (and by which flow they
//! came), in which scopes, what waits — not by ids, so loops converge.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;

use executive_engine::{
    Action, At, Engine, Entry, Event, Input, On, Outcome, State, TaskKey, Vars, WaitId,
    chosen_from_outside,
};
use executive_model::{
    Called, EventDefinition, FlowId, GatewayKind, NodeId, NodeKind, ProcessGraph, TaskKind,
};
use serde::Serialize;

use crate::promela::{inner_message, outside, started_from_outside};

/// What the exploration found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Exploration {
    /// Distinct states (by shape).
    pub states: usize,
    /// Every reachable state was explored (no bound hit).
    pub complete: bool,
    /// A run that gets stuck, as the inputs that lead there.
    pub deadlock: Option<Vec<String>>,
    /// A run that puts two tokens on one sequence flow.
    pub unsafe_run: Option<Vec<String>>,
    /// Activities no run starts (element ids).
    pub dead_activities: Vec<String>,
    /// End events some run reaches (element ids).
    pub ends: BTreeSet<String>,
    /// Why the engine could not be explored without data (an incident), if so.
    pub needs_data: Option<String>,
}

/// One state in the search: the engine state and how it was reached.
struct Node {
    state: State,
    /// The state it came from (`None`: the mission's first step, from nothing).
    from: Option<usize>,
    /// What happened on the way (for a first step, the branches it took, if any).
    label: String,
    /// How often the outside fired each repeating subscription ([`repeats`]) of the state.
    fired: BTreeMap<WaitId, u8>,
}

/// How often the outside fires one non-interrupting boundary event or event sub-process start
/// (a message, a condition, a timer cycle) per activation of what it is armed on: the first
/// time and one repetition, as the translation bounds them at its default loop bound
/// (`--loops 1`). Unbounded, a mission whose other tokens are stuck would never show as stuck,
/// since the outside could always fire once more.
pub const REPEATS: u8 = 2;

/// Whether `w` fires beside what it is armed on and stays armed: a non-interrupting boundary
/// event or event sub-process start.
fn repeats(g: &ProcessGraph, w: &executive_engine::Wait) -> bool {
    match &g.node(w.node).kind {
        NodeKind::Boundary(b) => !b.interrupting,
        NodeKind::Start(st) => {
            !st.interrupting
                && matches!(g.node(w.node).scope, executive_model::Scope::SubProcess(_))
        }
        _ => false,
    }
}

/// The shape of a state: tokens by (scope path, node, flow in, what they do), waits by node,
/// instance outcomes.
/// `starts` are the outside's starts ([`outside_starts`]), computed once by the caller.
pub(crate) fn shape(
    g: &ProcessGraph,
    s: &State,
    starts: &[(executive_model::ProcessId, NodeId)],
) -> String {
    let path = |scope| scope_path(g, s, scope);
    let mut tokens: Vec<String> = s
        .tokens
        .values()
        .map(|t| {
            let at = match &t.at {
                At::Task(_) => "task".to_owned(),
                At::UserTask(_) => "user".to_owned(),
                At::Scope(_) => "scope".to_owned(),
                At::Looping(l) => format!("loop{}:{}", l.started, l.completed),
                other => format!("{other:?}"),
            };
            format!(
                "{}|{}|{:?}|{at}",
                path(Some(t.scope)),
                g.node(t.node).id,
                t.via.map(|f| f.0)
            )
        })
        .collect();
    tokens.sort();
    let mut waits: Vec<String> = s
        .waits
        .values()
        .map(|w| format!("{}|{}", g.node(w.node).id, path(Some(w.scope))))
        .collect();
    waits.sort();
    // How the instances of each process ended. How many ended counts only for a process the
    // outside starts (once per run): a process the model starts itself (a message flow from
    // another pool) may be started once per round of a loop, and the loop would never
    // converge if each ended instance made a new state; what follows does not depend on it.
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    for i in s.instances.values() {
        let key = format!(
            "{}:{:?}",
            g.process(i.process).id,
            i.outcome.as_ref().map(std::mem::discriminant)
        );
        let n = outcomes.entry(key).or_default();
        let by_outside = starts.iter().any(|(p, _)| *p == i.process);
        if by_outside || i.outcome.is_none() || *n == 0 {
            *n += 1;
        }
    }
    format!("{tokens:?}{waits:?}{outcomes:?}")
}

/// Where a scope is, by element ids from the innermost out.
fn scope_path(g: &ProcessGraph, s: &State, mut scope: Option<executive_engine::ScopeId>) -> String {
    let mut p = Vec::new();
    while let Some(id) = scope {
        let Some(sc) = s.scopes.get(&id) else { break };
        p.push(match sc.kind {
            executive_engine::ScopeKind::Process(pid) => g.process(pid).id.clone(),
            executive_engine::ScopeKind::SubProcess(n) | executive_engine::ScopeKind::Body(n) => {
                g.node(n).id.clone()
            }
        });
        p.push(
            sc.owner
                .and_then(|o| s.tokens.get(&o))
                .map(|t| g.node(t.node).id.clone())
                .unwrap_or_default(),
        );
        scope = sc.parent;
    }
    p.join("/")
}

/// The firings counted in `fired` by shape, to tell states apart that differ only in them.
fn fired_shape(g: &ProcessGraph, s: &State, fired: &BTreeMap<WaitId, u8>) -> String {
    let mut out: Vec<String> = fired
        .iter()
        .filter_map(|(w, n)| {
            let wait = s.waits.get(w)?;
            Some(format!(
                "{}|{}|{n}",
                g.node(wait.node).id,
                scope_path(g, s, Some(wait.scope))
            ))
        })
        .collect();
    out.sort();
    out.join(",")
}

/// The code the exploration fails a task with to stand for every code no boundary names.
pub(crate) const UNNAMED: &str = "UNNAMED_FAILURE";

/// The error codes a failing task might raise: one per code some boundary or event
/// sub-process catches, plus one none names (for catch-alls).
pub(crate) fn codes(g: &ProcessGraph) -> Vec<String> {
    let mut out = BTreeSet::new();
    let mut catch_all = false;
    for n in &g.nodes {
        // Boundary events, and the error starts of event sub-processes.
        let triggers = match &n.kind {
            NodeKind::Boundary(b) => &b.triggers,
            NodeKind::Start(s) => &s.triggers,
            _ => continue,
        };
        for t in triggers {
            match t {
                // An error without a code is matched by its id, as the engine matches it.
                EventDefinition::Error { error: Some(e), .. } => {
                    let e = &g.errors[e.index()];
                    out.insert(e.code.clone().unwrap_or_else(|| e.id.clone()));
                }
                EventDefinition::Error { error: None, .. } => catch_all = true,
                _ => {}
            }
        }
    }
    if catch_all {
        out.insert(UNNAMED.to_owned());
    }
    out.into_iter().collect()
}

/// The choices a diverging gateway offers: one flow at an exclusive gateway, any non-empty set
/// of its first six flows otherwise.
pub(crate) fn branches(g: &ProcessGraph, gateway: NodeId) -> Vec<Vec<FlowId>> {
    let n = g.node(gateway);
    let exclusive = matches!(&n.kind, NodeKind::Gateway(gw) if gw.kind == GatewayKind::Exclusive);
    let count = n.outgoing.len().min(6);
    (1u32..(1 << count))
        .filter(|mask| !exclusive || mask.count_ones() == 1)
        .map(|mask| {
            (0..count)
                .filter(|k| mask & (1 << k) != 0)
                .map(|k| n.outgoing[k])
                .collect()
        })
        .collect()
}

/// How a step that takes `flows` at `gateway` is named (`Gateway.take[f1+f2]`).
pub(crate) fn take_label(g: &ProcessGraph, gateway: NodeId, flows: &[FlowId]) -> String {
    let names: Vec<&str> = flows.iter().map(|f| g.flow(*f).id.as_str()).collect();
    format!("{}.take[{}]", g.node(gateway).id, names.join("+"))
}

/// The start events by which the outside starts a mission's process: a message or condition
/// start of a primary process.
pub(crate) fn outside_starts(g: &ProcessGraph) -> Vec<(executive_model::ProcessId, NodeId)> {
    g.primary_processes()
        .into_iter()
        .flat_map(|p| {
            g.scope_nodes(executive_model::Scope::Process(p))
                .iter()
                .copied()
                .filter(|n| {
                    g.node(*n).incoming.is_empty()
                        && started_from_outside(g, *n)
                        && !inner_message(g, *n)
                })
                .map(move |n| (p, n))
        })
        .collect()
}

/// The starts of `starts` the outside may make in state `s` — each start event with its label
/// and input. It starts a process once per run, while no instance of it runs, as the
/// translation does at its default loop bound (the mission's start gave every primary process
/// its first instance, which ends at once where the process starts only on events). Bounded
/// so, a state where the rest of the mission is stuck still shows as a deadlock once the
/// outside has had its turn.
pub(crate) fn starts_now<'s>(
    g: &'s ProcessGraph,
    s: &'s State,
    starts: &'s [(executive_model::ProcessId, NodeId)],
) -> impl Iterator<Item = (NodeId, String, Event)> + 's {
    starts
        .iter()
        .filter(|(p, _)| {
            let (count, running) = s
                .instances
                .values()
                .filter(|i| i.process == *p)
                .fold((0, false), |(c, r), i| (c + 1, r || i.outcome.is_none()));
            !running && count <= 1
        })
        .map(|&(p, n)| {
            let start = Event::InstanceStarted {
                process: g.process(p).id.clone(),
                vars: Vars::new(),
                start: Some(g.node(n).id.clone()),
            };
            (n, format!("{}.fire", g.node(n).id), start)
        })
}

/// What the outside can do in a state, each with the subscription it fires, if any. `fired`
/// counts the firings of repeating subscriptions so far.
fn inputs(
    g: &ProcessGraph,
    s: &State,
    fired: &BTreeMap<WaitId, u8>,
    codes: &[String],
    starts: &[(executive_model::ProcessId, NodeId)],
) -> Vec<(String, Event, Option<WaitId>)> {
    let mut out = Vec::new();
    out.extend(starts_now(g, s, starts).map(|(_, label, event)| (label, event, None)));
    for (id, t) in &s.tokens {
        let label = g.node(t.node).id.clone();
        match &t.at {
            At::Task(key) | At::UserTask(key) => {
                let key: TaskKey = *key;
                out.push((
                    format!("{label}.complete"),
                    Event::TaskCompleted {
                        task: key,
                        output: Vars::new(),
                    },
                    None,
                ));
                if !matches!(&g.node(t.node).kind, NodeKind::Task(task) if task.kind == TaskKind::User)
                {
                    for c in codes {
                        out.push((
                            format!("{label}.fail[{c}]"),
                            Event::TaskFailed {
                                task: key,
                                code: c.clone(),
                                message: String::new(),
                            },
                            None,
                        ));
                    }
                }
            }
            At::Deciding => {
                for flows in branches(g, t.node) {
                    out.push((
                        take_label(g, t.node, &flows),
                        Event::BranchTaken { token: *id, flows },
                        None,
                    ));
                }
            }
            _ => {}
        }
    }
    for (wid, w) in &s.waits {
        // Timers armed together (on one activity, behind one gateway) fire by their deadlines.
        let later = match w.on {
            On::Timer { due, .. } => s.waits.values().any(|o| {
                o.token.is_some()
                    && o.token == w.token
                    && matches!(o.on, On::Timer { due: other, .. } if other < due)
            }),
            _ => false,
        };
        // A message the model's own senders send is theirs to give, not the outside's.
        let from_outside = match w.on {
            On::Message(..) => !inner_message(g, w.node),
            On::Timer { .. } | On::Condition { .. } | On::Manual => true,
            _ => false,
        };
        let spent = repeats(g, w) && fired.get(wid).is_some_and(|n| *n >= REPEATS);
        let fires = !later && !running_beside(g, s, w) && from_outside && !spent;
        if fires {
            // A timer fires as the engine fires it (a duration once, a cycle as often as it
            // repeats); other events by hand.
            let event = match w.on {
                On::Timer { key, .. } => Event::TimerFired { timer: key },
                _ => Event::WaitTriggered { wait: *wid },
            };
            out.push((format!("{}.fire", g.node(w.node).id), event, Some(*wid)));
        }
    }
    out
}

/// The instances of a process started by an event (`evented`) that run beside an older one of
/// the same process.
fn beside(
    s: &State,
    evented: &BTreeSet<executive_model::ProcessId>,
) -> Vec<executive_engine::InstanceId> {
    let mut running = BTreeSet::new();
    s.instances
        .iter()
        .filter(|(_, i)| i.outcome.is_none() && evented.contains(&i.process))
        .filter(|(_, i)| !running.insert(i.process))
        .map(|(id, _)| *id)
        .collect()
}

/// Whether `w` is the start of a non-interrupting event sub-process of which an instance
/// already runs in the same scope. Such a start fires again only once that instance has ended,
/// as in the translation (one instance at a time): each firing while one runs would add
/// another instance, and a sub-process whose body waits on an activity would then grow the
/// state space without bound.
pub(crate) fn running_beside(g: &ProcessGraph, s: &State, w: &executive_engine::Wait) -> bool {
    let non_interrupting = matches!(&g.node(w.node).kind, NodeKind::Start(st) if !st.interrupting);
    match g.node(w.node).scope {
        executive_model::Scope::SubProcess(esp) if non_interrupting => s
            .tokens
            .values()
            .any(|t| t.node == esp && t.scope == w.scope),
        _ => false,
    }
}

fn path_of(nodes: &[Node], mut at: usize) -> Vec<String> {
    let mut steps = Vec::new();
    loop {
        let node = &nodes[at];
        if !node.label.is_empty() {
            steps.push(node.label.clone());
        }
        match node.from {
            Some(from) => at = from,
            None => break,
        }
    }
    steps.reverse();
    steps
}

/// Explores the engine on `g` up to `max_states` distinct states.
pub fn explore(g: Arc<ProcessGraph>, max_states: usize) -> Exploration {
    let hold: BTreeSet<NodeId> = (0..g.nodes.len() as u32)
        .map(NodeId)
        .filter(|n| outside(&g, *n))
        .collect();
    let engine = |state: State, choices: &BTreeMap<NodeId, Vec<FlowId>>| {
        let mut e = Engine::restore(Arc::clone(&g), state);
        let game = e.game();
        game.decide = true;
        game.timers = true;
        game.instances = crate::promela::MAX_INSTANCES;
        game.hold = hold.clone();
        game.fixed = choices.clone();
        e
    };
    // `events` applied to `state`, each diverging gateway the step reaches decided as the
    // token arrives, as the engine decides it in flight: the step runs again from `state` once
    // per branch of the first gateway it left undecided, until none is. Each run: the branches
    // it took (labels), what it did, and where it ended.
    let within = |state: &State, events: &[Event]| {
        let mut done = Vec::new();
        let mut work = vec![(BTreeMap::new(), Vec::new())];
        while let Some((choices, labels)) = work.pop() {
            let mut e = engine(state.clone(), &choices);
            let mut actions = Vec::new();
            let mut rejected = None;
            for event in events {
                let seq = e.state().last_seq + 1;
                let input = Input {
                    seq,
                    at: 0,
                    event: event.clone(),
                };
                match e.step_into(input, &mut actions) {
                    Ok(()) => {}
                    Err(r) => {
                        rejected = Some(r);
                        break;
                    }
                }
            }
            if let Some(r) = rejected {
                done.push((labels, Err(r)));
                continue;
            }
            // The first gateway the step reached and left undecided (its token may be gone
            // by the end of the step, withdrawn by what came after).
            let open = actions.iter().find_map(|a| match a {
                Action::Record(r) => match &r.entry {
                    Entry::Entered { node, .. }
                        if chosen_from_outside(&g, *node) && !choices.contains_key(node) =>
                    {
                        Some(*node)
                    }
                    _ => None,
                },
                _ => None,
            });
            match open {
                Some(gateway) => {
                    for flows in branches(&g, gateway) {
                        let mut labels: Vec<String> = labels.clone();
                        labels.push(take_label(&g, gateway, &flows));
                        let mut choices = choices.clone();
                        choices.insert(gateway, flows);
                        work.push((choices, labels));
                    }
                }
                None => done.push((labels, Ok((actions, e.state().clone())))),
            }
        }
        done
    };
    let codes = codes(&g);
    let starts = outside_starts(&g);
    let mut entered: BTreeSet<NodeId> = BTreeSet::new();
    let note = |actions: &[Action], entered: &mut BTreeSet<NodeId>| {
        for a in actions {
            if let Action::Record(r) = a
                && let Entry::Entered { node, .. } = &r.entry
            {
                entered.insert(*node);
            }
        }
    };
    let mut out = Exploration {
        complete: true,
        ..Exploration::default()
    };
    // The mission starts: every primary process, each way its first step may decide.
    let start: Vec<Event> = g
        .primary_processes()
        .into_iter()
        .map(|p| Event::InstanceStarted {
            process: g.process(p).id.clone(),
            vars: Vars::new(),
            start: None,
        })
        .collect();
    let evented: BTreeSet<executive_model::ProcessId> = {
        let e = engine(State::default(), &BTreeMap::new());
        (0..g.processes.len() as u32)
            .map(executive_model::ProcessId)
            .filter(|p| !e.starts_untriggered(*p))
            .collect()
    };
    let mut nodes = Vec::new();
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut queue = VecDeque::new();
    for (labels, run) in within(&State::default(), &start) {
        match run {
            Ok((actions, state)) => {
                note(&actions, &mut entered);
                let key = shape(&g, &state, &starts);
                if seen.contains_key(&key) {
                    continue;
                }
                seen.insert(key, nodes.len());
                nodes.push(Node {
                    state,
                    from: None,
                    label: labels.join(" "),
                    fired: BTreeMap::new(),
                });
                queue.push_back(nodes.len() - 1);
            }
            Err(r) => {
                out.needs_data = Some(format!("the mission does not start: {r}"));
                return out;
            }
        }
    }
    'search: while let Some(at) = queue.pop_front() {
        let state = nodes[at].state.clone();
        if let Some((n, why)) = state
            .instances
            .values()
            .flat_map(|i| i.incidents.iter())
            .next()
        {
            out.needs_data = Some(format!("`{}`: {why}", g.node(*n).id));
            out.complete = false;
            break;
        }
        // Two tokens that came by the same flow to the same element of the same scope: two on
        // the flow, as the translation counts them (a gateway's join included; an activity
        // waiting for its `startQuantity` takes several by design).
        let mut by_flow = BTreeMap::new();
        for t in state.tokens.values() {
            if let Some(f) = t.via
                && !(matches!(t.at, At::Joining) && g.node(t.node).is_activity())
                && by_flow.insert((t.scope, t.node, f), ()).is_some()
                && out.unsafe_run.is_none()
            {
                out.unsafe_run = Some(path_of(&nodes, at));
            }
        }
        let running = state.instances.values().any(|i| i.outcome.is_none());
        let next = inputs(&g, &state, &nodes[at].fired, &codes, &starts);
        if next.is_empty() {
            if running && out.deadlock.is_none() {
                out.deadlock = Some(path_of(&nodes, at));
            }
            continue;
        }
        let failed = |s: &State| {
            s.instances
                .values()
                .any(|i| matches!(i.outcome, Some(Outcome::Failed { .. })))
        };
        let failed_before = failed(&state);
        for (label, event, wait) in next {
            for (taken, run) in within(&state, std::slice::from_ref(&event)) {
                let Ok((actions, mut after)) = run else {
                    continue;
                };
                let label = std::iter::once(label.clone())
                    .chain(taken)
                    .collect::<Vec<_>>()
                    .join(" ");
                // The translation fails tasks only with codes something catches.
                if !failed_before && failed(&after) && label.contains(".fail[") {
                    continue;
                }
                // A process started by an event (another pool's message, a signal) runs one
                // instance at a time, as the translation has one marking per process: an
                // instance started beside a running one is the translation's lost message (or
                // signal heard without effect), cancelled at once.
                let extra = beside(&after, &evented);
                if !extra.is_empty() {
                    let mut e = engine(after, &BTreeMap::new());
                    let mut ignored = Vec::new();
                    for instance in extra {
                        let input = Input {
                            seq: e.state().last_seq + 1,
                            at: 0,
                            event: Event::CancelRequested { instance },
                        };
                        if e.step_into(input, &mut ignored).is_err() {
                            break;
                        }
                    }
                    after = e.state().clone();
                }
                note(&actions, &mut entered);
                let mut fired = nodes[at].fired.clone();
                if let Some(w) = wait
                    && state.waits.get(&w).is_some_and(|w| repeats(&g, w))
                {
                    *fired.entry(w).or_default() += 1;
                }
                fired.retain(|w, _| after.waits.contains_key(w));
                let key = shape(&g, &after, &starts) + &fired_shape(&g, &after, &fired);
                if seen.contains_key(&key) {
                    continue;
                }
                if nodes.len() >= max_states {
                    // Incomplete either way: stop rather than expand what is queued.
                    out.complete = false;
                    break 'search;
                }
                seen.insert(key, nodes.len());
                nodes.push(Node {
                    state: after,
                    from: Some(at),
                    label,
                    fired,
                });
                queue.push_back(nodes.len() - 1);
            }
        }
    }
    out.states = nodes.len();
    // Activities of the processes that run (primary or called), never entered.
    let mut running: BTreeSet<executive_model::ProcessId> =
        g.primary_processes().into_iter().collect();
    let mut grew = true;
    while grew {
        grew = false;
        for (i, n) in g.nodes.iter().enumerate() {
            if let NodeKind::CallActivity(ca) = &n.kind
                && let Some(Called::Process(p)) = &ca.called
                && running.contains(&g.process_of(NodeId(i as u32)))
                && running.insert(*p)
            {
                grew = true;
            }
        }
    }
    for (i, n) in g.nodes.iter().enumerate() {
        let id = NodeId(i as u32);
        if !running.contains(&g.process_of(id)) {
            continue;
        }
        if n.is_activity() && !entered.contains(&id) {
            out.dead_activities.push(n.id.clone());
        }
        if matches!(n.kind, NodeKind::End(_)) && entered.contains(&id) {
            out.ends.insert(n.id.clone());
        }
    }
    out
}
