//! The FEEL test suite: golden `(expression, expected result)` tables for the DMN FEEL language
//! (literals, arithmetic, logic, lists, contexts, control flow, functions, built-ins, temporal
//! values) with Camunda 8's (feel-scala's) dialect where it differs (null comparison, the
//! Camunda extensions, backticked names, multi-line strings, Zeebe's `cycle`); positioned syntax
//! errors, load-time problems and free variables; and robustness: no input makes the parser or
//! the evaluator panic, overflow the stack or run unbounded.
//!
//! Results are compared as text: [`Value`]'s `Display` (numbers normalised `1.5`, strings quoted
//! `"a"`, lists `[1, 2]`, contexts `{a:1, b:2}`, `null`, temporal values in ISO form). Every
//! table is checked row by row and a failing test lists all of its differing rows.

mod camunda;
mod errors;
mod functions;
mod nulls;
mod robustness;
mod spec;
mod temporal;

use std::panic::{AssertUnwindSafe, catch_unwind};

use chrono::{FixedOffset, NaiveDate};
use rust_decimal::Decimal;

use crate::{BUDGET, Context, DateTime, Env, Evaluated, Problem, Stop, Value, Zone, parse};

/// The mission time every test evaluates at: 2026-11-23T10:00:00Z (a Monday).
fn now() -> DateTime {
    DateTime {
        local: NaiveDate::from_ymd_opt(2026, 11, 23)
            .and_then(|d| d.and_hms_opt(10, 0, 0))
            .expect("a valid date"),
        zone: Some(Zone {
            offset: FixedOffset::east_opt(0).expect("UTC"),
            id: None,
        }),
    }
}

/// Parses `text` (panicking with the syntax error) and evaluates it with `vars` and `budget`.
fn run(text: &str, vars: &[(&str, Value)], budget: usize) -> Result<Evaluated, Stop> {
    let expression = parse(text).unwrap_or_else(|p| panic!("syntax error: {p}"));
    let lookup = |name: &str| {
        vars.iter()
            .find(|(k, _)| *k == name)
            .map(|(_, v)| v.clone())
    };
    expression.evaluate(&Env {
        lookup: &lookup,
        now: now(),
        budget,
    })
}

/// The result of `text` evaluated without variables, as text. A syntax error or a [`Stop`]
/// panics with its message.
fn feel(text: &str) -> String {
    feel_vars(text, &[])
}

/// The result of `text` evaluated with `vars`, as text. A syntax error or a [`Stop`] panics
/// with its message.
fn feel_vars(text: &str, vars: &[(&str, Value)]) -> String {
    match run(text, vars, BUDGET) {
        Ok(e) => e.value.to_string(),
        Err(stop) => panic!("`{text}` stopped: {stop}"),
    }
}

/// What `text` gives, as text, never panicking for a syntax error or a stop (they are
/// described in angle brackets) and catching a panic of the implementation.
fn outcome(text: &str, vars: &[(&str, Value)]) -> String {
    let attempt = catch_unwind(AssertUnwindSafe(|| match parse(text) {
        Err(p) => format!("<syntax error: {} at {}>", p.message, p.span.start),
        Ok(expression) => {
            let lookup = |name: &str| {
                vars.iter()
                    .find(|(k, _)| *k == name)
                    .map(|(_, v)| v.clone())
            };
            let env = Env {
                lookup: &lookup,
                now: now(),
                budget: BUDGET,
            };
            match expression.evaluate(&env) {
                Ok(e) => e.value.to_string(),
                Err(stop) => format!("<stop: {stop}>"),
            }
        }
    }));
    attempt.unwrap_or_else(|p| format!("<panic: {}>", panic_text(p.as_ref())))
}

/// The message of a caught panic.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| (*s).to_owned()))
        .unwrap_or_else(|| "(no message)".to_owned())
}

/// Checks every `(expression, expected)` row without variables.
fn check(rows: &[(&str, &str)]) {
    check_vars(&[], rows);
}

/// Checks every `(expression, expected)` row with `vars`; fails listing every differing row.
fn check_vars(vars: &[(&str, Value)], rows: &[(&str, &str)]) {
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|(text, expected)| {
            let actual = outcome(text, vars);
            (actual != *expected)
                .then(|| format!("  {text}\n      expected {expected}\n      actual   {actual}"))
        })
        .collect();
    assert!(
        wrong.is_empty(),
        "{} of {} rows differ:\n{}",
        wrong.len(),
        rows.len(),
        wrong.join("\n")
    );
}

/// Checks that every expression's result starts with the given text (long decimals).
fn check_prefix(rows: &[(&str, &str)]) {
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|(text, prefix)| {
            let actual = outcome(text, &[]);
            (!actual.starts_with(prefix))
                .then(|| format!("  {text}\n      expected {prefix}…\n      actual   {actual}"))
        })
        .collect();
    assert!(
        wrong.is_empty(),
        "{} of {} rows differ:\n{}",
        wrong.len(),
        rows.len(),
        wrong.join("\n")
    );
}

/// A number.
fn n(i: i64) -> Value {
    Value::int(i)
}

/// A decimal number from its text (`"1.5"`).
fn dec(text: &str) -> Value {
    Value::Number(Decimal::from_str_exact(text).expect("a decimal"))
}

/// A string.
fn s(text: &str) -> Value {
    Value::String(text.to_owned())
}

/// A boolean.
fn b(value: bool) -> Value {
    Value::Bool(value)
}

/// A list.
fn list(items: impl IntoIterator<Item = Value>) -> Value {
    Value::List(items.into_iter().collect())
}

/// A context with the given entries, in order.
fn ctx(entries: &[(&str, Value)]) -> Value {
    Value::Context(Context(
        entries
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect(),
    ))
}

/// The variables of the design note's §3.2 table: `x="a"`, `a=true`, `b=false`, `n=3`,
/// `items=[1,2,3]`, `flag=false`, `nothing=null`; `missing` and `y` are not set.
fn camunda_vars() -> Vec<(&'static str, Value)> {
    vec![
        ("x", s("a")),
        ("a", b(true)),
        ("b", b(false)),
        ("n", n(3)),
        ("items", list([n(1), n(2), n(3)])),
        ("flag", b(false)),
        ("nothing", Value::Null),
    ]
}

/// The syntax error of `text`; panics if it parses.
fn syntax_error(text: &str) -> Problem {
    match parse(text) {
        Ok(_) => panic!("`{text}` parsed, a syntax error was expected"),
        Err(p) => p,
    }
}

/// The messages of the load-time problems of `text` (which must parse).
fn problems(text: &str) -> Vec<String> {
    parse(text)
        .unwrap_or_else(|p| panic!("syntax error: {p}"))
        .problems()
        .into_iter()
        .map(|p| p.message)
        .collect()
}

/// The free variables of `text` (which must parse).
fn variables(text: &str) -> Vec<String> {
    parse(text)
        .unwrap_or_else(|p| panic!("syntax error: {p}"))
        .variables()
        .to_vec()
}

/// Runs `body` in a child process (this test binary, filtered to the test `name` of the
/// calling module) when not already in one, so that a stack overflow, which aborts the whole
/// process, fails that test alone instead of the entire run.
fn isolated(module: &str, name: &str, body: impl FnOnce()) {
    const MARK: &str = "EXECUTIVE_FEEL_ISOLATED_TEST";
    if std::env::var_os(MARK).is_some() {
        body();
        return;
    }
    let path = module.split_once("::").map_or(module, |(_, rest)| rest);
    let test = format!("{path}::{name}");
    let exe = std::env::current_exe().expect("the test binary");
    let out = std::process::Command::new(exe)
        .args([test.as_str(), "--exact", "--nocapture", "--test-threads=1"])
        .env(MARK, "1")
        .output()
        .expect("the test binary runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "`{test}` failed in its own process ({}):\n{stdout}\n{stderr}",
        out.status
    );
}
