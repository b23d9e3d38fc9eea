//! Running Spin: `spin -a`, two compiles of `pan.c` (safety without claims, and with the LTL
//! claims), one `pan` run per property with the right flags, and the output read back — pan
//! exits 0 even when it finds an error, so verdicts come from its text: `errors: N`, what kind
//! of error, whether the search was complete (`../shared/design/verification.md` §6). A
//! violation's trail is replayed (`spin -t -T`) into BPMN steps.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde::Serialize;

use crate::promela::{Step, Translation};

/// Spin or the C compiler could not be run.
#[derive(Debug, thiserror::Error)]
pub enum SpinError {
    /// A tool is missing.
    #[error(
        "`{tool}` was not found: install it (Debian: `apt-get install spin gcc`) to verify with Spin"
    )]
    Missing {
        /// Which tool.
        tool: String,
    },
    /// A tool failed.
    #[error("`{command}` failed: {output}")]
    Failed {
        /// The command line.
        command: String,
        /// What it printed.
        output: String,
    },
    /// The work directory could not be written.
    #[error("{0}")]
    Io(String),
}

/// A property's verdict.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase", tag = "verdict", content = "why")]
pub enum Verdict {
    /// Checked over every reachable state: it holds.
    Holds,
    /// A counterexample exists.
    Violated,
    /// The search hit a bound (depth, memory): nothing is claimed.
    Incomplete(String),
}

/// One property checked.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// Its name (`no_deadlock`, a requirement's name).
    pub name: String,
    /// What it says, for people.
    pub description: String,
    /// Holds, violated or incomplete.
    #[serde(flatten)]
    pub verdict: Verdict,
    /// States stored.
    pub states: u64,
    /// Transitions explored.
    pub transitions: u64,
    /// Wall time of the pan run.
    pub seconds: f64,
    /// Detail (dead activities, the kind of violation).
    pub detail: Option<String>,
    /// The counterexample as BPMN steps, in order.
    pub counterexample: Vec<TraceStep>,
}

/// One step of a counterexample.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct TraceStep {
    /// The marker as printed (`ExcavateCall/RemoveMaterial.start`).
    pub marker: String,
    /// The BPMN step it stands for (absent for `start`, `ended`, lost signals).
    pub step: Option<Step>,
    /// The liveness counterexample's cycle starts here.
    pub cycle_start: bool,
}

/// An LTL property for Spin.
#[derive(Clone, Debug)]
pub struct Ltl {
    /// Name (a PROMELA identifier).
    pub name: String,
    /// For people.
    pub description: String,
    /// The formula over the model's globals.
    pub formula: String,
}

/// How hard pan may search.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// `-m`: maximum search depth.
    pub depth: u64,
    /// `-w`: 2^bits hash table slots.
    pub hash_bits: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            depth: 1_000_000,
            hash_bits: 22,
        }
    }
}

fn run(dir: &Path, program: &str, args: &[&str]) -> Result<(bool, String), SpinError> {
    let out = Command::new(program)
        .args(args)
        .current_dir(dir)
        .output()
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => SpinError::Missing {
                tool: program.to_owned(),
            },
            _ => SpinError::Io(format!("{program}: {e}")),
        })?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Ok((out.status.success(), text))
}

fn must(dir: &Path, program: &str, args: &[&str]) -> Result<String, SpinError> {
    let (ok, text) = run(dir, program, args)?;
    if ok {
        Ok(text)
    } else {
        Err(SpinError::Failed {
            command: format!("{program} {}", args.join(" ")),
            output: text,
        })
    }
}

fn number_before(text: &str, suffix: &str) -> u64 {
    text.lines()
        .find_map(|l| {
            let l = l.trim();
            let rest = l.strip_suffix(suffix).or_else(|| {
                l.find(suffix).map(|i| &l[..i])
            })?;
            rest.split_whitespace().last()?.parse().ok()
        })
        .unwrap_or(0)
}

/// What one pan run said.
struct PanRun {
    text: String,
    errors: u64,
    states: u64,
    transitions: u64,
    seconds: f64,
    incomplete: Option<String>,
}

fn pan(dir: &Path, binary: &str, args: &[&str], limits: Limits) -> Result<PanRun, SpinError> {
    let depth = format!("-m{}", limits.depth);
    let bits = format!("-w{}", limits.hash_bits);
    let mut all = vec![depth.as_str(), "-b", bits.as_str()];
    all.extend_from_slice(args);
    let t = Instant::now();
    let (_, text) = run(dir, &format!("./{binary}"), &all)?;
    let seconds = t.elapsed().as_secs_f64();
    let errors = text
        .lines()
        .find_map(|l| l.split("errors: ").nth(1)?.trim().parse().ok())
        .ok_or_else(|| SpinError::Failed {
            command: format!("{binary} {}", all.join(" ")),
            output: text.clone(),
        })?;
    // A bound hit makes an error report meaningless; a search stopped at a real error is
    // "not completed" but its counterexample stands.
    let bound = [
        "max search depth too small",
        "depth limit reached",
        "out of memory",
        "reached -DMEMLIM bound",
    ]
    .iter()
    .find(|m| text.contains(**m))
    .map(|m| (*m).to_owned());
    let incomplete = bound.or_else(|| {
        (errors == 0 && text.contains("Search not completed"))
            .then(|| "Search not completed".to_owned())
    });
    Ok(PanRun {
        errors,
        states: number_before(&text, " states, stored"),
        transitions: number_before(&text, " transitions ("),
        seconds,
        incomplete,
        text,
    })
}

/// Replays the trail of the last failing run into BPMN steps.
fn replay(dir: &Path, trail: &str, t: &Translation) -> Result<Vec<TraceStep>, SpinError> {
    let text = must(dir, "spin", &["-t", "-T", "-k", trail, "mission.pml"])?;
    let mut steps = Vec::new();
    let mut cycle = false;
    for line in text.lines() {
        if line.contains("START OF CYCLE") {
            cycle = true;
            continue;
        }
        let marker = line
            .trim()
            .strip_prefix("@@BPMN ")
            .map(str::to_owned)
            .or_else(|| line.trim().strip_prefix("@@").map(str::to_owned));
        if let Some(marker) = marker {
            steps.push(TraceStep {
                step: t.steps.get(&marker).cloned(),
                marker,
                cycle_start: std::mem::take(&mut cycle),
            });
        }
    }
    Ok(steps)
}

/// The activities no run starts, from pan's list of unreached statements (by PROMELA line:
/// every step is written on a line of its own).
fn dead_activities(text: &str, t: &Translation) -> Vec<String> {
    let mut unreached = std::collections::BTreeSet::new();
    let mut in_mission = false;
    for line in text.lines() {
        if line.starts_with("unreached in ") {
            in_mission = line.starts_with("unreached in proctype Mission");
            continue;
        }
        let number = line
            .trim()
            .strip_prefix("mission.pml:")
            .and_then(|r| r.split(',').next())
            .and_then(|n| n.parse::<usize>().ok());
        if in_mission && let Some(m) = number.and_then(|n| t.lines.get(&n)) {
            unreached.insert(m.clone());
        }
    }
    let mut dead = Vec::new();
    for (key, name) in &t.activities {
        let starts: Vec<&String> = t
            .steps
            .iter()
            .filter(|(_, s)| {
                format!("{}{}", s.path, s.element) == *key
                    && (s.phase == "start" || s.phase == "activate")
            })
            .map(|(m, _)| m)
            .collect();
        if !starts.is_empty() && starts.iter().all(|m| unreached.contains(*m)) {
            dead.push(format!("{key} ({name})"));
        }
    }
    dead
}

/// Checks the built-in properties and `requirements` with Spin, working in `dir` (kept, so the
/// model, trails and pan output can be inspected).
pub fn check(
    t: &Translation,
    requirements: &[Ltl],
    dir: &Path,
    limits: Limits,
) -> Result<Vec<Outcome>, SpinError> {
    std::fs::create_dir_all(dir).map_err(|e| SpinError::Io(format!("{}: {e}", dir.display())))?;
    let mut ltls = vec![Ltl {
        name: "safe".into(),
        description: "no sequence flow ever holds two tokens (no unsafe merge)".into(),
        formula: "[] !unsafe".into(),
    }, Ltl {
        name: "completes".into(),
        description: "every run of the mission ends (no run is stuck or runs forever)".into(),
        formula: "<> ended".into(),
    }];
    if t.signals {
        ltls.push(Ltl {
            name: "no_lost_signal".into(),
            description: "no signal is thrown while nothing that catches it is listening".into(),
            formula: "[] !lost".into(),
        });
    }
    ltls.extend(requirements.iter().cloned());
    let mut model = t.promela.clone();
    for l in &ltls {
        model.push_str(&format!("ltl {} {{ {} }}\n", l.name, l.formula));
    }
    let path: PathBuf = dir.join("mission.pml");
    std::fs::write(&path, &model).map_err(|e| SpinError::Io(format!("{}: {e}", path.display())))?;
    must(dir, "spin", &["-a", "mission.pml"])?;
    must(dir, "gcc", &["-O1", "-DSAFETY", "-DNOCLAIM", "-DVECTORSZ=4096", "-o", "pan_safety", "pan.c"])?;
    must(dir, "gcc", &["-O1", "-DVECTORSZ=4096", "-o", "pan_ltl", "pan.c"])?;

    let mut out = Vec::new();
    let outcome = |name: &str, description: &str, r: &PanRun, violated: bool| Outcome {
        name: name.to_owned(),
        description: description.to_owned(),
        verdict: match (&r.incomplete, violated) {
            (_, true) => Verdict::Violated,
            (Some(why), false) => Verdict::Incomplete(why.clone()),
            (None, false) => Verdict::Holds,
        },
        states: r.states,
        transitions: r.transitions,
        seconds: r.seconds,
        detail: None,
        counterexample: Vec::new(),
    };
    let with_trail = |mut o: Outcome, r: &PanRun, trail: &str| -> Result<Outcome, SpinError> {
        if o.verdict == Verdict::Violated && dir.join("mission.pml.trail").exists() {
            std::fs::rename(dir.join("mission.pml.trail"), dir.join(trail))
                .map_err(|e| SpinError::Io(e.to_string()))?;
            o.counterexample = replay(dir, trail, t)?;
        }
        let _ = std::fs::write(dir.join(format!("{}.out", o.name)), &r.text);
        Ok(o)
    };

    // No deadlock: invalid end states.
    let r = pan(dir, "pan_safety", &[], limits)?;
    let violated = r.errors > 0 && r.text.contains("invalid end state");
    let o = outcome(
        "no_deadlock",
        "no run gets stuck with tokens left that can never move",
        &r,
        violated,
    );
    out.push(with_trail(o, &r, "no_deadlock.trail")?);
    // No dead activities: a full search, errors ignored, then pan's unreached statements.
    let r = pan(dir, "pan_safety", &["-E"], limits)?;
    let dead = dead_activities(&r.text, t);
    let mut o = outcome(
        "no_dead_activities",
        "every activity is started in some run",
        &r,
        !dead.is_empty() && r.incomplete.is_none(),
    );
    if !dead.is_empty() {
        o.detail = Some(format!("never started: {}", dead.join(", ")));
    }
    let _ = std::fs::write(dir.join("no_dead_activities.out"), &r.text);
    out.push(o);
    // LTL: one run per claim.
    for l in &ltls {
        let r = pan(dir, "pan_ltl", &["-a", "-N", &l.name], limits)?;
        let violated = r.errors > 0 && r.incomplete.is_none();
        let mut o = outcome(&l.name, &l.description, &r, violated);
        if violated {
            o.detail = Some(if r.text.contains("acceptance cycle") {
                "a run that never satisfies it (acceptance cycle)".to_owned()
            } else {
                "a run that breaks it".to_owned()
            });
        }
        out.push(with_trail(o, &r, &format!("{}.trail", l.name))?);
    }
    Ok(out)
}
