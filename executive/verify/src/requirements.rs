//! Mission requirements (`<mission>.req.toml`): named statements in a small language over BPMN
//! elements and the mission's time and energy, compiled to LTL for Spin or to a [`Form`] for the
//! timed exploration.
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
//!
//! Resources: `time` (mission time since the start, compared with an ISO 8601 duration:
//! `time <= P10D`), `energy` (used since the start, idle draw included: `energy <= 40 kWh`),
//! `energy_left` (`>= 5 %`, or in `Wh`/`kWh`); of one vehicle's battery when the mission is
//! costed per pool (a fleet): `energy_left of "Scout" >= 20 %`. Suffixes: `E with Q` (E and, at that moment, Q),
//! `E after D` (E, later than D), `E within D` (eventually E, no later than D). A statement that
//! reads time or energy is `always`, `never`, `eventually` or `… within D`, and is checked by the
//! timed exploration ([`crate::timed`]) against the catalogues' costs, not by Spin:
//!
//! ```toml
//! [[requirement]]
//! name = "five_samples_in_ten_days"
//! check = 'count "Analyze Sample" >= 5 within P10D'
//! ```

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
    /// What it requires of every run.
    pub form: Form,
    /// The LTL formula with `@k` standing for atom `k` (see [`Requirement::atoms`]); empty when
    /// the statement reads time or energy ([`Form::timed`]: the timed exploration checks it).
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
            Ok((form, formula, atoms)) => out.push(Requirement {
                name: e.name,
                says: if e.says.is_empty() {
                    e.check.clone()
                } else {
                    e.says
                },
                check: e.check,
                form,
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
    Real(f64),
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
            while let Some(&d) = chars.peek().filter(|d| d.is_ascii_digit() || **d == '.') {
                n.push(d);
                chars.next();
            }
            if n.contains('.') {
                out.push(Tok::Real(
                    n.parse().map_err(|_| format!("`{n}` is not a number"))?,
                ));
            } else {
                out.push(Tok::Num(
                    n.parse().map_err(|_| format!("`{n}` is too large"))?,
                ));
            }
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
                _ if "<>()%".contains(c) => out.push(Tok::Op(c.to_string())),
                _ => return Err(format!("`{c}` is not part of the requirement language")),
            }
        }
    }
    Ok(out)
}

/// A quantity a resource requirement reads over a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Mission time since the start, ms.
    Time,
    /// Energy used since the start (idle draw included), Wh.
    Energy,
    /// Energy left in the battery, % of its capacity.
    EnergyLeftPct,
    /// Energy left in the battery, Wh.
    EnergyLeftWh,
}

/// A comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cmp {
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
    /// `==`
    Eq,
    /// `!=`
    Ne,
}

impl Cmp {
    fn parse(op: &str) -> Option<Cmp> {
        Some(match op {
            "<" => Cmp::Lt,
            "<=" => Cmp::Le,
            ">" => Cmp::Gt,
            ">=" => Cmp::Ge,
            "==" => Cmp::Eq,
            "!=" => Cmp::Ne,
            _ => return None,
        })
    }

    fn text(self) -> &'static str {
        match self {
            Cmp::Lt => "<",
            Cmp::Le => "<=",
            Cmp::Gt => ">",
            Cmp::Ge => ">=",
            Cmp::Eq => "==",
            Cmp::Ne => "!=",
        }
    }

    /// Whether `a OP b`.
    pub fn holds(self, a: f64, b: f64) -> bool {
        match self {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Gt => a > b,
            Cmp::Ge => a >= b,
            Cmp::Eq => a == b,
            Cmp::Ne => a != b,
        }
    }
}

/// A statement's expression (atoms by index into the requirement's [`Requirement::atoms`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// An atom that is true or false (`done`, `running`, `signal`, `error`).
    Atom(usize),
    /// A counted atom compared with a number.
    Count(usize, Cmp, u64),
    /// `ended`, `failed` or `terminated`.
    Word(String),
    /// A quantity compared with an amount (in the quantity's unit), energy of one vehicle
    /// (`energy of "Scout"`: its pool's id) or of the mission's one battery (`None`).
    Quantity(Quantity, Cmp, f64, Option<String>),
    /// `not`
    Not(Box<Expr>),
    /// `and`
    And(Box<Expr>, Box<Expr>),
    /// `or`
    Or(Box<Expr>, Box<Expr>),
}

impl Expr {
    fn and(a: Expr, b: Expr) -> Expr {
        Expr::And(Box::new(a), Box::new(b))
    }

    /// Whether it reads a quantity (time, energy).
    pub fn timed(&self) -> bool {
        match self {
            Expr::Quantity(..) => true,
            Expr::Not(e) => e.timed(),
            Expr::And(a, b) | Expr::Or(a, b) => a.timed() || b.timed(),
            _ => false,
        }
    }

    /// Once true, true for the rest of the run: made with `and`/`or` (no `not`) of atoms that
    /// are only ever set (`done`, `signal`, `error`; `count` at least a number; `ended`,
    /// `failed`, `terminated`). `running` comes and goes.
    fn monotone(&self, atoms: &[Atom]) -> bool {
        match self {
            Expr::Atom(k) => !matches!(atoms.get(*k), Some(Atom::Running(_)) | None),
            Expr::Count(_, op, _) => matches!(op, Cmp::Ge | Cmp::Gt),
            Expr::Word(_) => true,
            Expr::Quantity(..) | Expr::Not(_) => false,
            Expr::And(a, b) | Expr::Or(a, b) => a.monotone(atoms) && b.monotone(atoms),
        }
    }

    /// The LTL text, atoms as `@k`.
    fn ltl(&self) -> String {
        match self {
            Expr::Atom(k) => format!("@{k}"),
            Expr::Count(k, op, n) => format!("(@{k} {} {})", op.text(), n.min(&255)),
            Expr::Word(w) => w.clone(),
            Expr::Quantity(..) => "true".into(),
            Expr::Not(e) => format!("!{}", e.ltl()),
            Expr::And(a, b) => format!("({} && {})", a.ltl(), b.ltl()),
            Expr::Or(a, b) => format!("({} || {})", a.ltl(), b.ltl()),
        }
    }
}

/// What a statement requires of every run.
#[derive(Clone, Debug, PartialEq)]
pub enum Form {
    /// At some point.
    Eventually(Expr),
    /// At every point.
    Always(Expr),
    /// `after A eventually|always|never B` (the inner form).
    After(Expr, Box<Form>),
    /// At the end, if the condition holds (`None`: unless the mission failed).
    When(Expr, Option<Expr>),
}

impl Form {
    /// Whether it reads time or energy (then the timed exploration checks it, not Spin).
    pub fn timed(&self) -> bool {
        match self {
            Form::Eventually(e) | Form::Always(e) => e.timed(),
            Form::After(a, f) => a.timed() || f.timed(),
            Form::When(e, c) => e.timed() || c.as_ref().is_some_and(Expr::timed),
        }
    }

    /// The statement as a safety claim on the end of a run, for `eventually P` and `after A
    /// eventually P` with `A` and `P` monotone (`Expr::monotone`): `[] (ended -> (A -> P))`.
    /// In a run that ends the two agree — a monotone `P` that ever held still holds at the end,
    /// and a monotone `A` that ever held still holds there — so where every run ends (the
    /// built-in `completes`), this finite search decides the statement without pan's search
    /// for acceptance cycles (atoms as `@k`).
    pub fn at_end(&self, atoms: &[Atom]) -> Option<String> {
        match self {
            Form::Eventually(p) if p.monotone(atoms) => {
                Some(format!("[] (ended -> ({}))", p.ltl()))
            }
            Form::After(a, f) if a.monotone(atoms) => match f.as_ref() {
                Form::Eventually(p) if p.monotone(atoms) => {
                    Some(format!("[] (ended -> (({}) -> ({})))", a.ltl(), p.ltl()))
                }
                _ => None,
            },
            _ => None,
        }
    }

    fn ltl(&self) -> String {
        match self {
            Form::Eventually(e) => format!("<> ({})", e.ltl()),
            Form::Always(Expr::Not(e)) => format!("[] !({})", e.ltl()),
            Form::Always(e) => format!("[] ({})", e.ltl()),
            Form::After(a, f) => format!("[] (({}) -> {})", a.ltl(), f.ltl()),
            Form::When(e, c) => {
                let c = c.as_ref().map_or_else(|| "!failed".to_owned(), Expr::ltl);
                format!("[] ((ended && ({c})) -> ({}))", e.ltl())
            }
        }
    }
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

    fn atom(&mut self, a: Atom) -> usize {
        match self.atoms.iter().position(|x| *x == a) {
            Some(k) => k,
            None => {
                self.atoms.push(a);
                self.atoms.len() - 1
            }
        }
    }

    /// `of "POOL"` after `energy` or `energy_left`: the vehicle whose battery it reads, by its
    /// pool's id or name (a pool with a process), as the pool's id.
    fn vehicle(&mut self) -> Result<Option<String>, String> {
        if !self.word("of") {
            return Ok(None);
        }
        let name = self.string("of")?;
        let pools: Vec<&executive_model::Participant> = self
            .g
            .participants()
            .filter(|p| p.process.is_some())
            .collect();
        let found: Vec<&&executive_model::Participant> = pools
            .iter()
            .filter(|p| p.id == name || p.name.as_deref() == Some(name.as_str()))
            .collect();
        match found.as_slice() {
            [one] => Ok(Some(one.id.clone())),
            [] => Err(format!(
                "no pool with a process has the id or name \"{name}\" (pools: {})",
                pools
                    .iter()
                    .map(|p| format!("\"{}\"", p.id))
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
            _ => Err(format!("\"{name}\" names several pools; use an id")),
        }
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

    fn or(&mut self) -> Result<Expr, String> {
        let mut e = self.and()?;
        while self.word("or") {
            e = Expr::Or(Box::new(e), Box::new(self.and()?));
        }
        Ok(e)
    }

    fn and(&mut self) -> Result<Expr, String> {
        let mut e = self.not()?;
        while self.word("and") {
            e = Expr::and(e, self.not()?);
        }
        Ok(e)
    }

    fn not(&mut self) -> Result<Expr, String> {
        if self.word("not") {
            return Ok(Expr::Not(Box::new(self.not()?)));
        }
        self.primary()
    }

    fn op(&mut self, what: &str) -> Result<Cmp, String> {
        match self.toks.get(self.at) {
            Some(Tok::Op(op)) if Cmp::parse(op).is_some() => {
                self.at += 1;
                Ok(Cmp::parse(op).unwrap_or(Cmp::Eq))
            }
            _ => Err(format!(
                "`{what}` is compared (`<`, `<=`, `>`, `>=`, `==`, `!=`)"
            )),
        }
    }

    fn number(&mut self, after: &str) -> Result<f64, String> {
        match self.toks.get(self.at).cloned() {
            Some(Tok::Num(n)) => {
                self.at += 1;
                Ok(n as f64)
            }
            Some(Tok::Real(x)) => {
                self.at += 1;
                Ok(x)
            }
            _ => Err(format!("`{after}` needs a number after it")),
        }
    }

    /// An ISO 8601 duration (`P18D`, `PT6H30M`), in ms.
    fn duration(&mut self, after: &str) -> Result<f64, String> {
        let bad = || format!("`{after}` needs an ISO 8601 duration after it (`P18D`, `PT6H`)");
        let Some(Tok::Word(w)) = self.toks.get(self.at).cloned() else {
            return Err(bad());
        };
        let d =
            executive_model::timer::parse_duration(&w).map_err(|e| format!("{}: {e}", bad()))?;
        self.at += 1;
        Ok(d.approx_millis() as f64)
    }

    /// An amount of energy (`40 kWh`, `500 Wh`), in Wh.
    fn energy(&mut self, after: &str) -> Result<f64, String> {
        let n = self.number(after)?;
        if self.word("kWh") {
            Ok(n * 1000.0)
        } else if self.word("Wh") {
            Ok(n)
        } else {
            Err(format!(
                "`{after}` needs a unit after the number (`Wh`, `kWh`)"
            ))
        }
    }

    fn primary(&mut self) -> Result<Expr, String> {
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
                Ok(e)
            }
            Tok::Word(w) => match w.as_str() {
                "done" => {
                    let name = self.string("done")?;
                    let n = self.element(&name)?;
                    Ok(Expr::Atom(self.atom(Atom::Done(n))))
                }
                "count" => {
                    let name = self.string("count")?;
                    let n = self.element(&name)?;
                    let op = self
                        .op("count")
                        .map_err(|_| "`count` is compared with a number (`count \"X\" >= 5`)")?;
                    let Some(Tok::Num(k)) = self.toks.get(self.at).cloned() else {
                        return Err(format!("`{}` needs a number after it", op.text()));
                    };
                    self.at += 1;
                    // Counting beyond the number compared with adds states, not answers.
                    let bound = k.min(254) as u8 + 1;
                    Ok(Expr::Count(self.atom(Atom::Count(n, bound)), op, k))
                }
                "running" => {
                    let name = self.string("running")?;
                    let n = self.element(&name)?;
                    if !self.g.node(n).is_activity() {
                        return Err(format!("\"{}\" is not an activity", self.g.node(n).id));
                    }
                    Ok(Expr::Atom(self.atom(Atom::Running(n))))
                }
                "signal" => {
                    let s = self.string("signal")?;
                    let Some(sig) = self.g.signals.iter().find(|x| x.name == s || x.id == s) else {
                        return Err(format!("no signal is named \"{s}\""));
                    };
                    let name = sig.name.clone();
                    Ok(Expr::Atom(self.atom(Atom::Signal(name))))
                }
                "error" => {
                    let code = self.string("error")?;
                    Ok(Expr::Atom(self.atom(Atom::Error(code))))
                }
                "time" => {
                    let op = self.op("time")?;
                    Ok(Expr::Quantity(
                        Quantity::Time,
                        op,
                        self.duration(op.text())?,
                        None,
                    ))
                }
                "energy" => {
                    let pool = self.vehicle()?;
                    let op = self.op("energy")?;
                    Ok(Expr::Quantity(
                        Quantity::Energy,
                        op,
                        self.energy(op.text())?,
                        pool,
                    ))
                }
                "energy_left" => {
                    let pool = self.vehicle()?;
                    let op = self.op("energy_left")?;
                    let n = self.number(op.text())?;
                    if matches!(self.toks.get(self.at), Some(Tok::Op(p)) if p == "%") {
                        self.at += 1;
                        return Ok(Expr::Quantity(Quantity::EnergyLeftPct, op, n, pool));
                    }
                    self.at -= 1;
                    let wh = self.energy(op.text()).map_err(|_| {
                        "`energy_left` is compared with a percentage (`5 %`) or an energy (`2 kWh`)"
                            .to_owned()
                    })?;
                    Ok(Expr::Quantity(Quantity::EnergyLeftWh, op, wh, pool))
                }
                "ended" | "failed" | "terminated" => Ok(Expr::Word(w)),
                other => Err(format!("`{other}` is not part of the requirement language")),
            },
            other => Err(format!("unexpected {other:?}")),
        }
    }

    /// An expression with its suffixes: `with Q` (and Q, at that moment), `after D` (and
    /// later than D). `within D` is the caller's.
    fn body(&mut self) -> Result<Expr, String> {
        let mut e = self.or()?;
        loop {
            if self.word("with") {
                e = Expr::and(e, self.or()?);
            } else if self.word("after") {
                let d = self.duration("after")?;
                e = Expr::and(e, Expr::Quantity(Quantity::Time, Cmp::Gt, d, None));
            } else {
                return Ok(e);
            }
        }
    }

    /// `E within D`: E, no later than D.
    fn within(&mut self, e: Expr) -> Result<(Expr, bool), String> {
        if self.word("within") {
            let d = self.duration("within")?;
            return Ok((
                Expr::and(e, Expr::Quantity(Quantity::Time, Cmp::Le, d, None)),
                true,
            ));
        }
        Ok((e, false))
    }

    fn form(&mut self) -> Result<Form, String> {
        if self.word("eventually") {
            let e = self.body()?;
            return Ok(Form::Eventually(self.within(e)?.0));
        }
        if self.word("always") {
            return Ok(Form::Always(self.body()?));
        }
        if self.word("never") {
            return Ok(Form::Always(Expr::Not(Box::new(self.body()?))));
        }
        if self.word("after") {
            let a = self.or()?;
            if !(self.peek_word("eventually")
                || self.peek_word("always")
                || self.peek_word("never"))
            {
                return Err("`after A` is followed by `eventually`, `always` or `never`".into());
            }
            return Ok(Form::After(a, Box::new(self.form()?)));
        }
        let e = self.body()?;
        let (e, within) = self.within(e)?;
        if within {
            return Ok(Form::Eventually(e));
        }
        if !self.word("when") {
            return Err("a statement starts with `eventually`, `always`, `never` or `after`, or ends with `within …` or `when …`".into());
        }
        let c = if self.word("completed") {
            None
        } else {
            Some(self.or()?)
        };
        Ok(Form::When(e, c))
    }
}

/// Compiles one statement: its form, the LTL formula (atoms as `@k`; empty for a statement
/// that reads time or energy, which Spin does not check) and the atoms it reads.
pub fn compile(check: &str, g: &ProcessGraph) -> Result<(Form, String, Vec<Atom>), String> {
    let mut p = Parser {
        toks: lex(check)?,
        at: 0,
        g,
        atoms: Vec::new(),
    };
    let form = p.form()?;
    if p.at < p.toks.len() {
        return Err(format!("unexpected {:?} after the statement", p.toks[p.at]));
    }
    if form.timed() && !matches!(form, Form::Eventually(_) | Form::Always(_)) {
        return Err(
            "a statement about time or energy is `eventually …`, `always …`, `never …` or `… within D`"
                .into(),
        );
    }
    let ltl = if form.timed() {
        String::new()
    } else {
        form.ltl()
    };
    Ok((form, ltl, p.atoms))
}

/// A requirement's claims in the shared atom numbering.
#[derive(Clone, Debug)]
pub struct Formulas {
    /// The LTL formula.
    pub formula: String,
    /// The same as a safety claim on the end of a run ([`Form::at_end`]), if it has one.
    pub at_end: Option<String>,
}

/// The atoms of several requirements, deduplicated, with each requirement's formulas rewritten
/// to the shared numbering.
pub fn shared_atoms(reqs: &[Requirement]) -> (Vec<Atom>, BTreeMap<String, Formulas>) {
    let mut all: Vec<Atom> = Vec::new();
    let mut formulas = BTreeMap::new();
    for r in reqs.iter().filter(|r| !r.formula.is_empty()) {
        let mut f = r.formula.clone();
        let mut end = r.form.at_end(&r.atoms);
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
            end = end.map(|e| e.replace(&format!("@{k}"), &format!("#{j}")));
        }
        formulas.insert(
            r.name.clone(),
            Formulas {
                formula: f.replace('#', "@"),
                at_end: end.map(|e| e.replace('#', "@")),
            },
        );
    }
    (all, formulas)
}

/// The Spin claims of requirements, on a translation instrumented for their shared atoms
/// (`formulas` from [`shared_atoms`]): each `@k` becomes what reads atom `k` in the model.
pub fn claims(
    reqs: &[Requirement],
    formulas: &BTreeMap<String, Formulas>,
    t: &crate::Translation,
) -> Vec<crate::Ltl> {
    // Highest first, as in `shared_atoms`.
    let model = |mut text: String| {
        for (k, expr) in t.atoms.iter().enumerate().rev() {
            text = text.replace(&format!("@{k}"), expr);
        }
        text
    };
    reqs.iter()
        .filter(|r| !r.formula.is_empty())
        .map(|r| {
            let f = &formulas[&r.name];
            crate::Ltl {
                name: r.name.clone(),
                description: r.says.clone(),
                formula: model(f.formula.clone()),
                at_end: f.at_end.clone().map(model),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn graph() -> ProcessGraph {
        let xml = r#"<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d" targetNamespace="urn:t">
  <process id="p" isExecutable="true">
    <startEvent id="s"/><task id="a" name="Drill"/><task id="b" name="Scoop"/><endEvent id="e"/>
    <sequenceFlow id="f1" sourceRef="s" targetRef="a"/><sequenceFlow id="f2" sourceRef="a" targetRef="b"/>
    <sequenceFlow id="f3" sourceRef="b" targetRef="e"/>
  </process>
</definitions>"#;
        executive_model::load(xml.as_bytes()).graph.expect("valid")
    }

    /// Which statements have a form on the end of a run: `eventually` of atoms that stay true.
    #[test]
    fn only_eventually_of_what_stays_true_is_decided_at_the_end() {
        let g = graph();
        let at_end = |check: &str| {
            let (form, _, atoms) = compile(check, &g).expect(check);
            form.at_end(&atoms)
        };
        assert_eq!(
            at_end(r#"eventually (done "Drill" and count "Scoop" >= 2)"#).as_deref(),
            Some("[] (ended -> ((@0 && (@1 >= 2))))")
        );
        assert_eq!(
            at_end(r#"after done "Drill" eventually done "Scoop""#).as_deref(),
            Some("[] (ended -> ((@0) -> (@1)))")
        );
        for kept in [
            r#"eventually running "Drill""#,
            r#"eventually not done "Drill""#,
            r#"eventually count "Scoop" < 2"#,
            r#"after running "Drill" eventually done "Scoop""#,
            r#"after done "Drill" always done "Scoop""#,
            r#"never done "Drill""#,
            r#"count "Scoop" >= 1 when completed"#,
        ] {
            assert_eq!(at_end(kept), None, "{kept}");
        }
    }
}
