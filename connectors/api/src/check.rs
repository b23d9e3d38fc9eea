//! Load-time checks of a mission against the catalogues of the systems it will drive: every
//! service task's action exists, every input path exists with a compatible type, every output
//! reads a result field that exists, and every error code a boundary catches is declared. All
//! problems are listed, never just the first.

use std::fmt;

use crate::catalogue::{Catalogue, Type, field_at};
use crate::routes::ConnectorsConfig;
use crate::wire::codes;

/// What the mission asks of one task, independent of the model crate.
#[derive(Clone, Debug, Default)]
pub struct TaskUse {
    /// The task element id.
    pub task: String,
    /// Its name, for messages.
    pub name: String,
    /// Its resource name.
    pub resource: String,
    /// Goal field paths it writes, with the type the model declares (if any).
    pub inputs: Vec<(String, Option<Type>)>,
    /// Goal field paths it sets to a constant (a literal with no declared type), with the
    /// constant: checked against the field's type and range before flight.
    pub constants: Vec<(String, serde_json::Value)>,
    /// Result field paths its outputs read, with the declared type (if any).
    pub outputs: Vec<(String, Option<Type>)>,
    /// Error codes caught by error boundaries on it (`None`: a catch-all boundary).
    pub caught: Vec<String>,
    /// It has a timer boundary (a deadline of its own).
    pub timed: bool,
}

/// The tasks that call an action with no upper bound on its duration and have no timer
/// boundary: only the executive's watchdog, with the connector's default bound, ends them if
/// their system goes silent. One line per task.
pub fn unbounded(
    tasks: &[TaskUse],
    config: &ConnectorsConfig,
    catalogues: &[Option<Catalogue>],
) -> Vec<Mismatch> {
    let mut out = Vec::new();
    for t in tasks.iter().filter(|t| !t.timed) {
        let Some(route) = config.route(&t.resource) else {
            continue;
        };
        // Ground stations answer whenever the operator does: user tasks have no duration.
        if config.connectors[route.connector].answers {
            continue;
        }
        let Some(Some(cat)) = catalogues.get(route.connector) else {
            continue;
        };
        let Some(spec) = cat.action(&route.action) else {
            continue;
        };
        let bounded = match &spec.cost {
            None => false,
            Some(c) => c
                .duration_s
                .range(|_| Ok(None))
                .map_or(true, |(_, hi)| hi.is_finite()),
        };
        if !bounded {
            let c = &config.connectors[route.connector];
            let ends = match (c.limits.overrun_margin_ms, c.limits.overrun_default_ms) {
                (Some(_), ms) if ms > 0 => format!(
                    "only the watchdog's default bound ({ms} ms of mission time, `overrun_default_ms`) ends it"
                ),
                _ => format!(
                    "nothing ends it (connector `{}` has no watchdog for it: set `limits.overrun_margin_ms`)",
                    c.name
                ),
            };
            out.push(Mismatch {
                task: t.task.clone(),
                field: Some("resource".to_owned()),
                problem: format!(
                    "`{}` declares no upper bound on its duration and the task has no timer boundary: if its system goes silent, {ends}",
                    spec.name
                ),
            });
        }
    }
    out
}

/// One mismatch between the mission and the systems.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// The task element id.
    pub task: String,
    /// Where in the task's binding: `input:<goal field>`, `output:<result field>`, `resource`;
    /// `None` for the task as a whole.
    pub field: Option<String>,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "task `{}`: {}", self.task, self.problem)
    }
}

/// Checks every task against the catalogues (`catalogues[i]` belongs to connector `i`;
/// `None` when that connector has no catalogue to check against, like the scripted one).
pub fn check(
    tasks: &[TaskUse],
    config: &ConnectorsConfig,
    catalogues: &[Option<Catalogue>],
) -> Vec<Mismatch> {
    let mut out = Vec::new();
    for t in tasks {
        let mut problem = |field: Option<String>, problem: String| {
            out.push(Mismatch {
                task: t.task.clone(),
                field,
                problem,
            })
        };
        let input = |p: &str| Some(format!("input:{p}"));
        let output = |p: &str| Some(format!("output:{p}"));
        let resource = || Some("resource".to_owned());
        let Some(route) = config.route(&t.resource) else {
            problem(
                resource(),
                format!("no connector serves resource `{}`", t.resource),
            );
            continue;
        };
        let connector = &config.connectors[route.connector];
        let Some(Some(cat)) = catalogues.get(route.connector) else {
            continue;
        };
        let Some(spec) = cat.action(&route.action) else {
            problem(
                resource(),
                format!(
                    "action `{}` (resource `{}`) is not served by `{}` (connector `{}`)",
                    route.action,
                    t.resource,
                    connector.server(),
                    connector.name
                ),
            );
            continue;
        };
        for (path, declared) in &t.inputs {
            match field_at(&spec.goal, path) {
                None => problem(
                    input(path),
                    format!("input `{path}` is not a goal field of `{}`", spec.name),
                ),
                Some(want) => {
                    if let Some(d) = declared
                        && !want.accepts(d)
                    {
                        problem(
                            input(path),
                            format!(
                                "input `{path}` is declared {d} but `{}` expects {want}",
                                spec.name
                            ),
                        );
                    }
                }
            }
        }
        for (path, value) in &t.constants {
            if let Some(want) = field_at(&spec.goal, path)
                && let Err(e) = want.check(path, value)
            {
                problem(
                    input(path),
                    format!("input {e} (`{}` expects {want})", spec.name),
                );
            }
        }
        // Required goal fields (nested ones too) the task does not write.
        if !t.inputs.is_empty() {
            let mut required = Vec::new();
            required_paths(&spec.goal, "", &mut required);
            for name in required {
                let written = t.inputs.iter().any(|(p, _)| {
                    p == &name
                        || name.starts_with(&format!("{p}."))
                        || p.starts_with(&format!("{name}."))
                });
                if !written {
                    problem(
                        None,
                        format!(
                            "required goal field `{name}` of `{}` is not written by any input",
                            spec.name
                        ),
                    );
                }
            }
        }
        for (path, declared) in &t.outputs {
            match field_at(&spec.result, path) {
                None => problem(
                    output(path),
                    format!(
                        "output reads `{path}`, which is not a result field of `{}`",
                        spec.name
                    ),
                ),
                Some(have) => {
                    if let Some(d) = declared
                        && !d.accepts(have)
                    {
                        problem(
                            output(path),
                            format!(
                                "output `{path}` is declared {d} but `{}` returns {have}",
                                spec.name
                            ),
                        );
                    }
                }
            }
        }
        for code in &t.caught {
            if !spec.errors.contains_key(code) && !codes::ALL.contains(&code.as_str()) {
                problem(
                    None,
                    format!(
                        "an error boundary catches `{code}`, which `{}` does not declare (declared: {})",
                        spec.name,
                        if spec.errors.is_empty() {
                            "none".to_owned()
                        } else {
                            spec.errors.keys().cloned().collect::<Vec<_>>().join(", ")
                        }
                    ),
                );
            }
        }
    }
    out
}

/// Every required leaf path of a message (objects are walked, optional fields skipped).
fn required_paths(
    fields: &std::collections::BTreeMap<String, Type>,
    prefix: &str,
    out: &mut Vec<String>,
) {
    for (name, ty) in fields {
        let path = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        match ty {
            Type::Optional(_) => {}
            Type::Object(inner) => required_paths(inner, &path, out),
            _ => out.push(path),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalogue::ActionSpec;
    use crate::routes::{ConnectorConfig, Kind};

    #[test]
    fn every_problem_is_listed() {
        let config = lander_config();
        let cat = Catalogue {
            server: "lander".into(),
            actions: vec![
                serde_json::from_value::<ActionSpec>(serde_json::json!({
                    "name": "arm.move",
                    "goal": {"target": {"x": "f64", "y": "f64"}, "speed": "f64?", "joint": "u8?", "mode": "i32?"},
                    "result": {"reached": "bool"},
                    "errors": {"ARM_FAULT": "joint fault"}
                }))
                .unwrap(),
            ],
            ..Catalogue::default()
        };
        let tasks = vec![
            TaskUse {
                task: "Move".into(),
                resource: "arm.move".into(),
                inputs: vec![
                    ("target.x".into(), Some(Type::Int)),
                    ("target.z".into(), None),
                    ("speed".into(), Some(Type::String)),
                    ("joint".into(), None),
                    ("mode".into(), None),
                ],
                constants: vec![
                    ("joint".into(), serde_json::json!(300)),
                    ("mode".into(), serde_json::json!("fast")),
                ],
                outputs: vec![("reached".into(), Some(Type::Int)), ("pose".into(), None)],
                caught: vec![
                    "ARM_FAULT".into(),
                    "TOOL_STUCK".into(),
                    "CONNECTOR_LOST".into(),
                ],
                ..Default::default()
            },
            TaskUse {
                task: "Dig".into(),
                resource: "arm.dig".into(),
                ..Default::default()
            },
            TaskUse {
                task: "Pic".into(),
                resource: "camera.pic".into(),
                ..Default::default()
            },
        ];
        let found: Vec<String> = check(&tasks, &config, &[Some(cat)])
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            found,
            [
                "task `Move`: input `target.z` is not a goal field of `arm.move`",
                "task `Move`: input `speed` is declared string but `arm.move` expects f64?",
                "task `Move`: input `joint` is 300, outside the range of u8 (0..=255) (`arm.move` expects u8?)",
                "task `Move`: input `mode` must be i32, got a string (`arm.move` expects i32?)",
                "task `Move`: required goal field `target.y` of `arm.move` is not written by any input",
                "task `Move`: output `reached` is declared int but `arm.move` returns bool",
                "task `Move`: output reads `pose`, which is not a result field of `arm.move`",
                "task `Move`: an error boundary catches `TOOL_STUCK`, which `arm.move` does not declare (declared: ARM_FAULT)",
                "task `Dig`: action `arm.dig` (resource `arm.dig`) is not served by `lander` (connector `lander`)",
                "task `Pic`: no connector serves resource `camera.pic`",
            ]
        );
    }

    #[test]
    fn a_task_on_an_unbounded_action_without_a_timer_boundary_is_named() {
        let config: ConnectorsConfig = lander_config();
        let cat: Catalogue = serde_json::from_value(serde_json::json!({
            "server": "lander",
            "actions": [
                {"name": "arm.move", "cost": {"duration_s": 30.0, "power_w": 1.0}},
                {"name": "arm.wait"},
            ]
        }))
        .unwrap();
        let task = |id: &str, resource: &str, timed: bool| TaskUse {
            task: id.into(),
            resource: resource.into(),
            timed,
            ..Default::default()
        };
        let tasks = [
            task("Move", "arm.move", false),
            task("Wait", "arm.wait", false),
            task("Guarded", "arm.wait", true),
        ];
        let found = unbounded(&tasks, &config, &[Some(cat)]);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].task, "Wait");
        assert!(found[0].problem.contains("no upper bound"), "{}", found[0]);
    }

    fn lander_config() -> ConnectorsConfig {
        ConnectorsConfig {
            connectors: vec![ConnectorConfig {
                name: "lander".into(),
                kind: Kind::Zenoh,
                server: None,
                resources: vec!["arm.*".into()],
                actions: Default::default(),
                data: vec![],
                deadband: Default::default(),
                grace_ms: 1,
                clock: false,
                answers: false,
                limits: Default::default(),
                ros2: Default::default(),
            }],
        }
    }
}
