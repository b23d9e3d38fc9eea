//! FEEL values: null, booleans, decimal numbers, strings, the temporal types, lists, contexts,
//! ranges and functions; FEEL equality and ordering.

use std::cmp::Ordering;
use std::fmt;
use std::sync::Arc;

use chrono::{FixedOffset, NaiveDate, NaiveDateTime, NaiveTime, TimeDelta};
use rust_decimal::Decimal;

use crate::ast::Node;

/// A FEEL value.
#[derive(Clone, Debug)]
pub enum Value {
    /// `null`: missing, or the result of an operation that has no answer.
    Null,
    /// `true` / `false`.
    Bool(bool),
    /// A decimal number (28 significant digits).
    Number(Decimal),
    /// Text.
    String(String),
    /// A calendar date.
    Date(NaiveDate),
    /// A time of day, with or without a zone.
    Time(Time),
    /// A date and time, with or without a zone.
    DateTime(DateTime),
    /// A days-and-time duration (`P1DT2H`).
    DayTime(TimeDelta),
    /// A years-and-months duration (`P1Y2M`), in months.
    YearMonth(i64),
    /// A list.
    List(Vec<Value>),
    /// A context: entries in the order they were written.
    Context(Context),
    /// A range `[a..b]`.
    Range(Box<Range>),
    /// A function: built-in or defined in the expression.
    Function(Function),
}

/// A zone: an offset, and the zone id it was written with (`UTC`, `Europe/Paris`), if any.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Zone {
    /// The offset from UTC (for a zone id, its offset at that date and time).
    pub offset: FixedOffset,
    /// The id written after `@`, if the zone was given by id.
    pub id: Option<String>,
}

/// A time of day.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Time {
    /// The local time.
    pub time: NaiveTime,
    /// Its zone; `None` for a local time.
    pub zone: Option<Zone>,
}

/// A date and time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DateTime {
    /// The local date and time.
    pub local: NaiveDateTime,
    /// Its zone; `None` for a local date-time.
    pub zone: Option<Zone>,
}

/// Context entries, in order; keys are unique.
#[derive(Clone, Debug, Default)]
pub struct Context(pub Vec<(String, Value)>);

impl Context {
    /// The value of `key`, if present.
    pub fn get(&self, key: &str) -> Option<&Value> {
        self.0.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    /// Sets `key`, replacing an entry of that name in place or appending.
    pub fn put(&mut self, key: String, value: Value) {
        match self.0.iter_mut().find(|(k, _)| *k == key) {
            Some(slot) => slot.1 = value,
            None => self.0.push((key, value)),
        }
    }
}

/// One end of a range; `None` value means unbounded.
#[derive(Clone, Debug)]
pub struct Bound {
    /// The end point, or `None` for an open-ended range.
    pub value: Option<Value>,
    /// Whether the end point belongs to the range.
    pub closed: bool,
}

/// A range of comparable values.
#[derive(Clone, Debug)]
pub struct Range {
    /// The lower end.
    pub start: Bound,
    /// The upper end.
    pub end: Bound,
}

/// A function value.
#[derive(Clone, Debug)]
pub enum Function {
    /// A built-in function, by name.
    Builtin(&'static str),
    /// `function(a, b) body`, with the names visible where it was defined.
    Lambda(Arc<Lambda>),
}

/// A function defined in an expression.
#[derive(Debug)]
pub struct Lambda {
    /// Parameter names.
    pub params: Vec<String>,
    /// The body.
    pub body: Arc<Node>,
    /// The variables visible where the function was defined.
    pub closure: Vec<(String, Value)>,
}

impl Value {
    /// The FEEL name of the value's type, for messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Null => "null",
            Value::Bool(_) => "boolean",
            Value::Number(_) => "number",
            Value::String(_) => "string",
            Value::Date(_) => "date",
            Value::Time(_) => "time",
            Value::DateTime(_) => "date and time",
            Value::DayTime(_) => "days and time duration",
            Value::YearMonth(_) => "years and months duration",
            Value::List(_) => "list",
            Value::Context(_) => "context",
            Value::Range(_) => "range",
            Value::Function(_) => "function",
        }
    }

    /// Whether this is `null`.
    pub fn is_null(&self) -> bool {
        matches!(self, Value::Null)
    }

    /// A number from an integer.
    pub fn int(i: i64) -> Value {
        Value::Number(Decimal::from(i))
    }

    /// The number, if this is one.
    pub fn as_number(&self) -> Option<Decimal> {
        match self {
            Value::Number(n) => Some(*n),
            _ => None,
        }
    }

    /// The text, if this is a string.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::String(s) => Some(s),
            _ => None,
        }
    }

    /// FEEL equality: `None` where FEEL gives null (values of different kinds that are not
    /// comparable, functions). `null = null` is true; null against a value is false
    /// (Camunda: "comparing null to a value different from null results in false").
    pub fn feel_eq(&self, other: &Value) -> Option<bool> {
        use Value as V;
        Some(match (self, other) {
            (V::Null, V::Null) => true,
            (V::Null, _) | (_, V::Null) => false,
            (V::Bool(a), V::Bool(b)) => a == b,
            (V::Number(a), V::Number(b)) => a == b,
            (V::String(a), V::String(b)) => a == b,
            (V::List(a), V::List(b)) => {
                if a.len() != b.len() {
                    return Some(false);
                }
                for (x, y) in a.iter().zip(b) {
                    if !x.feel_eq(y)? {
                        return Some(false);
                    }
                }
                true
            }
            (V::Context(a), V::Context(b)) => {
                if a.0.len() != b.0.len() {
                    return Some(false);
                }
                for (k, x) in &a.0 {
                    match b.get(k) {
                        Some(y) if x.feel_eq(y)? => {}
                        _ => return Some(false),
                    }
                }
                true
            }
            (V::Range(a), V::Range(b)) => {
                let end = |x: &Bound, y: &Bound| -> Option<bool> {
                    Some(
                        x.closed == y.closed
                            && match (&x.value, &y.value) {
                                (None, None) => true,
                                (Some(p), Some(q)) => p.feel_eq(q)?,
                                _ => false,
                            },
                    )
                };
                end(&a.start, &b.start)? && end(&a.end, &b.end)?
            }
            (V::Function(_), _) | (_, V::Function(_)) => return None,
            (a, b) if a.is_temporal() && b.is_temporal() => crate::temporal::eq(a, b)?,
            _ => return None,
        })
    }

    /// FEEL ordering (`<`, `>`, …): `None` where FEEL gives null (null, different kinds,
    /// unordered kinds such as lists and contexts).
    pub fn compare(&self, other: &Value) -> Option<Ordering> {
        match (self, other) {
            (Value::Number(a), Value::Number(b)) => Some(a.cmp(b)),
            (Value::String(a), Value::String(b)) => Some(a.cmp(b)),
            (a, b) if a.is_temporal() && b.is_temporal() => crate::temporal::compare(a, b),
            _ => None,
        }
    }

    /// Whether this is a date, time, date and time or duration.
    pub fn is_temporal(&self) -> bool {
        matches!(
            self,
            Value::Date(_)
                | Value::Time(_)
                | Value::DateTime(_)
                | Value::DayTime(_)
                | Value::YearMonth(_)
        )
    }
}

/// Formats a decimal as FEEL prints it: no trailing zeros, no exponent.
pub fn number_text(n: &Decimal) -> String {
    n.normalize().to_string()
}

/// Quotes a string as a FEEL literal.
fn quoted(s: &str, f: &mut fmt::Formatter<'_>) -> fmt::Result {
    f.write_str("\"")?;
    for c in s.chars() {
        match c {
            '"' => f.write_str("\\\"")?,
            '\\' => f.write_str("\\\\")?,
            '\n' => f.write_str("\\n")?,
            '\r' => f.write_str("\\r")?,
            '\t' => f.write_str("\\t")?,
            c => write!(f, "{c}")?,
        }
    }
    f.write_str("\"")
}

/// The text FEEL's `string()` gives: strings unquoted, everything else as [`Value`]'s
/// `Display` (which quotes strings inside lists and contexts).
pub fn plain_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Null => f.write_str("null"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Number(n) => f.write_str(&number_text(n)),
            Value::String(s) => quoted(s, f),
            Value::Date(_)
            | Value::Time(_)
            | Value::DateTime(_)
            | Value::DayTime(_)
            | Value::YearMonth(_) => f.write_str(&crate::temporal::text(self)),
            Value::List(items) => {
                f.write_str("[")?;
                for (i, v) in items.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{v}")?;
                }
                f.write_str("]")
            }
            Value::Context(c) => {
                f.write_str("{")?;
                for (i, (k, v)) in c.0.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{k}:{v}")?;
                }
                f.write_str("}")
            }
            Value::Range(r) => {
                let (open, close) = (
                    if r.start.closed { "[" } else { "(" },
                    if r.end.closed { "]" } else { ")" },
                );
                let end = |b: &Bound| b.value.as_ref().map_or(String::new(), |v| v.to_string());
                write!(f, "{open}{}..{}{close}", end(&r.start), end(&r.end))
            }
            Value::Function(Function::Builtin(n)) => write!(f, "function {n}"),
            Value::Function(Function::Lambda(l)) => {
                write!(f, "function({})", l.params.join(", "))
            }
        }
    }
}
