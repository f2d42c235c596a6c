//! One gimbal behind gcud as the keyboards call it (`pelco_address`): its
//! session (`sagebrush_client::session`, which owns the connection to gcud,
//! the motion with its lease, the stops first), the presets a keyboard
//! cleared; the absolute moves (`4B`/`4D`) each name one axis, and the
//! session's goto in degrees keeps the other.

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex, MutexGuard};

use sagebrush_client::CommandError;
use sagebrush_client::door::DoorSessions;
use sagebrush_client::session::GimbalSession;
use sagebrush_protocol::Command;

use crate::config;

/// Which axis an absolute move sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisTo {
    Pan(f64),
    Tilt(f64),
}

#[derive(Debug)]
pub struct Gimbal {
    pub config: config::Gimbal,
    pub session: Arc<GimbalSession>,
    /// Presets a keyboard cleared (`05`): a go to one of them is not
    /// sent until it is set again. The gimbal keeps its presets (rev 1.9
    /// has no command to forget one), so this lasts until the door restarts.
    cleared: Mutex<BTreeSet<u8>>,
    /// The keyboard whose velocity the session holds (newest wins there:
    /// a keyboard whose velocity another's replaced is told the other's
    /// outcome, which is not its own).
    driver: Mutex<Option<Arc<str>>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Gimbal {
    pub fn new(config: config::Gimbal, door: &config::Config, sessions: &DoorSessions) -> Arc<Self> {
        let session = sessions.start(&config.name, config.address, config.zoom, door.max_move);
        Arc::new(Self {
            config,
            session,
            cleared: Mutex::default(),
            driver: Mutex::default(),
        })
    }

    /// The gimbal's pan and tilt in degrees for a keyboard's query: the
    /// session's last poll (at most `poll_ms` old, 250 ms while this door
    /// moves it) when that poll succeeded, so the answer comes within a
    /// keyboard's patience (`pyptzcontroller` waits 0.5 s); else `P?` now.
    pub async fn polled_position(&self) -> Result<(f64, f64), CommandError> {
        let status = self.session.status();
        match (status.position, status.error) {
            (Some(p), None) => Ok((f64::from(p.pan.degrees()), f64::from(p.tilt.degrees()))),
            _ => self.position().await,
        }
    }

    /// `P?` now: the gimbal's pan and tilt in degrees.
    pub async fn position(&self) -> Result<(f64, f64), CommandError> {
        let payload = self.session.send(Command::QueryPosition).await?.unwrap_or_default();
        let p = sagebrush_client::client::expect_position(&Command::QueryPosition, &payload)?;
        Ok((f64::from(p.pan.degrees()), f64::from(p.tilt.degrees())))
    }

    /// `Snn` for `principal`; the preset is no longer cleared once stored.
    pub async fn store_preset(&self, n: u8, principal: Option<&str>) -> Result<(), CommandError> {
        self.session.acting_for(principal).send(Command::StorePreset(n)).await?;
        lock(&self.cleared).remove(&n);
        Ok(())
    }

    /// Keyboard `who` posted the newest velocity.
    pub fn set_driver(&self, who: &Arc<str>) {
        *lock(&self.driver) = Some(Arc::clone(who));
    }

    /// Whether the newest velocity is keyboard `who`'s.
    pub fn is_driver(&self, who: &Arc<str>) -> bool {
        lock(&self.driver).as_ref().is_some_and(|d| Arc::ptr_eq(d, who))
    }

    /// Forgets preset `n` for the keyboards (`05`).
    pub fn clear_preset(&self, n: u8) {
        lock(&self.cleared).insert(n);
    }

    pub fn is_cleared(&self, n: u8) -> bool {
        lock(&self.cleared).contains(&n)
    }

    /// `GO` with one axis at `to`: the session keeps the other where the
    /// move asked before it aims while that one is asked or under way
    /// (the keyboard's pan, then its tilt), else where the gimbal is, and
    /// aims such gotos in the order they were asked.
    pub async fn go_to_axis(&self, to: AxisTo, principal: Option<&str>) -> Result<(), CommandError> {
        let (pan, tilt) = match to {
            AxisTo::Pan(p) => (Some(p), None),
            AxisTo::Tilt(t) => (None, Some(t)),
        };
        self.session
            .acting_for(principal)
            .go_to_degrees(pan, tilt)
            .await
            .map(drop)
    }
}
