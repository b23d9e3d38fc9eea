//! The in-memory twin of the sled store: same contract, and `crash()` keeps only what was
//! flushed, as a power cut would.

use std::collections::BTreeMap;

use executive_engine::{Action, Input, State};

use crate::{Recovered, Step, Store, StoreError};

#[derive(Clone, Debug, Default, PartialEq)]
struct Contents {
    steps: BTreeMap<u64, Step>,
    snapshots: BTreeMap<u64, State>,
    meta: BTreeMap<String, String>,
}

/// An in-memory store for tests.
#[derive(Clone, Debug, Default)]
pub struct MemStore {
    written: Contents,
    durable: Contents,
}

impl MemStore {
    /// An empty store.
    pub fn new() -> MemStore {
        MemStore::default()
    }

    /// The store as a restart after a power cut would find it: only flushed writes remain.
    pub fn crash(&self) -> MemStore {
        MemStore {
            written: self.durable.clone(),
            durable: self.durable.clone(),
        }
    }
}

impl Store for MemStore {
    fn commit_batch(&mut self, steps: &[(Input, Vec<Action>)]) -> Result<(), StoreError> {
        let mut last = self.written.steps.keys().next_back().copied().unwrap_or(0);
        for (input, _) in steps {
            if input.seq <= last {
                return Err(StoreError::OutOfOrder {
                    seq: input.seq,
                    last,
                });
            }
            last = input.seq;
        }
        for (input, actions) in steps {
            self.written.steps.insert(
                input.seq,
                Step {
                    input: input.clone(),
                    actions: actions.clone(),
                    done: vec![false; actions.len()],
                },
            );
        }
        self.flush()
    }

    fn done(&mut self, seq: u64, index: u32) -> Result<(), StoreError> {
        let flag = self
            .written
            .steps
            .get_mut(&seq)
            .and_then(|s| s.done.get_mut(index as usize))
            .ok_or(StoreError::UnknownAction { seq, index })?;
        *flag = true;
        Ok(())
    }

    fn snapshot(&mut self, seq: u64, state: &State) -> Result<(), StoreError> {
        self.written.snapshots.insert(seq, state.clone());
        while self.written.snapshots.len() > crate::KEEP_SNAPSHOTS {
            self.written.snapshots.pop_first();
        }
        // Steps up to the oldest kept snapshot are no longer needed (see the sled store).
        if self.written.snapshots.len() == crate::KEEP_SNAPSHOTS
            && let Some((&oldest, _)) = self.written.snapshots.first_key_value()
        {
            self.written.steps.retain(|s, _| *s > oldest);
        }
        self.flush()
    }

    fn set_meta(&mut self, key: &str, value: &str) -> Result<(), StoreError> {
        self.written.meta.insert(key.to_owned(), value.to_owned());
        self.flush()
    }

    fn flush(&mut self) -> Result<(), StoreError> {
        self.durable = self.written.clone();
        Ok(())
    }

    fn recover(&self) -> Result<Recovered, StoreError> {
        let c = &self.written;
        let snapshot = c
            .snapshots
            .iter()
            .next_back()
            .map(|(s, st)| (*s, st.clone()));
        let after = snapshot.as_ref().map_or(0, |(s, _)| *s);
        Ok(Recovered {
            steps: c.steps.range(after + 1..).map(|(_, s)| s.clone()).collect(),
            snapshot,
            meta: c.meta.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
        })
    }
}
