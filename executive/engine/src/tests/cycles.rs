//! Chapter 13 semantics: unstructured cycles made of sequence flows and gateways (rules in
//! docs/engine-semantics.md; BPMN 2.0.2 §13.3.1, §13.4.1–§13.4.3).

use super::*;

fn xor(id: &str) -> String {
    format!(r#"<exclusiveGateway id="{id}"/>"#)
}

/// An exclusive gateway whose default flow is `default`.
fn xor_default(id: &str, default: &str) -> String {
    format!(r#"<exclusiveGateway id="{id}" default="{default}"/>"#)
}

fn and(id: &str) -> String {
    format!(r#"<parallelGateway id="{id}"/>"#)
}

fn or(id: &str) -> String {
    format!(r#"<inclusiveGateway id="{id}"/>"#)
}

fn end(id: &str) -> String {
    format!(r#"<endEvent id="{id}"/>"#)
}

fn process(parts: &[String]) -> String {
    format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}</process>"#,
        parts.concat()
    )
}

fn b(name: &str, v: bool) -> (&str, Value) {
    (name, Value::Bool(v))
}

fn none() -> Vec<String> {
    Vec::new()
}

fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

/// Every task key dispatched for `node`, oldest first.
fn keys_of(d: &Driver, node: &str) -> Vec<TaskKey> {
    d.tasks
        .iter()
        .filter(|(n, _)| n == node)
        .map(|(_, k)| *k)
        .collect()
}

/// Completes one task by its key.
fn complete_key(d: &mut Driver, task: TaskKey, output: &[(&str, Value)]) -> Vec<String> {
    let output = output
        .iter()
        .map(|(k, v)| ((*k).to_owned(), v.clone()))
        .collect();
    d.step(Event::TaskCompleted { task, output })
        .expect("accepted")
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
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "M"),
        xor("M"),
        flow("f1", "M", "A"),
        task("A", "f1", "f2"),
        flow("f2", "A", "X"),
        xor_default("X", "out"),
        cond_flow("back", "X", "M", "again"),
        flow("out", "X", "e"),
        end("e"),
    ]));
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
        task("A", "p1", "f2"),
        flow("f2", "A", "X"),
        xor_default("X", "out"),
        cond_flow("back", "X", "A", "again"),
        flow("out", "X", "e"),
        end("e"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch A"]);
    let first = keys_of(&d, "A");
    // The first token leaves the cycle and ends; the instance waits for the other.
    assert_eq!(complete_key(&mut d, first[0], &[b("again", false)]), none());
    assert_eq!(
        complete_key(&mut d, first[1], &[b("again", true)]),
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
        flow("m1", "MA", "A"),
        task("A", "m1", "a1"),
        flow("a1", "A", "XA"),
        xor_default("XA", "xa"),
        cond_flow("ab", "XA", "MB", "go"),
        flow("xa", "XA", "e1"),
        end("e1"),
        xor("MB"),
        flow("m2", "MB", "B"),
        task("B", "m2", "b1"),
        flow("b1", "B", "XB"),
        xor_default("XB", "xb"),
        cond_flow("ba", "XB", "MA", "go"),
        flow("xb", "XB", "e2"),
        end("e2"),
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
    let bs = keys_of(&d, "B");
    assert_eq!(complete_key(&mut d, bs[0], &[b("go", false)]), none());
    assert_eq!(d.e.state().tokens.len(), 1);
    assert_eq!(
        complete_key(&mut d, bs[1], &[b("go", false)]),
        ["completed"]
    );
}

/// §13.4.2: nested cycles: the inner cycle runs to its exit in every round of the outer one.
#[test]
fn nested_cycles_run_the_inner_cycle_in_every_outer_round() {
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "MO"),
        xor("MO"),
        flow("f1", "MO", "O"),
        task("O", "f1", "f2"),
        flow("f2", "O", "MI"),
        xor("MI"),
        flow("f3", "MI", "I"),
        task("I", "f3", "f4"),
        flow("f4", "I", "XI"),
        xor_default("XI", "xi"),
        cond_flow("bi", "XI", "MI", "inner"),
        flow("xi", "XI", "XO"),
        xor_default("XO", "xo"),
        cond_flow("bo", "XO", "MO", "outer"),
        flow("xo", "XO", "e"),
        end("e"),
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
        flow("p1", "P", "MA"),
        xor("MA"),
        flow("m1", "MA", "A"),
        task("A", "m1", "a1"),
        flow("a1", "A", "IA"),
        or("IA"),
        flow("fa", "IA", "J"),
        cond_flow("ba", "IA", "MA", "again_a"),
        flow("p2", "P", "MB"),
        xor("MB"),
        flow("m2", "MB", "B"),
        task("B", "m2", "b1"),
        flow("b1", "B", "IB"),
        or("IB"),
        flow("fb", "IB", "J"),
        cond_flow("bb", "IB", "MB", "again_b"),
        and("J"),
        flow("j1", "J", "C"),
        task("C", "j1", "c1"),
        flow("c1", "C", "e"),
        end("e"),
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
    let cs = keys_of(&d, "C");
    assert_eq!(cs.len(), 2);
    assert_eq!(complete_key(&mut d, cs[0], &[]), none());
    assert_eq!(complete_key(&mut d, cs[1], &[]), ["completed"]);
}

/// §13.4.1: a cycle that comes back into a parallel join on one of its incoming flows only
/// brings one token there: the join waits for a token on the other flow, which never comes
/// (the model deadlocks there, as specified; the instance does not end).
#[test]
fn a_parallel_join_reentered_by_a_cycle_on_one_flow_waits_for_the_other() {
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "P"),
        and("P"),
        flow("p1", "P", "A"),
        task("A", "p1", "fa"),
        flow("fa", "A", "J"),
        flow("p2", "P", "MB"),
        xor("MB"),
        flow("m2", "MB", "B"),
        task("B", "m2", "fb"),
        flow("fb", "B", "J"),
        and("J"),
        flow("j1", "J", "C"),
        task("C", "j1", "c1"),
        flow("c1", "C", "X"),
        xor_default("X", "out"),
        cond_flow("back", "X", "MB", "again"),
        flow("out", "X", "e"),
        end("e"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A", "dispatch B"]);
    assert_eq!(d.complete("A", &[]), none());
    assert_eq!(d.complete("B", &[]), ["dispatch C"]);
    assert_eq!(d.complete("C", &[b("again", true)]), ["dispatch B"]);
    assert_eq!(d.complete("B", &[]), none());
    assert_eq!(joining(&d), 1);
    assert!(!finished(&d));
}

/// s -> IF (inclusive: `x > 0` to A, `x > 1` into the B cycle); A -> J; MB -> B -> XB
/// -(again)-> MB | J; J (inclusive join) -> C -> e.
fn join_after_a_cycle() -> String {
    process(&[
        flow("f0", "s", "IF"),
        or("IF"),
        cond_flow("i1", "IF", "A", "x &gt; 0"),
        cond_flow("i2", "IF", "MB", "x &gt; 1"),
        task("A", "i1", "fa"),
        flow("fa", "A", "J"),
        xor("MB"),
        flow("m1", "MB", "B"),
        task("B", "m1", "b1"),
        flow("b1", "B", "XB"),
        xor_default("XB", "fb"),
        cond_flow("back", "XB", "MB", "again"),
        flow("fb", "XB", "J"),
        or("J"),
        flow("j1", "J", "C"),
        task("C", "j1", "c1"),
        flow("c1", "C", "e"),
        end("e"),
    ])
}

/// §13.4.3: an inclusive join after a cycle waits while the token looping in the cycle can still
/// reach one of its empty incoming flows, however many rounds it takes, and fires as soon as it
/// arrives; without a token in the cycle it does not wait for it.
#[test]
fn an_inclusive_join_after_a_cycle_waits_for_the_looping_token_and_only_for_it() {
    let x = |v| [("x", Value::Int(v))];
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
        flow("f0", "s", "M"),
        xor("M"),
        flow("f1", "M", "IF"),
        or("IF"),
        cond_flow("i1", "IF", "A", "a"),
        cond_flow("i2", "IF", "B", "b"),
        task("A", "i1", "fa"),
        task("B", "i2", "fb"),
        flow("fa", "A", "J"),
        flow("fb", "B", "J"),
        or("J"),
        flow("j1", "J", "X"),
        xor_default("X", "out"),
        cond_flow("back", "X", "M", "again"),
        flow("out", "X", "e"),
        end("e"),
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
    let mut d = Driver::new(&process(&[
        flow("f0", "s", "J"),
        or("J"),
        flow("f1", "J", "A"),
        task("A", "f1", "f2"),
        flow("f2", "A", "X"),
        xor_default("X", "out"),
        cond_flow("back", "X", "J", "again"),
        flow("out", "X", "e"),
        end("e"),
    ]));
    assert_eq!(d.start(&[]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", true)]), ["dispatch A"]);
    assert_eq!(d.complete("A", &[b("again", false)]), ["completed"]);
}

/// s -> IF (inclusive: `x > 0` into the A cycle, `x > 1` to B); MA -> A -> IA (inclusive
/// split: always to J along `fa`, back to MA when `again`); B -> J along `fb`; J (inclusive
/// join) -> C -> e.
fn cycle_feeding_an_inclusive_join() -> String {
    process(&[
        flow("f0", "s", "IF"),
        or("IF"),
        cond_flow("i1", "IF", "MA", "x &gt; 0"),
        cond_flow("i2", "IF", "B", "x &gt; 1"),
        xor("MA"),
        flow("m1", "MA", "A"),
        task("A", "m1", "a1"),
        flow("a1", "A", "IA"),
        or("IA"),
        flow("fa", "IA", "J"),
        cond_flow("back", "IA", "MA", "again"),
        task("B", "i2", "fb"),
        flow("fb", "B", "J"),
        or("J"),
        flow("j1", "J", "C"),
        task("C", "j1", "c1"),
        flow("c1", "C", "e"),
        end("e"),
    ])
}

/// §13.4.3, the activation rule exactly: the join is activated when some incoming flow has a
/// token and every token that can reach an *empty* incoming flow (without passing the join)
/// can also reach an occupied one. A token looping in a cycle that can only come back along an
/// occupied incoming flow belongs to the next activation: the join fires without it (and fires
/// again when it arrives). A token that can reach an empty incoming flow, and only that, is
/// waited for.
#[test]
fn an_inclusive_join_does_not_wait_for_a_looping_token_that_can_only_reach_an_occupied_flow() {
    let x = |v| [("x", Value::Int(v))];
    let mut d = Driver::new(&cycle_feeding_an_inclusive_join());
    assert_eq!(d.start(&x(1)), ["dispatch A"]);
    // A's token reaches the join on `fa`; the next round of A can only come along `fa` again,
    // and nothing can reach `fb`.
    assert_eq!(
        sorted(d.complete("A", &[b("again", true)])),
        ["dispatch A", "dispatch C"]
    );
    assert_eq!(d.complete("A", &[b("again", false)]), ["dispatch C"]);
    for c in keys_of(&d, "C") {
        complete_key(&mut d, c, &[]);
    }
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
        flow("f0", "s", "M"),
        xor("M"),
        flow("f1", "M", "P"),
        and("P"),
        flow("p1", "P", "A"),
        task("A", "p1", "a1"),
        r#"<boundaryEvent id="tb" attachedToRef="A"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition></boundaryEvent>"#.to_owned(),
        flow("t1", "tb", "et"),
        end("et"),
        flow("a1", "A", "J"),
        flow("p2", "P", "S"),
        r#"<subProcess id="S"><startEvent id="ss"/>"#.to_owned(),
        flow("s1", "ss", "B"),
        task("B", "s1", "s2"),
        flow("s2", "B", "se"),
        end("se"),
        "</subProcess>".to_owned(),
        flow("b1", "S", "J"),
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
        xor_default("X", "out"),
        cond_flow("back", "X", "M", "again"),
        flow("out", "X", "e"),
        end("e"),
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
        flow("p1", "P", "Z"),
        task("Z", "p1", "z1"),
        flow("z1", "Z", "e"),
        end("e"),
        flow("p2", "P", "M"),
        xor("M"),
        flow("m1", "M", "N"),
        xor("N"),
        flow("n1", "N", "M"),
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
