//! Engine throughput and idle memory against bpmn-engine and SpiffWorkflow, same run.
//!
//! For each workload of `../shared/bench/peers/models` the engine runs one verification
//! instance (completed flow nodes must match `manifest.json`), then K instances back to back
//! with service tasks completing at once (`noop`, `inc`, `fail` as the peer harness defines
//! them); the peers run the same files in the same run, with the K and warm-ups of the harness's
//! matrix, each peer's figure the median of three fresh processes as the matrix takes it.
//! Prints completed flow nodes per second, instances per second and the ratio to the faster
//! peer; then memory per idle instance waiting on a user task. Run with `cargo bench -p executive-engine --bench steps`
//! (`STEPS_ONLY=<model>` for one row).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use executive_engine::{Engine, Event, Input, Vars};

mod workload;
use workload::{Buffers, bind, instance, operations};

#[path = "../../model/benches/peers.rs"]
mod peers;
use peers::{median, peers, report, shared};

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

struct Row {
    steps_per_s: f64,
    instances_per_s: f64,
}

fn ours(path: &Path, process: &str, expected: usize, min_seconds: f64) -> Result<Row, String> {
    let xml = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let loaded = executive_model::load(xml.as_bytes());
    let graph = Arc::new(
        loaded
            .graph
            .ok_or_else(|| format!("{:?}", loaded.diagnostics.first()))?,
    );
    let ops = bind(&graph, &operations(&xml));
    let mut buffers = Buffers::default();
    let mut e = Engine::new(Arc::clone(&graph));
    let mut seq = 0;
    let steps = instance(&mut e, &mut seq, process, &ops, &mut buffers);
    if steps != expected {
        return Err(format!("{steps} flow nodes completed, expected {expected}"));
    }
    let start = Instant::now();
    let mut n = 0u64;
    while start.elapsed().as_secs_f64() < min_seconds || n < 3 {
        // A fresh engine per batch keeps the finished instances from piling up.
        let mut e = Engine::new(Arc::clone(&graph));
        let mut seq = 0;
        for _ in 0..16 {
            instance(&mut e, &mut seq, process, &ops, &mut buffers);
            n += 1;
        }
    }
    let s = start.elapsed().as_secs_f64();
    Ok(Row {
        steps_per_s: (n as f64 * steps as f64) / s,
        instances_per_s: n as f64 / s,
    })
}

fn rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

fn idle_kb_per_instance(path: &Path, n: usize) -> Option<f64> {
    let loaded = executive_model::load(&std::fs::read(path).ok()?);
    let graph = Arc::new(loaded.graph?);
    let before = rss_kb()?;
    let mut e = Engine::new(graph);
    for i in 0..n {
        let _ = e.step(Input {
            seq: i as u64 + 1,
            at: 0,
            event: Event::InstanceStarted {
                process: "wait_user".into(),
                vars: Vars::new(),
                start: None,
            },
        });
    }
    let waiting = e
        .state()
        .instances
        .values()
        .filter(|i| i.outcome.is_none())
        .count();
    assert_eq!(waiting, n, "every instance waits on its user task");
    let after = rss_kb()?;
    Some((after.saturating_sub(before)) as f64 / n as f64)
}

fn main() {
    let models = shared().join("bench/peers/models");
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(models.join("manifest.json")).expect("manifest"),
    )
    .expect("manifest json");
    let peers = peers();
    // (ours and SpiffWorkflow's file, bpmn-engine's file, bpmn-engine's and SpiffWorkflow's
    // arguments): K, warm-ups and flags as in the harness's matrix (`rows()` of `run_all.sh`).
    type Row<'a> = (&'a str, &'a str, &'a [&'a str], &'a [&'a str]);
    let rows: [Row; 5] = [
        (
            "seq-100.bpmn",
            "seq-100.bpmn",
            &["10", "--warmup", "1"],
            &["60", "--warmup", "6"],
        ),
        (
            "seq-1000.bpmn",
            "seq-1000.bpmn",
            &["2", "--defer", "nexttick"],
            &["1"],
        ),
        (
            "par-100.bpmn",
            "par-100.bpmn",
            &["10", "--warmup", "1"],
            &["10", "--warmup", "1"],
        ),
        (
            "loop-1000.spiff.bpmn",
            "loop-1000.bpmn-engine.bpmn",
            &["2", "--defer", "nexttick"],
            &["1"],
        ),
        (
            "error-boundary.bpmn",
            "error-boundary.bpmn",
            &["250", "--warmup", "25"],
            &["3000", "--warmup", "300"],
        ),
    ];
    println!(
        "{:<22} {:>14} {:>14} {:>14} {:>10} {:>12}",
        "model", "ours steps/s", "bpmn-engine", "Spiff", "x faster", "ours inst/s"
    );
    // `STEPS_ONLY=error-boundary` runs the rows whose model name contains it (for profiling).
    let only = std::env::var("STEPS_ONLY").ok();
    for (file, engine_file, engine_args, spiff_args) in rows {
        if only.as_deref().is_some_and(|o| !file.contains(o)) {
            continue;
        }
        let m = &manifest[file];
        let process = m["process_id"].as_str().unwrap_or_default();
        let expected = m["expected_completed_flow_nodes"].as_u64().unwrap_or(0) as usize;
        let ours = match ours(&models.join(file), process, expected, 1.0) {
            Ok(r) => r,
            Err(e) => {
                println!("{file:<22} ours failed: {e}");
                continue;
            }
        };
        let steps = |engine: &str, f: &str, args: &[&str]| {
            peers
                .as_deref()
                .and_then(|d| median(d, engine, &models.join(f), args, "steps_per_s"))
        };
        let be = steps("bpmn-engine", engine_file, engine_args);
        let sp = steps("spiff", file, spiff_args);
        let faster = [be, sp].into_iter().flatten().reduce(f64::max);
        let show = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.0}"));
        let ratio = faster.map_or("-".to_owned(), |f| format!("{:.0}x", ours.steps_per_s / f));
        println!(
            "{file:<22} {:>14.0} {:>14} {:>14} {ratio:>10} {:>12.0}",
            ours.steps_per_s,
            show(be),
            show(sp),
            ours.instances_per_s
        );
    }
    // The loop again with its condition written in FEEL (`=count < 1000`, as Camunda 8 writes
    // it): what FEEL costs against CEL, both measured in this run.
    if only.as_deref().is_none_or(|o| "loop-1000-feel".contains(o)) {
        let file = "loop-1000.spiff.bpmn";
        let m = &manifest[file];
        let process = m["process_id"].as_str().unwrap_or_default();
        let expected = m["expected_completed_flow_nodes"].as_u64().unwrap_or(0) as usize;
        let xml = std::fs::read_to_string(models.join(file)).expect("loop model");
        let feel =
            std::env::temp_dir().join(format!("trace-loop-feel-{}.bpmn", std::process::id()));
        std::fs::write(
            &feel,
            xml.replace(">count &lt; 1000<", ">=count &lt; 1000<"),
        )
        .expect("FEEL loop model");
        let cel = ours(&models.join(file), process, expected, 1.0);
        let with_feel = ours(&feel, process, expected, 1.0);
        let _ = std::fs::remove_file(&feel);
        match (cel, with_feel) {
            (Ok(c), Ok(f)) => println!(
                "{:<22} {:>14.0} steps/s with FEEL, {:.0} with CEL: FEEL/CEL {:.2}",
                "loop-1000 (FEEL)",
                f.steps_per_s,
                c.steps_per_s,
                f.steps_per_s / c.steps_per_s
            ),
            (c, f) => println!("loop-1000 (FEEL) failed: {:?} / {:?}", c.err(), f.err()),
        }
    }
    let wait = models.join("wait-user.bpmn");
    let ours_kb = idle_kb_per_instance(&wait, 10_000);
    let idle = |engine: &str| {
        peers
            .as_deref()
            .and_then(|d| report(d, engine, &wait, &["1000", "--mode", "idle"]))
            .and_then(|l| l["rss_delta_kb_per_instance"].as_f64())
    };
    let show = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.2}"));
    println!(
        "idle instance (KB, RSS delta): ours {} (10,000 held), bpmn-engine {}, Spiff {} (1,000 held)",
        show(ours_kb),
        show(idle("bpmn-engine")),
        show(idle("spiff"))
    );
}
