//! The executive's ROS 2 connector: goals, feedback, results and cancels of ROS 2 actions,
//! through one `rclpy` node ([`BRIDGE`], a child process the connector drives over a pipe, one
//! JSON object per line).
//!
//! Why `rclpy` and not a Rust client: the connector reads each action's type at run time from
//! its definition, and `rclpy` (ROS 2's own client library) builds the messages, their
//! serialisation and type hashes for any type at run time, on whichever middleware the
//! installation uses (Fast DDS, Cyclone DDS, Zenoh). The Rust clients (`ros2-client`) need each
//! message type as a Rust type at compile time. A robot that runs ROS 2 has `rclpy`.
//!
//! - A goal is sent once its action's server is there; a server that does not appear within
//!   `limits.accept_within_ms` gives `NOT_ACCEPTED`.
//! - The goal's UUID is derived from TRACE's goal id ([`goal_uuid`]), so after a restart the
//!   connector asks the server for the result of the same goal (`reconcile`) instead of starting
//!   it again; a server that does not know it gives `CONNECTOR_LOST`.
//! - `SUCCEEDED` completes the task with the result's fields; `ABORTED` fails it with `ABORTED`,
//!   or with the value of the route's `error_field`; `CANCELED` after our cancel withdraws it.
//! - A server that goes while it runs a goal and is not back within `grace_ms` gives
//!   `CONNECTOR_LOST`; so does the bridge exiting (it is started again for the next goal).

use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command as Process, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use connector_api::contract::{BoxFuture, ConnectorError};
use connector_api::{
    ActionRoute, Catalogue, Command, Connector, ConnectorConfig, Report, Reports, Ros2Settings,
};
use serde_json::{Value, json};

/// How long a closing connector waits for the answers to the cancels it sent.
const CANCELS_WITHIN: Duration = Duration::from_secs(2);

/// The `rclpy` node the connector drives.
pub const BRIDGE: &str = include_str!("bridge.py");

/// A UUID for a goal id, the same every time (FNV-1a, 128 bits, marked as a version-8 UUID).
pub fn goal_uuid(goal_id: &str) -> String {
    let mut h: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    for b in goal_id.bytes() {
        h ^= u128::from(b);
        h = h.wrapping_mul(0x0000_0000_0100_0000_0000_0000_0000_013b);
    }
    let mut bytes = h.to_be_bytes();
    bytes[6] = (bytes[6] & 0x0f) | 0x80;
    bytes[8] = (bytes[8] & 0x3f) | 0x80;
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What the connector's methods ask of its worker thread.
enum Ask {
    Goal(Command, bool),
    Cancel(String),
    /// Stop, once the cancels sent have been answered (at most [`CANCELS_WITHIN`]); `done`
    /// hears when the bridge is gone.
    Close(Option<tokio::sync::oneshot::Sender<()>>),
}

/// What reaches the worker.
enum Msg {
    Ask(Ask),
    Line(String),
    Exited,
}

/// The ROS 2 connector.
pub struct Ros2Connector {
    name: String,
    catalogue: Result<Catalogue, String>,
    to_worker: mpsc::Sender<Msg>,
}

impl Ros2Connector {
    /// Starts the connector of `config` (its bridge runs from now on); reports go to `reports`.
    pub fn new(config: &ConnectorConfig, reports: Reports) -> Ros2Connector {
        let catalogue = crate::catalogue_of(config).map_err(|e| e.to_string());
        let (tx, rx) = mpsc::channel();
        let worker = Worker {
            config: config.clone(),
            reports,
            inbox: tx.clone(),
            bridge: None,
            goals: HashMap::new(),
            up: BTreeMap::new(),
        };
        std::thread::Builder::new()
            .name(format!("ros2-{}", config.name))
            .spawn(move || worker.run(rx))
            .expect("a thread");
        Ros2Connector {
            name: config.name.clone(),
            catalogue,
            to_worker: tx,
        }
    }

    fn ask(&self, a: Ask) {
        if self.to_worker.send(Msg::Ask(a)).is_err() {
            tracing::error!(
                connector = self.name,
                "the ROS 2 connector's worker has stopped"
            );
        }
    }
}

impl Connector for Ros2Connector {
    fn name(&self) -> &str {
        &self.name
    }

    fn catalogue(&mut self) -> BoxFuture<'_, Result<Option<Catalogue>, ConnectorError>> {
        let out = match &self.catalogue {
            Ok(c) => Ok(Some(c.clone())),
            Err(reason) => Err(ConnectorError::Protocol {
                system: self.name.clone(),
                reason: reason.clone(),
            }),
        };
        Box::pin(async move { out })
    }

    fn execute(&mut self, command: Command) {
        self.ask(Ask::Goal(command, false));
    }

    fn reconcile(&mut self, command: Command) {
        self.ask(Ask::Goal(command, true));
    }

    fn abort(&mut self, goal_id: &str) {
        self.ask(Ask::Cancel(goal_id.to_owned()));
    }

    fn notify(&mut self, name: &str, _payload: Value) {
        tracing::debug!(
            connector = self.name,
            name,
            "a ROS 2 connector takes no notifications"
        );
    }

    fn close(&mut self) -> BoxFuture<'_, ()> {
        let (done, gone) = tokio::sync::oneshot::channel();
        self.ask(Ask::Close(Some(done)));
        Box::pin(async move {
            let _ = tokio::time::timeout(CANCELS_WITHIN + Duration::from_secs(1), gone).await;
        })
    }
}

impl Drop for Ros2Connector {
    fn drop(&mut self) {
        let _ = self.to_worker.send(Msg::Ask(Ask::Close(None)));
    }
}

/// A goal the connector follows.
struct Goal {
    command: Command,
    resume: bool,
    action: String,
    error_field: Option<String>,
    since: Instant,
    sent: bool,
    cancelled: bool,
}

struct Bridge {
    child: Child,
    stdin: ChildStdin,
}

struct Worker {
    config: ConnectorConfig,
    reports: Reports,
    inbox: mpsc::Sender<Msg>,
    bridge: Option<Bridge>,
    goals: HashMap<String, Goal>,
    /// Each action's server: there, or gone since when.
    up: BTreeMap<String, Result<(), Instant>>,
}

impl Worker {
    fn run(mut self, rx: mpsc::Receiver<Msg>) {
        self.start();
        // Closing: since when, and who waits for the end.
        let mut closing: Option<(Instant, Option<tokio::sync::oneshot::Sender<()>>)> = None;
        loop {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(Msg::Ask(Ask::Close(done))) => {
                    closing.get_or_insert((Instant::now(), done));
                }
                Ok(Msg::Ask(Ask::Goal(c, resume))) => self.goal(c, resume),
                Ok(Msg::Ask(Ask::Cancel(id))) => self.cancel(&id),
                Ok(Msg::Line(l)) => self.line(&l),
                Ok(Msg::Exited) => self.exited(),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            self.tick();
            // A cancel sent reaches its server before the bridge goes: its answer is awaited.
            if let Some((at, _)) = &closing
                && (!self.goals.values().any(|g| g.cancelled) || at.elapsed() > CANCELS_WITHIN)
            {
                break;
            }
        }
        if let Some(mut b) = self.bridge.take() {
            let _ = b.child.kill();
            let _ = b.child.wait();
        }
        if let Some((_, Some(done))) = closing {
            let _ = done.send(());
        }
    }

    /// Starts the bridge and asks it to watch every action's server.
    fn start(&mut self) {
        let mut p = bridge(&self.config.ros2, "client", &self.config.name);
        let mut child = match p.spawn() {
            Ok(c) => c,
            Err(e) => {
                tracing::error!(connector = self.config.name, error = %e, "the ROS 2 bridge (rclpy) does not start");
                return;
            }
        };
        let (Some(stdin), Some(stdout), Some(stderr)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            return;
        };
        let tx = self.inbox.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(Msg::Line(line)).is_err() {
                    return;
                }
            }
            let _ = tx.send(Msg::Exited);
        });
        let name = self.config.name.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
                .take(10_000)
            {
                tracing::debug!(connector = name, "rclpy: {line}");
            }
        });
        self.bridge = Some(Bridge { child, stdin });
        let watch: Vec<Value> = self
            .config
            .actions
            .values()
            .filter_map(|route| match route {
                ActionRoute::Ros2(a) => {
                    Some(json!({"op": "watch", "action": a.action, "type": a.ty}))
                }
                ActionRoute::Name(_) => None,
            })
            .collect();
        for w in &watch {
            self.send(w);
        }
    }

    fn send(&mut self, v: &Value) {
        let Some(b) = &mut self.bridge else { return };
        if writeln!(b.stdin, "{v}")
            .and_then(|()| b.stdin.flush())
            .is_err()
        {
            tracing::warn!(
                connector = self.config.name,
                "the ROS 2 bridge does not read"
            );
        }
    }

    fn report(&self, r: Report) {
        let _ = self.reports.send(r);
    }

    fn fail(&mut self, goal_id: &str, code: &str, message: String) {
        self.goals.remove(goal_id);
        tracing::warn!(
            connector = self.config.name,
            goal = goal_id,
            code,
            "{message}"
        );
        self.report(Report::Failed {
            goal_id: goal_id.to_owned(),
            code: code.to_owned(),
            message,
        });
    }

    fn goal(&mut self, command: Command, resume: bool) {
        if self.goals.contains_key(&command.goal_id) {
            return;
        }
        let route = self
            .config
            .actions
            .get(&command.action)
            .and_then(|r| match r {
                ActionRoute::Ros2(a) => Some(a.clone()),
                ActionRoute::Name(_) => None,
            });
        let Some(route) = route else {
            let why = format!("`{}` is not routed to a ROS 2 action", command.action);
            return self.fail(&command.goal_id, "NO_CONNECTOR", why);
        };
        self.goals.insert(
            command.goal_id.clone(),
            Goal {
                command,
                resume,
                action: route.action,
                error_field: route.error_field,
                since: Instant::now(),
                sent: false,
                cancelled: false,
            },
        );
        if self.bridge.is_none() {
            self.start();
        }
    }

    fn cancel(&mut self, goal_id: &str) {
        let Some(g) = self.goals.get_mut(goal_id) else {
            return;
        };
        if g.sent {
            g.cancelled = true;
            self.send(&json!({"op": "cancel", "goal_id": goal_id}));
        } else {
            self.goals.remove(goal_id);
            self.report(Report::Canceled {
                goal_id: goal_id.to_owned(),
            });
        }
    }

    /// Sends the goals whose server is there; fails those that waited too long.
    fn tick(&mut self) {
        let accept = Duration::from_millis(self.config.limits.accept_within_ms);
        let grace = Duration::from_millis(self.config.grace_ms);
        let mut send = Vec::new();
        let mut failed = Vec::new();
        for (id, g) in &self.goals {
            match (g.sent, self.up.get(&g.action)) {
                (false, Some(Ok(()))) => send.push(id.clone()),
                (false, _) if g.since.elapsed() > accept => failed.push((
                    id.clone(),
                    "NOT_ACCEPTED",
                    format!("no server of `{}` appeared within {accept:?}", g.action),
                )),
                (true, Some(Err(gone))) if gone.elapsed() > grace => failed.push((
                    id.clone(),
                    "CONNECTOR_LOST",
                    format!(
                        "the server of `{}` went and did not return within {grace:?}",
                        g.action
                    ),
                )),
                _ => {}
            }
        }
        for (id, code, why) in failed {
            self.fail(&id, code, why);
        }
        for id in send {
            let Some(g) = self.goals.get_mut(&id) else {
                continue;
            };
            g.sent = true;
            let ty = match self.config.actions.get(&g.command.action) {
                Some(ActionRoute::Ros2(a)) => a.ty.clone(),
                _ => continue,
            };
            let v = json!({
                "op": if g.resume { "resume" } else { "goal" },
                "goal_id": id,
                "uuid": goal_uuid(&id),
                "action": g.action,
                "type": ty,
                "fields": g.command.fields,
            });
            self.send(&v);
        }
    }

    fn exited(&mut self) {
        if let Some(mut b) = self.bridge.take() {
            let _ = b.child.wait();
        }
        let sent: Vec<String> = self
            .goals
            .iter()
            .filter(|(_, g)| g.sent)
            .map(|(id, _)| id.clone())
            .collect();
        for id in sent {
            self.fail(
                &id,
                "CONNECTOR_LOST",
                "the ROS 2 bridge (rclpy) exited while the goal ran".into(),
            );
        }
        self.up.clear();
        tracing::warn!(
            connector = self.config.name,
            "the ROS 2 bridge exited; starting it again"
        );
        self.start();
    }

    /// One line of the bridge.
    fn line(&mut self, line: &str) {
        let Ok(v) = serde_json::from_str::<Value>(line) else {
            tracing::warn!(
                connector = self.config.name,
                "the ROS 2 bridge said: {line}"
            );
            return;
        };
        let text = |k: &str| v[k].as_str().unwrap_or_default().to_owned();
        let id = text("goal_id");
        let fields = || {
            v["fields"]
                .as_object()
                .map(|m| m.clone().into_iter().collect())
                .unwrap_or_default()
        };
        match v["ev"].as_str().unwrap_or_default() {
            "ready" => tracing::info!(connector = self.config.name, "ROS 2 bridge ready"),
            "server" => {
                let action = text("action");
                let state = if v["up"].as_bool() == Some(true) {
                    Ok(())
                } else {
                    Err(Instant::now())
                };
                tracing::info!(
                    connector = self.config.name,
                    action,
                    up = state.is_ok(),
                    "ROS 2 action server"
                );
                self.up.insert(action, state);
            }
            "accepted" if self.goals.contains_key(&id) => {
                self.report(Report::Accepted { goal_id: id });
            }
            "rejected" if self.goals.contains_key(&id) => {
                let why = format!("the server refused the goal: {}", text("reason"));
                self.fail(&id, "REJECTED", why);
            }
            "error" if self.goals.contains_key(&id) => {
                let why = format!("the goal could not be sent: {}", text("reason"));
                self.fail(&id, "TYPE_MISMATCH", why);
            }
            "feedback" if self.goals.contains_key(&id) => self.report(Report::Feedback {
                goal_id: id,
                progress_pct: None,
                fields: fields(),
            }),
            "result" => {
                let Some(g) = self.goals.remove(&id) else {
                    return;
                };
                match text("status").as_str() {
                    "SUCCEEDED" => self.report(Report::Done {
                        goal_id: id,
                        outputs: fields(),
                    }),
                    "CANCELED" if g.cancelled => self.report(Report::Canceled { goal_id: id }),
                    "UNKNOWN" => {
                        let why = format!("the server of `{}` does not know the goal", g.action);
                        self.fail(&id, "CONNECTOR_LOST", why);
                    }
                    status => {
                        let code = g
                            .error_field
                            .as_ref()
                            .and_then(|f| v["fields"][f].as_str())
                            .filter(|c| !c.is_empty())
                            .unwrap_or("ABORTED")
                            .to_owned();
                        let why = format!("the server of `{}` ended the goal {status}", g.action);
                        self.fail(&id, &code, why);
                    }
                }
            }
            _ => tracing::debug!(
                connector = self.config.name,
                "the ROS 2 bridge said: {line}"
            ),
        }
    }
}

/// The bridge's process in `role` (`client` or `server`), its node named for `name`, joining
/// the ROS graph as `settings` say.
pub(crate) fn bridge(settings: &Ros2Settings, role: &str, name: &str) -> Process {
    let mut p = Process::new(settings.python.as_deref().unwrap_or("python3"));
    p.arg("-c")
        .arg(BRIDGE)
        .arg(role)
        .arg(format!("trace_{}", sanitize(name)))
        .arg(settings.namespace.as_deref().unwrap_or(""))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(d) = settings.domain_id {
        p.env("ROS_DOMAIN_ID", d.to_string());
    }
    if let Some(r) = &settings.discovery {
        p.env("ROS_AUTOMATIC_DISCOVERY_RANGE", r.to_uppercase());
    }
    p
}

fn sanitize(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_goal_s_uuid_is_its_own_and_the_same_every_time() {
        let a = goal_uuid("europa-1a2b.1.42.1");
        assert_eq!(a, goal_uuid("europa-1a2b.1.42.1"));
        assert_ne!(a, goal_uuid("europa-1a2b.1.42.2"));
        assert_eq!(a.len(), 32);
        assert_eq!(&a[12..13], "8");
    }
}
