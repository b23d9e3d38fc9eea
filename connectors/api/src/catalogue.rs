//! The action catalogue a system serves: its actions with typed goal, result and feedback
//! fields (nested objects included) and the error codes each may raise — the paper's action
//! message definitions, as data the executive checks missions against before they fly.
//!
//! Types are written the way mission models declare them: `int`, `f64`, `string`, `bool`,
//! `timestamp`, `json`, `[T]` for lists, a trailing `?` for optional fields, and a JSON object
//! of fields for a nested message (`"selected_site": {"site_id": "int", "score": "f64"}`).
//! Integers of a fixed width (a ROS 2 `uint8`, an `int32`) are `i8`, `u8`, `i16`, `u16`, `i32`,
//! `u32` and `u64`: a value outside the width's range is refused like a mistyped one.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::wire::Fields;

/// A field's type.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "Value", into = "Value")]
pub enum Type {
    /// 64-bit signed integer.
    Int,
    /// An integer of a fixed width, in its range.
    Sized(Width),
    /// 64-bit float (an integer is accepted).
    Float,
    /// UTF-8 text.
    String,
    /// `true` / `false`.
    Bool,
    /// RFC 3339 text.
    Timestamp,
    /// Anything.
    Json,
    /// A list of one element type.
    List(Box<Type>),
    /// A nested message.
    Object(BTreeMap<String, Type>),
    /// May be absent or null.
    Optional(Box<Type>),
}

impl Type {
    /// Parses the text form (`int`, `[f64]`, `string?`).
    pub fn parse(s: &str) -> Option<Type> {
        let s = s.trim();
        if let Some(inner) = s.strip_suffix('?') {
            return Type::parse(inner).map(|t| Type::Optional(Box::new(t)));
        }
        if let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            return Type::parse(inner).map(|t| Type::List(Box::new(t)));
        }
        Some(match s {
            "int" | "i64" | "integer" | "long" => Type::Int,
            "i8" => Type::Sized(Width::I8),
            "u8" => Type::Sized(Width::U8),
            "i16" => Type::Sized(Width::I16),
            "u16" => Type::Sized(Width::U16),
            "i32" => Type::Sized(Width::I32),
            "u32" => Type::Sized(Width::U32),
            "u64" => Type::Sized(Width::U64),
            "f64" | "float" | "double" | "number" => Type::Float,
            "string" | "str" => Type::String,
            "bool" | "boolean" => Type::Bool,
            "timestamp" => Type::Timestamp,
            "json" | "any" => Type::Json,
            _ => return None,
        })
    }

    /// The type without its optional marker.
    pub fn required(&self) -> &Type {
        match self {
            Type::Optional(t) => t.required(),
            t => t,
        }
    }

    /// Whether a value of type `declared` (the model's declaration) can fill a field of this
    /// type: the same type, an `int` where an `f64` is expected, or `json` on either side.
    pub fn accepts(&self, declared: &Type) -> bool {
        match (self.required(), declared.required()) {
            (Type::Json, _) | (_, Type::Json) => true,
            (Type::Float, Type::Int | Type::Sized(_)) => true,
            // A declared `int` may fit or not: its values are checked when they are sent.
            (Type::Sized(_), Type::Int) | (Type::Int, Type::Sized(_)) => true,
            (Type::Sized(a), Type::Sized(b)) => a.holds(*b),
            (Type::Timestamp, Type::String) | (Type::String, Type::Timestamp) => true,
            (Type::List(a), Type::List(b)) => a.accepts(b),
            (Type::Object(a), Type::Object(b)) => b
                .iter()
                .all(|(k, t)| a.get(k).is_some_and(|at| at.accepts(t))),
            (a, b) => a == b,
        }
    }

    /// Checks a value against this type; the error names the first offending path.
    pub fn check(&self, path: &str, v: &Value) -> Result<(), String> {
        let bad = |want: &Type| Err(format!("`{path}` must be {want}, got {}", kind(v)));
        match (self, v) {
            (Type::Optional(_), Value::Null) => Ok(()),
            (Type::Optional(t), v) => t.check(path, v),
            (Type::Json, _) => Ok(()),
            (Type::Int, Value::Number(n)) if n.is_i64() => Ok(()),
            (Type::Sized(w), Value::Number(n)) if n.is_i64() || n.is_u64() => {
                let x = n
                    .as_i64()
                    .map(i128::from)
                    .or_else(|| n.as_u64().map(i128::from))
                    .unwrap_or_default();
                if w.range().contains(&x) {
                    Ok(())
                } else {
                    Err(format!(
                        "`{path}` is {x}, outside the range of {w} ({}..={})",
                        w.range().start(),
                        w.range().end()
                    ))
                }
            }
            (Type::Float, Value::Number(_)) => Ok(()),
            (Type::String | Type::Timestamp, Value::String(_)) => Ok(()),
            (Type::Bool, Value::Bool(_)) => Ok(()),
            (Type::List(t), Value::Array(items)) => items
                .iter()
                .enumerate()
                .try_for_each(|(i, item)| t.check(&format!("{path}[{i}]"), item)),
            (Type::Object(fields), Value::Object(map)) => check_fields(fields, map, path),
            (t, _) => bad(t),
        }
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a bool",
        Value::Number(n) if n.is_i64() || n.is_u64() => "an int",
        Value::Number(_) => "an f64",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

/// Checks an object's fields: every required field present and typed, no unknown field.
pub fn check_fields(
    spec: &BTreeMap<String, Type>,
    map: &Fields,
    prefix: &str,
) -> Result<(), String> {
    let join = |k: &str| {
        if prefix.is_empty() {
            k.to_owned()
        } else {
            format!("{prefix}.{k}")
        }
    };
    for (k, t) in spec {
        match map.get(k) {
            Some(v) => t.check(&join(k), v)?,
            None if matches!(t, Type::Optional(_)) => {}
            None => return Err(format!("`{}` is missing", join(k))),
        }
    }
    if let Some(k) = map.keys().find(|k| !spec.contains_key(*k)) {
        return Err(format!("`{}` is not a field", join(k)));
    }
    Ok(())
}

impl fmt::Display for Type {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Type::Int => f.write_str("int"),
            Type::Sized(w) => write!(f, "{w}"),
            Type::Float => f.write_str("f64"),
            Type::String => f.write_str("string"),
            Type::Bool => f.write_str("bool"),
            Type::Timestamp => f.write_str("timestamp"),
            Type::Json => f.write_str("json"),
            Type::List(t) => write!(f, "[{t}]"),
            Type::Optional(t) => write!(f, "{t}?"),
            Type::Object(fields) => {
                f.write_str("{")?;
                for (i, (k, t)) in fields.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{k}: {t}")?;
                }
                f.write_str("}")
            }
        }
    }
}

impl TryFrom<Value> for Type {
    type Error = String;
    fn try_from(v: Value) -> Result<Type, String> {
        match v {
            Value::String(s) => Type::parse(&s).ok_or_else(|| format!("unknown type `{s}`")),
            Value::Array(mut items) if items.len() == 1 => {
                Ok(Type::List(Box::new(Type::try_from(items.remove(0))?)))
            }
            Value::Object(map) => map
                .into_iter()
                .map(|(k, v)| Ok((k, Type::try_from(v)?)))
                .collect::<Result<_, String>>()
                .map(Type::Object),
            other => Err(format!(
                "a type is a string, a one-element list or an object, not {other}"
            )),
        }
    }
}

impl From<Type> for Value {
    fn from(t: Type) -> Value {
        match t {
            Type::Object(fields) => Value::Object(
                fields
                    .into_iter()
                    .map(|(k, t)| (k, Value::from(t)))
                    .collect(),
            ),
            Type::List(inner) if matches!(*inner, Type::Object(_)) => {
                Value::Array(vec![Value::from(*inner)])
            }
            t => Value::String(t.to_string()),
        }
    }
}

/// The width of a fixed-width integer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// -128..=127.
    I8,
    /// 0..=255.
    U8,
    /// -32 768..=32 767.
    I16,
    /// 0..=65 535.
    U16,
    /// -2³¹..=2³¹-1.
    I32,
    /// 0..=2³²-1.
    U32,
    /// 0..=2⁶⁴-1.
    U64,
}

impl Width {
    /// The values it holds.
    pub fn range(self) -> std::ops::RangeInclusive<i128> {
        match self {
            Width::I8 => i128::from(i8::MIN)..=i128::from(i8::MAX),
            Width::U8 => 0..=i128::from(u8::MAX),
            Width::I16 => i128::from(i16::MIN)..=i128::from(i16::MAX),
            Width::U16 => 0..=i128::from(u16::MAX),
            Width::I32 => i128::from(i32::MIN)..=i128::from(i32::MAX),
            Width::U32 => 0..=i128::from(u32::MAX),
            Width::U64 => 0..=i128::from(u64::MAX),
        }
    }

    /// Whether every value of `other` is one of its own.
    pub fn holds(self, other: Width) -> bool {
        let (a, b) = (self.range(), other.range());
        a.start() <= b.start() && b.end() <= a.end()
    }
}

impl fmt::Display for Width {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Width::I8 => "i8",
            Width::U8 => "u8",
            Width::I16 => "i16",
            Width::U16 => "u16",
            Width::I32 => "i32",
            Width::U32 => "u32",
            Width::U64 => "u64",
        })
    }
}

/// One action a system serves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActionSpec {
    /// The action name, e.g. `excavation.excavate`.
    pub name: String,
    /// What it does, for people.
    #[serde(default)]
    pub description: String,
    /// Goal fields.
    #[serde(default)]
    pub goal: BTreeMap<String, Type>,
    /// Result fields.
    #[serde(default)]
    pub result: BTreeMap<String, Type>,
    /// Feedback fields.
    #[serde(default)]
    pub feedback: BTreeMap<String, Type>,
    /// Error codes it may raise, with their meaning.
    #[serde(default)]
    pub errors: BTreeMap<String, String>,
    /// What it costs in time and energy, for verification before flight (`None`: undeclared).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cost: Option<crate::cost::Cost>,
}

/// Looks a dotted path (`selected_site.site_id`) up in a message's fields.
pub fn field_at<'s>(fields: &'s BTreeMap<String, Type>, path: &str) -> Option<&'s Type> {
    let mut parts = path.split('.');
    let mut t = fields.get(parts.next()?)?;
    for part in parts {
        match t.required() {
            Type::Object(inner) => t = inner.get(part)?,
            Type::Json => return Some(t),
            _ => return None,
        }
    }
    Some(t)
}

impl ActionSpec {
    /// Checks a goal's fields against the spec (servers refuse mistyped goals with this).
    pub fn check_goal(&self, fields: &Fields) -> Result<(), String> {
        check_fields(&self.goal, fields, "")
    }

    /// Checks a successful result's outputs (the client turns a mistyped result into a task
    /// error with this).
    pub fn check_result(&self, outputs: &Fields) -> Result<(), String> {
        check_fields(&self.result, outputs, "")
    }

    /// Every required result field (nested ones included, as dotted paths) that `outputs`
    /// lacks, with its type: what a `SUCCEEDED` result without (all of) its outputs is told.
    pub fn missing_outputs(&self, outputs: &Fields) -> Vec<(String, Type)> {
        let mut out = Vec::new();
        missing(&self.result, outputs, "", &mut out);
        out
    }

    /// Checks a feedback message's fields against the declared `feedback` fields (all of
    /// them optional: feedback may carry any subset, but nothing undeclared or mistyped).
    pub fn check_feedback(&self, fields: &Fields) -> Result<(), String> {
        for (k, v) in fields {
            match self.feedback.get(k) {
                Some(t) => t.check(k, v)?,
                None => return Err(format!("`{k}` is not a feedback field of `{}`", self.name)),
            }
        }
        Ok(())
    }
}

fn missing(
    spec: &BTreeMap<String, Type>,
    map: &Fields,
    prefix: &str,
    out: &mut Vec<(String, Type)>,
) {
    for (k, t) in spec {
        let path = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match (map.get(k), t) {
            (None, Type::Optional(_)) => {}
            (None, t) => out.push((path, t.clone())),
            (Some(Value::Object(inner)), Type::Object(fields)) => {
                missing(fields, inner, &path, out);
            }
            (Some(_), _) => {}
        }
    }
}

/// What one server serves.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Catalogue {
    /// The server id (`lander_sim`).
    pub server: String,
    /// Its actions.
    pub actions: Vec<ActionSpec>,
    /// The types of the telemetry values it publishes (`<root>/tm/<server>/<channel>`), by
    /// value name: `{"battery_soc_pct": "f64", "comm_window_open": "bool"}`. A value fed to the
    /// mission as system data is checked against its type before it reaches the engine.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub telemetry: BTreeMap<String, Type>,
    /// The battery its actions draw from, for verification before flight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub battery: Option<crate::cost::Battery>,
}

impl Catalogue {
    /// The action named `name`.
    pub fn action(&self, name: &str) -> Option<&ActionSpec> {
        self.actions.iter().find(|a| a.name == name)
    }

    /// Checks one telemetry value against its declared type. A value the catalogue does not
    /// declare must be a plain scalar (a number, a bool or a string; never null, a list or an
    /// object), and of the same kind as `previous`, the last value accepted for that name.
    pub fn check_telemetry(
        &self,
        name: &str,
        value: &Value,
        previous: Option<&Value>,
    ) -> Result<(), String> {
        if let Some(t) = self.telemetry.get(name) {
            return t.check(name, value);
        }
        let scalar = matches!(value, Value::Number(_) | Value::Bool(_) | Value::String(_));
        if !scalar {
            return Err(format!(
                "`{name}` is not declared in the catalogue, so it must be a number, a bool or a \
                 string; got {}",
                kind(value)
            ));
        }
        match previous {
            Some(p) if std::mem::discriminant(p) != std::mem::discriminant(value) => Err(format!(
                "`{name}` was {} and is now {}: an undeclared value keeps its first kind",
                kind(p),
                kind(value)
            )),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn nested_types_parse_and_paths_resolve() {
        let spec: ActionSpec = serde_json::from_value(json!({
            "name": "world_model.select_site",
            "goal": {"map_id": "string", "exclude_ids": "[int]", "min_score": "f64?"},
            "result": {"selected_site": {"site_id": "int", "score": "f64"}},
            "errors": {"NO_VALID_SITE": "no site left"}
        }))
        .unwrap();
        assert_eq!(
            field_at(&spec.result, "selected_site.site_id"),
            Some(&Type::Int)
        );
        assert_eq!(field_at(&spec.result, "selected_site.depth"), None);
        assert!(
            spec.check_goal(
                json!({"map_id": "m", "exclude_ids": [1, 2]})
                    .as_object()
                    .unwrap()
            )
            .is_ok()
        );
        let e = spec
            .check_goal(
                json!({"map_id": "m", "exclude_ids": [1, "x"]})
                    .as_object()
                    .unwrap(),
            )
            .unwrap_err();
        assert_eq!(e, "`exclude_ids[1]` must be int, got a string");
        let e = spec
            .check_goal(json!({"exclude_ids": []}).as_object().unwrap())
            .unwrap_err();
        assert_eq!(e, "`map_id` is missing");
        let back: ActionSpec =
            serde_json::from_value(serde_json::to_value(&spec).unwrap()).unwrap();
        assert_eq!(back, spec);
    }

    #[test]
    fn compatibility_widens_ints_only() {
        assert!(Type::Float.accepts(&Type::Int));
        assert!(!Type::Int.accepts(&Type::Float));
        assert!(Type::List(Box::new(Type::Float)).accepts(&Type::List(Box::new(Type::Int))));
        assert!(!Type::String.accepts(&Type::Bool));
    }

    #[test]
    fn missing_outputs_feedback_and_telemetry_are_named() {
        let spec: ActionSpec = serde_json::from_value(json!({
            "name": "dig",
            "result": {"depth_cm": "f64", "site": {"id": "int", "note": "string?"}, "extra": "int?"},
            "feedback": {"depth_cm": "f64"}
        }))
        .unwrap();
        let none = Fields::new();
        assert_eq!(
            spec.missing_outputs(&none),
            vec![
                ("depth_cm".to_owned(), Type::Float),
                (
                    "site".to_owned(),
                    Type::Object(
                        [
                            ("id".to_owned(), Type::Int),
                            ("note".to_owned(), Type::Optional(Box::new(Type::String)))
                        ]
                        .into()
                    )
                )
            ]
        );
        let partial = json!({"depth_cm": 1.0, "site": {}});
        assert_eq!(
            spec.missing_outputs(partial.as_object().unwrap()),
            vec![("site.id".to_owned(), Type::Int)]
        );
        assert!(
            spec.check_feedback(json!({"depth_cm": 4}).as_object().unwrap())
                .is_ok()
        );
        assert_eq!(
            spec.check_feedback(json!({"depth_cm": "high"}).as_object().unwrap()),
            Err("`depth_cm` must be f64, got a string".to_owned())
        );
        assert!(
            spec.check_feedback(json!({"x": 1}).as_object().unwrap())
                .is_err()
        );

        let cat: Catalogue = serde_json::from_value(json!({
            "server": "s", "actions": [], "telemetry": {"soc": "f64"}
        }))
        .unwrap();
        assert!(cat.check_telemetry("soc", &json!(81.5), None).is_ok());
        for bad in [json!("high"), json!(null), json!([1, 2])] {
            assert!(cat.check_telemetry("soc", &bad, None).is_err(), "{bad}");
        }
        // Undeclared: scalars only, and the kind sticks.
        assert!(cat.check_telemetry("t", &json!(true), None).is_ok());
        assert!(cat.check_telemetry("t", &json!(null), None).is_err());
        assert!(cat.check_telemetry("t", &json!({"a": 1}), None).is_err());
        assert!(
            cat.check_telemetry("t", &json!("x"), Some(&json!(1.0)))
                .is_err()
        );
        assert!(
            cat.check_telemetry("t", &json!(2), Some(&json!(1.0)))
                .is_ok()
        );
        // A catalogue without telemetry serialises as before.
        let plain = Catalogue::default();
        assert!(!serde_json::to_string(&plain).unwrap().contains("telemetry"));
    }
}
