//! mission-tests: shared helpers for the integration tiers (paths, the `trace` binary, corpora).

pub mod fleet_matrix;
pub mod fuzz;
pub mod hosts;
pub mod matrix;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the repository")
        .to_path_buf()
}

/// The shared test material (`../shared` beside the repository, or `$TRACE_SHARED`).
pub fn shared() -> PathBuf {
    match std::env::var_os("TRACE_SHARED") {
        Some(p) => PathBuf::from(p),
        None => repo().join("../shared"),
    }
}

/// A conformance corpus folder.
pub fn conformance(sub: &str) -> PathBuf {
    shared().join("conformance").join(sub)
}

/// Reads a JSON file that is an array of objects.
pub fn json_array(path: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Path of a workspace binary, built once per test run with the test's own cargo and profile.
pub fn bin(name: &str) -> PathBuf {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        // A bench runs from the release directory: its binaries are release builds.
        let release = profile_dir().ends_with("release");
        let mut build = Command::new(cargo);
        // What cargo set for this test binary (its package's name and directory) must not
        // reach the build: build scripts that watch those variables (ring's does) would run
        // again, and everything above them would be rebuilt, here and in the next build.
        for (key, _) in std::env::vars_os() {
            let key = key.to_string_lossy();
            if key.starts_with("CARGO_PKG_")
                || key.starts_with("CARGO_MANIFEST_")
                || key.starts_with("CARGO_BIN_")
                || matches!(
                    &*key,
                    "CARGO_CRATE_NAME"
                        | "CARGO_PRIMARY_PACKAGE"
                        | "CARGO_TARGET_TMPDIR"
                        | "OUT_DIR"
                )
            {
                build.env_remove(&*key);
            }
        }
        let status = build
            .args(["build", "--quiet", "--workspace", "--bins"])
            .args(release.then_some("--release"))
            .current_dir(repo())
            .status()
            .expect("cargo runs");
        assert!(status.success(), "building the workspace binaries failed");
    });
    profile_dir().join(name)
}

/// `<target>/<profile>`: the test or bench binary lives in its `deps`, the binaries in it.
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>")
        .to_owned()
}

/// The lines of an execution record (`docs/record.md`), parsed; none if the file is not there.
pub fn records(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).expect("record line"))
        .collect()
}

/// Waits for `child` to end, at most `bound` (its exit, waited for on a thread, is the event),
/// and kills it past that: its exit status, or `None` if it had to be killed.
pub fn ended(
    mut child: std::process::Child,
    bound: std::time::Duration,
) -> Option<std::process::ExitStatus> {
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait());
    });
    match rx.recv_timeout(bound) {
        Ok(Ok(status)) => Some(status),
        _ => {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
            None
        }
    }
}
