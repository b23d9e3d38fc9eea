//! Property tests: random interleavings of completions, failures, timers, answers, messages,
//! signals, cancellations, stale and duplicated inputs on a model with every kind of wait.

use std::collections::BTreeSet;
use std::sync::Arc;

use proptest::prelude::*;

use crate::{Action, Engine, Event, Input, InstanceId, State, TaskKey, TimerKey, Value, Vars};

const MODEL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL"
  xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0"
  id="defs" targetNamespace="urn:prop">
  <error id="stuck" errorCode="TOOL_STUCK"/>
  <message id="m" name="GO"/>
  <signal id="sig" name="ALERT"/>
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <serviceTask id="a"><extensionElements><trace:task resource="sys.a"/></extensionElements></serviceTask>
    <boundaryEvent id="ta" attachedToRef="a"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1M</timeDuration></timerEventDefinition></boundaryEvent>
    <boundaryEvent id="ea" attachedToRef="a"><errorEventDefinition errorRef="stuck"/></boundaryEvent>
    <serviceTask id="retry"><extensionElements><trace:task resource="sys.retry"/></extensionElements></serviceTask>
    <userTask id="u"><extensionElements><trace:task resource="ground.ok"><trace:output source="ok" target="ok" type="bool"/></trace:task></extensionElements></userTask>
    <exclusiveGateway id="x" default="fx2"/>
    <serviceTask id="c"><extensionElements><trace:task resource="sys.c"/></extensionElements></serviceTask>
    <intermediateCatchEvent id="wait"><messageEventDefinition messageRef="m"/></intermediateCatchEvent>
    <subProcess id="sp">
      <startEvent id="s2"/>
      <serviceTask id="d"><extensionElements><trace:task resource="sys.d"/></extensionElements></serviceTask>
      <endEvent id="e2"/>
      <sequenceFlow id="g1" sourceRef="s2" targetRef="d"/>
      <sequenceFlow id="g2" sourceRef="d" targetRef="e2"/>
    </subProcess>
    <boundaryEvent id="sa" attachedToRef="sp" cancelActivity="false"><signalEventDefinition signalRef="sig"/></boundaryEvent>
    <serviceTask id="alarm"><extensionElements><trace:task resource="sys.alarm"/></extensionElements></serviceTask>
    <parallelGateway id="join"/>
    <endEvent id="e"/>
    <endEvent id="e3"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f1" sourceRef="fork" targetRef="a"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="u"/>
    <sequenceFlow id="f3" sourceRef="fork" targetRef="wait"/>
    <sequenceFlow id="fa" sourceRef="a" targetRef="join"/>
    <sequenceFlow id="fta" sourceRef="ta" targetRef="join"/>
    <sequenceFlow id="fea" sourceRef="ea" targetRef="retry"/>
    <sequenceFlow id="fr" sourceRef="retry" targetRef="join"/>
    <sequenceFlow id="fu" sourceRef="u" targetRef="x"/>
    <sequenceFlow id="fx1" sourceRef="x" targetRef="c"><conditionExpression xsi:type="tFormalExpression">ok</conditionExpression></sequenceFlow>
    <sequenceFlow id="fx2" sourceRef="x" targetRef="join"/>
    <sequenceFlow id="fc" sourceRef="c" targetRef="join"/>
    <sequenceFlow id="fw" sourceRef="wait" targetRef="sp"/>
    <sequenceFlow id="fsp" sourceRef="sp" targetRef="join"/>
    <sequenceFlow id="fsa" sourceRef="sa" targetRef="alarm"/>
    <sequenceFlow id="fal" sourceRef="alarm" targetRef="e3"/>
    <sequenceFlow id="fj" sourceRef="join" targetRef="e"/>
  </process>
</definitions>"#;

#[derive(Clone, Debug)]
enum Op {
    Complete(usize),
    Fail(usize, bool),
    Fire(usize),
    Answer(usize, bool),
    Message,
    Signal,
    Start,
    Cancel(usize),
    Stale(usize),
    Repeat,
    Data(i64),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => any::<usize>().prop_map(Op::Complete),
        2 => (any::<usize>(), any::<bool>()).prop_map(|(i, b)| Op::Fail(i, b)),
        2 => any::<usize>().prop_map(Op::Fire),
        2 => (any::<usize>(), any::<bool>()).prop_map(|(i, b)| Op::Answer(i, b)),
        1 => Just(Op::Message),
        1 => Just(Op::Signal),
        1 => Just(Op::Start),
        1 => any::<usize>().prop_map(Op::Cancel),
        1 => any::<usize>().prop_map(Op::Stale),
        1 => Just(Op::Repeat),
        1 => (-5i64..5).prop_map(Op::Data),
    ]
}

#[derive(Default)]
struct Pending {
    tasks: Vec<TaskKey>,
    done: Vec<TaskKey>,
    user: Vec<TaskKey>,
    timers: Vec<(TimerKey, i64)>,
    instances: Vec<InstanceId>,
    finished: BTreeSet<InstanceId>,
}

impl Pending {
    fn absorb(&mut self, actions: &[Action]) {
        for a in actions {
            match a {
                Action::DispatchTask { task, .. } => self.tasks.push(*task),
                Action::CancelTask { task } => {
                    self.tasks.retain(|k| k != task);
                    self.done.push(*task);
                }
                Action::OpenUserTask { task, .. } => self.user.push(*task),
                Action::CloseUserTask { task } => self.user.retain(|k| k != task),
                Action::StartTimer { timer, at } => self.timers.push((*timer, *at)),
                Action::CancelTimer { timer } => self.timers.retain(|(k, _)| k != timer),
                Action::InstanceFinished { instance, .. } => {
                    self.finished.insert(*instance);
                }
                Action::Record(r) => {
                    if let crate::Entry::InstanceStarted { .. } = r.entry
                        && !self.instances.contains(&r.instance)
                    {
                        self.instances.push(r.instance);
                    }
                }
                Action::SendMessage(_) => {}
            }
        }
    }
}

fn pick<T: Copy>(v: &[T], i: usize) -> Option<T> {
    (!v.is_empty()).then(|| v[i % v.len()])
}

/// Structural invariants of a state: every token's scope exists and counts it, every
/// subscription belongs to something alive, ended instances hold nothing.
fn check_invariants(s: &State) -> Result<(), String> {
    for (id, t) in &s.tokens {
        let sc = s
            .scopes
            .get(&t.scope)
            .ok_or(format!("token {id:?} in a missing scope"))?;
        if sc.instance != t.instance {
            return Err(format!("token {id:?} crosses instances"));
        }
        for w in &t.waits {
            if !s.waits.contains_key(w) {
                return Err(format!("token {id:?} lists a missing wait {w:?}"));
            }
        }
    }
    for (id, sc) in &s.scopes {
        let n = s.tokens.values().filter(|t| t.scope == *id).count();
        if n != sc.tokens.len()
            || sc
                .tokens
                .iter()
                .any(|t| s.tokens.get(t).is_none_or(|t| t.scope != *id))
        {
            return Err(format!(
                "scope {id:?} lists {} tokens, holds {n}",
                sc.tokens.len()
            ));
        }
        if let Some(o) = sc.owner
            && !s.tokens.contains_key(&o)
        {
            return Err(format!("scope {id:?} owned by a missing token"));
        }
    }
    for (id, w) in &s.waits {
        if let Some(t) = w.token
            && !s.tokens.get(&t).is_some_and(|t| t.waits.contains(id))
        {
            return Err(format!("wait {id:?} of a missing token"));
        }
        if !s.scopes.contains_key(&w.scope) {
            return Err(format!("wait {id:?} of a missing scope"));
        }
    }
    for (id, i) in &s.instances {
        if i.outcome.is_some()
            && (s.tokens.values().any(|t| t.instance == *id)
                || s.waits.values().any(|w| w.instance == *id))
        {
            return Err(format!("ended instance {id:?} still holds tokens or waits"));
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// A `TokenSet` answers as the `BTreeSet` it replaced did, after any inserts and removes in
    /// any order, is written as the same JSON, and reads back the same from a list in any order
    /// and with repeats.
    #[test]
    fn a_token_set_behaves_and_is_written_as_a_btree_set(
        ops in prop::collection::vec((any::<bool>(), 0u64..12), 0..40),
        listed in prop::collection::vec(0u64..12, 0..12),
    ) {
        let mut set = crate::TokenSet::default();
        let mut model = BTreeSet::new();
        for (add, id) in ops {
            let t = crate::TokenId(id);
            if add {
                prop_assert_eq!(set.insert(t), model.insert(t));
            } else {
                prop_assert_eq!(set.remove(&t), model.remove(&t));
            }
            prop_assert_eq!(set.len(), model.len());
            prop_assert_eq!(set.is_empty(), model.is_empty());
            prop_assert!(set.iter().eq(model.iter()));
            prop_assert!((0..12).all(|i| set.contains(&crate::TokenId(i)) == model.contains(&crate::TokenId(i))));
        }
        prop_assert_eq!(serde_json::to_string(&set).unwrap(), serde_json::to_string(&model).unwrap());
        let json = serde_json::to_string(&listed).unwrap();
        let read: crate::TokenSet = serde_json::from_str(&json).unwrap();
        let expected: BTreeSet<crate::TokenId> = serde_json::from_str(&json).unwrap();
        prop_assert!(read.iter().eq(expected.iter()));
    }

    #[test]
    fn random_interleavings_keep_every_invariant(ops in prop::collection::vec(op(), 1..60)) {
        let loaded = executive_model::load(MODEL.as_bytes());
        let graph = Arc::new(loaded.graph.unwrap_or_else(|| panic!("{:#?}", loaded.diagnostics)));
        let mut e = Engine::new(Arc::clone(&graph));
        let mut p = Pending::default();
        let mut seq = 0u64;
        let mut now = 0i64;
        let mut accepted: Vec<(Input, Vec<Action>)> = Vec::new();
        let mut last: Option<Input> = None;
        // Every dispatch and user task as the engine gave it, by key.
        let mut given: std::collections::BTreeMap<TaskKey, Action> = Default::default();
        let start = || Event::InstanceStarted { process: "p".into(), vars: Vars::new(), start: None };
        for op in std::iter::once(Op::Start).chain(ops) {
            let event = match op {
                Op::Start => start(),
                Op::Complete(i) => match pick(&p.tasks, i) {
                    Some(task) => Event::TaskCompleted { task, output: Vars::new() },
                    None => continue,
                },
                Op::Fail(i, known) => match pick(&p.tasks, i) {
                    Some(task) => Event::TaskFailed {
                        task,
                        code: if known { "TOOL_STUCK" } else { "UNKNOWN" }.into(),
                        message: String::new(),
                    },
                    None => continue,
                },
                Op::Fire(i) => match pick(&p.timers, i) {
                    Some((timer, at)) => {
                        now = now.max(at);
                        Event::TimerFired { timer }
                    }
                    None => continue,
                },
                Op::Answer(i, good) => match pick(&p.user, i) {
                    Some(task) => Event::UserTaskAnswered {
                        task,
                        answer: [("ok".to_owned(), if good { Value::Bool(true) } else { Value::from("yes") })].into(),
                        operator: "prop".into(),
                    },
                    None => continue,
                },
                Op::Message => Event::MessageReceived { name: "GO".into(), correlation: None, payload: Vars::new(), flow: None, key: None },
                Op::Signal => Event::SignalReceived { name: "ALERT".into() },
                Op::Cancel(i) => match pick(&p.instances, i) {
                    Some(instance) => Event::CancelRequested { instance },
                    None => continue,
                },
                Op::Stale(i) => match pick(&p.done, i) {
                    Some(task) => Event::TaskCompleted { task, output: Vars::new() },
                    None => continue,
                },
                Op::Data(v) => Event::DataChanged { key: "level".into(), value: Value::Int(v) },
                Op::Repeat => match &last {
                    Some(input) => {
                        let before = e.state().clone();
                        prop_assert!(e.step(input.clone()).is_err(), "a repeated input was accepted");
                        prop_assert_eq!(e.state(), &before);
                        continue;
                    }
                    None => continue,
                },
            };
            seq += 1;
            now += 1;
            let input = Input { seq, at: now, event };
            let before = e.state().clone();
            let finished_before = p.finished.clone();
            match e.step(input.clone()) {
                Err(_) => {
                    prop_assert_eq!(e.state(), &before, "a rejected input changed the state");
                    seq -= 1;
                }
                Ok(actions) => {
                    for a in &actions {
                        let inst = match a {
                            Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. } => Some(task.instance),
                            Action::StartTimer { timer, .. } => Some(timer.instance),
                            _ => None,
                        };
                        prop_assert!(inst.is_none_or(|i| !finished_before.contains(&i)), "action after the instance ended: {:?}", a);
                    }
                    for k in p.tasks.iter().chain(p.user.iter()) {
                        if actions.iter().any(|a| matches!(a, Action::InstanceFinished { instance, .. } if *instance == k.instance)) {
                            p.done.push(*k);
                        }
                    }
                    p.absorb(&actions);
                    let finished = p.finished.clone();
                    p.tasks.retain(|k| e.state().tokens.get(&k.token).is_some_and(|t| t.at == crate::At::Task(*k)) && !finished.contains(&k.instance));
                    p.user.retain(|k| e.state().tokens.get(&k.token).is_some_and(|t| t.at == crate::At::UserTask(*k)));
                    p.timers.retain(|(k, _)| e.state().waits.contains_key(&k.wait));
                    for a in &actions {
                        if let Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. } = a {
                            given.insert(*task, a.clone());
                        }
                    }
                    // What a restart would command again is what the engine gave, for every
                    // task still out.
                    let again: Vec<Action> = e.in_flight().into_iter().filter(|a| !matches!(a, Action::StartTimer { .. })).collect();
                    for a in &again {
                        let (Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. }) = a else {
                            prop_assert!(false, "not a command: {:?}", a);
                            continue;
                        };
                        prop_assert_eq!(given.get(task), Some(a), "in flight again, not as given");
                    }
                    for k in p.tasks.iter().chain(&p.user) {
                        prop_assert!(again.iter().any(|a| matches!(a, Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. } if task == k)), "{:?} is out, and not in flight", k);
                    }
                    accepted.push((input.clone(), actions));
                    last = Some(input);
                }
            }
            if let Err(msg) = check_invariants(e.state()) {
                prop_assert!(false, "{}", msg);
            }
        }
        // Replaying the accepted inputs from the start gives the same actions and state.
        let mut replay = Engine::new(graph);
        for (input, actions) in &accepted {
            let again = replay.step(input.clone());
            prop_assert_eq!(again.as_ref(), Ok(actions));
        }
        prop_assert_eq!(replay.state(), e.state());
        // The state survives serialization unchanged.
        let json = serde_json::to_string(e.state()).expect("serializes");
        let back: State = serde_json::from_str(&json).expect("deserializes");
        prop_assert_eq!(&back, e.state());
        prop_assert_eq!(Engine::restore(Arc::clone(replay.graph()), back).in_flight(), e.in_flight());
    }
}
