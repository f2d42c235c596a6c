//! Host-side code shared by `gcud`, `gimbalctl` and `gimbalsim`:
//!
//! - [`logging`]: `tracing` set-up (stderr, `RUST_LOG`-style filters, JSON).
//! - [`transport`]: serial ports (tokio-serial) and TCP links as byte
//!   streams ([`transport::SerialOrTcp`]), with errors that name the device.
//! - [`pty`]: a fresh pseudo-terminal pair whose master is an async stream
//!   (the simulator's virtual serial port).
//! - [`timing`]: time-outs derived from the line rate (1.4.2).
//! - [`master`]: the bus/link master side of one command exchange (Figure
//!   6) over any stream, driving the protocol crate's `Transaction`.
//! - [`sim_line`]: a simulated bus served on a byte stream.
//! - [`hex`]: hex text of wire bytes, as `gimbalctl encode/decode` use it.
//! - [`capture`]: pcapng capture of bus and link traffic for Wireshark
//!   (`docs/capture.md`, `tools/wireshark/sagebrush.lua`).

pub mod capture;
pub mod codec;
pub mod hex;
pub mod logging;
pub mod master;
pub mod pty;
#[cfg(feature = "sim")]
pub mod sim_line;
pub mod timing;
pub mod transport;
