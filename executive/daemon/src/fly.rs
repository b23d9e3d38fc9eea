//! `trace fly`: one command for a whole mission on one host — starts the lander simulator and
//! a ground station answering by policy as separate processes, runs the executive against them over
//! Zenoh (embedded defaults: peers on loopback, no router), shows progress from the execution
//! record as the mission advances, and ends with a summary.

use std::collections::BTreeMap;
use std::io::{BufRead, Seek};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serde_json::Value;

/// How to fly (the flags of `trace fly`).
#[derive(Clone, Debug, clap::Args)]
pub struct FlyOptions {
    /// The mission model.
    #[arg(default_value = "deploy/missions/europa-bsm1.bpmn")]
    pub mission: PathBuf,
    /// Working directory for the stores and the record (default: `flights/<mission>-<time>`);
    /// it must not hold a previous flight.
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Connector configuration.
    #[arg(long, default_value = "deploy/connectors.toml")]
    pub connectors: PathBuf,
    /// The policy of the ground station `trace fly` starts.
    #[arg(long, default_value = "deploy/ground/policy.toml")]
    pub ground_policy: PathBuf,
    /// Start no ground station: answer the user tasks from another terminal with
    /// `ground-station --interactive`, or let the model's timers decide.
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
    /// A named scenario from deploy/scenarios/ (seed, profile and scripted faults), e.g.
    /// `stuck-tool-recovered`; overrides --seed, --profile and --faults.
    #[arg(long)]
    pub scenario: Option<String>,
    /// Zenoh flags for the executive (the systems connect to its first listen endpoint).
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

/// A named scenario (`deploy/scenarios/<name>.json`): seed, profile and scripted faults.
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
    /// Reads `deploy/scenarios/<name>.json` and writes its faults into `dir`.
    pub fn load(name: &str, dir: &Path) -> Result<Scenario, FlyError> {
        let bad = |reason: String| FlyError::Dir(format!("scenario `{name}`: {reason}"));
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(bad("names are letters, digits, - and _".into()));
        }
        let path = Path::new("deploy/scenarios").join(format!("{name}.json"));
        let text =
            std::fs::read_to_string(&path).map_err(|e| bad(format!("{}: {e}", path.display())))?;
        let v: Value =
            serde_json::from_str(&text).map_err(|e| bad(format!("{}: {e}", path.display())))?;
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

/// A sibling binary of the running `trace`.
fn sibling(name: &str) -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(|d| d.join(name)))
        .filter(|p| p.exists())
        .unwrap_or_else(|| PathBuf::from(name))
}

fn start(program: &str, args: &[String], log: &Path) -> Result<Child, FlyError> {
    let err = |reason: String| FlyError::Spawn {
        program: program.to_owned(),
        reason,
    };
    let log = std::fs::File::create(log).map_err(|e| err(e.to_string()))?;
    let mut copy = log.try_clone().map_err(|e| err(e.to_string()))?;
    let mut child = Command::new(sibling(program))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(log)
        .spawn()
        .map_err(|e| {
            err(format!(
                "{e} (build it with `cargo build --release --workspace --bins`)"
            ))
        })?;
    let mut line = String::new();
    let out = child.stdout.take().ok_or_else(|| err("no stdout".into()))?;
    let mut out = std::io::BufReader::new(out);
    out.read_line(&mut line).map_err(|e| err(e.to_string()))?;
    if !line.starts_with("ready") {
        let _ = child.kill();
        return Err(err(
            "exited before serving (see its log in the flight directory)".into(),
        ));
    }
    // What it prints after that (a ground station's answers) goes to its log.
    std::thread::spawn(move || std::io::copy(&mut out, &mut copy));
    Ok(child)
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
    let dir = opts.dir.clone().unwrap_or_else(|| {
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let stem = opts
            .mission
            .file_stem()
            .map_or_else(|| "mission".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("flights").join(format!("{stem}-{stamp}"))
    });
    if let Some(name) = &opts.scenario {
        let s = Scenario::load(name, &dir)?;
        println!("scenario {name}: {}", s.description);
        (opts.seed, opts.profile, opts.faults) = (s.seed, s.profile, Some(s.faults));
    }
    fly_in(&opts, &dir)
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
    let hub = opts
        .zenoh
        .listen
        .first()
        .cloned()
        .unwrap_or_else(|| connector_zenoh::DEFAULT_HUB.to_owned());
    let mut sim_args = vec![
        "--speed".to_owned(),
        opts.speed.to_string(),
        "--seed".into(),
        opts.seed.to_string(),
        "--profile".into(),
        opts.profile.clone(),
        "--store".into(),
        dir.join("sim").display().to_string(),
        "-e".into(),
        hub.clone(),
    ];
    if let Some(f) = &opts.faults {
        sim_args.extend(["--faults".to_owned(), f.display().to_string()]);
    }
    let mut children = Children(Vec::new());
    children
        .0
        .push(start("elap-sim", &sim_args, &dir.join("elap-sim.log"))?);
    if !opts.no_ground {
        children.0.push(start(
            "ground-station",
            &[
                "--policy".to_owned(),
                opts.ground_policy.display().to_string(),
                "--station".into(),
                "fly-policy".into(),
                "-e".into(),
                hub.clone(),
            ],
            &dir.join("ground.log"),
        )?);
    }
    let record = dir.join("store").join("record.jsonl");
    println!(
        "flying {} — simulator, {} and executive as separate processes on {hub}",
        opts.mission.display(),
        if opts.no_ground {
            "no ground station (answer with `ground-station --interactive`)"
        } else {
            "a policy ground station"
        }
    );
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (record, stop) = (record.clone(), Arc::clone(&stop));
        std::thread::spawn(move || progress(&record, &stop))
    };
    let mut zenoh = opts.zenoh.clone();
    if zenoh.listen.is_empty() && zenoh.connect.is_empty() {
        zenoh.listen = vec![hub];
    }
    let result = crate::driver::run(&crate::driver::RunOptions {
        model: Some(opts.mission.clone()),
        store: dir.join("store"),
        record: None,
        script: None,
        connectors: Some(opts.connectors.clone()),
        zenoh,
        catalogue_wait: Duration::from_secs(30),
        speed: 1.0,
        snapshot_every: 1000,
    });
    stop.store(true, Ordering::SeqCst);
    let _ = watcher.join();
    drop(children);
    let summary = result?;
    print!("{}", summarize(&record, &summary));
    let page = dir.join("timeline.html");
    match crate::timeline::write(&record, &page) {
        Ok(_) => println!("  timeline:          {}", page.display()),
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
    let mut t0 = None;
    let mut reader = crate::record::Reader::default();
    let mut samples = 0;
    let mut last_decile = 10;
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
                let entry = reader.read(&partial);
                partial.clear();
                let Some(v) = entry else { continue };
                let t = *t0.get_or_insert(v["mission_ms"].as_i64().unwrap_or(0));
                let d = day(&v, t);
                match v["kind"].as_str() {
                    Some("entered") => {
                        let ty = v["element"]["type"].as_str().unwrap_or_default();
                        if matches!(ty, "subProcess" | "callActivity" | "transaction") {
                            println!(
                                "  day {d:5.2}  phase: {}",
                                v["element"]["name"]
                                    .as_str()
                                    .unwrap_or_else(|| v["element"]["id"].as_str().unwrap_or("?"))
                            );
                        }
                    }
                    Some("completed") => match reader.resource(&v) {
                        Some("world_model.select_site") => println!(
                            "  day {d:5.2}  site {} selected ({})",
                            v["output"]["selected_site"]["site_id"],
                            v["output"]["selected_site"]["material"]
                                .as_str()
                                .unwrap_or("?")
                        ),
                        Some("instrument.analyze") => {
                            samples += 1;
                            println!("  day {d:5.2}  sample analysed ({samples} so far)");
                        }
                        Some("power.read_battery") => {
                            // One line per 10 % of charge used.
                            let soc = v["output"]["battery"]["soc_pct"].as_f64().unwrap_or(100.0);
                            let decile = (soc / 10.0).floor() as i64;
                            if decile < last_decile {
                                last_decile = decile;
                                println!("  day {d:5.2}  battery {soc:.1} %");
                            }
                        }
                        _ => {}
                    },
                    Some("failed") => println!(
                        "  day {d:5.2}  fault: {} on {}",
                        v["code"].as_str().unwrap_or("?"),
                        reader.resource(&v).unwrap_or("?")
                    ),
                    Some("caught") if v["what"] != "timer" => println!(
                        "  day {d:5.2}  handled: {} {} by {}",
                        v["what"].as_str().unwrap_or("?"),
                        v["name"].as_str().unwrap_or(""),
                        v["element"]["id"].as_str().unwrap_or("?")
                    ),
                    _ => {}
                }
            }
        }
        if done {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
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
