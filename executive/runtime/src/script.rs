//! The scripted connector: an in-process stand-in for real systems (tests, dry runs). Each
//! action answers after a set mission-time duration with set outputs, or fails with a code
//! on chosen attempts. It deduplicates by goal id and logs every effect it applies to a file,
//! so a task re-commanded after a restart is never applied twice.
//!
//! With an [`Agenda`] (a run without outside systems), the mission clock is virtual: an
//! answer is not a wall-clock sleep but an entry due at a mission time, and the driver moves
//! the clock from one due entry to the next — so a run's record does not depend on its speed.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use connector_api::contract::BoxFuture;
use connector_api::{Catalogue, Command, Connector, ConnectorError, Fields, Report, Reports};
use executive_engine::{Millis, TimerKey};
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
    agenda: Option<Agenda>,
}

/// The virtual mission clock of a run without outside systems, and what falls due on it:
/// armed timers and scripted answers, in order of mission time, then of arming. Shared by the
/// driver (which moves the clock) and the scripted connectors (which put their answers on
/// it).
#[derive(Clone, Default)]
pub struct Agenda(Arc<Mutex<Plan>>);

#[derive(Default)]
struct Plan {
    now: Millis,
    armed: u64,
    due: BTreeMap<(Millis, u64), Due>,
}

/// Something due on the agenda.
pub enum Due {
    /// A timer the engine armed.
    Timer(TimerKey),
    /// A scripted goal's answer: applying its effect gives the report (`None`: the effect
    /// could not be logged, so the goal is not answered).
    Goal {
        /// The goal.
        goal_id: String,
        /// Applies the effect and gives the report.
        answer: Box<dyn FnOnce() -> Option<Report> + Send>,
    },
}

impl Agenda {
    /// An agenda whose clock stands at `now`.
    pub fn new(now: Millis) -> Agenda {
        let a = Agenda::default();
        a.plan().now = now;
        a
    }

    fn plan(&self) -> std::sync::MutexGuard<'_, Plan> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Sets the clock (the mission's start, or where a resumed mission stood).
    pub fn set(&self, now: Millis) {
        self.plan().now = now;
    }

    /// Mission time now.
    pub fn now(&self) -> Millis {
        self.plan().now
    }

    /// The earliest deadline on the agenda.
    pub fn next(&self) -> Option<Millis> {
        self.plan().due.keys().next().map(|(at, _)| *at)
    }

    /// When a scripted goal is due, if it is on the agenda.
    pub fn goal_due(&self, goal_id: &str) -> Option<Millis> {
        self.plan().due.iter().find_map(|((at, _), d)| match d {
            Due::Goal { goal_id: g, .. } if g == goal_id => Some(*at),
            _ => None,
        })
    }

    /// Puts something on the agenda at mission time `at` (overdue: at once).
    pub fn push(&self, at: Millis, due: Due) {
        let mut p = self.plan();
        p.armed += 1;
        let n = p.armed;
        p.due.insert((at, n), due);
    }

    /// Takes a timer off the agenda.
    pub fn cancel_timer(&self, timer: TimerKey) {
        self.plan()
            .due
            .retain(|_, d| !matches!(d, Due::Timer(t) if *t == timer));
    }

    /// Takes a goal's answer off the agenda.
    pub fn cancel_goal(&self, goal_id: &str) {
        self.plan()
            .due
            .retain(|_, d| !matches!(d, Due::Goal { goal_id: g, .. } if g == goal_id));
    }

    /// Moves the clock to the earliest deadline (never back) and takes the first entry due.
    pub fn advance(&self) -> Option<Due> {
        let mut p = self.plan();
        let (at, _) = *p.due.keys().next()?;
        p.now = p.now.max(at);
        p.due.pop_first().map(|(_, d)| d)
    }
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
            agenda: None,
        })
    }

    /// Answers on the virtual clock of `agenda` (a run without outside systems) instead of
    /// after wall-clock sleeps.
    pub fn on_agenda(mut self, agenda: Option<Agenda>) -> ScriptConnector {
        self.agenda = agenda;
        self
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
        let (applied, effects) = (Arc::clone(&self.applied), self.effects.clone());
        let goal_id = command.goal_id.clone();
        let duration = rule.duration_ms.max(0);
        let answer = move || {
            if let Err(e) = apply(&applied, &effects, &command.goal_id, &command.action) {
                tracing::error!(error = %e, "effects log write failed");
                return None;
            }
            Some(match fails {
                Some(code) => Report::Failed {
                    message: format!("{} failed with {code}", command.action),
                    goal_id: command.goal_id,
                    code,
                },
                None => Report::Done {
                    goal_id: command.goal_id,
                    outputs: rule.outputs,
                },
            })
        };
        if let Some(agenda) = &self.agenda {
            if agenda.goal_due(&goal_id).is_none() {
                let at = agenda.now().saturating_add(duration);
                agenda.push(
                    at,
                    Due::Goal {
                        goal_id,
                        answer: Box::new(answer),
                    },
                );
            }
            return;
        }
        let delay = Duration::from_millis((duration as f64 / self.speed) as u64);
        let reports = self.reports.clone();
        let h = tokio::spawn(async move {
            tokio::time::sleep(delay).await;
            if let Some(report) = answer() {
                let _ = reports.send(report);
            }
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
        if let Some(agenda) = &self.agenda {
            agenda.cancel_goal(goal_id);
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
