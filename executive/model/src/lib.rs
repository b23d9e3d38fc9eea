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
//! - `bumpalo`: the arena the XML element tree lives in while a model loads (no allocation per
//!   element, siblings side by side, freed at once).
//! - `foldhash`: the hasher of the id maps the checks look up for every reference; several
//!   times faster than std's SipHash on short ids, and seeded per process, so ids drawn to
//!   collide cannot be prepared in advance.
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

mod arena;
pub mod binding;
mod build;
mod constraints;
pub mod dataflow;
mod diagnostic;
mod expr;
mod graph;
mod juel;
pub mod timer;
mod validate;
mod xml;

#[cfg(test)]
mod dataflow_tests;
#[cfg(test)]
mod tests;

use std::borrow::Cow;

use bumpalo::Bump;

pub use diagnostic::{Category, Diagnostic, Severity};
pub use expr::{Expression, Failure, Language, Program, feel_to_cel, parse_assignments};
pub use graph::*;
pub use xml::{BPMN_NS, CAMUNDA_NS, Limits, SPIFF_NS, TRACE_NS, XmlError, ZEEBE_NS};

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
    /// Imported documents as (location, decoded text), for rendering their diagnostics.
    pub imports: Vec<(String, String)>,
}

impl Loaded {
    /// The errors among the diagnostics.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics
            .iter()
            .filter(|d| d.severity == Severity::Error)
    }

    /// Did reading stop at the XML level (malformed, hostile or not BPMN)?
    pub fn unreadable(&self) -> bool {
        self.diagnostics
            .iter()
            .any(|d| d.file.is_none() && matches!(d.code, "malformed-xml" | "not-bpmn"))
    }

    /// The text of the file a diagnostic points into.
    pub fn text_of(&self, d: &Diagnostic) -> &str {
        match &d.file {
            None => &self.text,
            Some(f) => self
                .imports
                .iter()
                .find(|(l, _)| l == f)
                .map_or("", |(_, t)| t.as_str()),
        }
    }
}

/// How to load a model.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// Hard limits on the input.
    pub limits: Limits,
    /// A script connector is present: scripts that are not written in the expression language
    /// (and carry no `scriptFormat`) are accepted and run by it instead of being refused.
    pub script_connector: bool,
    /// Token-game mode (simulation, teaching, model exploration): a model that reads as BPMN
    /// yields a graph even with errors (sketches without resource names, conditions, timer
    /// values, messages, …); the diagnostics are still reported. Never used to run a mission.
    pub token_game: bool,
    /// Strict reading (`trace validate --strict`): every rule of the specification is enforced,
    /// so the warnings that name a rule bent harmlessly (an implicit end, a condition the
    /// semantics ignore, a missing `scriptFormat`, …) become errors. For scoring static-constraint
    /// corpora; the executive itself reads liberally.
    pub strict: bool,
}

/// Loads a mission model with the default [`Options`]; imports cannot be resolved.
pub fn load(bytes: &[u8]) -> Loaded {
    load_with(bytes, &Options::default())
}

/// Loads a mission model with explicit options; imports cannot be resolved.
pub fn load_with(bytes: &[u8], options: &Options) -> Loaded {
    load_bundle(bytes, options, &mut |location: &str| {
        Err(format!("no import resolver was given for `{location}`"))
    })
}

/// Most documents one bundle may import (transitively).
const MAX_IMPORTS: usize = 64;

/// A decoded document of a bundle: the main model (borrowed from the input when it is UTF-8) or
/// an import.
struct Source<'b> {
    name: Option<String>,
    text: Cow<'b, str>,
    base: usize,
    /// Reads as BPMN (imported XSD and WSDL are only checked for well-formedness).
    bpmn: bool,
}

/// Loads a mission bundle: the model and the documents it imports (`<bpmn:import location=…>`),
/// which `resolve` reads (the caller decides where from; this crate does no I/O). Call
/// activities may call processes of imported BPMN documents.
///
/// The element trees borrow from the decoded texts, so the texts of every document are read
/// first: an import is parsed once when it is read (well-formedness, its own imports) and once
/// more, beside the others, to build the model. Models seldom import anything; the main model
/// is parsed once.
pub fn load_bundle(
    bytes: &[u8],
    options: &Options,
    resolve: &mut dyn FnMut(&str) -> Result<Vec<u8>, String>,
) -> Loaded {
    let limits = &options.limits;
    let mut sink = Sink::default();
    let main = decode_part(bytes, None, 0, limits, &mut sink).unwrap_or(Source {
        name: None,
        text: Cow::Borrowed(""),
        base: 0,
        bpmn: false,
    });
    // The element trees of the model and its imports.
    let bump = arena::take();
    let main_doc = match main.bpmn {
        true => parse_part(&main, &bump, limits, &mut sink),
        false => None,
    };
    // The imports each document declares, in the order the documents were read (none: nothing
    // queued, and nothing allocated).
    let mut declared: std::collections::VecDeque<Vec<Import>> = Default::default();
    let first = main_doc.as_ref().map(imports_of).unwrap_or_default();
    if !first.is_empty() {
        declared.push_back(first);
    }
    let mut sources: Vec<Source<'static>> = Vec::new();
    // Resolve imports breadth-first; each document gets its own offset range.
    let mut end = main.text.len() + 1;
    while sources.len() < MAX_IMPORTS
        && let Some(wanted) = declared.pop_front()
    {
        for (offset, location, bpmn) in wanted {
            if sources
                .iter()
                .any(|p| p.name.as_deref() == Some(location.as_str()))
            {
                continue;
            }
            let bytes = if location.contains("://") {
                Err("imports by URL are not fetched; put the file beside the model".to_owned())
            } else {
                resolve(&location)
            };
            let bytes = match bytes {
                Ok(b) => b,
                Err(why) => {
                    // What the model uses from it is checked where it is used (a called
                    // process, a referenced message); an import nothing uses is harmless.
                    sink.bent(
                        "unresolved-import",
                        "EXT.001",
                        offset,
                        None,
                        format!("import `{location}` cannot be resolved: {why}; elements referenced from it are reported where they are used"),
                    );
                    continue;
                }
            };
            let base = end;
            let decoded = decode_part(&bytes, Some(location.clone()), base, limits, &mut sink)
                .map(|s| Cow::<'static, str>::Owned(s.text.into_owned()));
            let readable = decoded.is_some();
            let text = decoded.unwrap_or_default();
            end = base + text.len() + 1;
            let mut source = Source {
                name: Some(location.clone()),
                text,
                base,
                bpmn,
            };
            // Well-formedness is checked here (XSD and WSDL too), and a BPMN document's own
            // imports are read; BPMN documents are parsed again below, beside the model.
            let parsed = match readable {
                true => parse_part(&source, &Bump::new(), limits, &mut sink)
                    .map(|d| (d.root.is_bpmn("definitions"), imports_of(&d))),
                false => None,
            };
            let (definitions, nested) = match parsed {
                Some((definitions, nested)) => (Some(definitions), nested),
                None => (None, Vec::new()),
            };
            match definitions {
                None => {
                    sink.error(
                        "broken-import",
                        offset,
                        None,
                        format!("imported file `{location}` is not well-formed XML"),
                    );
                    source.bpmn = false;
                }
                Some(false) if bpmn => {
                    sink.error(
                        "broken-import",
                        offset,
                        None,
                        format!("imported file `{location}` is not a BPMN model"),
                    );
                }
                Some(_) => {}
            }
            if source.bpmn && !nested.is_empty() {
                declared.push_back(nested);
            }
            sources.push(source);
        }
    }
    let graph = match &main_doc {
        Some(main_doc) => {
            let imported: Vec<xml::Document<'_>> = sources
                .iter()
                .filter(|s| s.bpmn)
                .filter_map(|s| parse_part(s, &bump, limits, &mut sink))
                .collect();
            let docs: Vec<&xml::Document<'_>> =
                std::iter::once(main_doc).chain(&imported).collect();
            for d in &docs {
                for (offset, w) in &d.warnings {
                    sink.warning("xml", *offset, None, w.clone());
                }
            }
            let built = build::build(&docs, &mut sink, options);
            if let Some((g, ids)) = &built {
                validate::Checker::new(g, &mut sink).run();
                // One document's ids, each once, are what the checks index: the build's index
                // serves them.
                let shared = ids.as_ref().filter(|_| docs.len() == 1);
                for d in &docs {
                    constraints::check(d, shared, &mut sink);
                }
            }
            built.map(|(g, _)| g)
        }
        None => None,
    };
    drop(main_doc);
    arena::give_back(bump);
    if options.strict {
        sink.enforce_rules();
    } else {
        sink.drop_pedantic();
    }
    let ok = options.token_game || !sink.has_errors();
    let texts: Vec<diagnostic::SourceText<'_>> = std::iter::once(&main)
        .chain(&sources)
        .map(|p| diagnostic::SourceText {
            name: p.name.as_deref(),
            text: &p.text,
            base: p.base,
        })
        .collect();
    let diagnostics = sink.finish(&texts);
    let graph = graph.filter(|_| ok).map(|mut g| {
        g.warnings = diagnostics.clone();
        g
    });
    let text = main.text.into_owned();
    let imports = sources
        .into_iter()
        .filter_map(|p| Some((p.name?, p.text.into_owned())))
        .collect();
    Loaded {
        graph,
        diagnostics,
        text,
        imports,
    }
}

/// An import a document declares: offset, location, whether it is BPMN.
type Import = (usize, String, bool);

/// The imports a document declares.
fn imports_of(doc: &xml::Document<'_>) -> Vec<Import> {
    doc.root
        .bpmn_children("import")
        .map(|i| {
            let location = i.attr("location").unwrap_or_default().to_owned();
            let bpmn = i.attr("importType") == Some(BPMN_NS) || location.ends_with(".bpmn");
            (i.offset, location, bpmn)
        })
        .collect()
}

/// Decodes one document; problems go to `sink`.
fn decode_part<'b>(
    bytes: &'b [u8],
    name: Option<String>,
    base: usize,
    limits: &Limits,
    sink: &mut Sink,
) -> Option<Source<'b>> {
    if bytes.len() > limits.max_bytes {
        sink.error(
            "malformed-xml",
            base,
            None,
            format!(
                "the file is {} bytes; the limit is {}",
                bytes.len(),
                limits.max_bytes
            ),
        );
        return None;
    }
    let mut warnings = Vec::new();
    match xml::decode(bytes, &mut warnings) {
        Ok(text) => {
            for (o, w) in warnings {
                sink.warning("xml", o + base, None, w);
            }
            Some(Source {
                name,
                text,
                base,
                bpmn: true,
            })
        }
        Err(e) => {
            sink.error("malformed-xml", base, None, e.message);
            None
        }
    }
}

/// Parses one decoded document; problems go to `sink`.
fn parse_part<'t>(
    source: &'t Source<'_>,
    bump: &'t Bump,
    limits: &Limits,
    sink: &mut Sink,
) -> Option<xml::Document<'t>> {
    match xml::parse(&source.text, bump, source.base, limits, Vec::new()) {
        Ok(doc) => Some(doc),
        Err(e) => {
            sink.error("malformed-xml", e.offset, None, e.message);
            None
        }
    }
}
