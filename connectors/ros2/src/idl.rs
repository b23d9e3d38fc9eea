//! The ROS 2 interface definition language of `.msg`, `.srv` and `.action` files, as the ROS 2
//! documentation defines it ("About ROS 2 interfaces"): one field or constant per line,
//! `---` between a service's or action's parts, `#` comments.
//!
//! - A field is `TYPE NAME` or `TYPE NAME DEFAULT`; a constant `TYPE NAME=VALUE` (upper-case
//!   name). Field names are lower-case letters, digits and `_`, starting with a letter, with no
//!   `__` and no trailing `_`.
//! - `TYPE` is a primitive (`bool`, `byte`, `char`, `float32`, `float64`, `int8` … `uint64`,
//!   `string`, `wstring`), a bounded string (`string<=N`), or a message: `Name` of the same
//!   package or `package/Name`; then optionally `[]` (unbounded sequence), `[N]` (array of N)
//!   or `[<=N]` (sequence of at most N).
//!
//! Everything wrong is refused with its file and line.

use std::fmt;

/// A primitive or message type, without its array part.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Base {
    /// `bool`
    Bool,
    /// `byte` (an octet).
    Byte,
    /// `char` (an unsigned 8-bit number).
    Char,
    /// `float32`
    Float32,
    /// `float64`
    Float64,
    /// `int8`
    Int8,
    /// `uint8`
    UInt8,
    /// `int16`
    Int16,
    /// `uint16`
    UInt16,
    /// `int32`
    Int32,
    /// `uint32`
    UInt32,
    /// `int64`
    Int64,
    /// `uint64`
    UInt64,
    /// `string`, bounded (`string<=N`) or not.
    String(Option<u64>),
    /// `wstring`, bounded or not.
    WString(Option<u64>),
    /// A message: its package (`None`: the file's own) and name.
    Message {
        /// `geometry_msgs`
        package: Option<String>,
        /// `Point`
        name: String,
    },
}

/// How many of the base a field holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Count {
    /// One.
    One,
    /// `[]`: any number.
    Unbounded,
    /// `[N]`: exactly N.
    Fixed(u64),
    /// `[<=N]`: at most N.
    Bounded(u64),
}

/// A field's or constant's type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldType {
    /// What one element is.
    pub base: Base,
    /// How many.
    pub count: Count,
}

/// One field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    /// Its type.
    pub ty: FieldType,
    /// Its name.
    pub name: String,
    /// Its default value as written, if any.
    pub default: Option<String>,
    /// Its line (from 1).
    pub line: usize,
}

/// One constant.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Constant {
    /// Its type (a primitive or a string).
    pub ty: FieldType,
    /// Its name.
    pub name: String,
    /// Its value as written.
    pub value: String,
}

/// One part of a definition: a message, or a service's or action's request, response, goal,
/// result or feedback.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Part {
    /// Its fields, in order.
    pub fields: Vec<Field>,
    /// Its constants.
    pub constants: Vec<Constant>,
}

/// A definition that cannot be read: where, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}: {reason}")]
pub struct IdlError {
    /// The file.
    pub file: String,
    /// The line (from 1; 0 for the file as a whole).
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

/// Parses a definition file's text into its parts (one for a message, two for a service,
/// three for an action; `parts` says how many it must have).
pub fn parse(text: &str, file: &str, parts: usize) -> Result<Vec<Part>, IdlError> {
    let err = |line: usize, reason: String| IdlError {
        file: file.to_owned(),
        line,
        reason,
    };
    let mut out = vec![Part::default()];
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = strip_comment(raw).trim();
        if content.is_empty() {
            continue;
        }
        if content == "---" {
            out.push(Part::default());
            continue;
        }
        let (ty, rest) = content
            .split_once(char::is_whitespace)
            .ok_or_else(|| err(line, format!("`{content}` is a type without a name")))?;
        let ty = field_type(ty).map_err(|e| err(line, e))?;
        let rest = rest.trim_start();
        let part = out.last_mut().expect("one part at least");
        // A constant: `NAME=VALUE` (spaces allowed around `=`).
        let name_end = rest
            .find(|c: char| c.is_whitespace() || c == '=')
            .unwrap_or(rest.len());
        let (name, after) = rest.split_at(name_end);
        let after = after.trim_start();
        if let Some(value) = after.strip_prefix('=') {
            if !constant_name(name) {
                return Err(err(
                    line,
                    format!(
                        "constant `{name}`: a constant's name is upper-case letters, digits and `_`"
                    ),
                ));
            }
            if ty.count != Count::One || matches!(ty.base, Base::Message { .. }) {
                return Err(err(
                    line,
                    format!("constant `{name}`: a constant is one primitive or string"),
                ));
            }
            let value = value.trim();
            if value.is_empty() {
                return Err(err(line, format!("constant `{name}` has no value")));
            }
            part.constants.push(Constant {
                ty,
                name: name.to_owned(),
                value: value.to_owned(),
            });
            continue;
        }
        if !field_name(name) {
            return Err(err(
                line,
                format!(
                    "field `{name}`: a field's name is lower-case letters, digits and `_`, starting with a letter, without `__` or a trailing `_`"
                ),
            ));
        }
        if part.fields.iter().any(|f| f.name == name) {
            return Err(err(line, format!("field `{name}` is defined twice")));
        }
        let default = (!after.is_empty()).then(|| after.to_owned());
        if default.is_some() && matches!(ty.base, Base::Message { .. }) {
            return Err(err(
                line,
                format!("field `{name}`: a message field has no default value"),
            ));
        }
        part.fields.push(Field {
            ty,
            name: name.to_owned(),
            default,
            line,
        });
    }
    if out.len() != parts {
        return Err(err(
            0,
            format!(
                "{} part(s) separated by `---`, but this kind of definition has {parts}",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// The line without its comment (a `#` outside quotes).
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (Some(_), '\\') if !escaped => {
                escaped = true;
                continue;
            }
            (Some(q), c) if c == q && !escaped => quote = None,
            (None, '"' | '\'') => quote = Some(c),
            (None, '#') => return &line[..i],
            _ => {}
        }
        escaped = false;
    }
    line
}

fn field_name(n: &str) -> bool {
    n.starts_with(|c: char| c.is_ascii_lowercase())
        && n.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        && !n.contains("__")
        && !n.ends_with('_')
}

fn constant_name(n: &str) -> bool {
    n.starts_with(|c: char| c.is_ascii_uppercase())
        && n.chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}

/// Parses a type: base, then an optional array part.
pub fn field_type(text: &str) -> Result<FieldType, String> {
    let (base, count) = match text.find('[') {
        None => (text, Count::One),
        Some(i) => {
            let inner = text[i + 1..]
                .strip_suffix(']')
                .ok_or_else(|| format!("type `{text}`: `[` is not closed"))?;
            let count = if inner.is_empty() {
                Count::Unbounded
            } else if let Some(n) = inner.strip_prefix("<=") {
                Count::Bounded(size(n, text)?)
            } else {
                Count::Fixed(size(inner, text)?)
            };
            (&text[..i], count)
        }
    };
    Ok(FieldType {
        base: base_type(base).ok_or_else(|| format!("`{base}` is not a type"))?,
        count,
    })
}

fn size(n: &str, text: &str) -> Result<u64, String> {
    n.parse::<u64>()
        .ok()
        .filter(|n| *n > 0)
        .ok_or_else(|| format!("type `{text}`: `{n}` is not a size (a number from 1)"))
}

fn base_type(t: &str) -> Option<Base> {
    let bounded = |prefix: &str| -> Option<Option<u64>> {
        let rest = t.strip_prefix(prefix)?;
        if rest.is_empty() {
            return Some(None);
        }
        rest.strip_prefix("<=")?
            .parse::<u64>()
            .ok()
            .filter(|n| *n > 0)
            .map(Some)
    };
    Some(match t {
        "bool" => Base::Bool,
        "byte" => Base::Byte,
        "char" => Base::Char,
        "float32" => Base::Float32,
        "float64" => Base::Float64,
        "int8" => Base::Int8,
        "uint8" => Base::UInt8,
        "int16" => Base::Int16,
        "uint16" => Base::UInt16,
        "int32" => Base::Int32,
        "uint32" => Base::UInt32,
        "int64" => Base::Int64,
        "uint64" => Base::UInt64,
        // ROS 1's names for the builtin time types, which ROS 2 still reads.
        "time" => Base::Message {
            package: Some("builtin_interfaces".into()),
            name: "Time".into(),
        },
        "duration" => Base::Message {
            package: Some("builtin_interfaces".into()),
            name: "Duration".into(),
        },
        _ if t.starts_with("wstring") => Base::WString(bounded("wstring")?),
        _ if t.starts_with("string") => Base::String(bounded("string")?),
        _ => {
            let (package, name) = match t.split('/').collect::<Vec<_>>().as_slice() {
                [name] => (None, *name),
                [package, name] | [package, "msg", name] => (Some((*package).to_owned()), *name),
                _ => return None,
            };
            let word =
                |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !name.starts_with(|c: char| c.is_ascii_uppercase())
                || !word(name)
                || !package.as_deref().is_none_or(word)
            {
                return None;
            }
            Base::Message {
                package,
                name: name.to_owned(),
            }
        }
    })
}

impl fmt::Display for FieldType {
    /// The type as `rclpy` names it (`get_fields_and_field_types`): `int32`, `boolean`,
    /// `octet`, `string<22>`, `sequence<int32, 3>`, `test_msgs/BasicTypes[3]`, … A message of
    /// the file's own package is shown without one (the caller qualifies it).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let base = match &self.base {
            Base::Bool => "boolean".to_owned(),
            Base::Byte => "octet".to_owned(),
            Base::Char => "uint8".to_owned(),
            Base::Float32 => "float".to_owned(),
            Base::Float64 => "double".to_owned(),
            Base::Int8 => "int8".to_owned(),
            Base::UInt8 => "uint8".to_owned(),
            Base::Int16 => "int16".to_owned(),
            Base::UInt16 => "uint16".to_owned(),
            Base::Int32 => "int32".to_owned(),
            Base::UInt32 => "uint32".to_owned(),
            Base::Int64 => "int64".to_owned(),
            Base::UInt64 => "uint64".to_owned(),
            Base::String(None) => "string".to_owned(),
            Base::String(Some(n)) => format!("string<{n}>"),
            Base::WString(None) => "wstring".to_owned(),
            Base::WString(Some(n)) => format!("wstring<{n}>"),
            Base::Message { package, name } => match package {
                Some(p) => format!("{p}/{name}"),
                None => name.clone(),
            },
        };
        match self.count {
            Count::One => f.write_str(&base),
            Count::Fixed(n) => write!(f, "{base}[{n}]"),
            Count::Bounded(n) => write!(f, "sequence<{base}, {n}>"),
            Count::Unbounded => write!(f, "sequence<{base}>"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_constants_defaults_and_arrays() {
        let text = "# goal\nint32 order 5 # how many\nstring<=8 name \"a # b\"\nuint8 MAX=10\n\
                    geometry_msgs/Point[<=3] points\nfloat64[2] xy [1.0, 2.0]\n---\nint32[] sequence\n---\nbool done";
        let parts = parse(text, "F.action", 3).expect("parses");
        let goal = &parts[0];
        assert_eq!(goal.fields.len(), 4);
        assert_eq!(goal.fields[0].default.as_deref(), Some("5"));
        assert_eq!(goal.fields[1].default.as_deref(), Some("\"a # b\""));
        assert_eq!(goal.fields[1].ty.to_string(), "string<8>");
        assert_eq!(goal.constants[0].name, "MAX");
        assert_eq!(
            goal.fields[2].ty.to_string(),
            "sequence<geometry_msgs/Point, 3>"
        );
        assert_eq!(goal.fields[3].ty.to_string(), "double[2]");
        assert_eq!(parts[1].fields[0].ty.to_string(), "sequence<int32>");
        assert_eq!(parts[2].fields[0].line, 10);
    }

    #[test]
    fn what_is_wrong_is_refused_with_its_file_and_line() {
        for (text, parts, line, says) in [
            ("int32 order\nint33 x", 1, 2, "`int33` is not a type"),
            ("int32 Order", 1, 1, "a field's name is lower-case"),
            ("int32 bad__name", 1, 1, "without `__`"),
            ("int32 x\nint32 x", 1, 2, "defined twice"),
            ("int32[<=0] x", 1, 1, "is not a size"),
            ("int32[3 x", 1, 1, "`[` is not closed"),
            ("int32 lower=3", 1, 1, "a constant's name is upper-case"),
            ("Point p 3", 1, 1, "a message field has no default"),
            ("int32 x", 3, 0, "1 part(s)"),
            ("justonetoken", 1, 1, "a type without a name"),
        ] {
            let e = parse(text, "bad.action", parts).expect_err(text);
            assert_eq!(
                (e.file.as_str(), e.line),
                ("bad.action", line),
                "{text}: {e}"
            );
            assert!(e.reason.contains(says), "{text}: {e}");
        }
    }
}
