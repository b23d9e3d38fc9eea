//! The token game of `simulate`: a small model played through both branches of a gateway (the
//! task completed, then failed into its error boundary and past it), a timer fired by the
//! player, signals and messages from outside, start events offered, the Europa mission played
//! to its end, the data mode's defaults, a looping model stopped, and acts that do not fit
//! refused with the element named.

use std::sync::Arc;

use executive_model::{Options, ProcessGraph};
use serde_json::json;

use crate::simulate::{Act, Mode, SimError, Simulation, TaskView, TokenCount, View};

fn load(xml: &str) -> Arc<ProcessGraph> {
    let options = Options {
        token_game: true,
        script_connector: true,
        ..Default::default()
    };
    let loaded = executive_model::load_with(xml.as_bytes(), &options);
    let messages: Vec<&str> = loaded
        .diagnostics
        .iter()
        .map(|d| d.message.as_str())
        .collect();
    Arc::new(
        loaded
            .graph
            .unwrap_or_else(|| panic!("model does not load: {messages:?}")),
    )
}

fn model(body: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="Defs" targetNamespace="urn:trace:test">
{body}
</definitions>"#
    )
}

/// Start → exclusive gateway: `fA` to a service task with an error boundary catching `E1`
/// (to its own end), `fB` straight to the end; the task also ends there.
fn branches() -> Arc<ProcessGraph> {
    load(&model(
        r#"<error id="Error_E1" name="E one" errorCode="E1"/>
<process id="P" isExecutable="true">
  <startEvent id="Start"><outgoing>f1</outgoing></startEvent>
  <exclusiveGateway id="Choice"><incoming>f1</incoming><outgoing>fA</outgoing><outgoing>fB</outgoing></exclusiveGateway>
  <serviceTask id="Measure" name="Measure the sample">
    <incoming>fA</incoming><outgoing>fA2</outgoing>
    <extensionElements><trace:task resource="lab.measure"/></extensionElements>
  </serviceTask>
  <boundaryEvent id="Fault" attachedToRef="Measure"><outgoing>fE</outgoing><errorEventDefinition errorRef="Error_E1"/></boundaryEvent>
  <endEvent id="Done"><incoming>fA2</incoming><incoming>fB</incoming></endEvent>
  <endEvent id="FaultEnd"><incoming>fE</incoming></endEvent>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Choice"/>
  <sequenceFlow id="fA" sourceRef="Choice" targetRef="Measure"/>
  <sequenceFlow id="fB" sourceRef="Choice" targetRef="Done"/>
  <sequenceFlow id="fA2" sourceRef="Measure" targetRef="Done"/>
  <sequenceFlow id="fE" sourceRef="Fault" targetRef="FaultEnd"/>
</process>"#,
    ))
}

fn act(sim: &mut Simulation, act: Act) {
    let what = format!("{act:?}");
    sim.act(act)
        .unwrap_or_else(|e| panic!("{what}: {e}\n{:#?}", sim.view()));
}

fn complete(element: &str) -> Act {
    Act::Complete {
        element: element.to_owned(),
        result: None,
    }
}

fn choose(gateway: &str, flows: &[&str]) -> Act {
    Act::Choose {
        gateway: gateway.to_owned(),
        flows: flows.iter().map(|f| (*f).to_owned()).collect(),
    }
}

fn fire(element: &str) -> Act {
    Act::Fire {
        element: element.to_owned(),
    }
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| (*s).to_owned()).collect()
}

#[test]
fn a_chosen_branch_with_its_task_completed_reaches_the_end() {
    let mut sim = Simulation::start(branches()).expect("starts");
    let v = sim.view();
    assert_eq!(
        v.tokens,
        vec![TokenCount {
            element: "Choice".into(),
            count: 1
        }]
    );
    assert_eq!(v.gateways.len(), 1, "{v:#?}");
    assert_eq!(v.gateways[0].element, "Choice");
    assert_eq!(v.gateways[0].flows, strings(&["fA", "fB"]));
    assert!(v.tasks.is_empty() && v.waits.is_empty() && !v.ended && v.outcome.is_none());

    act(&mut sim, choose("Choice", &["fA"]));
    let v = sim.view();
    assert!(v.gateways.is_empty());
    assert_eq!(
        v.tasks,
        vec![TaskView {
            element: "Measure".into(),
            name: "Measure the sample".into(),
            kind: "serviceTask".into(),
            resource: Some("lab.measure".into()),
            catches: strings(&["E1"]),
        }]
    );

    act(&mut sim, complete("Measure"));
    let v = sim.view();
    assert!(v.ended, "{v:#?}");
    assert_eq!(v.outcome.as_deref(), Some("completed"));
    assert!(v.tokens.is_empty() && v.tasks.is_empty() && v.incidents.is_empty());
    assert_eq!(
        v.trace,
        strings(&[
            "exit:Start",
            "enter:Choice",
            "exit:Choice",
            "enter:Measure",
            "exit:Measure",
            "enter:Done",
            "exit:Done",
        ])
    );
    assert_eq!(v.steps, 3, "start, the choice, the completion");
    let json = serde_json::to_value(&v).expect("serialisable");
    assert_eq!(json["outcome"], "completed");
    assert_eq!(json["trace"][0], "exit:Start");
}

#[test]
fn a_task_failed_with_a_caught_code_takes_its_boundary_and_an_uncaught_one_fails() {
    let mut sim = Simulation::start(branches()).expect("starts");
    act(&mut sim, choose("Choice", &["fA"]));
    act(
        &mut sim,
        Act::Fail {
            element: "Measure".into(),
            code: "E1".into(),
        },
    );
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"), "{v:#?}");
    assert_eq!(
        v.trace[3..],
        strings(&[
            "enter:Measure",
            "exit:Measure",
            "exit:Fault",
            "enter:FaultEnd",
            "exit:FaultEnd",
        ])
    );
    assert!(!v.trace.contains(&"enter:Done".to_owned()));

    // Another code: nothing catches it, so the instance fails with it.
    let mut sim = Simulation::start(branches()).expect("starts");
    act(&mut sim, choose("Choice", &["fA"]));
    act(
        &mut sim,
        Act::Fail {
            element: "Measure".into(),
            code: "E2".into(),
        },
    );
    let v = sim.view();
    assert!(v.ended);
    let outcome = v.outcome.expect("an outcome");
    assert!(outcome.starts_with("failed: E2"), "{outcome}");
}

#[test]
fn the_other_branch_is_taken_when_it_is_chosen() {
    let mut sim = Simulation::start(branches()).expect("starts");
    act(&mut sim, choose("Choice", &["fB"]));
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"));
    assert_eq!(
        v.trace,
        strings(&[
            "exit:Start",
            "enter:Choice",
            "exit:Choice",
            "enter:Done",
            "exit:Done"
        ])
    );
}

#[test]
fn a_timer_fires_when_the_player_says_and_moves_mission_time_to_its_deadline() {
    let g = load(&model(
        r#"<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <intermediateCatchEvent id="Cool" name="Cool down">
    <timerEventDefinition><timeDuration>PT2H</timeDuration></timerEventDefinition>
  </intermediateCatchEvent>
  <endEvent id="End"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Cool"/>
  <sequenceFlow id="f2" sourceRef="Cool" targetRef="End"/>
</process>"#,
    ));
    let mut sim = Simulation::start(g).expect("starts");
    let v = sim.view();
    assert_eq!(v.waits.len(), 1, "{v:#?}");
    assert_eq!(v.waits[0].element, "Cool");
    assert_eq!(v.waits[0].kind, "timer");
    assert_eq!(v.waits[0].label, "Cool down: timer due T+02h00m00s");
    assert_eq!(sim.now(), 0);
    act(&mut sim, fire("Cool"));
    assert_eq!(sim.now(), 2 * 3600 * 1000);
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"));
    assert_eq!(
        v.trace,
        strings(&[
            "exit:Start",
            "enter:Cool",
            "exit:Cool",
            "enter:End",
            "exit:End"
        ])
    );
}

#[test]
fn a_boundary_timer_on_a_waiting_task_is_fired_by_its_own_id() {
    let g = load(&model(
        r#"<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <userTask id="Approve"/>
  <boundaryEvent id="Timeout" attachedToRef="Approve">
    <timerEventDefinition><timeDuration>P1D</timeDuration></timerEventDefinition>
  </boundaryEvent>
  <endEvent id="Approved"/>
  <endEvent id="TimedOut"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Approve"/>
  <sequenceFlow id="f2" sourceRef="Approve" targetRef="Approved"/>
  <sequenceFlow id="f3" sourceRef="Timeout" targetRef="TimedOut"/>
</process>"#,
    ));
    let mut sim = Simulation::start(g).expect("starts");
    let v = sim.view();
    assert_eq!(v.tasks.len(), 1);
    assert_eq!(v.tasks[0].kind, "userTask");
    assert!(v.tasks[0].catches.is_empty());
    assert_eq!(v.waits.len(), 1);
    assert_eq!(
        v.waits[0].label,
        "Timeout: timer due T+1d00h00m00s, boundary of `Approve`"
    );
    act(&mut sim, fire("Timeout"));
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"));
    assert!(v.trace.ends_with(&strings(&[
        "exit:Approve",
        "exit:Timeout",
        "enter:TimedOut",
        "exit:TimedOut"
    ])));
}

#[test]
fn signals_and_messages_come_from_outside() {
    let g = load(&model(
        r#"<signal id="Sig_Go" name="GO"/>
<message id="Msg_Ping" name="PING"/>
<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <intermediateCatchEvent id="WaitGo"><signalEventDefinition signalRef="Sig_Go"/></intermediateCatchEvent>
  <receiveTask id="Ping" messageRef="Msg_Ping"/>
  <endEvent id="End"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="WaitGo"/>
  <sequenceFlow id="f2" sourceRef="WaitGo" targetRef="Ping"/>
  <sequenceFlow id="f3" sourceRef="Ping" targetRef="End"/>
</process>"#,
    ));
    let mut sim = Simulation::start(g).expect("starts");
    assert_eq!(sim.view().waits[0].label, "WaitGo: signal `GO`");
    let e = sim
        .act(Act::Message {
            name: "PING".into(),
        })
        .expect_err("nothing waits for PING yet");
    assert!(e.to_string().contains("`PING`"), "{e}");
    act(&mut sim, Act::Signal { name: "GO".into() });
    let v = sim.view();
    assert_eq!(v.waits.len(), 1, "{v:#?}");
    assert_eq!(
        (v.waits[0].element.as_str(), v.waits[0].kind.as_str()),
        ("Ping", "message")
    );
    act(
        &mut sim,
        Act::Message {
            name: "PING".into(),
        },
    );
    assert_eq!(sim.view().outcome.as_deref(), Some("completed"));
}

#[test]
fn a_process_that_starts_on_a_message_offers_its_start_event() {
    let g = load(&model(
        r#"<message id="Msg_Go" name="GO"/>
<process id="P" isExecutable="true">
  <startEvent id="OnGo"><messageEventDefinition messageRef="Msg_Go"/></startEvent>
  <task id="Work"/>
  <endEvent id="End"/>
  <sequenceFlow id="f1" sourceRef="OnGo" targetRef="Work"/>
  <sequenceFlow id="f2" sourceRef="Work" targetRef="End"/>
</process>"#,
    ));
    let mut sim = Simulation::start(g).expect("starts");
    let v = sim.view();
    assert!(!v.ended && v.tokens.is_empty() && v.steps == 0);
    assert_eq!(v.waits.len(), 1);
    assert_eq!(
        (v.waits[0].element.as_str(), v.waits[0].kind.as_str()),
        ("OnGo", "start")
    );
    act(&mut sim, fire("OnGo"));
    let v = sim.view();
    assert!(v.waits.is_empty(), "{v:#?}");
    assert_eq!(v.tasks[0].kind, "task");
    act(&mut sim, complete("Work"));
    assert_eq!(sim.view().outcome.as_deref(), Some("completed"));
}

fn europa() -> Arc<ProcessGraph> {
    load(include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../deploy/missions/europa-bsm1.bpmn"
    )))
}

/// Plays: the first waiting task is completed; with none, the first wait is fired; with
/// neither, the view is returned (a gateway waits, or nothing is left).
fn autoplay(sim: &mut Simulation, max_acts: usize) -> View {
    for _ in 0..max_acts {
        let v = sim.view();
        if v.ended {
            return v;
        }
        if let Some(t) = v.tasks.first() {
            act(sim, complete(&t.element));
        } else if let Some(w) = v.waits.first() {
            act(sim, fire(&w.element));
        } else {
            return v;
        }
    }
    sim.view()
}

#[test]
fn europa_does_not_end_by_completing_tasks_alone() {
    // In the exploration game every diverging gateway waits for the player. Completing tasks
    // reaches `SiteApproved` and the battery monitor's `BatteryLow`; with no task left, the
    // first wait fired is the science sub-process's deadline (P18D), which interrupts the
    // science; the downlink phase then stops at `EnergyLeft`. Only gateways wait: this is why
    // the mission is played with a choice at each decision (next test).
    let mut sim = Simulation::start(europa()).expect("starts");
    let v = autoplay(&mut sim, 100);
    assert!(!v.ended, "{v:#?}");
    let waiting: Vec<&str> = v.gateways.iter().map(|g| g.element.as_str()).collect();
    assert_eq!(waiting, ["BatteryLow", "EnergyLeft"], "{v:#?}");
    assert!(v.tasks.is_empty() && v.waits.is_empty(), "{v:#?}");
    assert!(v.trace.contains(&"exit:MissionDeadline".to_owned()));
    assert!(v.incidents.is_empty(), "{:?}", v.incidents);
}

#[test]
fn europa_is_played_to_its_end_with_a_choice_at_each_decision() {
    let mut sim = Simulation::start(europa()).expect("starts");
    // The science path: the site approved, no slump, enough samples after one site; the
    // battery stays fine; the energy runs out after the first downlink pass.
    for (gateway, flow) in [
        ("SiteApproved", "f_s5"),
        ("Slumped", "e12"),
        ("EnoughSamples", "f_s13"),
        ("BatteryLow", "f_b6"),
        ("EnergyLeft", "f_d7"),
    ] {
        act(&mut sim, choose(gateway, &[flow]));
    }
    let first = sim.view();
    assert_eq!(first.tasks[0].element, "InitializeMission");
    assert_eq!(first.tasks[0].kind, "scriptTask");
    let v = autoplay(&mut sim, 200);
    assert!(v.ended, "not ended within 200 acts: {v:#?}");
    // The mission ends at its terminate end event, which ends the battery monitor too.
    assert_eq!(v.outcome.as_deref(), Some("terminated"));
    assert!(v.incidents.is_empty(), "{:?}", v.incidents);
    let at = |e: &str| {
        v.trace
            .iter()
            .position(|t| t == e)
            .unwrap_or_else(|| panic!("{e} not in {:?}", v.trace))
    };
    assert_eq!(at("exit:Landed"), 0);
    assert!(at("enter:ApproveSite") < at("enter:ExcavateCall"));
    assert!(at("enter:StowArm") < at("exit:ExcavateCall"));
    assert!(at("enter:ScienceDone") < at("enter:CollectImagesSeismic"));
    assert!(at("enter:PowerDepleted") < at("exit:CommunicateUntilDeath"));
    // A terminate end event ends the instance on entry: it is never left.
    assert_eq!(v.trace.last().map(String::as_str), Some("enter:MissionEnd"));
}

#[test]
fn europa_aborts_science_on_the_battery_signal_from_outside() {
    let mut sim = Simulation::start(europa()).expect("starts");
    let v = autoplay(&mut sim, 5);
    assert!(
        v.tokens.iter().any(|t| t.element == "ExcavateAndCollect"),
        "{v:#?}"
    );
    assert!(
        v.waits
            .iter()
            .any(|w| w.element == "BatteryAbort" && w.kind == "signal"),
        "{v:#?}"
    );
    act(
        &mut sim,
        Act::Signal {
            name: "BATTERY_LOW_ABORT".into(),
        },
    );
    let v = sim.view();
    assert!(
        !v.tokens.iter().any(|t| t.element == "ExcavateAndCollect"),
        "{v:#?}"
    );
    assert!(
        v.tasks.iter().any(|t| t.element == "PrioritizeData"),
        "{v:#?}"
    );
    assert!(v.trace.contains(&"exit:BatteryAbort".to_owned()));
}

#[test]
fn acts_that_do_not_fit_are_refused_naming_the_element() {
    let mut sim = Simulation::start(branches()).expect("starts");
    let before = sim.view();
    let refused = |sim: &mut Simulation, act: Act, name: &str| {
        let e = sim.act(act).expect_err("refused");
        let text = e.to_string();
        assert!(text.contains(&format!("`{name}`")), "{text}");
        e
    };
    let e = refused(&mut sim, complete("Nope"), "Nope");
    assert!(matches!(e, SimError::UnknownElement(_)));
    let e = refused(&mut sim, complete("Measure"), "Measure");
    assert!(matches!(e, SimError::NotWaiting { .. }), "{e:?}");
    refused(&mut sim, complete("Done"), "Done");
    refused(
        &mut sim,
        Act::Fail {
            element: "Measure".into(),
            code: "E1".into(),
        },
        "Measure",
    );
    let e = refused(&mut sim, fire("Measure"), "Measure");
    assert!(matches!(e, SimError::NothingWaits { .. }));
    let e = refused(&mut sim, choose("Measure", &["fA2"]), "Measure");
    assert!(matches!(e, SimError::NotChoosable { .. }));
    let e = refused(&mut sim, choose("Choice", &["f1"]), "Choice");
    assert!(matches!(e, SimError::UnknownFlow { .. }));
    refused(&mut sim, choose("Choice", &["nope"]), "Choice");
    refused(&mut sim, choose("Choice", &["fA", "fB"]), "Choice");
    refused(&mut sim, choose("Choice", &[]), "Choice");
    let e = refused(&mut sim, Act::Signal { name: "X".into() }, "X");
    assert!(matches!(e, SimError::UnknownSignal(_)));
    let e = refused(&mut sim, Act::Message { name: "M".into() }, "M");
    assert!(matches!(e, SimError::Rejected { .. }), "{e:?}");
    assert_eq!(sim.view(), before, "a refused act changes nothing");

    act(&mut sim, choose("Choice", &["fA"]));
    // A result that is not an object, an empty code, a code that is not a string.
    let e = refused(
        &mut sim,
        Act::Complete {
            element: "Measure".into(),
            result: Some(json!("done")),
        },
        "Measure",
    );
    assert!(matches!(e, SimError::BadAct { .. }));
    refused(
        &mut sim,
        Act::Fail {
            element: "Measure".into(),
            code: " ".into(),
        },
        "Measure",
    );
    let e = Act::from_json(json!({"act": "fail", "element": "Measure", "code": 5}))
        .expect_err("a number is not a code");
    assert!(e.to_string().contains("`Measure`"), "{e}");
    let e = Act::from_json(json!({"act": "jump", "element": "Measure"})).expect_err("no such act");
    assert!(e.to_string().contains("`Measure`"), "{e}");
    let read = Act::from_json(json!({"act": "fail", "element": "Measure", "code": "E1"}));
    assert_eq!(
        read.expect("a good act"),
        Act::Fail {
            element: "Measure".into(),
            code: "E1".into()
        }
    );

    act(&mut sim, complete("Measure"));
    let e = refused(&mut sim, complete("Measure"), "Measure");
    assert!(matches!(e, SimError::Ended(_)));
}

#[test]
fn in_the_data_mode_results_and_conditions_decide_and_an_unchosen_gateway_consumes_the_token() {
    let g = load(&model(
        r#"<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <serviceTask id="Measure"/>
  <exclusiveGateway id="High" default="fLow"/>
  <endEvent id="Hot"/>
  <endEvent id="Cold"/>
  <task id="Next"/>
  <exclusiveGateway id="Pick"/>
  <endEvent id="A"/>
  <endEvent id="B"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Measure"/>
  <sequenceFlow id="f2" sourceRef="Measure" targetRef="High"/>
  <sequenceFlow id="fHigh" sourceRef="High" targetRef="Hot"><conditionExpression>x &gt; 1</conditionExpression></sequenceFlow>
  <sequenceFlow id="fLow" sourceRef="High" targetRef="Cold"/>
  <sequenceFlow id="f3" sourceRef="Start" targetRef="Next"/>
  <sequenceFlow id="f4" sourceRef="Next" targetRef="Pick"/>
  <sequenceFlow id="fA" sourceRef="Pick" targetRef="A"/>
  <sequenceFlow id="fB" sourceRef="Pick" targetRef="B"/>
</process>"#,
    ));
    // The result decides the conditional gateway.
    let mut sim = Simulation::start_with(Arc::clone(&g), Mode::Data).expect("starts");
    assert_eq!(sim.mode(), Mode::Data);
    act(
        &mut sim,
        Act::Complete {
            element: "Measure".into(),
            result: Some(json!({"x": 2})),
        },
    );
    act(&mut sim, choose("Pick", &["fB"]));
    act(&mut sim, complete("Next"));
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"), "{v:#?}");
    assert!(v.trace.contains(&"enter:Hot".to_owned()));
    assert!(v.trace.contains(&"enter:B".to_owned()));
    assert!(v.gateways.is_empty());

    // No condition holds: the default flow. No choice at `Pick`, whose flows carry no
    // condition: the token stops there and is gone.
    let mut sim = Simulation::start_with(Arc::clone(&g), Mode::Data).expect("starts");
    act(
        &mut sim,
        Act::Complete {
            element: "Measure".into(),
            result: Some(json!({"x": 0})),
        },
    );
    act(&mut sim, complete("Next"));
    let v = sim.view();
    assert_eq!(v.outcome.as_deref(), Some("completed"), "{v:#?}");
    assert!(v.trace.contains(&"enter:Cold".to_owned()));
    assert!(v.trace.ends_with(&strings(&["enter:Pick", "exit:Pick"])));

    // No result at all: the condition reads a variable nothing set, an incident.
    let mut sim = Simulation::start_with(g, Mode::Data).expect("starts");
    act(&mut sim, complete("Measure"));
    let v = sim.view();
    assert!(!v.ended);
    assert_eq!(v.incidents.len(), 1, "{v:#?}");
    assert!(v.incidents[0].starts_with("High: "), "{:?}", v.incidents);
}

#[test]
fn a_loop_through_chosen_gateways_is_stopped_and_reported() {
    let g = load(&model(
        r#"<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <exclusiveGateway id="Again"/>
  <exclusiveGateway id="Back"/>
  <endEvent id="End"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Again"/>
  <sequenceFlow id="fLoop" sourceRef="Again" targetRef="Back"/>
  <sequenceFlow id="fOut" sourceRef="Again" targetRef="End"/>
  <sequenceFlow id="fBack" sourceRef="Back" targetRef="Again"/>
</process>"#,
    ));
    let mut sim = Simulation::start(g).expect("starts");
    let e = sim
        .act(choose("Again", &["fLoop"]))
        .expect_err("the loop is stopped");
    assert!(matches!(e, SimError::Runaway { .. }), "{e:?}");
    assert!(e.to_string().contains("`Again`"), "{e}");
    let v = sim.view();
    // The runaway, and the trace it filled.
    assert_eq!(v.incidents.len(), 2, "{:?}", v.incidents);
    let has = |start: &str| v.incidents.iter().any(|i| i.starts_with(start));
    assert!(
        has("Again: stopped after 10000 engine steps"),
        "{:?}",
        v.incidents
    );
    assert!(has("trace: "), "{:?}", v.incidents);
    assert_eq!(v.gateways.len(), 1, "the token waits at the gateway again");
    // The player can still take it out.
    act(&mut sim, choose("Again", &["fOut"]));
    assert_eq!(sim.view().outcome.as_deref(), Some("completed"));
}

#[test]
fn a_simulation_can_move_between_threads() {
    fn send<T: Send>() {}
    send::<Simulation>();
}

#[test]
fn a_loop_the_engine_cannot_leave_is_stopped_by_its_move_bound() {
    // Two gateways passing the token to each other: no task, wait or choice on the loop. The
    // engine stops the step after its bound of moves and records an incident on the token.
    let g = load(&model(
        r#"<process id="P" isExecutable="true">
  <startEvent id="Start"/>
  <exclusiveGateway id="Ping"/>
  <exclusiveGateway id="Pong"/>
  <sequenceFlow id="f1" sourceRef="Start" targetRef="Ping"/>
  <sequenceFlow id="f2" sourceRef="Ping" targetRef="Pong"/>
  <sequenceFlow id="f3" sourceRef="Pong" targetRef="Ping"/>
</process>"#,
    ));
    let sim = Simulation::start(g).expect("starts");
    let v = sim.view();
    assert!(!v.ended);
    assert_eq!(v.trace.len(), crate::simulate::MAX_TRACE);
    assert_eq!(v.incidents.len(), 2, "{:?}", v.incidents);
    assert!(v.incidents[0].contains("token moves"), "{:?}", v.incidents);
    assert!(v.incidents[1].starts_with("trace: "), "{:?}", v.incidents);
}
