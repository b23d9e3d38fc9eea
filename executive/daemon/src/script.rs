//! The scripted connector: an in-process stand-in for real systems (tests, dry runs). Each
//! action answers after a set mission-time duration with set outputs, or fails with a code
//! on chosen attempts. It deduplicates by goal id and logs every effect it applies to a file,
//! so a task re-commanded after a restart is never applied twice.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use connector_api::contract::BoxFuture;
use connector_api::{Catalogue, Command, Connector, ConnectorError, Fields, Report, Reports};
use serde::Deserialize;
use tokio::task::JoinHandle;

/// The script: rules by action name (exact, else the longest matching prefix, else
/// `default`).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// The rule for actions no other rule names.
    #[serde(default)]
    pub default: Rule,
    /// Rules by action name or prefix (`excavation.` matches `excavation.excavate`).
    #[serde(default)]
    pub resources: BTreeMap<String, Rule>,
}

/// How one action behaves.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rule {
    /// Mission time the activity takes.
    #[serde(default)]
    pub duration_ms: i64,
    /// The result's fields (user tasks: the answer).
    #[serde(default)]
    pub outputs: Fields,
    /// Fail with this error code on the attempts listed in `fail_attempts` (all if empty).
    #[serde(default)]
    pub fail: Option<String>,
    /// Attempts (1-based, per task key attempt) that fail.
    #[serde(default)]
    pub fail_attempts: Vec<u32>,
}

/// The connector: the script, the effects already applied, the activities running.
pub struct ScriptConnector {
    name: String,
    script: Script,
    effects: PathBuf,
    applied: Arc<Mutex<BTreeSet<String>>>,
    speed: f64,
    reports: Reports,
    running: HashMap<String, JoinHandle<()>>,
}

impl ScriptConnector {
    /// Loads the effects log (created if missing) beside the store.
    pub fn new(
        name: &str,
        script: Script,
        effects: &Path,
        speed: f64,
        reports: Reports,
    ) -> std::io::Result<ScriptConnector> {
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
            name: name.to_owned(),
            script,
            effects: effects.to_path_buf(),
            applied: Arc::new(Mutex::new(applied)),
            speed,
            reports,
            running: HashMap::new(),
        })
    }

    fn rule(&self, action: &str) -> &Rule {
        if let Some(r) = self.script.resources.get(action) {
            return r;
        }
        self.script
            .resources
            .iter()
            .filter(|(k, _)| action.starts_with(k.as_str()))
            .max_by_key(|(k, _)| k.len())
            .map_or(&self.script.default, |(_, r)| r)
    }
}

/// Applies the effect of a finished goal once: true the first time for this goal id.
fn apply(
    applied: &Mutex<BTreeSet<String>>,
    effects: &Path,
    goal_id: &str,
    action: &str,
) -> std::io::Result<bool> {
    let mut applied = applied.lock().unwrap_or_else(|p| p.into_inner());
    if applied.contains(goal_id) {
        return Ok(false);
    }
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(effects)?;
    let line = serde_json::json!({ "task": goal_id, "resource": action });
    f.write_all(format!("{line}\n").as_bytes())?;
    f.sync_data()?;
    applied.insert(goal_id.to_owned());
    Ok(true)
}

impl Connector for ScriptConnector {
    fn name(&self) -> &str {
        &self.name
    }

    fn catalogue(&mut self) -> BoxFuture<'_, Result<Option<Catalogue>, ConnectorError>> {
        Box::pin(async { Ok(None) })
    }

    fn execute(&mut self, command: Command) {
        if self
            .running
            .get(&command.goal_id)
            .is_some_and(|h| !h.is_finished())
        {
            return;
        }
        let attempt = connector_api::keys::goal_attempt(&command.goal_id);
        let rule = self.rule(&command.action).clone();
        let fails = rule
            .fail
            .clone()
            .filter(|_| rule.fail_attempts.is_empty() || rule.fail_attempts.contains(&attempt));
        let delay = Duration::from_millis((rule.duration_ms.max(0) as f64 / self.speed) as u64);
        let (applied, effects, reports) = (
            Arc::clone(&self.applied),
            self.effects.clone(),
            self.reports.clone(),
        );
        let goal_id = command.goal_id.clone();
        let h = tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            if let Err(e) = apply(&applied, &effects, &command.goal_id, &command.action) {
                tracing::error!(error = %e, "effects log write failed");
                return;
            }
            let report = match fails {
                Some(code) => Report::Failed {
                    message: format!("{} failed with {code}", command.action),
                    goal_id: command.goal_id,
                    code,
                },
                None => Report::Done {
                    goal_id: command.goal_id,
                    outputs: rule.outputs,
                },
            };
            let _ = reports.send(report);
        });
        self.running.insert(goal_id, h);
    }

    fn reconcile(&mut self, command: Command) {
        self.execute(command);
    }

    fn abort(&mut self, goal_id: &str) {
        if let Some(h) = self.running.remove(goal_id) {
            h.abort();
        }
    }

    fn notify(&mut self, name: &str, _payload: serde_json::Value) {
        tracing::info!(
            connector = self.name,
            name,
            "notification (scripted: not delivered)"
        );
    }

    fn close(&mut self) -> BoxFuture<'_, ()> {
        for (_, h) in self.running.drain() {
            h.abort();
        }
        Box::pin(async {})
    }
}
