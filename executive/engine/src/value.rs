//! Variable values: a JSON-like enum that is totally ordered, so engine state is `Eq` and `Ord`.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

/// Variables by name, in a fixed order.
pub type Vars = BTreeMap<String, Value>;

/// A variable value. Floats compare by bits order (`total_cmp`), so a `Value` is `Eq + Ord`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Value {
    /// JSON `null`.
    Null,
    /// `true` / `false`.
    Bool(bool),
    /// A whole number.
    Int(i64),
    /// A floating-point number.
    Float(F64),
    /// Text.
    String(String),
    /// A list.
    List(Vec<Value>),
    /// An object with named fields.
    Map(BTreeMap<String, Value>),
}

/// An `f64` ordered and compared by `total_cmp`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(transparent)]
pub struct F64(pub f64);

impl PartialEq for F64 {
    fn eq(&self, other: &Self) -> bool {
        self.0.total_cmp(&other.0).is_eq()
    }
}
impl Eq for F64 {}
impl PartialOrd for F64 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for F64 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}
impl std::hash::Hash for F64 {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.0.to_bits().hash(state);
    }
}

impl Value {
    /// The JSON name of the value's type, for messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Null => "null",
            Value::Bool(_) => "bool",
            Value::Int(_) => "int",
            Value::Float(_) => "f64",
            Value::String(_) => "string",
            Value::List(_) => "list",
            Value::Map(_) => "object",
        }
    }

    /// The value at a dotted path (`selected_site.site_id`), if every step exists.
    pub fn at_path(&self, path: &str) -> Option<&Value> {
        path.split('.').try_fold(self, |v, key| match v {
            Value::Map(m) => m.get(key),
            _ => None,
        })
    }

    /// Converts to a CEL value for expression evaluation.
    pub fn to_cel(&self) -> cel::Value {
        match self {
            Value::Null => cel::Value::Null,
            Value::Bool(b) => cel::Value::Bool(*b),
            Value::Int(i) => cel::Value::Int(*i),
            Value::Float(f) => cel::Value::Float(f.0),
            Value::String(s) => cel::Value::String(Arc::new(s.clone())),
            Value::List(l) => cel::Value::List(Arc::new(l.iter().map(Value::to_cel).collect())),
            Value::Map(m) => {
                let map: std::collections::HashMap<cel::objects::Key, cel::Value> = m
                    .iter()
                    .map(|(k, v)| (cel::objects::Key::from(k.clone()), v.to_cel()))
                    .collect();
                cel::Value::Map(cel::objects::Map { map: Arc::new(map) })
            }
        }
    }

    /// Converts a CEL result back. Durations and timestamps become ISO 8601 text; bytes,
    /// functions and opaque values are refused.
    pub fn from_cel(v: &cel::Value) -> Result<Value, String> {
        Ok(match v {
            cel::Value::Null => Value::Null,
            cel::Value::Bool(b) => Value::Bool(*b),
            cel::Value::Int(i) => Value::Int(*i),
            cel::Value::UInt(u) => {
                Value::Int(i64::try_from(*u).map_err(|_| format!("{u} does not fit in an int"))?)
            }
            cel::Value::Float(f) => Value::Float(F64(*f)),
            cel::Value::String(s) => Value::String(s.as_str().to_owned()),
            cel::Value::List(l) => {
                Value::List(l.iter().map(Value::from_cel).collect::<Result<_, _>>()?)
            }
            cel::Value::Map(m) => {
                let mut out = BTreeMap::new();
                for (k, v) in m.map.iter() {
                    let key = match k {
                        cel::objects::Key::String(s) => s.as_str().to_owned(),
                        cel::objects::Key::Int(i) => i.to_string(),
                        cel::objects::Key::Uint(u) => u.to_string(),
                        cel::objects::Key::Bool(b) => b.to_string(),
                    };
                    out.insert(key, Value::from_cel(v)?);
                }
                Value::Map(out)
            }
            other => {
                return Err(format!(
                    "an expression produced an unsupported value {other:?}"
                ));
            }
        })
    }

    /// Converts from JSON (numbers without a fraction become `Int`).
    pub fn from_json(v: &serde_json::Value) -> Value {
        match v {
            serde_json::Value::Null => Value::Null,
            serde_json::Value::Bool(b) => Value::Bool(*b),
            serde_json::Value::Number(n) => match n.as_i64() {
                Some(i) => Value::Int(i),
                None => Value::Float(F64(n.as_f64().unwrap_or(f64::NAN))),
            },
            serde_json::Value::String(s) => Value::String(s.clone()),
            serde_json::Value::Array(a) => Value::List(a.iter().map(Value::from_json).collect()),
            serde_json::Value::Object(o) => Value::Map(
                o.iter()
                    .map(|(k, v)| (k.clone(), Value::from_json(v)))
                    .collect(),
            ),
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match serde_json::to_string(self) {
            Ok(s) => f.write_str(&s),
            Err(_) => write!(f, "{self:?}"),
        }
    }
}

impl From<i64> for Value {
    fn from(v: i64) -> Value {
        Value::Int(v)
    }
}
impl From<f64> for Value {
    fn from(v: f64) -> Value {
        Value::Float(F64(v))
    }
}
impl From<bool> for Value {
    fn from(v: bool) -> Value {
        Value::Bool(v)
    }
}
impl From<&str> for Value {
    fn from(v: &str) -> Value {
        Value::String(v.to_owned())
    }
}
impl From<String> for Value {
    fn from(v: String) -> Value {
        Value::String(v)
    }
}
