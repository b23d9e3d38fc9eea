//! Mission requirements (`<mission>.req.toml`): named statements in a small language over BPMN
//! elements, compiled to LTL for Spin.
//!
//! ```toml
//! [[requirement]]
//! name = "abort_leads_to_communication"
//! says = "A battery abort always leads to Communicate Until Death"
//! check = 'after signal "BATTERY_LOW_ABORT" eventually done "Communicate Until Death"'
//! ```
//!
//! Bounded variables make the conditions and scripts that use them exact instead of abstract
//! (`data.rs`):
//!
//! ```toml
//! [variables]
//! samples_analyzed = "0..5"
//! ```
//!
//! Forms: `eventually E`, `always E`, `never E`, `after A eventually|always|never E`,
//! `E when completed` (at the mission's end, unless it failed), `E when C` (at the end, if C).
//! Expressions: `done "X"` (X — an element id or name — completed or was passed at least once),
//! `count "X"` (how often; compare with `>= 5`, `== 0`, …), `running "X"` (the activity X runs
//! now), `signal "S"` (signal S was thrown), `error "CODE"` (a failure with CODE was caught),
//! `ended`, `failed`, `terminated`, combined with `and`, `or`, `not` and parentheses.

use std::collections::BTreeMap;
use std::path::Path;

use executive_model::{NodeId, ProcessGraph};
use serde::Deserialize;

/// What a requirement observes in the model.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Atom {
    /// The element completed (or was passed) at least once.
    Done(NodeId),
    /// How often the element completed (a counter saturating at the given bound).
    Count(NodeId, u8),
    /// The activity runs now (no instrumentation: its slots).
    Running(NodeId),
    /// The signal (by name) was thrown.
    Signal(String),
    /// A failure with this error code was caught.
    Error(String),
}

/// One requirement, compiled.
#[derive(Clone, Debug)]
pub struct Requirement {
    /// Its name (a PROMELA identifier).
    pub name: String,
    /// What it says, for people.
    pub says: String,
    /// The statement as written.
    pub check: String,
    /// The LTL formula with `@k` standing for atom `k` (see [`Requirement::atoms`]).
    pub formula: String,
    /// The atoms it reads, in `@k` order.
    pub atoms: Vec<Atom>,
}

/// A requirements file could not be used.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {reason}")]
pub struct RequirementsError {
    /// The file.
    pub path: String,
    /// Every problem, one per line.
    pub reason: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    variables: BTreeMap<String, String>,
    #[serde(default)]
    requirement: Vec<Entry>,
}

/// A requirements file, compiled.
#[derive(Clone, Debug, Default)]
pub struct Loaded {
    /// The requirements, in file order.
    pub requirements: Vec<Requirement>,
    /// The bounded data variables declared for the translation.
    pub variables: crate::data::Variables,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    name: String,
    #[serde(default)]
    says: String,
    check: String,
}

const RESERVED: [&str; 6] = [
    "completes",
    "no_lost_signal",
    "no_deadlock",
    "safe",
    "no_dead_activities",
    "ended",
];

/// Reads and compiles a requirements file against the model.
pub fn load(path: &Path, g: &ProcessGraph) -> Result<Loaded, RequirementsError> {
    let text = std::fs::read_to_string(path).map_err(|e| RequirementsError {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    parse(&text, &path.display().to_string(), g)
}

/// Reads and compiles a requirements file's text (`path` names it in errors).
pub fn parse(text: &str, path: &str, g: &ProcessGraph) -> Result<Loaded, RequirementsError> {
    let bad = |reason: String| RequirementsError {
        path: path.to_owned(),
        reason,
    };
    let file: File = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
    let mut problems = Vec::new();
    let mut variables = crate::data::Variables::new();
    for (name, decl) in &file.variables {
        let ident = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ident {
            problems.push(format!("variable `{name}`: not a variable name"));
            continue;
        }
        match crate::data::kind(decl) {
            Ok(k) => {
                variables.insert(name.clone(), k);
            }
            Err(why) => problems.push(format!("variable `{name}`: {why}")),
        }
    }
    let mut out = Vec::new();
    for e in file.requirement {
        let named_ok = !e.name.is_empty()
            && e.name
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_lowercase() || c == '_')
            && e.name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
        if !named_ok {
            problems.push(format!(
                "`{}`: a requirement's name is lowercase letters, digits and _",
                e.name
            ));
            continue;
        }
        if RESERVED.contains(&e.name.as_str()) || out.iter().any(|r: &Requirement| r.name == e.name)
        {
            problems.push(format!("`{}`: the name is already taken", e.name));
            continue;
        }
        match compile(&e.check, g) {
            Ok((formula, atoms)) => out.push(Requirement {
                name: e.name,
                says: if e.says.is_empty() {
                    e.check.clone()
                } else {
                    e.says
                },
                check: e.check,
                formula,
                atoms,
            }),
            Err(why) => problems.push(format!("`{}`: {why}", e.name)),
        }
    }
    if problems.is_empty() {
        Ok(Loaded {
            requirements: out,
            variables,
        })
    } else {
        Err(bad(problems.join("\n")))
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Word(String),
    Str(String),
    Num(u64),
    Op(String),
}

fn lex(text: &str) -> Result<Vec<Tok>, String> {
    let mut out = Vec::new();
    let mut chars = text.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c == '"' {
            chars.next();
            let mut s = String::new();
            loop {
                match chars.next() {
                    Some('"') => break,
                    Some(c) => s.push(c),
                    None => return Err("a quote is not closed".into()),
                }
            }
            out.push(Tok::Str(s));
        } else if c.is_ascii_digit() {
            let mut n = String::new();
            while let Some(&d) = chars.peek().filter(|d| d.is_ascii_digit()) {
                n.push(d);
                chars.next();
            }
            out.push(Tok::Num(
                n.parse().map_err(|_| format!("`{n}` is too large"))?,
            ));
        } else if c.is_ascii_alphabetic() || c == '_' {
            let mut w = String::new();
            while let Some(&d) = chars
                .peek()
                .filter(|d| d.is_ascii_alphanumeric() || **d == '_')
            {
                w.push(d);
                chars.next();
            }
            out.push(Tok::Word(w));
        } else {
            chars.next();
            let two = chars.peek().map(|d| format!("{c}{d}"));
            match two.as_deref() {
                Some(">=" | "<=" | "==" | "!=") => {
                    chars.next();
                    out.push(Tok::Op(two.unwrap_or_default()));
                }
                _ if "<>()".contains(c) => out.push(Tok::Op(c.to_string())),
                _ => return Err(format!("`{c}` is not part of the requirement language")),
            }
        }
    }
    Ok(out)
}

struct Parser<'a> {
    toks: Vec<Tok>,
    at: usize,
    g: &'a ProcessGraph,
    atoms: Vec<Atom>,
}

impl Parser<'_> {
    fn peek_word(&self, w: &str) -> bool {
        matches!(self.toks.get(self.at), Some(Tok::Word(x)) if x == w)
    }

    fn word(&mut self, w: &str) -> bool {
        let yes = self.peek_word(w);
        if yes {
            self.at += 1;
        }
        yes
    }

    fn string(&mut self, after: &str) -> Result<String, String> {
        match self.toks.get(self.at) {
            Some(Tok::Str(s)) => {
                self.at += 1;
                Ok(s.clone())
            }
            _ => Err(format!("`{after}` needs a quoted name after it")),
        }
    }

    fn atom(&mut self, a: Atom) -> String {
        let k = match self.atoms.iter().position(|x| *x == a) {
            Some(k) => k,
            None => {
                self.atoms.push(a);
                self.atoms.len() - 1
            }
        };
        format!("@{k}")
    }

    fn element(&self, name: &str) -> Result<NodeId, String> {
        if let Some(n) = self.g.node_by_id(name) {
            return Ok(n);
        }
        let by_name: Vec<NodeId> = (0..self.g.nodes.len() as u32)
            .map(NodeId)
            .filter(|n| self.g.node(*n).name.as_deref() == Some(name))
            .collect();
        match by_name.as_slice() {
            [one] => Ok(*one),
            [] => Err(format!("no element has the id or name \"{name}\"")),
            many => Err(format!(
                "\"{name}\" names several elements ({}); use an id",
                many.iter()
                    .map(|n| self.g.node(*n).id.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        }
    }

    fn or(&mut self) -> Result<String, String> {
        let mut e = self.and()?;
        while self.word("or") {
            e = format!("({e} || {})", self.and()?);
        }
        Ok(e)
    }

    fn and(&mut self) -> Result<String, String> {
        let mut e = self.not()?;
        while self.word("and") {
            e = format!("({e} && {})", self.not()?);
        }
        Ok(e)
    }

    fn not(&mut self) -> Result<String, String> {
        if self.word("not") {
            return Ok(format!("!{}", self.not()?));
        }
        self.cmp()
    }

    fn cmp(&mut self) -> Result<String, String> {
        let counted = self.peek_word("count");
        let left = self.primary()?;
        if let Some(Tok::Op(op)) = self.toks.get(self.at).cloned()
            && op != "("
            && op != ")"
        {
            if !counted {
                return Err(format!("`{op}` compares a `count`"));
            }
            self.at += 1;
            let Some(Tok::Num(n)) = self.toks.get(self.at).cloned() else {
                return Err(format!("`{op}` needs a number after it"));
            };
            self.at += 1;
            return Ok(format!("({left} {op} {})", n.min(255)));
        }
        if counted {
            return Err("`count` is compared with a number (`count \"X\" >= 5`)".into());
        }
        Ok(left)
    }

    fn primary(&mut self) -> Result<String, String> {
        let Some(t) = self.toks.get(self.at).cloned() else {
            return Err("the statement ends too early".into());
        };
        self.at += 1;
        match t {
            Tok::Op(o) if o == "(" => {
                let e = self.or()?;
                if !matches!(self.toks.get(self.at), Some(Tok::Op(c)) if c == ")") {
                    return Err("a parenthesis is not closed".into());
                }
                self.at += 1;
                Ok(format!("({e})"))
            }
            Tok::Word(w) => match w.as_str() {
                "done" => {
                    let name = self.string("done")?;
                    let n = self.element(&name)?;
                    Ok(self.atom(Atom::Done(n)))
                }
                "count" => {
                    let name = self.string("count")?;
                    let n = self.element(&name)?;
                    // Counting beyond the number compared with adds states, not answers.
                    let bound = match self.toks.get(self.at + 1) {
                        Some(Tok::Num(k)) => (*k).min(254) as u8 + 1,
                        _ => 255,
                    };
                    Ok(self.atom(Atom::Count(n, bound)))
                }
                "running" => {
                    let name = self.string("running")?;
                    let n = self.element(&name)?;
                    if !self.g.node(n).is_activity() {
                        return Err(format!("\"{}\" is not an activity", self.g.node(n).id));
                    }
                    Ok(self.atom(Atom::Running(n)))
                }
                "signal" => {
                    let s = self.string("signal")?;
                    if !self.g.signals.iter().any(|x| x.name == s || x.id == s) {
                        return Err(format!("no signal is named \"{s}\""));
                    }
                    let name = self
                        .g
                        .signals
                        .iter()
                        .find(|x| x.name == s || x.id == s)
                        .map(|x| x.name.clone())
                        .unwrap_or(s);
                    Ok(self.atom(Atom::Signal(name)))
                }
                "error" => {
                    let code = self.string("error")?;
                    Ok(self.atom(Atom::Error(code)))
                }
                "ended" | "failed" | "terminated" => Ok(w),
                other => Err(format!("`{other}` is not part of the requirement language")),
            },
            other => Err(format!("unexpected {other:?}")),
        }
    }
}

/// Compiles one statement: the LTL formula (atoms as `@k`) and the atoms it reads.
pub fn compile(check: &str, g: &ProcessGraph) -> Result<(String, Vec<Atom>), String> {
    let mut p = Parser {
        toks: lex(check)?,
        at: 0,
        g,
        atoms: Vec::new(),
    };
    let formula = if p.word("eventually") {
        format!("<> ({})", p.or()?)
    } else if p.word("always") {
        format!("[] ({})", p.or()?)
    } else if p.word("never") {
        format!("[] !({})", p.or()?)
    } else if p.word("after") {
        let a = p.or()?;
        if p.word("eventually") {
            format!("[] (({a}) -> <> ({}))", p.or()?)
        } else if p.word("always") {
            format!("[] (({a}) -> [] ({}))", p.or()?)
        } else if p.word("never") {
            format!("[] (({a}) -> [] !({}))", p.or()?)
        } else {
            return Err("`after A` is followed by `eventually`, `always` or `never`".into());
        }
    } else {
        let e = p.or()?;
        if !p.word("when") {
            return Err("a statement starts with `eventually`, `always`, `never` or `after`, or ends with `when …`".into());
        }
        let c = if p.word("completed") {
            "!failed".to_owned()
        } else {
            p.or()?
        };
        format!("[] ((ended && ({c})) -> ({e}))")
    };
    if p.at < p.toks.len() {
        return Err(format!("unexpected {:?} after the statement", p.toks[p.at]));
    }
    Ok((formula, p.atoms))
}

/// The atoms of several requirements, deduplicated, with each requirement's formula rewritten
/// to the shared numbering.
pub fn shared_atoms(reqs: &[Requirement]) -> (Vec<Atom>, BTreeMap<String, String>) {
    let mut all: Vec<Atom> = Vec::new();
    let mut formulas = BTreeMap::new();
    for r in reqs {
        let mut f = r.formula.clone();
        // Highest first, so `@1` does not eat the start of `@12`.
        for (k, a) in r.atoms.iter().enumerate().rev() {
            let j = match all.iter().position(|x| x == a) {
                Some(j) => j,
                None => {
                    all.push(a.clone());
                    all.len() - 1
                }
            };
            f = f.replace(&format!("@{k}"), &format!("#{j}"));
        }
        formulas.insert(r.name.clone(), f.replace('#', "@"));
    }
    (all, formulas)
}

/// The Spin claims of requirements, on a translation instrumented for their shared atoms
/// (`formulas` from [`shared_atoms`]): each `@k` becomes what reads atom `k` in the model.
pub fn claims(
    reqs: &[Requirement],
    formulas: &BTreeMap<String, String>,
    t: &crate::Translation,
) -> Vec<crate::Ltl> {
    reqs.iter()
        .map(|r| {
            let mut formula = formulas[&r.name].clone();
            // Highest first, as in `shared_atoms`.
            for (k, expr) in t.atoms.iter().enumerate().rev() {
                formula = formula.replace(&format!("@{k}"), expr);
            }
            crate::Ltl {
                name: r.name.clone(),
                description: r.says.clone(),
                formula,
            }
        })
        .collect()
}
