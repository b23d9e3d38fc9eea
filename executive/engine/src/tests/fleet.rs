//! One engine per pool (a fleet, `Engine::participant`): message flows into another pool leave
//! the engine numbered, a message from another engine is taken only by its flow's target, once
//! per key, and a fleet of engines ends as the one engine running the whole collaboration does
//! (docs/engine-semantics.md § Message flows between pools, § A fleet).

use super::*;

const REQ_REP: &str = r#"<message id="req" name="request"/><message id="rep" name="report"/>"#;

/// Pool `L` (process `p`): start, send task `st` (request), receive task `rr` (report), end.
/// Pool `S` (process `q`): message start `qs` (request), service task `qa`, message end `qe`
/// (report). Message flows `toS` (`st` → `qs`) and `toL` (`qe` → `rr`).
fn request_report(extra_l: &str) -> String {
    format!(
        r#"{REQ_REP}
<collaboration id="c">
  <participant id="L" name="Lander" processRef="p"/>
  <participant id="S" name="Scout" processRef="q"/>
  <participant id="G" name="Ground"/>
  <messageFlow id="toS" sourceRef="st" targetRef="qs" messageRef="req"/>
  <messageFlow id="toL" sourceRef="qe" targetRef="rr" messageRef="rep"/>
  <messageFlow id="toG" sourceRef="p_end" targetRef="G"/>
</collaboration>
<process id="p" isExecutable="true">
  <startEvent id="ps"/>{}
  <sendTask id="st" messageRef="req"/>
  <receiveTask id="rr" messageRef="rep"/>
  <endEvent id="p_end"><messageEventDefinition messageRef="rep"/></endEvent>{extra_l}
</process>
<process id="q" isExecutable="true">
  <startEvent id="qs"><messageEventDefinition messageRef="req"/></startEvent>{}
  {}
  <endEvent id="qe"><messageEventDefinition messageRef="rep"/></endEvent>
</process>"#,
        path("pf", &["ps", "st", "rr", "p_end"]),
        path("qf", &["qs", "qa", "qe"]),
        task("qa", "", ""),
    )
}

/// The scout's report along flow `toL`, keyed `key`.
fn report(key: &str) -> Event {
    Event::MessageReceived {
        name: "report".into(),
        correlation: None,
        payload: Vars::new(),
        flow: Some("toL".into()),
        key: Some(key.into()),
    }
}

fn pool(body: &str, participant: &str) -> Driver {
    let mut d = Driver::new(body);
    let e = std::mem::replace(&mut d.e, engine(body));
    d.e = e.participant(participant).expect("a pool with a process");
    d
}

/// Steps `d` and returns its raw actions.
fn raw(d: &mut Driver, event: Event) -> Result<Vec<Action>, Rejected> {
    d.seq += 1;
    d.e.step(Input {
        seq: d.seq,
        at: d.now,
        event,
    })
}

/// Starts the lander's process `p` with no variables.
fn start_lander(d: &mut Driver) -> Result<Vec<Action>, Rejected> {
    raw(
        d,
        Event::InstanceStarted {
            process: "p".into(),
            vars: Vars::new(),
            start: None,
        },
    )
}

/// The messages `actions` send to other pools, as the inputs their receivers get.
fn letters(actions: &[Action], mission: &str) -> Vec<(String, Event)> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::SendMessage(m) => match &**m {
                crate::Outgoing {
                    name,
                    payload,
                    to: Some(to),
                    flow: Some(flow),
                    correlation,
                    number: Some(n),
                } => Some((
                    to.clone(),
                    Event::MessageReceived {
                        name: name.clone(),
                        correlation: correlation.clone(),
                        payload: payload.clone(),
                        flow: Some(flow.clone()),
                        key: Some(format!("{mission}.m{n}")),
                    },
                )),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

fn dispatched(actions: &[Action]) -> Vec<TaskKey> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::DispatchTask { task, .. } => Some(*task),
            _ => None,
        })
        .collect()
}

fn outcomes(d: &Driver) -> Vec<(String, Option<Outcome>)> {
    let g = d.e.graph();
    d.e.state()
        .instances
        .values()
        .map(|i| (g.process(i.process).id.clone(), i.outcome.clone()))
        .collect()
}

// A message flow into a pool another engine runs leaves the engine with the pool, the flow,
// and a number; the other pool's process does not start here.
#[test]
fn a_message_flow_into_another_engines_pool_leaves_numbered() {
    let body = request_report("");
    let mut l = pool(&body, "L");
    let out = raw(
        &mut l,
        Event::InstanceStarted {
            process: "p".into(),
            vars: vars(&[("site", Value::Int(7))]),
            start: None,
        },
    )
    .expect("starts");
    let sent = letters(&out, "lander");
    assert_eq!(sent.len(), 1);
    assert_eq!(sent[0].0, "S");
    let Event::MessageReceived {
        flow, key, payload, ..
    } = &sent[0].1
    else {
        unreachable!()
    };
    assert_eq!(flow.as_deref(), Some("toS"));
    assert_eq!(key.as_deref(), Some("lander.m1"));
    assert_eq!(payload.get("site"), Some(&Value::Int(7)));
    assert_eq!(outcomes(&l), [("p".to_owned(), None)]);
    assert_eq!(l.e.state().sent, 1);
}

// The pool is given by id or name; a black box or an unknown name is refused, naming the pools
// that can run; starting the other pool's process is refused.
#[test]
fn a_pool_is_chosen_by_id_or_name_and_only_it_starts() {
    let body = request_report("");
    let by_name = engine(&body).participant("Scout").expect("by name");
    assert_eq!(by_name.remote().values().collect::<Vec<_>>(), ["L"]);
    let Err(e) = engine(&body).participant("G") else {
        panic!("a black box runs nothing")
    };
    assert!(e.contains("black box") && e.contains("`L` (Lander)"), "{e}");
    let Err(e) = engine(&body).participant("Rover") else {
        panic!("no such pool")
    };
    assert!(e.contains("no pool is named `Rover`"), "{e}");
    let mut s = pool(&body, "S");
    let refused = start_lander(&mut s);
    assert!(
        matches!(&refused, Err(Rejected::Unsupported { reason, .. }) if reason.contains("`L`")),
        "{refused:?}"
    );
}

// A message along a flow is taken by that flow's target only, once per key: a resend is
// refused as already delivered and changes nothing; one its target cannot take is refused
// with the target named, and changes nothing.
#[test]
fn a_message_from_another_engine_is_applied_once_and_only_at_its_target() {
    let body = request_report("");
    let mut l = pool(&body, "L");
    let mut s = pool(&body, "S");
    let out = start_lander(&mut l).expect("starts");
    let (_, request) = letters(&out, "lander").remove(0);
    let out = raw(&mut s, request.clone()).expect("the scout starts");
    assert_eq!(dispatched(&out).len(), 1);
    let before = s.e.state().clone();
    assert_eq!(
        raw(&mut s, request),
        Err(Rejected::AlreadyDelivered("lander.m1".into()))
    );
    assert_eq!(s.e.state(), &before);
    // The report's flow ends at the lander's receive task: the scout cannot take it.
    let wrong = report("x.m1");
    let refused = raw(&mut s, wrong);
    assert!(
        matches!(&refused, Err(Rejected::Undeliverable { reason, .. }) if reason.contains("pool `L`")),
        "{refused:?}"
    );
    assert_eq!(s.e.state(), &before);
}

// A message whose target no longer waits (its instance ended) is refused, naming the target,
// and the key is not spent: nothing changed.
#[test]
fn a_message_for_an_ended_instance_is_refused_with_the_reason() {
    let body = request_report("");
    let mut l = pool(&body, "L");
    start_lander(&mut l).expect("starts");
    raw(&mut l, report("scout.m1")).expect("the lander takes its report");
    assert!(matches!(outcomes(&l)[0].1, Some(Outcome::Completed)));
    let refused = raw(&mut l, report("scout.m2"));
    assert!(
        matches!(&refused, Err(Rejected::Undeliverable { reason, .. }) if reason.contains("`rr` does not wait")),
        "{refused:?}"
    );
    assert!(!l.e.state().delivered.contains("scout.m2"));
}

/// Runs the collaboration as a fleet of one engine per pool, carrying every message between
/// them (each delivered twice: the second must be a harmless resend) and completing every
/// task at once; returns each pool's outcomes.
fn fly_fleet(body: &str, pools: &[&str]) -> Vec<Vec<(String, Option<Outcome>)>> {
    let mut engines: Vec<Driver> = pools.iter().map(|p| pool(body, p)).collect();
    let mut queue: Vec<(usize, Event)> = Vec::new();
    let starts: Vec<String> = {
        let g = engines[0].e.graph();
        g.primary_processes()
            .into_iter()
            .map(|p| g.process(p).id.clone())
            .collect()
    };
    for (i, d) in engines.iter().enumerate() {
        for p in &starts {
            let local =
                d.e.graph()
                    .process_by_id(p)
                    .is_some_and(|p| !d.e.remote().contains_key(&p));
            let untriggered =
                d.e.graph()
                    .process_by_id(p)
                    .is_some_and(|p| d.e.starts_untriggered(p));
            if local && untriggered {
                queue.push((
                    i,
                    Event::InstanceStarted {
                        process: p.clone(),
                        vars: Vars::new(),
                        start: None,
                    },
                ));
            }
        }
    }
    let mut guard = 0;
    while let Some((i, event)) = queue.pop() {
        guard += 1;
        assert!(guard < 1000, "the fleet does not settle");
        let Ok(out) = raw(&mut engines[i], event.clone()) else {
            continue;
        };
        if matches!(event, Event::MessageReceived { .. }) {
            assert!(
                matches!(
                    raw(&mut engines[i], event),
                    Err(Rejected::AlreadyDelivered(_))
                ),
                "a resend must be refused as delivered"
            );
        }
        for task in dispatched(&out) {
            queue.push((
                i,
                Event::TaskCompleted {
                    task,
                    output: Vars::new(),
                },
            ));
        }
        for (to, letter) in letters(&out, pools[i]) {
            if let Some(j) = pools.iter().position(|p| *p == to) {
                queue.insert(0, (j, letter));
            }
        }
    }
    engines.iter().map(outcomes).collect()
}

// A fleet of engines, one per pool, ends as the single engine running the whole collaboration:
// the scout's instance and the lander's complete, and nothing else starts.
#[test]
fn a_fleet_of_engines_ends_as_one_engine_running_the_collaboration() {
    let body = request_report("");
    let fleet = fly_fleet(&body, &["L", "S"]);
    let done = |p: &str| (p.to_owned(), Some(Outcome::Completed));
    assert_eq!(fleet, [vec![done("p")], vec![done("q")]]);
    let mut whole = Driver::new(&body);
    let out = whole.start(&[]);
    assert!(out.contains(&"dispatch qa".to_owned()), "{out:?}");
    whole.complete("qa", &[]);
    let mut all = outcomes(&whole);
    all.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(all, [done("p"), done("q")]);
}

/// A message sent out is written to the store's outbox as it always was: its fields beside its
/// type, none nested (the command is boxed in memory only).
#[test]
fn a_sent_message_is_written_as_before() {
    let sent = Action::SendMessage(Box::new(crate::Outgoing {
        name: "site".into(),
        payload: [("x".to_owned(), crate::Value::Int(3))].into(),
        to: Some("rover".into()),
        flow: Some("mf1".into()),
        correlation: None,
        number: Some(2),
    }));
    let json = serde_json::to_string(&sent).expect("serializes");
    assert_eq!(
        json,
        r#"{"type":"send_message","name":"site","payload":{"x":3},"to":"rover","flow":"mf1","number":2}"#
    );
    let back: Action = serde_json::from_str(&json).expect("deserializes");
    assert_eq!(back, sent);
}
