//! What a front door's `main` does (ARCHITECTURE "Layers",
//! `sagebrush-service`), once for every door: read its command line
//! (`--config FILE`, `--check`, the same for every door), load the
//! configuration (exit 2 with file:line:column on an error, as gcud),
//! answer `--check`, start logging and a two-thread runtime, catch the
//! signals that stop it, start its metrics (`[metrics] listen`,
//! [`crate::door_metrics`]), and run the door (exit 1 when it fails to
//! start). Output goes through `sagebrush_host`'s quiet printing, so a
//! closed stdout or stderr is no panic.

use std::future::Future;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{CommandFactory, FromArgMatches, Parser};

use sagebrush_host::man::{ExitStatus, Manual, logging_environment};

use crate::config_file::{self, ConfigError};
use crate::door_metrics::{CountFamily, DoorMetrics};

/// Exit code of a configuration error (`--check` or start-up), for gcud
/// and every door.
pub const EXIT_CONFIG: u8 = 2;
/// Exit code of a failure to start (an address in use, a state file).
pub const EXIT_START: u8 = 1;

/// A front door's command line.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    /// The configuration file (its help names the door's own).
    #[arg(long, value_name = "FILE")]
    config: PathBuf,
    /// Validate the configuration and exit: 0 valid, 2 invalid (file:line:column, key, what was expected).
    #[arg(long)]
    check: bool,
}

/// What `--check` says of a door's valid configuration.
pub trait Checked {
    /// What it holds, in a few words.
    fn summary(&self) -> String;

    /// What is absent now but may be there at start, each at its place
    /// (a serial device plugged in later): warnings, not errors.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

/// The door `name`'s command line, as its `--help` and manual page show it.
fn command(name: &'static str, about: &'static str) -> clap::Command {
    Args::command()
        .name(name)
        .bin_name(name)
        .about(about)
        .mut_arg("config", |a| {
            a.help(format!(
                "The configuration file (config/{name}.toml in the source tree, /etc/{name}/{name}.toml as packaged, documents every key)"
            ))
        })
}

/// What every door's manual page says beyond its command line
/// (`sagebrush_host::man`): a new door gets its page, with these sections,
/// from [`main`] alone.
fn manual(name: &str) -> Manual {
    let mut environment = logging_environment();
    environment.extend([
        (
            "STATE_DIRECTORY".to_owned(),
            format!(
                "Set by systemd for a unit with StateDirectory=: where {name} keeps presets.toml (unless \
                 state_file says otherwise) and a self-signed certificate."
            ),
        ),
        (
            "NOTIFY_SOCKET".to_owned(),
            format!("Set by systemd (Type=notify): {name} reports READY once it listens, and STOPPING."),
        ),
    ]);
    Manual {
        files: vec![
            (
                format!("/etc/{name}/{name}.toml"),
                format!(
                    "The configuration as packaged (--config), listening on loopback; every key is documented \
                     in it. Read at start only: systemctl restart {name} applies an edit; {name} --check \
                     --config /etc/{name}/{name}.toml checks it."
                ),
            ),
            (
                format!("/usr/lib/systemd/system/{name}.service"),
                format!("The unit, installed but not enabled: systemctl enable --now {name} (after gcud)."),
            ),
            (
                format!("/var/lib/{name}/"),
                format!(
                    "The unit's state directory when it has one ($STATE_DIRECTORY): presets.toml, the preset \
                     names; {name}-self-signed.crt and .key for [http] tls = \"self-signed\"."
                ),
            ),
        ],
        signals: vec![
            (
                "SIGTERM, SIGINT".to_owned(),
                format!("Stop: {name} tells systemd STOPPING, closes its listeners and exits 0."),
            ),
            (
                "SIGHUP".to_owned(),
                format!(
                    "Logged and otherwise ignored: {name} reads its configuration only at start (systemctl \
                     restart {name})."
                ),
            ),
            (
                "SIGUSR1".to_owned(),
                "Not handled: the process ends at once (the default action).".to_owned(),
            ),
        ],
        exit_status: ExitStatus::Codes(vec![
            (
                "0".to_owned(),
                "Stopped by SIGTERM or SIGINT; --check: the configuration is valid.".to_owned(),
            ),
            (
                EXIT_START.to_string(),
                "Could not start: an address in use, a state file that cannot be written.".to_owned(),
            ),
            (
                EXIT_CONFIG.to_string(),
                "The configuration is invalid: file:line:column, the key and what was expected.".to_owned(),
            ),
        ]),
        environment,
    }
}

/// A front door, as its start-up knows it.
#[derive(Debug, Clone, Copy)]
pub struct Door {
    /// Its program's name.
    pub name: &'static str,
    /// What it does, in its `--help`.
    pub about: &'static str,
    /// The families its metrics add to its requests and sessions
    /// (`sagebrush_client::outcomes::families`).
    pub families: fn() -> Vec<CountFamily>,
}

/// What a door's `run` is given by its start-up.
#[derive(Debug)]
pub struct Started {
    /// Its metrics, served when the configuration asks (`[metrics] listen`).
    pub metrics: Arc<DoorMetrics>,
    /// SIGTERM and SIGINT, caught since before it binds anything.
    pub signals: Signals,
}

/// Runs `door`: reads its command line, then reads the configuration
/// file, which `parse` validates (`--check` says what a valid one holds,
/// and warns), catches the signals, starts its metrics, and `run` serves
/// until the door stops.
pub fn main<C, Fut>(
    door: Door,
    parse: impl FnOnce(&Path, &str) -> Result<C, ConfigError>,
    run: impl FnOnce(C, Started) -> Fut,
) -> ExitCode
where
    C: Checked,
    Fut: Future<Output = Result<(), String>>,
{
    let Door { name, about, families } = door;
    if let Some(code) = sagebrush_host::man::generate_if_asked(|| command(name, about), || manual(name)) {
        return code;
    }
    let matches = command(name, about).get_matches();
    let args = Args::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let (file, check) = (args.config.as_path(), args.check);
    // `[metrics]` is the start-up's: read beside the door's own parse,
    // which checked it (`crate::door_link`).
    let parsed = config_file::read(file)
        .and_then(|text| Ok((parse(file, &text)?, crate::door_link::metrics_listen(file, &text)?)));
    let (config, metrics_listen) = match parsed {
        Ok(c) => c,
        Err(e) => {
            sagebrush_host::errln!("{name}: {e}");
            return ExitCode::from(EXIT_CONFIG);
        }
    };
    if check {
        for w in config.warnings() {
            sagebrush_host::errln!("{name}: warning: {w}");
        }
        sagebrush_host::outln!("{}: valid ({})", file.display(), config.summary());
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
    let start = async {
        let signals = Signals::install()?;
        let metrics = DoorMetrics::start(name, families(), metrics_listen).await?;
        run(config, Started { metrics, signals }).await
    };
    match runtime.block_on(start) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            sagebrush_host::errln!("{name}: {e}");
            ExitCode::from(EXIT_START)
        }
    }
}

/// SIGTERM and SIGINT, caught from before the door binds anything (so a
/// signal during start-up is not lost), and systemd's READY and STOPPING
/// around the wait for them. SIGHUP, which a daemon's operator sends to
/// reload, is logged and ignored (a door reads its configuration only at
/// start) rather than ending the door.
#[derive(Debug)]
pub struct Signals {
    term: tokio::signal::unix::Signal,
    int: tokio::signal::unix::Signal,
    hup: tokio::signal::unix::Signal,
}

impl Signals {
    /// Catches SIGTERM and SIGINT from now on.
    pub fn install() -> Result<Self, String> {
        use tokio::signal::unix::{SignalKind, signal};
        Ok(Self {
            term: signal(SignalKind::terminate()).map_err(|e| e.to_string())?,
            int: signal(SignalKind::interrupt()).map_err(|e| e.to_string())?,
            hup: signal(SignalKind::hangup()).map_err(|e| e.to_string())?,
        })
    }

    /// Tells systemd the door is ready, waits for SIGTERM or SIGINT, tells
    /// systemd it is stopping, and names the signal.
    pub async fn ready_then_wait(mut self) -> &'static str {
        let _ = sd_notify::notify(&[sd_notify::NotifyState::Ready]);
        let signal = loop {
            tokio::select! {
                _ = self.term.recv() => break "SIGTERM",
                _ = self.int.recv() => break "SIGINT",
                _ = self.hup.recv() => tracing::warn!(
                    "SIGHUP ignored: the configuration is read only at start; restart the door to apply an edit"
                ),
            }
        };
        let _ = sd_notify::notify(&[sd_notify::NotifyState::Stopping]);
        signal
    }
}
