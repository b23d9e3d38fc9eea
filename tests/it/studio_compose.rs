//! A mission drawn in TRACE Studio from an empty page, in headless Chromium, with no XML: tasks
//! from the catalogues with their inputs and outputs set in the panel, a decision whose two
//! flows carry conditions, a second process made with "New process" and called by a call
//! activity chosen from the file's processes, and a multi-instance task over a list. Each data
//! mistake a planner makes (a name left unquoted, a text for an `int`, `maybe` for a `bool`, a
//! misspelt variable in a condition, a timer that is not ISO 8601) is marked on the field it is
//! in, and listed for the element; the token game runs the called process on its own diagram;
//! the saved file passes `trace validate` with the systems' catalogues, and `trace verify`
//! proves it.

use std::process::Command;

use fantoccini::Client;
use mission_tests::{bin, repo};
use serde_json::json;

use crate::protocol::tempdir;
use crate::studio::{
    Page, choose, click, europa_studio, js, open_group, save_keys, type_into, until,
};

#[test]
fn a_planner_draws_a_whole_mission_from_an_empty_page_and_it_verifies() {
    let dir = tempdir("studio-compose");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    Page::start(europa_studio(&missions)).play(scenario);
    let saved = missions.join("mission-1.bpmn");
    let validate = Command::new(bin("trace"))
        .arg("validate")
        .arg(&saved)
        .arg("--connectors")
        .arg(repo().join("deploy/connectors.toml"))
        .output()
        .expect("trace validate");
    assert!(
        validate.status.success(),
        "{}",
        String::from_utf8_lossy(&validate.stdout)
    );
    let verify = Command::new(bin("trace"))
        .arg("verify")
        .arg(&saved)
        .arg("--dir")
        .arg(dir.join("verify"))
        .output()
        .expect("trace verify");
    let report = String::from_utf8_lossy(&verify.stdout);
    assert!(verify.status.success(), "{report}");
    for holds in ["no_deadlock", "no_dead_activities"] {
        assert!(
            report
                .lines()
                .any(|l| l.contains(holds) && l.contains("holds")),
            "{holds} in:\n{report}"
        );
    }
}

/// Runs `script` with the modeler as `m`, its registry as `r`, modeling as `g`, the factory
/// as `f`, and returns its value.
async fn with_modeler(c: &Client, script: &str) -> serde_json::Value {
    js(
        c,
        &format!(
            "const m = studio.modeler; const r = m.get('elementRegistry'); const g = m.get('modeling');
             const f = m.get('bpmnFactory'); {script}"
        ),
        vec![],
    )
    .await
}

/// Appends a new `type` named `name` (id `id`) after element `after`, as the context pad does.
async fn append(c: &Client, after: &str, ty: &str, id: &str, name: &str, dx: i32, dy: i32) {
    with_modeler(
        c,
        &format!(
            "const from = r.get('{after}');
             const bo = f.create('{ty}', {{ id: '{id}', name: '{name}' }});
             g.appendShape(from, {{ type: '{ty}', businessObject: bo }},
               {{ x: from.x + from.width / 2 + {dx}, y: from.y + from.height / 2 + {dy} }});"
        ),
    )
    .await;
}

/// Selects element `id` as a click on the canvas does.
async fn select(c: &Client, id: &str) {
    with_modeler(c, &format!("m.get('selection').select(r.get('{id}'));")).await;
}

/// Picks `value` in select `css` as a browser does: the option chosen, then its events.
async fn pick(c: &Client, css: &str, value: &str) {
    js(
        c,
        &format!(
            "const s = document.querySelector('{css}'); s.value = '{value}';
             for (const e of ['input', 'change']) s.dispatchEvent(new Event(e, {{ bubbles: true }}));"
        ),
        vec![],
    )
    .await;
}

/// Gives task `id` action `action` in the panel.
async fn action(c: &Client, id: &str, action: &str) {
    select(c, id).await;
    open_group(c, "trace-task").await;
    click(c, "#bio-properties-panel-trace-resource").await;
    pick(c, "#bio-properties-panel-trace-resource", action).await;
    until(
        c,
        &format!("{id} bound to {action}"),
        &format!(
            "const t = studio.modeler.get('elementRegistry').get('{id}').businessObject.extensionElements;
             return t && t.values.some(v => v.resource === '{action}')"
        ),
    )
    .await;
}

/// Adds a row to the task's `which` list (`inputs`, `outputs`): the action's next field (the
/// list opens, and so does the new row).
async fn add_row(c: &Client, which: &str) {
    click(
        c,
        &format!(
            r#"[data-group-id="group-trace-{which}"] .bio-properties-panel-group-header .bio-properties-panel-add-entry"#
        ),
    )
    .await;
}

/// Opens the task's `which` list (`inputs`, `outputs`) unless it is open.
async fn open_list(c: &Client, which: &str) {
    let open = js(
        c,
        &format!(
            r#"return !!document.querySelector('[data-group-id="group-trace-{which}"] .bio-properties-panel-list.open')"#
        ),
        vec![],
    )
    .await;
    if open != json!(true) {
        click(
            c,
            &format!(r#"[data-group-id="group-trace-{which}"] .bio-properties-panel-group-header"#),
        )
        .await;
    }
}

/// Opens row `row` of a list group unless it is open (a new row opens by itself).
async fn open_row(c: &Client, row: &str) {
    let open = js(
        c,
        &format!(
            r#"return !!document.querySelector('[data-entry-id="{row}"] .bio-properties-panel-collapsible-entry-entries.open')"#
        ),
        vec![],
    )
    .await;
    if open != json!(true) {
        click(
            c,
            &format!(r#"[data-entry-id="{row}"] .bio-properties-panel-collapsible-entry-header"#),
        )
        .await;
    }
}

/// The error the panel shows on entry `entry`, once it shows one.
async fn field_error(c: &Client, what: &str, entry: &str) -> String {
    until(
        c,
        what,
        &format!(
            r#"const e = document.querySelector('[data-entry-id="{entry}"] .bio-properties-panel-error');
               return e && e.textContent"#
        ),
    )
    .await
    .as_str()
    .unwrap_or_default()
    .to_owned()
}

/// Waits until entry `entry` shows no error and the model checks valid.
async fn clean(c: &Client, what: &str, entry: &str) {
    until(
        c,
        what,
        &format!(
            r#"return !document.querySelector('[data-entry-id="{entry}"] .bio-properties-panel-error')
                 && document.body.dataset.verdict === 'valid' && !document.querySelector('#problems li.error')"#
        ),
    )
    .await;
}

async fn scenario(c: Client, url: String) {
    c.goto(&url).await.expect("the studio's page");
    // An empty directory opens on a new mission at once.
    until(
        &c,
        "a new mission",
        "return document.body.dataset.ready === 'true'
           && document.getElementById('missions').value === 'mission-1.bpmn' && document.body.dataset.checks",
    )
    .await;
    // Read the battery, then decide on its energy.
    append(
        &c,
        "Start",
        "bpmn:ServiceTask",
        "ReadBattery",
        "Read battery",
        150,
        0,
    )
    .await;
    action(&c, "ReadBattery", "power.read_battery").await;
    add_row(&c, "outputs").await;
    until(
        &c,
        "the battery's energy as a variable",
        "const t = studio.modeler.get('elementRegistry').get('ReadBattery').businessObject.extensionElements.values[0];
         return t.outputs.length === 1 && t.outputs[0].source === 'battery.energy_wh' && t.outputs[0].target === 'battery_energy_wh'",
    )
    .await;
    append(
        &c,
        "ReadBattery",
        "bpmn:ExclusiveGateway",
        "Enough",
        "Enough energy?",
        130,
        0,
    )
    .await;
    append(
        &c,
        "Enough",
        "bpmn:CallActivity",
        "DigCall",
        "Dig",
        130,
        -100,
    )
    .await;
    append(&c, "DigCall", "bpmn:EndEvent", "Dug", "Dug", 150, 0).await;
    append(
        &c,
        "Enough",
        "bpmn:ServiceTask",
        "Images",
        "Take images",
        130,
        100,
    )
    .await;
    append(&c, "Images", "bpmn:EndEvent", "Imaged", "Imaged", 150, 0).await;
    // Take images: one per camera, a multi-instance task over a list (made multi-instance as
    // the wrench menu makes it).
    with_modeler(
        &c,
        "g.updateProperties(r.get('Images'), { loopCharacteristics:
           f.create('bpmn:MultiInstanceLoopCharacteristics', { isSequential: true }) });",
    )
    .await;
    action(&c, "Images", "camera.take_panorama").await;
    open_group(&c, "trace-loop").await;
    type_into(
        &c,
        "#bio-properties-panel-trace-loop-collection",
        r#"["mast_left", "mast_right"]"#,
    )
    .await;
    type_into(&c, "#bio-properties-panel-trace-loop-element", "cam").await;
    for _ in 0..3 {
        add_row(&c, "inputs").await;
    }
    until(
        &c,
        "three goal inputs",
        "return studio.modeler.get('elementRegistry').get('Images').businessObject.extensionElements
           .values.find(v => v.$type === 'trace:Task').inputs.map(i => i.target).join() === 'camera,exposure_ms,use_led'",
    )
    .await;
    let row = |i: usize| format!("Images-trace-inputs-{i}");
    for (i, right) in [(0, "cam"), (1, "40"), (2, "false")] {
        open_row(&c, &row(i)).await;
        type_into(&c, &format!("#bio-properties-panel-{}-expr", row(i)), right).await;
    }
    // A second process, made in the page, with its own task: what the call activity calls.
    js(&c, "window.prompt = () => 'Dig site';", vec![]).await;
    click(&c, "#new-process").await;
    until(
        &c,
        "the new process open",
        "return document.body.dataset.diagram === 'Process_1_diagram' && !!studio.modeler.get('elementRegistry').get('Start_1')",
    )
    .await;
    append(
        &c,
        "Start_1",
        "bpmn:ServiceTask",
        "Unstow",
        "Unstow arm",
        150,
        0,
    )
    .await;
    action(&c, "Unstow", "arm.unstow").await;
    append(
        &c,
        "Unstow",
        "bpmn:EndEvent",
        "Unstowed",
        "Unstowed",
        150,
        0,
    )
    .await;
    let offered = js(
        &c,
        "return [...document.getElementById('diagrams').options].map(o => o.value)",
        vec![],
    )
    .await;
    assert_eq!(offered, json!(["Diagram", "Process_1_diagram"]));
    choose(&c, "diagrams", "Diagram").await;
    until(
        &c,
        "the mission's diagram again",
        "return document.body.dataset.diagram === 'Diagram' && !!studio.modeler.get('elementRegistry').get('DigCall')",
    )
    .await;
    select(&c, "DigCall").await;
    open_group(&c, "trace-called").await;
    pick(
        &c,
        "#bio-properties-panel-trace-called-process",
        "Process_1",
    )
    .await;
    until(
        &c,
        "the called process chosen",
        "return studio.modeler.get('elementRegistry').get('DigCall').businessObject.calledElement === 'Process_1'",
    )
    .await;
    // The two flows out of the decision, each with its condition; a misspelt name is marked
    // on the condition's field with a "did you mean".
    let flows = with_modeler(
        &c,
        "const out = r.get('Enough').outgoing;
         return [out.find(f => f.target.id === 'DigCall').id, out.find(f => f.target.id === 'Images').id];",
    )
    .await;
    let (to_dig, to_images) = (
        flows[0].as_str().expect("a flow").to_owned(),
        flows[1].as_str().expect("a flow").to_owned(),
    );
    let condition = "#bio-properties-panel-trace-condition-expr";
    select(&c, &to_dig).await;
    open_group(&c, "trace-condition").await;
    type_into(&c, condition, "battery_enrgy_wh > 50").await;
    let marked = field_error(
        &c,
        "the misspelt name on the condition",
        "trace-condition-expr",
    )
    .await;
    assert!(
        marked.contains("did you mean `battery_energy_wh`?"),
        "{marked}"
    );
    // The element's own list in the panel says the same as the problem list.
    open_group(&c, "trace-problems").await;
    let listed = until(
        &c,
        "the flow's problem in the panel",
        r#"const li = document.querySelector('.trace-element-problems li[data-code="unwritten-variable"]');
           return li && li.textContent"#,
    )
    .await;
    let in_list = js(
        &c,
        &format!(
            r#"const li = document.querySelector('#problems li[data-code="unwritten-variable"][data-element="{to_dig}"]');
               return li && li.textContent"#
        ),
        vec![],
    )
    .await;
    let message = listed
        .as_str()
        .and_then(|l| l.split_once(": "))
        .map(|(_, m)| m.to_owned())
        .expect("a message");
    assert!(
        in_list.as_str().is_some_and(|l| l.ends_with(&message)),
        "{listed} / {in_list}"
    );
    type_into(&c, condition, "battery_energy_wh > 50").await;
    select(&c, &to_images).await;
    type_into(&c, condition, "battery_energy_wh <= 50").await;
    clean(&c, "the conditions right", "trace-condition-expr").await;
    // Each row's value as a planner gets it wrong: each mistake marked on its own field, then
    // set right again.
    select(&c, "Images").await;
    open_list(&c, "inputs").await;
    for (i, wrong, says) in [
        (
            0,
            "mast_stereo",
            "if it is a text, quote it: `\"mast_stereo\"`",
        ),
        (1, "\"fast\"", "which is not of type int"),
        (2, "maybe", "reads `maybe`, which nothing writes before it"),
    ] {
        open_row(&c, &row(i)).await;
        type_into(&c, &format!("#bio-properties-panel-{}-expr", row(i)), wrong).await;
        let marked = field_error(
            &c,
            &format!("{wrong} marked on its field"),
            &format!("{}-expr", row(i)),
        )
        .await;
        assert!(marked.contains(says), "{wrong}: {marked}");
    }
    select(&c, "Images").await;
    open_list(&c, "inputs").await;
    for (i, right) in [(0, "cam"), (1, "40"), (2, "false")] {
        open_row(&c, &row(i)).await;
        type_into(&c, &format!("#bio-properties-panel-{}-expr", row(i)), right).await;
    }
    clean(&c, "the inputs right", &format!("{}-expr", row(2))).await;
    // A timer that is not ISO 8601 is refused under its field, with the executive's reason;
    // a right one says when it fires.
    with_modeler(
        &c,
        "const b = g.createShape({ type: 'bpmn:BoundaryEvent', businessObject: f.create('bpmn:BoundaryEvent', {
             id: 'TooLong', cancelActivity: true,
             eventDefinitions: [f.create('bpmn:TimerEventDefinition', {
               timeDuration: f.create('bpmn:FormalExpression', { body: 'PT20D' }) })] }) },
           { x: r.get('Images').x + 20, y: r.get('Images').y + r.get('Images').height }, r.get('Images'), { attach: true });
         g.appendShape(b, { type: 'bpmn:EndEvent', businessObject: f.create('bpmn:EndEvent', { id: 'GaveUp', name: 'Gave up' }) },
           { x: b.x + 120, y: b.y + 80 });",
    )
    .await;
    select(&c, "TooLong").await;
    open_group(&c, "timer").await;
    let refused = until(
        &c,
        "the timer refused",
        "const p = document.querySelector('.trace-timer-preview .bio-properties-panel-error'); return p && p.textContent",
    )
    .await;
    assert!(
        refused.as_str().is_some_and(|r| r.contains("ISO 8601")),
        "{refused}"
    );
    type_into(
        &c,
        "#bio-properties-panel-timerEventDefinitionValue",
        "PT2H",
    )
    .await;
    let preview = until(
        &c,
        "the timer previewed",
        "const p = document.querySelector('.trace-timer-preview p');
         return p && !p.classList.contains('bio-properties-panel-error') && p.textContent.startsWith('fires') && p.textContent",
    )
    .await;
    assert_eq!(
        preview,
        json!("fires 2 h after the timer starts; first: +2 h")
    );
    // The token game: the decision taken to the call, whose task waits in the called process,
    // shown on that process's own diagram and completed there.
    click(&c, "#simulate").await;
    until(
        &c,
        "the game started",
        "return document.body.dataset.simulation === 'playing'",
    )
    .await;
    let views = |n: &str| format!("return Number(document.body.dataset.simulationViews) > {n}");
    let now = js(&c, "return document.body.dataset.simulationViews", vec![]).await;
    click(
        &c,
        r#"#simulate-acts button[data-act="complete"][data-element="ReadBattery"]"#,
    )
    .await;
    until(&c, "the battery read", &views(now.as_str().unwrap_or("0"))).await;
    let now = js(&c, "return document.body.dataset.simulationViews", vec![]).await;
    click(
        &c,
        &format!(r#"#simulate-acts button[data-act="choose"][data-flow="{to_dig}"]"#),
    )
    .await;
    until(
        &c,
        "the decision taken",
        &views(now.as_str().unwrap_or("0")),
    )
    .await;
    choose(&c, "diagrams", "Process_1_diagram").await;
    until(
        &c,
        "the called task's token on its own diagram",
        "return document.body.dataset.diagram === 'Process_1_diagram'
           && studio.modeler.get('canvas').hasMarker('Unstow', 'trace-live')
           && document.querySelector('#simulate-acts button[data-act=\"complete\"][data-element=\"Unstow\"]')",
    )
    .await;
    click(
        &c,
        r#"#simulate-acts button[data-act="complete"][data-element="Unstow"]"#,
    )
    .await;
    let ended = until(
        &c,
        "the game's end",
        "const s = document.body.dataset.simulation; return s.startsWith('ended:') && s",
    )
    .await;
    assert_eq!(ended, "ended:completed");
    // Saved as the planner saves: Ctrl+S.
    save_keys(&c, "mission-1.bpmn").await;
    let errors = js(&c, "return studio.errors", vec![]).await;
    assert_eq!(errors, json!([]), "the page's errors");
}
