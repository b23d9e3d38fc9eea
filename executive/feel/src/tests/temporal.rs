//! Temporal values: dates, times, date-times, the two duration kinds, `@"…"` literals,
//! arithmetic, comparison, properties, the temporal built-ins, and `now()` / `today()` from the
//! environment (2026-11-23T10:00:00Z, a Monday). Results print in ISO 8601 (`2026-11-23`,
//! `10:00:00Z`, `2026-11-23T10:00:00Z`, `P1DT2H`, `P1Y2M`). Sources: docs.camunda.io FEEL
//! *temporal expressions*, *data types*, *Conversion* and *Temporal functions*; DMN §10.3.4.1
//! (Table 72) and §10.3.4.8 (Table 79); feel.md §3.2 and §6.3 (the clock).

use super::{check, check_vars, feel, n};
use crate::Value;

/// Constructors and `@"…"` literals of every temporal kind.
#[test]
fn literals_and_constructors() {
    check(&[
        // docs.camunda.io FEEL temporal expressions, Literal; FEEL data types.
        ("date(\"2020-04-06\")", "2020-04-06"),
        ("@\"2020-04-06\"", "2020-04-06"),
        ("time(\"08:00:00\")", "08:00:00"),
        ("@\"08:00:00\"", "08:00:00"),
        ("time(\"08:00:00+02:00\")", "08:00:00+02:00"),
        ("@\"08:00:00+02:00\"", "08:00:00+02:00"),
        ("time(\"10:00:00Z\")", "10:00:00Z"),
        ("time(\"13:30\")", "13:30:00"),
        (
            "date and time(\"2020-04-06T08:00:00\")",
            "2020-04-06T08:00:00",
        ),
        (
            "date and time(\"2020-04-06T08:00:00+02:00\")",
            "2020-04-06T08:00:00+02:00",
        ),
        ("@\"2020-04-06T08:00:00\"", "2020-04-06T08:00:00"),
        ("@\"2026-11-23T10:00:00Z\"", "2026-11-23T10:00:00Z"),
        ("duration(\"P5D\")", "P5D"),
        ("duration(\"PT6H\")", "PT6H"),
        ("@\"P5D\"", "P5D"),
        ("@\"PT6H\"", "PT6H"),
        ("duration(\"P1Y6M\")", "P1Y6M"),
        ("duration(\"P3M\")", "P3M"),
        ("@\"P1Y6M\"", "P1Y6M"),
        ("duration(\"PT30M\")", "PT30M"),
        ("duration(\"P1DT6H\")", "P1DT6H"),
        ("duration(\"P2Y\")", "P2Y"),
        ("@\"P1DT2H\"", "P1DT2H"),
        ("@\"P1Y2M\"", "P1Y2M"),
        ("duration(\"-PT5H\")", "-PT5H"),
        // DMN §10.3.4.1 (Table 72) and docs.camunda.io Conversion functions.
        ("date(2012, 12, 25)", "2012-12-25"),
        (
            "date(date and time(\"2012-12-25T11:00:00Z\"))",
            "2012-12-25",
        ),
        ("time(date and time(\"2012-12-25T11:00:00Z\"))", "11:00:00Z"),
        ("time(23, 59, 0)", "23:59:00"),
        ("time(14, 30, 0, duration(\"PT1H\"))", "14:30:00+01:00"),
        (
            "date and time(date(\"2012-12-24\"), time(\"23:59:00\"))",
            "2012-12-24T23:59:00",
        ),
        (
            "date and time(date and time(\"2012-12-25T11:00:00\"), time(\"23:59:00\"))",
            "2012-12-25T23:59:00",
        ),
        ("duration(\"P2Y2M\") = duration(\"P26M\")", "true"),
        // Durations print normalised (DMN §10.3.2.3: valueymd⁻¹(13) = P1Y1M).
        ("duration(\"P26M\")", "P2Y2M"),
        ("duration(\"PT36H\")", "P1DT12H"),
        // docs.camunda.io Conversion functions: invalid calendar dates are null.
        ("date(\"2024-06-31\")", "null"),
        ("date(2024, 6, 31)", "null"),
        ("date and time(\"2024-06-31T10:00:00\")", "null"),
        ("duration(\"P1X\")", "null"),
        ("date(\"not a date\")", "null"),
        // docs.camunda.io Conversion functions, string(): ISO text.
        ("string(date(\"2012-12-25\"))", "\"2012-12-25\""),
        ("string(duration(\"P1D\"))", "\"P1D\""),
        (
            "string(@\"2026-11-23T10:00:00Z\")",
            "\"2026-11-23T10:00:00Z\"",
        ),
    ]);
}

/// Addition, subtraction, multiplication and division of temporal values.
#[test]
fn arithmetic() {
    check(&[
        // docs.camunda.io FEEL temporal expressions, Addition.
        ("date(\"2020-04-06\") + duration(\"P1D\")", "2020-04-07"),
        ("time(\"08:00:00\") + duration(\"PT1H\")", "09:00:00"),
        (
            "date and time(\"2020-04-06T08:00:00\") + duration(\"P7D\")",
            "2020-04-13T08:00:00",
        ),
        ("duration(\"P2D\") + duration(\"P5D\")", "P7D"),
        ("duration(\"P1D\") + date(\"2020-04-06\")", "2020-04-07"),
        ("date(\"2020-04-06\") + duration(\"P1M\")", "2020-05-06"),
        // docs.camunda.io FEEL temporal expressions, Subtraction.
        ("date(\"2020-04-06\") - date(\"2020-04-01\")", "P5D"),
        ("date(\"2020-04-06\") - duration(\"P5D\")", "2020-04-01"),
        ("time(\"08:00:00\") - time(\"06:00:00\")", "PT2H"),
        ("time(\"08:00:00\") - duration(\"PT2H\")", "06:00:00"),
        ("duration(\"P7D\") - duration(\"P2D\")", "P5D"),
        ("duration(\"P1Y\") - duration(\"P3M\")", "P9M"),
        // docs.camunda.io FEEL temporal expressions, Multiplication / Division.
        ("duration(\"P1D\") * 5", "P5D"),
        ("duration(\"P1M\") * 6", "P6M"),
        ("duration(\"P5D\") / duration(\"P1D\")", "5"),
        ("duration(\"P5D\") / 5", "P1D"),
        ("duration(\"P1Y\") / duration(\"P1M\")", "12"),
        ("duration(\"P1Y\") / 12", "P1M"),
        ("duration(\"PT1H\") * 1.5", "PT1H30M"),
        // DMN §10.3.4.1 (Table 72) examples.
        ("date(\"2012-12-25\") - date(\"2012-12-24\")", "P1D"),
        (
            "date and time(\"2012-12-24T23:59:00\") + duration(\"PT1M\")",
            "2012-12-25T00:00:00",
        ),
        (
            "date and time(\"2012-12-24T23:59:00\") - date and time(\"2012-12-22T03:45:00\")",
            "P2DT20H14M",
        ),
        ("time(\"23:59:00Z\") + duration(\"PT2M\")", "00:01:00Z"),
        // The brief and feel.md §3.2.
        ("date(\"2026-11-23\") + duration(\"P1D\")", "2026-11-24"),
        (
            "date and time(\"2026-11-23T10:00:00Z\") + duration(\"PT6H\")",
            "2026-11-23T16:00:00Z",
        ),
        (
            "@\"2026-11-23T10:00:00Z\" - @\"2026-11-23T08:30:00Z\"",
            "PT1H30M",
        ),
        (
            "@\"2026-11-23T12:00:00+02:00\" - @\"2026-11-23T10:00:00Z\"",
            "PT0S",
        ),
        // docs.camunda.io Temporal functions, abs(); DMN §10.3.4.5 abs(@"-PT5H").
        ("abs(duration(\"-PT5H\"))", "PT5H"),
        ("abs(duration(\"PT5H\"))", "PT5H"),
        ("abs(duration(\"-P2M\"))", "P2M"),
        // An operation not defined for the given values is null (docs.camunda.io error
        // handling).
        ("date(\"2026-11-23\") + 1", "null"),
        ("date(\"2026-11-23\") + date(\"2026-11-23\")", "null"),
        ("duration(\"P1D\") + duration(\"P1M\")", "null"),
    ]);
}

/// Temporal values of the same kind compare; different kinds do not (null).
#[test]
fn comparison() {
    check(&[
        // docs.camunda.io FEEL boolean expressions, Comparison.
        ("date(\"2020-04-05\") < date(\"2020-04-06\")", "true"),
        ("time(\"08:00:00\") <= time(\"08:00:00\")", "true"),
        ("duration(\"P1D\") > duration(\"P5D\")", "false"),
        ("duration(\"P1Y\") >= duration(\"P6M\")", "true"),
        ("date(\"2026-11-23\") = @\"2026-11-23\"", "true"),
        ("duration(\"PT24H\") = duration(\"P1D\")", "true"),
        ("duration(\"P1D\") > duration(\"PT23H\")", "true"),
        // The same instant in two offsets (DMN §10.3.2.3: date-times compare by value).
        (
            "@\"2026-11-23T10:00:00Z\" = @\"2026-11-23T12:00:00+02:00\"",
            "true",
        ),
        (
            "@\"2026-11-23T10:00:00Z\" < @\"2026-11-23T11:00:00+02:00\"",
            "false",
        ),
        (
            "@\"2026-11-23T10:00:00@UTC\" = @\"2026-11-23T10:00:00Z\"",
            "true",
        ),
        // Values of different kinds are not comparable.
        ("date(\"2026-11-23\") < 1", "null"),
        ("duration(\"P1D\") < duration(\"P1M\")", "null"),
        ("date(\"2026-11-23\") = \"2026-11-23\"", "null"),
    ]);
}

/// Properties of temporal values (docs.camunda.io FEEL temporal expressions, Properties).
#[test]
fn properties() {
    check(&[
        ("date(\"2020-04-06\").year", "2020"),
        ("date(\"2020-04-06\").month", "4"),
        ("date(\"2020-04-06\").day", "6"),
        ("date(\"2020-04-06\").weekday", "1"),
        ("time(\"08:00:00\").hour", "8"),
        ("date and time(\"2020-04-06T08:30:15\").minute", "30"),
        ("date and time(\"2020-04-06T08:30:15\").second", "15"),
        (
            "date and time(\"2020-04-06T08:00:00+02:00\").time offset",
            "PT2H",
        ),
        ("duration(\"PT2H30M\").hours", "2"),
        ("duration(\"PT2H30M\").minutes", "30"),
        ("duration(\"P2DT3H\").days", "2"),
        ("duration(\"PT90S\").seconds", "30"),
        ("duration(\"P6M\").months", "6"),
        ("duration(\"P1Y6M\").years", "1"),
        ("@\"2026-11-23\".year", "2026"),
        // A property a value does not have is null.
        ("date(\"2026-11-23\").hour", "null"),
        ("duration(\"P1D\").years", "null"),
    ]);
}

/// DMN §10.3.4.8 temporal built-ins (Table 79) and docs.camunda.io Temporal functions.
#[test]
fn temporal_functions() {
    check(&[
        // DMN §10.3.4.8.
        ("day of year(date(2019, 9, 17))", "260"),
        ("day of week(date(2019, 9, 17))", "\"Tuesday\""),
        ("month of year(date(2019, 9, 17))", "\"September\""),
        ("week of year(date(2019, 9, 17))", "38"),
        ("week of year(date(2003, 12, 29))", "1"),
        ("week of year(date(2004, 1, 4))", "1"),
        ("week of year(date(2005, 1, 1))", "53"),
        ("week of year(date(2005, 1, 3))", "1"),
        ("week of year(date(2005, 1, 9))", "1"),
        // docs.camunda.io Temporal functions: date-time arguments too.
        (
            "day of week(date and time(\"2019-09-17T12:00:00\"))",
            "\"Tuesday\"",
        ),
        ("day of year(date and time(\"2019-09-17T12:00:00\"))", "260"),
        ("week of year(date and time(\"2019-09-17T12:00:00\"))", "38"),
        (
            "month of year(date and time(\"2019-09-17T12:00:00\"))",
            "\"September\"",
        ),
        ("last day of month(date(\"2022-10-01\"))", "2022-10-31"),
        (
            "last day of month(date and time(\"2022-10-16T12:00:00\"))",
            "2022-10-31",
        ),
        ("last day of month(date(\"2024-02-10\"))", "2024-02-29"),
        // DMN §10.3.4.1 years and months duration().
        (
            "years and months duration(date(\"2011-12-22\"), date(\"2013-08-24\"))",
            "P1Y8M",
        ),
    ]);
}

/// `now()` and `today()` are the environment's mission time (UTC), never the wall clock.
#[test]
fn clock_from_the_environment() {
    check(&[
        // feel.md §6.3: the `at` of the step being evaluated; today() is its UTC date.
        ("now()", "2026-11-23T10:00:00Z"),
        ("today()", "2026-11-23"),
        ("now() = @\"2026-11-23T10:00:00Z\"", "true"),
        ("today() = date(\"2026-11-23\")", "true"),
        ("now() + duration(\"PT1H\")", "2026-11-23T11:00:00Z"),
        ("now() - @\"2026-11-23T00:00:00Z\"", "PT10H"),
        ("today() + duration(\"P7D\")", "2026-11-30"),
        ("today() - date(\"2026-01-01\")", "P326D"),
        ("date(now())", "2026-11-23"),
        ("time(now())", "10:00:00Z"),
        ("now().year", "2026"),
        ("now().hour", "10"),
        ("today().weekday", "1"),
        ("day of week(today())", "\"Monday\""),
        ("now() > @\"2026-01-01T00:00:00Z\"", "true"),
        ("@\"2026-11-23T10:00:00@UTC\" = now()", "true"),
        (
            "years and months duration(date(\"2000-11-24\"), today())",
            "P25Y11M",
        ),
        // docs.camunda.io Expressions (Zeebe): "To store the current date … convert it to a
        // string".
        ("string(today())", "\"2026-11-23\""),
        ("string(now())", "\"2026-11-23T10:00:00Z\""),
    ]);
    // The value is exactly the environment's: a date-time in UTC.
    assert!(matches!(
        super::run("now()", &[], crate::BUDGET).map(|e| e.value),
        Ok(Value::DateTime(ref d)) if d == &super::now()
    ));
    assert_eq!(feel("now()"), feel("now()"));
}

/// Temporal values read from variables (a timer's due date from a mapping).
#[test]
fn temporal_variables() {
    let due = Value::Date(chrono::NaiveDate::from_ymd_opt(2026, 12, 1).expect("a date"));
    check_vars(
        &[("due", due), ("days", n(3))],
        &[
            ("due", "2026-12-01"),
            ("due - today()", "P8D"),
            ("due + duration(\"P1D\") * days", "2026-12-04"),
            ("due > today()", "true"),
            ("string(due)", "\"2026-12-01\""),
        ],
    );
}
