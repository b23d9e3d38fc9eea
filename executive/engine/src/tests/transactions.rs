//! Chapter 13 semantics: transactions cancelled, failed or completed while other branches move
//! (rules in docs/engine-semantics.md; BPMN 2.0.2 §10.3.5 Transaction, §10.7, §13.5.5, §13.5.6).

use super::*;

/// A compensation handler: a service task marked `isForCompensation`.
fn handler(id: &str) -> String {
    format!(
        r#"<serviceTask id="{id}" isForCompensation="true"><extensionElements><trace:task resource="sys.{id}"/></extensionElements></serviceTask>"#
    )
}

/// A compensation boundary event on `activity`, associated with `handler` (which is declared
/// too).
fn compensated_by(activity: &str, h: &str) -> String {
    format!(
        r#"<boundaryEvent id="cb_{activity}" attachedToRef="{activity}"><compensateEventDefinition/></boundaryEvent>
        {}<association id="as_{activity}" sourceRef="cb_{activity}" targetRef="{h}"/>"#,
        handler(h)
    )
}

/// A task `id` compensated by the handler `c{id}`.
fn compensable(id: &str) -> String {
    task(id, "", "") + &compensated_by(id, &format!("c{id}"))
}

fn cancel_end(id: &str) -> String {
    format!(r#"<endEvent id="{id}"><cancelEventDefinition/></endEvent>"#)
}

fn compensation_throw(id: &str, definition: &str) -> String {
    format!(r#"<intermediateThrowEvent id="{id}">{definition}</intermediateThrowEvent>"#)
}

const COMPENSATE: &str = "<compensateEventDefinition/>";

/// A process `p` made of `parts` after its start `s`.
fn process(parts: &[String]) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}</process>"#,
        parts.concat()
    )
}

/// Transaction `T` holding `inner` (with its start event `ts`) and its cancel boundary `bc`
/// leading to task `after`, then to `after_next` (`"ea"`: an end event declared here); `T`
/// itself leads along `ft` to `next`.
fn transaction(inner: &[String], next: &str, after_next: &str) -> String {
    format!(
        r#"<transaction id="T"><startEvent id="ts"/>{}</transaction>
        <boundaryEvent id="bc" attachedToRef="T"><cancelEventDefinition/></boundaryEvent>
        {}{}{}{}"#,
        inner.concat(),
        path("fbc", &["bc", "after", after_next]),
        task("after", "", ""),
        if after_next == "ea" {
            ends(&["ea"])
        } else {
            String::new()
        },
        flow("ft", "T", next),
    )
}

/// A process `p`: start → transaction `T` (`inner`, see `transaction`) → end `e`, plus `extra`;
/// the cancel boundary's path ends at `ea`.
fn transaction_process(inner: &[String], extra: &str) -> String {
    process(&[
        flow("f0", "s", "T"),
        transaction(inner, "e", "ea"),
        ends(&["e"]),
        extra.to_owned(),
    ])
}

/// §10.3.5, §13.5.6: a cancel end event aborts the transaction: the task still running in the
/// other branch is cancelled, the completed activities are compensated newest first (one
/// handler after the other), and only then is the cancel boundary's flow taken.
#[test]
fn cancel_withdraws_the_running_task_compensates_newest_first_then_takes_the_boundary() {
    let mut d = Driver::new(&transaction_process(
        &[
            parallel("tf"),
            path("t", &["ts", "tf", "A", "B", "C", "te"]),
            path("u", &["tf", "W", "tc"]),
            compensable("A"),
            compensable("B"),
            tasks(&["C", "W"]),
            ends(&["te"]),
            cancel_end("tc"),
        ],
        "",
    ));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch W"]);
    assert_eq!(d.complete("A", &[]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[]), ["dispatch C"]);
    assert_eq!(d.complete("W", &[]), ["cancel C", "dispatch cB"]);
    assert_eq!(d.complete("cB", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);
    // The cancelled task's late answer is refused.
    let r = d.try_complete_key(d.key("C"), &[]);
    assert!(matches!(r, Err(Rejected::UnknownTask(_))), "{r:?}");
}

/// §13.5.5: compensation runs in reverse order of completion; activities of concurrent branches
/// have no order between them in the specification, and TRACE keeps one total order: newest
/// completion first, across branches.
#[test]
fn cancel_compensates_across_branches_in_reverse_completion_order() {
    let mut d = Driver::new(&transaction_process(
        &[
            parallel("tf"),
            path("t", &["ts", "tf", "A", "B", "te"]),
            path("u", &["tf", "X", "Y", "tc"]),
            compensable("A"),
            compensable("B"),
            compensable("X"),
            task("Y", "", ""),
            ends(&["te"]),
            cancel_end("tc"),
        ],
        "",
    ));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch X"]);
    assert_eq!(d.complete("A", &[]), ["dispatch B"]);
    assert_eq!(d.complete("X", &[]), ["dispatch Y"]);
    // B's branch ends inside the transaction; the transaction is still running.
    assert_eq!(d.complete("B", &[]), none());
    assert_eq!(d.complete("Y", &[]), ["dispatch cB"]);
    assert_eq!(d.complete("cB", &[]), ["dispatch cX"]);
    assert_eq!(d.complete("cX", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);
}

/// §10.3.5, §13.5.6: the cancel aborts everything inside the transaction, including a
/// compensation handler started by a compensation throw inside it; every completed activity
/// whose compensation has not started yet is still compensated before the cancel boundary is
/// taken (a cancelled transaction leaves no completed work uncompensated). The interrupted
/// handler itself is not started again: the specification is silent, and TRACE runs a
/// handler at most once per completed activity.
#[test]
fn cancel_while_a_compensation_throw_runs_interrupts_its_handler_and_compensates_the_rest() {
    let mut d = Driver::new(&transaction_process(
        &[
            parallel("tf"),
            path("t", &["ts", "tf", "A", "B", "th", "te"]),
            path("u", &["tf", "W", "tc"]),
            compensable("A"),
            compensable("B"),
            compensation_throw("th", COMPENSATE),
            task("W", "", ""),
            ends(&["te"]),
            cancel_end("tc"),
        ],
        "",
    ));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch W"]);
    assert_eq!(d.complete("A", &[]), ["dispatch B"]);
    // The throw compensates newest first: B's handler runs, A's waits its turn.
    assert_eq!(d.complete("B", &[]), ["dispatch cB"]);
    assert_eq!(d.complete("W", &[]), ["cancel cB", "dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);
}

/// §13.5.6 (terminate), §10.3.5: the compensation that a cancelled transaction runs belongs to
/// the instance; a terminate end event reached meanwhile in a parallel branch outside the
/// transaction withdraws the running handler, and the cancel boundary's flow is never taken.
#[test]
fn terminate_outside_while_the_cancelled_transaction_compensates_stops_everything() {
    let inner = [
        path("t", &["ts", "A", "tc"]),
        compensable("A"),
        cancel_end("tc"),
    ];
    let mut d = Driver::new(&process(&[
        path("f", &["s", "P", "T"]),
        parallel("P"),
        transaction(&inner, "e", "ea"),
        ends(&["e"]),
        path("g", &["P", "Z", "z"]),
        task("Z", "", ""),
        r#"<endEvent id="z"><terminateEventDefinition/></endEvent>"#.to_owned(),
    ]));
    let out = d.start(&[]);
    assert_eq!(sorted(out), ["dispatch A", "dispatch Z"]);
    assert_eq!(d.complete("A", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("Z", &[]), ["cancel cA", "terminated"]);
    assert!(d.e.state().tokens.is_empty());
}

/// §10.3.5: cancelling a transaction affects only what is inside it; a token in a parallel
/// branch outside keeps moving during the cancel and its compensation, and the cancel
/// boundary's token is an ordinary token afterwards (here it synchronises with that branch).
#[test]
fn tokens_outside_the_transaction_keep_moving_while_it_is_cancelled() {
    let inner = [
        path("t", &["ts", "A", "W", "tc"]),
        compensable("A"),
        task("W", "", ""),
        cancel_end("tc"),
    ];
    let mut d = Driver::new(&process(&[
        path("f", &["s", "P", "T"]),
        parallel("P"),
        transaction(&inner, "e0", "J"),
        ends(&["e0"]),
        path("g", &["P", "Z1", "Z2", "J", "e"]),
        tasks(&["Z1", "Z2"]),
        parallel("J"),
        ends(&["e"]),
    ]));
    assert_eq!(sorted(d.start(&[])), ["dispatch A", "dispatch Z1"]);
    assert_eq!(d.complete("A", &[]), ["dispatch W"]);
    assert_eq!(d.complete("W", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("Z1", &[]), ["dispatch Z2"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    // The join waits for the outside branch: the boundary token is an ordinary token.
    assert_eq!(d.complete("after", &[]), none());
    assert_eq!(d.complete("Z2", &[]), ["completed"]);
}

/// An error boundary `bh` on `T` leading to task `R`, then a compensation throw for the whole
/// enclosing scope, then an end.
fn hazard_path() -> String {
    [
        r#"<boundaryEvent id="bh" attachedToRef="T"><errorEventDefinition/></boundaryEvent>"#,
        &path("h", &["bh", "R", "hc", "eh"]),
        &task("R", "", ""),
        &compensation_throw("hc", COMPENSATE),
        &ends(&["eh"]),
    ]
    .concat()
}

/// §10.3.5 (Hazard), §10.7.3: an error inside a transaction interrupts it without compensation
/// (running work is cancelled, completed activities are not compensated), its error boundary is
/// taken, not its cancel boundary; and a failed activity is not compensable afterwards
/// ("presumed abort": its compensation is an empty operation).
#[test]
fn a_failing_task_inside_a_transaction_is_a_hazard_without_compensation() {
    let mut d = Driver::new(&transaction_process(
        &[
            parallel("tf"),
            path("t", &["ts", "tf", "A", "E", "te"]),
            path("u", &["tf", "W", "tc"]),
            compensable("A"),
            tasks(&["E", "W"]),
            ends(&["te"]),
            cancel_end("tc"),
        ],
        &hazard_path(),
    ));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch W"]);
    assert_eq!(d.complete("A", &[]), ["dispatch E"]);
    assert_eq!(d.fail("E", "HAZARD"), ["cancel W", "dispatch R"]);
    // Nothing to compensate: the transaction failed.
    assert_eq!(d.complete("R", &[]), ["completed"]);
}

/// §10.3.5 (Hazard), §13.5.6: an error end event inside the transaction is a hazard too: error
/// boundary, no compensation, even with a completed compensable activity inside.
#[test]
fn an_error_end_event_inside_a_transaction_is_a_hazard_not_a_cancel() {
    let mut d = Driver::new(&transaction_process(
        &[
            path("t", &["ts", "A", "tx"]),
            compensable("A"),
            r#"<endEvent id="tx"><errorEventDefinition/></endEvent>"#.to_owned(),
        ],
        &hazard_path(),
    ));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch R"]);
    assert_eq!(d.complete("R", &[]), ["completed"]);
}

/// A transaction `T` (A then B, both compensable) that completes, then `X` (compensable), then
/// a compensation throw `th` (for `activity_ref`, or the whole scope), then the end.
fn completed_transaction(activity_ref: Option<&str>) -> String {
    let inner = [
        path("t", &["ts", "A", "B", "te"]),
        compensable("A"),
        compensable("B"),
        ends(&["te"]),
    ];
    let def = match activity_ref {
        Some(a) => format!(r#"<compensateEventDefinition activityRef="{a}"/>"#),
        None => COMPENSATE.to_owned(),
    };
    process(&[
        flow("f0", "s", "T"),
        transaction(&inner, "X", "ea"),
        compensable("X"),
        path("g", &["X", "th", "e"]),
        compensation_throw("th", &def),
        ends(&["e"]),
    ])
}

/// §10.3.5 (successful completion), §13.5.5: a transaction that completes runs no
/// compensation; a later compensation throw outside compensates it as a whole (its completed
/// activities newest first), in reverse completion order with the activities around it.
#[test]
fn a_completed_transaction_is_compensated_as_a_whole_by_a_later_throw_outside() {
    let mut d = Driver::new(&completed_transaction(None));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[]), ["dispatch X"]);
    assert_eq!(d.complete("X", &[]), ["dispatch cX"]);
    assert_eq!(d.complete("cX", &[]), ["dispatch cB"]);
    assert_eq!(d.complete("cB", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["completed"]);
    // With activityRef naming the transaction, only the transaction is compensated.
    let mut d = Driver::new(&completed_transaction(Some("T")));
    d.start(&[]);
    d.complete("A", &[]);
    d.complete("B", &[]);
    assert_eq!(d.complete("X", &[]), ["dispatch cB"]);
    assert_eq!(d.complete("cB", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["completed"]);
}

/// A transaction whose task `A` has a non-interrupting timer boundary (1 s) leading to `H`
/// (compensable by `cH` when `h_compensable`); `A` leads to the cancel end event.
fn boundary_inside(h_compensable: bool) -> String {
    transaction_process(
        &[
            path("t", &["ts", "A", "tc"]),
            compensable("A"),
            format!(
                r#"<boundaryEvent id="tb" attachedToRef="A" cancelActivity="false">{}</boundaryEvent>"#,
                duration("PT1S")
            ),
            path("u", &["tb", "H", "te"]),
            if h_compensable {
                compensable("H")
            } else {
                task("H", "", "")
            },
            ends(&["te"]),
            cancel_end("tc"),
        ],
        "",
    )
}

/// §13.5.3, §13.5.6: the token a non-interrupting boundary event produced lives inside the
/// transaction; a cancel end event reached while it still runs cancels its task too. Had it
/// completed, its activity would be compensated with the others, newest first.
#[test]
fn cancel_reached_while_a_non_interrupting_boundary_branch_runs_cancels_that_branch_too() {
    let mut d = Driver::new(&boundary_inside(false));
    assert_eq!(d.start(&[]), ["timer 1000", "dispatch A"]);
    assert_eq!(d.fire(0, 1000), ["dispatch H"]);
    assert_eq!(d.complete("A", &[]), ["cancel H", "dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);

    let mut d = Driver::new(&boundary_inside(true));
    d.start(&[]);
    assert_eq!(d.fire(0, 1000), ["dispatch H"]);
    assert_eq!(d.complete("H", &[]), none());
    assert_eq!(d.complete("A", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch cH"]);
    assert_eq!(d.complete("cH", &[]), ["dispatch after"]);
}

/// §13.5.5: a sub-process completed inside the cancelled transaction is compensated through its
/// own completed activities, at its place in the reverse completion order.
#[test]
fn a_completed_sub_process_inside_a_cancelled_transaction_is_compensated_through_its_content() {
    let mut d = Driver::new(&transaction_process(
        &[
            path("t", &["ts", "S", "B", "tc"]),
            format!(
                r#"<subProcess id="S"><startEvent id="ss"/>{}{}{}</subProcess>"#,
                path("u", &["ss", "A", "se"]),
                compensable("A"),
                ends(&["se"]),
            ),
            compensable("B"),
            cancel_end("tc"),
        ],
        "",
    ));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[]), ["dispatch cB"]);
    assert_eq!(d.complete("cB", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
}

/// §13.5.6: two cancel end events reached in the same step cancel the transaction once: one
/// compensation, one token on the cancel boundary.
#[test]
fn two_cancel_ends_reached_together_cancel_once() {
    let mut d = Driver::new(&transaction_process(
        &[
            path("t", &["ts", "A", "tf", "tc1"]),
            flow("u", "tf", "tc2"),
            compensable("A"),
            parallel("tf"),
            cancel_end("tc1"),
            cancel_end("tc2"),
        ],
        "",
    ));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);
}

/// §10.3.5 with §13.4.2 (a cycle): a transaction retried through its cancel boundary starts
/// clean. The first attempt's completed work is compensated once, at its cancel; a later
/// compensation throw compensates only the successful attempt.
#[test]
fn a_transaction_retried_after_a_cancel_compensates_each_attempt_once() {
    let inner = [
        path("t", &["ts", "A", "tg"]),
        compensable("A"),
        r#"<exclusiveGateway id="tg" default="t3"/>"#.to_owned(),
        cond_flow("t2", "tg", "te", "ok"),
        ends(&["te"]),
        flow("t3", "tg", "tc"),
        cancel_end("tc"),
    ];
    let mut d = Driver::new(&process(&[
        path("f", &["s", "M", "T"]),
        r#"<exclusiveGateway id="M"/>"#.to_owned(),
        transaction(&inner, "th", "M"),
        compensation_throw("th", COMPENSATE),
        flow("f2", "th", "e"),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(
        d.complete("A", &[("ok", Value::Bool(false))]),
        ["dispatch cA"]
    );
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["dispatch A"]);
    assert_eq!(
        d.complete("A", &[("ok", Value::Bool(true))]),
        ["dispatch cA"]
    );
    assert_eq!(d.complete("cA", &[]), ["completed"]);
    assert_eq!(d.keys_of("cA").len(), 2);
}

/// §10.3.5, §13.5.6 (the specification does not say what happens without a cancel boundary
/// event): the transaction is still rolled back (its completed activities compensated), then
/// its path ends there; the instance completes once no token is left. It must not be left
/// running with no token and nothing to wait for.
#[test]
fn a_cancel_without_a_cancel_boundary_still_compensates_and_the_path_ends() {
    let mut d = Driver::new(&process(&[
        path("f", &["s", "T", "e"]),
        format!(
            r#"<transaction id="T"><startEvent id="ts"/>{}{}{}</transaction>"#,
            path("t", &["ts", "A", "tc"]),
            compensable("A"),
            cancel_end("tc"),
        ),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch cA"]);
    assert_eq!(d.complete("cA", &[]), ["completed"]);
}

/// §10.3.5, §13.5.3: cancelling the transaction withdraws it, so its own interrupting boundary
/// timer is disarmed at once (it cannot fire during the compensation; its late firing is
/// refused), while the token a non-interrupting boundary of the transaction produced before
/// runs outside it and is not affected.
#[test]
fn cancel_disarms_the_transactions_own_timers_but_not_what_its_boundaries_started() {
    let timer = |id: &str, interrupting: bool, due: &str| {
        format!(
            r#"<boundaryEvent id="{id}" attachedToRef="T" cancelActivity="{interrupting}">{}</boundaryEvent>"#,
            duration(due)
        )
    };
    let mut d = Driver::new(&transaction_process(
        &[
            path("t", &["ts", "A", "W", "tc"]),
            compensable("A"),
            task("W", "", ""),
            cancel_end("tc"),
        ],
        &[
            timer("nT", false, "PT1S"),
            path("n", &["nT", "N", "eN"]),
            task("N", "", ""),
            timer("iT", true, "PT1H"),
            flow("i0", "iT", "eI"),
            ends(&["eN", "eI"]),
        ]
        .concat(),
    ));
    let out = d.start(&[]);
    assert_eq!(
        sorted(out.clone()),
        ["dispatch A", "timer 1000", "timer 3600000"]
    );
    let timers: Vec<&String> = out.iter().filter(|a| a.starts_with("timer")).collect();
    let short = timers
        .iter()
        .position(|a| *a == "timer 1000")
        .expect("armed");
    assert_eq!(d.fire(short, 1000), ["dispatch N"]);
    assert_eq!(d.complete("A", &[]), ["dispatch W"]);
    assert_eq!(d.complete("W", &[]), ["untimer", "dispatch cA"]);
    let r = d.try_fire(1 - short);
    assert!(matches!(r, Err(Rejected::UnknownTimer(_))), "{r:?}");
    assert_eq!(d.complete("N", &[]), none());
    assert_eq!(d.complete("cA", &[]), ["dispatch after"]);
    assert_eq!(d.complete("after", &[]), ["completed"]);
}
