//! Durability costs against the disk's own fsync, measured in the same run: the latency of a
//! durable step (task result in -> engine step -> committed and flushed -> next dispatch in
//! hand), p50 and p99, beside raw `fdatasync` latency of a small write in the same directory;
//! the time to resume (open, recover, replay after the newest snapshot, in-flight commands) with
//! a 100,000-entry journal; and durable steps per second. Run with
//! `cargo bench -p executive-store --bench durable`.

use std::io::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use executive_engine::{Action, Engine, Event, Input, Vars};
use executive_store::{SledStore, Store};

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// start -> `n` service tasks in sequence -> end.
fn model(n: usize) -> Arc<executive_model::ProcessGraph> {
    let mut s = String::from(
        r#"<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="defs" targetNamespace="urn:bench"><process id="p" isExecutable="true"><startEvent id="s"/>"#,
    );
    let mut prev = "s".to_owned();
    for i in 0..n {
        s.push_str(&format!(
            r#"<serviceTask id="t{i}"><extensionElements><trace:task resource="bench.t"/></extensionElements></serviceTask><sequenceFlow id="f{i}" sourceRef="{prev}" targetRef="t{i}"/>"#
        ));
        prev = format!("t{i}");
    }
    s.push_str(&format!(
        r#"<endEvent id="e"/><sequenceFlow id="fe" sourceRef="{prev}" targetRef="e"/></process></definitions>"#
    ));
    let loaded = executive_model::load(s.as_bytes());
    Arc::new(loaded.graph.expect("bench model"))
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p) as usize]
}

fn fsync_latencies(dir: &Path, n: usize) -> Vec<f64> {
    let mut f = std::fs::File::create(dir.join("fsync-probe")).expect("probe file");
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f.write_all(&[7u8; 128]).expect("write");
            f.sync_data().expect("fdatasync");
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}

/// Drives `steps` task completions through engine + store; returns per-step latencies (ms).
fn durable_steps(
    store: &mut SledStore,
    graph: &Arc<executive_model::ProcessGraph>,
    steps: usize,
    snapshot_every: u64,
) -> Vec<f64> {
    let mut engine = Engine::new(Arc::clone(graph));
    let mut seq = 0;
    let mut next = Some(Event::InstanceStarted {
        process: "p".into(),
        vars: Vars::new(),
        start: None,
    });
    let mut lat = Vec::with_capacity(steps);
    while let Some(event) = next.take() {
        if lat.len() >= steps {
            break;
        }
        let t = Instant::now();
        seq += 1;
        let input = Input {
            seq,
            at: seq as i64,
            event,
        };
        let actions = engine.step(input.clone()).expect("accepted");
        store.commit(&input, &actions).expect("commit");
        if seq % snapshot_every == 0 {
            store.snapshot(seq, engine.state()).expect("snapshot");
        }
        // The next dispatch is now in hand: the latency ends here.
        lat.push(t.elapsed().as_secs_f64() * 1e3);
        for (i, a) in actions.iter().enumerate() {
            store.done(seq, i as u32).expect("done");
            if let Action::DispatchTask { task, .. } = a {
                next = Some(Event::TaskCompleted {
                    task: *task,
                    output: Vars::new(),
                });
            }
        }
    }
    lat
}

fn main() {
    let dir = std::env::temp_dir().join("trace-durable-bench");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("bench dir");

    // Latency of one durable step beside raw fdatasync, same disk, same run.
    let mut fsync = fsync_latencies(&dir, 500);
    let graph = model(600);
    let mut store = SledStore::open(&dir.join("latency")).expect("store");
    let mut steps = durable_steps(&mut store, &graph, 500, 1000);
    drop(store);
    let (f50, f99) = (percentile(&mut fsync, 0.5), percentile(&mut fsync, 0.99));
    let (s50, s99) = (percentile(&mut steps, 0.5), percentile(&mut steps, 0.99));
    println!("raw fdatasync        p50 {f50:.3} ms  p99 {f99:.3} ms");
    println!(
        "durable step         p50 {s50:.3} ms  p99 {s99:.3} ms  ({:.1}x fsync at p50)",
        s50 / f50
    );
    let total: f64 = steps.iter().sum();
    println!(
        "durable steps/s      {:.0} (one instance, one flush per step)",
        steps.len() as f64 / (total / 1e3)
    );

    // Group commit: 64 instances whose results arrive together, one flush per batch.
    let graph = model(50);
    let mut store = SledStore::open(&dir.join("group")).expect("store");
    let mut engine = Engine::new(Arc::clone(&graph));
    let mut seq = 0u64;
    let mut queue: Vec<Event> = (0..64)
        .map(|_| Event::InstanceStarted {
            process: "p".into(),
            vars: Vars::new(),
            start: None,
        })
        .collect();
    let t = Instant::now();
    let mut total = 0usize;
    while !queue.is_empty() {
        let mut batch = Vec::with_capacity(queue.len());
        for event in queue.drain(..) {
            seq += 1;
            let input = Input {
                seq,
                at: seq as i64,
                event,
            };
            let actions = engine.step(input.clone()).expect("accepted");
            batch.push((input, actions));
        }
        store.commit_batch(&batch).expect("group commit");
        total += batch.len();
        for (input, actions) in &batch {
            for (i, a) in actions.iter().enumerate() {
                store.done(input.seq, i as u32).expect("done");
                if let Action::DispatchTask { task, .. } = a {
                    queue.push(Event::TaskCompleted {
                        task: *task,
                        output: Vars::new(),
                    });
                }
            }
        }
    }
    let s = t.elapsed().as_secs_f64();
    println!(
        "durable steps/s with group commit of 64 instances: {:.0} ({total} steps)",
        total as f64 / s
    );
    drop(store);

    // Resume with a 100,000-entry journal (snapshots every 1,000 steps). Built once, reused.
    let big = std::env::temp_dir().join("trace-durable-bench-100k-v2");
    let graph = model(100_600);
    if !big.join("ready").exists() {
        let _ = std::fs::remove_dir_all(&big);
        println!(
            "building the 100,000-entry journal once (kept in {})...",
            big.display()
        );
        let mut store = SledStore::open(&big).expect("store");
        durable_steps(&mut store, &graph, 100_500, 1000);
        std::fs::write(big.join("ready"), b"").expect("marker");
    }
    let t = Instant::now();
    let store = SledStore::open(&big).expect("store");
    let opened = t.elapsed().as_secs_f64() * 1e3;
    let rec = store.recover().expect("recover");
    let recovered = t.elapsed().as_secs_f64() * 1e3;
    let mut engine = match &rec.snapshot {
        Some((_, s)) => Engine::restore(Arc::clone(&graph), s.clone()),
        None => Engine::new(Arc::clone(&graph)),
    };
    for step in &rec.steps {
        let again = engine.step(step.input.clone()).expect("replays");
        assert_eq!(again, step.actions, "replay is deterministic");
    }
    let first = engine.in_flight();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    assert!(!first.is_empty(), "an activity is in flight");
    println!(
        "resume (100,000-entry journal, {} replayed after the snapshot) to the first re-command: {ms:.1} ms (open {opened:.1}, recover {:.1})",
        rec.steps.len(),
        recovered - opened
    );
}
