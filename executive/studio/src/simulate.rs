//! The token game in the browser: one BPMN model played step by step on the executive's own
//! engine in token-game mode, driven from outside (the studio page, through HTTP).
//!
//! This module only translates: a player's [`Act`] becomes engine [`Event`]s, and the engine
//! [`State`](executive_engine::State) becomes a [`View`]. Every BPMN rule is the engine's
//! (`executive-engine`, the same `Engine::step` that `trace run` drives); nothing here decides
//! where a token goes.
//!
//! # How a model is played
//! - [`Simulation::start`] loads nothing itself: it takes a graph loaded with
//!   `executive_model::Options { token_game: true, script_connector: true, .. }` and starts it as
//!   `trace run` does: one instance of every executable top-level process that starts by itself
//!   (its first none start event, or its activities and gateways without incoming flow). A
//!   model whose processes start only on a message, signal, timer or condition starts
//!   nothing: their start events are offered as waits of kind `start` until one is fired
//!   (bpmn-js-token-simulation's way of starting, as the conformance runner
//!   `executive_runtime::conformance::token_sim` does). A drawing without executable processes
//!   (`isExecutable="false"`) is played as if they were, as the engine's token game allows.
//! - **Tasks** (every task but a receive task: service, user, send, script, business-rule,
//!   manual and plain) are *held* ([`executive_engine::Game::hold`]): the engine dispatches them
//!   and they wait for the player, who completes them ([`Act::Complete`]) or fails them with an
//!   error code ([`Act::Fail`]); the engine then takes an error boundary of the task, an outer
//!   catcher, or fails the instance, as at run time. A token game does not run a script
//!   task's assignments nor evaluate a task's inputs (the engine's token-game rule).
//! - **Waits** (timers, message, signal and conditional catches, the targets of an
//!   event-based gateway, boundary events on active activities, event sub-process starts,
//!   receive tasks, events without a definition) are fired by the player ([`Act::Fire`], by
//!   the element's id; for a boundary event, the boundary's id). A timer never fires by the
//!   clock: when fired, mission time moves on to its deadline (never back), so a timer's
//!   arithmetic is that of a run started at mission time 0 ([`Simulation::now`]). A timer
//!   without a value (a sketch) fires at the current time. Subscriptions that fired stay in a
//!   token game (a non-interrupting boundary or event sub-process can fire again).
//! - **Signals and messages from outside** are supported, as the engine supports them:
//!   [`Act::Signal`] broadcasts a signal the model declares to every catcher waiting for it;
//!   [`Act::Message`] delivers a message by name, without correlation key or payload, to the
//!   catcher waiting for it or to a process that starts on it.
//!
//! # Gateways: the two modes
//! The engine's token game has two ways to decide a diverging exclusive, inclusive or complex
//! gateway, one per [`Mode`]:
//! - [`Mode::Explore`] (the default, [`Simulation::start`]): the engine's exploration game
//!   ([`executive_engine::Game::decide`]). Every diverging exclusive gateway, and every
//!   inclusive or complex gateway with one incoming flow, **stops the token until the player
//!   chooses** (it is listed in [`View::gateways`]); a gateway with one outgoing flow passes.
//!   [`Act::Choose`] takes effect at once for a token waiting there, and from then on for every
//!   token that arrives (like bpmn-js-token-simulation's `setConfig`). The engine keeps no
//!   data in this mode: a task's result is recorded but sets no variable, conditions on
//!   gateways are not read, a multi-instance activity runs one body and a standard loop runs
//!   once. This is what a token game on a mission needs: a mission's gateways read the
//!   results of real activities, which a player does not have.
//! - [`Mode::Data`] ([`Simulation::start_with`]): the plain token game
//!   ([`executive_engine::Game::choices`]). A task's result goes through its output mappings as
//!   at run time (so a task whose `trace:task` declares outputs must be given a result that
//!   has them, or it fails with `TYPE_MISMATCH`), and a gateway without a choice evaluates its
//!   conditions as at run time: the first that holds, else the default flow, else an incident
//!   (as is a condition reading a variable no result has set); **a gateway without a
//!   choice whose outgoing flows carry no condition consumes the token** — the engine's
//!   token-game default: the token stops there and is gone, and the instance completes if it
//!   was the last. No token ever waits at a gateway in this mode ([`View::gateways`] stays
//!   empty), so a choice must be made before the token arrives.
//!
//! In both modes a choice is also given to the engine's `choices`, which an inclusive or
//! complex gateway that both joins and splits reads when it fires.
//!
//! # Bounds
//! The engine stops a step after a million token moves without waiting and records an
//! incident on the token (the model loops without a task, wait or choice on the loop). The
//! choices this module applies by itself are bounded too ([`MAX_AUTOMATIC`] per act), and a
//! player's act never runs more than that many engine steps: a loop through chosen gateways
//! only is reported as [`SimError::Runaway`] and as an incident of the view. The trace keeps
//! its first [`MAX_TRACE`] events (a model that loops would otherwise fill it with millions).
//! An act that reaches the engine's own bound still costs that step: about 1.5 s and a few
//! hundred megabytes of record entries while it runs, in a debug build.
//!
//! # Acts from a web page
//! Everything an [`Act`] names is checked against the model and the state before the engine
//! sees it; an act that does not fit is a [`SimError`] naming the element, never a panic.
//! [`Act::from_json`] reads the page's JSON (`{"act": "complete", "element": "Task_1"}`) and
//! reports a malformed act (a code that is not a string, …) the same way.

use std::collections::BTreeMap;
use std::sync::Arc;

use executive_engine::{
    At, Engine, Entry, Event, Input, InstanceId, Millis, On, Outcome, Rejected, TokenId, Vars,
};
use executive_model::{
    EventDefinition, FlowId, GatewayKind, NodeId, NodeKind, ProcessGraph, ProcessId, TaskKind,
};
use serde::{Deserialize, Serialize};

/// The most engine steps one act may cause (its own and the choices applied after it).
pub const MAX_AUTOMATIC: u64 = 10_000;

/// The most trace events kept ([`View::trace`]); later ones are dropped, which the view's
/// incidents say.
pub const MAX_TRACE: usize = 10_000;

/// How the engine decides gateways and keeps data (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Exploration without data: every diverging gateway waits for the player's choice.
    #[default]
    Explore,
    /// Data: task results set variables, conditions decide unchosen gateways.
    Data,
}

/// One move of the player.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "act", rename_all = "snake_case")]
pub enum Act {
    /// Complete the task waiting at `element` (the oldest token, if several wait there).
    Complete {
        /// The task's element id.
        element: String,
        /// The task's result: a JSON object of fields (none: an empty result).
        #[serde(default)]
        result: Option<serde_json::Value>,
    },
    /// Fail the task waiting at `element` with a BPMN error code.
    Fail {
        /// The task's element id.
        element: String,
        /// The error code (a boundary that catches every error takes any code).
        code: String,
    },
    /// Take these outgoing flows at `gateway`, now and from now on.
    Choose {
        /// The gateway's element id.
        gateway: String,
        /// Outgoing sequence flow ids (exactly one at an exclusive gateway).
        flows: Vec<String>,
    },
    /// Fire the wait at `element` (the oldest, if several wait there).
    Fire {
        /// The catching element's id (a boundary event's own id, a start event's id, …).
        element: String,
    },
    /// Broadcast a signal the model declares, by name.
    Signal {
        /// The signal's name.
        name: String,
    },
    /// Deliver a message by name (no correlation key, no payload).
    Message {
        /// The message's name.
        name: String,
    },
}

impl Act {
    /// Reads an act from a page's JSON; a malformed one is [`SimError::BadAct`], naming the
    /// element it was about when it names one.
    pub fn from_json(value: serde_json::Value) -> Result<Act, SimError> {
        let about = ["element", "gateway", "name"]
            .iter()
            .find_map(|k| value.get(*k).and_then(|v| v.as_str()))
            .unwrap_or("?")
            .to_owned();
        serde_json::from_value(value).map_err(|e| SimError::BadAct {
            element: about,
            reason: e.to_string(),
        })
    }

    /// The element (or name) the act is about, for logs and errors.
    pub fn subject(&self) -> &str {
        match self {
            Act::Complete { element, .. } | Act::Fail { element, .. } | Act::Fire { element } => {
                element
            }
            Act::Choose { gateway, .. } => gateway,
            Act::Signal { name } | Act::Message { name } => name,
        }
    }
}

/// Why an act (or the start) was refused. The simulation is unchanged, except for
/// [`SimError::Runaway`].
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// No process of the model starts, by itself or on a trigger.
    #[error("nothing in the model starts: no process has a start event or a start element")]
    NothingStarts,
    /// The simulation has ended; nothing more can happen.
    #[error("`{0}`: the simulation has ended")]
    Ended(String),
    /// The model has no flow node with this id.
    #[error("`{0}`: no such element in the model")]
    UnknownElement(String),
    /// The element is a task, but no token waits there for the player.
    #[error("`{element}`: no task waits there")]
    NotWaiting {
        /// The element id.
        element: String,
    },
    /// Nothing waits at the element for a trigger.
    #[error("`{element}`: nothing waits there to be fired")]
    NothingWaits {
        /// The element id.
        element: String,
    },
    /// The element cannot take a choice of flows.
    #[error("`{gateway}`: {reason}")]
    NotChoosable {
        /// The element id.
        gateway: String,
        /// Why.
        reason: String,
    },
    /// A flow of a choice is not an outgoing flow of the gateway.
    #[error("`{gateway}`: `{flow}` is not one of its outgoing flows")]
    UnknownFlow {
        /// The gateway's id.
        gateway: String,
        /// The flow id given.
        flow: String,
    },
    /// The act is malformed.
    #[error("`{element}`: {reason}")]
    BadAct {
        /// The element (or name) it is about.
        element: String,
        /// What is wrong.
        reason: String,
    },
    /// The model declares no signal of that name.
    #[error("`{0}`: the model declares no signal of that name")]
    UnknownSignal(String),
    /// The engine refused the input.
    #[error("`{element}`: the engine refused it: {source}")]
    Rejected {
        /// The element (or name) the act was about.
        element: String,
        /// The engine's reason.
        source: Rejected,
    },
    /// The act set off more than [`MAX_AUTOMATIC`] engine steps: the model loops through chosen
    /// gateways without waiting. Those steps were applied; the loop stopped.
    #[error(
        "`{element}`: stopped after {steps} engine steps: the model loops through chosen gateways without waiting"
    )]
    Runaway {
        /// The element the act was about.
        element: String,
        /// The steps taken.
        steps: u64,
    },
}

/// The number of tokens at one element.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct TokenCount {
    /// The element id.
    pub element: String,
    /// Tokens there (a running sub-process, call activity or loop holds one itself).
    pub count: u32,
}

/// A task waiting for the player.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct TaskView {
    /// The element id.
    pub element: String,
    /// Its name, or its id.
    pub name: String,
    /// The BPMN element (`serviceTask`, `userTask`, …).
    pub kind: String,
    /// The resource its `trace:task` binding names, if any.
    pub resource: Option<String>,
    /// The error codes its error boundaries catch (`*`: a boundary catching every error).
    pub catches: Vec<String>,
}

/// A wait the player can fire.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct WaitView {
    /// The element to fire.
    pub element: String,
    /// `timer`, `message`, `signal`, `condition`, `manual` (no definition) or `start`.
    pub kind: String,
    /// What it is, for people.
    pub label: String,
}

/// A gateway holding a token until the player chooses its flows.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct GatewayView {
    /// The gateway's id.
    pub element: String,
    /// Its outgoing flow ids, in document order.
    pub flows: Vec<String>,
}

/// The simulation as the page shows it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct View {
    /// Where tokens are, in document order of the elements.
    pub tokens: Vec<TokenCount>,
    /// Tasks waiting to be completed or failed, oldest token first.
    pub tasks: Vec<TaskView>,
    /// Waits that can be fired, oldest first.
    pub waits: Vec<WaitView>,
    /// Gateways waiting for a choice ([`Mode::Explore`] only), oldest token first.
    pub gateways: Vec<GatewayView>,
    /// Every `enter:Id` and `exit:Id` so far, in bpmn-js-token-simulation's vocabulary.
    pub trace: Vec<String>,
    /// Every instance has ended.
    pub ended: bool,
    /// How it ended, once it has: `completed`, `terminated`, `cancelled` or
    /// `failed: CODE: message` (with several instances, `process: outcome` joined by `; `).
    pub outcome: Option<String>,
    /// Tokens stuck with a reason (`Id: reason`), and runaway acts.
    pub incidents: Vec<String>,
    /// Engine inputs applied so far.
    pub steps: u64,
}

/// One model being played.
pub struct Simulation {
    g: Arc<ProcessGraph>,
    engine: Engine,
    mode: Mode,
    seq: u64,
    now: Millis,
    choices: BTreeMap<NodeId, Vec<FlowId>>,
    /// Start events offered until anything has started: (start event, its process).
    starts: Vec<(NodeId, ProcessId)>,
    trace: Vec<String>,
    trace_full: bool,
    after_event_gateway: bool,
    last_caught: Option<NodeId>,
    incidents: Vec<String>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulation")
            .field("mode", &self.mode)
            .field("steps", &self.seq)
            .field("now", &self.now)
            .finish_non_exhaustive()
    }
}

impl Simulation {
    /// Starts the model in [`Mode::Explore`].
    pub fn start(graph: Arc<ProcessGraph>) -> Result<Simulation, SimError> {
        Simulation::start_with(graph, Mode::Explore)
    }

    /// Starts the model in `mode`: every process that starts by itself gets an instance, as
    /// with `trace run`; a model that only starts on triggers offers its start events.
    pub fn start_with(graph: Arc<ProcessGraph>, mode: Mode) -> Result<Simulation, SimError> {
        let mut engine = Engine::new(Arc::clone(&graph));
        let game = engine.game();
        game.decide = mode == Mode::Explore;
        game.hold = held_tasks(&graph);
        let mut sim = Simulation {
            g: graph,
            engine,
            mode,
            seq: 0,
            now: 0,
            choices: BTreeMap::new(),
            starts: Vec::new(),
            trace: Vec::new(),
            trace_full: false,
            after_event_gateway: false,
            last_caught: None,
            incidents: Vec::new(),
        };
        let (untriggered, triggered): (Vec<_>, Vec<_>) = startable(&sim.g)
            .into_iter()
            .partition(|p| sim.engine.starts_untriggered(*p));
        if untriggered.is_empty() {
            sim.starts = triggered
                .iter()
                .flat_map(|p| start_events(&sim.g, *p).into_iter().map(move |n| (n, *p)))
                .collect();
            if sim.starts.is_empty() {
                return Err(SimError::NothingStarts);
            }
        }
        for p in untriggered {
            let process = sim.g.process(p).id.clone();
            tracing::debug!(%process, "simulation starts an instance");
            let event = Event::InstanceStarted {
                process: process.clone(),
                vars: Vars::new(),
                start: None,
            };
            sim.apply(event, &process)?;
        }
        Ok(sim)
    }

    /// The mode it plays in.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Mission time (milliseconds from the start, which is mission time 0): it moves only
    /// when a timer is fired.
    pub fn now(&self) -> Millis {
        self.now
    }

    /// Plays one act. On `Err` nothing changed, except after [`SimError::Runaway`].
    pub fn act(&mut self, act: Act) -> Result<(), SimError> {
        tracing::debug!(?act, "simulation act");
        if self.ended() {
            return Err(SimError::Ended(act.subject().to_owned()));
        }
        let before = self.seq;
        match act {
            Act::Complete { element, result } => self.complete(&element, result)?,
            Act::Fail { element, code } => self.fail(&element, code)?,
            Act::Choose { gateway, flows } => self.choose(&gateway, &flows)?,
            Act::Fire { element } => self.fire(&element)?,
            Act::Signal { name } => self.signal(name)?,
            Act::Message { name } => self.message(name)?,
        }
        if !self.engine.state().instances.is_empty() {
            // Something started: the start events are no longer offered.
            self.starts.clear();
        }
        self.settle(before)
    }

    /// The simulation now.
    pub fn view(&self) -> View {
        let ended = self.ended();
        View {
            tokens: self.tokens(),
            tasks: self.tasks(),
            waits: self.waits(),
            gateways: self.gateways(),
            trace: self.trace.clone(),
            ended,
            outcome: ended.then(|| self.outcome()),
            incidents: self.incidents(),
            steps: self.seq,
        }
    }

    fn complete(
        &mut self,
        element: &str,
        result: Option<serde_json::Value>,
    ) -> Result<(), SimError> {
        let output = match result {
            None | Some(serde_json::Value::Null) => Vars::new(),
            Some(serde_json::Value::Object(fields)) => fields
                .iter()
                .map(|(k, v)| (k.clone(), executive_engine::Value::from_json(v)))
                .collect(),
            Some(other) => {
                return Err(SimError::BadAct {
                    element: element.to_owned(),
                    reason: format!("a result is a JSON object of fields, not {other}"),
                });
            }
        };
        let task = self.waiting_task(element)?;
        self.apply(Event::TaskCompleted { task, output }, element)
    }

    fn fail(&mut self, element: &str, code: String) -> Result<(), SimError> {
        if code.trim().is_empty() {
            return Err(SimError::BadAct {
                element: element.to_owned(),
                reason: "an error code must not be empty".to_owned(),
            });
        }
        let task = self.waiting_task(element)?;
        let message = format!("failed by the player with `{code}`");
        self.apply(
            Event::TaskFailed {
                task,
                code,
                message,
            },
            element,
        )
    }

    /// The key of the oldest task waiting at `element`.
    fn waiting_task(&self, element: &str) -> Result<executive_engine::TaskKey, SimError> {
        let n = self.node(element)?;
        self.running_tokens()
            .find_map(|(_, t)| match t.at {
                At::Task(k) if t.node == n => Some(k),
                _ => None,
            })
            .ok_or_else(|| SimError::NotWaiting {
                element: element.to_owned(),
            })
    }

    fn choose(&mut self, gateway: &str, flows: &[String]) -> Result<(), SimError> {
        let n = self.node(gateway)?;
        let node = self.g.node(n);
        let not = |reason: &str| SimError::NotChoosable {
            gateway: gateway.to_owned(),
            reason: reason.to_owned(),
        };
        let exclusive = match &node.kind {
            NodeKind::Gateway(gw) => match gw.kind {
                GatewayKind::Exclusive => true,
                GatewayKind::Inclusive | GatewayKind::Complex => false,
                GatewayKind::Parallel => return Err(not("a parallel gateway takes every flow")),
                GatewayKind::EventBased { .. } => {
                    return Err(not("an event-based gateway follows the event that occurs"));
                }
            },
            _ => return Err(not("not a gateway")),
        };
        if flows.is_empty() {
            return Err(not("choose at least one outgoing flow"));
        }
        if exclusive && flows.len() > 1 {
            return Err(not("an exclusive gateway takes exactly one flow"));
        }
        let mut chosen = Vec::new();
        for f in flows {
            let id = node
                .outgoing
                .iter()
                .copied()
                .find(|o| self.g.flow(*o).id == *f)
                .ok_or_else(|| SimError::UnknownFlow {
                    gateway: gateway.to_owned(),
                    flow: f.clone(),
                })?;
            if !chosen.contains(&id) {
                chosen.push(id);
            }
        }
        chosen.sort();
        self.engine.game().choices.insert(n, chosen.clone());
        self.choices.insert(n, chosen);
        Ok(())
    }

    fn fire(&mut self, element: &str) -> Result<(), SimError> {
        let n = self.node(element)?;
        let running: Vec<InstanceId> = self.running().collect();
        let wait = self
            .engine
            .state()
            .waits
            .iter()
            .find(|(_, w)| w.node == n && running.contains(&w.instance))
            .map(|(id, w)| (*id, w.on.clone()));
        match wait {
            Some((_, On::Timer { key, due, .. })) => {
                if due != Millis::MAX {
                    self.now = self.now.max(due);
                }
                self.apply(Event::TimerFired { timer: key }, element)
            }
            Some((wait, _)) => self.apply(Event::WaitTriggered { wait }, element),
            None => self.fire_start(n, element),
        }
    }

    /// Starts the process of an offered start event.
    fn fire_start(&mut self, n: NodeId, element: &str) -> Result<(), SimError> {
        let Some(&(_, p)) = self.starts.iter().find(|(s, _)| *s == n) else {
            return Err(SimError::NothingWaits {
                element: element.to_owned(),
            });
        };
        let event = Event::InstanceStarted {
            process: self.g.process(p).id.clone(),
            vars: Vars::new(),
            start: Some(element.to_owned()),
        };
        self.apply(event, element)
    }

    fn signal(&mut self, name: String) -> Result<(), SimError> {
        if name.is_empty() || !self.g.signals.iter().any(|s| s.name == name) {
            return Err(SimError::UnknownSignal(name));
        }
        let subject = name.clone();
        self.apply(Event::SignalReceived { name }, &subject)
    }

    fn message(&mut self, name: String) -> Result<(), SimError> {
        if name.is_empty() {
            return Err(SimError::BadAct {
                element: name,
                reason: "a message needs a name (fire an unnamed one at its element)".to_owned(),
            });
        }
        let subject = name.clone();
        let event = Event::MessageReceived {
            name,
            correlation: None,
            payload: Vars::new(),
            flow: None,
            key: None,
        };
        self.apply(event, &subject)
    }

    /// [`Mode::Explore`]: gives every token waiting at a gateway the player has chosen for its
    /// choice, until none is left or the act has taken [`MAX_AUTOMATIC`] steps.
    fn settle(&mut self, before: u64) -> Result<(), SimError> {
        while let Some((token, node, flows)) = self.next_decision() {
            let element = self.g.node(node).id.clone();
            if self.seq - before >= MAX_AUTOMATIC {
                let steps = self.seq - before;
                tracing::warn!(%element, steps, "simulation act stopped: the model loops");
                self.incidents.push(format!(
                    "{element}: stopped after {steps} engine steps in one act: the model loops through chosen gateways without waiting"
                ));
                return Err(SimError::Runaway { element, steps });
            }
            self.apply(Event::BranchTaken { token, flows }, &element)?;
        }
        Ok(())
    }

    /// The oldest token waiting at a gateway the player has chosen for.
    fn next_decision(&self) -> Option<(TokenId, NodeId, Vec<FlowId>)> {
        self.running_tokens().find_map(|(id, t)| {
            let chosen = self.choices.get(&t.node)?;
            (t.at == At::Deciding).then(|| (*id, t.node, chosen.clone()))
        })
    }

    /// Gives the engine one input, then reads what it recorded.
    fn apply(&mut self, event: Event, element: &str) -> Result<(), SimError> {
        let input = Input {
            seq: self.seq + 1,
            at: self.now,
            event,
        };
        let actions = self
            .engine
            .step(input)
            .map_err(|source| SimError::Rejected {
                element: element.to_owned(),
                source,
            })?;
        self.seq += 1;
        for a in actions {
            if let executive_engine::Action::Record(r) = a {
                self.project(r.entry);
            }
        }
        Ok(())
    }

    /// Appends to the trace, up to [`MAX_TRACE`] events.
    fn record(&mut self, event: String) {
        if self.trace.len() < MAX_TRACE {
            self.trace.push(event);
        } else if !self.trace_full {
            self.trace_full = true;
            self.incidents
                .push(format!("trace: only the first {MAX_TRACE} events are kept"));
        }
    }

    /// Maps record entries to bpmn-js-token-simulation's vocabulary, as the conformance runner
    /// does (`executive_runtime::conformance::token_sim`): start and boundary events, link catch
    /// events, event sub-processes and the event an event-based gateway passes to are only
    /// exited; an event-based gateway is never exited; of the withdrawn elements only
    /// activities interrupted by their own boundary event are exited.
    fn project(&mut self, entry: Entry) {
        let g = Arc::clone(&self.g);
        match entry {
            Entry::Entered { node, .. } => {
                if !silent_entry(&g.node(node).kind) && !self.after_event_gateway {
                    self.record(format!("enter:{}", g.node(node).id));
                }
                self.after_event_gateway = false;
            }
            Entry::Left { node, .. } => {
                if is_event_gateway(&g.node(node).kind) {
                    self.after_event_gateway = true;
                } else {
                    self.record(format!("exit:{}", g.node(node).id));
                }
            }
            Entry::Withdrawn { node, .. } => {
                let by_own_boundary = self.last_caught.is_some_and(
                    |b| matches!(&g.node(b).kind, NodeKind::Boundary(x) if x.attached_to == node),
                );
                if g.node(node).is_activity() && by_own_boundary {
                    self.record(format!("exit:{}", g.node(node).id));
                }
            }
            Entry::Caught { node, .. } => self.last_caught = Some(node),
            _ => {}
        }
    }

    fn node(&self, id: &str) -> Result<NodeId, SimError> {
        self.g
            .node_by_id(id)
            .ok_or_else(|| SimError::UnknownElement(id.to_owned()))
    }

    /// Instances still running.
    fn running(&self) -> impl Iterator<Item = InstanceId> + '_ {
        self.engine
            .state()
            .instances
            .iter()
            .filter(|(_, i)| i.outcome.is_none())
            .map(|(id, _)| *id)
    }

    /// Tokens of running instances, oldest first.
    fn running_tokens(&self) -> impl Iterator<Item = (&TokenId, &executive_engine::Token)> {
        let s = self.engine.state();
        s.tokens.iter().filter(|(_, t)| {
            s.instances
                .get(&t.instance)
                .is_some_and(|i| i.outcome.is_none())
        })
    }

    fn ended(&self) -> bool {
        let s = self.engine.state();
        self.starts.is_empty()
            && !s.instances.is_empty()
            && s.instances.values().all(|i| i.outcome.is_some())
    }

    fn tokens(&self) -> Vec<TokenCount> {
        let mut by_node: BTreeMap<NodeId, u32> = BTreeMap::new();
        for (_, t) in self.running_tokens() {
            *by_node.entry(t.node).or_default() += 1;
        }
        by_node
            .into_iter()
            .map(|(n, count)| TokenCount {
                element: self.g.node(n).id.clone(),
                count,
            })
            .collect()
    }

    fn tasks(&self) -> Vec<TaskView> {
        self.running_tokens()
            .filter(|(_, t)| matches!(t.at, At::Task(_)))
            .map(|(_, t)| task_view(&self.g, t.node))
            .collect()
    }

    fn waits(&self) -> Vec<WaitView> {
        let s = self.engine.state();
        let running: Vec<InstanceId> = self.running().collect();
        let mut out: Vec<WaitView> = s
            .waits
            .iter()
            .filter(|(_, w)| running.contains(&w.instance))
            .map(|(_, w)| self.wait_view(w))
            .collect();
        out.extend(self.starts.iter().map(|(n, p)| WaitView {
            element: self.g.node(*n).id.clone(),
            kind: "start".to_owned(),
            label: format!(
                "{}: starts process `{}`",
                self.g.node(*n).label(),
                self.g.process(*p).id
            ),
        }));
        out
    }

    fn wait_view(&self, w: &executive_engine::Wait) -> WaitView {
        let s = self.engine.state();
        let node = self.g.node(w.node);
        let (kind, what) = match &w.on {
            On::Timer { due, .. } if *due == Millis::MAX => ("timer", "timer".to_owned()),
            On::Timer { due, .. } => ("timer", format!("timer due {}", mission_clock(*due))),
            On::Message(name, _) if name.is_empty() => ("message", "message".to_owned()),
            On::Message(name, _) => ("message", format!("message `{name}`")),
            On::Signal(name) if name.is_empty() => ("signal", "signal".to_owned()),
            On::Signal(name) => ("signal", format!("signal `{name}`")),
            On::Condition { .. } => ("condition", "condition".to_owned()),
            On::Manual => ("manual", "fired by hand".to_owned()),
        };
        let owner = w.token.and_then(|t| s.tokens.get(&t)).map(|t| t.node);
        let place = match (&node.kind, owner) {
            (NodeKind::Boundary(b), _) => {
                format!(", boundary of `{}`", self.g.node(b.attached_to).id)
            }
            (_, Some(o)) if is_event_gateway(&self.g.node(o).kind) => {
                format!(", after event-based gateway `{}`", self.g.node(o).id)
            }
            (_, None) => ", event sub-process start".to_owned(),
            _ => String::new(),
        };
        WaitView {
            element: node.id.clone(),
            kind: kind.to_owned(),
            label: format!("{}: {what}{place}", node.label()),
        }
    }

    fn gateways(&self) -> Vec<GatewayView> {
        self.running_tokens()
            .filter(|(_, t)| t.at == At::Deciding)
            .map(|(_, t)| GatewayView {
                element: self.g.node(t.node).id.clone(),
                flows: self
                    .g
                    .node(t.node)
                    .outgoing
                    .iter()
                    .map(|f| self.g.flow(*f).id.clone())
                    .collect(),
            })
            .collect()
    }

    fn outcome(&self) -> String {
        let s = self.engine.state();
        let each: Vec<(String, String)> = s
            .instances
            .values()
            .filter_map(|i| {
                let o = i.outcome.as_ref()?;
                Some((self.g.process(i.process).id.clone(), outcome_text(o)))
            })
            .collect();
        match each.as_slice() {
            [(_, only)] => only.clone(),
            many => many
                .iter()
                .map(|(p, o)| format!("{p}: {o}"))
                .collect::<Vec<_>>()
                .join("; "),
        }
    }

    fn incidents(&self) -> Vec<String> {
        let s = self.engine.state();
        s.instances
            .values()
            .flat_map(|i| &i.incidents)
            .map(|(n, why)| format!("{}: {why}", self.g.node(*n).id))
            .chain(self.incidents.iter().cloned())
            .collect()
    }
}

/// Every task the engine would dispatch in a token game waits for the player: every task but
/// a receive task, which waits for its message.
fn held_tasks(g: &ProcessGraph) -> std::collections::BTreeSet<NodeId> {
    (0..g.nodes.len() as u32)
        .map(NodeId)
        .filter(|n| matches!(&g.node(*n).kind, NodeKind::Task(t) if t.kind != TaskKind::Receive))
        .collect()
}

/// The processes `trace run` starts (executable, top-level, not called); a drawing with none
/// of those plays its top-level, uncalled processes.
fn startable(g: &ProcessGraph) -> Vec<ProcessId> {
    let primary = g.primary_processes();
    if !primary.is_empty() {
        return primary;
    }
    let called: Vec<ProcessId> = g
        .nodes
        .iter()
        .filter_map(|n| match &n.kind {
            NodeKind::CallActivity(c) => match &c.called {
                Some(executive_model::Called::Process(p)) => Some(*p),
                _ => None,
            },
            _ => None,
        })
        .collect();
    (0..g.processes.len() as u32)
        .map(ProcessId)
        .filter(|p| !g.process(*p).imported && !called.contains(p))
        .collect()
}

/// The start events (and instantiating receive tasks) of a process that starts on triggers.
fn start_events(g: &ProcessGraph, p: ProcessId) -> Vec<NodeId> {
    executive_runtime::waiting::triggered_starts(g, p)
        .into_iter()
        .map(|(n, _, _)| n)
        .fold(Vec::new(), |mut out, n| {
            if !out.contains(&n) {
                out.push(n);
            }
            out
        })
}

fn task_view(g: &ProcessGraph, n: NodeId) -> TaskView {
    let node = g.node(n);
    let resource = match &node.kind {
        NodeKind::Task(t) => t
            .binding
            .as_ref()
            .and_then(|b| b.resource.as_deref().map(str::to_owned)),
        _ => None,
    };
    let mut catches: Vec<String> = Vec::new();
    for &b in &node.boundaries {
        let NodeKind::Boundary(boundary) = &g.node(b).kind else {
            continue;
        };
        for d in &boundary.triggers {
            let code = match d {
                EventDefinition::Error { error: None, .. } => "*".to_owned(),
                EventDefinition::Error { error: Some(e), .. } => {
                    let x = &g.errors[e.index()];
                    x.code.clone().unwrap_or_else(|| x.id.clone())
                }
                _ => continue,
            };
            if !catches.contains(&code) {
                catches.push(code);
            }
        }
    }
    TaskView {
        element: node.id.clone(),
        name: node.label().to_owned(),
        kind: node.kind.element_name().to_owned(),
        resource,
        catches,
    }
}

fn silent_entry(kind: &NodeKind) -> bool {
    match kind {
        NodeKind::Start(_) | NodeKind::Boundary(_) => true,
        NodeKind::Catch(c) => c
            .triggers
            .iter()
            .any(|d| matches!(d, EventDefinition::Link(_))),
        NodeKind::SubProcess(sp) => matches!(sp.kind, executive_model::SubProcessKind::Event),
        _ => false,
    }
}

fn is_event_gateway(kind: &NodeKind) -> bool {
    matches!(kind, NodeKind::Gateway(g) if matches!(g.kind, GatewayKind::EventBased { .. }))
}

fn outcome_text(o: &Outcome) -> String {
    match o {
        Outcome::Completed => "completed".to_owned(),
        Outcome::Terminated => "terminated".to_owned(),
        Outcome::Cancelled => "cancelled".to_owned(),
        Outcome::Failed { code, message } => format!("failed: {code}: {message}"),
    }
}

/// Mission time from the start of the simulation: `T+1d02h03m04s`.
fn mission_clock(ms: Millis) -> String {
    let s = ms.max(0) / 1000;
    let (d, h, m, s) = (s / 86_400, s / 3600 % 24, s / 60 % 60, s % 60);
    if d > 0 {
        format!("T+{d}d{h:02}h{m:02}m{s:02}s")
    } else {
        format!("T+{h:02}h{m:02}m{s:02}s")
    }
}
