//! executive-engine: the BPMN 2.0 token engine of TRACE. No I/O, no clock, no randomness, no
//! threads, no hash-ordered collections.
//!
//! [`Engine::step`] takes one journaled [`Input`] (something that happened, stamped with its
//! mission time) and returns the [`Action`]s the driver must perform, after moving every token
//! that can move ("run to quiescence"). The same state and input always give the same state and
//! actions, in the same order, so a journal replays exactly; [`State`] is serde-serializable and
//! `Eq + Hash`, so it can be persisted and model-checked. A refused input ([`Rejected`]) leaves
//! the state unchanged.
//!
//! # Dependencies
//! - `executive-model`: the validated `ProcessGraph`; the engine never sees XML.
//! - `cel`: expressions (conditions, mappings, scripts), compiled once at load, evaluated here.
//! - `chrono`: ISO 8601 timer arithmetic in calendar units.
//! - `serde`: the state and the journal entries are data.
//! - `thin-vec`: a scope's and a token's short lists take one word instead of three, so the
//!   state's ordered maps move 120-byte scopes and 104-byte tokens with inline copies, where
//!   152 and 112 bytes went through calls to `memcpy` (`docs/benchmarks.md`, 2026-12-05).
//! - `smallvec`: a scope's token set keeps its first two tokens inline ([`TokenSet`]), so the
//!   usual scope allocates nothing for them.
//! - `compact_str`: a thrown or caught name in the record ([`Entry::Thrown`], [`Entry::Caught`])
//!   keeps up to 24 bytes inline, where error codes and signal names fit, instead of a copy on
//!   the heap for each entry. Both are written as the text they are.
//! - `thiserror`: [`Rejected`] is a typed error.
//!
//! Every element the loader reads executes, with BPMN 2.0 chapter 13 token semantics; an
//! expression or mapping that fails at run time becomes an *incident* on its token (the instance
//! keeps running, the ground sees the reason). The table below is `docs/engine-semantics.md`.
//!
#![doc = include_str!("../../../docs/engine-semantics.md")]

mod compensation;
mod data;
mod engine;
mod eval;
mod events;
mod feel;
mod game;
mod gateway;
mod io;
mod looping;
mod messages;
mod run;
mod scope;
mod state;
mod throws;
mod value;

pub use compact_str::CompactString;
pub use engine::Engine;
pub use eval::evaluate;
pub use game::Game;
pub use gateway::chosen_from_outside;
pub use io::{
    Action, Entry, Event, Input, InstanceId, Millis, Outcome, Outgoing, Record, Rejected, ScopeId,
    TaskKey, TimerKey, TokenId, Trigger, WaitId,
};
pub use messages::remote_processes;
pub use run::{implicit_starts, resource};
pub use state::{
    At, Compensable, CompensationRun, Handler, Instance, Loop, On, ScopeKind, ScopeState, State,
    Token, TokenSet, Wait,
};
pub use throws::throws;
pub use value::{F64, Value, Vars};

#[cfg(test)]
mod properties;
#[cfg(test)]
mod tests;
