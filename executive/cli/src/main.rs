//! The `trace` command: thin entry point over the `executive` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The allocator: mimalloc, as in every TRACE binary. glibc's malloc gives the heap's top back to
/// the kernel after large frees, so a process loading models again and again (the studio, the
/// runtime's checks) faulted its pages back in on every load: 326,000 page faults for 100 loads of
/// a 10,000-node model against 19,000, medians of 25-28 ms a load against 20-22 ms, depending on the
/// order of frees. mimalloc keeps freed pages for reuse and is also cheaper per small allocation
/// (an engine step allocates a few strings per record entry).
///
/// Its settings for a process that runs for days: an arena is committed as it is used, not all
/// at once, and pages unused for a second go back to the kernel. With mimalloc's defaults
/// (arenas committed eagerly on Linux, which then keep every page they ever held) the executive
/// flying Europa held 75 MB resident at real time and 88 MB at 200,000x; with these, 26 MB and
/// 35 MB (`cargo bench -p elap-sim --bench flight`, `docs/benchmarks.md`). A second's delay keeps the pages of a burst of loads.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

const ALLOCATOR_SETTINGS: [(&str, &str); 2] = [
    ("MIMALLOC_ARENA_EAGER_COMMIT", "0"),
    ("MIMALLOC_PURGE_DELAY", "1000"),
];

/// Runs this program again with [`ALLOCATOR_SETTINGS`] where the environment lacks them:
/// mimalloc reads its options as it starts, before `main`, and setting them through its C API
/// would take the `unsafe` the workspace forbids. `exec` keeps the process id, the arguments
/// and the open files; a setting the environment already has is kept, and if `exec` fails the
/// program goes on with mimalloc's defaults.
fn settle_allocator() {
    use std::os::unix::process::CommandExt;
    let missing: Vec<_> = ALLOCATOR_SETTINGS
        .iter()
        .filter(|(k, _)| std::env::var_os(k).is_none())
        .collect();
    if missing.is_empty() {
        return;
    }
    let Ok(exe) = std::env::current_exe() else {
        return;
    };
    let mut args = std::env::args_os();
    let mut again = std::process::Command::new(exe);
    if let Some(name) = args.next() {
        again.arg0(name);
    }
    again.args(args);
    for (k, v) in missing {
        again.env(k, v);
    }
    let _failed = again.exec();
}

/// TRACE: model, verify and execute robotic missions written in BPMN 2.0.
#[derive(Parser)]
#[command(name = "trace", version = env!("TRACE_LONG_VERSION"), about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check mission models and list every problem (exit 0 valid, 1 invalid, 2 unreadable).
    Validate {
        /// BPMN files to check.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Print diagnostics as JSON for tools.
        #[arg(long)]
        json: bool,
        /// Enforce every rule of BPMN 2.0.2: warnings that name a rule the model bends
        /// harmlessly (an implicit end, an ignored condition, a missing scriptFormat, …) become
        /// errors.
        #[arg(long)]
        strict: bool,
        /// The connectors the mission runs with: tasks are checked against their catalogues
        /// as `trace run` checks them, and system data names count as written. Default:
        /// ../connectors.toml beside each model, if it exists.
        #[arg(long, value_name = "FILE")]
        connectors: Option<PathBuf>,
        /// Catalogue files or directories (default: ../catalogues and ../ground/forms.json
        /// beside each model, those that exist).
        #[arg(long = "catalogue", value_name = "PATH")]
        catalogues: Vec<PathBuf>,
    },
    /// Run a mission (or resume the one its store holds) until every instance ends.
    ///
    /// The run ends when every instance has ended, or when it is stuck: instances still run
    /// but nothing is awaited — no task in flight, no user task open, no timer armed, and no
    /// message, signal or condition that anything could still cause (today only system data
    /// comes from outside; messages and signals can come only from the mission itself, so
    /// they are awaited only while something else is). A stuck run prints its incidents
    /// (element and message) and the waits nothing can satisfy. A process whose only start
    /// events are message or signal starts is not started empty: it waits for its start
    /// message, and if nothing would start at all the run is refused, naming the start event.
    ///
    /// While only outside things are awaited (a user task, a message, a timer or scripted
    /// answer more than 5 s of wall time away, a task in flight longer than 5 s), it says on
    /// stderr (and in the log at info) what it waits for, where and since when (mission time):
    /// at once, then every --report-waiting seconds.
    ///
    /// Without outside systems (no --connectors, or only scripted ones) the mission clock is
    /// virtual: it jumps to the next deadline (a timer, a scripted answer) when nothing else can
    /// move, waiting its distance divided by --speed; the record is the same at any speed.
    ///
    /// Exit status: 0 every instance ended (each outcome is printed; also after Ctrl-C, which
    /// `trace resume` continues); 1 the run could not start or failed (model, store,
    /// connectors, variables); 3 stuck: nothing can move and nothing is awaited, or nothing
    /// would start.
    Run {
        /// The mission model.
        mission: PathBuf,
        #[command(flatten)]
        run: RunArgs,
        #[command(flatten)]
        start: StartArgs,
    },
    /// Fly a mission on this host: start the lander simulator and the policy ground responder
    /// as separate processes, run the executive against them over Zenoh, show progress, and
    /// end with a summary.
    Fly(executive_runtime::fly::FlyOptions),
    /// Resume the mission a store holds after a crash or reboot (exit status as `trace run`).
    Resume {
        #[command(flatten)]
        run: RunArgs,
    },
    /// Watch a running mission from any host on the Zenoh network: its present state, then
    /// every execution-record entry as it happens.
    Monitor {
        /// The mission id (default: the first executive found).
        #[arg(long)]
        mission: Option<String>,
        /// Print the record stream as JSON Lines (first line: the state snapshot).
        #[arg(long)]
        jsonl: bool,
        /// Stop after this many record lines.
        #[arg(long)]
        lines: Option<usize>,
        #[command(flatten)]
        zenoh: connector_zenoh::ZenohArgs,
    },
    /// Run a Zenoh router (for deployments across hosts, deploy/zenoh/two-hosts/): the zenoh
    /// library in router mode on a configuration file `zenohd -c` would read, with QUIC/TLS and
    /// access control as that file says; every operation access control refuses is logged as
    /// a warning. Runs until Ctrl-C or SIGTERM.
    Router {
        #[command(flatten)]
        zenoh: connector_zenoh::ZenohArgs,
    },
    /// Serve TRACE Studio, the mission composer, in the browser: open, draw, check and save the
    /// BPMN missions of DIR (default deploy/missions), with actions and typed inputs from the
    /// systems' catalogues — served live by the running systems over Zenoh, else read from
    /// files — and every task checked against them as `trace run` would. Listens on loopback
    /// only unless --public.
    Studio(StudioArgs),
    /// Write Camunda element templates from the systems' catalogues, for planners who draw in
    /// Camunda Modeler: one per action, for Camunda 7 and Camunda 8, with one typed field per
    /// goal and result field. Camunda Modeler reads them from `.camunda/element-templates/`
    /// beside a diagram or above it; what they write loads in `trace validate` and `trace run`.
    Templates(TemplatesArgs),
    /// Print this command's reference, every subcommand and flag, as Markdown: `docs/cli.md` is
    /// its output, and a test fails when they differ.
    #[command(hide = true)]
    CliReference,
    /// Print the catalogue a middleware's definitions give, as JSON: for the studio, `trace
    /// templates` and pre-flight checks of missions on systems that serve no catalogue.
    #[command(subcommand)]
    Catalogue(CatalogueKind),
    /// Verify a mission model with Spin before it flies: no deadlock, safeness, no dead
    /// activities, every run ends, no lost signal (exit 0 all hold, 1 violated, 2 incomplete
    /// or not verifiable).
    Verify(executive_runtime::verify::VerifyOptions),
    /// Replay an execution record on its mission model through the engine: every step read
    /// back into its input, the engine's lines checked against the record's, and the tokens
    /// after each step printed (or only after step --at).
    Replay {
        /// The mission model the record was run on.
        mission: PathBuf,
        /// The execution record (JSON Lines).
        record: PathBuf,
        /// Print only the state after this step.
        #[arg(long, value_name = "SEQ")]
        at: Option<u64>,
    },
    /// Write the execution record as a self-contained HTML timeline (opens offline).
    Timeline {
        /// The execution record (JSON Lines). Several records — the vehicles of a fleet, each
        /// `NAME=RECORD` (else named by its folder) — are drawn on one time axis.
        #[arg(required = true, num_args = 1.., value_name = "RECORD")]
        records: Vec<String>,
        /// The page to write.
        #[arg(short, long, default_value = "timeline.html")]
        output: PathBuf,
    },
    /// Run a public conformance corpus against the engine (exit 1 if a case fails).
    #[command(subcommand)]
    Conformance(Corpus),
}

/// What only a first start takes.
#[derive(clap::Args, Default)]
struct StartArgs {
    /// A start variable of every instance the run starts, `name=value` (repeatable): the value
    /// is read as JSON if it is JSON (`n=3`, `ok=true`, `site={"id":2}`, `s="3"`), else taken
    /// as text (`who=ana`). BPMN process data carries no type here, so values are taken as
    /// given; a data object or property marked isCollection must be given a list, and a name
    /// the process does not declare (when it declares any) is warned about. Wins over --vars.
    #[arg(long = "var", value_name = "NAME=VALUE")]
    vars: Vec<String>,
    /// Start variables from a JSON file holding one object (its fields are the variables).
    #[arg(long = "vars", value_name = "FILE")]
    vars_file: Option<PathBuf>,
    /// Mission time at the start, RFC 3339 (`2031-07-04T12:00:00Z`) or milliseconds since
    /// the Unix epoch; default: now. Timers, `now()` and the record count from it.
    #[arg(long, value_name = "TIME")]
    start_at: Option<String>,
}

#[derive(clap::Args)]
struct RunArgs {
    /// Configuration file (TOML; see deploy/executive.toml). Flags override it, and it
    /// overrides the built-in defaults; `TRACE_*` environment variables sit in between.
    #[arg(long)]
    config: Option<PathBuf>,
    /// The store directory (journal, snapshots, outbox); default `<mission>.store`.
    #[arg(long)]
    store: Option<PathBuf>,
    /// The execution record (JSON Lines); default `record.jsonl` in the store.
    #[arg(long)]
    record: Option<PathBuf>,
    /// Script for the in-process scripted connector (JSON); without one, activities complete
    /// at once.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Mission time runs this many times faster than wall time (default 1).
    #[arg(long)]
    speed: Option<f64>,
    /// Write an engine-state snapshot every this many steps (default 1000).
    #[arg(long)]
    snapshot_every: Option<u64>,
    /// Connector configuration (TOML; see deploy/connectors.toml): which connectors to load
    /// and which resources each serves. Without one, a scripted connector serves everything.
    #[arg(long)]
    connectors: Option<PathBuf>,
    /// Seconds to wait for each system's catalogue before refusing to start.
    #[arg(long, default_value_t = 10.0)]
    catalogue_wait: f64,
    /// While the run waits only on outside things, repeat what it waits for every this many
    /// seconds of wall time (it is said at once when the wait starts or changes); 0: never.
    #[arg(long, default_value_t = 30.0, value_name = "SECONDS")]
    report_waiting: f64,
    /// Run only this pool (id or name) of the model's collaboration, as one executive of a
    /// fleet: each other pool with a process must be run by its own `trace run --participant`
    /// in the same deployment, and messages along message flows between pools cross over
    /// Zenoh, exactly once. Kept in the store: `trace resume` runs the same pool.
    #[arg(long, value_name = "POOL")]
    participant: Option<String>,
    #[command(flatten)]
    zenoh: connector_zenoh::ZenohArgs,
}

#[derive(Subcommand)]
enum Corpus {
    /// A betsy-format corpus: model folders and an expectations file.
    Betsy {
        /// The corpus folder (holding `basics/`, `gateways/`, …).
        dir: PathBuf,
        /// The expectations file (JSON array of tests and cases).
        expectations: PathBuf,
    },
    /// A bpmn-js-token-simulation corpus: `scenarios.json` and `simulator/` diagrams and traces.
    TokenSimulation {
        /// The corpus folder.
        dir: PathBuf,
    },
}

fn logging(filter: &str, json: bool) {
    // RUST_LOG wins over the configured filter, as users expect of Rust tools.
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(filter));
    // Colours only on a terminal: a log redirected to a file stays plain text.
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr);
    if json {
        builder.json().init();
    } else {
        builder.init();
    }
}

/// The middlewares whose definitions `trace catalogue` reads.
#[derive(clap::Subcommand)]
enum CatalogueKind {
    /// ROS 2 actions: every `.action` definition under AMENT_PREFIX_PATH's `share/` and DIRs
    /// (prefixes, `share/` directories or package directories), one entry per action named by
    /// its type (`test_msgs/action/Fibonacci`); an unreadable definition is refused with its
    /// file and line.
    Ros2 {
        /// Further directories of definitions.
        dirs: Vec<PathBuf>,
        /// The catalogue's server name.
        #[arg(long, default_value = "ros2")]
        server: String,
    },
}

fn main() -> anyhow::Result<ExitCode> {
    settle_allocator();
    let cli = Cli::parse();
    if !matches!(
        cli.command,
        Command::Run { .. }
            | Command::Resume { .. }
            | Command::Fly { .. }
            | Command::Monitor { .. }
            | Command::Router { .. }
            | Command::Studio(_)
    ) {
        logging("warn", false);
    }
    match cli.command {
        Command::Validate {
            files,
            json,
            strict,
            connectors,
            catalogues,
        } => {
            let stdout = std::io::stdout();
            let systems = executive_runtime::validate::Systems {
                connectors,
                catalogues,
            };
            match executive_runtime::validate::run(
                &files,
                json,
                strict,
                &systems,
                &mut stdout.lock(),
            ) {
                Ok(verdict) => Ok(ExitCode::from(verdict.exit_code() as u8)),
                // The reader stopped reading (`trace validate … | head`): nothing left to say.
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(ExitCode::SUCCESS),
                Err(e) => Err(e.into()),
            }
        }
        Command::Run {
            mission,
            run,
            start,
        } => drive(Some(mission), run, start),
        Command::Resume { run } => drive(None, run, StartArgs::default()),
        Command::Fly(opts) => {
            logging("warn,zenoh=error", false);
            executive_runtime::fly::fly(&opts)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Monitor {
            mission,
            jsonl,
            lines,
            zenoh,
        } => {
            logging("warn,zenoh=error", false);
            let rt = one_worker()?;
            let mut stdout = std::io::stdout();
            rt.block_on(executive_runtime::monitor::watch(
                &zenoh,
                mission,
                jsonl,
                lines,
                &mut stdout,
            ))?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Router { zenoh } => {
            connector_zenoh::router::log_router();
            let rt = one_worker()?;
            rt.block_on(async {
                let (session, ready) = connector_zenoh::router::open(&zenoh).await?;
                println!("{ready}");
                let mut term =
                    tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
                tracing::info!("router stopping");
                session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
                anyhow::Ok(())
            })?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Studio(args) => studio(args),
        Command::Templates(args) => templates(args),
        Command::CliReference => {
            use clap::CommandFactory;
            print!("{}", clap_markdown::help_markdown_command(&Cli::command()));
            Ok(ExitCode::SUCCESS)
        }
        Command::Catalogue(CatalogueKind::Ros2 { dirs, server }) => {
            let defs = connector_ros2::Definitions::from_env(&dirs);
            match connector_ros2::definitions::catalogue(&defs, &server) {
                Ok(cat) => {
                    println!("{}", serde_json::to_string_pretty(&cat)?);
                    Ok(ExitCode::SUCCESS)
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    Ok(ExitCode::FAILURE)
                }
            }
        }
        Command::Verify(opts) => {
            let report = match executive_runtime::verify::verify(&opts) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("error: {e}");
                    return Ok(ExitCode::from(2));
                }
            };
            if opts.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                executive_runtime::verify::print(&report, &mut std::io::stdout().lock())?;
            }
            Ok(ExitCode::from(report.exit_code()))
        }
        Command::Replay {
            mission,
            record,
            at,
        } => {
            let loaded = executive_runtime::validate::load_file(
                &mission,
                &executive_model::Options::default(),
            )
            .map_err(|e| anyhow::anyhow!("{}: {e}", mission.display()))?;
            let graph = loaded.graph.ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: the mission model is invalid (trace validate)",
                    mission.display()
                )
            })?;
            let text = std::fs::read_to_string(&record)
                .map_err(|e| anyhow::anyhow!("{}: {e}", record.display()))?;
            let frames = executive_runtime::replay::replay(std::sync::Arc::new(graph), &text)
                .map_err(|e| anyhow::anyhow!("{}: {e}", record.display()))?;
            for f in frames.iter().filter(|f| at.is_none_or(|a| a == f.seq)) {
                let tokens: Vec<String> =
                    f.tokens.iter().map(|(e, n)| format!("{e} ×{n}")).collect();
                println!(
                    "{} {} {} | {}",
                    f.seq,
                    f.mission_ms,
                    f.what,
                    tokens.join(", ")
                );
            }
            if let Some(a) = at
                && !frames.iter().any(|f| f.seq == a)
            {
                anyhow::bail!("{}: no step {a}", record.display());
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Timeline { records, output } => {
            let t = match records.as_slice() {
                [one] => executive_runtime::timeline::write(std::path::Path::new(one), &output)
                    .map_err(|e| anyhow::anyhow!("{one}: {e}"))?,
                several => {
                    let named: Vec<(String, PathBuf)> = several
                        .iter()
                        .map(|r| match r.split_once('=') {
                            Some((name, path)) => (name.to_owned(), PathBuf::from(path)),
                            None => {
                                let path = PathBuf::from(r);
                                let name = path.parent().and_then(|d| d.file_name()).map_or_else(
                                    || r.clone(),
                                    |d| d.to_string_lossy().into_owned(),
                                );
                                (name, path)
                            }
                        })
                        .collect();
                    executive_runtime::timeline::write_fleet(&named, &output)?
                }
            };
            println!(
                "{}: {} lanes, {} bars, {} markers, {} plotted series{}",
                output.display(),
                t.lanes.len(),
                t.bars.len(),
                t.markers.len(),
                t.series.len(),
                if t.skipped > 0 {
                    format!(" ({} unreadable record lines skipped)", t.skipped)
                } else {
                    String::new()
                }
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Conformance(Corpus::Betsy { dir, expectations }) => {
            let stdout = std::io::stdout();
            let totals =
                executive_runtime::conformance::betsy(&dir, &expectations, &mut stdout.lock())?;
            Ok(verdict(totals))
        }
        Command::Conformance(Corpus::TokenSimulation { dir }) => {
            let stdout = std::io::stdout();
            let totals =
                executive_runtime::conformance::token_simulation(&dir, &mut stdout.lock())?;
            Ok(verdict(totals))
        }
    }
}

/// `trace studio`'s arguments.
#[derive(clap::Args)]
struct StudioArgs {
    /// The directory of mission files.
    #[arg(default_value = "deploy/missions")]
    dir: PathBuf,
    /// The address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    address: std::net::IpAddr,
    /// The port (0: any free one).
    #[arg(long, default_value_t = 7780)]
    port: u16,
    /// Listen on an address that is not loopback (the studio has no authentication).
    #[arg(long)]
    public: bool,
    /// Catalogue files, or directories of them (repeatable). Default: DIR/../catalogues and
    /// DIR/../ground/forms.json, as laid out in deploy/.
    #[arg(long = "catalogue", value_name = "PATH")]
    catalogues: Vec<PathBuf>,
    /// The connectors `trace run` would load: with them, tasks are also checked against the
    /// catalogues as `trace run` checks them. Default: DIR/../connectors.toml if it exists.
    #[arg(long, value_name = "FILE")]
    connectors: Option<PathBuf>,
    /// Do not join Zenoh: offer only the catalogue files.
    #[arg(long)]
    offline: bool,
    /// Also be ground station NAME: the operations view answers user tasks through it, judged
    /// by the executive like any station's (needs the ground forms, `server: "ground"`).
    #[arg(long, value_name = "NAME", conflicts_with = "offline")]
    station: Option<String>,
    /// How to reach the running systems, whose catalogues win over the files (as the
    /// deployment's other processes are configured: a router's client, or a peer).
    #[command(flatten)]
    zenoh: connector_zenoh::ZenohArgs,
}

/// `trace templates`' arguments.
#[derive(clap::Args)]
struct TemplatesArgs {
    /// The directory of mission files the templates are for.
    #[arg(default_value = "deploy/missions")]
    dir: PathBuf,
    /// Where to write them. Default: DIR/.camunda/element-templates.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Catalogue files, or directories of them (repeatable). Default: DIR/../catalogues.
    #[arg(long = "catalogue", value_name = "PATH")]
    catalogues: Vec<PathBuf>,
    /// The connectors, for resource names that differ from action names and for which
    /// servers are ground stations (no templates). Default: DIR/../connectors.toml if it exists.
    #[arg(long, value_name = "FILE")]
    connectors: Option<PathBuf>,
}

/// The catalogues asked for, else those laid out beside `dir` as in deploy/.
fn catalogue_paths(dir: &std::path::Path, asked: &[PathBuf]) -> Vec<PathBuf> {
    if !asked.is_empty() {
        return asked.to_vec();
    }
    let up = dir.join("..");
    [up.join("catalogues"), up.join("ground/forms.json")]
        .into_iter()
        .filter(|p| p.exists())
        .collect()
}

/// The connectors asked for, else DIR/../connectors.toml if it exists.
fn connectors_of(
    dir: &std::path::Path,
    asked: Option<PathBuf>,
) -> anyhow::Result<Option<connector_api::ConnectorsConfig>> {
    let path = asked.or_else(|| Some(dir.join("../connectors.toml")).filter(|p| p.exists()));
    Ok(match path {
        Some(p) => Some(executive_studio::read_connectors(&p)?),
        None => None,
    })
}

fn templates(args: TemplatesArgs) -> anyhow::Result<ExitCode> {
    let paths = catalogue_paths(&args.dir, &args.catalogues);
    let mut catalogues = executive_studio::read_catalogues(&paths)?;
    let connectors = connectors_of(&args.dir, args.connectors)?;
    catalogues.extend(
        connectors
            .iter()
            .flat_map(executive_runtime::catalogues::generated),
    );
    anyhow::ensure!(
        !catalogues.is_empty(),
        "no catalogue: pass --catalogue PATH (a system's catalogue: elap-sim --print-catalogue), or --connectors with ROS 2 connectors"
    );
    let out = args
        .out
        .unwrap_or_else(|| args.dir.join(".camunda/element-templates"));
    let written = executive_studio::templates::write(&catalogues, connectors.as_ref(), &out)
        .map_err(|e| anyhow::anyhow!("{}: {e}", out.display()))?;
    for f in &written {
        println!("{}", f.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn studio(args: StudioArgs) -> anyhow::Result<ExitCode> {
    logging("warn,zenoh=error", false);
    let paths = catalogue_paths(&args.dir, &args.catalogues);
    let mut catalogues = executive_studio::read_catalogues(&paths)?;
    if !executive_studio::has_page() {
        eprintln!(
            "warning: this trace was built without the studio's page (Node.js and npm were \
             missing): install them (Debian: apt-get install nodejs npm) and build again"
        );
    }
    let connectors = connectors_of(&args.dir, args.connectors.clone())?;
    catalogues.extend(
        connectors
            .iter()
            .flat_map(executive_runtime::catalogues::generated),
    );
    let rt = one_worker()?;
    rt.block_on(async {
        let live = if args.offline {
            None
        } else {
            Some(executive_studio::live::Live::join(&args.zenoh).await?)
        };
        let heard = live.as_ref().map_or(0, |l| l.heard().len());
        let ground = match (&args.station, &live) {
            (Some(id), Some(live)) => {
                let forms = catalogues
                    .iter()
                    .cloned()
                    .chain(live.heard())
                    .find(|c| c.server == "ground")
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--station {id} needs the ground forms: --catalogue deploy/ground/forms.json"
                        )
                    })?;
                let (station, requests) = ground_station::station::Station::start(
                    live.session(),
                    live.keys().clone(),
                    std::sync::Arc::new(forms),
                    id.clone(),
                    None,
                    None,
                )
                .await
                .map_err(|e| anyhow::anyhow!("--station {id}: {e}"))?;
                tokio::spawn(std::sync::Arc::clone(&station).serve(requests));
                Some(station)
            }
            _ => None,
        };
        let studio = executive_studio::Studio {
            dir: args.dir.clone(),
            catalogues,
            connectors,
            live,
            ground,
        };
        let addr = std::net::SocketAddr::new(args.address, args.port);
        let bound = executive_studio::bind(studio, addr, args.public).await?;
        let at = bound.addr()?;
        println!(
            "ready http://{at}/ — missions in {}, {} catalogue file(s), {}; Ctrl-C stops",
            args.dir.display(),
            paths.len(),
            if args.offline {
                "offline".to_owned()
            } else {
                format!("{heard} system(s) serving now")
            }
        );
        tokio::select! {
            r = bound.serve() => r?,
            _ = tokio::signal::ctrl_c() => {}
        }
        anyhow::Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}

/// A tokio runtime on one worker thread (Zenoh refuses the current-thread scheduler).
fn one_worker() -> std::io::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
}

fn verdict(totals: executive_runtime::conformance::Totals) -> ExitCode {
    if totals.failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// `trace run`'s exit status when the mission is stuck (or nothing would start).
const STUCK: u8 = 3;

/// The start variables and start time of `trace run`, and its waiting reports.
fn extras(
    start: StartArgs,
    report_waiting: f64,
) -> anyhow::Result<executive_runtime::driver::RunExtras> {
    let mut vars = match &start.vars_file {
        Some(p) => {
            executive_runtime::driver::read_vars(p).map_err(|e| anyhow::anyhow!("--vars {e}"))?
        }
        None => Default::default(),
    };
    for v in &start.vars {
        let (name, value) =
            executive_runtime::driver::parse_var(v).map_err(|e| anyhow::anyhow!("--var {e}"))?;
        vars.insert(name, value);
    }
    let start_at = match &start.start_at {
        None => None,
        Some(t) => Some(match t.parse::<i64>() {
            Ok(ms) => ms,
            Err(_) => chrono::DateTime::parse_from_rfc3339(t)
                .map_err(|e| anyhow::anyhow!("--start-at {t}: not RFC 3339 or milliseconds: {e}"))?
                .timestamp_millis(),
        }),
    };
    anyhow::ensure!(
        report_waiting.is_finite() && report_waiting >= 0.0,
        "--report-waiting {report_waiting} must be a number of seconds"
    );
    Ok(executive_runtime::driver::RunExtras {
        vars,
        start_at,
        report_every: (report_waiting > 0.0)
            .then(|| std::time::Duration::from_secs_f64(report_waiting.min(86_400.0))),
    })
}

fn drive(mission: Option<PathBuf>, args: RunArgs, start: StartArgs) -> anyhow::Result<ExitCode> {
    use executive_runtime::config::Settings;
    let mut settings = Settings::default();
    if let Some(path) = &args.config {
        settings = settings.with_file(path)?;
    }
    settings = settings.with_env(&|k| std::env::var(k).ok())?;
    logging(&settings.log_filter, settings.log_json);
    let zenoh = settings.zenoh(args.zenoh);
    let store = match (args.store.or(settings.store), &mission) {
        (Some(s), _) => s,
        (None, Some(m)) => executive_runtime::driver::default_store(m),
        (None, None) => {
            anyhow::bail!("trace resume needs --store DIR (or [store] dir, or TRACE_STORE)")
        }
    };
    let speed = args.speed.unwrap_or(settings.speed);
    anyhow::ensure!(
        speed.is_finite() && speed > 0.0,
        "--speed {speed} must be a positive number"
    );
    anyhow::ensure!(
        args.catalogue_wait.is_finite() && args.catalogue_wait >= 0.0,
        "--catalogue-wait {} must be a number of seconds",
        args.catalogue_wait
    );
    let snapshot_every = args.snapshot_every.unwrap_or(settings.snapshot_every);
    anyhow::ensure!(snapshot_every > 0, "--snapshot-every must be at least 1");
    let opts = executive_runtime::driver::RunOptions {
        model: mission,
        store,
        record: args.record.or(settings.record),
        script: args.script.or(settings.script),
        connectors: args.connectors.or(settings.connectors),
        zenoh,
        catalogue_wait: std::time::Duration::from_secs_f64(args.catalogue_wait.min(3600.0)),
        speed,
        snapshot_every,
        participant: args.participant,
    };
    let extras = extras(start, args.report_waiting)?;
    let summary = match executive_runtime::driver::run_with(&opts, &extras) {
        Ok(s) => s,
        Err(e @ executive_runtime::driver::RunError::NothingStarts(_)) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(STUCK));
        }
        Err(e) => return Err(e.into()),
    };
    for (instance, outcome) in &summary.outcomes {
        println!("instance {instance}: {outcome:?}");
    }
    if let Some(stuck) = &summary.stuck {
        for instance in &stuck.running {
            println!("instance {instance}: Stuck");
        }
        for i in &stuck.incidents {
            println!("  {i}");
        }
        for (item, why) in &stuck.dead {
            println!("  waits for {}: {why}", item.describe());
        }
    }
    for item in &summary.not_started {
        println!("not started: waited for {}", item.describe());
    }
    if let Some((pool, c)) = &summary.fleet {
        println!(
            "pool {pool}: messages sent {} delivered, {} refused; {} received",
            c.delivered, c.refused, c.received
        );
    }
    println!(
        "{} steps, {} reboots, record: {}{}",
        summary.steps,
        summary.reboots,
        summary.record.display(),
        if summary.interrupted {
            " (interrupted)"
        } else {
            ""
        }
    );
    if let Some(stuck) = &summary.stuck {
        eprintln!(
            "error: the mission is stuck: nothing can move and nothing is awaited ({} incidents, {} dead waits)",
            stuck.incidents.len(),
            stuck.dead.len()
        );
        return Ok(ExitCode::from(STUCK));
    }
    Ok(ExitCode::SUCCESS)
}
