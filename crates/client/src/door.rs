//! A front door's start with this crate (ARCHITECTURE "Front doors"): its
//! `main`, the start-up every door shares
//! ([`sagebrush_service::door::main`]) with this crate's outcome counts
//! ([`crate::outcomes::families`]) as its metrics' families, and
//! [`DoorSessions`], the sessions of its gimbals over its one link to gcud.

use std::future::Future;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use sagebrush_protocol::Address;
use sagebrush_service::config_file::ConfigError;
use sagebrush_service::door::{Checked, Door, Started};

use crate::session::{GcudLink, GcudReachability, GimbalSession, SessionConfig};

/// Runs door `name` (`about`: what it does, in its `--help`): its
/// configuration read by `parse`, then `run` until it stops
/// ([`sagebrush_service::door::main`]).
pub fn main<C, Fut>(
    name: &'static str,
    about: &'static str,
    parse: impl FnOnce(&Path, &str) -> Result<C, ConfigError>,
    run: impl FnOnce(C, Started) -> Fut,
) -> ExitCode
where
    C: Checked,
    Fut: Future<Output = Result<(), String>>,
{
    let door = Door {
        name,
        about,
        families: crate::outcomes::families,
    };
    sagebrush_service::door::main(door, parse, run)
}

/// The sessions of a door's gimbals: one link to gcud, one poll period,
/// one account of whether gcud answers.
#[derive(Debug, Clone)]
pub struct DoorSessions {
    link: GcudLink,
    poll: Duration,
    reach: Arc<GcudReachability>,
}

impl DoorSessions {
    /// Sessions over `link` that poll every `poll`.
    pub fn new(link: &GcudLink, poll: Duration) -> Self {
        Self {
            link: link.clone(),
            poll,
            reach: Arc::default(),
        }
    }

    /// The session of gimbal `name` at `address`, started: `lens`, it
    /// polls the lens too; `max_move`, the longest a motion runs unless
    /// renewed.
    pub fn start(&self, name: &str, address: Address, lens: bool, max_move: Duration) -> Arc<GimbalSession> {
        let config = SessionConfig {
            link: self.link.clone(),
            address,
            poll: self.poll,
            lens,
            max_move,
            name: name.to_owned(),
        };
        GimbalSession::start(config, Arc::clone(&self.reach))
    }
}
