//! The mission's resource model: what each task of the model costs in time and energy, from the
//! catalogues of the systems that serve it (`cost`, `battery`: `connector_api::cost`), resolved
//! for the goal the task sends (a bound that depends on a goal field reads the field's value
//! from the task's input mapping, which must then be a number).
//!
//! Tasks no catalogue costs: a user task (the ground answers whenever it answers: from at once to
//! never), a receive task (the message comes whenever it comes). A service task routed to a
//! system whose catalogue declares no cost for its action is an error naming the task, when a
//! requirement needs the costs.
//!
//! **Vehicles.** A mission flown by one executive draws from one battery. A fleet (one executive
//! per pool) has one per vehicle: each pool's tasks are costed by its own connectors and
//! catalogues and draw from its own battery, and the processes its call activities call are its
//! own too.

use std::collections::BTreeMap;

use connector_api::cost::{Battery, Reading};
use connector_api::{Catalogue, ConnectorsConfig};
use executive_model::{Called, NodeId, NodeKind, ProcessGraph, ProcessId, TaskKind};

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

/// One vehicle: a battery and the pool whose tasks draw from it.
#[derive(Clone, Debug, PartialEq)]
pub struct Vehicle {
    /// Its pool's id (`None`: the whole mission, flown by one executive).
    pub pool: Option<String>,
    /// The battery it draws from.
    pub battery: Battery,
}

/// Every task's cost and every vehicle's battery.
#[derive(Clone, Debug, PartialEq)]
pub struct Costs {
    /// The vehicles (one, with no pool, unless the mission is costed per pool).
    pub vehicles: Vec<Vehicle>,
    /// The vehicle each process belongs to (absent: the first).
    pub owner: BTreeMap<ProcessId, usize>,
    /// Costs by task element (tasks absent here run at once and cost nothing: script tasks).
    pub tasks: BTreeMap<NodeId, TaskCost>,
}

impl Costs {
    /// One battery for the whole mission.
    pub fn one(battery: Battery, tasks: BTreeMap<NodeId, TaskCost>) -> Costs {
        Costs {
            vehicles: vec![Vehicle {
                pool: None,
                battery,
            }],
            owner: BTreeMap::new(),
            tasks,
        }
    }

    /// The vehicle an element belongs to.
    pub fn vehicle_of(&self, g: &ProcessGraph, node: NodeId) -> usize {
        self.owner.get(&g.process_of(node)).copied().unwrap_or(0)
    }

    /// A vehicle's name: its pool's id, or `mission`.
    pub fn name(&self, v: usize) -> &str {
        self.vehicles
            .get(v)
            .and_then(|x| x.pool.as_deref())
            .unwrap_or("mission")
    }
}

/// What costs one vehicle's tasks: its pool (`None`: the whole mission), its connectors and
/// their catalogues (`catalogues[i]` belongs to connector `i`).
#[derive(Clone, Copy, Debug)]
pub struct Source<'a> {
    /// The pool's id.
    pub pool: Option<&'a str>,
    /// Its connectors' routes.
    pub config: &'a ConnectorsConfig,
    /// Their catalogues.
    pub catalogues: &'a [Option<Catalogue>],
}

/// The vehicle of each process: a pool's own process, and whatever its call activities call,
/// transitively (a process called from two vehicles' belongs to the first found).
fn owners(g: &ProcessGraph, sources: &[Source]) -> Result<BTreeMap<ProcessId, usize>, String> {
    let mut owner = BTreeMap::new();
    for (v, s) in sources.iter().enumerate() {
        let Some(pool) = s.pool else { continue };
        let process = g
            .participants()
            .find(|p| p.id == pool)
            .and_then(|p| p.process)
            .ok_or_else(|| format!("no pool with a process has the id `{pool}`"))?;
        owner.insert(process, v);
    }
    loop {
        let mut more = Vec::new();
        for (i, node) in g.nodes.iter().enumerate() {
            if let NodeKind::CallActivity(c) = &node.kind
                && let Some(Called::Process(called)) = c.called
                && !owner.contains_key(&called)
                && let Some(v) = owner.get(&g.process_of(NodeId(i as u32)))
            {
                more.push((called, *v));
            }
        }
        if more.is_empty() {
            return Ok(owner);
        }
        for (p, v) in more {
            owner.entry(p).or_insert(v);
        }
    }
}

/// Resolves the cost of every task of `g` against its vehicle's connectors and catalogues;
/// every problem is listed.
pub fn costs(g: &ProcessGraph, sources: &[Source]) -> Result<Costs, Vec<String>> {
    let mut problems = Vec::new();
    let owner = owners(g, sources).map_err(|e| vec![e])?;
    let named = |v: usize, what: String| match sources.get(v).and_then(|s| s.pool) {
        Some(pool) if sources.len() > 1 => format!("pool `{pool}`: {what}"),
        _ => what,
    };
    let mut vehicles = Vec::new();
    for (v, s) in sources.iter().enumerate() {
        match s.catalogues.iter().flatten().find_map(|c| c.battery.clone()) {
            Some(battery) => vehicles.push(Vehicle {
                pool: s.pool.map(str::to_owned),
                battery,
            }),
            None => problems.push(named(
                v,
                "no catalogue declares a battery (`battery`: capacity_wh, idle_w) to draw energy from"
                    .to_owned(),
            )),
        }
    }
    let mut tasks = BTreeMap::new();
    for (i, node) in g.nodes.iter().enumerate() {
        let NodeKind::Task(t) = &node.kind else {
            continue;
        };
        let id = NodeId(i as u32);
        let v = owner.get(&g.process_of(id)).copied().unwrap_or(0);
        let Some(&Source {
            config, catalogues, ..
        }) = sources.get(v)
        else {
            continue;
        };
        let mut problem = |what: String| problems.push(named(v, what));
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
                problem(format!("task `{}`: it names no resource to cost", node.id));
            }
            continue;
        };
        let resource = binding.resource.as_deref().unwrap_or(&node.id);
        let Some(route) = config.route(resource) else {
            problem(format!(
                "task `{}`: no connector serves resource `{resource}`",
                node.id
            ));
            continue;
        };
        let Some(Some(cat)) = catalogues.get(route.connector) else {
            problem(format!(
                "task `{}`: no catalogue of connector `{}` to cost action `{}`",
                node.id, config.connectors[route.connector].name, route.action
            ));
            continue;
        };
        let Some(spec) = cat.action(&route.action) else {
            problem(format!(
                "task `{}`: server `{}` has no action `{}`",
                node.id, cat.server, route.action
            ));
            continue;
        };
        let Some(cost) = &spec.cost else {
            problem(format!(
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
            Err(e) => problem(format!(
                "task `{}` (action `{}`): {e}",
                node.id, route.action
            )),
        }
    }
    if problems.is_empty() {
        Ok(Costs {
            vehicles,
            owner,
            tasks,
        })
    } else {
        Err(problems)
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
