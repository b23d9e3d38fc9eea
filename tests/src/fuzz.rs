//! The fuzz targets' bodies: one function per reader of outside input, each taking any bytes
//! and required never to panic, overflow the stack or run unbounded. `fuzz/` wraps each in a
//! libFuzzer target (`cargo fuzz run <name>`); `tests/it/fuzz.rs` runs every one over its
//! seeds and over every crash input kept in `fuzz/regressions/<name>/`, so a crash found once
//! stays fixed. [`TARGETS`] names them all.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, LazyLock};

use connector_api::wire::{self, Answer, Goal, ResultMsg, Telemetry};
use connector_api::{Catalogue, ConnectorsConfig};
use executive_engine::{Action, Engine, Event, Input, Value, Vars};
use executive_model::{ProcessGraph, Severity};

/// A fuzz target's body.
pub type Target = fn(&[u8]);

/// Every target by name, as `fuzz/fuzz_targets/<name>.rs` wraps it.
pub const TARGETS: [(&str, Target); 8] = [
    ("loader", loader),
    ("feel", feel),
    ("expressions", expressions),
    ("wire", wire),
    ("answers", answers),
    ("record", record),
    ("config", config),
    ("store", store),
];

static EUROPA: LazyLock<Arc<ProcessGraph>> = LazyLock::new(|| {
    let bytes = include_bytes!("../../deploy/missions/europa-bsm1.bpmn");
    Arc::new(
        executive_model::load(bytes)
            .graph
            .expect("the Europa mission loads"),
    )
});

static CONNECTORS: LazyLock<ConnectorsConfig> = LazyLock::new(|| {
    executive_runtime::connectors::parse_config(include_str!("../../deploy/connectors.toml"))
        .expect("the deployment's connectors file is valid")
});

static LANDER: LazyLock<Catalogue> = LazyLock::new(elap_sim::catalogue::catalogue);

static FORMS: LazyLock<Arc<Catalogue>> = LazyLock::new(|| {
    Arc::new(
        serde_json::from_str(include_str!("../../deploy/ground/forms.json"))
            .expect("the ground forms are a catalogue"),
    )
});

/// The BPMN loader, and the engine on whatever loads: every process is started and every
/// task, user task, timer and message it asks for is answered, for a bounded number of steps.
pub fn loader(data: &[u8]) {
    let loaded = executive_model::load(data);
    for d in &loaded.diagnostics {
        let _ = loaded.text_of(d);
    }
    let Some(graph) = loaded.graph else {
        return;
    };
    if loaded
        .diagnostics
        .iter()
        .any(|d| d.severity == Severity::Error)
    {
        return;
    }
    fly(Arc::new(graph), 200);
}

/// Runs `graph` in the engine for at most `budget` steps, answering every action at once.
fn fly(graph: Arc<ProcessGraph>, budget: u64) {
    let mut engine = Engine::new(Arc::clone(&graph));
    let mut queue: Vec<(i64, Event)> = graph
        .primary_processes()
        .into_iter()
        .map(|p| {
            (
                0,
                Event::InstanceStarted {
                    process: graph.process(p).id.clone(),
                    vars: Vars::new(),
                    start: None,
                },
            )
        })
        .collect();
    let mut now = 0;
    for seq in 1..=budget {
        if queue.is_empty() {
            return;
        }
        let (at, event) = queue.remove(0);
        now = at.max(now);
        let Ok(actions) = engine.step(Input {
            seq,
            at: now,
            event,
        }) else {
            continue;
        };
        for a in actions {
            let next = match a {
                Action::DispatchTask { task, .. } => Event::TaskCompleted {
                    task,
                    output: Vars::new(),
                },
                Action::OpenUserTask { task, .. } => Event::UserTaskAnswered {
                    task,
                    answer: Vars::new(),
                    operator: "fuzz".into(),
                },
                Action::StartTimer { timer, at } => {
                    queue.push((at, Event::TimerFired { timer }));
                    continue;
                }
                Action::SendMessage(m) => Event::MessageReceived {
                    name: m.name,
                    correlation: None,
                    payload: m.payload,
                    flow: None,
                    key: None,
                },
                _ => continue,
            };
            queue.push((now, next));
        }
    }
}

/// FEEL: any text is parsed, checked and evaluated with a few variables and a small budget.
pub fn feel(data: &[u8]) {
    use executive_feel::{Context, DateTime, Env, Value, parse};
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(expression) = parse(text) else {
        return;
    };
    let _ = expression.problems();
    let vars = |name: &str| match name {
        "n" => Some(Value::int(3)),
        "s" => Some(Value::String("abc".into())),
        "l" => Some(Value::List(vec![Value::int(1), Value::int(2), Value::Null])),
        "c" => Some(Value::Context(Context(vec![("a".into(), Value::int(1))]))),
        "z" => Some(Value::Null),
        _ => None,
    };
    let env = Env {
        lookup: &vars,
        now: DateTime {
            local: chrono::NaiveDate::from_ymd_opt(2026, 11, 23)
                .and_then(|d| d.and_hms_opt(10, 0, 0))
                .unwrap_or_default(),
            zone: None,
        },
        budget: 20_000,
    };
    if let Ok(v) = expression.evaluate(&env) {
        let _ = v.value.to_string();
    }
}

/// The expression languages a model may declare (the first byte picks CEL, JUEL, FEEL or
/// XPath): compiled, translated to CEL, and evaluated as the engine evaluates conditions;
/// the rest also read as a script of assignments.
pub fn expressions(data: &[u8]) {
    use executive_model::{Expression, Language};
    let Some((pick, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let language = match pick % 4 {
        0 => Language::Cel,
        1 => Language::Juel,
        2 => Language::Feel,
        _ => Language::XPath,
    };
    let _ = executive_model::feel_to_cel(text);
    let _ = executive_model::parse_assignments(text);
    let Ok(expr) = Expression::compile(text, &language) else {
        return;
    };
    let _ = expr.cel_text();
    let mut vars = Vars::new();
    vars.insert("n".into(), Value::Int(3));
    vars.insert("s".into(), Value::String("abc".into()));
    vars.insert("b".into(), Value::Bool(true));
    vars.insert("l".into(), Value::List(vec![Value::Int(1), Value::Null]));
    vars.insert(
        "m".into(),
        Value::Map(BTreeMap::from([("a".to_owned(), Value::Int(1))])),
    );
    vars.insert("z".into(), Value::Null);
    let _ = executive_engine::evaluate(&expr, 1_800_000_000_000, &vars);
}

/// The wire payloads the executive, a system and a ground station read from the bus (the
/// first byte picks the message), then checked against the lander's catalogue as the
/// executive checks them.
pub fn wire(data: &[u8]) {
    let Some((pick, bytes)) = data.split_first() else {
        return;
    };
    let key = "trace/fuzz";
    let cat = &*LANDER;
    let spec = cat
        .actions
        .get(usize::from(*pick >> 4) % cat.actions.len().max(1));
    match pick % 12 {
        0 => {
            if let (Ok(g), Some(spec)) = (wire::parse::<Goal>("goal", key, bytes), spec) {
                let _ = spec.check_goal(&g.fields);
            }
        }
        1 => drop(wire::parse::<wire::GoalReply>("goal reply", key, bytes)),
        2 => drop(wire::parse::<wire::CancelRequest>("cancel", key, bytes)),
        3 => drop(wire::parse::<wire::CancelReply>("cancel reply", key, bytes)),
        4 => drop(wire::parse::<wire::StateReply>("state reply", key, bytes)),
        5 => drop(wire::parse::<wire::StatusMsg>("status", key, bytes)),
        6 => {
            if let (Ok(f), Some(spec)) = (
                wire::parse::<wire::FeedbackMsg>("feedback", key, bytes),
                spec,
            ) {
                let _ = spec.check_feedback(&f.fields);
            }
        }
        7 => {
            if let (Ok(r), Some(spec)) = (wire::parse::<ResultMsg>("result", key, bytes), spec) {
                let _ = spec.check_result(&r.outputs);
                let _ = spec.missing_outputs(&r.outputs);
            }
        }
        8 => {
            if let Ok(t) = wire::parse::<Telemetry>("telemetry", key, bytes) {
                for (name, v) in &t.values {
                    let _ = cat.check_telemetry(name, v, None);
                    let _ = cat.check_telemetry(name, v, Some(&serde_json::json!(1.5)));
                }
            }
        }
        9 => {
            if let Ok(c) = wire::parse::<Catalogue>("catalogue", key, bytes) {
                against(&c);
            }
        }
        10 => drop(wire::parse::<wire::AnswerReply>("answer reply", key, bytes)),
        _ => {
            let reading = |b: &[u8]| {
                let n = |i: usize| Some(u64::from_le_bytes(b.get(i..i + 8)?.try_into().ok()?));
                Some(wire::ClockReading {
                    mission_ms: n(0)? as i64,
                    speed: f64::from_bits(n(8)?),
                })
            };
            if let (Some(last), Some(next)) = (reading(bytes), bytes.get(16..).and_then(reading)) {
                let wall = std::time::Duration::from_millis(u64::from(bytes[0]) * 1000);
                let slack = std::time::Duration::from_millis(250);
                let _ = wire::check_clock(Some(last), next, wall, slack);
            }
        }
    }
}

/// Checks the Europa mission's tasks against a catalogue as `trace validate` does.
fn against(cat: &Catalogue) {
    let tasks = executive_runtime::connectors::task_uses(&EUROPA);
    let _ = connector_api::check(&tasks, &CONNECTORS, &[Some(cat.clone())]);
}

/// User-task answers: an operator's typed `field=value …` line for one of the ground forms
/// (the first byte picks the form), and an answer payload judged against the form as the
/// executive judges it.
pub fn answers(data: &[u8]) {
    let Some((pick, rest)) = data.split_first() else {
        return;
    };
    let forms = &*FORMS;
    let Some(spec) = forms
        .actions
        .get(usize::from(*pick) % forms.actions.len().max(1))
    else {
        return;
    };
    if let Ok(text) = std::str::from_utf8(rest) {
        let _ = ground_station::forms::parse_answer(spec, text);
    }
    if let Ok(a) = wire::parse::<Answer>("answer", "trace/fuzz", rest) {
        let _ = spec.check_result(&a.fields);
    }
}

/// The execution record as its readers take it: line by line (a line cut by a crash, a line
/// written twice after a restart), into the timeline, and the page's data.
pub fn record(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let mut reader = executive_runtime::record::Reader::default();
    for line in text.lines() {
        if let Some(v) = reader.read(line) {
            let _ = reader.resource(&v);
        }
    }
    let t = executive_runtime::timeline::build(text.lines().map(str::to_owned));
    let _ = serde_json::to_string(&t);
}

/// The configuration files (the first byte picks which): the executive's settings, the
/// connectors, a ground station's policy (and a decision by it), the scripted connector's
/// script, the simulator's fault script, a station's forms, and a requirements file.
pub fn config(data: &[u8]) {
    let Some((pick, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    match pick % 7 {
        0 => {
            let _ = executive_runtime::config::Settings::default().with_text(text, "fuzz.toml");
        }
        1 => {
            if let Ok(c) = executive_runtime::connectors::parse_config(text) {
                for resource in ["excavation.excavate", "ground.select_site", "x"] {
                    let _ = c.route(resource);
                }
            }
        }
        2 => {
            if let Ok(p) = ground_station::policy::Policy::parse(text, "fuzz.toml", FORMS.clone()) {
                let goal = serde_json::json!({"sites": [{"site_id": "A", "score": 0.5}], "n": 1});
                if let serde_json::Value::Object(goal) = goal {
                    for action in &FORMS.actions {
                        let _ = p.decide(&action.name, &goal);
                    }
                }
            }
        }
        3 => drop(serde_json::from_str::<executive_runtime::script::Script>(
            text,
        )),
        4 => {
            if let Ok(s) = serde_json::from_str::<elap_sim::Script>(text) {
                let _ = s.forced("excavation.excavate", 1);
            }
        }
        5 => {
            if let Ok(c) = serde_json::from_str::<Catalogue>(text) {
                for spec in &c.actions {
                    let _ = ground_station::forms::describe(spec);
                }
                against(&c);
            }
        }
        _ => {
            let _ = executive_verify::requirements::parse(text, "fuzz.req.toml", &EUROPA);
        }
    }
}

/// The store's recovery: entries as a damaged store may hold them (a JSON description of the
/// trees: `{"snapshot": [key, state], "steps": [[key, input, actions, [done keys]]], "meta":
/// [[k, v]]}`, byte strings as text), decoded, checked against the Europa model, and
/// resumed by replaying the journal as the executive does.
pub fn store(data: &[u8]) {
    use executive_store::{Raw, RawStep};
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(data) else {
        return;
    };
    let bytes = |v: &serde_json::Value| -> Vec<u8> {
        match v {
            serde_json::Value::String(s) => s.as_bytes().to_vec(),
            serde_json::Value::Number(n) => n.as_u64().unwrap_or(0).to_be_bytes().to_vec(),
            other => other.to_string().into_bytes(),
        }
    };
    let list = |v: &serde_json::Value| v.as_array().cloned().unwrap_or_default();
    let raw = Raw {
        snapshot: v["snapshot"].as_array().map(|p| {
            (
                bytes(&p[0]),
                bytes(p.get(1).unwrap_or(&serde_json::Value::Null)),
            )
        }),
        steps: list(&v["steps"])
            .iter()
            .map(|s| RawStep {
                key: bytes(&s[0]),
                input: bytes(&s[1]),
                actions: (!s[2].is_null()).then(|| bytes(&s[2])),
                done: list(&s[3]).iter().map(bytes).collect(),
            })
            .collect(),
        meta: list(&v["meta"])
            .iter()
            .map(|m| (bytes(&m[0]), bytes(&m[1])))
            .collect(),
    };
    let Ok(rec) = raw.decode() else {
        return;
    };
    let _ = rec.pending();
    let graph = Arc::clone(&EUROPA);
    let mut engine = match rec.snapshot {
        Some((_, state)) => {
            if state.check(&graph).is_err() {
                return;
            }
            Engine::restore(graph, state)
        }
        None => Engine::new(graph),
    };
    for step in rec.steps.into_iter().take(64) {
        if engine.step(step.input).as_ref() != Ok(&step.actions) {
            return;
        }
    }
}

/// Writes a starting corpus for every target under `out/<target>/`: the BPMN files of the
/// conformance corpora and the deployment (loader), the expressions written in them (FEEL,
/// expressions), the deployment's configuration files (config), payloads and answers shaped
/// by the lander's catalogue and the ground forms (wire, answers), and, when given, a real
/// run's execution record (record) and store (store). Returns the number of seeds per target.
pub fn seed(
    out: &Path,
    corpora: &[PathBuf],
    record_file: Option<&Path>,
    store_dir: Option<&Path>,
) -> std::io::Result<BTreeMap<&'static str, usize>> {
    let mut counts = BTreeMap::new();
    let mut put = |target: &'static str, bytes: &[u8]| -> std::io::Result<()> {
        let dir = out.join(target);
        std::fs::create_dir_all(&dir)?;
        let n = counts.entry(target).or_insert(0);
        *n += 1;
        std::fs::write(dir.join(format!("seed-{n:05}")), bytes)
    };
    let repo = crate::repo();
    // The corpora's small models (the fuzzer's speed goes with the input's size, and what a
    // large one holds, small ones hold too), and the shipped missions whatever their size.
    let mut models = Vec::new();
    for root in corpora {
        models.extend(files(root, "bpmn").into_iter().map(|p| (p, 12 << 10)));
    }
    models.extend(
        files(&repo.join("deploy/missions"), "bpmn")
            .into_iter()
            .map(|p| (p, usize::MAX)),
    );
    for (path, limit) in &models {
        let bytes = std::fs::read(path)?;
        if bytes.len() > *limit {
            continue;
        }
        put("loader", &bytes)?;
        for (language, text) in expressions_in(&String::from_utf8_lossy(&bytes)) {
            if language == 2 {
                put("feel", text.trim_start_matches('=').as_bytes())?;
            }
            put("expressions", &[&[language][..], text.as_bytes()].concat())?;
        }
    }
    let deploy = |p: &str| std::fs::read(repo.join("deploy").join(p));
    for (pick, file) in [
        (0u8, "executive.toml"),
        (1, "connectors.toml"),
        (2, "ground/policy.toml"),
        (5, "ground/forms.json"),
        (6, "missions/europa-bsm1.req.toml"),
    ] {
        put("config", &[&[pick][..], &deploy(file)?].concat())?;
    }
    for scenario in files(&repo.join("deploy/scenarios"), "json") {
        put("config", &[&[4u8][..], &std::fs::read(scenario)?].concat())?;
    }
    put(
        "config",
        b"\x03{\"default\":{\"duration_ms\":10},\"resources\":{\"excavation.\":{\"fail\":\"TOOL_STUCK\",\"fail_attempts\":[1]}}}",
    )?;
    let lander = &*LANDER;
    put(
        "wire",
        &[&[9u8][..], serde_json::to_string(lander)?.as_bytes()].concat(),
    )?;
    for (i, spec) in lander.actions.iter().enumerate().take(16) {
        let pick = |kind: u8| ((i as u8) << 4) | kind;
        let example = |fields: &BTreeMap<String, connector_api::Type>| {
            let map: serde_json::Map<String, serde_json::Value> = fields
                .iter()
                .map(|(k, t)| (k.clone(), example(t)))
                .collect();
            map
        };
        let goal = serde_json::json!({"goal_id": "m.1.2.1", "fields": example(&spec.goal)});
        let result = serde_json::json!({"goal_id": "m.1.2.1", "status": "SUCCEEDED", "outputs": example(&spec.result)});
        let feedback = serde_json::json!({"goal_id": "m.1.2.1", "progress_pct": 50.0, "fields": example(&spec.feedback)});
        put(
            "wire",
            &[&[pick(0)][..], goal.to_string().as_bytes()].concat(),
        )?;
        put(
            "wire",
            &[&[pick(7)][..], result.to_string().as_bytes()].concat(),
        )?;
        put(
            "wire",
            &[&[pick(6)][..], feedback.to_string().as_bytes()].concat(),
        )?;
    }
    for (pick, payload) in [
        (1u8, r#"{"goal_id":"m.1.2.1","status":"ACCEPTED"}"#),
        (2, r#"{"reason":"operator"}"#),
        (3, r#""CANCELLING""#),
        (4, r#"{"goal_id":"m.1.2.1","status":"EXECUTING","seq":3}"#),
        (
            5,
            r#"{"goal_id":"m.1.2.1","status":"EXECUTING","seq":3,"text":"digging"}"#,
        ),
        (
            8,
            r#"{"mission_ms":1800000000000,"values":{"battery_soc_pct":81.5,"comm_window_open":true}}"#,
        ),
        (10, r#"{"goal_id":"m.1.2.1","applied":true}"#),
    ] {
        put("wire", &[&[pick][..], payload.as_bytes()].concat())?;
    }
    put(
        "wire",
        &[
            &[11u8][..],
            &1_000i64.to_le_bytes(),
            &1.0f64.to_bits().to_le_bytes(),
            &61_000i64.to_le_bytes(),
            &60.0f64.to_bits().to_le_bytes(),
        ]
        .concat(),
    )?;
    for (i, spec) in FORMS.actions.iter().enumerate() {
        let line: Vec<String> = spec
            .result
            .iter()
            .map(|(k, t)| format!("{k}={}", example(t)))
            .collect();
        put(
            "answers",
            &[&[i as u8][..], line.join(" ").as_bytes()].concat(),
        )?;
        let fields: serde_json::Map<String, serde_json::Value> = spec
            .result
            .iter()
            .map(|(k, t)| (k.clone(), example(t)))
            .collect();
        let answer = serde_json::json!({"goal_id": "m.1.2.1", "operator": "ana", "station": "gs1", "fields": fields});
        put(
            "answers",
            &[&[i as u8][..], answer.to_string().as_bytes()].concat(),
        )?;
    }
    if let Some(path) = record_file {
        let text = std::fs::read_to_string(path)?;
        let lines: Vec<&str> = text.lines().collect();
        for chunk in lines.chunks(40) {
            put("record", chunk.join("\n").as_bytes())?;
        }
    }
    if let Some(dir) = store_dir {
        use executive_store::Store;
        let store = executive_store::SledStore::open(dir).map_err(std::io::Error::other)?;
        let raw = store.raw().map_err(std::io::Error::other)?;
        let _ = store.recover().map_err(std::io::Error::other)?;
        let text = |b: &[u8]| serde_json::Value::String(String::from_utf8_lossy(b).into_owned());
        let seq = |b: &[u8]| {
            serde_json::json!(
                b.get(..8)
                    .and_then(|k| k.try_into().ok())
                    .map_or(0, u64::from_be_bytes)
            )
        };
        // The start of the run: a whole flight's store is far over the fuzzer's input size.
        let steps: Vec<serde_json::Value> = raw
            .steps
            .iter()
            .take(12)
            .map(|s| {
                serde_json::json!([
                    seq(&s.key),
                    text(&s.input),
                    s.actions.as_deref().map_or(serde_json::Value::Null, text),
                    s.done.iter().map(|d| text(d)).collect::<Vec<_>>(),
                ])
            })
            .collect();
        let snapshot = raw
            .snapshot
            .as_ref()
            .map(|(k, v)| serde_json::json!([seq(k), text(v)]));
        let meta: Vec<serde_json::Value> = raw
            .meta
            .iter()
            .map(|(k, v)| serde_json::json!([text(k), text(v)]))
            .collect();
        put(
            "store",
            serde_json::json!({"snapshot": snapshot, "steps": steps, "meta": meta})
                .to_string()
                .as_bytes(),
        )?;
        put(
            "store",
            serde_json::json!({"steps": steps}).to_string().as_bytes(),
        )?;
        // The same run with a snapshot halfway, as a longer run keeps them.
        let rec = raw.decode().map_err(std::io::Error::other)?;
        let half = rec.steps.len().min(12) / 2;
        let mut engine = Engine::new(Arc::clone(&EUROPA));
        for step in &rec.steps[..half] {
            let _ = engine.step(step.input.clone());
        }
        let state = serde_json::to_string(engine.state())?;
        let at = rec
            .steps
            .get(half.saturating_sub(1))
            .map_or(0, |s| s.input.seq);
        put(
            "store",
            serde_json::json!({"snapshot": [at, state], "steps": &steps[half..], "meta": meta})
                .to_string()
                .as_bytes(),
        )?;
    }
    Ok(counts)
}

/// A value of type `t`, for seeds.
fn example(t: &connector_api::Type) -> serde_json::Value {
    use connector_api::Type;
    match t {
        Type::Optional(inner) => example(inner),
        Type::Bool => serde_json::json!(true),
        Type::Int | Type::Sized(_) => serde_json::json!(3),
        Type::Float => serde_json::json!(2.5),
        Type::String => serde_json::json!("A"),
        Type::Timestamp => serde_json::json!("2026-11-27T10:00:00Z"),
        Type::List(inner) => serde_json::json!([example(inner)]),
        Type::Object(fields) => serde_json::Value::Object(
            fields
                .iter()
                .map(|(k, t)| (k.clone(), example(t)))
                .collect(),
        ),
        Type::Json => serde_json::json!({"any": [1, "two"]}),
    }
}

/// Every file under `root` (recursively) whose name ends in `.ext`, sorted.
fn files(root: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == ext) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The expressions written in a BPMN text (condition bodies and `="…"` attribute values),
/// each with the first byte of the `expressions` target that picks its language.
fn expressions_in(text: &str) -> Vec<(u8, String)> {
    let unescape = |s: &str| {
        s.replace("&lt;", "<")
            .replace("&gt;", ">")
            .replace("&quot;", "\"")
            .replace("&apos;", "'")
            .replace("&amp;", "&")
    };
    let language = |s: &str| {
        let s = s.trim();
        if s.starts_with('=') {
            2
        } else if s.starts_with("${") || s.starts_with("#{") {
            1
        } else {
            0
        }
    };
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("Expression") {
        rest = &rest[i..];
        let (Some(gt), Some(end)) = (rest.find('>'), rest.find("</")) else {
            break;
        };
        if gt < end && !rest[..gt].ends_with('/') {
            let body = unescape(rest[gt + 1..end].trim());
            let body = body
                .trim_start_matches("<![CDATA[")
                .trim_end_matches("]]>")
                .trim()
                .to_owned();
            if !body.is_empty() && body.len() < 4096 {
                out.push((language(&body), body));
            }
        }
        rest = &rest["Expression".len()..];
    }
    let mut rest = text;
    while let Some(i) = rest.find("=\"=") {
        rest = &rest[i + 2..];
        if let Some(end) = rest.find('"') {
            out.push((2, unescape(&rest[..end])));
        }
    }
    out.sort();
    out.dedup();
    out
}
