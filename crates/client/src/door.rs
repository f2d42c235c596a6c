//! A front door's start with this crate (ARCHITECTURE "Front doors"): the
//! door as the start-up every door shares sees it
//! ([`sagebrush_service::door::main`]), with this crate's outcome counts
//! ([`crate::outcomes::families`]) as its metrics' families, and
//! [`DoorSessions`], the sessions of its gimbals over its one link to gcud.

use std::sync::Arc;
use std::time::Duration;

use sagebrush_protocol::Address;
use sagebrush_service::door::Door;

use crate::session::{GcudLink, GcudReachability, GimbalSession, SessionConfig};

/// Door `name` (`about`: what it does, in its `--help`) for the start-up
/// every door shares ([`sagebrush_service::door::main`]), its metrics
/// counting this crate's outcomes.
pub fn with_outcomes(name: &'static str, about: &'static str) -> Door {
    Door {
        name,
        about,
        families: crate::outcomes::families,
    }
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
