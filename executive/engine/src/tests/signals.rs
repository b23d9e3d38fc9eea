//! Chapter 13 semantics: signals (rules in docs/engine-semantics.md).
//!
//! A signal is broadcast (§10.5.6, §13.5.1–§13.5.3): every catcher waiting for it when it is
//! thrown catches it — in the thrower's instance and in every other one, intermediate catch
//! events, boundary events, event-based gateway branches, event sub-process starts — and every
//! process with a signal start event starts a new instance. A catcher that is not yet waiting
//! does not see it (the occurrence is not stored).

use super::*;

const SIGNALS: &str = r#"<signal id="sig" name="S"/><signal id="other" name="T"/>"#;

fn process(id: &str, parts: &[String]) -> String {
    format!(
        r#"<process id="{id}" isExecutable="true">{}</process>"#,
        parts.concat()
    )
}

/// The signals `S` (`sig`) and `T` (`other`) and a process `p` made of `parts`.
fn signals(parts: &[String]) -> String {
    format!("{SIGNALS}{}", process("p", parts))
}

/// A signal event definition of `signal`, or an anonymous one (`""`).
fn definition(signal: &str) -> String {
    if signal.is_empty() {
        "<signalEventDefinition/>".to_owned()
    } else {
        format!(r#"<signalEventDefinition signalRef="{signal}"/>"#)
    }
}

fn catch(id: &str, signal: &str) -> String {
    format!(
        r#"<intermediateCatchEvent id="{id}">{}</intermediateCatchEvent>"#,
        definition(signal)
    )
}

fn throw(id: &str, signal: &str) -> String {
    format!(
        r#"<intermediateThrowEvent id="{id}">{}</intermediateThrowEvent>"#,
        definition(signal)
    )
}

fn boundary(id: &str, on: &str, interrupting: bool) -> String {
    format!(
        r#"<boundaryEvent id="{id}" attachedToRef="{on}" cancelActivity="{interrupting}"><signalEventDefinition signalRef="sig"/></boundaryEvent>"#
    )
}

/// Process `q`: a start `qs` on signal `S`, sequence flows through `nodes` (declared in
/// `decls`), an end `qe`.
fn started_by_signal(nodes: &[&str], decls: &[String]) -> String {
    let all = [&["qs"], nodes, &["qe"]].concat();
    let start = format!(r#"<startEvent id="qs">{}</startEvent>"#, definition("sig"));
    process(
        "q",
        &[&[start, path("g", &all), ends(&["qe"])], decls].concat(),
    )
}

/// A signal boundary `bd` (`interrupting`) on `on`, leading to task `h` and its own end `eh`.
fn handled_boundary(on: &str, interrupting: bool) -> String {
    [
        boundary("bd", on, interrupting),
        path("h", &["bd", "h", "eh"]),
        task("h", "", ""),
        ends(&["eh"]),
    ]
    .concat()
}

/// §13.5.2: a catch event already waiting in the thrower's own instance catches the signal.
#[test]
fn a_throw_reaches_a_catch_already_waiting_in_the_same_instance() {
    let mut d = Driver::new(&signals(&[
        fork_into(&[&["c", "b"], &["a", "t"]]),
        catch("c", "sig"),
        tasks(&["b", "a"]),
        throw("t", "sig"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §13.5.2: waiting starts when the catch event is reached; a signal thrown earlier is gone
/// (§10.5.6: a published signal is not stored for later catchers).
#[test]
fn a_signal_thrown_before_the_catcher_waits_is_lost() {
    // Thrown on the way to the catch event.
    let mut d = Driver::new(&signals(&[
        chain(&["t", "c"]),
        throw("t", "sig"),
        catch("c", "sig"),
    ]));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["completed"]);

    // Thrown from outside while the instance still works on the task before the catch event.
    let mut d = Driver::new(&signals(&[
        chain(&["a", "c"]),
        task("a", "", ""),
        catch("c", "sig"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["completed"]);
}

/// Parallel branches of one step have no order in the specification (§13.4.1 fork: the tokens
/// move concurrently). TRACE lets the other tokens of the throw's wave arrive before a signal
/// is thrown (`waves.rs`), so a catch event reached in the same wave as the throw catches it.
#[test]
fn a_throw_waits_for_the_sibling_branches_of_its_wave() {
    let mut d = Driver::new(&signals(&[
        // The throwing branch comes first in document order.
        fork_into(&[&["t"], &["c"]]),
        throw("t", "sig"),
        catch("c", "sig"),
    ]));
    assert_eq!(d.start(&[]), ["completed"]);
}

/// §10.5.6: a signal is broadcast to every catcher in every instance, the thrower's included;
/// each catcher consumes its own copy.
#[test]
fn a_throw_reaches_every_waiting_catcher_of_every_instance() {
    let mut d = Driver::new(&signals(&[
        fork_into(&[&["c"], &["a", "t"]]),
        catch("c", "sig"),
        task("a", "", ""),
        throw("t", "sig"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.start(&[]), ["dispatch a"]);
    // The first instance throws: its own catch and the second instance's catch both pass.
    assert_eq!(d.complete_nth(0, &[]), ["completed"]);
    // The second instance's catch already consumed that signal; its own throw finds nobody.
    assert_eq!(d.complete_nth(1, &[]), ["completed"]);
}

/// §10.5.6, §13.5.1: a signal start event starts a new instance for each signal; the
/// occurrence that started it is consumed by the start, not by the new instance's own catch
/// events reached afterwards.
#[test]
fn a_signal_start_event_starts_one_instance_per_signal() {
    let mut d = Driver::new(&format!(
        "{SIGNALS}{}",
        started_by_signal(&["c", "b"], &[catch("c", "sig"), task("b", "", "")])
    ));
    // The first instance starts and waits at its catch event.
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.e.state().instances.len(), 1);
    // The second signal moves the first instance on and starts a second one.
    assert_eq!(d.signal("S"), ["dispatch b"]);
    assert_eq!(d.e.state().instances.len(), 2);
    assert_eq!(d.signal("T"), Vec::<String>::new());
    assert_eq!(d.e.state().instances.len(), 2);
}
/// §13.5.6: a signal end event throws, then its token is consumed like a none end event; the
/// thrower's instance completes and the signal starts a process elsewhere.
#[test]
fn a_signal_end_event_throws_then_ends_its_token() {
    let signal_end = format!(r#"<endEvent id="e">{}</endEvent>"#, definition("sig"));
    let mut d = Driver::new(&format!(
        "{}{}",
        signals(&[
            r#"<startEvent id="s"/>"#.to_owned(),
            path("f", &["s", "a", "e"]),
            task("a", "", ""),
            signal_end,
        ]),
        started_by_signal(&["b"], &[task("b", "", "")])
    ));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed", "dispatch b"]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// §13.5.3: an interrupting signal boundary event cancels its task and follows its own flow;
/// after that the task's boundary no longer listens.
#[test]
fn an_interrupting_boundary_on_a_task_cancels_it() {
    let mut d = Driver::new(&signals(&[
        chain(&["a"]),
        task("a", "", ""),
        handled_boundary("a", true),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), ["cancel a", "dispatch h"]);
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §13.5.3: a non-interrupting signal boundary event leaves its task running and fires again
/// at each signal while the task runs; it stops listening once the task completes, and the
/// instance completes only when the boundary paths have finished too.
#[test]
fn a_non_interrupting_boundary_on_a_task_fires_at_each_signal_while_it_runs() {
    let mut d = Driver::new(&signals(&[
        chain(&["a"]),
        task("a", "", ""),
        handled_boundary("a", false),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), ["dispatch h"]);
    assert_eq!(d.signal("S"), ["dispatch h"]);
    assert_eq!(d.complete("a", &[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.complete_nth(1, &[]), Vec::<String>::new());
    assert_eq!(d.complete_nth(2, &[]), ["completed"]);
}

/// Sub-process `sub` (start `ss`, `inner`, end `se`) on the line from the start to the end,
/// with `handled_boundary` on it.
fn sub_process(inner: &str, interrupting: bool) -> String {
    signals(&[
        chain(&["sub"]),
        format!(
            r#"<subProcess id="sub"><startEvent id="ss"/>{inner}<endEvent id="se"/></subProcess>"#
        ),
        handled_boundary("sub", interrupting),
    ])
}

/// §13.5.3 on a sub-process: interrupting cancels everything inside it; non-interrupting lets
/// it run on beside the boundary path.
#[test]
fn a_boundary_on_a_subprocess_interrupts_it_or_runs_beside_it() {
    // Inside: a fork into tasks `x` and `y`, each to the end.
    let inner = [
        path("i", &["ss", "fork"]),
        parallel("fork"),
        path("x", &["fork", "x", "se"]),
        path("y", &["fork", "y", "se"]),
        tasks(&["x", "y"]),
    ]
    .concat();
    let mut d = Driver::new(&sub_process(&inner, true));
    assert_eq!(d.start(&[]), ["dispatch x", "dispatch y"]);
    assert_eq!(d.signal("S"), ["cancel x", "cancel y", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);

    let mut d = Driver::new(&sub_process(&inner, false));
    assert_eq!(d.start(&[]), ["dispatch x", "dispatch y"]);
    assert_eq!(d.signal("S"), ["dispatch h"]);
    assert_eq!(d.complete("x", &[]), Vec::<String>::new());
    assert_eq!(d.complete("h", &[]), Vec::<String>::new());
    assert_eq!(d.complete("y", &[]), ["completed"]);
}

/// A signal thrown inside a sub-process reaches the interrupting boundary of that same
/// sub-process (the broadcast knows no scopes): the sub-process, thrower included, is
/// withdrawn and the boundary path runs.
#[test]
fn a_signal_thrown_inside_a_subprocess_interrupts_it_through_its_own_boundary() {
    let inner = [
        path("i", &["ss", "t", "x", "se"]),
        throw("t", "sig"),
        task("x", "", ""),
    ]
    .concat();
    let mut d = Driver::new(&sub_process(&inner, true));
    assert_eq!(d.start(&[]), ["dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// An event-based gateway `g` after the start, whose branches each lead through their nodes
/// (declared by the caller) to the end `e`.
fn event_based(branches: &[&[&str]]) -> String {
    let mut out = format!(
        r#"<startEvent id="s"/>{}<eventBasedGateway id="g"/><endEvent id="e"/>"#,
        flow("f", "s", "g")
    );
    for (k, nodes) in branches.iter().enumerate() {
        let all = [&["g"], *nodes, &["e"]].concat();
        out.push_str(&path(&format!("b{k}_"), &all));
    }
    out
}

/// §13.4.4: at an event-based gateway the signal branch wins; the other events are withdrawn
/// (the timer cancelled).
#[test]
fn an_event_based_gateway_takes_the_signal_branch_and_withdraws_the_others() {
    let mut d = Driver::new(&signals(&[
        event_based(&[&["c", "a"], &["tm", "b"]]),
        catch("c", "sig"),
        format!(
            r#"<intermediateCatchEvent id="tm">{}</intermediateCatchEvent>"#,
            duration("PT1H")
        ),
        tasks(&["a", "b"]),
    ]));
    assert_eq!(d.start(&[]), ["timer 3600000"]);
    assert_eq!(d.signal("S"), ["untimer", "dispatch a"]);
    let late = d.try_fire(0);
    assert!(matches!(late, Err(Rejected::UnknownTimer(_))), "{late:?}");
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// §13.4.4 says the first event wins; one signal satisfying two branches of one event-based
/// gateway at once is not ordered by the specification. TRACE takes one branch only, the
/// first in document order.
#[test]
fn an_event_based_gateway_with_two_branches_on_one_signal_takes_only_one() {
    let mut d = Driver::new(&signals(&[
        event_based(&[&["c1", "a"], &["c2", "b"]]),
        catch("c1", "sig"),
        catch("c2", "sig"),
        tasks(&["a", "b"]),
    ]));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["dispatch a"]);
    assert_eq!(d.complete("a", &[]), ["completed"]);
}

/// One broadcast reaches every kind of catcher at once: an event sub-process start, a
/// boundary event and an intermediate catch event of the same instance.
#[test]
fn one_signal_reaches_an_event_subprocess_a_boundary_and_a_catch_together() {
    let mut d = Driver::new(&signals(&[
        fork_into(&[&["a"], &["c", "b"]]),
        task("a", "", ""),
        handled_boundary("a", false),
        catch("c", "sig"),
        task("b", "", ""),
        format!(
            r#"<subProcess id="esp" triggeredByEvent="true"><startEvent id="es" isInterrupting="false">{}</startEvent>{}{}<endEvent id="ee"/></subProcess>"#,
            definition("sig"),
            path("j", &["es", "k", "ee"]),
            task("k", "", ""),
        ),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a"]);
    assert_eq!(
        sorted(d.signal("S")),
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
            &[
                fork_into(&[&["c"], &["a", "t"]]),
                catch("c", "s2"),
                task("a", "", ""),
                throw("t", "s1"),
            ]
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
        process("p", &[chain(&["c"]), catch("c", "noname")])
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.signal("other"), Vec::<String>::new());
    assert_eq!(d.signal("noname"), ["completed"]);
}

/// `signalRef` is optional (§10.5.5: `signalRef` [0..1]) and the specification says nothing of how an
/// anonymous signal travels. TRACE treats every anonymous signal as one signal with the empty
/// name: an anonymous throw reaches anonymous catchers (in any instance) and no named one; a
/// named throw never reaches an anonymous catcher.
#[test]
fn an_anonymous_signal_reaches_only_anonymous_catchers() {
    let mut d = Driver::new(&signals(&[
        fork_into(&[&["ca", "a"], &["cn", "b"], &["w", "t"]]),
        catch("ca", ""),
        catch("cn", "sig"),
        tasks(&["a", "b", "w"]),
        throw("t", ""),
    ]));
    assert_eq!(d.start(&[]), ["dispatch w"]);
    assert_eq!(d.complete("w", &[]), ["dispatch a"]);
    assert_eq!(d.signal("S"), ["dispatch b"]);
    d.complete("a", &[]);
    assert_eq!(d.complete("b", &[]), ["completed"]);
}

/// A signal from outside (`Event::SignalReceived`) that nothing waits for is accepted and
/// changes nothing but the input counter.
#[test]
fn an_outside_signal_nobody_waits_for_changes_nothing() {
    let mut d = Driver::new(&signals(&[chain(&["a"]), task("a", "", "")]));
    d.start(&[]);
    let before = d.e.state().clone();
    assert_eq!(d.signal("S"), Vec::<String>::new());
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
    let mut d = Driver::new(&signals(&[
        chain(&["c1", "c2"]),
        catch("c1", "sig"),
        catch("c2", "sig"),
    ]));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["completed"]);
}

/// §13.5.3: an interrupting boundary on a multi-instance activity cancels all its instances.
#[test]
fn an_interrupting_boundary_on_a_multi_instance_task_cancels_every_instance() {
    let mut d = Driver::new(&signals(&[
        chain(&["a"]),
        r#"<serviceTask id="a"><extensionElements><trace:task resource="sys.a"/></extensionElements><multiInstanceLoopCharacteristics><loopCardinality>2</loopCardinality></multiInstanceLoopCharacteristics></serviceTask>"#.to_owned(),
        handled_boundary("a", true),
    ]));
    assert_eq!(d.start(&[]), ["dispatch a", "dispatch a"]);
    assert_eq!(d.signal("S"), ["cancel a", "cancel a", "dispatch h"]);
    assert_eq!(d.complete("h", &[]), ["completed"]);
}

/// §10.5.4 multiple catch event (signal or message): the first trigger passes the token on
/// and the other subscription is dropped.
#[test]
fn a_multiple_catch_event_passes_on_the_signal_and_drops_its_message() {
    let mut d = Driver::new(&format!(
        r#"<message id="m" name="M"/>{}"#,
        signals(&[
            chain(&["c"]),
            r#"<intermediateCatchEvent id="c"><signalEventDefinition signalRef="sig"/><messageEventDefinition messageRef="m"/></intermediateCatchEvent>"#.to_owned(),
        ])
    ));
    assert_eq!(d.start(&[]), Vec::<String>::new());
    assert_eq!(d.signal("S"), ["completed"]);
    let r = d.message("M", None, &[]);
    assert!(matches!(r, Err(Rejected::NoReceiver(_))), "{r:?}");
}
