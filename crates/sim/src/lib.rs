//! Sans-IO model of Sagebrush pan-tilt gimbals speaking protocol rev 1.9:
//! what `gimbalsim` wraps in I/O, and what a daemon can embed in-process.
//!
//! - [`axis`], [`lens`]: motion physics (trapezoidal pan/tilt profiles,
//!   Tables 11-12; lens zoom/focus, Tables 16-17).
//! - [`gimbal`]: one gimbal's state behind every command, as a
//!   `DeviceHandler` of the protocol crate.
//! - [`bus`]: a line of gimbals, each an unmodified `DeviceEndpoint` (the
//!   firmware's device code: framer, address filter, ACK/NAK/NIC, Table 3
//!   header, result resent on NAK) with a [`Gimbal`] as its handler; the
//!   bus is only the wire around them: bytes in with their arrival time,
//!   [`bus::Outgoing`] bytes out with their due time.
//! - [`faults`]: seeded fault injection on the wire's bytes (dropped ACK,
//!   command damaged in transit, damaged answer byte, late answer, a command
//!   not heard).
//!
//! Time is milliseconds as a `u64` the caller passes in; nothing here reads
//! a clock or does I/O.

pub mod aux;
pub mod axis;
pub mod bus;
pub mod config;
pub mod faults;
pub mod gimbal;
pub mod lens;

pub use bus::{Bus, BusConfig, BusStats, Outgoing};
pub use config::GimbalConfig;
pub use faults::{Fault, FaultConfig};
pub use gimbal::Gimbal;
