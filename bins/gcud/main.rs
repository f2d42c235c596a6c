//! `gcud`: the GCU router daemon. The routing logic is the `sagebrush-gcu`
//! router core; this binary wires it to serial ports and TCP links
//! (ARCHITECTURE "Layers", 3 and 4).

mod admission;
mod capture;
mod config;
mod descriptors;
mod http;
mod io;
mod lines;
mod manual;
mod metric_families;
mod openmetrics;
mod reload;
mod router_task;
mod serial;
mod shard;
#[cfg(feature = "sim")]
mod simulated;
mod snapshot;
mod status;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{CommandFactory, Parser};
use sagebrush_service::door::{EXIT_CONFIG, EXIT_START};

#[derive(Debug, Parser)]
#[command(
    name = "gcud",
    version,
    about = "Sagebrush GCU router daemon (gimbal protocol rev 1.9)"
)]
struct Args {
    /// Configuration file (TOML): /etc/gcud/gcud.toml as packaged (config/gcud.toml in the source tree) documents every option.
    #[arg(long, short = 'c', value_name = "FILE")]
    config: PathBuf,
    /// Validate the configuration and exit: 0 valid, 2 invalid.
    #[arg(long)]
    check: bool,
    /// With --check: print what a reload (SIGHUP) of --config would change
    /// against this running configuration, without applying it; exit 2
    /// when the reload would be refused.
    #[arg(long, value_name = "RUNNING_FILE", requires = "check")]
    against: Option<PathBuf>,
}

/// Counts heap allocations for `gcud_heap_*` (module `snapshot`): the
/// data path's zero-allocation budget (ARCHITECTURE "Data path"), watched
/// in the field and by `cargo bench --bench gcud`.
#[global_allocator]
static HEAP: &stats_alloc::StatsAlloc<std::alloc::System> = &stats_alloc::INSTRUMENTED_SYSTEM;

fn main() -> ExitCode {
    if let Some(code) = sagebrush_host::man::generate_if_asked(Args::command, manual::manual) {
        return code;
    }
    let args = Args::parse();
    let config = match config::load(&args.config) {
        Ok(config) => config,
        Err(e) => {
            sagebrush_host::errln!("gcud: {e}");
            return ExitCode::from(EXIT_CONFIG);
        }
    };
    if args.check {
        let mut warnings = config.warnings.clone();
        if args.against.is_none() {
            // A running gcud holds its own addresses: no probe against it.
            warnings.extend(config.probe_listeners());
            warnings.extend(config.probe_serial_paths());
        }
        for w in &warnings {
            sagebrush_host::errln!("gcud: warning: {w}");
        }
    }
    if let Some(running) = &args.against {
        let running = match config::load(running) {
            Ok(running) => running,
            Err(e) => {
                sagebrush_host::errln!("gcud: {e}");
                return ExitCode::from(EXIT_CONFIG);
            }
        };
        let diff = reload::Diff::between(&running, &config);
        sagebrush_host::out!("{diff}");
        return match diff.needs_restart.is_empty() {
            true => ExitCode::SUCCESS,
            false => ExitCode::from(EXIT_CONFIG),
        };
    }
    if args.check {
        sagebrush_host::outln!(
            "{}: valid: group {}, {} port(s), {} link(s), {} route(s), {} governed gimbal(s), {} tour(s)",
            config.file.display(),
            config.gcu.group.get(),
            config.ports.len(),
            config.links.len(),
            config.routes.table.len(),
            config.governance.gimbals.len(),
            config.governance.tours.len()
        );
        return ExitCode::SUCCESS;
    }
    if let Err(e) = sagebrush_host::logging::init(config.log.filter(), false) {
        sagebrush_host::errln!("gcud: {e}");
        return ExitCode::from(EXIT_CONFIG);
    }
    for w in &config.warnings {
        tracing::warn!("{w}");
    }
    let descriptors = descriptors::Limit::raise();
    let http = http::Limits {
        max_connections: descriptors.http_connections(),
    };
    tracing::info!(
        was = descriptors.was,
        now = descriptors.now,
        http_connections = http.max_connections,
        "descriptor limit (RLIMIT_NOFILE)"
    );
    let lines = (config.ports.len() + config.links.len()) as u64;
    if let Some(needed) = descriptors.shortfall(config.limits.max_connections.get() as u64, lines, http.max_connections)
    {
        tracing::warn!(
            limit = descriptors.now,
            needed,
            "the descriptor limit is below what [limits] max_connections, the ports, links and HTTP endpoint may \
             hold open: connections beyond it wait to be accepted (raise LimitNOFILE)"
        );
    }
    // The router task yields after each bounded turn (router_task::Turn); the
    // I/O driver is polled every few scheduler ticks (61 by default), so
    // that a turn-by-turn flood cannot hide other sockets' readiness.
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .event_interval(4)
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            sagebrush_host::errln!("gcud: cannot start the async runtime: {e}");
            return ExitCode::from(EXIT_START);
        }
    };
    match runtime.block_on(router_task::run(config, http)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            sagebrush_host::errln!("gcud: {e}");
            ExitCode::from(EXIT_START)
        }
    }
}
