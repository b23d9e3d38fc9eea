//! Chapter 13 semantics: conditional events around sub-processes (§10.5.2 and §10.5.4 tables of
//! event types, §10.5.5 ConditionalEventDefinition, §13.5.1-§13.5.4; rules in
//! docs/engine-semantics.md).

use super::*;

fn cond(c: &str) -> String {
    format!(
        r#"<conditionalEventDefinition><condition xsi:type="tFormalExpression">{c}</condition></conditionalEventDefinition>"#
    )
}

fn data(d: &mut Driver, key: &str, value: Value) -> Vec<String> {
    d.step(Event::DataChanged {
        key: key.into(),
        value,
    })
    .expect("accepted")
}

fn no() -> Vec<String> {
    Vec::new()
}

/// Process `p`: start, sub-process `sp` (start, task `a`, task `b`, end), task `z`, end; a
/// conditional boundary `cb` on `sp` (`interrupting`, condition `c`) leads to task `h`.
fn sub_with_boundary(interrupting: bool, c: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}
        <subProcess id="sp"><startEvent id="ss"/>{}{}{}{}{}<endEvent id="se"/></subProcess>
        <boundaryEvent id="cb" attachedToRef="sp" cancelActivity="{interrupting}">{}</boundaryEvent>
        {}{}{}{}{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "sp"),
        flow("i0", "ss", "a"),
        task("a", "i0", "i1"),
        flow("i1", "a", "b"),
        task("b", "i1", "i2"),
        flow("i2", "b", "se"),
        cond(c),
        flow("f1", "sp", "z"),
        task("z", "f1", "f2"),
        flow("f2", "z", "e"),
        flow("f3", "cb", "h"),
        task("h", "f3", "f4"),
        flow("f4", "h", "e"),
    )
}

// §10.5.4 (conditional boundary: triggered when its condition becomes true), §13.5.3: an
// interrupting boundary cancels the sub-process and follows its own flow. The condition turns
// true when task `a` inside writes its result (§13.3.2: outputs are assigned as the activity
// completes), so the event occurs then: the sub-process is interrupted before its next task
// starts, and its normal outgoing flow is never taken.
#[test]
fn interrupting_conditional_boundary_fires_when_an_inner_task_sets_the_variable() {
    let mut d = Driver::new(&sub_with_boundary(true, "done == true"));
    assert_eq!(d.start(&[("done", Value::Bool(false))]), ["dispatch a"]);
    assert_eq!(
        d.complete("a", &[("done", Value::Bool(true))]),
        ["dispatch h"]
    );
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

// The same interrupting boundary fired by system data: the running inner task is cancelled.
#[test]
fn interrupting_conditional_boundary_on_data_change_cancels_the_inner_task() {
    let mut d = Driver::new(&sub_with_boundary(true, "level &gt; 5.0"));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(data(&mut d, "level", Value::from(3.0)), no());
    assert_eq!(
        data(&mut d, "level", Value::from(7.0)),
        ["cancel a", "dispatch h"]
    );
    // The cancelled task's late result is refused.
    let late = d.key("a");
    let r = d.step(Event::TaskCompleted {
        task: late,
        output: Vars::new(),
    });
    assert!(matches!(r, Err(Rejected::UnknownTask(_))), "{r:?}");
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

// §13.5.3: a non-interrupting boundary leaves the sub-process running and adds a token on its
// flow. §10.5.2 (conditional start event, the rule conditional events share): the condition
// must become false and then true before the event is triggered again, so while it stays true
// (set true again by the next inner task) nothing more fires.
#[test]
fn non_interrupting_conditional_boundary_fires_once_while_the_condition_stays_true() {
    let mut d = Driver::new(&sub_with_boundary(false, "done == true"));
    assert_eq!(d.start(&[("done", Value::Bool(false))]), ["dispatch a"]);
    assert_eq!(
        d.complete("a", &[("done", Value::Bool(true))]),
        ["dispatch b", "dispatch h"]
    );
    assert_eq!(d.complete("h", &[]), no());
    assert_eq!(
        d.complete("b", &[("done", Value::Bool(true))]),
        ["dispatch z"]
    );
    assert_eq!(d.complete("z", &[]), ["completed"]);
}

// The false -> true edge, on system data: true, still true (nothing), false, true again (fires
// again); after the sub-process completed its boundary listens no more.
#[test]
fn non_interrupting_conditional_boundary_fires_on_each_false_to_true_edge_while_active() {
    let mut d = Driver::new(&sub_with_boundary(false, "level &gt; 5.0"));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(data(&mut d, "level", Value::from(7.0)), ["dispatch h"]);
    assert_eq!(data(&mut d, "level", Value::from(8.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(3.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(9.0)), ["dispatch h"]);
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["dispatch z"]);
    assert_eq!(data(&mut d, "level", Value::from(1.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(10.0)), no());
    let hs: Vec<TaskKey> = d
        .tasks
        .iter()
        .filter(|(n, _)| n == "h")
        .map(|(_, k)| *k)
        .collect();
    assert_eq!(hs.len(), 2);
    for k in hs {
        let out = d
            .step(Event::TaskCompleted {
                task: k,
                output: Vars::new(),
            })
            .expect("accepted");
        assert_eq!(out, no());
    }
    assert_eq!(d.complete("z", &[]), ["completed"]);
}

// §10.5.4 is silent on a condition already true when the activity starts (the event is
// "triggered when the condition becomes true"). TRACE, like Camunda 7 and 8 ("triggering on
// scope activation"), evaluates it when the boundary starts listening and fires at once; a
// non-interrupting one then fires no more while the condition stays true.
#[test]
fn conditional_boundary_already_true_when_the_sub_process_starts_fires_at_once_and_only_once() {
    let mut d = Driver::new(&sub_with_boundary(false, "go == true"));
    assert_eq!(
        d.start(&[("go", Value::Bool(true))]),
        ["dispatch a", "dispatch h"]
    );
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("h", &[]), no());
    assert_eq!(d.complete("b", &[]), ["dispatch z"]);

    let mut d = Driver::new(&sub_with_boundary(true, "go == true"));
    let out = d.start(&[("go", Value::Bool(true))]);
    assert_eq!(
        out.last().map(String::as_str),
        Some("dispatch h"),
        "{out:?}"
    );
    assert!(!out.iter().any(|a| a == "dispatch z"), "{out:?}");
}

// Top-down (Camunda 7's order; the spec is silent): one data change makes both the interrupting
// boundary of the sub-process and the interrupting boundary of the task inside it true. The
// outer one fires; the inner activity is cancelled with the sub-process, so its own boundary
// never fires.
#[test]
fn outer_interrupting_conditional_boundary_wins_over_an_inner_one_on_the_same_change() {
    let body = sub_with_boundary(true, "level &gt; 5.0").replace(
        "</subProcess>",
        &format!(
            r#"<boundaryEvent id="ib" attachedToRef="a">{}</boundaryEvent>{}{}{}</subProcess>"#,
            cond("level &gt; 5.0"),
            flow("i3", "ib", "ih"),
            task("ih", "i3", "i4"),
            flow("i4", "ih", "se"),
        ),
    );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(
        data(&mut d, "level", Value::from(7.0)),
        ["cancel a", "dispatch h"]
    );
}

/// Process `p`: start, sub-process `sp` (start, task `a`, end, and an event sub-process `esp`
/// whose conditional start `cs` (`interrupting`, condition `c`) leads to task `eh`), task `z`,
/// end.
fn sub_with_event_sub(interrupting: bool, c: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}
        <subProcess id="sp"><startEvent id="ss"/>{}{}{}<endEvent id="se"/>
          <subProcess id="esp" triggeredByEvent="true"><startEvent id="cs" isInterrupting="{interrupting}">{}</startEvent>{}{}{}<endEvent id="ee"/></subProcess>
        </subProcess>
        {}{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "sp"),
        flow("i0", "ss", "a"),
        task("a", "i0", "i1"),
        flow("i1", "a", "se"),
        cond(c),
        flow("j0", "cs", "eh"),
        task("eh", "j0", "j1"),
        flow("j1", "eh", "ee"),
        flow("f1", "sp", "z"),
        task("z", "f1", "f2"),
        flow("f2", "z", "e"),
    )
}

// §13.5.4: an interrupting event sub-process cancels the rest of its enclosing sub-process and
// runs in its place; the sub-process completes when the event sub-process does, then the
// process moves on along the sub-process's outgoing flow.
#[test]
fn interrupting_conditional_event_sub_process_inside_a_sub_process_replaces_its_content() {
    let mut d = Driver::new(&sub_with_event_sub(true, "level &gt; 5.0"));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(
        data(&mut d, "level", Value::from(7.0)),
        ["cancel a", "dispatch eh"]
    );
    // Interrupted once: it does not fire again.
    assert_eq!(data(&mut d, "level", Value::from(1.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(8.0)), no());
    assert_eq!(d.complete("eh", &[]), ["dispatch z"]);
    assert_eq!(d.complete("z", &[]), ["completed"]);
}

// §13.5.4: a non-interrupting event sub-process runs beside the sub-process's content, once per
// false -> true edge of its condition; the sub-process completes only when all of them and its
// content are done. Its condition may be set by the content itself (a task's result).
#[test]
fn non_interrupting_conditional_event_sub_process_runs_beside_on_each_edge() {
    let mut d = Driver::new(&sub_with_event_sub(false, "level &gt; 5.0"));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(data(&mut d, "level", Value::from(7.0)), ["dispatch eh"]);
    assert_eq!(data(&mut d, "level", Value::from(9.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(2.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(6.0)), ["dispatch eh"]);
    assert_eq!(d.complete("a", &[]), no());
    let ehs: Vec<TaskKey> = d
        .tasks
        .iter()
        .filter(|(n, _)| n == "eh")
        .map(|(_, k)| *k)
        .collect();
    let first = d
        .step(Event::TaskCompleted {
            task: ehs[0],
            output: Vars::new(),
        })
        .expect("accepted");
    assert_eq!(first, no());
    let last = d
        .step(Event::TaskCompleted {
            task: ehs[1],
            output: Vars::new(),
        })
        .expect("accepted");
    assert_eq!(last, ["dispatch z"]);
    // The event sub-process listened only while its sub-process ran.
    assert_eq!(data(&mut d, "level", Value::from(0.0)), no());
    assert_eq!(data(&mut d, "level", Value::from(9.0)), no());
}

// The event sub-process's condition read from a variable a task inside the sub-process writes.
#[test]
fn conditional_event_sub_process_fires_when_an_inner_task_writes_the_variable() {
    let body = sub_with_event_sub(true, "found == true")
        .replace(
            r#"<endEvent id="se"/>"#,
            &format!(
                r#"{}{}<endEvent id="se"/>"#,
                task("b", "", ""),
                flow("i2", "b", "se")
            ),
        )
        .replace(
            r#"<sequenceFlow id="i1" sourceRef="a" targetRef="se"/>"#,
            &flow("i1", "a", "b"),
        );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[("found", Value::Bool(false))]), ["dispatch a"]);
    assert_eq!(
        d.complete("a", &[("found", Value::Bool(true))]),
        ["dispatch eh"]
    );
    assert_eq!(d.complete("eh", &[]), ["dispatch z"]);
}

// The condition turns true as the sub-process's last task writes its result: the event occurs
// while the sub-process is still active (its content has not completed yet), so the
// non-interrupting event sub-process runs, and the sub-process completes after it.
#[test]
fn conditional_event_sub_process_made_true_by_the_last_inner_task_still_runs() {
    let mut d = Driver::new(&sub_with_event_sub(false, "level &gt; 5.0"));
    assert_eq!(d.start(&[("level", Value::from(0.0))]), ["dispatch a"]);
    assert_eq!(
        d.complete("a", &[("level", Value::from(7.0))]),
        ["dispatch eh"]
    );
    assert_eq!(d.complete("eh", &[]), ["dispatch z"]);
}

/// Process `p`: start, conditional intermediate catch `c` (condition `cnd`), end.
fn catch_process(cnd: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<intermediateCatchEvent id="c">{}</intermediateCatchEvent>{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "c"),
        cond(cnd),
        flow("f1", "c", "e"),
    )
}

// §13.5.2: waiting starts when the catch event is reached. The spec does not say whether a
// condition already true then counts as "becoming true"; TRACE evaluates it on arrival and
// passes at once (Camunda 7: "when the execution arrives at the catching event, the condition is
// evaluated for the first time"; Camunda 8 likewise on activation).
#[test]
fn conditional_catch_already_true_on_arrival_passes_at_once() {
    let mut d = Driver::new(&catch_process("x &gt; 0"));
    assert_eq!(d.start(&[("x", Value::Int(1))]), ["completed"]);
    let mut d = Driver::new(&catch_process("heater &gt; 0.0"));
    assert_eq!(data(&mut d, "heater", Value::from(5.0)), no());
    assert_eq!(d.start(&[]), ["completed"]);
}

// A condition is re-evaluated after every step, over process variables as well as system data:
// a catch on one branch passes exactly when a task on the other branch has made it true.
#[test]
fn conditional_catch_is_re_evaluated_after_every_step() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}
        <intermediateCatchEvent id="c">{}</intermediateCatchEvent>{}{}
        {}{}{}{}{}<parallelGateway id="join"/>{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "fork"),
        flow("f1", "fork", "c"),
        flow("f2", "fork", "a"),
        cond("count &gt;= 2"),
        flow("f3", "c", "w"),
        task("w", "f3", "f4"),
        task("a", "f2", "f5"),
        flow("f5", "a", "b"),
        task("b", "f5", "f6"),
        flow("f6", "b", "join"),
        flow("f4", "w", "join"),
        flow("f7", "join", "e"),
    ));
    assert_eq!(d.start(&[("count", Value::Int(0))]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[("count", Value::Int(1))]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[("count", Value::Int(2))]), ["dispatch w"]);
    assert_eq!(d.complete("w", &[]), ["completed"]);
}

// A condition that cannot be evaluated yet (its variable is missing) is false: no firing, no
// incident; it fires once the data exists and makes it true.
#[test]
fn conditional_catch_over_missing_data_waits_without_incident() {
    let mut d = Driver::new(&catch_process("pressure &gt; 2.0"));
    assert_eq!(d.start(&[]), no());
    assert_eq!(data(&mut d, "other", Value::from(1.0)), no());
    assert!(
        d.e.state()
            .instances
            .values()
            .all(|i| i.incidents.is_empty())
    );
    assert_eq!(data(&mut d, "pressure", Value::from(3.0)), ["completed"]);
}

// §13.5.1 with Table 10.84 (§10.5.2): a conditional start event of a top-level process starts a
// new instance when its condition becomes true, and again only after it has become false and
// then true again. (Camunda 7 and 8 evaluate root conditional start events only on an API call.)
#[test]
fn conditional_start_event_starts_an_instance_on_each_false_to_true_edge() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s">{}</startEvent>{}{}{}<endEvent id="e"/></process>"#,
        cond("temp &gt; 300.0"),
        flow("f0", "s", "a"),
        task("a", "f0", "f1"),
        flow("f1", "a", "e"),
    ));
    assert_eq!(data(&mut d, "temp", Value::from(20.0)), no());
    assert_eq!(data(&mut d, "temp", Value::from(310.0)), ["dispatch a"]);
    assert_eq!(data(&mut d, "temp", Value::from(320.0)), no());
    assert_eq!(data(&mut d, "temp", Value::from(100.0)), no());
    assert_eq!(data(&mut d, "temp", Value::from(305.0)), ["dispatch a"]);
    assert_eq!(d.e.state().instances.len(), 2);
}
