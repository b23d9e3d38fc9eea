//! executive-store: the executive's durable memory — a journal of accepted inputs, engine-state
//! snapshots and an outbox of actions, committed so that a crash at any point loses nothing
//! that was acted on.
//!
//! One engine step is one [`Store::commit`]: the input and every action it produced are written
//! as one atomic batch and flushed **before** the caller performs any action ("commit, then
//! act"). The flush is one write and one `fdatasync` of a write-ahead log in front of sled;
//! sled is flushed at checkpoints. Performed actions are marked [`Store::done`]; after a crash the actions not marked
//! done are performed again — each carries its task or timer key, so repeating one is harmless.
//! Recovery ([`Store::recover`]) returns the newest snapshot and the journal after it, with the
//! actions each step produced, so the caller can replay the journal through the engine and
//! check that it produces the same actions (a difference is nondeterminism and is refused).
//!
//! Two implementations with one contract: [`SledStore`] on disk, and [`MemStore`], an in-memory
//! twin for tests in which "a crash drops what was not flushed".
//!
//! # Dependencies
//! - `sled` 0.34: an embedded, crash-safe B+ tree holding the trees, ordered by key and read
//!   back in ranges, made durable with an explicit `flush` at checkpoints. A step's journal
//!   entry and its outbox land together or not at all because both are in one record of the
//!   write-ahead log, which is written and synced first.
//! - `crc32fast`: the write-ahead log's record checksums (the CRC sled uses for its own log),
//!   so a record cut short by a crash is told from a whole one.
//! - `serde_json`: entries are stored as JSON, readable with any sled tool when debugging a
//!   store after an incident.
//! - `thiserror` for [`StoreError`], `tracing` for logs.

mod mem;
mod sled_store;
mod wal;

pub use mem::MemStore;
pub use sled_store::{Raw, RawStep, SledStore};

use executive_engine::{Action, Input, State};
use serde::{Deserialize, Serialize};

/// The store format written by this version; a store of another format is refused.
pub const FORMAT: &str = "trace-store/4";

/// Snapshots kept; steps up to the oldest kept one are pruned when a new one is written.
pub const KEEP_SNAPSHOTS: usize = 2;

/// One committed step: the input and the actions it produced, in order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// The accepted input.
    pub input: Input,
    /// The actions, in the order the engine produced them.
    pub actions: Vec<Action>,
    /// For each action, whether it has been performed.
    pub done: Vec<bool>,
}

/// What a store holds after a restart.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recovered {
    /// The newest snapshot: the sequence number it includes, and the state.
    pub snapshot: Option<(u64, State)>,
    /// The committed steps after the snapshot, in sequence order.
    pub steps: Vec<Step>,
    /// Mission metadata stored with [`Store::set_meta`].
    pub meta: Vec<(String, String)>,
}

impl Recovered {
    /// The actions committed but not marked done, oldest first: to be performed again.
    pub fn pending(&self) -> Vec<(u64, u32, &Action)> {
        self.steps
            .iter()
            .flat_map(|s| {
                s.actions
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !s.done.get(*i).copied().unwrap_or(false))
                    .map(move |(i, a)| (s.input.seq, i as u32, a))
            })
            .collect()
    }
}

/// Why a store operation failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The store directory cannot be opened.
    #[error("cannot open the store at {path}: {reason}")]
    Open {
        /// The directory.
        path: String,
        /// Why.
        reason: String,
    },
    /// The directory holds something that is not a TRACE store, or another format version.
    #[error("{path} is not a TRACE store of format {FORMAT}: {found}")]
    Foreign {
        /// The directory.
        path: String,
        /// What was found instead.
        found: String,
    },
    /// An entry cannot be read back.
    #[error("corrupt store entry in `{tree}` at key {key}: {reason}")]
    Corrupt {
        /// The tree (journal, outbox, snapshots, meta).
        tree: &'static str,
        /// The entry's key.
        key: String,
        /// Why.
        reason: String,
    },
    /// A commit would break the journal order.
    #[error("input {seq} does not follow the last committed input {last}")]
    OutOfOrder {
        /// The input's sequence number.
        seq: u64,
        /// The last committed one.
        last: u64,
    },
    /// `done` names an action that was never committed.
    #[error("no committed action {index} of step {seq}")]
    UnknownAction {
        /// Step.
        seq: u64,
        /// Action index.
        index: u32,
    },
    /// The disk failed.
    #[error("store I/O failed: {0}")]
    Io(String),
}

/// The store contract, shared by [`SledStore`] and [`MemStore`].
pub trait Store {
    /// Commits one step atomically and durably. Sequence numbers must increase.
    fn commit(&mut self, input: &Input, actions: &[Action]) -> Result<(), StoreError> {
        self.commit_batch(&[(input.clone(), actions.to_vec())])
    }
    /// Commits several steps as one atomic batch with one flush (group commit): the way to
    /// keep up with many instances whose results arrive together.
    fn commit_batch(&mut self, steps: &[(Input, Vec<Action>)]) -> Result<(), StoreError>;
    /// Marks action `index` of step `seq` performed (made durable with the next commit or
    /// flush: losing the mark only repeats an idempotent action).
    fn done(&mut self, seq: u64, index: u32) -> Result<(), StoreError>;
    /// Saves a snapshot of the engine state after step `seq`; recovery starts from the newest.
    fn snapshot(&mut self, seq: u64, state: &State) -> Result<(), StoreError>;
    /// Stores mission metadata (model path and digest, …), durably.
    fn set_meta(&mut self, key: &str, value: &str) -> Result<(), StoreError>;
    /// Makes everything written so far durable.
    fn flush(&mut self) -> Result<(), StoreError>;
    /// Reads back what survives a restart.
    fn recover(&self) -> Result<Recovered, StoreError>;
}

#[cfg(test)]
mod tests;
