//! Operations in TRACE Studio, in headless Chromium during a real `trace fly` (simulator, a
//! terminal ground station that never answers, the studio as a second station): the page lists
//! the executive, draws its model, shows the tokens of the state query at the same step, draws
//! the timeline from the executive's record as it grows (a bar selects its element, an element
//! outlines its bars), answers the site approval as operator `ana` at station `web` (recorded
//! as `ana@web`, the terminal station told), says plainly when the executive is gone, follows it
//! again, its reboot marked, when it is resumed; the flight's record, replayed through the
//! engine on the mission in the composer, shows at a chosen step the tokens its lines leave;
//! and a fleet's executives (`trace fly --fleet`) are followed at once on one diagram.

use std::io::{BufRead, BufReader};
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};

use fantoccini::{Client, Locator};
use mission_tests::{bin, repo};
use serde_json::{Value, json};

use crate::protocol::tempdir;
use crate::studio::{Kill, Page, WAIT, click, js, start, until, until_within};

/// A child started in a process group of its own (`process_group(0)`), killed whole when
/// dropped: `trace fly` and its simulator, a station.
pub(crate) struct Group(pub(crate) Kill);

impl Drop for Group {
    fn drop(&mut self) {
        // The group's id is its leader's pid (never 0 here: a child's id).
        let _ = Command::new("kill")
            .args(["-s", "KILL", "--", &format!("-{}", self.0.0.id())])
            .status();
        let _ = self.0.0.wait();
    }
}

/// `trace studio` on `missions`, joined to a flight by `join`, as the ground station `web`.
fn station_studio(missions: &std::path::Path, join: &[String]) -> Page {
    let mut studio = Command::new(bin("trace"));
    studio
        .arg("studio")
        .arg(missions)
        .args(["--port", "0", "--station", "web", "--catalogue"])
        .arg(repo().join("deploy/ground/forms.json"))
        .args(join);
    Page::start(studio)
}

#[test]
fn operations_follow_a_flying_mission_on_its_diagram() {
    let dir = tempdir("studio-ops");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    // The mission the composer holds, for replaying the flight's record on it.
    std::fs::copy(
        repo().join("deploy/missions/europa-bsm1.bpmn"),
        missions.join("europa-bsm1.bpmn"),
    )
    .expect("europa");
    // The ground answers nothing: the mission waits at its first site approval (six mission
    // hours, 21 s at this speed), long enough to compare the page with the executive.
    let mut fly = Command::new(bin("trace"));
    fly.args(["fly", "--no-ground", "--speed", "1000", "--dir"])
        .arg(dir.join("flight"))
        .process_group(0);
    let (fly, watch) = start(fly, "watch with:");
    let fly = Group(fly);
    let join: Vec<String> = watch
        .split_once("trace monitor ")
        .expect("the join flags")
        .1
        .split_whitespace()
        .map(str::to_owned)
        .collect();
    let hub = join[1].clone();
    let deployment = join[3].clone();
    // A terminal ground station whose operator never answers (its input held open): the
    // executive needs a ground catalogue to start.
    let mut station = Command::new(bin("ground-station"));
    station
        .args([
            "--interactive",
            "--operator",
            "nobody",
            "--station",
            "console",
        ])
        .args(&join)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .process_group(0);
    let mut station = station.spawn().expect("ground-station starts");
    // Everything the terminal station says, line by line as it says it.
    let (tell, said) = tokio::sync::mpsc::unbounded_channel::<String>();
    let out = station.stdout.take().expect("stdout");
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            let _ = tell.send(line);
        }
    });
    let _station = Group(Kill(station));
    // The studio is a ground station too: the page answers through it.
    let page = station_studio(&missions, &join);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    // The scratch directory stays with the test (it is removed when dropped): the block gets
    // its path.
    let path = dir.to_path_buf();
    rt.block_on(async move {
        let session = crate::protocol::open(&[], std::slice::from_ref(&hub)).await;
        let keys = connector_api::Keys::deployed(connector_api::keys::DEFAULT_ROOT, &deployment)
            .expect("keys");
        let c = page.browser().await;
        let flight = Flight {
            fly,
            dir: path,
            said,
            join: join.clone(),
        };
        let outcome = tokio::spawn(ops_scenario(
            c.clone(),
            page.url.clone(),
            session,
            keys,
            flight,
        ))
        .await;
        let _ = c.close().await;
        if let Err(e) = outcome {
            std::panic::resume_unwind(e.into_panic());
        }
    });
}

/// The flight the operations view follows: `trace fly` (killed when dropped), its directory,
/// what the terminal station said, and the flags that join its network.
struct Flight {
    fly: Group,
    dir: std::path::PathBuf,
    said: tokio::sync::mpsc::UnboundedReceiver<String>,
    join: Vec<String>,
}

async fn ops_scenario(
    c: Client,
    url: String,
    session: zenoh::Session,
    keys: connector_api::Keys,
    flight: Flight,
) {
    let Flight {
        fly,
        dir,
        mut said,
        join,
    } = flight;
    c.goto(&url).await.expect("the studio's page");
    until(
        &c,
        "the page ready",
        "return document.body.dataset.ready === 'true'",
    )
    .await;
    click(&c, "#ops-toggle").await;
    let listed = until(
        &c,
        "the executive listed",
        "return document.body.dataset.executives",
    )
    .await;
    let mission = listed.as_str().expect("a mission id").to_owned();
    until(
        &c,
        "its model drawn and its state shown",
        "return studio.ops.viewer.get('elementRegistry').get('ApproveSite') && document.body.dataset.opsSeq",
    )
    .await;
    // Waiting for the ground: the page's tokens are the executive's at the same step.
    until(
        &c,
        "the approval waiting",
        "return (document.body.dataset.opsTokens || '').includes('ApproveSite')",
    )
    .await;
    let began = std::time::Instant::now();
    loop {
        let page = js(
            &c,
            "return { seq: Number(document.body.dataset.opsSeq), tokens: JSON.parse(document.body.dataset.opsTokens),
               badges: [...document.querySelectorAll('.djs-overlay-ops .trace-token')].length }",
            vec![],
        )
        .await;
        let replies = session
            .get(keys.exec_state(&mission))
            .await
            .expect("a state query");
        let reply = replies.recv_async().await.expect("a state reply");
        let state: Value =
            serde_json::from_slice(&reply.result().expect("a state").payload().to_bytes())
                .expect("JSON");
        if state["seq"] == page["seq"] {
            assert_eq!(state["tokens"], page["tokens"], "at step {}", state["seq"]);
            let elements = state["tokens"].as_object().expect("tokens").len();
            assert!(
                page["badges"]
                    .as_u64()
                    .is_some_and(|b| b as usize >= elements.min(1)),
                "{page}"
            );
            break;
        }
        assert!(
            began.elapsed() < WAIT,
            "the page never showed the step of the state: {page} / {}",
            state["seq"]
        );
    }
    let flight = js(
        &c,
        "return [...document.querySelectorAll('#ops-flight li')].map(li => li.dataset.element)",
        vec![],
    )
    .await;
    assert!(
        flight
            .as_array()
            .is_some_and(|f| f.contains(&json!("ApproveSite"))),
        "{flight}"
    );
    // The site approval answered from the page: typed fields, an operator's name required.
    let form = r#"#ground-tasks .ground-task[data-task="ApproveSite"]"#;
    until(
        &c,
        "the approval on the page's desk",
        &format!("return !!document.querySelector('{form}')"),
    )
    .await;
    let shot = c.screenshot().await.expect("screenshot");
    std::fs::write(dir.join("studio-ops.png"), shot).expect("screenshot file");
    js(&c, "document.getElementById('operator').value = ''", vec![]).await;
    click(&c, &format!("{form} button")).await;
    let refused = until(
        &c,
        "no answer without an operator",
        &format!(
            "const r = document.querySelector('{form} .answer-error'); return r && r.textContent"
        ),
    )
    .await;
    assert!(
        refused.as_str().is_some_and(|r| r.contains("operator")),
        "{refused}"
    );
    js(
        &c,
        &format!(
            "document.getElementById('operator').value = 'ana';
             document.querySelector('{form} select[name=approve]').value = 'true';
             document.querySelector('{form} input[name=comment]').value = 'go';"
        ),
        vec![],
    )
    .await;
    click(&c, &format!("{form} button")).await;
    let outcome = until(
        &c,
        "the executive's verdict",
        &format!("const b = document.querySelector('{form}'); return b && b.dataset.outcome"),
    )
    .await;
    assert_eq!(outcome, "applied");
    // The executive recorded who answered (the line arrives on the page's record stream after
    // it is written to the file), and the other station was told.
    until(
        &c,
        "the answer in the record stream",
        "return studio.ops.lines().some(l => l.kind === 'user_task_answered')",
    )
    .await;
    let record = std::fs::read_to_string(dir.join("flight/store/record.jsonl")).expect("record");
    let line = record
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find(|v| v["kind"] == "user_task_answered")
        .expect("user_task_answered in the record");
    assert_eq!(line["operator"], "ana@web", "{line}");
    assert_eq!(line["answer"]["approve"], true, "{line}");
    let mut heard = Vec::new();
    while !heard
        .last()
        .is_some_and(|l: &String| l.contains("closed: answered by ana@web"))
    {
        match tokio::time::timeout(WAIT, said.recv()).await {
            Ok(Some(l)) => heard.push(l),
            _ => panic!("the terminal station was not told: {heard:?}"),
        }
    }
    // The timeline below the diagram: drawn from the executive's record, growing with it, and
    // selecting with the diagram both ways.
    let bars = |min: u64| {
        format!(
            "return Number(document.body.dataset.opsTimelineBars || 0) > {min} && Number(document.body.dataset.opsTimelineBars)"
        )
    };
    let first = until(&c, "the timeline drawn", &bars(0)).await;
    let first = first.as_u64().expect("bars");
    until(&c, "the timeline grown with the record", &bars(first)).await;
    js(
        &c,
        r#"const d = document.getElementById('ops-timeline').contentDocument;
           d.querySelector('rect.bar[data-element="ApproveSite"]').dispatchEvent(new MouseEvent('click', { bubbles: true }));"#,
        vec![],
    )
    .await;
    until(
        &c,
        "the bar's element selected on the diagram",
        "return document.body.dataset.opsSelected === 'ApproveSite'
           && studio.ops.viewer.get('canvas').hasMarker('ApproveSite', 'ops-selected')",
    )
    .await;
    js(
        &c,
        "const v = studio.ops.viewer;
         v.get('eventBus').fire('element.click', { element: v.get('elementRegistry').get('CapturePanorama') });",
        vec![],
    )
    .await;
    until(
        &c,
        "the element's bars outlined in the timeline",
        r#"const d = document.getElementById('ops-timeline').contentDocument;
           const b = [...d.querySelectorAll('rect.bar[data-element="CapturePanorama"]')];
           return b.length && b.every(r => r.classList.contains('selected'))
             && !d.querySelector('rect.bar.selected:not([data-element="CapturePanorama"])')"#,
    )
    .await;
    // The executive killed: the page says so plainly.
    drop(fly);
    let gone = until(
        &c,
        "the executive gone",
        "return document.body.dataset.opsGone === 'true' && document.getElementById('ops-status').textContent",
    )
    .await;
    assert!(gone.as_str().is_some_and(|g| g.contains("gone")), "{gone}");
    // Resumed, on the same store, endpoint and deployment: the page follows again and marks
    // the reboot.
    let hub = join[1].clone();
    let mut sim = Command::new(bin("elap-sim"));
    sim.args([
        "--speed",
        "1000",
        "--seed",
        "1",
        "--profile",
        "nominal",
        "--store",
    ])
    .arg(dir.join("flight/sim"))
    .args(&join)
    .process_group(0);
    let (sim, _) = start(sim, "ready");
    let _sim = Group(sim);
    let mut exec = Command::new(bin("trace"));
    exec.args(["resume", "--store"])
        .arg(dir.join("flight/store"))
        .arg("--connectors")
        .arg(dir.join("flight/connectors.toml"))
        .args(["-l", &hub, "--deployment", &join[3]])
        .stdout(Stdio::null())
        .process_group(0);
    let _exec = Group(Kill(exec.spawn().expect("trace resume starts")));
    let back = until(
        &c,
        "the executive back, its reboot marked",
        "return document.body.dataset.opsBack && document.body.dataset.opsReboots
           && document.body.dataset.opsGone === '' && document.getElementById('ops-status').textContent",
    )
    .await;
    assert!(back.as_str().is_some_and(|b| b.contains("step")), "{back}");
    // The record so far (a kill, a resume and a reboot in it), replayed on the mission in the
    // composer: at the step the approval was answered, the engine's tokens are those the
    // record's own entered/left/withdrawn lines leave.
    let copy = dir.join("record-so-far.jsonl");
    std::fs::copy(dir.join("flight/store/record.jsonl"), &copy).expect("record copy");
    let text = std::fs::read_to_string(&copy).expect("record");
    let lines: Vec<Value> = text
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let answered_at = lines
        .iter()
        .find(|v| v["kind"] == "user_task_answered")
        .and_then(|v| v["seq"].as_u64())
        .expect("the answer's step");
    let mut seen = std::collections::BTreeSet::new();
    let mut at: std::collections::BTreeMap<u64, String> = std::collections::BTreeMap::new();
    for v in &lines {
        let (Some(seq), Some(idx)) = (v["seq"].as_u64(), v["idx"].as_u64()) else {
            continue;
        };
        if seq > answered_at || !seen.insert((seq, idx)) {
            continue;
        }
        let token = v["token"].as_u64();
        match (v["kind"].as_str(), token) {
            (Some("entered"), Some(t)) => {
                at.insert(t, v["element"]["id"].as_str().unwrap_or("?").to_owned());
            }
            (Some("left" | "withdrawn"), Some(t)) => {
                at.remove(&t);
            }
            _ => {}
        }
    }
    let mut expected = serde_json::Map::new();
    for element in at.values() {
        let n = expected.get(element).and_then(Value::as_u64).unwrap_or(0);
        expected.insert(element.clone(), json!(n + 1));
    }
    click(&c, "#ops-toggle").await;
    c.find(Locator::Css("#record-file"))
        .await
        .expect("the record input")
        .send_keys(&copy.display().to_string())
        .await
        .expect("the record chosen");
    let frames = until(
        &c,
        "the record replayed",
        "return document.body.dataset.recordFrames",
    )
    .await;
    assert!(
        frames
            .as_str()
            .and_then(|f| f.parse::<usize>().ok())
            .is_some_and(|n| n > 10),
        "{frames}"
    );
    js(&c, &format!("studio.recording.at({answered_at})"), vec![]).await;
    let shown = js(
        &c,
        "return { seq: Number(document.body.dataset.recordSeq), tokens: JSON.parse(document.body.dataset.recordTokens) }",
        vec![],
    )
    .await;
    assert_eq!(shown["seq"], json!(answered_at));
    assert_eq!(
        shown["tokens"],
        Value::Object(expected),
        "at step {answered_at}"
    );
    let errors = js(&c, "return studio.errors", vec![]).await;
    assert_eq!(errors, json!([]), "errors in the page");
}

// A fleet followed at once: the lander's and the scout's executives (`trace fly --fleet`),
// each pool's tokens on the one diagram, and each message flow a message crossed marked.
#[test]
fn operations_follow_every_executive_of_a_fleet_on_one_diagram() {
    let dir = tempdir("studio-ops-fleet");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    // Nobody answers the site approval: the lander waits there (six mission hours, 21 s at
    // this speed) after the scout's report came.
    let mut fly = Command::new(bin("trace"));
    fly.args(["fly", "--fleet", "--no-ground", "--speed", "1000", "--dir"])
        .arg(dir.join("flight"))
        .process_group(0);
    let (fly, watch) = start(fly, "watch with:");
    let _fly = Group(fly);
    let join: Vec<String> = watch
        .split_once("trace monitor ")
        .expect("the join flags")
        .1
        .split_whitespace()
        .map(str::to_owned)
        .collect();
    // The studio is the ground station the lander's executive needs to start.
    let page = station_studio(&missions, &join);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async move {
        let c = page.browser().await;
        let checked = async {
            c.goto(&page.url).await.expect("the studio's page");
            until(
                &c,
                "the page ready",
                "return document.body.dataset.ready === 'true'",
            )
            .await;
            click(&c, "#ops-toggle").await;
            // The scout's executive comes up after waiting for its catalogues, beside the
            // lander's, two simulators, a station and the browser: on a loaded two-core machine
            // that may take longer than a page's usual wait, so this one has the test's budget.
            until_within(
                &c,
                "both executives followed",
                "return document.body.dataset.opsFleet === 'lander scout'",
                std::time::Duration::from_secs(100),
            )
            .await;
            until(
                &c,
                "the lander waiting for the ground, the report heard",
                "return (document.body.dataset.opsTokens || '').includes('ApproveSite')
                   && (document.body.dataset.opsMessageFlows || '').includes('mf_report')",
            )
            .await;
            let marks = js(
                &c,
                "const canvas = studio.ops.viewer.get('canvas');
                 return ['mf_request', 'mf_report'].map(f => canvas.hasMarker(f, 'ops-message'))
                   .concat([document.getElementById('ops-status').textContent]);",
                vec![],
            )
            .await;
            assert_eq!(marks[0], true, "{marks}");
            assert_eq!(marks[1], true, "{marks}");
            assert!(
                marks[2]
                    .as_str()
                    .unwrap_or_default()
                    .starts_with("fleet: lander, scout"),
                "{marks}"
            );
        };
        let outcome = tokio::time::timeout(std::time::Duration::from_secs(120), checked).await;
        let _ = c.close().await;
        outcome.expect("the fleet was followed within two minutes");
    });
}
