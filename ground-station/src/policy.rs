//! The policy file: how a station answers without a person (`deploy/ground/policy.toml`).
//!
//! Per user task type: `fixed` answer fields (TOML values), `computed` fields (CEL over the
//! task's goal: `task`, `name`, `context`, `deadline_ms`), a `delay_ms` before answering, or
//! `silent = true` to never answer so the model's timer boundary decides. Everything is checked
//! against the forms when the file is loaded: unknown task types and fields, wrongly typed
//! fixed values, expressions that do not compile, required fields left unanswered.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use connector_api::{Catalogue, Fields};
use serde::Deserialize;
use serde_json::Value;

/// The policy file could not be used.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {reason}")]
pub struct PolicyError {
    /// The file.
    pub path: String,
    /// What is wrong (every problem, one per line).
    pub reason: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PolicyFile {
    operator: Option<String>,
    #[serde(default)]
    task: BTreeMap<String, RuleFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RuleFile {
    #[serde(default)]
    delay_ms: u64,
    #[serde(default)]
    fixed: Fields,
    #[serde(default)]
    computed: BTreeMap<String, String>,
    #[serde(default)]
    silent: bool,
}

struct Computed {
    field: String,
    source: String,
    program: cel::Program,
}

struct Rule {
    delay: Duration,
    fixed: Fields,
    computed: Vec<Computed>,
    silent: bool,
}

/// What the policy does with a task.
#[derive(Debug, PartialEq)]
pub enum Decision {
    /// No rule for this task type: a person (or the model's timer) decides.
    Leave,
    /// Never answer: the model's timer boundary decides.
    Silent,
    /// Answer after `delay`; the fields, or why they could not be computed for this task.
    Answer {
        /// How long to wait first.
        delay: Duration,
        /// The answer.
        fields: Result<Fields, String>,
    },
}

/// A loaded, checked policy.
pub struct Policy {
    /// Recorded as the operator of its answers.
    pub operator: String,
    rules: HashMap<String, Rule>,
    forms: Arc<Catalogue>,
}

impl Policy {
    /// Reads and checks a policy against the forms the station serves.
    pub fn load(path: &Path, forms: Arc<Catalogue>) -> Result<Policy, PolicyError> {
        let text = std::fs::read_to_string(path).map_err(|e| PolicyError {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        Policy::parse(&text, &path.display().to_string(), forms)
    }

    /// Reads and checks a policy's text (`path` names it in errors) against the forms.
    pub fn parse(text: &str, path: &str, forms: Arc<Catalogue>) -> Result<Policy, PolicyError> {
        let bad = |reason: String| PolicyError {
            path: path.to_owned(),
            reason,
        };
        let file: PolicyFile = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let mut problems = Vec::new();
        let mut rules = HashMap::new();
        for (task, r) in file.task {
            let Some(form) = forms.action(&task) else {
                problems.push(format!(
                    "task `{task}`: no such form in the station's forms"
                ));
                continue;
            };
            for (k, v) in &r.fixed {
                match form.result.get(k) {
                    None => problems.push(format!("task `{task}`: `{k}` is not a field")),
                    Some(t) => {
                        if let Err(e) = t.check(k, v) {
                            problems.push(format!("task `{task}`: fixed {e}"));
                        }
                    }
                }
            }
            let mut computed = Vec::new();
            for (k, source) in r.computed {
                if !form.result.contains_key(&k) {
                    problems.push(format!("task `{task}`: `{k}` is not a field"));
                }
                match cel::Program::compile(&source) {
                    Ok(program) => computed.push(Computed {
                        field: k,
                        source,
                        program,
                    }),
                    Err(e) => problems.push(format!("task `{task}`: `{k}` = `{source}`: {e}")),
                }
            }
            if !r.silent {
                for (k, t) in &form.result {
                    let given = r.fixed.contains_key(k) || computed.iter().any(|c| &c.field == k);
                    if !given && !matches!(t, connector_api::Type::Optional(_)) {
                        problems.push(format!("task `{task}`: required field `{k}` has no answer"));
                    }
                }
            }
            rules.insert(
                task,
                Rule {
                    delay: Duration::from_millis(r.delay_ms),
                    fixed: r.fixed,
                    computed,
                    silent: r.silent,
                },
            );
        }
        if !problems.is_empty() {
            return Err(bad(problems.join("\n")));
        }
        Ok(Policy {
            operator: file.operator.unwrap_or_else(|| "policy".to_owned()),
            rules,
            forms,
        })
    }

    /// What to do with a task of type `action` whose goal is `goal`.
    pub fn decide(&self, action: &str, goal: &Fields) -> Decision {
        let Some(rule) = self.rules.get(action) else {
            return Decision::Leave;
        };
        if rule.silent {
            return Decision::Silent;
        }
        let mut fields = rule.fixed.clone();
        let mut ctx = cel::Context::default();
        for (k, v) in goal {
            ctx.add_variable_from_value(k.as_str(), to_cel(v));
        }
        for c in &rule.computed {
            let value = c
                .program
                .execute(&ctx)
                .map_err(|e| e.to_string())
                .and_then(|v| v.json().map_err(|e| e.to_string()));
            match value {
                Ok(v) => {
                    fields.insert(c.field.clone(), v);
                }
                Err(e) => {
                    return Decision::Answer {
                        delay: rule.delay,
                        fields: Err(format!("`{}` = `{}` failed: {e}", c.field, c.source)),
                    };
                }
            }
        }
        let checked = match self.forms.action(action) {
            Some(form) => form.check_result(&fields).map(|()| fields),
            None => Err(format!("no form for `{action}`")),
        };
        Decision::Answer {
            delay: rule.delay,
            fields: checked,
        }
    }
}

/// A JSON value as CEL sees it (integers stay integers, so `site_id == 3` holds).
fn to_cel(v: &Value) -> cel::Value {
    match v {
        Value::Null => cel::Value::Null,
        Value::Bool(b) => cel::Value::Bool(*b),
        Value::Number(n) => match n.as_i64() {
            Some(i) => cel::Value::Int(i),
            None => cel::Value::Float(n.as_f64().unwrap_or(f64::NAN)),
        },
        Value::String(s) => cel::Value::String(Arc::new(s.clone())),
        Value::Array(items) => cel::Value::List(Arc::new(items.iter().map(to_cel).collect())),
        Value::Object(map) => cel::Value::Map(cel::objects::Map {
            map: Arc::new(
                map.iter()
                    .map(|(k, v)| (cel::objects::Key::from(k.clone()), to_cel(v)))
                    .collect(),
            ),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn forms() -> Arc<Catalogue> {
        Arc::new(
            serde_json::from_value(json!({"server": "ground", "actions": [
                {"name": "ground.approve_site", "result": {"approve": "bool", "comment": "string?"}},
                {"name": "ground.decide", "result": {"decision": "string"}}
            ]}))
            .unwrap(),
        )
    }

    fn load(text: &str) -> Result<Policy, PolicyError> {
        let dir = std::env::temp_dir().join(format!("policy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!(
            "{:x}.toml",
            text.len() * 31 + text.bytes().map(usize::from).sum::<usize>()
        ));
        std::fs::write(&path, text).unwrap();
        Policy::load(&path, forms())
    }

    #[test]
    fn answers_are_fixed_computed_delayed_or_withheld() {
        let p = load(
            r#"
operator = "night-shift"
[task."ground.approve_site"]
delay_ms = 5
computed = { approve = "context.candidates[0].score >= 0.5 && context.candidates[0].site_id != 3" }
fixed = { comment = "standing policy" }
[task."ground.decide"]
silent = true
"#,
        )
        .unwrap();
        assert_eq!(p.operator, "night-shift");
        let goal = |score: f64, site: i64| {
            json!({"task": "ApproveSite", "context": {"candidates": [{"site_id": site, "score": score}]}})
                .as_object()
                .cloned()
                .unwrap()
        };
        let approve = |score, site| match p.decide("ground.approve_site", &goal(score, site)) {
            Decision::Answer { delay, fields } => {
                assert_eq!(delay, Duration::from_millis(5));
                fields.unwrap()["approve"].clone()
            }
            other => panic!("{other:?}"),
        };
        assert_eq!(approve(0.7, 1), json!(true));
        assert_eq!(approve(0.7, 3), json!(false));
        assert_eq!(approve(0.2, 1), json!(false));
        assert_eq!(p.decide("ground.decide", &Fields::new()), Decision::Silent);
        assert_eq!(p.decide("ground.other", &Fields::new()), Decision::Leave);
        // A context without what the expression reads: no answer, and why.
        match p.decide("ground.approve_site", &Fields::new()) {
            Decision::Answer { fields: Err(e), .. } => assert!(e.contains("`approve`"), "{e}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn every_problem_in_a_policy_is_named() {
        let err = load(
            r#"
[task."ground.approve_site"]
fixed = { approve = "yes", colour = "red" }
[task."ground.decide"]
computed = { decision = "1 +" }
[task."ground.unknown"]
silent = true
"#,
        )
        .err()
        .expect("refused")
        .reason;
        for part in [
            "task `ground.approve_site`: fixed `approve` must be bool, got a string",
            "task `ground.approve_site`: `colour` is not a field",
            "task `ground.decide`: `decision` = `1 +`",
            "task `ground.decide`: required field `decision` has no answer",
            "task `ground.unknown`: no such form",
        ] {
            assert!(err.contains(part), "{part} in {err}");
        }
    }
}
