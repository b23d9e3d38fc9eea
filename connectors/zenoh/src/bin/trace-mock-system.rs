//! `trace-mock-system`: serves a catalogue with scripted behaviour over the Zenoh activity
//! protocol (see `connector_zenoh::mock`), to try missions before the real system exists.

use std::path::PathBuf;

use clap::Parser;
use connector_zenoh::mock::{self, MockSpec};
use connector_zenoh::{ActionServer, Role, ServerOptions, ZenohArgs};

/// Serve a mock system's actions over Zenoh.
#[derive(Parser)]
#[command(name = "trace-mock-system", version = env!("TRACE_LONG_VERSION"), about)]
struct Cli {
    /// The definition: `{"catalogue": {...}, "behaviour": {"action": {...}}}` (JSON).
    spec: PathBuf,
    /// Keep the goal table here (sled) so a restarted system still knows its goals.
    #[arg(long)]
    store: Option<PathBuf>,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    connector_zenoh::log_to_stderr();
    let cli = Cli::parse();
    let text = std::fs::read_to_string(&cli.spec)
        .map_err(|e| anyhow::anyhow!("{}: {e}", cli.spec.display()))?;
    let spec: MockSpec =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", cli.spec.display()))?;
    let store = match &cli.store {
        Some(dir) => Some(sled::open(dir)?.open_tree("goals")?),
        None => None,
    };
    let session = cli.zenoh.open(Role::Spoke).await?;
    let (server, requests) = ActionServer::start(
        &session,
        ServerOptions {
            keys: cli.zenoh.keys()?,
            catalogue: spec.catalogue.clone(),
            store,
            accept: None,
            instance: None,
        },
    )
    .await?;
    let resume = server.unfinished();
    if let Some(clock) = spec.clock {
        tokio::spawn(mock::publish_clock(
            session.clone(),
            cli.zenoh.keys()?,
            spec.catalogue.server.clone(),
            clock,
        ));
    }
    println!("ready {}", spec.catalogue.server);
    tokio::select! {
        () = mock::run(spec, requests, resume) => {}
        _ = tokio::signal::ctrl_c() => {}
    }
    drop(server);
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
