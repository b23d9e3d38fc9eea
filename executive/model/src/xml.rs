//! Hostile-input-safe XML reading: bytes -> a namespace-resolved element tree with byte offsets.
//!
//! quick-xml does the tokenising; this module adds what a mission executive needs on top:
//! decoding (UTF-8, UTF-16 with BOM, Latin-1 declared), namespace resolution by URI (never by
//! prefix), and hard limits. A `<!DOCTYPE` is refused outright, so no external entity (XXE) is
//! ever opened and no entity-expansion bomb can be declared; only the five predefined entities
//! and character references are expanded. Size, depth, element and attribute counts are capped
//! so every input is read in bounded time and memory.

use quick_xml::events::attributes::Attribute;
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
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Ns {
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
    Unbound(String),
    /// Any other namespace URI (vendor extensions).
    Other(String),
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

impl Ns {
    fn from_uri(uri: &str) -> Ns {
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
            other => Ns::Other(other.to_owned()),
        }
    }
}

/// One attribute with its resolved namespace.
#[derive(Debug)]
pub(crate) struct Attr {
    pub(crate) ns: Ns,
    pub(crate) name: String,
    pub(crate) value: String,
}

/// One element: resolved name, attributes, direct text, children, and where its start tag begins.
#[derive(Debug)]
pub(crate) struct Element {
    pub(crate) ns: Ns,
    pub(crate) name: String,
    pub(crate) attrs: Vec<Attr>,
    pub(crate) text: String,
    pub(crate) children: Vec<Element>,
    /// Byte offset of the `<` of the start tag in the decoded text.
    pub(crate) offset: usize,
}

impl Element {
    /// Is this the BPMN-namespace element `name`?
    pub(crate) fn is_bpmn(&self, name: &str) -> bool {
        self.ns == Ns::Bpmn && self.name == name
    }

    /// Value of the un-namespaced attribute `name` (BPMN attributes are unqualified).
    pub(crate) fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|a| a.ns == Ns::None && a.name == name)
            .map(|a| a.value.as_str())
    }

    /// Value of the attribute `name` in namespace `ns`.
    pub(crate) fn attr_ns(&self, ns: &Ns, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|a| &a.ns == ns && a.name == name)
            .map(|a| a.value.as_str())
    }

    /// BPMN-namespace children named `name`.
    pub(crate) fn bpmn_children<'a>(
        &'a self,
        name: &'a str,
    ) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.is_bpmn(name))
    }

    /// First BPMN-namespace child named `name`.
    pub(crate) fn bpmn_child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.is_bpmn(name))
    }

    /// The children of `<bpmn:extensionElements>`, if any.
    pub(crate) fn extensions(&self) -> impl Iterator<Item = &Element> {
        self.bpmn_children("extensionElements")
            .flat_map(|e| e.children.iter())
    }

    /// Trimmed direct text.
    pub(crate) fn trimmed_text(&self) -> &str {
        self.text.trim()
    }
}

/// A parsed document: the decoded text and its root element.
#[derive(Debug)]
pub(crate) struct Document {
    pub(crate) root: Element,
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
pub(crate) fn decode(
    bytes: &[u8],
    warnings: &mut Vec<(usize, String)>,
) -> Result<String, XmlError> {
    if let Some(rest) = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]) {
        return decode_utf8(rest);
    }
    let utf16 = |le: bool, rest: &[u8]| -> Result<String, XmlError> {
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
                return Ok(text.to_owned());
            }
            warnings.push((0, format!("declared encoding {enc} decoded as Latin-1")));
            Ok(bytes.iter().map(|&b| char::from(b)).collect())
        }
        Some(other) => Err(err(
            0,
            format!("unsupported document encoding {other:?}; use UTF-8"),
        )),
    }
}

fn decode_utf8(bytes: &[u8]) -> Result<String, XmlError> {
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok(s.to_owned()),
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
struct Scope {
    bindings: Vec<(String, Ns)>,
    /// How many bindings each open element pushed.
    pushed: Vec<usize>,
}

impl Scope {
    fn resolve(&self, prefix: &str) -> Option<&Ns> {
        self.bindings
            .iter()
            .rev()
            .find(|(p, _)| p == prefix)
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

/// Parses decoded text into a [`Document`], enforcing `limits`.
/// Offsets are `base` plus the position in `text`, so several documents of a bundle share one
/// offset space.
pub(crate) fn parse(
    text: &str,
    base: usize,
    limits: &Limits,
    mut warnings: Vec<(usize, String)>,
) -> Result<Document, XmlError> {
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
        bindings: vec![("xml".to_owned(), Ns::Xml), (String::new(), Ns::None)],
        pushed: Vec::new(),
    };
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    let mut elements = 0usize;
    loop {
        let offset = base + reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            err(
                base + reader.error_position() as usize,
                format!("malformed XML: {e}"),
            )
        })?;
        match event {
            Event::Start(start) | Event::Empty(start) if root.is_some() => {
                let _ = start;
                return Err(err(offset, "content after the root element"));
            }
            Event::Start(start) => {
                elements += 1;
                if elements > limits.max_elements {
                    return Err(err(
                        offset,
                        format!("more than {} elements", limits.max_elements),
                    ));
                }
                if stack.len() >= limits.max_depth {
                    return Err(err(
                        offset,
                        format!("elements nested deeper than {}", limits.max_depth),
                    ));
                }
                let element = open(&start, offset, &mut scope, limits, &mut warnings)?;
                stack.push(element);
            }
            Event::Empty(start) => {
                elements += 1;
                if elements > limits.max_elements {
                    return Err(err(
                        offset,
                        format!("more than {} elements", limits.max_elements),
                    ));
                }
                let element = open(&start, offset, &mut scope, limits, &mut warnings)?;
                close_scope(&mut scope);
                attach(&mut stack, &mut root, element);
            }
            Event::End(_) => {
                close_scope(&mut scope);
                let element = stack
                    .pop()
                    .ok_or_else(|| err(offset, "unexpected end tag"))?;
                attach(&mut stack, &mut root, element);
            }
            Event::Text(t) => {
                let content = t.xml10_content();
                match stack.last_mut() {
                    Some(top) => top.text.push_str(&content),
                    None if content.trim().is_empty() => {}
                    None => return Err(err(offset, "text outside the root element")),
                }
            }
            Event::CData(c) => {
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&c.xml10_content());
                }
            }
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
                if let Some(top) = stack.last_mut() {
                    top.text.push(ch);
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
    if let Some(open) = stack.last() {
        return Err(err(
            base + text.len(),
            format!("document ends inside <{}>", open.name),
        ));
    }
    let root = root.ok_or_else(|| err(base, "no root element: this is not an XML document"))?;
    Ok(Document { root, warnings })
}

fn attach(stack: &mut [Element], root: &mut Option<Element>, element: Element) {
    match stack.last_mut() {
        Some(parent) => parent.children.push(element),
        None => *root = Some(element),
    }
}

fn close_scope(scope: &mut Scope) {
    let n = scope.pushed.pop().unwrap_or(0);
    let keep = scope.bindings.len().saturating_sub(n);
    scope.bindings.truncate(keep);
}

fn split_qname(raw: &str) -> (&str, &str) {
    match raw.split_once(':') {
        Some((p, l)) => (p, l),
        None => ("", raw),
    }
}

fn open(
    start: &BytesStart<'_>,
    offset: usize,
    scope: &mut Scope,
    limits: &Limits,
    warnings: &mut Vec<(usize, String)>,
) -> Result<Element, XmlError> {
    let mut raw_attrs: Vec<(String, String)> = Vec::new();
    for attr in start.attributes().with_checks(true) {
        let attr: Attribute<'_> =
            attr.map_err(|e| err(offset, format!("malformed attribute: {e}")))?;
        if raw_attrs.len() >= limits.max_attributes {
            return Err(err(
                offset,
                format!("element has more than {} attributes", limits.max_attributes),
            ));
        }
        let key: &str = attr.key.as_ref();
        let key = key.to_owned();
        let value = attr
            .normalized_value(quick_xml::XmlVersion::Implicit1_0)
            .map_err(|e| err(offset, format!("attribute {key}: {e}")))?
            .into_owned();
        raw_attrs.push((key, value));
    }
    let mut pushed = 0;
    for (key, value) in &raw_attrs {
        let prefix = if key == "xmlns" {
            Some(String::new())
        } else {
            key.strip_prefix("xmlns:").map(str::to_owned)
        };
        if let Some(prefix) = prefix {
            scope.bindings.push((prefix, Ns::from_uri(value)));
            pushed += 1;
        }
    }
    scope.pushed.push(pushed);
    let qname = start.name();
    let raw_name: &str = qname.as_ref();
    let raw_name = raw_name.to_owned();
    let (prefix, local) = split_qname(&raw_name);
    let ns = match scope.resolve(prefix) {
        Some(ns) => ns.clone(),
        None => {
            warnings.push((
                offset,
                format!("prefix {prefix:?} of <{raw_name}> is not declared"),
            ));
            Ns::Unbound(prefix.to_owned())
        }
    };
    let mut attrs = Vec::with_capacity(raw_attrs.len());
    for (key, value) in raw_attrs {
        if key == "xmlns" || key.starts_with("xmlns:") {
            continue;
        }
        let (prefix, local) = split_qname(&key);
        let ns = if prefix.is_empty() {
            Ns::None
        } else {
            scope
                .resolve(prefix)
                .cloned()
                .unwrap_or_else(|| Ns::Unbound(prefix.to_owned()))
        };
        attrs.push(Attr {
            ns,
            name: local.to_owned(),
            value,
        });
    }
    Ok(Element {
        ns,
        name: local.to_owned(),
        attrs,
        text: String::new(),
        children: Vec::new(),
        offset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Document, XmlError> {
        parse(text, 0, &Limits::default(), Vec::new())
    }

    #[test]
    fn resolves_namespaces_by_uri_not_prefix() {
        let doc = read(&format!(
            r#"<foo:definitions xmlns:foo="{BPMN_NS}"><process xmlns="{BPMN_NS}" id="p"/></foo:definitions>"#
        ))
        .unwrap();
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
