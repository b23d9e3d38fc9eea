//! The FEEL evaluator: a syntax tree and an [`Env`] → a value, with Camunda's null rules.
//! Each node visited and each list element made spends one step of the budget; nesting of
//! evaluation (function calls included) is capped, so recursion ends with [`Stop::Depth`].

use std::cmp::Ordering;
use std::sync::Arc;

use rust_decimal::Decimal;
use rust_decimal::prelude::{MathematicalOps, ToPrimitive};

use crate::ast::{Args, Iteration, Kind, Node, Op, Quantifier};
use crate::host::{self, Host};
use crate::value::{Bound, Context, Function, Lambda, Range, Value};
use crate::{Env, Evaluated, Stop};

/// The deepest evaluation nesting (syntax depth plus function calls).
pub(crate) const MAX_NESTING: usize = 320;

/// The local name the tested value is bound to while a test that uses `?` runs: no FEEL text
/// can name it (a backticked name never contains a backtick), so only `?` reads it.
const INPUT: &str = "`?`";

/// Evaluates `root` in `env`.
pub(crate) fn evaluate(root: &Node, env: &Env<'_>) -> Result<Evaluated, Stop> {
    let mut e = Evaluator {
        env,
        left: env.budget,
        depth: 0,
        note: None,
        quiet: 0,
        frames: Vec::new(),
    };
    let value = e.eval(root)?;
    Ok(Evaluated {
        value,
        note: e.note,
    })
}

pub(crate) struct Evaluator<'a> {
    env: &'a Env<'a>,
    left: usize,
    depth: usize,
    note: Option<String>,
    /// While above zero, null reasons are not recorded (trial evaluations).
    quiet: usize,
    /// Local names, innermost last: iteration variables, parameters, context entries, `item`.
    frames: Vec<Vec<(String, Value)>>,
}

impl Host for Evaluator<'_> {
    fn now(&self) -> crate::DateTime {
        self.env.now.clone()
    }

    fn null(&mut self, why: String) -> Value {
        if self.note.is_none() && self.quiet == 0 {
            self.note = Some(why);
        }
        Value::Null
    }

    fn spend(&mut self, units: usize) -> Result<(), Stop> {
        match self.left.checked_sub(units) {
            Some(l) => {
                self.left = l;
                Ok(())
            }
            None => {
                self.left = 0;
                Err(Stop::Budget(self.env.budget))
            }
        }
    }

    fn apply(&mut self, function: &Value, args: Vec<Value>) -> Result<Value, Stop> {
        match function {
            Value::Function(f) => self.call_positional(f, args),
            other => Ok(self.null(format!(
                "a {} is not a function and cannot be called",
                other.type_name()
            ))),
        }
    }
}

fn number_value(n: Option<Decimal>) -> Option<Value> {
    n.map(Value::Number)
}

impl Evaluator<'_> {
    fn eval(&mut self, node: &Node) -> Result<Value, Stop> {
        self.spend(1)?;
        self.depth += 1;
        if self.depth > MAX_NESTING {
            self.depth -= 1;
            return Err(Stop::Depth(MAX_NESTING));
        }
        let out = self.dispatch(node);
        self.depth -= 1;
        out
    }

    /// One node. Every arm that needs more than a few locals is its own function, so that this
    /// frame, which every level of nesting repeats, stays small.
    fn dispatch(&mut self, node: &Node) -> Result<Value, Stop> {
        match &node.kind {
            Kind::Null => Ok(Value::Null),
            Kind::Bool(b) => Ok(Value::Bool(*b)),
            Kind::Number(n) => Ok(Value::Number(*n)),
            Kind::String(s) => Ok(Value::String(s.clone())),
            Kind::At(text) => Ok(self.at(text)),
            Kind::Name(_) | Kind::Path(..) => self.name(node),
            Kind::Input => Ok(match self.local(INPUT) {
                Some(v) => v,
                None => self.null("`?` stands for the tested value only after `in`".to_owned()),
            }),
            Kind::Filter(list, filter) => self.filter(list, filter),
            Kind::Call(callee, args) => self.call(callee, args),
            Kind::Neg(inner) => self.negate(inner),
            Kind::Binary(op, l, r) => self.binary_nodes(*op, l, r),
            Kind::And(l, r) => self.logic(l, r, false),
            Kind::Or(l, r) => self.logic(l, r, true),
            Kind::Between(v, low, high) => self.between(v, low, high),
            Kind::In(v, tests) => self.in_node(v, tests),
            Kind::UnaryTest(..) | Kind::NotTests(_) | Kind::InputTest(_) => Ok(self.null(
                "a unary test such as `< 5` or `not(2, 3)` stands only after `in`".to_owned(),
            )),
            Kind::InstanceOf(v, ty) => self.instance(v, ty),
            Kind::List(items) => self.list(items),
            Kind::Context(entries) => self.context(entries),
            Kind::Range {
                start,
                start_closed,
                end,
                end_closed,
            } => self.range(start, *start_closed, end, *end_closed),
            Kind::If(c, a, b) => self.branch(c, a, b),
            Kind::For(its, body) => self.for_each(its, body),
            Kind::Quantified(q, its, body) => self.quantified(*q, its, body),
            Kind::Function(params, body) => self.lambda(params, body),
        }
    }

    #[inline(never)]
    fn at(&mut self, text: &str) -> Value {
        match crate::temporal::literal(text) {
            Ok(v) => v,
            Err(why) => self.null(format!("@\"{text}\": {why}")),
        }
    }

    #[inline(never)]
    fn name(&mut self, node: &Node) -> Result<Value, Stop> {
        Ok(match self.resolve(node)? {
            Some(v) => v,
            None => {
                let why = self.missing(node);
                self.null(why)
            }
        })
    }

    #[inline(never)]
    fn binary_nodes(&mut self, op: Op, l: &Node, r: &Node) -> Result<Value, Stop> {
        let a = self.eval(l)?;
        let b = self.eval(r)?;
        // Joining strings pays for the text it makes (as the string functions do), so
        // doubling a string again and again stops on the budget, not on memory.
        if let (Op::Add, Value::String(x), Value::String(y)) = (op, &a, &b) {
            self.spend((x.len() + y.len()) / 64)?;
        }
        Ok(self.binary(op, a, b))
    }

    #[inline(never)]
    fn between(&mut self, v: &Node, low: &Node, high: &Node) -> Result<Value, Stop> {
        let v = self.eval(v)?;
        let low = self.eval(low)?;
        let high = self.eval(high)?;
        Ok(match (v.compare(&low), v.compare(&high)) {
            (Some(a), Some(b)) => Value::Bool(a != Ordering::Less && b != Ordering::Greater),
            _ => self.null(format!(
                "`between` cannot compare {} with {} and {}",
                v.type_name(),
                low.type_name(),
                high.type_name()
            )),
        })
    }

    #[inline(never)]
    fn in_node(&mut self, v: &Node, tests: &[Node]) -> Result<Value, Stop> {
        let v = self.eval(v)?;
        self.in_tests(&v, tests)
    }

    #[inline(never)]
    fn instance(&mut self, v: &Node, ty: &str) -> Result<Value, Stop> {
        let v = self.eval(v)?;
        Ok(Value::Bool(instance_of(&v, ty)))
    }

    #[inline(never)]
    fn list(&mut self, items: &[Node]) -> Result<Value, Stop> {
        self.spend(items.len())?;
        let mut out = Vec::with_capacity(items.len());
        for i in items {
            out.push(self.eval(i)?);
        }
        Ok(Value::List(out))
    }

    /// A context literal: each entry sees the entries before it.
    #[inline(never)]
    fn context(&mut self, entries: &[(String, Node)]) -> Result<Value, Stop> {
        self.with_frame(Vec::new(), |e| {
            let mut ctx = Context::default();
            for (k, v) in entries {
                let value = e.eval(v)?;
                if let Some(f) = e.frames.last_mut() {
                    f.push((k.clone(), value.clone()));
                }
                ctx.put(k.clone(), value);
            }
            Ok(Value::Context(ctx))
        })
    }

    #[inline(never)]
    fn range(
        &mut self,
        start: &Node,
        start_closed: bool,
        end: &Node,
        end_closed: bool,
    ) -> Result<Value, Stop> {
        let a = self.eval(start)?;
        let b = self.eval(end)?;
        let bound = |v: Value, closed: bool| Bound {
            value: (!v.is_null()).then_some(v),
            closed,
        };
        Ok(Value::Range(Box::new(Range {
            start: bound(a, start_closed),
            end: bound(b, end_closed),
        })))
    }

    /// `if`: anything but `true` (null included) takes the `else` branch.
    #[inline(never)]
    fn branch(&mut self, c: &Node, a: &Node, b: &Node) -> Result<Value, Stop> {
        match self.eval(c)? {
            Value::Bool(true) => self.eval(a),
            _ => self.eval(b),
        }
    }

    /// `for`: the body's values, in order. A body that reads `partial` sees the values so far
    /// as a list (Camunda: "the previous elements are assigned to the variable `partial`").
    /// That list is a copy, made before each iteration, and costs a step per value copied,
    /// nested values included: `partial` over n numbers costs about n²/2 steps, and a body
    /// that returns `partial` itself (whose copies double) stops after a few iterations.
    #[inline(never)]
    fn for_each(&mut self, its: &[Iteration], body: &Node) -> Result<Value, Stop> {
        let partial = reads_partial(body);
        let mut out = Vec::new();
        // The number of values in `out`, nested ones included (counted only for `partial`).
        let mut copied = 0usize;
        self.iterate(its, 0, &mut |e| {
            let v = if partial {
                e.spend(copied)?;
                let so_far = vec![("partial".to_owned(), Value::List(out.clone()))];
                let v = e.with_frame(so_far, |e| e.eval(body))?;
                copied = copied.saturating_add(weight(&v, e.left));
                v
            } else {
                e.eval(body)?
            };
            e.spend(1)?;
            out.push(v);
            Ok(true)
        })?;
        Ok(Value::List(out))
    }

    #[inline(never)]
    fn quantified(&mut self, q: Quantifier, its: &[Iteration], body: &Node) -> Result<Value, Stop> {
        let want = q == Quantifier::Some;
        let mut found = !want;
        self.iterate(its, 0, &mut |e| {
            let holds = matches!(e.eval(body)?, Value::Bool(true));
            if holds == want {
                found = want;
                return Ok(false);
            }
            Ok(true)
        })?;
        Ok(Value::Bool(found))
    }

    #[inline(never)]
    fn lambda(&mut self, params: &[String], body: &Arc<Node>) -> Result<Value, Stop> {
        // The closure copies every visible local value: paid for by size, as a read is.
        let mut w = 0usize;
        for (_, v) in self.frames.iter().flatten() {
            w = w.saturating_add(weight(v, self.left) - 1);
        }
        self.spend(w)?;
        let closure = self.frames.iter().flatten().cloned().collect();
        Ok(Value::Function(Function::Lambda(Arc::new(Lambda {
            params: params.to_vec(),
            body: Arc::clone(body),
            closure,
        }))))
    }

    /// The value of a name bound inside the expression (iteration variable, parameter, context
    /// entry, `item`).
    fn local(&self, name: &str) -> Option<Value> {
        self.frames
            .iter()
            .rev()
            .find_map(|frame| frame.iter().rev().find(|(k, _)| k == name))
            .map(|(_, v)| v.clone())
    }

    /// The value a name or path denotes, or `None` if it does not exist (a missing variable
    /// or context entry: what `is defined` tells apart from a null). A built-in function's
    /// name is not a value: a missing variable `count` is null, as Camunda documents ("If no
    /// variable exists with the given name, the expression returns null"); `count(l)` still
    /// calls the function (see [`Self::call`]).
    fn resolve(&mut self, node: &Node) -> Result<Option<Value>, Stop> {
        match &node.kind {
            Kind::Name(name) => {
                // Reading a value copies it: the copy is paid for by its size, so values that
                // nest copies of themselves (`{a1: [a0, a0], a2: [a1, a1], …}`) cannot grow
                // memory exponentially within the step budget.
                let found = self
                    .frames
                    .iter()
                    .rev()
                    .find_map(|frame| frame.iter().rev().find(|(k, _)| k == name))
                    .map(|(_, v)| weight(v, self.left) - 1);
                if let Some(w) = found {
                    self.spend(w)?;
                    return Ok(self.local(name));
                }
                let v = (self.env.lookup)(name);
                if let Some(v) = &v {
                    self.spend(weight(v, self.left) - 1)?;
                }
                Ok(v)
            }
            Kind::Path(base, key) => {
                let base = match &base.kind {
                    Kind::Name(_) | Kind::Path(..) => match self.resolve(base)? {
                        Some(v) => v,
                        None => return Ok(None),
                    },
                    _ => self.eval(base)?,
                };
                Ok(self.member(&base, key))
            }
            _ => self.eval(node).map(Some),
        }
    }

    fn missing(&self, node: &Node) -> String {
        match &node.kind {
            Kind::Name(n) => format!("no variable `{n}`"),
            Kind::Path(_, k) => format!("no entry `{k}`"),
            _ => "no value".to_owned(),
        }
    }

    /// `base.key`: a context entry, a property of a temporal value, or the projection over a
    /// list. `None` where there is no such entry.
    fn member(&mut self, base: &Value, key: &str) -> Option<Value> {
        match base {
            Value::Context(c) => c.get(key).cloned(),
            Value::List(items) => Some(Value::List(
                items
                    .iter()
                    .map(|i| self.member(i, key).unwrap_or(Value::Null))
                    .collect(),
            )),
            Value::Null => Some(Value::Null),
            Value::Range(r) => match key {
                "start" => Some(r.start.value.clone().unwrap_or(Value::Null)),
                "end" => Some(r.end.value.clone().unwrap_or(Value::Null)),
                "start included" => Some(Value::Bool(r.start.closed)),
                "end included" => Some(Value::Bool(r.end.closed)),
                _ => None,
            },
            v if v.is_temporal() => crate::temporal::property(v, key),
            _ => None,
        }
    }

    fn with_frame<T>(
        &mut self,
        frame: Vec<(String, Value)>,
        f: impl FnOnce(&mut Self) -> Result<T, Stop>,
    ) -> Result<T, Stop> {
        self.frames.push(frame);
        let out = f(self);
        self.frames.pop();
        out
    }

    /// `list[filter]`: an index when the filter is a number, otherwise the items for which it
    /// holds (with `item` and the item's entries in scope).
    #[inline(never)]
    fn filter(&mut self, list: &Node, filter: &Node) -> Result<Value, Stop> {
        let base = self.eval(list)?;
        let items = match base {
            Value::List(items) => items,
            Value::Null => return Ok(self.null("filtering null".to_owned())),
            single => vec![single],
        };
        // A filter that is a number outside the items is an index (`l[1]`, `l[-1]`, `l[i]`).
        self.quiet += 1;
        let plain = self.eval(filter);
        self.quiet -= 1;
        if let Value::Number(n) = plain? {
            let len = items.len() as i64;
            let Some(i) = n.trunc().to_i64().filter(|_| n.fract().is_zero()) else {
                return Ok(self.null(format!("the index {n} is not a whole number")));
            };
            let at = if i > 0 { i - 1 } else { len + i };
            return Ok(if i != 0 && (0..len).contains(&at) {
                items.into_iter().nth(at as usize).unwrap_or(Value::Null)
            } else {
                self.null(format!("no item at index {i} of a list of {len}"))
            });
        }
        self.spend(items.len())?;
        let mut out = Vec::new();
        for item in items {
            let mut frame = vec![("item".to_owned(), item.clone())];
            if let Value::Context(c) = &item {
                frame.extend(c.0.iter().cloned());
            }
            let keep = self.with_frame(frame, |e| e.eval(filter))?;
            if matches!(keep, Value::Bool(true)) {
                out.push(item);
            }
        }
        Ok(Value::List(out))
    }

    #[inline(never)]
    fn call(&mut self, callee: &Node, args: &Args) -> Result<Value, Stop> {
        let function = match &callee.kind {
            // A function defined in the expression, else a built-in: a variable of the same
            // name (`count`, `sum`) does not hide a built-in function (feel-scala).
            Kind::Name(name) => match (self.local(name), host::overloads(name).next()) {
                (Some(Value::Function(f)), _) => f,
                (_, Some(b)) => Function::Builtin(b.name),
                (Some(other), None) => {
                    return Ok(self.null(format!(
                        "`{name}` is a {}, not a function",
                        other.type_name()
                    )));
                }
                (None, None) => return Ok(self.null(format!("no function `{name}`"))),
            },
            _ => match self.eval(callee)? {
                Value::Function(f) => f,
                other => {
                    return Ok(self.null(format!(
                        "a {} is not a function and cannot be called",
                        other.type_name()
                    )));
                }
            },
        };
        let values = match args {
            Args::Positional(nodes) => {
                let mut values = Vec::with_capacity(nodes.len());
                for n in nodes {
                    values.push(self.eval(n)?);
                }
                values
            }
            Args::Named(named) => {
                let mut values = Vec::with_capacity(named.len());
                for (k, n) in named {
                    values.push((k.clone(), self.eval(n)?));
                }
                return self.call_named(&function, values);
            }
        };
        // A function defined in a context entry sees itself by its name (recursion; the
        // nesting cap ends runaway recursion).
        if let (Kind::Name(name), Function::Lambda(l)) = (&callee.kind, &function) {
            let mut frame = l.closure.clone();
            frame.push((name.clone(), Value::Function(function.clone())));
            let mut args = values.into_iter();
            for p in &l.params {
                frame.push((p.clone(), args.next().unwrap_or(Value::Null)));
            }
            return self.invoke(l, frame);
        }
        self.call_positional(&function, values)
    }

    pub(crate) fn call_positional(
        &mut self,
        function: &Function,
        args: Vec<Value>,
    ) -> Result<Value, Stop> {
        match function {
            Function::Builtin(name) => {
                let n = args.len();
                let chosen = host::overloads(name).find(|b| {
                    if b.variadic {
                        n + 1 >= b.params.len()
                    } else {
                        n == b.params.len()
                    }
                });
                match chosen {
                    Some(b) => self.run_builtin(b, args),
                    None => Ok(self.null(format!("`{name}` takes no {n} arguments"))),
                }
            }
            Function::Lambda(l) => {
                let mut frame = l.closure.clone();
                let mut args = args.into_iter();
                for p in &l.params {
                    frame.push((p.clone(), args.next().unwrap_or(Value::Null)));
                }
                self.invoke(l, frame)
            }
        }
    }

    fn call_named(
        &mut self,
        function: &Function,
        args: Vec<(String, Value)>,
    ) -> Result<Value, Stop> {
        match function {
            Function::Builtin(name) => {
                // feel-scala: the form with the fewest parameters that has every name given;
                // parameters not named are null.
                let chosen = host::overloads(name)
                    .filter(|b| args.iter().all(|(k, _)| b.params.contains(&k.as_str())))
                    .min_by_key(|b| b.params.len());
                let Some(b) = chosen else {
                    let given: Vec<&str> = args.iter().map(|(k, _)| k.as_str()).collect();
                    return Ok(self.null(format!(
                        "`{name}` has no parameters named {}",
                        given.join(", ")
                    )));
                };
                let mut ordered = Vec::with_capacity(b.params.len());
                let mut args = args;
                for p in b.params {
                    match args.iter().position(|(k, _)| k == p) {
                        Some(i) => ordered.push(args.swap_remove(i).1),
                        None => ordered.push(Value::Null),
                    }
                }
                self.run_builtin(b, ordered)
            }
            Function::Lambda(l) => {
                let mut frame = l.closure.clone();
                for p in &l.params {
                    let v = args
                        .iter()
                        .find(|(k, _)| k == p)
                        .map_or(Value::Null, |(_, v)| v.clone());
                    frame.push((p.clone(), v));
                }
                self.invoke(l, frame)
            }
        }
    }

    fn invoke(&mut self, l: &Lambda, frame: Vec<(String, Value)>) -> Result<Value, Stop> {
        // The body runs with only its closure and parameters visible.
        let saved = std::mem::take(&mut self.frames);
        self.frames.push(frame);
        let out = self.eval(&l.body);
        self.frames = saved;
        out
    }

    fn run_builtin(&mut self, b: &'static host::Builtin, args: Vec<Value>) -> Result<Value, Stop> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            self.depth -= 1;
            return Err(Stop::Depth(MAX_NESTING));
        }
        let out = (b.run)(self, args);
        self.depth -= 1;
        out
    }

    #[inline(never)]
    fn negate(&mut self, inner: &Node) -> Result<Value, Stop> {
        let v = self.eval(inner)?;
        Ok(match v {
            Value::Number(n) => Value::Number(-n),
            Value::DayTime(d) => match d.checked_mul(-1) {
                Some(d) => Value::DayTime(d),
                None => self.null("the duration is out of range".to_owned()),
            },
            Value::YearMonth(m) => match m.checked_neg() {
                Some(m) => Value::YearMonth(m),
                None => self.null("the duration is out of range".to_owned()),
            },
            other => self.null(format!("cannot negate a {}", other.type_name())),
        })
    }

    fn binary(&mut self, op: Op, a: Value, b: Value) -> Value {
        match op {
            Op::Eq | Op::Ne => match a.feel_eq(&b) {
                Some(eq) => Value::Bool(eq == (op == Op::Eq)),
                None => self.null(format!(
                    "cannot compare {} with {}",
                    a.type_name(),
                    b.type_name()
                )),
            },
            Op::Lt | Op::Le | Op::Gt | Op::Ge => match a.compare(&b) {
                Some(o) => Value::Bool(match op {
                    Op::Lt => o == Ordering::Less,
                    Op::Le => o != Ordering::Greater,
                    Op::Gt => o == Ordering::Greater,
                    _ => o != Ordering::Less,
                }),
                None => self.null(format!(
                    "cannot order {} and {}",
                    a.type_name(),
                    b.type_name()
                )),
            },
            Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow => {
                let out = self.arithmetic(op, &a, &b);
                match out {
                    Some(v) => v,
                    None => {
                        let verb = match op {
                            Op::Add => "add",
                            Op::Sub => "subtract",
                            Op::Mul => "multiply",
                            Op::Div => "divide",
                            _ => "raise",
                        };
                        let why = if a.is_null() || b.is_null() {
                            format!("cannot {verb} null")
                        } else if matches!(op, Op::Div)
                            && b.as_number().is_some_and(|n| n.is_zero())
                        {
                            "division by zero".to_owned()
                        } else if a.as_number().is_some() && b.as_number().is_some() {
                            format!("the result of `{verb}` is out of range")
                        } else {
                            format!("cannot {verb} {} and {}", a.type_name(), b.type_name())
                        };
                        self.null(why)
                    }
                }
            }
        }
    }

    fn arithmetic(&mut self, op: Op, a: &Value, b: &Value) -> Option<Value> {
        match (a, b) {
            (Value::Number(x), Value::Number(y)) => match op {
                Op::Add => number_value(x.checked_add(*y)),
                Op::Sub => number_value(x.checked_sub(*y)),
                Op::Mul => number_value(x.checked_mul(*y)),
                Op::Div => number_value(x.checked_div(*y)),
                _ => number_value(power(*x, *y)),
            },
            (Value::String(x), Value::String(y)) if op == Op::Add => {
                Some(Value::String(format!("{x}{y}")))
            }
            _ if a.is_temporal() || b.is_temporal() => match op {
                Op::Add => crate::temporal::add(a, b),
                Op::Sub => crate::temporal::sub(a, b),
                Op::Mul => crate::temporal::mul(a, b),
                Op::Div => crate::temporal::div(a, b),
                _ => None,
            },
            _ => None,
        }
    }

    /// `and` (`or` when `or`): three-valued, left to right, stopping at a deciding operand.
    #[inline(never)]
    fn logic(&mut self, l: &Node, r: &Node, or: bool) -> Result<Value, Stop> {
        let a = self.eval(l)?;
        if matches!(a, Value::Bool(x) if x == or) {
            return Ok(a);
        }
        let b = self.eval(r)?;
        Ok(match (a, b) {
            (_, Value::Bool(x)) if x == or => Value::Bool(or),
            (Value::Bool(_), Value::Bool(_)) => Value::Bool(!or),
            (x, y) => {
                let bad = if matches!(x, Value::Bool(_)) { y } else { x };
                self.null(format!(
                    "`{}` needs booleans, got {}",
                    if or { "or" } else { "and" },
                    bad.type_name()
                ))
            }
        })
    }

    /// `v in tests`: true when a test holds; null when the only test cannot tell.
    fn in_tests(&mut self, v: &Value, tests: &[Node]) -> Result<Value, Stop> {
        let mut unknown = false;
        for t in tests {
            match self.unary_test(v, t, false)? {
                Some(true) => return Ok(Value::Bool(true)),
                Some(false) => {}
                None => unknown = true,
            }
        }
        Ok(if unknown && tests.len() == 1 {
            self.null(format!("cannot test a {} with `in`", v.type_name()))
        } else {
            Value::Bool(false)
        })
    }

    /// Whether `v` passes one test, `None` when it cannot tell. `input`: the test uses `?`
    /// (bound by the caller), so an expression test must give a boolean, which is the answer.
    fn unary_test(&mut self, v: &Value, t: &Node, input: bool) -> Result<Option<bool>, Stop> {
        Ok(match &t.kind {
            Kind::UnaryTest(op, bound) => {
                let b = self.eval(bound)?;
                match self.binary(*op, v.clone(), b) {
                    Value::Bool(x) => Some(x),
                    _ => None,
                }
            }
            Kind::NotTests(tests) => match self.in_tests(v, tests)? {
                Value::Bool(x) => Some(!x),
                _ => None,
            },
            Kind::InputTest(inner) => {
                let frame = vec![(INPUT.to_owned(), v.clone())];
                return self.with_frame(frame, |e| e.unary_test(v, inner, true));
            }
            _ if input => match self.eval(t)? {
                Value::Bool(x) => Some(x),
                other => {
                    self.null(format!(
                        "a test that uses `?` must give a boolean, not a {}",
                        other.type_name()
                    ));
                    None
                }
            },
            _ => match self.eval(t)? {
                Value::List(items) => {
                    self.spend(items.len())?;
                    if matches!(v, Value::List(_))
                        && v.feel_eq(&Value::List(items.clone())) == Some(true)
                    {
                        Some(true)
                    } else {
                        Some(items.iter().any(|i| match i {
                            Value::Range(r) => in_range(v, r) == Some(true),
                            i => v.feel_eq(i) == Some(true),
                        }))
                    }
                }
                Value::Range(r) => in_range(v, &r),
                other => v.feel_eq(&other),
            },
        })
    }

    /// Runs `body` for each combination of the iterations' values (the first varies slowest);
    /// `body` returns false to stop.
    fn iterate(
        &mut self,
        its: &[Iteration],
        k: usize,
        body: &mut dyn FnMut(&mut Self) -> Result<bool, Stop>,
    ) -> Result<bool, Stop> {
        let Some(it) = its.get(k) else {
            return body(self);
        };
        let source = self.eval(&it.source)?;
        let values: Box<dyn Iterator<Item = Value>> = match &it.end {
            Some(end) => {
                let end = self.eval(end)?;
                let (Some(a), Some(b)) = (whole(&source), whole(&end)) else {
                    self.null(format!(
                        "the range of `{}` needs whole numbers, got {} and {}",
                        it.name,
                        source.type_name(),
                        end.type_name()
                    ));
                    return Ok(true);
                };
                if a <= b {
                    Box::new((a..=b).map(Value::int))
                } else {
                    Box::new((b..=a).rev().map(Value::int))
                }
            }
            None => match source {
                Value::List(items) => Box::new(items.into_iter()),
                Value::Range(r) => match (
                    r.start.value.as_ref().and_then(whole),
                    r.end.value.as_ref().and_then(whole),
                ) {
                    (Some(a), Some(b)) => {
                        let a = if r.start.closed {
                            a
                        } else {
                            a.saturating_add(1)
                        };
                        let b = if r.end.closed { b } else { b.saturating_sub(1) };
                        Box::new((a..=b).map(Value::int))
                    }
                    _ => {
                        self.null(format!(
                            "`{}` iterates over a range without whole-number ends",
                            it.name
                        ));
                        return Ok(true);
                    }
                },
                Value::Null => {
                    self.null(format!("`{}` iterates over null", it.name));
                    Box::new(std::iter::empty())
                }
                single => Box::new(std::iter::once(single)),
            },
        };
        for v in values {
            self.spend(1)?;
            let go =
                self.with_frame(vec![(it.name.clone(), v)], |e| e.iterate(its, k + 1, body))?;
            if !go {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// Whether a `for` body reads its `partial`: the name outside the bodies of nested `for`s,
/// which bind their own (their iteration sources still see this one's).
fn reads_partial(n: &Node) -> bool {
    match &n.kind {
        Kind::Name(name) => name == "partial",
        Kind::For(its, _) => its
            .iter()
            .any(|i| reads_partial(&i.source) || i.end.as_ref().is_some_and(reads_partial)),
        _ => crate::check::children(n).into_iter().any(reads_partial),
    }
}

/// How many values `v` holds, itself and nested ones included, counting no further than just
/// past `cap` (so counting costs no more than the budget left).
fn weight(v: &Value, cap: usize) -> usize {
    let mut n = 0usize;
    let mut stack = vec![v];
    while let Some(x) = stack.pop() {
        n += 1;
        if n > cap {
            return n;
        }
        match x {
            Value::List(items) => stack.extend(items),
            Value::Context(c) => stack.extend(c.0.iter().map(|(_, v)| v)),
            _ => {}
        }
    }
    n
}

fn whole(v: &Value) -> Option<i64> {
    let n = v.as_number()?;
    if n.fract().is_zero() {
        n.to_i64()
    } else {
        None
    }
}

/// `x ** y`: exact for whole exponents; otherwise through logarithms.
fn power(x: Decimal, y: Decimal) -> Option<Decimal> {
    if y.fract().is_zero() {
        let e = y.to_i64()?;
        if x.is_zero() && e < 0 {
            return None;
        }
        x.checked_powi(e)
    } else {
        if x.is_sign_negative() {
            return None;
        }
        x.checked_powd(y)
    }
}

fn in_range(v: &Value, r: &Range) -> Option<bool> {
    let above = match &r.start.value {
        None => true,
        Some(s) => {
            let o = v.compare(s)?;
            o == Ordering::Greater || (r.start.closed && o == Ordering::Equal)
        }
    };
    let below = match &r.end.value {
        None => true,
        Some(e) => {
            let o = v.compare(e)?;
            o == Ordering::Less || (r.end.closed && o == Ordering::Equal)
        }
    };
    Some(above && below)
}

fn instance_of(v: &Value, ty: &str) -> bool {
    match ty {
        "Any" => !v.is_null(),
        "Null" => v.is_null(),
        t => v.type_name() == t,
    }
}
