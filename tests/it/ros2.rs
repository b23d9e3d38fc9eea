//! ROS 2 against the official tools, installed by `scripts/test` into a virtual environment
//! (`TRACE_ROS2`, default `~/.cache/trace-ros2/venv`: the `ros-jazzy-rclpy` and
//! `ros-jazzy-test-msgs` wheels): TRACE's reading of every `test_msgs`, `builtin_interfaces`,
//! `action_msgs` and `unique_identifier_msgs` definition gives each field the type `rclpy`
//! gives it, `trace catalogue ros2` prints them and `trace templates` offers them; and `trace
//! run` commands a real `rclpy` action server (`tests/python/ros2/server.py`, Fast DDS on
//! localhost, a ROS domain per test) through success with feedback, an `ABORTED` goal caught by an error boundary, a cancel by a
//! timer boundary that the server sees, a server killed mid-goal (`CONNECTOR_LOST`), the
//! executive killed and resumed mid-goal (the goal runs and ends once), a refused goal, and a
//! mission whose goal field path or integer range is wrong refused before it starts.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use connector_ros2::Definitions;
use mission_tests::{bin, records, repo};

/// The virtual environment `scripts/test` installs ROS 2 into.
pub(crate) fn venv() -> PathBuf {
    let dir = std::env::var_os("TRACE_ROS2")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default())
                .join(".cache/trace-ros2/venv")
        });
    assert!(
        dir.join("bin/python").exists(),
        "no ROS 2 virtual environment at {} (scripts/test installs it; or set TRACE_ROS2)",
        dir.display()
    );
    dir
}

const PACKAGES: [&str; 4] = [
    "test_msgs",
    "builtin_interfaces",
    "action_msgs",
    "unique_identifier_msgs",
];

#[test]
fn every_field_of_the_ros_definitions_has_the_type_rclpy_gives_it() {
    let venv = venv();
    let mut python = Command::new(venv.join("bin/python"));
    let (messages, actions) = agree_with_rclpy(&mut python, &venv, &PACKAGES);
    // Every definition of the four packages was compared.
    assert!(
        messages >= 15 && actions >= 2,
        "{messages} messages, {actions} actions"
    );
    let found = Definitions::new(&[venv]).actions();
    assert!(
        found.contains(&"test_msgs/action/Fibonacci".to_owned()),
        "{found:?}"
    );
}

/// Checks that every message and action of `packages` under `prefix` has, as TRACE reads it,
/// the field types `rclpy` (run as `python`) gives it; the numbers of messages and actions
/// compared.
pub(crate) fn agree_with_rclpy(
    python: &mut Command,
    prefix: &Path,
    packages: &[&str],
) -> (usize, usize) {
    let out = python
        .arg(repo().join("tests/python/ros2/types.py"))
        .arg(prefix.join("share"))
        .args(packages)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let official: serde_json::Map<String, serde_json::Value> =
        serde_json::from_slice(&out.stdout).expect("rclpy's types as JSON");
    let defs = Definitions::new(&[prefix.to_owned()]);
    let as_map = |fields: Vec<(String, String)>| -> serde_json::Value {
        fields
            .into_iter()
            .map(|(k, v)| (k, serde_json::Value::String(v)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    let (mut messages, mut actions) = (0, 0);
    for (key, want) in &official {
        let parts: Vec<&str> = key.split('/').collect();
        let ours = match parts.as_slice() {
            [pkg, "msg", name] => {
                messages += 1;
                as_map(defs.message_types(pkg, name).expect(key))
            }
            [_, "action", _] => {
                actions += 1;
                let a = defs.action(key).unwrap_or_else(|e| panic!("{key}: {e}"));
                serde_json::Value::Array(a.ros_types.into_iter().map(as_map).collect())
            }
            _ => panic!("{key}"),
        };
        assert_eq!(&ours, want, "{key}");
    }
    (messages, actions)
}

#[test]
fn trace_catalogue_ros2_prints_each_action_s_entry() {
    let venv = venv();
    let out = Command::new(bin("trace"))
        .args(["catalogue", "ros2"])
        .arg(venv.join("share/test_msgs"))
        .arg(venv.join("share/builtin_interfaces"))
        .output()
        .expect("trace runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cat: connector_api::Catalogue = serde_json::from_str(&text).expect("a catalogue");
    let fib = cat.action("test_msgs/action/Fibonacci").expect("Fibonacci");
    assert_eq!(fib.goal["order"].to_string(), "i32");
    assert_eq!(fib.result["sequence"].to_string(), "[i32]");
    let nested = cat
        .action("test_msgs/action/NestedMessage")
        .expect("NestedMessage");
    assert_eq!(
        nested.goal["nested_different_pkg"].to_string(),
        "{nanosec: u32, sec: i32}"
    );
    // A definition that cannot be read is refused with its file and line.
    let dir = crate::protocol::tempdir("ros2-bad");
    std::fs::create_dir_all(dir.join("bad_msgs/action")).expect("dir");
    std::fs::write(
        dir.join("bad_msgs/action/Dig.action"),
        "int32 depth\nfloat128 force\n---\n---\n",
    )
    .expect("file");
    let out = Command::new(bin("trace"))
        .args(["catalogue", "ros2"])
        .arg(dir.join("bad_msgs"))
        .output()
        .expect("trace runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("Dig.action:2: `float128` is not a type"),
        "{err}"
    );
}

/// A real `rclpy` server of `test_msgs/action/Fibonacci` at `/fibonacci` in ROS domain
/// `domain`, each number `step` seconds apart; its output lines are kept.
struct Server {
    child: Child,
    said: Arc<Mutex<Vec<String>>>,
}

impl Server {
    fn start(domain: u32, step: f64) -> Server {
        let venv = venv();
        let mut child = Command::new(venv.join("bin/python"))
            .arg(repo().join("tests/python/ros2/server.py"))
            .arg(step.to_string())
            .env("ROS_DOMAIN_ID", domain.to_string())
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the server starts");
        let out = child.stdout.take().expect("stdout");
        let said = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&said);
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if line == "ready" {
                    let _ = tx.send(());
                }
                keep.lock().expect("lines").push(line);
            }
        });
        rx.recv_timeout(Duration::from_secs(60))
            .expect("the rclpy server says ready within a minute");
        Server { child, said }
    }

    fn said(&self, line: &str) -> usize {
        self.said
            .lock()
            .expect("lines")
            .iter()
            .filter(|l| *l == line)
            .count()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A mission of one task on `fib.compute` with `order`, each way out an end of its own: `Done`,
/// `Aborted`, `Refused`, `Lost`, `TimedOut` (after `timeout`).
fn mission(order: &str, timeout: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="D" targetNamespace="t">
  <error id="EA" errorCode="ABORTED"/><error id="ER" errorCode="REJECTED"/><error id="EL" errorCode="CONNECTOR_LOST"/>
  <process id="P" isExecutable="true">
    <startEvent id="S"/>
    <sequenceFlow id="f1" sourceRef="S" targetRef="Fib"/>
    <serviceTask id="Fib"><extensionElements><trace:task resource="fib.compute">
      <trace:input target="order" source='{order}'/>
      <trace:output source="sequence" target="seq"/>
    </trace:task></extensionElements></serviceTask>
    <sequenceFlow id="f2" sourceRef="Fib" targetRef="Done"/>
    <endEvent id="Done"/>
    <boundaryEvent id="BA" attachedToRef="Fib"><errorEventDefinition errorRef="EA"/></boundaryEvent>
    <sequenceFlow id="f3" sourceRef="BA" targetRef="Aborted"/>
    <endEvent id="Aborted"/>
    <boundaryEvent id="BR" attachedToRef="Fib"><errorEventDefinition errorRef="ER"/></boundaryEvent>
    <sequenceFlow id="f4" sourceRef="BR" targetRef="Refused"/>
    <endEvent id="Refused"/>
    <boundaryEvent id="BL" attachedToRef="Fib"><errorEventDefinition errorRef="EL"/></boundaryEvent>
    <sequenceFlow id="f5" sourceRef="BL" targetRef="Lost"/>
    <endEvent id="Lost"/>
    <boundaryEvent id="BT" attachedToRef="Fib"><timerEventDefinition><timeDuration>{timeout}</timeDuration></timerEventDefinition></boundaryEvent>
    <sequenceFlow id="f6" sourceRef="BT" targetRef="TimedOut"/>
    <endEvent id="TimedOut"/>
  </process>
</definitions>"#
    )
}

/// The connectors file: `fib.compute` on the ROS 2 action `/fibonacci` in `domain`.
fn connectors(domain: u32) -> String {
    let venv = venv();
    format!(
        r#"[[connector]]
name = "fib"
kind = "ros2"
resources = ["fib.*"]
grace_ms = 1000

[connector.actions]
"fib.compute" = {{ action = "/fibonacci", type = "test_msgs/action/Fibonacci" }}

[connector.ros2]
python = "{}"
domain_id = {domain}
discovery = "localhost"
definitions = ["{}"]
"#,
        venv.join("bin/python").display(),
        venv.join("share").display()
    )
}

/// `trace run` (or `resume`) of `mission` in `dir` with the connectors of `domain`.
fn trace(dir: &Path, resume: bool, domain: u32) -> Command {
    std::fs::write(dir.join("connectors.toml"), connectors(domain)).expect("connectors");
    let mut c = Command::new(bin("trace"));
    if resume {
        c.arg("resume");
    } else {
        c.arg("run").arg(dir.join("mission.bpmn"));
    }
    c.arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .args(["--catalogue-wait", "30"])
        .env_remove("ROS_DOMAIN_ID")
        .stdout(Stdio::null());
    c
}

/// [`trace`] started, its standard error appended to `trace.log` in `dir`.
fn spawn(dir: &Path, resume: bool, domain: u32) -> Child {
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join("trace.log"))
        .expect("log");
    trace(dir, resume, domain)
        .stderr(log)
        .spawn()
        .expect("trace runs")
}

/// Runs the mission to its end (two minutes at most); its record's lines.
fn fly(dir: &Path, order: &str, timeout: &str, domain: u32) -> Vec<serde_json::Value> {
    std::fs::write(dir.join("mission.bpmn"), mission(order, timeout)).expect("mission");
    let child = spawn(dir, false, domain);
    finish(dir, child)
}

fn finish(dir: &Path, child: Child) -> Vec<serde_json::Value> {
    let status = mission_tests::ended(child, Duration::from_secs(120))
        .expect("the mission ends within two minutes");
    let lines = records(&dir.join("store/record.jsonl"));
    assert!(status.success(), "trace: {status}; record: {lines:#?}");
    lines
}

/// The end event the mission reached.
fn end(lines: &[serde_json::Value]) -> String {
    lines
        .iter()
        .rfind(|l| {
            l["kind"] == "entered"
                && ["Done", "Aborted", "Refused", "Lost", "TimedOut"]
                    .contains(&l["element"]["id"].as_str().unwrap_or_default())
        })
        .map(|l| l["element"]["id"].as_str().unwrap_or_default().to_owned())
        .unwrap_or_default()
}

#[test]
fn a_goal_succeeds_on_a_real_ros2_server_with_its_feedback_and_result() {
    let server = Server::start(61, 0.05);
    let dir = crate::protocol::tempdir("ros2-success");
    let lines = fly(&dir, "6", "PT1H", 61);
    assert_eq!(end(&lines), "Done", "{lines:#?}");
    let done = lines
        .iter()
        .find(|l| l["kind"] == "completed")
        .expect("completed");
    assert_eq!(
        done["output"]["sequence"],
        serde_json::json!([0, 1, 1, 2, 3, 5, 8]),
        "{done}"
    );
    assert!(
        lines.iter().filter(|l| l["kind"] == "feedback").count() >= 3,
        "{lines:#?}"
    );
    assert_eq!(server.said("goal 6"), 1);
}

#[test]
fn an_aborted_goal_is_caught_by_an_error_boundary() {
    let _server = Server::start(62, 0.05);
    let dir = crate::protocol::tempdir("ros2-aborted");
    let lines = fly(&dir, "13", "PT1H", 62);
    assert_eq!(end(&lines), "Aborted", "{lines:#?}");
}

#[test]
fn a_refused_goal_is_caught_as_rejected() {
    let _server = Server::start(63, 0.05);
    let dir = crate::protocol::tempdir("ros2-refused");
    let lines = fly(&dir, "-1", "PT1H", 63);
    assert_eq!(end(&lines), "Refused", "{lines:#?}");
}

#[test]
fn a_timer_boundary_cancels_the_goal_and_the_server_sees_the_cancel() {
    let server = Server::start(64, 0.05);
    let dir = crate::protocol::tempdir("ros2-cancel");
    let lines = fly(&dir, "300", "PT2S", 64);
    assert_eq!(end(&lines), "TimedOut", "{lines:#?}");
    // The cancel reaches the server (the mission may end first: wait for the server's word).
    let seen = mission_tests::hosts::poll(Duration::from_secs(20), || {
        (server.said("cancel") == 1).then_some(())
    });
    assert!(seen.is_some(), "the server never saw the cancel");
}

#[test]
fn a_server_killed_mid_goal_gives_connector_lost() {
    let mut server = Server::start(65, 0.05);
    let dir = crate::protocol::tempdir("ros2-lost");
    std::fs::write(dir.join("mission.bpmn"), mission("300", "PT1H")).expect("mission");
    let child = spawn(&dir, false, 65);
    let going = mission_tests::hosts::poll(Duration::from_secs(60), || {
        (server.said("goal 300") == 1).then_some(())
    });
    assert!(going.is_some(), "the goal never reached the server");
    server.child.kill().expect("kill");
    let lines = finish(&dir, child);
    assert_eq!(end(&lines), "Lost", "{lines:#?}");
}

#[test]
fn the_executive_killed_mid_goal_resumes_and_the_goal_runs_and_ends_once() {
    let server = Server::start(66, 0.25);
    let dir = crate::protocol::tempdir("ros2-resume");
    std::fs::write(dir.join("mission.bpmn"), mission("12", "PT1H")).expect("mission");
    let mut first = spawn(&dir, false, 66);
    let record = dir.join("store/record.jsonl");
    let accepted = mission_tests::hosts::poll(Duration::from_secs(60), || {
        let text = std::fs::read_to_string(&record).unwrap_or_default();
        text.contains("\"kind\":\"feedback\"").then_some(())
    });
    assert!(accepted.is_some(), "no feedback recorded");
    first.kill().expect("SIGKILL");
    let _ = first.wait();
    let child = spawn(&dir, true, 66);
    let lines = finish(&dir, child);
    assert_eq!(end(&lines), "Done", "{lines:#?}");
    let completed = lines.iter().filter(|l| l["kind"] == "completed").count();
    assert_eq!(completed, 1, "{lines:#?}");
    assert_eq!(server.said("goal 12"), 1, "the server ran the goal again");
}

#[test]
fn trace_templates_offers_the_ros2_actions_of_the_connectors() {
    let dir = crate::protocol::tempdir("ros2-templates");
    std::fs::write(dir.join("connectors.toml"), connectors(68)).expect("connectors");
    let out = Command::new(bin("trace"))
        .arg("templates")
        .arg(&*dir)
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .arg("--out")
        .arg(dir.join("templates"))
        .output()
        .expect("trace runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let c8 = std::fs::read_to_string(dir.join("templates/trace-fib.c8.json")).expect("templates");
    assert!(
        c8.contains("fib.compute") && c8.contains("order (i32)"),
        "{c8}"
    );
}

#[test]
fn a_wrong_field_or_an_integer_out_of_range_is_refused_before_the_mission_starts() {
    let dir = crate::protocol::tempdir("ros2-preflight");
    for (order, says) in [
        (
            "3000000000",
            "input `order` is 3000000000, outside the range of i32",
        ),
        ("\"fast\"", "input `order` must be i32, got a string"),
    ] {
        std::fs::write(dir.join("mission.bpmn"), mission(order, "PT1H")).expect("mission");
        let out = trace(&dir, false, 67).output().expect("trace runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{order}: {err}");
        assert!(err.contains(says), "{order}: {err}");
    }
    let wrong = mission("3", "PT1H").replace("target=\"order\"", "target=\"goal.order\"");
    std::fs::write(dir.join("mission.bpmn"), wrong).expect("mission");
    let out = trace(&dir, false, 67).output().expect("trace runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("input `goal.order` is not a goal field"),
        "{err}"
    );
}
