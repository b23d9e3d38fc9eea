//! The FEEL lexer: text → tokens with byte spans. Names are Java identifiers or backticked;
//! a built-in function's multi-word name (`string join`), or that of a function the engine
//! refuses (`random number`), is one token when a `(` follows. `?` (the tested value inside the
//! tests after `in`) is a name token of its own.

use rust_decimal::Decimal;

use crate::ast::Span;

/// A token.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    /// A number literal.
    Number(Decimal),
    /// A string literal, escapes resolved.
    String(String),
    /// `@"…"`: a temporal literal's text.
    At(String),
    /// A name (keywords included: the parser tells them apart); `quoted` for backticked names,
    /// which are never keywords.
    Name { text: String, quoted: bool },
    /// Punctuation and operators: `( ) [ ] { } , : . .. + - * / ** = != < <= > >=`.
    Punct(&'static str),
}

/// A token and where it was written.
#[derive(Clone, Debug)]
pub(crate) struct Token {
    pub(crate) tok: Tok,
    pub(crate) span: Span,
}

const PUNCTS: [&str; 21] = [
    "..", "**", "!=", "<=", ">=", "(", ")", "[", "]", "{", "}", ",", ":", ".", "+", "-", "*", "/",
    "=", "<", ">",
];

fn is_name_start(c: char) -> bool {
    c.is_alphabetic() || c == '_' || c == '$'
}

fn is_name_part(c: char) -> bool {
    c.is_alphanumeric() || c == '_' || c == '$'
}

/// Splits `text` into tokens, or says what is wrong and where.
pub(crate) fn lex(text: &str) -> Result<Vec<Token>, (String, Span)> {
    let multi: Vec<&'static str> = {
        let mut m: Vec<&'static str> = crate::host::all()
            .map(|b| b.name)
            .chain(crate::check::NOT_DETERMINISTIC.iter().copied())
            .filter(|n| n.contains(' '))
            .collect();
        m.sort_by_key(|n| std::cmp::Reverse(n.len()));
        m.dedup();
        m
    };
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < text.len() {
        let rest = &text[i..];
        let Some(c) = rest.chars().next() else { break };
        if c.is_whitespace() {
            i += c.len_utf8();
            continue;
        }
        // Comments: `//` to the end of the line, `/* … */`.
        if rest.starts_with("//") {
            i += rest.find('\n').unwrap_or(rest.len());
            continue;
        }
        if let Some(body) = rest.strip_prefix("/*") {
            let Some(end) = body.find("*/") else {
                return Err((
                    "a comment `/*` is not closed".to_owned(),
                    span(i, text.len()),
                ));
            };
            i += end + 4;
            continue;
        }
        let start = i;
        if c.is_ascii_digit() || (c == '.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            let (n, len) = number(rest).map_err(|m| (m, span(start, start + 1)))?;
            i += len;
            out.push(Token {
                tok: Tok::Number(n),
                span: span(start, i),
            });
            continue;
        }
        if c == '"' {
            let (s, len) = string(rest, start)?;
            i += len;
            out.push(Token {
                tok: Tok::String(s),
                span: span(start, i),
            });
            continue;
        }
        if c == '@' {
            if !rest[1..].starts_with('"') {
                return Err((
                    "`@` must be followed by a string: @\"2026-11-23\"".to_owned(),
                    span(start, start + 1),
                ));
            }
            let (s, len) = string(&rest[1..], start + 1)?;
            i += 1 + len;
            out.push(Token {
                tok: Tok::At(s),
                span: span(start, i),
            });
            continue;
        }
        if c == '`' {
            let Some(end) = rest[1..].find('`') else {
                return Err((
                    "a backticked name is not closed".to_owned(),
                    span(start, text.len()),
                ));
            };
            let name = &rest[1..1 + end];
            if name.is_empty() {
                return Err(("an empty backticked name".to_owned(), span(start, i + 2)));
            }
            i += end + 2;
            out.push(Token {
                tok: Tok::Name {
                    text: name.to_owned(),
                    quoted: true,
                },
                span: span(start, i),
            });
            continue;
        }
        if is_name_start(c) {
            if let Some((name, len)) = multi_word(rest, &multi) {
                i += len;
                out.push(Token {
                    tok: Tok::Name {
                        text: name.to_owned(),
                        quoted: false,
                    },
                    span: span(start, i),
                });
                continue;
            }
            let len = rest
                .char_indices()
                .find(|&(_, ch)| !is_name_part(ch))
                .map_or(rest.len(), |(j, _)| j);
            i += len;
            out.push(Token {
                tok: Tok::Name {
                    text: rest[..len].to_owned(),
                    quoted: false,
                },
                span: span(start, i),
            });
            continue;
        }
        if c == '?' {
            i += 1;
            out.push(Token {
                tok: Tok::Name {
                    text: "?".to_owned(),
                    quoted: false,
                },
                span: span(start, i),
            });
            continue;
        }
        match PUNCTS.iter().find(|p| rest.starts_with(**p)) {
            Some(p) => {
                i += p.len();
                out.push(Token {
                    tok: Tok::Punct(p),
                    span: span(start, i),
                });
            }
            None => {
                return Err((
                    format!("`{c}` is not part of FEEL"),
                    span(start, start + c.len_utf8()),
                ));
            }
        }
    }
    Ok(out)
}

fn span(start: usize, end: usize) -> Span {
    Span { start, end }
}

/// A multi-word built-in function name at the start of `rest`, when a `(` follows it; words
/// may be separated by any whitespace. Returns the name and the bytes it covers.
fn multi_word(rest: &str, names: &[&'static str]) -> Option<(&'static str, usize)> {
    for name in names {
        let mut at = 0;
        let mut ok = true;
        for (k, word) in name.split(' ').enumerate() {
            if k > 0 {
                let ws = rest[at..]
                    .char_indices()
                    .find(|&(_, c)| !c.is_whitespace())
                    .map_or(rest.len() - at, |(j, _)| j);
                if ws == 0 {
                    ok = false;
                    break;
                }
                at += ws;
            }
            if !rest[at..].starts_with(word) {
                ok = false;
                break;
            }
            at += word.len();
        }
        if !ok || rest[at..].chars().next().is_some_and(is_name_part) {
            continue;
        }
        if rest[at..].trim_start().starts_with('(') {
            return Some((name, at));
        }
    }
    None
}

/// A number literal at the start of `s`: digits, an optional fraction, an optional exponent.
/// A `.` followed by another `.` is a range, not a fraction.
fn number(s: &str) -> Result<(Decimal, usize), String> {
    let b = s.as_bytes();
    let mut i = 0;
    while i < b.len() && b[i].is_ascii_digit() {
        i += 1;
    }
    if i < b.len() && b[i] == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit) {
        i += 1;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
    }
    let mantissa = &s[..i];
    let mut exponent: i64 = 0;
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        let mut j = i + 1;
        let negative = b.get(j) == Some(&b'-');
        if matches!(b.get(j), Some(b'+' | b'-')) {
            j += 1;
        }
        let digits = j;
        while j < b.len() && b[j].is_ascii_digit() {
            j += 1;
        }
        if j > digits {
            let e: i64 = s[digits..j].parse().unwrap_or(i64::MAX);
            exponent = if negative { -e } else { e };
            i = j;
        }
    }
    let text = if mantissa.starts_with('.') {
        format!("0{mantissa}")
    } else {
        mantissa.to_owned()
    };
    let mut n = Decimal::from_str_exact(&text)
        .or_else(|_| text.parse::<Decimal>())
        .map_err(|_| format!("the number `{text}` does not fit in 28 significant digits"))?;
    if exponent != 0 {
        let ten = Decimal::TEN;
        for _ in 0..exponent.unsigned_abs().min(64) {
            n = if exponent > 0 {
                n.checked_mul(ten)
            } else {
                n.checked_div(ten)
            }
            .ok_or_else(|| format!("the number `{}` is out of range", &s[..i]))?;
        }
        if exponent.unsigned_abs() > 64 {
            return Err(format!("the number `{}` is out of range", &s[..i]));
        }
    }
    Ok((n, i))
}

/// A string literal at the start of `s` (which begins with `"`), starting at byte `at` of the
/// whole text. Raw line breaks are allowed (Camunda); escapes: `\" \\ \' \n \r \t \uXXXX
/// \UXXXXXX`; any other backslash is kept with the character after it.
fn string(s: &str, at: usize) -> Result<(String, usize), (String, Span)> {
    let mut out = String::new();
    let mut chars = s.char_indices().skip(1);
    while let Some((j, c)) = chars.next() {
        match c {
            '"' => return Ok((out, j + 1)),
            '\\' => {
                let Some((k, e)) = chars.next() else { break };
                match e {
                    '"' => out.push('"'),
                    '\\' => out.push('\\'),
                    '\'' => out.push('\''),
                    'n' => out.push('\n'),
                    'r' => out.push('\r'),
                    't' => out.push('\t'),
                    'u' | 'U' => {
                        let width = if e == 'u' { 4 } else { 6 };
                        let hex: String = s[k + 1..].chars().take(width).collect();
                        let code = (hex.len() == width
                            && hex.chars().all(|h| h.is_ascii_hexdigit()))
                        .then(|| u32::from_str_radix(&hex, 16).ok())
                        .flatten();
                        let mut decoded = code.and_then(char::from_u32);
                        let mut used = width;
                        // A surrogate pair written as two `\u` escapes.
                        if decoded.is_none()
                            && let Some(high) = code.filter(|c| (0xD800..0xDC00).contains(c))
                            && s[k + 1 + width..].starts_with("\\u")
                        {
                            let low_hex = s.get(k + 3 + width..k + 7 + width).unwrap_or("");
                            if let Ok(low) = u32::from_str_radix(low_hex, 16)
                                && (0xDC00..0xE000).contains(&low)
                            {
                                decoded = char::from_u32(
                                    0x10000 + ((high - 0xD800) << 10) + (low - 0xDC00),
                                );
                                used += 6;
                            }
                        }
                        let Some(ch) = decoded else {
                            return Err((
                                format!("`\\{e}{hex}` is not a character escape"),
                                Span {
                                    start: at + j,
                                    end: at + k + 1 + hex.len(),
                                },
                            ));
                        };
                        out.push(ch);
                        for _ in 0..used {
                            chars.next();
                        }
                    }
                    // Any other backslash stays as written (feel-scala): regular expressions
                    // such as "\\d{3}" depend on it.
                    other => {
                        out.push('\\');
                        out.push(other);
                    }
                }
            }
            c => out.push(c),
        }
    }
    Err((
        "the string is not closed: a `\"` is missing".to_owned(),
        Span {
            start: at,
            end: at + s.len(),
        },
    ))
}
