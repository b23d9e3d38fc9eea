//! Data: an activity's or event's inputs and outputs (§10.4: input and output sets, data
//! associations) resolved against the data objects, properties and items in scope.

use super::*;

impl<'d> Builder<'d, '_> {
    /// The ioSpecification and data associations of activity `el` (§10.4.1).
    pub(super) fn data_io(
        &mut self,
        el: &'d Element<'d>,
        owner: &str,
        strict: bool,
    ) -> Option<Box<DataIo>> {
        let spec = el.bpmn_child("ioSpecification");
        let ins: Vec<&'d Element<'d>> = el.bpmn_children("dataInputAssociation").collect();
        let outs: Vec<&'d Element<'d>> = el.bpmn_children("dataOutputAssociation").collect();
        if spec.is_none() && ins.is_empty() && outs.is_empty() {
            return None;
        }
        let params = |kind: &str| -> Vec<DataParam> {
            spec.into_iter()
                .flat_map(|s| s.bpmn_children(kind))
                .map(|d| DataParam {
                    id: d.attr("id").unwrap_or_default().to_owned(),
                    name: item_name(d),
                })
                .collect()
        };
        let mut io = DataIo {
            inputs: params("dataInput"),
            outputs: params("dataOutput"),
            ..DataIo::default()
        };
        let sets = |kind: &str, refs: &str, optional: &str, of: &[DataParam]| -> Vec<IoSet> {
            spec.into_iter()
                .flat_map(|s| s.bpmn_children(kind))
                .map(|set| {
                    let idx = |child: &str| -> Vec<usize> {
                        set.bpmn_children(child)
                            .filter_map(|r| of.iter().position(|p| p.id == local_ref(r.text)))
                            .collect()
                    };
                    IoSet {
                        refs: idx(refs),
                        optional: idx(optional),
                    }
                })
                .collect()
        };
        io.input_sets = sets("inputSet", "dataInputRefs", "optionalInputRefs", &io.inputs);
        io.output_sets = sets(
            "outputSet",
            "dataOutputRefs",
            "optionalOutputRefs",
            &io.outputs,
        );
        for (list, input) in [(ins, true), (outs, false)] {
            for a in list {
                let sources = a
                    .bpmn_children("sourceRef")
                    .filter_map(|r| self.data_ref(r.offset, r.text, &io))
                    .collect();
                let target = a
                    .bpmn_child("targetRef")
                    .and_then(|r| self.data_ref(r.offset, r.text, &io));
                let transformation = a
                    .bpmn_child("transformation")
                    .and_then(|t| self.expr(strict, t, owner, "data association transformation"));
                let mut assignments = Vec::new();
                for asg in a.bpmn_children("assignment") {
                    let (Some(from), Some(to)) = (asg.bpmn_child("from"), asg.bpmn_child("to"))
                    else {
                        continue;
                    };
                    if let Some(from) = self.expr(strict, from, owner, "assignment") {
                        let to = self.data_path(to.offset, to.trimmed_text(), &io);
                        assignments.push((from, to));
                    }
                }
                let assoc = DataAssociation {
                    sources,
                    target,
                    transformation,
                    assignments,
                };
                if input {
                    io.input_associations.push(assoc);
                } else {
                    io.output_associations.push(assoc);
                }
            }
        }
        Some(Box::new(io))
    }

    /// What the item-aware element `id` (seen from `offset`) stands for at run time.
    pub(super) fn data_ref(&self, offset: usize, id: &str, io: &DataIo) -> Option<DataRef> {
        let id = local_ref(id);
        if let Some(i) = io.inputs.iter().position(|p| p.id == id) {
            return Some(DataRef::Input(i));
        }
        if let Some(i) = io.outputs.iter().position(|p| p.id == id) {
            return Some(DataRef::Output(i));
        }
        let ns = self.doc_namespace[self.doc_of(offset)];
        // Item-aware elements: data objects and their references, properties, data stores and
        // their references, data inputs and outputs.
        let data = |id: &str| {
            self.all_ids
                .get(&(ns, id))
                .copied()
                .filter(|el| crate::constraints::ITEM_AWARE.contains(&el.name))
        };
        let el = data(id)?;
        let referenced = |attr: &str| el.attr(attr).and_then(|r| data(local_ref(r)));
        Some(match el.name {
            "dataObjectReference" => {
                DataRef::Variable(item_name(referenced("dataObjectRef").unwrap_or(el)))
            }
            "dataStoreReference" => {
                DataRef::Store(item_name(referenced("dataStoreRef").unwrap_or(el)))
            }
            "dataStore" => DataRef::Store(item_name(el)),
            _ => DataRef::Variable(item_name(el)),
        })
    }

    /// The path an assignment's `to` writes: its first part names a data input or output of the
    /// activity, or an item-aware element, by id or name; the rest is a path inside it.
    pub(super) fn data_path(&self, offset: usize, to: &str, io: &DataIo) -> String {
        let to = to.trim();
        let (first, rest) = to.split_once('.').map_or((to, None), |(f, r)| (f, Some(r)));
        let name = match self.data_ref(offset, first, io) {
            Some(DataRef::Input(i)) => io.inputs[i].name.clone(),
            Some(DataRef::Output(i)) => io.outputs[i].name.clone(),
            Some(DataRef::Variable(n) | DataRef::Store(n)) => n,
            None => first.to_owned(),
        };
        match rest {
            Some(r) => format!("{name}.{r}"),
            None => name,
        }
    }
}
