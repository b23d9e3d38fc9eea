//! `trace verify`: loads and validates a mission model, translates it to PROMELA, checks it with
//! Spin, and prints every property with its verdict, states and time; a violation's
//! counterexample is printed as BPMN steps and written as JSON beside the model's PROMELA, in a
//! work directory outside the model's folder (see [`default_work_dir`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use executive_verify::{Bounds, Limits, Outcome, Verdict};

/// How to verify (the flags of `trace verify`).
#[derive(Clone, Debug, clap::Args)]
pub struct VerifyOptions {
    /// The mission model.
    pub mission: PathBuf,
    /// The mission's requirements (default: `<mission>.req.toml` beside the model, if there).
    #[arg(long)]
    pub requirements: Option<PathBuf>,
    /// Where the PROMELA model, pan's output, trails and counterexamples go (default: a
    /// directory per model under the system's temporary directory,
    /// `trace-verify-<mission>-<hash>`, never beside the model; the report names it).
    #[arg(long, visible_alias = "work-dir")]
    pub dir: Option<PathBuf>,
    /// How often a cycle (a retry, a loop body) may repeat per scope activation (every branch
    /// is still explored with 1; more repetitions multiply the states).
    #[arg(long, default_value_t = 1)]
    pub loops: u8,
    /// pan's maximum search depth.
    #[arg(long, default_value_t = 1_000_000)]
    pub depth: u64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also explore the executive's own engine (no translation) and compare its verdicts.
    #[arg(long)]
    pub native: bool,
}

/// Why verification could not give verdicts.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// The model file could not be read.
    #[error("{0}")]
    Read(String),
    /// The model is invalid.
    #[error(
        "{path}: the mission model is invalid ({first}); run `trace validate` for every problem"
    )]
    Invalid {
        /// The file.
        path: String,
        /// Its first error.
        first: String,
    },
    /// Elements the translation does not cover.
    #[error("{path}: cannot verify these elements:\n{}", .refusals.iter().map(|r| format!("  {r}")).collect::<Vec<_>>().join("\n"))]
    Refused {
        /// The file.
        path: String,
        /// Every refusal.
        refusals: Vec<executive_verify::Refusal>,
    },
    /// Spin failed.
    #[error(transparent)]
    Spin(#[from] executive_verify::SpinError),
    /// The requirements file is unusable.
    #[error(transparent)]
    Requirements(#[from] executive_verify::RequirementsError),
}

/// The result: every property, and where the work files are.
#[derive(Debug, serde::Serialize)]
pub struct Report {
    /// The model.
    pub mission: String,
    /// The requirements file read, if any.
    pub requirements: Option<PathBuf>,
    /// Outcomes in order.
    pub properties: Vec<Outcome>,
    /// The work directory.
    pub dir: PathBuf,
    /// End events some run reaches, according to Spin.
    pub ends: std::collections::BTreeSet<String>,
    /// The native exploration, when asked for.
    pub native: Option<executive_verify::Exploration>,
}

impl Report {
    /// Exit status: 0 all hold, 1 something violated, 2 something incomplete.
    pub fn exit_code(&self) -> u8 {
        if self
            .properties
            .iter()
            .any(|o| o.verdict == Verdict::Violated)
        {
            1
        } else if self
            .properties
            .iter()
            .any(|o| matches!(o.verdict, Verdict::Incomplete(_)))
        {
            2
        } else {
            0
        }
    }
}

/// Verifies a mission model.
pub fn verify(opts: &VerifyOptions) -> Result<Report, VerifyError> {
    let path = &opts.mission;
    let loaded = crate::validate::load_file(path, &executive_model::Options::default())
        .map_err(|e| VerifyError::Read(format!("{}: {e}", path.display())))?;
    let req_file = opts.requirements.clone().or_else(|| {
        let beside = path.with_extension("req.toml");
        beside.exists().then_some(beside)
    });
    let requirements = match req_file {
        Some(f) => {
            let text =
                std::fs::read_to_string(&f).map_err(|e| executive_verify::RequirementsError {
                    path: f.display().to_string(),
                    reason: e.to_string(),
                })?;
            Some((f, text))
        }
        None => None,
    };
    verify_loaded(Job {
        mission: path.display().to_string(),
        loaded,
        requirements,
        dir: opts.dir.clone().unwrap_or_else(|| default_work_dir(path)),
        loops: opts.loops,
        depth: opts.depth,
        native: opts.native,
    })
}

/// One verification of a model already read (`trace verify`, and the studio's, which holds
/// the model and its requirements as text).
pub struct Job {
    /// The model's name in the report (its path).
    pub mission: String,
    /// The model as loaded.
    pub loaded: executive_model::Loaded,
    /// The requirements file's path (for messages and the report) and its text.
    pub requirements: Option<(PathBuf, String)>,
    /// Where the work files go.
    pub dir: PathBuf,
    /// As [`VerifyOptions::loops`].
    pub loops: u8,
    /// As [`VerifyOptions::depth`].
    pub depth: u64,
    /// As [`VerifyOptions::native`].
    pub native: bool,
}

/// Verifies a loaded model against its requirements.
pub fn verify_loaded(job: Job) -> Result<Report, VerifyError> {
    let Some(graph) = job.loaded.graph else {
        let first = job
            .loaded
            .diagnostics
            .iter()
            .find(|d| d.severity == executive_model::Severity::Error)
            .map(|d| d.message.clone())
            .unwrap_or_default();
        return Err(VerifyError::Invalid {
            path: job.mission,
            first,
        });
    };
    let loaded = match &job.requirements {
        Some((f, text)) => {
            executive_verify::requirements::parse(text, &f.display().to_string(), &graph)?
        }
        None => Default::default(),
    };
    let reqs = loaded.requirements;
    let (atoms, formulas) = executive_verify::requirements::shared_atoms(&reqs);
    let t = executive_verify::translate(
        &graph,
        Bounds { loops: job.loops },
        &atoms,
        &loaded.variables,
    )
    .map_err(|refusals| VerifyError::Refused {
        path: job.mission.clone(),
        refusals,
    })?;
    let ltls = executive_verify::requirements::claims(&reqs, &formulas, &t);
    let dir = job.dir;
    let limits = Limits {
        depth: job.depth,
        ..Limits::default()
    };
    let checked = executive_verify::check(&t, &ltls, &dir, limits)?;
    let properties = checked.properties;
    let graph = std::sync::Arc::new(graph);
    let native = job
        .native
        .then(|| executive_verify::explore(std::sync::Arc::clone(&graph), 2_000_000));
    for o in &properties {
        if !o.counterexample.is_empty() {
            let file = dir.join(format!("{}.counterexample.json", o.name));
            let _ = std::fs::write(&file, serde_json::to_string_pretty(o).unwrap_or_default());
            let record = dir.join(format!("{}.counterexample.jsonl", o.name));
            let _ = std::fs::write(&record, as_record(&o.counterexample, &graph));
        }
    }
    Ok(Report {
        mission: job.mission,
        requirements: job.requirements.map(|(f, _)| f),
        properties,
        dir,
        ends: checked.ends,
        native,
    })
}

/// The work directory when none is given: outside the model's folder, so verifying a mission
/// kept in a repository leaves the repository clean. It sits in the system's temporary
/// directory (`$TMPDIR`, else `/tmp`), named after the model and a hash of its absolute path and
/// the user's home: one per model and user, reused (and overwritten) by the next run of the same
/// model, so repeated runs do not pile up.
pub fn default_work_dir(model: &Path) -> PathBuf {
    let absolute = std::fs::canonicalize(model)
        .or_else(|_| std::path::absolute(model))
        .unwrap_or_else(|_| model.to_path_buf());
    let home = std::env::var_os("HOME").unwrap_or_default();
    // FNV-1a: stable across builds and platforms (std's hasher is not promised to be).
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for b in absolute
        .as_os_str()
        .as_encoded_bytes()
        .iter()
        .chain([0u8].iter())
        .chain(home.as_encoded_bytes())
    {
        hash = (hash ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    let stem = model
        .file_stem()
        .map_or_else(|| "mission".into(), |s| s.to_string_lossy());
    std::env::temp_dir().join(format!("trace-verify-{stem}-{hash:016x}"))
}

/// A counterexample as an execution record (one minute of mission time per step), so
/// `trace timeline` draws it like a flown mission: activities as bars, boundaries and lost
/// signals as markers.
pub fn as_record(
    steps: &[executive_verify::TraceStep],
    g: &executive_model::ProcessGraph,
) -> String {
    use executive_model::NodeKind;
    use serde_json::json;
    let mut out = String::new();
    let mut tokens = std::collections::BTreeMap::new();
    for (i, s) in steps.iter().enumerate() {
        let at = i as i64 * 60_000;
        // Record lines are told apart by (seq, idx): one step's lines get their own indices.
        let mut idx = 0;
        let mut line = |extra: serde_json::Value, at: i64| {
            let mut v = json!({"v": 1, "seq": i + 1, "idx": idx, "mission_ms": at});
            idx += 1;
            if let (Some(o), Some(e)) = (v.as_object_mut(), extra.as_object()) {
                o.extend(e.clone());
            }
            out.push_str(&v.to_string());
            out.push('\n');
        };
        let Some(st) = &s.step else {
            if let Some(sig) = s.marker.strip_prefix("LOST ") {
                line(
                    json!({"kind": "caught", "what": "lost signal", "name": sig,
                    "element": {"id": "", "name": format!("lost {sig}"), "type": "boundaryEvent"}}),
                    at,
                );
            }
            continue;
        };
        let Some(node) = g.node_by_id(&st.element).map(|n| g.node(n)) else {
            continue;
        };
        let element = json!({"id": st.element, "name": st.name,
            "type": node.kind.element_name()});
        let key = format!("{}{}", st.path, st.element);
        let resource = match &node.kind {
            NodeKind::Task(t) => t.binding.as_ref().and_then(|b| b.resource.clone()),
            _ => None,
        }
        .unwrap_or_else(|| format!("model.{}", st.element));
        let scope = matches!(
            node.kind,
            NodeKind::SubProcess(_) | NodeKind::CallActivity(_)
        );
        let dispatched = json!({"kind": "dispatched", "task": key,
            "resource": resource, "element": element});
        match st.phase.as_str() {
            "activate" => {
                let token = tokens.len() as i64 + 1;
                tokens.insert(key, token);
                line(
                    json!({"kind": "entered", "token": token, "element": element}),
                    at,
                );
            }
            "complete" if scope => {
                if let Some(token) = tokens.remove(&key) {
                    line(
                        json!({"kind": "left", "token": token, "element": element}),
                        at,
                    );
                }
            }
            "start" => line(dispatched, at),
            "complete" => line(json!({"kind": "completed", "task": key}), at),
            "run" => {
                line(dispatched, at);
                line(json!({"kind": "completed", "task": key}), at + 30_000);
            }
            p if p.starts_with("fail[") => line(
                json!({"kind": "failed", "task": key,
                "code": p.trim_start_matches("fail[").trim_end_matches(']'),
                "message": "a failure the model catches"}),
                at,
            ),
            "fire" => {
                let NodeKind::Boundary(be) = &node.kind else {
                    continue;
                };
                line(
                    json!({"kind": "caught", "what": "boundary", "name": st.name,
                    "element": element}),
                    at,
                );
                // An interrupted scope ends here.
                let holder = g.node(be.attached_to);
                let key = format!("{}{}", st.path, holder.id);
                if let Some(token) = tokens.remove(&key) {
                    line(
                        json!({"kind": "withdrawn", "token": token,
                        "element": {"id": holder.id, "name": holder.label(),
                            "type": holder.kind.element_name()}}),
                        at,
                    );
                }
            }
            _ => {}
        }
    }
    out
}

/// Prints a report for people.
pub fn print(report: &Report, out: &mut dyn Write) -> std::io::Result<()> {
    match &report.requirements {
        Some(r) => writeln!(out, "verify {} with {} (Spin)", report.mission, r.display())?,
        None => writeln!(
            out,
            "verify {} (Spin; no requirements file)",
            report.mission
        )?,
    }
    if let Some(n) = &report.native {
        writeln!(
            out,
            "native exploration of the engine: {} states{}",
            n.states,
            if n.complete { "" } else { " (incomplete)" }
        )?;
        if let Some(why) = &n.needs_data {
            writeln!(out, "  cannot explore without data: {why}")?;
        }
        let verdict = |bad: bool| if bad { "VIOLATED" } else { "holds" };
        writeln!(out, "  {:<12} no_deadlock", verdict(n.deadlock.is_some()))?;
        if let Some(p) = &n.deadlock {
            writeln!(out, "               {}", p.join(" → "))?;
        }
        writeln!(out, "  {:<12} safe", verdict(n.unsafe_run.is_some()))?;
        if let Some(p) = &n.unsafe_run {
            writeln!(out, "               {}", p.join(" → "))?;
        }
        writeln!(
            out,
            "  {:<12} no_dead_activities{}",
            verdict(!n.dead_activities.is_empty()),
            if n.dead_activities.is_empty() {
                String::new()
            } else {
                format!(" (never started: {})", n.dead_activities.join(", "))
            }
        )?;
        writeln!(
            out,
            "  end events reached: {} (Spin: {})",
            n.ends.iter().cloned().collect::<Vec<_>>().join(", "),
            report.ends.iter().cloned().collect::<Vec<_>>().join(", ")
        )?;
    }
    for o in &report.properties {
        let verdict = match &o.verdict {
            Verdict::Holds => "holds".to_owned(),
            Verdict::Violated => "VIOLATED".to_owned(),
            Verdict::Incomplete(why) => format!("incomplete ({why})"),
        };
        writeln!(
            out,
            "  {verdict:<12} {:<20} {} states, {:.2} s — {}",
            o.name, o.states, o.seconds, o.description
        )?;
        if let Some(d) = &o.detail {
            writeln!(out, "               {d}")?;
        }
        if !o.counterexample.is_empty() {
            writeln!(out, "               counterexample:")?;
            for (i, s) in o.counterexample.iter().enumerate() {
                let what = match &s.step {
                    Some(st) => format!("{}{} ({}) {}", st.path, st.element, st.name, st.phase),
                    None => s.marker.clone(),
                };
                let cycle = if s.cycle_start {
                    "  <- cycle starts"
                } else {
                    ""
                };
                writeln!(out, "               {:>3}. {what}{cycle}", i + 1)?;
            }
            let file = Path::new(&report.dir).join(format!("{}.counterexample", o.name));
            writeln!(
                out,
                "               (JSON: {}.json; as a record for `trace timeline`: {}.jsonl)",
                file.display(),
                file.display()
            )?;
        }
    }
    writeln!(
        out,
        "work files (PROMELA, pan's output, trails): {}",
        report.dir.display()
    )?;
    Ok(())
}
