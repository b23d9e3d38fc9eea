//! The mission's resource model: what each task of the model costs in time and energy, from the
//! catalogues of the systems that serve it (`cost`, `battery`: `connector_api::cost`), resolved
//! for the goal the task sends (a bound that depends on a goal field reads the field's value
//! from the task's input mapping, which must then be a number).
//!
//! Tasks no catalogue costs: a user task (the ground answers whenever it answers: from at once to
//! never), a receive task (the message comes whenever it comes). A service task routed to a
//! system whose catalogue declares no cost for its action is an error naming the task, when a
//! requirement needs the costs.

use std::collections::BTreeMap;

use connector_api::cost::{Battery, Reading};
use connector_api::{Catalogue, ConnectorsConfig};
use executive_model::{NodeId, NodeKind, ProcessGraph, TaskKind};

/// One task's cost.
#[derive(Clone, Debug, PartialEq)]
pub struct TaskCost {
    /// How long it runs, ms: `(min, max)`; `max` may be infinite.
    pub duration_ms: (f64, f64),
    /// Its power on top of the idle draw, W: `(min, max)`.
    pub power_w: (f64, f64),
    /// Variables its outputs write from a battery reading, with what they read.
    pub reads: Vec<(String, Reading)>,
    /// What a failure with a given code costs instead.
    pub errors: BTreeMap<String, TaskCost>,
    /// The error codes it can fail with: those its action declares and the protocol's (`None`:
    /// not known, any).
    pub codes: Option<std::collections::BTreeSet<String>>,
}

impl TaskCost {
    /// A task that takes any time and no energy of its own (a ground decision, a message).
    pub fn open() -> TaskCost {
        TaskCost {
            duration_ms: (0.0, f64::INFINITY),
            power_w: (0.0, 0.0),
            reads: Vec::new(),
            errors: BTreeMap::new(),
            codes: None,
        }
    }

    /// Its power while it runs, W, whatever its outcome will be: the least and the greatest of
    /// success and every failure's own.
    pub fn power_envelope(&self) -> (f64, f64) {
        self.errors.values().fold(self.power_w, |(lo, hi), e| {
            (lo.min(e.power_w.0), hi.max(e.power_w.1))
        })
    }

    /// The cost of the outcome: a failure with `code` (its own bounds if declared), or success.
    pub fn outcome(&self, code: Option<&str>) -> &TaskCost {
        code.and_then(|c| self.errors.get(c)).unwrap_or(self)
    }
}

/// Every task's cost and the battery.
#[derive(Clone, Debug, PartialEq)]
pub struct Costs {
    /// The battery the mission draws from.
    pub battery: Battery,
    /// Costs by task element (tasks absent here run at once and cost nothing: script tasks).
    pub tasks: BTreeMap<NodeId, TaskCost>,
}

/// Resolves the cost of every task of `g` against the connectors' routes and catalogues
/// (`catalogues[i]` belongs to connector `i`); every problem is listed.
pub fn costs(
    g: &ProcessGraph,
    config: &ConnectorsConfig,
    catalogues: &[Option<Catalogue>],
) -> Result<Costs, Vec<String>> {
    let mut problems = Vec::new();
    let battery = catalogues.iter().flatten().find_map(|c| c.battery.clone());
    if battery.is_none() {
        problems.push(
            "no catalogue declares a battery (`battery`: capacity_wh, idle_w) to draw energy from"
                .to_owned(),
        );
    }
    let mut tasks = BTreeMap::new();
    for (i, node) in g.nodes.iter().enumerate() {
        let NodeKind::Task(t) = &node.kind else {
            continue;
        };
        let id = NodeId(i as u32);
        match t.kind {
            TaskKind::User | TaskKind::Receive | TaskKind::Manual => {
                tasks.insert(id, TaskCost::open());
                continue;
            }
            TaskKind::Script
                if t.binding
                    .as_ref()
                    .and_then(|b| b.resource.as_ref())
                    .is_none() =>
            {
                continue;
            }
            _ => {}
        }
        let Some(binding) = &t.binding else {
            if matches!(
                t.kind,
                TaskKind::Service | TaskKind::Send | TaskKind::BusinessRule
            ) {
                problems.push(format!("task `{}`: it names no resource to cost", node.id));
            }
            continue;
        };
        let resource = binding.resource.clone().unwrap_or_else(|| node.id.clone());
        let Some(route) = config.route(&resource) else {
            problems.push(format!(
                "task `{}`: no connector serves resource `{resource}`",
                node.id
            ));
            continue;
        };
        let Some(Some(cat)) = catalogues.get(route.connector) else {
            problems.push(format!(
                "task `{}`: no catalogue of connector `{}` to cost action `{}`",
                node.id, config.connectors[route.connector].name, route.action
            ));
            continue;
        };
        let Some(spec) = cat.action(&route.action) else {
            problems.push(format!(
                "task `{}`: server `{}` has no action `{}`",
                node.id, cat.server, route.action
            ));
            continue;
        };
        let Some(cost) = &spec.cost else {
            problems.push(format!(
                "task `{}`: the catalogue of `{}` declares no cost for action `{}`",
                node.id, cat.server, route.action
            ));
            continue;
        };
        // A goal field's value: a number the input mapping writes, or absent.
        let field = |name: &str| -> Result<Option<f64>, String> {
            match binding.inputs.iter().find(|i| i.target == name) {
                None => Ok(None),
                Some(i) => i.source.text.trim().parse::<f64>().map(Some).map_err(|_| {
                    format!(
                        "is set from `{}`, not a number, so its cost is not known before flight",
                        i.source.text
                    )
                }),
            }
        };
        let reads: Vec<(String, Reading)> = binding
            .outputs
            .iter()
            .filter_map(|o| {
                cost.reads
                    .get(o.source.text.trim())
                    .map(|r| (o.target.clone(), *r))
            })
            .collect();
        match resolve(cost, field) {
            Ok(c) => {
                let codes = spec
                    .errors
                    .keys()
                    .cloned()
                    .chain(
                        connector_api::wire::codes::ALL
                            .iter()
                            .map(|c| (*c).to_owned()),
                    )
                    .collect();
                tasks.insert(
                    id,
                    TaskCost {
                        reads,
                        codes: Some(codes),
                        ..c
                    },
                );
            }
            Err(e) => problems.push(format!(
                "task `{}` (action `{}`): {e}",
                node.id, route.action
            )),
        }
    }
    match battery {
        Some(battery) if problems.is_empty() => Ok(Costs { battery, tasks }),
        _ => Err(problems),
    }
}

/// A declared cost, for a goal whose fields `field` knows.
fn resolve(
    cost: &connector_api::cost::Cost,
    field: impl Fn(&str) -> Result<Option<f64>, String> + Copy,
) -> Result<TaskCost, connector_api::cost::Unknown> {
    let d = cost.duration_s.range(field)?;
    let errors = cost
        .errors
        .iter()
        .map(|(code, c)| Ok((code.clone(), resolve(c, field)?)))
        .collect::<Result<_, connector_api::cost::Unknown>>()?;
    Ok(TaskCost {
        duration_ms: (d.0 * 1000.0, d.1 * 1000.0),
        power_w: cost.power_w.range(field)?,
        reads: Vec::new(),
        errors,
        codes: None,
    })
}
