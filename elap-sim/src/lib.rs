//! # elap-sim
//!
//! The Europa Lander Autonomy Prototype simulator (design `elap-sim.md`): a lander with a
//! battery, heaters, an arm and excavation tool, cameras, instruments, a seismometer, an Earth
//! link with windows, and a world model of sites, samples and data products; and, with
//! `--vehicle scout`, the small hopper of a two-vehicle fleet that flies to candidate sites and
//! surveys them, with its own battery, activities and faults. The scout is a vehicle profile of
//! the same simulator rather than a crate of its own: everything but its activities (the
//! protocol server, the mission clock, telemetry, seeded faults and scripted ones, the world
//! and goal table kept in sled across restarts) is the same, and a second copy of it would be
//! code to keep in step.
//!
//! The core (`world`, `activities`, `faults`, `rng`, `catalogue`) is deterministic and has no
//! I/O and no clock: time and randomness come in from the caller and from a seeded generator
//! kept in the world, so a seed, a fault profile and a scripted fault file give the same run.
//! The `elap-sim` binary is the thin shell that serves the activities over Zenoh with the
//! action server library of `connector-zenoh`, runs the mission clock, publishes telemetry and
//! keeps its world and goal table in sled.
//!
//! Dependencies: `connector-api`/`connector-zenoh` (the protocol, not re-implemented), `sled`
//! (world and goal table survive restarts), `clap`, `serde_json`, `thiserror`, `tokio`,
//! `tracing`. No RNG crate: SplitMix64 is twelve lines and its state is one saved word.

pub mod activities;
pub mod catalogue;
pub mod faults;
pub mod rng;
pub mod world;

pub use activities::{Ended, Plan, Running, Sim};
pub use faults::{Profile, Script};
pub use world::{Vehicle, World};

#[cfg(test)]
mod tests;
