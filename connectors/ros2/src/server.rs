//! Serving ROS 2 actions from a Rust system: the other side of the connector. A system (the
//! ELAP simulator) names the actions it serves, each by its resource and its ROS 2 route as a
//! connectors file writes it; [`Ros2Server`] runs one `rclpy` node with an action server for
//! each ([`crate::connector::BRIDGE`] in its `server` role), and hands the system each goal
//! accepted and each cancel asked. The system ends each goal once: succeeded with its result,
//! aborted with an error code (written to the route's `error_field`), or canceled.
//!
//! The node lives as long as the system: when the system exits, however it exits, the node reads
//! the end of its input, aborts the goals it holds and exits too. Goals are not kept across a
//! restart: a client that followed one sees its server go (`CONNECTOR_LOST` in TRACE).

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use connector_api::{Ros2Action, Ros2Settings};
use serde_json::{Map, Value, json};
use tokio::sync::mpsc::{UnboundedReceiver, UnboundedSender, unbounded_channel};

use crate::connector::bridge;

/// How long the node may take to start and serve every action (importing `rclpy` and the
/// actions' types takes a second or two).
const START_WITHIN: Duration = Duration::from_secs(60);

/// Why the servers did not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The Python process did not start.
    #[error("the ROS 2 node (rclpy, `{python}`) does not start: {source}")]
    Spawn {
        /// The interpreter.
        python: String,
        /// Why.
        source: std::io::Error,
    },
    /// The node refused an action, or exited, or did not answer in time.
    #[error("the ROS 2 node does not serve `{resource}`: {reason}")]
    Serve {
        /// The action's resource.
        resource: String,
        /// Why (the node's words, or what it did not do).
        reason: String,
    },
}

/// What the system is asked.
#[derive(Debug)]
pub enum Request {
    /// A goal accepted: execute it, then end it.
    Goal(ServedGoal),
    /// The client asks to cancel the goal of this UUID.
    Cancel(String),
}

/// A goal the system executes.
#[derive(Clone, Debug)]
pub struct ServedGoal {
    /// The goal's UUID (32 hex digits, as the client chose it).
    pub uuid: String,
    /// The resource of the action it is a goal of.
    pub resource: String,
    /// The goal's fields.
    pub fields: Map<String, Value>,
    error_field: Option<String>,
    input: Input,
}

type Input = Arc<Mutex<ChildStdin>>;

fn write(input: &Input, v: &Value) {
    let mut i = input.lock().unwrap_or_else(|p| p.into_inner());
    if writeln!(i, "{v}").and_then(|()| i.flush()).is_err() {
        tracing::warn!("the ROS 2 node does not read (it has exited)");
    }
}

impl ServedGoal {
    /// Publishes feedback.
    pub fn feedback(&self, fields: Map<String, Value>) {
        write(
            &self.input,
            &json!({"op": "feedback", "uuid": self.uuid, "fields": fields}),
        );
    }

    /// Ends the goal `SUCCEEDED` with its result.
    pub fn succeed(&self, fields: Map<String, Value>) {
        write(
            &self.input,
            &json!({"op": "succeed", "uuid": self.uuid, "fields": fields}),
        );
    }

    /// Ends the goal `ABORTED`, its code in the route's error field (where it has one).
    pub fn abort(&self, code: &str, message: &str) {
        tracing::info!(
            resource = self.resource,
            code,
            message,
            "ROS 2 goal aborted"
        );
        let mut fields = Map::new();
        if let Some(f) = &self.error_field {
            fields.insert(f.clone(), Value::from(code));
        }
        write(
            &self.input,
            &json!({"op": "abort", "uuid": self.uuid, "fields": fields}),
        );
    }

    /// Ends the goal `CANCELED` (after its client asked), with what it achieved.
    pub fn canceled(&self, fields: Map<String, Value>) {
        write(
            &self.input,
            &json!({"op": "canceled", "uuid": self.uuid, "fields": fields}),
        );
    }
}

/// The node serving the system's actions; dropping it stops the node.
pub struct Ros2Server {
    child: Child,
}

impl Drop for Ros2Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// What the node's output reader passes on while the node starts.
enum Started {
    Serving(String),
    Failed(String, String),
}

impl Ros2Server {
    /// Starts a node named for `name` serving `actions` (resource → route), joining the ROS
    /// graph as `settings` say, and returns once every action is served. Blocks while the node
    /// starts (seconds): call it before serving anything else.
    pub fn start(
        name: &str,
        settings: &Ros2Settings,
        actions: &BTreeMap<String, Ros2Action>,
    ) -> Result<(Ros2Server, UnboundedReceiver<Request>), ServeError> {
        let python = settings.python.clone().unwrap_or_else(|| "python3".into());
        let mut child =
            bridge(settings, "server", name)
                .spawn()
                .map_err(|source| ServeError::Spawn {
                    python: python.clone(),
                    source,
                })?;
        let (Some(stdin), Some(stdout), Some(stderr)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            unreachable!("the bridge's pipes are asked for");
        };
        let server = Ros2Server { child };
        let input: Input = Arc::new(Mutex::new(stdin));
        let errors: BTreeMap<String, Option<String>> = actions
            .iter()
            .map(|(r, a)| (r.clone(), a.error_field.clone()))
            .collect();
        let (requests, rx) = unbounded_channel();
        let (started, starting) = mpsc::channel();
        let reader = Reader {
            input: Arc::clone(&input),
            errors,
            requests,
            started,
        };
        std::thread::spawn(move || reader.run(stdout));
        let label = name.to_owned();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
                .take(10_000)
            {
                tracing::debug!(node = label, "rclpy: {line}");
            }
        });
        for (resource, a) in actions {
            write(
                &input,
                &json!({"op": "serve", "resource": resource, "action": a.action, "type": a.ty}),
            );
        }
        let mut waiting: std::collections::BTreeSet<&String> = actions.keys().collect();
        while !waiting.is_empty() {
            let first = waiting.first().map(|r| (*r).clone()).unwrap_or_default();
            match starting.recv_timeout(START_WITHIN) {
                Ok(Started::Serving(r)) => {
                    waiting.remove(&r);
                }
                Ok(Started::Failed(resource, reason)) => {
                    return Err(ServeError::Serve { resource, reason });
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    return Err(ServeError::Serve {
                        resource: first,
                        reason: format!("not served within {START_WITHIN:?}"),
                    });
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(ServeError::Serve {
                        resource: first,
                        reason: format!(
                            "the node exited (is `{python}` a Python with rclpy and the action's package?)"
                        ),
                    });
                }
            }
        }
        tracing::info!(
            node = name,
            actions = actions.len(),
            "serving ROS 2 actions"
        );
        Ok((server, rx))
    }
}

/// Reads the node's events.
struct Reader {
    input: Input,
    errors: BTreeMap<String, Option<String>>,
    requests: UnboundedSender<Request>,
    started: mpsc::Sender<Started>,
}

impl Reader {
    fn run(self, stdout: std::process::ChildStdout) {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let Ok(v) = serde_json::from_str::<Value>(&line) else {
                tracing::warn!("the ROS 2 node said: {line}");
                continue;
            };
            let text = |k: &str| v[k].as_str().unwrap_or_default().to_owned();
            match v["ev"].as_str().unwrap_or_default() {
                "serving" => {
                    let _ = self.started.send(Started::Serving(text("resource")));
                }
                "goal" => {
                    let resource = text("resource");
                    let goal = ServedGoal {
                        uuid: text("uuid"),
                        error_field: self.errors.get(&resource).cloned().flatten(),
                        resource,
                        fields: v["fields"].as_object().cloned().unwrap_or_default(),
                        input: Arc::clone(&self.input),
                    };
                    let _ = self.requests.send(Request::Goal(goal));
                }
                "cancel" => {
                    let _ = self.requests.send(Request::Cancel(text("uuid")));
                }
                "unserved" => {
                    // An action type that does not import, a name that is not a name.
                    let _ = self
                        .started
                        .send(Started::Failed(text("resource"), text("reason")));
                }
                "error" => tracing::warn!(goal = text("uuid"), "ROS 2 node: {}", text("reason")),
                _ => tracing::debug!("the ROS 2 node said: {line}"),
            }
        }
        tracing::warn!("the ROS 2 node exited");
    }
}
