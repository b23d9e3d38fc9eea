//! executive-model: BPMN 2.0 XML -> a validated, immutable [`ProcessGraph`]. No I/O.
//!
//! "Parse, don't validate": [`load`] returns a graph only when the model has no errors, so the
//! engine never sees an unchecked model. One run reports **every** problem, each with element
//! id, byte offset, line and column and a plain sentence ([`Diagnostic`]).
//!
//! Reading is hardened for input from outside: a DOCTYPE is refused (no XXE, no entity bombs),
//! and size, depth, element and attribute counts are capped ([`Limits`]), so hostile input is
//! rejected in bounded time and memory and never panics.
//!
//! Dependencies, chosen deliberately:
//! - `quick-xml`: a fast pull parser that borrows from the input; it does no entity expansion of
//!   its own beyond the predefined entities, which is what hardening needs.
//! - `chrono`: ISO 8601 dates and calendar-correct month arithmetic for timers.
//! - `cel`: the expression language (see [`Expression`]).
//! - `thiserror` / `serde`: typed errors and machine-readable diagnostics (`--json`).
//!
//! # Supported elements
//! Every element of BPMN 2.0 process modelling is read into the graph: start, end,
//! intermediate catch/throw and boundary events with none, message, signal, timer, conditional,
//! error, escalation, terminate, compensation, link, cancel and multiple definitions; exclusive,
//! inclusive, parallel, event-based and complex gateways; service, user, script, send, receive,
//! manual, business-rule and plain tasks; embedded, event, transaction and ad-hoc
//! sub-processes; call activities; standard loops and multi-instance; conditions and default
//! flows; data objects and properties; collaborations, lanes and message flows; global
//! messages, signals, errors and escalations. Task bindings are read from our own namespace
//! `urn:trace:bpmn:1.0` and from Camunda 8 and Camunda 7 extensions ([`binding`]).

pub mod binding;
mod build;
mod diagnostic;
mod expr;
mod graph;
pub mod timer;
mod validate;
mod xml;

pub use diagnostic::{Diagnostic, Severity};
pub use expr::{Expression, parse_assignments};
pub use graph::*;
pub use xml::{BPMN_NS, CAMUNDA_NS, Limits, TRACE_NS, XmlError, ZEEBE_NS};

use diagnostic::Sink;

/// The result of loading one model: the graph if it has no errors, and every diagnostic.
#[derive(Debug)]
pub struct Loaded {
    /// The validated graph; `None` when any diagnostic is an error.
    pub graph: Option<ProcessGraph>,
    /// Every problem found, errors and warnings, in source order.
    pub diagnostics: Vec<Diagnostic>,
    /// The decoded source text (for rendering diagnostics with source lines).
    pub text: String,
}

impl Loaded {
    /// The errors among the diagnostics.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Error)
    }

    /// Did reading stop at the XML level (malformed, hostile or not BPMN)?
    pub fn unreadable(&self) -> bool {
        self.diagnostics.iter().any(|d| matches!(d.code, "malformed-xml" | "not-bpmn"))
    }
}

/// Loads a mission model from its bytes with the default [`Limits`].
pub fn load(bytes: &[u8]) -> Loaded {
    load_with(bytes, &Limits::default())
}

/// Loads a mission model from its bytes with explicit limits.
pub fn load_with(bytes: &[u8], limits: &Limits) -> Loaded {
    let mut sink = Sink::default();
    let mut warnings = Vec::new();
    if bytes.len() > limits.max_bytes {
        sink.error("malformed-xml", 0, None, format!("the file is {} bytes; the limit is {}", bytes.len(), limits.max_bytes));
        return Loaded { graph: None, diagnostics: sink.finish(""), text: String::new() };
    }
    let text = match xml::decode(bytes, &mut warnings) {
        Ok(t) => t,
        Err(e) => {
            sink.error("malformed-xml", 0, None, e.message);
            return Loaded { graph: None, diagnostics: sink.finish(""), text: String::new() };
        }
    };
    let doc = match xml::parse(&text, limits, warnings) {
        Ok(d) => d,
        Err(e) => {
            sink.error("malformed-xml", e.offset, None, e.message);
            let diagnostics = sink.finish(&text);
            return Loaded { graph: None, diagnostics, text };
        }
    };
    for (offset, w) in &doc.warnings {
        sink.warning("xml", *offset, None, w.clone());
    }
    let graph = {
        let built = build::build(&doc, &mut sink);
        if let Some(g) = &built {
            validate::Checker { g, sink: &mut sink }.run();
            validate::element_checks(&doc.root, &mut sink);
        }
        built
    };
    let ok = !sink.has_errors();
    let diagnostics = sink.finish(&text);
    let graph = graph.filter(|_| ok).map(|mut g| {
        g.warnings = diagnostics.clone();
        g
    });
    Loaded { graph, diagnostics, text }
}
