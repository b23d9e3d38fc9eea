//! JUEL (`${…}`, Camunda 7's expression language): the subset that maps exactly onto CEL, translated at load.
//!
//! Camunda 7, Activiti, Flowable and bpmn-engine write conditions in JUEL (JSR-245 Unified
//! EL, `${…}` / `#{…}`). TRACE evaluates CEL, so a JUEL body is translated to CEL text once, at
//! load. Anything outside the subset is refused with a sentence naming the first such construct
//! and its position (a 0-based character offset into the body); nothing is guessed.
//!
//! # The subset
//! - Literals: 64-bit integers, decimals (`1.5`, `.5`, `1.`, `2e3`), strings in `'…'` or `"…"`
//!   with JUEL's only escapes (`\\` and the string's own quote), `true`, `false`, `null`.
//! - Names and paths: `a`, `a.b.c`, `a['b']` / `a["b"]` (written `a.b` when `b` is a CEL name,
//!   else `a["b"]`), indexes `a[0]`, `a[i]`, and `(…)` before `.` / `[`.
//! - Operators with JUEL's precedence: unary `-`, `!`/`not`, `empty`; `*` `/`/`div` `%`/`mod`;
//!   `+` `-`; `<` `>` `<=` `>=` (`lt gt le ge`); `==` `!=` (`eq ne`); `&&`/`and`; `||`/`or`;
//!   `c ? a : b`; parentheses. Words become symbols; parentheses are added where CEL's precedence
//!   differs (CEL puts `==` and `<` on one level).
//! - `a / b` and `a div b` become `double(a) / double(b)`: JUEL always divides as doubles
//!   (`1/2` is `0.5`), CEL would truncate ints. `%` stays `%` (ints only in CEL 0.15).
//! - `empty x` becomes `x == null || size(x) == 0`.
//! - `x.contains(y)`, `x.startsWith(y)`, `x.endsWith(y)` (the same on strings in Java and CEL),
//!   `x.size()` -> `size(x)` and `x.isEmpty()` -> `size(x) == 0` (lists and maps).
//!
//! # What "exactly" means
//! Where both languages give a value it is the same value. Some expressions JUEL evaluates fail in
//! CEL with an evaluation error instead, because JUEL coerces where CEL does not: `null` counts as
//! 0 / false there; a missing map key or list index gives `null`; Java's longs wrap on overflow;
//! CEL 0.15 needs one type for `+ - * %` (`1 + 1.5` is an error; `%` on decimals too), while `==`
//! and `<` compare ints and doubles numerically (`1 == 1.0` is true, as in JUEL). The
//! differences in value depend on run-time types, so the text cannot show them:
//! - a variable holding a string compared with a number or boolean (`s == 1`, s = "1"): JUEL
//!   converts the string, CEL says false; `+` on two string variables adds in JUEL (its `+` is
//!   arithmetic only, string concatenation is not JUEL) and concatenates in CEL. Written with
//!   literals (`n == '1'`, `s + 'x'`) these are refused.
//! - `==` on whole lists or maps with int vs double elements: Java's `equals` says `[1] != [1.0]`.
//! - `<` on strings orders by UTF-16 unit in Java, by code point in CEL (differs only for
//!   characters above U+FFFF against U+E000..U+FFFF).
//!
//! # Refused, and why
//! - Java method calls other than those above (beans, delegates: `orderService.check(x)`) and
//!   functions (`f(x)`, `ns:f(x)`): TRACE runs no Java.
//! - The engine objects `execution`, `task`, `authorization` (Camunda 7) and `environment`,
//!   `services` (bpmn-engine): TRACE's variables are plain names, it has no such objects.
//! - EL 3.0, which Camunda 7 lacks too: lambdas `->`, `;`, assignment `=`, `+=`, list, set and map
//!   literals; and `instanceof`, `new`. `#{…}` is read as `${…}`: its deferred (method
//!   expression) uses need Java.
//! - A `.` or `[` after a literal, names with `$` or non-ASCII letters, CEL reserved words (`in`,
//!   `if`, …) as names, other string escapes, integers beyond 64 bits, nesting deeper than 32.

use std::fmt::Write as _;

/// CEL's reserved words (literals and words kept for embedding).
const CEL_RESERVED: &str = "as break const continue else false for function if import in let \
    loop namespace null package return true var void while";
/// JUEL's reserved words.
const JUEL_WORDS: &str = "and or not eq ne lt gt le ge div mod empty instanceof true false null";
/// Binary levels, loosest first: JUEL spellings with their CEL operator, and CEL's precedence.
const LEVELS: [(&str, u8); 6] = [
    ("||:|| or:||", OR),
    ("&&:&& and:&&", OR + 1),
    ("==:== !=:!= eq:== ne:!=", REL),
    ("<=:<= >=:>= <:< >:> le:<= ge:>= lt:< gt:>", REL),
    ("+:+ -:-", REL + 1),
    ("*:* /:/ div:/ %:% mod:%", REL + 2),
];
/// CEL precedences: `c ? a : b`, `||` (`&&` is one more), relations, unary operators, atoms.
const TERN: u8 = 1;
const OR: u8 = 2;
const REL: u8 = 4;
const UNARY: u8 = 7;
const ATOM: u8 = 8;
const MAX_DEPTH: usize = 64;
const NOT_SUBSET: &str = "is not in the JUEL subset";

/// Translates the body of a JUEL expression (the text inside `${` `}` / `#{` `}`, already
/// unwrapped) to CEL text. Err(reason) names the first construct outside the subset in a plain
/// sentence, e.g. "calls `orderService.check(…)` at offset 0, a Java method call (a bean or
/// delegate), which TRACE cannot evaluate".
pub(crate) fn to_cel(juel: &str) -> Result<String, String> {
    let src: Vec<char> = juel.chars().collect();
    let toks = tokenize(&src);
    let mut p = Parser {
        src: &src,
        toks,
        at: 0,
        depth: 0,
    };
    if p.tok().0 == Tok::End {
        return Err("the expression is empty".to_owned());
    }
    let out = p.ternary()?;
    if p.tok().0 != Tok::End {
        return Err(p.unexpected());
    }
    Ok(out.0)
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Name(String),
    Int(i64),
    Float(f64),
    Str(String),
    Sym(&'static str),
    /// A lexical refusal: the last token before `End`, reported if the parser gets that far.
    Bad(String),
    End,
}

/// A token with its start and end (character offsets).
type Token = (Tok, usize, usize);

fn tokenize(src: &[char]) -> Vec<Token> {
    const SYMS: &str = "== != <= >= && || < > ! + - * / % ( ) [ ] . , ? :";
    let mut toks = Vec::new();
    let mut i = 0;
    while let Some(&c) = src.get(i) {
        let (at, next) = (i, src.get(i + 1).copied());
        let two: String = src[i..(i + 2).min(src.len())].iter().collect();
        let tok = if c.is_whitespace() {
            i += 1;
            continue;
        } else if c.is_ascii_digit() || (c == '.' && next.is_some_and(|n| n.is_ascii_digit())) {
            number(src, &mut i)
        } else if c == '\'' || c == '"' {
            string(src, &mut i, c)
        } else if c.is_alphabetic() || c == '_' || (c == '$' && next != Some('{')) {
            while src
                .get(i)
                .is_some_and(|&c| c.is_alphanumeric() || c == '_' || c == '$')
            {
                i += 1;
            }
            let name: String = src[at..i].iter().collect();
            match name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                true => Tok::Name(name),
                false => Tok::Bad(format!(
                    "the name `{name}` at offset {at} has `$` or \
                    non-ASCII letters, which CEL names cannot have"
                )),
            }
        } else if let Some(s) = SYMS
            .split(' ')
            .find(|s| two.starts_with(s) && two != "->" && two != "+=")
        {
            i += s.len();
            Tok::Sym(s)
        } else {
            let what = match c {
                '-' => "a lambda `->` (EL 3.0, which Camunda 7 lacks)",
                '+' => "string concatenation `+=` (EL 3.0, which Camunda 7 lacks)",
                '=' => "an assignment `=` (EL 3.0; JUEL compares with `==`)",
                ';' => "a `;` (EL 3.0 sequences)",
                '{' | '}' => "a set or map literal `{…}` (EL 3.0)",
                '&' | '|' => "a single `&` or `|` (JUEL has `&&` and `||`)",
                '$' | '#' if next == Some('{') => "a nested `${` or `#{`",
                _ => "",
            };
            Tok::Bad(match what {
                "" => format!("the character `{c}` at offset {at} is not JUEL"),
                _ => format!("{what} at offset {at} {NOT_SUBSET}"),
            })
        };
        let bad = matches!(tok, Tok::Bad(_));
        toks.push((tok, at, i));
        if bad {
            break;
        }
    }
    toks.push((Tok::End, src.len(), src.len()));
    toks
}

fn digits(src: &[char], i: &mut usize) -> String {
    let start = *i;
    while src.get(*i).is_some_and(char::is_ascii_digit) {
        *i += 1;
    }
    src[start..*i].iter().collect()
}

/// JUEL numbers: `12`, `1.5`, `1.`, `.5`, each with an optional exponent (`2e3`, `1.5E-2`).
fn number(src: &[char], i: &mut usize) -> Tok {
    let at = *i;
    let int = digits(src, i);
    let frac = (src.get(*i) == Some(&'.')).then(|| {
        *i += 1;
        digits(src, i)
    });
    let mut exp = String::new();
    if matches!(src.get(*i), Some('e' | 'E')) {
        let mut j = *i + 1 + usize::from(matches!(src.get(*i + 1), Some('+' | '-')));
        if !digits(src, &mut j).is_empty() {
            exp = src[*i..j].iter().collect();
            *i = j;
        }
    }
    let text: String = src[at..*i].iter().collect();
    let too_big = |what| Tok::Bad(format!("the {what} `{text}` at offset {at} is too large"));
    if frac.is_none() && exp.is_empty() {
        return int.parse().map_or_else(|_| too_big("integer"), Tok::Int);
    }
    let zero = |s: String| if s.is_empty() { "0".to_owned() } else { s };
    let norm = format!("{}.{}{exp}", zero(int), zero(frac.unwrap_or_default()));
    match norm.parse::<f64>() {
        Ok(f) if f.is_finite() => Tok::Float(f),
        _ => too_big("number"),
    }
}

/// A JUEL string: its only escapes are `\\` and the string's own quote.
fn string(src: &[char], i: &mut usize, quote: char) -> Tok {
    let (at, mut s) = (*i, String::new());
    *i += 1;
    while let Some(&c) = src.get(*i) {
        *i += 1;
        match (c, src.get(*i)) {
            (c, _) if c == quote => return Tok::Str(s),
            ('\\', Some(&e)) if e == quote || e == '\\' => {
                s.push(e);
                *i += 1;
            }
            ('\\', Some(e)) => {
                return Tok::Bad(format!(
                    "the escape `\\{e}` at offset {} is not JUEL (only `\\{quote}` and `\\\\` are)",
                    *i - 1
                ));
            }
            (c, _) => s.push(c),
        }
    }
    Tok::Bad(format!("the string opened at offset {at} is not closed"))
}

/// A translated piece: CEL text, the CEL precedence of its outer operator, its static kind
/// ("number", "string", "boolean" or "" when unknown) and its value if it is a string literal.
struct Out(String, u8, &'static str, Option<String>);

fn out(text: String, prec: u8, kind: &'static str) -> Out {
    Out(text, prec, kind, None)
}

/// The CEL text of `o`, in parentheses if it binds looser than `min`.
fn wrap(o: Out, min: u8) -> String {
    if o.1 < min { format!("({})", o.0) } else { o.0 }
}

fn reserved(words: &str, name: &str) -> bool {
    words.split_whitespace().any(|w| w == name)
}

fn is_cel_name(n: &str) -> bool {
    let first = n
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
    first && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') && !reserved(CEL_RESERVED, n)
}

/// `s` as a CEL double-quoted string literal.
fn cel_string(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        let _ = match c {
            '"' | '\\' => write!(o, "\\{c}"),
            '\n' => write!(o, "\\n"),
            '\r' => write!(o, "\\r"),
            '\t' => write!(o, "\\t"),
            c if c.is_control() => write!(o, "\\u{:04x}", u32::from(c)),
            c => write!(o, "{c}"),
        };
    }
    o + "\""
}

struct Parser<'a> {
    src: &'a [char],
    toks: Vec<Token>,
    at: usize,
    depth: usize,
}

impl Parser<'_> {
    fn tok(&self) -> &Token {
        &self.toks[self.at.min(self.toks.len() - 1)]
    }
    fn bump(&mut self) {
        self.at += usize::from(self.tok().0 != Tok::End);
    }
    fn is(&self, s: &str) -> bool {
        matches!(&self.tok().0, Tok::Sym(t) if *t == s)
            || matches!(&self.tok().0, Tok::Name(n) if n == s)
    }
    fn text(&self, from: usize, to: usize) -> String {
        self.src.get(from..to).unwrap_or_default().iter().collect()
    }
    fn expect(&mut self, s: &str) -> Result<(), String> {
        if !self.is(s) {
            return Err(self.unexpected());
        }
        self.bump();
        Ok(())
    }
    fn unexpected(&self) -> String {
        match self.tok() {
            (Tok::Bad(m), _, _) => m.clone(),
            (Tok::End, _, _) => "the expression ends too early (it is not valid JUEL)".to_owned(),
            (Tok::Name(n), at, _) if n == "instanceof" => {
                format!("`instanceof` at offset {at} (a Java type test) {NOT_SUBSET}")
            }
            &(_, at, end) => format!(
                "`{}` at offset {at} is unexpected (not valid JUEL)",
                self.text(at, end)
            ),
        }
    }
    fn enter(&mut self) -> Result<(), String> {
        self.depth += 1;
        match self.depth > MAX_DEPTH {
            true => Err(format!(
                "the expression nests deeper than {} levels",
                MAX_DEPTH / 2
            )),
            false => Ok(()),
        }
    }

    fn ternary(&mut self) -> Result<Out, String> {
        self.enter()?;
        let mut o = self.level(0)?;
        if self.is("?") {
            self.bump();
            let a = self.ternary()?;
            self.expect(":")?;
            let b = self.ternary()?;
            let kind = if a.2 == b.2 { a.2 } else { "" };
            o = out(
                format!("{} ? {} : {}", wrap(o, OR), wrap(a, OR), wrap(b, TERN)),
                TERN,
                kind,
            );
        }
        self.depth -= 1;
        Ok(o)
    }

    /// Binary operators of `level`, left-associative, with the operand checks JUEL needs.
    fn level(&mut self, level: usize) -> Result<Out, String> {
        let Some(&(ops, prec)) = LEVELS.get(level) else {
            return self.unary();
        };
        let mut l = self.level(level + 1)?;
        let op_of = |p: &Self| {
            ops.split(' ')
                .find_map(|o| o.split_once(':').filter(|o| p.is(o.0)))
        };
        while let Some((_, op)) = op_of(self) {
            let (_, at, end) = *self.tok();
            let juel = self.text(at, end);
            self.bump();
            let r = self.level(level + 1)?;
            let other = [l.2, r.2]
                .into_iter()
                .find(|k| *k == "number" || *k == "boolean");
            let string = l.2 == "string" || r.2 == "string";
            l = if prec == REL && string && other.is_some() {
                return Err(format!(
                    "`{juel}` at offset {at} compares a string with a {}: JUEL \
                    would convert the string, CEL would not",
                    other.unwrap_or_default()
                ));
            } else if prec > REL && string {
                return Err(format!(
                    "`{juel}` at offset {at} does arithmetic on a string: JUEL \
                    makes it a number (string concatenation is not JUEL), CEL would not"
                ));
            } else if op == "/" {
                out(format!("double({}) / double({})", l.0, r.0), prec, "number")
            } else {
                let kind = if prec > REL { "number" } else { "boolean" };
                out(
                    format!("{} {op} {}", wrap(l, prec), wrap(r, prec + 1)),
                    prec,
                    kind,
                )
            };
        }
        Ok(l)
    }

    fn unary(&mut self) -> Result<Out, String> {
        self.enter()?;
        let (_, at, end) = *self.tok();
        let op = self.text(at, end);
        let o = if ["-", "!", "not", "empty"].iter().any(|s| self.is(s)) {
            self.bump();
            let x = self.unary()?;
            match op.as_str() {
                "-" if x.2 == "string" => {
                    return Err(format!(
                        "`-` at offset {at} negates a string: JUEL makes it a \
                        number, CEL would not"
                    ));
                }
                "-" => out(format!("-{}", wrap(x, UNARY)), UNARY, "number"),
                "empty" if x.0.len() > 400 => {
                    return Err(format!(
                        "`empty` at offset {at} applies to an operand too long \
                        to write twice, as CEL needs"
                    ));
                }
                "empty" => {
                    let x = wrap(x, ATOM);
                    out(format!("{x} == null || size({x}) == 0"), OR, "boolean")
                }
                _ => out(format!("!{}", wrap(x, UNARY)), UNARY, "boolean"),
            }
        } else {
            self.postfix()?
        };
        self.depth -= 1;
        Ok(o)
    }

    /// A primary followed by `.name`, `[key]` and the allowed method calls.
    fn postfix(&mut self) -> Result<Out, String> {
        let start = self.tok().1;
        let literal = matches!(self.tok().0, Tok::Int(_) | Tok::Float(_) | Tok::Str(_))
            || ["true", "false", "null"].iter().any(|w| self.is(w));
        let mut x = self.primary()?;
        while self.is(".") || self.is("[") {
            let (_, at, _) = *self.tok();
            if literal {
                return Err(format!(
                    "`{}` at offset {at} reads a property or method of a literal, \
                    which {NOT_SUBSET}",
                    self.text(at, at + 1)
                ));
            }
            let recv = wrap(x, ATOM);
            let bracket = self.is("[");
            self.bump();
            let mut name_end = at;
            let key = if bracket {
                let k = self.ternary()?;
                self.expect("]")?;
                k.3.ok_or(k.0)
            } else if let (Tok::Name(n), _, end) = self.tok().clone()
                && !reserved(JUEL_WORDS, &n)
            {
                name_end = end;
                self.bump();
                Ok(n)
            } else {
                return Err(self.unexpected());
            };
            x = match key {
                Ok(k) if bracket || !self.is("(") => match is_cel_name(&k) {
                    true => out(format!("{recv}.{k}"), ATOM, ""),
                    false => out(format!("{recv}[{}]", cel_string(&k)), ATOM, ""),
                },
                Err(k) => out(format!("{recv}[{k}]"), ATOM, ""),
                Ok(m) => self.method(&recv, &m, start, name_end)?,
            };
        }
        Ok(x)
    }

    /// `recv.name(…)`, the current token being `(`: only the methods that mean the same in CEL.
    fn method(&mut self, recv: &str, name: &str, start: usize, end: usize) -> Result<Out, String> {
        let (arity, kind) = match name {
            "contains" | "startsWith" | "endsWith" => (1, "boolean"),
            "size" => (0, "number"),
            "isEmpty" => (0, "boolean"),
            _ => {
                return Err(format!(
                    "calls `{}(…)` at offset {start}, a Java method call (a bean \
                    or delegate), which TRACE cannot evaluate",
                    self.text(start, end)
                ));
            }
        };
        self.bump();
        let mut args = Vec::new();
        while !self.is(")") {
            if !args.is_empty() {
                self.expect(",")?;
            }
            args.push(self.ternary()?.0);
        }
        self.bump();
        if args.len() != arity {
            let n = args.len();
            let at = end.saturating_sub(name.len());
            return Err(format!(
                "`{name}` at offset {at} takes {arity} argument(s), not {n}"
            ));
        }
        Ok(match name {
            "size" => out(format!("size({recv})"), ATOM, kind),
            "isEmpty" => out(format!("size({recv}) == 0"), REL, kind),
            _ => out(format!("{recv}.{name}({})", args.concat()), ATOM, kind),
        })
    }

    fn primary(&mut self) -> Result<Out, String> {
        let (tok, at, _) = self.tok().clone();
        let peek = |n: usize| self.toks.get(self.at + n).map(|t| &t.0);
        let o = match tok {
            Tok::Int(i) => out(i.to_string(), ATOM, "number"),
            Tok::Float(f) => out(format!("{f:?}"), ATOM, "number"),
            Tok::Str(s) => Out(cel_string(&s), ATOM, "string", Some(s)),
            Tok::Sym("(") => {
                self.bump();
                let inner = self.ternary()?; // callers add parentheses where CEL needs them
                if !self.is(")") {
                    return Err(self.unexpected());
                }
                inner
            }
            Tok::Sym("[") => return Err(format!("a list literal `[` at offset {at} {NOT_SUBSET}")),
            Tok::Name(n) => match n.as_str() {
                "true" | "false" => out(n, ATOM, "boolean"),
                "null" => out(n, ATOM, ""),
                "new" if matches!(peek(1), Some(Tok::Name(c)) if !reserved(JUEL_WORDS, c)) => {
                    return Err(format!("`{n}` at offset {at} (a Java object) {NOT_SUBSET}"));
                }
                w if reserved(JUEL_WORDS, w) => return Err(self.unexpected()),
                "execution" | "task" | "authorization" | "environment" | "services" => {
                    let engine = match n.as_str() {
                        "environment" | "services" => "bpmn-engine",
                        _ => "Camunda 7",
                    };
                    return Err(format!(
                        "reads `{n}` (at offset {at}), an engine object of \
                        {engine}, which TRACE does not have"
                    ));
                }
                _ => {
                    let call = match (peek(1), peek(2), peek(3)) {
                        (Some(Tok::Sym("(")), _, _) => Some(n.clone()),
                        (Some(Tok::Sym(":")), Some(Tok::Name(f)), Some(Tok::Sym("("))) => {
                            Some(format!("{n}:{f}"))
                        }
                        _ => None,
                    };
                    if let Some(f) = call {
                        return Err(format!(
                            "calls `{f}(…)` at offset {at}, a function (a Java \
                            static method), which TRACE cannot evaluate"
                        ));
                    }
                    if reserved(CEL_RESERVED, &n) {
                        return Err(format!("the name `{n}` at offset {at} is reserved in CEL"));
                    }
                    out(n, ATOM, "")
                }
            },
            _ => return Err(self.unexpected()),
        };
        self.bump();
        Ok(o)
    }
}

#[cfg(test)]
mod tests {
    use super::to_cel;
    use cel::Value::{self, Bool, Float, Int, Null};
    use std::collections::HashMap;

    /// Accepted JUEL with the CEL it becomes.
    const ACCEPTED: &[(&str, &str)] = &[
        ("a eq 'x' and not (b gt 2)", r#"a == "x" && !(b > 2)"#),
        ("x / 2", "double(x) / double(2)"),
        ("x div 2 * y mod 3", "double(x) / double(2) * y % 3"),
        ("a * (b / c)", "a * (double(b) / double(c))"),
        (r#"test.contains("a")"#, r#"test.contains("a")"#),
        ("order['total'] >= 100", "order.total >= 100"),
        (r#"o["my key"].x[0][i + 1]"#, r#"o["my key"].x[0][i + 1]"#),
        ("a.in == a['if']", r#"a["in"] == a["if"]"#),
        ("a lt b == c < d", "a < b == (c < d)"),
        ("a - (b - c) - -1", "a - (b - c) - -1"),
        ("c ? 1 : d ? 2.5 : null", "c ? 1 : d ? 2.5 : null"),
        ("(c ? a : b) ? x || y : z", "(c ? a : b) ? x || y : z"),
        (
            "empty l or l.size() ge 3",
            "l == null || size(l) == 0 || size(l) >= 3",
        ),
        (
            "not empty s && v.isEmpty()",
            "!(s == null || size(s) == 0) && size(v) == 0",
        ),
        (
            r#"s.startsWith('a\'"') || s.endsWith("\\")"#,
            r#"s.startsWith("a'\"") || s.endsWith("\\")"#,
        ),
        ("'tab\there\u{1}'", r#""tab\there\u0001""#),
        (
            "1. + .5e1 + 1E3 + 2.5e-7 + 007",
            "1.0 + 5.0 + 1000.0 + 2.5e-7 + 7",
        ),
        ("(a).b != null and !true", "a.b != null && !true"),
        ("new ne size", "new != size"),
        ("1 == 1.0 && 'é' != \"\"", r#"1 == 1.0 && "é" != """#),
    ];

    #[test]
    fn accepted_examples_translate_and_compile() {
        for (juel, cel) in ACCEPTED {
            assert_eq!(to_cel(juel).as_deref(), Ok(*cel), "{juel}");
            assert!(cel::Program::compile(cel).is_ok(), "{cel} does not compile");
        }
    }

    fn eval(juel: &str, vars: Vec<(&str, Value)>) -> Result<Value, String> {
        let program = cel::Program::compile(&to_cel(juel)?).map_err(|e| e.to_string())?;
        let mut ctx = cel::Context::default();
        for (name, value) in vars {
            ctx.add_variable_from_value(name, value);
        }
        program.execute(&ctx).map_err(|e| format!("{e:?}"))
    }

    #[test]
    fn evaluates_as_juel_does() {
        let order = Value::from(HashMap::from([("total", 150)]));
        let (x, s, l) = ("x".into(), "".into(), vec![1, 2].into());
        let cases = vec![
            (
                "a eq 'x' and not (b gt 2)",
                vec![("a", x), ("b", Int(1))],
                Bool(true),
            ),
            ("x / 2", vec![("x", Int(3))], Float(1.5)),
            (
                r#"test.contains("a")"#,
                vec![("test", "bab".into())],
                Bool(true),
            ),
            ("order['total'] >= 100", vec![("order", order)], Bool(true)),
            ("1 < 2 == 3 < 4 and 7 mod 3 - -1 == 2", vec![], Bool(true)),
            (r#"'it\'s' == "it's""#, vec![], Bool(true)),
            (
                "empty s && empty n",
                vec![("s", s), ("n", Null)],
                Bool(true),
            ),
            ("not empty l && l.size() == 2", vec![("l", l)], Bool(true)),
            ("c ? 1 : 2.5", vec![("c", Bool(false))], Float(2.5)),
            // cel 0.15 compares ints and doubles numerically, as JUEL does.
            ("1 == 1.0 and 2 gt 1.5", vec![], Bool(true)),
        ];
        for (juel, vars, want) in cases {
            assert_eq!(eval(juel, vars), Ok(want), "{juel}");
        }
        // cel 0.15 has no mixed int/double arithmetic (JUEL gives 2.5): an error, not a value.
        assert!(eval("1 + 1.5", vec![]).is_err());
    }

    #[test]
    fn refusals_name_the_construct_and_offset() {
        let cases = [
            (
                "orderService.check(x)",
                "calls `orderService.check(…)` at offset 0, a Java",
            ),
            ("a && x.length()", "calls `x.length(…)` at offset 5"),
            (
                "execution.getVariable('x')",
                "reads `execution` (at offset 0), an engine",
            ),
            ("environment.variables.x", "engine object of bpmn-engine"),
            ("f(1)", "calls `f(…)` at offset 0, a function"),
            ("fn:upper(x)", "calls `fn:upper(…)`"),
            (
                "x -> x + 1",
                "lambda `->` (EL 3.0, which Camunda 7 lacks) at offset 2",
            ),
            (
                "a = 1",
                "assignment `=` (EL 3.0; JUEL compares with `==`) at offset 2",
            ),
            ("a; b", "`;` (EL 3.0 sequences) at offset 1"),
            (
                "a += 'x'",
                "`+=` (EL 3.0, which Camunda 7 lacks) at offset 2",
            ),
            ("[1, 2]", "list literal `[` at offset 0"),
            ("{1: 2}", "map literal `{…}` (EL 3.0) at offset 0"),
            (
                "x instanceof Foo",
                "`instanceof` at offset 2 (a Java type test)",
            ),
            ("new Foo()", "`new` at offset 0 (a Java object)"),
            (
                "'abc'.length()",
                "`.` at offset 5 reads a property or method of a literal",
            ),
            ("1 == '1'", "compares a string with a number"),
            (
                "x eq 'true' or true == 'true'",
                "`==` at offset 20 compares a string with a boolean",
            ),
            ("x + 'a'", "`+` at offset 2 does arithmetic on a string"),
            ("-'1'", "`-` at offset 0 negates a string"),
            ("#{x}", "nested `${` or `#{` at offset 0"),
            ("in + 1", "`in` at offset 0 is reserved in CEL"),
            ("é", "non-ASCII"),
            ("a.$x", "the name `$x` at offset 2 has `$`"),
            (r"'a\nb'", r"the escape `\n` at offset 2 is not JUEL"),
            (r#""a\'""#, r"the escape `\'` at offset 2"),
            ("'abc", "the string opened at offset 0 is not closed"),
            (
                "99999999999999999999",
                "the integer `99999999999999999999` at offset 0 is too",
            ),
            ("1e999", "too large"),
            ("  ", "the expression is empty"),
            ("a b", "`b` at offset 2 is unexpected"),
            ("a.and", "`and` at offset 2 is unexpected"),
            ("a ? b", "ends too early"),
            ("a @ b", "the character `@` at offset 2 is not JUEL"),
            (
                "empty empty empty empty empty empty empty empty x",
                "too long to write twice",
            ),
            (
                "a.contains(1, 2)",
                "`contains` at offset 2 takes 1 argument(s), not 2",
            ),
        ];
        for (juel, want) in cases {
            match to_cel(juel) {
                Err(e) => assert!(e.contains(want), "{juel}: {e}"),
                Ok(cel) => panic!("{juel} was accepted as {cel}"),
            }
        }
        let deeper = format!("{}a{}", "(".repeat(70), ")".repeat(70));
        assert!(to_cel(&deeper).is_err_and(|e| e.contains("nests deeper than 32 levels")));
    }

    #[test]
    fn the_deepest_accepted_nesting_compiles() {
        let shapes = [
            ("a lt b == (", ")"),
            ("not (", ")"),
            ("a / (", ")"),
            ("x[", "]"),
        ];
        let more = [
            ("a ? (", ") : b"),
            ("s.contains(", ")"),
            ("empty (", ")"),
            ("-(", ")"),
        ];
        for (open, close) in shapes.into_iter().chain(more) {
            let nest = |n: usize| to_cel(&format!("{}a{}", open.repeat(n), close.repeat(n)));
            let deepest = (1..80)
                .map_while(|n| nest(n).ok())
                .last()
                .unwrap_or_default();
            assert!(cel::Program::compile(&deepest).is_ok(), "{deepest}");
        }
    }

    #[test]
    fn garbage_never_panics_and_accepted_garbage_compiles() {
        const BITS: &str = "a|b.c|'x'|\"y\\\"\"|1|2.5|.5e|1e|(|)|[|]|.|,|?|:|==|eq|and|or|not|\
            empty|-|+|*|/|div|%|<|ge|!|.contains(|.size()|true|null| |\\|'|$|{|é|execution|f(|\
            ->|=|;|in|\u{0}";
        let bits: Vec<&str> = BITS.split('|').collect();
        let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = |n: usize| {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            usize::try_from(seed >> 33).unwrap_or(0) % n
        };
        let mut accepted = 0;
        for _ in 0..4000 {
            let len = 1 + next(10);
            let juel: String = (0..len).map(|_| bits[next(bits.len())]).collect();
            if let Ok(cel) = to_cel(&juel) {
                accepted += 1;
                assert!(
                    cel::Program::compile(&cel).is_ok(),
                    "{juel} -> {cel} does not compile"
                );
            }
        }
        assert!(
            accepted > 50,
            "only {accepted} garbage strings were accepted"
        );
    }
}
