//! `trace router`: a Zenoh router opened from the zenoh library every TRACE binary already
//! links, reading the same JSON5 files `zenohd -c` reads (`deploy/zenoh/two-hosts/`).
//!
//! Why not `zenohd`: it is a second full build of zenoh (with plugins and the admin space we do
//! not use: about 12 minutes on these machines) whose version must be kept equal to ours by
//! hand. The library in `router` mode routes, scouts, terminates QUIC/TLS and enforces access
//! control exactly as `zenohd` does; the binary adds only plugins. A site that wants
//! `zenohd` (for its REST or storage plugins) runs `zenohd -c` on the same files.
//!
//! What the library does not do on its own is say when access control refuses something:
//! Zenoh logs each decision at trace level, among every allowed one. [`log_router`] keeps the
//! refusals and writes each as a warning (`refused by access control: …`, naming the peer,
//! its certificate's common name, the operation and the key), so an operator sees a denied
//! publisher, and the tests wait for that line. The price: with access control on, each message
//! the router decides on is one trace event formatted for [`log_router`]'s filter (a string
//! per message, not a lock or a write).
//!
//! A flood of refused messages does not flood the log ([`Limiter`]): the same refusal (peer,
//! operation, key) is written at most once every 10 s, and at most 50 refusals in all every
//! 10 s; the next line written says how many were not. Zenoh names a peer's certificate only
//! on the first decision for a key, and then only its id; each line this router writes names
//! the certificate, remembered by id.
//!
//! Two more of Zenoh's lines are rewritten, through the same limiter. A connection refused at
//! the QUIC/TLS handshake (an unknown certificate authority, no client certificate) is said as
//! such, with the handshake's reason and without Zenoh's hint about the open-file limit (the
//! acceptor does not give the peer's address). And the errors a client can cause by
//! undeclaring what access control refused to let it declare (`Unknown subscriber`, …: the
//! router never knew it) are not errors of the router: they are dropped.

use std::cell::RefCell;
use std::collections::HashMap;
use std::fmt;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use tracing::field::{Field, Visit};
use tracing_subscriber::filter::{EnvFilter, filter_fn};
use tracing_subscriber::layer::{Context, SubscriberExt};
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{Layer, Registry};

use crate::session::{Role, SessionError, ZenohArgs};

/// The module Zenoh logs its access-control decisions from.
const ACL_TARGET: &str = "zenoh::net::routing::interceptor::access_control";

/// What a refusal in Zenoh's log says (`<zid> on <subject> is unauthorized to <op> on <key>`).
const REFUSED: &str = "is unauthorized to";

/// What Zenoh says of a peer that no subject matches (the default permission then applies to
/// everything it does, without a line per message).
const NO_SUBJECT: &str = "did not match any configured ACL subject";

/// What Zenoh says before it works out, on the same thread, every permission of a key
/// expression a peer declared (one line per kind of message, refused ones included, though
/// nothing was sent yet): those lines are not refusals.
const CACHING: &str = "caching permissions for `";

/// What Zenoh says when a message is decided from that cache.
const CACHED: &str = "Using cached result";

/// The prefix of every refusal this router writes.
pub const REFUSAL: &str = "refused by access control:";

/// The prefix of a connection refused at the handshake, as this router writes it.
pub const HANDSHAKE: &str = "refused a connection at the QUIC/TLS handshake:";

/// What Zenoh's QUIC acceptor says of a handshake that failed.
const ACCEPT_FAILED: &str = "QUIC acceptor failed: ";

/// The module of Zenoh's routing tables, whose errors on an undeclaration of something it
/// never knew a client can cause at will.
const HAT_TARGET: &str = "zenoh::net::routing::hat";

/// Opens the router: the configuration of `args` (file, flags, `--zenoh-set`) in `router`
/// mode, listening on the default loopback endpoint if nothing says otherwise. The router
/// runs until the session is dropped. Returns the session and a `ready` line naming its id
/// and endpoints.
pub async fn open(args: &ZenohArgs) -> Result<(zenoh::Session, String), SessionError> {
    let mut config = args.config(Role::Hub)?;
    config
        .insert_json5("mode", "\"router\"")
        .map_err(|e| SessionError::Config(e.to_string()))?;
    let listen = config
        .get_json("listen/endpoints")
        .unwrap_or_else(|_| "[]".to_owned());
    let acl = config
        .get_json("access_control/enabled")
        .is_ok_and(|v| v == "true");
    let session = zenoh::open(config)
        .await
        .map_err(|e| SessionError::Open(e.to_string()))?;
    let zid = session.info().zid().await;
    tracing::info!(%zid, %listen, acl, "router open");
    let ready = format!(
        "ready router {zid} — listening on {listen}, access control {}",
        if acl { "on" } else { "off" }
    );
    Ok((session, ready))
}

/// Logging for `trace router`: `RUST_LOG` (default: info, Zenoh's own warnings) to stderr, and
/// every operation access control refuses as a warning line starting with [`REFUSAL`].
pub fn log_router() {
    let env =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info,zenoh=warn"));
    let fmt = tracing_subscriber::fmt::layer()
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .with_filter(env);
    let refusals = Refusals.with_filter(filter_fn(|m| m.target().starts_with(ACL_TARGET)));
    Registry::default()
        .with(Rewritten)
        .with(fmt)
        .with(refusals)
        .init();
}

/// Zenoh's lines a peer can cause that this router says otherwise: a handshake refused (said
/// plainly, rate-limited) and undeclarations of what it never knew (dropped).
struct Rewritten;

impl<S: tracing::Subscriber> Layer<S> for Rewritten {
    fn event_enabled(&self, event: &tracing::Event<'_>, _: Context<'_, S>) -> bool {
        let meta = event.metadata();
        let hat = meta.target().starts_with(HAT_TARGET) && *meta.level() == tracing::Level::ERROR;
        let quic = meta.target().contains("quic") && *meta.level() == tracing::Level::WARN;
        if !hat && !quic {
            return true;
        }
        let mut message = Message(String::new());
        event.record(&mut message);
        if hat {
            return !is_unknown_undeclared(&message.0);
        }
        let Some(reason) = handshake_refusal(&message.0) else {
            return true;
        };
        write_limited(HANDSHAKE, &reason);
        false
    }
}

/// Whether a routing-table error is an undeclaration of something the router never knew.
fn is_unknown_undeclared(message: &str) -> bool {
    matches!(
        message,
        "Unknown subscriber" | "Unknown token" | "Unknown id" | "Unknown queryable"
    ) || message.contains("undeclaration in router region with no")
}

/// The reason of a failed QUIC/TLS handshake in Zenoh's warning, if the line is one.
fn handshake_refusal(message: &str) -> Option<String> {
    let at = message.find(ACCEPT_FAILED)?;
    let rest = &message[at + ACCEPT_FAILED.len()..];
    let rest = rest
        .split(" Hint: increase the system open file limit")
        .next()
        .unwrap_or(rest);
    // `ConnectionError(TransportError(Error { code: …, frame: None, reason: "…" }))`: the
    // reason, when there is one.
    let reason = rest
        .split_once("reason: \"")
        .and_then(|(_, r)| r.split_once('"'))
        .map_or(rest.trim(), |(r, _)| r);
    Some(reason.to_owned())
}

/// Keeps the refusals among Zenoh's access-control log events.
struct Refusals;

thread_local! {
    /// The key expression whose permissions this thread is working out, if it is.
    static CACHING_KEY: RefCell<Option<String>> = const { RefCell::new(None) };
}

impl<S: tracing::Subscriber> Layer<S> for Refusals {
    fn on_event(&self, event: &tracing::Event<'_>, _: Context<'_, S>) {
        let mut message = Message(String::new());
        event.record(&mut message);
        if !is_refusal(&message.0) {
            // A decision that names the peer's certificate: remembered for later lines.
            if !message.0.starts_with(CACHED) {
                named(&message.0);
            }
            return;
        }
        let line = named(message.0.trim_start_matches("Using cached result: "));
        write_limited(REFUSAL, &line);
    }
}

/// Writes `prefix line` as a warning if the limiter admits it, saying how many were not.
fn write_limited(prefix: &str, line: &str) {
    let admitted = LIMITER
        .lock()
        .map(|mut l| l.admit(line, Instant::now()))
        .unwrap_or(Some(0));
    if let Some(unlogged) = admitted {
        let more = if unlogged > 0 {
            format!(" ({unlogged} refusals not logged since the last line)")
        } else {
            String::new()
        };
        // Written directly: emitting a tracing event from inside a layer would re-enter it.
        eprintln!("WARN trace::router: {prefix} {line}{more}");
    }
}

/// Peers' certificates, by Zenoh id, as Zenoh named them on a first decision (at most
/// [`REMEMBERED`]; forgotten all at once when full).
static SUBJECTS: Mutex<Option<HashMap<String, String>>> = Mutex::new(None);

/// Learns the certificate a decision line names (`<zid> on <subject> is …`), and gives a
/// refusal line that names only the id (`<zid> is unauthorized …`) its certificate.
fn named(line: &str) -> String {
    let Ok(mut subjects) = SUBJECTS.lock() else {
        return line.to_owned();
    };
    let subjects = subjects.get_or_insert_with(HashMap::new);
    let Some((zid, rest)) = line.split_once(' ') else {
        return line.to_owned();
    };
    if let Some((subject, _)) = rest.strip_prefix("on ").and_then(|r| r.split_once(" is ")) {
        if subjects.len() >= REMEMBERED && !subjects.contains_key(zid) {
            subjects.clear();
        }
        subjects.insert(zid.to_owned(), subject.to_owned());
        return line.to_owned();
    }
    match subjects.get(zid) {
        Some(subject) if rest.starts_with("is ") => format!("{zid} on {subject} {rest}"),
        _ => line.to_owned(),
    }
}

/// How often one refusal is written, and the window of the overall budget.
const EVERY: Duration = Duration::from_secs(10);

/// Refusal lines written at most per [`EVERY`], whatever they are.
const BUDGET: u32 = 50;

/// Different refusals remembered at most (a flood of new keys forgets the oldest first).
const REMEMBERED: usize = 4096;

static LIMITER: Mutex<Limiter> = Mutex::new(Limiter {
    last: None,
    window: None,
    written: 0,
    unlogged: 0,
});

/// Which refusal lines are written: each line at most once every [`EVERY`], at most
/// [`BUDGET`] lines in all per [`EVERY`]; the lines not written are counted.
struct Limiter {
    last: Option<HashMap<String, Instant>>,
    window: Option<Instant>,
    written: u32,
    unlogged: u64,
}

impl Limiter {
    /// Whether `line`, refused at `now`, is written: `Some(n)` with the refusals not written
    /// since the last line that was, `None` when it is not written (it is counted).
    fn admit(&mut self, line: &str, now: Instant) -> Option<u64> {
        let last = self.last.get_or_insert_with(HashMap::new);
        if last
            .get(line)
            .is_some_and(|at| now.duration_since(*at) < EVERY)
        {
            self.unlogged += 1;
            return None;
        }
        if self.window.is_none_or(|w| now.duration_since(w) >= EVERY) {
            self.window = Some(now);
            self.written = 0;
        }
        if self.written >= BUDGET {
            self.unlogged += 1;
            return None;
        }
        if last.len() >= REMEMBERED {
            last.retain(|_, at| now.duration_since(*at) < EVERY);
            if last.len() >= REMEMBERED {
                last.clear();
            }
        }
        last.insert(line.to_owned(), now);
        self.written += 1;
        Some(std::mem::take(&mut self.unlogged))
    }
}

/// Whether a line of Zenoh's access control is a message refused (or a peer that no subject
/// names), telling the permissions worked out for a new key expression apart.
fn is_refusal(line: &str) -> bool {
    CACHING_KEY.with(|caching| {
        let mut caching = caching.borrow_mut();
        if let Some(at) = line.find(CACHING) {
            let key = &line[at + CACHING.len()..];
            *caching = key.split('`').next().map(str::to_owned);
            return false;
        }
        let working_out = !line.starts_with(CACHED)
            && caching
                .as_deref()
                .is_some_and(|key| line.ends_with(&format!(" on {key}")));
        if !working_out {
            *caching = None;
        }
        !working_out && (line.contains(REFUSED) || line.contains(NO_SUBJECT))
    })
}

/// The `message` field of an event.
struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.0 = value.to_owned();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_of_refusals_writes_a_bounded_number_of_lines_and_counts_the_rest() {
        let mut l = Limiter {
            last: None,
            window: None,
            written: 0,
            unlogged: 0,
        };
        let t0 = Instant::now();
        let same =
            "5c6f on CertCommonName(station-a) is unauthorized to Put (ingress) on trace/d/tm/x";
        // The same refusal 1,000 times within a second: written once.
        let written = (0..1000)
            .filter(|i| l.admit(same, t0 + Duration::from_micros(*i)).is_some())
            .count();
        assert_eq!(written, 1);
        // After 10 s it is written again, saying how many were not.
        assert_eq!(l.admit(same, t0 + EVERY), Some(999));
        // 10,000 different refusals within the window: the budget's worth are written.
        let written = (0..10_000)
            .filter(|i| {
                l.admit(
                    &format!("{same}/{i}"),
                    t0 + EVERY + Duration::from_micros(*i),
                )
                .is_some()
            })
            .count();
        assert_eq!(written, BUDGET as usize - 1);
        // The next window writes again, with the count of the ones it left out.
        let next = l.admit("another", t0 + EVERY * 2);
        assert_eq!(next, Some(10_000 - (BUDGET as u64 - 1)));
        assert!(l.last.as_ref().is_some_and(|m| m.len() <= REMEMBERED));
    }

    #[test]
    fn a_refusal_named_only_by_id_is_given_the_certificate_its_first_decision_named() {
        let first = "7a1b on CertCommonName(station-z)+Transport(Quic) is authorized to Put (ingress) on trace/d/act/ground/a/status";
        assert_eq!(named(first), first);
        assert_eq!(
            named("7a1b is unauthorized to Put (ingress) on trace/d/tm/x"),
            "7a1b on CertCommonName(station-z)+Transport(Quic) is unauthorized to Put (ingress) on trace/d/tm/x"
        );
        // An id never seen stays as it is.
        let other = "99ff is unauthorized to Put (ingress) on trace/d/tm/x";
        assert_eq!(named(other), other);
    }

    #[test]
    fn a_failed_handshake_is_said_with_its_reason_and_undeclared_strangers_are_quiet() {
        let warn = r#"QUIC acceptor failed: ConnectionLost(TransportError(Error { code: Code::crypto(2a), frame: None, reason: "invalid peer certificate: UnknownIssuer" })) Hint: increase the system open file limit."#;
        assert_eq!(
            handshake_refusal(warn).as_deref(),
            Some("invalid peer certificate: UnknownIssuer")
        );
        assert_eq!(handshake_refusal("something else"), None);
        assert!(is_unknown_undeclared("Unknown subscriber"));
        assert!(is_unknown_undeclared(
            "Token undeclaration in router region with no resource"
        ));
        assert!(!is_unknown_undeclared("Unknown wire expr"));
    }

    #[test]
    fn permissions_worked_out_for_a_new_key_are_not_refusals_but_decisions_are() {
        let peer = "5c6f on CertCommonName(monitor)+Transport(Tls)";
        let lines = [
            (
                "ACL (ingress): caching permissions for `trace/d/tm/x` ...",
                false,
            ),
            (
                &*format!("{peer} is unauthorized to Put (ingress) on trace/d/tm/x"),
                false,
            ),
            (
                &*format!(
                    "{peer} is authorized to Declare/Undeclare Subscriber (ingress) on trace/d/tm/x"
                ),
                false,
            ),
            (
                &*format!("{peer} is unauthorized to Reply (ingress) on trace/d/tm/x"),
                false,
            ),
            (
                "Using cached result: 5c6f is unauthorized to Put (ingress) on trace/d/tm/x",
                true,
            ),
            (
                &*format!("{peer} is unauthorized to Query (ingress) on trace/d/act/a/goal/1"),
                true,
            ),
            (
                "5c6f did not match any configured ACL subject. Default permission `Deny` will be applied on all messages",
                true,
            ),
            (
                "Using cached result: 5c6f is authorized to Put (ingress) on trace/d/tm/x",
                false,
            ),
        ];
        for (line, refused) in lines {
            assert_eq!(is_refusal(line), refused, "{line}");
        }
    }
}
