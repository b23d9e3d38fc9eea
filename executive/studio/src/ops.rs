//! Operations: the running missions, followed live as `trace monitor` follows them
//! (`docs/protocol.md` §8b), for the studio's operations view. The studio's Zenoh membership
//! ([`Live`]) finds the executives by their liveliness tokens, asks one for its model (to draw
//! it) and follows it: its present state first, then every record line as it is written, the
//! state asked again after each burst of lines (so the tokens shown are always the engine's
//! own), and its going and coming back (a restarted executive). The record lines it has of a
//! mission (the last `history` reply and the lines followed since) are kept, so a mission's
//! timeline stays once its executive has left.

use std::collections::BTreeMap;
use std::time::Duration;

use serde::Serialize;
use serde_json::Value;
use tokio::sync::mpsc;

use crate::live::{Live, LiveError};

/// How many missions' records [`Books`] keeps (the least recently written one goes first).
const BOOKS_KEPT: usize = 16;

/// How long a state or model query waits for the executive.
const ASK_FOR: Duration = Duration::from_secs(5);

/// After record lines arrive, the state is asked again once this long has passed without more.
const SETTLE: Duration = Duration::from_millis(150);

/// One executive the studio has seen.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Presence {
    /// Its mission id.
    pub mission: String,
    /// Its liveliness token is declared now.
    pub alive: bool,
    /// How many times it came back after going (restarts seen by this studio).
    pub reboots: u32,
}

/// What following a mission tells the page, in order.
#[derive(Clone, Debug, PartialEq)]
pub enum Happening {
    /// The mission's present state (`docs/protocol.md` §8b), first and after record lines.
    State(Value),
    /// One execution-record line (`docs/record.md`) newer than the last state, parsed (what
    /// the page gets is written again from it: never raw bytes from the network).
    Line(Value),
    /// The executive is gone (its token was withdrawn: stopped, or crashed).
    Gone,
    /// It is back (a restart); a fresh state follows.
    Back,
}

/// Why a query to an executive gave nothing.
#[derive(Debug, thiserror::Error)]
pub enum AskError {
    /// No executive of that mission answered in time.
    #[error("mission `{0}`: no executive answered (is it running?)")]
    NoAnswer(String),
    /// Zenoh refused the query.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

/// The record lines the studio has of each mission, by their `line` number (`docs/record.md`):
/// a line met in a `history` reply and on the stream is kept once.
#[derive(Debug, Default)]
pub struct Books {
    books: BTreeMap<String, (u64, BTreeMap<u64, String>)>,
    writes: u64,
}

impl Books {
    /// Keeps record line `line` (its text) of `mission`; a line without a number is not kept.
    fn keep(&mut self, mission: &str, line: &Value, text: &str) {
        let Some(n) = line["line"].as_u64() else {
            return;
        };
        self.writes += 1;
        if !self.books.contains_key(mission) && self.books.len() == BOOKS_KEPT {
            let oldest = self
                .books
                .iter()
                .min_by_key(|(_, (at, _))| *at)
                .map(|(m, _)| m.clone());
            if let Some(m) = oldest {
                self.books.remove(&m);
            }
        }
        let book = self.books.entry(mission.to_owned()).or_default();
        book.0 = self.writes;
        book.1.entry(n).or_insert_with(|| text.to_owned());
    }

    /// The record of `mission` as kept, one line each, in order; `None` if none was kept.
    fn text(&self, mission: &str) -> Option<String> {
        let (_, lines) = self.books.get(mission)?;
        let mut out = String::new();
        for l in lines.values() {
            out.push_str(l);
            out.push('\n');
        }
        Some(out)
    }
}

enum Raw {
    Line(String),
    Token(bool),
}

impl Live {
    /// Every executive seen, by mission id.
    pub fn executives(&self) -> Vec<Presence> {
        self.executives_seen()
            .lock()
            .map(|m| m.values().cloned().collect())
            .unwrap_or_default()
    }

    /// The model mission `mission` runs: its BPMN XML as the executive read it.
    pub async fn model(&self, mission: &str) -> Result<Vec<u8>, AskError> {
        self.ask_one(&self.keys().exec_model(mission), mission)
            .await
    }

    /// The execution record the mission's executive has written so far: its `history` reply
    /// with the lines followed since; once the executive has left (the mission ended, or it
    /// stopped), what the studio kept of it.
    pub async fn history(&self, mission: &str) -> Result<String, AskError> {
        let asked = self
            .ask_one(&self.keys().exec_history(mission), mission)
            .await;
        let mut books = self.books();
        match asked {
            Ok(bytes) => {
                let text = String::from_utf8_lossy(&bytes);
                for l in text.lines() {
                    if let Ok(v) = serde_json::from_str::<Value>(l) {
                        books.keep(mission, &v, l);
                    }
                }
                // A record without line numbers (written before they were) as it came.
                Ok(books.text(mission).unwrap_or_else(|| text.into_owned()))
            }
            Err(e) => books.text(mission).ok_or(e),
        }
    }

    /// The mission's present state.
    pub async fn state(&self, mission: &str) -> Result<Value, AskError> {
        let bytes = self
            .ask_one(&self.keys().exec_state(mission), mission)
            .await?;
        serde_json::from_slice(&bytes).map_err(|e| {
            tracing::warn!(mission, "an unreadable state reply: {e}");
            AskError::NoAnswer(mission.to_owned())
        })
    }

    async fn ask_one(&self, key: &str, mission: &str) -> Result<Vec<u8>, AskError> {
        let replies = self
            .session()
            .get(key)
            .timeout(ASK_FOR)
            .with(connector_zenoh::replies())
            .await
            .map_err(|e| AskError::Zenoh(e.to_string()))?;
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result() {
                return Ok(sample.payload().to_bytes().into_owned());
            }
        }
        Err(AskError::NoAnswer(mission.to_owned()))
    }

    /// Follows mission `mission`: what happens arrives on the returned channel until it is
    /// dropped. Subscribes first, then asks the present, so nothing falls between them.
    pub async fn follow(
        self: &std::sync::Arc<Self>,
        mission: &str,
    ) -> Result<mpsc::UnboundedReceiver<Happening>, LiveError> {
        let keys = self.keys().clone();
        let (raw_tx, mut raw) = mpsc::unbounded_channel::<Raw>();
        let tx = raw_tx.clone();
        let lines = self
            .session()
            .declare_subscriber(keys.exec_record(mission))
            .callback(move |s| {
                let _ = tx.send(Raw::Line(
                    String::from_utf8_lossy(&s.payload().to_bytes()).into_owned(),
                ));
            })
            .await
            .map_err(|e| LiveError::Zenoh(e.to_string()))?;
        let tokens = self
            .session()
            .liveliness()
            .declare_subscriber(keys.alive("exec", mission))
            // With history: a token declared before this subscription is known to it, so its
            // withdrawal is heard too (the first put is the present, not a return).
            .history(true)
            .callback(move |s| {
                let _ = raw_tx.send(Raw::Token(s.kind() == zenoh::sample::SampleKind::Put));
            })
            .await
            .map_err(|e| LiveError::Zenoh(e.to_string()))?;
        let (out, happenings) = mpsc::unbounded_channel();
        let live = std::sync::Arc::clone(self);
        let mission = mission.to_owned();
        tokio::spawn(async move {
            // The subscriptions live as long as the page follows.
            let _keep = (lines, tokens);
            let mut seq0 = present(&live, &mission, &out).await;
            let mut dirty = false;
            let mut gone = seq0.is_none();
            loop {
                tokio::select! {
                    () = out.closed() => break,
                    () = tokio::time::sleep(SETTLE), if dirty => {
                        dirty = false;
                        match present(&live, &mission, &out).await {
                            Some(s) => seq0 = Some(s),
                            None => gone = true,
                        }
                    }
                    raw = raw.recv() => match raw {
                        None => break,
                        Some(Raw::Line(line)) => {
                            let Some(line) = serde_json::from_str::<Value>(&line)
                                .ok()
                                .filter(|v| v["kind"].is_string())
                            else {
                                tracing::warn!(%mission, "an unreadable record line was ignored");
                                continue;
                            };
                            live.books().keep(&mission, &line, &line.to_string());
                            // An engine step's lines: those the state already holds are
                            // skipped, the others ask for the state again. Lines of no step
                            // (accepted, feedback, reboot) pass as they are.
                            if let Some(seq) = line["seq"].as_u64() {
                                if seq0.is_some_and(|s| seq <= s) {
                                    continue;
                                }
                                dirty = true;
                            }
                            let _ = out.send(Happening::Line(line));
                        }
                        Some(Raw::Token(false)) => {
                            gone = true;
                            let _ = out.send(Happening::Gone);
                        }
                        Some(Raw::Token(true)) if gone => {
                            gone = false;
                            let _ = out.send(Happening::Back);
                            match present(&live, &mission, &out).await {
                                Some(s) => seq0 = Some(s),
                                None => gone = true,
                            }
                        }
                        Some(Raw::Token(true)) => {}
                    }
                }
            }
            tracing::debug!(%mission, "stopped following");
        });
        Ok(happenings)
    }
}

/// Asks the state and sends it; its step, or `None` if no executive answered (then the
/// page is told it is gone).
async fn present(
    live: &Live,
    mission: &str,
    out: &mpsc::UnboundedSender<Happening>,
) -> Option<u64> {
    match live.state(mission).await {
        Ok(state) => {
            let seq = state["seq"].as_u64();
            let _ = out.send(Happening::State(state));
            seq
        }
        Err(e) => {
            tracing::info!("{e}");
            let _ = out.send(Happening::Gone);
            None
        }
    }
}

/// Records a token of `<root>/alive/exec/<mission>` appearing or going.
pub(crate) fn seen(map: &mut BTreeMap<String, Presence>, mission: &str, alive: bool) {
    let p = map.entry(mission.to_owned()).or_insert_with(|| Presence {
        mission: mission.to_owned(),
        alive,
        reboots: 0,
    });
    if alive && !p.alive {
        p.reboots += 1;
    }
    p.alive = alive;
}
