//! Timer definitions: ISO 8601 dates, durations and repeating cycles, parsed with chrono.

use chrono::{DateTime, Duration, FixedOffset, Months, NaiveDateTime};

use crate::expr::Expression;

/// A timer event definition.
#[derive(Clone, Debug, PartialEq)]
pub struct Timer {
    /// `timeDate`, `timeDuration` or `timeCycle`.
    pub kind: TimerKind,
    /// The value: a fixed ISO 8601 text, or an expression evaluated when the timer starts.
    pub value: TimerValue,
}

/// Which timer element the model used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimerKind {
    /// `timeDate`: fires at an absolute time.
    Date,
    /// `timeDuration`: fires after a duration.
    Duration,
    /// `timeCycle`: fires repeatedly.
    Cycle,
}

/// The value of a timer.
#[derive(Clone, Debug, PartialEq)]
pub enum TimerValue {
    /// A fixed ISO 8601 value.
    Fixed(TimerSpec),
    /// An expression giving the ISO 8601 text at run time.
    Expression(Expression),
    /// A value that does not parse, kept only in non-executable (descriptive) processes,
    /// which are never run.
    Unparsed(String),
}

/// A parsed ISO 8601 timer value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TimerSpec {
    /// An absolute time.
    Date(DateTime<FixedOffset>),
    /// A duration.
    Duration(IsoDuration),
    /// A repeating interval `R[n][/start]/interval[/end]`.
    Cycle {
        /// `n`; `None` repeats without bound.
        repetitions: Option<u32>,
        /// First firing is at `start + interval`, or `activation + interval`.
        start: Option<DateTime<FixedOffset>>,
        /// Time between firings.
        interval: IsoDuration,
        /// No firing after this time.
        end: Option<DateTime<FixedOffset>>,
    },
}

/// An ISO 8601 duration, keeping calendar units so months add as months.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IsoDuration {
    /// Years.
    pub years: u32,
    /// Months.
    pub months: u32,
    /// Weeks.
    pub weeks: u32,
    /// Days.
    pub days: u32,
    /// Hours.
    pub hours: u32,
    /// Minutes.
    pub minutes: u32,
    /// Seconds, in milliseconds.
    pub millis: u64,
}

impl IsoDuration {
    /// The instant this duration after `from` (calendar-correct for years and months).
    pub fn after(&self, from: DateTime<FixedOffset>) -> Option<DateTime<FixedOffset>> {
        let months = self.years.checked_mul(12)?.checked_add(self.months)?;
        let t = from.checked_add_months(Months::new(months))?;
        let fixed = Duration::try_weeks(self.weeks.into())?
            .checked_add(&Duration::try_days(self.days.into())?)?
            .checked_add(&Duration::try_hours(self.hours.into())?)?
            .checked_add(&Duration::try_minutes(self.minutes.into())?)?
            .checked_add(&Duration::try_milliseconds(
                i64::try_from(self.millis).ok()?,
            )?)?;
        t.checked_add_signed(fixed)
    }

    /// Length in milliseconds, counting a month as 30 days and a year as 365 days.
    pub fn approx_millis(&self) -> u64 {
        let days = u64::from(self.years) * 365
            + u64::from(self.months) * 30
            + u64::from(self.weeks) * 7
            + u64::from(self.days);
        ((days * 24 + u64::from(self.hours)) * 60 + u64::from(self.minutes)) * 60_000 + self.millis
    }
}

/// Parses a timer value for `kind`. The value of `<timeDuration>` and its siblings is an
/// expression (§10.5.6, `tFormalExpression`) whose value is ISO 8601: a literal ISO 8601 text is
/// read at once, and so is a quoted constant (`"PT0.5S"`, as SpiffWorkflow writes it); an
/// expression wrapper (`${…}`, `=…`) or a name such as `due_time` makes it an expression
/// evaluated when the timer is armed. Text that looks like ISO 8601 but is not is an error here,
/// not a variable.
pub fn parse_timer(kind: TimerKind, raw: &str) -> Result<Timer, String> {
    let text = raw.trim();
    let quoted = ['"', '\''].into_iter().find_map(|q| {
        text.strip_prefix(q)
            .and_then(|t| t.strip_suffix(q))
            .filter(|t| !t.contains(q))
    });
    if let Some(inner) = quoted {
        return parse_timer(kind, inner);
    }
    if crate::expr::wrapped(text).is_some() || names_a_variable(text) {
        return Ok(Timer {
            kind,
            value: TimerValue::Expression(Expression::parse(text)?),
        });
    }
    let spec = match kind {
        TimerKind::Date => TimerSpec::Date(parse_date(text)?),
        TimerKind::Duration => TimerSpec::Duration(parse_duration(text)?),
        TimerKind::Cycle => parse_cycle(text)?,
    };
    Ok(Timer {
        kind,
        value: TimerValue::Fixed(spec),
    })
}

/// Is a timer value a bare name (`due_time`, `order.deadline`) rather than ISO 8601 text? Text
/// that starts as ISO 8601 does (`P…`, `R…`, a digit, a sign) is never taken for a name.
fn names_a_variable(text: &str) -> bool {
    let iso_like =
        text.starts_with(['P', 'R', '+', '-']) || text.starts_with(|c: char| c.is_ascii_digit());
    let name_like = text
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
        && text.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_');
    name_like && !iso_like
}

/// Parses an ISO 8601 date-time; one without an offset is taken as UTC.
pub fn parse_date(text: &str) -> Result<DateTime<FixedOffset>, String> {
    if let Ok(t) = DateTime::parse_from_rfc3339(text) {
        return Ok(t);
    }
    for format in ["%Y-%m-%dT%H:%M:%S%.f", "%Y-%m-%dT%H:%M"] {
        if let Ok(t) = NaiveDateTime::parse_from_str(text, format) {
            return Ok(t.and_utc().fixed_offset());
        }
    }
    Err(format!(
        "`{text}` is not an ISO 8601 date-time (e.g. 2026-11-23T10:00:00Z)"
    ))
}

/// Parses an ISO 8601 duration such as `PT20D`, `P1DT2H`, `PT0.5S` or `P2W`.
pub fn parse_duration(text: &str) -> Result<IsoDuration, String> {
    let bad = || format!("`{text}` is not an ISO 8601 duration (e.g. PT30M, P20D, P1DT2H)");
    let rest = text.strip_prefix('P').ok_or_else(bad)?;
    let (date, time) = match rest.split_once('T') {
        Some((d, t)) if !t.is_empty() => (d, Some(t)),
        Some(_) => return Err(bad()),
        None => (rest, None),
    };
    if date.is_empty() && time.is_none() {
        return Err(bad());
    }
    let mut d = IsoDuration::default();
    let mut seen = false;
    for (value, unit) in components(date).ok_or_else(bad)? {
        let n: u32 = value.parse().map_err(|_| bad())?;
        match unit {
            'Y' => d.years = n,
            'M' => d.months = n,
            'W' => d.weeks = n,
            'D' => d.days = n,
            _ => return Err(bad()),
        }
        seen = true;
    }
    for (value, unit) in time
        .map(components)
        .unwrap_or(Some(Vec::new()))
        .ok_or_else(bad)?
    {
        match unit {
            'H' => d.hours = value.parse().map_err(|_| bad())?,
            'M' => d.minutes = value.parse().map_err(|_| bad())?,
            'S' => {
                let secs: f64 = value.replace(',', ".").parse().map_err(|_| bad())?;
                if !secs.is_finite() || !(0.0..=1e12).contains(&secs) {
                    return Err(bad());
                }
                d.millis = (secs * 1000.0).round() as u64;
            }
            _ => return Err(bad()),
        }
        seen = true;
    }
    if !seen {
        return Err(bad());
    }
    Ok(d)
}

/// Splits `3D4H` into `[("3",'D'), ("4",'H')]`; `None` on anything else.
fn components(s: &str) -> Option<Vec<(&str, char)>> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, c) in s.char_indices() {
        if c.is_ascii_alphabetic() {
            if i == start {
                return None;
            }
            out.push((&s[start..i], c));
            start = i + 1;
        } else if !(c.is_ascii_digit() || c == '.' || c == ',') {
            return None;
        }
    }
    (start == s.len()).then_some(out)
}

/// Parses `R[n]/interval`, `R[n]/start/interval` or `R[n]/interval/end`.
pub fn parse_cycle(text: &str) -> Result<TimerSpec, String> {
    let bad = |why: &str| {
        format!("`{text}` is not an ISO 8601 repeating interval (e.g. R5/PT10S): {why}")
    };
    let parts: Vec<&str> = text.split('/').collect();
    let reps = parts[0].strip_prefix('R').ok_or_else(|| {
        if text.split_whitespace().count() >= 5 {
            bad("cron expressions are not supported")
        } else {
            bad("it must start with R")
        }
    })?;
    let repetitions = if reps.is_empty() {
        None
    } else {
        Some(
            reps.parse::<u32>()
                .map_err(|_| bad("bad repetition count"))?,
        )
    };
    let (start, interval, end) = match parts.len() {
        2 => (None, parse_duration(parts[1]).map_err(|e| bad(&e))?, None),
        3 if parts[1].starts_with('P') => (
            None,
            parse_duration(parts[1]).map_err(|e| bad(&e))?,
            Some(parse_date(parts[2]).map_err(|e| bad(&e))?),
        ),
        3 => (
            Some(parse_date(parts[1]).map_err(|e| bad(&e))?),
            parse_duration(parts[2]).map_err(|e| bad(&e))?,
            None,
        ),
        _ => return Err(bad("expected 2 or 3 parts separated by /")),
    };
    if interval.approx_millis() == 0 {
        return Err(bad("the interval is zero"));
    }
    Ok(TimerSpec::Cycle {
        repetitions,
        start,
        interval,
        end,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(parse_duration("PT20D").ok(), None, "days belong before T");
        assert_eq!(
            parse_duration("P20D").unwrap().approx_millis(),
            20 * 86_400_000
        );
        assert_eq!(parse_duration("PT1M30.5S").unwrap().approx_millis(), 90_500);
        assert_eq!(parse_duration("P1Y2M3W4DT5H6M7S").unwrap().months, 2);
        for bad in ["", "P", "PT", "1D", "P-1D", "PxD", "PT1.5.5S", "P1H"] {
            assert!(parse_duration(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn months_are_calendar_months() {
        let jan31 = parse_date("2026-01-31T00:00:00Z").unwrap();
        let d = parse_duration("P1M").unwrap();
        assert_eq!(
            d.after(jan31).unwrap().to_rfc3339(),
            "2026-02-28T00:00:00+00:00"
        );
    }

    #[test]
    fn cycles_and_dates() {
        assert!(matches!(
            parse_cycle("R4/PT1S").unwrap(),
            TimerSpec::Cycle {
                repetitions: Some(4),
                ..
            }
        ));
        assert!(matches!(
            parse_cycle("R/2026-01-01T00:00:00Z/PT1H").unwrap(),
            TimerSpec::Cycle {
                repetitions: None,
                start: Some(_),
                ..
            }
        ));
        assert!(matches!(
            parse_cycle("R2/PT1H/2026-01-01T00:00:00Z").unwrap(),
            TimerSpec::Cycle { end: Some(_), .. }
        ));
        assert!(
            parse_cycle("0 0 9-17 * * MON-FRI")
                .unwrap_err()
                .contains("cron")
        );
        assert!(parse_cycle("R/PT0S").is_err());
        assert!(parse_date("2026-11-23T10:00:00").is_ok());
        assert!(parse_date("tomorrow").is_err());
        let t = parse_timer(TimerKind::Duration, "${deadline}").unwrap();
        assert!(matches!(t.value, TimerValue::Expression(_)));
    }
}
