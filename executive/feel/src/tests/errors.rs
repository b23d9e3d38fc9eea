//! What a loader learns without running an expression: syntax errors positioned at the
//! offending token (design feel.md §6.4 step 1: "the token's offset in the expression … message
//! names the expected token"), load-time problems (§6.4 step 2 and the crate doc of
//! `Expression::problems`), and the free variables (§6.4 step 3).

use super::{problems, syntax_error, variables};
use crate::parse;

/// Checks that each text is a syntax error starting at the given byte offset, with a message
/// and a span inside the text; fails listing every differing row.
fn check_errors(rows: &[(&str, usize)]) {
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|&(text, at)| match parse(text) {
            Ok(_) => Some(format!(
                "  {text:?}\n      expected an error at {at}, it parsed"
            )),
            Err(p) => {
                let good = p.span.start == at
                    && p.span.start <= p.span.end
                    && p.span.end <= text.len()
                    && !p.message.trim().is_empty()
                    && p.text == text;
                (!good).then(|| {
                    format!(
                        "  {text:?}\n      expected an error at {at}\n      actual   {}..{}: {}",
                        p.span.start, p.span.end, p.message
                    )
                })
            }
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

/// Syntax errors point at the token that cannot continue the expression (the end of the text
/// when the expression is incomplete).
#[test]
fn syntax_errors_are_positioned() {
    check_errors(&[
        // feel.md §3.3: the error cases DSNTK could not position.
        ("a <", 3),
        ("(1 + 2", 6),
        ("[1, 2", 5),
        ("\"abc", 0),
        ("if x then 1", 11),
        // feel.md §3.1/§3.2: an unquoted name with a space is an error at its second word.
        ("order total > 100", 6),
        ("foo bar(1)", 4),
        // feel.md §3.3: `x = = 1` parses in DSNTK; in Camunda it is an error.
        ("x = = 1", 4),
        // feel.md §3.2: `= =` with the marker stripped.
        ("=", 0),
        // docs.camunda.io FEEL unary-tests, Expressions: `?` is the input value of a test;
        // outside the tests after `in` it stands for nothing.
        ("? > 3", 0),
        ("x + ?", 4),
        ("? in [1, 2]", 0),
        ("contains(?, \"a\")", 9),
        ("for ? in [1] return 1", 4),
        ("x in [1] and ? > 1", 13),
        ("{?: 1}", 1),
        ("a.?", 2),
        ("x in f(?: 1)", 8),
        ("x in not()", 9),
        ("x in not(1, )", 12),
        // A type name Camunda does not document.
        ("x instance of datetime", 14),
        // More incomplete or misplaced tokens.
        ("1 +", 3),
        (")", 0),
        ("1 2", 2),
        ("{a: }", 4),
        ("{a 1}", 3),
        ("[1,,2]", 3),
        ("if x then 1 else", 16),
        ("for x in return 1", 9),
        ("some x in [1] x > 1", 14),
        ("x instance of", 13),
        ("`abc", 0),
        ("function(x)", 11),
        ("x.", 2),
        ("x[", 2),
        ("\"a\" \"b\"", 4),
        ("a <> b", 3),
        // DMN grammar rule 41: arguments are all named or all positional.
        ("f(a: 1, 2)", 8),
        // An empty or blank expression: at its start.
        ("", 0),
        ("   ", 0),
    ]);
}

/// A syntax error's message says what was expected or found, and the `Problem` renders it
/// with the position and the expression.
#[test]
fn syntax_error_messages() {
    let p = syntax_error("(1 + 2");
    assert!(
        p.message.contains(')'),
        "the message names `)`: {}",
        p.message
    );
    let text = p.to_string();
    assert!(text.contains("at 6") && text.contains("(1 + 2"), "{text}");
    let p = syntax_error("order total > 100");
    assert!(
        p.message.contains("total") || p.message.contains('`'),
        "the message shows the name or suggests backticks: {}",
        p.message
    );
    assert_eq!(syntax_error("\"abc").text, "\"abc");
    let p = syntax_error("? > 3");
    assert!(
        p.message.contains("`?`") && p.message.contains("after `in`"),
        "the message says where `?` belongs: {}",
        p.message
    );
    let p = syntax_error("d instance of datetime");
    assert!(
        p.message.contains("day-time-duration"),
        "the message lists the type names: {}",
        p.message
    );
}

/// `problems()` reports what is wrong beyond syntax, once per cause.
#[test]
fn load_time_problems() {
    let rows: &[(&str, &str)] = &[
        // The crate doc of `Expression::problems`: unknown functions, wrong argument counts or
        // names, literal arguments a function refuses, functions that are not deterministic.
        ("frobnicate(1)", "frobnicate"),
        ("substring(\"a\")", "substring"),
        ("upper case(\"a\", \"b\")", "upper case"),
        ("not()", "not"),
        // The message names the unknown parameter or the expected ones.
        ("substring(string: \"a\", begin: 1)", "begin|start position"),
        // The non-deterministic functions are refused as such, not as a name with a space.
        ("uuid()", "`uuid()` is not deterministic"),
        ("random number()", "`random number()` is not deterministic"),
        ("random  number()", "`random number()` is not deterministic"),
        (
            "1 + random number() * 10",
            "`random number()` is not deterministic",
        ),
        ("date(\"2026-02-30\")", "2026-02-30"),
        ("duration(\"P1X\")", "P1X"),
        ("time(\"25:00:00\")", "25:00:00"),
        ("@\"2026-02-30\"", "2026-02-30"),
        // A zone id the time-zone database does not know is refused when the model loads.
        (
            "date and time(\"2026-11-23T10:00:00@Mars/Olympus\")",
            "Mars/Olympus",
        ),
        ("@\"2026-11-23T10:00:00@Mars/Olympus\"", "Mars/Olympus"),
        ("time(\"10:00:00@Mars/Olympus\")", "Mars/Olympus"),
        // feel.md §6.4: invalid regexes in literal arguments.
        ("matches(\"a\", \"(\")", "("),
        // The `regex` crate matches in linear time: no look-around, no back-references
        // (Camunda's Java regex has both).
        ("matches(\"ab\", \"a(?=b)\")", "look-around"),
        ("replace(\"ab\", \"(?<!a)b\", \"c\")", "look-around"),
        ("matches(\"aa\", \"(a)\\1\")", "backreferences"),
    ];
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|(text, word)| {
            let found = match parse(text) {
                Ok(_) => problems(text),
                Err(p) => vec![format!("<syntax error: {} at {}>", p.message, p.span.start)],
            };
            (found.len() != 1 || !word.split('|').any(|w| found[0].contains(w))).then(|| {
                format!(
                    "  {text}\n      expected one problem naming {word:?}\n      actual   {found:?}"
                )
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
    // Every problem is found, each at its own place.
    let text = "count([frobnicate(1), uuid()]) + 1";
    let found = parse(text).expect("parses").problems();
    let starts: Vec<usize> = found.iter().map(|p| p.span.start).collect();
    assert_eq!(starts, [7, 22], "{found:?}");
    let p = &parse("x + frobnicate(1)").expect("parses").problems()[0];
    assert_eq!(
        (p.span.start, p.text.as_str()),
        (4, "x + frobnicate(1)"),
        "{p:?}"
    );
}

/// Valid expressions, including non-literal arguments and functions defined in the
/// expression, have no problems.
#[test]
fn no_false_problems() {
    for text in [
        "substring(\"foobar\", 3)",
        "substring(string: \"foobar\", start position: 3)",
        "date(\"2026-02-28\")",
        "date(x)",
        "duration(d)",
        "@\"2026-11-23T10:00:00@UTC\"",
        "@\"2026-11-23T10:00:00+02:00\"",
        "@\"P1DT2H\"",
        "is defined(x)",
        "get or else(x, 1)",
        "now() + duration(\"PT1H\")",
        "today()",
        "string join([\"a\"], \",\")",
        "min(1, 2, 3)",
        "sum([1, 2])",
        "{f: function(x) x * 2, r: f(3)}.r",
        "sort([3,1], function(x, y) x < y)",
        "cycle(3, duration(\"PT1H\"))",
        "matches(x, \"^a.c$\")",
        "for f in [1] return f",
        "not(true)",
        "x in not(1, 2)",
        "x in contains(?, \"a\")",
        "for i in 1..3 return partial",
        "x",
    ] {
        assert_eq!(problems(text), Vec::<String>::new(), "`{text}`");
    }
}

/// `variables()` lists the free variables, sorted and without duplicates: names and path
/// roots, without iteration, lambda-parameter, `item` and context-entry names.
#[test]
fn free_variables() {
    let rows: &[(&str, &[&str])] = &[
        // The brief's examples.
        ("for x in items return x + y", &["items", "y"]),
        ("{a: 1, b: a + c}", &["c"]),
        ("order.total > 1", &["order"]),
        // More binders and scopes.
        ("items[item > n]", &["items", "n"]),
        ("some x in xs satisfies x > limit", &["limit", "xs"]),
        ("every x in xs, y in ys satisfies x < y", &["xs", "ys"]),
        ("function(a) a + b", &["b"]),
        ("{f: function(x) x + k, r: f(1)}.r", &["k"]),
        ("for i in 1..n return i", &["n"]),
        ("for x in [1], y in x..m return y", &["m"]),
        ("count(for x in xs return x) + x", &["x", "xs"]),
        ("{a: 1}.a + a", &["a"]),
        ("if p then q else r", &["p", "q", "r"]),
        ("b + a + b", &["a", "b"]),
        ("x.y.z", &["x"]),
        ("z.a[item > 1].b", &["z"]),
        ("`order total` > 100", &["order total"]),
        ("is defined(y)", &["y"]),
        ("get or else(v, 0)", &["v"]),
        ("string join(names, \", \")", &["names"]),
        ("sort(list: l, precedes: function(a, b) a < b)", &["l"]),
        ("date(d) + duration(\"P1D\")", &["d"]),
        ("now()", &[]),
        ("\"literal\"", &[]),
        ("[1, 2, 3][item > 1]", &[]),
        // docs.camunda.io FEEL control flow: `partial` is bound inside a `for` body only.
        ("for i in 1..3 return partial[-1]", &[]),
        ("for x in xs return count(partial) + y", &["xs", "y"]),
        ("for x in partial return x", &["partial"]),
        ("some x in xs satisfies partial", &["partial", "xs"]),
        ("partial", &["partial"]),
        // `?` is the tested value, not a variable; a built-in's name outside a call is one.
        ("x in contains(?, y)", &["x", "y"]),
        ("x in not(a, < b)", &["a", "b", "x"]),
        ("count = null", &["count"]),
    ];
    let wrong: Vec<String> = rows
        .iter()
        .filter_map(|(text, expected)| {
            let actual = variables(text);
            (actual != *expected).then(|| {
                format!("  {text}\n      expected {expected:?}\n      actual   {actual:?}")
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
