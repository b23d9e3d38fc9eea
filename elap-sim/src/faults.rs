//! Fault injection: a profile scales the per-call probabilities of the activity catalogue, and
//! scripted faults force a given code at a given action and attempt, so every scenario is
//! reproducible.

use serde::Deserialize;

/// How often faults happen.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Every probability × 0.2.
    Nominal,
    /// The catalogue's probabilities.
    Demanding,
    /// No random faults at all (scripted ones only).
    Quiet,
}

impl Profile {
    /// The factor applied to catalogue probabilities.
    pub fn factor(self) -> f64 {
        match self {
            Profile::Nominal => 0.2,
            Profile::Demanding => 1.0,
            Profile::Quiet => 0.0,
        }
    }
}

/// One forced fault.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scripted {
    /// The action, e.g. `excavation.excavate`.
    pub action: String,
    /// The n-th call of that action in the mission (1-based); all calls if absent.
    #[serde(default)]
    pub call: Option<u32>,
    /// The error code; or `HIGH_POWER_DRAW` (adds `draw_w` to the idle draw, no failure);
    /// or `STALL` (the activity never finishes on its own); or `SLUMP` (assess_slump detects
    /// one); or, for the scout's `survey.site`, `UNSAFE` or `SAFE` (what it finds).
    pub code: String,
    /// For `HIGH_POWER_DRAW`: extra watts.
    #[serde(default)]
    pub draw_w: f64,
}

/// A scripted fault file: `{"faults": [...]}`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Forced faults.
    #[serde(default)]
    pub faults: Vec<Scripted>,
}

impl Script {
    /// The fault forced on call number `call` of `action`, if any.
    pub fn forced(&self, action: &str, call: u32) -> Option<&Scripted> {
        self.faults
            .iter()
            .find(|f| f.action == action && f.call.is_none_or(|c| c == call))
    }
}
