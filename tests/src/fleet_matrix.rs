//! The fleet's crash matrix: the two-vehicle Europa mission (`deploy/missions/europa-fleet.bpmn`)
//! flown by its five processes on loopback — both simulators, a ground station, the lander's
//! and the scout's executives — with SIGKILLs mid-exchange of the lander's executive, the
//! scout's executive or the scout's simulator, each victim restarted on its store; then judged
//! from both executives' records: did both parts end, did each request the lander sent start
//! exactly one survey, did each report the scout sent reach the lander exactly once, and was a
//! goal lost. The scout finds the first two sites unsafe, so each flight has three exchanges.
//! Used by the crash bench and, reduced, by the integration tests.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::matrix::{Proc, Rng, lines, system, until};
use crate::{bin, repo};

/// Which process is killed, mid-exchange.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Victim {
    /// The lander's executive, while its survey request is out.
    LanderExecutive,
    /// The scout's executive, while it works on a request.
    ScoutExecutive,
    /// The scout's simulator, while one of its activities runs.
    ScoutSimulator,
}

impl Victim {
    /// Every kind, in report order.
    pub const ALL: [Victim; 3] = [
        Victim::LanderExecutive,
        Victim::ScoutExecutive,
        Victim::ScoutSimulator,
    ];

    /// Its name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Victim::LanderExecutive => "lander executive mid-exchange",
            Victim::ScoutExecutive => "scout executive mid-exchange",
            Victim::ScoutSimulator => "scout simulator mid-survey",
        }
    }
}

/// How a fleet flight went.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Flight {
    /// Kills made.
    pub kills: usize,
    /// Both executives ended (successfully) within the bound.
    pub ended: bool,
    /// How the lander's part ended (`completed`, …).
    pub outcome: Option<String>,
    /// Survey requests the lander sent (distinct keys) and that were applied.
    pub requests: usize,
    /// Surveys the scout started: one per request applied.
    pub surveys: usize,
    /// Reports the scout sent (distinct keys).
    pub reports: usize,
    /// Reports the lander took.
    pub heard: usize,
    /// Messages refused by their receiver.
    pub refused: usize,
    /// Goals lost (a task failed with a protocol code) in either vehicle.
    pub lost: usize,
}

impl Flight {
    /// Nothing lost, nothing applied twice, nothing misrouted: every request started exactly
    /// one survey, every report was heard exactly once, nothing refused, no goal lost.
    pub fn exact(&self) -> bool {
        self.ended
            && self.requests == self.surveys
            && self.reports == self.heard
            && self.refused == 0
            && self.lost == 0
    }
}

/// The simulation speed: 2,000 mission ms per wall ms (a survey takes about a second).
const SPEED: &str = "2000";

/// The scout's findings: the first two sites unsafe, the third safe (`elap-sim --faults`).
pub const SCOUT_FAULTS: &str = r#"{"faults": [
  {"action": "survey.site", "call": 1, "code": "UNSAFE"},
  {"action": "survey.site", "call": 2, "code": "UNSAFE"},
  {"action": "survey.site", "call": 3, "code": "SAFE"}]}"#;

struct Fleet {
    dir: PathBuf,
    hub: String,
}

impl Fleet {
    /// The Zenoh flags of a process: the lander's executive listens, the others connect.
    fn joined(&self, listen: bool) -> [&str; 3] {
        let flag = if listen { "-l" } else { "-e" };
        [flag, &self.hub, "--no-multicast-scouting"]
    }

    /// A system, started and waited for (its `ready` line).
    fn system(&self, program: &str, args: &[String]) -> Proc {
        let mut c = Command::new(bin(program));
        c.args(args).args(self.joined(false));
        system(program, c)
    }

    fn simulator(&self, vehicle: &str) -> Proc {
        let mut args = vec![
            "--vehicle".to_owned(),
            vehicle.into(),
            "--speed".into(),
            SPEED.into(),
            "--profile".into(),
            "quiet".into(),
            "--store".into(),
            self.dir
                .join(format!("{vehicle}-sim"))
                .display()
                .to_string(),
        ];
        if vehicle == "scout" {
            args.extend([
                "--faults".into(),
                self.dir.join("scout-faults.json").display().to_string(),
                "--clock-of".into(),
                "lander_sim".into(),
            ]);
        }
        self.system("elap-sim", &args)
    }

    fn ground(&self) -> Proc {
        let policy = repo().join("deploy/ground/policy.toml");
        self.system(
            "ground-station",
            &[
                "--policy".into(),
                policy.display().to_string(),
                "--station".into(),
                "station-a".into(),
                "--store".into(),
                self.dir.join("ground").display().to_string(),
            ],
        )
    }

    /// The executive of `pool`: `trace run` (`resume`: `trace resume`), its log appended.
    fn executive(&self, pool: &str, resume: bool) -> Proc {
        let mut c = Command::new(bin("trace"));
        if resume {
            c.arg("resume");
        } else {
            c.arg("run")
                .arg(repo().join("deploy/missions/europa-fleet.bpmn"))
                .args(["--participant", pool]);
        }
        c.arg("--store")
            .arg(self.dir.join(pool))
            .args(["--catalogue-wait", "30"])
            .arg("--connectors")
            .arg(repo().join(format!("deploy/fleet/{pool}.toml")))
            .args(self.joined(pool == "lander"));
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(self.dir.join(format!("{pool}.log")))
            .expect("executive log");
        Proc(Some(
            c.stdout(Stdio::null())
                .stderr(log)
                .spawn()
                .expect("trace starts"),
        ))
    }

    fn record(&self, pool: &str) -> PathBuf {
        self.dir.join(pool).join("record.jsonl")
    }
}

fn keys(lines: &[Value], kind: &str) -> BTreeSet<String> {
    lines
        .iter()
        .filter(|v| v["kind"] == kind)
        .filter_map(|v| v["key"].as_str().map(str::to_owned))
        .collect()
}

fn count(lines: &[Value], pred: impl Fn(&Value) -> bool) -> usize {
    lines.iter().filter(|v| pred(v)).count()
}

/// Whether a scout activity (hop or survey) has been dispatched and not ended.
fn scout_busy(lines: &[Value]) -> bool {
    let mut open = BTreeSet::new();
    for v in lines {
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str() {
            Some("dispatched") if v["resource"] != "power.read_battery" => {
                open.insert(task);
            }
            Some("completed" | "failed" | "cancelled") => {
                open.remove(&task);
            }
            _ => {}
        }
    }
    !open.is_empty()
}

/// Flies the fleet once in a fresh `dir`, with `kills` kills of `victim` (at most one per
/// exchange, in exchanges 1, 2, 3), giving up after `bound`.
pub fn fly(dir: &Path, seed: u64, victim: Victim, kills: usize, bound: Duration) -> Flight {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).expect("flight dir");
    std::fs::write(dir.join("scout-faults.json"), SCOUT_FAULTS).expect("faults");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port");
    let f = Fleet {
        dir: dir.to_owned(),
        hub: format!("tcp/127.0.0.1:{port}"),
    };
    let deadline = Instant::now() + bound;
    let mut made = 0;
    let mut lander = f.executive("lander", false);
    let _lander_sim = f.simulator("lander");
    let mut scout_sim = f.simulator("scout");
    let _ground = f.ground();
    let mut scout = f.executive("scout", false);
    let mut rng = Rng(seed.wrapping_mul(31).wrapping_add(victim as u64));
    for k in 0..kills.min(3) {
        // The exchange: the lander's (k+1)-th request is out, or the scout works on it.
        let ready = |l: &[Value]| match victim {
            Victim::LanderExecutive => keys(l, "message_sent").len() > k,
            Victim::ScoutExecutive => count(l, |v| v["kind"] == "instance_started") > k,
            Victim::ScoutSimulator => {
                count(l, |v| v["kind"] == "instance_started") > k && scout_busy(l)
            }
        };
        let (exec, record) = match victim {
            Victim::LanderExecutive => (&mut lander, f.record("lander")),
            _ => (&mut scout, f.record("scout")),
        };
        if !until(exec, &record, deadline, |l, _| ready(l)) {
            break;
        }
        // Where in the exchange the kill lands: a seeded 0 to 300 ms on (a survey takes about a
        // second). This pause is the kill point's choice, not a wait for an event.
        std::thread::sleep(Duration::from_millis(rng.next() % 300));
        made += 1;
        match victim {
            Victim::LanderExecutive => {
                lander.kill();
                lander = f.executive("lander", true);
            }
            Victim::ScoutExecutive => {
                scout.kill();
                scout = f.executive("scout", true);
            }
            Victim::ScoutSimulator => {
                scout_sim.kill();
                scout_sim = f.simulator("scout");
            }
        }
    }
    // Both executives end once both parts have ended.
    let mut ended = true;
    for p in [&mut lander, &mut scout] {
        if let Some(child) = p.0.take() {
            let left = deadline.saturating_duration_since(Instant::now());
            ended &= crate::ended(child, left).is_some_and(|s| s.success());
        }
    }
    let flight = Flight {
        kills: made,
        ended,
        ..judge(&lines(&f.record("lander")), &lines(&f.record("scout")))
    };
    if !flight.exact() {
        eprintln!("fleet flight in {}: {flight:?}", dir.display());
    }
    flight
}

/// What the lander's and the scout's records (`lander`, `scout`) say of a fleet flight: its
/// outcome, requests and surveys, reports sent and heard, refusals and lost goals (no kills; the
/// flight counted as ended).
pub fn judge(l: &[Value], s: &[Value]) -> Flight {
    let lost = |lines: &[Value]| {
        count(lines, |v| {
            v["kind"] == "failed"
                && matches!(
                    v["code"].as_str(),
                    Some("CONNECTOR_LOST" | "NOT_ACCEPTED" | "PROTOCOL_ERROR")
                )
        })
    };
    Flight {
        kills: 0,
        ended: true,
        outcome: l
            .iter()
            .rfind(|v| v["kind"] == "instance_finished")
            .and_then(|v| v["outcome"]["type"].as_str().map(str::to_owned)),
        requests: keys(l, "message_delivered").len(),
        surveys: count(s, |v| v["kind"] == "instance_started"),
        reports: keys(s, "message_delivered").len(),
        heard: count(l, |v| {
            v["kind"] == "caught" && v["what"] == "message" && v["name"] == "survey_report"
        }),
        refused: count(l, |v| v["kind"] == "message_refused")
            + count(s, |v| v["kind"] == "message_refused"),
        lost: lost(l) + lost(s),
    }
}
