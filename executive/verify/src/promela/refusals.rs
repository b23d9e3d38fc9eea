//! What the translation does not cover: each such element refused with its id and the reason.

use super::*;

impl Tr<'_> {
    pub(super) fn refuse_unsupported(&mut self) {
        let g = self.g;
        for n in g.nodes.iter() {
            let no = |r: &str| refusal(&n.id, r);
            let bad = match &n.kind {
                NodeKind::Start(s) => {
                    let in_event_sub = matches!(n.scope, Scope::SubProcess(p)
                        if matches!(&g.node(p).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event)));
                    if in_event_sub {
                        None // refused with its event sub-process
                    } else if s
                        .triggers
                        .iter()
                        .any(|t| !matches!(t, EventDefinition::Timer(_)))
                    {
                        Some(no("start events triggered by messages, signals or conditions are not translated (a none or timer start is)"))
                    } else {
                        None
                    }
                }
                NodeKind::End(defs) => defs
                    .iter()
                    .find(|d| {
                        matches!(
                            d,
                            EventDefinition::Cancel
                                | EventDefinition::Compensate { .. }
                                | EventDefinition::Link(_)
                        )
                    })
                    .map(|d| no(&format!("{} on an end event is not translated", d.element_name()))),
                NodeKind::Throw(defs) => defs
                    .iter()
                    .find(|d| matches!(d, EventDefinition::Compensate { .. }))
                    .map(|d| no(&format!("{} on a throw event is not translated", d.element_name()))),
                NodeKind::Catch(c) if c.parallel_multiple => Some(no(
                    "parallel-multiple catch events (every trigger needed) are not translated",
                )),
                NodeKind::Catch(c) => c
                    .triggers
                    .iter()
                    .find(|d| matches!(d, EventDefinition::Error { .. } | EventDefinition::Escalation(_) | EventDefinition::Compensate { .. }))
                    .map(|d| no(&format!("{} on a catch event is not translated", d.element_name()))),
                NodeKind::Boundary(b) => {
                    if b.parallel_multiple {
                        Some(no("parallel-multiple boundary events are not translated"))
                    } else if b.triggers.iter().any(|d| {
                        matches!(d, EventDefinition::Compensate { .. } | EventDefinition::Cancel)
                    }) {
                        Some(no("compensation and cancel boundaries are not translated"))
                    } else {
                        None
                    }
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
                    SubProcessKind::Embedded => None,
                    SubProcessKind::Event => Some(no("event sub-processes are not translated yet")),
                    SubProcessKind::Transaction => Some(no("transactions are not translated")),
                    SubProcessKind::AdHoc { .. } => Some(no("ad-hoc sub-processes are not translated")),
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
            if n.is_activity() {
                if n.for_compensation || n.compensation_handler.is_some() {
                    self.refusals.push(no("compensation is not translated"));
                } else if n.start_quantity != 1 || n.completion_quantity != 1 {
                    self.refusals.push(no(
                        "start or completion quantities other than 1 are not translated",
                    ));
                } else if let Some(Looping::MultiInstance(mi)) = &n.looping
                    && mi.behavior != executive_model::MiBehavior::All
                {
                    self.refusals.push(no(
                        "multi-instance behaviours that throw events (None, One, Complex) are not translated",
                    ));
                } else if let Some(Looping::MultiInstance(mi)) = &n.looping
                    && !mi.sequential
                {
                    self.refusals.push(no(
                        "parallel multi-instance is not translated (sequential is, as a bounded loop)",
                    ));
                } else if n.outgoing.iter().any(|f| g.flow(*f).condition.is_some()) {
                    self.refusals.push(no(
                        "conditional sequence flows leaving an activity are not translated (use a gateway)",
                    ));
                }
                if let NodeKind::SubProcess(s) = &n.kind
                    && matches!(s.kind, SubProcessKind::Embedded)
                    && !s.nodes.iter().any(|m| {
                        matches!(&g.node(*m).kind, NodeKind::Start(st) if st.triggers.is_empty())
                    })
                {
                    self.refusals
                        .push(no("a sub-process without a none start event is not translated"));
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
        for c in &self.g.collaborations {
            if let Some(m) = c.message_flows.first() {
                self.refusals.push(refusal(
                    &m.id,
                    "message flows between pools are not translated yet",
                ));
            }
        }
    }

    // ----- names and slots -----
}
