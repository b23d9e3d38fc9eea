//! Ground stations as separate processes answering a running mission's user tasks over Zenoh:
//! every kind of bad answer refused with the reason and nothing applied, two stations racing
//! (first valid answer wins, the other is told, nobody logs an error), an operator answering
//! at the terminal through a pseudo-terminal, and restarts: a station killed with a task open
//! answers it by its policy when restarted on its store, and an answer sent while the executive
//! is down is sent again until the resumed executive judges it.

use std::io::BufRead;
use std::path::Path;
use std::process::{Child, ChildStderr, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use connector_api::wire::Answer;
use connector_api::{Channel, Keys};
use mission_tests::bin;
use serde_json::{Value, json};

use crate::protocol::{args, endpoint, port, router, tempdir};

/// How long any one expected event may take before the test fails (a hang guard, not a
/// timing assertion).
const EVENT: Duration = Duration::from_secs(60);

/// `n` user tasks in parallel (`ground.approve_site`, each showing one candidate site and
/// guarded by a one-hour timer), then the end.
fn mission(n: usize) -> String {
    let mut tasks = String::new();
    for i in 1..=n {
        tasks.push_str(&format!(
            r#"
    <userTask id="approve{i}" name="Approve site {i}"><extensionElements><trace:task resource="ground.approve_site">
      <trace:input target="candidates" source='[{{"site_id": {i}, "score": 0.9, "material": "ice"}}]' type="json"/>
      <trace:output source="approve" target="ok{i}" type="bool"/></trace:task></extensionElements></userTask>
    <boundaryEvent id="late{i}" attachedToRef="approve{i}"><timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition></boundaryEvent>
    <endEvent id="timeout{i}"/>
    <sequenceFlow id="a{i}" sourceRef="fork" targetRef="approve{i}"/>
    <sequenceFlow id="b{i}" sourceRef="approve{i}" targetRef="join"/>
    <sequenceFlow id="c{i}" sourceRef="late{i}" targetRef="timeout{i}"/>"#
        ));
    }
    // One task needs no gateways (a gateway with one way in and one way out is invalid).
    let (fork, join) = if n == 1 {
        ("approve1", "approve1")
    } else {
        ("fork", "join")
    };
    let gateways = if n == 1 {
        String::new()
    } else {
        r#"<parallelGateway id="fork"/><parallelGateway id="join"/>"#.to_owned()
    };
    let tasks = if n == 1 {
        tasks
            .replace(
                r#"<sequenceFlow id="a1" sourceRef="fork" targetRef="approve1"/>"#,
                "",
            )
            .replace(
                r#"<sequenceFlow id="b1" sourceRef="approve1" targetRef="join"/>"#,
                "",
            )
    } else {
        tasks
    };
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="defs" targetNamespace="urn:ground">
  <process id="ground" isExecutable="true">
    <startEvent id="s"/>
    {gateways}
    <endEvent id="end"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="{fork}"/>
    <sequenceFlow id="f2" sourceRef="{join}" targetRef="end"/>{tasks}
  </process>
</definitions>"#
    )
}

const CONNECTORS: &str = r#"
[[connector]]
name = "ground"
kind = "zenoh"
resources = ["ground.*"]
answers = true
grace_ms = 600000
"#;

/// A mission of `n` user tasks, ready to run in `dir`.
fn setup(name: &str, n: usize) -> crate::protocol::Scratch {
    let dir = tempdir(name);
    std::fs::write(dir.join("mission.bpmn"), mission(n)).expect("mission");
    std::fs::write(dir.join("connectors.toml"), CONNECTORS).expect("connectors");
    dir
}

/// A process's log (its standard error), echoed to the test's as it comes.
struct Log {
    lines: Arc<Mutex<Vec<String>>>,
    reader: std::thread::JoinHandle<()>,
}

fn echo(stderr: ChildStderr) -> Log {
    let lines = Arc::<Mutex<Vec<String>>>::default();
    let keep = Arc::clone(&lines);
    let reader = std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            eprintln!("{line}");
            keep.lock().unwrap_or_else(|p| p.into_inner()).push(line);
        }
    });
    Log { lines, reader }
}

impl Log {
    /// The lines at level ERROR, once the process has ended and its log is read to the end.
    fn errors(self) -> Vec<String> {
        let _ = self.reader.join();
        let lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        lines
            .iter()
            .filter(|l| l.contains(" ERROR "))
            .cloned()
            .collect()
    }
}

/// A running executive (and its log), killed if the test fails before it ends.
struct Exec(Option<Child>, Option<Log>);

impl Drop for Exec {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = (c.kill(), c.wait());
        }
    }
}

/// `trace run` on the mission in `dir` with these Zenoh endpoint flags.
fn executive(dir: &Path, zenoh: &[&str]) -> Exec {
    trace(
        &["run", dir.join("mission.bpmn").to_str().expect("path")],
        dir,
        zenoh,
    )
}

/// `trace resume` of the mission in `dir` with these Zenoh endpoint flags.
fn resume(dir: &Path, zenoh: &[&str]) -> Exec {
    trace(&["resume"], dir, zenoh)
}

fn trace(verb: &[&str], dir: &Path, zenoh: &[&str]) -> Exec {
    let mut child = Command::new(bin("trace"))
        .args(verb)
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .args(zenoh)
        .arg("--no-multicast-scouting")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("trace starts");
    let log = echo(child.stderr.take().expect("stderr"));
    Exec(Some(child), Some(log))
}

/// The executive's exit, waited for on a thread so a hang fails the test instead of CI.
fn exits(mut exec: Exec) -> String {
    let child = exec.0.take().expect("running");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    let out = rx
        .recv_timeout(EVENT)
        .expect("the mission ends")
        .expect("trace run");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{stdout}");
    stdout
}

/// A ground station answering by `policy` (TOML text), its output lines on a channel.
struct Station {
    child: Child,
    lines: mpsc::Receiver<String>,
    seen: Vec<String>,
    log: Option<Log>,
}

impl Station {
    fn start(dir: &Path, id: &str, policy: &str, zenoh: &[&str]) -> Station {
        let file = dir.join(format!("{id}.toml"));
        std::fs::write(&file, policy).expect("policy");
        let mut child = Command::new(bin("ground-station"))
            .arg("--policy")
            .arg(&file)
            .args(["--station", id, "--no-multicast-scouting"])
            .args(zenoh)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ground-station starts");
        let log = echo(child.stderr.take().expect("stderr"));
        let out = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut s = Station {
            child,
            lines,
            seen: Vec::new(),
            log: Some(log),
        };
        s.expect(|l| l.starts_with("ready ground"));
        s
    }

    /// Waits for a line matching `what`; returns it.
    fn expect(&mut self, what: impl Fn(&str) -> bool) -> String {
        loop {
            let line = self
                .lines
                .recv_timeout(EVENT)
                .unwrap_or_else(|e| panic!("{e}; station said so far: {:#?}", self.seen));
            self.seen.push(line.clone());
            if what(&line) {
                return line;
            }
        }
    }
}

impl Drop for Station {
    fn drop(&mut self) {
        let _ = (self.child.kill(), self.child.wait());
    }
}

/// The record's lines, a line written again after a crash (same `seq` and `idx`) read once.
fn record(dir: &Path) -> Vec<Value> {
    let mut seen = std::collections::BTreeSet::new();
    std::fs::read_to_string(dir.join("store/record.jsonl"))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["seq"].is_null() || seen.insert((v["seq"].to_string(), v["idx"].to_string())))
        .collect()
}

fn answered(dir: &Path) -> Vec<Value> {
    record(dir)
        .into_iter()
        .filter(|v| v["kind"] == "user_task_answered")
        .collect()
}

/// Waits for the next liveliness change of `kind` on a subscriber's channel.
async fn until(
    changes: &mut tokio::sync::mpsc::UnboundedReceiver<zenoh::sample::SampleKind>,
    kind: zenoh::sample::SampleKind,
) {
    while tokio::time::timeout(EVENT, changes.recv())
        .await
        .expect("a liveliness change")
        .expect("subscriber open")
        != kind
    {}
}

/// Waits until `session` sees a liveliness token on `key`.
async fn seen(session: &zenoh::Session, key: &str) {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let tx = std::sync::Mutex::new(Some(tx));
    let _sub = session
        .liveliness()
        .declare_subscriber(key)
        .history(true)
        .callback(move |_| {
            if let Some(tx) = tx.lock().ok().and_then(|mut t| t.take()) {
                let _ = tx.send(());
            }
        })
        .await
        .expect("liveliness subscriber");
    tokio::time::timeout(EVENT, rx)
        .await
        .unwrap_or_else(|_| panic!("{key} is not seen"))
        .expect("seen");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_bad_answer_is_refused_with_its_reason_and_changes_nothing() {
    // Two tasks: the second keeps the mission running after the first is answered.
    let dir = setup("ground-bad", 2);
    let hub = endpoint(port());
    // This station's policy never answers: the test is the other station.
    let mut station = Station::start(
        &dir,
        "quiet",
        "[task.\"ground.approve_site\"]\nsilent = true\n",
        &["-e", &hub],
    );
    let exec = executive(&dir, &["-l", &hub]);
    let open = station.expect(|l| l.starts_with("task 1 open:"));
    assert!(
        open.contains(", ground.approve_site] deadline 20"),
        "{open}"
    );
    station.expect(|l| l.starts_with("task 2 open:"));
    station.expect(|l| l.contains("left to the model's timer"));

    let session = args(&[], std::slice::from_ref(&hub))
        .open(connector_zenoh::Role::Spoke)
        .await
        .expect("session");
    let keys = Keys::default();
    // This session talks to the executive and the station once it knows them (each declares
    // its liveliness token after its queryables).
    seen(&session, &keys.alive("exec", "*")).await;
    seen(&session, &keys.alive("ground", "quiet")).await;
    // The tasks' goal ids, from the station's goal table.
    let replies = session
        .get(keys.goal("ground", "ground.approve_site", Channel::State, "*"))
        .await
        .expect("state query");
    let mut goals = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        let state: Value =
            serde_json::from_slice(&reply.result().expect("state").payload().to_bytes())
                .expect("json");
        goals.push(state["goal_id"].as_str().expect("goal id").to_owned());
    }
    assert_eq!(goals.len(), 2, "{goals:?}");
    let (goal_id, other) = (goals[0].clone(), goals[1].clone());
    let mission = goal_id.split('.').next().expect("mission id").to_owned();

    let send = |goal_id: &str, fields: Value, operator: &str| {
        let answer = Answer {
            goal_id: goal_id.to_owned(),
            fields: fields.as_object().cloned().unwrap_or_default(),
            operator: operator.to_owned(),
            station: "desk-1".to_owned(),
        };
        let (session, keys) = (session.clone(), keys.clone());
        async move {
            connector_zenoh::send_answer(
                &session,
                &keys,
                "ground",
                "ground.approve_site",
                &answer,
                EVENT,
            )
            .await
            .expect("a verdict")
        }
    };
    // A monitor joining now shows both tasks waiting for the ground, with their deadlines.
    let monitor = Command::new(bin("trace"))
        .args([
            "monitor",
            "--lines",
            "0",
            "-e",
            &hub,
            "--no-multicast-scouting",
        ])
        .output()
        .expect("monitor runs");
    let board = String::from_utf8_lossy(&monitor.stdout).into_owned();
    for i in [1, 2] {
        assert!(
            board.contains(&format!("open user task: Approve site {i} ({mission}.1.")),
            "{board}"
        );
    }
    assert_eq!(board.matches(", deadline 20").count(), 2, "{board}");
    assert!(board.contains("instance 1: running"), "{board}");
    let unknown = format!("{mission}.1.999.1");
    for (goal, fields, operator, reason) in [
        (
            unknown.as_str(),
            json!({"approve": true}),
            "ana",
            "no open user task has goal id",
        ),
        (&goal_id, json!({}), "ana", "`approve` is missing"),
        (
            &goal_id,
            json!({"approve": "yes"}),
            "ana",
            "`approve` must be bool, got a string",
        ),
        (
            &goal_id,
            json!({"approve": true, "colour": "red"}),
            "ana",
            "`colour` is not a field",
        ),
        (
            &goal_id,
            json!({"approve": true, "comment": 7}),
            "ana",
            "`comment` must be string",
        ),
        (
            &goal_id,
            json!({"approve": true}),
            " ",
            "must name its operator",
        ),
    ] {
        let r = send(goal, fields, operator).await;
        assert!(!r.applied, "{goal}: applied");
        let why = r.reason.expect("a reason");
        assert!(why.contains(reason), "expected `{reason}` in `{why}`");
    }
    // Not even an answer: refused with the key named.
    let key = keys.goal("ground", "ground.approve_site", Channel::Answer, &goal_id);
    let replies = session
        .get(&key)
        .payload(b"{not json".to_vec())
        .await
        .expect("get");
    let reply: Value = serde_json::from_slice(
        &replies
            .recv_async()
            .await
            .expect("reply")
            .result()
            .expect("a refusal is a reply")
            .payload()
            .to_bytes(),
    )
    .expect("json");
    assert_eq!(reply["applied"], false);
    assert!(
        reply["reason"]
            .as_str()
            .is_some_and(|r| r.starts_with(&format!("malformed answer payload on {key}"))),
        "{reply}"
    );
    assert!(
        answered(&dir).is_empty(),
        "a refused answer changed the mission"
    );

    // A valid answer is applied once; the same answer again is refused, naming who answered.
    let r = send(
        &goal_id,
        json!({"approve": true, "comment": "ice, go"}),
        "ana",
    )
    .await;
    assert!(r.applied, "{r:?}");
    // The same answer again (a station that never heard the verdict) is confirmed, not
    // applied twice.
    let ana = json!({"approve": true, "comment": "ice, go"});
    assert!(send(&goal_id, ana.clone(), "ana").await.applied);
    let closed = format!("user task `{goal_id}` is closed: answered by ana@desk-1");
    let again = send(&goal_id, json!({"approve": false}), "ben").await;
    assert_eq!(again.reason.as_deref(), Some(closed.as_str()));
    // The other station is told.
    station.expect(|l| l.ends_with(" closed: answered by ana@desk-1"));
    // The executive is killed and resumed: it still knows the answer it applied, and who
    // gave it (from its record).
    // Its liveliness token says when it is gone and when it is back (it declares the token
    // after its answer queryable).
    let (tokens_tx, mut tokens) = tokio::sync::mpsc::unbounded_channel();
    let _tokens = session
        .liveliness()
        .declare_subscriber(keys.alive("exec", "*"))
        .callback(move |s| {
            let _ = tokens_tx.send(s.kind());
        })
        .await
        .expect("liveliness subscriber");
    let mut exec = exec;
    let mut child = exec.0.take().expect("running");
    let _ = (child.kill(), child.wait());
    until(&mut tokens, zenoh::sample::SampleKind::Delete).await;
    let exec = resume(&dir, &["-l", &hub]);
    until(&mut tokens, zenoh::sample::SampleKind::Put).await;
    let same = send(&goal_id, ana.clone(), "ana").await;
    assert!(same.applied, "{same:?}");
    let again = send(&goal_id, json!({"approve": false}), "ben").await;
    assert_eq!(again.reason.as_deref(), Some(closed.as_str()));
    assert!(send(&other, json!({"approve": false}), "ben").await.applied);
    exits(exec);
    let answers = answered(&dir);
    assert_eq!(answers.len(), 2, "{answers:#?}");
    assert_eq!(answers[0]["operator"], "ana@desk-1");
    assert_eq!(
        answers[0]["answer"],
        json!({"approve": true, "comment": "ice, go"})
    );
    assert_eq!(answers[1]["operator"], "ben@desk-1");
    session.close().await.expect("close");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_stations_race_and_the_first_valid_answer_wins() {
    let n = 3;
    let dir = setup("ground-race", n);
    // Stations are clients of a router (as deployed); the executive joins once both are up,
    // so every station sees every task.
    let p = port();
    let hub = endpoint(p);
    let router = router(p).await;
    let (up_tx, mut up) = tokio::sync::mpsc::unbounded_channel();
    let _up = router
        .liveliness()
        .declare_subscriber(Keys::default().alive("ground", "*"))
        .history(true)
        .callback(move |s| {
            let _ = up_tx.send(s.key_expr().to_string());
        })
        .await
        .expect("liveliness subscriber");
    let policy = |operator: &str, approve: bool| {
        format!(
            "operator = \"{operator}\"\n[task.\"ground.approve_site\"]\nfixed = {{ approve = {approve} }}\n"
        )
    };
    let client = ["--mode", "client", "-e", &hub];
    let mut a = Station::start(&dir, "alpha", &policy("amy", true), &client);
    let mut b = Station::start(&dir, "bravo", &policy("bob", false), &client);
    let mut seen = std::collections::BTreeSet::new();
    while seen.len() < 2 {
        let key = tokio::time::timeout(EVENT, up.recv())
            .await
            .expect("stations up");
        seen.insert(key.expect("token"));
    }
    let mut exec = executive(&dir, &["-e", &hub]);
    let exec_log = exec.1.take().expect("log");
    tokio::task::spawn_blocking(move || exits(exec))
        .await
        .expect("the mission ends");
    // Exactly one answer per task, each consistent with the station that gave it.
    let answers = answered(&dir);
    assert_eq!(answers.len(), n, "{answers:#?}");
    let mut wins = [0, 0];
    for v in &answers {
        match v["operator"].as_str() {
            Some("amy@alpha") => {
                assert_eq!(v["answer"]["approve"], true);
                wins[0] += 1;
            }
            Some("bob@bravo") => {
                assert_eq!(v["answer"]["approve"], false);
                wins[1] += 1;
            }
            other => panic!("answer by {other:?}"),
        }
    }
    // Each station saw every task and heard its outcome: its answer applied, or who won.
    for (station, won, other) in [
        (&mut a, wins[0], "bob@bravo"),
        (&mut b, wins[1], "amy@alpha"),
    ] {
        let mut applied = 0;
        let mut told = 0;
        let mut decided = std::collections::BTreeSet::new();
        while decided.len() < n {
            let line = station.expect(|l| {
                l.contains("answered: applied") || l.contains(&format!("answered by {other}"))
            });
            let number: u32 = line
                .trim_start_matches("task ")
                .split(' ')
                .next()
                .and_then(|n| n.parse().ok())
                .expect("task number");
            if decided.insert(number) {
                if line.contains("applied") {
                    applied += 1;
                } else {
                    told += 1;
                }
            }
        }
        assert_eq!((applied, told), (won, n - won), "{:#?}", station.seen);
        let opened = station
            .seen
            .iter()
            .filter(|l| l.contains(" open: "))
            .count();
        assert_eq!(opened, n, "{:#?}", station.seen);
    }
    // A race is nominal: the answer that lost, and a verdict that arrives after its station was
    // told it won, are no error in anybody's log (read to the end once each process is gone).
    let mut logs = vec![("executive", exec_log)];
    for (who, station) in [("alpha", &mut a), ("bravo", &mut b)] {
        let _ = (station.child.kill(), station.child.wait());
        logs.push((who, station.log.take().expect("log")));
    }
    for (who, log) in logs {
        assert_eq!(log.errors(), Vec::<String>::new(), "{who} logged errors");
    }
    router.close().await.expect("router closes");
}

#[test]
fn an_operator_answers_at_the_terminal_with_typed_fields() {
    let dir = setup("ground-tty", 1);
    let hub = endpoint(port());
    let mut cmd = Command::new(bin("ground-station"));
    cmd.args([
        "--interactive",
        "--operator",
        "ana",
        "--station",
        "console",
        "-e",
        &hub,
        "--no-multicast-scouting",
    ]);
    let mut tty = rexpect::session::spawn_command(cmd, Some(EVENT.as_millis() as u64))
        .expect("ground-station in a pseudo-terminal");
    tty.exp_string("ready ground console").expect("ready");
    tty.exp_string("ground> ").expect("prompt");
    let exec = executive(&dir, &["-l", &hub]);
    tty.exp_string("task 1 open: Approve site 1")
        .expect("the task arrives");
    tty.send_line("list").expect("list");
    tty.exp_regex(r"1  Approve site 1 \[approve1, ground.approve_site\] deadline \d{4}-")
        .expect("listed");
    tty.send_line("show 1").expect("show");
    for part in [
        "element   approve1",
        "\"material\": \"ice\"",
        "approve: bool",
        "comment: string (optional)",
    ] {
        tty.exp_string(part).expect(part);
    }
    for (typed, said) in [
        (
            "answer 1 approve=maybe",
            "not sent: `approve` must be bool: `maybe` is not one",
        ),
        ("answer 1 comment=later", "not sent: `approve` is missing"),
        (
            "answer 1 approve=true colour=red",
            "not sent: `colour` is not a field of this form",
        ),
        ("answer 4 approve=true", "task 4 is not open"),
        ("answer one approve=true", "`one` is not a task number"),
    ] {
        tty.send_line(typed).expect("typed");
        tty.exp_string(said).expect(said);
    }
    assert!(
        answered(&dir).is_empty(),
        "a refused answer changed the mission"
    );
    tty.send_line(r#"answer 1 approve=true comment="ice at 3 m""#)
        .expect("typed");
    tty.exp_string("task 1 answered: applied (ana@console)")
        .expect("applied");
    tty.send_line("list").expect("list");
    tty.exp_string("no open tasks").expect("closed");
    exits(exec);
    let answers = answered(&dir);
    assert_eq!(answers.len(), 1);
    assert_eq!(answers[0]["operator"], "ana@console");
    assert_eq!(
        answers[0]["answer"],
        json!({"approve": true, "comment": "ice at 3 m"})
    );
    tty.send_line("quit").expect("quit");
    tty.exp_eof().expect("the station leaves");
}

/// The liveliness tokens on `key` that `session` can find now (a query, answered when routing
/// is done: no waiting on time).
async fn tokens(session: &zenoh::Session, key: &str) -> Vec<String> {
    let replies = session
        .liveliness()
        .get(key)
        .await
        .expect("liveliness query");
    let mut found = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            found.push(sample.key_expr().to_string());
        }
    }
    found
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_station_of_another_deployment_is_never_offered_a_task() {
    let dir = setup("ground-deployments", 1);
    let hub = endpoint(port());
    let answer = |operator: &str, approve: bool| {
        format!(
            "operator = \"{operator}\"\n[task.\"ground.approve_site\"]\nfixed = {{ approve = {approve} }}\n"
        )
    };
    // A station of deployment B, up before the executive of deployment A on the same Zenoh
    // network: were it offered the task, it would answer at once.
    let mut other = Station::start(
        &dir,
        "bravo",
        &answer("bob", false),
        &["-e", &hub, "--deployment", "flight-b"],
    );
    assert!(
        other.seen[0].contains("deployment flight-b (keys trace/flight-b/…)"),
        "{:?}",
        other.seen
    );
    // A's forms are served from the start (the executive checks its user tasks against them),
    // by a station of A that never answers.
    let mut quiet = Station::start(
        &dir,
        "quiet",
        "operator = \"sam\"\n[task.\"ground.approve_site\"]\nsilent = true\n",
        &["-e", &hub, "--deployment", "flight-a"],
    );
    let mut exec = executive(&dir, &["-l", &hub, "--deployment", "flight-a"]);
    let opened = crate::durability::until_record(
        exec.0.as_mut().expect("running"),
        &dir.join("store/record.jsonl"),
        |t| t.contains(r#""kind":"user_task_opened""#),
    );
    assert!(opened, "the executive ended before opening the task");
    // The executive of A is on the network: found under A's keys, not under B's.
    let session = args(&[], std::slice::from_ref(&hub))
        .open(connector_zenoh::Role::Spoke)
        .await
        .expect("session");
    let (a, b) = (
        Keys::deployed("trace", "flight-a").expect("keys"),
        Keys::deployed("trace", "flight-b").expect("keys"),
    );
    // Both are reachable from this session (peers learn of each other through the hub).
    seen(&session, &a.alive("exec", "*")).await;
    seen(&session, &b.alive("ground", "*")).await;
    assert_eq!(tokens(&session, &a.alive("exec", "*")).await.len(), 1);
    assert!(tokens(&session, &b.alive("exec", "*")).await.is_empty());
    assert_eq!(
        tokens(&session, &b.alive("ground", "*")).await,
        ["trace/flight-b/alive/ground/bravo"]
    );
    // A's silent station holds the task; nothing is open at B's station.
    quiet.expect(|l| l.starts_with("task 1 open:"));
    let replies = session
        .get(b.goal("ground", "ground.approve_site", Channel::State, "*"))
        .await
        .expect("state query");
    assert!(
        replies.recv_async().await.is_err(),
        "B's station holds a goal"
    );
    assert!(answered(&dir).is_empty());
    // A station of A that joins late is offered the task and answers it; the mission ends.
    let mut own = Station::start(
        &dir,
        "alpha",
        &answer("amy", true),
        &["-e", &hub, "--deployment", "flight-a"],
    );
    own.expect(|l| l.starts_with("task 1 open:"));
    exits(exec);
    let answers = answered(&dir);
    assert_eq!(answers.len(), 1, "{answers:#?}");
    assert_eq!(answers[0]["operator"], "amy@alpha");
    let _ = (quiet.child.kill(), quiet.child.wait());
    // B's station, everything it said until it was stopped: never a task.
    let _ = (other.child.kill(), other.child.wait());
    while let Ok(line) = other.lines.recv_timeout(EVENT) {
        other.seen.push(line);
    }
    assert_eq!(other.seen.len(), 1, "{:#?}", other.seen);
    session.close().await.expect("close");
}

/// A policy that approves after `delay_ms`: long enough for the test to kill a process while
/// the task is open and the answer not yet sent.
fn approves_after(operator: &str, delay_ms: u64) -> String {
    format!(
        "operator = \"{operator}\"\n[task.\"ground.approve_site\"]\nfixed = {{ approve = true }}\ndelay_ms = {delay_ms}\n"
    )
}

#[test]
fn a_station_restarted_on_its_store_answers_its_open_task_by_its_policy() {
    let dir = setup("ground-station-restart", 1);
    let hub = endpoint(port());
    let store = dir.join("keeper.store");
    let store = store.to_str().expect("path");
    let policy = approves_after("kim", 3000);
    let flags = ["-e", &hub, "--store", store];
    let mut first = Station::start(&dir, "keeper", &policy, &flags);
    let exec = executive(&dir, &["-l", &hub]);
    first.expect(|l| l.starts_with("task 1 open:"));
    // Killed before its policy answered: the task is kept in the station's store.
    drop(first);
    // Restarted, it reopens the task from its store; before, the task came back on the desk
    // without the policy and was never answered.
    let mut again = Station::start(&dir, "keeper", &policy, &flags);
    again.expect(|l| l.starts_with("task 1 answered: applied (kim@keeper)"));
    assert!(
        again.seen.iter().any(|l| l.starts_with("task 1 open:")),
        "{:#?}",
        again.seen
    );
    exits(exec);
    assert_eq!(answered(&dir)[0]["operator"], "kim@keeper");
}

#[test]
fn an_answer_sent_while_the_executive_is_down_is_sent_again_until_it_is_judged() {
    let dir = setup("ground-executive-down", 1);
    let hub = endpoint(port());
    let mut station = Station::start(&dir, "patient", &approves_after("pat", 3000), &["-e", &hub]);
    let mut exec = executive(&dir, &["-l", &hub]);
    station.expect(|l| l.starts_with("task 1 open:"));
    let mut child = exec.0.take().expect("running");
    let _ = (child.kill(), child.wait());
    // The policy answers while no executive is up: the station says so and keeps the answer.
    // Before, the answer was refused at once ("no executive answered") and never sent again.
    station.expect(|l| l.starts_with("task 1 answer pending:"));
    let resumed = resume(&dir, &["-l", &hub]);
    station.expect(|l| l.starts_with("task 1 answered: applied (pat@patient)"));
    exits(resumed);
    let answers = answered(&dir);
    assert_eq!(answers.len(), 1, "{answers:#?}");
    assert_eq!(answers[0]["operator"], "pat@patient");
}
