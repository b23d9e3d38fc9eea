//! The fleet's message path between two executives over Zenoh, beside raw Zenoh in the same
//! run on the same two sessions (peer to peer on loopback): one message flow from pool `A` to
//! pool `B` of a collaboration, each message the sender's engine step committed to its sled
//! store, the letter sent through the fleet link, the receiver's engine step committed to its
//! own store, and the verdict back (the sender's done mark then written, unflushed, as the
//! driver does). Baselines: a raw query answered at once, a raw put answered by a put
//! (subscriber to subscriber), and `fdatasync` of a small append in the stores' directory. Then
//! messages per second with 100 in flight.
//! `cargo bench -p executive-runtime --bench fleet` (`ROUNDS=n` to change the sample size).

use std::collections::BTreeMap;
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

use connector_api::wire::Letter;
use connector_api::{Keys, Report};
use connector_zenoh::Fleet;
use executive_engine::{Action, Engine, Event, Input, Vars};
use executive_store::{Recovered, SledStore, Store, StoreError};
use tokio::sync::mpsc::{UnboundedReceiver, unbounded_channel};
use zenoh::Wait;

/// The allocator the TRACE binaries run with (see the `trace` command's `main.rs`), so that the
/// bench measures what ships.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Pool `A` sends one message and ends; each message starts an instance of pool `B`'s process.
const MODEL: &str = r#"<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:bench">
  <message id="ping" name="ping"/>
  <collaboration id="c">
    <participant id="A" processRef="pa"/>
    <participant id="B" processRef="pb"/>
    <messageFlow id="mf" sourceRef="send" targetRef="hear"/>
  </collaboration>
  <process id="pa" isExecutable="true">
    <startEvent id="sa"/>
    <sequenceFlow id="fa1" sourceRef="sa" targetRef="send"/>
    <intermediateThrowEvent id="send"><messageEventDefinition messageRef="ping"/></intermediateThrowEvent>
    <sequenceFlow id="fa2" sourceRef="send" targetRef="ea"/>
    <endEvent id="ea"/>
  </process>
  <process id="pb" isExecutable="true">
    <startEvent id="hear"><messageEventDefinition messageRef="ping"/></startEvent>
    <sequenceFlow id="fb" sourceRef="hear" targetRef="eb"/>
    <endEvent id="eb"/>
  </process>
</definitions>"#;

#[path = "../../../connectors/zenoh/benches/loopback/mod.rs"]
mod loopback;
use loopback::{echo, pair, pct, raw_query};

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

/// One executive's side: its engine, its store and its next sequence number.
struct Side {
    engine: Engine,
    store: Box<dyn Store + Send>,
    seq: u64,
}

impl Side {
    /// On a sled store in `dir`, or, without one, on a store that keeps nothing.
    fn new(
        graph: &Arc<executive_model::ProcessGraph>,
        pool: &str,
        dir: Option<&std::path::Path>,
    ) -> Side {
        Side {
            engine: Engine::new(Arc::clone(graph))
                .participant(pool)
                .expect("pool"),
            store: match dir {
                Some(dir) => Box::new(SledStore::open(dir).expect("store")),
                None => Box::new(Discard),
            },
            seq: 0,
        }
    }

    /// Steps `events` and commits the steps together (one flush, as the driver commits
    /// whatever has arrived), returning each step's number and actions.
    fn step(&mut self, events: Vec<Event>) -> Vec<(u64, Vec<Action>)> {
        let mut steps = Vec::with_capacity(events.len());
        for event in events {
            self.seq += 1;
            let input = Input {
                seq: self.seq,
                at: self.seq as i64,
                event,
            };
            let actions = self.engine.step(input.clone()).expect("accepted");
            steps.push((input, actions));
        }
        self.store.commit_batch(&steps).expect("commit");
        steps
            .into_iter()
            .map(|(input, actions)| (input.seq, actions))
            .collect()
    }
}

/// The sender's steps: `n` new instances of `pa`, committed together, whose messages leave as
/// letters.
fn send_some(a: &mut Side, n: usize, fleet: &Fleet, unsent: &mut BTreeMap<String, (u64, u32)>) {
    let starts = (0..n)
        .map(|_| Event::InstanceStarted {
            process: "pa".into(),
            vars: Vars::new(),
            start: None,
        })
        .collect();
    for (seq, actions) in a.step(starts) {
        for (i, action) in actions.into_iter().enumerate() {
            if let Action::SendMessage(m) = action
                && let executive_engine::Outgoing {
                    name,
                    to: Some(to),
                    flow: Some(flow),
                    number: Some(number),
                    ..
                } = *m
            {
                let key = format!("bench.m{number}");
                unsent.insert(key.clone(), (seq, i as u32));
                fleet.send(Letter {
                    key,
                    from: "A".into(),
                    to,
                    flow,
                    name,
                    correlation: None,
                    payload: Default::default(),
                });
            } else {
                a.store.done(seq, i as u32).expect("done");
            }
        }
    }
}

/// The sender waits for a verdict, takes every other one already there, and marks their
/// messages done; returns how many.
async fn delivered(
    a: &mut Side,
    reports: &mut UnboundedReceiver<Report>,
    unsent: &mut BTreeMap<String, (u64, u32)>,
) -> usize {
    let mut n = 0;
    let mut next = reports.recv().await;
    while let Some(report) = next {
        if let Report::Delivered { key, refused } = report {
            assert!(refused.is_none(), "refused: {refused:?}");
            let (seq, index) = unsent.remove(&key).expect("a message sent");
            a.store.done(seq, index).expect("done");
            n += 1;
        }
        next = reports.try_recv().ok();
    }
    n
}

/// A store that keeps nothing: the message path with the commits' cost taken out.
struct Discard;

impl Store for Discard {
    fn commit_batch(&mut self, _: &[(Input, Vec<Action>)]) -> Result<(), StoreError> {
        Ok(())
    }
    fn done(&mut self, _: u64, _: u32) -> Result<(), StoreError> {
        Ok(())
    }
    fn snapshot(&mut self, _: u64, _: &executive_engine::State) -> Result<(), StoreError> {
        Ok(())
    }
    fn set_meta(&mut self, _: &str, _: &str) -> Result<(), StoreError> {
        Ok(())
    }
    fn flush(&mut self) -> Result<(), StoreError> {
        Ok(())
    }
    fn recover(&self) -> Result<Recovered, StoreError> {
        Ok(Recovered::default())
    }
}

/// Two executives joined on `root`: the sender's side, its fleet link and its reports; the
/// receiver runs in a task (each letter stepped, committed, then acknowledged).
struct Link {
    a: Side,
    fleet: Fleet,
    reports: UnboundedReceiver<Report>,
    unsent: BTreeMap<String, (u64, u32)>,
    other: Fleet,
    receiver: tokio::task::JoinHandle<()>,
}

impl Link {
    async fn join(
        (sa, sb): (&zenoh::Session, &zenoh::Session),
        root: &str,
        graph: &Arc<executive_model::ProcessGraph>,
        dir: Option<&std::path::Path>,
    ) -> Link {
        let keys = Keys::new(root).expect("root");
        let (tx_b, mut rx_b) = unbounded_channel();
        let other = Fleet::join(sb, keys.clone(), "B", tx_b)
            .await
            .expect("fleet B");
        let mut b = Side::new(graph, "B", dir.map(|d| d.join("b")).as_deref());
        let receiver = tokio::spawn(async move {
            // Every letter already there is stepped and committed together; then each is
            // acknowledged.
            while let Some(first) = rx_b.recv().await {
                let (mut events, mut verdicts) = (Vec::new(), Vec::new());
                let mut next = Some(first);
                while let Some(report) = next {
                    if let Report::Letter { letter, verdict } = report {
                        events.push(Event::MessageReceived {
                            name: letter.name,
                            correlation: None,
                            payload: Vars::new(),
                            flow: Some(letter.flow),
                            key: Some(letter.key),
                        });
                        verdicts.push(verdict);
                    }
                    next = rx_b.try_recv().ok();
                }
                for (_, actions) in b.step(events) {
                    assert!(!actions.is_empty(), "the message started an instance of pb");
                }
                for verdict in verdicts {
                    verdict.give(Ok(()));
                }
            }
        });
        let (tx_a, reports) = unbounded_channel();
        let fleet = Fleet::join(sa, keys, "A", tx_a).await.expect("fleet A");
        assert!(
            fleet
                .wait_for(&["B".to_owned()], Duration::from_secs(30))
                .await
                .is_empty(),
            "pool B's executive is seen"
        );
        Link {
            a: Side::new(graph, "A", dir.map(|d| d.join("a")).as_deref()),
            fleet,
            reports,
            unsent: BTreeMap::new(),
            other,
            receiver,
        }
    }

    fn send(&mut self, n: usize) {
        send_some(&mut self.a, n, &self.fleet, &mut self.unsent);
    }

    async fn delivered(&mut self) -> usize {
        delivered(&mut self.a, &mut self.reports, &mut self.unsent).await
    }

    /// One message, sent and acknowledged.
    async fn once(&mut self) {
        self.send(1);
        self.delivered().await;
    }

    async fn close(mut self) {
        self.fleet.close().await;
        self.other.close().await;
        self.receiver.abort();
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let rounds: usize = std::env::var("ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(2000);
    let dir = std::env::temp_dir().join(format!("trace-fleet-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("bench dir");
    let loaded = executive_model::load(MODEL.as_bytes());
    let graph = Arc::new(loaded.graph.expect("bench model"));

    let (sb, sa) = pair().await;
    let mut durable = Link::join((&sa, &sb), "bench", &graph, Some(&dir)).await;
    let mut memory = Link::join((&sa, &sb), "bench-mem", &graph, None).await;

    // Baselines on the same sessions: a raw query answered at once, and a put answered by a put.
    let _echo = echo(&sb).await;
    let pong_to = sb.clone();
    let _ping = sb
        .declare_subscriber("bench/raw/ping")
        .callback(move |s| {
            let _ = pong_to
                .put("bench/raw/pong", s.payload().to_bytes().into_owned())
                .wait();
        })
        .await
        .expect("ping subscriber");
    let pongs = sa
        .declare_subscriber("bench/raw/pong")
        .await
        .expect("pong subscriber");
    let raw_put = || async {
        sa.put("bench/raw/ping", br#"{"key":"bench.m1"}"#.to_vec())
            .await
            .expect("put");
        pongs.recv_async().await.expect("pong");
    };
    while !raw_query(&sa).await {} // wait for routing
    let mut probe = std::fs::File::create(dir.join("fsync-probe")).expect("probe file");
    let mut fsync = || {
        let t = Instant::now();
        probe.write_all(&[7u8; 128]).expect("write");
        probe.sync_data().expect("fdatasync");
        t.elapsed()
    };

    // Warm-up, then alternating blocks, so that every measurement sees the same machine load.
    for _ in 0..200 {
        raw_query(&sa).await;
        raw_put().await;
        durable.once().await;
        memory.once().await;
    }
    let (mut query, mut put, mut sync, mut path, mut link) = (
        Vec::with_capacity(rounds),
        Vec::with_capacity(rounds),
        Vec::with_capacity(rounds),
        Vec::with_capacity(rounds),
        Vec::with_capacity(rounds),
    );
    while path.len() < rounds {
        for _ in 0..100 {
            let t = Instant::now();
            raw_query(&sa).await;
            query.push(t.elapsed());
        }
        for _ in 0..100 {
            let t = Instant::now();
            raw_put().await;
            put.push(t.elapsed());
        }
        for _ in 0..100 {
            sync.push(fsync());
        }
        for _ in 0..100 {
            let t = Instant::now();
            durable.once().await;
            path.push(t.elapsed());
        }
        for _ in 0..100 {
            let t = Instant::now();
            memory.once().await;
            link.push(t.elapsed());
        }
    }
    for v in [&mut query, &mut put, &mut sync, &mut path, &mut link] {
        v.sort();
    }
    println!(
        "one message between two executives, {rounds} samples each, peer to peer on loopback, same run:"
    );
    let line = |what: &str, v: &[Duration]| {
        println!(
            "  {what:<34} p50 {:7.1} µs   p99 {:7.1} µs",
            us(pct(v, 0.5)),
            us(pct(v, 0.99))
        );
    };
    line("raw fdatasync (128 B append)", &sync);
    line("raw zenoh query", &query);
    line("raw zenoh put -> put back", &put);
    line("message: commit, send, commit, ack", &path);
    line("the same without a store", &link);
    let (p50, q50, f50) = (
        us(pct(&path, 0.5)),
        us(pct(&query, 0.5)),
        us(pct(&sync, 0.5)),
    );
    println!(
        "  ratio message/raw query       p50 {:.2}x   (goal: within 3x, both commits' flushes included)",
        p50 / q50
    );
    println!(
        "  beyond the query and two fdatasyncs: p50 {:.1} µs",
        p50 - q50 - 2.0 * f50
    );

    // Throughput: 100 messages in flight; as verdicts come, as many new messages leave, their
    // steps committed together.
    let total = rounds.max(2000);
    let t = Instant::now();
    durable.send(100);
    let (mut sent, mut done) = (100, 0);
    while done < total {
        let n = durable.delivered().await;
        done += n;
        let more = n.min(total - sent);
        if more > 0 {
            durable.send(more);
            sent += more;
        }
    }
    let secs = t.elapsed().as_secs_f64();
    println!(
        "messages per second with 100 in flight: {:.0} ({total} messages, each committed by both executives)",
        total as f64 / secs
    );
    durable.close().await;
    memory.close().await;
    let _ = std::fs::remove_dir_all(&dir);
}
