//! A collaboration: its participants (pools) and message flows, each end resolved.

use super::*;

impl<'d> Builder<'d, '_> {
    pub(super) fn collaboration(&mut self, el: &Element) {
        let participants = el
            .bpmn_children("participant")
            .map(|p| Participant {
                id: p.attr("id").unwrap_or_default().to_owned(),
                name: p.attr("name").map(str::to_owned),
                process: p.attr("processRef").and_then(|r| {
                    let r = local_ref(r);
                    let found = self.find_process(self.doc_of(p.offset), r, false);
                    if found.is_none() {
                        self.sink.warning(
                            "dangling-reference",
                            p.offset,
                            p.attr("id"),
                            format!(
                                "participant processRef `{r}` does not name a process of this model"
                            ),
                        );
                    }
                    found
                }),
            })
            .collect();
        let mut message_flows = Vec::new();
        for f in el.bpmn_children("messageFlow") {
            let id = f.attr("id").unwrap_or_default().to_owned();
            let mut ends = Vec::new();
            for attr in ["sourceRef", "targetRef"] {
                let r = f.attr(attr).map(local_ref).unwrap_or_default().to_owned();
                if self.any_ref(f.offset, &r).is_none() {
                    self.sink.error(
                        "dangling-reference",
                        f.offset,
                        Some(&id),
                        format!("message flow {attr} `{r}` does not exist"),
                    );
                }
                ends.push(r);
            }
            let message = self.resolve(|b| &b.messages, f, "messageRef", &id);
            let target = ends.pop().unwrap_or_default();
            let source = ends.pop().unwrap_or_default();
            message_flows.push(MessageFlow {
                id,
                source,
                target,
                message,
            });
        }
        self.g.collaborations.push(Collaboration {
            id: el.attr("id").unwrap_or_default().to_owned(),
            participants,
            message_flows,
        });
    }
}
