//! The build script of every TRACE binary's package (`build = "…/scripts/version.rs"`): sets
//! `TRACE_LONG_VERSION`, what `--version` prints after the binary's name — the workspace
//! version, the commit it was built from, and the Zenoh it speaks:
//! `0.1.0 (commit 8b14b3c0d2a1, zenoh 1.10.2)`.
//!
//! The commit comes from `git rev-parse` (`unknown` outside a clone, as in a source archive);
//! Zenoh's version from the workspace's `Cargo.lock`, the version actually linked. The script
//! runs again when the checked-out commit or the lock file changes.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let root = manifest
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .map(Path::to_path_buf);
    let zenoh = root
        .as_ref()
        .and_then(|r| std::fs::read_to_string(r.join("Cargo.lock")).ok())
        .and_then(|lock| locked_version(&lock, "zenoh"))
        .unwrap_or_else(|| "unknown".to_owned());
    let commit = git(&manifest, &["rev-parse", "--short=12", "HEAD"]);
    if let Some(root) = &root {
        println!(
            "cargo:rerun-if-changed={}",
            root.join("Cargo.lock").display()
        );
    }
    // The commit moves when HEAD does, or the branch it names.
    if let Some(dir) = git(&manifest, &["rev-parse", "--absolute-git-dir"]) {
        let dir = PathBuf::from(dir);
        println!("cargo:rerun-if-changed={}", dir.join("HEAD").display());
        if let Some(branch) = git(&manifest, &["symbolic-ref", "-q", "HEAD"]) {
            println!("cargo:rerun-if-changed={}", dir.join(branch).display());
        }
        println!(
            "cargo:rerun-if-changed={}",
            dir.join("packed-refs").display()
        );
    }
    println!(
        "cargo:rustc-env=TRACE_LONG_VERSION={} (commit {}, zenoh {zenoh})",
        std::env::var("CARGO_PKG_VERSION").unwrap_or_default(),
        commit.as_deref().unwrap_or("unknown"),
    );
}

/// What `git args` prints in `dir`, if git is there and succeeds.
fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
        .filter(|s| !s.is_empty())
}

/// The version of package `name` in a `Cargo.lock`.
fn locked_version(lock: &str, name: &str) -> Option<String> {
    let mut lines = lock.lines();
    while let Some(line) = lines.next() {
        if line.trim() == format!("name = \"{name}\"") {
            let version = lines.next()?.trim().strip_prefix("version = \"")?;
            return Some(version.trim_end_matches('"').to_owned());
        }
    }
    None
}
