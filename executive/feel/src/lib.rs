//! FEEL, the DMN *Friendly Enough Expression Language*, in the dialect Camunda 8 writes: parsed
//! and checked when a mission loads, evaluated by the engine with FEEL's semantics.
//!
//! Pure: no I/O, no clock (`now()` and `today()` are the mission time of the step being
//! evaluated, passed in [`Env`]), no randomness, no hash-ordered collections, no threads.
//! Total: no input makes the lexer, parser or evaluator panic; nesting is capped and every
//! evaluation has a step budget, so an expression cannot overflow the stack or run for ever.
//!
//! # Why not an existing crate
//! The design note `../shared/design/feel.md` measured the candidates on our machines. The only
//! usable one, DSNTK 0.3.0, evaluates DMN FEEL correctly but resolves names against the
//! variables known *at parse time* (a loader knows none: `a and b` is one name), reads the wall
//! clock, links a blocking HTTP client and two C libraries (81 new crates), aborts the process on
//! deep recursion, panics on some decimal overflows, iterates `for` in quadratic time, reports
//! syntax errors without a position, and lacks 20 of the built-ins Camunda users call. Those
//! break the engine's invariants (deterministic, total, bounded, positioned diagnostics), so
//! this crate implements the dialect itself on two well-kept pure-Rust crates: `rust_decimal`
//! (exact decimal arithmetic, checked operations that never panic) and `chrono` with
//! `chrono-tz` (the temporal types and the IANA zone database), plus `regex` (linear-time
//! matching with a compiled-size limit) for `matches`, `replace` and `split`, and `base64` for
//! `to base64` / `from base64`. JSON (`from json`,
//! `to json`) has its own small reader and writer: serde_json without workspace-wide features
//! would sort object keys and read numbers as floats.
//!
//! # The dialect
//! Camunda's rules (feel-scala), where they differ from plain DMN FEEL:
//! - names are Java identifiers; other names are written in backticks (`` `order total` ``);
//!   multi-word names are only built-in functions (`string join(…)`) and context keys;
//! - comparing null with a non-null value by `=` is false (`!=` true); `<` with null is null;
//! - `is defined` (false for null and missing), `get or else`, `assert`, `is empty`,
//!   `is blank`, `from json`, `to json`, `to base64`, `from base64` built-ins, and Zeebe's
//!   `cycle`, `fromAi`, `bpmnError`, `jobError`;
//! - a call may name some parameters only; the others are null;
//! - string literals may span lines;
//! - a `for` body sees the values so far as `partial`;
//! - `in` takes Camunda's unary tests: comparisons, ranges, lists of tests, `not(…)`, and
//!   expressions using `?` for the tested value (`x in contains(?, "a")`);
//! - a missing variable is null even when it is named like a built-in function (`count`): a
//!   built-in is found only in call position.
//!
//! Numbers are decimals with 28 significant digits (feel-scala has 34); a result that does not fit
//! is null. Zones are offsets, `Z` and IANA zone ids (`@Europe/Paris`, with daylight saving, from
//! `chrono-tz`'s database); unknown ids are refused when the model loads.
//! Not supported: unary-test syntax outside `in` (DMN decision tables), `external` functions,
//! `uuid()` and `random number()` (not deterministic).

mod ast;
mod builtins;
mod check;
mod eval;
mod host;
mod lexer;
mod parser;
mod temporal;
#[cfg(test)]
mod tests;
mod value;

pub use ast::Span;
pub use host::Stop;
pub use value::{
    Bound, Context, DateTime, Function, Range, Time, Value, Zone, number_text, plain_text,
};

/// The most nested syntax the parser accepts (brackets, operators, calls).
pub const MAX_DEPTH: usize = 64;

/// The default step budget of one evaluation.
pub const BUDGET: usize = 100_000;

/// A parsed and checked FEEL expression.
#[derive(Clone, Debug)]
pub struct Expression {
    source: String,
    root: std::sync::Arc<ast::Node>,
    variables: Vec<String>,
}

/// A syntax error or a load-time problem, at a byte offset of the expression text.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{message} (at {} of `{text}`)", .span.start)]
pub struct Problem {
    /// What is wrong, naming what was expected.
    pub message: String,
    /// Where in the expression text.
    pub span: Span,
    /// The expression text.
    pub text: String,
}

/// What an evaluation may read.
pub struct Env<'a> {
    /// The value of a variable, or `None` if it is not defined.
    pub lookup: &'a dyn Fn(&str) -> Option<Value>,
    /// The mission time: what `now()` and `today()` give (UTC).
    pub now: DateTime,
    /// The step budget (see [`BUDGET`]).
    pub budget: usize,
}

/// The result of an evaluation.
#[derive(Clone, Debug)]
pub struct Evaluated {
    /// The value.
    pub value: Value,
    /// The first reason a null arose during the evaluation (`no variable \`x\``), if any:
    /// what an incident should say when the result is not what the site needs.
    pub note: Option<String>,
}

/// Parses `text` (without Camunda's leading `=`).
pub fn parse(text: &str) -> Result<Expression, Problem> {
    let root = parser::parse(text).map_err(|(message, span)| Problem {
        message,
        span,
        text: text.to_owned(),
    })?;
    let variables = check::free_variables(&root);
    Ok(Expression {
        source: text.to_owned(),
        root: std::sync::Arc::new(root),
        variables,
    })
}

impl Expression {
    /// The expression text.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The variables the expression reads (names and the roots of paths), sorted.
    pub fn variables(&self) -> &[String] {
        &self.variables
    }

    /// The variables it reads for certain: [`Expression::variables`] but the names inside a
    /// filter's condition, which may be fields of the items filtered (`sites[score > 0.8]`).
    /// Worked out when asked (the check before flight asks; loading does not).
    pub fn required(&self) -> Vec<String> {
        check::required_variables(&self.root)
    }

    /// What is wrong beyond syntax, found without running: unknown functions, wrong argument
    /// counts or names, literal arguments a function refuses (`date("2026-02-30")`), functions
    /// that are not deterministic.
    pub fn problems(&self) -> Vec<Problem> {
        check::problems(&self.root)
            .into_iter()
            .map(|(message, span)| Problem {
                message,
                span,
                text: self.source.clone(),
            })
            .collect()
    }

    /// Evaluates the expression.
    pub fn evaluate(&self, env: &Env<'_>) -> Result<Evaluated, Stop> {
        eval::evaluate(&self.root, env)
    }
}
