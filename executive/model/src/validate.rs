//! Semantic checks over a built graph: what the XML schema cannot say but execution needs.
//!
//! Each check names the element and says what is wrong in a sentence. Where the check enforces
//! one of the BPMN 2.0 static constraints that BPMNspector numbers (`EXT.nnn`), the diagnostic
//! carries that number. Three strengths: `hard` (the model is ambiguous: an error everywhere),
//! `report` (what stops a process running: an error in an executable process, a warning in a
//! descriptive one), and `bent` (a rule bent harmlessly, such as an implicit end or an
//! unreachable node: a warning naming the rule, an error only when reading strictly).

use std::collections::BTreeSet;

use crate::diagnostic::Sink;
use crate::graph::*;
use crate::xml::Element;

mod levels;

pub(crate) struct Checker<'a> {
    g: &'a ProcessGraph,
    sink: &'a mut Sink,
    /// The nodes reached in the scope being checked: those marked with `scope_mark`. One array
    /// for every scope, so that many scopes cost no more than one.
    reached: Vec<u32>,
    /// The mark of the scope being checked (0: none yet).
    scope_mark: u32,
}

impl<'a> Checker<'a> {
    pub(crate) fn new(g: &'a ProcessGraph, sink: &'a mut Sink) -> Checker<'a> {
        Checker {
            g,
            sink,
            reached: vec![0; g.nodes.len()],
            scope_mark: 0,
        }
    }
}

fn has_trigger(triggers: &[EventDefinition], f: impl Fn(&EventDefinition) -> bool) -> bool {
    triggers.iter().any(f)
}

impl Checker<'_> {
    fn strict(&self, n: NodeId) -> bool {
        self.g.process(self.g.process_of(n)).executable
    }

    /// What stops a process running: an error in an executable process (a BPMN error when it is
    /// marked `isExecutable="true"`, else an execution problem); in a descriptive process, a
    /// warning, which `--strict` makes an error when it names a rule.
    fn report(
        &mut self,
        n: NodeId,
        code: &'static str,
        constraint: Option<&'static str>,
        message: String,
    ) {
        let node = self.g.node(n);
        let d = if self.strict(n) {
            let d = self.sink.error(code, node.offset, Some(&node.id), message);
            // Without isExecutable="true" the process may be a drawing: what stops it running
            // is an execution finding.
            if !self.g.process(self.g.process_of(n)).declared_executable {
                d.execution();
            }
            d
        } else if let Some(rule) = constraint {
            // A drawing may leave out what only execution needs; `--strict` still enforces
            // the rule.
            self.sink
                .bent(code, rule, node.offset, Some(&node.id), message)
        } else {
            self.sink
                .warning(code, node.offset, Some(&node.id), message)
        };
        if let Some(c) = constraint {
            d.constraint(c);
        }
    }

    fn hard(
        &mut self,
        n: NodeId,
        code: &'static str,
        constraint: Option<&'static str>,
        message: String,
    ) {
        let node = self.g.node(n);
        let d = self.sink.error(code, node.offset, Some(&node.id), message);
        if let Some(c) = constraint {
            d.constraint(c);
        }
    }

    /// A rule bent harmlessly: a warning naming the rule (an error with `--strict`).
    fn bent(&mut self, n: NodeId, code: &'static str, rule: &'static str, message: String) {
        let node = self.g.node(n);
        self.sink
            .bent(code, rule, node.offset, Some(&node.id), message);
    }

    /// A rule that binds executable processes only by its own text (the Common Executable
    /// conformance class, §2: EXT.011; and the conditions §10.6.1 and §13.3.1 ignore), bent
    /// harmlessly: as [`Self::bent`] in an executable process; in a descriptive one, a warning
    /// even with `--strict`. The Descriptive and Analytic classes' rules (flows every node
    /// needs, reachability, gateways) bind every process.
    fn bent_executable(
        &mut self,
        n: NodeId,
        code: &'static str,
        rule: &'static str,
        message: String,
    ) {
        if self.strict(n) {
            self.bent(n, code, rule, message);
        } else {
            let node = self.g.node(n);
            self.sink
                .noted(code, rule, node.offset, Some(&node.id), message);
        }
    }

    pub(crate) fn run(&mut self) {
        for i in 0..self.g.nodes.len() {
            self.node(NodeId(i as u32));
        }
        for p in 0..self.g.processes.len() as u32 {
            self.scope(Scope::Process(ProcessId(p)));
        }
        for i in 0..self.g.nodes.len() {
            if matches!(self.g.nodes[i].kind, NodeKind::SubProcess(_)) {
                self.scope(Scope::SubProcess(NodeId(i as u32)));
            }
        }
        self.signals();
    }

    fn node(&mut self, n: NodeId) {
        let g = self.g;
        let node = g.node(n);
        let (ins, outs) = (node.incoming.len(), node.outgoing.len());
        // A compensation activity runs only as the handler its boundary event's association
        // names: a sequence flow in or out would make it run in normal flow too, or continue
        // after compensating (bpmn-js will not draw such flows either).
        if node.for_compensation && (ins > 0 || outs > 0) {
            self.hard(
                n,
                "compensation-handler-flow",
                Some("§10.3"),
                "a compensation activity (isForCompensation) cannot have incoming or outgoing sequence flows; it runs only as a compensation handler".to_owned(),
            );
        }
        // Conditional flows leave activities and exclusive, inclusive and complex gateways
        // (§8.3.13); from an event the condition is still evaluated, as on an activity.
        if matches!(
            node.kind,
            NodeKind::Start(_) | NodeKind::Catch(_) | NodeKind::Throw(_) | NodeKind::Boundary(_)
        ) {
            for f in &node.outgoing {
                if g.flow(*f).condition.is_some() {
                    let msg = format!(
                        "sequence flow `{}` leaves an event with a condition; conditional flows leave activities and gateways, and it is evaluated as on an activity",
                        g.flow(*f).id
                    );
                    self.bent(n, "condition-on-event", "§8.3.13", msg);
                }
            }
        }
        let in_subprocess = match node.scope {
            Scope::SubProcess(s) => Some(s),
            Scope::Process(_) => None,
        };
        let event_sub = in_subprocess.is_some_and(|s| {
            matches!(
                &g.node(s).kind,
                NodeKind::SubProcess(SubProcess {
                    kind: SubProcessKind::Event,
                    ..
                })
            )
        });
        match &node.kind {
            NodeKind::Start(s) => {
                if ins > 0 {
                    self.hard(
                        n,
                        "flow-into-start",
                        Some("EXT.056"),
                        "a start event cannot have incoming sequence flows".to_owned(),
                    );
                }
                if outs == 0 {
                    self.bent(
                        n,
                        "no-outgoing",
                        "EXT.101",
                        "a start event should have an outgoing sequence flow; without one, its token ends at once".to_owned(),
                    );
                }
                if event_sub {
                    if s.triggers.is_empty() {
                        self.report(n, "event-subprocess-start", Some("EXT.059"), "the start event of an event sub-process needs a trigger (message, timer, signal, error, escalation, conditional or compensation)".to_owned());
                    }
                    if let Some(bad) = s.triggers.iter().find(|t| {
                        matches!(
                            t,
                            EventDefinition::Cancel
                                | EventDefinition::Link(_)
                                | EventDefinition::Terminate
                        )
                    }) {
                        let msg = format!(
                            "an event sub-process cannot be started by {}",
                            bad.element_name()
                        );
                        self.report(n, "event-subprocess-start", Some("EXT.059"), msg);
                    }
                    if !s.interrupting
                        && let Some(bad) = s.triggers.iter().find(|t| {
                            matches!(
                                t,
                                EventDefinition::Error { .. } | EventDefinition::Compensate { .. }
                            )
                        })
                    {
                        let msg = format!(
                            "a {} start event always interrupts (isInterrupting cannot be false)",
                            bad.element_name()
                        );
                        self.report(n, "event-subprocess-start", Some("EXT.059"), msg);
                    }
                } else if in_subprocess.is_some() {
                    if let Some(t) = s.triggers.first() {
                        let msg = format!(
                            "a start event inside an embedded sub-process must be a none start event, not {}",
                            t.element_name()
                        );
                        self.report(n, "triggered-start-in-subprocess", Some("EXT.098"), msg);
                    }
                } else if let Some(bad) = s.triggers.iter().find(|t| {
                    !matches!(
                        t,
                        EventDefinition::Message(_)
                            | EventDefinition::Timer(_)
                            | EventDefinition::Conditional(_)
                            | EventDefinition::Signal(_)
                    )
                }) {
                    let msg = format!(
                        "a top-level start event cannot be triggered by {}; use message, timer, conditional or signal",
                        bad.element_name()
                    );
                    self.report(n, "bad-start-trigger", Some("EXT.098"), msg);
                }
            }
            NodeKind::End(results) => {
                if ins == 0 {
                    self.bent(
                        n,
                        "no-incoming",
                        "EXT.107",
                        "an end event should have an incoming sequence flow; without one, no token reaches it".to_owned(),
                    );
                }
                if outs > 0 {
                    self.hard(
                        n,
                        "flow-from-end",
                        Some("EXT.007"),
                        "an end event cannot have outgoing sequence flows".to_owned(),
                    );
                }
                if let Some(bad) = results.iter().find(|t| {
                    matches!(
                        t,
                        EventDefinition::Timer(_)
                            | EventDefinition::Conditional(_)
                            | EventDefinition::Link(_)
                    )
                }) {
                    let msg = format!("an end event cannot throw {}", bad.element_name());
                    self.report(n, "bad-end-result", Some("§10.5.3"), msg);
                }
                if results.iter().any(|t| matches!(t, EventDefinition::Cancel))
                    && !self.in_transaction(n)
                {
                    self.report(
                        n,
                        "cancel-outside-transaction",
                        Some("§10.5.3"),
                        "a cancel end event must be inside a transaction".to_owned(),
                    );
                }
                self.escalation_codes(n, results);
            }
            NodeKind::Catch(c) => {
                if let Some(bad) = c.triggers.iter().find(|t| {
                    !matches!(
                        t,
                        EventDefinition::Message(_)
                            | EventDefinition::Timer(_)
                            | EventDefinition::Conditional(_)
                            | EventDefinition::Link(_)
                            | EventDefinition::Signal(_)
                    )
                }) {
                    let msg = format!(
                        "an intermediate catch event cannot wait for {}",
                        bad.element_name()
                    );
                    self.report(n, "bad-catch-trigger", Some("EXT.148"), msg);
                }
                if c.triggers.is_empty() {
                    self.report(
                        n,
                        "catch-without-trigger",
                        Some("§10.5.4"),
                        "an intermediate catch event needs an event definition".to_owned(),
                    );
                }
                let link = c
                    .triggers
                    .iter()
                    .any(|t| matches!(t, EventDefinition::Link(_)));
                if outs == 0 {
                    self.bent(
                        n,
                        "no-outgoing",
                        "EXT.116",
                        "an intermediate event should have an outgoing sequence flow; without one, its token ends here".to_owned(),
                    );
                }
                if link && ins > 0 {
                    self.hard(
                        n,
                        "link-both-ways",
                        Some("EXT.117"),
                        "a link catch event cannot also have incoming sequence flows".to_owned(),
                    );
                }
            }
            NodeKind::Throw(results) => {
                if let Some(bad) = results.iter().find(|t| {
                    !matches!(
                        t,
                        EventDefinition::Message(_)
                            | EventDefinition::Escalation(_)
                            | EventDefinition::Compensate { .. }
                            | EventDefinition::Link(_)
                            | EventDefinition::Signal(_)
                    )
                }) {
                    let msg = format!(
                        "an intermediate throw event cannot throw {}",
                        bad.element_name()
                    );
                    self.report(n, "bad-throw-result", Some("EXT.149"), msg);
                }
                let link = results
                    .iter()
                    .any(|t| matches!(t, EventDefinition::Link(_)));
                if link && outs > 0 {
                    self.hard(
                        n,
                        "link-both-ways",
                        Some("EXT.117"),
                        "a link throw event cannot also have outgoing sequence flows".to_owned(),
                    );
                }
                if !link && outs == 0 {
                    self.bent(
                        n,
                        "no-outgoing",
                        "EXT.116",
                        "an intermediate event should have an outgoing sequence flow; without one, its token ends here".to_owned(),
                    );
                }
                self.escalation_codes(n, results);
            }
            NodeKind::Boundary(b) => {
                if ins > 0 {
                    self.hard(
                        n,
                        "flow-into-boundary",
                        Some("EXT.006"),
                        "a boundary event cannot have incoming sequence flows".to_owned(),
                    );
                }
                if b.triggers.is_empty() {
                    self.report(
                        n,
                        "boundary-without-trigger",
                        Some("EXT.110"),
                        "a boundary event needs an event definition".to_owned(),
                    );
                }
                if let Some(bad) = b
                    .triggers
                    .iter()
                    .find(|t| matches!(t, EventDefinition::Link(_) | EventDefinition::Terminate))
                {
                    let msg = format!("a boundary event cannot wait for {}", bad.element_name());
                    self.report(n, "bad-boundary-trigger", Some("EXT.110"), msg);
                }
                let attached = g.node(b.attached_to);
                if has_trigger(&b.triggers, |t| matches!(t, EventDefinition::Cancel))
                    && !matches!(
                        &attached.kind,
                        NodeKind::SubProcess(SubProcess {
                            kind: SubProcessKind::Transaction,
                            ..
                        })
                    )
                {
                    self.report(
                        n,
                        "cancel-boundary-not-on-transaction",
                        Some("EXT.111"),
                        "a cancel boundary event must be attached to a transaction".to_owned(),
                    );
                }
                let compensation = has_trigger(&b.triggers, |t| {
                    matches!(t, EventDefinition::Compensate { .. })
                });
                if compensation && outs > 0 {
                    self.hard(n, "compensation-boundary-flow", Some("EXT.114"), "a compensation boundary event cannot have outgoing sequence flows; connect its handler with an association".to_owned());
                }
                if !compensation && outs == 0 {
                    self.bent(
                        n,
                        "no-outgoing",
                        "EXT.116",
                        "a boundary event should have an outgoing sequence flow; without one, its token ends here".to_owned(),
                    );
                }
            }
            NodeKind::Gateway(gw) => self.gateway(n, gw),
            NodeKind::Task(t) => self.task(n, t),
            NodeKind::SubProcess(s) => {
                if matches!(s.kind, SubProcessKind::Event) && (ins > 0 || outs > 0) {
                    self.hard(
                        n,
                        "event-subprocess-flow",
                        Some("EXT.056"),
                        "an event sub-process cannot have incoming or outgoing sequence flows"
                            .to_owned(),
                    );
                }
                if let SubProcessKind::AdHoc { .. } = s.kind {
                    if !s.nodes.iter().any(|c| g.node(*c).is_activity()) {
                        self.bent(
                            n,
                            "empty-adhoc",
                            "EXT.061",
                            "an ad-hoc sub-process should contain at least one activity; empty, it completes at once".to_owned(),
                        );
                    }
                    if let Some(c) = s
                        .nodes
                        .iter()
                        .find(|c| matches!(g.node(**c).kind, NodeKind::Start(_) | NodeKind::End(_)))
                    {
                        let msg = format!(
                            "start and end events are not allowed in an ad-hoc sub-process (found `{}`)",
                            g.node(*c).id
                        );
                        self.report(n, "event-in-adhoc", Some("EXT.062"), msg);
                    }
                }
            }
            NodeKind::CallActivity(c) => {
                if let Some(Called::Process(p)) = c.called {
                    let starts: Vec<&StartEvent> = g
                        .process(p)
                        .nodes
                        .iter()
                        .filter_map(|s| match &g.node(*s).kind {
                            NodeKind::Start(s) => Some(s),
                            _ => None,
                        })
                        .collect();
                    if !starts.is_empty() && starts.iter().all(|s| !s.triggers.is_empty()) {
                        let msg = format!(
                            "calls process `{}`, which has no none start event to be started by a call activity",
                            g.process(p).id
                        );
                        self.report(n, "called-process-start", Some("EXT.099"), msg);
                    }
                }
            }
        }
        if let Some(d) = node.default_flow
            && g.flow(d).condition.is_some()
        {
            self.bent_executable(
                n,
                "conditional-default",
                "§10.6.1",
                format!(
                    "default flow `{}` has a condition, which is ignored: a default flow is taken when no other flow is",
                    g.flow(d).id
                ),
            );
        }
        if matches!(
            node.kind,
            NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_)
        ) && matches!(node.scope, Scope::Process(_) | Scope::SubProcess(_))
        {
            self.loop_bounds(n);
        }
    }

    fn loop_bounds(&mut self, n: NodeId) {
        if let Some(Looping::MultiInstance(mi)) = &self.g.node(n).looping
            && let Some(c) = &mi.cardinality
            && c.text.trim().starts_with('-')
        {
            self.report(
                n,
                "bad-cardinality",
                None,
                format!("loop cardinality `{}` is negative", c.source),
            );
        }
    }

    fn in_transaction(&self, mut n: NodeId) -> bool {
        while let Scope::SubProcess(s) = self.g.node(n).scope {
            if matches!(
                &self.g.node(s).kind,
                NodeKind::SubProcess(SubProcess {
                    kind: SubProcessKind::Transaction,
                    ..
                })
            ) {
                return true;
            }
            n = s;
        }
        false
    }

    fn escalation_codes(&mut self, n: NodeId, results: &[EventDefinition]) {
        for r in results {
            if let EventDefinition::Escalation(e) = r {
                let has_code = e.is_some_and(|e| {
                    self.g.escalations[e.index()]
                        .code
                        .as_deref()
                        .is_some_and(|c| !c.is_empty())
                });
                if !has_code {
                    self.bent_executable(
                        n,
                        "escalation-without-code",
                        "EXT.011",
                        "a thrown escalation should reference an escalation with an escalationCode; without one, only catch-all escalation events catch it"
                            .to_owned(),
                    );
                }
            }
        }
    }

    fn gateway(&mut self, n: NodeId, gw: &Gateway) {
        let g = self.g;
        let node = g.node(n);
        let (ins, outs) = (node.incoming.len(), node.outgoing.len());
        if outs == 0 {
            let msg = format!(
                "{} has no outgoing sequence flow: tokens end here",
                gw.kind.element_name()
            );
            self.bent(n, "no-outgoing", "EXT.151", msg);
        }
        if ins <= 1 && outs <= 1 && !(gw.instantiate && ins == 0) {
            self.bent(
                n,
                "pass-through-gateway",
                "EXT.135",
                "a gateway should have several incoming or several outgoing sequence flows; this one passes its token on"
                    .to_owned(),
            );
        }
        match gw.kind {
            GatewayKind::Exclusive | GatewayKind::Inclusive if outs > 1 => {
                let unconditional: Vec<&str> = node
                    .outgoing
                    .iter()
                    .filter(|f| Some(**f) != node.default_flow && g.flow(**f).condition.is_none())
                    .map(|f| g.flow(*f).id.as_str())
                    .collect();
                // Flows without a condition: an inclusive gateway always takes them; an
                // exclusive gateway tests its flows in document order, so one such flow, last
                // and with no default, is the default in all but name (§13.3.2). More are
                // ambiguous: engines differ on which one wins.
                let last = node.outgoing.last().map(|f| g.flow(*f).id.as_str());
                let as_default = gw.kind == GatewayKind::Exclusive
                    && node.default_flow.is_none()
                    && unconditional.len() == 1
                    && last == unconditional.first().copied();
                if gw.kind == GatewayKind::Inclusive && !unconditional.is_empty() {
                    let msg = format!(
                        "diverging inclusiveGateway has outgoing flows without a condition, which it always takes: {}",
                        unconditional.join(", ")
                    );
                    self.sink
                        .warning("unconditional-branch", node.offset, Some(&node.id), msg);
                } else if as_default {
                    let msg = format!(
                        "exclusiveGateway has no default flow; `{}`, its last outgoing flow and the only one without a condition, is taken when no condition holds",
                        unconditional.join(", ")
                    );
                    self.sink
                        .warning("unconditional-branch", node.offset, Some(&node.id), msg);
                } else if !unconditional.is_empty() {
                    let msg = format!(
                        "diverging {} has outgoing flows without a condition that are not the default: {}; which one is taken is ambiguous (mark one as the default flow)",
                        gw.kind.element_name(),
                        unconditional.join(", ")
                    );
                    self.report(n, "unconditional-branch", None, msg);
                } else if node.default_flow.is_none() {
                    let msg = format!(
                        "{} has only conditional outgoing flows and no default flow: when no condition holds, the token has nowhere to go (add a default flow)",
                        gw.kind.element_name()
                    );
                    self.sink
                        .warning("no-default-flow", node.offset, Some(&node.id), msg);
                }
            }
            GatewayKind::EventBased { .. } => {
                for f in &node.outgoing {
                    if g.flow(*f).condition.is_some() {
                        let msg = format!(
                            "sequence flow `{}` leaves an event-based gateway with a condition; it is ignored (the event that occurs first decides)",
                            g.flow(*f).id
                        );
                        self.bent(n, "condition-on-event-gateway", "§10.6.6", msg);
                    }
                    let t = g.node(g.flow(*f).target);
                    let ok = match &t.kind {
                        NodeKind::Catch(c) => c.triggers.iter().all(|d| {
                            matches!(
                                d,
                                EventDefinition::Message(_)
                                    | EventDefinition::Signal(_)
                                    | EventDefinition::Timer(_)
                                    | EventDefinition::Conditional(_)
                            )
                        }),
                        NodeKind::Task(Task {
                            kind: TaskKind::Receive,
                            ..
                        }) => t.boundaries.is_empty(),
                        _ => false,
                    };
                    if !ok {
                        let msg = format!(
                            "an event-based gateway may only lead to message, signal, timer or conditional catch events or receive tasks without boundary events; `{}` is none of these",
                            t.id
                        );
                        self.hard(n, "bad-event-gateway-target", Some("EXT.138"), msg);
                    }
                    if t.incoming.len() > 1 {
                        let msg = format!(
                            "`{}` follows an event-based gateway and must have no other incoming sequence flow",
                            t.id
                        );
                        self.report(n, "bad-event-gateway-target", Some("EXT.138"), msg);
                    }
                }
                let kinds: BTreeSet<bool> = node
                    .outgoing
                    .iter()
                    .map(|f| matches!(g.node(g.flow(*f).target).kind, NodeKind::Task(_)))
                    .collect();
                let has_message_catch = node.outgoing.iter().any(|f| matches!(&g.node(g.flow(*f).target).kind, NodeKind::Catch(c) if c.triggers.iter().any(|d| matches!(d, EventDefinition::Message(_)))));
                if kinds.contains(&true) && has_message_catch {
                    self.hard(
                        n,
                        "mixed-event-gateway",
                        Some("EXT.139"),
                        "an event-based gateway cannot mix receive tasks with message catch events"
                            .to_owned(),
                    );
                }
                if gw.instantiate && ins > 0 {
                    self.hard(
                        n,
                        "instantiating-gateway-flow",
                        Some("EXT.142"),
                        "an instantiating event-based gateway cannot have incoming sequence flows"
                            .to_owned(),
                    );
                }
            }
            GatewayKind::Complex if gw.activation.is_none() && ins > 1 => {
                self.report(
                    n,
                    "missing-activation-condition",
                    None,
                    "a converging complex gateway needs an activationCondition".to_owned(),
                );
            }
            GatewayKind::Parallel => {
                for f in &node.outgoing {
                    if g.flow(*f).condition.is_some() {
                        let msg = format!(
                            "sequence flow `{}` leaves a parallel gateway; its condition is ignored (a parallel gateway takes every outgoing flow)",
                            g.flow(*f).id
                        );
                        self.bent_executable(n, "condition-on-parallel", "§13.3.1", msg);
                    }
                }
            }
            _ => {}
        }
    }

    fn task(&mut self, n: NodeId, t: &Task) {
        let node = self.g.node(n);
        match t.kind {
            TaskKind::Service | TaskKind::BusinessRule | TaskKind::Send => {
                let resource = t.binding.as_ref().and_then(|b| b.resource.as_deref());
                // A send task with a message, or drawn with a message flow, sends it.
                let sends = t.kind == TaskKind::Send
                    && (t.message.is_some()
                        || self
                            .g
                            .collaborations
                            .iter()
                            .any(|c| c.message_flows.iter().any(|f| f.source == node.id)));
                if resource.is_none_or(str::is_empty) && !sends {
                    let msg = format!(
                        "{} `{}` has no resource name: add <trace:task resource=\"…\"> (or zeebe:taskDefinition type, or camunda:topic) so a connector can run it",
                        t.kind.element_name(),
                        node.label()
                    );
                    self.report(n, "missing-resource", None, msg);
                }
            }
            TaskKind::Receive if t.instantiate && !node.incoming.is_empty() => {
                self.hard(
                    n,
                    "instantiating-receive-flow",
                    Some("EXT.049"),
                    "a receive task with instantiate=\"true\" cannot have incoming sequence flows"
                        .to_owned(),
                );
            }
            _ => {}
        }
    }

    /// Every thrown signal should have a catcher somewhere.
    fn signals(&mut self) {
        let g = self.g;
        let mut caught = BTreeSet::new();
        for node in &g.nodes {
            let triggers = match &node.kind {
                NodeKind::Start(s) => &s.triggers,
                NodeKind::Catch(c) => &c.triggers,
                NodeKind::Boundary(b) => &b.triggers,
                _ => continue,
            };
            for t in triggers {
                if let EventDefinition::Signal(Some(s)) = t {
                    caught.insert(g.signals[s.index()].name.as_str());
                }
            }
        }
        for (i, node) in g.nodes.iter().enumerate() {
            let results = match &node.kind {
                NodeKind::End(r) | NodeKind::Throw(r) => r,
                _ => continue,
            };
            for r in results {
                if let EventDefinition::Signal(Some(s)) = r {
                    let name = &g.signals[s.index()].name;
                    if !caught.contains(name.as_str()) {
                        let msg = format!(
                            "signal `{name}` is thrown here but no event in this model catches it"
                        );
                        self.sink
                            .warning("uncaught-signal", node.offset, Some(&node.id), msg);
                        let _ = i;
                    }
                }
            }
        }
    }
}

/// Constraint checks of one BPMN element that need the raw element (attributes the graph does
/// not keep). `executable` / `declared`: the element's process is executable / marked
/// `isExecutable="true"`; `flows`: the sequence flows ending at and leaving the element, for
/// one with a `gatewayDirection`. Called from the walk of [`crate::constraints::check`].
pub(crate) fn element_check(
    el: &Element,
    executable: bool,
    declared: bool,
    flows: Option<(usize, usize)>,
    sink: &mut Sink,
) {
    if el.ns == crate::xml::Ns::Bpmn {
        let id = el.attr("id");
        match el.name {
            "process"
                if el.attr("processType") == Some("Public")
                    && el.attr("isExecutable") == Some("true") =>
            {
                sink.bent(
                    "public-executable",
                    "EXT.035",
                    el.offset,
                    id,
                    "a public process should not be executable; it is run as marked executable"
                        .to_owned(),
                );
            }
            "sequenceFlow" if executable && el.attr("isImmediate") == Some("false") => {
                sink.bent(
                        "not-immediate",
                        "EXT.024",
                        el.offset,
                        id,
                        "isImmediate=\"false\" is not allowed in an executable process; the flow is taken immediately".to_owned(),
                    );
            }
            "scriptTask" if executable => {
                if let Some(s) = el.bpmn_child("script")
                    && !s.trimmed_text().is_empty()
                    && el.attr("scriptFormat").is_some_and(|f| f.trim().is_empty())
                {
                    sink.bent(
                        "empty-script-format",
                        "EXT.053",
                        el.offset,
                        id,
                        "scriptFormat is empty; the script is read as if it had none".to_owned(),
                    );
                }
            }
            _ => {}
        }
        if el.name == "boundaryEvent"
            && el.attr("cancelActivity") == Some("false")
            && [
                "errorEventDefinition",
                "cancelEventDefinition",
                "compensateEventDefinition",
            ]
            .iter()
            .any(|d| el.bpmn_child(d).is_some())
        {
            sink.bent(
                    "non-interrupting-error",
                    "EXT.110",
                    el.offset,
                    id,
                    "error, cancel and compensation boundary events always interrupt: cancelActivity=\"false\" is ignored".to_owned(),
                );
        }
        for (attr, constraint) in [
            ("startQuantity", "EXT.037"),
            ("completionQuantity", "EXT.038"),
        ] {
            let Some(v) = el.attr(attr) else { continue };
            let max = crate::MAX_QUANTITY;
            // How many tokens to wait for is undefined at zero: an executable process
            // cannot run with it; a drawing (ADONIS writes 0 throughout) is read as 1. Over
            // the bound the model is fine BPMN that TRACE will not run (each token is state).
            let (error, bent, limit) = match v.trim().parse::<u32>() {
                Ok(q) if q > max => (
                    format!("{attr}=\"{v}\" is over the {max} tokens TRACE runs for one activity"),
                    format!("{attr}=\"{v}\" is over {max} tokens; it is read as {max}"),
                    true,
                ),
                Ok(q) if q >= 1 => continue,
                _ => (
                    format!("{attr}=\"{v}\" must be a whole number of at least 1"),
                    format!(
                        "{attr}=\"{v}\" should be a whole number of at least 1; it is read as 1"
                    ),
                    false,
                ),
            };
            if executable {
                let d = sink.error("bad-quantity", el.offset, id, error);
                d.constraint(constraint);
                if limit || !declared {
                    d.execution();
                }
            } else {
                sink.bent("bad-quantity", constraint, el.offset, id, bent);
            }
        }
        if let Some(dir) = el.attr("gatewayDirection") {
            // The sequence flows decide, whatever `<incoming>`/`<outgoing>` list.
            let (ins, outs) = flows.unwrap_or_default();
            let bad = match dir {
                "Diverging" => (ins > 1).then_some((
                    "EXT.018",
                    "a diverging gateway cannot have more than one incoming sequence flow",
                )),
                "Converging" => (outs > 1).then_some((
                    "EXT.018",
                    "a converging gateway cannot have more than one outgoing sequence flow",
                )),
                "Mixed" => (ins < 2 || outs < 2).then_some((
                    "EXT.019",
                    "a mixed gateway needs several incoming and several outgoing sequence flows",
                )),
                _ => None,
            };
            if let Some((c, msg)) = bad {
                sink.bent(
                    "gateway-direction",
                    c,
                    el.offset,
                    id,
                    format!("{msg}; gatewayDirection is ignored, the sequence flows decide"),
                );
            }
        }
    }
}
