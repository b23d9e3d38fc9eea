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

/// Whether a problem breaks BPMN 2.0 itself or only keeps this executive from running the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Category {
    /// The model violates BPMN 2.0 (schema, static constraints, broken references).
    Bpmn,
    /// Valid BPMN, but not executable as written: an expression that does not compile, a
    /// service task without a resource name, an ambiguous gateway, a script no one can run.
    Execution,
}

/// Codes of the checks that concern executability rather than BPMN validity.
const EXECUTION_CODES: &[&str] = &[
    "bad-expression",
    "missing-resource",
    "bad-timer",
    "unconditional-branch",
    "no-default-flow",
    "bad-script",
    "missing-script",
    "unsupported",
    "bad-binding",
    "conflicting-bindings",
    "bad-type",
    "unknown-element",
    "missing-activation-condition",
    "unknown-script-language",
    "missing-called-process",
    "missing-message",
    "missing-cardinality",
    "unevaluated-language",
];

/// One problem in a model.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// Stable kebab-case name of the check, e.g. `dangling-reference`.
    pub code: &'static str,
    /// BPMN violation or executability problem.
    pub category: Category,
    /// The rule of the specification this check enforces, if any: a static constraint in
    /// BPMNspector's numbering (`EXT.nnn`), `REF` (typed references), `XSD` (the schema), or a
    /// clause of BPMN 2.0.2 (`§13.2.1`) where no number exists.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub constraint: Option<&'static str>,
    /// What is wrong, in a plain sentence.
    pub message: String,
    /// The imported file the problem is in; `None` for the model file itself.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// BPMN id of the element concerned, if it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub element: Option<String>,
    /// The part of the element a form edits that the problem is in, when one is: a task's
    /// goal input `input:<goal field>` or result output `output:<result field>`, its
    /// `resource`, a flow's `condition` (what the studio marks on that field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
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
        write!(
            f,
            "{}:{}: {sev}[{}]: {}",
            self.line, self.column, self.code, self.message
        )?;
        if let Some(e) = &self.element {
            write!(f, " (element {e})")?;
        }
        Ok(())
    }
}

/// One text of a bundle and where its offsets start.
pub(crate) struct SourceText<'a> {
    /// `None` for the model itself, else the import location.
    pub(crate) name: Option<&'a str>,
    pub(crate) text: &'a str,
    pub(crate) base: usize,
}

/// Collects diagnostics while a model is read, then fills in line and column.
#[derive(Debug, Default)]
pub(crate) struct Sink {
    pub(crate) items: Vec<Diagnostic>,
    /// Indices in `items` of the rules bent harmlessly: errors when reading strictly.
    bent: Vec<usize>,
    /// Indices in `items` of the rules only a strict reading reports.
    pedantic: Vec<usize>,
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
        let category = if EXECUTION_CODES.contains(&code) {
            Category::Execution
        } else {
            Category::Bpmn
        };
        self.items.push(Diagnostic {
            severity,
            code,
            category,
            constraint: None,
            message,
            file: None,
            element: element.map(str::to_owned),
            field: None,
            offset,
            line: 0,
            column: 0,
        });
        self.items.last_mut().expect("just pushed")
    }

    pub(crate) fn error(
        &mut self,
        code: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.push(Severity::Error, code, offset, element, message)
    }

    pub(crate) fn warning(
        &mut self,
        code: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.push(Severity::Warning, code, offset, element, message)
    }

    /// A rule of the specification bent harmlessly: the meaning of the model is still clear (the
    /// sentence says how it is read). A warning that names the rule; `--strict` makes it an error.
    pub(crate) fn bent(
        &mut self,
        code: &'static str,
        rule: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.bent.push(self.items.len());
        self.noted(code, rule, offset, element, message)
    }

    /// A rule that binds executable processes only, bent in a descriptive one: a warning naming
    /// the rule, even when reading strictly.
    pub(crate) fn noted(
        &mut self,
        code: &'static str,
        rule: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.push(Severity::Warning, code, offset, element, message)
            .constraint(rule)
    }

    /// A rule that nearly every model of the tools people use bends and that TRACE never
    /// needs (an `operationRef` on a message event, EXT.128): an error when reading strictly,
    /// and not said otherwise, where it would only be noise.
    pub(crate) fn pedantic(
        &mut self,
        code: &'static str,
        rule: &'static str,
        offset: usize,
        element: Option<&str>,
        message: String,
    ) -> &mut Diagnostic {
        self.pedantic.push(self.items.len());
        self.bent(code, rule, offset, element, message)
    }

    /// Strict reading: every rule bent harmlessly becomes an error.
    pub(crate) fn enforce_rules(&mut self) {
        for &i in &self.bent {
            self.items[i].severity = Severity::Error;
        }
    }

    /// Lenient reading: the rules only a strict reading reports are dropped.
    pub(crate) fn drop_pedantic(&mut self) {
        // Indices ascend as they were pushed: one walk beside the items.
        let mut pedantic = std::mem::take(&mut self.pedantic).into_iter().peekable();
        let mut k = 0;
        self.items.retain(|_| {
            let drop = pedantic.next_if_eq(&k).is_some();
            k += 1;
            !drop
        });
        self.bent.clear();
    }

    pub(crate) fn has_errors(&self) -> bool {
        self.items.iter().any(|d| d.severity == Severity::Error)
    }

    /// Fills in file, line and column and sorts by position (errors first on a tie). `files`
    /// are the bundle's texts in offset order: the model first, then its imports.
    pub(crate) fn finish(mut self, files: &[SourceText<'_>]) -> Vec<Diagnostic> {
        self.items.sort_by_key(|a| (a.offset, a.severity));
        self.items.dedup();
        // Line starts of each file, computed once (diagnostics can be many on a large model).
        let mut starts: Vec<Option<Vec<usize>>> = vec![None; files.len()];
        for d in &mut self.items {
            let Some(i) = files.iter().rposition(|f| f.base <= d.offset) else {
                continue;
            };
            let f = &files[i];
            let text = f.text;
            let starts = starts[i].get_or_insert_with(|| {
                std::iter::once(0)
                    .chain(text.match_indices('\n').map(|(i, _)| i + 1))
                    .collect()
            });
            let offset = (d.offset - f.base).min(text.len());
            let line = starts.partition_point(|&s| s <= offset).max(1);
            let start = starts[line - 1];
            d.line = line;
            d.column = text
                .get(start..offset)
                .map_or(offset - start, |s| s.chars().count())
                + 1;
            d.offset = offset;
            d.file = f.name.map(str::to_owned);
        }
        self.items
    }
}

impl Diagnostic {
    /// Tags the diagnostic with the BPMN static constraint it enforces.
    pub(crate) fn constraint(&mut self, id: &'static str) -> &mut Self {
        self.constraint = Some(id);
        self
    }

    /// Files the diagnostic as an execution problem: valid (or harmlessly bent) BPMN that this
    /// executive cannot run as written.
    pub(crate) fn execution(&mut self) -> &mut Self {
        self.category = Category::Execution;
        self
    }
}
