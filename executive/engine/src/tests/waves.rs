//! Chapter 13 semantics: what happens within one step (rules in docs/engine-semantics.md,
//! "Within a step").
//!
//! Tokens move in waves: the tokens made ready by one arrival move after every token that was
//! ready before it (§13.2's token game, breadth first). A throw — signal, error, escalation,
//! cancel, terminate, message — takes effect after the other tokens of its wave have arrived,
//! and before anything their arrivals made ready. Every pair of throw kind and sibling kind is
//! tried: the sibling beside the throw is entered before the throw acts, and what comes after
//! the sibling is not.

use super::*;

/// A throw kind: the thrower (id `T`), the scope it sits in (`{inner}` is the fork and the
/// branches), and the record entry its effect writes first.
struct Throw {
    name: &'static str,
    globals: &'static str,
    thrower: &'static str,
    scope: &'static str,
    effect: &'static str,
}

const THROWS: [Throw; 5] = [
    Throw {
        name: "terminate",
        globals: "",
        thrower: r#"<endEvent id="T"><terminateEventDefinition/></endEvent>"#,
        scope: "{inner}",
        effect: "withdrawn:",
    },
    Throw {
        name: "error",
        globals: r#"<error id="err" errorCode="E"/>"#,
        thrower: r#"<endEvent id="T"><errorEventDefinition errorRef="err"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><errorEventDefinition/></boundaryEvent>
            <endEvent id="caught"/><sequenceFlow id="fb" sourceRef="b" targetRef="caught"/>"#,
        effect: "caught:b",
    },
    Throw {
        name: "escalation",
        globals: r#"<escalation id="esc" escalationCode="X"/>"#,
        thrower: r#"<endEvent id="T"><escalationEventDefinition escalationRef="esc"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><escalationEventDefinition/></boundaryEvent>
            <endEvent id="caught"/><sequenceFlow id="fb" sourceRef="b" targetRef="caught"/>"#,
        effect: "caught:b",
    },
    Throw {
        name: "signal",
        globals: r#"<signal id="sig" name="S"/>"#,
        thrower: r#"<endEvent id="T"><signalEventDefinition signalRef="sig"/></endEvent>"#,
        scope: r#"<subProcess id="sub">{inner}</subProcess>
            <boundaryEvent id="b" attachedToRef="sub"><signalEventDefinition signalRef="sig"/></boundaryEvent>
            <endEvent id="caught"/><sequenceFlow id="fb" sourceRef="b" targetRef="caught"/>"#,
        effect: "caught:b",
    },
    Throw {
        name: "cancel",
        globals: "",
        thrower: r#"<endEvent id="T"><cancelEventDefinition/></endEvent>"#,
        scope: r#"<transaction id="sub">{inner}</transaction>
            <boundaryEvent id="b" attachedToRef="sub"><cancelEventDefinition/></boundaryEvent>
            <endEvent id="caught"/><sequenceFlow id="fb" sourceRef="b" targetRef="caught"/>"#,
        effect: "caught:b",
    },
];

/// A sibling kind: the element `X` beside the throw, and what comes after it (`next`).
struct Sibling {
    name: &'static str,
    element: &'static str,
    next: &'static str,
}

const SIBLINGS: [Sibling; 4] = [
    Sibling {
        name: "task",
        element: r#"<serviceTask id="X"><extensionElements><trace:task resource="r.x"/></extensionElements></serviceTask>
            <sequenceFlow id="fx" sourceRef="X" targetRef="after"/>"#,
        next: "after",
    },
    Sibling {
        name: "gateway",
        element: r#"<exclusiveGateway id="X"/><sequenceFlow id="fx" sourceRef="X" targetRef="after"/>"#,
        next: "after",
    },
    Sibling {
        name: "event",
        element: r#"<intermediateCatchEvent id="X"><timerEventDefinition><timeDuration>PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>
            <sequenceFlow id="fx" sourceRef="X" targetRef="after"/>"#,
        next: "after",
    },
    Sibling {
        name: "sub-process",
        element: r#"<subProcess id="X"><startEvent id="xs"/><endEvent id="xe"/><sequenceFlow id="fxs" sourceRef="xs" targetRef="xe"/></subProcess>
            <sequenceFlow id="fx" sourceRef="X" targetRef="after"/>"#,
        next: "xs",
    },
];

/// The model of one pair: a parallel split whose one branch throws and whose other enters the
/// sibling.
fn model(t: &Throw, s: &Sibling) -> String {
    let inner = format!(
        r#"<startEvent id="s"/><parallelGateway id="fork"/>{thrower}{sibling}
        <serviceTask id="after"><extensionElements><trace:task resource="r.after"/></extensionElements></serviceTask>
        <endEvent id="done"/>
        <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
        <sequenceFlow id="f1" sourceRef="fork" targetRef="T"/>
        <sequenceFlow id="f2" sourceRef="fork" targetRef="X"/>
        <sequenceFlow id="f3" sourceRef="after" targetRef="done"/>"#,
        thrower = t.thrower,
        sibling = s.element,
    );
    let scope = t.scope.replace("{inner}", &inner);
    // A throw that needs a scope to act on is inside a sub-process the process starts.
    let scope = if t.scope == "{inner}" {
        scope
    } else {
        format!(
            r#"<startEvent id="ps"/>{scope}<endEvent id="pe"/>
            <sequenceFlow id="p1" sourceRef="ps" targetRef="sub"/>
            <sequenceFlow id="p2" sourceRef="sub" targetRef="pe"/>"#
        )
    };
    format!(
        r#"{globals}<process id="p" isExecutable="true">{scope}</process>"#,
        globals = t.globals
    )
}

/// The entries the first step writes, as `entered:ID`, `withdrawn:ID`, `caught:ID`.
fn first_step(body: &str) -> Vec<String> {
    let mut e = engine(body);
    let actions = first_start(&mut e);
    let g = Arc::clone(e.graph());
    actions
        .into_iter()
        .filter_map(|a| match a {
            Action::Record(r) => match r.entry {
                Entry::Entered { node, .. } => Some(format!("entered:{}", g.node(node).id)),
                Entry::Withdrawn { node, .. } => Some(format!("withdrawn:{}", g.node(node).id)),
                Entry::Caught { node, .. } => Some(format!("caught:{}", g.node(node).id)),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

#[test]
fn a_throw_acts_after_its_waves_siblings_have_arrived_and_before_what_they_start() {
    for t in &THROWS {
        for s in &SIBLINGS {
            let body = model(t, s);
            let entries = first_step(&body);
            let pair = format!("{} beside a {}", t.name, s.name);
            let at = |what: &str| entries.iter().position(|e| e.starts_with(what));
            let thrown = at("entered:T").unwrap_or_else(|| panic!("{pair}: {entries:?}"));
            let effect = entries
                .iter()
                .skip(thrown)
                .position(|e| e.starts_with(t.effect))
                .map(|i| i + thrown)
                .unwrap_or_else(|| panic!("{pair}: no {} in {entries:?}", t.effect));
            let sibling = at("entered:X").unwrap_or_else(|| panic!("{pair}: {entries:?}"));
            assert!(
                sibling < effect,
                "{pair}: the sibling after the throw: {entries:?}"
            );
            assert!(
                at(&format!("entered:{}", s.next)).is_none_or(|n| n > effect),
                "{pair}: `{}` moved before the throw acted: {entries:?}",
                s.next
            );
        }
    }
}

#[test]
fn a_message_thrown_beside_its_catcher_is_caught_in_the_same_step() {
    // The catch event is reached in the throw's wave: it waits before the message goes.
    let body = r#"<message id="m" name="M"/>
        <process id="p" isExecutable="true">
          <startEvent id="s"/><parallelGateway id="fork"/>
          <intermediateThrowEvent id="T"><messageEventDefinition messageRef="m"/></intermediateThrowEvent>
          <intermediateCatchEvent id="X"><messageEventDefinition messageRef="m"/></intermediateCatchEvent>
          <endEvent id="e1"/><endEvent id="e2"/>
          <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
          <sequenceFlow id="f1" sourceRef="fork" targetRef="T"/>
          <sequenceFlow id="f2" sourceRef="fork" targetRef="X"/>
          <sequenceFlow id="f3" sourceRef="T" targetRef="e1"/>
          <sequenceFlow id="f4" sourceRef="X" targetRef="e2"/>
        </process>"#;
    let entries = first_step(body);
    assert!(
        entries.contains(&"caught:X".to_owned()) && entries.contains(&"entered:e2".to_owned()),
        "{entries:?}"
    );
}

#[test]
fn a_throw_alone_in_its_wave_acts_at_once() {
    // Nothing else moves with it: the terminate acts when it arrives, before the sub-process
    // the split started beside it in an earlier wave has its start event moved on.
    let body = r#"<process id="p" isExecutable="true">
          <startEvent id="s"/><parallelGateway id="fork"/>
          <subProcess id="X"><startEvent id="xs"/><intermediateCatchEvent id="xc"><timerEventDefinition><timeDuration>PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>
            <sequenceFlow id="x1" sourceRef="xs" targetRef="xc"/></subProcess>
          <endEvent id="T"><terminateEventDefinition/></endEvent>
          <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
          <sequenceFlow id="f1" sourceRef="fork" targetRef="X"/>
          <sequenceFlow id="f2" sourceRef="fork" targetRef="T"/>
        </process>"#;
    let entries = first_step(body);
    assert!(!entries.contains(&"entered:xc".to_owned()), "{entries:?}");
}

#[test]
fn a_deferred_throw_keeps_its_place_before_the_next_wave() {
    // Three tokens in one wave: a gateway before the throw, a task after it. The gateway's
    // token moves on first (its next token is of the next wave); the throw, put back behind
    // the task, still acts before that next-wave token arrives.
    let body = r#"<process id="p" isExecutable="true">
          <startEvent id="s"/><parallelGateway id="fork"/>
          <exclusiveGateway id="A"/>
          <serviceTask id="a2"><extensionElements><trace:task resource="r.a"/></extensionElements></serviceTask>
          <endEvent id="T"><terminateEventDefinition/></endEvent>
          <serviceTask id="B"><extensionElements><trace:task resource="r.b"/></extensionElements></serviceTask>
          <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
          <sequenceFlow id="f1" sourceRef="fork" targetRef="A"/>
          <sequenceFlow id="f2" sourceRef="fork" targetRef="T"/>
          <sequenceFlow id="f3" sourceRef="fork" targetRef="B"/>
          <sequenceFlow id="f4" sourceRef="A" targetRef="a2"/>
        </process>"#;
    let entries = first_step(body);
    assert!(entries.contains(&"entered:B".to_owned()), "{entries:?}");
    assert!(!entries.contains(&"entered:a2".to_owned()), "{entries:?}");
}

#[test]
fn throwers_of_one_wave_act_in_the_order_they_arrived() {
    // The signal thrower arrives first and is put back behind the terminate; the terminate,
    // put back behind it in turn, acts second: the signal has started the process's event
    // sub-process by then, and the terminate ends only the sub-process around both.
    let body = r#"<signal id="sig" name="S"/>
        <process id="p" isExecutable="true">
          <startEvent id="ps"/>
          <subProcess id="sub">
            <startEvent id="s"/><parallelGateway id="fork"/>
            <intermediateThrowEvent id="T"><signalEventDefinition signalRef="sig"/></intermediateThrowEvent>
            <endEvent id="te"/>
            <endEvent id="stop"><terminateEventDefinition/></endEvent>
            <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
            <sequenceFlow id="f1" sourceRef="fork" targetRef="T"/>
            <sequenceFlow id="f2" sourceRef="fork" targetRef="stop"/>
            <sequenceFlow id="f3" sourceRef="T" targetRef="te"/>
          </subProcess>
          <endEvent id="pe"/>
          <sequenceFlow id="p1" sourceRef="ps" targetRef="sub"/>
          <sequenceFlow id="p2" sourceRef="sub" targetRef="pe"/>
          <subProcess id="esp" triggeredByEvent="true">
            <startEvent id="es" isInterrupting="false"><signalEventDefinition signalRef="sig"/></startEvent>
            <serviceTask id="X"><extensionElements><trace:task resource="r.x"/></extensionElements></serviceTask>
            <sequenceFlow id="e1" sourceRef="es" targetRef="X"/>
          </subProcess>
        </process>"#;
    let entries = first_step(body);
    assert!(entries.contains(&"entered:X".to_owned()), "{entries:?}");
    assert!(!entries.contains(&"entered:te".to_owned()), "{entries:?}");
}
