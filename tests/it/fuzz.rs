//! The fuzz targets' bodies without libFuzzer: every crash input kept in `fuzz/regressions/`
//! goes through its target again, and so do seeds made from the deployment; and a store whose
//! snapshot decodes but does not fit the model is refused by `trace resume`, entry named.

use std::process::{Command, Stdio};

use crate::protocol::tempdir;
use mission_tests::fuzz::{TARGETS, seed};

#[test]
fn every_kept_crash_input_runs_through_its_target_without_panicking() {
    let root = mission_tests::repo().join("fuzz/regressions");
    let mut ran = 0;
    for dir in std::fs::read_dir(&root)
        .expect("fuzz/regressions exists")
        .flatten()
    {
        let name = dir.file_name().to_string_lossy().into_owned();
        let Some((_, target)) = TARGETS.iter().find(|(n, _)| *n == name) else {
            panic!("fuzz/regressions/{name}: no fuzz target has that name");
        };
        for file in std::fs::read_dir(dir.path()).expect("a folder").flatten() {
            let bytes = std::fs::read(file.path()).expect("readable");
            eprintln!("{}", file.path().display());
            target(&bytes);
            ran += 1;
        }
    }
    assert!(ran > 0, "no regression inputs under {}", root.display());
}

#[test]
fn seeds_from_the_deployment_run_through_every_target() {
    let out = tempdir("fuzz-seeds");
    let counts = seed(&out, &[], None, None).expect("seeding works");
    for (name, target) in TARGETS {
        let dir = out.join(name);
        let Ok(files) = std::fs::read_dir(&dir) else {
            continue;
        };
        for f in files.flatten() {
            target(&std::fs::read(f.path()).expect("readable"));
        }
    }
    for name in ["loader", "expressions", "config", "wire", "answers"] {
        assert!(
            counts.get(name).copied().unwrap_or(0) > 0,
            "no {name} seeds: {counts:?}"
        );
    }
}

/// One task that takes a mission day: the run waits with a token on it.
const WAITING: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:damaged">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <serviceTask id="dig" name="Dig"><extensionElements><trace:task resource="sys.dig"/></extensionElements></serviceTask>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="dig"/>
    <sequenceFlow id="f2" sourceRef="dig" targetRef="e"/>
  </process>
</definitions>"#;

#[test]
fn a_snapshot_damaged_into_another_shape_is_refused_on_resume_with_the_entry_named() {
    let dir = tempdir("damaged-snapshot");
    std::fs::write(dir.join("m.bpmn"), WAITING).expect("mission");
    std::fs::write(
        dir.join("script.json"),
        r#"{"default": {"duration_ms": 86400000}}"#,
    )
    .expect("script");
    let store = dir.join("store");
    let mut child = Command::new(mission_tests::bin("trace"))
        .arg("run")
        .arg(dir.join("m.bpmn"))
        .arg("--store")
        .arg(&store)
        .arg("--script")
        .arg(dir.join("script.json"))
        .args(["--snapshot-every", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("trace starts");
    // It says what it waits for once the task is out and it listens for Ctrl-C.
    let stderr = std::io::BufReader::new(child.stderr.take().expect("piped"));
    let (said, heard) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in std::io::BufRead::lines(stderr).map_while(Result::ok) {
            let _ = said.send(line);
        }
    });
    let waiting = heard.iter().any(|l| l.starts_with("waiting"));
    assert!(waiting, "the run never said what it waits for");
    // Interrupted (Ctrl-C): the run stops with its store flushed, to be resumed.
    let interrupted = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(interrupted.success());
    let status = child.wait().expect("reaped");
    reader.join().expect("stderr read to its end");
    let rest: Vec<String> = heard.iter().collect();
    assert!(status.success(), "{status}: {}", rest.join("\n"));

    // A snapshot that decodes but names an element the model does not have.
    {
        let db = sled::open(&store).expect("the store opens");
        let snapshots = db.open_tree("snapshots").expect("tree");
        let (key, value) = snapshots
            .last()
            .expect("readable")
            .expect("a snapshot was written");
        let mut state: serde_json::Value = serde_json::from_slice(&value).expect("JSON");
        let tokens = state["tokens"].as_object_mut().expect("tokens");
        assert!(!tokens.is_empty(), "the snapshot holds the waiting token");
        for token in tokens.values_mut() {
            token["node"] = serde_json::json!(99_999);
        }
        snapshots
            .insert(key, serde_json::to_vec(&state).expect("JSON"))
            .expect("written");
        db.flush().expect("flushed");
    }
    let out = Command::new(mission_tests::bin("trace"))
        .arg("resume")
        .arg("--store")
        .arg(&store)
        .arg("--script")
        .arg(dir.join("script.json"))
        .output()
        .expect("trace resume runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("corrupt store entry in `snapshots`")
            && stderr.contains("does not fit the mission model")
            && stderr.contains("element #99999"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}
