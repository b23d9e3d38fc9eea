//! The Europa BSM-1 mission end to end across separate processes over Zenoh: the executive
//! (`trace run`), the lander simulator (`elap-sim`) and a ground station answering by policy
//! (`ground-station --policy deploy/ground/policy.toml`), and the named fault scenarios flown with
//! `trace fly --scenario`, each checked from the execution record.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::Path;
use std::process::{Child, Command, Stdio};

use mission_tests::{bin, repo};

use crate::protocol::{endpoint, port, tempdir};

/// Starts a system process and waits for its `ready` line.
fn system(program: &str, args: &[&str]) -> Child {
    let mut child = Command::new(bin(program))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("system starts");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("ready line");
    assert!(line.starts_with("ready"), "{program}: {line}");
    child
}

/// The lander simulator (with `sim` flags) and a policy ground station on `hub`; both
/// are killed when this is dropped.
struct Systems(Child, Child);

impl Systems {
    fn start(hub: &str, sim: &[&str]) -> Systems {
        let mut args = sim.to_vec();
        args.extend(["-e", hub, "--no-multicast-scouting"]);
        let policy = repo().join("deploy/ground/policy.toml");
        let ground = [
            "--policy",
            policy.to_str().expect("path"),
            "-e",
            hub,
            "--no-multicast-scouting",
        ];
        Systems(system("elap-sim", &args), system("ground-station", &ground))
    }
}

impl Drop for Systems {
    fn drop(&mut self) {
        for c in [&mut self.0, &mut self.1] {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// `trace <verb>` (`run` or `resume`) on the Europa mission against `hub`, its store in `dir`.
fn executive(verb: &str, dir: &Path, hub: &str) -> Command {
    let mut c = Command::new(bin("trace"));
    c.arg(verb);
    if verb == "run" {
        c.arg(repo().join("deploy/missions/europa-bsm1.bpmn"));
    }
    c.arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(repo().join("deploy/connectors.toml"))
        .args(["-l", hub, "--no-multicast-scouting"]);
    c
}

struct Run {
    outcome: serde_json::Value,
    completed: BTreeMap<String, usize>,
    failed: Vec<(String, String)>,
    days: f64,
}

fn fly(dir: &Path, seed: &str, profile: &str) -> Run {
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let hub = endpoint(port());
    let sim_store = dir.join("sim");
    let systems = Systems::start(
        &hub,
        &[
            "--speed",
            "200000",
            "--seed",
            seed,
            "--profile",
            profile,
            "--start-ms",
            "1790000000000",
            "--store",
            sim_store.to_str().expect("path"),
        ],
    );
    let out = executive("run", dir, &hub).output().expect("trace runs");
    drop(systems);
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("store/record.jsonl")).expect("record");
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("record line"))
        .collect();
    let mut resource = BTreeMap::new();
    let mut completed = BTreeMap::new();
    let mut failed = Vec::new();
    for v in &lines {
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str() {
            Some("dispatched") => {
                resource.insert(task, v["resource"].as_str().unwrap_or_default().to_owned());
            }
            Some("completed") => *completed.entry(resource[&task].clone()).or_insert(0) += 1,
            Some("failed") => failed.push((
                resource[&task].clone(),
                v["code"].as_str().unwrap_or_default().to_owned(),
            )),
            _ => {}
        }
    }
    let first = lines
        .first()
        .and_then(|v| v["mission_ms"].as_i64())
        .unwrap_or(0);
    let last = lines
        .last()
        .and_then(|v| v["mission_ms"].as_i64())
        .unwrap_or(0);
    let outcome = lines
        .iter()
        .rev()
        .find(|v| v["kind"] == "instance_finished")
        .map(|v| v["outcome"].clone())
        .expect("the mission ended");
    Run {
        outcome,
        completed,
        failed,
        days: (last - first) as f64 / 86_400_000.0,
    }
}

#[test]
fn the_nominal_europa_mission_runs_across_processes_to_communicate_until_death() {
    let dir = tempdir("europa-nominal");
    let run = fly(&dir, "1", "quiet");
    // Five samples collected, transferred and analysed, then the data downlinked until the
    // battery is spent; the mission ends through Communicate Until Death's terminate end.
    assert_eq!(
        run.completed.get("instrument.analyze"),
        Some(&5),
        "{:?}",
        run.completed
    );
    assert_eq!(run.completed.get("sampling.collect_sample"), Some(&5));
    assert!(run.completed.get("comm.downlink").is_some_and(|n| *n > 0));
    assert_eq!(run.outcome["type"], "terminated", "{}", run.outcome);
    // Downlinks outside a window fail with NO_WINDOW and are handled by the model.
    assert!(
        run.failed
            .iter()
            .all(|(r, c)| r == "comm.downlink" && c == "NO_WINDOW"),
        "{:?}",
        run.failed
    );
    // About 19.5 days on an idle machine; the upper bound only rules out a runaway, since at
    // 200,000x every second a loaded machine holds a process back is 2.3 mission days.
    assert!(run.days > 10.0 && run.days < 30.0, "{} days", run.days);
}

#[test]
fn trace_fly_runs_the_mission_with_one_command_and_summarises_it() {
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempdir("europa-fly");
    let out = Command::new(bin("trace"))
        .current_dir(repo())
        .args(["fly", "--speed", "100000", "--profile", "quiet", "--dir"])
        .arg(dir.join("flight"))
        .args(["-l", &endpoint(port()), "--no-multicast-scouting"])
        .output()
        .expect("trace fly runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for line in [
        "phase: Excavate",
        "sample analysed (5 so far)",
        "mission summary",
        "outcome:           instance 1 Terminated",
        "samples analysed:  5",
        "execution record:",
        "timeline:",
    ] {
        assert!(stdout.contains(line), "missing {line:?} in:\n{stdout}");
    }
    // A second flight into the same directory is refused rather than mixed with the first.
    let again = Command::new(bin("trace"))
        .current_dir(repo())
        .args(["fly", "--dir"])
        .arg(dir.join("flight"))
        .output()
        .expect("trace fly runs");
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("already holds a flight"));
}

/// One flight at a time: mission time runs on the wall clock at a high speed, so a flight
/// competing for the CPU with another would see its lander age faster between steps.
pub(crate) static FLIGHT: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Flies a named scenario with `trace fly`; returns the record's lines.
fn scenario(name: &str) -> Vec<serde_json::Value> {
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempdir(&format!("scenario-{name}"));
    let out = Command::new(bin("trace"))
        .current_dir(repo())
        .args(["fly", "--speed", "100000", "--scenario", name, "--dir"])
        .arg(dir.join("flight"))
        .args(["-l", &endpoint(port()), "--no-multicast-scouting"])
        .output()
        .expect("trace fly runs");
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_to_string(dir.join("flight/store/record.jsonl"))
        .expect("record")
        .lines()
        .map(|l| serde_json::from_str(l).expect("record line"))
        .collect()
}

/// (resource, kind, code or output) of every task outcome, in order.
pub(crate) fn outcomes(lines: &[serde_json::Value]) -> Vec<(String, String, serde_json::Value)> {
    outcomes_from(lines, 0)
}

/// Task outcomes recorded from line `from` on (tasks may have been dispatched before it).
fn outcomes_from(
    lines: &[serde_json::Value],
    from: usize,
) -> Vec<(String, String, serde_json::Value)> {
    let mut resource = BTreeMap::new();
    let mut out = Vec::new();
    for (i, v) in lines.iter().enumerate() {
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str() {
            Some("dispatched") => {
                resource.insert(task, v["resource"].as_str().unwrap_or_default().to_owned());
            }
            Some(k @ ("completed" | "failed")) if i >= from => out.push((
                resource[&task].clone(),
                k.to_owned(),
                if k == "failed" {
                    v["code"].clone()
                } else {
                    v["output"].clone()
                },
            )),
            _ => {}
        }
    }
    out
}

fn count(o: &[(String, String, serde_json::Value)], resource: &str, kind: &str) -> usize {
    o.iter()
        .filter(|(r, k, _)| r == resource && k == kind)
        .count()
}

#[test]
fn scenario_stuck_tool_recovered() {
    let o = outcomes(&scenario("stuck-tool-recovered"));
    let stuck = o
        .iter()
        .position(|(r, k, c)| r == "excavation.excavate" && k == "failed" && c == "TOOL_STUCK")
        .expect("the tool stuck");
    // Causal order: stuck, then unstick, then the excavation retried and completed.
    let unstick = o[stuck..]
        .iter()
        .position(|(r, k, _)| r == "excavation.unstick_tool" && k == "completed")
        .expect("unstick ran")
        + stuck;
    assert!(
        o[unstick..]
            .iter()
            .any(|(r, k, _)| r == "excavation.excavate" && k == "completed")
    );
    assert_eq!(count(&o, "instrument.analyze", "completed"), 5);
}

#[test]
fn scenario_stuck_tool_abandoned_for_a_new_site() {
    let lines = scenario("stuck-tool-abandoned");
    let o = outcomes(&lines);
    assert_eq!(count(&o, "excavation.excavate", "failed"), 4);
    assert!(
        lines
            .iter()
            .any(|v| v["kind"] == "caught" && v["what"] == "escalation")
    );
    // The abandoned site is excluded: one more site selected than samples need.
    assert!(count(&o, "world_model.select_site", "completed") >= 4);
    assert_eq!(count(&o, "instrument.analyze", "completed"), 5);
}

#[test]
fn scenario_slump_repeats_the_removal() {
    let o = outcomes(&scenario("slump"));
    let slumped = o
        .iter()
        .position(|(r, _, out)| r == "excavation.assess_slump" && out["slump"]["detected"] == true)
        .expect("a slump was detected");
    // The next step of the excavation (the battery monitor runs alongside) is the removal again.
    let next = o[slumped + 1..]
        .iter()
        .find(|(r, _, _)| r.starts_with("excavation.") || r.starts_with("arm."))
        .expect("the excavation went on");
    assert_eq!(next.0, "excavation.excavate", "{next:?}");
    assert_eq!(count(&o, "instrument.analyze", "completed"), 5);
}

#[test]
fn scenario_battery_abort_leads_to_communicate_until_death() {
    let lines = scenario("battery-abort");
    let thrown = lines
        .iter()
        .position(|v| {
            v["kind"] == "thrown" && v["what"] == "signal" && v["name"] == "BATTERY_LOW_ABORT"
        })
        .expect("the battery monitor aborted");
    let o = outcomes_from(&lines, thrown);
    // After the abort: no more science, only communication and battery readings.
    assert!(
        o.iter().all(|(r, _, _)| r.starts_with("comm.")
            || r.starts_with("data.")
            || r.starts_with("power.")),
        "{o:?}"
    );
    assert!(count(&outcomes(&lines), "instrument.analyze", "completed") < 5);
    let last = lines
        .iter()
        .rev()
        .find(|v| v["kind"] == "instance_finished")
        .expect("ended");
    assert_eq!(last["outcome"]["type"], "terminated");
}

#[test]
fn scenario_executive_killed_mid_excavation_and_restarted() {
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempdir("europa-reboot");
    let hub = endpoint(port());
    let sim_store = dir.join("sim");
    let systems = Systems::start(
        &hub,
        &[
            "--speed",
            "100000",
            "--profile",
            "quiet",
            "--start-ms",
            "1790000000000",
            "--store",
            sim_store.to_str().expect("path"),
        ],
    );
    let exec = |verb: &str| {
        let mut c = executive(verb, &dir, &hub);
        c.stdout(Stdio::null()).stderr(Stdio::null());
        c
    };
    let record = dir.join("store/record.jsonl");
    let mut first = exec("run").spawn().expect("executive starts");
    let excavating = crate::durability::until_record(&mut first, &record, |text| {
        text.contains(r#""resource":"excavation.excavate""#)
    });
    assert!(excavating, "the executive ended before excavating");
    first.kill().expect("kill -9");
    first.wait().expect("reaped");
    let before = std::fs::read_to_string(&record).expect("record");
    let in_flight: Vec<String> = before
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["kind"] == "dispatched" && v["resource"] == "excavation.excavate")
        .filter_map(|v| v["task"].as_str().map(str::to_owned))
        .collect();
    let status = exec("resume").status().expect("executive resumes");
    drop(systems);
    assert!(status.success());
    // A line written again after the kill repeats its (seq, idx): readers keep the first.
    let mut seen = std::collections::BTreeSet::new();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&record)
        .expect("record")
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("line"))
        .filter(|v| {
            v["seq"].is_null() || seen.insert((v["seq"].clone().to_string(), v["idx"].to_string()))
        })
        .collect();
    assert!(lines.iter().any(|v| v["kind"] == "reboot"));
    // The excavation in flight at the kill ended exactly once: reconciled, not lost or repeated.
    for task in &in_flight {
        let ends = lines
            .iter()
            .filter(|v| {
                v["task"] == task.as_str() && (v["kind"] == "completed" || v["kind"] == "failed")
            })
            .count();
        assert_eq!(ends, 1, "task {task} ended {ends} times");
    }
    let o = outcomes(&lines);
    assert_eq!(count(&o, "instrument.analyze", "completed"), 5);
    assert!(o.iter().all(|(_, _, c)| c != "CONNECTOR_LOST"), "{o:?}");
}

#[test]
fn scenario_deadline_cancels_the_excavation_in_flight() {
    let lines = scenario("deadline");
    let fired = lines
        .iter()
        .position(|v| v["kind"] == "caught" && v["element"]["id"] == "MissionDeadline")
        .expect("the mission deadline fired");
    // The stalled excavation was cancelled by the interrupting deadline, never completed.
    let cancelled: Vec<&str> = lines[fired..]
        .iter()
        .filter(|v| v["kind"] == "cancelled")
        .filter_map(|v| v["task"].as_str())
        .collect();
    assert!(!cancelled.is_empty(), "no task cancelled at the deadline");
    let resources: BTreeMap<&str, &str> = lines
        .iter()
        .filter(|v| v["kind"] == "dispatched")
        .filter_map(|v| Some((v["task"].as_str()?, v["resource"].as_str()?)))
        .collect();
    assert!(
        cancelled
            .iter()
            .any(|t| resources.get(t) == Some(&"excavation.excavate")),
        "{cancelled:?}"
    );
    let after = outcomes_from(&lines, fired);
    assert!(
        after.iter().all(|(r, _, _)| !r.starts_with("excavation.")),
        "{after:?}"
    );
    let last = lines
        .iter()
        .rev()
        .find(|v| v["kind"] == "instance_finished")
        .expect("ended");
    assert_eq!(last["outcome"]["type"], "terminated");
}

#[test]
fn a_monitor_started_mid_mission_starts_from_the_present() {
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempdir("europa-monitor");
    let hub = endpoint(port());
    let systems = Systems::start(&hub, &["--speed", "100000", "--profile", "quiet"]);
    let record = dir.join("store/record.jsonl");
    let mut exec = executive("run", &dir, &hub)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("executive starts");
    let mid = crate::durability::until_record(&mut exec, &record, |t| {
        t.contains(r#""resource":"instrument.analyze""#)
    });
    assert!(mid, "the mission ended before the monitor joined");
    let joined_at = std::fs::read_to_string(&record)
        .expect("record")
        .lines()
        .count();
    let out = Command::new(bin("trace"))
        .args([
            "monitor",
            "--jsonl",
            "--lines",
            "5",
            "-e",
            &hub,
            "--no-multicast-scouting",
        ])
        .output()
        .expect("monitor runs");
    let _ = (exec.kill(), exec.wait());
    drop(systems);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("monitor prints JSON Lines"))
        .collect();
    assert_eq!(lines.len(), 6, "a snapshot and five record lines");
    let snap = &lines[0]["state"];
    assert_eq!(lines[0]["kind"], "snapshot");
    assert!(
        snap["mission"]
            .as_str()
            .is_some_and(|m| m.starts_with("europa-bsm1-"))
    );
    // The present: at least as far as the record was when the monitor joined, with tokens in
    // the science phase.
    let seq0 = snap["seq"].as_u64().expect("seq");
    let record_now: Vec<serde_json::Value> = std::fs::read_to_string(&record)
        .expect("record")
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let seq_at_join = record_now[..joined_at.min(record_now.len())]
        .iter()
        .filter_map(|v| v["seq"].as_u64())
        .max()
        .unwrap_or(0);
    assert!(
        seq0 >= seq_at_join,
        "snapshot at {seq0}, record at {seq_at_join}"
    );
    assert!(snap["tokens"].as_object().is_some_and(|t| !t.is_empty()));
    // What follows is the record itself, after the snapshot.
    for l in &lines[1..] {
        if let Some(s) = l["seq"].as_u64() {
            assert!(s > seq0);
        }
        assert!(record_now.contains(l), "not in the record: {l}");
    }
}
