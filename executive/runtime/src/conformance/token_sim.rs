//! `trace conformance token-simulation DIR`: runs bpmn-js-token-simulation scenarios on the
//! engine in token-game mode and compares the element enter/exit traces ("projected mode" of
//! the corpus README: flow nodes only; exact order, or for interleaved parallel branches the
//! same multiset of events).

use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::Arc;

use executive_engine::{Action, Engine, Entry, Event, Input, Outcome, TaskKey, Vars};
use executive_model::{NodeId, NodeKind, Options, ProcessGraph};
use serde::Deserialize;

/// The reviewed, deliberate difference from the simulator's reading of BPMN, found by what the
/// engine did, not by the scenario's name: an error nothing catches.
pub const UNCAUGHT_ERROR: &str = "an error end event that nothing catches fails the instance \
     (BPMN 2.0 10.5.1, and the betsy corpus); the simulator ends the sub-process normally and \
     continues";

/// One scenario of `scenarios.json`.
#[derive(Debug, Deserialize)]
pub struct Scenario {
    /// Name (diagram name, `#n` for several).
    pub name: String,
    /// The diagram file.
    pub diagram: String,
    /// Upstream `describe` block.
    pub section: String,
    /// Not verified upstream: informative only.
    #[serde(default)]
    pub skipped_upstream: bool,
    /// The steps.
    pub steps: Vec<serde_json::Value>,
}

/// The outcome of one scenario.
#[derive(Debug)]
pub struct ScenarioResult {
    /// Scenario name.
    pub name: String,
    /// Upstream section.
    pub section: String,
    /// Informative only.
    pub informative: bool,
    /// A reviewed deviation, with its reason.
    pub deviation: Option<&'static str>,
    /// `None` when it passed, else why not.
    pub failure: Option<String>,
}

/// Runs every scenario of `dir/scenarios.json` against the diagrams in `dir/simulator`.
pub fn run_corpus(dir: &Path) -> Result<Vec<ScenarioResult>, String> {
    let path = dir.join("scenarios.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let scenarios: Vec<Scenario> =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(scenarios
        .iter()
        .map(|s| {
            let (failure, uncaught) = match run(dir, s) {
                Ok(()) => (None, false),
                Err((why, uncaught)) => (Some(why), uncaught),
            };
            ScenarioResult {
                name: s.name.clone(),
                section: s.section.clone(),
                informative: s.skipped_upstream,
                deviation: uncaught.then_some(UNCAUGHT_ERROR),
                failure,
            }
        })
        .collect())
}

struct Player {
    g: Arc<ProcessGraph>,
    engine: Engine,
    seq: u64,
    held: BTreeMap<NodeId, Vec<TaskKey>>,
    trace: Vec<String>,
    started: Vec<executive_engine::InstanceId>,
    after_event_gateway: bool,
    last_caught: Option<NodeId>,
    /// An error nothing caught failed an instance ([`UNCAUGHT_ERROR`]).
    uncaught: bool,
}

/// Plays `s`; a failure says whether an error nothing caught failed an instance on the way.
fn run(dir: &Path, s: &Scenario) -> Result<(), (String, bool)> {
    let path = dir.join("simulator").join(&s.diagram);
    let bytes = std::fs::read(&path).map_err(|e| (format!("{}: {e}", path.display()), false))?;
    let options = Options {
        token_game: true,
        script_connector: true,
        ..Options::default()
    };
    let loaded = executive_model::load_with(&bytes, &options);
    let g = Arc::new(loaded.graph.ok_or_else(|| {
        let first = loaded
            .diagnostics
            .iter()
            .find(|d| d.severity == executive_model::Severity::Error);
        let why = format!(
            "does not load: {}",
            first.map_or("?", |d| d.message.as_str())
        );
        (why, false)
    })?);
    let mut p = Player {
        engine: Engine::new(Arc::clone(&g)),
        g,
        seq: 0,
        held: BTreeMap::new(),
        trace: Vec::new(),
        started: Vec::new(),
        after_event_gateway: false,
        last_caught: None,
        uncaught: false,
    };
    p.engine.game();
    p.steps(dir, &s.steps).map_err(|why| (why, p.uncaught))
}

impl Player {
    /// Runs the scenario's steps in order.
    fn steps(&mut self, dir: &Path, steps: &[serde_json::Value]) -> Result<(), String> {
        for step in steps {
            let str_of = |k: &str| step[k].as_str().unwrap_or_default().to_owned();
            match step["op"].as_str().unwrap_or_default() {
                "setConfig" => {
                    let gw = self.node(&str_of("gateway"))?;
                    let flows = step["activeOutgoing"]
                        .as_array()
                        .into_iter()
                        .flatten()
                        .filter_map(|f| f.as_str())
                        .filter_map(|f| self.g.flows.iter().position(|x| x.id == f))
                        .map(|i| executive_model::FlowId(i as u32))
                        .collect();
                    self.engine.game().choices.insert(gw, flows);
                }
                "waitAtElement" => {
                    let n = self.node(&str_of("element"))?;
                    self.engine.game().hold.insert(n);
                }
                "trigger" => self.trigger(&str_of("element"), step["scopeOf"].as_str())?,
                "signal" => self.message_flow(&str_of("element"))?,
                "expectTrace" => {
                    let fixture = dir.join("simulator").join(str_of("fixture"));
                    let text = std::fs::read_to_string(&fixture)
                        .map_err(|e| format!("{}: {e}", fixture.display()))?;
                    let events: Vec<String> =
                        serde_json::from_str(&text).map_err(|e| e.to_string())?;
                    let expected: Vec<String> = events
                        .iter()
                        .filter_map(|e| {
                            let mut parts = e.split(':');
                            let (action, element) = (parts.next()?, parts.next()?);
                            // A collapsed sub-process is reported by its diagram plane, `<id>_plane`.
                            let element = element
                                .strip_suffix("_plane")
                                .filter(|id| self.g.node_by_id(id).is_some())
                                .unwrap_or(element);
                            (matches!(action, "enter" | "exit")
                                && self.g.node_by_id(element).is_some())
                            .then(|| format!("{action}:{element}"))
                        })
                        .collect();
                    let got = std::mem::take(&mut self.trace);
                    if got != expected {
                        let (mut a, mut b) = (got.clone(), expected.clone());
                        a.sort();
                        b.sort();
                        if a != b {
                            return Err(format!(
                                "trace differs:\n  expected {expected:?}\n  got      {got:?}"
                            ));
                        }
                    }
                }
                "expectInstanceCompleted" => {
                    let first = self.started.first().ok_or("no instance was started")?;
                    let inst = &self.engine.state().instances[first];
                    if inst.outcome != Some(Outcome::Completed) {
                        return Err(format!("instance not completed: {:?}", inst.outcome));
                    }
                }
                other => return Err(format!("unknown step `{other}`")),
            }
        }
        Ok(())
    }

    fn node(&self, id: &str) -> Result<NodeId, String> {
        self.g
            .node_by_id(id)
            .ok_or_else(|| format!("no element `{id}`"))
    }

    fn trigger(&mut self, element: &str, scope_of: Option<&str>) -> Result<(), String> {
        let n = self.node(element)?;
        // A waiting subscription at the element (for a boundary: on the activity `scope_of`).
        let s = self.engine.state();
        let wait = s
            .waits
            .iter()
            .filter(|(_, w)| w.node == n)
            .find(|(_, w)| match scope_of {
                Some(x) => w
                    .token
                    .and_then(|t| s.tokens.get(&t))
                    .is_some_and(|t| self.g.node(t.node).id == x),
                None => true,
            })
            .map(|(id, _)| *id);
        if let Some(wait) = wait {
            return self.apply(Event::WaitTriggered { wait });
        }
        if let Some(task) = self
            .held
            .get_mut(&n)
            .and_then(|v| (!v.is_empty()).then(|| v.remove(0)))
        {
            return self.apply(Event::TaskCompleted {
                task,
                output: Vars::new(),
            });
        }
        let implicit = self.g.node(n).incoming.is_empty()
            && !matches!(self.g.node(n).kind, NodeKind::Boundary(_));
        if (matches!(self.g.node(n).kind, NodeKind::Start(_)) || implicit)
            && let executive_model::Scope::Process(p) = self.g.node(n).scope
        {
            let process = self.g.process(p).id.clone();
            return self.apply(Event::InstanceStarted {
                process,
                vars: Vars::new(),
                start: Some(element.to_owned()),
            });
        }
        let s = self.engine.state();
        let waiting: Vec<String> = s
            .waits
            .values()
            .map(|w| self.g.node(w.node).id.clone())
            .chain(
                s.tokens
                    .values()
                    .map(|t| format!("{} ({:?})", self.g.node(t.node).id, t.at)),
            )
            .collect();
        Err(format!(
            "nothing waits at `{element}`; waiting: {waiting:?}"
        ))
    }

    fn message_flow(&mut self, id: &str) -> Result<(), String> {
        let (target, message) = self
            .g
            .collaborations
            .iter()
            .flat_map(|c| &c.message_flows)
            .find(|m| m.id == id)
            .map(|m| (m.target.clone(), m.message))
            .ok_or_else(|| format!("no message flow `{id}`"))?;
        if self.g.node_by_id(&target).is_some() {
            return self.trigger(&target, None);
        }
        // A pool: start its process; a pool without one (a black box, §9.2) takes the message
        // out of the model, and nothing here moves.
        let pool = self
            .g
            .participants()
            .find(|p| p.id == target)
            .ok_or_else(|| {
                format!("message flow `{id}` targets `{target}`, which is not a pool or element")
            })?;
        let Some(process) = pool.process else {
            return Ok(());
        };
        // Started once, at the message start event the message is for (the flow's message,
        // else the only message start); a process without one starts as any other.
        let starts: Vec<(&str, Option<executive_model::MessageId>)> = self
            .g
            .scope_nodes(executive_model::Scope::Process(process))
            .iter()
            .map(|n| self.g.node(*n))
            .filter_map(|n| match &n.kind {
                NodeKind::Start(s) => s.triggers.iter().find_map(|t| match t {
                    executive_model::EventDefinition::Message(m) => Some((n.id.as_str(), *m)),
                    _ => None,
                }),
                _ => None,
            })
            .collect();
        let start = starts
            .iter()
            .find(|(_, m)| m.is_some() && *m == message)
            .or((starts.len() == 1).then(|| &starts[0]))
            .map(|(id, _)| (*id).to_owned());
        let process = self.g.process(process).id.clone();
        self.apply(Event::InstanceStarted {
            process,
            vars: Vars::new(),
            start,
        })
    }

    fn apply(&mut self, first: Event) -> Result<(), String> {
        let mut queue = VecDeque::from([first]);
        while let Some(event) = queue.pop_front() {
            self.seq += 1;
            if self.seq > 10_000 {
                return Err("the scenario does not settle (more than 10,000 steps)".to_owned());
            }
            let actions = self
                .engine
                .step(Input {
                    seq: self.seq,
                    at: 0,
                    event,
                })
                .map_err(|e| e.to_string())?;
            for a in actions {
                match a {
                    Action::DispatchTask { task, node, .. } => {
                        self.held.entry(node).or_default().push(task);
                    }
                    Action::CancelTask { task } => {
                        queue.retain(
                            |e| !matches!(e, Event::TaskCompleted { task: k, .. } if *k == task),
                        );
                        for held in self.held.values_mut() {
                            held.retain(|k| *k != task);
                        }
                    }
                    Action::Record(r) => self.project(r.instance, r.entry),
                    _ => {}
                }
            }
        }
        Ok(())
    }

    /// Maps record entries to the simulator's vocabulary: start and boundary events, link
    /// catch events, event sub-processes and the event an event-based gateway passes to are
    /// only exited; an event-based gateway is never exited; of the withdrawn elements only
    /// activities are exited.
    fn project(&mut self, instance: executive_engine::InstanceId, entry: Entry) {
        let kind = |n: NodeId| &self.g.node(n).kind;
        let name = |n: NodeId| self.g.node(n).id.clone();
        let event_gateway = |n: NodeId| matches!(kind(n), NodeKind::Gateway(g) if matches!(g.kind, executive_model::GatewayKind::EventBased { .. }));
        match entry {
            Entry::InstanceStarted { .. } => self.started.push(instance),
            Entry::InstanceFinished {
                outcome: Outcome::Failed { .. },
                ..
            } => self.uncaught = true,
            Entry::Entered { node, .. } => {
                let silent = match kind(node) {
                    NodeKind::Start(_) | NodeKind::Boundary(_) => true,
                    NodeKind::Catch(c) => c
                        .triggers
                        .iter()
                        .any(|d| matches!(d, executive_model::EventDefinition::Link(_))),
                    NodeKind::SubProcess(sp) => {
                        matches!(sp.kind, executive_model::SubProcessKind::Event)
                    }
                    _ => false,
                };
                if !silent && !self.after_event_gateway {
                    self.trace.push(format!("enter:{}", name(node)));
                }
                self.after_event_gateway = false;
            }
            Entry::Left { node, .. } => {
                if event_gateway(node) {
                    self.after_event_gateway = true;
                } else {
                    self.trace.push(format!("exit:{}", name(node)));
                }
            }
            // Only an activity interrupted by its own boundary event is exited.
            Entry::Withdrawn { node, .. } => {
                let by_own_boundary = self.last_caught.is_some_and(|b| {
                    matches!(kind(b), NodeKind::Boundary(x) if x.attached_to == node && x.interrupting)
                });
                if self.g.node(node).is_activity() && by_own_boundary {
                    self.trace.push(format!("exit:{}", name(node)));
                }
            }
            Entry::Caught { node, .. } => self.last_caught = Some(node),
            _ => {}
        }
    }
}
