//! The `trace` command: thin entry point over the `executive` library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// TRACE: model, verify and execute robotic missions written in BPMN 2.0.
#[derive(Parser)]
#[command(name = "trace", version, about)]
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
    },
    /// Run a public conformance corpus against the engine (exit 1 if a case fails).
    #[command(subcommand)]
    Conformance(Corpus),
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

fn main() -> anyhow::Result<ExitCode> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match cli.command {
        Command::Validate { files, json } => {
            let stdout = std::io::stdout();
            let verdict = executive::validate::run(&files, json, &mut stdout.lock())?;
            Ok(ExitCode::from(verdict.exit_code() as u8))
        }
        Command::Conformance(Corpus::Betsy { dir, expectations }) => {
            let stdout = std::io::stdout();
            let totals = executive::conformance::betsy(&dir, &expectations, &mut stdout.lock())?;
            Ok(verdict(totals))
        }
        Command::Conformance(Corpus::TokenSimulation { dir }) => {
            let stdout = std::io::stdout();
            let totals = executive::conformance::token_simulation(&dir, &mut stdout.lock())?;
            Ok(verdict(totals))
        }
    }
}

fn verdict(totals: executive::conformance::Totals) -> ExitCode {
    if totals.failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
