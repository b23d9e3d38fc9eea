//! Bounded data: variables the requirements file declares (`[variables]`, e.g.
//! `samples_analyzed = "0..5"`, `site_approved = "bool"`) are kept in the PROMELA model, so the
//! conditions and script assignments that use only them are translated instead of abstracted.
//! Everything else stays a nondeterministic choice.
//!
//! Expressions are translated from the CEL subset that has a PROMELA meaning: integer and
//! boolean literals, declared variables, `+ - == != < <= > >= && || !` and parentheses.
//! Variables are mission-wide by name (scopes are not told apart); an integer assigned beyond
//! its range is clamped to it.

use std::collections::BTreeMap;

/// A declared variable's type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `true` / `false`.
    Bool,
    /// An integer in `min..=max`.
    Int(i64, i64),
}

/// The declared variables by name.
pub type Variables = BTreeMap<String, Kind>;

/// Reads one declaration (`"bool"`, `"0..5"`).
pub fn kind(text: &str) -> Result<Kind, String> {
    let t = text.trim();
    if t == "bool" {
        return Ok(Kind::Bool);
    }
    let (a, b) = t
        .split_once("..")
        .ok_or_else(|| format!("`{t}` is neither `bool` nor a range like `0..5`"))?;
    let (min, max) = (
        a.trim()
            .parse::<i64>()
            .map_err(|_| format!("`{a}` is not an integer"))?,
        b.trim()
            .parse::<i64>()
            .map_err(|_| format!("`{b}` is not an integer"))?,
    );
    if min > max || max - min > 255 || min < -32768 || max > 32767 {
        return Err(format!(
            "`{t}`: a range has at most 256 values, within a short"
        ));
    }
    Ok(Kind::Int(min, max))
}

/// The PROMELA name of a declared variable.
pub fn var(name: &str) -> String {
    format!("d_{name}")
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Id(String),
    Int(i64),
    Op(&'static str),
}

fn lex(text: &str) -> Option<Vec<Tok>> {
    const OPS: [&str; 15] = [
        "==", "!=", "<=", ">=", "&&", "||", "<", ">", "+", "-", "!", "(", ")", "true", "false",
    ];
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let c = b[i] as char;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() {
            let start = i;
            while i < b.len() && (b[i] as char).is_ascii_digit() {
                i += 1;
            }
            if i < b.len() && b[i] == b'.' {
                return None; // floats have no PROMELA meaning
            }
            out.push(Tok::Int(text[start..i].parse().ok()?));
        } else if c.is_ascii_alphabetic() || c == '_' {
            let start = i;
            while i < b.len() && ((b[i] as char).is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            let w = &text[start..i];
            match w {
                "true" => out.push(Tok::Op("true")),
                "false" => out.push(Tok::Op("false")),
                _ => out.push(Tok::Id(w.to_owned())),
            }
        } else {
            let op = OPS[..12].iter().find(|o| text[i..].starts_with(**o))?;
            out.push(Tok::Op(op));
            i += op.len();
        }
    }
    Some(out)
}

struct Parser<'a> {
    toks: Vec<Tok>,
    at: usize,
    vars: &'a Variables,
}

impl Parser<'_> {
    fn op(&mut self, o: &str) -> bool {
        let yes = matches!(self.toks.get(self.at), Some(Tok::Op(x)) if *x == o);
        if yes {
            self.at += 1;
        }
        yes
    }

    fn or(&mut self) -> Option<String> {
        let mut e = self.and()?;
        while self.op("||") {
            e = format!("({e} || {})", self.and()?);
        }
        Some(e)
    }

    fn and(&mut self) -> Option<String> {
        let mut e = self.not()?;
        while self.op("&&") {
            e = format!("({e} && {})", self.not()?);
        }
        Some(e)
    }

    fn not(&mut self) -> Option<String> {
        if self.op("!") {
            return Some(format!("!{}", self.not()?));
        }
        self.cmp()
    }

    fn cmp(&mut self) -> Option<String> {
        let left = self.sum()?;
        for o in ["==", "!=", "<=", ">=", "<", ">"] {
            if self.op(o) {
                return Some(format!("({left} {o} {})", self.sum()?));
            }
        }
        Some(left)
    }

    fn sum(&mut self) -> Option<String> {
        let mut e = self.atom()?;
        loop {
            if self.op("+") {
                e = format!("({e} + {})", self.atom()?);
            } else if self.op("-") {
                e = format!("({e} - {})", self.atom()?);
            } else {
                return Some(e);
            }
        }
    }

    fn atom(&mut self) -> Option<String> {
        let t = self.toks.get(self.at)?.clone();
        self.at += 1;
        match t {
            Tok::Int(n) => Some(n.to_string()),
            Tok::Op("true") => Some("true".into()),
            Tok::Op("false") => Some("false".into()),
            Tok::Op("(") => {
                let e = self.or()?;
                self.op(")").then_some(format!("({e})"))
            }
            Tok::Id(name) if self.vars.contains_key(&name) => Some(var(&name)),
            _ => None,
        }
    }
}

/// The PROMELA form of a CEL expression, if it reads only declared variables and uses only the
/// translated subset.
pub fn expression(cel: &str, vars: &Variables) -> Option<String> {
    if vars.is_empty() {
        return None;
    }
    let mut p = Parser {
        toks: lex(cel)?,
        at: 0,
        vars,
    };
    let e = p.or()?;
    (p.at == p.toks.len()).then_some(e)
}

/// Effects that assign `value` (PROMELA, or `None`: unknown, any value of the range) to a
/// declared variable, clamped to its range.
pub fn assign(name: &str, kind: &Kind, value: Option<String>) -> Vec<String> {
    let v = var(name);
    match (kind, value) {
        (Kind::Bool, Some(e)) => vec![format!("{v} = {e}")],
        (Kind::Bool, None) => vec![format!("if :: {v} = true :: {v} = false fi")],
        (Kind::Int(min, max), Some(e)) => vec![
            format!("{v} = {e}"),
            format!(
                "if :: {v} > {max} -> {v} = {max} :: {v} < {min} -> {v} = {min} :: else -> skip fi"
            ),
        ],
        (Kind::Int(min, max), None) => {
            let choices: Vec<String> = (*min..=*max).map(|k| format!(":: {v} = {k}")).collect();
            vec![format!("if {} fi", choices.join(" "))]
        }
    }
}

/// PROMELA declarations of the variables.
pub fn declarations(vars: &Variables) -> String {
    vars.iter()
        .map(|(name, k)| match k {
            Kind::Bool => format!("bool {};\n", var(name)),
            Kind::Int(..) => format!("short {};\n", var(name)),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_translated_subset_and_what_stays_abstract() {
        let vars: Variables = [
            ("samples".to_owned(), Kind::Int(0, 5)),
            ("ok".to_owned(), Kind::Bool),
        ]
        .into();
        assert_eq!(
            expression("samples >= 5 && !ok", &vars).as_deref(),
            Some("((d_samples >= 5) && !d_ok)")
        );
        assert_eq!(
            expression("samples + 1", &vars).as_deref(),
            Some("(d_samples + 1)")
        );
        assert_eq!(
            expression("battery < 30.0", &vars),
            None,
            "undeclared, float"
        );
        assert_eq!(expression("samples < 30.0", &vars), None, "float");
        assert_eq!(expression("size(list) > 0", &vars), None, "function");
        assert_eq!(kind("0..5"), Ok(Kind::Int(0, 5)));
        assert!(kind("5..0").is_err() && kind("int").is_err());
        assert_eq!(
            assign("ok", &Kind::Bool, None),
            ["if :: d_ok = true :: d_ok = false fi"]
        );
    }
}
