//! The FEEL language itself: literals, arithmetic, strings, comparison, logic, `between`, `in`,
//! `instance of`, lists, filters, projections, contexts, `if`, `for`, `some`/`every`, function
//! definitions and invocations. Sources: the DMN specification (clause 10, "FEEL"; section and
//! grammar-rule numbers as in DMN 1.5, the same as DMN 1.3 for those cited) and the FEEL language
//! guide of docs.camunda.io (`components/modeler/feel/language-guide/…`).

use super::{camunda_vars, check, check_prefix, check_vars, ctx, dec, feel, feel_vars, list, n, s};

/// Literals of every kind print as FEEL writes them; numbers are normalised.
#[test]
fn literals() {
    check(&[
        // docs.camunda.io FEEL data types: null, numbers (`.4`, `-5`), strings, booleans.
        ("null", "null"),
        ("1", "1"),
        ("2.3", "2.3"),
        (".4", "0.4"),
        ("-5", "-5"),
        ("0.5", "0.5"),
        ("1.50", "1.5"),
        ("007", "7"),
        ("\"valid\"", "\"valid\""),
        ("true", "true"),
        ("false", "false"),
        // docs.camunda.io FEEL data types, List: `[]`, `[1,2,3]`, nested lists.
        ("[]", "[]"),
        ("[1,2,3]", "[1, 2, 3]"),
        ("[\"a\",\"b\"]", "[\"a\", \"b\"]"),
        (
            "[[\"list\"], \"of\", [[\"lists\"]]]",
            "[[\"list\"], \"of\", [[\"lists\"]]]",
        ),
        ("[1, \"a\", null, true]", "[1, \"a\", null, true]"),
        // docs.camunda.io FEEL data types, Context: `{}`, names or strings as keys.
        ("{}", "{}"),
        ("{a:1}", "{a:1}"),
        ("{b: 2, c: \"valid\"}", "{b:2, c:\"valid\"}"),
        ("{nested: {d: 3}}", "{nested:{d:3}}"),
        ("{\"a\": 1}", "{a:1}"),
        // Entries keep the order they were written in (feel.md §6.3: ordered contexts).
        ("{b: 1, a: 2}", "{b:1, a:2}"),
        // DMN §10.3.2.7 Ranges: a range is a value.
        ("[1..10]", "[1..10]"),
        ("(1..10]", "(1..10]"),
    ]);
}

/// Arithmetic is exact decimal arithmetic (Scala BigDecimal in feel-scala; 28 digits here).
#[test]
fn arithmetic() {
    check(&[
        // docs.camunda.io FEEL numeric expressions.
        ("2 + 3", "5"),
        ("5 - 3", "2"),
        ("5 * 3", "15"),
        ("6 / 2", "3"),
        ("2 ** 3", "8"),
        // feel.md §3.2 and §6.1 (measured): decimals, not binary floats.
        ("3 / 2", "1.5"),
        ("0.1 + 0.2", "0.3"),
        ("0.1 + 0.2 = 0.3", "true"),
        ("1.1 * 3", "3.3"),
        ("12345678901234567890 + 1", "12345678901234567891"),
        ("1 - 1.0", "0"),
        // DMN §10.3.1.2 grammar (and its precedence table): usual precedence, left
        // associative, unary minus.
        ("2 + 3 * 4", "14"),
        ("(2 + 3) * 4", "20"),
        ("2 * 3 + 1", "7"),
        ("10 - 2 - 3", "5"),
        ("12 / 2 / 3", "2"),
        ("-(1 + 2)", "-3"),
        ("1 - -1", "2"),
        ("5 * -1", "-5"),
        ("2 ** 3 * 2", "16"),
        // docs.camunda.io FEEL error handling: "An operation is not defined for the given
        // values" → null.
        ("1 / 0", "null"),
        ("0 / 0", "null"),
        // Crate doc (lib.rs): a result that does not fit 28 significant digits is null.
        ("10 ** 28", "10000000000000000000000000000"),
        ("10 ** 29", "null"),
    ]);
    // feel.md §3.2: `n / 2 = 1.5` with n = 3.
    check_vars(
        &camunda_vars(),
        &[
            ("n / 2", "1.5"),
            ("n / 2 = 1.5", "true"),
            ("n * n - 1", "8"),
        ],
    );
    // feel.md §3.2 / §6.1: `10 / 3` is 3.333… (28 digits here, 34 in feel-scala).
    check_prefix(&[("10 / 3", "3.333333333333"), ("1 / 3", "0.333333333333")]);
}

/// `+` concatenates two strings; with any other operand it has no value.
#[test]
fn string_concatenation() {
    check(&[
        // docs.camunda.io FEEL string expressions: `"foo" + "bar"`.
        ("\"foo\" + \"bar\"", "\"foobar\""),
        ("\"a\" + \"b\"", "\"ab\""),
        ("\"\" + \"\"", "\"\""),
        // docs.camunda.io: "The concatenation is only available for string values"; feel.md §4.
        ("\"order-\" + string(123)", "\"order-123\""),
        ("\"site-\" + 3", "null"),
        ("3 + \"a\"", "null"),
        ("\"a\" + true", "null"),
        ("\"a\" * 2", "null"),
        ("\"a\" - \"a\"", "null"),
    ]);
    // feel.md §3.2: `"site-" + string(n)` → "site-3", `"site-" + n` → null.
    check_vars(
        &camunda_vars(),
        &[
            ("\"site-\" + string(n)", "\"site-3\""),
            ("\"site-\" + n", "null"),
            ("x + \"b\"", "\"ab\""),
        ],
    );
}

/// Comparison operators; values of different kinds do not compare (null).
#[test]
fn comparison() {
    check(&[
        // docs.camunda.io FEEL boolean expressions, Comparison.
        ("5 = 5", "true"),
        ("5 != 5", "false"),
        ("1 < 2", "true"),
        ("2 <= 2", "true"),
        ("3 > 2", "true"),
        ("2 >= 3", "false"),
        ("1.0 = 1", "true"),
        ("\"abc\" = \"abc\"", "true"),
        ("\"a\" < \"b\"", "true"),
        ("true = true", "true"),
        ("true != false", "true"),
        // DMN §10.3.2.2 (equality): lists and contexts compare element by element.
        ("[1,2] = [1,2]", "true"),
        ("[1,2] = [2,1]", "false"),
        ("[1,2] = [1,2,3]", "false"),
        ("{a: 1, b: 2} = {b: 2, a: 1}", "true"),
        ("{a: 1} = {a: 2}", "false"),
        // docs.camunda.io boolean expressions: "Both values must be of the same type.
        // Otherwise, the result is null."
        ("1 = \"1\"", "null"),
        ("1 < \"a\"", "null"),
        // DMN §10.3.2 (comparison semantics): `<` is defined for numbers, strings and temporal values only.
        ("true < false", "null"),
        ("[1] < [2]", "null"),
    ]);
}

/// `and` and `or` follow three-valued logic; non-booleans count as null.
#[test]
fn ternary_logic() {
    check(&[
        // docs.camunda.io FEEL boolean expressions, Conjunction/and.
        ("true and true", "true"),
        ("true and false", "false"),
        ("true and null", "null"),
        ("true and \"otherwise\"", "null"),
        ("false and null", "false"),
        ("false and \"otherwise\"", "false"),
        ("null and false", "false"),
        ("null and null", "null"),
        // docs.camunda.io FEEL boolean expressions, Disjunction/or.
        ("true or false", "true"),
        ("false or false", "false"),
        ("true or null", "true"),
        ("true or \"otherwise\"", "true"),
        ("false or null", "null"),
        ("false or \"otherwise\"", "null"),
        ("null or true", "true"),
        // DMN grammar rules 49, 50: `and` binds tighter than `or`.
        ("true or false and false", "true"),
        ("(true or false) and false", "false"),
        ("1 < 2 and 2 < 3", "true"),
    ]);
    // feel.md §3.2: `a and b` with a = true, b = false.
    check_vars(&camunda_vars(), &[("a and b", "false"), ("a or b", "true")]);
}

/// `between` is inclusive at both ends.
#[test]
fn between() {
    check(&[
        // docs.camunda.io FEEL boolean expressions: `5 between 3 and 7`.
        ("5 between 3 and 7", "true"),
        ("3 between 3 and 7", "true"),
        ("7 between 3 and 7", "true"),
        ("8 between 3 and 7", "false"),
        (
            "date(\"2020-04-06\") between date(\"2020-04-05\") and date(\"2020-04-09\")",
            "true",
        ),
        ("\"b\" between \"a\" and \"c\"", "true"),
    ]);
    check_vars(&camunda_vars(), &[("n between 1 and 5", "true")]);
}

/// `in` tests a value against a list, a range, a unary comparison, or several of them.
#[test]
fn in_unary_tests() {
    check(&[
        // docs.camunda.io FEEL boolean expressions, Unary-tests/in.
        ("5 in (3..7)", "true"),
        (
            "date(\"2021-06-04\") in [date(\"2021-05-01\")..date(\"2021-05-31\")]",
            "false",
        ),
        ("5 in (3,5,7)", "true"),
        ("5 in [2,4,6,8]", "false"),
        // The brief's examples (FEEL 1.3 grammar rules 7, 14, 15).
        ("5 in (<= 5)", "true"),
        ("5 in (< 5)", "false"),
        ("5 in [1,2,5]", "true"),
        ("\"a\" in [\"a\",\"b\"]", "true"),
        ("\"c\" in [\"a\",\"b\"]", "false"),
        // docs.camunda.io FEEL unary tests, Interval: open and closed ends.
        ("2 in (2..5)", "false"),
        ("2 in [2..5]", "true"),
        ("5 in (2..5]", "true"),
        ("5 in [2..5)", "false"),
        ("5 in ]2..5[", "false"),
        // docs.camunda.io FEEL unary tests, Disjunction: `< 10, > 50`.
        ("60 in (< 10, > 50)", "true"),
        ("20 in (< 10, > 50)", "false"),
        ("\"b\" in (\"a\", \"b\")", "true"),
        // DMN §10.3.2.7: a range end may be any expression.
        ("5 in [1 + 1 .. 2 * 3]", "true"),
        // docs.camunda.io FEEL unary-tests, Negation/not: "Negates a given unary-test
        // expression … It returns true if the given unary-test evaluates to false."
        ("\"valid\" in not(\"valid\")", "false"),
        ("\"other\" in not(\"valid\")", "true"),
        ("5 in not(4)", "true"),
        ("5 in not(5)", "false"),
        ("2 in not(2, 3)", "false"),
        ("3 in not(2, 3)", "false"),
        ("4 in not(2, 3)", "true"),
        ("5 in not(< 3, > 10)", "true"),
        ("11 in not(< 3, > 10)", "false"),
        ("5 in not([1..5])", "false"),
        ("6 in not([1..5])", "true"),
        ("5 in not(4) and true", "true"),
        // Negating a test that cannot tell is null, as the test itself is.
        ("\"a\" in not(< 1)", "null"),
        // docs.camunda.io FEEL unary-tests, Expressions: "The input value can be accessed in
        // the expression by using the symbol `?`".
        ("\"good day\" in contains(?, \"good\")", "true"),
        ("\"bad day\" in contains(?, \"good\")", "false"),
        (
            "\"ops@camunda.com\" in ends with(?, \"@camunda.com\")",
            "true",
        ),
        (
            "\"ops@example.com\" in ends with(?, \"@camunda.com\")",
            "false",
        ),
        ("5 in (? > 3)", "true"),
        ("2 in (? > 3)", "false"),
        ("12 in (< 5, ? > 10)", "true"),
        ("3 in (< 5, ? > 10)", "true"),
        ("7 in (< 5, ? > 10)", "false"),
        ("7 in (odd(?), 4)", "true"),
        ("[1, 2] in (count(?) = 2)", "true"),
        ("5 in not(? > 3)", "false"),
        ("1 in not(? > 3)", "true"),
        ("4 in < ? + 1", "true"),
        ("5 in (? in [1..10])", "true"),
        // A `?` in a nested `in`'s tests is that `in`'s value (3), not the outer one.
        ("true in (3 in (? = 3))", "true"),
        // A test that uses `?` must give a boolean; a number is no answer.
        ("5 in (? + 1)", "null"),
        ("5 in (? + 1, 5)", "true"),
    ]);
    check_vars(
        &camunda_vars(),
        &[
            ("n in [1..5]", "true"),
            ("n in (1..3)", "false"),
            ("n in [1..3]", "true"),
            ("n in (< 5)", "true"),
            ("n in items", "true"),
            ("x in [\"a\", \"b\"]", "true"),
            ("n in not(1, 2)", "true"),
            ("x in not(\"a\")", "false"),
            ("n in (? = n)", "true"),
            ("items in (list contains(?, 2))", "true"),
        ],
    );
}

/// `instance of` checks a value's type; `Any` matches every non-null value.
#[test]
fn instance_of() {
    check(&[
        // docs.camunda.io FEEL boolean expressions, Instance of.
        ("1 instance of number", "true"),
        ("1 instance of string", "false"),
        ("1 instance of Any", "true"),
        ("null instance of Any", "false"),
        (
            "duration(\"P3M\") instance of years and months duration",
            "true",
        ),
        (
            "duration(\"PT4H\") instance of days and time duration",
            "true",
        ),
        (
            "duration(\"PT4H\") instance of years and months duration",
            "false",
        ),
        // The same type names for the other kinds.
        ("\"a\" instance of string", "true"),
        ("true instance of boolean", "true"),
        ("[1] instance of list", "true"),
        ("{a: 1} instance of context", "true"),
        ("[1] instance of context", "false"),
        ("date(\"2026-11-23\") instance of date", "true"),
        ("date(\"2026-11-23\") instance of date and time", "false"),
        ("time(\"10:00:00\") instance of time", "true"),
        ("now() instance of date and time", "true"),
        ("(function(x) x) instance of function", "true"),
        // docs.camunda.io FEEL boolean expressions, Instance of: the type names `date time`,
        // `day-time-duration`, `year-month-duration`.
        ("now() instance of date time", "true"),
        (
            "date and time(\"2026-11-23T10:00:00Z\") instance of date time",
            "true",
        ),
        ("date(\"2026-11-23\") instance of date time", "false"),
        ("duration(\"PT4H\") instance of day-time-duration", "true"),
        ("duration(\"P3M\") instance of day-time-duration", "false"),
        ("duration(\"P3M\") instance of year-month-duration", "true"),
        (
            "duration(\"PT4H\") instance of year-month-duration",
            "false",
        ),
        ("@\"P1D\" instance of day-time-duration and true", "true"),
        ("date(\"2026-11-23\") instance of date", "true"),
    ]);
    check_vars(
        &camunda_vars(),
        &[
            ("x instance of string", "true"),
            ("n instance of number", "true"),
            ("items instance of list", "true"),
            ("missing instance of Any", "false"),
            ("nothing instance of Any", "false"),
        ],
    );
}

/// Lists index from 1, negative indexes count from the end, anything else is null.
#[test]
fn list_index() {
    check(&[
        // docs.camunda.io FEEL list expressions, Get element.
        ("[1,2,3,4][1]", "1"),
        ("[1,2,3,4][2]", "2"),
        ("[1,2,3,4][4]", "4"),
        ("[1,2,3,4][5]", "null"),
        ("[1,2,3,4][0]", "null"),
        ("[1,2,3,4][-1]", "4"),
        ("[1,2,3,4][-2]", "3"),
        ("[1,2,3,4][-5]", "null"),
        // docs.camunda.io Expressions (Zeebe), List expressions.
        ("[\"a\",\"b\",\"c\"][1]", "\"a\""),
        ("[\"a\",\"b\",\"c\"][2]", "\"b\""),
        ("[\"a\",\"b\",\"c\"][-1]", "\"c\""),
        ("[[1,2],[3,4]][2][1]", "3"),
    ]);
    // feel.md §3.2: `items[1]`, `items[-1]`, `items[0]`.
    check_vars(
        &camunda_vars(),
        &[
            ("items[1]", "1"),
            ("items[-1]", "3"),
            ("items[0]", "null"),
            ("items[n]", "3"),
            ("items[n + 1]", "null"),
        ],
    );
}

/// A boolean in brackets filters a list: `item` is the element, or its entries by name.
#[test]
fn list_filter() {
    check(&[
        // docs.camunda.io FEEL list expressions, Filter.
        ("[1,2,3,4][item > 2]", "[3, 4]"),
        ("[1,2,3,4][item > 10]", "[]"),
        ("[1,2,3,4][even(item)]", "[2, 4]"),
        ("[1,2,3][item > 1]", "[2, 3]"),
        // A condition that is null (or not a boolean) drops the element.
        ("[1,null,3][item > 1]", "[3]"),
        ("[1,2,3][item >= 2][1]", "2"),
        // DMN §10.3.2.5: context entries are visible by name in the filter.
        ("[{x:1, y:2}, {x:2, y:3}][x=1]", "[{x:1, y:2}]"),
        ("[{x:1, y:2}, {x:null, y:3}][x < 2]", "[{x:1, y:2}]"),
        ("[{a:1},{a:2}][a > 1]", "[{a:2}]"),
        // docs.camunda.io FEEL context expressions, Filter.
        (
            "[{a: \"p1\", b: 5}, {a: \"p2\", b: 10}][b > 7]",
            "[{a:\"p2\", b:10}]",
        ),
        ("[{a:1},{a:2}][item.a = 1]", "[{a:1}]"),
    ]);
    check_vars(&camunda_vars(), &[("items[item > n - 2]", "[2, 3]")]);
}

/// A path on a list of contexts projects every element.
#[test]
fn list_projection() {
    check(&[
        // DMN §10.3.2.5.
        ("[{x:1, y:2}, {x:2, y:3}].y", "[2, 3]"),
        ("[{x:1, y:2}, {x:2}].y", "[2, null]"),
        // docs.camunda.io FEEL context expressions, Projection; error handling: `[1, null]`.
        (
            "[{a: \"p1\", b: 5}, {a: \"p2\", b: 10}].a",
            "[\"p1\", \"p2\"]",
        ),
        ("[{a:1},{b:2}].a", "[1, null]"),
    ]);
}

/// Contexts: entries see the entries before them; paths select entries.
#[test]
fn contexts() {
    check(&[
        // docs.camunda.io FEEL context expressions, Literal.
        ("{a: 1, b: 2}", "{a:1, b:2}"),
        ("{\"a\": 1, \"b\": 2}", "{a:1, b:2}"),
        ("{a: 2, b: a * 2}", "{a:2, b:4}"),
        ("{a: 1, b: {c: 2}}", "{a:1, b:{c:2}}"),
        // docs.camunda.io FEEL context expressions, Get entry/path.
        ("{a: 2}.a", "2"),
        ("{a: {b: 3}}.a", "{b:3}"),
        ("{a: {b: 3}}.a.b", "3"),
        // The brief / feel.md §3.2.
        ("{a: 1, b: 2}.b", "2"),
        ("{a: 1, b: a + 1}.b", "2"),
        ("{a: 1, b: a + 1, c: b * 10}.c", "20"),
        ("{a: 1}.b", "null"),
        // DMN §10.3.2.6: keys may be strings; a quoted key is read with backticks.
        ("{\"first name\": \"Ann\"}.`first name`", "\"Ann\""),
        ("{\"a-b\": 1}", "{a-b:1}"),
        // Nested contexts see the entries of the contexts around them.
        ("{a: 1, b: {c: a + 1}}.b.c", "2"),
        // Multi-line context literal (docs.camunda.io FEEL context expressions).
        ("{\n  a: 1,\n  b: 2\n}", "{a:1, b:2}"),
    ]);
    let order = ctx(&[
        ("id", s("order-123")),
        ("customer", ctx(&[("name", s("Paul"))])),
        ("total price", dec("21.2")),
    ]);
    // docs.camunda.io Expressions (Zeebe), Access variables; FEEL variables, Escape names.
    check_vars(
        &[("order", order)],
        &[
            ("order.id", "\"order-123\""),
            ("order.customer.name", "\"Paul\""),
            ("order.`total price`", "21.2"),
            ("order.customer.age", "null"),
            ("order.customer", "{name:\"Paul\"}"),
        ],
    );
}

/// `if` takes the `else` branch for false, null and non-booleans.
#[test]
fn if_then_else() {
    check(&[
        // docs.camunda.io FEEL control flow, If conditions.
        ("if 5 < 10 then \"low\" else \"high\"", "\"low\""),
        ("if 12 < 10 then \"low\" else \"high\"", "\"high\""),
        ("if null then \"low\" else \"high\"", "\"high\""),
        ("if \"yes\" then 1 else 2", "2"),
        ("if true then if false then 1 else 2 else 3", "2"),
        ("(if true then 1 else 2) + 1", "2"),
    ]);
    // feel.md §3.2.
    check_vars(
        &camunda_vars(),
        &[
            ("if n > 2 then \"big\" else \"small\"", "\"big\""),
            ("if missing then 1 else 2", "2"),
        ],
    );
}

/// `for` iterates lists, integer ranges (either direction) and several iteration contexts.
#[test]
fn for_loops() {
    check(&[
        // docs.camunda.io FEEL control flow, For loops.
        ("for x in [1,2,3] return x * 2", "[2, 4, 6]"),
        ("for x in [1,2], y in [3,4] return x * y", "[3, 4, 6, 8]"),
        (
            "for x in 0..8 return 2 ** x",
            "[1, 2, 4, 8, 16, 32, 64, 128, 256]",
        ),
        ("for x in 3..1 return 2 * x", "[6, 4, 2]"),
        // feel.md §3.2.
        ("for i in 1..3 return i * 2", "[2, 4, 6]"),
        ("for i in 1..1 return i", "[1]"),
        ("for x in [] return x", "[]"),
        // DMN grammar rule 46 (for expression): a later source may use an earlier name.
        ("for x in [1,2], y in x..2 return y", "[1, 2, 2]"),
        (
            "for x in [\"a\",\"b\"] return x + \"!\"",
            "[\"a!\", \"b!\"]",
        ),
        ("for c in [{a:1},{a:2}] return c.a", "[1, 2]"),
        ("count(for i in 1..1000 return i)", "1000"),
    ]);
    check_vars(
        &camunda_vars(),
        &[
            ("for x in items return x + 1", "[2, 3, 4]"),
            ("for i in 1..n return i", "[1, 2, 3]"),
        ],
    );
}

/// Inside a `for` body, `partial` is the list of the values so far (docs.camunda.io FEEL
/// control flow, For loops: "While iterating over the list, the previous elements are
/// assigned to the variable `partial`"), across every combination of several iterations.
#[test]
fn for_partial() {
    check(&[
        // docs.camunda.io FEEL control flow, For loops.
        (
            "for i in 1..10 return if (i <= 2) then 1 else partial[-1] + partial[-2]",
            "[1, 1, 2, 3, 5, 8, 13, 21, 34, 55]",
        ),
        (
            "for x in [\"a\",\"b\",\"c\"] return {value: x, index: count(partial) + 1}",
            "[{value:\"a\", index:1}, {value:\"b\", index:2}, {value:\"c\", index:3}]",
        ),
        ("for x in [\"a\",\"b\"] return count(partial) + 1", "[1, 2]"),
        ("for i in 1..3 return partial", "[[], [[]], [[], [[]]]]"),
        (
            "for x in [1,2], y in [3,4] return count(partial)",
            "[0, 1, 2, 3]",
        ),
        (
            "for i in 1..4 return if i = 1 then 1 else sum(partial) + i",
            "[1, 3, 7, 15]",
        ),
        // A nested `for` has its own `partial`; its source sees the outer one.
        (
            "for i in 1..2 return for j in 1..2 return count(partial)",
            "[[0, 1], [0, 1]]",
        ),
        (
            "for i in 1..3 return for j in 0..count(partial) return j",
            "[[0], [0, 1], [0, 1, 2]]",
        ),
        // A function defined in the body sees `partial` too.
        (
            "for i in 1..3 return (function() count(partial))()",
            "[0, 1, 2]",
        ),
        // `some` and `every` have no `partial`; outside a `for` it is an ordinary name.
        ("some i in [1, 2] satisfies partial = null", "true"),
        ("partial", "null"),
    ]);
    check_vars(
        &[("partial", n(7))],
        &[
            ("partial + 1", "8"),
            ("for i in 1..2 return partial", "[[], [[]]]"),
            ("for i in 1..2 return i + partial", "[null, null]"),
        ],
    );
}

/// `some` / `every` quantify over one or several lists.
#[test]
fn quantifiers() {
    check(&[
        // docs.camunda.io FEEL list expressions, Some / Every.
        ("some x in [1,2,3] satisfies x > 2", "true"),
        ("some x in [1,2,3] satisfies x > 5", "false"),
        ("some x in [1,2,3] satisfies even(x)", "true"),
        ("some x in [1,2], y in [2,3] satisfies x < y", "true"),
        ("every x in [1,2,3] satisfies x >= 1", "true"),
        ("every x in [1,2,3] satisfies x >= 2", "false"),
        ("every x in [1,2,3] satisfies even(x)", "false"),
        ("every x in [1,2], y in [2,3] satisfies x < y", "false"),
        // DMN 1.3: `some`/`every` are any()/all() of the results; §10.3.4.4 any([]) = false,
        // all([]) = true.
        ("some x in [] satisfies true", "false"),
        ("every x in [] satisfies false", "true"),
    ]);
    check_vars(
        &camunda_vars(),
        &[("every i in items satisfies i <= n", "true")],
    );
}

/// Functions defined in an expression: called by position or by name, closures, values.
#[test]
fn user_functions() {
    check(&[
        // The brief; docs.camunda.io FEEL functions, User-defined ("defined and invoked in a
        // context").
        ("{f: function(x) x * 2, r: f(3)}.r", "6"),
        ("{add: function(a, b) a + b, r: add(1, 2)}.r", "3"),
        // docs.camunda.io FEEL functions, Invocation: named arguments in any order.
        ("{f: function(a, b) a - b, r: f(b: 1, a: 5)}.r", "4"),
        // A function sees the entries defined before it.
        ("{y: 10, f: function(x) x + y, r: f(1)}.r", "11"),
        (
            "{f: function(x) x + 1, g: function(x) f(x) * 2, r: g(1)}.r",
            "4",
        ),
        // DMN grammar rule 40 (function invocation): any expression yielding a function.
        ("(function(x) x + 1)(2)", "3"),
        // DMN §10.3.4.9 sort: a function value as an argument.
        ("sort([3,1,2], function(x, y) x < y)", "[1, 2, 3]"),
        ("sort([3,1,2], function(x, y) x > y)", "[3, 2, 1]"),
    ]);
    check_vars(
        &camunda_vars(),
        &[("{f: function(x) x * n, r: f(2)}.r", "6")],
    );
}

/// Built-in functions take positional or named arguments (multi-word parameter names too).
#[test]
fn named_arguments() {
    check(&[
        // The brief; docs.camunda.io FEEL string functions (parameter names).
        (
            "substring(string: \"foobar\", start position: 3)",
            "\"obar\"",
        ),
        (
            "substring(start position: 3, string: \"foobar\")",
            "\"obar\"",
        ),
        (
            "substring(string: \"foobar\", start position: 3, length: 3)",
            "\"oba\"",
        ),
        // docs.camunda.io FEEL built-in functions introduction / FEEL functions.
        ("contains(\"me@camunda.com\", \".com\")", "true"),
        (
            "contains(string: \"me@camunda.com\", match: \".de\")",
            "false",
        ),
        // docs.camunda.io Expressions (Zeebe), Invoke functions.
        ("contains(string: \"foobar\", match: \"foo\")", "true"),
        // DMN §10.3.4.9.
        (
            "sort(list: [3,1,4,5,2], precedes: function(x,y) x < y)",
            "[1, 2, 3, 4, 5]",
        ),
    ]);
}

/// Names: Java-like identifiers, or any text in backticks (Camunda extension).
#[test]
fn names() {
    let vars = [
        ("order total", n(150)),
        ("tracking-id", s("T-1")),
        ("_under", n(1)),
        ("camelCase2", n(2)),
        ("été", n(3)),
    ];
    // docs.camunda.io FEEL variables, Variable names / Escape variable names; feel.md §3.2.
    check_vars(
        &vars,
        &[
            ("`order total` > 100", "true"),
            ("`tracking-id`", "\"T-1\""),
            ("_under + camelCase2", "3"),
            ("été", "3"),
            ("{`a b`: 1}", "{a b:1}"),
        ],
    );
    // Names are case-sensitive (docs.camunda.io FEEL variables).
    assert_eq!(feel_vars("Camelcase2", &vars), "null");
}

/// Evaluation reads the variables and nothing else; the same input gives the same output.
#[test]
fn deterministic() {
    let text = "{a: for i in 1..50 return i * i, b: sum(a), c: now(), d: today()}";
    let first = feel(text);
    assert_eq!(first, feel(text));
    assert!(
        first.ends_with("b:42925, c:2026-11-23T10:00:00Z, d:2026-11-23}"),
        "{first}"
    );
    assert_eq!(feel_vars("items", &[("items", list([n(1)]))]), "[1]");
}
