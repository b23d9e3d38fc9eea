//! Hostile-input-safe XML reading: bytes -> a namespace-resolved element tree with byte offsets.
//!
//! The tree borrows from the decoded text: names always, attribute values and text wherever
//! they need no normalising (no entity, no line-end or white-space rewrite), which is nearly
//! always. Its nodes, attribute and child lists (and the rare normalised strings) live in one
//! arena ([`Bump`]) the caller owns: reading makes no allocation per element, siblings lie side
//! by side for the walks that follow, and the whole tree is freed at once. Diagram
//! interchange (BPMN DI, DC and DI namespaces below the root) is read and checked like the rest
//! but not kept: nothing executes or checks the drawing, and in a drawn model it is about half
//! the elements.
//!
//! quick-xml does the tokenising; this module adds what a mission executive needs on top:
//! decoding (UTF-8, UTF-16 with BOM, Latin-1 declared), namespace resolution by URI (never by
//! prefix), and hard limits. A `<!DOCTYPE` is refused outright, so no external entity (XXE) is
//! ever opened and no entity-expansion bomb can be declared; only the five predefined entities
//! and character references are expanded. Size, depth, element and attribute counts are capped
//! so every input is read in bounded time and memory.

use std::borrow::Cow;
use std::cell::Cell;

use bumpalo::Bump;
use quick_xml::events::attributes::{Attribute, Attributes};
use quick_xml::events::{BytesStart, Event};
use quick_xml::reader::Reader;

/// Hard limits on what the reader accepts.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Largest accepted input, in bytes.
    pub max_bytes: usize,
    /// Deepest element nesting.
    pub max_depth: usize,
    /// Most elements in one document.
    pub max_elements: usize,
    /// Most attributes on one element.
    pub max_attributes: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_bytes: 64 << 20,
            max_depth: 200,
            max_elements: 2_000_000,
            max_attributes: 512,
        }
    }
}

/// The namespaces the loader understands, resolved by URI.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ns<'a> {
    Bpmn,
    BpmnDi,
    Dc,
    Di,
    Camunda,
    Zeebe,
    Spiff,
    Trace,
    Xsi,
    Xml,
    /// No namespace (an unprefixed attribute, or an element with no default namespace).
    None,
    /// A prefix that no `xmlns:` declaration binds.
    Unbound(&'a str),
    /// Any other namespace URI (vendor extensions).
    Other(&'a str),
}

/// URI of the BPMN 2.0 model namespace.
pub const BPMN_NS: &str = "http://www.omg.org/spec/BPMN/20100524/MODEL";
/// URI of the project's own extension namespace (task bindings, forms).
pub const TRACE_NS: &str = "urn:trace:bpmn:1.0";
/// URI of the Camunda 8 (Zeebe) extension namespace.
pub const ZEEBE_NS: &str = "http://camunda.org/schema/zeebe/1.0";
/// URI of the Camunda 7 extension namespace.
pub const CAMUNDA_NS: &str = "http://camunda.org/schema/1.0/bpmn";
/// URI of SpiffWorkflow's extension namespace.
pub const SPIFF_NS: &str = "http://spiffworkflow.org/bpmn/schema/1.0/core";

impl<'a> Ns<'a> {
    fn from_uri(uri: &'a str) -> Ns<'a> {
        match uri {
            BPMN_NS => Ns::Bpmn,
            "http://www.omg.org/spec/BPMN/20100524/DI" => Ns::BpmnDi,
            "http://www.omg.org/spec/DD/20100524/DC" => Ns::Dc,
            "http://www.omg.org/spec/DD/20100524/DI" => Ns::Di,
            CAMUNDA_NS => Ns::Camunda,
            ZEEBE_NS => Ns::Zeebe,
            SPIFF_NS => Ns::Spiff,
            TRACE_NS => Ns::Trace,
            "http://www.w3.org/2001/XMLSchema-instance" => Ns::Xsi,
            "http://www.w3.org/XML/1998/namespace" => Ns::Xml,
            "" => Ns::None,
            _ => Ns::Other(uri),
        }
    }
}

/// One attribute with its resolved namespace.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Attr<'a> {
    pub(crate) ns: Ns<'a>,
    pub(crate) name: &'a str,
    pub(crate) value: &'a str,
}

/// One element: resolved name, attributes, direct text, children, and where its start tag begins.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Element<'a> {
    pub(crate) ns: Ns<'a>,
    pub(crate) name: &'a str,
    pub(crate) attrs: &'a [Attr<'a>],
    /// Direct text; white space between child elements is kept only where it is all there is.
    pub(crate) text: &'a str,
    pub(crate) children: &'a [Element<'a>],
    /// Byte offset of the `<` of the start tag in the decoded text.
    pub(crate) offset: usize,
}

impl<'a> Element<'a> {
    /// Is this the BPMN-namespace element `name`?
    pub(crate) fn is_bpmn(&self, name: &str) -> bool {
        self.ns == Ns::Bpmn && self.name == name
    }

    /// Value of the un-namespaced attribute `name` (BPMN attributes are unqualified).
    pub(crate) fn attr(&self, name: &str) -> Option<&'a str> {
        self.attrs
            .iter()
            .find(|a| a.ns == Ns::None && a.name == name)
            .map(|a| a.value)
    }

    /// Value of the attribute `name` in namespace `ns`.
    pub(crate) fn attr_ns(&self, ns: &Ns<'_>, name: &str) -> Option<&'a str> {
        self.attrs
            .iter()
            .find(|a| &a.ns == ns && a.name == name)
            .map(|a| a.value)
    }

    /// BPMN-namespace children named `name`.
    pub(crate) fn bpmn_children<'s>(
        &'s self,
        name: &'s str,
    ) -> impl Iterator<Item = &'a Element<'a>> + 's {
        self.children.iter().filter(move |c| c.is_bpmn(name))
    }

    /// First BPMN-namespace child named `name`.
    pub(crate) fn bpmn_child(&self, name: &str) -> Option<&'a Element<'a>> {
        self.children.iter().find(|c| c.is_bpmn(name))
    }

    /// The children of `<bpmn:extensionElements>`, if any.
    pub(crate) fn extensions(&self) -> impl Iterator<Item = &'a Element<'a>> + '_ {
        self.bpmn_children("extensionElements")
            .flat_map(|e| e.children.iter())
    }

    /// Trimmed direct text.
    pub(crate) fn trimmed_text(&self) -> &'a str {
        self.text.trim()
    }
}

/// A parsed document: the decoded text and its root element.
#[derive(Debug)]
pub(crate) struct Document<'a> {
    pub(crate) root: Element<'a>,
    /// How many kept elements carry an `id` (to size the id maps once).
    pub(crate) ids: usize,
    /// Problems that did not stop reading (declared encoding ignored, unbound prefixes).
    pub(crate) warnings: Vec<(usize, String)>,
}

/// Why a document could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlError {
    /// Byte offset in the decoded text where the problem was found.
    pub offset: usize,
    /// What is wrong, in a plain sentence.
    pub message: String,
}

fn err(offset: usize, message: impl Into<String>) -> XmlError {
    XmlError {
        offset,
        message: message.into(),
    }
}

/// Decodes input bytes to text: UTF-8 (BOM stripped), UTF-16 with a BOM, or Latin-1 where the
/// XML declaration says so. Anything else is refused with the offset of the first bad byte.
/// UTF-8 input, nearly all of it, is borrowed, not copied.
pub(crate) fn decode<'b>(
    bytes: &'b [u8],
    warnings: &mut Vec<(usize, String)>,
) -> Result<Cow<'b, str>, XmlError> {
    if let Some(rest) = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]) {
        return decode_utf8(rest);
    }
    let utf16 = |le: bool, rest: &[u8]| -> Result<Cow<'b, str>, XmlError> {
        if !rest.len().is_multiple_of(2) {
            return Err(err(rest.len(), "UTF-16 input has an odd number of bytes"));
        }
        let units = rest.chunks_exact(2).map(|c| {
            if le {
                u16::from_le_bytes([c[0], c[1]])
            } else {
                u16::from_be_bytes([c[0], c[1]])
            }
        });
        char::decode_utf16(units)
            .collect::<Result<String, _>>()
            .map(Cow::Owned)
            .map_err(|_| err(0, "input is not valid UTF-16"))
    };
    if let Some(rest) = bytes.strip_prefix(&[0xFF, 0xFE]) {
        return utf16(true, rest);
    }
    if let Some(rest) = bytes.strip_prefix(&[0xFE, 0xFF]) {
        return utf16(false, rest);
    }
    let declared = declared_encoding(bytes).map(|e| e.to_ascii_lowercase());
    match declared.as_deref() {
        None | Some("utf-8") | Some("utf8") => decode_utf8(bytes),
        Some(
            enc @ ("iso-8859-1" | "latin1" | "windows-1252" | "cp1252" | "us-ascii" | "ascii"),
        ) => {
            if let Ok(text) = std::str::from_utf8(bytes) {
                if !text.is_ascii() {
                    warnings.push((
                        0,
                        format!("declared encoding {enc} is read as UTF-8, which the content is"),
                    ));
                }
                return Ok(Cow::Borrowed(text));
            }
            warnings.push((0, format!("declared encoding {enc} decoded as Latin-1")));
            Ok(Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()))
        }
        Some(other) => Err(err(
            0,
            format!("unsupported document encoding {other:?}; use UTF-8"),
        )),
    }
}

fn decode_utf8(bytes: &[u8]) -> Result<Cow<'_, str>, XmlError> {
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok(Cow::Borrowed(s)),
        Err(e) => Err(err(
            e.valid_up_to(),
            format!(
                "input is not UTF-8 (bad byte at offset {})",
                e.valid_up_to()
            ),
        )),
    }
}

/// Reads `encoding="…"` from an XML declaration at the very start of the input, if any.
fn declared_encoding(bytes: &[u8]) -> Option<&str> {
    let head = &bytes[..bytes.len().min(200)];
    if !head.starts_with(b"<?xml") {
        return None;
    }
    let end = head.windows(2).position(|w| w == b"?>")?;
    let decl = std::str::from_utf8(&head[..end]).ok()?;
    let at = decl.find("encoding")?;
    let rest = decl[at + "encoding".len()..]
        .trim_start()
        .strip_prefix('=')?
        .trim_start();
    let quote = rest.chars().next()?;
    if quote != '"' && quote != '\'' {
        return None;
    }
    let rest = &rest[1..];
    Some(&rest[..rest.find(quote)?])
}

/// Namespace bindings in force: (prefix, namespace) pairs, innermost last.
struct Scope<'a> {
    bindings: Vec<(&'a str, Ns<'a>)>,
    /// How many bindings each open element pushed.
    pushed: Vec<usize>,
}

impl<'a> Scope<'a> {
    fn resolve(&self, prefix: &str) -> Option<&Ns<'a>> {
        self.bindings
            .iter()
            .rev()
            .find(|(p, _)| *p == prefix)
            .map(|(_, ns)| ns)
    }
}

/// Does a closing quote run straight into the next pseudo-attribute (`"1.0"encoding`)?
fn attributes_run_together(decl: &str) -> bool {
    let mut quote = None;
    let mut closed = false;
    for c in decl.chars() {
        if closed && c.is_alphanumeric() {
            return true;
        }
        closed = false;
        match quote {
            Some(q) if c == q => {
                quote = None;
                closed = true;
            }
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None => {}
        }
    }
    false
}

/// An element being read: its children so far are `pending[first..]`.
struct Open<'a> {
    element: Element<'a>,
    first: usize,
    text: Cow<'a, str>,
}

/// What [`parse`] keeps while reading.
struct Tree<'a> {
    bump: &'a Bump,
    /// Elements open, outermost first.
    open: Vec<Open<'a>>,
    /// Children of the open elements, read so far, in order.
    pending: Vec<Element<'a>>,
    /// Attributes of the element being opened.
    attrs: Vec<Attr<'a>>,
    root: Option<Element<'a>>,
    /// Depth inside a diagram-interchange subtree, which is read but not kept.
    hidden: usize,
    /// Kept elements with an `id`.
    ids: usize,
}

impl<'a> Tree<'a> {
    /// Is an element just opened kept (not part of the drawing below the root)?
    fn keeps(&self, element: &Element<'_>) -> bool {
        let drawing = matches!(element.ns, Ns::BpmnDi | Ns::Dc | Ns::Di);
        self.hidden == 0 && (self.open.is_empty() || !drawing)
    }

    /// A finished element joins its parent's children (or becomes the root).
    fn attach(&mut self, element: Element<'a>) {
        match self.open.is_empty() {
            false => self.pending.push(element),
            true => self.root = Some(element),
        }
    }

    /// Closes the innermost open element: its children and text move into the arena.
    fn close(&mut self) -> Option<Element<'a>> {
        let Open {
            mut element,
            first,
            text,
        } = self.open.pop()?;
        element.children = self.bump.alloc_slice_copy(&self.pending[first..]);
        self.pending.truncate(first);
        element.text = keep(self.bump, text);
        Some(element)
    }

    fn text(&mut self, piece: Cow<'a, str>) {
        if let Some(top) = self.open.last_mut() {
            append(&mut top.text, piece);
        }
    }
}

/// Parses decoded text into a [`Document`] whose tree lives in `bump`, enforcing `limits`.
/// Offsets are `base` plus the position in `text`, so several documents of a bundle share one
/// offset space.
pub(crate) fn parse<'a>(
    text: &'a str,
    bump: &'a Bump,
    base: usize,
    limits: &Limits,
    warnings: Vec<(usize, String)>,
) -> Result<Document<'a>, XmlError> {
    let mut tree = Tree {
        bump,
        open: Vec::new(),
        pending: recycle(PENDING.take()),
        attrs: Vec::new(),
        root: None,
        hidden: 0,
        ids: 0,
    };
    let read = read(text, &mut tree, base, limits, warnings);
    if tree.pending.capacity() <= KEEP_PENDING {
        PENDING.set(recycle(tree.pending));
    }
    read
}

/// The most siblings' room [`PENDING`] keeps between loads (about 8 MB).
const KEEP_PENDING: usize = 100_000;

thread_local! {
    /// The children buffer of this thread's last parse, emptied: a large model's siblings need
    /// megabytes, which a new buffer would fault in afresh on every load.
    static PENDING: Cell<Vec<Element<'static>>> = const { Cell::new(Vec::new()) };
}

/// `v`, emptied, as a vector of `U`: on the same allocation where `T` and `U` have one layout
/// (std collects in place then), as here, where they differ only in what they borrow from.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().filter_map(|_| None).collect()
}

/// Reads `text` into `tree` (see [`parse`]).
fn read<'a>(
    text: &'a str,
    tree: &mut Tree<'a>,
    base: usize,
    limits: &Limits,
    mut warnings: Vec<(usize, String)>,
) -> Result<Document<'a>, XmlError> {
    if text.len() > limits.max_bytes {
        return Err(err(
            base,
            format!(
                "document is {} bytes; the limit is {}",
                text.len(),
                limits.max_bytes
            ),
        ));
    }
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut scope = Scope {
        bindings: vec![("xml", Ns::Xml), ("", Ns::None)],
        pushed: Vec::new(),
    };
    let mut elements = 0usize;
    loop {
        let offset = base + reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            err(
                base + reader.error_position() as usize,
                format!("malformed XML: {e}"),
            )
        })?;
        // `<a/>` is read as `<a>` closed at once.
        let (event, empty) = match event {
            Event::Empty(start) => (Event::Start(start), true),
            event => (event, false),
        };
        match event {
            Event::Start(_) if tree.root.is_some() => {
                return Err(err(offset, "content after the root element"));
            }
            Event::Start(start) | Event::Empty(start) => {
                elements += 1;
                if elements > limits.max_elements {
                    return Err(err(
                        offset,
                        format!("more than {} elements", limits.max_elements),
                    ));
                }
                if !empty && tree.open.len() + tree.hidden >= limits.max_depth {
                    return Err(err(
                        offset,
                        format!("elements nested deeper than {}", limits.max_depth),
                    ));
                }
                let element = open(
                    text,
                    &start,
                    offset,
                    &mut scope,
                    limits,
                    tree,
                    &mut warnings,
                )?;
                let kept = tree.keeps(&element);
                tree.ids += usize::from(kept && element.attr("id").is_some());
                if empty {
                    close_scope(&mut scope);
                    if kept {
                        tree.attach(element);
                    }
                } else if kept {
                    tree.open.push(Open {
                        element,
                        first: tree.pending.len(),
                        text: Cow::Borrowed(""),
                    });
                } else {
                    tree.hidden += 1;
                }
            }
            Event::End(_) => {
                close_scope(&mut scope);
                if tree.hidden > 0 {
                    tree.hidden -= 1;
                    continue;
                }
                let element = tree
                    .close()
                    .ok_or_else(|| err(offset, "unexpected end tag"))?;
                tree.attach(element);
            }
            Event::Text(_) | Event::CData(_) if tree.hidden > 0 => {}
            Event::Text(t) => {
                let content = t.xml10_content();
                if tree.open.is_empty() && !content.trim().is_empty() {
                    return Err(err(offset, "text outside the root element"));
                }
                tree.text(content);
            }
            Event::CData(c) => tree.text(c.xml10_content()),
            Event::GeneralRef(r) => {
                let ch = if r.is_char_ref() {
                    r.resolve_char_ref()
                        .ok()
                        .flatten()
                        .ok_or_else(|| err(offset, "invalid character reference"))?
                } else {
                    match &*r.xml10_content() {
                        "lt" => '<',
                        "gt" => '>',
                        "amp" => '&',
                        "apos" => '\'',
                        "quot" => '"',
                        name => {
                            return Err(err(
                                offset,
                                format!(
                                    "undefined entity &{name}; (only the five predefined XML entities are allowed)"
                                ),
                            ));
                        }
                    }
                };
                if tree.hidden == 0 {
                    tree.text(Cow::Owned(ch.to_string()));
                }
            }
            Event::DocType(_) => {
                return Err(err(
                    offset,
                    "DOCTYPE declarations are refused: a mission model needs no DTD, and DTDs carry \
                     external-entity (XXE) and entity-expansion attacks",
                ));
            }
            Event::Decl(_) => {
                // `<?xml version="1.0"encoding="UTF-8"?>`: pseudo-attributes must be separated by
                // white space (XML 1.0 §2.8). Read leniently, as bpmn-js does.
                let decl = text
                    .trim_start_matches('\u{feff}')
                    .strip_prefix("<?xml")
                    .and_then(|t| t.find("?>").map(|e| &t[..e]));
                if decl.is_some_and(attributes_run_together) {
                    warnings.push((
                        offset,
                        "the XML declaration is not well-formed (no space between its attributes); read leniently".to_owned(),
                    ));
                }
            }
            Event::PI(_) | Event::Comment(_) => {}
            Event::Eof => break,
        }
    }
    if let Some(open) = tree.open.last() {
        return Err(err(
            base + text.len(),
            format!("document ends inside <{}>", open.element.name),
        ));
    }
    let root = tree
        .root
        .take()
        .ok_or_else(|| err(base, "no root element: this is not an XML document"))?;
    Ok(Document {
        root,
        ids: tree.ids,
        warnings,
    })
}

/// A string of the tree: borrowed as it is, or copied into the arena.
fn keep<'a>(bump: &'a Bump, text: Cow<'a, str>) -> &'a str {
    match text {
        Cow::Borrowed(s) => s,
        Cow::Owned(s) => bump.alloc_str(&s),
    }
}

/// Adds a piece of text to an element's text, borrowing while it is the only piece. White
/// space meeting white space (the indentation between child elements) is not added: it would
/// copy every indented parent's text for nothing the model reads.
fn append<'a>(text: &mut Cow<'a, str>, piece: Cow<'a, str>) {
    let blank = |s: &str| s.bytes().all(|b| b.is_ascii_whitespace());
    if text.is_empty() {
        *text = piece;
    } else if !(blank(&piece) && blank(text)) {
        text.to_mut().push_str(&piece);
    }
}

fn close_scope(scope: &mut Scope<'_>) {
    let n = scope.pushed.pop().unwrap_or(0);
    let keep = scope.bindings.len().saturating_sub(n);
    scope.bindings.truncate(keep);
}

fn split_qname(raw: &str) -> (&str, &str) {
    // Names are short: a plain scan beats a searcher's set-up.
    match raw.bytes().position(|b| b == b':') {
        Some(at) => (&raw[..at], &raw[at + 1..]),
        None => ("", raw),
    }
}

/// `piece` as a slice of `text`, when it lies inside it (the reader borrows from the text, so
/// a tag always does).
fn within<'a>(text: &'a str, piece: &str) -> Option<&'a str> {
    let at = (piece.as_ptr() as usize).checked_sub(text.as_ptr() as usize)?;
    text.get(at..at + piece.len())
        .filter(|s| s.as_ptr() == piece.as_ptr())
}

fn open<'a>(
    text: &'a str,
    start: &BytesStart<'a>,
    offset: usize,
    scope: &mut Scope<'a>,
    limits: &Limits,
    tree: &mut Tree<'a>,
    warnings: &mut Vec<(usize, String)>,
) -> Result<Element<'a>, XmlError> {
    let tag = within(text, start)
        .ok_or_else(|| err(offset, "the tag could not be located in the document"))?;
    let name_len = start.name().as_ref().len();
    let raw_name = &tag[..name_len];
    let mut attributes = Attributes::new(tag, name_len);
    attributes.with_checks(true);
    let attrs = &mut tree.attrs;
    attrs.clear();
    let mut pushed = 0;
    for (count, attr) in attributes.enumerate() {
        let attr: Attribute<'a> =
            attr.map_err(|e| err(offset, format!("malformed attribute: {e}")))?;
        if count >= limits.max_attributes {
            return Err(err(
                offset,
                format!("element has more than {} attributes", limits.max_attributes),
            ));
        }
        let key = attr.key.0;
        let value = attr
            .normalized_value(quick_xml::XmlVersion::Implicit1_0)
            .map_err(|e| err(offset, format!("attribute {key}: {e}")))?;
        let value = keep(tree.bump, value);
        let prefix = if key == "xmlns" {
            Some("")
        } else {
            key.strip_prefix("xmlns:")
        };
        match prefix {
            Some(prefix) => {
                scope.bindings.push((prefix, Ns::from_uri(value)));
                pushed += 1;
            }
            None => attrs.push(Attr {
                ns: Ns::None,
                name: key,
                value,
            }),
        }
    }
    scope.pushed.push(pushed);
    let (prefix, local) = split_qname(raw_name);
    let ns = match scope.resolve(prefix) {
        Some(ns) => *ns,
        None => {
            warnings.push((
                offset,
                format!("prefix {prefix:?} of <{raw_name}> is not declared"),
            ));
            Ns::Unbound(prefix)
        }
    };
    for attr in attrs.iter_mut() {
        let (prefix, local) = split_qname(attr.name);
        if !prefix.is_empty() {
            attr.ns = scope
                .resolve(prefix)
                .copied()
                .unwrap_or(Ns::Unbound(prefix));
            attr.name = local;
        }
    }
    Ok(Element {
        ns,
        name: local,
        attrs: tree.bump.alloc_slice_copy(attrs),
        text: "",
        children: &[],
        offset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Document<'_>, XmlError> {
        // Each test's tree lives as long as the test.
        let bump = Box::leak(Box::new(Bump::new()));
        parse(text, bump, 0, &Limits::default(), Vec::new())
    }

    #[test]
    fn reads_the_drawing_without_keeping_it() {
        let di = "http://www.omg.org/spec/BPMN/20100524/DI";
        let dc = "http://www.omg.org/spec/DD/20100524/DC";
        let model = |shape: &str| {
            format!(
                r#"<definitions xmlns="{BPMN_NS}" xmlns:di="{di}" xmlns:dc="{dc}"><process id="p"/><di:BPMNDiagram><di:BPMNPlane>{shape}</di:BPMNPlane></di:BPMNDiagram><message id="m"/></definitions>"#
            )
        };
        let text =
            model(r#"<di:BPMNShape bpmnElement="p">t &amp;<dc:Bounds x="1"/></di:BPMNShape>"#);
        let doc = read(&text).unwrap();
        let kept: Vec<&str> = doc.root.children.iter().map(|c| c.name).collect();
        assert_eq!(kept, ["process", "message"]);
        assert!(
            doc.root.text.is_empty(),
            "the drawing's text is not the parent's"
        );
        // Still read: well-formedness and entities inside the drawing are checked.
        for bad in [
            r#"<dc:Bounds x="1" x="2"/>"#,
            "<di:BPMNShape>&nope;</di:BPMNShape>",
            "<dc:Bounds>",
        ] {
            assert!(read(&model(bad)).is_err(), "{bad}");
        }
        // The root is kept whatever its namespace.
        assert_eq!(
            read(&format!(r#"<di:BPMNDiagram xmlns:di="{di}"/>"#))
                .unwrap()
                .root
                .name,
            "BPMNDiagram"
        );
    }

    #[test]
    fn keeps_the_children_buffer_between_parses() {
        let siblings = format!("<r>{}</r>", "<a/>".repeat(1000));
        let first = read(&siblings).unwrap();
        assert_eq!(first.root.children.len(), 1000);
        let kept = PENDING.take();
        assert!(
            kept.is_empty() && kept.capacity() >= 1000,
            "{}",
            kept.capacity()
        );
        PENDING.set(kept);
        // The next parse reads on the kept buffer and leaves nothing of the last tree in it.
        assert_eq!(read("<r><b/><c/></r>").unwrap().root.children.len(), 2);
        assert!(PENDING.take().capacity() >= 1000);
    }

    #[test]
    fn resolves_namespaces_by_uri_not_prefix() {
        let text = format!(
            r#"<foo:definitions xmlns:foo="{BPMN_NS}"><process xmlns="{BPMN_NS}" id="p"/></foo:definitions>"#
        );
        let doc = read(&text).unwrap();
        assert!(doc.root.is_bpmn("definitions"));
        assert!(doc.root.children[0].is_bpmn("process"));
        assert_eq!(doc.root.children[0].attr("id"), Some("p"));
    }

    #[test]
    fn refuses_doctype_and_unknown_entities() {
        let xxe = r#"<?xml version="1.0"?><!DOCTYPE d [<!ENTITY x SYSTEM "file:///etc/passwd">]><d>&x;</d>"#;
        assert!(read(xxe).unwrap_err().message.contains("DOCTYPE"));
        assert!(
            read("<d>&x;</d>")
                .unwrap_err()
                .message
                .contains("undefined entity")
        );
        assert_eq!(read("<d>&lt;&#65;</d>").unwrap().root.text, "<A");
    }

    #[test]
    fn borrows_what_needs_no_normalising_and_joins_text_pieces() {
        let text = "<p a=\"plain\" b=\"x &amp; y\" c=\"tab\tbed\">\n  <s>a &lt; b<![CDATA[ & c]]>\nd</s>\n  <t/>\n</p>";
        let doc = read(text).unwrap();
        let value = |name: &str| {
            doc.root
                .attrs
                .iter()
                .find(|a| a.name == name)
                .unwrap()
                .value
        };
        let borrowed = |s: &str| within(text, s).is_some();
        assert!(value("a") == "plain" && borrowed(value("a")));
        assert_eq!(value("b"), "x & y");
        assert_eq!(value("c"), "tab bed", "attribute-value normalisation");
        assert_eq!(doc.root.children[0].text, "a < b & c\nd");
        assert_eq!(doc.root.children[1].text, "");
        assert!(doc.root.trimmed_text().is_empty());
        assert!(borrowed(doc.root.text), "indentation is not copied");
    }

    #[test]
    fn enforces_depth_and_attribute_limits() {
        let deep = "<a>".repeat(300) + &"</a>".repeat(300);
        assert!(read(&deep).unwrap_err().message.contains("deeper"));
        let attrs: String = (0..600).map(|i| format!(" a{i}=\"1\"")).collect();
        assert!(
            read(&format!("<a{attrs}/>"))
                .unwrap_err()
                .message
                .contains("attributes")
        );
    }

    #[test]
    fn reports_where_malformed_xml_breaks() {
        let e = read("<a>\n<b></c></a>").unwrap_err();
        assert!(e.message.starts_with("malformed XML"), "{e:?}");
        assert!(e.offset >= 4, "{e:?}");
    }

    #[test]
    fn decodes_declared_latin1_and_refuses_garbage() {
        let mut w = Vec::new();
        let bytes = b"<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?><a>\xe9</a>";
        assert_eq!(decode(bytes, &mut w).unwrap().chars().last(), Some('>'));
        assert!(!w.is_empty());
        assert!(decode(b"\x89PNG\r\n\x1a\n\xff\xff", &mut Vec::new()).is_err());
    }
}
