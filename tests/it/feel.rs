//! A Camunda 8 model as Camunda Modeler writes it — FEEL conditions, FEEL script tasks, FEEL io
//! mappings and a FEEL input collection — validates cleanly and runs with FEEL's semantics in
//! `trace run`; FEEL syntax errors are reported by `trace validate` with element and position.

use std::process::Command;

use mission_tests::{bin, records};

const CAMUNDA8: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" xmlns:zeebe="http://camunda.org/schema/zeebe/1.0" xmlns:modeler="http://camunda.org/schema/modeler/1.0" id="Definitions_1" targetNamespace="http://bpmn.io/schema/bpmn" exporter="Camunda Modeler" exporterVersion="5.30.0" modeler:executionPlatform="Camunda Cloud" modeler:executionPlatformVersion="8.6.0">
  <bpmn:process id="survey" name="Survey" isExecutable="true">
    <bpmn:startEvent id="start"><bpmn:outgoing>f1</bpmn:outgoing></bpmn:startEvent>
    <bpmn:scriptTask id="plan" name="Plan">
      <bpmn:extensionElements><zeebe:script expression="={sites: [{id: &#34;A&#34;, score: 0.9}, {id: &#34;B&#34;, score: 0.4}, {id: &#34;C&#34;, score: 0.85}], n: 3}" resultVariable="plan" /></bpmn:extensionElements>
      <bpmn:incoming>f1</bpmn:incoming><bpmn:outgoing>f2</bpmn:outgoing>
    </bpmn:scriptTask>
    <bpmn:scriptTask id="halve" name="Halve">
      <bpmn:extensionElements><zeebe:script expression="=plan.n / 2" resultVariable="half" /></bpmn:extensionElements>
      <bpmn:incoming>f2</bpmn:incoming><bpmn:outgoing>f3</bpmn:outgoing>
    </bpmn:scriptTask>
    <bpmn:exclusiveGateway id="worth" name="Worth it?" default="no"><bpmn:incoming>f3</bpmn:incoming><bpmn:outgoing>yes</bpmn:outgoing><bpmn:outgoing>no</bpmn:outgoing></bpmn:exclusiveGateway>
    <bpmn:sequenceFlow id="yes" sourceRef="worth" targetRef="survey_task"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">=half = 1.5 and some s in plan.sites satisfies s.score &gt; 0.8</bpmn:conditionExpression></bpmn:sequenceFlow>
    <bpmn:sequenceFlow id="no" sourceRef="worth" targetRef="wrong" />
    <bpmn:serviceTask id="survey_task" name="Survey">
      <bpmn:extensionElements>
        <zeebe:taskDefinition type="sys.survey" />
        <zeebe:ioMapping>
          <zeebe:input source="=string join(for s in plan.sites[score &gt; 0.8] return s.id, &#34;,&#34;)" target="site_ids" />
          <zeebe:input source="=count(plan.sites)" target="count" />
          <zeebe:output source="=depth * 2" target="depth2" />
        </zeebe:ioMapping>
      </bpmn:extensionElements>
      <bpmn:incoming>yes</bpmn:incoming><bpmn:outgoing>f4</bpmn:outgoing>
    </bpmn:serviceTask>
    <bpmn:serviceTask id="sample" name="Sample">
      <bpmn:extensionElements>
        <zeebe:taskDefinition type="sys.sample" />
        <zeebe:ioMapping><zeebe:input source="=site.id" target="site_id" /></zeebe:ioMapping>
      </bpmn:extensionElements>
      <bpmn:incoming>f4</bpmn:incoming><bpmn:outgoing>f5</bpmn:outgoing>
      <bpmn:multiInstanceLoopCharacteristics isSequential="true">
        <bpmn:extensionElements><zeebe:loopCharacteristics inputCollection="=plan.sites[score &gt; 0.8]" inputElement="site" /></bpmn:extensionElements>
      </bpmn:multiInstanceLoopCharacteristics>
    </bpmn:serviceTask>
    <bpmn:exclusiveGateway id="deep" name="Deep enough?" default="shallow"><bpmn:incoming>f5</bpmn:incoming><bpmn:outgoing>ok</bpmn:outgoing><bpmn:outgoing>shallow</bpmn:outgoing></bpmn:exclusiveGateway>
    <bpmn:sequenceFlow id="ok" sourceRef="deep" targetRef="done"><bpmn:conditionExpression xsi:type="bpmn:tFormalExpression" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">=depth2 = 5</bpmn:conditionExpression></bpmn:sequenceFlow>
    <bpmn:sequenceFlow id="shallow" sourceRef="deep" targetRef="wrong" />
    <bpmn:endEvent id="done"><bpmn:incoming>ok</bpmn:incoming></bpmn:endEvent>
    <bpmn:endEvent id="wrong"><bpmn:incoming>no</bpmn:incoming><bpmn:incoming>shallow</bpmn:incoming></bpmn:endEvent>
    <bpmn:sequenceFlow id="f1" sourceRef="start" targetRef="plan" />
    <bpmn:sequenceFlow id="f2" sourceRef="plan" targetRef="halve" />
    <bpmn:sequenceFlow id="f3" sourceRef="halve" targetRef="worth" />
    <bpmn:sequenceFlow id="f4" sourceRef="survey_task" targetRef="sample" />
    <bpmn:sequenceFlow id="f5" sourceRef="sample" targetRef="deep" />
  </bpmn:process>
</bpmn:definitions>"#;

const SCRIPT: &str = r#"{"default": {"duration_ms": 5},
  "resources": {"sys.survey": {"duration_ms": 5, "outputs": {"depth": 2.5}}}}"#;

fn workdir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("trace-feel-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("work dir");
    dir
}

#[test]
fn a_camunda_8_model_validates_and_runs_with_feel_semantics() {
    let dir = workdir("run");
    let mission = dir.join("survey.bpmn");
    std::fs::write(&mission, CAMUNDA8).expect("mission");
    std::fs::write(dir.join("script.json"), SCRIPT).expect("script");

    let out = Command::new(bin("trace"))
        .args(["validate", "--strict"])
        .arg(&mission)
        .output()
        .expect("trace validate");
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert!(!text.contains("warning"), "{text}");

    let out = Command::new(bin("trace"))
        .arg("run")
        .arg(&mission)
        .arg("--store")
        .arg(dir.join("store"))
        .arg("--script")
        .arg(dir.join("script.json"))
        .output()
        .expect("trace run");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("instance 1: Completed"), "{stdout}");

    let record = records(&dir.join("store/record.jsonl"));
    let dispatched: Vec<&serde_json::Value> = record
        .iter()
        .filter(|r| r["kind"] == "dispatched")
        .collect();
    // FEEL: 3 / 2 = 1.5, `some … satisfies`, a filter on a context entry, `for … return`.
    assert_eq!(dispatched[0]["element"]["id"], "survey_task");
    assert_eq!(dispatched[0]["request"]["site_ids"], "A,C");
    assert_eq!(dispatched[0]["request"]["count"], 3);
    // The input collection is the filtered list: two sequential bodies, A then C.
    let sites: Vec<&serde_json::Value> = dispatched[1..]
        .iter()
        .map(|d| &d["request"]["site_id"])
        .collect();
    assert_eq!(sites, ["A", "C"]);
    // 2.5 * 2 = 5 exactly: the `=depth2 = 5` branch.
    let took: Vec<&str> = record
        .iter()
        .filter(|r| r["kind"] == "took")
        .filter_map(|r| r["flow"].as_str())
        .collect();
    assert!(took.contains(&"yes") && took.contains(&"ok"), "{took:?}");
    assert!(
        !took.contains(&"no") && !took.contains(&"shallow"),
        "{took:?}"
    );
}

#[test]
fn every_feel_syntax_error_is_reported_by_validate_with_element_and_position() {
    let dir = workdir("validate");
    let mission = dir.join("broken.bpmn");
    let broken = CAMUNDA8
        .replace("=plan.n / 2", "=plan.n / ")
        .replace("=count(plan.sites)", "=count(plan.sites, 2)")
        .replace("=depth2 = 5", "=depth2 = = 5")
        .replace("=site.id", "=not(site.id")
        .replace(
            "inputCollection=\"=plan.sites[score &gt; 0.8]\"",
            "inputCollection=\"=plan.sites[score &gt; 0.8\"",
        );
    std::fs::write(&mission, broken).expect("mission");
    let out = Command::new(bin("trace"))
        .args(["validate", "--json"])
        .arg(&mission)
        .output()
        .expect("trace validate");
    assert!(!out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let errors: Vec<(String, String)> = report[0]["diagnostics"]
        .as_array()
        .expect("diagnostics")
        .iter()
        .filter(|d| d["severity"] == "error")
        .map(|d| {
            (
                d["element"].as_str().unwrap_or_default().to_owned(),
                d["message"].as_str().unwrap_or_default().to_owned(),
            )
        })
        .collect();
    let find = |element: &str, fragment: &str| {
        assert!(
            errors
                .iter()
                .any(|(e, m)| e == element && m.contains(fragment)),
            "no error on {element} containing {fragment:?}: {errors:#?}"
        );
    };
    find("halve", "at the end of `plan.n /`");
    find("survey_task", "`count` does not take 2 arguments");
    find("ok", "at character 10 of `depth2 = = 5`");
    find(
        "sample",
        "to close the call, found the end (FEEL, at the end of `not(site.id`)",
    );
    find("sample", "input collection");
    assert_eq!(errors.len(), 5, "{errors:#?}");
}
