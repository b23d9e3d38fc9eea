//! The workloads the engine benches run: each service task bound once to the operation the peer
//! harness gives it (`noop`, `inc`, `fail`), and one instance run to its end with tasks completing
//! at once. Shared by `steps` (the rate) and `allocs` (allocations per instance).

use std::collections::{BTreeMap, VecDeque};

use executive_engine::{Action, Engine, Entry, Event, Input, TaskKey, Value, Vars};

/// Service operation of each service task, from `implementation="${environment.services.op}"`.
pub(crate) fn operations(xml: &str) -> BTreeMap<String, String> {
    let mut ops = BTreeMap::new();
    for part in xml.split("<bpmn:serviceTask ").skip(1) {
        let tag = part.split('>').next().unwrap_or("");
        let id = tag.split("id=\"").nth(1).and_then(|r| r.split('"').next());
        let op = tag
            .split("environment.services.")
            .nth(1)
            .and_then(|r| r.split('}').next());
        if let (Some(id), Some(op)) = (id, op) {
            ops.insert(id.to_owned(), op.to_owned());
        }
    }
    ops
}

/// A service operation of the peer harness.
#[derive(Clone, Copy)]
pub(crate) enum Op {
    /// Completes with no output.
    Noop,
    /// Completes with the goal's `count` plus one.
    Inc,
    /// Fails with `SVC_FAIL`.
    Fail,
}

/// The service operation of each node, bound once before running (as the peers bind their
/// service functions once).
pub(crate) fn bind(g: &executive_model::ProcessGraph, ops: &BTreeMap<String, String>) -> Vec<Op> {
    g.nodes
        .iter()
        .map(|n| match ops.get(&n.id).map(String::as_str) {
            Some("fail") => Op::Fail,
            Some("inc") => Op::Inc,
            _ => Op::Noop,
        })
        .collect()
}

/// What a task's connector answers: the harness's queue holds these, small and plain, and
/// makes each event only as it is stepped.
#[derive(Clone, Copy)]
enum Reply {
    /// The instance starts.
    Start,
    /// The task fails with `SVC_FAIL`.
    Fail(TaskKey),
    /// The task completes; `inc` returns the goal's count plus one.
    Complete(TaskKey, Option<i64>),
}

/// The queue of replies and the buffer of actions, kept from one instance to the next (as a
/// driver keeps its own).
#[derive(Default)]
pub(crate) struct Buffers {
    queue: VecDeque<Reply>,
    actions: Vec<Action>,
}

/// Runs one instance to its end; returns the completed flow nodes (if counted).
pub(crate) fn instance(
    e: &mut Engine,
    seq: &mut u64,
    process: &str,
    ops: &[Op],
    b: &mut Buffers,
) -> usize {
    let Buffers { queue, actions } = b;
    queue.push_back(Reply::Start);
    let mut completed = 0;
    while let Some(reply) = queue.pop_front() {
        *seq += 1;
        let event = match reply {
            Reply::Start => Event::InstanceStarted {
                process: process.to_owned(),
                vars: Vars::new(),
                start: None,
            },
            Reply::Fail(task) => Event::TaskFailed {
                task,
                code: "SVC_FAIL".into(),
                message: String::new(),
            },
            Reply::Complete(task, count) => Event::TaskCompleted {
                task,
                output: count
                    .map(|c| [("count".to_owned(), Value::Int(c))].into())
                    .unwrap_or_default(),
            },
        };
        e.step_into(
            Input {
                seq: *seq,
                at: 0,
                event,
            },
            actions,
        )
        .expect("accepted");
        // Read in place, then dropped in place (as a driver writes each action to its store).
        for a in actions.iter() {
            match a {
                Action::DispatchTask {
                    task,
                    node,
                    request,
                    ..
                } => queue.push_back(match ops[node.index()] {
                    Op::Fail => Reply::Fail(*task),
                    Op::Inc => {
                        let count = match request.get("count") {
                            Some(Value::Int(c)) => *c,
                            _ => 0,
                        };
                        Reply::Complete(*task, Some(count + 1))
                    }
                    Op::Noop => Reply::Complete(*task, None),
                }),
                Action::Record(r) if matches!(r.entry, Entry::Left { .. }) => completed += 1,
                _ => {}
            }
        }
        actions.clear();
    }
    completed
}
