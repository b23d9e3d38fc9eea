//! Chapter 13 semantics: event sub-processes (rules in docs/engine-semantics.md).
//!
//! An event sub-process listens while the scope that contains it (process or sub-process) is
//! active (§10.3.5, §13.5.4). Interrupting: the scope's other work is cancelled, the event
//! sub-process runs once, and when it ends the scope completes normally (§10.5.6: it
//! "absorbs" the event). Non-interrupting: it runs beside the scope's work, once per
//! occurrence, concurrently (§10.5.6), and the scope completes only when every such instance
//! has completed too (§13.3.4).

use super::*;

const DEFS: &str = r#"<signal id="sig" name="S"/><message id="poke" name="poke"/><error id="err" errorCode="E"/><escalation id="esc" escalationCode="X"/>"#;

fn process(body: &str) -> String {
    format!(r#"{DEFS}<process id="p" isExecutable="true">{body}</process>"#)
}

/// An event sub-process `id` whose start `{id}s` carries `definition` and whose body is one
/// task `{id}t`.
fn esp(id: &str, definition: &str, interrupting: bool) -> String {
    let (start, body, end) = (format!("{id}s"), format!("{id}t"), format!("{id}e"));
    format!(
        r#"<subProcess id="{id}" triggeredByEvent="true"><startEvent id="{start}" isInterrupting="{interrupting}">{definition}</startEvent>{}{}<endEvent id="{end}"/></subProcess>"#,
        path(&format!("{id}f"), &[&start, &body, &end]),
        task(&body, "", ""),
    )
}

const SIGNAL: &str = r#"<signalEventDefinition signalRef="sig"/>"#;
const MESSAGE: &str = r#"<messageEventDefinition messageRef="poke"/>"#;
const ERROR: &str = r#"<errorEventDefinition errorRef="err"/>"#;
const ANY_ERROR: &str = "<errorEventDefinition/>";
const ESCALATION: &str = r#"<escalationEventDefinition escalationRef="esc"/>"#;

fn cycle(value: &str) -> String {
    format!(
        r#"<timerEventDefinition><timeCycle xsi:type="tFormalExpression">{value}</timeCycle></timerEventDefinition>"#
    )
}

/// start → `a` → end, plus `extra`.
fn one_task(extra: &str) -> String {
    process(&format!("{}{}{extra}", chain(&["a"]), task("a", "", "")))
}

/// start → fork → `a`, `b` → ends, plus `extra`.
fn two_tasks(extra: &str) -> String {
    process(&format!(
        "{}{}{extra}",
        fork_into(&[&["a"], &["b"]]),
        tasks(&["a", "b"])
    ))
}

/// start → `a` → sub-process `sub` (fork → `x`, `y`, plus `inner`) → `b` → end, plus `outer`
/// (boundary events of `sub`, their paths, event sub-processes of the process).
fn nested(inner: &str, outer: &str) -> String {
    process(&format!(
        r#"{}{}<subProcess id="sub"><startEvent id="ss"/>{}<parallelGateway id="fork"/>{}{}{}<endEvent id="se1"/><endEvent id="se2"/>{inner}</subProcess>{outer}"#,
        chain(&["a", "sub", "b"]),
        tasks(&["a", "b"]),
        flow("i0", "ss", "fork"),
        path("x", &["fork", "x", "se1"]),
        path("y", &["fork", "y", "se2"]),
        tasks(&["x", "y"]),
    ))
}

/// A boundary event `bd` on `sub` with `definition`, leading to task `h` and its end `eh`.
fn sub_boundary(definition: &str) -> String {
    format!(
        r#"<boundaryEvent id="bd" attachedToRef="sub">{definition}</boundaryEvent>{}{}<endEvent id="eh"/>"#,
        path("h", &["bd", "h", "eh"]),
        task("h", "", ""),
    )
}

/// The message `poke` from outside.
fn poke(d: &mut Driver) -> Result<Vec<String>, Rejected> {
    d.message("poke", None, &[])
}

/// §10.5.6 non-interrupting handlers: each occurrence starts one more event sub-process
/// instance, concurrently with the scope's work and with each other; §13.3.4: the scope (here
/// the process) completes only when none of them is still active.
#[test]
fn a_non_interrupting_event_subprocess_runs_once_per_occurrence_beside_the_scope() {
    let mut d = Driver::new(&one_task(&esp("m", MESSAGE, false)));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(poke(&mut d).expect("received"), ["dispatch mt"]);
    assert_eq!(poke(&mut d).expect("received"), ["dispatch mt"]);
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(1, &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(2, &[]), ["completed"]);
}

/// §10.3.5: the event sub-process starts each time its trigger occurs while the parent is
/// active — and a scope whose own flow has ended but which still runs an event sub-process
/// instance is active.
#[test]
fn a_scope_waiting_for_its_event_subprocess_still_listens() {
    let mut d = Driver::new(&one_task(&esp("n", SIGNAL, false)));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), ["dispatch nt"]);
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["dispatch nt"]);
    assert_eq!(d.complete_nth(1, &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(2, &[]), ["completed"]);
    // The scope has ended: nobody listens any more.
    assert!(d.e.state().waits.is_empty());
}

/// §13.5.4, §10.5.6 interrupting handlers: the scope's other work is cancelled, the event
/// sub-process runs, and its end completes the scope normally. It fires once: the interrupted
/// scope no longer listens (Camunda 7 and 8 likewise: "an interrupting event sub-process can be
/// triggered only once").
#[test]
fn an_interrupting_event_subprocess_cancels_the_scope_and_fires_once() {
    let mut d = Driver::new(&two_tasks(&esp("i", SIGNAL, true)));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch b"]);
    assert_eq!(d.signal("S"), ["cancel a", "cancel b", "dispatch it"]);
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete("it", &[]), ["completed"]);
}

/// An interrupting event sub-process also cancels the running instances of the scope's
/// non-interrupting event sub-processes, and none of them starts again afterwards (§13.5.4:
/// the parent stays interrupted until the handler ends; as Camunda 8).
#[test]
fn an_interrupting_event_subprocess_cancels_running_non_interrupting_ones() {
    let mut d = Driver::new(&one_task(&format!(
        "{}{}",
        esp("n", MESSAGE, false),
        esp("i", SIGNAL, true)
    )));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(poke(&mut d).expect("received"), ["dispatch nt"]);
    assert_eq!(d.signal("S"), ["cancel a", "cancel nt", "dispatch it"]);
    let r = poke(&mut d);
    assert!(matches!(r, Err(Rejected::NoReceiver(_))), "{r:?}");
    assert_eq!(d.complete("it", &[]), ["completed"]);
}

/// §10.5.6: one occurrence is consumed by every event sub-process that waits for it; two
/// non-interrupting signal event sub-processes of one scope both start.
#[test]
fn one_signal_starts_every_non_interrupting_event_subprocess_of_the_scope() {
    let mut d = Driver::new(&one_task(&format!(
        "{}{}",
        esp("n1", SIGNAL, false),
        esp("n2", SIGNAL, false)
    )));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), ["dispatch n1t", "dispatch n2t"]);
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(1, &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(2, &[]), ["completed"]);
}

/// One signal caught in one scope by an interrupting and a non-interrupting event sub-process:
/// both were waiting when it was thrown, so both catch it whatever the document order — the
/// non-interrupting one first, then the interrupting one cancels the scope's work, the instance
/// the other just started included (before its task was reached).
#[test]
fn one_signal_caught_by_an_interrupting_and_a_non_interrupting_sibling_is_one_outcome() {
    for (first, second) in [(("n", false), ("i", true)), (("i", true), ("n", false))] {
        let mut d = Driver::new(&one_task(&format!(
            "{}{}",
            esp(first.0, SIGNAL, first.1),
            esp(second.0, SIGNAL, second.1)
        )));
        assert_eq!(d.start(&[]), ["dispatch a"]);
        d.seq += 1;
        let actions =
            d.e.step(Input {
                seq: d.seq,
                at: d.now,
                event: Event::SignalReceived { name: "S".into() },
            })
            .expect("a signal is always accepted");
        let g = Arc::clone(d.e.graph());
        let caught: Vec<&str> = actions
            .iter()
            .filter_map(|a| match a {
                Action::Record(r) => match &r.entry {
                    Entry::Caught { node, .. } => Some(g.node(*node).id.as_str()),
                    _ => None,
                },
                _ => None,
            })
            .collect();
        assert_eq!(caught, ["ns", "is"], "{} listed first", first.0);
        let dispatched: Vec<&str> = actions
            .iter()
            .filter_map(|a| match a {
                Action::DispatchTask { node, .. } => Some(g.node(*node).id.as_str()),
                _ => None,
            })
            .collect();
        assert_eq!(dispatched, ["it"], "{} listed first", first.0);
    }
}

/// One signal reaches event sub-processes in nested scopes: the one inside the running
/// sub-process and the one of the process both start (inner scopes first).
#[test]
fn one_signal_starts_event_subprocesses_in_nested_scopes() {
    let mut d = Driver::new(&nested(
        &esp("inner", SIGNAL, false),
        &esp("outer", SIGNAL, false),
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["dispatch x", "dispatch y"]);
    assert_eq!(d.signal("S"), ["dispatch innert", "dispatch outert"]);
}

/// When one signal starts a non-interrupting event sub-process inside a sub-process and an
/// interrupting one of the enclosing process, the interrupting one wins: everything in its
/// scope, the inner event sub-process included, is cancelled. (The specification has no order
/// among the catchers of one broadcast; the outcome does not depend on it.)
#[test]
fn an_interrupting_outer_event_subprocess_cancels_an_inner_one_started_by_the_same_signal() {
    let mut d = Driver::new(&nested(
        &esp("inner", SIGNAL, false),
        &esp("outer", SIGNAL, true),
    ));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["dispatch x", "dispatch y"]);
    let out = d.signal("S");
    assert!(
        out.contains(&"cancel x".to_owned()) && out.contains(&"cancel y".to_owned()),
        "{out:?}"
    );
    assert_eq!(out.last().map(String::as_str), Some("dispatch outert"));
    // No task of the inner event sub-process is left running.
    let dispatched_inner = out.iter().filter(|a| *a == "dispatch innert").count();
    let cancelled_inner = out.iter().filter(|a| *a == "cancel innert").count();
    assert_eq!(dispatched_inner, cancelled_inner, "{out:?}");
    assert_eq!(d.complete("outert", &[]), ["completed"]);
}

/// §10.3.5, §13.5.4: an event sub-process inside a sub-process listens only while that
/// sub-process runs — not before it starts, not after it ends — and the sub-process waits for
/// its running instance before the parent flow moves on (§13.3.4).
#[test]
fn an_event_subprocess_in_a_subprocess_listens_only_while_it_runs() {
    let mut d = Driver::new(&nested(&esp("n", SIGNAL, false), ""));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete("a", &[]), ["dispatch x", "dispatch y"]);
    assert_eq!(d.signal("S"), ["dispatch nt"]);
    assert_eq!(d.complete("x", &[]), Vec::<String>::new());
    assert_eq!(d.complete("y", &[]), Vec::<String>::new());
    assert_eq!(d.complete("nt", &[]), ["dispatch b"]);
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// A message for an event sub-process whose scope is not running has no receiver: it is
/// refused before the scope starts and after it ends.
#[test]
fn a_message_event_subprocess_has_no_receiver_outside_its_scope() {
    let mut d = Driver::new(&nested(&esp("m", MESSAGE, false), ""));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    let r = poke(&mut d);
    assert!(matches!(r, Err(Rejected::NoReceiver(_))), "{r:?}");
    d.complete("a", &[]);
    assert_eq!(poke(&mut d).expect("received"), ["dispatch mt"]);
    d.complete("x", &[]);
    d.complete("y", &[]);
    assert_eq!(d.complete("mt", &[]), ["dispatch b"]);
    let r = poke(&mut d);
    assert!(matches!(r, Err(Rejected::NoReceiver(_))), "{r:?}");
}

/// §13.5.4, §10.5.6: an interrupting event sub-process of a sub-process replaces the
/// sub-process's work; when it ends without rethrowing, the sub-process completes normally and
/// the parent flow resumes along the sub-process's outgoing flow.
#[test]
fn an_interrupting_event_subprocess_of_a_subprocess_completes_it_normally() {
    let mut d = Driver::new(&nested(&esp("i", MESSAGE, true), ""));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["dispatch x", "dispatch y"]);
    assert_eq!(
        poke(&mut d).expect("received"),
        ["cancel x", "cancel y", "dispatch it"]
    );
    assert_eq!(d.complete("it", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §10.5.6, §13.5.4: an error a task of the scope throws is caught by the scope's error event
/// sub-process (always interrupting) before any error boundary of the enclosing sub-process;
/// the sub-process then completes normally.
#[test]
fn an_error_event_subprocess_catches_a_task_failure_before_the_boundary() {
    let boundary = sub_boundary(ERROR);
    let mut d = Driver::new(&nested(&esp("r", ERROR, true), &boundary));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["dispatch x", "dispatch y"]);
    assert_eq!(d.fail("x", "E"), ["cancel y", "dispatch rt"]);
    assert_eq!(d.complete("rt", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// An error the event sub-process does not catch (another code) passes it by and reaches the
/// catch-all boundary of the sub-process, which interrupts it.
#[test]
fn an_error_of_another_code_passes_the_event_subprocess_to_the_boundary() {
    let boundary = sub_boundary(ANY_ERROR);
    let mut d = Driver::new(&nested(&esp("r", ERROR, true), &boundary));
    d.start(&[]);
    d.complete("a", &[]);
    assert_eq!(d.fail("x", "OTHER"), ["cancel y", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §13.5.4: an event sub-process may rethrow to continue outside the boundary of its parent
/// sub-process. TRACE: whatever an event sub-process throws and does not catch inside itself
/// goes past every event sub-process of its parent scope (Zeebe likewise lets no second event
/// sub-process of the scope catch it) to the parent's boundary events, interrupting it.
#[test]
fn an_error_inside_an_event_subprocess_goes_to_the_boundary_of_its_parent() {
    let boundary = sub_boundary(ERROR);
    let inner = format!("{}{}", esp("m", MESSAGE, false), esp("r", ERROR, true));
    let mut d = Driver::new(&nested(&inner, &boundary));
    d.start(&[]);
    d.complete("a", &[]);
    assert_eq!(poke(&mut d).expect("received"), ["dispatch mt"]);
    assert_eq!(d.fail("mt", "E"), ["cancel x", "cancel y", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §10.5.6: escalation event sub-processes catch what an intermediate throw event of their
/// scope escalates; non-interrupting, the thrower goes on; interrupting, the scope's work,
/// the thrower included, is cancelled.
#[test]
fn an_escalation_event_subprocess_catches_a_throw_of_its_scope() {
    let body = |interrupting: bool| {
        process(&format!(
            r#"{}{}<intermediateThrowEvent id="t">{ESCALATION}</intermediateThrowEvent>{}"#,
            fork_into(&[&["a"], &["w", "t", "c"]]),
            tasks(&["a", "w", "c"]),
            esp("x", ESCALATION, interrupting),
        ))
    };
    let mut d = Driver::new(&body(false));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch w"]);
    assert_eq!(d.complete("w", &[]), ["dispatch c", "dispatch xt"]);
    d.complete("a", &[]);
    d.complete("c", &[]);
    assert_eq!(d.complete("xt", &[]), ["completed"]);

    let mut d = Driver::new(&body(true));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch w"]);
    assert_eq!(d.complete("w", &[]), ["cancel a", "dispatch xt"]);
    assert_eq!(d.complete("xt", &[]), ["completed"]);
}

/// Timer event sub-processes (§10.5.6, §13.5.4): an interrupting duration
/// timer cancels the scope's work when due; its timer is cancelled if the scope ends first.
#[test]
fn an_interrupting_timer_event_subprocess_fires_when_due_or_is_cancelled_with_its_scope() {
    let extra = esp("t", &duration("PT10M"), true);
    let mut d = Driver::new(&one_task(&extra));
    assert_eq!(d.start(&[]), ["timer 600000", "dispatch a"]);
    assert_eq!(d.fire(0, 600_000), ["cancel a", "dispatch tt"]);
    assert_eq!(d.complete("tt", &[]), ["completed"]);

    let mut d = Driver::new(&one_task(&extra));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["untimer", "completed"]);
}

/// A non-interrupting timer cycle starts one event sub-process instance per firing while the
/// scope runs (R2: two firings), beside the scope's work.
#[test]
fn a_non_interrupting_timer_cycle_event_subprocess_starts_once_per_firing() {
    let mut d = Driver::new(&one_task(&esp("t", &cycle("R2/PT1M"), false)));
    assert_eq!(d.start(&[]), ["timer 60000", "dispatch a"]);
    assert_eq!(d.fire(0, 60_000), ["timer 60000", "dispatch tt"]);
    assert_eq!(d.fire(1, 60_000), ["dispatch tt"]);
    d.complete("a", &[]);
    d.complete_nth(1, &[]);
    assert_eq!(d.complete_nth(2, &[]), ["completed"]);
}

/// A running non-interrupting event sub-process instance belongs to its scope: when an
/// interrupting boundary event cancels the sub-process, the instance is cancelled with it.
#[test]
fn a_boundary_interrupting_the_subprocess_cancels_its_running_event_subprocess() {
    let boundary = sub_boundary(&duration("PT1H"));
    let mut d = Driver::new(&nested(&esp("n", SIGNAL, false), &boundary));
    d.start(&[]);
    assert_eq!(
        d.complete("a", &[]),
        ["timer 3600000", "dispatch x", "dispatch y"]
    );
    assert_eq!(d.signal("S"), ["dispatch nt"]);
    d.complete("x", &[]);
    d.complete("y", &[]);
    assert_eq!(d.fire(0, 3_600_000), ["cancel nt", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// A terminate end event in the scope's own flow ends the scope at once, cancelling its running
/// event sub-process instances (§13.5.6 terminate: all activities in the scope are terminated).
#[test]
fn a_terminate_end_cancels_running_event_subprocess_instances() {
    let mut d = Driver::new(&one_task(&esp("n", SIGNAL, false)).replace(
        r#"<endEvent id="e"/>"#,
        r#"<endEvent id="e"><terminateEventDefinition/></endEvent>"#,
    ));
    d.start(&[]);
    assert_eq!(d.signal("S"), ["dispatch nt"]);
    assert_eq!(d.complete("a", &[]), ["cancel nt", "terminated"]);
}

/// A signal end event of the scope's own flow starts the scope's signal event sub-process: the
/// scope is still active while its last token throws (§13.5.6: the end event's result is
/// performed, then the token is consumed), and it then waits for that instance.
#[test]
fn a_signal_end_event_starts_an_event_subprocess_of_its_own_scope() {
    let mut d = Driver::new(&one_task(&esp("n", SIGNAL, false)).replace(
        r#"<endEvent id="e"/>"#,
        r#"<endEvent id="e"><signalEventDefinition signalRef="sig"/></endEvent>"#,
    ));
    d.start(&[]);
    assert_eq!(d.complete("a", &[]), ["dispatch nt"]);
    assert_eq!(d.complete("nt", &[]), ["completed"]);
}

/// A message event sub-process receives the message's payload: its variables are visible to
/// the event sub-process's tasks (they are local to that event sub-process instance).
#[test]
fn a_message_event_subprocess_sees_the_message_payload() {
    let body = one_task(&esp("m", MESSAGE, false)).replace(
        r#"<trace:task resource="sys.mt"/>"#,
        r#"<trace:task resource="sys.mt"><trace:input target="n" source="n"/></trace:task>"#,
    );
    let mut d = Driver::new(&body);
    d.start(&[]);
    let out = d.message("poke", None, &[("n", Value::Int(5))]);
    assert_eq!(out.expect("received"), ["dispatch mt"]);
    assert_eq!(d.request("mt").get("n"), Some(&Value::Int(5)));
}

/// §13.5.4: an error event sub-process may rethrow the error to continue outside the
/// sub-process: its error end event goes to the sub-process's error boundary (not back to
/// itself), after its own work.
#[test]
fn an_error_event_subprocess_rethrowing_continues_at_the_boundary() {
    let boundary = sub_boundary(ERROR);
    let rethrow = esp("r", ERROR, true).replace(
        r#"<endEvent id="re"/>"#,
        &format!(r#"<endEvent id="re">{ERROR}</endEvent>"#),
    );
    let mut d = Driver::new(&nested(&rethrow, &boundary));
    d.start(&[]);
    d.complete("a", &[]);
    assert_eq!(d.fail("x", "E"), ["cancel y", "dispatch rt"]);
    assert_eq!(d.complete("rt", &[]), ["dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §13.5.4: for a multi-instance activity an interrupting event sub-process cancels only the
/// instance it was triggered in. A message goes to one receiver, so only one body is
/// interrupted; the other runs on, and the activity completes when both bodies have.
#[test]
fn an_interrupting_event_subprocess_of_a_multi_instance_subprocess_interrupts_one_body() {
    let body = nested(&esp("i", MESSAGE, true), "").replace(
        r#"<subProcess id="sub">"#,
        r#"<subProcess id="sub"><multiInstanceLoopCharacteristics><loopCardinality>2</loopCardinality></multiInstanceLoopCharacteristics>"#,
    );
    let mut d = Driver::new(&body);
    d.start(&[]);
    assert_eq!(
        d.complete("a", &[]),
        ["dispatch x", "dispatch y", "dispatch x", "dispatch y"]
    );
    assert_eq!(
        poke(&mut d).expect("received"),
        ["cancel x", "cancel y", "dispatch it"]
    );
    // The second body still runs: its task completes; it still listens, and the next message
    // interrupts it alone.
    assert_eq!(d.complete_nth(3, &[]), Vec::<String>::new());
    assert_eq!(poke(&mut d).expect("received"), ["cancel y", "dispatch it"]);
    assert_eq!(d.complete_nth(5, &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(6, &[]), ["dispatch b"]);
}
