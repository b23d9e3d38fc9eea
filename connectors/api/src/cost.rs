//! What an action costs in time and energy, as a catalogue declares it for verification before
//! flight (`trace verify`'s resource requirements, `docs/protocol.md` §3a): bounds, each fixed or
//! linear in a goal field, that hold for every outcome of the action (success, each failure).
//!
//! ```json
//! "cost": {"duration_s": [1500, {"field": "max_bites", "times": 1500, "default": 8}],
//!          "power_w": 250}
//! ```
//!
//! Energy is the power times the duration; `errors` gives a failure's own bounds where they differ
//! (a link that is not there fails at once). A catalogue's
//! `battery` says what every action's energy comes out of: its capacity and the draw of the
//! system while idle (hotel loads and heaters, on top of which actions draw).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// A quantity: a number, or linear in one goal field (`times × field + plus`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Quantity {
    /// A fixed amount.
    Fixed(f64),
    /// `times × goal[field] + plus`; `default` when the goal leaves the field out.
    Field {
        /// The goal field (a dotted path).
        field: String,
        /// Its factor.
        #[serde(default = "one")]
        times: f64,
        /// The constant added.
        #[serde(default)]
        plus: f64,
        /// The field's value when the goal leaves it out (the system's default).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        default: Option<f64>,
    },
}

fn one() -> f64 {
    1.0
}

/// Lower and upper bounds: `[min, max]`, or one quantity for both.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Value", into = "Value")]
pub struct Bounds {
    /// The least it can be.
    pub min: Quantity,
    /// The most it can be.
    pub max: Quantity,
}

impl TryFrom<Value> for Bounds {
    type Error = String;
    fn try_from(v: Value) -> Result<Bounds, String> {
        let q = |v: Value| {
            serde_json::from_value::<Quantity>(v.clone()).map_err(|_| {
                format!("a bound is a number or {{\"field\", \"times\", \"plus\", \"default\"}}, not {v}")
            })
        };
        match v {
            Value::Array(mut items) if items.len() == 2 => {
                let max = q(items.remove(1))?;
                let min = q(items.remove(0))?;
                Ok(Bounds { min, max })
            }
            Value::Array(_) => Err("bounds are `[min, max]`".into()),
            other => {
                let one = q(other)?;
                Ok(Bounds {
                    min: one.clone(),
                    max: one,
                })
            }
        }
    }
}

impl From<Bounds> for Value {
    fn from(b: Bounds) -> Value {
        let q = |q: Quantity| serde_json::to_value(q).unwrap_or(Value::Null);
        if b.min == b.max {
            q(b.min)
        } else {
            Value::Array(vec![q(b.min), q(b.max)])
        }
    }
}

/// What one action costs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cost {
    /// How long it runs, s.
    pub duration_s: Bounds,
    /// Its average power while it runs, W, on top of the idle draw (its energy is the power
    /// times the duration).
    #[serde(default = "no_power")]
    pub power_w: Bounds,
    /// Result fields that report the battery when the action ends: field path → `soc_pct`
    /// (state of charge, %) or `energy_wh` (energy left, Wh).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub reads: BTreeMap<String, Reading>,
    /// What a failure with a given code costs instead (`duration_s`, `power_w`), when it
    /// differs from the action's own bounds: `{"NO_WINDOW": {"duration_s": 60}}`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub errors: BTreeMap<String, Cost>,
}

fn no_power() -> Bounds {
    Bounds {
        min: Quantity::Fixed(0.0),
        max: Quantity::Fixed(0.0),
    }
}

/// What a result field reports about the battery.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reading {
    /// State of charge, % of the capacity.
    SocPct,
    /// Energy left, Wh.
    EnergyWh,
}

/// The battery every action's energy comes out of.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Battery {
    /// Capacity, Wh (full at the start of the mission).
    pub capacity_wh: f64,
    /// Draw while idle, W (always on, under every action's own).
    pub idle_w: f64,
}

/// A quantity could not be worked out for a goal.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("goal field `{field}` {why}")]
pub struct Unknown {
    /// The field.
    pub field: String,
    /// Why its value is not known.
    pub why: String,
}

impl Quantity {
    /// The amount for a goal whose fields are known where `field` says (`None`: the goal leaves
    /// the field out; `Err`: the model does not fix it).
    pub fn value(
        &self,
        field: impl Fn(&str) -> Result<Option<f64>, String>,
    ) -> Result<f64, Unknown> {
        match self {
            Quantity::Fixed(v) => Ok(*v),
            Quantity::Field {
                field: name,
                times,
                plus,
                default,
            } => {
                let unknown = |why: String| Unknown {
                    field: name.clone(),
                    why,
                };
                let v = match field(name).map_err(unknown)? {
                    Some(v) => v,
                    None => {
                        default.ok_or_else(|| unknown("is not set and has no default".into()))?
                    }
                };
                Ok(times * v + plus)
            }
        }
    }
}

impl Bounds {
    /// `(min, max)` for a goal (see [`Quantity::value`]); the larger if they cross.
    pub fn range(
        &self,
        field: impl Fn(&str) -> Result<Option<f64>, String> + Copy,
    ) -> Result<(f64, f64), Unknown> {
        let lo = self.min.value(field)?;
        let hi = self.max.value(field)?;
        Ok((lo.min(hi).max(0.0), hi.max(lo).max(0.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_read_a_number_a_pair_and_a_goal_field() {
        let c: Cost = serde_json::from_value(serde_json::json!({
            "duration_s": [1500, {"field": "max_bites", "times": 1500, "default": 8}],
            "power_w": 250,
            "reads": {"battery.soc_pct": "soc_pct"}
        }))
        .unwrap();
        let none = |_: &str| Ok(None);
        assert_eq!(c.duration_s.range(none).unwrap(), (1500.0, 12000.0));
        let three = |_: &str| Ok(Some(3.0));
        assert_eq!(c.duration_s.range(three).unwrap(), (1500.0, 4500.0));
        assert_eq!(c.power_w.range(none).unwrap(), (250.0, 250.0));
        let back = serde_json::to_value(&c).unwrap();
        assert_eq!(serde_json::from_value::<Cost>(back).unwrap(), c);
        let unset = serde_json::from_value::<Bounds>(serde_json::json!({"field": "x"})).unwrap();
        assert!(unset.range(none).unwrap_err().to_string().contains("`x`"));
        assert!(serde_json::from_value::<Bounds>(serde_json::json!([1, 2, 3])).is_err());
        assert!(serde_json::from_value::<Bounds>(serde_json::json!("soon")).is_err());
    }
}
