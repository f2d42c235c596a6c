//! Host-side code shared by `gcud`, `gimbalctl` and `gimbalsim` (the
//! master side of an exchange, and the gcud client, are `sagebrush-client`):
//!
//! - [`backoff`]: the back-off of every line opened again after a failure.
//! - [`logging`]: `tracing` set-up (stderr, `RUST_LOG`-style filters, JSON).
//! - [`transport`]: serial ports (tokio-serial) and TCP links as byte
//!   streams ([`transport::SerialOrTcp`]), with errors that name the device.
//! - [`pty`]: a fresh pseudo-terminal pair whose master is an async stream
//!   (the simulator's virtual serial port).
//! - [`timing`]: time-outs derived from the line rate (1.4.2).
//! - [`sim_line`]: a simulated bus served on a byte stream.
//! - [`hex`]: hex text of wire bytes, as `gimbalctl encode/decode` use it.
//! - [`man`]: manual pages and shell completions from each program's clap
//!   definition.
//! - [`stdio`]: stdout/stderr writes that end quietly on a closed pipe.
//! - [`capture`]: pcapng capture of bus and link traffic for Wireshark
//!   (`docs/capture.md`, `tools/wireshark/sagebrush.lua`).

pub mod backoff;
pub mod capture;
pub mod hex;
pub mod logging;
pub mod man;
pub mod pty;
#[cfg(feature = "sim")]
pub mod sim_line;
pub mod stdio;
pub mod throttle;
pub mod timing;
pub mod tls;
pub mod transport;
