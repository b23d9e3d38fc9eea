//! Moving tokens to quiescence: arriving at nodes, leaving them, consuming tokens, incidents.
//!
//! A little over 1,000 lines, on purpose: arriving and leaving are one job, each node kind's
//! arrival sharing the token's bookkeeping with its leaving; throws (`throws.rs`), events
//! (`events.rs`), gateways (`gateway.rs`) and compensation have rooms of their own.

use std::borrow::Cow;
use std::collections::{BTreeSet, VecDeque};

use executive_model::{
    EventDefinition, FlowId, NodeId, NodeKind, ProcessGraph, Scope, SubProcessKind, TaskKind,
};

use crate::eval;
use crate::io::{Action, Entry, InstanceId, Millis, Record, ScopeId, TokenId, Trigger, WaitId};
use crate::state::{At, On, ScopeKind, State, Token};
use crate::value::{Value, Vars};

/// One step's working context: the state being changed, the actions produced, the tokens that
/// still have to move.
pub(crate) struct Run<'a> {
    pub(crate) g: &'a ProcessGraph,
    pub(crate) s: &'a mut State,
    pub(crate) now: Millis,
    /// The step's actions, appended to the caller's buffer.
    pub(crate) out: &'a mut Vec<Action>,
    /// The tokens ready to arrive, each with its wave: one more than the wave of the arrival
    /// that made it ready (the step's first tokens are wave 1).
    pub(crate) ready: VecDeque<(TokenId, u32)>,
    /// The wave of the token arriving now (0 before the first arrival of the step).
    pub(crate) wave: u32,
    /// Record token moves (entered / left / took). Off only for benchmarks of raw stepping.
    pub(crate) trace_moves: bool,
    /// Token-game settings, if the engine plays a token game.
    pub(crate) game: Option<&'a crate::game::Game>,
    /// Throwers put back behind the other tokens of their wave, now due to throw.
    pub(crate) throw_now: crate::state::TokenSet,
    /// The incoming flows of a join reachable from a node, memoised (derived from the graph
    /// only, not state).
    pub(crate) reach: &'a mut std::collections::BTreeMap<(NodeId, NodeId, bool), Vec<FlowId>>,
    /// The processes of pools other executives run, with their pool's id.
    pub(crate) remote: &'a std::collections::BTreeMap<executive_model::ProcessId, String>,
}

/// Conditional events re-evaluated this many rounds in one step at most (a condition that keeps
/// flipping would otherwise never let the step end).
const MAX_CONDITION_ROUNDS: usize = 1000;

/// Token arrivals in one step at most. A model that loops without ever waiting would otherwise
/// never return; its tokens become incidents instead.
const MAX_MOVES: usize = 1_000_000;

impl<'a> Run<'a> {
    pub(crate) fn mint(&mut self) -> u64 {
        self.s.next_id += 1;
        self.s.next_id
    }

    /// Appends a record entry, made by `entry` where it is written: an entry made first and
    /// moved in was copied through the stack, and reading back what was just written cost a
    /// store-forwarding stall per entry (`docs/benchmarks.md`, 2026-12-05).
    #[inline(always)]
    pub(crate) fn record(&mut self, instance: InstanceId, entry: impl FnOnce() -> Entry) {
        let at = self.now;
        self.out.reserve(1);
        self.out.extend(std::iter::once_with(|| {
            Action::Record(Record {
                instance,
                at,
                entry: entry(),
            })
        }));
    }

    /// Creates a token at `node` in `scope`, ready to arrive there.
    pub(crate) fn spawn(&mut self, scope: ScopeId, node: NodeId, via: Option<FlowId>) -> TokenId {
        let id = TokenId(self.mint());
        let instance = self.s.scopes[&scope].instance;
        self.s.tokens.insert(
            id,
            Token {
                instance,
                scope,
                node,
                via,
                at: At::Ready,
                attempts: 0,
                body: false,
                compensating: None,
                waits: thin_vec::ThinVec::new(),
                goal: None,
                command: None,
            },
        );
        if let Some(sc) = self.s.scopes.get_mut(&scope) {
            sc.tokens.insert(id);
        }
        self.ready.push_back((id, self.wave + 1));
        id
    }

    /// Moves every ready token, then re-evaluates joins and conditions, until nothing moves.
    pub(crate) fn quiesce(&mut self) {
        let mut moves = 0;
        for _ in 0..MAX_CONDITION_ROUNDS {
            while let Some((t, wave)) = self.ready.pop_front() {
                if self.s.tokens.get(&t).is_some_and(|t| t.at == At::Ready) {
                    moves += 1;
                    if moves > MAX_MOVES {
                        self.incident(t, format!("the step exceeded {MAX_MOVES} token moves: the model loops without waiting"));
                        continue;
                    }
                    self.wave = wave;
                    self.arrive(t);
                }
            }
            if self.joins() || self.conditions() {
                continue;
            }
            return;
        }
        // Conditions kept firing: leave the remaining work for the next input.
    }

    /// Variable lookup from a scope: the scope chain up to the enclosing process, then system
    /// data.
    pub(crate) fn lookup(&self, scope: ScopeId, name: &str) -> Option<Value> {
        let mut cur = Some(scope);
        while let Some(id) = cur {
            let sc = self.s.scopes.get(&id)?;
            if let Some(v) = sc.vars.get(name) {
                return Some(v.clone());
            }
            if matches!(sc.kind, ScopeKind::Process(_)) {
                break;
            }
            if self.declares(&sc.kind, name) {
                // A data object of this sub-process instance that has no value yet.
                return None;
            }
            cur = sc.parent;
        }
        self.s.data.get(name).cloned()
    }

    /// Writes a variable where it is defined in the scope chain, else in the enclosing process.
    pub(crate) fn set_var(&mut self, scope: ScopeId, name: &str, value: Value) {
        let mut cur = scope;
        loop {
            let Some(sc) = self.s.scopes.get(&cur) else {
                return;
            };
            let top = matches!(sc.kind, ScopeKind::Process(_)) || sc.parent.is_none();
            if sc.vars.contains_key(name) || top || self.declares(&sc.kind, name) {
                break;
            }
            match sc.parent {
                Some(p) => cur = p,
                None => break,
            }
        }
        if let Some(sc) = self.s.scopes.get_mut(&cur) {
            sc.vars.insert(name.to_owned(), value);
        }
    }

    pub(crate) fn eval(
        &self,
        scope: ScopeId,
        expr: &executive_model::Expression,
        read: &mut Vars,
    ) -> Result<Value, String> {
        eval::eval(expr, self.now, &|n| self.lookup(scope, n), read)
    }

    pub(crate) fn condition(
        &self,
        scope: ScopeId,
        expr: &executive_model::Expression,
        read: &mut Vars,
    ) -> Result<bool, String> {
        eval::condition(expr, self.now, &|n| self.lookup(scope, n), read)
    }

    /// The token is stuck: record why and leave it there.
    pub(crate) fn incident(&mut self, t: TokenId, message: String) {
        let Some(tok) = self.s.tokens.get_mut(&t) else {
            return;
        };
        tok.at = At::Incident;
        let (instance, node) = (tok.instance, tok.node);
        if let Some(i) = self.s.instances.get_mut(&instance) {
            i.incidents.push((node, message.clone()));
        }
        self.record(instance, || Entry::Incident { node, message });
    }

    /// A token arrives at its node.
    fn arrive(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node_id, instance, body) = (tok.node, tok.instance, tok.body);
        let node = g.node(node_id);
        if self.trace_moves && !self.throw_now.contains(&t) {
            self.record(instance, || Entry::Entered {
                node: node_id,
                token: t,
            });
        }
        match &node.kind {
            NodeKind::Start(_) | NodeKind::Boundary(_) => self.leave(t),
            NodeKind::End(defs) => self.end_event(t, defs),
            NodeKind::Throw(defs) => self.throw_event(t, defs),
            NodeKind::Catch(c) => {
                if let [EventDefinition::Link(_)] = c.triggers.as_slice() {
                    self.leave(t);
                } else {
                    self.catch_event(t, node_id, &c.triggers);
                }
            }
            NodeKind::Gateway(gw) => self.gateway(t, gw),
            NodeKind::Task(_) | NodeKind::SubProcess(_) | NodeKind::CallActivity(_) => {
                if node.start_quantity > 1 && !body && !self.quantity_reached(t) {
                    return;
                }
                if !body {
                    self.subscribe_boundaries(t);
                }
                self.activate(t);
            }
        }
    }

    /// `startQuantity`: the activity starts when that many tokens have arrived; the others are
    /// merged into this one.
    fn quantity_reached(&mut self, t: TokenId) -> bool {
        let tok = &self.s.tokens[&t];
        let (scope, node) = (tok.scope, tok.node);
        let need = self.g.node(node).start_quantity as usize;
        let waiting: Vec<TokenId> = self
            .s
            .joining
            .get(&(scope, node))
            .map(|s| s.iter().copied().filter(|o| *o != t).collect())
            .unwrap_or_default();
        if waiting.len() + 1 < need {
            self.park(t);
            return false;
        }
        for o in waiting.into_iter().take(need - 1) {
            self.consume(o);
        }
        self.unpark(t);
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Ready;
        }
        true
    }

    /// Starts the work of an activity (one body of it, for loops).
    pub(crate) fn start_activity(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node_id, scope) = (tok.node, tok.scope);
        let node = g.node(node_id);
        match &node.kind {
            NodeKind::Task(task) => self.start_task(t, task),
            NodeKind::SubProcess(_) => {
                let child = self.open_scope(t, ScopeKind::SubProcess(node_id), Vars::new());
                self.start_scope(child, node_id);
            }
            NodeKind::CallActivity(call) => match &call.called {
                Some(executive_model::Called::Process(p)) => {
                    // Exploring without data: the caller's variables pass as they are.
                    let binding = call.binding.as_ref().filter(|_| !self.decides());
                    let vars = self.call_inputs(t, scope, binding);
                    let child = self.open_scope(t, ScopeKind::Process(*p), vars);
                    self.start_process_scope(child, *p, None);
                }
                Some(executive_model::Called::GlobalTask(id)) => match g.global_tasks.get(id) {
                    Some(task) => self.start_task(t, task),
                    None => self.incident(t, format!("global task `{id}` is missing")),
                },
                None => self.incident(t, "the call activity calls nothing".to_owned()),
            },
            _ => self.leave(t),
        }
    }

    fn call_inputs(
        &mut self,
        t: TokenId,
        scope: ScopeId,
        binding: Option<&executive_model::binding::TaskBinding>,
    ) -> Vars {
        let mut vars = Vars::new();
        // Declared data inputs are what the called process gets (§10.3.6).
        let data = match self.task_data_inputs(t) {
            Ok(d) => d,
            Err(e) => {
                self.incident(t, e);
                None
            }
        };
        let all = binding.is_some_and(|b| b.all_in)
            || (data.is_none() && binding.is_none_or(|b| b.inputs.is_empty()));
        if all {
            let mut cur = Some(scope);
            let mut chain = Vec::new();
            while let Some(id) = cur {
                let Some(sc) = self.s.scopes.get(&id) else {
                    break;
                };
                chain.push(id);
                if matches!(sc.kind, ScopeKind::Process(_)) {
                    break;
                }
                cur = sc.parent;
            }
            for id in chain.into_iter().rev() {
                vars.extend(self.s.scopes[&id].vars.clone());
            }
        }
        vars.extend(data.unwrap_or_default());
        if let Some(b) = binding {
            for m in &b.inputs {
                // A mapping sees the targets of the mappings before it (Camunda: "evaluated in
                // the defined order"), then the scope's variables.
                let v = eval::eval(
                    &m.source,
                    self.now,
                    &|n| vars.get(n).cloned().or_else(|| self.lookup(scope, n)),
                    &mut Vars::new(),
                );
                match v {
                    Ok(v) => eval::set_path(&mut vars, &m.target, v),
                    Err(e) => {
                        self.incident(t, format!("input `{}`: {e}", m.target));
                    }
                }
            }
        }
        vars
    }

    fn start_task(&mut self, t: TokenId, task: &executive_model::Task) {
        let tok = &self.s.tokens[&t];
        let (scope, node, instance) = (tok.scope, tok.node, tok.instance);
        if let Some(game) = self.game
            && task.kind != TaskKind::Receive
        {
            // A task that a message flow points at waits for the message: an implicitly
            // started one always; in a player's token game (not model exploration, which plays
            // what a mission run does) any other too, as bpmn-js-token-simulation plays it,
            // unless the player holds it (then it waits for the player, and a message that
            // comes meanwhile is lost, as anywhere) or it also sends one — the simulator then
            // takes its messages in the drawing's order, left to right, which the engine does
            // not keep; such a task sends when it is left.
            // The cheap tests first: model exploration scans no message flows for a task
            // entered along a sequence flow.
            let id = &self.g.node(node).id;
            let implicit = self.g.node(node).incoming.is_empty();
            let flows = || self.g.collaborations.iter().flat_map(|c| &c.message_flows);
            let messaged = (implicit || !(game.decide || game.hold.contains(&node)))
                && flows().any(|m| &m.target == id)
                && (implicit || !flows().any(|m| &m.source == id));
            if messaged {
                self.subscribe(t, node, On::Message(String::new(), None));
                if let Some(tok) = self.s.tokens.get_mut(&t) {
                    tok.at = At::Catching;
                }
                return;
            }
            if !game.hold.contains(&node) {
                return self.complete_activity(t);
            }
            return self.dispatch(t, None);
        }
        match task.kind {
            TaskKind::User => {
                // The operator sees the visible variables and the task's declared inputs.
                let mut context = self.visible_vars(scope);
                match self.task_data_inputs(t) {
                    Ok(d) => context.extend(d.unwrap_or_default()),
                    Err(e) => return self.incident(t, e),
                }
                if let Some(b) = &task.binding {
                    match self.task_inputs(t, b, context) {
                        Some(c) => context = c,
                        None => return,
                    }
                }
                let key = self.next_key(t);
                if let Some(tok) = self.s.tokens.get_mut(&t) {
                    tok.at = At::UserTask(key);
                }
                self.record(instance, || Entry::Opened { task: key, node });
                if let Some(tok) = self.s.tokens.get_mut(&t) {
                    tok.goal = crate::state::goal(&context);
                }
                self.out.push(Action::OpenUserTask {
                    task: key,
                    node,
                    context,
                });
            }
            TaskKind::Receive => {
                let name = self.message_name(task.message);
                self.subscribe(t, node, On::Message(name, None));
                if let Some(tok) = self.s.tokens.get_mut(&t) {
                    tok.at = At::Catching;
                }
            }
            TaskKind::Script
                if task
                    .script
                    .as_ref()
                    .is_some_and(|s| s.assignments.is_some()) =>
            {
                let assignments = task
                    .script
                    .as_ref()
                    .and_then(|s| s.assignments.as_ref())
                    .map(Vec::as_slice)
                    .unwrap_or_default();
                for (name, expr) in assignments {
                    match self.eval(scope, expr, &mut Vars::new()) {
                        Ok(v) => self.set_var(scope, name, v),
                        Err(e) => return self.incident(t, format!("script: {e}")),
                    }
                }
                self.complete_activity(t);
            }
            TaskKind::Script | TaskKind::Service | TaskKind::BusinessRule | TaskKind::Send
                if task.binding.as_ref().is_some_and(|b| b.resource.is_some())
                    || task.kind == TaskKind::Script
                    || (task.kind != TaskKind::Send && task.binding.is_some()) =>
            {
                self.dispatch(t, task.binding.as_ref());
            }
            TaskKind::Send => {
                let name = self.message_name(task.message);
                let payload = self.visible_vars(scope);
                self.send_message(instance, Some(node), scope, name, payload);
                self.complete_activity(t);
            }
            TaskKind::Service | TaskKind::BusinessRule => self.dispatch(t, None),
            TaskKind::Script | TaskKind::Manual | TaskKind::Plain => self.complete_activity(t),
        }
    }

    fn next_key(&mut self, t: TokenId) -> crate::io::TaskKey {
        let tok = self.s.tokens.get_mut(&t).expect("token exists");
        tok.attempts += 1;
        crate::io::TaskKey {
            instance: tok.instance,
            token: t,
            attempt: tok.attempts,
        }
    }

    /// A task's declared inputs evaluated over `into`; a failing input fails the task with
    /// `TYPE_MISMATCH` (and gives `None`).
    fn task_inputs(
        &mut self,
        t: TokenId,
        b: &executive_model::binding::TaskBinding,
        mut into: Vars,
    ) -> Option<Vars> {
        let tok = &self.s.tokens[&t];
        let (scope, node) = (tok.scope, tok.node);
        for m in &b.inputs {
            // Earlier targets first, then the scope (as in `call_inputs`).
            let value = eval::eval(
                &m.source,
                self.now,
                &|n| into.get(n).cloned().or_else(|| self.lookup(scope, n)),
                &mut Vars::new(),
            )
            .and_then(|v| match &m.ty {
                Some(ty) => eval::convert(v, ty),
                None => Ok(v),
            });
            match value {
                Ok(v) => eval::set_path(&mut into, &m.target, v),
                Err(e) => {
                    let message = format!(
                        "input `{}` of `{}`: {e}",
                        m.target,
                        self.g.node(node).label()
                    );
                    self.task_error(t, "TYPE_MISMATCH", &message);
                    return None;
                }
            }
        }
        Some(into)
    }

    fn dispatch(&mut self, t: TokenId, binding: Option<&executive_model::binding::TaskBinding>) {
        let tok = &self.s.tokens[&t];
        let (scope, node, instance) = (tok.scope, tok.node, tok.instance);
        // A `trace:task` declares its goal exactly (no inputs: an empty goal); the other
        // dialects pass every visible variable when they map none, as their engines do.
        // A declared ioSpecification is an exact interface too: its data inputs, by name.
        let data = match self.task_data_inputs(t) {
            Ok(d) => d,
            Err(e) => return self.incident(t, e),
        };
        let request = match (
            binding.filter(|b| {
                !b.inputs.is_empty() || b.dialect == executive_model::binding::Dialect::Trace
            }),
            data,
        ) {
            (None, None) => self.visible_vars(scope),
            (None, Some(d)) => d,
            (Some(b), d) => match self.task_inputs(t, b, d.unwrap_or_default()) {
                Some(request) => request,
                None => return,
            },
        };
        let key = self.next_key(t);
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Task(key);
        }
        self.record(instance, || Entry::Dispatched {
            task: key,
            node,
            request: request.clone(),
        });
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.goal = crate::state::goal(&request);
        }
        self.out.push(Action::DispatchTask {
            task: key,
            node,
            request,
        });
    }

    /// Every variable visible from a scope (inner ones win), without system data.
    pub(crate) fn visible_vars(&self, scope: ScopeId) -> Vars {
        // Innermost first: a name already taken by an inner scope is skipped.
        let mut out = Vars::new();
        let mut cur = Some(scope);
        while let Some(id) = cur {
            let Some(sc) = self.s.scopes.get(&id) else {
                break;
            };
            if sc.vars.is_empty() {
                // Nothing to add (and nothing to drop or clone).
            } else if out.is_empty() {
                out.clone_from(&sc.vars);
            } else {
                for (k, v) in &sc.vars {
                    if !out.contains_key(k) {
                        out.insert(k.clone(), v.clone());
                    }
                }
            }
            if matches!(sc.kind, ScopeKind::Process(_)) {
                break;
            }
            cur = sc.parent;
        }
        out
    }

    pub(crate) fn message_name(&self, m: Option<executive_model::MessageId>) -> String {
        m.map(|m| self.g.messages[m.index()].name.clone())
            .unwrap_or_default()
    }

    /// Exploring a model without data ([`crate::Game::decide`]): no mapping is evaluated.
    pub(crate) fn decides(&self) -> bool {
        self.game.is_some_and(|g| g.decide)
    }

    /// Applies a task's result: declared outputs, or every field when none is declared.
    pub(crate) fn apply_outputs(&mut self, t: TokenId, output: &Vars) -> Result<(), String> {
        if self.decides() {
            return Ok(());
        }
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (scope, node) = (tok.scope, tok.node);
        let binding = match &g.node(node).kind {
            NodeKind::Task(task) => task.binding.as_ref(),
            NodeKind::CallActivity(c) => match &c.called {
                Some(executive_model::Called::GlobalTask(id)) => {
                    g.global_tasks.get(id).and_then(|t| t.binding.as_ref())
                }
                _ => c.binding.as_ref(),
            },
            _ => None,
        };
        let data_out = self.has_data_outputs(node);
        match binding.filter(|b| !b.outputs.is_empty()) {
            // Declared data outputs: only they come back, through their associations.
            None if data_out => {}
            None => {
                for (k, v) in output {
                    self.set_var(scope, k, v.clone());
                }
            }
            Some(b) => {
                // An output mapping sees the targets of the mappings before it, then the
                // result's fields, then the scope's variables (Camunda sets the result as local
                // variables of the task, then applies the output mappings).
                let mut done = Vars::new();
                for m in &b.outputs {
                    let v = eval::eval(
                        &m.source,
                        self.now,
                        &|n| {
                            done.get(n)
                                .or_else(|| output.get(n))
                                .cloned()
                                .or_else(|| self.lookup(scope, n))
                        },
                        &mut Vars::new(),
                    )
                    .and_then(|v| match &m.ty {
                        Some(ty) => eval::convert(v, ty),
                        None => Ok(v),
                    })
                    .map_err(|e| format!("output `{}`: {e}", m.target))?;
                    eval::set_path(&mut done, &m.target, v.clone());
                    self.set_var(scope, &m.target, v);
                }
            }
        }
        if data_out {
            self.copy_outputs(node, scope, output)?;
        }
        Ok(())
    }

    /// The activity's work is done: register compensation, drop boundaries, leave.
    pub(crate) fn complete_activity(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope, body) = (tok.node, tok.scope, tok.body);
        if body {
            // One body of a loop: its scope ends, and the loop decides what follows.
            self.consume(t);
            return;
        }
        // (A sub-process registers itself, with its inner activities, when its scope ends.)
        if g.node(node).compensation_handler.is_some()
            && !matches!(g.node(node).kind, NodeKind::SubProcess(_))
            && let Some(sc) = self.s.scopes.get_mut(&scope)
        {
            sc.compensable.push(crate::state::Compensable {
                node,
                inner: thin_vec::ThinVec::new(),
            });
        }
        self.drop_waits(t);
        // The result just written may make a condition true: that event occurs now, before the
        // token moves on (an interrupting one may withdraw this token with its scope).
        self.conditions();
        if !self.s.tokens.contains_key(&t) {
            return;
        }
        self.leave(t);
    }

    /// Leaves the token's node along its outgoing flows (none: the token is consumed).
    pub(crate) fn leave(&mut self, t: TokenId) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node_id, scope, instance) = (tok.node, tok.scope, tok.instance);
        let node = g.node(node_id);
        if self.trace_moves {
            self.record(instance, || Entry::Left {
                node: node_id,
                token: t,
            });
        }
        // A token game passes a message along every message flow drawn from an element
        // without a message definition of its own (message throwers send when they throw).
        if self.game.is_some() && !sends_message(&node.kind) {
            self.along_message_flows(node_id, "", None, &Vars::new());
            if !self.s.tokens.contains_key(&t) {
                return;
            }
        }
        let flows = match self.outgoing(t, node_id, scope) {
            Ok(f) => f,
            Err(e) => return self.incident(t, e),
        };
        self.take(t, &flows, node.completion_quantity);
    }

    /// Moves the token along `flows` (copies for the others); no flow consumes it.
    pub(crate) fn take(&mut self, t: TokenId, flows: &[FlowId], quantity: u32) {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (scope, instance) = (tok.scope, tok.instance);
        if flows.is_empty() {
            self.consume(t);
            return;
        }
        let mut first = true;
        for &f in flows {
            for _ in 0..quantity.max(1) {
                if self.trace_moves {
                    self.record(instance, || Entry::Took { flow: f });
                }
                let target = g.flow(f).target;
                if first {
                    first = false;
                    if let Some(tok) = self.s.tokens.get_mut(&t) {
                        tok.node = target;
                        tok.via = Some(f);
                        tok.at = At::Ready;
                        tok.body = false;
                        tok.goal = None;
                    }
                    self.ready.push_back((t, self.wave + 1));
                } else {
                    self.spawn(scope, target, Some(f));
                }
            }
        }
    }

    /// The flows leaving a node that is not a gateway: conditional flows whose condition holds,
    /// unconditional ones, and the default only when no condition held.
    fn outgoing(
        &mut self,
        t: TokenId,
        node_id: NodeId,
        scope: ScopeId,
    ) -> Result<Cow<'a, [FlowId]>, String> {
        let g = self.g;
        let node = g.node(node_id);
        if node.outgoing.iter().all(|f| g.flow(*f).condition.is_none()) {
            return Ok(Cow::Borrowed(&node.outgoing));
        }
        let mut taken = Vec::new();
        let mut read = Vars::new();
        let mut any_condition = false;
        for &f in &node.outgoing {
            if Some(f) == node.default_flow {
                continue;
            }
            match &g.flow(f).condition {
                None => taken.push(f),
                Some(c) => {
                    if self.condition(scope, c, &mut read)? {
                        any_condition = true;
                        taken.push(f);
                    }
                }
            }
        }
        if !any_condition && let Some(d) = node.default_flow {
            taken.push(d);
        }
        let instance = self.s.tokens[&t].instance;
        self.record(instance, || Entry::Decided {
            node: node_id,
            flows: taken.clone(),
            read,
        });
        if taken.is_empty() {
            return Err(format!(
                "no outgoing flow of `{}` could be taken",
                node.label()
            ));
        }
        Ok(Cow::Owned(taken))
    }

    /// The token waits at its node's join.
    pub(crate) fn park(&mut self, t: TokenId) {
        let Some(tok) = self.s.tokens.get_mut(&t) else {
            return;
        };
        tok.at = At::Joining;
        let key = (tok.scope, tok.node);
        self.s.joining.entry(key).or_default().insert(t);
    }

    /// The token no longer waits at a join (it fired, was merged, or was withdrawn).
    pub(crate) fn unpark(&mut self, t: TokenId) {
        self.s.joins.remove(&t);
        let Some(tok) = self.s.tokens.get(&t) else {
            return;
        };
        let key = (tok.scope, tok.node);
        if let Some(set) = self.s.joining.get_mut(&key) {
            set.remove(&t);
            if set.is_empty() {
                self.s.joining.remove(&key);
            }
        }
    }

    /// Removes a token that has finished (or was merged at a join); its scope may complete.
    pub(crate) fn consume(&mut self, t: TokenId) {
        self.drop_waits(t);
        self.unpark(t);
        let Some(tok) = self.s.tokens.remove(&t) else {
            return;
        };
        let scope = tok.scope;
        if let Some(run) = tok.compensating {
            self.compensation_step(scope, *run);
        }
        let Some(sc) = self.s.scopes.get_mut(&scope) else {
            return;
        };
        sc.tokens.remove(&t);
        if sc.tokens.is_empty() && !sc.ending {
            self.complete_scope(scope);
        }
    }

    /// Removes a token's subscriptions (boundaries, catch events).
    pub(crate) fn drop_waits(&mut self, t: TokenId) {
        let Some(tok) = self.s.tokens.get_mut(&t) else {
            return;
        };
        let waits = std::mem::take(&mut tok.waits);
        for w in waits {
            self.unsubscribe(w);
        }
    }

    /// Removes one subscription, cancelling its timer.
    pub(crate) fn unsubscribe(&mut self, w: WaitId) {
        if let Some(wait) = self.s.waits.remove(&w)
            && let On::Timer { key, .. } = wait.on
        {
            self.out.push(Action::CancelTimer { timer: key });
        }
    }

    /// Tokens in a scope, in id order.
    pub(crate) fn tokens_in(&self, scope: ScopeId) -> Vec<TokenId> {
        self.s
            .scopes
            .get(&scope)
            .map(|s| s.tokens.iter().copied().collect())
            .unwrap_or_default()
    }

    /// The nodes a scope starts at: its none start events, and every other node without
    /// incoming flow (implicit start: activities, gateways, throw and end events; not boundary
    /// events, link catch events, compensation handlers or event sub-processes).
    pub(crate) fn start_nodes(&self, scope: Scope) -> Vec<NodeId> {
        let g = self.g;
        g.scope_nodes(scope)
            .iter()
            .copied()
            .filter(|n| match &g.node(*n).kind {
                NodeKind::Start(s) => s.triggers.is_empty(),
                _ => false,
            })
            .chain(self.implicit_starts(scope))
            .collect()
    }

    /// Nodes of a scope that start without a start event (no incoming flow).
    pub(crate) fn implicit_starts(&self, scope: Scope) -> Vec<NodeId> {
        implicit_starts(self.g, scope)
    }

    /// Joins (inclusive, complex) waiting for tokens that can no longer come: fire them.
    fn joins(&mut self) -> bool {
        if self.s.joins.is_empty() {
            return false;
        }
        let waiting: Vec<TokenId> = self.s.joins.iter().copied().collect();
        let mut fired = false;
        // Gateways whose join was found waiting this round: every token waiting there sees the
        // same tokens that may still come, so one answer holds for all of them (asking each
        // made a wide inclusive join cost the cube of its branches).
        let mut held: BTreeSet<(ScopeId, NodeId)> = BTreeSet::new();
        for t in waiting {
            let Some(tok) = self.s.tokens.get(&t).filter(|t| t.at == At::Joining) else {
                continue;
            };
            let at = (tok.scope, tok.node);
            let gateway = matches!(self.g.node(tok.node).kind, NodeKind::Gateway(_));
            if gateway && held.contains(&at) {
                continue;
            }
            if self.try_join(t) {
                fired = true;
            } else if gateway && self.s.tokens.get(&t).is_some_and(|t| t.at == At::Joining) {
                held.insert(at);
            }
        }
        fired
    }

    /// Re-evaluates conditional subscriptions; fires those that became true.
    fn conditions(&mut self) -> bool {
        let g = self.g;
        let waits: Vec<(WaitId, ScopeId, NodeId, usize, bool)> = self
            .s
            .waits
            .iter()
            .filter_map(|(id, w)| match w.on {
                On::Condition { trigger, last } => Some((*id, w.scope, w.node, trigger, last)),
                _ => None,
            })
            .collect();
        let mut fired = false;
        for (w, scope, node, trigger, last) in waits {
            if !self.s.waits.contains_key(&w) {
                continue;
            }
            let Some(EventDefinition::Conditional(expr)) = triggers_of(g, node).get(trigger) else {
                continue;
            };
            // The condition of a waiting token reads its own scope.
            let scope = self.s.waits[&w]
                .token
                .and_then(|t| self.s.tokens.get(&t))
                .map_or(scope, |t| t.scope);
            let now = self
                .condition(scope, expr, &mut Vars::new())
                .unwrap_or(false);
            if let Some(On::Condition { last: l, .. }) = self.s.waits.get_mut(&w).map(|w| &mut w.on)
            {
                *l = now;
            }
            if now && !last {
                fired = true;
                self.trigger(w, Trigger::Condition, expr.source.clone(), &Vars::new());
            }
        }
        fired
    }

    /// Conditional start events of executable top-level processes, over system data (the only
    /// data they can read, so only `DataChanged` re-evaluates them): each one
    /// whose condition turned true starts a new instance (§13.5.1; it must turn false and then
    /// true again before it starts another).
    pub(crate) fn start_conditions(&mut self) {
        let g = self.g;
        for (i, p) in g.processes.iter().enumerate() {
            if !p.executable || p.imported {
                continue;
            }
            for &n in &p.nodes {
                let NodeKind::Start(st) = &g.node(n).kind else {
                    continue;
                };
                for d in &st.triggers {
                    let EventDefinition::Conditional(expr) = d else {
                        continue;
                    };
                    let now = eval::condition(
                        expr,
                        self.now,
                        &|k| self.s.data.get(k).cloned(),
                        &mut Vars::new(),
                    )
                    .unwrap_or(false);
                    let was = if now {
                        !self.s.start_conditions.insert(n)
                    } else {
                        self.s.start_conditions.remove(&n)
                    };
                    if now && !was {
                        let process = executive_model::ProcessId(i as u32);
                        self.start_instance_at(
                            process,
                            n,
                            Vars::new(),
                            Trigger::Condition,
                            &expr.source,
                        );
                    }
                }
            }
        }
    }
}

/// The event definitions a catching node reacts to.
pub(crate) fn triggers_of(g: &ProcessGraph, node: NodeId) -> &[EventDefinition] {
    match &g.node(node).kind {
        NodeKind::Start(s) => &s.triggers,
        NodeKind::Catch(c) => &c.triggers,
        NodeKind::Boundary(b) => &b.triggers,
        _ => &[],
    }
}

/// Whether a node sends its message when it throws (message throw or end event); in a token
/// game every other node, send tasks included, passes messages on when it is left.
fn sends_message(kind: &NodeKind) -> bool {
    match kind {
        NodeKind::Throw(defs) | NodeKind::End(defs) => defs
            .iter()
            .any(|d| matches!(d, EventDefinition::Message(_))),
        _ => false,
    }
}

/// The resource a task is dispatched to: its binding's resource, else a script task's script
/// (run by a connector), else its element id. A call activity that calls a global task is
/// dispatched as that task. The engine's dispatches name the node only; the adapters that give
/// the command or write the record read its resource here, from the model.
pub fn resource(g: &ProcessGraph, node: NodeId) -> &str {
    let n = g.node(node);
    let task = match &n.kind {
        NodeKind::Task(task) => Some(task),
        NodeKind::CallActivity(call) => match &call.called {
            Some(executive_model::Called::GlobalTask(id)) => g.global_tasks.get(id),
            _ => None,
        },
        _ => None,
    };
    task.and_then(|t| {
        let bound = t.binding.as_ref().and_then(|b| b.resource.as_deref());
        bound.or(t.script.as_ref().map(|s| s.text.as_str()))
    })
    .unwrap_or(&n.id)
}

/// Nodes of a scope that start with it without a start event: every node without incoming flow
/// but start and boundary events, link catch events, compensation handlers and event
/// sub-processes (BPMN 2.0.2 §13.2.2, implicit start).
pub fn implicit_starts(g: &ProcessGraph, scope: Scope) -> Vec<NodeId> {
    g.scope_nodes(scope)
            .iter()
            .copied()
            .filter(|n| {
                let node = g.node(*n);
                node.incoming.is_empty()
                    && !node.for_compensation
                    && !matches!(node.kind, NodeKind::Start(_) | NodeKind::Boundary(_))
                    && !matches!(&node.kind, NodeKind::Catch(c) if c.triggers.iter().any(|d| matches!(d, EventDefinition::Link(_))))
                    && !matches!(&node.kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event))
            })
            .collect()
}
