//! Expressions: the one language for conditions, mappings, loop conditions and scripts.
//!
//! The language is CEL (Common Expression Language, the `cel` crate): side-effect free,
//! terminating, no I/O and no clock, so an expression cannot hurt the deterministic engine, and
//! it reads the conditions other BPMN test suites are written in (`test.contains("a")`,
//! `integerVariable < 2`) as they are. Camunda's wrappers are removed before compiling: JUEL
//! `${…}` and FEEL's leading `=`, so simple Camunda conditions load unchanged. Every expression
//! is compiled once at load; a syntax error is a diagnostic, never a run-time surprise.

use std::sync::Arc;

/// A compiled expression with the text it came from.
#[derive(Clone)]
pub struct Expression {
    /// The expression as written in the model (trimmed).
    pub source: String,
    /// The CEL text compiled (wrappers removed).
    pub text: String,
    /// Variables the expression reads, sorted: a conditional event re-evaluates when one changes.
    pub variables: Vec<String>,
    program: Arc<cel::Program>,
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

impl Expression {
    /// Compiles `raw`, removing JUEL `${…}` / `#{…}` and FEEL `=` wrappers first.
    pub fn parse(raw: &str) -> Result<Expression, String> {
        let source = raw.trim().to_owned();
        let text = unwrap(&source).trim().to_owned();
        if text.is_empty() {
            return Err("the expression is empty".to_owned());
        }
        let program = cel::Program::compile(&text).map_err(|e| {
            let msg = e.to_string();
            let first = msg
                .lines()
                .next()
                .unwrap_or("syntax error")
                .trim()
                .to_owned();
            format!("{first} in `{text}`")
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
            program: Arc::new(program),
        })
    }

    /// The compiled CEL program.
    pub fn program(&self) -> &cel::Program {
        &self.program
    }
}

fn unwrap(s: &str) -> &str {
    for open in ["${", "#{"] {
        if let Some(inner) = s.strip_prefix(open).and_then(|r| r.strip_suffix('}')) {
            return inner;
        }
    }
    s.strip_prefix('=').unwrap_or(s)
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
