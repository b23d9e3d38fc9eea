//! `elap-sim`: the lander simulator process. Serves every activity of the catalogue over the
//! Zenoh activity protocol, runs the mission clock at `--speed`, publishes telemetry, and keeps
//! its world and goal table in sled so a restarted simulator carries on where it was.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use connector_api::wire::Telemetry;
use connector_zenoh::{ActionServer, GoalHandle, Request, Role, ServerOptions, ZenohArgs};
use elap_sim::catalogue::{SERVER, catalogue};
use elap_sim::{Profile, Script, Sim, World};
use serde_json::json;
use tokio::sync::watch;

/// The ELAP lander simulator.
#[derive(Parser)]
#[command(name = "elap-sim", version, about)]
struct Cli {
    /// Fault generator seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fault profile.
    #[arg(long, value_enum, default_value = "nominal")]
    profile: Profile,
    /// Scripted faults (JSON: {"faults": [{"action", "call", "code", "draw_w"}]}).
    #[arg(long)]
    faults: Option<PathBuf>,
    /// Mission time runs this many times faster than wall time.
    #[arg(long, default_value_t = 3600.0)]
    speed: f64,
    /// Where the world and the goal table are kept (default: a fresh temporary world).
    #[arg(long)]
    store: Option<PathBuf>,
    /// Landing time, ms since the epoch (default: now).
    #[arg(long)]
    start_ms: Option<i64>,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

/// The mission clock: held at the landing time until the first goal arrives (the lander does
/// not age while the executive starts), then running `speed` times faster than wall time.
struct Clock {
    base_ms: i64,
    at: std::sync::OnceLock<Instant>,
    speed: f64,
}

impl Clock {
    fn now(&self) -> i64 {
        match self.at.get() {
            Some(at) => self.base_ms + (at.elapsed().as_secs_f64() * 1000.0 * self.speed) as i64,
            None => self.base_ms,
        }
    }
    /// Starts the clock (first goal); later calls do nothing.
    fn run(&self) {
        let _ = self.at.set(Instant::now());
    }
    /// The speed telemetry reports: 0 while held.
    fn rate(&self) -> f64 {
        if self.at.get().is_some() {
            self.speed
        } else {
            0.0
        }
    }
    fn wall(&self, mission_ms: i64) -> Duration {
        Duration::from_secs_f64((mission_ms.max(0) as f64 / 1000.0 / self.speed).min(1e6))
    }
}

struct Shared {
    sim: Mutex<Sim>,
    clock: Clock,
    tree: Option<sled::Tree>,
}

impl Shared {
    fn save(&self, sim: &Sim) {
        if let Some(t) = &self.tree {
            let done = serde_json::to_vec(sim)
                .map_err(|e| e.to_string())
                .and_then(|b| t.insert("sim", b).map_err(|e| e.to_string()))
                .and_then(|_| t.flush().map_err(|e| e.to_string()));
            if let Err(e) = done {
                tracing::error!(error = %e, "world not saved");
            }
        }
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    connector_zenoh::log_to_stderr();
    let cli = Cli::parse();
    anyhow::ensure!(
        cli.speed.is_finite() && cli.speed > 0.0,
        "--speed must be positive"
    );
    let script: Script = match &cli.faults {
        Some(p) => serde_json::from_str(&std::fs::read_to_string(p)?)
            .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?,
        None => Script::default(),
    };
    let db = match &cli.store {
        Some(dir) => Some(sled::open(dir).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?),
        None => None,
    };
    let tree = db.as_ref().map(|d| d.open_tree("world")).transpose()?;
    let goals = db.as_ref().map(|d| d.open_tree("goals")).transpose()?;
    let saved = match tree.as_ref().and_then(|t| t.get("sim").ok().flatten()) {
        Some(b) => Some(
            serde_json::from_slice::<Sim>(&b)
                .map_err(|e| anyhow::anyhow!("the saved world is damaged: {e}"))?,
        ),
        None => None,
    };
    let sim = match saved {
        Some(s) => s.with(cli.profile, script),
        None => {
            let start = cli.start_ms.unwrap_or_else(|| {
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_millis() as i64)
            });
            Sim::new(World::new(start, cli.seed), cli.profile, script)
        }
    };
    let clock = Clock {
        base_ms: sim.world.now_ms,
        at: std::sync::OnceLock::new(),
        speed: cli.speed,
    };
    let shared = Arc::new(Shared {
        sim: Mutex::new(sim),
        clock,
        tree,
    });
    let session = cli.zenoh.open(Role::Spoke).await?;
    let keys = cli.zenoh.keys()?;
    let joined = format!("deployment {} (keys {}/…)", keys.deployment(), keys.root());
    let _alive = session
        .liveliness()
        .declare_token(keys.alive("lander_sim", &format!("sim-{}", std::process::id())))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    tokio::spawn(telemetry(
        session.clone(),
        keys.clone(),
        Arc::clone(&shared),
    ));
    let (server, mut requests) = ActionServer::start(
        &session,
        ServerOptions {
            keys,
            catalogue: catalogue(),
            store: goals,
            accept: None,
            instance: None,
        },
    )
    .await?;
    let cancels: Arc<Mutex<std::collections::HashMap<String, watch::Sender<bool>>>> =
        Arc::default();
    let start = |h: GoalHandle| {
        let (tx, rx) = watch::channel(false);
        cancels
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(h.goal_id.clone(), tx);
        tokio::spawn(activity(h, Arc::clone(&shared), rx));
    };
    // Goals that were running when the simulator stopped start over.
    for h in server.unfinished() {
        start(h);
    }
    // The startup line (`trace fly` waits for `ready`): what is served and where.
    println!("ready {SERVER} — {joined}");
    loop {
        tokio::select! {
            r = requests.recv() => match r {
                Some(Request::Goal(h)) => start(h),
                Some(Request::Cancel(h, _)) => {
                    if let Some(tx) = cancels.lock().unwrap_or_else(|p| p.into_inner()).remove(&h.goal_id) {
                        let _ = tx.send(true);
                    }
                }
                None => break,
            },
            _ = tokio::signal::ctrl_c() => break,
        }
    }
    let sim = shared.sim.lock().unwrap_or_else(|p| p.into_inner()).clone();
    shared.save(&sim);
    drop(server);
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// Runs one activity: plan at the start, wait its duration on the mission clock (feedback on
/// the way, cancel honoured), then apply it and report.
async fn activity(h: GoalHandle, shared: Arc<Shared>, mut cancel: watch::Receiver<bool>) {
    shared.clock.run();
    let plan = {
        let mut sim = shared.sim.lock().unwrap_or_else(|p| p.into_inner());
        sim.world.advance(shared.clock.now());
        sim.plan(&h.action, &h.fields)
    };
    let plan = match plan {
        Ok(p) => p,
        Err(e) => {
            h.abort("REJECTED", &e.to_string()).await;
            return;
        }
    };
    h.executing().await;
    let started = shared.clock.now();
    let steps = 4;
    let mut cancelled = false;
    for k in 1..=steps {
        let wait = shared.clock.wall(plan.duration_ms / steps);
        tokio::select! {
            () = tokio::time::sleep(wait) => {}
            r = cancel.wait_for(|c| *c) => { cancelled = r.is_ok(); }
        }
        if cancelled {
            break;
        }
        if k < steps {
            h.feedback(Some(100.0 * k as f64 / steps as f64), Default::default())
                .await;
        }
    }
    let now = shared.clock.now();
    let fraction = if cancelled {
        ((now - started) as f64 / plan.duration_ms.max(1) as f64).min(0.99)
    } else {
        1.0
    };
    let (outcome, sim) = {
        let mut sim = shared.sim.lock().unwrap_or_else(|p| p.into_inner());
        let o = sim.finish(
            &plan,
            fraction,
            now.max(started + (plan.duration_ms as f64 * fraction) as i64),
        );
        (o, sim.clone())
    };
    shared.save(&sim);
    match (cancelled, outcome) {
        (true, Ok(partial)) => {
            h.canceled(partial).await;
        }
        (true, Err(_)) => {
            h.canceled(Default::default()).await;
        }
        (false, Ok(outputs)) => {
            h.succeed(outputs).await;
        }
        (false, Err((code, message))) => {
            tracing::info!(action = h.action, code, message, "activity failed");
            h.abort(&code, &message).await;
        }
    }
}

/// Publishes the clock, power, thermal and comm telemetry every 100 ms of wall time.
async fn telemetry(session: zenoh::Session, keys: connector_api::Keys, shared: Arc<Shared>) {
    let mut n: u64 = 0;
    loop {
        let now = shared.clock.now();
        let (values, sim) = {
            let mut sim = shared.sim.lock().unwrap_or_else(|p| p.into_inner());
            sim.world.advance(now);
            let w = &sim.world;
            (
                [
                    ("clock", json!({"speed": shared.clock.rate()})),
                    (
                        "power",
                        json!({"battery_soc_pct": w.soc_pct(), "battery_energy_wh": w.energy_wh}),
                    ),
                    ("thermal", json!({"arm_temp_c": w.arm_temp_k - 273.15})),
                    ("comm", json!({"comm_window_open": w.window_open(now)})),
                ],
                n.is_multiple_of(10).then(|| sim.clone()),
            )
        };
        if let Some(sim) = sim {
            shared.save(&sim);
        }
        for (channel, v) in values {
            let t = Telemetry {
                mission_ms: now,
                values: v.as_object().cloned().unwrap_or_default(),
            };
            let body = serde_json::to_vec(&t).unwrap_or_default();
            if session
                .put(keys.telemetry(SERVER, channel), body)
                .await
                .is_err()
            {
                return;
            }
        }
        n += 1;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}
