//! Diagnostics: every problem found in a model, with element id, position and a plain sentence.

use serde::Serialize;

/// How serious a diagnostic is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// The model cannot be executed.
    Error,
    /// The model loads, but something deserves a look.
    Warning,
}

/// One problem in a model.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// Stable kebab-case name of the check, e.g. `dangling-reference`.
    pub code: &'static str,
    /// BPMN 2.0 static constraint this check enforces (BPMNspector numbering), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub constraint: Option<&'static str>,
    /// What is wrong, in a plain sentence.
    pub message: String,
    /// BPMN id of the element concerned, if it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub element: Option<String>,
    /// Byte offset in the source text.
    pub offset: usize,
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
}

impl std::fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let sev = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(f, "{}:{}: {sev}[{}]: {}", self.line, self.column, self.code, self.message)?;
        if let Some(e) = &self.element {
            write!(f, " (element {e})")?;
        }
        Ok(())
    }
}

/// Collects diagnostics while a model is read, then fills in line and column.
#[derive(Debug, Default)]
pub(crate) struct Sink {
    pub(crate) items: Vec<Diagnostic>,
}

impl Sink {
    pub(crate) fn push(
        &mut self,
        severity: Severity,
        code: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.items.push(Diagnostic {
            severity,
            code,
            constraint: None,
            message,
            element: element.map(str::to_owned),
            offset,
            line: 0,
            column: 0,
        });
        self.items.last_mut().expect("just pushed")
    }

    pub(crate) fn error(&mut self, code: &'static str, offset: usize, element: Option<&str>, message: String) -> &mut Diagnostic {
        self.push(Severity::Error, code, offset, element, message)
    }

    pub(crate) fn warning(&mut self, code: &'static str, offset: usize, element: Option<&str>, message: String) -> &mut Diagnostic {
        self.push(Severity::Warning, code, offset, element, message)
    }

    pub(crate) fn has_errors(&self) -> bool {
        self.items.iter().any(|d| d.severity == Severity::Error)
    }

    /// Fills in line and column from `text` and sorts by position (errors first on a tie).
    pub(crate) fn finish(mut self, text: &str) -> Vec<Diagnostic> {
        let starts: Vec<usize> = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        for d in &mut self.items {
            let offset = d.offset.min(text.len());
            let line = starts.partition_point(|&s| s <= offset).max(1);
            let start = starts[line - 1];
            let column = text.get(start..offset).map_or(offset - start, |s| s.chars().count()) + 1;
            d.line = line;
            d.column = column;
        }
        self.items.sort_by(|a, b| (a.offset, a.severity).cmp(&(b.offset, b.severity)));
        self.items.dedup();
        self.items
    }
}

impl Diagnostic {
    /// Tags the diagnostic with the BPMN static constraint it enforces.
    pub(crate) fn constraint(&mut self, id: &'static str) -> &mut Self {
        self.constraint = Some(id);
        self
    }
}
