//! Chapter 13 semantics: signals (rules in docs/engine-semantics.md).
//!
//! A signal is broadcast (§10.5.6, §13.5.1–§13.5.3): every catcher waiting for it when it is
//! thrown catches it — in the thrower's instance and in every other one, intermediate catch
//! events, boundary events, event-based gateway branches, event sub-process starts — and every
//! process with a signal start event starts a new instance. A catcher that is not yet waiting
//! does not see it (the occurrence is not stored).

use super::*;

const SIGNALS: &str = r#"<signal id="sig" name="S"/><signal id="other" name="T"/>"#;

fn process(id: &str, body: &str) -> String {
    format!(r#"<process id="{id}" isExecutable="true">{body}</process>"#)
}

fn catch(id: &str, signal: &str) -> String {
    let r = if signal.is_empty() {
        String::new()
    } else {
        format!(r#" signalRef="{signal}""#)
    };
    format!(
        r#"<intermediateCatchEvent id="{id}"><signalEventDefinition{r}/></intermediateCatchEvent>"#
    )
}

fn throw(id: &str, signal: &str) -> String {
    let r = if signal.is_empty() {
        String::new()
    } else {
        format!(r#" signalRef="{signal}""#)
    };
    format!(
        r#"<intermediateThrowEvent id="{id}"><signalEventDefinition{r}/></intermediateThrowEvent>"#
    )
}

fn boundary(id: &str, on: &str, interrupting: bool) -> String {
    format!(
        r#"<boundaryEvent id="{id}" attachedToRef="{on}" cancelActivity="{interrupting}"><signalEventDefinition signalRef="sig"/></boundaryEvent>"#
    )
}

fn signal(d: &mut Driver, name: &str) -> Vec<String> {
    d.step(Event::SignalReceived { name: name.into() })
        .expect("a signal is always accepted")
}

/// Completes the `i`-th dispatched task (dispatch order), whatever its node.
fn complete_nth(d: &mut Driver, i: usize) -> Vec<String> {
    let task = d.tasks[i].1;
    d.step(Event::TaskCompleted {
        task,
        output: Vars::new(),
    })
    .expect("accepted")
}

fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

/// §13.5.2: a catch event already waiting in the thrower's own instance catches the signal.
#[test]
fn a_throw_reaches_a_catch_already_waiting_in_the_same_instance() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}{}{}{}{}<endEvent id="e1"/><endEvent id="e2"/>"#,
                flow("f0", "s", "fork"),
                flow("f1", "fork", "c"),
                catch("c", "sig"),
                flow("f2", "c", "b"),
                task("b", "f2", "f3"),
                flow("f3", "b", "e1"),
                flow("f4", "fork", "a"),
                task("a", "f4", "f5"),
                flow("f5", "a", "t"),
                throw("t", "sig"),
                flow("f6", "t", "e2"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §13.5.2: waiting starts when the catch event is reached; a signal thrown earlier is gone
/// (§10.5.6: a published signal is not stored for later catchers).
#[test]
fn a_signal_thrown_before_the_catcher_waits_is_lost() {
    // Thrown on the way to the catch event.
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "t"),
                throw("t", "sig"),
                flow("f1", "t", "c"),
                catch("c", "sig"),
                flow("f2", "c", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), ["completed"]);

    // Thrown from outside while the instance still works on the task before the catch event.
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "a"),
                task("a", "f0", "f1"),
                flow("f1", "a", "c"),
                catch("c", "sig"),
                flow("f2", "c", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), ["completed"]);
}

/// Parallel branches of one step have no order in the specification (§13.4.1 fork: the tokens
/// move concurrently). TRACE lets the other ready tokens of the step settle before a signal is
/// thrown, so a catch event reached in the same instant as the throw catches it.
#[test]
fn a_throw_waits_for_the_sibling_branches_of_the_same_step_to_settle() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}<endEvent id="e1"/><endEvent id="e2"/>"#,
                flow("f0", "s", "fork"),
                // The throwing branch comes first in document order.
                flow("f1", "fork", "t"),
                throw("t", "sig"),
                flow("f2", "t", "e1"),
                flow("f3", "fork", "c"),
                catch("c", "sig"),
                flow("f4", "c", "e2"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["completed"]);
}

/// §10.5.6: a signal is broadcast to every catcher in every instance, the thrower's included;
/// each catcher consumes its own copy.
#[test]
fn a_throw_reaches_every_waiting_catcher_of_every_instance() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}{}{}<endEvent id="e1"/><endEvent id="e2"/>"#,
                flow("f0", "s", "fork"),
                flow("f1", "fork", "c"),
                catch("c", "sig"),
                flow("f2", "c", "e1"),
                flow("f3", "fork", "a"),
                task("a", "f3", "f4"),
                flow("f4", "a", "t"),
                throw("t", "sig"),
                flow("f5", "t", "e2"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.start(&[]), ["dispatch a"]);
    // The first instance throws: its own catch and the second instance's catch both pass.
    assert_eq!(complete_nth(&mut d, 0), ["completed"]);
    // The second instance's catch already consumed that signal; its own throw finds nobody.
    assert_eq!(complete_nth(&mut d, 1), ["completed"]);
}

/// §10.5.6, §13.5.1: a signal start event starts a new instance for each signal; the
/// occurrence that started it is consumed by the start, not by the new instance's own catch
/// events reached afterwards.
#[test]
fn a_signal_start_event_starts_one_instance_per_signal() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "q",
            &format!(
                r#"<startEvent id="qs"><signalEventDefinition signalRef="sig"/></startEvent>{}{}{}{}{}<endEvent id="qe"/>"#,
                flow("g0", "qs", "c"),
                catch("c", "sig"),
                flow("g1", "c", "b"),
                task("b", "g1", "g2"),
                flow("g2", "b", "qe"),
            )
        )
    ));
    // The first instance starts and waits at its catch event.
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    assert_eq!(d.e.state().instances.len(), 1);
    // The second signal moves the first instance on and starts a second one.
    assert_eq!(signal(&mut d, "S"), ["dispatch b"]);
    assert_eq!(d.e.state().instances.len(), 2);
    assert_eq!(signal(&mut d, "T"), Vec::<String>::new());
    assert_eq!(d.e.state().instances.len(), 2);
}

/// §13.5.6: a signal end event throws, then its token is consumed like a none end event; the
/// thrower's instance completes and the signal starts a process elsewhere.
#[test]
fn a_signal_end_event_throws_then_ends_its_token() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}<endEvent id="e"><signalEventDefinition signalRef="sig"/></endEvent>"#,
                flow("f0", "s", "a"),
                task("a", "f0", "f1"),
                flow("f1", "a", "e"),
            )
        ),
        process(
            "q",
            &format!(
                r#"<startEvent id="qs"><signalEventDefinition signalRef="sig"/></startEvent>{}{}{}<endEvent id="qe"/>"#,
                flow("g0", "qs", "b"),
                task("b", "g0", "g1"),
                flow("g1", "b", "qe"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed", "dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §13.5.3: an interrupting signal boundary event cancels its task and follows its own flow;
/// after that the task's boundary no longer listens.
#[test]
fn an_interrupting_boundary_on_a_task_cancels_it() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "a"),
                task("a", "f0", "f1"),
                boundary("b", "a", true),
                flow("fb", "b", "h"),
                task("h", "fb", "f2"),
                flow("f2", "h", "e"),
                flow("f1", "a", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(signal(&mut d, "S"), ["cancel a", "dispatch h"]);
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §13.5.3: a non-interrupting signal boundary event leaves its task running and fires again
/// at each signal while the task runs; it stops listening once the task completes, and the
/// instance completes only when the boundary paths have finished too.
#[test]
fn a_non_interrupting_boundary_on_a_task_fires_at_each_signal_while_it_runs() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}{}{}{}{}<endEvent id="e"/><endEvent id="eh"/>"#,
                flow("f0", "s", "a"),
                task("a", "f0", "f1"),
                boundary("b", "a", false),
                flow("fb", "b", "h"),
                task("h", "fb", "f2"),
                flow("f2", "h", "eh"),
                flow("f1", "a", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(signal(&mut d, "S"), ["dispatch h"]);
    assert_eq!(signal(&mut d, "S"), ["dispatch h"]);
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    assert_eq!(complete_nth(&mut d, 1), Vec::<String>::new());
    assert_eq!(complete_nth(&mut d, 2), ["completed"]);
}

/// §13.5.3 on a sub-process: interrupting cancels everything inside it; non-interrupting lets
/// it run on beside the boundary path.
#[test]
fn a_boundary_on_a_subprocess_interrupts_it_or_runs_beside_it() {
    let model = |interrupting: bool| {
        format!(
            "{SIGNALS}{}",
            process(
                "p",
                &format!(
                    r#"<startEvent id="s"/>{}<subProcess id="sub"><startEvent id="ss"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}<endEvent id="se"/></subProcess>{}{}{}{}<endEvent id="e"/><endEvent id="eh"/>{}"#,
                    flow("f0", "s", "sub"),
                    flow("i0", "ss", "fork"),
                    flow("i1", "fork", "x"),
                    flow("i2", "fork", "y"),
                    task("x", "i1", "i3"),
                    task("y", "i2", "i4"),
                    flow("i3", "x", "se"),
                    flow("i4", "y", "se"),
                    boundary("b", "sub", interrupting),
                    flow("fb", "b", "h"),
                    task("h", "fb", "f2"),
                    flow("f2", "h", "eh"),
                    flow("f1", "sub", "e"),
                )
            )
        )
    };
    let mut d = Driver::new(&model(true));
    assert_eq!(d.start(&[]), ["dispatch x", "dispatch y"]);
    assert_eq!(signal(&mut d, "S"), ["cancel x", "cancel y", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);

    let mut d = Driver::new(&model(false));
    assert_eq!(d.start(&[]), ["dispatch x", "dispatch y"]);
    assert_eq!(signal(&mut d, "S"), ["dispatch h"]);
    assert_eq!(d.complete("x", &[]), Vec::<String>::new());
    assert_eq!(d.complete("h", &[]), Vec::<String>::new());
    assert_eq!(d.complete("y", &[]), ["completed"]);
}

/// A signal thrown inside a sub-process reaches the interrupting boundary of that same
/// sub-process (the broadcast knows no scopes): the sub-process, thrower included, is
/// withdrawn and the boundary path runs.
#[test]
fn a_signal_thrown_inside_a_subprocess_interrupts_it_through_its_own_boundary() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<subProcess id="sub"><startEvent id="ss"/>{}{}{}{}{}<endEvent id="se"/></subProcess>{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "sub"),
                flow("i0", "ss", "t"),
                throw("t", "sig"),
                flow("i1", "t", "x"),
                task("x", "i1", "i2"),
                flow("i2", "x", "se"),
                boundary("b", "sub", true),
                flow("fb", "b", "h"),
                task("h", "fb", "f2"),
                flow("f2", "h", "e"),
                flow("f1", "sub", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §13.4.4: at an event-based gateway the signal branch wins; the other events are withdrawn
/// (the timer cancelled).
#[test]
fn an_event_based_gateway_takes_the_signal_branch_and_withdraws_the_others() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<eventBasedGateway id="g"/>{}{}{}{}{}
                <intermediateCatchEvent id="tm"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>
                {}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "g"),
                flow("f1", "g", "c"),
                catch("c", "sig"),
                flow("f2", "c", "a"),
                task("a", "f2", "f3"),
                flow("f3", "a", "e"),
                flow("f4", "g", "tm"),
                flow("f5", "tm", "b"),
                task("b", "f5", "f6"),
                flow("f6", "b", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["timer 3600000"]);
    assert_eq!(signal(&mut d, "S"), ["untimer", "dispatch a"]);
    let timer = d.timers[0];
    let late = d.step(Event::TimerFired { timer });
    assert!(matches!(late, Err(Rejected::UnknownTimer(_))), "{late:?}");
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// §13.4.4 says the first event wins; one signal satisfying two branches of one event-based
/// gateway at once is not ordered by the specification. TRACE takes one branch only, the
/// first in document order.
#[test]
fn an_event_based_gateway_with_two_branches_on_one_signal_takes_only_one() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<eventBasedGateway id="g"/>{}{}{}{}{}{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "g"),
                flow("f1", "g", "c1"),
                catch("c1", "sig"),
                flow("f2", "c1", "a"),
                task("a", "f2", "f3"),
                flow("f3", "a", "e"),
                flow("f4", "g", "c2"),
                catch("c2", "sig"),
                flow("f5", "c2", "b"),
                task("b", "f5", "f6"),
                flow("f6", "b", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// One broadcast reaches every kind of catcher at once: an event sub-process start, a
/// boundary event and an intermediate catch event of the same instance.
#[test]
fn one_signal_reaches_an_event_subprocess_a_boundary_and_a_catch_together() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}{}{}{}{}{}
                <subProcess id="esp" triggeredByEvent="true"><startEvent id="es" isInterrupting="false"><signalEventDefinition signalRef="sig"/></startEvent>{}{}{}<endEvent id="ee"/></subProcess>
                <endEvent id="e1"/><endEvent id="e2"/><endEvent id="e3"/>"#,
                flow("f0", "s", "fork"),
                flow("f1", "fork", "a"),
                task("a", "f1", "f2"),
                flow("f2", "a", "e1"),
                boundary("bd", "a", false),
                flow("fb", "bd", "h"),
                task("h", "fb", "fh"),
                flow("fh", "h", "e2"),
                flow("f3", "fork", "c"),
                catch("c", "sig"),
                flow("f4", "c", "b"),
                task("b", "f4", "f5") + &flow("f5", "b", "e3"),
                flow("j0", "es", "k"),
                task("k", "j0", "j1"),
                flow("j1", "k", "ee"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(
        sorted(signal(&mut d, "S")),
        ["dispatch b", "dispatch h", "dispatch k"]
    );
}

/// §10.5.5 does not say how two signal elements are told apart at run time; TRACE (like
/// Camunda) matches signals by name, so two definitions with one name are one signal.
#[test]
fn two_signal_definitions_sharing_a_name_are_one_signal() {
    let mut d = Driver::new(&format!(
        r#"<signal id="s1" name="S"/><signal id="s2" name="S"/>{}"#,
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}{}{}<endEvent id="e1"/><endEvent id="e2"/>"#,
                flow("f0", "s", "fork"),
                flow("f1", "fork", "c"),
                catch("c", "s2"),
                flow("f2", "c", "e1"),
                flow("f3", "fork", "a"),
                task("a", "f3", "f4"),
                flow("f4", "a", "t"),
                throw("t", "s1"),
                flow("f5", "t", "e2"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// A signal element without a name is known by its id (the name a signal from outside
/// gives).
#[test]
fn a_signal_without_a_name_is_known_by_its_id() {
    let mut d = Driver::new(&format!(
        r#"<signal id="noname"/>{}"#,
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "c"),
                catch("c", "noname"),
                flow("f1", "c", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "other"), Vec::<String>::new());
    assert_eq!(signal(&mut d, "noname"), ["completed"]);
}

/// `signalRef` is optional (§10.5.5: `signalRef` [0..1]) and the specification says nothing of how an
/// anonymous signal travels. TRACE treats every anonymous signal as one signal with the empty
/// name: an anonymous throw reaches anonymous catchers (in any instance) and no named one; a
/// named throw never reaches an anonymous catcher.
#[test]
fn an_anonymous_signal_reaches_only_anonymous_catchers() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<parallelGateway id="fork"/>{}{}{}{}{}{}{}{}{}{}{}{}{}{}{}<endEvent id="e1"/><endEvent id="e2"/><endEvent id="e3"/>"#,
                flow("f0", "s", "fork"),
                flow("f1", "fork", "ca"),
                catch("ca", ""),
                flow("f2", "ca", "a"),
                task("a", "f2", "f3"),
                flow("f3", "a", "e1"),
                flow("f4", "fork", "cn"),
                catch("cn", "sig"),
                flow("f5", "cn", "b"),
                task("b", "f5", "f6"),
                flow("f6", "b", "e2"),
                flow("f7", "fork", "w"),
                task("w", "f7", "f8"),
                flow("f8", "w", "t"),
                throw("t", ""),
                flow("f9", "t", "e3"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch w"]);
    assert_eq!(d.complete("w", &[]), ["dispatch a"]);
    assert_eq!(signal(&mut d, "S"), ["dispatch b"]);
    d.complete("a", &[]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// A signal from outside (`Event::SignalReceived`) that nothing waits for is accepted and
/// changes nothing but the input counter.
#[test]
fn an_outside_signal_nobody_waits_for_changes_nothing() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "a"),
                task("a", "f0", "f1"),
                flow("f1", "a", "e"),
            )
        )
    ));
    d.start(&[]);
    let before = d.e.state().clone();
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    let after = d.e.state();
    assert_eq!(
        (&after.instances, &after.scopes, &after.tokens, &after.waits),
        (
            &before.instances,
            &before.scopes,
            &before.tokens,
            &before.waits
        )
    );
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// One occurrence is consumed once per catcher: a token that passes a signal catch event and
/// then reaches a second catch event on the same signal waits there for the next occurrence
/// (§13.5.2: waiting starts when the event is reached).
#[test]
fn one_occurrence_moves_a_token_past_one_catch_event_only() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "c1"),
                catch("c1", "sig"),
                flow("f1", "c1", "c2"),
                catch("c2", "sig"),
                flow("f2", "c2", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), ["completed"]);
}

/// §13.5.3: an interrupting boundary on a multi-instance activity cancels all its instances.
#[test]
fn an_interrupting_boundary_on_a_multi_instance_task_cancels_every_instance() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<serviceTask id="a"><extensionElements><trace:task resource="sys.a"/></extensionElements><multiInstanceLoopCharacteristics><loopCardinality>2</loopCardinality></multiInstanceLoopCharacteristics></serviceTask>{}{}{}{}{}<endEvent id="e"/>"#,
                flow("f0", "s", "a"),
                boundary("b", "a", true),
                flow("fb", "b", "h"),
                task("h", "fb", "f2"),
                flow("f2", "h", "e"),
                flow("f1", "a", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch a"]);
    assert_eq!(signal(&mut d, "S"), ["cancel a", "cancel a", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §10.5.4 multiple catch event (signal or message): the first trigger passes the token on
/// and the other subscription is dropped.
#[test]
fn a_multiple_catch_event_passes_on_the_signal_and_drops_its_message() {
    let mut d = Driver::new(&format!(
        r#"{SIGNALS}<message id="m" name="M"/>{}"#,
        process(
            "p",
            &format!(
                r#"<startEvent id="s"/>{}<intermediateCatchEvent id="c"><signalEventDefinition signalRef="sig"/><messageEventDefinition messageRef="m"/></intermediateCatchEvent>{}<endEvent id="e"/>"#,
                flow("f0", "s", "c"),
                flow("f1", "c", "e"),
            )
        )
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(signal(&mut d, "S"), ["completed"]);
    let r = d.step(Event::MessageReceived {
        name: "M".into(),
        correlation: None,
        payload: Vars::new(),
    });
    assert!(matches!(r, Err(Rejected::NoReceiver(_))), "{r:?}");
}
