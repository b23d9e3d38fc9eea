//! Chapter 13 semantics: conditional events around sub-processes (§10.5.2 and §10.5.4 tables of
//! event types, §10.5.5 ConditionalEventDefinition, §13.5.1-§13.5.4; rules in
//! docs/engine-semantics.md).

use super::*;

fn cond(c: &str) -> String {
    format!(
        r#"<conditionalEventDefinition><condition xsi:type="tFormalExpression">{c}</condition></conditionalEventDefinition>"#
    )
}

/// The system data `level` changes to `v`.
fn level(d: &mut Driver, v: f64) -> Vec<String> {
    d.data("level", Value::from(v))
}

/// Process `p`: start, sub-process `sp` (start, task `a`, task `b`, end), task `z`, end; a
/// conditional boundary `cb` on `sp` (`interrupting`, condition `c`) leads to task `h`.
fn sub_with_boundary(interrupting: bool, c: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <subProcess id="sp"><startEvent id="ss"/>{}<endEvent id="se"/></subProcess>
        <boundaryEvent id="cb" attachedToRef="sp" cancelActivity="{interrupting}">{}</boundaryEvent>
        {}{}{}<endEvent id="e"/></process>"#,
        path("i", &["ss", "a", "b", "se"]) + &tasks(&["a", "b"]),
        cond(c),
        path("f", &["s", "sp", "z", "e"]),
        path("h", &["cb", "h", "e"]),
        tasks(&["z", "h"]),
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
    assert_eq!(level(&mut d, 3.0), none());
    assert_eq!(level(&mut d, 7.0), ["cancel a", "dispatch h"]);
    // The cancelled task's late result is refused.
    let r = d.try_complete_key(d.key("a"), &[]);
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
    assert_eq!(d.complete("h", &[]), none());
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
    assert_eq!(level(&mut d, 7.0), ["dispatch h"]);
    assert_eq!(level(&mut d, 8.0), none());
    assert_eq!(level(&mut d, 3.0), none());
    assert_eq!(level(&mut d, 9.0), ["dispatch h"]);
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["dispatch z"]);
    assert_eq!(level(&mut d, 1.0), none());
    assert_eq!(level(&mut d, 10.0), none());
    assert_eq!(d.complete_every("h"), [none(), none()]);
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
    assert_eq!(d.complete("h", &[]), none());
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
            r#"<boundaryEvent id="ib" attachedToRef="a">{}</boundaryEvent>{}{}</subProcess>"#,
            cond("level &gt; 5.0"),
            path("ih", &["ib", "ih", "se"]),
            task("ih", "", ""),
        ),
    );
    let mut d = Driver::new(&body);
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(level(&mut d, 7.0), ["cancel a", "dispatch h"]);
}

/// Process `p`: start, sub-process `sp` (start, task `a`, end, and an event sub-process `esp`
/// whose conditional start `cs` (`interrupting`, condition `c`) leads to task `eh`), task `z`,
/// end.
fn sub_with_event_sub(interrupting: bool, c: &str) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>
        <subProcess id="sp"><startEvent id="ss"/>{}<endEvent id="se"/>
          <subProcess id="esp" triggeredByEvent="true"><startEvent id="cs" isInterrupting="{interrupting}">{}</startEvent>{}<endEvent id="ee"/></subProcess>
        </subProcess>
        {}<endEvent id="e"/></process>"#,
        path("i", &["ss", "a", "se"]) + &task("a", "", ""),
        cond(c),
        path("j", &["cs", "eh", "ee"]) + &task("eh", "", ""),
        path("f", &["s", "sp", "z", "e"]) + &task("z", "", ""),
    )
}

// §13.5.4: an interrupting event sub-process cancels the rest of its enclosing sub-process and
// runs in its place; the sub-process completes when the event sub-process does, then the
// process moves on along the sub-process's outgoing flow.
#[test]
fn interrupting_conditional_event_sub_process_inside_a_sub_process_replaces_its_content() {
    let mut d = Driver::new(&sub_with_event_sub(true, "level &gt; 5.0"));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(level(&mut d, 7.0), ["cancel a", "dispatch eh"]);
    // Interrupted once: it does not fire again.
    assert_eq!(level(&mut d, 1.0), none());
    assert_eq!(level(&mut d, 8.0), none());
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
    assert_eq!(level(&mut d, 7.0), ["dispatch eh"]);
    assert_eq!(level(&mut d, 9.0), none());
    assert_eq!(level(&mut d, 2.0), none());
    assert_eq!(level(&mut d, 6.0), ["dispatch eh"]);
    assert_eq!(d.complete("a", &[]), none());
    let ehs = d.keys_of("eh");
    assert_eq!(d.complete_key(ehs[0], &[]), none());
    assert_eq!(d.complete_key(ehs[1], &[]), ["dispatch z"]);
    // The event sub-process listened only while its sub-process ran.
    assert_eq!(level(&mut d, 0.0), none());
    assert_eq!(level(&mut d, 9.0), none());
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
        r#"<process id="p" isExecutable="true">{}<intermediateCatchEvent id="c">{}</intermediateCatchEvent></process>"#,
        chain(&["c"]),
        cond(cnd),
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
    assert_eq!(d.data("heater", Value::from(5.0)), none());
    assert_eq!(d.start(&[]), ["completed"]);
}

// A condition is re-evaluated after every step, over process variables as well as system data:
// a catch on one branch passes exactly when a task on the other branch has made it true.
#[test]
fn conditional_catch_is_re_evaluated_after_every_step() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}{}
        <intermediateCatchEvent id="c">{}</intermediateCatchEvent>{}{}<endEvent id="e"/></process>"#,
        flow("f0", "s", "fork") + &parallel("fork"),
        path("fc", &["fork", "c", "w", "join"]),
        cond("count &gt;= 2"),
        path("fa", &["fork", "a", "b", "join"]) + &tasks(&["w", "a", "b"]),
        parallel("join") + &flow("f7", "join", "e"),
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
    assert_eq!(d.start(&[]), none());
    assert_eq!(d.data("other", Value::from(1.0)), none());
    assert!(
        d.e.state()
            .instances
            .values()
            .all(|i| i.incidents.is_empty())
    );
    assert_eq!(d.data("pressure", Value::from(3.0)), ["completed"]);
}

// §13.5.1 with Table 10.84 (§10.5.2): a conditional start event of a top-level process starts a
// new instance when its condition becomes true, and again only after it has become false and
// then true again. (Camunda 7 and 8 evaluate root conditional start events only on an API call.)
#[test]
fn conditional_start_event_starts_an_instance_on_each_false_to_true_edge() {
    let mut d = Driver::new(&format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s">{}</startEvent>{}{}<endEvent id="e"/></process>"#,
        cond("temp &gt; 300.0"),
        path("f", &["s", "a", "e"]),
        task("a", "", ""),
    ));
    assert_eq!(d.data("temp", Value::from(20.0)), none());
    assert_eq!(d.data("temp", Value::from(310.0)), ["dispatch a"]);
    assert_eq!(d.data("temp", Value::from(320.0)), none());
    assert_eq!(d.data("temp", Value::from(100.0)), none());
    assert_eq!(d.data("temp", Value::from(305.0)), ["dispatch a"]);
    assert_eq!(d.e.state().instances.len(), 2);
}
