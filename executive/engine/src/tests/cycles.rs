//! Chapter 13 semantics: unstructured cycles made of sequence flows and gateways (rules in
//! docs/engine-semantics.md; BPMN 2.0.2 §13.3.1, §13.4.1–§13.4.3).

use super::*;

fn xor(id: &str) -> String {
    format!(r#"<exclusiveGateway id="{id}"/>"#)
}

fn and(id: &str) -> String {
    parallel(id)
}

fn or(id: &str) -> String {
    format!(r#"<inclusiveGateway id="{id}"/>"#)
}

/// An exclusive gateway `x` that goes back to `to` when `cond` holds, else on (its default
/// flow) to `next`.
fn back_or_on(x: &str, cond: &str, to: &str, next: &str) -> String {
    format!(
        r#"<exclusiveGateway id="{x}" default="{x}_on"/>{}{}"#,
        cond_flow(&format!("{x}_back"), x, to, cond),
        flow(&format!("{x}_on"), x, next)
    )
}

fn process(parts: &[String]) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}</process>"#,
        parts.concat()
    )
}

/// s → `merge` (the gateway `gateway`) → A → X, back to `merge` while `again`, else to the end.
fn loop_through_a(merge: &str, gateway: String) -> String {
    process(&[
        path("f", &["s", merge, "A", "X"]),
        gateway,
        task("A", "", ""),
        back_or_on("X", "again", merge, "e"),
        ends(&["e"]),
    ])
}

fn b(name: &str, v: bool) -> (&str, Value) {
    (name, Value::Bool(v))
}

/// Tokens waiting at a join.
fn joining(d: &Driver) -> usize {
    d.e.state().joining.values().map(|s| s.len()).sum()
}

fn finished(d: &Driver) -> bool {
    d.e.state().instances.values().all(|i| i.outcome.is_some())
}

/// §13.4.2: a backward flow into a converging exclusive gateway: each arriving token passes on
/// at once, so the task repeats until the exit condition; one token, whatever the round.
#[test]
fn backward_flow_into_an_exclusive_merge_repeats_until_the_exit() {
    let mut d = Driver::new(&loop_through_a("M", xor("M")));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    for _ in 0..3 {
        assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
        assert_eq!(d.e.state().tokens.len(), 1);
    }
    assert_eq!(d.complete("A", &[b("again", false)]), ["completed"]);
}

/// §13.3.1 (uncontrolled flow): an activity with several incoming flows starts once for every
/// arriving token, without waiting for the others; a backward flow straight into a task is such
/// a flow. Two tokens started in parallel circulate in the same cycle independently.
#[test]
fn backward_flow_straight_into_a_task_starts_it_for_every_token() {
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "P"),
        and("P"),
        flow("p1", "P", "A"),
        flow("p2", "P", "A"),
        task("A", "", ""),
        flow("f2", "A", "X"),
        back_or_on("X", "again", "A", "e"),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch A"]);
    let first = d.keys_of("A");
    // The first token leaves the cycle and ends; the instance waits for the other.
    assert_eq!(d.complete_key(first[0], &[b("again", false)]), none());
    assert_eq!(
        d.complete_key(first[1], &[b("again", true)]),
        ["dispatch A"]
    );
    assert_eq!(d.complete("A", &[b("again", false)]), ["completed"]);
}

/// A cycle A <-> B entered at A or at B (`D` decides) or at both (`D` a parallel fork):
/// s -> D -> {MA, MB}; MA -> A -> XA -(go)-> MB | e1; MB -> B -> XB -(go)-> MA | e2.
fn two_entries(d: &str) -> String {
    process(&[
        flow("f0", "s", "D"),
        d.to_owned(),
        cond_flow("da", "D", "MA", "!at_b"),
        cond_flow("db", "D", "MB", "at_b"),
        xor("MA"),
        path("a", &["MA", "A", "XA"]),
        back_or_on("XA", "go", "MB", "e1"),
        xor("MB"),
        path("b", &["MB", "B", "XB"]),
        back_or_on("XB", "go", "MA", "e2"),
        tasks(&["A", "B"]),
        ends(&["e1", "e2"]),
    ])
}

/// §13.4.2 (irreducible loop): a cycle with two entry points needs no special treatment; each
/// token follows the flows, whichever entry it came in by, and two tokens in the same cycle
/// move independently through its exclusive merges.
#[test]
fn a_cycle_with_two_entry_points_runs_from_either_entry_and_from_both() {
    let mut d = Driver::new(&two_entries(&xor("D")));
    assert_eq!(d.start(&[b("at_b", false)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("go", true)]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[b("go", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("go", false)]), ["completed"]);

    let mut d = Driver::new(&two_entries(&xor("D")));
    assert_eq!(d.start(&[b("at_b", true)]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[b("go", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("go", false)]), ["completed"]);

    // Entered at both (a parallel fork ignores conditions): two tokens in one cycle.
    let mut d = Driver::new(&two_entries(&and("D")));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[b("go", true)]), ["dispatch B"]);
    let bs = d.keys_of("B");
    assert_eq!(d.complete_key(bs[0], &[b("go", false)]), none());
    assert_eq!(d.e.state().tokens.len(), 1);
    assert_eq!(d.complete_key(bs[1], &[b("go", false)]), ["completed"]);
}

/// §13.4.2: nested cycles: the inner cycle runs to its exit in every round of the outer one.
#[test]
fn nested_cycles_run_the_inner_cycle_in_every_outer_round() {
    let mut d = Driver::new(&process(&[
        path("f", &["s", "MO", "O", "MI", "I", "XI"]),
        xor("MO"),
        xor("MI"),
        tasks(&["O", "I"]),
        back_or_on("XI", "inner", "MI", "XO"),
        back_or_on("XO", "outer", "MO", "e"),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch O"]);
    assert_eq!(d.complete("O", &[]), ["dispatch I"]);
    let go = |i, o| [b("inner", i), b("outer", o)];
    assert_eq!(d.complete("I", &go(true, true)), ["dispatch I"]);
    assert_eq!(d.complete("I", &go(false, true)), ["dispatch O"]);
    assert_eq!(d.complete("O", &[]), ["dispatch I"]);
    assert_eq!(d.complete("I", &go(true, false)), ["dispatch I"]);
    assert_eq!(d.complete("I", &go(false, false)), ["completed"]);
}

/// §13.4.1: a parallel join consumes exactly one token per incoming flow; excess tokens on one
/// flow stay there for the next activation. Here each branch is a cycle that sends one token to
/// the join per round (an inclusive split: always to the join, back when asked), so the join
/// pairs the rounds: A twice, then B twice, gives two activations, not one and not three.
#[test]
fn a_parallel_join_fed_by_cycles_pairs_tokens_round_by_round() {
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "P"),
        and("P"),
        path("a", &["P", "MA", "A", "IA", "J"]),
        cond_flow("ba", "IA", "MA", "again_a"),
        path("b", &["P", "MB", "B", "IB", "J"]),
        cond_flow("bb", "IB", "MB", "again_b"),
        xor("MA"),
        xor("MB"),
        tasks(&["A", "B"]),
        or("IA"),
        or("IB"),
        and("J"),
        path("j", &["J", "C", "e"]),
        task("C", "", ""),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[b("again_a", true)]), ["dispatch A"]);
    // Two tokens on the same incoming flow do not activate the join.
    assert_eq!(d.complete("A", &[b("again_a", false)]), none());
    assert_eq!(joining(&d), 2);
    // One token on B's flow: one activation; A's second token stays.
    assert_eq!(
        sorted(d.complete("B", &[b("again_b", true)])),
        ["dispatch B", "dispatch C"]
    );
    assert_eq!(joining(&d), 1);
    assert_eq!(d.complete("B", &[b("again_b", false)]), ["dispatch C"]);
    assert_eq!(joining(&d), 0);
    let cs = d.keys_of("C");
    assert_eq!(cs.len(), 2);
    assert_eq!(d.complete_key(cs[0], &[]), none());
    assert_eq!(d.complete_key(cs[1], &[]), ["completed"]);
}

/// §13.4.1: a cycle that comes back into a parallel join on one of its incoming flows only
/// brings one token there: the join waits for a token on the other flow, which never comes
/// (the model deadlocks there, as specified; the instance does not end).
#[test]
fn a_parallel_join_reentered_by_a_cycle_on_one_flow_waits_for_the_other() {
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "P"),
        and("P"),
        path("a", &["P", "A", "J"]),
        path("b", &["P", "MB", "B", "J"]),
        xor("MB"),
        and("J"),
        path("j", &["J", "C", "X"]),
        tasks(&["A", "B", "C"]),
        back_or_on("X", "again", "MB", "e"),
        ends(&["e"]),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[]), none());
    assert_eq!(d.complete("B", &[]), ["dispatch C"]);
    assert_eq!(d.complete("C", &[b("again", true)]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[]), none());
    assert_eq!(joining(&d), 1);
    assert!(!finished(&d));
}

/// s -> IF (inclusive split: `x > 0` to `first`, `x > 1` to `second`); `between`; J (inclusive
/// join) -> C -> e.
fn inclusive_split_and_join(first: &str, second: &str, between: &[String]) -> String {
    let frame = [
        flow("f0", "s", "IF"),
        or("IF"),
        cond_flow("i1", "IF", first, "x &gt; 0"),
        cond_flow("i2", "IF", second, "x &gt; 1"),
        or("J"),
        path("j", &["J", "C", "e"]),
        task("C", "", ""),
        ends(&["e"]),
    ];
    process(&[&frame, between].concat())
}

/// The variable `x`, for `inclusive_split_and_join`.
fn x(v: i64) -> [(&'static str, Value); 1] {
    [("x", Value::Int(v))]
}

/// `inclusive_split_and_join`: A -> J; MB -> B -> XB -(again)-> MB | J.
fn join_after_a_cycle() -> String {
    inclusive_split_and_join(
        "A",
        "MB",
        &[
            flow("fa", "A", "J"),
            xor("MB"),
            path("b", &["MB", "B", "XB"]),
            back_or_on("XB", "again", "MB", "J"),
            tasks(&["A", "B"]),
        ],
    )
}

/// §13.4.3: an inclusive join after a cycle waits while the token looping in the cycle can still
/// reach one of its empty incoming flows, however many rounds it takes, and fires as soon as it
/// arrives; without a token in the cycle it does not wait for it.
#[test]
fn an_inclusive_join_after_a_cycle_waits_for_the_looping_token_and_only_for_it() {
    let mut d = Driver::new(&join_after_a_cycle());
    assert_eq!(d.start(&x(2)), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[]), none());
    for _ in 0..3 {
        assert_eq!(d.complete("B", &[b("again", true)]), ["dispatch B"]);
    }
    assert_eq!(d.complete("B", &[b("again", false)]), ["dispatch C"]);
    assert_eq!(d.complete("C", &[]), ["completed"]);

    // The looping branch finishes first: the join waits for A.
    let mut d = Driver::new(&join_after_a_cycle());
    d.start(&x(2));
    assert_eq!(d.complete("B", &[b("again", false)]), none());
    assert_eq!(d.complete("A", &[]), ["dispatch C"]);

    // The cycle's branch was not taken: nothing to wait for.
    let mut d = Driver::new(&join_after_a_cycle());
    assert_eq!(d.start(&x(1)), ["dispatch A"]);
    assert_eq!(d.complete("A", &[]), ["dispatch C"]);
}

/// §13.4.3: an inclusive split and join inside a cycle synchronise each round on the branches
/// taken in that round: the join neither deadlocks on the token that loops back nor waits for
/// a branch the next round does not take.
#[test]
fn an_inclusive_join_inside_a_cycle_synchronises_each_round() {
    let mut d = Driver::new(&process(&[
        path("f", &["s", "M", "IF"]),
        xor("M"),
        or("IF"),
        cond_flow("i1", "IF", "A", "a"),
        cond_flow("i2", "IF", "B", "b"),
        tasks(&["A", "B"]),
        flow("fa", "A", "J"),
        flow("fb", "B", "J"),
        or("J"),
        flow("j1", "J", "X"),
        back_or_on("X", "again", "M", "e"),
        ends(&["e"]),
    ]));
    assert_eq!(
        d.start(&[b("a", true), b("b", true)]),
        ["dispatch A", "dispatch B"]
    );
    assert_eq!(d.complete("A", &[b("again", true)]), none());
    // Round 2 takes A only.
    assert_eq!(d.complete("B", &[b("b", false)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", false)]), ["completed"]);
}

/// §13.4.3: an inclusive gateway as the entry merge of a loop (one incoming flow from before
/// the loop, one backward flow) fires for every round: no other token can reach it.
#[test]
fn an_inclusive_merge_at_the_entry_of_a_loop_fires_every_round() {
    let mut d = Driver::new(&loop_through_a("J", or("J")));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", false)]), ["completed"]);
}

/// `inclusive_split_and_join`: MA -> A -> IA (inclusive split: always to J along `fa`, back to
/// MA when `again`); B -> J along `fb`.
fn cycle_feeding_an_inclusive_join() -> String {
    inclusive_split_and_join(
        "MA",
        "B",
        &[
            xor("MA"),
            path("a", &["MA", "A", "IA"]),
            or("IA"),
            flow("fa", "IA", "J"),
            cond_flow("back", "IA", "MA", "again"),
            flow("fb", "B", "J"),
            tasks(&["A", "B"]),
        ],
    )
}

/// §13.4.3, the activation rule exactly: the join is activated when some incoming flow has a
/// token and every token that can reach an *empty* incoming flow (without passing the join)
/// can also reach an occupied one. A token looping in a cycle that can only come back along an
/// occupied incoming flow belongs to the next activation: the join fires without it (and fires
/// again when it arrives). A token that can reach an empty incoming flow, and only that, is
/// waited for.
#[test]
fn an_inclusive_join_does_not_wait_for_a_looping_token_that_can_only_reach_an_occupied_flow() {
    let mut d = Driver::new(&cycle_feeding_an_inclusive_join());
    assert_eq!(d.start(&x(1)), ["dispatch A"]);
    // A's token reaches the join on `fa`; the next round of A can only come along `fa` again,
    // and nothing can reach `fb`.
    assert_eq!(
        sorted(d.complete("A", &[b("again", true)])),
        ["dispatch A", "dispatch C"]
    );
    assert_eq!(d.complete("A", &[b("again", false)]), ["dispatch C"]);
    d.complete_every("C");
    assert!(finished(&d));

    // With B running, the join waits for B (it can reach the empty `fb`), but once `fa` and
    // `fb` hold a token each, the looping A does not hold it back.
    let mut d = Driver::new(&cycle_feeding_an_inclusive_join());
    assert_eq!(sorted(d.start(&x(2))), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
    assert_eq!(d.complete("B", &[]), ["dispatch C"]);
    assert_eq!(d.complete("A", &[b("again", false)]), ["dispatch C"]);
}

/// A cycle through a parallel fork and join, a sub-process, an inclusive split and join and an
/// interrupting timer boundary, run for many rounds: the engine's state does not grow with the
/// rounds (same tokens, scopes, subscriptions and waiting joins each round; serialized size
/// constant up to the digits of the counters).
#[test]
fn a_cycle_run_for_many_rounds_keeps_the_state_bounded() {
    let mut d = Driver::new(&process(&[
        path("f", &["s", "M", "P"]),
        xor("M"),
        and("P"),
        path("a", &["P", "A", "J"]),
        task("A", "", ""),
        format!(
            r#"<boundaryEvent id="tb" attachedToRef="A">{}</boundaryEvent>"#,
            duration("PT1H")
        ),
        flow("t1", "tb", "et"),
        path("b", &["P", "S", "J"]),
        format!(
            r#"<subProcess id="S"><startEvent id="ss"/>{}{}<endEvent id="se"/></subProcess>"#,
            path("s", &["ss", "B", "se"]),
            task("B", "", ""),
        ),
        and("J"),
        flow("j1", "J", "I1"),
        or("I1"),
        cond_flow("o1", "I1", "t1x", "n &gt;= 0"),
        cond_flow("o2", "I1", "t2x", "n &gt;= 0"),
        r#"<task id="t1x"/><task id="t2x"/>"#.to_owned(),
        flow("o3", "t1x", "I2"),
        flow("o4", "t2x", "I2"),
        or("I2"),
        flow("i1", "I2", "X"),
        back_or_on("X", "again", "M", "e"),
        ends(&["et", "e"]),
    ]));
    let first = d.start(&[("n", Value::Int(0))]);
    assert_eq!(sorted(first), ["dispatch A", "dispatch B", "timer 3600000"]);
    let measure = |d: &Driver| {
        let s = d.e.state();
        (
            (s.tokens.len(), s.scopes.len(), s.waits.len()),
            (s.joining.len(), s.joins.len(), s.fired_complex.len()),
            serde_json::to_string(s).expect("serializes").len(),
        )
    };
    let (counts, joins, size) = measure(&d);
    // A's token, the sub-process's token and B's token inside it; the root and the
    // sub-process's scope; the timer.
    assert_eq!(counts, (3, 2, 1));
    const ROUNDS: usize = 1000;
    for round in 1..=ROUNDS {
        assert_eq!(d.complete("A", &[b("again", round < ROUNDS)]), ["untimer"]);
        let out = d.complete("B", &[]);
        if round == ROUNDS {
            assert_eq!(out, ["completed"]);
            break;
        }
        assert_eq!(
            sorted(out),
            ["dispatch A", "dispatch B", "timer 3600000"],
            "round {round}"
        );
        let (c, j, s) = measure(&d);
        assert_eq!((c, j), (counts, joins), "round {round}");
        // Ids and sequence numbers grow by a few digits; anything per round would be far more.
        assert!(s <= size + 200, "round {round}: {s} bytes, {size} at first");
    }
    let s = d.e.state();
    assert!(s.tokens.is_empty() && s.scopes.is_empty() && s.waits.is_empty());
    assert!(s.instances.values().all(|i| i.incidents.is_empty()));
}

/// Documented bound (docs/engine-semantics.md): a cycle without any wait state would never let
/// a step end; after 1,000,000 token moves in one step the looping token becomes an incident
/// (the instance keeps running and does not end). Tokens of other branches are not affected:
/// work dispatched before keeps its course, and the next input is processed normally.
#[test]
fn a_cycle_without_a_wait_state_stops_at_the_move_bound_with_an_incident() {
    let body = process(&[
        flow("f0", "s", "P"),
        and("P"),
        path("z", &["P", "Z", "e"]),
        task("Z", "", ""),
        ends(&["e"]),
        path("m", &["P", "M", "N", "M"]),
        xor("M"),
        xor("N"),
    ]);
    let mut d = Driver::new(&body);
    // Without move records: a million moves would otherwise record a million entries.
    d.e = engine(&body).with_move_records(false);
    let out = d.start(&[]);
    assert_eq!(
        out,
        [
            "dispatch Z",
            "incident the step exceeded 1000000 token moves: the model loops without waiting"
        ]
    );
    let s = d.e.state();
    assert_eq!(s.tokens.len(), 2);
    let i = s.instances.values().next().expect("instance");
    assert!(i.outcome.is_none());
    assert_eq!(i.incidents.len(), 1);
    // Z completes normally; the stuck token keeps the instance from ending.
    assert_eq!(d.complete("Z", &[]), none());
    assert_eq!(d.e.state().tokens.len(), 1);
    assert!(!finished(&d));
}
