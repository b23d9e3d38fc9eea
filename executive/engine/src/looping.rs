//! Standard loops and multi-instance activities: each body runs in its own scope.

use executive_model::{EventDefinition, Looping, MiBehavior};

use crate::io::{Entry, ScopeId, TokenId, Trigger};
use crate::run::{Run, triggers_of};
use crate::state::{At, Loop, ScopeKind, ScopeState};
use crate::value::{Value, Vars};
use compact_str::CompactString;

/// Bodies a parallel multi-instance activity may start at once: each is a scope and a token
/// the engine keeps, and a cardinality or collection comes from data (a wrong value of a
/// trillion would be a trillion scopes within one step). A sequential one runs its bodies one by
/// one, unbounded.
pub(crate) const MAX_PARALLEL: u64 = 10_000;

impl Run<'_> {
    /// A looping activity starts.
    pub(crate) fn start_loop(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        let mut state = Loop {
            started: 0,
            completed: 0,
            total: None,
            running: Vec::new(),
            outputs: Default::default(),
            items: None,
            thrown: 0,
        };
        match g.node(node).looping.as_ref() {
            Some(Looping::Standard {
                test_before,
                condition,
                ..
            }) => {
                self.set_loop(t, state);
                if *test_before && !self.decides() {
                    match self.loop_condition(t, condition.as_ref(), 0) {
                        Ok(true) => {}
                        Ok(false) => return self.loop_done(t),
                        Err(e) => return self.incident(t, e),
                    }
                }
                self.start_body(t);
            }
            Some(looping @ Looping::MultiInstance(mi)) => {
                if self.decides() {
                    state.total = Some(self.decided_count(looping));
                } else if let Some(c) = &mi.input_collection {
                    // The collection may be a data input of the activity (§10.3.8).
                    let inputs = self.loop_data_inputs(t);
                    let lookup = |n: &str| inputs.get(n).cloned().or_else(|| self.lookup(scope, n));
                    match crate::eval::eval(c, self.now, &lookup, &mut Vars::new()) {
                        Ok(Value::List(items)) => {
                            state.total = Some(items.len() as u64);
                            state.items = Some(items);
                        }
                        Ok(other) => {
                            return self.incident(
                                t,
                                format!(
                                    "input collection `{}` is {}, not a list",
                                    c.source,
                                    other.type_name()
                                ),
                            );
                        }
                        Err(e) => return self.incident(t, e),
                    }
                } else if let Some(c) = &mi.cardinality {
                    match self.eval(scope, c, &mut Vars::new()) {
                        Ok(Value::Int(n)) if n >= 0 => state.total = Some(n as u64),
                        Ok(other) => {
                            return self.incident(
                                t,
                                format!("loop cardinality `{}` is {other}, not a count", c.source),
                            );
                        }
                        Err(e) => return self.incident(t, e),
                    }
                }
                let total = state.total.unwrap_or(0);
                self.set_loop(t, state);
                if total == 0 {
                    return self.loop_done(t);
                }
                if !mi.sequential && total > MAX_PARALLEL {
                    return self.incident(
                        t,
                        format!(
                            "{total} parallel instances are more than the {MAX_PARALLEL} one activity may run at once; make it sequential or split the collection"
                        ),
                    );
                }
                let n = if mi.sequential { 1 } else { total };
                for _ in 0..n {
                    self.start_body(t);
                }
            }
            None => self.start_activity(t),
        }
    }

    /// Exploring without data (`decides`): how many instances or bodies `looping` runs — a count
    /// the model writes as a number (`Looping::literal_count`), up to the game's cap, else one.
    fn decided_count(&self, looping: &Looping) -> u64 {
        let cap = self.game.map_or(0, |g| g.instances).max(1);
        looping.literal_count().map_or(1, |n| n.min(cap))
    }

    fn set_loop(&mut self, t: TokenId, l: Loop) {
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Looping(Box::new(l));
        }
    }

    fn loop_mut(&mut self, t: TokenId) -> Option<&mut Loop> {
        match self.s.tokens.get_mut(&t).map(|t| &mut t.at) {
            Some(At::Looping(l)) => Some(l),
            _ => None,
        }
    }

    fn loop_condition(
        &self,
        t: TokenId,
        cond: Option<&executive_model::Expression>,
        counter: u64,
    ) -> Result<bool, String> {
        let Some(c) = cond else { return Ok(true) };
        let scope = self.s.tokens[&t].scope;
        let lookup = |n: &str| {
            if n == "loopCounter" {
                Some(Value::Int(counter as i64))
            } else {
                self.lookup(scope, n)
            }
        };
        crate::eval::condition(c, self.now, &lookup, &mut Vars::new())
    }

    /// Starts one more body of the looping activity of token `t`.
    fn start_body(&mut self, t: TokenId) {
        let tok = &self.s.tokens[&t];
        let (node, instance, parent) = (tok.node, tok.instance, tok.scope);
        let Some(l) = self.loop_mut(t) else { return };
        l.started += 1;
        let counter = l.started;
        let item = l
            .items
            .as_ref()
            .and_then(|i| i.get(counter as usize - 1))
            .cloned();
        let (total, active, completed) = (l.total, l.running.len() as u64 + 1, l.completed);
        let mut vars = Vars::new();
        vars.insert("loopCounter".into(), Value::Int(counter as i64));
        if let Some(total) = total {
            vars.insert("nrOfInstances".into(), Value::Int(total as i64));
            vars.insert("nrOfActiveInstances".into(), Value::Int(active as i64));
            vars.insert(
                "nrOfCompletedInstances".into(),
                Value::Int(completed as i64),
            );
        }
        if let (Some(item), Some(Looping::MultiInstance(mi))) =
            (item, self.g.node(node).looping.as_ref())
        {
            let name = mi
                .input_element
                .clone()
                .unwrap_or_else(|| "item".to_owned());
            vars.insert(name, item);
        }
        // The output item is the instance's own: what the body writes to it stays there.
        if let Some(Looping::MultiInstance(mi)) = self.g.node(node).looping.as_ref()
            && let Some(e) = &mi.output_element
            && e.variables.len() == 1
            && e.variables[0] == e.source.trim()
        {
            vars.entry(e.source.trim().to_owned())
                .or_insert(Value::Null);
        }
        let scope = ScopeId(self.mint());
        self.s.scopes.insert(
            scope,
            ScopeState {
                instance,
                parent: Some(parent),
                owner: Some(t),
                kind: ScopeKind::Body(node),
                vars,
                compensable: thin_vec::ThinVec::new(),
                ending: false,
                tokens: Default::default(),
                waits: thin_vec::ThinVec::new(),
            },
        );
        if let Some(l) = self.loop_mut(t) {
            l.running.push(scope);
        }
        let b = self.spawn(scope, node, None);
        if let Some(tok) = self.s.tokens.get_mut(&b) {
            tok.body = true;
        }
    }

    /// One body finished (its scope completed with variables `vars`).
    pub(crate) fn body_done(&mut self, t: TokenId, scope: ScopeId, vars: &Vars) {
        let g = self.g;
        let node = self.s.tokens[&t].node;
        let Some(l) = self.loop_mut(t) else { return };
        l.running.retain(|s| *s != scope);
        l.completed += 1;
        let counter = vars.get("loopCounter").cloned();
        let (completed, started, total, running) =
            (l.completed, l.started, l.total, l.running.len());
        match g.node(node).looping.as_ref() {
            Some(
                looping @ Looping::Standard {
                    maximum, condition, ..
                },
            ) => {
                let limit = if self.decides() {
                    Some(self.decided_count(looping))
                } else {
                    *maximum
                };
                if limit.is_some_and(|m| completed >= m) {
                    return self.loop_done(t);
                }
                match self.loop_condition(t, condition.as_ref(), completed) {
                    Ok(true) => self.start_body(t),
                    Ok(false) => self.loop_done(t),
                    Err(e) => self.incident(t, e),
                }
            }
            Some(Looping::MultiInstance(mi)) => {
                let parent = self.s.tokens[&t].scope;
                let with_body = |r: &Run<'_>, n: &str| -> Option<Value> {
                    // BPMN's (and Camunda 7's) names, and Camunda 8's.
                    match n {
                        "nrOfCompletedInstances" | "numberOfCompletedInstances" => {
                            Some(Value::Int(completed as i64))
                        }
                        "nrOfActiveInstances" | "numberOfActiveInstances" => {
                            Some(Value::Int(running as i64))
                        }
                        "nrOfInstances" | "numberOfInstances" => {
                            total.map(|x| Value::Int(x as i64))
                        }
                        // Boundary events end the whole activity, so no body is ever
                        // terminated while the others go on.
                        "numberOfTerminatedInstances" => Some(Value::Int(0)),
                        _ => vars.get(n).cloned().or_else(|| r.lookup(parent, n)),
                    }
                };
                if let Some(e) = &mi.output_element {
                    let out =
                        crate::eval::eval(e, self.now, &|n| with_body(self, n), &mut Vars::new());
                    match out {
                        Ok(v) => {
                            let c = match counter {
                                Some(Value::Int(c)) => c as u64,
                                _ => completed,
                            };
                            if let Some(l) = self.loop_mut(t) {
                                l.outputs.insert(c, v);
                            }
                        }
                        Err(e) => return self.incident(t, e),
                    }
                }
                // Behaviour events: thrown to the activity's own signal boundary events.
                let thrown = self.loop_mut(t).map_or(0, |l| l.thrown);
                let (throw, stop) = match mi.behavior {
                    MiBehavior::None => (true, false),
                    MiBehavior::One => (thrown == 0, false),
                    MiBehavior::All => (false, false),
                    MiBehavior::Complex => {
                        let mut hit = false;
                        for c in &mi.complex {
                            match crate::eval::condition(
                                c,
                                self.now,
                                &|n| with_body(self, n),
                                &mut Vars::new(),
                            ) {
                                Ok(b) => hit |= b,
                                Err(e) => return self.incident(t, e),
                            }
                        }
                        (hit && thrown == 0, hit)
                    }
                };
                if throw {
                    if let Some(l) = self.loop_mut(t) {
                        l.thrown += 1;
                    }
                    self.behavior_event(t);
                }
                let done_by_condition = match &mi.completion {
                    Some(_) if self.decides() => false,
                    Some(c) => {
                        match crate::eval::condition(
                            c,
                            self.now,
                            &|n| with_body(self, n),
                            &mut Vars::new(),
                        ) {
                            Ok(b) => b,
                            Err(e) => return self.incident(t, e),
                        }
                    }
                    None => false,
                };
                if stop || done_by_condition || Some(completed) == total {
                    let rest = self
                        .loop_mut(t)
                        .map(|l| std::mem::take(&mut l.running))
                        .unwrap_or_default();
                    for s in rest {
                        self.cancel_scope(s);
                    }
                    return self.loop_done(t);
                }
                if mi.sequential && total.is_some_and(|n| started < n) {
                    self.start_body(t);
                }
            }
            None => self.loop_done(t),
        }
    }

    /// The multi-instance activity throws its behaviour event: its signal boundary events fire
    /// (without interrupting it).
    fn behavior_event(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope, instance) = (tok.node, tok.scope, tok.instance);
        for &b in &g.node(node).boundaries {
            if triggers_of(g, b)
                .iter()
                .any(|d| matches!(d, EventDefinition::Signal(_)))
            {
                self.record(instance, || Entry::Caught {
                    what: Trigger::Signal,
                    name: CompactString::const_new("multi-instance behavior"),
                    node: b,
                });
                self.spawn(scope, b, None);
            }
        }
    }

    /// The loop is over: write the output collection, and the activity completes.
    fn loop_done(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        if let Some(Looping::MultiInstance(mi)) = g.node(node).looping.as_ref()
            && let Some(name) = &mi.output_collection
        {
            let outputs = self
                .loop_mut(t)
                .map(|l| l.outputs.values().cloned().collect())
                .unwrap_or_default();
            self.set_var(scope, name, Value::List(outputs));
        }
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Ready;
        }
        self.complete_activity(t);
    }
}
