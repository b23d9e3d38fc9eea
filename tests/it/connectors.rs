//! Missions over connectors, `trace run` against mock systems in their own processes: one
//! mission routed to two servers, and a mission that does not match the systems' catalogues
//! refused before it starts with every problem listed.

use std::path::Path;
use std::process::Command;

use mission_tests::bin;
use serde_json::json;

use crate::protocol::{endpoint, mock_process, port, tempdir};

const MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="D" targetNamespace="t">
  <error id="E_stuck" errorCode="TOOL_STUCK"/>
  <error id="E_glare" errorCode="GLARE"/>
  <process id="P" isExecutable="true">
    <startEvent id="S"/>
    <sequenceFlow id="f1" sourceRef="S" targetRef="Move"/>
    <serviceTask id="Move" name="Move Arm">
      <extensionElements><trace:task resource="arm.move">
        <trace:input target="target.x" source="1.5" type="f64"/>
        <trace:input target="target.y" source="2" type="int"/>
        <trace:output source="reached" target="reached" type="bool"/>
      </trace:task></extensionElements>
    </serviceTask>
    <boundaryEvent id="Stuck" attachedToRef="Move"><errorEventDefinition errorRef="E_stuck"/></boundaryEvent>
    <sequenceFlow id="f2" sourceRef="Move" targetRef="Shoot"/>
    <serviceTask id="Shoot" name="Take Picture">
      <extensionElements><trace:task resource="camera.shoot">
        <trace:input target="exposure_ms" source="40" type="int"/>
        <trace:output source="image_id" target="image" type="string"/>
      </trace:task></extensionElements>
    </serviceTask>
    <boundaryEvent id="Glare" attachedToRef="Shoot"><errorEventDefinition errorRef="E_glare"/></boundaryEvent>
    <sequenceFlow id="f3" sourceRef="Shoot" targetRef="End"/>
    <endEvent id="End"/>
    <sequenceFlow id="f4" sourceRef="Stuck" targetRef="End2"/>
    <endEvent id="End2"/>
    <sequenceFlow id="f5" sourceRef="Glare" targetRef="End3"/>
    <endEvent id="End3"/>
  </process>
</definitions>"#;

const CONNECTORS: &str = r#"
[[connector]]
name = "lander"
kind = "zenoh"
server = "lander_sim"
resources = ["arm.*"]

[[connector]]
name = "camera"
kind = "zenoh"
server = "camera_sys"
resources = ["camera.*"]
[connector.actions]
"camera.shoot" = "camera.capture"
"#;

fn arm(goal: serde_json::Value) -> serde_json::Value {
    json!({
        "catalogue": {"server": "lander_sim", "actions": [{
            "name": "arm.move", "goal": goal, "result": {"reached": "bool"},
            "errors": {"TOOL_STUCK": "stuck"}
        }]},
        "behaviour": {"arm.move": {"duration_ms": 20, "outputs": {"reached": true}}}
    })
}

fn camera(action: &str, result: serde_json::Value) -> serde_json::Value {
    json!({
        "catalogue": {"server": "camera_sys", "actions": [{
            "name": action, "goal": {"exposure_ms": "int"}, "result": result,
            "errors": {"GLARE": "the sun is in the frame"}
        }]},
        "behaviour": {(action): {"duration_ms": 20, "outputs": {"image_id": "img-1"}}}
    })
}

fn run(dir: &Path, endpoints: &[String]) -> (i32, String, String) {
    let model = dir.join("mission.bpmn");
    std::fs::write(&model, MISSION).expect("model");
    let config = dir.join("connectors.toml");
    std::fs::write(&config, CONNECTORS).expect("config");
    let mut cmd = Command::new(bin("trace"));
    cmd.arg("run")
        .arg(&model)
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(&config)
        .args(["--listen", &endpoint(port()), "--no-multicast-scouting"]);
    for e in endpoints {
        cmd.args(["--connect", e]);
    }
    let out = cmd.output().expect("trace runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn one_mission_drives_two_systems_through_two_connectors() {
    let dir = tempdir("two-systems");
    let (pa, pb) = (endpoint(port()), endpoint(port()));
    let goal = json!({"target": {"x": "f64", "y": "f64"}});
    let mut a = mock_process(&arm(goal), &pa, &dir.join("a").tap_mkdir());
    let mut b = mock_process(
        &camera("camera.capture", json!({"image_id": "string"})),
        &pb,
        &dir.join("b").tap_mkdir(),
    );
    let (code, stdout, stderr) = run(&dir, &[pa, pb]);
    let _ = (a.kill(), b.kill(), a.wait(), b.wait());
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("Completed"), "{stdout}");
    let record = std::fs::read_to_string(dir.join("store/record.jsonl")).expect("record");
    let lines: Vec<serde_json::Value> = record
        .lines()
        .map(|l| serde_json::from_str(l).expect("record line"))
        .collect();
    let of_kind = |kind: &str, field: &str| -> Vec<String> {
        lines
            .iter()
            .filter(|v| v["kind"] == kind)
            .map(|v| v[field].to_string())
            .collect()
    };
    let dispatched_elements: Vec<String> = lines
        .iter()
        .filter(|v| v["kind"] == "dispatched")
        .map(|v| v["element"]["id"].to_string())
        .collect();
    assert_eq!(dispatched_elements, [r#""Move""#, r#""Shoot""#]);
    assert_eq!(of_kind("completed", "task"), of_kind("dispatched", "task"));
    // Each went to its own system: the goals were accepted by the server named in the route.
    let accepted = lines.iter().filter(|v| v["kind"] == "accepted").count();
    assert_eq!(accepted, 2, "{record}");
    let dispatched: Vec<&serde_json::Value> =
        lines.iter().filter(|v| v["kind"] == "dispatched").collect();
    assert_eq!(
        dispatched[0]["request"],
        json!({"target": {"x": 1.5, "y": 2}})
    );
}

#[test]
fn a_mission_that_does_not_match_the_catalogues_is_refused_with_every_problem() {
    let dir = tempdir("mismatch");
    let (pa, pb) = (endpoint(port()), endpoint(port()));
    // The arm expects `target.z` too and names `y` a string; the camera serves another
    // action name and declares no GLARE.
    let goal = json!({"target": {"x": "f64", "y": "string", "z": "f64"}});
    let mut a = mock_process(&arm(goal), &pa, &dir.join("a").tap_mkdir());
    let mut b = mock_process(
        &camera("camera.snap", json!({"image_id": "string"})),
        &pb,
        &dir.join("b").tap_mkdir(),
    );
    let (code, stdout, stderr) = run(&dir, &[pa, pb]);
    let _ = (a.kill(), b.kill(), a.wait(), b.wait());
    assert_ne!(code, 0, "{stdout}");
    for problem in [
        "task `Move`: input `target.y` is declared int but `arm.move` expects string",
        "task `Move`: required goal field `target.z` of `arm.move` is not written by any input",
        "task `Shoot`: action `camera.capture` (resource `camera.shoot`) is not served by `camera_sys` (connector `camera`)",
        "(3 problems)",
    ] {
        assert!(
            stderr.contains(problem),
            "missing {problem:?} in:\n{stderr}"
        );
    }
    // Nothing ran: the store holds no step.
    assert!(!dir.join("store/record.jsonl").exists());
}

trait TapMkdir {
    fn tap_mkdir(self) -> Self;
}

impl TapMkdir for std::path::PathBuf {
    fn tap_mkdir(self) -> Self {
        std::fs::create_dir_all(&self).expect("dir");
        self
    }
}

const TIMED: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="D" targetNamespace="t">
  <process id="P" isExecutable="true">
    <startEvent id="S"/>
    <sequenceFlow id="f1" sourceRef="S" targetRef="Wait"/>
    <intermediateCatchEvent id="Wait" name="Wait Ten Hours">
      <timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT10H</timeDuration></timerEventDefinition>
    </intermediateCatchEvent>
    <sequenceFlow id="f2" sourceRef="Wait" targetRef="Ping"/>
    <serviceTask id="Ping"><extensionElements><trace:task resource="sys.ping"/></extensionElements></serviceTask>
    <sequenceFlow id="f3" sourceRef="Ping" targetRef="E"/>
    <endEvent id="E"/>
  </process>
</definitions>"#;

#[test]
fn timers_run_on_the_clock_a_system_supplies() {
    let dir = tempdir("system-clock");
    let p = endpoint(port());
    let start_ms = 946_684_800_000_i64; // 2000-01-01, far from today's wall clock
    let spec = json!({
        "catalogue": {"server": "sys", "actions": [{"name": "sys.ping"}]},
        "clock": {"start_ms": start_ms, "speed": 200000.0}
    });
    let mut sys = mock_process(&spec, &p, &dir.join("sys").tap_mkdir());
    let model = dir.join("timed.bpmn");
    std::fs::write(&model, TIMED).expect("model");
    let config = dir.join("connectors.toml");
    std::fs::write(
        &config,
        "[[connector]]\nname = \"sys\"\nkind = \"zenoh\"\nresources = [\"sys.*\"]\nclock = true\n",
    )
    .expect("config");
    // Ten hours of mission time at 200,000x is 0.18 s of wall time; on the wall clock the run
    // would not end, so the bound below only guards a hang.
    let child = Command::new(bin("trace"))
        .arg("run")
        .arg(&model)
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(&config)
        .args([
            "--listen",
            &endpoint(port()),
            "--connect",
            &p,
            "--no-multicast-scouting",
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("trace runs");
    // The event is the run's exit; the bound only keeps a broken clock from hanging CI.
    let (tx, rx) = std::sync::mpsc::channel();
    let pid = child.id();
    std::thread::spawn(move || {
        let mut child = child;
        let _ = tx.send(child.wait());
    });
    let status = match rx.recv_timeout(std::time::Duration::from_secs(120)) {
        Ok(s) => s.ok(),
        Err(_) => {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            None
        }
    };
    let _ = (sys.kill(), sys.wait());
    assert!(
        status.is_some_and(|s| s.success()),
        "the run did not end on the system clock"
    );
    let record = std::fs::read_to_string(dir.join("store/record.jsonl")).expect("record");
    let at = |kind: &str| -> i64 {
        record
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("line"))
            .find(|v| v["kind"] == kind)
            .and_then(|v| v["mission_ms"].as_i64())
            .unwrap_or_else(|| panic!("no {kind} line"))
    };
    let (armed, fired) = (at("timer_started"), at("timer_fired"));
    // Mission time is the system's (year 2000), not the wall clock's.
    assert!(
        (start_ms..start_ms + 365 * 86_400_000).contains(&armed),
        "armed at {armed}"
    );
    assert!(
        fired - armed >= 36_000_000,
        "fired {} ms after arming",
        fired - armed
    );
}
