//! Gateways: exclusive, parallel, inclusive (with the non-local join rule), complex and
//! event-based.

use std::collections::BTreeSet;

use executive_model::{FlowId, Gateway, GatewayKind, NodeId, NodeKind, ProcessGraph};

use crate::io::{Entry, TokenId};
use crate::run::Run;
use crate::state::At;
use crate::value::{Value, Vars};

/// Whether a token at `gateway` waits for its branch to be chosen when the engine explores
/// (`Game::decide`): a diverging exclusive gateway, or an inclusive or complex one that does
/// not join.
pub fn chosen_from_outside(g: &ProcessGraph, gateway: NodeId) -> bool {
    let n = g.node(gateway);
    match &n.kind {
        NodeKind::Gateway(gw) => {
            n.outgoing.len() > 1
                && match gw.kind {
                    GatewayKind::Exclusive => true,
                    GatewayKind::Inclusive | GatewayKind::Complex => n.incoming.len() <= 1,
                    _ => false,
                }
        }
        _ => false,
    }
}

impl Run<'_> {
    /// A token arrives at a gateway.
    pub(crate) fn gateway(&mut self, t: TokenId, gw: &Gateway) {
        let g = self.g;
        let node = self.s.tokens[&t].node;
        let n = g.node(node);
        let decides = self.game.is_some_and(|g| g.decide)
            && chosen_from_outside(g, node)
            // A branch fixed before the step is taken as the token arrives.
            && !self.game.is_some_and(|g| g.fixed.contains_key(&node));
        if decides {
            if let Some(tok) = self.s.tokens.get_mut(&t) {
                tok.at = At::Deciding;
            }
            return;
        }
        if self.game.is_some_and(|g| g.decide)
            && n.outgoing.len() == 1
            && gw.kind == GatewayKind::Exclusive
        {
            let out = n.outgoing.clone();
            return self.leave_gateway(t, &out);
        }
        match gw.kind {
            GatewayKind::Exclusive => match self.choose(t, node, false) {
                Ok(flows) => self.leave_gateway(t, &flows),
                Err(e) => self.incident(t, e),
            },
            GatewayKind::Parallel => {
                if n.incoming.len() > 1 && !self.parallel_join(t) {
                    return;
                }
                let out = n.outgoing.clone();
                self.leave_gateway(t, &out);
            }
            GatewayKind::Inclusive | GatewayKind::Complex => {
                if n.incoming.len() > 1 {
                    self.park(t);
                    self.s.joins.insert(t);
                    self.try_join(t);
                } else {
                    self.split(t);
                }
            }
            GatewayKind::EventBased { .. } => self.event_gateway(t),
        }
    }

    pub(crate) fn leave_gateway(&mut self, t: TokenId, flows: &[FlowId]) {
        if self.trace_moves {
            let tok = &self.s.tokens[&t];
            let (instance, node) = (tok.instance, tok.node);
            self.record(instance, || Entry::Left { node, token: t });
        }
        self.take(t, flows, 1);
    }

    fn split(&mut self, t: TokenId) {
        let node = self.s.tokens[&t].node;
        match self.choose(t, node, true) {
            Ok(flows) => self.leave_gateway(t, &flows),
            Err(e) => self.incident(t, e),
        }
    }

    /// The flows a diverging gateway takes: the first whose condition holds (`all`: every one),
    /// else the default flow. A single unconditional flow is simply taken.
    fn choose(&mut self, t: TokenId, node: NodeId, all: bool) -> Result<Vec<FlowId>, String> {
        let g = self.g;
        let n = g.node(node);
        if n.outgoing.len() == 1 && g.flow(n.outgoing[0]).condition.is_none() {
            return Ok(n.outgoing.clone());
        }
        if let Some(game) = self.game {
            let unconditioned = n.outgoing.iter().all(|f| g.flow(*f).condition.is_none());
            if let Some(chosen) = game.fixed.get(&node).or_else(|| game.choices.get(&node)) {
                return Ok(n
                    .outgoing
                    .iter()
                    .copied()
                    .filter(|f| chosen.contains(f))
                    .collect());
            }
            if (unconditioned && n.outgoing.len() > 1) || n.outgoing.is_empty() {
                // Nobody chose a branch (or there is none): the token stops here.
                return Ok(Vec::new());
            }
        }
        let scope = self.s.tokens[&t].scope;
        let mut read = Vars::new();
        let mut taken = Vec::new();
        for &f in &n.outgoing {
            if Some(f) == n.default_flow {
                continue;
            }
            let ok = match &g.flow(f).condition {
                None => true,
                Some(c) => self.condition(scope, c, &mut read)?,
            };
            if ok {
                taken.push(f);
                if !all {
                    break;
                }
            }
        }
        if taken.is_empty()
            && let Some(d) = n.default_flow
        {
            taken.push(d);
        }
        let instance = self.s.tokens[&t].instance;
        self.record(instance, || Entry::Decided {
            node,
            flows: taken.clone(),
            read,
        });
        if taken.is_empty() {
            return Err(format!(
                "no condition of gateway `{}` holds and it has no default flow",
                n.label()
            ));
        }
        Ok(taken)
    }

    /// Tokens of the same scope waiting at the same join as `t`, `t` included.
    fn joining(&self, t: TokenId) -> Vec<TokenId> {
        let tok = &self.s.tokens[&t];
        let mut out: Vec<TokenId> = self
            .s
            .joining
            .get(&(tok.scope, tok.node))
            .map(|s| s.iter().copied().collect())
            .unwrap_or_default();
        if !out.contains(&t) {
            out.push(t);
        }
        out
    }

    /// A parallel join fires when a token waits on every incoming flow.
    fn parallel_join(&mut self, t: TokenId) -> bool {
        let g = self.g;
        self.park(t);
        let (node, scope) = (self.s.tokens[&t].node, self.s.tokens[&t].scope);
        // Fewer waiting tokens than incoming flows: it cannot fire yet (checked in O(1)).
        let waiting = self.s.joining.get(&(scope, node)).map_or(0, |s| s.len());
        if waiting < g.node(node).incoming.len() {
            return false;
        }
        // The first waiting token of each incoming flow; the arriving token covers its own.
        let mut by_flow: std::collections::BTreeMap<FlowId, TokenId> = Default::default();
        if let Some(f) = self.s.tokens[&t].via {
            by_flow.insert(f, t);
        }
        for o in self.joining(t) {
            if let Some(f) = self.s.tokens[&o].via {
                by_flow.entry(f).or_insert(o);
            }
        }
        let mut picked = Vec::new();
        for f in &g.node(node).incoming {
            match by_flow.get(f) {
                Some(&o) => picked.push(o),
                None => return false,
            }
        }
        for o in picked {
            if o != t {
                self.consume(o);
            }
        }
        self.unpark(t);
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Ready;
        }
        true
    }

    /// An inclusive or complex join: fire when no further token can arrive (inclusive), or when
    /// the activation condition holds (complex). Returns whether it fired or absorbed.
    pub(crate) fn try_join(&mut self, t: TokenId) -> bool {
        let g = self.g;
        let tok = &self.s.tokens[&t];
        let (node, scope) = (tok.node, tok.scope);
        let NodeKind::Gateway(gw) = &g.node(node).kind else {
            // An activity waiting for an InputSet (§13.3.2).
            return self.retry_activation(t);
        };
        let waiting = self.joining(t);
        // Incoming flows holding a token (§13.4.3: a token that can also reach one of them
        // belongs to a later activation and is not waited for).
        let filled: BTreeSet<FlowId> = waiting
            .iter()
            .filter_map(|o| self.s.tokens[o].via)
            .collect();
        let pending = self.can_arrive(scope, node, &waiting, &filled);
        if gw.kind == GatewayKind::Complex {
            if self.s.fired_complex.contains(&(scope, node)) {
                // The rest of a wave that already activated the gateway is absorbed.
                for o in waiting {
                    self.consume(o);
                }
                if !self.can_arrive(scope, node, &[], &BTreeSet::new()) {
                    self.s.fired_complex.remove(&(scope, node));
                }
                return true;
            }
            let activated = match &gw.activation {
                None => !pending,
                Some(expr) => {
                    let count = waiting.len() as i64;
                    let lookup = |n: &str| {
                        if n == "activationCount" {
                            Some(Value::Int(count))
                        } else {
                            self.lookup(scope, n)
                        }
                    };
                    match crate::eval::condition(expr, self.now, &lookup, &mut Vars::new()) {
                        Ok(b) => b,
                        Err(e) => {
                            self.unpark(t);
                            self.incident(t, e);
                            return false;
                        }
                    }
                }
            };
            if !activated {
                return false;
            }
            if pending {
                self.s.fired_complex.insert((scope, node));
            }
        } else if pending {
            return false;
        }
        // One token per incoming flow is merged; later tokens on the same flow wait for the
        // next activation.
        let mut flows = BTreeSet::new();
        if let Some(f) = self.s.tokens[&t].via {
            flows.insert(f);
        }
        for &o in &waiting {
            if o != t
                && (gw.kind == GatewayKind::Complex
                    || flows.insert(self.s.tokens[&o].via.unwrap_or(FlowId(u32::MAX))))
            {
                self.consume(o);
            }
        }
        self.unpark(t);
        if let Some(tok) = self.s.tokens.get_mut(&t) {
            tok.at = At::Ready;
        }
        self.split(t);
        true
    }

    /// Whether a token of `scope` other than `except` can still arrive at `join` on an empty
    /// incoming flow (one not in `filled`) while it cannot reach an occupied one (§13.4.3),
    /// paths not passing through `join`. A token at `join` itself (not waiting) always counts.
    fn can_arrive(
        &mut self,
        scope: crate::io::ScopeId,
        join: NodeId,
        except: &[TokenId],
        filled: &BTreeSet<FlowId>,
    ) -> bool {
        // A set: a wide join has as many waiting tokens as tokens that may come.
        let except: BTreeSet<TokenId> = except.iter().copied().collect();
        let others: BTreeSet<NodeId> = self
            .tokens_in(scope)
            .into_iter()
            .filter(|o| !except.contains(o))
            .map(|o| self.s.tokens[&o].node)
            .collect();
        others.into_iter().any(|from| {
            if from == join {
                return true;
            }
            // It may still bring a token to an empty flow (boundary events included: they can
            // fire while the activity runs), and no path of sequence flows leads it to an
            // occupied one (§13.4.3 counts only sequence flows for that exemption).
            let may = self.incoming_reached(from, join, true);
            let along_flows = self.incoming_reached(from, join, false);
            may.iter().any(|f| !filled.contains(f))
                && !along_flows.iter().any(|f| filled.contains(f))
        })
    }

    /// The incoming flows of `join` a token at `from` can reach along sequence flows and links
    /// (and, with `boundaries`, through the boundary events of the activities on the way)
    /// without passing through `join`.
    fn incoming_reached(&mut self, from: NodeId, join: NodeId, boundaries: bool) -> Vec<FlowId> {
        if let Some(r) = self.reach.get(&(from, join, boundaries)) {
            return r.clone();
        }
        let g = self.g;
        let mut seen = BTreeSet::new();
        let mut stack = vec![from];
        let mut found = BTreeSet::new();
        while let Some(n) = stack.pop() {
            if n == join || !seen.insert(n) {
                continue;
            }
            let node = g.node(n);
            for &f in &node.outgoing {
                let target = g.flow(f).target;
                if target == join {
                    found.insert(f);
                } else {
                    stack.push(target);
                }
            }
            if boundaries {
                stack.extend(node.boundaries.iter().copied());
            }
            // A link throw continues at the link catch events of its name.
            if let NodeKind::Throw(defs) = &node.kind {
                for d in defs {
                    if let executive_model::EventDefinition::Link(name) = d {
                        for &c in g.scope_nodes(node.scope) {
                            if matches!(&g.node(c).kind, NodeKind::Catch(k) if k.triggers.iter().any(|x| matches!(x, executive_model::EventDefinition::Link(l) if l == name)))
                            {
                                stack.push(c);
                            }
                        }
                    }
                }
            }
        }
        let found: Vec<FlowId> = found.into_iter().collect();
        self.reach.insert((from, join, boundaries), found.clone());
        found
    }
}
