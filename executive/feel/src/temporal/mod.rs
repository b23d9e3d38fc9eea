//! FEEL's temporal values: dates, times, dates and times, days-and-time and years-and-months
//! durations. Equality and ordering, the text form feel-scala prints, `@"…"` literals,
//! properties (`.year`, `.time offset`, …), arithmetic and the temporal built-in functions.
//!
//! Zones are fixed offsets (`+01:00`, `Z`) or zone ids of the IANA tz database (`@UTC`,
//! `@Europe/Paris`; chrono-tz's copy, tzdata 2025b), as feel-scala's `java.time.ZoneId`. A value
//! with a zone id keeps the id (printed `…@Europe/Paris`, given by `.timezone`) and the offset
//! it has (`.time offset`); an unknown id (`@Mars/Olympus`) is refused, naming it.
//!
//! Semantic choices (DMN 1.3 clauses; where feel-scala differs, it is said):
//! - A time or date and time with a zone and one without are not comparable: `=`, `<` and `-`
//!   between them have no value (null). feel-scala does the same ("Can't compare"); DMN 1.3
//!   §10.3.2.3.4 (time) and §10.3.2.3.6 (date-time) leave the local one's zone unknown.
//! - Two zoned values are equal when they are the same instant (DMN 1.3 §10.3.2.3.6, value_dt;
//!   §10.3.2.3.4, value_t: seconds since midnight UTC, not wrapped to the day), so
//!   `@"10:00:00+01:00" = @"09:00:00Z"`. feel-scala's `=` compares offsets too (Java
//!   `equals`) while its `<` compares instants; here both compare instants.
//! - `time - time` is signed (DMN 1.3 Table 57); feel-scala gives the absolute difference for
//!   zoned times.
//! - Durations times or divided by a number are exact, then cut to whole nanoseconds (days and
//!   time) or whole months (years and months), towards zero (DMN 1.3 Table 57: value × number;
//!   feel-scala first cuts the number to an integer). A duration divided by a duration of the
//!   same kind is an exact decimal (feel-scala divides whole milliseconds).
//! - Years and months added to a date move by calendar months, clamped to the end of the month
//!   (`@"2024-01-31" + @"P1M"` is `2024-02-29`; java.time's `plusMonths`).
//! - A date plus a days and time duration is the date of midnight plus it (feel-scala; DMN 1.3
//!   §10.3.2.3.5 takes a date as its midnight): `@"2026-01-01" + @"PT36H"` is `2026-01-02`.
//! - `date - date and time` and the like have no value (feel-scala; DMN 1.5 would convert the
//!   date to midnight UTC).
//! - A date and time with a zone id has the zone's offset at its local date-time, daylight
//!   saving included (java.time `ZonedDateTime.of`, which feel-scala uses): a local time in a
//!   gap moves forward by the gap (`@"2026-03-29T02:30:00@Europe/Berlin"` is 03:30, +02:00); in
//!   an overlap the earlier offset is taken (`2026-10-25T02:30:00@Europe/Berlin` is +02:00),
//!   unless an offset is written before the id in brackets (`…02:30:00+01:00[Europe/Berlin]`),
//!   which must then be one of the zone's offsets there. Such a value prints with the id only,
//!   so an overlap's second hour reads back as the first (as in feel-scala). The database lists
//!   changes up to 2099; later dates keep the last offset (java.time goes on switching).
//! - Days and time durations move a zoned date and time's instant, the offset then the zone's
//!   at the new instant (java.time `ZonedDateTime.plus(Duration)`, as feel-scala adds them):
//!   `@"2026-03-28T12:00:00@Europe/Berlin" + @"P1D"` is `2026-03-29T13:00:00@Europe/Berlin`.
//!   Years and months move the local date-time, then take the zone's offset there, keeping the
//!   old offset in an overlap when it is one of the two (`plus(Period)`, i.e. `ofLocal` with
//!   the old offset preferred). With a fixed offset both keep the offset.
//! - A time of day with a zone id (`@"10:00:00@Europe/Paris"`) has the zone's standard offset
//!   (feel-scala: `getStandardOffset(Instant.now)`; with no clock here, under the database's
//!   latest rules, read at 2100-01-01T00:00:00Z; a negative daylight saving such as
//!   Europe/Dublin's winter counts as standard, as in java.time's data), so
//!   `@"10:00:00@Europe/Paris" = @"09:00:00Z"` all year. `time(date and time)` keeps the date
//!   and time's offset (feel-scala's `ZonedTime.of`), and `date and time(date, time)` with a
//!   zone id takes the zone's offset at that date (`ZonedTime.withDate`).

mod arith;
mod functions;
mod parse;
#[cfg(test)]
mod tests;
mod zones;

use std::cmp::Ordering;
use std::fmt::Write as _;

use chrono::{Datelike, NaiveDate, NaiveTime, TimeDelta, Timelike};

use crate::value::{DateTime, Time, Value, Zone};

pub(crate) use arith::{add, div, mul, sub};
pub(crate) use functions::TEMPORAL;

/// Nanoseconds in a second.
const NANOS: i128 = 1_000_000_000;

/// The number of nanoseconds in `d`.
fn nanos_of(d: TimeDelta) -> i128 {
    i128::from(d.num_seconds()) * NANOS + i128::from(d.subsec_nanos())
}

/// The duration of `nanos` nanoseconds, if it fits.
fn delta(nanos: i128) -> Option<TimeDelta> {
    let seconds = i64::try_from(nanos.div_euclid(NANOS)).ok()?;
    let rest = u32::try_from(nanos.rem_euclid(NANOS)).ok()?;
    TimeDelta::new(seconds, rest)
}

/// The offset of a zone, as a duration.
fn offset_delta(zone: &Zone) -> TimeDelta {
    TimeDelta::try_seconds(i64::from(zone.offset.local_minus_utc())).unwrap_or_default()
}

/// Nanoseconds since midnight of a time as written (a leap second counts as the second before).
fn time_nanos(t: NaiveTime) -> i128 {
    i128::from(t.num_seconds_from_midnight()) * NANOS + i128::from(t.nanosecond() % 1_000_000_000)
}

/// A zoned time's place on the UTC clock: nanoseconds since midnight UTC, not wrapped to the
/// day (DMN 1.3 value_t), so `10:00:00+01:00` and `09:00:00Z` have the same key.
fn time_key(t: &Time, zone: &Zone) -> i128 {
    time_nanos(t.time) - i128::from(zone.offset.local_minus_utc()) * NANOS
}

/// Nanoseconds since 1970-01-01T00:00:00 of a local date-time, taken as UTC.
fn local_nanos(local: chrono::NaiveDateTime) -> i128 {
    i128::from(local.and_utc().timestamp()) * NANOS + i128::from(local.nanosecond() % 1_000_000_000)
}

/// A zoned date-time's instant: nanoseconds since the Unix epoch.
fn instant(dt: &DateTime, zone: &Zone) -> i128 {
    local_nanos(dt.local) - i128::from(zone.offset.local_minus_utc()) * NANOS
}

/// FEEL equality of two temporal values; `None` when the kinds cannot be compared (a date and a
/// duration, a zoned and a local time or date and time).
pub(crate) fn eq(a: &Value, b: &Value) -> Option<bool> {
    compare_same(a, b).map(Ordering::is_eq)
}

/// FEEL ordering of two temporal values of the same kind; `None` otherwise (see [`eq`]).
pub(crate) fn compare(a: &Value, b: &Value) -> Option<Ordering> {
    compare_same(a, b)
}

/// The order of two values of one temporal kind.
fn compare_same(a: &Value, b: &Value) -> Option<Ordering> {
    match (a, b) {
        (Value::Date(x), Value::Date(y)) => Some(x.cmp(y)),
        (Value::Time(x), Value::Time(y)) => match (&x.zone, &y.zone) {
            (None, None) => Some(x.time.cmp(&y.time)),
            (Some(zx), Some(zy)) => Some(time_key(x, zx).cmp(&time_key(y, zy))),
            _ => None,
        },
        (Value::DateTime(x), Value::DateTime(y)) => match (&x.zone, &y.zone) {
            (None, None) => Some(x.local.cmp(&y.local)),
            (Some(zx), Some(zy)) => Some(instant(x, zx).cmp(&instant(y, zy))),
            _ => None,
        },
        (Value::DayTime(x), Value::DayTime(y)) => Some(x.cmp(y)),
        (Value::YearMonth(x), Value::YearMonth(y)) => Some(x.cmp(y)),
        _ => None,
    }
}

/// Writes a date: `2026-11-23`, `-0044-03-15`, `10000-01-01`.
fn write_date(out: &mut String, d: NaiveDate) {
    let year = d.year();
    if year < 0 {
        let _ = write!(out, "-{:04}", year.unsigned_abs());
    } else {
        let _ = write!(out, "{year:04}");
    }
    let _ = write!(out, "-{:02}-{:02}", d.month(), d.day());
}

/// Writes `.fffffffff` without trailing zeros, or nothing for whole seconds.
fn write_fraction(out: &mut String, nanos: u32) {
    if nanos > 0 {
        let digits = format!("{nanos:09}");
        out.push('.');
        out.push_str(digits.trim_end_matches('0'));
    }
}

/// Writes a time of day: `10:00:00`, `10:00:00.5`.
fn write_time(out: &mut String, t: NaiveTime) {
    let _ = write!(out, "{:02}:{:02}:{:02}", t.hour(), t.minute(), t.second());
    write_fraction(out, t.nanosecond() % 1_000_000_000);
}

/// Writes a zone suffix: `@Europe/Paris`, `@UTC`, `Z` (offset 0 without an id), `+01:00`, `-05:30`.
fn write_zone(out: &mut String, zone: Option<&Zone>) {
    let Some(zone) = zone else { return };
    if let Some(id) = &zone.id {
        out.push('@');
        out.push_str(id);
        return;
    }
    let seconds = zone.offset.local_minus_utc();
    if seconds == 0 {
        out.push('Z');
        return;
    }
    let (sign, abs) = (if seconds < 0 { '-' } else { '+' }, seconds.unsigned_abs());
    let _ = write!(out, "{sign}{:02}:{:02}", abs / 3600, abs / 60 % 60);
    if abs % 60 != 0 {
        let _ = write!(out, ":{:02}", abs % 60);
    }
}

/// Writes a days and time duration: `P1DT2H3M4.5S`, `PT0S`, `-PT1H`.
fn write_day_time(out: &mut String, d: TimeDelta) {
    if d < TimeDelta::zero() {
        out.push('-');
    }
    let d = d.abs();
    let (seconds, nanos) = (
        d.num_seconds().unsigned_abs(),
        d.subsec_nanos().unsigned_abs(),
    );
    let (days, hours, minutes, secs) = (
        seconds / 86_400,
        seconds / 3_600 % 24,
        seconds / 60 % 60,
        seconds % 60,
    );
    out.push('P');
    if days > 0 {
        let _ = write!(out, "{days}D");
    }
    if hours == 0 && minutes == 0 && secs == 0 && nanos == 0 {
        if days == 0 {
            out.push_str("T0S");
        }
        return;
    }
    out.push('T');
    if hours > 0 {
        let _ = write!(out, "{hours}H");
    }
    if minutes > 0 {
        let _ = write!(out, "{minutes}M");
    }
    if secs > 0 || nanos > 0 {
        let _ = write!(out, "{secs}");
        write_fraction(out, nanos);
        out.push('S');
    }
}

/// Writes a years and months duration: `P1Y2M`, `P0M`, `-P1Y`.
fn write_year_month(out: &mut String, months: i64) {
    if months < 0 {
        out.push('-');
    }
    let abs = months.unsigned_abs();
    let (years, rest) = (abs / 12, abs % 12);
    out.push('P');
    if years > 0 {
        let _ = write!(out, "{years}Y");
    }
    if rest > 0 || years == 0 {
        let _ = write!(out, "{rest}M");
    }
}

/// The text of a temporal value as feel-scala prints it (`string()`, messages): date
/// `2026-11-23`; time `10:00:00`, `10:00:00.5`, `10:00:00Z`, `10:00:00+01:00`,
/// `10:00:00@Europe/Paris` (a zone id without the offset);
/// date and time `2026-11-23T10:00:00` with the same zone suffixes; days and time duration
/// `P1DT2H3M4.5S`, `PT0S`, `-PT1H`; years and months duration `P1Y2M`, `P0M`, `-P1Y`.
/// Other values print as [`Value`]'s `Display`.
pub(crate) fn text(v: &Value) -> String {
    let mut out = String::new();
    match v {
        Value::Date(d) => write_date(&mut out, *d),
        Value::Time(t) => {
            write_time(&mut out, t.time);
            write_zone(&mut out, t.zone.as_ref());
        }
        Value::DateTime(dt) => {
            write_date(&mut out, dt.local.date());
            out.push('T');
            write_time(&mut out, dt.local.time());
            write_zone(&mut out, dt.zone.as_ref());
        }
        Value::DayTime(d) => write_day_time(&mut out, *d),
        Value::YearMonth(m) => write_year_month(&mut out, *m),
        other => return other.to_string(),
    }
    out
}

/// The value of an `@"…"` literal: a date and time, a date, a time or a duration (either
/// kind). The error names what the text is not, and why (`not a valid date: no such date`);
/// it does not repeat the text, which callers show in front of it (`@"2026-02-30": …`).
pub(crate) fn literal(text: &str) -> Result<Value, String> {
    let body = text.strip_prefix('-').unwrap_or(text);
    let digits = body
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(body.len());
    let after = body.get(digits..).and_then(|rest| rest.chars().next());
    let (kind, result) = if body.starts_with('P') {
        ("duration", parse::duration(text))
    } else if digits > 0 && after == Some('-') {
        let before_zone = text.split('@').next().unwrap_or_default();
        if before_zone.contains(['T', ':']) {
            ("date and time", parse::date_time(text).map(Value::DateTime))
        } else {
            ("date", parse::date(text).map(Value::Date))
        }
    } else if (digits > 0 && after == Some(':')) || text.starts_with('T') {
        ("time", parse::time(text).map(Value::Time))
    } else {
        return Err("not a date, time, date and time or duration".to_owned());
    };
    result.map_err(|why| {
        if why.starts_with("not a ") {
            why
        } else {
            format!("not a valid {kind}: {why}")
        }
    })
}

/// A property of a temporal value (DMN 1.3 Table 65, feel-scala): `year`, `month`, `day`,
/// `weekday` (1 = Monday) of dates and dates and times; `hour`, `minute`, `second`,
/// `time offset` (a days and time duration, null when local), `timezone` (the zone id, null
/// without one) of times and dates and times; `days`, `hours`, `minutes`, `seconds` of days and
/// time durations (each cut towards zero, as java.time's `toDays`, `toHours % 24`, …);
/// `years`, `months` of years and months durations. `None` for anything else.
pub(crate) fn property(v: &Value, name: &str) -> Option<Value> {
    let int = |n: i64| Some(Value::int(n));
    let date_part = |d: NaiveDate| match name {
        "year" => int(i64::from(d.year())),
        "month" => int(i64::from(d.month())),
        "day" => int(i64::from(d.day())),
        "weekday" => int(i64::from(d.weekday().number_from_monday())),
        _ => None,
    };
    let time_part = |t: NaiveTime, zone: Option<&Zone>| match name {
        "hour" => int(i64::from(t.hour())),
        "minute" => int(i64::from(t.minute())),
        "second" => int(i64::from(t.second())),
        "time offset" => Some(zone.map_or(Value::Null, |z| Value::DayTime(offset_delta(z)))),
        "timezone" => Some(
            zone.and_then(|z| z.id.clone())
                .map_or(Value::Null, Value::String),
        ),
        _ => None,
    };
    match v {
        Value::Date(d) => date_part(*d),
        Value::Time(t) => time_part(t.time, t.zone.as_ref()),
        Value::DateTime(dt) => {
            date_part(dt.local.date()).or_else(|| time_part(dt.local.time(), dt.zone.as_ref()))
        }
        Value::DayTime(d) => {
            let seconds = d.num_seconds();
            match name {
                "days" => int(seconds / 86_400),
                "hours" => int(seconds / 3_600 % 24),
                "minutes" => int(seconds / 60 % 60),
                "seconds" => int(seconds % 60),
                _ => None,
            }
        }
        Value::YearMonth(m) => match name {
            "years" => int(m / 12),
            "months" => int(m % 12),
            _ => None,
        },
        _ => None,
    }
}

/// The absolute value of a duration (`abs(@"-PT5H")` is `PT5H`); `None` for other values.
pub(crate) fn abs(v: &Value) -> Option<Value> {
    match v {
        Value::DayTime(d) => Some(Value::DayTime(d.abs())),
        Value::YearMonth(m) => m.checked_abs().map(Value::YearMonth),
        _ => None,
    }
}
