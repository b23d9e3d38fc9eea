//! The temporal built-in functions (DMN 1.3 §10.3.4.1 and §10.3.4.x, Camunda's "conversion"
//! and "temporal" function pages, Zeebe's `cycle`): constructors (`date`, `time`,
//! `date and time`, `duration`, `years and months duration`), the mission clock (`now`,
//! `today`), calendar functions (`day of week`, …, `last day of month`) and timer cycles.
//! A null, wrongly typed or unreadable argument gives null with a reason naming the call and
//! what is wrong (`date("2026-02-30"): no such date`).

use std::fmt::Display;

use chrono::{Datelike, NaiveDate, NaiveTime};
use rust_decimal::Decimal;
use rust_decimal::prelude::ToPrimitive;

use super::{parse, zones};
use crate::host::{Builtin, Host, Stop};
use crate::value::{DateTime, Time, Value, Zone, number_text};

/// What a built-in returns.
type Run = Result<Value, Stop>;

/// Every temporal built-in signature. Parameter names follow DMN 1.3 §10.3.4.1 and feel-scala
/// (Zeebe's for `cycle`), for calls with named arguments.
pub(crate) static TEMPORAL: &[Builtin] = &[
    Builtin {
        name: "date",
        params: &["from"],
        variadic: false,
        run: date_from,
    },
    Builtin {
        name: "date",
        params: &["year", "month", "day"],
        variadic: false,
        run: date_of,
    },
    Builtin {
        name: "time",
        params: &["from"],
        variadic: false,
        run: time_from,
    },
    Builtin {
        name: "time",
        params: &["hour", "minute", "second"],
        variadic: false,
        run: time_of,
    },
    Builtin {
        name: "time",
        params: &["hour", "minute", "second", "offset"],
        variadic: false,
        run: time_of,
    },
    Builtin {
        name: "date and time",
        params: &["from"],
        variadic: false,
        run: date_time_from,
    },
    Builtin {
        name: "date and time",
        params: &["date", "time"],
        variadic: false,
        run: date_time_of,
    },
    Builtin {
        name: "date and time",
        params: &["date", "timezone"],
        variadic: false,
        run: date_time_of,
    },
    Builtin {
        name: "duration",
        params: &["from"],
        variadic: false,
        run: duration_from,
    },
    Builtin {
        name: "years and months duration",
        params: &["from", "to"],
        variadic: false,
        run: years_and_months,
    },
    Builtin {
        name: "now",
        params: &[],
        variadic: false,
        run: now,
    },
    Builtin {
        name: "today",
        params: &[],
        variadic: false,
        run: today,
    },
    Builtin {
        name: "day of week",
        params: &["date"],
        variadic: false,
        run: day_of_week,
    },
    Builtin {
        name: "day of year",
        params: &["date"],
        variadic: false,
        run: day_of_year,
    },
    Builtin {
        name: "week of year",
        params: &["date"],
        variadic: false,
        run: week_of_year,
    },
    Builtin {
        name: "month of year",
        params: &["date"],
        variadic: false,
        run: month_of_year,
    },
    Builtin {
        name: "last day of month",
        params: &["date"],
        variadic: false,
        run: last_day_of_month,
    },
    Builtin {
        name: "cycle",
        params: &["interval"],
        variadic: false,
        run: cycle,
    },
    Builtin {
        name: "cycle",
        params: &["repetitions", "interval"],
        variadic: false,
        run: cycle,
    },
];

/// English day names, Monday first.
const WEEKDAYS: [&str; 7] = [
    "Monday",
    "Tuesday",
    "Wednesday",
    "Thursday",
    "Friday",
    "Saturday",
    "Sunday",
];

/// English month names, January first.
const MONTHS: [&str; 12] = [
    "January",
    "February",
    "March",
    "April",
    "May",
    "June",
    "July",
    "August",
    "September",
    "October",
    "November",
    "December",
];

/// An argument as a reason shows it: as FEEL prints it, clipped; lists, contexts and functions
/// by their brackets only.
fn show(v: &Value) -> String {
    match v {
        Value::String(s) => Value::String(parse::clip(s)).to_string(),
        Value::List(_) => "[…]".to_owned(),
        Value::Context(_) => "{…}".to_owned(),
        Value::Function(_) => "function".to_owned(),
        other => parse::clip(&other.to_string()),
    }
}

/// Null, with the reason `name(args): why`.
fn fail(host: &mut dyn Host, name: &str, args: &[Value], why: impl Display) -> Run {
    let shown: Vec<String> = args.iter().map(show).collect();
    Ok(host.null(format!("{name}({}): {why}", shown.join(", "))))
}

/// Why `got` does not do as parameter `param`.
fn wrong(param: &str, expected: &str, got: &Value) -> String {
    if got.is_null() {
        format!("{param} is null")
    } else {
        format!("{param} must be {expected}, not a {}", got.type_name())
    }
}

/// Why a call has the wrong number of arguments (the evaluator should not let it happen).
fn arity(n: usize) -> String {
    format!("expects {n} argument{}", if n == 1 { "" } else { "s" })
}

/// The result of a parse, or null with its reason.
fn parsed<T>(
    host: &mut dyn Host,
    name: &str,
    args: &[Value],
    r: Result<T, String>,
    f: fn(T) -> Value,
) -> Run {
    match r {
        Ok(v) => Ok(f(v)),
        Err(why) => fail(host, name, args, why),
    }
}

/// A whole number argument.
fn whole(param: &str, v: &Value) -> Result<i64, String> {
    match v {
        Value::Number(n) if n.fract().is_zero() => n
            .to_i64()
            .ok_or_else(|| format!("{param} {} is out of range", number_text(n))),
        Value::Number(n) => Err(format!("{param} {} is not a whole number", number_text(n))),
        other => Err(wrong(param, "a number", other)),
    }
}

/// The calendar date of a date or a date and time.
fn calendar(v: &Value) -> Option<NaiveDate> {
    match v {
        Value::Date(d) => Some(*d),
        Value::DateTime(dt) => Some(dt.local.date()),
        _ => None,
    }
}

/// `date(from)`: a date string, or the date of a date and time (or a date).
fn date_from(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "date";
    match args.as_slice() {
        [Value::String(s)] => parsed(host, NAME, &args, parse::date(s), Value::Date),
        [v] => match calendar(v) {
            Some(d) => Ok(Value::Date(d)),
            None => fail(
                host,
                NAME,
                &args,
                wrong("from", "a string, a date or a date and time", v),
            ),
        },
        _ => fail(host, NAME, &args, arity(1)),
    }
}

/// `date(year, month, day)`: whole numbers naming a calendar date.
fn date_of(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "date";
    let [year, month, day] = args.as_slice() else {
        return fail(host, NAME, &args, arity(3));
    };
    let parts = (|| {
        let (y, m, d) = (
            whole("year", year)?,
            whole("month", month)?,
            whole("day", day)?,
        );
        let y = i32::try_from(y)
            .ok()
            .filter(|y| (NaiveDate::MIN.year()..=NaiveDate::MAX.year()).contains(y))
            .ok_or("year out of range")?;
        let (m, d) = (u32::try_from(m).unwrap_or(0), u32::try_from(d).unwrap_or(0));
        NaiveDate::from_ymd_opt(y, m, d).ok_or_else(|| "no such date".to_owned())
    })();
    parsed(host, NAME, &args, parts, Value::Date)
}

/// `time(from)`: a time string, the time of a date and time (with its zone), or midnight UTC
/// of a date (DMN 1.3 §10.3.4.1, feel-scala).
fn time_from(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "time";
    match args.as_slice() {
        [Value::String(s)] => parsed(host, NAME, &args, parse::time(s), Value::Time),
        [Value::Time(t)] => Ok(Value::Time(t.clone())),
        [Value::DateTime(dt)] => Ok(Value::Time(Time {
            time: dt.local.time(),
            zone: dt.zone.clone(),
        })),
        [Value::Date(_)] => Ok(Value::Time(Time {
            time: NaiveTime::MIN,
            zone: Some(Zone {
                offset: chrono::Offset::fix(&chrono::Utc),
                id: None,
            }),
        })),
        [v] => fail(
            host,
            NAME,
            &args,
            wrong("from", "a string, a date or a date and time", v),
        ),
        _ => fail(host, NAME, &args, arity(1)),
    }
}

/// The time of day `hour:minute:second` (the second may have a fraction).
fn clock(hour: &Value, minute: &Value, second: &Value) -> Result<NaiveTime, String> {
    let (h, m) = (whole("hour", hour)?, whole("minute", minute)?);
    let s = match second {
        Value::Number(n) => *n,
        other => return Err(wrong("second", "a number", other)),
    };
    let whole_s = s.trunc();
    let nanos = (s - whole_s)
        .checked_mul(Decimal::from(1_000_000_000))
        .and_then(|n| n.trunc().to_u32());
    match (u32::try_from(h), u32::try_from(m), whole_s.to_u32(), nanos) {
        (Ok(h), Ok(m), Some(s), Some(nanos))
            if h < 24 && m < 60 && s < 60 && !whole_s.is_sign_negative() =>
        {
            NaiveTime::from_hms_nano_opt(h, m, s, nanos)
                .ok_or_else(|| "no such time of day".to_owned())
        }
        _ => Err("no such time of day".to_owned()),
    }
}

/// `time(hour, minute, second)` (local) and `time(hour, minute, second, offset)` (the offset a
/// days and time duration, or null for a local time).
fn time_of(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "time";
    let made = match args.as_slice() {
        [h, m, s] => clock(h, m, s).map(|time| Time { time, zone: None }),
        [h, m, s, offset] => clock(h, m, s).and_then(|time| {
            let zone = match offset {
                Value::Null => None,
                Value::DayTime(d) if d.subsec_nanos() == 0 => Some(Zone {
                    offset: i32::try_from(d.num_seconds())
                        .map_err(|_| "offset beyond ±18:00".to_owned())
                        .and_then(parse::offset)?,
                    id: None,
                }),
                Value::DayTime(_) => return Err("offset must be whole seconds".to_owned()),
                other => return Err(wrong("offset", "a days and time duration", other)),
            };
            Ok(Time { time, zone })
        }),
        _ => return fail(host, NAME, &args, arity(4)),
    };
    parsed(host, NAME, &args, made, Value::Time)
}

/// `date and time(from)`: a date and time string, or a date string (midnight, local).
fn date_time_from(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "date and time";
    match args.as_slice() {
        [Value::String(s)] => parsed(host, NAME, &args, parse::date_time(s), Value::DateTime),
        [v] => fail(host, NAME, &args, wrong("from", "a string", v)),
        _ => fail(host, NAME, &args, arity(1)),
    }
}

/// `date and time(date, time)`: the date of a date or date and time at a time (zoned when the
/// time is; with a zone id, at the zone's offset on that date, as feel-scala's
/// `ZonedTime.withDate`); and Camunda's `date and time(date, timezone)`: a date and time in a
/// zone (a local one gets the zone, as java.time's `atZone`; a zoned one is the same instant in
/// the new zone, as `withZoneSameInstant`).
fn date_time_of(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "date and time";
    let [date, second] = args.as_slice() else {
        return fail(host, NAME, &args, arity(2));
    };
    let made = match (date, second) {
        (Value::DateTime(dt), Value::String(id)) => in_zone(dt, id),
        (_, Value::String(_)) => Err(wrong(
            "date",
            "a date and time when a timezone is given",
            date,
        )),
        (_, Value::Time(t)) => match (calendar(date), &t.zone) {
            (Some(d), Some(zone)) => parse::place(d.and_time(t.time), zone.clone()),
            (Some(d), None) => Ok(DateTime {
                local: d.and_time(t.time),
                zone: None,
            }),
            (None, _) => Err(wrong("date", "a date or a date and time", date)),
        },
        (_, other) => Err(wrong("time", "a time (or a timezone string)", other)),
    };
    parsed(host, NAME, &args, made, Value::DateTime)
}

/// A date and time in the zone `id` (see [`date_time_of`]).
fn in_zone(dt: &DateTime, id: &str) -> Result<DateTime, String> {
    let zone = parse::zone(id)?;
    let Some(old) = &dt.zone else {
        return parse::place(dt.local, zone);
    };
    let out_of_range = || "out of range".to_owned();
    let utc = dt
        .local
        .checked_sub_signed(super::offset_delta(old))
        .ok_or_else(out_of_range)?;
    match (zones::rules(&zone), zone.id.as_deref()) {
        (Some(tz), Some(id)) => zones::at_instant(utc, tz, id).ok_or_else(out_of_range),
        _ => Ok(DateTime {
            local: utc
                .checked_add_signed(super::offset_delta(&zone))
                .ok_or_else(out_of_range)?,
            zone: Some(zone),
        }),
    }
}

/// `duration(from)`: a duration string, of either kind.
fn duration_from(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "duration";
    match args.as_slice() {
        [Value::String(s)] => parsed(host, NAME, &args, parse::duration(s), |v| v),
        [v] => fail(host, NAME, &args, wrong("from", "a string", v)),
        _ => fail(host, NAME, &args, arity(1)),
    }
}

/// The whole months from `from` to `to` (java.time `Period.between`, days dropped).
fn months_between(from: NaiveDate, to: NaiveDate) -> i64 {
    let month_number = |d: NaiveDate| i64::from(d.year()) * 12 + i64::from(d.month0());
    let mut months = month_number(to) - month_number(from);
    let days = i64::from(to.day()) - i64::from(from.day());
    if months > 0 && days < 0 {
        months -= 1;
    } else if months < 0 && days > 0 {
        months += 1;
    }
    months
}

/// `years and months duration(from, to)`: the whole months between two dates or dates and
/// times (their calendar dates; zones are ignored, as feel-scala does).
fn years_and_months(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "years and months duration";
    let [from, to] = args.as_slice() else {
        return fail(host, NAME, &args, arity(2));
    };
    match (calendar(from), calendar(to)) {
        (Some(a), Some(b)) => Ok(Value::YearMonth(months_between(a, b))),
        (None, _) => fail(
            host,
            NAME,
            &args,
            wrong("from", "a date or a date and time", from),
        ),
        (_, None) => fail(
            host,
            NAME,
            &args,
            wrong("to", "a date or a date and time", to),
        ),
    }
}

/// `now()`: the mission time.
fn now(host: &mut dyn Host, args: Vec<Value>) -> Run {
    if !args.is_empty() {
        return fail(host, "now", &args, arity(0));
    }
    Ok(Value::DateTime(host.now()))
}

/// `today()`: the date of the mission time.
fn today(host: &mut dyn Host, args: Vec<Value>) -> Run {
    if !args.is_empty() {
        return fail(host, "today", &args, arity(0));
    }
    Ok(Value::Date(host.now().local.date()))
}

/// Runs `f` on the calendar date of the one argument `date` of function `name`.
fn on_date(host: &mut dyn Host, name: &str, args: &[Value], f: fn(NaiveDate) -> Value) -> Run {
    match args {
        [v] => match calendar(v) {
            Some(d) => Ok(f(d)),
            None => fail(
                host,
                name,
                args,
                wrong("date", "a date or a date and time", v),
            ),
        },
        _ => fail(host, name, args, arity(1)),
    }
}

/// `day of week(date)`: "Monday" … "Sunday".
fn day_of_week(host: &mut dyn Host, args: Vec<Value>) -> Run {
    on_date(host, "day of week", &args, |d| {
        let i = d.weekday().num_days_from_monday() as usize;
        Value::String(WEEKDAYS.get(i).copied().unwrap_or_default().to_owned())
    })
}

/// `day of year(date)`: 1 … 366.
fn day_of_year(host: &mut dyn Host, args: Vec<Value>) -> Run {
    on_date(host, "day of year", &args, |d| {
        Value::int(i64::from(d.ordinal()))
    })
}

/// `week of year(date)`: the ISO 8601 week number, 1 … 53.
fn week_of_year(host: &mut dyn Host, args: Vec<Value>) -> Run {
    on_date(host, "week of year", &args, |d| {
        Value::int(i64::from(d.iso_week().week()))
    })
}

/// `month of year(date)`: "January" … "December".
fn month_of_year(host: &mut dyn Host, args: Vec<Value>) -> Run {
    on_date(host, "month of year", &args, |d| {
        let i = d.month0() as usize;
        Value::String(MONTHS.get(i).copied().unwrap_or_default().to_owned())
    })
}

/// `last day of month(date)` (Camunda): the last date of the date's month.
fn last_day_of_month(host: &mut dyn Host, args: Vec<Value>) -> Run {
    on_date(host, "last day of month", &args, |d| {
        let last = (28..=31)
            .rev()
            .find_map(|day| NaiveDate::from_ymd_opt(d.year(), d.month(), day))
            .unwrap_or(d);
        Value::Date(last)
    })
}

/// Zeebe's `cycle(interval)` → `"R/P7D"` and `cycle(repetitions, interval)` → `"R3/PT1H"`: an
/// ISO 8601 repeating interval for a timer cycle (null repetitions: for ever). Zeebe prints a
/// days and time duration as java.time does (`PT168H`); this prints FEEL's form (`P7D`), which
/// means the same.
fn cycle(host: &mut dyn Host, args: Vec<Value>) -> Run {
    const NAME: &str = "cycle";
    let (repetitions, interval) = match args.as_slice() {
        [interval] => (&Value::Null, interval),
        [repetitions, interval] => (repetitions, interval),
        _ => return fail(host, NAME, &args, arity(2)),
    };
    if !matches!(interval, Value::DayTime(_) | Value::YearMonth(_)) {
        return fail(host, NAME, &args, wrong("interval", "a duration", interval));
    }
    let count = match repetitions {
        Value::Null => String::new(),
        other => match whole("repetitions", other) {
            Ok(n) if n >= 0 => n.to_string(),
            Ok(_) => return fail(host, NAME, &args, "repetitions must not be negative"),
            Err(why) => return fail(host, NAME, &args, why),
        },
    };
    Ok(Value::String(format!("R{count}/{}", super::text(interval))))
}
