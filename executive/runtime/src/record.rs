//! The execution record: one JSON object per line, appended and flushed as the mission runs,
//! so a record cut by a kill is valid up to its last line. Schema: `docs/record.md`.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

use executive_engine::{Entry, Record};
use executive_model::{NodeId, ProcessGraph};
use serde_json::{Map, Value, json};

/// The record schema version written in every line (`"v"`).
pub const RECORD_VERSION: u32 = 1;

/// Where record lines are also sent as they are written (live monitoring).
pub type Mirror = Box<dyn Fn(&str) + Send>;

/// Appends record lines to a file.
pub struct RecordWriter {
    file: File,
    graph: Arc<ProcessGraph>,
    mirror: Option<Mirror>,
    /// The position the next line takes in the file (`"line"`, from 1).
    next: u64,
}

impl RecordWriter {
    /// Opens `path` for appending (created if missing).
    /// Lines already in the file are counted: every line's `line` is its position in the file.
    pub fn open(path: &Path, graph: Arc<ProcessGraph>) -> std::io::Result<RecordWriter> {
        let file = OpenOptions::new().create(true).append(true).open(path)?;
        let written = std::fs::read(path)?.iter().filter(|b| **b == b'\n').count() as u64;
        Ok(RecordWriter {
            file,
            graph,
            mirror: None,
            next: written + 1,
        })
    }

    /// Writes one engine record entry, stamped with the input's sequence number, the action's
    /// index in that step (a line written again after a crash repeats the same pair) and wall
    /// time.
    pub fn write(
        &mut self,
        seq: u64,
        index: usize,
        wall_ms: i64,
        record: &Record,
    ) -> std::io::Result<()> {
        let mut line = to_json(&self.graph, seq, wall_ms, record);
        line["idx"] = serde_json::json!(index);
        self.line(line)
    }

    /// Writes a line the executive itself produces (reboot markers).
    pub fn reboot(
        &mut self,
        mission_ms: i64,
        wall_ms: i64,
        reboots: u64,
        pending: usize,
    ) -> std::io::Result<()> {
        let line = json!({
            "v": RECORD_VERSION,
            "kind": "reboot",
            "mission_ms": mission_ms,
            "wall": wall(wall_ms),
            "reboots": reboots,
            "recommanded": pending,
        });
        self.line(line)
    }

    /// Writes a line about a goal that is not an engine step (`accepted`, `feedback`): the
    /// task key, the goal id, times, and `body`'s fields.
    pub fn activity(
        &mut self,
        kind: &str,
        task: &str,
        goal_id: &str,
        mission_ms: i64,
        wall_ms: i64,
        body: Value,
    ) -> std::io::Result<()> {
        let mut fields = json!({"task": task, "goal": goal_id});
        if let (Some(o), Value::Object(b)) = (fields.as_object_mut(), body) {
            o.extend(b);
        }
        self.fleet(kind, mission_ms, wall_ms, fields)
    }

    /// Writes a line the executive produces that is not an engine step — about the fleet link
    /// (`message_sent`, `message_delivered`, `message_refused`, `peer`), or about a goal
    /// ([`RecordWriter::activity`]): times, and `body`'s fields.
    pub fn fleet(
        &mut self,
        kind: &str,
        mission_ms: i64,
        wall_ms: i64,
        body: Value,
    ) -> std::io::Result<()> {
        let mut line = json!({
            "v": RECORD_VERSION,
            "kind": kind,
            "mission_ms": mission_ms,
            "wall": wall(wall_ms),
        });
        if let (Some(o), Value::Object(b)) = (line.as_object_mut(), body) {
            o.extend(b);
        }
        self.line(line)
    }

    /// Every line written from now on is also handed to `mirror` (live monitoring).
    pub fn mirror(&mut self, mirror: Mirror) {
        self.mirror = Some(mirror);
    }

    fn line(&mut self, mut v: Value) -> std::io::Result<()> {
        v["line"] = json!(self.next);
        let mut text = serde_json::to_string(&v).map_err(std::io::Error::other)?;
        text.push('\n');
        // One write per line, then flush: a kill leaves whole lines only.
        self.file.write_all(text.as_bytes())?;
        self.file.flush()?;
        self.next += 1;
        if let Some(m) = &self.mirror {
            m(text.trim_end());
        }
        Ok(())
    }
}

/// Reads a record back: parses each line, counts the unreadable ones (a line cut by a crash),
/// keeps the first of a line written again after a restart (same `seq` and `idx`), and
/// remembers each task's resource from its `dispatched` line.
#[derive(Debug, Default)]
pub struct Reader {
    seen: std::collections::BTreeSet<(u64, u64)>,
    resources: std::collections::BTreeMap<String, String>,
    /// Lines that were not JSON.
    pub skipped: usize,
}

impl Reader {
    /// The line's entry, or `None` if it is unreadable, blank or a repeat.
    pub fn read(&mut self, line: &str) -> Option<Value> {
        let Ok(v) = serde_json::from_str::<Value>(line) else {
            self.skipped += usize::from(!line.trim().is_empty());
            return None;
        };
        if let (Some(seq), Some(idx)) = (v["seq"].as_u64(), v["idx"].as_u64())
            && !self.seen.insert((seq, idx))
        {
            return None;
        }
        if v["kind"] == "dispatched"
            && let (Some(task), Some(resource)) = (v["task"].as_str(), v["resource"].as_str())
        {
            self.resources.insert(task.to_owned(), resource.to_owned());
        }
        Some(v)
    }

    /// The resource of the task an entry is about, if it was dispatched.
    pub fn resource(&self, v: &Value) -> Option<&str> {
        self.resources.get(v["task"].as_str()?).map(String::as_str)
    }
}

fn wall(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms)
        .unwrap_or_default()
        .to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

fn element(g: &ProcessGraph, n: NodeId) -> Value {
    let node = g.node(n);
    json!({ "id": node.id, "name": node.name, "type": node.kind.element_name() })
}

/// The JSON object of one record entry.
pub fn to_json(g: &ProcessGraph, seq: u64, wall_ms: i64, r: &Record) -> Value {
    let mut o = Map::new();
    o.insert("v".into(), json!(RECORD_VERSION));
    o.insert("seq".into(), json!(seq));
    o.insert("mission_ms".into(), json!(r.at));
    o.insert("wall".into(), json!(wall(wall_ms)));
    o.insert("instance".into(), json!(r.instance.0));
    let mut put = |k: &str, v: Value| {
        o.insert(k.to_owned(), v);
    };
    let kind = match &r.entry {
        Entry::InstanceStarted { process, vars } => {
            put("process", json!(process));
            put("vars", json!(vars));
            "instance_started"
        }
        Entry::InstanceFinished {
            outcome,
            uncaught_escalations,
        } => {
            put("outcome", json!(outcome));
            put("uncaught_escalations", json!(uncaught_escalations));
            "instance_finished"
        }
        Entry::Entered { node, token } => {
            put("element", element(g, *node));
            put("token", json!(token.0));
            "entered"
        }
        Entry::Left { node, token } => {
            put("element", element(g, *node));
            put("token", json!(token.0));
            "left"
        }
        Entry::Withdrawn { node, token } => {
            put("element", element(g, *node));
            put("token", json!(token.0));
            "withdrawn"
        }
        Entry::Took { flow } => {
            put("flow", json!(g.flow(*flow).id));
            "took"
        }
        Entry::Decided { node, flows, read } => {
            put("element", element(g, *node));
            put(
                "flows",
                json!(flows.iter().map(|f| &g.flow(*f).id).collect::<Vec<_>>()),
            );
            put("read", json!(read));
            "decided"
        }
        Entry::Dispatched {
            task,
            node,
            request,
        } => {
            put("task", json!(task.to_string()));
            put("element", element(g, *node));
            put("resource", json!(executive_engine::resource(g, *node)));
            put("request", json!(request));
            "dispatched"
        }
        Entry::Completed { task, output } => {
            put("task", json!(task.to_string()));
            put("output", json!(output));
            "completed"
        }
        Entry::Failed {
            task,
            code,
            message,
        } => {
            put("task", json!(task.to_string()));
            put("code", json!(code));
            put("message", json!(message));
            "failed"
        }
        Entry::Cancelled { task } => {
            put("task", json!(task.to_string()));
            "cancelled"
        }
        Entry::Opened { task, node } => {
            put("task", json!(task.to_string()));
            put("element", element(g, *node));
            "user_task_opened"
        }
        Entry::Answered {
            task,
            operator,
            answer,
        } => {
            put("task", json!(task.to_string()));
            put("operator", json!(operator));
            put("answer", json!(answer));
            "user_task_answered"
        }
        Entry::TimerStarted { timer, node, due } => {
            put("timer", json!(timer.to_string()));
            put("element", element(g, *node));
            put("due_ms", json!(due));
            "timer_started"
        }
        Entry::TimerFired { timer, node } => {
            put("timer", json!(timer.to_string()));
            put("element", element(g, *node));
            "timer_fired"
        }
        Entry::Thrown { what, name, node } => {
            put("what", json!(what));
            put("name", json!(name));
            if let Some(n) = node {
                put("element", element(g, *n));
            }
            "thrown"
        }
        Entry::Caught { what, name, node } => {
            put("what", json!(what));
            put("name", json!(name));
            put("element", element(g, *node));
            "caught"
        }
        Entry::Incident { node, message } => {
            put("element", element(g, *node));
            put("message", json!(message));
            "incident"
        }
        Entry::Data { key, value } => {
            put("key", json!(key));
            put("value", json!(value));
            "data"
        }
    };
    o.insert("kind".into(), json!(kind));
    Value::Object(o)
}
