//! Hostile and broken input: entity bombs, XXE, deep nesting, huge files, attribute floods and
//! random bytes are refused with a clear message in bounded time, never a panic; floods of
//! listed flows, links, pools and data associations are checked in linear time.

use executive_model::{Limits, Options, load, load_with};
use mission_tests::repo;
use proptest::prelude::*;

fn refused(bytes: &[u8]) -> String {
    let loaded = load(bytes);
    assert!(loaded.graph.is_none());
    loaded
        .errors()
        .map(|d| d.message.clone())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn entity_expansion_bomb_is_refused() {
    let mut bomb = String::from("<?xml version=\"1.0\"?><!DOCTYPE lolz [<!ENTITY lol \"lol\">");
    for i in 1..10 {
        bomb.push_str(&format!(
            "<!ENTITY lol{i} \"{}\">",
            format!("&lol{};", i - 1).repeat(10)
        ));
    }
    bomb.push_str("]><definitions>&lol9;</definitions>");
    assert!(refused(bomb.as_bytes()).contains("DOCTYPE"));
}

#[test]
fn external_entities_are_never_read() {
    let dir = std::env::temp_dir().join(format!("trace-xxe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let secret = dir.join("secret.txt");
    std::fs::write(&secret, "TOP-SECRET-PAYLOAD").unwrap();
    let xml = format!(
        "<?xml version=\"1.0\"?><!DOCTYPE d [<!ENTITY xxe SYSTEM \"file://{}\">]><bpmn:definitions xmlns:bpmn=\"http://www.omg.org/spec/BPMN/20100524/MODEL\"><bpmn:process id=\"&xxe;\"/></bpmn:definitions>",
        secret.display()
    );
    let message = refused(xml.as_bytes());
    assert!(!message.contains("TOP-SECRET"), "{message}");
    // Without a DOCTYPE, an undeclared entity is an error too.
    assert!(refused(b"<bpmn:definitions xmlns:bpmn=\"http://www.omg.org/spec/BPMN/20100524/MODEL\">&xxe;</bpmn:definitions>").contains("undefined entity"));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn deep_nesting_is_refused() {
    let deep = "<a>".repeat(100_000) + &"</a>".repeat(100_000);
    assert!(refused(deep.as_bytes()).contains("nested deeper"));
}

#[test]
fn oversized_input_and_attribute_floods_are_refused() {
    let small = Options {
        limits: Limits {
            max_bytes: 1 << 20,
            ..Limits::default()
        },
        ..Options::default()
    };
    let big = vec![b' '; (1 << 20) + 1];
    assert!(
        load_with(&big, &small)
            .errors()
            .any(|d| d.message.contains("limit"))
    );
    let attrs: String = (0..10_000).map(|i| format!(" custom:a{i}=\"v\"")).collect();
    let flood = format!(
        "<bpmn:definitions xmlns:bpmn=\"http://www.omg.org/spec/BPMN/20100524/MODEL\" xmlns:custom=\"urn:x\"><bpmn:startEvent{attrs}/></bpmn:definitions>"
    );
    assert!(refused(flood.as_bytes()).contains("attributes"));
}

#[test]
fn twenty_thousand_flows_listed_at_both_ends_are_checked_in_linear_time() {
    // Each listing is looked up once; none is compared with every other listing of its node.
    let model = |unlisted: usize| {
        let n = 20_000;
        let ids = |skip: usize| -> String {
            (0..n)
                .filter(|i| *i != skip)
                .map(|i| format!("<bpmn:incoming>f{i}</bpmn:incoming>"))
                .collect()
        };
        let outgoing = ids(n).replace("incoming>", "outgoing>");
        let flows: String = (0..n)
            .map(|i| format!(r#"<bpmn:sequenceFlow id="f{i}" sourceRef="s" targetRef="e"/>"#))
            .collect();
        format!(
            r#"<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d"><bpmn:process id="p" isExecutable="true"><bpmn:startEvent id="s">{outgoing}</bpmn:startEvent><bpmn:endEvent id="e">{}</bpmn:endEvent>{flows}</bpmn:process></bpmn:definitions>"#,
            ids(unlisted)
        )
    };
    let mismatches = |xml: String| {
        let loaded = load(xml.as_bytes());
        assert!(loaded.graph.is_some(), "{:?}", loaded.errors().next());
        loaded
            .diagnostics
            .iter()
            .filter(|d| d.code == "flow-mismatch")
            .map(|d| d.message.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(mismatches(model(usize::MAX)), Vec::<String>::new());
    let one = mismatches(model(12_345));
    assert_eq!(one.len(), 1, "{one:?}");
    assert!(one[0].contains("`f12345`"), "{one:?}");
}

#[test]
fn links_pools_and_data_associations_by_the_ten_thousand_are_checked_in_linear_time() {
    // Each of these was a scan per element (of the scope per link thrown, of every process per
    // participant, of the activity per association): minutes for models of this kind at the
    // size limit.
    let n = 10_000;
    let head =
        r#"<bpmn:definitions xmlns:bpmn="http://www.omg.org/spec/BPMN/20100524/MODEL" id="d">"#;
    let process = |body: String| {
        format!(
            r#"{head}<bpmn:process id="p" isExecutable="true">{body}</bpmn:process></bpmn:definitions>"#
        )
    };
    let links = process(
        r#"<bpmn:startEvent id="s"/><bpmn:parallelGateway id="fork"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="a" sourceRef="s" targetRef="fork"/>"#.to_owned()
            + &(0..n)
                .map(|i| format!(r#"<bpmn:intermediateThrowEvent id="lt{i}"><bpmn:linkEventDefinition name="L{i}"/></bpmn:intermediateThrowEvent><bpmn:sequenceFlow id="x{i}" sourceRef="fork" targetRef="lt{i}"/><bpmn:intermediateCatchEvent id="lc{i}"><bpmn:linkEventDefinition name="L{i}"/></bpmn:intermediateCatchEvent><bpmn:sequenceFlow id="y{i}" sourceRef="lc{i}" targetRef="e"/>"#))
                .collect::<String>(),
    );
    let mut pools = format!(r#"{head}<bpmn:collaboration id="c">"#);
    pools += &(0..n)
        .map(|i| format!(r#"<bpmn:participant id="pa{i}" processRef="p{i}"/>"#))
        .collect::<String>();
    pools += "</bpmn:collaboration>";
    pools += &(0..n)
        .map(|i| format!(r#"<bpmn:process id="p{i}" isExecutable="true"><bpmn:startEvent id="s{i}"/><bpmn:endEvent id="e{i}"/><bpmn:sequenceFlow id="f{i}" sourceRef="s{i}" targetRef="e{i}"/></bpmn:process>"#))
        .collect::<String>();
    pools += "</bpmn:definitions>";
    let data = process(
        r#"<bpmn:startEvent id="s"/><bpmn:endEvent id="e"/><bpmn:sequenceFlow id="a" sourceRef="s" targetRef="t"/><bpmn:sequenceFlow id="b" sourceRef="t" targetRef="e"/>"#.to_owned()
            + &(0..n).map(|i| format!(r#"<bpmn:dataObject id="do{i}"/>"#)).collect::<String>()
            + r#"<bpmn:task id="t"><bpmn:ioSpecification><bpmn:dataInput id="in"/><bpmn:inputSet><bpmn:dataInputRefs>in</bpmn:dataInputRefs></bpmn:inputSet><bpmn:outputSet/></bpmn:ioSpecification>"#
            + &(0..n)
                .map(|i| format!(r#"<bpmn:dataInputAssociation id="da{i}"><bpmn:sourceRef>do{i}</bpmn:sourceRef><bpmn:targetRef>in</bpmn:targetRef></bpmn:dataInputAssociation>"#))
                .collect::<String>()
            + "</bpmn:task>",
    );
    for (what, xml) in [("links", links), ("pools", pools), ("data", data)] {
        let loaded = load(xml.as_bytes());
        assert!(
            loaded.graph.is_some(),
            "{what}: {:?}",
            loaded.errors().next()
        );
        assert!(
            loaded.diagnostics.is_empty(),
            "{what}: {:?}",
            &loaded.diagnostics[..1]
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let loaded = load(&bytes);
        prop_assert!(loaded.graph.is_none() || !loaded.diagnostics.iter().any(|d| d.severity == executive_model::Severity::Error));
    }

    #[test]
    fn damaged_missions_never_panic(cut in 0usize..100_000, flip in 0usize..100_000, byte in any::<u8>()) {
        let mut bytes = std::fs::read(repo().join("deploy/missions/europa-bsm1.bpmn")).unwrap();
        let i = flip % bytes.len();
        bytes[i] = byte;
        bytes.truncate(cut % bytes.len() + 1);
        let loaded = load(&bytes);
        for d in &loaded.diagnostics {
            prop_assert!(d.line >= 1 && d.column >= 1);
        }
    }
}
