//! Round trip dispatch → result through the Zenoh connector and an action server answering at
//! once, beside a raw Zenoh query round trip measured in the same run on the same two
//! sessions (peer to peer on loopback); and goals per second with 100 goals in flight.
//! `cargo bench -p connector-zenoh --bench roundtrip` (`ROUNDS=n` to change the sample size).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use connector_api::{
    ActionSpec, Catalogue, Command, Connector, ConnectorConfig, Fields, Keys, Kind, Report,
};
use connector_zenoh::{ActionServer, ClientOptions, Request, ServerOptions, ZenohConnector};

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

mod loopback;
use loopback::{echo, pair, pct, raw_query};

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let rounds: usize = std::env::var("ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(3000);
    let (sys, exec) = pair().await;
    let keys = Keys::new("bench").expect("root");

    // Baseline: a raw queryable answering at once.
    let _raw = echo(&sys).await;
    let raw_once = || raw_query(&exec);
    while !raw_once().await {} // wait for routing
    // The action server: succeeds every goal at once.
    let catalogue = Catalogue {
        server: "sys".into(),
        actions: vec![ActionSpec {
            name: "noop".into(),
            description: String::new(),
            goal: BTreeMap::new(),
            result: BTreeMap::new(),
            feedback: BTreeMap::new(),
            errors: BTreeMap::new(),
            cost: None,
        }],
        ..Catalogue::default()
    };
    let (_server, mut requests) = ActionServer::start(
        &sys,
        ServerOptions {
            keys: keys.clone(),
            catalogue,
            store: None,
            accept: None,
            instance: None,
        },
    )
    .await
    .expect("server");
    tokio::spawn(async move {
        while let Some(r) = requests.recv().await {
            if let Request::Goal(h) = r {
                h.succeed(Fields::new()).await;
            }
        }
    });
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let mut c = ZenohConnector::new(
        &exec,
        ClientOptions {
            keys,
            config: ConnectorConfig {
                name: "sys".into(),
                kind: Kind::Zenoh,
                server: None,
                resources: vec!["*".into()],
                actions: BTreeMap::new(),
                data: vec![],
                deadband: BTreeMap::new(),
                grace_ms: 3000,
                clock: false,
                answers: false,
                limits: Default::default(),
                ros2: Default::default(),
            },
            client: "bench".into(),
            mission: "bench".into(),
            catalogue_wait: Duration::from_secs(30),
            query_timeout: Duration::from_secs(5),
        },
        tx,
    )
    .await
    .expect("connector");
    c.catalogue().await.expect("catalogue");
    let mut goal = 0u64;
    let mut command = || {
        goal += 1;
        Command {
            goal_id: format!("b.1.{goal}.1"),
            action: "noop".into(),
            fields: Fields::new(),
        }
    };
    let until_done = async |rx: &mut tokio::sync::mpsc::UnboundedReceiver<Report>| loop {
        if let Some(Report::Done { .. }) = rx.recv().await {
            return;
        }
    };
    // Warm-up, then interleave the two measurements so both see the same machine load.
    for _ in 0..200 {
        raw_once().await;
        c.execute(command());
        until_done(&mut rx).await;
    }
    // Alternating blocks: both see the same machine load over the run, and neither's
    // trailing traffic lands inside the other's samples (except at block edges).
    let (mut raw, mut proto) = (Vec::with_capacity(rounds), Vec::with_capacity(rounds));
    while raw.len() < rounds {
        for _ in 0..250 {
            let t = Instant::now();
            raw_once().await;
            raw.push(t.elapsed());
        }
        for _ in 0..250 {
            let t = Instant::now();
            c.execute(command());
            until_done(&mut rx).await;
            proto.push(t.elapsed());
        }
    }
    raw.sort();
    proto.sort();
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    println!("round trip, {rounds} samples each, peer to peer on loopback, same run:");
    println!(
        "  raw zenoh query      p50 {:7.1} µs   p99 {:7.1} µs",
        us(pct(&raw, 0.5)),
        us(pct(&raw, 0.99))
    );
    println!(
        "  goal -> result       p50 {:7.1} µs   p99 {:7.1} µs",
        us(pct(&proto, 0.5)),
        us(pct(&proto, 0.99))
    );
    println!(
        "  ratio (protocol/raw) p50 {:.2}x        p99 {:.2}x   (goal: within 1.5x)",
        us(pct(&proto, 0.5)) / us(pct(&raw, 0.5)),
        us(pct(&proto, 0.99)) / us(pct(&raw, 0.99))
    );
    // Throughput: keep 100 goals in flight.
    let total = rounds.max(1000);
    let t = Instant::now();
    let mut sent = 0;
    for _ in 0..100 {
        c.execute(command());
        sent += 1;
    }
    let mut done = 0;
    while done < total {
        until_done(&mut rx).await;
        done += 1;
        if sent < total {
            c.execute(command());
            sent += 1;
        }
    }
    let secs = t.elapsed().as_secs_f64();
    println!(
        "throughput, 100 goals in flight: {:.0} goals/s ({total} goals in {:.2} s)",
        total as f64 / secs,
        secs
    );
    c.close().await;
}
