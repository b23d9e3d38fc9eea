//! Values across the FEEL boundary: engine values to FEEL values and back, and the mission
//! time as FEEL's `now()`.

use std::collections::BTreeMap;

use chrono::{DateTime, FixedOffset};
use executive_feel::{Context, Value as Feel, Zone};
use rust_decimal::Decimal;
use rust_decimal::prelude::{FromPrimitive, ToPrimitive};

use crate::io::Millis;
use crate::value::{F64, Value};

/// The mission time `now` (milliseconds since the epoch) as a FEEL date and time in UTC.
pub(crate) fn mission_time(now: Millis) -> executive_feel::DateTime {
    let at = DateTime::from_timestamp_millis(now).unwrap_or_default();
    executive_feel::DateTime {
        local: at.naive_utc(),
        zone: Some(Zone {
            offset: FixedOffset::east_opt(0).unwrap_or_else(|| at.fixed_offset().timezone()),
            id: None,
        }),
    }
}

/// An engine value as FEEL sees it. Whole numbers are exact; a float becomes the decimal of its
/// shortest text (`0.1` stays 0.1); one a decimal cannot hold (NaN, infinities, beyond 28
/// digits) is null.
pub(crate) fn to_feel(v: &Value) -> Feel {
    match v {
        Value::Null => Feel::Null,
        Value::Bool(b) => Feel::Bool(*b),
        Value::Int(i) => Feel::Number(Decimal::from(*i)),
        Value::Float(F64(f)) => f
            .to_string()
            .parse::<Decimal>()
            .ok()
            .or_else(|| Decimal::from_f64(*f))
            .map_or(Feel::Null, Feel::Number),
        Value::String(s) => Feel::String(s.clone()),
        Value::List(items) => Feel::List(items.iter().map(to_feel).collect()),
        Value::Map(m) => Feel::Context(Context(
            m.iter().map(|(k, v)| (k.clone(), to_feel(v))).collect(),
        )),
    }
}

/// A FEEL result as an engine value. Numbers that are whole and fit become ints, others floats
/// (the nearest `f64`); dates, times and durations become their ISO 8601 text (a zoned date and
/// time with its offset, so timers read it); ranges and functions cannot be stored.
pub(crate) fn from_feel(v: &Feel) -> Result<Value, String> {
    Ok(match v {
        Feel::Null => Value::Null,
        Feel::Bool(b) => Value::Bool(*b),
        Feel::Number(n) => match n.fract().is_zero().then(|| n.to_i64()).flatten() {
            Some(i) => Value::Int(i),
            None => Value::Float(F64(n.to_f64().unwrap_or(f64::NAN))),
        },
        Feel::String(s) => Value::String(s.clone()),
        Feel::DateTime(dt) => Value::String(match &dt.zone {
            Some(z) => {
                let at = dt.local.and_local_timezone(z.offset).single();
                match at {
                    Some(at) => at.to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true),
                    None => v.to_string(),
                }
            }
            None => executive_feel::plain_text(v),
        }),
        Feel::Date(_) | Feel::Time(_) | Feel::DayTime(_) | Feel::YearMonth(_) => {
            Value::String(executive_feel::plain_text(v))
        }
        Feel::List(items) => Value::List(items.iter().map(from_feel).collect::<Result<_, _>>()?),
        Feel::Context(c) => {
            let mut out = BTreeMap::new();
            for (k, v) in &c.0 {
                out.insert(k.clone(), from_feel(v)?);
            }
            Value::Map(out)
        }
        Feel::Range(_) | Feel::Function(_) => {
            return Err(format!(
                "a FEEL {} cannot be stored in a variable",
                v.type_name()
            ));
        }
    })
}
