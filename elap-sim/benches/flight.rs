//! Wall time of the full Europa mission over Zenoh — executive, lander simulator and ground
//! responder as separate release processes on loopback — at increasing time scales, with the
//! CPU time each process used, so the share of executive, simulator and transport/waiting shows.
//! Baseline in the same run: the clock-bound time (mission time / speed) the mission cannot go
//! below. `cargo bench -p elap-sim --bench flight` (builds the release binaries first).

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn target() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"))
        .join("release")
}

/// CPU seconds a live process has used (utime + stime from /proc).
fn cpu(pid: u32) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn system(bin: &str, args: &[String]) -> Child {
    let mut c = Command::new(target().join(bin))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("system starts");
    let mut line = String::new();
    std::io::BufReader::new(c.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("ready");
    c
}

fn main() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let ok = Command::new(cargo)
        .args(["build", "--release", "--quiet", "--workspace", "--bins"])
        .current_dir(root())
        .status()
        .expect("cargo");
    assert!(ok.success());
    println!("Europa BSM-1, nominal (quiet profile), three processes on loopback:");
    println!(
        "{:>10} {:>9} {:>11} {:>10} {:>9} {:>9} {:>10} {:>8}",
        "speed", "mission", "clock-bound", "wall", "exec cpu", "sim cpu", "ground cpu", "samples"
    );
    for speed in [200_000.0, 1_000_000.0] {
        let dir =
            std::env::temp_dir().join(format!("trace-bench-flight-{}-{speed}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .map(|a| a.port())
            .expect("port");
        let hub = format!("tcp/127.0.0.1:{port}");
        let mut sim = system(
            "elap-sim",
            &[
                "--speed".into(),
                speed.to_string(),
                "--profile".into(),
                "quiet".into(),
                "--start-ms".into(),
                "1790000000000".into(),
                "-e".into(),
                hub.clone(),
            ],
        );
        let policy = root().join("deploy/ground/policy.toml");
        let mut ground = system(
            "ground-station",
            &[
                "--policy".into(),
                policy.display().to_string(),
                "-e".into(),
                hub.clone(),
            ],
        );
        let t = Instant::now();
        let mut exec = Command::new(target().join("trace"))
            .arg("run")
            .arg(root().join("deploy/missions/europa-bsm1.bpmn"))
            .arg("--store")
            .arg(dir.join("store"))
            .arg("--connectors")
            .arg(root().join("deploy/connectors.toml"))
            .args(["-l", &hub])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("executive");
        let mut exec_cpu = 0.0;
        loop {
            if let Some(c) = cpu(exec.id()) {
                exec_cpu = c;
            }
            if exec.try_wait().expect("wait").is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let wall = t.elapsed().as_secs_f64();
        let (sim_cpu, ground_cpu) = (
            cpu(sim.id()).unwrap_or(0.0),
            cpu(ground.id()).unwrap_or(0.0),
        );
        let _ = (sim.kill(), ground.kill(), sim.wait(), ground.wait());
        let record = std::fs::read_to_string(dir.join("store/record.jsonl")).unwrap_or_default();
        let lines: Vec<serde_json::Value> = record
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect();
        let t0 = lines
            .first()
            .and_then(|v| v["mission_ms"].as_i64())
            .unwrap_or(0);
        let t1 = lines
            .last()
            .and_then(|v| v["mission_ms"].as_i64())
            .unwrap_or(0);
        let days = (t1 - t0) as f64 / 86_400_000.0;
        let samples = record.matches(r#""resource":"instrument.analyze""#).count();
        let outcome = lines
            .iter()
            .rev()
            .find(|v| v["kind"] == "instance_finished")
            .map_or_else(|| "did not end".to_owned(), |v| v["outcome"].to_string());
        println!(
            "{:>9}x {:>8.1}d {:>10.2}s {:>9.2}s {:>8.2}s {:>8.2}s {:>9.2}s {:>8}  {}",
            speed,
            days,
            (t1 - t0) as f64 / 1000.0 / speed,
            wall,
            exec_cpu,
            sim_cpu,
            ground_cpu,
            samples,
            outcome
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
    println!(
        "(transport and waiting = wall − the processes' CPU; goal: a 20-day mission in under 10 s)"
    );
}
