//! The sled store against its in-memory twin on random operation sequences (with kills that
//! leave the directory as the process had written it), the refusal of foreign, damaged, in-use
//! and out-of-order input, a closed store reopened at once, and an earlier format upgraded.

use std::path::PathBuf;

use executive_engine::{Action, Event, Input, State, TimerKey};
use proptest::prelude::*;

use crate::{MemStore, SledStore, Store, StoreError};

fn scratch(name: &str) -> PathBuf {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("trace-store-{}-{name}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn input(seq: u64) -> Input {
    Input {
        seq,
        at: seq as i64 * 1000,
        event: Event::SignalReceived {
            name: format!("S{seq}"),
        },
    }
}

fn actions(seq: u64, n: usize) -> Vec<Action> {
    (0..n)
        .map(|i| Action::StartTimer {
            timer: TimerKey {
                instance: executive_engine::InstanceId(seq),
                wait: executive_engine::WaitId(i as u64),
                firing: 1,
            },
            at: seq as i64 + i as i64,
        })
        .collect()
}

fn state(n: u64) -> State {
    State {
        next_id: n,
        last_seq: n,
        ..State::default()
    }
}

#[derive(Clone, Debug)]
enum Op {
    Commit(usize),
    Done(usize, usize),
    Snapshot,
    Meta(u8),
    Flush,
    Reopen,
    Kill,
    Stale,
}

/// Copies a store directory as it is on disk now: what a SIGKILL of its process would leave.
fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).expect("copy dir");
    for entry in std::fs::read_dir(from).expect("read dir") {
        let path = entry.expect("entry").path();
        let target = to.join(path.file_name().expect("name"));
        if path.is_dir() {
            copy_dir(&path, &target);
        } else {
            std::fs::copy(&path, &target).expect("copy file");
        }
    }
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        5 => (0usize..4).prop_map(Op::Commit),
        3 => (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Op::Done(a, b)),
        1 => Just(Op::Snapshot),
        1 => any::<u8>().prop_map(Op::Meta),
        1 => Just(Op::Flush),
        1 => Just(Op::Reopen),
        2 => Just(Op::Kill),
        1 => Just(Op::Stale),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn sled_store_and_memory_twin_agree(ops in prop::collection::vec(op(), 1..40)) {
        let dir = scratch("model");
        let mut disk = SledStore::open(&dir).expect("opens");
        let mut mem = MemStore::new();
        let mut seq = 0u64;
        let mut committed: Vec<(u64, usize)> = Vec::new();
        for op in ops {
            match op {
                Op::Commit(n) => {
                    seq += 1;
                    let (i, a) = (input(seq), actions(seq, n));
                    disk.commit(&i, &a).expect("disk commit");
                    mem.commit(&i, &a).expect("memory commit");
                    committed.push((seq, n));
                }
                Op::Done(s, i) => {
                    if let Some(&(step, n)) = committed.get(s % committed.len().max(1)) {
                        let index = (i % n.max(1)) as u32;
                        let a = disk.done(step, index).is_ok();
                        let b = mem.done(step, index).is_ok();
                        prop_assert_eq!(a, b);
                    }
                }
                Op::Snapshot => {
                    disk.snapshot(seq, &state(seq)).expect("disk snapshot");
                    mem.snapshot(seq, &state(seq)).expect("memory snapshot");
                }
                Op::Meta(v) => {
                    disk.set_meta("model", &v.to_string()).expect("disk meta");
                    mem.set_meta("model", &v.to_string()).expect("memory meta");
                }
                Op::Flush => {
                    disk.flush().expect("disk flush");
                    mem.flush().expect("memory flush");
                }
                Op::Reopen => {
                    // A clean restart: both keep what they wrote and flushed.
                    disk.flush().expect("flush");
                    mem.flush().expect("flush");
                    drop(disk);
                    disk = SledStore::open(&dir).expect("reopens");
                    mem = mem.crash();
                }
                Op::Kill => {
                    // The process dies: its files stay as written, sled's unflushed pages
                    // never reach them, and the store resumes from the copy.
                    let killed = scratch("killed");
                    copy_dir(&dir, &killed);
                    drop(disk);
                    std::fs::remove_dir_all(&dir).expect("remove");
                    std::fs::rename(&killed, &dir).expect("rename");
                    disk = SledStore::open(&dir).expect("reopens after a kill");
                    mem = mem.crash();
                }
                Op::Stale => {
                    let a = disk.commit(&input(seq), &[]);
                    let b = mem.commit(&input(seq), &[]);
                    let refused = matches!(a, Err(StoreError::OutOfOrder { .. }));
                    prop_assert!(refused || seq == 0, "a stale commit was accepted");
                    prop_assert_eq!(a.is_ok(), b.is_ok());
                    if a.is_ok() {
                        seq += 1;
                        committed.push((seq, 0));
                    }
                }
            }
            prop_assert_eq!(disk.recover().expect("disk recovers"), mem.recover().expect("memory recovers"));
        }
        drop(disk);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn a_kill_right_after_commits_keeps_them_all_from_the_log() {
    let dir = scratch("kill");
    let killed = scratch("killed");
    let mut s = SledStore::open(&dir).expect("opens");
    for seq in 1..=50 {
        s.commit(&input(seq), &actions(seq, 2)).expect("commit");
        s.done(seq, 0).expect("done");
    }
    s.set_meta("model", "europa.bpmn").expect("meta");
    copy_dir(&dir, &killed);
    drop(s);
    for _ in 0..2 {
        // Caught up from the log, then (the second time) from sled alone.
        let r = SledStore::open(&killed)
            .expect("reopens")
            .recover()
            .expect("recovers");
        assert_eq!(r.steps.len(), 50);
        // Each step's first mark rode with the next commit; the last one with the metadata.
        assert_eq!(r.pending().len(), 50);
        assert_eq!(r.meta, vec![("model".to_owned(), "europa.bpmn".to_owned())]);
    }
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&killed);
}

#[test]
fn a_record_cut_short_is_written_over_and_the_store_opens_again() {
    let dir = scratch("torn");
    let kill = |s: SledStore| {
        // The process dies: the directory stays as it had written it.
        let killed = scratch("torn-killed");
        copy_dir(&dir, &killed);
        drop(s);
        std::fs::remove_dir_all(&dir).expect("remove");
        std::fs::rename(&killed, &dir).expect("rename");
    };
    let mut s = SledStore::open(&dir).expect("opens");
    s.commit(&input(1), &actions(1, 1)).expect("commit");
    kill(s);
    // A record of the same pass cut short after step 1's: its first 20 bytes landed.
    let log = dir.join(crate::wal::FILE);
    let mut bytes = std::fs::read(&log).expect("log");
    let first = bytes.iter().rposition(|b| *b != 0).expect("a record") + 1;
    let header: Vec<u8> = bytes[..20].to_vec();
    bytes[first..first + 20].copy_from_slice(&header);
    std::fs::write(&log, &bytes).expect("write");
    for seq in 2..=3 {
        let mut s = SledStore::open(&dir).expect("a torn tail is no damage");
        s.commit(&input(seq), &actions(seq, 1)).expect("commit");
        kill(s);
    }
    let r = SledStore::open(&dir)
        .expect("opens")
        .recover()
        .expect("recovers");
    assert_eq!(
        r.steps.iter().map(|s| s.input.seq).collect::<Vec<_>>(),
        [1, 2, 3]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_store_of_the_format_before_the_log_opens_and_is_upgraded() {
    let dir = scratch("upgrade");
    {
        let mut s = SledStore::open(&dir).expect("opens");
        s.commit(&input(1), &actions(1, 1)).expect("commit");
        s.snapshot(1, &state(1)).expect("snapshot");
        s.commit(&input(2), &actions(2, 1)).expect("commit");
        s.snapshot(2, &state(2)).expect("snapshot");
    }
    // Mark it as the earlier format wrote it: the same trees, no log.
    {
        let db = sled::open(&dir).expect("sled");
        db.open_tree("meta")
            .expect("meta")
            .insert("format", "trace-store/1")
            .expect("insert");
        db.flush().expect("flush");
    }
    std::fs::remove_file(dir.join(crate::wal::FILE)).expect("no log before");
    let r = SledStore::open(&dir)
        .expect("an earlier format opens")
        .recover()
        .expect("recovers");
    assert_eq!(r.snapshot.map(|(s, _)| s), Some(2));
    let db = sled::open(&dir).expect("sled");
    let format = db
        .open_tree("meta")
        .expect("meta")
        .get("format")
        .expect("get");
    assert_eq!(format.as_deref(), Some(crate::FORMAT.as_bytes()));
    drop(db);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_crash_keeps_every_commit_and_forgets_unflushed_done_marks() {
    let mut mem = MemStore::new();
    mem.commit(&input(1), &actions(1, 2)).expect("commit");
    mem.done(1, 0).expect("done");
    let after = mem.crash().recover().expect("recovers");
    assert_eq!(after.steps.len(), 1);
    assert_eq!(
        after.pending().len(),
        2,
        "the unflushed mark is lost: both actions are redone"
    );
    mem.flush().expect("flush");
    assert_eq!(mem.crash().recover().expect("recovers").pending().len(), 1);
}

#[test]
fn recovery_starts_at_the_newest_snapshot() {
    let dir = scratch("snap");
    let mut s = SledStore::open(&dir).expect("opens");
    for seq in 1..=5 {
        s.commit(&input(seq), &actions(seq, 1)).expect("commit");
        if seq == 3 {
            s.snapshot(3, &state(3)).expect("snapshot");
        }
    }
    drop(s);
    let r = SledStore::open(&dir)
        .expect("reopens")
        .recover()
        .expect("recovers");
    assert_eq!(r.snapshot.as_ref().map(|(s, _)| *s), Some(3));
    assert_eq!(
        r.steps.iter().map(|s| s.input.seq).collect::<Vec<_>>(),
        [4, 5]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_store_in_use_is_refused_and_a_closed_one_reopens_at_once() {
    let dir = scratch("in-use");
    let s = SledStore::open(&dir).expect("opens");
    // Open twice: the lock is held for good, and the second open says so.
    let e = SledStore::open(&dir).err().expect("refused");
    assert!(e.to_string().contains("in use"), "{e}");
    // Closed, it opens again at once, again and again: each open waits out sled's release of
    // the lock the close before left to its flusher thread.
    drop(s);
    for _ in 0..20 {
        drop(SledStore::open(&dir).expect("reopens"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn foreign_and_damaged_stores_are_refused_with_the_reason() {
    // A file where a directory should be.
    let file = scratch("file");
    std::fs::write(&file, b"not a store").expect("write");
    let e = SledStore::open(&file).err().expect("refused");
    assert!(e.to_string().contains("a file"), "{e}");
    let _ = std::fs::remove_file(&file);

    // Another program's sled database.
    let other = scratch("other");
    {
        let db = sled::open(&other).expect("sled");
        db.insert("hello", "world").expect("insert");
        db.flush().expect("flush");
    }
    let e = SledStore::open(&other).err().expect("refused");
    assert!(matches!(e, StoreError::Foreign { .. }), "{e}");
    let _ = std::fs::remove_dir_all(&other);

    // A store whose files were overwritten with garbage.
    let damaged = scratch("damaged");
    {
        let mut s = SledStore::open(&damaged).expect("opens");
        s.commit(&input(1), &actions(1, 1)).expect("commit");
    }
    for entry in std::fs::read_dir(&damaged).expect("dir") {
        let path = entry.expect("entry").path();
        if path.is_file() {
            std::fs::write(&path, vec![0xA5u8; 4096]).expect("overwrite");
        }
    }
    match SledStore::open(&damaged) {
        Err(e) => assert!(!e.to_string().is_empty()),
        // If sled salvages the directory, what it returns must still be a clean refusal or
        // readable data, never a panic.
        Ok(s) => {
            let _ = s.recover();
        }
    }
    let _ = std::fs::remove_dir_all(&damaged);
}

#[test]
fn out_of_order_commits_and_unknown_actions_are_refused() {
    let dir = scratch("order");
    let mut s = SledStore::open(&dir).expect("opens");
    s.commit(&input(2), &actions(2, 1)).expect("commit");
    assert!(matches!(
        s.commit(&input(2), &[]),
        Err(StoreError::OutOfOrder { seq: 2, last: 2 })
    ));
    assert!(matches!(
        s.done(2, 5),
        Err(StoreError::UnknownAction { seq: 2, index: 5 })
    ));
    assert!(matches!(
        s.done(9, 0),
        Err(StoreError::UnknownAction { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn recovery_refuses_damaged_entries_naming_tree_key_and_reason() {
    use crate::{Raw, RawStep};
    let step = |seq: u64, input_seq: u64| RawStep {
        key: seq.to_be_bytes().to_vec(),
        input: serde_json::to_vec(&input(input_seq)).expect("JSON"),
        actions: Some(serde_json::to_vec(&actions(input_seq, 2)).expect("JSON")),
        done: vec![[&seq.to_be_bytes()[..], &1u32.to_be_bytes()[..]].concat()],
    };
    let refused = |raw: Raw| match raw.decode() {
        Err(StoreError::Corrupt { tree, key, reason }) => format!("{tree} {key}: {reason}"),
        other => panic!("not refused: {other:?}"),
    };
    // Whole: decoded, with its done mark.
    let ok = Raw {
        steps: vec![step(1, 1), step(2, 2)],
        ..Raw::default()
    }
    .decode()
    .expect("decodes");
    assert_eq!(ok.steps[1].done, vec![false, true]);
    // A journal entry under another step's key.
    let why = refused(Raw {
        steps: vec![step(1, 1), step(2, 5)],
        ..Raw::default()
    });
    assert!(
        why.starts_with("journal 2: ") && why.contains("out of order"),
        "{why}"
    );
    // A step without its outbox entry.
    let mut lost = step(1, 1);
    lost.actions = None;
    let why = refused(Raw {
        steps: vec![lost],
        ..Raw::default()
    });
    assert!(
        why.starts_with("outbox 1: ") && why.contains("no outbox entry"),
        "{why}"
    );
    // Bytes that are not an entry, in each tree.
    let mut garbled = step(1, 1);
    garbled.input = b"{\"seq\":1,".to_vec();
    assert!(
        refused(Raw {
            steps: vec![garbled],
            ..Raw::default()
        })
        .starts_with("journal 1: ")
    );
    assert!(
        refused(Raw {
            snapshot: Some((7u64.to_be_bytes().to_vec(), b"not a state".to_vec())),
            ..Raw::default()
        })
        .starts_with("snapshots 7: ")
    );
    assert!(
        refused(Raw {
            snapshot: Some((b"k".to_vec(), b"{}".to_vec())),
            ..Raw::default()
        })
        .contains("not a sequence number")
    );
}
