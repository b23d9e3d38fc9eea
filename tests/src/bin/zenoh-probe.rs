//! `zenoh-probe`: one raw Zenoh operation under a chosen identity, for the tests across hosts
//! (tests/it/hosts.rs) — what an honest or a hostile process on the bus could try.
//!
//!   zenoh-probe [ZENOH FLAGS] sub KEY             subscribe; print `sample KEY PAYLOAD` per sample
//!   zenoh-probe [ZENOH FLAGS] put KEY PAYLOAD      put (Block), then stay up
//!   zenoh-probe [ZENOH FLAGS] get KEY [PAYLOAD]    query (3 s); print `reply …` per reply, `done`
//!   zenoh-probe [ZENOH FLAGS] queryable KEY        serve KEY; print `query KEY` per query
//!   zenoh-probe [ZENOH FLAGS] token KEY            declare a liveliness token, then stay up
//!   zenoh-probe [ZENOH FLAGS] alive KEY            liveliness subscriber with history; print
//!                                                  `alive KEY` / `gone KEY`
//!   zenoh-probe [ZENOH FLAGS] undeclare KEY        declare a liveliness token and a queryable
//!                                                  on KEY, undeclare both; print `undeclared`,
//!                                                  then stay up
//!   zenoh-probe [ZENOH FLAGS] flood KEY COUNT      COUNT puts (Drop) paced over 20 s, then,
//!                                                  half a second later, an `end` put (Block);
//!                                                  print `flooded COUNT`, then stay up
//!   zenoh-probe [ZENOH FLAGS] count KEY            subscribe; at the `end` put, print
//!                                                  `counted N`: the samples before it
//!
//! Every operation prints `ready` once its session is open and its declaration or send made;
//! a session that cannot open prints `error: …` and exits 1.

use std::io::Write;
use std::time::Duration;

use clap::Parser;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;

/// Longer than the period of any rate limit a test's router applies (20 puts a second: 50 ms),
/// with room for the limiter's own clock.
const LIMITER_WINDOW: Duration = Duration::from_millis(500);

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    zenoh: connector_zenoh::ZenohArgs,
    /// sub, put, get, queryable, token, alive, undeclare, flood or count.
    op: String,
    /// The key expression.
    key: String,
    /// The payload of put and get; flood's count.
    payload: Option<String>,
}

fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

#[tokio::main(flavor = "multi_thread", worker_threads = 1)]
async fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match probe(&cli).await {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            say(&format!("error: {e}"));
            std::process::ExitCode::FAILURE
        }
    }
}

async fn probe(cli: &Cli) -> Result<(), zenoh::Error> {
    let session = cli.zenoh.open(connector_zenoh::Role::Spoke).await?;
    let key = cli.key.as_str();
    let payload = cli.payload.clone().unwrap_or_default();
    let text = |s: &zenoh::bytes::ZBytes| String::from_utf8_lossy(&s.to_bytes()).into_owned();
    match cli.op.as_str() {
        "sub" => {
            let sub = session.declare_subscriber(key).await?;
            say("ready");
            while let Ok(s) = sub.recv_async().await {
                say(&format!("sample {} {}", s.key_expr(), text(s.payload())));
            }
        }
        "put" => {
            session
                .put(key, payload)
                .congestion_control(CongestionControl::Block)
                .await?;
            say("ready");
            std::future::pending::<()>().await;
        }
        "get" => {
            let replies = session
                .get(key)
                .payload(payload)
                .timeout(Duration::from_secs(3))
                .await?;
            say("ready");
            while let Ok(r) = replies.recv_async().await {
                match r.result() {
                    Ok(s) => say(&format!("reply ok {} {}", s.key_expr(), text(s.payload()))),
                    Err(e) => say(&format!("reply err {}", text(e.payload()))),
                }
            }
            say("done");
        }
        "queryable" => {
            let q = session.declare_queryable(key).await?;
            say("ready");
            while let Ok(query) = q.recv_async().await {
                say(&format!("query {}", query.key_expr()));
                let _ = query.reply(query.key_expr().clone(), "probe").await;
            }
        }
        "token" => {
            let _token = session.liveliness().declare_token(key).await?;
            say("ready");
            std::future::pending::<()>().await;
        }
        "alive" => {
            let sub = session
                .liveliness()
                .declare_subscriber(key)
                .history(true)
                .await?;
            say("ready");
            while let Ok(s) = sub.recv_async().await {
                let what = if s.kind() == SampleKind::Put {
                    "alive"
                } else {
                    "gone"
                };
                say(&format!("{what} {}", s.key_expr()));
            }
        }
        "undeclare" => {
            let token = session.liveliness().declare_token(key).await?;
            let queryable = session.declare_queryable(key).await?;
            say("ready");
            token.undeclare().await?;
            queryable.undeclare().await?;
            say("undeclared");
            std::future::pending::<()>().await;
        }
        "flood" => {
            let count: u64 = payload
                .parse()
                .map_err(|_| format!("flood: COUNT `{payload}` is not a number"))?;
            let publisher = session
                .declare_publisher(key)
                .congestion_control(CongestionControl::Drop)
                .await?;
            say("ready");
            let start = tokio::time::Instant::now();
            let over = Duration::from_secs(20);
            for i in 0..count {
                publisher.put(format!("{{\"flood\": {i}}}")).await?;
                // Paced: a load generator's rate, not a wait for anything.
                if i % 100 == 99 {
                    let due = start + over.mul_f64((i + 1) as f64 / count as f64);
                    tokio::time::sleep_until(due).await;
                }
            }
            // The end mark must pass a router that lets a few puts a second through
            // (`ground-router.json5`, 20 a second per key): it goes a window of the limiter
            // after the last flood put. Nothing comes back to wait for; the window is the event.
            tokio::time::sleep(LIMITER_WINDOW).await;
            session
                .put(key, "{\"flood\": \"end\"}")
                .congestion_control(CongestionControl::Block)
                .await?;
            say(&format!("flooded {count}"));
            std::future::pending::<()>().await;
        }
        "count" => {
            let sub = session.declare_subscriber(key).await?;
            say("ready");
            let mut n = 0u64;
            while let Ok(s) = sub.recv_async().await {
                if text(s.payload()).contains("\"end\"") {
                    say(&format!("counted {n}"));
                } else {
                    n += 1;
                }
            }
        }
        other => return Err(format!("unknown operation {other}").into()),
    }
    Ok(())
}
