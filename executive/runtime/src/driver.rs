//! The driver loop: feeds what happens (task results, timers, answers) into the engine one
//! input at a time, commits each step to the store, then performs its actions — and on start
//! resumes whatever the store holds.
//!
//! The run ends when every instance has ended, or when it is stuck: running instances remain
//! but nothing is awaited (`crate::waiting` says what that means), so no input can ever come.
//! While only outside things are awaited (a user task, a message, a far timer, a long task),
//! it says what it waits for, at once and then periodically.
//!
//! Without outside systems (only scripted connectors) the mission clock is virtual
//! ([`crate::script::Agenda`]): it stands still while anything can move, and jumps to the next
//! deadline (a timer, a scripted answer) when nothing can. `--speed` only paces the jumps in
//! wall time, so the record is the same at any speed; the clock also stands still while the
//! executive is down.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use connector_api::{Command, Report, Verdict};
use connector_zenoh::ZenohArgs;
use executive_engine::{
    Action, Engine, Event, Input, Millis, Outcome, Rejected, TaskKey, TimerKey, Value, Vars,
};
use executive_model::ProcessGraph;
use executive_store::{SledStore, Store, StoreError};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use crate::connectors::{Connectors, Setup, SetupError};
use crate::record::RecordWriter;
use crate::script::{Agenda, Due};
use crate::waiting::{Assessment, Item, Outside, What};

mod fleet;
mod watchdog;
pub use fleet::Counts as FleetCounts;

/// A wait this close (wall time) is not reported: the run is busy, not waiting.
pub const SOON: Duration = Duration::from_secs(5);

/// How to run a mission.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// The mission model; `None` to resume the mission the store holds.
    pub model: Option<PathBuf>,
    /// The store directory.
    pub store: PathBuf,
    /// The execution record (default: `record.jsonl` in the store directory).
    pub record: Option<PathBuf>,
    /// The scripted connector's script (JSON); without one every activity completes at once.
    pub script: Option<PathBuf>,
    /// The connector configuration (TOML); without one a scripted connector serves every
    /// resource.
    pub connectors: Option<PathBuf>,
    /// Zenoh flags (for Zenoh connectors).
    pub zenoh: ZenohArgs,
    /// How long to wait for each system's catalogue before refusing to start.
    pub catalogue_wait: Duration,
    /// Mission time runs this many times faster than wall time.
    pub speed: f64,
    /// A snapshot is written every this many steps.
    pub snapshot_every: u64,
    /// Run only this pool (its id or name) of the model's collaboration, as one executive of
    /// a fleet: the other pools are run by other executives of the same deployment, and their
    /// message flows cross over Zenoh (`docs/protocol.md` §8c). `None`: every pool here.
    pub participant: Option<String>,
}

/// What `trace run` adds to [`RunOptions`]: the start variables, the mission clock's start,
/// and how often a waiting run says what it waits for. The default: no variables, the
/// mission starts now, no waiting reports.
#[derive(Clone, Debug, Default)]
pub struct RunExtras {
    /// Variables every instance the run starts begins with.
    pub vars: Vars,
    /// Mission time at the first start (`None`: wall time now). Ignored on resume.
    pub start_at: Option<Millis>,
    /// How often (wall time) a waiting run repeats what it waits for; `None`: it never says.
    pub report_every: Option<Duration>,
}

/// How a run ended.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Each instance's outcome.
    pub outcomes: Vec<(u64, Outcome)>,
    /// Last committed sequence number.
    pub steps: u64,
    /// Restarts of this mission so far.
    pub reboots: u64,
    /// Where the execution record is.
    pub record: PathBuf,
    /// The pool this executive ran, and what crossed the fleet link (`--participant`).
    pub fleet: Option<(String, FleetCounts)>,
    /// Stopped by a signal before the mission ended.
    pub interrupted: bool,
    /// Ended because nothing could move and nothing was awaited: the incidents and dead
    /// waits say why (`None`: every instance ended, or interrupted).
    pub stuck: Option<Assessment>,
    /// Processes that start only on a message, signal, timer or condition and were never
    /// started: their start events.
    pub not_started: Vec<Item>,
}

/// Why a run could not proceed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The model does not load.
    #[error(
        "{path}: the mission model is invalid ({first}); run `trace validate` for every problem"
    )]
    Model {
        /// The model file.
        path: String,
        /// The first problem.
        first: String,
    },
    /// The store holds a different mission.
    #[error("the store holds mission {held}, not {given}; use another --store or `trace resume`")]
    DifferentMission {
        /// The mission in the store.
        held: String,
        /// The mission given.
        given: String,
    },
    /// Resuming needs a store with a mission in it.
    #[error("the store at {0} holds no mission to resume")]
    NothingToResume(String),
    /// Replaying the journal gave different actions: the engine is not the one that wrote it.
    #[error(
        "replay of input {seq} produced different actions than were committed; refusing to continue this mission"
    )]
    Nondeterminism {
        /// The input.
        seq: u64,
    },
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The connectors could not be set up, or the mission does not match the systems.
    #[error(transparent)]
    Setup(#[from] SetupError),
    /// Nothing would start: every process starts only on a trigger nothing in this run can
    /// give.
    #[error(
        "nothing would start: {}; run it with a process that has a none start event, or with a system that sends it",
        .0.iter().map(|(i, why)| format!("{} ({why})", i.describe())).collect::<Vec<_>>().join("; ")
    )]
    NothingStarts(Vec<(Item, String)>),
    /// The start variables do not fit the process's declared data.
    #[error("start variables: {0}")]
    Vars(String),
    /// A file could not be read or written.
    #[error("{0}")]
    Io(String),
    /// `--participant` names no pool with a process.
    #[error("--participant: {0}")]
    Participant(String),
    /// The store holds the run of another pool.
    #[error("the store holds the run of pool `{held}`, not `{given}`; use another --store")]
    DifferentParticipant {
        /// The pool in the store.
        held: String,
        /// The pool given.
        given: String,
    },
    /// Pools of the collaboration that no executive runs.
    #[error(
        "{} run by no executive in deployment `{deployment}` (waited {waited:?}): start each with `trace run MISSION --participant POOL` in the same deployment",
        .pools.iter().map(|p| format!("pool `{p}` is")).collect::<Vec<_>>().join(", ")
    )]
    PeersAbsent {
        /// The pools.
        pools: Vec<String>,
        /// The deployment.
        deployment: String,
        /// How long the run waited for them.
        waited: Duration,
    },
}

/// A command in flight on a connector.
struct Flight {
    connector: usize,
    goal_id: String,
    resource: String,
    user: bool,
    /// The last feedback (progress and fields), for monitors.
    feedback: Option<serde_json::Value>,
    /// The dispatch's place in the store (step, action), marked done once the system has
    /// acknowledged the goal: until then a restart sends the goal again rather than asking
    /// the system about a goal it may never have received.
    mark: Option<(u64, u32)>,
    /// The system acknowledged the goal.
    acked: bool,
    /// The goal as sent (the watchdog asks its state with it).
    command: Command,
}

/// The store's meta key listing, as of the newest snapshot, the tasks whose goals no system
/// had acknowledged: their dispatch steps are not replayed after that snapshot, so a restart
/// learns from here that they must be sent again.
const UNACKED: &str = "unacknowledged";

/// FNV-1a: a stable digest of the model bytes, to recognise the mission a store belongs to.
fn digest(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

fn wall_ms() -> Millis {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as Millis)
}

/// The mission clock timers run against: the wall clock (possibly scaled), or, with the
/// connectors, a clock a system supplies (the paper's "alternate clock").
pub trait MissionClock {
    /// Mission time now.
    fn now(&self) -> Millis;
    /// How long to wait on the wall clock until mission time `due`.
    fn wall_delay(&self, due: Millis) -> Duration;
    /// Wall time per unit of mission time (to wait out activity durations).
    fn speed(&self) -> f64;
}

/// The wall clock anchored at the mission's first start, running `speed` times faster;
/// downtime counts as mission time (the lander's clock does not stop when the executive does).
#[derive(Clone, Copy, Debug)]
pub struct ScaledWallClock {
    wall0: Millis,
    mission0: Millis,
    speed: f64,
}

impl MissionClock for ScaledWallClock {
    fn now(&self) -> Millis {
        self.mission0 + ((wall_ms() - self.wall0) as f64 * self.speed) as Millis
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        let left = (due.saturating_sub(self.now())).max(0) as f64 / self.speed;
        Duration::from_millis(left as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// A system's mission clock (the paper's "alternate clock"): the mission time it last reported,
/// advanced at its speed since.
#[derive(Clone, Copy, Debug)]
pub struct SystemClock {
    mission0: Millis,
    at: std::time::Instant,
    speed: f64,
}

impl SystemClock {
    /// The clock as reported now.
    pub fn new(mission_ms: Millis, speed: f64) -> SystemClock {
        SystemClock {
            mission0: mission_ms,
            at: std::time::Instant::now(),
            // 0: the system holds its clock (not started yet); timers wait for the next report.
            speed: if speed.is_finite() && speed >= 0.0 {
                speed
            } else {
                1.0
            },
        }
    }
}

impl MissionClock for SystemClock {
    fn now(&self) -> Millis {
        self.mission0 + (self.at.elapsed().as_secs_f64() * 1000.0 * self.speed) as Millis
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        if self.speed == 0.0 {
            return Duration::from_secs(3600);
        }
        let left = due.saturating_sub(self.now()).max(0) as f64 / self.speed;
        Duration::from_micros((left * 1000.0) as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// The virtual mission clock of a run without outside systems: it reads the agenda; waiting
/// until a deadline takes its distance in mission time divided by the speed.
struct VirtualClock {
    agenda: Agenda,
    speed: f64,
}

impl MissionClock for VirtualClock {
    fn now(&self) -> Millis {
        self.agenda.now()
    }
    fn wall_delay(&self, due: Millis) -> Duration {
        let left = due.saturating_sub(self.now()).max(0) as f64 / self.speed;
        Duration::from_micros((left * 1000.0).min(1e15) as u64)
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// One `--var name=value`: the value is JSON if it parses as JSON, else the text itself.
pub fn parse_var(arg: &str) -> Result<(String, Value), String> {
    let (name, value) = arg
        .split_once('=')
        .ok_or_else(|| format!("`{arg}` is not name=value"))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(format!("`{arg}` has no variable name"));
    }
    let value =
        serde_json::from_str::<Value>(value).unwrap_or_else(|_| Value::String(value.to_owned()));
    Ok((name.to_owned(), value))
}

/// A `--vars` file: one JSON object, its fields the variables.
pub fn read_vars(path: &Path) -> Result<Vars, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str::<Vars>(&text)
        .map_err(|e| format!("{}: not a JSON object of variables: {e}", path.display()))
}

/// Checks start variables against the data a process declares (its properties and data
/// objects carry no type in BPMN as TRACE reads it, only `isCollection`): a collection must
/// be given a list. Names the process does not declare are returned (a warning: models
/// often use undeclared variables).
fn check_vars(
    g: &ProcessGraph,
    p: executive_model::ProcessId,
    vars: &Vars,
) -> Result<Vec<String>, String> {
    let process = g.process(p);
    let declared: Vec<_> = process
        .properties
        .iter()
        .chain(&process.data_objects)
        .collect();
    let mut undeclared = Vec::new();
    for (name, value) in vars {
        match declared
            .iter()
            .find(|d| d.name.as_deref().unwrap_or(&d.id) == name)
        {
            Some(d) if d.collection && !matches!(value, Value::List(_)) => {
                return Err(format!(
                    "`{name}` is a collection in process `{}` (isCollection), but was given {} `{value}`",
                    process.id,
                    value.type_name()
                ));
            }
            Some(_) => {}
            None if !declared.is_empty() => undeclared.push(name.clone()),
            None => {}
        }
    }
    Ok(undeclared)
}

/// Runs (or resumes) a mission to its end; blocks. Uses a single-threaded tokio runtime.
pub fn run(opts: &RunOptions) -> Result<Summary, RunError> {
    run_with(opts, &RunExtras::default())
}

/// [`run`] with start variables, a start time and waiting reports.
pub fn run_with(opts: &RunOptions, extras: &RunExtras) -> Result<Summary, RunError> {
    // Zenoh refuses tokio's current-thread scheduler; one worker keeps the driver sequential.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_time()
        .enable_io()
        .build()
        .map_err(|e| RunError::Io(e.to_string()))?;
    rt.block_on(drive(opts, extras))
}

struct Driver {
    /// Restarts of this mission so far (shown to monitors).
    reboots: u64,
    g: Arc<ProcessGraph>,
    engine: Engine,
    store: SledStore,
    record: RecordWriter,
    connectors: Connectors,
    mission: String,
    clock: Box<dyn MissionClock>,
    seq: u64,
    tx: mpsc::UnboundedSender<Event>,
    /// Where the watchdog's stages arrive (`driver/watchdog.rs`).
    watch_tx: mpsc::UnboundedSender<watchdog::Watch>,
    /// Armed timers with their mission-time deadlines (re-armed when the clock changes); on
    /// the virtual clock they are on the agenda and have no sleeping task.
    timers: BTreeMap<TimerKey, (Millis, Option<JoinHandle<()>>)>,
    /// The virtual clock's agenda (runs without outside systems).
    agenda: Option<Agenda>,
    /// What outside systems can deliver.
    outside: Outside,
    /// Primary processes that start only on a trigger and have not started.
    unstarted: Vec<executive_model::ProcessId>,
    /// Tasks whose result the engine refused, with the reason (their goal is gone).
    refused: BTreeMap<TaskKey, String>,
    /// When each awaited thing was first seen: mission time and wall instant.
    since: BTreeMap<String, (Millis, std::time::Instant)>,
    /// How often a waiting run repeats what it waits for.
    report_every: Option<Duration>,
    /// The last waiting report: when, and what it listed.
    reported: Option<(std::time::Instant, Vec<String>)>,
    /// Incidents already told.
    told: BTreeSet<(u64, String, String)>,
    /// Mission time of the last step: inputs never go back in time when the clock source
    /// changes.
    last_at: Millis,
    flights: BTreeMap<TaskKey, Flight>,
    goals: HashMap<String, TaskKey>,
    /// Operators' answers waiting to be stepped, each with the verdict its sender waits for.
    answers: Vec<(String, Event, Verdict)>,
    /// Dispatches whose goals were acknowledged since the last step: marked done with it.
    acked: Vec<(u64, u32)>,
    /// User tasks answered, by goal id: who answered and what (from the record on resume),
    /// so the same answer sent again is confirmed rather than refused.
    answered: HashMap<String, (String, Vars)>,
    snapshot_every: u64,
    /// The fleet link, when this executive runs one pool of a fleet.
    post: Option<fleet::Post>,
}

/// Fault injection for the crash tests: with `TRACE_CRASH_AT=<point>` in its environment, the
/// executive sends itself SIGKILL at that point (nothing more runs or is written; it aborts if
/// `kill` cannot be run). The points are the fleet link's: `message-committed` (a step that sends a
/// message is committed, nothing sent yet), `message-acknowledged` (its receiver's verdict
/// arrived, not yet marked done) and `letter-committed` (a received message's step is
/// committed, not yet acknowledged).
fn crash_point(point: &str) {
    static AT: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    if AT
        .get_or_init(|| std::env::var("TRACE_CRASH_AT").ok())
        .as_deref()
        == Some(point)
    {
        eprintln!("TRACE_CRASH_AT={point}: killed here");
        let _ = std::process::Command::new("kill")
            .args(["-s", "KILL", &std::process::id().to_string()])
            .status();
        std::process::abort();
    }
}

fn meta(rec: &executive_store::Recovered, key: &str) -> Option<String> {
    rec.meta
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
}

async fn drive(opts: &RunOptions, extras: &RunExtras) -> Result<Summary, RunError> {
    let mut store = SledStore::open(&opts.store)?;
    let rec = store.recover()?;
    let held_model = meta(&rec, "model");
    let model = match (&opts.model, &held_model) {
        (Some(m), _) => m.clone(),
        (None, Some(m)) => PathBuf::from(m),
        (None, None) => return Err(RunError::NothingToResume(opts.store.display().to_string())),
    };
    let bytes =
        std::fs::read(&model).map_err(|e| RunError::Io(format!("{}: {e}", model.display())))?;
    let loaded = crate::validate::load_file(&model, &executive_model::Options::default())
        .map_err(|e| RunError::Io(format!("{}: {e}", model.display())))?;
    let graph = Arc::new(loaded.graph.ok_or_else(|| {
        RunError::Model {
            path: model.display().to_string(),
            first: loaded
                .diagnostics
                .iter()
                .find(|d| d.severity == executive_model::Severity::Error)
                .map_or_else(String::new, |d| d.message.clone()),
        }
    })?);
    let given = digest(&bytes);
    let model_xml: Arc<[u8]> = Arc::from(bytes);
    if let Some(held) = meta(&rec, "digest")
        && held != given
    {
        return Err(RunError::DifferentMission {
            held: held_model.unwrap_or(held),
            given: model.display().to_string(),
        });
    }
    let resumed = rec.snapshot.is_some() || !rec.steps.is_empty();
    // The mission id prefixes every goal id; minted once, kept in the store.
    let mission = meta(&rec, "mission").unwrap_or_else(|| mint_mission(&model));
    // One pool of a fleet: the store remembers which.
    let participant = match (&opts.participant, meta(&rec, "participant")) {
        (Some(given), held) => {
            let (id, remote) = fleet::resolve(&graph, given)?;
            if let Some(held) = held.filter(|h| *h != id) {
                return Err(RunError::DifferentParticipant { held, given: id });
            }
            Some((id, remote))
        }
        (None, Some(held)) => Some(fleet::resolve(&graph, &held)?),
        (None, None) => None,
    };
    let remote = participant
        .as_ref()
        .map(|(_, r)| r.clone())
        .unwrap_or_default();
    let engine_of = |state: Option<executive_engine::State>| -> Result<Engine, RunError> {
        let e = match state {
            Some(s) => Engine::restore(Arc::clone(&graph), s),
            None => Engine::new(Arc::clone(&graph)),
        };
        match &participant {
            Some((id, _)) => e.participant(id).map_err(RunError::Participant),
            None => Ok(e),
        }
    };

    // Connectors first: a mission that does not match its systems never starts.
    let (reports_tx, mut reports) = mpsc::unbounded_channel();
    let fleet_reports = reports_tx.clone();
    let effects = opts.store.join("effects.jsonl");
    let agenda = Agenda::default();
    let mut connectors = Connectors::open(
        &Setup {
            config: opts.connectors.as_deref(),
            script: opts.script.as_deref(),
            effects: &effects,
            speed: opts.speed.max(1e-6),
            zenoh: &opts.zenoh,
            mission: mission.clone(),
            catalogue_wait: opts.catalogue_wait,
            // In a fleet the other executives are outside systems: no virtual clock.
            agenda: participant.is_none().then(|| agenda.clone()),
            fleet: participant.is_some(),
        },
        reports_tx,
    )
    .await?;
    // The start variables are known at a first start; a resumed run's are in its state.
    let start: std::collections::BTreeSet<String> = extras.vars.keys().cloned().collect();
    let start = (!resumed).then_some(&start);
    if let Err(e) = connectors.check(&graph, &loaded.text, &remote, start).await {
        connectors.close().await;
        return Err(e.into());
    }
    let post = match &participant {
        Some((pool, remote)) => {
            let joined = match (connectors.session(), opts.zenoh.keys()) {
                (Some(session), Ok(keys)) => {
                    fleet::Post::join(
                        session,
                        keys,
                        pool,
                        remote,
                        fleet_reports,
                        opts.catalogue_wait,
                        !resumed,
                    )
                    .await
                }
                (_, Err(e)) => Err(RunError::Io(e.to_string())),
                (None, _) => Err(RunError::Io(
                    "the fleet link has no Zenoh session".to_owned(),
                )),
            };
            match joined {
                Ok(p) => Some(p),
                Err(e) => {
                    connectors.close().await;
                    return Err(e);
                }
            }
        }
        None => {
            drop(fleet_reports);
            None
        }
    };
    let all_scripted = connectors
        .config
        .connectors
        .iter()
        .all(|c| c.kind == connector_api::Kind::Script);
    // The virtual clock only without outside systems: the fleet's other executives are one.
    let agenda = (all_scripted && post.is_none()).then_some(agenda);
    let outside = Outside {
        // In a fleet, the other pools' executives send messages.
        messages: post.is_some(),
        signals: false,
        data: connectors
            .config
            .connectors
            .iter()
            .any(|c| !c.data.is_empty()),
    };
    // Processes that start only on a trigger are not started empty: they wait for it. If
    // nothing would start at all, and nothing outside can give the trigger, refuse now,
    // before anything is journaled.
    let probe = match engine_of(None) {
        Ok(e) => e,
        Err(e) => {
            connectors.close().await;
            return Err(e);
        }
    };
    let (untriggered, triggered): (Vec<_>, Vec<_>) = graph
        .primary_processes()
        .into_iter()
        .filter(|p| !remote.contains_key(p))
        .partition(|p| probe.starts_untriggered(*p));
    if !resumed && untriggered.is_empty() && !triggered.is_empty() {
        let a = crate::waiting::assess(&graph, probe.state(), outside, &|_| None, &triggered);
        if a.awaited.is_empty() {
            connectors.close().await;
            return Err(RunError::NothingStarts(a.dead));
        }
    }
    if !resumed {
        for &p in &untriggered {
            let undeclared = match check_vars(&graph, p, &extras.vars) {
                Ok(u) => u,
                Err(e) => {
                    connectors.close().await;
                    return Err(RunError::Vars(e));
                }
            };
            for name in undeclared {
                tracing::warn!(variable = %name, process = %graph.process(p).id, "start variable the process does not declare");
                eprintln!(
                    "warning: start variable `{name}`: process `{}` declares no data of that name",
                    graph.process(p).id
                );
            }
        }
    }
    // A system that supplies the mission clock is heard from before anything is timed.
    let mut early = Vec::new();
    let mut system_clock = None;
    if connectors.config.connectors.iter().any(|c| c.clock) {
        let waited = tokio::time::timeout(opts.catalogue_wait, async {
            while let Some(r) = reports.recv().await {
                match r {
                    Report::Clock { mission_ms, speed } => {
                        return Some(SystemClock::new(mission_ms, speed));
                    }
                    other => early.push(other),
                }
            }
            None
        })
        .await;
        match waited {
            Ok(Some(c)) => system_clock = Some(c),
            _ => {
                connectors.close().await;
                return Err(RunError::Io(format!(
                    "no mission clock from the system within {:?} (a connector has `clock = true`)",
                    opts.catalogue_wait
                )));
            }
        }
    }
    store.set_meta("mission", &mission)?;

    let clock = match meta(&rec, "clock").and_then(|c| {
        let mut p = c.split(',');
        Some(ScaledWallClock {
            wall0: p.next()?.parse().ok()?,
            mission0: p.next()?.parse().ok()?,
            speed: p.next()?.parse().ok()?,
        })
    }) {
        Some(c) => c,
        None => {
            let now = wall_ms();
            let c = ScaledWallClock {
                wall0: now,
                mission0: extras.start_at.unwrap_or(now),
                speed: opts.speed.max(1e-6),
            };
            store.set_meta("clock", &format!("{},{},{}", c.wall0, c.mission0, c.speed))?;
            c
        }
    };
    store.set_meta("model", &model.display().to_string())?;
    store.set_meta("digest", &given)?;
    if let Some((pool, _)) = &participant {
        store.set_meta("participant", pool)?;
    }

    // Restore and replay: the journal after the snapshot must give the committed actions.
    if let Some((seq, state)) = &rec.snapshot {
        state.check(&graph).map_err(|reason| StoreError::Corrupt {
            tree: "snapshots",
            key: seq.to_string(),
            reason: format!("the state does not fit the mission model: {reason}"),
        })?;
    }
    let mut engine = engine_of(rec.snapshot.as_ref().map(|(_, state)| state.clone()))?;
    let mut seq = rec.snapshot.as_ref().map_or(0, |(s, _)| *s);
    for step in &rec.steps {
        let again = engine.step(step.input.clone());
        if again.as_ref() != Ok(&step.actions) {
            return Err(RunError::Nondeterminism {
                seq: step.input.seq,
            });
        }
        seq = step.input.seq;
    }

    let record_path = opts
        .record
        .clone()
        .unwrap_or_else(|| opts.store.join("record.jsonl"));
    let record = RecordWriter::open(&record_path, Arc::clone(&graph))
        .map_err(|e| RunError::Io(format!("{}: {e}", record_path.display())))?;
    let (tx, mut rx) = mpsc::unbounded_channel();
    let (watch_tx, mut watch_rx) = mpsc::unbounded_channel();
    let mut record = record;
    let mut monitor = match connectors.session() {
        Some(session) => {
            let keys = opts.zenoh.keys().map_err(|e| RunError::Io(e.to_string()))?;
            // Every process of a deployment names it when it starts (docs/protocol.md §1).
            eprintln!(
                "mission {mission} — deployment {} (keys {}/…)",
                keys.deployment(),
                keys.root()
            );
            match crate::monitor::Publisher::start(
                session,
                &keys,
                &mission,
                model_xml.clone(),
                record_path.clone(),
            )
            .await
            {
                Ok((p, queries)) => {
                    record.mirror(p.mirror());
                    Some((p, queries))
                }
                Err(e) => {
                    tracing::warn!(error = %e, "live monitoring not available");
                    None
                }
            }
        }
        None => None,
    };
    let clock: Box<dyn MissionClock> = match &agenda {
        // The virtual clock starts where the mission stood: at its first start, or, resumed,
        // at its last step (downtime is not mission time without outside systems).
        Some(a) => {
            a.set(if resumed {
                engine.state().now.max(clock.mission0)
            } else {
                clock.mission0
            });
            Box::new(VirtualClock {
                agenda: a.clone(),
                speed: opts.speed.max(1e-6),
            })
        }
        None => Box::new(clock),
    };
    // A resumed mission's triggered processes have not started if no instance of them has.
    let unstarted: Vec<_> = triggered
        .into_iter()
        .filter(|p| !engine.state().instances.values().any(|i| i.process == *p))
        .collect();
    let answered = if resumed {
        answered_in(&record_path, &mission)
    } else {
        HashMap::new()
    };
    let mut d = Driver {
        reboots: 0,
        g: graph,
        engine,
        store,
        record,
        connectors,
        mission,
        clock,
        seq,
        tx,
        watch_tx,
        timers: BTreeMap::new(),
        last_at: 0,
        flights: BTreeMap::new(),
        goals: HashMap::new(),
        answers: Vec::new(),
        acked: Vec::new(),
        answered,
        snapshot_every: opts.snapshot_every.max(1),
        agenda,
        outside,
        unstarted,
        refused: BTreeMap::new(),
        since: BTreeMap::new(),
        report_every: extras.report_every,
        reported: None,
        told: BTreeSet::new(),
        post,
    };
    if let Some(c) = system_clock {
        d.set_clock(c);
    }
    let early: Vec<Event> = early.into_iter().filter_map(|r| d.event_of(r)).collect();
    let mut reboots: u64 = meta(&rec, "reboots")
        .and_then(|r| r.parse().ok())
        .unwrap_or(0);
    if resumed {
        reboots += 1;
        d.store.set_meta("reboots", &reboots.to_string())?;
        let in_flight = d.engine.in_flight();
        d.record
            .reboot(d.clock.now(), wall_ms(), reboots, in_flight.len())
            .map_err(|e| RunError::Io(e.to_string()))?;
        tracing::info!(reboots, recommanded = in_flight.len(), "resumed");
        d.reboots = reboots;
        // Actions committed but not performed, except commands: those come from the state.
        // A command committed but never performed is sent; one performed before the crash is
        // reconciled with its system (still running, finished, or lost).
        // A dispatch is done once its system acknowledged the goal; the ones not done (in the
        // steps replayed, or listed at the newest snapshot) are sent again — harmless, a goal
        // id is idempotent — and only acknowledged goals are asked about.
        let mut unsent: BTreeMap<TaskKey, Option<(u64, u32)>> = meta(&rec, UNACKED)
            .and_then(|v| serde_json::from_str::<Vec<TaskKey>>(&v).ok())
            .unwrap_or_default()
            .into_iter()
            .map(|t| (t, None))
            .collect();
        for step in &rec.steps {
            for (i, a) in step.actions.iter().enumerate() {
                if step.done.get(i).copied().unwrap_or(false) {
                    continue;
                }
                match a {
                    Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. } => {
                        unsent.insert(*task, Some((step.input.seq, i as u32)));
                    }
                    Action::StartTimer { .. } => {}
                    _ => d.perform(step.input.seq, i, a.clone())?,
                }
            }
        }
        if let Some(post) = d.post.as_mut() {
            post.resend(meta(&rec, fleet::UNSENT));
        }
        for a in in_flight {
            match &a {
                Action::DispatchTask { task, .. } | Action::OpenUserTask { task, .. } => {
                    match unsent.get(task).copied() {
                        None => d.reconcile(a),
                        Some(mark) => {
                            d.command_of(a, false, mark);
                        }
                    }
                }
                // Timers armed before the crash are armed again.
                _ => d.perform(d.seq, usize::MAX, a)?,
            }
        }
    } else {
        for p in untriggered {
            let process = d.g.process(p).id.clone();
            d.feed_all(vec![Event::InstanceStarted {
                process,
                vars: extras.vars.clone(),
                start: None,
            }])?;
        }
    }
    d.feed_all(early)?;
    let mut interrupted = false;
    // Both signals are watched from here on, so one that arrives between two turns of the
    // loop (or before its first) is still seen, never the default action that kills.
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate())
        .map_err(|e| RunError::Io(format!("cannot watch SIGTERM: {e}")))?;
    let mut int = signal(SignalKind::interrupt())
        .map_err(|e| RunError::Io(format!("cannot watch SIGINT: {e}")))?;
    let mut stuck = None;
    loop {
        if d.part_done().await {
            break;
        }
        let a = d.assess();
        // Nothing awaited and nothing queued: no input can ever come.
        if a.stuck() && rx.is_empty() && d.answers.is_empty() && d.quiet_link() {
            tracing::info!(
                incidents = a.incidents.len(),
                dead = a.dead.len(),
                "stuck: nothing can move and nothing is awaited"
            );
            stuck = Some(a);
            break;
        }
        let wake = d.watch(&a);
        // On the virtual clock: the next deadline, reached after its distance at `--speed`
        // once nothing else is queued (`biased`: what is queued always goes first).
        let due = d
            .agenda
            .as_ref()
            .and_then(Agenda::next)
            .map(|t| d.clock.wall_delay(t));
        // SIGINT or SIGTERM: stop between steps; everything committed stays, `trace resume`
        // continues.
        let state_query = async {
            match monitor.as_mut() {
                Some((p, queries)) => {
                    let q = queries.recv().await;
                    q.map(|q| (q, p.state_key().to_owned()))
                }
                None => std::future::pending().await,
            }
        };
        let first = tokio::select! {
            biased;
            _ = int.recv() => { interrupted = true; break }
            _ = term.recv() => { interrupted = true; break }
            m = rx.recv() => m,
            r = reports.recv() => r.and_then(|r| d.event_of(r)),
            Some(w) = watch_rx.recv() => {
                d.on_watch(w);
                None
            }
            Some((q, key)) = state_query => {
                crate::monitor::answer(q, &key, d.snapshot()).await;
                None
            }
            () = tokio::time::sleep(due.unwrap_or_default()), if due.is_some() => d.due_event(),
            () = tokio::time::sleep_until(wake.unwrap_or_else(tokio::time::Instant::now)), if wake.is_some() => None,
        };
        // Group commit: everything that has arrived is stepped, committed with one flush,
        // then acted on.
        let mut events: Vec<Event> = first.into_iter().collect();
        while events.len() < 256 {
            if let Ok(more) = rx.try_recv() {
                events.push(more);
            } else if let Ok(r) = reports.try_recv() {
                events.extend(d.event_of(r));
            } else {
                break;
            }
        }
        d.mark_acked()?;
        d.feed_all(events)?;
        d.apply_answers()?;
        d.apply_letters()?;
    }
    // Acknowledged messages are marked done before the store closes: a resume of an ended
    // mission sends nothing again.
    d.mark_acked()?;
    d.store.flush()?;
    // Answers that arrived too late are refused, so their stations hear it before we leave.
    reports.close();
    while let Ok(r) = reports.try_recv() {
        if let Report::Answer { verdict, .. } = r {
            verdict.give(Err("the mission has ended".to_owned()));
        }
    }
    for (_, _, verdict) in d.answers.drain(..) {
        verdict.give(Err("the mission has ended".to_owned()));
    }
    // Letters not stepped get no verdict: their senders hear that this executive is stopping
    // and send them again to its next run.
    if let Some(p) = d.post.as_mut() {
        p.letters.clear();
    }
    let fleet = d.post.as_ref().map(|p| (p.pool.clone(), p.counts));
    if let Some(p) = d.post.as_mut() {
        if !interrupted {
            p.linger().await;
        }
        p.fleet.close().await;
    }
    d.connectors.close().await;
    let outcomes = d
        .engine
        .state()
        .instances
        .iter()
        .filter_map(|(id, i)| i.outcome.clone().map(|o| (id.0, o)))
        .collect();
    let not_started = d
        .assess()
        .awaited
        .into_iter()
        .chain(d.assess().dead.into_iter().map(|(i, _)| i))
        .filter(|i| matches!(i.what, What::Start { .. }))
        .collect();
    Ok(Summary {
        outcomes,
        steps: d.seq,
        reboots,
        record: record_path,
        fleet,
        interrupted,
        stuck,
        not_started,
    })
}

impl Driver {
    fn finished(&self) -> bool {
        let i = &self.engine.state().instances;
        !i.is_empty() && i.values().all(|i| i.outcome.is_some()) && self.quiet_link()
    }

    /// What the run waits for now.
    fn assess(&self) -> Assessment {
        let s = self.engine.state();
        let unstarted: Vec<_> = self
            .unstarted
            .iter()
            .copied()
            .filter(|p| !s.instances.values().any(|i| i.process == *p))
            .collect();
        let held = |k: TaskKey| {
            if self.flights.contains_key(&k) {
                Some(Ok(()))
            } else {
                self.refused.get(&k).map(|why| Err(why.clone()))
            }
        };
        crate::waiting::assess(&self.g, s, self.outside, &held, &unstarted)
    }

    /// The next thing due on the virtual clock, as an input (the clock moves to it).
    fn due_event(&mut self) -> Option<Event> {
        match self.agenda.as_ref()?.advance()? {
            Due::Timer(timer) => Some(Event::TimerFired { timer }),
            Due::Goal { answer, .. } => answer().and_then(|r| self.event_of(r)),
        }
    }

    /// How far (wall time) an awaited thing is, if known: a timer's or a scripted answer's
    /// deadline.
    fn distance(&self, item: &Item) -> Option<Duration> {
        match &item.what {
            What::Timer { due } => Some(self.clock.wall_delay(*due)),
            What::Task { task, .. } | What::UserTask { task } => {
                let goal = &self.flights.get(task)?.goal_id;
                let due = self.agenda.as_ref()?.goal_due(goal)?;
                Some(self.clock.wall_delay(due))
            }
            _ => None,
        }
    }

    /// Tells new incidents at once, and, when only outside things (or far ones) are awaited,
    /// what the run waits for: at once when that starts or changes, then every
    /// `report_every`. Returns when to look again (wall time).
    fn watch(&mut self, a: &Assessment) -> Option<tokio::time::Instant> {
        for i in &a.incidents {
            if self
                .told
                .insert((i.instance, i.element.clone(), i.message.clone()))
            {
                tracing::warn!(instance = i.instance, element = %i.element, message = %i.message, "incident");
                eprintln!("{i}");
            }
        }
        let now = std::time::Instant::now();
        let mission_now = self.clock.now().max(self.last_at);
        self.since
            .retain(|k, _| a.awaited.iter().any(|i| &i.key == k));
        for i in &a.awaited {
            self.since
                .entry(i.key.clone())
                .or_insert((mission_now, now));
        }
        let every = self.report_every?;
        // Busy: something is due soon, or a task on an outside system is young.
        let mut recheck: Option<std::time::Instant> = None;
        let mut busy = false;
        for i in &a.awaited {
            match (self.distance(i), &i.what) {
                (Some(d), _) => busy |= d < SOON,
                (None, What::Task { .. }) => {
                    let (_, seen) = self.since[&i.key];
                    if now.duration_since(seen) < SOON {
                        busy = true;
                        let at = seen + SOON;
                        recheck = Some(recheck.map_or(at, |r| r.min(at)));
                    }
                }
                _ => {}
            }
        }
        if busy || a.awaited.is_empty() {
            self.reported = None;
            return recheck.map(tokio::time::Instant::from_std);
        }
        let listed: Vec<String> = a
            .awaited
            .iter()
            .filter(|i| i.what != What::Join)
            .map(|i| i.key.clone())
            .collect();
        let due = match &self.reported {
            Some((at, before)) => *before != listed || now.duration_since(*at) >= every,
            None => true,
        };
        if due {
            eprintln!(
                "waiting (mission time {}) for:",
                crate::waiting::mission_time(mission_now)
            );
            for i in a.awaited.iter().filter(|i| i.what != What::Join) {
                let since = crate::waiting::mission_time(self.since[&i.key].0);
                tracing::info!(
                    what = i.kind(),
                    element = %i.element,
                    name = i.name.as_deref().unwrap_or_default(),
                    instance = i.instance,
                    since = %since,
                    "waiting for {}",
                    i.describe()
                );
                let scripted = match &i.what {
                    What::Task { task, .. } | What::UserTask { task } => self
                        .flights
                        .get(task)
                        .and_then(|f| self.agenda.as_ref()?.goal_due(&f.goal_id))
                        .map(|t| {
                            format!(
                                ", the script answers at {}",
                                crate::waiting::mission_time(t)
                            )
                        }),
                    _ => None,
                };
                eprintln!(
                    "  {}, since {since}{}",
                    i.describe(),
                    scripted.unwrap_or_default()
                );
            }
            self.reported = Some((now, listed));
        }
        self.reported
            .as_ref()
            .map(|(at, _)| tokio::time::Instant::from_std(*at + every))
    }

    /// The input a connector report stands for, if any. Reports of goals no longer in flight
    /// (a result after an abort, a duplicate) are dropped.
    fn event_of(&mut self, report: Report) -> Option<Event> {
        let task_of = |goals: &HashMap<String, TaskKey>, id: &str| goals.get(id).copied();
        match report {
            Report::Data { key, value } => match serde_json::from_value::<Value>(value) {
                Ok(value) => Some(Event::DataChanged { key, value }),
                Err(e) => {
                    tracing::warn!(key, error = %e, "system data ignored");
                    None
                }
            },
            Report::Clock { mission_ms, speed } => {
                self.set_clock(SystemClock::new(mission_ms, speed));
                None
            }
            Report::Accepted { goal_id } => {
                let task = task_of(&self.goals, &goal_id)?;
                if let Some(f) = self.flights.get_mut(&task) {
                    let first = !f.acked;
                    f.acked = true;
                    self.acked.extend(f.mark.take());
                    // The goal runs from now: the watchdog counts from here.
                    if first {
                        self.arm_watchdog(task);
                    }
                }
                self.note("accepted", task, &goal_id, serde_json::json!({}));
                None
            }
            Report::Feedback {
                goal_id,
                progress_pct,
                fields,
            } => {
                let task = task_of(&self.goals, &goal_id)?;
                let body = serde_json::json!({ "progress_pct": progress_pct, "fields": fields });
                if let Some(f) = self.flights.get_mut(&task) {
                    f.feedback = Some(body.clone());
                }
                self.note("feedback", task, &goal_id, body);
                None
            }
            r @ (Report::Letter { .. } | Report::Delivered { .. } | Report::Peer { .. }) => {
                self.fleet_report(r);
                None
            }
            Report::Canceled { goal_id } => {
                tracing::debug!(goal_id, "goal cancelled");
                None
            }
            Report::Answer {
                goal_id,
                fields,
                operator,
                verdict,
            } => {
                let task = match self.goals.get(&goal_id) {
                    Some(t) if self.flights.get(t).is_some_and(|f| f.user) => *t,
                    _ => {
                        let same =
                            serde_json::from_value::<Vars>(serde_json::Value::Object(fields)).ok();
                        verdict.give(match self.answered.get(&goal_id) {
                            Some((by, answer))
                                if *by == operator && same.as_ref() == Some(answer) =>
                            {
                                Ok(())
                            }
                            Some((by, _)) => {
                                Err(format!("user task `{goal_id}` is closed: answered by {by}"))
                            }
                            None => Err(format!("no open user task has goal id `{goal_id}`")),
                        });
                        return None;
                    }
                };
                match serde_json::from_value::<Vars>(serde_json::Value::Object(fields)) {
                    Ok(answer) => self.answers.push((
                        goal_id,
                        Event::UserTaskAnswered {
                            task,
                            answer,
                            operator,
                        },
                        verdict,
                    )),
                    Err(e) => verdict.give(Err(format!("the answer's values do not convert: {e}"))),
                }
                None
            }
            Report::Done { goal_id, outputs } => {
                let task = self.goals.remove(&goal_id)?;
                let flight = self.flights.remove(&task)?;
                let vars: Vars = outputs
                    .into_iter()
                    .filter_map(|(k, v)| Some((k, serde_json::from_value(v).ok()?)))
                    .collect();
                Some(if flight.user {
                    let operator = match vars.get("operator") {
                        Some(Value::String(s)) => s.clone(),
                        _ => self.connectors.list[flight.connector].name().to_owned(),
                    };
                    Event::UserTaskAnswered {
                        task,
                        answer: vars,
                        operator,
                    }
                } else {
                    Event::TaskCompleted { task, output: vars }
                })
            }
            Report::Failed {
                goal_id,
                code,
                message,
            } => {
                let task = self.goals.remove(&goal_id)?;
                self.flights.remove(&task);
                Some(Event::TaskFailed {
                    task,
                    code,
                    message,
                })
            }
        }
    }

    /// A line of the execution record about a goal, written by the executive (not a step).
    fn note(&mut self, kind: &str, task: TaskKey, goal_id: &str, body: serde_json::Value) {
        if let Err(e) = self.record.activity(
            kind,
            &task.to_string(),
            goal_id,
            self.clock.now(),
            wall_ms(),
            body,
        ) {
            tracing::warn!(error = %e, "record line not written");
        }
    }

    /// Operators' answers, one step each: the verdict goes back once the step is committed
    /// (applied) or refused by the engine (nothing changed) — a task closed meanwhile by a
    /// boundary event refuses the answer.
    fn apply_answers(&mut self) -> Result<(), RunError> {
        for (goal_id, event, verdict) in std::mem::take(&mut self.answers) {
            // Out of flight first, so closing the answered task withdraws it from no station.
            let task = self.goals.remove(&goal_id);
            let flight = task.and_then(|t| self.flights.remove(&t));
            let applied = match &event {
                Event::UserTaskAnswered {
                    operator, answer, ..
                } => Some((operator.clone(), answer.clone())),
                _ => None,
            };
            let refused = self
                .feed_all(vec![event])?
                .pop()
                .flatten()
                .map(|r| r.to_string());
            match refused {
                None => {
                    self.answered.extend(applied.map(|a| (goal_id, a)));
                    verdict.give(Ok(()));
                }
                Some(reason) => {
                    if let (Some(task), Some(flight)) = (task, flight) {
                        self.goals.insert(goal_id, task);
                        self.flights.insert(task, flight);
                    }
                    verdict.give(Err(reason));
                }
            }
        }
        Ok(())
    }

    /// Inputs stepped in order, committed together (one flush), then acted on. Returns, per
    /// input, why the engine refused it (`None`: stepped).
    fn feed_all(&mut self, events: Vec<Event>) -> Result<Vec<Option<Rejected>>, RunError> {
        let mut steps = Vec::with_capacity(events.len());
        let mut refusals = Vec::with_capacity(events.len());
        for event in events {
            if let Event::TimerFired { timer } = &event {
                self.timers.remove(timer);
            }
            let input = Input {
                seq: self.seq + 1,
                at: self.clock.now().max(self.last_at),
                event,
            };
            match self.engine.step(input.clone()) {
                Ok(actions) => {
                    self.seq = input.seq;
                    self.last_at = input.at;
                    steps.push((input, actions));
                    refusals.push(None);
                }
                Err(rejected) => {
                    // A timer firing just after the step that disarmed it, or a result racing
                    // the cancel of its task, is a race the engine settles: not news.
                    if matches!(
                        rejected,
                        Rejected::UnknownTimer(_)
                            | Rejected::UnknownTask(_)
                            | Rejected::AlreadyDelivered(_)
                    ) {
                        tracing::debug!(%rejected, "input refused (a harmless race)");
                    } else {
                        tracing::warn!(%rejected, "input refused");
                    }
                    if let Event::TaskCompleted { task, .. }
                    | Event::TaskFailed { task, .. }
                    | Event::UserTaskAnswered { task, .. } = &input.event
                    {
                        self.refused
                            .insert(*task, format!("its result was refused: {rejected}"));
                    }
                    refusals.push(Some(rejected));
                }
            }
        }
        if steps.is_empty() {
            return Ok(refusals);
        }
        self.store.commit_batch(&steps)?;
        let mut snapshot = false;
        for (input, actions) in steps {
            snapshot |= input.seq.is_multiple_of(self.snapshot_every);
            for (i, a) in actions.into_iter().enumerate() {
                self.perform(input.seq, i, a)?;
            }
        }
        if snapshot {
            // First the goals no system has acknowledged, then the snapshot after which their
            // dispatches are no longer replayed (a crash between the two only sends more again).
            let unacked: Vec<TaskKey> = self
                .flights
                .iter()
                .filter(|(_, f)| !f.acked)
                .map(|(task, _)| *task)
                .collect();
            let unacked = serde_json::to_string(&unacked).unwrap_or_else(|_| "[]".to_owned());
            self.store.set_meta(UNACKED, &unacked)?;
            if let Some(p) = &self.post {
                self.store.set_meta(fleet::UNSENT, &p.unsent_json())?;
            }
            self.store.snapshot(self.seq, self.engine.state())?;
        }
        Ok(refusals)
    }

    /// Marks the dispatches whose goals were acknowledged as done (flushed with the next
    /// commit: a mark lost in a crash only sends a goal again). A dispatch whose step was
    /// pruned since is covered by the snapshot's list instead.
    fn mark_acked(&mut self) -> Result<(), RunError> {
        for (seq, index) in std::mem::take(&mut self.acked) {
            match self.store.done(seq, index) {
                Err(StoreError::UnknownAction { .. }) => {
                    tracing::debug!(seq, index, "acknowledged dispatch already pruned");
                }
                other => other?,
            }
        }
        Ok(())
    }

    /// Performs one action; `index` `usize::MAX` for re-commands (nothing to mark done).
    fn perform(&mut self, seq: u64, index: usize, a: Action) -> Result<(), RunError> {
        match a {
            a @ (Action::DispatchTask { .. } | Action::OpenUserTask { .. }) => {
                // Done when the system acknowledges the goal (`Report::Accepted`), not now.
                let mark = (index != usize::MAX).then_some((seq, index as u32));
                self.command_of(a, false, mark);
                return Ok(());
            }
            Action::CancelTask { task } | Action::CloseUserTask { task } => {
                if let Some(f) = self.flights.remove(&task) {
                    self.goals.remove(&f.goal_id);
                    self.connectors.list[f.connector].abort(&f.goal_id);
                }
            }
            Action::StartTimer { timer, at } => self.arm(timer, at),
            Action::CancelTimer { timer } => {
                if let Some((_, Some(h))) = self.timers.remove(&timer) {
                    h.abort();
                }
                if let Some(a) = &self.agenda {
                    a.cancel_timer(timer);
                }
            }
            Action::Record(r) => self
                .record
                .write(seq, index, wall_ms(), &r)
                .map_err(|e| RunError::Io(e.to_string()))?,
            Action::SendMessage {
                name,
                payload,
                to: Some(to),
                flow: Some(flow),
                correlation,
                number: Some(number),
            } if self.post.as_ref().is_some_and(|p| p.peers.contains(&to)) => {
                let Some(post) = self.post.as_mut() else {
                    return Ok(());
                };
                let letter =
                    post.letter(&self.mission, number, to, flow, name, correlation, &payload);
                let mark = (index != usize::MAX).then_some((seq, index as u32));
                crash_point("message-committed");
                let line = serde_json::json!({"seq": seq, "idx": index, "key": letter.key,
                    "to": letter.to, "flow": letter.flow, "name": letter.name});
                post.send(letter, mark);
                self.fleet_line("message_sent", line);
                // Done once its receiver gives a verdict.
                return Ok(());
            }
            Action::SendMessage { name, payload, .. } => {
                match self.connectors.config.route(&name) {
                    Some(route) => {
                        let payload = serde_json::to_value(&payload).unwrap_or_default();
                        self.connectors.list[route.connector].notify(&route.action, payload);
                    }
                    None => {
                        tracing::info!(%name, "message sent out of the mission (no connector routes it)")
                    }
                }
            }
            Action::InstanceFinished { instance, outcome } => {
                tracing::info!(instance = instance.0, ?outcome, "instance finished");
            }
        }
        if index != usize::MAX {
            self.store.done(seq, index as u32)?;
        }
        Ok(())
    }

    /// The present state for a remote monitor.
    fn snapshot(&self) -> serde_json::Value {
        let in_flight = self
            .flights
            .iter()
            .map(|(task, f)| {
                let node = self.engine.state().tokens.get(&task.token).map(|t| t.node);
                let mut v = serde_json::json!({"task": task.to_string(), "goal": f.goal_id,
                    "resource": f.resource, "user_task": f.user, "feedback": f.feedback,
                    "element": node.map(|n| self.g.node(n).id.as_str()),
                    "name": node.map(|n| self.g.node(n).label())});
                if f.user
                    && let Some(due) = self.deadline(*task)
                {
                    v["deadline_ms"] = serde_json::json!(due);
                }
                v
            })
            .collect();
        let mut state =
            crate::monitor::snapshot(&self.mission, &self.engine, self.last_at, in_flight);
        // What each connector refused (garbage, unknown goals, mistyped data, …), so an
        // operator sees that something on the bus is talking nonsense.
        let dropped: serde_json::Map<String, serde_json::Value> = self
            .connectors
            .list
            .iter()
            .map(|c| (c.name().to_owned(), serde_json::json!(c.dropped())))
            .collect();
        state["dropped"] = serde_json::Value::Object(dropped);
        state["reboots"] = serde_json::json!(self.reboots);
        // The mission clock now, and how fast it runs, so a page counts down to deadlines.
        state["clock"] =
            serde_json::json!({ "now_ms": self.clock.now(), "speed": self.clock.speed() });
        if let Some(p) = &self.post {
            state["fleet"] = p.state();
        }
        state
    }

    /// Arms (or re-arms) a timer for mission time `at` on the current clock.
    fn arm(&mut self, timer: TimerKey, at: Millis) {
        if let Some(a) = &self.agenda {
            a.cancel_timer(timer);
            a.push(at, Due::Timer(timer));
            self.timers.insert(timer, (at, None));
            return;
        }
        let delay = self.clock.wall_delay(at);
        let tx = self.tx.clone();
        let h = tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            let _ = tx.send(Event::TimerFired { timer });
        });
        if let Some((_, Some(old))) = self.timers.insert(timer, (at, Some(h))) {
            old.abort();
        }
    }

    /// Switches to a system's clock; armed timers are re-armed against it.
    /// Systems report their clock several times a second; timers are re-armed only when the
    /// report disagrees with the clock in use (another speed, or drift beyond 10 ms of wall
    /// time).
    fn set_clock(&mut self, clock: SystemClock) {
        let drift = (self.clock.now() - clock.now()).abs() as f64;
        if self.clock.speed() == clock.speed && drift <= 10.0 * clock.speed.max(1.0) {
            return;
        }
        self.clock = Box::new(clock);
        let armed: Vec<(TimerKey, Millis)> =
            self.timers.iter().map(|(k, (at, _))| (*k, *at)).collect();
        for (timer, at) in armed {
            self.arm(timer, at);
        }
    }

    /// The goal of a user task: which task (element id and name), the variables the
    /// operator sees, and the deadline — the earliest timer boundary on the task (mission
    /// time), when it has one.
    fn user_goal(&self, task: TaskKey, node: executive_model::NodeId, context: Vars) -> Vars {
        let n = self.g.node(node);
        let mut goal = Vars::from([
            ("task".to_owned(), Value::String(n.id.clone())),
            ("name".to_owned(), Value::String(n.label().to_owned())),
            ("context".to_owned(), Value::Map(context)),
        ]);
        if let Some(due) = self.deadline(task) {
            goal.insert("deadline_ms".to_owned(), Value::Int(due));
        }
        goal
    }

    /// When the earliest timer boundary on a task fires (mission time), if it has one.
    fn deadline(&self, task: TaskKey) -> Option<Millis> {
        self.engine
            .state()
            .waits
            .values()
            .filter(|w| w.token == Some(task.token))
            .filter_map(|w| match w.on {
                executive_engine::On::Timer { due, .. } => Some(due),
                _ => None,
            })
            .min()
    }

    /// The resource a user task is routed by: its binding's, else its element id.
    fn user_resource(&self, node: executive_model::NodeId) -> String {
        match &self.g.node(node).kind {
            executive_model::NodeKind::Task(t) => {
                t.binding.as_ref().and_then(|b| b.resource.clone())
            }
            _ => None,
        }
        .unwrap_or_else(|| self.g.node(node).id.clone())
    }

    /// After a restart: asks the system about a command performed before the crash.
    fn reconcile(&mut self, a: Action) {
        if let Some(task) = self.command_of(a, true, None)
            && let Some(f) = self.flights.get_mut(&task)
        {
            f.acked = true;
            self.arm_watchdog(task);
        }
    }

    /// A dispatch or a user task, sent (or, `reconcile`, asked about) through its connector;
    /// `mark` is the dispatch's place in the store, marked done once the system acknowledges
    /// the goal. Returns the task.
    fn command_of(
        &mut self,
        a: Action,
        reconcile: bool,
        mark: Option<(u64, u32)>,
    ) -> Option<TaskKey> {
        match a {
            Action::DispatchTask {
                task,
                resource,
                request,
                ..
            } => {
                self.command(task, &resource, request, false, reconcile, mark);
                Some(task)
            }
            Action::OpenUserTask {
                task,
                node,
                context,
            } => {
                let resource = self.user_resource(node);
                let fields = self.user_goal(task, node, context);
                self.command(task, &resource, fields, true, reconcile, mark);
                Some(task)
            }
            _ => None,
        }
    }

    /// Hands a command to the connector its resource routes to (idempotent by key). A
    /// resource no connector serves fails the task with `NO_CONNECTOR`.
    fn command(
        &mut self,
        task: TaskKey,
        resource: &str,
        fields: Vars,
        user: bool,
        reconcile: bool,
        mark: Option<(u64, u32)>,
    ) {
        if self.flights.contains_key(&task) {
            return;
        }
        let goal_id = connector_api::keys::goal_id(
            &self.mission,
            task.instance.0,
            task.token.0,
            task.attempt,
        );
        let Some(route) = self.connectors.config.route(resource) else {
            let _ = self.tx.send(Event::TaskFailed {
                task,
                code: connector_api::wire::codes::NO_CONNECTOR.to_owned(),
                message: format!("no connector serves resource `{resource}`"),
            });
            return;
        };
        let fields = match serde_json::to_value(&fields) {
            Ok(serde_json::Value::Object(m)) => m,
            _ => Default::default(),
        };
        let command = Command {
            goal_id: goal_id.clone(),
            action: route.action,
            fields,
        };
        self.goals.insert(goal_id.clone(), task);
        self.flights.insert(
            task,
            Flight {
                connector: route.connector,
                goal_id,
                resource: resource.to_owned(),
                user,
                feedback: None,
                mark,
                acked: false,
                command: command.clone(),
            },
        );
        let c = &mut self.connectors.list[route.connector];
        if reconcile {
            c.reconcile(command);
        } else {
            c.execute(command);
        }
    }
}

/// The user tasks answered in an execution record, by goal id: who answered and what.
fn answered_in(record: &Path, mission: &str) -> HashMap<String, (String, Vars)> {
    let text = std::fs::read_to_string(record).unwrap_or_default();
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["kind"] == "user_task_answered")
        .filter_map(|v| {
            let mut parts = v["task"].as_str()?.split('-').map(str::parse::<u64>);
            let (i, t, a) = (
                parts.next()?.ok()?,
                parts.next()?.ok()?,
                parts.next()?.ok()?,
            );
            let goal = connector_api::keys::goal_id(mission, i, t, u32::try_from(a).ok()?);
            let answer = serde_json::from_value::<Vars>(v["answer"].clone()).ok()?;
            Some((goal, (v["operator"].as_str()?.to_owned(), answer)))
        })
        .collect()
}

/// A mission id: the model's file stem (key-safe) and the first start's wall time.
fn mint_mission(model: &Path) -> String {
    let stem: String = model
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!(
        "{}-{:x}",
        if stem.is_empty() { "mission" } else { &stem },
        wall_ms()
    )
}

/// The store directory's default for a mission file: `<mission>.store` beside it.
pub fn default_store(model: &Path) -> PathBuf {
    model.with_extension("store")
}
