//! What a built-in function may ask of the evaluation that calls it: the mission clock, a null
//! with its reason, budget, and calling a function value (for `sort` and friends).

use crate::value::{DateTime, Value};

/// Why an evaluation stops as a whole (not a null: the expression has no value at all).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Stop {
    /// The step budget ran out: the expression does too much work.
    #[error("the evaluation exceeded its budget of {0} steps")]
    Budget(usize),
    /// Calls or nesting went deeper than the evaluator allows.
    #[error("the evaluation nested deeper than {0} levels")]
    Depth(usize),
    /// `assert(value, condition)` failed, or another deliberate failure.
    #[error("{0}")]
    Failed(String),
}

/// The evaluation's services for built-in functions.
pub(crate) trait Host {
    /// The current mission time (the time of the step being evaluated), in UTC.
    fn now(&self) -> DateTime;
    /// Records why a null arose (the first reason is kept) and returns `Value::Null`.
    fn null(&mut self, why: String) -> Value;
    /// Spends `units` of the step budget (one per list element produced or visited).
    fn spend(&mut self, units: usize) -> Result<(), Stop>;
    /// Calls a function value with positional arguments.
    fn apply(&mut self, function: &Value, args: Vec<Value>) -> Result<Value, Stop>;
}

/// A built-in function signature. A name may have several (overloads by parameter count or by
/// parameter names); the evaluator picks the one whose parameters the call supplies.
pub(crate) struct Builtin {
    /// The function's FEEL name (may contain spaces: `string join`).
    pub name: &'static str,
    /// Parameter names, for named arguments (`substring(string: "a", start position: 1)`).
    pub params: &'static [&'static str],
    /// Whether the last parameter takes any number of arguments (`min(1, 2, 3)`); the function
    /// then receives every argument as given.
    pub variadic: bool,
    /// The function: gets exactly `params.len()` arguments (or at least `params.len() - 1`
    /// when `variadic`), in parameter order.
    pub run: fn(&mut dyn Host, Vec<Value>) -> Result<Value, Stop>,
}

/// Every built-in signature of `name` (empty if there is no such function).
pub(crate) fn overloads(name: &str) -> impl Iterator<Item = &'static Builtin> {
    all().filter(move |b| b.name == name)
}

/// Every built-in signature.
pub(crate) fn all() -> impl Iterator<Item = &'static Builtin> {
    crate::builtins::BUILTINS
        .iter()
        .chain(crate::temporal::TEMPORAL.iter())
}
