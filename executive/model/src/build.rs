//! Building the graph: the element tree of a `definitions` document -> [`ProcessGraph`].
//!
//! Two passes over each process: the first gives every flow node an id (so references that point
//! forward resolve), the second reads each node's details, flows, defaults and boundaries. Every
//! reference that does not resolve, and every element the executive cannot execute, becomes a
//! diagnostic; nothing is skipped silently.
//!
//! Rooms: this file holds the passes over a document (ids, globals, processes, scopes, flows,
//! references and expressions); what is read of each element is beside it, in `build/`: a
//! node's details (`nodes.rs`), event definitions (`events.rs`), tasks and scripts
//! (`tasks.rs`), data inputs and outputs (`data.rs`), defaults and loops (`looping.rs`),
//! collaborations (`collaboration.rs`).

use std::collections::BTreeMap;

use foldhash::{HashMap, HashMapExt};

use crate::binding::Reader as BindingReader;
use crate::constraints::schema_attr;
use crate::diagnostic::Sink;
use crate::expr::{Expression, Failure, Language, parse_assignments};
use crate::graph::*;
use crate::timer::{TimerKind, parse_timer};
use crate::xml::{Document, Element, Ns};

mod collaboration;
mod data;
mod events;
mod looping;
mod nodes;
mod tasks;

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
    /// Every BPMN element with an id, first occurrence of each: ids are unique per target
    /// namespace, so keyed by (namespace index, id).
    pub(crate) all_ids: Ids<'d>,
    /// Whether some id is given to more than one element of a namespace.
    duplicate_ids: bool,
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

/// Every BPMN element with an id, by (namespace index, id): the first of each.
pub(crate) type Ids<'d> = HashMap<(usize, &'d str), &'d Element<'d>>;

/// Builds the graph from parsed documents, with the index of their ids when no id is used twice
/// (the constraint checks look ids up in it). Returns `None` only when the root is not a BPMN
/// `definitions` element; every other problem is a diagnostic in `sink`.
pub(crate) fn build<'d>(
    docs: &[&'d Document<'d>],
    sink: &mut Sink,
    options: &crate::Options,
) -> Option<(ProcessGraph, Option<Ids<'d>>)> {
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
    // Flow nodes carry ids, so there are at most as many as ids: room for them at once, not
    // copied as it grows (on a large model the copies cost fresh pages too). Up to a bound, as
    // hostile input may hold millions of ids and no flow node.
    let ids: usize = docs.iter().map(|d| d.ids).sum();
    let nodes = ids.min(1 << 16);
    let mut b = Builder {
        sink,
        g: ProcessGraph {
            id: root.attr("id").map(str::to_owned),
            target_namespace: root.attr("targetNamespace").map(str::to_owned),
            processes: Vec::new(),
            nodes: Vec::with_capacity(nodes),
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
        node_src: Vec::with_capacity(nodes),
        flow_src: Vec::new(),
        associations: Vec::new(),
        messages: BTreeMap::new(),
        signals: BTreeMap::new(),
        errors: BTreeMap::new(),
        escalations: BTreeMap::new(),
        global_event_defs: BTreeMap::new(),
        global_tasks: BTreeMap::new(),
        all_ids: HashMap::with_capacity(ids),
        duplicate_ids: false,
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
    let ids = (!b.duplicate_ids).then_some(b.all_ids);
    Some((b.g, ids))
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
    fn any_ref(&self, offset: usize, id: &str) -> Option<&'d Element<'d>> {
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
                if let Some(other) = self.all_ids.get(&(ns, id)) {
                    let msg = format!(
                        "id `{id}` is used twice: by <{}> and by <{}> at byte {}",
                        el.name, other.name, other.offset
                    );
                    self.duplicate_ids = true;
                    self.sink
                        .error("duplicate-id", el.offset, Some(id), msg)
                        .constraint("EXT.002");
                } else {
                    self.all_ids.insert((ns, id), el);
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
                    // Attributes of activities only: on another element they are reported
                    // and ignored.
                    for_compensation: schema_attr(child, "isForCompensation") == Some("true"),
                    start_quantity: quantity(schema_attr(child, "startQuantity")),
                    completion_quantity: quantity(schema_attr(child, "completionQuantity")),
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
        self.g.flows.reserve_exact(sources.len());
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
                        let what = match b.any_ref(el.offset, r).map(|e| e.name) {
                            Some(name) => format!(
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
