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
    Action, Engine, Event, Input, Millis, Outcome, Outgoing, Rejected, TaskKey, TimerKey, Value,
    Vars,
};
use executive_model::ProcessGraph;
use executive_store::{SledStore, Store, StoreError};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use crate::connectors::{Connectors, Setup, SetupError};
use crate::record::RecordWriter;
use crate::script::{Agenda, Due};
use crate::waiting::{Assessment, Item, Outside, What};

mod actions;
mod clock;
mod fleet;
mod inputs;
mod vars;
mod watchdog;
use clock::VirtualClock;
pub use clock::{MissionClock, ScaledWallClock, SystemClock};
pub use fleet::Counts as FleetCounts;
use vars::check_vars;
pub use vars::{parse_var, read_vars};

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
    // The mission id prefixes every goal id and message key; minted once, kept in the store.
    let mission = meta(&rec, "mission").unwrap_or_else(|| {
        mint_mission(
            &model,
            participant.as_ref().map(|(id, _)| id.as_str()),
            wall_ms(),
        )
    });
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

/// A mission id: the model's file stem, the pool this executive runs if it is one of a fleet
/// (so the executives of one fleet, started in the same millisecond, never share an id), and
/// the first start's wall time; every part made key-safe (`docs/protocol.md` §1).
fn mint_mission(model: &Path, pool: Option<&str>, wall_ms: Millis) -> String {
    let safe = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    let stem = model
        .file_stem()
        .map(|s| safe(&s.to_string_lossy()))
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "mission".to_owned());
    match pool {
        Some(pool) => format!("{stem}-{}-{wall_ms:x}", safe(pool)),
        None => format!("{stem}-{wall_ms:x}"),
    }
}

/// The store directory's default for a mission file: `<mission>.store` beside it.
pub fn default_store(model: &Path) -> PathBuf {
    model.with_extension("store")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_executives_of_a_fleet_started_in_one_millisecond_get_different_key_safe_ids() {
        let model = Path::new("/m/europa fleet.v2.bpmn");
        let at = 0x1a2_458c_d14b;
        let lander = mint_mission(model, Some("lander"), at);
        let scout = mint_mission(model, Some("scout"), at);
        assert_eq!(lander, "europa_fleet_v2-lander-1a2458cd14b");
        assert_ne!(lander, scout);
        assert_eq!(mint_mission(model, None, at), "europa_fleet_v2-1a2458cd14b");
        // A pool id is made key-safe as the stem is: no dot, slash or wildcard reaches a key.
        assert_eq!(
            mint_mission(Path::new(""), Some("a.b/*"), 1),
            "mission-a_b__-1"
        );
    }
}
