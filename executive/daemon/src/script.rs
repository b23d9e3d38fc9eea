//! The scripted connector: an in-process stand-in for real systems (tests, dry runs). Each
//! resource answers after a set mission-time duration with set outputs, or fails with a code
//! on chosen attempts. It deduplicates by task key and logs every effect it applies to a file,
//! so a task re-commanded after a restart is never applied twice.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use executive_engine::{TaskKey, Vars};
use serde::Deserialize;

/// The script: rules by resource name (exact, else the longest matching prefix, else
/// `default`).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// The rule for resources no other rule names.
    #[serde(default)]
    pub default: Rule,
    /// Rules by resource name or prefix (`excavation.` matches `excavation.excavate`).
    #[serde(default)]
    pub resources: BTreeMap<String, Rule>,
}

/// How one resource behaves.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rule {
    /// Mission time the activity takes.
    #[serde(default)]
    pub duration_ms: i64,
    /// The result's fields (user tasks: the answer).
    #[serde(default)]
    pub outputs: Vars,
    /// Fail with this error code on the attempts listed in `fail_attempts` (all if empty).
    #[serde(default)]
    pub fail: Option<String>,
    /// Attempts (1-based, per task key attempt) that fail.
    #[serde(default)]
    pub fail_attempts: Vec<u32>,
}

/// What the connector decided for one command.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Complete with these outputs after `duration_ms` of mission time.
    Complete {
        /// Mission time it takes.
        duration_ms: i64,
        /// Result fields.
        outputs: Vars,
    },
    /// Fail with this code after `duration_ms`.
    Fail {
        /// Mission time it takes.
        duration_ms: i64,
        /// Error code.
        code: String,
    },
}

/// The connector state: the script and the effects already applied.
pub struct ScriptConnector {
    script: Script,
    effects: PathBuf,
    applied: BTreeSet<String>,
}

impl ScriptConnector {
    /// Loads the effects log (created if missing) beside the store.
    pub fn new(script: Script, effects: &Path) -> std::io::Result<ScriptConnector> {
        let mut applied = BTreeSet::new();
        if let Ok(f) = std::fs::File::open(effects) {
            for line in std::io::BufReader::new(f).lines() {
                let line = line?;
                // A line cut by a kill is ignored: its effect was not completed.
                if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line)
                    && let Some(k) = v["task"].as_str()
                {
                    applied.insert(k.to_owned());
                }
            }
        }
        Ok(ScriptConnector {
            script,
            effects: effects.to_path_buf(),
            applied,
        })
    }

    fn rule(&self, resource: &str) -> &Rule {
        if let Some(r) = self.script.resources.get(resource) {
            return r;
        }
        self.script
            .resources
            .iter()
            .filter(|(k, _)| resource.starts_with(k.as_str()))
            .max_by_key(|(k, _)| k.len())
            .map_or(&self.script.default, |(_, r)| r)
    }

    /// What a command will do.
    pub fn plan(&self, task: TaskKey, resource: &str) -> Outcome {
        let rule = self.rule(resource);
        match &rule.fail {
            Some(code)
                if rule.fail_attempts.is_empty() || rule.fail_attempts.contains(&task.attempt) =>
            {
                Outcome::Fail {
                    duration_ms: rule.duration_ms,
                    code: code.clone(),
                }
            }
            _ => Outcome::Complete {
                duration_ms: rule.duration_ms,
                outputs: rule.outputs.clone(),
            },
        }
    }

    /// Applies the effect of a finished command once: true the first time for this key.
    pub fn apply(&mut self, task: TaskKey, resource: &str) -> std::io::Result<bool> {
        let key = task.to_string();
        if self.applied.contains(&key) {
            return Ok(false);
        }
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.effects)?;
        let line = serde_json::json!({ "task": key, "resource": resource });
        f.write_all(format!("{line}\n").as_bytes())?;
        f.sync_data()?;
        self.applied.insert(key);
        Ok(true)
    }
}
