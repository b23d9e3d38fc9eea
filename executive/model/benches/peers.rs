//! The peer harness of `../shared/bench/peers` (bpmn-engine, SpiffWorkflow), shared by the
//! benchmarks: installed once into a scratch copy (`shared/` is read-only), then run per model.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The shared folder beside the project (or `$TRACE_SHARED`).
pub(crate) fn shared() -> PathBuf {
    std::env::var_os("TRACE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared"))
}

fn run(cmd: &mut Command) -> Option<String> {
    let out = cmd.output().ok()?;
    if !out.status.success() {
        eprintln!(
            "{:?} failed: {}",
            cmd,
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
        );
    }
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// A scratch copy of the peer harness with bpmn-engine and SpiffWorkflow installed.
pub(crate) fn peers() -> Option<PathBuf> {
    let dir = std::env::temp_dir().join("trace-bench-peers");
    if !dir.join("node_modules/bpmn-engine/package.json").exists()
        || !dir.join(".venv/bin/python").exists()
    {
        std::fs::create_dir_all(&dir).ok()?;
        for f in [
            "package.json",
            "package-lock.json",
            "requirements.txt",
            "run_bpmn_engine.js",
            "run_spiff.py",
        ] {
            std::fs::copy(shared().join("bench/peers").join(f), dir.join(f)).ok()?;
        }
        run(Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund", "--silent"])
            .current_dir(&dir))?;
        run(Command::new("python3")
            .args(["-m", "venv", ".venv"])
            .current_dir(&dir))?;
        run(Command::new(dir.join(".venv/bin/pip"))
            .args(["install", "-q", "-r", "requirements.txt"])
            .current_dir(&dir))?;
    }
    Some(dir)
}

/// Runs a peer (`bpmn-engine` or `spiff`) on `model` with `args` and returns its JSON line;
/// `None` if it failed (the reason is printed).
pub(crate) fn report(
    dir: &Path,
    engine: &str,
    model: &Path,
    args: &[&str],
) -> Option<serde_json::Value> {
    let model = model.to_str()?;
    let out = match engine {
        "bpmn-engine" => run(Command::new("node")
            .args([
                "--stack-size=4000",
                "--max-old-space-size=8192",
                "--expose-gc",
                "run_bpmn_engine.js",
                model,
            ])
            .args(args)
            .current_dir(dir))?,
        _ => run(Command::new(dir.join(".venv/bin/python"))
            .args(["run_spiff.py", model])
            .args(args)
            .arg("--deep")
            .current_dir(dir))?,
    };
    let line: serde_json::Value = serde_json::from_str(out.lines().last()?).ok()?;
    if let Some(e) = line.get("error") {
        eprintln!("{engine} on {model}: {e}");
        return None;
    }
    Some(line)
}

/// Fresh processes per peer measurement: the harness's own matrix takes the median over three
/// (`REPS=3` in `run_all.sh`), as one process's figure moves by half between runs (bpmn-engine
/// parsing `seq-1000`: 47 to 80 ms in three runs of one hour).
pub(crate) const REPS: usize = 3;

/// The median of `field` over [`REPS`] fresh runs of a peer (see [`report`]); `None` if every
/// run failed.
pub(crate) fn median(
    dir: &Path,
    engine: &str,
    model: &Path,
    args: &[&str],
    field: &str,
) -> Option<f64> {
    let mut values: Vec<f64> = (0..REPS)
        .filter_map(|_| report(dir, engine, model, args)?[field].as_f64())
        .collect();
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}
