//! A station's flood across the two-host lab (tests/it/hosts.rs) on a link shaped to 1 Mbit/s:
//! 60,000 puts its certificate may send, in 20 s, thinned at the ground router to at most 20 a
//! second, the site approval answered meanwhile applied once as without the flood; and 20,000
//! puts it may not send at the same time, leaving a bounded router log that names the
//! certificate.

use std::time::Duration;

use mission_tests::hosts::Lab;

use crate::hosts::{WAIT, approval_answered_once, run_approval, slow_policy, station_with};

const REFUSAL: &str = connector_zenoh::router::REFUSAL;

/// Puts one station's certificate may send, but not 3,000 a second of them.
const FLOODED: &str = "trace/d/act/ground/approve_site/status";

#[test]
fn a_stations_flood_over_a_narrow_link_is_thinned_at_its_router_and_changes_nothing() {
    let mut lab = Lab::new("flood", 1);
    lab.routers();
    // A 1 Mbit/s link to the lander.
    lab.shape(1, "1mbit");
    let (lander, ground) = (lab.lander.clone(), lab.grounds[0].clone());
    // What of the flood reaches the lander, counted there.
    lab.start_probe("lander-count", &lander, "exec", &["count", FLOODED]);
    // A listener to the telemetry the station may not publish: without one, its session would
    // drop those puts itself (Zenoh sends a put only where a subscriber is), and the router
    // would have nothing to refuse.
    lab.start_probe("lander-tm", &lander, "exec", &["sub", "trace/d/tm/**"]);
    lab.start_probe(
        "lander-ear",
        &lander,
        "exec",
        &["alive", "trace/*/alive/**"],
    );
    // The approval is answered 10 s (wall) after it opens, while the flood runs.
    let policy = slow_policy(&lab, 10_000);
    station_with(&mut lab, 1, "station-a", &policy);
    lab.until_said("lander-ear", &["alive/ground/station-a"], WAIT);
    run_approval(&mut lab);
    let record = lab.dir.join("store/record.jsonl");
    lab.until_recorded(&record, "the approval opened", WAIT, |l| {
        l["kind"] == "user_task_opened"
    });
    // The same certificate, from a second session: 60,000 allowed puts in 20 s, and 20,000
    // on a key it may not publish on.
    lab.start_probe("flood", &ground, "station-a", &["flood", FLOODED, "60000"]);
    lab.start_probe(
        "refused-flood",
        &ground,
        "station-a",
        &["flood", "trace/d/tm/lander_sim/clock", "20000"],
    );
    lab.until_said("flood", &["flooded 60000"], Duration::from_secs(90));
    lab.until_said("refused-flood", &["flooded 20000"], Duration::from_secs(90));
    // The router let through at most 20 a second of the allowed ones (a second's slack for the
    // flood's own start and end).
    let counted = lab.until_said("lander-count", &["counted "], Duration::from_secs(60));
    let crossed: u64 = counted
        .trim_start_matches("counted ")
        .trim()
        .parse()
        .expect("a count");
    eprintln!("flood: {crossed} of 60000 allowed puts crossed the link");
    assert!(
        crossed <= 20 * 22,
        "{crossed} of the flood's 60,000 puts crossed the link"
    );
    // The mission as without a flood: the station's answer applied once, no timer fired, no
    // connection lost, completed.
    let (lines, took) = approval_answered_once(&mut lab);
    let answered = lines
        .iter()
        .find(|l| l["kind"] == "user_task_answered")
        .expect("answered");
    assert!(
        answered["operator"]
            .as_str()
            .is_some_and(|o| o.ends_with("@station-a")),
        "{answered}"
    );
    eprintln!(
        "flood: the approval was answered {took} mission ms after it opened (10 s wall at 300x: 3,000,000)"
    );
    // The refused flood left a bounded log naming the certificate: at most the limiter's 50
    // lines per 10 s.
    let log = lab.log("ground-router1");
    let refusals: Vec<&str> = log.lines().filter(|l| l.contains(REFUSAL)).collect();
    eprintln!(
        "flood: {} refusal lines, {} bytes of router log",
        refusals.len(),
        log.len()
    );
    assert!(!refusals.is_empty(), "the refused flood was not logged");
    assert!(refusals.len() <= 4 * 50, "{} refusal lines", refusals.len());
    assert!(
        refusals.iter().all(|l| l.contains("station-a")),
        "a refusal that does not name the certificate:\n{}",
        refusals.join("\n")
    );
}
