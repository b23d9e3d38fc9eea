//! The crash bench: Europa flown across processes on loopback with SIGKILLs of the executive
//! (at points chosen by record growth), the simulator mid-activity, a ground station with a
//! task open, and the executive and simulator together, each victim resumed on its store; per
//! kind: flights, kills, flights resumed to the uninterrupted outcome, stuck flights, goals
//! lost, effects applied twice; and the executive's restart: to its store recovered, and to the
//! first word from its systems. Run with `cargo bench -p mission-tests --bench crash`
//! (`TRACE_CRASH_FLIGHTS=N` flights of executive kills, 4 kills each, default 50; a quarter as
//! many for each other kind, 2 kills each).

use std::time::{Duration, Instant};

use mission_tests::matrix::{self, Flight, Tally, Victim};

fn main() {
    let flights: usize = std::env::var("TRACE_CRASH_FLIGHTS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(50);
    let root = std::env::temp_dir().join(format!("trace-crash-bench-{}", std::process::id()));
    let bound = Duration::from_secs(180);
    let t0 = Instant::now();
    // The uninterrupted flight of each seed is the reference its interrupted flights meet.
    let seeds = 4u64;
    let references: Vec<Flight> = (1..=seeds)
        .map(|seed| {
            let f = matrix::fly(
                &root.join(format!("ref-{seed}")),
                seed,
                Victim::Executive,
                0,
                bound,
            );
            println!(
                "reference flight, seed {seed}: {} with {} samples analysed",
                f.outcome.as_deref().unwrap_or("stuck"),
                f.analysed
            );
            f
        })
        .collect();
    let mut store_ms = Vec::new();
    let mut systems_ms = Vec::new();
    let mut rows = Vec::new();
    for victim in Victim::ALL {
        let (n, kills) = match victim {
            Victim::Executive => (flights, 4),
            _ => (flights.div_ceil(4), 2),
        };
        let mut tally = Tally::default();
        for i in 0..n {
            let seed = 1 + (i as u64 % seeds);
            let f = matrix::fly(
                &root.join(format!("{victim:?}-{i}")),
                seed,
                victim,
                kills,
                bound,
            );
            tally.add(&f, &references[(seed - 1) as usize]);
            store_ms.extend(&f.store_ms);
            systems_ms.extend(&f.systems_ms);
        }
        println!(
            "{:<28} flights {:>3}  kills {:>4}  same outcome {:>3}  stuck {}  goals lost {}  effects duplicated {}",
            victim.name(),
            tally.runs,
            tally.kills,
            tally.same,
            tally.stuck,
            tally.lost,
            tally.duplicated
        );
        rows.push((victim, tally));
    }
    let (s50, s99) = (
        matrix::quantile(&mut store_ms, 0.5),
        matrix::quantile(&mut store_ms, 0.99),
    );
    let (c50, c99) = (
        matrix::quantile(&mut systems_ms, 0.5),
        matrix::quantile(&mut systems_ms, 0.99),
    );
    println!(
        "executive restart ({} restarts): store recovered p50 {s50:.0} ms, p99 {s99:.0} ms; \
         systems back p50 {c50:.0} ms, p99 {c99:.0} ms ({:.1}× the store alone at p50)",
        store_ms.len(),
        c50 / s50.max(1e-9)
    );
    println!("total {:.0} s", t0.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&root);
}
