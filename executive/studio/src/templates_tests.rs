//! Camunda element templates from the deployment's catalogues: every one valid for Camunda's
//! own validator (the one Camunda Modeler uses), and each, applied as Camunda Modeler applies
//! its bindings, a service task that `trace validate` accepts and `trace run`'s catalogue check
//! passes — for Camunda 7 and Camunda 8.

use std::path::PathBuf;
use std::process::Command;

use connector_api::catalogue::field_at;
use connector_api::{Catalogue, ConnectorsConfig, Type};
use serde_json::Value;

use crate::templates::{Platform, templates, write};

fn deploy() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../deploy"))
}

fn setup() -> (Vec<Catalogue>, ConnectorsConfig) {
    let d = deploy();
    let catalogues = crate::read_catalogues(&[d.join("catalogues"), d.join("ground/forms.json")])
        .expect("catalogues");
    let config = crate::read_connectors(&d.join("connectors.toml")).expect("connectors");
    (catalogues, config)
}

#[test]
fn every_template_passes_camundas_validator() {
    let (catalogues, config) = setup();
    let out = std::env::temp_dir().join(format!("trace-templates-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let files = write(&catalogues, Some(&config), &out).expect("written");
    // Each vehicle's actions for both Camundas; the ground's forms give none.
    let names: Vec<_> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "trace-lander_sim.c7.json",
            "trace-lander_sim.c8.json",
            "trace-scout_sim.c7.json",
            "trace-scout_sim.c8.json"
        ]
    );
    let output = Command::new("node")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/web/check-templates.mjs"
        ))
        .args(&files)
        .env("TRACE_NODE_MODULES", env!("TRACE_STUDIO_NODE_MODULES"))
        .output()
        .expect("node runs (scripts/test installs it)");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let lines: Vec<Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), 4, "{stdout}");
    for (l, (actions, platform)) in lines
        .iter()
        .zip([(20, "c7"), (20, "c8"), (3, "c7"), (3, "c8")])
    {
        assert_eq!(l["templates"], actions, "{l}");
        assert_eq!(l["errors"], serde_json::json!([]), "{l}");
        assert_eq!(l["platform"], platform, "{l}");
    }
}

#[test]
fn the_validator_refuses_a_broken_template() {
    // The check above could pass by validating nothing: a template with a binding no Camunda
    // knows must be refused, naming it.
    let (catalogues, config) = setup();
    let mut list = templates(&catalogues[0], Some(&config), Platform::Camunda8);
    list[0]["properties"][1]["binding"]["type"] = "zeebe:inputs".into();
    let file = std::env::temp_dir().join(format!("trace-broken-{}.json", std::process::id()));
    std::fs::write(&file, list.to_string()).expect("written");
    let output = Command::new("node")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/web/check-templates.mjs"
        ))
        .arg(&file)
        .env("TRACE_NODE_MODULES", env!("TRACE_STUDIO_NODE_MODULES"))
        .output()
        .expect("node runs");
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stdout).contains("zeebe:inputs"));
}

/// A value a planner might enter for a goal field of type `ty`, as each Camunda writes it.
fn sample(ty: &Type, platform: Platform) -> &'static str {
    match (platform, ty) {
        (Platform::Camunda7, Type::Int) => "${3}",
        (Platform::Camunda7, Type::Float) => "${0.5}",
        (Platform::Camunda7, Type::Bool) => "${true}",
        (Platform::Camunda7, Type::String) => "mast",
        (Platform::Camunda7, Type::Timestamp) => "2031-07-04T12:00:00Z",
        (Platform::Camunda7, _) => "${earlier}",
        (Platform::Camunda8, Type::Int) => "=3",
        (Platform::Camunda8, Type::Float) => "=0.5",
        (Platform::Camunda8, Type::Bool) => "=true",
        (Platform::Camunda8, Type::String) => "mast",
        (Platform::Camunda8, Type::Timestamp) => "2031-07-04T12:00:00Z",
        (Platform::Camunda8, _) => "=earlier",
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// The service task Camunda Modeler writes when `template` is applied and its fields filled
/// (Camunda's documented binding rules: a `property` is an attribute; `camunda:inputParameter`
/// and `camunda:outputParameter` go in `camunda:inputOutput`, the output's `value` being the
/// variable; `zeebe:taskDefinition` `type`; `zeebe:input` / `zeebe:output` in `zeebe:ioMapping`).
fn applied(
    template: &Value,
    goal: &std::collections::BTreeMap<String, Type>,
    platform: Platform,
) -> String {
    let mut attrs = String::new();
    let mut c7_io = String::new();
    let mut zeebe_io = String::new();
    let mut task_type = String::new();
    for p in template["properties"].as_array().expect("properties") {
        let b = &p["binding"];
        let value = |name: &str| -> String {
            p["value"].as_str().map_or_else(
                || {
                    let ty = field_at(goal, name).expect("a goal field").required();
                    sample(ty, platform).to_owned()
                },
                str::to_owned,
            )
        };
        match b["type"].as_str().expect("binding type") {
            "property" => attrs.push_str(&format!(
                " {}=\"{}\"",
                b["name"].as_str().unwrap(),
                escape(&value(""))
            )),
            "camunda:inputParameter" => {
                let name = b["name"].as_str().unwrap();
                c7_io.push_str(&format!(
                    "<camunda:inputParameter name=\"{name}\">{}</camunda:inputParameter>",
                    escape(&value(name))
                ));
            }
            "camunda:outputParameter" => c7_io.push_str(&format!(
                "<camunda:outputParameter name=\"{}\">{}</camunda:outputParameter>",
                p["value"].as_str().unwrap(),
                escape(b["source"].as_str().unwrap())
            )),
            "zeebe:taskDefinition" => task_type = value(""),
            "zeebe:input" => {
                let name = b["name"].as_str().unwrap();
                zeebe_io.push_str(&format!(
                    "<zeebe:input source=\"{}\" target=\"{name}\"/>",
                    escape(&value(name))
                ));
            }
            "zeebe:output" => zeebe_io.push_str(&format!(
                "<zeebe:output source=\"{}\" target=\"{}\"/>",
                escape(b["source"].as_str().unwrap()),
                p["value"].as_str().unwrap()
            )),
            other => panic!("a binding the test does not know: {other}"),
        }
    }
    let extensions = match platform {
        Platform::Camunda7 => format!("<camunda:inputOutput>{c7_io}</camunda:inputOutput>"),
        Platform::Camunda8 => format!(
            "<zeebe:taskDefinition type=\"{task_type}\"/><zeebe:ioMapping>{zeebe_io}</zeebe:ioMapping>"
        ),
    };
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL"
  xmlns:camunda="http://camunda.org/schema/1.0/bpmn" xmlns:zeebe="http://camunda.org/schema/zeebe/1.0"
  id="d" targetNamespace="urn:test">
<bpmn:process id="p" isExecutable="true">
<bpmn:startEvent id="s"/><bpmn:sequenceFlow id="f1" sourceRef="s" targetRef="t"/>
<bpmn:serviceTask id="t"{attrs}><bpmn:extensionElements>{extensions}</bpmn:extensionElements></bpmn:serviceTask>
<bpmn:sequenceFlow id="f2" sourceRef="t" targetRef="e"/><bpmn:endEvent id="e"/>
</bpmn:process></bpmn:definitions>"#
    )
}

#[test]
fn every_template_applied_is_a_binding_trace_reads_and_runs() {
    let (catalogues, config) = setup();
    let lander = &catalogues[0];
    for platform in [Platform::Camunda7, Platform::Camunda8] {
        let list = templates(lander, Some(&config), platform);
        let list = list.as_array().expect("an array");
        assert_eq!(list.len(), lander.actions.len());
        for (template, action) in list.iter().zip(&lander.actions) {
            let xml = applied(template, &action.goal, platform);
            let loaded = executive_model::load(xml.as_bytes());
            let errors: Vec<String> = loaded.errors().map(|d| d.to_string()).collect();
            assert!(
                errors.is_empty(),
                "{platform:?} {}: {errors:?}\n{xml}",
                action.name
            );
            let graph = loaded.graph.expect("a graph");
            let uses = executive_runtime::connectors::task_uses(&graph);
            assert_eq!(uses.len(), 1);
            assert_eq!(uses[0].resource, action.name);
            let catalogues = vec![Some(lander.clone()), None];
            let mismatches = connector_api::check(&uses, &config, &catalogues);
            assert!(
                mismatches.is_empty(),
                "{platform:?} {}: {mismatches:?}\n{xml}",
                action.name
            );
        }
    }
}
