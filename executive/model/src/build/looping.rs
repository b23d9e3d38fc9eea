//! A node's default flow, and its loop or multi-instance characteristics.

use super::*;

impl<'d> Builder<'d, '_> {
    /// A node's default flow: read on the elements whose schema type has `default` (activities
    /// and exclusive, inclusive and complex gateways); elsewhere it is reported and ignored.
    pub(super) fn default_flow(&mut self, nid: NodeId, el: &Element, owner: &str) {
        let Some(d) = schema_attr(el, "default") else {
            return;
        };
        let d = local_ref(d);
        let found = self
            .g
            .node(nid)
            .outgoing
            .iter()
            .copied()
            .find(|f| self.g.flow(*f).id == d);
        match found {
            Some(f) => self.g.nodes[nid.index()].default_flow = Some(f),
            None => {
                self.sink.error(
                    "bad-default-flow",
                    el.offset,
                    Some(owner),
                    format!("default flow `{d}` is not an outgoing sequence flow of this element"),
                );
            }
        }
    }

    pub(super) fn looping(&mut self, nid: NodeId, el: &Element, owner: &str, strict: bool) {
        if let Some(l) = el.bpmn_child("standardLoopCharacteristics") {
            let maximum = match l.attr("loopMaximum") {
                None => None,
                Some(m) => match m.trim().parse::<u64>() {
                    Ok(v) => Some(v),
                    Err(_) => {
                        self.problem(
                            strict,
                            "bad-attribute",
                            l.offset,
                            Some(owner),
                            format!("loopMaximum=\"{m}\" is not a non-negative whole number"),
                        );
                        None
                    }
                },
            };
            let condition = l
                .bpmn_child("loopCondition")
                .and_then(|c| self.expr(strict, c, owner, "loop condition"));
            self.g.nodes[nid.index()].looping = Some(Looping::Standard {
                test_before: l.attr("testBefore") == Some("true"),
                maximum,
                condition,
            });
            return;
        }
        let Some(m) = el.bpmn_child("multiInstanceLoopCharacteristics") else {
            return;
        };
        let zeebe = m
            .extensions()
            .find(|e| e.ns == Ns::Zeebe && e.name == "loopCharacteristics");
        let cardinality = m
            .bpmn_child("loopCardinality")
            .and_then(|c| self.expr(strict, c, owner, "loop cardinality"));
        // A data input of the activity's ioSpecification is read by its name (§10.3.8).
        let data_inputs = self.g.nodes[nid.index()]
            .data
            .as_ref()
            .map(|d| d.inputs.clone())
            .unwrap_or_default();
        let collection_written = m.bpmn_child("loopDataInputRef").is_some()
            || m.attr_ns(&Ns::Camunda, "collection").is_some()
            || zeebe.is_some_and(|z| z.attr("inputCollection").is_some());
        let mut input_collection = m
            .bpmn_child("loopDataInputRef")
            .map(|r| local_ref(r.text).to_owned())
            .map(|r| match data_inputs.iter().find(|p| p.id == r) {
                Some(p) => p.name.clone(),
                None => r,
            })
            .or_else(|| m.attr_ns(&Ns::Camunda, "collection").map(str::to_owned))
            .map(|c| (c, Language::Cel))
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("inputCollection"))
                    .map(|c| (c.to_owned(), Language::Feel))
            })
            .and_then(|(c, language)| match Expression::compile(&c, &language) {
                Ok(e) => Some(e),
                Err(f) => {
                    self.expr_problem(strict, m.offset, owner, "input collection", f);
                    None
                }
            });
        // A collection that is written but does not compile has its own diagnostic.
        if !collection_written && m.bpmn_child("loopCardinality").is_none() && strict {
            self.problem(
                strict,
                "missing-cardinality",
                m.offset,
                Some(owner),
                "multi-instance needs a loopCardinality or an input collection".to_owned(),
            )
            .constraint("EXT.067");
            input_collection = None;
        }
        let item_name = |child: &str| {
            m.bpmn_child(child)
                .and_then(|d| d.attr("name").or(d.attr("id")))
                .map(str::to_owned)
        };
        let input_element = item_name("inputDataItem")
            .or_else(|| {
                m.attr_ns(&Ns::Camunda, "elementVariable")
                    .map(str::to_owned)
            })
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("inputElement"))
                    .map(str::to_owned)
            });
        let output_collection = m
            .bpmn_child("loopDataOutputRef")
            .map(|r| local_ref(r.text).to_owned())
            .or_else(|| {
                zeebe
                    .and_then(|z| z.attr("outputCollection"))
                    .map(str::to_owned)
            });
        let output_element =
            match item_name("outputDataItem") {
                Some(name) => Expression::parse(&name).ok(),
                None => zeebe.and_then(|z| z.attr("outputElement")).and_then(|e| {
                    match Expression::compile(e, &Language::Feel) {
                        Ok(e) => Some(e),
                        Err(f) => {
                            self.expr_problem(strict, m.offset, owner, "output element", f);
                            None
                        }
                    }
                }),
            };
        let completion = m
            .bpmn_child("completionCondition")
            .and_then(|c| self.expr(strict, c, owner, "completion condition"));
        let behavior = match m.attr("behavior") {
            Some("None") => MiBehavior::None,
            Some("One") => MiBehavior::One,
            Some("Complex") => MiBehavior::Complex,
            _ => MiBehavior::All,
        };
        self.g.nodes[nid.index()].looping = Some(Looping::MultiInstance(Box::new(MultiInstance {
            sequential: m.attr("isSequential") == Some("true"),
            cardinality,
            input_collection,
            input_element,
            output_collection,
            output_element,
            completion,
            behavior,
            complex: m
                .bpmn_children("complexBehaviorDefinition")
                .filter_map(|d| d.bpmn_child("condition"))
                .filter_map(|c| self.expr(strict, c, owner, "complex behavior condition"))
                .collect(),
        })));
    }
}
