//! Wall time of the full Europa mission over Zenoh — executive, lander simulator and ground
//! responder as separate release processes on loopback — at increasing time scales, with the
//! CPU time each process used, so the share of executive, simulator and transport/waiting shows.
//! Baseline in the same run: the clock-bound time (mission time / speed) the mission cannot go
//! below. The executive's footprint beside it: its peak resident memory (`VmHWM`) over the
//! flight, and a window of real time (speed 1, `TRACE_BENCH_REALTIME_S` seconds, default 60)
//! with its resident memory and CPU time there. `cargo bench -p elap-sim --bench flight` (builds
//! the release binaries first).

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

/// A field of `/proc/<pid>/status` in MiB (`VmRSS`, `VmHWM`: given there in kB).
fn memory(pid: u32, field: &str) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
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

/// What one flight measured.
struct Flight {
    /// Wall seconds from the executive's start to its end (or to the window's end).
    wall: f64,
    /// The CPU seconds of the executive, the simulator and the ground station.
    cpu: [f64; 3],
    /// The executive's resident memory at the end, and its peak, MiB.
    rss: f64,
    peak: f64,
    /// The record's lines.
    record: Vec<serde_json::Value>,
}

/// Europa flown at `speed`, to its end, or for `window` of wall time.
fn fly(speed: f64, window: Option<Duration>) -> Flight {
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
    let (mut exec_cpu, mut rss, mut peak) = (0.0, 0.0, 0.0);
    loop {
        // Read while the process lives: its /proc entry goes with it.
        if let Some(c) = cpu(exec.id()) {
            exec_cpu = c;
        }
        rss = memory(exec.id(), "VmRSS:").unwrap_or(rss);
        peak = memory(exec.id(), "VmHWM:").unwrap_or(peak);
        if exec.try_wait().expect("wait").is_some() {
            break;
        }
        if window.is_some_and(|w| t.elapsed() >= w) {
            let _ = (exec.kill(), exec.wait());
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let wall = t.elapsed().as_secs_f64();
    let cpu = [
        exec_cpu,
        cpu(sim.id()).unwrap_or(0.0),
        cpu(ground.id()).unwrap_or(0.0),
    ];
    let _ = (sim.kill(), ground.kill(), sim.wait(), ground.wait());
    let text = std::fs::read_to_string(dir.join("store/record.jsonl")).unwrap_or_default();
    let record = text
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    Flight {
        wall,
        cpu,
        rss,
        peak,
        record,
    }
}

/// Mission milliseconds from the record's first line to its last.
fn span(record: &[serde_json::Value]) -> i64 {
    let at = |v: Option<&serde_json::Value>| v.and_then(|v| v["mission_ms"].as_i64()).unwrap_or(0);
    at(record.last()) - at(record.first())
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
        "{:>10} {:>9} {:>11} {:>10} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8}",
        "speed",
        "mission",
        "clock-bound",
        "wall",
        "exec cpu",
        "exec rss",
        "exec peak",
        "sim cpu",
        "ground cpu",
        "samples"
    );
    for speed in [200_000.0, 1_000_000.0] {
        let f = fly(speed, None);
        let ms = span(&f.record);
        let samples = f
            .record
            .iter()
            .filter(|v| v["resource"] == "instrument.analyze" && v["kind"] == "dispatched")
            .count();
        let outcome = f
            .record
            .iter()
            .rev()
            .find(|v| v["kind"] == "instance_finished")
            .map_or_else(|| "did not end".to_owned(), |v| v["outcome"].to_string());
        println!(
            "{:>9}x {:>8.1}d {:>10.2}s {:>9.2}s {:>8.2}s {:>7.1}MB {:>7.1}MB {:>8.2}s {:>9.2}s {:>8}  {}",
            speed,
            ms as f64 / 86_400_000.0,
            ms as f64 / 1000.0 / speed,
            f.wall,
            f.cpu[0],
            f.rss,
            f.peak,
            f.cpu[1],
            f.cpu[2],
            samples,
            outcome
        );
    }
    println!(
        "(transport and waiting = wall − the processes' CPU; goal: a 20-day mission in under 10 s)"
    );
    let secs: u64 = std::env::var("TRACE_BENCH_REALTIME_S")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    let f = fly(1.0, Some(Duration::from_secs(secs)));
    println!(
        "real time, the first {:.0} s of the mission ({} record lines): executive resident {:.1} MB \
         (peak {:.1} MB), CPU {:.2} s ({:.2} % of one core)",
        f.wall,
        f.record.len(),
        f.rss,
        f.peak,
        f.cpu[0],
        100.0 * f.cpu[0] / f.wall
    );
    println!("(goal: the executive under 40 MB resident on Europa)");
}
