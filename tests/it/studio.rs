//! TRACE Studio in a real browser (Debian's chromium through chromedriver, WebDriver):
//! `trace studio` serves a directory holding the Europa mission; the TRACE panel shows a task's
//! action and goal inputs from the catalogues, refuses a path that is not a goal field, marks
//! a wrongly typed input, gives a new task its action and a typed input, and offers an error
//! boundary the action's error codes; `trace validate`'s diagnostics and `trace run`'s check
//! against the catalogues land on the element they concern; the saved file passes
//! `trace validate` and differs from the modeler's export only where edited; a copy with a
//! seeded flaw is verified and its counterexample replayed on the diagram in order; the token
//! game plays Europa to its end. And the catalogues live: a studio on a router's network offers
//! what a running simulator serves, and stops offering it when the simulator is gone.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use fantoccini::{Client, ClientBuilder, Locator};
use mission_tests::{bin, repo};
use serde_json::{Value, json};

use crate::protocol::tempdir;

/// A child process killed when dropped.
pub(crate) struct Kill(pub(crate) Child);

impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `command` and returns it with the first stdout line that contains `needle`.
pub(crate) fn start(mut command: Command, needle: &str) -> (Kill, String) {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap_or_else(|e| panic!("{command:?}: {e}"));
    let out = child.stdout.take().expect("stdout");
    let mut lines = BufReader::new(out).lines();
    let line = loop {
        match lines.next() {
            Some(Ok(l)) if l.contains(needle) => break l,
            Some(Ok(_)) => continue,
            _ => panic!("{command:?} ended without saying {needle:?}"),
        }
    };
    // Keep reading so the process never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    (Kill(child), line)
}

pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

pub(crate) const WAIT: Duration = Duration::from_secs(30);

/// A started studio with chromedriver beside it, both killed when dropped.
pub(crate) struct Page {
    /// The studio's address (`http://127.0.0.1:PORT/`).
    pub(crate) url: String,
    driver_port: u16,
    _studio: Kill,
    _driver: Kill,
}

impl Page {
    /// Starts `studio` (a `trace studio` command) and a chromedriver on a free port.
    pub(crate) fn start(studio: Command) -> Page {
        let (studio, ready) = start(studio, "ready http://");
        let url = ready
            .split_whitespace()
            .nth(1)
            .expect("the studio's address")
            .to_owned();
        let driver_port = free_port();
        let mut driver = Command::new("chromedriver");
        driver.arg(format!("--port={driver_port}"));
        let (driver, _) = start(driver, "started successfully");
        Page {
            url,
            driver_port,
            _studio: studio,
            _driver: driver,
        }
    }

    /// Plays `scenario` (given a browser session and the studio's address) to its end; the
    /// session is closed even when the scenario fails, or Chromium would outlive the test.
    pub(crate) fn play<F>(self, scenario: impl FnOnce(Client, String) -> F)
    where
        F: std::future::Future<Output = ()> + Send + 'static,
    {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        rt.block_on(async move {
            let c = self.browser().await;
            let outcome = tokio::spawn(scenario(c.clone(), self.url.clone())).await;
            let _ = c.close().await;
            if let Err(e) = outcome {
                std::panic::resume_unwind(e.into_panic());
            }
        });
    }

    /// A WebDriver session of headless Debian chromium.
    pub(crate) async fn browser(&self) -> Client {
        session(self.driver_port).await
    }
}

/// A WebDriver session of headless Debian chromium, through the chromedriver on `driver_port`.
pub(crate) async fn session(driver_port: u16) -> Client {
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        json!({ "binary": "/usr/bin/chromium", "args": [
            "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
            "--disable-quic", "--no-first-run", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--window-size=1600,900"] }),
    );
    ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(caps)
        .connect(&format!("http://127.0.0.1:{driver_port}"))
        .await
        .expect("a WebDriver session")
}

#[test]
fn the_studio_opens_checks_edits_and_saves_a_mission_in_headless_chromium() {
    let dir = tempdir("studio");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    let original =
        std::fs::read_to_string(repo().join("deploy/missions/europa-bsm1.bpmn")).expect("europa");
    std::fs::write(missions.join("europa-bsm1.bpmn"), &original).expect("copy");
    // A copy with a seeded flaw: the merge before Communicate Until Death made a parallel
    // join, which waits for all three of its incoming paths where only one ever comes.
    let flawed = original
        .replace(
            r#"<bpmn:exclusiveGateway id="ToCommunicate""#,
            r#"<bpmn:parallelGateway id="ToCommunicate""#,
        )
        .replacen(
            "</bpmn:exclusiveGateway>\n  <bpmn:subProcess id=\"CommunicateUntilDeath\"",
            "</bpmn:parallelGateway>\n  <bpmn:subProcess id=\"CommunicateUntilDeath\"",
            1,
        );
    assert_ne!(flawed, original);
    std::fs::write(missions.join("europa-flawed.bpmn"), &flawed).expect("flawed copy");
    std::fs::copy(
        repo().join("deploy/missions/europa-bsm1.req.toml"),
        missions.join("europa-flawed.req.toml"),
    )
    .expect("requirements");
    // The scratch directory stays with the test (it is removed when dropped): the scenario
    // gets its path.
    let path = dir.to_path_buf();
    Page::start(europa_studio(&missions)).play(|c, url| scenario(c, url, path));
    let saved = std::fs::read_to_string(missions.join("europa-bsm1.bpmn")).expect("saved");
    assert!(
        saved.contains(r#"target="exposure_ms" source="80""#),
        "the edit is not in the saved file"
    );
    let out = Command::new(bin("trace"))
        .arg("validate")
        .arg(missions.join("europa-bsm1.bpmn"))
        .output()
        .expect("trace validate");
    assert!(
        out.status.success(),
        "the saved file does not validate:\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// `trace studio` on `missions` with Europa's catalogues, ground forms and connectors, offline
/// (the files only: another test's systems on this host stay out of it).
pub(crate) fn europa_studio(missions: &std::path::Path) -> Command {
    let mut studio = Command::new(bin("trace"));
    studio
        .arg("studio")
        .arg(missions)
        .args(["--port", "0", "--catalogue"])
        .arg(repo().join("deploy/catalogues"))
        .arg("--catalogue")
        .arg(repo().join("deploy/ground/forms.json"))
        .arg("--connectors")
        .arg(repo().join("deploy/connectors.toml"))
        .arg("--offline");
    studio
}

/// Runs `script` in the page (its `arguments` are `args`) and returns its value.
pub(crate) async fn js(c: &Client, script: &str, args: Vec<Value>) -> Value {
    c.execute(script, args)
        .await
        .unwrap_or_else(|e| panic!("script failed: {e}\n{script}"))
}

/// Waits until `script` returns a truthy value; fails naming `what`.
pub(crate) async fn until(c: &Client, what: &str, script: &str) -> Value {
    until_within(c, what, script, WAIT).await
}

/// [`until`], failing only after `within`.
pub(crate) async fn until_within(c: &Client, what: &str, script: &str, within: Duration) -> Value {
    let start = std::time::Instant::now();
    loop {
        let v = js(c, script, vec![]).await;
        if !(v.is_null() || v == json!(false) || v == json!("") || v == json!(0)) {
            return v;
        }
        if start.elapsed() > within {
            let errors = js(c, "return studio.errors", vec![]).await;
            let problems = js(
                c,
                "return [...document.querySelectorAll('#problems li')].map(l => l.textContent)",
                vec![],
            )
            .await;
            // What the page had come to: its data attributes, which its views keep up to date.
            let shown = js(c, "return Object.assign({}, document.body.dataset)", vec![]).await;
            panic!(
                "the page never showed {what}; its errors: {errors}; its problems: {problems}; its state: {shown}"
            );
        }
        // What is waited for is the page's state; this pause only spares the CPU.
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

pub(crate) async fn click(c: &Client, css: &str) {
    c.wait()
        .at_most(WAIT)
        .for_element(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("{css}: {e}"))
        .click()
        .await
        .unwrap_or_else(|e| panic!("click {css}: {e}"));
}

/// Chooses `value` in the page's select `id`, as a browser does: the value set, then its
/// change event.
pub(crate) async fn choose(c: &Client, id: &str, value: &str) {
    js(
        c,
        &format!(
            "const s = document.getElementById('{id}'); s.value = '{value}';
             s.dispatchEvent(new Event('change', {{ bubbles: true }}));"
        ),
        vec![],
    )
    .await;
}

/// Saves the open file as a planner does, with Ctrl+S, and waits until `file` is saved.
pub(crate) async fn save_keys(c: &Client, file: &str) {
    js(
        c,
        "document.body.dataset.saved = ''; window.dispatchEvent(new KeyboardEvent('keydown', { key: 's', ctrlKey: true }))",
        vec![],
    )
    .await;
    until(
        c,
        &format!("{file} saved"),
        &format!("return document.body.dataset.saved === '{file}'"),
    )
    .await;
}

/// Opens panel group `id` unless it is open (the panel keeps a group open across elements).
pub(crate) async fn open_group(c: &Client, id: &str) {
    let open = js(
        c,
        &format!(r#"return !!document.querySelector('[data-group-id="group-{id}"] .bio-properties-panel-group-entries.open')"#),
        vec![],
    )
    .await;
    if open != json!(true) {
        click(
            c,
            &format!(r#"[data-group-id="group-{id}"] .bio-properties-panel-group-header"#),
        )
        .await;
    }
}

/// Replaces the text of input `css` with `text`.
pub(crate) async fn type_into(c: &Client, css: &str, text: &str) {
    let field = c
        .wait()
        .at_most(WAIT)
        .for_element(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("{css}: {e}"));
    // Ctrl+A, release, then the text: one keystroke sequence (clearing first re-renders the
    // field, and the element found would be stale).
    field
        .send_keys(&format!("\u{E009}a\u{E000}{text}"))
        .await
        .expect("type");
}

async fn scenario(c: Client, url: String, dir: std::path::PathBuf) {
    c.goto(&url).await.expect("the studio's page");
    until(
        &c,
        "the mission loaded",
        "return document.body.dataset.ready === 'true' && document.body.dataset.checks",
    )
    .await;
    // The model as the modeler writes it before any edit: the saved file must differ from it
    // only where edited.
    js(
        &c,
        "studio.modeler.saveXML({ format: true }).then(r => { window.baseline = r.xml; })",
        vec![],
    )
    .await;
    let baseline = until(&c, "the baseline export", "return window.baseline").await;
    let verdict = js(&c, "return document.body.dataset.verdict", vec![]).await;
    assert_eq!(verdict, "valid", "Europa as the studio checks it");
    let systems = js(&c, "return document.body.dataset.systems", vec![]).await;
    assert_eq!(
        systems,
        "lander_sim (file) · scout_sim (file) · ground (file)"
    );
    let shapes = js(
        &c,
        "return studio.modeler.get('elementRegistry').getAll().length",
        vec![],
    )
    .await;
    assert!(
        shapes.as_u64().is_some_and(|n| n > 100),
        "{shapes} elements drawn"
    );

    // The panel shows the task's action and its goal inputs, from the catalogue.
    click(&c, r#"g.djs-element[data-element-id="CapturePanorama"]"#).await;
    open_group(&c, "trace-task").await;
    let action = c
        .find(Locator::Css("#bio-properties-panel-trace-resource"))
        .await
        .expect("the action field")
        .prop("value")
        .await
        .expect("its value");
    assert_eq!(action.as_deref(), Some("camera.take_panorama"));
    open_group(&c, "trace-inputs").await;
    let row = "CapturePanorama-trace-inputs-1";
    click(
        &c,
        &format!(r#"[data-entry-id="{row}"] .bio-properties-panel-collapsible-entry-header"#),
    )
    .await;
    // A path that is not a goal field is refused under the field, and not written.
    type_into(&c, &format!("#bio-properties-panel-{row}-path"), "exposure").await;
    let error = until(
        &c,
        "the path refused",
        &format!(r#"const e = document.querySelector('[data-entry-id="{row}-path"] .bio-properties-panel-error'); return e && e.textContent"#),
    )
    .await;
    assert!(
        error
            .as_str()
            .is_some_and(|e| e.contains("not a goal field of camera.take_panorama")),
        "{error}"
    );
    type_into(
        &c,
        &format!("#bio-properties-panel-{row}-path"),
        "exposure_ms",
    )
    .await;
    type_into(&c, &format!("#bio-properties-panel-{row}-expr"), "80").await;
    let model = r#"const t = studio.modeler.get('elementRegistry').get('CapturePanorama').businessObject
        .extensionElements.values.find(v => v.$type === 'trace:Task');
        const i = t.inputs.find(i => i.target === 'exposure_ms'); return i && i.source"#;
    until(
        &c,
        "the new exposure in the model",
        &format!("{model} === '80'"),
    )
    .await;
    // A wrongly typed input: the marker of `trace run`'s check on the task, until it is set
    // back.
    let set_type = |t: &str| {
        format!(
            "const s = document.querySelector('#bio-properties-panel-{row}-type');
             s.value = '{t}';
             for (const e of ['input', 'change']) s.dispatchEvent(new Event(e, {{ bubbles: true }}));"
        )
    };
    js(&c, &set_type("string"), vec![]).await;
    let mismatch = until(
        &c,
        "the wrong type marked",
        r#"const li = document.querySelector('#problems li[data-code="catalogue-mismatch"][data-element="CapturePanorama"]');
           return li && document.querySelector('g.djs-element[data-element-id="CapturePanorama"]').classList.contains('trace-error') && li.textContent"#,
    )
    .await;
    assert!(
        mismatch.as_str().is_some_and(
            |m| m.contains("`exposure_ms` is declared string") && m.contains("expects int")
        ),
        "{mismatch}"
    );
    js(&c, &set_type("int"), vec![]).await;
    until(
        &c,
        "the type right again",
        r#"return document.body.dataset.mismatches === '0' && !document.querySelector('#problems li[data-element="CapturePanorama"]')"#,
    )
    .await;

    // A new service task: the executive's diagnostics land on it; its action and a typed input
    // come from the panel.
    js(
        &c,
        "const m = studio.modeler; const root = m.get('canvas').getRootElement();
         const bo = m.get('bpmnFactory').create('bpmn:ServiceTask', { id: 'Seismic', name: 'Record Seismic' });
         m.get('modeling').createShape({ type: 'bpmn:ServiceTask', businessObject: bo }, { x: 400, y: 620 }, root);
         m.get('selection').select(m.get('elementRegistry').get('Seismic'));",
        vec![],
    )
    .await;
    until(
        &c,
        "a problem on the new task",
        r#"return document.querySelector('#problems li[data-element="Seismic"]')
            && document.querySelector('g.djs-element[data-element-id="Seismic"]').classList.contains('trace-error')"#,
    )
    .await;
    open_group(&c, "trace-task").await;
    c.wait()
        .at_most(WAIT)
        .for_element(Locator::Css("#bio-properties-panel-trace-resource"))
        .await
        .expect("the action field");
    // Picked as a browser does: the option chosen, then its input and change events.
    js(
        &c,
        "const s = document.querySelector('#bio-properties-panel-trace-resource');
         s.value = 'camera.take_panorama';
         for (const e of ['input', 'change']) s.dispatchEvent(new Event(e, { bubbles: true }));",
        vec![],
    )
    .await;
    until(
        &c,
        "the action picked",
        "const t = studio.modeler.get('elementRegistry').get('Seismic').businessObject.extensionElements;
         return t && t.values.some(v => v.resource === 'camera.take_panorama')",
    )
    .await;
    click(&c, r#"[data-group-id="group-trace-inputs"] .bio-properties-panel-group-header .bio-properties-panel-add-entry"#).await;
    let binding = until(
        &c,
        "the new task's binding",
        r#"const t = studio.modeler.get('elementRegistry').get('Seismic').businessObject.extensionElements;
           const b = t && t.values.find(v => v.$type === 'trace:Task');
           return b && b.inputs.length === 1 && { resource: b.resource, target: b.inputs[0].target, type: b.inputs[0].type }"#,
    )
    .await;
    assert_eq!(
        binding,
        json!({ "resource": "camera.take_panorama", "target": "camera", "type": "string" })
    );
    // Clicking a problem selects its element.
    js(&c, "studio.modeler.get('selection').select(null)", vec![]).await;
    click(&c, r#"#problems li[data-element="Seismic"]"#).await;
    let selected = js(
        &c,
        "return studio.modeler.get('selection').get().map(e => e.id)",
        vec![],
    )
    .await;
    assert_eq!(selected, json!(["Seismic"]));
    // The problems as the binding now stands (checked again after the edit), then the picture.
    until(
        &c,
        "the problem list checked again",
        r#"return document.querySelector('#problems li[data-element="Seismic"]')
            && !document.querySelector('#problems li[data-code="missing-resource"]')"#,
    )
    .await;
    let shot = c.screenshot().await.expect("screenshot");
    std::fs::write(dir.join("studio.png"), shot).expect("screenshot file");
    // Removed again, the model is valid; saved, it is on disk.
    js(
        &c,
        "const m = studio.modeler; m.get('modeling').removeElements([m.get('elementRegistry').get('Seismic')]);",
        vec![],
    )
    .await;
    until(&c, "the model valid again", "return document.body.dataset.verdict === 'valid' && !document.querySelector('#problems li.error')").await;
    // A binding as another tool might write it, naming an action no system serves: valid BPMN,
    // but `trace run` would refuse it, and the studio says so on the task.
    js(
        &c,
        "const m = studio.modeler; const el = m.get('elementRegistry').get('CapturePanorama');
         const t = el.businessObject.extensionElements.values.find(v => v.$type === 'trace:Task');
         m.get('modeling').updateModdleProperties(el, t, { resource: 'camera.take_pano' });",
        vec![],
    )
    .await;
    let line = until(
        &c,
        "the catalogue mismatch on the task",
        r#"const li = document.querySelector('#problems li[data-code="catalogue-mismatch"][data-element="CapturePanorama"]');
           return li && document.querySelector('g.djs-element[data-element-id="CapturePanorama"]').classList.contains('trace-error')
             && document.body.dataset.mismatches === '1' && li.textContent"#,
    )
    .await;
    assert!(
        line.as_str()
            .is_some_and(|l| l.contains("`camera.take_pano`") && l.contains("lander_sim")),
        "{line}"
    );
    js(&c, "studio.modeler.get('commandStack').undo()", vec![]).await;
    // An error boundary offers the codes the task's action declares, then the protocol's.
    click(&c, r#"g.djs-element[data-element-id="CollectFailed"]"#).await;
    open_group(&c, "trace-error").await;
    let options = until(
        &c,
        "the error codes offered",
        "const s = document.querySelector('#bio-properties-panel-trace-error-code');
         return s && [...s.options].map(o => o.value)",
    )
    .await;
    assert_eq!(
        options,
        json!([
            "",
            "INSUFFICIENT_VOLUME",
            "SAMPLE_CONTAMINATED",
            "CONNECTOR_LOST",
            "REJECTED",
            "TYPE_MISMATCH",
            "NO_CONNECTOR",
            "NOT_ACCEPTED",
            "PROTOCOL_ERROR",
            "ABORTED"
        ])
    );
    js(
        &c,
        "const s = document.querySelector('#bio-properties-panel-trace-error-code');
         s.value = 'SAMPLE_CONTAMINATED';
         for (const e of ['input', 'change']) s.dispatchEvent(new Event(e, { bubbles: true }));",
        vec![],
    )
    .await;
    until(
        &c,
        "the boundary catching the chosen code",
        "const d = studio.modeler.get('elementRegistry').get('CollectFailed').businessObject.eventDefinitions[0];
         return d.errorRef && d.errorRef.errorCode === 'SAMPLE_CONTAMINATED' && d.errorRef.$parent.rootElements.includes(d.errorRef)",
    )
    .await;
    js(&c, "studio.modeler.get('commandStack').undo()", vec![]).await;
    until(
        &c,
        "the catch-all again",
        "return !studio.modeler.get('elementRegistry').get('CollectFailed').businessObject.eventDefinitions[0].errorRef",
    )
    .await;
    until(&c, "the mismatch gone with the undo", "return document.body.dataset.verdict === 'valid' && document.body.dataset.mismatches === '0' && !document.querySelector('#problems li.error')").await;
    click(&c, "#save").await;
    until(&c, "the file saved", "return document.body.dataset.saved").await;
    let saved = std::fs::read_to_string(dir.join("missions/europa-bsm1.bpmn")).expect("saved");
    let baseline = baseline.as_str().expect("the baseline");
    let changed: Vec<(&str, &str)> = baseline
        .lines()
        .zip(saved.lines())
        .filter(|(a, b)| a != b)
        .collect();
    assert_eq!(baseline.lines().count(), saved.lines().count());
    assert_eq!(changed.len(), 1, "{changed:#?}");
    assert!(
        changed[0].0.contains(r#"target="exposure_ms" source="40""#)
            && changed[0].1.contains(r#"target="exposure_ms" source="80""#),
        "{changed:#?}"
    );

    // Verification on the diagram: the flawed copy, its requirements beside it.
    choose(&c, "missions", "europa-flawed.bpmn").await;
    until(
        &c,
        "the flawed copy and its requirements",
        "return document.getElementById('requirements').value.includes('ends_through_communication')
           && studio.modeler.get('elementRegistry').get('ToCommunicate').type === 'bpmn:ParallelGateway'",
    )
    .await;
    click(&c, "#verify").await;
    until(&c, "the verdicts", "return document.body.dataset.verified").await;
    let verified = js(&c, "return document.body.dataset.verified", vec![]).await;
    assert_eq!(verified, "violated");
    let deadlock = js(
        &c,
        r#"const li = document.querySelector('#properties li[data-name="no_deadlock"]'); return li && li.className"#,
        vec![],
    )
    .await;
    assert_eq!(deadlock, "property violated");
    // The engine's own exploration agrees: a run gets stuck.
    let native = js(
        &c,
        "const li = document.querySelector('#properties li.native'); return li && li.textContent",
        vec![],
    )
    .await;
    assert!(
        native.as_str().is_some_and(
            |n| n.starts_with("engine exploration: ") && n.contains("a run that gets stuck")
        ),
        "{native}"
    );
    // The counterexample, stepped forward: each step's element is the current one, every
    // earlier one stays marked as visited, in the counterexample's order.
    let steps = js(&c, "return studio.verification.replay().steps", vec![]).await;
    let steps = steps.as_array().expect("steps").clone();
    assert!(steps.len() > 5, "{steps:?}");
    let shown: Vec<String> = steps
        .iter()
        .map(|s| {
            let step = &s["step"];
            let path = step["path"].as_str().unwrap_or("");
            match path.split('/').next().filter(|p| !p.is_empty()) {
                Some(call) => call.to_owned(),
                None => step["element"].as_str().unwrap_or("").to_owned(),
            }
        })
        .collect();
    for (i, id) in shown.iter().enumerate() {
        let now = js(&c, "return document.body.dataset.replay", vec![]).await;
        assert_eq!(now, format!("{}/{}:{id}", i + 1, steps.len()), "step {i}");
        if !id.is_empty() {
            let marked = js(
                &c,
                "const m = studio.modeler.get('canvas'); return arguments[0].filter(Boolean).map(id => [id, m.hasMarker(id, 'trace-current'), m.hasMarker(id, 'trace-visited')])",
                vec![json!(shown[..=i])],
            )
            .await;
            for m in marked.as_array().expect("markers") {
                let (el, current) = (m[0].as_str().unwrap(), m[1] == json!(true));
                assert!(
                    current == (el == id) && (current || m[2] == json!(true)),
                    "step {i}: {el} marked {m}"
                );
            }
        }
        click(&c, "#replay-forward").await;
    }
    let shot = c.screenshot().await.expect("screenshot");
    std::fs::write(dir.join("studio-verify.png"), shot).expect("screenshot file");

    // The token game: Europa played on the engine from the page's buttons — the planner's
    // choice at each decision, otherwise the first waiting task completed, else the first
    // wait fired — to its terminate end.
    choose(&c, "missions", "europa-bsm1.bpmn").await;
    until(
        &c,
        "Europa open again",
        "return studio.modeler.get('elementRegistry').get('ToCommunicate').type === 'bpmn:ExclusiveGateway'",
    )
    .await;
    click(&c, "#simulate").await;
    until(
        &c,
        "the game started",
        "return document.body.dataset.simulation === 'playing'",
    )
    .await;
    let plan = json!({ "SiteApproved": "f_s5", "Slumped": "e12", "EnoughSamples": "f_s13",
        "BatteryLow": "f_b6", "EnergyLeft": "f_d7" });
    let mut acts = 0;
    loop {
        let state = js(&c, "return document.body.dataset.simulation", vec![]).await;
        if state.as_str().is_some_and(|s| s.starts_with("ended:")) {
            assert_eq!(state, "ended:terminated");
            break;
        }
        assert!(acts < 300, "the game did not end within 300 acts: {state}");
        // What is offered now, as the page shows it.
        let next = js(
            &c,
            "const plan = arguments[0];
             const all = [...document.querySelectorAll('#simulate-acts button')];
             const choose = all.filter(b => b.dataset.act === 'choose');
             const planned = choose.find(b => plan[b.dataset.element] === b.dataset.flow);
             const b = planned || (!choose.length && (all.find(b => b.dataset.act === 'complete')
               || all.find(b => b.dataset.act === 'fire')));
             if (!b) return { stuck: all.map(b => b.textContent) };
             const before = Number(document.body.dataset.simulationViews);
             b.click();
             return { clicked: b.textContent, before };",
            vec![plan.clone()],
        )
        .await;
        assert!(next.get("stuck").is_none(), "nothing planned to do: {next}");
        acts += 1;
        until(
            &c,
            "the view after the act",
            &format!(
                "return Number(document.body.dataset.simulationViews) > {}",
                next["before"]
            ),
        )
        .await;
        if acts == 12 {
            let shot = c.screenshot().await.expect("screenshot");
            std::fs::write(dir.join("studio-simulate.png"), shot).expect("screenshot file");
        }
    }
    let last = js(
        &c,
        "const t = studio.simulation.view().trace; return t[t.length - 1]",
        vec![],
    )
    .await;
    assert_eq!(last, "enter:MissionEnd");
    let errors = js(&c, "return studio.errors", vec![]).await;
    assert_eq!(errors, json!([]), "errors in the page");
}

/// One HTTP/1.1 request to the studio; the status and the body.
fn http(addr: &str, method: &str, path: &str, body: &[u8]) -> (u16, String) {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("the studio accepts");
    s.set_read_timeout(Some(WAIT)).expect("timeout");
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: studio\r\nConnection: close\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .expect("request");
    s.write_all(body).expect("body");
    let mut out = String::new();
    s.read_to_string(&mut out).expect("response");
    let status = out[9..12].parse().expect("a status");
    let body = out.split_once("\r\n\r\n").map_or("", |(_, b)| b).to_owned();
    (status, body)
}

/// The servers `GET /api/catalogues` offers, with their source.
fn offered(addr: &str) -> Vec<(String, String)> {
    let (status, body) = http(addr, "GET", "/api/catalogues", b"");
    assert_eq!(status, 200, "{body}");
    let list: Vec<Value> = serde_json::from_str(&body).expect("JSON");
    list.iter()
        .map(|c| {
            (
                c["server"].as_str().unwrap_or("?").to_owned(),
                c["source"].as_str().unwrap_or("?").to_owned(),
            )
        })
        .collect()
}

/// Asks until `done` holds for what is offered (each ask is a round of Zenoh queries).
fn until_offered(addr: &str, what: &str, done: impl Fn(&[(String, String)]) -> bool) {
    let start = std::time::Instant::now();
    loop {
        let now = offered(addr);
        if done(&now) {
            return;
        }
        assert!(start.elapsed() < WAIT, "{what}: still offered {now:?}");
    }
}

#[test]
fn the_studio_offers_what_the_running_systems_serve() {
    let dir = tempdir("studio-live");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    let hub = format!("tcp/127.0.0.1:{}", free_port());
    let mut router = Command::new(bin("trace"));
    router.args(["router", "--no-multicast-scouting", "-l", &hub]);
    let (_router, _) = start(router, "ready router");
    let client = ["--mode", "client", "--no-multicast-scouting", "-e", &hub];
    // No catalogue file: whatever the studio offers comes from the network.
    let mut studio = Command::new(bin("trace"));
    studio
        .arg("studio")
        .arg(&missions)
        .args(["--port", "0", "--connectors"])
        .arg(repo().join("deploy/connectors.toml"))
        .args(client);
    let (_studio, ready) = start(studio, "ready http://");
    assert!(ready.contains("0 system(s) serving now"), "{ready}");
    let addr = ready
        .split_whitespace()
        .nth(1)
        .and_then(|u| u.strip_prefix("http://"))
        .map(|u| u.trim_end_matches('/').to_owned())
        .expect("the studio's address");
    assert_eq!(offered(&addr), []);

    let mut sim = Command::new(bin("elap-sim"));
    sim.args(["--speed", "1000", "--profile", "quiet", "--seed", "1"])
        .args(client);
    let (sim, _) = start(sim, "ready");
    until_offered(&addr, "the simulator's catalogue, live", |o| {
        o == [("lander_sim".to_owned(), "live".to_owned())]
    });
    // The check uses it as `trace run` would: the lander's tasks are checked, the ground's
    // forms are not known here.
    let europa = std::fs::read(repo().join("deploy/missions/europa-bsm1.bpmn")).expect("europa");
    let (_, report) = http(&addr, "POST", "/api/validate", &europa);
    let report: Value = serde_json::from_str(&report).expect("JSON");
    assert_eq!(
        report["catalogue"],
        json!({ "checked": true, "servers": ["lander_sim"], "missing": ["ground"], "mismatches": 0 }),
        "{report}"
    );
    drop(sim);
    until_offered(&addr, "the simulator gone", |o| o.is_empty());
}
