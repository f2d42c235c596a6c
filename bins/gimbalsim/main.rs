//! `gimbalsim`: a bus of virtual Sagebrush pan-tilt gimbals (protocol rev
//! 1.9) on a pseudo-terminal, a TCP listener or a serial device. The model
//! is `sagebrush-sim`; this binary only does I/O around it.

mod cli;
mod manual;
mod run;

use std::process::ExitCode;

use clap::{CommandFactory, Parser};

fn main() -> ExitCode {
    if let Some(code) = sagebrush_host::man::generate_if_asked(cli::Cli::command, manual::manual) {
        return code;
    }
    let cli = cli::Cli::parse();
    if let Err(e) = sagebrush_host::logging::init(&cli.log, cli.log_json) {
        sagebrush_host::errln!("gimbalsim: {e}");
        return ExitCode::from(2);
    }
    let config = match cli.bus_config() {
        Ok(config) => config,
        Err(e) => {
            sagebrush_host::errln!("gimbalsim: {e}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = sagebrush_sim::Bus::new(config.clone(), 0) {
        sagebrush_host::errln!("gimbalsim: {e}");
        return ExitCode::from(2);
    }
    let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(rt) => rt,
        Err(e) => {
            sagebrush_host::errln!("gimbalsim: cannot start the runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(run::run(cli, config)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            sagebrush_host::errln!("gimbalsim: {e}");
            ExitCode::from(1)
        }
    }
}
