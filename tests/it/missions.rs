//! The shipped mission models: every model under `deploy/missions/` loads with zero
//! diagnostics, and the Europa BSM-1 model has the structure the TRACE paper describes.

use executive_model::*;
use executive_runtime::validate::load_file;
use mission_tests::repo;

#[test]
fn every_deployed_mission_validates_cleanly() {
    let dir = repo().join("deploy/missions");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).expect("deploy/missions") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "bpmn") {
            let loaded = load_file(&path, &Options::default()).expect("readable");
            assert!(
                loaded.diagnostics.is_empty(),
                "{}: {:#?}",
                path.display(),
                loaded.diagnostics
            );
            count += 1;
        }
    }
    println!("deploy/missions: {count} model(s), zero diagnostics");
    assert!(count >= 1);
}

fn europa() -> ProcessGraph {
    let loaded = load_file(
        &repo().join("deploy/missions/europa-bsm1.bpmn"),
        &Options::default(),
    )
    .expect("readable");
    loaded.graph.expect("valid")
}

fn find(g: &ProcessGraph, name: &str) -> NodeId {
    (0..g.nodes.len() as u32)
        .map(NodeId)
        .find(|n| g.node(*n).name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no element named {name:?}"))
}

fn resource(g: &ProcessGraph, name: &str) -> String {
    match &g.node(find(g, name)).kind {
        NodeKind::Task(Task {
            binding: Some(b), ..
        }) => b.resource.as_deref().unwrap_or_default().to_owned(),
        other => panic!("{name} is not a bound task: {other:?}"),
    }
}

#[test]
fn europa_mission_follows_the_paper() {
    let g = europa();
    // Only the main process starts with the mission; Excavate is reused through a call activity.
    let main = g.process_by_id("BSM1").expect("main process");
    assert_eq!(g.primary_processes(), vec![main]);
    let excavate = find(&g, "Excavate");
    assert!(
        matches!(&g.node(excavate).kind, NodeKind::CallActivity(c) if c.called == Some(Called::Process(g.process_by_id("Excavate").unwrap())))
    );
    // Paper 4.2: site_id flows from site selection into Excavate and Find Collection Targets.
    assert_eq!(
        resource(&g, "Select Next Valid Excavation Option"),
        "world_model.select_site"
    );
    assert_eq!(
        resource(&g, "Find Collection Targets"),
        "sampling.find_targets"
    );
    // Escalation out of Excavate selects another site.
    let on_escalation = g.node(excavate).boundaries.iter().any(|b| matches!(&g.node(*b).kind, NodeKind::Boundary(e) if matches!(e.triggers[..], [EventDefinition::Escalation(Some(_))])));
    assert!(on_escalation, "escalation boundary on Excavate");
    // Paper 4.1: an error boundary on Remove Material leads to a decision on the fault.
    let remove = find(&g, "Remove Material");
    assert_eq!(resource(&g, "Remove Material"), "excavation.excavate");
    let fault = g.node(remove).boundaries[0];
    assert!(
        matches!(&g.node(fault).kind, NodeKind::Boundary(b) if matches!(&b.triggers[..], [EventDefinition::Error { error: None, code_variable: Some(_), .. }]))
    );
    let decision = g.flow(g.node(fault).outgoing[0]).target;
    assert!(
        matches!(&g.node(decision).kind, NodeKind::Gateway(gw) if gw.kind == GatewayKind::Exclusive)
    );
    assert!(
        g.node(decision)
            .outgoing
            .iter()
            .any(|f| g.node(g.flow(*f).target).name.as_deref() == Some("Unstick Tool"))
    );
    assert_eq!(
        resource(&g, "Assess Final Excavation Success"),
        "excavation.assess_slump"
    );
    // Collect All Samples: a multi-instance over the collection targets, done at 5 samples.
    let collect = find(&g, "Collect All Samples from Excavation Site");
    assert!(
        matches!(&g.node(collect).looping, Some(Looping::MultiInstance(m)) if m.input_collection.is_some() && m.completion.is_some())
    );
    // Time and energy contingencies on the science sub-process.
    let science = find(&g, "Excavate and Collect Samples");
    let triggers: Vec<&str> = g
        .node(science)
        .boundaries
        .iter()
        .filter_map(|b| match &g.node(*b).kind {
            NodeKind::Boundary(b) if b.interrupting => {
                b.triggers.first().map(EventDefinition::element_name)
            }
            _ => None,
        })
        .collect();
    assert_eq!(triggers, ["timerEventDefinition", "signalEventDefinition"]);
    let monitor = find(&g, "Battery Below 30 %?".replace("Below", "below").as_str());
    assert!(g.node(monitor).outgoing.iter().any(|f| {
        g.flow(*f)
            .condition
            .as_ref()
            .is_some_and(|c| c.text.contains("30.0"))
    }));
    // Both lead to Communicate Until Death, then the mission ends.
    let death = find(&g, "Communicate Until Death");
    let after = g.flow(g.node(death).outgoing[0]).target;
    assert!(
        matches!(&g.node(after).kind, NodeKind::End(r) if matches!(r[..], [EventDefinition::Terminate]))
    );
    // Ground decisions are user tasks with a timeout default.
    let approve = find(&g, "Approve Excavation Site");
    assert!(matches!(&g.node(approve).kind, NodeKind::Task(t) if t.kind == TaskKind::User));
    assert!(
        matches!(&g.node(g.node(approve).boundaries[0]).kind, NodeKind::Boundary(b) if matches!(b.triggers[..], [EventDefinition::Timer(_)]))
    );
}
