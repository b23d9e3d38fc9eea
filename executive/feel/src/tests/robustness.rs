//! Totality and bounds (crate doc: "no input makes the lexer, parser or evaluator panic;
//! nesting is capped and every evaluation has a step budget"; feel.md §3.7 and §6.3): a
//! deterministic pseudo-random walk over token soups and mutated expressions, and the edge
//! cases that broke the measured alternative (overflowing decimals, deep recursion, quadratic
//! or unbounded loops, deep nesting, huge literals). Tests that could overflow the stack run
//! in their own process (`isolated`), so an abort fails one test, not the whole run.

use std::panic::{AssertUnwindSafe, catch_unwind};

use super::{camunda_vars, isolated, outcome, panic_text, run};
use crate::{BUDGET, Env, Stop, Value, parse};

/// The pieces the walk assembles: FEEL tokens, keywords, names, built-in names, literals of
/// every kind, and edge characters (unterminated quotes, `@"`, backticks, unicode, controls,
/// very long numbers).
const TOKENS: &[&str] = &[
    "1",
    "0",
    "2.5",
    ".5",
    "-",
    "+",
    "*",
    "/",
    "**",
    "=",
    "!=",
    "<",
    "<=",
    ">",
    ">=",
    "(",
    ")",
    "[",
    "]",
    "{",
    "}",
    ",",
    ":",
    ".",
    "..",
    "x",
    "n",
    "items",
    "item",
    "nothing",
    "missing",
    "a",
    "b",
    "\"a\"",
    "\"\"",
    "\"",
    "'",
    "@\"",
    "@\"2026-11-23\"",
    "@\"P1D\"",
    "@\"10:00:00Z\"",
    "@\"2026-11-23T10:00:00@UTC\"",
    "@\"bad\"",
    "@",
    "`",
    "`a b`",
    "and",
    "or",
    "not",
    "if",
    "then",
    "else",
    "for",
    "in",
    "return",
    "some",
    "every",
    "satisfies",
    "between",
    "instance",
    "of",
    "instance of",
    "number",
    "function",
    "function(x)",
    "external",
    "null",
    "true",
    "false",
    "date(",
    "date and time(",
    "duration(\"P",
    "duration(\"PT1H\")",
    "substring(",
    "string join(",
    "count(",
    "sum(",
    "sort(",
    "is defined(",
    "get or else(",
    "assert(",
    "now()",
    "today()",
    "cycle(",
    "matches(",
    "\"(a+)+$\"",
    "f(",
    "f",
    "{f: function(x) f(x),",
    "for i in 1..",
    "1..",
    "99999999",
    "99999999999999999999999999999999999999",
    "0.0000000000000000000000000000001",
    "-99999999999",
    "?",
    "not(",
    "partial",
    "day-time-duration",
    "random number(",
    "é",
    "\u{10348}",
    "\u{0}",
    "\u{feff}",
    "\u{202e}",
    "\n",
    "\r\n",
    "\t",
    " ",
    "  ",
    "\\",
    "\\u",
    "\\u00",
    "\\U",
    "#",
    "$",
    ";",
    "%",
    "|",
    "&",
    "^",
    "~",
    "start position:",
    "string:",
    "item.a",
    ".a",
    "[1,2,3]",
    "{a:1}",
    "[item > 1]",
];

/// Valid expressions the mutation walk starts from.
const SEEDS: &[&str] = &[
    "x = \"a\" and n / 2 = 1.5",
    "if n > 2 then \"big\" else \"small\"",
    "for i in 1..3, j in items return i * j",
    "some x in [1,2,3] satisfies x > 2",
    "{a: 1, b: a + 1, c: [a, b][item > 1]}.c",
    "{f: function(x) x * 2, r: f(3)}.r",
    "substring(string: \"foobar\", start position: 3)",
    "date and time(\"2026-11-23T10:00:00Z\") + duration(\"PT6H\")",
    "`order total` > 100 or is defined(y)",
    "[{a: 1}, {b: 2}].a",
    "string join(for i in items return string(i), \", \")",
    "n in [1..5] and x in (\"a\", \"b\") and 5 in (< 10)",
    "x in not(\"a\", < 3) or n in (? > 2, contains(?, \"b\"))",
    "for i in 1..5 return if i <= 2 then 1 else partial[-1] + partial[-2]",
    "d instance of day-time-duration or d instance of date time",
    "sort([3,1,2], function(a, b) a < b)[-1]",
    "\"multi\nline\" + \"\\u00e9\"",
    "now() - @\"2026-01-01T00:00:00Z\" > duration(\"P1D\")",
];

/// The walk's generator: a 64-bit linear congruential generator (Knuth's MMIX constants).
struct Walk(u64);

impl Walk {
    /// The next pseudo-random number in `0..bound`.
    fn below(&mut self, bound: usize) -> usize {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 33) % bound as u64) as usize
    }
}

/// Parses `text`, asks for its problems and variables, and evaluates it with a small budget;
/// returns whether it parsed. Panics propagate.
fn exercise(text: &str, vars: &[(&str, Value)]) -> bool {
    let Ok(expression) = parse(text) else {
        return false;
    };
    let _ = expression.problems();
    let _ = expression.variables();
    let lookup = |name: &str| {
        vars.iter()
            .find(|(k, _)| *k == name)
            .map(|(_, v)| v.clone())
    };
    let env = Env {
        lookup: &lookup,
        now: super::now(),
        budget: 2_000,
    };
    if let Ok(e) = expression.evaluate(&env) {
        let _ = e.value.to_string();
    }
    true
}

/// Runs [`exercise`] on each text, collecting the texts that panicked.
fn survey(texts: impl Iterator<Item = String>) -> (usize, usize, Vec<String>) {
    let vars = camunda_vars();
    let (mut total, mut parsed, mut panics) = (0, 0, Vec::new());
    for text in texts {
        total += 1;
        match catch_unwind(AssertUnwindSafe(|| exercise(&text, &vars))) {
            Ok(true) => parsed += 1,
            Ok(false) => {}
            Err(p) => panics.push(format!("{text:?}: {}", panic_text(p.as_ref()))),
        }
    }
    (total, parsed, panics)
}

/// No token soup makes the parser, the checker or the evaluator panic (20,000 soups).
#[test]
fn no_token_soup_panics() {
    isolated(module_path!(), "no_token_soup_panics", || {
        let mut walk = Walk(0x9e37_79b9_7f4a_7c15);
        let soups = (0..20_000).map(|_| {
            let len = walk.below(24);
            let glue = if walk.below(3) == 0 { "" } else { " " };
            (0..len)
                .map(|_| TOKENS[walk.below(TOKENS.len())])
                .collect::<Vec<_>>()
                .join(glue)
        });
        let (total, parsed, panics) = survey(soups);
        assert!(
            panics.is_empty(),
            "{} of {total} soups panicked:\n{}",
            panics.len(),
            panics.join("\n")
        );
        // The walk is not vacuous: some soups are valid expressions.
        assert!(parsed >= 200, "only {parsed} of {total} soups parsed");
    });
}

/// No mutation of a valid expression (characters deleted, duplicated, replaced, tokens
/// inserted, cut anywhere, even inside a UTF-8 sequence's neighbourhood) panics.
#[test]
fn no_mutated_expression_panics() {
    isolated(module_path!(), "no_mutated_expression_panics", || {
        let mut walk = Walk(0x2545_f491_4f6c_dd1d);
        let mutants = (0..10_000).map(|_| {
            let mut chars: Vec<char> = SEEDS[walk.below(SEEDS.len())].chars().collect();
            for _ in 0..=walk.below(4) {
                let at = walk.below(chars.len() + 1);
                match walk.below(5) {
                    0 if at < chars.len() => {
                        chars.remove(at);
                    }
                    1 if at < chars.len() => chars.insert(at, chars[at]),
                    2 if at < chars.len() => {
                        let t = TOKENS[walk.below(TOKENS.len())];
                        chars[at] = t.chars().next().unwrap_or(' ');
                    }
                    3 => chars.truncate(at),
                    _ => {
                        let t = TOKENS[walk.below(TOKENS.len())];
                        chars.splice(at..at, t.chars());
                    }
                }
            }
            chars.into_iter().collect::<String>()
        });
        let (total, parsed, panics) = survey(mutants);
        assert!(
            panics.is_empty(),
            "{} of {total} mutants panicked:\n{}",
            panics.len(),
            panics.join("\n")
        );
        assert!(parsed >= 500, "only {parsed} of {total} mutants parsed");
    });
}

/// Overflowing and out-of-range arithmetic and arguments give null (or one of the listed
/// values; `*`: any value), never a panic (feel.md §3.7, §6.3: checked decimal arithmetic).
#[test]
fn edge_values_never_panic() {
    let rows: &[(&str, &[&str])] = &[
        ("2 ** 999999999", &["null"]),
        ("2 ** -999999999", &["null", "0"]),
        ("10 ** 6144", &["null"]),
        ("string(10 ** 6144 * 10)", &["null"]),
        ("(-10) ** 6145", &["null"]),
        ("0 ** -1", &["null"]),
        ("2 ** 0.5", &["*"]),
        (
            "99999999999999999999999999999 * 99999999999999999999999999999",
            &["null"],
        ),
        (
            "-99999999999999999999999999999 - 99999999999999999999999999999",
            &["null"],
        ),
        (
            "0.0000000000000000000000000001 / 99999999999999999999999999999",
            &["null", "0"],
        ),
        ("1 / 0", &["null"]),
        ("modulo(1, 0)", &["null"]),
        ("decimal(1, 99999999999)", &["null", "1"]),
        ("decimal(1, -99999999999)", &["null", "0"]),
        ("round up(1.5, -99999999999)", &["null", "0"]),
        ("floor(1.5, 99999999)", &["null", "1.5"]),
        ("sqrt(-1)", &["null"]),
        ("log(0)", &["null"]),
        ("log(-1)", &["null"]),
        ("exp(99999)", &["null"]),
        ("substring(\"abc\", 99999999999)", &["null", "\"\""]),
        ("substring(\"abc\", -99999999999)", &["null", "\"abc\""]),
        ("substring(\"abc\", 1, 99999999999)", &["null", "\"abc\""]),
        ("substring(\"abc\", 1, -5)", &["null", "\"\""]),
        ("substring(\"abc\", 1.5)", &["*"]),
        ("substring(\"abc\", 0)", &["null", "\"abc\""]),
        (
            "sublist([1,2,3], 99999999999, 99999999999)",
            &["null", "[]"],
        ),
        ("insert before([1], 99999999999, 2)", &["null"]),
        ("remove([1], -99999999999)", &["null"]),
        ("[1,2,3][99999999999]", &["null"]),
        ("[1,2,3][-99999999999999999999]", &["null"]),
        ("[1,2,3][1.5]", &["*"]),
        ("date(99999999999, 1, 1)", &["null"]),
        ("date(2026, 13, 1)", &["null"]),
        ("time(25, 0, 0)", &["null"]),
        ("duration(\"P99999999999999999999D\")", &["null"]),
        ("@\"P99999999999999999999Y\"", &["null"]),
        (
            "date(\"2026-11-23\") + duration(\"P999999999Y\")",
            &["null"],
        ),
        ("duration(\"PT1S\") * 99999999999999999999", &["null"]),
        ("now() + duration(\"P99999999D\")", &["null"]),
        ("duration(\"P1D\") / 0", &["null"]),
        (
            "matches(\"aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa!\", \"(a+)+$\")",
            &["false"],
        ),
        (
            "matches(\"a\", \"a{1000}{1000}{1000}\")",
            &["null", "false"],
        ),
        ("replace(\"abc\", \"(\", \"x\")", &["null"]),
        ("split(\"abc\", \"\")", &["*"]),
        ("\"\\uD800\"", &["*"]),
        ("string length(\"\\U10FFFF\")", &["*"]),
        ("number(\"1e999999\")", &["null"]),
    ];
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|(text, allowed)| {
            let actual = outcome(text, &[]);
            let fine = if allowed == &["*"] {
                !actual.starts_with("<panic")
            } else {
                allowed.contains(&actual.as_str()) || actual.starts_with("<syntax error")
            };
            (!fine).then(|| {
                format!("  {text}\n      expected one of {allowed:?}\n      actual   {actual}")
            })
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

/// An unbounded loop stops on the step budget instead of running for ever (feel.md §3.7:
/// `for i in 1..1000000` did not finish in DSNTK; §6.3: ranges are never materialised).
#[test]
fn loops_stop_on_the_budget() {
    for text in [
        "for i in 1..100000000 return i",
        "for i in 1..300, j in 1..300 return i * j",
        "count(for i in 1..100000000 return i)",
        "string join(for i in 1..100000 return \"x\")",
        // `partial` copies the values so far each time: quadratic, so bounded early.
        "for i in 1..100000000 return partial",
        "for i in 1..1000 return count(partial)",
    ] {
        let started = std::time::Instant::now();
        let result = run(text, &[], BUDGET).map(|e| e.value.to_string());
        assert!(
            matches!(result, Err(Stop::Budget(_))),
            "`{text}` gave {result:?}"
        );
        assert!(
            started.elapsed().as_secs() < 30,
            "`{text}` took {:?}",
            started.elapsed()
        );
    }
    // A range as a value is not materialised: membership in a huge range is one comparison.
    let result = run("5 in [1..100000000]", &[], BUDGET).map(|e| e.value.to_string());
    assert_eq!(result, Ok("true".to_owned()));
}

/// The default budget (100,000 steps) affords a 10,000-element loop, but not a 50,000-element
/// one: each iteration costs at least a node visit and an element (crate doc of `eval`: "each
/// node visited and each list element made spends one step"), so 50,000 iterations exceed it.
#[test]
fn default_budget_boundary() {
    let result = run("count(for i in 1..10000 return i)", &[], BUDGET).map(|e| e.value.to_string());
    assert_eq!(result, Ok("10000".to_owned()));
    let result = run("count(for i in 1..50000 return i)", &[], BUDGET).map(|e| e.value.to_string());
    assert!(matches!(result, Err(Stop::Budget(_))), "{result:?}");
    // A smaller budget stops earlier.
    let result = run("count(for i in 1..1000 return i)", &[], 100).map(|e| e.value.to_string());
    assert!(matches!(result, Err(Stop::Budget(_))), "{result:?}");
    // docs/feel.md, "Bounded and total": a body that does a little work runs out at about
    // 20,000 items; one that reads `partial` (a copy of the values so far) at about 300.
    let result = run("count(for i in 1..19000 return i * 2)", &[], BUDGET);
    assert!(result.is_ok(), "{result:?}");
    let result = run("count(for i in 1..21000 return i * 2)", &[], BUDGET);
    assert!(matches!(result, Err(Stop::Budget(_))), "{result:?}");
    let result = run("count(for i in 1..300 return count(partial))", &[], BUDGET)
        .map(|e| e.value.to_string());
    assert_eq!(result, Ok("300".to_owned()));
    let result = run("count(for i in 1..500 return count(partial))", &[], BUDGET);
    assert!(matches!(result, Err(Stop::Budget(_))), "{result:?}");
    // Only a body that reads `partial` pays for it.
    let result = run("count(for i in 1..10000 return i)", &[], BUDGET);
    assert!(result.is_ok(), "{result:?}");
}

/// Recursion through functions defined in a context ends with `Stop::Depth` (or a null when
/// the function cannot see itself), never a stack overflow (feel.md §3.7: DSNTK aborts).
#[test]
fn recursion_is_bounded() {
    isolated(module_path!(), "recursion_is_bounded", || {
        for text in [
            "{f: function(x) f(x + 1), r: f(1)}.r",
            "{f: function(x) if x > 0 then f(x - 1) else 0, r: f(100000)}.r",
            "{f: function(x) sort([1, 2], function(a, b) f(a) < b), r: f(1)}.r",
            "{f: function(x) for i in [1] return f(i), r: f(1)}.r",
            "{f: function(x) [x][f(item)], r: f(1)}.r",
        ] {
            let result = run(text, &[], BUDGET).map(|e| e.value.to_string());
            let fine = matches!(result, Err(Stop::Depth(_)) | Err(Stop::Budget(_)))
                || result == Ok("null".to_owned());
            assert!(fine, "`{text}` gave {result:?}");
        }
        let result = run("{f: function(x) f(x + 1), r: f(1)}.r", &[], BUDGET);
        assert!(
            matches!(result, Err(Stop::Depth(_))) || result.is_ok_and(|e| e.value.is_null()),
            "direct recursion stops on depth or is null"
        );
    });
}

/// Deep nesting is a syntax error (the parser caps it at `MAX_DEPTH`), not a stack overflow;
/// long flat expressions are no problem for the parser and, evaluated, give their value or
/// stop on depth.
#[test]
fn deep_nesting_is_bounded() {
    isolated(module_path!(), "deep_nesting_is_bounded", || {
        let deep = [
            format!("{}1{}", "(".repeat(10_000), ")".repeat(10_000)),
            "(".repeat(10_000),
            format!("{}1{}", "[".repeat(10_000), "]".repeat(10_000)),
            format!("{}1{}", "{a:".repeat(10_000), "}".repeat(10_000)),
            format!("{}1{}", "not(".repeat(10_000), ")".repeat(10_000)),
            format!("{}1", "if true then ".repeat(10_000)),
            format!("{}1", "function(x) ".repeat(10_000)),
            format!("{}1", "for i in ".repeat(10_000)),
            format!("{}x", "some x in [1] satisfies ".repeat(10_000)),
            "@\"".repeat(10_000),
            "\"".repeat(10_001),
        ];
        for text in &deep {
            let outcome = catch_unwind(AssertUnwindSafe(|| parse(text).map(|_| ())));
            assert!(
                matches!(outcome, Ok(Err(_))),
                "{}…: expected a syntax error",
                &text[..text.len().min(40)]
            );
        }
        // Nesting well inside the cap parses and evaluates.
        let shallow = format!("{}1{}", "(".repeat(30), ")".repeat(30));
        assert_eq!(outcome(&shallow, &[]), "1");
        // 10,000 minus signs, 10,000-term sums, paths and lists: a value, a depth stop or a
        // syntax error, never a crash.
        let long = [
            (format!("{}1", "-".repeat(10_000)), "1"),
            (format!("{}1", "- ".repeat(10_001)), "-1"),
            (vec!["1"; 10_000].join(" + "), "10000"),
            (vec!["1"; 10_000].join(" * "), "1"),
            (vec!["true"; 10_000].join(" and "), "true"),
            (format!("[{}][-1]", vec!["1"; 10_000].join(",")), "1"),
            (format!("x{}", ".a".repeat(10_000)), "null"),
            (format!("items{}", "[1]".repeat(10_000)), "null"),
        ];
        for (text, value) in &long {
            let result = outcome(text, &camunda_vars());
            let fine = result == *value
                || result.starts_with("<syntax error")
                || result.starts_with("<stop: the evaluation nested deeper");
            assert!(fine, "{}…: {result}", &text[..text.len().min(40)]);
        }
    });
}

/// Huge literals: a 1 MB string, terminated or not, a 100,000-digit number.
#[test]
fn huge_literals() {
    let body = "a".repeat(1_000_000);
    let unterminated = format!("\"{body}");
    let p = parse(&unterminated).expect_err("an unterminated string is a syntax error");
    assert_eq!(p.span.start, 0, "the error points at the opening quote");
    let text = format!("string length(\"{body}\")");
    assert_eq!(outcome(&text, &[]), "1000000");
    let text = format!("\"{body}\" + \"b\" = \"{body}b\"");
    assert_eq!(outcome(&text, &[]), "true");
    let digits = "9".repeat(100_000);
    let result = outcome(&digits, &[]);
    assert!(
        result == "null" || result.starts_with("<syntax error"),
        "{}",
        &result[..result.len().min(80)]
    );
    let result = outcome(&format!("0.{digits}"), &[]);
    assert!(
        result == "null"
            || result.starts_with("<syntax error")
            || result.starts_with('1')
            || result.starts_with("0.9"),
        "{}",
        &result[..result.len().min(80)]
    );
    let name = "x".repeat(100_000);
    assert_eq!(outcome(&name, &[]), "null");
}

/// Values that nest copies of themselves double at every level; each read pays for the copy, so
/// thirty levels (a billion values) stop on the budget instead of exhausting memory.
#[test]
fn self_doubling_values_stop_on_the_budget() {
    let doubling = |level: &dyn Fn(usize) -> String| {
        let mut text = String::from("{a0: [1]");
        for i in 1..=30 {
            text.push_str(&format!(", a{i}: {}", level(i - 1)));
        }
        text + "}.a0"
    };
    // Through a list literal, a built-in function and a function of the expression.
    for text in [
        doubling(&|p| format!("[a{p}, a{p}]")),
        doubling(&|p| format!("append([], a{p}, a{p})")),
        doubling(&|p| format!("(function(x) [x, x])(a{p})")),
        doubling(&|p| format!("string(a{p}) + string(a{p})")),
    ] {
        let result = run(&text, &[], BUDGET);
        assert!(matches!(result, Err(Stop::Budget(_))), "{text}: {result:?}");
    }
}
