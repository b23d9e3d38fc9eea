//! Built-in functions: conversion, boolean, string, list, numeric, context and sort, with the
//! examples of the DMN specification's tables (§10.3.4.1–§10.3.4.10, DMN 1.5 text; the same
//! examples in DMN 1.3 unless noted) and of docs.camunda.io *FEEL built-in functions* pages
//! (Camunda extensions marked there).

use super::{check, check_prefix, check_vars, ctx, list, n, s};

/// DMN §10.3.4.1 conversion functions (Table 72) and docs.camunda.io *Conversion functions*.
#[test]
fn conversion_functions() {
    check(&[
        // DMN §10.3.4.1.
        ("string(1.1)", "\"1.1\""),
        ("string(null)", "null"),
        ("number(\"1 000,0\", \" \", \",\")", "1000"),
        (
            "number(\"1 000,0\", \" \", \",\") = number(\"1,000.0\", \",\", \".\")",
            "true",
        ),
        (
            "years and months duration(date(\"2011-12-22\"), date(\"2013-08-24\"))",
            "P1Y8M",
        ),
        // docs.camunda.io Conversion functions.
        ("string(date(\"2012-12-25\"))", "\"2012-12-25\""),
        ("number(\"1500.5\")", "1500.5"),
        ("number(\"1,500\", \",\")", "1500"),
        ("number(\"1 500.5\", \" \", \".\")", "1500.5"),
        ("number(\"abc\")", "null"),
        (
            "context([{\"key\":\"a\", \"value\":1}, {\"key\":\"b\", \"value\":2}])",
            "{a:1, b:2}",
        ),
        // DMN 1.5 §10.3.4.10 context(): extra entries are ignored, missing ones give null.
        (
            "context([{key:\"a\", value:1}, {key:\"b\", value:2, something: \"else\"}])",
            "{a:1, b:2}",
        ),
        ("context([{key:\"a\", value:1}, {key:\"b\"}])", "null"),
        // string() of the other kinds: strings unquoted, the rest as FEEL prints them
        // (docs.camunda.io Expressions: `"order-" + string(orderId)`).
        ("string(123)", "\"123\""),
        ("string(-1.50)", "\"-1.5\""),
        ("string(true)", "\"true\""),
        ("string(\"a\")", "\"a\""),
        ("string([1, 2])", "\"[1, 2]\""),
        // docs.camunda.io Conversion functions: from json / to json.
        ("from json(\"{\\\"a\\\": 1, \\\"b\\\": 2}\")", "{a:1, b:2}"),
        ("from json(\"true\")", "true"),
        ("from json(\"\\\"2023-06-14\\\"\")", "\"2023-06-14\""),
        ("from json(\"{\")", "null"),
        ("to json({a: 1, b: 2})", "\"{\\\"a\\\":1,\\\"b\\\":2}\""),
        ("to json(true)", "\"true\""),
        ("to json(@\"2023-06-14\")", "\"\\\"2023-06-14\\\"\""),
        ("to json(@\"P3Y\")", "\"\\\"P3Y\\\"\""),
    ]);
}

/// DMN §10.3.4.2 boolean function and docs.camunda.io *Boolean functions*.
#[test]
fn boolean_functions() {
    check(&[
        ("not(true)", "false"),
        ("not(false)", "true"),
        ("not(null)", "null"),
        ("not(1)", "null"),
    ]);
    // feel.md §3.2: `not(flag)` with flag = false.
    check_vars(&[("flag", super::b(false))], &[("not(flag)", "true")]);
}

/// DMN §10.3.4.3 string functions (Table 74).
#[test]
fn string_functions_dmn() {
    check(&[
        ("substring(\"foobar\",3)", "\"obar\""),
        ("substring(\"foobar\",3,3)", "\"oba\""),
        ("substring(\"foobar\", -2, 1)", "\"a\""),
        // "\U01F40Eab" in the spec: one code point, then "ab".
        ("substring(\"🐎ab\", 2)", "\"ab\""),
        ("string length(\"foo\")", "3"),
        ("string length(\"🐎ab\")", "3"),
        ("upper case(\"aBc4\")", "\"ABC4\""),
        ("lower case(\"aBc4\")", "\"abc4\""),
        ("substring before(\"foobar\",\"bar\")", "\"foo\""),
        ("substring before(\"foobar\",\"xyz\")", "\"\""),
        ("substring after(\"foobar\", \"ob\")", "\"ar\""),
        ("substring after(\"\", \"a\")", "\"\""),
        ("replace(\"banana\",\"a\",\"o\")", "\"bonono\""),
        (
            "replace(\"abcd\", \"(ab)|(a)\", \"[1=$1][2=$2]\")",
            "\"[1=ab][2=]cd\"",
        ),
        ("contains(\"foobar\", \"of\")", "false"),
        ("starts with(\"foobar\", \"fo\")", "true"),
        ("ends with(\"foobar\", \"r\")", "true"),
        ("matches(\"foobar\", \"^fo*b\")", "true"),
        ("split(\"John Doe\", \"\\\\s\")", "[\"John\", \"Doe\"]"),
        (
            "split(\"a;b;c;;\", \";\")",
            "[\"a\", \"b\", \"c\", \"\", \"\"]",
        ),
        (
            "string join([\"a\",\"b\",\"c\"], \"_and_\")",
            "\"a_and_b_and_c\"",
        ),
        ("string join([\"a\",\"b\",\"c\"], \"\")", "\"abc\""),
        ("string join([\"a\",\"b\",\"c\"], null)", "\"abc\""),
        ("string join([\"a\"], \"X\")", "\"a\""),
        ("string join([\"a\",null,\"c\"], \"X\")", "\"aXc\""),
        ("string join([], \"X\")", "\"\""),
        ("string join([\"a\",\"b\",\"c\"])", "\"abc\""),
        ("string join([\"a\",null,\"c\"])", "\"ac\""),
        ("string join([])", "\"\""),
        // "Whenever a parameter is outside its domain, the result of the built-in is null."
        ("upper case(1)", "null"),
        ("substring(\"foobar\", \"a\")", "null"),
    ]);
}

/// docs.camunda.io *String functions* examples, including the Camunda extensions.
#[test]
fn string_functions_camunda() {
    check(&[
        ("substring(\"foobar\", 3)", "\"obar\""),
        ("substring(\"foobar\", -2)", "\"ar\""),
        ("substring(\"foobar\", 3, 3)", "\"oba\""),
        ("substring(\"foobar\", -3, 2)", "\"ba\""),
        ("substring(\"foobar\", 3, 10)", "\"obar\""),
        ("substring after(\"foobar\", \"ob\")", "\"ar\""),
        ("matches(\"foobar\", \"^fo*bar\")", "true"),
        ("matches(\"FooBar\", \"foo\", \"i\")", "true"),
        ("matches(\"FooBar\", \"foo\")", "false"),
        (
            "replace(\"0123456789\", \"(\\d{3})(\\d{3})(\\d{4})\", \"($1) $2-$3\")",
            "\"(012) 345-6789\"",
        ),
        (
            "replace(\"How do you feel?\", \"Feel\", \"FEEL\", \"i\")",
            "\"How do you FEEL?\"",
        ),
        ("split(\"John Doe\", \"\\s\" )", "[\"John\", \"Doe\"]"),
        (
            "extract(\"references are 1234, 1256, 1378\", \"12[0-9]*\")",
            "[\"1234\", \"1256\"]",
        ),
        ("extract(\"abc\", \"[0-9]+\")", "[]"),
        ("trim(\"  hello world  \")", "\"hello world\""),
        ("trim(\"hello   world \")", "\"hello   world\""),
        ("to base64(\"FEEL\")", "\"RkVFTA==\""),
        ("is blank(\"\")", "true"),
        ("is blank(\" \")", "true"),
        ("is blank(\"hello world\")", "false"),
        // docs.camunda.io List functions, string join (Camunda's prefix and suffix).
        (
            "string join([\"a\",\"b\",\"c\"], \", \", \"[\", \"]\")",
            "\"[a, b, c]\"",
        ),
        ("string join([\"a\",\"b\",\"c\"], \", \")", "\"a, b, c\""),
        // Characters, not bytes (DMN: "number of characters (or code points)").
        ("upper case(\"é\")", "\"É\""),
        ("substring(\"héllo\", 2, 3)", "\"éll\""),
        ("string length(\"héllo\")", "5"),
    ]);
}

/// DMN §10.3.4.4 list functions (Table 75) and docs.camunda.io *List functions*.
#[test]
fn list_functions() {
    check(&[
        // DMN §10.3.4.4.
        ("list contains([1,2,3], 2)", "true"),
        ("list contains([1,2,3], 5)", "false"),
        ("count([1,2,3])", "3"),
        ("count([])", "0"),
        ("count([1,[2,3]])", "2"),
        ("min([1,2,3])", "1"),
        ("max(1,2,3)", "3"),
        ("min(1)", "1"),
        ("min([1])", "1"),
        ("max([])", "null"),
        ("sum([1,2,3])", "6"),
        ("sum(1,2,3)", "6"),
        ("sum(1)", "1"),
        ("sum([])", "null"),
        ("mean([1,2,3])", "2"),
        ("mean(1,2,3)", "2"),
        ("mean(1)", "1"),
        ("mean([])", "null"),
        ("all([false,null,true])", "false"),
        ("all(true)", "true"),
        ("all([true])", "true"),
        ("all([])", "true"),
        ("all(0)", "null"),
        ("any([false,null,true])", "true"),
        ("any(false)", "false"),
        ("any([])", "false"),
        ("any(0)", "null"),
        ("sublist([4,5,6], 1, 2)", "[4, 5]"),
        ("append([1], 2, 3)", "[1, 2, 3]"),
        ("concatenate([1,2],[3])", "[1, 2, 3]"),
        // DMN: `insert before([1,3], 1, 2) = [2,1,3]` (docs.camunda.io prints [1,2,3], a
        // typo: the function inserts newItem 2 at position 1).
        ("insert before([1,3],1,2)", "[2, 1, 3]"),
        ("remove([1,2,3], 2)", "[1, 3]"),
        ("reverse([1,2,3])", "[3, 2, 1]"),
        ("index of([1,2,3,2],2)", "[2, 4]"),
        ("union([1,2],[2,3])", "[1, 2, 3]"),
        ("distinct values([1,2,3,2,1])", "[1, 2, 3]"),
        ("flatten([[1,2],[[3]], 4])", "[1, 2, 3, 4]"),
        ("product([2, 3, 4])", "24"),
        ("product([])", "null"),
        ("product(2, 3, 4)", "24"),
        ("median(8, 2, 5, 3, 4)", "4"),
        ("median([6, 1, 2, 3])", "2.5"),
        ("median([])", "null"),
        ("stddev([47])", "null"),
        ("stddev(47)", "null"),
        ("mode(6, 3, 9, 6, 6)", "[6]"),
        ("mode([6, 1, 9, 6, 1])", "[1, 6]"),
        ("mode([])", "[]"),
        // docs.camunda.io List functions.
        ("sublist([1,2,3], 2)", "[2, 3]"),
        ("sublist([1,2,3], 1, 2)", "[1, 2]"),
        ("concatenate([1],[2],[3])", "[1, 2, 3]"),
        ("and([true,false])", "false"),
        ("and(false,null,true)", "false"),
        ("or([false,true])", "true"),
        ("or(false,null,true)", "true"),
        ("min([\"b\", \"a\"])", "\"a\""),
        ("is empty([])", "true"),
        ("is empty([1,2,3])", "false"),
        // docs.camunda.io Expressions (Zeebe), Invoke functions.
        ("count([\"a\",\"b\",\"c\"])", "3"),
        ("append([\"a\",\"b\"], \"c\")", "[\"a\", \"b\", \"c\"]"),
    ]);
    // DMN §10.3.4.4 stddev( 2, 4, 7, 5 ) = 2.081665999466132735282297706979931 (34 digits).
    check_prefix(&[
        ("stddev(2, 4, 7, 5)", "2.08166599946613273528"),
        ("stddev([2, 4, 7, 5])", "2.08166599946613273528"),
    ]);
    // feel.md §3.2: `list contains([1,2,3], n)`, `count(items) > 0`, `sum([1,2,3])`.
    check_vars(
        &[("n", n(3)), ("items", list([n(1), n(2), n(3)]))],
        &[
            ("list contains([1,2,3], n)", "true"),
            ("count(items) > 0", "true"),
            ("sum(items)", "6"),
        ],
    );
}

/// DMN §10.3.4.5 numeric functions (Table 76) and docs.camunda.io *Numeric functions*.
#[test]
fn numeric_functions() {
    check(&[
        // DMN §10.3.4.5.
        ("decimal(1/3, 2)", "0.33"),
        ("decimal(1.5, 0)", "2"),
        ("decimal(2.5, 0)", "2"),
        ("floor(1.5)", "1"),
        ("floor(-1.56, 1)", "-1.6"),
        ("ceiling(1.5)", "2"),
        ("ceiling(-1.56, 1)", "-1.5"),
        ("round up(5.5, 0)", "6"),
        ("round up(-5.5, 0)", "-6"),
        ("round up(1.121, 2)", "1.13"),
        ("round up(-1.126, 2)", "-1.13"),
        ("round down(5.5, 0)", "5"),
        ("round down(-5.5, 0)", "-5"),
        ("round down(1.121, 2)", "1.12"),
        ("round down(-1.126, 2)", "-1.12"),
        ("round half up(5.5, 0)", "6"),
        ("round half up(-5.5, 0)", "-6"),
        ("round half up(1.121, 2)", "1.12"),
        ("round half up(-1.126, 2)", "-1.13"),
        ("round half down(5.5, 0)", "5"),
        ("round half down(-5.5, 0)", "-5"),
        ("round half down(1.121, 2)", "1.12"),
        ("round half down(-1.126, 2)", "-1.13"),
        ("abs(10)", "10"),
        ("abs(-10)", "10"),
        ("modulo(12, 5)", "2"),
        ("modulo(-12,5)", "3"),
        ("modulo(12,-5)", "-3"),
        ("modulo(-12,-5)", "-2"),
        ("modulo(10.1, 4.5)", "1.1"),
        ("modulo(-10.1, 4.5)", "3.4"),
        ("modulo(10.1, -4.5)", "-3.4"),
        ("modulo(-10.1, -4.5)", "-1.1"),
        ("sqrt(16)", "4"),
        ("sqrt(-1)", "null"),
        ("odd(5)", "true"),
        ("odd(2)", "false"),
        ("even(5)", "false"),
        ("even(2)", "true"),
        // docs.camunda.io Numeric functions (scale optional).
        ("floor(-1.5)", "-2"),
        ("ceiling(-1.5)", "-1"),
        ("round up(5.5)", "6"),
        ("round down(5.5)", "5"),
        ("round half up(5.5)", "6"),
        ("round half down(5.5)", "5"),
        ("decimal(2.5, 0, \"half_up\")", "3"),
        // Both sources write a space before the parenthesis.
        ("round down (-5.5, 0)", "-5"),
        ("round half down (-1.126, 2)", "-1.13"),
        // docs.camunda.io Expressions (Zeebe), Invoke functions.
        ("floor(1.5)", "1"),
        // "Whenever a parameter is outside its domain, the result of the built-in is null."
        ("modulo(1, 0)", "null"),
        ("abs(\"a\")", "null"),
    ]);
    // DMN §10.3.4.5: log(10) = 2.30258509299, exp(5) = 148.413159102577.
    check_prefix(&[
        ("log(10)", "2.30258509299"),
        ("exp(5)", "148.4131591025766"),
    ]);
}

/// DMN §10.3.4.10 context functions (Table 81) and docs.camunda.io *Context functions*.
#[test]
fn context_functions() {
    check(&[
        // DMN §10.3.4.10.
        ("get value({key1 : \"value1\"}, \"key1\")", "\"value1\""),
        ("get value({key1 : \"value1\"}, \"unexistent-key\")", "null"),
        (
            "get entries({key1 : \"value1\", key2 : \"value2\"})",
            "[{key:\"key1\", value:\"value1\"}, {key:\"key2\", value:\"value2\"}]",
        ),
        ("context put({x:1}, \"y\", 2)", "{x:1, y:2}"),
        ("context put({x:1, y:0}, \"y\", 2)", "{x:1, y:2}"),
        ("context put({x:1, y:0, z:0}, \"y\", 2)", "{x:1, y:2, z:0}"),
        (
            "context put({x:1, y: {a: 0} }, [\"y\", \"a\"], 2)",
            "{x:1, y:{a:2}}",
        ),
        ("context put({x:1, y: {a: 0} }, [], 2)", "null"),
        // docs.camunda.io Context functions.
        ("get value({foo: 123}, \"foo\")", "123"),
        ("get value({a: 1}, \"b\")", "null"),
        ("get value({x:1, y: {z:0}}, [\"y\", \"z\"])", "0"),
        ("get value({x: {y: {z:0}}}, [\"x\", \"y\"])", "{z:0}"),
        ("get value({a: {b: 3}}, [\"b\"])", "null"),
        ("get entries({foo: 123})", "[{key:\"foo\", value:123}]"),
        ("context put({x:1}, [\"y\"], 2)", "{x:1, y:2}"),
        (
            "context put({x:1, y: {z:0}}, [\"y\", \"z\"], 2)",
            "{x:1, y:{z:2}}",
        ),
        ("context put({x:1}, [\"y\", \"z\"], 2)", "{x:1, y:{z:2}}"),
        ("context merge([{x:1}, {y:2}])", "{x:1, y:2}"),
        ("context merge([{x:1, y: 0}, {y:2}])", "{x:1, y:2}"),
        // feel-scala's older names (docs.camunda.io 8.1 Context functions: put, put all).
        ("put({x:1}, \"y\", 2)", "{x:1, y:2}"),
        ("put all({x:1}, {y:2})", "{x:1, y:2}"),
        // docs.camunda.io FEEL variables tip: `get value(order, "total price")`.
        ("get value({\"total price\": 5}, \"total price\")", "5"),
        // get entries / context are inverses (docs.camunda.io Conversion functions).
        ("context(get entries({a: 1, b: [2]}))", "{a:1, b:[2]}"),
    ]);
    let order = ctx(&[("total price", n(5)), ("id", s("o-1"))]);
    check_vars(
        &[("order", order)],
        &[
            ("get value(order, \"total price\")", "5"),
            ("get entries(order).key", "[\"total price\", \"id\"]"),
        ],
    );
}
