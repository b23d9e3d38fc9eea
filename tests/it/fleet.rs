//! A fleet: two `trace run --participant` processes, one per pool of a collaboration, exchange
//! the messages of its message flows over Zenoh, exactly once, across a SIGKILL of either
//! executive at each point of the exchange; an executive whose peer pool nothing runs is
//! refused before it starts, naming the pool; the fleet link refuses forged and garbage letters
//! and carries a message through a router that goes down; `trace fly --fleet` flies the
//! two-vehicle mission; and `trace verify` checks the collaboration as a whole.

use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::Duration;

use mission_tests::bin;

use crate::protocol::{endpoint, port, tempdir};

/// The lander asks the scout to survey `site` and waits an hour for its report, correlated by
/// `site`; the scout starts on the request, surveys and reports.
pub(crate) const SURVEY: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0"
  xmlns:zeebe="http://camunda.org/schema/zeebe/1.0" id="D" targetNamespace="t">
  <message id="req" name="survey_request"/>
  <message id="rep" name="survey_report">
    <extensionElements><zeebe:subscription correlationKey="=site"/></extensionElements>
  </message>
  <collaboration id="C">
    <participant id="lander" name="Lander" processRef="LanderP"/>
    <participant id="scout" name="Scout" processRef="ScoutP"/>
    <messageFlow id="ask" sourceRef="Ask" targetRef="Asked" messageRef="req"/>
    <messageFlow id="tell" sourceRef="Tell" targetRef="Heard" messageRef="rep"/>
  </collaboration>
  <process id="LanderP" isExecutable="true">
    <startEvent id="LS"/>
    <sequenceFlow id="l1" sourceRef="LS" targetRef="Ask"/>
    <intermediateThrowEvent id="Ask"><messageEventDefinition messageRef="req"/></intermediateThrowEvent>
    <sequenceFlow id="l2" sourceRef="Ask" targetRef="Wait"/>
    <eventBasedGateway id="Wait"/>
    <sequenceFlow id="l3" sourceRef="Wait" targetRef="Heard"/>
    <intermediateCatchEvent id="Heard"><messageEventDefinition messageRef="rep"/></intermediateCatchEvent>
    <sequenceFlow id="l4" sourceRef="Heard" targetRef="Choose"/>
    <serviceTask id="Choose"><extensionElements><trace:task resource="lander.choose"/></extensionElements></serviceTask>
    <sequenceFlow id="l5" sourceRef="Choose" targetRef="LE"/>
    <endEvent id="LE"/>
    <sequenceFlow id="l6" sourceRef="Wait" targetRef="Silence"/>
    <intermediateCatchEvent id="Silence"><timerEventDefinition><timeDuration>PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>
    <sequenceFlow id="l7" sourceRef="Silence" targetRef="NoReport"/>
    <endEvent id="NoReport"/>
  </process>
  <process id="ScoutP" isExecutable="true">
    <startEvent id="Asked"><messageEventDefinition messageRef="req"/></startEvent>
    <sequenceFlow id="s1" sourceRef="Asked" targetRef="Survey"/>
    <serviceTask id="Survey"><extensionElements><trace:task resource="scout.survey"/></extensionElements></serviceTask>
    <sequenceFlow id="s2" sourceRef="Survey" targetRef="Tell"/>
    <intermediateThrowEvent id="Tell"><messageEventDefinition messageRef="rep"/></intermediateThrowEvent>
    <sequenceFlow id="s3" sourceRef="Tell" targetRef="SE"/>
    <endEvent id="SE"/>
  </process>
</definitions>"#;

/// One executive of the fleet: `trace run` of `pool` (or `trace resume` of its store), listening
/// on `listen` and connecting to `connect`; `crash` is the `TRACE_CRASH_AT` point, if any.
fn executive(
    dir: &Path,
    pool: &str,
    resume: bool,
    listen: &str,
    connect: &str,
    crash: Option<&str>,
) -> Child {
    let mut c = Command::new(bin("trace"));
    if resume {
        c.arg("resume");
    } else {
        c.arg("run")
            .arg(dir.join("fleet.bpmn"))
            .args(["--participant", pool, "--var", "site=3"]);
    }
    c.arg("--store")
        .arg(dir.join(pool.to_lowercase()))
        .args(["--catalogue-wait", "30"])
        .args(["-l", listen, "-e", connect, "--no-multicast-scouting"])
        .env_remove("TRACE_CRASH_AT")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit());
    if let Some(point) = crash {
        c.env("TRACE_CRASH_AT", point);
    }
    c.spawn().expect("trace starts")
}

/// Waits for `child` to end, at most two minutes (then kills it and fails).
fn ends(child: Child, what: &str) -> ExitStatus {
    mission_tests::ended(child, Duration::from_secs(120))
        .unwrap_or_else(|| panic!("{what} did not end within two minutes"))
}

/// A record's lines, each line written again after a restart (same `seq` and `idx`) once.
fn lines(record: &Path) -> Vec<serde_json::Value> {
    let mut reader = executive_runtime::record::Reader::default();
    std::fs::read_to_string(record)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| reader.read(l))
        .collect()
}

/// How many of a record's lines match `pred`.
fn count(record: &Path, pred: impl Fn(&serde_json::Value) -> bool) -> usize {
    lines(record).iter().filter(|v| pred(v)).count()
}

/// Flies the survey with the `crashing` pool's executive aborting at `point` (if any), resumed
/// once it has; checks that each message was applied exactly once, to the right instance.
fn fly(name: &str, crash: Option<(&str, &str)>) {
    let dir = tempdir(name);
    std::fs::write(dir.join("fleet.bpmn"), SURVEY).expect("mission");
    let (a, b) = (endpoint(port()), endpoint(port()));
    let point = |pool: &str| crash.filter(|(p, _)| *p == pool).map(|(_, at)| at);
    let mut lander = Some(executive(&dir, "lander", false, &a, &b, point("lander")));
    let mut scout = Some(executive(&dir, "Scout", false, &b, &a, point("scout")));
    if let Some((pool, at)) = crash {
        let (slot, listen, connect) = match pool {
            "lander" => (&mut lander, &a, &b),
            _ => (&mut scout, &b, &a),
        };
        let status = ends(slot.take().expect("started"), pool);
        assert!(!status.success(), "{pool} did not stop at {at}: {status}");
        *slot = Some(executive(&dir, pool, true, listen, connect, None));
    }
    let l = ends(lander.take().expect("started"), "the lander");
    let s = ends(scout.take().expect("started"), "the scout");
    assert!(l.success() && s.success(), "lander {l}, scout {s}");
    let (lr, sr) = (
        dir.join("lander/record.jsonl"),
        dir.join("scout/record.jsonl"),
    );
    // The request started exactly one scout instance, with the lander's site.
    let started: Vec<serde_json::Value> = lines(&sr)
        .into_iter()
        .filter(|v| v["kind"] == "instance_started")
        .collect();
    assert_eq!(started.len(), 1, "{started:#?}");
    assert_eq!(started[0]["process"], "ScoutP");
    assert_eq!(started[0]["vars"]["site"], 3);
    // The report released the lander's wait once, at the message catch, not the timer.
    let caught = count(&lr, |v| {
        v["kind"] == "caught" && v["name"] == "survey_report"
    });
    assert_eq!(caught, 1);
    assert_eq!(count(&lr, |v| v["kind"] == "timer_fired"), 0);
    for record in [&lr, &sr] {
        let ends: Vec<serde_json::Value> = lines(record)
            .into_iter()
            .filter(|v| v["kind"] == "instance_finished")
            .collect();
        assert_eq!(ends.len(), 1, "{ends:#?}");
        assert_eq!(ends[0]["outcome"]["type"], "completed", "{ends:#?}");
        // Each message was sent under one key and acknowledged.
        let sent: std::collections::BTreeSet<String> = lines(record)
            .iter()
            .filter(|v| v["kind"] == "message_sent")
            .map(|v| v["key"].as_str().unwrap_or_default().to_owned())
            .collect();
        let delivered: std::collections::BTreeSet<String> = lines(record)
            .iter()
            .filter(|v| v["kind"] == "message_delivered")
            .map(|v| v["key"].as_str().unwrap_or_default().to_owned())
            .collect();
        assert_eq!(sent.len(), 1, "{}", record.display());
        assert_eq!(sent, delivered, "{}", record.display());
    }
}

#[test]
fn two_executives_fly_one_collaboration_over_zenoh() {
    fly("fleet-plain", None);
}

// Each crash point of the exchange, on each side: the sender before it sends and after its
// receiver acknowledged; the receiver after it committed, before it acknowledged.
#[test]
fn the_lander_aborted_after_committing_its_request_sends_it_on_resume() {
    fly("fleet-l-committed", Some(("lander", "message-committed")));
}

#[test]
fn the_lander_aborted_after_its_request_was_acknowledged_does_not_apply_it_twice() {
    fly("fleet-l-acked", Some(("lander", "message-acknowledged")));
}

#[test]
fn the_lander_aborted_after_committing_the_report_acknowledges_the_resend() {
    fly("fleet-l-letter", Some(("lander", "letter-committed")));
}

#[test]
fn the_scout_aborted_after_committing_the_request_acknowledges_the_resend() {
    fly("fleet-s-letter", Some(("scout", "letter-committed")));
}

#[test]
fn the_scout_aborted_after_committing_its_report_sends_it_on_resume() {
    fly("fleet-s-committed", Some(("scout", "message-committed")));
}

#[test]
fn the_scout_aborted_after_its_report_was_acknowledged_does_not_apply_it_twice() {
    fly("fleet-s-acked", Some(("scout", "message-acknowledged")));
}

// Before anything starts, a pool of the collaboration that no executive runs is named.
#[test]
fn a_pool_nothing_runs_is_refused_before_the_mission_starts() {
    let dir = tempdir("fleet-alone");
    std::fs::write(dir.join("fleet.bpmn"), SURVEY).expect("mission");
    let out = Command::new(bin("trace"))
        .arg("run")
        .arg(dir.join("fleet.bpmn"))
        .args(["--participant", "Lander", "--catalogue-wait", "0.5"])
        .arg("--store")
        .arg(dir.join("lander"))
        .args(["-l", &endpoint(port()), "--no-multicast-scouting"])
        .output()
        .expect("trace runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("pool `scout` is run by no executive in deployment `default`"),
        "{err}"
    );
    // Nothing was journaled: the lander never started.
    assert!(!dir.join("lander/record.jsonl").exists());
    let wrong = Command::new(bin("trace"))
        .arg("run")
        .arg(dir.join("fleet.bpmn"))
        .args(["--participant", "Rover"])
        .arg("--store")
        .arg(dir.join("rover"))
        .output()
        .expect("trace runs");
    let err = String::from_utf8_lossy(&wrong.stderr);
    assert!(
        err.contains("no pool is named `Rover`") && err.contains("`scout` (Scout)"),
        "{err}"
    );
}

/// `trace fly --fleet` in `dir` with `extra` flags; its standard output.
fn fly_fleet(dir: &Path, extra: &[&str]) -> String {
    // At 20,000x the lander's six hours for a report are a second of wall time: a scout slowed
    // by a loaded machine still answers in time (at the default 200,000x, 0.1 s, it did not
    // always, and the lander rightly went on alone).
    let out = Command::new(bin("trace"))
        .args(["fly", "--fleet", "--speed", "20000", "--dir"])
        .arg(dir)
        .args(extra)
        .output()
        .expect("trace fly runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// The sites the lander's excavation was commanded at.
fn dug(record: &Path) -> Vec<i64> {
    lines(record)
        .iter()
        .filter(|v| v["kind"] == "dispatched" && v["resource"] == "excavation.excavate")
        .filter_map(|v| v["request"]["site_id"].as_i64())
        .collect()
}

// The two-vehicle Europa mission flown as a fleet: five processes, each vehicle's part ends,
// the scout's report reaches the lander, and the summary is per vehicle.
#[test]
fn trace_fly_flies_the_fleet_mission_to_its_end() {
    let dir = tempdir("fleet-fly");
    let out = fly_fleet(&dir.join("flight"), &[]);
    assert!(out.contains("as a fleet"), "{out}");
    let lander = dir.join("flight/store/record.jsonl");
    let scout = dir.join("flight/scout/record.jsonl");
    for (name, record) in [("lander", &lander), ("scout", &scout)] {
        assert!(
            out.lines().any(|l| l.trim_start().starts_with(name)
                && l.contains("completed")
                && l.contains("1 sent (1 delivered, 0 refused), 1 received")),
            "{out}"
        );
        assert_eq!(
            count(record, |v| v["kind"] == "instance_finished"
                && v["outcome"]["type"] == "completed"),
            1,
            "{name}"
        );
    }
    // The lander decided on the scout's report (read at its gateway), and dug once.
    let decided: Vec<serde_json::Value> = lines(&lander)
        .into_iter()
        .filter(|v| v["kind"] == "decided" && v["element"]["id"] == "SiteUnsafe")
        .collect();
    assert_eq!(decided.len(), 1, "{decided:#?}");
    assert!(decided[0]["read"]["report_status"].is_string());
    assert_eq!(dug(&lander).len(), 1);
    // One timeline for both vehicles, with the messages on it.
    let page = std::fs::read_to_string(dir.join("flight/timeline.html")).expect("timeline");
    for lane in [
        "lander · messages",
        "scout · messages",
        "scout · system: survey",
    ] {
        assert!(page.contains(lane), "no lane {lane}");
    }
    assert_eq!(
        page.matches(r#""kind":"message""#).count(),
        4,
        "two sent, two taken"
    );
}

// The scout finds the first site unsafe: the lander excludes it, asks about the next site it
// selects, and digs there; the scout ran once per request.
#[test]
fn a_site_the_scout_reports_unsafe_is_never_dug() {
    let dir = tempdir("fleet-unsafe");
    let faults = dir.join("scout-faults.json");
    std::fs::write(
        &faults,
        r#"{"faults": [{"action": "survey.site", "call": 1, "code": "UNSAFE"},
                       {"action": "survey.site", "call": 2, "code": "SAFE"}]}"#,
    )
    .expect("faults");
    let faults = faults.display().to_string();
    fly_fleet(
        &dir.join("flight"),
        &["--profile", "quiet", "--scout-faults", &faults],
    );
    let lander = dir.join("flight/store/record.jsonl");
    let scout = dir.join("flight/scout/record.jsonl");
    let surveyed: Vec<i64> = lines(&scout)
        .iter()
        .filter(|v| v["kind"] == "dispatched" && v["resource"] == "survey.site")
        .filter_map(|v| v["request"]["site_id"].as_i64())
        .collect();
    assert_eq!(surveyed.len(), 2, "{surveyed:?}");
    assert_ne!(surveyed[0], surveyed[1]);
    assert_eq!(dug(&lander), [surveyed[1]]);
    assert_eq!(count(&scout, |v| v["kind"] == "instance_started"), 2);
}

/// The survey of [`SURVEY`] with a flaw seeded across the two pools: the lander waits for the
/// report with no timer, and a scout short of charge ends without sending one.
fn seeded_deadlock() -> String {
    SURVEY
        .replace(
            r#"<sequenceFlow id="l6" sourceRef="Wait" targetRef="Silence"/>"#,
            "",
        )
        .replace(
            r#"<intermediateCatchEvent id="Silence"><timerEventDefinition><timeDuration>PT1H</timeDuration></timerEventDefinition></intermediateCatchEvent>"#,
            "",
        )
        .replace(r#"<sequenceFlow id="l7" sourceRef="Silence" targetRef="NoReport"/>"#, "")
        .replace(r#"<endEvent id="NoReport"/>"#, "")
        .replace(
            r#"<sequenceFlow id="s1" sourceRef="Asked" targetRef="Survey"/>"#,
            r#"<sequenceFlow id="s1" sourceRef="Asked" targetRef="Charged"/>
    <exclusiveGateway id="Charged" default="s0"/>
    <sequenceFlow id="s4" sourceRef="Charged" targetRef="Survey"><conditionExpression>charge &gt;= 40</conditionExpression></sequenceFlow>
    <sequenceFlow id="s0" sourceRef="Charged" targetRef="TooLow"/>
    <endEvent id="TooLow"/>"#,
        )
}

// The two-vehicle mission is verified as a whole: every pool together, Spin and the engine's
// own exploration agreeing on it.
#[test]
fn the_fleet_mission_verifies_as_a_whole_and_spin_agrees_with_the_engine() {
    let path = mission_tests::repo().join("deploy/missions/europa-fleet.bpmn");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&path)
        .arg("--native")
        .output()
        .expect("trace verify runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    // Its requirements (`europa-fleet.req.toml`) name both vehicles' elements.
    for p in [
        "no_deadlock",
        "safe",
        "no_dead_activities",
        "completes",
        "digging_waits_for_the_scout",
        "reports_answer_requests",
        "every_request_is_answered_or_outwaited",
        "scout_surveys_with_a_reserve",
        "scout_hops_with_a_reserve",
        "lander_keeps_half_while_the_scout_surveys",
    ] {
        assert!(
            text.lines().any(|l| l.contains("holds") && l.contains(p)),
            "{p}: {text}"
        );
    }
    // Time and energy per vehicle: each pool costed by its own connectors (found beside the
    // missions, deploy/fleet/), each with its own battery.
    let timed = text
        .lines()
        .find(|l| l.starts_with("timed exploration"))
        .unwrap_or_default();
    for part in [
        "lander: ",
        "fleet/lander.toml",
        "fleet/scout.toml",
        "(lander ",
        ", scout ",
    ] {
        assert!(timed.contains(part), "{part}: {timed}");
    }
    let graph = executive_model::load(&std::fs::read(&path).expect("mission"))
        .graph
        .expect("it loads");
    let dir = tempdir("fleet-compare");
    match crate::verify::compare(graph, &dir) {
        crate::verify::Compared::Done(c) => {
            assert!(c.how.is_empty(), "{:?}", c.how);
            assert!(c.ends.contains("SiteExcavated") && c.ends.contains("SurveyDone"));
        }
        _ => panic!("the fleet mission is translated and explored without data"),
    }
}

#[test]
fn energy_in_a_fleet_names_its_vehicle_and_each_pool_needs_its_connectors() {
    let dir = tempdir("fleet-energy");
    let model = dir.join("fleet.bpmn");
    std::fs::copy(
        mission_tests::repo().join("deploy/missions/europa-fleet.bpmn"),
        &model,
    )
    .expect("copy");
    let verify = |reqs: &str, connectors: &[&str]| {
        let req = dir.join("fleet.req.toml");
        std::fs::write(&req, reqs).expect("requirements");
        let mut c = Command::new(bin("trace"));
        c.arg("verify").arg(&model).arg("--requirements").arg(&req);
        for f in connectors {
            c.arg("--connectors").arg(f);
        }
        let out = c.output().expect("trace verify runs");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned()
                + &String::from_utf8_lossy(&out.stderr),
        )
    };
    let fleet = |pool: &str| {
        format!(
            "{pool}={}",
            mission_tests::repo()
                .join(format!("deploy/fleet/{pool}.toml"))
                .display()
        )
    };
    let (lander, scout) = (fleet("lander"), fleet("scout"));
    let mission = "[[requirement]]\nname = \"r\"\ncheck = 'never energy_left < 5 %'\n";
    let (code, text) = verify(mission, &[&lander, &scout]);
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("say whose"), "{text}");
    let scout_only = "[[requirement]]\nname = \"r\"\ncheck = 'never (running \"Survey Site\" and energy_left of \"Scout\" < 10 %)'\n";
    let (code, text) = verify(scout_only, &[&lander, &scout]);
    assert_eq!(code, Some(0), "{text}");
    let (code, text) = verify(scout_only, &[&lander]);
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("no file for pool(s) `scout`"), "{text}");
    let (code, text) = verify(scout_only, &["rover=x.toml", &scout]);
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("`rover`"), "{text}");
}

// A deadlock between the vehicles — the lander waits for a report the scout never sends — is
// found by Spin and by the engine's exploration, each with a run through both vehicles' steps.
#[test]
fn a_deadlock_between_the_vehicles_is_found_by_spin_and_by_the_engine() {
    let dir = tempdir("fleet-deadlock");
    let model = dir.join("seeded.bpmn");
    std::fs::write(&model, seeded_deadlock()).expect("model");
    let out = Command::new(bin("trace"))
        .arg("verify")
        .arg(&model)
        .args(["--json", "--dir"])
        .arg(dir.join("work"))
        .output()
        .expect("trace verify runs");
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let deadlock = report["properties"]
        .as_array()
        .expect("properties")
        .iter()
        .find(|p| p["name"] == "no_deadlock")
        .expect("no_deadlock")
        .clone();
    assert_eq!(deadlock["verdict"], "violated", "{deadlock:#}");
    let steps: Vec<String> = deadlock["counterexample"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|s| s["step"]["element"].as_str().map(str::to_owned))
        .collect();
    // The lander asked; the scout, short of charge, ended without a word.
    assert!(steps.iter().any(|s| s == "Ask"), "{steps:?}");
    assert!(steps.iter().any(|s| s == "Charged"), "{steps:?}");
    let graph = executive_model::load(seeded_deadlock().as_bytes())
        .graph
        .expect("it loads");
    let native = executive_verify::explore(std::sync::Arc::new(graph), 100_000);
    // The mission's start sends the request and starts the scout; its choice strands the
    // lander.
    let run = native.deadlock.expect("the engine's exploration finds it");
    assert_eq!(run, ["Charged.take[s0]"]);
    assert!(native.ends.contains("TooLow") && native.ends.contains("LE"));
}

/// A letter from `from` to `to` keyed `key`.
fn letter(key: &str, from: &str, to: &str) -> connector_api::wire::Letter {
    connector_api::wire::Letter {
        key: key.into(),
        from: from.into(),
        to: to.into(),
        flow: "ask".into(),
        name: "survey_request".into(),
        correlation: None,
        payload: serde_json::Map::new(),
    }
}

/// One raw query carrying `body` on `key`: the reply's payload, or the error reply's text.
async fn ask(
    session: &zenoh::Session,
    key: &str,
    body: Vec<u8>,
) -> Result<serde_json::Value, String> {
    let replies = session
        .get(key)
        .payload(body)
        .timeout(Duration::from_secs(5))
        .await
        .expect("query sent");
    let reply = replies.recv_async().await.expect("a reply");
    match reply.result() {
        Ok(s) => Ok(serde_json::from_slice(&s.payload().to_bytes()).expect("JSON reply")),
        Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
    }
}

/// Waits until pool `pool`'s inbox is reachable from `session`: its presence, which an executive
/// declares after its inbox, has reached it (a letter sent before would find nobody to answer).
pub(crate) async fn reachable(session: &zenoh::Session, keys: &connector_api::Keys, pool: &str) {
    let presence = session
        .liveliness()
        .declare_subscriber(keys.fleet_alive(pool, "running"))
        .history(true)
        .await
        .expect("presence subscriber");
    tokio::time::timeout(Duration::from_secs(30), presence.recv_async())
        .await
        .unwrap_or_else(|_| panic!("the presence of pool `{pool}` reaches this session"))
        .expect("a presence sample");
}

// At the door of a fleet executive's inbox: garbage, a letter sent as another pool than it
// names, and one addressed to another pool are refused with the reason and counted, not
// handed to the executive; a good one is, and its verdict is the reply.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_fleet_link_refuses_forged_and_garbage_letters_and_replies_the_verdict() {
    use connector_api::{Keys, Report};
    let hub = endpoint(port());
    let scout_side = crate::protocol::open(std::slice::from_ref(&hub), &[]).await;
    let other = crate::protocol::open(&[], std::slice::from_ref(&hub)).await;
    let keys = Keys::new("trace").expect("keys");
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let fleet = connector_zenoh::Fleet::join(&scout_side, keys.clone(), "scout", tx)
        .await
        .expect("joins");
    reachable(&other, &keys, "scout").await;
    let garbage = ask(
        &other,
        &keys.fleet_message("scout", "lander", "k.m1"),
        b"{not json".to_vec(),
    )
    .await;
    assert!(
        matches!(&garbage, Err(e) if e.contains("malformed letter")),
        "{garbage:?}"
    );
    let forged = serde_json::to_vec(&letter("k.m2", "rover", "scout")).expect("json");
    let forged = ask(
        &other,
        &keys.fleet_message("scout", "lander", "k.m2"),
        forged,
    )
    .await;
    assert!(
        matches!(&forged, Err(e) if e.contains("sent as `lander`")),
        "{forged:?}"
    );
    let elsewhere = serde_json::to_vec(&letter("k.m3", "lander", "rover")).expect("json");
    let elsewhere = ask(
        &other,
        &keys.fleet_message("scout", "lander", "k.m3"),
        elsewhere,
    )
    .await;
    assert!(
        matches!(&elsewhere, Err(e) if e.contains("for pool `rover`")),
        "{elsewhere:?}"
    );
    assert_eq!(fleet.dropped().total, 3);
    // A good letter reaches the executive, whose verdict is the reply.
    let good = serde_json::to_vec(&letter("k.m4", "lander", "scout")).expect("json");
    let key = keys.fleet_message("scout", "lander", "k.m4");
    let reply = tokio::spawn({
        let other = other.clone();
        async move { ask(&other, &key, good).await }
    });
    let verdict = loop {
        match rx.recv().await.expect("reports") {
            Report::Letter { letter, verdict } => {
                assert_eq!(
                    (letter.key.as_str(), letter.from.as_str()),
                    ("k.m4", "lander")
                );
                break verdict;
            }
            _ => continue,
        }
    };
    verdict.give(Err("`Asked` does not wait for it".into()));
    let reply = reply.await.expect("joined").expect("a verdict");
    assert_eq!(reply["applied"], false);
    assert_eq!(reply["reason"], "`Asked` does not wait for it");
}

// A message sent while nothing serves its pool (a cut link, a router down) is sent again until
// the receiver is back and gives its verdict: here the router between the two goes down with
// the letter in flight, and comes back.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_message_crosses_a_router_that_goes_down_and_comes_back() {
    use connector_api::{Keys, Report};
    let rp = port();
    let router = crate::protocol::router(rp).await;
    let via = [endpoint(rp)];
    let lander = crate::protocol::open(&[], &via).await;
    let scout = crate::protocol::open(&[], &via).await;
    let keys = Keys::new("trace").expect("keys");
    let (ltx, mut lrx) = tokio::sync::mpsc::unbounded_channel();
    let (stx, mut srx) = tokio::sync::mpsc::unbounded_channel();
    let from = connector_zenoh::Fleet::join(&lander, keys.clone(), "lander", ltx)
        .await
        .expect("lander joins");
    let _to = connector_zenoh::Fleet::join(&scout, keys.clone(), "scout", stx)
        .await
        .expect("scout joins");
    assert!(
        from.wait_for(&["scout".into()], Duration::from_secs(10))
            .await
            .is_empty()
    );
    router.close().await.expect("router down");
    from.send(letter("k.m1", "lander", "scout"));
    assert_eq!(from.unacknowledged(), ["k.m1"]);
    let router = crate::protocol::router(rp).await;
    // The scout's executive applies it once the link is back (Zenoh reconnects the peers).
    let verdict = loop {
        match tokio::time::timeout(Duration::from_secs(60), srx.recv()).await {
            Ok(Some(Report::Letter { letter, verdict })) => {
                assert_eq!(letter.key, "k.m1");
                break verdict;
            }
            Ok(Some(_)) => continue,
            other => panic!("the letter never came through: {other:?}"),
        }
    };
    verdict.give(Ok(()));
    loop {
        match tokio::time::timeout(Duration::from_secs(30), lrx.recv()).await {
            Ok(Some(Report::Delivered { key, refused })) => {
                assert_eq!((key.as_str(), refused), ("k.m1", None));
                break;
            }
            Ok(Some(_)) => continue,
            other => panic!("no verdict reached the sender: {other:?}"),
        }
    }
    assert!(from.unacknowledged().is_empty());
    drop(router);
}

// The fleet's crash matrix, reduced: one flight per kind, each with a kill in each of two
// exchanges; nothing lost, applied twice or misrouted, and both parts end.
#[test]
fn the_fleet_crash_matrix_reduced_loses_nothing_and_repeats_nothing() {
    use mission_tests::fleet_matrix::{Victim, fly};
    let dir = tempdir("fleet-matrix");
    for (i, victim) in Victim::ALL.into_iter().enumerate() {
        let f = fly(
            &dir.join(format!("{i}")),
            i as u64 + 1,
            victim,
            2,
            Duration::from_secs(120),
        );
        assert_eq!(f.kills, 2, "{}: {f:?}", victim.name());
        assert!(f.exact(), "{}: {f:?}", victim.name());
        assert_eq!(
            f.outcome.as_deref(),
            Some("completed"),
            "{}: {f:?}",
            victim.name()
        );
        assert_eq!((f.requests, f.reports), (3, 3), "{}: {f:?}", victim.name());
    }
}
