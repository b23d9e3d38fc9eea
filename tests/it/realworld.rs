//! Real-world models drawn by other people for their own engines and tools
//! (`../shared/conformance/realworld`): each read as `trace run` reads it, counted by verdict, and
//! every file that keeps a BPMN error listed here with the clause it breaks.
//!
//! A BPMN error must be a real breach of BPMN 2.0.2 that leaves the model ambiguous or
//! unexecutable; what TRACE cannot run (Python or JavaScript scripts, FEEL beyond the subset,
//! called processes deployed elsewhere) is an execution problem. A file listed here that starts
//! to load, or a file not listed that keeps a BPMN error, fails the test, so the list stays true.

use std::collections::BTreeMap;

use executive_model::{Category, Options, Severity};
use executive_runtime::validate::load_file;
use mission_tests::{conformance, json_array};

/// Files that keep a BPMN error, with the clause and why the refusal is right.
const KEPT: &[(&str, &str)] = &[
    (
        "bpmn-io/bpmn-js-examples/theming/resources/kitchen-sink.bpmn",
        "EXT.111 (§10.5.4): a cancel boundary event is attached to a task, not a transaction; SpiffWorkflow refuses the same (invalid_cancel.bpmn)",
    ),
    (
        "bpmn-io/bpmn-js/test/fixtures/bpmn/error/duplicate-ids.bpmn",
        "§8.3.1 and the schema's xsd:ID: two processes share one id; a bpmn-js import-error fixture",
    ),
    (
        "bpmn-io/bpmn-js/test/fixtures/bpmn/error/missing-namespace.bpmn",
        "§8.2 (the XSD's target namespace): <definitions> outside the BPMN namespace is not BPMN; a bpmn-js error fixture",
    ),
    (
        "bpmn-io/bpmn-js/test/fixtures/bpmn/import/error/boundaryEvent-invalidAttachToRef.bpmn",
        "§10.5.4 and the XSD (attachedToRef is required and names an activity): the boundary event is attached to nothing; a bpmn-js import-error fixture",
    ),
    (
        "bpmn-io/bpmn-js/test/fixtures/bpmn/import/error/boundaryEvent-missingAttachToRef.bpmn",
        "§10.5.4 and the XSD (attachedToRef is required): the boundary event is attached to nothing; a bpmn-js import-error fixture",
    ),
    (
        "paed01-bpmn-engine/test/resources/service-task-operation.bpmn",
        "§8.2: the root is in http://schema.omg.org/spec/BPMN/2.0, a pre-release namespace, not BPMN 2.0's; nothing upstream loads the file",
    ),
    (
        "spiffworkflow/tests/SpiffWorkflow/bpmn/data/data_object_invalid.bpmn",
        "§8.3.1 and xsd:ID: a duplicated id and data associations to references that do not exist; invalid on purpose",
    ),
    (
        "spiffworkflow/tests/SpiffWorkflow/bpmn/data/invalid_cancel.bpmn",
        "EXT.111 (§10.5.4): a cancel boundary event outside a transaction; SpiffWorkflow's CancelBoundaryTest expects a ValidationException",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/DefinitionsTest.shouldNotAffectCommentsResult.bpmn",
        "XML 1.0 §2.1: content after the root element; a fragment the Zeebe model API compares as text",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/validation/LinkEventTest.testCatchLinkEventAfterEventBasedGatewayNotAllowed.bpmn",
        "EXT.138, EXT.117, EXT.124: a link catch event after an event-based gateway; Zeebe's validation test refuses it",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/validation/LinkEventTest.testInvalidEventLinkMultipleTarget.bpmn",
        "§10.5.6 (a link has one target): two link catch events share a name, so a throw of it is ambiguous; Zeebe's validation test refuses it",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/validation/default-flow-inclusive-gateway.bpmn",
        "§10.6.3 (default: one of the gateway's outgoing flows): the default names a flow that does not leave the gateway; Zeebe's validation test refuses it",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/validation/default-flow.bpmn",
        "§10.6.2 (default: one of the gateway's outgoing flows): the default names a flow that does not leave the gateway; Zeebe's validation test refuses it",
    ),
    (
        "zeebe/zeebe/bpmn-model/src/test/resources/io/camunda/zeebe/model/bpmn/validation/multiple-timer-start-event-sub-process.bpmn",
        "EXT.098 (§10.5.2): timer start events inside an embedded sub-process, which has no trigger of its own to wait for",
    ),
];

#[test]
fn realworld_models_load_unless_they_break_bpmn() {
    let root = conformance("realworld");
    let mut verdicts: BTreeMap<String, usize> = BTreeMap::new();
    let mut execution: BTreeMap<&str, usize> = BTreeMap::new();
    let mut wrong = Vec::new();
    for entry in json_array(&root.join("files.json")) {
        let file = entry["path"].as_str().expect("path");
        let own = entry["own_engine"].as_str().unwrap_or("none");
        let well_formed = entry["xml_well_formed"].as_bool().expect("xml_well_formed");
        let loaded = load_file(&root.join(file), &Options::default())
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let errors: Vec<_> = loaded.errors().collect();
        let bpmn: Vec<String> = errors
            .iter()
            .filter(|d| d.category == Category::Bpmn)
            .map(|d| format!("{}:{} [{}] {}", d.line, d.column, d.code, d.message))
            .collect();
        for d in errors.iter().filter(|d| d.category == Category::Execution) {
            *execution.entry(d.code).or_default() += 1;
        }
        let verdict = if loaded.unreadable() {
            "unreadable"
        } else if !bpmn.is_empty() {
            "bpmn error"
        } else if !errors.is_empty() {
            "execution problem"
        } else if loaded
            .diagnostics
            .iter()
            .any(|d| d.severity == Severity::Warning)
        {
            "loads with warnings"
        } else {
            "loads clean"
        };
        *verdicts.entry(format!("{verdict} ({own})")).or_default() += 1;
        *verdicts.entry(verdict.to_owned()).or_default() += 1;
        // Not well-formed: refused with the position, or (the choice made for bpmn-js's own
        // drawing fixtures: an undeclared prefix, a declaration without spaces) read leniently
        // with a warning saying so.
        let lenient = loaded.diagnostics.iter().any(|d| d.code == "xml");
        if !well_formed && !loaded.unreadable() && !lenient {
            wrong.push(format!("{file}: not well-formed XML, read without a word"));
        }
        let kept = KEPT.iter().any(|(f, _)| *f == file);
        match (bpmn.is_empty() && !loaded.unreadable(), kept) {
            (true, true) => wrong.push(format!(
                "{file}: listed in KEPT but loads now; remove it from the list"
            )),
            (false, false) => wrong.push(format!(
                "{file} ({own}): BPMN errors with no clause on record: {bpmn:#?}"
            )),
            _ => {}
        }
        // An execution problem names what is missing: no bare failures.
        for d in &loaded.diagnostics {
            assert!(!d.message.is_empty() && d.line >= 1, "{file}: {d:?}");
        }
    }
    println!("realworld verdicts: {verdicts:#?}");
    println!("realworld execution problems by code: {execution:#?}");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    assert_eq!(
        verdicts.get("bpmn error").copied().unwrap_or(0)
            + verdicts.get("unreadable").copied().unwrap_or(0),
        KEPT.len()
    );
}
