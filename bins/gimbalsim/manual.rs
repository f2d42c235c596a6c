//! What `man gimbalsim` says beyond the command line (sagebrush_host::man).

use sagebrush_host::man::{ExitStatus, Manual, logging_environment};

pub fn manual() -> Manual {
    Manual {
        files: Manual::pairs(&[
            (
                "/dev/pts/N",
                "The pseudo-terminal it attaches to by default (--pty), named on the first line of standard \
                 output; --link PATH makes a symlink to it, removed at a stop by SIGINT or SIGTERM.",
            ),
            (
                "/usr/lib/MULTIARCH/wireshark/plugins/sagebrush/sagebrush.lua",
                "The Wireshark and tshark dissector that decodes --capture files (MULTIARCH: x86_64-linux-gnu \
                 on amd64).",
            ),
        ]),
        signals: Manual::pairs(&[
            (
                "SIGINT, SIGTERM",
                "Stop: print one line of JSON statistics (stats {...}) on standard output, complete the \
                 --capture file, remove the --link symlink, exit 0.",
            ),
            (
                "SIGHUP, SIGUSR1",
                "Not handled: the process ends at once (the default action), without statistics.",
            ),
        ]),
        exit_status: ExitStatus::Codes(Manual::pairs(&[
            ("0", "Stopped by SIGINT or SIGTERM."),
            (
                "1",
                "The bus could not be attached or served (a serial device or address that cannot be opened).",
            ),
            (
                "2",
                "Bad arguments or an invalid bus description (the message names it).",
            ),
        ])),
        environment: logging_environment(),
    }
}
