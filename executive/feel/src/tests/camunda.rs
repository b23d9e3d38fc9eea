//! Camunda 8's dialect: the design note's §3.2 table (the Camunda column is the expected value),
//! the shapes Zeebe models write (mappings, conditions, correlation keys), string literals
//! (escapes, raw line breaks), `assert`, and Zeebe's `cycle()`. Sources: feel.md §3.2 and §4;
//! docs.camunda.io *Expressions* (Zeebe), FEEL *data types*, *boolean functions*.

use super::{camunda_vars, check, check_vars, ctx, list, n, run, s};
use crate::{BUDGET, Stop};

/// Every row of feel.md §3.2 with the Camunda / feel-scala column as the expected result.
#[test]
fn design_note_table() {
    let mut vars = camunda_vars();
    vars.push(("order total", n(150)));
    check_vars(
        &vars,
        &[
            ("x = \"a\"", "true"),
            ("a and b", "false"),
            ("n / 2 = 1.5", "true"),
            ("n / 2", "1.5"),
            ("if n > 2 then \"big\" else \"small\"", "\"big\""),
            ("list contains([1,2,3], n)", "true"),
            ("some x in [1,2,3] satisfies x > 2", "true"),
            ("for i in 1..3 return i * 2", "[2, 4, 6]"),
            ("count(items) > 0", "true"),
            ("not(flag)", "true"),
            ("x != null", "true"),
            ("is defined(y)", "false"),
            ("\"site-\" + string(n)", "\"site-3\""),
            ("\"site-\" + n", "null"),
            (
                "date and time(\"2026-11-23T10:00:00Z\") + duration(\"PT6H\")",
                "2026-11-23T16:00:00Z",
            ),
            (
                "@\"2026-11-23T10:00:00Z\" + duration(\"PT6H\")",
                "2026-11-23T16:00:00Z",
            ),
            ("{a: 1, b: 2}.b", "2"),
            ("items[1]", "1"),
            ("items[-1]", "3"),
            ("items[0]", "null"),
            ("sum([1,2,3])", "6"),
            ("`order total` > 100", "true"),
            ("missing = 3", "false"),
            ("nothing != 3", "true"),
            ("0.1 + 0.2 = 0.3", "true"),
            ("get or else(missing, \"d\")", "\"d\""),
            ("cycle(3, duration(\"PT1H\"))", "\"R3/PT1H\""),
            ("if missing then 1 else 2", "2"),
            ("\"line one\nline two\"", "\"line one\\nline two\""),
        ],
    );
}

/// Expressions of the shapes Zeebe models use in mappings, conditions and correlation keys.
#[test]
fn zeebe_expressions() {
    let order = ctx(&[
        ("id", s("order-123")),
        ("amount", n(250)),
        ("items", list([s("item-1"), s("item-2"), s("item-3")])),
        (
            "customer",
            ctx(&[("name", s("Paul")), ("email", s("paul@example.com"))]),
        ),
    ]);
    let vars = [
        ("order", order),
        ("orderId", n(123)),
        ("owner", s("Paul")),
        ("totalPrice", super::dec("21.2")),
        ("orderCount", n(7)),
        ("status", s("DONE")),
    ];
    check_vars(
        &vars,
        &[
            // docs.camunda.io Expressions (Zeebe): access variables, boolean expressions.
            ("owner", "\"Paul\""),
            ("totalPrice", "21.2"),
            ("order.id", "\"order-123\""),
            ("order.customer.name", "\"Paul\""),
            ("order.amount > 100", "true"),
            ("owner = \"Paul\"", "true"),
            ("owner != \"Paul\"", "false"),
            ("totalPrice < 25", "true"),
            ("totalPrice between 10 and 25", "true"),
            ("orderCount >= 5 and orderCount < 15", "true"),
            ("orderCount > 15 or totalPrice > 50", "false"),
            ("\"order-\" + string(orderId)", "\"order-123\""),
            ("order = null", "false"),
            ("order.missing = null", "true"),
            ("is defined(order.id)", "true"),
            ("is defined(order.missing)", "false"),
            // Mappings that build values (feel.md §3.1: a bare context literal is common).
            (
                "{id: order.id, count: count(order.items) + 1}",
                "{id:\"order-123\", count:4}",
            ),
            ("order.items[1]", "\"item-1\""),
            ("order.items[-1]", "\"item-3\""),
            ("count(order.items)", "3"),
            (
                "for item in order.items return upper case(item)",
                "[\"ITEM-1\", \"ITEM-2\", \"ITEM-3\"]",
            ),
            // Functions the shared corpus calls (feel.md §1).
            ("contains(order.customer.email, \"@\")", "true"),
            ("substring before(order.customer.email, \"@\")", "\"paul\""),
            (
                "substring after(order.customer.email, \"@\")",
                "\"example.com\"",
            ),
            ("upper case(status)", "\"DONE\""),
            (
                "string join(order.items, \",\")",
                "\"item-1,item-2,item-3\"",
            ),
            ("not(is empty(order.items))", "true"),
            ("day of week(today())", "\"Monday\""),
            ("string(today())", "\"2026-11-23\""),
        ],
    );
}

/// String literals: escapes (docs.camunda.io FEEL data types, String) and raw line breaks
/// (feel.md §4: "String literals may span lines").
#[test]
fn string_literals() {
    check(&[
        // docs.camunda.io FEEL data types: `\'`, `\"`, `\\`, `\n`, `\r`, `\t`, `\u269D`.
        ("\"\\\"\"", "\"\\\"\""),
        ("string length(\"\\\"\")", "1"),
        ("\"\\\\\"", "\"\\\\\""),
        ("string length(\"\\\\\")", "1"),
        ("\"a\\nb\"", "\"a\\nb\""),
        ("string length(\"a\\nb\")", "3"),
        ("\"\\t\"", "\"\\t\""),
        ("\"\\r\"", "\"\\r\""),
        ("\"\\'\"", "\"'\""),
        ("\"\\u00e9\"", "\"é\""),
        ("\"\\u00e9\" = \"é\"", "true"),
        ("\"\\u269D\"", "\"⚝\""),
        ("\"it's\"", "\"it's\""),
        ("\"\"", "\"\""),
        ("\"🐎\"", "\"🐎\""),
        // A raw line break inside a literal is part of the string.
        ("\"line 1\nline 2\"", "\"line 1\\nline 2\""),
        ("string length(\"a\nb\")", "3"),
        ("\"a\r\nb\"", "\"a\\r\\nb\""),
        (
            "\"You are an agent.\n\nAnswer briefly.\" + \"\n\"",
            "\"You are an agent.\\n\\nAnswer briefly.\\n\"",
        ),
        // Text that looks like syntax inside a string is just text.
        (
            "\"a, b] } // not a comment\"",
            "\"a, b] } // not a comment\"",
        ),
    ]);
}

/// `assert(value, condition[, cause])` returns the value, or fails the whole evaluation
/// (docs.camunda.io FEEL boolean functions and error handling, Camunda extension).
#[test]
fn assert_fails_the_evaluation() {
    let vars = camunda_vars();
    check_vars(
        &vars,
        &[
            ("assert(x, x != null)", "\"a\""),
            ("assert(n, n >= 0)", "3"),
            ("assert(n, n >= 0, \"'n' should be positive\")", "3"),
        ],
    );
    for text in [
        "assert(missing, missing != null)",
        "assert(nothing, nothing != null)",
        "assert(-1, -1 >= 0)",
    ] {
        let result = run(text, &vars, BUDGET).map(|e| e.value.to_string());
        assert!(
            matches!(result, Err(Stop::Failed(_))),
            "`{text}` gave {result:?}"
        );
    }
    match run(
        "assert(-1, -1 >= 0, \"'b' should be positive\")",
        &[],
        BUDGET,
    ) {
        Err(Stop::Failed(message)) => {
            assert!(message.contains("'b' should be positive"), "{message}");
        }
        other => panic!("expected a failure, got {other:?}"),
    }
}

/// Zeebe's `cycle(repetitions, interval)`: an ISO 8601 repeating interval as a string
/// (docs.camunda.io Expressions, Temporal expressions).
#[test]
fn cycle() {
    check(&[
        ("cycle(3, duration(\"PT1H\"))", "\"R3/PT1H\""),
        ("cycle(duration(\"P7D\"))", "\"R/P7D\""),
        // "If the first argument is null or not passed in, the interval is unbounded."
        ("cycle(null, duration(\"P7D\"))", "\"R/P7D\""),
        ("cycle(1, @\"PT30M\")", "\"R1/PT30M\""),
    ]);
    check_vars(
        &[("retries", n(5))],
        &[("cycle(retries, duration(\"PT10S\"))", "\"R5/PT10S\"")],
    );
}

/// A variable named like a built-in (`count`, `sum`: common in process data) does not hide the
/// function in call position, and the function name does not hide the variable elsewhere
/// (feel-scala looks functions and variables up separately).
#[test]
fn variables_named_like_functions() {
    check_vars(
        &[
            ("count", n(5)),
            ("sum", n(2)),
            ("items", list([n(1), n(2)])),
        ],
        &[
            ("count(items)", "2"),
            ("count + 1", "6"),
            ("sum(items) + sum", "5"),
            ("{f: function(x) x + 1, r: f(count)}.r", "6"),
        ],
    );
    // Without such variables the names are missing variables, null (docs.camunda.io FEEL
    // variables: "If no variable exists with the given name, the expression returns null"),
    // not the built-in functions; a call still finds the function.
    check_vars(
        &[("items", list([n(1), n(2)]))],
        &[
            ("count = null", "true"),
            ("is defined(count)", "false"),
            ("if sum = null then 0 else sum", "0"),
            ("date", "null"),
            ("string = null", "true"),
            ("max instance of function", "false"),
            ("get or else(count, 9)", "9"),
            ("count(items) + sum(items)", "5"),
            ("string join([\"a\"], \"\")", "\"a\""),
        ],
    );
    let e = run("count", &[], BUDGET).expect("evaluates");
    assert_eq!(e.note.as_deref(), Some("no variable `count`"));
    // The variable is free, so the engine passes it in.
    assert_eq!(super::variables("count = null"), ["count"]);
}
