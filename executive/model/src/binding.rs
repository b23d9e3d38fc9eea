//! Task bindings: how a task reaches a system (resource name, typed inputs and outputs).
//!
//! Four dialects are read into one [`TaskBinding`] (ours wins when a model carries several):
//! - ours, namespace `urn:trace:bpmn:1.0` (prefix `trace`):
//!   `<trace:task resource="excavation.excavate"><trace:input target="site_id" source="site.id" type="int"/>
//!   <trace:output source="achieved_depth_cm" target="depth_cm" type="f64"/></trace:task>`;
//! - Camunda 8: `zeebe:taskDefinition type=…` and `zeebe:ioMapping` (`zeebe:input` / `zeebe:output`);
//! - Camunda 7: `camunda:topic` / `camunda:class` / `camunda:delegateExpression` and
//!   `camunda:inputOutput` (`camunda:inputParameter` / `camunda:outputParameter`), and
//!   `camunda:in` / `camunda:out` on call activities, `camunda:connector` (its `connectorId`);
//! - SpiffWorkflow: `spiffworkflow:serviceTaskOperator` and its parameters,
//!   `spiffworkflow:calledDecisionId`.
//!
//! Inputs evaluate `source` (an expression over the instance's variables) into the goal field
//! `target` (a dotted path such as `selected_site.site_id`). Outputs evaluate `source` (an
//! expression over the result's fields) into the variable `target`.

use serde::Serialize;

use crate::diagnostic::Sink;
use crate::expr::{Expression, Failure, Language};
use crate::xml::{Element, Ns};

/// Which extension vocabulary a binding was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Dialect {
    /// The standard `implementation` attribute (resource name only).
    Bpmn,
    /// `urn:trace:bpmn:1.0`.
    Trace,
    /// Camunda 8 (`zeebe:`).
    Zeebe,
    /// Camunda 7 (`camunda:`).
    Camunda7,
    /// SpiffWorkflow (`spiffworkflow:`).
    Spiff,
}

/// A declared field type of a goal, result or form field.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldType {
    /// 64-bit signed integer (`int`).
    Int,
    /// 64-bit float (`f64`, `float`, `double`).
    Float,
    /// UTF-8 string.
    String,
    /// Boolean.
    Bool,
    /// RFC 3339 timestamp.
    Timestamp,
    /// A list of one element type (`[int]`).
    List(Box<FieldType>),
    /// Any JSON value.
    Json,
}

impl FieldType {
    /// Parses `int`, `f64`, `string`, `bool`, `timestamp`, `json` or `[T]`.
    pub fn parse(s: &str) -> Option<FieldType> {
        let s = s.trim();
        if let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            return FieldType::parse(inner).map(|t| FieldType::List(Box::new(t)));
        }
        Some(match s {
            "int" | "i64" | "integer" | "long" => FieldType::Int,
            "f64" | "float" | "double" | "number" => FieldType::Float,
            "string" | "str" => FieldType::String,
            "bool" | "boolean" => FieldType::Bool,
            "timestamp" => FieldType::Timestamp,
            "json" | "any" => FieldType::Json,
            _ => return None,
        })
    }
}

impl std::fmt::Display for FieldType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FieldType::Int => f.write_str("int"),
            FieldType::Float => f.write_str("f64"),
            FieldType::String => f.write_str("string"),
            FieldType::Bool => f.write_str("bool"),
            FieldType::Timestamp => f.write_str("timestamp"),
            FieldType::Json => f.write_str("json"),
            FieldType::List(t) => write!(f, "[{t}]"),
        }
    }
}

/// One input: `source` evaluated over the variables, written to the goal field `target`.
#[derive(Clone, Debug)]
pub struct InputMapping {
    /// Goal field path, e.g. `selected_site.site_id`.
    pub target: String,
    /// Expression over the instance's variables.
    pub source: Expression,
    /// Declared type, checked against the action catalogue and converted at run time.
    pub ty: Option<FieldType>,
}

/// One output: `source` evaluated over the result fields, written to the variable `target`.
#[derive(Clone, Debug)]
pub struct OutputMapping {
    /// Expression over the result (a field path such as `selected_site.site_id` is one).
    pub source: Expression,
    /// Variable name.
    pub target: String,
    /// Declared type (for user tasks, the form field type).
    pub ty: Option<FieldType>,
}

/// How a task reaches a system.
#[derive(Clone, Debug)]
pub struct TaskBinding {
    /// Vocabulary it was read from.
    pub dialect: Dialect,
    /// Resource name routed to a connector, e.g. `excavation.excavate` or `ground.approve_site`.
    pub resource: Option<String>,
    /// Inputs, in document order.
    pub inputs: Vec<InputMapping>,
    /// Outputs, in document order.
    pub outputs: Vec<OutputMapping>,
    /// Retries the connector may make before the failure reaches the model.
    pub retries: Option<u32>,
    /// Call activities: pass every variable in (`camunda:in variables="all"`).
    pub all_in: bool,
    /// Call activities: pass every variable out.
    pub all_out: bool,
}

impl TaskBinding {
    fn new(dialect: Dialect) -> TaskBinding {
        TaskBinding {
            dialect,
            resource: None,
            inputs: Vec::new(),
            outputs: Vec::new(),
            retries: None,
            all_in: false,
            all_out: false,
        }
    }
}

/// Context for reading one element's binding: where to report and how strictly.
pub(crate) struct Reader<'a> {
    pub(crate) sink: &'a mut Sink,
    pub(crate) element_id: &'a str,
    /// Executable processes get errors; descriptive ones get warnings.
    pub(crate) strict: bool,
}

impl Reader<'_> {
    fn problem(&mut self, offset: usize, code: &'static str, message: String) {
        if self.strict {
            self.sink
                .error(code, offset, Some(self.element_id), message);
        } else {
            self.sink
                .warning(code, offset, Some(self.element_id), message);
        }
    }

    fn expr(&mut self, offset: usize, raw: &str, what: &str) -> Option<Expression> {
        match Expression::compile(raw, &Language::Cel) {
            Ok(e) => Some(e),
            Err(f) => {
                self.problem(offset, f.code(), format!("{what}: {f}"));
                None
            }
        }
    }

    /// A literal string as an expression (Camunda's static values).
    fn literal(&mut self, offset: usize, value: &str, what: &str) -> Option<Expression> {
        let quoted = serde_json_string(value);
        self.expr(offset, &quoted, what)
    }

    fn ty(&mut self, el: &Element, ns: &Ns) -> Option<FieldType> {
        let raw = el.attr("type").or_else(|| el.attr_ns(ns, "type"))?;
        let t = FieldType::parse(raw);
        if t.is_none() {
            self.problem(el.offset, "bad-type", format!("unknown field type `{raw}` (use int, f64, string, bool, timestamp, json or [T])"));
        }
        t
    }

    /// Reads every binding on `el` (a task or call activity). `trace:task` wins; several other
    /// dialects on one element are refused, since which one wins would be a guess.
    pub(crate) fn read(&mut self, el: &Element) -> Option<TaskBinding> {
        self.foreign_scripts(el);
        // Our own binding is addressed to this executive: it wins over the other engines'
        // (a model may carry bindings for several engines).
        if let Some(b) = self.read_trace(el) {
            return Some(b);
        }
        let zeebe = self.read_zeebe(el);
        let camunda = self.read_camunda(el);
        let spiff = self.read_spiff(el);
        let found = usize::from(zeebe.is_some())
            + usize::from(camunda.is_some())
            + usize::from(spiff.is_some());
        if found > 1 {
            self.problem(el.offset, "conflicting-bindings", "the task carries bindings in more than one other engine's dialect (zeebe, camunda, spiffworkflow), and which one runs would be a guess; keep one, or add a trace:task".to_owned());
        }
        zeebe.or(camunda).or(spiff).or_else(|| implementation(el))
    }

    fn read_trace(&mut self, el: &Element) -> Option<TaskBinding> {
        let task = el
            .extensions()
            .find(|e| e.ns == Ns::Trace && e.name == "task")?;
        let mut b = TaskBinding::new(Dialect::Trace);
        b.resource = task.attr("resource").map(Into::into);
        if let Some(r) = task.attr("retries") {
            match r.parse() {
                Ok(n) => b.retries = Some(n),
                Err(_) => self.problem(
                    task.offset,
                    "bad-attribute",
                    format!("retries=\"{r}\" is not a whole number"),
                ),
            }
        }
        for child in task.children {
            if child.ns != Ns::Trace {
                continue;
            }
            let (target, source) = (child.attr("target"), child.attr("source"));
            match child.name {
                "input" | "output" => {
                    let (Some(target), Some(source)) = (target, source) else {
                        self.problem(
                            child.offset,
                            "bad-binding",
                            format!("trace:{} needs both source and target", child.name),
                        );
                        continue;
                    };
                    let ty = self.ty(child, &Ns::Trace);
                    let what = format!("trace:{} {target}", child.name);
                    let Some(source) = self.expr(child.offset, source, &what) else {
                        continue;
                    };
                    if child.name == "input" {
                        b.inputs.push(InputMapping {
                            target: target.to_owned(),
                            source,
                            ty,
                        });
                    } else {
                        b.outputs.push(OutputMapping {
                            source,
                            target: target.to_owned(),
                            ty,
                        });
                    }
                }
                other => self.problem(
                    child.offset,
                    "unknown-element",
                    format!("trace:{other} is not part of the trace vocabulary (input, output)"),
                ),
            }
        }
        Some(b)
    }

    fn read_zeebe(&mut self, el: &Element) -> Option<TaskBinding> {
        let zeebe: Vec<&Element> = el.extensions().filter(|e| e.ns == Ns::Zeebe).collect();
        if zeebe.is_empty() {
            return None;
        }
        let mut b = TaskBinding::new(Dialect::Zeebe);
        let mut relevant = false;
        for z in zeebe {
            match z.name {
                "taskDefinition" => {
                    relevant = true;
                    b.resource = self.constant(z, "type");
                    b.retries = self.constant(z, "retries").and_then(|r| r.parse().ok());
                }
                "ioMapping" => {
                    relevant = true;
                    for m in z.children.iter().filter(|m| m.ns == Ns::Zeebe) {
                        let Some(target) = m.attr("target").filter(|t| !t.trim().is_empty()) else {
                            self.problem(
                                m.offset,
                                "bad-binding",
                                format!("zeebe:{} needs a target", m.name),
                            );
                            continue;
                        };
                        let what = format!("zeebe:{} {target}", m.name);
                        // Zeebe: a value starting with `=` is FEEL, any other a static string;
                        // a mapping without a source sets its target to null.
                        let source = match m.attr("source").map(str::trim) {
                            None | Some("") => self.expr(m.offset, "null", &what),
                            Some(source) if source.starts_with('=') => {
                                self.expr(m.offset, source, &what)
                            }
                            Some(source) => self.literal(m.offset, source, &what),
                        };
                        let Some(source) = source else { continue };
                        match m.name {
                            "input" => b.inputs.push(InputMapping {
                                target: target.to_owned(),
                                source,
                                ty: None,
                            }),
                            "output" => b.outputs.push(OutputMapping {
                                source,
                                target: target.to_owned(),
                                ty: None,
                            }),
                            _ => {}
                        }
                    }
                }
                // A Camunda 8 business rule task calls a DMN decision: the decision is the
                // resource a connector serves, as `camunda:decisionRef` is for Camunda 7.
                "calledDecision" => {
                    relevant = true;
                    b.resource = self.constant(z, "decisionId");
                }
                // What a Camunda 8 user task says about people and dates: TRACE's ground
                // stations do not use it, but a FEEL error in it is still named.
                "assignmentDefinition" | "taskSchedule" => {
                    for a in z.attrs {
                        let (attr, value) = (&a.name, &a.value);
                        let Some(body) = value.trim().strip_prefix('=') else {
                            continue;
                        };
                        if let Err(p) = executive_feel::parse(body) {
                            self.sink.warning(
                                "bad-expression",
                                z.offset,
                                Some(self.element_id),
                                format!(
                                    "zeebe:{} {attr} (not used by TRACE): {} (FEEL, `{body}`)",
                                    z.name, p.message
                                ),
                            );
                        }
                    }
                }
                "calledElement" => {
                    relevant = true;
                    b.all_in = z.attr("propagateAllParentVariables") != Some("false");
                    b.all_out = z.attr("propagateAllChildVariables") != Some("false");
                }
                _ => {}
            }
        }
        relevant.then_some(b)
    }

    /// A Zeebe attribute that may be static text or FEEL (`type="=…"`): TRACE routes tasks when
    /// the mission loads, so an expression must be a constant.
    fn constant(&mut self, z: &Element, attr: &str) -> Option<String> {
        match crate::expr::constant_text(z.attr(attr)?) {
            Ok(v) => Some(v),
            Err(why) => {
                self.problem(
                    z.offset,
                    "bad-binding",
                    format!("zeebe:{} {attr}: {why}", z.name),
                );
                None
            }
        }
    }

    /// Behaviour another engine attaches to the task and TRACE would otherwise drop without a
    /// word: SpiffWorkflow's pre- and post-scripts (Python), whichever binding runs the task.
    fn foreign_scripts(&mut self, el: &Element) {
        for ext in el.extensions().filter(|e| {
            e.ns == Ns::Spiff
                && matches!(e.name, "preScript" | "postScript")
                && !e.trimmed_text().is_empty()
        }) {
            let when = if ext.name == "preScript" {
                "before"
            } else {
                "after"
            };
            self.problem(
                ext.offset,
                "unevaluated-language",
                format!("spiffworkflow:{} is a Python script SpiffWorkflow runs {when} the task, which TRACE does not run", ext.name),
            );
        }
    }

    /// SpiffWorkflow: a service task names its operator and parameters
    /// (`spiffworkflow:serviceTaskOperator id=… / parameters / parameter id value`, values in the
    /// process's expression language), a business rule task its decision
    /// (`spiffworkflow:calledDecisionId`).
    fn read_spiff(&mut self, el: &Element) -> Option<TaskBinding> {
        let mut b = TaskBinding::new(Dialect::Spiff);
        let mut relevant = false;
        for ext in el.extensions().filter(|e| e.ns == Ns::Spiff) {
            match ext.name {
                "serviceTaskOperator" => {
                    relevant = true;
                    b.resource = ext.attr("id").map(Into::into);
                    let params = ext
                        .children
                        .iter()
                        .filter(|c| c.name == "parameters")
                        .flat_map(|p| p.children.iter())
                        .filter(|p| p.ns == Ns::Spiff && p.name == "parameter");
                    for p in params {
                        let (Some(target), Some(value)) = (p.attr("id"), p.attr("value")) else {
                            self.problem(
                                p.offset,
                                "bad-binding",
                                "spiffworkflow:parameter needs id and value".to_owned(),
                            );
                            continue;
                        };
                        let what = format!("spiffworkflow:parameter {target}");
                        if let Some(source) = self.expr(p.offset, value, &what) {
                            b.inputs.push(InputMapping {
                                target: target.to_owned(),
                                source,
                                ty: None,
                            });
                        }
                    }
                }
                "calledDecisionId" => {
                    relevant = true;
                    b.resource = Some(ext.trimmed_text().into());
                }
                _ => {}
            }
        }
        relevant.then_some(b)
    }

    fn read_camunda(&mut self, el: &Element) -> Option<TaskBinding> {
        let mut b = TaskBinding::new(Dialect::Camunda7);
        let mut relevant = false;
        for attr in [
            "topic",
            "class",
            "delegateExpression",
            "expression",
            "decisionRef",
        ] {
            if let Some(v) = el.attr_ns(&Ns::Camunda, attr) {
                b.resource = Some(v.into());
                relevant = true;
                break;
            }
        }
        // A Camunda Connect connector (`camunda:connector`): its id is the resource a TRACE
        // connector serves, and its own inputOutput maps the goal.
        let connector = el
            .extensions()
            .find(|e| e.ns == Ns::Camunda && e.name == "connector");
        if let Some(id) = connector.and_then(|c| {
            c.children
                .iter()
                .find(|e| e.ns == Ns::Camunda && e.name == "connectorId")
        }) {
            b.resource = Some(id.trimmed_text().into());
            relevant = true;
        }
        let inner = connector
            .into_iter()
            .flat_map(|c| c.children.iter())
            .filter(|e| e.name == "inputOutput");
        for ext in el.extensions().filter(|e| e.ns == Ns::Camunda).chain(inner) {
            match ext.name {
                "inputOutput" => {
                    relevant = true;
                    for p in ext.children.iter().filter(|p| p.ns == Ns::Camunda) {
                        let Some(name) = p.attr("name") else {
                            self.problem(
                                p.offset,
                                "bad-binding",
                                format!("camunda:{} needs a name", p.name),
                            );
                            continue;
                        };
                        let what = format!("camunda:{} {name}", p.name);
                        let value =
                            if let Some(nested) = p.children.iter().find(|c| c.ns == Ns::Camunda) {
                                match camunda_value(nested) {
                                    Ok(cel) => self.expr(nested.offset, &cel, &what),
                                    Err(f) => {
                                        let code = match f {
                                            Failure::Syntax(_) => "unsupported",
                                            Failure::Unevaluated(_) => "unevaluated-language",
                                        };
                                        self.problem(nested.offset, code, format!("{what}: {f}"));
                                        continue;
                                    }
                                }
                            } else {
                                let raw = p.trimmed_text();
                                if raw.starts_with("${") || raw.starts_with("#{") {
                                    self.expr(p.offset, raw, &what)
                                } else {
                                    self.literal(p.offset, raw, &what)
                                }
                            };
                        let Some(value) = value else { continue };
                        match p.name {
                            "inputParameter" => b.inputs.push(InputMapping {
                                target: name.to_owned(),
                                source: value,
                                ty: None,
                            }),
                            "outputParameter" => b.outputs.push(OutputMapping {
                                source: value,
                                target: name.to_owned(),
                                ty: None,
                            }),
                            _ => {}
                        }
                    }
                }
                "in" | "out" => {
                    relevant = true;
                    let inbound = ext.name == "in";
                    if ext.attr("variables") == Some("all") {
                        if inbound {
                            b.all_in = true
                        } else {
                            b.all_out = true
                        }
                        continue;
                    }
                    let target = ext.attr("target");
                    let source = match (ext.attr("source"), ext.attr("sourceExpression")) {
                        (Some(s), None) => {
                            self.expr(ext.offset, s, &format!("camunda:{} source", ext.name))
                        }
                        (None, Some(s)) => self.expr(
                            ext.offset,
                            s,
                            &format!("camunda:{} sourceExpression", ext.name),
                        ),
                        _ => {
                            self.problem(ext.offset, "bad-binding", format!("camunda:{} needs exactly one of source, sourceExpression, or variables=\"all\"", ext.name));
                            continue;
                        }
                    };
                    let (Some(source), Some(target)) = (source, target) else {
                        if target.is_none() {
                            self.problem(
                                ext.offset,
                                "bad-binding",
                                format!("camunda:{} needs a target", ext.name),
                            );
                        }
                        continue;
                    };
                    if inbound {
                        b.inputs.push(InputMapping {
                            target: target.to_owned(),
                            source,
                            ty: None,
                        });
                    } else {
                        b.outputs.push(OutputMapping {
                            source,
                            target: target.to_owned(),
                            ty: None,
                        });
                    }
                }
                _ => {}
            }
        }
        relevant.then_some(b)
    }
}

/// `value` as a quoted string literal of the expression language.
fn serde_json_string(value: &str) -> String {
    let mut out = String::with_capacity(value.len() + 2);
    out.push('"');
    for c in value.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A Camunda 7 structured parameter value (`camunda:map`, `camunda:list`, nested, with literal
/// or `${…}` leaves) as CEL text; a `camunda:script` value is refused with its language, and
/// anything else that is not a value as unsupported (`Failure::Syntax`).
fn camunda_value(el: &Element) -> Result<String, Failure> {
    let leaf = |e: &Element| -> Result<String, Failure> {
        match e.children.iter().find(|c| c.ns == Ns::Camunda) {
            Some(nested) => camunda_value(nested),
            None => {
                let raw = e.trimmed_text();
                // Camunda 7 reads `${…}` / `#{…}` as JUEL and anything else as a literal.
                match crate::expr::wrapped(raw) {
                    Some((Language::Juel, _)) => {
                        Expression::compile(raw, &Language::Cel).map(|x| format!("({})", x.text))
                    }
                    _ => Ok(serde_json_string(raw)),
                }
            }
        }
    };
    match el.name {
        "map" => {
            let entries: Result<Vec<String>, Failure> = el
                .children
                .iter()
                .filter(|c| c.ns == Ns::Camunda && c.name == "entry")
                .map(|e| {
                    let key = e
                        .attr("key")
                        .ok_or_else(|| Failure::Syntax("a camunda:entry has no key".to_owned()))?;
                    Ok(format!("{}: {}", serde_json_string(key), leaf(e)?))
                })
                .collect();
            Ok(format!("{{{}}}", entries?.join(", ")))
        }
        "list" => {
            let values: Result<Vec<String>, Failure> = el
                .children
                .iter()
                .filter(|c| c.ns == Ns::Camunda)
                .map(|v| {
                    if v.name == "value" {
                        leaf(v)
                    } else {
                        camunda_value(v)
                    }
                })
                .collect();
            Ok(format!("[{}]", values?.join(", ")))
        }
        "script" => Err(Failure::Unevaluated(format!(
            "a camunda:script value (in {}) is not evaluated by TRACE; write the value as an expression",
            el.attr("scriptFormat").unwrap_or("an unnamed language")
        ))),
        other => Err(Failure::Syntax(format!(
            "camunda:{other} is not a parameter value"
        ))),
    }
}

/// Is the event `el` implemented like a task (a Camunda 8 job worker, a Camunda 7 delegate or
/// external task, our own binding)? Such a message throw or end event needs no message.
pub(crate) fn implemented_as_task(el: &Element) -> bool {
    let on = |e: &Element| {
        ["topic", "class", "delegateExpression", "expression"]
            .iter()
            .any(|a| e.attr_ns(&Ns::Camunda, a).is_some())
    };
    el.extensions().any(|e| {
        (e.ns == Ns::Zeebe && e.name == "taskDefinition") || (e.ns == Ns::Trace && e.name == "task")
    }) || on(el)
        || el.bpmn_child("messageEventDefinition").is_some_and(on)
}

/// The standard `implementation` attribute as the resource name, when no extension binds the
/// task: `implementation="excavation.excavate"`, or an engine-style `${environment.services.noop}`
/// (the `${…}` is removed). The BPMN defaults `##WebService` and `##unspecified` name nothing.
fn implementation(el: &Element) -> Option<TaskBinding> {
    let raw = el.attr("implementation")?.trim();
    if raw.starts_with("##") || raw.is_empty() {
        return None;
    }
    let name = raw
        .strip_prefix("${")
        .and_then(|r| r.strip_suffix('}'))
        .unwrap_or(raw)
        .trim();
    let mut b = TaskBinding::new(Dialect::Bpmn);
    b.resource = Some(name.into());
    Some(b)
}
