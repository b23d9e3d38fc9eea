//! The workloads the engine benches run: each service task bound once to the operation the peer
//! harness gives it (`noop`, `inc`, `fail`), and one instance run to its end with tasks completing
//! at once. Shared by `steps` (the rate) and `allocs` (allocations per instance).

use std::collections::{BTreeMap, VecDeque};

use executive_engine::{Action, Engine, Entry, Event, Input, Value, Vars};

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

/// The service operation of each node, bound once before running (as the peers bind their
/// service functions once).
pub(crate) fn bind(
    g: &executive_model::ProcessGraph,
    ops: &BTreeMap<String, String>,
) -> Vec<&'static str> {
    g.nodes
        .iter()
        .map(|n| match ops.get(&n.id).map(String::as_str) {
            Some("fail") => "fail",
            Some("inc") => "inc",
            _ => "noop",
        })
        .collect()
}

/// Runs one instance to its end; returns the completed flow nodes (if counted).
pub(crate) fn instance(
    e: &mut Engine,
    seq: &mut u64,
    process: &str,
    ops: &[&'static str],
) -> usize {
    let mut queue = VecDeque::from([Event::InstanceStarted {
        process: process.to_owned(),
        vars: Vars::new(),
        start: None,
    }]);
    let mut completed = 0;
    while let Some(event) = queue.pop_front() {
        *seq += 1;
        let actions = e
            .step(Input {
                seq: *seq,
                at: 0,
                event,
            })
            .expect("accepted");
        for a in actions {
            match a {
                Action::DispatchTask {
                    task,
                    node,
                    request,
                    ..
                } => {
                    queue.push_back(match ops[node.index()] {
                        "fail" => Event::TaskFailed {
                            task,
                            code: "SVC_FAIL".into(),
                            message: String::new(),
                        },
                        "inc" => {
                            let count = match request.get("count") {
                                Some(Value::Int(c)) => *c,
                                _ => 0,
                            };
                            Event::TaskCompleted {
                                task,
                                output: [("count".to_owned(), Value::Int(count + 1))].into(),
                            }
                        }
                        _ => Event::TaskCompleted {
                            task,
                            output: Vars::new(),
                        },
                    });
                }
                Action::Record(r) if matches!(r.entry, Entry::Left { .. }) => completed += 1,
                _ => {}
            }
        }
    }
    completed
}
