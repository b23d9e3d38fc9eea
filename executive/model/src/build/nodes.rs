//! Each flow node's details, read in the second pass once every id is known: its kind, its
//! boundaries, its bindings and data, and what the executive cannot run named.

use super::*;

impl<'d> Builder<'d, '_> {
    /// Is the process of `scope` marked `isExecutable="true"`?
    pub(super) fn declared_in(&self, scope: Scope) -> bool {
        let p = match scope {
            Scope::Process(p) => p,
            Scope::SubProcess(s) => self.g.process_of(s),
        };
        self.g.process(p).declared_executable
    }

    pub(super) fn node_details(&mut self, nid: NodeId) {
        let NodeSource { el, strict } = self.node_src[nid.index()];
        self.declared = self.declared_in(self.g.node(nid).scope);
        let owner = self.g.node(nid).id.clone();
        let parallel_multiple = el.attr("parallelMultiple") == Some("true");
        if ACTIVITIES.contains(&el.name) {
            self.g.nodes[nid.index()].data = self.data_io(el, &owner, strict);
        } else if let Some(a) = el
            .bpmn_child("dataInputAssociation")
            .or_else(|| el.bpmn_child("dataOutputAssociation"))
        {
            // An event's data associations fill or empty its message (§10.4.2): not executed
            // yet, and never dropped without a word.
            let msg = format!(
                "the {} of this event is not executed by TRACE (the event's own payload is used as is)",
                a.name
            );
            self.problem(strict, "unsupported", a.offset, Some(&owner), msg);
        }
        let kind = match el.name {
            "startEvent" => NodeKind::Start(StartEvent {
                triggers: self.event_definitions(el, &owner, strict),
                interrupting: el.attr("isInterrupting") != Some("false"),
                parallel_multiple,
            }),
            "endEvent" | "intermediateThrowEvent"
                if el.bpmn_child("messageEventDefinition").is_some()
                    && crate::binding::implemented_as_task(el) =>
            {
                NodeKind::Task(self.event_task(el, &owner, strict))
            }
            "endEvent" => NodeKind::End(self.event_definitions(el, &owner, strict)),
            "intermediateCatchEvent" => NodeKind::Catch(CatchEvent {
                triggers: self.event_definitions(el, &owner, strict),
                parallel_multiple,
            }),
            "intermediateThrowEvent" => NodeKind::Throw(self.event_definitions(el, &owner, strict)),
            "boundaryEvent" => {
                let triggers = self.event_definitions(el, &owner, strict);
                let attached = el.attr("attachedToRef").map(local_ref);
                let attached_to = match attached.and_then(|a| self.node_ref(el.offset, a)) {
                    // Judged by the element name: the activity may come later in the document,
                    // so its details may not be read yet.
                    Some(a) if ACTIVITIES.contains(&self.node_src[a.index()].el.name) => {
                        if self.g.node(a).scope != self.g.node(nid).scope {
                            self.sink.error("cross-scope-boundary", el.offset, Some(&owner), "boundary event is attached to an activity of another process or sub-process level".to_owned());
                        }
                        a
                    }
                    Some(a) => {
                        let msg = format!(
                            "boundary event is attached to <{}> `{}`, which is not an activity",
                            self.node_src[a.index()].el.name,
                            self.g.node(a).id
                        );
                        self.sink
                            .error("boundary-on-non-activity", el.offset, Some(&owner), msg);
                        nid
                    }
                    None => {
                        let msg = match attached {
                            Some(a) => format!("attachedToRef `{a}` does not name an activity"),
                            None => "boundary event has no attachedToRef".to_owned(),
                        };
                        self.sink
                            .error("dangling-reference", el.offset, Some(&owner), msg);
                        nid
                    }
                };
                if attached_to != nid {
                    self.g.nodes[attached_to.index()].boundaries.push(nid);
                }
                // Error, cancel and compensation boundaries always interrupt (§10.5.4).
                let always = triggers.iter().any(|t| {
                    matches!(
                        t,
                        EventDefinition::Error { .. }
                            | EventDefinition::Cancel
                            | EventDefinition::Compensate { .. }
                    )
                });
                NodeKind::Boundary(BoundaryEvent {
                    attached_to,
                    triggers,
                    interrupting: always || el.attr("cancelActivity") != Some("false"),
                    parallel_multiple,
                })
            }
            g @ ("exclusiveGateway" | "inclusiveGateway" | "parallelGateway"
            | "eventBasedGateway" | "complexGateway") => {
                let kind = match g {
                    "exclusiveGateway" => GatewayKind::Exclusive,
                    "inclusiveGateway" => GatewayKind::Inclusive,
                    "parallelGateway" => GatewayKind::Parallel,
                    "eventBasedGateway" => GatewayKind::EventBased {
                        parallel: el.attr("eventGatewayType") == Some("Parallel"),
                    },
                    _ => GatewayKind::Complex,
                };
                let activation = el
                    .bpmn_child("activationCondition")
                    .and_then(|c| self.expr(strict, c, &owner, "activation condition"));
                NodeKind::Gateway(Gateway {
                    kind,
                    activation,
                    instantiate: el.attr("instantiate") == Some("true"),
                })
            }
            "subProcess" | "transaction" | "adHocSubProcess" => {
                if let Some(z) = el
                    .extensions()
                    .find(|e| e.ns == Ns::Zeebe && e.name == "adHoc")
                {
                    self.sink.warning(
                        "unsupported",
                        z.offset,
                        Some(&owner),
                        "zeebe:adHoc (Camunda 8's choice of the activities to run, and its output collection) is not read: TRACE runs the ad-hoc sub-process as BPMN describes it, every activity without incoming flows enabled".to_owned(),
                    );
                }
                let sub_kind = match el.name {
                    "transaction" => SubProcessKind::Transaction,
                    "adHocSubProcess" => SubProcessKind::AdHoc {
                        sequential: el.attr("ordering") == Some("Sequential"),
                        completion: el
                            .bpmn_child("completionCondition")
                            .and_then(|c| self.expr(strict, c, &owner, "completion condition")),
                        cancel_remaining: el.attr("cancelRemainingInstances") != Some("false"),
                    },
                    _ if el.attr("triggeredByEvent") == Some("true") => SubProcessKind::Event,
                    _ => SubProcessKind::Embedded,
                };
                match &mut self.g.nodes[nid.index()].kind {
                    NodeKind::SubProcess(s) => s.kind = sub_kind,
                    _ => unreachable!("sub-process nodes are created as such in the first pass"),
                }
                self.looping(nid, el, &owner, strict);
                self.default_flow(nid, el, &owner);
                return;
            }
            "callActivity" => {
                let zeebe_id = el
                    .extensions()
                    .find(|e| e.ns == Ns::Zeebe && e.name == "calledElement")
                    .and_then(|e| e.attr("processId"));
                // Zeebe may write the process id as FEEL: a constant names the process; one
                // that reads variables chooses it at run time, which TRACE does not do.
                let zeebe_id = match zeebe_id.map(crate::expr::constant_text) {
                    Some(Err(why)) => {
                        self.problem(
                            strict,
                            "missing-called-process",
                            el.offset,
                            Some(&owner),
                            why,
                        );
                        None
                    }
                    Some(Ok(id)) => Some(id),
                    None => None,
                };
                let called_attr = el.attr("calledElement").or(zeebe_id.as_deref());
                let doc = self.doc_of(el.offset);
                // A prefixed reference (`ns1:Process`) prefers an imported document.
                let prefixed = called_attr.is_some_and(|c| c.contains(':'));
                let called = match called_attr.map(local_ref) {
                    Some(c) => match (
                        self.find_process(doc, c, prefixed),
                        self.global_tasks.contains_key(c),
                    ) {
                        (Some(p), _) => Some(Called::Process(p)),
                        (None, true) => Some(Called::GlobalTask(c.to_owned())),
                        (None, false) => {
                            let msg = format!(
                                "call activity calls `{c}`, which is not a process or global task of this mission bundle"
                            );
                            if strict {
                                self.problem(
                                    strict,
                                    "missing-called-process",
                                    el.offset,
                                    Some(&owner),
                                    msg,
                                );
                            } else {
                                // A drawing may call what another bundle deploys; reading
                                // strictly, the reference names nothing (REF).
                                self.sink.bent(
                                    "missing-called-process",
                                    "REF",
                                    el.offset,
                                    Some(&owner),
                                    msg,
                                );
                            }
                            None
                        }
                    },
                    None => {
                        self.problem(
                            strict,
                            "missing-called-process",
                            el.offset,
                            Some(&owner),
                            "call activity has no calledElement".to_owned(),
                        );
                        None
                    }
                };
                let binding = BindingReader {
                    sink: self.sink,
                    element_id: &owner,
                    strict,
                }
                .read(el);
                NodeKind::CallActivity(CallActivity { called, binding })
            }
            task => NodeKind::Task(self.task(el, task, &owner, strict)),
        };
        self.g.nodes[nid.index()].kind = kind;
        self.looping(nid, el, &owner, strict);
        self.default_flow(nid, el, &owner);
    }
}
