//! `trace fly --fleet`: the two-vehicle mission (`deploy/missions/europa-fleet.bpmn`) on one
//! host. Five processes: the lander and scout simulators (`elap-sim`, `elap-sim --vehicle
//! scout`), a ground station answering by policy, the scout's executive (`trace run
//! --participant scout`), and this process, the lander's executive. The two executives meet
//! through the mission's message flows (`docs/protocol.md` §8c); the summary is per vehicle,
//! with the messages that crossed between them.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serde_json::Value;

use super::{Children, FlyError, FlyOptions, Net, built_in, program, progress, start};

/// The two-vehicle mission, built in.
pub(super) const MISSION: (&str, &str) = (
    "europa-fleet.bpmn",
    include_str!("../../../../deploy/missions/europa-fleet.bpmn"),
);

/// The lander executive's connectors (`deploy/fleet/lander.toml`), built in.
const LANDER: &str = include_str!("../../../../deploy/fleet/lander.toml");

/// The scout executive's connectors (`deploy/fleet/scout.toml`), built in.
const SCOUT: &str = include_str!("../../../../deploy/fleet/scout.toml");

/// The pools of the built-in mission, and what each vehicle is called.
const POOLS: [&str; 2] = ["lander", "scout"];

/// How long the scout's executive may take to end after the lander's has.
const SCOUT_ENDS_WITHIN: Duration = Duration::from_secs(60);

/// Flies the two-vehicle mission in `dir`.
pub(super) fn fly(opts: &FlyOptions, dir: &Path) -> Result<(), FlyError> {
    let (mission, shown) = super::mission_file(opts, dir, MISSION)?;
    let lander = match &opts.connectors {
        Some(c) => c.clone(),
        None => built_in(dir, "lander-connectors.toml", LANDER)?,
    };
    let scout = built_in(dir, "scout-connectors.toml", SCOUT)?;
    let net = Net::new(&opts.zenoh)?;
    let deployment = net.exec.deployment();
    // One mission time for the fleet: both vehicles land at the same moment, and the scout's
    // clock is the lander's.
    let landed = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis())
        .to_string();
    let simulator = |vehicle: &str, store: &str, faults: &Option<std::path::PathBuf>| {
        let mut args = vec![
            "--start-ms".to_owned(),
            landed.clone(),
            "--vehicle".into(),
            vehicle.to_owned(),
            "--speed".into(),
            opts.speed.to_string(),
            "--seed".into(),
            opts.seed.to_string(),
            "--profile".into(),
            opts.profile.clone(),
            "--store".into(),
            dir.join(store).display().to_string(),
        ];
        args.extend(net.systems.iter().cloned());
        if let Some(f) = faults {
            args.extend(["--faults".to_owned(), f.display().to_string()]);
        }
        if vehicle == "scout" {
            args.extend(["--clock-of".to_owned(), "lander_sim".into()]);
        }
        args
    };
    let mut children = Children(Vec::new());
    children.0.push(start(
        "elap-sim",
        &simulator("lander", "sim", &opts.faults),
        &dir.join("elap-sim.log"),
    )?);
    children.0.push(start(
        "elap-sim",
        &simulator("scout", "scout-sim", &opts.scout_faults),
        &dir.join("scout-sim.log"),
    )?);
    children.0.extend(super::ground(opts, dir, &net)?);
    let scout_exec = scout_executive(&mission, &scout, dir, &net)?;
    say!(
        "flying {shown} as a fleet — the lander's and the scout's simulators and executives, \
         {}, each a separate process on {}, deployment {deployment}",
        if opts.no_ground {
            "no ground station"
        } else {
            "a policy ground station"
        },
        net.hub,
    );
    let join = net.join(opts);
    if opts.no_ground {
        say!("  answer the user tasks with: ground-station --interactive {join}");
    }
    say!("  watch with:                 trace monitor {join}");
    let record = dir.join("store").join("record.jsonl");
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
        connectors: Some(lander),
        zenoh: net.exec,
        catalogue_wait: Duration::from_secs(30),
        speed: 1.0,
        snapshot_every: 1000,
        participant: Some(POOLS[0].to_owned()),
    });
    stop.store(true, Ordering::SeqCst);
    let _ = watcher.join();
    let scout_end = ends(scout_exec, SCOUT_ENDS_WITHIN);
    drop(children);
    let summary = result?;
    say!(
        "{}",
        super::summarize(&record, &summary).trim_end_matches('\n')
    );
    let scout_record = dir.join("scout").join("record.jsonl");
    {
        use std::io::Write as _;
        let _ = write!(
            std::io::stdout(),
            "{}",
            vehicles(&[(POOLS[0], &record), (POOLS[1], &scout_record)])
        );
    }
    if let Err(why) = scout_end {
        say!(
            "  the scout's executive: {why} (its log: {})",
            dir.join("scout.log").display()
        );
    }
    let page = dir.join("timeline.html");
    let records = [
        (POOLS[0].to_owned(), record),
        (POOLS[1].to_owned(), scout_record),
    ];
    match crate::timeline::write_fleet(&records, &page) {
        Ok(_) => say!("  timeline (both vehicles): {}", page.display()),
        Err(e) => tracing::warn!(error = %e, "timeline not written"),
    }
    Ok(())
}

/// The scout's executive: `trace run MISSION --participant scout`, its output in `scout.log`.
fn scout_executive(
    mission: &Path,
    connectors: &Path,
    dir: &Path,
    net: &Net,
) -> Result<Child, FlyError> {
    let log = dir.join("scout.log");
    let err = |reason: String| FlyError::Spawn {
        program: "trace (the scout's executive)".to_owned(),
        reason,
    };
    let file = std::fs::File::create(&log).map_err(|e| err(e.to_string()))?;
    let copy = file.try_clone().map_err(|e| err(e.to_string()))?;
    Command::new(program("trace"))
        .arg("run")
        .arg(mission)
        .args(["--participant", POOLS[1], "--catalogue-wait", "30"])
        .arg("--store")
        .arg(dir.join("scout"))
        .arg("--connectors")
        .arg(connectors)
        .args(&net.systems)
        .stdout(file)
        .stderr(copy)
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| err(e.to_string()))
}

/// Waits at most `within` for `child` to end successfully (its exit, waited for on a thread,
/// is the event); kills it otherwise.
fn ends(mut child: Child, within: Duration) -> Result<(), String> {
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait());
    });
    match rx.recv_timeout(within) {
        Ok(Ok(s)) if s.success() => Ok(()),
        Ok(Ok(s)) => Err(format!("ended with {s}")),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            Err(format!("still running after {within:?}; stopped"))
        }
    }
}

/// Per vehicle: how its part ended, its mission time, and the messages it sent (delivered,
/// refused) and took from the other vehicle.
pub fn vehicles(records: &[(&str, &Path)]) -> String {
    let mut out = String::from("\nvehicles\n");
    for (name, record) in records {
        let mut reader = crate::record::Reader::default();
        let text = std::fs::read_to_string(record).unwrap_or_default();
        let lines: Vec<Value> = text.lines().filter_map(|l| reader.read(l)).collect();
        let count = |pred: &dyn Fn(&Value) -> bool| lines.iter().filter(|v| pred(v)).count();
        let keys = |kind: &str| {
            lines
                .iter()
                .filter(|v| v["kind"] == kind)
                .filter_map(|v| v["key"].as_str())
                .collect::<std::collections::BTreeSet<_>>()
                .len()
        };
        let outcomes: Vec<String> = lines
            .iter()
            .filter(|v| v["kind"] == "instance_finished")
            .map(|v| match v["outcome"]["type"].as_str() {
                Some("failed") => {
                    format!("failed {}", v["outcome"]["code"].as_str().unwrap_or("?"))
                }
                Some(t) => t.to_owned(),
                None => "?".to_owned(),
            })
            .collect();
        let span = match (
            lines.iter().find_map(|v| v["mission_ms"].as_i64()),
            lines.iter().rev().find_map(|v| v["mission_ms"].as_i64()),
        ) {
            (Some(a), Some(b)) => (b - a) as f64 / 3_600_000.0,
            _ => 0.0,
        };
        let received = count(&|v| v["kind"] == "caught" && v["what"] == "message");
        let tasks = count(&|v| v["kind"] == "completed");
        let faults = count(&|v| v["kind"] == "failed");
        out += &format!(
            "  {name:<7} {}; {span:.1} h of mission time; {tasks} activities, {faults} failed; \
             messages: {} sent ({} delivered, {} refused), {received} received\n",
            if outcomes.is_empty() {
                "no instance".to_owned()
            } else {
                outcomes.join(", ")
            },
            keys("message_sent"),
            keys("message_delivered"),
            lines
                .iter()
                .filter(|v| v["kind"] == "message_refused" && v["by"] == "sender")
                .count(),
        );
        out += &format!("          record: {}\n", record.display());
    }
    out
}
