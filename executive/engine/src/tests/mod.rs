//! Element-level snapshot tests: small inline models, an input script, the expected actions.

use std::sync::Arc;

use crate::{Action, Engine, Entry, Event, Input, Outcome, Rejected, State, TaskKey, Value, Vars};

// One module per construct whose rule docs/engine-semantics.md writes down from chapter 13 of
// BPMN 2.0.2, including combinations no corpus has.
mod conditional_events;
mod cycles;
mod data;
mod event_subprocesses;
mod feel;
mod fleet;
mod message_flows;
mod signals;
mod transactions;
mod waves;

const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL"
  xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0"
  xmlns:camunda="http://camunda.org/schema/1.0/bpmn" xmlns:zeebe="http://camunda.org/schema/zeebe/1.0"
  id="d" targetNamespace="urn:test">"#;

fn engine(body: &str) -> Engine {
    let xml = format!("{HEAD}{body}</definitions>");
    let loaded = executive_model::load(xml.as_bytes());
    let graph = loaded
        .graph
        .unwrap_or_else(|| panic!("{:#?}", loaded.diagnostics));
    Engine::new(Arc::new(graph))
}

/// The actions of the first input an engine takes: process `p` started, without variables.
fn first_start(e: &mut Engine) -> Vec<Action> {
    e.step(Input {
        seq: 1,
        at: 0,
        event: Event::InstanceStarted {
            process: "p".into(),
            vars: Vars::new(),
            start: None,
        },
    })
    .expect("starts")
}

/// Drives an engine and renders its actions compactly: `dispatch <node>`, `timer <ms>`, ….
struct Driver {
    e: Engine,
    seq: u64,
    now: i64,
    tasks: Vec<(String, TaskKey)>,
    timers: Vec<crate::TimerKey>,
    user: Vec<(String, TaskKey)>,
}

impl Driver {
    fn new(body: &str) -> Driver {
        Driver {
            e: engine(body),
            seq: 0,
            now: 0,
            tasks: Vec::new(),
            timers: Vec::new(),
            user: Vec::new(),
        }
    }

    fn step(&mut self, event: Event) -> Result<Vec<String>, Rejected> {
        self.seq += 1;
        let actions = self.e.step(Input {
            seq: self.seq,
            at: self.now,
            event,
        })?;
        let g = Arc::clone(self.e.graph());
        let id = |n: executive_model::NodeId| g.node(n).id.clone();
        let mut out = Vec::new();
        for a in actions {
            match a {
                Action::DispatchTask { task, node, .. } => {
                    out.push(format!("dispatch {}", id(node)));
                    self.tasks.push((id(node), task));
                }
                Action::CancelTask { task } => {
                    let n = self
                        .tasks
                        .iter()
                        .find(|(_, k)| *k == task)
                        .map(|(n, _)| n.clone());
                    out.push(format!("cancel {}", n.unwrap_or_default()));
                }
                Action::OpenUserTask { task, node, .. } => {
                    out.push(format!("open {}", id(node)));
                    self.user.push((id(node), task));
                }
                Action::CloseUserTask { .. } => out.push("close".to_owned()),
                Action::StartTimer { timer, at } => {
                    out.push(format!("timer {}", at - self.now));
                    self.timers.push(timer);
                }
                Action::CancelTimer { .. } => out.push("untimer".to_owned()),
                Action::SendMessage(m) => out.push(format!("send {}", m.name)),
                Action::InstanceFinished { outcome, .. } => out.push(match outcome {
                    Outcome::Failed { code, .. } => format!("failed {code}"),
                    o => format!("{o:?}").to_lowercase(),
                }),
                Action::Record(r) => {
                    if let Entry::Incident { message, .. } = r.entry {
                        out.push(format!("incident {message}"));
                    }
                }
            }
        }
        Ok(out)
    }

    fn start(&mut self, vars: &[(&str, Value)]) -> Vec<String> {
        let vars: Vars = vars
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect();
        self.step(Event::InstanceStarted {
            process: "p".into(),
            vars,
            start: None,
        })
        .expect("starts")
    }

    fn key(&self, node: &str) -> TaskKey {
        self.tasks
            .iter()
            .rev()
            .find(|(n, _)| n == node)
            .map(|(_, k)| *k)
            .unwrap_or_else(|| panic!("no task {node}"))
    }

    fn complete(&mut self, node: &str, output: &[(&str, Value)]) -> Vec<String> {
        let task = self.key(node);
        let output = output
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect();
        self.step(Event::TaskCompleted { task, output })
            .expect("accepted")
    }

    fn fail(&mut self, node: &str, code: &str) -> Vec<String> {
        let task = self.key(node);
        self.step(Event::TaskFailed {
            task,
            code: code.into(),
            message: String::new(),
        })
        .expect("accepted")
    }

    fn fire(&mut self, i: usize, after: i64) -> Vec<String> {
        self.now += after;
        let timer = self.timers[i];
        self.step(Event::TimerFired { timer }).expect("accepted")
    }
}

/// A service task; `_incoming` / `_outgoing` name its flows for the reader (the flows
/// themselves carry the references).
fn task(id: &str, _incoming: &str, _outgoing: &str) -> String {
    format!(
        r#"<serviceTask id="{id}"><extensionElements><trace:task resource="sys.{id}"/></extensionElements></serviceTask>"#
    )
}

fn flow(id: &str, from: &str, to: &str) -> String {
    format!(r#"<sequenceFlow id="{id}" sourceRef="{from}" targetRef="{to}"/>"#)
}

fn cond_flow(id: &str, from: &str, to: &str, cond: &str) -> String {
    format!(
        r#"<sequenceFlow id="{id}" sourceRef="{from}" targetRef="{to}"><conditionExpression xsi:type="tFormalExpression">{cond}</conditionExpression></sequenceFlow>"#
    )
}

// Helpers shared by the construct modules.

/// Sequence flows along `nodes`, from each node to the next, named `{prefix}0`, `{prefix}1`, ….
fn path(prefix: &str, nodes: &[&str]) -> String {
    nodes
        .windows(2)
        .enumerate()
        .map(|(i, w)| flow(&format!("{prefix}{i}"), w[0], w[1]))
        .collect()
}

/// A start `s`, sequence flows through `nodes` (declared by the caller), an end `e`.
fn chain(nodes: &[&str]) -> String {
    let all = [&["s"], nodes, &["e"]].concat();
    format!(
        r#"<startEvent id="s"/>{}<endEvent id="e"/>"#,
        path("f", &all)
    )
}

/// A start `s` and a parallel fork `fork` into `branches`: branch `k` (from 1) flows from
/// `fork` through its nodes (declared by the caller) to its own end `e{k}`.
fn fork_into(branches: &[&[&str]]) -> String {
    let mut out = format!(
        r#"<startEvent id="s"/>{}{}"#,
        flow("f0", "s", "fork"),
        parallel("fork")
    );
    for (k, nodes) in branches.iter().enumerate() {
        let end = format!("e{}", k + 1);
        let all = [&["fork"], *nodes, &[end.as_str()]].concat();
        out.push_str(&path(&format!("b{}_", k + 1), &all));
        out.push_str(&ends(&[&end]));
    }
    out
}

/// Service tasks (see `task`), one per id.
fn tasks(ids: &[&str]) -> String {
    ids.iter().map(|id| task(id, "", "")).collect()
}

/// None end events, one per id.
fn ends(ids: &[&str]) -> String {
    ids.iter()
        .map(|id| format!(r#"<endEvent id="{id}"/>"#))
        .collect()
}

fn parallel(id: &str) -> String {
    format!(r#"<parallelGateway id="{id}"/>"#)
}

/// A timer event definition due `duration` (ISO 8601) after it starts waiting.
fn duration(duration: &str) -> String {
    format!(
        r#"<timerEventDefinition><timeDuration xsi:type="tFormalExpression">{duration}</timeDuration></timerEventDefinition>"#
    )
}

fn vars(pairs: &[(&str, Value)]) -> Vars {
    pairs
        .iter()
        .map(|(k, v)| ((*k).to_owned(), v.clone()))
        .collect()
}

/// No action.
fn none() -> Vec<String> {
    Vec::new()
}

/// Actions whose order the rule does not fix, sorted.
fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

impl Driver {
    fn signal(&mut self, name: &str) -> Vec<String> {
        self.step(Event::SignalReceived { name: name.into() })
            .expect("a signal is always accepted")
    }

    fn message(
        &mut self,
        name: &str,
        correlation: Option<Value>,
        payload: &[(&str, Value)],
    ) -> Result<Vec<String>, Rejected> {
        self.step(Event::MessageReceived {
            name: name.into(),
            correlation,
            payload: vars(payload),
            flow: None,
            key: None,
        })
    }

    /// System data `key` changes to `value`.
    fn data(&mut self, key: &str, value: Value) -> Vec<String> {
        self.step(Event::DataChanged {
            key: key.into(),
            value,
        })
        .expect("accepted")
    }

    /// Every task key dispatched for `node`, oldest first.
    fn keys_of(&self, node: &str) -> Vec<TaskKey> {
        self.tasks
            .iter()
            .filter(|(n, _)| n == node)
            .map(|(_, k)| *k)
            .collect()
    }

    fn try_complete_key(
        &mut self,
        task: TaskKey,
        output: &[(&str, Value)],
    ) -> Result<Vec<String>, Rejected> {
        self.step(Event::TaskCompleted {
            task,
            output: vars(output),
        })
    }

    /// Completes one task by its key.
    fn complete_key(&mut self, task: TaskKey, output: &[(&str, Value)]) -> Vec<String> {
        self.try_complete_key(task, output).expect("accepted")
    }

    /// Completes the `i`-th dispatched task (dispatch order), whatever its node.
    fn complete_nth(&mut self, i: usize, output: &[(&str, Value)]) -> Vec<String> {
        self.complete_key(self.tasks[i].1, output)
    }

    /// Completes every task dispatched for `node`, oldest first; the actions of each.
    fn complete_every(&mut self, node: &str) -> Vec<Vec<String>> {
        self.keys_of(node)
            .into_iter()
            .map(|k| self.complete_key(k, &[]))
            .collect()
    }

    /// The goal of the latest dispatch of `node` (while it runs).
    fn request(&self, node: &str) -> Vars {
        let key = self.key(node);
        let given = self.e.in_flight().into_iter().find_map(|a| match a {
            Action::DispatchTask { task, request, .. } if task == key => Some(request),
            _ => None,
        });
        given.unwrap_or_else(|| panic!("{node} is not dispatched"))
    }

    /// The `i`-th timer fires (again) without time passing.
    fn try_fire(&mut self, i: usize) -> Result<Vec<String>, Rejected> {
        let timer = self.timers[i];
        self.step(Event::TimerFired { timer })
    }
}

#[test]
fn sequence_of_tasks_runs_in_order() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}{}{}{}<endEvent id="e"/>{}</process>"#,
        flow("f1", "s", "a"),
        task("a", "f1", "f2"),
        flow("f2", "a", "b"),
        task("b", "f2", "f3"),
        flow("f3", "b", "e"),
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

#[test]
fn exclusive_gateway_takes_first_true_then_default_then_incident() {
    let body = format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<exclusiveGateway id="g" default="fd"/>{}{}{}{}{}<endEvent id="e"/>{}{}</process>"#,
        flow("f0", "s", "g"),
        cond_flow("f1", "g", "a", "x &gt; 1"),
        cond_flow("f2", "g", "b", "x &gt; 0"),
        flow("fd", "g", "e"),
        task("a", "f1", "fa"),
        task("b", "f2", "fb"),
        flow("fa", "a", "e"),
        flow("fb", "b", "e"),
    );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x", Value::Int(5))]), ["dispatch a"]);
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x", Value::Int(1))]), ["dispatch b"]);
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x", Value::Int(0))]), ["completed"]);
    // A condition over a missing variable is an incident on the token, not a crash.
    let mut d = Driver::new(&body);
    let out = d.start(&[]);
    assert!(out[0].starts_with("incident"), "{out:?}");
}

#[test]
fn parallel_join_waits_for_every_branch() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}<parallelGateway id="join"/>{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "fork"),
        flow("f1", "fork", "a"),
        flow("f2", "fork", "b"),
        task("a", "f1", "f3"),
        task("b", "f2", "f4"),
        flow("f3", "a", "join"),
        flow("f4", "b", "join"),
        flow("f5", "join", "e"),
    ));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch b"]);
    assert_eq!(d.complete("b", &[]), Vec::<String>::new());
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

#[test]
fn inclusive_join_waits_only_for_tokens_that_can_still_arrive() {
    let body = format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<inclusiveGateway id="fork"/>{}{}{}{}{}{}<inclusiveGateway id="join"/>{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "fork"),
        cond_flow("f1", "fork", "a", "x &gt; 0"),
        cond_flow("f2", "fork", "b", "x &gt; 1"),
        task("a", "f1", "f3"),
        task("b", "f2", "f4"),
        flow("f3", "a", "join"),
        flow("f4", "b", "join"),
        flow("f5", "join", "e"),
    );
    // One branch taken: the join fires without waiting for the other.
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x", Value::Int(1))]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed"]);
    // Both taken: it waits for both.
    let mut d = Driver::new(&body);
    assert_eq!(
        d.start(&[("x", Value::Int(2))]),
        ["dispatch a", "dispatch b"]
    );
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

#[test]
fn a_wide_inclusive_join_fires_once_when_its_last_taken_branch_arrives() {
    // 300 branches, the first 200 taken: every arrival asks whether a token may still come
    // (once per join and step, not once per waiting token).
    let mut body = format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<inclusiveGateway id="fork"/><inclusiveGateway id="join"/>{}<endEvent id="e"/>"#,
        flow("f0", "s", "fork"),
        flow("fz", "join", "e"),
    );
    for i in 0..300 {
        body += &cond_flow(
            &format!("x{i}"),
            "fork",
            &format!("t{i}"),
            &format!("n &gt; {i}"),
        );
        body += &task(&format!("t{i}"), "", "");
        body += &flow(&format!("y{i}"), &format!("t{i}"), "join");
    }
    body += "</process>";
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("n", Value::Int(200))]).len(), 200);
    for i in (1..200).rev() {
        assert_eq!(d.complete(&format!("t{i}"), &[]), Vec::<String>::new());
    }
    assert_eq!(d.complete("t0", &[]), ["completed"]);
}

#[test]
fn error_boundary_catches_a_task_failure_by_code() {
    let mut d = Driver::new(&format!(
        r#"<error id="stuck" errorCode="TOOL_STUCK"/><process id="p" isExecutable="true"><startEvent id="s"/>{}{}
        <boundaryEvent id="b" attachedToRef="a"><errorEventDefinition errorRef="stuck" trace:errorCodeVariable="fault"/></boundaryEvent>
        {}{}{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "a"),
        task("a", "f0", "f1"),
        flow("fb", "b", "u"),
        task("u", "fb", "f2"),
        flow("f2", "u", "e"),
        flow("f1", "a", "e"),
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.fail("a", "TOOL_STUCK"), ["dispatch u"]);
    let vars = &d.e.state().scopes.values().next().expect("root").vars;
    assert_eq!(vars.get("fault"), Some(&Value::from("TOOL_STUCK")));
    assert_eq!(d.complete("u", &[]), ["completed"]);
}

#[test]
fn uncaught_error_fails_the_instance_and_cancels_the_rest() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "fork"),
        flow("f1", "fork", "a"),
        flow("f2", "fork", "b"),
        task("a", "f1", "f3"),
        task("b", "f2", "f4"),
        flow("f3", "a", "e"),
        flow("f4", "b", "e"),
    ));
    d.start(&[]);
    assert_eq!(d.fail("a", "BOOM"), ["cancel b", "failed BOOM"]);
    // The cancelled task's late result is refused: its key is fenced.
    let late = d.key("b");
    let r = d.step(Event::TaskCompleted {
        task: late,
        output: Vars::new(),
    });
    assert!(matches!(r, Err(Rejected::UnknownTask(_))), "{r:?}");
}

#[test]
fn interrupting_timer_boundary_cancels_the_task() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}{}
        <boundaryEvent id="t" attachedToRef="a"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT6H</timeDuration></timerEventDefinition></boundaryEvent>
        {}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "a"),
        task("a", "f0", "f1"),
        flow("ft", "t", "e"),
        flow("f1", "a", "e"),
    ));
    assert_eq!(d.start(&[]), ["timer 21600000", "dispatch a"]);
    assert_eq!(d.fire(0, 21_600_000), ["cancel a", "completed"]);
}

#[test]
fn user_task_answers_are_type_checked_and_bad_ones_change_nothing() {
    let mut d = Driver::new(
        r#"<process id="p" isExecutable="true"><startEvent id="s"><outgoing>f0</outgoing></startEvent>
        <userTask id="u"><extensionElements><trace:task resource="ground.approve">
          <trace:output source="approved" target="approved" type="bool"/></trace:task></extensionElements>
          <incoming>f0</incoming><outgoing>f1</outgoing></userTask>
        <endEvent id="e"><incoming>f1</incoming></endEvent>
        <sequenceFlow id="f0" sourceRef="s" targetRef="u"/><sequenceFlow id="f1" sourceRef="u" targetRef="e"/></process>"#,
    );
    assert_eq!(d.start(&[]), ["open u"]);
    let task = d.user[0].1;
    let before = d.e.state().clone();
    let wrong = [("approved", Value::from("yes"))];
    let r = d.step(Event::UserTaskAnswered {
        task,
        answer: wrong
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect(),
        operator: "ops".into(),
    });
    assert!(
        matches!(&r, Err(Rejected::BadAnswer { reason, .. }) if reason.contains("approved") && reason.contains("bool")),
        "{r:?}"
    );
    assert_eq!(d.e.state(), &before);
    let r = d.step(Event::UserTaskAnswered {
        task,
        answer: [("approved".to_owned(), Value::Bool(true))].into(),
        operator: "ops".into(),
    });
    assert_eq!(r.expect("accepted"), ["close", "completed"]);
}

#[test]
fn duplicate_and_old_inputs_are_refused() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "a"),
        task("a", "f0", "f1"),
        flow("f1", "a", "e"),
    ));
    d.start(&[]);
    let r = d.e.step(Input {
        seq: 1,
        at: 0,
        event: Event::SignalReceived { name: "x".into() },
    });
    assert!(
        matches!(r, Err(Rejected::Duplicate { seq: 1, last: 1 })),
        "{r:?}"
    );
}

#[test]
fn multi_instance_parallel_over_a_collection_collects_outputs() {
    let mut d = Driver::new(
        r#"<process id="p" isExecutable="true"><startEvent id="s"><outgoing>f0</outgoing></startEvent>
        <serviceTask id="a"><extensionElements><trace:task resource="sys.a"/></extensionElements>
          <incoming>f0</incoming><outgoing>f1</outgoing>
          <multiInstanceLoopCharacteristics camunda:collection="sites" camunda:elementVariable="site"/></serviceTask>
        <endEvent id="e"><incoming>f1</incoming></endEvent>
        <sequenceFlow id="f0" sourceRef="s" targetRef="a"/><sequenceFlow id="f1" sourceRef="a" targetRef="e"/></process>"#,
    );
    let sites = Value::List(vec![Value::Int(7), Value::Int(8), Value::Int(9)]);
    assert_eq!(
        d.start(&[("sites", sites)]),
        ["dispatch a", "dispatch a", "dispatch a"]
    );
    let keys: Vec<TaskKey> = d.tasks.iter().map(|(_, k)| *k).collect();
    for (i, k) in keys.iter().enumerate() {
        let out = d
            .step(Event::TaskCompleted {
                task: *k,
                output: Vars::new(),
            })
            .expect("accepted");
        assert_eq!(out.is_empty(), i < 2, "{out:?}");
    }
}

#[test]
fn signals_reach_every_waiting_instance() {
    let body = r#"<signal id="sig" name="BATTERY_LOW"/><process id="p" isExecutable="true">
        <startEvent id="s"><outgoing>f0</outgoing></startEvent>
        <intermediateCatchEvent id="c"><incoming>f0</incoming><outgoing>f1</outgoing><signalEventDefinition signalRef="sig"/></intermediateCatchEvent>
        <endEvent id="e"><incoming>f1</incoming></endEvent>
        <sequenceFlow id="f0" sourceRef="s" targetRef="c"/><sequenceFlow id="f1" sourceRef="c" targetRef="e"/></process>"#;
    let mut d = Driver::new(body);
    d.start(&[]);
    d.start(&[]);
    let out = d
        .step(Event::SignalReceived {
            name: "BATTERY_LOW".into(),
        })
        .expect("accepted");
    assert_eq!(out, ["completed", "completed"]);
}

#[test]
fn message_events_implemented_by_a_job_worker_run_as_tasks() {
    // Camunda 8 implements a message throw or end event with a job worker: the event is a task.
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <intermediateThrowEvent id="notify"><extensionElements><zeebe:taskDefinition type="notify"/></extensionElements><messageEventDefinition/></intermediateThrowEvent>
        <endEvent id="report"><extensionElements><zeebe:taskDefinition type="report"/></extensionElements><messageEventDefinition/></endEvent>
        {}{}</process>"#,
        flow("f1", "s", "notify"),
        flow("f2", "notify", "report"),
    ));
    assert_eq!(d.start(&[]), ["dispatch notify"]);
    assert_eq!(d.complete("notify", &[]), ["dispatch report"]);
    // The end event's token ends once its job is done.
    assert_eq!(d.complete("report", &[]), ["completed"]);
}

#[test]
fn conditional_event_fires_when_system_data_changes() {
    let mut d = Driver::new(
        r#"<process id="p" isExecutable="true"><startEvent id="s"><outgoing>f0</outgoing></startEvent>
        <intermediateCatchEvent id="c"><incoming>f0</incoming><outgoing>f1</outgoing>
          <conditionalEventDefinition><condition xsi:type="tFormalExpression">heater_temp_c &gt; -20.0</condition></conditionalEventDefinition></intermediateCatchEvent>
        <endEvent id="e"><incoming>f1</incoming></endEvent>
        <sequenceFlow id="f0" sourceRef="s" targetRef="c"/><sequenceFlow id="f1" sourceRef="c" targetRef="e"/></process>"#,
    );
    let data = |v: f64| Event::DataChanged {
        key: "heater_temp_c".into(),
        value: Value::from(v),
    };
    assert_eq!(d.step(data(-80.0)).expect("ok"), Vec::<String>::new());
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.step(data(-40.0)).expect("ok"), Vec::<String>::new());
    assert_eq!(d.step(data(-10.0)).expect("ok"), ["completed"]);
}

#[test]
fn terminate_end_event_withdraws_everything() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}<endEvent id="t"><terminateEventDefinition/></endEvent>{}{}</process>"#,
        flow("f0", "s", "fork"),
        flow("f1", "fork", "a"),
        flow("f2", "fork", "b"),
        task("a", "f1", "f3"),
        flow("f3", "a", "t"),
        task("b", "f2", "f4"),
    ) .replace("</process>", r#"<endEvent id="e"/><sequenceFlow id="f4" sourceRef="b" targetRef="e"/></process>"#));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["cancel b", "terminated"]);
}

/// A start, `n` service tasks, an end.
fn sequence(n: usize) -> String {
    let mut body = String::from(r#"<process id="p" isExecutable="true"><startEvent id="s"/>"#);
    let mut prev = "s".to_owned();
    for i in 0..n {
        body.push_str(&task(&format!("t{i}"), "", ""));
        body.push_str(&flow(&format!("f{i}"), &prev, &format!("t{i}")));
        prev = format!("t{i}");
    }
    body.push_str(&format!(
        r#"<endEvent id="e"/>{}</process>"#,
        flow("fe", &prev, "e")
    ));
    body
}

#[test]
fn long_paths_run_with_a_flat_stack_and_flat_memory() {
    // A small stack proves that neither loading nor stepping recurses along the path.
    let run = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(|| {
            let mut d = Driver::new(&sequence(100_000));
            d.start(&[]);
            let mut steps = 0;
            while let Some((_, task)) = d.tasks.pop() {
                let out = d
                    .step(Event::TaskCompleted {
                        task,
                        output: Vars::new(),
                    })
                    .expect("accepted");
                steps += 1;
                // Memory stays flat: one token, one scope, whatever the position.
                assert!(d.e.state().tokens.len() <= 1 && d.e.state().scopes.len() <= 1);
                if out == ["completed"] {
                    break;
                }
            }
            steps
        })
        .expect("thread");
    assert_eq!(run.join().expect("no stack overflow"), 100_000);
}

#[test]
fn a_hundred_thousand_iteration_loop_completes() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<exclusiveGateway id="m"/>{}
        <scriptTask id="inc" scriptFormat="cel"><script>n = n + 1</script></scriptTask>{}
        <exclusiveGateway id="x" default="out"/>{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "m"),
        flow("f1", "m", "inc"),
        flow("f2", "inc", "x"),
        cond_flow("back", "x", "m", "n &lt; 100000"),
        flow("out", "x", "e"),
    ));
    assert_eq!(d.start(&[("n", Value::Int(0))]), ["completed"]);
}

#[test]
fn a_state_is_checked_against_the_model_before_it_is_resumed() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}{}<endEvent id="e"/>{}</process>"#,
        flow("f1", "s", "a"),
        task("a", "f1", "f2"),
        flow("f2", "a", "e"),
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    let graph = Arc::clone(d.e.graph());
    let good = d.e.state().clone();
    assert_eq!(good.check(&graph), Ok(()));
    let damaged = |f: &dyn Fn(&mut State)| {
        let mut s = good.clone();
        f(&mut s);
        s.check(&graph).expect_err("damage is found")
    };
    let why = damaged(&|s| s.tokens.values_mut().for_each(|t| t.node.0 = 999));
    assert!(why.contains("names element #999 of"), "{why}");
    let why = damaged(&|s| s.tokens.values_mut().for_each(|t| t.scope.0 = 77));
    assert!(why.contains("names scope 77 which is not held"), "{why}");
    let why = damaged(&|s| s.instances.values_mut().for_each(|i| i.process.0 = 5));
    assert!(why.contains("names process #5 of 1"), "{why}");
    let why = damaged(&|s| s.scopes.clear());
    assert!(why.contains("which is not held"), "{why}");
}

#[test]
fn a_parallel_multi_instance_beyond_the_bound_is_an_incident_and_a_sequential_one_runs() {
    let model = |sequential: bool| {
        format!(
            r#"<process id="p" isExecutable="true"><startEvent id="s"><outgoing>f0</outgoing></startEvent>
        <serviceTask id="a"><extensionElements><trace:task resource="sys.a"/></extensionElements>
          <incoming>f0</incoming><outgoing>f1</outgoing>
          <multiInstanceLoopCharacteristics isSequential="{sequential}"><loopCardinality>n</loopCardinality></multiInstanceLoopCharacteristics></serviceTask>
        <endEvent id="e"><incoming>f1</incoming></endEvent>
        <sequenceFlow id="f0" sourceRef="s" targetRef="a"/><sequenceFlow id="f1" sourceRef="a" targetRef="e"/></process>"#
        )
    };
    let huge = Value::Int(1_000_000_000_000);
    let out = Driver::new(&model(false)).start(&[("n", huge.clone())]);
    assert_eq!(out.len(), 1, "{out:?}");
    assert!(
        out[0].starts_with("incident 1000000000000 parallel instances are more than the 10000"),
        "{out:?}"
    );
    assert_eq!(
        Driver::new(&model(true)).start(&[("n", huge)]),
        ["dispatch a"]
    );
    let at_bound = Driver::new(&model(false)).start(&[("n", Value::Int(10_000))]);
    assert_eq!(at_bound.len(), 10_000);
}

/// After a restart the engine commands again what it commanded, from its state alone: the
/// same key, resource and goal (a call activity's, its global task's). A state saved before
/// tokens kept only the goal (they kept the whole command) gives the same commands.
#[test]
fn a_restored_state_gives_its_commands_again_even_from_an_older_snapshot() {
    let body = format!(
        r#"<globalBusinessRuleTask id="g"><extensionElements><trace:task resource="sys.rule"/></extensionElements></globalBusinessRuleTask>
        <process id="p" isExecutable="true"><startEvent id="s"/>{fork}
        <callActivity id="c" calledElement="g"/>
        <serviceTask id="a"><extensionElements><trace:task resource="sys.a"><trace:input target="n" source="n"/></trace:task></extensionElements></serviceTask>
        <serviceTask id="b" camunda:type="external" camunda:topic="lab.b"/>
        <userTask id="u"/>
        {ends}{f1}{f2}{f3}{f4}{f5}{f6}{f7}{f8}{f9}</process>"#,
        fork = parallel("fork"),
        ends = ends(&["ea", "eb", "eu", "ec"]),
        f8 = flow("f8", "fork", "c"),
        f9 = flow("f9", "c", "ec"),
        f5 = flow("f5", "a", "ea"),
        f6 = flow("f6", "b", "eb"),
        f7 = flow("f7", "u", "eu"),
        f1 = flow("f1", "s", "fork"),
        f2 = flow("f2", "fork", "a"),
        f3 = flow("f3", "fork", "b"),
        f4 = flow("f4", "fork", "u"),
    );
    let mut d = Driver::new(&body);
    let given: Vec<Action> =
        d.e.step(Input {
            seq: 1,
            at: 0,
            event: Event::InstanceStarted {
                process: "p".into(),
                vars: vars(&[("n", Value::Int(7))]),
                start: None,
            },
        })
        .expect("starts")
        .into_iter()
        .filter(|a| matches!(a, Action::DispatchTask { .. } | Action::OpenUserTask { .. }))
        .collect();
    assert_eq!(given.len(), 4, "{given:#?}");
    assert!(
        given.iter().any(
            |a| matches!(a, Action::DispatchTask { node, .. } if crate::resource(d.e.graph(), *node) == "sys.rule")
        ),
        "{given:#?}"
    );
    assert_eq!(d.e.in_flight(), given);
    let graph = Arc::clone(d.e.graph());
    let saved = serde_json::to_value(d.e.state()).expect("serializes");
    let restored: State = serde_json::from_value(saved.clone()).expect("deserializes");
    assert_eq!(
        Engine::restore(Arc::clone(&graph), restored).in_flight(),
        given
    );
    // The older form: each token held its whole command, and no goal.
    let mut older = saved;
    let mut commands = 0;
    for token in older["tokens"]
        .as_object_mut()
        .expect("tokens")
        .values_mut()
    {
        let token = token.as_object_mut().expect("a token");
        token.remove("goal");
        // `at` is `{"Task": key}` or `{"UserTask": key}` for a token with a command.
        let key = match &token["at"] {
            serde_json::Value::Object(at) => at.values().next().cloned(),
            _ => None,
        };
        let command = given.iter().find(|a| {
            matches!(a, Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. }
                if serde_json::to_value(task).ok() == key)
        });
        if let Some(c) = command {
            let mut c = serde_json::to_value(c).expect("serializes");
            // An older dispatch named its resource too.
            if let Action::DispatchTask { node, .. } =
                serde_json::from_value(c.clone()).expect("reads")
            {
                c["resource"] = crate::resource(&graph, node).into();
            }
            token.insert("command".into(), c);
            commands += 1;
        }
    }
    assert_eq!(commands, 4);
    let older: State = serde_json::from_value(older).expect("an older snapshot deserializes");
    assert_eq!(
        Engine::restore(Arc::clone(&graph), older).in_flight(),
        given
    );
}

#[test]
fn an_older_dispatch_and_its_record_entry_naming_their_resource_are_read() {
    let mut e = engine(&format!(
        r#"<process id="p" isExecutable="true">{}{}</process>"#,
        tasks(&["a"]),
        chain(&["a"])
    ));
    let actions = first_start(&mut e);
    let mut seen = 0;
    for a in &actions {
        let mut json = serde_json::to_value(a).expect("serializes");
        match a {
            Action::DispatchTask { .. } => json["resource"] = "sys.a".into(),
            Action::Record(r) if matches!(r.entry, Entry::Dispatched { .. }) => {
                json["entry"]["resource"] = "sys.a".into();
            }
            _ => continue,
        }
        seen += 1;
        let back: Action = serde_json::from_value(json).expect("an older action deserializes");
        assert_eq!(&back, a);
    }
    assert_eq!(seen, 2, "{actions:#?}");
}
