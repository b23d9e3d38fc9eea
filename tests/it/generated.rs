//! The generated differential test: random small models from a grammar of the constructs Spin and
//! the engine both take — tasks, timers, signals thrown and caught, parallel and exclusive
//! blocks, branches that end early in every kind of end event, sub-processes with boundary
//! events, event sub-processes — seeded, a few hundred per run. On each, Spin on the PROMELA translation and
//! the engine's own exploration must agree exactly. Each model is written out first; a
//! disagreement names its seed and file, to be kept as a test.

use std::fmt::Write;

use crate::protocol::tempdir;
use crate::verify::{Compared, compare_within};

/// xorshift64*: a reproducible stream from a seed, enough to draw model shapes.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 33) % n
    }

    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
}

/// One model being drawn: elements and flows are written into the scope's buffer.
struct Draw {
    rng: Rng,
    ids: usize,
}

const TRIGGERS: [&str; 5] = [
    r#"<signalEventDefinition signalRef="S0"/>"#,
    r#"<signalEventDefinition signalRef="S1"/>"#,
    r#"<errorEventDefinition errorRef="E"/>"#,
    r#"<escalationEventDefinition escalationRef="X"/>"#,
    r#"<timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition>"#,
];

impl Draw {
    fn id(&mut self, prefix: &str) -> String {
        self.ids += 1;
        format!("{prefix}{}", self.ids)
    }

    fn flow(&mut self, out: &mut String, from: &str, to: &str) {
        let id = self.id("f");
        let _ = write!(
            out,
            r#"<sequenceFlow id="{id}" sourceRef="{from}" targetRef="{to}"/>"#
        );
    }

    fn task(&mut self, out: &mut String) -> String {
        let id = self.id("t");
        let _ = write!(
            out,
            r#"<serviceTask id="{id}"><extensionElements><trace:task resource="r.{id}"/></extensionElements></serviceTask>"#
        );
        id
    }

    /// An end event of a random kind; `inner` allows errors and escalations (caught around).
    fn end(&mut self, out: &mut String, inner: bool) -> String {
        let id = self.id("e");
        let kinds = if inner { 5 } else { 3 };
        let def = match self.rng.below(kinds) {
            0 => "",
            1 => "<terminateEventDefinition/>",
            2 => r#"<signalEventDefinition signalRef="S0"/>"#,
            3 => r#"<errorEventDefinition errorRef="E"/>"#,
            _ => r#"<escalationEventDefinition escalationRef="X"/>"#,
        };
        let _ = write!(out, r#"<endEvent id="{id}">{def}</endEvent>"#);
        id
    }

    /// A sequence of one to three items after `from`; the last element's id.
    fn seq(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        let mut at = from.to_owned();
        for _ in 0..=self.rng.below(if depth == 0 { 3 } else { 1 }) {
            at = self.item(out, &at, depth, inner);
        }
        at
    }

    /// One item entered from `from`; the element the next one follows.
    fn item(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        // Sub-processes nest one deep, blocks two deep: small enough to explore in full.
        let kind = match depth {
            0 => self.rng.below(8),
            1 => self.rng.below(6),
            _ => self.rng.below(3),
        };
        match kind {
            0 => {
                let id = self.task(out);
                self.flow(out, from, &id);
                id
            }
            1 => {
                let id = self.id("c");
                let def = if self.rng.chance(50) {
                    TRIGGERS[4]
                } else {
                    TRIGGERS[self.rng.below(2) as usize]
                };
                let _ = write!(
                    out,
                    r#"<intermediateCatchEvent id="{id}">{def}</intermediateCatchEvent>"#
                );
                self.flow(out, from, &id);
                id
            }
            2 => {
                let id = self.id("th");
                let def = TRIGGERS[self.rng.below(2) as usize];
                let _ = write!(
                    out,
                    r#"<intermediateThrowEvent id="{id}">{def}</intermediateThrowEvent>"#
                );
                self.flow(out, from, &id);
                id
            }
            3 => {
                // A branch that ends early beside the main path.
                let split = self.id("ps");
                let _ = write!(out, r#"<parallelGateway id="{split}"/>"#);
                self.flow(out, from, &split);
                let side = self.seq(out, &split, depth + 1, inner);
                let end = self.end(out, inner);
                self.flow(out, &side, &end);
                split
            }
            4 => {
                let (split, join) = (self.id("g"), self.id("j"));
                let _ = write!(
                    out,
                    r#"<parallelGateway id="{split}"/><parallelGateway id="{join}"/>"#
                );
                self.flow(out, from, &split);
                for _ in 0..2 {
                    let last = self.seq(out, &split, depth + 1, inner);
                    self.flow(out, &last, &join);
                }
                join
            }
            5 => {
                // An exclusive block: a condition on one branch (on a name nothing writes:
                // both Spin and the exploration take either branch), the other the default;
                // each branch starts with a task, so its first flow is the split's own.
                let (split, join) = (self.id("x"), self.id("j"));
                let firsts = [self.id("f"), self.id("f")];
                let _ = write!(
                    out,
                    r#"<exclusiveGateway id="{split}" default="{}"/><exclusiveGateway id="{join}"/>"#,
                    firsts[1]
                );
                self.flow(out, from, &split);
                for (k, first) in firsts.iter().enumerate() {
                    let t = self.task(out);
                    let condition = if k == 0 {
                        r#"<conditionExpression xsi:type="tFormalExpression">go == 1</conditionExpression>"#
                    } else {
                        ""
                    };
                    let _ = write!(
                        out,
                        r#"<sequenceFlow id="{first}" sourceRef="{split}" targetRef="{t}">{condition}</sequenceFlow>"#
                    );
                    let last = self.seq(out, &t, depth + 1, inner);
                    self.flow(out, &last, &join);
                }
                join
            }
            _ => {
                let id = self.id("sp");
                let mut body = String::new();
                self.scope(&mut body, depth + 1, true);
                let _ = write!(out, r#"<subProcess id="{id}">{body}</subProcess>"#);
                self.flow(out, from, &id);
                if self.rng.chance(60) {
                    let b = self.id("b");
                    let def = TRIGGERS[self.rng.below(5) as usize];
                    let cancel = def.contains("error") || self.rng.chance(60);
                    let _ = write!(
                        out,
                        r#"<boundaryEvent id="{b}" attachedToRef="{id}" cancelActivity="{cancel}">{def}</boundaryEvent>"#
                    );
                    let after = self.task(out);
                    self.flow(out, &b, &after);
                    let end = self.id("e");
                    let _ = write!(out, r#"<endEvent id="{end}"/>"#);
                    self.flow(out, &after, &end);
                }
                id
            }
        }
    }

    /// A scope's content: start, a sequence, an end, perhaps an event sub-process.
    fn scope(&mut self, out: &mut String, depth: u32, inner: bool) {
        let start = self.id("s");
        let _ = write!(out, r#"<startEvent id="{start}"/>"#);
        let last = self.seq(out, &start, depth, inner);
        let end = self.end(out, inner);
        self.flow(out, &last, &end);
        if self.rng.chance(25) {
            let (esp, s, e) = (self.id("esp"), self.id("es"), self.id("ee"));
            let def = TRIGGERS[self.rng.below(5) as usize];
            let interrupting = def.contains("error") || self.rng.chance(50);
            let mut body = String::new();
            let t = self.task(&mut body);
            let _ = write!(
                out,
                r#"<subProcess id="{esp}" triggeredByEvent="true"><startEvent id="{s}" isInterrupting="{interrupting}">{def}</startEvent>{body}<endEvent id="{e}"/>"#
            );
            self.flow(out, &s, &t);
            self.flow(out, &t, &e);
            out.push_str("</subProcess>");
        }
    }
}

/// The model drawn from `seed`.
fn model(seed: u64) -> String {
    let mut d = Draw {
        rng: Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1),
        ids: 0,
    };
    let mut body = String::new();
    d.scope(&mut body, 0, false);
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:generated">
  <signal id="S0" name="S0"/><signal id="S1" name="S1"/><error id="E" errorCode="E"/><escalation id="X" escalationCode="X"/>
  <process id="p" isExecutable="true">{body}</process>
</definitions>"#
    )
}

#[test]
fn spin_and_the_engine_agree_on_generated_models() {
    let count: u64 = std::env::var("TRACE_GENERATED_MODELS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(200);
    let first: u64 = std::env::var("TRACE_GENERATED_SEED")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1);
    let work = tempdir("generated");
    let (mut compared, mut invalid, mut refused, mut needs_data) = (0u64, 0, 0, 0);
    // Models with an exclusive split, where the exploration decides before anything else.
    let mut deciding = 0;
    let mut differences = Vec::new();
    for seed in first..first + count {
        let xml = model(seed);
        deciding += u64::from(xml.contains("<exclusiveGateway"));
        let path = work.join(format!("{seed}.bpmn"));
        std::fs::write(&path, &xml).expect("model written");
        let loaded = executive_model::load(xml.as_bytes());
        let Some(graph) = loaded.graph else {
            invalid += 1;
            println!("seed {seed}: invalid: {:?}", loaded.diagnostics);
            continue;
        };
        match compare_within(graph, &work.join(seed.to_string()), 20_000) {
            Compared::Refused(why) => {
                refused += 1;
                println!("seed {seed}: not translated: {why}");
            }
            Compared::NeedsData => needs_data += 1,
            Compared::Done(c) => {
                compared += 1;
                if !c.how.is_empty() {
                    // Kept beyond the scratch directory, to become a test.
                    let kept = std::env::temp_dir().join(format!("trace-generated-{seed}.bpmn"));
                    let _ = std::fs::copy(&path, &kept);
                    differences.push(format!(
                        "seed {seed} ({}): {}",
                        kept.display(),
                        c.how.join("; ")
                    ));
                }
            }
        }
    }
    println!(
        "generated: {count} models from seed {first} ({deciding} with an exclusive split): {compared} compared, {} agree exactly; {invalid} invalid, {refused} not translated, {needs_data} not explorable",
        compared - differences.len() as u64
    );
    assert!(differences.is_empty(), "{}", differences.join("\n"));
    assert_eq!(invalid, 0, "the grammar draws only valid models");
    assert!(
        compared * 10 >= count * 9,
        "only {compared} of {count} compared"
    );
}
