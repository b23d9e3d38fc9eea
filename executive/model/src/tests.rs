//! Unit tests of the loader: one small model per element kind, one per diagnostic.

use crate::*;

const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL"
  xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0"
  xmlns:zeebe="http://camunda.org/schema/zeebe/1.0" xmlns:camunda="http://camunda.org/schema/1.0/bpmn"
  xmlns:spiffworkflow="http://spiffworkflow.org/bpmn/schema/1.0/core"
  id="d" targetNamespace="urn:test">"#;

/// A document with `globals` at definitions level and `body` inside process `p`.
fn doc(globals: &str, body: &str) -> String {
    format!(
        r#"{HEAD}{globals}<bpmn:process id="p" isExecutable="true">{body}</bpmn:process></bpmn:definitions>"#
    )
}

/// start -> `middle` (elements with id `x`) -> end, with flows s->x and x->e.
fn around(middle: &str) -> String {
    doc(
        "",
        &format!(
            r#"<bpmn:startEvent id="s"/>{middle}<bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="e"/>"#
        ),
    )
}

fn ok(xml: &str) -> ProcessGraph {
    let loaded = load(xml.as_bytes());
    match loaded.graph {
        Some(g) => g,
        None => panic!("expected a valid model, got {:#?}", loaded.diagnostics),
    }
}

/// The codes of the errors found in `xml`.
fn errors(xml: &str) -> Vec<&'static str> {
    load(xml.as_bytes()).errors().map(|d| d.code).collect()
}

fn kind<'g>(g: &'g ProcessGraph, id: &str) -> &'g NodeKind {
    &g.node(g.node_by_id(id).expect("node exists")).kind
}

#[test]
fn tasks_of_every_kind() {
    for (tag, want) in [
        ("task", TaskKind::Plain),
        ("manualTask", TaskKind::Manual),
        ("receiveTask", TaskKind::Receive),
        ("userTask", TaskKind::User),
    ] {
        let g = ok(&around(&format!(r#"<bpmn:{tag} id="x"/>"#)));
        assert!(
            matches!(kind(&g, "x"), NodeKind::Task(t) if t.kind == want),
            "{tag}"
        );
    }
    let service = r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><trace:task resource="arm.stow"/></bpmn:extensionElements></bpmn:serviceTask>"#;
    let g = ok(&around(service));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!()
    };
    assert_eq!(
        t.binding.as_ref().and_then(|b| b.resource.as_deref()),
        Some("arm.stow")
    );
    let script = r#"<bpmn:scriptTask id="x" scriptFormat="cel"><bpmn:script>n = 1; m = n + 1</bpmn:script></bpmn:scriptTask>"#;
    let g = ok(&around(script));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!()
    };
    assert_eq!(
        t.script
            .as_ref()
            .and_then(|s| s.assignments.as_ref())
            .map(Vec::len),
        Some(2)
    );
}

#[test]
fn task_bindings_in_three_dialects() {
    let ours = r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><trace:task resource="excavation.excavate">
        <trace:input target="selected_site.site_id" source="site.id" type="int"/>
        <trace:output source="achieved_depth_cm" target="depth" type="f64"/></trace:task></bpmn:extensionElements></bpmn:serviceTask>"#;
    let zeebe = r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><zeebe:taskDefinition type="excavate" retries="3"/>
        <zeebe:ioMapping><zeebe:input source="=site.id" target="site_id"/><zeebe:output source="=depth" target="depth"/></zeebe:ioMapping>
        </bpmn:extensionElements></bpmn:serviceTask>"#;
    let camunda = r#"<bpmn:serviceTask id="x" camunda:type="external" camunda:topic="excavate"><bpmn:extensionElements>
        <camunda:inputOutput><camunda:inputParameter name="site_id">${site.id}</camunda:inputParameter>
        <camunda:inputParameter name="mode">fast</camunda:inputParameter></camunda:inputOutput></bpmn:extensionElements></bpmn:serviceTask>"#;
    for (xml, resource, inputs) in [
        (ours, "excavation.excavate", 1),
        (zeebe, "excavate", 1),
        (camunda, "excavate", 2),
    ] {
        let g = ok(&around(xml));
        let NodeKind::Task(t) = kind(&g, "x") else {
            panic!()
        };
        let b = t.binding.as_ref().expect("binding");
        assert_eq!(b.resource.as_deref(), Some(resource));
        assert_eq!(b.inputs.len(), inputs);
    }
    let g = ok(&around(ours));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!()
    };
    let b = t.binding.as_ref().unwrap();
    assert_eq!(b.inputs[0].target, "selected_site.site_id");
    assert_eq!(b.inputs[0].ty, Some(binding::FieldType::Int));
    assert_eq!(b.outputs[0].source.text, "achieved_depth_cm");
    // A Camunda static value is a string literal.
    let g = ok(&around(camunda));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!()
    };
    assert_eq!(
        t.binding.as_ref().unwrap().inputs[1].source.text,
        "\"fast\""
    );
}

#[test]
fn gateways_of_every_kind() {
    for (tag, want) in [
        ("exclusiveGateway", GatewayKind::Exclusive),
        ("inclusiveGateway", GatewayKind::Inclusive),
        ("parallelGateway", GatewayKind::Parallel),
        ("complexGateway", GatewayKind::Complex),
    ] {
        let xml = doc(
            "",
            &format!(
                r#"<bpmn:startEvent id="s"/><bpmn:{tag} id="g"/><bpmn:{tag} id="j"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/>
            <bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="j"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a &gt; 1</bpmn:conditionExpression></bpmn:sequenceFlow>
            <bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="j"/><bpmn:sequenceFlow id="f3" sourceRef="j" targetRef="e"/>"#
            ),
        );
        let xml = xml.replace(
            &format!(r#"<bpmn:{tag} id="g"/>"#),
            &format!(r#"<bpmn:{tag} id="g" default="f2"/>"#),
        );
        let xml = xml.replace(r#"<bpmn:complexGateway id="j"/>"#, r#"<bpmn:complexGateway id="j"><bpmn:activationCondition xsi:type="bpmn:tFormalExpression">activationCount &gt;= 1</bpmn:activationCondition></bpmn:complexGateway>"#);
        let xml = if tag == "parallelGateway" {
            xml.replace(r#" default="f2""#, "").replace(r#"<bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a &gt; 1</bpmn:conditionExpression>"#, "")
        } else {
            xml
        };
        let g = ok(&xml);
        assert!(
            matches!(kind(&g, "g"), NodeKind::Gateway(gw) if gw.kind == want),
            "{tag}"
        );
    }
    let eb = doc(
        "<bpmn:message id=\"m\" name=\"go\"/>",
        r#"<bpmn:startEvent id="s"/><bpmn:eventBasedGateway id="g"/>
        <bpmn:intermediateCatchEvent id="c1"><bpmn:messageEventDefinition messageRef="m"/></bpmn:intermediateCatchEvent>
        <bpmn:intermediateCatchEvent id="c2"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT5M</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>
        <bpmn:endEvent id="e"/>
        <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="c1"/>
        <bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="c2"/><bpmn:sequenceFlow id="f3" sourceRef="c1" targetRef="e"/>
        <bpmn:sequenceFlow id="f4" sourceRef="c2" targetRef="e"/>"#,
    );
    let g = ok(&eb);
    assert!(
        matches!(kind(&g, "g"), NodeKind::Gateway(gw) if gw.kind == GatewayKind::EventBased { parallel: false })
    );
}

#[test]
fn events_with_every_definition() {
    let globals = r#"<bpmn:message id="m" name="msg"/><bpmn:signal id="sig" name="BATTERY_LOW"/>
        <bpmn:error id="err" errorCode="TOOL_STUCK"/><bpmn:escalation id="esc" escalationCode="FAILED"/>"#;
    let body = r#"<bpmn:startEvent id="s"/>
        <bpmn:intermediateThrowEvent id="t1"><bpmn:signalEventDefinition signalRef="sig"/></bpmn:intermediateThrowEvent>
        <bpmn:intermediateThrowEvent id="t2"><bpmn:escalationEventDefinition escalationRef="esc"/></bpmn:intermediateThrowEvent>
        <bpmn:intermediateCatchEvent id="c1"><bpmn:messageEventDefinition messageRef="m"/></bpmn:intermediateCatchEvent>
        <bpmn:intermediateCatchEvent id="c2"><bpmn:conditionalEventDefinition><bpmn:condition xsi:type="bpmn:tFormalExpression">battery.soc &lt; 30.0</bpmn:condition></bpmn:conditionalEventDefinition></bpmn:intermediateCatchEvent>
        <bpmn:intermediateCatchEvent id="c3"><bpmn:timerEventDefinition><bpmn:timeCycle xsi:type="bpmn:tFormalExpression">R3/PT1H</bpmn:timeCycle></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>
        <bpmn:intermediateThrowEvent id="l1"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateThrowEvent>
        <bpmn:intermediateCatchEvent id="l2"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateCatchEvent>
        <bpmn:task id="a"/>
        <bpmn:boundaryEvent id="b1" attachedToRef="a"><bpmn:errorEventDefinition errorRef="err" trace:errorCodeVariable="code"/></bpmn:boundaryEvent>
        <bpmn:boundaryEvent id="b2" attachedToRef="a" cancelActivity="false"><bpmn:signalEventDefinition signalRef="sig"/></bpmn:boundaryEvent>
        <bpmn:endEvent id="e"><bpmn:terminateEventDefinition/></bpmn:endEvent>
        <bpmn:endEvent id="e2"><bpmn:errorEventDefinition errorRef="err"/></bpmn:endEvent>
        <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t1"/><bpmn:sequenceFlow id="f2" sourceRef="t1" targetRef="t2"/>
        <bpmn:sequenceFlow id="f3" sourceRef="t2" targetRef="c1"/><bpmn:sequenceFlow id="f4" sourceRef="c1" targetRef="c2"/>
        <bpmn:sequenceFlow id="f5" sourceRef="c2" targetRef="c3"/><bpmn:sequenceFlow id="f6" sourceRef="c3" targetRef="l1"/>
        <bpmn:sequenceFlow id="f7" sourceRef="l2" targetRef="a"/><bpmn:sequenceFlow id="f8" sourceRef="a" targetRef="e"/>
        <bpmn:sequenceFlow id="f9" sourceRef="b1" targetRef="e2"/><bpmn:sequenceFlow id="f10" sourceRef="b2" targetRef="e"/>"#;
    let g = ok(&doc(globals, body));
    assert!(
        matches!(kind(&g, "t1"), NodeKind::Throw(r) if matches!(r[..], [EventDefinition::Signal(Some(_))]))
    );
    assert!(
        matches!(kind(&g, "c2"), NodeKind::Catch(c) if matches!(&c.triggers[..], [EventDefinition::Conditional(e)] if e.variables == ["battery"]))
    );
    assert!(
        matches!(kind(&g, "c3"), NodeKind::Catch(c) if matches!(&c.triggers[..], [EventDefinition::Timer(_)]))
    );
    assert!(
        matches!(kind(&g, "b1"), NodeKind::Boundary(b) if b.interrupting && matches!(&b.triggers[..], [EventDefinition::Error { code_variable: Some(v), .. }] if v == "code"))
    );
    assert!(matches!(kind(&g, "b2"), NodeKind::Boundary(b) if !b.interrupting));
    let a = g.node(g.node_by_id("a").unwrap());
    assert_eq!(a.boundaries.len(), 2);
    assert!(
        matches!(kind(&g, "e"), NodeKind::End(r) if matches!(r[..], [EventDefinition::Terminate]))
    );
}

#[test]
fn subprocesses_call_activities_and_loops() {
    let body = r#"<bpmn:startEvent id="s"/>
        <bpmn:subProcess id="sub"><bpmn:startEvent id="s2"/><bpmn:task id="inner"/><bpmn:endEvent id="e2"/>
          <bpmn:sequenceFlow id="g1" sourceRef="s2" targetRef="inner"/><bpmn:sequenceFlow id="g2" sourceRef="inner" targetRef="e2"/>
          <bpmn:multiInstanceLoopCharacteristics isSequential="true"><bpmn:loopCardinality xsi:type="bpmn:tFormalExpression">3</bpmn:loopCardinality>
          <bpmn:completionCondition xsi:type="bpmn:tFormalExpression">nrOfCompletedInstances &gt;= 2</bpmn:completionCondition></bpmn:multiInstanceLoopCharacteristics>
        </bpmn:subProcess>
        <bpmn:callActivity id="call" calledElement="q"><bpmn:standardLoopCharacteristics testBefore="true" loopMaximum="5">
          <bpmn:loopCondition xsi:type="bpmn:tFormalExpression">n &lt; 3</bpmn:loopCondition></bpmn:standardLoopCharacteristics></bpmn:callActivity>
        <bpmn:transaction id="tx"><bpmn:startEvent id="s3"/><bpmn:endEvent id="e3"/><bpmn:sequenceFlow id="h1" sourceRef="s3" targetRef="e3"/></bpmn:transaction>
        <bpmn:adHocSubProcess id="adhoc" ordering="Sequential"><bpmn:task id="free"/></bpmn:adHocSubProcess>
        <bpmn:subProcess id="esp" triggeredByEvent="true"><bpmn:startEvent id="s4" isInterrupting="false">
          <bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1H</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:startEvent>
          <bpmn:endEvent id="e4"/><bpmn:sequenceFlow id="k1" sourceRef="s4" targetRef="e4"/></bpmn:subProcess>
        <bpmn:endEvent id="e"/>
        <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="sub"/><bpmn:sequenceFlow id="f2" sourceRef="sub" targetRef="call"/>
        <bpmn:sequenceFlow id="f3" sourceRef="call" targetRef="tx"/><bpmn:sequenceFlow id="f4" sourceRef="tx" targetRef="adhoc"/>
        <bpmn:sequenceFlow id="f5" sourceRef="adhoc" targetRef="e"/>"#;
    let called = r#"<bpmn:process id="q" isExecutable="true"><bpmn:startEvent id="qs"/><bpmn:endEvent id="qe"/>
        <bpmn:sequenceFlow id="q1" sourceRef="qs" targetRef="qe"/></bpmn:process>"#;
    let xml = doc("", body).replace(
        "</bpmn:definitions>",
        &format!("{called}</bpmn:definitions>"),
    );
    let g = ok(&xml);
    let sub = g.node_by_id("sub").unwrap();
    assert!(
        matches!(&g.node(sub).looping, Some(Looping::MultiInstance(m)) if m.sequential && m.completion.is_some())
    );
    assert_eq!(
        g.node(g.node_by_id("inner").unwrap()).scope,
        Scope::SubProcess(sub)
    );
    assert!(
        matches!(kind(&g, "call"), NodeKind::CallActivity(c) if c.called == Some(Called::Process(g.process_by_id("q").unwrap())))
    );
    assert!(matches!(
        &g.node(g.node_by_id("call").unwrap()).looping,
        Some(Looping::Standard {
            test_before: true,
            maximum: Some(5),
            condition: Some(_)
        })
    ));
    assert!(
        matches!(kind(&g, "tx"), NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::Transaction))
    );
    assert!(
        matches!(kind(&g, "adhoc"), NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::AdHoc { sequential: true, .. }))
    );
    assert!(
        matches!(kind(&g, "esp"), NodeKind::SubProcess(s) if matches!(s.kind, SubProcessKind::Event))
    );
    // The called process is not started with the mission.
    assert_eq!(g.primary_processes(), vec![g.process_by_id("p").unwrap()]);
}

#[test]
fn collaborations_lanes_and_data() {
    let xml = format!(
        r#"{HEAD}<bpmn:message id="m" name="ping"/>
        <bpmn:collaboration id="c"><bpmn:participant id="pa" processRef="p"/><bpmn:participant id="pb" name="Ground"/>
          <bpmn:messageFlow id="mf" sourceRef="x" targetRef="pb" messageRef="m"/></bpmn:collaboration>
        <bpmn:process id="p" isExecutable="true"><bpmn:laneSet><bpmn:lane id="lane" name="Arm"><bpmn:flowNodeRef>x</bpmn:flowNodeRef></bpmn:lane></bpmn:laneSet>
          <bpmn:property id="prop" name="battery"/><bpmn:dataObject id="do" name="samples" isCollection="true"/>
          <bpmn:startEvent id="s"/><bpmn:sendTask id="x" messageRef="m"/><bpmn:endEvent id="e"/>
          <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="e"/></bpmn:process></bpmn:definitions>"#
    );
    let g = ok(&xml);
    let c = &g.collaborations[0];
    assert_eq!(c.participants.len(), 2);
    assert_eq!(c.message_flows[0].message, Some(MessageId(0)));
    let p = g.process(g.process_by_id("p").unwrap());
    assert_eq!(p.lanes[0].nodes, vec![g.node_by_id("x").unwrap()]);
    assert_eq!(p.properties[0].name.as_deref(), Some("battery"));
    assert!(p.data_objects[0].collection);
}

#[test]
fn data_inputs_are_visible_to_their_activity_and_inside_their_process_only() {
    // The process declares `pin`; task `a` declares `ain`; task `x` reads `source` into its own
    // input `xin`.
    let model = |source: &str| {
        let io = |id: &str| {
            format!(
                r#"<bpmn:ioSpecification><bpmn:dataInput id="{id}"/><bpmn:inputSet><bpmn:dataInputRefs>{id}</bpmn:dataInputRefs></bpmn:inputSet><bpmn:outputSet/></bpmn:ioSpecification>"#
            )
        };
        format!(
            r#"{HEAD}<bpmn:process id="p" isExecutable="true">{}<bpmn:startEvent id="s"/><bpmn:task id="a">{}</bpmn:task>
            <bpmn:task id="x">{}<bpmn:dataInputAssociation id="da"><bpmn:sourceRef>{source}</bpmn:sourceRef><bpmn:targetRef>xin</bpmn:targetRef></bpmn:dataInputAssociation></bpmn:task>
            <bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="a"/><bpmn:sequenceFlow id="f2" sourceRef="a" targetRef="x"/><bpmn:sequenceFlow id="f3" sourceRef="x" targetRef="e"/></bpmn:process></bpmn:definitions>"#,
            io("pin"),
            io("ain"),
            io("xin")
        )
    };
    let codes = |source: &str| -> Vec<&'static str> {
        load(model(source).as_bytes())
            .diagnostics
            .iter()
            .map(|d| d.code)
            .collect()
    };
    assert_eq!(codes("pin"), Vec::<&str>::new(), "the process's own input");
    assert_eq!(codes("xin"), Vec::<&str>::new(), "the task's own input");
    assert_eq!(codes("ain"), ["invisible-data"], "another task's input");
}

#[test]
fn each_diagnostic_fires_on_its_minimal_model() {
    let cases: Vec<(&str, String)> = vec![
        ("duplicate-id", around(r#"<bpmn:task id="x"/><bpmn:task id="x"/>"#)),
        ("dangling-reference", doc("", r#"<bpmn:startEvent id="s"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="nowhere"/>"#)),
        ("boundary-on-non-activity", around(r#"<bpmn:task id="x"/><bpmn:boundaryEvent id="b" attachedToRef="s"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1M</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:boundaryEvent>"#)),
        ("missing-called-process", around(r#"<bpmn:callActivity id="x" calledElement="ghost"/>"#)),
        ("ambiguous-link", doc("", r#"<bpmn:startEvent id="s"/><bpmn:intermediateThrowEvent id="x"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateThrowEvent><bpmn:intermediateCatchEvent id="c1"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateCatchEvent><bpmn:intermediateCatchEvent id="c2"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateCatchEvent><bpmn:endEvent id="e1"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f1" sourceRef="c1" targetRef="e1"/><bpmn:sequenceFlow id="f2" sourceRef="c2" targetRef="e2"/>"#)),
        ("bad-data-association", around(r#"<bpmn:task id="x"><bpmn:ioSpecification><bpmn:dataInput id="di"/><bpmn:dataOutput id="do"/><bpmn:inputSet><bpmn:dataInputRefs>di</bpmn:dataInputRefs></bpmn:inputSet><bpmn:outputSet><bpmn:dataOutputRefs>do</bpmn:dataOutputRefs></bpmn:outputSet></bpmn:ioSpecification><bpmn:dataInputAssociation id="da"><bpmn:sourceRef>ob</bpmn:sourceRef><bpmn:targetRef>do</bpmn:targetRef></bpmn:dataInputAssociation></bpmn:task><bpmn:dataObject id="ob"/>"#)),
        ("compensation-handler-flow", around(r#"<bpmn:task id="x" isForCompensation="true"/>"#)),
        ("bad-timer", around(r#"<bpmn:intermediateCatchEvent id="x"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">5 minutes</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>"#)),
        ("bad-expression", around(r#"<bpmn:scriptTask id="x" scriptFormat="cel"><bpmn:script>a = (</bpmn:script></bpmn:scriptTask>"#).replace("bad-script", "")),
        ("missing-resource", around(r#"<bpmn:serviceTask id="x"/>"#)),
        ("unsupported-element", around(r#"<bpmn:task id="x"/><bpmn:choreographyTask id="ct"/>"#)),
        ("malformed-xml", "<bpmn:definitions".to_owned()),
        ("not-bpmn", "<html/>".to_owned()),
    ];
    for (code, xml) in cases {
        let found = errors(&xml);
        let found = if code == "bad-expression" {
            found
                .into_iter()
                .map(|c| {
                    if c == "bad-script" {
                        "bad-expression"
                    } else {
                        c
                    }
                })
                .collect()
        } else {
            found
        };
        assert!(found.contains(&code), "{code}: expected it among {found:?}");
    }
}

/// In a drawing (`isExecutable="false"`) a reference that names nothing is a warning naming
/// the reference rule — vendor exports are full of them, and a call may name what another
/// bundle deploys — and an error when reading strictly.
#[test]
fn a_drawings_broken_references_are_warnings_and_errors_when_strict() {
    let cases = [
        (
            "missing-called-process",
            r#"<bpmn:callActivity id="x" calledElement="ghost"/>"#,
        ),
        (
            "dangling-reference",
            r#"<bpmn:task id="x"/><bpmn:dataObjectReference id="r" dataObjectRef="ghost"/>"#,
        ),
        (
            "dangling-reference",
            r#"<bpmn:task id="x"/><bpmn:textAnnotation id="a"/><bpmn:association id="l" sourceRef="a" targetRef="ghost"/>"#,
        ),
    ];
    for (code, middle) in cases {
        let xml = around(middle).replace(r#"isExecutable="true""#, r#"isExecutable="false""#);
        let loaded = load(xml.as_bytes());
        assert!(
            loaded.errors().next().is_none(),
            "{middle}: {:#?}",
            loaded.diagnostics
        );
        assert!(
            loaded.diagnostics.iter().any(|d| d.code == code
                && d.severity == Severity::Warning
                && d.constraint == Some("REF")),
            "{middle}: {:#?}",
            loaded.diagnostics
        );
        assert!(strict_errors(&xml).contains(&code), "{middle}");
    }
}

/// Loads `xml` strictly (`trace validate --strict`).
fn strict_errors(xml: &str) -> Vec<&'static str> {
    let options = crate::Options {
        strict: true,
        ..crate::Options::default()
    };
    crate::load_with(xml.as_bytes(), &options)
        .errors()
        .map(|d| d.code)
        .collect()
}

#[test]
fn rules_bent_harmlessly_are_warnings_that_name_the_rule_and_errors_when_strict() {
    let cases: Vec<(&str, String)> = vec![
        (
            "unreachable",
            around(
                r#"<bpmn:task id="x"/><bpmn:task id="island"><bpmn:outgoing>z</bpmn:outgoing></bpmn:task><bpmn:sequenceFlow id="z" sourceRef="island" targetRef="e"/>"#,
            ),
        ),
        (
            "no-outgoing",
            doc(
                "",
                r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="g"/>"#,
            ),
        ),
        (
            "start-without-end",
            doc(
                "",
                r#"<bpmn:startEvent id="s"/><bpmn:task id="t"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="t"/>"#,
            ),
        ),
        (
            "end-without-start",
            doc(
                "",
                r#"<bpmn:task id="t"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="t" targetRef="e"/>"#,
            ),
        ),
        // A blank diagram: a start event alone.
        ("no-outgoing", doc("", r#"<bpmn:startEvent id="s"/>"#)),
        (
            "natural-language-expression",
            doc(
                "",
                r#"<bpmn:startEvent id="s"/><bpmn:intermediateCatchEvent id="x"><bpmn:timerEventDefinition><bpmn:timeDuration>PT1H</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent><bpmn:exclusiveGateway id="g" default="f3"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f0" sourceRef="x" targetRef="g"/><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e"><bpmn:conditionExpression>x &lt; 2</bpmn:conditionExpression></bpmn:sequenceFlow><bpmn:sequenceFlow id="f3" sourceRef="g" targetRef="e2"/>"#,
            ),
        ),
        (
            "condition-on-parallel",
            doc(
                "",
                r#"<bpmn:startEvent id="s"/><bpmn:parallelGateway id="g"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="e"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a</bpmn:conditionExpression></bpmn:sequenceFlow><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e2"/>"#,
            ),
        ),
        (
            "conditional-default",
            doc(
                "",
                r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g" default="f2"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="e"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a</bpmn:conditionExpression></bpmn:sequenceFlow><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e2"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">b</bpmn:conditionExpression></bpmn:sequenceFlow>"#,
            ),
        ),
        (
            "public-executable",
            format!(
                r#"{HEAD}<bpmn:process id="p" isExecutable="true" processType="Public"><bpmn:startEvent id="s"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="e"/></bpmn:process></bpmn:definitions>"#
            ),
        ),
        (
            "unknown-attribute",
            around(r#"<bpmn:task id="x" color="red"/>"#),
        ),
        (
            "missing-script-format",
            around(r#"<bpmn:scriptTask id="x"><bpmn:script>a = 1</bpmn:script></bpmn:scriptTask>"#),
        ),
        (
            "non-interrupting-error",
            around(
                r#"<bpmn:task id="x"/><bpmn:boundaryEvent id="b" attachedToRef="x" cancelActivity="false"><bpmn:errorEventDefinition/><bpmn:outgoing>fb</bpmn:outgoing></bpmn:boundaryEvent><bpmn:endEvent id="eb"/><bpmn:sequenceFlow id="fb" sourceRef="b" targetRef="eb"/>"#,
            ),
        ),
    ];
    for (code, xml) in &cases {
        let loaded = load(xml.as_bytes());
        let warning = loaded.diagnostics.iter().find(|d| d.code == *code);
        assert!(
            warning.is_some_and(|d| d.severity == Severity::Warning && d.constraint.is_some()),
            "{code}: expected a warning naming a rule among {:#?}",
            loaded.diagnostics
        );
        assert!(loaded.graph.is_some(), "{code}: {:#?}", loaded.diagnostics);
        assert!(
            strict_errors(xml).contains(code),
            "{code}: expected an error when strict"
        );
    }
}

#[test]
fn bent_rules_are_read_as_the_warning_says() {
    // An error boundary marked non-interrupting still interrupts.
    let g = ok(&around(
        r#"<bpmn:task id="x"/><bpmn:boundaryEvent id="b" attachedToRef="x" cancelActivity="false"><bpmn:errorEventDefinition/></bpmn:boundaryEvent>"#,
    ));
    assert!(matches!(kind(&g, "b"), NodeKind::Boundary(b) if b.interrupting));
    // A timer and a condition without xsi:type are read in the process's language.
    let g = ok(&around(
        r#"<bpmn:intermediateCatchEvent id="x"><bpmn:timerEventDefinition><bpmn:timeDuration>PT1H</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>"#,
    ));
    assert!(
        matches!(kind(&g, "x"), NodeKind::Catch(c) if matches!(c.triggers[..], [EventDefinition::Timer(_)]))
    );
}

#[test]
fn a_flow_not_listed_at_one_end_is_named_even_when_another_listing_repeats() {
    // Where one node lists a flow twice, the listings still add up to "every end listed".
    let flows = |s_out: &str, x_out: &str| {
        let loaded = load(
            around(&format!(
                r#"<bpmn:task id="x"><bpmn:incoming>f1</bpmn:incoming>{x_out}</bpmn:task>"#
            ))
            .replace(
                r#"<bpmn:startEvent id="s"/>"#,
                &format!(r#"<bpmn:startEvent id="s">{s_out}</bpmn:startEvent>"#),
            )
            .replace(
                r#"<bpmn:endEvent id="e"/>"#,
                r#"<bpmn:endEvent id="e"><bpmn:incoming>f2</bpmn:incoming></bpmn:endEvent>"#,
            )
            .as_bytes(),
        );
        assert!(loaded.graph.is_some(), "{:#?}", loaded.diagnostics);
        loaded
            .diagnostics
            .iter()
            .filter(|d| d.code == "flow-mismatch")
            .map(|d| (d.element.clone().unwrap_or_default(), d.constraint))
            .collect::<Vec<_>>()
    };
    let out = |f: &str| format!("<bpmn:outgoing>{f}</bpmn:outgoing>");
    assert_eq!(flows(&out("f1"), &out("f2")), []);
    assert_eq!(
        flows(&(out("f1") + &out("f1")), ""),
        [("x".to_owned(), Some("EXT.023"))]
    );
    assert_eq!(flows("", &out("f2")), [("s".to_owned(), Some("EXT.101"))]);
    // Past the listings the walk compares pairwise, every flow is looked up.
    assert_eq!(
        flows(&out("f1").repeat(40), ""),
        [("x".to_owned(), Some("EXT.023"))]
    );
    assert_eq!(flows(&out("f1").repeat(40), &out("f2")), []);
}

#[test]
fn expressions_in_other_languages_are_execution_problems_naming_the_language() {
    let cond = |attrs: &str, text: &str| {
        doc(
            "",
            &format!(
                r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g" default="f2"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="e"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression" {attrs}>{text}</bpmn:conditionExpression></bpmn:sequenceFlow><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e2"/>"#
            ),
        )
    };
    for (attrs, text, language) in [
        (r#"language="javascript""#, "a &gt; 1", "JavaScript"),
        (r#"language="groovy""#, "a &gt; 1", "Groovy"),
        ("", "${orderService.isValid(order)}", "JUEL"),
    ] {
        let loaded = load(cond(attrs, text).as_bytes());
        let d = loaded
            .diagnostics
            .iter()
            .find(|d| d.code == "unevaluated-language")
            .unwrap_or_else(|| panic!("{text}: {:#?}", loaded.diagnostics));
        assert_eq!(d.category, Category::Execution);
        assert!(d.message.contains(language), "{}", d.message);
        assert!(
            loaded
                .diagnostics
                .iter()
                .all(|d| d.category == Category::Execution || d.severity == Severity::Warning)
        );
    }
    // FEEL is evaluated as FEEL; its syntax errors are BPMN-independent expression errors with
    // their position.
    let loaded = load(cond("", r#"= day of week(today()) = "Tuesday""#).as_bytes());
    assert!(
        loaded.errors().next().is_none(),
        "{:#?}",
        loaded.diagnostics
    );
    let loaded = load(cond("", "= a &lt; ").as_bytes());
    let d = loaded.errors().next().expect("a FEEL syntax error");
    assert_eq!(d.code, "bad-expression");
    assert!(d.message.contains("at the end of `a <`"), "{}", d.message);
    // Inside the subset, JUEL conditions compile to CEL; CEL and FEEL compile as they are.
    for text in [
        "${a == 'x' and not b}",
        r#"=a = "x" and not(b)"#,
        r#"a == "x" &amp;&amp; !b"#,
    ] {
        ok(&cond("", text));
    }
    // The definitions may declare the language for every expression.
    let xml = cond("", "a &gt; 1").replace(
        r#"targetNamespace="urn:test""#,
        r#"targetNamespace="urn:test" expressionLanguage="http://groovy.codehaus.org/""#,
    );
    assert!(errors(&xml).contains(&"unevaluated-language"));
}

#[test]
fn timer_values_are_iso_text_quoted_constants_or_expressions() {
    let timer = |value: &str| {
        around(&format!(
            r#"<bpmn:intermediateCatchEvent id="x"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">{value}</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>"#
        ))
    };
    let value = |xml: &str| match kind(&ok(xml), "x") {
        NodeKind::Catch(c) => match &c.triggers[..] {
            [EventDefinition::Timer(t)] => t.value.clone(),
            other => panic!("{other:?}"),
        },
        other => panic!("{other:?}"),
    };
    assert!(matches!(
        value(&timer("PT1H")),
        crate::timer::TimerValue::Fixed(_)
    ));
    assert!(matches!(
        value(&timer("\"PT0.03S\"")),
        crate::timer::TimerValue::Fixed(_)
    ));
    assert!(matches!(
        value(&timer("due_time")),
        crate::timer::TimerValue::Expression(_)
    ));
    // Text that looks like ISO 8601 but is not stays an error, not a variable.
    assert!(errors(&timer("PT1X")).contains(&"bad-timer"));
}

#[test]
fn camunda8_job_worker_scripts_and_decisions_are_dispatched_by_resource() {
    let g = ok(&doc(
        "",
        r#"<bpmn:startEvent id="s"/><bpmn:scriptTask id="x"><bpmn:extensionElements><zeebe:taskDefinition type="render"/></bpmn:extensionElements></bpmn:scriptTask>
        <bpmn:businessRuleTask id="y"><bpmn:extensionElements><zeebe:calledDecision decisionId="approve" resultVariable="ok"/></bpmn:extensionElements></bpmn:businessRuleTask><bpmn:endEvent id="e"/>
        <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="y"/><bpmn:sequenceFlow id="f3" sourceRef="y" targetRef="e"/>"#,
    ));
    for (id, resource) in [("x", "render"), ("y", "approve")] {
        let NodeKind::Task(t) = kind(&g, id) else {
            panic!("{id} is not a task")
        };
        assert_eq!(
            t.binding.as_ref().and_then(|b| b.resource.as_deref()),
            Some(resource)
        );
    }
}

#[test]
fn camunda7_connectors_maps_and_lists_are_read() {
    let g = ok(&around(
        r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><camunda:connector><camunda:inputOutput>
          <camunda:inputParameter name="headers"><camunda:map><camunda:entry key="Accept">application/json</camunda:entry><camunda:entry key="n">${count}</camunda:entry></camunda:map></camunda:inputParameter>
          <camunda:inputParameter name="ids"><camunda:list><camunda:value>a</camunda:value><camunda:value>${b}</camunda:value></camunda:list></camunda:inputParameter>
        </camunda:inputOutput><camunda:connectorId>http-connector</camunda:connectorId></camunda:connector></bpmn:extensionElements></bpmn:serviceTask>"#,
    ));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!("not a task")
    };
    let b = t.binding.as_ref().expect("binding");
    assert_eq!(b.resource.as_deref(), Some("http-connector"));
    let texts: Vec<&str> = b.inputs.iter().map(|i| i.source.text.as_str()).collect();
    assert_eq!(
        texts,
        [
            r#"{"Accept": "application/json", "n": (count)}"#,
            r#"["a", (b)]"#
        ]
    );
}

#[test]
fn spiffworkflow_operators_and_decisions_are_resources_and_its_scripts_are_named() {
    let xml = around(
        r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><spiffworkflow:serviceTaskOperator id="http/GetRequest"><spiffworkflow:parameters>
          <spiffworkflow:parameter id="url" type="str" value="'https://example.org'"/><spiffworkflow:parameter id="retries" type="int" value="4"/>
        </spiffworkflow:parameters></spiffworkflow:serviceTaskOperator></bpmn:extensionElements></bpmn:serviceTask>"#,
    );
    let g = ok(&xml);
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!("not a task")
    };
    let b = t.binding.as_ref().expect("binding");
    assert_eq!(b.resource.as_deref(), Some("http/GetRequest"));
    assert_eq!(
        b.inputs
            .iter()
            .map(|i| i.target.as_str())
            .collect::<Vec<_>>(),
        ["url", "retries"]
    );
    // A Python pre-script would be dropped silently: it is named instead.
    let with_script = xml.replace(
        "</spiffworkflow:serviceTaskOperator>",
        "</spiffworkflow:serviceTaskOperator><spiffworkflow:preScript>x = 1</spiffworkflow:preScript>",
    );
    assert_eq!(errors(&with_script), ["unevaluated-language"]);
}

#[test]
fn a_trace_binding_wins_over_other_engines_bindings() {
    // A model drawn for several engines carries a binding for each: ours is addressed to us.
    let g = ok(&around(
        r#"<bpmn:serviceTask id="x"><bpmn:extensionElements><trace:task resource="arm.dig"/><zeebe:taskDefinition type="dig"/></bpmn:extensionElements></bpmn:serviceTask>"#,
    ));
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!("not a task")
    };
    assert_eq!(
        t.binding.as_ref().and_then(|b| b.resource.as_deref()),
        Some("arm.dig")
    );
    // Two other engines' bindings leave the choice to a guess: refused.
    let two = around(
        r#"<bpmn:serviceTask id="x" camunda:topic="dig"><bpmn:extensionElements><zeebe:taskDefinition type="dig2"/></bpmn:extensionElements></bpmn:serviceTask>"#,
    );
    assert!(errors(&two).contains(&"conflicting-bindings"));
}

#[test]
fn event_data_associations_are_not_dropped_silently() {
    let xml = around(
        r#"<bpmn:intermediateThrowEvent id="x"><bpmn:dataInput id="di"/><bpmn:dataInputAssociation><bpmn:sourceRef>do</bpmn:sourceRef><bpmn:targetRef>di</bpmn:targetRef></bpmn:dataInputAssociation><bpmn:inputSet><bpmn:dataInputRefs>di</bpmn:dataInputRefs></bpmn:inputSet><bpmn:signalEventDefinition/></bpmn:intermediateThrowEvent><bpmn:dataObject id="do"/>"#,
    );
    assert!(
        errors(&xml).contains(&"unsupported"),
        "{:?}",
        load(xml.as_bytes()).diagnostics
    );
}

#[test]
fn camunda8_script_tasks_are_one_feel_expression_and_its_variable() {
    let xml = around(
        r#"<bpmn:scriptTask id="x"><bpmn:extensionElements><zeebe:script expression="=count" resultVariable="n"/></bpmn:extensionElements></bpmn:scriptTask>"#,
    );
    let g = ok(&xml);
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!("not a task")
    };
    let a = t
        .script
        .as_ref()
        .and_then(|s| s.assignments.as_ref())
        .expect("assignments");
    assert_eq!((a[0].0.as_str(), a[0].1.text.as_str()), ("n", "count"));
    // Any FEEL runs; an unknown function is found when the model loads.
    assert!(
        load(xml.replace("=count", "=today()").as_bytes())
            .errors()
            .next()
            .is_none()
    );
    let loaded = load(xml.replace("=count", "=tomorrow()").as_bytes());
    let d = loaded.errors().next().expect("an error");
    assert_eq!(d.code, "bad-expression");
    assert!(
        d.message.contains("no built-in function `tomorrow`"),
        "{}",
        d.message
    );
}

#[test]
fn feel_scripts_by_script_format_are_one_expression_and_its_result_variable() {
    let xml = around(
        r#"<bpmn:scriptTask id="x" scriptFormat="feel" camunda:resultVariable="total"><bpmn:script>sum(for o in orders return o.amount)</bpmn:script></bpmn:scriptTask>"#,
    );
    let g = ok(&xml);
    let NodeKind::Task(t) = kind(&g, "x") else {
        panic!("not a task")
    };
    let a = t
        .script
        .as_ref()
        .and_then(|s| s.assignments.as_ref())
        .expect("assignments");
    assert_eq!(a[0].0, "total");
    assert_eq!(a[0].1.variables, ["orders"]);
    let loaded = load(xml.replace("sum(for", "sum(fr").as_bytes());
    let d = loaded.errors().next().expect("a FEEL syntax error");
    assert_eq!(d.code, "bad-expression");
}

#[test]
fn camunda_8_names_codes_and_task_types_may_be_constant_feel() {
    // Camunda 8 lets these be expressions; TRACE matches them when the mission loads, so a
    // constant is read as its value and one that reads variables is an error.
    let xml = doc(
        r#"<bpmn:message id="m" name="=&quot;ready&quot;"/><bpmn:error id="er" errorCode="=&quot;E&quot; + &quot;1&quot;"/>"#,
        r#"<bpmn:startEvent id="s"/><bpmn:serviceTask id="t"><bpmn:extensionElements><zeebe:taskDefinition type="=&quot;sys.t&quot;" retries="=3"/></bpmn:extensionElements></bpmn:serviceTask>
        <bpmn:userTask id="u"><bpmn:extensionElements><zeebe:assignmentDefinition assignee="=lookup(" /></bpmn:extensionElements></bpmn:userTask>
        <bpmn:endEvent id="e"/>
        <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="f1" sourceRef="t" targetRef="u"/><bpmn:sequenceFlow id="f2" sourceRef="u" targetRef="e"/>"#,
    );
    let loaded = load(xml.as_bytes());
    assert!(
        loaded.errors().next().is_none(),
        "{:#?}",
        loaded.diagnostics
    );
    let g = loaded.graph.expect("valid");
    assert_eq!(g.messages[0].name, "ready");
    assert_eq!(g.errors[0].code.as_deref(), Some("E1"));
    let NodeKind::Task(t) = kind(&g, "t") else {
        panic!("not a task")
    };
    let b = t.binding.as_ref().expect("binding");
    assert_eq!((b.resource.as_deref(), b.retries), (Some("sys.t"), Some(3)));
    // The assignee is not used by TRACE; its FEEL error is still named, as a warning.
    assert!(
        loaded
            .diagnostics
            .iter()
            .any(|d| d.code == "bad-expression" && d.message.contains("assignee"))
    );
    // A name that reads variables is only known at run time.
    let dynamic = xml.replace("name=\"=&quot;ready&quot;\"", "name=\"=kind\"");
    let loaded = load(dynamic.as_bytes());
    let d = loaded.errors().next().expect("an error");
    assert!(
        d.message.contains("reads variables (kind)"),
        "{}",
        d.message
    );
}

#[test]
fn a_condition_that_cannot_be_evaluated_is_not_mistaken_for_none() {
    let xml = doc(
        "",
        r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
        <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/>
        <bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="e"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression" language="javascript">a &gt; 1</bpmn:conditionExpression></bpmn:sequenceFlow>
        <bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e2"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a &lt;= 1</bpmn:conditionExpression></bpmn:sequenceFlow>"#,
    );
    assert_eq!(errors(&xml), ["unevaluated-language"]);
}

#[test]
fn correlation_properties_and_supported_interfaces_are_valid_bpmn() {
    let xml = format!(
        r#"{HEAD}<bpmn:message id="m" name="ping"/><bpmn:interface id="if" name="Lander"><bpmn:operation id="op" name="ping"><bpmn:inMessageRef>m</bpmn:inMessageRef></bpmn:operation></bpmn:interface>
        <bpmn:correlationProperty id="cp" name="site"><bpmn:correlationPropertyRetrievalExpression messageRef="m"><bpmn:messagePath>site</bpmn:messagePath></bpmn:correlationPropertyRetrievalExpression></bpmn:correlationProperty>
        <bpmn:process id="p" isExecutable="true"><bpmn:supportedInterfaceRef>if</bpmn:supportedInterfaceRef>
          <bpmn:correlationSubscription correlationKeyRef="ck"><bpmn:correlationPropertyBinding correlationPropertyRef="cp"><bpmn:dataPath>site</bpmn:dataPath></bpmn:correlationPropertyBinding></bpmn:correlationSubscription>
          <bpmn:startEvent id="s"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="e"/></bpmn:process>
        <bpmn:collaboration id="c"><bpmn:participant id="pa" processRef="p"/><bpmn:correlationKey id="ck"><bpmn:correlationPropertyRef>cp</bpmn:correlationPropertyRef></bpmn:correlationKey></bpmn:collaboration></bpmn:definitions>"#
    );
    let loaded = load(xml.as_bytes());
    let bpmn: Vec<_> = loaded
        .diagnostics
        .iter()
        .filter(|d| d.category == Category::Bpmn)
        .collect();
    assert!(bpmn.is_empty(), "{bpmn:#?}");
}

#[test]
fn message_events_implemented_by_a_job_worker_are_tasks() {
    let g = ok(&doc(
        "",
        r#"<bpmn:startEvent id="s"/><bpmn:intermediateThrowEvent id="x"><bpmn:extensionElements><zeebe:taskDefinition type="notify"/></bpmn:extensionElements><bpmn:messageEventDefinition/></bpmn:intermediateThrowEvent>
        <bpmn:endEvent id="e"><bpmn:extensionElements><zeebe:taskDefinition type="report"/></bpmn:extensionElements><bpmn:messageEventDefinition/></bpmn:endEvent>
        <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="e"/>"#,
    ));
    for (id, resource, element) in [
        ("x", "notify", "intermediateThrowEvent"),
        ("e", "report", "endEvent"),
    ] {
        let NodeKind::Task(t) = kind(&g, id) else {
            panic!("{id} is not a task")
        };
        assert_eq!(
            t.binding.as_ref().and_then(|b| b.resource.as_deref()),
            Some(resource)
        );
        assert_eq!(kind(&g, id).element_name(), element);
    }
    assert!(g.warnings.is_empty(), "{:#?}", g.warnings);
}

#[test]
fn processes_without_is_executable_report_what_stops_them_as_execution_problems() {
    let xml = format!(
        r#"{HEAD}<bpmn:process id="p"><bpmn:startEvent id="s"/><bpmn:intermediateCatchEvent id="x"/><bpmn:endEvent id="e"/>
        <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="x"/><bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="e"/></bpmn:process></bpmn:definitions>"#
    );
    let loaded = load(xml.as_bytes());
    let d = loaded
        .errors()
        .find(|d| d.code == "catch-without-trigger")
        .expect("reported");
    assert_eq!(d.category, Category::Execution);
    // Marked executable, the same model breaks BPMN.
    let loaded = load(
        xml.replace(r#"id="p">"#, r#"id="p" isExecutable="true">"#)
            .as_bytes(),
    );
    assert!(
        loaded
            .errors()
            .any(|d| d.code == "catch-without-trigger" && d.category == Category::Bpmn)
    );
}

#[test]
fn a_gateway_without_default_is_a_warning_that_names_it() {
    let xml = doc(
        "",
        r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
        <bpmn:sequenceFlow id="f0" sourceRef="s" targetRef="g"/>
        <bpmn:sequenceFlow id="f1" sourceRef="g" targetRef="e"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">a</bpmn:conditionExpression></bpmn:sequenceFlow>
        <bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e2"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">!a</bpmn:conditionExpression></bpmn:sequenceFlow>"#,
    );
    let loaded = load(xml.as_bytes());
    assert!(loaded.graph.is_some());
    let w = loaded
        .diagnostics
        .iter()
        .find(|d| d.code == "no-default-flow")
        .expect("warning");
    assert_eq!(
        (w.severity, w.element.as_deref()),
        (Severity::Warning, Some("g"))
    );
}

#[test]
fn every_problem_is_listed_with_line_and_column() {
    let xml = format!(
        "{HEAD}\n<bpmn:process id=\"p\" isExecutable=\"true\">\n<bpmn:startEvent id=\"s\"/>\n<bpmn:serviceTask id=\"t\"/>\n<bpmn:endEvent id=\"e\"/>\n<bpmn:sequenceFlow id=\"f1\" sourceRef=\"s\" targetRef=\"t\"/>\n<bpmn:sequenceFlow id=\"f2\" sourceRef=\"t\" targetRef=\"gone\"/>\n</bpmn:process></bpmn:definitions>"
    );
    let loaded = load(xml.as_bytes());
    let head_lines = HEAD.lines().count();
    let missing = loaded
        .errors()
        .find(|d| d.code == "missing-resource")
        .expect("missing resource");
    assert_eq!((missing.line, missing.column), (head_lines + 3, 1));
    let dangling = loaded
        .errors()
        .find(|d| d.code == "dangling-reference")
        .expect("dangling");
    assert_eq!(
        (dangling.line, dangling.element.as_deref()),
        (head_lines + 6, Some("f2"))
    );
}

#[test]
fn imports_resolve_through_the_callers_resolver() {
    let lib = format!(r#"{HEAD}<bpmn:process id="lib" isExecutable="true"><bpmn:startEvent id="ls"/><bpmn:endEvent id="le"/>
        <bpmn:sequenceFlow id="l1" sourceRef="ls" targetRef="le"/></bpmn:process></bpmn:definitions>"#).replace("urn:test", "urn:lib");
    let main = around(r#"<bpmn:callActivity id="x" calledElement="lib"/>"#)
        .replace("<bpmn:process", r#"<bpmn:import importType="http://www.omg.org/spec/BPMN/20100524/MODEL" location="lib.bpmn" namespace="urn:lib"/><bpmn:process"#);
    let loaded = load_bundle(main.as_bytes(), &Options::default(), &mut |loc| {
        if loc == "lib.bpmn" {
            Ok(lib.clone().into_bytes())
        } else {
            Err("no such file".into())
        }
    });
    let g = loaded
        .graph
        .unwrap_or_else(|| panic!("{:#?}", loaded.diagnostics));
    let lib_id = g.process_by_id("lib").unwrap();
    assert!(g.process(lib_id).imported);
    assert_eq!(g.primary_processes(), vec![g.process_by_id("p").unwrap()]);
    // Unresolved, the import itself is a warning naming the rule; what the model needed from it
    // is an error where it is used.
    let missing = load(main.as_bytes());
    assert!(
        missing
            .diagnostics
            .iter()
            .any(|d| d.code == "unresolved-import"
                && d.severity == Severity::Warning
                && d.constraint == Some("EXT.001"))
    );
    assert!(missing.errors().any(|d| d.code == "missing-called-process"));
}

#[test]
fn imports_of_imports_resolve_and_a_broken_import_is_named_once() {
    // main imports lib.bpmn (which imports deep.bpmn, whose process main calls), an XSD that is
    // only checked for well-formedness, and a file that is not XML.
    let import = |location: &str, kind: &str| {
        format!(
            r#"<bpmn:import importType="{kind}" location="{location}" namespace="urn:{location}"/>"#
        )
    };
    let bpmn = "http://www.omg.org/spec/BPMN/20100524/MODEL";
    let xsd = "http://www.w3.org/2001/XMLSchema";
    let deep = format!(r#"{HEAD}<bpmn:process id="deep" isExecutable="true"><bpmn:startEvent id="ds"/><bpmn:endEvent id="de"/>
        <bpmn:sequenceFlow id="d1" sourceRef="ds" targetRef="de"/></bpmn:process></bpmn:definitions>"#).replace("urn:test", "urn:deep");
    let lib = format!("{HEAD}{}</bpmn:definitions>", import("deep.bpmn", bpmn))
        .replace("urn:test", "urn:lib");
    let imports = [
        ("lib.bpmn", bpmn),
        ("types.xsd", xsd),
        ("broken.bpmn", bpmn),
    ]
    .map(|(l, k)| import(l, k))
    .concat();
    let main = around(r#"<bpmn:callActivity id="x" calledElement="deep"/>"#)
        .replace("<bpmn:process", &format!("{imports}<bpmn:process"));
    let files = |loc: &str| -> Result<Vec<u8>, String> {
        match loc {
            "lib.bpmn" => Ok(lib.clone().into_bytes()),
            "deep.bpmn" => Ok(deep.clone().into_bytes()),
            "types.xsd" => {
                Ok(br#"<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema"/>"#.to_vec())
            }
            "broken.bpmn" => Ok(b"\xff\xfe\x00not xml".to_vec()),
            _ => Err("no such file".into()),
        }
    };
    let loaded = load_bundle(main.as_bytes(), &Options::default(), &mut |loc| files(loc));
    let broken: Vec<&str> = loaded
        .errors()
        .filter(|d| d.file.as_deref() == Some("broken.bpmn") || d.code == "broken-import")
        .map(|d| d.code)
        .collect();
    assert_eq!(
        broken,
        ["broken-import", "malformed-xml"],
        "{:#?}",
        loaded.diagnostics
    );
    assert_eq!(loaded.errors().count(), 2, "{:#?}", loaded.diagnostics);
    let names: Vec<&str> = loaded.imports.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["lib.bpmn", "types.xsd", "broken.bpmn", "deep.bpmn"]);
    // Without the broken file the bundle loads, with the process two imports away.
    let fixed = main.replace(&import("broken.bpmn", bpmn), "");
    let loaded = load_bundle(fixed.as_bytes(), &Options::default(), &mut |loc| files(loc));
    let g = loaded
        .graph
        .unwrap_or_else(|| panic!("{:#?}", loaded.diagnostics));
    assert!(g.process(g.process_by_id("deep").unwrap()).imported);
}

#[test]
fn a_boundary_event_may_come_before_its_activity() {
    // bpmn-js writes elements in creation order, so a boundary event can precede its task.
    let g = ok(&around(
        r#"<bpmn:boundaryEvent id="b" attachedToRef="x"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1H</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:boundaryEvent>
        <bpmn:userTask id="x"/><bpmn:endEvent id="e2"/><bpmn:sequenceFlow id="f3" sourceRef="b" targetRef="e2"/>"#,
    ));
    let t = g.node_by_id("x").expect("x");
    assert_eq!(g.node(t).boundaries, vec![g.node_by_id("b").expect("b")]);
}

#[test]
fn a_quantity_over_the_bound_is_refused_when_executable_and_read_as_the_bound_in_a_drawing() {
    let task =
        |q: &str| format!(r#"<bpmn:task id="x" startQuantity="1" completionQuantity="{q}"/>"#);
    assert_eq!(errors(&around(&task("4000000000"))), ["bad-quantity"]);
    let loaded = load(around(&task("4000000000")).as_bytes());
    let d = loaded.errors().next().expect("an error");
    assert!(d.message.contains("over the 1000 tokens"), "{}", d.message);
    assert!(errors(&around(&task("1000"))).is_empty());
    let drawing =
        around(&task("5000")).replace(r#"isExecutable="true""#, r#"isExecutable="false""#);
    let g = ok(&drawing);
    let x = g.node(g.node_by_id("x").expect("x"));
    assert_eq!(x.completion_quantity, crate::MAX_QUANTITY);
}

#[test]
fn strict_applies_the_flow_rules_to_descriptive_processes_too() {
    // BPMNspector's descriptive and analytic classes bind every process: a drawing marked
    // isExecutable="false" with an unreachable task, a gateway without outgoing flow, a
    // pass-through gateway or a boundary event going nowhere is refused with --strict, and only
    // warned about without it. EXT.011 (an escalation code) binds executable processes only.
    let cases = [
        (
            "unreachable",
            r#"<bpmn:startEvent id="s"/><bpmn:task id="t"/><bpmn:task id="island"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/>
            <bpmn:sequenceFlow id="f3" sourceRef="island" targetRef="e"/>"#,
        ),
        (
            "no-outgoing",
            r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="g"/>"#,
        ),
        (
            "pass-through-gateway",
            r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="g"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="e"/>"#,
        ),
        (
            "no-outgoing",
            r#"<bpmn:startEvent id="s"/><bpmn:task id="t"/><bpmn:endEvent id="e"/>
            <bpmn:boundaryEvent id="b" attachedToRef="t"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1H</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:boundaryEvent>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/>"#,
        ),
    ];
    for (code, body) in cases {
        let xml = doc("", body).replace(r#"isExecutable="true""#, r#"isExecutable="false""#);
        let lenient = load(xml.as_bytes());
        assert!(lenient.graph.is_some(), "{code}: {:?}", lenient.diagnostics);
        assert!(
            lenient.diagnostics.iter().any(|d| d.code == code),
            "{code}: warned about without --strict: {:?}",
            lenient.diagnostics
        );
        assert!(
            strict_errors(&xml).contains(&code),
            "{code}: {:?}",
            strict_errors(&xml)
        );
    }
}

#[test]
fn a_call_activitys_data_must_match_what_it_calls_when_strict() {
    // §10.3.6: the call's data inputs and outputs match the called process's exactly, in
    // number and item (one item definition, or two with the same structureRef). Variables pass
    // by name, so a mismatch is only warned about; --strict refuses it.
    let call = |inputs: &str, callee_inputs: &str| {
        format!(
            r#"{HEAD}<bpmn:itemDefinition id="text" structureRef="xsd:string"/><bpmn:itemDefinition id="text2" structureRef="xsd:string"/><bpmn:itemDefinition id="number" structureRef="xsd:int"/>
            <bpmn:process id="p" isExecutable="true"><bpmn:startEvent id="s"/>
              <bpmn:callActivity id="c" calledElement="q"><bpmn:ioSpecification>{inputs}<bpmn:inputSet/><bpmn:outputSet/></bpmn:ioSpecification></bpmn:callActivity>
              <bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="c"/><bpmn:sequenceFlow id="f2" sourceRef="c" targetRef="e"/></bpmn:process>
            <bpmn:process id="q" isExecutable="true"><bpmn:ioSpecification>{callee_inputs}<bpmn:inputSet/><bpmn:outputSet/></bpmn:ioSpecification>
              <bpmn:startEvent id="qs"/><bpmn:endEvent id="qe"/><bpmn:sequenceFlow id="g" sourceRef="qs" targetRef="qe"/></bpmn:process></bpmn:definitions>"#
        )
    };
    let input =
        |id: &str, item: &str| format!(r#"<bpmn:dataInput id="{id}" itemSubjectRef="{item}"/>"#);
    let matching = call(&input("a", "text"), &input("b", "text2"));
    assert!(
        !strict_errors(&matching).contains(&"call-data-mismatch"),
        "{:?}",
        strict_errors(&matching)
    );
    for wrong in [
        call(&input("a", "number"), &input("b", "text")),
        call("", &input("b", "text")),
        call(
            &format!("{}{}", input("a", "text"), input("a2", "text")),
            &input("b", "text"),
        ),
    ] {
        let lenient = load(wrong.as_bytes());
        assert!(lenient.graph.is_some(), "{:?}", lenient.diagnostics);
        assert!(
            lenient
                .diagnostics
                .iter()
                .any(|d| d.code == "call-data-mismatch" && d.constraint == Some("§10.3.6"))
        );
        assert!(strict_errors(&wrong).contains(&"call-data-mismatch"));
    }
}

#[test]
fn flow_rules_read_the_sequence_flows_and_bend_harmlessly() {
    // Each is warned about and refused with --strict, naming its clause: a gatewayDirection
    // contradicting the sequence flows (counted from sourceRef/targetRef, with no
    // <incoming>/<outgoing> listed), a condition on a flow leaving an event, an event
    // sub-process with two start events.
    let cases = [
        (
            "gateway-direction",
            r#"<bpmn:startEvent id="s"/><bpmn:parallelGateway id="g"/><bpmn:parallelGateway id="j" gatewayDirection="Converging"/><bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="g"/><bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="j"/><bpmn:sequenceFlow id="f3" sourceRef="g" targetRef="j"/>
            <bpmn:sequenceFlow id="f4" sourceRef="j" targetRef="e"/><bpmn:sequenceFlow id="f5" sourceRef="j" targetRef="e2"/>"#,
        ),
        (
            "condition-on-event",
            r#"<bpmn:startEvent id="s"/><bpmn:task id="t"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">true</bpmn:conditionExpression></bpmn:sequenceFlow>
            <bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/>"#,
        ),
        (
            "event-subprocess-starts",
            r#"<bpmn:startEvent id="s"/><bpmn:task id="t"/><bpmn:endEvent id="e"/>
            <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/>
            <bpmn:subProcess id="esp" triggeredByEvent="true">
              <bpmn:startEvent id="a"><bpmn:signalEventDefinition signalRef="sig"/></bpmn:startEvent>
              <bpmn:startEvent id="b"><bpmn:signalEventDefinition signalRef="sig"/></bpmn:startEvent>
              <bpmn:endEvent id="x"/><bpmn:sequenceFlow id="g1" sourceRef="a" targetRef="x"/><bpmn:sequenceFlow id="g2" sourceRef="b" targetRef="x"/>
            </bpmn:subProcess>"#,
        ),
    ];
    for (code, body) in cases {
        let xml = doc(r#"<bpmn:signal id="sig" name="S"/>"#, body);
        let lenient = load(xml.as_bytes());
        assert!(lenient.graph.is_some(), "{code}: {:?}", lenient.diagnostics);
        assert!(
            lenient
                .diagnostics
                .iter()
                .any(|d| d.code == code && d.constraint.is_some()),
            "{code}: {:?}",
            lenient.diagnostics
        );
        assert!(
            strict_errors(&xml).contains(&code),
            "{code}: {:?}",
            strict_errors(&xml)
        );
    }
}

#[test]
fn items_that_travel_together_must_be_equivalent_when_strict() {
    // §10.3.3 and §10.4.1: a service task's data carries the items of its operation's
    // messages (EXT.045 for the out-message), a send (receive) task's data input (output) the
    // item of its message, and a data association without a transformation joins equivalent
    // items — one item definition, or two naming the same structure. Each combination of
    // where the items differ and whether they are equivalent: only the inequivalent ones are
    // warned about, and refused with --strict.
    let items = r#"<bpmn:itemDefinition id="text" structureRef="xsd:string"/><bpmn:itemDefinition id="text2" structureRef="xsd:string"/>
        <bpmn:itemDefinition id="number" structureRef="xsd:int"/><bpmn:itemDefinition id="bare"/><bpmn:itemDefinition id="bare2"/>
        <bpmn:message id="m" itemRef="text"/>
        <bpmn:interface id="if"><bpmn:operation id="op"><bpmn:inMessageRef>m</bpmn:inMessageRef><bpmn:outMessageRef>m</bpmn:outMessageRef></bpmn:operation></bpmn:interface>"#;
    let io = |kind: &str, item: &str| {
        let sets = if kind == "dataInput" {
            "<bpmn:inputSet><bpmn:dataInputRefs>din</bpmn:dataInputRefs></bpmn:inputSet><bpmn:outputSet/>"
        } else {
            "<bpmn:inputSet/><bpmn:outputSet><bpmn:dataOutputRefs>din</bpmn:dataOutputRefs></bpmn:outputSet>"
        };
        format!(
            r#"<bpmn:ioSpecification><bpmn:{kind} id="din" itemSubjectRef="{item}"/>{sets}</bpmn:ioSpecification>"#
        )
    };
    let around = |task: String| {
        doc(
            items,
            &format!(
                r#"<bpmn:startEvent id="s"/>{task}<bpmn:endEvent id="e"/>
                <bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/>"#
            ),
        )
    };
    let task = |tag: &str, attrs: &str, kind: &str, item: &str| {
        around(format!(
            r#"<bpmn:{tag} id="t" {attrs}><bpmn:extensionElements><trace:task resource="x.y"/></bpmn:extensionElements>{}</bpmn:{tag}>"#,
            io(kind, item)
        ))
    };
    let association = |object: &str, input: &str, transform: bool| {
        around(format!(
            r#"<bpmn:dataObject id="o" itemSubjectRef="{object}"/>
            <bpmn:serviceTask id="t"><bpmn:extensionElements><trace:task resource="x.y"/></bpmn:extensionElements>{}<bpmn:dataInputAssociation><bpmn:sourceRef>o</bpmn:sourceRef><bpmn:targetRef>din</bpmn:targetRef>{}</bpmn:dataInputAssociation></bpmn:serviceTask>"#,
            io("dataInput", input),
            if transform {
                r#"<bpmn:transformation xsi:type="bpmn:tFormalExpression">string(o)</bpmn:transformation>"#
            } else {
                ""
            }
        ))
    };
    let mut cases = Vec::new();
    for (item, equivalent) in [
        ("text", true),
        ("text2", true),
        ("number", false),
        ("bare", false),
    ] {
        for kind in ["dataInput", "dataOutput"] {
            cases.push((
                task("serviceTask", r#"operationRef="op""#, kind, item),
                equivalent,
            ));
        }
        cases.push((
            task("sendTask", r#"messageRef="m""#, "dataInput", item),
            equivalent,
        ));
        cases.push((
            task("receiveTask", r#"messageRef="m""#, "dataOutput", item),
            equivalent,
        ));
        cases.push((association("text", item, false), equivalent));
        cases.push((association("text", item, true), true));
    }
    cases.push((association("bare", "bare", false), true));
    cases.push((association("bare", "bare2", false), false));
    for (xml, equivalent) in cases {
        let lenient = load(xml.as_bytes());
        let warned = lenient
            .diagnostics
            .iter()
            .any(|d| d.code == "item-mismatch");
        assert_eq!(warned, !equivalent, "{xml}\n{:?}", lenient.diagnostics);
        assert!(lenient.graph.is_some(), "{:?}", lenient.diagnostics);
        assert_eq!(
            strict_errors(&xml).contains(&"item-mismatch"),
            !equivalent,
            "{xml}"
        );
    }
}

#[test]
fn rules_only_a_strict_reading_reports() {
    // A message event without operationRef in a process marked isExecutable="true" (EXT.128),
    // and an attribute the schema lacks in a descriptive process: nearly every drawing has
    // them and nothing needs them, so a lenient reading says nothing and --strict refuses them.
    let message = |executable: &str, operation: &str| {
        format!(
            r#"{HEAD}<bpmn:message id="m" name="M"/><bpmn:interface id="if"><bpmn:operation id="op"/></bpmn:interface>
            <bpmn:process id="p" isExecutable="{executable}"><bpmn:startEvent id="s"><bpmn:messageEventDefinition messageRef="m" {operation}/></bpmn:startEvent>
            <bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="e"/></bpmn:process></bpmn:definitions>"#
        )
    };
    for (xml, refused) in [
        (message("true", ""), true),
        (message("true", r#"operationRef="op""#), false),
        (message("false", ""), false),
    ] {
        let lenient = load(xml.as_bytes());
        assert!(
            !lenient
                .diagnostics
                .iter()
                .any(|d| d.code == "missing-operation"),
            "{:?}",
            lenient.diagnostics
        );
        assert_eq!(
            strict_errors(&xml).contains(&"missing-operation"),
            refused,
            "{xml}"
        );
    }
    let drawing = doc(
        "",
        r#"<bpmn:startEvent id="s" colour="red"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f" sourceRef="s" targetRef="e"/>"#,
    )
    .replace(r#"isExecutable="true""#, r#"isExecutable="false""#);
    assert!(
        !load(drawing.as_bytes())
            .diagnostics
            .iter()
            .any(|d| d.code == "unknown-attribute")
    );
    assert!(strict_errors(&drawing).contains(&"unknown-attribute"));
}

#[test]
fn events_and_gateways_get_the_flows_their_kind_needs_when_strict() {
    // §10.5.4: an intermediate event in normal flow is the target of a sequence flow (where
    // the level has no start events; with them it is unreachable, EXT.150); a link catch is
    // entered by its throw. §10.6.6: no condition on a flow out of an event-based gateway.
    let timer = r#"<bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1H</bpmn:timeDuration></bpmn:timerEventDefinition>"#;
    let cases = [
        (
            "no-incoming",
            format!(
                r#"<bpmn:intermediateCatchEvent id="c">{timer}</bpmn:intermediateCatchEvent><bpmn:task id="t"/><bpmn:sequenceFlow id="f" sourceRef="c" targetRef="t"/>"#
            ),
            true,
        ),
        (
            "no-incoming",
            r#"<bpmn:intermediateThrowEvent id="c"/><bpmn:task id="t"/><bpmn:sequenceFlow id="f" sourceRef="c" targetRef="t"/>"#.to_owned(),
            true,
        ),
        (
            "no-incoming",
            r#"<bpmn:task id="a"/><bpmn:intermediateThrowEvent id="lt"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateThrowEvent>
            <bpmn:intermediateCatchEvent id="lc"><bpmn:linkEventDefinition name="L"/></bpmn:intermediateCatchEvent><bpmn:task id="t"/>
            <bpmn:sequenceFlow id="f0" sourceRef="a" targetRef="lt"/><bpmn:sequenceFlow id="f" sourceRef="lc" targetRef="t"/>"#.to_owned(),
            false,
        ),
        (
            "condition-on-event-gateway",
            format!(
                r#"<bpmn:startEvent id="s"/><bpmn:eventBasedGateway id="g"/>
                <bpmn:intermediateCatchEvent id="c1">{timer}</bpmn:intermediateCatchEvent><bpmn:intermediateCatchEvent id="c2"><bpmn:signalEventDefinition/></bpmn:intermediateCatchEvent>
                <bpmn:endEvent id="e"/><bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="g"/>
                <bpmn:sequenceFlow id="f2" sourceRef="g" targetRef="c1"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression">true</bpmn:conditionExpression></bpmn:sequenceFlow>
                <bpmn:sequenceFlow id="f3" sourceRef="g" targetRef="c2"/><bpmn:sequenceFlow id="f4" sourceRef="c1" targetRef="e"/><bpmn:sequenceFlow id="f5" sourceRef="c2" targetRef="e"/>"#
            ),
            true,
        ),
    ];
    for (code, body, refused) in cases {
        for executable in ["true", "false"] {
            let xml = doc("", &body).replace(
                r#"isExecutable="true""#,
                &format!(r#"isExecutable="{executable}""#),
            );
            let lenient = load(xml.as_bytes());
            assert_eq!(
                lenient.diagnostics.iter().any(|d| d.code == code),
                refused,
                "{code}: {:?}",
                lenient.diagnostics
            );
            assert_eq!(
                strict_errors(&xml).contains(&code),
                refused,
                "{code}: {xml}"
            );
        }
    }
}

#[test]
fn an_attribute_the_schema_gives_only_other_elements_is_reported_and_ignored() {
    // BPMN 2.0.2 Semantic.xsd: each of these attributes belongs to some types only. Each case
    // is an element `x` between a start and an end, in an executable process.
    let misplaced = [
        (r#"<bpmn:parallelGateway id="x" default="f2"/>"#, "default"),
        (
            r#"<bpmn:intermediateThrowEvent id="x" default="f2"/>"#,
            "default",
        ),
        (
            r#"<bpmn:intermediateThrowEvent id="x" completionQuantity="2"/>"#,
            "completionQuantity",
        ),
        (
            r#"<bpmn:intermediateThrowEvent id="x" startQuantity="2"/>"#,
            "startQuantity",
        ),
        (
            r#"<bpmn:parallelGateway id="x" isForCompensation="true"/>"#,
            "isForCompensation",
        ),
        (
            r#"<bpmn:intermediateThrowEvent id="x" parallelMultiple="true"/>"#,
            "parallelMultiple",
        ),
        (
            r#"<bpmn:task id="x" cancelActivity="false"/>"#,
            "cancelActivity",
        ),
        (
            r#"<bpmn:task id="x" isInterrupting="false"/>"#,
            "isInterrupting",
        ),
        (
            r#"<bpmn:task id="x" triggeredByEvent="true"/>"#,
            "triggeredByEvent",
        ),
        (r#"<bpmn:task id="x" calledElement="p"/>"#, "calledElement"),
        (
            r#"<bpmn:task id="x" scriptFormat="text/x-cel"/>"#,
            "scriptFormat",
        ),
        (
            r#"<bpmn:task id="x" eventGatewayType="Parallel"/>"#,
            "eventGatewayType",
        ),
        (r#"<bpmn:task id="x" instantiate="true"/>"#, "instantiate"),
        (
            r#"<bpmn:task id="x" gatewayDirection="Unspecified"/>"#,
            "gatewayDirection",
        ),
        (r#"<bpmn:task id="x" isImmediate="true"/>"#, "isImmediate"),
        (r#"<bpmn:task id="x" ordering="Parallel"/>"#, "ordering"),
        (
            "<bpmn:subProcess id=\"x\" method=\"##Compensate\"/>",
            "method",
        ),
        (r#"<bpmn:task id="x" errorCode="E1"/>"#, "errorCode"),
        (r#"<bpmn:task id="x" testBefore="true"/>"#, "testBefore"),
    ];
    for (middle, attr) in misplaced {
        let xml = around(middle);
        let loaded = load(xml.as_bytes());
        assert!(
            loaded
                .diagnostics
                .iter()
                .any(|d| d.code == "unknown-attribute"
                    && d.message.contains(&format!("no attribute `{attr}`"))),
            "{middle}: {:?}",
            loaded.diagnostics
        );
        assert!(
            strict_errors(&xml).contains(&"unknown-attribute"),
            "{middle}"
        );
        // Ignored: the node reads as if the attribute were not there.
        let g = loaded
            .graph
            .unwrap_or_else(|| panic!("{middle}: {:?}", loaded.diagnostics));
        let x = g.node(g.node_by_id("x").expect("x"));
        assert_eq!(
            (
                x.default_flow,
                x.for_compensation,
                x.start_quantity,
                x.completion_quantity
            ),
            (None, false, 1, 1),
            "{middle}"
        );
    }
    let placed = [
        r#"<bpmn:task id="x" isForCompensation="false" startQuantity="1" completionQuantity="1" default="f2"/>"#,
        r#"<bpmn:exclusiveGateway id="x" default="f2" gatewayDirection="Unspecified"/>"#,
        r#"<bpmn:inclusiveGateway id="x" default="f2"/>"#,
        r#"<bpmn:complexGateway id="x" default="f2"/>"#,
        r#"<bpmn:receiveTask id="x" instantiate="false"/>"#,
        r#"<bpmn:subProcess id="x" triggeredByEvent="false"/>"#,
        "<bpmn:transaction id=\"x\" method=\"##Compensate\"/>",
        r#"<bpmn:adHocSubProcess id="x" ordering="Parallel" cancelRemainingInstances="true"><bpmn:task id="a"/></bpmn:adHocSubProcess>"#,
        r#"<bpmn:intermediateCatchEvent id="x" parallelMultiple="false"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT1S</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>"#,
    ];
    for middle in placed {
        let loaded = load(around(middle).as_bytes());
        assert!(
            !loaded
                .diagnostics
                .iter()
                .any(|d| d.code == "unknown-attribute"),
            "{middle}: {:?}",
            loaded.diagnostics
        );
    }
    // An activity keeps what its type gives it.
    let g = load(around(r#"<bpmn:task id="x" completionQuantity="2" default="f2"/>"#).as_bytes())
        .graph
        .expect("loads");
    let x = g.node(g.node_by_id("x").expect("x"));
    assert_eq!(x.completion_quantity, 2);
    assert!(x.default_flow.is_some());
}
