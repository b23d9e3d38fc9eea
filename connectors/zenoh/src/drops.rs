//! Everything the connector refuses is logged at warn — what, from which key and why — and
//! counted, but never floods the log: at most one line per key per `drop_log_every_ms`, the
//! next line saying how many were not logged in between. The counts are what an operator's
//! monitor shows ([`connector_api::contract::Dropped`]), and tests wait on them.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use connector_api::contract::Dropped;
use tokio::sync::watch;

/// Why a message was dropped: the names are the keys of [`Dropped::by_reason`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reason {
    /// The payload does not parse as what its key carries.
    Garbage,
    /// A status, feedback or result for a goal of this mission that this connector never ran.
    UnknownGoal,
    /// A second result for a goal whose outcome was already reported.
    Duplicate,
    /// Feedback for a goal whose outcome was already reported.
    Late,
    /// A status that cannot appear where it did (a result that is not terminal, `UNKNOWN` on
    /// the status stream, …).
    InvalidStatus,
    /// Feedback or telemetry that does not match its declared type.
    Mistyped,
    /// A mission clock report that is not plausible.
    ImplausibleClock,
    /// A goal, state or cancel reply that could not be understood.
    UnreadableReply,
}

impl Reason {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Reason::Garbage => "garbage",
            Reason::UnknownGoal => "unknown_goal",
            Reason::Duplicate => "duplicate",
            Reason::Late => "late",
            Reason::InvalidStatus => "invalid_status",
            Reason::Mistyped => "mistyped",
            Reason::ImplausibleClock => "implausible_clock",
            Reason::UnreadableReply => "unreadable_reply",
        }
    }
}

/// Keys tracked one by one for rate limiting; past this, the others share one line (a peer
/// publishing on ever new telemetry channels cannot grow the table without bound).
const MAX_KEYS: usize = 1024;
const OTHER_KEYS: &str = "(other keys)";

struct PerKey {
    logged: Instant,
    unlogged: u64,
}

struct Inner {
    keys: HashMap<String, PerKey>,
    counts: Dropped,
}

/// The drop log and counters of one connector.
pub(crate) struct Drops {
    connector: String,
    every: Duration,
    inner: Mutex<Inner>,
    counts: watch::Sender<Dropped>,
}

/// Whether to write a line now, and how many drops on the key went unlogged before it.
#[derive(Debug, PartialEq, Eq)]
enum Verdict {
    Log { unlogged: u64 },
    Quiet,
}

impl Drops {
    pub(crate) fn new(connector: &str, every: Duration) -> Drops {
        Drops {
            connector: connector.to_owned(),
            every,
            inner: Mutex::new(Inner {
                keys: HashMap::new(),
                counts: Dropped::default(),
            }),
            counts: watch::Sender::new(Dropped::default()),
        }
    }

    /// Counts a drop and logs it unless the key was logged less than `every` ago.
    /// `what` is the kind of message (`result`, `feedback`, `goal reply`, …), `goal_id` the
    /// goal it names if any, `why` the reason in words.
    pub(crate) fn drop(&self, reason: Reason, key: &str, what: &str, goal_id: &str, why: &str) {
        let verdict = self.count(reason, key, Instant::now());
        if let Verdict::Log { unlogged } = verdict {
            tracing::warn!(
                connector = self.connector,
                key,
                what,
                goal_id,
                reason = reason.name(),
                unlogged,
                "message dropped: {why}"
            );
        }
    }

    fn count(&self, reason: Reason, key: &str, now: Instant) -> Verdict {
        let mut inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        inner.counts.total += 1;
        *inner
            .counts
            .by_reason
            .entry(reason.name().to_owned())
            .or_default() += 1;
        self.counts.send_replace(inner.counts.clone());
        let slot = if inner.keys.contains_key(key) || inner.keys.len() < MAX_KEYS {
            key
        } else {
            OTHER_KEYS
        };
        match inner.keys.get_mut(slot) {
            Some(k) if now.duration_since(k.logged) < self.every => {
                k.unlogged += 1;
                Verdict::Quiet
            }
            Some(k) => {
                let unlogged = std::mem::take(&mut k.unlogged);
                k.logged = now;
                Verdict::Log { unlogged }
            }
            None => {
                inner.keys.insert(
                    slot.to_owned(),
                    PerKey {
                        logged: now,
                        unlogged: 0,
                    },
                );
                Verdict::Log { unlogged: 0 }
            }
        }
    }

    /// The counts so far.
    pub(crate) fn counts(&self) -> Dropped {
        self.counts.borrow().clone()
    }

    /// The counts, updated on every drop.
    pub(crate) fn watch(&self) -> watch::Receiver<Dropped> {
        self.counts.subscribe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_key_per_period_and_every_drop_counted() {
        let d = Drops::new("lander", Duration::from_secs(10));
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        assert_eq!(
            d.count(Reason::Garbage, "k/a", at(0)),
            Verdict::Log { unlogged: 0 }
        );
        assert_eq!(d.count(Reason::Garbage, "k/a", at(1)), Verdict::Quiet);
        assert_eq!(d.count(Reason::UnknownGoal, "k/a", at(9)), Verdict::Quiet);
        // Another key has its own period.
        assert_eq!(
            d.count(Reason::UnknownGoal, "k/b", at(9)),
            Verdict::Log { unlogged: 0 }
        );
        // Ten seconds on, the next line says how many were not logged.
        assert_eq!(
            d.count(Reason::Garbage, "k/a", at(10)),
            Verdict::Log { unlogged: 2 }
        );
        let c = d.counts();
        assert_eq!(c.total, 5);
        assert_eq!(c.by_reason["garbage"], 3);
        assert_eq!(c.by_reason["unknown_goal"], 2);
        assert_eq!(*d.watch().borrow(), c);
    }

    #[test]
    fn the_key_table_is_bounded() {
        let d = Drops::new("lander", Duration::from_secs(10));
        let now = Instant::now();
        for i in 0..MAX_KEYS + 10 {
            d.count(Reason::Mistyped, &format!("tm/{i}"), now);
        }
        let inner = d.inner.lock().unwrap();
        assert_eq!(inner.keys.len(), MAX_KEYS + 1);
        assert_eq!(inner.keys[OTHER_KEYS].unlogged, 9);
    }
}
