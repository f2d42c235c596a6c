//! One gimbal behind gcud as the keyboards call it (`pelco_address`): its
//! session (`sagebrush_client::session`, which owns the connection to gcud,
//! the motion with its lease, the stops first), the presets a keyboard
//! cleared, and the aim of the absolute moves (`4B`/`4D`), each of which
//! names one axis while the gimbal's `GO` takes both.

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use sagebrush_client::CommandError;
use sagebrush_client::door::DoorSessions;
use sagebrush_client::session::{GimbalSession, Motion};
use sagebrush_protocol::{Angle, Command, Position};

use crate::config;

/// The target of the last absolute move: the other axis of the next one
/// aims there while the gimbal is on its way (a keyboard sends the pan
/// then the tilt, 50 ms apart for `pyptzcontroller`).
#[derive(Clone, Copy, Debug)]
struct Aim {
    pan: f64,
    tilt: f64,
    at: Instant,
}

/// An aim younger than this is kept even before the session reports the
/// move under way (gcud not having acknowledged it yet).
const AIM_FRESH: Duration = Duration::from_secs(1);

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
    /// Absolute moves one at a time, each reading the last one's aim.
    aim: tokio::sync::Mutex<Option<Aim>>,
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
            aim: tokio::sync::Mutex::new(None),
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

    /// `GO` with one axis at `to` and the other where the last absolute
    /// move aimed it while that move is under way, else where the gimbal is.
    pub async fn go_to_axis(&self, to: AxisTo, principal: Option<&str>) -> Result<(), CommandError> {
        let mut aim = self.aim.lock().await;
        let moving = self.session.status().motion != Motion::Idle;
        let (pan, tilt) = match *aim {
            Some(a) if moving || a.at.elapsed() < AIM_FRESH => (a.pan, a.tilt),
            _ => self.position().await?,
        };
        let (pan, tilt) = match to {
            AxisTo::Pan(p) => (p, tilt),
            AxisTo::Tilt(t) => (pan, t),
        };
        let angle = |deg: f64| Angle::from_degrees(deg as f32).map_err(|e| CommandError::Usage(e.to_string()));
        let target = Position::new(angle(pan)?, angle(tilt)?);
        *aim = Some(Aim {
            pan,
            tilt,
            at: Instant::now(),
        });
        // Posted now (its first poll), waited for after the aim is released.
        let session = Arc::clone(&self.session);
        let principal = principal.map(str::to_owned);
        let mut go = Box::pin(async move { session.acting_for(principal.as_deref()).go_to(target).await });
        let first = crate::keyboard::poll_once(&mut go);
        drop(aim);
        match first {
            Some(done) => done,
            None => go.await,
        }
    }
}
