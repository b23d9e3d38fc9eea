//! Crash anywhere: each finding of the crash matrix as a test — a goal the system never
//! acknowledged before the executive was killed is sent again on resume (not declared lost),
//! and a simulator killed mid-activity carries the activity on when restarted, its mission
//! clock never going back — and the crash matrix, reduced: Europa with two kills of each kind
//! ends as the uninterrupted flight does.

use std::path::Path;
use std::process::{Child, Command, Stdio};

use mission_tests::{bin, records};
use serde_json::json;

use crate::durability::until_record;
use crate::protocol::{command, connector, endpoint, expect, mock_process, open, port, tempdir};

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

/// `elap-sim` connecting to `hub`, keeping its world and goals in `store`; returns once it
/// serves (its session is connected by then, so nothing it publishes afterwards is lost).
fn simulator(hub: &str, store: &Path) -> Child {
    use std::io::BufRead;
    let mut child = Command::new(bin("elap-sim"))
        .args(["--speed", "1000", "--profile", "quiet", "--seed", "1"])
        .arg("--store")
        .arg(store)
        .args(["-e", hub, "--no-multicast-scouting"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("elap-sim starts");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("ready line");
    assert!(line.starts_with("ready"), "{line}");
    child
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_simulator_carries_its_activity_on_and_its_clock_never_goes_back() {
    use connector_api::{Connector, Report};
    let dir = tempdir("crash-simulator");
    // The test is the hub: the simulator connects to it, so a restarted simulator is heard
    // from its first message on.
    let hub = endpoint(port());
    let session = open(std::slice::from_ref(&hub), &[]).await;
    let store = dir.join("sim");
    let mut sim = simulator(&hub, &store);
    // The simulator's mission clock, as it reports it.
    let (clock_tx, mut clock) = tokio::sync::mpsc::unbounded_channel::<i64>();
    let _clock = session
        .declare_subscriber(connector_api::Keys::default().telemetry("lander_sim", "clock"))
        .callback(move |s| {
            let t: serde_json::Value =
                serde_json::from_slice(&s.payload().to_bytes()).unwrap_or_default();
            if let Some(ms) = t["mission_ms"].as_i64() {
                let _ = clock_tx.send(ms);
            }
        })
        .await
        .expect("clock subscriber");
    let (mut c, mut rx) = connector(&session, "lander_sim", 60_000).await;
    // One mission hour of seismometer recording: 3.6 s of wall time, feedback every quarter.
    c.execute(command(
        "m.1.1.1",
        "seismometer.record",
        json!({"duration_s": 3600}),
    ));
    let progress = |r: &Report| match r {
        Report::Feedback { progress_pct, .. } => *progress_pct,
        _ => None,
    };
    let first = expect(&mut rx, |r| progress(r).is_some()).await;
    assert_eq!(progress(&first), Some(25.0));
    // Killed a quarter of the way through; what its clock said last.
    let _ = (sim.kill(), sim.wait());
    let mut before = 0;
    while let Ok(ms) = clock.try_recv() {
        before = before.max(ms);
    }
    let mut sim = simulator(&hub, &store);
    let after = tokio::time::timeout(std::time::Duration::from_secs(30), clock.recv())
        .await
        .expect("the restarted simulator reports its clock")
        .expect("clock reports");
    // Before, the clock went back to the last periodic save (up to an hour of mission time).
    assert!(
        after >= before,
        "the clock went back {} ms across the restart",
        before - after
    );
    // The recording carries on from where it was: its progress never starts over, and it
    // ends once.
    let mut seen = Vec::new();
    let outcome = loop {
        match expect(&mut rx, |r| {
            matches!(
                r,
                Report::Feedback { .. } | Report::Done { .. } | Report::Failed { .. }
            )
        })
        .await
        {
            r @ Report::Feedback { .. } => seen.extend(progress(&r)),
            r => break r,
        }
    };
    let _ = (sim.kill(), sim.wait());
    assert!(matches!(outcome, Report::Done { .. }), "{outcome:?}");
    assert!(
        seen.iter().all(|p| *p > 25.0),
        "restarted from the beginning: {seen:?}"
    );
    c.close().await;
}

#[test]
fn the_crash_matrix_reduced_loses_nothing_repeats_nothing_and_never_sticks() {
    reduced_matrix(mission_tests::matrix::Layout::Loopback);
}

/// Europa with two kills of each kind of `layout` ends as the uninterrupted flight does (with
/// as many samples analysed, except after kills that leave the lander without its simulator or
/// a router), losing and repeating nothing.
pub(crate) fn reduced_matrix(layout: mission_tests::matrix::Layout) {
    use mission_tests::matrix::{self, Layout, Tally, Victim};
    let root = tempdir(&format!("crash-matrix-{layout:?}"));
    let bound = std::time::Duration::from_secs(240);
    let reference = matrix::fly(
        &root.join("reference"),
        layout,
        1,
        Victim::Executive,
        0,
        bound,
    );
    // Europa ends by its terminate end event once its samples are analysed.
    assert!(
        reference.outcome.is_some() && reference.analysed == 5,
        "the uninterrupted flight: {reference:?}"
    );
    let kinds = match layout {
        Layout::Loopback => &Victim::ALL[..],
        Layout::Hosts => &Victim::ACROSS_HOSTS[..],
    };
    for &victim in kinds {
        let f = matrix::fly(
            &root.join(format!("{victim:?}")),
            layout,
            1,
            victim,
            2,
            bound,
        );
        let mut tally = Tally::default();
        tally.add(&f, &reference);
        assert!(f.kills >= 1, "{}: no kill was made: {f:?}", victim.name());
        // A lander without its simulator, or a router down, for the second a restart takes is
        // over a mission day at this speed: approvals time out, the deadline comes sooner. The
        // same end, not necessarily as many samples (docs/benchmarks.md, the crash matrix).
        let alike = match victim {
            Victim::Executive | Victim::Ground => tally.same,
            Victim::Simulator | Victim::Both | Victim::LanderRouter | Victim::GroundRouter => {
                tally.ended
            }
        };
        assert_eq!(
            (alike, tally.stuck, tally.lost, tally.duplicated),
            (1, 0, 0, 0),
            "{}: {f:?} against {reference:?}",
            victim.name()
        );
    }
}
