//! The token engine against public conformance corpora, run as users run it: the
//! `trace conformance` command on the visible betsy and token-simulation corpora.

use std::process::Command;

use mission_tests::{bin, conformance};

#[test]
fn betsy_corpus_passes_every_visible_case() {
    let dir = conformance("betsy");
    let out = Command::new(bin("trace"))
        .args(["conformance", "betsy"])
        .arg(&dir)
        .arg(dir.join("expectations.json"))
        .output()
        .expect("trace runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    let last = stdout.lines().last().unwrap_or_default();
    assert_eq!(last, "106 passed, 0 failed", "{stdout}");
    assert!(out.status.success());
}

#[test]
fn betsy_runner_reports_failures_and_exits_nonzero() {
    // A corpus whose expectation is wrong on purpose: the runner must say so, not pass it.
    let dir = conformance("betsy");
    let tmp = std::env::temp_dir().join(format!("trace-betsy-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).expect("temp dir");
    let expectations = tmp.join("expectations.json");
    std::fs::write(
        &expectations,
        r#"[{"name":"SequenceFlow","group":"basics","cases":[{"variables":{},"start_parallel_process":false,"delay_ms":0,"expected_multiset":["SCRIPT_task9"]}]}]"#,
    )
    .expect("write");
    let out = Command::new(bin("trace"))
        .args(["conformance", "betsy"])
        .arg(&dir)
        .arg(&expectations)
        .output()
        .expect("trace runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("FAIL basics/SequenceFlow#1"), "{stdout}");
    assert_eq!(stdout.lines().last(), Some("0 passed, 1 failed"));
    assert_eq!(out.status.code(), Some(1));
}

#[test]
fn token_simulation_corpus_passes_every_counted_scenario() {
    let out = Command::new(bin("trace"))
        .args(["conformance", "token-simulation"])
        .arg(conformance("token-simulation"))
        .output()
        .expect("trace runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    // One reviewed deviation is reported with its reason and not counted.
    assert_eq!(stdout.matches("DEVIATION ").count(), 1, "{stdout}");
    assert!(
        !stdout.contains("FAIL ") && !stdout.contains("INFO "),
        "{stdout}"
    );
    assert_eq!(
        stdout.lines().last(),
        Some("92 passed, 0 failed"),
        "{stdout}"
    );
    assert!(out.status.success());
}
