//! The validated, immutable process graph: every BPMN element of a mission model, indexed.
//!
//! Elements live in flat arenas (`nodes`, `flows`, …) addressed by small copyable ids, so the
//! engine can hold positions as integers and the graph can be shared read-only. Each node knows
//! its [`Scope`] (the process or sub-process that contains it), its flows and its boundary events.

use std::collections::BTreeMap;

use crate::binding::TaskBinding;
use crate::diagnostic::Diagnostic;
use crate::expr::Expression;
use crate::timer::Timer;

macro_rules! id_type {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(
            Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
        )]
        #[serde(transparent)]
        pub struct $name(pub u32);
        impl $name {
            /// The arena index.
            pub fn index(self) -> usize {
                self.0 as usize
            }
        }
    };
}

id_type!(
    /// Index of a flow node in [`ProcessGraph::nodes`].
    NodeId
);
id_type!(
    /// Index of a sequence flow in [`ProcessGraph::flows`].
    FlowId
);
id_type!(
    /// Index of a process in [`ProcessGraph::processes`].
    ProcessId
);
id_type!(
    /// Index of a message in [`ProcessGraph::messages`].
    MessageId
);
id_type!(
    /// Index of a signal in [`ProcessGraph::signals`].
    SignalId
);
id_type!(
    /// Index of an error in [`ProcessGraph::errors`].
    ErrorId
);
id_type!(
    /// Index of an escalation in [`ProcessGraph::escalations`].
    EscalationId
);

/// The most tokens a `startQuantity` or `completionQuantity` may name. More is refused in an
/// executable process (each token is state the engine keeps; a fuzzed `completionQuantity` of
/// four billion is four billion tokens spawned in one step) and read as this in a drawing.
pub const MAX_QUANTITY: u32 = 1000;

/// A loaded mission model: one BPMN `definitions` document (plus the documents it imports).
#[derive(Debug)]
pub struct ProcessGraph {
    /// `id` of the `definitions` element.
    pub id: Option<String>,
    /// `targetNamespace` of the `definitions` element.
    pub target_namespace: Option<String>,
    /// All processes, in document order.
    pub processes: Vec<Process>,
    /// All flow nodes of all processes and sub-processes.
    pub nodes: Vec<Node>,
    /// All sequence flows.
    pub flows: Vec<SequenceFlow>,
    /// Global message definitions.
    pub messages: Vec<Message>,
    /// Global signal definitions.
    pub signals: Vec<Signal>,
    /// Global error definitions.
    pub errors: Vec<ErrorDef>,
    /// Global escalation definitions.
    pub escalations: Vec<Escalation>,
    /// Collaborations (pools and message flows).
    pub collaborations: Vec<Collaboration>,
    /// Warnings found while loading (the graph has no errors, or it would not exist).
    pub warnings: Vec<Diagnostic>,
    /// Global tasks (`globalScriptTask`, …) by id, run by call activities.
    pub global_tasks: BTreeMap<String, Task>,
    /// Every node, sorted by BPMN id (the first of equal ids only): the index of
    /// [`ProcessGraph::node_by_id`], holding no second copy of the ids.
    pub(crate) node_ids: Vec<NodeId>,
    pub(crate) process_ids: BTreeMap<String, ProcessId>,
}

impl ProcessGraph {
    /// The pools of every collaboration, in document order.
    pub fn participants(&self) -> impl Iterator<Item = &Participant> {
        self.collaborations.iter().flat_map(|c| &c.participants)
    }

    /// The node with this index.
    pub fn node(&self, id: NodeId) -> &Node {
        &self.nodes[id.index()]
    }

    /// The sequence flow with this index.
    pub fn flow(&self, id: FlowId) -> &SequenceFlow {
        &self.flows[id.index()]
    }

    /// The process with this index.
    pub fn process(&self, id: ProcessId) -> &Process {
        &self.processes[id.index()]
    }

    /// Looks a flow node up by its BPMN id.
    pub fn node_by_id(&self, id: &str) -> Option<NodeId> {
        let at = self
            .node_ids
            .binary_search_by(|n| self.nodes[n.index()].id.as_str().cmp(id))
            .ok()?;
        Some(self.node_ids[at])
    }

    /// Sorts [`ProcessGraph::node_ids`] once every node is in, keeping the first node of an id
    /// drawn twice.
    pub(crate) fn index_nodes(&mut self) {
        // Sorted as (id, node) pairs side by side, not as nodes looked up in the graph for
        // every comparison.
        let mut ids: Vec<(&str, NodeId)> = self
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| (n.id.as_str(), NodeId(i as u32)))
            .collect();
        ids.sort_unstable();
        ids.dedup_by(|later, first| later.0 == first.0);
        self.node_ids = ids.into_iter().map(|(_, n)| n).collect();
    }

    /// Looks a process up by its BPMN id.
    pub fn process_by_id(&self, id: &str) -> Option<ProcessId> {
        self.process_ids.get(id).copied()
    }

    /// The nodes directly inside `scope`.
    pub fn scope_nodes(&self, scope: Scope) -> &[NodeId] {
        match scope {
            Scope::Process(p) => &self.process(p).nodes,
            Scope::SubProcess(n) => match &self.node(n).kind {
                NodeKind::SubProcess(s) => &s.nodes,
                _ => &[],
            },
        }
    }

    /// The process a node belongs to, however deeply nested.
    pub fn process_of(&self, mut node: NodeId) -> ProcessId {
        loop {
            match self.node(node).scope {
                Scope::Process(p) => return p,
                Scope::SubProcess(parent) => node = parent,
            }
        }
    }

    /// The processes some call activity calls.
    pub fn called_processes(&self) -> std::collections::BTreeSet<ProcessId> {
        self.nodes
            .iter()
            .filter_map(|n| match &n.kind {
                NodeKind::CallActivity(CallActivity {
                    called: Some(Called::Process(p)),
                    ..
                }) => Some(*p),
                _ => None,
            })
            .collect()
    }

    /// Processes that start when the mission starts: the executable ones of the model file
    /// that no call activity calls. Processes marked `isExecutable="false"` are descriptive
    /// and never run; imported and called ones run only when called.
    pub fn primary_processes(&self) -> Vec<ProcessId> {
        let called = self.called_processes();
        (0..self.processes.len() as u32)
            .map(ProcessId)
            .filter(|p| {
                self.process(*p).executable && !self.process(*p).imported && !called.contains(p)
            })
            .collect()
    }
}

/// Where a node sits: directly in a process, or inside a sub-process node.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Scope {
    /// Top level of a process.
    Process(ProcessId),
    /// Inside a sub-process (embedded, event, transaction or ad-hoc).
    SubProcess(NodeId),
}

/// One BPMN process.
#[derive(Debug)]
pub struct Process {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// Checked and run as executable: `isExecutable` is not `false` (absent counts as executable,
    /// as Camunda Modeler and the conformance suites assume).
    pub executable: bool,
    /// `isExecutable="true"` is written. Without it, the process is run when asked to, but what
    /// would stop it running is an execution finding, not a breach of BPMN (it may be a drawing).
    pub declared_executable: bool,
    /// Comes from an imported document: callable, but not started with the mission.
    pub imported: bool,
    /// Nodes at the top level of the process.
    pub nodes: Vec<NodeId>,
    /// Process properties (variables declared by the model).
    pub properties: Vec<DataItem>,
    /// Data objects declared at the top level.
    pub data_objects: Vec<DataItem>,
    /// Lanes, flattened (nested lane sets included).
    pub lanes: Vec<Lane>,
    /// Byte offset of the element in the source.
    pub offset: usize,
}

/// A declared data object or property.
#[derive(Debug, Clone)]
pub struct DataItem {
    /// BPMN id.
    pub id: String,
    /// Name, which is also the variable name.
    pub name: Option<String>,
    /// `isCollection`.
    pub collection: bool,
}

/// A lane: a named partition of a process holding some nodes.
#[derive(Debug, Clone)]
pub struct Lane {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// Nodes drawn in the lane.
    pub nodes: Vec<NodeId>,
}

/// A collaboration: pools (participants) and the message flows between them.
#[derive(Debug, Clone)]
pub struct Collaboration {
    /// BPMN id.
    pub id: String,
    /// Pools.
    pub participants: Vec<Participant>,
    /// Message flows.
    pub message_flows: Vec<MessageFlow>,
}

/// A pool.
#[derive(Debug, Clone)]
pub struct Participant {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// The process drawn in the pool, if any (a black-box pool has none).
    pub process: Option<ProcessId>,
}

/// A message flow between two pools.
#[derive(Debug, Clone)]
pub struct MessageFlow {
    /// BPMN id.
    pub id: String,
    /// BPMN id of the sending element (node or participant).
    pub source: String,
    /// BPMN id of the receiving element (node or participant).
    pub target: String,
    /// The message carried, if named.
    pub message: Option<MessageId>,
}

/// A global message.
#[derive(Debug, Clone)]
pub struct Message {
    /// BPMN id.
    pub id: String,
    /// Name used for correlation.
    pub name: String,
    /// Correlation key expression (Zeebe `subscription correlationKey`), if any.
    pub correlation_key: Option<Expression>,
}

/// A global signal.
#[derive(Debug, Clone)]
pub struct Signal {
    /// BPMN id.
    pub id: String,
    /// Name; signals are broadcast by name.
    pub name: String,
}

/// A global error.
#[derive(Debug, Clone)]
pub struct ErrorDef {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// `errorCode`: what connectors report and boundary events match.
    pub code: Option<String>,
}

/// A global escalation.
#[derive(Debug, Clone)]
pub struct Escalation {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// `escalationCode`.
    pub code: Option<String>,
}

/// A sequence flow.
#[derive(Debug)]
pub struct SequenceFlow {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// Source node.
    pub source: NodeId,
    /// Target node.
    pub target: NodeId,
    /// `conditionExpression`.
    pub condition: Option<Expression>,
    /// Byte offset of the element in the source.
    pub offset: usize,
}

/// A flow node: event, gateway, activity.
#[derive(Debug)]
pub struct Node {
    /// BPMN id.
    pub id: String,
    /// Display name.
    pub name: Option<String>,
    /// What the node is.
    pub kind: NodeKind,
    /// The process or sub-process containing it.
    pub scope: Scope,
    /// Incoming sequence flows, in document order.
    pub incoming: Vec<FlowId>,
    /// Outgoing sequence flows, in document order.
    pub outgoing: Vec<FlowId>,
    /// `default` flow (gateways and activities).
    pub default_flow: Option<FlowId>,
    /// Boundary events attached to this activity, in document order.
    pub boundaries: Vec<NodeId>,
    /// Loop or multi-instance characteristics (activities).
    pub looping: Option<Looping>,
    /// `isForCompensation`.
    pub for_compensation: bool,
    /// `startQuantity`: tokens that must arrive before the activity starts (1 unless set; at
    /// most [`MAX_QUANTITY`]).
    pub start_quantity: u32,
    /// `completionQuantity`: tokens the activity emits on each outgoing flow (1 unless set; at
    /// most [`MAX_QUANTITY`]).
    pub completion_quantity: u32,
    /// Compensation handler reached from this activity's compensation boundary event.
    pub compensation_handler: Option<NodeId>,
    /// The activity's ioSpecification and data associations (§10.4), if it declares any.
    pub data: Option<Box<DataIo>>,
    /// Byte offset of the element in the source.
    pub offset: usize,
}

/// An activity's data interface and data associations (§10.4.1, executed as §10.4.2).
#[derive(Debug, Default)]
pub struct DataIo {
    /// `dataInput`s of the ioSpecification, in document order.
    pub inputs: Vec<DataParam>,
    /// `dataOutput`s of the ioSpecification, in document order.
    pub outputs: Vec<DataParam>,
    /// `inputSet`s, in document order (indexes into `inputs`).
    pub input_sets: Vec<IoSet>,
    /// `outputSet`s, in document order (indexes into `outputs`).
    pub output_sets: Vec<IoSet>,
    /// `dataInputAssociation`s, in document order.
    pub input_associations: Vec<DataAssociation>,
    /// `dataOutputAssociation`s, in document order.
    pub output_associations: Vec<DataAssociation>,
}

/// A data input or output: the goal or result field of its name.
#[derive(Debug, Clone)]
pub struct DataParam {
    /// BPMN id.
    pub id: String,
    /// Field name: the `name`, else the id.
    pub name: String,
}

/// An input or output set.
#[derive(Debug, Clone, Default)]
pub struct IoSet {
    /// The data inputs (outputs) of the set.
    pub refs: Vec<usize>,
    /// Those of `refs` that may be unavailable.
    pub optional: Vec<usize>,
}

/// What a data association reads or writes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DataRef {
    /// A data object, property, process data input or output, or multi-instance data item:
    /// the variable of that name.
    Variable(String),
    /// A data store: the system data of that name.
    Store(String),
    /// A data input of the activity.
    Input(usize),
    /// A data output of the activity.
    Output(usize),
}

/// A data input or output association.
#[derive(Debug)]
pub struct DataAssociation {
    /// `sourceRef`s.
    pub sources: Vec<DataRef>,
    /// `targetRef`.
    pub target: Option<DataRef>,
    /// `transformation`.
    pub transformation: Option<Expression>,
    /// `assignment`s: `from`, and the path `to` writes (its first part names the target).
    pub assignments: Vec<(Expression, String)>,
}

impl Node {
    /// Name if present, else id: how a person refers to the node.
    pub fn label(&self) -> &str {
        self.name
            .as_deref()
            .filter(|n| !n.trim().is_empty())
            .unwrap_or(&self.id)
    }

    /// Is this node an activity (task, sub-process or call activity)?
    pub fn is_activity(&self) -> bool {
        matches!(
            self.kind,
            NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_)
        )
    }
}

/// The kinds of flow node.
#[derive(Debug)]
pub enum NodeKind {
    /// Start event.
    Start(StartEvent),
    /// End event, with the results it throws (none = plain end).
    End(Vec<EventDefinition>),
    /// Intermediate catch event.
    Catch(CatchEvent),
    /// Intermediate throw event, with what it throws (none = pass-through).
    Throw(Vec<EventDefinition>),
    /// Boundary event.
    Boundary(BoundaryEvent),
    /// Gateway.
    Gateway(Gateway),
    /// Task of any kind.
    Task(Task),
    /// Sub-process of any kind.
    SubProcess(SubProcess),
    /// Call activity.
    CallActivity(CallActivity),
}

impl NodeKind {
    /// The BPMN element name, for messages.
    pub fn element_name(&self) -> &'static str {
        match self {
            NodeKind::Start(_) => "startEvent",
            NodeKind::End(_) => "endEvent",
            NodeKind::Catch(_) => "intermediateCatchEvent",
            NodeKind::Throw(_) => "intermediateThrowEvent",
            NodeKind::Boundary(_) => "boundaryEvent",
            NodeKind::Gateway(g) => g.kind.element_name(),
            NodeKind::Task(t) => t.event.unwrap_or(t.kind.element_name()),
            NodeKind::SubProcess(s) => match s.kind {
                SubProcessKind::Transaction => "transaction",
                SubProcessKind::AdHoc { .. } => "adHocSubProcess",
                _ => "subProcess",
            },
            NodeKind::CallActivity(_) => "callActivity",
        }
    }
}

/// A start event.
#[derive(Debug)]
pub struct StartEvent {
    /// Triggers; empty for a none start.
    pub triggers: Vec<EventDefinition>,
    /// `isInterrupting` (event sub-process starts).
    pub interrupting: bool,
    /// `parallelMultiple`: all triggers must occur.
    pub parallel_multiple: bool,
}

/// An intermediate catch event.
#[derive(Debug)]
pub struct CatchEvent {
    /// What it waits for (several = multiple, any one of them).
    pub triggers: Vec<EventDefinition>,
    /// `parallelMultiple`: all triggers must occur.
    pub parallel_multiple: bool,
}

/// A boundary event.
#[derive(Debug)]
pub struct BoundaryEvent {
    /// The activity it is attached to.
    pub attached_to: NodeId,
    /// What it waits for.
    pub triggers: Vec<EventDefinition>,
    /// `cancelActivity`: interrupting.
    pub interrupting: bool,
    /// `parallelMultiple`.
    pub parallel_multiple: bool,
}

/// An event definition: the trigger of a catch event or the result of a throw event.
#[derive(Debug)]
pub enum EventDefinition {
    /// Message, optionally naming the global message.
    Message(Option<MessageId>),
    /// Signal, optionally naming the global signal.
    Signal(Option<SignalId>),
    /// Timer.
    Timer(Timer),
    /// Conditional, with its condition.
    Conditional(Expression),
    /// Error.
    Error {
        /// The error; `None` catches every error.
        error: Option<ErrorId>,
        /// Catching: variable that receives the caught error code
        /// (`trace:errorCodeVariable` or `camunda:errorCodeVariable`).
        code_variable: Option<String>,
        /// Catching: variable that receives the error message.
        message_variable: Option<String>,
    },
    /// Escalation; `None` catches every escalation.
    Escalation(Option<EscalationId>),
    /// Terminate (end events).
    Terminate,
    /// Cancel (transactions).
    Cancel,
    /// Compensation, optionally of one activity.
    Compensate {
        /// `activityRef`: compensate only this activity.
        activity: Option<NodeId>,
        /// `waitForCompletion`.
        wait: bool,
    },
    /// Link, by name.
    Link(String),
}

impl EventDefinition {
    /// The BPMN name of the definition, for messages.
    pub fn element_name(&self) -> &'static str {
        match self {
            EventDefinition::Message(_) => "messageEventDefinition",
            EventDefinition::Signal(_) => "signalEventDefinition",
            EventDefinition::Timer(_) => "timerEventDefinition",
            EventDefinition::Conditional(_) => "conditionalEventDefinition",
            EventDefinition::Error { .. } => "errorEventDefinition",
            EventDefinition::Escalation(_) => "escalationEventDefinition",
            EventDefinition::Terminate => "terminateEventDefinition",
            EventDefinition::Cancel => "cancelEventDefinition",
            EventDefinition::Compensate { .. } => "compensateEventDefinition",
            EventDefinition::Link(_) => "linkEventDefinition",
        }
    }
}

/// A gateway.
#[derive(Debug)]
pub struct Gateway {
    /// Which kind.
    pub kind: GatewayKind,
    /// Complex gateway `activationCondition`.
    pub activation: Option<Expression>,
    /// Event-based gateway `instantiate`.
    pub instantiate: bool,
}

/// The gateway kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatewayKind {
    /// XOR.
    Exclusive,
    /// OR.
    Inclusive,
    /// AND.
    Parallel,
    /// Event-based (exclusive or parallel type).
    EventBased {
        /// `eventGatewayType="Parallel"`.
        parallel: bool,
    },
    /// Complex.
    Complex,
}

impl GatewayKind {
    /// The BPMN element name.
    pub fn element_name(self) -> &'static str {
        match self {
            GatewayKind::Exclusive => "exclusiveGateway",
            GatewayKind::Inclusive => "inclusiveGateway",
            GatewayKind::Parallel => "parallelGateway",
            GatewayKind::EventBased { .. } => "eventBasedGateway",
            GatewayKind::Complex => "complexGateway",
        }
    }
}

/// A task.
#[derive(Debug)]
pub struct Task {
    /// Which kind of task.
    pub kind: TaskKind,
    /// How the task reaches a system: resource name and typed inputs/outputs.
    pub binding: Option<TaskBinding>,
    /// Script of a script task.
    pub script: Option<Script>,
    /// Message of a send or receive task.
    pub message: Option<MessageId>,
    /// Receive task `instantiate`.
    pub instantiate: bool,
    /// The event this task stands for, when a message throw or end event is implemented like a
    /// task (a Camunda 8 job worker, a Camunda 7 delegate): `intermediateThrowEvent` or
    /// `endEvent`. It is dispatched as a send task; an end event's token then ends.
    pub event: Option<&'static str>,
}

impl Task {
    /// Is this a message end event implemented like a task?
    pub fn ends(&self) -> bool {
        self.event == Some("endEvent")
    }
}

/// The task kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TaskKind {
    /// Plain (undefined) task: passes through.
    Plain,
    /// Service task: a robot activity through a connector.
    Service,
    /// User task: a ground decision.
    User,
    /// Script task: evaluated by the engine.
    Script,
    /// Send task.
    Send,
    /// Receive task.
    Receive,
    /// Manual task: passes through.
    Manual,
    /// Business-rule task: dispatched like a service task.
    BusinessRule,
}

impl TaskKind {
    /// The BPMN element name.
    pub fn element_name(self) -> &'static str {
        match self {
            TaskKind::Plain => "task",
            TaskKind::Service => "serviceTask",
            TaskKind::User => "userTask",
            TaskKind::Script => "scriptTask",
            TaskKind::Send => "sendTask",
            TaskKind::Receive => "receiveTask",
            TaskKind::Manual => "manualTask",
            TaskKind::BusinessRule => "businessRuleTask",
        }
    }
}

/// A script: assignments in the expression language, or a foreign script run by a connector.
#[derive(Debug)]
pub struct Script {
    /// `scriptFormat`, if given.
    pub format: Option<String>,
    /// The script text as written.
    pub text: String,
    /// The parsed assignments, when the script is written in the expression language.
    pub assignments: Option<Vec<(String, Expression)>>,
}

/// A sub-process.
#[derive(Debug)]
pub struct SubProcess {
    /// Which kind.
    pub kind: SubProcessKind,
    /// Nodes directly inside it.
    pub nodes: Vec<NodeId>,
    /// Data objects and properties declared inside it: variables of each of its instances.
    pub data_objects: Vec<DataItem>,
}

/// The sub-process kinds.
#[derive(Debug)]
pub enum SubProcessKind {
    /// Embedded sub-process.
    Embedded,
    /// Event sub-process (`triggeredByEvent`).
    Event,
    /// Transaction.
    Transaction,
    /// Ad-hoc sub-process.
    AdHoc {
        /// `ordering="Sequential"`.
        sequential: bool,
        /// `completionCondition`.
        completion: Option<Expression>,
        /// `cancelRemainingInstances`.
        cancel_remaining: bool,
    },
}

/// A call activity.
#[derive(Debug)]
pub struct CallActivity {
    /// The process it calls; `None` only in a non-executable process whose callee is missing.
    pub called: Option<Called>,
    /// Input mappings into the called process (`camunda:in`, `zeebe:ioMapping`, ours).
    pub binding: Option<TaskBinding>,
}

/// What a call activity calls.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Called {
    /// A process of the same model.
    Process(ProcessId),
    /// A global task of the same model, by id (executed as a one-task process).
    GlobalTask(String),
}

/// Loop or multi-instance characteristics.
#[derive(Debug)]
pub enum Looping {
    /// `standardLoopCharacteristics`.
    Standard {
        /// `testBefore`.
        test_before: bool,
        /// `loopMaximum`.
        maximum: Option<u64>,
        /// `loopCondition`.
        condition: Option<Expression>,
    },
    /// `multiInstanceLoopCharacteristics`.
    MultiInstance(Box<MultiInstance>),
}

impl Looping {
    /// How many times the activity runs when the model fixes it without data: a multi-instance
    /// activity's [`MultiInstance::literal_count`], or a standard loop without a condition,
    /// which runs to its `loopMaximum` (at least once).
    pub fn literal_count(&self) -> Option<u64> {
        match self {
            Looping::Standard {
                maximum: Some(m),
                condition: None,
                ..
            } => Some((*m).max(1)),
            Looping::Standard { .. } => None,
            Looping::MultiInstance(mi) => mi.literal_count(),
        }
    }
}

/// Multi-instance characteristics.
#[derive(Debug)]
pub struct MultiInstance {
    /// `isSequential`.
    pub sequential: bool,
    /// `loopCardinality`.
    pub cardinality: Option<Expression>,
    /// The input collection (a variable or expression).
    pub input_collection: Option<Expression>,
    /// Name of the per-instance element variable.
    pub input_element: Option<String>,
    /// Variable collecting the outputs.
    pub output_collection: Option<String>,
    /// Expression giving each instance's output element.
    pub output_element: Option<Expression>,
    /// `completionCondition`.
    pub completion: Option<Expression>,
    /// `behavior` for throwing events of the instances.
    pub behavior: MiBehavior,
    /// Conditions of the `complexBehaviorDefinition`s (behavior `Complex`), in document order.
    pub complex: Vec<Expression>,
}

impl MultiInstance {
    /// How many instances run when the model writes the count as a number (`loopCardinality`
    /// `3`, no input collection), which verification can take as it is without data.
    pub fn literal_count(&self) -> Option<u64> {
        if self.input_collection.is_some() {
            return None;
        }
        self.cardinality.as_ref()?.text.trim().parse().ok()
    }
}

/// Multi-instance `behavior`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MiBehavior {
    /// Every completing instance throws the activity's event.
    None,
    /// Only the first completing instance throws.
    One,
    /// No event is thrown (the default).
    All,
    /// The `complexBehaviorDefinition`s decide.
    Complex,
}
