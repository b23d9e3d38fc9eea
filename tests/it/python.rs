//! `docs/protocol.md` is the contract: a system and a ground station written in Python from
//! the document alone (`tests/python/`, the `eclipse-zenoh` package) fly a mission with
//! `trace run` — goals, feedback, an error boundary, a ground decision — while sending wrong
//! messages that the executive must refuse, log and count without changing the mission; and a
//! system that accepts a goal and then says nothing more cannot make the task wait without end
//! (the executive's watchdog fails it with `OVERRUN`, caught by a boundary, and cancels it).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use mission_tests::{bin, records, repo};
use serde_json::Value;

use crate::protocol::{endpoint, port, tempdir};

/// How long any one process of the flight may take; the mission itself takes about a second.
const BOUND: Duration = Duration::from_secs(120);

/// Where `scripts/test` installs the Python Zenoh package (`TRACE_PYTHONPATH`).
fn python_path() -> PathBuf {
    std::env::var_os("TRACE_PYTHONPATH")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache/trace-python")
        })
}

fn python(script: &str) -> Command {
    let mut c = Command::new("python3");
    c.env("PYTHONPATH", python_path())
        .arg(repo().join("tests/python").join(script));
    c
}

/// Starts a Python process and waits for its `ready` line (it serves from then on).
fn start(script: &str, args: &[String], log: &Path) -> Child {
    let mut child = python(script)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(log).expect("log file"))
        .spawn()
        .expect("python3 starts");
    let stdout = child.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if line.starts_with("ready") {
                let _ = tx.send(line);
            }
        }
    });
    match rx.recv_timeout(BOUND) {
        Ok(_) => child,
        Err(_) => {
            let _ = child.kill();
            panic!(
                "{script} never said it was ready: {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
    }
}

/// Waits for a child to exit (on a thread, so the exit is the event) within [`BOUND`],
/// killing it (and failing) if it does not.
fn finish(child: Child, what: &str, log: &Path) -> std::process::ExitStatus {
    let pid = child.id();
    let (tx, rx) = mpsc::channel();
    let mut child = child;
    std::thread::spawn(move || {
        let _ = tx.send(child.wait());
    });
    match rx.recv_timeout(BOUND) {
        Ok(status) => status.expect("wait"),
        Err(_) => {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            panic!(
                "{what} did not end within {BOUND:?}; its log:\n{}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
    }
}

fn json_file(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn a_python_system_and_ground_station_written_from_the_document_fly_a_mission() {
    let import = Command::new("python3")
        .env("PYTHONPATH", python_path())
        .args(["-c", "import zenoh"])
        .output()
        .expect("python3 runs");
    assert!(
        import.status.success(),
        "the Python package eclipse-zenoh does not import from {}: run scripts/test, which \
         installs it ({})",
        python_path().display(),
        String::from_utf8_lossy(&import.stderr)
    );
    let dir = tempdir("python");
    let hub = endpoint(port());
    let deployment = format!("py-{}", std::process::id());
    let (system_report, ground_report) = (dir.join("system.json"), dir.join("ground.json"));
    let (system_log, ground_log, exec_log) = (
        dir.join("system.log"),
        dir.join("ground.log"),
        dir.join("exec.log"),
    );
    let flags = |report: &Path| {
        vec![
            "--connect".to_owned(),
            hub.clone(),
            "--deployment".to_owned(),
            deployment.clone(),
            "--report".to_owned(),
            report.display().to_string(),
        ]
    };
    let system = start("trace_system.py", &flags(&system_report), &system_log);
    let ground = start("trace_ground.py", &flags(&ground_report), &ground_log);
    let store = dir.join("store");
    let exec = Command::new(bin("trace"))
        .args(["run"])
        .arg(repo().join("tests/python/mission.bpmn"))
        .arg("--connectors")
        .arg(repo().join("tests/python/connectors.toml"))
        .arg("--store")
        .arg(&store)
        .args([
            "--catalogue-wait",
            "60",
            "-l",
            &hub,
            "--deployment",
            &deployment,
        ])
        .env("RUST_LOG", "warn,zenoh=error")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&exec_log).expect("exec log"))
        .spawn()
        .expect("trace run starts");
    let status = finish(exec, "trace run", &exec_log);
    let log = std::fs::read_to_string(&exec_log).unwrap_or_default();
    assert!(status.success(), "trace run failed ({status}):\n{log}");
    // Like every process of a deployment, the executive named it when it started (§1).
    assert!(
        log.lines().any(|l| l.starts_with("mission ")
            && l.ends_with(&format!(
                "— deployment {deployment} (keys trace/{deployment}/…)"
            ))),
        "{log}"
    );
    // Both Python processes end on their own once the executive's token is gone.
    assert!(finish(system, "the Python system", &system_log).success());
    assert!(finish(ground, "the Python ground station", &ground_log).success());

    // The record: the mission ran as drawn, and nothing refused reached it.
    let lines = records(&store.join("record.jsonl"));
    let of = |kind: &str| -> Vec<&Value> { lines.iter().filter(|v| v["kind"] == kind).collect() };
    let task_of = |resource: &str| -> String {
        of("dispatched")
            .into_iter()
            .find(|v| v["resource"] == resource)
            .and_then(|v| v["task"].as_str())
            .unwrap_or_else(|| panic!("{resource} was never dispatched"))
            .to_owned()
    };
    let ended = |task: &str| -> Vec<&Value> {
        lines
            .iter()
            .filter(|v| v["task"] == task && (v["kind"] == "completed" || v["kind"] == "failed"))
            .collect()
    };
    let dig = ended(&task_of("drill.dig"));
    assert_eq!(dig.len(), 1, "{dig:?}");
    assert_eq!(dig[0]["output"]["achieved_cm"], 5.2, "{dig:?}");
    let feedback: Vec<&Value> = of("feedback");
    assert_eq!(
        feedback.len(),
        1,
        "only the well-typed feedback: {feedback:?}"
    );
    assert_eq!(feedback[0]["fields"]["depth_cm"], 2.5);
    let heat = ended(&task_of("thermal.heat"));
    assert_eq!(heat[0]["kind"], "failed");
    assert_eq!(heat[0]["code"], "HEATER_FAULT");
    assert_eq!(ended(&task_of("thermal.cool"))[0]["kind"], "completed");
    let answered = of("user_task_answered");
    assert_eq!(answered.len(), 1, "{answered:?}");
    assert_eq!(answered[0]["operator"], "py-op@py-station");
    assert_eq!(answered[0]["answer"]["approve"], true);
    assert_eq!(ended(&task_of("arm.stow"))[0]["kind"], "completed");
    let finished = of("instance_finished");
    assert_eq!(finished[0]["outcome"]["type"], "completed", "{finished:?}");
    // Battery telemetry arrived as system data, the mistyped value did not.
    let data: Vec<&Value> = of("data");
    assert!(!data.is_empty(), "no telemetry reached the mission");
    assert!(data.iter().all(|v| v["value"].is_f64()), "{data:?}");

    // What the executive refused, it logged: the mistyped feedback and telemetry, the garbage
    // result, the result for a goal it never sent.
    for (reason, what) in [
        ("mistyped", "feedback"),
        ("mistyped", "telemetry"),
        ("garbage", "result"),
    ] {
        assert!(
            log.lines().any(|l| l.contains("message dropped")
                && l.contains(&format!("reason=\"{reason}\""))
                && l.contains(&format!("what=\"{what}\""))),
            "no log line for the {reason} {what}:\n{log}"
        );
    }

    // The station: what it was told.
    let ground = json_file(&ground_report);
    let user_task = &ground["user_tasks"][0];
    assert_eq!(user_task["task"], "Approve", "{user_task}");
    assert_eq!(user_task["name"], "Approve the dig");
    assert_eq!(user_task["context"]["depth"], 5.2, "{user_task}");
    let verdict = |label: &str| ground["verdicts"][label]["reply"].clone();
    let wrong = verdict("wrong_type");
    assert_eq!(wrong["applied"], false, "{wrong}");
    assert!(
        wrong["reason"].as_str().unwrap_or("").contains("approve"),
        "{wrong}"
    );
    let not_open = verdict("not_open");
    assert_eq!(not_open["applied"], false);
    assert!(
        not_open["reason"]
            .as_str()
            .unwrap_or("")
            .contains("no open user task"),
        "{not_open}"
    );
    assert_eq!(verdict("right")["applied"], true);
    assert_eq!(ground["cancel_reason"], "answered by py-op@py-station");
    // The monitor state it asked while its task was open: the task by element id and name,
    // and the drops so far counted by reason.
    let state = &ground["state"]["reply"];
    assert_eq!(state["tokens"]["Approve"], 1, "{state}");
    let open = state["in_flight"]
        .as_array()
        .and_then(|a| a.iter().find(|f| f["user_task"] == true))
        .unwrap_or_else(|| panic!("no open user task in {state}"));
    assert_eq!(open["element"], "Approve");
    assert_eq!(open["name"], "Approve the dig");
    let dropped = &state["dropped"]["py_lander"];
    for reason in ["mistyped", "garbage", "unknown_goal"] {
        assert!(
            dropped["by_reason"][reason].as_u64().unwrap_or(0) >= 1,
            "no {reason} drop counted: {state}"
        );
    }

    // The system: each goal arrived once per goal id, with its typed fields.
    let system = json_file(&system_report);
    let goals = system["goals"].as_array().expect("goals");
    let dig_goal = goals
        .iter()
        .find(|g| g["action"] == "drill.dig")
        .unwrap_or_else(|| panic!("no dig goal in {system}"));
    assert_eq!(dig_goal["fields"]["depth_cm"], 5.0);
}

/// One task on `probe.scan` (declared to take a second) with a boundary catching `OVERRUN`.
const SILENT_MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="D" targetNamespace="t">
  <error id="EO" errorCode="OVERRUN"/>
  <process id="P" isExecutable="true">
    <startEvent id="S"/>
    <sequenceFlow id="f1" sourceRef="S" targetRef="Scan"/>
    <serviceTask id="Scan"><extensionElements><trace:task resource="probe.scan"/></extensionElements></serviceTask>
    <sequenceFlow id="f2" sourceRef="Scan" targetRef="Scanned"/>
    <endEvent id="Scanned"/>
    <boundaryEvent id="Overrun" attachedToRef="Scan"><errorEventDefinition errorRef="EO"/></boundaryEvent>
    <sequenceFlow id="f3" sourceRef="Overrun" targetRef="GaveUp"/>
    <endEvent id="GaveUp"/>
  </process>
</definitions>"#;

#[test]
fn a_system_that_goes_silent_after_accepting_a_goal_is_overrun_and_cancelled() {
    let dir = tempdir("python-silent");
    let hub = endpoint(port());
    let deployment = format!("py-silent-{}", std::process::id());
    let (report, log, exec_log) = (
        dir.join("system.json"),
        dir.join("system.log"),
        dir.join("exec.log"),
    );
    let args: Vec<String> = [
        "--connect",
        &hub,
        "--deployment",
        &deployment,
        "--report",
        &report.display().to_string(),
        "--silent",
    ]
    .map(str::to_owned)
    .into();
    let system = start("trace_system.py", &args, &log);
    std::fs::write(dir.join("mission.bpmn"), SILENT_MISSION).expect("mission");
    // The watchdog's margins made short: half a second past the declared second, then a second
    // for the state query.
    std::fs::write(
        dir.join("connectors.toml"),
        "[[connector]]\nname = \"py_lander\"\nkind = \"zenoh\"\nserver = \"py_lander\"\n\
         resources = [\"probe.*\"]\ngrace_ms = 5000\n\
         limits = { overrun_margin_ms = 500, overrun_state_wait_ms = 1000 }\n",
    )
    .expect("connectors");
    let exec = Command::new(bin("trace"))
        .arg("run")
        .arg(dir.join("mission.bpmn"))
        .arg("--connectors")
        .arg(dir.join("connectors.toml"))
        .arg("--store")
        .arg(dir.join("store"))
        .args([
            "--catalogue-wait",
            "60",
            "-l",
            &hub,
            "--deployment",
            &deployment,
        ])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&exec_log).expect("exec log"))
        .spawn()
        .expect("trace run starts");
    let status = finish(exec, "trace run", &exec_log);
    let exec_text = std::fs::read_to_string(&exec_log).unwrap_or_default();
    assert!(
        status.success(),
        "trace run failed ({status}):\n{exec_text}"
    );
    assert!(finish(system, "the Python system", &log).success());
    let lines = records(&dir.join("store/record.jsonl"));
    let failed: Vec<&Value> = lines.iter().filter(|v| v["kind"] == "failed").collect();
    assert_eq!(failed.len(), 1, "{lines:#?}");
    assert_eq!(failed[0]["code"], "OVERRUN", "{failed:?}");
    assert!(
        lines
            .iter()
            .any(|v| v["kind"] == "entered" && v["element"]["id"] == "GaveUp"),
        "{lines:#?}"
    );
    // Before giving up the executive asked the goal's state, and after it sent a cancel: the
    // silent system heard both and answered neither.
    let r = json_file(&report);
    let events: Vec<&str> = r["events"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|e| e["what"].as_str())
        .collect();
    assert!(events.contains(&"state_ignored"), "{r}");
    assert!(events.contains(&"cancel_ignored"), "{r}");
}
