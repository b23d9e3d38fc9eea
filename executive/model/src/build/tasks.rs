//! Tasks: a task's binding (its resource and mappings in any dialect), an event's implied task,
//! and scripts in their language.

use super::*;

impl<'d> Builder<'d, '_> {
    /// A task (or global task, whose element name has lost its `global` prefix).
    pub(super) fn task(
        &mut self,
        el: &'d Element<'d>,
        name: &str,
        owner: &str,
        strict: bool,
    ) -> Task {
        let kind = match name {
            "serviceTask" => TaskKind::Service,
            "userTask" => TaskKind::User,
            "scriptTask" => TaskKind::Script,
            "sendTask" => TaskKind::Send,
            "receiveTask" => TaskKind::Receive,
            "manualTask" => TaskKind::Manual,
            "businessRuleTask" => TaskKind::BusinessRule,
            _ => TaskKind::Plain,
        };
        let binding = BindingReader {
            sink: self.sink,
            element_id: owner,
            strict,
        }
        .read(el);
        // A script task implemented by a job worker or an external task (a resource name) is
        // dispatched like a service task: it needs no script of its own.
        let worker = binding.as_ref().is_some_and(|b| b.resource.is_some())
            && el.bpmn_child("script").is_none();
        let script = (kind == TaskKind::Script && !worker)
            .then(|| self.script(el, owner, strict))
            .flatten();
        let message = matches!(kind, TaskKind::Send | TaskKind::Receive)
            .then(|| self.resolve(|b| &b.messages, el, "messageRef", owner))
            .flatten();
        Task {
            kind,
            binding,
            script,
            message,
            instantiate: el.attr("instantiate") == Some("true"),
            event: None,
        }
    }

    /// A message throw or end event implemented like a task (see [`Task::event`]).
    pub(super) fn event_task(&mut self, el: &'d Element<'d>, owner: &str, strict: bool) -> Task {
        let mut t = self.task(el, "sendTask", owner, strict);
        let def = el.bpmn_child("messageEventDefinition");
        if t.binding.is_none()
            && let Some(d) = def
        {
            // Camunda 7 puts the delegate on the event definition.
            t.binding = BindingReader {
                sink: self.sink,
                element_id: owner,
                strict,
            }
            .read(d);
        }
        t.message = def.and_then(|d| self.resolve(|b| &b.messages, d, "messageRef", owner));
        t.event = Some(if el.name == "endEvent" {
            "endEvent"
        } else {
            "intermediateThrowEvent"
        });
        t
    }

    pub(super) fn script(&mut self, el: &Element, owner: &str, strict: bool) -> Option<Script> {
        // Camunda 8 writes a script task as one FEEL expression and the variable it sets.
        if let Some(z) = el
            .extensions()
            .find(|e| e.ns == Ns::Zeebe && e.name == "script")
        {
            let (Some(expression), Some(result)) = (z.attr("expression"), z.attr("resultVariable"))
            else {
                self.problem(
                    strict,
                    "bad-binding",
                    z.offset,
                    Some(owner),
                    "zeebe:script needs expression and resultVariable".to_owned(),
                );
                return None;
            };
            return match Expression::compile(expression, &Language::Feel) {
                Ok(e) => Some(Script {
                    format: Some("feel".to_owned()),
                    text: format!("{result} = {expression}"),
                    assignments: Some(vec![(result.to_owned(), e)]),
                }),
                Err(f) => {
                    self.expr_problem(strict, z.offset, owner, "zeebe:script", f);
                    None
                }
            };
        }
        let Some(s) = el.bpmn_child("script") else {
            let msg = match el.attr_ns(&Ns::Camunda, "resource") {
                Some(r) => format!(
                    "the script is kept in an external resource `{r}` (camunda:resource), which TRACE does not read; put it in <script>"
                ),
                None => "script task has no <script>".to_owned(),
            };
            self.problem(strict, "missing-script", el.offset, Some(owner), msg);
            return None;
        };
        let format = el
            .attr("scriptFormat")
            .filter(|f| !f.trim().is_empty())
            .map(str::to_owned);
        let text = s.trimmed_text().to_owned();
        // A FEEL script (Camunda 7's `scriptFormat="feel"`) is one expression; its value goes to
        // `camunda:resultVariable`, or nowhere.
        if format
            .as_deref()
            .is_some_and(|f| Language::named(f) == Language::Feel)
        {
            let result = el.attr_ns(&Ns::Camunda, "resultVariable");
            return match Expression::compile(&text, &Language::Feel) {
                Ok(e) => Some(Script {
                    format,
                    assignments: Some(result.map(|r| (r.to_owned(), e)).into_iter().collect()),
                    text,
                }),
                Err(f) => {
                    self.expr_problem(strict, s.offset, owner, "FEEL script", f);
                    None
                }
            };
        }
        let ours = matches!(format.as_deref(), Some("cel" | "text/x-cel" | "trace"));
        let assignments = match parse_assignments(&text) {
            Ok(a) => {
                if format.is_none() {
                    self.sink.bent(
                        "missing-script-format",
                        "EXT.053",
                        el.offset,
                        Some(owner),
                        "the script task names no scriptFormat; its script is read as CEL assignments".to_owned(),
                    );
                }
                Some(a)
            }
            Err(e) if ours => {
                self.problem(
                    strict,
                    "bad-script",
                    s.offset,
                    Some(owner),
                    format!("script: {e}"),
                );
                None
            }
            Err(e) if format.is_none() && !self.script_connector => {
                self.sink.bent(
                    "missing-script-format",
                    "EXT.053",
                    el.offset,
                    Some(owner),
                    "the script task names no scriptFormat".to_owned(),
                );
                let msg = format!(
                    "the script names no language and is not CEL assignments ({e}): TRACE runs CEL assignments `name = expression`, and scripts in other languages through a script connector"
                );
                self.problem(strict, "unevaluated-language", s.offset, Some(owner), msg);
                None
            }
            // A script in another language runs through a script connector.
            Err(_) => None,
        };
        Some(Script {
            format,
            text,
            assignments,
        })
    }
}
