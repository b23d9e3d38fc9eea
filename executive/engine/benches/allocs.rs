//! Allocations per instance of each workload the `steps` bench runs (the same models, the same
//! bound operations, tasks completing at once, record entries on), counted by an instrumented
//! system allocator: how many allocations the engine asks for does not depend on the allocator
//! behind them, and counters would slow the rate the `steps` bench measures, so they live in
//! this bench of their own; the two print one row per workload each. Run with `cargo bench -p executive-engine --bench allocs`
//! (`STEPS_ONLY=<model>` for one row).

use std::sync::Arc;

use executive_engine::Engine;
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

mod workload;
use workload::{Buffers, bind, instance, operations};

#[path = "../../model/benches/peers.rs"]
mod peers;

/// The system allocator, every allocation counted.
#[global_allocator]
static ALLOCATOR: &StatsAlloc<std::alloc::System> = &INSTRUMENTED_SYSTEM;

/// Instances counted per workload (after one to warm up).
const INSTANCES: u64 = 1_000;

fn main() {
    let models = peers::shared().join("bench/peers/models");
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(models.join("manifest.json")).expect("manifest"),
    )
    .expect("manifest json");
    let only = std::env::var("STEPS_ONLY").ok();
    println!(
        "{:<22} {:>16} {:>16} {:>18}",
        "model", "allocs/instance", "bytes/instance", "allocs/flow node"
    );
    for file in [
        "seq-100.bpmn",
        "seq-1000.bpmn",
        "par-100.bpmn",
        "loop-1000.spiff.bpmn",
        "error-boundary.bpmn",
    ] {
        if only.as_deref().is_some_and(|o| !file.contains(o)) {
            continue;
        }
        let m = &manifest[file];
        let process = m["process_id"].as_str().unwrap_or_default();
        let xml = std::fs::read_to_string(models.join(file)).expect("model");
        let graph = Arc::new(
            executive_model::load(xml.as_bytes())
                .graph
                .expect("the model loads"),
        );
        let ops = bind(&graph, &operations(&xml));
        let mut buffers = Buffers::default();
        let mut engine = Engine::new(Arc::clone(&graph));
        let mut seq = 0;
        let nodes = instance(&mut engine, &mut seq, process, &ops, &mut buffers);
        // As the `steps` bench runs them: a fresh engine per 16 instances, its state dropped
        // (and counted) with it.
        let region = Region::new(ALLOCATOR);
        let mut n = 0;
        while n < INSTANCES {
            let mut engine = Engine::new(Arc::clone(&graph));
            let mut seq = 0;
            for _ in 0..16 {
                instance(&mut engine, &mut seq, process, &ops, &mut buffers);
                n += 1;
            }
        }
        let used = region.change();
        let per = used.allocations as f64 / n as f64;
        println!(
            "{file:<22} {per:>16.1} {:>16.0} {:>18.2}",
            used.bytes_allocated as f64 / n as f64,
            per / nodes.max(1) as f64
        );
    }
}
