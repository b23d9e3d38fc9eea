//! Running Spin: `spin -a`, two compiles of `pan.c` (safety without claims, and with the LTL
//! claims), one `pan` run per property with the right flags, and the output read back — pan
//! exits 0 even when it finds an error, so verdicts come from its text: `errors: N`, what kind
//! of error, whether the search was complete (`../shared/design/verification.md` §6). A
//! violation's trail is replayed (`spin -t -T`) into BPMN steps.

use std::path::Path;
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
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TraceStep {
    /// The marker as printed (`ExcavateCall/RemoveMaterial.start`).
    pub marker: String,
    /// The BPMN step it stands for (absent for `start`, `ended`, lost signals).
    pub step: Option<Step>,
    /// The liveness counterexample's cycle starts here.
    pub cycle_start: bool,
    /// Mission time and energy at this step (timed requirements' counterexamples).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resources: Option<crate::timed::Resources>,
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
    /// A safety formula on the end of a run that agrees with `formula` wherever every run ends
    /// (`requirements::Form::at_end`): where the built-in `completes` holds, it decides the
    /// claim without a search for acceptance cycles.
    pub at_end: Option<String>,
}

/// How hard pan may search.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// `-m`: maximum search depth.
    pub depth: u64,
    /// `-w`: 2^bits hash table slots.
    pub hash_bits: u32,
    /// Expect millions of states (a deeper loop bound): compile pan with `-O2` (its compile
    /// costs seconds, repaid several times over on a large search) and a larger hash table.
    pub deep: bool,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            depth: 1_000_000,
            hash_bits: 22,
            deep: false,
        }
    }
}

impl Limits {
    /// The C compiler's optimisation flag for pan.
    fn opt(&self) -> &'static str {
        if self.deep { "-O2" } else { "-O0" }
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
            let rest = l
                .strip_suffix(suffix)
                .or_else(|| l.find(suffix).map(|i| &l[..i]))?;
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

/// Runs the `pan` binary at `binary` (a path, absolute when `dir` is not its folder) in `dir`,
/// where it writes its trails.
fn pan(dir: &Path, binary: &str, args: &[&str], limits: Limits) -> Result<PanRun, SpinError> {
    let depth = format!("-m{}", limits.depth);
    let bits = format!(
        "-w{}",
        if limits.deep {
            limits.hash_bits.max(26)
        } else {
            limits.hash_bits
        }
    );
    let mut all = vec![depth.as_str(), "-b", bits.as_str()];
    all.extend_from_slice(args);
    let t = Instant::now();
    let (_, text) = run(dir, binary, &all)?;
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

/// Replays a trail (in `dir`, against its `mission.pml`) into BPMN steps.
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
                resources: None,
            });
        }
    }
    Ok(steps)
}

/// The steps no run takes, from pan's list of unreached statements (by PROMELA line: every
/// step is written on a line of its own; a step written on several lines — an activity entered
/// along several flows — is unreached only if all of them are; an activity entered inside
/// another step's branch is unreached only if its witnesses are too).
fn unreached(text: &str, t: &Translation) -> std::collections::BTreeSet<String> {
    let mut lines = std::collections::BTreeSet::new();
    let mut witnesses = std::collections::BTreeSet::new();
    let mut in_mission = false;
    for line in text.lines() {
        if line.starts_with("unreached in ") {
            in_mission = line.starts_with("unreached in proctype Mission");
            continue;
        }
        // A start step's first effect takes its incoming token: if that is unreached, so is
        // the step (other statements on the line may be branches never taken).
        let takes = line.contains("-1)\"");
        let number = line
            .trim()
            .strip_prefix("mission.pml:")
            .and_then(|r| r.split(',').next())
            .and_then(|n| n.parse::<usize>().ok());
        if in_mission
            && let Some(k) = line
                .split("\"entry = ")
                .nth(1)
                .and_then(|r| r.split('"').next())
                .and_then(|k| k.parse::<usize>().ok())
        {
            witnesses.insert(k);
        }
        if in_mission
            && takes
            && let Some(n) = number.filter(|n| t.lines.contains_key(n))
        {
            lines.insert(n);
        }
    }
    let reached: std::collections::BTreeSet<&String> = t
        .lines
        .iter()
        .filter(|(n, _)| !lines.contains(*n))
        .map(|(_, m)| m)
        .chain(
            t.witnesses
                .iter()
                .enumerate()
                .filter(|(k, _)| !witnesses.contains(k))
                .map(|(_, m)| m),
        )
        .collect();
    lines
        .iter()
        .filter_map(|n| t.lines.get(n))
        .chain(witnesses.iter().filter_map(|k| t.witnesses.get(*k)))
        .filter(|m| !reached.contains(m))
        .cloned()
        .collect()
}

/// The activities no run starts.
fn dead_activities(unreached: &std::collections::BTreeSet<String>, t: &Translation) -> Vec<String> {
    let mut dead = Vec::new();
    for (key, name) in &t.activities {
        let starts: Vec<&String> = t
            .steps
            .iter()
            .filter(|(_, s)| {
                format!("{}{}", s.path, s.element) == *key
                    && matches!(s.phase.as_str(), "start" | "activate" | "run")
            })
            .map(|(m, _)| m)
            .collect();
        if !starts.is_empty() && starts.iter().all(|m| unreached.contains(*m)) {
            dead.push(format!("{key} ({name})"));
        }
    }
    dead
}

/// The errors a `-c0 -e` run reported: (kind, trail file), in order.
fn errors_found(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut kind = None;
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("pan:")
            && let Some((n, what)) = rest.split_once(": ")
            && n.parse::<u64>().is_ok()
        {
            kind = Some(what.to_owned());
        } else if let Some(file) = line.strip_prefix("pan: wrote ")
            && let Some(k) = kind.take()
        {
            out.push((k, file.trim().to_owned()));
        }
    }
    out
}

fn write(path: &Path, text: &str) -> Result<(), SpinError> {
    std::fs::write(path, text).map_err(|e| SpinError::Io(format!("{}: {e}", path.display())))
}

/// Checks the built-in properties and `requirements` with Spin, working in `dir` (kept, so the
/// models, pan's output, trails and counterexamples can be inspected): one exhaustive safety
/// search (`dir/safety`: deadlocks, unsafe flows, unreached activities, every error kept) and
/// one search per LTL claim (`dir/ltl`).
pub fn check(
    t: &Translation,
    requirements: &[Ltl],
    dir: &Path,
    limits: Limits,
) -> Result<Checked, SpinError> {
    let (sdir, ldir) = (dir.join("safety"), dir.join("ltl"));
    for d in [&sdir, &ldir] {
        std::fs::create_dir_all(d).map_err(|e| SpinError::Io(format!("{}: {e}", d.display())))?;
        for entry in std::fs::read_dir(d).into_iter().flatten().flatten() {
            if entry.file_name().to_string_lossy().contains(".trail") {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
    let mut ltls = vec![Ltl {
        name: COMPLETES.into(),
        description: "every run of the mission ends (no run is stuck or runs forever)".into(),
        formula: "<> ended".into(),
        at_end: None,
    }];
    if t.signals {
        ltls.push(Ltl {
            name: "no_lost_signal".into(),
            description: "no signal is thrown while nothing that catches it is listening".into(),
            formula: "[] !lost".into(),
            at_end: None,
        });
    }
    ltls.extend(requirements.iter().cloned());
    // A liveness claim with a form on the end of a run is searched as that safety claim; its
    // own search runs only if `completes` does not hold (`Ltl::at_end`).
    let at_end: Vec<Ltl> = ltls
        .iter()
        .filter(|l| !safe_claim(l))
        .filter_map(|l| {
            l.at_end.as_ref().map(|f| Ltl {
                name: format!("{}{AT_END}", l.name),
                description: l.description.clone(),
                formula: f.clone(),
                at_end: None,
            })
        })
        .collect();
    let deferred = |l: &Ltl| !safe_claim(l) && l.at_end.is_some();
    // The safety claims (no `<>`: a violation is a finite run) are searched together, as their
    // conjunction, without pan's search for acceptance cycles; each alone only if it fails.
    let safeties: Vec<&Ltl> = ltls
        .iter()
        .filter(|l| safe_claim(l))
        .chain(at_end.iter())
        .collect();
    let mut ltl_model = t.ltl_model();
    for l in ltls.iter().chain(at_end.iter()) {
        ltl_model.push_str(&format!("ltl {} {{ {} }}\n", l.name, l.formula));
    }
    if safeties.len() > 1 {
        let all: Vec<String> = safeties
            .iter()
            .map(|l| format!("({})", l.formula))
            .collect();
        ltl_model.push_str(&format!("ltl {ALL_SAFETY} {{ {} }}\n", all.join(" && ")));
    }
    write(&sdir.join("mission.pml"), &t.promela)?;
    write(&ldir.join("mission.pml"), &ltl_model)?;
    must(&ldir, "spin", &["-a", "mission.pml"])?;
    must(
        &ldir,
        "gcc",
        &[limits.opt(), "-DVECTORSZ=4096", "-o", "pan", "pan.c"],
    )?;
    // The searches are independent: two workers share them, one starting with the safety
    // search (`-O0` by default: pan.c compiles in a fifth of the time of `-O2`, which wins for
    // the state spaces of bounded models; `Limits::deep` says when it does not).
    let mut jobs: Vec<Job> = Vec::new();
    if safeties.len() > 1 {
        jobs.push(Job::AllSafety);
    } else {
        jobs.extend(
            ltls.iter()
                .filter(|l| safe_claim(l))
                .cloned()
                .map(Job::Claim),
        );
    }
    jobs.extend(
        ltls.iter()
            .filter(|l| !safe_claim(l) && !deferred(l))
            .cloned()
            .map(Job::Claim),
    );
    let queue = std::sync::Mutex::new(jobs.into_iter().enumerate().collect::<Vec<_>>());
    // Each worker runs the one binary in its own folder, where pan writes its trail. (Not a
    // copy of the binary: a file this process holds open for writing cannot be executed by a
    // child forked meanwhile — `Text file busy`.)
    let binary = std::path::absolute(ldir.join("pan"))
        .map_err(|e| SpinError::Io(e.to_string()))?
        .to_string_lossy()
        .into_owned();
    let worker = |w: usize| -> Result<Vec<(usize, Vec<Outcome>)>, SpinError> {
        let wdir = ldir.join(format!("w{w}"));
        std::fs::create_dir_all(&wdir).map_err(|e| SpinError::Io(e.to_string()))?;
        // Trails are replayed here too: spin writes its preprocessed model (`pan.pre`) in
        // the directory it runs in, so two replays in one directory at once collide.
        write(&wdir.join("mission.pml"), &ltl_model)?;
        let mut done = Vec::new();
        loop {
            let next = {
                let mut q = queue
                    .lock()
                    .map_err(|_| SpinError::Io("a worker died".into()))?;
                if q.is_empty() {
                    break;
                }
                q.remove(0)
            };
            let (k, job) = next;
            done.push((
                k,
                run_job(t, &job, &safeties, &binary, &wdir, ldir.as_path(), limits)?,
            ));
        }
        Ok(done)
    };
    let (safety, claims) = std::thread::scope(|scope| {
        let other = scope.spawn(|| {
            let safety = safety_search(t, &sdir, limits);
            (safety, worker(1))
        });
        let mine = worker(0);
        let (safety, theirs) = other.join().unwrap_or_else(|_| {
            (
                Err(SpinError::Io("a search panicked".into())),
                Ok(Vec::new()),
            )
        });
        let mut all = mine.and_then(|mut a| {
            a.extend(theirs?);
            Ok(a)
        });
        if let Ok(a) = &mut all {
            a.sort_by_key(|(k, _)| *k);
        }
        (safety, all)
    });
    let (mut properties, ends) = safety?;
    let mut found: Vec<Outcome> = claims?.into_iter().flat_map(|(_, o)| o).collect();
    // Every run ends: the claims searched on the end of a run are decided. Otherwise their own
    // searches run now.
    let every_run_ends = found
        .iter()
        .any(|o| o.name == COMPLETES && o.verdict == Verdict::Holds);
    let mut again = Vec::new();
    for l in ltls.iter().filter(|l| deferred(l)) {
        let end_name = format!("{}{AT_END}", l.name);
        match found.iter().position(|o| o.name == end_name) {
            Some(i) if every_run_ends => {
                let mut o = found.remove(i);
                o.name = l.name.clone();
                let how = "decided on the end of every run, since every run ends";
                o.detail = Some(match o.detail.take() {
                    Some(d) => format!("{d}; {how}"),
                    None => how.to_owned(),
                });
                found.push(o);
            }
            _ => {
                found.retain(|o| o.name != end_name);
                again.push((again.len(), Job::Claim(l.clone())));
            }
        }
    }
    if !again.is_empty() {
        *queue
            .lock()
            .map_err(|_| SpinError::Io("a worker died".into()))? = again;
        let (a, b) = std::thread::scope(|scope| {
            let other = scope.spawn(|| worker(1));
            let mine = worker(0);
            (
                mine,
                other
                    .join()
                    .unwrap_or_else(|_| Err(SpinError::Io("a search panicked".into()))),
            )
        });
        found.extend(a?.into_iter().chain(b?).flat_map(|(_, o)| o));
    }
    // In the order the claims were given.
    for l in &ltls {
        if let Some(o) = found.iter().find(|o| o.name == l.name) {
            properties.push(o.clone());
        }
    }
    Ok(Checked { properties, ends })
}

/// The name of the conjunction of the safety claims.
const ALL_SAFETY: &str = "all_safety_claims";

/// The built-in claim that every run ends.
const COMPLETES: &str = "completes";

/// What a claim's form on the end of a run is named after it.
const AT_END: &str = "_at_end";

/// A claim without `<>`: a safety property (a violation is a finite run).
fn safe_claim(l: &Ltl) -> bool {
    !l.formula.contains("<>")
}

/// One search a claims worker makes.
enum Job {
    /// Every safety claim at once.
    AllSafety,
    /// One claim.
    Claim(Ltl),
}

/// Runs one job in worker directory `wdir`; its outcomes (the conjunction's: one per safety
/// claim, each searched alone when the conjunction fails).
fn run_job(
    t: &Translation,
    job: &Job,
    safeties: &[&Ltl],
    binary: &str,
    wdir: &Path,
    ldir: &Path,
    limits: Limits,
) -> Result<Vec<Outcome>, SpinError> {
    match job {
        Job::Claim(l) => Ok(vec![claim(t, l, binary, wdir, ldir, limits)?]),
        Job::AllSafety => {
            let r = pan(wdir, binary, &["-N", ALL_SAFETY], limits)?;
            write(&ldir.join(format!("{ALL_SAFETY}.out")), &r.text)?;
            if r.errors == 0 || r.incomplete.is_some() {
                return Ok(safeties
                    .iter()
                    .map(|l| {
                        let mut o = outcome(&l.name, &l.description, &r, false);
                        o.detail = Some("searched with the other safety claims at once".into());
                        o
                    })
                    .collect());
            }
            let _ = std::fs::remove_file(wdir.join("mission.pml.trail"));
            safeties
                .iter()
                .map(|l| claim(t, l, binary, wdir, ldir, limits))
                .collect()
        }
    }
}

/// What Spin found.
#[derive(Clone, Debug, Serialize)]
pub struct Checked {
    /// Every property, built-in ones first.
    pub properties: Vec<Outcome>,
    /// End events some run reaches (element ids).
    pub ends: std::collections::BTreeSet<String>,
}

fn outcome(name: &str, description: &str, r: &PanRun, violated: bool) -> Outcome {
    Outcome {
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
    }
}

/// No deadlock, safeness and no dead activities from one exhaustive search that continues
/// past errors (each error's trail kept).
fn safety_search(
    t: &Translation,
    sdir: &Path,
    limits: Limits,
) -> Result<(Vec<Outcome>, std::collections::BTreeSet<String>), SpinError> {
    must(sdir, "spin", &["-a", "mission.pml"])?;
    must(
        sdir,
        "gcc",
        &[
            limits.opt(),
            "-DVECTORSZ=4096",
            "-DSAFETY",
            "-DNOCLAIM",
            "-o",
            "pan",
            "pan.c",
        ],
    )?;

    let mut out = Vec::new();
    let r = pan(sdir, "./pan", &["-c0", "-e"], limits)?;
    write(&sdir.join("pan.out"), &r.text)?;
    let errors = errors_found(&r.text);
    let first = |what: &str| errors.iter().find(|(k, _)| k.starts_with(what));
    for (name, description, kind, note) in [
        (
            "no_deadlock",
            "no run gets stuck with tokens left that can never move",
            "invalid end state",
            "tokens are left where nothing can move them",
        ),
        (
            "safe",
            "no sequence flow ever holds two tokens (no unsafe merge)",
            "assertion violated",
            "a sequence flow receives a second token",
        ),
    ] {
        let found = first(kind);
        let mut o = outcome(name, description, &r, found.is_some());
        if let Some((_, trail)) = found {
            o.detail = Some(note.to_owned());
            o.counterexample = replay(sdir, trail, t)?;
        }
        out.push(o);
    }
    let skipped = unreached(&r.text, t);
    let dead = dead_activities(&skipped, t);
    let mut o = outcome(
        "no_dead_activities",
        "every activity is started in some run",
        &r,
        !dead.is_empty() && r.incomplete.is_none(),
    );
    if !dead.is_empty() {
        o.detail = Some(format!("never started: {}", dead.join(", ")));
    }
    out.push(o);
    // End events some run reaches.
    let ends = t
        .steps
        .iter()
        .filter(|(m, st)| st.phase == "end" && !skipped.contains(*m))
        .map(|(_, st)| st.element.clone())
        .collect();
    Ok((out, ends))
}

/// One claim's search in worker directory `wdir` (its output and trail kept in `ldir`).
fn claim(
    t: &Translation,
    l: &Ltl,
    binary: &str,
    wdir: &Path,
    ldir: &Path,
    limits: Limits,
) -> Result<Outcome, SpinError> {
    let args: &[&str] = if safe_claim(l) {
        &["-N", &l.name]
    } else {
        &["-a", "-N", &l.name]
    };
    let r = pan(wdir, binary, args, limits)?;
    write(&ldir.join(format!("{}.out", l.name)), &r.text)?;
    let violated = r.errors > 0 && r.incomplete.is_none();
    let mut o = outcome(&l.name, &l.description, &r, violated);
    if violated {
        o.detail = Some(if r.text.contains("acceptance cycle") {
            "a run that never satisfies it (acceptance cycle)".to_owned()
        } else {
            "a run that breaks it".to_owned()
        });
        o.counterexample = replay(wdir, "mission.pml.trail", t)?;
        let trail = format!("{}.trail", l.name);
        std::fs::rename(wdir.join("mission.pml.trail"), ldir.join(&trail))
            .map_err(|e| SpinError::Io(e.to_string()))?;
    }
    Ok(o)
}
