//! The store on sled: trees `meta`, `journal` (seq -> input), `outbox` (seq -> the step's
//! actions), `done` (seq, index -> performed) and `snapshots` (seq -> state); keys are
//! big-endian so they sort by sequence number. Commits, done marks and metadata are made durable
//! by the write-ahead log in front of sled ([`crate::wal`]); sled itself is flushed at
//! checkpoints.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::{Duration, Instant};

use executive_engine::{Action, Input, State};

use crate::wal::{self, Entry, Record, Wal};
use crate::{FORMAT, KEEP_SNAPSHOTS, Recovered, Step, Store, StoreError};

/// The `meta` key of the write-ahead log's current pass ([`crate::wal`]), four bytes big-endian.
const EPOCH: &str = "wal-epoch";

/// Earlier store formats this version opens, and rewrites as [`FORMAT`]: `trace-store/1` is
/// the same trees without a write-ahead log; in `trace-store/2` and before, a snapshot's tokens
/// keep their whole command (the engine reads it as the command's goal when it restores); in
/// `trace-store/3` and before, a dispatch in the outbox names its resource (read and ignored: the
/// resource is the model's, [`executive_engine::resource`]). An older `trace` refuses a store it
/// would misread.
const EARLIER: &[&str] = &["trace-store/1", "trace-store/2", "trace-store/3"];

/// A store in a directory on disk.
pub struct SledStore {
    path: String,
    db: sled::Db,
    meta: sled::Tree,
    journal: sled::Tree,
    outbox: sled::Tree,
    done: sled::Tree,
    snapshots: sled::Tree,
    wal: Wal,
    /// Done marks applied to sled but not yet logged: they ride with the next record.
    marks: Record,
}

/// How long an open waits for the store's lock. sled releases a closed database's lock only when
/// its flusher thread has exited, after the close returns (spacejam/sled#1234), so an open just
/// after a close in the same process can find it still held for a moment; a lock held longer is
/// another process's, and the store is refused as in use.
const LOCK_WAIT: Duration = Duration::from_secs(1);

/// Whether sled refused to open because the directory's lock is held (sled 0.34 reports it as
/// an `Other` I/O error with this text, the OS's `WouldBlock` inside).
fn locked(e: &sled::Error) -> bool {
    matches!(e, sled::Error::Io(io) if io.to_string().starts_with("could not acquire lock"))
}

fn io(e: impl std::fmt::Display) -> StoreError {
    StoreError::Io(e.to_string())
}

fn seq_key(seq: u64) -> [u8; 8] {
    seq.to_be_bytes()
}

fn seq_of(tree: &'static str, key: &[u8]) -> Result<u64, StoreError> {
    let bytes: [u8; 8] = key
        .get(..8)
        .and_then(|k| k.try_into().ok())
        .ok_or_else(|| StoreError::Corrupt {
            tree,
            key: format!("{key:?}"),
            reason: "the key is not a sequence number".to_owned(),
        })?;
    Ok(u64::from_be_bytes(bytes))
}

fn decode<T: serde::de::DeserializeOwned>(
    tree: &'static str,
    seq: u64,
    bytes: &[u8],
) -> Result<T, StoreError> {
    serde_json::from_slice(bytes).map_err(|e| StoreError::Corrupt {
        tree,
        key: seq.to_string(),
        reason: e.to_string(),
    })
}

impl SledStore {
    /// Opens (or creates) the store in directory `path`. A directory holding anything but a
    /// TRACE store of this format, or a damaged one, is refused with the reason.
    pub fn open(path: &Path) -> Result<SledStore, StoreError> {
        let shown = path.display().to_string();
        if path.is_file() {
            return Err(StoreError::Foreign {
                path: shown,
                found: "a file, not a store directory".to_owned(),
            });
        }
        // sled reports most damage as errors, but not all of it: a panic while reading a
        // damaged file is turned into a refusal too.
        let waited = Instant::now();
        let mut pause = Duration::from_millis(5);
        let opened = loop {
            // No periodic flush: what must be durable is in the write-ahead log, and sled is
            // flushed at checkpoints.
            let config = sled::Config::new().path(path).flush_every_ms(None);
            match catch_unwind(AssertUnwindSafe(|| config.open())) {
                Ok(Err(e)) if locked(&e) && waited.elapsed() < LOCK_WAIT => {
                    tracing::debug!(path = %shown, "store locked; waiting for its lock");
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_millis(100));
                }
                other => break other,
            }
        };
        let db = match opened {
            Ok(Ok(db)) => db,
            Ok(Err(e)) if locked(&e) => {
                return Err(StoreError::Open {
                    path: shown,
                    reason: format!(
                        "the store is in use: its lock was still held after {} s (another executive on the same store?)",
                        LOCK_WAIT.as_secs()
                    ),
                });
            }
            Ok(Err(e)) => {
                return Err(StoreError::Open {
                    path: shown,
                    reason: e.to_string(),
                });
            }
            Err(_) => {
                return Err(StoreError::Open {
                    path: shown,
                    reason: "the store files are damaged (sled could not read them)".to_owned(),
                });
            }
        };
        let tree = |name: &str| db.open_tree(name).map_err(io);
        let (meta, journal, outbox, done, snapshots) = (
            tree("meta")?,
            tree("journal")?,
            tree("outbox")?,
            tree("done")?,
            tree("snapshots")?,
        );
        let epoch = match meta.get(EPOCH).map_err(io)? {
            None => 0,
            Some(v) => <[u8; 4]>::try_from(v.as_ref())
                .map(u32::from_be_bytes)
                .map_err(|_| StoreError::Corrupt {
                    tree: "meta",
                    key: EPOCH.to_owned(),
                    reason: format!("{} bytes where an epoch has 4", v.len()),
                })?,
        };
        let (wal, logged) = Wal::open(path, epoch)?;
        let mut store = SledStore {
            meta,
            journal,
            outbox,
            done,
            snapshots,
            path: shown,
            db,
            wal,
            marks: Record::default(),
        };
        store.check_format()?;
        if !logged.is_empty() {
            let n = logged.len();
            store.apply(logged)?;
            store.checkpoint()?;
            tracing::info!(path = %store.path, entries = n, "store caught up from its write-ahead log");
        }
        tracing::debug!(path = %store.path, "store opened");
        Ok(store)
    }

    /// Applies logged entries to sled, in order (each an insert, so applying one again is
    /// harmless).
    fn apply(&self, entries: Vec<Entry>) -> Result<(), StoreError> {
        for entry in entries {
            match entry {
                Entry::Step {
                    key,
                    input,
                    actions,
                } => {
                    self.journal.insert(key.as_slice(), input).map_err(io)?;
                    self.outbox.insert(key, actions).map_err(io)?;
                }
                Entry::Done { key } => {
                    self.done.insert(key, &[]).map_err(io)?;
                }
                Entry::Meta { key, value } => {
                    self.meta.insert(key, value).map_err(io)?;
                }
            }
        }
        Ok(())
    }

    /// Makes sled durable, with the next pass of the log, which then starts: sled holds every
    /// entry logged so far.
    fn checkpoint(&mut self) -> Result<(), StoreError> {
        let next = self.wal.epoch().wrapping_add(1);
        self.meta.insert(EPOCH, &next.to_be_bytes()).map_err(io)?;
        self.db.flush().map_err(io)?;
        self.wal.restart(next);
        self.marks = Record::default();
        Ok(())
    }

    /// Logs `record`, with the done marks not yet logged ahead of it, durably.
    fn log(&mut self, record: Record) -> Result<(), StoreError> {
        let mut marks = std::mem::take(&mut self.marks);
        marks.extend(record);
        if marks.is_empty() {
            return Ok(());
        }
        self.wal.append(&marks)
    }

    fn check_format(&self) -> Result<(), StoreError> {
        match self.meta.get("format").map_err(io)? {
            Some(f) if f.as_ref() == FORMAT.as_bytes() => Ok(()),
            Some(f) if EARLIER.iter().any(|e| f.as_ref() == e.as_bytes()) => {
                tracing::info!(path = %self.path, from = %String::from_utf8_lossy(&f), to = FORMAT, "store format upgraded");
                self.meta.insert("format", FORMAT.as_bytes()).map_err(io)?;
                self.db.flush().map_err(io)?;
                Ok(())
            }
            Some(f) => Err(StoreError::Foreign {
                path: self.path.clone(),
                found: format!("format `{}`", String::from_utf8_lossy(&f)),
            }),
            None => {
                let others: Vec<String> = self
                    .db
                    .tree_names()
                    .into_iter()
                    .map(|n| String::from_utf8_lossy(&n).into_owned())
                    .filter(|n| {
                        ![
                            "__sled__default",
                            "meta",
                            "journal",
                            "outbox",
                            "done",
                            "snapshots",
                        ]
                        .contains(&n.as_str())
                    })
                    .collect();
                let used = !self.journal.is_empty() || !self.db.is_empty() || !others.is_empty();
                if used {
                    return Err(StoreError::Foreign {
                        path: self.path.clone(),
                        found: "a sled database without a TRACE format marker".to_owned(),
                    });
                }
                self.meta.insert("format", FORMAT.as_bytes()).map_err(io)?;
                self.db.flush().map_err(io)?;
                Ok(())
            }
        }
    }

    fn last_seq(&self) -> Result<u64, StoreError> {
        match self.journal.last().map_err(io)? {
            Some((k, _)) => seq_of("journal", &k),
            None => Ok(0),
        }
    }
}

impl Store for SledStore {
    fn commit_batch(&mut self, steps: &[(Input, Vec<Action>)]) -> Result<(), StoreError> {
        let mut last = self.last_seq()?;
        let mut rows = Vec::with_capacity(steps.len());
        for (input, actions) in steps {
            if input.seq <= last {
                return Err(StoreError::OutOfOrder {
                    seq: input.seq,
                    last,
                });
            }
            last = input.seq;
            rows.push((
                seq_key(input.seq),
                serde_json::to_vec(input).map_err(io)?,
                serde_json::to_vec(actions).map_err(io)?,
            ));
        }
        let mut record = Record::default();
        for (key, input, actions) in &rows {
            record.step(key, input, actions);
        }
        self.log(record)?;
        // No sled transaction: the record makes the step's entries atomic (a crash between
        // the inserts is caught up from it on open), and a transaction would seal sled's
        // buffer, writing and syncing it on every step.
        for (key, input, actions) in rows {
            self.journal.insert(key, input).map_err(io)?;
            self.outbox.insert(key, actions).map_err(io)?;
        }
        if self.wal.len() > wal::CHECKPOINT_BYTES {
            self.checkpoint()?;
        }
        Ok(())
    }

    fn done(&mut self, seq: u64, index: u32) -> Result<(), StoreError> {
        let actions = self.outbox.get(seq_key(seq)).map_err(io)?;
        let count = match actions {
            Some(bytes) => decode::<Vec<Action>>("outbox", seq, &bytes)?.len(),
            None => 0,
        };
        if index as usize >= count {
            return Err(StoreError::UnknownAction { seq, index });
        }
        let mut key = seq_key(seq).to_vec();
        key.extend_from_slice(&index.to_be_bytes());
        self.done.insert(key.as_slice(), &[]).map_err(io)?;
        self.marks.done(&key);
        Ok(())
    }

    fn snapshot(&mut self, seq: u64, state: &State) -> Result<(), StoreError> {
        let bytes = serde_json::to_vec(state).map_err(io)?;
        self.snapshots.insert(seq_key(seq), bytes).map_err(io)?;
        let keys: Vec<sled::IVec> = self
            .snapshots
            .iter()
            .keys()
            .collect::<Result<_, _>>()
            .map_err(io)?;
        for old in keys.iter().take(keys.len().saturating_sub(KEEP_SNAPSHOTS)) {
            self.snapshots.remove(old).map_err(io)?;
        }
        // Steps up to the oldest kept snapshot are no longer needed to recover: pruning them
        // keeps the store, and so the time to open it, independent of the mission's length.
        // (The execution record is the mission's history.)
        if let Some(oldest) = keys
            .len()
            .checked_sub(KEEP_SNAPSHOTS)
            .and_then(|i| keys.get(i))
        {
            let upto = seq_of("snapshots", oldest)?;
            for tree in [&self.journal, &self.outbox] {
                let old: Vec<sled::IVec> = tree
                    .range(..=seq_key(upto))
                    .keys()
                    .collect::<Result<_, _>>()
                    .map_err(io)?;
                for k in old {
                    tree.remove(k).map_err(io)?;
                }
            }
            let mut end = seq_key(upto).to_vec();
            end.extend_from_slice(&u32::MAX.to_be_bytes());
            let old: Vec<sled::IVec> = self
                .done
                .range(..=end)
                .keys()
                .collect::<Result<_, _>>()
                .map_err(io)?;
            for k in old {
                self.done.remove(k).map_err(io)?;
            }
        }
        self.checkpoint()
    }

    fn set_meta(&mut self, key: &str, value: &str) -> Result<(), StoreError> {
        let mut record = Record::default();
        record.meta(key.as_bytes(), value.as_bytes());
        self.log(record)?;
        self.meta.insert(key, value.as_bytes()).map_err(io)?;
        Ok(())
    }

    fn flush(&mut self) -> Result<(), StoreError> {
        self.log(Record::default())
    }

    fn recover(&self) -> Result<Recovered, StoreError> {
        self.raw()?.decode()
    }
}

/// A store closed in order leaves sled holding everything, its log at a new pass with nothing in
/// it, so that tools reading sled directly see the whole store (a kill leaves the log to be
/// caught up on open).
impl Drop for SledStore {
    fn drop(&mut self) {
        if (self.wal.len() > 0 || !self.marks.is_empty())
            && let Err(e) = self.checkpoint()
        {
            tracing::warn!(path = %self.path, error = %e, "store closed without a checkpoint; its write-ahead log is caught up when it is opened");
        }
    }
}

impl SledStore {
    /// What recovery reads, as stored: the newest snapshot, the journal after it with its
    /// outbox entries and done marks, and the metadata (for tools that inspect a store, and
    /// the fuzzer's seeds).
    pub fn raw(&self) -> Result<Raw, StoreError> {
        let snapshot = self
            .snapshots
            .last()
            .map_err(io)?
            .map(|(k, v)| (k.to_vec(), v.to_vec()));
        let after = match &snapshot {
            Some((k, _)) => seq_of("snapshots", k)?,
            None => 0,
        };
        let mut steps = Vec::new();
        for entry in self.journal.range(seq_key(after + 1)..) {
            let (k, v) = entry.map_err(io)?;
            let actions = self.outbox.get(&k).map_err(io)?.map(|a| a.to_vec());
            let mut done = Vec::new();
            for d in self.done.scan_prefix(&k) {
                done.push(d.map_err(io)?.0.to_vec());
            }
            steps.push(RawStep {
                key: k.to_vec(),
                input: v.to_vec(),
                actions,
                done,
            });
        }
        let mut meta = Vec::new();
        for entry in self.meta.iter() {
            let (k, v) = entry.map_err(io)?;
            meta.push((k.to_vec(), v.to_vec()));
        }
        Ok(Raw {
            snapshot,
            steps,
            meta,
        })
    }
}

/// What recovery reads from the store, as bytes: the newest snapshot (key, value), the
/// journal after it with each step's outbox entry and done marks, and the metadata. Decoding
/// it is a pure function, so damaged entries are refused the same way whatever held them,
/// and fuzzing reaches it without a disk.
#[derive(Clone, Debug, Default)]
pub struct Raw {
    /// The newest snapshot's key and value.
    pub snapshot: Option<(Vec<u8>, Vec<u8>)>,
    /// The journaled steps after it, in key order.
    pub steps: Vec<RawStep>,
    /// Metadata keys and values (the format marker among them).
    pub meta: Vec<(Vec<u8>, Vec<u8>)>,
}

/// One journaled step as stored.
#[derive(Clone, Debug, Default)]
pub struct RawStep {
    /// The journal key (the big-endian sequence number).
    pub key: Vec<u8>,
    /// The journaled input.
    pub input: Vec<u8>,
    /// The outbox entry of the same key, if there is one.
    pub actions: Option<Vec<u8>>,
    /// The keys of the step's done marks (sequence number, then action index).
    pub done: Vec<Vec<u8>>,
}

impl Raw {
    /// Decodes what was read into what the executive resumes from; a damaged or missing entry
    /// is refused with its tree, key and reason.
    pub fn decode(&self) -> Result<Recovered, StoreError> {
        let snapshot = match &self.snapshot {
            Some((k, v)) => {
                let seq = seq_of("snapshots", k)?;
                Some((seq, decode::<State>("snapshots", seq, v)?))
            }
            None => None,
        };
        let mut steps: Vec<Step> = Vec::new();
        let mut last = snapshot.as_ref().map_or(0, |(s, _)| *s);
        for raw in &self.steps {
            let seq = seq_of("journal", &raw.key)?;
            let input: Input = decode("journal", seq, &raw.input)?;
            if seq <= last || input.seq != seq {
                return Err(StoreError::Corrupt {
                    tree: "journal",
                    key: seq.to_string(),
                    reason: format!(
                        "the entry holds input {} after step {last}: the journal is out of order",
                        input.seq
                    ),
                });
            }
            last = seq;
            let actions: Vec<Action> = match &raw.actions {
                Some(bytes) => decode("outbox", seq, bytes)?,
                None => {
                    return Err(StoreError::Corrupt {
                        tree: "outbox",
                        key: seq.to_string(),
                        reason: "a journaled step has no outbox entry".to_owned(),
                    });
                }
            };
            let mut done = vec![false; actions.len()];
            for dk in &raw.done {
                let index = dk
                    .get(8..12)
                    .and_then(|b| <[u8; 4]>::try_from(b).ok())
                    .map(u32::from_be_bytes);
                if let Some(flag) = index.and_then(|i| done.get_mut(i as usize)) {
                    *flag = true;
                }
            }
            steps.push(Step {
                input,
                actions,
                done,
            });
        }
        let meta = self
            .meta
            .iter()
            .filter(|(k, _)| k.as_slice() != b"format" && k.as_slice() != EPOCH.as_bytes())
            .map(|(k, v)| {
                (
                    String::from_utf8_lossy(k).into_owned(),
                    String::from_utf8_lossy(v).into_owned(),
                )
            })
            .collect();
        Ok(Recovered {
            snapshot,
            steps,
            meta,
        })
    }
}
