//! `gcud`: the GCU router daemon (issue 5). Routing lives in `sagebrush-gcu`;
//! this binary wires it to serial ports and TCP links.

// Wiring to the router core lands with the router (issue 4); until then only
// `--check` reads the configuration.
#[allow(dead_code)]
mod config;
#[allow(dead_code)]
mod metrics;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

/// Exit code for a configuration error.
const EXIT_CONFIG: u8 = 2;

#[derive(Debug, Parser)]
#[command(name = "gcud", version, about = "Sagebrush GCU router daemon")]
struct Args {
    /// Configuration file (TOML).
    #[arg(long, short = 'c', value_name = "FILE")]
    config: PathBuf,
    /// Validate the configuration and exit (0 valid, 2 invalid).
    #[arg(long)]
    check: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let config = match config::load(&args.config) {
        Ok(config) => config,
        Err(e) => {
            eprintln!("gcud: {e}");
            return ExitCode::from(EXIT_CONFIG);
        }
    };
    if args.check {
        println!(
            "{}: valid: group {}, {} port(s), {} link(s), {} route(s)",
            config.file.display(),
            config.group,
            config.ports.len(),
            config.links.len(),
            config.routes.len()
        );
        return ExitCode::SUCCESS;
    }
    eprintln!("gcud: the daemon is not wired to the router core yet");
    ExitCode::FAILURE
}
