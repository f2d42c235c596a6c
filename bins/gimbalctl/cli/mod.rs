//! Command line of `gimbalctl`: transport, addressing, time-outs, and one
//! subcommand per command family of Tables 4, 11 and 16 and the rev 1.9 list.
//! Every argument names its unit and range; every subcommand has examples.
//!
//! Split by concern: this module holds the global options, the exit codes
//! and the shared `--wait` and `--for`/`--hold` arguments; `command.rs` the
//! subcommands (one per command family); `families.rs` the nested
//! subcommands and value enums; `values.rs` the parsers of argument values
//! (address, angles, rates, durations, ID lists).

use std::time::Duration;

use clap::{Args, Parser};
use sagebrush_host::transport::parse_baud;
use sagebrush_protocol::Address;

/// A subcommand's examples for its `after_help`: one `gimbalctl` line per
/// argument; a bare line talks to the demo's first gimbal through gcud
/// (`--tcp 127.0.0.1:4001 --to 5.1.1`), a line after `gimbalctl` is
/// written out whole.
macro_rules! examples {
    (@lines $(,)?) => { "" };
    (@lines gimbalctl $line:literal $(, $($rest:tt)*)?) => {
        concat!("\n  gimbalctl ", $line, examples!(@lines $($($rest)*)?))
    };
    (@lines $line:literal $(, $($rest:tt)*)?) => {
        concat!("\n  gimbalctl --tcp 127.0.0.1:4001 --to 5.1.1 ", $line, examples!(@lines $($($rest)*)?))
    };
    ($($line:tt)+) => {
        concat!("Examples:", examples!(@lines $($line)+))
    };
}

mod command;
mod families;
mod manual;
mod parse;
mod values;

pub use command::Cmd;
pub use families::*;
pub use manual::manual;
pub use parse::parse;
pub use values::*;

/// Exit code: `--wait` saw the mount stop away from its target.
pub const EXIT_STOPPED_SHORT: u8 = 20;
/// Exit code: `--wait` gave up while the mount was still moving.
pub const EXIT_WAIT_TIMEOUT: u8 = 21;
/// Exit code: the stop after `--for`/`--hold` was not acknowledged.
pub const EXIT_STOP_UNCONFIRMED: u8 = 22;

pub const EXIT_CODES: &str = "\
Exit codes:
   0  success
   1  I/O error: cannot open the serial port or connect, the line closed
   2  bad arguments (the message names the argument and its range)
   3  NAK after all retries (the command kept arriving damaged)
   4  no ACK after all retries (nothing answered; scan: no GCU or device answered D?)
   5  NIC: the device does not implement or cannot apply the command
   6  no result: acknowledged, but the result did not come in time
   7  malformed result: a result came that is not the command's
   8..19, 23..32  not delivered or refused, as the GCU reported it (through gcud):
       8 device silent (did not acknowledge)   9 device answered NAK to every try
      10 no such port on the GCU              11 port not open (port down)
      12 a queue on the way was full          13 no route to the group
      14 link toward the group down           15 the GCU is shutting down
      16 source group not allowed (--from)    17 routing loop
      18 not confirmed in time (may still execute)
      19 waited in a queue too long, given up unsent
      23 refused: another link of equal or higher priority controls the gimbal
      24 refused: the target lies outside the gimbal's travel limits
      25 refused: the path may enter a keep-out zone
      26 refused: the gimbal's position is unknown and it has limits or zones
      27 given up: a stop for the same gimbal overtook it in gcud's queue
      28 refused: gcud cannot bound it on a governed gimbal (allow it by name)
      29 refused: a stop from a link below the holder within a second of its last
      30 refused: a speed change whose rate is unknown while the gimbal slews
      31 refused: the gimbal did not say where the preset lies
      32 refused: the link's priority does not permit it (tours, rules)
  20  --wait: the mount stopped short of its target (limits? travel?)
  21  --wait: still moving when --wait-timeout ran out
  22  --for/--hold: the stop was not acknowledged (the mount may still move)
 130, 143  interrupted by SIGINT, SIGTERM (--capture: the file completed first; scan: what it
       found so far printed)
  Commands to device 255 get no ACK on a shared bus: success means written.";

/// Command Sagebrush pan-tilt gimbals (protocol rev 1.9) by hand.
///
/// Talks to a bus directly (--serial, or --tcp --direct to a device server,
/// as bus master) or to a GCU daemon (--tcp, as a client like the MCU).
/// Angles are degrees (positive = pan right, clockwise seen from above, and
/// tilt up), rates degrees per second. Every command to a device needs --to
/// GROUP.PORT.DEVICE.
#[derive(Debug, Parser)]
#[command(
    name = "gimbalctl",
    version,
    after_help = concat!(examples!("goto 45 -10 --wait", "slew right --for 2s", gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 position", gimbalctl "--tcp 127.0.0.1:4001 scan --devices 1-8"), "\n\nRun `gimbalctl help <SUBCOMMAND>` for a subcommand's arguments and examples."),
    after_long_help = EXIT_CODES
)]
pub struct Cli {
    #[command(flatten)]
    pub global: Global,
    #[command(subcommand)]
    pub command: Cmd,
}

#[derive(Debug, Args)]
pub struct Global {
    /// Serial device of the bus (this program is its master).
    #[arg(
        long,
        global = true,
        env = "GIMBALCTL_SERIAL",
        conflicts_with = "tcp",
        value_name = "PATH",
        help_heading = "Connection (global)"
    )]
    pub serial: Option<String>,
    /// Line rate of --serial in bit/s: 1200, 2400, 4800, 9600, 19200, 38400, 57600 or 115200.
    #[arg(long, global = true, default_value_t = 9600, value_parser = parse_baud, help_heading = "Connection (global)")]
    pub baud: u32,
    /// A GCU daemon's client address HOST:PORT, e.g. 127.0.0.1:4001 (this program is a client like the MCU), or tls://HOST:PORT with --tls-ca (and --tls-cert, --tls-key: your principal at gcud); with --direct a device server's.
    #[arg(long, global = true, env = "GIMBALCTL_TCP", value_name = "HOST:PORT", value_parser = parse_gcud, help_heading = "Connection (global)")]
    pub tcp: Option<String>,
    /// With --tcp tls://HOST:PORT: the CA that signed gcud's certificate (PEM).
    #[arg(
        long,
        global = true,
        env = "GIMBALCTL_TLS_CA",
        value_name = "FILE",
        help_heading = "Connection (global)"
    )]
    pub tls_ca: Option<std::path::PathBuf>,
    /// With --tcp tls://HOST:PORT: your client certificate (PEM); its subject CN is your principal at gcud.
    #[arg(
        long,
        global = true,
        env = "GIMBALCTL_TLS_CERT",
        value_name = "FILE",
        requires = "tls_key",
        help_heading = "Connection (global)"
    )]
    pub tls_cert: Option<std::path::PathBuf>,
    /// With --tls-cert: its private key (PEM).
    #[arg(
        long,
        global = true,
        env = "GIMBALCTL_TLS_KEY",
        value_name = "FILE",
        requires = "tls_cert",
        help_heading = "Connection (global)"
    )]
    pub tls_key: Option<std::path::PathBuf>,
    /// --tcp leads to a bus, not gcud (a device server such as ser2net, gimbalsim --tcp): this program is its master, asks gcud nothing (no ~W) and `scan` sweeps --bus.
    #[arg(long, global = true, help_heading = "Connection (global)")]
    pub direct: bool,
    /// Destination GROUP.PORT.DEVICE, each 0..255 (255 = wildcard at that level). Required by every command to a device.
    #[arg(long, global = true, value_parser = parse_address, value_name = "G.P.D", help_heading = "Addressing (global)")]
    pub to: Option<Address>,
    /// Source group address 0..254 (0 = the MCU).
    #[arg(
        long,
        global = true,
        default_value_t = 0,
        value_name = "G",
        help_heading = "Addressing (global)"
    )]
    pub from: u8,
    /// Record every byte of the line (both ways, timed) to FILE as pcapng for Wireshark with tools/wireshark/sagebrush.lua (docs/capture.md); SIGINT/SIGTERM complete the file, then exit 130/143.
    #[arg(long, global = true, value_name = "FILE", help_heading = "Output (global)")]
    pub capture: Option<std::path::PathBuf>,
    /// Print JSON (one object per line) instead of text; the README documents every shape.
    #[arg(long, global = true, help_heading = "Output (global)")]
    pub json: bool,
    /// Log filter for diagnostics on stderr (RUST_LOG syntax).
    #[arg(
        long,
        global = true,
        default_value = "warn,sagebrush_client::master=error",
        value_name = "FILTER",
        help_heading = "Output (global)"
    )]
    pub log: String,
    /// Retransmissions after the first, 0..255 (default 3).
    #[arg(long, global = true, value_name = "N", help_heading = "Time-outs (global)")]
    pub retries: Option<u8>,
    /// Wait for ACK/NAK, milliseconds (default derived from --baud; 1000 over TCP).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub ack_timeout: Option<u64>,
    /// Wait for a result after the ACK, milliseconds (default derived from --baud; 5000 over TCP).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub result_timeout: Option<u64>,
    /// Wait for a NIC after the ACK of a command without result, milliseconds.
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub nic_window: Option<u64>,
    /// Wait for the IX initialisation result, milliseconds (default 60000).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub init_timeout: Option<u64>,
}

// `--wait` and its time-out, shared by every positioning command. A plain
// comment, not a doc comment: clap takes a flattened struct's doc comment as
// the `about` of every subcommand that flattens it (`gimbalctl help goto`
// would show it instead of goto's own line); tests/cli_texts.rs checks.
#[derive(Debug, Clone, Copy, Args)]
pub struct WaitArgs {
    /// Poll until the motion ends; exit 20 if it stopped short of the target, 21 if still moving at --wait-timeout.
    #[arg(long)]
    pub wait: bool,
    /// Give up waiting after this many milliseconds, 1..=3600000.
    #[arg(long, default_value_t = 60_000, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=3_600_000))]
    pub wait_timeout: u64,
}

// `--for` / `--hold` of continuous motions (a plain comment, as above).
#[derive(Debug, Clone, Copy, Args)]
pub struct JogArgs {
    /// Move for DURATION (e.g. 2s, 2sec, 500ms, 1m; 1ms..=1h), then send the stop and confirm it.
    #[arg(long = "for", value_name = "DURATION", value_parser = parse_duration, conflicts_with = "hold")]
    pub duration: Option<Duration>,
    /// Keep the connection (and the motion) until Ctrl-C, SIGTERM or end of stdin, then stop and confirm (stdin from /dev/null ends it at once: use a terminal or a pipe).
    #[arg(long)]
    pub hold: bool,
}

#[cfg(test)]
mod tests {
    use clap::{Command, CommandFactory};

    use super::Cli;

    /// Every subcommand (`preset store`, `zoom in`, ...), `help` aside.
    fn subcommands(cmd: &Command) -> Vec<&Command> {
        let mut all = Vec::new();
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            all.push(sub);
            all.extend(subcommands(sub));
        }
        all
    }

    /// The subcommands' arguments are built only for the one parsed
    /// (`defer`); built, every subcommand at every depth takes the global
    /// arguments (`gimbalctl preset store 3 --to 5.1.1`).
    #[test]
    fn every_subcommand_built_takes_the_global_arguments() {
        let mut cli = Cli::command();
        cli.build();
        let all = subcommands(&cli);
        assert!(all.len() > 40, "{} subcommands", all.len());
        for sub in all {
            let ids: Vec<_> = sub.get_arguments().map(|a| a.get_id().as_str()).collect();
            for global in ["to", "tcp", "serial", "json", "from"] {
                assert!(ids.contains(&global), "`{}` lacks --{global}: {ids:?}", sub.get_name());
            }
        }
    }
}
