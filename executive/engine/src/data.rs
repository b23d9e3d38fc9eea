//! Data associations (BPMN 2.0.2 §10.4.1, §10.4.2, §13.3.2): an activity's data inputs are
//! filled from its scope before it starts (it waits while no InputSet is available), and its
//! data outputs are copied back when it completes.

use executive_model::{DataAssociation, DataIo, DataRef, IoSet, Looping, NodeId, NodeKind};

use crate::eval;
use crate::io::{Entry, ScopeId, TokenId};
use crate::run::Run;
use crate::state::{At, ScopeKind};
use crate::value::{Value, Vars};

/// What running one data association gives.
enum Copied {
    /// A source is unavailable: the association cannot run.
    Unavailable,
    /// The target's new value (`None`: nothing was copied).
    Value(Option<Value>),
}

/// Every data input (output) required: the set assumed when the ioSpecification names none.
fn every(n: usize) -> IoSet {
    IoSet {
        refs: (0..n).collect(),
        optional: Vec::new(),
    }
}

impl Run<'_> {
    fn data_io(&self, node: NodeId) -> Option<&DataIo> {
        self.g.node(node).data.as_deref()
    }

    /// Does `kind` (a sub-process instance) declare the data object or property `name`?
    pub(crate) fn declares(&self, kind: &ScopeKind, name: &str) -> bool {
        let ScopeKind::SubProcess(n) = kind else {
            return false;
        };
        matches!(&self.g.node(*n).kind, NodeKind::SubProcess(sp)
            if sp.data_objects.iter().any(|d| d.name.as_deref().unwrap_or(&d.id) == name))
    }

    fn source(&self, scope: ScopeId, r: &DataRef, io: &DataIo, known: &Vars) -> Option<Value> {
        match r {
            DataRef::Variable(n) => known.get(n).cloned().or_else(|| self.lookup(scope, n)),
            DataRef::Store(n) => self.s.data.get(n).cloned(),
            DataRef::Output(i) => known.get(&io.outputs[*i].name).cloned(),
            DataRef::Input(_) => None,
        }
    }

    /// Runs one association (§10.4.1, Execution Semantics for DataAssociation): the
    /// transformation replaces the target; then each assignment writes `from` where `to` points;
    /// with neither, the single source is copied. `known` holds values read before the scope
    /// (data outputs, a multi-instance item).
    fn run_association(
        &self,
        scope: ScopeId,
        a: &DataAssociation,
        io: &DataIo,
        known: &Vars,
        target: &str,
        current: Option<Value>,
    ) -> Result<Copied, String> {
        let mut values = Vec::new();
        for s in &a.sources {
            match self.source(scope, s, io, known) {
                Some(v) => values.push(v),
                None => return Ok(Copied::Unavailable),
            }
        }
        let lookup = |n: &str| known.get(n).cloned().or_else(|| self.lookup(scope, n));
        let mut value = match &a.transformation {
            Some(e) => Some(eval::eval(e, self.now, &lookup, &mut Vars::new())?),
            None if a.assignments.is_empty() && values.len() == 1 => values.pop(),
            None => current,
        };
        for (from, to) in &a.assignments {
            let v = eval::eval(from, self.now, &lookup, &mut Vars::new())?;
            // `to` names the target (or a path inside it); any other path is inside the target.
            let path = if to == target || to.starts_with(&format!("{target}.")) {
                to.clone()
            } else {
                format!("{target}.{to}")
            };
            let mut holder = Vars::new();
            if let Some(cur) = value.take() {
                holder.insert(target.to_owned(), cur);
            }
            eval::set_path(&mut holder, &path, v);
            value = holder.remove(target);
        }
        Ok(Copied::Value(value))
    }

    /// §10.4.2: the data inputs of activity `node` seen from `scope` (`known` read first): the
    /// first InputSet, in order, whose required inputs' associations can all run. `Ok(None)`: no
    /// InputSet is available.
    fn fill_inputs(
        &self,
        node: NodeId,
        scope: ScopeId,
        known: &Vars,
    ) -> Result<Option<Vars>, String> {
        let Some(io) = self.data_io(node).filter(|io| !io.inputs.is_empty()) else {
            return Ok(Some(Vars::new()));
        };
        let all = [every(io.inputs.len())];
        let sets = if io.input_sets.is_empty() {
            &all[..]
        } else {
            &io.input_sets[..]
        };
        'sets: for set in sets {
            let mut filled = Vars::new();
            for &i in &set.refs {
                let name = &io.inputs[i].name;
                let mut value = None;
                for a in &io.input_associations {
                    if a.target != Some(DataRef::Input(i)) {
                        continue;
                    }
                    match self.run_association(scope, a, io, known, name, value.take())? {
                        Copied::Value(v) => value = v,
                        Copied::Unavailable if set.optional.contains(&i) => {
                            value = None;
                            break;
                        }
                        Copied::Unavailable => continue 'sets,
                    }
                }
                if let Some(v) = value {
                    filled.insert(name.clone(), v);
                }
            }
            return Ok(Some(filled));
        }
        Ok(None)
    }

    /// What the activity-level check may take for granted: a multi-instance activity's input
    /// item exists in each instance.
    fn loop_items(&self, node: NodeId) -> Vars {
        match &self.g.node(node).looping {
            Some(Looping::MultiInstance(mi)) => mi
                .input_element
                .iter()
                .map(|n| (n.clone(), Value::Null))
                .collect(),
            _ => Vars::new(),
        }
    }

    /// The data inputs of the activity of token `t`, filled in the token's scope; `Ok(None)` when
    /// the activity declares none.
    pub(crate) fn task_data_inputs(&self, t: TokenId) -> Result<Option<Vars>, String> {
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        if self.data_io(node).is_none_or(|io| io.inputs.is_empty()) || self.decides() {
            return Ok(None);
        }
        match self.fill_inputs(node, scope, &Vars::new())? {
            Some(v) => Ok(Some(v)),
            None => Err(format!(
                "no input set of `{}` is available",
                self.g.node(node).label()
            )),
        }
    }

    /// The data inputs of the looping activity of token `t` (for its input collection).
    pub(crate) fn loop_data_inputs(&self, t: TokenId) -> Vars {
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        let items = self.loop_items(node);
        self.fill_inputs(node, scope, &items)
            .ok()
            .flatten()
            .unwrap_or_default()
    }

    /// §13.3.2: the activity of token `t` becomes active once one of its InputSets is available;
    /// until then it waits at its node (boundary events armed), re-checked after every step.
    pub(crate) fn activate(&mut self, t: TokenId) {
        let tok = &self.s.tokens[&t];
        let (node, scope, body) = (tok.node, tok.scope, tok.body);
        let has_inputs = self.data_io(node).is_some_and(|io| !io.inputs.is_empty());
        if has_inputs && !body && !self.decides() {
            let items = self.loop_items(node);
            match self.fill_inputs(node, scope, &items) {
                Ok(Some(_)) => {}
                Ok(None) => {
                    if let Some(tok) = self.s.tokens.get_mut(&t) {
                        tok.at = At::Joining;
                    }
                    self.s.joins.insert(t);
                    return;
                }
                Err(e) => return self.incident(t, e),
            }
        }
        if self.g.node(node).looping.is_some() && !body {
            self.start_loop(t);
        } else {
            self.start_activity(t);
        }
    }

    /// A waiting activity is checked again; returns whether it started (or became an incident).
    pub(crate) fn retry_activation(&mut self, t: TokenId) -> bool {
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        let items = self.loop_items(node);
        if matches!(self.fill_inputs(node, scope, &items), Ok(None)) {
            return false;
        }
        self.unpark(t);
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Ready;
        }
        self.activate(t);
        true
    }

    /// Does the activity copy data outputs back (§13.3.2)?
    pub(crate) fn has_data_outputs(&self, node: NodeId) -> bool {
        self.data_io(node)
            .is_some_and(|io| !io.outputs.is_empty() || !io.output_associations.is_empty())
    }

    /// §13.3.2: on completion, the first OutputSet whose required data outputs are in `result`
    /// is chosen and the output associations of its data outputs run. Err: no OutputSet is
    /// available (the activity ends with an exception).
    pub(crate) fn copy_outputs(
        &mut self,
        node: NodeId,
        scope: ScopeId,
        result: &Vars,
    ) -> Result<(), String> {
        let Some(io) = self.data_io(node) else {
            return Ok(());
        };
        let outputs: Vars = io
            .outputs
            .iter()
            .filter_map(|p| result.get(&p.name).map(|v| (p.name.clone(), v.clone())))
            .collect();
        let all = [every(io.outputs.len())];
        let sets = if io.output_sets.is_empty() {
            &all[..]
        } else {
            &io.output_sets[..]
        };
        let available = |s: &&IoSet| {
            s.refs
                .iter()
                .all(|i| s.optional.contains(i) || outputs.contains_key(&io.outputs[*i].name))
        };
        let Some(set) = sets.iter().find(available) else {
            let missing: Vec<&str> = sets[0]
                .refs
                .iter()
                .map(|i| io.outputs[*i].name.as_str())
                .filter(|n| !outputs.contains_key(*n))
                .collect();
            return Err(format!(
                "no output set is available: the result lacks {}",
                missing.join(", ")
            ));
        };
        let mut writes = Vec::new();
        for a in &io.output_associations {
            // Only the associations of the chosen set's data outputs run.
            if a.sources
                .iter()
                .any(|s| matches!(s, DataRef::Output(i) if !set.refs.contains(i)))
            {
                continue;
            }
            let (name, store) = match &a.target {
                Some(DataRef::Variable(n)) => (n, false),
                Some(DataRef::Store(n)) => (n, true),
                _ => continue,
            };
            let current = if store {
                self.s.data.get(name).cloned()
            } else {
                self.lookup(scope, name)
            };
            if let Copied::Value(Some(v)) =
                self.run_association(scope, a, io, &outputs, name, current)?
            {
                writes.push((name.clone(), store, v));
            }
        }
        for (name, store, v) in writes {
            if store {
                let instance = self.s.scopes[&scope].instance;
                self.s.data.insert(name.clone(), v.clone());
                self.record(instance, || Entry::Data {
                    key: name,
                    value: v,
                });
            } else {
                self.set_var(scope, &name, v);
            }
        }
        Ok(())
    }
}
