//! Europa on two middlewares at once (`deploy/ros2`): the lander's arm and excavation are ROS 2
//! actions of the package `europa_msgs` (built for `rclpy` by `deploy/ros2/build.py` with ROS 2's
//! own generators, cached beside `TRACE_ROS2`), served by `elap-sim --ros2` through real `rclpy`
//! action servers; everything else stays on Zenoh. Checked: the definitions describe the
//! simulator's activities exactly, and `rclpy` types every field as TRACE reads it; a tool stuck on ROS 2 is caught by the mission's error
//! boundary and recovered; a stalled excavation is cancelled by the mission deadline through
//! ROS 2's cancel.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use mission_tests::{bin, records, repo};

use crate::europa::outcomes;
use crate::protocol::{endpoint, port, tempdir};
use crate::ros2::venv;

/// `europa_msgs` built for the venv's `rclpy` (about 20 s the first time): the install prefix,
/// kept per content of the definitions and the build script.
fn overlay() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let venv = venv();
            let src = repo().join("deploy/ros2");
            let mut text = std::fs::read(src.join("build.py")).expect("build.py");
            let mut files: Vec<PathBuf> = ["action", "msg"]
                .iter()
                .flat_map(|k| std::fs::read_dir(src.join("europa_msgs").join(k)).expect("dir"))
                .map(|e| e.expect("entry").path())
                .collect();
            files.sort();
            for f in &files {
                text.extend(f.to_string_lossy().bytes());
                text.extend(std::fs::read(f).expect("definition"));
            }
            // FNV-1a: the same key on every run and machine.
            let key = text.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
                (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
            });
            let prefix = venv
                .parent()
                .expect("the venv's folder")
                .join(format!("europa_msgs-{key:016x}"));
            if !prefix.join("share/europa_msgs").is_dir() {
                let building = prefix.with_extension(format!("building-{}", std::process::id()));
                let out = Command::new(venv.join("bin/python"))
                    .arg(src.join("build.py"))
                    .arg(src.join("europa_msgs"))
                    .arg(&building)
                    .output()
                    .expect("build.py runs");
                assert!(
                    out.status.success(),
                    "building europa_msgs failed:\n{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                let _ = std::fs::remove_dir_all(&prefix);
                std::fs::rename(&building, &prefix).expect("the prefix moves into place");
            }
            prefix
        })
        .clone()
}

/// The environment a sourced ROS 2 workspace gives: the venv's Python first on PATH, the
/// package's libraries, Python types and definitions found, a ROS domain of the test's own.
fn sourced(c: &mut Command, domain: u32) {
    let venv = venv();
    let prefix = overlay();
    let path = std::env::var("PATH").unwrap_or_default();
    let site = std::fs::read_dir(prefix.join("lib"))
        .expect("lib")
        .map(|e| e.expect("entry").path())
        .find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("python"))
        })
        .expect("lib/python3.X")
        .join("site-packages");
    c.env("PATH", format!("{}:{path}", venv.join("bin").display()))
        .env("PYTHONPATH", site)
        .env("LD_LIBRARY_PATH", prefix.join("lib"))
        .env(
            "AMENT_PREFIX_PATH",
            format!("{}:{}", prefix.display(), venv.display()),
        )
        .env("ROS_DOMAIN_ID", domain.to_string());
}

/// The lander simulator serving its arm and excavation over ROS 2 (with `faults`), and a policy
/// ground station, on `hub`; killed when dropped. The simulator's first lines are kept.
struct Systems {
    sim: Child,
    ground: Child,
    said: Vec<String>,
}

impl Systems {
    fn start(dir: &Path, hub: &str, domain: u32, faults: &str) -> Systems {
        std::fs::write(dir.join("faults.json"), faults).expect("faults");
        let mut sim = Command::new(bin("elap-sim"));
        sim.arg("--ros2")
            .arg(repo().join("deploy/ros2/connectors.toml"))
            .arg("--faults")
            .arg(dir.join("faults.json"))
            .args(["--speed", "200000", "--profile", "quiet", "--seed", "1"])
            .args([
                "--start-ms",
                "1790000000000",
                "-e",
                hub,
                "--no-multicast-scouting",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        sourced(&mut sim, domain);
        let mut sim = sim.spawn().expect("elap-sim starts");
        let mut said = Vec::new();
        let mut out = BufReader::new(sim.stdout.take().expect("stdout"));
        while !said.last().is_some_and(|l: &String| l.starts_with("ready")) {
            let mut line = String::new();
            let n = out.read_line(&mut line).expect("a line");
            assert!(n > 0, "elap-sim exited: {said:?}");
            said.push(line.trim().to_owned());
        }
        let mut ground = Command::new(bin("ground-station"))
            .arg("--policy")
            .arg(repo().join("deploy/ground/policy.toml"))
            .args(["-e", hub, "--no-multicast-scouting"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("ground-station starts");
        let mut line = String::new();
        BufReader::new(ground.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("ready line");
        assert!(line.starts_with("ready"), "ground-station: {line}");
        Systems { sim, ground, said }
    }
}

impl Drop for Systems {
    fn drop(&mut self) {
        for c in [&mut self.sim, &mut self.ground] {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Prints the ROS graph's actions with their types, once the simulator's are discovered (or
/// after 20 s).
const GRAPH: &str = r#"
import time, rclpy
from rclpy.action import get_action_names_and_types
rclpy.init()
node = rclpy.create_node("probe")
names = []
for _ in range(100):
    names = get_action_names_and_types(node)
    if any(n.endswith("/excavate") for n, _ in names):
        break
    time.sleep(0.2)
for n, types in names:
    print(n, *types)
"#;

/// Flies Europa with `deploy/ros2/connectors.toml` and `faults`; the record's lines.
fn fly(name: &str, domain: u32, faults: &str) -> Vec<serde_json::Value> {
    let _one = crate::europa::FLIGHT
        .lock()
        .unwrap_or_else(|p| p.into_inner());
    let dir = tempdir(name);
    let hub = endpoint(port());
    let systems = Systems::start(&dir, &hub, domain, faults);
    assert!(
        systems
            .said
            .iter()
            .any(|l| l.contains("excavation.excavate") && l.contains("over ROS 2")),
        "{:?}",
        systems.said
    );
    // Any ROS 2 node sees the simulator's actions, in the connectors file's namespace.
    let mut graph = Command::new("python3");
    graph.arg("-c").arg(GRAPH);
    sourced(&mut graph, domain);
    let seen = graph.output().expect("python runs");
    let seen = String::from_utf8_lossy(&seen.stdout);
    for name in ["/lander/arm/unstow", "/lander/excavation/excavate"] {
        assert!(
            seen.lines().any(|l| l
                == format!(
                    "{name} europa_msgs/action/{}",
                    if name.ends_with("unstow") {
                        "Unstow"
                    } else {
                        "Excavate"
                    }
                )),
            "{name} not in the ROS graph: {seen}"
        );
    }
    let mut run = Command::new(bin("trace"));
    run.arg("run")
        .arg(repo().join("deploy/missions/europa-bsm1.bpmn"))
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(repo().join("deploy/ros2/connectors.toml"))
        .args(["-l", &hub, "--no-multicast-scouting"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    sourced(&mut run, domain);
    let child = run.spawn().expect("trace runs");
    let out = wait(child);
    drop(systems);
    let lines = records(&dir.join("store/record.jsonl"));
    assert!(out.0, "trace run failed:\n{}\nrecord: {lines:#?}", out.1);
    lines
}

/// Waits (five minutes at most) for `trace run`: whether it succeeded, and its standard error.
fn wait(mut child: Child) -> (bool, String) {
    let mut err = child.stderr.take().expect("stderr");
    let text = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    let status = mission_tests::ended(child, Duration::from_secs(300));
    let text = text.join().unwrap_or_default();
    (status.is_some_and(|s| s.success()), text)
}

#[test]
fn the_ros2_definitions_describe_the_simulator_s_arm_and_excavation_exactly() {
    let config =
        executive_runtime::catalogues::read_connectors(&repo().join("deploy/ros2/connectors.toml"))
            .expect("the connectors file reads");
    let arm = config
        .connectors
        .iter()
        .find(|c| c.kind == connector_api::Kind::Ros2)
        .expect("a ROS 2 connector");
    let ros = connector_ros2::catalogue_of(arm).expect("the definitions read");
    let out = Command::new(bin("elap-sim"))
        .arg("--print-catalogue")
        .output()
        .expect("elap-sim runs");
    let sim: connector_api::Catalogue = serde_json::from_slice(&out.stdout).expect("catalogue");
    let routed: Vec<&str> = ros.actions.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(routed.len(), 7, "{routed:?}");
    for a in &ros.actions {
        let s = sim
            .action(&a.name)
            .unwrap_or_else(|| panic!("the simulator has no `{}`", a.name));
        assert_eq!(a.goal, s.goal, "{}: goal", a.name);
        let mut result = a.result.clone();
        assert!(result.remove("error_code").is_some(), "{}", a.name);
        assert_eq!(result, s.result, "{}: result", a.name);
        assert_eq!(
            a.errors.keys().collect::<Vec<_>>(),
            s.errors.keys().collect::<Vec<_>>(),
            "{}: error codes",
            a.name
        );
    }
    // Every arm and excavation activity of the simulator goes to ROS 2.
    for s in &sim.actions {
        let prefix = s.name.split('.').next().unwrap_or_default();
        assert_eq!(
            routed.contains(&s.name.as_str()),
            prefix == "arm" || prefix == "excavation",
            "{}",
            s.name
        );
    }
}

#[test]
fn rclpy_types_europa_msgs_as_trace_reads_it() {
    let mut python = Command::new("python3");
    sourced(&mut python, 0);
    let (messages, actions) =
        crate::ros2::agree_with_rclpy(&mut python, &overlay(), &["europa_msgs"]);
    assert_eq!((messages, actions), (2, 7));
}

#[test]
fn europa_recovers_a_tool_stuck_on_ros2_with_the_rest_on_zenoh() {
    let lines = fly(
        "ros2-europa-stuck",
        71,
        r#"{"faults": [{"action": "excavation.excavate", "call": 2, "code": "TOOL_STUCK"}]}"#,
    );
    let o = outcomes(&lines);
    // Arm and excavation ran on ROS 2 (the simulator serves them nowhere else), with their
    // results' fields; the error code came back in `error_code` and the boundary caught it.
    let unstow = o
        .iter()
        .find(|(r, k, _)| r == "arm.unstow" && k == "completed")
        .expect("the arm unstowed");
    assert_eq!(unstow.2["arm_state"], "unstowed", "{unstow:?}");
    let stuck = o
        .iter()
        .position(|(r, k, c)| r == "excavation.excavate" && k == "failed" && c == "TOOL_STUCK")
        .unwrap_or_else(|| panic!("the tool stuck: {o:#?}"));
    let unstick = o[stuck..]
        .iter()
        .position(|(r, k, _)| r == "excavation.unstick_tool" && k == "completed")
        .expect("unstick ran")
        + stuck;
    let dug = o[unstick..]
        .iter()
        .find(|(r, k, _)| r == "excavation.excavate" && k == "completed")
        .expect("the excavation retried and completed");
    assert!(dug.2["achieved_depth_cm"].as_f64().is_some(), "{dug:?}");
    // Feedback of the ROS 2 goals reached the record.
    assert!(
        lines
            .iter()
            .any(|l| l["kind"] == "feedback" && l["fields"]["percent"].is_number()),
        "no ROS 2 feedback recorded"
    );
    // The Zenoh side ran as it does without ROS 2: the same five analyses.
    let analyses = o
        .iter()
        .filter(|(r, k, _)| r == "instrument.analyze" && k == "completed")
        .count();
    assert_eq!(analyses, 5, "{o:#?}");
}

#[test]
fn europa_s_deadline_cancels_a_stalled_excavation_through_ros2() {
    let lines = fly(
        "ros2-europa-deadline",
        72,
        r#"{"faults": [{"action": "excavation.excavate", "call": 1, "code": "STALL"}]}"#,
    );
    let fired = lines
        .iter()
        .position(|v| v["kind"] == "caught" && v["element"]["id"] == "MissionDeadline")
        .expect("the mission deadline fired");
    // The stalled excavation was cancelled, never completed.
    let resources: std::collections::BTreeMap<&str, &str> = lines
        .iter()
        .filter(|v| v["kind"] == "dispatched")
        .filter_map(|v| Some((v["task"].as_str()?, v["resource"].as_str()?)))
        .collect();
    let cancelled = lines[fired..]
        .iter()
        .filter(|v| v["kind"] == "cancelled")
        .filter_map(|v| resources.get(v["task"].as_str()?).copied())
        .collect::<Vec<_>>();
    assert!(cancelled.contains(&"excavation.excavate"), "{cancelled:?}");
    let o = outcomes(&lines);
    assert!(
        !o.iter()
            .any(|(r, k, _)| r == "excavation.excavate" && k == "completed"),
        "{o:#?}"
    );
    let last = lines
        .iter()
        .rev()
        .find(|v| v["kind"] == "instance_finished")
        .expect("ended");
    assert_eq!(last["outcome"]["type"], "terminated");
}
