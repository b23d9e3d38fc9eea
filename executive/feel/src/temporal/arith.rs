//! Temporal arithmetic (DMN 1.3 Tables 57 and 58, Camunda's "temporal expressions"): `+` and
//! `-` between dates, times, dates and times and durations, durations times or divided by a
//! number, and a duration divided by one of its kind. `None` when FEEL does not define the
//! operation for the kinds given, or when the result does not fit (every step is checked).

use chrono::{Months, NaiveDate, NaiveDateTime, NaiveTime, TimeDelta};
use rust_decimal::Decimal;
use rust_decimal::prelude::ToPrimitive;

use super::{delta, instant, nanos_of, offset_delta, time_key, zones};
use crate::value::{DateTime, Time, Value};

/// `date + duration` for a days and time duration: the date of midnight plus it.
fn date_plus(d: NaiveDate, x: TimeDelta) -> Option<NaiveDate> {
    d.and_time(NaiveTime::MIN)
        .checked_add_signed(x)
        .map(|dt| dt.date())
}

/// A date moved by `months` calendar months, the day clamped to the end of the month.
fn shift_months(d: NaiveDate, months: i64) -> Option<NaiveDate> {
    let n = Months::new(u32::try_from(months.unsigned_abs()).ok()?);
    if months >= 0 {
        d.checked_add_months(n)
    } else {
        d.checked_sub_months(n)
    }
}

/// A local date-time moved by `months` calendar months, the time of day kept.
fn shift_local(local: NaiveDateTime, months: i64) -> Option<NaiveDateTime> {
    shift_months(local.date(), months).map(|d| d.and_time(local.time()))
}

/// A date and time with another local date-time, same zone.
fn moved(dt: &DateTime, local: NaiveDateTime) -> Value {
    Value::DateTime(DateTime {
        local,
        zone: dt.zone.clone(),
    })
}

/// A date and time plus a days and time duration. With a zone id, the instant moves and the
/// offset is the zone's at the new instant (java.time `ZonedDateTime.plus(Duration)`, which
/// feel-scala uses: `@"2026-03-28T12:00:00@Europe/Berlin" + @"P1D"` is
/// `2026-03-29T13:00:00@Europe/Berlin`, 24 hours later across the change to summer time);
/// otherwise the local date-time moves, the offset kept.
fn plus_time(dt: &DateTime, x: TimeDelta) -> Option<Value> {
    let local = dt.local.checked_add_signed(x)?;
    if let Some(zone) = &dt.zone
        && let (Some(tz), Some(id)) = (zones::rules(zone), zone.id.as_deref())
    {
        let utc = local.checked_sub_signed(offset_delta(zone))?;
        return zones::at_instant(utc, tz, id).map(Value::DateTime);
    }
    Some(moved(dt, local))
}

/// A date and time moved by `months` calendar months (the day clamped to the end of the
/// month, the time of day kept). With a zone id, the offset is the zone's at the new local
/// date-time, the old offset kept in an overlap if it is one of the two, a gap's time moved
/// forward (java.time `ZonedDateTime.plus(Period)`, via `ofLocal` with the old offset
/// preferred).
fn plus_months(dt: &DateTime, months: i64) -> Option<Value> {
    let local = shift_local(dt.local, months)?;
    if let Some(zone) = &dt.zone
        && let (Some(tz), Some(id)) = (zones::rules(zone), zone.id.as_deref())
    {
        return zones::at_local(local, tz, id, Some(zone.offset)).map(Value::DateTime);
    }
    Some(moved(dt, local))
}

/// A time plus a duration, wrapping around the day; same zone.
fn time_plus(t: &Time, x: TimeDelta) -> Value {
    Value::Time(Time {
        time: t.time.overflowing_add_signed(x).0,
        zone: t.zone.clone(),
    })
}

/// `-x`, checked.
fn neg(x: TimeDelta) -> Option<TimeDelta> {
    TimeDelta::zero().checked_sub(&x)
}

/// `a + b` for temporal operands: date, time or date and time plus a duration (either order;
/// a time only with days and time), and two durations of one kind.
pub(crate) fn add(a: &Value, b: &Value) -> Option<Value> {
    use Value as V;
    match (a, b) {
        (V::Date(d), V::DayTime(x)) | (V::DayTime(x), V::Date(d)) => date_plus(*d, *x).map(V::Date),
        (V::Date(d), V::YearMonth(m)) | (V::YearMonth(m), V::Date(d)) => {
            shift_months(*d, *m).map(V::Date)
        }
        (V::Time(t), V::DayTime(x)) | (V::DayTime(x), V::Time(t)) => Some(time_plus(t, *x)),
        (V::DateTime(dt), V::DayTime(x)) | (V::DayTime(x), V::DateTime(dt)) => plus_time(dt, *x),
        (V::DateTime(dt), V::YearMonth(m)) | (V::YearMonth(m), V::DateTime(dt)) => {
            plus_months(dt, *m)
        }
        (V::DayTime(x), V::DayTime(y)) => x.checked_add(y).map(V::DayTime),
        (V::YearMonth(x), V::YearMonth(y)) => x.checked_add(*y).map(V::YearMonth),
        _ => None,
    }
}

/// `a - b` for temporal operands: the days and time duration between two dates, two times or
/// two dates and times (both zoned or both local), a date, time or date and time minus a
/// duration, and two durations of one kind.
pub(crate) fn sub(a: &Value, b: &Value) -> Option<Value> {
    use Value as V;
    match (a, b) {
        (V::Date(x), V::Date(y)) => Some(V::DayTime(x.signed_duration_since(*y))),
        (V::Date(d), V::DayTime(x)) => date_plus(*d, neg(*x)?).map(V::Date),
        (V::Date(d), V::YearMonth(m)) => shift_months(*d, m.checked_neg()?).map(V::Date),
        (V::Time(x), V::Time(y)) => match (&x.zone, &y.zone) {
            (None, None) => Some(V::DayTime(x.time.signed_duration_since(y.time))),
            (Some(zx), Some(zy)) => delta(time_key(x, zx) - time_key(y, zy)).map(V::DayTime),
            _ => None,
        },
        (V::Time(t), V::DayTime(x)) => Some(time_plus(t, neg(*x)?)),
        (V::DateTime(x), V::DateTime(y)) => match (&x.zone, &y.zone) {
            (None, None) => Some(V::DayTime(x.local.signed_duration_since(y.local))),
            (Some(zx), Some(zy)) => delta(instant(x, zx) - instant(y, zy)).map(V::DayTime),
            _ => None,
        },
        (V::DateTime(dt), V::DayTime(x)) => plus_time(dt, neg(*x)?),
        (V::DateTime(dt), V::YearMonth(m)) => plus_months(dt, m.checked_neg()?),
        (V::DayTime(x), V::DayTime(y)) => x.checked_sub(y).map(V::DayTime),
        (V::YearMonth(x), V::YearMonth(y)) => x.checked_sub(*y).map(V::YearMonth),
        _ => None,
    }
}

/// A days and time duration as a decimal number of nanoseconds.
fn nanos_decimal(x: TimeDelta) -> Option<Decimal> {
    Decimal::try_from_i128_with_scale(nanos_of(x), 0).ok()
}

/// A decimal number of nanoseconds, cut towards zero, as a days and time duration.
fn from_nanos(n: Decimal) -> Option<Value> {
    delta(n.trunc().to_i128()?).map(Value::DayTime)
}

/// A decimal number of months, cut towards zero, as a years and months duration.
fn from_months(n: Decimal) -> Option<Value> {
    n.trunc().to_i64().map(Value::YearMonth)
}

/// `a * b`: a duration times a number, either order (exact, then cut to whole nanoseconds or
/// whole months towards zero).
pub(crate) fn mul(a: &Value, b: &Value) -> Option<Value> {
    use Value as V;
    match (a, b) {
        (V::DayTime(x), V::Number(n)) | (V::Number(n), V::DayTime(x)) => {
            from_nanos(nanos_decimal(*x)?.checked_mul(*n)?)
        }
        (V::YearMonth(m), V::Number(n)) | (V::Number(n), V::YearMonth(m)) => {
            from_months(Decimal::from(*m).checked_mul(*n)?)
        }
        _ => None,
    }
}

/// `a / b`: a duration divided by a non-zero number (cut towards zero as for [`mul`]), or by a
/// non-zero duration of its kind (an exact decimal number).
pub(crate) fn div(a: &Value, b: &Value) -> Option<Value> {
    use Value as V;
    match (a, b) {
        (V::DayTime(x), V::Number(n)) if !n.is_zero() => {
            from_nanos(nanos_decimal(*x)?.checked_div(*n)?)
        }
        (V::YearMonth(m), V::Number(n)) if !n.is_zero() => {
            from_months(Decimal::from(*m).checked_div(*n)?)
        }
        (V::DayTime(x), V::DayTime(y)) if !y.is_zero() => nanos_decimal(*x)?
            .checked_div(nanos_decimal(*y)?)
            .map(V::Number),
        (V::YearMonth(x), V::YearMonth(y)) if *y != 0 => Decimal::from(*x)
            .checked_div(Decimal::from(*y))
            .map(V::Number),
        _ => None,
    }
}
