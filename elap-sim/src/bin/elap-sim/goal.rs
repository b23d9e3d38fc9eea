//! A goal the simulator executes, whichever way it came: over the Zenoh activity protocol, or
//! as a ROS 2 action goal (`--ros2`). The activity is the same; only how it is acknowledged,
//! reported and ended differs.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use connector_api::{ActionRoute, ConnectorsConfig, Fields, Ros2Action, Ros2Settings, Status};
use connector_ros2::ServedGoal;
use connector_zenoh::GoalHandle;

/// A goal under way.
pub(crate) enum Goal {
    /// From the executive's Zenoh connector.
    Zenoh(GoalHandle),
    /// From a ROS 2 action client; the flag is set once the client asks to cancel.
    Ros2(ServedGoal, Arc<AtomicBool>),
}

impl Goal {
    /// The key the simulator keeps the activity under.
    pub(crate) fn id(&self) -> String {
        match self {
            Goal::Zenoh(h) => h.goal_id.clone(),
            Goal::Ros2(g, _) => ros2_id(&g.uuid),
        }
    }

    pub(crate) fn action(&self) -> &str {
        match self {
            Goal::Zenoh(h) => &h.action,
            Goal::Ros2(g, _) => &g.resource,
        }
    }

    pub(crate) fn fields(&self) -> &Fields {
        match self {
            Goal::Zenoh(h) => &h.fields,
            Goal::Ros2(g, _) => &g.fields,
        }
    }

    /// Says the activity runs (ROS 2: the server's execute callback already says so).
    pub(crate) async fn executing(&self) {
        if let Goal::Zenoh(h) = self {
            h.executing().await;
        }
    }

    /// Whether the client has asked to cancel (Zenoh: a cancel accepted before a restart).
    pub(crate) fn cancel_asked(&self) -> bool {
        match self {
            Goal::Zenoh(h) => h.status() == Status::Canceling,
            Goal::Ros2(_, asked) => asked.load(Ordering::SeqCst),
        }
    }

    pub(crate) async fn feedback(&self, percent: f64) {
        match self {
            Goal::Zenoh(h) => h.feedback(Some(percent), Fields::default()).await,
            Goal::Ros2(g, _) => {
                let mut f = Fields::new();
                f.insert("percent".into(), percent.into());
                g.feedback(f);
            }
        }
    }

    pub(crate) async fn succeed(&self, outputs: Fields) {
        match self {
            Goal::Zenoh(h) => {
                h.succeed(outputs).await;
            }
            Goal::Ros2(g, _) => g.succeed(outputs),
        }
    }

    pub(crate) async fn abort(&self, code: &str, message: &str) {
        match self {
            Goal::Zenoh(h) => {
                h.abort(code, message).await;
            }
            Goal::Ros2(g, _) => g.abort(code, message),
        }
    }

    pub(crate) async fn canceled(&self, partial: Fields) {
        match self {
            Goal::Zenoh(h) => {
                h.canceled(partial).await;
            }
            Goal::Ros2(g, _) => g.canceled(partial),
        }
    }
}

/// The simulator's key for the ROS 2 goal of this UUID.
pub(crate) fn ros2_id(uuid: &str) -> String {
    format!("ros2-{uuid}")
}

/// The actions a connectors file routes to ROS 2, per ROS 2 connector: how it joins the ROS
/// graph, and each resource's action.
pub(crate) type Ros2Routes = Vec<(String, Ros2Settings, BTreeMap<String, Ros2Action>)>;

/// Reads the ROS 2 routes of a connectors file.
pub(crate) fn ros2_routes(path: &Path) -> anyhow::Result<Ros2Routes> {
    let text =
        std::fs::read_to_string(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let config: ConnectorsConfig =
        toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let config = config.beside(path.parent().unwrap_or(Path::new("")));
    let routes: Ros2Routes = config
        .connectors
        .into_iter()
        .filter(|c| c.kind == connector_api::Kind::Ros2)
        .map(|c| {
            let actions = c
                .actions
                .into_iter()
                .filter_map(|(r, a)| match a {
                    ActionRoute::Ros2(a) => Some((r, a)),
                    ActionRoute::Name(_) => None,
                })
                .collect();
            (c.name, c.ros2, actions)
        })
        .collect();
    anyhow::ensure!(
        routes.iter().any(|(_, _, a)| !a.is_empty()),
        "{}: no `kind = \"ros2\"` connector routes an action",
        path.display()
    );
    Ok(routes)
}
