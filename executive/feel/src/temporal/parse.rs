//! Reading the ISO 8601 text forms FEEL uses for dates, times, dates and times, durations and
//! zones (feel-scala's grammar). Every function returns what the text is, or a short reason
//! saying what is wrong ("no such date"); callers put the function call in front of it.

use chrono::{Datelike, FixedOffset, NaiveDate, NaiveDateTime, NaiveTime};

use super::{NANOS, zones};
use crate::value::{DateTime, Time, Value, Zone};

/// What a text that is not a date is expected to look like.
const DATE_SHAPE: &str = "not a date (expected YYYY-MM-DD)";
/// What a text that is not a time is expected to look like.
const TIME_SHAPE: &str = "not a time (expected hh:mm:ss, optionally with a fraction and Z, +hh:mm or @zone id such as @Europe/Paris)";
/// What a text that is not a date and time is expected to look like.
const DATE_TIME_SHAPE: &str = "not a date and time (expected YYYY-MM-DDThh:mm:ss, optionally with a fraction and Z, +hh:mm or @zone id such as @Europe/Paris)";
/// What a text that is not a duration is expected to look like.
const DURATION_SHAPE: &str = "not a duration (expected e.g. P1Y2M or P1DT2H3M4.5S)";
/// The largest offset from UTC a zone may have (as in `java.time.ZoneOffset`): 18 hours.
const MAX_OFFSET_SECONDS: i32 = 18 * 3600;

/// A position in an ASCII text.
struct Cursor<'a> {
    /// The text's bytes.
    bytes: &'a [u8],
    /// The next byte to read.
    at: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `text`.
    fn new(text: &'a str) -> Self {
        Cursor {
            bytes: text.as_bytes(),
            at: 0,
        }
    }

    /// The next byte, if any.
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.at).copied()
    }

    /// Whether the whole text has been read.
    fn done(&self) -> bool {
        self.at >= self.bytes.len()
    }

    /// Reads `byte` if it is next.
    fn eat(&mut self, byte: u8) -> bool {
        if self.peek() == Some(byte) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    /// Reads a run of ASCII digits (possibly empty) and returns it.
    fn run(&mut self) -> &'a [u8] {
        let start = self.at;
        while self.peek().is_some_and(|b| b.is_ascii_digit()) {
            self.at += 1;
        }
        self.bytes.get(start..self.at).unwrap_or_default()
    }

    /// Reads exactly `n` digits as a number.
    fn fixed(&mut self, n: usize) -> Option<u32> {
        let start = self.at;
        let digits = self.bytes.get(start..start + n)?;
        if !digits.iter().all(u8::is_ascii_digit) {
            return None;
        }
        self.at += n;
        Some(
            digits
                .iter()
                .fold(0, |acc, d| acc * 10 + u32::from(d - b'0')),
        )
    }

    /// The rest of the text (from the cursor), as text.
    fn rest(&self) -> &'a str {
        std::str::from_utf8(self.bytes.get(self.at..).unwrap_or_default()).unwrap_or_default()
    }
}

/// The value of a run of decimal digits, or `None` when it has more than 18 digits.
fn number(digits: &[u8]) -> Option<u64> {
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    Some(
        digits
            .iter()
            .fold(0, |acc, d| acc * 10 + u64::from(d - b'0')),
    )
}

/// The nanoseconds of a fraction's digits (`5` → 500 000 000); `None` beyond 9 digits.
fn fraction(digits: &[u8]) -> Option<u32> {
    if digits.is_empty() || digits.len() > 9 {
        return None;
    }
    let mut nanos = 0u32;
    for i in 0..9 {
        nanos = nanos * 10 + digits.get(i).map_or(0, |d| u32::from(d - b'0'));
    }
    Some(nanos)
}

/// Shortens `text` for a message: at most 40 characters.
pub(crate) fn clip(text: &str) -> String {
    let mut chars = text.chars();
    let head: String = chars.by_ref().take(40).collect();
    if chars.next().is_some() {
        format!("{head}…")
    } else {
        head
    }
}

/// Reads a date `[-]YYYY-MM-DD` (a year of 4 to 9 digits, no leading zero beyond four).
fn date_part(c: &mut Cursor<'_>, shape: &str) -> Result<NaiveDate, String> {
    let negative = c.eat(b'-');
    let digits = c.run();
    if digits.len() < 4 || digits.len() > 9 || (digits.len() > 4 && digits.first() == Some(&b'0')) {
        return Err(shape.to_owned());
    }
    let year = number(digits).ok_or_else(|| shape.to_owned())?;
    if !c.eat(b'-') {
        return Err(shape.to_owned());
    }
    let month = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    if !c.eat(b'-') {
        return Err(shape.to_owned());
    }
    let day = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    let year = i64::try_from(year).map_err(|_| "year out of range".to_owned())?;
    let year = if negative { -year } else { year };
    if year < i64::from(NaiveDate::MIN.year()) || year > i64::from(NaiveDate::MAX.year()) {
        return Err("year out of range".to_owned());
    }
    let year = i32::try_from(year).map_err(|_| "year out of range".to_owned())?;
    NaiveDate::from_ymd_opt(year, month, day).ok_or_else(|| "no such date".to_owned())
}

/// Reads a time of day `hh:mm[:ss[.fffffffff]]` (feel-scala accepts the seconds missing).
fn time_part(c: &mut Cursor<'_>, shape: &str) -> Result<NaiveTime, String> {
    let hour = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    if !c.eat(b':') {
        return Err(shape.to_owned());
    }
    let minute = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    let (mut second, mut nanos) = (0, 0);
    if c.eat(b':') {
        second = c.fixed(2).ok_or_else(|| shape.to_owned())?;
        if c.eat(b'.') {
            let digits = c.run();
            if digits.len() > 9 {
                return Err("more than 9 digits after the decimal point of the seconds".to_owned());
            }
            nanos = fraction(digits).ok_or_else(|| shape.to_owned())?;
        }
    }
    if hour > 23 || minute > 59 || second > 59 {
        return Err("no such time of day".to_owned());
    }
    NaiveTime::from_hms_nano_opt(hour, minute, second, nanos)
        .ok_or_else(|| "no such time of day".to_owned())
}

/// The offset `±hh:mm[:ss]` (already past the sign), checked against ±18:00.
fn offset_part(c: &mut Cursor<'_>, negative: bool, shape: &str) -> Result<FixedOffset, String> {
    let hours = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    if !c.eat(b':') {
        return Err(shape.to_owned());
    }
    let minutes = c.fixed(2).ok_or_else(|| shape.to_owned())?;
    let seconds = if c.eat(b':') {
        c.fixed(2).ok_or_else(|| shape.to_owned())?
    } else {
        0
    };
    if minutes > 59 || seconds > 59 {
        return Err("no such offset".to_owned());
    }
    let seconds = i32::try_from(hours * 3600 + minutes * 60 + seconds)
        .map_err(|_| "no such offset".to_owned())?;
    offset(if negative { -seconds } else { seconds })
}

/// The fixed offset of `seconds` east of UTC, if within ±18:00.
pub(crate) fn offset(seconds: i32) -> Result<FixedOffset, String> {
    if seconds.abs() > MAX_OFFSET_SECONDS {
        return Err("offset beyond ±18:00".to_owned());
    }
    FixedOffset::east_opt(seconds).ok_or_else(|| "offset beyond ±18:00".to_owned())
}

/// UTC as a fixed offset.
fn utc() -> FixedOffset {
    FixedOffset::east_opt(0).unwrap_or_else(|| unreachable!("zero is a valid offset"))
}

/// The zone a zone id or offset text names: a zone id of the IANA tz database (`Europe/Paris`,
/// `UTC`, `Etc/GMT+5`; case-sensitive, as java.time's `ZoneId.of`), kept as the zone's id with
/// the zone's standard offset (what a time of day gets, see [`zones::standard_offset`]; a date
/// and time takes the offset at its date, see [`place`]); `Z` or `±hh:mm[:ss]` (offsets
/// without an id).
pub(crate) fn zone(text: &str) -> Result<Zone, String> {
    match text {
        "Z" => Ok(Zone {
            offset: utc(),
            id: None,
        }),
        "" => Err("no zone id".to_owned()),
        _ if text.starts_with(['+', '-']) => {
            let mut c = Cursor::new(text);
            let negative = c.eat(b'-');
            if !negative {
                c.eat(b'+');
            }
            let offset = offset_part(&mut c, negative, "not an offset (expected ±hh:mm)")?;
            if !c.done() {
                return Err("not an offset (expected ±hh:mm)".to_owned());
            }
            Ok(Zone { offset, id: None })
        }
        _ => match zones::rules_of(text) {
            Some(tz) => Ok(Zone {
                offset: zones::standard_offset(tz),
                id: Some(text.to_owned()),
            }),
            None => Err(format!(
                "unknown time zone `{}` (expected an IANA zone id such as Europe/Paris, Z or an offset such as +01:00)",
                clip(text)
            )),
        },
    }
}

/// The date and time `local` in `zone`: with a zone id, at the offset the zone has there (a
/// local time in a gap moved forward, the earlier offset in an overlap; see
/// [`zones::at_local`]); with a fixed offset, as is.
pub(crate) fn place(local: NaiveDateTime, zone: Zone) -> Result<DateTime, String> {
    match (zones::rules(&zone), zone.id.as_deref()) {
        (Some(tz), Some(id)) => {
            zones::at_local(local, tz, id, None).ok_or_else(|| "out of range".to_owned())
        }
        _ => Ok(DateTime {
            local,
            zone: Some(zone),
        }),
    }
}

/// What may follow a time, as written.
enum Suffix {
    /// Nothing: a local time.
    Local,
    /// `Z`, `±hh:mm` or `@zone`.
    Zone(Zone),
    /// `Z[zone id]` or `±hh:mm[zone id]`: an offset and the zone it must be an offset of (and
    /// the text in brackets, for messages).
    Both(FixedOffset, Zone, String),
}

/// Reads what may follow a time: nothing (a local time), `Z`, `±hh:mm` (either optionally
/// followed by `[zone id]`), or `@zone id`. The cursor must then be at the end.
fn zone_part(c: &mut Cursor<'_>, shape: &str) -> Result<Suffix, String> {
    let Some(first) = c.peek() else {
        return Ok(Suffix::Local);
    };
    let offset = match first {
        b'@' => {
            c.at += 1;
            let id = c.rest();
            c.at = c.bytes.len();
            return zone(id).map(Suffix::Zone);
        }
        b'Z' | b'z' => {
            c.at += 1;
            utc()
        }
        b'+' | b'-' => {
            c.at += 1;
            offset_part(c, first == b'-', shape)?
        }
        _ => return Err(shape.to_owned()),
    };
    if c.eat(b'[') {
        let rest = c.rest();
        let Some(id) = rest.strip_suffix(']') else {
            return Err(shape.to_owned());
        };
        c.at = c.bytes.len();
        return zone(id).map(|named| Suffix::Both(offset, named, id.to_owned()));
    }
    if !c.done() {
        return Err(shape.to_owned());
    }
    Ok(Suffix::Zone(Zone { offset, id: None }))
}

/// Why an offset written before `[id]` is refused.
fn mismatch(id: &str) -> String {
    format!("offset does not match the zone `{}`", clip(id))
}

/// A date `YYYY-MM-DD` (DMN 1.3 §10.3.4.1 `date(from)`; the year may have up to 9 digits and a
/// minus sign, as feel-scala allows).
pub(crate) fn date(text: &str) -> Result<NaiveDate, String> {
    if !text.is_ascii() {
        return Err(DATE_SHAPE.to_owned());
    }
    let mut c = Cursor::new(text);
    let date = date_part(&mut c, DATE_SHAPE)?;
    if !c.done() {
        return Err(if c.peek() == Some(b'T') {
            format!("{DATE_SHAPE}; for a date and time use date(date and time(…))")
        } else {
            DATE_SHAPE.to_owned()
        });
    }
    Ok(date)
}

/// A time `hh:mm:ss[.f]` with an optional `Z`, `±hh:mm` or `@zone` (and, as feel-scala, an
/// optional leading `T` and optional seconds).
pub(crate) fn time(text: &str) -> Result<Time, String> {
    if !text.is_ascii() {
        return Err(TIME_SHAPE.to_owned());
    }
    let mut c = Cursor::new(text);
    c.eat(b'T');
    let time = time_part(&mut c, TIME_SHAPE)?;
    let zone = match zone_part(&mut c, TIME_SHAPE)? {
        Suffix::Local => None,
        Suffix::Zone(zone) => Some(zone),
        Suffix::Both(offset, named, _) if named.offset == offset => Some(Zone {
            offset,
            id: named.id,
        }),
        Suffix::Both(_, _, id) => return Err(mismatch(&id)),
    };
    Ok(Time { time, zone })
}

/// A date and time `YYYY-MM-DDThh:mm:ss[.f]` with an optional zone as for [`time`]; a date
/// alone is midnight of that date, local (DMN 1.3 §10.3.4.1 `date and time(from)`).
pub(crate) fn date_time(text: &str) -> Result<DateTime, String> {
    if !text.is_ascii() {
        return Err(DATE_TIME_SHAPE.to_owned());
    }
    let mut c = Cursor::new(text);
    let date = date_part(&mut c, DATE_TIME_SHAPE)?;
    if c.done() {
        return Ok(DateTime {
            local: date.and_time(NaiveTime::MIN),
            zone: None,
        });
    }
    if !c.eat(b'T') {
        return Err(DATE_TIME_SHAPE.to_owned());
    }
    let local = date.and_time(time_part(&mut c, DATE_TIME_SHAPE)?);
    match zone_part(&mut c, DATE_TIME_SHAPE)? {
        Suffix::Local => Ok(DateTime { local, zone: None }),
        Suffix::Zone(zone) => place(local, zone),
        Suffix::Both(offset, named, id) => {
            let valid = match zones::rules(&named) {
                Some(tz) => zones::offsets_at(local, tz).contains(&offset),
                None => named.offset == offset,
            };
            if !valid {
                return Err(mismatch(&id));
            }
            Ok(DateTime {
                local,
                zone: Some(Zone {
                    offset,
                    id: named.id,
                }),
            })
        }
    }
}

/// A duration `[-]P[nY][nM][nD][T[nH][nM][n[.f]S]]`: with years and months only, a years and
/// months duration; with days, hours, minutes and seconds only, a days and time duration
/// (DMN 1.3 §10.3.2.3.7–8: the two kinds cannot be mixed).
pub(crate) fn duration(text: &str) -> Result<Value, String> {
    let shape = || DURATION_SHAPE.to_owned();
    let too_large = || "duration too large".to_owned();
    if !text.is_ascii() {
        return Err(shape());
    }
    let mut c = Cursor::new(text);
    let negative = c.eat(b'-');
    if !c.eat(b'P') {
        return Err(shape());
    }
    let (mut months, mut nanos): (Option<i128>, Option<i128>) = (None, None);
    let (mut in_time, mut after_t, mut rank) = (false, false, 0u8);
    while !c.done() {
        if c.eat(b'T') {
            if in_time {
                return Err(shape());
            }
            (in_time, after_t) = (true, true);
            continue;
        }
        after_t = false;
        let digits = c.run();
        if digits.is_empty() {
            return Err(shape());
        }
        let n = i128::from(number(digits).ok_or_else(too_large)?);
        let mut frac = 0i128;
        if c.eat(b'.') {
            let digits = c.run();
            if digits.len() > 9 {
                return Err("more than 9 digits after the decimal point of the seconds".to_owned());
            }
            frac = i128::from(fraction(digits).ok_or_else(shape)?);
            if c.peek() != Some(b'S') || !in_time {
                return Err(shape());
            }
        }
        let unit = c.peek().ok_or_else(shape)?;
        c.at += 1;
        let (this, per) = match (in_time, unit) {
            (false, b'Y') => (1, 12),
            (false, b'M') => (2, 1),
            (false, b'D') => (3, 86_400 * NANOS),
            (true, b'H') => (4, 3_600 * NANOS),
            (true, b'M') => (5, 60 * NANOS),
            (true, b'S') => (6, NANOS),
            _ => return Err(shape()),
        };
        if this <= rank {
            return Err(shape());
        }
        rank = this;
        if this <= 2 {
            months = Some(months.unwrap_or(0) + n * per);
        } else {
            nanos = Some(nanos.unwrap_or(0) + n * per + frac);
        }
    }
    if after_t || rank == 0 {
        return Err(shape());
    }
    match (months, nanos) {
        (Some(_), Some(_)) => Err(
            "mixes years or months with days or time: FEEL durations are either years and months (P1Y2M) or days and time (P1DT2H)"
                .to_owned(),
        ),
        (Some(m), None) => {
            let m = i64::try_from(if negative { -m } else { m }).map_err(|_| too_large())?;
            Ok(Value::YearMonth(m))
        }
        (None, Some(n)) => super::delta(if negative { -n } else { n })
            .map(Value::DayTime)
            .ok_or_else(too_large),
        (None, None) => Err(shape()),
    }
}
