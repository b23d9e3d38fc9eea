//! A collaboration with a black-box pool (BPMN §9.2: a participant without a process), flown by
//! a real `trace run --participant` over Zenoh: the message along the flow into the black box
//! leaves the engine (recorded, handed to the connectors), and the black box's answer, sent by
//! an outside process as a letter from that pool (`docs/protocol.md` §8c), is applied once and
//! ends the mission; a letter on a flow the black box does not send is refused.

use std::process::{Command, Stdio};
use std::time::Duration;

use connector_api::Keys;
use connector_api::wire::Letter;
use mission_tests::bin;
use serde_json::Value;

use crate::protocol::{endpoint, port, tempdir};
use crate::studio::Kill;

/// Lander `A` runs a process; `B` (the ground, say) is a pool with no process: `A` sends it
/// `ping` and waits for its `pong`.
const MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:black-box">
  <message id="Ping" name="ping"/>
  <message id="Pong" name="pong"/>
  <collaboration id="C">
    <participant id="A" name="Lander" processRef="PA"/>
    <participant id="B" name="Ground, a black box"/>
    <messageFlow id="out" sourceRef="send" targetRef="B" messageRef="Ping"/>
    <messageFlow id="back" sourceRef="B" targetRef="wait" messageRef="Pong"/>
  </collaboration>
  <process id="PA" isExecutable="true">
    <startEvent id="s"/>
    <intermediateThrowEvent id="send"><messageEventDefinition messageRef="Ping"/></intermediateThrowEvent>
    <intermediateCatchEvent id="wait"><messageEventDefinition messageRef="Pong"/></intermediateCatchEvent>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="send"/>
    <sequenceFlow id="f2" sourceRef="send" targetRef="wait"/>
    <sequenceFlow id="f3" sourceRef="wait" targetRef="e"/>
  </process>
</definitions>"#;

/// The record's lines so far.
fn record(path: &std::path::Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// Sends `letter` as pool `from` and returns the verdict, or the refusal's text.
async fn send(session: &zenoh::Session, keys: &Keys, letter: &Letter) -> Result<Value, String> {
    let key = keys.fleet_message(&letter.to, &letter.from, &letter.key);
    let replies = session
        .get(&key)
        .payload(serde_json::to_vec(letter).expect("JSON"))
        .timeout(Duration::from_secs(10))
        .await
        .expect("query sent");
    let reply = replies.recv_async().await.expect("a reply");
    match reply.result() {
        Ok(s) => Ok(serde_json::from_slice(&s.payload().to_bytes()).expect("a JSON verdict")),
        Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_black_box_pool_hears_the_mission_and_answers_it_from_outside() {
    let dir = tempdir("black-box");
    std::fs::write(dir.join("mission.bpmn"), MISSION).expect("mission");
    let hub = endpoint(port());
    let mut exec = Command::new(bin("trace"));
    exec.arg("run")
        .arg(dir.join("mission.bpmn"))
        .args(["--participant", "A", "--store"])
        .arg(dir.join("store"))
        .args(["-l", &hub, "--no-multicast-scouting"])
        .stdout(Stdio::null());
    let exec = Kill(exec.spawn().expect("trace run starts"));
    let path = dir.join("store/record.jsonl");
    // The lander sent `ping` out of the engine and waits for `pong`.
    mission_tests::hosts::poll(Duration::from_secs(60), || {
        record(&path)
            .iter()
            .any(|l| l["kind"] == "entered" && l["element"]["id"] == "wait")
            .then_some(())
    })
    .unwrap_or_else(|| panic!("the lander never waited: {:?}", record(&path)));
    let lines = record(&path);
    assert!(
        lines
            .iter()
            .any(|l| l["kind"] == "thrown" && l["what"] == "message" && l["name"] == "ping"),
        "{lines:?}"
    );
    let session = crate::protocol::open(&[], std::slice::from_ref(&hub)).await;
    let keys = Keys::default();
    crate::fleet::reachable(&session, &keys, "A").await;
    let letter = |key: &str, flow: &str| Letter {
        key: key.to_owned(),
        from: "B".to_owned(),
        to: "A".to_owned(),
        flow: flow.to_owned(),
        name: "pong".to_owned(),
        correlation: None,
        payload: connector_api::Fields::new(),
    };
    // A letter on a flow that does not leave the black box is refused, with the reason.
    let wrong = send(&session, &keys, &letter("ground.m0", "out")).await;
    assert!(
        matches!(&wrong, Ok(v) if v["applied"] == false) || wrong.is_err(),
        "{wrong:?}"
    );
    // The black box's answer: applied, and applied once however often it is sent.
    let verdict = send(&session, &keys, &letter("ground.m1", "back"))
        .await
        .expect("a verdict");
    assert_eq!(verdict["applied"], true, "{verdict}");
    let exited = tokio::task::spawn_blocking(move || {
        let mut exec = exec;
        exec.0.wait()
    })
    .await
    .expect("joined")
    .expect("trace run ends");
    assert!(exited.success(), "{exited}");
    let lines = record(&path);
    let end = lines
        .iter()
        .rev()
        .find(|l| l["kind"] == "instance_finished")
        .expect("the mission ended");
    assert_eq!(end["outcome"]["type"], "completed", "{end}");
    assert_eq!(
        lines
            .iter()
            .filter(|l| l["kind"] == "caught" && l["element"]["id"] == "wait")
            .count(),
        1,
        "{lines:?}"
    );
    drop(dir);
}
