//! The fleet link (`docs/protocol.md` §8c): the executive of one pool of a collaboration, its
//! presence, and the messages its message flows carry to and from the executives of the other
//! pools.
//!
//! A message is sent as a query on `<root>/fleet/<to>/message/<from>/<key>` and sent again, with
//! backoff, until a reply gives the receiver's verdict: applied (committed by its step, now or
//! on an earlier try) or refused with a reason. Both are final. A query that gets no verdict
//! (the receiver is down, the link is cut, the receiver is stopping) is tried again, however
//! long that takes, and said in the log every 30 s. The receiver replies only once its step is
//! committed, so an acknowledged message survives the receiver's crash; the sender marks it
//! done only when acknowledged, so an unacknowledged one survives the sender's crash; and the
//! key makes every repetition harmless.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use connector_api::wire::{self, Letter, LetterReply};
use connector_api::{Keys, PeerState, Report, Reports, Verdict};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::query::{ConsolidationMode, Query, Queryable};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

use crate::codec::{encoding, json};
use crate::drops::{Drops, Reason};

/// How long one try waits for the receiver's verdict.
const TRY_WAIT: Duration = Duration::from_secs(5);
/// The pause after the first failed try, doubled after each up to [`MAX_PAUSE`].
const FIRST_PAUSE: Duration = Duration::from_millis(100);
const MAX_PAUSE: Duration = Duration::from_secs(2);
/// How often a message still unacknowledged is said in the log.
const SAY_EVERY: Duration = Duration::from_secs(30);

/// Why the fleet link could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    /// A pool id that cannot be a key chunk.
    #[error("pool id: {0}")]
    Pool(#[from] connector_api::keys::BadChunk),
    /// Zenoh refused a declaration.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

struct Shared {
    session: Session,
    keys: Keys,
    pool: String,
    reports: Reports,
    rt: tokio::runtime::Handle,
    /// Messages being sent, by key.
    sending: Mutex<HashMap<String, tokio::task::JoinHandle<()>>>,
    /// The state of each pool's executive seen so far (this one's among them).
    peers: tokio::sync::watch::Sender<BTreeMap<String, PeerState>>,
    drops: Drops,
}

/// This executive's place in a fleet: its presence, its inbox, and its messages in flight.
pub struct Fleet {
    shared: Arc<Shared>,
    /// The presence token, and whether it says `done`.
    alive: Option<(LivelinessToken, bool)>,
    inbox: Option<Queryable<()>>,
    peers: Option<Subscriber<()>>,
}

impl Fleet {
    /// Joins the fleet as the executive of `pool`: declares its presence and its inbox, and
    /// follows the other executives' presence. Received messages and the verdicts on sent ones
    /// come back on `reports`.
    pub async fn join(
        session: &Session,
        keys: Keys,
        pool: &str,
        reports: Reports,
    ) -> Result<Fleet, FleetError> {
        connector_api::keys::check_chunk(pool)?;
        let z = |e: zenoh::Error| FleetError::Zenoh(e.to_string());
        let shared = Arc::new(Shared {
            session: session.clone(),
            keys: keys.clone(),
            pool: pool.to_owned(),
            reports,
            rt: tokio::runtime::Handle::current(),
            sending: Mutex::new(HashMap::new()),
            peers: tokio::sync::watch::Sender::new(BTreeMap::new()),
            drops: Drops::new(&format!("fleet:{pool}"), Duration::from_secs(10)),
        });
        let me = Arc::clone(&shared);
        let peers = session
            .liveliness()
            .declare_subscriber(keys.fleet_alive_all())
            .history(true)
            .callback(move |s| me.on_peer(s.key_expr().as_str(), s.kind()))
            .await
            .map_err(z)?;
        let me = Arc::clone(&shared);
        let inbox = session
            .declare_queryable(keys.fleet_inbox(pool))
            .complete(true)
            .callback(move |q| me.on_letter(q))
            .await
            .map_err(z)?;
        let alive = session
            .liveliness()
            .declare_token(keys.fleet_alive(pool, "running"))
            .await
            .map_err(z)?;
        tracing::info!(pool, "joined the fleet");
        Ok(Fleet {
            shared,
            alive: Some((alive, false)),
            inbox: Some(inbox),
            peers: Some(peers),
        })
    }

    /// The state of each pool's executive seen so far (this one's among them).
    pub fn peers(&self) -> BTreeMap<String, PeerState> {
        self.shared.peers.borrow().clone()
    }

    /// Waits at most `wait` for the executives of `pools`; returns those still absent.
    pub async fn wait_for(&self, pools: &[String], wait: Duration) -> Vec<String> {
        let mut rx = self.shared.peers.subscribe();
        let missing = |p: &BTreeMap<String, PeerState>| -> Vec<String> {
            pools
                .iter()
                .filter(|x| p.get(*x).is_none_or(|s| *s == PeerState::Absent))
                .cloned()
                .collect()
        };
        let _ = tokio::time::timeout(wait, rx.wait_for(|p| missing(p).is_empty())).await;
        missing(&self.peers())
    }

    /// Says whether this executive's part has ended with every message acknowledged (`done`)
    /// or runs: the new token is declared before the old one goes, so peers never see it
    /// absent.
    pub async fn set_done(&mut self, done: bool) {
        if self.alive.as_ref().is_none_or(|(_, d)| *d == done) {
            return;
        }
        let state = if done { "done" } else { "running" };
        let key = self.shared.keys.fleet_alive(&self.shared.pool, state);
        match self.shared.session.liveliness().declare_token(key).await {
            Ok(token) => {
                if let Some((old, _)) = self.alive.replace((token, done))
                    && let Err(e) = old.undeclare().await
                {
                    tracing::debug!(error = %e, "fleet presence undeclare failed");
                }
                tracing::info!(pool = self.shared.pool, state, "fleet part");
            }
            Err(e) => tracing::warn!(error = %e, state, "fleet presence not declared"),
        }
    }

    /// Sends `letter` until its receiver gives a verdict, reported as [`Report::Delivered`].
    /// A letter already being sent (the same key) is not sent twice.
    pub fn send(&self, letter: Letter) {
        let mut sending = self.shared.in_flight();
        if sending.contains_key(&letter.key) {
            return;
        }
        let key = letter.key.clone();
        let task = self
            .shared
            .rt
            .spawn(Arc::clone(&self.shared).deliver(letter));
        sending.insert(key, task);
    }

    /// The keys of the messages sent and not yet given a verdict.
    pub fn unacknowledged(&self) -> Vec<String> {
        let mut keys: Vec<String> = self.shared.in_flight().keys().cloned().collect();
        keys.sort();
        keys
    }

    /// Messages refused at the door (unreadable, or addressed to another pool), by reason.
    pub fn dropped(&self) -> connector_api::contract::Dropped {
        self.shared.drops.counts()
    }

    /// Stops sending (what is unacknowledged stays in the store and is sent on resume) and
    /// withdraws the presence and the inbox. A letter's verdict is replied where it is given, so
    /// none given before this is lost with the process; one dropped ungiven tells its sender to
    /// try again.
    pub async fn close(&mut self) {
        for (_, h) in self.shared.in_flight().drain() {
            h.abort();
        }
        if let Some((t, _)) = self.alive.take()
            && let Err(e) = t.undeclare().await
        {
            tracing::debug!(error = %e, "fleet presence undeclare failed");
        }
        if let Some(q) = self.inbox.take()
            && let Err(e) = q.undeclare().await
        {
            tracing::debug!(error = %e, "fleet inbox undeclare failed");
        }
        if let Some(s) = self.peers.take()
            && let Err(e) = s.undeclare().await
        {
            tracing::debug!(error = %e, "fleet presence subscriber undeclare failed");
        }
    }
}

impl Shared {
    /// The letters being sent, by key (those whose task has ended dropped).
    fn in_flight(&self) -> std::sync::MutexGuard<'_, HashMap<String, tokio::task::JoinHandle<()>>> {
        let mut sending = self.sending.lock().unwrap_or_else(|p| p.into_inner());
        sending.retain(|_, h| !h.is_finished());
        sending
    }

    fn report(&self, r: Report) {
        if self.reports.send(r).is_err() {
            tracing::debug!("the executive no longer listens to the fleet link");
        }
    }

    /// A peer's token came or went: `running` and `done` set its state; a `running` token
    /// gone means it went away running; a `done` token gone leaves it done (it left after its
    /// part ended, or it runs again, which its new `running` token, declared first, said).
    fn on_peer(&self, key: &str, kind: SampleKind) {
        let Some((pool, token)) = self.keys.fleet_pool_of(key) else {
            return;
        };
        let next = match (token, kind) {
            ("running", SampleKind::Put) => Some(PeerState::Running),
            ("done", SampleKind::Put) => Some(PeerState::Done),
            ("running", SampleKind::Delete) => Some(PeerState::Absent),
            _ => None,
        };
        let Some(state) = next else { return };
        let changed = self.peers.send_if_modified(|p| {
            // A `running` token gone after `done` came: the peer flipped, it is done.
            if state == PeerState::Absent && p.get(pool) == Some(&PeerState::Done) {
                return false;
            }
            p.insert(pool.to_owned(), state) != Some(state)
        });
        if changed && pool != self.pool {
            match state {
                PeerState::Absent => tracing::warn!(pool, "fleet executive gone"),
                _ => tracing::info!(pool, ?state, "fleet executive"),
            }
            self.report(Report::Peer {
                pool: pool.to_owned(),
                state,
            });
        }
    }

    /// One letter, tried until its receiver gives a verdict.
    async fn deliver(self: Arc<Shared>, letter: Letter) {
        let key = self
            .keys
            .fleet_message(&letter.to, &letter.from, &letter.key);
        let payload = json(&letter);
        let started = Instant::now();
        let mut said = started;
        let mut pause = FIRST_PAUSE;
        let mut tries: u64 = 0;
        loop {
            tries += 1;
            match self.try_once(&key, &payload, &letter.key).await {
                Ok(reply) => {
                    match &reply.reason {
                        None if reply.applied => tracing::info!(
                            key = letter.key,
                            to = letter.to,
                            flow = letter.flow,
                            tries,
                            "message delivered"
                        ),
                        reason => tracing::warn!(
                            key = letter.key,
                            to = letter.to,
                            flow = letter.flow,
                            tries,
                            reason = reason.as_deref().unwrap_or("none given"),
                            "message refused by its receiver"
                        ),
                    }
                    return;
                }
                Err(why) => {
                    if tries == 1 || said.elapsed() >= SAY_EVERY {
                        said = Instant::now();
                        tracing::warn!(
                            key = letter.key,
                            to = letter.to,
                            flow = letter.flow,
                            tries,
                            waited_s = started.elapsed().as_secs(),
                            "message not acknowledged yet ({why}); sending it again until it is"
                        );
                    } else {
                        tracing::debug!(key = letter.key, tries, %why, "message try failed");
                    }
                }
            }
            tokio::time::sleep(pause).await;
            pause = (pause * 2).min(MAX_PAUSE);
        }
    }

    /// One try: the receiver's verdict, or why there is none. A verdict is reported to the
    /// executive from Zenoh's callback as it arrives (the first reply decides), before this
    /// task hears of it.
    async fn try_once(
        self: &Arc<Shared>,
        key: &str,
        payload: &[u8],
        letter: &str,
    ) -> Result<LetterReply, String> {
        let (tx, rx) = tokio::sync::oneshot::channel();
        let first = Mutex::new(Some(tx));
        let (me, name) = (Arc::clone(self), letter.to_owned());
        self.session
            .get(key)
            .payload(payload.to_vec())
            .encoding(encoding("letter"))
            .consolidation(ConsolidationMode::None)
            .timeout(TRY_WAIT)
            .callback(move |reply| {
                let Some(tx) = first.lock().unwrap_or_else(|p| p.into_inner()).take() else {
                    return tracing::debug!(letter = name, "a later reply to a letter; dropped");
                };
                let verdict = verdict_of(&reply, &name);
                if let Ok(r) = &verdict {
                    // No longer in flight once it has its verdict (before it is reported).
                    me.in_flight().remove(&name);
                    me.report(Report::Delivered {
                        key: name.clone(),
                        refused: (!r.applied).then(|| {
                            r.reason
                                .clone()
                                .unwrap_or_else(|| "no reason given".to_owned())
                        }),
                    });
                }
                let _ = tx.send(verdict);
            })
            .await
            .map_err(|e| format!("zenoh: {e}"))?;
        rx.await
            .map_err(|_| "no executive of that pool answered".to_owned())?
    }

    /// A letter for this pool: checked at the door (in Zenoh's callback, as it arrives), then
    /// stepped by the executive, which replies with the verdict from its own step once it is
    /// committed ([`Verdict::call`]): no task of the link is woken between the commit and the
    /// reply. A letter the executive drops unstepped (it stops) tells its sender to try again.
    fn on_letter(&self, query: Query) {
        let key = query.key_expr().as_str().to_owned();
        let bytes = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let letter = match wire::parse::<Letter>("letter", &key, &bytes) {
            Ok(l) => l,
            Err(e) => {
                self.drops
                    .drop(Reason::Garbage, &key, "letter", "", &e.to_string());
                return reply_err(&query, &e.to_string());
            }
        };
        let chunk = Keys::last_chunk(&key);
        let sender = key.rsplit('/').nth(1).unwrap_or_default();
        let wrong = if letter.key != chunk {
            Some(format!(
                "the letter is keyed `{}` but was sent on `{chunk}`",
                letter.key
            ))
        } else if letter.from != sender {
            Some(format!(
                "the letter is from pool `{}` but was sent as `{sender}`",
                letter.from
            ))
        } else if letter.to != self.pool {
            Some(format!(
                "the letter is for pool `{}`, this executive runs `{}`",
                letter.to, self.pool
            ))
        } else {
            None
        };
        if let Some(why) = wrong {
            self.drops.drop(Reason::Garbage, &key, "letter", "", &why);
            return reply_err(&query, &why);
        }
        let name = letter.key.clone();
        let verdict = Verdict::call(move |given| {
            let reply = match given {
                Some(Ok(())) => LetterReply {
                    key: name,
                    applied: true,
                    reason: None,
                },
                Some(Err(reason)) => LetterReply {
                    key: name,
                    applied: false,
                    reason: Some(reason),
                },
                // Not decided: the sender tries again (never a refusal, which would be final).
                None => return reply_err(&query, "the executive is stopping"),
            };
            if let Err(e) = query
                .reply(query.key_expr().clone(), json(&reply))
                .encoding(encoding("letter_reply"))
                .wait()
            {
                tracing::debug!(key, error = %e, "letter verdict not sent (the sender will try again)");
            }
        });
        self.report(Report::Letter { letter, verdict });
    }
}

/// The receiver's verdict on letter `letter` in `reply`, or why it is none.
fn verdict_of(reply: &zenoh::query::Reply, letter: &str) -> Result<LetterReply, String> {
    match reply.result() {
        Ok(sample) => {
            let key = sample.key_expr().as_str();
            let r = wire::parse::<LetterReply>("letter reply", key, &sample.payload().to_bytes())
                .map_err(|e| e.to_string())?;
            if r.key == letter {
                Ok(r)
            } else {
                Err(format!("the reply names message `{}`", r.key))
            }
        }
        Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
    }
}

fn reply_err(query: &Query, why: &str) {
    if let Err(e) = query.reply_err(why.to_owned()).wait() {
        tracing::debug!(error = %e, "letter error reply not sent");
    }
}
