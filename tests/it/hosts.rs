//! Lander and ground on separate hosts (network namespaces made by the test, joined by veth
//! links) through two `trace router`s with QUIC, mutual TLS and access control by certificate:
//! the Europa mission flown (with one station, and with two stations on two ground hosts
//! racing), every operation a role may not do refused, a client without the deployment's
//! certificate kept out, a user task answered across a link cut for an hour of mission time,
//! a cut with goals in flight unnoticed on the lander and a late monitor given the present,
//! seconds of latency on a narrow link, the crash matrix with router kills on either side, and
//! TRACE Studio on the ground following the mission on the lander (with the monitor's
//! certificate: its list, model, present and timeline, nothing refused). A station's flood is
//! in `flood.rs`.

use std::time::Duration;

use mission_tests::hosts::Lab;
use mission_tests::{records, repo};

const REFUSAL: &str = connector_zenoh::router::REFUSAL;

fn path(rel: &str) -> String {
    repo().join(rel).to_string_lossy().into_owned()
}

/// Europa on the lander (simulator at 200,000x, executive) with a policy station on each of
/// `stations` ground hosts; returns the lab once the executive has ended, and its record.
fn fly_europa(name: &str, stations: &[&str]) -> (Lab, Vec<serde_json::Value>) {
    // One flight at a time: two at 200,000x would bend each other's clocks.
    static FLIGHT: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = FLIGHT.lock().unwrap_or_else(|p| p.into_inner());
    let mut lab = Lab::new(name, stations.len());
    lab.routers();
    start_europa(&mut lab, "200000", stations);
    let status = lab.proc("executive").child.wait().expect("executive exits");
    assert!(
        status.success(),
        "executive: {status}\n{}",
        lab.log("executive")
    );
    let lines = records(&lab.dir.join("store/record.jsonl"));
    (lab, lines)
}

#[test]
fn europa_flies_across_two_hosts_through_routers_with_mutual_tls_and_access_control() {
    let (lab, lines) = fly_europa("europa", &["station-a"]);
    // Communicate Until Death's terminate end, samples analysed, every task ended once, none
    // lost to a vanished connection.
    let end = lines
        .iter()
        .rev()
        .find(|l| l["kind"] == "instance_finished")
        .expect("the mission ended");
    assert_eq!(end["outcome"]["type"], "terminated", "{end}");
    let analyze: std::collections::BTreeSet<_> = lines
        .iter()
        .filter(|l| l["kind"] == "dispatched" && l["resource"] == "instrument.analyze")
        .map(|l| l["task"].to_string())
        .collect();
    let analysed = lines
        .iter()
        .filter(|l| l["kind"] == "completed" && analyze.contains(&l["task"].to_string()))
        .count();
    // Five when every approval comes in time; at 200,000x an approval's six hours are 0.1 s
    // of wall time, and a site whose approval times out is skipped.
    assert!(analysed >= 1, "no sample analysed");
    let mut ended = std::collections::BTreeMap::new();
    for l in &lines {
        if matches!(
            l["kind"].as_str(),
            Some("completed" | "failed" | "user_task_answered")
        ) {
            assert_ne!(l["code"], "CONNECTOR_LOST", "{l}");
            let n = ended
                .entry((l["task"].to_string(), l["kind"].to_string()))
                .or_insert(0);
            *n += 1;
            assert_eq!(*n, 1, "ended twice: {l}");
        }
    }
    // User tasks crossed the link: the station on the ground answered them.
    assert!(
        lines.iter().any(|l| l["kind"] == "user_task_answered"
            && l["operator"]
                .as_str()
                .is_some_and(|o| o.ends_with("@station-a"))),
        "no user task answered from the ground"
    );
    // The flight needed nothing the access control forbids.
    for router in ["lander-router", "ground-router1"] {
        let log = lab.log(router);
        assert!(!log.contains(REFUSAL), "{router} refused something:\n{log}");
    }
}

/// A ground station with certificate `cert` on ground host `k`, answering by `policy`.
pub(crate) fn station_with(lab: &mut Lab, k: usize, cert: &str, policy: &str) {
    let mut args = Lab::client_flags("station.json5", cert);
    args.extend(["--station", cert, "--policy", policy].map(str::to_owned));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let c = lab.command(&lab.grounds[k - 1].clone(), "ground-station", &args);
    lab.start(cert, c);
}

#[test]
fn two_stations_on_two_ground_hosts_race_and_each_answer_is_applied_once() {
    let (lab, lines) = fly_europa("race", &["station-a", "station-b"]);
    let end = lines
        .iter()
        .rev()
        .find(|l| l["kind"] == "instance_finished")
        .expect("the mission ended");
    assert_eq!(end["outcome"]["type"], "terminated", "{end}");
    let answered = lines
        .iter()
        .filter(|l| l["kind"] == "user_task_answered")
        .count();
    assert!(answered >= 1, "no approval answered");
    // Each approval was applied for exactly one of the two stations; the other was told.
    let applied: usize = ["station-a", "station-b"]
        .iter()
        .map(|s| lab.output(s).matches("answered: applied").count())
        .sum();
    assert_eq!(
        applied,
        answered,
        "{}\n{}",
        lab.output("station-a"),
        lab.output("station-b")
    );
    let mut tasks = std::collections::BTreeSet::new();
    for l in lines.iter().filter(|l| l["kind"] == "user_task_answered") {
        assert!(tasks.insert(l["task"].to_string()), "answered twice: {l}");
    }
}

/// What one forbidden operation is: who tries it from where, and which router refuses it.
struct Forbidden {
    what: &'static str,
    ground: bool,
    cert: &'static str,
    op: &'static str,
    key: &'static str,
    refused_by: &'static str,
}

pub(crate) const WAIT: Duration = Duration::from_secs(20);

#[test]
fn every_operation_a_role_may_not_do_is_refused_by_the_routers_and_never_delivered() {
    let mut lab = Lab::new("acl", 1);
    lab.routers();
    let (lander, ground) = (lab.lander.clone(), lab.grounds[0].clone());
    // The honest side: the executive hears everything and serves the answers; the lander
    // simulator serves its actions; a station serves the user tasks.
    lab.start_probe("exec-sub", &lander, "exec", &["sub", "trace/d/**"]);
    lab.start_probe(
        "exec-answers",
        &lander,
        "exec",
        &["queryable", "trace/d/act/ground/*/answer/*"],
    );
    lab.start_probe(
        "exec-alive",
        &lander,
        "exec",
        &["alive", "trace/d/alive/**"],
    );
    lab.start_probe(
        "sim-serves",
        &lander,
        "lander_sim",
        &["queryable", "trace/d/act/lander_sim/**"],
    );
    lab.start_probe(
        "station-serves",
        &ground,
        "station-a",
        &["queryable", "trace/d/act/ground/*/goal/*"],
    );
    // The routers have propagated every declaration once an allowed query reaches its server:
    // the executive's goal to the simulator, and a station's answer to the executive.
    for (ns, cert, key, server) in [
        (
            &lander,
            "exec",
            "trace/d/act/lander_sim/drill/goal/m.1.1.1",
            "sim-serves",
        ),
        (
            &ground,
            "station-a",
            "trace/d/act/ground/approve/answer/m.1.1.1",
            "exec-answers",
        ),
        (
            &lander,
            "exec",
            "trace/d/act/ground/approve/goal/m.1.1.1",
            "station-serves",
        ),
    ] {
        let out = lab
            .probe(ns, cert, &["get", key, "{}"])
            .output()
            .expect("probe");
        let out = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.contains(&format!("reply ok {key} probe")),
            "{cert} {key}: {out}"
        );
        lab.until_said(server, &["query", key], WAIT);
    }

    let forbidden = [
        Forbidden {
            what: "a station sends a goal to a system",
            ground: true,
            cert: "station-a",
            op: "get",
            key: "trace/d/act/lander_sim/drill/goal/m.1.9.1",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a station cancels a system's goal",
            ground: true,
            cert: "station-a",
            op: "get",
            key: "trace/d/act/lander_sim/drill/cancel/m.1.1.1",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a station publishes the clock",
            ground: true,
            cert: "station-a",
            op: "put",
            key: "trace/d/tm/lander_sim/clock",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a station publishes a system's result",
            ground: true,
            cert: "station-a",
            op: "put",
            key: "trace/d/act/lander_sim/drill/result",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a station spoofs a system's presence",
            ground: true,
            cert: "station-a",
            op: "token",
            key: "trace/d/alive/act/lander_sim/drill",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a monitor answers a user task",
            ground: true,
            cert: "monitor",
            op: "get",
            key: "trace/d/act/ground/approve/answer/m.1.1.1",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a monitor serves user tasks",
            ground: true,
            cert: "monitor",
            op: "queryable",
            key: "trace/d/act/ground/*/goal/*",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a monitor publishes a record line",
            ground: true,
            cert: "monitor",
            op: "put",
            key: "trace/d/exec/m/record",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "an unknown certificate publishes telemetry",
            ground: true,
            cert: "intruder",
            op: "put",
            key: "trace/d/tm/lander_sim/battery",
            refused_by: "ground-router1",
        },
        Forbidden {
            what: "a system sends a user task",
            ground: false,
            cert: "lander_sim",
            op: "get",
            key: "trace/d/act/ground/approve/goal/m.1.9.1",
            refused_by: "lander-router",
        },
        Forbidden {
            what: "a system publishes under another system's keys",
            ground: false,
            cert: "lander_sim",
            op: "put",
            key: "trace/d/act/camera/snap/result",
            refused_by: "lander-router",
        },
        Forbidden {
            what: "a system publishes a user task's result",
            ground: false,
            cert: "lander_sim",
            op: "put",
            key: "trace/d/act/ground/approve/result",
            refused_by: "lander-router",
        },
        Forbidden {
            what: "a system that is not the clock's source publishes the clock",
            ground: false,
            cert: "camera",
            op: "put",
            key: "trace/d/tm/camera/clock",
            refused_by: "lander-router",
        },
    ];
    for (i, f) in forbidden.iter().enumerate() {
        let ns = if f.ground { &ground } else { &lander };
        let payload = format!("forbidden-{i}");
        let name = format!("forbidden-{i}");
        let mut c = lab.probe(ns, f.cert, &[f.op, f.key, &payload]);
        if f.op == "get" {
            let out = c.output().expect("probe runs");
            let out = String::from_utf8_lossy(&out.stdout);
            assert!(!out.contains("reply ok"), "{}: answered: {out}", f.what);
        } else {
            lab.start(&name, c);
        }
        // An unknown certificate matches no subject: Zenoh says so once, at its connection.
        let needle = if f.cert == "intruder" {
            "did not match"
        } else {
            f.key
        };
        lab.until_logged(f.refused_by, &[REFUSAL, needle], WAIT);
        eprintln!("refused as it must be: {}", f.what);
    }
    // What access control refused to let a station declare, undeclared by it: refused again,
    // naming its certificate, and no error of the router's own.
    let refused_key = "trace/d/act/lander_sim/drill/goal/undeclared";
    lab.start_probe(
        "undeclares",
        &ground,
        "station-a",
        &["undeclare", refused_key],
    );
    lab.until_said("undeclares", &["undeclared"], WAIT);
    lab.until_logged("ground-router1", &[REFUSAL, "station-a", refused_key], WAIT);
    // The same kinds of operation by the roles that may do them are delivered, after the
    // forbidden ones: what the executive heard by then is all it will hear of those.
    for (ns, cert, key) in [
        (&lander, "lander_sim", "trace/d/act/lander_sim/drill/result"),
        (&lander, "lander_sim", "trace/d/tm/lander_sim/clock"),
        (&lander, "camera", "trace/d/tm/camera/temperature"),
        (&ground, "station-a", "trace/d/act/ground/approve/result"),
    ] {
        let name = format!("allowed-{cert}-{}", key.replace('/', "_"));
        lab.start_probe(&name, ns, cert, &["put", key, "allowed"]);
        lab.until_said("exec-sub", &["sample", key, "allowed"], WAIT);
    }
    lab.start_probe(
        "allowed-token",
        &ground,
        "station-a",
        &["token", "trace/d/alive/ground/station-a"],
    );
    lab.until_said(
        "exec-alive",
        &["alive trace/d/alive/ground/station-a"],
        WAIT,
    );
    let heard = lab.output("exec-sub") + &lab.output("exec-alive") + &lab.output("exec-answers");
    assert!(
        !heard.contains("forbidden"),
        "the executive heard:\n{heard}"
    );
    assert!(
        !heard.contains("lander_sim/drill\n"),
        "a spoofed token arrived:\n{heard}"
    );
    let served = lab.output("sim-serves") + &lab.output("station-serves");
    assert!(
        !served.contains("m.1.9.1"),
        "a forbidden goal was served:\n{served}"
    );
    assert!(
        !served.contains("cancel"),
        "a forbidden cancel was served:\n{served}"
    );
    // Every refusal names the certificate (but the intruder's, whom no subject names), and
    // nothing a client did made an error line.
    for router in ["lander-router", "ground-router1"] {
        let log = lab.log(router);
        for l in log.lines().filter(|l| l.contains(REFUSAL)) {
            assert!(
                l.contains("CertCommonName(") || l.contains("did not match"),
                "{router}: a refusal without its certificate: {l}"
            );
        }
        assert!(
            !log.lines()
                .any(|l| l.contains(" ERROR ") && l.contains("routing::hat")),
            "{router} logged a routing error a client caused:\n{log}"
        );
    }
}

#[test]
fn a_client_without_a_certificate_of_the_deployment_cannot_connect() {
    let mut lab = Lab::new("mtls", 1);
    lab.routers();
    let ground = lab.grounds[0].clone();
    // Its own authority: a certificate the deployment never issued.
    let other = lab.dir.join("other");
    let out = std::process::Command::new(repo().join("deploy/certs.sh"))
        .arg(&other)
        .arg("station-a")
        .output()
        .expect("certs.sh");
    assert!(out.status.success());
    let other_cert = "transport/link/tls/connect_certificate=\"other/station-a.pem\"";
    let other_key = "transport/link/tls/connect_private_key=\"other/station-a.key\"";
    for (what, sets) in [
        (
            "no certificate",
            vec!["transport/link/tls/enable_mtls=false"],
        ),
        (
            "a certificate of another authority",
            vec![other_cert, other_key],
        ),
    ] {
        // A station's flags with the certificate taken away or replaced, giving up after 3 s.
        let mut args = vec![
            "--zenoh-set",
            r#"connect/timeout_ms={"client": 3000, "peer": 3000, "router": 3000}"#,
        ];
        for set in sets {
            args.extend(["--zenoh-set", set]);
        }
        args.extend(["put", "trace/d/tm/lander_sim/clock", "x"]);
        let out = lab
            .probe(&ground, "station-a", &args)
            .output()
            .expect("probe runs");
        let text = String::from_utf8_lossy(&out.stdout);
        // Refused by the router, not by a mistake in the probe's own configuration.
        assert!(
            !out.status.success() && text.contains("error") && !text.contains("configuration"),
            "{what}: {text}"
        );
    }
    // The router says plainly that it refused them at the handshake, and why, without Zenoh's
    // hint about the open-file limit.
    let line = lab.until_logged(
        "ground-router1",
        &[connector_zenoh::router::HANDSHAKE],
        WAIT,
    );
    assert!(!line.contains("open file limit"), "{line}");
    assert!(
        !lab.log("ground-router1").contains("Hint: increase"),
        "{}",
        lab.log("ground-router1")
    );
}

/// A policy that approves every site after `delay_ms` (wall time), written into the lab.
pub(crate) fn slow_policy(lab: &Lab, delay_ms: u64) -> String {
    let file = lab.dir.join("slow-policy.toml");
    std::fs::write(
        &file,
        format!(
            "operator = \"policy\"\n[task.\"ground.approve_site\"]\ndelay_ms = {delay_ms}\n\
             fixed = {{ approve = true, comment = \"given while the link was cut\" }}\n"
        ),
    )
    .expect("policy");
    file.to_string_lossy().into_owned()
}

const HOUR_MS: i64 = 3_600_000;

/// A ground decision alone: Europa's site approval (same resource, form and PT6H timer).
const APPROVAL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="Approval" targetNamespace="urn:trace:tests">
  <bpmn:process id="Approve" isExecutable="true">
    <bpmn:startEvent id="Start"><bpmn:outgoing>f1</bpmn:outgoing></bpmn:startEvent>
    <bpmn:userTask id="ApproveSite" name="Approve Excavation Site">
      <bpmn:incoming>f1</bpmn:incoming><bpmn:outgoing>f2</bpmn:outgoing>
      <bpmn:extensionElements>
        <trace:task resource="ground.approve_site">
          <trace:input target="candidates" source='[{"site_id": 3, "score": 0.9, "material": "ice"}]' type="json"/>
          <trace:output source="approve" target="site_approved" type="bool"/>
        </trace:task>
      </bpmn:extensionElements>
    </bpmn:userTask>
    <bpmn:boundaryEvent id="ApprovalTimeout" attachedToRef="ApproveSite">
      <bpmn:outgoing>f3</bpmn:outgoing>
      <bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">PT6H</bpmn:timeDuration></bpmn:timerEventDefinition>
    </bpmn:boundaryEvent>
    <bpmn:endEvent id="Approved"><bpmn:incoming>f2</bpmn:incoming></bpmn:endEvent>
    <bpmn:endEvent id="TimedOut"><bpmn:incoming>f3</bpmn:incoming></bpmn:endEvent>
    <bpmn:sequenceFlow id="f1" sourceRef="Start" targetRef="ApproveSite"/>
    <bpmn:sequenceFlow id="f2" sourceRef="ApproveSite" targetRef="Approved"/>
    <bpmn:sequenceFlow id="f3" sourceRef="ApprovalTimeout" targetRef="TimedOut"/>
  </bpmn:process>
</bpmn:definitions>
"#;

/// The ground connector of `deploy/connectors.toml` alone.
const GROUND_ONLY: &str = r#"[[connector]]
name = "ground"
kind = "zenoh"
server = "ground"
resources = ["ground.*"]
answers = true
grace_ms = 600000
"#;

/// Starts the executive on the lander with [`APPROVAL`] and [`GROUND_ONLY`] at 300x (an hour
/// of mission time is 12 s of wall time; the approval's six hours 72 s).
pub(crate) fn run_approval(lab: &mut Lab) {
    std::fs::write(lab.dir.join("approval.bpmn"), APPROVAL).expect("mission");
    std::fs::write(lab.dir.join("ground.toml"), GROUND_ONLY).expect("connectors");
    let exec = lab.command(
        &lab.lander,
        "trace",
        &[
            "run",
            "approval.bpmn",
            "--store",
            "store",
            "--connectors",
            "ground.toml",
            "--speed",
            "300",
            "--zenoh-config",
            &Lab::config("executive.json5"),
        ],
    );
    lab.spawn("executive", exec);
}

#[test]
fn an_answer_given_while_the_link_is_cut_is_applied_once_when_the_link_returns_an_hour_later() {
    let mut lab = Lab::new("cut-answer", 1);
    lab.routers();
    let policy = slow_policy(&lab, 1500);
    station_with(&mut lab, 1, "station-a", &policy);
    // 300x: an hour of mission time is 12 s, longer than Zenoh's 10 s lease, so the routers'
    // link is declared dead and opened again; the approval's timer (PT6H) is 72 s away.
    run_approval(&mut lab);
    let record = lab.dir.join("store/record.jsonl");
    let (open, _) = lab.until_recorded(&record, "the approval opened", WAIT, |l| {
        l["kind"] == "user_task_opened"
    });
    let task = open["task"].as_str().expect("task key").to_owned();
    // The station has the task on its desk; the link goes before its answer (1.5 s later).
    lab.until_said("station-a", &["task", "open"], WAIT);
    lab.link(1, false);
    let cut_ms = open["mission_ms"].as_i64().expect("mission time");
    lab.until_said("station-a", &["answer pending"], WAIT);
    // The link stays down for an hour of mission time: this wait is the fault's length, not a
    // synchronisation (the assertion below checks the hour on the mission clock).
    std::thread::sleep(Duration::from_millis(12_500));
    lab.link(1, true);
    let (answered, _) = lab.until_recorded(
        &record,
        "the answer applied",
        Duration::from_secs(60),
        |l| l["kind"] == "user_task_answered" && l["task"] == task.as_str(),
    );
    assert_eq!(answered["operator"], "policy@station-a", "{answered}");
    let after = answered["mission_ms"].as_i64().expect("mission time") - cut_ms;
    assert!(after >= HOUR_MS, "applied {after} ms after the cut");
    lab.until_said("station-a", &["answered: applied"], WAIT);
    // Applied once; the approval's own end, not its timer or a lost connection.
    approval_answered_once(&mut lab);
}

/// Waits for [`run_approval`]'s executive to end, and checks that the approval went as with no
/// trouble: answered once, no timer fired, no connection lost, the instance completed. The
/// record, and how long (mission ms) the answer took after the task opened.
pub(crate) fn approval_answered_once(lab: &mut Lab) -> (Vec<serde_json::Value>, i64) {
    let status = lab.proc("executive").child.wait().expect("executive exits");
    assert!(
        status.success(),
        "executive: {status}\n{}",
        lab.log("executive")
    );
    let lines = records(&lab.dir.join("store/record.jsonl"));
    let opened = lines
        .iter()
        .find(|l| l["kind"] == "user_task_opened")
        .expect("opened");
    let answered: Vec<_> = lines
        .iter()
        .filter(|l| l["kind"] == "user_task_answered")
        .collect();
    assert_eq!(answered.len(), 1, "{lines:#?}");
    let took = answered[0]["mission_ms"].as_i64().expect("ms")
        - opened["mission_ms"].as_i64().expect("ms");
    for l in &lines {
        assert_ne!(l["code"], "CONNECTOR_LOST", "{l}");
        assert_ne!(l["kind"], "timer_fired", "{l}");
    }
    let end = lines
        .iter()
        .rev()
        .find(|l| l["kind"] == "instance_finished")
        .expect("ended");
    assert_eq!(end["outcome"]["type"], "completed", "{end}");
    (lines, took)
}

/// Europa on the lander at `speed` (the simulator's, on its store `sim`) with a policy
/// station on each of `stations` ground hosts; returns once the executive is running (its
/// record file path).
fn start_europa(lab: &mut Lab, speed: &str, stations: &[&str]) -> std::path::PathBuf {
    let sim = lab.command(
        &lab.lander.clone(),
        "elap-sim",
        &[
            "--zenoh-config",
            &Lab::config("lander_sim.json5"),
            "--speed",
            speed,
            "--seed",
            "1",
            "--profile",
            "quiet",
            "--start-ms",
            "1790000000000",
            "--store",
            "sim",
        ],
    );
    lab.start("lander_sim", sim);
    for (k, station) in stations.iter().enumerate() {
        station_with(lab, k + 1, station, &path("deploy/ground/policy.toml"));
    }
    let exec = lab.command(
        &lab.lander,
        "trace",
        &[
            "run",
            &path("deploy/missions/europa-bsm1.bpmn"),
            "--store",
            "store",
            "--connectors",
            &path("deploy/connectors.toml"),
            "--zenoh-config",
            &Lab::config("executive.json5"),
        ],
    );
    lab.spawn("executive", exec);
    lab.dir.join("store/record.jsonl")
}

/// Lander tasks (not ground, not the battery reading) the record has completed.
fn lander_done(lines: &[serde_json::Value]) -> usize {
    let lander: std::collections::BTreeSet<_> = lines
        .iter()
        .filter(|l| {
            l["kind"] == "dispatched"
                && l["resource"]
                    .as_str()
                    .is_some_and(|r| !r.starts_with("ground") && r != "power.read_battery")
        })
        .map(|l| l["task"].to_string())
        .collect();
    lines
        .iter()
        .filter(|l| l["kind"] == "completed" && lander.contains(&l["task"].to_string()))
        .count()
}

#[test]
fn a_link_cut_with_goals_in_flight_goes_unnoticed_on_the_lander_and_a_late_monitor_gets_the_present()
 {
    let mut lab = Lab::new("cut-flight", 1);
    lab.routers();
    let ground = lab.grounds[0].clone();
    // Someone on the ground hears the record stream: when it hears again, the link is back.
    lab.start_probe(
        "ground-ear",
        &ground,
        "monitor",
        &["sub", "trace/*/exec/*/record"],
    );
    // 50,000x: Europa's 18 days in about half a minute, so the flight outlives the cut.
    let record = start_europa(&mut lab, "50000", &["station-a"]);
    lab.until_recorded(&record, "a lander activity dispatched", WAIT, |l| {
        l["kind"] == "dispatched" && l["resource"] == "excavation.excavate"
    });
    lab.until_said("ground-ear", &["sample"], WAIT);
    lab.link(1, false);
    let before = lander_done(&records(&record));
    // Down until three more lander activities have ended: the lander goes on alone.
    let during = lab.until_record(&record, "lander work during the cut", WAIT, |ls| {
        lander_done(ls) >= before + 3
    });
    let heard = lab.output("ground-ear").lines().count();
    lab.link(1, true);
    let last_seq = during
        .iter()
        .filter_map(|l| l["seq"].as_u64())
        .max()
        .expect("seq");
    // The ground hears the stream again (a new line after the cut), then a monitor joins late.
    mission_tests::hosts::poll(Duration::from_secs(30), || {
        (lab.output("ground-ear").lines().count() > heard).then_some(())
    })
    .expect("the ground hears the record again after the link came back");
    let mut args = ["monitor", "--jsonl", "--lines", "0"]
        .map(str::to_owned)
        .to_vec();
    args.extend(Lab::client_flags("monitor.json5", "monitor"));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = lab
        .command(&ground, "trace", &args)
        .output()
        .expect("monitor runs");
    let text = String::from_utf8_lossy(&out.stdout);
    let snapshot: serde_json::Value = text
        .lines()
        .next()
        .and_then(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| {
            panic!(
                "no snapshot: {text}\n{}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
    assert_eq!(snapshot["kind"], "snapshot", "{snapshot}");
    let state = &snapshot["state"];
    // The present includes everything the lander did while the ground was cut off.
    assert!(
        state["seq"].as_u64().is_some_and(|s| s >= last_seq),
        "the monitor's present ({}) is older than the cut's last step {last_seq}",
        state["seq"]
    );
    // It is this flight's present: every task it has in flight was commanded in this record.
    let lines = records(&record);
    for t in state["in_flight"].as_array().expect("in flight") {
        assert!(
            lines.iter().any(|l| l["task"] == t["task"]
                && matches!(l["kind"].as_str(), Some("dispatched" | "user_task_opened"))),
            "{t} is not in the record"
        );
    }
    // Nothing on the lander noticed: no goal lost or failed by the connection, every task
    // ended once. The flight is then left to the lab's end.
    let mut ended = std::collections::BTreeSet::new();
    for l in &lines {
        assert_ne!(l["code"], "CONNECTOR_LOST", "{l}");
        if matches!(l["kind"].as_str(), Some("completed" | "failed")) {
            assert!(ended.insert(l["task"].to_string()), "ended twice: {l}");
        }
    }
}

/// One-way delay of the relay between the ground router and the lander's (wall ms).
const DELAY_MS: u64 = 1500;

/// The link is shaped to 256 kbit/s (`tc … tbf`) and every datagram between the routers is held
/// 1.5 s each way by a relay on the ground host.
#[test]
fn seconds_of_latency_between_the_hosts_neither_repeat_an_answer_nor_lose_the_ground() {
    let mut lab = Lab::new("latency", 1);
    // A space link: the routers give the handshake across a 3 s round trip 30 s.
    let slow = [
        "--zenoh-set",
        "transport/unicast/open_timeout=30000",
        "--zenoh-set",
        "transport/unicast/accept_timeout=30000",
    ];
    lab.lander_router_with("lander-router", &slow);
    // A narrow link as well as a long one.
    lab.shape(1, "256kbit");
    let ground = lab.grounds[0].clone();
    let relay = lab.command(
        &ground,
        "delay-relay",
        &[
            "127.0.0.1:7448",
            &format!("{}:7447", Lab::lander_addr(1)),
            &DELAY_MS.to_string(),
        ],
    );
    lab.start("relay", relay);
    lab.ground_router_to(1, "ground-router1", "quic/127.0.0.1:7448", &slow);
    // The lander hears the station once the link across the relay is open.
    let lander = lab.lander.clone();
    lab.start_probe(
        "lander-ear",
        &lander,
        "exec",
        &["alive", "trace/*/alive/**"],
    );
    let policy = slow_policy(&lab, 0);
    station_with(&mut lab, 1, "station-a", &policy);
    lab.until_said(
        "lander-ear",
        &["alive/ground/station-a"],
        Duration::from_secs(60),
    );
    // 300x: the approval's six hours are 72 s of wall time, many round trips.
    run_approval(&mut lab);
    // The goal went down and the answer came up through the relay: at least one round trip
    // of mission time (300 mission ms per wall ms) between them.
    let (_, took) = approval_answered_once(&mut lab);
    assert!(
        took >= (2 * DELAY_MS * 300) as i64,
        "answered {took} mission ms after opening: the relay was not in the path"
    );
    // The station was told its answer was applied, once.
    lab.until_said("station-a", &["answered: applied"], WAIT);
    assert_eq!(
        lab.output("station-a").matches("answered: applied").count(),
        1
    );
}

#[test]
fn the_crash_matrix_across_two_hosts_with_router_kills_loses_nothing_and_repeats_nothing() {
    crate::crash::reduced_matrix(mission_tests::matrix::Layout::Hosts);
}

/// `http-get URL` inside namespace `ns`: the body, or the reason it failed.
fn http_get(lab: &Lab, ns: &str, url: &str) -> Result<String, String> {
    let out = lab
        .command(ns, "http-get", &[url])
        .output()
        .map_err(|e| e.to_string())?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        Err(String::from_utf8_lossy(&out.stderr).into_owned())
    }
}

#[test]
fn the_studio_on_the_ground_follows_the_mission_flying_on_the_lander() {
    let mut lab = Lab::new("studio", 1);
    lab.routers();
    let ground = lab.grounds[0].clone();
    let record = start_europa(&mut lab, "5000", &["station-a"]);
    lab.until_recorded(&record, "a lander activity dispatched", WAIT, |l| {
        l["kind"] == "dispatched"
    });
    // The studio on the ground host, with the monitor's configuration and certificate.
    std::fs::create_dir_all(lab.dir.join("missions")).expect("missions dir");
    let mut args = ["studio", "missions", "--port", "7780"]
        .map(str::to_owned)
        .to_vec();
    args.extend(Lab::client_flags("monitor.json5", "monitor"));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let studio = lab.command(&ground, "trace", &args);
    lab.start("studio", studio);
    let base = "http://127.0.0.1:7780/api/ops";
    let executives = mission_tests::hosts::poll(WAIT, || {
        let list: serde_json::Value =
            serde_json::from_str(&http_get(&lab, &ground, &format!("{base}/executives")).ok()?)
                .ok()?;
        list.as_array()
            .filter(|l| l.iter().any(|e| e["alive"] == true))
            .cloned()
    })
    .expect("the executive on the lander is listed on the ground");
    let mission = executives[0]["mission"]
        .as_str()
        .expect("mission id")
        .to_owned();
    // Its model, its present and its timeline, across the link and both routers' access
    // control (a monitor may ask exactly these).
    let model = http_get(&lab, &ground, &format!("{base}/{mission}/model")).expect("model");
    assert!(model.contains(r#"id="ApproveSite""#), "not Europa's model");
    let state: serde_json::Value = serde_json::from_str(
        &http_get(&lab, &ground, &format!("{base}/{mission}/state")).expect("state"),
    )
    .expect("a state");
    assert_eq!(state["mission"], mission.as_str());
    assert!(state["seq"].as_u64().is_some_and(|s| s > 0), "{state}");
    let page = http_get(&lab, &ground, &format!("{base}/{mission}/timeline")).expect("timeline");
    assert!(
        page.contains(r#""bars":[{"#),
        "the timeline drawn on the ground has no bars"
    );
    // Nothing the studio did was refused by either router.
    for router in ["ground-router1", "lander-router"] {
        let log = lab.log(router);
        assert!(
            !log.contains(REFUSAL),
            "{router} refused something:
{log}"
        );
    }
}
