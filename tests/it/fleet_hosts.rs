//! A fleet across three hosts (network namespaces made by the test): the lander, the ground and
//! the scout, each with its own `trace router` (QUIC, mutual TLS, access control by
//! certificate), the scout's linked to the lander's. The two-vehicle mission flies to its end
//! with the link between the vehicles cut and restored while the scout's report is on its way,
//! each message applied exactly once; and an executive, or a vehicle's router, that sends a
//! message as another participant, serves its inbox or claims its presence is refused by the
//! routers and never delivered.

use std::time::Duration;

use mission_tests::fleet_matrix::{SCOUT_FAULTS, judge};
use mission_tests::hosts::Lab;
use mission_tests::matrix::lines;
use mission_tests::repo;

const REFUSAL: &str = connector_zenoh::router::REFUSAL;
const WAIT: Duration = Duration::from_secs(20);

fn path(rel: &str) -> String {
    repo().join(rel).to_string_lossy().into_owned()
}

/// The mission's speed: 500 mission ms per wall ms, so the lander's six hours without a report
/// are 43 s of wall time, and the scout's hop and survey 3 s.
const SPEED: &str = "500";

/// A simulator of `vehicle` in namespace `ns`, with the certificate `cert`, started as `name`.
fn simulator(lab: &mut Lab, ns: &str, vehicle: &str, cert: &str, extra: &[&str]) {
    let mut args = Lab::client_flags("lander_sim.json5", cert);
    let store = format!("{vehicle}-sim");
    args.extend(
        [
            "--vehicle",
            vehicle,
            "--speed",
            SPEED,
            "--seed",
            "1",
            "--profile",
            "quiet",
            "--start-ms",
            "1790000000000",
            "--store",
            &store,
        ]
        .map(str::to_owned),
    );
    args.extend(extra.iter().map(|s| (*s).to_owned()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let c = lab.command(ns, "elap-sim", &args);
    lab.start(cert, c);
}

/// The executive of `pool` in namespace `ns`, with the certificate `cert`: `trace run` of the
/// two-vehicle mission, on the store `<pool>` in the lab.
fn executive(lab: &mut Lab, ns: &str, pool: &str, cert: &str) {
    let mut args: Vec<String> = [
        "run",
        &path("deploy/missions/europa-fleet.bpmn"),
        "--participant",
        pool,
        "--store",
        pool,
        "--catalogue-wait",
        "30",
        "--connectors",
        &path(&format!("deploy/fleet/{pool}.toml")),
    ]
    .map(str::to_owned)
    .into();
    args.extend(Lab::client_flags("executive.json5", cert));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let c = lab.command(ns, "trace", &args);
    lab.spawn(&format!("{pool}-executive"), c);
}

#[test]
fn the_fleet_flies_across_three_hosts_and_a_cut_between_the_vehicles_loses_and_repeats_nothing() {
    let mut lab = Lab::fleet("fleet");
    lab.routers();
    let (lander, ground, scout) = (lab.lander.clone(), lab.grounds[0].clone(), lab.scout_ns());
    std::fs::write(lab.dir.join("scout-faults.json"), SCOUT_FAULTS).expect("faults");
    simulator(&mut lab, &lander, "lander", "lander_sim", &[]);
    simulator(
        &mut lab,
        &scout,
        "scout",
        "scout_sim",
        &["--faults", "scout-faults.json"],
    );
    let mut station = Lab::client_flags("station.json5", "station-a");
    station.extend(
        [
            "--station",
            "station-a",
            "--policy",
            &path("deploy/ground/policy.toml"),
        ]
        .map(str::to_owned),
    );
    let station: Vec<&str> = station.iter().map(String::as_str).collect();
    let c = lab.command(&ground, "ground-station", &station);
    lab.start("station-a", c);
    executive(&mut lab, &lander, "lander", "exec");
    executive(&mut lab, &scout, "scout", "scout_exec");
    let (lr, sr) = (
        lab.dir.join("lander/record.jsonl"),
        lab.dir.join("scout/record.jsonl"),
    );

    // The second exchange: the scout has taken the lander's second request and hops to the
    // site. The link between the vehicles goes; the scout surveys alone and its report, once
    // committed, cannot reach the lander.
    lab.until_record(&sr, "the second request taken", WAIT * 3, |ls| {
        ls.iter()
            .filter(|l| l["kind"] == "instance_started")
            .count()
            >= 2
    });
    let link = lab.scout_link();
    lab.link(link, false);
    let said = lab.until_logged(
        "scout-executive",
        &["message not acknowledged yet"],
        Duration::from_secs(60),
    );
    eprintln!("during the cut: {said}");
    let unsent = lines(&sr)
        .iter()
        .filter(|l| l["kind"] == "message_sent")
        .count();
    lab.link(link, true);

    // Both parts end; the lander heard every report, the one sent into the cut once.
    for pool in ["lander", "scout"] {
        let name = format!("{pool}-executive");
        let pid = lab.proc(&name).child.id();
        let ended = mission_tests::hosts::poll(Duration::from_secs(120), || {
            lab.proc(&name).child.try_wait().ok().flatten()
        });
        let Some(status) = ended else {
            let _ = std::process::Command::new("kill")
                .args(["-9", &pid.to_string()])
                .status();
            panic!("{name} did not end within two minutes:\n{}", lab.log(&name));
        };
        assert!(status.success(), "{name}: {status}\n{}", lab.log(&name));
    }
    let (l, s) = (lines(&lr), lines(&sr));
    let flight = judge(&l, &s);
    assert!(flight.exact(), "{flight:?}");
    assert_eq!(flight.outcome.as_deref(), Some("completed"), "{flight:?}");
    assert_eq!((flight.requests, flight.reports), (3, 3), "{flight:?}");
    assert!(
        unsent >= 2,
        "the cut came before the second report: {unsent} sent"
    );
    assert!(
        !l.iter().any(|v| v["kind"] == "timer_fired"),
        "the lander decided without a report"
    );
    // The flight needed nothing the access control forbids.
    for router in ["lander-router", "ground-router1", "scout-router"] {
        let log = lab.log(router);
        assert!(!log.contains(REFUSAL), "{router} refused something:\n{log}");
    }
}

/// One message a participant may not send, or a claim it may not make.
struct Forged {
    what: &'static str,
    ns: &'static str,
    cert: &'static str,
    op: &'static str,
    key: &'static str,
    refused_by: &'static str,
}

#[test]
fn an_executive_sends_messages_only_as_its_own_participant() {
    let mut lab = Lab::fleet("fleet-acl");
    lab.routers();
    let ns = |lab: &Lab, which: &str| match which {
        "lander" => lab.lander.clone(),
        _ => lab.scout_ns(),
    };
    // The honest side: each executive serves its own inbox and hears the fleet's presence.
    let (lander, scout) = (ns(&lab, "lander"), ns(&lab, "scout"));
    lab.start_probe(
        "lander-inbox",
        &lander,
        "exec",
        &["queryable", "trace/d/fleet/lander/message/*/*"],
    );
    lab.start_probe(
        "scout-inbox",
        &scout,
        "scout_exec",
        &["queryable", "trace/d/fleet/scout/message/*/*"],
    );
    lab.start_probe(
        "lander-hears",
        &lander,
        "exec",
        &["alive", "trace/d/fleet/*/alive/*"],
    );
    // Each sends as itself, across the vehicles' link: delivered (which also says every
    // declaration has crossed both routers).
    for (from, cert, key, inbox) in [
        (
            "lander",
            "exec",
            "trace/d/fleet/scout/message/lander/honest-1",
            "scout-inbox",
        ),
        (
            "scout",
            "scout_exec",
            "trace/d/fleet/lander/message/scout/honest-2",
            "lander-inbox",
        ),
    ] {
        let at = ns(&lab, from);
        let delivered = mission_tests::hosts::poll(WAIT, || {
            let out = lab.probe(&at, cert, &["get", key, "{}"]).output().ok()?;
            let out = String::from_utf8_lossy(&out.stdout).into_owned();
            out.contains(&format!("reply ok {key} probe")).then_some(())
        });
        assert!(
            delivered.is_some(),
            "{from} could not send as itself: {key}"
        );
        lab.until_said(inbox, &["query", key], WAIT);
    }

    let forged = [
        Forged {
            what: "the lander's executive sends as the scout",
            ns: "lander",
            cert: "exec",
            op: "get",
            key: "trace/d/fleet/scout/message/scout/forged-1",
            refused_by: "lander-router",
        },
        Forged {
            what: "the lander's executive sends to itself as the scout",
            ns: "lander",
            cert: "exec",
            op: "get",
            key: "trace/d/fleet/lander/message/scout/forged-2",
            refused_by: "lander-router",
        },
        Forged {
            what: "the scout's executive sends as the lander",
            ns: "scout",
            cert: "scout_exec",
            op: "get",
            key: "trace/d/fleet/lander/message/lander/forged-3",
            refused_by: "scout-router",
        },
        Forged {
            what: "the scout's executive serves the lander's inbox",
            ns: "scout",
            cert: "scout_exec",
            op: "queryable",
            key: "trace/d/fleet/lander/message/*/*",
            refused_by: "scout-router",
        },
        Forged {
            what: "the scout's executive claims the lander's presence",
            ns: "scout",
            cert: "scout_exec",
            op: "token",
            key: "trace/d/fleet/lander/alive/done",
            refused_by: "scout-router",
        },
        Forged {
            what: "the scout's simulator sends a message",
            ns: "scout",
            cert: "scout_sim",
            op: "get",
            key: "trace/d/fleet/lander/message/scout/forged-6",
            refused_by: "scout-router",
        },
        Forged {
            what: "a station sends a message",
            ns: "ground",
            cert: "station-a",
            op: "get",
            key: "trace/d/fleet/lander/message/lander/forged-7",
            refused_by: "ground-router1",
        },
    ];
    for f in &forged {
        let at = match f.ns {
            "ground" => lab.grounds[0].clone(),
            other => ns(&lab, other),
        };
        let mut c = lab.probe(&at, f.cert, &[f.op, f.key, "forged"]);
        if f.op == "get" {
            let out = c.output().expect("probe runs");
            let out = String::from_utf8_lossy(&out.stdout);
            assert!(!out.contains("reply ok"), "{}: answered: {out}", f.what);
        } else {
            lab.start(&format!("forged-{}", f.op), c);
        }
        lab.until_logged(f.refused_by, &[REFUSAL, f.key], WAIT);
        eprintln!("refused as it must be: {}", f.what);
    }

    // A vehicle's router is checked too: a process holding the scout router's certificate,
    // connected straight to the lander's router, may not send as the lander either.
    let direct = format!(
        "connect/endpoints=[\"quic/{}:7447\"]",
        Lab::lander_addr(lab.scout_link())
    );
    let key = "trace/d/fleet/lander/message/lander/forged-8";
    let out = lab
        .probe(
            &scout,
            "scout-router",
            &["--zenoh-set", &direct, "get", key, "forged"],
        )
        .output()
        .expect("probe runs");
    let out = String::from_utf8_lossy(&out.stdout);
    assert!(!out.contains("reply ok"), "answered: {out}");
    lab.until_logged("lander-router", &[REFUSAL, key], WAIT);

    // A message the inboxes take after the forged ones: what they served by then is all they
    // will serve of those.
    let key = "trace/d/fleet/scout/message/lander/honest-3";
    let out = lab
        .probe(&lander, "exec", &["get", key, "{}"])
        .output()
        .expect("probe");
    assert!(String::from_utf8_lossy(&out.stdout).contains("reply ok"));
    let served = lab.output("lander-inbox") + &lab.output("scout-inbox");
    assert!(
        !served.contains("forged"),
        "a forged message was served:\n{served}"
    );
    let heard = lab.output("lander-hears");
    assert!(
        !heard.contains("lander/alive"),
        "a forged presence arrived:\n{heard}"
    );
}
