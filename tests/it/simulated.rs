//! The token game against bpmn-js-token-simulation itself: random models from the generated
//! test's grammar (without what the simulator runs as a plain task), each run by the simulator in
//! headless chromium and driven at random from its seed (gateway branches, tasks that wait,
//! outside triggers), and written as a scenario of the token-simulation corpus; the corpus
//! runner behind `trace conformance token-simulation` replays every scenario on the engine,
//! which must enter and leave the same elements. Two kinds of difference are counted, not
//! failed: the reviewed deviation (an error nothing catches), and order within a step in a model
//! that throws ([`RACE`]); where the simulator departs from BPMN the grammar draws around it
//! (`docs/engine-semantics.md`, "Within a step"). `TRACE_SIMULATED_MODELS` and
//! `TRACE_SIMULATED_SEED` choose the models; `TRACE_SIMULATED_RACES` prints the races too.

use std::process::Command;

use executive_runtime::conformance::token_sim;
use mission_tests::repo;
use serde_json::{Value, json};

use crate::generated::{model, number};
use crate::protocol::tempdir;
use crate::studio::{free_port, session, start};

/// Outside triggers per model, at most.
const TRIGGERS: u64 = 40;

#[test]
fn the_engine_plays_generated_models_as_bpmn_js_token_simulation_does() {
    let count = number("TRACE_SIMULATED_MODELS", 500);
    let first = number("TRACE_SIMULATED_SEED", 1);
    let work = tempdir("simulated");
    let page = work.join("page");
    let built = Command::new("node")
        .arg(repo().join("tests/simulator/build.mjs"))
        .arg(&page)
        .env("TRACE_NODE_MODULES", executive_studio::NODE_MODULES)
        .status()
        .expect("node runs (scripts/test installs it)");
    assert!(built.success(), "the simulator's page did not build");

    let port = free_port();
    let mut driver = Command::new("chromedriver");
    driver.arg(format!("--port={port}"));
    let (_driver, _) = start(driver, "started successfully");
    let runs: Vec<(u64, String, Result<Value, String>)> =
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime")
            .block_on(async {
                let mut client = open(port, &page).await;
                let mut runs = Vec::new();
                for seed in first..first + count {
                    let xml = model(seed, true);
                    let ran = match &client {
                        Err(e) => Err(e.clone()),
                        Ok(c) => c
                            .execute_async(
                                "const [xml, seed, limit, done] = arguments; \
                                 simulate(xml, seed, limit).then(done);",
                                vec![json!(xml), json!(seed), json!(TRIGGERS)],
                            )
                            .await
                            .map_err(|e| e.to_string()),
                    };
                    if ran.is_err() {
                        // A page whose script never returned answers nothing more: a new one.
                        if let Ok(c) = client {
                            let _ = c.close().await;
                        }
                        client = open(port, &page).await;
                    }
                    runs.push((seed, xml, ran));
                }
                if let Ok(c) = client {
                    let _ = c.close().await;
                }
                runs
            });

    // The simulator's runs, written as a corpus in the upstream format.
    let corpus = work.join("corpus");
    std::fs::create_dir_all(corpus.join("simulator")).expect("corpus dir");
    let mut scenarios = Vec::new();
    let mut refused = Vec::new();
    for (seed, xml, ran) in &runs {
        let run = match ran {
            Ok(v) if v.get("error").is_none() => v,
            Ok(v) => {
                refused.push(format!("seed {seed}: {}", v["error"]));
                continue;
            }
            Err(e) => {
                refused.push(format!("seed {seed}: {e}"));
                continue;
            }
        };
        let diagram = format!("Simulator.{seed}.bpmn");
        let fixture = format!("Simulator.{seed}.json");
        std::fs::write(corpus.join("simulator").join(&diagram), xml).expect("diagram");
        std::fs::write(
            corpus.join("simulator").join(&fixture),
            run["trace"].to_string(),
        )
        .expect("trace");
        let mut steps = run["steps"].as_array().cloned().unwrap_or_default();
        steps.push(json!({ "op": "expectTrace", "fixture": fixture }));
        scenarios.push(json!({
            "name": seed.to_string(), "diagram": diagram, "section": "generated", "steps": steps,
        }));
    }
    std::fs::write(
        corpus.join("scenarios.json"),
        serde_json::to_string_pretty(&scenarios).expect("json"),
    )
    .expect("scenarios");

    let results = token_sim::run_corpus(&corpus).expect("the corpus runs");
    let (mut deviations, mut races, mut differences) = (Vec::new(), Vec::new(), Vec::new());
    for r in &results {
        let Some(why) = &r.failure else { continue };
        let xml = std::fs::read_to_string(
            corpus
                .join("simulator")
                .join(format!("Simulator.{}.bpmn", r.name)),
        )
        .expect("diagram");
        if let Some(deviation) = r.deviation {
            deviations.push(format!("seed {}: {deviation}", r.name));
        } else if let throwers = throwers(&xml)
            && !throwers.is_empty()
            && (ordered(why, &throwers) || why.starts_with("nothing waits at"))
        {
            if std::env::var_os("TRACE_SIMULATED_RACES").is_some() {
                println!("{}", kept(&corpus, &r.name, why, &scenarios));
            }
            races.push(r.name.clone());
        } else {
            differences.push(kept(&corpus, &r.name, why, &scenarios));
        }
    }
    println!(
        "simulated: {count} models from seed {first}: {} run by the simulator, {} agree, {} reviewed deviations, {} differ only in order within a step; {} refused by the simulator",
        results.len(),
        results.len() - deviations.len() - races.len() - differences.len(),
        deviations.len(),
        races.len(),
        refused.len()
    );
    for d in &deviations {
        println!("  deviation {d}");
    }
    if !races.is_empty() {
        println!("  {RACE}: seeds {}", races.join(", "));
    }
    for r in &refused {
        println!("  refused {}", r.chars().take(160).collect::<String>());
    }
    assert!(differences.is_empty(), "{}", differences.join("\n"));
    // The simulator throws on a few models (a terminate inside a sub-process that compensation
    // keeps: "illegal transition: terminating -> compensable"); nearly all must run.
    assert!(
        refused.len() * 20 <= runs.len(),
        "the simulator refused {} of {} models",
        refused.len(),
        runs.len()
    );
}

/// A browser session on the simulator's page; a run that takes longer than [`SCRIPT`] is
/// given up.
async fn open(port: u16, page: &std::path::Path) -> Result<fantoccini::Client, String> {
    let c = session(port).await;
    c.update_timeouts(fantoccini::wd::TimeoutConfiguration::new(
        Some(SCRIPT),
        None,
        None,
    ))
    .await
    .map_err(|e| e.to_string())?;
    c.goto(&format!("file://{}", page.join("index.html").display()))
        .await
        .map_err(|e| format!("the page did not open: {e}"))?;
    Ok(c)
}

/// How long the simulator may take over one model.
const SCRIPT: std::time::Duration = std::time::Duration::from_secs(10);

/// The difference of order within a step (docs/engine-semantics.md, "Within a step"): the
/// simulator throws the moment it enters a throw event (a terminate ends everything that has not
/// yet moved; a catcher entered after the throw, in its order of work, misses it), and the engine
/// at the end of the throw's wave, once every other token of the wave has arrived. So, in a model
/// that throws, one of them moves a few elements further than the other, or each moves
/// differently only after a throw event was entered, or a catcher waits in one and not in the
/// other ([`ordered`]).
const RACE: &str = "order within a step: the simulator throws as it enters a throw event, the engine \
     at the end of the throw's wave";

/// Whether two traces differ as the order within a step makes them (the failure's two traces,
/// as the corpus runner prints them): one holds every element entry and exit of the other and
/// more, or what each holds beyond the other comes after one of `throwers` was entered in it.
fn ordered(why: &str, throwers: &std::collections::BTreeSet<String>) -> bool {
    let list = |label: &str| -> Option<Vec<String>> {
        let line = why
            .lines()
            .find_map(|l| l.trim_start().strip_prefix(label))?;
        serde_json::from_str(line.trim()).ok()
    };
    let within = |small: &[String], large: &[String]| {
        let mut large = large.to_vec();
        small.iter().all(|e| {
            large
                .iter()
                .position(|g| g == e)
                .map(|i| large.swap_remove(i))
                .is_some()
        })
    };
    let (Some(expected), Some(got)) = (list("expected"), list("got")) else {
        return false;
    };
    // Everything one trace has beyond the other comes after its first throw event was entered.
    let after_a_throw = |ours: &[String], theirs: &[String]| {
        let Some(first) = ours.iter().position(|e| {
            e.strip_prefix("enter:")
                .is_some_and(|id| throwers.contains(id))
        }) else {
            return false;
        };
        let mut rest = theirs.to_vec();
        ours.iter()
            .enumerate()
            .all(|(i, e)| match rest.iter().position(|g| g == e) {
                Some(k) => {
                    rest.swap_remove(k);
                    true
                }
                None => i > first,
            })
    };
    within(&expected, &got)
        || within(&got, &expected)
        || (after_a_throw(&expected, &got) && after_a_throw(&got, &expected))
}

/// The ids of the elements of `xml` that throw, by the engine's own rule
/// ([`executive_engine::throws`]): what acts at the end of its wave in the engine and as it is
/// entered in the simulator.
fn throwers(xml: &str) -> std::collections::BTreeSet<String> {
    use executive_model::NodeKind;
    let Some(g) = executive_model::load(xml.as_bytes()).graph else {
        return Default::default();
    };
    g.nodes
        .iter()
        .filter(|n| match &n.kind {
            NodeKind::Throw(defs) | NodeKind::End(defs) => executive_engine::throws(defs),
            _ => false,
        })
        .map(|n| n.id.clone())
        .collect()
}

/// A difference, its diagram and trace kept beyond the scratch directory to become a test.
fn kept(corpus: &std::path::Path, name: &str, why: &str, scenarios: &[Value]) -> String {
    let kept = std::env::temp_dir().join(format!("trace-simulated-{name}"));
    let _ = std::fs::remove_dir_all(&kept);
    let _ = std::fs::create_dir_all(&kept);
    for file in [
        format!("Simulator.{name}.bpmn"),
        format!("Simulator.{name}.json"),
    ] {
        let _ = std::fs::copy(corpus.join("simulator").join(&file), kept.join(&file));
    }
    let steps = scenarios
        .iter()
        .find(|s| s["name"] == name)
        .map(|s| s["steps"].to_string())
        .unwrap_or_default();
    format!("seed {name} ({}): {why}\n  steps {steps}", kept.display())
}
