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
    /// The connectors (routes to the systems) whose catalogues cost the tasks, for requirements
    /// on time and energy: `FILE`, or for a fleet one `POOL=FILE` per pool with a process, each
    /// pool's tasks costed by its own and drawing from its own battery. Default:
    /// `fleet/<pool id>.toml` in the model's folder or the one above when there is one for
    /// every pool of two or more, else `connectors.toml` there.
    #[arg(long, value_name = "[POOL=]FILE")]
    pub connectors: Vec<String>,
    /// Catalogue files or folders of them (default: `catalogues/` beside each connectors file,
    /// or in the folder above it).
    #[arg(long)]
    pub catalogues: Vec<PathBuf>,
    /// States the timed exploration may visit before its verdicts are `incomplete`.
    #[arg(long, default_value_t = 400_000)]
    pub max_states: usize,
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
    /// Requirements read time or energy but the tasks' costs are not known.
    #[error("{path}: requirements on time and energy need every task's cost:\n{}", .problems.iter().map(|p| format!("  {p}")).collect::<Vec<_>>().join("\n"))]
    Costs {
        /// The model.
        path: String,
        /// Every problem.
        problems: Vec<String>,
    },
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
    /// The timed exploration, when requirements read time or energy (their verdicts are in
    /// `properties`).
    pub timed: Option<TimedSummary>,
}

/// What the timed exploration covered.
#[derive(Debug, serde::Serialize)]
pub struct TimedSummary {
    /// States explored.
    pub states: usize,
    /// When runs end and the energy used by then, over every run.
    pub end: Option<executive_verify::timed::Resources>,
    /// Where the costs came from (the connectors file).
    pub connectors: String,
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
    let systems = systems(&loaded, path, &opts.connectors, &opts.catalogues);
    verify_loaded(Job {
        mission: path.display().to_string(),
        loaded,
        requirements,
        dir: opts.dir.clone().unwrap_or_else(|| default_work_dir(path)),
        loops: opts.loops,
        depth: opts.depth,
        native: opts.native,
        systems,
        max_states: opts.max_states,
    })
}

/// The connectors and catalogues that cost the tasks, per vehicle (`connectors`: `FILE` or
/// `POOL=FILE` each): the files named, else one `fleet/<pool>.toml` per pool with a process
/// (two or more) in the model's folder or the one above, else `connectors.toml` there; each
/// file's catalogues are `catalogues/` beside it or in the folder above. `Err` says what is
/// missing or unreadable (only an error when a requirement needs the costs).
pub fn systems(
    loaded: &executive_model::Loaded,
    model: &Path,
    connectors: &[String],
    catalogues: &[PathBuf],
) -> Result<Vec<Systems>, String> {
    let dir = model.parent().unwrap_or(Path::new("."));
    let near = |name: &str| {
        [dir.join(name), dir.join("..").join(name)]
            .into_iter()
            .find(|f| f.exists())
    };
    let with_process: Vec<&executive_model::Participant> = loaded
        .graph
        .iter()
        .flat_map(|g| g.participants())
        .filter(|p| p.process.is_some())
        .collect();
    let pools: Vec<String> = with_process.iter().map(|p| p.id.clone()).collect();
    let files: Vec<(Option<String>, PathBuf)> = if connectors.is_empty() {
        let fleet: Vec<(Option<String>, PathBuf)> = pools
            .iter()
            .filter_map(|p| Some((Some(p.clone()), near(&format!("fleet/{p}.toml"))?)))
            .collect();
        if pools.len() > 1 && fleet.len() == pools.len() {
            fleet
        } else {
            vec![(
                None,
                near("connectors.toml").ok_or_else(|| {
                    format!(
                        "no connectors.toml in {} or the folder above (give --connectors)",
                        dir.display()
                    )
                })?,
            )]
        }
    } else {
        let mut files = Vec::new();
        for c in connectors {
            match c.split_once('=') {
                Some((pool, file)) => {
                    let id = with_process
                        .iter()
                        .find(|p| p.id == pool || p.name.as_deref() == Some(pool))
                        .map(|p| p.id.clone())
                        .ok_or_else(|| {
                            format!(
                                "--connectors {c}: no pool with a process has the id or name `{pool}` (pools: {})",
                                pools.join(", ")
                            )
                        })?;
                    files.push((Some(id), PathBuf::from(file)));
                }
                None => files.push((None, PathBuf::from(c))),
            }
        }
        match files.iter().filter(|(p, _)| p.is_none()).count() {
            0 => {
                let missing: Vec<&String> = pools
                    .iter()
                    .filter(|p| !files.iter().any(|(q, _)| q.as_ref() == Some(*p)))
                    .collect();
                if !missing.is_empty() {
                    return Err(format!(
                        "--connectors names no file for pool(s) {}: give one per pool with a process",
                        missing
                            .iter()
                            .map(|p| format!("`{p}`"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ));
                }
            }
            1 if files.len() == 1 => {}
            _ => {
                return Err(
                    "--connectors: give one FILE for the whole mission, or POOL=FILE for each pool"
                        .to_owned(),
                );
            }
        }
        files
    };
    files
        .into_iter()
        .map(|(pool, file)| {
            let config = crate::catalogues::read_connectors(&file).map_err(|e| e.to_string())?;
            let beside = file.parent().unwrap_or(Path::new("."));
            let paths = if catalogues.is_empty() {
                let here = beside.join("catalogues");
                let above = beside.join("../catalogues");
                vec![if !here.exists() && above.exists() {
                    above
                } else {
                    here
                }]
            } else {
                catalogues.to_vec()
            };
            let read = crate::catalogues::read(&paths).map_err(|e| e.to_string())?;
            let served = crate::catalogues::served(&config, &read);
            Ok(Systems {
                pool,
                source: file.display().to_string(),
                config,
                catalogues: served,
            })
        })
        .collect()
}

/// The systems a mission will drive, as files describe them: the whole mission's, or one pool's.
#[derive(Clone, Debug)]
pub struct Systems {
    /// The pool they serve (`None`: the whole mission).
    pub pool: Option<String>,
    /// Where they were read (the connectors file).
    pub source: String,
    /// Its routes.
    pub config: connector_api::ConnectorsConfig,
    /// Each connector's catalogue, if one was found.
    pub catalogues: Vec<Option<connector_api::Catalogue>>,
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
    /// The systems whose catalogues cost the tasks, per vehicle (`Err`: why they are not
    /// known).
    pub systems: Result<Vec<Systems>, String>,
    /// As [`VerifyOptions::max_states`].
    pub max_states: usize,
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
    let timed_costs = if reqs.iter().any(|r| r.form.timed()) {
        let costs = job
            .systems
            .as_ref()
            .map_err(|e| vec![e.clone()])
            .and_then(|systems| {
                let sources: Vec<executive_verify::resources::Source> = systems
                    .iter()
                    .map(|s| executive_verify::resources::Source {
                        pool: s.pool.as_deref(),
                        config: &s.config,
                        catalogues: &s.catalogues,
                    })
                    .collect();
                let costs = executive_verify::resources::costs(&graph, &sources)?;
                let unread = executive_verify::timed::vehicles(&reqs, &costs);
                if !unread.is_empty() {
                    return Err(unread);
                }
                let from = systems
                    .iter()
                    .map(|s| match &s.pool {
                        Some(p) => format!("{p}: {}", s.source),
                        None => s.source.clone(),
                    })
                    .collect::<Vec<_>>()
                    .join(", ");
                Ok((costs, from))
            });
        Some(costs.map_err(|problems| VerifyError::Costs {
            path: job.mission.clone(),
            problems,
        })?)
    } else {
        None
    };
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
        // Each further repetition per cycle multiplies the states: millions from two on.
        deep: job.loops > 1,
        ..Limits::default()
    };
    let checked = executive_verify::check(&t, &ltls, &dir, limits)?;
    let mut properties = checked.properties;
    let graph = std::sync::Arc::new(graph);
    let timed = timed_costs.map(|(costs, connectors)| {
        let limits = executive_verify::timed::TimedLimits {
            loops: job.loops,
            max_states: job.max_states,
        };
        let t =
            executive_verify::timed::check(std::sync::Arc::clone(&graph), &costs, &reqs, limits);
        properties.extend(t.properties);
        TimedSummary {
            states: t.states,
            end: t.end,
            connectors,
        }
    });
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
        timed,
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
        // A timed counterexample has its times (the latest the step can happen); Spin's
        // steps get one minute each.
        let at = s
            .resources
            .as_ref()
            .map_or(i as i64 * 60_000, |r| r.time_ms.hi.min(9e15) as i64);
        let spent = s
            .resources
            .as_ref()
            .and_then(|r| r.activity_wh)
            .map(|e| json!([round(e.lo), round(e.hi)]));
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
            NodeKind::Task(t) => t.binding.as_ref().and_then(|b| b.resource.as_deref()),
            _ => None,
        }
        .map_or_else(|| format!("model.{}", st.element), str::to_owned);
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
            "complete" => line(
                json!({"kind": "completed", "task": key, "energy_wh": spent}),
                at,
            ),
            "run" => {
                line(dispatched, at);
                line(json!({"kind": "completed", "task": key}), at + 30_000);
            }
            p if p.starts_with("fail[") => line(
                json!({"kind": "failed", "task": key,
                "code": p.trim_start_matches("fail[").trim_end_matches(']'),
                "message": "a failure the model catches", "energy_wh": spent}),
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
        if let Some(r) = &s.resources {
            line(
                json!({"kind": "data", "key": "energy_used_wh", "value": round(r.energy_wh.hi)}),
                at,
            );
            for (pool, e) in &r.vehicles {
                line(
                    json!({"kind": "data", "key": format!("energy_used_wh_{pool}"), "value": round(e.hi)}),
                    at,
                );
            }
        }
    }
    out
}

/// Mission time for people: `3d 04:12`.
fn mission_time(ms: f64) -> String {
    if !ms.is_finite() {
        return "later".into();
    }
    let m = (ms / 60_000.0).round() as i64;
    format!("{}d {:02}:{:02}", m / 1440, (m % 1440) / 60, m % 60)
}

fn round(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
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
    if let Some(t) = &report.timed {
        let end = t.end.as_ref().map_or_else(String::new, |e| {
            let each: Vec<String> = e
                .vehicles
                .iter()
                .map(|(pool, x)| format!("{pool} {:.0} to {:.0}", x.lo, x.hi))
                .collect();
            format!(
                "; runs end between {} and {} having used {:.0} to {:.0} Wh{}",
                mission_time(e.time_ms.lo),
                mission_time(e.time_ms.hi),
                e.energy_wh.lo,
                e.energy_wh.hi,
                if each.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", each.join(", "))
                }
            )
        });
        writeln!(
            out,
            "timed exploration of the engine: {} states, costs from {}{end}",
            t.states, t.connectors
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
            // A long run (weeks of a monitor polling hourly): its start and its end.
            let total = o.counterexample.len();
            for (i, s) in o.counterexample.iter().enumerate() {
                if total > 60 && i == 10 {
                    writeln!(out, "               … {} steps …", total - 50)?;
                }
                if total > 60 && (10..total - 40).contains(&i) {
                    continue;
                }
                let what = match &s.step {
                    Some(st) => format!("{}{} ({}) {}", st.path, st.element, st.name, st.phase),
                    None => s.marker.clone(),
                };
                let cycle = if s.cycle_start {
                    "  <- cycle starts"
                } else {
                    ""
                };
                let at = s.resources.as_ref().map_or_else(String::new, |r| {
                    let energy = if r.vehicles.is_empty() {
                        format!("{:.0} Wh", r.energy_wh.hi)
                    } else {
                        r.vehicles
                            .iter()
                            .map(|(pool, e)| format!("{pool} {:.0} Wh", e.hi))
                            .collect::<Vec<_>>()
                            .join(", ")
                    };
                    format!("  [{}, {energy}]", mission_time(r.time_ms.hi))
                });
                writeln!(out, "               {:>3}. {what}{cycle}{at}", i + 1)?;
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
