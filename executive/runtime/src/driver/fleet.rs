//! One executive of a fleet (`trace run --participant POOL`): the driver's side of the fleet
//! link. The engine runs only the pool's process; a message flow into another pool's process
//! leaves the engine as a numbered `SendMessage`, committed with its step before it is sent,
//! sent until its receiver gives a verdict, and marked done only then (a restart sends the
//! unacknowledged ones again). A message from another executive is stepped like any input and
//! acknowledged once its step is committed; the engine refuses a key it has applied before
//! (acknowledged again as applied) and a message whose flow's target cannot take it (refused
//! with the reason, recorded and logged).

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use connector_api::Verdict;
use connector_api::wire::Letter;
use connector_zenoh::Fleet;
use executive_engine::{Event, Rejected, Value, Vars};
use executive_model::{ProcessGraph, ProcessId};

use super::{Driver, Report, RunError, crash_point, wall_ms};

/// How long an executive whose part has ended stays while a peer is still there (see
/// [`Post::linger`]).
const LINGER: Duration = Duration::from_secs(2);

/// The store's meta key listing, as of the newest snapshot, the messages no receiver had
/// acknowledged: their steps may be pruned after that snapshot, so a restart learns from here
/// that they must be sent again.
pub(super) const UNSENT: &str = "fleet-unsent";

/// The pool `given` (its id or name) of `g`'s collaboration, and the processes of the other
/// pools, each with its pool's id.
pub(super) fn resolve(
    g: &ProcessGraph,
    given: &str,
) -> Result<(String, BTreeMap<ProcessId, String>), RunError> {
    let remote = executive_engine::remote_processes(g, given).map_err(RunError::Participant)?;
    let id = g
        .participants()
        .find(|p| p.id == given || p.name.as_deref() == Some(given))
        .map_or_else(|| given.to_owned(), |p| p.id.clone());
    Ok((id, remote))
}

/// The fleet link of a running executive.
pub(super) struct Post {
    pub(super) fleet: Fleet,
    /// This executive's pool.
    pub(super) pool: String,
    /// The pools other executives run.
    pub(super) peers: BTreeSet<String>,
    /// Messages sent and not yet given a verdict, by key, with their place in the store
    /// (marked done once acknowledged).
    pub(super) unsent: BTreeMap<String, (Letter, Option<(u64, u32)>)>,
    /// Messages received, waiting to be stepped, with the verdict their sender waits for.
    pub(super) letters: Vec<(Event, Verdict)>,
    /// Messages sent and acknowledged, and received and applied, in this run.
    pub(super) counts: Counts,
    /// The pools this part, ended, last said it waits for.
    pub(super) waited_for: Vec<String>,
    /// The message flows a message has crossed, either way, in this run (for monitors).
    pub(super) crossed: BTreeSet<String>,
}

/// What crossed the fleet link in this run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Messages sent and applied by their receiver.
    pub delivered: u64,
    /// Messages sent and refused by their receiver.
    pub refused: u64,
    /// Messages received and applied (a resend counted once).
    pub received: u64,
}

impl Post {
    /// Joins the fleet as `pool` and waits at most `wait` for the executives of every other
    /// pool with a process. At a first start (`required`), a pool nothing runs is refused,
    /// named; a resumed part carries on without it (what it sends waits for it).
    pub(super) async fn join(
        session: &zenoh::Session,
        keys: connector_api::Keys,
        pool: &str,
        remote: &BTreeMap<ProcessId, String>,
        reports: connector_api::Reports,
        wait: Duration,
        required: bool,
    ) -> Result<Post, RunError> {
        let mut fleet = Fleet::join(session, keys.clone(), pool, reports)
            .await
            .map_err(|e| RunError::Io(format!("fleet link: {e}")))?;
        let peers: BTreeSet<String> = remote.values().cloned().collect();
        let list: Vec<String> = peers.iter().cloned().collect();
        let missing = fleet.wait_for(&list, wait).await;
        if !missing.is_empty() && !required {
            tracing::warn!(pools = ?missing, "resuming without these pools' executives; their messages wait for them");
        } else if !missing.is_empty() {
            fleet.close().await;
            return Err(RunError::PeersAbsent {
                pools: missing,
                deployment: keys.deployment().to_owned(),
                waited: wait,
            });
        }
        tracing::info!(pool, peers = ?list, "every pool of the collaboration has its executive");
        Ok(Post {
            fleet,
            pool: pool.to_owned(),
            peers,
            unsent: BTreeMap::new(),
            letters: Vec::new(),
            counts: Counts::default(),
            waited_for: Vec::new(),
            crossed: BTreeSet::new(),
        })
    }

    /// What a monitor's state query shows of the fleet (`docs/protocol.md` §8b).
    pub(super) fn state(&self) -> serde_json::Value {
        serde_json::json!({"pool": self.pool, "peers": self.fleet.peers(),
            "flows": self.crossed, "unacknowledged": self.unsent.keys().collect::<Vec<_>>()})
    }

    /// Before leaving: this executive stays, its `done` token declared, while another pool's
    /// executive is still there, for at most [`LINGER`]. A peer waiting for this part's end
    /// learns it from the token. Closed at once, the declaration can be lost with the session
    /// (seen across routers: a peer then saw only the `running` token go and waited for ever).
    pub(super) async fn linger(&self) {
        let start = std::time::Instant::now();
        while start.elapsed() < LINGER {
            let states = self.fleet.peers();
            let present = self.peers.iter().any(|p| {
                matches!(
                    states.get(p),
                    Some(connector_api::PeerState::Running | connector_api::PeerState::Done)
                )
            });
            if !present {
                return;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        tracing::debug!("left while another pool's executive is still there");
    }

    /// The pools whose executives have not ended their part (running or away).
    pub(super) fn peers_running(&self) -> Vec<String> {
        let states = self.fleet.peers();
        self.peers
            .iter()
            .filter(|p| states.get(*p) != Some(&connector_api::PeerState::Done))
            .cloned()
            .collect()
    }

    /// The letter for a message the engine sent to `to` along `flow`, keyed by the mission
    /// id and the engine's message number.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn letter(
        &self,
        mission: &str,
        number: u64,
        to: String,
        flow: String,
        name: String,
        correlation: Option<Value>,
        payload: &Vars,
    ) -> Letter {
        let payload = match serde_json::to_value(payload) {
            Ok(serde_json::Value::Object(m)) => m,
            _ => serde_json::Map::new(),
        };
        Letter {
            key: format!("{mission}.m{number}"),
            from: self.pool.clone(),
            to,
            flow,
            name,
            correlation: correlation.and_then(|c| serde_json::to_value(c).ok()),
            payload,
        }
    }

    /// Sends `letter` until acknowledged; `mark` is its action's place in the store.
    pub(super) fn send(&mut self, letter: Letter, mark: Option<(u64, u32)>) {
        self.crossed.insert(letter.flow.clone());
        let key = letter.key.clone();
        let entry = self
            .unsent
            .entry(key)
            .or_insert_with(|| (letter.clone(), mark));
        entry.1 = entry.1.or(mark);
        self.fleet.send(letter);
    }

    /// The unacknowledged letters, for the snapshot's meta.
    pub(super) fn unsent_json(&self) -> String {
        let letters: Vec<&Letter> = self.unsent.values().map(|(l, _)| l).collect();
        serde_json::to_string(&letters).unwrap_or_else(|_| "[]".to_owned())
    }

    /// Sends again the letters listed at the newest snapshot.
    pub(super) fn resend(&mut self, listed: Option<String>) {
        let letters: Vec<Letter> = listed
            .and_then(|l| serde_json::from_str(&l).ok())
            .unwrap_or_default();
        for l in letters {
            self.send(l, None);
        }
    }

    /// A letter's verdict arrived: its place in the store, to be marked done.
    pub(super) fn delivered(&mut self, key: &str, refused: &Option<String>) -> Option<(u64, u32)> {
        let (_, mark) = self.unsent.remove(key)?;
        match refused {
            None => self.counts.delivered += 1,
            Some(_) => self.counts.refused += 1,
        }
        mark
    }

    /// A letter from another executive: the input it is, queued with its verdict; or refused
    /// at once when it cannot have come along its flow.
    pub(super) fn received(&mut self, g: &ProcessGraph, letter: Letter, verdict: Verdict) {
        if let Err(why) = self.check(g, &letter) {
            tracing::warn!(
                key = letter.key,
                from = letter.from,
                flow = letter.flow,
                "message refused: {why}"
            );
            verdict.give(Err(why));
            return;
        }
        let payload: Vars = match serde_json::from_value(serde_json::Value::Object(letter.payload))
        {
            Ok(v) => v,
            Err(e) => {
                return verdict.give(Err(format!("the payload's values do not convert: {e}")));
            }
        };
        let correlation = match letter.correlation.map(serde_json::from_value::<Value>) {
            None => None,
            Some(Ok(c)) => Some(c),
            Some(Err(e)) => {
                return verdict.give(Err(format!("the correlation value does not convert: {e}")));
            }
        };
        self.letters.push((
            Event::MessageReceived {
                name: letter.name,
                correlation,
                payload,
                flow: Some(letter.flow),
                key: Some(letter.key),
            },
            verdict,
        ));
    }

    /// A letter must come from another pool of the collaboration — one another executive runs,
    /// or a black box (a pool without a process, §9.2, whose messages an outside system sends:
    /// access control says which) — along a message flow that leaves that pool (at one of its
    /// elements or at the pool itself).
    fn check(&self, g: &ProcessGraph, letter: &Letter) -> Result<(), String> {
        let black_box = letter.from != self.pool
            && g.participants()
                .any(|p| p.id == letter.from && p.process.is_none());
        if !self.peers.contains(&letter.from) && !black_box {
            return Err(format!(
                "`{}` is not another pool of this collaboration",
                letter.from
            ));
        }
        let flow = g
            .collaborations
            .iter()
            .flat_map(|c| &c.message_flows)
            .find(|m| m.id == letter.flow)
            .ok_or_else(|| format!("the model has no message flow `{}`", letter.flow))?;
        let pool = g.participants().find(|p| p.id == letter.from);
        let from_pool = flow.source == letter.from
            || g.node_by_id(&flow.source)
                .is_some_and(|n| pool.and_then(|p| p.process) == Some(g.process_of(n)));
        if from_pool {
            Ok(())
        } else {
            Err(format!(
                "message flow `{}` does not leave pool `{}`",
                letter.flow, letter.from
            ))
        }
    }

    /// The engine's refusal, as the sender's verdict: a key applied before is applied. `flow`
    /// is the message's.
    pub(super) fn verdict(&mut self, refused: Option<Rejected>, flow: &str) -> Result<(), String> {
        match refused {
            None => {
                self.counts.received += 1;
                self.crossed.insert(flow.to_owned());
                Ok(())
            }
            Some(Rejected::AlreadyDelivered(_)) => Ok(()),
            Some(r) => Err(r.to_string()),
        }
    }
}

impl Driver {
    /// Whether the run ends: every instance has ended and, in a fleet, every message was
    /// acknowledged and every other pool's executive has ended its part too (until then this
    /// one stays, done, and takes their messages: a peer that resumes may send again what this
    /// one already applied, and it needs the acknowledgement).
    pub(super) async fn part_done(&mut self) -> bool {
        let own = self.finished();
        let Some(post) = self.post.as_mut() else {
            return own;
        };
        post.fleet.set_done(own).await;
        if !own {
            return false;
        }
        let running = post.peers_running();
        if running.is_empty() {
            return true;
        }
        if post.waited_for != running {
            post.waited_for.clone_from(&running);
            tracing::info!(pools = ?running, "this part has ended; waiting for the other pools' executives to end theirs");
            eprintln!(
                "this pool's part has ended; waiting for {} to end theirs",
                running
                    .iter()
                    .map(|p| format!("pool `{p}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        false
    }

    /// No message of the fleet link waits to be stepped or acknowledged.
    pub(super) fn quiet_link(&self) -> bool {
        self.post
            .as_ref()
            .is_none_or(|p| p.unsent.is_empty() && p.letters.is_empty())
    }

    /// Messages from other executives, one step each: the verdict goes back once the step is
    /// committed, or with the engine's refusal (nothing changed).
    pub(super) fn apply_letters(&mut self) -> Result<(), RunError> {
        let letters = match self.post.as_mut() {
            Some(p) => std::mem::take(&mut p.letters),
            None => return Ok(()),
        };
        for (event, verdict) in letters {
            let (key, flow) = match &event {
                Event::MessageReceived { key, flow, .. } => (
                    key.clone().unwrap_or_default(),
                    flow.clone().unwrap_or_default(),
                ),
                _ => (String::new(), String::new()),
            };
            let refused = self.feed_all(vec![event])?.pop().flatten();
            if refused.is_none() {
                crash_point("letter-committed");
            }
            let Some(post) = self.post.as_mut() else {
                break;
            };
            let given = post.verdict(refused, &flow);
            if let Err(why) = &given {
                tracing::warn!(key, "message refused: {why}");
                self.fleet_line(
                    "message_refused",
                    serde_json::json!({"key": key, "reason": why, "by": "receiver"}),
                );
            }
            verdict.give(given);
        }
        Ok(())
    }

    /// A line of the execution record about the fleet link (not a step).
    pub(super) fn fleet_line(&mut self, kind: &str, body: serde_json::Value) {
        if let Err(e) = self.record.fleet(kind, self.clock.now(), wall_ms(), body) {
            tracing::warn!(error = %e, "record line not written");
        }
    }

    /// What the fleet link reported: a message to step, a verdict on one sent, a peer's state.
    pub(super) fn fleet_report(&mut self, report: Report) {
        match report {
            Report::Letter { letter, verdict } => {
                if let Some(p) = self.post.as_mut() {
                    p.received(&self.g, letter, verdict);
                } else {
                    verdict.give(Err("this executive runs no pool of a fleet".to_owned()));
                }
            }
            Report::Delivered { key, refused } => {
                crash_point("message-acknowledged");
                let mark = self.post.as_mut().and_then(|p| p.delivered(&key, &refused));
                self.acked.extend(mark);
                match &refused {
                    None => self.fleet_line("message_delivered", serde_json::json!({"key": key})),
                    Some(why) => {
                        tracing::warn!(key, "message refused by its receiver: {why}");
                        self.fleet_line(
                            "message_refused",
                            serde_json::json!({"key": key, "reason": why, "by": "sender"}),
                        );
                    }
                }
            }
            Report::Peer { pool, state } => {
                self.fleet_line("peer", serde_json::json!({"pool": pool, "state": state}));
            }
            _ => {}
        }
    }
}
