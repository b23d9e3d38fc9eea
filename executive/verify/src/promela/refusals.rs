//! What the translation does not cover: each such element refused with its id and the reason.

use super::*;

impl Tr<'_> {
    pub(super) fn refuse_unsupported(&mut self) {
        let g = self.g;
        let primaries = g.primary_processes();
        for (i, n) in g.nodes.iter().enumerate() {
            let id = NodeId(i as u32);
            let no = |r: &str| refusal(&n.id, r);
            let bad = match &n.kind {
                NodeKind::Start(s) => {
                    let in_event_sub = matches!(n.scope, Scope::SubProcess(p) if is_event_sub(g, p));
                    let primary = matches!(n.scope, Scope::Process(p) if primaries.contains(&p));
                    let by_event = s.triggers.iter().all(|t| {
                        matches!(
                            t,
                            EventDefinition::Timer(_)
                                | EventDefinition::Message(_)
                                | EventDefinition::Signal(_)
                                | EventDefinition::Conditional(_)
                        )
                    });
                    let timed = s.triggers.iter().all(|t| matches!(t, EventDefinition::Timer(_)));
                    if s.parallel_multiple {
                        Some(no("parallel-multiple start events (every trigger needed) are not translated"))
                    } else if in_event_sub || timed || (primary && by_event) {
                        None
                    } else {
                        Some(no("a start event of a called process or sub-process triggered by an event is not translated (a process's message, signal, condition or timer start is)"))
                    }
                }
                NodeKind::End(defs) => {
                    if defs.iter().any(|d| matches!(d, EventDefinition::Cancel))
                        && self.transaction_of(id).is_none()
                    {
                        Some(no("a cancel end event outside a transaction cannot execute"))
                    } else {
                        defs.iter()
                            .find(|d| matches!(d, EventDefinition::Link(_)))
                            .map(|d| no(&format!("{} on an end event is not translated", d.element_name())))
                    }
                }
                NodeKind::Catch(c) if c.parallel_multiple => Some(no(
                    "parallel-multiple catch events (every trigger needed) are not translated",
                )),
                NodeKind::Catch(c) => c
                    .triggers
                    .iter()
                    .find(|d| matches!(d, EventDefinition::Error { .. } | EventDefinition::Escalation(_) | EventDefinition::Compensate { .. }))
                    .map(|d| no(&format!("{} on a catch event is not translated", d.element_name()))),
                NodeKind::Boundary(b) if b.parallel_multiple => {
                    Some(no("parallel-multiple boundary events are not translated"))
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
                    SubProcessKind::AdHoc { .. } => Some(no("ad-hoc sub-processes are not translated")),
                    _ => None,
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
            if !n.is_activity() && self.implicit(id) {
                self.refusals.push(no(
                    "an event or gateway without incoming flow (it starts with its scope) is not translated (an activity is)",
                ));
                continue;
            }
            if n.is_activity() {
                if n.start_quantity != 1 || n.completion_quantity != 1 {
                    self.refusals.push(no(
                        "start or completion quantities other than 1 are not translated",
                    ));
                } else if let Some(Looping::MultiInstance(mi)) = &n.looping
                    && !mi.sequential
                    && self.signals_itself(id)
                {
                    self.refusals.push(no(
                        "a parallel multi-instance body that throws a signal it also catches is not translated (the translation runs the bodies of a parallel multi-instance sub-process or call one after another, so one instance would not hear another)",
                    ));
                } else if n.outgoing.iter().any(|f| g.flow(*f).condition.is_some()) {
                    self.refusals.push(no(
                        "conditional sequence flows leaving an activity are not translated (use a gateway)",
                    ));
                }
                if let NodeKind::SubProcess(s) = &n.kind
                    && matches!(
                        s.kind,
                        SubProcessKind::Embedded | SubProcessKind::Transaction
                    )
                    && !s.nodes.iter().any(|m| {
                        matches!(&g.node(*m).kind, NodeKind::Start(st) if st.triggers.is_empty())
                            || self.implicit(*m)
                    })
                {
                    self.refusals.push(no(
                        "a sub-process with neither a none start event nor an element without incoming flow never starts anything",
                    ));
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
    }

    /// The body of activity `n` (a sub-process, or the process a call activity calls) throws a
    /// signal that something in it also catches.
    fn signals_itself(&self, n: NodeId) -> bool {
        let g = self.g;
        let called = match &g.node(n).kind {
            NodeKind::CallActivity(ca) => match &ca.called {
                Some(Called::Process(p)) => Some(*p),
                _ => return false,
            },
            NodeKind::SubProcess(_) => None,
            _ => return false,
        };
        let inside = |m: NodeId| match called {
            Some(p) => g.process_of(m) == p,
            None => self.within(m, n),
        };
        let (mut thrown, mut caught) = (BTreeSet::new(), BTreeSet::new());
        for (i, node) in g.nodes.iter().enumerate() {
            if !inside(NodeId(i as u32)) {
                continue;
            }
            let (defs, set) = match &node.kind {
                NodeKind::Throw(d) | NodeKind::End(d) => (d, &mut thrown),
                NodeKind::Catch(ce) => (&ce.triggers, &mut caught),
                NodeKind::Boundary(be) => (&be.triggers, &mut caught),
                NodeKind::Start(st) => (&st.triggers, &mut caught),
                _ => continue,
            };
            for d in defs {
                if let EventDefinition::Signal(s) = d {
                    set.insert(s.map(|s| s.index()));
                }
            }
        }
        thrown
            .iter()
            .any(|s| s.is_none() || caught.contains(s) || caught.contains(&None))
    }

    // ----- names and slots -----
}
