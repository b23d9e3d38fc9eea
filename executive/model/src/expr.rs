//! Expressions: conditions, mappings, loop conditions and scripts, each read in the language it
//! is written in and compiled to one of the two languages the engine evaluates.
//!
//! The engine evaluates CEL (Common Expression Language, the `cel` crate) and FEEL (DMN's
//! expression language in Camunda 8's dialect, the `executive-feel` crate): both side-effect
//! free, terminating, with no I/O and no clock of their own, so an expression cannot hurt the
//! deterministic engine. CEL reads the plain conditions other BPMN tools write
//! (`test.contains("a")`, `x < 2`) as they are; FEEL is what Camunda Modeler 8 writes. Every
//! expression is compiled and checked once at load; a problem is a diagnostic, never a run-time
//! surprise.
//!
//! The language of an expression ([`Language`]) comes from where it is written: Camunda's
//! wrappers name it (JUEL `${…}` / `#{…}` for Camunda 7, a leading `=` for FEEL in Camunda 8),
//! then the `language` attribute of the expression element, then `expressionLanguage` of the
//! definitions; with none of these it is CEL. FEEL runs as FEEL; JUEL is translated to CEL when
//! it stays inside a subset whose meaning is the same in both ([`crate::juel`]);
//! XPath, which modelers write as boilerplate around plain values, is read as CEL when the text
//! is CEL; any other language (JavaScript, Groovy, Python, …) is an *execution* problem naming
//! the language, so that a binding can be supplied.

use std::sync::Arc;

/// A compiled expression with the text it came from.
#[derive(Clone)]
pub struct Expression {
    /// The expression as written in the model (trimmed).
    pub source: String,
    /// The text compiled: CEL, or FEEL without Camunda's `=` (wrappers removed).
    pub text: String,
    /// Variables the expression reads, sorted: a conditional event re-evaluates when one changes.
    pub variables: Vec<String>,
    program: Compiled,
}

#[derive(Clone)]
enum Compiled {
    Cel(Arc<cel::Program>),
    Feel(Arc<executive_feel::Expression>),
}

/// The compiled form of an expression, in the language the engine evaluates it in.
pub enum Program<'a> {
    /// A CEL program.
    Cel(&'a cel::Program),
    /// A FEEL expression.
    Feel(&'a executive_feel::Expression),
}

impl std::fmt::Debug for Expression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Expression({:?})", self.source)
    }
}

impl PartialEq for Expression {
    fn eq(&self, other: &Self) -> bool {
        self.source == other.source
    }
}

/// The language an expression is written in.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Language {
    /// The Common Expression Language: what the engine evaluates.
    Cel,
    /// The Java Unified Expression Language (`${…}`), Camunda 7's.
    Juel,
    /// The Friendly Enough Expression Language (DMN), Camunda 8's.
    Feel,
    /// XPath, the specification's default, which many modelers declare as boilerplate.
    XPath,
    /// Any other language, as named in the model.
    Other(String),
}

impl Language {
    /// The language a `language`, `expressionLanguage` or `scriptFormat` value names.
    pub fn named(name: &str) -> Language {
        let l = name.trim().to_ascii_lowercase();
        let l = l.trim_end_matches('/');
        if l.is_empty() || matches!(l, "cel" | "text/x-cel" | "trace" | "application/x-cel") {
            Language::Cel
        } else if l.contains("xpath") {
            Language::XPath
        } else if l.contains("feel") {
            Language::Feel
        } else if matches!(
            l,
            "juel" | "el" | "uel" | "http://java.sun.com/products/jsp"
        ) || l.ends_with("/el")
        {
            Language::Juel
        } else {
            Language::Other(name.trim().to_owned())
        }
    }

    /// The name people know the language by.
    pub fn label(&self) -> String {
        match self {
            Language::Cel => "CEL".to_owned(),
            Language::Juel => "JUEL".to_owned(),
            Language::Feel => "FEEL".to_owned(),
            Language::XPath => "XPath".to_owned(),
            Language::Other(n) => {
                let l = n.to_ascii_lowercase();
                let known = [
                    ("javascript", "JavaScript"),
                    ("ecmascript", "JavaScript"),
                    ("groovy", "Groovy"),
                    ("python", "Python"),
                    ("mvel", "MVEL"),
                    ("java", "Java"),
                    ("ruby", "Ruby"),
                    ("xslt", "XSLT"),
                ];
                known
                    .iter()
                    .find(|(k, _)| l.contains(k))
                    .map_or_else(|| format!("`{n}`"), |(_, v)| (*v).to_owned())
            }
        }
    }
}

/// Why an expression cannot be compiled.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Failure {
    /// The text is not valid in its language (or empty).
    Syntax(String),
    /// Valid, perhaps, but in a language (or a part of one) that TRACE does not evaluate.
    Unevaluated(String),
}

impl Failure {
    /// The diagnostic code: `bad-expression` or `unevaluated-language`.
    pub fn code(&self) -> &'static str {
        match self {
            Failure::Syntax(_) => "bad-expression",
            Failure::Unevaluated(_) => "unevaluated-language",
        }
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Syntax(m) | Failure::Unevaluated(m) => f.write_str(m),
        }
    }
}

/// The language an undeclared expression that is not CEL is plainly written in, by the marks
/// of the other engines' defaults: the BPMN XPath functions (§10.2.2, the specification's
/// default language), a JSONPath `$.`, Python's word operators and constants (SpiffWorkflow),
/// Java/MVEL statements (jBPM, Kogito: `return …;`, `kcontext`). `None` when nothing marks it.
fn dialect(text: &str) -> Option<&'static str> {
    const XPATH: [&str; 6] = [
        "getDataObject(",
        "getDataInput(",
        "getDataOutput(",
        "getActivityInstanceAttribute(",
        "getProcessInstanceAttribute(",
        "getGlobalTaskInstanceAttribute(",
    ];
    let t = text.trim();
    if XPATH.iter().any(|f| t.contains(f)) || t.starts_with("/") || t.contains("bpmn:") {
        return Some("XPath (the specification's default language)");
    }
    if t.starts_with("$.") || t.starts_with("$[") {
        return Some("JSONPath");
    }
    let statement = t.ends_with(';') || t.starts_with("return ") || t.contains("kcontext");
    if statement {
        return Some("Java or MVEL (jBPM, Kogito)");
    }
    let words: Vec<&str> = t
        .split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty())
        .collect();
    let python = words.iter().any(|w| {
        matches!(
            *w,
            "not" | "and" | "or" | "is" | "None" | "True" | "False" | "elif"
        )
    });
    if python {
        return Some("Python (SpiffWorkflow's language)");
    }
    None
}

impl Expression {
    /// Compiles `raw`, reading JUEL `${…}` / `#{…}` and FEEL `=…` by their wrappers and any other
    /// text as CEL.
    pub fn parse(raw: &str) -> Result<Expression, String> {
        Self::compile(raw, &Language::Cel).map_err(|f| f.to_string())
    }

    /// Compiles `raw`, written in `declared` unless a wrapper says otherwise.
    pub fn compile(raw: &str, declared: &Language) -> Result<Expression, Failure> {
        let source = raw.trim().to_owned();
        if source.is_empty() {
            return Err(Failure::Syntax("the expression is empty".to_owned()));
        }
        let (language, body) = match wrapped(&source) {
            Some((l, body)) => (l, body.trim()),
            None => (declared.clone(), source.as_str()),
        };
        let text = match &language {
            Language::Cel | Language::XPath => body.to_owned(),
            Language::Juel => crate::juel::to_cel(body).map_err(|why| {
                Failure::Unevaluated(format!(
                    "JUEL expression `{source}` is outside the subset TRACE evaluates: {why}"
                ))
            })?,
            Language::Feel => return compile_feel(source.clone(), body),
            other => {
                return Err(Failure::Unevaluated(format!(
                    "`{source}` is written in {}, which TRACE does not evaluate; write it in CEL or supply a binding",
                    other.label()
                )));
            }
        };
        if text.is_empty() {
            return Err(Failure::Syntax("the expression is empty".to_owned()));
        }
        let program = cel::Program::compile(&text).map_err(|e| {
            let msg = e.to_string();
            let first = msg
                .lines()
                .next()
                .unwrap_or("syntax error")
                .trim()
                .to_owned();
            if language == Language::XPath {
                Failure::Unevaluated(format!(
                    "`{text}` is declared XPath, which TRACE does not evaluate, and is not CEL either ({first})"
                ))
            } else if language != Language::Cel {
                // Valid in its own language, perhaps, but beyond what translates to CEL.
                Failure::Unevaluated(format!(
                    "{} expression `{source}` is outside the subset TRACE evaluates ({first})",
                    language.label()
                ))
            } else if let Some(dialect) = dialect(&text) {
                // Undeclared, not CEL, and plainly another engine's language: named as such.
                Failure::Unevaluated(format!(
                    "`{text}` reads as {dialect}, which TRACE does not evaluate, not as CEL ({first}); write it in CEL or declare its language"
                ))
            } else {
                Failure::Syntax(format!("{first} in `{text}`"))
            }
        })?;
        let mut variables: Vec<String> = program
            .references()
            .variables()
            .into_iter()
            .map(str::to_owned)
            .collect();
        variables.sort();
        variables.dedup();
        Ok(Expression {
            source,
            text,
            variables,
            program: Compiled::Cel(Arc::new(program)),
        })
    }

    /// A condition that never holds: what stands in the graph for one that cannot be evaluated
    /// (its problem is reported), so that no check mistakes it for a missing condition.
    pub(crate) fn never() -> Expression {
        Expression::parse("false").expect("`false` is CEL")
    }

    /// The variables it reads for certain, sorted (what the check before flight asks):
    /// [`Expression::variables`], but names that may be an item's fields or a comprehension's
    /// own (FEEL filters, CEL macros). Worked out when asked, not when the model loads.
    pub fn required(&self) -> Vec<String> {
        let mut out = match &self.program {
            Compiled::Feel(p) => p.required(),
            Compiled::Cel(_) => match cel::parser::Parser::new().parse(&self.text) {
                Ok(ast) => {
                    let mut out = Vec::new();
                    cel_free(&ast, &mut Vec::new(), &mut out);
                    out
                }
                Err(_) => self.variables.clone(),
            },
        };
        out.sort();
        out.dedup();
        out
    }

    /// The compiled program.
    pub fn program(&self) -> Program<'_> {
        match &self.program {
            Compiled::Cel(p) => Program::Cel(p),
            Compiled::Feel(p) => Program::Feel(p),
        }
    }

    /// The expression as CEL text, for tools that read CEL (verification): CEL as written, FEEL
    /// when it stays inside the subset that means the same in both ([`feel_to_cel`]).
    pub fn cel_text(&self) -> Result<String, String> {
        match &self.program {
            Compiled::Cel(_) => Ok(self.text.clone()),
            Compiled::Feel(_) => feel_to_cel(&self.text),
        }
    }
}

/// The free names of a CEL expression: identifiers, but a comprehension's own variables
/// within it (`x` in `list.map(x, x * 2)`, which `cel`'s references list as variables).
fn cel_free(e: &cel::IdedExpr, bound: &mut Vec<String>, out: &mut Vec<String>) {
    use cel::common::ast::{EntryExpr, Expr};
    match &e.expr {
        Expr::Ident(name) => {
            if !name.starts_with('@') && !bound.contains(name) {
                out.push(name.clone());
            }
        }
        Expr::Call(c) => {
            for t in c.target.iter().map(|t| &**t).chain(&c.args) {
                cel_free(t, bound, out);
            }
        }
        Expr::Select(s) => cel_free(&s.operand, bound, out),
        Expr::List(l) => {
            for x in &l.elements {
                cel_free(x, bound, out);
            }
        }
        Expr::Map(m) => {
            for x in &m.entries {
                if let EntryExpr::MapEntry(m) = &x.expr {
                    cel_free(&m.key, bound, out);
                    cel_free(&m.value, bound, out);
                }
            }
        }
        Expr::Struct(s) => {
            for x in &s.entries {
                if let EntryExpr::StructField(f) = &x.expr {
                    cel_free(&f.value, bound, out);
                }
            }
        }
        Expr::Comprehension(c) => {
            cel_free(&c.iter_range, bound, out);
            cel_free(&c.accu_init, bound, out);
            let mark = bound.len();
            bound.extend(
                [Some(&c.iter_var), c.iter_var2.as_ref(), Some(&c.accu_var)]
                    .into_iter()
                    .flatten()
                    .cloned(),
            );
            for x in [&c.loop_cond, &c.loop_step, &c.result] {
                cel_free(x, bound, out);
            }
            bound.truncate(mark);
        }
        Expr::Literal(_) | Expr::Unspecified => {}
    }
}

/// Parses and checks FEEL text; syntax errors and problems found without running (unknown
/// functions, argument counts, literal arguments a function refuses) name their position.
fn compile_feel(source: String, body: &str) -> Result<Expression, Failure> {
    let at = |p: &executive_feel::Problem| {
        if p.span.start >= body.len() {
            return format!("{} (FEEL, at the end of `{body}`)", p.message);
        }
        let column = body.get(..p.span.start).map_or(0, |b| b.chars().count()) + 1;
        format!("{} (FEEL, at character {column} of `{body}`)", p.message)
    };
    let parsed = executive_feel::parse(body).map_err(|p| Failure::Syntax(at(&p)))?;
    let problems = parsed.problems();
    if !problems.is_empty() {
        let all: Vec<String> = problems.iter().map(at).collect();
        return Err(Failure::Syntax(all.join("; ")));
    }
    Ok(Expression {
        source,
        text: body.to_owned(),
        variables: parsed.variables().to_vec(),
        program: Compiled::Feel(Arc::new(parsed)),
    })
}

/// A Camunda 8 attribute that is static text or a FEEL expression (`=…`) that reads no
/// variables, as the text it stands for (`="survey"` is `survey`, `=3` is `3`).
pub(crate) fn constant_text(raw: &str) -> Result<String, String> {
    let Some(body) = raw.trim().strip_prefix('=') else {
        return Ok(raw.trim().to_owned());
    };
    let e = executive_feel::parse(body).map_err(|p| format!("`{raw}`: {}", p.message))?;
    if !e.variables().is_empty() {
        return Err(format!(
            "`{raw}` reads variables ({}), so it is only known at run time; TRACE resolves it when the mission loads, so write a constant",
            e.variables().join(", ")
        ));
    }
    let env = executive_feel::Env {
        lookup: &|_| None,
        now: executive_feel::DateTime {
            local: chrono::NaiveDateTime::default(),
            zone: None,
        },
        budget: executive_feel::BUDGET,
    };
    match e.evaluate(&env).map(|v| v.value) {
        Ok(
            v @ (executive_feel::Value::String(_)
            | executive_feel::Value::Number(_)
            | executive_feel::Value::Bool(_)),
        ) => Ok(executive_feel::plain_text(&v)),
        Ok(other) => Err(format!("`{raw}` gives {other}, not a text or a number")),
        Err(stop) => Err(format!("`{raw}`: {stop}")),
    }
}

/// The language a Camunda wrapper names, and the text inside it.
pub(crate) fn wrapped(s: &str) -> Option<(Language, &str)> {
    for open in ["${", "#{"] {
        if let Some(inner) = s.strip_prefix(open).and_then(|r| r.strip_suffix('}')) {
            return Some((Language::Juel, inner));
        }
    }
    s.strip_prefix('=').map(|r| (Language::Feel, r))
}

/// Translates the part of FEEL that means the same in CEL: names and dotted paths, string,
/// number and boolean literals, `null`, comparisons (`=` is equality), `and`, `or`, `not(…)` and
/// parentheses. Verification reads conditions in this subset; the engine runs FEEL itself.
pub fn feel_to_cel(feel: &str) -> Result<String, String> {
    let mut out = String::new();
    let mut chars = feel.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        match c {
            c if c.is_whitespace() => out.push(' '),
            '(' | ')' => out.push(c),
            '"' => {
                out.push('"');
                loop {
                    match chars.next() {
                        Some((_, '"')) => break,
                        Some((j, '\\')) => {
                            return Err(format!(
                                "an escape in a string at {j} is not in the subset"
                            ));
                        }
                        Some((_, ch)) => out.push(ch),
                        None => return Err("a string is not closed".to_owned()),
                    }
                }
                out.push('"');
            }
            '=' => out.push_str("=="),
            '!' if chars.peek().is_some_and(|(_, n)| *n == '=') => {
                chars.next();
                out.push_str("!=");
            }
            '<' | '>' => {
                out.push(c);
                if chars.peek().is_some_and(|(_, n)| *n == '=') {
                    chars.next();
                    out.push('=');
                }
            }
            c if c.is_ascii_digit() => {
                out.push(c);
                while let Some((_, d)) = chars.peek().copied() {
                    if d.is_ascii_digit() || d == '.' {
                        out.push(d);
                        chars.next();
                    } else {
                        break;
                    }
                }
            }
            c if c.is_ascii_alphabetic() || c == '_' => {
                let mut word = String::from(c);
                while let Some((_, d)) = chars.peek().copied() {
                    if d.is_ascii_alphanumeric() || d == '_' || d == '.' {
                        word.push(d);
                        chars.next();
                    } else {
                        break;
                    }
                }
                match word.as_str() {
                    "and" => out.push_str("&&"),
                    "or" => out.push_str("||"),
                    "not" => {
                        while chars.peek().is_some_and(|(_, n)| n.is_whitespace()) {
                            chars.next();
                        }
                        if chars.peek().is_none_or(|(_, n)| *n != '(') {
                            return Err("`not` is a function in FEEL: not(…)".to_owned());
                        }
                        out.push('!');
                    }
                    "true" | "false" | "null" => out.push_str(&word),
                    "if" | "then" | "else" | "for" | "in" | "some" | "every" | "satisfies"
                    | "instance" | "of" | "between" | "function" | "return" => {
                        return Err(format!("`{word}` is not in the subset"));
                    }
                    w if w.ends_with('.') || w.contains("..") => {
                        return Err(format!("`{w}` is not a name or path"));
                    }
                    w => {
                        // A name followed by `(` is a function call, outside the subset.
                        let mut ahead = chars.clone();
                        while ahead.peek().is_some_and(|(_, n)| n.is_whitespace()) {
                            ahead.next();
                        }
                        if ahead.peek().is_some_and(|(_, n)| *n == '(') {
                            return Err(format!("calls `{w}(…)`"));
                        }
                        out.push_str(w);
                    }
                }
            }
            other => return Err(format!("`{other}` at {i} is not in the subset")),
        }
    }
    Ok(out.trim().to_owned())
}

/// Parses a script in the expression language: assignments `name = expression`, one per line or
/// separated by `;`.
pub fn parse_assignments(script: &str) -> Result<Vec<(String, Expression)>, String> {
    let mut out = Vec::new();
    for stmt in script
        .split([';', '\n'])
        .map(str::trim)
        .filter(|s| !s.is_empty())
    {
        let eq = assignment_eq(stmt)
            .ok_or_else(|| format!("`{stmt}` is not an assignment `name = expression`"))?;
        let name = stmt[..eq].trim();
        let valid = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !valid {
            return Err(format!("`{name}` is not a variable name"));
        }
        out.push((name.to_owned(), Expression::parse(&stmt[eq + 1..])?));
    }
    if out.is_empty() {
        return Err("the script is empty".to_owned());
    }
    Ok(out)
}

/// Byte index of the `=` of an assignment (not part of `==`, `!=`, `<=`, `>=`).
fn assignment_eq(stmt: &str) -> Option<usize> {
    let b = stmt.as_bytes();
    (0..b.len()).find(|&i| {
        b[i] == b'='
            && b.get(i + 1) != Some(&b'=')
            && !matches!(
                i.checked_sub(1).map(|j| b[j]),
                Some(b'=' | b'!' | b'<' | b'>')
            )
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn undeclared_expressions_of_other_engines_are_named_by_their_language() {
        for (text, language) in [
            ("not val", "Python"),
            ("done and not failed", "Python"),
            ("x is None", "Python"),
            ("bpmn:getDataObject('approved')", "XPath"),
            ("not(bpmn:getDataObject('approved'))", "XPath"),
            ("$.foo == true", "JSONPath"),
            ("return approved == true;", "MVEL"),
            ("kcontext.getVariable(\"x\") ==", "MVEL"),
        ] {
            match Expression::compile(text, &Language::Cel) {
                Err(Failure::Unevaluated(m)) => {
                    assert!(m.contains(language), "{text}: {m}")
                }
                other => panic!("{text}: {other:?}"),
            }
        }
        // CEL that fails for its own reasons stays a syntax error.
        assert!(matches!(
            Expression::compile("a >", &Language::Cel),
            Err(Failure::Syntax(_))
        ));
        // And what is CEL compiles, whatever words it uses.
        assert!(Expression::compile("notes == 'x' && order_total > 3", &Language::Cel).is_ok());
    }

    use super::*;

    #[test]
    fn reads_external_suite_conditions_as_written() {
        let e = Expression::parse(" test.contains(\"a\") ").unwrap();
        assert_eq!(e.variables, vec!["test"]);
        assert_eq!(
            Expression::parse("${integerVariable < 2}").unwrap().text,
            "integerVariable < 2"
        );
        assert_eq!(
            Expression::parse("=battery.soc_pct < 30.0")
                .unwrap()
                .variables,
            vec!["battery"]
        );
        assert_eq!(
            Expression::parse("=decision = \"yes\" and not(late)")
                .unwrap()
                .cel_text()
                .unwrap(),
            "decision == \"yes\" && !(late)"
        );
    }

    #[test]
    fn each_language_by_wrapper_then_declaration() {
        let unevaluated = |raw: &str, l: &Language| match Expression::compile(raw, l) {
            Err(Failure::Unevaluated(m)) => m,
            other => panic!("{raw}: {other:?}"),
        };
        let js = Language::named("text/javascript");
        assert!(unevaluated("a > 1", &js).contains("JavaScript"));
        assert!(unevaluated("a > 1", &Language::named("python")).contains("Python"));
        // A wrapper names the language whatever is declared.
        assert_eq!(Expression::compile("${a}", &js).unwrap().text, "a");
        // FEEL is FEEL, by its `=` or by declaration; its errors say where.
        let feel =
            Expression::compile("= day of week(today()) = \"Monday\"", &Language::Cel).unwrap();
        assert!(matches!(feel.program(), Program::Feel(_)));
        assert_eq!(
            Expression::compile("x in [1..3]", &Language::Feel)
                .unwrap()
                .variables,
            ["x"]
        );
        match Expression::compile("=x = = 1", &Language::Cel) {
            Err(Failure::Syntax(m)) => assert!(m.contains("character 5"), "{m}"),
            other => panic!("{other:?}"),
        }
        match Expression::compile("=count(l) > 0 and frobnicate(l)", &Language::Cel) {
            Err(Failure::Syntax(m)) => assert!(m.contains("frobnicate"), "{m}"),
            other => panic!("{other:?}"),
        }
        // XPath declared as boilerplate around a plain value is read; real XPath is named.
        let xpath = Language::named("http://www.w3.org/1999/XPath");
        assert_eq!(Expression::compile("true", &xpath).unwrap().text, "true");
        assert!(unevaluated("count(/a/b) > 1 and", &xpath).contains("XPath"));
        assert_eq!(
            Language::named("https://www.omg.org/spec/DMN/20191111/FEEL/"),
            Language::Feel
        );
    }

    #[test]
    fn no_text_in_any_language_makes_the_reader_panic() {
        // A deterministic walk over strings made of the characters that matter to the readers.
        const ALPHABET: &[char] = &[
            'a',
            'b',
            '1',
            '.',
            ' ',
            '"',
            '\'',
            '\\',
            '=',
            '!',
            '<',
            '>',
            '(',
            ')',
            '[',
            ']',
            '{',
            '}',
            '$',
            '#',
            '+',
            '-',
            '/',
            '?',
            ':',
            ',',
            'é',
            '\u{10348}',
            '\n',
        ];
        let languages = [
            Language::Cel,
            Language::Juel,
            Language::Feel,
            Language::XPath,
            Language::named("groovy"),
        ];
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..3000 {
            let mut text = String::new();
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            for _ in 0..(state >> 59) {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1);
                text.push(ALPHABET[(state >> 33) as usize % ALPHABET.len()]);
            }
            for l in &languages {
                let _ = Expression::compile(&text, l);
                let _ = Expression::compile(&format!("={text}"), l);
                let _ = Expression::compile(&format!("${{{text}}}"), l);
            }
            let _ = feel_to_cel(&text);
            let _ = Language::named(&text).label();
        }
    }

    #[test]
    fn syntax_errors_name_the_expression() {
        let e = Expression::parse("a < ").unwrap_err();
        assert!(e.contains("`a <`"), "{e}");
        assert!(Expression::parse("  ").is_err());
    }

    #[test]
    fn scripts_are_assignments() {
        let a = parse_assignments("x = 1; y = x == 1\nz = y").unwrap();
        assert_eq!(
            a.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
            ["x", "y", "z"]
        );
        assert!(parse_assignments("SCRIPT_task1").is_err());
        assert!(parse_assignments("a.b = 1").is_err());
    }
}
