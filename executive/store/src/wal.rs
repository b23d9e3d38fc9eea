//! The store's write-ahead log: what a commit writes to disk with one write and one
//! `fdatasync`, in front of sled, which is then written without a flush of its own.
//!
//! sled turns one flush into about three write-and-sync pairs (docs/benchmarks.md), so a step
//! that waited for sled cost a multiple of the disk's sync time. Here a step waits for one
//! write and one `fdatasync` of this file; sled is made durable at a checkpoint (each snapshot,
//! or when the log has grown past [`CHECKPOINT_BYTES`]), after which the log starts again at
//! its beginning. On open, every whole record is applied to sled again, in order: applying one
//! is an insert of the same key and value, so applying one twice is harmless.
//!
//! The file is allocated ahead in zeroed chunks and written over in place, so a sync carries
//! no change of the file's size (the sync of an append does: a probe on one disk measured
//! 140 µs against 191). Each pass over the file has an epoch, kept in sled's `meta` tree and
//! made durable by the checkpoint that starts the pass; a record of another epoch is what a
//! previous pass left, and ends the log. A record is `magic (4) | epoch (4) | payload length
//! (4) | CRC-32 of epoch, length and payload (4) | payload`, integers little-endian; the payload
//! is a sequence of entries, each a tag byte and length-prefixed fields. Only the last record
//! of a pass can be torn by a crash (a commit returns after its record is synced, so no later
//! record exists): a torn last record was never acknowledged and is dropped with a warning. A
//! damaged record followed by a whole one of the same pass is damage, not a crash, and the
//! store is refused, naming the offset.

use std::fs::{File, OpenOptions};
use std::io::Read;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use crate::StoreError;

/// The log's file name inside the store directory.
pub(crate) const FILE: &str = "trace-wal";

/// The log size past which a commit checkpoints (flushes sled and starts the log again), so
/// that the log, and the time to open the store, stay bounded between snapshots.
pub(crate) const CHECKPOINT_BYTES: u64 = 8 << 20;

/// The file grows by zeroed chunks of this size, ahead of the records written into it.
const CHUNK: u64 = 1 << 20;

const MAGIC: [u8; 4] = *b"TWAL";
const HEADER: usize = 16;

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

    fn bytes(&self, epoch: u32) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + self.payload.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&epoch.to_le_bytes());
        out.extend_from_slice(&(self.payload.len() as u32).to_le_bytes());
        let crc = checksum(&out[4..12], &self.payload);
        out.extend_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&self.payload);
        out
    }
}

fn checksum(epoch_and_len: &[u8], payload: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(epoch_and_len);
    h.update(payload);
    h.finalize()
}

/// The open log.
pub(crate) struct Wal {
    path: PathBuf,
    file: File,
    /// The pass being written.
    epoch: u32,
    /// Where the next record goes: the end of this pass's records.
    len: u64,
    /// The file's size: zeros, or a previous pass's records, after `len`.
    allocated: u64,
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
    /// Opens (or creates) the log in `dir` and reads the whole records of pass `epoch`.
    pub(crate) fn open(dir: &Path, epoch: u32) -> Result<(Wal, Vec<Entry>), StoreError> {
        let path = dir.join(FILE);
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(|e| io(&path, e))?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(|e| io(&path, e))?;
        let read = parse(&bytes, epoch)?;
        if read.torn {
            tracing::warn!(
                path = %path.display(),
                offset = read.whole,
                "the write-ahead log ends in a record a crash cut short; it was never acknowledged and is dropped"
            );
        }
        let wal = Wal {
            path,
            file,
            epoch,
            len: read.whole as u64,
            allocated: bytes.len() as u64,
        };
        Ok((wal, read.entries))
    }

    /// Writes a record after the last one and waits for it to be on disk (one write, one
    /// `fdatasync`; the file grows, by a zeroed chunk, only when the record does not fit).
    pub(crate) fn append(&mut self, record: &Record) -> Result<(), StoreError> {
        let bytes = record.bytes(self.epoch);
        let end = self.len + bytes.len() as u64;
        if end > self.allocated {
            let grown = end.div_ceil(CHUNK) * CHUNK;
            let zeros = vec![0u8; (grown - self.allocated) as usize];
            self.file
                .write_all_at(&zeros, self.allocated)
                .map_err(|e| io(&self.path, e))?;
            self.allocated = grown;
        }
        self.file
            .write_all_at(&bytes, self.len)
            .map_err(|e| io(&self.path, e))?;
        self.file.sync_data().map_err(|e| io(&self.path, e))?;
        self.len = end;
        Ok(())
    }

    /// How far this pass has written.
    pub(crate) fn len(&self) -> u64 {
        self.len
    }

    /// The pass being written.
    pub(crate) fn epoch(&self) -> u32 {
        self.epoch
    }

    /// Starts pass `epoch` at the file's beginning: to be called once sled holds everything
    /// logged so far and `epoch` is durable in it.
    pub(crate) fn restart(&mut self, epoch: u32) {
        self.epoch = epoch;
        self.len = 0;
    }
}

/// What the log holds of one pass.
pub(crate) struct Pass {
    /// The entries of its whole records, in order.
    pub(crate) entries: Vec<Entry>,
    /// The bytes those records span.
    pub(crate) whole: usize,
    /// Whether a record of the pass follows them, cut short.
    pub(crate) torn: bool,
}

/// What the bytes at an offset are.
enum At<'a> {
    /// A whole record of the pass: its payload and where it ends.
    Whole(&'a [u8], usize),
    /// A record of the pass that does not check: where it says it ends, if within the file.
    Bad(Option<usize>),
    /// Not a record of the pass: zeros, another pass's bytes, or too few bytes for a header.
    Other,
}

fn at(bytes: &[u8], offset: usize, epoch: u32) -> At<'_> {
    let Some(header) = bytes.get(offset..).and_then(|r| r.get(..HEADER)) else {
        return At::Other;
    };
    let word =
        |i: usize| u32::from_le_bytes([header[i], header[i + 1], header[i + 2], header[i + 3]]);
    if header[..4] != MAGIC || word(4) != epoch {
        return At::Other;
    }
    let len = word(8) as usize;
    let start = offset + HEADER;
    let Some(payload) = bytes.get(start..start + len) else {
        return At::Bad(None);
    };
    if checksum(&header[4..12], payload) != word(12) {
        return At::Bad(Some(start + len));
    }
    At::Whole(payload, start + len)
}

/// Reads the whole records of pass `epoch` from the file's beginning. A record of the pass that
/// does not check ends the log as torn, unless a whole record of the pass follows it: then it
/// is damage, refused.
pub(crate) fn parse(bytes: &[u8], epoch: u32) -> Result<Pass, StoreError> {
    let mut entries = Vec::new();
    let mut offset = 0;
    loop {
        match at(bytes, offset, epoch) {
            At::Whole(payload, end) => {
                read_entries(payload, offset, &mut entries)?;
                offset = end;
            }
            At::Other => {
                return Ok(Pass {
                    entries,
                    whole: offset,
                    torn: false,
                });
            }
            At::Bad(end) => {
                if end.is_some_and(|e| matches!(at(bytes, e, epoch), At::Whole(..))) {
                    return Err(damaged(
                        offset,
                        "a record's checksum does not match, and a whole record follows it",
                    ));
                }
                return Ok(Pass {
                    entries,
                    whole: offset,
                    torn: true,
                });
            }
        }
    }
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
    //! Records read back whole; a torn tail is dropped; a previous pass's records end the log;
    //! damage before the end is refused; any bytes at all are read without a panic.

    use super::*;
    use proptest::prelude::*;

    fn record(n: u8) -> Record {
        let mut r = Record::default();
        r.done(&[n; 12]);
        r.step(&[n; 8], b"{\"seq\":1}", b"[]");
        r.meta(b"model", &[n]);
        r
    }

    fn log(epoch: u32, records: &[Record]) -> Vec<u8> {
        records.iter().flat_map(|r| r.bytes(epoch)).collect()
    }

    proptest! {
        #[test]
        fn any_bytes_are_read_or_refused_never_a_panic(
            bytes in prop::collection::vec(any::<u8>(), 0..512),
            cut in 0usize..64,
        ) {
            let _ = parse(&bytes, 0);
            // Behind whole records too, and with a header whose length is anything.
            let mut log = log(3, &[record(1)]);
            log.extend_from_slice(&MAGIC);
            log.extend_from_slice(&3u32.to_le_bytes());
            log.extend_from_slice(&bytes[..bytes.len().min(cut)]);
            let _ = parse(&log, 3);
        }
    }

    #[test]
    fn whole_records_read_back_in_order() {
        let bytes = log(0, &[record(1), record(2)]);
        let read = parse(&bytes, 0).expect("parses");
        assert_eq!((read.whole, read.torn), (bytes.len(), false));
        assert_eq!(read.entries.len(), 6);
        assert_eq!(read.entries[3], Entry::Done { key: vec![2; 12] });
    }

    #[test]
    fn a_torn_last_record_is_dropped_at_every_cut() {
        let first = log(0, &[record(1)]);
        let both = log(0, &[record(1), record(2)]);
        for cut in first.len()..both.len() {
            // Cut short, then zeros (the chunk allocated ahead) or the file's end.
            for tail in [0, 64] {
                let mut bytes = both[..cut].to_vec();
                bytes.resize(cut + tail, 0);
                let read = parse(&bytes, 0).expect("a torn tail is no damage");
                assert_eq!(
                    (read.entries.len(), read.whole),
                    (3, first.len()),
                    "cut at {cut}"
                );
            }
        }
        // A last record whose payload was garbled.
        let mut garbled = both;
        let n = garbled.len();
        garbled[n - 1] ^= 0xFF;
        let read = parse(&garbled, 0).expect("parses");
        assert_eq!((read.whole, read.torn), (first.len(), true));
    }

    #[test]
    fn a_previous_pass_ends_the_log() {
        // Pass 1 wrote three records; pass 2 wrote one over the first.
        let mut bytes = log(1, &[record(1), record(2), record(3)]);
        let over = log(2, &[record(9)]);
        bytes[..over.len()].copy_from_slice(&over);
        let read = parse(&bytes, 2).expect("parses");
        assert_eq!(
            (read.entries.len(), read.whole, read.torn),
            (3, over.len(), false)
        );
        // Read as pass 3 (a checkpoint made durable, nothing written since): nothing.
        assert_eq!(parse(&bytes, 3).expect("parses").entries.len(), 0);
    }

    #[test]
    fn damage_before_the_end_is_refused_naming_the_offset() {
        let mut bytes = log(0, &[record(1), record(2)]);
        bytes[HEADER + 3] ^= 0xFF;
        let e = parse(&bytes, 0).err().expect("refused");
        assert!(
            e.to_string().contains("`wal` at key byte 0") && e.to_string().contains("checksum"),
            "{e}"
        );
    }

    #[test]
    fn a_torn_first_record_is_written_over() {
        let dir = std::env::temp_dir().join(format!("trace-wal-torn-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let whole = record(1).bytes(0);
        std::fs::write(dir.join(FILE), &whole[..whole.len() - 3]).expect("write");
        let (mut wal, read) = Wal::open(&dir, 0).expect("a torn record is no damage");
        assert!(read.is_empty());
        wal.append(&record(2)).expect("append");
        drop(wal);
        let (_, read) = Wal::open(&dir, 0).expect("reopens");
        assert_eq!(read.len(), 3, "the new record, where the torn one was");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn records_go_over_the_previous_pass_in_place() {
        let dir = std::env::temp_dir().join(format!("trace-wal-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        let (mut wal, read) = Wal::open(&dir, 0).expect("opens");
        assert!(read.is_empty());
        wal.append(&record(1)).expect("append");
        wal.append(&record(2)).expect("append");
        let size = std::fs::metadata(dir.join(FILE)).expect("file").len();
        assert_eq!(size, CHUNK, "allocated ahead by one chunk");
        wal.restart(1);
        wal.append(&record(3)).expect("append");
        drop(wal);
        let (_, read) = Wal::open(&dir, 1).expect("reopens");
        assert_eq!(read.len(), 3, "only the new pass's record");
        assert_eq!(std::fs::metadata(dir.join(FILE)).expect("file").len(), size);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
