//! Sans-IO model of Sagebrush pan-tilt gimbals speaking protocol rev 1.9:
//! what `gimbalsim` wraps in I/O, and what a daemon can embed in-process.
//!
//! - [`axis`], [`lens`]: motion physics (trapezoidal pan/tilt profiles,
//!   Tables 11-12; lens zoom/focus, Tables 16-17).
//! - [`gimbal`]: one gimbal's state behind every command, as a
//!   `DeviceHandler` of the protocol crate.
//! - [`bus`]: a line of gimbals, each behind a `DeviceEndpoint`: bytes in
//!   with their arrival time, [`bus::Outgoing`] bytes out with their due time.
//! - [`faults`]: seeded fault injection (dropped ACK, NAK, damaged byte,
//!   late answer, silence).
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
