//! Messages: sending along message flows or by name, receiving, correlation, and the pools this
//! engine does not run (another executive's in a fleet, or a black box), whose messages leave
//! the engine with a number that makes a resend harmless.

use std::collections::BTreeMap;

use executive_model::{EventDefinition, NodeId, NodeKind, ProcessGraph, ProcessId, Scope};

use crate::io::{Action, Entry, InstanceId, Outgoing, Rejected, ScopeId, TokenId, Trigger, WaitId};
use crate::run::Run;
use crate::state::On;
use crate::value::{Value, Vars};

/// What takes a message at one end of a message flow.
#[derive(Debug)]
pub(crate) enum Receiver {
    /// A waiting catch event, receive task or boundary event.
    Wait(WaitId),
    /// A start event (or instantiating receive task) of a process this engine runs.
    Start(ProcessId, NodeId),
    /// A pool whose process this engine runs, started at its start event for the message
    /// (`None`: none drawn, a plain start).
    Pool(ProcessId, Option<NodeId>),
    /// A pool this engine does not run: the message leaves the engine for it.
    Away(String),
}

/// The processes of the pools other than `participant` (given by id or name) in the model's
/// collaborations, each with the id of its pool: what an executive running only
/// `participant`'s pool leaves to the others. Errs, naming the pools there are, when no pool
/// of that id or name has a process.
pub fn remote_processes(
    g: &ProcessGraph,
    participant: &str,
) -> Result<BTreeMap<ProcessId, String>, String> {
    let pools: Vec<_> = g.participants().collect();
    let ours: Vec<_> = pools
        .iter()
        .filter(|p| p.id == participant || p.name.as_deref() == Some(participant))
        .collect();
    let runnable = |p: &&&executive_model::Participant| p.process.is_some();
    let names = || {
        let list: Vec<String> = pools
            .iter()
            .filter(runnable)
            .map(|p| match &p.name {
                Some(n) => format!("`{}` ({n})", p.id),
                None => format!("`{}`", p.id),
            })
            .collect();
        if list.is_empty() {
            "the model has no pool with a process".to_owned()
        } else {
            format!("pools with a process: {}", list.join(", "))
        }
    };
    let ours = match ours.as_slice() {
        [one] if one.process.is_some() => one,
        [_] => {
            return Err(format!(
                "pool `{participant}` is a black box (it has no process to run); {}",
                names()
            ));
        }
        [] => return Err(format!("no pool is named `{participant}`; {}", names())),
        _ => {
            return Err(format!(
                "several pools are named `{participant}`: give its id; {}",
                names()
            ));
        }
    };
    Ok(pools
        .iter()
        .filter(|p| p.id != ours.id)
        .filter_map(|p| Some((p.process?, p.id.clone())))
        .filter(|(process, _)| Some(*process) != ours.process)
        .collect())
}

impl Run<'_> {
    /// Sends a message: along the message flows drawn from its thrower if there are any, else
    /// to the first catcher waiting for it, else to a process that starts on it; what nothing
    /// inside takes goes out of the engine. A message with a correlation key carries the
    /// sender's value of that key (evaluated in `scope`).
    pub(crate) fn send_message(
        &mut self,
        instance: InstanceId,
        node: Option<NodeId>,
        scope: ScopeId,
        name: String,
        payload: Vars,
    ) {
        let correlation = self.thrown_message(instance, node, scope, &name);
        let drawn = node.is_some_and(|n| {
            let id = &self.g.node(n).id;
            self.g
                .collaborations
                .iter()
                .flat_map(|c| &c.message_flows)
                .any(|m| &m.source == id)
        });
        let delivered = match node {
            // Drawn message flows name the receivers: no delivery by name besides them.
            Some(n) if drawn => self.along_message_flows(n, &name, correlation.as_ref(), &payload),
            _ => self.deliver_message(&name, correlation.as_ref(), &payload),
        };
        if !delivered {
            self.out.push(Action::SendMessage(Box::new(Outgoing {
                name,
                payload,
                to: None,
                flow: None,
                correlation: None,
                number: None,
            })));
        }
    }

    /// Records that `node` sent message `name` and returns the sender's value of the message's
    /// correlation key (evaluated in the sender's `scope`), if it has one.
    fn thrown_message(
        &mut self,
        instance: InstanceId,
        node: Option<NodeId>,
        scope: ScopeId,
        name: &str,
    ) -> Option<Value> {
        self.record(instance, || Entry::Thrown {
            what: Trigger::Message,
            name: name.into(),
            node,
        });
        let key = self.g.messages.iter().find(|m| m.name == name)?;
        let key = key.correlation_key.as_ref()?;
        // A key that cannot be evaluated is null, which no keyed receiver matches.
        Some(
            self.eval(scope, key, &mut Vars::new())
                .unwrap_or(Value::Null),
        )
    }

    /// A send task run by a connector has sent its message: the receivers inside the engine
    /// that its message flows point at get it now (the connector reached anything outside).
    pub(crate) fn connector_sent(&mut self, t: TokenId) {
        if self.game.is_some() {
            // A token game passes messages on when the task is left.
            return;
        }
        let tok = &self.s.tokens[&t];
        let (node, scope, instance) = (tok.node, tok.scope, tok.instance);
        let NodeKind::Task(task) = &self.g.node(node).kind else {
            return;
        };
        if task.kind != executive_model::TaskKind::Send {
            return;
        }
        let name = self.message_name(task.message);
        let payload = self.visible_vars(scope);
        let correlation = self.thrown_message(instance, Some(node), scope, &name);
        self.along_message_flows(node, &name, correlation.as_ref(), &payload);
    }

    /// Delivers a message along the message flows drawn from `node` (collaborations): to the
    /// catch event, receive task or start event at the other end, to the process of the pool
    /// it points at, or out of the engine to a pool it does not run. False if no flow leaves
    /// `node` or nothing at their ends takes it.
    pub(crate) fn along_message_flows(
        &mut self,
        node: NodeId,
        name: &str,
        correlation: Option<&Value>,
        payload: &Vars,
    ) -> bool {
        let g = self.g;
        let source = &g.node(node).id;
        let mut delivered = false;
        for m in g
            .collaborations
            .iter()
            .flat_map(|c| &c.message_flows)
            .filter(|m| &m.source == source)
        {
            if let Some(r) = self.receiver_at(&m.target, name, correlation) {
                self.deliver_to(r, &m.id, name, correlation, payload);
                delivered = true;
            }
        }
        delivered
    }

    /// What takes message `name` (with `correlation`) at `target`, the id of a message flow's
    /// target: a node or a pool. A target this engine does not run always takes it (it leaves).
    pub(crate) fn receiver_at(
        &self,
        target: &str,
        name: &str,
        correlation: Option<&Value>,
    ) -> Option<Receiver> {
        let g = self.g;
        if let Some(n) = g.node_by_id(target) {
            if let Some(pool) = self.remote.get(&g.process_of(n)) {
                return Some(Receiver::Away(pool.clone()));
            }
            let wait = self.s.waits.iter().find(|(id, w)| {
                w.node == n
                    && match w.on {
                        On::Message(..) => self.correlates(**id, name, correlation),
                        On::Manual => true,
                        _ => false,
                    }
            });
            if let Some((id, _)) = wait {
                return Some(Receiver::Wait(*id));
            }
            let starts = match &g.node(n).kind {
                NodeKind::Start(_) => true,
                // A receive task with `instantiate` and no incoming flow starts it too.
                NodeKind::Task(t) => t.instantiate && g.node(n).incoming.is_empty(),
                _ => false,
            };
            return match (starts, g.node(n).scope) {
                (true, Scope::Process(p)) => Some(Receiver::Start(p, n)),
                _ => None,
            };
        }
        let pool = g.participants().find(|p| p.id == target)?;
        let Some(p) = pool.process else {
            // A black box (§9.2): nothing here runs it; the message leaves for it.
            return Some(Receiver::Away(pool.id.clone()));
        };
        if let Some(away) = self.remote.get(&p) {
            return Some(Receiver::Away(away.clone()));
        }
        // The pool's process receives it at its start event for this message, else (none
        // drawn) as a plain start.
        let start = g.process(p).nodes.iter().copied().find(|n| {
            matches!(&g.node(*n).kind, NodeKind::Start(st) if st.triggers.iter().any(
                |d| matches!(d, EventDefinition::Message(m) if self.message_name(*m) == name)))
        });
        Some(Receiver::Pool(p, start))
    }

    /// Gives message `name`, sent along message flow `flow`, to `r`.
    pub(crate) fn deliver_to(
        &mut self,
        r: Receiver,
        flow: &str,
        name: &str,
        correlation: Option<&Value>,
        payload: &Vars,
    ) {
        match r {
            Receiver::Wait(w) => self.trigger(w, Trigger::Message, name.to_owned(), payload),
            Receiver::Start(p, n) | Receiver::Pool(p, Some(n)) => {
                self.start_instance_at(p, n, payload.clone(), Trigger::Message, name);
            }
            Receiver::Pool(p, None) => {
                let (_, root) = self.open_instance(p, payload.clone(), None);
                self.start_process_scope(root, p, None);
            }
            Receiver::Away(to) => {
                self.s.sent += 1;
                let number = self.s.sent;
                self.out.push(Action::SendMessage(Box::new(Outgoing {
                    name: name.to_owned(),
                    payload: payload.clone(),
                    to: Some(to),
                    flow: Some(flow.to_owned()),
                    correlation: correlation.cloned(),
                    number: Some(number),
                })));
            }
        }
    }

    /// The receiver of a message that came along message flow `flow` from another executive:
    /// the flow's target, which must be this engine's and able to take it now.
    pub(crate) fn flow_receiver(
        &self,
        flow: &str,
        name: &str,
        correlation: Option<&Value>,
    ) -> Result<Receiver, Rejected> {
        let refuse = |reason: String| Rejected::Undeliverable {
            name: name.to_owned(),
            flow: flow.to_owned(),
            reason,
        };
        let m = self
            .g
            .collaborations
            .iter()
            .flat_map(|c| &c.message_flows)
            .find(|m| m.id == flow)
            .ok_or_else(|| refuse("the model has no message flow of that id".to_owned()))?;
        match self.receiver_at(&m.target, name, correlation) {
            Some(Receiver::Away(pool)) => Err(refuse(format!(
                "its target `{}` is in pool `{pool}`, which this executive does not run",
                m.target
            ))),
            Some(r) => Ok(r),
            None => Err(refuse(match correlation {
                Some(c) => format!(
                    "`{}` does not wait for it with correlation {c} (not reached yet, or its instance has moved on or ended)",
                    m.target
                ),
                None => format!(
                    "`{}` does not wait for it (not reached yet, or its instance has moved on or ended)",
                    m.target
                ),
            })),
        }
    }

    /// Delivers a message inside the engine; false if nothing takes it.
    pub(crate) fn deliver_message(
        &mut self,
        name: &str,
        correlation: Option<&Value>,
        payload: &Vars,
    ) -> bool {
        if let Some(w) = self.message_receiver(name, correlation) {
            self.trigger(w, Trigger::Message, name.to_owned(), payload);
            return true;
        }
        let starts = self.start_events_on(
            |d, r| matches!(d, EventDefinition::Message(m) if r.message_name(*m) == name),
        );
        let Some(&(process, start)) = starts.first() else {
            return false;
        };
        self.start_instance_at(process, start, payload.clone(), Trigger::Message, name);
        true
    }

    /// The subscription that takes a message: the oldest waiting one whose correlation key
    /// (if the message has one) evaluates to `correlation`.
    pub(crate) fn message_receiver(
        &self,
        name: &str,
        correlation: Option<&Value>,
    ) -> Option<WaitId> {
        self.s.waits.iter().find_map(|(id, w)| match &w.on {
            On::Message(n, _) if n == name && self.correlates(*id, name, correlation) => Some(*id),
            _ => None,
        })
    }

    /// Whether message subscription `w` takes a message of `name` with `correlation`: without a
    /// correlation key or value, any; with both, when the key evaluates to the value in the
    /// subscriber's scope. Explored without data ([`crate::Game::decide`]), any: keys read
    /// data the exploration does not have, and verification abstracts correlation away.
    fn correlates(&self, w: WaitId, name: &str, correlation: Option<&Value>) -> bool {
        if self.decides() {
            return self.s.waits.contains_key(&w);
        }
        let key = self
            .g
            .messages
            .iter()
            .find(|m| m.name == name)
            .and_then(|m| m.correlation_key.as_ref());
        let Some(w) = self.s.waits.get(&w) else {
            return false;
        };
        match (key, correlation) {
            (Some(k), Some(c)) => {
                let scope = w
                    .token
                    .and_then(|t| self.s.tokens.get(&t))
                    .map_or(w.scope, |t| t.scope);
                // A null key matches nothing (Zeebe refuses null correlation keys).
                !matches!(c, Value::Null)
                    && self.eval(scope, k, &mut Vars::new()).is_ok_and(|v| &v == c)
            }
            _ => true,
        }
    }
}
