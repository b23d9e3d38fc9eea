//! `ground-station`: answers a mission's user tasks — by policy, or by an operator at the
//! terminal (`--interactive`), or both (the policy answers what it has rules for).

use std::path::PathBuf;
use std::sync::Arc;

use clap::Parser;
use connector_zenoh::{Role, ZenohArgs};
use ground_station::policy::Policy;
use ground_station::station::{Station, say};
use ground_station::{forms, terminal};

/// The allocator every TRACE binary runs with (why: the `trace` command's `main.rs`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The forms the Europa mission uses, built in (`deploy/ground/forms.json`).
const DEFAULT_FORMS: &str = include_str!("../../deploy/ground/forms.json");

/// Answer a mission's user tasks over Zenoh.
#[derive(Parser)]
#[command(name = "ground-station", version = env!("TRACE_LONG_VERSION"), about)]
struct Cli {
    /// The forms served (a catalogue, JSON); default: the Europa mission's.
    #[arg(long)]
    forms: Option<PathBuf>,
    /// Answer by this policy (TOML) where it has a rule for the task type.
    #[arg(long)]
    policy: Option<PathBuf>,
    /// Take answers from the operator at this terminal.
    #[arg(long)]
    interactive: bool,
    /// Who answers at the terminal (recorded with every answer); default `$USER`.
    #[arg(long)]
    operator: Option<String>,
    /// This station's id (recorded with every answer); default `station-<pid>`.
    #[arg(long)]
    station: Option<String>,
    /// Keep the open tasks here (sled) across restarts of the station.
    #[arg(long)]
    store: Option<PathBuf>,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    connector_zenoh::log_to_stderr();
    let cli = Cli::parse();
    let forms = Arc::new(match &cli.forms {
        Some(path) => forms::load(path)?,
        None => serde_json::from_str(DEFAULT_FORMS)?,
    });
    let policy = match &cli.policy {
        Some(path) => Some(Arc::new(Policy::load(path, Arc::clone(&forms))?)),
        None => None,
    };
    if policy.is_none() && !cli.interactive {
        anyhow::bail!("nothing would answer: give --policy FILE, --interactive, or both");
    }
    let store = match &cli.store {
        Some(dir) => Some(sled::open(dir)?.open_tree("goals")?),
        None => None,
    };
    let id = cli
        .station
        .clone()
        .unwrap_or_else(|| format!("station-{}", std::process::id()));
    let keys = cli.zenoh.keys()?;
    let joined = format!("deployment {} (keys {}/…)", keys.deployment(), keys.root());
    let session = cli.zenoh.open(Role::Spoke).await?;
    let (station, requests) =
        Station::start(&session, keys, forms, id.clone(), store, policy).await?;
    // The startup line (`trace fly` waits for `ready`): who serves and where.
    say(&format!("ready ground {id} — {joined}"));
    let serving = tokio::spawn(Arc::clone(&station).serve(requests));
    if cli.interactive {
        let operator = cli
            .operator
            .or_else(|| std::env::var("USER").ok())
            .unwrap_or_else(|| "operator".to_owned());
        terminal::run(station, operator).await;
    } else {
        tokio::select! {
            _ = serving => {}
            _ = tokio::signal::ctrl_c() => {}
        }
    }
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
