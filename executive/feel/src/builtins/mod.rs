//! FEEL's non-temporal built-in functions, in Camunda 8's (feel-scala's) dialect: boolean,
//! conversion (with JSON), string (with Base64), list, numeric, context and range functions,
//! and the functions Zeebe and the Connectors runtime add (`fromAi`, `bpmnError`, `jobError`).
//! The temporal ones (`date`, `now`, `day of week`, …) live in `crate::temporal`.
//!
//! Every function is total: a null or wrongly typed argument, or a result that does not fit,
//! gives null with a reason (recorded through [`Host::null`]); only `assert` fails the evaluation
//! on purpose, and functions that walk or build lists spend budget in proportion to their size.
//! `uuid()` and `random number()` are deliberately absent (not deterministic).

mod contexts;
mod conversion;
mod encoding;
mod json;
mod lists;
mod logic;
mod numbers;
mod ranges;
mod strings;
#[cfg(test)]
mod testing;
mod zeebe;

use rust_decimal::Decimal;
use rust_decimal::prelude::ToPrimitive;

use crate::host::{Builtin, Host, Stop};
use crate::value::{Context, Value};

/// Why a built-in gives no value: a null with its reason, or a stop of the whole evaluation.
#[derive(Debug)]
pub(super) enum Fail {
    /// The function's answer is null, for this reason (without the function's name).
    Null(String),
    /// The evaluation stops (budget, depth, `assert`).
    Stop(Stop),
}

impl From<Stop> for Fail {
    fn from(s: Stop) -> Self {
        Fail::Stop(s)
    }
}

/// What the implementation of a built-in returns.
pub(super) type Out = Result<Value, Fail>;

/// A null result for `why`.
pub(super) fn null<T>(why: impl Into<String>) -> Result<T, Fail> {
    Err(Fail::Null(why.into()))
}

/// Turns an implementation's outcome into the built-in's: a null records its reason, prefixed
/// with the function's name.
fn finish(host: &mut dyn Host, name: &str, out: Out) -> Result<Value, Stop> {
    match out {
        Ok(v) => Ok(v),
        Err(Fail::Null(why)) => Ok(host.null(format!("{name}: {why}"))),
        Err(Fail::Stop(s)) => Err(s),
    }
}

/// The arguments as an array of `N` (missing ones are null, extra ones dropped).
pub(super) fn take<const N: usize>(args: Vec<Value>) -> [Value; N] {
    let mut it = args.into_iter();
    std::array::from_fn(|_| it.next().unwrap_or(Value::Null))
}

/// The arguments of a variadic `f(list)` / `f(a, b, …)`: a single list argument is the list of
/// values; otherwise the arguments themselves are (feel-scala's rule for varargs).
pub(super) fn varargs(mut args: Vec<Value>) -> Vec<Value> {
    if args.len() == 1
        && matches!(args.first(), Some(Value::List(_)))
        && let Some(Value::List(items)) = args.pop()
    {
        return items;
    }
    args
}

/// The reason for an argument of the wrong type.
pub(super) fn wrong(param: &str, expected: &str, found: &Value) -> Fail {
    if found.is_null() {
        Fail::Null(format!("`{param}` is null"))
    } else {
        Fail::Null(format!(
            "`{param}` must be {expected}, not a {}",
            found.type_name()
        ))
    }
}

/// The text of a string argument.
pub(super) fn text<'a>(v: &'a Value, param: &str) -> Result<&'a str, Fail> {
    match v {
        Value::String(s) => Ok(s),
        other => Err(wrong(param, "a string", other)),
    }
}

/// The number of a number argument.
pub(super) fn number(v: &Value, param: &str) -> Result<Decimal, Fail> {
    match v {
        Value::Number(n) => Ok(*n),
        other => Err(wrong(param, "a number", other)),
    }
}

/// The items of a list argument.
pub(super) fn list(v: Value, param: &str) -> Result<Vec<Value>, Fail> {
    match v {
        Value::List(items) => Ok(items),
        other => Err(wrong(param, "a list", &other)),
    }
}

/// The items of a list argument, borrowed.
pub(super) fn list_ref<'a>(v: &'a Value, param: &str) -> Result<&'a [Value], Fail> {
    match v {
        Value::List(items) => Ok(items),
        other => Err(wrong(param, "a list", other)),
    }
}

/// The entries of a context argument.
pub(super) fn context(v: Value, param: &str) -> Result<Context, Fail> {
    match v {
        Value::Context(c) => Ok(c),
        other => Err(wrong(param, "a context", &other)),
    }
}

/// A position or length argument: a number, truncated towards zero as feel-scala does
/// (`1.9` is `1`); numbers beyond `i64` saturate (they are out of range for any list anyway).
pub(super) fn whole(v: &Value, param: &str) -> Result<i64, Fail> {
    let n = number(v, param)?.trunc();
    Ok(n.to_i64().unwrap_or(if n.is_sign_negative() {
        i64::MIN
    } else {
        i64::MAX
    }))
}

/// Context entries being collected, with an index by key so that many entries cost
/// `n log n`, not `n²`.
#[derive(Default)]
pub(super) struct Entries {
    entries: Vec<(String, Value)>,
    index: std::collections::BTreeMap<String, usize>,
}

impl Entries {
    /// Sets `key`: replaces the value of an existing entry in place, or appends.
    pub(super) fn put(&mut self, key: String, value: Value) {
        match self.index.get(&key).and_then(|&i| self.entries.get_mut(i)) {
            Some(slot) => slot.1 = value,
            None => {
                self.index.insert(key.clone(), self.entries.len());
                self.entries.push((key, value));
            }
        }
    }

    /// The context.
    pub(super) fn done(self) -> Context {
        Context(self.entries)
    }
}

/// A built-in entry whose implementation is `$f(host, args) -> Out`.
macro_rules! builtin {
    ($name:literal, [$($p:literal),*], $f:path) => {
        Builtin {
            name: $name,
            params: &[$($p),*],
            variadic: false,
            run: |h, a| {
                let out = $f(&mut *h, a);
                finish(h, $name, out)
            },
        }
    };
    ($name:literal, [$($p:literal),*] variadic, $f:path) => {
        Builtin {
            name: $name,
            params: &[$($p),*],
            variadic: true,
            run: |h, a| {
                let out = $f(&mut *h, a);
                finish(h, $name, out)
            },
        }
    };
}

/// Every non-temporal built-in signature. Overloads of one name are separate entries; among
/// entries with the same number of parameters the first is the one positional calls get, so
/// those share one implementation that looks at the argument types.
pub(crate) static BUILTINS: &[Builtin] = &[
    // Boolean functions.
    builtin!("not", ["negand"], logic::not),
    builtin!("is defined", ["value"], logic::is_defined),
    builtin!("get or else", ["value", "default"], logic::get_or_else),
    builtin!("assert", ["value", "condition"], logic::assert),
    builtin!("assert", ["value", "condition", "cause"], logic::assert),
    // Conversion functions.
    builtin!("string", ["from"], conversion::string),
    builtin!("number", ["from"], conversion::number),
    builtin!("number", ["from", "grouping separator"], conversion::number),
    builtin!(
        "number",
        ["from", "grouping separator", "decimal separator"],
        conversion::number
    ),
    builtin!("context", ["entries"], conversion::context),
    builtin!("from json", ["value"], json::from_json),
    builtin!("to json", ["value"], json::to_json),
    // String functions.
    builtin!(
        "substring",
        ["string", "start position"],
        strings::substring
    ),
    builtin!(
        "substring",
        ["string", "start position", "length"],
        strings::substring
    ),
    builtin!("string length", ["string"], strings::length),
    builtin!("upper case", ["string"], strings::upper_case),
    builtin!("lower case", ["string"], strings::lower_case),
    builtin!("substring before", ["string", "match"], strings::before),
    builtin!("substring after", ["string", "match"], strings::after),
    builtin!("contains", ["string", "match"], strings::contains),
    builtin!("starts with", ["string", "match"], strings::starts_with),
    builtin!("ends with", ["string", "match"], strings::ends_with),
    builtin!(
        "replace",
        ["input", "pattern", "replacement"],
        strings::replace
    ),
    builtin!(
        "replace",
        ["input", "pattern", "replacement", "flags"],
        strings::replace
    ),
    builtin!("matches", ["input", "pattern"], strings::matches),
    builtin!("matches", ["input", "pattern", "flags"], strings::matches),
    builtin!("split", ["string", "delimiter"], strings::split),
    builtin!("extract", ["input", "pattern"], strings::extract),
    builtin!("trim", ["string"], strings::trim),
    builtin!("is blank", ["string"], strings::is_blank),
    builtin!("to base64", ["value"], encoding::to_base64),
    builtin!("from base64", ["value"], encoding::from_base64),
    // List functions.
    builtin!("list contains", ["list", "element"], lists::contains),
    builtin!("count", ["list"], lists::count),
    builtin!("min", ["list"] variadic, lists::min),
    builtin!("max", ["list"] variadic, lists::max),
    builtin!("sum", ["list"] variadic, lists::sum),
    builtin!("product", ["list"] variadic, lists::product),
    builtin!("mean", ["list"] variadic, lists::mean),
    builtin!("median", ["list"] variadic, lists::median),
    builtin!("stddev", ["list"] variadic, lists::stddev),
    builtin!("mode", ["list"] variadic, lists::mode),
    builtin!("all", ["list"] variadic, lists::all),
    builtin!("and", ["list"] variadic, lists::all),
    builtin!("any", ["list"] variadic, lists::any),
    builtin!("or", ["list"] variadic, lists::any),
    builtin!("sublist", ["list", "start position"], lists::sublist),
    builtin!("sublist", ["list", "start"], lists::sublist),
    builtin!(
        "sublist",
        ["list", "start position", "length"],
        lists::sublist
    ),
    builtin!("sublist", ["list", "start", "length"], lists::sublist),
    builtin!("append", ["list", "items"] variadic, lists::append),
    builtin!("concatenate", ["lists"] variadic, lists::concatenate),
    builtin!(
        "insert before",
        ["list", "position", "newItem"],
        lists::insert_before
    ),
    builtin!("remove", ["list", "position"], lists::remove),
    builtin!("reverse", ["list"], lists::reverse),
    builtin!("index of", ["list", "match"], lists::index_of),
    builtin!("union", ["lists"] variadic, lists::union),
    builtin!("distinct values", ["list"], lists::distinct_values),
    builtin!("duplicate values", ["list"], lists::duplicate_values),
    builtin!("flatten", ["list"], lists::flatten),
    builtin!("sort", ["list"], lists::sort),
    builtin!("sort", ["list", "precedes"], lists::sort),
    builtin!("string join", ["list"], lists::string_join),
    builtin!("string join", ["list", "delimiter"], lists::string_join),
    builtin!(
        "string join",
        ["list", "delimiter", "prefix", "suffix"],
        lists::string_join
    ),
    builtin!("is empty", ["list"], lists::is_empty),
    builtin!("partition", ["list", "size"], lists::partition),
    // Numeric functions.
    builtin!("decimal", ["n", "scale"], numbers::decimal),
    builtin!("decimal", ["n", "scale", "mode"], numbers::decimal),
    builtin!("floor", ["n"], numbers::floor),
    builtin!("floor", ["n", "scale"], numbers::floor),
    builtin!("ceiling", ["n"], numbers::ceiling),
    builtin!("ceiling", ["n", "scale"], numbers::ceiling),
    builtin!("round up", ["n"], numbers::round_up),
    builtin!("round up", ["n", "scale"], numbers::round_up),
    builtin!("round down", ["n"], numbers::round_down),
    builtin!("round down", ["n", "scale"], numbers::round_down),
    builtin!("round half up", ["n"], numbers::round_half_up),
    builtin!("round half up", ["n", "scale"], numbers::round_half_up),
    builtin!("round half down", ["n"], numbers::round_half_down),
    builtin!("round half down", ["n", "scale"], numbers::round_half_down),
    builtin!("abs", ["n"], numbers::abs),
    builtin!("abs", ["number"], numbers::abs),
    builtin!("modulo", ["dividend", "divisor"], numbers::modulo),
    builtin!("sqrt", ["number"], numbers::sqrt),
    builtin!("log", ["number"], numbers::log),
    builtin!("exp", ["number"], numbers::exp),
    builtin!("odd", ["number"], numbers::odd),
    builtin!("even", ["number"], numbers::even),
    // Context functions.
    builtin!("get value", ["context", "key"], contexts::get_value),
    builtin!("get value", ["context", "keys"], contexts::get_value),
    builtin!("get value", ["m", "key"], contexts::get_value),
    builtin!("get entries", ["context"], contexts::get_entries),
    builtin!("get entries", ["m"], contexts::get_entries),
    builtin!("context put", ["context", "key", "value"], contexts::put),
    builtin!("context put", ["context", "keys", "value"], contexts::put),
    builtin!("context merge", ["contexts"] variadic, contexts::merge),
    builtin!("put", ["context", "key", "value"], contexts::put),
    builtin!("put all", ["contexts"] variadic, contexts::merge),
    // Range functions (DMN 1.3 §10.3.4.9): point/point, point/range, range/point and
    // range/range forms, told apart by the argument types.
    builtin!("before", ["point1", "point2"], ranges::before),
    builtin!("before", ["point", "range"], ranges::before),
    builtin!("before", ["range", "point"], ranges::before),
    builtin!("before", ["range1", "range2"], ranges::before),
    builtin!("after", ["point1", "point2"], ranges::after),
    builtin!("after", ["point", "range"], ranges::after),
    builtin!("after", ["range", "point"], ranges::after),
    builtin!("after", ["range1", "range2"], ranges::after),
    builtin!("meets", ["range1", "range2"], ranges::meets),
    builtin!("met by", ["range1", "range2"], ranges::met_by),
    builtin!("overlaps", ["range1", "range2"], ranges::overlaps),
    builtin!(
        "overlaps before",
        ["range1", "range2"],
        ranges::overlaps_before
    ),
    builtin!(
        "overlaps after",
        ["range1", "range2"],
        ranges::overlaps_after
    ),
    builtin!("finishes", ["point", "range"], ranges::finishes),
    builtin!("finishes", ["range1", "range2"], ranges::finishes),
    builtin!("finished by", ["range", "point"], ranges::finished_by),
    builtin!("finished by", ["range1", "range2"], ranges::finished_by),
    builtin!("includes", ["range", "point"], ranges::includes),
    builtin!("includes", ["range1", "range2"], ranges::includes),
    builtin!("during", ["point", "range"], ranges::during),
    builtin!("during", ["range1", "range2"], ranges::during),
    builtin!("starts", ["point", "range"], ranges::starts),
    builtin!("starts", ["range1", "range2"], ranges::starts),
    builtin!("started by", ["range", "point"], ranges::started_by),
    builtin!("started by", ["range1", "range2"], ranges::started_by),
    builtin!("coincides", ["point1", "point2"], ranges::coincides),
    builtin!("coincides", ["range1", "range2"], ranges::coincides),
    // Zeebe's `fromAi` (AI agent tool parameters) and the Connectors runtime's error-expression
    // functions.
    builtin!("fromAi", ["value"], zeebe::from_ai),
    builtin!("fromAi", ["value", "description"], zeebe::from_ai),
    builtin!("fromAi", ["value", "description", "type"], zeebe::from_ai),
    builtin!(
        "fromAi",
        ["value", "description", "type", "schema"],
        zeebe::from_ai
    ),
    builtin!(
        "fromAi",
        ["value", "description", "type", "schema", "options"],
        zeebe::from_ai
    ),
    builtin!("bpmnError", ["code", "message"], zeebe::bpmn_error),
    builtin!(
        "bpmnError",
        ["code", "message", "variables"],
        zeebe::bpmn_error
    ),
    builtin!("jobError", ["message"], zeebe::job_error),
    builtin!("jobError", ["message", "variables"], zeebe::job_error),
    builtin!(
        "jobError",
        ["message", "variables", "retries"],
        zeebe::job_error
    ),
    builtin!(
        "jobError",
        ["message", "variables", "retries", "retryBackoff"],
        zeebe::job_error
    ),
];

#[cfg(test)]
mod tests {
    use super::BUILTINS;
    use super::testing::{Mock, lit};
    use crate::host::Stop;
    use crate::value::Value;

    /// Awkward arguments: nulls, extremes, empty and mixed collections, ranges, functions.
    const SAMPLES: &[&str] = &[
        "null",
        "0",
        "-1",
        "79228162514264337593543950335",
        "-79228162514264337593543950335",
        "0.0000000000000000000000000001",
        "2.5",
        "\"\"",
        "\"a,b\"",
        "\"(\"",
        "[]",
        "[1, \"a\", null, [2]]",
        "[\"x\", \"y\"]",
        "{}",
        "{key: \"k\", value: 1}",
        "[{a: 1}, {b: [1]}]",
        "[1..5)",
        "(..0]",
        "true",
        "@before",
        "[3, 1, 2]",
    ];

    /// Every argument tuple of `n` samples (fewer samples for long tuples).
    fn tuples(n: usize) -> Vec<Vec<Value>> {
        let samples: Vec<Value> = SAMPLES.iter().map(|s| lit(s)).collect();
        let pool = if n >= 3 { &samples[..9] } else { &samples[..] };
        let mut out = vec![Vec::new()];
        for _ in 0..n {
            out = out
                .into_iter()
                .flat_map(|t| {
                    pool.iter().map(move |s| {
                        let mut t = t.clone();
                        t.push(s.clone());
                        t
                    })
                })
                .collect();
        }
        out
    }

    #[test]
    fn every_signature_is_total_and_explains_its_nulls() {
        let mut silent = Vec::new();
        for b in BUILTINS {
            let counts: Vec<usize> = if b.variadic {
                vec![0, 1, 2, 3]
            } else {
                vec![b.params.len()]
            };
            for n in counts {
                if n + 1 < b.params.len() {
                    continue;
                }
                for args in tuples(n) {
                    let shown: Vec<String> = args.iter().map(ToString::to_string).collect();
                    let mut host = Mock::new(100_000);
                    match (b.run)(&mut host, args) {
                        Ok(Value::Null) if host.notes.is_empty() => {
                            silent.push(format!("{}({})", b.name, shown.join(", ")));
                        }
                        Ok(_) => {}
                        Err(Stop::Failed(_)) if b.name == "assert" => {}
                        Err(e) => panic!("{}({}) stopped: {e}", b.name, shown.join(", ")),
                    }
                    // The first note may come from a function `sort` called; the
                    // function's own note follows.
                    if !host.notes.is_empty() {
                        assert!(
                            host.notes.iter().any(|n| n.starts_with(b.name)),
                            "{}({}): notes {:?}",
                            b.name,
                            shown.join(", "),
                            host.notes
                        );
                    }
                }
            }
        }
        // Null without a reason only where null is the answer itself.
        silent.retain(|c| {
            !c.starts_with("get or else(") && !c.starts_with("assert(") && !c.starts_with("fromAi(")
        });
        assert!(
            silent.is_empty(),
            "nulls without a reason:\n{}",
            silent.join("\n")
        );
    }

    #[test]
    fn names_and_parameters_are_well_formed() {
        for b in BUILTINS {
            assert!(!b.name.is_empty() && b.name.trim() == b.name);
            let same: Vec<_> = BUILTINS
                .iter()
                .filter(|o| o.name == b.name && o.params == b.params)
                .collect();
            assert_eq!(same.len(), 1, "{} has a duplicate signature", b.name);
            assert!(
                !matches!(b.name, "uuid" | "random number"),
                "not deterministic"
            );
        }
    }
}
