//! `gimbalctl` against the real `gimbalsim` on a fresh pseudo-terminal per
//! test: every command family, exit codes, recovery from injected faults,
//! and encode/decode against golden vectors.

#[path = "../support/mod.rs"]
mod support;

mod arguments;
mod bus;
mod delivery;
mod jog;
mod output;
mod scan;
mod window;

use std::time::Duration;

use serde_json::Value;

use support::cli::At;
use support::cli::{DemoGcud, FakeBus, spawn_ctl, wait_output};
use support::{Sim, eventually, gimbalctl, gimbalctl_stdin};
