//! Camunda element templates from the systems' catalogues (`trace templates`), so a planner
//! who draws in Camunda Modeler gets the studio's choices there: one template per action, for
//! Camunda 7 and for Camunda 8, each a service task bound to the action with one field per goal
//! field (typed where the template format can say it) and one per top-level result field.
//!
//! What a template writes is a binding TRACE reads (`executive_model::binding`): for Camunda 7
//! an external task (`camunda:type="external"`, `camunda:topic` = the resource) with
//! `camunda:inputParameter` per goal field (a plain value is text in Camunda 7, so other types
//! take an expression `${…}`) and `camunda:outputParameter` per result field; for Camunda 8
//! `zeebe:taskDefinition type` = the resource and `zeebe:input` / `zeebe:output` mappings
//! (FEEL `=…` where the field is not text). Error codes are listed in each template's
//! description: neither format can add the boundary events that catch them.
//!
//! The formats are Camunda's published JSON schemas (`@camunda/element-templates-json-schema`
//! and `@camunda/zeebe-element-templates-json-schema`); the tests validate every template with
//! `@bpmn-io/element-templates-validator`, the validator Camunda Modeler itself uses.

use std::collections::BTreeMap;

use connector_api::{ActionSpec, Catalogue, ConnectorsConfig, Kind, Type};
use serde_json::{Value, json};

/// The schema a Camunda 7 template names.
pub const C7_SCHEMA: &str =
    "https://unpkg.com/@camunda/element-templates-json-schema/resources/schema.json";
/// The schema a Camunda 8 template names.
pub const C8_SCHEMA: &str =
    "https://unpkg.com/@camunda/zeebe-element-templates-json-schema/resources/schema.json";

/// Which Camunda a template is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Platform {
    /// Camunda 7 (`camunda:`).
    Camunda7,
    /// Camunda 8 (`zeebe:`).
    Camunda8,
}

impl Platform {
    /// The short name used in file names: `c7`, `c8`.
    pub fn short(self) -> &'static str {
        match self {
            Platform::Camunda7 => "c7",
            Platform::Camunda8 => "c8",
        }
    }
}

/// The resource a task names to reach `action` of `server`: the name the connectors route to
/// it (an `actions` rename, else the action's own name).
pub fn resource_for(config: Option<&ConnectorsConfig>, server: &str, action: &str) -> String {
    config
        .into_iter()
        .flat_map(|c| &c.connectors)
        .filter(|c| c.kind != Kind::Script && c.server() == server)
        .flat_map(|c| &c.actions)
        .find(|(resource, a)| match a {
            connector_api::ActionRoute::Name(n) => n == action,
            connector_api::ActionRoute::Ros2(_) => resource.as_str() == action,
        })
        .map_or_else(|| action.to_owned(), |(resource, _)| resource.clone())
}

/// The templates of every action of `catalogue` for `platform`, as one JSON array (the file
/// Camunda Modeler reads from `.camunda/element-templates/`). A catalogue of ground forms (a
/// connector with `answers`) gives none: user tasks are not bound through these formats.
pub fn templates(
    catalogue: &Catalogue,
    config: Option<&ConnectorsConfig>,
    platform: Platform,
) -> Value {
    let answers = config
        .into_iter()
        .flat_map(|c| &c.connectors)
        .any(|c| c.answers && c.server() == catalogue.server);
    if answers {
        return json!([]);
    }
    Value::Array(
        catalogue
            .actions
            .iter()
            .map(|a| {
                let resource = resource_for(config, &catalogue.server, &a.name);
                template(&catalogue.server, a, &resource, platform)
            })
            .collect(),
    )
}

fn template(server: &str, action: &ActionSpec, resource: &str, platform: Platform) -> Value {
    let mut description = if action.description.is_empty() {
        format!("`{}` of {server}", action.name)
    } else {
        action.description.clone()
    };
    if !action.errors.is_empty() {
        let codes: Vec<&str> = action.errors.keys().map(String::as_str).collect();
        description.push_str(&format!(". Error codes: {}", codes.join(", ")));
    }
    let mut properties = Vec::new();
    let mut goal = Vec::new();
    leaves(&action.goal, "", false, &mut goal);
    // Results go out whole, one variable per top-level field (`selected_site`, an object).
    let result: Vec<(&String, &Type)> = action.result.iter().collect();
    match platform {
        Platform::Camunda7 => {
            properties.push(json!({
                "type": "Hidden", "value": "external",
                "binding": { "type": "property", "name": "camunda:type" }
            }));
            properties.push(json!({
                "label": "Resource", "type": "String", "value": resource, "editable": false,
                "binding": { "type": "property", "name": "camunda:topic" }
            }));
            // Camunda 7 has no optional input: an empty parameter would be the text "".
            for (path, ty, _) in goal.iter().filter(|(_, _, optional)| !optional) {
                properties.push(c7_input(path, ty));
            }
            for (field, ty) in &result {
                properties.push(json!({
                    "label": format!("Result {field} ({ty}) into variable"),
                    "type": "String",
                    "value": field,
                    "binding": { "type": "camunda:outputParameter", "source": format!("${{{field}}}") }
                }));
            }
        }
        Platform::Camunda8 => {
            properties.push(json!({
                "label": "Resource", "type": "String", "value": resource, "editable": false,
                "binding": { "type": "zeebe:taskDefinition", "property": "type" }
            }));
            for (path, ty, optional) in &goal {
                properties.push(c8_input(path, ty, *optional));
            }
            for (field, ty) in &result {
                properties.push(json!({
                    "label": format!("Result {field} ({ty}) into variable"),
                    "type": "String",
                    "value": field,
                    "binding": { "type": "zeebe:output", "source": format!("={field}") }
                }));
            }
        }
    }
    let mut t = json!({
        "$schema": match platform { Platform::Camunda7 => C7_SCHEMA, Platform::Camunda8 => C8_SCHEMA },
        "name": format!("{} ({server})", action.name),
        "id": format!("trace.{server}.{}", action.name),
        "version": 1,
        "description": description,
        "appliesTo": ["bpmn:ServiceTask"],
        "properties": properties,
    });
    if platform == Platform::Camunda8 {
        t["category"] =
            json!({ "id": format!("trace.{server}"), "name": format!("TRACE: {server}") });
        t["elementType"] = json!({ "value": "bpmn:ServiceTask" });
    }
    t
}

/// Every leaf field of a message as (dotted path, type, optional): objects are walked, since
/// TRACE writes nested goal fields by path (`selected_site.site_id`).
fn leaves(
    fields: &BTreeMap<String, Type>,
    prefix: &str,
    optional: bool,
    out: &mut Vec<(String, Type, bool)>,
) {
    for (name, ty) in fields {
        let path = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        let opt = optional || matches!(ty, Type::Optional(_));
        match ty.required() {
            Type::Object(inner) => leaves(inner, &path, opt, out),
            t => out.push((path, t.clone(), opt)),
        }
    }
}

fn field_help(path: &str, ty: &Type, optional: bool) -> String {
    format!(
        "Goal field `{path}`: {ty}{}",
        if optional { ", optional" } else { ", required" }
    )
}

/// A required goal field's Camunda 7 input (optional ones are not offered, see above).
fn c7_input(path: &str, ty: &Type) -> Value {
    let optional = false;
    let binding = json!({ "type": "camunda:inputParameter", "name": path });
    let label = format!("{path} ({ty})");
    match ty {
        Type::Bool => json!({
            "label": label, "type": "Dropdown", "value": "${false}",
            "description": field_help(path, ty, optional),
            "choices": [ { "name": "true", "value": "${true}" }, { "name": "false", "value": "${false}" } ],
            "binding": binding
        }),
        Type::String | Type::Timestamp => json!({
            "label": label, "type": "String",
            "description": format!("{}: text, or an expression ${{…}}", field_help(path, ty, optional)),
            "constraints": { "notEmpty": true },
            "binding": binding
        }),
        _ => json!({
            "label": label, "type": "String",
            "description": format!("{}: an expression, e.g. ${{3}} or ${{site.id}} (plain values are text in Camunda 7)", field_help(path, ty, optional)),
            "constraints": {
                "notEmpty": true,
                "pattern": { "value": "^\\$\\{.+\\}$", "message": "an expression ${…}: a plain value would be text" }
            },
            "binding": binding
        }),
    }
}

fn c8_input(path: &str, ty: &Type, optional: bool) -> Value {
    let binding = json!({ "type": "zeebe:input", "name": path });
    let mut p = json!({
        "label": format!("{path} ({ty})"),
        "type": "String",
        "description": field_help(path, ty, optional),
        "binding": binding,
    });
    match ty {
        Type::String | Type::Timestamp => p["feel"] = json!("optional"),
        _ => p["feel"] = json!("required"),
    }
    if optional {
        p["optional"] = json!(true);
    } else {
        p["constraints"] = json!({ "notEmpty": true });
    }
    p
}

/// Writes `trace-<server>.c7.json` and `trace-<server>.c8.json` into `out` (created if
/// missing) for every catalogue that gives templates; returns the files written.
pub fn write(
    catalogues: &[Catalogue],
    config: Option<&ConnectorsConfig>,
    out: &std::path::Path,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(out)?;
    let mut written = Vec::new();
    for cat in catalogues {
        for platform in [Platform::Camunda7, Platform::Camunda8] {
            let list = templates(cat, config, platform);
            if list.as_array().is_none_or(Vec::is_empty) {
                continue;
            }
            let file = out.join(format!("trace-{}.{}.json", cat.server, platform.short()));
            let text = serde_json::to_string_pretty(&list).map_err(std::io::Error::other)?;
            std::fs::write(&file, text)?;
            written.push(file);
        }
    }
    Ok(written)
}
