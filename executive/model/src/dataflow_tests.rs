//! Tests of the data-flow check before flight: one small model per way a name is written
//! (or not) before it is read, and generated models (sequences, exclusive and parallel
//! blocks) whose every read is judged against a structural oracle.

use std::collections::BTreeSet;

use crate::dataflow::{Context, Finding, Site, check};
use crate::*;

const HEAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL"
  xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:test">"#;

fn graph(body: &str) -> ProcessGraph {
    // One message, for the events that catch it.
    let xml = format!(
        r#"{HEAD}<bpmn:message id="msg" name="msg"/><bpmn:process id="p" isExecutable="true">{body}</bpmn:process></bpmn:definitions>"#
    );
    let loaded = load(xml.as_bytes());
    loaded
        .graph
        .unwrap_or_else(|| panic!("{:#?}\n{xml}", loaded.diagnostics))
}

fn findings(g: &ProcessGraph) -> Vec<Finding> {
    check(
        g,
        &Context {
            start: &BTreeSet::new(),
            results: &|_| None,
        },
    )
}

/// `(element id, variable, "unwritten" | "sometimes")` of every finding.
fn judged(g: &ProcessGraph) -> BTreeSet<(String, String, &'static str)> {
    findings(g)
        .into_iter()
        .map(|f| {
            let (site, kind) = match &f {
                Finding::Unwritten { site, .. } => (site.clone(), "unwritten"),
                Finding::Sometimes { site, .. } => (site.clone(), "sometimes"),
            };
            let id = match site {
                Site::Node(n) => g.node(n).id.clone(),
                Site::Flow(fl) => g.flow(fl).id.clone(),
            };
            (id, f.var().to_owned(), kind)
        })
        .collect()
}

fn script(id: &str, text: &str) -> String {
    format!(
        r#"<bpmn:scriptTask id="{id}" scriptFormat="cel"><bpmn:script>{text}</bpmn:script></bpmn:scriptTask>"#
    )
}

fn flow(id: &str, from: &str, to: &str) -> String {
    format!(r#"<bpmn:sequenceFlow id="{id}" sourceRef="{from}" targetRef="{to}"/>"#)
}

/// start → each element in turn → end.
fn chain(elements: &[(&str, String)]) -> ProcessGraph {
    let mut body = String::from(r#"<bpmn:startEvent id="s"/><bpmn:endEvent id="e"/>"#);
    let mut prev = "s".to_owned();
    for (i, (id, xml)) in elements.iter().enumerate() {
        body.push_str(xml);
        body.push_str(&flow(&format!("c{i}"), &prev, id));
        prev = (*id).to_owned();
    }
    body.push_str(&flow("cz", &prev, "e"));
    graph(&body)
}

#[test]
fn a_name_read_before_anything_writes_it_is_unwritten_and_the_late_writer_is_named() {
    let g = chain(&[("r", script("r", "y = x + 1")), ("w", script("w", "x = 1"))]);
    let f = findings(&g);
    assert_eq!(f.len(), 1, "{f:?}");
    let Finding::Unwritten { var, writer, .. } = &f[0] else {
        panic!("{f:?}")
    };
    assert_eq!(var, "x");
    assert_eq!(writer.map(|w| g.node(w).id.as_str()), Some("w"));
}

#[test]
fn a_cel_macro_s_own_variable_is_not_read_from_the_scope() {
    let g = chain(&[
        ("w", script("w", "sites = [1, 2]")),
        (
            "r",
            script(
                "r",
                "ok = sites.exists(s, s &gt; 1) &amp;&amp; sites.map(x, x * 2).size() &gt; 0",
            ),
        ),
    ]);
    assert!(judged(&g).is_empty(), "{:?}", judged(&g));
}

#[test]
fn a_script_s_assignments_see_the_ones_before_them() {
    let g = chain(&[("w", script("w", "x = 1\ny = x + 1"))]);
    assert!(judged(&g).is_empty());
}

#[test]
fn a_name_written_on_one_branch_of_a_choice_is_read_on_some_paths_only() {
    let body = format!(
        r#"<bpmn:startEvent id="s"/><bpmn:exclusiveGateway id="x" default="f3"/>{}
        <bpmn:exclusiveGateway id="j"/>{}<bpmn:endEvent id="e"/>
        {}<bpmn:sequenceFlow id="f2" sourceRef="x" targetRef="w"><bpmn:conditionExpression>1 &lt; 2</bpmn:conditionExpression></bpmn:sequenceFlow>
        {}{}{}{}{}"#,
        script("w", "v = 1"),
        script("r", "y = v"),
        flow("f1", "s", "x"),
        flow("f3", "x", "j"),
        flow("f4", "w", "j"),
        flow("f5", "j", "r"),
        flow("f6", "r", "e"),
        "",
    );
    let g = graph(&body);
    let f = findings(&g);
    let Some(Finding::Sometimes { path, .. }) = f.first() else {
        panic!("{f:?}")
    };
    let path: Vec<&str> = path.iter().map(|n| g.node(*n).id.as_str()).collect();
    assert_eq!(path, ["s", "x", "j", "r"]);
}

#[test]
fn a_parallel_join_has_what_every_branch_wrote_and_branches_may_see_each_other() {
    let body = format!(
        r#"<bpmn:startEvent id="s"/><bpmn:parallelGateway id="x"/>{}{}
        <bpmn:parallelGateway id="j"/>{}<bpmn:endEvent id="e"/>
        {}{}{}{}{}{}{}"#,
        script("a", "v = 1"),
        script("b", "z = v"),
        script("r", "y = v + z"),
        flow("f1", "s", "x"),
        flow("f2", "x", "a"),
        flow("f3", "x", "b"),
        flow("f4", "a", "j"),
        flow("f5", "b", "j"),
        flow("f6", "j", "r"),
        flow("f7", "r", "e"),
    );
    let g = graph(&body);
    // After the join both are written; in branch b, `v` may have been written by a, or not.
    assert_eq!(
        judged(&g),
        BTreeSet::from([("b".to_owned(), "v".to_owned(), "sometimes")])
    );
}

#[test]
fn a_message_s_payload_an_unknown_result_or_a_foreign_script_may_write_anything() {
    let message = r#"<bpmn:intermediateCatchEvent id="m"><bpmn:messageEventDefinition messageRef="msg"/></bpmn:intermediateCatchEvent>"#;
    let g = chain(&[
        ("m", message.to_owned()),
        ("r", script("r", "y = anything")),
    ]);
    assert!(judged(&g).iter().all(|(_, _, k)| *k != "unwritten"));
    let task = r#"<bpmn:serviceTask id="t"><bpmn:extensionElements><trace:task resource="a.b"/></bpmn:extensionElements></bpmn:serviceTask>"#;
    let g = chain(&[("t", task.to_owned()), ("r", script("r", "y = anything"))]);
    assert!(judged(&g).iter().all(|(_, _, k)| *k != "unwritten"));
    let py = r#"<bpmn:scriptTask id="py" scriptFormat="python"><bpmn:script>anything = 1</bpmn:script></bpmn:scriptTask>"#;
    let g = chain(&[("py", py.to_owned()), ("r", script("r", "y = anything"))]);
    assert!(judged(&g).iter().all(|(_, _, k)| *k != "unwritten"));
    // A task whose result fields are known writes those and nothing else.
    let g = chain(&[("t", task.to_owned()), ("r", script("r", "y = anything"))]);
    let f = check(
        &g,
        &Context {
            start: &BTreeSet::new(),
            results: &|_| Some(vec!["depth".to_owned()]),
        },
    );
    assert!(
        matches!(&f[..], [Finding::Unwritten { var, .. }] if var == "anything"),
        "{f:?}"
    );
}

#[test]
fn start_variables_declared_data_and_loop_variables_are_written() {
    let g = chain(&[("r", script("r", "y = given"))]);
    let f = check(
        &g,
        &Context {
            start: &BTreeSet::from(["given".to_owned()]),
            results: &|_| None,
        },
    );
    assert!(f.is_empty(), "{f:?}");
    let body = format!(
        r#"<bpmn:property id="pp" name="declared"/>{}"#,
        script("r", "y = declared")
    );
    let g = graph(&format!(
        r#"<bpmn:startEvent id="s"/>{body}<bpmn:endEvent id="e"/>{}{}"#,
        flow("f1", "s", "r"),
        flow("f2", "r", "e")
    ));
    assert!(judged(&g).is_empty());
    let mi = r#"<bpmn:scriptTask id="l" scriptFormat="cel"><bpmn:multiInstanceLoopCharacteristics isSequential="true"><bpmn:loopCardinality>3</bpmn:loopCardinality></bpmn:multiInstanceLoopCharacteristics><bpmn:script>y = loopCounter + nrOfInstances</bpmn:script></bpmn:scriptTask>"#;
    let g = chain(&[("l", mi.to_owned())]);
    assert!(judged(&g).is_empty(), "{:?}", judged(&g));
}

#[test]
fn event_sub_processes_boundaries_and_conditions_see_what_their_scope_may_have_written() {
    // An event sub-process may start after anything in its scope ran.
    let body = format!(
        r#"<bpmn:startEvent id="s"/>{}<bpmn:endEvent id="e"/>{}{}
        <bpmn:subProcess id="esp" triggeredByEvent="true">
          <bpmn:startEvent id="es" isInterrupting="false"><bpmn:signalEventDefinition/></bpmn:startEvent>
          {}<bpmn:endEvent id="ee"/>{}{}
        </bpmn:subProcess>"#,
        script("w", "v = 1"),
        flow("f1", "s", "w"),
        flow("f2", "w", "e"),
        script("r", "y = v"),
        flow("g1", "es", "r"),
        flow("g2", "r", "ee"),
    );
    let g = graph(&body);
    assert!(
        judged(&g).iter().all(|(_, _, k)| *k != "unwritten"),
        "{:?}",
        judged(&g)
    );
    // A boundary's path may follow anything inside the activity it interrupts.
    let body = format!(
        r#"<bpmn:startEvent id="s"/>
        <bpmn:subProcess id="sp"><bpmn:startEvent id="is"/>{}<bpmn:endEvent id="ie"/>{}{}</bpmn:subProcess>
        <bpmn:boundaryEvent id="b" attachedToRef="sp"><bpmn:errorEventDefinition/></bpmn:boundaryEvent>
        {}<bpmn:endEvent id="e"/><bpmn:endEvent id="e2"/>{}{}{}{}"#,
        script("w", "v = 1"),
        flow("i1", "is", "w"),
        flow("i2", "w", "ie"),
        script("r", "y = v"),
        flow("f1", "s", "sp"),
        flow("f2", "sp", "e"),
        flow("f3", "b", "r"),
        flow("f4", "r", "e2"),
    );
    let g = graph(&body);
    assert!(
        judged(&g).iter().all(|(_, _, k)| *k != "unwritten"),
        "{:?}",
        judged(&g)
    );
    // A condition waited for in one branch may be made true by another.
    let body = format!(
        r#"<bpmn:startEvent id="s"/><bpmn:parallelGateway id="x"/>{}
        <bpmn:intermediateCatchEvent id="c"><bpmn:conditionalEventDefinition><bpmn:condition>done</bpmn:condition></bpmn:conditionalEventDefinition></bpmn:intermediateCatchEvent>
        <bpmn:endEvent id="e1"/><bpmn:endEvent id="e2"/>{}{}{}{}{}"#,
        script("w", "done = true"),
        flow("f1", "s", "x"),
        flow("f2", "x", "w"),
        flow("f3", "x", "c"),
        flow("f4", "w", "e1"),
        flow("f5", "c", "e2"),
    );
    let g = graph(&body);
    assert!(
        judged(&g).iter().all(|(_, _, k)| *k != "unwritten"),
        "{:?}",
        judged(&g)
    );
}

#[test]
fn a_called_process_gets_what_its_call_passes_in() {
    let called = |binding: &str| {
        let xml = format!(
            r#"{HEAD}<bpmn:process id="p" isExecutable="true"><bpmn:startEvent id="s"/>{}
            <bpmn:callActivity id="c" calledElement="q">{binding}</bpmn:callActivity><bpmn:endEvent id="e"/>{}{}{}</bpmn:process>
            <bpmn:process id="q" isExecutable="true"><bpmn:startEvent id="qs"/>{}<bpmn:endEvent id="qe"/>{}{}</bpmn:process></bpmn:definitions>"#,
            script("w", "v = 1"),
            flow("f1", "s", "w"),
            flow("f2", "w", "c"),
            flow("f3", "c", "e"),
            script("r", "y = v"),
            flow("g1", "qs", "r"),
            flow("g2", "r", "qe"),
        );
        let loaded = load(xml.as_bytes());
        let g = loaded.graph.expect("valid");
        judged(&g)
    };
    // No mapping: every variable goes in.
    assert!(called("").is_empty());
    // Mappings: only what they name.
    let only = r#"<bpmn:extensionElements><trace:task><trace:input target="w" source="1"/></trace:task></bpmn:extensionElements>"#;
    assert_eq!(
        called(only),
        BTreeSet::from([("r".to_owned(), "v".to_owned(), "unwritten")])
    );
}

/// A generated process: writes and reads of three names in sequences, choices and parallel
/// blocks.
#[derive(Debug, Clone)]
enum Block {
    Write(char),
    Read(char),
    Seq(Vec<Block>),
    Xor(Vec<Block>),
    And(Vec<Block>),
}

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

fn generate(rng: &mut Rng, depth: u32, parallel: bool) -> Block {
    let var = |rng: &mut Rng| ['a', 'b', 'c'][rng.below(3) as usize];
    let kinds = if depth == 0 {
        2
    } else if parallel {
        5
    } else {
        4
    };
    match rng.below(kinds) {
        0 => Block::Write(var(rng)),
        1 => Block::Read(var(rng)),
        k => {
            let n = 2 + rng.below(2) as usize;
            let inner = (0..n).map(|_| generate(rng, depth - 1, parallel)).collect();
            match k {
                2 => Block::Seq(inner),
                3 => Block::Xor(inner),
                _ => Block::And(inner),
            }
        }
    }
}

/// The BPMN of a block between `from` and a returned exit node; reads are `r<k>` tasks.
struct Emit {
    body: String,
    n: usize,
}

impl Emit {
    fn id(&mut self, prefix: &str) -> String {
        self.n += 1;
        format!("{prefix}{}", self.n)
    }

    /// A flow; out of an exclusive split it has the condition `true` (every choice open).
    fn link(&mut self, from: &str, to: &str, chosen: bool) {
        let id = self.id("f");
        if chosen {
            self.body.push_str(&format!(
                r#"<bpmn:sequenceFlow id="{id}" sourceRef="{from}" targetRef="{to}"><bpmn:conditionExpression>true</bpmn:conditionExpression></bpmn:sequenceFlow>"#
            ));
        } else {
            self.body.push_str(&flow(&id, from, to));
        }
    }

    fn block(&mut self, b: &Block, from: &str, chosen: bool) -> String {
        match b {
            Block::Write(v) => {
                let id = self.id("w");
                self.body.push_str(&script(&id, &format!("{v} = 1")));
                self.link(from, &id, chosen);
                id
            }
            Block::Read(v) => {
                let id = self.id("r");
                self.body.push_str(&script(&id, &format!("{id} = {v}")));
                self.link(from, &id, chosen);
                id
            }
            Block::Seq(items) => {
                let mut at = from.to_owned();
                for (k, i) in items.iter().enumerate() {
                    at = self.block(i, &at, chosen && k == 0);
                }
                at
            }
            Block::Xor(items) | Block::And(items) => {
                let xor = matches!(b, Block::Xor(_));
                let kind = if xor {
                    "exclusiveGateway"
                } else {
                    "parallelGateway"
                };
                let split = self.id("x");
                let join = self.id("j");
                self.body.push_str(&format!(
                    r#"<bpmn:{kind} id="{split}"/><bpmn:{kind} id="{join}"/>"#
                ));
                self.link(from, &split, chosen);
                for i in items {
                    let out = self.block(i, &split, xor);
                    self.link(&out, &join, false);
                }
                join
            }
        }
    }
}

/// The oracle: for each read, whether the name is written on no path, some paths or every
/// path before it, by structural recursion (`may`, `must` in; writes of parallel siblings
/// count as may).
fn oracle(
    b: &Block,
    may: &BTreeSet<char>,
    must: &BTreeSet<char>,
    reads: &mut Vec<(char, &'static str)>,
) -> (BTreeSet<char>, BTreeSet<char>) {
    match b {
        Block::Write(v) => {
            let mut m = may.clone();
            m.insert(*v);
            let mut s = must.clone();
            s.insert(*v);
            (m, s)
        }
        Block::Read(v) => {
            reads.push((
                *v,
                if !may.contains(v) {
                    "unwritten"
                } else if !must.contains(v) {
                    "sometimes"
                } else {
                    "written"
                },
            ));
            (may.clone(), must.clone())
        }
        Block::Seq(items) => items.iter().fold((may.clone(), must.clone()), |(m, s), i| {
            oracle(i, &m, &s, reads)
        }),
        Block::Xor(items) => {
            let mut m = may.clone();
            let mut s: Option<BTreeSet<char>> = None;
            for i in items {
                let (im, is) = oracle(i, may, must, reads);
                m.extend(im);
                s = Some(match s {
                    None => is,
                    Some(s) => s.intersection(&is).copied().collect(),
                });
            }
            (m, s.unwrap_or_default())
        }
        Block::And(items) => {
            let all: Vec<BTreeSet<char>> = items.iter().map(writes_in).collect();
            let mut m = may.clone();
            let mut s = must.clone();
            for (k, i) in items.iter().enumerate() {
                let mut side = may.clone();
                for (j, w) in all.iter().enumerate() {
                    if j != k {
                        side.extend(w);
                    }
                }
                let (im, is) = oracle(i, &side, must, reads);
                m.extend(im);
                s.extend(is);
            }
            (m, s)
        }
    }
}

fn writes_in(b: &Block) -> BTreeSet<char> {
    match b {
        Block::Write(v) => BTreeSet::from([*v]),
        Block::Read(_) => BTreeSet::new(),
        Block::Seq(i) | Block::Xor(i) | Block::And(i) => i.iter().flat_map(writes_in).collect(),
    }
}

fn generated(seed: u64, parallel: bool) -> (ProcessGraph, Vec<(String, char, &'static str)>) {
    let mut rng = Rng(seed);
    let block = Block::Seq((0..3).map(|_| generate(&mut rng, 3, parallel)).collect());
    let mut e = Emit {
        body: r#"<bpmn:startEvent id="s"/><bpmn:endEvent id="e"/>"#.to_owned(),
        n: 0,
    };
    let last = e.block(&block, "s", false);
    e.link(&last, "e", false);
    let g = graph(&e.body);
    let mut reads = Vec::new();
    oracle(&block, &BTreeSet::new(), &BTreeSet::new(), &mut reads);
    // Reads are numbered in document order, as the oracle meets them.
    let ids: Vec<String> = g
        .nodes
        .iter()
        .filter(|n| n.id.starts_with('r'))
        .map(|n| n.id.clone())
        .collect();
    let mut sorted = ids;
    sorted.sort_by_key(|i| i[1..].parse::<usize>().unwrap_or(0));
    let judged = sorted
        .into_iter()
        .zip(reads)
        .map(|(id, (v, k))| (id, v, k))
        .collect();
    (g, judged)
}

#[test]
fn generated_sequences_and_choices_are_judged_exactly_as_the_oracle_judges_them() {
    let mut kinds = std::collections::BTreeMap::new();
    for seed in 0..300 {
        let (g, want) = generated(seed, false);
        let got = judged(&g);
        for (id, v, kind) in &want {
            *kinds.entry(*kind).or_insert(0) += 1;
            let found = got
                .iter()
                .find(|(i, var, _)| i == id && var.starts_with(*v))
                .map_or("written", |(_, _, k)| *k);
            assert_eq!(found, *kind, "seed {seed}: read {id} of `{v}`");
        }
    }
    // Every verdict occurs often.
    assert!(
        kinds.values().all(|n| *n > 50) && kinds.len() == 3,
        "{kinds:?}"
    );
}

#[test]
fn generated_parallel_blocks_never_call_a_name_unwritten_that_a_path_may_write() {
    let mut unwritten = 0;
    for seed in 0..300 {
        let (g, want) = generated(seed, true);
        let got = judged(&g);
        for (id, v, kind) in &want {
            let found = got
                .iter()
                .find(|(i, var, _)| i == id && var.starts_with(*v))
                .map_or("written", |(_, _, k)| *k);
            if found == "unwritten" {
                unwritten += 1;
                assert_eq!(*kind, "unwritten", "seed {seed}: read {id} of `{v}`");
            }
        }
    }
    // The check still finds names no path writes.
    assert!(unwritten > 20, "{unwritten}");
}
