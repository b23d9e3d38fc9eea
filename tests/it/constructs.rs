//! The Spin translation of event sub-processes, compensation, transactions with cancel, message
//! flows between pools, processes the outside starts, parallel multi-instance, inclusive joins
//! behind links, unsafe merges, receive tasks, repeating outside events and counts written as
//! numbers: per construct a mission model on which Spin and the engine agree exactly, and a
//! flawed variant both find the flaw in.

use crate::generated::service_task;
use crate::protocol::tempdir;
use crate::verify::{Compared, Comparison, compare};

const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:constructs">
  <error id="JAM" errorCode="JAM"/>
  <message id="STATUS" name="status"/>
  <message id="SAMPLE" name="sample"/>
  <signal id="RESULT" name="result"/>"#;

/// Loads `body` (inside `definitions`); it must be valid.
fn graph(name: &str, body: &str) -> executive_model::ProcessGraph {
    let text = format!("{HEAD}\n{body}\n</definitions>");
    let loaded = executive_model::load(text.as_bytes());
    loaded
        .graph
        .unwrap_or_else(|| panic!("{name}: invalid: {:?}", loaded.diagnostics))
}

/// What the translation refuses in `body` (it must refuse something).
fn refused(name: &str, body: &str) -> Vec<executive_verify::Refusal> {
    executive_verify::translate(
        &graph(name, body),
        executive_verify::Bounds::default(),
        &[],
        &Default::default(),
    )
    .expect_err("the model is refused")
}

/// Loads `body` (inside `definitions`) and compares Spin with the engine on it; the model must
/// translate and explore, and Spin must miss nothing the engine does.
fn compared(name: &str, body: &str) -> Comparison {
    match compare(graph(name, body), &tempdir(&format!("constructs-{name}"))) {
        Compared::Refused(why) => panic!("{name}: not translated: {why}"),
        Compared::NeedsData => panic!("{name}: the engine could not be explored"),
        Compared::Done(c) => {
            assert!(c.unsound.is_empty(), "{name}: {:?}", c.unsound);
            c
        }
    }
}

/// Exact agreement: the same deadlocks, unsafe runs, dead activities and end events.
fn agree(name: &str, body: &str) -> Comparison {
    let c = compared(name, body);
    assert!(
        c.how.is_empty(),
        "{name}: Spin and the engine differ: {:?}",
        c.how
    );
    c
}

fn set(items: &[&str]) -> std::collections::BTreeSet<String> {
    items.iter().map(|s| (*s).to_owned()).collect()
}

/// Excavation in a sub-process: a jam (error JAM) of the drill is caught by the sub-process's
/// error event sub-process, which wins over the sub-process's own JAM boundary (`give_up`, dead
/// unless the event sub-process is removed; clearing is a ground decision, which cannot fail
/// and so throw a jam of its own to the boundary); a status request (message, non-interrupting) is
/// answered beside the work by a report the operator confirms, one request at a time in both
/// (the engine's exploration once piled up one held instance per request, without bound); a
/// one-hour deadline (timer, interrupting) stows the arm.
fn excavation(with_event_sub: bool) -> String {
    let on_jam = if with_event_sub {
        r#"<subProcess id="on_jam" name="On jam" triggeredByEvent="true">
        <startEvent id="jam"><errorEventDefinition errorRef="JAM"/></startEvent>
        <userTask id="clear" name="Approve jam clearing"/>
        <endEvent id="cleared"/>
        <sequenceFlow id="j1" sourceRef="jam" targetRef="clear"/>
        <sequenceFlow id="j2" sourceRef="clear" targetRef="cleared"/>
      </subProcess>"#
    } else {
        ""
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <subProcess id="excavate" name="Excavate">
      <startEvent id="es"/>
      <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
      <endEvent id="drilled"/>
      <sequenceFlow id="e1" sourceRef="es" targetRef="drill"/>
      <sequenceFlow id="e2" sourceRef="drill" targetRef="drilled"/>
      {on_jam}
      <subProcess id="on_status" name="On status request" triggeredByEvent="true">
        <startEvent id="status" isInterrupting="false"><messageEventDefinition messageRef="STATUS"/></startEvent>
        <userTask id="report" name="Confirm status report"/>
        <endEvent id="reported"/>
        <sequenceFlow id="r1" sourceRef="status" targetRef="report"/>
        <sequenceFlow id="r2" sourceRef="report" targetRef="reported"/>
      </subProcess>
    </subProcess>
    <boundaryEvent id="jammed" attachedToRef="excavate"><errorEventDefinition errorRef="JAM"/></boundaryEvent>
    <task id="give_up" name="Give up"/>
    <endEvent id="done"/>
    <endEvent id="gave_up"/>
    <subProcess id="on_deadline" name="On deadline" triggeredByEvent="true">
      <startEvent id="deadline"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition></startEvent>
      <task id="stow" name="Stow arm"/>
      <endEvent id="stowed"/>
      <sequenceFlow id="d1" sourceRef="deadline" targetRef="stow"/>
      <sequenceFlow id="d2" sourceRef="stow" targetRef="stowed"/>
    </subProcess>
    <sequenceFlow id="f1" sourceRef="s" targetRef="excavate"/>
    <sequenceFlow id="f2" sourceRef="excavate" targetRef="done"/>
    <sequenceFlow id="f3" sourceRef="jammed" targetRef="give_up"/>
    <sequenceFlow id="f4" sourceRef="give_up" targetRef="gave_up"/>
  </process>"#
    )
}

#[test]
fn event_sub_processes_catch_errors_first_and_start_on_messages_and_timers() {
    let c = agree("event-subs", &excavation(true));
    // The jam goes to the event sub-process, never to the boundary behind it.
    assert_eq!(c.dead, set(&["give_up"]));
    assert_eq!(
        c.ends,
        set(&["cleared", "done", "drilled", "reported", "stowed"])
    );
    assert!(!c.deadlock && !c.unsafe_run);
    // Without the event sub-process the boundary catches the jam.
    let c = agree("event-subs-boundary", &excavation(false));
    assert!(c.dead.is_empty(), "{:?}", c.dead);
    assert!(c.ends.contains("gave_up"));
}

/// Drilling with a compensation handler (refill the hole); a bad core rolls back by throwing
/// compensation. `throw_first` throws it before drilling: nothing has completed, so the
/// handler never runs.
fn drilling(throw_first: bool) -> String {
    let (a, b) = if throw_first {
        ("rollback", "drill")
    } else {
        ("drill", "rollback")
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
    <boundaryEvent id="undo" attachedToRef="drill"><compensateEventDefinition/></boundaryEvent>
    <serviceTask id="refill" name="Refill hole" isForCompensation="true"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
    <association id="a1" associationDirection="One" sourceRef="undo" targetRef="refill"/>
    <intermediateThrowEvent id="rollback" name="Roll back"><compensateEventDefinition/></intermediateThrowEvent>
    <task id="stow" name="Stow"/>
    <endEvent id="done"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="{a}"/>
    <sequenceFlow id="f2" sourceRef="{a}" targetRef="{b}"/>
    <sequenceFlow id="f3" sourceRef="{b}" targetRef="stow"/>
    <sequenceFlow id="f4" sourceRef="stow" targetRef="done"/>
  </process>"#
    )
}

#[test]
fn compensation_runs_the_handlers_of_completed_activities_only() {
    let c = agree("compensation", &drilling(false));
    assert!(c.dead.is_empty(), "the handler runs: {:?}", c.dead);
    let c = agree("compensation-early", &drilling(true));
    assert_eq!(
        c.dead,
        set(&["refill"]),
        "nothing completed yet to compensate"
    );
}

/// A transaction: drill (compensated by refilling), then keep the sample or cancel. The cancel
/// boundary reports the cancellation; both paths meet at `join` (a parallel join deadlocks: only
/// one of them ever comes).
fn sampling(join: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <transaction id="sample" name="Take sample">
      <startEvent id="ts"/>
      <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
      <boundaryEvent id="undo" attachedToRef="drill"><compensateEventDefinition/></boundaryEvent>
      <serviceTask id="refill" name="Refill hole" isForCompensation="true"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
      <association id="a1" associationDirection="One" sourceRef="undo" targetRef="refill"/>
      <exclusiveGateway id="check" name="Sample good?" default="keep"/>
      <endEvent id="kept"/>
      <endEvent id="discard"><cancelEventDefinition/></endEvent>
      <sequenceFlow id="t1" sourceRef="ts" targetRef="drill"/>
      <sequenceFlow id="t2" sourceRef="drill" targetRef="check"/>
      <sequenceFlow id="keep" sourceRef="check" targetRef="kept"/>
      <sequenceFlow id="bad" sourceRef="check" targetRef="discard"><conditionExpression xsi:type="tFormalExpression">bad</conditionExpression></sequenceFlow>
    </transaction>
    <boundaryEvent id="cancelled" attachedToRef="sample"><cancelEventDefinition/></boundaryEvent>
    <task id="report" name="Report cancellation"/>
    <{join} id="join"/>
    <endEvent id="done"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="sample"/>
    <sequenceFlow id="f2" sourceRef="sample" targetRef="join"/>
    <sequenceFlow id="f3" sourceRef="cancelled" targetRef="report"/>
    <sequenceFlow id="f4" sourceRef="report" targetRef="join"/>
    <sequenceFlow id="f5" sourceRef="join" targetRef="done"/>
  </process>"#
    )
}

#[test]
fn a_cancelled_transaction_compensates_then_takes_its_cancel_boundary() {
    let c = agree("transaction", &sampling("exclusiveGateway"));
    assert!(c.dead.is_empty(), "refill and report run: {:?}", c.dead);
    assert!(!c.deadlock);
    assert_eq!(c.ends, set(&["discard", "done", "kept"]));
    let c = agree("transaction-join", &sampling("parallelGateway"));
    assert!(c.deadlock, "kept and cancelled never both come");
}

/// Two pools: the lander collects a sample and sends it; the orbiter's process starts on the
/// message (its start event is where the message flow ends) and relays it.
const POOLS: &str = r#"<collaboration id="c">
    <participant id="lander_pool" name="Lander" processRef="lander"/>
    <participant id="orbiter_pool" name="Orbiter" processRef="orbiter"/>
    <messageFlow id="m1" sourceRef="send" targetRef="wake"/>
  </collaboration>
  <process id="lander" isExecutable="true">
    <startEvent id="s"/>
    <task id="collect" name="Collect sample"/>
    <sendTask id="send" name="Send sample" messageRef="SAMPLE"/>
    <endEvent id="sent"/>
    <sequenceFlow id="l1" sourceRef="s" targetRef="collect"/>
    <sequenceFlow id="l2" sourceRef="collect" targetRef="send"/>
    <sequenceFlow id="l3" sourceRef="send" targetRef="sent"/>
  </process>
  <process id="orbiter" isExecutable="true">
    <startEvent id="wake"><messageEventDefinition messageRef="SAMPLE"/></startEvent>
    <task id="relay" name="Relay to Earth"/>
    <endEvent id="relayed"/>
    <sequenceFlow id="o1" sourceRef="wake" targetRef="relay"/>
    <sequenceFlow id="o2" sourceRef="relay" targetRef="relayed"/>
  </process>"#;

#[test]
fn message_flows_between_pools_start_the_receiving_process() {
    let c = agree("pools", POOLS);
    assert!(c.dead.is_empty(), "the orbiter relays: {:?}", c.dead);
    assert_eq!(c.ends, set(&["relayed", "sent"]));
    // Without the orbiter's process, the lander's message leaves the model: the lander still
    // ends, and the translation takes it.
    let lander_only = POOLS
        .split("<process id=\"orbiter\"")
        .next()
        .unwrap_or_default()
        .replace(
            r#"<messageFlow id="m1" sourceRef="send" targetRef="wake"/>"#,
            r#"<messageFlow id="m1" sourceRef="send" targetRef="orbiter_pool"/>"#,
        )
        .replace(r#"processRef="orbiter""#, "");
    let c = agree("pools-lander", &lander_only);
    assert_eq!(c.ends, set(&["sent"]));
}

/// A relay process the ground starts by a message (no pool in the model sends it), beside the
/// lander's own work: its activity is held while the lander works. `stuck` joins the relay's
/// two exclusive ways with a parallel gateway, so a relay run never ends; `waiting` makes the
/// lander wait, beside its drilling, for a signal nothing throws.
fn relay(stuck: bool, waiting: bool) -> String {
    let join = if stuck {
        "parallelGateway"
    } else {
        "exclusiveGateway"
    };
    let lander = if waiting {
        r#"<parallelGateway id="fork"/>
    <intermediateCatchEvent id="result"><signalEventDefinition signalRef="RESULT"/></intermediateCatchEvent>
    <parallelGateway id="join"/>
    <sequenceFlow id="l1" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="l2" sourceRef="fork" targetRef="drill"/>
    <sequenceFlow id="l3" sourceRef="fork" targetRef="result"/>
    <sequenceFlow id="l4" sourceRef="drill" targetRef="join"/>
    <sequenceFlow id="l5" sourceRef="result" targetRef="join"/>
    <sequenceFlow id="l6" sourceRef="join" targetRef="drilled"/>"#
    } else {
        r#"<sequenceFlow id="l1" sourceRef="s" targetRef="drill"/>
    <sequenceFlow id="l2" sourceRef="drill" targetRef="drilled"/>"#
    };
    format!(
        r#"<process id="lander" isExecutable="true">
    <startEvent id="s"/>
    <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="arm"/></extensionElements></serviceTask>
    <endEvent id="drilled"/>
    {lander}
  </process>
  <process id="relay" isExecutable="true">
    <startEvent id="asked"><messageEventDefinition messageRef="STATUS"/></startEvent>
    <serviceTask id="send" name="Send status"><extensionElements><trace:task resource="comm"/></extensionElements></serviceTask>
    <exclusiveGateway id="how" default="r4"/>
    <task id="short" name="Short report"/>
    <task id="long" name="Long report"/>
    <{join} id="merge"/>
    <endEvent id="relayed"/>
    <sequenceFlow id="r1" sourceRef="asked" targetRef="send"/>
    <sequenceFlow id="r2" sourceRef="send" targetRef="how"/>
    <sequenceFlow id="r3" sourceRef="how" targetRef="short"><conditionExpression xsi:type="tFormalExpression">brief</conditionExpression></sequenceFlow>
    <sequenceFlow id="r4" sourceRef="how" targetRef="long"/>
    <sequenceFlow id="r5" sourceRef="short" targetRef="merge"/>
    <sequenceFlow id="r6" sourceRef="long" targetRef="merge"/>
    <sequenceFlow id="r7" sourceRef="merge" targetRef="relayed"/>
  </process>"#
    )
}

#[test]
fn a_process_the_outside_starts_by_a_message_runs_in_both() {
    // The engine's exploration once never started it (its `send` dead, `relayed` unreached,
    // where Spin found both).
    let c = agree("relay", &relay(false, false));
    assert!(c.dead.is_empty(), "{:?}", c.dead);
    assert_eq!(c.ends, set(&["drilled", "relayed"]));
    assert!(!c.deadlock && !c.unsafe_run);
    let c = agree("relay-stuck", &relay(true, false));
    assert!(c.deadlock, "a relay run waits at its parallel join forever");
    assert_eq!(c.ends, set(&["drilled"]));
    // The lander stuck while the relay is idle: that the outside could still start the relay
    // does not hide it (the outside starts it once per run, as the translation does).
    let c = agree("relay-lander-waits", &relay(false, true));
    assert!(c.deadlock, "the lander waits for a signal nothing throws");
    assert_eq!(c.ends, set(&["relayed"]));
}

/// Three parallel analyses of a sample; the first result (behaviour `One`) notifies the ground
/// through the activity's signal boundary without stopping the others. `collide` sends both the
/// notification and the analyses into one task through an exclusive merge, so two tokens can
/// meet there.
fn analyses(collide: bool) -> String {
    let (after_notify, notified) = if collide {
        ("archive", "")
    } else {
        ("notified", r#"<endEvent id="notified"/>"#)
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <serviceTask id="analyze" name="Analyze sample">
      <extensionElements><trace:task resource="lab"/></extensionElements>
      <multiInstanceLoopCharacteristics isSequential="false" behavior="One" oneBehaviorEventRef="first">
        <loopCardinality xsi:type="tFormalExpression">3</loopCardinality>
      </multiInstanceLoopCharacteristics>
    </serviceTask>
    <boundaryEvent id="first_result" attachedToRef="analyze" cancelActivity="false"><signalEventDefinition id="first" signalRef="RESULT"/></boundaryEvent>
    <task id="notify" name="Notify ground"/>
    <exclusiveGateway id="archive"/>
    <task id="store" name="Archive"/>
    <endEvent id="done"/>
    {notified}
    <sequenceFlow id="f1" sourceRef="s" targetRef="analyze"/>
    <sequenceFlow id="f2" sourceRef="analyze" targetRef="archive"/>
    <sequenceFlow id="f3" sourceRef="first_result" targetRef="notify"/>
    <sequenceFlow id="f4" sourceRef="notify" targetRef="{after_notify}"/>
    <sequenceFlow id="f5" sourceRef="archive" targetRef="store"/>
    <sequenceFlow id="f6" sourceRef="store" targetRef="done"/>
  </process>"#
    )
}

#[test]
fn parallel_instances_complete_together_and_throw_their_behaviour_event() {
    let c = agree("multi-instance", &analyses(false));
    assert!(c.dead.is_empty(), "{:?}", c.dead);
    assert_eq!(c.ends, set(&["done", "notified"]));
    assert!(!c.unsafe_run);
    let c = agree("multi-instance-merge", &analyses(true));
    assert!(
        c.unsafe_run,
        "the notification can reach the merge while the analyses' token is there"
    );
}

/// Two sites surveyed by a parallel multi-instance sub-process (drive, then image; a stuck
/// drive is caught inside the body and the site skipped). `signal_inside` makes the body
/// broadcast "result" and wait for it: instances that hear each other are refused, named.
fn survey(signal_inside: bool) -> String {
    let (after_image, extra) = if signal_inside {
        (
            "tell",
            r#"<intermediateThrowEvent id="tell"><signalEventDefinition signalRef="RESULT"/></intermediateThrowEvent>
      <intermediateCatchEvent id="hear"><signalEventDefinition signalRef="RESULT"/></intermediateCatchEvent>
      <sequenceFlow id="b5" sourceRef="tell" targetRef="hear"/>
      <sequenceFlow id="b6" sourceRef="hear" targetRef="imaged"/>"#,
        )
    } else {
        ("imaged", "")
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <subProcess id="sites" name="Survey sites">
      <multiInstanceLoopCharacteristics isSequential="false">
        <loopCardinality xsi:type="tFormalExpression">2</loopCardinality>
      </multiInstanceLoopCharacteristics>
      <startEvent id="bs"/>
      <serviceTask id="drive" name="Drive to site"><extensionElements><trace:task resource="rover"/></extensionElements></serviceTask>
      <boundaryEvent id="stuck" attachedToRef="drive"><errorEventDefinition errorRef="JAM"/></boundaryEvent>
      <serviceTask id="image" name="Image site"><extensionElements><trace:task resource="camera"/></extensionElements></serviceTask>
      <endEvent id="imaged"/>
      <endEvent id="skipped"/>
      <sequenceFlow id="b1" sourceRef="bs" targetRef="drive"/>
      <sequenceFlow id="b2" sourceRef="drive" targetRef="image"/>
      <sequenceFlow id="b3" sourceRef="image" targetRef="{after_image}"/>
      <sequenceFlow id="b4" sourceRef="stuck" targetRef="skipped"/>
      {extra}
    </subProcess>
    <endEvent id="done"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="sites"/>
    <sequenceFlow id="f2" sourceRef="sites" targetRef="done"/>
  </process>"#
    )
}

#[test]
fn a_parallel_multi_instance_sub_process_runs_its_bodies_and_completes() {
    let c = agree("multi-instance-body", &survey(false));
    assert!(c.dead.is_empty() && !c.deadlock && !c.unsafe_run);
    assert_eq!(c.ends, set(&["done", "imaged", "skipped"]));
    let refused = refused("multi-instance-signals", &survey(true));
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert_eq!(refused[0].element, "sites");
    assert!(
        refused[0].reason.contains("signal"),
        "{}",
        refused[0].reason
    );
}

/// A process drawn with an activity left unconnected at its start (Charge), beside the start
/// event's path: the engine starts it with the process (implicit start, BPMN 2.0.2 §13.2.2),
/// and so does the translation; an unconnected gateway is refused, named.
fn unconnected(gateway: bool) -> String {
    let extra = if gateway {
        r#"<parallelGateway id="fork"/><endEvent id="e3"/><sequenceFlow id="g1" sourceRef="fork" targetRef="e3"/>"#
    } else {
        ""
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <task id="survey" name="Survey"/>
    <endEvent id="e1"/>
    <task id="charge" name="Charge batteries"/>
    <endEvent id="e2"/>
    {extra}
    <sequenceFlow id="f1" sourceRef="s" targetRef="survey"/>
    <sequenceFlow id="f2" sourceRef="survey" targetRef="e1"/>
    <sequenceFlow id="f3" sourceRef="charge" targetRef="e2"/>
  </process>"#
    )
}

#[test]
fn activities_without_incoming_flow_start_with_their_scope() {
    let c = agree("implicit-start", &unconnected(false));
    assert!(c.dead.is_empty(), "Charge runs: {:?}", c.dead);
    assert_eq!(c.ends, set(&["e1", "e2"]));
    let refused = refused("implicit-gateway", &unconnected(true));
    assert_eq!(
        refused
            .iter()
            .map(|r| r.element.as_str())
            .collect::<Vec<_>>(),
        ["fork"]
    );
}

/// An inclusive block whose first branch reaches the join through a link (`link`), or along a
/// flow: the join waits for a token coming through the link as for one on a flow.
fn linked_join(link: bool) -> String {
    let (a, b, join) = (service_task("a"), service_task("b"), service_task("after"));
    let first = if link {
        r#"<intermediateThrowEvent id="jump"><linkEventDefinition name="L"/></intermediateThrowEvent>
    <intermediateCatchEvent id="land"><linkEventDefinition name="L"/></intermediateCatchEvent>
    <sequenceFlow id="f3" sourceRef="a" targetRef="jump"/>
    <sequenceFlow id="f4" sourceRef="land" targetRef="j"/>"#
    } else {
        r#"<sequenceFlow id="f3" sourceRef="a" targetRef="j"/>"#
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <inclusiveGateway id="o" default="f2"/>
    <inclusiveGateway id="j"/>
    {a}{b}{join}
    <endEvent id="e"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="o"/>
    <sequenceFlow id="f1" sourceRef="o" targetRef="a"><conditionExpression xsi:type="tFormalExpression">go == 1</conditionExpression></sequenceFlow>
    <sequenceFlow id="f2" sourceRef="o" targetRef="b"/>
    {first}
    <sequenceFlow id="f5" sourceRef="b" targetRef="j"/>
    <sequenceFlow id="f6" sourceRef="j" targetRef="after"/>
    <sequenceFlow id="f7" sourceRef="after" targetRef="e"/>
  </process>"#
    )
}

#[test]
fn an_inclusive_join_waits_for_a_token_still_coming_through_a_link() {
    for link in [false, true] {
        let c = agree(&format!("linked-join-{link}"), &linked_join(link));
        assert!(!c.deadlock && !c.unsafe_run, "link {link}");
        assert_eq!(c.ends, set(&["e"]));
    }
}

/// Two parallel branches merged without a gateway into `merged`, which runs once per token and
/// splits again: one branch waits at a parallel join for the other, so the second round's token
/// waits on the same flow beside the first's (unsafe), and both rounds then pass the join.
/// `guarded` adds an error event sub-process, so that no task is one step in the translation.
fn doubled(guarded: bool) -> String {
    let tasks: String = ["slow", "last"].iter().map(|t| service_task(t)).collect();
    let guard = if guarded {
        r#"<subProcess id="esp" triggeredByEvent="true">
      <startEvent id="es"><errorEventDefinition errorRef="JAM"/></startEvent>
      <endEvent id="ee"/>
      <sequenceFlow id="g1" sourceRef="es" targetRef="ee"/>
    </subProcess>"#
    } else {
        ""
    };
    merged_twice(&format!(
        r#"<parallelGateway id="again"/>
    <parallelGateway id="join"/>
    {tasks}
    {guard}
    <sequenceFlow id="f5" sourceRef="merged" targetRef="again"/>
    <sequenceFlow id="f6" sourceRef="again" targetRef="slow"/>
    <sequenceFlow id="f7" sourceRef="again" targetRef="join"/>
    <sequenceFlow id="f8" sourceRef="slow" targetRef="join"/>
    <sequenceFlow id="f9" sourceRef="join" targetRef="last"/>
    <sequenceFlow id="f10" sourceRef="last" targetRef="e"/>"#
    ))
}

/// A process whose two parallel branches (`a`, `b`) merge without a gateway into `merged`,
/// which runs once per token; `rest` holds what follows `merged`, up to the end event `e`.
fn merged_twice(rest: &str) -> String {
    let tasks: String = ["a", "b", "merged"]
        .iter()
        .map(|t| service_task(t))
        .collect();
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    {tasks}
    <endEvent id="e"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f1" sourceRef="fork" targetRef="a"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="b"/>
    <sequenceFlow id="f3" sourceRef="a" targetRef="merged"/>
    <sequenceFlow id="f4" sourceRef="b" targetRef="merged"/>
    {rest}
  </process>"#
    )
}

#[test]
fn a_second_token_on_a_flow_or_into_a_running_task_is_unsafe_and_kept() {
    for guarded in [false, true] {
        let c = agree(&format!("doubled-{guarded}"), &doubled(guarded));
        // Unsafe, but nothing is lost: both rounds pass the join and end.
        assert!(c.unsafe_run, "guarded {guarded}");
        assert!(!c.deadlock, "guarded {guarded}");
        assert!(c.ends.contains("e"), "guarded {guarded}: {:?}", c.ends);
    }
}

/// A sub-process waits in a receive task, an error event sub-process beside it.
fn receiving() -> String {
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <subProcess id="sp">
      <startEvent id="s1"/>
      <receiveTask id="wait" messageRef="STATUS"/>
      <endEvent id="e1"/>
      <sequenceFlow id="g0" sourceRef="s1" targetRef="wait"/>
      <sequenceFlow id="g1" sourceRef="wait" targetRef="e1"/>
      <subProcess id="esp" triggeredByEvent="true">
        <startEvent id="es"><errorEventDefinition errorRef="JAM"/></startEvent>
        {handle}
        <endEvent id="ee"/>
        <sequenceFlow id="h0" sourceRef="es" targetRef="handle"/>
        <sequenceFlow id="h1" sourceRef="handle" targetRef="ee"/>
      </subProcess>
    </subProcess>
    {after}
    <endEvent id="e"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="sp"/>
    <sequenceFlow id="f1" sourceRef="sp" targetRef="after"/>
    <sequenceFlow id="f2" sourceRef="after" targetRef="e"/>
  </process>"#,
        handle = service_task("handle"),
        after = service_task("after"),
    )
}

#[test]
fn a_receive_task_waits_for_its_message_and_never_fails() {
    let c = agree("receiving", &receiving());
    // Only a system's task fails; the error handler beside the receive task never runs.
    assert!(c.dead.contains("handle"), "{:?}", c.dead);
    assert!(!c.ends.contains("ee"), "{:?}", c.ends);
    assert!(c.ends.contains("e") && !c.deadlock, "{:?}", c.ends);
}

/// Two branches merged without a gateway into `merged`, which runs once per token; both leave
/// along one flow into `into`: a sub-process (`sub`) or a parallel multi-instance task.
fn doubled_into(sub: bool) -> String {
    let into = if sub {
        format!(
            r#"<subProcess id="into"><startEvent id="s1"/>{}<endEvent id="e1"/><sequenceFlow id="g0" sourceRef="s1" targetRef="inner"/><sequenceFlow id="g1" sourceRef="inner" targetRef="e1"/></subProcess>"#,
            service_task("inner")
        )
    } else {
        r#"<serviceTask id="into"><extensionElements><trace:task resource="r.into"/></extensionElements><multiInstanceLoopCharacteristics isSequential="false"><loopCardinality xsi:type="tFormalExpression">2</loopCardinality></multiInstanceLoopCharacteristics></serviceTask>"#.to_owned()
    };
    merged_twice(&format!(
        r#"{into}
    <sequenceFlow id="f5" sourceRef="merged" targetRef="into"/>
    <sequenceFlow id="f6" sourceRef="into" targetRef="e"/>"#
    ))
}

#[test]
fn a_second_token_into_a_running_sub_process_or_multi_instance_task_is_unsafe() {
    for sub in [true, false] {
        let c = agree(&format!("doubled-into-{sub}"), &doubled_into(sub));
        assert!(c.unsafe_run, "sub-process {sub}");
        assert!(c.ends.contains("e"), "sub-process {sub}: {:?}", c.ends);
    }
}

/// The main path waits for a signal nothing throws, while the outside may send messages to a
/// non-interrupting event sub-process (`esp`) or boundary event on the waiting sub-process.
fn stuck_beside_messages(esp: bool) -> String {
    let beside = if esp {
        format!(
            r#"<subProcess id="esp" triggeredByEvent="true"><startEvent id="es" isInterrupting="false"><messageEventDefinition messageRef="STATUS"/></startEvent>{}<endEvent id="ee"/><sequenceFlow id="h0" sourceRef="es" targetRef="report"/><sequenceFlow id="h1" sourceRef="report" targetRef="ee"/></subProcess>"#,
            service_task("report")
        )
    } else {
        format!(
            r#"<boundaryEvent id="b" attachedToRef="sp" cancelActivity="false"><messageEventDefinition messageRef="STATUS"/></boundaryEvent>{}<endEvent id="ee"/><sequenceFlow id="h0" sourceRef="b" targetRef="report"/><sequenceFlow id="h1" sourceRef="report" targetRef="ee"/>"#,
            service_task("report")
        )
    };
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <subProcess id="sp">
      <startEvent id="s1"/>
      <intermediateCatchEvent id="never"><signalEventDefinition signalRef="RESULT"/></intermediateCatchEvent>
      <endEvent id="e1"/>
      <sequenceFlow id="g0" sourceRef="s1" targetRef="never"/>
      <sequenceFlow id="g1" sourceRef="never" targetRef="e1"/>
    </subProcess>
    {beside}
    <endEvent id="e"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="sp"/>
    <sequenceFlow id="f1" sourceRef="sp" targetRef="e"/>
  </process>"#
    )
}

#[test]
fn a_mission_stuck_beside_a_repeating_message_event_deadlocks_once_the_outside_has_had_its_turns() {
    for esp in [true, false] {
        let c = agree(&format!("stuck-{esp}"), &stuck_beside_messages(esp));
        assert!(c.deadlock, "event sub-process {esp}");
        assert!(
            c.ends.contains("ee") && !c.ends.contains("e"),
            "{:?}",
            c.ends
        );
    }
}

/// A sub-process run twice by `looping` (each body signals `result` at its end) beside a branch
/// that waits for two such signals.
fn counted(looping: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <subProcess id="many">
      {looping}
      <startEvent id="s1"/>
      {work}
      <intermediateThrowEvent id="tell"><signalEventDefinition signalRef="RESULT"/></intermediateThrowEvent>
      <endEvent id="e1"/>
      <sequenceFlow id="g0" sourceRef="s1" targetRef="work"/>
      <sequenceFlow id="g1" sourceRef="work" targetRef="tell"/>
      <sequenceFlow id="g2" sourceRef="tell" targetRef="e1"/>
    </subProcess>
    <intermediateCatchEvent id="first"><signalEventDefinition signalRef="RESULT"/></intermediateCatchEvent>
    <intermediateCatchEvent id="second"><signalEventDefinition signalRef="RESULT"/></intermediateCatchEvent>
    {both}
    <endEvent id="e"/>
    <endEvent id="done"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f1" sourceRef="fork" targetRef="many"/>
    <sequenceFlow id="f2" sourceRef="many" targetRef="e"/>
    <sequenceFlow id="f3" sourceRef="fork" targetRef="first"/>
    <sequenceFlow id="f4" sourceRef="first" targetRef="second"/>
    <sequenceFlow id="f5" sourceRef="second" targetRef="both"/>
    <sequenceFlow id="f6" sourceRef="both" targetRef="done"/>
  </process>"#,
        work = service_task("work"),
        both = service_task("both"),
    )
}

#[test]
fn a_count_written_as_a_number_runs_exactly_that_many_bodies() {
    let each = |sequential| {
        format!(
            r#"<multiInstanceLoopCharacteristics isSequential="{sequential}"><loopCardinality xsi:type="tFormalExpression">2</loopCardinality></multiInstanceLoopCharacteristics>"#
        )
    };
    for (name, looping) in [
        ("sequential", each(true)),
        ("parallel", each(false)),
        (
            "loop",
            r#"<standardLoopCharacteristics loopMaximum="2"/>"#.to_owned(),
        ),
    ] {
        // Two bodies, two signals: the waiting branch always goes on (one body would leave it
        // stuck, which Spin found where it chose one and the engine always ran one).
        let c = agree(&format!("counted-{name}"), &counted(&looping));
        assert!(!c.deadlock, "{name}");
        assert!(
            c.ends.contains("done") && !c.dead.contains("both"),
            "{name}: {:?}",
            c.ends
        );
    }
}

/// After preparing, the lander sends the orbiter a sample along each of `sends` branches in one
/// step, beside a task; with `fails`, each branch then ends in an error nothing catches, in the same step.
fn lander_and_orbiter(sends: usize, fails: bool) -> String {
    let error = if fails {
        r#"<errorEventDefinition errorRef="JAM"/>"#
    } else {
        ""
    };
    let branches: String = (0..sends)
        .map(|k| {
            format!(
                r#"<intermediateThrowEvent id="send{k}"><messageEventDefinition messageRef="SAMPLE"/></intermediateThrowEvent><sequenceFlow id="l{k}" sourceRef="fork" targetRef="send{k}"/><sequenceFlow id="n{k}" sourceRef="send{k}" targetRef="sent{k}"/><endEvent id="sent{k}">{error}</endEvent>"#
            )
        })
        .collect();
    let flows: String = (0..sends)
        .map(|k| format!(r#"<messageFlow id="m{k}" sourceRef="send{k}" targetRef="wake"/>"#))
        .collect();
    format!(
        r#"<collaboration id="c">
    <participant id="lander_pool" processRef="lander"/>
    <participant id="orbiter_pool" processRef="orbiter"/>
    {flows}
  </collaboration>
  <process id="lander" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    {branches}
    {prepare}
    {work}
    <endEvent id="done"/>
    <sequenceFlow id="l8" sourceRef="s" targetRef="prepare"/>
    <sequenceFlow id="l9" sourceRef="prepare" targetRef="fork"/>
    <sequenceFlow id="w1" sourceRef="fork" targetRef="work"/>
    <sequenceFlow id="w2" sourceRef="work" targetRef="done"/>
  </process>
  <process id="orbiter" isExecutable="true">
    <startEvent id="wake"><messageEventDefinition messageRef="SAMPLE"/></startEvent>
    {relay}
    <endEvent id="relayed"/>
    <sequenceFlow id="o1" sourceRef="wake" targetRef="relay"/>
    <sequenceFlow id="o2" sourceRef="relay" targetRef="relayed"/>
  </process>"#,
        prepare = service_task("prepare"),
        work = service_task("work"),
        relay = service_task("relay"),
    )
}

#[test]
fn a_second_message_to_a_running_process_is_lost_and_the_sender_goes_on() {
    // Both samples leave in one step: the orbiter's process runs once (one instance at a time,
    // the second message lost), and the lander's work goes on (the exploration used to drop
    // the whole run, so nothing after it was reached).
    let c = agree("two-samples", &lander_and_orbiter(2, false));
    assert!(!c.deadlock);
    assert_eq!(c.ends, set(&["done", "relayed", "sent0", "sent1"]));
}

#[test]
fn an_uncaught_error_fails_its_own_process_and_another_pool_runs_on() {
    // The lander's error, in the step that sent the sample, ends the lander only: the orbiter,
    // started by the message, relays (Spin used to clear every process).
    let c = agree("failing-lander", &lander_and_orbiter(1, true));
    assert_eq!(c.ends, set(&["relayed", "sent0"]));
}
