//! What happens within a step, in Spin and in the engine alike: for every pair of throw kind and
//! sibling kind (a parallel split whose one branch throws and whose other enters the sibling),
//! Spin on the PROMELA translation and the engine's own exploration agree exactly on deadlocks,
//! unsafe runs, dead activities and end events (docs/engine-semantics.md, "Within a step").

use crate::protocol::tempdir;
use crate::verify::{Compared, Comparison, compare};

/// A throw kind: the thrower `T` and the scope around the split (`{inner}`).
struct Throw {
    name: &'static str,
    globals: &'static str,
    thrower: &'static str,
    scope: &'static str,
}

const CAUGHT: &str =
    r#"<endEvent id="caught"/><sequenceFlow id="fb" sourceRef="b" targetRef="caught"/>"#;

const THROWS: [Throw; 7] = [
    Throw {
        name: "terminate",
        globals: "",
        thrower: r#"<endEvent id="T"><terminateEventDefinition/></endEvent>"#,
        scope: "{inner}",
    },
    Throw {
        name: "error",
        globals: r#"<error id="err" errorCode="E"/>"#,
        thrower: r#"<endEvent id="T"><errorEventDefinition errorRef="err"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><errorEventDefinition errorRef="err"/></boundaryEvent>{caught}"#,
    },
    Throw {
        name: "escalation",
        globals: r#"<escalation id="esc" escalationCode="X"/>"#,
        thrower: r#"<endEvent id="T"><escalationEventDefinition escalationRef="esc"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><escalationEventDefinition escalationRef="esc"/></boundaryEvent>{caught}"#,
    },
    Throw {
        name: "signal to a boundary",
        globals: r#"<signal id="sig" name="S"/>"#,
        thrower: r#"<endEvent id="T"><signalEventDefinition signalRef="sig"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><signalEventDefinition signalRef="sig"/></boundaryEvent>{caught}"#,
    },
    Throw {
        // The issue's model: the signal starts an interrupting event sub-process.
        name: "signal to an event sub-process",
        globals: r#"<signal id="sig" name="S"/>"#,
        thrower: r#"<intermediateThrowEvent id="T"><signalEventDefinition signalRef="sig"/></intermediateThrowEvent>
            <endEvent id="te"/><sequenceFlow id="ft" sourceRef="T" targetRef="te"/>"#,
        scope: r#"{inner}<subProcess id="esp" triggeredByEvent="true">
            <startEvent id="es"><signalEventDefinition signalRef="sig"/></startEvent>
            <endEvent id="ee"/><sequenceFlow id="fe" sourceRef="es" targetRef="ee"/></subProcess>"#,
    },
    Throw {
        name: "cancel",
        globals: "",
        thrower: r#"<endEvent id="T"><cancelEventDefinition/></endEvent>"#,
        scope: r#"<transaction id="sub">{inner}</transaction>
            <boundaryEvent id="b" attachedToRef="sub"><cancelEventDefinition/></boundaryEvent>{caught}"#,
    },
    Throw {
        name: "escalation to an event sub-process",
        globals: r#"<escalation id="esc" escalationCode="X"/>"#,
        thrower: r#"<endEvent id="T"><escalationEventDefinition escalationRef="esc"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}<subProcess id="esp" triggeredByEvent="true">
            <startEvent id="es"><escalationEventDefinition escalationRef="esc"/></startEvent>
            <endEvent id="ee"/><sequenceFlow id="fe" sourceRef="es" targetRef="ee"/></subProcess></subProcess>"#,
    },
];

/// A sibling kind: the element `X` beside the throw; `after` follows it.
const SIBLINGS: [(&str, &str); 4] = [
    (
        "task",
        r#"<serviceTask id="X"><extensionElements><trace:task resource="r.x"/></extensionElements></serviceTask>"#,
    ),
    ("gateway", r#"<exclusiveGateway id="X"/>"#),
    (
        "event",
        r#"<intermediateCatchEvent id="X"><timerEventDefinition><timeDuration>PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>"#,
    ),
    (
        "sub-process",
        r#"<subProcess id="X"><startEvent id="xs"/><serviceTask id="xt"><extensionElements><trace:task resource="r.xt"/></extensionElements></serviceTask><endEvent id="xe"/>
            <sequenceFlow id="fx1" sourceRef="xs" targetRef="xt"/><sequenceFlow id="fx2" sourceRef="xt" targetRef="xe"/></subProcess>"#,
    ),
];

/// The model of one pair.
fn model(t: &Throw, sibling: &str) -> String {
    let inner = format!(
        r#"<startEvent id="s"/><parallelGateway id="fork"/>{thrower}{sibling}
        <serviceTask id="after"><extensionElements><trace:task resource="r.after"/></extensionElements></serviceTask>
        <endEvent id="done"/>
        <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
        <sequenceFlow id="f1" sourceRef="fork" targetRef="T"/>
        <sequenceFlow id="f2" sourceRef="fork" targetRef="X"/>
        <sequenceFlow id="fx" sourceRef="X" targetRef="after"/>
        <sequenceFlow id="f3" sourceRef="after" targetRef="done"/>"#,
        thrower = t.thrower,
    );
    let scope = t
        .scope
        .replace("{inner}", &inner)
        .replace("{caught}", CAUGHT);
    let scope = if t.scope.starts_with("<subProcess") || t.scope.starts_with("<transaction") {
        format!(
            r#"<startEvent id="ps"/>{scope}<endEvent id="pe"/>
            <sequenceFlow id="p1" sourceRef="ps" targetRef="sub"/>
            <sequenceFlow id="p2" sourceRef="sub" targetRef="pe"/>"#
        )
    } else {
        scope
    };
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:waves">
  {globals}<process id="p" isExecutable="true">{scope}</process>
</definitions>"#,
        globals = t.globals
    )
}

/// Spin and the engine on `xml`: they must agree exactly.
pub(crate) fn agree(name: &str, xml: &str) -> Comparison {
    let loaded = executive_model::load(xml.as_bytes());
    let graph = loaded
        .graph
        .unwrap_or_else(|| panic!("{name}: invalid: {:?}", loaded.diagnostics));
    match compare(
        graph,
        &tempdir(&format!("waves-{}", name.replace(' ', "-"))),
    ) {
        Compared::Refused(why) => panic!("{name}: not translated: {why}"),
        Compared::NeedsData => panic!("{name}: the engine could not be explored"),
        Compared::Done(c) => {
            assert!(
                c.how.is_empty(),
                "{name}: Spin and the engine differ: {:?}\n{xml}",
                c.how
            );
            c
        }
    }
}

#[test]
fn spin_and_the_engine_agree_on_every_throw_beside_every_sibling() {
    for t in &THROWS {
        for (kind, sibling) in SIBLINGS {
            let pair = format!("{} beside a {kind}", t.name);
            let c = agree(&pair, &model(t, sibling));
            // The sibling is entered before the throw acts; what follows it never is.
            assert!(!c.dead.contains("X"), "{pair}: {:?}", c.dead);
            assert!(c.dead.contains("after"), "{pair}: {:?}", c.dead);
            if kind == "sub-process" {
                assert!(c.dead.contains("xt"), "{pair}: {:?}", c.dead);
            }
        }
    }
}
