//! What `man gimbalctl` (and each `gimbalctl-SUBCOMMAND` page) says beyond
//! the command line (sagebrush_host::man): files, signals, the exit codes
//! of [`EXIT_CODES`] and the environment.

use sagebrush_host::man::{ExitStatus, Manual};

use super::EXIT_CODES;

/// The Wireshark dissector as the package installs it, for `--capture` files.
const DISSECTOR: &str = "/usr/lib/MULTIARCH/wireshark/plugins/sagebrush/sagebrush.lua";

pub fn manual() -> Manual {
    Manual {
        files: vec![
            (
                DISSECTOR.to_owned(),
                "The Wireshark and tshark dissector that decodes --capture files, loaded for every user \
                 (MULTIARCH: x86_64-linux-gnu on amd64; tshark -G folders names the directory Global Lua \
                 Plugins)."
                    .to_owned(),
            ),
            (
                "/etc/gcud/gcud.toml".to_owned(),
                "gcud's configuration: the client link to give --tcp, its TLS files and the [[principal]] \
                 names a --tls-cert certificate must carry."
                    .to_owned(),
            ),
        ],
        signals: Manual::pairs(&[
            (
                "SIGINT, SIGTERM",
                "A motion with --for or --hold sends its stop and confirms it, then exits; scan prints what it \
                 found so far and exits 130 or 143; with --capture the capture file is completed first, then \
                 exit 130 or 143; watch ends on SIGINT as its normal end. Otherwise the process ends at once; \
                 through gcud, gcud's dead-man stops a motion the closed connection had started.",
            ),
            (
                "SIGHUP, SIGUSR1",
                "Not handled: the process ends (the default action), and through gcud the dead-man stops its \
                 motion.",
            ),
        ]),
        exit_status: ExitStatus::Table(EXIT_CODES),
        environment: Manual::pairs(&[(
            "RUST_LOG",
            "The log filter of the diagnostics on stderr; it wins over --log when set.",
        )]),
    }
}
