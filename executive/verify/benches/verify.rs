//! Verification benchmark: the Europa mission with all its requirements, and scaling as
//! concurrent excavation sub-processes are added (1–4), for Spin (translate, generate, compile,
//! search) and the native engine exploration side by side, in the same run.
//!
//! `cargo bench -p executive-verify --bench verify` (needs `spin` and `gcc`).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use executive_verify::{Atom, Bounds, Limits, Ltl, Translation};

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn load(text: &str) -> executive_model::ProcessGraph {
    executive_model::load(text.as_bytes())
        .graph
        .expect("the benchmark model is valid")
}

/// `r` excavation sub-processes in parallel (dig with a stuck-tool retry and a slump check),
/// and a battery monitor whose abort signal interrupts each of them.
fn rovers(r: usize) -> String {
    let mut body = String::new();
    let mut flows = String::new();
    for i in 1..=r {
        body.push_str(&format!(
            r#"
    <subProcess id="dig{i}" name="Excavation {i}">
      <startEvent id="s{i}"/>
      <task id="approach{i}" name="Approach {i}"/>
      <exclusiveGateway id="retry{i}"/>
      <task id="remove{i}" name="Remove Material {i}"/>
      <boundaryEvent id="stuck{i}" attachedToRef="remove{i}"><errorEventDefinition errorRef="err"/></boundaryEvent>
      <task id="unstick{i}" name="Unstick {i}"/>
      <exclusiveGateway id="slump{i}" default="ok{i}"/>
      <task id="stow{i}" name="Stow {i}"/>
      <endEvent id="e{i}"/>
      <sequenceFlow id="a{i}" sourceRef="s{i}" targetRef="approach{i}"/>
      <sequenceFlow id="b{i}" sourceRef="approach{i}" targetRef="retry{i}"/>
      <sequenceFlow id="c{i}" sourceRef="retry{i}" targetRef="remove{i}"/>
      <sequenceFlow id="d{i}" sourceRef="remove{i}" targetRef="slump{i}"/>
      <sequenceFlow id="again{i}" sourceRef="slump{i}" targetRef="retry{i}"><conditionExpression xsi:type="tFormalExpression">slumped</conditionExpression></sequenceFlow>
      <sequenceFlow id="ok{i}" sourceRef="slump{i}" targetRef="stow{i}"/>
      <sequenceFlow id="u{i}" sourceRef="stuck{i}" targetRef="unstick{i}"/>
      <sequenceFlow id="v{i}" sourceRef="unstick{i}" targetRef="retry{i}"/>
      <sequenceFlow id="w{i}" sourceRef="stow{i}" targetRef="e{i}"/>
    </subProcess>
    <boundaryEvent id="abort{i}" attachedToRef="dig{i}"><signalEventDefinition signalRef="low"/></boundaryEvent>
    <task id="safe{i}" name="Safe {i}"/>"#
        ));
        flows.push_str(&format!(
            r#"
    <sequenceFlow id="f{i}" sourceRef="fork" targetRef="dig{i}"/>
    <sequenceFlow id="g{i}" sourceRef="dig{i}" targetRef="join"/>
    <sequenceFlow id="h{i}" sourceRef="abort{i}" targetRef="safe{i}"/>
    <sequenceFlow id="k{i}" sourceRef="safe{i}" targetRef="join"/>"#
        ));
    }
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" id="d" targetNamespace="urn:bench">
  <error id="err" errorCode="TOOL_STUCK"/>
  <signal id="low" name="BatteryLow"/>
  <process id="rovers" isExecutable="true">
    <startEvent id="start"/>
    <parallelGateway id="fork"/>
    <exclusiveGateway id="join"/>
    <task id="read" name="Read Battery"/>
    <exclusiveGateway id="low_q" default="fine"/>
    <intermediateThrowEvent id="throw"><signalEventDefinition signalRef="low"/></intermediateThrowEvent>
    <endEvent id="monitor_end"/>
    <endEvent id="end"><terminateEventDefinition/></endEvent>{body}
    <sequenceFlow id="f0" sourceRef="start" targetRef="fork"/>
    <sequenceFlow id="m1" sourceRef="fork" targetRef="read"/>
    <sequenceFlow id="m2" sourceRef="read" targetRef="low_q"/>
    <sequenceFlow id="m3" sourceRef="low_q" targetRef="throw"><conditionExpression xsi:type="tFormalExpression">battery_soc_pct &lt; 30.0</conditionExpression></sequenceFlow>
    <sequenceFlow id="fine" sourceRef="low_q" targetRef="monitor_end"/>
    <sequenceFlow id="m4" sourceRef="throw" targetRef="monitor_end"/>
    <sequenceFlow id="j" sourceRef="join" targetRef="end"/>{flows}
  </process>
</definitions>"#
    )
}

struct Run {
    states: u64,
    seconds: f64,
    verdicts: String,
    holding: usize,
    total: usize,
}

/// What Spin is asked on a model: the loop bound, the search limits, the observed atoms and
/// declared variables, and the claims on the translation (built-ins only: none).
struct Ask<'a> {
    bounds: Bounds,
    limits: Limits,
    atoms: &'a [Atom],
    variables: &'a executive_verify::data::Variables,
    claims: &'a dyn Fn(&Translation) -> Vec<Ltl>,
}

/// Spin on `g`: wall time (translate, `spin -a`, the compiles, every pan run), the largest
/// search and the verdicts.
fn spin(g: &executive_model::ProcessGraph, ask: &Ask, dir: &Path) -> Run {
    let t0 = Instant::now();
    let t =
        executive_verify::translate(g, ask.bounds, ask.atoms, ask.variables).expect("translates");
    let checked =
        executive_verify::check(&t, &(ask.claims)(&t), dir, ask.limits).expect("spin runs");
    let seconds = t0.elapsed().as_secs_f64();
    let states = checked
        .properties
        .iter()
        .map(|o| o.states)
        .max()
        .unwrap_or(0);
    let bad: Vec<&str> = checked
        .properties
        .iter()
        .filter(|o| o.verdict != executive_verify::Verdict::Holds)
        .map(|o| o.name.as_str())
        .collect();
    Run {
        states,
        seconds,
        holding: checked.properties.len() - bad.len(),
        total: checked.properties.len(),
        verdicts: if bad.is_empty() {
            format!("all {} hold", checked.properties.len())
        } else {
            format!("not holding: {}", bad.join(", "))
        },
    }
}

fn native(g: executive_model::ProcessGraph) -> Run {
    let t0 = Instant::now();
    let e = executive_verify::explore(Arc::new(g), 5_000_000);
    let seconds = t0.elapsed().as_secs_f64();
    let mut bad = Vec::new();
    if e.deadlock.is_some() {
        bad.push("no_deadlock");
    }
    if e.unsafe_run.is_some() {
        bad.push("safe");
    }
    if !e.dead_activities.is_empty() {
        bad.push("no_dead_activities");
    }
    if !e.complete {
        bad.push("(incomplete)");
    }
    // Of the three built-ins it decides.
    let failed = bad.iter().filter(|b| !b.starts_with('(')).count();
    Run {
        states: e.states as u64,
        seconds,
        holding: 3 - failed,
        total: 3,
        verdicts: if bad.is_empty() {
            "built-ins hold".to_owned()
        } else {
            format!("not holding: {}", bad.join(", "))
        },
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let work = std::env::temp_dir().join(format!("verify-bench-{}", std::process::id()));
    let europa = std::fs::read_to_string(root.join("deploy/missions/europa-bsm1.bpmn"))
        .expect("Europa model");
    let g = load(&europa);
    let loaded = executive_verify::requirements::load(
        &root.join("deploy/missions/europa-bsm1.req.toml"),
        &g,
    )
    .expect("requirements");
    let reqs = loaded.requirements;
    let (atoms, formulas) = executive_verify::requirements::shared_atoms(&reqs);
    let claims = |t: &Translation| executive_verify::requirements::claims(&reqs, &formulas, t);
    let ask = |loops: u8, limits: Limits| Ask {
        bounds: Bounds { loops },
        limits,
        atoms: &atoms,
        variables: &loaded.variables,
        claims: &claims,
    };
    let once = spin(&g, &ask(1, Limits::default()), &work.join("europa"));
    let n = native(load(&europa));
    // The same at the deeper bound (`trace verify --loops 2`): optimised pan, larger hash table.
    let deep = Limits {
        deep: true,
        ..Limits::default()
    };
    let twice = spin(&g, &ask(2, deep), &work.join("europa-loops2"));
    // Time and energy: the timed exploration with the lander's declared costs.
    let costs = {
        let text = std::fs::read_to_string(root.join("deploy/connectors.toml")).expect("routes");
        let config: connector_api::ConnectorsConfig = toml::from_str(&text).expect("routes");
        let lander: connector_api::Catalogue = serde_json::from_str(
            &std::fs::read_to_string(root.join("deploy/catalogues/lander_sim.json"))
                .expect("catalogue"),
        )
        .expect("catalogue");
        let cats: Vec<Option<connector_api::Catalogue>> = config
            .connectors
            .iter()
            .map(|c| (c.server() == lander.server).then(|| lander.clone()))
            .collect();
        let source = executive_verify::resources::Source {
            pool: None,
            config: &config,
            catalogues: &cats,
        };
        executive_verify::resources::costs(&g, &[source]).expect("costs")
    };
    let timed = |loops: u8| {
        let t0 = Instant::now();
        let t = executive_verify::timed::check(
            Arc::new(load(&europa)),
            &costs,
            &reqs,
            executive_verify::timed::TimedLimits {
                loops,
                ..Default::default()
            },
        );
        let held = t
            .properties
            .iter()
            .filter(|o| o.verdict == executive_verify::Verdict::Holds)
            .count();
        (
            t0.elapsed().as_secs_f64(),
            t.states,
            held,
            t.properties.len(),
        )
    };
    let (timed1_s, timed1_states, timed1_held, timed_n) = timed(1);
    let (timed2_s, timed2_states, timed2_held, _) = timed(2);
    println!(
        "Europa BSM-1 with its requirements ({} properties):",
        once.total
    );
    println!(
        "  Spin   {:>6.2} s wall (translate, spin -a, gcc, every pan run), largest search {} states; {} of {} hold",
        once.seconds, once.states, once.holding, once.total
    );
    println!(
        "  native {:>6.2} s, {} states; {}",
        n.seconds, n.states, n.verdicts
    );
    println!(
        "  Spin --loops 2 {:>6.2} s wall, largest search {} states; {} of {} hold",
        twice.seconds, twice.states, twice.holding, twice.total
    );
    println!(
        "  time and energy ({timed_n} requirements): timed exploration {timed1_s:.2} s, {timed1_states} states, {timed1_held} hold; --loops 2 {timed2_s:.2} s, {timed2_states} states, {timed2_held} hold"
    );
    println!("\nScaling: concurrent excavation sub-processes (built-in properties):");
    println!("  R | Spin states | Spin s | native states | native s | Spin/native time");
    for r in 1..=4 {
        let text = rovers(r);
        let built_ins = Ask {
            bounds: Bounds::default(),
            limits: Limits::default(),
            atoms: &[],
            variables: &Default::default(),
            claims: &|_| Vec::new(),
        };
        let s = spin(&load(&text), &built_ins, &work.join(format!("r{r}")));
        let n = native(load(&text));
        println!(
            "  {r} | {:>11} | {:>6.2} | {:>13} | {:>8.2} | {:>6.1}x   (Spin: {}; native: {})",
            s.states,
            s.seconds,
            n.states,
            n.seconds,
            s.seconds / n.seconds.max(1e-6),
            s.verdicts,
            n.verdicts
        );
    }
    let _ = std::fs::remove_dir_all(&work);
}
