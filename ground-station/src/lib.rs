//! # ground-station
//!
//! The ground station answers the user tasks a mission opens (site approvals, decisions after a
//! fault): each open task arrives over Zenoh as a goal of the `ground` server with the task's
//! element, the variables it shows and its deadline; the answer goes back to the executive as
//! an `answer` query and the executive's verdict comes back as the reply (`docs/protocol.md`
//! § Ground stations). Several stations may run: every one sees every task, the first valid
//! answer wins, the others are told who answered.
//!
//! - [`forms`]: the forms (the `ground` catalogue) and typed answers read from text;
//! - [`policy`]: the policy file — per task type a fixed answer, one computed from the task's
//!   context, a delay, or silence;
//! - [`desk`]: the open tasks as an operator sees them;
//! - [`station`]: the Zenoh side — serving the catalogue, receiving tasks and withdrawals,
//!   sending answers;
//! - [`terminal`]: the interactive operator console (`list`, `show`, `answer`).
//!
//! Dependencies: `connector-zenoh` (the action server library: goal table, liveliness,
//! catalogue — the station is one more server of the activity protocol), `cel` (the same
//! expression language as the mission models, so a planner writes policy conditions the way
//! they write gateway conditions), `toml` (the policy file, like the connector configuration),
//! `sled` (the optional goal table across restarts), `clap`, `thiserror`, `tracing`.

pub mod desk;
pub mod forms;
pub mod policy;
pub mod station;
pub mod terminal;
