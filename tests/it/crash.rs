//! Crash anywhere: each finding of the crash matrix as a test — a goal the system never
//! acknowledged before the executive was killed is sent again on resume (not declared lost).

use std::path::Path;
use std::process::{Child, Command, Stdio};

use mission_tests::{bin, records};
use serde_json::json;

use crate::durability::until_record;
use crate::protocol::{endpoint, mock_process, port, tempdir};

/// Two branches: a timer, then a task on the `lander` system; and a longer timer, whose step
/// (committed, flushed) comes while the task's goal is still undelivered.
const AFTER_A_WHILE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="D" targetNamespace="t">
  <process id="P" isExecutable="true">
    <startEvent id="S"/>
    <sequenceFlow id="f0" sourceRef="S" targetRef="Split"/>
    <parallelGateway id="Split"/>
    <sequenceFlow id="f1" sourceRef="Split" targetRef="Wait"/>
    <intermediateCatchEvent id="Wait"><timerEventDefinition><timeDuration>PT1S</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <sequenceFlow id="f2" sourceRef="Wait" targetRef="Dig"/>
    <serviceTask id="Dig" name="Dig"><extensionElements><trace:task resource="dig"/></extensionElements></serviceTask>
    <sequenceFlow id="f3" sourceRef="Dig" targetRef="Join"/>
    <sequenceFlow id="f4" sourceRef="Split" targetRef="Later"/>
    <intermediateCatchEvent id="Later"><timerEventDefinition><timeDuration>PT2S</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <sequenceFlow id="f5" sourceRef="Later" targetRef="Join"/>
    <parallelGateway id="Join"/>
    <sequenceFlow id="f6" sourceRef="Join" targetRef="End"/>
    <endEvent id="End"/>
  </process>
</definitions>"#;

/// The `lander` system: `dig` succeeds after 20 ms; goals have a minute to find it.
const CONNECTORS: &str = r#"
[[connector]]
name = "lander"
kind = "zenoh"
server = "lander"
resources = ["dig"]
grace_ms = 60000
"#;

fn lander() -> serde_json::Value {
    json!({
        "catalogue": {"server": "lander", "actions": [{"name": "dig", "result": {}}]},
        "behaviour": {"dig": {"duration_ms": 20}}
    })
}

/// `trace run` (or `resume`) of the mission in `dir`, connecting to `system`.
fn executive(verb: &str, dir: &Path, system: &str) -> Child {
    let mut c = Command::new(bin("trace"));
    c.arg(verb);
    if verb == "run" {
        c.arg(dir.join("mission.bpmn"));
    }
    c.arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .args([
            "-l",
            &endpoint(port()),
            "-e",
            system,
            "--no-multicast-scouting",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("trace starts")
}

#[test]
fn a_goal_never_acknowledged_before_a_kill_is_sent_again_not_lost() {
    let dir = tempdir("crash-unacknowledged");
    std::fs::write(dir.join("mission.bpmn"), AFTER_A_WHILE).expect("mission");
    std::fs::write(dir.join("connectors.toml"), CONNECTORS).expect("connectors");
    let record = dir.join("store/record.jsonl");
    let system = endpoint(port());
    // The system serves its catalogue at the start, then goes away before the timer fires:
    // the goal is dispatched (committed, handed to the connector) but nobody receives it.
    let mut first = mock_process(&lander(), &system, &dir);
    let mut exec = executive("run", &dir, &system);
    assert!(
        until_record(&mut exec, &record, |t| t
            .contains(r#""kind":"timer_started""#)),
        "the executive ended before arming its timer"
    );
    let _ = (first.kill(), first.wait());
    // The later timer's step is committed after the dispatch: whatever the dispatch marked
    // by then is durable.
    assert!(
        until_record(&mut exec, &record, |t| t.contains(r#""kind":"dispatched""#)
            && t.matches(r#""kind":"timer_fired""#).count() == 2),
        "the executive ended before dispatching"
    );
    let _ = (exec.kill(), exec.wait());
    // The system comes back with an empty goal table; the executive resumes.
    let mut again = mock_process(&lander(), &system, &dir);
    let resumed = executive("resume", &dir, &system)
        .wait()
        .expect("resume ends");
    let _ = (again.kill(), again.wait());
    assert!(resumed.success(), "trace resume failed: {resumed}");
    let lines = records(&record);
    let ends: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|v| v["kind"] == "completed" || v["kind"] == "failed")
        .collect();
    // Before, the dispatch counted as done when handed over, so the resumed executive asked
    // the system about a goal it never had and ended it as CONNECTOR_LOST.
    assert_eq!(ends.len(), 1, "{ends:#?}");
    assert_eq!(ends[0]["kind"], "completed", "{ends:#?}");
    assert!(lines.iter().any(|v| v["kind"] == "reboot"));
}
