//! `trace run` as a user meets it: a stuck mission ends with exit 3 naming its incidents, a
//! process that starts only on a message is never reported "Completed", start variables reach
//! conditions, the scripted run's virtual clock gives the same record at any `--speed`, and a
//! waiting run says what it waits for.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use mission_tests::{bin, records};

/// `trace run`'s exit status for a stuck mission (documented in `trace run --help`).
const STUCK: i32 = 3;

/// An exclusive gateway whose conditions read `level`, which nobody sets.
const UNDEFINED: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" id="d" targetNamespace="urn:run">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <exclusiveGateway id="decide" name="Decide"/>
    <endEvent id="big"/>
    <endEvent id="small"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="decide"/>
    <sequenceFlow id="to_big" sourceRef="decide" targetRef="big"><conditionExpression xsi:type="tFormalExpression">level &gt; 3</conditionExpression></sequenceFlow>
    <sequenceFlow id="to_small" sourceRef="decide" targetRef="small"><conditionExpression xsi:type="tFormalExpression">level &lt;= 3</conditionExpression></sequenceFlow>
  </process>
</definitions>"#;

/// One branch stops on an undefined variable, the other runs a 50 ms scripted task first.
const INCIDENT_AND_BRANCH: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:run">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <exclusiveGateway id="decide" name="Decide"/>
    <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="sys.drill"/></extensionElements></serviceTask>
    <endEvent id="e1"/>
    <endEvent id="e2"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="decide"/>
    <sequenceFlow id="f3" sourceRef="fork" targetRef="drill"/>
    <sequenceFlow id="f4" sourceRef="decide" targetRef="e1"><conditionExpression xsi:type="tFormalExpression">missing_flag == true</conditionExpression></sequenceFlow>
    <sequenceFlow id="f5" sourceRef="drill" targetRef="e2"/>
  </process>
</definitions>"#;

/// A process whose only start is a message start event.
const MESSAGE_START: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:run">
  <message id="m" name="go"/>
  <process id="p" isExecutable="true">
    <startEvent id="start_on_go" name="Go received"><messageEventDefinition messageRef="m"/></startEvent>
    <task id="work" name="Work"/>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="start_on_go" targetRef="work"/>
    <sequenceFlow id="f2" sourceRef="work" targetRef="e"/>
  </process>
</definitions>"#;

/// Two pools: `sender` starts by itself and sends `go`, which starts `receiver`.
const SENT_START: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:run">
  <message id="m" name="go"/>
  <collaboration id="c">
    <participant id="ps" processRef="sender"/>
    <participant id="pr" processRef="receiver"/>
    <messageFlow id="mf" sourceRef="send" targetRef="start_on_go"/>
  </collaboration>
  <process id="sender" isExecutable="true">
    <startEvent id="s"/>
    <intermediateThrowEvent id="send"><messageEventDefinition messageRef="m"/></intermediateThrowEvent>
    <endEvent id="se"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="send"/>
    <sequenceFlow id="f2" sourceRef="send" targetRef="se"/>
  </process>
  <process id="receiver" isExecutable="true">
    <startEvent id="start_on_go"><messageEventDefinition messageRef="m"/></startEvent>
    <task id="work" name="Work"/>
    <endEvent id="re"/>
    <sequenceFlow id="g1" sourceRef="start_on_go" targetRef="work"/>
    <sequenceFlow id="g2" sourceRef="work" targetRef="re"/>
  </process>
</definitions>"#;

/// Two timers and two scripted tasks racing: the 100 ms timer, then `sample` (150 ms),
/// `drill` (200 ms) and the 300 ms timer end at distinct mission times.
const RACE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:run">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="sys.drill"/></extensionElements></serviceTask>
    <intermediateCatchEvent id="t_long"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT0.3S</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <intermediateCatchEvent id="t_short"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT0.1S</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <serviceTask id="sample" name="Sample"><extensionElements><trace:task resource="sys.sample"/></extensionElements></serviceTask>
    <boundaryEvent id="late" attachedToRef="sample"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT0.5S</timeDuration></timerEventDefinition></boundaryEvent>
    <parallelGateway id="join"/>
    <endEvent id="e"/>
    <endEvent id="too_late"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="drill"/>
    <sequenceFlow id="f3" sourceRef="fork" targetRef="t_long"/>
    <sequenceFlow id="f4" sourceRef="fork" targetRef="t_short"/>
    <sequenceFlow id="f5" sourceRef="drill" targetRef="join"/>
    <sequenceFlow id="f6" sourceRef="t_long" targetRef="join"/>
    <sequenceFlow id="f7" sourceRef="t_short" targetRef="sample"/>
    <sequenceFlow id="f8" sourceRef="sample" targetRef="join"/>
    <sequenceFlow id="f9" sourceRef="join" targetRef="e"/>
    <sequenceFlow id="f10" sourceRef="late" targetRef="too_late"/>
  </process>
</definitions>"#;

const RACE_SCRIPT: &str = r#"{"resources": {"sys.drill": {"duration_ms": 200},
  "sys.sample": {"duration_ms": 150}}}"#;

/// A user task the script answers only after a day of mission time.
const USER_TASK: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:run">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <userTask id="approve" name="Approve"><extensionElements><trace:task resource="ground.approve"><trace:output source="ok" target="ok" type="bool"/></trace:task></extensionElements></userTask>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="approve"/>
    <sequenceFlow id="f2" sourceRef="approve" targetRef="e"/>
  </process>
</definitions>"#;

const DAY_LATER: &str =
    r#"{"resources": {"ground.approve": {"duration_ms": 86400000, "outputs": {"ok": true}}}}"#;

fn workdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("trace-run-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("work dir");
    dir
}

/// `trace run MODEL --store DIR/<store>` with more arguments, to its end.
fn run(dir: &Path, model: &str, store: &str, args: &[&str]) -> Output {
    let mission = dir.join("mission.bpmn");
    std::fs::write(&mission, model).expect("mission");
    Command::new(bin("trace"))
        .arg("run")
        .arg(&mission)
        .arg("--store")
        .arg(dir.join(store))
        .args(args)
        .output()
        .expect("trace runs")
}

fn text(out: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

#[test]
fn an_unwritten_variable_is_refused_before_flight_and_a_wrong_one_ends_the_run_with_exit_3() {
    let dir = workdir("undefined");
    // Nothing writes `level`: the run is refused before its first step, naming the name.
    let out = run(&dir, UNDEFINED, "refused", &[]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(
        String::from_utf8_lossy(&out.stderr)
            .contains("from `Decide` reads `level`, which nothing writes before it"),
        "{all}"
    );
    // Given as a text, it cannot be compared: the gateway's incident leaves the run stuck.
    let out = run(&dir, UNDEFINED, "store", &["--var", "level=\"high\""]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(STUCK), "{all}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("instance 1: Stuck"), "{all}");
    assert!(
        stdout.contains("incident at `decide` (Decide)") && stdout.contains("level"),
        "{all}"
    );
    assert!(!stdout.contains("Completed"), "{all}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("stuck"),
        "{all}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_stuck_on_an_incident_finishes_its_other_branches_first() {
    let dir = workdir("branch");
    std::fs::write(
        dir.join("script.json"),
        r#"{"resources": {"sys.drill": {"duration_ms": 50}}}"#,
    )
    .expect("script");
    let script = dir.join("script.json");
    let out = run(
        &dir,
        INCIDENT_AND_BRANCH,
        "store",
        &["--script", script.to_str().expect("path")],
    );
    let all = text(&out);
    assert_eq!(out.status.code(), Some(STUCK), "{all}");
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("incident at `decide` (Decide)"),
        "{all}"
    );
    // The drill branch ran to its end before the run gave up.
    let kinds: Vec<(String, String)> = records(&dir.join("store/record.jsonl"))
        .iter()
        .map(|v| {
            (
                v["kind"].as_str().unwrap_or_default().to_owned(),
                v["element"]["id"].as_str().unwrap_or_default().to_owned(),
            )
        })
        .collect();
    let incident = kinds.iter().position(|(k, _)| k == "incident");
    let ended = kinds.iter().position(|(k, e)| k == "entered" && e == "e2");
    assert!(
        matches!((incident, ended), (Some(i), Some(e)) if i < e),
        "{kinds:?}"
    );
    assert!(kinds.iter().any(|(k, _)| k == "completed"), "{kinds:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_process_started_only_by_a_message_is_not_reported_completed() {
    let dir = workdir("message-start");
    let out = run(&dir, MESSAGE_START, "store", &[]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(STUCK), "{all}");
    assert!(!all.contains("Completed"), "{all}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("message `go`") && stderr.contains("`start_on_go` (Go received)"),
        "{all}"
    );
    // Refused before anything was journaled: no instance started.
    assert!(records(&dir.join("store/record.jsonl")).is_empty(), "{all}");

    // Sent by another process of the mission, the message starts it.
    let out = run(&dir, SENT_START, "sent", &[]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(0), "{all}");
    let lines = records(&dir.join("sent/record.jsonl"));
    let started: Vec<&str> = lines
        .iter()
        .filter(|v| v["kind"] == "instance_started")
        .filter_map(|v| v["process"].as_str())
        .collect();
    assert_eq!(started, ["sender", "receiver"], "{all}");
    assert!(
        lines
            .iter()
            .any(|v| v["kind"] == "left" && v["element"]["id"] == "work"),
        "{all}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn start_variables_reach_conditions() {
    let dir = workdir("vars");
    let decided = |store: &str| -> Vec<String> {
        records(&dir.join(store).join("record.jsonl"))
            .iter()
            .filter(|v| v["kind"] == "decided")
            .flat_map(|v| v["flows"].as_array().cloned().unwrap_or_default())
            .filter_map(|f| f.as_str().map(str::to_owned))
            .collect()
    };
    let out = run(&dir, UNDEFINED, "var", &["--var", "level=5"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(decided("var"), ["to_big"]);
    let started = records(&dir.join("var/record.jsonl"))
        .into_iter()
        .find(|v| v["kind"] == "instance_started")
        .expect("started");
    assert_eq!(started["vars"]["level"], 5, "typed as JSON: {started}");

    // A file of variables, and --var winning over it.
    std::fs::write(dir.join("vars.json"), r#"{"level": 1}"#).expect("vars");
    let file = dir.join("vars.json");
    let file = file.to_str().expect("path");
    let out = run(&dir, UNDEFINED, "file", &["--vars", file]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(decided("file"), ["to_small"]);
    let out = run(
        &dir,
        UNDEFINED,
        "both",
        &["--vars", file, "--var", "level=4"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(decided("both"), ["to_big"]);

    // Text that is not JSON is a string: comparing it with a number is an incident.
    let out = run(&dir, UNDEFINED, "text", &["--var", "level=high"]);
    assert_eq!(out.status.code(), Some(STUCK), "{}", text(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_scripted_run_gives_the_same_record_at_any_speed() {
    let dir = workdir("speed");
    std::fs::write(dir.join("script.json"), RACE_SCRIPT).expect("script");
    let script = dir.join("script.json");
    let script = script.to_str().expect("path");
    let start = "2031-07-04T12:00:00Z";
    let lines = |store: &str| -> Vec<serde_json::Value> {
        records(&dir.join(store).join("record.jsonl"))
            .into_iter()
            .map(|mut v| {
                v.as_object_mut().expect("object").remove("wall");
                v
            })
            .collect()
    };
    for (store, speed) in [("slow", "1"), ("fast", "1000000")] {
        let out = run(
            &dir,
            RACE,
            store,
            &["--script", script, "--speed", speed, "--start-at", start],
        );
        assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    }
    let (slow, fast) = (lines("slow"), lines("fast"));
    assert_eq!(slow, fast, "the record depends on --speed");

    // Mission time never goes back, and everything happens at its scripted moment.
    let t0 = slow[0]["mission_ms"].as_i64().expect("mission time");
    assert_eq!(t0, 1_940_932_800_000, "--start-at sets the mission clock");
    assert!(
        slow.windows(2)
            .all(|w| w[0]["mission_ms"].as_i64() <= w[1]["mission_ms"].as_i64()),
        "mission time went back"
    );
    let at = |kind: &str, element: &str| -> i64 {
        slow.iter()
            .find(|v| v["kind"] == kind && v["element"]["id"] == element)
            .and_then(|v| v["mission_ms"].as_i64())
            .unwrap_or_else(|| panic!("no {kind} of {element}"))
            - t0
    };
    assert_eq!(at("timer_fired", "t_short"), 100);
    assert_eq!(at("left", "sample"), 250);
    assert_eq!(at("left", "drill"), 200);
    assert_eq!(at("timer_fired", "t_long"), 300);
    let fired: Vec<&str> = slow
        .iter()
        .filter(|v| v["kind"] == "timer_fired")
        .filter_map(|v| v["element"]["id"].as_str())
        .collect();
    assert_eq!(
        fired,
        ["t_short", "t_long"],
        "timers fire in mission-time order"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_waiting_run_says_what_it_waits_for() {
    let dir = workdir("waiting");
    let mission = dir.join("mission.bpmn");
    std::fs::write(&mission, USER_TASK).expect("mission");
    std::fs::write(dir.join("script.json"), DAY_LATER).expect("script");
    let mut child = Command::new(bin("trace"))
        .arg("run")
        .arg(&mission)
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--script")
        .arg(dir.join("script.json"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("trace starts");
    // The waiting line is the event: read stderr until it comes (or the run ends).
    let stderr = child.stderr.take().expect("stderr");
    let mut seen = Vec::new();
    let mut found = None;
    for line in std::io::BufReader::new(stderr).lines() {
        let line = line.expect("stderr line");
        if line.contains("user task `approve` (Approve)") {
            found = Some(line);
            break;
        }
        seen.push(line);
    }
    child.kill().expect("kill");
    child.wait().expect("reaped");
    let line = found.unwrap_or_else(|| panic!("no waiting line in:\n{}", seen.join("\n")));
    assert!(
        seen.iter().any(|l| l.starts_with("waiting (mission time ")),
        "{seen:?}"
    );
    assert!(
        line.contains("in instance 1") && line.contains(", since 20"),
        "{line}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
