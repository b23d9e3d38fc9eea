//! The operator console: `list` the open tasks, `show N` one with its form and context,
//! `answer N field=value …` with the fields checked against the form before anything is sent,
//! `help`, `quit`. Tasks opening and closing are announced as they happen.

use std::io::{BufRead, Write};
use std::sync::Arc;

use tokio::sync::mpsc;

use crate::forms;
use crate::station::{Station, say};

const HELP: &str = "commands:
  list                      the open tasks
  show N                    task N: its form and the mission variables it shows
  answer N field=value ...  answer task N (values as JSON; text may be bare or \"quoted\")
  help                      this text
  quit                      leave (open tasks stay open for other stations)";

const PROMPT: &str = "ground> ";

fn prompt() {
    let mut out = std::io::stdout().lock();
    let _ = write!(out, "{PROMPT}");
    let _ = out.flush();
}

/// Runs the console on standard input until `quit` or end of input.
pub async fn run(station: Arc<Station>, operator: String) {
    let (tx, mut lines) = mpsc::unbounded_channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    say(&format!(
        "ground station {} — operator {operator}; type `help`",
        station.id
    ));
    prompt();
    while let Some(line) = lines.recv().await {
        let line = line.trim();
        let (cmd, rest) = line.split_once(' ').unwrap_or((line, ""));
        match cmd {
            "" => {}
            "quit" | "exit" => break,
            "help" => say(HELP),
            "list" => list(&station),
            "show" => match number(rest) {
                Ok(n) => show(&station, n),
                Err(e) => say(&e),
            },
            "answer" => {
                let (n, fields) = rest.trim().split_once(' ').unwrap_or((rest.trim(), ""));
                match number(n) {
                    Ok(n) => answer(&station, n, fields, &operator).await,
                    Err(e) => say(&e),
                }
            }
            other => say(&format!("unknown command `{other}`; type `help`")),
        }
        prompt();
    }
}

fn number(text: &str) -> Result<u32, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("`{}` is not a task number; `list` shows them", text.trim()))
}

fn list(station: &Station) {
    let desk = station.desk();
    let mut any = false;
    for t in desk.list() {
        any = true;
        say(&format!("  {:>3}  {}", t.number, t.line()));
    }
    if !any {
        say("no open tasks");
    }
}

fn show(station: &Station, n: u32) {
    let desk = station.desk();
    let Some(t) = desk.get(n) else {
        return say(&format!("task {n} is not open; `list` shows the open ones"));
    };
    say(&format!("task {n}: {}", t.name()));
    say(&format!("  element   {}", t.task()));
    say(&format!("  type      {}", t.handle.action));
    say(&format!("  goal      {}", t.handle.goal_id));
    if let Some(d) = t.deadline() {
        say(&format!(
            "  deadline  {d} (mission time; then the model decides)"
        ));
    }
    let context = serde_json::to_string_pretty(t.context()).unwrap_or_default();
    say("  context");
    for line in context.lines() {
        say(&format!("    {line}"));
    }
    say("  form");
    if let Some(form) = station.forms().action(&t.handle.action) {
        for line in forms::describe(form) {
            say(&format!("    {line}"));
        }
    }
}

async fn answer(station: &Station, n: u32, text: &str, operator: &str) {
    let form = {
        let desk = station.desk();
        let Some(t) = desk.get(n) else {
            return say(&format!("task {n} is not open; `list` shows the open ones"));
        };
        station.forms().action(&t.handle.action).cloned()
    };
    let Some(form) = form else {
        return say(&format!("task {n} has no form at this station"));
    };
    match forms::parse_answer(&form, text) {
        Ok(fields) => {
            station.answer(n, fields, operator).await;
        }
        Err(e) => say(&format!("not sent: {e}")),
    }
}
