//! # connector-zenoh
//!
//! The activity protocol of `docs/protocol.md` over Zenoh, kept thin: every key comes from
//! `connector_api::keys`, every payload from `connector_api::wire`.
//!
//! - [`ZenohConnector`]: the executive's connector to one server (goals, cancels, state
//!   reconciliation, liveliness and `CONNECTOR_LOST`, bounded waits with backoff and
//!   `NOT_ACCEPTED` / `PROTOCOL_ERROR`, results, feedback and telemetry typed at the door,
//!   every dropped message logged and counted);
//! - [`ActionServer`]: the reusable server side for any system (the lander simulator, the
//!   ground station, test servers);
//! - [`send_answer`]: a ground station's answer to a user task, and the executive's verdict;
//! - [`Fleet`]: the executive of one pool of a collaboration among the others: presence, and
//!   the messages of its message flows, sent until acknowledged, committed before the reply;
//! - [`replies`]: the reply handler of every query, which drops a reply that arrives after
//!   its query stopped being awaited without logging it as an error;
//! - [`ZenohArgs`]: the Zenoh flags and embedded defaults every TRACE binary shares;
//! - [`router`]: `trace router`, a Zenoh router for multi-host deployments that logs what its
//!   access control refuses.
//!
//! Dependencies: `zenoh` 1.10.2 with `default-features = false` and only `transport_tcp` and
//! `transport_quic` (TCP on one host; QUIC, with TLS 1.3 and client certificates, between
//! hosts — not `transport_tls`, whose link shares one rustls stream between reader and writer
//! unsoundly, eclipse-zenoh/zenoh#2557; the other transports cost most of the build); no
//! `zenoh-ext`: results survive link loss through `state` reconciliation on reappearance
//! instead of AdvancedPublisher caches, which also covers executive restarts. `sled` keeps a
//! server's goal table across restarts; `clap` for the shared flags; `flume` (already Zenoh's own
//! channel) for query replies, with the late ones dropped quietly.

mod answer;
mod client;
mod codec;
mod drops;
mod fleet;
pub mod mock;
mod replies;
pub mod router;
mod server;
mod session;

pub use answer::{AnswerError, send_answer};
pub use client::{ClientOptions, ZenohConnector};
pub use fleet::{Fleet, FleetError};
pub use replies::{Replies, replies};
pub use server::{AcceptFn, ActionServer, GoalHandle, Request, ServerError, ServerOptions};
pub use session::{DEFAULT_HUB, Role, SessionError, ZenohArgs, log_to_stderr};
