//! # connector-api
//!
//! The contract between the TRACE executive and the systems it drives (paper §3.1–3.2), and
//! the parts of the Zenoh activity protocol that do not depend on Zenoh:
//!
//! - [`contract`]: the [`Connector`] trait (execute, reconcile, abort, catalogue, notify) and
//!   the [`Report`]s a connector sends back (accepted, feedback, done, failed, cancelled,
//!   system data, mission clock, an operator's answer with its [`Verdict`]);
//! - [`keys`]: every key expression of the protocol, built in one place;
//! - [`wire`]: the JSON payloads, status codes and protocol error codes;
//! - [`catalogue`]: the action catalogue with typed (nested) fields and declared error codes;
//! - [`routes`]: the connector configuration mapping resource names to connectors and actions;
//! - [`check`]: the load-time check of a mission against the catalogues.
//!
//! The wire format is specified in `docs/protocol.md`, detailed enough to implement either
//! side in another language.
//!
//! Dependencies: `serde`/`serde_json` (the wire format is JSON, readable from any language and
//! in any log), `thiserror` (typed errors), `tokio::sync` (the report channel: unbounded so a
//! Zenoh callback never blocks on the executive).

pub mod catalogue;
pub mod check;
pub mod contract;
pub mod cost;
pub mod keys;
pub mod routes;
pub mod wire;

pub use catalogue::{ActionSpec, Catalogue, Type};
pub use check::{Mismatch, TaskUse, check};
pub use contract::{Command, Connector, ConnectorError, PeerState, Report, Reports, Verdict};
pub use keys::{Channel, Keys};
pub use routes::{
    ActionRoute, ConnectorConfig, ConnectorsConfig, Kind, Ros2Action, Ros2Settings, Route,
};
pub use wire::{Fields, Status};
