//! The store's write-ahead log: what a commit writes to disk with one write and one
//! `fdatasync`, in front of sled, which is then written without a flush of its own.
//!
//! sled turns one flush into about three write-and-sync pairs (docs/benchmarks.md), so a step
//! that waited for sled cost a multiple of the disk's sync time. Here a step waits for one
//! append and one `fdatasync` of this file; sled is made durable at a checkpoint (each snapshot,
//! or when the log has grown past [`CHECKPOINT_BYTES`]), after which the log is emptied. On
//! open, every whole record is applied to sled again, in order: applying one is an insert of
//! the same key and value, so applying one twice is harmless.
//!
//! A record is `magic (4) | payload length (4) | CRC-32 of the payload (4) | payload`, integers
//! little-endian; the payload is a sequence of entries, each a tag byte and length-prefixed
//! fields. Only the last record can be torn by a crash (a commit returns after its record is
//! synced, so no later record exists): a torn last record was never acknowledged and is dropped
//! with a warning. A damaged record followed by others is damage, not a crash, and the store is
//! refused, naming the offset.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::StoreError;

/// The log's file name inside the store directory.
pub(crate) const FILE: &str = "trace-wal";

/// The log size past which a commit checkpoints (flushes sled and empties the log), so that
/// the log, and the time to open the store, stay bounded between snapshots.
pub(crate) const CHECKPOINT_BYTES: u64 = 8 << 20;

const MAGIC: [u8; 4] = *b"TWAL";
const HEADER: usize = 12;

/// One change to sled, as logged.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Entry {
    /// A committed step: its journal key, input and actions, as sled stores them.
    Step {
        key: Vec<u8>,
        input: Vec<u8>,
        actions: Vec<u8>,
    },
    /// A done mark's key (step, then action index).
    Done { key: Vec<u8> },
    /// A metadata key and value.
    Meta { key: Vec<u8>, value: Vec<u8> },
}

const STEP: u8 = 1;
const DONE: u8 = 2;
const META: u8 = 3;

/// A record being built: entries appended in the order sled is to apply them.
#[derive(Default)]
pub(crate) struct Record {
    payload: Vec<u8>,
}

impl Record {
    fn field(&mut self, bytes: &[u8]) {
        // Entries are bounded far below 4 GiB (an input or a step's actions as JSON).
        self.payload
            .extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        self.payload.extend_from_slice(bytes);
    }

    /// Logs a committed step.
    pub(crate) fn step(&mut self, key: &[u8], input: &[u8], actions: &[u8]) {
        self.payload.push(STEP);
        self.field(key);
        self.field(input);
        self.field(actions);
    }

    /// Logs a done mark.
    pub(crate) fn done(&mut self, key: &[u8]) {
        self.payload.push(DONE);
        self.field(key);
    }

    /// Logs a metadata value.
    pub(crate) fn meta(&mut self, key: &[u8], value: &[u8]) {
        self.payload.push(META);
        self.field(key);
        self.field(value);
    }

    /// Appends another record's entries after these.
    pub(crate) fn extend(&mut self, other: Record) {
        self.payload.extend_from_slice(&other.payload);
    }

    /// Whether nothing was logged.
    pub(crate) fn is_empty(&self) -> bool {
        self.payload.is_empty()
    }

    fn bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + self.payload.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&(self.payload.len() as u32).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&self.payload).to_le_bytes());
        out.extend_from_slice(&self.payload);
        out
    }
}

/// The open log.
pub(crate) struct Wal {
    path: PathBuf,
    file: File,
    len: u64,
}

fn io(path: &Path, e: std::io::Error) -> StoreError {
    StoreError::Io(format!("write-ahead log {}: {e}", path.display()))
}

fn damaged(offset: usize, reason: impl Into<String>) -> StoreError {
    StoreError::Corrupt {
        tree: "wal",
        key: format!("byte {offset}"),
        reason: reason.into(),
    }
}

impl Wal {
    /// Opens (or creates) the log in `dir` and reads its whole records.
    pub(crate) fn open(dir: &Path) -> Result<(Wal, Vec<Entry>), StoreError> {
        let path = dir.join(FILE);
        let mut file = OpenOptions::new()
            .create(true)
            .append(true)
            .read(true)
            .open(&path)
            .map_err(|e| io(&path, e))?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(|e| io(&path, e))?;
        let (entries, whole) = parse(&bytes)?;
        if whole < bytes.len() {
            tracing::warn!(
                path = %path.display(),
                offset = whole,
                dropped = bytes.len() - whole,
                "the write-ahead log ends in a record a crash cut short; it was never acknowledged and is dropped"
            );
        }
        let len = bytes.len() as u64;
        Ok((Wal { path, file, len }, entries))
    }

    /// Appends a record and waits for it to be on disk (one write, one `fdatasync`).
    pub(crate) fn append(&mut self, record: &Record) -> Result<(), StoreError> {
        let bytes = record.bytes();
        self.file.write_all(&bytes).map_err(|e| io(&self.path, e))?;
        self.file.sync_data().map_err(|e| io(&self.path, e))?;
        self.len += bytes.len() as u64;
        Ok(())
    }

    /// The log's size in bytes.
    pub(crate) fn len(&self) -> u64 {
        self.len
    }

    /// Empties the log, durably: to be called once sled holds everything it logged.
    pub(crate) fn clear(&mut self) -> Result<(), StoreError> {
        self.file.set_len(0).map_err(|e| io(&self.path, e))?;
        self.file.sync_data().map_err(|e| io(&self.path, e))?;
        self.len = 0;
        Ok(())
    }
}

/// Reads the entries of every whole record, and how many bytes they span; a torn last record
/// is left out, a damaged record followed by more bytes is refused.
pub(crate) fn parse(bytes: &[u8]) -> Result<(Vec<Entry>, usize), StoreError> {
    let mut entries = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let rest = &bytes[at..];
        let Some(header) = rest.get(..HEADER) else {
            return torn(bytes, at, entries);
        };
        if header[..4] != MAGIC {
            return torn(bytes, at, entries);
        }
        let len = u32::from_le_bytes([header[4], header[5], header[6], header[7]]) as usize;
        let crc = u32::from_le_bytes([header[8], header[9], header[10], header[11]]);
        let Some(payload) = rest.get(HEADER..HEADER + len) else {
            // The record reaches past the end of the file: its write was cut short.
            return Ok((entries, at));
        };
        let end = at + HEADER + len;
        if crc32fast::hash(payload) != crc {
            if end == bytes.len() {
                return Ok((entries, at));
            }
            return Err(damaged(
                at,
                "a record's checksum does not match, and more records follow it",
            ));
        }
        read_entries(payload, at, &mut entries)?;
        at = end;
    }
    Ok((entries, at))
}

/// At `at` the bytes are not a record header: the rest is a torn tail only if it is shorter
/// than a header or all zeros (a file extended before its data landed); otherwise it is damage.
fn torn(bytes: &[u8], at: usize, entries: Vec<Entry>) -> Result<(Vec<Entry>, usize), StoreError> {
    let rest = &bytes[at..];
    if rest.len() < HEADER && MAGIC.starts_with(&rest[..rest.len().min(4)]) {
        return Ok((entries, at));
    }
    if rest.iter().all(|b| *b == 0) {
        return Ok((entries, at));
    }
    Err(damaged(at, "the bytes there are not a log record"))
}

fn read_entries(payload: &[u8], record: usize, out: &mut Vec<Entry>) -> Result<(), StoreError> {
    let mut p = payload;
    let field = |p: &mut &[u8]| -> Result<Vec<u8>, StoreError> {
        let len = p
            .get(..4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            .ok_or_else(|| damaged(record, "a record's entry ends inside a field length"))?;
        let value = p
            .get(4..4 + len)
            .ok_or_else(|| damaged(record, "a record's field reaches past its record"))?
            .to_vec();
        *p = &p[4 + len..];
        Ok(value)
    };
    while let Some((&tag, rest)) = p.split_first() {
        p = rest;
        let entry = match tag {
            STEP => Entry::Step {
                key: field(&mut p)?,
                input: field(&mut p)?,
                actions: field(&mut p)?,
            },
            DONE => Entry::Done {
                key: field(&mut p)?,
            },
            META => Entry::Meta {
                key: field(&mut p)?,
                value: field(&mut p)?,
            },
            other => return Err(damaged(record, format!("unknown entry tag {other}"))),
        };
        out.push(entry);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! Records read back whole; a torn tail is dropped; damage before the end is refused; any
    //! bytes at all are read without a panic.

    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn any_bytes_are_read_or_refused_never_a_panic(
            bytes in prop::collection::vec(any::<u8>(), 0..512),
            at in 0usize..64,
        ) {
            let _ = parse(&bytes);
            // Behind whole records too, and with a header whose length is anything.
            let mut log = log(&[record(1)]);
            log.extend_from_slice(&MAGIC);
            log.extend_from_slice(&bytes[..bytes.len().min(at)]);
            let _ = parse(&log);
        }
    }

    fn record(n: u8) -> Record {
        let mut r = Record::default();
        r.done(&[n; 12]);
        r.step(&[n; 8], b"{\"seq\":1}", b"[]");
        r.meta(b"model", &[n]);
        r
    }

    fn log(records: &[Record]) -> Vec<u8> {
        records.iter().flat_map(Record::bytes).collect()
    }

    #[test]
    fn whole_records_read_back_in_order() {
        let bytes = log(&[record(1), record(2)]);
        let (entries, whole) = parse(&bytes).expect("parses");
        assert_eq!(whole, bytes.len());
        assert_eq!(entries.len(), 6);
        assert_eq!(entries[3], Entry::Done { key: vec![2; 12] });
    }

    #[test]
    fn a_torn_last_record_is_dropped_at_every_cut() {
        let first = log(&[record(1)]);
        let both = log(&[record(1), record(2)]);
        for cut in first.len()..both.len() {
            let (entries, whole) = parse(&both[..cut]).expect("a torn tail is no damage");
            assert_eq!((entries.len(), whole), (3, first.len()), "cut at {cut}");
        }
        // A file extended with zeros before the record's bytes landed.
        let mut zeros = first.clone();
        zeros.extend_from_slice(&[0; 40]);
        assert_eq!(parse(&zeros).expect("parses").1, first.len());
        // A last record whose payload was garbled.
        let mut garbled = both;
        let n = garbled.len();
        garbled[n - 1] ^= 0xFF;
        assert_eq!(parse(&garbled).expect("parses").1, first.len());
    }

    #[test]
    fn damage_before_the_end_is_refused_naming_the_offset() {
        let mut bytes = log(&[record(1), record(2)]);
        bytes[HEADER + 3] ^= 0xFF;
        let e = parse(&bytes).expect_err("refused");
        assert!(
            e.to_string().contains("`wal` at key byte 0") && e.to_string().contains("checksum"),
            "{e}"
        );
        let mut bytes = log(&[record(1)]);
        bytes.extend_from_slice(b"garbage that is not a record at all");
        let e = parse(&bytes).expect_err("refused");
        assert!(e.to_string().contains("not a log record"), "{e}");
    }
}
