//! `trace fly` as a user runs it: from a directory that is not the repository, as installed
//! binaries (the systems found next to `trace` or on `PATH`, the demo mission and its files
//! built in), and two flights at once while a Zenoh router's default port is taken — each
//! flight its own deployment on its own free port; each finished flight's record replays
//! through the engine (`trace replay`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use mission_tests::bin;

use crate::protocol::tempdir;

/// `name` installed into `dir`: a hard link to the built binary where the file system allows,
/// else a copy (not a symbolic link, which `current_exe` would resolve back to the build).
fn install(name: &str, dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).expect("bin dir");
    let to = dir.join(name);
    if std::fs::hard_link(bin(name), &to).is_err() {
        std::fs::copy(bin(name), &to).expect("copy");
    }
    to
}

/// `trace fly` of the built-in mission with `trace` at `trace`, in `cwd`, with this `PATH`.
fn fly(trace: &Path, cwd: &Path, path: &str) -> Command {
    let mut c = Command::new(trace);
    c.current_dir(cwd)
        .env("PATH", path)
        .env_remove("TRACE_DEPLOYMENT")
        .args(["fly", "--speed", "100000", "--profile", "quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    c
}

fn said(out: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The value after the word `word` in `line` (up to a comma or white space).
fn after<'l>(line: &'l str, word: &str) -> &'l str {
    line.split_once(&format!(" {word} "))
        .map(|(_, rest)| rest.split([',', ' ']).next().unwrap_or(rest))
        .unwrap_or_else(|| panic!("no `{word}` in {line}"))
}

#[test]
fn an_installed_trace_without_its_systems_says_where_it_looked() {
    let root = tempdir("fly-lonely");
    let trace = install("trace", &root.join("bin"));
    let work = root.join("work");
    std::fs::create_dir_all(&work).expect("work dir");
    let out = fly(&trace, &work, "/usr/bin:/bin").output().expect("runs");
    assert!(!out.status.success(), "{}", said(&out));
    let text = said(&out);
    assert!(
        text.contains(&format!(
            "elap-sim: not found next to {} or on PATH",
            root.join("bin").display()
        )),
        "{text}"
    );
}

#[test]
fn two_flights_at_once_from_anywhere_each_its_own_deployment_and_port() {
    let _one = crate::europa::FLIGHT
        .lock()
        .unwrap_or_else(|p| p.into_inner());
    // A Zenoh router's default port, taken for the test (already taken: all the better).
    let _router = std::net::TcpListener::bind("127.0.0.1:7447").ok();
    let root = tempdir("fly-anywhere");
    let work = root.join("work");
    std::fs::create_dir_all(&work).expect("work dir");
    // One flight as an installed set: `trace` alone in one directory, the systems on PATH.
    let installed = install("trace", &root.join("bin"));
    for system in ["elap-sim", "ground-station"] {
        install(system, &root.join("systems"));
    }
    let on_path = format!("{}:/usr/bin:/bin", root.join("systems").display());
    // The other as built, by absolute path: the systems sit next to it.
    let built = bin("trace");
    assert!(built.is_absolute());
    let flights: Vec<_> = [(installed, on_path), (built, "/usr/bin:/bin".to_owned())]
        .into_iter()
        .map(|(trace, path)| {
            let child = fly(&trace, &work, &path).spawn().expect("trace fly starts");
            std::thread::spawn(move || child.wait_with_output().expect("trace fly"))
        })
        .collect();
    let outs: Vec<Output> = flights
        .into_iter()
        .map(|f| f.join().expect("flight thread"))
        .collect();
    let mut places = Vec::new();
    for out in &outs {
        let text = said(out);
        assert!(out.status.success(), "{text}");
        for line in [
            "flying europa-bsm1.bpmn (built in)",
            "mission summary",
            "outcome:           instance 1",
            "timeline:",
        ] {
            assert!(text.contains(line), "missing {line:?} in:\n{text}");
        }
        let first = text.lines().next().expect("a first line");
        let (hub, deployment) = (after(first, "on"), after(first, "deployment"));
        assert!(hub.starts_with("tcp/127.0.0.1:"), "{first}");
        assert_ne!(hub, "tcp/127.0.0.1:7447", "{first}");
        places.push((hub.to_owned(), deployment.to_owned()));
    }
    assert_ne!(places[0].0, places[1].0, "one port for two flights");
    assert_ne!(places[0].1, places[1].1, "one deployment for two flights");
    // Both flights landed in the working directory, each with a copy of what it flew; each
    // flight's station was offered exactly its own flight's user tasks.
    for (_, deployment) in &places {
        let dir = work.join("flights").join(deployment);
        for file in ["europa-bsm1.bpmn", "connectors.toml", "ground-policy.toml"] {
            assert!(dir.join(file).is_file(), "{}: no {file}", dir.display());
        }
        let record = std::fs::read_to_string(dir.join("store/record.jsonl")).expect("record");
        let opened = record.matches(r#""kind":"user_task_opened""#).count();
        assert!(opened > 0);
        let ground = std::fs::read_to_string(dir.join("ground.log")).expect("ground log");
        assert!(
            ground
                .lines()
                .next()
                .is_some_and(|l| l.contains(&format!("deployment {deployment} "))),
            "{ground}"
        );
        assert_eq!(ground.matches(" open: ").count(), opened, "{ground}");
        let sim = std::fs::read_to_string(dir.join("elap-sim.log")).expect("sim log");
        assert!(
            sim.starts_with(&format!("ready lander_sim — deployment {deployment} ")),
            "{sim}"
        );
        // The finished flight replays through the engine, every line as recorded, one state per
        // step, and ends with no token left.
        let steps: std::collections::BTreeSet<u64> = record
            .lines()
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter_map(|v| v["seq"].as_u64())
            .collect();
        let out = Command::new(bin("trace"))
            .arg("replay")
            .arg(dir.join("europa-bsm1.bpmn"))
            .arg(dir.join("store/record.jsonl"))
            .output()
            .expect("trace replay");
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(text.lines().count(), steps.len());
        let last = text.lines().last().expect("a last step");
        assert!(last.ends_with("| "), "tokens left at the end: {last}");
    }
}
