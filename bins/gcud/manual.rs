//! What `man gcud` says beyond the command line (sagebrush_host::man):
//! the installed files, the signals (SIGHUP reloads, SIGUSR1 captures,
//! SIGTERM and SIGINT stop), the exit status and the environment.

use sagebrush_host::man::{ExitStatus, Manual, logging_environment};
use sagebrush_service::door::{EXIT_CONFIG, EXIT_START};

pub fn manual() -> Manual {
    let mut environment = logging_environment();
    environment.extend(Manual::pairs(&[(
        "NOTIFY_SOCKET",
        "Set by systemd (Type=notify): gcud reports READY, RELOADING on SIGHUP and STOPPING.",
    )]));
    Manual {
        files: Manual::pairs(&[
            (
                "/etc/gcud/gcud.toml",
                "The configuration as packaged (--config): every key is documented in it. Read at start and at \
                 every SIGHUP; check an edit with gcud --check --config /etc/gcud/gcud.toml.",
            ),
            (
                "/usr/lib/systemd/system/gcud.service",
                "The unit, installed but not enabled: systemctl enable --now gcud after editing the \
                 configuration; systemctl reload gcud sends SIGHUP.",
            ),
            (
                "/var/lib/gcud/",
                "The unit's state directory (StateDirectory=gcud), e.g. for a [capture] file such as \
                 /var/lib/gcud/gcud.pcapng.",
            ),
            (
                "/etc/udev/rules.d/99-sagebrush-gimbal.rules",
                "Stable names (/dev/gimbal-bus-N) and the dialout group for the buses' USB serial adapters.",
            ),
            (
                "/usr/share/doc/sagebrush/examples/demo.toml",
                "A configuration with simulated gimbals, no hardware needed (gcud --config it).",
            ),
        ]),
        signals: Manual::pairs(&[
            (
                "SIGHUP",
                "Reload the configuration file: it is read and checked as at start; a broken one, or one that \
                 changes what needs a restart, is refused and logged and the running configuration stays; \
                 otherwise the difference is applied (gcud --check --against shows it beforehand).",
            ),
            (
                "SIGUSR1",
                "Start a traffic capture with [capture] as the file reads now, or stop the running one \
                 (docs/capture.md).",
            ),
            (
                "SIGTERM, SIGINT",
                "Stop gracefully: new commands are refused, running motions are stopped, transactions in \
                 flight get up to [gcu] shutdown_grace_ms to finish, then gcud exits 0.",
            ),
        ]),
        exit_status: ExitStatus::Codes(vec![
            (
                "0".into(),
                "Stopped by SIGTERM or SIGINT; --check: the configuration is valid.".into(),
            ),
            (
                EXIT_START.to_string(),
                "Could not start: a link or metrics address that cannot be bound (in use), or the runtime.".into(),
            ),
            (
                EXIT_CONFIG.to_string(),
                "The configuration is invalid (file:line:column, the key and what was expected), or --check \
                 --against: the reload would be refused."
                    .into(),
            ),
        ]),
        environment,
    }
}
