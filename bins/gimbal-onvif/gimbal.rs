//! One gimbal behind gcud, as gimbal-onvif drives it: its own connection
//! to gcud's client listener (which carries every motion, so gcud's
//! dead-man stops them if gimbal-onvif dies), the position polled with
//! `P?` so that GetStatus answers at once, and continuous moves that never
//! outlive their time-out.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use sagebrush_client::connection::{UNREACHABLE_POLL, proportional_speed};
use sagebrush_client::{CommandError, GimbalConnection};
use sagebrush_protocol::{Angle, Axis, Command, LensPosition, LensSpeed, Position, Speed, U12};
use tokio::time::Instant;
use tracing::{info, warn};

use crate::config;

/// What GetStatus reports, kept by the poller.
#[derive(Clone, Debug, Default)]
pub struct Status {
    /// The last `P?` answer.
    pub position: Option<Position>,
    /// Why the last poll failed, when it did.
    pub error: Option<String>,
    /// The last `V?` answer (gimbals with `zoom`).
    pub lens: Option<LensPosition>,
    /// The position changed between the last two polls.
    pub changing: bool,
}

pub use sagebrush_client::Identity;

/// A continuous motion in progress: which axes, and its number (a newer
/// move or a stop replaces it, so an older time-out stops nothing).
#[derive(Clone, Copy, Debug, Default)]
struct Motion {
    generation: u64,
    pan: bool,
    tilt: bool,
    zoom: bool,
}

#[derive(Debug)]
pub struct Gimbal {
    pub config: config::Gimbal,
    max_move: Duration,
    /// This gimbal's own connection to gcud, one command at a time.
    connection: tokio::sync::Mutex<GimbalConnection>,
    status: Mutex<Status>,
    motion: Mutex<Motion>,
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
    pub fn new(config: config::Gimbal, link: &config::Config) -> Arc<Self> {
        let connection = GimbalConnection::new(&link.gcud, link.source_group, config.address, link.nic_window);
        Arc::new(Self {
            config,
            max_move: link.max_move,
            connection: tokio::sync::Mutex::new(connection),
            status: Mutex::new(Status::default()),
            motion: Mutex::new(Motion::default()),
        })
    }

    /// Sends `command` over this gimbal's connection (opened when needed;
    /// dropped when it fails, so the next command opens a fresh one).
    pub async fn send(&self, command: &Command<'_>) -> Result<Option<Vec<u8>>, CommandError> {
        self.connection.lock().await.send(command).await
    }

    /// `P?` now.
    pub async fn position(&self) -> Result<Position, CommandError> {
        self.connection.lock().await.position().await
    }

    /// `V?`: the lens's zoom and focus (Table 17).
    pub async fn lens(&self) -> Result<LensPosition, CommandError> {
        self.connection.lock().await.lens().await
    }

    /// `V`: the lens to zoom `x` (0..=1 of its range), focus where it is.
    pub async fn zoom_to(&self, x: f64) -> Result<(), CommandError> {
        let focus = self.lens().await?.focus;
        let zoom =
            U12::new((x.clamp(0.0, 1.0) * ZOOM_MAX).round() as u16).map_err(|e| CommandError::Usage(e.to_string()))?;
        self.send(&Command::LensGoTo(LensPosition { zoom, focus }))
            .await
            .map(drop)
    }

    /// What the poller reads: the position, and the lens when there is one.
    async fn reading(&self) -> Result<(Position, Option<LensPosition>), CommandError> {
        let position = self.position().await?;
        let lens = if self.config.zoom {
            Some(self.lens().await?)
        } else {
            None
        };
        Ok((position, lens))
    }

    /// `D?`.
    pub async fn identity(&self) -> Result<Identity, CommandError> {
        self.connection.lock().await.identity().await
    }

    pub fn status(&self) -> Status {
        self.status.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// Whether a continuous motion is in progress.
    pub fn moving(&self) -> bool {
        let m = *self.motion.lock().unwrap_or_else(|p| p.into_inner());
        m.pan || m.tilt || m.zoom
    }

    /// Polls `P?` every `every` until the task is dropped; a gimbal that
    /// does not answer is asked again only after [`UNREACHABLE_POLL`], since
    /// each unanswered poll holds its bus for all of gcud's retries.
    pub async fn poll(self: Arc<Self>, every: Duration) {
        loop {
            let reading = self.reading().await;
            let failed = reading.is_err();
            {
                let mut s = self.status.lock().unwrap_or_else(|p| p.into_inner());
                match reading {
                    Ok((p, lens)) => {
                        s.changing = s.position.is_some_and(|old| old != p) || (s.lens.is_some() && s.lens != lens);
                        s.position = Some(p);
                        s.lens = lens;
                        s.error = None;
                    }
                    Err(e) => {
                        s.changing = false;
                        s.error = Some(e.to_string());
                    }
                }
            }
            tokio::time::sleep(if failed { UNREACHABLE_POLL.max(every) } else { every }).await;
        }
    }

    /// `GO` to a position in degrees (Table 15).
    pub async fn go_to(&self, pan: f64, tilt: f64) -> Result<(), CommandError> {
        let angle = |deg: f64| Angle::from_degrees(deg as f32).map_err(|e| CommandError::Usage(e.to_string()));
        self.end_motion();
        self.send(&Command::GoTo(Position::new(angle(pan)?, angle(tilt)?)))
            .await
            .map(drop)
    }

    /// `Pnn`: to a preset the gimbal stored (Table 11).
    pub async fn go_to_preset(&self, n: u8) -> Result<(), CommandError> {
        self.end_motion();
        self.send(&Command::GoToPreset(n)).await.map(drop)
    }

    /// `HO`: to the fixed home position.
    pub async fn go_home(&self) -> Result<(), CommandError> {
        self.end_motion();
        self.send(&Command::Home).await.map(drop)
    }

    /// The longest a continuous move runs.
    pub fn max_move(&self) -> Duration {
        self.max_move
    }

    /// A new motion number; the motion before it is over.
    fn end_motion(&self) -> Motion {
        let mut m = self.motion.lock().unwrap_or_else(|p| p.into_inner());
        let old = *m;
        *m = Motion {
            generation: old.generation + 1,
            ..Motion::default()
        };
        old
    }

    /// ContinuousMove: each axis with `Some(v)` starts at proportional speed
    /// |v| toward v's sign (`SPn`+`PR`/`PL`, `STn`+`TU`/`TD`; the zoom at lens
    /// speed `Zn`+`ZI`/`ZO`), or stops when v is 0; all are stopped after
    /// `timeout` (at most the configured maximum), unless another move or a
    /// stop came first.
    pub async fn continuous(
        self: &Arc<Self>,
        pan: Option<f64>,
        tilt: Option<f64>,
        zoom: Option<f64>,
        timeout: Option<Duration>,
    ) -> Result<(), CommandError> {
        let generation = self.end_motion().generation + 1;
        // end_motion made `generation` current; a stop or another move while
        // this one starts makes it stale.
        type Speed = fn(f64) -> Command<'static>;
        let axes: [(Option<f64>, Speed, Command<'static>, Command<'static>, Command<'static>); 3] = [
            (
                pan,
                |v| Command::SetSpeed(Axis::Pan, speed_of(v)),
                Command::PanRight,
                Command::PanLeft,
                Command::PanStop,
            ),
            (
                tilt,
                |v| Command::SetSpeed(Axis::Tilt, speed_of(v)),
                Command::TiltUp,
                Command::TiltDown,
                Command::TiltStop,
            ),
            (
                zoom,
                |v| Command::ZoomSpeed(lens_speed_of(v)),
                Command::ZoomIn,
                Command::ZoomOut,
                Command::ZoomStop,
            ),
        ];
        let mut moving = Motion {
            generation,
            ..Motion::default()
        };
        for (i, (v, speed, positive, negative, stop)) in axes.into_iter().enumerate() {
            let Some(v) = v else { continue };
            let sent = if v == 0.0 {
                self.send(&stop).await
            } else {
                match self.send(&speed(v)).await {
                    Ok(_) => self.send(if v > 0.0 { &positive } else { &negative }).await,
                    Err(e) => Err(e),
                }
            };
            if let Err(e) = sent {
                // Never leave one axis moving with no time-out: the move failed as a whole.
                if let Err(stop) = self.stop_motion(moving).await {
                    warn!(gimbal = %self.config.name, error = %stop, "stop after a failed move failed");
                }
                return Err(e);
            }
            let axis = match i {
                0 => &mut moving.pan,
                1 => &mut moving.tilt,
                _ => &mut moving.zoom,
            };
            *axis |= v != 0.0;
        }
        {
            let mut m = self.motion.lock().unwrap_or_else(|p| p.into_inner());
            if m.generation != generation {
                // A stop or another move replaced this one while it started.
                return Ok(());
            }
            *m = moving;
        }
        if moving.pan || moving.tilt || moving.zoom {
            let run = timeout.unwrap_or(self.max_move).min(self.max_move);
            let me = Arc::clone(self);
            tokio::spawn(async move {
                tokio::time::sleep_until(Instant::now() + run).await;
                let m = *me.motion.lock().unwrap_or_else(|p| p.into_inner());
                if m.generation == generation {
                    info!(gimbal = %me.config.name, ms = run.as_millis() as u64, "move time-out: stopping");
                    if let Err(e) = me.stop_motion(m).await {
                        warn!(gimbal = %me.config.name, error = %e, "the stop after a move's time-out failed");
                    }
                }
            });
        }
        Ok(())
    }

    /// Stops the axes of `m` that move (pan and tilt together).
    async fn stop_motion(&self, m: Motion) -> Result<(), CommandError> {
        self.stop(m.pan || m.tilt, m.zoom).await
    }

    /// Stop: the pan/tilt motors (`PS` and `TS`) and the zoom (`ZS`), each
    /// confirmed by its ACK; a stop that is not confirmed is sent once more,
    /// then an error.
    pub async fn stop(&self, pan_tilt: bool, zoom: bool) -> Result<(), CommandError> {
        self.end_motion();
        let stops = [
            (pan_tilt, Command::PanStop),
            (pan_tilt, Command::TiltStop),
            (zoom, Command::ZoomStop),
        ];
        let stops: Vec<Command<'_>> = stops
            .into_iter()
            .filter(|(wanted, _)| *wanted)
            .map(|(_, c)| c)
            .collect();
        self.connection.lock().await.stop(&stops).await
    }

    /// Stops what this gimbal-onvif started (at SIGTERM): a continuous move,
    /// or a positioning move still under way.
    pub async fn shutdown(&self) {
        if self.moving() || self.status().changing {
            if let Err(e) = self.stop(true, self.config.zoom).await {
                warn!(gimbal = %self.config.name, error = %e, "stop at shutdown failed");
            }
        }
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
