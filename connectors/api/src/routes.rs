//! The connector configuration (`deploy/connectors.toml`): which connectors the executive
//! loads, and which resource names each one serves, mapped to action names — the paper's XML
//! configuration of activities.

use std::collections::BTreeMap;

use serde::Deserialize;

/// The whole configuration file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConnectorsConfig {
    /// The connectors, in order.
    #[serde(default, rename = "connector")]
    pub connectors: Vec<ConnectorConfig>,
}

/// What kind of connector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// A system in another process, over the Zenoh activity protocol.
    Zenoh,
    /// The in-process scripted connector (tests, dry runs).
    Script,
    /// ROS 2 action servers (`connectors/ros2`).
    Ros2,
}

/// One connector.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConnectorConfig {
    /// Its name in logs and the execution record.
    pub name: String,
    /// Its kind.
    pub kind: Kind,
    /// Zenoh: the server id whose actions it calls (`lander_sim`); defaults to `name`.
    #[serde(default)]
    pub server: Option<String>,
    /// Resource names it serves: exact names, or prefixes ending in `*` (`arm.*`). The
    /// longest match over all connectors wins.
    #[serde(default)]
    pub resources: Vec<String>,
    /// Resource name → action name, where they differ (`functional.excavate_site` →
    /// `excavation.excavate`); other resources call the action of the same name. ROS 2: the
    /// action's name and type (`{ action = "/fibonacci", type = "test_msgs/action/Fibonacci" }`),
    /// the resource naming its catalogue entry.
    #[serde(default)]
    pub actions: BTreeMap<String, ActionRoute>,
    /// Telemetry keys fed to the mission as system data (conditional events, gateway
    /// conditions).
    #[serde(default)]
    pub data: Vec<String>,
    /// Per data key: the smallest change of a number that is fed to the mission (others are
    /// dropped, so telemetry cannot flood the journal).
    #[serde(default)]
    pub deadband: BTreeMap<String, f64>,
    /// Zenoh: milliseconds a server may be gone while it runs a goal before the goal fails
    /// with `CONNECTOR_LOST`.
    #[serde(default = "default_grace")]
    pub grace_ms: u64,
    /// Zenoh: this connector's system supplies the mission clock.
    #[serde(default)]
    pub clock: bool,
    /// Zenoh: the server is a set of ground stations answering user tasks. Every goal and
    /// cancel goes to all of them; answers arrive as `answer` queries, the executive checks
    /// each and the first valid one wins (`docs/protocol.md` § Ground stations).
    #[serde(default)]
    pub answers: bool,
    /// Zenoh: how long goals may stay unacknowledged, how often the server is asked again and
    /// how loudly refusals are logged (`[connector.limits]`; every field has a default).
    #[serde(default)]
    pub limits: crate::contract::Limits,
    /// ROS 2: how the connector joins the ROS graph (`[connector.ros2]`).
    #[serde(default)]
    pub ros2: Ros2Settings,
}

/// Where a resource goes on its connector.
#[derive(Clone, Debug, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum ActionRoute {
    /// An action of the connector's server, by name.
    Name(String),
    /// A ROS 2 action.
    Ros2(Ros2Action),
}

/// A ROS 2 action a resource calls.
#[derive(Clone, Debug, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ros2Action {
    /// Its name in the ROS graph (`/fibonacci`; relative names take the connector's namespace).
    pub action: String,
    /// Its type (`test_msgs/action/Fibonacci`).
    #[serde(rename = "type")]
    pub ty: String,
    /// A result field that carries an error code: an `ABORTED` goal fails with its value
    /// (when it is a non-empty text) instead of `ABORTED`.
    #[serde(default)]
    pub error_field: Option<String>,
}

/// How a ROS 2 connector joins the ROS graph; every field has a default.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ros2Settings {
    /// `ROS_DOMAIN_ID` (default: the environment's, else 0).
    pub domain_id: Option<u32>,
    /// The namespace relative action names are resolved in (`/lander`).
    pub namespace: Option<String>,
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE`: `localhost`, `subnet`, `off` or `system_default`
    /// (default: the environment's).
    pub discovery: Option<String>,
    /// Directories of `.action` and `.msg` definitions besides `AMENT_PREFIX_PATH`'s (relative
    /// to the connectors file).
    #[serde(default)]
    pub definitions: Vec<std::path::PathBuf>,
    /// The Python that has `rclpy` and the actions' packages (default: `python3`).
    pub python: Option<String>,
}

fn default_grace() -> u64 {
    3000
}

impl ConnectorsConfig {
    /// The configuration read from a file in `dir`: relative paths in it (a ROS 2 connector's
    /// `definitions`) are relative to the file, not to where a command runs.
    pub fn beside(mut self, dir: &std::path::Path) -> ConnectorsConfig {
        for c in &mut self.connectors {
            for d in &mut c.ros2.definitions {
                if d.is_relative() {
                    *d = dir.join(&*d);
                }
            }
        }
        self
    }
}

impl ConnectorConfig {
    /// The Zenoh server id.
    pub fn server(&self) -> &str {
        self.server.as_deref().unwrap_or(&self.name)
    }
}

/// Where one resource goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Route {
    /// Index of the connector in the configuration.
    pub connector: usize,
    /// The action to call.
    pub action: String,
}

impl ConnectorsConfig {
    /// The connector and action for a resource: an explicit `actions` entry, else the longest
    /// matching `resources` pattern (an exact name beats any prefix).
    pub fn route(&self, resource: &str) -> Option<Route> {
        let mut best: Option<(usize, usize)> = None; // (score, connector)
        for (i, c) in self.connectors.iter().enumerate() {
            if let Some(to) = c.actions.get(resource) {
                return Some(Route {
                    connector: i,
                    action: match to {
                        ActionRoute::Name(n) => n.clone(),
                        ActionRoute::Ros2(_) => resource.to_owned(),
                    },
                });
            }
            for p in &c.resources {
                let score = match p.strip_suffix('*') {
                    Some(prefix) if resource.starts_with(prefix) => prefix.len(),
                    None if p == resource => usize::MAX,
                    _ => continue,
                };
                if best.is_none_or(|(s, _)| score > s) {
                    best = Some((score, i));
                }
            }
        }
        best.map(|(_, i)| Route {
            connector: i,
            action: resource.to_owned(),
        })
    }

    /// Problems in the configuration itself (duplicate names, bad chunks), all of them.
    pub fn problems(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (i, c) in self.connectors.iter().enumerate() {
            if self.connectors[..i].iter().any(|o| o.name == c.name) {
                out.push(format!("connector `{}` is configured twice", c.name));
            }
            if c.kind == Kind::Zenoh
                && let Err(e) = crate::keys::check_chunk(c.server())
            {
                out.push(format!("connector `{}`: server {e}", c.name));
            }
            for (resource, a) in &c.actions {
                match (a, c.kind) {
                    (ActionRoute::Name(a), _) => {
                        if let Err(e) = crate::keys::check_chunk(a) {
                            out.push(format!("connector `{}`: action {e}", c.name));
                        }
                    }
                    (ActionRoute::Ros2(_), Kind::Ros2) => {}
                    (ActionRoute::Ros2(_), _) => out.push(format!(
                        "connector `{}`: `{resource}` names a ROS 2 action, but the connector's kind is not `ros2`",
                        c.name
                    )),
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> ConnectorsConfig {
        ConnectorsConfig {
            connectors: vec![
                ConnectorConfig {
                    name: "lander".into(),
                    kind: Kind::Zenoh,
                    server: Some("lander_sim".into()),
                    resources: vec!["*".into(), "arm.*".into()],
                    actions: [(
                        "functional.excavate_site".into(),
                        ActionRoute::Name("excavation.excavate".into()),
                    )]
                    .into(),
                    data: vec![],
                    deadband: BTreeMap::new(),
                    grace_ms: 1000,
                    clock: false,
                    answers: false,
                    limits: Default::default(),
                    ros2: Default::default(),
                },
                ConnectorConfig {
                    name: "ground".into(),
                    kind: Kind::Zenoh,
                    server: None,
                    resources: vec!["ground.*".into(), "arm.stow".into()],
                    actions: BTreeMap::new(),
                    data: vec![],
                    deadband: BTreeMap::new(),
                    grace_ms: 1000,
                    clock: false,
                    answers: false,
                    limits: Default::default(),
                    ros2: Default::default(),
                },
            ],
        }
    }

    #[test]
    fn longest_match_wins_and_actions_map() {
        let c = cfg();
        assert_eq!(c.route("arm.unstow").unwrap().connector, 0);
        assert_eq!(c.route("arm.stow").unwrap().connector, 1);
        assert_eq!(c.route("ground.approve_site").unwrap().connector, 1);
        assert_eq!(c.route("camera.take").unwrap().connector, 0);
        assert_eq!(
            c.route("functional.excavate_site").unwrap().action,
            "excavation.excavate"
        );
        assert!(c.problems().is_empty());
    }

    #[test]
    fn limits_are_configured_per_connector_with_defaults_for_the_rest() {
        let c: ConnectorsConfig = toml::from_str(
            r#"
            [[connector]]
            name = "lander"
            kind = "zenoh"
            resources = ["*"]
            limits = { accept_within_ms = 2000, unreadable_max = 3 }
            "#,
        )
        .expect("parses");
        let limits = &c.connectors[0].limits;
        assert_eq!(limits.accept_within_ms, 2000);
        assert_eq!(limits.unreadable_max, 3);
        assert_eq!(
            limits.retry_max_ms,
            crate::contract::Limits::default().retry_max_ms
        );
        let wrong = toml::from_str::<ConnectorsConfig>(
            "[[connector]]\nname = \"x\"\nkind = \"zenoh\"\nlimits = { accept_in = 1 }\n",
        );
        assert!(wrong.unwrap_err().to_string().contains("accept_in"));
    }
}
