//! `trace fly`: one command for a whole mission on one host — starts the lander simulator and
//! a ground station answering by policy as separate processes, runs the executive against them over
//! Zenoh (embedded defaults: peers on loopback, no router), shows progress from the execution
//! record as the mission advances, and ends with a summary.
//!
//! It works from any directory and as installed binaries: the demo mission, its connector
//! routes, the ground policy and the named scenarios are built in (a file given on the command
//! line overrides each; the simulator's catalogue and the ground forms are built into those
//! binaries), and the flight directory keeps a copy of what was flown. `elap-sim` and
//! `ground-station` are found next to the running `trace`, else on `PATH`. Each flight is its
//! own deployment (every key under `<key-root>/<flight id>`, `docs/protocol.md` §1) on a free
//! loopback port, so flights, and a Zenoh router on 7447, coexist on one host.

use std::collections::BTreeMap;
use std::io::{BufRead, Seek};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serde_json::Value;

/// Prints to stdout what a flight says, as `println!` does, but never fails the flight when
/// nobody reads it any more (`trace fly | head`): the flight goes on, its record is the
/// account.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod fleet;
pub use fleet::vehicles;

/// The demo mission, built in: its file name (the mission id's stem) and text.
const MISSION: (&str, &str) = (
    "europa-bsm1.bpmn",
    include_str!("../../../deploy/missions/europa-bsm1.bpmn"),
);

/// The demo mission's connector routes (`deploy/connectors.toml`), built in.
const CONNECTORS: &str = include_str!("../../../deploy/connectors.toml");

/// The ground station's policy (`deploy/ground/policy.toml`), built in.
const GROUND_POLICY: &str = include_str!("../../../deploy/ground/policy.toml");
/// How long a flight with `--no-ground` waits for the operator's ground station before it
/// starts: a week, said every half minute (`docs/guide/operating.md`).
const NO_GROUND_WAIT: Duration = Duration::from_secs(7 * 24 * 3600);

/// The named scenarios (`deploy/scenarios/*.json`), built in.
const SCENARIOS: &[(&str, &str)] = &[
    (
        "battery-abort",
        include_str!("../../../deploy/scenarios/battery-abort.json"),
    ),
    (
        "deadline",
        include_str!("../../../deploy/scenarios/deadline.json"),
    ),
    (
        "nominal",
        include_str!("../../../deploy/scenarios/nominal.json"),
    ),
    (
        "slump",
        include_str!("../../../deploy/scenarios/slump.json"),
    ),
    (
        "stuck-tool-abandoned",
        include_str!("../../../deploy/scenarios/stuck-tool-abandoned.json"),
    ),
    (
        "stuck-tool-recovered",
        include_str!("../../../deploy/scenarios/stuck-tool-recovered.json"),
    ),
];

/// How to fly (the flags of `trace fly`).
#[derive(Clone, Debug, clap::Args)]
pub struct FlyOptions {
    /// The mission model (default: the built-in Europa BSM-1 mission,
    /// deploy/missions/europa-bsm1.bpmn).
    pub mission: Option<PathBuf>,
    /// Working directory for the stores and the record (default: `flights/<flight id>`);
    /// it must not hold a previous flight.
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Connector configuration (default: the built-in routes of the Europa mission,
    /// deploy/connectors.toml).
    #[arg(long)]
    pub connectors: Option<PathBuf>,
    /// The policy of the ground station `trace fly` starts (default: the built-in
    /// deploy/ground/policy.toml).
    #[arg(long)]
    pub ground_policy: Option<PathBuf>,
    /// Start no ground station: the flight waits, saying so, until one joins — typically
    /// `ground-station --interactive` in another terminal (the command to type is printed) —
    /// and what its operator leaves unanswered the model's timers decide.
    #[arg(long)]
    pub no_ground: bool,
    /// Mission time runs this many times faster than wall time (200000: a 20-day mission in
    /// under 10 s).
    #[arg(long, default_value_t = 200000.0)]
    pub speed: f64,
    /// The simulator's fault seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The simulator's fault profile: nominal, demanding or quiet.
    #[arg(long, default_value = "nominal")]
    pub profile: String,
    /// Scripted faults for the simulator (JSON).
    #[arg(long)]
    pub faults: Option<PathBuf>,
    /// Fly the two-vehicle mission (default: the built-in deploy/missions/europa-fleet.bpmn)
    /// as a fleet: the lander's and the scout's simulators and executives, each its own
    /// process, cooperating through the mission's message flows; `--connectors` is then the
    /// lander's.
    #[arg(long)]
    pub fleet: bool,
    /// With `--fleet`: scripted faults for the scout's simulator (JSON; `survey.site` also
    /// takes the codes `UNSAFE` and `SAFE`, what the scout finds).
    #[arg(long, requires = "fleet")]
    pub scout_faults: Option<PathBuf>,
    /// A scenario (seed, profile and scripted faults): a built-in name (battery-abort,
    /// deadline, nominal, slump, stuck-tool-abandoned, stuck-tool-recovered) or a JSON file
    /// of the same shape; overrides --seed, --profile and --faults.
    #[arg(long)]
    pub scenario: Option<String>,
    /// Zenoh flags. Without endpoints the executive listens on a free loopback port and the
    /// systems connect to it; with `-l` they connect to its first listen endpoint, with `-e`
    /// to the same endpoints. The deployment defaults to the flight id.
    #[command(flatten)]
    pub zenoh: connector_zenoh::ZenohArgs,
}

/// Why a flight could not be flown.
#[derive(Debug, thiserror::Error)]
pub enum FlyError {
    /// A helper process could not start.
    #[error("{program}: {reason}")]
    Spawn {
        /// Which program.
        program: String,
        /// Why.
        reason: String,
    },
    /// The working directory is not usable.
    #[error("{0}")]
    Dir(String),
    /// The executive failed.
    #[error(transparent)]
    Run(#[from] crate::driver::RunError),
}

/// A scenario: seed, profile and scripted faults.
#[derive(Debug)]
pub struct Scenario {
    /// What it shows.
    pub description: String,
    /// Simulator seed.
    pub seed: u64,
    /// Fault profile.
    pub profile: String,
    /// The scripted faults, written out for the simulator.
    pub faults: PathBuf,
}

impl Scenario {
    /// The built-in scenario `name`, or the scenario file `name` (a path ending in `.json` or
    /// naming a directory); writes its faults into `dir`.
    pub fn load(name: &str, dir: &Path) -> Result<Scenario, FlyError> {
        let bad = |reason: String| FlyError::Dir(format!("scenario `{name}`: {reason}"));
        let text = if name.ends_with(".json") || name.contains(std::path::is_separator) {
            std::fs::read_to_string(name).map_err(|e| bad(e.to_string()))?
        } else {
            SCENARIOS
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, text)| (*text).to_owned())
                .ok_or_else(|| {
                    let known: Vec<&str> = SCENARIOS.iter().map(|(n, _)| *n).collect();
                    bad(format!(
                        "not a built-in scenario ({}) nor a .json file",
                        known.join(", ")
                    ))
                })?
        };
        let v: Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        std::fs::create_dir_all(dir).map_err(|e| bad(e.to_string()))?;
        let faults = dir.join("faults.json");
        std::fs::write(
            &faults,
            serde_json::json!({ "faults": v["faults"] }).to_string(),
        )
        .map_err(|e| bad(e.to_string()))?;
        Ok(Scenario {
            description: v["description"].as_str().unwrap_or_default().to_owned(),
            seed: v["seed"].as_u64().unwrap_or(1),
            profile: v["profile"].as_str().unwrap_or("nominal").to_owned(),
            faults,
        })
    }
}

struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A program of the TRACE set: next to the running `trace` (a build or an installed set),
/// else found on `PATH`.
fn program(name: &str) -> PathBuf {
    let file = format!("{name}{}", std::env::consts::EXE_SUFFIX);
    std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(|d| d.join(&file)))
        .filter(|p| p.is_file())
        .unwrap_or_else(|| PathBuf::from(file))
}

/// Starts `name`, its stderr and later output into `log`, and waits for its `ready` line.
fn start(name: &str, args: &[String], log: &Path) -> Result<Child, FlyError> {
    let err = |reason: String| FlyError::Spawn {
        program: name.to_owned(),
        reason,
    };
    let file = std::fs::File::create(log).map_err(|e| err(e.to_string()))?;
    let mut copy = file.try_clone().map_err(|e| err(e.to_string()))?;
    let path = program(name);
    let mut child = Command::new(&path)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(file)
        .spawn()
        .map_err(|e| {
            let here = std::env::current_exe()
                .ok()
                .and_then(|p| p.parent().map(Path::to_path_buf))
                .map_or_else(String::new, |d| format!(" next to {} or", d.display()));
            err(if e.kind() == std::io::ErrorKind::NotFound {
                format!(
                    "not found{here} on PATH (build the set with `cargo build --release \
                     --workspace --bins`, or install it beside `trace`)"
                )
            } else {
                format!("{}: {e}", path.display())
            })
        })?;
    let mut line = String::new();
    let out = child.stdout.take().ok_or_else(|| err("no stdout".into()))?;
    let mut out = std::io::BufReader::new(out);
    out.read_line(&mut line).map_err(|e| err(e.to_string()))?;
    if !line.starts_with("ready") {
        let _ = child.kill();
        let _ = child.wait();
        let said = std::fs::read_to_string(log).unwrap_or_default();
        let tail: Vec<&str> = said.lines().filter(|l| !l.trim().is_empty()).collect();
        let tail = tail[tail.len().saturating_sub(5)..].join("\n  ");
        return Err(err(format!(
            "exited before serving (its log: {}){}",
            log.display(),
            if tail.is_empty() {
                String::new()
            } else {
                format!(":\n  {tail}")
            }
        )));
    }
    // The ready line (deployment and keys) and what it prints after that (a ground
    // station's answers) go to its log.
    let _ = std::io::Write::write_all(&mut copy, line.as_bytes());
    std::thread::spawn(move || std::io::copy(&mut out, &mut copy));
    Ok(child)
}

/// `name` made one key chunk (a deployment name): anything but letters, digits, `-`, `_` and
/// `.` becomes `-`.
fn chunk(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// Flies the mission; prints progress and a summary to stdout.
pub fn fly(opts: &FlyOptions) -> Result<(), FlyError> {
    if !(opts.speed.is_finite() && opts.speed > 0.0) {
        return Err(FlyError::Dir(format!(
            "--speed {} must be positive",
            opts.speed
        )));
    }
    let mut opts = opts.clone();
    // The flight id: the mission, the time and this process (unique on the host).
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let built = if opts.fleet {
        fleet::MISSION.0
    } else {
        MISSION.0
    };
    let stem = opts
        .mission
        .as_deref()
        .unwrap_or(Path::new(built))
        .file_stem()
        .map_or_else(|| "mission".into(), |s| s.to_string_lossy().into_owned());
    let flight = chunk(&format!("{stem}-{stamp}-{}", std::process::id()));
    let dir = opts
        .dir
        .clone()
        .unwrap_or_else(|| PathBuf::from("flights").join(&flight));
    if let Some(name) = &opts.scenario {
        let s = Scenario::load(name, &dir)?;
        say!("scenario {name}: {}", s.description);
        (opts.seed, opts.profile, opts.faults) = (s.seed, s.profile, Some(s.faults));
    }
    // A deployment given by flag or environment is kept; otherwise the flight is its own.
    if opts.zenoh.deployment.is_none() {
        let given = std::env::var("TRACE_DEPLOYMENT")
            .ok()
            .filter(|d| !d.is_empty());
        opts.zenoh.deployment = Some(given.unwrap_or(flight));
    }
    fly_in(&opts, &dir)
}

/// Where the processes of a flight meet: the executive's Zenoh flags and the flags every
/// system gets.
struct Net {
    exec: connector_zenoh::ZenohArgs,
    systems: Vec<String>,
    /// Where, for people: the endpoint to give `-e`.
    hub: String,
}

/// Where flight ports are picked: below Linux's ephemeral range (32768–60999), from which the
/// system hands out the source ports of outgoing connections and the ports of `bind(0)`: a
/// port picked there could be taken by any connection before the executive binds it.
const FLIGHT_PORTS: std::ops::Range<u16> = 20_000..32_000;

/// A free TCP port on 127.0.0.1 outside the ephemeral range: found free by binding it, then
/// released (the executive binds it next). Tried from a point that differs per process and
/// per call, so two flights started together do not try the same ports in the same order.
fn free_port() -> Result<u16, FlyError> {
    let span = u32::from(FLIGHT_PORTS.end - FLIGHT_PORTS.start);
    let seed = std::process::id()
        ^ std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
    for i in 0..span {
        let port = FLIGHT_PORTS.start + ((seed.wrapping_mul(2_654_435_761) + i) % span) as u16;
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return Ok(port);
        }
    }
    Err(FlyError::Dir(format!(
        "no free port on 127.0.0.1 in {}..{}",
        FLIGHT_PORTS.start, FLIGHT_PORTS.end
    )))
}

/// The first listen endpoint of a Zenoh configuration (a list, or one per mode).
fn first_listen(config: &zenoh::Config) -> Option<String> {
    let v: Value = serde_json::from_str(&config.get_json("listen/endpoints").ok()?).ok()?;
    let list = match &v {
        Value::Object(m) => m.get("peer").or_else(|| m.values().next())?,
        other => other,
    };
    list.as_array()?.first()?.as_str().map(str::to_owned)
}

impl Net {
    /// The flags that join the flight, for the commands it prints (`trace monitor …`).
    fn join(&self, opts: &FlyOptions) -> String {
        let mut j = format!("-e {} --deployment {}", self.hub, self.exec.deployment());
        if opts.zenoh.root != connector_api::keys::DEFAULT_ROOT {
            j += &format!(" --key-root {}", opts.zenoh.root);
        }
        j
    }

    fn new(z: &connector_zenoh::ZenohArgs) -> Result<Net, FlyError> {
        let mut exec = z.clone();
        let mut systems = vec![
            "--key-root".to_owned(),
            z.root.clone(),
            "--deployment".into(),
            z.deployment(),
        ];
        if let Some(mode) = &z.mode {
            systems.extend(["--mode".to_owned(), mode.clone()]);
        }
        if z.multicast_scouting {
            systems.push("--multicast-scouting".into());
        }
        let hub = if let Some(hub) = z.listen.first() {
            hub.clone()
        } else if !z.connect.is_empty() {
            // A router or another peer: everyone connects to it.
            for e in &z.connect {
                systems.extend(["-e".to_owned(), e.clone()]);
            }
            return Ok(Net {
                hub: z.connect.join(", "),
                exec,
                systems,
            });
        } else if z.zenoh_config.is_some() {
            let config = z
                .config(connector_zenoh::Role::Hub)
                .map_err(|e| FlyError::Dir(e.to_string()))?;
            first_listen(&config).unwrap_or_else(|| connector_zenoh::DEFAULT_HUB.to_owned())
        } else {
            let hub = format!("tcp/127.0.0.1:{}", free_port()?);
            exec.listen = vec![hub.clone()];
            hub
        };
        systems.extend(["-e".to_owned(), hub.clone()]);
        Ok(Net { exec, systems, hub })
    }
}

/// The mission flown: the file given, else the built-in `(name, text)` written into `dir`; and
/// how to name it to people.
fn mission_file(
    opts: &FlyOptions,
    dir: &Path,
    (name, text): (&str, &str),
) -> Result<(PathBuf, String), FlyError> {
    Ok(match &opts.mission {
        Some(m) => (m.clone(), m.display().to_string()),
        None => (built_in(dir, name, text)?, format!("{name} (built in)")),
    })
}

/// The policy ground station of a flight (none with `--no-ground`), joined to `net`.
fn ground(opts: &FlyOptions, dir: &Path, net: &Net) -> Result<Option<Child>, FlyError> {
    if opts.no_ground {
        return Ok(None);
    }
    let policy = match &opts.ground_policy {
        Some(p) => p.clone(),
        None => built_in(dir, "ground-policy.toml", GROUND_POLICY)?,
    };
    let mut args = vec![
        "--policy".to_owned(),
        policy.display().to_string(),
        "--station".into(),
        "fly-policy".into(),
    ];
    args.extend(net.systems.iter().cloned());
    start("ground-station", &args, &dir.join("ground.log")).map(Some)
}

/// Writes a built-in file into the flight directory (what was flown stays with the flight).
fn built_in(dir: &Path, name: &str, text: &str) -> Result<PathBuf, FlyError> {
    let path = dir.join(name);
    std::fs::write(&path, text).map_err(|e| FlyError::Dir(format!("{}: {e}", path.display())))?;
    Ok(path)
}

fn fly_in(opts: &FlyOptions, dir: &Path) -> Result<(), FlyError> {
    if dir.join("store").exists() {
        return Err(FlyError::Dir(format!(
            "{} already holds a flight; choose another --dir (or `trace resume --store {}`)",
            dir.display(),
            dir.join("store").display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| FlyError::Dir(format!("{}: {e}", dir.display())))?;
    if opts.fleet {
        return fleet::fly(opts, dir);
    }
    let (mission, shown) = mission_file(opts, dir, MISSION)?;
    let connectors = match &opts.connectors {
        Some(c) => c.clone(),
        None => built_in(dir, "connectors.toml", CONNECTORS)?,
    };
    let net = Net::new(&opts.zenoh)?;
    let deployment = net.exec.deployment();
    let mut sim_args = vec![
        "--speed".to_owned(),
        opts.speed.to_string(),
        "--seed".into(),
        opts.seed.to_string(),
        "--profile".into(),
        opts.profile.clone(),
        "--store".into(),
        dir.join("sim").display().to_string(),
    ];
    sim_args.extend(net.systems.iter().cloned());
    if let Some(f) = &opts.faults {
        sim_args.extend(["--faults".to_owned(), f.display().to_string()]);
    }
    let mut children = Children(Vec::new());
    children
        .0
        .push(start("elap-sim", &sim_args, &dir.join("elap-sim.log"))?);
    children.0.extend(ground(opts, dir, &net)?);
    let record = dir.join("store").join("record.jsonl");
    let join = net.join(opts);
    say!(
        "flying {shown} — simulator, {} and executive as separate processes on {}, \
         deployment {deployment}",
        if opts.no_ground {
            "no ground station"
        } else {
            "a policy ground station"
        },
        net.hub,
    );
    if opts.no_ground {
        say!("  answer the user tasks with: ground-station --interactive {join}");
    }
    say!("  watch with:                 trace monitor {join}");
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (record, stop) = (record.clone(), Arc::clone(&stop));
        std::thread::spawn(move || progress(&record, &stop))
    };
    let result = crate::driver::run(&crate::driver::RunOptions {
        model: Some(mission),
        store: dir.join("store"),
        record: None,
        script: None,
        connectors: Some(connectors),
        zenoh: net.exec,
        // Without a ground station of its own, the flight waits for the operator's (saying so
        // every half minute) as long as it takes; its own simulator answers at once.
        catalogue_wait: if opts.no_ground {
            NO_GROUND_WAIT
        } else {
            Duration::from_secs(30)
        },
        speed: 1.0,
        snapshot_every: 1000,
        participant: None,
    });
    stop.store(true, Ordering::SeqCst);
    let _ = watcher.join();
    drop(children);
    let summary = result?;
    say!("{}", summarize(&record, &summary).trim_end_matches('\n'));
    let page = dir.join("timeline.html");
    match crate::timeline::write(&record, &page) {
        Ok(_) => say!("  timeline:          {}", page.display()),
        Err(e) => tracing::warn!(error = %e, "timeline not written"),
    }
    Ok(())
}

fn day(v: &Value, t0: i64) -> f64 {
    (v["mission_ms"].as_i64().unwrap_or(t0) - t0) as f64 / 86_400_000.0
}

/// Follows the record and prints what a ground operator wants to see.
fn progress(record: &Path, stop: &AtomicBool) {
    let mut pos = 0u64;
    let mut shown = Progress::default();
    let mut partial = String::new();
    loop {
        let done = stop.load(Ordering::SeqCst);
        if let Ok(mut f) = std::fs::File::open(record)
            && f.seek(std::io::SeekFrom::Start(pos)).is_ok()
        {
            let mut r = std::io::BufReader::new(f);
            let mut line = String::new();
            while r.read_line(&mut line).unwrap_or(0) > 0 {
                pos += line.len() as u64;
                partial.push_str(&line);
                line.clear();
                if !partial.ends_with('\n') {
                    continue;
                }
                if let Some(out) = shown.line(&partial) {
                    say!("{out}");
                }
                partial.clear();
            }
        }
        if done {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A phase of the mission: a sub-process, call activity or transaction.
fn is_phase(v: &Value) -> bool {
    matches!(
        v["element"]["type"].as_str(),
        Some("subProcess" | "callActivity" | "transaction")
    )
}

/// What the progress display has shown so far.
#[derive(Default)]
struct Progress {
    reader: crate::record::Reader,
    t0: Option<i64>,
    samples: usize,
    /// The lowest battery decile shown (`None`: none yet, as if 100 %).
    decile: Option<i64>,
    /// Open phases: (instance, element) → the token that opened it. A phase is shown when it
    /// opens, not again while it is open (the instances of a multi-instance phase, a phase
    /// entered by several branches at once).
    phases: BTreeMap<(i64, String), i64>,
}

impl Progress {
    /// The progress line for one record line, if it is worth one.
    fn line(&mut self, line: &str) -> Option<String> {
        let v = self.reader.read(line)?;
        let t0 = *self.t0.get_or_insert(v["mission_ms"].as_i64().unwrap_or(0));
        let d = day(&v, t0);
        let said = match v["kind"].as_str()? {
            kind @ ("entered" | "left" | "withdrawn") if is_phase(&v) => {
                let at = (
                    v["instance"].as_i64().unwrap_or_default(),
                    v["element"]["id"].as_str().unwrap_or_default().to_owned(),
                );
                let token = v["token"].as_i64().unwrap_or_default();
                if kind != "entered" {
                    if self.phases.get(&at) == Some(&token) {
                        self.phases.remove(&at);
                    }
                    return None;
                }
                if self.phases.contains_key(&at) {
                    return None;
                }
                self.phases.insert(at, token);
                format!(
                    "phase: {}",
                    v["element"]["name"]
                        .as_str()
                        .unwrap_or_else(|| v["element"]["id"].as_str().unwrap_or("?"))
                )
            }
            "instance_finished" => {
                let instance = v["instance"].as_i64().unwrap_or_default();
                self.phases.retain(|(i, _), _| *i != instance);
                return None;
            }
            "completed" => match self.reader.resource(&v)? {
                "world_model.select_site" => format!(
                    "site {} selected ({})",
                    v["output"]["selected_site"]["site_id"],
                    v["output"]["selected_site"]["material"]
                        .as_str()
                        .unwrap_or("?")
                ),
                "instrument.analyze" => {
                    self.samples += 1;
                    format!("sample analysed ({} so far)", self.samples)
                }
                "power.read_battery" => {
                    // One line per 10 % of charge used.
                    let soc = v["output"]["battery"]["soc_pct"].as_f64().unwrap_or(100.0);
                    let decile = (soc / 10.0).floor() as i64;
                    if decile >= self.decile.unwrap_or(10) {
                        return None;
                    }
                    self.decile = Some(decile);
                    format!("battery {soc:.1} %")
                }
                _ => return None,
            },
            "failed" => format!(
                "fault: {} on {}",
                v["code"].as_str().unwrap_or("?"),
                self.reader.resource(&v).unwrap_or("?")
            ),
            "caught" if v["what"] != "timer" => format!(
                "handled: {} {} by {}",
                v["what"].as_str().unwrap_or("?"),
                v["name"].as_str().unwrap_or(""),
                v["element"]["id"].as_str().unwrap_or("?")
            ),
            _ => return None,
        };
        Some(format!("  day {d:5.2}  {said}"))
    }
}

/// The end-of-flight summary, from the record.
pub fn summarize(record: &Path, summary: &crate::driver::Summary) -> String {
    let mut reader = crate::record::Reader::default();
    let text = std::fs::read_to_string(record).unwrap_or_default();
    let lines: Vec<Value> = text.lines().filter_map(|l| reader.read(l)).collect();
    let (mut analysed, mut faults, mut handled) = (0, BTreeMap::<String, usize>::new(), 0);
    let mut battery = None;
    let mut contingencies = Vec::new();
    for v in &lines {
        match v["kind"].as_str() {
            Some("completed") => match reader.resource(v) {
                Some("instrument.analyze") => analysed += 1,
                Some("power.read_battery") => {
                    battery = v["output"]["battery"]["soc_pct"].as_f64().or(battery)
                }
                _ => {}
            },
            Some("failed") => {
                *faults
                    .entry(format!(
                        "{} on {}",
                        v["code"].as_str().unwrap_or("?"),
                        reader.resource(v).unwrap_or("?")
                    ))
                    .or_default() += 1
            }
            Some("caught") if v["what"] == "error" || v["what"] == "escalation" => handled += 1,
            Some("thrown") if v["what"] == "signal" || v["what"] == "escalation" => contingencies
                .push(format!(
                    "{} {}",
                    v["what"].as_str().unwrap_or("?"),
                    v["name"].as_str().unwrap_or("?")
                )),
            _ => {}
        }
    }
    let t0 = lines
        .first()
        .and_then(|v| v["mission_ms"].as_i64())
        .unwrap_or(0);
    let days = lines.last().map_or(0.0, |v| day(v, t0));
    let mut out = String::from("\nmission summary\n");
    for (i, o) in &summary.outcomes {
        out += &format!("  outcome:           instance {i} {o:?}\n");
    }
    out += &format!("  mission time:      {days:.1} days\n");
    out += &format!("  samples analysed:  {analysed}\n");
    if faults.is_empty() {
        out += "  faults:            none\n";
    } else {
        out += &format!(
            "  faults:            {} met, {handled} caught by the model's boundaries\n",
            faults.values().sum::<usize>()
        );
        for (f, n) in &faults {
            out += &format!("                     {n} × {f}\n");
        }
    }
    if !contingencies.is_empty() {
        out += &format!("  contingencies:     {}\n", contingencies.join(", "));
    }
    if let Some(b) = battery {
        out += &format!("  energy left:       {b:.1} % at the last battery reading\n");
    }
    out += &format!("  execution record:  {}\n", record.display());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(seq: u64, kind: &str, id: &str, token: u64) -> String {
        serde_json::json!({
            "v": 1, "kind": kind, "seq": seq, "idx": 0, "instance": 1, "token": token,
            "mission_ms": 86_400_000 * seq,
            "element": {"id": id, "name": id, "type": "subProcess"},
        })
        .to_string()
    }

    #[test]
    fn a_phase_is_shown_when_it_opens_not_again_while_it_is_open() {
        let mut p = Progress::default();
        let shown: Vec<String> = [
            entry(0, "entered", "Collect", 8),
            // The instances of a multi-instance phase enter it again.
            entry(1, "entered", "Collect", 21),
            entry(2, "entered", "Collect", 30),
            entry(3, "entered", "Monitor", 4),
            entry(4, "left", "Collect", 8),
            // The next pass through the phase is a new phase line.
            entry(5, "entered", "Collect", 8),
            entry(6, "withdrawn", "Collect", 8),
            entry(7, "entered", "Collect", 9),
        ]
        .iter()
        .filter_map(|l| p.line(l))
        .collect();
        assert_eq!(
            shown,
            [
                "  day  0.00  phase: Collect",
                "  day  3.00  phase: Monitor",
                "  day  5.00  phase: Collect",
                "  day  7.00  phase: Collect",
            ]
        );
    }

    #[test]
    fn scenarios_are_built_in_and_files_override_them() {
        let dir = std::env::temp_dir().join(format!("trace-fly-scenario-{}", std::process::id()));
        let s = Scenario::load("deadline", &dir).expect("built in");
        assert_eq!((s.seed, s.profile.as_str()), (1, "quiet"));
        assert!(s.faults.is_file());
        let file = dir.join("mine.json");
        std::fs::write(
            &file,
            r#"{"description": "mine", "seed": 7, "profile": "demanding", "faults": []}"#,
        )
        .expect("write");
        let s = Scenario::load(&file.display().to_string(), &dir).expect("a file");
        assert_eq!((s.seed, s.description.as_str()), (7, "mine"));
        let e = Scenario::load("nosuch", &dir).expect_err("unknown");
        assert!(e.to_string().contains("stuck-tool-recovered"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_flight_id_is_one_key_chunk() {
        assert_eq!(chunk("my mission 2-17/x"), "my-mission-2-17-x");
        assert!(connector_api::keys::check_chunk(&chunk("a*b$c#d?e f@")).is_ok());
    }
}
