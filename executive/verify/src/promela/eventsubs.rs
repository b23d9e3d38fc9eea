//! Event sub-processes, and processes started by a message, signal or condition.
//!
//! An event sub-process is armed while the scope it sits in runs (the sub-process is active;
//! for a process, something inside it still runs) and no interrupting event sub-process of that
//! scope has started. A timer, message or condition start fires as an event from outside does;
//! a signal start hears the signals thrown in the model; an error or escalation start catches
//! what is thrown inside the scope (`Tr::catchers`). An interrupting start clears the scope
//! first; a non-interrupting one starts beside it, one instance at a time (the translation has
//! one marking per scope: a second concurrent instance is not modelled), a duration timer once
//! and anything else at most the loop bound plus one times per activation of the scope. A
//! compensation start only runs as its sub-process's compensation (`compensation.rs`).

use super::*;

impl Tr<'_> {
    /// The start events of the event sub-processes directly in `scope`.
    pub(super) fn event_sub_starts(&self, scope: Scope) -> Vec<NodeId> {
        let g = self.g;
        g.scope_nodes(scope)
            .iter()
            .filter_map(|n| match &g.node(*n).kind {
                NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event) => {
                    Some(&sp.nodes)
                }
                _ => None,
            })
            .flatten()
            .copied()
            .filter(|s| matches!(g.node(*s).kind, NodeKind::Start(_)))
            .collect()
    }

    /// The event sub-process a start event belongs to.
    pub(super) fn event_sub_of(&self, start: NodeId) -> Option<NodeId> {
        match self.g.node(start).scope {
            Scope::SubProcess(e) if is_event_sub(self.g, e) => Some(e),
            _ => None,
        }
    }

    /// The scope an event sub-process sits in, as `contents` takes it (`None`: the process).
    fn owner_scope(&self, esp: NodeId) -> Option<NodeId> {
        match self.g.node(esp).scope {
            Scope::SubProcess(s) => Some(s),
            Scope::Process(_) => None,
        }
    }

    /// An interrupting start of an event sub-process (compensation starts are not: they never
    /// fire while the scope runs).
    fn interrupts(&self, start: NodeId) -> bool {
        matches!(&self.g.node(start).kind, NodeKind::Start(st)
            if st.interrupting
                && !st.triggers.iter().any(|d| matches!(d, EventDefinition::Compensate { .. })))
    }

    /// The event sub-process of `start` is armed in context `c`.
    fn armed(&self, c: usize, start: NodeId) -> Option<String> {
        let esp = self.event_sub_of(start)?;
        let owner = self.owner_scope(esp);
        let mut parts = vec![match owner {
            Some(s) => format!("act[{}]", self.a(c, s)),
            // An end event of the process throwing: the process is active until its throw
            // has acted (a signal end event that is its last token still starts its event
            // sub-process, as in the engine).
            None if self.ending == Some(c) => "true".to_owned(),
            None => format!("!{}", self.idle_inside(c, None)),
        }];
        let element = self.g.node(esp).scope;
        for other in self.event_sub_starts(element) {
            if self.interrupts(other)
                && let Some(e) = self.event_sub_of(other)
            {
                parts.push(self.esp_idle(c, e));
            }
        }
        if !self.interrupts(start) {
            parts.push(self.esp_idle(c, esp));
        }
        parts.sort();
        parts.dedup();
        Some(parts.join(" && "))
    }

    /// Neither running nor asked for: event sub-process `esp` in context `c`.
    pub(super) fn esp_idle(&self, c: usize, esp: NodeId) -> String {
        let mut parts = vec![format!("!act[{}]", self.a(c, esp))];
        if let NodeKind::SubProcess(sp) = &self.g.node(esp).kind {
            parts.extend(
                sp.nodes
                    .iter()
                    .filter_map(|s| self.pend_ix.get(&(c, *s)))
                    .map(|k| format!("pend[{k}] == 0")),
            );
        }
        parts.join(" && ")
    }

    /// Starts the event sub-process of `start` in context `c`: an interrupting start first
    /// clears the scope it sits in. `inside`: within another step, which then also records the
    /// start's `fire` (a step of its own is named by it).
    pub(super) fn start_event_sub(&mut self, c: usize, start: NodeId, alt: &mut Alt, inside: bool) {
        let Some(esp) = self.event_sub_of(start) else {
            return;
        };
        if self.interrupts(start) {
            let scope = self.contents(c, self.owner_scope(esp));
            self.clear(&scope, alt);
        }
        self.ask(c, start, alt);
        if inside {
            self.fired(c, start, alt);
        }
    }

    /// Asks for the event sub-process of `start` (or for a compensation handler, `start` being
    /// the handler): its own step enters it (`activity`), so no run that never enters it
    /// counts as one that does.
    pub(super) fn ask(&self, c: usize, start: NodeId, alt: &mut Alt) {
        if let Some(k) = self.pend_ix.get(&(c, start)) {
            alt.effect.push(format!("pend[{k}]++"));
        }
    }

    /// Records start event `start` firing within another step (its marker and what observes it).
    pub(super) fn fired(&mut self, c: usize, start: NodeId, alt: &mut Alt) {
        let m = self.marker(c, start, "fire");
        alt.effect.push(format!("printf(\"@@BPMN {m}\\n\")"));
        let id = self.g.node(start).id.clone();
        alt.effect.extend(self.observed(&id, "fire"));
    }

    /// The steps of an event sub-process started from outside: its timer, message and
    /// condition starts, whenever armed.
    pub(super) fn event_sub(&mut self, c: usize, esp: NodeId) {
        let NodeKind::SubProcess(sp) = &self.g.node(esp).kind else {
            return;
        };
        let starts: Vec<NodeId> = sp.nodes.clone();
        for start in starts {
            let NodeKind::Start(st) = &self.g.node(start).kind else {
                continue;
            };
            let spontaneous = st.triggers.iter().any(|d| {
                matches!(
                    d,
                    EventDefinition::Timer(_)
                        | EventDefinition::Message(_)
                        | EventDefinition::Conditional(_)
                )
            });
            let once = fixed_duration_of(&st.triggers).is_some();
            if !spontaneous {
                continue;
            }
            let Some(armed) = self.armed(c, start) else {
                continue;
            };
            let mut alt = Alt {
                outside: true,
                ..Alt::default()
            };
            alt.guard.push(armed);
            if !self.interrupts(start) {
                let k = self.cnt_ix[&(c, esp)];
                let limit = if once {
                    1
                } else {
                    u32::from(self.bounds.loops) + 1
                };
                alt.guard.push(format!("reps[{k}] < {limit}"));
                alt.effect.push(format!("reps[{k}]++"));
            }
            self.start_event_sub(c, start, &mut alt, false);
            let m = self.marker(c, start, "fire");
            self.push(&m, alt);
        }
    }

    /// A signal thrown in the model reaches the signal starts of armed event sub-processes
    /// and of processes: the effects for one such start (`heard` set when it is taken).
    pub(super) fn signal_start(&mut self, c: usize, start: NodeId, alt: &mut Alt) -> bool {
        if let Some(esp) = self.event_sub_of(start) {
            let Some(armed) = self.armed(c, start) else {
                return false;
            };
            let mut fire = Alt::default();
            // The engine enters the event sub-process as the signal is caught (its instance
            // opens, the start event's token put): an interrupting catcher that hears the same
            // signal after it cancels it entered, so its entry is marked here too, not only in
            // the step that then runs it.
            let entered = self.marker(c, esp, "activate");
            let k = self.witnesses.len();
            self.witnesses.push(entered.clone());
            fire.effect
                .push(format!("printf(\"@@BPMN {entered}\\n\"); entry = {k}"));
            self.start_event_sub(c, start, &mut fire, true);
            alt.effect.push(format!(
                "if :: {armed} -> {}; heard = 1 :: else -> skip fi",
                fire.effect.join("; ")
            ));
        } else if self.start_ix.contains_key(&(c, start)) {
            let mut fire = Alt::default();
            let guard = self.process_start(c, start, &mut fire);
            self.fired(c, start, &mut fire);
            // The engine starts another instance whenever the process already runs; the
            // translation starts it only when idle, and the signal is heard either way.
            alt.effect.push(format!(
                "if :: {guard} -> {} :: else -> skip fi; heard = 1",
                fire.effect.join("; ")
            ));
        } else {
            return false;
        }
        true
    }

    /// A message from the model reaches `start`, a message start event: a new instance of its
    /// process starts if it is idle (the translation has one marking per process), else the
    /// message is lost. The effect, guarded.
    pub(super) fn start_on_message(&mut self, c: usize, start: NodeId) -> Option<String> {
        if self.event_sub_of(start).is_some() || !self.start_ix.contains_key(&(c, start)) {
            return None;
        }
        let mut fire = Alt::default();
        let guard = self.process_start(c, start, &mut fire);
        self.fired(c, start, &mut fire);
        Some(format!(
            "if :: {guard} -> {} :: else -> skip fi",
            fire.effect.join("; ")
        ))
    }

    /// `n` is a start event of a process that starts a new instance on a message, signal or
    /// condition.
    pub(super) fn event_start(&self, n: NodeId) -> bool {
        let node = self.g.node(n);
        matches!(node.scope, Scope::Process(_))
            && matches!(&node.kind, NodeKind::Start(st) if st.triggers.iter().any(|d| matches!(
                d,
                EventDefinition::Message(_) | EventDefinition::Signal(_) | EventDefinition::Conditional(_)
            )))
    }

    /// Starts a process's instance at `start` (an event start): its guard (the process idle,
    /// fewer than the loop bound such starts so far) and effects.
    fn process_start(&mut self, c: usize, start: NodeId, alt: &mut Alt) -> String {
        let k = self.start_ix[&(c, start)];
        let guard = format!(
            "{} && starts[{k}] < {}",
            self.idle_inside(c, None),
            self.bounds.loops
        );
        alt.effect.push(format!("starts[{k}]++"));
        self.reset(c, None, alt);
        self.start_implicit(c, None, alt);
        let outs = self.g.node(start).outgoing.clone();
        self.put_all(c, &outs, alt);
        guard
    }

    /// A process started by a message or a condition from outside: whenever it is idle, at
    /// most the loop bound times (a signal start hears the model's signals instead).
    pub(super) fn message_start(&mut self, c: usize, start: NodeId) {
        if !started_from_outside(self.g, start)
            || inner_message(self.g, start)
            || !self.start_ix.contains_key(&(c, start))
        {
            return;
        }
        let mut alt = Alt {
            outside: true,
            ..Alt::default()
        };
        let guard = self.process_start(c, start, &mut alt);
        alt.guard.push(guard);
        let m = self.marker(c, start, "fire");
        self.push(&m, alt);
    }
}
