//! # executive-verify
//!
//! Verifies a mission model before it flies (paper §1): the validated model is translated into
//! PROMELA ([`promela`]) and checked with the Spin model checker ([`spin`]) for the built-in
//! properties — no deadlock, safeness, no dead activities, every run ends, no lost signal — and
//! for the mission's LTL requirements ([`requirements`]: a small language over BPMN elements). Each verdict is `holds`, `violated` (with the counterexample as BPMN
//! steps) or `incomplete` (a search bound was hit: never reported as holding).
//!
//! [`explore`] checks the same properties on the executive's own engine, with no translation,
//! so the two can be compared (the differential test).
//!
//! Requirements on mission time and energy are checked by [`timed`]: the engine explored with a
//! clock zone (difference-bound matrices, `zone.rs`) and energy bounds per state, against the
//! costs the systems' catalogues declare ([`resources`]); why this method, there.
//!
//! Spin is an external tool (Debian `spin`, plus a C compiler): it is what the TRACE lineage
//! specifies as the LTL oracle. Dependencies: `executive-model` (the validated graph),
//! `connector-api` (the catalogues' costs), `tracing` (what the timed exploration decides),
//! `executive-engine` (explored natively in token-game mode),
//! `serde`/`serde_json` (the JSON report and counterexamples), `toml` (the requirements file,
//! like the other configuration files), `thiserror`.

pub mod data;
pub mod explore;
pub mod promela;
pub mod requirements;
pub mod resources;
pub mod spin;
pub mod timed;
mod zone;

pub use explore::{Exploration, explore};
pub use promela::{Bounds, Refusal, Step, Translation, translate};
pub use requirements::{Atom, Requirement, RequirementsError};
pub use spin::{Checked, Limits, Ltl, Outcome, SpinError, TraceStep, Verdict, check};
