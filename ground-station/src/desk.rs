//! The open user tasks as an operator sees them: numbered in arrival order, with the task's
//! element, name, context and deadline, until they are answered or withdrawn.

use std::collections::{BTreeMap, HashMap};

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

/// The open tasks, and the number every task seen has (a repeated goal keeps its number).
#[derive(Debug, Default)]
pub struct Desk {
    next: u32,
    open: BTreeMap<u32, OpenTask>,
    numbers: HashMap<String, u32>,
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

    /// Closes the task with this goal id; the task, if it was open.
    pub fn close(&mut self, goal_id: &str) -> Option<OpenTask> {
        let n = self.numbers.get(goal_id)?;
        self.open.remove(n)
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
