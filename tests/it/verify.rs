//! `trace verify` with the real Spin: per construct, a small model with a known flaw (deadlock,
//! dead activity, unsafe merge, lost signal) and its fixed version get exactly the expected
//! verdicts and readable BPMN counterexamples; a flaw seeded into Europa is found (Europa itself
//! verifies in the README's tour, `tour.rs`).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

use mission_tests::{bin, repo};
use serde_json::Value;

use crate::protocol::tempdir;

const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" id="d" targetNamespace="urn:verify">"#;

fn model(body: &str) -> String {
    format!("{HEAD}\n{body}\n</definitions>")
}

/// An exclusive choice between two tasks, then `join` (a parallel join deadlocks; an exclusive
/// merge is the fix).
fn choice(join: &str) -> String {
    model(&format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <exclusiveGateway id="choose" name="Choose tool" default="f3"/>
    <task id="a" name="Drill"/>
    <task id="b" name="Scoop"/>
    <{join} id="join" name="Tool done"/>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="choose"/>
    <sequenceFlow id="f2" sourceRef="choose" targetRef="a"><conditionExpression xsi:type="tFormalExpression">hard</conditionExpression></sequenceFlow>
    <sequenceFlow id="f3" sourceRef="choose" targetRef="b"/>
    <sequenceFlow id="f4" sourceRef="a" targetRef="join"/>
    <sequenceFlow id="f5" sourceRef="b" targetRef="join"/>
    <sequenceFlow id="f6" sourceRef="join" targetRef="e"/>
  </process>"#
    ))
}

/// Two parallel branches merged by `join`, then one task (an exclusive merge is unsafe; a
/// parallel join is the fix).
fn branches(join: &str) -> String {
    model(&format!(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <task id="a" name="Image"/>
    <task id="b" name="Sound"/>
    <{join} id="merge" name="Merge"/>
    <task id="c" name="Downlink"/>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="a"/>
    <sequenceFlow id="f3" sourceRef="fork" targetRef="b"/>
    <sequenceFlow id="f4" sourceRef="a" targetRef="merge"/>
    <sequenceFlow id="f5" sourceRef="b" targetRef="merge"/>
    <sequenceFlow id="f6" sourceRef="merge" targetRef="c"/>
    <sequenceFlow id="f7" sourceRef="c" targetRef="e"/>
  </process>"#
    ))
}

/// A sub-process whose error boundary leads to Free Tool; inside, `task` (a script task cannot
/// fail, so Free Tool is dead; a task the lander runs can).
fn fault(script: bool) -> String {
    let task = if script {
        r#"<scriptTask id="t" name="Dig" scriptFormat="cel"><script>dug = true</script></scriptTask>"#
    } else {
        r#"<task id="t" name="Dig"/>"#
    };
    model(&format!(
        r#"<error id="err" errorCode="TOOL_STUCK"/>
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <subProcess id="sp" name="Excavate">
      <startEvent id="ss"/>
      {task}
      <endEvent id="se"/>
      <sequenceFlow id="g1" sourceRef="ss" targetRef="t"/>
      <sequenceFlow id="g2" sourceRef="t" targetRef="se"/>
    </subProcess>
    <boundaryEvent id="stuck" name="Tool stuck" attachedToRef="sp"><errorEventDefinition errorRef="err"/></boundaryEvent>
    <task id="h" name="Free Tool"/>
    <endEvent id="e1"/>
    <endEvent id="e2"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="sp"/>
    <sequenceFlow id="f2" sourceRef="sp" targetRef="e1"/>
    <sequenceFlow id="f3" sourceRef="stuck" targetRef="h"/>
    <sequenceFlow id="f4" sourceRef="h" targetRef="e2"/>
  </process>"#
    ))
}

/// A battery monitor aborting the excavation: by a signal thrown from a parallel branch once the
/// battery is read (lost when that comes before the arm is deployed and the excavation
/// listens), or by a level-triggered conditional boundary.
fn abort(by_signal: bool) -> String {
    let (decl, monitor, boundary) = if by_signal {
        (
            r#"<signal id="sig" name="BatteryLow"/>"#,
            r#"<intermediateThrowEvent id="throw" name="Battery low"><signalEventDefinition signalRef="sig"/></intermediateThrowEvent>
    <endEvent id="me"/>
    <task id="read" name="Read battery"/>
    <sequenceFlow id="m0" sourceRef="fork" targetRef="read"/>
    <sequenceFlow id="m1" sourceRef="read" targetRef="throw"/>
    <sequenceFlow id="m2" sourceRef="throw" targetRef="me"/>"#,
            r#"<signalEventDefinition signalRef="sig"/>"#,
        )
    } else {
        (
            "",
            "",
            r#"<conditionalEventDefinition><condition xsi:type="tFormalExpression">battery_soc_pct &lt; 30.0</condition></conditionalEventDefinition>"#,
        )
    };
    let (gateway, entry) = if by_signal {
        (
            r#"<parallelGateway id="fork"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="deploy"/>
    <task id="deploy" name="Deploy arm"/>
    <sequenceFlow id="fd" sourceRef="deploy" targetRef="sp"/>"#,
            "",
        )
    } else {
        (
            "",
            r#"<sequenceFlow id="f1" sourceRef="s" targetRef="sp"/>"#,
        )
    };
    model(&format!(
        r#"{decl}
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    {gateway}
    <subProcess id="sp" name="Excavate">
      <startEvent id="ss"/>
      <task id="dig" name="Dig"/>
      <endEvent id="se"/>
      <sequenceFlow id="g1" sourceRef="ss" targetRef="dig"/>
      <sequenceFlow id="g2" sourceRef="dig" targetRef="se"/>
    </subProcess>
    <boundaryEvent id="abort" name="Abort" attachedToRef="sp">{boundary}</boundaryEvent>
    <task id="home" name="Stow Arm"/>
    <endEvent id="e1"/>
    <endEvent id="e2"/>
    {monitor}
    {entry}
    <sequenceFlow id="f3" sourceRef="sp" targetRef="e1"/>
    <sequenceFlow id="f4" sourceRef="abort" targetRef="home"/>
    <sequenceFlow id="f5" sourceRef="home" targetRef="e2"/>
  </process>"#
    ))
}

/// `trace verify --json` on `text`; the exit code and each property's report by name.
fn verify(name: &str, text: &str) -> (i32, BTreeMap<String, Value>) {
    let (code, props, _) = verify_in(name, text);
    (code, props)
}

/// As [`verify`], also with the work directory the report names (the default one: outside the
/// model's folder, which is left holding only the model).
fn verify_in(name: &str, text: &str) -> (i32, BTreeMap<String, Value>, PathBuf) {
    let dir = tempdir(&format!("verify-{name}"));
    let file = dir.join(format!("{name}.bpmn"));
    std::fs::write(&file, text).expect("model");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&file)
        .arg("--json")
        .output()
        .expect("trace verify runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let report: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| {
        panic!(
            "{name}: {e}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let props = report["properties"]
        .as_array()
        .expect("properties")
        .iter()
        .map(|p| (p["name"].as_str().expect("name").to_owned(), p.clone()))
        .collect();
    let work = PathBuf::from(report["dir"].as_str().expect("the work directory"));
    assert!(
        !work.starts_with(&dir),
        "{name}: the work files go outside the model's folder, not to {}",
        work.display()
    );
    let beside: Vec<_> = std::fs::read_dir(&dir)
        .expect("model folder")
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(
        beside,
        [std::ffi::OsString::from(format!("{name}.bpmn"))],
        "{name}: nothing is written beside the model"
    );
    (out.status.code().unwrap_or(-1), props, work)
}

fn verdicts(props: &BTreeMap<String, Value>) -> BTreeMap<&str, &str> {
    props
        .iter()
        .map(|(k, v)| (k.as_str(), v["verdict"].as_str().unwrap_or("?")))
        .collect()
}

/// The counterexample as `element.phase` steps.
fn steps(p: &Value) -> Vec<String> {
    p["counterexample"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|s| match s["step"].as_object() {
            Some(st) => format!(
                "{}.{}",
                st["element"].as_str().unwrap_or("?"),
                st["phase"].as_str().unwrap_or("?")
            ),
            None => s["marker"].as_str().unwrap_or("?").to_owned(),
        })
        .collect()
}

fn all_hold(name: &str, text: &str, expected: &[&str]) {
    let (code, props) = verify(name, text);
    let v = verdicts(&props);
    assert_eq!(
        v.keys().copied().collect::<Vec<_>>(),
        expected,
        "{props:#?}"
    );
    assert!(v.values().all(|v| *v == "holds"), "{name}: {v:?}");
    assert_eq!(code, 0);
}

const BUILT_IN: [&str; 4] = ["completes", "no_dead_activities", "no_deadlock", "safe"];

#[test]
fn a_deadlock_is_found_with_its_path_and_the_fix_holds() {
    let (code, props) = verify("deadlock", &choice("parallelGateway"));
    assert_eq!(code, 1);
    let v = verdicts(&props);
    assert_eq!(v["no_deadlock"], "violated");
    assert_eq!(v["completes"], "violated");
    assert_eq!(v["safe"], "holds");
    assert_eq!(v["no_dead_activities"], "holds");
    // The shortest story: one branch taken, its task done, stuck at the join.
    let path = steps(&props["no_deadlock"]);
    assert_eq!(path[0], "start");
    assert!(
        path == ["start", "choose.take[f2]", "a.run"]
            || path == ["start", "choose.take[f3]", "b.run"],
        "{path:?}"
    );
    all_hold("deadlock-fixed", &choice("exclusiveGateway"), &BUILT_IN);
}

#[test]
fn a_dead_activity_is_named_and_the_fix_holds() {
    let (code, props) = verify("dead", &fault(true));
    assert_eq!(code, 1);
    let v = verdicts(&props);
    assert_eq!(v["no_dead_activities"], "violated");
    assert_eq!(
        props["no_dead_activities"]["detail"],
        "never started: h (Free Tool)"
    );
    for p in ["no_deadlock", "safe", "completes"] {
        assert_eq!(v[p], "holds", "{p}");
    }
    all_hold("dead-fixed", &fault(false), &BUILT_IN);
}

#[test]
fn an_unsafe_merge_is_found_and_the_fix_holds() {
    let (code, props) = verify("unsafe", &branches("exclusiveGateway"));
    assert_eq!(code, 1);
    let v = verdicts(&props);
    assert_eq!(v["safe"], "violated");
    assert_eq!(v["no_deadlock"], "holds");
    // Both branches reach the merge before Downlink takes the first token.
    let path = steps(&props["safe"]);
    let merges = path.iter().filter(|s| s.starts_with("merge.")).count();
    assert_eq!(merges, 2, "{path:?}");
    assert!(!path.iter().any(|s| s == "c.run"), "{path:?}");
    all_hold("unsafe-fixed", &branches("parallelGateway"), &BUILT_IN);
}

#[test]
fn a_lost_signal_is_found_and_a_level_triggered_abort_holds() {
    let (code, props) = verify("lost", &abort(true));
    assert_eq!(code, 1);
    let v = verdicts(&props);
    assert_eq!(v["no_lost_signal"], "violated");
    for p in BUILT_IN {
        assert_eq!(v[p], "holds", "{p}");
    }
    // The signal goes out before the excavation listens (the monitor's branch ends in the same
    // step), which then starts listening for a signal that will not come again.
    let path = steps(&props["no_lost_signal"]);
    assert_eq!(
        path,
        [
            "start",
            "fork.pass",
            "read.run",
            "throw.pass",
            "UNHEARD signal BatteryLow",
            "me.end",
            "deploy.run",
            "sp.activate",
            "LOST signal BatteryLow"
        ]
    );
    all_hold("lost-fixed", &abort(false), &BUILT_IN);
}

/// A flaw seeded into a copy of the Europa mission (the gateway that joins the three ways into
/// Communicate Until Death made parallel instead of exclusive) is found, with the story told in
/// BPMN steps.
#[test]
fn a_flaw_seeded_into_europa_is_found_with_a_readable_counterexample() {
    let text = std::fs::read_to_string(repo().join("deploy/missions/europa-bsm1.bpmn"))
        .expect("Europa model");
    let seeded = text.replacen(
        r#"<bpmn:exclusiveGateway id="ToCommunicate" name="Communicate">"#,
        r#"<bpmn:parallelGateway id="ToCommunicate" name="Communicate">"#,
        1,
    );
    let seeded = seeded.replacen(
        "</bpmn:exclusiveGateway>\n  <bpmn:subProcess id=\"CommunicateUntilDeath\"",
        "</bpmn:parallelGateway>\n  <bpmn:subProcess id=\"CommunicateUntilDeath\"",
        1,
    );
    assert_ne!(seeded, text, "the flaw is seeded");
    let (code, props, work) = verify_in("europa-seeded", &seeded);
    assert_eq!(code, 1);
    let v = verdicts(&props);
    assert_eq!(v["no_deadlock"], "violated", "{v:?}");
    assert_eq!(v["completes"], "violated", "{v:?}");
    // The science ends one way; the parallel gateway waits for the other two forever.
    let path = steps(&props["no_deadlock"]);
    assert_eq!(path[0], "start");
    assert!(
        path.contains(&"ExcavateAndCollect.activate".to_owned()),
        "{path:?}"
    );
    let ways = [
        "CollectImagesSeismic.run",
        "MissionDeadline.fire",
        "BatteryAbort.fire",
    ];
    assert_eq!(
        path.iter().filter(|s| ways.contains(&s.as_str())).count(),
        1,
        "one way in, and the join waits for the others: {path:?}"
    );
    assert!(
        !path.iter().any(|s| s.starts_with("CommunicateUntilDeath")),
        "{path:?}"
    );
    // The same story as an execution record, drawn by the timeline viewer.
    let record = work.join("no_deadlock.counterexample.jsonl");
    let page = work.join("no_deadlock.html");
    let out = Command::new(bin("trace"))
        .arg("timeline")
        .arg(&record)
        .arg("-o")
        .arg(&page)
        .output()
        .expect("trace timeline runs");
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bars: usize = said
        .split(" bars")
        .next()
        .and_then(|t| t.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("a bar count");
    assert!(bars >= 5, "{said}");
    let html = std::fs::read_to_string(&page).expect("page");
    assert!(
        html.contains("Excavate and Collect Samples"),
        "the science phase is drawn"
    );
}

#[test]
fn requirements_are_checked_and_bad_ones_refused_with_the_reason() {
    let dir = tempdir("verify-req");
    let file = dir.join("branches.bpmn");
    std::fs::write(&file, branches("parallelGateway")).expect("model");
    let req = |text: &str| {
        std::fs::write(dir.join("branches.req.toml"), text).expect("requirements");
        Command::new(bin("trace"))
            .arg("verify")
            .arg(&file)
            .output()
            .expect("trace verify runs")
    };
    let out = req(r#"
[[requirement]]
name = "downlinks_once"
says = "The data goes down exactly once, after both measurements"
check = 'count "Downlink" == 1 when completed'
[[requirement]]
name = "image_first"
check = 'never (done "Downlink" and not done "Image")'
[[requirement]]
name = "sound_before_image"
check = 'never (done "Image" and not done "Sound")'
"#);
    let text = String::from_utf8_lossy(&out.stdout);
    for (name, verdict) in [
        ("downlinks_once", "holds"),
        ("image_first", "holds"),
        ("sound_before_image", "VIOLATED"),
    ] {
        assert!(
            text.lines()
                .any(|l| l.contains(name) && l.trim_start().starts_with(verdict)),
            "{name}: {text}"
        );
    }
    assert_eq!(out.status.code(), Some(1));
    let out = req(r#"
[[requirement]]
name = "x"
check = 'eventually done "Nowhere"'
[[requirement]]
name = "y"
check = 'count "Image" maybe'
[[requirement]]
name = "safe"
check = 'eventually ended'
"#);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    for part in [
        "`x`: no element has the id or name \"Nowhere\"",
        "`y`: `count` is compared with a number",
        "`safe`: the name is already taken",
    ] {
        assert!(err.contains(part), "{part} in {err}");
    }
}

/// How Spin (on the PROMELA translation) and the native exploration (on the engine itself)
/// differ on one model, and which of the differences would be unsound.
pub(crate) struct Comparison {
    /// Every difference, by kind (empty: they agree exactly).
    pub how: Vec<String>,
    /// Differences where Spin misses something the engine does.
    pub unsound: Vec<String>,
    /// End events the engine reaches.
    pub ends: std::collections::BTreeSet<String>,
    /// Activities the engine never starts.
    pub dead: std::collections::BTreeSet<String>,
    /// The engine deadlocks / puts two tokens on a flow.
    pub deadlock: bool,
    pub unsafe_run: bool,
}

/// The outcome of comparing one model.
pub(crate) enum Compared {
    Refused(String),
    NeedsData,
    Done(Comparison),
}

/// Compares Spin and the engine on `graph`: the translation may over-approximate — it lets
/// internal moves of one step interleave, and loops repeat — so Spin may find more, never less:
/// every deadlock or unsafe run the engine has, Spin has; every end event the engine reaches,
/// Spin reaches; every activity Spin calls dead, the engine never starts.
pub(crate) fn compare(graph: executive_model::ProcessGraph, work: &std::path::Path) -> Compared {
    compare_within(graph, work, 200_000)
}

/// [`compare`], exploring the engine up to `states` states.
pub(crate) fn compare_within(
    graph: executive_model::ProcessGraph,
    work: &std::path::Path,
    states: usize,
) -> Compared {
    use executive_verify::{Bounds, Limits, Verdict};
    let tr = match executive_verify::translate(&graph, Bounds::default(), &[], &Default::default())
    {
        Ok(tr) => tr,
        Err(refusals) => {
            let why: Vec<String> = refusals.iter().map(|r| r.to_string()).collect();
            return Compared::Refused(why.join("; "));
        }
    };
    let graph = std::sync::Arc::new(graph);
    let native = executive_verify::explore(std::sync::Arc::clone(&graph), states);
    if native.needs_data.is_some() || !native.complete {
        return Compared::NeedsData;
    }
    let spin = executive_verify::check(&tr, &[], work, Limits::default())
        .unwrap_or_else(|e| panic!("{}: {e}", work.display()));
    let verdict = |p: &str| {
        spin.properties
            .iter()
            .find(|o| o.name == p)
            .map(|o| o.verdict.clone())
            .expect("a built-in property")
    };
    let spin_deadlock = verdict("no_deadlock") == Verdict::Violated;
    let spin_unsafe = verdict("safe") == Verdict::Violated;
    let spin_dead: std::collections::BTreeSet<String> = spin
        .properties
        .iter()
        .find(|o| o.name == "no_dead_activities")
        .and_then(|o| o.detail.clone())
        .map(|d| {
            d.trim_start_matches("never started: ")
                .split(", ")
                .map(|s| {
                    let key = s.split(" (").next().unwrap_or(s);
                    key.rsplit('/').next().unwrap_or(key).to_owned()
                })
                .collect()
        })
        .unwrap_or_default();
    let native_dead: std::collections::BTreeSet<String> =
        native.dead_activities.iter().cloned().collect();
    let (mut how, mut unsound) = (Vec::new(), Vec::new());
    // A finding the engine has and Spin has not is unsound; the other way, over-approximated.
    for (what, engine, spin, missed) in [
        (
            "deadlock",
            native.deadlock.is_some(),
            spin_deadlock,
            "the engine deadlocks, Spin says no",
        ),
        (
            "unsafe",
            native.unsafe_run.is_some(),
            spin_unsafe,
            "the engine is unsafe, Spin says safe",
        ),
    ] {
        if engine != spin {
            how.push(format!("{what}: engine {engine} Spin {spin}"));
            if engine {
                unsound.push(missed.to_owned());
            }
        }
    }
    if native_dead != spin_dead {
        how.push(format!("dead: engine {native_dead:?} Spin {spin_dead:?}"));
        if !spin_dead.is_subset(&native_dead) {
            unsound.push(format!(
                "Spin calls {:?} dead, the engine starts them",
                spin_dead.difference(&native_dead).collect::<Vec<_>>()
            ));
        }
    }
    if native.ends != spin.ends {
        how.push(format!(
            "ends: engine {:?} Spin {:?}",
            native.ends, spin.ends
        ));
        if !native.ends.is_subset(&spin.ends) {
            unsound.push(format!(
                "the engine reaches {:?}, Spin does not",
                native.ends.difference(&spin.ends).collect::<Vec<_>>()
            ));
        }
    }
    Compared::Done(Comparison {
        how,
        unsound,
        ends: native.ends,
        dead: native_dead,
        deadlock: native.deadlock.is_some(),
        unsafe_run: native.unsafe_run.is_some(),
    })
}

/// The differential test: on every visible betsy model the translator takes, Spin and the
/// engine are compared ([`compare`]). Where they differ at all, the model is listed with how.
#[test]
fn spin_and_the_engine_agree_on_the_betsy_models() {
    let root = mission_tests::conformance("betsy");
    let options = executive_model::Options {
        script_connector: true,
        ..executive_model::Options::default()
    };
    let work = tempdir("verify-betsy");
    let (mut compared, mut agree, mut refused, mut needs_data) = (0, 0, 0, 0);
    let mut differences = Vec::new();
    let mut unsound = Vec::new();
    for t in mission_tests::json_array(&root.join("expectations.json")) {
        let (group, name) = (t["group"].as_str().unwrap(), t["name"].as_str().unwrap());
        let path = root.join(group).join(format!("{name}.bpmn"));
        let loaded = executive_runtime::validate::load_file(&path, &options).expect("readable");
        let Some(graph) = loaded.graph else { continue };
        match compare(graph, &work.join(name)) {
            Compared::Refused(why) => {
                refused += 1;
                println!("  not translated: {group}/{name}: {why}");
            }
            Compared::NeedsData => needs_data += 1,
            Compared::Done(c) => {
                compared += 1;
                if c.how.is_empty() {
                    agree += 1;
                } else {
                    differences.push(format!("{group}/{name}: {}", c.how.join("; ")));
                }
                unsound.extend(c.unsound.iter().map(|u| format!("{group}/{name}: {u}")));
            }
        }
    }
    println!(
        "differential: {compared} betsy models compared, {agree} agree exactly; {refused} not translated, {needs_data} not explorable without data"
    );
    for d in &differences {
        println!("  over-approximated by Spin: {d}");
    }
    assert!(unsound.is_empty(), "{}", unsound.join("\n"));
    assert!(compared >= 65, "only {compared} models compared");
}

#[test]
fn a_missing_spin_is_named_with_how_to_install_it() {
    let dir = tempdir("verify-nospin");
    let file = dir.join("m.bpmn");
    std::fs::write(&file, choice("exclusiveGateway")).expect("model");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&file)
        .env("PATH", dir.join("empty"))
        .output()
        .expect("trace verify runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("`spin` was not found: install it (Debian: `apt-get install spin gcc`)"),
        "{err}"
    );
}

/// Timers armed together fire in the order of their durations: behind a 1 h boundary, a 2 h
/// boundary on the same task never fires — for Spin and for the engine alike.
#[test]
fn timers_armed_together_fire_shortest_first() {
    let text = model(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <task id="dig" name="Dig"/>
    <boundaryEvent id="hour" attachedToRef="dig"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition></boundaryEvent>
    <boundaryEvent id="two" attachedToRef="dig"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT2H</timeDuration></timerEventDefinition></boundaryEvent>
    <task id="short" name="Short"/>
    <task id="long" name="Long"/>
    <endEvent id="e1"/><endEvent id="e2"/><endEvent id="e3"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="dig"/>
    <sequenceFlow id="f2" sourceRef="dig" targetRef="e1"/>
    <sequenceFlow id="f3" sourceRef="hour" targetRef="short"/>
    <sequenceFlow id="f4" sourceRef="short" targetRef="e2"/>
    <sequenceFlow id="f5" sourceRef="two" targetRef="long"/>
    <sequenceFlow id="f6" sourceRef="long" targetRef="e3"/>
  </process>"#,
    );
    let dir = tempdir("verify-timers");
    let file = dir.join("timers.bpmn");
    std::fs::write(&file, text).expect("model");
    let out = Command::new(bin("trace"))
        .args(["verify", "--native", "--json"])
        .arg(&file)
        .output()
        .expect("trace verify runs");
    let report: Value = serde_json::from_slice(&out.stdout).expect("json");
    let dead = report["properties"]
        .as_array()
        .expect("properties")
        .iter()
        .find(|p| p["name"] == "no_dead_activities")
        .expect("dead activities");
    assert_eq!(dead["detail"], "never started: long (Long)", "{report:#}");
    assert_eq!(
        report["native"]["dead_activities"],
        serde_json::json!(["long"])
    );
}

/// A process drawn across the page with link events: `goto` jumps to the catch named `name`.
fn links(name: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:t">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <task id="survey" name="Survey"/>
    <intermediateThrowEvent id="goto"><linkEventDefinition name="{name}"/></intermediateThrowEvent>
    <intermediateCatchEvent id="dig_here"><linkEventDefinition name="to_dig"/></intermediateCatchEvent>
    <task id="dig" name="Dig"/>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="survey"/>
    <sequenceFlow id="f2" sourceRef="survey" targetRef="goto"/>
    <sequenceFlow id="f3" sourceRef="dig_here" targetRef="dig"/>
    <sequenceFlow id="f4" sourceRef="dig" targetRef="e"/>
  </process>
</definitions>"#
    )
}

#[test]
fn link_events_continue_at_their_catch_in_spin_as_in_the_engine() {
    // Linked: the token goes on at Dig and the mission ends; nothing refused.
    let (code, props) = verify("links", &links("to_dig"));
    let v = verdicts(&props);
    assert_eq!(code, 0, "{props:#?}");
    assert!(v.values().all(|v| *v == "holds"), "{v:?}");
    let text = links("to_dig");
    let g = std::sync::Arc::new(
        executive_model::load(text.as_bytes())
            .graph
            .expect("a linked model is valid"),
    );
    let native = executive_verify::explore(std::sync::Arc::clone(&g), 10_000);
    assert!(native.deadlock.is_none() && native.dead_activities.is_empty());
    assert_eq!(native.ends.iter().collect::<Vec<_>>(), ["e"]);
    let t = executive_verify::translate(
        &g,
        executive_verify::Bounds::default(),
        &[],
        &Default::default(),
    )
    .expect("links are translated");
    assert!(t.promela.contains("@@BPMN goto"), "the throw is a step");
}

/// An activity entered along two flows, one of which no run marks (a user task's error boundary:
/// the ground's answer never fails), is started along the other: it is not dead.
#[test]
fn an_activity_entered_along_only_one_of_its_flows_is_not_dead() {
    let text = model(
        r#"<process id="p" isExecutable="true">
    <startEvent id="s"/>
    <userTask id="approve" name="Approve stowing"/>
    <boundaryEvent id="rejected" attachedToRef="approve"><errorEventDefinition/></boundaryEvent>
    <task id="stow" name="Stow arm"/>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="approve"/>
    <sequenceFlow id="f2" sourceRef="approve" targetRef="stow"/>
    <sequenceFlow id="f3" sourceRef="rejected" targetRef="stow"/>
    <sequenceFlow id="f4" sourceRef="stow" targetRef="e"/>
  </process>"#,
    );
    let (_, props) = verify("two-ways-in", &text);
    let dead = &props["no_dead_activities"];
    assert_eq!(dead["verdict"], "holds", "{dead:#}");
}

/// `eventually` requirements where every run ends are decided on the end of each run (a safety
/// search), and still by pan's search for acceptance cycles where some run does not end.
#[test]
fn eventually_is_decided_on_the_end_of_runs_only_when_every_run_ends() {
    let dir = tempdir("verify-at-end");
    let run = |join: &str| {
        let file = dir.join(format!("tools-{join}.bpmn"));
        std::fs::write(&file, choice(join)).expect("model");
        std::fs::write(
            dir.join(format!("tools-{join}.req.toml")),
            r#"
[[requirement]]
name = "drills"
check = 'eventually done "Drill"'
[[requirement]]
name = "uses_a_tool"
check = 'eventually (done "Drill" or done "Scoop")'
[[requirement]]
name = "drill_then_tool_done"
check = 'after done "Drill" eventually done "Tool done"'
"#,
        )
        .expect("requirements");
        let out = Command::new(bin("trace"))
            .arg("verify")
            .arg(&file)
            .arg("--json")
            .output()
            .expect("trace verify runs");
        let report: Value = serde_json::from_slice(&out.stdout).expect("a JSON report");
        report["properties"]
            .as_array()
            .expect("properties")
            .iter()
            .map(|p| (p["name"].as_str().expect("name").to_owned(), p.clone()))
            .collect::<BTreeMap<String, Value>>()
    };
    let at_end = |p: &Value| {
        p["detail"]
            .as_str()
            .is_some_and(|d| d.contains("decided on the end of every run"))
    };
    // An exclusive merge: every run ends.
    let props = run("exclusiveGateway");
    assert_eq!(props["completes"]["verdict"], "holds");
    assert_eq!(props["drills"]["verdict"], "violated", "the Scoop run");
    assert!(at_end(&props["drills"]), "{:#}", props["drills"]);
    assert!(
        steps(&props["drills"]).iter().any(|s| s == "b.run"),
        "the counterexample scoops: {:?}",
        steps(&props["drills"])
    );
    for name in ["uses_a_tool", "drill_then_tool_done"] {
        assert_eq!(props[name]["verdict"], "holds", "{name}");
        assert!(at_end(&props[name]), "{name}: {:#}", props[name]);
    }
    // A parallel join: a run gets stuck, so the claims get their own searches.
    let props = run("parallelGateway");
    assert_eq!(props["completes"]["verdict"], "violated");
    assert_eq!(props["drills"]["verdict"], "violated");
    assert_eq!(props["uses_a_tool"]["verdict"], "holds");
    assert_eq!(
        props["drill_then_tool_done"]["verdict"], "violated",
        "the join never completes"
    );
    assert!(props.values().all(|p| !at_end(p)), "{props:#?}");
}
