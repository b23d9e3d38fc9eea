//! `trace timeline RECORD.jsonl -o timeline.html`: the execution record as one self-contained
//! HTML page (no network at view time, no JavaScript library): a lane per mission phase and per
//! system resource with activity bars coloured by outcome, ground decisions with who answered,
//! faults and boundary events as markers, reboots as gaps, and the data decisions used (battery
//! state of charge, temperatures) plotted on the same time axis; zoom with the wheel, details on
//! hover.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::Path;

use serde::Serialize;
use serde_json::Value;

/// The page template; `/*DATA*/` is replaced by the timeline's JSON.
const TEMPLATE: &str = include_str!("../assets/timeline.html");

/// One activity bar.
#[derive(Debug, Serialize, PartialEq)]
pub struct Bar {
    /// Lane name.
    pub lane: String,
    /// The BPMN element id (for views that select it on the diagram).
    pub element: String,
    /// Label (element name or id).
    pub label: String,
    /// Start, mission ms.
    pub start: i64,
    /// End, mission ms (open bars end at the record's end).
    pub end: i64,
    /// `completed`, `failed`, `cancelled`, `answered`, `running`.
    pub outcome: String,
    /// Hover text.
    pub detail: String,
}

/// One point event.
#[derive(Debug, Serialize, PartialEq)]
pub struct Marker {
    /// Lane name.
    pub lane: String,
    /// When, mission ms.
    pub at: i64,
    /// `fault`, `boundary`, `signal`, `reboot`.
    pub kind: String,
    /// Hover text.
    pub detail: String,
}

/// Everything the page draws.
#[derive(Debug, Default, Serialize)]
pub struct Timeline {
    /// Lanes in display order.
    pub lanes: Vec<String>,
    /// Activity bars.
    pub bars: Vec<Bar>,
    /// Point events.
    pub markers: Vec<Marker>,
    /// Plotted series: name → (mission ms, value).
    pub series: BTreeMap<String, Vec<(i64, f64)>>,
    /// Record lines that were not JSON (a line cut by a crash).
    pub skipped: usize,
    /// First and last mission time.
    pub span: (i64, i64),
}

/// The plotted series a system data key belongs to. The battery's state of charge reaches the
/// record two ways — as system data (`battery_soc_pct`, from telemetry) and as the output of
/// `power.read_battery` — and both are one quantity: one series, not two.
fn series_of(key: &str) -> String {
    match key {
        "battery_soc_pct" => BATTERY.to_owned(),
        _ => key.to_owned(),
    }
}

/// The battery's series.
const BATTERY: &str = "battery state of charge (%)";

fn lane_of(resource: &str) -> String {
    let system = resource.split('.').next().unwrap_or(resource);
    format!("system: {system}")
}

fn label(v: &Value) -> String {
    v["element"]["name"]
        .as_str()
        .or_else(|| v["element"]["id"].as_str())
        .unwrap_or("?")
        .to_owned()
}

/// Builds the timeline from record lines (duplicated `(seq, idx)` lines after a crash are
/// read once).
pub fn build(lines: impl Iterator<Item = String>) -> Timeline {
    let mut t = Timeline::default();
    // task → (lane, label, start, resource, element)
    let mut open: BTreeMap<String, (String, String, i64, String, String)> = BTreeMap::new();
    let mut phases: BTreeMap<i64, (String, i64, String)> = BTreeMap::new(); // token → (label, start, element)
    let mut reader = crate::record::Reader::default();
    let (mut first, mut last) = (i64::MAX, i64::MIN);
    let mut lanes: Vec<String> = Vec::new();
    let lane = |name: &str, lanes: &mut Vec<String>| {
        if !lanes.iter().any(|l| l == name) {
            lanes.push(name.to_owned());
        }
    };
    for line in lines {
        let Some(v) = reader.read(&line) else {
            continue;
        };
        let at = v["mission_ms"].as_i64().unwrap_or(0);
        first = first.min(at);
        last = last.max(at);
        let task = v["task"].as_str().unwrap_or_default().to_owned();
        match v["kind"].as_str().unwrap_or_default() {
            "entered" => {
                let ty = v["element"]["type"].as_str().unwrap_or_default();
                if matches!(ty, "subProcess" | "callActivity" | "transaction") {
                    phases.insert(
                        v["token"].as_i64().unwrap_or(-1),
                        (label(&v), at, element(&v)),
                    );
                }
            }
            "left" | "withdrawn" => {
                if let Some((l, start, id)) = phases.remove(&v["token"].as_i64().unwrap_or(-1)) {
                    lane("mission phases", &mut lanes);
                    t.bars.push(Bar {
                        lane: "mission phases".into(),
                        element: id,
                        detail: format!(
                            "{l}: {}",
                            if v["kind"] == "left" {
                                "completed"
                            } else {
                                "interrupted"
                            }
                        ),
                        label: l,
                        start,
                        end: at,
                        outcome: if v["kind"] == "left" {
                            "completed".into()
                        } else {
                            "cancelled".into()
                        },
                    });
                }
            }
            "dispatched" => {
                let resource = v["resource"].as_str().unwrap_or_default().to_owned();
                let l = lane_of(&resource);
                lane(&l, &mut lanes);
                open.insert(task, (l, label(&v), at, resource, element(&v)));
            }
            "user_task_opened" => {
                lane("ground decisions", &mut lanes);
                open.insert(
                    task,
                    (
                        "ground decisions".into(),
                        label(&v),
                        at,
                        "user task".into(),
                        element(&v),
                    ),
                );
            }
            kind @ ("completed" | "failed" | "cancelled" | "user_task_answered") => {
                if let Some((l, name, start, resource, id)) = open.remove(&task) {
                    let detail = match kind {
                        "failed" => format!(
                            "{name} ({resource}) failed: {} {}",
                            v["code"].as_str().unwrap_or("?"),
                            v["message"].as_str().unwrap_or("")
                        ),
                        "user_task_answered" => format!(
                            "{name}: answered by {} with {}",
                            v["operator"].as_str().unwrap_or("?"),
                            v["answer"]
                        ),
                        _ => format!("{name} ({resource}) {kind}"),
                    };
                    // A verifier's counterexample says what each activity spent.
                    let detail = match v["energy_wh"].as_array().map(|e| {
                        (
                            e.first().and_then(|x| x.as_f64()),
                            e.get(1).and_then(|x| x.as_f64()),
                        )
                    }) {
                        Some((Some(lo), Some(hi))) if lo == hi => format!("{detail}, {lo:.0} Wh"),
                        Some((Some(lo), Some(hi))) => format!("{detail}, {lo:.0}–{hi:.0} Wh"),
                        _ => detail,
                    };
                    if kind == "failed" {
                        t.markers.push(Marker {
                            lane: l.clone(),
                            at,
                            kind: "fault".into(),
                            detail: detail.clone(),
                        });
                    }
                    if resource == "power.read_battery"
                        && let Some(soc) = v["output"]["battery"]["soc_pct"].as_f64()
                    {
                        t.series.entry(BATTERY.into()).or_default().push((at, soc));
                    }
                    t.bars.push(Bar {
                        lane: l,
                        element: id,
                        label: name,
                        start,
                        end: at,
                        outcome: if kind == "user_task_answered" {
                            "answered".into()
                        } else {
                            kind.into()
                        },
                        detail,
                    });
                }
            }
            // Messages between the vehicles of a fleet: when one left, and when one was taken.
            kind @ ("caught" | "message_sent")
                if kind == "message_sent" || v["what"] == "message" =>
            {
                let name = v["name"].as_str().unwrap_or("");
                let detail = if kind == "caught" {
                    format!("message {name} taken by {}", label(&v))
                } else {
                    format!(
                        "message {name} sent to pool {} ({})",
                        v["to"].as_str().unwrap_or("?"),
                        v["key"].as_str().unwrap_or("")
                    )
                };
                lane("messages", &mut lanes);
                t.markers.push(Marker {
                    lane: "messages".into(),
                    at,
                    kind: "message".into(),
                    detail,
                });
            }
            "caught" if v["what"] != "timer" || v["element"]["type"] == "boundaryEvent" => {
                lane("contingencies", &mut lanes);
                t.markers.push(Marker {
                    lane: "contingencies".into(),
                    at,
                    kind: if v["what"] == "signal" {
                        "signal".into()
                    } else {
                        "boundary".into()
                    },
                    detail: format!(
                        "{} {} caught by {}",
                        v["what"].as_str().unwrap_or("?"),
                        v["name"].as_str().unwrap_or(""),
                        label(&v)
                    ),
                });
            }
            "data" => {
                if let Some(x) = v["value"].as_f64() {
                    t.series
                        .entry(series_of(v["key"].as_str().unwrap_or("?")))
                        .or_default()
                        .push((at, x));
                }
            }
            "reboot" => {
                lane("executive", &mut lanes);
                t.markers.push(Marker {
                    lane: "executive".into(),
                    at,
                    kind: "reboot".into(),
                    detail: format!(
                        "executive restarted (reboot {}), {} commands reconciled",
                        v["reboots"], v["recommanded"]
                    ),
                });
            }
            _ => {}
        }
    }
    for (_, (l, name, start, resource, id)) in open {
        t.bars.push(Bar {
            lane: l,
            element: id,
            detail: format!("{name} ({resource}) still running at the end of the record"),
            label: name,
            start,
            end: last,
            outcome: "running".into(),
        });
    }
    // Phases first, then systems, then the rest.
    lanes.sort_by_key(|l| match l.as_str() {
        "mission phases" => 0,
        "ground decisions" => 2,
        "contingencies" => 3,
        "executive" => 4,
        _ => 1,
    });
    // A series fed from two sources is drawn as one line in time order.
    for points in t.series.values_mut() {
        points.sort_by_key(|p| p.0);
        points.dedup();
    }
    t.lanes = lanes;
    t.skipped = reader.skipped;
    t.span = if first <= last { (first, last) } else { (0, 0) };
    t
}

/// The element id of a record line (empty if it names none).
fn element(v: &serde_json::Value) -> String {
    v["element"]["id"].as_str().unwrap_or_default().to_owned()
}

/// The page for a timeline: the self-contained HTML of `trace timeline`, titled `title`.
pub fn page(t: &Timeline, title: &str) -> std::io::Result<String> {
    let data = serde_json::to_string(t)
        .map_err(std::io::Error::other)?
        .replace("</", "<\\/");
    let title = title.replace('&', "&amp;").replace('<', "&lt;");
    // The title first: the data may hold anything, `{{TITLE}}` included.
    Ok(TEMPLATE
        .replace("{{TITLE}}", &title)
        .replace("/*DATA*/", &data))
}

/// The timelines of a fleet's vehicles on one time axis: each vehicle's lanes and series,
/// named by the vehicle, one after the other.
pub fn fleet(vehicles: Vec<(String, Timeline)>) -> Timeline {
    let mut all = Timeline {
        span: (i64::MAX, i64::MIN),
        ..Timeline::default()
    };
    for (name, t) in vehicles {
        let named = |lane: &str| format!("{name} · {lane}");
        all.lanes.extend(t.lanes.iter().map(|l| named(l)));
        all.bars.extend(t.bars.into_iter().map(|b| Bar {
            lane: named(&b.lane),
            ..b
        }));
        all.markers.extend(t.markers.into_iter().map(|m| Marker {
            lane: named(&m.lane),
            ..m
        }));
        all.series
            .extend(t.series.into_iter().map(|(k, v)| (named(&k), v)));
        all.skipped += t.skipped;
        all.span = (all.span.0.min(t.span.0), all.span.1.max(t.span.1));
    }
    if all.span.0 > all.span.1 {
        all.span = (0, 0);
    }
    all
}

/// Writes the page of a fleet's records, each named by its vehicle, to `out`.
pub fn write_fleet(
    records: &[(String, std::path::PathBuf)],
    out: &Path,
) -> std::io::Result<Timeline> {
    let mut vehicles = Vec::new();
    for (name, record) in records {
        let f = std::fs::File::open(record)
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", record.display())))?;
        vehicles.push((
            name.clone(),
            build(std::io::BufReader::new(f).lines().map_while(Result::ok)),
        ));
    }
    let t = fleet(vehicles);
    let title: Vec<&str> = records.iter().map(|(n, _)| n.as_str()).collect();
    std::fs::write(out, page(&t, &format!("fleet: {}", title.join(", ")))?)?;
    Ok(t)
}

/// Writes the page for `record` to `out`; returns the timeline drawn.
pub fn write(record: &Path, out: &Path) -> std::io::Result<Timeline> {
    let f = std::fs::File::open(record)?;
    let t = build(std::io::BufReader::new(f).lines().map_while(Result::ok));
    std::fs::write(out, page(&t, &record.display().to_string())?)?;
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bars_markers_and_series_come_from_the_record() {
        let lines = [
            r#"{"v":1,"kind":"entered","seq":1,"idx":0,"mission_ms":0,"token":2,"element":{"id":"Exc","name":"Excavate","type":"callActivity"}}"#,
            r#"{"v":1,"kind":"dispatched","seq":1,"idx":1,"mission_ms":0,"task":"1-3-1","resource":"excavation.excavate","element":{"id":"Dig","name":"Remove Material","type":"serviceTask"}}"#,
            r#"{"v":1,"kind":"dispatched","seq":1,"idx":1,"mission_ms":0,"task":"1-3-1","resource":"excavation.excavate","element":{"id":"Dig","name":"Remove Material","type":"serviceTask"}}"#,
            "{\"v\":1,\"kind\":\"fail",
            r#"{"v":1,"kind":"failed","seq":2,"idx":0,"mission_ms":1000,"task":"1-3-1","code":"TOOL_STUCK","message":"stuck"}"#,
            r#"{"v":1,"kind":"caught","seq":2,"idx":1,"mission_ms":1000,"what":"error","name":"TOOL_STUCK","element":{"id":"Fault","name":"Removal Fault","type":"boundaryEvent"}}"#,
            r#"{"v":1,"kind":"reboot","mission_ms":1500,"reboots":1,"recommanded":1}"#,
            r#"{"v":1,"kind":"dispatched","seq":3,"idx":0,"mission_ms":2000,"task":"1-4-1","resource":"power.read_battery","element":{"id":"Read","name":"Read Battery","type":"serviceTask"}}"#,
            r#"{"v":1,"kind":"data","seq":3,"idx":1,"mission_ms":1800,"key":"battery_soc_pct","value":81.0}"#,
            r#"{"v":1,"kind":"completed","seq":4,"idx":0,"mission_ms":2000,"task":"1-4-1","output":{"battery":{"soc_pct":80.5}}}"#,
            r#"{"v":1,"kind":"data","seq":4,"idx":2,"mission_ms":2500,"key":"arm_temp_c","value":-120.0}"#,
            r#"{"v":1,"kind":"left","seq":4,"idx":1,"mission_ms":3000,"token":2,"element":{"id":"Exc","name":"Excavate","type":"callActivity"}}"#,
        ];
        let t = build(lines.iter().map(|s| (*s).to_owned()));
        assert_eq!(t.skipped, 1);
        assert_eq!(
            t.lanes,
            [
                "mission phases",
                "system: excavation",
                "system: power",
                "contingencies",
                "executive"
            ]
        );
        assert_eq!(t.bars.len(), 3);
        assert!(
            t.bars
                .iter()
                .any(|b| b.label == "Remove Material" && b.outcome == "failed" && b.end == 1000)
        );
        assert!(
            t.bars
                .iter()
                .any(|b| b.label == "Excavate" && b.start == 0 && b.end == 3000)
        );
        assert_eq!(
            t.markers
                .iter()
                .map(|m| m.kind.as_str())
                .collect::<Vec<_>>(),
            ["fault", "boundary", "reboot"]
        );
        // The battery is one series, whether read by a task or reported as system data.
        assert_eq!(
            t.series.keys().collect::<Vec<_>>(),
            ["arm_temp_c", "battery state of charge (%)"]
        );
        assert_eq!(
            t.series["battery state of charge (%)"],
            [(1800, 81.0), (2000, 80.5)]
        );
        assert_eq!(t.span, (0, 3000));
    }
}
