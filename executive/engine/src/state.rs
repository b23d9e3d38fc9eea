//! The engine's state: instances, scopes, tokens and subscriptions, in ordered maps only, so
//! that the state is serializable, comparable and hashable (replay checks and model checking).

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};
use smallvec::SmallVec;
use thin_vec::ThinVec;

use crate::io::{InstanceId, Millis, Outcome, ScopeId, TaskKey, TimerKey, TokenId, WaitId};
use crate::value::{Value, Vars};
use executive_model::{FlowId, NodeId, ProcessId};

/// Everything the engine knows. Restore it to resume; compare two to check a replay.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct State {
    /// Next id to mint (instances, scopes, tokens and waits share the counter).
    pub next_id: u64,
    /// Sequence number of the last accepted input.
    pub last_seq: u64,
    /// Mission time of the last accepted input.
    pub now: Millis,
    /// Instances, running or ended.
    pub instances: BTreeMap<InstanceId, Instance>,
    /// Live scope instances.
    pub scopes: BTreeMap<ScopeId, ScopeState>,
    /// Live tokens.
    pub tokens: BTreeMap<TokenId, Token>,
    /// Live subscriptions.
    pub waits: BTreeMap<WaitId, Wait>,
    /// System data from `DataChanged`, visible to every expression after the variables.
    pub data: Vars,
    /// Tokens waiting at inclusive or complex joins, re-checked when tokens move.
    pub joins: BTreeSet<TokenId>,
    /// Tokens waiting at any join (gateway or `startQuantity`), by scope and node.
    #[serde(with = "pairs")]
    pub joining: BTreeMap<(ScopeId, NodeId), BTreeSet<TokenId>>,
    /// Complex gateways that fired and now absorb the rest of their wave, by scope.
    pub fired_complex: BTreeSet<(ScopeId, NodeId)>,
    /// Conditional start events of top-level processes whose condition held at the last
    /// evaluation (a new instance starts on false -> true only).
    #[serde(default)]
    pub start_conditions: BTreeSet<NodeId>,
    /// Messages sent along message flows to pools other executives run: the last number minted.
    #[serde(default)]
    pub sent: u64,
    /// Keys of the messages delivered from other executives (each applied once).
    #[serde(default)]
    pub delivered: BTreeSet<String>,
}

/// One process instance.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Instance {
    /// The process it runs.
    pub process: ProcessId,
    /// Its root scope while it runs.
    pub root: Option<ScopeId>,
    /// How it ended, once it has.
    pub outcome: Option<Outcome>,
    /// Escalations nothing caught, by code.
    pub uncaught_escalations: Vec<String>,
    /// Incidents: tokens stuck with a reason, by node.
    pub incidents: Vec<(NodeId, String)>,
}

/// A running scope: a process, sub-process, called process, or one body of a loop.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ScopeState {
    /// The instance.
    pub instance: InstanceId,
    /// The enclosing scope; `None` for the instance root.
    pub parent: Option<ScopeId>,
    /// The token (in the parent scope) whose activity this scope executes.
    pub owner: Option<TokenId>,
    /// What it executes.
    pub kind: ScopeKind,
    /// Local variables.
    pub vars: Vars,
    /// Completed activities that can be compensated, oldest first.
    pub compensable: ThinVec<Compensable>,
    /// Set while the scope is being torn down, so completion is not reported twice.
    pub ending: bool,
    /// Tokens in the scope.
    pub tokens: TokenSet,
    /// Event sub-process start subscriptions of the scope.
    pub waits: ThinVec<WaitId>,
}

/// A set of tokens in id order: the tokens of a scope, the throwers a step put back. Most such
/// sets hold one or two tokens at a time, so the set is a sorted list that keeps two inline: a
/// `BTreeSet` allocates a node for its first token and walks it to drop. It is written as the
/// list it is, as a `BTreeSet` was, and read back sorted and without repeats whatever order a
/// snapshot gives.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct TokenSet(SmallVec<[TokenId; 2]>);

impl TokenSet {
    /// Adds `t`; false if it was there. Tokens are minted in increasing order, so this
    /// appends, in the usual case.
    pub fn insert(&mut self, t: TokenId) -> bool {
        match self.0.binary_search(&t) {
            Ok(_) => false,
            Err(i) => {
                self.0.insert(i, t);
                true
            }
        }
    }

    /// Removes `t`; false if it was not there.
    pub fn remove(&mut self, t: &TokenId) -> bool {
        match self.0.binary_search(t) {
            Ok(i) => {
                self.0.remove(i);
                true
            }
            Err(_) => false,
        }
    }

    /// Whether `t` is in the set.
    pub fn contains(&self, t: &TokenId) -> bool {
        self.0.binary_search(t).is_ok()
    }

    /// How many tokens.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The tokens, in id order.
    pub fn iter(&self) -> impl Iterator<Item = &TokenId> {
        self.0.iter()
    }
}

impl Serialize for TokenSet {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter())
    }
}

impl<'de> Deserialize<'de> for TokenSet {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut ids = Vec::<TokenId>::deserialize(d)?;
        ids.sort_unstable();
        ids.dedup();
        Ok(Self(SmallVec::from_vec(ids)))
    }
}

/// What a scope executes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ScopeKind {
    /// A process: the instance root, or one called by a call activity.
    Process(ProcessId),
    /// A sub-process node (embedded, event, transaction, ad-hoc).
    SubProcess(NodeId),
    /// One execution of the body of a looping or multi-instance activity.
    Body(NodeId),
}

/// A token: a position in a scope.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Token {
    /// The instance.
    pub instance: InstanceId,
    /// The scope it moves in.
    pub scope: ScopeId,
    /// The node it is at.
    pub node: NodeId,
    /// The flow it arrived by.
    pub via: Option<FlowId>,
    /// What it is doing there.
    pub at: At,
    /// Dispatches so far (task attempts).
    pub attempts: u32,
    /// The token runs the body of a looping activity: finishing it ends the body scope.
    pub body: bool,
    /// The token runs a compensation handler for this thrower (waiting throw token, if any).
    pub compensating: Option<Box<CompensationRun>>,
    /// Its subscriptions (catch events, boundaries).
    pub waits: ThinVec<WaitId>,
    /// The goal of the command in flight for this token: its dispatch's request, or its open
    /// user task's context (none when empty). With `at` and `node` it gives the command again
    /// after a restart ([`crate::Engine::in_flight`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Box<Vars>>,
    /// The whole command, as snapshots written before `goal` kept it: read, and moved into
    /// `goal` when an engine is restored; never written.
    #[serde(default, skip_serializing)]
    pub(crate) command: Option<Box<crate::io::Action>>,
}

impl Token {
    /// Moves a command read from an older snapshot into `goal`.
    pub(crate) fn upgrade(&mut self) {
        if let Some(c) = self.command.take() {
            self.goal = match *c {
                crate::io::Action::DispatchTask { request: g, .. }
                | crate::io::Action::OpenUserTask { context: g, .. } => {
                    (!g.is_empty()).then(|| Box::new(g))
                }
                _ => None,
            };
        }
    }
}

/// A command's goal as a token keeps it: none when empty.
pub(crate) fn goal(vars: &Vars) -> Option<Box<Vars>> {
    (!vars.is_empty()).then(|| Box::new(vars.clone()))
}

/// A completed activity that can be compensated.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Compensable {
    /// The activity.
    pub node: NodeId,
    /// A completed sub-process: its own completed activities, oldest first.
    pub inner: ThinVec<Compensable>,
}

/// One compensation handler to run.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Handler {
    /// The activity associated with a compensation boundary event.
    Activity(NodeId),
    /// A compensation event sub-process (its start event) of a completed sub-process, with
    /// that sub-process's completed activities.
    EventSub(NodeId, ThinVec<Compensable>),
    /// The compensation of this completed sub-process is over (recorded as leaving it).
    Done(NodeId),
}

/// A compensation run in progress: the handlers still to run, newest first.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CompensationRun {
    /// The token waiting for the run to finish (throw event or transaction cancel), if any.
    pub waiter: Option<TokenId>,
    /// Handlers still to run after the current one.
    pub rest: Vec<Handler>,
}

/// What a token is doing at its node.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum At {
    /// Moving; the run loop advances it.
    Ready,
    /// A task dispatched to a connector.
    Task(TaskKey),
    /// A user task open on the ground.
    UserTask(TaskKey),
    /// Waiting for events (catch event, receive task, event-based gateway).
    Catching,
    /// Waiting at a join (gateway or `startQuantity`).
    Joining,
    /// Running a child scope (sub-process, call activity, loop).
    Scope(ScopeId),
    /// Running the bodies of a looping or multi-instance activity.
    Looping(Box<Loop>),
    /// Waiting for compensation handlers to finish.
    Compensating,
    /// Stuck; the reason is an incident of the instance.
    Incident,
    /// At a diverging gateway, waiting for its branches to be chosen (token games only).
    Deciding,
}

/// The progress of a standard loop or a multi-instance activity.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Loop {
    /// Bodies started so far.
    pub started: u64,
    /// Bodies completed so far.
    pub completed: u64,
    /// Multi-instance: how many bodies in all (standard loop: `None`).
    pub total: Option<u64>,
    /// Running body scopes.
    pub running: Vec<ScopeId>,
    /// Multi-instance output elements by loop counter.
    pub outputs: BTreeMap<u64, Value>,
    /// The multi-instance input items, if an input collection is used.
    pub items: Option<Vec<Value>>,
    /// Multi-instance behaviour events thrown so far.
    pub thrown: u64,
}

/// A subscription: what a waiting token or scope will react to.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Wait {
    /// The instance.
    pub instance: InstanceId,
    /// The catching node: catch event, boundary event, event sub-process start, receive task,
    /// or the target of an event-based gateway.
    pub node: NodeId,
    /// The token waiting (catch event, receive task, gateway) or carrying the boundary
    /// (the activity's token). `None` for event sub-process starts.
    pub token: Option<TokenId>,
    /// The scope whose event sub-process start this is.
    pub scope: ScopeId,
    /// What triggers it.
    pub on: On,
}

/// What triggers a subscription.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum On {
    /// A message by name, optionally with the correlation value it expects.
    Message(String, Option<Value>),
    /// A signal by name.
    Signal(String),
    /// A timer armed until `due`; `left` repetitions after this one (`None` = unbounded).
    Timer {
        /// The current arming.
        key: TimerKey,
        /// Deadline.
        due: Millis,
        /// Repetitions left after this one.
        left: Option<u32>,
    },
    /// Nothing but a manual trigger (token games: an event without a definition).
    Manual,
    /// A condition; `last` is its value at the previous evaluation (fires on false -> true).
    Condition {
        /// The index of the trigger in the node's event definitions.
        trigger: usize,
        /// Value at the last evaluation.
        last: bool,
    },
}

/// Serializes a map with composite keys as a list of pairs (JSON keys must be strings).
mod pairs {
    use std::collections::BTreeMap;

    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(super) fn serialize<K: Serialize, V: Serialize, S: Serializer>(
        map: &BTreeMap<K, V>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        s.collect_seq(map.iter())
    }

    pub(super) fn deserialize<'de, K, V, D>(d: D) -> Result<BTreeMap<K, V>, D::Error>
    where
        K: Deserialize<'de> + Ord,
        V: Deserialize<'de>,
        D: Deserializer<'de>,
    {
        Ok(Vec::<(K, V)>::deserialize(d)?.into_iter().collect())
    }
}

impl State {
    /// Checks that a state read back from a store can be resumed on `graph`: every element,
    /// flow and process it names exists, and every instance, scope, token and wait it refers to
    /// is held. A store damaged (or edited) into another shape is refused with the first
    /// problem, before the engine relies on it.
    pub fn check(&self, graph: &executive_model::ProcessGraph) -> Result<(), String> {
        fn within(index: usize, len: usize, kind: &str, what: &str) -> Result<(), String> {
            (index < len)
                .then_some(())
                .ok_or_else(|| format!("{what} names {kind} #{index} of {len}"))
        }
        fn held<K: Ord, V>(
            map: &BTreeMap<K, V>,
            k: &K,
            id: u64,
            kind: &str,
            what: &str,
        ) -> Result<(), String> {
            map.contains_key(k)
                .then_some(())
                .ok_or_else(|| format!("{what} names {kind} {id} which is not held"))
        }
        let node = |n: NodeId, what: &str| within(n.index(), graph.nodes.len(), "element", what);
        let flow = |f: FlowId, what: &str| within(f.index(), graph.flows.len(), "flow", what);
        let process =
            |p: ProcessId, what: &str| within(p.index(), graph.processes.len(), "process", what);
        let instance = |i: InstanceId, what: &str| held(&self.instances, &i, i.0, "instance", what);
        let scope = |s: ScopeId, what: &str| held(&self.scopes, &s, s.0, "scope", what);
        let token = |t: TokenId, what: &str| held(&self.tokens, &t, t.0, "token", what);
        let wait = |w: WaitId, what: &str| held(&self.waits, &w, w.0, "wait", what);
        fn compensable(
            c: &[Compensable],
            node: &dyn Fn(NodeId, &str) -> Result<(), String>,
        ) -> Result<(), String> {
            c.iter().try_for_each(|c| {
                node(c.node, "a compensable activity")?;
                compensable(&c.inner, node)
            })
        }
        let kind = |k: &ScopeKind, what: &str| match *k {
            ScopeKind::Process(p) => process(p, what),
            ScopeKind::SubProcess(n) | ScopeKind::Body(n) => node(n, what),
        };
        for (id, i) in &self.instances {
            let what = format!("instance {}", id.0);
            process(i.process, &what)?;
            if let Some(s) = i.root {
                scope(s, &what)?;
            }
            i.incidents.iter().try_for_each(|(n, _)| node(*n, &what))?;
        }
        for (id, s) in &self.scopes {
            let what = format!("scope {}", id.0);
            instance(s.instance, &what)?;
            if let Some(p) = s.parent {
                scope(p, &what)?;
            }
            if let Some(t) = s.owner {
                token(t, &what)?;
            }
            kind(&s.kind, &what)?;
            compensable(&s.compensable, &node)?;
            s.tokens.iter().try_for_each(|t| token(*t, &what))?;
            s.waits.iter().try_for_each(|w| wait(*w, &what))?;
        }
        for (id, t) in &self.tokens {
            let what = format!("token {}", id.0);
            instance(t.instance, &what)?;
            scope(t.scope, &what)?;
            node(t.node, &what)?;
            if let Some(f) = t.via {
                flow(f, &what)?;
            }
            t.waits.iter().try_for_each(|w| wait(*w, &what))?;
            match &t.at {
                At::Scope(s) => scope(*s, &what)?,
                At::Looping(l) => l.running.iter().try_for_each(|s| scope(*s, &what))?,
                At::Task(k) | At::UserTask(k) => instance(k.instance, &what)?,
                _ => {}
            }
            if let Some(run) = &t.compensating {
                if let Some(w) = run.waiter {
                    token(w, &what)?;
                }
                for h in &run.rest {
                    match h {
                        Handler::Activity(n) | Handler::Done(n) => node(*n, &what)?,
                        Handler::EventSub(n, c) => {
                            node(*n, &what)?;
                            compensable(c, &node)?;
                        }
                    }
                }
            }
        }
        for (id, w) in &self.waits {
            let what = format!("wait {}", id.0);
            instance(w.instance, &what)?;
            node(w.node, &what)?;
            scope(w.scope, &what)?;
            if let Some(t) = w.token {
                token(t, &what)?;
            }
        }
        self.joins.iter().try_for_each(|t| token(*t, "a join"))?;
        for ((s, n), ts) in &self.joining {
            scope(*s, "a join")?;
            node(*n, "a join")?;
            ts.iter().try_for_each(|t| token(*t, "a join"))?;
        }
        for (s, n) in &self.fired_complex {
            scope(*s, "a complex gateway")?;
            node(*n, "a complex gateway")?;
        }
        self.start_conditions
            .iter()
            .try_for_each(|n| node(*n, "a conditional start"))
    }
}
