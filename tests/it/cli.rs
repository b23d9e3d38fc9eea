//! The `trace` command as users run it: `trace validate`'s exit codes, rustc-style diagnostics
//! with line:column and a caret, and `--json` for tools, each ending quietly when its reader
//! goes away; and `docs/cli.md`, the reference of
//! every command and flag, equal to what the clap definitions say (`TRACE_BLESS=1` writes it
//! again after a change); every binary's `--version` with its commit and Zenoh's version.

use std::io::Read;
use std::process::{Command, Stdio};

use mission_tests::{bin, repo};

const BROKEN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" id="d" targetNamespace="urn:t">
  <bpmn:process id="p" isExecutable="true">
    <bpmn:startEvent id="start"/>
    <bpmn:serviceTask id="drill" name="Drill"/>
    <bpmn:intermediateCatchEvent id="wait"><bpmn:timerEventDefinition><bpmn:timeDuration xsi:type="bpmn:tFormalExpression">two days</bpmn:timeDuration></bpmn:timerEventDefinition></bpmn:intermediateCatchEvent>
    <bpmn:endEvent id="end"/>
    <bpmn:sequenceFlow id="f1" sourceRef="start" targetRef="drill"/>
    <bpmn:sequenceFlow id="f2" sourceRef="drill" targetRef="wait"/>
    <bpmn:sequenceFlow id="f3" sourceRef="wait" targetRef="nowhere"/>
  </bpmn:process>
</bpmn:definitions>
"#;

fn trace(args: &[&str]) -> (i32, String) {
    let out = Command::new(bin("trace"))
        .args(args)
        .output()
        .expect("trace runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

fn temp_model(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("trace-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

// `trace validate … | head`: the reader goes away after a few bytes; the command ends quietly
// (no "Broken pipe" error), in either format.
#[test]
fn validate_ends_quietly_when_its_reader_goes_away() {
    let path = temp_model("noisy.bpmn", BROKEN);
    for json in [false, true] {
        let mut command = Command::new(bin("trace"));
        command.arg("validate");
        if json {
            command.arg("--json");
        }
        // Far more than a pipe holds, so the command is still writing when the reader leaves.
        let mut child = command
            .args(std::iter::repeat_n(&path, 2000))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("trace runs");
        let mut out = child.stdout.take().expect("stdout");
        let mut first = [0u8; 64];
        out.read_exact(&mut first).expect("the first bytes");
        drop(out);
        let ended = child.wait_with_output().expect("trace ends");
        let stderr = String::from_utf8_lossy(&ended.stderr);
        assert!(ended.status.success(), "json {json}: {stderr}");
        assert!(!stderr.contains("Broken pipe"), "json {json}: {stderr}");
    }
}

#[test]
fn the_europa_mission_is_valid() {
    let mission = repo().join("deploy/missions/europa-bsm1.bpmn");
    let (code, out) = trace(&["validate", mission.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    assert!(out.trim_end().ends_with("europa-bsm1.bpmn: valid"), "{out}");
}

#[test]
fn a_broken_model_gets_every_problem_with_its_position() {
    let path = temp_model("broken.bpmn", BROKEN);
    let (code, out) = trace(&["validate", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}");
    for (code, line) in [
        ("missing-resource", 5),
        ("bad-timer", 6),
        ("dangling-reference", 10),
    ] {
        assert!(
            out.contains(&format!("[{code}")),
            "{code} missing from:\n{out}"
        );
        assert!(
            out.contains(&format!("broken.bpmn:{line}:")),
            "line {line} missing from:\n{out}"
        );
    }
    assert!(out.contains('^'), "a caret under the source line:\n{out}");
    assert!(out.contains("error(s)"), "{out}");
}

#[test]
fn json_output_and_exit_codes_for_tools() {
    let broken = temp_model("broken-json.bpmn", BROKEN);
    let garbage = temp_model("garbage.bpmn", "not xml at all");
    let (code, out) = trace(&[
        "validate",
        "--json",
        broken.to_str().unwrap(),
        garbage.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "the worst verdict decides: unreadable");
    let reports: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(reports[0]["verdict"], "invalid");
    assert!(reports[0]["diagnostics"].as_array().unwrap().len() >= 3);
    assert_eq!(reports[0]["diagnostics"][0]["line"], 5);
    assert_eq!(reports[1]["verdict"], "unreadable");
    let (code, _) = trace(&["validate", "/nonexistent/mission.bpmn"]);
    assert_eq!(code, 2);
}

#[test]
fn the_command_reference_is_what_the_clap_definitions_say() {
    let (code, generated) = trace(&["cli-reference"]);
    assert_eq!(code, 0);
    let path = repo().join("docs/cli.md");
    if std::env::var_os("TRACE_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("docs/cli.md written");
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "docs/cli.md differs from `trace cli-reference`: run the test again with TRACE_BLESS=1 \
         and commit the file (first differing line: {:?})",
        committed
            .lines()
            .zip(generated.lines())
            .find(|(a, b)| a != b)
    );
}

/// Every binary's `--version`: its name, the workspace version, the commit it was built from
/// (this clone's HEAD) and the Zenoh version of `Cargo.lock`.
#[test]
fn every_binary_says_its_version_commit_and_zenoh() {
    let lock = std::fs::read_to_string(repo().join("Cargo.lock")).expect("Cargo.lock");
    let zenoh = lock
        .split("[[package]]")
        .find(|p| p.contains("\nname = \"zenoh\"\n"))
        .and_then(|p| p.split("version = \"").nth(1))
        .and_then(|v| v.split('"').next())
        .expect("zenoh in Cargo.lock")
        .to_owned();
    let head = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(repo())
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or_else(
            || "unknown".to_owned(),
            |o| String::from_utf8_lossy(&o.stdout).trim().to_owned(),
        );
    for name in ["trace", "elap-sim", "ground-station", "trace-mock-system"] {
        let out = Command::new(bin(name))
            .arg("--version")
            .output()
            .expect("--version");
        assert!(out.status.success(), "{name}");
        assert_eq!(
            String::from_utf8_lossy(&out.stdout).trim(),
            format!(
                "{name} {} (commit {head}, zenoh {zenoh})",
                env!("CARGO_PKG_VERSION")
            )
        );
    }
}
