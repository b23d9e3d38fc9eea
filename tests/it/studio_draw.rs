//! TRACE Studio draws every part of a mission in headless Chromium: the second process of
//! Europa's file (Excavate) opens from the diagram list and by double-clicking the activity that
//! calls it; a flow's condition is edited in the panel and a misspelt variable in it is marked
//! at once with a "did you mean"; a call activity's called process is chosen from the file's
//! processes and those of the files it imports; the token game, played from the mission's
//! diagram, runs Excavate and is shown and played on Excavate's own diagram; a multi-instance
//! activity's items are set in the panel; each problem is named by the element's name at its
//! line of the saved file; New asks for a file name; the saved file validates.

use std::process::Command;

use fantoccini::{Client, Locator};
use mission_tests::{bin, repo};
use serde_json::json;

use crate::protocol::tempdir;
use crate::studio::{
    Page, choose, click, europa_studio, js, open_group, save_keys, type_into, until,
};

#[test]
fn the_studio_opens_every_process_and_edits_conditions_and_calls_without_xml() {
    let dir = tempdir("studio-draw");
    let missions = dir.join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    std::fs::copy(
        repo().join("deploy/missions/europa-bsm1.bpmn"),
        missions.join("europa-bsm1.bpmn"),
    )
    .expect("copy");
    std::fs::write(missions.join("with-import.bpmn"), CALLER).expect("caller");
    std::fs::write(missions.join("lib.bpmn"), LIB).expect("lib");
    Page::start(europa_studio(&missions)).play(scenario);
    let saved = std::fs::read_to_string(missions.join("europa-bsm1.bpmn")).expect("saved");
    assert!(
        saved.contains("fault_code == \"TOOL_STUCK\" &amp;&amp; attempts &lt; 5"),
        "the edited condition is not in the saved file"
    );
    assert!(
        saved.contains(
            r#"<zeebe:loopCharacteristics inputCollection="= tried_sites" inputElement="site" />"#
        ),
        "the multi-instance items are not in the saved file"
    );
    let out = Command::new(bin("trace"))
        .arg("validate")
        .arg(missions.join("europa-bsm1.bpmn"))
        .arg("--connectors")
        .arg(repo().join("deploy/connectors.toml"))
        .output()
        .expect("trace validate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// A mission whose call activity calls a process of the file it imports.
const CALLER: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:bpmndi="http://www.omg.org/spec/BPMN/20100524/DI" xmlns:dc="http://www.omg.org/spec/DD/20100524/DC" xmlns:di="http://www.omg.org/spec/DD/20100524/DI" id="caller" targetNamespace="urn:caller">
  <bpmn:import importType="http://www.omg.org/spec/BPMN/20100524/MODEL" location="lib.bpmn" namespace="urn:lib"/>
  <bpmn:process id="Main" isExecutable="true">
    <bpmn:startEvent id="S"/>
    <bpmn:callActivity id="CallLib" name="Calibrate" calledElement="Calibrate"/>
    <bpmn:endEvent id="E"/>
    <bpmn:sequenceFlow id="f1" sourceRef="S" targetRef="CallLib"/>
    <bpmn:sequenceFlow id="f2" sourceRef="CallLib" targetRef="E"/>
  </bpmn:process>
  <bpmndi:BPMNDiagram id="D"><bpmndi:BPMNPlane id="P" bpmnElement="Main">
    <bpmndi:BPMNShape id="S_di" bpmnElement="S"><dc:Bounds x="100" y="100" width="36" height="36"/></bpmndi:BPMNShape>
    <bpmndi:BPMNShape id="CallLib_di" bpmnElement="CallLib"><dc:Bounds x="200" y="78" width="100" height="80"/></bpmndi:BPMNShape>
    <bpmndi:BPMNShape id="E_di" bpmnElement="E"><dc:Bounds x="360" y="100" width="36" height="36"/></bpmndi:BPMNShape>
    <bpmndi:BPMNEdge id="f1_di" bpmnElement="f1"><di:waypoint x="136" y="118"/><di:waypoint x="200" y="118"/></bpmndi:BPMNEdge>
    <bpmndi:BPMNEdge id="f2_di" bpmnElement="f2"><di:waypoint x="300" y="118"/><di:waypoint x="360" y="118"/></bpmndi:BPMNEdge>
  </bpmndi:BPMNPlane></bpmndi:BPMNDiagram>
</bpmn:definitions>"#;

/// The file it imports: two processes.
const LIB: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" id="lib" targetNamespace="urn:lib">
  <bpmn:process id="Calibrate" name="Calibrate the arm" isExecutable="true">
    <bpmn:startEvent id="cs"/><bpmn:endEvent id="ce"/><bpmn:sequenceFlow id="c1" sourceRef="cs" targetRef="ce"/>
  </bpmn:process>
  <bpmn:process id="Park" name="Park the arm" isExecutable="true">
    <bpmn:startEvent id="ps"/><bpmn:endEvent id="pe"/><bpmn:sequenceFlow id="p1" sourceRef="ps" targetRef="pe"/>
  </bpmn:process>
</bpmn:definitions>"#;

/// Selects diagram `id` from the page's list, as a planner picks it.
async fn pick_diagram(c: &Client, id: &str) {
    choose(c, "diagrams", id).await;
    until(
        c,
        &format!("diagram {id}"),
        &format!("return document.body.dataset.diagram === '{id}'"),
    )
    .await;
}

async fn scenario(c: Client, url: String) {
    c.goto(&url).await.expect("the studio's page");
    until(
        &c,
        "the mission loaded",
        "return document.body.dataset.ready === 'true' && document.body.dataset.checks",
    )
    .await;
    // Both processes of the file are offered.
    let offered = js(
        &c,
        "return [...document.getElementById('diagrams').options].map(o => o.textContent)",
        vec![],
    )
    .await;
    assert_eq!(
        offered,
        json!(["Europa Lander Basic Surface Mission 1", "Excavate"])
    );
    // Double-clicking the call activity opens the process it calls.
    let dblclick = "const r = studio.modeler.get('elementRegistry').get('ExcavateCall');
        studio.modeler.get('eventBus').fire('element.dblclick', { element: r, originalEvent: new MouseEvent('dblclick') });";
    js(&c, dblclick, vec![]).await;
    until(
        &c,
        "the Excavate process",
        "return document.body.dataset.diagram === 'Diagram_Excavate' && !!studio.modeler.get('elementRegistry').get('RemoveMaterial')",
    )
    .await;
    // The condition of `tool stuck`, in the panel; a misspelt name is marked at once.
    // A flow's drawn path has no box to click: selected as the canvas selects it.
    js(
        &c,
        "const r = studio.modeler.get('elementRegistry'); studio.modeler.get('selection').select(r.get('e15'));",
        vec![],
    )
    .await;
    open_group(&c, "trace-condition").await;
    let field = "#bio-properties-panel-trace-condition-expr";
    let value = c
        .find(Locator::Css(field))
        .await
        .expect("the condition field")
        .prop("value")
        .await
        .expect("its value");
    assert_eq!(
        value.as_deref(),
        Some("fault_code == \"TOOL_STUCK\" && attempts < 4")
    );
    type_into(&c, field, "fault_cod == \"TOOL_STUCK\" && attempts < 5").await;
    let problem = until(
        &c,
        "the misspelt name marked",
        r#"const p = [...document.querySelectorAll('#problems li')].find(l => l.dataset.code === 'unwritten-variable' && l.dataset.element === 'e15');
           return p && p.textContent"#,
    )
    .await;
    let problem = problem.as_str().unwrap_or_default().to_owned();
    assert!(problem.contains("did you mean `fault_code`?"), "{problem}");
    // Named as the planner named the flow, at its line in the file as it will be saved.
    assert!(problem.contains("at `tool stuck` (line "), "{problem}");
    let line: usize = problem
        .split("(line ")
        .nth(1)
        .and_then(|r| r.split(')').next())
        .and_then(|n| n.parse().ok())
        .expect("a line");
    let marked = js(
        &c,
        "return studio.modeler.get('canvas').hasMarker('e15', 'trace-error')",
        vec![],
    )
    .await;
    assert_eq!(marked, json!(true));
    type_into(&c, field, "fault_code == \"TOOL_STUCK\" && attempts < 5").await;
    until(
        &c,
        "the condition checked clean",
        "return document.body.dataset.verdict === 'valid' && !studio.modeler.get('canvas').hasMarker('e15', 'trace-error')",
    )
    .await;
    // Back to the mission: the call activity's called process, chosen from the file's.
    pick_diagram(&c, "Diagram_BSM1").await;
    click(&c, r#"g.djs-element[data-element-id="ExcavateCall"]"#).await;
    open_group(&c, "trace-called").await;
    let options = js(
        &c,
        "return [...document.querySelectorAll('#bio-properties-panel-trace-called-process option')].map(o => o.value)",
        vec![],
    )
    .await;
    assert_eq!(options, json!(["", "BSM1", "Excavate"]));
    let chosen = js(
        &c,
        "return document.querySelector('#bio-properties-panel-trace-called-process').value",
        vec![],
    )
    .await;
    assert_eq!(chosen, json!("Excavate"));
    // Saved as the planner saves: Ctrl+S.
    save_keys(&c, "europa-bsm1.bpmn").await;
    // The line the problem named is the flow's in the saved file.
    let saved: String = js(
        &c,
        "return fetch('/api/missions/europa-bsm1.bpmn').then(r => r.text())",
        vec![],
    )
    .await
    .as_str()
    .unwrap_or_default()
    .to_owned();
    let at = saved
        .lines()
        .position(|l| l.contains(r#"id="e15""#))
        .expect("the flow in the saved file")
        + 1;
    assert_eq!(line, at, "the problem's line");
    // The token game reaches Excavate: played from the mission's diagram (at each decision the
    // planned flow — the site approved, the battery fine —, otherwise the first waiting task
    // completed, else the first wait fired) until the call activity's process runs, then shown
    // and played on Excavate's own diagram.
    click(&c, "#simulate").await;
    until(
        &c,
        "the game started",
        "return document.body.dataset.simulation === 'playing'",
    )
    .await;
    let heat = r#"#simulate-acts button[data-act="complete"][data-element="HeatArm"]"#;
    let mut acts = 0;
    loop {
        let next = js(
            &c,
            &format!(
                "if (document.querySelector('{heat}')) return {{ there: true }};
                 const all = [...document.querySelectorAll('#simulate-acts button')];
                 const choose = all.filter(b => b.dataset.act === 'choose');
                 const plan = {{ SiteApproved: 'f_s5', Slumped: 'e12', EnoughSamples: 'f_s13', BatteryLow: 'f_b6', EnergyLeft: 'f_d7' }};
                 const b = choose.find(b => plan[b.dataset.element] === b.dataset.flow)
                   || (!choose.length && (all.find(b => b.dataset.act === 'complete') || all.find(b => b.dataset.act === 'fire')));
                 if (!b) return {{ stuck: all.map(b => b.textContent) }};
                 const before = Number(document.body.dataset.simulationViews);
                 b.click();
                 return {{ clicked: b.textContent, before }};"
            ),
            vec![],
        )
        .await;
        if next.get("there").is_some() {
            break;
        }
        assert!(next.get("stuck").is_none(), "nothing to do: {next}");
        acts += 1;
        assert!(acts < 60, "Excavate not reached in 60 acts: {next}");
        until(
            &c,
            "the view after the act",
            &format!(
                "return Number(document.body.dataset.simulationViews) > {}",
                next["before"]
            ),
        )
        .await;
    }
    pick_diagram(&c, "Diagram_Excavate").await;
    until(
        &c,
        "Excavate's waiting task marked on its own diagram",
        "return document.body.dataset.diagram === 'Diagram_Excavate'
           && studio.modeler.get('canvas').hasMarker('HeatArm', 'trace-live')
           && !!document.querySelector('.djs-overlay-trace-sim .trace-token')",
    )
    .await;
    click(&c, heat).await;
    until(
        &c,
        "the token moved on in Excavate",
        "const c = studio.modeler.get('canvas');
         return c.hasMarker('UnstowArm', 'trace-live') && !c.hasMarker('HeatArm', 'trace-live')",
    )
    .await;
    pick_diagram(&c, "Diagram_BSM1").await;
    // A task made multi-instance (as the wrench menu makes it) gets its items in the panel.
    js(
        &c,
        "const m = studio.modeler; const el = m.get('elementRegistry').get('SelectNextSite');
         m.get('modeling').updateProperties(el, { loopCharacteristics:
           m.get('bpmnFactory').create('bpmn:MultiInstanceLoopCharacteristics', { isSequential: true }) });",
        vec![],
    )
    .await;
    click(&c, r#"g.djs-element[data-element-id="SelectNextSite"]"#).await;
    open_group(&c, "trace-loop").await;
    type_into(
        &c,
        "#bio-properties-panel-trace-loop-collection",
        "tried_sites",
    )
    .await;
    type_into(&c, "#bio-properties-panel-trace-loop-element", "site").await;
    until(
        &c,
        "the items in the model",
        "const l = studio.modeler.get('elementRegistry').get('SelectNextSite').businessObject.loopCharacteristics;
         const z = l.extensionElements && l.extensionElements.values[0];
         return z && z.inputCollection === '= tried_sites' && z.inputElement === 'site'",
    )
    .await;
    save_keys(&c, "europa-bsm1.bpmn").await;
    // A call activity of a file that imports another is offered that file's processes too.
    choose(&c, "missions", "with-import.bpmn").await;
    until(
        &c,
        "the importing mission",
        "return !!studio.modeler.get('elementRegistry').get('CallLib') && document.body.dataset.verdict === 'valid'",
    )
    .await;
    click(&c, r#"g.djs-element[data-element-id="CallLib"]"#).await;
    open_group(&c, "trace-called").await;
    let options = js(
        &c,
        "return [...document.querySelectorAll('#bio-properties-panel-trace-called-process option')].map(o => o.textContent)",
        vec![],
    )
    .await;
    assert_eq!(
        options,
        json!([
            "(none)",
            "Main",
            "Calibrate the arm (Calibrate, from lib.bpmn)",
            "Park the arm (Park, from lib.bpmn)"
        ])
    );
    // New asks for the file's name and keeps nothing unsaved without asking.
    js(
        &c,
        "window.prompt = () => 'survey'; window.confirm = () => true; document.getElementById('new').click();",
        vec![],
    )
    .await;
    until(
        &c,
        "the new mission",
        "return document.getElementById('missions').value === 'survey.bpmn'",
    )
    .await;
    let errors = js(&c, "return studio.errors", vec![]).await;
    assert_eq!(errors, json!([]), "the page's errors");
}
