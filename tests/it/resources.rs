//! Time and energy before flight against the lander simulator: the Europa mission flown on the
//! engine with the simulator's own activity model (`elap_sim::Sim`) over many seeds and fault
//! profiles, every step's time and every battery reading checked against the bounds the
//! verifier computes for the path the run took (`executive_verify::timed::follow`); and
//! `trace verify` giving the mission's time and energy requirements verdicts, with a seeded
//! over-budget variant's counterexample drawn by `trace timeline`.

use std::collections::BTreeMap;
use std::process::Command;
use std::sync::Arc;

use elap_sim::{Profile, Script, Sim, World};
use executive_engine::{Action, Engine, Entry, Event, Input, TaskKey, TimerKey, Value, Vars};
use executive_model::{NodeId, ProcessGraph};
use executive_verify::timed::{Bound, Observed, follow};
use mission_tests::{bin, repo};

use crate::protocol::tempdir;

fn europa() -> Arc<ProcessGraph> {
    let bytes = std::fs::read(repo().join("deploy/missions/europa-bsm1.bpmn")).expect("model");
    Arc::new(executive_model::load(&bytes).graph.expect("valid"))
}

fn costs(g: &ProcessGraph) -> executive_verify::resources::Costs {
    let text = std::fs::read_to_string(repo().join("deploy/connectors.toml")).expect("routes");
    let config = executive_runtime::connectors::parse_config(&text).expect("routes parse");
    let lander = elap_sim::catalogue::catalogue();
    let catalogues = executive_runtime::catalogues::served(&config, &[lander]);
    let source = executive_verify::resources::Source {
        pool: None,
        config: &config,
        catalogues: &catalogues,
    };
    executive_verify::resources::costs(g, &[source]).expect("every task costed")
}

/// What is due next in the flight, by mission time.
enum Due {
    Done(TaskKey),
    Timer(TimerKey),
    Answer(TaskKey),
}

/// Flies Europa on the engine with the simulator core, the ground approving every site after
/// `answer_ms`; the run's steps as the verifier names them, and the energy the simulator used.
fn flight(
    g: &Arc<ProcessGraph>,
    seed: u64,
    profile: Profile,
    answer_ms: i64,
) -> (Vec<Observed>, f64) {
    let mut sim = Sim::new(World::new(0, seed), profile, Script::default());
    let mut engine = Engine::new(Arc::clone(g));
    let mut due: BTreeMap<(i64, u64), Due> = BTreeMap::new();
    let mut order = 0u64;
    let mut nodes: BTreeMap<TaskKey, NodeId> = BTreeMap::new();
    let mut observed = Vec::new();
    let mut now = 0i64;
    let mut event = Some(Event::InstanceStarted {
        process: g.process(g.primary_processes()[0]).id.clone(),
        vars: Vars::new(),
        start: None,
    });
    let capacity = sim.world.capacity_wh;
    for _ in 0..200_000 {
        let Some(ev) = event.take() else { break };
        let seq = engine.state().last_seq + 1;
        let actions = engine
            .step(Input {
                seq,
                at: now,
                event: ev,
            })
            .expect("the engine takes the flight's inputs");
        let mut over = false;
        for a in actions {
            order += 1;
            match a {
                Action::DispatchTask {
                    task,
                    node,
                    request,
                } => {
                    nodes.insert(task, node);
                    sim.world.advance(now);
                    let goal = serde_json::to_value(&request)
                        .ok()
                        .and_then(|v| v.as_object().cloned())
                        .unwrap_or_default();
                    let r = sim
                        .begin(
                            &task.to_string(),
                            executive_engine::resource(g, node),
                            &goal,
                            now,
                        )
                        .expect("served");
                    due.insert((now + r.plan.duration_ms, order), Due::Done(task));
                }
                Action::CancelTask { task } => {
                    sim.end(&task.to_string(), true, now);
                    due.retain(|_, d| !matches!(d, Due::Done(k) if *k == task));
                }
                Action::OpenUserTask { task, node, .. } => {
                    nodes.insert(task, node);
                    due.insert((now + answer_ms, order), Due::Answer(task));
                }
                Action::CloseUserTask { task } => {
                    due.retain(|_, d| !matches!(d, Due::Answer(k) if *k == task));
                }
                Action::StartTimer { timer, at } => {
                    due.insert((at.max(now), order), Due::Timer(timer));
                }
                Action::CancelTimer { timer } => {
                    due.retain(|_, d| !matches!(d, Due::Timer(k) if *k == timer));
                }
                Action::Record(r) => {
                    if let Some(o) = step(g, &nodes, &r.entry, r.at as f64, capacity) {
                        observed.push(o);
                    }
                }
                Action::InstanceFinished { .. } => over = true,
                Action::SendMessage(_) => {}
            }
        }
        if over {
            break;
        }
        let Some(((at, _), next)) = due.pop_first() else {
            break;
        };
        now = at;
        event = Some(match next {
            Due::Timer(timer) => Event::TimerFired { timer },
            Due::Answer(task) => Event::UserTaskAnswered {
                task,
                answer: Vars::from([("approve".to_owned(), Value::Bool(true))]),
                operator: "flight".into(),
            },
            Due::Done(task) => match sim.end(&task.to_string(), false, now).map(|e| e.outcome) {
                Some(Ok(fields)) => Event::TaskCompleted {
                    task,
                    output: fields
                        .iter()
                        .map(|(k, v)| (k.clone(), Value::from_json(v)))
                        .collect(),
                },
                Some(Err((code, message))) => Event::TaskFailed {
                    task,
                    code,
                    message,
                },
                None => panic!("the simulator lost goal {task}"),
            },
        });
    }
    sim.world.advance(now);
    (observed, capacity - sim.world.energy_wh)
}

/// A record entry as the verifier names the step, with the energy a battery reading says.
fn step(
    g: &ProcessGraph,
    nodes: &BTreeMap<TaskKey, NodeId>,
    entry: &Entry,
    at: f64,
    capacity: f64,
) -> Option<Observed> {
    let id = |n: NodeId| g.node(n).id.clone();
    let mut data = Vars::new();
    let (label, energy_wh) = match entry {
        Entry::Completed { task, output } => {
            data.clone_from(output);
            let left = output
                .get("battery")
                .and_then(|b| b.at_path("energy_wh"))
                .and_then(|e| match e {
                    Value::Float(x) => Some(x.0),
                    Value::Int(i) => Some(*i as f64),
                    _ => None,
                });
            (
                format!("{}.complete", id(nodes[task])),
                left.map(|l| capacity - l),
            )
        }
        Entry::Answered { task, answer, .. } => {
            data.clone_from(answer);
            (format!("{}.complete", id(nodes[task])), None)
        }
        Entry::Failed { task, code, .. } => (format!("{}.fail[{code}]", id(nodes[task])), None),
        Entry::TimerFired { node, .. } => (format!("{}.fire", id(*node)), None),
        // Decisions: the verifier's engine makes them from the same data.
        _ => return None,
    };
    Some(Observed {
        label,
        output: data,
        at_ms: at,
        energy_wh,
    })
}

#[test]
fn every_simulated_flight_lies_within_the_bounds_the_verifier_computes_for_its_path() {
    let g = europa();
    let costs = costs(&g);
    let mut flights = 0;
    let mut cut = 0;
    let mut reads = 0;
    let mut widths = Vec::new();
    let mut spans = Vec::new();
    for seed in 1..=8u64 {
        for profile in [Profile::Quiet, Profile::Nominal, Profile::Demanding] {
            // The ground answers at once, or after the approval timeout (PT6H) has fired.
            let answer_ms = if seed % 3 == 0 {
                7 * 3_600_000
            } else {
                30 * 60_000
            };
            let (run, used) = flight(&g, seed, profile, answer_ms);
            let bounds: Vec<Bound> = follow(Arc::clone(&g), &costs, &run).unwrap_or_else(|e| {
                let steps: Vec<String> = run
                    .iter()
                    .map(|o| format!("{} @{}", o.label, o.at_ms))
                    .collect();
                panic!(
                    "seed {seed} {profile:?}: the flight leaves the verifier's bounds: {e}\n{}",
                    steps.join("\n")
                )
            });
            // Followed to the end, or to where the battery is certainly empty (the simulator
            // draws on from an empty battery; the verifier ends the run there).
            let whole = bounds.len() == run.len();
            for b in &bounds {
                if let Some(m) = b.measured_wh {
                    // The simulator charges an activity when it ends: a reading taken while one
                    // runs is short of it by at most what it has drawn so far.
                    assert!(
                        b.energy_wh.lo - b.in_flight_wh - 1e-6 <= m && m <= b.energy_wh.hi + 1e-6,
                        "seed {seed} {profile:?}: {} read {m:.1} Wh used, bounds {:.1}..{:.1} \
                         (in flight {:.1})",
                        b.label,
                        b.energy_wh.lo,
                        b.energy_wh.hi,
                        b.in_flight_wh
                    );
                    reads += 1;
                    widths.push(b.energy_wh.hi - b.energy_wh.lo);
                }
            }
            let last = bounds.last().expect("steps");
            if whole {
                assert!(
                    last.energy_wh.lo - 1e-6 <= used && used <= last.energy_wh.hi + 1e-6,
                    "seed {seed} {profile:?}: the flight used {used:.1} Wh, bounds {:?}",
                    last.energy_wh
                );
            } else {
                assert!(
                    used >= 45_000.0 - 1e-6,
                    "seed {seed} {profile:?}: {used} Wh used"
                );
                cut += 1;
            }
            spans.push(last.window_ms.hi - last.window_ms.lo);
            flights += 1;
        }
    }
    let mean = widths.iter().sum::<f64>() / widths.len().max(1) as f64;
    let widest = widths.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "{flights} flights ({cut} followed until their battery was certainly empty), {reads} battery \
         readings inside the bounds; energy bounds {mean:.1} Wh wide on average, {widest:.1} Wh at \
         most; last step's time window {:.0} s wide at most",
        spans.iter().copied().fold(0.0, f64::max) / 1000.0
    );
    assert!(
        flights == 24 && reads > 1000,
        "{flights} flights, {reads} readings"
    );
}

#[test]
fn trace_verify_gives_time_and_energy_verdicts_and_a_counterexample_the_timeline_draws() {
    let dir = tempdir("verify-resources");
    let model = repo().join("deploy/missions/europa-bsm1.bpmn");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&model)
        .arg("--dir")
        .arg(dir.join("work"))
        .output()
        .expect("trace verify runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in [
        "communicates_with_reserve",
        "science_keeps_a_reserve",
        "no_digging_after_day_19",
    ] {
        assert!(
            text.lines()
                .any(|l| l.contains("holds") && l.contains(name)),
            "{name}: {text}"
        );
    }
    assert!(text.contains("timed exploration of the engine"), "{text}");

    // Seeded flaw: the Battery Monitor aborts only below 3 % instead of 30 %.
    let flawed = dir.join("europa-flawed.bpmn");
    let xml = std::fs::read_to_string(&model).expect("model");
    let seeded = xml.replace("battery_soc_pct &lt; 30.0", "battery_soc_pct &lt; 3.0");
    assert_ne!(seeded, xml, "the threshold is where the flaw is seeded");
    std::fs::write(&flawed, seeded).expect("variant");
    std::fs::copy(
        repo().join("deploy/missions/europa-bsm1.req.toml"),
        dir.join("europa-flawed.req.toml"),
    )
    .expect("requirements");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&flawed)
        .arg("--connectors")
        .arg(repo().join("deploy/connectors.toml"))
        .arg("--dir")
        .arg(dir.join("flawed"))
        .output()
        .expect("trace verify runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.lines()
            .any(|l| l.contains("VIOLATED") && l.contains("science_keeps_a_reserve")),
        "{text}"
    );
    let record = dir.join("flawed/science_keeps_a_reserve.counterexample.jsonl");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&record)
        .expect("counterexample record")
        .lines()
        .map(|l| serde_json::from_str(l).expect("record line"))
        .collect();
    // The run ends with science running on less than a quarter of the battery.
    let used = lines
        .iter()
        .rev()
        .find(|v| v["key"] == "energy_used_wh")
        .and_then(|v| v["value"].as_f64())
        .expect("energy along the run");
    assert!(used > 0.75 * 45_000.0, "{used} Wh");
    // Each activity says what it spent.
    assert!(
        lines
            .iter()
            .any(|v| v["kind"] == "completed" && v["energy_wh"].is_array())
    );
    let html = crate::timeline::render(&record, &dir.join("flawed.html"));
    assert!(
        html.contains("energy_used_wh") && html.contains(" Wh"),
        "the page shows energy"
    );
}
