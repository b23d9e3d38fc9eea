//! Null handling in Camunda's dialect: a missing variable or entry is null, not an error;
//! comparing null with a non-null value by `=` is false (`!=` true); ordering with null is null;
//! `is defined` is false for missing and null values alike (Camunda 8.4+); `get or else` supplies a default.
//! Sources: design note feel.md §3.2 (Camunda column) and §4; docs.camunda.io *Expressions*
//! (null checks), FEEL *boolean expressions* (null check), *error handling*, *boolean functions*.

use super::{camunda_vars, check, check_vars, ctx, n};

/// `=` and `!=` against null: true only when both sides are null (or missing).
#[test]
fn null_equality() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §3.2: `missing = 3` → false, `nothing != 3` → true ("comparing null to
            // a value different from null results in false").
            ("missing = 3", "false"),
            ("nothing != 3", "true"),
            ("nothing = 3", "false"),
            ("missing != 3", "true"),
            ("3 = missing", "false"),
            // feel.md §3.2: `x != null` (x = "a").
            ("x != null", "true"),
            ("x = null", "false"),
            // feel.md §4 / docs.camunda.io Expressions: `x = null` is true for null or missing.
            ("missing = null", "true"),
            ("nothing = null", "true"),
            ("missing = nothing", "true"),
            ("missing != null", "false"),
            ("missing.y = null", "true"),
            ("missing.y.z = null", "true"),
            ("missing = \"a\"", "false"),
            ("missing = [1]", "false"),
        ],
    );
    check(&[
        // docs.camunda.io FEEL boolean expressions, Null check.
        ("null = null", "true"),
        ("\"foo\" = null", "false"),
        ("{x: null}.x = null", "true"),
        ("{}.y = null", "true"),
        ("null != null", "false"),
        ("null != 1", "true"),
    ]);
}

/// Ordering, arithmetic and paths with null give null.
#[test]
fn null_propagation() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §4: `<`, `>` with null give null.
            ("missing < 3", "null"),
            ("nothing > 3", "null"),
            ("3 >= missing", "null"),
            ("missing <= missing", "null"),
            ("missing between 1 and 5", "null"),
            // docs.camunda.io FEEL error handling: "Expressions and operators can deal with
            // null values. In many cases, they result also in null."
            ("missing + 1", "null"),
            ("1 - nothing", "null"),
            ("-missing", "null"),
            ("missing * 2", "null"),
            ("missing + \"a\"", "null"),
            ("missing.y", "null"),
            ("missing[1]", "null"),
            ("missing.y > 10", "null"),
            ("nothing.y", "null"),
            ("x.y", "null"),
            ("not(nothing)", "null"),
            ("missing(1)", "null"),
        ],
    );
    check(&[
        // docs.camunda.io FEEL error handling, Handle null values.
        ("[{a: 1}, {b: 2}].a", "[1, null]"),
        ("[{a: 1}, {b: 2}][a < 10]", "[{a:1}]"),
        // docs.camunda.io FEEL boolean functions: `not(null)` → null.
        ("not(null)", "null"),
    ]);
    // docs.camunda.io FEEL error handling: `a.b > 10` → null when `a` has no `b`.
    check_vars(&[("a", ctx(&[("c", n(1))]))], &[("a.b > 10", "null")]);
}

/// Null in `and`, `or`, `if`, quantifiers and filters follows three-valued logic.
#[test]
fn null_in_logic() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §4: `and`/`or` are three-valued; `if` takes the else branch on null.
            ("missing and false", "false"),
            ("missing and true", "null"),
            ("missing or true", "true"),
            ("missing or false", "null"),
            ("if missing then 1 else 2", "2"),
            ("if nothing then 1 else 2", "2"),
            ("if missing = null then 1 else 2", "1"),
            // docs.camunda.io FEEL variables tip: guard with a null check.
            ("nothing != null and nothing > 10", "false"),
            ("missing = null or missing > 10", "true"),
            ("some i in [1, null] satisfies i = null", "true"),
        ],
    );
    check(&[
        // Filters compare missing entries the same way (camunda/feel-scala#582, fixed for
        // Camunda 8.3: non-existing entries compare gracefully in filters).
        ("[{x:5},{y:2}][x > 3]", "[{x:5}]"),
        ("[{x:5},{y:2}][x = null]", "[{y:2}]"),
        ("[{x:5},{y:2}][x != null and x > 3]", "[{x:5}]"),
    ]);
}

/// `is defined(v)`: false for a missing variable or entry and for null, true for any other value.
#[test]
fn is_defined() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §3.2: `is defined(y)` → false (y not set).
            ("is defined(y)", "false"),
            ("is defined(missing)", "false"),
            // docs.camunda.io Boolean functions (8.4+): "Breaking change … the function
            // returns false if the value is null" (8.2 and earlier said true).
            ("is defined(nothing)", "false"),
            // docs.camunda.io FEEL boolean functions.
            ("is defined(1)", "true"),
            ("is defined(x)", "true"),
            ("is defined(missing.y)", "false"),
            ("is defined(x.y)", "false"),
            ("is defined({a: 1}.a)", "true"),
            ("is defined({a: 1}.b)", "false"),
        ],
    );
}

/// `get or else(value, default)`: the value unless it is null.
#[test]
fn get_or_else() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §3.2.
            ("get or else(missing, \"d\")", "\"d\""),
            ("get or else(nothing, 0)", "0"),
            ("get or else(n, 0)", "3"),
            ("get or else(missing.y, \"prio-99\")", "\"prio-99\""),
        ],
    );
    check(&[
        // docs.camunda.io FEEL boolean functions, get or else.
        ("get or else(\"this\", \"default\")", "\"this\""),
        ("get or else(null, \"default\")", "\"default\""),
        ("get or else(null, null)", "null"),
        ("get or else(false, true)", "false"),
        ("get or else(value: null, default: \"d\")", "\"d\""),
    ]);
}

/// Null among list elements and function arguments.
#[test]
fn null_in_lists_and_functions() {
    check_vars(
        &camunda_vars(),
        &[
            // feel.md §4: comparing null with a value is false, so `in` a list is false.
            ("missing in [1, 2]", "false"),
            ("nothing in [1, null]", "true"),
            // DMN §10.3.4.4: list contains takes any element including null.
            ("list contains([1, null], null)", "true"),
            ("list contains([1, 2], missing)", "false"),
            ("count([null, null])", "2"),
            // docs.camunda.io FEEL list functions, string join: null items are ignored.
            ("string join([\"a\", missing, \"c\"], \"-\")", "\"a-c\""),
            // docs.camunda.io FEEL error handling: a function that cannot be invoked with the
            // given arguments gives null.
            ("upper case(missing)", "null"),
            ("string length(nothing)", "null"),
            ("substring(missing, 1)", "null"),
            ("count(missing)", "null"),
            ("date(missing)", "null"),
        ],
    );
}
