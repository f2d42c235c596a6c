//! What every program that commands gimbals shares, from a bus master
//! (`gimbalctl --serial`) to gcud's front doors (`gimbalctl --tcp`,
//! `gimbal-onvif`):
//!
//! - [`codec`]: the protocol crate's streaming framer as a tokio codec.
//! - [`master`]: the master side of one command exchange (Figure 6) over
//!   any stream, driving the protocol crate's `Transaction`.
//! - [`client`]: a connection to a bus or to gcud's client listener: send a
//!   command to an address and await its ACK, result or delivery report,
//!   each failure a [`client::CommandError`]; poll the position.
//! - [`connection`]: one gimbal behind gcud over a connection of its own,
//!   opened when needed and renewed after a failure; `P?` and `D?`.
//! - [`session`]: one gimbal as every front door drives it: the motion
//!   as one object with its deadline, stops first and owed until the bus
//!   confirms them, velocities coalesced, one cached poll.
//! - [`outcomes`]: what became of this process's commands, counted for
//!   a door's metrics.
//! - [`door`]: a front door for the shared start-up (its metrics counting
//!   these outcomes) and the sessions of its gimbals over its one link.
//! - [`governance`]: what gcud decides about its gimbals, asked of it
//!   (who controls a gimbal, release, tours): the GCU commands of port 0.
//!
//! Configuration files, a door's start-up and the bounded listener are
//! `sagebrush-service`'s, which gcud shares without this crate.

pub mod client;
pub mod codec;
pub mod connection;
pub mod door;
pub mod governance;
pub mod master;
pub mod outcomes;
pub mod presets;
pub mod session;

pub use client::{Client, CommandError, GcudClient};
pub use connection::{GimbalConnection, Identity};
