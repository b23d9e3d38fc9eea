//! The checks the studio runs as the model changes: every diagnostic of `trace validate`, and
//! the load-time check of `trace run` against the systems' catalogues (every resource served,
//! input paths and types, outputs, caught error codes), each on the element it concerns.

use std::path::{Path, PathBuf};

use executive_model::{Diagnostic, Loaded, Options, Severity, load_bundle};
use serde::Serialize;

use crate::Studio;

/// The code of a diagnostic from the catalogue check.
pub use executive_runtime::validate::CATALOGUE_CODE;

/// What `POST /api/validate` answers.
#[derive(Debug, Serialize)]
pub struct Report {
    /// `trace validate`'s verdict: `valid`, `invalid` or `unreadable`.
    pub verdict: &'static str,
    /// Its diagnostics, then the catalogue check's (code [`CATALOGUE_CODE`], errors: `trace
    /// run` would refuse to start), in that order.
    pub diagnostics: Vec<Diagnostic>,
    /// What the catalogue check covered.
    pub catalogue: Coverage,
}

/// What the catalogue check covered.
#[derive(Debug, Default, Serialize)]
pub struct Coverage {
    /// Whether it ran: a connectors configuration is known and the model is valid.
    pub checked: bool,
    /// The servers whose catalogues the tasks were checked against.
    pub servers: Vec<String>,
    /// Servers the configuration routes to but no catalogue was found for: their tasks'
    /// fields are not checked (`trace run` would ask the running system).
    pub missing: Vec<String>,
    /// How many catalogue mismatches were found.
    pub mismatches: usize,
}

/// `trace validate` on `bytes` (imports read from the mission directory, plain file names
/// only), then, when the model is valid and the studio knows the connectors, the catalogue
/// check of `trace run`.
pub fn check(studio: &Studio, bytes: &[u8]) -> Report {
    let loaded = load(&studio.dir, bytes, &Options::default());
    let verdict = if loaded.unreadable() {
        "unreadable"
    } else if loaded.graph.is_some() && loaded.errors().next().is_none() {
        "valid"
    } else {
        "invalid"
    };
    let mut diagnostics = loaded.diagnostics;
    let mut catalogue = Coverage::default();
    // The checks of `trace validate` with the studio's systems (and of `trace run`, but for
    // the start variables); a catalogue mismatch is counted, not a verdict on the model.
    let served = studio
        .connectors
        .as_ref()
        .map(|c| executive_runtime::catalogues::served(c, &studio.catalogues()))
        .unwrap_or_default();
    if let Some(graph) = &loaded.graph {
        diagnostics.extend(executive_runtime::validate::system_diagnostics(
            graph,
            &loaded.text,
            studio.connectors.as_ref(),
            &served,
        ));
    }
    let verdict = if verdict == "valid"
        && diagnostics
            .iter()
            .any(|d| d.severity == Severity::Error && d.code != CATALOGUE_CODE)
    {
        "invalid"
    } else {
        verdict
    };
    if let Some(config) = &studio.connectors
        && loaded.graph.is_some()
    {
        catalogue.checked = true;
        for (c, cat) in config.connectors.iter().zip(&served) {
            let list = if cat.is_some() {
                &mut catalogue.servers
            } else {
                &mut catalogue.missing
            };
            if c.kind == connector_api::Kind::Zenoh && !list.iter().any(|s| s == c.server()) {
                list.push(c.server().to_owned());
            }
        }
        catalogue.mismatches = diagnostics
            .iter()
            .filter(|d| d.code == CATALOGUE_CODE)
            .count();
    }
    Report {
        verdict,
        diagnostics,
        catalogue,
    }
}

/// Loads a model as `trace validate` does (with `options`), imports read from `dir` (plain
/// file names only).
pub fn load(dir: &Path, bytes: &[u8], options: &Options) -> Loaded {
    let max = options.limits.max_bytes;
    let mut resolve = |location: &str| -> Result<Vec<u8>, String> {
        // Imports may be any file of the directory (not only missions), nothing outside it.
        if location.contains(['/', '\\']) || location.starts_with('.') {
            return Err(format!(
                "`{location}`: the studio reads imports from the mission directory only"
            ));
        }
        let p: PathBuf = dir.join(location);
        let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        if bytes.len() > max {
            return Err(format!(
                "{} is {} bytes; the limit is {max}",
                p.display(),
                bytes.len()
            ));
        }
        Ok(bytes)
    };
    load_bundle(bytes, options, &mut resolve)
}
