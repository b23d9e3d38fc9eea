//! Tidy checks on the repository itself: every Rust source file starts with a `//!` line
//! saying what it holds, and each vehicle's catalogue file is what the simulator serves.

use mission_tests::repo;

fn rust_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if path.is_dir() && name != "target" && !name.to_string_lossy().starts_with('.') {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn every_source_file_says_what_it_holds() {
    let mut files = Vec::new();
    for top in [
        "executive",
        "connectors",
        "elap-sim",
        "ground-station",
        "tests",
    ] {
        rust_files(&repo().join(top), &mut files);
    }
    let missing: Vec<String> = files
        .iter()
        .filter(|f| {
            !std::fs::read_to_string(f)
                .unwrap_or_default()
                .starts_with("//!")
        })
        .map(|f| f.display().to_string())
        .collect();
    assert!(files.len() > 10);
    assert!(
        missing.is_empty(),
        "files without a leading //! line: {missing:?}"
    );
}

#[test]
fn each_vehicles_catalogue_file_is_what_the_simulator_serves() {
    for vehicle in ["lander", "scout"] {
        let out = std::process::Command::new(mission_tests::bin("elap-sim"))
            .args(["--vehicle", vehicle, "--print-catalogue"])
            .output()
            .expect("elap-sim runs");
        assert!(out.status.success());
        let path = format!("deploy/catalogues/{vehicle}_sim.json");
        let file = std::fs::read_to_string(repo().join(&path)).expect("the catalogue file");
        let served: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
        let kept: serde_json::Value = serde_json::from_str(&file).expect("JSON");
        assert!(
            served == kept,
            "{path} is out of date: write it again with \
             `elap-sim --vehicle {vehicle} --print-catalogue > {path}`"
        );
    }
}
