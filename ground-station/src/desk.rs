//! The open user tasks as an operator sees them: numbered in arrival order, with the task's
//! element, name, context and deadline, until they are answered or withdrawn; then, for a
//! while, the tasks closed and who or what closed them.

use std::collections::{BTreeMap, HashMap, VecDeque};

use connector_zenoh::GoalHandle;
use serde_json::Value;

/// One open user task.
#[derive(Debug)]
pub struct OpenTask {
    /// The operator's short handle for it.
    pub number: u32,
    /// The goal: id, action (task type) and fields.
    pub handle: GoalHandle,
    /// This station's answer is with the executive; a withdrawal waits for its verdict.
    pub answering: bool,
    /// Withdrawn (and why) while our answer was with the executive.
    pub withdrawn: Option<String>,
}

impl OpenTask {
    fn text(&self, key: &str) -> &str {
        self.handle
            .fields
            .get(key)
            .and_then(Value::as_str)
            .unwrap_or("?")
    }

    /// The task's element id in the mission model.
    pub fn task(&self) -> &str {
        self.text("task")
    }

    /// The task's name in the mission model.
    pub fn name(&self) -> &str {
        self.text("name")
    }

    /// The variables the task shows.
    pub fn context(&self) -> &Value {
        self.handle.fields.get("context").unwrap_or(&Value::Null)
    }

    /// The deadline (mission time), if a timer boundary guards the task.
    pub fn deadline(&self) -> Option<String> {
        let ms = self.handle.fields.get("deadline_ms")?.as_i64()?;
        chrono::DateTime::from_timestamp_millis(ms)
            .map(|t| t.format("%Y-%m-%dT%H:%M:%SZ").to_string())
    }

    /// One line: number, name, element, type and deadline.
    pub fn line(&self) -> String {
        let deadline = self
            .deadline()
            .map(|d| format!(" deadline {d}"))
            .unwrap_or_default();
        format!(
            "{} [{}, {}]{deadline}",
            self.name(),
            self.task(),
            self.handle.action
        )
    }
}

/// How many closed tasks [`Desk::closed`] keeps.
const CLOSED_KEPT: usize = 20;

/// A task no longer open, and who or what closed it.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ClosedTask {
    /// Its number while it was open.
    pub number: u32,
    /// Its element id in the mission model.
    pub task: String,
    /// Its name in the mission model.
    pub name: String,
    /// Who or what closed it: `answered by ana@web`, or the mission's reason for withdrawing
    /// it (`docs/protocol.md` §8a).
    pub why: String,
}

/// The open tasks, the number every task seen has (a repeated goal keeps its number), and the
/// last tasks closed.
#[derive(Debug, Default)]
pub struct Desk {
    next: u32,
    open: BTreeMap<u32, OpenTask>,
    numbers: HashMap<String, u32>,
    closed: VecDeque<ClosedTask>,
}

impl Desk {
    /// Opens a task (a repeated goal keeps its number); `None` when it was already open.
    pub fn open(&mut self, handle: GoalHandle) -> Option<&OpenTask> {
        if self.numbers.contains_key(&handle.goal_id) {
            return None;
        }
        self.next += 1;
        let number = self.next;
        self.numbers.insert(handle.goal_id.clone(), number);
        Some(self.open.entry(number).or_insert(OpenTask {
            number,
            handle,
            answering: false,
            withdrawn: None,
        }))
    }

    /// Closes the task with this goal id, saying who or what closed it; the task, if it was
    /// open.
    pub fn close(&mut self, goal_id: &str, why: &str) -> Option<OpenTask> {
        let n = self.numbers.get(goal_id)?;
        let t = self.open.remove(n)?;
        if self.closed.len() == CLOSED_KEPT {
            self.closed.pop_front();
        }
        self.closed.push_back(ClosedTask {
            number: t.number,
            task: t.task().to_owned(),
            name: t.name().to_owned(),
            why: why.to_owned(),
        });
        Some(t)
    }

    /// The last tasks closed (at most 20), oldest first.
    pub fn closed(&self) -> impl Iterator<Item = &ClosedTask> {
        self.closed.iter()
    }

    /// An open task by number.
    pub fn get(&self, number: u32) -> Option<&OpenTask> {
        self.open.get(&number)
    }

    /// An open task by number, to change.
    pub fn get_mut(&mut self, number: u32) -> Option<&mut OpenTask> {
        self.open.get_mut(&number)
    }

    /// An open task by goal id, to change.
    pub fn by_goal(&mut self, goal_id: &str) -> Option<&mut OpenTask> {
        let n = self.numbers.get(goal_id)?;
        self.open.get_mut(n)
    }

    /// Open tasks in arrival order.
    pub fn list(&self) -> impl Iterator<Item = &OpenTask> {
        self.open.values()
    }
}
