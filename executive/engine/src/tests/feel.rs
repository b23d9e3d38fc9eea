//! Camunda 8 models run with FEEL's semantics: conditions, `zeebe:script` script tasks, io
//! mappings (with and without a source), multi-instance input collections, timers and message
//! correlation keys written in FEEL, and `now()` as the step's mission time.

use super::*;

/// The Camunda 8 process most models look like: a FEEL script, a FEEL gateway, a job worker with
/// FEEL mappings, and a multi-instance over a FEEL-filtered collection.
const CAMUNDA8: &str = r#"<process id="p" isExecutable="true">
  <startEvent id="s"/>
  <scriptTask id="half"><extensionElements><zeebe:script expression="=n / 2" resultVariable="half"/></extensionElements></scriptTask>
  <exclusiveGateway id="g" default="other"/>
  <serviceTask id="a"><extensionElements>
    <zeebe:taskDefinition type="sys.a"/>
    <zeebe:ioMapping>
      <zeebe:input source="=string join(for s in sites return upper case(s), &quot;,&quot;)" target="codes"/>
      <zeebe:input target="scratch"/>
      <zeebe:input source="static text" target="label"/>
      <zeebe:output source="=result.depth * 2" target="depth2"/>
    </zeebe:ioMapping></extensionElements></serviceTask>
  <serviceTask id="b"><extensionElements><zeebe:taskDefinition type="sys.b"/></extensionElements>
    <multiInstanceLoopCharacteristics><extensionElements>
      <zeebe:loopCharacteristics inputCollection="=sites[item != &quot;c&quot;]" inputElement="site"/>
    </extensionElements></multiInstanceLoopCharacteristics></serviceTask>
  <endEvent id="e"/><endEvent id="e2"/>
  <sequenceFlow id="f1" sourceRef="s" targetRef="half"/>
  <sequenceFlow id="f2" sourceRef="half" targetRef="g"/>
  <sequenceFlow id="yes" sourceRef="g" targetRef="a"><conditionExpression xsi:type="tFormalExpression">=half = 1.5 and list contains(sites, "a")</conditionExpression></sequenceFlow>
  <sequenceFlow id="other" sourceRef="g" targetRef="e2"/>
  <sequenceFlow id="f3" sourceRef="a" targetRef="b"/>
  <sequenceFlow id="f4" sourceRef="b" targetRef="e"/>
</process>"#;

fn strings(items: &[&str]) -> Value {
    Value::List(
        items
            .iter()
            .map(|s| Value::String((*s).to_owned()))
            .collect(),
    )
}

#[test]
fn a_camunda_8_model_runs_with_feel_semantics() {
    let mut d = Driver::new(CAMUNDA8);
    // `3 / 2` is 1.5 in FEEL (CEL would give 1).
    assert_eq!(
        d.start(&[("n", Value::Int(3)), ("sites", strings(&["a", "b", "c"]))]),
        ["dispatch a"]
    );
    let goal = d.request("a");
    assert_eq!(goal["codes"], Value::String("A,B,C".into()));
    assert_eq!(
        goal["scratch"],
        Value::Null,
        "an input without a source is null"
    );
    assert_eq!(goal["label"], Value::String("static text".into()));
    let result = Value::Map([("depth".to_owned(), Value::Float(crate::value::F64(2.5)))].into());
    assert_eq!(
        d.complete("a", &[("result", result)]),
        ["dispatch b", "dispatch b"],
        "the filtered collection has two items"
    );
    let vars =
        &d.e.state()
            .scopes
            .values()
            .next()
            .expect("the process scope")
            .vars;
    assert_eq!(
        vars["depth2"],
        Value::Int(5),
        "2.5 * 2 is the whole number 5"
    );
    assert_eq!(vars["half"], Value::Float(crate::value::F64(1.5)));
}

#[test]
fn a_feel_comparison_with_null_is_false_and_an_ordering_with_null_an_incident_saying_why() {
    // `missing = 1.5` is false in Camunda's FEEL (null compared with a value), so the default
    // flow is taken rather than an incident raised.
    let mut d = Driver::new(&CAMUNDA8.replace(
        "=half = 1.5 and list contains(sites, \"a\")",
        "=missing = 1.5",
    ));
    assert_eq!(
        d.start(&[("n", Value::Int(3)), ("sites", strings(&["a"]))]),
        ["completed"]
    );
    // A comparison that is null (ordering against null) is not a boolean: an incident that
    // says why.
    let mut d = Driver::new(&CAMUNDA8.replace(
        "=half = 1.5 and list contains(sites, \"a\")",
        "=missing &gt; 1",
    ));
    let out = d.start(&[("n", Value::Int(3)), ("sites", strings(&["a"]))]);
    assert_eq!(out.len(), 1, "{out:?}");
    assert!(
        out[0].starts_with("incident") && out[0].contains("no variable `missing`"),
        "{out:?}"
    );
}

#[test]
fn feel_timer_values_arm_timers() {
    // A FEEL duration value and a FEEL string both arm the timer, from the step's mission time.
    for duration in [
        "=duration(&quot;PT1H&quot;)",
        "=&quot;PT&quot; + string(hours) + &quot;H&quot;",
    ] {
        let mut d = Driver::new(&format!(
            r#"<process id="p" isExecutable="true"><startEvent id="s"/>
            <intermediateCatchEvent id="t"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">{duration}</timeDuration></timerEventDefinition></intermediateCatchEvent>
            <endEvent id="e"/>
            {}{}</process>"#,
            flow("f1", "s", "t"),
            flow("f2", "t", "e"),
        ));
        d.now = 1_795_000_000_000;
        assert_eq!(
            d.start(&[("hours", Value::Int(1))]),
            ["timer 3600000"],
            "{duration}"
        );
        assert_eq!(d.fire(0, 3_600_000), ["completed"]);
    }
}

#[test]
fn now_is_the_mission_time_of_the_step() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <serviceTask id="a"><extensionElements><zeebe:taskDefinition type="sys.a"/><zeebe:ioMapping>
          <zeebe:input source="=string(now())" target="at"/>
          <zeebe:input source="=string(today())" target="day"/>
        </zeebe:ioMapping></extensionElements></serviceTask>
        <endEvent id="e"/>{}{}</process>"#,
        flow("f1", "s", "a"),
        flow("f2", "a", "e"),
    ));
    // 2026-11-23T10:00:00Z
    d.now = 1_795_428_000_000;
    d.start(&[]);
    let goal = d.request("a");
    assert_eq!(goal["at"], Value::String("2026-11-23T10:00:00Z".into()));
    assert_eq!(goal["day"], Value::String("2026-11-23".into()));
}

#[test]
fn feel_correlation_keys_match_messages() {
    let mut d = Driver::new(&format!(
        r#"<message id="m" name="sample-ready"><extensionElements><zeebe:subscription correlationKey="=&quot;site-&quot; + string(site)"/></extensionElements></message>
        <process id="p" isExecutable="true"><startEvent id="s"/>
        <intermediateCatchEvent id="c"><messageEventDefinition messageRef="m"/></intermediateCatchEvent>
        <endEvent id="e"/>{}{}</process>"#,
        flow("f1", "s", "c"),
        flow("f2", "c", "e"),
    ));
    d.start(&[("site", Value::Int(7))]);
    let key = |k: &str| Some(Value::String(k.to_owned()));
    assert_eq!(
        d.message("sample-ready", key("site-8"), &[])
            .expect("accepted"),
        none()
    );
    assert_eq!(
        d.message("sample-ready", key("site-7"), &[])
            .expect("accepted"),
        ["completed"]
    );
}

#[test]
fn mappings_see_earlier_targets_then_the_result_then_process_variables() {
    // Camunda: mappings are evaluated in order, a source sees the targets before it; output
    // mappings see the result (as local variables) and the process variables.
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <serviceTask id="a"><extensionElements><zeebe:taskDefinition type="sys.a"/><zeebe:ioMapping>
          <zeebe:input source="=data.total" target="t"/>
          <zeebe:input source="=t + 1" target="u"/>
          <zeebe:output source="=result + data.total" target="r2"/>
          <zeebe:output source="=r2 * 2" target="r3"/>
        </zeebe:ioMapping></extensionElements></serviceTask>
        {}<endEvent id="e"/>{}{}{}</process>"#,
        task("b", "f2", "f3"),
        flow("f1", "s", "a"),
        flow("f2", "a", "b"),
        flow("f3", "b", "e"),
    ));
    let data = Value::Map([("total".to_owned(), Value::Int(10))].into());
    d.start(&[("data", data)]);
    let goal = d.request("a");
    assert_eq!((&goal["t"], &goal["u"]), (&Value::Int(10), &Value::Int(11)));
    assert_eq!(
        d.complete("a", &[("result", Value::Int(5))]),
        ["dispatch b"]
    );
    let vars =
        &d.e.state()
            .scopes
            .values()
            .next()
            .expect("the process scope")
            .vars;
    assert_eq!(
        (&vars["r2"], &vars["r3"]),
        (&Value::Int(15), &Value::Int(30))
    );
}

#[test]
fn camunda_8_completion_conditions_read_number_of_instances() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <serviceTask id="a"><extensionElements><zeebe:taskDefinition type="sys.a"/></extensionElements>
          <multiInstanceLoopCharacteristics>
            <extensionElements><zeebe:loopCharacteristics inputCollection="=[1, 2, 3, 4]" inputElement="i"/></extensionElements>
            <completionCondition xsi:type="tFormalExpression">=numberOfCompletedInstances / numberOfInstances &gt;= 0.5</completionCondition>
          </multiInstanceLoopCharacteristics></serviceTask>
        <endEvent id="e"/>{}{}</process>"#,
        flow("f1", "s", "a"),
        flow("f2", "a", "e"),
    ));
    assert_eq!(d.start(&[]).len(), 4);
    assert_eq!(d.complete_nth(0, &[]), none());
    // Two of four completed: the condition holds, the other two are cancelled.
    let out = d.complete_nth(1, &[]);
    assert_eq!(out.last().map(String::as_str), Some("completed"), "{out:?}");
}

#[test]
fn a_null_correlation_key_matches_no_keyed_receiver() {
    let mut d = Driver::new(&format!(
        r#"<message id="m" name="ready"><extensionElements><zeebe:subscription correlationKey="=site"/></extensionElements></message>
        <process id="p" isExecutable="true"><startEvent id="s"/>
        <intermediateCatchEvent id="c"><messageEventDefinition messageRef="m"/></intermediateCatchEvent>
        <endEvent id="e"/>{}{}</process>"#,
        flow("f1", "s", "c"),
        flow("f2", "c", "e"),
    ));
    // The instance has no `site`: its key is null, which nothing matches.
    d.start(&[]);
    assert_eq!(
        d.message("ready", Some(Value::Null), &[])
            .expect("accepted"),
        none()
    );
    assert_eq!(
        d.message("ready", Some(Value::String("x".into())), &[])
            .expect("accepted"),
        none()
    );
}
