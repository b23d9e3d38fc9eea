//! The engine: validates an input against the state, then applies it and runs to quiescence.

use std::collections::BTreeMap;
use std::sync::Arc;

use executive_model::{NodeId, NodeKind, ProcessGraph, ProcessId, TaskKind};

use crate::game::Game;
use crate::io::{Action, Entry, Event, Input, Outcome, Rejected, TaskKey, Trigger};
use crate::run::Run;
use crate::state::{At, On, State};
use crate::value::Vars;

/// The BPMN token engine over one validated model.
pub struct Engine {
    graph: Arc<ProcessGraph>,
    state: State,
    reach: BTreeMap<(NodeId, NodeId, bool), Vec<executive_model::FlowId>>,
    /// The ready-token queue, kept empty between steps so a step does not allocate one.
    ready: std::collections::VecDeque<(crate::io::TokenId, u32)>,
    trace_moves: bool,
    game: Option<Game>,
    /// The processes of pools other executives run, with their pool's id (a fleet).
    remote: BTreeMap<executive_model::ProcessId, String>,
}

impl Engine {
    /// An engine with no instance yet.
    pub fn new(graph: Arc<ProcessGraph>) -> Engine {
        Engine::restore(graph, State::default())
    }

    /// An engine resuming from a saved state (the same model it was saved with).
    pub fn restore(graph: Arc<ProcessGraph>, mut state: State) -> Engine {
        for t in state.tokens.values_mut() {
            t.upgrade();
        }
        Engine {
            graph,
            state,
            reach: BTreeMap::new(),
            ready: Default::default(),
            trace_moves: true,
            game: None,
            remote: BTreeMap::new(),
        }
    }

    /// Runs only the pool `participant` (its id or name) of the model's collaboration, as one
    /// executive of a fleet: the other pools' processes never run here, and a message flow
    /// into them leaves the engine as a numbered [`Action::SendMessage`] naming the pool.
    /// Errs, naming the pools there are, when no pool of that id or name has a process.
    pub fn participant(mut self, participant: &str) -> Result<Engine, String> {
        self.remote = crate::messages::remote_processes(&self.graph, participant)?;
        Ok(self)
    }

    /// Leaves `remote`'s processes (with their pool's id) to no one here: they do not start,
    /// and a message flow into them leaves the engine ([`Engine::participant`] with any set of
    /// pools; the timed exploration's vehicles whose battery is empty).
    pub fn with_remote(mut self, remote: BTreeMap<executive_model::ProcessId, String>) -> Engine {
        self.remote = remote;
        self
    }

    /// The processes this engine leaves to other executives, with their pool's id (empty
    /// unless [`Engine::participant`] chose a pool).
    pub fn remote(&self) -> &BTreeMap<executive_model::ProcessId, String> {
        &self.remote
    }

    /// Switches token-game mode on: tasks complete at once unless held ([`Game::hold`]: they
    /// are dispatched and the player completes them), a gateway takes the flows chosen in
    /// [`Game::choices`] (none chosen: the token stops there), events without a definition and
    /// timers without a value fire only when triggered (`Event::WaitTriggered`).
    pub fn game(&mut self) -> &mut Game {
        self.game.get_or_insert_with(Game::default)
    }

    /// Turns the `entered` / `left` / `took` record entries off (benchmarks of raw stepping).
    pub fn with_move_records(mut self, on: bool) -> Engine {
        self.trace_moves = on;
        self
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The commands to give again after a restart, from the state alone: every dispatched task
    /// and open user task (same keys, so a connector treats them as the same goal) and every
    /// armed timer at its absolute deadline (an overdue one fires at once).
    pub fn in_flight(&self) -> Vec<Action> {
        let s = &self.state;
        let commands = s.tokens.values().filter_map(|t| {
            let goal = || t.goal.as_deref().cloned().unwrap_or_default();
            match t.at {
                At::Task(task) => Some(Action::DispatchTask {
                    task,
                    node: t.node,
                    request: goal(),
                }),
                At::UserTask(task) => Some(Action::OpenUserTask {
                    task,
                    node: t.node,
                    context: goal(),
                }),
                _ => None,
            }
        });
        let timers = s.waits.values().filter_map(|w| match w.on {
            On::Timer { key, due, .. } if due != crate::io::Millis::MAX => {
                Some(Action::StartTimer {
                    timer: key,
                    at: due,
                })
            }
            _ => None,
        });
        commands.chain(timers).collect()
    }

    /// Whether an instance of `process` started without naming a start event
    /// (`Event::InstanceStarted` with `start: None`) enters anything: the process has a none
    /// start event, or an activity or gateway without incoming flow. A process that starts
    /// only on messages, signals, timers or conditions does not: such an instance would
    /// complete at once, having entered nothing.
    pub fn starts_untriggered(&self, process: executive_model::ProcessId) -> bool {
        let g = &self.graph;
        let scope = executive_model::Scope::Process(process);
        g.scope_nodes(scope).iter().any(|n| {
            matches!(&g.node(*n).kind, NodeKind::Start(s) if s.triggers.is_empty())
                && g.node(*n).incoming.is_empty()
        }) || !crate::run::implicit_starts(g, scope).is_empty()
    }

    /// The model.
    pub fn graph(&self) -> &Arc<ProcessGraph> {
        &self.graph
    }

    /// Applies one input. On `Err` the state is unchanged.
    #[must_use = "actions must be persisted, then executed by the driver"]
    pub fn step(&mut self, input: Input) -> Result<Vec<Action>, Rejected> {
        // Room for a typical step (7 actions) in one of the allocator's small size classes.
        let mut out = Vec::with_capacity(8);
        self.step_into(input, &mut out).map(|()| out)
    }

    /// [`Engine::step`], appending the actions to `out`: a driver that drains one buffer
    /// step after step allocates none for them. On `Err`, the state and `out` are unchanged.
    pub fn step_into(&mut self, input: Input, out: &mut Vec<Action>) -> Result<(), Rejected> {
        if input.seq <= self.state.last_seq {
            return Err(Rejected::Duplicate {
                seq: input.seq,
                last: self.state.last_seq,
            });
        }
        self.check(&input.event)?;
        let mut ready = std::mem::take(&mut self.ready);
        ready.clear();
        let mut run = Run {
            g: &self.graph,
            s: &mut self.state,
            now: input.at,
            out,
            ready,
            trace_moves: self.trace_moves,
            wave: 0,
            game: self.game.as_ref(),
            throw_now: Default::default(),
            reach: &mut self.reach,
            remote: &self.remote,
        };
        // A message from another executive: its key and its receiver are checked before
        // anything changes.
        if let Event::MessageReceived {
            name,
            correlation,
            flow,
            key,
            ..
        } = &input.event
        {
            let refused = match (key, flow) {
                (Some(k), _) if run.s.delivered.contains(k) => {
                    Some(Rejected::AlreadyDelivered(k.clone()))
                }
                (_, Some(f)) => run.flow_receiver(f, name, correlation.as_ref()).err(),
                _ => None,
            };
            if let Some(r) = refused {
                self.ready = run.ready;
                return Err(r);
            }
        }
        run.s.last_seq = input.seq;
        run.s.now = run.s.now.max(input.at);
        apply(&mut run, input.event);
        run.quiesce();
        self.ready = run.ready;
        Ok(())
    }

    /// The process an `InstanceStarted` starts, if it may start here (at `start`, if named).
    fn check_start(&self, process: &str, start: Option<&str>) -> Result<ProcessId, Rejected> {
        let g = &self.graph;
        let game = self.game.is_some();
        let p = g
            .process_by_id(process)
            .filter(|p| game || g.process(*p).executable)
            .ok_or_else(|| Rejected::UnknownProcess(process.to_owned()))?;
        if let Some(pool) = self.remote.get(&p) {
            return Err(Rejected::Unsupported {
                element: process.to_owned(),
                reason: format!("its pool `{pool}` is run by another executive"),
            });
        }
        if let Some(start) = start {
            let ok = g.node_by_id(start).is_some_and(|n| {
                g.node(n).scope == executive_model::Scope::Process(p)
                    && g.node(n).incoming.is_empty()
            });
            if !ok {
                return Err(Rejected::UnknownStart {
                    process: process.to_owned(),
                    start: start.to_owned(),
                });
            }
        }
        Ok(p)
    }

    /// Refuses inputs that do not fit the state, before anything changes.
    fn check(&self, event: &Event) -> Result<(), Rejected> {
        let s = &self.state;
        let g = &self.graph;
        match event {
            Event::InstanceStarted { process, start, .. } => {
                self.check_start(process, start.as_deref()).map(|_| ())
            }
            Event::TaskCompleted { task, .. } | Event::TaskFailed { task, .. } => {
                match s.tokens.get(&task.token).map(|t| &t.at) {
                    Some(At::Task(k)) if k == task => Ok(()),
                    _ => Err(Rejected::UnknownTask(*task)),
                }
            }
            Event::UserTaskAnswered { task, answer, .. } => {
                let Some(tok) = s
                    .tokens
                    .get(&task.token)
                    .filter(|t| t.at == At::UserTask(*task))
                else {
                    return Err(Rejected::UnknownTask(*task));
                };
                check_answer(g, tok.node, *task, answer)
            }
            Event::BranchTaken { token, flows } => {
                let node = match s.tokens.get(token) {
                    Some(t) if t.at == At::Deciding => g.node(t.node),
                    _ => return Err(Rejected::NotDeciding(*token)),
                };
                let exclusive = matches!(&node.kind,
                    NodeKind::Gateway(gw) if gw.kind == executive_model::GatewayKind::Exclusive);
                let fits = !flows.is_empty()
                    && flows.iter().all(|f| node.outgoing.contains(f))
                    && (!exclusive || flows.len() == 1);
                if fits {
                    Ok(())
                } else {
                    Err(Rejected::NotDeciding(*token))
                }
            }
            Event::TimerFired { timer } => match s.waits.get(&timer.wait).map(|w| &w.on) {
                Some(On::Timer { key, .. }) if key == timer => Ok(()),
                _ => Err(Rejected::UnknownTimer(*timer)),
            },
            // Along a flow: its target is checked in `step`, where expressions can be evaluated.
            Event::MessageReceived { flow: Some(_), .. } => Ok(()),
            Event::MessageReceived { name, .. } => {
                let waiting = s
                    .waits
                    .values()
                    .any(|w| matches!(&w.on, On::Message(n, _) if n == name));
                let starts = g.processes.iter().any(|p| {
                    p.executable
                        && p.nodes.iter().any(|n| {
                            let is_name = |m: &Option<executive_model::MessageId>| {
                                m.is_some_and(|m| g.messages[m.index()].name == *name)
                            };
                            match &g.node(*n).kind {
                                NodeKind::Start(st) => st.triggers.iter().any(|d| {
                                    matches!(d, executive_model::EventDefinition::Message(m) if is_name(m))
                                }),
                                NodeKind::Task(t) => t.instantiate && is_name(&t.message),
                                _ => false,
                            }
                        })
                });
                if waiting || starts {
                    Ok(())
                } else {
                    Err(Rejected::NoReceiver(name.clone()))
                }
            }
            Event::CancelRequested { instance } => match s.instances.get(instance) {
                Some(i) if i.outcome.is_none() => Ok(()),
                _ => Err(Rejected::UnknownInstance(instance.0)),
            },
            Event::WaitTriggered { wait } => match s.waits.contains_key(wait) {
                true => Ok(()),
                false => Err(Rejected::UnknownWait(*wait)),
            },
            Event::SignalReceived { .. } | Event::DataChanged { .. } => Ok(()),
        }
    }
}

/// A user-task answer must give every declared form field, with its declared type.
fn check_answer(
    g: &ProcessGraph,
    node: NodeId,
    task: TaskKey,
    answer: &Vars,
) -> Result<(), Rejected> {
    let NodeKind::Task(t) = &g.node(node).kind else {
        return Ok(());
    };
    if t.kind != TaskKind::User {
        return Ok(());
    }
    let Some(b) = &t.binding else { return Ok(()) };
    for m in &b.outputs {
        // A form field is an output whose source is a plain field name.
        let field = m.source.text.as_str();
        if !field.chars().all(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let Some(v) = answer.get(field) else {
            return Err(Rejected::BadAnswer {
                task,
                reason: format!("field `{field}` is missing"),
            });
        };
        if let Some(ty) = &m.ty {
            crate::eval::convert(v.clone(), ty).map_err(|e| Rejected::BadAnswer {
                task,
                reason: format!("field `{field}`: {e}"),
            })?;
        }
    }
    Ok(())
}

fn apply(run: &mut Run<'_>, event: Event) {
    match event {
        Event::InstanceStarted {
            process,
            vars,
            start,
        } => {
            let Some(p) = run.g.process_by_id(&process) else {
                return;
            };
            let (_, root) = run.open_instance(p, vars, Some(process));
            let start = start.and_then(|s| run.g.node_by_id(&s));
            run.start_process_scope(root, p, start);
        }
        Event::TaskCompleted { task, output } => {
            let t = task.token;
            run.record(task.instance, || Entry::Completed {
                task,
                output: output.clone(),
            });
            if let Some(tok) = run.s.tokens.get_mut(&t) {
                tok.at = At::Ready;
            }
            if run.game.is_some_and(|g| g.decide) {
                return run.complete_activity(t);
            }
            match run.apply_outputs(t, &output) {
                Ok(()) => {
                    run.connector_sent(t);
                    run.complete_activity(t);
                }
                Err(e) => {
                    let label = run.g.node(run.s.tokens[&t].node).label().to_owned();
                    run.task_error(t, "TYPE_MISMATCH", &format!("{label}: {e}"));
                }
            }
        }
        Event::TaskFailed {
            task,
            code,
            message,
        } => {
            if let Some(tok) = run.s.tokens.get_mut(&task.token) {
                tok.at = At::Ready;
            }
            // The failure is recorded before what it causes, with the input's own strings.
            let first = run.out.len();
            run.task_error(task.token, &code, &message);
            let failed = crate::io::Record {
                instance: task.instance,
                at: run.now,
                entry: Entry::Failed {
                    task,
                    code,
                    message,
                },
            };
            run.out.insert(first, Action::Record(failed));
        }
        Event::UserTaskAnswered {
            task,
            answer,
            operator,
        } => {
            let t = task.token;
            run.record(task.instance, || Entry::Answered {
                task,
                operator,
                answer: answer.clone(),
            });
            run.out.push(Action::CloseUserTask { task });
            if let Some(tok) = run.s.tokens.get_mut(&t) {
                tok.at = At::Ready;
            }
            match run.apply_outputs(t, &answer) {
                Ok(()) => run.complete_activity(t),
                Err(e) => run.incident(t, e),
            }
        }
        Event::BranchTaken { token, flows } => {
            if let Some(tok) = run.s.tokens.get_mut(&token) {
                tok.at = At::Ready;
            }
            run.leave_gateway(token, &flows);
        }
        Event::TimerFired { timer } => {
            let Some(w) = run.s.waits.get(&timer.wait) else {
                return;
            };
            let node = w.node;
            run.record(timer.instance, || Entry::TimerFired { timer, node });
            run.trigger(timer.wait, Trigger::Timer, String::new(), &Vars::new());
        }
        Event::MessageReceived {
            name,
            correlation,
            payload,
            flow,
            key,
        } => {
            if let Some(k) = key {
                run.s.delivered.insert(k);
            }
            match flow {
                Some(f) => {
                    if let Ok(r) = run.flow_receiver(&f, &name, correlation.as_ref()) {
                        run.deliver_to(r, &f, &name, correlation.as_ref(), &payload);
                    }
                }
                None => {
                    run.deliver_message(&name, correlation.as_ref(), &payload);
                }
            }
        }
        Event::SignalReceived { name } => {
            let instance = crate::io::InstanceId(0);
            run.broadcast(instance, None, &name);
        }
        Event::DataChanged { key, value } => {
            for (id, i) in &run.s.instances {
                if i.outcome.is_none() {
                    run.out.push(Action::Record(crate::io::Record {
                        instance: *id,
                        at: run.now,
                        entry: Entry::Data {
                            key: key.clone(),
                            value: value.clone(),
                        },
                    }));
                }
            }
            run.s.data.insert(key, value);
            run.start_conditions();
        }
        Event::WaitTriggered { wait } => {
            let what = match run.s.waits.get(&wait).map(|w| &w.on) {
                Some(On::Message(..)) => Trigger::Message,
                Some(On::Signal(_)) => Trigger::Signal,
                Some(On::Timer { .. }) => Trigger::Timer,
                Some(On::Manual) => Trigger::Signal,
                _ => Trigger::Condition,
            };
            run.trigger(wait, what, "triggered".to_owned(), &Vars::new());
        }
        Event::CancelRequested { instance } => run.finish_instance(instance, Outcome::Cancelled),
    }
}
