//! Crash anywhere, resume correctly: `trace run` killed with SIGKILL at 50+ moments of a long
//! mission and resumed each time ends like an uninterrupted run, with no effect applied twice,
//! no gap in the journal, a valid execution record, and timers due during downtime fired once.

use std::path::{Path, PathBuf};
use std::process::{Child, Command};

use executive_store::{SledStore, Store};
use mission_tests::bin;

/// start -> drill (fails TOOL_STUCK on attempt 1, caught: unstick, retry) -> 100 sequential
/// samples -> a 1 s timer -> ground approval (user task) -> end.
const MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="defs" targetNamespace="urn:kill">
  <error id="stuck" errorCode="TOOL_STUCK"/>
  <process id="kill" isExecutable="true">
    <startEvent id="s"/>
    <serviceTask id="drill" name="Drill"><extensionElements><trace:task resource="sys.drill"/></extensionElements></serviceTask>
    <boundaryEvent id="stuck_b" attachedToRef="drill"><errorEventDefinition errorRef="stuck"/></boundaryEvent>
    <serviceTask id="unstick" name="Unstick"><extensionElements><trace:task resource="sys.unstick"/></extensionElements></serviceTask>
    <serviceTask id="sample" name="Sample"><extensionElements><trace:task resource="sys.sample"/></extensionElements>
      <multiInstanceLoopCharacteristics isSequential="true"><loopCardinality xsi:type="tFormalExpression">100</loopCardinality></multiInstanceLoopCharacteristics>
    </serviceTask>
    <intermediateCatchEvent id="wait"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1S</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <userTask id="approve" name="Approve"><extensionElements><trace:task resource="ground.approve"><trace:output source="ok" target="ok" type="bool"/></trace:task></extensionElements></userTask>
    <endEvent id="end"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="drill"/>
    <sequenceFlow id="f2" sourceRef="drill" targetRef="sample"/>
    <sequenceFlow id="f3" sourceRef="stuck_b" targetRef="unstick"/>
    <sequenceFlow id="f4" sourceRef="unstick" targetRef="drill"/>
    <sequenceFlow id="f5" sourceRef="sample" targetRef="wait"/>
    <sequenceFlow id="f6" sourceRef="wait" targetRef="approve"/>
    <sequenceFlow id="f7" sourceRef="approve" targetRef="end"/>
  </process>
</definitions>"#;

const SCRIPT: &str = r#"{"default": {"duration_ms": 20},
  "resources": {"sys.drill": {"duration_ms": 50, "fail": "TOOL_STUCK", "fail_attempts": [1]},
                "ground.approve": {"duration_ms": 10, "outputs": {"ok": true}}}}"#;

fn workdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("trace-kill-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("work dir");
    std::fs::write(dir.join("mission.bpmn"), MISSION).expect("mission");
    std::fs::write(dir.join("script.json"), SCRIPT).expect("script");
    dir
}

fn start(dir: &Path, resume: bool) -> Child {
    let mut cmd = Command::new(bin("trace"));
    if resume {
        cmd.arg("resume");
    } else {
        cmd.arg("run").arg(dir.join("mission.bpmn"));
    }
    cmd.arg("--store")
        .arg(dir.join("store"))
        .arg("--script")
        .arg(dir.join("script.json"))
        .args(["--snapshot-every", "40"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("trace starts")
}

/// Polls the execution record until `ready` holds for its text (true) or the process exits
/// (false). The record line is the event; the millisecond between polls only spares the CPU.
pub(crate) fn until_record(child: &mut Child, record: &Path, ready: impl Fn(&str) -> bool) -> bool {
    loop {
        if child.try_wait().expect("wait").is_some() {
            return false;
        }
        if ready(&std::fs::read_to_string(record).unwrap_or_default()) {
            return true;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

fn lines(path: &Path) -> usize {
    std::fs::read_to_string(path).map_or(0, |t| t.lines().count())
}

/// Resources of the applied effects, sorted: the multiset of completed activities.
fn effects(dir: &Path) -> (Vec<String>, usize) {
    let text = std::fs::read_to_string(dir.join("store/effects.jsonl")).unwrap_or_default();
    let mut keys = std::collections::BTreeSet::new();
    let mut resources = Vec::new();
    let mut total = 0;
    for l in text.lines() {
        let v: serde_json::Value = serde_json::from_str(l).expect("effects line");
        total += 1;
        keys.insert(v["task"].as_str().unwrap_or_default().to_owned());
        resources.push(v["resource"].as_str().unwrap_or_default().to_owned());
    }
    assert_eq!(keys.len(), total, "an effect was applied twice");
    resources.sort();
    (resources, total)
}

fn finish(child: Child) -> String {
    let out = child.wait_with_output().expect("trace ends");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn killed_fifty_times_the_mission_ends_as_if_never_interrupted() {
    // The reference: one uninterrupted run.
    let clean = workdir("clean");
    let stdout = finish(start(&clean, false));
    assert!(stdout.contains("instance 1: Completed"), "{stdout}");
    let (expected, _) = effects(&clean);
    assert_eq!(expected.iter().filter(|r| *r == "sys.sample").count(), 100);

    let dir = workdir("killed");
    let record = dir.join("store/record.jsonl");
    let mut seed: u64 = 0x5eed;
    let mut kills = 0;
    let mut child = start(&dir, false);
    let stdout = loop {
        // Kill after a random number of new record lines: an event, not a sleep.
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let target = lines(&record) + 1 + (seed >> 33) as usize % 12;
        let exited = !until_record(&mut child, &record, |text| text.lines().count() >= target);
        if exited {
            break finish(child);
        }
        child.kill().expect("SIGKILL");
        child.wait().expect("reaped");
        kills += 1;
        child = start(&dir, true);
    };
    println!("{kills} kills");
    assert!(kills >= 50, "only {kills} kills before the mission ended");
    assert!(stdout.contains("instance 1: Completed"), "{stdout}");
    let (got, _) = effects(&dir);
    assert_eq!(
        got, expected,
        "the completed activities differ from an uninterrupted run"
    );

    // The execution record is valid JSON Lines, shows every reboot, and each line carries its
    // own position across the fifty restarts (what joins the history and the live stream).
    let text = std::fs::read_to_string(&record).expect("record");
    let mut reboots = 0;
    for (i, l) in text.lines().enumerate() {
        let v: serde_json::Value =
            serde_json::from_str(l).unwrap_or_else(|e| panic!("bad record line {l}: {e}"));
        if v["kind"] == "reboot" {
            reboots += 1;
        }
        assert_eq!(v["line"], i + 1, "{l}");
    }
    assert_eq!(reboots, kills, "one reboot marker per kill");

    // The journal after the newest snapshot has no gaps.
    let store = SledStore::open(&dir.join("store")).expect("store opens");
    let rec = store.recover().expect("recovers");
    let first = rec.snapshot.as_ref().map_or(0, |(s, _)| *s);
    for (i, step) in rec.steps.iter().enumerate() {
        assert_eq!(step.input.seq, first + 1 + i as u64, "journal gap");
    }
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&clean);
}

#[test]
fn a_timer_due_during_downtime_fires_once_on_resume() {
    let dir = workdir("timer");
    let record = dir.join("store/record.jsonl");
    let mut child = start(&dir, false);
    // Wait until the 1 s timer is armed, then stay down until its deadline has passed.
    assert!(
        until_record(&mut child, &record, |text| text
            .contains("\"timer_started\"")),
        "ended before the timer"
    );
    child.kill().expect("SIGKILL");
    child.wait().expect("reaped");
    let text = std::fs::read_to_string(&record).expect("record");
    let due = text
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["kind"] == "timer_started")
        .and_then(|v| v["due_ms"].as_i64())
        .expect("the timer's deadline is recorded");
    // The downtime itself is what this test is about: it must outlast the deadline (mission
    // time is wall time at speed 1), so the waiting here is the event, not a guess.
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock")
        .as_millis() as i64;
    std::thread::sleep(std::time::Duration::from_millis(
        (due - now).max(0) as u64 + 100,
    ));
    let stdout = finish(start(&dir, true));
    assert!(stdout.contains("instance 1: Completed"), "{stdout}");
    let text = std::fs::read_to_string(&record).expect("record");
    assert_eq!(
        text.matches("\"timer_fired\"").count(),
        1,
        "the overdue timer fired once"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
