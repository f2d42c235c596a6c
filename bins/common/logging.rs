//! `tracing` set-up for the binaries: human or JSON lines on stderr, level
//! from a filter string (`RUST_LOG` syntax, e.g. `info,sagebrush_sim=debug`);
//! the `RUST_LOG` environment variable wins when set. Under systemd
//! (`JOURNAL_STREAM` set) lines carry no timestamp: the journal adds its own.

use std::io::IsTerminal;

use tracing_subscriber::EnvFilter;

/// Installs the global subscriber. `default_filter` applies when `RUST_LOG`
/// is unset; a malformed filter is reported, not ignored.
pub fn init(default_filter: &str, json: bool) -> Result<(), String> {
    let filter = match std::env::var("RUST_LOG") {
        Ok(env) if !env.is_empty() => EnvFilter::try_new(&env).map_err(|e| format!("RUST_LOG={env:?}: {e}"))?,
        _ => EnvFilter::try_new(default_filter).map_err(|e| format!("log filter {default_filter:?}: {e}"))?,
    };
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false);
    let journal = std::env::var_os("JOURNAL_STREAM").is_some();
    let result = match (json, journal) {
        (true, _) => builder.json().try_init(),
        (false, true) => builder.without_time().try_init(),
        (false, false) => builder.try_init(),
    };
    result.map_err(|e| format!("cannot install the logger: {e}"))
}
