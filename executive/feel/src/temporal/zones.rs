//! Zone rules for zone ids (`Europe/Berlin`, `UTC`), from chrono-tz's copy of the IANA tz
//! database, applied as java.time's `ZonedDateTime` applies them (feel-scala keeps a zoned
//! date and time as a `ZonedDateTime`): the offset of a local date-time in a zone, a gap's
//! local time shifted forward, an overlap's earlier offset, and instants seen in a zone.

use chrono::{FixedOffset, LocalResult, NaiveDate, NaiveDateTime, Offset, TimeDelta, TimeZone};
use chrono_tz::{GapInfo, OffsetComponents, Tz};

use crate::value::{DateTime, Zone};

/// The rules of the zone id `id`, if the database knows it (case-sensitive, as java.time's
/// `ZoneId.of`).
pub(crate) fn rules_of(id: &str) -> Option<Tz> {
    id.parse().ok()
}

/// The rules of a zone written with a zone id; `None` for a fixed offset (or an id the database
/// does not know, which only a value built outside this module can carry).
pub(crate) fn rules(zone: &Zone) -> Option<Tz> {
    zone.id.as_deref().and_then(rules_of)
}

/// A duration of `seconds`.
fn seconds(seconds: i32) -> TimeDelta {
    TimeDelta::try_seconds(i64::from(seconds)).unwrap_or_default()
}

/// The zoned date-time `id` gives the instant `utc` (a UTC date-time): its local date-time and
/// offset (java.time `ZonedDateTime.ofInstant`). `None` if it does not fit.
pub(crate) fn at_instant(utc: NaiveDateTime, tz: Tz, id: &str) -> Option<DateTime> {
    let offset = tz.offset_from_utc_datetime(&utc).fix();
    let local = utc.checked_add_signed(seconds(offset.local_minus_utc()))?;
    Some(DateTime {
        local,
        zone: Some(Zone {
            offset,
            id: Some(id.to_owned()),
        }),
    })
}

/// The zoned date-time of the local date-time `local` in `tz` (java.time
/// `ZonedDateTime.ofLocal(local, zone, preferred)`): the zone's offset there; in an overlap
/// (clocks going back) `preferred` if it is one of the two offsets, else the earlier one (the
/// offset before the change); in a gap (clocks going forward) the local date-time moved forward
/// by the gap's length, with the offset after it. `None` if it does not fit.
pub(crate) fn at_local(
    local: NaiveDateTime,
    tz: Tz,
    id: &str,
    preferred: Option<FixedOffset>,
) -> Option<DateTime> {
    let offset = match tz.offset_from_local_datetime(&local) {
        LocalResult::Single(o) => o.fix(),
        LocalResult::Ambiguous(before, after) => {
            let (before, after) = (before.fix(), after.fix());
            if preferred == Some(after) {
                after
            } else {
                before
            }
        }
        LocalResult::None => {
            // The instant the local date-time names with the offset before the gap, seen in the
            // zone: the same local date-time moved forward by the gap's length.
            let (_, before) = GapInfo::new(&local, &tz)?.begin?;
            let utc = local.checked_sub_signed(seconds(before.fix().local_minus_utc()))?;
            return at_instant(utc, tz, id);
        }
    };
    Some(DateTime {
        local,
        zone: Some(Zone {
            offset,
            id: Some(id.to_owned()),
        }),
    })
}

/// The offsets `tz` gives the local date-time `local`: one, two in an overlap, none in a gap.
pub(crate) fn offsets_at(local: NaiveDateTime, tz: Tz) -> Vec<FixedOffset> {
    match tz.offset_from_local_datetime(&local) {
        LocalResult::Single(o) => vec![o.fix()],
        LocalResult::Ambiguous(a, b) => vec![a.fix(), b.fix()],
        LocalResult::None => Vec::new(),
    }
}

/// The offset a time of day with the zone id of `tz` gets: the zone's standard offset (no
/// daylight saving) under the database's latest rules. feel-scala takes
/// `getStandardOffset(Instant.now)`; with no clock here, the instant is 2100-01-01T00:00:00Z,
/// after the last change the database lists (so the zone's rules as they now stand). As in
/// java.time's (rearguard) data, a negative daylight saving (Europe/Dublin's winter) is
/// standard time.
pub(crate) fn standard_offset(tz: Tz) -> FixedOffset {
    let reference = NaiveDate::from_ymd_opt(2100, 1, 1)
        .and_then(|d| d.and_hms_opt(0, 0, 0))
        .unwrap_or_default();
    let offset = tz.offset_from_utc_datetime(&reference);
    let standard = offset.base_utc_offset() + offset.dst_offset().min(TimeDelta::zero());
    i32::try_from(standard.num_seconds())
        .ok()
        .and_then(FixedOffset::east_opt)
        .unwrap_or_else(|| offset.fix())
}
