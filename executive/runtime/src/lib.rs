//! executive: the TRACE executive runtime behind the `trace` command.
//!
//! The `trace` binary (crate `executive/cli`) is a thin `main` (argument parsing, logging, exit
//! codes); everything it does is a library function here, so tests and TRACE Studio call it
//! in-process.
//!
//! Dependencies, chosen deliberately:
//! - `clap` (derive) for the command line: subcommands, help and validation for free.
//! - `codespan-reporting` for diagnostics: rustc-style source excerpts with carets, without
//!   hand-formatting, and small (no proc-macros, unlike `miette`).
//! - typed errors (`thiserror`); `anyhow` only in the command line's `main`.
//! - `tracing` + `tracing-subscriber` for logs with an env filter.
//! - `tokio` (current-thread runtime, timers, channels, signals) for the driver loop: one
//!   thread is enough, since the engine step is microseconds and everything else waits.
//! - `chrono` for wall-clock stamps in the execution record.

pub mod catalogues;
pub mod config;
pub mod conformance;
pub mod connectors;
pub mod dataflow;
pub mod driver;
pub mod fly;
pub mod monitor;
pub mod record;
pub mod replay;
pub mod script;
pub mod timeline;
pub mod validate;
pub mod verify;
pub mod waiting;
