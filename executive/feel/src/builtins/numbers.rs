//! Numeric built-ins: `decimal` (with feel-scala's optional rounding mode), `floor`, `ceiling`,
//! the `round …` family (scale optional, default 0, as docs.camunda.io documents them), `abs`,
//! `modulo`, `sqrt`, `log`, `exp`, `odd`, `even`.
//!
//! Rounding works on the decimal's digits exactly, for any scale FEEL allows (−6111 to 6176):
//! a scale beyond the 28 decimals a number can have leaves it as it is, a negative scale rounds
//! to tens, hundreds, …; a result that does not fit is null. `sqrt`, `log` and `exp` are
//! computed to 28 significant digits (feel-scala uses doubles: 16 digits).

use rust_decimal::prelude::{FromPrimitive, ToPrimitive};
use rust_decimal::{Decimal, MathematicalOps};

use super::{Out, null, number, take, text};
use crate::host::Host;
use crate::value::Value;

/// How to round the digits that are dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// To the nearest, ties to the even neighbour (`decimal`).
    HalfEven,
    /// Towards −∞ (`floor`).
    Floor,
    /// Towards +∞ (`ceiling`).
    Ceiling,
    /// Away from zero (`round up`).
    Up,
    /// Towards zero (`round down`).
    Down,
    /// To the nearest, ties away from zero (`round half up`).
    HalfUp,
    /// To the nearest, ties towards zero (`round half down`).
    HalfDown,
}

/// `n` rounded to `scale` decimals (negative: to a multiple of 10^−scale) by `mode`; `None` if
/// the result does not fit a decimal.
fn round(n: Decimal, scale: i64, mode: Mode) -> Option<Decimal> {
    let s = i64::from(n.scale());
    if scale >= s {
        return Some(n);
    }
    // Digits to drop: at least 1. Beyond 38 every digit of the mantissa (< 10^29) is dropped
    // and the dropped part is below half of the unit, as it is at 38.
    let drop = u32::try_from((s - scale).min(38)).ok()?;
    let m = n.mantissa();
    let negative = m < 0;
    let a = m.unsigned_abs();
    let p = 10u128.pow(drop);
    let (q, r) = (a / p, a % p);
    let twice = r * 2;
    let up = match mode {
        Mode::Down => false,
        Mode::Up => r != 0,
        Mode::Floor => negative && r != 0,
        Mode::Ceiling => !negative && r != 0,
        Mode::HalfUp => twice >= p,
        Mode::HalfDown => twice > p,
        Mode::HalfEven => twice > p || (twice == p && q % 2 == 1),
    };
    let q = q + u128::from(up);
    let q = i128::try_from(q).ok()?;
    let q = if negative { -q } else { q };
    if scale >= 0 {
        Decimal::try_from_i128_with_scale(q, u32::try_from(scale).ok()?).ok()
    } else if q == 0 {
        Some(Decimal::ZERO)
    } else {
        let k = u32::try_from(-scale).ok().filter(|&k| k <= 38)?;
        Decimal::try_from_i128_with_scale(q.checked_mul(10i128.checked_pow(k)?)?, 0).ok()
    }
}

/// A `scale` argument: a whole number from −6111 to 6176 (FEEL's range).
fn scale(v: &Value) -> Result<i64, super::Fail> {
    let s = number(v, "scale")?;
    if !s.fract().is_zero() {
        return null(format!("the scale must be a whole number, not {s}"));
    }
    match s.to_i64() {
        Some(s) if (-6111..=6176).contains(&s) => Ok(s),
        _ => null(format!("the scale {s} is outside -6111..6176")),
    }
}

/// `n` rounded by `mode`, to the `scale` argument if given, else to a whole number.
fn rounded(args: Vec<Value>, mode: Mode) -> Out {
    let n_args = args.len();
    let [n, s] = take(args);
    let n = number(&n, "n")?;
    let s = if n_args < 2 { 0 } else { scale(&s)? };
    match round(n, s, mode) {
        Some(r) => Ok(Value::Number(r)),
        None => null("the result is out of range"),
    }
}

/// The rounding modes `decimal(n, scale, mode)` accepts: the names of Java's `RoundingMode`.
const MODES: &str = "UP, DOWN, CEILING, FLOOR, HALF_UP, HALF_DOWN, HALF_EVEN, UNNECESSARY";

/// `decimal(n, scale)`: rounded half to even. `decimal(n, scale, mode)` (feel-scala; the
/// docs' example is `decimal(2.5, 0, "half_up")` = 3): rounded by a `java.math.RoundingMode`
/// named in any case, one of [`MODES`]; `UNNECESSARY` gives `n` if it has no more decimals
/// than `scale`, and null if it would have to be rounded (Java throws).
pub(super) fn decimal(_: &mut dyn Host, args: Vec<Value>) -> Out {
    if args.len() < 3 {
        return rounded(args, Mode::HalfEven);
    }
    let [n, s, mode] = take(args);
    let n = number(&n, "n")?;
    let s = scale(&s)?;
    let name = text(&mode, "mode")?;
    let mode = match name.to_uppercase().as_str() {
        "UP" => Some(Mode::Up),
        "DOWN" => Some(Mode::Down),
        "CEILING" => Some(Mode::Ceiling),
        "FLOOR" => Some(Mode::Floor),
        "HALF_UP" => Some(Mode::HalfUp),
        "HALF_DOWN" => Some(Mode::HalfDown),
        "HALF_EVEN" => Some(Mode::HalfEven),
        "UNNECESSARY" => None,
        _ => return null(format!("the rounding mode {name:?} is not one of {MODES}")),
    };
    let Some(mode) = mode else {
        return match round(n, s, Mode::Down) {
            Some(r) if r == n => Ok(Value::Number(n)),
            _ => null(format!(
                "rounding mode UNNECESSARY, but {n} has more than {s} decimals"
            )),
        };
    };
    match round(n, s, mode) {
        Some(r) => Ok(Value::Number(r)),
        None => null("the result is out of range"),
    }
}

/// `floor(n)`, `floor(n, scale)`.
pub(super) fn floor(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::Floor)
}

/// `ceiling(n)`, `ceiling(n, scale)`.
pub(super) fn ceiling(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::Ceiling)
}

/// `round up(n)`, `round up(n, scale)`: away from zero.
pub(super) fn round_up(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::Up)
}

/// `round down(n)`, `round down(n, scale)`: towards zero.
pub(super) fn round_down(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::Down)
}

/// `round half up(n)`, `round half up(n, scale)`: to the nearest, ties away from zero.
pub(super) fn round_half_up(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::HalfUp)
}

/// `round half down(n)`, `round half down(n, scale)`: to the nearest, ties towards zero.
pub(super) fn round_half_down(_: &mut dyn Host, args: Vec<Value>) -> Out {
    rounded(args, Mode::HalfDown)
}

/// `abs(n)`: the absolute value of a number, or of a duration (through the temporal module).
pub(super) fn abs(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    match n {
        Value::Number(n) => Ok(Value::Number(n.abs())),
        other if other.is_temporal() => match crate::temporal::abs(&other) {
            Some(v) => Ok(v),
            None if matches!(other, Value::DayTime(_) | Value::YearMonth(_)) => {
                null("the duration is out of range")
            }
            None => Err(super::wrong("n", "a number or a duration", &other)),
        },
        other => Err(super::wrong("n", "a number or a duration", &other)),
    }
}

/// `modulo(dividend, divisor)`: the remainder with the sign of the divisor
/// (`modulo(-12, 5)` is 3); null for a zero divisor.
pub(super) fn modulo(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [dividend, divisor] = take(args);
    let a = number(&dividend, "dividend")?;
    let b = number(&divisor, "divisor")?;
    if b.is_zero() {
        return null("division by zero");
    }
    let Some(r) = a.checked_rem(b) else {
        return null("the result is out of range");
    };
    let r = if !r.is_zero() && r.is_sign_negative() != b.is_sign_negative() {
        match r.checked_add(b) {
            Some(r) => r,
            None => return null("the result is out of range"),
        }
    } else {
        r
    };
    Ok(Value::Number(r))
}

/// The square root by Newton's method from a floating-point estimate, to 28 digits; `None`
/// for a negative number. Exact for exact squares.
pub(super) fn square_root(n: Decimal) -> Option<Decimal> {
    if n.is_zero() {
        return Some(Decimal::ZERO);
    }
    if n.is_sign_negative() {
        return None;
    }
    let guess = n.to_f64().map(f64::sqrt).and_then(Decimal::from_f64);
    let mut x = match guess {
        Some(g) if g > Decimal::ZERO => g,
        _ => n,
    };
    let mut previous = Decimal::ZERO;
    for _ in 0..100 {
        let next = x
            .checked_add(n.checked_div(x)?)?
            .checked_div(Decimal::TWO)?;
        if next == x || next == previous {
            return Some(next.min(x));
        }
        previous = x;
        x = next;
    }
    Some(x)
}

/// `sqrt(number)`: null for a negative number.
pub(super) fn sqrt(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    let n = number(&n, "number")?;
    match square_root(n) {
        Some(r) => Ok(Value::Number(r)),
        None => null(format!("no square root of the negative number {n}")),
    }
}

/// `log(number)`: the natural logarithm; null for zero and negative numbers.
pub(super) fn log(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    let n = number(&n, "number")?;
    if n <= Decimal::ZERO {
        return null(format!("no logarithm of {n} (the number must be above 0)"));
    }
    match n.checked_ln() {
        Some(r) => Ok(Value::Number(r)),
        None => null("the result is out of range"),
    }
}

/// `exp(number)`: e to the power of the number; null when that is too big, 0 when too small.
pub(super) fn exp(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    let n = number(&n, "number")?;
    match n.checked_exp() {
        Some(r) => Ok(Value::Number(r)),
        None if n.is_sign_negative() => Ok(Value::Number(Decimal::ZERO)),
        None => null(format!("exp({n}) is out of range")),
    }
}

/// `odd(number)`: whether a whole number is odd (false for fractions, as feel-scala).
pub(super) fn odd(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    let n = number(&n, "number")?;
    Ok(Value::Bool(
        n.checked_rem(Decimal::TWO)
            .is_some_and(|r| r.abs() == Decimal::ONE),
    ))
}

/// `even(number)`: whether a whole number is even (false for fractions, as feel-scala).
pub(super) fn even(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [n] = take(args);
    let n = number(&n, "number")?;
    Ok(Value::Bool(
        n.checked_rem(Decimal::TWO).is_some_and(|r| r.is_zero()),
    ))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{check, nulls};
    use super::{Mode, round, square_root};
    use rust_decimal::Decimal;

    #[test]
    fn decimal_rounds_half_even() {
        check(&[
            ("decimal(0.333333, 2)", "0.33"),
            ("decimal(1.5, 0)", "2"),
            ("decimal(2.5, 0)", "2"),
            ("decimal(-2.5, 0)", "-2"),
            ("decimal(-1.5, 0)", "-2"),
            ("decimal(1.125, 2)", "1.12"),
            ("decimal(1.135, 2)", "1.14"),
            ("decimal(1.1351, 2)", "1.14"),
            ("decimal(7.5, 30)", "7.5"),
            ("decimal(7.5, 6176)", "7.5"),
            ("decimal(125, -1)", "120"),
            ("decimal(135, -1)", "140"),
            ("decimal(12345, -3)", "12000"),
            ("decimal(5, -6111)", "0"),
            ("decimal(0, 2)", "0"),
        ]);
        nulls(&[
            (
                "decimal(1, 2.5)",
                "the scale must be a whole number, not 2.5",
            ),
            ("decimal(1, 6177)", "the scale 6177 is outside -6111..6176"),
            ("decimal(1, -6112)", "outside"),
            ("decimal(null, 2)", "`n` is null"),
            ("decimal(1, null)", "`scale` is null"),
            ("decimal(\"1\", 2)", "`n` must be a number, not a string"),
            (
                "decimal(79228162514264337593543950335, -28)",
                "the result is out of range",
            ),
        ]);
    }

    #[test]
    fn decimal_with_a_rounding_mode() {
        check(&[
            ("decimal(2.5, 0, \"half_up\")", "3"),
            ("decimal(2.5, 0, \"HALF_UP\")", "3"),
            ("decimal(2.5, 0, \"Half_Down\")", "2"),
            ("decimal(2.5, 0, \"half_even\")", "2"),
            ("decimal(3.5, 0, \"half_even\")", "4"),
            ("decimal(-2.5, 0, \"half_up\")", "-3"),
            ("decimal(1.121, 2, \"up\")", "1.13"),
            ("decimal(-1.129, 2, \"down\")", "-1.12"),
            ("decimal(-1.121, 2, \"ceiling\")", "-1.12"),
            ("decimal(-1.121, 2, \"floor\")", "-1.13"),
            ("decimal(1.5, 1, \"unnecessary\")", "1.5"),
            ("decimal(1.5, 3, \"unnecessary\")", "1.5"),
            ("decimal(150, -1, \"unnecessary\")", "150"),
            ("decimal(0.333, 2, \"half_even\")", "0.33"),
            ("decimal(125, -1, \"half_up\")", "130"),
        ]);
        nulls(&[
            (
                "decimal(1.55, 1, \"unnecessary\")",
                "rounding mode UNNECESSARY, but 1.55 has more than 1 decimals",
            ),
            ("decimal(155, -1, \"UNNECESSARY\")", "more than -1 decimals"),
            (
                "decimal(1.5, 0, \"half\")",
                "decimal: the rounding mode \"half\" is not one of UP, DOWN, CEILING, FLOOR, HALF_UP, HALF_DOWN, HALF_EVEN, UNNECESSARY",
            ),
            ("decimal(1.5, 0, \"half up\")", "is not one of"),
            ("decimal(1.5, 0, \"\")", "is not one of"),
            ("decimal(1.5, 0, null)", "`mode` is null"),
            (
                "decimal(1.5, 0, 1)",
                "`mode` must be a string, not a number",
            ),
            ("decimal(null, 0, \"up\")", "`n` is null"),
            ("decimal(1.5, null, \"up\")", "`scale` is null"),
            ("decimal(1.5, 0.5, \"up\")", "whole number"),
            (
                "decimal(79228162514264337593543950335, -1, \"up\")",
                "the result is out of range",
            ),
        ]);
    }

    #[test]
    fn floor_and_ceiling() {
        check(&[
            ("floor(1.5)", "1"),
            ("floor(-1.5)", "-2"),
            ("floor(-1.56, 1)", "-1.6"),
            ("floor(1.56, 1)", "1.5"),
            ("floor(5)", "5"),
            ("floor(-0.5)", "-1"),
            ("floor(199, -2)", "100"),
            ("ceiling(1.5)", "2"),
            ("ceiling(-1.5)", "-1"),
            ("ceiling(-1.56, 1)", "-1.5"),
            ("ceiling(1.56, 1)", "1.6"),
            ("ceiling(-0.5)", "0"),
            ("ceiling(101, -2)", "200"),
        ]);
        nulls(&[
            ("floor(null)", "`n` is null"),
            ("ceiling(\"1.5\")", "must be a number"),
            ("floor(1.5, 0.5)", "whole number"),
        ]);
    }

    #[test]
    fn round_family() {
        check(&[
            ("round up(5.5, 0)", "6"),
            ("round up(-5.5, 0)", "-6"),
            ("round up(1.121, 2)", "1.13"),
            ("round up(-1.126, 2)", "-1.13"),
            ("round up(1.12, 2)", "1.12"),
            ("round down(5.5, 0)", "5"),
            ("round down(-5.5, 0)", "-5"),
            ("round down(1.121, 2)", "1.12"),
            ("round down(-1.126, 2)", "-1.12"),
            ("round half up(5.5, 0)", "6"),
            ("round half up(-5.5, 0)", "-6"),
            ("round half up(1.121, 2)", "1.12"),
            ("round half up(-1.126, 2)", "-1.13"),
            ("round half up(1.125, 2)", "1.13"),
            ("round half down(5.5, 0)", "5"),
            ("round half down(-5.5, 0)", "-5"),
            ("round half down(1.121, 2)", "1.12"),
            ("round half down(-1.126, 2)", "-1.13"),
            ("round half down(1.125, 2)", "1.12"),
            ("round up(5, -1)", "10"),
            ("round down(59, -1)", "50"),
            // The scale is optional (default 0), as docs.camunda.io documents it.
            ("round up(5.5)", "6"),
            ("round up(-5.5)", "-6"),
            ("round up(5)", "5"),
            ("round down(5.5)", "5"),
            ("round down(-5.5)", "-5"),
            ("round half up(5.5)", "6"),
            ("round half up(-5.5)", "-6"),
            ("round half up(5.4)", "5"),
            ("round half down(5.5)", "5"),
            ("round half down(-5.5)", "-5"),
            ("round half down(5.6)", "6"),
        ]);
        nulls(&[
            ("round up(null, 0)", "`n` is null"),
            ("round down(1, null)", "`scale` is null"),
            ("round half up(1, \"2\")", "`scale` must be a number"),
            ("round half down(1, 1.5)", "whole number"),
            ("round up(5, -40)", "out of range"),
            ("round up(null)", "round up: `n` is null"),
            ("round down(\"5.5\")", "`n` must be a number, not a string"),
            ("round half up([1])", "`n` must be a number, not a list"),
            ("round half down(null)", "`n` is null"),
        ]);
    }

    #[test]
    fn rounding_at_the_limits() {
        let max = Decimal::MAX;
        assert_eq!(round(max, 0, Mode::Up), Some(max));
        assert_eq!(round(max, -1, Mode::Up), None);
        assert_eq!(
            round(max, -1, Mode::Down),
            Decimal::from_str_exact("79228162514264337593543950330").ok()
        );
        assert_eq!(round(Decimal::MIN, -29, Mode::Floor), None);
        assert_eq!(round(Decimal::MIN, -29, Mode::Ceiling), Some(Decimal::ZERO));
        assert_eq!(round(Decimal::MIN, -30, Mode::HalfUp), Some(Decimal::ZERO));
        let tiny = Decimal::new(1, 28);
        assert_eq!(round(tiny, 27, Mode::Up), Some(Decimal::new(1, 27)));
        assert_eq!(round(tiny, 27, Mode::HalfEven), Some(Decimal::ZERO));
        assert_eq!(round(-tiny, 0, Mode::Floor), Some(Decimal::NEGATIVE_ONE));
    }

    #[test]
    fn abs_and_modulo() {
        check(&[
            ("abs(10)", "10"),
            ("abs(-10)", "10"),
            ("abs(-1.5)", "1.5"),
            ("abs(0)", "0"),
            ("modulo(12, 5)", "2"),
            ("modulo(-12, 5)", "3"),
            ("modulo(12, -5)", "-3"),
            ("modulo(-12, -5)", "-2"),
            ("modulo(10.1, 4.5)", "1.1"),
            ("modulo(-10.1, 4.5)", "3.4"),
            ("modulo(10.1, -4.5)", "-3.4"),
            ("modulo(-10.1, -4.5)", "-1.1"),
            ("modulo(10, 5)", "0"),
            ("modulo(-10, 5)", "0"),
            (
                "modulo(79228162514264337593543950335, -79228162514264337593543950335)",
                "0",
            ),
            (
                "modulo(-1, 79228162514264337593543950335)",
                "79228162514264337593543950334",
            ),
        ]);
        nulls(&[
            ("abs(null)", "`n` is null"),
            (
                "abs(\"-1\")",
                "`n` must be a number or a duration, not a string",
            ),
            ("modulo(12, 0)", "division by zero"),
            ("modulo(null, 5)", "`dividend` is null"),
            ("modulo(5, null)", "`divisor` is null"),
        ]);
    }

    #[test]
    fn roots_logs_and_powers() {
        check(&[
            ("sqrt(16)", "4"),
            ("sqrt(0)", "0"),
            ("sqrt(2)", "1.4142135623730950488016887242"),
            ("sqrt(0.0001)", "0.01"),
            ("sqrt(79228162514264337593543950335)", "281474976710656"),
            ("log(1)", "0"),
            ("exp(0)", "1"),
            ("exp(-1000)", "0"),
        ]);
        nulls(&[
            ("sqrt(-1)", "no square root of the negative number -1"),
            ("sqrt(null)", "`number` is null"),
            ("log(0)", "no logarithm of 0"),
            ("log(-1)", "must be above 0"),
            ("log(\"e\")", "must be a number"),
            ("exp(1000)", "exp(1000) is out of range"),
            ("exp(null)", "`number` is null"),
        ]);
    }

    #[test]
    fn log_and_exp_are_close() {
        // ln(10) = 2.30258509299404568401799145468…, e^5 = 148.413159102576603421115580040…
        for (c, want) in [
            ("log(10)", "2.3025850929940456840179914547"),
            ("exp(5)", "148.41315910257660342111558004"),
            ("log(2.718281828459045235360287471352)", "1"),
            ("exp(-1)", "0.3678794411714423215955237702"),
        ] {
            let (out, _) = super::super::testing::call(c);
            let got = match out {
                Ok(crate::value::Value::Number(n)) => n,
                other => panic!("{c}: {other:?}"),
            };
            let want = super::super::conversion::parse_number(want).unwrap_or_default();
            assert!((got - want).abs() <= Decimal::new(1, 25), "{c} = {got}");
        }
    }

    #[test]
    fn square_root_is_close() {
        for text in [
            "2",
            "3",
            "0.5",
            "1e-20",
            "12345678901234567890",
            "0.0000000000000000000000000001",
        ] {
            let n = super::super::conversion::parse_number(text).unwrap_or_default();
            let r = square_root(n).unwrap_or_default();
            let err = (r * r - n).abs();
            assert!(
                err <= n * Decimal::new(1, 26) + Decimal::new(1, 28),
                "sqrt({text}) = {r}"
            );
        }
    }

    #[test]
    fn odd_and_even() {
        check(&[
            ("odd(5)", "true"),
            ("odd(-5)", "true"),
            ("odd(2)", "false"),
            ("odd(0)", "false"),
            ("odd(1.5)", "false"),
            ("even(5)", "false"),
            ("even(-4)", "true"),
            ("even(0)", "true"),
            ("even(2.0)", "true"),
            ("even(2.5)", "false"),
        ]);
        nulls(&[
            ("odd(null)", "`number` is null"),
            ("even(\"2\")", "must be a number"),
        ]);
    }
}
