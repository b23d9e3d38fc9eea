//! Deterministic replay of an execution record: every engine step of the record is read back
//! into the input that caused it (an instance started, a task completed or failed, a user task
//! answered, a timer fired, system data changed), given to a fresh engine of the mission model
//! in order, and the lines the engine writes are compared with the lines the record holds —
//! every field but wall time, and no line more or fewer (only the last step of a record cut by
//! a kill may lack its tail). The state after each step is then the engine's own — what the studio's
//! replay shows at any chosen moment — and a record that does not come from this model (or a
//! model changed since) is refused at the first step that differs, naming it.
//!
//! Lines of no step (`reboot`, `accepted`, `feedback`) are skipped; a line written again after
//! a crash (the same `seq` and `idx`) is read once, as every record reader does.
//!
//! What a record cannot say is not replayed: inputs the runtime does not give (a message, a
//! signal or a cancel from outside; a token game's choices), and a process started by a
//! condition or a message (the record names no start event). Such a step is refused, naming it.

use std::collections::BTreeMap;
use std::sync::Arc;

use executive_engine::{
    Action, Engine, Event, Input, InstanceId, Outcome, TaskKey, TimerKey, TokenId, Vars, WaitId,
};
use executive_model::ProcessGraph;
use serde::Serialize;
use serde_json::Value;

/// At most this many steps are replayed (a record of 18 mission days has a few thousand).
pub const MAX_STEPS: usize = 200_000;

/// The mission after one step of the record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Frame {
    /// The step (`seq` in the record).
    pub seq: u64,
    /// Its mission time, ms since the Unix epoch.
    pub mission_ms: i64,
    /// The input, for people: `completed Remove Material`, `timer fired Wait 1 h`, …
    pub what: String,
    /// Tokens by element id, after the step (the engine's state).
    pub tokens: BTreeMap<String, usize>,
    /// Instances ended by then, with how.
    pub ended: BTreeMap<u64, String>,
}

/// Why a record could not be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A line is not JSON, or a step line lacks what its kind needs.
    #[error("record line {line}: {reason}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// No input can be read from a step's lines.
    #[error("step {seq}: none of its lines says what caused it ({kinds})")]
    NoInput {
        /// The step.
        seq: u64,
        /// The kinds of its lines.
        kinds: String,
    },
    /// The engine refused the input read back.
    #[error("step {seq}: the engine refused it: {reason}")]
    Refused {
        /// The step.
        seq: u64,
        /// The engine's reason.
        reason: String,
    },
    /// The engine writes something else than the record holds: the record is not of this
    /// model, or the model changed since.
    #[error(
        "step {seq}: the record does not come from this model — line {idx} is `{recorded}`, the engine writes `{replayed}`"
    )]
    Differs {
        /// The step.
        seq: u64,
        /// The line's index in the step.
        idx: usize,
        /// What the record holds (its kind and element).
        recorded: String,
        /// What the engine writes there.
        replayed: String,
    },
    /// More steps than [`MAX_STEPS`].
    #[error("the record has more than {MAX_STEPS} steps")]
    TooLong,
}

/// One step's lines, by index, each with its 1-based line number in the record.
type Step = BTreeMap<usize, (usize, Value)>;

/// Replays `record` (JSON Lines) on `graph`: one frame per step, in order.
pub fn replay(graph: Arc<ProcessGraph>, record: &str) -> Result<Vec<Frame>, ReplayError> {
    let steps = steps(record)?;
    if steps.len() > MAX_STEPS {
        return Err(ReplayError::TooLong);
    }
    let mut engine = Engine::new(Arc::clone(&graph));
    let mut frames = Vec::with_capacity(steps.len());
    let mut ended = BTreeMap::new();
    // Task keys to element names, from the dispatches seen so far (completions name no element).
    let mut names: BTreeMap<String, String> = BTreeMap::new();
    let last = steps.keys().next_back().copied();
    for (seq, lines) in steps {
        let (event, mut what, cause) = input(seq, &lines)?;
        if let Some(name) = cause["task"]
            .as_str()
            .filter(|_| cause["element"].is_null())
            .and_then(|t| names.get(t))
        {
            what = format!("{what} {name}");
        }
        for (_, l) in lines.values() {
            if let (Some(t), Some(n)) = (l["task"].as_str(), l["element"]["name"].as_str()) {
                names.insert(t.to_owned(), n.to_owned());
            }
        }
        let at = lines
            .values()
            .find_map(|(_, l)| l["mission_ms"].as_i64())
            .unwrap_or_default();
        let actions = engine
            .step(Input { seq, at, event })
            .map_err(|e| ReplayError::Refused {
                seq,
                reason: e.to_string(),
            })?;
        compare(&graph, seq, &actions, &lines, Some(seq) == last)?;
        for (id, i) in &engine.state().instances {
            if let Some(o) = &i.outcome {
                ended.entry(id.0).or_insert_with(|| outcome(o));
            }
        }
        let mut tokens = BTreeMap::new();
        for t in engine.state().tokens.values() {
            *tokens.entry(graph.node(t.node).id.clone()).or_default() += 1;
        }
        frames.push(Frame {
            seq,
            mission_ms: at,
            what,
            tokens,
            ended: ended.clone(),
        });
    }
    Ok(frames)
}

fn outcome(o: &Outcome) -> String {
    serde_json::to_value(o)
        .ok()
        .and_then(|v| v["type"].as_str().map(str::to_owned))
        .unwrap_or_else(|| format!("{o:?}"))
}

/// The record's step lines grouped by `seq`, each once.
fn steps(record: &str) -> Result<BTreeMap<u64, Step>, ReplayError> {
    let mut steps: BTreeMap<u64, Step> = BTreeMap::new();
    for (n, text) in record.lines().enumerate() {
        if text.trim().is_empty() {
            continue;
        }
        let v: Value = serde_json::from_str(text).map_err(|e| ReplayError::Line {
            line: n + 1,
            reason: format!("not JSON: {e}"),
        })?;
        let (Some(seq), Some(idx)) = (v["seq"].as_u64(), v["idx"].as_u64()) else {
            continue; // not an engine step: reboot, accepted, feedback
        };
        steps
            .entry(seq)
            .or_default()
            .entry(idx as usize)
            .or_insert((n + 1, v));
        if steps.len() > MAX_STEPS {
            return Err(ReplayError::TooLong);
        }
    }
    Ok(steps)
}

/// `<instance>-<a>-<b>`, the record's task and timer keys.
fn triple(s: &str) -> Option<(u64, u64, u32)> {
    let mut parts = s.split('-');
    let a = parts.next()?.parse().ok()?;
    let b = parts.next()?.parse().ok()?;
    let c = parts.next()?.parse().ok()?;
    parts.next().is_none().then_some((a, b, c))
}

/// The variables of a line's field `key` (absent: none).
fn vars(l: &Value, key: &str) -> Result<Vars, String> {
    match &l[key] {
        Value::Null => Ok(Vars::new()),
        v => {
            serde_json::from_value(v.clone()).map_err(|e| format!("`{key}` is not variables: {e}"))
        }
    }
}

/// The input that caused a step, read from the first of its lines that says; with it, what it
/// was for people and that line.
fn input(seq: u64, lines: &Step) -> Result<(Event, String, &Value), ReplayError> {
    for (line, l) in lines.values() {
        let bad = |what: &str| ReplayError::Line {
            line: *line,
            reason: format!("step {seq}: {what}"),
        };
        let element = l["element"]["name"].as_str().unwrap_or("").to_owned();
        let task = || {
            l["task"]
                .as_str()
                .and_then(triple)
                .map(|(i, t, a)| TaskKey {
                    instance: InstanceId(i),
                    token: TokenId(t),
                    attempt: a,
                })
                .ok_or_else(|| bad("a task key `<instance>-<token>-<attempt>` is missing"))
        };
        let event = match l["kind"].as_str().unwrap_or("") {
            "instance_started" => Event::InstanceStarted {
                process: l["process"]
                    .as_str()
                    .ok_or_else(|| bad("instance_started without its process"))?
                    .to_owned(),
                vars: vars(l, "vars").map_err(|e| bad(&e))?,
                start: None,
            },
            "completed" => Event::TaskCompleted {
                task: task()?,
                output: vars(l, "output").map_err(|e| bad(&e))?,
            },
            "failed" => Event::TaskFailed {
                task: task()?,
                code: l["code"].as_str().unwrap_or_default().to_owned(),
                message: l["message"].as_str().unwrap_or_default().to_owned(),
            },
            "user_task_answered" => Event::UserTaskAnswered {
                task: task()?,
                answer: vars(l, "answer").map_err(|e| bad(&e))?,
                operator: l["operator"].as_str().unwrap_or_default().to_owned(),
            },
            "timer_fired" => {
                let (i, w, f) = l["timer"]
                    .as_str()
                    .and_then(triple)
                    .ok_or_else(|| bad("a timer key `<instance>-<wait>-<firing>` is missing"))?;
                Event::TimerFired {
                    timer: TimerKey {
                        instance: InstanceId(i),
                        wait: WaitId(w),
                        firing: f,
                    },
                }
            }
            "data" => Event::DataChanged {
                key: l["key"]
                    .as_str()
                    .ok_or_else(|| bad("data without its key"))?
                    .to_owned(),
                value: serde_json::from_value(l["value"].clone())
                    .map_err(|e| bad(&format!("data value: {e}")))?,
            },
            _ => continue,
        };
        let kind = l["kind"].as_str().unwrap_or("").replace('_', " ");
        let what = if element.is_empty() {
            kind
        } else {
            format!("{kind} {element}")
        };
        return Ok((event, what, l));
    }
    Err(ReplayError::NoInput {
        seq,
        kinds: lines
            .values()
            .filter_map(|(_, l)| l["kind"].as_str())
            .collect::<Vec<_>>()
            .join(", "),
    })
}

/// The lines the engine writes for this step against the record's: every field but wall time
/// (and the schema version), line for line. Only the `last` step may lack lines at its end (a
/// record cut by a kill); a line the engine does not write is a difference too.
fn compare(
    graph: &ProcessGraph,
    seq: u64,
    actions: &[Action],
    lines: &Step,
    last: bool,
) -> Result<(), ReplayError> {
    let shown = |v: &Value| {
        format!(
            "{} {}",
            v["kind"].as_str().unwrap_or("?"),
            v["element"]["id"]
                .as_str()
                .or(v["task"].as_str())
                .unwrap_or("")
        )
        .trim_end()
        .to_owned()
    };
    let differs = |idx: usize, recorded: String, replayed: String| ReplayError::Differs {
        seq,
        idx,
        recorded,
        replayed,
    };
    let mut written = std::collections::BTreeSet::new();
    let mut missing = None;
    for (idx, action) in actions.iter().enumerate() {
        let Action::Record(r) = action else { continue };
        written.insert(idx);
        let mut replayed = crate::record::to_json(graph, seq, 0, r);
        replayed["idx"] = serde_json::json!(idx);
        let Some((_, recorded)) = lines.get(&idx) else {
            missing.get_or_insert((idx, shown(&replayed)));
            continue;
        };
        if let Some((at, _)) = missing {
            // A hole before a line the record has: not a cut tail.
            return Err(differs(at, "nothing".into(), shown(&replayed)));
        }
        let same = |v: &Value, w: &Value| {
            let strip = |x: &Value| {
                let mut x = x.clone();
                if let Some(o) = x.as_object_mut() {
                    o.remove("wall");
                    o.remove("v");
                    // Where the line sits in its file, not what the engine wrote.
                    o.remove("line");
                }
                x
            };
            strip(v) == strip(w)
        };
        if !same(recorded, &replayed) {
            return Err(differs(idx, shown(recorded), shown(&replayed)));
        }
    }
    if let Some((idx, replayed)) = missing
        && !last
    {
        return Err(differs(idx, "nothing".into(), replayed));
    }
    if let Some((idx, (_, extra))) = lines.iter().find(|(i, _)| !written.contains(*i)) {
        return Err(differs(*idx, shown(extra), "nothing".into()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! A record written from the engine's own steps replays to the same states; the same
    //! record on a changed model, or with a broken line, is refused naming where.

    use super::*;

    const MODEL: &str = r#"<?xml version="1.0"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="t">
<bpmn:process id="p" isExecutable="true">
<bpmn:startEvent id="s"/><bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="a"/>
<bpmn:serviceTask id="a" name="Dig"><bpmn:extensionElements><trace:task resource="arm.dig"/></bpmn:extensionElements></bpmn:serviceTask>
<bpmn:sequenceFlow id="f2" sourceRef="a" targetRef="b"/>
<bpmn:serviceTask id="b" name="Look"><bpmn:extensionElements><trace:task resource="camera.look"/></bpmn:extensionElements></bpmn:serviceTask>
<bpmn:sequenceFlow id="f3" sourceRef="b" targetRef="e"/><bpmn:endEvent id="e"/>
</bpmn:process></bpmn:definitions>"#;

    fn graph(xml: &str) -> Arc<ProcessGraph> {
        let loaded = executive_model::load(xml.as_bytes());
        Arc::new(loaded.graph.expect("a valid model"))
    }

    /// Runs the model, completing each task as it is dispatched; the record it writes.
    fn flown() -> String {
        let g = graph(MODEL);
        let mut engine = Engine::new(Arc::clone(&g));
        let mut out = String::new();
        let mut event = Event::InstanceStarted {
            process: "p".into(),
            vars: Vars::new(),
            start: None,
        };
        for seq in 1.. {
            let actions = engine
                .step(Input {
                    seq,
                    at: 1000 * seq as i64,
                    event,
                })
                .expect("a step");
            let mut next = None;
            for (idx, a) in actions.iter().enumerate() {
                match a {
                    Action::Record(r) => {
                        let mut line = crate::record::to_json(&g, seq, 0, r);
                        line["idx"] = serde_json::json!(idx);
                        out.push_str(&line.to_string());
                        out.push('\n');
                    }
                    Action::DispatchTask { task, .. } => {
                        next = Some(Event::TaskCompleted {
                            task: *task,
                            output: Vars::new(),
                        })
                    }
                    _ => {}
                }
            }
            match next {
                Some(e) => event = e,
                None => break,
            }
        }
        out
    }

    #[test]
    fn a_record_replays_to_the_engines_states() {
        let record = flown();
        // A line written again after a crash, and a reboot marker: read once, skipped.
        let first = record.lines().next().expect("a line").to_owned();
        let record = format!("{record}{first}\n{{\"v\":1,\"kind\":\"reboot\",\"reboots\":1}}\n");
        let frames = replay(graph(MODEL), &record).expect("replayed");
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[0].what, "instance started");
        assert_eq!(frames[0].tokens, BTreeMap::from([("a".to_owned(), 1)]));
        assert_eq!(frames[1].what, "completed Dig");
        assert_eq!(frames[1].tokens, BTreeMap::from([("b".to_owned(), 1)]));
        assert!(frames[2].tokens.is_empty());
        assert_eq!(
            frames[2].ended.get(&1).map(String::as_str),
            Some("completed")
        );
    }

    #[test]
    fn a_record_of_another_model_or_a_broken_line_is_refused_naming_where() {
        let record = flown();
        // The tasks swapped: the first step already enters another element.
        let other = MODEL
            .replace(r#"targetRef="a""#, r#"targetRef="x""#)
            .replace(
                r#"sourceRef="s" targetRef="x""#,
                r#"sourceRef="s" targetRef="b""#,
            )
            .replace(
                r#"sourceRef="a" targetRef="b""#,
                r#"sourceRef="a" targetRef="e""#,
            )
            .replace(
                r#"sourceRef="b" targetRef="e""#,
                r#"sourceRef="b" targetRef="a""#,
            );
        let e = replay(graph(&other), &record).expect_err("another model");
        assert!(matches!(e, ReplayError::Differs { seq: 1, .. }), "{e}");
        assert!(
            e.to_string().contains("does not come from this model"),
            "{e}"
        );
        let broken = format!("{record}{{not json\n");
        let e = replay(graph(MODEL), &broken).expect_err("a broken line");
        let n = record.lines().count() + 1;
        assert!(
            e.to_string()
                .starts_with(&format!("record line {n}: not JSON")),
            "{e}"
        );
        // A line taken out of a step that is not the last, a field changed, a line added.
        let lines: Vec<&str> = record.lines().collect();
        let holed = [&lines[..1], &lines[2..]].concat().join("\n");
        let e = replay(graph(MODEL), &holed).expect_err("a line missing");
        assert!(matches!(e, ReplayError::Differs { seq: 1, .. }), "{e}");
        let changed = record.replacen(r#""resource":"arm.dig""#, r#""resource":"arm.dug""#, 1);
        assert_ne!(changed, record);
        let e = replay(graph(MODEL), &changed).expect_err("a field changed");
        assert!(matches!(e, ReplayError::Differs { .. }), "{e}");
        let extra = format!(
            "{record}{}\n",
            lines[0].replace(r#""idx":0"#, r#""idx":99"#)
        );
        let e = replay(graph(MODEL), &extra).expect_err("a line more");
        assert!(matches!(e, ReplayError::Differs { idx: 99, .. }), "{e}");
        // The last step cut short by a kill still replays.
        let cut = lines[..lines.len() - 1].join("\n");
        assert_eq!(replay(graph(MODEL), &cut).expect("a cut tail").len(), 3);
        // A step whose lines say nothing of its cause.
        let e = replay(
            graph(MODEL),
            r#"{"v":1,"seq":1,"idx":0,"kind":"took","flow":"f1","mission_ms":0,"instance":1}"#,
        )
        .expect_err("no input");
        assert!(matches!(e, ReplayError::NoInput { seq: 1, .. }), "{e}");
    }
}
