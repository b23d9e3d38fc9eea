//! Ground decisions and a mission's end in the studio's operations view, in headless Chromium
//! beside a real `trace run` over Zenoh (the studio its only ground station): an open task is
//! announced and counted down to its deadline in mission time, its context is shown as a table,
//! not JSON; a task the mission withdraws when its timer fires, and one answered from the page,
//! are each listed with who or what closed them; and when the mission ends the page says it
//! ended and how, not that the executive is gone, and its timeline stays, drawn complete.

use std::process::{Command, Stdio};

use fantoccini::Client;
use mission_tests::{bin, repo};
use serde_json::{Value, json};

use crate::protocol::{endpoint, port, tempdir};
use crate::studio::{Kill, Page, click, js, until};

/// Two site approvals in parallel, each to its own end: the first times out after ten mission
/// minutes (five wall seconds at speed 120), the second has a hundred hours.
const MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="defs" targetNamespace="urn:ops-ground">
  <process id="approvals" isExecutable="true">
    <startEvent id="s"/>
    <parallelGateway id="fork"/>
    <userTask id="quick" name="Approve the near site"><extensionElements><trace:task resource="ground.approve_site">
      <trace:input target="candidates" source='[{"site_id": 1, "score": 0.4, "material": "regolith"}]' type="json"/></trace:task></extensionElements></userTask>
    <boundaryEvent id="quickLate" attachedToRef="quick"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT10M</timeDuration></timerEventDefinition></boundaryEvent>
    <userTask id="slow" name="Approve the far site"><extensionElements><trace:task resource="ground.approve_site">
      <trace:input target="candidates" source='[{"site_id": 2, "score": 0.91, "material": "ice"}, {"site_id": 3, "score": 0.7, "material": "salt"}]' type="json"/>
      <trace:output source="approve" target="far_ok" type="bool"/></trace:task></extensionElements></userTask>
    <boundaryEvent id="slowLate" attachedToRef="slow"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT100H</timeDuration></timerEventDefinition></boundaryEvent>
    <endEvent id="quickDone"/><endEvent id="quickTimedOut"/><endEvent id="slowDone"/><endEvent id="slowTimedOut"/>
    <sequenceFlow id="f0" sourceRef="s" targetRef="fork"/>
    <sequenceFlow id="f1" sourceRef="fork" targetRef="quick"/>
    <sequenceFlow id="f2" sourceRef="fork" targetRef="slow"/>
    <sequenceFlow id="f3" sourceRef="quick" targetRef="quickDone"/>
    <sequenceFlow id="f4" sourceRef="quickLate" targetRef="quickTimedOut"/>
    <sequenceFlow id="f5" sourceRef="slow" targetRef="slowDone"/>
    <sequenceFlow id="f6" sourceRef="slowLate" targetRef="slowTimedOut"/>
  </process>
</definitions>"#;

const CONNECTORS: &str = r#"
[[connector]]
name = "ground"
kind = "zenoh"
resources = ["ground.*"]
answers = true
"#;

#[test]
fn ground_tasks_are_announced_counted_down_and_closed_and_an_ended_mission_stays_shown() {
    let dir = tempdir("studio-ops-ground");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    std::fs::write(dir.join("mission.bpmn"), MISSION).expect("mission");
    std::fs::write(dir.join("connectors.toml"), CONNECTORS).expect("connectors");
    let hub = endpoint(port());
    // The executive listens; it starts once a ground station (the studio) serves the forms.
    let mut exec = Command::new(bin("trace"));
    exec.arg("run")
        .arg(dir.join("mission.bpmn"))
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .args(["--speed", "120", "-l", &hub, "--no-multicast-scouting"])
        .stdout(Stdio::null());
    let exec = Kill(exec.spawn().expect("trace run starts"));
    let mut studio = Command::new(bin("trace"));
    studio
        .arg("studio")
        .arg(&missions)
        .args(["--port", "0", "--station", "web", "--catalogue"])
        .arg(repo().join("deploy/ground/forms.json"))
        .args(["-e", &hub, "--no-multicast-scouting"]);
    let page = Page::start(studio);
    let store = dir.join("store");
    page.play(move |c, url| scenario(c, url, exec, store));
    drop(dir);
}

async fn scenario(c: Client, url: String, mut exec: Kill, store: std::path::PathBuf) {
    c.goto(&url).await.expect("the studio's page");
    until(
        &c,
        "the page ready",
        "return document.body.dataset.ready === 'true'",
    )
    .await;
    click(&c, "#ops-toggle").await;
    let form = r#"#ground-tasks .ground-task[data-task="slow"]"#;
    // Announced as it opens, the page's title counting what is open.
    let announced = until(
        &c,
        "the far site's approval announced",
        "const a = document.getElementById('ground-announce').textContent;
         return a.includes('Approve the far site') && a",
    )
    .await;
    assert!(
        announced
            .as_str()
            .is_some_and(|a| a.starts_with("Ground decision ") && a.contains("answer by ")),
        "{announced}"
    );
    // Counted down in mission time: a hundred hours at most, going down.
    let left = until(
        &c,
        "the deadline counted down",
        &format!(
            "const c = document.querySelector('{form} .countdown');
             return c && c.dataset.left && {{ left: Number(c.dataset.left), text: c.textContent }}"
        ),
    )
    .await;
    let first = left["left"].as_f64().expect("ms left");
    assert!(first > 0.0 && first <= 100.0 * 3_600_000.0, "{left}");
    assert!(
        left["text"]
            .as_str()
            .is_some_and(|t| t.contains(" h ") && t.ends_with("left)")),
        "{left}"
    );
    until(
        &c,
        "the countdown going down",
        &format!(
            "const c = document.querySelector('{form} .countdown');
             return Number(c.dataset.left) < {first}"
        ),
    )
    .await;
    // The context the mission shows, as a table of the candidate sites.
    let table = js(
        &c,
        &format!(
            "const t = document.querySelector('{form} .context table');
             return t && [...t.querySelectorAll('tr')].map(r => [...r.children].map(c => c.textContent))"
        ),
        vec![],
    )
    .await;
    assert_eq!(
        table,
        json!([
            ["material", "score", "site_id"],
            ["ice", "0.91", "2"],
            ["salt", "0.7", "3"]
        ])
    );
    // The near site's approval: withdrawn by the mission when its ten minutes are over.
    let quick = until(
        &c,
        "the near site's approval closed by its timer",
        r#"const li = document.querySelector('#ground-closed li[data-task="quick"]');
           return li && li.dataset.closed"#,
    )
    .await;
    assert!(
        quick
            .as_str()
            .is_some_and(|q| q.starts_with("withdrawn by the mission")),
        "{quick}"
    );
    // The far one answered from the page.
    js(
        &c,
        &format!(
            "document.getElementById('operator').value = 'ana';
             document.querySelector('{form} select[name=approve]').value = 'true';"
        ),
        vec![],
    )
    .await;
    click(&c, &format!("{form} button")).await;
    let slow = until(
        &c,
        "the far site's approval closed by its answer",
        r#"const li = document.querySelector('#ground-closed li[data-task="slow"]');
           return li && li.dataset.closed"#,
    )
    .await;
    assert_eq!(slow, "answered by ana@web");
    // Both branches ended: the mission is over, said as such, its executive gone.
    let status = until(
        &c,
        "the mission's end",
        "return document.body.dataset.opsEnded && document.getElementById('ops-status').textContent",
    )
    .await;
    assert!(
        status
            .as_str()
            .is_some_and(|s| s.contains("the mission ended (completed)") && s.contains("has left")),
        "{status}"
    );
    let gone = js(&c, "return document.body.dataset.opsGone", vec![]).await;
    assert_ne!(gone, json!("true"), "an end is not a crash");
    let exited = exec.0.wait().expect("trace run ends");
    assert!(exited.success(), "{exited}");
    // The timeline stays, drawn once more after the executive left: both approvals in it.
    let bars = until(
        &c,
        "the whole timeline after the end",
        r#"const d = document.getElementById('ops-timeline').contentDocument;
           const ids = d ? [...d.querySelectorAll('rect.bar')].map(b => b.dataset.element) : [];
           return ids.includes('quick') && ids.includes('slow') && ids"#,
    )
    .await;
    assert!(bars.as_array().is_some_and(|b| b.len() >= 2), "{bars}");
    // The record says the same: one answer, by ana at the studio's station.
    let record = std::fs::read_to_string(store.join("record.jsonl")).expect("record");
    let answered: Vec<Value> = record
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["kind"] == "user_task_answered")
        .collect();
    assert_eq!(answered.len(), 1, "{answered:?}");
    assert_eq!(answered[0]["operator"], "ana@web");
    let errors = js(&c, "return studio.errors", vec![]).await;
    assert_eq!(errors, json!([]), "errors in the page");
}
