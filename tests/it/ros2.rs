//! ROS 2 (issue 36) against the official tools, installed by `scripts/test` into a virtual
//! environment (`TRACE_ROS2`, default `~/.cache/trace-ros2/venv`: the `ros-jazzy-rclpy` and
//! `ros-jazzy-test-msgs` wheels): TRACE's reading of every `test_msgs`, `builtin_interfaces`,
//! `action_msgs` and `unique_identifier_msgs` definition gives each field the type `rclpy`
//! gives it, every action's catalogue entry resolves, and `trace catalogue ros2` prints them.

use std::path::PathBuf;
use std::process::Command;

use connector_ros2::Definitions;
use mission_tests::{bin, repo};

/// The virtual environment `scripts/test` installs ROS 2 into.
pub(crate) fn venv() -> PathBuf {
    let dir = std::env::var_os("TRACE_ROS2")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default())
                .join(".cache/trace-ros2/venv")
        });
    assert!(
        dir.join("bin/python").exists(),
        "no ROS 2 virtual environment at {} (scripts/test installs it; or set TRACE_ROS2)",
        dir.display()
    );
    dir
}

const PACKAGES: [&str; 4] = [
    "test_msgs",
    "builtin_interfaces",
    "action_msgs",
    "unique_identifier_msgs",
];

#[test]
fn every_field_of_the_ros_definitions_has_the_type_rclpy_gives_it() {
    let venv = venv();
    let out = Command::new(venv.join("bin/python"))
        .arg(repo().join("tests/python/ros2/types.py"))
        .arg(venv.join("share"))
        .args(PACKAGES)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let official: serde_json::Map<String, serde_json::Value> =
        serde_json::from_slice(&out.stdout).expect("rclpy's types as JSON");
    let defs = Definitions::new(&[venv]);
    let as_map = |fields: Vec<(String, String)>| -> serde_json::Value {
        fields
            .into_iter()
            .map(|(k, v)| (k, serde_json::Value::String(v)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    let (mut messages, mut actions) = (0, 0);
    for (key, want) in &official {
        let parts: Vec<&str> = key.split('/').collect();
        let ours = match parts.as_slice() {
            [pkg, "msg", name] => {
                messages += 1;
                as_map(defs.message_types(pkg, name).expect(key))
            }
            [_, "action", _] => {
                actions += 1;
                let a = defs.action(key).unwrap_or_else(|e| panic!("{key}: {e}"));
                serde_json::Value::Array(a.ros_types.into_iter().map(as_map).collect())
            }
            _ => panic!("{key}"),
        };
        assert_eq!(&ours, want, "{key}");
    }
    // Every definition of the four packages was compared.
    assert!(
        messages >= 15 && actions >= 2,
        "{messages} messages, {actions} actions"
    );
    let found = defs.actions();
    assert!(
        found.contains(&"test_msgs/action/Fibonacci".to_owned()),
        "{found:?}"
    );
}

#[test]
fn trace_catalogue_ros2_prints_each_action_s_entry() {
    let venv = venv();
    let out = Command::new(bin("trace"))
        .args(["catalogue", "ros2"])
        .arg(venv.join("share/test_msgs"))
        .arg(venv.join("share/builtin_interfaces"))
        .output()
        .expect("trace runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cat: connector_api::Catalogue = serde_json::from_str(&text).expect("a catalogue");
    let fib = cat.action("test_msgs/action/Fibonacci").expect("Fibonacci");
    assert_eq!(fib.goal["order"].to_string(), "i32");
    assert_eq!(fib.result["sequence"].to_string(), "[i32]");
    let nested = cat
        .action("test_msgs/action/NestedMessage")
        .expect("NestedMessage");
    assert_eq!(
        nested.goal["nested_different_pkg"].to_string(),
        "{nanosec: u32, sec: i32}"
    );
    // A definition that cannot be read is refused with its file and line.
    let dir = crate::protocol::tempdir("ros2-bad");
    std::fs::create_dir_all(dir.join("bad_msgs/action")).expect("dir");
    std::fs::write(
        dir.join("bad_msgs/action/Dig.action"),
        "int32 depth\nfloat128 force\n---\n---\n",
    )
    .expect("file");
    let out = Command::new(bin("trace"))
        .args(["catalogue", "ros2"])
        .arg(dir.join("bad_msgs"))
        .output()
        .expect("trace runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("Dig.action:2: `float128` is not a type"),
        "{err}"
    );
}
