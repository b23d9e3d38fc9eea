//! Event definitions read: message, signal, timer, conditional, error, escalation, terminate,
//! cancel, compensation and link, each with its references resolved and its rules checked.

use super::*;

impl<'d> Builder<'d, '_> {
    pub(super) fn event_definitions(
        &mut self,
        el: &'d Element<'d>,
        owner: &str,
        strict: bool,
    ) -> Vec<EventDefinition> {
        let mut defs: Vec<&'d Element<'d>> = el
            .children
            .iter()
            .filter(|c| c.ns == Ns::Bpmn && c.name.ends_with("EventDefinition"))
            .collect();
        for r in el.bpmn_children("eventDefinitionRef") {
            let id = local_ref(r.text);
            // A reference to a definition the event already holds inline adds nothing.
            if defs.iter().any(|d| d.attr("id") == Some(id)) {
                continue;
            }
            match self.global_event_defs.get(id) {
                Some(d) => defs.push(d),
                None => {
                    self.sink.error(
                        "dangling-reference",
                        r.offset,
                        Some(owner),
                        format!("eventDefinitionRef `{}` does not exist", r.trimmed_text()),
                    );
                }
            }
        }
        let mut out = Vec::new();
        for d in defs {
            let def = match d.name {
                "messageEventDefinition" => {
                    EventDefinition::Message(self.resolve(|b| &b.messages, d, "messageRef", owner))
                }
                "signalEventDefinition" => {
                    EventDefinition::Signal(self.resolve(|b| &b.signals, d, "signalRef", owner))
                }
                "errorEventDefinition" => {
                    let var = |name: &str| {
                        d.attr_ns(&Ns::Trace, name)
                            .or_else(|| d.attr_ns(&Ns::Camunda, name))
                            .map(str::to_owned)
                    };
                    EventDefinition::Error {
                        error: self.resolve(|b| &b.errors, d, "errorRef", owner),
                        code_variable: var("errorCodeVariable"),
                        message_variable: var("errorMessageVariable"),
                    }
                }
                "escalationEventDefinition" => EventDefinition::Escalation(self.resolve(
                    |b| &b.escalations,
                    d,
                    "escalationRef",
                    owner,
                )),
                "terminateEventDefinition" => EventDefinition::Terminate,
                "cancelEventDefinition" => EventDefinition::Cancel,
                "compensateEventDefinition" => {
                    let activity =
                        d.attr("activityRef")
                            .and_then(|r| match self.node_ref(d.offset, r) {
                                Some(n) => Some(n),
                                None => {
                                    self.sink.error(
                                        "dangling-reference",
                                        d.offset,
                                        Some(owner),
                                        format!("activityRef `{r}` does not name an activity"),
                                    );
                                    None
                                }
                            });
                    EventDefinition::Compensate {
                        activity,
                        wait: d.attr("waitForCompletion") != Some("false"),
                    }
                }
                "linkEventDefinition" => {
                    // A throw may name its catch explicitly; then the pair shares the catch's name.
                    let target = d
                        .bpmn_child("target")
                        .and_then(|t| self.link_names.get(local_ref(t.text)).copied());
                    EventDefinition::Link(target.or(d.attr("name")).unwrap_or_default().to_owned())
                }
                // A condition that cannot be evaluated (empty, or in another language) is a
                // problem of its own; the event stays a conditional event, which never fires.
                "conditionalEventDefinition" => {
                    let e = match d.bpmn_child("condition") {
                        Some(c) => self.expr(strict, c, owner, "condition of conditional event"),
                        None => {
                            self.problem(
                                strict,
                                "missing-condition",
                                d.offset,
                                Some(owner),
                                "conditional event definition has no <condition>".to_owned(),
                            )
                            .constraint("XSD");
                            None
                        }
                    };
                    EventDefinition::Conditional(e.unwrap_or_else(Expression::never))
                }
                "timerEventDefinition" => {
                    let parts: Vec<(TimerKind, &Element)> = [
                        ("timeDate", TimerKind::Date),
                        ("timeDuration", TimerKind::Duration),
                        ("timeCycle", TimerKind::Cycle),
                    ]
                    .into_iter()
                    .filter_map(|(n, k)| d.bpmn_child(n).map(|c| (k, c)))
                    .collect();
                    let [(kind, value)] = parts[..] else {
                        let msg = format!(
                            "timer event definition needs exactly one of timeDate, timeDuration, timeCycle (found {})",
                            parts.len()
                        );
                        self.problem(strict, "bad-timer", d.offset, Some(owner), msg);
                        out.push(EventDefinition::Timer(crate::timer::Timer {
                            kind: TimerKind::Duration,
                            value: crate::timer::TimerValue::Unparsed(String::new()),
                        }));
                        continue;
                    };
                    match parse_timer(kind, value.trimmed_text()) {
                        Ok(t) => {
                            let text = value.trimmed_text();
                            if matches!(t.value, crate::timer::TimerValue::Expression(_))
                                && crate::expr::wrapped(text).is_none()
                            {
                                let rule = match kind {
                                    TimerKind::Date => "EXT.132",
                                    TimerKind::Cycle => "EXT.133",
                                    TimerKind::Duration => "EXT.134",
                                };
                                self.sink.bent(
                                    "timer-expression",
                                    rule,
                                    value.offset,
                                    Some(owner),
                                    format!("`{text}` is not ISO 8601; it is read as an expression whose value is (a variable holding the time)"),
                                );
                            }
                            EventDefinition::Timer(t)
                        }
                        Err(e) => {
                            self.problem(strict, "bad-timer", value.offset, Some(owner), e);
                            EventDefinition::Timer(crate::timer::Timer {
                                kind,
                                value: crate::timer::TimerValue::Unparsed(
                                    value.trimmed_text().to_owned(),
                                ),
                            })
                        }
                    }
                }
                other => {
                    self.problem(
                        strict,
                        "unsupported-element",
                        d.offset,
                        Some(owner),
                        format!("<{other}> is not a BPMN event definition"),
                    );
                    continue;
                }
            };
            out.push(def);
        }
        out
    }
}
