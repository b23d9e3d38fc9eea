//! The Zenoh activity protocol on loopback, with real sessions (multicast off, a port per
//! test) and a real killed process: goal → feedback → result, rejection, cancel, duplicate goal
//! ids, reconciliation after an executive restart, CONNECTOR_LOST, a result surviving a router
//! restart, and garbage on every key. Everything waits on replies, reports or liveliness.

use std::collections::BTreeMap;
use std::process::{Child, Stdio};
use std::time::Duration;

use connector_api::wire::{Fields, Status, StatusMsg};
use connector_api::{
    ActionSpec, Catalogue, Channel, Command, Connector, ConnectorConfig, Keys, Kind, Report,
};
use connector_zenoh::mock::{self, Behaviour, MockSpec};
use connector_zenoh::{
    ActionServer, ClientOptions, Request, Role, ServerOptions, ZenohArgs, ZenohConnector,
};
use serde_json::json;
use tokio::sync::mpsc;
use zenoh::Session;

/// A free loopback port.
pub(crate) fn port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

pub(crate) fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// Zenoh flags for a peer that listens on and/or connects to loopback endpoints.
pub(crate) fn args(listen: &[String], connect: &[String]) -> ZenohArgs {
    ZenohArgs {
        listen: listen.to_vec(),
        connect: connect.to_vec(),
        no_multicast_scouting: true,
        root: "trace".into(),
        ..ZenohArgs::default()
    }
}

pub(crate) async fn open(listen: &[String], connect: &[String]) -> Session {
    args(listen, connect)
        .open(Role::Spoke)
        .await
        .expect("zenoh opens")
}

fn spec(name: &str) -> ActionSpec {
    serde_json::from_value(json!({
        "name": name,
        "goal": {"site": {"id": "int"}, "depth_cm": "f64?"},
        "result": {"depth_cm": "f64"},
        "errors": {"TOOL_STUCK": "the tool is stuck"}
    }))
    .expect("spec")
}

fn catalogue(server: &str, actions: &[&str]) -> Catalogue {
    Catalogue {
        server: server.into(),
        actions: actions.iter().map(|a| spec(a)).collect(),
        ..Catalogue::default()
    }
}

fn behaviour(entries: &[(&str, Behaviour)]) -> BTreeMap<String, Behaviour> {
    entries
        .iter()
        .map(|(k, b)| ((*k).to_owned(), b.clone()))
        .collect()
}

fn outputs() -> Fields {
    json!({"depth_cm": 12.5})
        .as_object()
        .cloned()
        .unwrap_or_default()
}

/// A bare server `lander` serving `dig`; the test plays the application.
async fn dig_server(session: &Session) -> (ActionServer, mpsc::UnboundedReceiver<Request>) {
    ActionServer::start(
        session,
        ServerOptions {
            keys: Keys::default(),
            catalogue: catalogue("lander", &["dig"]),
            store: None,
            accept: None,
            instance: None,
        },
    )
    .await
    .expect("server")
}

/// Serves a mock system in this process.
async fn serve(session: &Session, spec: MockSpec) -> ActionServer {
    let (server, requests) = ActionServer::start(
        session,
        ServerOptions {
            keys: Keys::default(),
            catalogue: spec.catalogue.clone(),
            store: None,
            accept: None,
            instance: None,
        },
    )
    .await
    .expect("server starts");
    tokio::spawn(mock::run(spec, requests, Vec::new()));
    server
}

fn connector_config(server: &str, grace_ms: u64) -> ConnectorConfig {
    ConnectorConfig {
        name: server.into(),
        kind: Kind::Zenoh,
        server: Some(server.into()),
        resources: vec!["*".into()],
        actions: BTreeMap::new(),
        data: vec!["battery_soc_pct".into()],
        deadband: [("battery_soc_pct".to_owned(), 1.0)].into(),
        grace_ms,
        clock: false,
        answers: false,
        limits: Default::default(),
        ros2: Default::default(),
    }
}

pub(crate) async fn connector(
    session: &Session,
    server: &str,
    grace_ms: u64,
) -> (ZenohConnector, mpsc::UnboundedReceiver<Report>) {
    let (tx, rx) = mpsc::unbounded_channel();
    let mut c = ZenohConnector::new(
        session,
        ClientOptions {
            keys: Keys::default(),
            config: connector_config(server, grace_ms),
            client: "test-exec".into(),
            mission: "m".into(),
            catalogue_wait: Duration::from_secs(20),
            query_timeout: Duration::from_secs(5),
        },
        tx,
    )
    .await
    .expect("connector");
    // The catalogue answers once routing between the two sessions has converged.
    c.catalogue().await.expect("catalogue");
    (c, rx)
}

/// The next report matching `want`, skipping others; fails after a generous bound.
pub(crate) async fn expect(
    rx: &mut mpsc::UnboundedReceiver<Report>,
    want: impl Fn(&Report) -> bool,
) -> Report {
    let found = tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            match rx.recv().await {
                Some(r) if want(&r) => return r,
                Some(_) => {}
                None => panic!("report channel closed"),
            }
        }
    })
    .await;
    found.expect("the expected report arrived")
}

pub(crate) fn command(goal_id: &str, action: &str, fields: serde_json::Value) -> Command {
    Command {
        goal_id: goal_id.into(),
        action: action.into(),
        fields: fields.as_object().cloned().unwrap_or_default(),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn goal_feedback_result_and_failure() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let exec = open(&[], &[p]).await;
    let _server = serve(
        &sys,
        MockSpec {
            clock: None,
            catalogue: catalogue("lander", &["dig", "drill"]),
            behaviour: behaviour(&[
                (
                    "dig",
                    Behaviour {
                        duration_ms: 30,
                        feedback: 3,
                        outputs: outputs(),
                        ..Behaviour::default()
                    },
                ),
                (
                    "drill",
                    Behaviour {
                        fail: Some("TOOL_STUCK".into()),
                        fail_attempts: vec![1],
                        outputs: outputs(),
                        ..Behaviour::default()
                    },
                ),
            ]),
        },
    )
    .await;
    let (mut c, mut rx) = connector(&exec, "lander", 5000).await;
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 4}})));
    expect(
        &mut rx,
        |r| matches!(r, Report::Accepted { goal_id } if goal_id == "m.1.1.1"),
    )
    .await;
    let fb = expect(&mut rx, |r| matches!(r, Report::Feedback { .. })).await;
    assert!(matches!(fb, Report::Feedback { progress_pct: Some(p), .. } if p > 0.0));
    let done = expect(&mut rx, |r| matches!(r, Report::Done { .. })).await;
    assert_eq!(
        done,
        Report::Done {
            goal_id: "m.1.1.1".into(),
            outputs: outputs()
        }
    );
    // Attempt 1 of drill fails with the declared code; attempt 2 succeeds.
    c.execute(command("m.1.2.1", "drill", json!({"site": {"id": 4}})));
    let failed = expect(&mut rx, |r| matches!(r, Report::Failed { .. })).await;
    assert!(
        matches!(&failed, Report::Failed { goal_id, code, .. } if goal_id == "m.1.2.1" && code == "TOOL_STUCK"),
        "{failed:?}"
    );
    c.execute(command("m.1.2.2", "drill", json!({"site": {"id": 4}})));
    expect(
        &mut rx,
        |r| matches!(r, Report::Done { goal_id, .. } if goal_id == "m.1.2.2"),
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mistyped_and_refused_goals_are_rejected_with_the_reason() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let exec = open(&[], &[p]).await;
    let (server, mut requests) = ActionServer::start(
        &sys,
        ServerOptions {
            keys: Keys::default(),
            catalogue: catalogue("lander", &["dig"]),
            store: None,
            accept: Some(std::sync::Arc::new(|_, f: &Fields| {
                if f.get("depth_cm").and_then(|d| d.as_f64()) > Some(100.0) {
                    Err("deeper than the arm reaches".into())
                } else {
                    Ok(())
                }
            })),
            instance: None,
        },
    )
    .await
    .expect("server");
    let (mut c, mut rx) = connector(&exec, "lander", 5000).await;
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": "four"}})));
    let r = expect(&mut rx, |r| matches!(r, Report::Failed { .. })).await;
    let Report::Failed { code, message, .. } = r else {
        unreachable!()
    };
    assert_eq!(code, "REJECTED");
    assert_eq!(message, "`site.id` must be int, got a string");
    c.execute(command(
        "m.1.2.1",
        "dig",
        json!({"site": {"id": 1}, "depth_cm": 500}),
    ));
    let r = expect(&mut rx, |r| matches!(r, Report::Failed { .. })).await;
    assert!(
        matches!(&r, Report::Failed { message, .. } if message == "deeper than the arm reaches"),
        "{r:?}"
    );
    // A rejected goal id stays rejected when repeated, and the application never saw it.
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    let r = expect(&mut rx, |r| matches!(r, Report::Failed { .. })).await;
    assert!(matches!(&r, Report::Failed { goal_id, .. } if goal_id == "m.1.1.1"));
    assert!(requests.try_recv().is_err());
    assert_eq!(server.status("m.1.1.1"), Some(Status::Rejected));
}

/// Subscribes to an action's status stream (to watch the server side).
async fn statuses(
    session: &Session,
    server: &str,
    action: &str,
) -> mpsc::UnboundedReceiver<StatusMsg> {
    let (tx, rx) = mpsc::unbounded_channel();
    let sub = session
        .declare_subscriber(Keys::default().stream(server, action, Channel::Status))
        .callback(move |s| {
            if let Ok(m) = serde_json::from_slice::<StatusMsg>(&s.payload().to_bytes()) {
                let _ = tx.send(m);
            }
        })
        .await
        .expect("subscriber");
    // Keep the subscriber declared for the session's life.
    std::mem::forget(sub);
    rx
}

async fn until_status(rx: &mut mpsc::UnboundedReceiver<StatusMsg>, goal: &str, status: Status) {
    tokio::time::timeout(Duration::from_secs(30), async {
        while let Some(m) = rx.recv().await {
            if m.goal_id == goal && m.status == status {
                return;
            }
        }
    })
    .await
    .expect("status reached");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_mid_goal() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let exec = open(&[], &[p]).await;
    let server = serve(
        &sys,
        MockSpec {
            clock: None,
            catalogue: catalogue("lander", &["dig"]),
            behaviour: behaviour(&[(
                "dig",
                Behaviour {
                    hang: true,
                    ..Behaviour::default()
                },
            )]),
        },
    )
    .await;
    let mut status = statuses(&exec, "lander", "dig").await;
    let (mut c, mut rx) = connector(&exec, "lander", 5000).await;
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    until_status(&mut status, "m.1.1.1", Status::Executing).await;
    expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
    c.abort("m.1.1.1");
    until_status(&mut status, "m.1.1.1", Status::Canceling).await;
    until_status(&mut status, "m.1.1.1", Status::Canceled).await;
    assert_eq!(server.status("m.1.1.1"), Some(Status::Canceled));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_repeated_goal_id_is_answered_with_the_same_goal() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let exec = open(&[], &[p]).await;
    let (_server, mut requests) = dig_server(&sys).await;
    let (mut c, mut rx) = connector(&exec, "lander", 5000).await;
    let goal = json!({"goal_id": "m.1.1.1", "fields": {"site": {"id": 1}}}).to_string();
    let key = Keys::default().goal("lander", "dig", Channel::Goal, "m.1.1.1");
    for _ in 0..2 {
        let replies = exec.get(&key).payload(goal.clone()).await.expect("get");
        let reply = replies.recv_async().await.expect("a reply");
        let body: serde_json::Value =
            serde_json::from_slice(&reply.result().expect("ok").payload().to_bytes())
                .expect("json");
        assert_eq!(body["status"], "ACCEPTED", "{body}");
    }
    // The connector's own send of the same id joins the goal already running.
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
    let Some(Request::Goal(h)) = requests.recv().await else {
        panic!("one goal")
    };
    assert!(requests.try_recv().is_err(), "the goal was started twice");
    h.succeed(outputs()).await;
    let done = expect(&mut rx, |r| matches!(r, Report::Done { .. })).await;
    assert!(matches!(done, Report::Done { goal_id, .. } if goal_id == "m.1.1.1"));
    // After completion a repeat returns the result, not a new run.
    let replies = exec.get(&key).payload(goal).await.expect("get");
    let reply = replies.recv_async().await.expect("a reply");
    let body: serde_json::Value =
        serde_json::from_slice(&reply.result().expect("ok").payload().to_bytes()).expect("json");
    assert_eq!(body["status"], "SUCCEEDED");
    assert_eq!(body["result"]["outputs"]["depth_cm"], 12.5);
    assert!(requests.try_recv().is_err());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_executive_restart_reconciles_goals_in_flight() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let (_server, mut requests) = dig_server(&sys).await;
    // First executive: sends two goals, then dies.
    let exec1 = open(&[], std::slice::from_ref(&p)).await;
    let mut status = statuses(&sys, "lander", "dig").await;
    let (mut c1, mut rx1) = connector(&exec1, "lander", 5000).await;
    c1.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    c1.execute(command("m.1.2.1", "dig", json!({"site": {"id": 2}})));
    for _ in 0..2 {
        expect(&mut rx1, |r| matches!(r, Report::Accepted { .. })).await;
    }
    exec1.close().await.expect("close");
    drop((c1, rx1));
    let mut goals = BTreeMap::new();
    for _ in 0..2 {
        let Some(Request::Goal(h)) = requests.recv().await else {
            panic!("goal")
        };
        goals.insert(h.goal_id.clone(), h);
    }
    // While it is down, the first goal finishes.
    goals["m.1.1.1"].succeed(outputs()).await;
    until_status(&mut status, "m.1.1.1", Status::Succeeded).await;
    // The restarted executive reconciles: finished → result; running → waits; unknown → lost.
    let exec2 = open(&[], &[p]).await;
    let (mut c2, mut rx2) = connector(&exec2, "lander", 5000).await;
    c2.reconcile(command("m.1.1.1", "dig", json!({})));
    c2.reconcile(command("m.1.2.1", "dig", json!({})));
    c2.reconcile(command("m.1.3.1", "dig", json!({})));
    let done = expect(&mut rx2, |r| {
        matches!(r, Report::Done { .. } | Report::Failed { .. })
    })
    .await;
    let lost = expect(&mut rx2, |r| {
        matches!(r, Report::Done { .. } | Report::Failed { .. })
    })
    .await;
    let (done, lost) = if matches!(done, Report::Done { .. }) {
        (done, lost)
    } else {
        (lost, done)
    };
    assert!(
        matches!(&done, Report::Done { goal_id, .. } if goal_id == "m.1.1.1"),
        "{done:?}"
    );
    assert!(
        matches!(&lost, Report::Failed { goal_id, code, .. } if goal_id == "m.1.3.1" && code == "CONNECTOR_LOST"),
        "{lost:?}"
    );
    goals["m.1.2.1"].succeed(outputs()).await;
    let r = expect(&mut rx2, |r| matches!(r, Report::Done { .. })).await;
    assert!(matches!(r, Report::Done { goal_id, .. } if goal_id == "m.1.2.1"));
}

/// Starts the mock system binary; returns once it says it is serving.
pub(crate) fn mock_process(spec: &serde_json::Value, listen: &str, dir: &std::path::Path) -> Child {
    use std::io::BufRead;
    let file = dir.join("mock.json");
    std::fs::write(&file, spec.to_string()).expect("spec written");
    let mut child = std::process::Command::new(mission_tests::bin("trace-mock-system"))
        .arg(&file)
        .args(["--listen", listen, "--no-multicast-scouting"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("mock system starts");
    let out = child.stdout.take().expect("stdout");
    let mut line = String::new();
    std::io::BufReader::new(out)
        .read_line(&mut line)
        .expect("ready line");
    assert!(line.starts_with("ready"), "{line}");
    child
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_killed_mid_goal_yields_connector_lost() {
    let dir = tempdir("killed");
    let p = endpoint(port());
    let spec = json!({
        "catalogue": catalogue("lander", &["dig"]),
        "behaviour": {"dig": {"hang": true}}
    });
    let mut child = mock_process(&spec, &p, &dir);
    let exec = open(&[], &[p]).await;
    let (mut c, mut rx) = connector(&exec, "lander", 300).await;
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
    child.kill().expect("kill -9");
    child.wait().expect("reaped");
    let r = expect(&mut rx, |r| matches!(r, Report::Failed { .. })).await;
    let Report::Failed {
        goal_id,
        code,
        message,
    } = r
    else {
        unreachable!()
    };
    assert_eq!(
        (goal_id.as_str(), code.as_str()),
        ("m.1.1.1", "CONNECTOR_LOST")
    );
    assert!(
        message.contains("did not return within 300 ms"),
        "{message}"
    );
}

/// A test's own directory under the system's temp dir, removed when the test passes (kept, with
/// what the test left there, when it fails): flights copy binaries and stores into theirs, and
/// the leftovers of many runs filled this machine's disk.
pub(crate) struct Scratch(std::path::PathBuf);

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for Scratch {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

pub(crate) fn tempdir(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("trace-it-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    Scratch(d)
}

pub(crate) async fn router(port: u16) -> Session {
    let a = ZenohArgs {
        mode: Some("router".into()),
        ..args(&[endpoint(port)], &[])
    };
    a.open(Role::Spoke).await.expect("router opens")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_result_published_while_the_router_is_down_is_not_lost() {
    let rp = port();
    let r1 = router(rp).await;
    let client = |p: u16| ZenohArgs {
        mode: Some("client".into()),
        ..args(&[], &[endpoint(p)])
    };
    let sys = client(rp).open(Role::Spoke).await.expect("system");
    let exec = client(rp).open(Role::Spoke).await.expect("executive");
    let (_server, mut requests) = dig_server(&sys).await;
    let (mut c, mut rx) = connector(&exec, "lander", 60_000).await;
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
    let Some(Request::Goal(h)) = requests.recv().await else {
        panic!("goal")
    };
    r1.close().await.expect("router stops");
    // Published with nobody to route it: `put` succeeds and the sample is gone.
    assert!(h.succeed(outputs()).await);
    let _r2 = router(rp).await;
    // The server's liveliness comes back through the new router; the connector asks for the
    // goal's state and gets the result.
    let done = expect(&mut rx, |r| matches!(r, Report::Done { .. })).await;
    assert!(matches!(done, Report::Done { goal_id, .. } if goal_id == "m.1.1.1"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_on_any_key_is_refused_and_both_sides_keep_working() {
    let p = endpoint(port());
    let sys = open(std::slice::from_ref(&p), &[]).await;
    let exec = open(&[], &[p]).await;
    let _server = serve(
        &sys,
        MockSpec {
            clock: None,
            catalogue: catalogue("lander", &["dig"]),
            behaviour: behaviour(&[(
                "dig",
                Behaviour {
                    outputs: outputs(),
                    ..Behaviour::default()
                },
            )]),
        },
    )
    .await;
    let (mut c, mut rx) = connector(&exec, "lander", 5000).await;
    let k = Keys::default();
    let garbage: [&[u8]; 4] = [
        b"\xff\xfe",
        b"{",
        b"[1,2]",
        br#"{"goal_id":"m.1.1.1","status":"BOGUS","seq":1}"#,
    ];
    for g in garbage {
        for ch in [Channel::Status, Channel::Feedback, Channel::Result] {
            exec.put(k.stream("lander", "dig", ch), g.to_vec())
                .await
                .expect("put");
        }
        exec.put(k.telemetry("lander", "power"), g.to_vec())
            .await
            .expect("put");
        for ch in [Channel::Goal, Channel::Cancel, Channel::State] {
            let replies = exec
                .get(k.goal("lander", "dig", ch, "m.9.9.9"))
                .payload(g.to_vec())
                .await
                .expect("get");
            let reply = replies.recv_async().await.expect("an answer");
            if ch == Channel::Goal {
                let err = reply.result().expect_err("garbage goal refused");
                let text = String::from_utf8_lossy(&err.payload().to_bytes()).into_owned();
                assert!(
                    text.starts_with(
                        "malformed goal payload on trace/default/act/lander/dig/goal/m.9.9.9"
                    ),
                    "{text}"
                );
            }
        }
    }
    // A goal whose id differs from its key, and one for an action not served.
    let replies = exec
        .get(k.goal("lander", "dig", Channel::Goal, "m.9.9.9"))
        .payload(json!({"goal_id": "other", "fields": {}}).to_string())
        .await
        .expect("get");
    let err = replies
        .recv_async()
        .await
        .expect("answer")
        .result()
        .expect_err("refused")
        .payload()
        .to_bytes()
        .into_owned();
    assert!(String::from_utf8_lossy(&err).contains("differs from the key"));
    // Telemetry with a wrongly typed value is fed as data only when it parses as telemetry.
    exec.put(
        k.telemetry("lander", "power"),
        json!({"mission_ms": 5, "values": {"battery_soc_pct": 80.0}}).to_string(),
    )
    .await
    .expect("put");
    let data = expect(&mut rx, |r| matches!(r, Report::Data { .. })).await;
    assert_eq!(
        data,
        Report::Data {
            key: "battery_soc_pct".into(),
            value: json!(80.0)
        }
    );
    c.execute(command("m.1.1.1", "dig", json!({"site": {"id": 1}})));
    let done = expect(&mut rx, |r| matches!(r, Report::Done { .. })).await;
    assert!(matches!(done, Report::Done { goal_id, .. } if goal_id == "m.1.1.1"));
}

/// Servers that misbehave on purpose, written by hand on raw Zenoh: every wait of the
/// connector has an end with a declared code, and whatever it refuses is counted (and logged)
/// instead of reaching the mission.
mod misbehaving {
    use super::*;
    use connector_api::contract::{Dropped, Limits};
    use tokio::sync::watch;
    use zenoh::Wait;
    use zenoh::liveliness::LivelinessToken;
    use zenoh::query::{Query, Queryable};

    /// `lander` serving `dig` by hand: the catalogue is served and the action announced, and
    /// every goal and state query is handed to the test, which answers it — or not.
    struct RawServer {
        goals: mpsc::UnboundedReceiver<Query>,
        states: mpsc::UnboundedReceiver<Query>,
        session: Session,
        _token: LivelinessToken,
        _queryables: Vec<Queryable<()>>,
    }

    impl RawServer {
        async fn start(session: &Session, catalogue: Catalogue) -> RawServer {
            let k = Keys::default();
            let body = serde_json::to_vec(&catalogue).expect("catalogue");
            let mut queryables = vec![
                session
                    .declare_queryable(k.catalogue("lander"))
                    .callback(move |q| {
                        let _ = q.reply(q.key_expr().clone(), body.clone()).wait();
                    })
                    .await
                    .expect("catalogue queryable"),
            ];
            let forward = |channel| {
                let (tx, rx) = mpsc::unbounded_channel();
                let q = session
                    .declare_queryable(k.goal_queryable("lander", "dig", channel))
                    .complete(true)
                    .callback(move |q| {
                        let _ = tx.send(q);
                    });
                (q, rx)
            };
            let (goal_q, goals) = forward(Channel::Goal);
            let (state_q, states) = forward(Channel::State);
            queryables.push(goal_q.await.expect("goal queryable"));
            queryables.push(state_q.await.expect("state queryable"));
            let token = session
                .liveliness()
                .declare_token(k.alive_action("lander", "dig"))
                .await
                .expect("token");
            RawServer {
                goals,
                states,
                session: session.clone(),
                _token: token,
                _queryables: queryables,
            }
        }

        async fn publish(&self, channel: Channel, body: serde_json::Value) {
            self.session
                .put(
                    Keys::default().stream("lander", "dig", channel),
                    body.to_string(),
                )
                .await
                .expect("put");
        }
    }

    async fn reply(q: &Query, body: serde_json::Value) {
        q.reply(q.key_expr().clone(), body.to_string())
            .await
            .expect("reply");
    }

    /// The catalogue of `lander`: `dig` with a result and a typed feedback field, and typed
    /// telemetry.
    fn lander() -> Catalogue {
        serde_json::from_value(json!({
            "server": "lander",
            "actions": [{
                "name": "dig",
                "goal": {"site": {"id": "int"}},
                "result": {"depth_cm": "f64"},
                "feedback": {"depth_cm": "f64"},
                "errors": {"TOOL_STUCK": "the tool is stuck"}
            }],
            "telemetry": {"battery_soc_pct": "f64"}
        }))
        .expect("catalogue")
    }

    async fn limited(
        session: &Session,
        limits: Limits,
        query_timeout: Duration,
        clock: bool,
    ) -> (ZenohConnector, mpsc::UnboundedReceiver<Report>) {
        let (tx, rx) = mpsc::unbounded_channel();
        let mut config = connector_config("lander", 60_000);
        config.clock = clock;
        let mut c = ZenohConnector::with_limits(
            session,
            ClientOptions {
                keys: Keys::default(),
                config,
                client: "test-exec".into(),
                mission: "m".into(),
                catalogue_wait: Duration::from_secs(20),
                query_timeout,
            },
            limits,
            tx,
        )
        .await
        .expect("connector");
        c.catalogue().await.expect("catalogue");
        (c, rx)
    }

    fn dig(goal_id: &str) -> Command {
        command(goal_id, "dig", json!({"site": {"id": 1}}))
    }

    /// The next report that ends a goal.
    async fn outcome(rx: &mut mpsc::UnboundedReceiver<Report>) -> Report {
        expect(rx, |r| {
            matches!(
                r,
                Report::Done { .. } | Report::Failed { .. } | Report::Canceled { .. }
            )
        })
        .await
    }

    fn failed(r: &Report) -> (&str, &str, &str) {
        match r {
            Report::Failed {
                goal_id,
                code,
                message,
            } => (goal_id, code, message),
            other => panic!("expected a failure, got {other:?}"),
        }
    }

    /// Waits until the connector has dropped `n` messages for `reason`.
    async fn dropped(drops: &mut watch::Receiver<Dropped>, reason: &str, n: u64) -> Dropped {
        let found = tokio::time::timeout(
            Duration::from_secs(30),
            drops.wait_for(|d| d.by_reason.get(reason).copied().unwrap_or(0) >= n),
        )
        .await;
        found
            .expect("the drops were counted")
            .expect("connector alive")
            .clone()
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_server_that_never_answers_a_goal_ends_it_with_not_accepted() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let limits = Limits {
            accept_within_ms: 2_000,
            retry_first_ms: 50,
            retry_max_ms: 400,
            ..Limits::default()
        };
        let (mut c, mut rx) =
            limited(&exec, limits.clone(), Duration::from_millis(300), false).await;
        c.execute(dig("m.1.1.1"));
        // The server holds every goal query and never replies.
        let mut held = vec![raw.goals.recv().await.expect("the goal arrives")];
        let r = outcome(&mut rx).await;
        let (goal_id, code, message) = failed(&r);
        assert_eq!((goal_id, code), ("m.1.1.1", "NOT_ACCEPTED"));
        assert!(
            message.contains("did not accept the goal within 2000 ms"),
            "{message}"
        );
        while let Ok(q) = raw.goals.try_recv() {
            held.push(q);
        }
        // Re-sent with backoff, not in a tight loop: never more than the schedule allows.
        assert!(
            held.len() <= limits.max_sends() as usize,
            "{} sends, the schedule allows {}",
            held.len(),
            limits.max_sends()
        );
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn garbage_results_published_about_a_running_goal_never_end_it() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let limits = Limits {
            retry_first_ms: 20,
            unreadable_max: 3,
            ..Limits::default()
        };
        let (mut c, mut rx) = limited(&exec, limits, Duration::from_secs(5), false).await;
        let mut drops = c.drops();
        c.execute(dig("m.1.1.1"));
        let q = raw.goals.recv().await.expect("goal");
        reply(&q, json!({"goal_id": "m.1.1.1", "status": "ACCEPTED"})).await;
        expect(
            &mut rx,
            |r| matches!(r, Report::Accepted { goal_id } if goal_id == "m.1.1.1"),
        )
        .await;
        // Ten unusable results naming the goal, more than unreadable_max: half do not parse,
        // half are not terminal.
        let k = Keys::default();
        for _ in 0..5 {
            sys.put(
                k.stream("lander", "dig", Channel::Result),
                br#"{"goal_id":"m.1.1.1","status":"#.to_vec(),
            )
            .await
            .expect("put");
            raw.publish(
                Channel::Result,
                json!({"goal_id": "m.1.1.1", "status": "EXECUTING"}),
            )
            .await;
        }
        dropped(&mut drops, "garbage", 5).await;
        dropped(&mut drops, "invalid_status", 5).await;
        // The server is asked instead, and says the goal runs.
        let q = tokio::time::timeout(Duration::from_secs(20), raw.states.recv())
            .await
            .expect("a state query within 20 s")
            .expect("a state query");
        reply(
            &q,
            json!({"goal_id": "m.1.1.1", "status": "EXECUTING", "seq": 2}),
        )
        .await;
        // Then the server's own result ends it.
        raw.publish(
            Channel::Result,
            json!({"goal_id": "m.1.1.1", "status": "SUCCEEDED", "outputs": {"depth_cm": 4.0}}),
        )
        .await;
        let r = tokio::time::timeout(Duration::from_secs(20), outcome(&mut rx))
            .await
            .expect("the goal ends within 20 s");
        assert!(
            matches!(&r, Report::Done { goal_id, .. } if goal_id == "m.1.1.1"),
            "{r:?}"
        );
        drop(c);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_terminal_status_without_its_result_ends_with_protocol_error() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let limits = Limits {
            retry_first_ms: 20,
            unreadable_max: 3,
            ..Limits::default()
        };
        let (mut c, mut rx) = limited(&exec, limits, Duration::from_secs(5), false).await;
        let mut drops = c.drops();
        c.execute(dig("m.1.1.1"));
        // The goal reply and every state reply say SUCCEEDED, and never carry the result.
        let q = raw.goals.recv().await.expect("goal");
        reply(&q, json!({"goal_id": "m.1.1.1", "status": "SUCCEEDED"})).await;
        let answer_states = tokio::spawn(async move {
            let mut asked = 0;
            while let Some(q) = raw.states.recv().await {
                asked += 1;
                reply(
                    &q,
                    json!({"goal_id": "m.1.1.1", "status": "SUCCEEDED", "seq": 3}),
                )
                .await;
            }
            asked
        });
        let r = outcome(&mut rx).await;
        let (goal_id, code, message) = failed(&r);
        assert_eq!((goal_id, code), ("m.1.1.1", "PROTOCOL_ERROR"));
        assert!(message.contains("without its result"), "{message}");
        assert!(message.starts_with("3 answers of `lander`"), "{message}");
        dropped(&mut drops, "unreadable_reply", 3).await;
        drop(c);
        answer_states.abort();
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_result_that_is_not_terminal_is_refused_and_the_goal_keeps_waiting() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let limits = Limits {
            retry_first_ms: 20,
            ..Limits::default()
        };
        let (mut c, mut rx) = limited(&exec, limits, Duration::from_secs(5), false).await;
        let mut drops = c.drops();
        c.execute(dig("m.1.1.1"));
        let q = raw.goals.recv().await.expect("goal");
        reply(&q, json!({"goal_id": "m.1.1.1", "status": "ACCEPTED"})).await;
        expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
        raw.publish(
            Channel::Result,
            json!({"goal_id": "m.1.1.1", "status": "EXECUTING", "outputs": {}}),
        )
        .await;
        dropped(&mut drops, "invalid_status", 1).await;
        // Refused: the connector asks for the goal's state, which says it still runs.
        let q = raw.states.recv().await.expect("the server is asked again");
        reply(
            &q,
            json!({"goal_id": "m.1.1.1", "status": "EXECUTING", "seq": 2}),
        )
        .await;
        raw.publish(
            Channel::Result,
            json!({"goal_id": "m.1.1.1", "status": "SUCCEEDED", "outputs": {"depth_cm": 3.5}}),
        )
        .await;
        let r = outcome(&mut rx).await;
        assert_eq!(
            r,
            Report::Done {
                goal_id: "m.1.1.1".into(),
                outputs: json!({"depth_cm": 3.5})
                    .as_object()
                    .cloned()
                    .unwrap_or_default()
            }
        );
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn results_end_goals_with_declared_codes() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let (mut c, mut rx) =
            limited(&exec, Limits::default(), Duration::from_secs(5), false).await;
        let results = [
            (
                "m.1.1.1",
                json!({"status": "REJECTED", "error": {"code": "X", "message": "arm busy"}}),
            ),
            ("m.1.2.1", json!({"status": "ABORTED"})),
            ("m.1.3.1", json!({"status": "SUCCEEDED"})),
            (
                "m.1.4.1",
                json!({"status": "ABORTED", "error": {"code": "TOOL_STUCK"}}),
            ),
        ];
        for (goal_id, result) in &results {
            c.execute(dig(goal_id));
            let q = raw.goals.recv().await.expect("goal");
            reply(&q, json!({"goal_id": goal_id, "status": "ACCEPTED"})).await;
            expect(
                &mut rx,
                |r| matches!(r, Report::Accepted { goal_id: g } if g == goal_id),
            )
            .await;
            let mut body = result.clone();
            body["goal_id"] = json!(goal_id);
            raw.publish(Channel::Result, body).await;
            let r = outcome(&mut rx).await;
            let (id, code, message) = failed(&r);
            assert_eq!(id, *goal_id);
            match *goal_id {
                // §9: REJECTED is the error `REJECTED`, whatever code the server wrote.
                "m.1.1.1" => assert_eq!((code, message), ("REJECTED", "arm busy")),
                "m.1.2.1" => {
                    assert_eq!(code, "ABORTED");
                    assert!(message.contains("without an error code"), "{message}");
                }
                // No `outputs` although the catalogue declares `depth_cm`: named.
                "m.1.3.1" => {
                    assert_eq!(code, "TYPE_MISMATCH");
                    assert!(message.contains("`depth_cm` (f64)"), "{message}");
                }
                _ => assert_eq!(code, "TOOL_STUCK"),
            }
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn mistyped_feedback_never_reaches_the_mission() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let (mut c, mut rx) =
            limited(&exec, Limits::default(), Duration::from_secs(5), false).await;
        let mut drops = c.drops();
        c.execute(dig("m.1.1.1"));
        let q = raw.goals.recv().await.expect("goal");
        reply(&q, json!({"goal_id": "m.1.1.1", "status": "ACCEPTED"})).await;
        expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
        for bad in [
            json!({"goal_id": "m.1.1.1", "progress_pct": 10.0, "fields": {"depth_cm": "high"}}),
            json!({"goal_id": "m.1.1.1", "fields": {"depth_cm": null}}),
            json!({"goal_id": "m.1.1.1", "fields": {"depth_cm": [1, 2]}}),
            json!({"goal_id": "m.1.1.1", "fields": {"colour": "red"}}),
            json!({"goal_id": "m.1.1.1", "progress_pct": 250.0}),
        ] {
            raw.publish(Channel::Feedback, bad).await;
        }
        raw.publish(
            Channel::Feedback,
            json!({"goal_id": "m.1.1.1", "progress_pct": 20.0, "fields": {"depth_cm": 4.1}}),
        )
        .await;
        // Samples on one key arrive in order: the first feedback delivered is the good one.
        let fb = expect(&mut rx, |r| matches!(r, Report::Feedback { .. })).await;
        assert_eq!(
            fb,
            Report::Feedback {
                goal_id: "m.1.1.1".into(),
                progress_pct: Some(20.0),
                fields: json!({"depth_cm": 4.1})
                    .as_object()
                    .cloned()
                    .unwrap_or_default()
            }
        );
        assert_eq!(
            dropped(&mut drops, "mistyped", 5).await.by_reason["mistyped"],
            5
        );
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn unknown_duplicate_and_garbage_results_are_counted() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let mut raw = RawServer::start(&sys, lander()).await;
        let (mut c, mut rx) =
            limited(&exec, Limits::default(), Duration::from_secs(5), false).await;
        let mut drops = c.drops();
        let result =
            json!({"goal_id": "m.1.1.1", "status": "SUCCEEDED", "outputs": {"depth_cm": 1.0}});
        c.execute(dig("m.1.1.1"));
        let q = raw.goals.recv().await.expect("goal");
        reply(&q, json!({"goal_id": "m.1.1.1", "status": "ACCEPTED"})).await;
        expect(&mut rx, |r| matches!(r, Report::Accepted { .. })).await;
        raw.publish(Channel::Result, result.clone()).await;
        assert!(matches!(outcome(&mut rx).await, Report::Done { .. }));
        // Another executive's goal is none of our business; ours, never sent, is unknown.
        raw.publish(
            Channel::Result,
            json!({"goal_id": "other.1.1.1", "status": "SUCCEEDED", "outputs": {}}),
        )
        .await;
        raw.publish(
            Channel::Result,
            json!({"goal_id": "m.9.9.9", "status": "SUCCEEDED", "outputs": {}}),
        )
        .await;
        raw.publish(Channel::Result, result).await;
        raw.session
            .put(
                Keys::default().stream("lander", "dig", Channel::Result),
                "{",
            )
            .await
            .expect("put");
        let d = dropped(&mut drops, "garbage", 1).await;
        assert_eq!(d.by_reason.get("unknown_goal"), Some(&1), "{d:?}");
        assert_eq!(d.by_reason.get("duplicate"), Some(&1), "{d:?}");
        assert_eq!(d.total, 3, "{d:?}");
        assert_eq!(c.dropped(), d);
        assert!(rx.try_recv().is_err(), "nothing reached the mission");
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn mistyped_telemetry_and_implausible_clock_reports_are_refused() {
        let p = endpoint(port());
        let sys = open(std::slice::from_ref(&p), &[]).await;
        let exec = open(&[], &[p]).await;
        let raw = RawServer::start(&sys, lander()).await;
        let (c, mut rx) = limited(&exec, Limits::default(), Duration::from_secs(5), true).await;
        let mut drops = c.drops();
        let k = Keys::default();
        let tm = |channel: &str, body: serde_json::Value| {
            raw.session
                .put(k.telemetry("lander", channel), body.to_string())
        };
        for bad in [json!("high"), json!(null), json!([1, 2])] {
            tm(
                "power",
                json!({"mission_ms": 5, "values": {"battery_soc_pct": bad}}),
            )
            .await
            .expect("put");
        }
        tm(
            "power",
            json!({"mission_ms": 5, "values": {"battery_soc_pct": 81.5}}),
        )
        .await
        .expect("put");
        let data = expect(&mut rx, |r| matches!(r, Report::Data { .. })).await;
        assert_eq!(
            data,
            Report::Data {
                key: "battery_soc_pct".into(),
                value: json!(81.5)
            }
        );
        dropped(&mut drops, "mistyped", 3).await;
        // The clock: the first report is believed; an hour ahead and backwards are not; a
        // report 100 ms on (well within a second of slack at speed 1) is.
        let start = 1_795_430_254_329_i64;
        for (mission_ms, speed) in [
            (start, 1.0),
            (start + 3_600_000, 1.0),
            (start - 1_000, 1.0),
            (start + 100, f64::NAN),
            (start + 100, 1.0),
        ] {
            let speed = if speed.is_nan() {
                json!("fast")
            } else {
                json!(speed)
            };
            tm(
                "clock",
                json!({"mission_ms": mission_ms, "values": {"speed": speed}}),
            )
            .await
            .expect("put");
        }
        let first = expect(&mut rx, |r| matches!(r, Report::Clock { .. })).await;
        assert_eq!(
            first,
            Report::Clock {
                mission_ms: start,
                speed: 1.0
            }
        );
        let next = expect(&mut rx, |r| matches!(r, Report::Clock { .. })).await;
        assert_eq!(
            next,
            Report::Clock {
                mission_ms: start + 100,
                speed: 1.0
            }
        );
        assert_eq!(
            dropped(&mut drops, "implausible_clock", 3).await.by_reason["implausible_clock"],
            3
        );
    }
}
