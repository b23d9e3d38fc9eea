//! What a run waits for, read from the engine state alone (pure; the driver does the
//! printing): whether anything is still *awaited*, what is waited on and where, and, when
//! nothing is, why the run is stuck (incidents and waits nothing can satisfy).
//!
//! **Awaited** means something that can still happen without the executive doing anything
//! more, in a running instance:
//! - a task in flight on a connector (the connector holds its goal: it answers, fails it, or
//!   reports it lost), or a user task open on one;
//! - an armed timer (the driver fires it);
//! - a message, signal or condition subscription (and a join, or the start of a process that
//!   starts only on a message or signal) — but only while something *could* still trigger it:
//!   either anything in the first two groups is still awaited (its outcome may throw the
//!   message or signal, write the variable, bring the token to the join), or an outside system
//!   can deliver it ([`Outside`]: system data for conditions; no connector delivers messages
//!   or signals to `trace run` today).
//!
//! When running instances remain and nothing is awaited, no input can ever arrive: the run is
//! stuck, and the incidents and the dead waits say why.

use std::collections::BTreeSet;

use executive_engine::{At, Millis, On, State, TaskKey};
use executive_model::{EventDefinition, NodeId, NodeKind, ProcessGraph, ProcessId};

/// What outside systems can deliver to this run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Outside {
    /// Messages from outside (no connector delivers them today).
    pub messages: bool,
    /// Signals from outside (no connector delivers them today).
    pub signals: bool,
    /// System data (telemetry), which conditions read.
    pub data: bool,
}

/// What an item waits for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum What {
    /// A task in flight on a connector.
    Task {
        /// The task key.
        task: TaskKey,
        /// The resource it was dispatched to.
        resource: String,
    },
    /// A user task open on the ground.
    UserTask {
        /// The task key.
        task: TaskKey,
    },
    /// An armed timer.
    Timer {
        /// Its deadline (mission time).
        due: Millis,
    },
    /// A message.
    Message(String),
    /// A signal.
    Signal(String),
    /// A condition turning true.
    Condition,
    /// A join waiting for its other branches.
    Join,
    /// A process that starts only on a trigger and has not started.
    Start {
        /// The process id.
        process: String,
        /// The trigger (`message `go``, `signal `s``, `a timer`, `a condition`).
        trigger: String,
    },
}

/// One wait: what, where, in which instance.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Item {
    /// A stable identity (for "since when").
    pub key: String,
    /// The instance (`None`: a process not started).
    pub instance: Option<u64>,
    /// The element id.
    pub element: String,
    /// The element's name, if it has one.
    pub name: Option<String>,
    /// What it waits for.
    pub what: What,
}

/// A token stuck on an incident.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Incident {
    /// The instance.
    pub instance: u64,
    /// The element id.
    pub element: String,
    /// The element's name, if it has one.
    pub name: Option<String>,
    /// Why.
    pub message: String,
}

/// The run at one moment.
#[derive(Clone, Debug, Default)]
pub struct Assessment {
    /// What can still happen.
    pub awaited: Vec<Item>,
    /// Waits nothing can satisfy any more (non-empty only when nothing is awaited), and tasks
    /// whose connector no longer holds them.
    pub dead: Vec<(Item, String)>,
    /// Tokens stuck on incidents in running instances.
    pub incidents: Vec<Incident>,
    /// Instances still running.
    pub running: Vec<u64>,
}

impl Assessment {
    /// Running instances (or processes waiting to start) remain and nothing is awaited: no
    /// input can ever come.
    pub fn stuck(&self) -> bool {
        self.awaited.is_empty()
            && (!self.running.is_empty()
                || self
                    .dead
                    .iter()
                    .any(|(i, _)| matches!(i.what, What::Start { .. })))
    }
}

/// A process among `processes` that starts only on a trigger: its start events and what
/// triggers each (`None` when it starts by itself: [`executive_engine::Engine::starts_untriggered`]
/// decides that).
pub fn triggered_starts(g: &ProcessGraph, process: ProcessId) -> Vec<(NodeId, String, Trigger)> {
    let mut out = Vec::new();
    for &n in &g.process(process).nodes {
        let node = g.node(n);
        match &node.kind {
            NodeKind::Start(s) if node.incoming.is_empty() => {
                for d in &s.triggers {
                    let t = match d {
                        EventDefinition::Message(m) => Trigger::Message(
                            m.map(|m| g.messages[m.index()].name.clone())
                                .unwrap_or_default(),
                        ),
                        EventDefinition::Signal(s) => Trigger::Signal(
                            s.map(|s| g.signals[s.index()].name.clone())
                                .unwrap_or_default(),
                        ),
                        EventDefinition::Conditional(_) => Trigger::Condition,
                        EventDefinition::Timer(_) => Trigger::Timer,
                        _ => continue,
                    };
                    out.push((n, node.id.clone(), t));
                }
            }
            NodeKind::Task(t) if t.instantiate && node.incoming.is_empty() => {
                let name = t
                    .message
                    .map(|m| g.messages[m.index()].name.clone())
                    .unwrap_or_default();
                out.push((n, node.id.clone(), Trigger::Message(name)));
            }
            _ => {}
        }
    }
    out
}

/// What starts a triggered process.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Trigger {
    /// A message by name.
    Message(String),
    /// A signal by name.
    Signal(String),
    /// A timer start event (not armed for top-level processes).
    Timer,
    /// A conditional start event over system data.
    Condition,
}

impl std::fmt::Display for Trigger {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Trigger::Message(m) => write!(f, "message `{m}`"),
            Trigger::Signal(s) => write!(f, "signal `{s}`"),
            Trigger::Timer => f.write_str("a timer"),
            Trigger::Condition => f.write_str("a condition"),
        }
    }
}

/// Assesses the state. `held` says whether a connector still holds a task's goal;
/// `unstarted` lists the processes that start only on a trigger and have not started.
pub fn assess(
    g: &ProcessGraph,
    s: &State,
    outside: Outside,
    held: &dyn Fn(TaskKey) -> Option<Result<(), String>>,
    unstarted: &[ProcessId],
) -> Assessment {
    let mut a = Assessment::default();
    let running: BTreeSet<_> = s
        .instances
        .iter()
        .filter(|(_, i)| i.outcome.is_none())
        .map(|(id, _)| *id)
        .collect();
    a.running = running.iter().map(|i| i.0).collect();
    // Sure to come (tasks, timers, what outside delivers) and only if anything else does.
    let mut sure = Vec::new();
    let mut maybe = Vec::new();
    let item = |key: String, instance: Option<u64>, n: NodeId, what: What| {
        let node = g.node(n);
        Item {
            key,
            instance,
            element: node.id.clone(),
            name: node.name.clone(),
            what,
        }
    };
    for (id, t) in &s.tokens {
        if !running.contains(&t.instance) {
            continue;
        }
        let instance = Some(t.instance.0);
        match &t.at {
            At::Task(k) | At::UserTask(k) => {
                let what = match &t.at {
                    At::Task(_) => What::Task {
                        task: *k,
                        resource: executive_engine::resource(g, t.node).to_string(),
                    },
                    _ => What::UserTask { task: *k },
                };
                let it = item(format!("task {k}"), instance, t.node, what);
                match held(*k) {
                    Some(Ok(())) => sure.push(it),
                    Some(Err(why)) => a.dead.push((it, why)),
                    None => a
                        .dead
                        .push((it, "no connector holds its goal any more".to_owned())),
                }
            }
            At::Joining => maybe.push(item(format!("join {}", id.0), instance, t.node, What::Join)),
            At::Incident => {
                let message = s
                    .instances
                    .get(&t.instance)
                    .and_then(|i| i.incidents.iter().rev().find(|(n, _)| *n == t.node))
                    .map_or_else(|| "incident".to_owned(), |(_, m)| m.clone());
                let node = g.node(t.node);
                let incident = Incident {
                    instance: t.instance.0,
                    element: node.id.clone(),
                    name: node.name.clone(),
                    message,
                };
                if !a.incidents.contains(&incident) {
                    a.incidents.push(incident);
                }
            }
            _ => {}
        }
    }
    for (id, w) in &s.waits {
        if !running.contains(&w.instance) {
            continue;
        }
        let instance = Some(w.instance.0);
        let key = format!("wait {}", id.0);
        match &w.on {
            On::Timer { due, .. } if *due != Millis::MAX => {
                sure.push(item(key, instance, w.node, What::Timer { due: *due }))
            }
            on => {
                // What only an outside system can deliver is sure to come if one can.
                let (what, from_outside) = match on {
                    On::Message(m, _) => (What::Message(m.clone()), outside.messages),
                    On::Signal(m) => (What::Signal(m.clone()), outside.signals),
                    On::Condition { .. } => (What::Condition, outside.data),
                    _ => continue,
                };
                let it = item(key, instance, w.node, what);
                if from_outside { &mut sure } else { &mut maybe }.push(it);
            }
        }
    }
    for &p in unstarted {
        for (n, id, trigger) in triggered_starts(g, p) {
            let from_outside = match &trigger {
                Trigger::Message(_) => outside.messages,
                Trigger::Signal(_) => outside.signals,
                Trigger::Condition => outside.data,
                Trigger::Timer => {
                    let it = item(
                        format!("start {id}"),
                        None,
                        n,
                        What::Start {
                            process: g.process(p).id.clone(),
                            trigger: trigger.to_string(),
                        },
                    );
                    a.dead.push((
                        it,
                        "`trace run` does not arm timer start events of top-level processes"
                            .to_owned(),
                    ));
                    continue;
                }
            };
            let it = item(
                format!("start {id}"),
                None,
                n,
                What::Start {
                    process: g.process(p).id.clone(),
                    trigger: trigger.to_string(),
                },
            );
            if from_outside { &mut sure } else { &mut maybe }.push(it);
        }
    }
    if sure.is_empty() {
        a.dead.extend(maybe.into_iter().map(|i| {
            let why = match i.what {
                What::Join => "no other branch can arrive any more",
                What::Condition => "no input can change what it reads any more",
                _ => "nothing in this run can send it any more (no connector delivers messages or signals to `trace run`)",
            };
            (i, why.to_owned())
        }));
    } else {
        a.awaited = sure;
        a.awaited.extend(maybe);
    }
    a
}

/// An element as people read it: `` `id` (name)``.
pub fn element(id: &str, name: Option<&str>) -> String {
    match name {
        Some(n) if !n.is_empty() && n != id => format!("`{id}` ({n})"),
        _ => format!("`{id}`"),
    }
}

/// Mission time as RFC 3339 (UTC, milliseconds).
pub fn mission_time(ms: Millis) -> String {
    chrono::DateTime::from_timestamp_millis(ms).map_or_else(
        || format!("{ms} ms"),
        |t| t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true),
    )
}

impl Item {
    /// What and where, for people: ``user task `approve` (Approve) in instance 1``.
    pub fn describe(&self) -> String {
        let at = element(&self.element, self.name.as_deref());
        let inst = self
            .instance
            .map_or_else(String::new, |i| format!(" in instance {i}"));
        match &self.what {
            What::Task { resource, .. } => format!("task {at} on `{resource}`{inst}"),
            What::UserTask { .. } => format!("user task {at}{inst}"),
            What::Timer { due } => format!("timer {at}{inst}, due {}", mission_time(*due)),
            What::Message(m) => format!("message `{m}` at {at}{inst}"),
            What::Signal(m) => format!("signal `{m}` at {at}{inst}"),
            What::Condition => format!("condition at {at}{inst}"),
            What::Join => format!("the other branches at join {at}{inst}"),
            What::Start { process, trigger } => {
                format!("{trigger} at {at}, the start of process `{process}`")
            }
        }
    }

    /// The kind of wait, one word (log field).
    pub fn kind(&self) -> &'static str {
        match self.what {
            What::Task { .. } => "task",
            What::UserTask { .. } => "user_task",
            What::Timer { .. } => "timer",
            What::Message(_) => "message",
            What::Signal(_) => "signal",
            What::Condition => "condition",
            What::Join => "join",
            What::Start { .. } => "start",
        }
    }
}

impl std::fmt::Display for Incident {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "incident at {} in instance {}: {}",
            element(&self.element, self.name.as_deref()),
            self.instance,
            self.message
        )
    }
}
