//! Data mistakes a planner makes, caught before flight: Europa with a goal input written
//! unquoted, a text for an `int` field, `maybe` for a `bool` and a misspelt variable in a
//! condition is refused by `trace validate` with each element and field named; `trace run`
//! refuses a mission that reads a name nothing writes before it starts, and starts it once
//! the name is given with `--var`.

use std::process::Command;

use mission_tests::{bin, repo};

use crate::protocol::tempdir;

/// Europa with the planner's four mistakes, in a mission directory beside Europa's connectors
/// and catalogues (as `deploy/` holds them).
fn mistaken() -> (crate::protocol::Scratch, std::path::PathBuf) {
    let dir = tempdir("dataflow-europa");
    std::fs::create_dir_all(dir.join("missions")).expect("dir");
    for f in ["connectors.toml", "catalogues", "ground"] {
        let status = Command::new("cp")
            .arg("-r")
            .arg(repo().join("deploy").join(f))
            .arg(dir.join(f))
            .status()
            .expect("cp");
        assert!(status.success());
    }
    let text = std::fs::read_to_string(repo().join("deploy/missions/europa-bsm1.bpmn"))
        .expect("Europa")
        .replace(r#"source='"mast_stereo"'"#, "source='mast_stereo'")
        .replace(
            r#"target="exposure_ms" source="40""#,
            r#"target="exposure_ms" source='"fast"'"#,
        )
        .replace(
            r#"target="use_led" source="false""#,
            r#"target="use_led" source="maybe""#,
        )
        .replace("samples_analyzed &gt;= 5", "samples_analysed &gt;= 5");
    let path = dir.join("missions/europa.bpmn");
    std::fs::write(&path, text).expect("model");
    (dir, path)
}

#[test]
fn trace_validate_refuses_each_data_mistake_naming_its_element_and_field() {
    let (_dir, path) = mistaken();
    let out = Command::new(bin("trace"))
        .arg("validate")
        .arg(&path)
        .output()
        .expect("trace runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    for needle in [
        "error[unwritten-variable]: `Capture Panoramic Image` reads `mast_stereo`, which nothing writes before it",
        "if it is a text, quote it: `\"mast_stereo\"`",
        "`Capture Panoramic Image` reads `maybe`",
        "error[literal-type]: `Capture Panoramic Image` sets `exposure_ms` (int) to `\"fast\"`, which is not of type int",
        "reads `samples_analysed`, which nothing writes before it (in `samples_analysed >= 5`); did you mean `samples_analyzed`?",
        "element `CapturePanorama`",
    ] {
        assert!(text.contains(needle), "missing {needle:?} in:\n{text}");
    }
    // Europa itself has none of them.
    let out = Command::new(bin("trace"))
        .arg("validate")
        .arg(repo().join("deploy/missions/europa-bsm1.bpmn"))
        .output()
        .expect("trace runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// A mission whose script reads `budget`, which nothing in it writes.
const READS_BUDGET: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="t">
  <process id="p" isExecutable="true">
    <startEvent id="s"/>
    <scriptTask id="plan" name="Plan" scriptFormat="cel"><script>left = budget - 10</script></scriptTask>
    <endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="plan"/>
    <sequenceFlow id="f2" sourceRef="plan" targetRef="e"/>
  </process>
</definitions>"#;

#[test]
fn trace_run_refuses_a_name_nothing_writes_until_it_is_given_at_start() {
    let dir = tempdir("dataflow-run");
    let model = dir.join("m.bpmn");
    std::fs::write(&model, READS_BUDGET).expect("model");
    let run = |store: &str, vars: &[&str]| {
        Command::new(bin("trace"))
            .arg("run")
            .arg(&model)
            .arg("--store")
            .arg(dir.join(store))
            .args(vars)
            .output()
            .expect("trace runs")
    };
    let out = run("a", &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("`Plan` reads `budget`, which nothing writes before it"),
        "{err}"
    );
    // Nothing ran: no step was recorded.
    assert!(
        !dir.join("a/record.jsonl").exists()
            || mission_tests::records(&dir.join("a/record.jsonl")).is_empty()
    );
    let out = run("b", &["--var", "budget=100"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
