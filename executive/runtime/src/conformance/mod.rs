//! `trace conformance …`: run public BPMN conformance corpora against the engine and print
//! the result per group and a closing `N passed, M failed` line.

pub mod betsy;
pub mod token_sim;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// Totals of a corpus run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Totals {
    /// Cases that passed.
    pub passed: usize,
    /// Cases that failed.
    pub failed: usize,
}

/// Runs a betsy-format corpus and prints the report to `out`.
pub fn betsy(dir: &Path, expectations: &Path, out: &mut dyn Write) -> std::io::Result<Totals> {
    let results = betsy::run_corpus(dir, expectations).map_err(std::io::Error::other)?;
    let mut groups: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for r in &results {
        let e = groups.entry(r.group.as_str()).or_default();
        if r.passed() {
            e.0 += 1;
        } else {
            e.1 += 1;
        }
    }
    for (g, (p, f)) in &groups {
        writeln!(out, "{g:<12} {p:>4} passed {f:>4} failed")?;
    }
    for r in results.iter().filter(|r| !r.passed()) {
        writeln!(
            out,
            "FAIL {}: expected {:?}, got {:?}",
            r.id, r.expected, r.got
        )?;
    }
    let passed = results.iter().filter(|r| r.passed()).count();
    let failed = results.len() - passed;
    writeln!(out, "{passed} passed, {failed} failed")?;
    Ok(Totals { passed, failed })
}

/// Runs a bpmn-js-token-simulation corpus and prints the report to `out`. Scenarios not
/// verified upstream are reported as informative and not counted.
pub fn token_simulation(dir: &Path, out: &mut dyn Write) -> std::io::Result<Totals> {
    let results = token_sim::run_corpus(dir).map_err(std::io::Error::other)?;
    let mut groups: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    let counted = |r: &&token_sim::ScenarioResult| !r.informative && r.deviation.is_none();
    for r in results.iter().filter(counted) {
        let e = groups.entry(r.section.as_str()).or_default();
        if r.failure.is_none() {
            e.0 += 1;
        } else {
            e.1 += 1;
        }
    }
    for (g, (p, f)) in &groups {
        writeln!(out, "{g:<40} {p:>4} passed {f:>4} failed")?;
    }
    for r in &results {
        if let Some(why) = r.deviation {
            let state = if r.failure.is_some() {
                "differs"
            } else {
                "now agrees"
            };
            writeln!(out, "DEVIATION {} ({state}): {why}", r.name)?;
        } else if let Some(why) = &r.failure {
            let tag = if r.informative { "INFO" } else { "FAIL" };
            writeln!(out, "{tag} {}: {why}", r.name)?;
        }
    }
    let counted: Vec<_> = results.iter().filter(counted).collect();
    let passed = counted.iter().filter(|r| r.failure.is_none()).count();
    let failed = counted.len() - passed;
    writeln!(out, "{passed} passed, {failed} failed")?;
    Ok(Totals { passed, failed })
}
