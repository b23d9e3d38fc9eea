//! Building the graph: the element tree of a `definitions` document -> [`ProcessGraph`].
//!
//! Two passes over each process: the first gives every flow node an id (so references that point
//! forward resolve), the second reads each node's details, flows, defaults and boundaries. Every
//! reference that does not resolve, and every element the executive cannot execute, becomes a
//! diagnostic; nothing is skipped silently.

use std::collections::BTreeMap;

use foldhash::{HashMap, HashMapExt};

use crate::binding::Reader as BindingReader;
use crate::diagnostic::Sink;
use crate::expr::{Expression, Failure, Language, parse_assignments};
use crate::graph::*;
use crate::timer::{TimerKind, parse_timer};
use crate::xml::{Document, Element, Ns};

/// BPMN activity element names.
pub(crate) const ACTIVITIES: &[&str] = &[
    "task",
    "serviceTask",
    "userTask",
    "scriptTask",
    "sendTask",
    "receiveTask",
    "manualTask",
    "businessRuleTask",
    "subProcess",
    "transaction",
    "adHocSubProcess",
    "callActivity",
];

/// BPMN flow-node element names (events, gateways and the activities).
pub(crate) const FLOW_NODES: &[&str] = &[
    "startEvent",
    "endEvent",
    "intermediateCatchEvent",
    "intermediateThrowEvent",
    "boundaryEvent",
    "exclusiveGateway",
    "inclusiveGateway",
    "parallelGateway",
    "eventBasedGateway",
    "complexGateway",
    "task",
    "serviceTask",
    "userTask",
    "scriptTask",
    "sendTask",
    "receiveTask",
    "manualTask",
    "businessRuleTask",
    "subProcess",
    "transaction",
    "adHocSubProcess",
    "callActivity",
];

/// BPMN elements that may stand in a process or sub-process and carry no control flow.
const PASSIVE: &[&str] = &[
    "sequenceFlow",
    "dataObject",
    "dataObjectReference",
    "dataStoreReference",
    "textAnnotation",
    "association",
    "group",
    "laneSet",
    "property",
    "ioSpecification",
    "documentation",
    "extensionElements",
    "dataInputAssociation",
    "dataOutputAssociation",
    "auditing",
    "monitoring",
    "correlationSubscription",
    "supports",
    "category",
    "ioBinding",
    "resourceRole",
    "performer",
    "humanPerformer",
    "potentialOwner",
    "dataInput",
    "dataOutput",
    "inputSet",
    "outputSet",
    "standardLoopCharacteristics",
    "multiInstanceLoopCharacteristics",
    "incoming",
    "outgoing",
    "completionCondition",
    "renderings",
    "rendering",
    "supportedInterfaceRef",
    "categoryValueRef",
];

/// Flow elements of the schema that a process can hold but the executive cannot run.
const UNRUNNABLE_FLOW_ELEMENTS: &[&str] = &[
    "callChoreography",
    "choreographyTask",
    "subChoreography",
    "event",
    "implicitThrowEvent",
];

/// Strips a QName prefix from a reference (`tns:Message_1` -> `Message_1`).
pub(crate) fn local_ref(r: &str) -> &str {
    let r = r.trim();
    r.rsplit_once(':').map_or(r, |(_, l)| l)
}

struct NodeSource<'d> {
    el: &'d Element<'d>,
    strict: bool,
}

pub(crate) struct Builder<'d, 's> {
    pub(crate) sink: &'s mut Sink,
    g: ProcessGraph,
    node_src: Vec<NodeSource<'d>>,
    flow_src: Vec<(&'d Element<'d>, Scope, bool)>,
    associations: Vec<&'d Element<'d>>,
    messages: BTreeMap<String, MessageId>,
    signals: BTreeMap<String, SignalId>,
    errors: BTreeMap<String, ErrorId>,
    escalations: BTreeMap<String, EscalationId>,
    /// Definitions-level event definitions, by id (`eventDefinitionRef`).
    global_event_defs: BTreeMap<String, &'d Element<'d>>,
    /// Global tasks callable by call activities.
    global_tasks: BTreeMap<String, &'d Element<'d>>,
    /// Every BPMN id in the document, with the element name and offset.
    /// Ids are unique per target namespace: (namespace index, id) -> (element name, offset).
    pub(crate) all_ids: HashMap<(usize, &'d str), (&'d str, usize)>,
    /// Item-aware elements (data objects and their references, properties, data stores and their
    /// references, data inputs and outputs) by (namespace index, id).
    data_els: HashMap<(usize, &'d str), &'d Element<'d>>,
    /// First offset of each document of the bundle, ascending.
    bases: Vec<usize>,
    /// Namespace index of each document (documents with equal targetNamespace share one).
    doc_namespace: Vec<usize>,
    /// The expression language each document declares (`expressionLanguage`; CEL when absent).
    doc_language: Vec<Language>,
    /// Flow nodes and processes by (document, id).
    scoped_nodes: HashMap<(usize, &'d str), NodeId>,
    scoped_processes: BTreeMap<(usize, &'d str), ProcessId>,
    /// Names of link event definitions by id (a link throw may name its catch by `<target>`).
    link_names: BTreeMap<&'d str, &'d str>,
    /// Foreign scripts are run by a script connector (see [`crate::Options`]).
    script_connector: bool,
    /// Whether the process of the element being read is marked `isExecutable="true"`; without
    /// it, what stops the process running is an execution problem (it may be a drawing).
    declared: bool,
}

/// Builds the graph from a parsed document. Returns `None` only when the root is not a BPMN
/// `definitions` element; every other problem is a diagnostic in `sink`.
pub(crate) fn build(
    docs: &[&Document],
    sink: &mut Sink,
    options: &crate::Options,
) -> Option<ProcessGraph> {
    let root = &docs.first()?.root;
    if !root.is_bpmn("definitions") {
        let what = match &root.ns {
            Ns::Other(uri) => format!("<{}> in namespace {uri}", root.name),
            _ => format!("<{}>", root.name),
        };
        sink.error("not-bpmn", root.offset, None, format!(
            "the root element is {what}, not a BPMN 2.0 <definitions> (namespace http://www.omg.org/spec/BPMN/20100524/MODEL)"
        ));
        return None;
    }
    let mut b = Builder {
        sink,
        g: ProcessGraph {
            id: root.attr("id").map(str::to_owned),
            target_namespace: root.attr("targetNamespace").map(str::to_owned),
            processes: Vec::new(),
            nodes: Vec::new(),
            flows: Vec::new(),
            messages: Vec::new(),
            signals: Vec::new(),
            errors: Vec::new(),
            escalations: Vec::new(),
            collaborations: Vec::new(),
            warnings: Vec::new(),
            global_tasks: BTreeMap::new(),
            node_ids: Vec::new(),
            process_ids: BTreeMap::new(),
        },
        node_src: Vec::new(),
        flow_src: Vec::new(),
        associations: Vec::new(),
        messages: BTreeMap::new(),
        signals: BTreeMap::new(),
        errors: BTreeMap::new(),
        escalations: BTreeMap::new(),
        global_event_defs: BTreeMap::new(),
        global_tasks: BTreeMap::new(),
        all_ids: HashMap::with_capacity(docs.iter().map(|d| d.ids).sum()),
        data_els: HashMap::new(),
        bases: docs.iter().map(|d| d.root.offset).collect(),
        doc_namespace: {
            let mut seen: Vec<Option<&str>> = Vec::new();
            docs.iter()
                .map(|d| {
                    let ns = d.root.attr("targetNamespace");
                    seen.iter().position(|s| *s == ns).unwrap_or_else(|| {
                        seen.push(ns);
                        seen.len() - 1
                    })
                })
                .collect()
        },
        doc_language: docs
            .iter()
            .map(|d| Language::named(d.root.attr("expressionLanguage").unwrap_or_default()))
            .collect(),
        scoped_nodes: HashMap::new(),
        scoped_processes: BTreeMap::new(),
        link_names: BTreeMap::new(),
        script_connector: options.script_connector,
        declared: true,
    };
    for (i, doc) in docs.iter().enumerate() {
        if i > 0 && !doc.root.is_bpmn("definitions") {
            continue;
        }
        b.collect_ids(&doc.root);
        b.globals(&doc.root);
    }
    for (i, doc) in docs.iter().enumerate() {
        if i > 0 && !doc.root.is_bpmn("definitions") {
            continue;
        }
        for el in doc.root.bpmn_children("process") {
            b.process(el, i > 0);
        }
    }
    b.flows();
    for i in 0..b.node_src.len() {
        b.node_details(NodeId(i as u32));
    }
    b.compensation_associations();
    b.declared = true;
    let globals: Vec<(String, &Element)> = b
        .global_tasks
        .iter()
        .map(|(id, el)| (id.clone(), *el))
        .collect();
    for (id, el) in globals {
        let name = el.name.strip_prefix("global").unwrap_or(el.name);
        let name = format!("{}{}", name[..1].to_ascii_lowercase(), &name[1..]);
        let task = b.task(el, &name, &id, true);
        b.g.global_tasks.insert(id, task);
    }
    for doc in docs {
        for el in doc.root.bpmn_children("collaboration") {
            b.collaboration(el);
        }
    }
    b.unknown_definitions_children(root);
    b.g.index_nodes();
    Some(b.g)
}

impl<'d> Builder<'d, '_> {
    /// Which document of the bundle an offset lies in.
    fn doc_of(&self, offset: usize) -> usize {
        self.bases
            .partition_point(|b| *b <= offset)
            .saturating_sub(1)
    }

    /// The flow node `id` as seen from the element at `offset` (same document).
    fn node_ref(&self, offset: usize, id: &str) -> Option<NodeId> {
        self.scoped_nodes
            .get(&(self.doc_of(offset), local_ref(id)))
            .copied()
    }

    /// The element `id` in the namespace of the element at `offset`.
    fn any_ref(&self, offset: usize, id: &str) -> Option<(&'d str, usize)> {
        let ns = self.doc_namespace[self.doc_of(offset)];
        self.all_ids.get(&(ns, local_ref(id))).copied()
    }

    fn problem(
        &mut self,
        strict: bool,
        code: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut crate::Diagnostic {
        if strict {
            let d = self.sink.error(code, offset, element, message);
            if !self.declared {
                d.execution();
            }
            d
        } else {
            self.sink.warning(code, offset, element, message)
        }
    }

    fn collect_ids(&mut self, root: &'d Element<'d>) {
        let mut stack = vec![root];
        while let Some(el) = stack.pop() {
            if el.ns == Ns::Bpmn
                && let Some(id) = el.attr("id")
            {
                let ns = self.doc_namespace[self.doc_of(el.offset)];
                if let Some((other, at)) = self.all_ids.get(&(ns, id)).copied() {
                    let msg = format!(
                        "id `{id}` is used twice: by <{}> and by <{other}> at byte {at}",
                        el.name
                    );
                    self.sink
                        .error("duplicate-id", el.offset, Some(id), msg)
                        .constraint("EXT.002");
                } else {
                    self.all_ids.insert((ns, id), (el.name, el.offset));
                    if crate::constraints::ITEM_AWARE.contains(&el.name) {
                        self.data_els.insert((ns, id), el);
                    }
                }
                if el.name == "linkEventDefinition" {
                    self.link_names.insert(id, el.attr("name").unwrap_or(id));
                }
            }
            // BPMN DI and foreign extensions hold no BPMN ids of their own.
            if el.ns == Ns::Bpmn {
                stack.extend(el.children.iter().rev());
            }
        }
    }

    /// A name or code Camunda 8 may write as FEEL (`name="=…"`): static text as it is, a
    /// constant expression as its value; one that reads variables is an error, since TRACE
    /// matches names and codes when the mission loads.
    fn constant(&mut self, el: &Element, attr: &str, owner: &str) -> Option<String> {
        let raw = el.attr(attr)?;
        match crate::expr::constant_text(raw) {
            Ok(v) => Some(v),
            Err(why) => {
                self.sink.error(
                    "bad-expression",
                    el.offset,
                    Some(owner),
                    format!("{attr}: {why}"),
                );
                Some(raw.to_owned())
            }
        }
    }

    fn globals(&mut self, root: &'d Element<'d>) {
        for el in root.children {
            if el.ns != Ns::Bpmn {
                continue;
            }
            let id = el.attr("id").unwrap_or_default().to_owned();
            match el.name {
                "message" => {
                    let name = self.constant(el, "name", &id).unwrap_or_else(|| id.clone());
                    // Zeebe's correlation key is FEEL, with or without its `=`.
                    let correlation_key = el
                        .extensions()
                        .find(|e| e.ns == Ns::Zeebe && e.name == "subscription")
                        .and_then(|s| Some((s, s.attr("correlationKey")?)))
                        .and_then(|(s, k)| match Expression::compile(k, &Language::Feel) {
                            Ok(e) => Some(e),
                            Err(f) => {
                                self.sink.error(
                                    f.code(),
                                    s.offset,
                                    Some(&id),
                                    format!("correlation key of message `{id}`: {f}"),
                                );
                                None
                            }
                        });
                    self.messages
                        .insert(id.clone(), MessageId(self.g.messages.len() as u32));
                    self.g.messages.push(Message {
                        id,
                        name,
                        correlation_key,
                    });
                }
                "signal" => {
                    let name = self.constant(el, "name", &id).unwrap_or_else(|| id.clone());
                    self.signals
                        .insert(id.clone(), SignalId(self.g.signals.len() as u32));
                    self.g.signals.push(Signal { id, name });
                }
                "error" => {
                    self.errors
                        .insert(id.clone(), ErrorId(self.g.errors.len() as u32));
                    let code = self.constant(el, "errorCode", &id);
                    self.g.errors.push(ErrorDef {
                        id,
                        name: el.attr("name").map(str::to_owned),
                        code,
                    });
                }
                "escalation" => {
                    self.escalations
                        .insert(id.clone(), EscalationId(self.g.escalations.len() as u32));
                    let code = self.constant(el, "escalationCode", &id);
                    self.g.escalations.push(Escalation {
                        id,
                        name: el.attr("name").map(str::to_owned),
                        code,
                    });
                }
                n if n.ends_with("EventDefinition") => {
                    self.global_event_defs.insert(id, el);
                }
                n if n.starts_with("global") && n.ends_with("Task") => {
                    self.global_tasks.insert(id, el);
                }
                _ => {}
            }
        }
    }

    fn unknown_definitions_children(&mut self, root: &Element) {
        const KNOWN: &[&str] = &[
            "process",
            "collaboration",
            "message",
            "signal",
            "error",
            "escalation",
            "itemDefinition",
            "interface",
            "dataStore",
            "import",
            "extension",
            "documentation",
            "extensionElements",
            "choreography",
            "globalConversation",
            "correlationProperty",
            "category",
            "resource",
            "partnerEntity",
            "partnerRole",
            "endPoint",
            "relationship",
            "eventDefinition",
            "globalTask",
            "globalScriptTask",
            "globalUserTask",
            "globalManualTask",
            "globalBusinessRuleTask",
        ];
        for el in root.children {
            if el.ns == Ns::Bpmn
                && !KNOWN.contains(&el.name)
                && !el.name.ends_with("EventDefinition")
            {
                self.sink.warning(
                    "unknown-element",
                    el.offset,
                    el.attr("id"),
                    format!(
                        "<{}> is not a BPMN 2.0 root element; it is ignored",
                        el.name
                    ),
                );
            }
        }
    }

    fn process(&mut self, el: &'d Element<'d>, imported: bool) {
        let pid = ProcessId(self.g.processes.len() as u32);
        let id = el.attr("id").unwrap_or_default().to_owned();
        let strict = el.attr("isExecutable") != Some("false");
        // Problems found while its elements are first read are reported for this process.
        self.declared = el.attr("isExecutable") == Some("true");
        if !id.is_empty() {
            self.g.process_ids.entry(id.clone()).or_insert(pid);
            self.scoped_processes.insert(
                (self.doc_of(el.offset), el.attr("id").unwrap_or_default()),
                pid,
            );
        }
        self.g.processes.push(Process {
            id,
            name: el.attr("name").map(str::to_owned),
            executable: strict,
            declared_executable: el.attr("isExecutable") == Some("true"),
            imported,
            nodes: Vec::new(),
            properties: data_items(el, "property"),
            data_objects: data_items(el, "dataObject"),
            lanes: Vec::new(),
            offset: el.offset,
        });
        let nodes = self.scope(el, Scope::Process(pid), strict);
        self.g.processes[pid.index()].nodes = nodes;
        let mut lanes = Vec::new();
        for set in el.bpmn_children("laneSet") {
            self.lanes(set, &mut lanes);
        }
        self.g.processes[pid.index()].lanes = lanes;
    }

    fn lanes(&mut self, set: &Element, out: &mut Vec<Lane>) {
        for lane in set.bpmn_children("lane") {
            let nodes = lane
                .bpmn_children("flowNodeRef")
                .filter_map(|r| self.node_ref(r.offset, r.text))
                .collect();
            out.push(Lane {
                id: lane.attr("id").unwrap_or_default().to_owned(),
                name: lane.attr("name").map(str::to_owned),
                nodes,
            });
            for child in lane.bpmn_children("childLaneSet") {
                self.lanes(child, out);
            }
        }
    }

    /// First pass over a process or sub-process: allocate its nodes, remember its flows.
    fn scope(&mut self, el: &'d Element<'d>, scope: Scope, strict: bool) -> Vec<NodeId> {
        let mut nodes = Vec::new();
        for child in el.children {
            if child.ns != Ns::Bpmn {
                continue;
            }
            let name = child.name;
            if FLOW_NODES.contains(&name) {
                let nid = NodeId(self.g.nodes.len() as u32);
                let xml_id = child.attr("id");
                let id = match xml_id {
                    Some(id) => id.to_owned(),
                    // The schema makes ids optional; one that nothing references may be left
                    // out. The node gets a name for messages and records.
                    None => {
                        let id = format!("{name}@{}", child.offset);
                        self.sink.warning(
                            "missing-id",
                            child.offset,
                            None,
                            format!("<{name}> has no id; it is called `{id}` here"),
                        );
                        id
                    }
                };
                if let Some(xml_id) = xml_id {
                    self.scoped_nodes
                        .insert((self.doc_of(child.offset), xml_id), nid);
                }
                self.g.nodes.push(Node {
                    id,
                    name: child.attr("name").map(str::to_owned),
                    kind: NodeKind::End(Vec::new()),
                    scope,
                    incoming: Vec::new(),
                    outgoing: Vec::new(),
                    default_flow: None,
                    boundaries: Vec::new(),
                    looping: None,
                    for_compensation: child.attr("isForCompensation") == Some("true"),
                    start_quantity: quantity(child.attr("startQuantity")),
                    completion_quantity: quantity(child.attr("completionQuantity")),
                    compensation_handler: None,
                    data: None,
                    offset: child.offset,
                });
                self.node_src.push(NodeSource { el: child, strict });
                nodes.push(nid);
                if matches!(name, "subProcess" | "transaction" | "adHocSubProcess") {
                    let inner = self.scope(child, Scope::SubProcess(nid), strict);
                    self.g.nodes[nid.index()].kind = NodeKind::SubProcess(SubProcess {
                        kind: SubProcessKind::Embedded,
                        nodes: inner,
                        data_objects: data_items(child, "dataObject")
                            .into_iter()
                            .chain(data_items(child, "property"))
                            .collect(),
                    });
                }
            } else if name == "sequenceFlow" {
                self.flow_src.push((child, scope, strict));
            } else if name == "association" {
                self.associations.push(child);
            } else if !PASSIVE.contains(&name) && !UNRUNNABLE_FLOW_ELEMENTS.contains(&name) {
                // Not a flow element at all (the schema allows none other here): a misplaced
                // element that execution never reads.
                let msg = format!("<{name}> is not a flow element; it is ignored here");
                self.sink.bent(
                    "misplaced-element",
                    "XSD",
                    child.offset,
                    child.attr("id"),
                    msg,
                );
            } else if !PASSIVE.contains(&name) {
                let msg = format!(
                    "<{name}> is not a flow element the executive knows; the model cannot run with it"
                );
                self.problem(
                    strict,
                    "unsupported-element",
                    child.offset,
                    child.attr("id"),
                    msg,
                );
            }
        }
        nodes
    }

    fn flows(&mut self) {
        let sources = std::mem::take(&mut self.flow_src);
        for (el, scope, strict) in sources {
            self.declared = self.declared_in(scope);
            let id = el.attr("id").unwrap_or_default().to_owned();
            let end = |b: &mut Self, attr: &str| -> Option<NodeId> {
                let Some(r) = el.attr(attr) else {
                    b.sink.error(
                        "missing-reference",
                        el.offset,
                        Some(&id),
                        format!("sequence flow has no {attr}"),
                    );
                    return None;
                };
                let r = local_ref(r);
                match b.node_ref(el.offset, r) {
                    Some(n) => Some(n),
                    None => {
                        let what = match b.any_ref(el.offset, r) {
                            Some((name, _)) => format!(
                                "<{name}> `{r}`, which is not a flow node (activity, event or gateway)"
                            ),
                            None => format!("`{r}`, which does not exist"),
                        };
                        let constraint = if attr == "sourceRef" {
                            "EXT.007"
                        } else {
                            "EXT.006"
                        };
                        b.sink
                            .error(
                                "dangling-reference",
                                el.offset,
                                Some(&id),
                                format!("sequence flow {attr} names {what}"),
                            )
                            .constraint(constraint);
                        None
                    }
                }
            };
            let (source, target) = (end(self, "sourceRef"), end(self, "targetRef"));
            let (Some(source), Some(target)) = (source, target) else {
                continue;
            };
            for (n, role) in [(source, "source"), (target, "target")] {
                if self.g.node(n).scope != scope {
                    let msg = format!(
                        "sequence flow connects `{}` in another process or sub-process level (its {role}); flows cannot cross scope boundaries",
                        self.g.node(n).id
                    );
                    self.sink
                        .error("cross-scope-flow", el.offset, Some(&id), msg);
                }
            }
            let condition = el
                .bpmn_child("conditionExpression")
                .and_then(|c| self.condition(strict, c, &id, "condition of sequence flow"));
            let fid = FlowId(self.g.flows.len() as u32);
            self.g.nodes[source.index()].outgoing.push(fid);
            self.g.nodes[target.index()].incoming.push(fid);
            self.g.flows.push(SequenceFlow {
                id,
                name: el.attr("name").map(str::to_owned),
                source,
                target,
                condition,
                offset: el.offset,
            });
        }
    }

    /// Links each compensation boundary event to its handler through the association between them.
    fn compensation_associations(&mut self) {
        for a in std::mem::take(&mut self.associations) {
            let end = |attr: &str| a.attr(attr).and_then(|r| self.node_ref(a.offset, r));
            let (Some(source), Some(target)) = (end("sourceRef"), end("targetRef")) else {
                continue;
            };
            let NodeKind::Boundary(b) = &self.g.node(source).kind else {
                continue;
            };
            if !b
                .triggers
                .iter()
                .any(|t| matches!(t, EventDefinition::Compensate { .. }))
            {
                continue;
            }
            let activity = b.attached_to;
            if !self.g.node(target).for_compensation {
                let msg = format!(
                    "compensation handler `{}` must be marked isForCompensation=\"true\"",
                    self.g.node(target).id
                );
                self.sink
                    .error("handler-not-for-compensation", a.offset, a.attr("id"), msg)
                    .constraint("EXT.144");
            }
            self.g.nodes[activity.index()].compensation_handler = Some(target);
        }
        for i in 0..self.g.nodes.len() {
            let node = &self.g.nodes[i];
            if let NodeKind::Boundary(b) = &node.kind
                && b.triggers
                    .iter()
                    .any(|t| matches!(t, EventDefinition::Compensate { .. }))
                && self.g.node(b.attached_to).compensation_handler.is_none()
            {
                let msg = "a compensation boundary event should be connected by an association to its compensation handler; without one, nothing is compensated for the activity".to_owned();
                self.sink.bent(
                    "compensation-without-handler",
                    "EXT.143",
                    node.offset,
                    Some(&node.id.clone()),
                    msg,
                );
            }
        }
    }

    /// A process by id: in document `doc` first (or last, when `prefer_other`), else anywhere.
    fn find_process(&self, doc: usize, id: &str, prefer_other: bool) -> Option<ProcessId> {
        let own = self.scoped_processes.get(&(doc, id)).copied();
        // One lookup per other document of the bundle, not a scan of every process.
        let other = (0..self.bases.len())
            .filter(|d| *d != doc)
            .find_map(|d| self.scoped_processes.get(&(d, id)).copied());
        if prefer_other {
            other.or(own)
        } else {
            own.or(other)
        }
    }

    /// The language an expression element is written in: its `language` attribute, else the
    /// document's `expressionLanguage`.
    fn language_of(&self, el: &Element) -> Language {
        match el.attr("language") {
            Some(l) => Language::named(l),
            None => self.doc_language[self.doc_of(el.offset)].clone(),
        }
    }

    /// A condition that cannot be evaluated: its problem is reported, and it stands in the graph
    /// as a condition that never holds, so that no check mistakes the flow for an unconditioned
    /// one (only a token game, which chooses branches itself, ever runs such a graph).
    fn condition(
        &mut self,
        strict: bool,
        el: &Element,
        owner: &str,
        what: &str,
    ) -> Option<Expression> {
        if el.trimmed_text().is_empty() {
            return None;
        }
        Some(
            self.expr(strict, el, owner, what)
                .unwrap_or_else(Expression::never),
        )
    }

    /// Compiles the expression in `el`; a failure is a diagnostic (`bad-expression`, or
    /// `unevaluated-language` naming the language).
    fn expr(&mut self, strict: bool, el: &Element, owner: &str, what: &str) -> Option<Expression> {
        let language = self.language_of(el);
        match Expression::compile(el.trimmed_text(), &language) {
            Ok(e) => Some(e),
            Err(f) => {
                self.expr_problem(strict, el.offset, owner, what, f);
                None
            }
        }
    }

    fn expr_problem(&mut self, strict: bool, offset: usize, owner: &str, what: &str, f: Failure) {
        self.problem(
            strict,
            f.code(),
            offset,
            Some(owner),
            format!("{what}: {f}"),
        );
    }

    fn resolve<T: Copy>(
        &mut self,
        map_of: fn(&Self) -> &BTreeMap<String, T>,
        el: &Element,
        attr: &str,
        owner: &str,
    ) -> Option<T> {
        let r = el.attr(attr)?;
        let key = local_ref(r);
        match map_of(self).get(key) {
            Some(v) => Some(*v),
            None => {
                let msg = format!(
                    "{attr} `{key}` does not name a {} defined in this model",
                    attr.trim_end_matches("Ref")
                );
                self.sink
                    .error("dangling-reference", el.offset, Some(owner), msg);
                None
            }
        }
    }

    fn event_definitions(
        &mut self,
        el: &'d Element<'d>,
        owner: &str,
        strict: bool,
    ) -> Vec<EventDefinition> {
        let mut defs: Vec<&'d Element<'d>> = el
            .children
            .iter()
            .filter(|c| c.ns == Ns::Bpmn && c.name.ends_with("EventDefinition"))
            .collect();
        for r in el.bpmn_children("eventDefinitionRef") {
            let id = local_ref(r.text);
            // A reference to a definition the event already holds inline adds nothing.
            if defs.iter().any(|d| d.attr("id") == Some(id)) {
                continue;
            }
            match self.global_event_defs.get(id) {
                Some(d) => defs.push(d),
                None => {
                    self.sink.error(
                        "dangling-reference",
                        r.offset,
                        Some(owner),
                        format!("eventDefinitionRef `{}` does not exist", r.trimmed_text()),
                    );
                }
            }
        }
        let mut out = Vec::new();
        for d in defs {
            let def = match d.name {
                "messageEventDefinition" => {
                    EventDefinition::Message(self.resolve(|b| &b.messages, d, "messageRef", owner))
                }
                "signalEventDefinition" => {
                    EventDefinition::Signal(self.resolve(|b| &b.signals, d, "signalRef", owner))
                }
                "errorEventDefinition" => {
                    let var = |name: &str| {
                        d.attr_ns(&Ns::Trace, name)
                            .or_else(|| d.attr_ns(&Ns::Camunda, name))
                            .map(str::to_owned)
                    };
                    EventDefinition::Error {
                        error: self.resolve(|b| &b.errors, d, "errorRef", owner),
                        code_variable: var("errorCodeVariable"),
                        message_variable: var("errorMessageVariable"),
                    }
                }
                "escalationEventDefinition" => EventDefinition::Escalation(self.resolve(
                    |b| &b.escalations,
                    d,
                    "escalationRef",
                    owner,
                )),
                "terminateEventDefinition" => EventDefinition::Terminate,
                "cancelEventDefinition" => EventDefinition::Cancel,
                "compensateEventDefinition" => {
                    let activity =
                        d.attr("activityRef")
                            .and_then(|r| match self.node_ref(d.offset, r) {
                                Some(n) => Some(n),
                                None => {
                                    self.sink.error(
                                        "dangling-reference",
                                        d.offset,
                                        Some(owner),
                                        format!("activityRef `{r}` does not name an activity"),
                                    );
                                    None
                                }
                            });
                    EventDefinition::Compensate {
                        activity,
                        wait: d.attr("waitForCompletion") != Some("false"),
                    }
                }
                "linkEventDefinition" => {
                    // A throw may name its catch explicitly; then the pair shares the catch's name.
                    let target = d
                        .bpmn_child("target")
                        .and_then(|t| self.link_names.get(local_ref(t.text)).copied());
                    EventDefinition::Link(target.or(d.attr("name")).unwrap_or_default().to_owned())
                }
                // A condition that cannot be evaluated (empty, or in another language) is a
                // problem of its own; the event stays a conditional event, which never fires.
                "conditionalEventDefinition" => {
                    let e = match d.bpmn_child("condition") {
                        Some(c) => self.expr(strict, c, owner, "condition of conditional event"),
                        None => {
                            self.problem(
                                strict,
                                "missing-condition",
                                d.offset,
                                Some(owner),
                                "conditional event definition has no <condition>".to_owned(),
                            )
                            .constraint("XSD");
                            None
                        }
                    };
                    EventDefinition::Conditional(e.unwrap_or_else(Expression::never))
                }
                "timerEventDefinition" => {
                    let parts: Vec<(TimerKind, &Element)> = [
                        ("timeDate", TimerKind::Date),
                        ("timeDuration", TimerKind::Duration),
                        ("timeCycle", TimerKind::Cycle),
                    ]
                    .into_iter()
                    .filter_map(|(n, k)| d.bpmn_child(n).map(|c| (k, c)))
                    .collect();
                    let [(kind, value)] = parts[..] else {
                        let msg = format!(
                            "timer event definition needs exactly one of timeDate, timeDuration, timeCycle (found {})",
                            parts.len()
                        );
                        self.problem(strict, "bad-timer", d.offset, Some(owner), msg);
                        out.push(EventDefinition::Timer(crate::timer::Timer {
                            kind: TimerKind::Duration,
                            value: crate::timer::TimerValue::Unparsed(String::new()),
                        }));
                        continue;
                    };
                    match parse_timer(kind, value.trimmed_text()) {
                        Ok(t) => {
                            let text = value.trimmed_text();
                            if matches!(t.value, crate::timer::TimerValue::Expression(_))
                                && crate::expr::wrapped(text).is_none()
                            {
                                let rule = match kind {
                                    TimerKind::Date => "EXT.132",
                                    TimerKind::Cycle => "EXT.133",
                                    TimerKind::Duration => "EXT.134",
                                };
                                self.sink.bent(
                                    "timer-expression",
                                    rule,
                                    value.offset,
                                    Some(owner),
                                    format!("`{text}` is not ISO 8601; it is read as an expression whose value is (a variable holding the time)"),
                                );
                            }
                            EventDefinition::Timer(t)
                        }
                        Err(e) => {
                            self.problem(strict, "bad-timer", value.offset, Some(owner), e);
                            EventDefinition::Timer(crate::timer::Timer {
                                kind,
                                value: crate::timer::TimerValue::Unparsed(
                                    value.trimmed_text().to_owned(),
                                ),
                            })
                        }
                    }
                }
                other => {
                    self.problem(
                        strict,
                        "unsupported-element",
                        d.offset,
                        Some(owner),
                        format!("<{other}> is not a BPMN event definition"),
                    );
                    continue;
                }
            };
            out.push(def);
        }
        out
    }

    /// Is the process of `scope` marked `isExecutable="true"`?
    fn declared_in(&self, scope: Scope) -> bool {
        let p = match scope {
            Scope::Process(p) => p,
            Scope::SubProcess(s) => self.g.process_of(s),
        };
        self.g.process(p).declared_executable
    }

    fn node_details(&mut self, nid: NodeId) {
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
                            self.problem(
                                strict,
                                "missing-called-process",
                                el.offset,
                                Some(&owner),
                                msg,
                            );
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

    /// The ioSpecification and data associations of activity `el` (§10.4.1).
    fn data_io(&mut self, el: &'d Element<'d>, owner: &str, strict: bool) -> Option<Box<DataIo>> {
        let spec = el.bpmn_child("ioSpecification");
        let ins: Vec<&'d Element<'d>> = el.bpmn_children("dataInputAssociation").collect();
        let outs: Vec<&'d Element<'d>> = el.bpmn_children("dataOutputAssociation").collect();
        if spec.is_none() && ins.is_empty() && outs.is_empty() {
            return None;
        }
        let params = |kind: &str| -> Vec<DataParam> {
            spec.into_iter()
                .flat_map(|s| s.bpmn_children(kind))
                .map(|d| DataParam {
                    id: d.attr("id").unwrap_or_default().to_owned(),
                    name: item_name(d),
                })
                .collect()
        };
        let mut io = DataIo {
            inputs: params("dataInput"),
            outputs: params("dataOutput"),
            ..DataIo::default()
        };
        let sets = |kind: &str, refs: &str, optional: &str, of: &[DataParam]| -> Vec<IoSet> {
            spec.into_iter()
                .flat_map(|s| s.bpmn_children(kind))
                .map(|set| {
                    let idx = |child: &str| -> Vec<usize> {
                        set.bpmn_children(child)
                            .filter_map(|r| of.iter().position(|p| p.id == local_ref(r.text)))
                            .collect()
                    };
                    IoSet {
                        refs: idx(refs),
                        optional: idx(optional),
                    }
                })
                .collect()
        };
        io.input_sets = sets("inputSet", "dataInputRefs", "optionalInputRefs", &io.inputs);
        io.output_sets = sets(
            "outputSet",
            "dataOutputRefs",
            "optionalOutputRefs",
            &io.outputs,
        );
        for (list, input) in [(ins, true), (outs, false)] {
            for a in list {
                let sources = a
                    .bpmn_children("sourceRef")
                    .filter_map(|r| self.data_ref(r.offset, r.text, &io))
                    .collect();
                let target = a
                    .bpmn_child("targetRef")
                    .and_then(|r| self.data_ref(r.offset, r.text, &io));
                let transformation = a
                    .bpmn_child("transformation")
                    .and_then(|t| self.expr(strict, t, owner, "data association transformation"));
                let mut assignments = Vec::new();
                for asg in a.bpmn_children("assignment") {
                    let (Some(from), Some(to)) = (asg.bpmn_child("from"), asg.bpmn_child("to"))
                    else {
                        continue;
                    };
                    if let Some(from) = self.expr(strict, from, owner, "assignment") {
                        let to = self.data_path(to.offset, to.trimmed_text(), &io);
                        assignments.push((from, to));
                    }
                }
                let assoc = DataAssociation {
                    sources,
                    target,
                    transformation,
                    assignments,
                };
                if input {
                    io.input_associations.push(assoc);
                } else {
                    io.output_associations.push(assoc);
                }
            }
        }
        Some(Box::new(io))
    }

    /// What the item-aware element `id` (seen from `offset`) stands for at run time.
    fn data_ref(&self, offset: usize, id: &str, io: &DataIo) -> Option<DataRef> {
        let id = local_ref(id);
        if let Some(i) = io.inputs.iter().position(|p| p.id == id) {
            return Some(DataRef::Input(i));
        }
        if let Some(i) = io.outputs.iter().position(|p| p.id == id) {
            return Some(DataRef::Output(i));
        }
        let ns = self.doc_namespace[self.doc_of(offset)];
        let el = *self.data_els.get(&(ns, id))?;
        let referenced = |attr: &str| {
            el.attr(attr)
                .and_then(|r| self.data_els.get(&(ns, local_ref(r))))
                .copied()
        };
        Some(match el.name {
            "dataObjectReference" => {
                DataRef::Variable(item_name(referenced("dataObjectRef").unwrap_or(el)))
            }
            "dataStoreReference" => {
                DataRef::Store(item_name(referenced("dataStoreRef").unwrap_or(el)))
            }
            "dataStore" => DataRef::Store(item_name(el)),
            _ => DataRef::Variable(item_name(el)),
        })
    }

    /// The path an assignment's `to` writes: its first part names a data input or output of the
    /// activity, or an item-aware element, by id or name; the rest is a path inside it.
    fn data_path(&self, offset: usize, to: &str, io: &DataIo) -> String {
        let to = to.trim();
        let (first, rest) = to.split_once('.').map_or((to, None), |(f, r)| (f, Some(r)));
        let name = match self.data_ref(offset, first, io) {
            Some(DataRef::Input(i)) => io.inputs[i].name.clone(),
            Some(DataRef::Output(i)) => io.outputs[i].name.clone(),
            Some(DataRef::Variable(n) | DataRef::Store(n)) => n,
            None => first.to_owned(),
        };
        match rest {
            Some(r) => format!("{name}.{r}"),
            None => name,
        }
    }

    /// A task (or global task, whose element name has lost its `global` prefix).
    fn task(&mut self, el: &'d Element<'d>, name: &str, owner: &str, strict: bool) -> Task {
        let kind = match name {
            "serviceTask" => TaskKind::Service,
            "userTask" => TaskKind::User,
            "scriptTask" => TaskKind::Script,
            "sendTask" => TaskKind::Send,
            "receiveTask" => TaskKind::Receive,
            "manualTask" => TaskKind::Manual,
            "businessRuleTask" => TaskKind::BusinessRule,
            _ => TaskKind::Plain,
        };
        let binding = BindingReader {
            sink: self.sink,
            element_id: owner,
            strict,
        }
        .read(el);
        // A script task implemented by a job worker or an external task (a resource name) is
        // dispatched like a service task: it needs no script of its own.
        let worker = binding.as_ref().is_some_and(|b| b.resource.is_some())
            && el.bpmn_child("script").is_none();
        let script = (kind == TaskKind::Script && !worker)
            .then(|| self.script(el, owner, strict))
            .flatten();
        let message = matches!(kind, TaskKind::Send | TaskKind::Receive)
            .then(|| self.resolve(|b| &b.messages, el, "messageRef", owner))
            .flatten();
        Task {
            kind,
            binding,
            script,
            message,
            instantiate: el.attr("instantiate") == Some("true"),
            event: None,
        }
    }

    /// A message throw or end event implemented like a task (see [`Task::event`]).
    fn event_task(&mut self, el: &'d Element<'d>, owner: &str, strict: bool) -> Task {
        let mut t = self.task(el, "sendTask", owner, strict);
        let def = el.bpmn_child("messageEventDefinition");
        if t.binding.is_none()
            && let Some(d) = def
        {
            // Camunda 7 puts the delegate on the event definition.
            t.binding = BindingReader {
                sink: self.sink,
                element_id: owner,
                strict,
            }
            .read(d);
        }
        t.message = def.and_then(|d| self.resolve(|b| &b.messages, d, "messageRef", owner));
        t.event = Some(if el.name == "endEvent" {
            "endEvent"
        } else {
            "intermediateThrowEvent"
        });
        t
    }

    fn script(&mut self, el: &Element, owner: &str, strict: bool) -> Option<Script> {
        // Camunda 8 writes a script task as one FEEL expression and the variable it sets.
        if let Some(z) = el
            .extensions()
            .find(|e| e.ns == Ns::Zeebe && e.name == "script")
        {
            let (Some(expression), Some(result)) = (z.attr("expression"), z.attr("resultVariable"))
            else {
                self.problem(
                    strict,
                    "bad-binding",
                    z.offset,
                    Some(owner),
                    "zeebe:script needs expression and resultVariable".to_owned(),
                );
                return None;
            };
            return match Expression::compile(expression, &Language::Feel) {
                Ok(e) => Some(Script {
                    format: Some("feel".to_owned()),
                    text: format!("{result} = {expression}"),
                    assignments: Some(vec![(result.to_owned(), e)]),
                }),
                Err(f) => {
                    self.expr_problem(strict, z.offset, owner, "zeebe:script", f);
                    None
                }
            };
        }
        let Some(s) = el.bpmn_child("script") else {
            let msg = match el.attr_ns(&Ns::Camunda, "resource") {
                Some(r) => format!(
                    "the script is kept in an external resource `{r}` (camunda:resource), which TRACE does not read; put it in <script>"
                ),
                None => "script task has no <script>".to_owned(),
            };
            self.problem(strict, "missing-script", el.offset, Some(owner), msg);
            return None;
        };
        let format = el
            .attr("scriptFormat")
            .filter(|f| !f.trim().is_empty())
            .map(str::to_owned);
        let text = s.trimmed_text().to_owned();
        // A FEEL script (Camunda 7's `scriptFormat="feel"`) is one expression; its value goes to
        // `camunda:resultVariable`, or nowhere.
        if format
            .as_deref()
            .is_some_and(|f| Language::named(f) == Language::Feel)
        {
            let result = el.attr_ns(&Ns::Camunda, "resultVariable");
            return match Expression::compile(&text, &Language::Feel) {
                Ok(e) => Some(Script {
                    format,
                    assignments: Some(result.map(|r| (r.to_owned(), e)).into_iter().collect()),
                    text,
                }),
                Err(f) => {
                    self.expr_problem(strict, s.offset, owner, "FEEL script", f);
                    None
                }
            };
        }
        let ours = matches!(format.as_deref(), Some("cel" | "text/x-cel" | "trace"));
        let assignments = match parse_assignments(&text) {
            Ok(a) => {
                if format.is_none() {
                    self.sink.bent(
                        "missing-script-format",
                        "EXT.053",
                        el.offset,
                        Some(owner),
                        "the script task names no scriptFormat; its script is read as CEL assignments".to_owned(),
                    );
                }
                Some(a)
            }
            Err(e) if ours => {
                self.problem(
                    strict,
                    "bad-script",
                    s.offset,
                    Some(owner),
                    format!("script: {e}"),
                );
                None
            }
            Err(e) if format.is_none() && !self.script_connector => {
                self.sink.bent(
                    "missing-script-format",
                    "EXT.053",
                    el.offset,
                    Some(owner),
                    "the script task names no scriptFormat".to_owned(),
                );
                let msg = format!(
                    "the script names no language and is not CEL assignments ({e}): TRACE runs CEL assignments `name = expression`, and scripts in other languages through a script connector"
                );
                self.problem(strict, "unevaluated-language", s.offset, Some(owner), msg);
                None
            }
            // A script in another language runs through a script connector.
            Err(_) => None,
        };
        Some(Script {
            format,
            text,
            assignments,
        })
    }

    fn default_flow(&mut self, nid: NodeId, el: &Element, owner: &str) {
        let Some(d) = el.attr("default") else { return };
        let d = local_ref(d);
        let found = self
            .g
            .node(nid)
            .outgoing
            .iter()
            .copied()
            .find(|f| self.g.flow(*f).id == d);
        match found {
            Some(f) => self.g.nodes[nid.index()].default_flow = Some(f),
            None => {
                self.sink.error(
                    "bad-default-flow",
                    el.offset,
                    Some(owner),
                    format!("default flow `{d}` is not an outgoing sequence flow of this element"),
                );
            }
        }
    }

    fn looping(&mut self, nid: NodeId, el: &Element, owner: &str, strict: bool) {
        if let Some(l) = el.bpmn_child("standardLoopCharacteristics") {
            let maximum = match l.attr("loopMaximum") {
                None => None,
                Some(m) => match m.trim().parse::<u64>() {
                    Ok(v) => Some(v),
                    Err(_) => {
                        self.problem(
                            strict,
                            "bad-attribute",
                            l.offset,
                            Some(owner),
                            format!("loopMaximum=\"{m}\" is not a non-negative whole number"),
                        );
                        None
                    }
                },
            };
            let condition = l
                .bpmn_child("loopCondition")
                .and_then(|c| self.expr(strict, c, owner, "loop condition"));
            self.g.nodes[nid.index()].looping = Some(Looping::Standard {
                test_before: l.attr("testBefore") == Some("true"),
                maximum,
                condition,
            });
            return;
        }
        let Some(m) = el.bpmn_child("multiInstanceLoopCharacteristics") else {
            return;
        };
        let zeebe = m
            .extensions()
            .find(|e| e.ns == Ns::Zeebe && e.name == "loopCharacteristics");
        let cardinality = m
            .bpmn_child("loopCardinality")
            .and_then(|c| self.expr(strict, c, owner, "loop cardinality"));
        // A data input of the activity's ioSpecification is read by its name (§10.3.8).
        let data_inputs = self.g.nodes[nid.index()]
            .data
            .as_ref()
            .map(|d| d.inputs.clone())
            .unwrap_or_default();
        let collection_written = m.bpmn_child("loopDataInputRef").is_some()
            || m.attr_ns(&Ns::Camunda, "collection").is_some()
            || zeebe.is_some_and(|z| z.attr("inputCollection").is_some());
        let mut input_collection = m
            .bpmn_child("loopDataInputRef")
            .map(|r| local_ref(r.text).to_owned())
            .map(|r| match data_inputs.iter().find(|p| p.id == r) {
                Some(p) => p.name.clone(),
                None => r,
            })
            .or_else(|| m.attr_ns(&Ns::Camunda, "collection").map(str::to_owned))
            .map(|c| (c, Language::Cel))
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("inputCollection"))
                    .map(|c| (c.to_owned(), Language::Feel))
            })
            .and_then(|(c, language)| match Expression::compile(&c, &language) {
                Ok(e) => Some(e),
                Err(f) => {
                    self.expr_problem(strict, m.offset, owner, "input collection", f);
                    None
                }
            });
        // A collection that is written but does not compile has its own diagnostic.
        if !collection_written && m.bpmn_child("loopCardinality").is_none() && strict {
            self.problem(
                strict,
                "missing-cardinality",
                m.offset,
                Some(owner),
                "multi-instance needs a loopCardinality or an input collection".to_owned(),
            )
            .constraint("EXT.067");
            input_collection = None;
        }
        let item_name = |child: &str| {
            m.bpmn_child(child)
                .and_then(|d| d.attr("name").or(d.attr("id")))
                .map(str::to_owned)
        };
        let input_element = item_name("inputDataItem")
            .or_else(|| {
                m.attr_ns(&Ns::Camunda, "elementVariable")
                    .map(str::to_owned)
            })
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("inputElement"))
                    .map(str::to_owned)
            });
        let output_collection = m
            .bpmn_child("loopDataOutputRef")
            .map(|r| local_ref(r.text).to_owned())
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("outputCollection"))
                    .map(str::to_owned)
            });
        let output_element =
            match item_name("outputDataItem") {
                Some(name) => Expression::parse(&name).ok(),
                None => zeebe.and_then(|z| z.attr("outputElement")).and_then(|e| {
                    match Expression::compile(e, &Language::Feel) {
                        Ok(e) => Some(e),
                        Err(f) => {
                            self.expr_problem(strict, m.offset, owner, "output element", f);
                            None
                        }
                    }
                }),
            };
        let completion = m
            .bpmn_child("completionCondition")
            .and_then(|c| self.expr(strict, c, owner, "completion condition"));
        let behavior = match m.attr("behavior") {
            Some("None") => MiBehavior::None,
            Some("One") => MiBehavior::One,
            Some("Complex") => MiBehavior::Complex,
            _ => MiBehavior::All,
        };
        self.g.nodes[nid.index()].looping = Some(Looping::MultiInstance(Box::new(MultiInstance {
            sequential: m.attr("isSequential") == Some("true"),
            cardinality,
            input_collection,
            input_element,
            output_collection,
            output_element,
            completion,
            behavior,
            complex: m
                .bpmn_children("complexBehaviorDefinition")
                .filter_map(|d| d.bpmn_child("condition"))
                .filter_map(|c| self.expr(strict, c, owner, "complex behavior condition"))
                .collect(),
        })));
    }

    fn collaboration(&mut self, el: &Element) {
        let participants = el
            .bpmn_children("participant")
            .map(|p| Participant {
                id: p.attr("id").unwrap_or_default().to_owned(),
                name: p.attr("name").map(str::to_owned),
                process: p.attr("processRef").and_then(|r| {
                    let r = local_ref(r);
                    let found = self.find_process(self.doc_of(p.offset), r, false);
                    if found.is_none() {
                        self.sink.warning(
                            "dangling-reference",
                            p.offset,
                            p.attr("id"),
                            format!(
                                "participant processRef `{r}` does not name a process of this model"
                            ),
                        );
                    }
                    found
                }),
            })
            .collect();
        let mut message_flows = Vec::new();
        for f in el.bpmn_children("messageFlow") {
            let id = f.attr("id").unwrap_or_default().to_owned();
            let mut ends = Vec::new();
            for attr in ["sourceRef", "targetRef"] {
                let r = f.attr(attr).map(local_ref).unwrap_or_default().to_owned();
                if self.any_ref(f.offset, &r).is_none() {
                    self.sink.error(
                        "dangling-reference",
                        f.offset,
                        Some(&id),
                        format!("message flow {attr} `{r}` does not exist"),
                    );
                }
                ends.push(r);
            }
            let message = self.resolve(|b| &b.messages, f, "messageRef", &id);
            let target = ends.pop().unwrap_or_default();
            let source = ends.pop().unwrap_or_default();
            message_flows.push(MessageFlow {
                id,
                source,
                target,
                message,
            });
        }
        self.g.collaborations.push(Collaboration {
            id: el.attr("id").unwrap_or_default().to_owned(),
            participants,
            message_flows,
        });
    }
}

/// The variable an item-aware element stands for: its name, else its id.
fn item_name(el: &Element) -> String {
    el.attr("name")
        .or(el.attr("id"))
        .unwrap_or_default()
        .to_owned()
}

fn data_items(el: &Element, name: &str) -> Vec<DataItem> {
    el.bpmn_children(name)
        .map(|d| DataItem {
            id: d.attr("id").unwrap_or_default().to_owned(),
            name: d.attr("name").map(str::to_owned),
            collection: d.attr("isCollection") == Some("true"),
        })
        .collect()
}

/// `startQuantity` / `completionQuantity`: a positive count, 1 when absent. Zero and garbage
/// refuse an executable process (EXT.037/038) and are read as 1 in a descriptive one.
fn quantity(raw: Option<&str>) -> u32 {
    raw.and_then(|v| v.trim().parse().ok())
        .filter(|&q| q > 0)
        .unwrap_or(1)
        .min(crate::MAX_QUANTITY)
}
