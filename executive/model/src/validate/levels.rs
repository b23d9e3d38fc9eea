//! The checks of one process level (a process, or the inside of a sub-process): what is
//! reachable from its starts, its link pairs, its start and end events together (EXT.097,
//! EXT.105), the incoming and outgoing flows its nodes need (EXT.150, EXT.151, §10.5.4).

use std::collections::{BTreeMap, BTreeSet};

use super::Checker;
use crate::graph::*;

impl Checker<'_> {
    /// Reachability and link pairing within one scope.
    pub(super) fn scope(&mut self, scope: Scope) {
        let g = self.g;
        let nodes = g.scope_nodes(scope);
        if nodes.is_empty() {
            return;
        }
        // An event sub-process has one start event, its trigger (§10.3.5; Camunda 7 and 8
        // refuse more): with several, each starts it.
        if let Scope::SubProcess(esp) = scope
            && matches!(&g.node(esp).kind, NodeKind::SubProcess(sp) if matches!(sp.kind, SubProcessKind::Event))
        {
            let starts = nodes
                .iter()
                .filter(|m| matches!(g.node(**m).kind, NodeKind::Start(_)))
                .count();
            if starts > 1 {
                self.bent(
                    esp,
                    "event-subprocess-starts",
                    "§10.3.5",
                    format!("an event sub-process has one start event, its trigger; this one has {starts}, and each starts it"),
                );
            }
        }
        let links_thrown: BTreeSet<&str> = nodes
            .iter()
            .filter_map(|n| match &g.node(*n).kind {
                NodeKind::Throw(r) => r.iter().find_map(|d| {
                    if let EventDefinition::Link(name) = d {
                        Some(name.as_str())
                    } else {
                        None
                    }
                }),
                _ => None,
            })
            .collect();
        let mut links_caught: BTreeSet<&str> = BTreeSet::new();
        for n in nodes {
            if let NodeKind::Catch(c) = &g.node(*n).kind
                && let Some(name) = c.triggers.iter().find_map(|d| match d {
                    EventDefinition::Link(name) => Some(name.as_str()),
                    _ => None,
                })
                && !links_caught.insert(name)
            {
                // §10.5.6: a link may have several sources but only one target.
                self.report(
                    *n,
                    "ambiguous-link",
                    Some("§10.5.6"),
                    format!(
                        "a second link catch event named `{name}` in the same process level: a link throw would not know where to continue"
                    ),
                );
            }
        }
        for n in nodes {
            let node = g.node(*n);
            match &node.kind {
                NodeKind::Throw(r) => {
                    for d in r {
                        if let EventDefinition::Link(name) = d
                            && !links_caught.contains(name.as_str())
                        {
                            self.report(
                                *n,
                                "unmatched-link",
                                Some("EXT.118"),
                                format!(
                                    "no link catch event named `{name}` in the same process level"
                                ),
                            );
                        }
                    }
                }
                NodeKind::Catch(c) => {
                    for d in &c.triggers {
                        if let EventDefinition::Link(name) = d
                            && !links_thrown.contains(name.as_str())
                        {
                            self.report(
                                *n,
                                "unmatched-link",
                                Some("EXT.124"),
                                format!("no link throw event named `{name}` leads here"),
                            );
                        }
                    }
                }
                _ => {}
            }
        }
        // Entry points: start events, or (implicit start) nodes without incoming flows.
        let is_entry = |n: NodeId| {
            let node = g.node(n);
            match &node.kind {
                NodeKind::Start(_) => true,
                NodeKind::Boundary(_) => false,
                NodeKind::SubProcess(SubProcess {
                    kind: SubProcessKind::Event,
                    ..
                }) => true,
                NodeKind::Catch(c)
                    if c.triggers
                        .iter()
                        .any(|d| matches!(d, EventDefinition::Link(_))) =>
                {
                    false
                }
                _ => node.for_compensation,
            }
        };
        let has_start = nodes
            .iter()
            .any(|n| matches!(g.node(*n).kind, NodeKind::Start(_)));
        let adhoc = matches!(scope, Scope::SubProcess(s) if matches!(&g.node(s).kind, NodeKind::SubProcess(SubProcess { kind: SubProcessKind::AdHoc { .. }, .. })));
        self.scope_mark += 1;
        let (reached, mark) = (&mut self.reached, self.scope_mark);
        let mut newly_seen = |n: NodeId| {
            let first = reached[n.index()] != mark;
            reached[n.index()] = mark;
            first
        };
        // The catch events of each link name, looked up as throws are reached (a scan of the
        // scope per throw would be quadratic in the links).
        let mut link_catches: BTreeMap<&str, Vec<NodeId>> = BTreeMap::new();
        if !links_thrown.is_empty() {
            for n in nodes {
                if let NodeKind::Catch(c) = &g.node(*n).kind {
                    for t in &c.triggers {
                        if let EventDefinition::Link(l) = t {
                            link_catches.entry(l.as_str()).or_default().push(*n);
                        }
                    }
                }
            }
        }
        let mut work: Vec<NodeId> = nodes
            .iter()
            .copied()
            .filter(|n| {
                is_entry(*n)
                    || adhoc
                    || (!has_start
                        && g.node(*n).incoming.is_empty()
                        && !matches!(g.node(*n).kind, NodeKind::Boundary(_) | NodeKind::Catch(_)))
            })
            .collect();
        // Catch events without incoming flows in a scope without start events are implicit starts
        // only if they are not link targets.
        if !has_start {
            work.extend(nodes.iter().copied().filter(|n| matches!(&g.node(*n).kind, NodeKind::Catch(c) if g.node(*n).incoming.is_empty() && !c.triggers.iter().any(|d| matches!(d, EventDefinition::Link(_))))));
        }
        while let Some(n) = work.pop() {
            if !newly_seen(n) {
                continue;
            }
            let node = g.node(n);
            work.extend(node.outgoing.iter().map(|f| g.flow(*f).target));
            work.extend(node.boundaries.iter().copied());
            if let NodeKind::Throw(r) = &node.kind {
                for d in r {
                    if let EventDefinition::Link(name) = d {
                        work.extend(link_catches.get(name.as_str()).into_iter().flatten());
                    }
                }
            }
        }
        // Compensation handlers are reached through their boundary event's association.
        for n in nodes {
            if let Some(h) = g.node(*n).compensation_handler {
                newly_seen(h);
            }
        }
        // Not seen from any start: unreachable.
        let unreachable: Vec<NodeId> = nodes.iter().copied().filter(|n| newly_seen(*n)).collect();
        for n in unreachable {
            let node = g.node(n);
            let msg = format!(
                "{} `{}` can never be reached: no path leads to it from a start event, so it never runs",
                node.kind.element_name(),
                node.label()
            );
            self.bent(n, "unreachable", "EXT.150", msg);
        }
        // An intermediate event in normal flow is the target of a sequence flow (§10.5.4; a
        // link catch is entered by its throw). Where the level has start events, one without
        // is unreachable above; without them it starts the level (§13.2).
        if !has_start && !adhoc {
            for n in nodes {
                let node = g.node(*n);
                let intermediate = match &node.kind {
                    NodeKind::Catch(c) => !c
                        .triggers
                        .iter()
                        .any(|d| matches!(d, EventDefinition::Link(_))),
                    NodeKind::Throw(_) => true,
                    _ => false,
                };
                if intermediate && node.incoming.is_empty() && !node.for_compensation {
                    let msg = format!(
                        "{} `{}` has no incoming sequence flow: an intermediate event in normal flow is the target of one; without it, it starts this level",
                        node.kind.element_name(),
                        node.label()
                    );
                    self.bent(*n, "no-incoming", "§10.5.4", msg);
                }
            }
        }
        // Start and end events come together at one process level (EXT.097, EXT.105).
        let has_end = nodes.iter().any(|n| match &g.node(*n).kind {
            NodeKind::End(_) => true,
            NodeKind::Task(t) => t.ends(),
            _ => false,
        });
        let owner = match scope {
            Scope::Process(p) => (g.process(p).offset, g.process(p).id.clone()),
            Scope::SubProcess(s) => (g.node(s).offset, g.node(s).id.clone()),
        };
        if !adhoc
            && !matches!(scope, Scope::SubProcess(s) if matches!(&g.node(s).kind, NodeKind::SubProcess(SubProcess { kind: SubProcessKind::Event, .. })))
        {
            if has_end && !has_start {
                self.sink.bent(
                    "end-without-start",
                    "EXT.097",
                    owner.0,
                    Some(&owner.1),
                    "this process level has end events but no start event: it starts at every element without incoming sequence flow".to_owned(),
                );
            }
            if has_start && !has_end {
                self.sink.bent(
                    "start-without-end",
                    "EXT.105",
                    owner.0,
                    Some(&owner.1),
                    "this process level has a start event but no end event: tokens end where their path ends".to_owned(),
                );
            }
        }
        // With end events in use, every node needs an outgoing flow (EXT.151).
        if has_end {
            for n in nodes {
                let node = g.node(*n);
                let exempt = match &node.kind {
                    NodeKind::End(_) | NodeKind::Boundary(_) | NodeKind::Throw(_) => true,
                    NodeKind::Task(t) => t.ends() || node.for_compensation,
                    NodeKind::SubProcess(SubProcess {
                        kind: SubProcessKind::Event,
                        ..
                    }) => true,
                    _ => node.for_compensation,
                };
                if !exempt && node.outgoing.is_empty() {
                    let msg = format!(
                        "{} `{}` has no outgoing sequence flow although the process uses end events: its token ends here",
                        node.kind.element_name(),
                        node.label()
                    );
                    self.bent(*n, "no-outgoing", "EXT.151", msg);
                }
            }
        }
    }
}
