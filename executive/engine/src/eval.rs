//! Evaluating CEL expressions over scope variables and system data; typed field conversion;
//! timer deadlines. Pure functions.

use std::sync::{Arc, LazyLock};

use chrono::{DateTime, FixedOffset};
use executive_model::binding::FieldType;
use executive_model::timer::Timer;
use executive_model::timer::{self, TimerKind, TimerSpec, TimerValue};
use executive_model::{Expression, Program};

use crate::io::Millis;
use crate::value::{F64, Value, Vars};

/// The CEL standard library, built once (building it per evaluation would dominate a step).
static ENV: LazyLock<Arc<cel::Env>> = LazyLock::new(|| Arc::new(cel::Env::stdlib()));

/// Evaluates `expr` at mission time `now`, looking each variable it reads up with `lookup`.
/// CEL leaves undefined variables unbound, so the expression fails with CEL's "undeclared
/// reference" error; FEEL reads them as null, as Camunda does.
pub(crate) fn eval(
    expr: &Expression,
    now: Millis,
    lookup: &dyn Fn(&str) -> Option<Value>,
    read: &mut Vars,
) -> Result<Value, String> {
    explained(expr, now, lookup, read).map(|(v, _)| v)
}

/// Evaluates `expr` over `vars` at mission time `now`, exactly as the engine does in flight
/// (for tools that check an expression before a mission runs it, and for fuzzing).
pub fn evaluate(expr: &Expression, now: Millis, vars: &Vars) -> Result<Value, String> {
    eval(expr, now, &|name| vars.get(name).cloned(), &mut Vars::new())
}

/// [`eval`], with why a FEEL result is null (`: no variable `x``, or empty), for messages about
/// a result of the wrong type.
fn explained(
    expr: &Expression,
    now: Millis,
    lookup: &dyn Fn(&str) -> Option<Value>,
    read: &mut Vars,
) -> Result<(Value, String), String> {
    match expr.program() {
        Program::Cel(program) => {
            let mut ctx = cel::Context::with_env(Arc::clone(&ENV));
            for name in &expr.variables {
                if let Some(v) = lookup(name) {
                    ctx.add_variable_from_value(name.as_str(), v.to_cel());
                    read.insert(name.clone(), v);
                }
            }
            let out = program
                .execute(&ctx)
                .map_err(|e| format!("`{}` failed: {e}", expr.source))?;
            let v = Value::from_cel(&out).map_err(|e| format!("`{}`: {e}", expr.source))?;
            Ok((v, String::new()))
        }
        Program::Feel(feel) => {
            let seen = std::cell::RefCell::new(Vars::new());
            let find = |name: &str| {
                let v = lookup(name)?;
                seen.borrow_mut().insert(name.to_owned(), v.clone());
                Some(crate::feel::to_feel(&v))
            };
            let env = executive_feel::Env {
                lookup: &find,
                now: crate::feel::mission_time(now),
                budget: executive_feel::BUDGET,
            };
            let out = feel
                .evaluate(&env)
                .map_err(|e| format!("`{}` failed: {e}", expr.source))?;
            read.extend(seen.into_inner());
            let why = out.note.map(|n| format!(": {n}")).unwrap_or_default();
            let v = crate::feel::from_feel(&out.value)
                .map_err(|e| format!("`{}`: {e}{why}", expr.source))?;
            Ok((
                v,
                if out.value.is_null() {
                    why
                } else {
                    String::new()
                },
            ))
        }
    }
}

/// Evaluates a condition: it must give a boolean.
pub(crate) fn condition(
    expr: &Expression,
    now: Millis,
    lookup: &dyn Fn(&str) -> Option<Value>,
    read: &mut Vars,
) -> Result<bool, String> {
    match explained(expr, now, lookup, read)? {
        (Value::Bool(b), _) => Ok(b),
        (other, why) => Err(format!(
            "condition `{}` gave {} `{other}`, not a bool{why}",
            expr.source,
            other.type_name(),
        )),
    }
}

/// Converts `v` to the declared type, or says why it cannot be.
pub(crate) fn convert(v: Value, ty: &FieldType) -> Result<Value, String> {
    Ok(match (ty, v) {
        (FieldType::Json, v) => v,
        (FieldType::Int, Value::Int(i)) => Value::Int(i),
        (FieldType::Int, Value::Float(f)) if f.0.fract() == 0.0 && f.0.abs() < 9.0e15 => {
            Value::Int(f.0 as i64)
        }
        (FieldType::Float, Value::Float(f)) => Value::Float(f),
        (FieldType::Float, Value::Int(i)) => Value::Float(F64(i as f64)),
        (FieldType::String, Value::String(s)) => Value::String(s),
        (FieldType::Bool, Value::Bool(b)) => Value::Bool(b),
        (FieldType::Timestamp, Value::String(s)) => {
            DateTime::parse_from_rfc3339(&s)
                .map_err(|e| format!("`{s}` is not a timestamp: {e}"))?;
            Value::String(s)
        }
        (FieldType::List(t), Value::List(items)) => Value::List(
            items
                .into_iter()
                .map(|i| convert(i, t))
                .collect::<Result<_, _>>()?,
        ),
        (ty, v) => return Err(format!("expected {ty}, got {} `{v}`", v.type_name())),
    })
}

/// Sets `path` (`a.b.c`) in `vars`, creating objects on the way.
pub(crate) fn set_path(vars: &mut Vars, path: &str, value: Value) {
    let mut parts = path.split('.');
    let first = parts.next().unwrap_or(path);
    let rest: Vec<&str> = parts.collect();
    if rest.is_empty() {
        vars.insert(first.to_owned(), value);
        return;
    }
    let mut cur = vars
        .entry(first.to_owned())
        .or_insert_with(|| Value::Map(Default::default()));
    for key in rest {
        if !matches!(cur, Value::Map(_)) {
            *cur = Value::Map(Default::default());
        }
        let Value::Map(m) = cur else { return };
        cur = m
            .entry(key.to_owned())
            .or_insert_with(|| Value::Map(Default::default()));
    }
    *cur = value;
}

fn datetime(ms: Millis) -> DateTime<FixedOffset> {
    DateTime::from_timestamp_millis(ms)
        .unwrap_or_default()
        .fixed_offset()
}

/// The first deadline of a timer armed at `now`, and how many repetitions follow it.
pub(crate) fn deadline(
    t: &Timer,
    now: Millis,
    lookup: &dyn Fn(&str) -> Option<Value>,
) -> Result<(Millis, Option<u32>), String> {
    let spec = match &t.value {
        TimerValue::Fixed(s) => s.clone(),
        TimerValue::Expression(e) => {
            let text = match explained(e, now, lookup, &mut Vars::new())? {
                (Value::String(s), _) => s,
                (other, why) => {
                    return Err(format!(
                        "timer expression `{}` gave {other}, not ISO 8601 text{why}",
                        e.source
                    ));
                }
            };
            match t.kind {
                TimerKind::Date => TimerSpec::Date(timer::parse_date(&text)?),
                TimerKind::Duration => TimerSpec::Duration(timer::parse_duration(&text)?),
                TimerKind::Cycle => timer::parse_cycle(&text)?,
            }
        }
        TimerValue::Unparsed(s) => return Err(format!("timer value `{s}` is not ISO 8601")),
    };
    let from = datetime(now);
    let overflow = || "the timer deadline is out of range".to_owned();
    Ok(match spec {
        TimerSpec::Date(d) => (d.timestamp_millis(), Some(0)),
        TimerSpec::Duration(d) => (
            d.after(from).ok_or_else(overflow)?.timestamp_millis(),
            Some(0),
        ),
        TimerSpec::Cycle {
            repetitions,
            start,
            interval,
            end,
        } => {
            let first = interval.after(start.unwrap_or(from)).ok_or_else(overflow)?;
            if end.is_some_and(|e| first > e) {
                return Err("the timer cycle ends before its first firing".to_owned());
            }
            (
                first.timestamp_millis(),
                repetitions.map(|r| r.saturating_sub(1)),
            )
        }
    })
}

/// The next deadline of a repeating timer after the one at `due`.
pub(crate) fn next_deadline(t: &Timer, due: Millis) -> Option<Millis> {
    let TimerValue::Fixed(TimerSpec::Cycle { interval, end, .. }) = &t.value else {
        return None;
    };
    let next = interval.after(datetime(due))?;
    if end.is_some_and(|e| next > e) {
        return None;
    }
    Some(next.timestamp_millis())
}
