//! The token-game mode's settings (`Engine::game`): what the player decides from outside.
//! Its own module so that the step (`run.rs`) reads it without depending on the engine that
//! owns it.

use std::collections::BTreeMap;

use executive_model::NodeId;

/// Token-game mode: the engine as a simulator (model exploration, the studio's token game,
/// replaying the standard's token game). Never used to run a mission.
#[derive(Clone, Debug, Default)]
pub struct Game {
    /// Gateways whose outgoing flows are chosen from outside, by node.
    pub choices: BTreeMap<NodeId, Vec<executive_model::FlowId>>,
    /// Tasks that wait to be completed from outside (dispatched); every other task completes
    /// at once.
    pub hold: std::collections::BTreeSet<NodeId>,
    /// Every diverging gateway waits for its branches to be chosen from outside
    /// ([`crate::Event::BranchTaken`]), one token at a time, unless `fixed` names its branch
    /// (model exploration); a task's result carries no data.
    pub decide: bool,
    /// Gateways whose branch is fixed before the step, taken as the token arrives even where
    /// `decide` would stop it: model exploration runs a step once per branch of each gateway
    /// it reaches, as the engine decides in flight, within the step.
    pub fixed: BTreeMap<NodeId, Vec<executive_model::FlowId>>,
    /// Timers fire as in flight — a duration once, a cycle as often as it repeats — where a
    /// token game's player may otherwise fire a non-interrupting timer again by hand (model
    /// exploration: the translation fires a duration once per activation).
    pub timers: bool,
    /// With `decide`, a multi-instance activity or loop whose count the model writes as a
    /// number (`Looping::literal_count`) runs that many instances or bodies, at most this many;
    /// any other runs one. 0 (the default): one each.
    pub instances: u64,
}
