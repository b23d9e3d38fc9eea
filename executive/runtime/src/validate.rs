//! `trace validate`: load models and report every diagnostic, for people or for tools.

use std::io::Write;
use std::path::{Path, PathBuf};

use codespan_reporting::diagnostic::{Diagnostic as Report, Label};
use codespan_reporting::files::SimpleFile;
use codespan_reporting::term::{self, Config};
use executive_model::{Category, Diagnostic, Loaded, Options, ProcessGraph, Severity, load_bundle};
use serde::Serialize;

/// The verdict on one file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    /// Loads with no errors (warnings allowed).
    Valid,
    /// Reads as BPMN but has errors.
    Invalid,
    /// Cannot be read at all (missing file, not XML, hostile XML, not BPMN).
    Unreadable,
}

impl Verdict {
    /// The process exit code for this verdict: 0 valid, 1 invalid, 2 unreadable.
    pub fn exit_code(self) -> i32 {
        match self {
            Verdict::Valid => 0,
            Verdict::Invalid => 1,
            Verdict::Unreadable => 2,
        }
    }
}

/// One file's outcome, as printed with `--json`.
#[derive(Debug, Serialize)]
pub struct FileReport {
    /// The path as given.
    pub file: PathBuf,
    /// `valid`, `invalid` or `unreadable`.
    pub verdict: &'static str,
    /// Every diagnostic, in source order.
    pub diagnostics: Vec<Diagnostic>,
}

/// Loads the model at `path` with its imports, read from files relative to it.
pub fn load_file(path: &Path, options: &Options) -> std::io::Result<Loaded> {
    let bytes = std::fs::read(path)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let max = options.limits.max_bytes as u64;
    let mut resolve = |location: &str| -> Result<Vec<u8>, String> {
        let file = dir.join(location);
        let len = std::fs::metadata(&file)
            .map_err(|e| format!("{}: {e}", file.display()))?
            .len();
        if len > max {
            return Err(format!(
                "{} is {len} bytes; the limit is {max}",
                file.display()
            ));
        }
        std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))
    };
    Ok(load_bundle(&bytes, options, &mut resolve))
}

/// Loads `path`; a file that cannot be read becomes an `unreadable` diagnostic.
pub fn check_file(path: &Path, options: &Options) -> (Verdict, Loaded) {
    match load_file(path, options) {
        Ok(loaded) => {
            let verdict = if loaded.unreadable() {
                Verdict::Unreadable
            } else if loaded.graph.is_some() {
                Verdict::Valid
            } else {
                Verdict::Invalid
            };
            (verdict, loaded)
        }
        Err(e) => {
            let d = Diagnostic {
                severity: Severity::Error,
                code: "unreadable",
                category: Category::Bpmn,
                constraint: None,
                message: format!("cannot read {}: {e}", path.display()),
                file: None,
                element: None,
                field: None,
                offset: 0,
                line: 1,
                column: 1,
            };
            (
                Verdict::Unreadable,
                Loaded {
                    graph: None,
                    diagnostics: vec![d],
                    text: String::new(),
                    imports: Vec::new(),
                },
            )
        }
    }
}

/// Writes diagnostics the way rustc does: a headline, the source line and a caret.
pub fn render(out: &mut dyn Write, path: &Path, loaded: &Loaded) -> std::io::Result<()> {
    let config = Config::default();
    for d in &loaded.diagnostics {
        let text = loaded.text_of(d);
        let name = match &d.file {
            None => path.display().to_string(),
            Some(f) => path
                .parent()
                .unwrap_or(Path::new(""))
                .join(f)
                .display()
                .to_string(),
        };
        let file = SimpleFile::new(name, text);
        let report = match d.severity {
            Severity::Error => Report::error(),
            Severity::Warning => Report::warning(),
        };
        let mut code = d.code.to_owned();
        if let Some(c) = d.constraint {
            code = format!("{code}, {c}");
        }
        let mut report = report.with_code(code).with_message(&d.message);
        if !text.is_empty() {
            let start = d.offset.min(text.len());
            let end = text[start..]
                .find(['>', '\n'])
                .map_or(start, |i| start + i + 1);
            let label = match &d.element {
                Some(e) => Label::primary((), start..end).with_message(format!("element `{e}`")),
                None => Label::primary((), start..end),
            };
            report = report.with_labels(vec![label]);
        } else if let Some(e) = &d.element {
            report = report.with_notes(vec![format!("element `{e}`")]);
        }
        term::emit_to_io_write(out, &config, &file, &report).map_err(|e| match e {
            codespan_reporting::files::Error::Io(io) => io,
            other => std::io::Error::other(other),
        })?;
    }
    Ok(())
}

/// A connectors configuration and the catalogue each of its connectors serves.
pub type Resolved = (
    connector_api::ConnectorsConfig,
    Vec<Option<connector_api::Catalogue>>,
);

/// What the mission is checked against besides BPMN: the systems it will run with.
#[derive(Debug, Default, Clone)]
pub struct Systems {
    /// The connectors file; default: `../connectors.toml` beside each model, if it exists.
    pub connectors: Option<PathBuf>,
    /// Catalogue files or directories; default: `../catalogues` and `../ground/forms.json`
    /// beside each model, those that exist.
    pub catalogues: Vec<PathBuf>,
}

impl Systems {
    /// The connectors and their served catalogues for `graph`, read from `path` (none when no
    /// connectors file is given or beside it).
    pub fn resolve(&self, path: &Path, graph: &ProcessGraph) -> Result<Option<Resolved>, String> {
        let up = path.parent().unwrap_or(Path::new("")).join("..");
        // A fleet's pools each run with connectors of their own (`trace run --participant`):
        // one file beside the model is not theirs.
        let fleet = || graph.participants().filter(|p| p.process.is_some()).count() > 1;
        let config = match self
            .connectors
            .clone()
            .or_else(|| Some(up.join("connectors.toml")).filter(|p| p.exists() && !fleet()))
        {
            Some(p) => crate::catalogues::read_connectors(&p).map_err(|e| e.to_string())?,
            None => return Ok(None),
        };
        let paths: Vec<PathBuf> = if self.catalogues.is_empty() {
            [up.join("catalogues"), up.join("ground/forms.json")]
                .into_iter()
                .filter(|p| p.exists())
                .collect()
        } else {
            self.catalogues.clone()
        };
        let mut catalogues = crate::catalogues::read(&paths).map_err(|e| e.to_string())?;
        catalogues.extend(crate::catalogues::generated(&config));
        let served = crate::catalogues::served(&config, &catalogues);
        Ok(Some((config, served)))
    }
}

/// The code of a task that does not fit its system's catalogue.
pub const CATALOGUE_CODE: &str = "catalogue-mismatch";

/// What a valid model's systems add to its diagnostics, as `trace run` checks it before
/// flight: the data checks ([`crate::dataflow`]), then, with connectors, each task that does not
/// fit its catalogue (an error, [`CATALOGUE_CODE`]).
pub fn system_diagnostics(
    graph: &ProcessGraph,
    text: &str,
    config: Option<&connector_api::ConnectorsConfig>,
    catalogues: &[Option<connector_api::Catalogue>],
) -> Vec<Diagnostic> {
    let known = crate::dataflow::Known {
        config,
        catalogues,
        start: None,
    };
    let mut found = crate::dataflow::diagnostics(graph, text, &known);
    if let Some(config) = config {
        let uses = crate::connectors::task_uses(graph);
        for m in connector_api::check(&uses, config, catalogues) {
            found.push(at_task(graph, text, Severity::Error, CATALOGUE_CODE, m));
        }
    }
    found
}

fn at_task(
    graph: &ProcessGraph,
    text: &str,
    severity: Severity,
    code: &'static str,
    m: connector_api::Mismatch,
) -> Diagnostic {
    let offset = graph
        .node_by_id(&m.task)
        .map_or(0, |n| graph.node(n).offset);
    let mut d = crate::dataflow::located(text, severity, code, &m.task, offset, m.problem);
    d.field = m.field;
    d
}

/// [`system_diagnostics`] of a valid model with the systems of `path`, and a warning for each
/// task only the watchdog would end, added to its diagnostics; an error among them makes it
/// invalid.
pub fn check_systems(path: &Path, loaded: &mut Loaded, systems: &Systems) -> Result<(), String> {
    let Some(graph) = &loaded.graph else {
        return Ok(());
    };
    let resolved = systems.resolve(path, graph)?;
    let (config, catalogues) = match &resolved {
        Some((c, cats)) => (Some(c), cats.as_slice()),
        None => (None, &[][..]),
    };
    let mut found = system_diagnostics(graph, &loaded.text, config, catalogues);
    if let Some(config) = config {
        // A task nothing but the watchdog's default ends if its system goes silent.
        let uses = crate::connectors::task_uses(graph);
        for m in connector_api::check::unbounded(&uses, config, catalogues) {
            found.push(at_task(
                graph,
                &loaded.text,
                Severity::Warning,
                "unbounded-task",
                m,
            ));
        }
    }
    loaded.diagnostics.extend(found);
    loaded
        .diagnostics
        .sort_by_key(|d| (d.file.is_some(), d.offset, d.severity));
    Ok(())
}

/// Runs `trace validate` over `files`, printing to `out`; returns the worst verdict. `strict`
/// enforces every rule of the specification (warnings that name a rule become errors); each
/// valid model is also checked against `systems`.
pub fn run(
    files: &[PathBuf],
    json: bool,
    strict: bool,
    systems: &Systems,
    out: &mut dyn Write,
) -> std::io::Result<Verdict> {
    let mut worst = Verdict::Valid;
    let mut reports = Vec::new();
    let options = Options {
        strict,
        ..Options::default()
    };
    for path in files {
        let (mut verdict, mut loaded) = check_file(path, &options);
        if verdict == Verdict::Valid {
            if let Err(e) = check_systems(path, &mut loaded, systems) {
                writeln!(out, "{}: {e}", path.display())?;
                verdict = Verdict::Unreadable;
            } else if loaded.errors().next().is_some() {
                verdict = Verdict::Invalid;
            }
        }
        tracing::debug!(file = %path.display(), ?verdict, diagnostics = loaded.diagnostics.len(), "validated");
        worst = worst.max(verdict);
        if json {
            let verdict = match verdict {
                Verdict::Valid => "valid",
                Verdict::Invalid => "invalid",
                Verdict::Unreadable => "unreadable",
            };
            reports.push(FileReport {
                file: path.clone(),
                verdict,
                diagnostics: loaded.diagnostics,
            });
        } else {
            render(out, path, &loaded)?;
            let errors = loaded.errors().count();
            let warnings = loaded.diagnostics.len() - errors;
            match verdict {
                Verdict::Valid if warnings == 0 => writeln!(out, "{}: valid", path.display())?,
                Verdict::Valid => {
                    writeln!(out, "{}: valid, {warnings} warning(s)", path.display())?
                }
                _ => writeln!(
                    out,
                    "{}: {errors} error(s), {warnings} warning(s)",
                    path.display()
                )?,
            }
        }
    }
    if json {
        // An I/O error (the reader gone: `trace validate --json | head`) keeps its kind.
        serde_json::to_writer_pretty(&mut *out, &reports).map_err(|e| match e.io_error_kind() {
            Some(kind) => std::io::Error::new(kind, e),
            None => std::io::Error::other(e),
        })?;
        writeln!(out)?;
    }
    Ok(worst)
}
