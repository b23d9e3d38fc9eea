//! JSON conversion built-ins (Camunda 8.9, feel-scala 1.20; DMN 1.6): `from json(value)` reads
//! JSON text into a FEEL value, `to json(value)` writes a FEEL value as JSON text.
//!
//! Both are written here rather than on `serde_json`: without its `preserve_order` and
//! `arbitrary_precision` features (which would change `serde_json` for the whole workspace)
//! it sorts object keys and reads numbers as binary floats, while feel-scala (Jackson) keeps
//! the keys in the order written and every digit of a number. So `from json` is a small
//! strict RFC 8259 reader: objects become contexts in key order as written (a repeated key
//! keeps its first place and takes the last value, as Jackson's `ObjectNode` does), arrays
//! lists, numbers exact decimals read from their text, strings stay strings (`"2023-06-14"` is
//! not turned into a date). Both walk with an explicit stack, never recursing on the depth of
//! the value; `from json` refuses documents nested deeper than [`MAX_DEPTH`].

use std::fmt::Write as _;

use super::conversion::parse_number;
use super::{Entries, Fail, Out, null, take, text};
use crate::host::Host;
use crate::value::{Context, Function, Time, Value, Zone, number_text, plain_text};

/// The deepest nesting of arrays and objects `from json` reads: Jackson's default limit
/// (`StreamReadConstraints.maxNestingDepth`), so what Zeebe reads, this reads.
pub(super) const MAX_DEPTH: usize = 1000;

/// `from json(value)`: the FEEL value of a JSON text; null (with the position of the first
/// error) for text that is not JSON, and for numbers beyond the 28 digits of a decimal.
pub(super) fn from_json(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value] = take(args);
    let json = text(&value, "value")?;
    host.spend(json.len() / 64)?;
    Reader {
        text: json,
        bytes: json.as_bytes(),
        at: 0,
    }
    .document(host)
}

/// An array or object being read.
enum Open {
    /// An array and its items so far.
    Array(Vec<Value>),
    /// An object, its entries so far and the key whose value is being read.
    Object(Entries, String),
}

/// A JSON reader over the text, at a byte offset.
struct Reader<'a> {
    text: &'a str,
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    /// Reads the whole text as one JSON value (surrounded by optional white space).
    fn document(&mut self, host: &mut dyn Host) -> Out {
        let mut open: Vec<Open> = Vec::new();
        loop {
            // A value starts here: a scalar, or an array or object that is opened.
            self.space();
            let mut value = match self.bytes.get(self.at) {
                Some(b'[') => {
                    self.deeper(&open)?;
                    self.at += 1;
                    self.space();
                    if self.eat(b']') {
                        Value::List(Vec::new())
                    } else {
                        open.push(Open::Array(Vec::new()));
                        continue;
                    }
                }
                Some(b'{') => {
                    self.deeper(&open)?;
                    self.at += 1;
                    self.space();
                    if self.eat(b'}') {
                        Value::Context(Context::default())
                    } else {
                        let key = self.key()?;
                        open.push(Open::Object(Entries::default(), key));
                        continue;
                    }
                }
                _ => self.scalar()?,
            };
            host.spend(1)?;
            // Hand the value to the array or object around it, closing those that end here.
            loop {
                match open.last_mut() {
                    None => {
                        self.space();
                        if self.at < self.bytes.len() {
                            return Err(self.error("more text after the JSON value"));
                        }
                        return Ok(value);
                    }
                    Some(Open::Array(items)) => {
                        items.push(value);
                        self.space();
                        if self.eat(b',') {
                            break;
                        }
                        if !self.eat(b']') {
                            return Err(self.error("expected `,` or `]`"));
                        }
                        let Some(Open::Array(items)) = open.pop() else {
                            return Err(self.error("unbalanced array"));
                        };
                        value = Value::List(items);
                    }
                    Some(Open::Object(entries, key)) => {
                        entries.put(std::mem::take(key), value);
                        self.space();
                        if self.eat(b',') {
                            self.space();
                            *key = self.key()?;
                            break;
                        }
                        if !self.eat(b'}') {
                            return Err(self.error("expected `,` or `}`"));
                        }
                        let Some(Open::Object(entries, _)) = open.pop() else {
                            return Err(self.error("unbalanced object"));
                        };
                        value = Value::Context(entries.done());
                    }
                }
                host.spend(1)?;
            }
        }
    }

    /// Fails if the array or object starting here would nest deeper than [`MAX_DEPTH`]
    /// (counting itself, empty or not).
    fn deeper(&self, open: &[Open]) -> Result<(), Fail> {
        if open.len() >= MAX_DEPTH {
            return Err(self.error(&format!("nested deeper than {MAX_DEPTH} levels")));
        }
        Ok(())
    }

    /// An object key and the `:` after it.
    fn key(&mut self) -> Result<String, Fail> {
        if self.bytes.get(self.at) != Some(&b'"') {
            return Err(self.error("expected a key (a string in double quotes)"));
        }
        let key = self.string()?;
        self.space();
        if !self.eat(b':') {
            return Err(self.error("expected `:` after the key"));
        }
        Ok(key)
    }

    /// A string, number, `true`, `false` or `null`.
    fn scalar(&mut self) -> Out {
        let rest = &self.bytes[self.at..];
        for (word, v) in [
            ("true", Value::Bool(true)),
            ("false", Value::Bool(false)),
            ("null", Value::Null),
        ] {
            if rest.starts_with(word.as_bytes()) {
                self.at += word.len();
                return Ok(v);
            }
        }
        match rest.first() {
            Some(b'"') => self.string().map(Value::String),
            Some(b'-' | b'0'..=b'9') => self.number(),
            Some(_) => Err(self.error("expected a value")),
            None => Err(self.error("the text ends where a value was expected")),
        }
    }

    /// A number, by the JSON grammar `-?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?`, as the
    /// exact decimal its text denotes.
    fn number(&mut self) -> Out {
        let start = self.at;
        self.eat(b'-');
        match self.bytes.get(self.at) {
            Some(b'0') => self.at += 1,
            Some(b'1'..=b'9') => self.digits(),
            _ => return Err(self.error("expected a digit")),
        }
        if self.eat(b'.') {
            if !self.bytes.get(self.at).is_some_and(u8::is_ascii_digit) {
                return Err(self.error("expected a digit after `.`"));
            }
            self.digits();
        }
        if self.eat(b'e') || self.eat(b'E') {
            if !self.eat(b'+') {
                self.eat(b'-');
            }
            if !self.bytes.get(self.at).is_some_and(u8::is_ascii_digit) {
                return Err(self.error("expected a digit in the exponent"));
            }
            self.digits();
        }
        let digits = &self.text[start..self.at];
        match parse_number(digits) {
            Ok(n) => Ok(Value::Number(n)),
            Err(why) => {
                let shown: String = digits.chars().take(40).collect();
                let more = if shown.len() < digits.len() {
                    "…"
                } else {
                    ""
                };
                null(format!("the JSON number {shown}{more} is {why}"))
            }
        }
    }

    /// Skips ASCII digits.
    fn digits(&mut self) {
        while self.bytes.get(self.at).is_some_and(u8::is_ascii_digit) {
            self.at += 1;
        }
    }

    /// A string in double quotes, unescaped.
    fn string(&mut self) -> Result<String, Fail> {
        self.at += 1;
        let mut out = String::new();
        loop {
            let run = self.bytes[self.at..]
                .iter()
                .position(|&b| b == b'"' || b == b'\\' || b < 0x20);
            let Some(len) = run else {
                self.at = self.bytes.len();
                return Err(self.error("the string is not closed"));
            };
            out.push_str(&self.text[self.at..self.at + len]);
            self.at += len;
            match self.bytes[self.at] {
                b'"' => {
                    self.at += 1;
                    return Ok(out);
                }
                b'\\' => {
                    self.at += 1;
                    let c = match self.bytes.get(self.at) {
                        Some(b'"') => '"',
                        Some(b'\\') => '\\',
                        Some(b'/') => '/',
                        Some(b'b') => '\u{8}',
                        Some(b'f') => '\u{c}',
                        Some(b'n') => '\n',
                        Some(b'r') => '\r',
                        Some(b't') => '\t',
                        Some(b'u') => {
                            self.at += 1;
                            out.push(self.unicode()?);
                            continue;
                        }
                        _ => return Err(self.error("invalid escape in a string")),
                    };
                    self.at += 1;
                    out.push(c);
                }
                _ => return Err(self.error("a control character in a string must be escaped")),
            }
        }
    }

    /// The character of a `\uXXXX` escape (after the `u`), joining a surrogate pair.
    fn unicode(&mut self) -> Result<char, Fail> {
        let high = self.hex4()?;
        let code = if (0xD800..0xDC00).contains(&high) {
            if !self.bytes[self.at..].starts_with(b"\\u") {
                return Err(self.error("a high surrogate must be followed by a low one"));
            }
            self.at += 2;
            let low = self.hex4()?;
            if !(0xDC00..0xE000).contains(&low) {
                return Err(self.error("a high surrogate must be followed by a low one"));
            }
            0x10000 + ((high - 0xD800) << 10) + (low - 0xDC00)
        } else {
            high
        };
        char::from_u32(code).ok_or_else(|| self.error("a lone low surrogate"))
    }

    /// Four hexadecimal digits.
    fn hex4(&mut self) -> Result<u32, Fail> {
        let digits = self
            .text
            .get(self.at..self.at + 4)
            .filter(|d| d.bytes().all(|b| b.is_ascii_hexdigit()));
        let Some(digits) = digits else {
            return Err(self.error("expected four hexadecimal digits after `\\u`"));
        };
        self.at += 4;
        u32::from_str_radix(digits, 16).map_err(|_| self.error("invalid `\\u` escape"))
    }

    /// Skips JSON white space (space, tab, line feed, carriage return).
    fn space(&mut self) {
        while matches!(self.bytes.get(self.at), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.at += 1;
        }
    }

    /// Steps over `b` if it is next.
    fn eat(&mut self, b: u8) -> bool {
        let here = self.bytes.get(self.at) == Some(&b);
        if here {
            self.at += 1;
        }
        here
    }

    /// The reason for a null: what is wrong, at which character (from 1).
    fn error(&self, what: &str) -> Fail {
        let at = self.at.min(self.text.len());
        let column = self.text.get(..at).map_or(at, |t| t.chars().count()) + 1;
        Fail::Null(format!("not JSON: {what} at character {column}"))
    }
}

/// `to json(value)`: the JSON text of a value. Strings are escaped; numbers written in full
/// without trailing zeros (`1.50` is `1.5`); contexts become objects and lists arrays, in
/// order; `null` is `null`; dates, times, date-times and durations become strings in the form
/// `string()` gives, except that a date-time with a zone id also carries its offset, as
/// feel-scala writes it (`"2023-06-14T14:55:00Z[UTC]"`), and a time with a zone id gives its
/// offset. Ranges and functions have no JSON form: null with the reason (feel-scala writes
/// them as strings of their FEEL text instead).
pub(super) fn to_json(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [value] = take(args);
    write(host, &value).map(Value::String)
}

/// The JSON text of `value`, written with an explicit stack of what remains.
fn write(host: &mut dyn Host, value: &Value) -> Result<String, Fail> {
    let mut out = String::new();
    let mut work = vec![Step::Value(value)];
    while let Some(step) = work.pop() {
        let v = match step {
            Step::Text(t) => {
                out.push_str(t);
                continue;
            }
            Step::Key(k) => {
                write_string(&mut out, k);
                out.push(':');
                continue;
            }
            Step::Value(v) => v,
        };
        host.spend(1)?;
        match v {
            Value::Null => out.push_str("null"),
            Value::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
            Value::Number(n) => out.push_str(&number_text(n)),
            Value::String(s) => {
                host.spend(s.len() / 64)?;
                write_string(&mut out, s);
            }
            Value::List(items) => {
                out.push('[');
                work.push(Step::Text("]"));
                for (i, item) in items.iter().enumerate().rev() {
                    work.push(Step::Value(item));
                    if i > 0 {
                        work.push(Step::Text(","));
                    }
                }
            }
            Value::Context(c) => {
                out.push('{');
                work.push(Step::Text("}"));
                for (i, (k, item)) in c.0.iter().enumerate().rev() {
                    work.push(Step::Value(item));
                    work.push(Step::Key(k));
                    if i > 0 {
                        work.push(Step::Text(","));
                    }
                }
            }
            Value::Range(_) => return null(format!("the range {v} has no JSON form")),
            Value::Function(f) => {
                let name = match f {
                    Function::Builtin(name) => format!("`{name}`"),
                    Function::Lambda(_) => "defined in the expression".to_owned(),
                };
                return null(format!("a function ({name}) has no JSON form"));
            }
            temporal => write_string(&mut out, &iso(temporal)),
        }
    }
    Ok(out)
}

/// What remains to be written.
enum Step<'a> {
    /// A value.
    Value(&'a Value),
    /// Punctuation.
    Text(&'static str),
    /// An object key and its `:`.
    Key(&'a str),
}

/// The text of a temporal value in JSON: as `string()` gives it, but with the offset instead
/// of a zone id (`14:55:00Z` for `14:55:00@UTC`), and for a date-time the zone id after it in
/// brackets, as `java.time.ZonedDateTime` prints (`2023-06-14T14:55:00Z[UTC]`).
fn iso(v: &Value) -> String {
    let offset_only = |z: &Zone| Zone {
        offset: z.offset,
        id: None,
    };
    match v {
        Value::Time(t) if t.zone.as_ref().is_some_and(|z| z.id.is_some()) => {
            plain_text(&Value::Time(Time {
                time: t.time,
                zone: t.zone.as_ref().map(offset_only),
            }))
        }
        Value::DateTime(dt) => match dt.zone.as_ref() {
            Some(z) if z.id.is_some() => {
                let mut local = dt.clone();
                local.zone = Some(offset_only(z));
                let mut out = plain_text(&Value::DateTime(local));
                let _ = write!(out, "[{}]", z.id.as_deref().unwrap_or_default());
                out
            }
            _ => plain_text(v),
        },
        other => plain_text(other),
    }
}

/// Writes `s` as a JSON string: quoted, with `"`, `\` and control characters escaped.
fn write_string(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            '\u{8}' => out.push_str("\\b"),
            '\u{c}' => out.push_str("\\f"),
            c if u32::from(c) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, call_with, check, nulls};
    use super::{MAX_DEPTH, from_json, to_json, write};
    use crate::host::Stop;
    use crate::value::Value;

    /// `from json` of a Rust string (no FEEL escaping to think about).
    fn read(json: &str) -> (Result<Value, String>, Vec<String>) {
        let mut host = Mock::new(10_000_000);
        let out = match from_json(&mut host, vec![Value::String(json.to_owned())]) {
            Ok(v) => Ok(v),
            Err(super::Fail::Null(why)) => Err(why),
            Err(super::Fail::Stop(s)) => Err(format!("stopped: {s}")),
        };
        (out, host.notes)
    }

    /// The FEEL text of `from json(json)`, or `null: reason`.
    fn shown(json: &str) -> String {
        match read(json).0 {
            Ok(v) => v.to_string(),
            Err(why) => format!("null: {why}"),
        }
    }

    #[test]
    fn from_json_reads_values() {
        for (json, want) in [
            (r#"{"a": 1, "b": 2}"#, "{a:1, b:2}"),
            (r#"{"b": 1, "a": 2}"#, "{b:1, a:2}"),
            (r#"{"a": 1, "b": 2, "a": 3}"#, "{a:3, b:2}"),
            ("[1, 2, 3]", "[1, 2, 3]"),
            ("[]", "[]"),
            ("{}", "{}"),
            (" \n\t[ ] \r\n", "[]"),
            ("true", "true"),
            ("false", "false"),
            ("null", "null"),
            ("1", "1"),
            ("-0", "0"),
            ("1.50", "1.5"),
            ("0.1", "0.1"),
            ("1e3", "1000"),
            ("1E-2", "0.01"),
            ("-2.5e+1", "-25"),
            (
                "12345678901234567890.123456789",
                "12345678901234567890.123456789",
            ),
            (r#""a""#, r#""a""#),
            (r#""2023-06-14""#, r#""2023-06-14""#),
            (r#""P1Y""#, r#""P1Y""#),
            (r#""héllo 🐎""#, r#""héllo 🐎""#),
            (
                r#"{"x": [1, {"y": [true, null]}], "z": "w"}"#,
                r#"{x:[1, {y:[true, null]}], z:"w"}"#,
            ),
            (r#"{"total price": 5}"#, "{total price:5}"),
        ] {
            assert_eq!(shown(json), want, "from json({json})");
        }
    }

    #[test]
    fn from_json_unescapes_strings() {
        for (json, want) in [
            (r#""q\"b\\s\/\b\f\n\r\t""#, "q\"b\\s/\u{8}\u{c}\n\r\t"),
            (r#""\u00e9\u0041\u00E9""#, "éAé"),
            (r#""\ud83d\ude00""#, "😀"),
            (r#""\u0000""#, "\u{0}"),
            ("\"\u{7f}é\"", "\u{7f}é"),
        ] {
            assert!(
                matches!(read(json).0, Ok(Value::String(ref s)) if s == want),
                "from json({json})"
            );
        }
    }

    #[test]
    fn from_json_refuses_what_is_not_json() {
        for (json, why) in [
            (
                "",
                "the text ends where a value was expected at character 1",
            ),
            ("{", "expected a key"),
            ("[1,]", "expected a value at character 4"),
            ("[1 2]", "expected `,` or `]` at character 4"),
            (r#"{"a" 1}"#, "expected `:` after the key"),
            (r#"{"a": 1,}"#, "expected a key"),
            ("{a: 1}", "expected a key"),
            (r#"{"a": 1]"#, "expected `,` or `}`"),
            ("[1]]", "more text after the JSON value at character 4"),
            ("invalid", "expected a value at character 1"),
            ("tru", "expected a value"),
            ("True", "expected a value"),
            ("01", "more text after the JSON value at character 2"),
            ("+1", "expected a value"),
            (".5", "expected a value"),
            ("1.", "expected a digit after `.`"),
            ("1e", "expected a digit in the exponent"),
            ("-", "expected a digit"),
            ("NaN", "expected a value"),
            (r#""abc"#, "the string is not closed"),
            (
                "\"a\nb\"",
                "a control character in a string must be escaped",
            ),
            (r#""\x""#, "invalid escape"),
            (r#""\u12""#, "four hexadecimal digits"),
            (
                r#""\ud83d""#,
                "a high surrogate must be followed by a low one",
            ),
            (
                r#""\ud83d\u0041""#,
                "a high surrogate must be followed by a low one",
            ),
            (r#""\ude00""#, "a lone low surrogate"),
            ("'a'", "expected a value"),
            ("[1] // c", "more text after the JSON value"),
            ("1e99", "the JSON number 1e99 is out of range"),
            (
                "99999999999999999999999999999999",
                "the JSON number 99999999999999999999999999999999 is out of range",
            ),
        ] {
            match read(json).0 {
                Err(got) => assert!(got.contains(why), "from json({json:?}): {got}"),
                Ok(v) => panic!("from json({json:?}) = {v}, want null for {why:?}"),
            }
        }
    }

    #[test]
    fn from_json_positions_count_characters() {
        assert_eq!(
            shown(r#"["é", x]"#),
            "null: not JSON: expected a value at character 7"
        );
    }

    #[test]
    fn from_json_arguments() {
        check(&[("from json(\"[1, 2]\")", "[1, 2]")]);
        nulls(&[
            ("from json(null)", "`value` is null"),
            ("from json(1)", "`value` must be a string, not a number"),
            ("from json(\"{\")", "from json: not JSON"),
        ]);
    }

    #[test]
    fn from_json_nesting_is_capped_without_recursion() {
        let deep = |n: usize| format!("{}{}", "[".repeat(n), "]".repeat(n));
        let (ok, _) = read(&deep(MAX_DEPTH));
        let value = ok.expect("the deepest allowed nesting reads");
        // The value prints and converts back without overflowing the stack.
        let mut host = Mock::new(10_000_000);
        let json = to_json(&mut host, vec![value.clone()]);
        assert!(matches!(json, Ok(Value::String(ref s)) if s.len() == 2 * MAX_DEPTH));
        assert_eq!(value.to_string().len(), 2 * MAX_DEPTH);
        drop(value);
        let (too_deep, _) = read(&deep(MAX_DEPTH + 1));
        assert!(too_deep.is_err_and(|why| why.contains("nested deeper than 1000 levels")));
        let (huge, _) = read(&"[".repeat(1_000_000));
        assert!(huge.is_err());
        let objects = format!("{}1{}", r#"{"a":"#.repeat(MAX_DEPTH), "}".repeat(MAX_DEPTH));
        assert!(read(&objects).0.is_ok());
    }

    #[test]
    fn from_json_spends_per_value_and_text() {
        let mut host = Mock::new(5);
        assert_eq!(
            call_with(&mut host, "from json(\"[1, 2, 3, 4, 5, 6]\")").err(),
            Some(Stop::Budget(5))
        );
        let mut host = Mock::new(1_000_000);
        let long = format!("\"{}\"", "a".repeat(6400));
        let _ = from_json(&mut host, vec![Value::String(long)]);
        assert!(host.spent >= 100, "spent {}", host.spent);
    }

    #[test]
    fn to_json_writes_values() {
        check(&[
            ("to json({a: 1, b: 2})", r#""{\"a\":1,\"b\":2}""#),
            ("to json({b: 1, a: 2})", r#""{\"b\":1,\"a\":2}""#),
            ("to json(true)", r#""true""#),
            ("to json(null)", r#""null""#),
            ("to json(1)", r#""1""#),
            ("to json(1.50)", r#""1.5""#),
            ("to json(-0.001)", r#""-0.001""#),
            (
                "to json(79228162514264337593543950335)",
                r#""79228162514264337593543950335""#,
            ),
            ("to json(\"a\")", r#""\"a\"""#),
            ("to json(\"\")", r#""\"\"""#),
            (
                "to json([1, \"a\", null, [true]])",
                r#""[1,\"a\",null,[true]]""#,
            ),
            ("to json([])", r#""[]""#),
            ("to json({})", r#""{}""#),
            (
                "to json({a: {b: [1, {c: null}]}})",
                r#""{\"a\":{\"b\":[1,{\"c\":null}]}}""#,
            ),
            ("to json({\"total price\": 5})", r#""{\"total price\":5}""#),
        ]);
        nulls(&[
            (
                "to json([1..5))",
                "to json: the range [1..5) has no JSON form",
            ),
            ("to json({a: [(..0]]})", "the range (..0] has no JSON form"),
            ("to json(@not)", "a function (`not`) has no JSON form"),
            ("to json([1, @sum])", "a function (`sum`) has no JSON form"),
        ]);
    }

    #[test]
    fn to_json_escapes_strings() {
        let mut host = Mock::new(1000);
        let s = "q\"b\\s/\u{8}\u{c}\n\r\t\u{1}\u{1f}é😀\u{7f}";
        let out = to_json(&mut host, vec![Value::String(s.to_owned())]);
        let Ok(Value::String(json)) = out else {
            panic!("a string")
        };
        assert_eq!(
            json,
            "\"q\\\"b\\\\s/\\b\\f\\n\\r\\t\\u0001\\u001fé😀\u{7f}\""
        );
        // And back again.
        assert!(matches!(read(&json).0, Ok(Value::String(back)) if back == s));
        // Keys are escaped too.
        let mut host = Mock::new(1000);
        let c = crate::value::Context(vec![("a\"b".to_owned(), Value::int(1))]);
        let out = to_json(&mut host, vec![Value::Context(c)]);
        assert!(matches!(out, Ok(Value::String(ref j)) if j == "{\"a\\\"b\":1}"));
    }

    #[test]
    fn to_json_round_trips_through_from_json() {
        for json in [
            r#"{"b":[1,2.5,{"c":null}],"a":"x","d":true}"#,
            "[]",
            r#"[[[[]]],{}]"#,
            r#""2023-06-14""#,
            "-12.75",
        ] {
            let (v, _) = read(json);
            let mut host = Mock::new(1000);
            let back = to_json(&mut host, vec![v.expect("JSON")]);
            assert!(
                matches!(back, Ok(Value::String(ref s)) if s == json),
                "{json} came back as {back:?}"
            );
        }
    }

    #[test]
    fn to_json_writes_temporal_values_as_strings() {
        use chrono::{FixedOffset, NaiveDate, NaiveTime, TimeDelta};

        use crate::value::{DateTime, Time, Zone};
        let date = NaiveDate::from_ymd_opt(2023, 6, 14).unwrap_or_default();
        let time = NaiveTime::from_hms_opt(14, 55, 0).unwrap_or_default();
        let utc = FixedOffset::east_opt(0).expect("UTC");
        let plus2 = FixedOffset::east_opt(7200).expect("+02:00");
        let zone = |offset, id: Option<&str>| {
            Some(Zone {
                offset,
                id: id.map(str::to_owned),
            })
        };
        let dt = |zone| {
            Value::DateTime(DateTime {
                local: date.and_time(time),
                zone,
            })
        };
        let t = |zone| Value::Time(Time { time, zone });
        for (v, want) in [
            (Value::Date(date), "\"2023-06-14\""),
            (t(None), "\"14:55:00\""),
            (t(zone(plus2, None)), "\"14:55:00+02:00\""),
            (t(zone(utc, Some("UTC"))), "\"14:55:00Z\""),
            (dt(None), "\"2023-06-14T14:55:00\""),
            (dt(zone(utc, None)), "\"2023-06-14T14:55:00Z\""),
            (dt(zone(plus2, None)), "\"2023-06-14T14:55:00+02:00\""),
            (dt(zone(utc, Some("UTC"))), "\"2023-06-14T14:55:00Z[UTC]\""),
            (
                dt(zone(plus2, Some("Europe/Berlin"))),
                "\"2023-06-14T14:55:00+02:00[Europe/Berlin]\"",
            ),
            (Value::DayTime(TimeDelta::hours(2)), "\"PT2H\""),
            (Value::YearMonth(18), "\"P1Y6M\""),
            (
                Value::List(vec![Value::Date(date), Value::YearMonth(36)]),
                "[\"2023-06-14\",\"P3Y\"]",
            ),
        ] {
            let mut host = Mock::new(1000);
            let out = to_json(&mut host, vec![v.clone()]);
            assert!(
                matches!(out, Ok(Value::String(ref s)) if s == want),
                "to json({v}) = {out:?}, want {want}"
            );
        }
    }

    #[test]
    fn to_json_spends_and_walks_without_recursion() {
        let mut host = Mock::new(3);
        assert_eq!(
            call_with(&mut host, "to json([1, 2, 3, 4])").err(),
            Some(Stop::Budget(3))
        );
        let mut deep = Value::List(Vec::new());
        for _ in 0..100_000 {
            deep = Value::List(vec![deep]);
        }
        let mut host = Mock::new(10_000_000);
        let out = write(&mut host, &deep);
        assert!(matches!(out, Ok(ref s) if s.len() == 200_002));
        // Taken apart level by level: dropping it whole would recurse.
        while let Value::List(mut items) = deep {
            deep = items.pop().unwrap_or(Value::Null);
        }
    }
}
