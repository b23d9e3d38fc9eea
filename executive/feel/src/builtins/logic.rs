//! Boolean built-ins: `not`, `is defined`, `get or else`, `assert`.

use super::{Out, take, wrong};
use crate::host::{Host, Stop};
use crate::value::{Value, plain_text};

/// `not(negand)`: the negation of a boolean; null for anything else.
pub(super) fn not(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [negand] = take(args);
    match negand {
        Value::Bool(b) => Ok(Value::Bool(!b)),
        other => Err(wrong("negand", "a boolean", &other)),
    }
}

/// `is defined(value)`: whether the value is not null. Since feel-scala 1.17 (Camunda 8.3) a
/// missing variable or context entry evaluates to null, and Camunda's current documentation
/// makes `is defined(null)` false to match (a breaking change from 8.2, where a null variable
/// was "defined"): one rule for missing and null alike.
pub(super) fn is_defined(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value] = take(args);
    Ok(Value::Bool(!value.is_null()))
}

/// `get or else(value, default)`: `value` unless it is null, else `default`.
pub(super) fn get_or_else(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value, default] = take(args);
    Ok(if value.is_null() { default } else { value })
}

/// `assert(value, condition)` and `assert(value, condition, cause)`: `value` when `condition`
/// is true; otherwise the evaluation fails with `cause` (or a standard message).
pub(super) fn assert(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [value, condition, cause] = take(args);
    if matches!(condition, Value::Bool(true)) {
        return Ok(value);
    }
    let message = match cause {
        Value::Null if n < 3 => "assertion failed: the condition is not fulfilled".to_owned(),
        Value::Null => {
            "assertion failed: the condition is not fulfilled (the cause is null)".to_owned()
        }
        other => plain_text(&other),
    };
    if matches!(condition, Value::Bool(false) | Value::Null) {
        Err(Stop::Failed(message).into())
    } else {
        // A condition that is not a boolean is not fulfilled either; say why.
        let why = format!("{message} (the condition is a {})", condition.type_name());
        Err(Stop::Failed(why).into())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{call, check, nulls};
    use crate::host::Stop;
    use crate::value::Value;

    #[test]
    fn not_negates_booleans_only() {
        check(&[("not(true)", "false"), ("not(false)", "true")]);
        nulls(&[
            ("not(null)", "`negand` is null"),
            ("not(1)", "`negand` must be a boolean, not a number"),
            ("not(\"true\")", "not a string"),
        ]);
    }

    #[test]
    fn is_defined_of_a_value_is_true() {
        // Camunda 8.3+: `is defined(1)` is true, `is defined(null)` false.
        check(&[
            ("is defined(1)", "true"),
            ("is defined(null)", "false"),
            ("is defined([])", "true"),
        ]);
    }

    #[test]
    fn get_or_else_replaces_null_only() {
        check(&[
            ("get or else(\"this\", \"default\")", "\"this\""),
            ("get or else(null, \"default\")", "\"default\""),
            ("get or else(null, null)", "null"),
            ("get or else(false, true)", "false"),
            ("get or else([], 1)", "[]"),
        ]);
    }

    #[test]
    fn assert_returns_the_value_or_fails() {
        check(&[
            ("assert(\"value\", true)", "\"value\""),
            ("assert(null, true)", "null"),
            ("assert(5, true, \"never\")", "5"),
        ]);
        let failed = |c: &str| match call(c).0 {
            Err(Stop::Failed(m)) => m,
            other => panic!("{c}: want a failure, got {other:?}"),
        };
        assert!(failed("assert(-1, false)").contains("the condition is not fulfilled"));
        assert!(failed("assert(-1, null)").contains("not fulfilled"));
        assert!(failed("assert(-1, \"yes\")").contains("the condition is a string"));
        assert_eq!(
            failed("assert(-1, false, \"The value must be positive\")"),
            "The value must be positive"
        );
        assert!(failed("assert(-1, false, null)").contains("not fulfilled"));
        assert_eq!(failed("assert(-1, false, 42)"), "42");
        // Not a null: the evaluation stops, nothing is recorded.
        let (out, host) = call("assert(1, false)");
        assert!(out.is_err() && host.notes.is_empty());
        assert!(matches!(call("assert(1, true)").0, Ok(Value::Number(_))));
    }
}
