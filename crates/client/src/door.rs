//! What a front door's `main` does once its arguments are read
//! (ARCHITECTURE "Layers", `sagebrush-client`): load the configuration
//! (exit 2 with file:line:column on an error, as gcud), answer `--check`,
//! start logging and a two-thread runtime, and run the door (exit 1 when it
//! fails to start). Output goes through `sagebrush_host`'s quiet printing,
//! so a closed stdout or stderr is no panic.

use std::future::Future;
use std::path::Path;
use std::process::ExitCode;

use crate::config_file::ConfigError;

/// Exit code of a configuration error (`--check` or start-up), as gcud's.
pub const EXIT_CONFIG: u8 = 2;
/// Exit code of a failure to start (an address in use, a state file).
pub const EXIT_START: u8 = 1;

/// Runs the door `name` on the configuration at `file`: `load` reads it,
/// `summary` says what a valid one holds (`--check`), `run` serves until
/// the door stops.
pub fn main<C, Fut>(
    name: &str,
    file: &Path,
    check: bool,
    load: impl FnOnce(&Path) -> Result<C, ConfigError>,
    summary: impl FnOnce(&C) -> String,
    run: impl FnOnce(C) -> Fut,
) -> ExitCode
where
    Fut: Future<Output = Result<(), String>>,
{
    let config = match load(file) {
        Ok(c) => c,
        Err(e) => {
            sagebrush_host::errln!("{name}: {e}");
            return ExitCode::from(EXIT_CONFIG);
        }
    };
    if check {
        sagebrush_host::outln!("{}: valid ({})", file.display(), summary(&config));
        return ExitCode::SUCCESS;
    }
    if let Err(e) = sagebrush_host::logging::init("info", false) {
        sagebrush_host::errln!("{name}: {e}");
        return ExitCode::from(EXIT_CONFIG);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            sagebrush_host::errln!("{name}: cannot start the runtime: {e}");
            return ExitCode::from(EXIT_START);
        }
    };
    match runtime.block_on(run(config)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            sagebrush_host::errln!("{name}: {e}");
            ExitCode::from(EXIT_START)
        }
    }
}
