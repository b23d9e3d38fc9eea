//! String built-ins: `substring`, `string length`, `upper case`, `lower case`,
//! `substring before`/`after`, `contains`, `starts with`, `ends with`, the regular-expression
//! functions `replace`, `matches`, `split`, `extract`, and `trim`, `is blank`.
//!
//! Positions count Unicode characters from 1 (negative from the end). Patterns are compiled by
//! the `regex` crate (linear time, compiled size capped), with the XPath flags `i`, `s`, `m`,
//! `x` and `q`; what `regex` does not support (look-around, back-references) gives null with
//! the reason.

use regex::{Regex, RegexBuilder};

use super::{Fail, Out, null, take, text, whole};
use crate::host::Host;
use crate::value::Value;

/// The most memory one compiled pattern may take.
const REGEX_SIZE_LIMIT: usize = 1 << 20;

/// `substring(string, start position)` and `substring(string, start position, length)`: the
/// characters from `start position` (1-based; negative counts from the end), `length` of them
/// or to the end.
pub(super) fn substring(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let n = args.len();
    let [string, start, length] = take(args);
    let s = text(&string, "string")?;
    let start = whole(&start, "start position")?;
    let len = s.chars().count();
    let from = position(start, len).ok_or_else(|| {
        Fail::Null(format!(
            "start position {start} is outside the string (length {len})"
        ))
    })?;
    let count = if n < 3 {
        len - from
    } else {
        let length = whole(&length, "length")?;
        let Ok(length) = usize::try_from(length) else {
            return null(format!("the length {length} is negative"));
        };
        length.min(len - from)
    };
    Ok(Value::String(s.chars().skip(from).take(count).collect()))
}

/// The 0-based index of a 1-based (negative: from the end) position in a sequence of `len`,
/// allowing the position just past the end; `None` for 0 and positions beyond either end.
pub(super) fn position(p: i64, len: usize) -> Option<usize> {
    let len_i = i64::try_from(len).ok()?;
    let i = if p > 0 {
        p - 1
    } else if p < 0 {
        len_i.checked_add(p)?
    } else {
        return None;
    };
    if (0..=len_i).contains(&i) {
        usize::try_from(i).ok()
    } else {
        None
    }
}

/// `string length(string)`: the number of characters.
pub(super) fn length(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string] = take(args);
    let count = text(&string, "string")?.chars().count();
    Ok(Value::Number(count.into()))
}

/// `upper case(string)`.
pub(super) fn upper_case(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string] = take(args);
    Ok(Value::String(text(&string, "string")?.to_uppercase()))
}

/// `lower case(string)`.
pub(super) fn lower_case(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string] = take(args);
    Ok(Value::String(text(&string, "string")?.to_lowercase()))
}

/// The two string arguments `string` and `match`.
fn string_and_match(args: Vec<Value>) -> Result<(String, String), Fail> {
    let [string, pattern] = take(args);
    Ok((
        text(&string, "string")?.to_owned(),
        text(&pattern, "match")?.to_owned(),
    ))
}

/// `substring before(string, match)`: the text before the first occurrence of `match`; empty
/// if there is none.
pub(super) fn before(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let (s, m) = string_and_match(args)?;
    Ok(Value::String(match s.find(&m) {
        Some(i) => s[..i].to_owned(),
        None => String::new(),
    }))
}

/// `substring after(string, match)`: the text after the first occurrence of `match`; empty if
/// there is none (the whole string for an empty `match`).
pub(super) fn after(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let (s, m) = string_and_match(args)?;
    Ok(Value::String(match s.find(&m) {
        Some(i) => s[i + m.len()..].to_owned(),
        None => String::new(),
    }))
}

/// `contains(string, match)`.
pub(super) fn contains(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let (s, m) = string_and_match(args)?;
    Ok(Value::Bool(s.contains(&m)))
}

/// `starts with(string, match)`.
pub(super) fn starts_with(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let (s, m) = string_and_match(args)?;
    Ok(Value::Bool(s.starts_with(&m)))
}

/// `ends with(string, match)`.
pub(super) fn ends_with(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let (s, m) = string_and_match(args)?;
    Ok(Value::Bool(s.ends_with(&m)))
}

/// Compiles `pattern` with XPath `flags` (`i` case-insensitive, `s` dot matches newlines, `m`
/// multi-line anchors, `x` ignore whitespace, `q` literal text).
pub(super) fn regex(pattern: &str, flags: &str) -> Result<Regex, Fail> {
    let literal = flags.contains('q');
    let escaped;
    let source = if literal {
        escaped = regex::escape(pattern);
        escaped.as_str()
    } else {
        pattern
    };
    let mut b = RegexBuilder::new(source);
    b.size_limit(REGEX_SIZE_LIMIT)
        .dfa_size_limit(REGEX_SIZE_LIMIT);
    for c in flags.chars() {
        match c {
            'i' => b.case_insensitive(true),
            's' => b.dot_matches_new_line(true),
            'm' => b.multi_line(true),
            'x' if !literal => b.ignore_whitespace(true),
            'x' | 'q' => &mut b,
            other => {
                return null(format!(
                    "unknown flag {other:?} (the flags are i, s, m, x and q)"
                ));
            }
        };
    }
    b.build().map_err(|e| {
        let why = match &e {
            regex::Error::CompiledTooBig(_) => "it is too big".to_owned(),
            other => {
                let text = other.to_string();
                let last = text.lines().last().unwrap_or_default().trim();
                last.strip_prefix("error: ").unwrap_or(last).to_owned()
            }
        };
        Fail::Null(format!("invalid pattern {pattern:?}: {why}"))
    })
}

/// The `flags` argument of `replace`/`matches`: absent or null means none.
fn flags(v: &Value) -> Result<&str, Fail> {
    match v {
        Value::Null => Ok(""),
        other => text(other, "flags"),
    }
}

/// `replace(input, pattern, replacement)` and `replace(input, pattern, replacement, flags)`:
/// every match of `pattern` replaced; `$1`…`$9` (and `${name}`) in `replacement` insert
/// groups, `\` takes the next character literally (XPath and Java rules).
pub(super) fn replace(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [input, pattern, replacement, fl] = take(args);
    let input = text(&input, "input")?;
    let pattern = text(&pattern, "pattern")?;
    let replacement = text(&replacement, "replacement")?;
    let re = regex(pattern, flags(&fl)?)?;
    let template = template(replacement, &re)?;
    let mut out = String::new();
    let mut last = 0;
    for caps in re.captures_iter(input) {
        let Some(m) = caps.get(0) else { continue };
        out.push_str(&input[last..m.start()]);
        let before = out.len();
        for piece in &template {
            match piece {
                Piece::Text(t) => out.push_str(t),
                Piece::Group(g) => out.push_str(caps.get(*g).map_or("", |m| m.as_str())),
                Piece::Named(g) => out.push_str(caps.name(g).map_or("", |m| m.as_str())),
            }
        }
        host.spend(1 + (out.len() - before) / 64)?;
        last = m.end();
    }
    out.push_str(&input[last..]);
    Ok(Value::String(out))
}

/// A part of a replacement: text, or a group of the match by number or name.
enum Piece {
    Text(String),
    Group(usize),
    Named(String),
}

/// Reads a replacement string. A `$` takes the longest run of digits that names a group of
/// `re` (at least one digit), or `{name}`; `\` escapes the next character.
fn template(replacement: &str, re: &Regex) -> Result<Vec<Piece>, Fail> {
    let groups = re.captures_len();
    let mut out = Vec::new();
    let mut lit = String::new();
    let mut chars = replacement.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' => match chars.next() {
                Some(n) => lit.push(n),
                None => return null("the replacement ends with a lone `\\`"),
            },
            '$' => {
                let piece = match chars.next() {
                    Some('{') => {
                        let mut name = String::new();
                        loop {
                            match chars.next() {
                                Some('}') => break,
                                Some(n) => name.push(n),
                                None => return null("the replacement has `${` without `}`"),
                            }
                        }
                        if let Ok(g) = name.parse::<usize>() {
                            if g >= groups {
                                return null(format!("the pattern has no group {g}"));
                            }
                            Piece::Group(g)
                        } else if re.capture_names().flatten().any(|n| n == name) {
                            Piece::Named(name)
                        } else {
                            return null(format!("the pattern has no group named {name:?}"));
                        }
                    }
                    Some(d) if d.is_ascii_digit() => {
                        let mut g = d.to_digit(10).map_or(0, |d| d as usize);
                        if g >= groups {
                            return null(format!("the pattern has no group {g}"));
                        }
                        while let Some(next) = chars.peek().and_then(|c| c.to_digit(10)) {
                            match g.checked_mul(10).and_then(|x| x.checked_add(next as usize)) {
                                Some(longer) if longer < groups => {
                                    g = longer;
                                    chars.next();
                                }
                                _ => break,
                            }
                        }
                        Piece::Group(g)
                    }
                    _ => {
                        return null(
                            "a `$` in the replacement must be followed by a group number or {name} (write `\\$` for a dollar sign)",
                        );
                    }
                };
                if !lit.is_empty() {
                    out.push(Piece::Text(std::mem::take(&mut lit)));
                }
                out.push(piece);
            }
            c => lit.push(c),
        }
    }
    if !lit.is_empty() {
        out.push(Piece::Text(lit));
    }
    Ok(out)
}

/// `matches(input, pattern)` and `matches(input, pattern, flags)`: whether `pattern` matches
/// somewhere in `input`.
pub(super) fn matches(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [input, pattern, fl] = take(args);
    let input = text(&input, "input")?;
    let pattern = text(&pattern, "pattern")?;
    let re = regex(pattern, flags(&fl)?)?;
    Ok(Value::Bool(re.is_match(input)))
}

/// `split(string, delimiter)`: the parts between matches of the pattern `delimiter`, trailing
/// empty parts kept, as Java's `split(…, -1)` (an empty match at the very start makes no empty
/// first part).
pub(super) fn split(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string, delimiter] = take(args);
    let s = text(&string, "string")?;
    let re = regex(text(&delimiter, "delimiter")?, "")?;
    let mut parts = Vec::new();
    let mut last = 0;
    for m in re.find_iter(s) {
        if m.end() == 0 {
            continue;
        }
        host.spend(1)?;
        parts.push(Value::String(s[last..m.start()].to_owned()));
        last = m.end();
    }
    host.spend(1)?;
    parts.push(Value::String(s[last..].to_owned()));
    Ok(Value::List(parts))
}

/// `extract(input, pattern)`: every match of `pattern` in `input`, in order.
pub(super) fn extract(host: &mut dyn Host, args: Vec<Value>) -> Out {
    let [input, pattern] = take(args);
    let s = text(&input, "input")?;
    let re = regex(text(&pattern, "pattern")?, "")?;
    let mut out = Vec::new();
    for m in re.find_iter(s) {
        host.spend(1)?;
        out.push(Value::String(m.as_str().to_owned()));
    }
    Ok(Value::List(out))
}

/// `trim(string)`: without leading and trailing spaces and control characters (Java's
/// `String.trim`).
pub(super) fn trim(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string] = take(args);
    let s = text(&string, "string")?;
    Ok(Value::String(s.trim_matches(|c: char| c <= ' ').to_owned()))
}

/// `is blank(string)`: whether the string is empty or only whitespace.
pub(super) fn is_blank(_: &mut dyn Host, args: Vec<Value>) -> Out {
    let [string] = take(args);
    let s = text(&string, "string")?;
    Ok(Value::Bool(s.chars().all(char::is_whitespace)))
}

#[cfg(test)]
mod tests {
    use super::super::testing::{Mock, call_with, check, nulls};
    use crate::host::Stop;

    #[test]
    fn substring_counts_characters() {
        check(&[
            ("substring(\"foobar\", 3)", "\"obar\""),
            ("substring(\"foobar\", 3, 3)", "\"oba\""),
            ("substring(\"foobar\", -2, 1)", "\"a\""),
            ("substring(\"foobar\", -2)", "\"ar\""),
            ("substring(\"foobar\", -6, 2)", "\"fo\""),
            ("substring(\"foobar\", 7)", "\"\""),
            ("substring(\"foobar\", 1, 99)", "\"foobar\""),
            ("substring(\"foobar\", 2, 0)", "\"\""),
            ("substring(\"foobar\", 3.9, 2.9)", "\"ob\""),
            ("substring(\"\u{1F600}a\u{e9}b\", 2, 2)", "\"a\u{e9}\""),
            ("substring(\"\u{1F600}\u{1F601}\", -1)", "\"\u{1F601}\""),
        ]);
        nulls(&[
            (
                "substring(\"foobar\", 0)",
                "start position 0 is outside the string (length 6)",
            ),
            ("substring(\"foobar\", 8)", "outside the string"),
            ("substring(\"foobar\", -7)", "outside the string"),
            (
                "substring(\"foobar\", 99999999999999999999)",
                "outside the string",
            ),
            ("substring(\"foobar\", 1, -1)", "the length -1 is negative"),
            ("substring(null, 1)", "`string` is null"),
            ("substring(\"a\", null)", "`start position` is null"),
            (
                "substring(\"a\", \"1\")",
                "`start position` must be a number",
            ),
            ("substring(1, 1)", "`string` must be a string, not a number"),
            ("substring(\"a\", 1, null)", "`length` is null"),
        ]);
    }

    #[test]
    fn length_and_case() {
        check(&[
            ("string length(\"foo\")", "3"),
            ("string length(\"\")", "0"),
            ("string length(\"\u{1F600}\u{e9}\")", "2"),
            ("upper case(\"aBc4\")", "\"ABC4\""),
            ("upper case(\"stra\u{df}e\")", "\"STRASSE\""),
            ("lower case(\"aBc4\")", "\"abc4\""),
        ]);
        nulls(&[
            ("string length(null)", "`string` is null"),
            ("string length(1)", "must be a string"),
            ("upper case(null)", "`string` is null"),
            ("lower case([])", "not a list"),
        ]);
    }

    #[test]
    fn before_after_and_searches() {
        check(&[
            ("substring before(\"foobar\", \"bar\")", "\"foo\""),
            ("substring before(\"foobar\", \"xyz\")", "\"\""),
            ("substring before(\"foobar\", \"\")", "\"\""),
            ("substring after(\"foobar\", \"ob\")", "\"ar\""),
            ("substring after(\"\", \"a\")", "\"\""),
            ("substring after(\"foobar\", \"\")", "\"foobar\""),
            ("substring after(\"\u{e9}t\u{e9}\", \"t\")", "\"\u{e9}\""),
            ("contains(\"foobar\", \"of\")", "false"),
            ("contains(\"foobar\", \"oba\")", "true"),
            ("contains(\"foobar\", \"\")", "true"),
            ("starts with(\"foobar\", \"fo\")", "true"),
            ("starts with(\"foobar\", \"o\")", "false"),
            ("ends with(\"foobar\", \"r\")", "true"),
            ("ends with(\"foobar\", \"b\")", "false"),
        ]);
        nulls(&[
            ("substring before(null, \"a\")", "`string` is null"),
            ("substring after(\"a\", null)", "`match` is null"),
            ("contains(\"a\", 1)", "`match` must be a string"),
            ("starts with(1, \"a\")", "`string` must be a string"),
            ("ends with(null, null)", "`string` is null"),
        ]);
    }

    #[test]
    fn replace_with_groups_and_flags() {
        check(&[
            (
                "replace(\"abcd\", \"(ab)|(a)\", \"[1=$1][2=$2]\")",
                "\"[1=ab][2=]cd\"",
            ),
            (
                r#"replace("0123456789", "(\d{3})(\d{3})(\d{4})", "($1) $2-$3")"#,
                "\"(012) 345-6789\"",
            ),
            ("replace(\"abracadabra\", \"bra\", \"*\")", "\"a*cada*\""),
            ("replace(\"abracadabra\", \"a.*a\", \"*\")", "\"*\""),
            ("replace(\"abracadabra\", \"a.*?a\", \"*\")", "\"*c*bra\""),
            ("replace(\"abracadabra\", \"a\", \"\")", "\"brcdbr\""),
            (
                "replace(\"abracadabra\", \"a(.)\", \"a$1$1\")",
                "\"abbraccaddabbra\"",
            ),
            ("replace(\"AAAA\", \"A+\", \"b\")", "\"b\""),
            ("replace(\"AAAA\", \"A+?\", \"b\")", "\"bbbb\""),
            (
                "replace(\"darted\", \"^(.*?)d(.*)$\", \"$1c$2\")",
                "\"carted\"",
            ),
            ("replace(\"abc\", \"x*\", \"-\")", "\"-a-b-c-\""),
            ("replace(\"abc\", \"B\", \"x\", \"i\")", "\"axc\""),
            ("replace(\"a.c\", \".\", \"x\", \"q\")", "\"axc\""),
            ("replace(\"a b\", \"a b\", \"x\", \"x\")", "\"a b\""),
            ("replace(\"ab\", \"a b\", \"x\", \"x\")", "\"x\""),
            ("replace(\"a\\nb\", \"a.b\", \"x\", \"s\")", "\"x\""),
            ("replace(\"a\\nb\", \"^b\", \"x\", \"m\")", "\"a\\nx\""),
            ("replace(\"ab\", \"(a)\", \"\\\\$1\")", "\"$1b\""),
            ("replace(\"ab\", \"(a)\", \"$11\")", "\"a1b\""),
            ("replace(\"ab\", \"(?P<x>a)\", \"<${x}>\")", "\"<a>b\""),
            ("replace(\"ab\", \"a\", \"[$0]\")", "\"[a]b\""),
            ("replace(\"ab\", \"a\", \"x\", null)", "\"xb\""),
        ]);
        nulls(&[
            ("replace(\"abc\", \"(\", \"x\")", "invalid pattern \"(\""),
            ("replace(\"abc\", \"a(?=b)\", \"x\")", "invalid pattern"),
            ("replace(\"abc\", \"a\", \"$2\")", "no group 2"),
            (
                "replace(\"abc\", \"a\", \"$x\")",
                "must be followed by a group number",
            ),
            ("replace(\"abc\", \"a\", \"x\\\\\")", "lone"),
            ("replace(\"abc\", \"a\", \"${y}\")", "no group named \"y\""),
            ("replace(\"abc\", \"a\", \"${y\")", "without `}`"),
            ("replace(\"abc\", \"a\", \"x\", \"k\")", "unknown flag 'k'"),
            ("replace(null, \"a\", \"x\")", "`input` is null"),
            ("replace(\"a\", null, \"x\")", "`pattern` is null"),
            ("replace(\"a\", \"a\", null)", "`replacement` is null"),
            (
                "replace(\"a\", \"a\", \"b\", 1)",
                "`flags` must be a string",
            ),
        ]);
    }

    #[test]
    fn replace_spends_per_match() {
        let mut host = Mock::new(3);
        assert_eq!(
            call_with(&mut host, "replace(\"aaaaa\", \"a\", \"b\")").err(),
            Some(Stop::Budget(3))
        );
    }

    #[test]
    fn huge_patterns_are_refused() {
        nulls(&[(
            "matches(\"a\", \"\\w{1000}\\w{1000}\\w{1000}\")",
            "invalid pattern",
        )]);
    }

    #[test]
    fn matches_searches() {
        check(&[
            ("matches(\"foobar\", \"^fo*bar\")", "true"),
            ("matches(\"foobar\", \"^fo*b$\")", "false"),
            ("matches(\"foobar\", \"oba\")", "true"),
            ("matches(\"FooBar\", \"foo\")", "false"),
            ("matches(\"FooBar\", \"foo\", \"i\")", "true"),
            ("matches(\"abracadabra\", \"bra\")", "true"),
            ("matches(\"abracadabra\", \"^a.*a$\")", "true"),
            ("matches(\"abracadabra\", \"^bra\")", "false"),
            ("matches(\"a\\nb\", \"a.b\")", "false"),
            ("matches(\"a\\nb\", \"a.b\", \"s\")", "true"),
            ("matches(\"x\\nb\", \"^b$\", \"m\")", "true"),
            ("matches(\"a+b\", \"a+b\", \"q\")", "true"),
            ("matches(\"\u{e9}\", \"^\\w$\")", "true"),
        ]);
        nulls(&[
            ("matches(\"a\", \"[\")", "invalid pattern \"[\""),
            ("matches(\"a\", \"(a)\\1\")", "invalid pattern"),
            ("matches(null, \"a\")", "`input` is null"),
            ("matches(\"a\", 1)", "`pattern` must be a string"),
            ("matches(\"a\", \"a\", \"z\")", "unknown flag"),
        ]);
    }

    #[test]
    fn split_by_pattern() {
        check(&[
            ("split(\"John Doe\", \"\\s\")", "[\"John\", \"Doe\"]"),
            (
                "split(\"a;b;c;;\", \";\")",
                "[\"a\", \"b\", \"c\", \"\", \"\"]",
            ),
            ("split(\";a\", \";\")", "[\"\", \"a\"]"),
            ("split(\"abc\", \"\")", "[\"a\", \"b\", \"c\", \"\"]"),
            ("split(\"\", \",\")", "[\"\"]"),
            ("split(\"a1b22c\", \"[0-9]+\")", "[\"a\", \"b\", \"c\"]"),
        ]);
        nulls(&[
            ("split(null, \",\")", "`string` is null"),
            ("split(\"a\", null)", "`delimiter` is null"),
            ("split(\"a\", \"(\")", "invalid pattern"),
        ]);
    }

    #[test]
    fn extract_matches() {
        check(&[
            (
                "extract(\"references are 1234, 1256, 1378\", \"12[0-9]*\")",
                "[\"1234\", \"1256\"]",
            ),
            ("extract(\"abc\", \"x\")", "[]"),
        ]);
        nulls(&[
            ("extract(null, \"a\")", "`input` is null"),
            ("extract(\"a\", \"+\")", "invalid pattern"),
        ]);
    }

    #[test]
    fn trim_and_blank() {
        check(&[
            ("trim(\"  hello world  \")", "\"hello world\""),
            ("trim(\"hello world \")", "\"hello world\""),
            ("trim(\"\\t\\n x \\n\")", "\"x\""),
            ("trim(\"\")", "\"\""),
            ("is blank(\"\")", "true"),
            ("is blank(\" \")", "true"),
            ("is blank(\" \\t\\n\")", "true"),
            ("is blank(\"hello world\")", "false"),
        ]);
        nulls(&[
            ("trim(null)", "`string` is null"),
            ("is blank(null)", "`string` is null"),
            ("is blank(1)", "must be a string"),
        ]);
    }
}
