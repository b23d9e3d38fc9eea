//! The studio's HTTP routes over a real socket: the page, listing, reading and saving missions
//! (atomic, refusing what is not BPMN), validation, the catalogues, and every refusal — names
//! that leave the directory, unknown files, bodies over the loader's limit, other interfaces.

use std::net::SocketAddr;
use std::path::PathBuf;

use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::{StartError, Studio, bind};

const EUROPA: &str = include_str!("../../../deploy/missions/europa-bsm1.bpmn");

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trace-studio-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    std::fs::write(d.join("europa.bpmn"), EUROPA).expect("europa");
    d
}

async fn serve(dir: PathBuf) -> SocketAddr {
    let deploy = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../deploy"));
    let catalogues =
        crate::read_catalogues(&[deploy.join("catalogues"), deploy.join("ground/forms.json")])
            .expect("catalogues");
    let bound = bind(
        Studio {
            dir,
            catalogues,
            connectors: Some(
                crate::read_connectors(std::path::Path::new(concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/../../deploy/connectors.toml"
                )))
                .expect("connectors"),
            ),
            live: None,
            ground: None,
        },
        "127.0.0.1:0".parse().unwrap(),
        false,
    )
    .await
    .expect("bound");
    let addr = bound.addr().expect("addr");
    tokio::spawn(bound.serve());
    addr
}

/// One HTTP/1.1 request; returns the status and the body.
async fn http(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, String) {
    let mut s = tokio::net::TcpStream::connect(addr).await.expect("connect");
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: studio\r\nConnection: close\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).await.expect("write");
    s.write_all(body).await.expect("write");
    let mut out = Vec::new();
    s.read_to_end(&mut out).await.expect("read");
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text[9..12].parse().expect("status");
    let body = text
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_owned();
    (status, body)
}

fn json(body: &str) -> serde_json::Value {
    // Bodies are small and not chunked here, except large ones we do not parse.
    serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {body}"))
}

#[tokio::test]
async fn the_page_and_the_missions_are_served() {
    let addr = serve(dir("serve")).await;
    let (status, page) = http(addr, "GET", "/", b"").await;
    assert_eq!(status, 200);
    assert!(page.contains("TRACE Studio"), "{page}");
    let (status, list) = http(addr, "GET", "/api/missions", b"").await;
    assert_eq!(status, 200);
    assert_eq!(json(&list)[0]["name"], "europa.bpmn");
    let (status, _) = http(addr, "GET", "/api/missions/europa.bpmn", b"").await;
    assert_eq!(status, 200);
    let (status, cats) = http(addr, "GET", "/api/catalogues", b"").await;
    assert_eq!(status, 200);
    assert_eq!(json(&cats)[0]["server"], "lander_sim");
    let (status, v) = http(addr, "POST", "/api/validate", EUROPA.as_bytes()).await;
    assert_eq!(status, 200);
    assert_eq!(json(&v)["verdict"], "valid", "{v}");
    let (status, _) = http(addr, "GET", "/no-such-file.js", b"").await;
    assert_eq!(status, 404);
}

/// A GET with extra header lines; the raw response's head and body bytes.
async fn get_with(addr: SocketAddr, path: &str, headers: &str) -> (String, Vec<u8>) {
    let mut s = tokio::net::TcpStream::connect(addr).await.expect("connect");
    let head = format!("GET {path} HTTP/1.1\r\nHost: studio\r\nConnection: close\r\n{headers}\r\n");
    s.write_all(head.as_bytes()).await.expect("write");
    let mut out = Vec::new();
    s.read_to_end(&mut out).await.expect("read");
    let at = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a head");
    (
        String::from_utf8_lossy(&out[..at]).to_lowercase(),
        out[at + 4..].to_vec(),
    )
}

#[tokio::test]
async fn the_page_is_served_gzipped_and_revalidated_by_its_tag() {
    let addr = serve(dir("gzip")).await;
    let (plain_head, plain) = get_with(addr, "/", "").await;
    assert!(!plain_head.contains("content-encoding"), "{plain_head}");
    let (head, zipped) = get_with(addr, "/", "Accept-Encoding: br;q=1, gzip;q=0.8\r\n").await;
    assert!(head.contains("content-encoding: gzip"), "{head}");
    assert!(head.contains("cache-control: no-cache") && head.contains("vary: accept-encoding"));
    // gzip's magic bytes, and smaller than the page.
    assert_eq!(&zipped[..2], &[0x1f, 0x8b]);
    assert!(
        zipped.len() < plain.len(),
        "{} ≥ {}",
        zipped.len(),
        plain.len()
    );
    let tag = head
        .lines()
        .find_map(|l| l.strip_prefix("etag: "))
        .expect("an entity tag")
        .to_owned();
    let (head, body) = get_with(addr, "/", &format!("If-None-Match: {tag}\r\n")).await;
    assert!(head.starts_with("http/1.1 304"), "{head}");
    assert!(body.is_empty());
    let (head, _) = get_with(addr, "/", "If-None-Match: \"other\"\r\n").await;
    assert!(head.starts_with("http/1.1 200"), "{head}");
}

#[tokio::test]
async fn validation_reports_what_trace_validate_reports() {
    let addr = serve(dir("validate")).await;
    let broken = EUROPA.replace(
        r#"targetRef="SelectInitialSites""#,
        r#"targetRef="Nowhere""#,
    );
    let (_, v) = http(addr, "POST", "/api/validate", broken.as_bytes()).await;
    let v = json(&v);
    assert_eq!(v["verdict"], "invalid", "{v}");
    assert!(
        v["diagnostics"]
            .as_array()
            .unwrap()
            .iter()
            .any(|d| d["severity"] == "error" && d["line"].as_u64().is_some()),
        "{v}"
    );
    let (_, v) = http(addr, "POST", "/api/validate", b"<not xml").await;
    assert_eq!(json(&v)["verdict"], "unreadable");
    let (status, _) = http(addr, "POST", "/api/validate/..%2Fx.bpmn", EUROPA.as_bytes()).await;
    assert_eq!(status, 400);
}

#[tokio::test]
async fn tasks_are_checked_against_the_catalogues_as_trace_run_would() {
    let addr = serve(dir("catalogue")).await;
    let (_, v) = http(addr, "POST", "/api/validate", EUROPA.as_bytes()).await;
    let v = json(&v);
    assert_eq!(v["catalogue"]["checked"], true, "{v}");
    assert_eq!(v["catalogue"]["mismatches"], 0, "{v}");
    assert_eq!(
        v["catalogue"]["servers"],
        serde_json::json!(["lander_sim", "ground"]),
        "{v}"
    );
    assert_eq!(v["catalogue"]["missing"], serde_json::json!([]), "{v}");
    // An action no system serves, and an input the action does not take (so its required
    // field is not written): each named, on its task, while the model stays valid BPMN.
    let broken = EUROPA
        .replace(
            r#"resource="world_model.build_terrain_map""#,
            r#"resource="world_model.build_terrain""#,
        )
        .replace(r#"target="exposure_ms""#, r#"target="exposure_s""#);
    let (_, v) = http(addr, "POST", "/api/validate", broken.as_bytes()).await;
    let v = json(&v);
    assert_eq!(v["verdict"], "valid", "{v}");
    assert_eq!(v["catalogue"]["mismatches"], 3, "{v}");
    let mismatches: Vec<_> = v["diagnostics"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["code"] == crate::checks::CATALOGUE_CODE)
        .collect();
    assert!(
        mismatches.iter().any(|d| d["message"]
            .as_str()
            .unwrap()
            .contains("`world_model.build_terrain`")),
        "{v}"
    );
    assert!(
        mismatches.iter().any(|d| d["message"]
            .as_str()
            .unwrap()
            .contains("input `exposure_s`")),
        "{v}"
    );
    assert!(
        mismatches.iter().any(|d| d["message"]
            .as_str()
            .unwrap()
            .contains("required goal field `exposure_ms`")),
        "{v}"
    );
    for d in &mismatches {
        let id = d["element"].as_str().unwrap();
        let line = d["line"].as_u64().unwrap() as usize;
        assert!(
            broken
                .lines()
                .nth(line - 1)
                .unwrap()
                .contains(&format!("id=\"{id}\"")),
            "line {line} is not {id}'s: {d}"
        );
    }
}

#[tokio::test]
async fn requirements_are_kept_beside_the_mission_and_verify_refuses_what_it_cannot_check() {
    let d = dir("verify");
    let addr = serve(d.clone()).await;
    let (status, _) = http(addr, "GET", "/api/requirements/europa.bpmn", b"").await;
    assert_eq!(status, 404);
    let text = "[[requirement]]\nname = \"ends\"\ncheck = 'eventually ended'\n";
    let (status, _) = http(
        addr,
        "PUT",
        "/api/requirements/europa.bpmn",
        text.as_bytes(),
    )
    .await;
    assert_eq!(status, 200);
    assert_eq!(
        std::fs::read_to_string(d.join("europa.req.toml")).unwrap(),
        text
    );
    let (status, back) = http(addr, "GET", "/api/requirements/europa.bpmn", b"").await;
    assert_eq!((status, back.as_str()), (200, text));
    let (status, _) = http(addr, "PUT", "/api/requirements/..%2Fx.bpmn", b"x").await;
    assert_eq!(status, 400);
    let (status, _) = http(addr, "PUT", "/api/requirements/europa.bpmn", b"\xff\xfe").await;
    assert_eq!(status, 422);
    // What verify refuses before Spin runs: not a request, a bound out of range, a model
    // that is not valid, a requirement that does not compile against the model.
    let (status, v) = http(addr, "POST", "/api/verify/europa.bpmn", b"<xml/>").await;
    assert_eq!(status, 400, "{v}");
    let body = |model: &str, req: &str, loops: u8| {
        serde_json::json!({ "model": model, "requirements": req, "loops": loops }).to_string()
    };
    let (status, v) = http(
        addr,
        "POST",
        "/api/verify/europa.bpmn",
        body(EUROPA, "", 9).as_bytes(),
    )
    .await;
    assert_eq!(status, 400, "{v}");
    let broken = EUROPA.replace(
        r#"targetRef="SelectInitialSites""#,
        r#"targetRef="Nowhere""#,
    );
    let (status, v) = http(
        addr,
        "POST",
        "/api/verify/europa.bpmn",
        body(&broken, "", 1).as_bytes(),
    )
    .await;
    assert_eq!(status, 422, "{v}");
    assert!(
        json(&v)["error"].as_str().unwrap().contains("invalid"),
        "{v}"
    );
    let bad = "[[requirement]]\nname = \"x\"\ncheck = 'eventually done \"No Such Task\"'\n";
    let (status, v) = http(
        addr,
        "POST",
        "/api/verify/europa.bpmn",
        body(EUROPA, bad, 1).as_bytes(),
    )
    .await;
    assert_eq!(status, 422, "{v}");
    assert!(
        json(&v)["error"].as_str().unwrap().contains("No Such Task"),
        "{v}"
    );
}

#[tokio::test]
async fn a_token_game_is_played_through_the_routes_and_refuses_acts_that_do_not_fit() {
    let addr = serve(dir("simulate")).await;
    let (status, v) = http(addr, "POST", "/api/simulate", b"<not bpmn").await;
    assert_eq!(status, 422, "{v}");
    let (status, v) = http(addr, "POST", "/api/simulate", EUROPA.as_bytes()).await;
    assert_eq!(status, 200, "{v}");
    let v = json(&v);
    let id = v["id"].as_u64().expect("an id");
    let first = v["view"]["tasks"][0]["element"]
        .as_str()
        .expect("a task waits")
        .to_owned();
    let steps = v["view"]["steps"].as_u64().unwrap();
    let path = format!("/api/simulate/{id}");
    let (status, _) = http(addr, "POST", &path, b"{not json").await;
    assert_eq!(status, 400);
    let (status, _) = http(addr, "POST", &path, br#"{"act": "dance", "element": "x"}"#).await;
    assert_eq!(status, 400);
    let (status, v) = http(
        addr,
        "POST",
        &path,
        br#"{"act": "complete", "element": "NoSuchTask"}"#,
    )
    .await;
    assert_eq!(status, 422, "{v}");
    let v = json(&v);
    assert!(v["error"].as_str().unwrap().contains("NoSuchTask"), "{v}");
    assert_eq!(
        v["view"]["steps"].as_u64(),
        Some(steps),
        "a refused act changes nothing"
    );
    let act = serde_json::json!({ "act": "complete", "element": first }).to_string();
    let (status, v) = http(addr, "POST", &path, act.as_bytes()).await;
    assert_eq!(status, 200, "{v}");
    let v = json(&v);
    assert!(v["view"]["steps"].as_u64().unwrap() > steps, "{v}");
    assert!(
        v["view"]["trace"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!(format!("exit:{first}"))),
        "{v}"
    );
    let (status, _) = http(addr, "POST", "/api/simulate/999999", act.as_bytes()).await;
    assert_eq!(status, 404);
    let (status, _) = http(addr, "DELETE", &path, b"").await;
    assert_eq!(status, 204);
    let (status, _) = http(addr, "POST", &path, act.as_bytes()).await;
    assert_eq!(status, 404);
}

#[tokio::test]
async fn a_record_is_replayed_on_the_model_or_refused_naming_the_line() {
    let addr = serve(dir("replay")).await;
    let body = |record: &str| serde_json::json!({ "model": EUROPA, "record": record }).to_string();
    let started = r#"{"v":1,"kind":"instance_started","seq":1,"idx":0,"mission_ms":5,"instance":1,"process":"BSM1","vars":{}}"#;
    let (status, v) = http(addr, "POST", "/api/replay", body(started).as_bytes()).await;
    assert_eq!(status, 200, "{v}");
    let frames = json(&v)["frames"].as_array().cloned().expect("frames");
    assert_eq!(frames.len(), 1, "{v}");
    assert_eq!(frames[0]["what"], "instance started");
    assert!(
        frames[0]["tokens"]
            .as_object()
            .is_some_and(|t| !t.is_empty()),
        "{v}"
    );
    let (status, v) = http(addr, "POST", "/api/replay", body("{not json").as_bytes()).await;
    assert_eq!(status, 422, "{v}");
    assert!(
        json(&v)["error"]
            .as_str()
            .unwrap()
            .starts_with("record line 1:"),
        "{v}"
    );
    let (status, _) = http(addr, "POST", "/api/replay", b"[]").await;
    assert_eq!(status, 400);
}

#[tokio::test]
async fn an_offline_studio_says_it_follows_no_mission_and_is_no_ground_station() {
    let addr = serve(dir("offline")).await;
    for path in ["/api/ops/executives", "/api/ops/m1/state", "/api/ground"] {
        let (status, v) = http(addr, "GET", path, b"").await;
        assert_eq!(status, 503, "{path}: {v}");
        assert!(json(&v)["error"].as_str().is_some(), "{v}");
    }
    let (status, _) = http(
        addr,
        "POST",
        "/api/ground/1",
        br#"{"operator":"ana","fields":{}}"#,
    )
    .await;
    assert_eq!(status, 503);
}

#[tokio::test]
async fn a_save_is_atomic_and_refuses_what_is_not_bpmn() {
    let d = dir("save");
    let addr = serve(d.clone()).await;
    let edited = EUROPA.replace(r#"source="40""#, r#"source="80""#);
    let (status, body) = http(addr, "PUT", "/api/missions/europa.bpmn", edited.as_bytes()).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(
        std::fs::read_to_string(d.join("europa.bpmn")).unwrap(),
        edited
    );
    // A new file, with errors (a drawing in progress), is saved too.
    let (status, body) = http(addr, "PUT", "/api/missions/new.bpmn", b"<definitions xmlns=\"http://www.omg.org/spec/BPMN/20100524/MODEL\"><process id=\"P\" isExecutable=\"true\"><task id=\"T\"/></process></definitions>").await;
    assert_eq!(status, 200, "{body}");
    // Not BPMN: refused with the diagnostics, the file untouched, no temporary file left.
    for garbage in [
        &b"garbage"[..],
        b"<html><body/></html>",
        b"<?xml version=\"1.0\"?><!DOCTYPE a [<!ENTITY x \"y\">]><a>&x;</a>",
    ] {
        let (status, body) = http(addr, "PUT", "/api/missions/europa.bpmn", garbage).await;
        assert_eq!(status, 422, "{body}");
        assert!(
            json(&body)["error"]
                .as_str()
                .unwrap()
                .contains("not a BPMN model")
        );
    }
    assert_eq!(
        std::fs::read_to_string(d.join("europa.bpmn")).unwrap(),
        edited
    );
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}

#[tokio::test]
async fn names_outside_the_directory_and_unknown_files_are_refused() {
    let d = dir("names");
    std::fs::write(d.join("secret.txt"), "no").unwrap();
    let addr = serve(d.clone()).await;
    for name in [
        "..%2Fetc%2Fpasswd",
        "secret.txt",
        ".hidden.bpmn",
        "a%2Fb.bpmn",
        "..bpmn",
        "%2Fetc%2Fx.bpmn",
    ] {
        let (status, body) = http(addr, "GET", &format!("/api/missions/{name}"), b"").await;
        assert_eq!(status, 400, "{name}: {body}");
        assert!(
            json(&body)["error"]
                .as_str()
                .unwrap()
                .contains("not a mission file name")
        );
        let (status, _) = http(
            addr,
            "PUT",
            &format!("/api/missions/{name}"),
            EUROPA.as_bytes(),
        )
        .await;
        assert_eq!(status, 400, "{name}");
    }
    let (status, body) = http(addr, "GET", "/api/missions/absent.bpmn", b"").await;
    assert_eq!(status, 404, "{body}");
    // Over the loader's limit: refused before it is read.
    let huge = vec![b' '; executive_model::Options::default().limits.max_bytes + 10];
    let (status, _) = http(addr, "PUT", "/api/missions/huge.bpmn", &huge).await;
    assert_eq!(status, 413);
    assert!(!d.join("huge.bpmn").exists());
}

#[tokio::test]
async fn only_loopback_unless_asked_and_only_a_directory() {
    let studio = Studio {
        dir: dir("bind"),
        catalogues: Vec::new(),
        connectors: None,
        live: None,
        ground: None,
    };
    let e = bind(studio.clone(), "0.0.0.0:0".parse().unwrap(), false).await;
    assert!(matches!(e, Err(StartError::NotLoopback(_))));
    let e = bind(
        Studio {
            dir: studio.dir.join("europa.bpmn"),
            catalogues: Vec::new(),
            connectors: None,
            live: None,
            ground: None,
        },
        "127.0.0.1:0".parse().unwrap(),
        false,
    )
    .await;
    assert!(matches!(e, Err(StartError::NoDirectory(_))));
}

#[test]
fn a_catalogue_that_is_not_one_is_named() {
    let d = dir("catalogue");
    std::fs::write(d.join("bad.json"), "{\"server\": 3}").unwrap();
    let e = crate::read_catalogues(&[d.join("bad.json")]).unwrap_err();
    assert!(e.to_string().contains("bad.json: not a catalogue"), "{e}");
}
