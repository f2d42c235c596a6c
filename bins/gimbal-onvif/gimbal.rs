//! One gimbal behind gcud, as gimbal-onvif drives it: ONVIF's generic
//! spaces and velocities turned into Sagebrush terms for the gimbal's
//! session (`sagebrush_client::session`), which owns the connection to
//! gcud, the motion in progress with its Timeout, the stops and the
//! polled position GetStatus answers from.

use std::sync::Arc;
use std::time::Duration;

use sagebrush_client::connection::proportional_speed;
use sagebrush_client::door::DoorSessions;
use sagebrush_client::session::{Axes, Drive, GimbalSession, Motion, Velocity};
use sagebrush_client::{CommandError, Identity};
use sagebrush_protocol::{Command, LensPosition, LensSpeed, Position, Reply, Speed, U12};

use crate::config;

pub use sagebrush_client::session::Status;

#[derive(Debug)]
pub struct Gimbal {
    pub config: config::Gimbal,
    max_move: Duration,
    session: Arc<GimbalSession>,
}

/// Proportional speed (Table 11, 0..=15) for a generic velocity 0 < |v| <= 1.
pub fn speed_of(velocity: f64) -> Speed {
    proportional_speed(velocity)
}

/// Lens speed (Table 16, 0..=9) for a generic zoom velocity 0 < |v| <= 1.
pub fn lens_speed_of(velocity: f64) -> LensSpeed {
    let n = (velocity.abs() * 10.0).ceil().clamp(1.0, 10.0) as u8 - 1;
    LensSpeed::new(n).unwrap_or(LensSpeed::new(9).expect("in range"))
}

/// The lens's zoom range (Table 17, 12 bits) as ONVIF's generic 0..=1.
pub const ZOOM_MAX: f64 = 4095.0;

/// Generic position (-1..=1 over `travel`) to degrees, and back.
pub fn to_degrees(x: f64, travel: (f64, f64)) -> f64 {
    travel.0 + (x + 1.0) / 2.0 * (travel.1 - travel.0)
}

pub fn to_generic(degrees: f64, travel: (f64, f64)) -> f64 {
    (2.0 * (degrees - travel.0) / (travel.1 - travel.0) - 1.0).clamp(-1.0, 1.0)
}

impl Gimbal {
    /// The gimbal and its session (started here; `reach` is shared by
    /// every gimbal of this door).
    pub fn new(config: config::Gimbal, link: &config::Config, sessions: &DoorSessions) -> Arc<Self> {
        let session = sessions.start(&config.name, config.address, config.zoom, link.max_move);
        Arc::new(Self {
            config,
            max_move: link.max_move,
            session,
        })
    }

    /// Sends `command` (a preset to store) after the motions and stops,
    /// for ONVIF user `by` (ARCHITECTURE "Principals").
    pub async fn send(&self, command: &Command<'static>, by: &str) -> Result<Option<Vec<u8>>, CommandError> {
        self.session.acting_for(Some(by)).send(*command).await
    }

    /// Where the gimbal points now (the session's poll).
    pub async fn position(&self) -> Result<Position, CommandError> {
        self.session.position().await
    }

    /// `V?`: the lens's zoom and focus (Table 17).
    pub async fn lens(&self) -> Result<LensPosition, CommandError> {
        let payload = self.session.send(Command::QueryLens).await?.unwrap_or_default();
        match Reply::parse(&Command::QueryLens, &payload) {
            Ok(Reply::Lens(lens)) => Ok(lens),
            _ => Err(CommandError::BadReply(format!(
                "V? result {:?} is not a Table 17 lens position",
                String::from_utf8_lossy(&payload)
            ))),
        }
    }

    /// `V`: the lens to zoom `x` (0..=1 of its range), focus where it is.
    pub async fn zoom_to(&self, x: f64, by: &str) -> Result<(), CommandError> {
        let focus = self.lens().await?.focus;
        let zoom =
            U12::new((x.clamp(0.0, 1.0) * ZOOM_MAX).round() as u16).map_err(|e| CommandError::Usage(e.to_string()))?;
        self.send(&Command::LensGoTo(LensPosition { zoom, focus }), by)
            .await
            .map(drop)
    }

    /// gcud's rules of the gimbal (`~B`): its limits, zones and the presets
    /// gcud reserves.
    pub async fn rules(&self) -> Result<sagebrush_client::governance::Rules, CommandError> {
        self.session.rules().await
    }

    /// `D?`, asked once.
    pub async fn identity(&self) -> Result<Identity, CommandError> {
        self.session.identity().await
    }

    pub fn status(&self) -> Status {
        self.session.status()
    }

    /// ONVIF's MoveStatus of the pan/tilt: MOVING from the moment a move
    /// is accepted until the bus shows it ended (the session's motion
    /// truth, ARCHITECTURE "Front doors"), IDLE after a refused move or
    /// once another controller took the gimbal (GetStatus's Error names
    /// it), UNKNOWN while a stop is owed that gcud could not be reached for.
    pub fn move_status(status: &Status) -> &'static str {
        match status.motion {
            Motion::Idle => "IDLE",
            Motion::Moving => "MOVING",
            Motion::Unknown => "UNKNOWN",
        }
    }

    /// `GO` to a position in degrees (Table 15).
    pub async fn go_to(&self, pan: f64, tilt: f64, by: &str) -> Result<(), CommandError> {
        self.session
            .acting_for(Some(by))
            .go_to_degrees(Some(pan), Some(tilt))
            .await
            .map(drop)
    }

    /// `Pnn`: to a preset the gimbal stored (Table 11).
    pub async fn go_to_preset(&self, n: u8, by: &str) -> Result<(), CommandError> {
        self.session.acting_for(Some(by)).go_to_preset(n).await
    }

    /// `HO`: to the fixed home position.
    pub async fn go_home(&self, by: &str) -> Result<(), CommandError> {
        self.session.acting_for(Some(by)).home().await
    }

    /// The longest a continuous move runs.
    pub fn max_move(&self) -> Duration {
        self.max_move
    }

    /// ContinuousMove: each axis with `Some(v)` moves at proportional speed
    /// |v| toward v's sign (`SPn`+`PR`/`PL`, `STn`+`TU`/`TD`; the zoom at lens
    /// speed `Zn`+`ZI`/`ZO`), or stops when v is 0; whatever moves is
    /// stopped after `timeout` (at most the configured maximum), unless
    /// another move or a stop came first.
    pub async fn continuous(
        &self,
        pan: Option<f64>,
        tilt: Option<f64>,
        zoom: Option<f64>,
        timeout: Option<Duration>,
        by: &str,
    ) -> Result<(), CommandError> {
        let velocity = Velocity {
            pan: pan.map(|v| Drive::signed(v, speed_of)),
            tilt: tilt.map(|v| Drive::signed(v, speed_of)),
            zoom: zoom.map(|v| Drive::signed(v, lens_speed_of)),
        };
        self.session
            .acting_for(Some(by))
            .velocity(velocity, timeout, "ONVIF ContinuousMove")
            .await
    }

    /// Stop: the pan/tilt motors (`PS` and `TS`) and the zoom (`ZS`), sent
    /// before anything else and until the bus confirms them.
    pub async fn stop(&self, pan_tilt: bool, zoom: bool) -> Result<(), CommandError> {
        self.session
            .stop(Axes {
                pan: pan_tilt,
                tilt: pan_tilt,
                zoom,
            })
            .await
    }

    /// Stops what this gimbal-onvif started (at SIGTERM): a continuous move,
    /// or a positioning move still under way.
    pub async fn shutdown(&self) {
        self.session.shutdown().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic_spaces_map_linearly_onto_the_travel() {
        let travel = (-180.0, 180.0);
        assert_eq!(to_degrees(-1.0, travel), -180.0);
        assert_eq!(to_degrees(0.5, travel), 90.0);
        assert_eq!(to_generic(90.0, travel), 0.5);
        assert_eq!(to_generic(400.0, travel), 1.0);
        let tilt = (-30.0, 90.0);
        assert_eq!(to_degrees(0.0, tilt), 30.0);
        assert_eq!(speed_of(1.0).get(), 15);
        assert_eq!(speed_of(-0.01).get(), 0);
        assert_eq!(speed_of(0.5).get(), 7);
        assert_eq!(lens_speed_of(1.0).get(), 9);
        assert_eq!(lens_speed_of(0.05).get(), 0);
    }
}
