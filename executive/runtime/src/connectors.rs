//! The executive's connectors: built from the connector configuration, checked against the
//! mission before it starts (every problem listed), and addressed by route.

use std::path::Path;
use std::time::Duration;

use connector_api::{
    Catalogue, Connector, ConnectorConfig, ConnectorsConfig, Kind, Mismatch, Reports, TaskUse, Type,
};
use connector_zenoh::{ClientOptions, Role, ZenohArgs, ZenohConnector};
use executive_model::{EventDefinition, NodeKind, ProcessGraph, TaskKind};

use crate::script::{Script, ScriptConnector};

/// Why the connectors could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// The configuration file is unreadable or invalid.
    #[error("{path}: {reason}")]
    Config {
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// Zenoh could not be opened.
    #[error(transparent)]
    Zenoh(#[from] connector_zenoh::SessionError),
    /// A connector failed to start or to answer.
    #[error("connector `{name}`: {reason}")]
    Connector {
        /// Which.
        name: String,
        /// What happened.
        reason: String,
    },
    /// The mission does not match the systems.
    #[error("the mission does not match the systems it drives ({} problems):\n{}", .0.len(), .0.iter().map(|m| format!("  {m}")).collect::<Vec<_>>().join("\n"))]
    Mismatches(Vec<Mismatch>),
    /// An expression reads a name that nothing writes before it, or a literal can never fit.
    #[error("the mission reads data nothing gives it ({} problems):\n{}", .0.len(), .0.iter().map(|m| format!("  {m}")).collect::<Vec<_>>().join("\n"))]
    Data(Vec<String>),
}

/// The loaded connectors.
pub struct Connectors {
    /// The configuration (routes).
    pub config: ConnectorsConfig,
    /// One per configured connector, in order.
    pub list: Vec<Box<dyn Connector>>,
    /// Each connector's catalogue, once [`Connectors::check`] has asked for them.
    pub catalogues: Vec<Option<Catalogue>>,
    session: Option<zenoh::Session>,
}

/// What the connectors need to know about the run.
pub struct Setup<'a> {
    /// The connector configuration file (`None`: one scripted connector serving everything).
    pub config: Option<&'a Path>,
    /// The scripted connector's script.
    pub script: Option<&'a Path>,
    /// Where the scripted connector logs its effects.
    pub effects: &'a Path,
    /// Mission time speed-up (the scripted connector's durations).
    pub speed: f64,
    /// Zenoh flags.
    pub zenoh: &'a ZenohArgs,
    /// The mission id (goal ids start with it; we are `exec-<mission>` on Zenoh).
    pub mission: String,
    /// How long to wait for each system's catalogue.
    pub catalogue_wait: Duration,
    /// The virtual mission clock: scripted connectors answer on it when every connector is
    /// scripted (no outside system); otherwise they sleep on the wall clock.
    pub agenda: Option<crate::script::Agenda>,
    /// The run is one executive of a fleet: Zenoh is opened for the fleet link even when no
    /// connector needs it.
    pub fleet: bool,
}

fn read_config(path: &Path) -> Result<ConnectorsConfig, SetupError> {
    let bad = |reason: String| SetupError::Config {
        path: path.display().to_string(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let dir = path.parent().unwrap_or(Path::new(""));
    parse_config(&text).map(|c| c.beside(dir)).map_err(bad)
}

/// Reads a connectors file's text (`connectors.toml`) and checks it: the reason when it is
/// not TOML of that shape or its routes are inconsistent.
pub fn parse_config(text: &str) -> Result<ConnectorsConfig, String> {
    let config: ConnectorsConfig = toml::from_str(text).map_err(|e| e.to_string())?;
    let problems = config.problems();
    if !problems.is_empty() {
        return Err(problems.join("; "));
    }
    Ok(config)
}

impl Connectors {
    /// Builds every configured connector; Zenoh is opened only if one needs it.
    pub async fn open(setup: &Setup<'_>, reports: Reports) -> Result<Connectors, SetupError> {
        let config = match setup.config {
            Some(p) => read_config(p)?,
            None => ConnectorsConfig {
                connectors: vec![ConnectorConfig {
                    name: "script".into(),
                    kind: Kind::Script,
                    server: None,
                    resources: vec!["*".into()],
                    actions: Default::default(),
                    data: Vec::new(),
                    deadband: Default::default(),
                    grace_ms: 0,
                    clock: false,
                    answers: false,
                    limits: Default::default(),
                    ros2: Default::default(),
                }],
            },
        };
        let script = match setup.script {
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(|e| SetupError::Config {
                    path: p.display().to_string(),
                    reason: e.to_string(),
                })?;
                serde_json::from_str::<Script>(&text).map_err(|e| SetupError::Config {
                    path: p.display().to_string(),
                    reason: e.to_string(),
                })?
            }
            None => Script::default(),
        };
        let session = if setup.fleet || config.connectors.iter().any(|c| c.kind == Kind::Zenoh) {
            Some(setup.zenoh.open(Role::Hub).await?)
        } else {
            None
        };
        let keys = setup.zenoh.keys()?;
        let agenda = setup
            .agenda
            .clone()
            .filter(|_| config.connectors.iter().all(|c| c.kind == Kind::Script));
        let mut list: Vec<Box<dyn Connector>> = Vec::new();
        for c in &config.connectors {
            let failed = |reason: String| SetupError::Connector {
                name: c.name.clone(),
                reason,
            };
            list.push(match (c.kind, &session) {
                (Kind::Script, _) => Box::new(
                    ScriptConnector::new(
                        &c.name,
                        script.clone(),
                        setup.effects,
                        setup.speed,
                        reports.clone(),
                    )
                    .map_err(|e| failed(e.to_string()))?
                    .on_agenda(agenda.clone()),
                ),
                (Kind::Zenoh, Some(session)) => Box::new(
                    ZenohConnector::with_limits(
                        session,
                        ClientOptions {
                            keys: keys.clone(),
                            config: c.clone(),
                            client: format!("exec-{}", setup.mission),
                            mission: setup.mission.clone(),
                            catalogue_wait: setup.catalogue_wait,
                            query_timeout: Duration::from_secs(5),
                        },
                        c.limits.clone(),
                        reports.clone(),
                    )
                    .await
                    .map_err(|e| failed(e.to_string()))?,
                ),
                (Kind::Zenoh, None) => unreachable!("a session is opened for zenoh connectors"),
                (Kind::Ros2, _) => Box::new(connector_ros2::Ros2Connector::new(c, reports.clone())),
            });
        }
        Ok(Connectors {
            config,
            list,
            catalogues: Vec::new(),
            session,
        })
    }

    /// Checks the mission against every connector's catalogue; all problems at once. The
    /// tasks of `remote` processes (other pools of a fleet, run by other executives) are not
    /// this run's.
    ///
    /// The data checks ([`crate::dataflow`]) run too: with the start variables when they are
    /// known (`start`, a first start), an expression that reads a name nothing writes before
    /// it refuses the start.
    pub async fn check(
        &mut self,
        g: &ProcessGraph,
        text: &str,
        remote: &std::collections::BTreeMap<executive_model::ProcessId, String>,
        start: Option<&std::collections::BTreeSet<String>>,
    ) -> Result<(), SetupError> {
        let mut catalogues: Vec<Option<Catalogue>> = Vec::new();
        for c in &mut self.list {
            let name = c.name().to_owned();
            catalogues.push(c.catalogue().await.map_err(|e| SetupError::Connector {
                name,
                reason: e.to_string(),
            })?);
        }
        let uses: Vec<TaskUse> = task_uses(g)
            .into_iter()
            .filter(|u| {
                g.node_by_id(&u.task)
                    .is_none_or(|n| !remote.contains_key(&g.process_of(n)))
            })
            .collect();
        let mismatches = connector_api::check(&uses, &self.config, &catalogues);
        for w in connector_api::check::unbounded(&uses, &self.config, &catalogues) {
            tracing::warn!(task = w.task, "{}", w.problem);
            eprintln!("warning: {w}");
        }
        let mut data = Vec::new();
        let known = crate::dataflow::Known {
            config: Some(&self.config),
            catalogues: &catalogues,
            start,
        };
        for d in crate::dataflow::diagnostics(g, text, &known) {
            let local = d
                .element
                .as_deref()
                .and_then(|e| element_process(g, e))
                .is_none_or(|p| !remote.contains_key(&p));
            if !local {
                continue;
            }
            let element = d.element.clone().unwrap_or_default();
            if d.severity == executive_model::Severity::Error {
                data.push(format!("line {}: {} [{}]", d.line, d.message, d.code));
            } else {
                tracing::warn!(element, "{}", d.message);
                eprintln!("warning: `{element}` (line {}): {}", d.line, d.message);
            }
        }
        self.catalogues = catalogues;
        if !mismatches.is_empty() {
            for d in data {
                tracing::error!("{d}");
            }
            Err(SetupError::Mismatches(mismatches))
        } else if !data.is_empty() {
            Err(SetupError::Data(data))
        } else {
            Ok(())
        }
    }

    /// The Zenoh session, if a connector opened one.
    pub fn session(&self) -> Option<&zenoh::Session> {
        self.session.as_ref()
    }

    /// Undeclares everything and closes Zenoh.
    pub async fn close(&mut self) {
        for c in &mut self.list {
            c.close().await;
        }
        if let Some(s) = self.session.take()
            && let Err(e) = s.close().await
        {
            tracing::debug!(error = %e, "zenoh close failed");
        }
    }
}

fn is_path(s: &str) -> bool {
    !s.is_empty()
        && s.split('.').all(|p| {
            let mut c = p.chars();
            c.next()
                .is_some_and(|f| f.is_ascii_alphabetic() || f == '_')
                && c.all(|x| x.is_ascii_alphanumeric() || x == '_')
        })
}

/// What each dispatched task of the model asks of the systems.
pub fn task_uses(g: &ProcessGraph) -> Vec<TaskUse> {
    let mut out = Vec::new();
    for node in &g.nodes {
        let NodeKind::Task(t) = &node.kind else {
            continue;
        };
        let resource = t.binding.as_ref().and_then(|b| b.resource.clone());
        let dispatched = match t.kind {
            TaskKind::User | TaskKind::Service | TaskKind::BusinessRule => true,
            TaskKind::Send | TaskKind::Script => resource.is_some(),
            _ => false,
        };
        if !dispatched {
            continue;
        }
        let ty = |f: &Option<executive_model::binding::FieldType>| {
            f.as_ref().and_then(|f| Type::parse(&f.to_string()))
        };
        // A user task's goal is `{task, name, context, deadline_ms?}` (what the operator sees);
        // only its answer (outputs) is checked against the form.
        let user = t.kind == TaskKind::User;
        let (inputs, outputs) = match &t.binding {
            Some(b) => (
                b.inputs
                    .iter()
                    .filter(|_| !user)
                    .map(|i| (i.target.clone(), ty(&i.ty)))
                    .collect(),
                b.outputs
                    .iter()
                    .flat_map(|o| {
                        if is_path(&o.source.text) {
                            vec![(o.source.text.clone(), ty(&o.ty))]
                        } else {
                            o.source
                                .variables
                                .iter()
                                .map(|v| (v.clone(), None))
                                .collect()
                        }
                    })
                    .collect(),
            ),
            None => (Vec::new(), Vec::new()),
        };
        // Inputs set to a constant without a declared type: the constant is what is sent.
        let constants = t
            .binding
            .iter()
            .flat_map(|b| &b.inputs)
            .filter(|i| !user && i.ty.is_none())
            .filter_map(|i| {
                let v = serde_json::from_str::<serde_json::Value>(i.source.text.trim()).ok()?;
                (!v.is_null()).then(|| (i.target.clone(), v))
            })
            .collect();
        let caught = node
            .boundaries
            .iter()
            .filter_map(|b| match &g.node(*b).kind {
                NodeKind::Boundary(be) => Some(be),
                _ => None,
            })
            .flat_map(|be| &be.triggers)
            .filter_map(|d| match d {
                EventDefinition::Error { error: Some(e), .. } => g.errors[e.index()].code.clone(),
                _ => None,
            })
            .collect();
        let timed = node.boundaries.iter().any(|b| {
            matches!(&g.node(*b).kind, NodeKind::Boundary(be)
                if be.triggers.iter().any(|d| matches!(d, EventDefinition::Timer(_))))
        });
        out.push(TaskUse {
            timed,
            task: node.id.clone(),
            name: node.label().to_owned(),
            resource: resource.unwrap_or_else(|| node.id.clone()),
            inputs,
            constants,
            outputs,
            caught,
        });
    }
    out
}

/// The process of a node or sequence flow, by BPMN id.
fn element_process(g: &ProcessGraph, id: &str) -> Option<executive_model::ProcessId> {
    if let Some(n) = g.node_by_id(id) {
        return Some(g.process_of(n));
    }
    g.flows
        .iter()
        .find(|f| f.id == id)
        .map(|f| g.process_of(f.source))
}
