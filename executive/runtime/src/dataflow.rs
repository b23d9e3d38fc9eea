//! Data mistakes caught before flight (`docs/engine-semantics.md`, "Variables before flight"),
//! for `trace validate`, `trace run`'s pre-flight check and the studio:
//! - a variable read that no path writes first ([`executive_model::dataflow`]), with the writer
//!   that comes too late, a name it may have meant, and, for a goal input, the hint to quote a
//!   text;
//! - a variable read that some path reaches unwritten (a warning naming one such path);
//! - a literal that can never be its input's declared type (`"fast"` for an `int`);
//! - a condition written as a literal that is not `true` or `false`.
//!
//! How sure each finding is decides its severity. A name no path writes is an error where
//! everything that could supply it is known: the connectors' system data (a connectors file),
//! and the start variables (`trace run --var`, or, for a mission in TRACE's own vocabulary,
//! the process's declared properties and data objects: TRACE missions declare what they are
//! started with). Otherwise it may come from outside (another engine's starter, telemetry),
//! and it is a warning that says so. A FEEL condition reads a missing name as null, so there
//! it is a warning too.

use std::collections::BTreeSet;

use connector_api::{Catalogue, ConnectorsConfig};
use executive_model::binding::{Dialect, FieldType};
use executive_model::dataflow::{self, Context, Finding, Site};
use executive_model::{
    Category, Diagnostic, EventDefinition, Expression, NodeId, NodeKind, ProcessGraph, ProcessId,
    Severity,
};

/// The code of an unwritten variable's diagnostic.
pub const UNWRITTEN: &str = "unwritten-variable";
/// The code of a variable written on some paths only.
pub const SOMETIMES: &str = "maybe-unwritten-variable";
/// The code of a literal of the wrong type.
pub const LITERAL: &str = "literal-type";

/// What is known besides the model.
#[derive(Default)]
pub struct Known<'a> {
    /// The connectors: their system data names, and their routes to the catalogues.
    pub config: Option<&'a ConnectorsConfig>,
    /// Each connector's catalogue, as [`crate::catalogues::served`] gives them.
    pub catalogues: &'a [Option<Catalogue>],
    /// The start variables, when they are known (`trace run`).
    pub start: Option<&'a BTreeSet<String>>,
}

/// Every data finding of `g` as a diagnostic located in `text`.
pub fn diagnostics(g: &ProcessGraph, text: &str, known: &Known<'_>) -> Vec<Diagnostic> {
    let data: Option<BTreeSet<String>> = known.config.map(|c| {
        c.connectors
            .iter()
            .flat_map(|c| c.data.iter().cloned())
            .collect()
    });
    let start = known.start.cloned().unwrap_or_default();
    let results = |n: NodeId| result_fields(g, known, n);
    let cx = Context {
        start: &start,
        results: &results,
    };
    // Every name the model writes, for "did you mean": only once a name is found unwritten.
    let written = std::cell::OnceCell::new();
    let missions = trace_missions(g);
    let mut out = Vec::new();
    for f in dataflow::check(g, &cx) {
        let var = f.var();
        if data.as_ref().is_some_and(|d| d.contains(var)) {
            continue; // system data
        }
        let (site, node) = match &f {
            Finding::Unwritten { site, .. } | Finding::Sometimes { site, .. } => {
                (site.clone(), site_node(g, site))
            }
        };
        let (element, offset, label) = match &site {
            Site::Node(n) => {
                let node = g.node(*n);
                (node.id.clone(), node.offset, format!("`{}`", node.label()))
            }
            Site::Flow(fl) => {
                let flow = g.flow(*fl);
                let from = g.node(flow.source).label();
                let name = flow
                    .name
                    .as_deref()
                    .filter(|s| !s.trim().is_empty())
                    .map_or(String::new(), |n| format!(" `{n}`"));
                (
                    flow.id.clone(),
                    flow.offset,
                    format!("the condition of the flow{name} from `{from}`"),
                )
            }
        };
        match f {
            Finding::Unwritten {
                var,
                expression,
                feel,
                writer,
                ..
            } => {
                let goal_input = goal_input(g, &site, &expression).is_some();
                let sure = data.is_some()
                    && (known.start.is_some() || missions.contains(&g.process_of(node)))
                    && (!feel || goal_input);
                let mut message = format!(
                    "{label} reads `{var}`, which nothing writes before it (in `{expression}`)"
                );
                if let Some(w) = writer {
                    message.push_str(&format!(
                        "; `{}` writes it, but no path runs it first",
                        g.node(w).label()
                    ));
                }
                let mut names: BTreeSet<&str> = written
                    .get_or_init(|| dataflow::written_names(g))
                    .iter()
                    .map(String::as_str)
                    .collect();
                names.extend(data.iter().flatten().map(String::as_str));
                if let Some(m) = dataflow::near(&var, names) {
                    message.push_str(&format!("; did you mean `{m}`?"));
                }
                if goal_input && expression.trim() == var {
                    message.push_str(&format!("; if it is a text, quote it: `\"{var}\"`"));
                }
                if !sure {
                    message.push_str(if known.start.is_some() {
                        " (it may be system data: no connectors are known)"
                    } else if feel {
                        " (FEEL reads it as null)"
                    } else {
                        " (unless the mission is started with it: `trace run --var`)"
                    });
                }
                let mut d = located(
                    text,
                    if sure {
                        Severity::Error
                    } else {
                        Severity::Warning
                    },
                    UNWRITTEN,
                    &element,
                    offset,
                    message,
                );
                d.field = field_of(g, &site, &expression);
                out.push(d);
            }
            Finding::Sometimes {
                var,
                expression,
                path,
                ..
            } => {
                let path: Vec<String> = path
                    .iter()
                    .map(|n| format!("`{}`", g.node(*n).label()))
                    .collect();
                let via = if path.is_empty() {
                    String::new()
                } else {
                    format!(": for example {}", path.join(" → "))
                };
                let mut d = located(
                    text,
                    Severity::Warning,
                    SOMETIMES,
                    &element,
                    offset,
                    format!(
                        "{label} reads `{var}` (in `{expression}`), which some paths reach without writing it{via}"
                    ),
                );
                d.field = field_of(g, &site, &expression);
                out.push(d);
            }
        }
    }
    out.extend(literals(g, text));
    out
}

/// The node a finding is read at (a flow's: its source).
fn site_node(g: &ProcessGraph, s: &Site) -> NodeId {
    match s {
        Site::Node(n) => *n,
        Site::Flow(f) => g.flow(*f).source,
    }
}

/// The goal field `expression` feeds, when it is an input of the task at `site`.
fn goal_input<'g>(g: &'g ProcessGraph, site: &Site, expression: &str) -> Option<&'g str> {
    let Site::Node(n) = site else { return None };
    let b = match &g.node(*n).kind {
        NodeKind::Task(t) => t.binding.as_ref(),
        NodeKind::CallActivity(c) => c.binding.as_ref(),
        _ => None,
    }?;
    b.inputs
        .iter()
        .find(|i| i.source.source == expression)
        .map(|i| i.target.as_str())
}

/// The part of the element a finding at `site` is in, for [`Diagnostic::field`].
fn field_of(g: &ProcessGraph, site: &Site, expression: &str) -> Option<String> {
    match site {
        Site::Flow(_) => Some("condition".to_owned()),
        Site::Node(_) => goal_input(g, site, expression).map(|t| format!("input:{t}")),
    }
}

/// The processes that are TRACE missions: a task of them is bound in TRACE's own vocabulary.
fn trace_missions(g: &ProcessGraph) -> BTreeSet<ProcessId> {
    g.nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| {
            matches!(&n.kind, NodeKind::Task(t)
                if t.binding.as_ref().is_some_and(|b| b.dialect == Dialect::Trace))
        })
        .map(|(i, _)| g.process_of(NodeId(i as u32)))
        .collect()
}

/// The result fields of a dispatched task, from its catalogue.
fn result_fields(g: &ProcessGraph, known: &Known<'_>, n: NodeId) -> Option<Vec<String>> {
    let config = known.config?;
    let NodeKind::Task(t) = &g.node(n).kind else {
        return None;
    };
    let resource = t.binding.as_ref()?.resource.as_deref()?;
    let route = config.route(resource)?;
    let cat = known.catalogues.get(route.connector)?.as_ref()?;
    let spec = cat.action(&route.action)?;
    Some(spec.result.keys().cloned().collect())
}

/// Literals that can never be what they feed: a goal input's declared type, or a condition.
fn literals(g: &ProcessGraph, text: &str) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    for n in &g.nodes {
        let b = match &n.kind {
            NodeKind::Task(t) => t.binding.as_ref(),
            NodeKind::CallActivity(c) => c.binding.as_ref(),
            _ => None,
        };
        for i in b.iter().flat_map(|b| &b.inputs) {
            let (Some(ty), Some(v)) = (&i.ty, literal(&i.source)) else {
                continue;
            };
            if !fits(&v, ty) {
                let mut d = located(
                    text,
                    Severity::Error,
                    LITERAL,
                    &n.id,
                    n.offset,
                    format!(
                        "`{}` sets `{}` ({}) to `{}`, which is not of type {}",
                        n.label(),
                        i.target,
                        ty_name(ty),
                        i.source.source,
                        ty_name(ty)
                    ),
                );
                d.field = Some(format!("input:{}", i.target));
                out.push(d);
            }
        }
        let conditions = match &n.kind {
            NodeKind::Catch(c) => c.triggers.iter().collect::<Vec<_>>(),
            NodeKind::Boundary(b) => b.triggers.iter().collect(),
            NodeKind::Start(s) => s.triggers.iter().collect(),
            _ => Vec::new(),
        };
        for d in conditions {
            if let EventDefinition::Conditional(e) = d
                && let Some(v) = literal(e)
                && !v.is_boolean()
            {
                out.push(never_boolean(text, &n.id, n.offset, e));
            }
        }
    }
    for f in &g.flows {
        if let Some(c) = &f.condition
            && let Some(v) = literal(c)
            && !v.is_boolean()
        {
            let mut d = never_boolean(text, &f.id, f.offset, c);
            d.field = Some("condition".to_owned());
            out.push(d);
        }
    }
    out
}

fn never_boolean(text: &str, id: &str, offset: usize, e: &Expression) -> Diagnostic {
    located(
        text,
        Severity::Error,
        LITERAL,
        id,
        offset,
        format!(
            "the condition `{}` is never true or false: it is a constant {}",
            e.source,
            match literal(e) {
                Some(serde_json::Value::String(_)) => "text",
                Some(serde_json::Value::Number(_)) => "number",
                Some(serde_json::Value::Array(_)) => "list",
                Some(serde_json::Value::Object(_)) => "object",
                _ => "value",
            }
        ),
    )
}

/// The value of an expression that is a JSON literal with no variable in it.
fn literal(e: &Expression) -> Option<serde_json::Value> {
    if !e.variables.is_empty() {
        return None;
    }
    serde_json::from_str(e.text.trim())
        .ok()
        .filter(|v: &serde_json::Value| !v.is_null())
}

fn fits(v: &serde_json::Value, ty: &FieldType) -> bool {
    use serde_json::Value as J;
    match (ty, v) {
        (FieldType::Json, _) => true,
        (FieldType::Int, J::Number(n)) => {
            n.is_i64() || n.as_f64().is_some_and(|f| f.fract() == 0.0)
        }
        (FieldType::Float, J::Number(_)) => true,
        (FieldType::String | FieldType::Timestamp, J::String(_)) => true,
        (FieldType::Bool, J::Bool(_)) => true,
        (FieldType::List(t), J::Array(items)) => items.iter().all(|i| fits(i, t)),
        _ => false,
    }
}

fn ty_name(t: &FieldType) -> String {
    match t {
        FieldType::Int => "int".into(),
        FieldType::Float => "f64".into(),
        FieldType::String => "string".into(),
        FieldType::Bool => "bool".into(),
        FieldType::Timestamp => "timestamp".into(),
        FieldType::Json => "json".into(),
        FieldType::List(t) => format!("[{}]", ty_name(t)),
    }
}

/// A diagnostic at `offset` of `text` (an element of an imported file: at the model's start).
pub fn located(
    text: &str,
    severity: Severity,
    code: &'static str,
    element: &str,
    offset: usize,
    message: String,
) -> Diagnostic {
    let offset = if offset <= text.len() && text.is_char_boundary(offset) {
        offset
    } else {
        0
    };
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before[before.rfind('\n').map_or(0, |n| n + 1)..]
        .chars()
        .count()
        + 1;
    Diagnostic {
        severity,
        code,
        category: Category::Execution,
        constraint: None,
        message,
        file: None,
        element: Some(element.to_owned()),
        field: None,
        offset,
        line,
        column,
    }
}
