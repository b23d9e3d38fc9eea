//! The crash matrix: the Europa mission flown across separate processes (the executive, the
//! lander simulator and a ground station, each with its store) — on loopback, or on two hosts
//! through their routers ([`crate::hosts`]) — with SIGKILLs of one kind of process at points
//! chosen by the execution record's growth, each victim restarted (on its store) — then the
//! flight judged from the record and the simulator's world: did it end as the uninterrupted
//! flight did, was it stuck, was a goal lost, was an effect applied twice. Used by the crash
//! bench (`cargo bench -p mission-tests --bench crash`) and, reduced, by the integration tests.

use std::collections::{BTreeMap, BTreeSet};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::hosts::Lab;
use crate::{bin, repo};

/// Where a flight's processes run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// One host: every process a peer of the executive's loopback endpoint.
    Loopback,
    /// Two hosts ([`Lab`]): the executive and the simulator on the lander, the ground station
    /// on the ground, each a client of its host's router (QUIC, mutual TLS, access control).
    Hosts,
}

/// Which process is killed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Victim {
    /// The executive (`trace run`, then `trace resume`).
    Executive,
    /// The simulator, while an activity of the lander runs.
    Simulator,
    /// The ground station, while a user task is open (as near as the record tells).
    Ground,
    /// The executive and the simulator at the same moment.
    Both,
    /// The lander's router (two hosts only), while a lander activity runs.
    LanderRouter,
    /// The ground's router (two hosts only), while a user task is open.
    GroundRouter,
}

impl Victim {
    /// Every kind on loopback, in report order.
    pub const ALL: [Victim; 4] = [
        Victim::Executive,
        Victim::Simulator,
        Victim::Ground,
        Victim::Both,
    ];

    /// Every kind on two hosts, in report order.
    pub const ACROSS_HOSTS: [Victim; 6] = [
        Victim::Executive,
        Victim::Simulator,
        Victim::Ground,
        Victim::Both,
        Victim::LanderRouter,
        Victim::GroundRouter,
    ];

    /// Its name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Victim::Executive => "executive",
            Victim::Simulator => "simulator mid-activity",
            Victim::Ground => "ground station, task open",
            Victim::Both => "executive + simulator",
            Victim::LanderRouter => "lander router mid-activity",
            Victim::GroundRouter => "ground router, task open",
        }
    }
}

/// How a flight went, judged from its record and the simulator's world.
#[derive(Clone, Debug, Default)]
pub struct Flight {
    /// Kills made (a flight that ends early gets fewer than asked).
    pub kills: usize,
    /// The instance's outcome type (`completed`, …); `None`: the flight never ended (stuck).
    pub outcome: Option<String>,
    /// Samples analysed (`instrument.analyze` completed).
    pub analysed: usize,
    /// Goals lost: tasks failed with a protocol code (`CONNECTOR_LOST`, `NOT_ACCEPTED`,
    /// `PROTOCOL_ERROR`): the system or the executive lost track of a goal.
    pub lost: usize,
    /// Effects applied twice: a task that ended twice, or more samples in the simulator's world
    /// than sample collections completed (or cancelled, which may come after the end) in the
    /// record.
    pub duplicated: usize,
    /// Per executive restart: wall ms from `trace resume` starting to its `reboot` line (the
    /// store recovered and the process up).
    pub store_ms: Vec<f64>,
    /// Per executive restart: wall ms from `trace resume` starting to the first word from a
    /// system after the reboot (a goal accepted, feedback or a result: the systems are back).
    pub systems_ms: Vec<f64>,
}

/// SplitMix64: the kill points of a seed are the same on every machine.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn between(&mut self, low: usize, high: usize) -> usize {
        low + (self.next() % (high - low).max(1) as u64) as usize
    }
}

/// The simulation speed of every flight: 100,000 mission ms per wall ms (18 mission days in
/// about 16 s).
pub const SPEED: &str = "100000";

/// A started process, killed when dropped.
pub(crate) struct Proc(pub(crate) Option<Child>);

impl Proc {
    pub(crate) fn kill(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Starts a system and waits for its `ready` line.
pub(crate) fn system(program: &str, mut command: Command) -> Proc {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("{program} starts: {e}"));
    let mut line = String::new();
    let _ = std::io::BufReader::new(child.stdout.take().expect("stdout")).read_line(&mut line);
    assert!(
        line.starts_with("ready"),
        "{program} did not start: {line:?}"
    );
    Proc(Some(child))
}

struct Deployment {
    dir: PathBuf,
    seed: u64,
    net: Net,
}

/// How the processes find each other.
enum Net {
    /// Peers of the executive's endpoint.
    Loopback { hub: String },
    /// Clients of their hosts' routers.
    Hosts(Lab),
}

impl Deployment {
    /// `program` on `host` (the lander, else the ground) with `args`, joined to the others.
    fn command(&self, program: &str, lander: bool, args: &[String]) -> Command {
        match &self.net {
            Net::Loopback { hub } => {
                let mut c = Command::new(bin(program));
                c.args(args);
                let flag = if program == "trace" { "-l" } else { "-e" };
                c.args([flag, hub, "--no-multicast-scouting"]);
                c
            }
            Net::Hosts(lab) => {
                let (file, cert) = match program {
                    "trace" => ("executive.json5", "exec"),
                    "elap-sim" => ("lander_sim.json5", "lander_sim"),
                    _ => ("station.json5", "station-a"),
                };
                let mut all = args.to_vec();
                all.extend(Lab::client_flags(file, cert));
                let all: Vec<&str> = all.iter().map(String::as_str).collect();
                let ns = if lander { &lab.lander } else { &lab.grounds[0] };
                lab.command(ns, program, &all)
            }
        }
    }

    fn simulator(&self) -> Proc {
        let args = [
            "--speed",
            SPEED,
            "--profile",
            "quiet",
            "--seed",
            &self.seed.to_string(),
            "--store",
            &self.dir.join("sim").display().to_string(),
        ];
        system(
            "elap-sim",
            self.command("elap-sim", true, &args.map(str::to_owned)),
        )
    }

    fn ground(&self) -> Proc {
        let args = [
            "--policy",
            &repo()
                .join("deploy/ground/policy.toml")
                .display()
                .to_string(),
            "--station",
            "station-a",
            "--store",
            &self.dir.join("ground").display().to_string(),
        ];
        system(
            "ground-station",
            self.command("ground-station", false, &args.map(str::to_owned)),
        )
    }

    fn executive(&self, verb: &str) -> Proc {
        let mut args = vec![verb.to_owned()];
        if verb == "run" {
            args.push(
                repo()
                    .join("deploy/missions/europa-bsm1.bpmn")
                    .display()
                    .to_string(),
            );
        }
        args.extend([
            "--store".to_owned(),
            self.dir.join("store").display().to_string(),
            "--connectors".to_owned(),
            repo().join("deploy/connectors.toml").display().to_string(),
        ]);
        // Every run's log, one after the other, for a flight that went wrong.
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(self.dir.join("executive.log"))
            .expect("executive log");
        let child = self
            .command("trace", true, &args)
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .expect("trace starts");
        Proc(Some(child))
    }

    /// Kills the router named by `victim` and starts it again (waiting for its `ready`).
    fn restart_router(&mut self, victim: Victim, n: usize) {
        let Net::Hosts(lab) = &mut self.net else {
            panic!("{} on loopback: there is no router", victim.name())
        };
        lab.kill(&lab_router_name(victim, n));
        let next = lab_router_name(victim, n + 1);
        if victim == Victim::LanderRouter {
            lab.lander_router(&next);
        } else {
            lab.ground_router(1, &next);
        }
    }

    fn record(&self) -> PathBuf {
        self.dir.join("store/record.jsonl")
    }
}

/// The record's lines so far (a line written again after a crash read once).
pub fn lines(record: &Path) -> Vec<Value> {
    let mut seen = BTreeSet::new();
    std::fs::read_to_string(record)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v["seq"].is_null() || seen.insert((v["seq"].to_string(), v["idx"].to_string())))
        .collect()
}

fn raw_count(record: &Path) -> usize {
    std::fs::read_to_string(record).map_or(0, |t| t.lines().count())
}

/// Tasks dispatched and not ended, with their resources.
fn open_tasks(lines: &[Value]) -> BTreeMap<String, String> {
    let mut open = BTreeMap::new();
    for v in lines {
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str() {
            Some("dispatched") | Some("user_task_opened") => {
                let resource = v["resource"].as_str().unwrap_or("ground").to_owned();
                open.insert(task, resource);
            }
            Some("completed" | "failed" | "cancelled" | "user_task_answered") => {
                open.remove(&task);
            }
            _ => {}
        }
    }
    open
}

/// Waits (polling the record) until `ready` holds, the executive exits, or `bound` passes.
pub(crate) fn until(
    exec: &mut Proc,
    record: &Path,
    bound: Instant,
    mut ready: impl FnMut(&[Value], usize) -> bool,
) -> bool {
    loop {
        let exited = exec
            .0
            .as_mut()
            .is_none_or(|c| c.try_wait().ok().flatten().is_some());
        if exited || Instant::now() > bound {
            return false;
        }
        let n = raw_count(record);
        if ready(&lines(record), n) {
            return true;
        }
        // The record's lines are the events (a kill point is a line count); this pause between
        // two reads of the file only spares the CPU the flight runs on.
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The name a router has in the lab after `n` restarts.
fn lab_router_name(victim: Victim, n: usize) -> String {
    let base = if victim == Victim::LanderRouter {
        "lander-router"
    } else {
        "ground-router1"
    };
    if n == 0 {
        base.to_owned()
    } else {
        format!("{base}-{n}")
    }
}

/// Flies Europa once, laid out as `layout`, with `kills` kills of `victim` (0: the
/// uninterrupted reference), in a fresh directory under `dir`, giving up after `bound` of wall
/// time.
pub fn fly(
    dir: &Path,
    layout: Layout,
    seed: u64,
    victim: Victim,
    kills: usize,
    bound: Duration,
) -> Flight {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).expect("flight dir");
    let net = match layout {
        Layout::Loopback => {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .and_then(|l| l.local_addr())
                .map(|a| a.port())
                .expect("a free port");
            Net::Loopback {
                hub: format!("tcp/127.0.0.1:{port}"),
            }
        }
        Layout::Hosts => {
            let mut lab = Lab::new("crash", 1);
            lab.routers();
            Net::Hosts(lab)
        }
    };
    let mut d = Deployment {
        dir: dir.to_owned(),
        seed,
        net,
    };
    let mut restarts = 0;
    let record = d.record();
    let deadline = Instant::now() + bound;
    let mut rng = Rng(seed.wrapping_mul(31).wrapping_add(victim as u64));
    let mut flight = Flight::default();
    let mut exec = d.executive("run");
    let mut sim = d.simulator();
    let mut ground = d.ground();
    let mut at = 0;
    for _ in 0..kills {
        // The next kill point: a few to a few hundred record lines on.
        at = rng.between(at + 5, at + 400);
        let target = at;
        let wanted = |l: &[Value], n: usize| {
            n >= target
                && match victim {
                    Victim::Simulator | Victim::Both | Victim::LanderRouter => open_tasks(l)
                        .values()
                        .any(|r| !r.starts_with("ground") && r != "power.read_battery"),
                    Victim::Ground | Victim::GroundRouter => {
                        open_tasks(l).values().any(|r| r.starts_with("ground"))
                    }
                    Victim::Executive => true,
                }
        };
        if !until(&mut exec, &record, deadline, wanted) {
            break;
        }
        flight.kills += 1;
        match victim {
            Victim::Executive | Victim::Both => {
                exec.kill();
                if victim == Victim::Both {
                    sim.kill();
                    sim = d.simulator();
                }
                let before = raw_count(&record);
                let started = Instant::now();
                exec = d.executive("resume");
                // The reboot line, then the first word from a system after it.
                let mut rebooted = None;
                let contact = until(&mut exec, &record, deadline, |l, n| {
                    if n <= before {
                        return false;
                    }
                    let Some(i) = l.iter().rposition(|v| v["kind"] == "reboot") else {
                        return false;
                    };
                    if rebooted.is_none() {
                        rebooted = Some(started.elapsed().as_secs_f64() * 1000.0);
                    }
                    l[i..].iter().any(|v| {
                        matches!(
                            v["kind"].as_str(),
                            Some("accepted" | "feedback" | "completed" | "failed" | "data")
                        )
                    })
                });
                flight.store_ms.extend(rebooted);
                if contact {
                    flight
                        .systems_ms
                        .push(started.elapsed().as_secs_f64() * 1000.0);
                }
            }
            Victim::Simulator => {
                sim.kill();
                sim = d.simulator();
            }
            Victim::Ground => {
                ground.kill();
                ground = d.ground();
            }
            Victim::LanderRouter | Victim::GroundRouter => {
                d.restart_router(victim, restarts);
                restarts += 1;
            }
        }
    }
    // Then the flight runs to its end (the executive's exit, waited for on a thread), or the
    // bound says it is stuck.
    let ended = match exec.0.take() {
        Some(mut child) => {
            let pid = child.id();
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let _ = tx.send(child.wait());
            });
            let left = deadline.saturating_duration_since(Instant::now());
            let ended = rx.recv_timeout(left).is_ok();
            if !ended {
                let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            }
            ended
        }
        None => true,
    };
    exec.kill();
    sim.kill();
    ground.kill();
    judge(&mut flight, &d, ended);
    flight
}

fn judge(flight: &mut Flight, d: &Deployment, ended: bool) {
    let lines = lines(&d.record());
    flight.outcome = lines
        .iter()
        .rfind(|v| v["kind"] == "instance_finished")
        .and_then(|v| v["outcome"]["type"].as_str().map(str::to_owned))
        .filter(|_| ended);
    let mut resource = BTreeMap::new();
    let mut ends: BTreeMap<String, usize> = BTreeMap::new();
    let mut collected = 0;
    let mut cancelled = 0;
    for v in &lines {
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str() {
            Some("dispatched") => {
                resource.insert(task, v["resource"].as_str().unwrap_or_default().to_owned());
            }
            Some(kind @ ("completed" | "failed")) => {
                *ends.entry(task.clone()).or_default() += 1;
                let r = resource.get(&task).map_or("", String::as_str);
                if kind == "completed" && r == "instrument.analyze" {
                    flight.analysed += 1;
                }
                if kind == "completed" && r == "sampling.collect_sample" {
                    collected += 1;
                }
                let code = v["code"].as_str().unwrap_or_default();
                if matches!(code, "CONNECTOR_LOST" | "NOT_ACCEPTED" | "PROTOCOL_ERROR") {
                    flight.lost += 1;
                }
            }
            // An interrupting event may cancel a collection the simulator has just finished
            // (its result on the way, or held up by a router down): its sample is real.
            Some("cancelled")
                if resource.get(&task).map(String::as_str) == Some("sampling.collect_sample") =>
            {
                cancelled += 1;
            }
            _ => {}
        }
    }
    flight.duplicated = ends.values().filter(|n| **n > 1).count();
    // The simulator's world: every sample in it came from one collection goal, completed or
    // cancelled after its end.
    if let Some(samples) = world_samples(&d.dir.join("sim"))
        && samples > collected + cancelled
    {
        flight.duplicated += samples - collected - cancelled;
    }
}

/// How many samples the simulator's saved world holds.
fn world_samples(store: &Path) -> Option<usize> {
    let db = sled::open(store).ok()?;
    let bytes = db.open_tree("world").ok()?.get("sim").ok()??;
    let sim: Value = serde_json::from_slice(&bytes).ok()?;
    sim["world"]["samples"].as_array().map(Vec::len)
}

/// The per-kind totals of a bench or test run.
#[derive(Clone, Debug, Default)]
pub struct Tally {
    /// Flights.
    pub runs: usize,
    /// Kills made.
    pub kills: usize,
    /// Flights that ended as the uninterrupted flight did (outcome and samples analysed).
    pub same: usize,
    /// Flights that ended with the uninterrupted flight's outcome, maybe with fewer samples
    /// analysed: while a router is down, the ground's approvals cannot arrive, and while the
    /// simulator is down no lander activity ends; at 100,000x a second of restart is over a
    /// mission day — the approvals' six-hour timers fire and their sites are skipped, and the
    /// deadline comes sooner, as in flight.
    pub ended: usize,
    /// Flights that never ended.
    pub stuck: usize,
    /// Goals lost, over all flights.
    pub lost: usize,
    /// Effects applied twice, over all flights.
    pub duplicated: usize,
}

impl Tally {
    /// Adds a flight, judged against the reference flight.
    pub fn add(&mut self, f: &Flight, reference: &Flight) {
        self.runs += 1;
        self.kills += f.kills;
        if f.outcome.is_none() {
            self.stuck += 1;
        } else if f.outcome == reference.outcome {
            self.ended += 1;
            if f.analysed == reference.analysed {
                self.same += 1;
            }
        }
        self.lost += f.lost;
        self.duplicated += f.duplicated;
    }
}

/// The `p` quantile (0–1) of `v` (sorted in place); 0 for none.
pub fn quantile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}
