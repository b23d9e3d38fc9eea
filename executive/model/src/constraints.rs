//! BPMN 2.0 static constraints read off the element tree: typed references, data
//! (ioSpecification, item definitions, data associations), collaborations and message flows,
//! and the attributes the graph does not keep.
//!
//! Each check carries the BPMNspector number (`EXT.nnn`) of the constraint it enforces. The
//! constraints deliberately **not** enforced are listed in `docs/bpmn-constraints.md` with the
//! reason (e.g. EXT.128: WSDL `operationRef` on message events; the executive correlates
//! messages by name).

use std::borrow::Cow;
use std::cell::OnceCell;
use std::collections::BTreeSet;

use foldhash::{HashMap, HashMapExt, HashSet, HashSetExt};

use crate::build::{ACTIVITIES, FLOW_NODES, Ids, local_ref};
use crate::diagnostic::Sink;
use crate::xml::{Document, Element, Ns};

mod data;
use data::*;

/// Rules whose breach leaves the meaning clear: warnings naming the rule (errors with
/// `--strict`). Each message says how the model is read.
const BENT: &[&str] = &[
    "unknown-attribute",
    "bad-mime-type",
    "bad-uri",
    "natural-language-expression",
    "flow-mismatch",
    "io-set",
    "message-flow-none-event",
    "unknown-script-language",
    "collection-mismatch",
    "call-data-mismatch",
    "item-mismatch",
];

/// Rules only a strict reading reports (`Sink::pedantic`).
const PEDANTIC: &[&str] = &["missing-operation"];

/// References that execution never follows, and why a dangling one leaves the meaning clear:
/// `<incoming>`/`<outgoing>` repeat what the sequence flows say, lanes and categories only
/// document, item definitions only type data (the engine's values carry their own types),
/// interfaces and their operations describe services the executive does not call through WSDL,
/// and a loop data reference that names nothing is read as the name of a variable (as
/// SpiffWorkflow writes it). A dangling one is a rule bent harmlessly.
fn documentary(owner: &str, name: &str) -> Option<&'static str> {
    Some(match (owner, name) {
        (_, "incoming" | "outgoing") => "; the sequence flows' own sourceRef and targetRef decide",
        (_, "flowNodeRef") => "; lanes only document who does what",
        (_, "categoryValueRef") => "; categories only document",
        (_, "itemSubjectRef" | "itemRef" | "structureRef" | "evaluatesToTypeRef") => {
            "; item definitions only type data, and values carry their own types"
        }
        ("operation", _) | (_, "interfaceRef" | "supportedInterfaceRef") => {
            "; interfaces and operations are not called through"
        }
        (_, "loopDataInputRef" | "loopDataOutputRef") => {
            "; it is read as the name of a variable holding the collection"
        }
        _ => return None,
    })
}

/// Item-aware elements: what a data association may read or write, and what a reference to data
/// must name.
pub(crate) const ITEM_AWARE: &[&str] = &[
    "dataObject",
    "dataObjectReference",
    "property",
    "dataStore",
    "dataStoreReference",
    "dataInput",
    "dataOutput",
    // Multi-instance data items are data inputs and outputs (tDataInput / tDataOutput, §10.3.8).
    "inputDataItem",
    "outputDataItem",
];

/// Whether the schema type of `element` defines `attr`, for the attributes only some types have
/// (BPMN 2.0.2 `Semantic.xsd`), with the types that have it as a reader would say them; `None`
/// for the other attributes (`id` and `name` are on nearly every type, and `messageRef`,
/// `operationRef` and `implementation` on too many to check here). What the schema does not give
/// an element, TRACE does not read on it ([`schema_attr`]).
pub(crate) fn defines(element: &str, attr: &str) -> Option<(bool, &'static str)> {
    // Asked of every attribute of every element: the activity test only where it counts.
    let activity = || ACTIVITIES.contains(&element);
    Some(match attr {
        "isForCompensation" | "startQuantity" | "completionQuantity" => (activity(), "activities"),
        "default" => (
            activity()
                || matches!(
                    element,
                    "exclusiveGateway" | "inclusiveGateway" | "complexGateway"
                ),
            "activities and exclusive, inclusive and complex gateways",
        ),
        "gatewayDirection" => (
            matches!(
                element,
                "exclusiveGateway"
                    | "inclusiveGateway"
                    | "parallelGateway"
                    | "eventBasedGateway"
                    | "complexGateway"
            ),
            "gateways",
        ),
        "eventGatewayType" => (element == "eventBasedGateway", "<eventBasedGateway>"),
        "instantiate" => (
            matches!(element, "eventBasedGateway" | "receiveTask"),
            "<eventBasedGateway> and <receiveTask>",
        ),
        "parallelMultiple" => (
            matches!(
                element,
                "startEvent" | "intermediateCatchEvent" | "boundaryEvent"
            ),
            "catch events",
        ),
        "isInterrupting" => (element == "startEvent", "<startEvent>"),
        "cancelActivity" | "attachedToRef" => (element == "boundaryEvent", "<boundaryEvent>"),
        "triggeredByEvent" => (
            matches!(element, "subProcess" | "adHocSubProcess" | "transaction"),
            "sub-processes",
        ),
        "ordering" | "cancelRemainingInstances" => {
            (element == "adHocSubProcess", "<adHocSubProcess>")
        }
        "method" => (element == "transaction", "<transaction>"),
        "calledElement" => (element == "callActivity", "<callActivity>"),
        "scriptFormat" => (
            matches!(element, "scriptTask" | "globalScriptTask"),
            "<scriptTask> and <globalScriptTask>",
        ),
        "isImmediate" => (element == "sequenceFlow", "<sequenceFlow>"),
        "isSequential" | "behavior" | "oneBehaviorEventRef" | "noneBehaviorEventRef" => (
            element == "multiInstanceLoopCharacteristics",
            "<multiInstanceLoopCharacteristics>",
        ),
        "testBefore" | "loopMaximum" => (
            element == "standardLoopCharacteristics",
            "<standardLoopCharacteristics>",
        ),
        "waitForCompletion" | "activityRef" => (
            element == "compensateEventDefinition",
            "<compensateEventDefinition>",
        ),
        "errorRef" => (element == "errorEventDefinition", "<errorEventDefinition>"),
        "signalRef" => (
            element == "signalEventDefinition",
            "<signalEventDefinition>",
        ),
        "escalationRef" => (
            element == "escalationEventDefinition",
            "<escalationEventDefinition>",
        ),
        "errorCode" => (element == "error", "<error>"),
        "escalationCode" => (element == "escalation", "<escalation>"),
        _ => return None,
    })
}

/// The value of `attr` on `el`, where the schema gives `el`'s type that attribute ([`defines`]):
/// what the builder reads of the attributes only some types have.
pub(crate) fn schema_attr<'a>(el: &Element<'a>, attr: &str) -> Option<&'a str> {
    el.attr(attr)
        .filter(|_| !matches!(defines(el.name, attr), Some((false, _))))
}

/// Every unqualified attribute the BPMN 2.0 schema defines, on any element.
fn schema_attribute(name: &str) -> bool {
    // A `match` on the names: faster than hashing them, and this is asked of every attribute.
    matches!(
        name,
        "id" | "name"
            | "isExecutable"
            | "processType"
            | "isClosed"
            | "definitionalCollaborationRef"
            | "implementation"
            | "sourceRef"
            | "targetRef"
            | "isImmediate"
            | "default"
            | "gatewayDirection"
            | "eventGatewayType"
            | "instantiate"
            | "attachedToRef"
            | "cancelActivity"
            | "parallelMultiple"
            | "isInterrupting"
            | "isForCompensation"
            | "startQuantity"
            | "completionQuantity"
            | "triggeredByEvent"
            | "calledElement"
            | "scriptFormat"
            | "messageRef"
            | "operationRef"
            | "errorRef"
            | "signalRef"
            | "escalationRef"
            | "activityRef"
            | "waitForCompletion"
            | "errorCode"
            | "escalationCode"
            | "structureRef"
            | "itemKind"
            | "isCollection"
            | "itemSubjectRef"
            | "itemRef"
            | "dataObjectRef"
            | "dataStoreRef"
            | "capacity"
            | "isUnlimited"
            | "processRef"
            | "textFormat"
            | "associationDirection"
            | "categoryValueRef"
            | "value"
            | "targetNamespace"
            | "expressionLanguage"
            | "typeLanguage"
            | "exporter"
            | "exporterVersion"
            | "location"
            | "namespace"
            | "importType"
            | "method"
            | "ordering"
            | "cancelRemainingInstances"
            | "isSequential"
            | "behavior"
            | "testBefore"
            | "loopMaximum"
            | "oneBehaviorEventRef"
            | "noneBehaviorEventRef"
            | "evaluatesToTypeRef"
            | "language"
            | "inputDataRef"
            | "outputDataRef"
            | "initiatingParticipantRef"
            | "loopType"
            | "minimum"
            | "maximum"
            | "parameterRef"
            | "implementationRef"
            | "isRequired"
            | "correlationKeyRef"
            | "definition"
            | "mustUnderstand"
            | "type"
            | "inMessageRef"
            | "outMessageRef"
            | "calledChoreographyRef"
            | "calledCollaborationRef"
            | "resourceRef"
            | "partnerRoleRef"
            | "partnerEntityRef"
            | "participantRef"
            | "interfaceRef"
            | "messageFlowRef"
            | "conversationNodeRef"
            | "direction"
            | "dataStateRef"
            | "dataInputRefs"
            | "dataOutputRefs"
            | "correlationPropertyRef"
    )
}

/// Allowed target kinds for a reference held in a child element (`<x>id</x>`) or an attribute.
fn ref_targets(owner: &str, name: &str) -> Option<&'static [&'static str]> {
    Some(match (owner, name) {
        (_, "participantRef") | (_, "initiatingParticipantRef") => &["participant"],
        (_, "errorRef") => &["error"],
        (_, "messageRef" | "inMessageRef" | "outMessageRef") => &["message"],
        (_, "signalRef") => &["signal"],
        (_, "escalationRef") => &["escalation"],
        (_, "itemRef" | "itemSubjectRef") => &["itemDefinition"],
        ("error" | "signal" | "escalation", "structureRef") => &["itemDefinition"],
        (_, "operationRef") => &["operation"],
        (_, "interfaceRef" | "supportedInterfaceRef") => &["interface"],
        ("participant", "processRef") => &["process"],
        (_, "dataObjectRef") => &["dataObject"],
        (_, "dataStoreRef") => &["dataStore"],
        ("dataInputAssociation" | "dataOutputAssociation", "sourceRef" | "targetRef") => ITEM_AWARE,
        (_, "dataInputRefs" | "optionalInputRefs" | "whileExecutingInputRefs") => &["dataInput"],
        (_, "dataOutputRefs" | "optionalOutputRefs" | "whileExecutingOutputRefs") => {
            &["dataOutput"]
        }
        (_, "inputSetRefs") => &["inputSet"],
        (_, "outputSetRefs") => &["outputSet"],
        (_, "flowNodeRef") => FLOW_NODES,
        (_, "resourceRef") => &["resource"],
        (_, "parameterRef") => &["resourceParameter"],
        (_, "choreographyRef") => &["choreography"],
        (_, "categoryValueRef") => &["categoryValue"],
        (_, "messageFlowRef") => &["messageFlow"],
        (_, "incoming" | "outgoing") if FLOW_NODES.contains(&owner) => &["sequenceFlow"],
        ("multiInstanceLoopCharacteristics", "loopDataInputRef" | "loopDataOutputRef") => {
            ITEM_AWARE
        }
        (_, "activityRef") => ACTIVITIES,
        _ => return None,
    })
}

///
/// Lookups only, so hash maps; iteration goes through `elements`, in a fixed order.
struct Index<'d, 'i> {
    /// Every BPMN element with an id, keyed by (0, id): the build's index of a document whose
    /// ids are unique, or one of the document's own.
    by_id: Cow<'i, Ids<'d>>,
    /// The elements of `by_id`, first occurrence of each id.
    elements: Vec<&'d Element<'d>>,
    /// The process each element lies in, and the participant of each process. Built when first
    /// asked (only message flows and data visibility ask).
    processes: OnceCell<Processes<'d>>,
    /// Sequence flows among `elements`.
    flows: usize,
    /// Whether some id is given to more than one element.
    duplicate_ids: bool,
    /// The root, for walks done only when a check needs them.
    root: &'d Element<'d>,
    /// What holds each data input and output, by id: the element that declares it in its
    /// ioSpecification (`true`) or directly, as events do (`false`). Built when first asked.
    holders: OnceCell<HashMap<&'d str, (&'d Element<'d>, bool)>>,
    /// How many sequence flows end at and leave each element, by id. Built when first asked.
    ends: OnceCell<HashMap<&'d str, (usize, usize)>>,
}

/// Which process each element lies in, by element id, and the participant of each process, by
/// process id.
struct Processes<'d> {
    of: HashMap<&'d str, &'d str>,
    pools: HashMap<&'d str, &'d str>,
}

impl<'d, 'i> Index<'d, 'i> {
    /// The element attribute `attr` of `el` names, if it names one.
    fn named(&self, el: &Element, attr: &str) -> Option<&'d Element<'d>> {
        el.attr(attr).and_then(|r| self.get(local_ref(r)))
    }

    /// The element with id `id`, if any (the first, when several have it).
    fn get(&self, id: &str) -> Option<&'d Element<'d>> {
        self.by_id.get(&(0, id)).copied()
    }

    /// The index of `root`'s tree, on `shared` when given (see `by_id`).
    fn new(root: &'d Element<'d>, ids: usize, shared: Option<&'i Ids<'d>>) -> Index<'d, 'i> {
        let mut ix = Index {
            by_id: match shared {
                Some(shared) => Cow::Borrowed(shared),
                None => Cow::Owned(HashMap::with_capacity(ids)),
            },
            elements: Vec::with_capacity(ids),
            processes: OnceCell::new(),
            flows: 0,
            duplicate_ids: false,
            root,
            holders: OnceCell::new(),
            ends: OnceCell::new(),
        };
        let mut stack: Vec<&Element> = vec![root];
        while let Some(el) = stack.pop() {
            if el.ns != Ns::Bpmn {
                continue;
            }
            if let Some(id) = el.attr("id") {
                let first = match &mut ix.by_id {
                    // The build's index holds every id once.
                    Cow::Borrowed(_) => true,
                    Cow::Owned(own) => match own.entry((0, id)) {
                        std::collections::hash_map::Entry::Vacant(v) => {
                            v.insert(el);
                            true
                        }
                        std::collections::hash_map::Entry::Occupied(_) => false,
                    },
                };
                if first {
                    ix.elements.push(el);
                    ix.flows += usize::from(el.name == "sequenceFlow");
                } else {
                    ix.duplicate_ids = true;
                }
            }
            stack.extend(el.children);
        }
        ix
    }

    /// The process element `id` lies in (see `processes`).
    fn process_of(&self, id: &str) -> Option<&'d str> {
        self.processes().of.get(id).copied()
    }

    fn processes(&self) -> &Processes<'d> {
        self.processes.get_or_init(|| {
            let mut found = Processes {
                of: HashMap::with_capacity(self.elements.len()),
                pools: HashMap::new(),
            };
            let mut stack: Vec<(&Element, Option<&str>)> = vec![(self.root, None)];
            while let Some((el, process)) = stack.pop() {
                if el.ns != Ns::Bpmn {
                    continue;
                }
                let id = el.attr("id");
                let process = if el.name == "process" { id } else { process };
                if let (Some(id), Some(p)) = (id, process) {
                    found.of.insert(id, p);
                }
                if el.name == "participant"
                    && let (Some(id), Some(p)) = (id, el.attr("processRef"))
                {
                    found.pools.insert(local_ref(p), id);
                }
                stack.extend(el.children.iter().map(|c| (c, process)));
            }
            found
        })
    }

    /// What holds the data input or output `id` (see `holders`).
    /// The sequence flows ending at and leaving element `id` (their `targetRef` and
    /// `sourceRef` decide, whatever `<incoming>` and `<outgoing>` list).
    fn flow_ends(&self, id: &str) -> (usize, usize) {
        let ends = self.ends.get_or_init(|| {
            let mut ends: HashMap<&'d str, (usize, usize)> = HashMap::new();
            for f in self.elements.iter().filter(|e| e.name == "sequenceFlow") {
                if let Some(t) = f.attr("targetRef") {
                    ends.entry(local_ref(t)).or_default().0 += 1;
                }
                if let Some(s) = f.attr("sourceRef") {
                    ends.entry(local_ref(s)).or_default().1 += 1;
                }
            }
            ends
        });
        ends.get(id).copied().unwrap_or_default()
    }

    fn holder(&self, id: &str) -> Option<(&'d Element<'d>, bool)> {
        let holders = self.holders.get_or_init(|| {
            let data =
                |c: &Element| c.ns == Ns::Bpmn && matches!(c.name, "dataInput" | "dataOutput");
            let mut holders = HashMap::new();
            let mut stack = vec![self.root];
            while let Some(el) = stack.pop() {
                if el.ns != Ns::Bpmn {
                    continue;
                }
                for c in el.children {
                    if data(c) {
                        if let Some(id) = c.attr("id") {
                            holders.entry(id).or_insert((el, false));
                        }
                    } else if c.ns == Ns::Bpmn && c.name == "ioSpecification" {
                        for d in c.children.iter().filter(|d| data(d)) {
                            if let Some(id) = d.attr("id") {
                                holders.entry(id).or_insert((el, true));
                            }
                        }
                    }
                }
                stack.extend(el.children.iter());
            }
            holders
        });
        holders.get(id).copied()
    }

    fn kind(&self, id: &str) -> Option<&'d str> {
        self.get(local_ref(id)).map(|e| e.name)
    }

    /// The pool an element belongs to: a participant itself, or the participant of its process.
    fn pool(&self, id: &str) -> Option<&'d str> {
        let id = local_ref(id);
        let el = self.get(id)?;
        if el.name == "participant" {
            return el.attr("id");
        }
        let processes = self.processes();
        let p = processes.of.get(id)?;
        Some(processes.pools.get(p).copied().unwrap_or(p))
    }
}

fn is_formal(el: &Element) -> bool {
    el.attrs
        .iter()
        .any(|a| a.ns == Ns::Xsi && a.name == "type" && local_ref(a.value) == "tFormalExpression")
}

/// A literal that can never be a condition (a number or a quoted string).
fn non_boolean_literal(text: &str) -> bool {
    let t = text.trim();
    t.parse::<f64>().is_ok()
        || (t.len() >= 2
            && (t.starts_with('"') && t.ends_with('"') || t.starts_with('\'') && t.ends_with('\'')))
}

fn is_mime_type(v: &str) -> bool {
    let Some((ty, sub)) = v.split_once('/') else {
        return false;
    };
    let token = |s: &str| {
        !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || "!#$&^_.+-".contains(c))
    };
    token(ty) && token(sub.split(';').next().unwrap_or_default().trim())
}

fn is_uri(v: &str) -> bool {
    if v.starts_with("##") {
        return true;
    }
    let Some((scheme, _)) = v.split_once(':') else {
        return false;
    };
    scheme
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic())
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "+.-".contains(c))
        && !v.contains(char::is_whitespace)
}

/// Runs every element-level constraint over the document (with
/// [`crate::validate::element_check`] in the same walk), and [`event_data`].
pub(crate) fn check<'d>(doc: &'d Document<'d>, shared: Option<&Ids<'d>>, sink: &mut Sink) {
    let root = &doc.root;
    let ix = Index::new(root, doc.ids, shared);
    // Each element with its parent, whether its process is executable and marked so, and the
    // id of its process.
    type Visit<'e> = (
        &'e Element<'e>,
        Option<&'e Element<'e>>,
        bool,
        bool,
        Option<&'e str>,
    );
    let mut stack: Vec<Visit<'_>> = vec![(root, None, false, false, None)];
    // Flow ends listed by the node at that end (see `flow_node_refs`).
    let mut listed = 0;
    while let Some((el, parent, executable, declared, process)) = stack.pop() {
        if el.ns != Ns::Bpmn {
            continue;
        }
        let (executable, declared) = if el.name == "process" {
            (
                el.attr("isExecutable") != Some("false"),
                el.attr("isExecutable") == Some("true"),
            )
        } else {
            (executable, declared)
        };
        let flows = el
            .attr("gatewayDirection")
            .and(el.attr("id"))
            .map(|id| ix.flow_ends(id));
        crate::validate::element_check(el, executable, declared, flows, sink);
        let id = el.attr("id");
        let process = if el.name == "process" { id } else { process };
        let in_process = (id.is_some() && process.is_some()) || el.name == "process";
        // References whose breach leaves the meaning clear, reported as bent rules below.
        let mut soft: Vec<(&'static str, String)> = Vec::new();
        let mut err = |code: &'static str, constraint: &'static str, msg: String| {
            // Descriptive processes (isExecutable="false") are drawings: a broken reference there is
            // worth a warning, not a refusal, as vendor exports are full of them; reading
            // strictly, it breaks the rule all the same (REF).
            // An attribute the schema lacks, outside an executable process: said only when
            // reading strictly (drawings carry many, and nothing runs them).
            if PEDANTIC.contains(&code) || (code == "unknown-attribute" && !executable) {
                sink.pedantic(code, constraint, el.offset, id, msg);
            } else if BENT.contains(&code) || (constraint == "REF" && in_process && !executable) {
                sink.bent(code, constraint, el.offset, id, msg);
            } else {
                sink.error(code, el.offset, id, msg).constraint(constraint);
            }
        };
        // Attributes the schema does not define, unqualified (vendor ones carry a namespace), or
        // defines only on other types: ignored, with a warning (outside executable processes,
        // only when reading strictly).
        for a in el.attrs.iter().filter(|a| a.ns == Ns::None) {
            let msg = if !schema_attribute(a.name) {
                format!(
                    "<{}> has no attribute `{}` in BPMN 2.0; it is ignored (tool-specific attributes belong in their own namespace)",
                    el.name, a.name
                )
            } else if let Some((false, owners)) = defines(el.name, a.name) {
                format!(
                    "<{}> has no attribute `{}` in BPMN 2.0 (the schema gives it to {owners}); it is ignored",
                    el.name, a.name
                )
            } else {
                continue;
            };
            err("unknown-attribute", "XSD", msg);
        }
        // Typed references, in attributes and in child elements; a dangling one that execution
        // never follows is a rule bent harmlessly, reported below.
        let attrs = el
            .attrs
            .iter()
            .filter(|a| a.ns == Ns::None)
            .map(|a| (a.name, a.value));
        let children = el
            .children
            .iter()
            .filter(|c| c.ns == Ns::Bpmn && c.children.is_empty())
            .map(|c| (c.name, c.trimmed_text()));
        for (name, value) in attrs.chain(children) {
            // An association links any two elements; what it names must exist (a rule bent
            // harmlessly: only a compensation handler's association is followed, and a handler
            // it misses is reported as such).
            if el.name == "association"
                && matches!(name, "sourceRef" | "targetRef")
                && ix.kind(value).is_none()
            {
                soft.push((
                    "dangling-reference",
                    format!(
                        "{name} `{}` does not exist; an association only documents",
                        local_ref(value)
                    ),
                ));
                continue;
            }
            let Some(kinds) = ref_targets(el.name, name) else {
                continue;
            };
            match documentary(el.name, name) {
                Some(why) => check_ref(&ix, name, value, kinds, &mut |code, _, msg| {
                    soft.push((code, format!("{msg}{why}")));
                }),
                None => check_ref(&ix, name, value, kinds, &mut err),
            }
        }
        if FLOW_NODES.contains(&el.name) {
            listed += flow_node_refs(el, &ix, &mut err);
        }
        match el.name {
            "documentation" | "textAnnotation" => {
                if let Some(f) = el.attr("textFormat")
                    && !is_mime_type(f)
                {
                    let c = if el.name == "documentation" {
                        "EXT.004"
                    } else {
                        "EXT.010"
                    };
                    err(
                        "bad-mime-type",
                        c,
                        format!("textFormat=\"{f}\" is not a MIME type such as text/plain"),
                    );
                }
            }
            "scriptTask" => {
                const LANGUAGES: &[&str] = &[
                    "cel",
                    "trace",
                    "javascript",
                    "js",
                    "groovy",
                    "python",
                    "juel",
                    "feel",
                    "ecmascript",
                    "jruby",
                    "ruby",
                    "lua",
                ];
                if let Some(f) = el.attr("scriptFormat")
                    && !f.trim().is_empty()
                    && !is_mime_type(f)
                    && !LANGUAGES.contains(&f.to_ascii_lowercase().as_str())
                {
                    err(
                        "unknown-script-language",
                        "EXT.145",
                        format!(
                            "scriptFormat=\"{f}\" is not a MIME type (e.g. text/x-cel); it is read as the name of a script language, which a script connector runs"
                        ),
                    );
                }
            }
            "transaction" => {
                if let Some(m) = el.attr("method")
                    && !is_uri(m)
                {
                    err(
                        "bad-uri",
                        "EXT.060",
                        format!(
                            "transaction method=\"{m}\" is not a URI (e.g. ##Compensate); the transaction compensates, as with ##Compensate"
                        ),
                    );
                }
            }
            "participantMultiplicity" => {
                let num = |a: &str| el.attr(a).and_then(|v| v.trim().parse::<i64>().ok());
                if num("minimum").is_some_and(|m| m < 0) {
                    err(
                        "bad-multiplicity",
                        "EXT.029",
                        "participant multiplicity minimum cannot be negative".to_owned(),
                    );
                }
                if let (Some(min), Some(max)) = (num("minimum"), num("maximum"))
                    && (max < min || max < 1)
                {
                    err(
                        "bad-multiplicity",
                        "EXT.030",
                        format!(
                            "participant multiplicity maximum {max} is below the minimum {min} or below 1"
                        ),
                    );
                }
            }
            "choreography" | "globalConversation" if el.bpmn_child("choreographyRef").is_some() => {
                err(
                    "choreography-ref",
                    "EXT.027",
                    format!("a {} cannot reference a choreography", el.name),
                );
            }
            "collaboration" => {
                for r in el.bpmn_children("choreographyRef") {
                    if let Some(ch) = ix.get(local_ref(r.text)) {
                        let closed = |e: &Element| e.attr("isClosed") == Some("true");
                        if ch.name == "choreography" && closed(ch) != closed(el) {
                            err("is-closed-mismatch", "EXT.033", "the collaboration and the choreography it references must agree on isClosed".to_owned());
                        }
                    }
                }
            }
            "messageFlow" => message_flow(el, &ix, &mut err),
            "performer" | "humanPerformer" | "potentialOwner" | "resourceRole" => {
                let has_ref = el.bpmn_child("resourceRef").is_some();
                if has_ref && el.bpmn_child("resourceAssignmentExpression").is_some() {
                    err("resource-ambiguous", "EXT.039", "a resource role has either a resourceRef or a resourceAssignmentExpression, not both".to_owned());
                }
                if !has_ref && el.bpmn_child("resourceParameterBinding").is_some() {
                    err(
                        "resource-binding-without-ref",
                        "EXT.040",
                        "resource parameter bindings need a resourceRef".to_owned(),
                    );
                }
            }
            "dataInputAssociation" | "dataOutputAssociation" => {
                data_association(el, parent, &ix, &mut err)
            }
            "ioSpecification" => io_specification(el, &mut err),
            "dataObject" | "dataInput" | "dataOutput" | "inputDataItem" | "outputDataItem" => {
                if let Some(item) = ix.named(el, "itemSubjectRef") {
                    let coll = |e: &Element| e.attr("isCollection") == Some("true");
                    if item.name == "itemDefinition" && coll(item) != coll(el) {
                        let c = match el.name {
                            "dataObject" => "EXT.077",
                            "dataInput" => "EXT.081",
                            _ => "EXT.083",
                        };
                        err(
                            "collection-mismatch",
                            if el.name == "dataObject" {
                                "EXT.020"
                            } else {
                                c
                            },
                            format!(
                                "isCollection of {} does not match its itemDefinition `{}`",
                                el.name,
                                item.attr("id").unwrap_or_default()
                            ),
                        );
                    }
                }
            }
            "multiInstanceLoopCharacteristics" => {
                multi_instance(el, parent, executable, &ix, &mut err)
            }
            "serviceTask" => operation_items(el, &ix, &mut err),
            "sendTask" | "receiveTask" if el.attr("messageRef").is_some() => {
                message_items(el, &ix, &mut err);
                if let Some(io) = el.bpmn_child("ioSpecification") {
                    let send = el.name == "sendTask";
                    let (sets, items, c1, c2) = if send {
                        ("inputSet", "dataInput", "EXT.046", "EXT.047")
                    } else {
                        ("outputSet", "dataOutput", "EXT.050", "EXT.051")
                    };
                    if io.bpmn_children(sets).count() > 1 {
                        err(
                            "message-task-io",
                            c1,
                            format!("a {} with a message has at most one {sets}", el.name),
                        );
                    }
                    if io.bpmn_children(items).count() > 1 {
                        err(
                            "message-task-io",
                            c2,
                            format!("a {} with a message has at most one {items}", el.name),
                        );
                    }
                }
            }
            // A message event implemented by a job worker or delegate (Camunda) is a task: it
            // needs no message.
            "messageEventDefinition"
                if !parent.is_some_and(crate::binding::implemented_as_task) =>
            {
                if executable && el.attr("messageRef").is_none() {
                    err(
                        "missing-message",
                        "EXT.127",
                        "a message event in an executable process must name its message (messageRef) to be sent or correlated"
                            .to_owned(),
                    );
                }
                if declared
                    && el.attr("operationRef").is_none()
                    && el.bpmn_child("operationRef").is_none()
                {
                    err(
                        "missing-operation",
                        "EXT.128",
                        "a message event of a process marked isExecutable=\"true\" names the operation it uses (operationRef); TRACE sends and correlates by the message alone".to_owned(),
                    );
                }
            }
            "standardLoopCharacteristics"
                if parent.is_some_and(|p| {
                    p.bpmn_child("multiInstanceLoopCharacteristics").is_some()
                }) =>
            {
                err("two-loop-markers", "EXT.041", "an activity has either standard loop or multi-instance characteristics, not both".to_owned());
            }
            "ioBinding" => io_binding(el, &ix, &mut err),
            "callActivity" => call_data(el, &ix, &mut err),
            "conditionExpression"
            | "condition"
            | "loopCondition"
            | "completionCondition"
            | "activationCondition" => {
                let text = el.trimmed_text();
                if non_boolean_literal(text) {
                    let c = if parent.is_some_and(|p| p.name == "complexBehaviorDefinition") {
                        "EXT.072"
                    } else {
                        "EXT.071"
                    };
                    err(
                        "non-boolean-condition",
                        c,
                        format!("condition `{text}` is not a boolean expression"),
                    );
                }
            }
            _ => {}
        }
        // Natural-language expressions cannot be executed (EXT.012).
        const EXPRESSIONS: &[&str] = &[
            "conditionExpression",
            "condition",
            "loopCondition",
            "completionCondition",
            "activationCondition",
            "loopCardinality",
            "timeDate",
            "timeDuration",
            "timeCycle",
            "from",
            "to",
        ];
        let formal_by_schema =
            el.name == "condition" && parent.is_some_and(|p| p.name == "complexBehaviorDefinition");
        if executable
            && EXPRESSIONS.contains(&el.name)
            && !formal_by_schema
            && !is_formal(el)
            && !el.trimmed_text().is_empty()
        {
            err(
                "natural-language-expression",
                "EXT.012",
                format!(
                    "<{}> has no xsi:type=\"tFormalExpression\", which an executable process needs; it is read as a formal expression in the process's language",
                    el.name
                ),
            );
        }
        for (code, msg) in soft {
            sink.bent(code, "REF", el.offset, id, msg);
        }
        stack.extend(
            el.children
                .iter()
                .map(|c| (c, Some(el), executable, declared, process)),
        );
    }
    // Every end of every flow listed (ids unique, so no listing is counted twice): nothing for
    // `listed_flows` to find.
    if ix.duplicate_ids || listed != 2 * ix.flows {
        listed_flows(&ix, sink);
    }
    event_data(root, &ix, sink);
}

/// Where a document lists `<incoming>`/`<outgoing>` on its flow nodes, every sequence flow must
/// be listed at both of its ends (EXT.101 for start events, EXT.107 for end events).
/// Linear in the listings and flows, however many one node lists.
fn listed_flows(ix: &Index<'_, '_>, sink: &mut Sink) {
    // Every listing once: (the listing element's id, `incoming` or `outgoing`, the flow).
    let mut listings = HashSet::new();
    for el in &ix.elements {
        let Some(id) = el.attr("id") else {
            continue;
        };
        for child in ["incoming", "outgoing"] {
            listings.extend(
                el.bpmn_children(child)
                    .map(|r| (id, child, local_ref(r.text))),
            );
        }
    }
    if listings.is_empty() {
        return;
    }
    for f in ix.elements.iter().filter(|el| el.name == "sequenceFlow") {
        let fid = f.attr("id").unwrap_or_default();
        for (end, child) in [("sourceRef", "outgoing"), ("targetRef", "incoming")] {
            let Some(node) = f.attr(end).map(local_ref) else {
                continue;
            };
            let Some(n) = ix.get(node) else {
                continue;
            };
            if !listings.contains(&(node, child, fid)) {
                let c = match (n.name, child) {
                    ("startEvent", "outgoing") => "EXT.101",
                    ("endEvent", "incoming") => "EXT.107",
                    _ => "EXT.023",
                };
                let msg = format!(
                    "sequence flow `{fid}` is not listed in the <{child}> elements of `{node}`; the flow's own sourceRef and targetRef decide"
                );
                sink.bent("flow-mismatch", c, n.offset, Some(node), msg);
            }
        }
    }
}

fn check_ref(
    ix: &Index<'_, '_>,
    what: &str,
    value: &str,
    kinds: &[&str],
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    for r in value.split_whitespace() {
        match ix.kind(r) {
            // Operations and structures may live in imported WSDL or XSD documents.
            None if matches!(what, "operationRef" | "structureRef") => {}
            None => err(
                "dangling-reference",
                "REF",
                format!("{what} `{}` does not exist", local_ref(r)),
            ),
            Some(k) if !kinds.contains(&k) => err(
                "wrong-reference",
                "REF",
                format!(
                    "{what} `{}` names a <{k}>, not {}",
                    local_ref(r),
                    kinds.join(" or ")
                ),
            ),
            Some(_) => {}
        }
    }
}

/// Listings of one kind on one node that [`flow_node_refs`] counts, comparing each with those
/// before it.
const SHORT_LIST: usize = 16;

/// `<incoming>` / `<outgoing>` must list flows that really enter / leave the node (EXT.023).
/// Returns how many flows the node lists rightly (each once, among its first [`SHORT_LIST`]
/// listings of a kind), so that [`check`] can tell whether every flow is listed at both ends
/// without looking each one up again.
fn flow_node_refs(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) -> usize {
    let id = el.attr("id");
    let mut listed = 0;
    for (child, attr) in [("incoming", "targetRef"), ("outgoing", "sourceRef")] {
        for (i, r) in el.bpmn_children(child).enumerate() {
            let f = local_ref(r.text);
            let Some(flow) = ix.get(f).filter(|flow| flow.name == "sequenceFlow") else {
                continue;
            };
            if flow.attr(attr).map(local_ref) == Some(id.unwrap_or_default()) {
                // Once per flow, and only with an id (without one, no flow ends here). Past
                // `SHORT_LIST` listings the count is given up (pairs would grow quadratically):
                // `check` then runs `listed_flows`.
                let first = i < SHORT_LIST
                    && !el
                        .bpmn_children(child)
                        .take(i)
                        .any(|earlier| local_ref(earlier.text) == f);
                listed += usize::from(id.is_some() && first);
            } else {
                err(
                    "flow-mismatch",
                    "EXT.023",
                    format!(
                        "<{child}> lists sequence flow `{f}`, whose {attr} is not this element; the flow's own sourceRef and targetRef decide"
                    ),
                );
            }
        }
    }
    listed
}

fn message_flow(
    el: &Element,
    ix: &Index<'_, '_>,
    err: &mut impl FnMut(&'static str, &'static str, String),
) {
    let (Some(s), Some(t)) = (
        el.attr("sourceRef").map(local_ref),
        el.attr("targetRef").map(local_ref),
    ) else {
        return;
    };
    let interaction = |k: &str| {
        k == "participant"
            || ACTIVITIES.contains(&k)
            || k.ends_with("Event")
            || k == "choreographyTask"
    };
    for (end, role) in [(s, "source"), (t, "target")] {
        if let Some(k) = ix.kind(end)
            && !interaction(k)
        {
            err(
                "bad-message-flow-end",
                "EXT.009",
                format!(
                    "a message flow cannot connect <{k}> `{end}` (its {role}); only pools, activities and events exchange messages"
                ),
            );
        }
    }
    if s == t || ix.pool(s).is_some_and(|p| Some(p) == ix.pool(t)) {
        err(
            "message-flow-same-pool",
            "EXT.031",
            "a message flow must connect two different pools".to_owned(),
        );
    }
    let msg_def = |id: &str| {
        ix.get(id).is_some_and(|e| {
            e.bpmn_child("messageEventDefinition").is_some()
                || e.bpmn_children("eventDefinitionRef")
                    .any(|r| ix.kind(r.text) == Some("messageEventDefinition"))
        })
    };
    if let Some(k) = ix.kind(s) {
        if matches!(k, "startEvent" | "intermediateCatchEvent" | "boundaryEvent") {
            err(
                "bad-message-flow-end",
                "EXT.102",
                format!("<{k}> `{s}` catches events and cannot send a message flow"),
            );
        } else if matches!(k, "endEvent" | "intermediateThrowEvent") && !msg_def(s) {
            err(
                "message-flow-none-event",
                "EXT.109",
                format!(
                    "<{k}> `{s}` sends a message flow but is not a message event; the flow is drawn, no message is sent"
                ),
            );
        }
    }
    if let Some(k) = ix.kind(t) {
        if matches!(k, "endEvent" | "intermediateThrowEvent") {
            err(
                "bad-message-flow-end",
                "EXT.102",
                format!("<{k}> `{t}` throws events and cannot receive a message flow"),
            );
        } else if matches!(k, "startEvent" | "intermediateCatchEvent" | "boundaryEvent")
            && !msg_def(t)
        {
            err(
                "message-flow-none-event",
                "EXT.109",
                format!(
                    "<{k}> `{t}` receives a message flow but is not a message event; the flow is drawn, no message is awaited"
                ),
            );
        }
    }
}
