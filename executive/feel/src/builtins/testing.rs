//! Test support for the built-ins: a mock [`Host`], a reader for the literal values the tests
//! write (`[1, "a", {k: null}, [1..5)]`), and table checks of calls against expected values.

use chrono::NaiveDate;
use rust_decimal::Decimal;

use super::BUILTINS;
use crate::host::{Host, Stop};
use crate::value::{Bound, Context, DateTime, Function, Range, Value};

/// A host that records null reasons and spent budget; `apply` calls built-ins only.
pub(super) struct Mock {
    /// Every null reason, in order.
    pub notes: Vec<String>,
    /// Budget spent so far.
    pub spent: usize,
    /// The budget.
    pub budget: usize,
}

impl Mock {
    /// A host with `budget` steps.
    pub(super) fn new(budget: usize) -> Mock {
        Mock {
            notes: Vec::new(),
            spent: 0,
            budget,
        }
    }
}

impl Host for Mock {
    fn now(&self) -> DateTime {
        DateTime {
            local: NaiveDate::from_ymd_opt(2026, 11, 23)
                .and_then(|d| d.and_hms_opt(10, 0, 0))
                .unwrap_or_default(),
            zone: None,
        }
    }

    fn null(&mut self, why: String) -> Value {
        self.notes.push(why);
        Value::Null
    }

    fn spend(&mut self, units: usize) -> Result<(), Stop> {
        self.spent = self.spent.saturating_add(units);
        if self.spent > self.budget {
            Err(Stop::Budget(self.budget))
        } else {
            Ok(())
        }
    }

    fn apply(&mut self, function: &Value, args: Vec<Value>) -> Result<Value, Stop> {
        match function {
            Value::Function(Function::Builtin(name)) => call_in(self, name, args),
            other => Err(Stop::Failed(format!("mock: cannot apply {other}"))),
        }
    }
}

/// Calls built-in `name` with positional arguments, choosing the overload as the evaluator
/// does (the first whose parameter count fits).
pub(super) fn call_in(host: &mut Mock, name: &str, args: Vec<Value>) -> Result<Value, Stop> {
    let n = args.len();
    let chosen = BUILTINS.iter().find(|b| {
        b.name == name
            && if b.variadic {
                n + 1 >= b.params.len()
            } else {
                n == b.params.len()
            }
    });
    match chosen {
        Some(b) => (b.run)(host, args),
        None => Err(Stop::Failed(format!(
            "mock: no `{name}` taking {n} arguments"
        ))),
    }
}

/// Reads `name(arg, …)` and calls it on a fresh host with a large budget.
pub(super) fn call(text: &str) -> (Result<Value, Stop>, Mock) {
    let mut host = Mock::new(1_000_000);
    let out = call_with(&mut host, text);
    (out, host)
}

/// Reads `name(arg, …)` and calls it on `host`.
pub(super) fn call_with(host: &mut Mock, text: &str) -> Result<Value, Stop> {
    let open = text.find('(').expect("a call has `(`");
    let name = text[..open].trim();
    let inner = text[open + 1..]
        .trim_end()
        .strip_suffix(')')
        .expect("a call ends with `)`");
    let mut r = Reader::new(inner);
    let mut args = Vec::new();
    r.ws();
    while !r.done() {
        args.push(r.value());
        r.ws();
        if !r.eat(",") {
            break;
        }
    }
    assert!(r.done(), "unread text in `{text}` at {}", r.pos);
    call_in(host, name, args)
}

/// Reads a literal value.
pub(super) fn lit(text: &str) -> Value {
    let mut r = Reader::new(text);
    let v = r.value();
    r.ws();
    assert!(r.done(), "unread text in `{text}`");
    v
}

/// Checks each `(call, expected)`: the result printed equals the expected literal printed.
/// A failure lists every differing row.
pub(super) fn check(rows: &[(&str, &str)]) {
    let mut bad = Vec::new();
    for (c, expected) in rows {
        let (out, host) = call(c);
        let want = lit(expected).to_string();
        match out {
            Ok(v) if v.to_string() == want => {}
            Ok(v) => bad.push(format!(
                "{c}: got {v}, want {want} (notes {:?})",
                host.notes
            )),
            Err(e) => bad.push(format!("{c}: stopped ({e}), want {want}")),
        }
    }
    assert!(
        bad.is_empty(),
        "{} rows differ:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

/// Checks each `(call, reason)`: the result is null and the first recorded reason contains
/// `reason` (and names the function).
pub(super) fn nulls(rows: &[(&str, &str)]) {
    let mut bad = Vec::new();
    for (c, reason) in rows {
        let (out, host) = call(c);
        let name = c[..c.find('(').unwrap_or(0)].trim();
        match (out, host.notes.first()) {
            (Ok(Value::Null), Some(note)) if note.contains(reason) && note.starts_with(name) => {}
            (Ok(v), note) => bad.push(format!(
                "{c}: got {v}, note {note:?}, want null for {reason:?}"
            )),
            (Err(e), _) => bad.push(format!("{c}: stopped ({e}), want null for {reason:?}")),
        }
    }
    assert!(
        bad.is_empty(),
        "{} rows differ:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

/// A reader of test literals: null, booleans, numbers, strings, lists, contexts, ranges
/// (`[1..5)`, `(..3]` open below) and built-in functions (`@before`).
struct Reader<'a> {
    s: &'a str,
    pos: usize,
}

impl<'a> Reader<'a> {
    fn new(s: &'a str) -> Self {
        Reader { s, pos: 0 }
    }

    fn rest(&self) -> &'a str {
        &self.s[self.pos..]
    }

    fn done(&self) -> bool {
        self.pos >= self.s.len()
    }

    fn ws(&mut self) {
        let t = self.rest();
        self.pos += t.len() - t.trim_start().len();
    }

    fn eat(&mut self, t: &str) -> bool {
        self.ws();
        if self.rest().starts_with(t) {
            self.pos += t.len();
            true
        } else {
            false
        }
    }

    fn value(&mut self) -> Value {
        self.ws();
        let rest = self.rest();
        for (word, v) in [
            ("null", Value::Null),
            ("true", Value::Bool(true)),
            ("false", Value::Bool(false)),
        ] {
            if rest.starts_with(word) {
                self.pos += word.len();
                return v;
            }
        }
        match rest.chars().next() {
            Some('"') => Value::String(self.string()),
            Some('{') => self.context(),
            Some('[' | '(') => self.list_or_range(),
            Some('@') => {
                self.pos += 1;
                let name: String = self
                    .rest()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == ' ')
                    .collect();
                self.pos += name.len();
                let b = BUILTINS
                    .iter()
                    .find(|b| b.name == name.trim_end())
                    .expect("a built-in");
                Value::Function(Function::Builtin(b.name))
            }
            _ => {
                let b = rest.as_bytes();
                let mut end = 0;
                while let Some(&c) = b.get(end) {
                    let digit_after = b.get(end + 1).is_some_and(u8::is_ascii_digit);
                    if c.is_ascii_digit() || (c == b'-' && end == 0) || (c == b'.' && digit_after) {
                        end += 1;
                    } else {
                        break;
                    }
                }
                let n = rest[..end].to_owned();
                assert!(!n.is_empty(), "no value at `{rest}`");
                self.pos += n.len();
                Value::Number(n.parse::<Decimal>().expect("a number"))
            }
        }
    }

    fn string(&mut self) -> String {
        self.pos += 1;
        let mut out = String::new();
        let mut chars = self.rest().char_indices();
        while let Some((i, c)) = chars.next() {
            match c {
                '"' => {
                    self.pos += i + 1;
                    return out;
                }
                '\\' => match chars.next() {
                    Some((_, 'n')) => out.push('\n'),
                    Some((_, 't')) => out.push('\t'),
                    Some((_, c @ ('"' | '\\'))) => out.push(c),
                    Some((_, c)) => {
                        out.push('\\');
                        out.push(c);
                    }
                    None => break,
                },
                c => out.push(c),
            }
        }
        panic!("unterminated string");
    }

    fn context(&mut self) -> Value {
        self.pos += 1;
        let mut entries = Context::default();
        if self.eat("}") {
            return Value::Context(entries);
        }
        loop {
            self.ws();
            let key = if self.rest().starts_with('"') {
                self.string()
            } else {
                let k: String = self.rest().chars().take_while(|c| *c != ':').collect();
                self.pos += k.len();
                k.trim().to_owned()
            };
            assert!(self.eat(":"), "a context key is followed by `:`");
            let v = self.value();
            entries.put(key, v);
            if self.eat("}") {
                return Value::Context(entries);
            }
            assert!(self.eat(","), "context entries are separated by `,`");
        }
    }

    fn list_or_range(&mut self) -> Value {
        let open = self.rest().starts_with('[');
        self.pos += 1;
        if self.eat("..") {
            return self.range_end(open, None);
        }
        if open && self.eat("]") {
            return Value::List(Vec::new());
        }
        let first = self.value();
        if self.eat("..") {
            return self.range_end(open, Some(first));
        }
        assert!(open, "`(` starts a range");
        let mut items = vec![first];
        loop {
            if self.eat("]") {
                return Value::List(items);
            }
            assert!(self.eat(","), "list items are separated by `,`");
            items.push(self.value());
        }
    }

    fn range_end(&mut self, start_closed: bool, start: Option<Value>) -> Value {
        self.ws();
        let end = if self.rest().starts_with([']', ')']) {
            None
        } else {
            Some(self.value())
        };
        let end_closed = if self.eat("]") {
            true
        } else {
            assert!(self.eat(")"), "a range ends with `]` or `)`");
            false
        };
        Value::Range(Box::new(Range {
            start: Bound {
                value: start,
                closed: start_closed,
            },
            end: Bound {
                value: end,
                closed: end_closed,
            },
        }))
    }
}
