//! Chapter 13 semantics: message flows between pools, message events, send and receive tasks
//! (§9.3, §10.5.5 MessageEventDefinition, §13.3.3 send and receive tasks, §13.4.4 event-based
//! gateway, §13.5.1-§13.5.3 message start, catch and boundary events; rules in
//! docs/engine-semantics.md).

use super::*;

const PING: &str = r#"<message id="m" name="ping"/>"#;
const MESSAGE: &str = r#"<messageEventDefinition messageRef="m"/>"#;
const RECEIVE_TASK: &str = r#"<receiveTask id="rt" messageRef="m"/>"#;

/// A collaboration: `pools` are (participant id, processRef), `flows` are message flows
/// (source, target).
fn collab(pools: &[(&str, Option<&str>)], flows: &[(&str, &str)]) -> String {
    let mut out = String::from(r#"<collaboration id="c">"#);
    for (id, p) in pools {
        match p {
            Some(p) => out.push_str(&format!(r#"<participant id="{id}" processRef="{p}"/>"#)),
            None => out.push_str(&format!(r#"<participant id="{id}"/>"#)),
        }
    }
    for (i, (s, t)) in flows.iter().enumerate() {
        out.push_str(&format!(
            r#"<messageFlow id="mf{i}" sourceRef="{s}" targetRef="{t}" messageRef="m"/>"#
        ));
    }
    out.push_str("</collaboration>");
    out
}

/// The message `ping`, pool `A` (process `p`, the `sender`) and pool `B` (process `q`, the
/// `receiver`), and one message flow `source` → `target` between them.
fn two_pools(source: &str, target: &str, sender: &str, receiver: &str) -> String {
    format!(
        "{PING}{}{sender}{receiver}",
        collab(&[("A", Some("p")), ("B", Some("q"))], &[(source, target)])
    )
}

/// Process `id`: a start `{id}s` carrying `start` (an event definition, or `""`), sequence
/// flows through `nodes` (declared in `decls`), an end `{id}e`.
fn line(id: &str, start: &str, nodes: &[&str], decls: &str) -> String {
    let (s, e) = (format!("{id}s"), format!("{id}e"));
    let all = [&[s.as_str()], nodes, &[e.as_str()]].concat();
    format!(
        r#"<process id="{id}" isExecutable="true"><startEvent id="{s}">{start}</startEvent>{}{decls}<endEvent id="{e}"/></process>"#,
        path(&format!("{id}f"), &all)
    )
}

/// An intermediate catch event of the message `ping`.
fn catch(id: &str) -> String {
    format!(r#"<intermediateCatchEvent id="{id}">{MESSAGE}</intermediateCatchEvent>"#)
}

/// Process `p`: start, a send task `st` (message `ping`), end.
fn sender_send_task() -> String {
    line("p", "", &["st"], r#"<sendTask id="st" messageRef="m"/>"#)
}

/// Process `p`: start, an intermediate message throw event `mt`, end.
fn sender_throw() -> String {
    let throw = format!(r#"<intermediateThrowEvent id="mt">{MESSAGE}</intermediateThrowEvent>"#);
    line("p", "", &["mt"], &throw)
}

/// Process `q`: start, a receive task `rt` (message `ping`), a service task `qa`, end.
fn receiver_task() -> String {
    line(
        "q",
        "",
        &["rt", "qa"],
        &(RECEIVE_TASK.to_owned() + &task("qa", "", "")),
    )
}

/// Process `q`: a start `qs` carrying `start`, a service task `qa`, end.
fn receiver_start(start: &str) -> String {
    line("q", start, &["qa"], &task("qa", "", ""))
}

fn start_process(d: &mut Driver, process: &str, v: &[(&str, Value)]) -> Vec<String> {
    d.step(Event::InstanceStarted {
        process: process.into(),
        vars: vars(v),
        start: None,
    })
    .expect("starts")
}

/// Every instance in start order: (process id, finished?).
fn instances(d: &Driver) -> Vec<(String, bool)> {
    let g = d.e.graph();
    d.e.state()
        .instances
        .values()
        .map(|i| (g.process(i.process).id.clone(), i.outcome.is_some()))
        .collect()
}

/// A variable of the root scope of the `n`th instance (start order).
fn root_var(d: &Driver, n: usize, name: &str) -> Option<Value> {
    let s = d.e.state();
    let root = s.instances.values().nth(n)?.root?;
    s.scopes.get(&root)?.vars.get(name).cloned()
}

fn running(v: &[(&str, bool)]) -> Vec<(String, bool)> {
    v.iter().map(|(p, f)| ((*p).to_owned(), *f)).collect()
}

// §13.3.3: a send task sends its message and completes; a receive task waits for it and
// completes when it arrives; §9.3: the message flow says where it goes. The sender's data
// travels as the payload and lands in the receiving instance.
#[test]
fn send_task_along_message_flow_completes_the_waiting_receive_task() {
    let mut d = Driver::new(&two_pools(
        "st",
        "rt",
        &sender_send_task(),
        &receiver_task(),
    ));
    assert_eq!(start_process(&mut d, "q", &[]), Vec::<String>::new());
    let out = d.start(&[("x", Value::Int(5))]);
    assert_eq!(out, ["dispatch qa", "completed"]);
    assert_eq!(running(&[("q", false), ("p", true)]), instances(&d));
    assert_eq!(root_var(&d, 0, "x"), Some(Value::Int(5)));
    assert_eq!(d.complete("qa", &[]), ["completed"]);
}

// §13.5.1, §10.5.2: a message start event starts a new instance each time its message arrives;
// the message flow from the throw event of the other pool delivers it; nothing leaves the engine.
#[test]
fn message_throw_along_flow_to_message_start_event_starts_the_other_pool() {
    let mut d = Driver::new(&two_pools(
        "mt",
        "qs",
        &sender_throw(),
        &receiver_start(MESSAGE),
    ));
    // The sender's token ends before the new instance's first token reaches its task.
    assert_eq!(
        d.start(&[("x", Value::Int(1))]),
        ["completed", "dispatch qa"]
    );
    // Each message starts one more instance.
    assert_eq!(
        d.start(&[("x", Value::Int(2))]),
        ["completed", "dispatch qa"]
    );
    assert_eq!(
        instances(&d),
        running(&[("p", true), ("q", false), ("p", true), ("q", false)])
    );
    assert_eq!(root_var(&d, 1, "x"), Some(Value::Int(1)));
    assert_eq!(root_var(&d, 3, "x"), Some(Value::Int(2)));
}

// §10.5.3, §13.5.6: a message end event sends its message, then the token ends; an
// intermediate message catch event (§13.5.2) waiting at the other end of the flow passes.
#[test]
fn message_end_event_along_flow_releases_an_intermediate_catch_event() {
    let sender = format!(
        r#"<process id="p" isExecutable="true"><startEvent id="s"/>{}<endEvent id="me">{MESSAGE}</endEvent></process>"#,
        flow("f0", "s", "me"),
    );
    let receiver = line("q", "", &["qc"], &catch("qc"));
    let mut d = Driver::new(&two_pools("me", "qc", &sender, &receiver));
    assert_eq!(start_process(&mut d, "q", &[]), Vec::<String>::new());
    assert_eq!(d.start(&[]), ["completed", "completed"]);
    assert_eq!(instances(&d), running(&[("q", true), ("p", true)]));
}

// §9.3: a message flow to a black-box pool (a participant without a process) leaves the
// engine: the driver delivers it (`SendMessage`).
#[test]
fn message_flow_to_a_black_box_pool_leaves_the_engine() {
    let mut d = Driver::new(&format!(
        "{PING}{}{}",
        collab(&[("A", Some("p")), ("Ground", None)], &[("mt", "Ground")]),
        sender_throw(),
    ));
    assert_eq!(d.start(&[]), ["send ping", "completed"]);
}

// §9.3: the message flow names the receiver. A catcher of the same message in a process the
// flow does not point at must not take it: the message goes to the black-box pool drawn.
#[test]
fn message_flow_to_a_black_box_pool_is_not_taken_by_an_unconnected_catcher_of_the_same_name() {
    let mut d = Driver::new(&format!(
        "{PING}{}{}{}",
        collab(
            &[("A", Some("p")), ("Ground", None), ("R", Some("r"))],
            &[("mt", "Ground")]
        ),
        sender_throw(),
        line("r", "", &["rc"], &catch("rc")),
    ));
    assert_eq!(start_process(&mut d, "r", &[]), Vec::<String>::new());
    assert_eq!(d.start(&[]), ["send ping", "completed"]);
    assert_eq!(instances(&d), running(&[("r", false), ("p", true)]));
}

// §9.3, §13.5.1: a message flow to the pool of an executable process delivers the message to
// that process: its message start event for that message starts a new instance there.
#[test]
fn message_flow_to_a_pool_starts_its_process_at_the_message_start_event() {
    let mut d = Driver::new(&two_pools(
        "mt",
        "B",
        &sender_throw(),
        &receiver_start(MESSAGE),
    ));
    assert_eq!(d.start(&[]), ["completed", "dispatch qa"]);
    assert_eq!(instances(&d), running(&[("p", true), ("q", false)]));
}

// A message flow to the pool of a process with a none start event starts an instance there
// (the pool is drawn as the receiver; TRACE starts it as `InstanceStarted` would).
#[test]
fn message_flow_to_a_pool_with_a_none_start_starts_an_instance() {
    let mut d = Driver::new(&two_pools("mt", "B", &sender_throw(), &receiver_start("")));
    assert_eq!(
        d.start(&[("x", Value::Int(3))]),
        ["completed", "dispatch qa"]
    );
    assert_eq!(root_var(&d, 1, "x"), Some(Value::Int(3)));
}

// §13.5.2 ("waiting starts when the intermediate event is reached"), §13.3.3: a message that
// arrives before its receiver waits is not kept for it. TRACE sends it out of the engine (no
// internal catcher took it) and the receiver, reached later, keeps waiting. (Camunda 7 fails
// the correlation; Camunda 8 buffers a published message for its time to live.)
#[test]
fn message_sent_before_the_receiver_waits_is_not_kept_for_it() {
    let mut d = Driver::new(&two_pools(
        "st",
        "rt",
        &sender_send_task(),
        &receiver_task(),
    ));
    assert_eq!(d.start(&[]), ["send ping", "completed"]);
    assert_eq!(start_process(&mut d, "q", &[]), Vec::<String>::new());
    assert_eq!(instances(&d), running(&[("p", true), ("q", false)]));
    // It still waits: the next message releases it.
    assert_eq!(d.start(&[]), ["dispatch qa", "completed"]);
}

/// How many tokens wait at node `id`.
fn waiting_at(d: &Driver, id: &str) -> usize {
    let g = d.e.graph();
    d.e.state()
        .tokens
        .values()
        .filter(|t| g.node(t.node).id == id)
        .count()
}

// §13.3.3: a message matches at most one receiver (key-based correlation: one process
// instance). Without a correlation key TRACE gives it to the oldest waiting instance; the next
// message goes to the next one. (Camunda 7 `correlate` refuses a message two executions match.)
#[test]
fn one_message_releases_exactly_one_of_two_waiting_instances_oldest_first() {
    let mut d = Driver::new(&two_pools(
        "st",
        "rt",
        &sender_send_task(),
        &receiver_task(),
    ));
    start_process(&mut d, "q", &[("who", Value::from("first"))]);
    start_process(&mut d, "q", &[("who", Value::from("second"))]);
    assert_eq!(d.start(&[]), ["dispatch qa", "completed"]);
    assert_eq!(
        instances(&d),
        running(&[("q", false), ("q", false), ("p", true)])
    );
    // The first receiver moved on (its task is out), the second still waits at `rt`.
    assert_eq!(waiting_at(&d, "rt"), 1);
    assert_eq!(d.start(&[]), ["dispatch qa", "completed"]);
}

/// Process `q` waiting at a receive task whose message correlates on `orderId`.
fn correlated_receiver() -> String {
    format!(
        r#"<message id="m" name="ping"><extensionElements><zeebe:subscription xmlns:zeebe="http://camunda.org/schema/zeebe/1.0" correlationKey="=orderId"/></extensionElements></message>{}"#,
        receiver_task()
    )
}

/// Two instances of `correlated_receiver`, waiting for order 1 and order 2.
fn two_orders_waiting(d: &mut Driver) {
    start_process(d, "q", &[("orderId", Value::Int(1))]);
    start_process(d, "q", &[("orderId", Value::Int(2))]);
}

// §13.3.3, §8.3.2 (key-based correlation): a message from outside with a correlation value goes
// to the instance whose key evaluates to it, whatever the order the instances wait in.
#[test]
fn external_message_goes_to_the_instance_whose_correlation_key_matches() {
    let mut d = Driver::new(&correlated_receiver());
    two_orders_waiting(&mut d);
    let out = d.message("ping", Some(Value::Int(2)), &[("paid", Value::Bool(true))]);
    assert_eq!(out.expect("accepted"), ["dispatch qa"]);
    assert_eq!(root_var(&d, 1, "paid"), Some(Value::Bool(true)));
    assert_eq!(root_var(&d, 0, "paid"), None);
    let out = d.message("ping", Some(Value::Int(1)), &[]);
    assert_eq!(out.expect("accepted"), ["dispatch qa"]);
}

// §13.3.3 key-based correlation applies to messages between pools too: the message carries the
// sender's value of the correlation key, and only the receiver with the same value takes it.
#[test]
fn message_between_pools_goes_to_the_receiver_whose_correlation_key_matches_the_sender() {
    let mut d = Driver::new(&format!(
        "{}{}{}",
        collab(&[("A", Some("p")), ("B", Some("q"))], &[("st", "rt")]),
        sender_send_task(),
        correlated_receiver(),
    ));
    two_orders_waiting(&mut d);
    assert_eq!(
        d.start(&[("orderId", Value::Int(2))]),
        ["dispatch qa", "completed"]
    );
    let s = d.e.state();
    let waiting: Vec<Option<Value>> = s
        .tokens
        .values()
        .filter(|t| d.e.graph().node(t.node).id == "rt")
        .map(|t| s.scopes[&t.scope].vars.get("orderId").cloned())
        .collect();
    assert_eq!(waiting, [Some(Value::Int(1))]);
}

// A message from outside that nothing waits for and that starts nothing is refused, and the
// state is unchanged (Camunda 7 likewise refuses a message no execution matches).
#[test]
fn external_message_nobody_waits_for_is_refused() {
    let mut d = Driver::new(&format!("{PING}{}", receiver_task()));
    let before = d.e.state().clone();
    let r = d.message("ping", None, &[]);
    assert!(
        matches!(&r, Err(Rejected::NoReceiver(n)) if n == "ping"),
        "{r:?}"
    );
    assert_eq!(d.e.state(), &before);
}

// §13.3.3: the correlation decides. A message whose correlation value no waiting instance has
// reaches none of them (the spec does not say how the sender learns it; TRACE accepts the input
// and drops the message, where a message nobody waits for at all is refused).
#[test]
fn external_message_whose_correlation_matches_no_instance_reaches_none() {
    let mut d = Driver::new(&correlated_receiver());
    start_process(&mut d, "q", &[("orderId", Value::Int(1))]);
    let before = d.e.state().clone();
    let r = d.message("ping", Some(Value::Int(9)), &[("paid", Value::Bool(true))]);
    assert!(
        matches!(&r, Ok(out) if out.is_empty()) || matches!(&r, Err(Rejected::NoReceiver(_))),
        "{r:?}"
    );
    assert_eq!(d.e.state().tokens, before.tokens);
    assert_eq!(d.e.state().waits, before.waits);
    assert_eq!(root_var(&d, 0, "paid"), None);
}

// §13.5.1: a message from outside to a message start event starts an instance with the payload;
// a receive task with `instantiate="true"` and no incoming flow (§13.3.3) does the same and
// completes at once.
#[test]
fn external_message_starts_instances_at_message_start_and_instantiating_receive_task() {
    let mut d = Driver::new(&format!("{PING}{}", receiver_start(MESSAGE)));
    let out = d.message("ping", None, &[("site", Value::Int(4))]);
    assert_eq!(out.expect("accepted"), ["dispatch qa"]);
    assert_eq!(root_var(&d, 0, "site"), Some(Value::Int(4)));

    let body = format!(
        r#"{PING}<process id="q" isExecutable="true"><receiveTask id="rt" messageRef="m" instantiate="true"/>{}{}<endEvent id="qe"/></process>"#,
        path("g", &["rt", "qa", "qe"]),
        task("qa", "", ""),
    );
    let mut d = Driver::new(&body);
    let out = d.message("ping", None, &[]);
    assert_eq!(out.expect("accepted"), ["dispatch qa"]);
    assert_eq!(d.complete("qa", &[]), ["completed"]);
}

// §13.4.4: an event-based gateway waits for the first of its events; a message delivered along a
// message flow to one branch's catch event takes that branch and withdraws the others (the
// timer is cancelled).
#[test]
fn message_along_flow_wins_an_event_based_gateway_and_withdraws_the_timer() {
    let receiver = format!(
        r#"<process id="q" isExecutable="true"><startEvent id="qs"/>{}<eventBasedGateway id="gw"/>{}{}
        <intermediateCatchEvent id="qt">{}</intermediateCatchEvent>{}{}<endEvent id="qe"/></process>"#,
        flow("g0", "qs", "gw"),
        path("ga", &["gw", "qc", "qa", "qe"]),
        catch("qc"),
        duration("PT1H"),
        path("gb", &["gw", "qt", "qb", "qe"]),
        tasks(&["qa", "qb"]),
    );
    let mut d = Driver::new(&two_pools("mt", "qc", &sender_throw(), &receiver));
    assert_eq!(start_process(&mut d, "q", &[]), ["timer 3600000"]);
    assert_eq!(d.start(&[]), ["untimer", "dispatch qa", "completed"]);
    // The withdrawn timer can no longer fire.
    let r = d.try_fire(0);
    assert!(matches!(r, Err(Rejected::UnknownTimer(_))), "{r:?}");
}

/// Process `q`: a sub-process `sp` (start, task `qa`, end) with a message boundary `mb`
/// (`interrupting`), followed by task `qz`; the boundary leads to task `qh`.
fn receiver_sub_process(interrupting: bool) -> String {
    format!(
        r#"<process id="q" isExecutable="true"><startEvent id="qs"/>{}
        <subProcess id="sp"><startEvent id="ss"/>{}{}<endEvent id="se"/></subProcess>
        <boundaryEvent id="mb" attachedToRef="sp" cancelActivity="{interrupting}">{MESSAGE}</boundaryEvent>
        {}{}{}<endEvent id="qe"/></process>"#,
        path("g", &["qs", "sp", "qz", "qe"]),
        path("h", &["ss", "qa", "se"]),
        task("qa", "", ""),
        path("b", &["mb", "qh", "qe"]),
        task("qz", "", ""),
        task("qh", "", ""),
    )
}

// §13.5.3: an interrupting message boundary event on a sub-process consumes the message,
// cancels the sub-process (its running task is cancelled) and follows the boundary's flow; the
// sub-process's normal outgoing flow is not taken.
#[test]
fn message_along_flow_to_an_interrupting_boundary_cancels_the_sub_process() {
    let mut d = Driver::new(&two_pools(
        "mt",
        "mb",
        &sender_throw(),
        &receiver_sub_process(true),
    ));
    assert_eq!(start_process(&mut d, "q", &[]), ["dispatch qa"]);
    assert_eq!(d.start(&[]), ["cancel qa", "completed", "dispatch qh"]);
    assert_eq!(d.complete("qh", &[]), ["completed"]);
}

// §13.5.3: a non-interrupting message boundary leaves the sub-process running and starts the
// boundary's path beside it, at each message while the sub-process is active; once the
// sub-process has completed the boundary no longer listens.
#[test]
fn message_to_a_non_interrupting_boundary_runs_beside_the_sub_process_each_time() {
    let mut d = Driver::new(&two_pools(
        "mt",
        "mb",
        &sender_throw(),
        &receiver_sub_process(false),
    ));
    assert_eq!(start_process(&mut d, "q", &[]), ["dispatch qa"]);
    assert_eq!(d.start(&[]), ["completed", "dispatch qh"]);
    assert_eq!(d.start(&[]), ["completed", "dispatch qh"]);
    assert_eq!(d.complete("qa", &[]), ["dispatch qz"]);
    // The boundary's subscription ended with the sub-process: the next message finds no one.
    assert_eq!(d.start(&[]), ["send ping", "completed"]);
    d.complete_every("qh");
    assert_eq!(d.complete("qz", &[]), ["completed"]);
}

// §13.5.3 with correlation by name from outside: the boundary of the sub-process takes a
// message received from outside too.
#[test]
fn external_message_interrupts_a_sub_process_through_its_boundary() {
    let mut d = Driver::new(&format!("{PING}{}", receiver_sub_process(true)));
    assert_eq!(start_process(&mut d, "q", &[]), ["dispatch qa"]);
    let out = d.message("ping", None, &[("why", Value::from("abort"))]);
    assert_eq!(out.expect("accepted"), ["cancel qa", "dispatch qh"]);
    assert_eq!(root_var(&d, 0, "why"), Some(Value::from("abort")));
}

// §13.3.3, §13.5.1: a message from outside goes to an instance waiting for it before it starts a
// new one at a message start event of the same message (the spec does not order the two;
// Camunda 7's correlation likewise looks for a waiting execution before a message start event).
#[test]
fn external_message_goes_to_a_waiting_instance_before_starting_a_new_one() {
    let mut d = Driver::new(&format!(
        "{PING}{}{}",
        line("q", "", &["rt"], RECEIVE_TASK),
        line("r", MESSAGE, &["ra"], &task("ra", "", "")),
    ));
    start_process(&mut d, "q", &[]);
    let out = d.message("ping", None, &[]);
    assert_eq!(out.expect("accepted"), ["completed"]);
    // Nobody waits now: the next one starts `r`.
    let out = d.message("ping", None, &[]);
    assert_eq!(out.expect("accepted"), ["dispatch ra"]);
}

// §13.3.3: "the Message is sent and the Send Task completes". A send task run by a connector
// (a `trace:task` binding) sends when its work is done: the receiver its message flow points
// at gets the message when the connector reports completion.
#[test]
fn send_task_run_by_a_connector_delivers_along_its_message_flow_when_it_completes() {
    let sender = line(
        "p",
        "",
        &["st"],
        r#"<sendTask id="st" messageRef="m"><extensionElements><trace:task resource="radio.send"/></extensionElements></sendTask>"#,
    );
    let mut d = Driver::new(&two_pools("st", "rt", &sender, &receiver_task()));
    start_process(&mut d, "q", &[]);
    assert_eq!(d.start(&[]), ["dispatch st"]);
    let out = d.complete("st", &[]);
    assert!(out.contains(&"dispatch qa".to_owned()), "{out:?}");
}

// docs/engine-semantics.md, "A task a message flow reaches, in the token game": in a player's
// token game a task that a message flow reaches waits for the message, as
// bpmn-js-token-simulation plays it; held by the player, it waits for the player instead and a
// message that comes meanwhile is lost; model exploration runs it as a mission does.
#[test]
fn in_a_players_token_game_a_task_a_message_flow_reaches_waits_for_its_message() {
    let receiver = line("q", "", &["qt"], r#"<task id="qt"/>"#);
    let model = two_pools("st", "qt", &sender_send_task(), &receiver);
    // Played: q waits at its task until p's send task sends.
    let mut d = Driver::new(&model);
    d.e.game();
    assert_eq!(start_process(&mut d, "q", &[]), Vec::<String>::new());
    assert_eq!(instances(&d), running(&[("q", false)]));
    d.start(&[]);
    assert_eq!(instances(&d), running(&[("q", true), ("p", true)]));
    // Held by the player: the message is lost, and the task waits for the player.
    let mut d = Driver::new(&model);
    let qt = d.e.graph().node_by_id("qt").expect("qt");
    d.e.game().hold.insert(qt);
    assert_eq!(start_process(&mut d, "q", &[]), ["dispatch qt"]);
    d.start(&[]);
    assert_eq!(instances(&d), running(&[("q", false), ("p", true)]));
    assert_eq!(d.complete("qt", &[]), ["completed"]);
    // Explored: the task completes at once, as a mission runs it.
    let mut d = Driver::new(&model);
    d.e.game().decide = true;
    assert_eq!(start_process(&mut d, "q", &[]), ["completed"]);
}
