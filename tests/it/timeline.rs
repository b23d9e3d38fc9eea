//! The timeline page in a real browser: `trace timeline` turns a record (with a failure, a
//! boundary event, a reboot, a ground answer and battery data) into one HTML file, headless
//! Chromium renders it offline, and the DOM has the expected lanes, bars, markers and one
//! battery plot; a screenshot is saved beside it.

use std::process::Command;

use mission_tests::bin;

use crate::protocol::tempdir;

const RECORD: &str = r#"{"v":1,"kind":"entered","seq":1,"idx":0,"mission_ms":0,"token":2,"element":{"id":"Exc","name":"Excavate","type":"callActivity"}}
{"v":1,"kind":"dispatched","seq":1,"idx":1,"mission_ms":0,"task":"1-3-1","resource":"excavation.excavate","element":{"id":"Dig","name":"Remove Material","type":"serviceTask"}}
{"v":1,"kind":"failed","seq":2,"idx":0,"mission_ms":3600000,"task":"1-3-1","code":"TOOL_STUCK","message":"stuck at 6 cm"}
{"v":1,"kind":"caught","seq":2,"idx":1,"mission_ms":3600000,"what":"error","name":"TOOL_STUCK","element":{"id":"Fault","name":"Removal Fault","type":"boundaryEvent"}}
{"v":1,"kind":"dispatched","seq":2,"idx":2,"mission_ms":3600000,"task":"1-3-2","resource":"excavation.excavate","element":{"id":"Dig","name":"Remove Material","type":"serviceTask"}}
{"v":1,"kind":"reboot","mission_ms":5000000,"reboots":1,"recommanded":1}
{"v":1,"kind":"completed","seq":3,"idx":0,"mission_ms":9000000,"task":"1-3-2","output":{"achieved_depth_cm":10.0}}
{"v":1,"kind":"user_task_opened","seq":3,"idx":1,"mission_ms":9000000,"task":"1-5-1","element":{"id":"Approve","name":"Approve Site","type":"userTask"}}
{"v":1,"kind":"user_task_answered","seq":4,"idx":0,"mission_ms":12000000,"task":"1-5-1","operator":"alice","answer":{"approve":true}}
{"v":1,"kind":"dispatched","seq":4,"idx":1,"mission_ms":12000000,"task":"1-6-1","resource":"power.read_battery","element":{"id":"Read","name":"Read Battery","type":"serviceTask"}}
{"v":1,"kind":"completed","seq":5,"idx":0,"mission_ms":12000000,"task":"1-6-1","output":{"battery":{"soc_pct":81.5}}}
{"v":1,"kind":"data","seq":5,"idx":1,"mission_ms":13000000,"key":"battery_soc_pct","value":80.0}
{"v":1,"kind":"left","seq":5,"idx":2,"mission_ms":14000000,"token":2,"element":{"id":"Exc","name":"Excavate","type":"callActivity"}}
"#;

/// `trace timeline RECORD -o PAGE`, which must succeed; the page.
pub(crate) fn render(record: &std::path::Path, page: &std::path::Path) -> String {
    let out = Command::new(bin("trace"))
        .arg("timeline")
        .arg(record)
        .arg("-o")
        .arg(page)
        .output()
        .expect("trace timeline runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_to_string(page).expect("page")
}

#[test]
fn the_timeline_renders_in_headless_chromium() {
    let dir = tempdir("timeline");
    let record = dir.join("record.jsonl");
    std::fs::write(&record, RECORD).expect("record");
    let page = dir.join("timeline.html");
    let html = render(&record, &page);
    assert!(
        !html.contains("<script src") && !html.contains("<link") && !html.contains("url(http"),
        "the page must not fetch anything"
    );
    let chromium = |extra: &[&str]| {
        Command::new("chromium")
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--window-size=1400,700",
            ])
            .arg(format!(
                "--user-data-dir={}",
                dir.join("chromium").display()
            ))
            .args(extra)
            .arg(format!("file://{}", page.display()))
            .output()
            .expect("chromium runs (Debian package `chromium`, installed by scripts/test)")
    };
    let dom = chromium(&["--dump-dom"]);
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert!(
        dom.contains(r#"data-rendered="5""#),
        "the script did not render:\n{dom}"
    );
    for lane in [
        "mission phases",
        "system: excavation",
        "system: power",
        "ground decisions",
        "contingencies",
        "executive",
    ] {
        assert!(
            dom.contains(&format!(r#"data-lane="{lane}""#)),
            "lane {lane} missing"
        );
    }
    for bar in [
        r#"class="bar outcome-failed" data-lane="system: excavation" data-label="Remove Material""#,
        r#"class="bar outcome-completed" data-lane="system: excavation" data-label="Remove Material""#,
        r#"class="bar outcome-answered" data-lane="ground decisions" data-label="Approve Site""#,
        r#"class="bar outcome-completed" data-lane="mission phases" data-label="Excavate""#,
    ] {
        assert!(dom.contains(bar), "bar missing: {bar}");
    }
    for kind in ["fault", "boundary", "reboot"] {
        assert!(
            dom.contains(&format!(r#"data-kind="{kind}""#)),
            "marker {kind} missing"
        );
    }
    assert!(dom.contains("answered by alice"));
    assert!(dom.contains(r#"data-series="battery state of charge (%)""#));
    // The battery, read by a task and reported as system data, is one plot, not two.
    assert_eq!(
        dom.matches(r#"class="plot""#).count(),
        1,
        "one plotted series:\n{dom}"
    );
    let shot = dir.join("timeline.png");
    chromium(&[&format!("--screenshot={}", shot.display())]);
    let png = std::fs::read(&shot).expect("screenshot written");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 5000);
}
