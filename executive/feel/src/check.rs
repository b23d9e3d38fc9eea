//! What can be known about a FEEL expression without running it: the variables it reads, and
//! problems beyond syntax (unknown functions, argument counts and names, literal arguments a
//! function refuses, functions that are not deterministic).

use crate::ast::{Args, Iteration, Kind, Node, Span};
use crate::host;
use crate::value::Value;

/// Functions whose literal arguments are checked by calling them when the model loads.
const CHECKED_ON_LITERALS: &[&str] = &[
    "date",
    "time",
    "date and time",
    "duration",
    "years and months duration",
    "number",
    "matches",
    "replace",
    "split",
    "extract",
    "cycle",
];

/// Functions the engine refuses because they are not deterministic (a replay after a crash
/// would see other values). Multi-word ones are lexed as one name before `(`, so that the
/// message is this one rather than the one for an unquoted name with a space.
pub(crate) const NOT_DETERMINISTIC: &[&str] = &["uuid", "random number"];

/// Calls every node of the tree, parents first.
pub(crate) fn walk(n: &Node, f: &mut dyn FnMut(&Node)) {
    f(n);
    for c in children(n) {
        walk(c, f);
    }
}

/// A node's direct children.
pub(crate) fn children(n: &Node) -> Vec<&Node> {
    match &n.kind {
        Kind::Null | Kind::Bool(_) | Kind::Number(_) | Kind::String(_) | Kind::At(_) => vec![],
        Kind::Name(_) | Kind::Input => vec![],
        Kind::Path(b, _)
        | Kind::Neg(b)
        | Kind::InstanceOf(b, _)
        | Kind::UnaryTest(_, b)
        | Kind::InputTest(b) => vec![b],
        Kind::NotTests(tests) => tests.iter().collect(),
        Kind::Filter(a, b) | Kind::Binary(_, a, b) | Kind::And(a, b) | Kind::Or(a, b) => vec![a, b],
        Kind::Call(c, args) => {
            let mut v: Vec<&Node> = vec![c];
            match args {
                Args::Positional(a) => v.extend(a.iter()),
                Args::Named(a) => v.extend(a.iter().map(|(_, n)| n)),
            }
            v
        }
        Kind::Between(a, b, c) | Kind::If(a, b, c) => vec![a, b, c],
        Kind::In(a, tests) => std::iter::once(&**a).chain(tests.iter()).collect(),
        Kind::List(items) => items.iter().collect(),
        Kind::Context(entries) => entries.iter().map(|(_, n)| n).collect(),
        Kind::Range { start, end, .. } => vec![start, end],
        Kind::For(its, body) | Kind::Quantified(_, its, body) => its
            .iter()
            .flat_map(|i| std::iter::once(&i.source).chain(i.end.iter()))
            .chain(std::iter::once(&**body))
            .collect(),
        Kind::Function(_, body) => vec![&**body],
    }
}

/// A walk that knows which names are bound inside the expression.
struct Scoped<'a> {
    bound: Vec<String>,
    visit: &'a mut dyn FnMut(&Node, &[String]),
}

impl Scoped<'_> {
    fn node(&mut self, n: &Node) {
        (self.visit)(n, &self.bound);
        match &n.kind {
            Kind::Filter(list, filter) => {
                self.node(list);
                self.bound.push("item".to_owned());
                self.node(filter);
                self.bound.pop();
            }
            Kind::Context(entries) => {
                let mark = self.bound.len();
                for (k, v) in entries {
                    self.node(v);
                    self.bound.push(k.clone());
                }
                self.bound.truncate(mark);
            }
            Kind::For(its, body) | Kind::Quantified(_, its, body) => {
                let mark = self.bound.len();
                self.iterations(its);
                // A `for` body sees the results so far as `partial`.
                if matches!(n.kind, Kind::For(..)) {
                    self.bound.push("partial".to_owned());
                }
                self.node(body);
                self.bound.truncate(mark);
            }
            Kind::Function(params, body) => {
                let mark = self.bound.len();
                self.bound.extend(params.iter().cloned());
                self.node(body);
                self.bound.truncate(mark);
            }
            _ => {
                for c in children(n) {
                    self.node(c);
                }
            }
        }
    }

    fn iterations(&mut self, its: &[Iteration]) {
        for it in its {
            self.node(&it.source);
            if let Some(e) = &it.end {
                self.node(e);
            }
            self.bound.push(it.name.clone());
        }
    }
}

/// The variables an expression reads wherever it is evaluated: [`free_variables`] outside
/// every filter's condition (inside one, a name may be a field of the item filtered).
pub(crate) fn required_variables(root: &Node) -> Vec<String> {
    let mut conditions: Vec<(usize, usize)> = Vec::new();
    walk(root, &mut |n| {
        if let Kind::Filter(_, f) = &n.kind {
            conditions.push((f.span.start, f.span.end));
        }
    });
    free_names(root, &|n: &Node| {
        !conditions
            .iter()
            .any(|(s, e)| *s <= n.span.start && n.span.end <= *e)
    })
}

/// The variables an expression reads: free names and the roots of paths, sorted. A name in
/// call position is a function, not a variable, unless the expression binds it.
pub(crate) fn free_variables(root: &Node) -> Vec<String> {
    free_names(root, &|_| true)
}

/// The free names of `root` that `keep` keeps.
fn free_names(root: &Node, keep: &dyn Fn(&Node) -> bool) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut callees: Vec<(usize, usize)> = Vec::new();
    // Spans of names used as callees, found first so the names walk can skip them.
    walk(root, &mut |n| {
        if let Kind::Call(c, _) = &n.kind
            && matches!(c.kind, Kind::Name(_))
        {
            callees.push((c.span.start, c.span.end));
        }
    });
    Scoped {
        bound: Vec::new(),
        visit: &mut |n, bound| {
            if let Kind::Name(name) = &n.kind
                && !bound.contains(name)
                && !callees.contains(&(n.span.start, n.span.end))
                && !(host::overloads(name).next().is_some() && name.contains(' '))
                && keep(n)
            {
                out.push(name.clone());
            }
        },
    }
    .node(root);
    out.sort();
    out.dedup();
    out
}

/// Problems found without running, with where they are.
pub(crate) fn problems(root: &Node) -> Vec<(String, Span)> {
    let mut out = Vec::new();
    Scoped {
        bound: Vec::new(),
        visit: &mut |n, bound| match &n.kind {
            Kind::At(text) => {
                if let Err(why) = crate::temporal::literal(text) {
                    out.push((format!("@\"{text}\": {why}"), n.span));
                }
            }
            Kind::Call(callee, args) => {
                if let Kind::Name(name) = &callee.kind
                    && !bound.contains(name)
                    && let Some(p) = call_problem(name, args)
                {
                    out.push((p, callee.span));
                } else if let Kind::Name(name) = &callee.kind
                    && !bound.contains(name)
                    && CHECKED_ON_LITERALS.contains(&name.as_str())
                    && let Some(why) = literal_call(n)
                {
                    out.push((format!("`{name}(…)` with these arguments: {why}"), n.span));
                }
            }
            _ => {}
        },
    }
    .node(root);
    out
}

fn call_problem(name: &str, args: &Args) -> Option<String> {
    if NOT_DETERMINISTIC.contains(&name) {
        return Some(format!(
            "`{name}()` is not deterministic, so the engine cannot replay it; pass the value in as a variable"
        ));
    }
    let sigs: Vec<&host::Builtin> = host::overloads(name).collect();
    if sigs.is_empty() {
        return Some(format!("no built-in function `{name}`"));
    }
    let fits = match args {
        Args::Positional(a) => sigs.iter().any(|b| {
            if b.variadic {
                a.len() + 1 >= b.params.len()
            } else {
                a.len() == b.params.len()
            }
        }),
        Args::Named(a) => sigs
            .iter()
            .any(|b| a.iter().all(|(k, _)| b.params.contains(&k.as_str()))),
    };
    if fits {
        return None;
    }
    let forms: Vec<String> = sigs
        .iter()
        .map(|b| format!("{name}({})", b.params.join(", ")))
        .collect();
    Some(match args {
        Args::Positional(a) => format!(
            "`{name}` does not take {} argument{}: it is {}",
            a.len(),
            if a.len() == 1 { "" } else { "s" },
            forms.join(" or ")
        ),
        Args::Named(_) => format!(
            "`{name}` has no form with these parameter names: it is {}",
            forms.join(" or ")
        ),
    })
}

/// Evaluates a call whose arguments are all literals; the reason it gives null, if it does.
fn literal_call(call: &Node) -> Option<String> {
    let Kind::Call(_, args) = &call.kind else {
        return None;
    };
    let literal = |n: &Node| {
        matches!(
            n.kind,
            Kind::Null | Kind::Bool(_) | Kind::Number(_) | Kind::String(_) | Kind::At(_)
        )
    };
    let all = match args {
        Args::Positional(a) => !a.is_empty() && a.iter().all(literal),
        Args::Named(a) => !a.is_empty() && a.iter().all(|(_, n)| literal(n)),
    };
    if !all {
        return None;
    }
    let env = crate::Env {
        lookup: &|_| None,
        now: crate::DateTime {
            local: chrono::NaiveDateTime::default(),
            zone: None,
        },
        budget: 10_000,
    };
    match crate::eval::evaluate(call, &env) {
        Ok(e) if matches!(e.value, Value::Null) => {
            Some(e.note.unwrap_or_else(|| "it gives null".to_owned()))
        }
        Ok(_) => None,
        Err(stop) => Some(stop.to_string()),
    }
}
