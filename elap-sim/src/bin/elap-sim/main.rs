//! `elap-sim`: the lander simulator process. Serves every activity of the catalogue over the
//! Zenoh activity protocol, runs the mission clock at `--speed`, publishes telemetry, and keeps
//! its world and goal table in sled so a restarted simulator carries on where it was: the
//! mission clock runs on through the downtime (the lander does not stop ageing while its
//! software restarts), activities under way continue with the plan they had, and an activity's
//! effects are saved with the fact that it ended, keyed by its goal, so they apply once.
//!
//! With `--ros2 CONNECTORS`, the activities that file's ROS 2 connectors route are served as
//! ROS 2 actions instead (`connector_ros2::Ros2Server`), from the same world. Their goals are
//! not kept across a restart: ROS 2's action servers hold goals in memory only.

mod goal;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use connector_api::Status;
use connector_api::wire::Telemetry;
use connector_zenoh::{ActionServer, Request, Role, ServerOptions, ZenohArgs};
use elap_sim::catalogue;
use elap_sim::{Ended, Profile, Script, Sim, Vehicle, World};
use goal::Goal;
use serde::{Deserialize, Serialize};
use serde_json::json;
use tokio::sync::watch;

/// The allocator every TRACE binary runs with (why: the `trace` command's `main.rs`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The ELAP lander simulator.
#[derive(Parser)]
#[command(name = "elap-sim", version = env!("TRACE_LONG_VERSION"), about)]
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
    /// Print the catalogue the simulator serves (JSON, `docs/protocol.md` §3) and exit: what
    /// `deploy/catalogues/<server>.json` holds for tools that work without a running system.
    #[arg(long)]
    print_catalogue: bool,
    /// Which vehicle to simulate: the lander (server `lander_sim`), or the scout that surveys
    /// sites for it (server `scout_sim`). A restarted simulator keeps the vehicle it was.
    #[arg(long, value_enum, default_value = "lander")]
    vehicle: Vehicle,
    /// Take the mission clock of another simulator of the same deployment (its server id,
    /// e.g. `lander_sim`): this one's clock starts when that one's runs, at its mission time,
    /// so the vehicles of a fleet share one mission time. Without it (or before that clock is
    /// heard), the first goal starts the clock.
    #[arg(long, value_name = "SERVER")]
    clock_of: Option<String>,
    /// Serve as ROS 2 actions, not over Zenoh, the activities this connectors file routes to
    /// ROS 2 (its `kind = "ros2"` connectors: each resource's action name and type, and how to
    /// join the ROS graph). `[connector.ros2] python` must have rclpy and the actions' package
    /// (`deploy/ros2`).
    #[arg(long, value_name = "CONNECTORS")]
    ros2: Option<PathBuf>,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

/// The mission clock: held at the landing time until the first goal arrives (the lander does
/// not age while the executive starts), then running `speed` times faster than wall time.
struct Clock {
    base_ms: std::sync::atomic::AtomicI64,
    at: std::sync::OnceLock<Instant>,
    speed: f64,
}

/// Where the running clock stood against the wall clock, saved when it starts so a restarted
/// simulator's clock goes on from where the downtime has taken it, not from its last save.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct Anchor {
    /// Mission time at `wall_ms`.
    mission_ms: i64,
    /// Wall time, ms since the epoch.
    wall_ms: i64,
    /// Mission ms per wall ms since then.
    speed: f64,
}

fn wall_now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

impl Clock {
    fn now(&self) -> i64 {
        match self.at.get() {
            Some(at) => self.base() + (at.elapsed().as_secs_f64() * 1000.0 * self.speed) as i64,
            None => self.base(),
        }
    }
    fn base(&self) -> i64 {
        self.base_ms.load(std::sync::atomic::Ordering::SeqCst)
    }
    /// Starts the clock; `true` the first time (later calls do nothing).
    fn run(&self) -> bool {
        self.at.set(Instant::now()).is_ok()
    }
    /// Starts the held clock at `mission_ms` (another vehicle's time); `false` if it runs.
    fn run_at(&self, mission_ms: i64) -> bool {
        if self.at.get().is_some() {
            return false;
        }
        self.base_ms.store(
            mission_ms.max(self.base()),
            std::sync::atomic::Ordering::SeqCst,
        );
        self.run()
    }
    /// The anchor of the running clock, now.
    fn anchor(&self) -> Anchor {
        Anchor {
            mission_ms: self.now(),
            wall_ms: wall_now_ms(),
            speed: self.speed,
        }
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
    /// Saves the simulator (world, activities under way and ended) durably, under its lock:
    /// saves never overtake one another, so an older copy cannot overwrite a newer one.
    fn save(&self) {
        let sim = self.sim();
        self.put("sim", &*sim);
    }

    fn put(&self, key: &str, value: &impl Serialize) {
        if let Some(t) = &self.tree {
            let done = serde_json::to_vec(value)
                .map_err(|e| e.to_string())
                .and_then(|b| t.insert(key, b).map_err(|e| e.to_string()))
                .and_then(|_| t.flush().map_err(|e| e.to_string()));
            if let Err(e) = done {
                tracing::error!(error = %e, key, "simulator state not saved");
            }
        }
    }

    /// Starts the mission clock at the first goal, saving where it stands.
    fn run_clock(&self) {
        if self.clock.run() {
            self.put("clock", &self.clock.anchor());
        }
    }

    /// Another vehicle's clock reading: a held clock that follows it starts at its time.
    fn follow(&self, reading: &Telemetry) {
        let running = reading
            .values
            .get("speed")
            .and_then(serde_json::Value::as_f64)
            .is_some_and(|s| s > 0.0);
        if running && self.clock.run_at(reading.mission_ms) {
            tracing::info!(
                mission_ms = reading.mission_ms,
                "mission clock taken from the fleet"
            );
            self.put("clock", &self.clock.anchor());
        }
    }

    fn sim(&self) -> std::sync::MutexGuard<'_, Sim> {
        self.sim.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// The value saved under `key` in the simulator's `world` tree, if one was saved; `what` names
/// it when it is damaged.
fn saved<T: serde::de::DeserializeOwned>(
    tree: Option<&sled::Tree>,
    key: &str,
    what: &str,
) -> anyhow::Result<Option<T>> {
    match tree.and_then(|t| t.get(key).ok().flatten()) {
        Some(b) => serde_json::from_slice(&b)
            .map(Some)
            .map_err(|e| anyhow::anyhow!("the saved {what} is damaged: {e}")),
        None => Ok(None),
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    connector_zenoh::log_to_stderr();
    let cli = Cli::parse();
    if cli.print_catalogue {
        println!(
            "{}",
            serde_json::to_string_pretty(&catalogue::of(cli.vehicle))?
        );
        return Ok(());
    }
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
    let sim = match saved::<Sim>(tree.as_ref(), "sim", "world")? {
        Some(s) => s.with(cli.profile, script),
        None => {
            let start = cli.start_ms.unwrap_or_else(|| {
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_millis() as i64)
            });
            Sim::new(World::of(cli.vehicle, start, cli.seed), cli.profile, script)
        }
    };
    // A clock that was running before a restart ran on through the downtime.
    let anchor = saved::<Anchor>(tree.as_ref(), "clock", "clock")?;
    // A saved world is the vehicle it was.
    let vehicle = sim.world.vehicle;
    if vehicle != cli.vehicle {
        tracing::warn!(saved = %vehicle, given = %cli.vehicle, "the store holds another vehicle; simulating the saved one");
    }
    let served = vehicle.server();
    let ros2 = cli.ros2.as_deref().map(goal::ros2_routes).transpose()?;
    let mut zenoh_catalogue = catalogue::of(vehicle);
    if let Some(routes) = &ros2 {
        for resource in routes.iter().flat_map(|(_, _, a)| a.keys()) {
            anyhow::ensure!(
                zenoh_catalogue.actions.iter().any(|a| &a.name == resource),
                "`{resource}` is routed to ROS 2, but the {vehicle} has no such activity"
            );
        }
        zenoh_catalogue
            .actions
            .retain(|a| !routes.iter().any(|(_, _, r)| r.contains_key(&a.name)));
    }
    let base_ms = match anchor {
        Some(a) => {
            let downtime = (wall_now_ms() - a.wall_ms).max(0) as f64 * a.speed;
            (a.mission_ms + downtime as i64).max(sim.world.now_ms)
        }
        None => sim.world.now_ms,
    };
    let clock = Clock {
        base_ms: std::sync::atomic::AtomicI64::new(base_ms),
        at: std::sync::OnceLock::new(),
        speed: cli.speed,
    };
    let shared = Arc::new(Shared {
        sim: Mutex::new(sim),
        clock,
        tree,
    });
    if anchor.is_some() {
        shared.run_clock();
    }
    let session = cli.zenoh.open(Role::Spoke).await?;
    let keys = cli.zenoh.keys()?;
    let joined = format!("deployment {} (keys {}/…)", keys.deployment(), keys.root());
    let _alive = session
        .liveliness()
        .declare_token(keys.alive(served, &format!("sim-{}", std::process::id())))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    tokio::spawn(telemetry(
        session.clone(),
        keys.clone(),
        Arc::clone(&shared),
    ));
    // A fleet's vehicles share the mission time of the one named.
    let _follow = match (&cli.clock_of, anchor) {
        (Some(server), None) => {
            let me = Arc::clone(&shared);
            Some(
                session
                    .declare_subscriber(keys.telemetry(server, "clock"))
                    .callback(move |s| {
                        match serde_json::from_slice::<Telemetry>(&s.payload().to_bytes()) {
                            Ok(t) => me.follow(&t),
                            Err(e) => tracing::warn!(error = %e, "unreadable clock reading"),
                        }
                    })
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?,
            )
        }
        _ => None,
    };
    let (server, mut requests) = ActionServer::start(
        &session,
        ServerOptions {
            keys,
            catalogue: zenoh_catalogue,
            store: goals,
            accept: None,
            instance: None,
        },
    )
    .await?;
    let cancels: Arc<Mutex<std::collections::HashMap<String, watch::Sender<bool>>>> =
        Arc::default();
    let start = |h: Goal| {
        let (tx, rx) = watch::channel(false);
        cancels
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(h.id(), tx);
        tokio::spawn(activity(h, Arc::clone(&shared), rx));
    };
    let cancel = |id: &str| {
        if let Some(tx) = cancels.lock().unwrap_or_else(|p| p.into_inner()).remove(id) {
            let _ = tx.send(true);
        }
    };
    // The ROS 2 nodes, one per connector, their requests merged into one stream.
    let (ros2_tx, mut ros2_requests) = tokio::sync::mpsc::unbounded_channel();
    let mut _nodes = Vec::new();
    for (name, settings, actions) in ros2.iter().flatten() {
        let (node, mut rx) = tokio::task::block_in_place(|| {
            connector_ros2::Ros2Server::start(&format!("{served}_{name}"), settings, actions)
        })?;
        _nodes.push(node);
        let tx = ros2_tx.clone();
        tokio::spawn(async move {
            while let Some(r) = rx.recv().await {
                if tx.send(r).is_err() {
                    return;
                }
            }
        });
        println!(
            "serving {} over ROS 2 ({name})",
            actions.keys().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    drop(ros2_tx);
    let mut asked: std::collections::HashMap<String, Arc<std::sync::atomic::AtomicBool>> =
        std::collections::HashMap::new();
    // Outcomes kept for goals whose results were recorded before the restart are dropped;
    // goals under way when the simulator stopped carry on (or, ended but unrecorded, report).
    {
        let mut sim = shared.sim();
        let recorded: Vec<String> = sim
            .ended
            .keys()
            .filter(|g| server.status(g).is_none_or(Status::is_terminal))
            .cloned()
            .collect();
        for g in &recorded {
            sim.forget(g);
        }
    }
    for h in server.unfinished() {
        start(Goal::Zenoh(h));
    }
    // Watched from before `ready` on, so a Ctrl-C between two requests is never missed.
    let mut interrupt = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())?;
    // The startup line (`trace fly` waits for `ready`): what is served and where.
    println!("ready {served} — {joined}");
    loop {
        tokio::select! {
            r = requests.recv() => match r {
                Some(Request::Goal(h)) => start(Goal::Zenoh(h)),
                Some(Request::Cancel(h, _)) => cancel(&h.goal_id),
                None => break,
            },
            Some(r) = ros2_requests.recv() => match r {
                connector_ros2::Request::Goal(g) => {
                    let flag = Arc::new(std::sync::atomic::AtomicBool::new(false));
                    asked.retain(|_, f| Arc::strong_count(f) > 1);
                    asked.insert(goal::ros2_id(&g.uuid), Arc::clone(&flag));
                    start(Goal::Ros2(g, flag));
                }
                connector_ros2::Request::Cancel(uuid) => {
                    let id = goal::ros2_id(&uuid);
                    if let Some(f) = asked.get(&id) {
                        f.store(true, std::sync::atomic::Ordering::SeqCst);
                    }
                    cancel(&id);
                }
            },
            _ = interrupt.recv() => break,
        }
    }
    shared.save();
    drop(server);
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// Runs one activity: begun (planned once per goal, saved), waited on the mission clock with
/// feedback on the way and cancel honoured, then ended (its effects saved with its outcome)
/// and reported. After a restart the same goal carries on where it was, and one that had ended
/// only reports its outcome again.
async fn activity(h: Goal, shared: Arc<Shared>, mut cancel: watch::Receiver<bool>) {
    shared.run_clock();
    let id = h.id();
    let begun = {
        let mut sim = shared.sim();
        sim.world.advance(shared.clock.now());
        match sim.ended.get(&id) {
            Some(e) => Ok(Err(e.clone())),
            None => sim
                .begin(&id, h.action(), h.fields(), shared.clock.now())
                .map(Ok),
        }
    };
    let running = match begun {
        Ok(Ok(r)) => r,
        Ok(Err(ended)) => return report(&h, &shared, ended).await,
        Err(e) => {
            h.abort("REJECTED", &e.to_string()).await;
            return;
        }
    };
    shared.save();
    h.executing().await;
    // A cancel accepted before a restart still holds.
    let mut cancelled = h.cancel_asked();
    let steps = 4;
    let resumed_at = shared.clock.now();
    for k in 1..=steps {
        if cancelled {
            break;
        }
        let at = running.started_ms + running.plan.duration_ms * k / steps;
        // Progress reported before a restart (or passed during it) is not reported again.
        if k < steps && at <= resumed_at && resumed_at > running.started_ms {
            continue;
        }
        let wait = shared.clock.wall((at - shared.clock.now()).max(0));
        tokio::select! {
            () = tokio::time::sleep(wait) => {}
            r = cancel.wait_for(|c| *c) => { cancelled = r.is_ok(); }
        }
        if !cancelled && k < steps {
            h.feedback(100.0 * k as f64 / steps as f64).await;
        }
    }
    let ended = {
        let mut sim = shared.sim();
        sim.end(&id, cancelled, shared.clock.now())
    };
    let Some(ended) = ended else {
        h.abort("REJECTED", "the activity's plan was lost").await;
        return;
    };
    // The effects and the outcome are durable before the result goes out.
    shared.save();
    report(&h, &shared, ended).await;
}

/// Publishes how an activity ended (the goal's result, recorded in the goal table), then
/// forgets the outcome kept for it.
async fn report(h: &Goal, shared: &Shared, ended: Ended) {
    match (ended.cancelled, ended.outcome) {
        (true, Ok(partial)) => h.canceled(partial).await,
        (true, Err(_)) => h.canceled(Default::default()).await,
        (false, Ok(outputs)) => h.succeed(outputs).await,
        (false, Err((code, message))) => {
            tracing::info!(action = h.action(), code, message, "activity failed");
            h.abort(&code, &message).await;
        }
    }
    shared.sim().forget(&h.id());
}

/// Publishes the clock, power, thermal and comm telemetry every 100 ms of wall time.
async fn telemetry(session: zenoh::Session, keys: connector_api::Keys, shared: Arc<Shared>) {
    loop {
        let now = shared.clock.now();
        // Nothing to save here: between activities the world only ages, and a restarted
        // simulator ages it again from its clock.
        let values = {
            let mut sim = shared.sim();
            sim.world.advance(now);
            let w = &sim.world;
            let all = [
                ("clock", json!({"speed": shared.clock.rate()})),
                (
                    "power",
                    json!({"battery_soc_pct": w.soc_pct(), "battery_energy_wh": w.energy_wh}),
                ),
                ("thermal", json!({"arm_temp_c": w.arm_temp_k - 273.15})),
                ("comm", json!({"comm_window_open": w.window_open(now)})),
            ];
            // The scout has a battery, no arm and no Earth link of its own.
            let kept = match w.vehicle {
                Vehicle::Lander => 4,
                Vehicle::Scout => 2,
            };
            (
                w.vehicle.server(),
                all.into_iter().take(kept).collect::<Vec<_>>(),
            )
        };
        let (server, values) = values;
        for (channel, v) in values {
            let t = Telemetry {
                mission_ms: now,
                values: v.as_object().cloned().unwrap_or_default(),
            };
            let body = serde_json::to_vec(&t).unwrap_or_default();
            if session
                .put(keys.telemetry(server, channel), body)
                .await
                .is_err()
            {
                return;
            }
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}
