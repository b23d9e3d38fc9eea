//! The crash bench: Europa flown across processes — on loopback, then on two hosts through
//! their routers — with SIGKILLs of the executive (at points chosen by record growth), the
//! simulator mid-activity, a ground station with a task open, the executive and simulator
//! together, and (on two hosts) the lander's or the ground's router, each victim resumed. Per
//! kind: flights, kills, flights resumed to the uninterrupted outcome (samples analysed
//! included) and to its end (the same outcome type), stuck flights, goals lost, effects applied
//! twice; and the executive's restart: to its store recovered, and to the first word from its
//! systems. Run with `cargo bench -p mission-tests --bench crash` (`TRACE_CRASH_FLIGHTS=N`
//! flights of executive kills on loopback, 4 kills each, default 50;
//! `TRACE_CRASH_HOSTS_FLIGHTS=N` on two hosts, default a quarter of that; a quarter as many
//! for each other kind, 2 kills each). Then the fleet: the two-vehicle mission with its lander
//! executive, scout executive or scout simulator killed mid-exchange
//! (`TRACE_CRASH_FLEET_FLIGHTS=N` flights per kind, default 10, two kills each).

use std::path::Path;
use std::time::{Duration, Instant};

use mission_tests::matrix::{self, Flight, Layout, Tally, Victim};

fn main() {
    let flights: usize = std::env::var("TRACE_CRASH_FLIGHTS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(50);
    let hosts_flights: usize = std::env::var("TRACE_CRASH_HOSTS_FLIGHTS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(flights.div_ceil(4));
    let root = std::env::temp_dir().join(format!("trace-crash-bench-{}", std::process::id()));
    let bound = Duration::from_secs(180);
    // The binaries are built (if stale) before any flight's bound starts counting.
    mission_tests::bin("trace");
    let t0 = Instant::now();
    for (layout, kinds, flights) in [
        (Layout::Loopback, &Victim::ALL[..], flights),
        (Layout::Hosts, &Victim::ACROSS_HOSTS[..], hosts_flights),
    ] {
        if flights > 0 {
            println!("== {layout:?}");
            bench(
                &root.join(format!("{layout:?}")),
                layout,
                kinds,
                flights,
                bound,
            );
        }
    }
    // The fleet: `TRACE_CRASH_FLEET_FLIGHTS=N` flights per kind (default 10), a kill in each of
    // two of its three exchanges.
    let fleet_flights: usize = std::env::var("TRACE_CRASH_FLEET_FLIGHTS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(10);
    if fleet_flights > 0 {
        println!("== Fleet (two executives, loopback)");
        fleet(&root.join("fleet"), fleet_flights, bound);
    }
    println!(
        "total {:.0} s; flights under {}",
        t0.elapsed().as_secs_f64(),
        root.display()
    );
}

/// The fleet's kinds: `flights` each, two kills mid-exchange per flight; one row per kind.
fn fleet(root: &Path, flights: usize, bound: Duration) {
    use mission_tests::fleet_matrix::{self, Victim};
    for victim in Victim::ALL {
        let (mut kills, mut exact, mut ended, mut lost, mut twice, mut refused) =
            (0, 0, 0, 0, 0, 0);
        for i in 0..flights {
            let dir = root.join(format!("{victim:?}-{i}"));
            let f = fleet_matrix::fly(&dir, 1 + i as u64, victim, 2, bound);
            kills += f.kills;
            exact += usize::from(f.exact());
            ended += usize::from(f.ended);
            // A message applied less often than it was delivered is lost; more, twice.
            lost +=
                f.requests.saturating_sub(f.surveys) + f.reports.saturating_sub(f.heard) + f.lost;
            twice += f.surveys.saturating_sub(f.requests) + f.heard.saturating_sub(f.reports);
            refused += f.refused;
            if f.exact() {
                let _ = std::fs::remove_dir_all(&dir);
            } else {
                println!("  kept {} for a look: {f:?}", dir.display());
            }
        }
        println!(
            "{:<32} flights {flights:>3}  kills {kills:>4}  exactly once {exact:>3}  ended {ended:>3}  \
             lost {lost}  applied twice {twice}  refused {refused}",
            victim.name()
        );
    }
}

/// The flights of one layout: `flights` with executive kills, a quarter as many of each other
/// kind; prints one row per kind and the executive's restart times.
fn bench(root: &Path, layout: Layout, kinds: &[Victim], flights: usize, bound: Duration) {
    // The uninterrupted flight of each seed is the reference its interrupted flights meet.
    let seeds = 4u64;
    let references: Vec<Flight> = (1..=seeds)
        .map(|seed| {
            let f = matrix::fly(
                &root.join(format!("ref-{seed}")),
                layout,
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
    // `TRACE_CRASH_KINDS=Simulator,LanderRouter`: only those kinds (names as in the enum).
    let only = std::env::var("TRACE_CRASH_KINDS").ok();
    for &victim in kinds {
        if only
            .as_deref()
            .is_some_and(|o| !o.split(',').any(|k| k == format!("{victim:?}")))
        {
            continue;
        }
        let (n, kills) = match victim {
            Victim::Executive => (flights, 4),
            _ => (flights.div_ceil(4), 2),
        };
        let mut tally = Tally::default();
        for i in 0..n {
            let seed = 1 + (i as u64 % seeds);
            let f = matrix::fly(
                &root.join(format!("{victim:?}-{i}")),
                layout,
                seed,
                victim,
                kills,
                bound,
            );
            tally.add(&f, &references[(seed - 1) as usize]);
            // A flight that went wrong keeps its directory (record, stores, logs) for a look.
            let dir = root.join(format!("{victim:?}-{i}"));
            if f.outcome.is_none() || f.lost > 0 || f.duplicated > 0 {
                println!("  kept {} for a look: {f:?}", dir.display());
            } else {
                let _ = std::fs::remove_dir_all(&dir);
            }
            store_ms.extend(&f.store_ms);
            systems_ms.extend(&f.systems_ms);
        }
        println!(
            "{:<28} flights {:>3}  kills {:>4}  same outcome {:>3}  same end {:>3}  stuck {}  goals lost {}  effects duplicated {}",
            victim.name(),
            tally.runs,
            tally.kills,
            tally.same,
            tally.ended,
            tally.stuck,
            tally.lost,
            tally.duplicated
        );
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
}
