//! Parse + validate benchmark: our loader against bpmn-engine and SpiffWorkflow, same run.
//!
//! Times `executive_model::load` on a generated 10,000-node model and on the peers'
//! `seq-1000.bpmn`, then runs the peer harness of `../shared/bench/peers` (parse mode) on the same
//! files in the same run (each peer's figure the median of three fresh processes, as the
//! harness's matrix takes it), and prints each time and the ratio to the faster peer. The limit is
//! printed beside: quick-xml reading the same bytes, every event and attribute, with no tree
//! (`raw ms`, and how many times that the loader takes). The peers are
//! installed once into a scratch copy of the harness (`$TMPDIR/trace-bench-peers`), since
//! `shared/` is read-only. Run with `cargo bench -p executive-model --bench parse`.
//! `PARSE_ONLY=seq-1000` (or `generated`) loads that model `PARSE_REPS` times (default 2,000)
//! and nothing else, for profiling.

use std::path::Path;
use std::time::Instant;

#[path = "peers.rs"]
mod peers;
use peers::{peers, shared};

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// start -> `n - 2` service tasks -> end, bound for both us and the peers.
fn generated(n: usize) -> String {
    let mut s = String::from(concat!(
        r#"<?xml version="1.0" encoding="UTF-8"?><bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" "#,
        r#"xmlns:spiffworkflow="http://spiffworkflow.org/bpmn/schema/1.0/core" "#,
        r#"xmlns:trace="urn:trace:bpmn:1.0" id="Definitions_gen" targetNamespace="urn:bench"><bpmn:process id="gen" isExecutable="true">"#,
        r#"<bpmn:startEvent id="s"><bpmn:outgoing>f0</bpmn:outgoing></bpmn:startEvent>"#
    ));
    for i in 1..n - 1 {
        s.push_str(&format!(
            r#"<bpmn:serviceTask id="t{i}" implementation="${{environment.services.noop}}"><bpmn:extensionElements><trace:task resource="bench.noop"/><spiffworkflow:serviceTaskOperator id="noop" resultVariable="r"><spiffworkflow:parameters /></spiffworkflow:serviceTaskOperator></bpmn:extensionElements><bpmn:incoming>f{}</bpmn:incoming><bpmn:outgoing>f{i}</bpmn:outgoing></bpmn:serviceTask><bpmn:sequenceFlow id="f{}" sourceRef="{}" targetRef="t{i}"/>"#,
            i - 1,
            i - 1,
            if i == 1 { "s".to_owned() } else { format!("t{}", i - 1) }
        ));
    }
    s.push_str(&format!(
        r#"<bpmn:endEvent id="e"><bpmn:incoming>f{0}</bpmn:incoming></bpmn:endEvent><bpmn:sequenceFlow id="f{0}" sourceRef="t{0}" targetRef="e"/></bpmn:process></bpmn:definitions>"#,
        n - 2
    ));
    s
}

/// Median wall time of `reps` loads, in milliseconds.
fn ours(bytes: &[u8], reps: usize) -> (f64, usize) {
    let diagnostics = executive_model::load(bytes).diagnostics.len();
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            let loaded = executive_model::load(bytes);
            std::hint::black_box(&loaded);
            t.elapsed().as_secs_f64() * 1000.0
        })
        .collect();
    times.sort_by(f64::total_cmp);
    (times[reps / 2], diagnostics)
}

/// Median wall time (ms) of quick-xml reading every event and attribute of `bytes`, building
/// nothing: the floor for any loader on the same XML reader. It reads as the loader does,
/// borrowing from the bytes (no event buffer to copy into).
fn raw(bytes: &[u8], reps: usize) -> f64 {
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            let mut reader = quick_xml::Reader::from_reader(bytes);
            let mut seen = 0usize;
            loop {
                match reader.read_event() {
                    Ok(quick_xml::events::Event::Eof) | Err(_) => break,
                    Ok(quick_xml::events::Event::Start(e) | quick_xml::events::Event::Empty(e)) => {
                        seen += e
                            .attributes()
                            .flatten()
                            .map(|a| a.value.len())
                            .sum::<usize>();
                    }
                    Ok(_) => seen += 1,
                }
            }
            std::hint::black_box(seen);
            t.elapsed().as_secs_f64() * 1000.0
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[reps / 2]
}

/// Warm median parse time (ms) reported by a peer runner in parse mode (six parses, as in the
/// harness's matrix), the median over [`peers::REPS`] fresh processes.
fn peer(dir: &Path, engine: &str, model: &Path) -> Option<f64> {
    let args = ["6", "--mode", "parse"];
    peers::median(dir, engine, model, &args, "parse_warm_median_ms")
}

fn main() {
    if let Ok(only) = std::env::var("PARSE_ONLY") {
        let bytes = match only.as_str() {
            "generated" => generated(10_000).into_bytes(),
            _ => std::fs::read(shared().join("bench/peers/models/seq-1000.bpmn")).expect("model"),
        };
        let reps = std::env::var("PARSE_REPS")
            .ok()
            .and_then(|r| r.parse().ok())
            .unwrap_or(2_000);
        let (ms, _) = ours(&bytes, reps);
        println!("{only}: median {ms:.3} ms over {reps} loads");
        return;
    }
    let scratch = std::env::temp_dir().join("trace-bench-models");
    std::fs::create_dir_all(&scratch).expect("scratch dir");
    let generated_path = scratch.join("gen-10000.bpmn");
    std::fs::write(&generated_path, generated(10_000)).expect("write model");
    let models = [
        ("generated 10,000 nodes", generated_path),
        (
            "seq-1000.bpmn",
            shared().join("bench/peers/models/seq-1000.bpmn"),
        ),
    ];
    let peers = peers();
    if peers.is_none() {
        eprintln!(
            "peer harness unavailable (needs node, npm, python3 -m venv and registry access); printing our times only"
        );
    }
    println!(
        "{:<24} {:>10} {:>12} {:>12} {:>14} {:>8} {:>10}  diagnostics",
        "model", "ours ms", "bpmn-engine", "Spiff", "x faster peer", "raw ms", "ours/raw"
    );
    for (name, path) in &models {
        let bytes = std::fs::read(path).expect("model");
        let (ms, diagnostics) = ours(&bytes, 21);
        let floor = raw(&bytes, 21);
        let engine = peers.as_deref().and_then(|d| peer(d, "bpmn-engine", path));
        let spiff = peers.as_deref().and_then(|d| peer(d, "spiff", path));
        let faster = [engine, spiff].into_iter().flatten().reduce(f64::min);
        let show = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.2}"));
        let ratio = faster.map_or("-".to_owned(), |f| format!("{:.0}x", f / ms));
        println!(
            "{name:<24} {ms:>10.3} {:>12} {:>12} {ratio:>14} {floor:>8.3} {:>9.1}x  {diagnostics}",
            show(engine),
            show(spiff),
            ms / floor
        );
    }
}
