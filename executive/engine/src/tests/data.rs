//! Chapter 10.4 / 13.3 semantics: data objects, properties, data stores, ioSpecification, data
//! associations, input and output sets, call activity and global task data, multi-instance
//! data (rules in docs/engine-semantics.md).

use super::*;

fn int(i: i64) -> Value {
    Value::Int(i)
}

/// The goals of every dispatch of `node` still running, in dispatch order.
fn requests(d: &Driver, node: &str) -> Vec<Vars> {
    let flying = d.e.in_flight();
    d.tasks
        .iter()
        .filter(|(n, _)| n == node)
        .filter_map(|(_, k)| {
            flying.iter().find_map(|a| match a {
                Action::DispatchTask { task, request, .. } if task == k => Some(request.clone()),
                _ => None,
            })
        })
        .collect()
}

/// The variables of the instance's process scope (the root scope of the first instance).
fn root_vars(d: &Driver) -> Vars {
    d.e.state()
        .scopes
        .values()
        .find(|s| s.parent.is_none())
        .map(|s| s.vars.clone())
        .expect("the instance is running")
}

/// A service task bound to `sys.<id>` with the given trace inputs (`target=source`) and extra
/// standard children (ioSpecification, data associations, loop characteristics).
fn bound(id: &str, inputs: &[(&str, &str)], body: &str) -> String {
    let inputs: String = inputs
        .iter()
        .map(|(t, s)| format!(r#"<trace:input target="{t}" source="{s}"/>"#))
        .collect();
    format!(
        r#"<serviceTask id="{id}"><extensionElements><trace:task resource="sys.{id}">{inputs}</trace:task></extensionElements>{body}</serviceTask>"#
    )
}

/// A process `p` with start `s` -> `nodes`... -> end `e`, in a line (ids in `chain`).
fn line(decls: &str, nodes: &str, chain: &[&str]) -> String {
    let mut flows = String::new();
    let mut prev = "s";
    for (i, n) in chain.iter().chain(std::iter::once(&"e")).enumerate() {
        flows.push_str(&flow(&format!("l{i}"), prev, n));
        prev = n;
    }
    format!(
        r#"<process id="p" isExecutable="true">{decls}<startEvent id="s"/>{nodes}<endEvent id="e"/>{flows}</process>"#
    )
}

// ---------------------------------------------------------------------------------------------
// Visibility (§10.4.1 Data Objects, Properties)
// ---------------------------------------------------------------------------------------------

/// §10.4.1: a data object (or property) of a process is visible to every element of the
/// process, sub-processes included.
#[test]
fn process_data_is_visible_inside_nested_sub_processes() {
    let mut d = Driver::new(&line(
        r#"<dataObject id="DO_x" name="x"/><property id="P_k" name="k"/>"#,
        &format!(
            r#"<subProcess id="sp"><startEvent id="s2"/><subProcess id="sp2"><startEvent id="s3"/>
            <scriptTask id="calc" scriptFormat="cel"><script>y = x + k</script></scriptTask><endEvent id="e3"/>{}{}</subProcess>
            <endEvent id="e2"/>{}{}</subProcess>{}"#,
            flow("g1", "s3", "calc"),
            flow("g2", "calc", "e3"),
            flow("h1", "s2", "sp2"),
            flow("h2", "sp2", "e2"),
            bound("b", &[("y", "y")], ""),
        ),
        &["sp", "b"],
    ));
    assert_eq!(d.start(&[("x", int(1)), ("k", int(10))]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("y", int(11))]));
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §10.4.1: a data object (and a property) declared in a sub-process is instantiated with the
/// sub-process and disposed of with it: the sub-process's elements see it, nothing outside
/// does, and the process's variable of the same name is not touched.
#[test]
fn sub_process_data_lives_and_dies_with_the_sub_process() {
    let mut d = Driver::new(&line(
        r#"<dataObject id="DO_tmp_outer" name="outer"/>"#,
        &format!(
            r#"<subProcess id="sp"><dataObject id="DO_tmp" name="tmp"/><property id="P_note" name="note"/>
            <startEvent id="s2"/><scriptTask id="w" scriptFormat="cel"><script>tmp = 5
note = "inner"
outer = 1</script></scriptTask>{}<endEvent id="e2"/>{}{}{}</subProcess>{}"#,
            bound("a", &[("tmp", "tmp"), ("note", "note")], ""),
            flow("g1", "s2", "w"),
            flow("g2", "w", "a"),
            flow("g3", "a", "e2"),
            bound("b", &[], ""),
        ),
        &["sp", "b"],
    ));
    assert_eq!(d.start(&[("note", Value::from("outer"))]), ["dispatch a"]);
    assert_eq!(
        d.request("a"),
        vars(&[("note", Value::from("inner")), ("tmp", int(5))])
    );
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    let root = root_vars(&d);
    assert_eq!(
        root.get("tmp"),
        None,
        "the sub-process's data object leaked"
    );
    assert_eq!(root.get("note"), Some(&Value::from("outer")));
    // A data object of the process written from inside is the process's.
    assert_eq!(root.get("outer"), Some(&int(1)));
}

/// §10.4.1 with §13.3.7: every instance of a multi-instance sub-process is a sub-process
/// instance of its own, with its own data objects; instances do not see each other's.
#[test]
fn each_multi_instance_sub_process_has_its_own_data_objects() {
    let mut d = Driver::new(&line(
        "",
        &format!(
            r#"<subProcess id="sp"><multiInstanceLoopCharacteristics camunda:collection="sites" camunda:elementVariable="site"/>
            <dataObject id="DO_tmp" name="tmp"/>
            <startEvent id="s2"/><scriptTask id="w" scriptFormat="cel"><script>tmp = site * 10</script></scriptTask>
            {}{}<endEvent id="e2"/>{}{}{}{}</subProcess>"#,
            bound("a", &[], ""),
            bound("b", &[("tmp", "tmp")], ""),
            flow("g1", "s2", "w"),
            flow("g2", "w", "a"),
            flow("g3", "a", "b"),
            flow("g4", "b", "e2"),
        ),
        &["sp"],
    ));
    let sites = Value::List(vec![int(7), int(8)]);
    assert_eq!(d.start(&[("sites", sites)]), ["dispatch a", "dispatch a"]);
    // The first instance goes on after the second one wrote its own `tmp`.
    assert_eq!(d.complete_nth(0, &[]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("tmp", int(70))]));
    assert_eq!(d.complete_nth(1, &[]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("tmp", int(80))]));
}

// ---------------------------------------------------------------------------------------------
// Data associations (§10.4.1 DataAssociation, §10.4.2 Execution Semantics for Data)
// ---------------------------------------------------------------------------------------------

/// A task `id` with one data input `<id>_in` named `input` fed from `source` (an item-aware
/// element id), and one data output `<id>_out` named `output` copied to `target`.
fn io(input: Option<(&str, &str)>, output: Option<(&str, &str)>) -> String {
    let mut spec = String::from("<ioSpecification>");
    let mut assoc = String::new();
    if let Some((name, source)) = input {
        spec.push_str(&format!(r#"<dataInput id="i_{name}" name="{name}"/>"#));
        assoc.push_str(&format!(
            r#"<dataInputAssociation><sourceRef>{source}</sourceRef><targetRef>i_{name}</targetRef></dataInputAssociation>"#
        ));
    }
    if let Some((name, _)) = output {
        spec.push_str(&format!(r#"<dataOutput id="o_{name}" name="{name}"/>"#));
    }
    spec.push_str("<inputSet>");
    if let Some((name, _)) = input {
        spec.push_str(&format!("<dataInputRefs>i_{name}</dataInputRefs>"));
    }
    spec.push_str("</inputSet><outputSet>");
    if let Some((name, target)) = output {
        spec.push_str(&format!("<dataOutputRefs>o_{name}</dataOutputRefs>"));
        assoc.push_str(&format!(
            r#"<dataOutputAssociation><sourceRef>o_{name}</sourceRef><targetRef>{target}</targetRef></dataOutputAssociation>"#
        ));
    }
    spec.push_str("</outputSet></ioSpecification>");
    spec + &assoc
}

const SITE_AND_DEPTH: &str = r#"<dataObject id="DO_site" name="site"/><dataObjectReference id="R_site" dataObjectRef="DO_site"/>
    <dataObject id="DO_measured" name="measured"/><dataObjectReference id="R_measured" dataObjectRef="DO_measured"/>"#;

/// A `line` with `decls` through the task `a`, then `b`, which reads `measured` as `m`.
fn a_then_b_reading_measured(decls: &str, a: &str) -> String {
    line(
        decls,
        &format!("{a}{}", bound("b", &[("m", "measured")], "")),
        &["a", "b"],
    )
}

/// §10.4.2, §13.3.2: before the task starts, its data input association copies the data object
/// (through a data object reference) into the task's data input; a declared ioSpecification
/// is the task's interface, so the goal holds exactly its data inputs, by name.
#[test]
fn data_input_association_fills_the_task_input_before_it_starts() {
    let mut d = Driver::new(&line(
        SITE_AND_DEPTH,
        &bound("a", &[], &io(Some(("target", "R_site")), None)),
        &["a"],
    ));
    assert_eq!(d.start(&[("site", int(5))]), ["dispatch a"]);
    assert_eq!(d.request("a"), vars(&[("target", int(5))]));
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// §10.4.2, §13.3.2: when the task completes, its data output association copies the data
/// output (the result field of that name) into the data object; the data output itself is the
/// task's, not a variable of the process.
#[test]
fn data_output_association_copies_the_output_into_the_data_object_on_completion() {
    let mut d = Driver::new(&a_then_b_reading_measured(
        SITE_AND_DEPTH,
        &bound("a", &[], &io(None, Some(("depth", "R_measured")))),
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[("depth", int(12))]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("m", int(12))]));
    assert_eq!(root_vars(&d).get("depth"), None);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §10.4.1 (Execution Semantics for DataAssociation): a transformation is evaluated and its
/// result replaces the target; then each assignment evaluates `from` and writes it to the
/// element `to` designates. On the way out, the transformation sees the data outputs.
#[test]
fn transformation_then_assignments_compute_what_is_copied() {
    let a = bound(
        "a",
        &[],
        r#"<ioSpecification><dataInput id="i1" name="doubled"/><dataInput id="i2" name="pos"/><dataOutput id="o1" name="depth"/>
        <inputSet><dataInputRefs>i1</dataInputRefs><dataInputRefs>i2</dataInputRefs></inputSet>
        <outputSet><dataOutputRefs>o1</dataOutputRefs></outputSet></ioSpecification>
      <dataInputAssociation><sourceRef>R_site</sourceRef><targetRef>i1</targetRef>
        <transformation xsi:type="tFormalExpression">site * 2</transformation></dataInputAssociation>
      <dataInputAssociation><sourceRef>R_site</sourceRef><targetRef>i2</targetRef>
        <assignment><from xsi:type="tFormalExpression">site + 1</from><to xsi:type="tFormalExpression">pos.x</to></assignment>
        <assignment><from xsi:type="tFormalExpression">0</from><to xsi:type="tFormalExpression">pos.y</to></assignment></dataInputAssociation>
      <dataOutputAssociation><sourceRef>o1</sourceRef><targetRef>R_measured</targetRef>
        <transformation xsi:type="tFormalExpression">depth + 100</transformation></dataOutputAssociation>"#,
    );
    let mut d = Driver::new(&a_then_b_reading_measured(SITE_AND_DEPTH, &a));
    assert_eq!(d.start(&[("site", int(5))]), ["dispatch a"]);
    let pos = Value::Map(vars(&[("x", int(6)), ("y", int(0))]));
    assert_eq!(d.request("a"), vars(&[("doubled", int(10)), ("pos", pos)]));
    assert_eq!(d.complete("a", &[("depth", int(7))]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("m", int(107))]));
}

/// §10.4.1 Properties and Data Stores: a process property is a variable of the process; a data
/// store persists beyond the process (TRACE: the system data, e.g. telemetry), and both are
/// sources of data input associations.
#[test]
fn properties_and_data_stores_feed_data_inputs() {
    let a = bound(
        "a",
        &[],
        r#"<ioSpecification><dataInput id="i1" name="limit"/><dataInput id="i2" name="soc"/>
        <inputSet><dataInputRefs>i1</dataInputRefs><dataInputRefs>i2</dataInputRefs></inputSet><outputSet/></ioSpecification>
      <dataInputAssociation><sourceRef>P_budget</sourceRef><targetRef>i1</targetRef></dataInputAssociation>
      <dataInputAssociation><sourceRef>R_battery</sourceRef><targetRef>i2</targetRef></dataInputAssociation>"#,
    );
    let mut d = Driver::new(&format!(
        r#"<dataStore id="DS_battery" name="battery_soc_pct"/>{}"#,
        line(
            r#"<property id="P_budget" name="budget"/><dataStoreReference id="R_battery" dataStoreRef="DS_battery"/>"#,
            &a,
            &["a"],
        )
    ));
    d.step(Event::DataChanged {
        key: "battery_soc_pct".into(),
        value: int(64),
    })
    .expect("accepted");
    assert_eq!(d.start(&[("budget", int(3))]), ["dispatch a"]);
    assert_eq!(d.request("a"), vars(&[("limit", int(3)), ("soc", int(64))]));
}

// ---------------------------------------------------------------------------------------------
// Input and output sets (§10.4.2, §13.3.2)
// ---------------------------------------------------------------------------------------------

/// §10.4.2: if a source of a data association is unavailable, its InputSet is unavailable; with
/// no InputSet available the activity waits (it is not started) until a source is written, and
/// then starts. (Camunda 7 and 8 ignore ioSpecification: they would start it at once.)
#[test]
fn an_unavailable_input_set_holds_the_activity_until_its_source_is_written() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true">{SITE_AND_DEPTH}{}{}{}</process>"#,
        fork_into(&[&["b"], &["a"]]),
        bound("b", &[], &io(Some(("need", "R_measured")), None)),
        bound("a", &[], &io(None, Some(("depth", "R_measured")))),
    ));
    // `b` is reached first, but `measured` has no value yet.
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[("depth", int(3))]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("need", int(3))]));
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// A waiting activity is still an activity of its scope: an interrupting boundary timer
/// withdraws it, and it is never started afterwards even when its data arrives.
#[test]
fn an_activity_waiting_for_data_is_withdrawn_by_its_boundary_event() {
    let mut d = Driver::new(&line(
        SITE_AND_DEPTH,
        &format!(
            r#"{}<boundaryEvent id="t" attachedToRef="b">{}</boundaryEvent>
            {}<endEvent id="late"/>"#,
            bound("b", &[], &io(Some(("need", "R_measured")), None)),
            duration("PT1M"),
            flow("ft", "t", "late"),
        ),
        &["b"],
    ));
    assert_eq!(d.start(&[]), ["timer 60000"]);
    assert_eq!(d.fire(0, 60_000), ["completed"]);
}

/// Data objects `x1` and `x2`, and a task `a` whose data inputs `first` (`i1`, fed from `x1`)
/// and `second` (`i2`, fed from `x2`) are grouped into `input_sets`.
fn first_and_second(input_sets: &str) -> String {
    let a = bound(
        "a",
        &[],
        &format!(
            r#"<ioSpecification><dataInput id="i1" name="first"/><dataInput id="i2" name="second"/>{input_sets}<outputSet/></ioSpecification>
            <dataInputAssociation><sourceRef>DO_x1</sourceRef><targetRef>i1</targetRef></dataInputAssociation>
            <dataInputAssociation><sourceRef>DO_x2</sourceRef><targetRef>i2</targetRef></dataInputAssociation>"#
        ),
    );
    line(
        r#"<dataObject id="DO_x1" name="x1"/><dataObject id="DO_x2" name="x2"/>"#,
        &a,
        &["a"],
    )
}

/// §10.4.2 / §13.3.2: a data input that is optional in the InputSet does not make the set
/// unavailable; the activity starts without it.
#[test]
fn an_optional_input_may_be_unavailable() {
    let body = first_and_second(
        "<inputSet><dataInputRefs>i1</dataInputRefs><dataInputRefs>i2</dataInputRefs><optionalInputRefs>i2</optionalInputRefs></inputSet>",
    );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x1", int(1))]), ["dispatch a"]);
    assert_eq!(d.request("a"), vars(&[("first", int(1))]));
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x1", int(1)), ("x2", int(2))]), ["dispatch a"]);
    assert_eq!(
        d.request("a"),
        vars(&[("first", int(1)), ("second", int(2))])
    );
    // The required one is still required.
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x2", int(2))]), Vec::<String>::new());
}

/// §10.4.2 / §13.3.2: InputSets are evaluated in document order; the first available one starts
/// the activity (only its data inputs are filled), later ones are not evaluated.
#[test]
fn the_first_available_input_set_starts_the_activity() {
    let body = first_and_second(
        "<inputSet><dataInputRefs>i1</dataInputRefs></inputSet><inputSet><dataInputRefs>i2</dataInputRefs></inputSet>",
    );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x2", int(2))]), ["dispatch a"]);
    assert_eq!(d.request("a"), vars(&[("second", int(2))]));
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("x1", int(1)), ("x2", int(2))]), ["dispatch a"]);
    assert_eq!(d.request("a"), vars(&[("first", int(1))]));
}

/// §13.3.2: on completion the first OutputSet whose required data outputs are all available is
/// chosen and its output associations run; optional outputs may be missing; with no OutputSet
/// available the activity ends with an exception (TRACE: the BPMN error `TYPE_MISMATCH`, as for
/// any result that does not fit the task's declared outputs).
#[test]
fn an_unavailable_output_set_is_an_exception() {
    let a = bound(
        "a",
        &[],
        r#"<ioSpecification><dataOutput id="o1" name="depth"/><dataOutput id="o2" name="note"/><inputSet/>
        <outputSet><dataOutputRefs>o1</dataOutputRefs><dataOutputRefs>o2</dataOutputRefs><optionalOutputRefs>o2</optionalOutputRefs></outputSet></ioSpecification>
      <dataOutputAssociation><sourceRef>o1</sourceRef><targetRef>R_measured</targetRef></dataOutputAssociation>
      <dataOutputAssociation><sourceRef>o2</sourceRef><targetRef>DO_note</targetRef></dataOutputAssociation>"#,
    );
    let body = a_then_b_reading_measured(
        &format!(r#"{SITE_AND_DEPTH}<dataObject id="DO_note" name="note"/>"#),
        &a,
    );
    let mut d = Driver::new(&body);
    d.start(&[]);
    assert_eq!(d.complete("a", &[("depth", int(4))]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("m", int(4))]));
    assert_eq!(root_vars(&d).get("note"), None);
    let mut d = Driver::new(&body);
    d.start(&[]);
    assert_eq!(
        d.complete("a", &[("note", Value::from("no depth"))]),
        ["failed TYPE_MISMATCH"]
    );
}

// ---------------------------------------------------------------------------------------------
// Call activities and global tasks (§10.3.6, §10.3.7, §13.3.4)
// ---------------------------------------------------------------------------------------------

const CALLEE: &str = r#"<process id="q" isExecutable="true">
      <ioSpecification><dataInput id="q_in" name="arg"/><dataOutput id="q_out" name="res"/>
        <inputSet><dataInputRefs>q_in</dataInputRefs></inputSet><outputSet><dataOutputRefs>q_out</dataOutputRefs></outputSet></ioSpecification>
      <startEvent id="qs"/><serviceTask id="qa" implementation="sys.qa"/>
      <scriptTask id="qw" scriptFormat="cel"><script>res = arg * 2</script></scriptTask><endEvent id="qe"/>
      <sequenceFlow id="q1" sourceRef="qs" targetRef="qa"/><sequenceFlow id="q2" sourceRef="qa" targetRef="qw"/>
      <sequenceFlow id="q3" sourceRef="qw" targetRef="qe"/></process>"#;

/// `CALLEE` and a caller: `c` (the call activity), then `b` (fed `inputs`), with `decls`.
fn caller(decls: &str, c: &str, inputs: &[(&str, &str)]) -> String {
    format!(
        "{CALLEE}{}",
        line(
            decls,
            &format!("{c}{}", bound("b", inputs, "")),
            &["c", "b"]
        )
    )
}

/// Started with `site` 3 (and a `secret`), the callee sees `arg` 3 and nothing else; `b` then
/// gets the callee's `res` (6) as `m`, and `res` itself does not come back.
fn site_goes_in_as_arg_and_res_comes_back_as_measured(d: &mut Driver) {
    assert_eq!(
        d.start(&[("site", int(3)), ("secret", int(9))]),
        ["dispatch qa"]
    );
    assert_eq!(d.request("qa"), vars(&[("arg", int(3))]));
    assert_eq!(d.complete("qa", &[]), ["dispatch b"]);
    assert_eq!(d.request("b"), vars(&[("m", int(6))]));
    assert_eq!(root_vars(d).get("res"), None);
}

/// §10.3.6, §10.4.1 Data Inputs: a call activity passes data to the called process through its
/// own data inputs (filled by its associations), which are the called process's data inputs of
/// the same name; the called process sees those and nothing else of the caller; its data
/// outputs come back through the call activity's data outputs and their associations.
#[test]
fn call_activity_passes_data_through_its_io_specification() {
    let c = r#"<callActivity id="c" calledElement="q">
      <ioSpecification><dataInput id="c_in" name="arg"/><dataOutput id="c_out" name="res"/>
        <inputSet><dataInputRefs>c_in</dataInputRefs></inputSet><outputSet><dataOutputRefs>c_out</dataOutputRefs></outputSet></ioSpecification>
      <dataInputAssociation><sourceRef>R_site</sourceRef><targetRef>c_in</targetRef></dataInputAssociation>
      <dataOutputAssociation><sourceRef>c_out</sourceRef><targetRef>R_measured</targetRef></dataOutputAssociation>
    </callActivity>"#;
    let mut d = Driver::new(&caller(SITE_AND_DEPTH, c, &[("m", "measured")]));
    site_goes_in_as_arg_and_res_comes_back_as_measured(&mut d);
}

/// The Camunda mappings on a call activity (`camunda:in` / `camunda:out`): only the named
/// variables go in and come out.
#[test]
fn call_activity_camunda_mappings_pass_only_the_named_variables() {
    let c = r#"<callActivity id="c" calledElement="q"><extensionElements>
      <camunda:in source="site" target="arg"/><camunda:out source="res" target="measured"/></extensionElements></callActivity>"#;
    let mut d = Driver::new(&caller("", c, &[("m", "measured")]));
    site_goes_in_as_arg_and_res_comes_back_as_measured(&mut d);
}

/// Without any mapping the spec passes nothing. TRACE's documented choice (docs/engine-semantics.md,
/// call activity; Camunda 8's default `propagateAllParentVariables`): a copy of the caller's
/// variables goes in; nothing comes out (as the spec, and Camunda 7 without `camunda:out`).
#[test]
fn call_activity_without_mappings_copies_variables_in_and_nothing_out() {
    let mut d = Driver::new(&caller(
        "",
        r#"<callActivity id="c" calledElement="q"/>"#,
        &[],
    ));
    assert_eq!(d.start(&[("arg", int(3))]), ["dispatch qa"]);
    assert_eq!(d.request("qa"), vars(&[("arg", int(3))]));
    assert_eq!(d.complete("qa", &[]), ["dispatch b"]);
    assert_eq!(root_vars(&d).get("res"), None);
    assert_eq!(root_vars(&d).get("arg"), Some(&int(3)));
}

/// §10.3.7, §13.3.4: a call activity that calls a global task runs that task in its place:
/// a global business-rule task is dispatched with the global task's binding (its inputs from
/// the caller's variables, its outputs back into them); a global user task is opened; a global
/// CEL script task runs at once.
#[test]
fn a_call_activity_runs_the_global_task_it_calls() {
    let globals = r#"<globalBusinessRuleTask id="g_rule"><extensionElements><trace:task resource="sys.rule">
        <trace:input target="site_id" source="site"/><trace:output source="score" target="score"/></trace:task></extensionElements></globalBusinessRuleTask>
      <globalUserTask id="g_ask"><extensionElements><trace:task resource="ground.ask">
        <trace:output source="ok" target="ok" type="bool"/></trace:task></extensionElements></globalUserTask>
      <globalScriptTask id="g_calc" scriptFormat="cel"><script>total = score + 1</script></globalScriptTask>"#;
    let mut d = Driver::new(&format!(
        "{globals}{}",
        line(
            "",
            &format!(
                r#"<callActivity id="c1" calledElement="g_rule"/><callActivity id="c2" calledElement="g_ask"/><callActivity id="c3" calledElement="g_calc"/>{}"#,
                bound("b", &[("total", "total"), ("ok", "ok")], "")
            ),
            &["c1", "c2", "c3", "b"]
        )
    ));
    assert_eq!(d.start(&[("site", int(4))]), ["dispatch c1"]);
    assert_eq!(d.request("c1"), vars(&[("site_id", int(4))]));
    assert_eq!(
        d.complete("c1", &[("score", int(41)), ("noise", int(0))]),
        ["open c2"]
    );
    assert_eq!(root_vars(&d).get("noise"), None);
    let task = d.user[0].1;
    let out = d
        .step(Event::UserTaskAnswered {
            task,
            answer: vars(&[("ok", Value::Bool(true))]),
            operator: "ops".into(),
        })
        .expect("accepted");
    assert_eq!(out, ["close", "dispatch b"]);
    assert_eq!(
        d.request("b"),
        vars(&[("ok", Value::Bool(true)), ("total", int(42))])
    );
}

// ---------------------------------------------------------------------------------------------
// Multi-instance data (§10.3.8 MultiInstanceLoopCharacteristics, §13.3.7)
// ---------------------------------------------------------------------------------------------

/// §13.3.7: each instance gets its own input item (and loopCounter); the item is the
/// instance's, not visible after the activity.
#[test]
fn multi_instance_input_items_are_local_to_each_instance() {
    let mut d = Driver::new(&line(
        "",
        &format!(
            "{}{}",
            bound(
                "a",
                &[("site", "site"), ("n", "loopCounter")],
                r#"<multiInstanceLoopCharacteristics camunda:collection="sites" camunda:elementVariable="site"/>"#
            ),
            bound("b", &[], "")
        ),
        &["a", "b"],
    ));
    let sites = Value::List(vec![int(7), int(8)]);
    assert_eq!(d.start(&[("sites", sites)]), ["dispatch a", "dispatch a"]);
    assert_eq!(
        requests(&d, "a"),
        [
            vars(&[("n", int(1)), ("site", int(7))]),
            vars(&[("n", int(2)), ("site", int(8))])
        ]
    );
    d.complete_nth(1, &[]);
    assert_eq!(d.complete_nth(0, &[]), ["dispatch b"]);
    let root = root_vars(&d);
    assert_eq!(root.get("site"), None);
    assert_eq!(root.get("loopCounter"), None);
}

/// §10.3.8: `loopDataInputRef` references a data input of the activity's ioSpecification (here
/// filled from a data object by an association); one instance per item, whose
/// `inputDataItem` is the source of an association into the instance's own data input.
#[test]
fn loop_data_input_ref_names_a_data_input_of_the_activity() {
    let a = bound(
        "a",
        &[],
        r#"<ioSpecification><dataInput id="a_sites" name="all"/><dataInput id="a_one" name="target"/>
        <inputSet><dataInputRefs>a_sites</dataInputRefs><dataInputRefs>a_one</dataInputRefs></inputSet><outputSet/></ioSpecification>
      <dataInputAssociation><sourceRef>R_sites</sourceRef><targetRef>a_sites</targetRef></dataInputAssociation>
      <dataInputAssociation><sourceRef>a_item</sourceRef><targetRef>a_one</targetRef></dataInputAssociation>
      <multiInstanceLoopCharacteristics><loopDataInputRef>a_sites</loopDataInputRef><inputDataItem id="a_item" name="site"/></multiInstanceLoopCharacteristics>"#,
    );
    let mut d = Driver::new(&line(
        r#"<dataObject id="DO_sites" name="sites" isCollection="true"/><dataObjectReference id="R_sites" dataObjectRef="DO_sites"/>"#,
        &a,
        &["a"],
    ));
    let sites = Value::List(vec![int(7), int(8)]);
    assert_eq!(d.start(&[("sites", sites)]), ["dispatch a", "dispatch a"]);
    let got: Vec<Option<Value>> = requests(&d, "a")
        .iter()
        .map(|r| r.get("target").cloned())
        .collect();
    assert_eq!(got, [Some(int(7)), Some(int(8))]);
}

/// §10.3.8, §13.3.7: the `outputDataItem` is each instance's own; the output collection holds
/// the items in instance order, whatever order the instances complete in.
#[test]
fn multi_instance_output_items_are_per_instance_and_collected_in_order() {
    let mut d = Driver::new(&line(
        "",
        &format!(
            "{}{}",
            bound(
                "a",
                &[],
                r#"<multiInstanceLoopCharacteristics camunda:collection="sites" camunda:elementVariable="site">
                  <loopDataOutputRef>depths</loopDataOutputRef><outputDataItem id="a_depth" name="depth"/></multiInstanceLoopCharacteristics>"#
            ),
            bound("b", &[("all", "depths")], "")
        ),
        &["a", "b"],
    ));
    let sites = Value::List(vec![int(7), int(8)]);
    assert_eq!(d.start(&[("sites", sites)]), ["dispatch a", "dispatch a"]);
    assert_eq!(
        d.complete_nth(1, &[("depth", int(80))]),
        Vec::<String>::new()
    );
    assert_eq!(
        root_vars(&d).get("depth"),
        None,
        "an instance's item leaked"
    );
    assert_eq!(d.complete_nth(0, &[("depth", int(70))]), ["dispatch b"]);
    assert_eq!(
        d.request("b"),
        vars(&[("all", Value::List(vec![int(70), int(80)]))])
    );
    assert_eq!(root_vars(&d).get("depth"), None);
}
