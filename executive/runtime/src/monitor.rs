//! Remote monitoring. The executive side (`Publisher`): a liveliness token
//! `<root>/alive/exec/<mission>`, every execution-record line on `<root>/exec/<mission>/record`,
//! a snapshot of the mission's present state on the queryable `<root>/exec/<mission>/state`,
//! so a monitor that joins late starts from the present, the mission model's XML on the
//! queryable `<root>/exec/<mission>/model`, so a view can draw it, and the record written so far
//! on `<root>/exec/<mission>/history`, so a view can draw its timeline. The monitor side is `trace monitor`
//! ([`watch`]).

use connector_api::Keys;
use connector_zenoh::{Role, ZenohArgs};
use executive_engine::Engine;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use tokio::sync::mpsc;
use zenoh::Session;
use zenoh::qos::CongestionControl;
use zenoh::query::Query;

/// The executive's live publication. State queries are handed to the driver, which answers
/// them between steps with a snapshot built then (nothing is built for nobody).
pub struct Publisher {
    _queryable: zenoh::query::Queryable<()>,
    _model: zenoh::query::Queryable<()>,
    state_key: String,
    _history: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
    lines: mpsc::UnboundedSender<String>,
}

impl Publisher {
    /// Declares the token, the model queryable (answered here with `model`, the BPMN XML), the
    /// history queryable (answered with the file `record` as it is then) and the state
    /// queryable (its queries arrive on the returned receiver); record lines go out in order on
    /// a task.
    pub async fn start(
        session: &Session,
        keys: &Keys,
        mission: &str,
        model: std::sync::Arc<[u8]>,
        record: std::path::PathBuf,
    ) -> Result<(Publisher, mpsc::UnboundedReceiver<Query>), zenoh::Error> {
        // The record so far, read when asked (a monitor that joins late draws its timeline).
        let (history_tx, mut history_queries) = mpsc::unbounded_channel::<Query>();
        // Replies go on the queryable's own key (a query may name a wildcard, on which access
        // control refuses replies).
        let history_key = keys.exec_history(mission);
        let model_key = keys.exec_model(mission);
        let history_queryable = session
            .declare_queryable(history_key.clone())
            .callback(move |q| {
                let _ = history_tx.send(q);
            })
            .await?;
        tokio::spawn(async move {
            while let Some(q) = history_queries.recv().await {
                let text = match tokio::fs::read(&record).await {
                    Ok(t) => t,
                    Err(e) => {
                        tracing::warn!(record = %record.display(), error = %e, "history not read");
                        continue;
                    }
                };
                if let Err(e) = q
                    .reply(history_key.clone(), text)
                    .encoding(zenoh::bytes::Encoding::TEXT_PLAIN.with_schema("trace.record/1"))
                    .await
                {
                    tracing::debug!(error = %e, "history reply failed");
                }
            }
        });
        // Model queries are answered on a task of this runtime, not in Zenoh's callback.
        let (model_tx, mut model_queries) = mpsc::unbounded_channel::<Query>();
        let model_queryable = session
            .declare_queryable(model_key.clone())
            .callback(move |q| {
                let _ = model_tx.send(q);
            })
            .await?;
        tokio::spawn(async move {
            while let Some(q) = model_queries.recv().await {
                if let Err(e) = q
                    .reply(model_key.clone(), &model[..])
                    .encoding(zenoh::bytes::Encoding::APPLICATION_XML)
                    .await
                {
                    tracing::debug!(error = %e, "model reply failed");
                }
            }
        });
        let (queries_tx, queries) = mpsc::unbounded_channel();
        let queryable = session
            .declare_queryable(keys.exec_state(mission))
            .callback(move |q| {
                let _ = queries_tx.send(q);
            })
            .await?;
        let token = session
            .liveliness()
            .declare_token(keys.alive("exec", mission))
            .await?;
        let (tx, mut rx) = mpsc::unbounded_channel::<String>();
        let (session, key) = (session.clone(), keys.exec_record(mission));
        tokio::spawn(async move {
            while let Some(line) = rx.recv().await {
                if let Err(e) = session
                    .put(&key, line)
                    .encoding(encoding("record"))
                    .congestion_control(CongestionControl::Block)
                    .await
                {
                    tracing::debug!(error = %e, "record line not published");
                }
            }
        });
        Ok((
            Publisher {
                _queryable: queryable,
                _model: model_queryable,
                state_key: keys.exec_state(mission),
                _history: history_queryable,
                _token: token,
                lines: tx,
            },
            queries,
        ))
    }

    /// The key the state is answered on.
    pub fn state_key(&self) -> &str {
        &self.state_key
    }

    /// A function handing record lines to the publication.
    pub fn mirror(&self) -> crate::record::Mirror {
        let tx = self.lines.clone();
        Box::new(move |line| {
            let _ = tx.send(line.to_owned());
        })
    }
}

/// `application/json;trace.<kind>/1`, as every protocol payload (`docs/protocol.md` §1a).
fn encoding(kind: &str) -> zenoh::bytes::Encoding {
    zenoh::bytes::Encoding::APPLICATION_JSON.with_schema(connector_api::wire::schema(kind))
}

/// The mission's present state, as a state query is answered.
pub fn snapshot(mission: &str, engine: &Engine, mission_ms: i64, in_flight: Vec<Value>) -> Value {
    let g = engine.graph();
    let s = engine.state();
    let mut tokens: BTreeMap<&str, usize> = BTreeMap::new();
    for t in s.tokens.values() {
        *tokens.entry(g.node(t.node).id.as_str()).or_default() += 1;
    }
    let instances: Vec<Value> = s
        .instances
        .iter()
        .map(|(id, i)| json!({ "instance": id.0, "outcome": i.outcome }))
        .collect();
    // The variables decisions read: those in sequence-flow conditions, as they are now.
    let read: std::collections::BTreeSet<&str> = g
        .flows
        .iter()
        .filter_map(|f| f.condition.as_ref())
        .flat_map(|c| c.variables.iter().map(String::as_str))
        .collect();
    let mut decision_vars = BTreeMap::new();
    for scope in s.scopes.values() {
        for (k, v) in &scope.vars {
            if read.contains(k.as_str()) {
                decision_vars.insert(k.as_str(), v);
            }
        }
    }
    // The timers armed now, by element, with their deadlines in mission time.
    let timers: Vec<Value> = s
        .waits
        .values()
        .filter_map(|w| match &w.on {
            executive_engine::On::Timer { due, .. } => {
                Some(json!({ "element": g.node(w.node).id, "due_ms": due }))
            }
            _ => None,
        })
        .collect();
    json!({
        "mission": mission,
        "seq": s.last_seq,
        "timers": timers,
        "mission_ms": mission_ms,
        "instances": instances,
        "tokens": tokens,
        "in_flight": in_flight,
        "decision_vars": decision_vars,
        "data": s.data,
    })
}

/// The live view of a snapshot: where the mission is, what runs, what waits for the ground,
/// and the values its decisions read.
pub fn board(snapshot: &Value) -> String {
    let mut out = String::new();
    let mut line = |s: String| {
        out.push_str(&s);
        out.push('\n');
    };
    let at = snapshot["mission_ms"]
        .as_i64()
        .and_then(chrono::DateTime::from_timestamp_millis)
        .map(|t| t.format("%Y-%m-%dT%H:%M:%SZ").to_string())
        .unwrap_or_default();
    line(format!(
        "── {} · step {} · mission time {at}",
        snapshot["mission"].as_str().unwrap_or("?"),
        snapshot["seq"]
    ));
    for i in snapshot["instances"].as_array().into_iter().flatten() {
        let status = match &i["outcome"] {
            Value::Null => "running".to_owned(),
            o => format!(
                "ended: {}",
                o.as_str().map_or_else(|| o.to_string(), str::to_owned)
            ),
        };
        line(format!("   instance {}: {status}", i["instance"]));
    }
    let active: Vec<String> = snapshot["tokens"]
        .as_object()
        .into_iter()
        .flatten()
        .map(|(e, n)| format!("{e} ×{n}"))
        .collect();
    line(format!("   active: {}", active.join(", ")));
    let flights = snapshot["in_flight"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    for f in flights.iter().filter(|f| f["user_task"] != true) {
        let progress = f["feedback"]["progress_pct"]
            .as_f64()
            .map(|p| format!(" {p:.0} %"))
            .unwrap_or_default();
        line(format!(
            "   in flight: {}{progress} ({})",
            f["resource"].as_str().unwrap_or("?"),
            f["name"].as_str().unwrap_or("?")
        ));
    }
    for f in flights.iter().filter(|f| f["user_task"] == true) {
        let deadline = f["deadline_ms"]
            .as_i64()
            .and_then(chrono::DateTime::from_timestamp_millis)
            .map(|t| format!(", deadline {}", t.format("%Y-%m-%dT%H:%M:%SZ")))
            .unwrap_or_default();
        line(format!(
            "   open user task: {} ({}{deadline})",
            f["name"].as_str().unwrap_or("?"),
            f["goal"].as_str().unwrap_or("?")
        ));
    }
    // System data is the newest value of a key a scope may also hold.
    let values: BTreeMap<&String, &Value> = snapshot["decision_vars"]
        .as_object()
        .into_iter()
        .flatten()
        .chain(snapshot["data"].as_object().into_iter().flatten())
        .collect();
    let values: Vec<String> = values
        .into_iter()
        .map(|(k, v)| format!("{k}={}", short(v)))
        .collect();
    if !values.is_empty() {
        line(format!("   decisions read: {}", values.join(", ")));
    }
    // Messages the connectors refused: zero is not news.
    for (connector, d) in snapshot["dropped"].as_object().into_iter().flatten() {
        if d["total"].as_u64().unwrap_or(0) == 0 {
            continue;
        }
        let reasons: Vec<String> = d["by_reason"]
            .as_object()
            .into_iter()
            .flatten()
            .map(|(reason, n)| format!("{reason} {n}"))
            .collect();
        line(format!(
            "   refused from {connector}: {} ({})",
            d["total"],
            reasons.join(", ")
        ));
    }
    out
}

/// Why [`watch`] stopped early.
#[derive(Debug, thiserror::Error)]
pub enum WatchError {
    /// The Zenoh session or its configuration.
    #[error(transparent)]
    Session(#[from] connector_zenoh::SessionError),
    /// A Zenoh operation failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// The output could not be written.
    #[error(transparent)]
    Output(#[from] std::io::Error),
    /// The liveliness subscription ended before a mission was found.
    #[error("the monitor stopped before it found an executive")]
    Stopped,
}

fn zenoh_error(e: impl std::fmt::Display) -> WatchError {
    WatchError::Zenoh(e.to_string())
}

/// How often the readable view shows the board again (when something happened).
const BOARD_EVERY: std::time::Duration = std::time::Duration::from_secs(2);

/// Asks the executive for its present state.
async fn state(session: &zenoh::Session, key: &str) -> Result<Value, WatchError> {
    let replies = session
        .get(key)
        .with(connector_zenoh::replies())
        .await
        .map_err(zenoh_error)?;
    Ok(match replies.recv_async().await {
        Ok(r) => r
            .result()
            .ok()
            .and_then(|s| serde_json::from_slice(&s.payload().to_bytes()).ok())
            .unwrap_or(Value::Null),
        Err(_) => Value::Null,
    })
}

/// Answers one state query, on the state's own key `key` (a query may name a wildcard, on
/// which access control refuses replies).
pub async fn answer(query: Query, key: &str, snapshot: Value) {
    if let Err(e) = query
        .reply(key, snapshot.to_string())
        .encoding(encoding("exec_state"))
        .await
    {
        tracing::debug!(error = %e, "state reply failed");
    }
}

/// `trace monitor`: finds a running mission (or the one named), prints its present state, then
/// every record line as it happens — readable (with the state board again every few seconds
/// while things happen), or raw JSON Lines with `jsonl`. Returns when the mission's executive
/// goes away (or after `lines` record lines, for tools and tests; 0: the present state only).
pub async fn watch(
    zenoh: &ZenohArgs,
    mission: Option<String>,
    jsonl: bool,
    lines: Option<usize>,
    out: &mut (dyn std::io::Write + Send),
) -> Result<(), WatchError> {
    let session = zenoh.open(Role::Spoke).await.map_err(zenoh_error)?;
    let keys = zenoh.keys()?;
    // Monitors announce themselves like every other process (`docs/protocol.md` §6).
    let _me = session
        .liveliness()
        .declare_token(keys.alive("monitor", &format!("monitor-{}", std::process::id())))
        .await
        .map_err(zenoh_error)?;
    // Which mission: the one named, else the first executive alive.
    let (alive_tx, mut alive_rx) = mpsc::unbounded_channel::<(String, bool)>();
    let prefix = format!("{}/alive/exec/", keys.root());
    let _alive = session
        .liveliness()
        .declare_subscriber(format!("{prefix}*"))
        .history(true)
        .callback(move |s| {
            let id = s.key_expr().as_str().trim_start_matches(&prefix).to_owned();
            let _ = alive_tx.send((id, s.kind() == zenoh::sample::SampleKind::Put));
        })
        .await
        .map_err(zenoh_error)?;
    // Said after a few seconds, then every half minute, for as long as no executive is there.
    let mut waiting = tokio::time::interval_at(
        tokio::time::Instant::now() + std::time::Duration::from_secs(5),
        std::time::Duration::from_secs(30),
    );
    let mission = loop {
        tokio::select! {
            a = alive_rx.recv() => match a {
                Some((id, true)) if mission.as_ref().is_none_or(|m| *m == id) => break id,
                Some(_) => {}
                None => return Err(WatchError::Stopped),
            },
            _ = waiting.tick() => tracing::warn!(
                deployment = keys.deployment(),
                mission = mission.as_deref().unwrap_or("any"),
                "waiting for an executive to watch"
            ),
        }
    };
    // Subscribe first, then take the snapshot, so nothing falls between them.
    let (tx, mut rx) = mpsc::unbounded_channel::<String>();
    let _sub = session
        .declare_subscriber(keys.exec_record(&mission))
        .callback(move |s| {
            let _ = tx.send(String::from_utf8_lossy(&s.payload().to_bytes()).into_owned());
        })
        .await
        .map_err(zenoh_error)?;
    let snapshot = state(&session, &keys.exec_state(&mission)).await?;
    let seq0 = snapshot["seq"].as_u64().unwrap_or(0);
    if jsonl {
        writeln!(out, "{}", json!({ "kind": "snapshot", "state": snapshot }))?;
    } else {
        write!(out, "{}", board(&snapshot))?;
    }
    out.flush()?;
    let mut printed = 0;
    // The readable view shows the board again every few seconds while lines arrive.
    let mut refresh = tokio::time::interval(BOARD_EVERY);
    refresh.tick().await;
    let mut fresh = true;
    while lines.is_none_or(|n| printed < n) {
        let line = tokio::select! {
            l = rx.recv() => l,
            a = alive_rx.recv() => match a {
                Some((id, false)) if id == mission => None,
                _ => continue,
            },
            _ = refresh.tick(), if !jsonl => {
                if !fresh {
                    let now = state(&session, &keys.exec_state(&mission)).await?;
                    write!(out, "{}", board(&now))?;
                    out.flush()?;
                    fresh = true;
                }
                continue;
            }
        };
        let Some(line) = line else { break };
        let Ok(v) = serde_json::from_str::<Value>(&line) else {
            tracing::warn!("an unreadable record line was ignored");
            continue;
        };
        // Lines the snapshot already covers are skipped.
        if v["seq"].as_u64().is_some_and(|s| s <= seq0) {
            continue;
        }
        if jsonl {
            writeln!(out, "{line}")?;
        } else {
            writeln!(
                out,
                "  {} {}",
                v["kind"].as_str().unwrap_or("?"),
                describe(&v)
            )?;
        }
        out.flush()?;
        printed += 1;
        fresh = false;
    }
    session.close().await.map_err(zenoh_error)?;
    Ok(())
}

/// A value for people: numbers to two decimals.
fn short(v: &Value) -> String {
    match v.as_f64() {
        Some(f) if v.is_f64() => format!("{f:.2}"),
        _ => v.to_string(),
    }
}

fn describe(v: &Value) -> String {
    let element = v["element"]["name"]
        .as_str()
        .or_else(|| v["element"]["id"].as_str())
        .unwrap_or("");
    match v["kind"].as_str().unwrap_or_default() {
        "dispatched" => format!("{} ({element})", v["resource"].as_str().unwrap_or("?")),
        "failed" => format!(
            "{} {}",
            v["code"].as_str().unwrap_or("?"),
            v["message"].as_str().unwrap_or("")
        ),
        "completed" => v["task"].as_str().unwrap_or("").to_owned(),
        "feedback" => format!(
            "{} {}",
            v["goal"].as_str().unwrap_or("?"),
            v["progress_pct"]
                .as_f64()
                .map(|p| format!("{p:.0} %"))
                .unwrap_or_default()
        ),
        "accepted" => v["goal"].as_str().unwrap_or("?").to_owned(),
        "data" => format!(
            "{}={}",
            v["key"].as_str().unwrap_or("?"),
            short(&v["value"])
        ),
        "took" => v["flow"].as_str().unwrap_or("").to_owned(),
        "decided" => format!(
            "{element}: read {}",
            v["read"]
                .as_object()
                .into_iter()
                .flatten()
                .map(|(k, x)| format!("{k}={}", short(x)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        "user_task_answered" => format!(
            "{} by {}: {}",
            v["task"].as_str().unwrap_or("?"),
            v["operator"].as_str().unwrap_or("?"),
            v["answer"]
        ),
        "thrown" | "caught" => format!(
            "{} {} {element}",
            v["what"].as_str().unwrap_or(""),
            v["name"].as_str().unwrap_or("")
        ),
        _ => element.to_owned(),
    }
}
