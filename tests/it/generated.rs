//! The generated differential test: random small models from a grammar of the constructs Spin and
//! the engine both take — tasks, timers, signals thrown and caught, parallel, exclusive and
//! inclusive blocks, event-based races, loops, branches merged without a gateway, link jumps,
//! branches that end early in every kind of end event, tasks and sub-processes with boundary
//! events, event sub-processes, multi-instance tasks and sub-processes, standard loops,
//! transactions cancelled or not, call activities, compensation, messages, conditions and timer
//! cycles from outside, messages to another pool — seeded, a few hundred per run. On each, Spin
//! on the PROMELA translation and the engine's own exploration must agree exactly. Each model is
//! written out first; a disagreement names its seed and file, to be kept as a test. The same
//! grammar, drawn for bpmn-js-token-simulation, also draws implicit starts, branches that end
//! without an end event, empty sub-processes and ones with two starts, errors and escalations
//! caught whatever their code, event sub-processes that throw again, compensation event
//! sub-processes, a pool a signal starts, a task a message reaches, a message raced against a
//! timer and a receive task after an event-based gateway (`simulated.rs`).

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
    /// Inside a loop's body: nothing there leaves a token behind, doubles one or throws (a
    /// signal could start another instance of an event sub-process each round), so each round
    /// starts from the same marking and the engine's state space stays finite (Spin bounds a
    /// cycle's rounds, the exploration only converges).
    looping: bool,
    /// The processes call activities call, drawn beside the main one.
    called: String,
    /// Drawing a called process (its elements send nothing to the other pool).
    calling: u32,
    /// The throw events that send a message to the other pool.
    sends: Vec<String>,
    /// Drawn for bpmn-js-token-simulation (`simulated.rs`): without what it runs as a plain task
    /// (multi-instance, standard loops, call activities), without loops back through a gateway,
    /// whose branch it keeps for every round, with every compensation throw naming its task and
    /// every merge without a gateway after an exclusive split (see `simulated.rs`).
    game: bool,
    /// Inside an inclusive block drawn for the simulator: no event-based gateway there (the
    /// simulator's inclusive join does not wait for a token passing from one to its event).
    joining: bool,
}

/// A service task run by a system (resource `r.<id>`).
pub(crate) fn service_task(id: &str) -> String {
    format!(
        r#"<serviceTask id="{id}"><extensionElements><trace:task resource="r.{id}"/></extensionElements></serviceTask>"#
    )
}

/// A split whose branches [`Draw::branches`] draws.
struct Split<'a> {
    id: &'a str,
    branches: usize,
    /// Each branch but the default has a condition.
    guarded: bool,
    /// The last branch's flow id, the split's default.
    default: Option<&'a str>,
}

const TRIGGERS: [&str; 8] = [
    r#"<signalEventDefinition signalRef="S0"/>"#,
    r#"<signalEventDefinition signalRef="S1"/>"#,
    r#"<errorEventDefinition errorRef="E"/>"#,
    r#"<escalationEventDefinition escalationRef="X"/>"#,
    r#"<timerEventDefinition><timeDuration xsi:type="tFormalExpression">PT1H</timeDuration></timerEventDefinition>"#,
    r#"<messageEventDefinition messageRef="M"/>"#,
    r#"<timerEventDefinition><timeCycle xsi:type="tFormalExpression">R2/PT1H</timeCycle></timerEventDefinition>"#,
    r#"<conditionalEventDefinition><condition xsi:type="tFormalExpression">ready == 1</condition></conditionalEventDefinition>"#,
];

impl Draw {
    /// A trigger of [`TRIGGERS`] for a boundary event or an event sub-process's start; drawn for
    /// the simulator, an error or escalation is sometimes caught whatever its code.
    fn trigger(&mut self) -> &'static str {
        let def = TRIGGERS[self.rng.below(8) as usize];
        if self.game && (def.contains("error") || def.contains("escalation")) && self.rng.chance(40)
        {
            if def.contains("error") {
                "<errorEventDefinition/>"
            } else {
                "<escalationEventDefinition/>"
            }
        } else {
            def
        }
    }

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
        out.push_str(&service_task(&id));
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
            0 => self.rng.below(19),
            1 => self.rng.below(15),
            _ => self.rng.below(3),
        };
        let kind = if self.game && matches!(kind, 8 | 11 | 14 | 16) {
            0
        } else {
            kind
        };
        match kind {
            2 | 3 if self.looping => {
                let id = self.task(out);
                self.flow(out, from, &id);
                id
            }
            0 => {
                let id = self.task(out);
                self.flow(out, from, &id);
                if depth > 0 || !self.rng.chance(25) {
                    return id;
                }
                // A contingency on the task itself, interrupting or not.
                let after = self.contingency(out, &id, 50);
                let end = self.end(out, inner);
                self.flow(out, &after, &end);
                id
            }
            1 => {
                let id = self.id("c");
                let def = match self.rng.below(7) {
                    0..3 => TRIGGERS[4],
                    3 => TRIGGERS[5],
                    4 => TRIGGERS[7],
                    k => TRIGGERS[k as usize - 5],
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
                // Drawn for the simulator, the branch may end where its last element ends (§13.2).
                if !(self.game && self.rng.chance(30)) {
                    let end = self.end(out, inner);
                    self.flow(out, &side, &end);
                }
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
                // An exclusive block: a condition on one branch, the other the default.
                let (split, join, default) = (self.id("x"), self.id("j"), self.id("f"));
                let _ = write!(
                    out,
                    r#"<exclusiveGateway id="{split}" default="{default}"/><exclusiveGateway id="{join}"/>"#
                );
                self.flow(out, from, &split);
                let split = Split {
                    id: &split,
                    branches: 2,
                    guarded: true,
                    default: Some(&default),
                };
                for last in self.branches(out, &split, depth, inner) {
                    self.flow(out, &last, &join);
                }
                join
            }
            6 => self.inclusive(out, from, depth, inner),
            7 => self.race(out, from, depth, inner),
            8 => self.again(out, from, depth, inner),
            9 => self.merge(out, from, depth, inner),
            10 => {
                // A jump: a link thrown here continues at its catch.
                let (throw, catch) = (self.id("lt"), self.id("lc"));
                let name = format!("L{}", self.ids);
                let _ = write!(
                    out,
                    r#"<intermediateThrowEvent id="{throw}"><linkEventDefinition name="{name}"/></intermediateThrowEvent><intermediateCatchEvent id="{catch}"><linkEventDefinition name="{name}"/></intermediateCatchEvent>"#
                );
                self.flow(out, from, &throw);
                catch
            }
            11 => self.many(out, from, depth, inner),
            12 if !self.looping => self.compensation(out, from, depth, inner),
            13 if !self.looping && self.calling == 0 && self.rng.chance(50) => {
                // A message to the other pool, which `model` draws: a throw event or a send task.
                let id = self.id("sm");
                let _ = if self.rng.chance(50) {
                    write!(out, r#"<sendTask id="{id}" messageRef="N"/>"#)
                } else {
                    write!(
                        out,
                        r#"<intermediateThrowEvent id="{id}"><messageEventDefinition messageRef="N"/></intermediateThrowEvent>"#
                    )
                };
                self.sends.push(id.clone());
                self.flow(out, from, &id);
                id
            }
            12 | 13 => {
                // A message from outside, awaited by a receive task or a catch event.
                let id = self.id("rm");
                if self.rng.chance(50) {
                    let _ = write!(out, r#"<receiveTask id="{id}" messageRef="M"/>"#);
                } else {
                    let _ = write!(
                        out,
                        r#"<intermediateCatchEvent id="{id}">{}</intermediateCatchEvent>"#,
                        TRIGGERS[5]
                    );
                }
                self.flow(out, from, &id);
                id
            }
            14 => {
                // A standard loop without a condition: it runs up to its maximum.
                let id = self.id("lt");
                let test_before = self.rng.chance(50);
                let _ = write!(
                    out,
                    r#"<serviceTask id="{id}"><extensionElements><trace:task resource="r.{id}"/></extensionElements><standardLoopCharacteristics testBefore="{test_before}" loopMaximum="2"/></serviceTask>"#
                );
                self.flow(out, from, &id);
                id
            }
            15 => self.transaction(out, from, depth),
            16 => {
                // A call of a process of its own, executable or not.
                let (id, called) = (self.id("ca"), self.id("q"));
                let mut body = String::new();
                self.calling += 1;
                self.scope(&mut body, depth + 1, true);
                self.calling -= 1;
                let executable = self.rng.chance(50);
                let _ = write!(
                    self.called,
                    r#"<process id="{called}" isExecutable="{executable}">{body}</process>"#
                );
                let _ = write!(out, r#"<callActivity id="{id}" calledElement="{called}"/>"#);
                self.flow(out, from, &id);
                self.perhaps_contingency(out, &id, 50);
                id
            }
            _ => {
                let id = self.id("sp");
                let mut body = String::new();
                // Drawn for the simulator, a sub-process may be empty: it completes at once.
                if !(self.game && self.rng.chance(10)) {
                    self.scope(&mut body, depth + 1, true);
                }
                let _ = write!(out, r#"<subProcess id="{id}">{body}</subProcess>"#);
                self.flow(out, from, &id);
                self.perhaps_contingency(out, &id, 60);
                id
            }
        }
    }

    /// With `percent` chance, a [`Draw::contingency`] on `holder` and a plain end after its task.
    fn perhaps_contingency(&mut self, out: &mut String, holder: &str, percent: u64) {
        if self.rng.chance(percent) {
            let after = self.contingency(out, holder, 60);
            let end = self.id("e");
            let _ = write!(out, r#"<endEvent id="{end}"/>"#);
            self.flow(out, &after, &end);
        }
    }

    /// A boundary event of a random trigger on `holder` (interrupting for an error, else with
    /// `interrupting` percent chance) and the task after it; the task's id.
    fn contingency(&mut self, out: &mut String, holder: &str, interrupting: u64) -> String {
        let b = self.id("b");
        let def = self.trigger();
        let cancel = def.contains("error") || self.rng.chance(interrupting);
        let _ = write!(
            out,
            r#"<boundaryEvent id="{b}" attachedToRef="{holder}" cancelActivity="{cancel}">{def}</boundaryEvent>"#
        );
        let after = self.task(out);
        self.flow(out, &b, &after);
        after
    }

    /// A transaction: a sequence, then an exclusive split to its end or to a cancel end event,
    /// and a cancel boundary event on it with the task after it.
    fn transaction(&mut self, out: &mut String, from: &str, depth: u32) -> String {
        let (id, start, split, end, cancel) = (
            self.id("tx"),
            self.id("s"),
            self.id("x"),
            self.id("e"),
            self.id("ce"),
        );
        let mut body = String::new();
        let _ = write!(body, r#"<startEvent id="{start}"/>"#);
        let last = self.seq(&mut body, &start, depth + 1, true);
        let (ended, cancelled, condition) = (self.id("f"), self.id("f"), self.condition());
        let _ = write!(
            body,
            r#"<exclusiveGateway id="{split}" default="{ended}"/><endEvent id="{end}"/><endEvent id="{cancel}"><cancelEventDefinition/></endEvent><sequenceFlow id="{ended}" sourceRef="{split}" targetRef="{end}"/><sequenceFlow id="{cancelled}" sourceRef="{split}" targetRef="{cancel}">{condition}</sequenceFlow>"#
        );
        self.flow(&mut body, &last, &split);
        let _ = write!(out, r#"<transaction id="{id}">{body}</transaction>"#);
        self.flow(out, from, &id);
        let (b, after, stop) = (self.id("b"), self.id("t"), self.id("e"));
        let _ = write!(
            out,
            r#"<boundaryEvent id="{b}" attachedToRef="{id}"><cancelEventDefinition/></boundaryEvent>{}<endEvent id="{stop}"/>"#,
            service_task(&after)
        );
        self.flow(out, &b, &after);
        self.flow(out, &after, &stop);
        id
    }

    /// A multi-instance activity, two instances one after another or side by side: a task, or
    /// at the top level a sub-process.
    fn many(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        let sequential = self.rng.chance(50);
        let each = format!(
            r#"<multiInstanceLoopCharacteristics isSequential="{sequential}"><loopCardinality xsi:type="tFormalExpression">2</loopCardinality></multiInstanceLoopCharacteristics>"#
        );
        let id = if depth == 0 && self.rng.chance(50) {
            let id = self.id("msp");
            let mut body = String::new();
            self.scope(&mut body, depth + 1, inner);
            let _ = write!(out, r#"<subProcess id="{id}">{each}{body}</subProcess>"#);
            id
        } else {
            let id = self.id("mt");
            let _ = write!(
                out,
                r#"<serviceTask id="{id}"><extensionElements><trace:task resource="r.{id}"/></extensionElements>{each}</serviceTask>"#
            );
            id
        };
        self.flow(out, from, &id);
        id
    }

    /// A task with a compensation handler, what follows it, and a compensation throw (of that
    /// task's handler or of every completed one in the scope).
    fn compensation(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        if self.game && self.rng.chance(30) {
            // Drawn for the simulator: a sub-process whose handler is an event sub-process.
            let (t, esp, s, e) = (self.id("sp"), self.id("esp"), self.id("es"), self.id("ee"));
            let mut body = String::new();
            self.scope(&mut body, depth + 1, inner);
            let mut handler = String::new();
            let h = self.task(&mut handler);
            let _ = write!(
                out,
                r#"<subProcess id="{t}">{body}<subProcess id="{esp}" triggeredByEvent="true"><startEvent id="{s}"><compensateEventDefinition/></startEvent>{handler}<endEvent id="{e}"/>"#
            );
            self.flow(out, &s, &h);
            self.flow(out, &h, &e);
            out.push_str("</subProcess></subProcess>");
            self.flow(out, from, &t);
            return self.compensated(out, &t, depth, inner);
        }
        let t = self.task(out);
        self.flow(out, from, &t);
        let (b, handler, link) = (self.id("cb"), self.id("ch"), self.id("a"));
        let _ = write!(
            out,
            r#"<boundaryEvent id="{b}" attachedToRef="{t}"><compensateEventDefinition/></boundaryEvent><serviceTask id="{handler}" isForCompensation="true"><extensionElements><trace:task resource="r.{handler}"/></extensionElements></serviceTask><association id="{link}" sourceRef="{b}" targetRef="{handler}"/>"#
        );
        self.compensated(out, &t, depth, inner)
    }

    /// What follows `t`, an activity with a compensation handler, and the throw of its
    /// compensation (or of every handler in the scope).
    fn compensated(&mut self, out: &mut String, t: &str, depth: u32, inner: bool) -> String {
        let last = self.seq(out, t, depth + 1, inner);
        let throw = self.id("ct");
        // The simulator compensates nothing for a throw of every handler (it looks for one of
        // the scope itself): it throws the task's own there.
        let which = if self.game || self.rng.chance(50) {
            format!(r#" activityRef="{t}""#)
        } else {
            String::new()
        };
        let _ = write!(
            out,
            r#"<intermediateThrowEvent id="{throw}"><compensateEventDefinition{which}/></intermediateThrowEvent>"#
        );
        self.flow(out, &last, &throw);
        throw
    }

    /// A condition on a name nothing writes: Spin and the exploration take it either way.
    fn condition(&mut self) -> String {
        let name = self.id("go");
        format!(
            r#"<conditionExpression xsi:type="tFormalExpression">{name} == 1</conditionExpression>"#
        )
    }

    /// The branches of `split` (each begins with a task, so its first flow is the split's own,
    /// conditional or the default); the last element of each.
    fn branches(
        &mut self,
        out: &mut String,
        split: &Split<'_>,
        depth: u32,
        inner: bool,
    ) -> Vec<String> {
        let mut lasts = Vec::new();
        for k in 0..split.branches {
            let t = self.task(out);
            let last = k + 1 == split.branches;
            let (first, condition) = match split.default {
                Some(d) if last => (d.to_owned(), String::new()),
                _ if split.guarded => (self.id("f"), self.condition()),
                _ => (self.id("f"), String::new()),
            };
            let _ = write!(
                out,
                r#"<sequenceFlow id="{first}" sourceRef="{}" targetRef="{t}">{condition}</sequenceFlow>"#,
                split.id
            );
            lasts.push(self.seq(out, &t, depth + 1, inner));
        }
        lasts
    }

    /// An inclusive block: two or three conditional branches, one of them perhaps the default
    /// (without one, no branch may be taken), joined by an inclusive gateway (§13.4.3).
    fn inclusive(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        let (split, join) = (self.id("o"), self.id("j"));
        let default = self.rng.chance(60).then(|| self.id("f"));
        let n = 2 + self.rng.below(2) as usize;
        let _ = write!(
            out,
            r#"<inclusiveGateway id="{split}"{}/><inclusiveGateway id="{join}"/>"#,
            default
                .as_ref()
                .map(|d| format!(r#" default="{d}""#))
                .unwrap_or_default()
        );
        self.flow(out, from, &split);
        let split = Split {
            id: &split,
            branches: n,
            guarded: true,
            default: default.as_deref(),
        };
        let outer = std::mem::replace(&mut self.joining, true);
        for last in self.branches(out, &split, depth, inner) {
            self.flow(out, &last, &join);
        }
        self.joining = outer;
        join
    }

    /// A race: an event-based gateway before two catch events (a timer, a signal, a message), each
    /// followed by its own branch, merged by an exclusive gateway.
    fn race(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        if self.game && self.joining {
            let id = self.task(out);
            self.flow(out, from, &id);
            return id;
        }
        let (gate, join) = (self.id("eb"), self.id("j"));
        let _ = write!(
            out,
            r#"<eventBasedGateway id="{gate}"/><exclusiveGateway id="{join}"/>"#
        );
        self.flow(out, from, &gate);
        let mut triggers = vec![self.rng.below(2) as usize, 4];
        match self.rng.below(10) {
            0..3 => triggers[1] = 1 - triggers[0],
            3..6 => triggers[1] = 5,
            _ => {}
        }
        for trigger in triggers {
            let c = self.id("c");
            // Drawn for the simulator, the message may be awaited by a receive task.
            let _ = if trigger == 5 && self.game && self.rng.chance(50) {
                write!(out, r#"<receiveTask id="{c}" messageRef="M"/>"#)
            } else {
                write!(
                    out,
                    r#"<intermediateCatchEvent id="{c}">{}</intermediateCatchEvent>"#,
                    TRIGGERS[trigger]
                )
            };
            self.flow(out, &gate, &c);
            let last = self.seq(out, &c, depth + 1, inner);
            self.flow(out, &last, &join);
        }
        join
    }

    /// A loop: an exclusive merge, a body, and an exclusive split back to the merge on a
    /// condition, forward by default to a task.
    fn again(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        let (merge, split, forward) = (self.id("lm"), self.id("ls"), self.id("f"));
        let _ = write!(
            out,
            r#"<exclusiveGateway id="{merge}"/><exclusiveGateway id="{split}" default="{forward}"/>"#
        );
        self.flow(out, from, &merge);
        let t = self.task(out);
        self.flow(out, &merge, &t);
        let outer = std::mem::replace(&mut self.looping, true);
        let last = self.seq(out, &t, depth + 1, inner);
        self.looping = outer;
        self.flow(out, &last, &split);
        let (back, condition) = (self.id("f"), self.condition());
        let next = self.task(out);
        let _ = write!(
            out,
            r#"<sequenceFlow id="{back}" sourceRef="{split}" targetRef="{merge}">{condition}</sequenceFlow><sequenceFlow id="{forward}" sourceRef="{split}" targetRef="{next}"/>"#
        );
        next
    }

    /// Branches merged without a gateway: an exclusive split's (one token arrives) or a
    /// parallel split's (the task after them runs once per branch).
    fn merge(&mut self, out: &mut String, from: &str, depth: u32, inner: bool) -> String {
        let split = self.id("m");
        // Two tokens along one flow reach what follows a parallel split's merge in one step:
        // the simulator passes one where BPMN passes each (§13.4.2), so it draws exclusive ones.
        let exclusive = self.looping || self.game || self.rng.chance(50);
        let default = exclusive.then(|| self.id("f"));
        let _ = match &default {
            Some(d) => write!(out, r#"<exclusiveGateway id="{split}" default="{d}"/>"#),
            None => write!(out, r#"<parallelGateway id="{split}"/>"#),
        };
        self.flow(out, from, &split);
        let split = Split {
            id: &split,
            branches: 2,
            guarded: exclusive,
            default: default.as_deref(),
        };
        let lasts = self.branches(out, &split, depth, inner);
        let next = self.task(out);
        for last in lasts {
            self.flow(out, &last, &next);
        }
        next
    }

    /// A scope's content: start, a sequence, an end, perhaps an event sub-process. Drawn for the
    /// simulator, the start event may be left out (the first element starts the scope, §13.2),
    /// or a sub-process may have a second start event with a task of its own.
    fn scope(&mut self, out: &mut String, depth: u32, inner: bool) {
        let mark = out.len();
        let start = self.id("s");
        let _ = write!(out, r#"<startEvent id="{start}"/>"#);
        let last = self.seq(out, &start, depth, inner);
        let end = self.end(out, inner);
        self.flow(out, &last, &end);
        if self.game
            && self.rng.chance(20)
            && let Some(implicit) = without_start(&out[mark..], &start)
        {
            out.truncate(mark);
            out.push_str(&implicit);
        } else if self.game && depth > 0 && self.rng.chance(15) {
            let (second, end) = (self.id("s"), self.id("e"));
            let _ = write!(out, r#"<startEvent id="{second}"/><endEvent id="{end}"/>"#);
            let t = self.task(out);
            self.flow(out, &second, &t);
            self.flow(out, &t, &end);
        }
        if self.rng.chance(25) {
            let (esp, s, e) = (self.id("esp"), self.id("es"), self.id("ee"));
            let def = self.trigger();
            let interrupting = def.contains("error") || self.rng.chance(50);
            let mut body = String::new();
            let t = self.task(&mut body);
            // Drawn for the simulator, an event sub-process inside may throw again what it
            // caught, to the scope around.
            let again = if self.game && inner && self.rng.chance(30) {
                match def {
                    d if d.starts_with("<error") => r#"<errorEventDefinition errorRef="E"/>"#,
                    d if d.starts_with("<escalation") => {
                        r#"<escalationEventDefinition escalationRef="X"/>"#
                    }
                    _ => "",
                }
            } else {
                ""
            };
            let _ = write!(
                out,
                r#"<subProcess id="{esp}" triggeredByEvent="true"><startEvent id="{s}" isInterrupting="{interrupting}">{def}</startEvent>{body}<endEvent id="{e}">{again}</endEvent>"#
            );
            self.flow(out, &s, &t);
            self.flow(out, &t, &e);
            out.push_str("</subProcess>");
        }
    }

    /// The other pool, when the main process sends to it: its process (started by the message,
    /// or waiting for it after a task, in a catch event or a receive task) and the
    /// collaboration with the message flows.
    fn other(&mut self) -> String {
        if self.sends.is_empty() {
            // Drawn for the simulator, perhaps a pool that a signal starts.
            if !(self.game && self.rng.chance(30)) {
                return String::new();
            }
            let signal = self.rng.below(2);
            return format!(
                r#"<process id="r" isExecutable="true"><startEvent id="rs"><signalEventDefinition signalRef="S{signal}"/></startEvent>{}<endEvent id="re"/><sequenceFlow id="rf0" sourceRef="rs" targetRef="rt"/><sequenceFlow id="rf1" sourceRef="rt" targetRef="re"/></process><collaboration id="c"><participant id="P" processRef="p"/><participant id="R" processRef="r"/></collaboration>"#,
                service_task("rt")
            );
        }
        // Drawn for the simulator, the message may also be awaited by a task (one a message
        // flow reaches waits for it, as a receive task does).
        let how = self.rng.below(if self.game { 5 } else { 3 });
        let receiver = if how == 0 { "rs" } else { "rc" };
        let wait = match how {
            1 => {
                r#"<intermediateCatchEvent id="rc"><messageEventDefinition messageRef="N"/></intermediateCatchEvent>"#
            }
            3 => r#"<task id="rc"/>"#,
            _ => r#"<receiveTask id="rc" messageRef="N"/>"#,
        };
        let body = if how == 4 {
            // Drawn for the simulator: a race between the message and a timer.
            format!(
                r#"<startEvent id="rs"/>{}<eventBasedGateway id="rg"/><intermediateCatchEvent id="rc"><messageEventDefinition messageRef="N"/></intermediateCatchEvent><intermediateCatchEvent id="rd">{}</intermediateCatchEvent><endEvent id="re"/><endEvent id="rx"/><sequenceFlow id="rf0" sourceRef="rs" targetRef="rt"/><sequenceFlow id="rf1" sourceRef="rt" targetRef="rg"/><sequenceFlow id="rf2" sourceRef="rg" targetRef="rc"/><sequenceFlow id="rf3" sourceRef="rg" targetRef="rd"/><sequenceFlow id="rf4" sourceRef="rc" targetRef="re"/><sequenceFlow id="rf5" sourceRef="rd" targetRef="rx"/>"#,
                service_task("rt"),
                TRIGGERS[4]
            )
        } else if how == 0 {
            format!(
                r#"<startEvent id="rs"><messageEventDefinition messageRef="N"/></startEvent>{}<endEvent id="re"/><sequenceFlow id="rf0" sourceRef="rs" targetRef="rt"/><sequenceFlow id="rf1" sourceRef="rt" targetRef="re"/>"#,
                service_task("rt")
            )
        } else {
            format!(
                r#"<startEvent id="rs"/>{}{wait}<endEvent id="re"/><sequenceFlow id="rf0" sourceRef="rs" targetRef="rt"/><sequenceFlow id="rf1" sourceRef="rt" targetRef="rc"/><sequenceFlow id="rf2" sourceRef="rc" targetRef="re"/>"#,
                service_task("rt")
            )
        };
        let flows: String = self
            .sends
            .iter()
            .enumerate()
            .map(|(k, s)| {
                format!(r#"<messageFlow id="mf{k}" sourceRef="{s}" targetRef="{receiver}"/>"#)
            })
            .collect();
        format!(
            r#"<process id="r" isExecutable="true">{body}</process><collaboration id="c"><participant id="P" processRef="p"/><participant id="R" processRef="r"/>{flows}</collaboration>"#
        )
    }
}

/// `drawn` without the start event `start` and the flow that leaves it; `None` when that flow
/// leads to a parallel gateway, which the simulator never fires without incoming flows.
fn without_start(drawn: &str, start: &str) -> Option<String> {
    let event = format!(r#"<startEvent id="{start}"/>"#);
    let source = format!(r#" sourceRef="{start}" targetRef=""#);
    let mut text = drawn.replacen(&event, "", 1);
    let at = text.find(&source)?;
    let target = &text[at + source.len()..];
    let target = &target[..target.find('"')?];
    if text.contains(&format!(r#"<parallelGateway id="{target}""#)) {
        return None;
    }
    let open = text[..at].rfind("<sequenceFlow")?;
    let close = at + text[at..].find("/>")? + 2;
    text.replace_range(open..close, "");
    Some(text)
}

/// The model drawn from `seed`; `game`: for bpmn-js-token-simulation ([`Draw::game`]).
pub(crate) fn model(seed: u64, game: bool) -> String {
    let mut d = Draw {
        rng: Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1),
        ids: 0,
        looping: false,
        called: String::new(),
        calling: 0,
        sends: Vec::new(),
        game,
        joining: false,
    };
    let mut body = String::new();
    d.scope(&mut body, 0, false);
    let other = d.other();
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<definitions xmlns="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:trace="urn:trace:bpmn:1.0" id="d" targetNamespace="urn:generated">
  <signal id="S0" name="S0"/><signal id="S1" name="S1"/><error id="E" errorCode="E"/><escalation id="X" escalationCode="X"/><message id="M" name="M"/><message id="N" name="N"/>
  <process id="p" isExecutable="true">{body}</process>{}{other}
</definitions>"#,
        d.called
    )
}

/// The number the environment variable `name` holds, else `default`: how many models, from
/// which seed.
pub(crate) fn number(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(default)
}

#[test]
fn spin_and_the_engine_agree_on_generated_models() {
    let count = number("TRACE_GENERATED_MODELS", 200);
    let first = number("TRACE_GENERATED_SEED", 1);
    let work = tempdir("generated");
    let (mut compared, mut invalid, mut refused, mut needs_data) = (0u64, 0, 0, 0);
    // Models with an exclusive split, where the exploration decides before anything else.
    let mut deciding = 0;
    // Models with a second pool the main process sends to.
    let mut pools = 0;
    let mut differences = Vec::new();
    for seed in first..first + count {
        let xml = model(seed, false);
        deciding += u64::from(xml.contains("<exclusiveGateway"));
        pools += u64::from(xml.contains("<collaboration"));
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
        "generated: {count} models from seed {first} ({deciding} with an exclusive split, {pools} with two pools): {compared} compared, {} agree exactly; {invalid} invalid, {refused} not translated, {needs_data} not explorable",
        compared - differences.len() as u64
    );
    assert!(differences.is_empty(), "{}", differences.join("\n"));
    assert_eq!(invalid, 0, "the grammar draws only valid models");
    assert!(
        compared * 10 >= count * 9,
        "only {compared} of {count} compared"
    );
}
