//! Timer definitions previewed as the panel edits them: read by the executive's own parser
//! (`executive_model::timer`), so a value the executive would refuse is refused here with the
//! same message, and said in words with its first firings in mission time — from a given
//! moment, or counted from when the timer starts.

use chrono::{DateTime, FixedOffset, SecondsFormat};
use executive_model::timer::{IsoDuration, TimerKind, TimerSpec, TimerValue, parse_timer};
use serde::Serialize;

/// How many firings of a cycle a preview lists.
const FIRINGS: usize = 3;

/// What a timer definition means.
#[derive(Debug, PartialEq, Eq, Serialize)]
pub struct Preview {
    /// In words: `fires 6 h after the timer starts`.
    pub summary: String,
    /// Its first firings: instants (RFC 3339, mission time) when a start was given or the
    /// timer is absolute, else offsets from the timer's start (`+6 h`).
    pub firings: Vec<String>,
}

/// The kind of timer named as in BPMN: `timeDate`, `timeDuration`, `timeCycle`.
pub fn kind(name: &str) -> Option<TimerKind> {
    match name {
        "timeDate" => Some(TimerKind::Date),
        "timeDuration" => Some(TimerKind::Duration),
        "timeCycle" => Some(TimerKind::Cycle),
        _ => None,
    }
}

/// Previews timer `text` of `kind`, started at mission time `from_ms` if given; the parser's
/// message when the executive would refuse it.
pub fn preview(kind: TimerKind, text: &str, from_ms: Option<i64>) -> Result<Preview, String> {
    if text.trim().is_empty() {
        return Err("no value: the timer would never fire".to_owned());
    }
    let timer = parse_timer(kind, text)?;
    let from = from_ms
        .and_then(DateTime::from_timestamp_millis)
        .map(|t| t.fixed_offset());
    let spec = match timer.value {
        TimerValue::Fixed(spec) => spec,
        TimerValue::Expression(e) => {
            return Ok(Preview {
                summary: format!(
                    "computed when the timer starts, from the expression `{}`",
                    e.source.trim()
                ),
                firings: Vec::new(),
            });
        }
        TimerValue::Unparsed(why) => return Err(why),
    };
    let at = |t: DateTime<FixedOffset>| t.to_rfc3339_opts(SecondsFormat::Secs, true);
    Ok(match spec {
        TimerSpec::Date(t) => Preview {
            summary: format!("fires at {} (mission time)", at(t)),
            firings: vec![at(t)],
        },
        TimerSpec::Duration(d) => Preview {
            summary: format!("fires {} after the timer starts", words(&d)),
            firings: vec![match from {
                Some(f) => d
                    .after(f)
                    .map(at)
                    .unwrap_or_else(|| "beyond the calendar".into()),
                None => format!("+{}", words(&d)),
            }],
        },
        TimerSpec::Cycle {
            repetitions,
            start,
            interval,
            end,
        } => {
            let times = match repetitions {
                Some(1) => "once".to_owned(),
                Some(n) => format!("{n} times"),
                None => "without end".to_owned(),
            };
            let first = match start {
                Some(s) => format!("from {}", at(s)),
                None => "from when the timer starts".to_owned(),
            };
            let until = end
                .map(|e| format!(", not after {}", at(e)))
                .unwrap_or_default();
            let n = repetitions.map_or(FIRINGS, |r| (r as usize).min(FIRINGS));
            let mut firings = Vec::new();
            match start.or(from) {
                Some(mut t) => {
                    for _ in 0..n {
                        match interval.after(t) {
                            Some(next) if end.is_none_or(|e| next <= e) => {
                                firings.push(at(next));
                                t = next;
                            }
                            _ => break,
                        }
                    }
                }
                None => {
                    firings = (1..=n)
                        .map(|k| format!("+{}", words(&times_n(&interval, k as u32))))
                        .collect();
                }
            }
            Preview {
                summary: format!("fires every {} {times}, {first}{until}", words(&interval)),
                firings,
            }
        }
    })
}

/// `d` taken `k` times, unit by unit.
fn times_n(d: &IsoDuration, k: u32) -> IsoDuration {
    IsoDuration {
        years: d.years.saturating_mul(k),
        months: d.months.saturating_mul(k),
        weeks: d.weeks.saturating_mul(k),
        days: d.days.saturating_mul(k),
        hours: d.hours.saturating_mul(k),
        minutes: d.minutes.saturating_mul(k),
        millis: d.millis.saturating_mul(u64::from(k)),
    }
}

/// A duration for people: `1 d 6 h`, `90 s`, `0.5 s`.
fn words(d: &IsoDuration) -> String {
    let mut parts = Vec::new();
    for (n, unit) in [
        (d.years, "y"),
        (d.months, "mo"),
        (d.weeks, "w"),
        (d.days, "d"),
        (d.hours, "h"),
        (d.minutes, "min"),
    ] {
        if n > 0 {
            parts.push(format!("{n} {unit}"));
        }
    }
    if d.millis > 0 {
        let s = d.millis as f64 / 1000.0;
        parts.push(format!("{s} s"));
    }
    if parts.is_empty() {
        "0 s".to_owned()
    } else {
        parts.join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T0: i64 = 1_795_437_454_000; // 2026-11-23T12:37:34Z

    fn p(kind: &str, text: &str, from: Option<i64>) -> Result<Preview, String> {
        preview(super::kind(kind).expect("a kind"), text, from)
    }

    #[test]
    fn durations_fire_once_after_the_start() {
        let d = p("timeDuration", "PT6H", None).unwrap();
        assert_eq!(d.summary, "fires 6 h after the timer starts");
        assert_eq!(d.firings, ["+6 h"]);
        let d = p("timeDuration", "P1DT30M", Some(T0)).unwrap();
        assert_eq!(d.firings, ["2026-11-24T13:07:34Z"]);
    }

    #[test]
    fn dates_fire_at_their_instant() {
        let d = p("timeDate", "2027-01-01T00:00:00Z", None).unwrap();
        assert_eq!(d.summary, "fires at 2027-01-01T00:00:00Z (mission time)");
    }

    #[test]
    fn cycles_list_their_first_firings_within_their_bounds() {
        let c = p("timeCycle", "R2/PT1H", None).unwrap();
        assert_eq!(
            c.summary,
            "fires every 1 h 2 times, from when the timer starts"
        );
        assert_eq!(c.firings, ["+1 h", "+2 h"]);
        let c = p("timeCycle", "R/PT10M", Some(T0)).unwrap();
        assert_eq!(c.firings.len(), FIRINGS);
        assert_eq!(c.firings[1], "2026-11-23T12:57:34Z");
        let c = p("timeCycle", "R/2027-01-01T00:00:00Z/PT1H", None).unwrap();
        assert_eq!(c.firings[0], "2027-01-01T01:00:00Z");
        let c = p(
            "timeCycle",
            "R5/PT1H/2027-01-01T01:30:00Z",
            Some(1_798_761_600_000),
        )
        .unwrap();
        assert_eq!(c.firings, ["2027-01-01T01:00:00Z"], "the end bounds it");
    }

    #[test]
    fn expressions_are_computed_when_the_timer_starts() {
        let e = p("timeDuration", "= wait_for", None).unwrap();
        assert!(
            e.summary.starts_with("computed when the timer starts"),
            "{e:?}"
        );
        assert!(e.firings.is_empty());
    }

    #[test]
    fn what_the_executive_refuses_is_refused_with_its_message() {
        for (kind, text) in [
            ("timeDuration", "PT20D"),
            ("timeDuration", ""),
            ("timeCycle", "0 0 * * *"),
            ("timeCycle", "R3/PT0S"),
            ("timeDate", "2027-13-01"),
        ] {
            assert!(p(kind, text, None).is_err(), "{kind} {text}");
        }
        let e = p("timeCycle", "0 0 12 * * ?", None).unwrap_err();
        assert!(e.contains("cron expressions are not supported"), "{e}");
    }
}
