//! Conversion built-ins: `string`, `number` (with separators) and `context` (from key-value
//! pairs). `decimal` is with the numeric functions, `string join` with the list functions.

use std::str::FromStr;

use rust_decimal::Decimal;

use super::{Entries, Fail, Out, null, take, text, wrong};
use crate::host::Host;
use crate::value::{Value, plain_text};

/// `string(from)`: the text of a value (strings as they are, other values as FEEL prints
/// them); null for null.
pub(super) fn string(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [from] = take(args);
    match from {
        Value::Null => null("`from` is null"),
        Value::String(s) => Ok(Value::String(s)),
        other => {
            host.spend(size(&other))?;
            let s = plain_text(&other);
            host.spend(s.len() / 64)?;
            Ok(Value::String(s))
        }
    }
}

/// The number of values inside `v` (itself, list items and context entries, recursively),
/// counted without recursion.
pub(super) fn size(v: &Value) -> usize {
    let mut count = 0usize;
    let mut stack = vec![v];
    while let Some(v) = stack.pop() {
        count = count.saturating_add(1);
        match v {
            Value::List(items) => stack.extend(items.iter()),
            Value::Context(c) => stack.extend(c.0.iter().map(|(_, v)| v)),
            _ => {}
        }
    }
    count
}

/// `number(from)`, `number(from, grouping separator)`,
/// `number(from, grouping separator, decimal separator)`: the number a text denotes. The
/// grouping separator is one of space, `,` and `.`; the decimal separator `,` or `.`; either
/// may be null (not used).
pub(super) fn number(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [from, grouping, decimal] = take(args);
    let from = text(&from, "from")?;
    let grouping = match &grouping {
        Value::Null => None,
        Value::String(g) if matches!(g.as_str(), " " | "," | ".") => Some(g.as_str()),
        Value::String(g) => {
            return null(format!(
                "the grouping separator must be \" \", \",\" or \".\", not {g:?}"
            ));
        }
        other => return Err(wrong("grouping separator", "a string", other)),
    };
    let decimal = match &decimal {
        Value::Null => None,
        Value::String(d) if matches!(d.as_str(), "," | ".") => Some(d.as_str()),
        Value::String(d) => {
            return null(format!(
                "the decimal separator must be \",\" or \".\", not {d:?}"
            ));
        }
        other => return Err(wrong("decimal separator", "a string", other)),
    };
    if n == 3 && grouping.is_some() && grouping == decimal {
        return null("the grouping and decimal separators must differ");
    }
    let mut digits = from.to_owned();
    if let Some(g) = grouping {
        digits = digits.replace(g, "");
    }
    if let Some(d) = decimal {
        digits = digits.replace(d, ".");
    }
    match parse_number(&digits) {
        Ok(n) => Ok(Value::Number(n)),
        Err(why) => null(format!("cannot read {from:?} as a number: {why}")),
    }
}

/// Reads a number the way Java's `BigDecimal(String)` does: an optional sign, digits with an
/// optional decimal point, an optional exponent (`1.5e3`). No spaces, no grouping.
pub(super) fn parse_number(s: &str) -> Result<Decimal, &'static str> {
    let (mantissa, exponent) = match s.find(['e', 'E']) {
        Some(i) => (&s[..i], Some(&s[i + 1..])),
        None => (s, None),
    };
    let (negative, unsigned) = match mantissa.as_bytes().first() {
        Some(b'-') => (true, &mantissa[1..]),
        Some(b'+') => (false, &mantissa[1..]),
        _ => (false, mantissa),
    };
    let (int, frac) = unsigned.split_once('.').unwrap_or((unsigned, ""));
    let all_digits = |t: &str| t.bytes().all(|b| b.is_ascii_digit());
    if (int.is_empty() && frac.is_empty()) || !all_digits(int) || !all_digits(frac) {
        return Err("not a number");
    }
    let plain = format!(
        "{}{}.{}",
        if negative { "-" } else { "" },
        if int.is_empty() { "0" } else { int },
        if frac.is_empty() { "0" } else { frac }
    );
    let value = Decimal::from_str(&plain).map_err(|_| "out of range")?;
    let Some(exponent) = exponent else {
        return Ok(value);
    };
    let (exp_negative, exp_digits) = match exponent.as_bytes().first() {
        Some(b'-') => (true, &exponent[1..]),
        Some(b'+') => (false, &exponent[1..]),
        _ => (false, exponent),
    };
    if exp_digits.is_empty() || !all_digits(exp_digits) {
        return Err("not a number");
    }
    if value.is_zero() {
        return Ok(Decimal::ZERO);
    }
    let exp_digits = exp_digits.trim_start_matches('0');
    // A value within range has at most 29 integer digits and 28 decimals, so any exponent
    // beyond 60 either overflows or leaves nothing.
    let mut exp: u32 = if exp_digits.len() > 3 {
        1000
    } else {
        exp_digits.parse().unwrap_or(1000)
    };
    let mut out = value;
    while exp > 0 {
        let step = exp.min(28);
        let factor =
            Decimal::try_from_i128_with_scale(10i128.pow(step), 0).map_err(|_| "out of range")?;
        out = if exp_negative {
            if out.is_zero() {
                return Ok(Decimal::ZERO);
            }
            out.checked_div(factor).ok_or("out of range")?
        } else {
            out.checked_mul(factor).ok_or("out of range")?
        };
        exp -= step;
    }
    Ok(out)
}

/// `context(entries)`: the context whose entries are the given `{key, value}` contexts (a
/// later entry with the same key replaces an earlier one).
pub(super) fn context(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [entries] = take(args);
    let entries = super::list(entries, "entries")?;
    host.spend(entries.len())?;
    let mut out = Entries::default();
    for (i, entry) in entries.into_iter().enumerate() {
        let Value::Context(mut c) = entry else {
            return null(format!(
                "entry {} must be a context {{key, value}}, not a {}",
                i + 1,
                entry.type_name()
            ));
        };
        let value = match c.0.iter().position(|(k, _)| k == "value") {
            Some(p) => c.0.swap_remove(p).1,
            None => return null(format!("entry {} has no `value`", i + 1)),
        };
        let key = match c.get("key") {
            Some(Value::String(k)) => k.clone(),
            Some(other) => {
                return Err(Fail::Null(format!(
                    "the key of entry {} must be a string, not a {}",
                    i + 1,
                    other.type_name()
                )));
            }
            None => return null(format!("entry {} has no `key`", i + 1)),
        };
        out.put(key, value);
    }
    Ok(Value::Context(out.done()))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, call_with, check, nulls};
    use super::parse_number;
    use crate::host::Stop;

    #[test]
    fn string_of_values() {
        check(&[
            ("string(1.1)", "\"1.1\""),
            ("string(1.10)", "\"1.1\""),
            ("string(-0)", "\"0\""),
            ("string(\"a\")", "\"a\""),
            ("string(true)", "\"true\""),
            ("string([1, \"a\", null])", r#""[1, \"a\", null]""#),
            ("string({a: 1})", "\"{a:1}\""),
            ("string([1..5))", "\"[1..5)\""),
            ("string(@not)", "\"function not\""),
        ]);
        nulls(&[("string(null)", "`from` is null")]);
    }

    #[test]
    fn string_spends_for_big_values() {
        let mut host = Mock::new(3);
        assert_eq!(
            call_with(&mut host, "string([1, 2, 3, 4])").err(),
            Some(Stop::Budget(3))
        );
    }

    #[test]
    fn number_reads_text() {
        check(&[
            ("number(\"1500.5\")", "1500.5"),
            ("number(\"-12\")", "-12"),
            ("number(\"+7\")", "7"),
            ("number(\".5\")", "0.5"),
            ("number(\"5.\")", "5"),
            ("number(\"1e3\")", "1000"),
            ("number(\"1.5E-2\")", "0.015"),
            ("number(\"0e999999\")", "0"),
            ("number(\"1,500\", \",\")", "1500"),
            ("number(\"1 500\", \" \")", "1500"),
            ("number(\"1,500.5\", \",\", \".\")", "1500.5"),
            ("number(\"1.000.000,01\", \".\", \",\")", "1000000.01"),
            ("number(\"1500,5\", null, \",\")", "1500.5"),
            ("number(\"1,500\", \",\", null)", "1500"),
            ("number(\"12\", null, null)", "12"),
        ]);
        nulls(&[
            ("number(\"abc\")", "cannot read \"abc\" as a number"),
            ("number(\"\")", "not a number"),
            ("number(\" 1\")", "not a number"),
            ("number(\"1_000\")", "not a number"),
            ("number(\"1e\")", "not a number"),
            ("number(\"1e99\")", "out of range"),
            (
                "number(\"99999999999999999999999999999999\")",
                "out of range",
            ),
            ("number(null)", "`from` is null"),
            ("number(5)", "`from` must be a string"),
            ("number(\"1,500\", \";\")", "grouping separator must be"),
            ("number(\"1,5\", \".\", \";\")", "decimal separator must be"),
            ("number(\"1,5\", \",\", \",\")", "must differ"),
            (
                "number(\"1,5\", 1, \",\")",
                "`grouping separator` must be a string",
            ),
        ]);
    }

    #[test]
    fn parse_number_edges() {
        assert!(parse_number("1e-40").is_ok_and(|n| n.is_zero()));
        assert!(parse_number("-").is_err());
        assert!(parse_number(".").is_err());
        assert!(parse_number("1.2.3").is_err());
        assert!(parse_number("1e+2").is_ok_and(|n| n == 100.into()));
        assert!(parse_number("١٢").is_err());
    }

    #[test]
    fn context_from_entries() {
        check(&[
            (
                "context([{key: \"a\", value: 1}, {key: \"b\", value: 2}])",
                "{a: 1, b: 2}",
            ),
            (
                "context([{key: \"a\", value: 1}, {key: \"a\", value: 2}])",
                "{a: 2}",
            ),
            (
                "context([{key: \"a\", value: null, extra: 3}])",
                "{a: null}",
            ),
            ("context([])", "{}"),
        ]);
        nulls(&[
            ("context(null)", "`entries` is null"),
            ("context([1])", "entry 1 must be a context"),
            ("context([{key: \"a\"}])", "entry 1 has no `value`"),
            ("context([{value: 1}])", "entry 1 has no `key`"),
            (
                "context([{key: 1, value: 1}])",
                "the key of entry 1 must be a string",
            ),
        ]);
    }
}
