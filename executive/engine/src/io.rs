//! What goes into the engine (inputs: things that happened) and what comes out (actions: things
//! the driver must do, and record entries).

use compact_str::CompactString;
use serde::{Deserialize, Serialize};

use crate::value::{Value, Vars};
use executive_model::{FlowId, NodeId};

/// Milliseconds since the Unix epoch, on the mission clock. Stamped on inputs by the driver.
pub type Millis = i64;

/// Identifies a process instance. Minted by the engine, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct InstanceId(pub u64);

/// Identifies a token. Minted by the engine, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct TokenId(pub u64);

/// Identifies a scope instance (process, sub-process, call, loop body). Minted by the engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ScopeId(pub u64);

/// Identifies a subscription (timer, message, signal or conditional wait). Minted by the engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct WaitId(pub u64);

/// One attempt at one task: the idempotency key for connectors and the fencing token for late
/// results. A repeated dispatch with the same key is the same goal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct TaskKey {
    /// The instance the task runs in.
    pub instance: InstanceId,
    /// The token at the task.
    pub token: TokenId,
    /// 1 for the first dispatch of this token, then one more for each loop iteration.
    pub attempt: u32,
}

impl std::fmt::Display for TaskKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{}-{}", self.instance.0, self.token.0, self.attempt)
    }
}

/// One arming of one timer. A repeating timer gets a new `firing` each time it is re-armed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct TimerKey {
    /// The instance the timer belongs to.
    pub instance: InstanceId,
    /// The subscription.
    pub wait: WaitId,
    /// 1 for the first arming, then one more per repetition of a cycle.
    pub firing: u32,
}

impl std::fmt::Display for TimerKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{}-{}", self.instance.0, self.wait.0, self.firing)
    }
}

/// One journaled input: the only thing the engine reads. `at` is stamped by the driver.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Input {
    /// Strictly increasing sequence number; a repeated or older one is rejected.
    pub seq: u64,
    /// When it happened, on the mission clock.
    pub at: Millis,
    /// What happened.
    pub event: Event,
}

/// Something that happened (past tense).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    /// Start an instance of a process (by BPMN id) with initial variables.
    InstanceStarted {
        /// The process id.
        process: String,
        /// Initial variables.
        vars: Vars,
        /// The start event (by id) that starts it. Without one, the first none start event in
        /// document order (each start event is an independent way to start a process), or,
        /// without start events, every activity and gateway without incoming flow.
        #[serde(default)]
        start: Option<String>,
    },
    /// A dispatched task finished successfully.
    TaskCompleted {
        /// Which attempt.
        task: TaskKey,
        /// The result's fields.
        output: Vars,
    },
    /// A dispatched task failed with a mission error code (a BPMN error, caught by boundaries).
    TaskFailed {
        /// Which attempt.
        task: TaskKey,
        /// The error code, e.g. `TOOL_STUCK`.
        code: String,
        /// A human-readable reason.
        message: String,
    },
    /// A ground operator answered an open user task.
    UserTaskAnswered {
        /// Which user task.
        task: TaskKey,
        /// The answer's fields.
        answer: Vars,
        /// Who answered.
        operator: String,
    },
    /// A timer the engine started fell due.
    TimerFired {
        /// Which arming.
        timer: TimerKey,
    },
    /// A message arrived from outside.
    MessageReceived {
        /// The message name.
        name: String,
        /// Correlation key: only a waiting catcher whose key evaluates to this value takes it.
        correlation: Option<Value>,
        /// The message's fields, merged into the receiving scope.
        payload: Vars,
        /// The message flow it came along, from the executive of another pool (a fleet): only
        /// that flow's target takes it, and a message it cannot take is refused
        /// ([`Rejected::Undeliverable`]) with the state unchanged.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        flow: Option<String>,
        /// The sender's key for it (`<sender mission>.<message number>`): a key already
        /// delivered is refused as [`Rejected::AlreadyDelivered`], so a resend is harmless.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        key: Option<String>,
    },
    /// A signal arrived from outside; it is broadcast to every waiting catcher.
    SignalReceived {
        /// The signal name.
        name: String,
    },
    /// System data changed (telemetry); conditions that read `key` are re-evaluated.
    DataChanged {
        /// The data key, e.g. `battery_soc_pct`.
        key: String,
        /// The new value.
        value: Value,
    },
    /// An operator fires a subscription by hand (a contingency forced from the ground, or a
    /// step of a token game), as if its event had occurred.
    WaitTriggered {
        /// The subscription.
        wait: WaitId,
    },
    /// Token games with [`crate::Game::decide`]: the branches a token waiting at a diverging
    /// gateway takes (exactly one at an exclusive gateway).
    BranchTaken {
        /// The token at the gateway.
        token: TokenId,
        /// The outgoing flows it takes.
        flows: Vec<executive_model::FlowId>,
    },
    /// Cancel an instance: every in-flight task is cancelled and the instance ends.
    CancelRequested {
        /// Which instance.
        instance: InstanceId,
    },
}

/// Something the driver must do (imperative). Persist first, then act.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Action {
    /// Run a task through the connector that serves its resource: [`crate::resource`] of
    /// `node`, read from the model where the command is given.
    DispatchTask {
        /// Idempotency key.
        task: TaskKey,
        /// The task element.
        node: NodeId,
        /// The goal's fields.
        request: Vars,
    },
    /// Abort a dispatched task.
    CancelTask {
        /// Which attempt.
        task: TaskKey,
    },
    /// Ask the ground: open a user task.
    OpenUserTask {
        /// Its key; the answer quotes it.
        task: TaskKey,
        /// The user task element.
        node: NodeId,
        /// The variables the operator sees.
        context: Vars,
    },
    /// The user task is no longer open (answered or withdrawn).
    CloseUserTask {
        /// Which user task.
        task: TaskKey,
    },
    /// Fire `TimerFired { timer }` at `at` (at once if `at` has passed).
    StartTimer {
        /// Which arming.
        timer: TimerKey,
        /// Deadline on the mission clock.
        at: Millis,
    },
    /// Forget a started timer.
    CancelTimer {
        /// Which arming.
        timer: TimerKey,
    },
    /// Deliver a message outside the engine: along a message flow to a pool this engine does
    /// not run (another executive's, or a black box), or, with no flow, because no catcher
    /// inside waited for it. Boxed: the rarest command is the largest, and every other action
    /// (most are record entries) moves at the size of the next largest.
    SendMessage(Box<Outgoing>),
    /// Append an entry to the execution record.
    Record(Record),
    /// The instance ended.
    InstanceFinished {
        /// Which instance.
        instance: InstanceId,
        /// How.
        outcome: Outcome,
    },
}

/// A message the engine sends out ([`Action::SendMessage`]).
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Outgoing {
    /// The message name.
    pub name: String,
    /// Its fields.
    pub payload: Vars,
    /// The participant (pool) it goes to, when a message flow names one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<String>,
    /// The message flow it goes along.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flow: Option<String>,
    /// The sender's value of the message's correlation key, if it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation: Option<Value>,
    /// The message's number, minted by this engine (one more per message sent along a
    /// flow): with the mission id, the key that makes sending it again harmless.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number: Option<u64>,
}

/// How an instance ended.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Outcome {
    /// Every token reached an end.
    Completed,
    /// A terminate end event ended it.
    Terminated,
    /// An error nothing caught ended it.
    Failed {
        /// The error code.
        code: String,
        /// The reason.
        message: String,
    },
    /// Cancelled on request.
    Cancelled,
}

/// One execution-record entry produced by a step.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Record {
    /// The instance.
    pub instance: InstanceId,
    /// Mission time of the step.
    pub at: Millis,
    /// What happened.
    pub entry: Entry,
}

/// The kinds of record entries.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Entry {
    /// The instance started.
    InstanceStarted {
        /// The process.
        process: String,
        /// Initial variables.
        vars: Vars,
    },
    /// The instance ended.
    InstanceFinished {
        /// How.
        outcome: Outcome,
        /// Escalations nothing caught, by code.
        uncaught_escalations: Vec<String>,
    },
    /// A token entered a flow node.
    Entered {
        /// The node.
        node: NodeId,
        /// The token.
        token: TokenId,
    },
    /// A token left a flow node (completed it).
    Left {
        /// The node.
        node: NodeId,
        /// The token.
        token: TokenId,
    },
    /// A token was withdrawn from a node (interrupted or cancelled).
    Withdrawn {
        /// The node.
        node: NodeId,
        /// The token.
        token: TokenId,
    },
    /// A sequence flow was taken.
    Took {
        /// The flow.
        flow: FlowId,
    },
    /// A gateway (or conditional flows) chose outgoing flows, having read these variables.
    Decided {
        /// The deciding node.
        node: NodeId,
        /// The flows taken.
        flows: Vec<FlowId>,
        /// The variable values the conditions read.
        read: Vars,
    },
    /// A task was dispatched (to [`crate::resource`] of `node`, which the record's writer
    /// reads from the model).
    Dispatched {
        /// The attempt.
        task: TaskKey,
        /// The task element.
        node: NodeId,
        /// The goal.
        request: Vars,
    },
    /// A task completed.
    Completed {
        /// The attempt.
        task: TaskKey,
        /// Its result.
        output: Vars,
    },
    /// A task failed.
    Failed {
        /// The attempt.
        task: TaskKey,
        /// Error code.
        code: String,
        /// Reason.
        message: String,
    },
    /// A task was cancelled.
    Cancelled {
        /// The attempt.
        task: TaskKey,
    },
    /// A user task was opened.
    Opened {
        /// The user task.
        task: TaskKey,
        /// The element.
        node: NodeId,
    },
    /// A user task was answered.
    Answered {
        /// The user task.
        task: TaskKey,
        /// Who answered.
        operator: String,
        /// The answer.
        answer: Vars,
    },
    /// A timer was started.
    TimerStarted {
        /// The arming.
        timer: TimerKey,
        /// The catching node.
        node: NodeId,
        /// Deadline.
        due: Millis,
    },
    /// A timer fired.
    TimerFired {
        /// The arming.
        timer: TimerKey,
        /// The catching node.
        node: NodeId,
    },
    /// Something was thrown: a signal, message, error, escalation or compensation.
    Thrown {
        /// What kind.
        what: Trigger,
        /// The name or code (kept inline when short, as error codes and signal names are).
        name: CompactString,
        /// The throwing node, if any.
        node: Option<NodeId>,
    },
    /// A catching event or boundary caught something.
    Caught {
        /// What kind.
        what: Trigger,
        /// The name or code (kept inline when short).
        name: CompactString,
        /// The catching node.
        node: NodeId,
    },
    /// A token is stuck: no outgoing flow could be taken, an expression failed, and so on.
    Incident {
        /// Where.
        node: NodeId,
        /// Why.
        message: String,
    },
    /// A system data value changed (data used by conditions).
    Data {
        /// The key.
        key: String,
        /// The value.
        value: Value,
    },
}

/// The kinds of things thrown and caught.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Trigger {
    /// A message.
    Message,
    /// A signal.
    Signal,
    /// A BPMN error.
    Error,
    /// An escalation.
    Escalation,
    /// Compensation.
    Compensation,
    /// A timer.
    Timer,
    /// A condition that became true.
    Condition,
    /// A transaction cancel.
    Cancel,
}

/// Why an input was refused. The state is unchanged.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Rejected {
    /// The input's sequence number is not newer than the last accepted one.
    #[error("input {seq} is not newer than the last accepted input {last}")]
    Duplicate {
        /// The input's seq.
        seq: u64,
        /// The last accepted seq.
        last: u64,
    },
    /// The process id is not an executable process of the model.
    #[error("there is no executable process `{0}` in the model")]
    UnknownProcess(String),
    /// No instance has this id (or it ended).
    #[error("instance {0} does not exist or has ended")]
    UnknownInstance(u64),
    /// No task is waiting for this key: it finished, was cancelled, or the attempt is stale.
    #[error("no task is waiting for key {0} (finished, cancelled or a stale attempt)")]
    UnknownTask(TaskKey),
    /// The start element is not a start of that process.
    #[error("`{start}` is not a start event of process `{process}`")]
    UnknownStart {
        /// The process.
        process: String,
        /// The element id given.
        start: String,
    },
    /// No token waits at a gateway for this choice of branches.
    #[error("token {0:?} does not wait for these branches")]
    NotDeciding(TokenId),
    /// No subscription has this id.
    #[error("no subscription {0:?} is waiting")]
    UnknownWait(WaitId),
    /// No timer is armed with this key.
    #[error("no timer is armed with key {0}")]
    UnknownTimer(TimerKey),
    /// Nothing waits for this message and no process starts on it.
    #[error("nothing waits for message `{0}` and no process starts on it")]
    NoReceiver(String),
    /// A message sent along a message flow that its target cannot take now.
    #[error("message `{name}` along flow `{flow}`: {reason}")]
    Undeliverable {
        /// The message name.
        name: String,
        /// The message flow.
        flow: String,
        /// Why, naming the target.
        reason: String,
    },
    /// A message whose key was delivered before (a resend): nothing changes.
    #[error("message {0} was already delivered")]
    AlreadyDelivered(String),
    /// A user-task answer does not fit the task's form.
    #[error("answer to user task {task}: {reason}")]
    BadAnswer {
        /// The user task.
        task: TaskKey,
        /// What is wrong, naming the field.
        reason: String,
    },
    /// The model cannot be executed by this engine.
    #[error("`{element}` cannot be executed: {reason}")]
    Unsupported {
        /// The element id.
        element: String,
        /// Why.
        reason: String,
    },
}
