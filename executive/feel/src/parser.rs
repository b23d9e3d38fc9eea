//! The FEEL parser: tokens → syntax tree, by precedence climbing. Precedence, loosest first:
//! `if`/`for`/`some`/`every`/`function`, `or`, `and`, comparison (`= != < <= > >=`, `between`,
//! `in`, `instance of`), `+ -`, `* /`, `**`, unary `-`, then paths, filters and calls.
//! Nesting is capped (brackets and the tree's depth), so no text can overflow the stack.
//!
//! After `in` come unary tests: one test, a parenthesised list `(< 5, 7, [9..10])`, or
//! `not(…)` of a list; a test may use `?` for the value it tests (`x in contains(?, "a")`),
//! and `?` anywhere else is a syntax error.

use std::sync::Arc;

use crate::ast::{Args, Iteration, Kind, Node, Op, Quantifier, Span};
use crate::lexer::{Tok, Token, lex};

/// The deepest syntax tree the parser builds.
pub(crate) const MAX_TREE: usize = 256;

/// Words that cannot be variable names.
const KEYWORDS: &[&str] = &[
    "and",
    "or",
    "if",
    "then",
    "else",
    "for",
    "in",
    "return",
    "some",
    "every",
    "satisfies",
    "between",
    "instance",
    "of",
    "function",
    "null",
    "true",
    "false",
    "external",
    "?",
];

/// Type names after `instance of` as written (a `-` is a token of its own) and the type each
/// names; a name comes before any name that begins it (`date and time` before `date`). Camunda
/// documents both `days and time duration` and `day-time-duration` (FEEL boolean expressions,
/// "Instance of").
const TYPES: &[(&str, &str)] = &[
    ("years and months duration", "years and months duration"),
    ("year-month-duration", "years and months duration"),
    ("days and time duration", "days and time duration"),
    ("day-time-duration", "days and time duration"),
    ("date and time", "date and time"),
    ("date time", "date and time"),
    ("function", "function"),
    ("boolean", "boolean"),
    ("context", "context"),
    ("number", "number"),
    ("string", "string"),
    ("range", "range"),
    ("date", "date"),
    ("time", "time"),
    ("list", "list"),
    ("Null", "Null"),
    ("Any", "Any"),
];

type Error = (String, Span);

/// Parses a whole expression.
pub(crate) fn parse(text: &str) -> Result<Node, Error> {
    let tokens = lex(text)?;
    let mut p = Parser {
        tokens,
        at: 0,
        depth: 0,
        end: text.len(),
        range_end: false,
        question: None,
    };
    if p.tokens.is_empty() {
        return Err((
            "the expression is empty".to_owned(),
            Span { start: 0, end: 0 },
        ));
    }
    let node = p.expression()?;
    if let Some(t) = p.peek() {
        return Err((
            format!(
                "unexpected {} after a complete expression",
                describe(&t.tok)
            ),
            t.span,
        ));
    }
    Ok(node)
}

struct Parser {
    tokens: Vec<Token>,
    at: usize,
    depth: usize,
    end: usize,
    /// Parsing the upper end of a range, where `[` may close it (`]1..5[`).
    range_end: bool,
    /// Inside a test after `in`: how many times the test has used `?` so far (`None` outside
    /// tests, where `?` is an error).
    question: Option<usize>,
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Number(n) => format!("number `{n}`"),
        Tok::String(_) => "a string".to_owned(),
        Tok::At(_) => "a temporal literal".to_owned(),
        Tok::Name { text, .. } => format!("`{text}`"),
        Tok::Punct(p) => format!("`{p}`"),
    }
}

/// The depth of a node's tree, counted as the parser builds it.
fn depth_of(n: &Node) -> usize {
    // Only the left spine can grow without bound (left-associative chains); the parser
    // bounds everything else by its own recursion depth.
    let mut d = 1;
    let mut cur = n;
    loop {
        cur = match &cur.kind {
            Kind::Binary(_, l, _) | Kind::And(l, _) | Kind::Or(l, _) => l,
            Kind::Path(l, _) | Kind::Filter(l, _) | Kind::Call(l, _) => l,
            _ => return d,
        };
        d += 1;
        if d > MAX_TREE {
            return d;
        }
    }
}

impl Parser {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.at)
    }

    fn peek_at(&self, k: usize) -> Option<&Tok> {
        self.tokens.get(self.at + k).map(|t| &t.tok)
    }

    fn here(&self) -> Span {
        self.peek().map_or(
            Span {
                start: self.end,
                end: self.end,
            },
            |t| t.span,
        )
    }

    fn is_punct(&self, p: &str) -> bool {
        matches!(self.peek(), Some(Token { tok: Tok::Punct(q), .. }) if *q == p)
    }

    fn is_word(&self, w: &str) -> bool {
        matches!(self.peek(), Some(Token { tok: Tok::Name { text, quoted: false }, .. }) if text == w)
    }

    fn eat_punct(&mut self, p: &str) -> bool {
        let yes = self.is_punct(p);
        if yes {
            self.at += 1;
        }
        yes
    }

    fn eat_word(&mut self, w: &str) -> bool {
        let yes = self.is_word(w);
        if yes {
            self.at += 1;
        }
        yes
    }

    fn found(&self) -> String {
        self.peek()
            .map_or_else(|| "the end".to_owned(), |t| describe(&t.tok))
    }

    fn expect_punct(&mut self, p: &str, context: &str) -> Result<Span, Error> {
        let span = self.here();
        if self.eat_punct(p) {
            Ok(span)
        } else {
            Err((
                format!("expected `{p}` {context}, found {}", self.found()),
                span,
            ))
        }
    }

    fn expect_word(&mut self, w: &str, context: &str) -> Result<(), Error> {
        if self.eat_word(w) {
            Ok(())
        } else {
            Err((
                format!("expected `{w}` {context}, found {}", self.found()),
                self.here(),
            ))
        }
    }

    fn node(&self, kind: Kind, start: usize) -> Result<Node, Error> {
        let end = self
            .at
            .checked_sub(1)
            .and_then(|i| self.tokens.get(i))
            .map_or(start, |t| t.span.end);
        let node = Node {
            kind,
            span: Span { start, end },
        };
        if depth_of(&node) > MAX_TREE {
            return Err((
                format!("the expression nests deeper than {MAX_TREE} levels"),
                node.span,
            ));
        }
        Ok(node)
    }

    fn start(&self) -> usize {
        self.here().start
    }

    /// A full expression, including the textual forms.
    fn expression(&mut self) -> Result<Node, Error> {
        self.depth += 1;
        if self.depth > crate::MAX_DEPTH {
            return Err((
                format!(
                    "the expression nests deeper than {} levels",
                    crate::MAX_DEPTH
                ),
                self.here(),
            ));
        }
        let out = self.textual();
        self.depth -= 1;
        out
    }

    fn textual(&mut self) -> Result<Node, Error> {
        let start = self.start();
        if self.eat_word("if") {
            let c = self.expression()?;
            self.expect_word("then", "after the condition of `if`")?;
            let a = self.expression()?;
            self.expect_word(
                "else",
                "after `if … then …`: FEEL's `if` always has an `else`",
            )?;
            let b = self.expression()?;
            return self.node(Kind::If(Box::new(c), Box::new(a), Box::new(b)), start);
        }
        if self.eat_word("for") {
            let its = self.iterations(true)?;
            self.expect_word("return", "after the iterations of `for`")?;
            let body = self.expression()?;
            return self.node(Kind::For(its, Box::new(body)), start);
        }
        for (w, q) in [("some", Quantifier::Some), ("every", Quantifier::Every)] {
            if self.is_word(w) && matches!(self.peek_at(1), Some(Tok::Name { .. })) {
                self.at += 1;
                let its = self.iterations(false)?;
                self.expect_word("satisfies", &format!("after the iterations of `{w}`"))?;
                let body = self.expression()?;
                return self.node(Kind::Quantified(q, its, Box::new(body)), start);
            }
        }
        if self.is_word("function") && matches!(self.peek_at(1), Some(Tok::Punct("("))) {
            self.at += 2;
            let mut params = Vec::new();
            if !self.eat_punct(")") {
                loop {
                    params.push(self.name("a parameter name")?);
                    if self.eat_punct(":") {
                        self.type_name()?;
                    }
                    if self.eat_punct(")") {
                        break;
                    }
                    self.expect_punct(",", "between parameters")?;
                }
            }
            if self.is_word("external") {
                return Err((
                    "external functions are not supported: they would call outside the engine"
                        .to_owned(),
                    self.here(),
                ));
            }
            let body = self.expression()?;
            return self.node(Kind::Function(params, Arc::new(body)), start);
        }
        self.disjunction()
    }

    fn iterations(&mut self, ranges: bool) -> Result<Vec<Iteration>, Error> {
        let mut its = Vec::new();
        loop {
            let name = self.name("an iteration variable")?;
            self.expect_word("in", &format!("after the iteration variable `{name}`"))?;
            let source = self.expression()?;
            let end = if ranges && self.eat_punct("..") {
                Some(self.expression()?)
            } else {
                None
            };
            its.push(Iteration { name, source, end });
            if !self.eat_punct(",") {
                return Ok(its);
            }
        }
    }

    /// A variable or parameter name: one unquoted non-keyword word, or a backticked name.
    fn name(&mut self, what: &str) -> Result<String, Error> {
        match self.peek() {
            Some(Token {
                tok: Tok::Name { text, quoted },
                ..
            }) if *quoted || !KEYWORDS.contains(&text.as_str()) => {
                let text = text.clone();
                self.at += 1;
                Ok(text)
            }
            _ => Err((
                format!("expected {what}, found {}", self.found()),
                self.here(),
            )),
        }
    }

    fn type_name(&mut self) -> Result<String, Error> {
        let start = self.here();
        // Match the tokens ahead against each spelling of a type name.
        for (spelling, ty) in TYPES {
            let mut parts: Vec<&str> = Vec::new();
            for word in spelling.split(' ') {
                for (k, piece) in word.split('-').enumerate() {
                    if k > 0 {
                        parts.push("-");
                    }
                    parts.push(piece);
                }
            }
            let fits = parts
                .iter()
                .enumerate()
                .all(|(k, w)| match self.peek_at(k) {
                    Some(Tok::Punct(p)) => *w == "-" && *p == "-",
                    Some(Tok::Name {
                        text,
                        quoted: false,
                    }) => text == w,
                    _ => false,
                });
            if fits {
                self.at += parts.len();
                // Parameterised types: `list<number>`, `context<a: number>`.
                if self.eat_punct("<") {
                    let mut level = 1;
                    while level > 0 {
                        match self.peek().map(|t| t.tok.clone()) {
                            Some(Tok::Punct("<")) => level += 1,
                            Some(Tok::Punct(">")) => level -= 1,
                            None => {
                                return Err(("a type `<…>` is not closed".to_owned(), start));
                            }
                            _ => {}
                        }
                        self.at += 1;
                    }
                }
                return Ok((*ty).to_owned());
            }
        }
        Err((
            format!(
                "expected a type (number, string, boolean, date, time, date and time, days and time duration, years and months duration, list, context, range, function, Any, Null; also date time, day-time-duration, year-month-duration), found {}",
                self.found()
            ),
            start,
        ))
    }

    fn disjunction(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.conjunction()?;
        while self.eat_word("or") {
            let right = self.conjunction()?;
            left = self.node(Kind::Or(Box::new(left), Box::new(right)), start)?;
        }
        Ok(left)
    }

    fn conjunction(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.comparison()?;
        while self.eat_word("and") {
            let right = self.comparison()?;
            left = self.node(Kind::And(Box::new(left), Box::new(right)), start)?;
        }
        Ok(left)
    }

    fn comparison_op(&self) -> Option<Op> {
        match self.peek().map(|t| &t.tok) {
            Some(Tok::Punct("=")) => Some(Op::Eq),
            Some(Tok::Punct("!=")) => Some(Op::Ne),
            Some(Tok::Punct("<")) => Some(Op::Lt),
            Some(Tok::Punct("<=")) => Some(Op::Le),
            Some(Tok::Punct(">")) => Some(Op::Gt),
            Some(Tok::Punct(">=")) => Some(Op::Ge),
            _ => None,
        }
    }

    fn comparison(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.additive()?;
        loop {
            if let Some(op) = self.comparison_op() {
                self.at += 1;
                let right = self.additive()?;
                left = self.node(Kind::Binary(op, Box::new(left), Box::new(right)), start)?;
            } else if self.eat_word("between") {
                let low = self.additive()?;
                self.expect_word("and", "between the ends of `between`")?;
                let high = self.additive()?;
                left = self.node(
                    Kind::Between(Box::new(left), Box::new(low), Box::new(high)),
                    start,
                )?;
            } else if self.eat_word("in") {
                let tests = self.tests()?;
                left = self.node(Kind::In(Box::new(left), tests), start)?;
            } else if self.is_word("instance")
                && matches!(self.peek_at(1), Some(Tok::Name { text, quoted: false }) if text == "of")
            {
                self.at += 2;
                let ty = self.type_name()?;
                left = self.node(Kind::InstanceOf(Box::new(left), ty), start)?;
            } else {
                return Ok(left);
            }
        }
    }

    /// The right side of `in`: one test, a parenthesised list of tests `(< 5, 7, [9..10])`, or
    /// the negation of a list `not(2, 3)` (Camunda's unary tests, which `in` evaluates).
    fn tests(&mut self) -> Result<Vec<Node>, Error> {
        let start = self.start();
        if self.is_word("not") && matches!(self.peek_at(1), Some(Tok::Punct("("))) {
            self.at += 2;
            let tests = self.test_list("`in not(…)`")?;
            return Ok(vec![self.node(Kind::NotTests(tests), start)?]);
        }
        if self.is_punct("(") && self.parenthesised_tests() {
            self.at += 1;
            return self.test_list("`in (…)`");
        }
        Ok(vec![self.test(false)?])
    }

    /// Tests separated by `,` up to `)` (the `(` already read).
    fn test_list(&mut self, what: &str) -> Result<Vec<Node>, Error> {
        let mut tests = Vec::new();
        loop {
            tests.push(self.test(true)?);
            if self.eat_punct(")") {
                return Ok(tests);
            }
            self.expect_punct(",", &format!("between the tests of {what}"))?;
        }
    }

    /// Whether the `(` ahead opens a list of tests rather than an expression or open range:
    /// it holds a top-level `,`, or starts with a comparison operator.
    fn parenthesised_tests(&self) -> bool {
        if matches!(
            self.peek_at(1),
            Some(Tok::Punct("<" | "<=" | ">" | ">=" | "=" | "!="))
        ) {
            return true;
        }
        let mut level = 0usize;
        for t in &self.tokens[self.at..] {
            match t.tok {
                Tok::Punct("(" | "[" | "{") => level += 1,
                Tok::Punct(")" | "]" | "}") => {
                    level = level.saturating_sub(1);
                    if level == 0 {
                        return false;
                    }
                }
                Tok::Punct(",") if level == 1 => return true,
                Tok::Punct("..") if level == 1 => return false,
                _ => {}
            }
        }
        false
    }

    /// One test: a comparison with the tested value (`< 5`), or a value, range, list or
    /// expression. A test in a parenthesised list is a whole expression (`? > 10`); a lone
    /// test binds like the operand of a comparison. A test that uses `?` is wrapped in
    /// [`Kind::InputTest`] (a `?` inside a nested `in`'s tests belongs to that `in`).
    fn test(&mut self, in_list: bool) -> Result<Node, Error> {
        let outer = self.question.replace(0);
        let out = self.bare_test(in_list);
        let uses_input = self.question.is_some_and(|n| n > 0);
        self.question = outer;
        let node = out?;
        Ok(if uses_input {
            Node {
                span: node.span,
                kind: Kind::InputTest(Box::new(node)),
            }
        } else {
            node
        })
    }

    fn bare_test(&mut self, in_list: bool) -> Result<Node, Error> {
        let start = self.start();
        if let Some(op) = self.comparison_op() {
            self.at += 1;
            let v = self.additive()?;
            return self.node(Kind::UnaryTest(op, Box::new(v)), start);
        }
        if in_list {
            self.expression()
        } else {
            self.additive()
        }
    }

    fn additive(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.multiplicative()?;
        loop {
            let op = if self.eat_punct("+") {
                Op::Add
            } else if self.eat_punct("-") {
                Op::Sub
            } else {
                return Ok(left);
            };
            let right = self.multiplicative()?;
            left = self.node(Kind::Binary(op, Box::new(left), Box::new(right)), start)?;
        }
    }

    fn multiplicative(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.power()?;
        loop {
            let op = if self.eat_punct("*") {
                Op::Mul
            } else if self.eat_punct("/") {
                Op::Div
            } else {
                return Ok(left);
            };
            let right = self.power()?;
            left = self.node(Kind::Binary(op, Box::new(left), Box::new(right)), start)?;
        }
    }

    fn power(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut left = self.unary()?;
        while self.eat_punct("**") {
            let right = self.unary()?;
            left = self.node(
                Kind::Binary(Op::Pow, Box::new(left), Box::new(right)),
                start,
            )?;
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut negations = 0usize;
        while self.eat_punct("-") {
            negations += 1;
        }
        let mut node = self.postfix()?;
        // `--x` is `x`: fold pairs so a run of signs builds no deep tree.
        if negations % 2 == 1 {
            node = self.node(Kind::Neg(Box::new(node)), start)?;
        }
        Ok(node)
    }

    fn postfix(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let mut node = self.primary()?;
        loop {
            if self.eat_punct(".") {
                let key = self.path_key()?;
                node = self.node(Kind::Path(Box::new(node), key), start)?;
            } else if self.is_punct("[") && (!self.range_end || self.bracket_closes()) {
                self.at += 1;
                let filter = self.expression()?;
                self.expect_punct("]", "to close the filter `[…]`")?;
                node = self.node(Kind::Filter(Box::new(node), Box::new(filter)), start)?;
            } else if self.is_punct("(") {
                self.at += 1;
                let args = self.arguments()?;
                node = self.node(Kind::Call(Box::new(node), args), start)?;
            } else {
                return Ok(node);
            }
        }
    }

    /// The key after `.`: a name, a keyword used as a key, or `time offset`.
    fn path_key(&mut self) -> Result<String, Error> {
        match self.peek().map(|t| t.tok.clone()) {
            Some(Tok::Name { text, quoted }) if quoted || text != "?" => {
                self.at += 1;
                if text == "time" && self.is_word("offset") {
                    self.at += 1;
                    return Ok("time offset".to_owned());
                }
                Ok(text)
            }
            _ => Err((
                format!("expected a name after `.`, found {}", self.found()),
                self.here(),
            )),
        }
    }

    /// Whether the tokens ahead are `words… :` (a named argument or context key).
    fn named_ahead(&self) -> bool {
        let mut k = 0;
        while matches!(self.peek_at(k), Some(Tok::Name { text, quoted }) if *quoted || text != "?")
        {
            k += 1;
        }
        k > 0 && matches!(self.peek_at(k), Some(Tok::Punct(":")))
    }

    /// Words up to `:`, joined by single spaces.
    fn words_key(&mut self) -> String {
        let mut words = Vec::new();
        while let Some(Token {
            tok: Tok::Name { text, quoted },
            ..
        }) = self.peek()
            && (*quoted || text != "?")
        {
            words.push(text.clone());
            self.at += 1;
        }
        words.join(" ")
    }

    fn arguments(&mut self) -> Result<Args, Error> {
        if self.eat_punct(")") {
            return Ok(Args::Positional(Vec::new()));
        }
        if self.named_ahead() {
            let mut named = Vec::new();
            loop {
                if !self.named_ahead() {
                    return Err((
                        format!(
                            "expected a named argument `name: value` (a call's arguments are all named or all positional), found {}",
                            self.found()
                        ),
                        self.here(),
                    ));
                }
                let key = self.words_key();
                self.at += 1; // `:`
                named.push((key, self.expression()?));
                if self.eat_punct(")") {
                    return Ok(Args::Named(named));
                }
                self.expect_punct(",", "between arguments, or `)` to close the call")?;
            }
        }
        let mut args = Vec::new();
        loop {
            args.push(self.expression()?);
            if self.eat_punct(")") {
                return Ok(Args::Positional(args));
            }
            self.expect_punct(",", "between arguments, or `)` to close the call")?;
        }
    }

    fn primary(&mut self) -> Result<Node, Error> {
        let start = self.start();
        let Some(token) = self.peek().cloned() else {
            return Err((
                "the expression ends where a value was expected".to_owned(),
                self.here(),
            ));
        };
        match token.tok {
            Tok::Number(n) => {
                self.at += 1;
                self.node(Kind::Number(n), start)
            }
            Tok::String(s) => {
                self.at += 1;
                self.node(Kind::String(s), start)
            }
            Tok::At(s) => {
                self.at += 1;
                self.node(Kind::At(s), start)
            }
            Tok::Name { text, quoted } => {
                if !quoted {
                    match text.as_str() {
                        "null" => {
                            self.at += 1;
                            return self.node(Kind::Null, start);
                        }
                        "true" | "false" => {
                            self.at += 1;
                            return self.node(Kind::Bool(text == "true"), start);
                        }
                        "if" | "for" | "some" | "every" | "function" => return self.expression(),
                        "?" => {
                            let Some(uses) = self.question.as_mut() else {
                                return Err((
                                    "`?` stands for the tested value only in the tests after `in` (`x in contains(?, \"a\")`, `x in (< 5, ? > 10)`)".to_owned(),
                                    token.span,
                                ));
                            };
                            *uses += 1;
                            self.at += 1;
                            return self.node(Kind::Input, start);
                        }
                        // `and(…)` and `or(…)` are also list functions (feel-scala).
                        "and" | "or" if matches!(self.peek_at(1), Some(Tok::Punct("("))) => {
                            self.at += 1;
                            return self.node(Kind::Name(text), start);
                        }
                        w if KEYWORDS.contains(&w) => {
                            return Err((
                                format!("`{w}` is a keyword; a value was expected here"),
                                token.span,
                            ));
                        }
                        _ => {}
                    }
                }
                self.at += 1;
                // A name is one word: two unquoted words in a row are a name with a space,
                // which Camunda's FEEL writes in backticks.
                if let Some(Token {
                    tok:
                        Tok::Name {
                            text: next,
                            quoted: false,
                        },
                    span,
                }) = self.peek()
                    && !KEYWORDS.contains(&next.as_str())
                {
                    return Err((
                        format!(
                            "unexpected `{next}` after the name `{text}`: a name with spaces is written in backticks (`{text} {next}`)"
                        ),
                        *span,
                    ));
                }
                self.node(Kind::Name(text), start)
            }
            Tok::Punct("(") => {
                self.at += 1;
                let inner = self.expression()?;
                if self.eat_punct("..") {
                    return self.range_rest(start, false, inner);
                }
                self.expect_punct(")", "to close `(`")?;
                // Keep the parenthesised span for messages.
                Ok(Node {
                    kind: inner.kind,
                    span: Span {
                        start,
                        end: self.tokens[self.at - 1].span.end,
                    },
                })
            }
            Tok::Punct("]") => {
                self.at += 1;
                let low = self.expression()?;
                self.expect_punct("..", "in the range `]a..b`")?;
                self.range_rest(start, false, low)
            }
            Tok::Punct("[") => {
                self.at += 1;
                if self.eat_punct("]") {
                    return self.node(Kind::List(Vec::new()), start);
                }
                let first = self.expression()?;
                if self.eat_punct("..") {
                    return self.range_rest(start, true, first);
                }
                let mut items = vec![first];
                loop {
                    if self.eat_punct("]") {
                        return self.node(Kind::List(items), start);
                    }
                    self.expect_punct(",", "between list items, or `]` to close the list")?;
                    items.push(self.expression()?);
                }
            }
            Tok::Punct("{") => {
                self.at += 1;
                let mut entries: Vec<(String, Node)> = Vec::new();
                if self.eat_punct("}") {
                    return self.node(Kind::Context(entries), start);
                }
                loop {
                    let key_span = self.here();
                    let key = match self.peek().map(|t| t.tok.clone()) {
                        Some(Tok::String(s)) => {
                            self.at += 1;
                            s
                        }
                        Some(Tok::Name { text, quoted }) if quoted || text != "?" => {
                            self.words_key()
                        }
                        _ => {
                            return Err((
                                format!("expected a context key, found {}", self.found()),
                                key_span,
                            ));
                        }
                    };
                    self.expect_punct(":", &format!("after the context key `{key}`"))?;
                    if entries.iter().any(|(k, _)| *k == key) {
                        return Err((
                            format!("the context has two entries named `{key}`"),
                            key_span,
                        ));
                    }
                    entries.push((key, self.expression()?));
                    if self.eat_punct("}") {
                        return self.node(Kind::Context(entries), start);
                    }
                    self.expect_punct(",", "between context entries, or `}` to close the context")?;
                }
            }
            _ => Err((
                format!("expected a value, found {}", describe(&token.tok)),
                token.span,
            )),
        }
    }

    /// Whether the `[` ahead has a matching `]` (a filter) rather than closing a range `a..b[`.
    fn bracket_closes(&self) -> bool {
        let mut level = 0usize;
        for t in &self.tokens[self.at..] {
            match t.tok {
                Tok::Punct("(" | "[" | "{") => level += 1,
                Tok::Punct("]") if level == 1 => return true,
                Tok::Punct(")" | "]" | "}") => {
                    level = level.saturating_sub(1);
                    if level == 0 {
                        return false;
                    }
                }
                _ => {}
            }
        }
        false
    }

    /// After `[a..` or `(a..` or `]a..`: the upper end and its bracket.
    fn range_rest(&mut self, start: usize, start_closed: bool, low: Node) -> Result<Node, Error> {
        let outer = std::mem::replace(&mut self.range_end, true);
        let high = self.expression();
        self.range_end = outer;
        let high = high?;
        let end_closed = if self.eat_punct("]") {
            true
        } else if self.eat_punct(")") || self.eat_punct("[") {
            false
        } else {
            return Err((
                format!(
                    "expected `]`, `)` or `[` to close the range, found {}",
                    self.found()
                ),
                self.here(),
            ));
        };
        self.node(
            Kind::Range {
                start: Box::new(low),
                start_closed,
                end: Box::new(high),
                end_closed,
            },
            start,
        )
    }
}
