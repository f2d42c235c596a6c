//! One gimbal as a VISCA camera: what each message becomes for its gimbal
//! session (`sagebrush_client::session`). Inquiries are answered at once
//! from the session's poll (no bus time); drives go straight to the
//! session, whose motion rule coalesces them (newest wins per axis, for one
//! user; a stop overtakes; at most 8 callers wait, the older told at once),
//! each for the motion lease since VISCA drives have no time-out of their
//! own, answered Completion once in force (or superseded) and `90 61 41 FF`
//! with gcud's reason logged when refused; every other command is ACKed,
//! carried out in order by the camera's worker from a short queue (full:
//! "command buffer full"), then answered Completion or `90 61 41 FF` with
//! gcud's reason logged.
//! Anything not implemented is answered `90 60 02 FF` at once.
//!
//! Units: a VISCA position step is `degrees_per_step` degrees (pan right
//! and tilt up positive, as Sagebrush's Table 15); pan speeds `01`..`18`
//! and tilt speeds `01`..`14` are fractions of the fastest, onto the
//! gimbal's proportional speeds 0..=15 (Table 11); zoom positions
//! `0000`..`4000` onto the lens's 0..=4095, four VISCA steps a lens step
//! (Table 17); lens speeds 0..=7 onto 0..=9 (Table 16).

use std::sync::Arc;
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::connection::proportional_speed;
use sagebrush_client::session::{Drive, GimbalSession, Velocity};
use sagebrush_protocol::{Angle, Command as Bus, LensPosition, LensSpeed, U12};
use sagebrush_service::door_metrics::DoorMetrics;
use tokio::sync::mpsc;
use tracing::{info, warn};

use crate::config::Gimbal;
use crate::reply::Replier;
use crate::stats::{Stats, may_warn};
use crate::visca::{self, Command, Inquiry, LensDrive, MemoryOp, Message, Way};

/// Commands (other than drives) waiting for the worker; more are answered
/// "command buffer full".
pub const QUEUE: usize = 8;
/// VISCA zoom steps (CAM_Zoom direct, `0000` wide to `4000` optical tele)
/// per step of the lens's 0..=4095 (Table 17).
const ZOOM_STEP: u32 = 4;

/// A command for the worker.
#[derive(Debug)]
pub struct Job {
    command: Command,
    replier: Replier,
}

#[derive(Debug)]
pub struct Camera {
    pub config: Gimbal,
    pub session: Arc<GimbalSession>,
    /// How long a drive runs unless its client repeats it.
    lease: Duration,
    jobs: mpsc::Sender<Job>,
    pub stats: Arc<Stats>,
    /// The door's metrics: each message counted by its kind.
    pub metrics: Arc<DoorMetrics>,
}

/// The gimbal's proportional speed for VISCA speed `v` of at most `max`.
pub fn speed(v: u8, max: u8) -> sagebrush_protocol::Speed {
    proportional_speed(f64::from(v) / f64::from(max))
}

/// The lens speed (0..=9) for VISCA lens speed `p` (0..=7).
pub fn lens_speed(p: u8) -> LensSpeed {
    let n = (f64::from(p.min(visca::LENS_SPEED_MAX)) * 9.0 / 7.0).round() as u8;
    LensSpeed::new(n).unwrap_or(LensSpeed::new(LensSpeed::MAX).expect("in range"))
}

/// The velocity of a Pan-tiltDrive (VISCA `01` is left and up).
pub fn drive_velocity(pan_speed: u8, tilt_speed: u8, pan: Way, tilt: Way) -> Velocity {
    let p = speed(pan_speed, visca::PAN_SPEED_MAX);
    let t = speed(tilt_speed, visca::TILT_SPEED_MAX);
    Velocity {
        pan: Some(match pan {
            Way::First => Drive::Back(p),
            Way::Second => Drive::Forward(p),
            Way::Stop => Drive::Stop,
        }),
        tilt: Some(match tilt {
            Way::First => Drive::Forward(t),
            Way::Second => Drive::Back(t),
            Way::Stop => Drive::Stop,
        }),
        zoom: None,
    }
}

impl Camera {
    pub fn new(
        config: Gimbal,
        session: Arc<GimbalSession>,
        lease: Duration,
        stats: Arc<Stats>,
        metrics: Arc<DoorMetrics>,
    ) -> (Arc<Self>, mpsc::Receiver<Job>) {
        let (jobs, rx) = mpsc::channel(QUEUE);
        let camera = Arc::new(Self {
            config,
            session,
            lease,
            jobs,
            stats,
            metrics,
        });
        (camera, rx)
    }

    /// Posts a drive (or a stop: no axis moving) to the session for its
    /// client's user; the client hears Completion once it is in force or
    /// superseded, `90 61 41 FF` when gcud refuses it (its reason logged).
    fn drive(&self, velocity: Velocity, replier: Replier) {
        let outcome =
            self.session
                .acting_for(replier.user.as_deref())
                .post_velocity(velocity, Some(self.lease), "visca");
        let (name, stats) = (self.config.name.clone(), Arc::clone(&self.stats));
        tokio::spawn(async move {
            let result = outcome
                .await
                .unwrap_or_else(|_| Err(CommandError::Io("the gimbal's session ended".into())));
            match result {
                Ok(()) => replier.send(&visca::completion()),
                Err(e) => {
                    let total = Stats::count(&stats.not_executed);
                    if may_warn("drive not executed", &name) {
                        // gcud's decision (another controller, a limit): routine, in words.
                        info!(gimbal = %name, from = %replier.peer, total, reason = %e, "drive not executed: answered 90 61 41 FF");
                    }
                    replier.send(&visca::not_executable());
                }
            }
        });
    }

    /// Answers or carries out `message` from `replier`.
    pub fn handle(&self, message: Message, replier: Replier) {
        Stats::count(&self.stats.received);
        self.metrics.request(message.kind());
        let command = match message {
            Message::Inquiry(q) => return replier.send(&self.inquiry(q)),
            Message::Command(c) => c,
        };
        let lens = self.config.lens;
        match command {
            Command::IfClear => replier.send(&visca::clear_done()),
            Command::Power(true) => {
                replier.send(&visca::ack());
                replier.send(&visca::completion());
            }
            Command::Power(false) => self.refuse(&replier, "the door does not switch gimbals off"),
            Command::Memory(MemoryOp::Reset, n) => self.refuse(
                &replier,
                &format!("the gimbal keeps preset {n}: it can be stored again (Memory set), not erased"),
            ),
            Command::Drive {
                pan_speed,
                tilt_speed,
                pan,
                tilt,
            } => {
                replier.send(&visca::ack());
                self.drive(drive_velocity(pan_speed, tilt_speed, pan, tilt), replier);
            }
            Command::Zoom(d) if lens => {
                replier.send(&visca::ack());
                let zoom = match d {
                    LensDrive::Stop => Drive::Stop,
                    LensDrive::Up(p) => Drive::Forward(lens_speed(p)),
                    LensDrive::Down(p) => Drive::Back(lens_speed(p)),
                };
                let velocity = Velocity {
                    zoom: Some(zoom),
                    ..Velocity::default()
                };
                self.drive(velocity, replier);
            }
            Command::Zoom(_) | Command::ZoomTo(_) | Command::Focus(_) if !lens => {
                Stats::count(&self.stats.syntax);
                replier.send(&visca::syntax_error());
            }
            other => match self.jobs.try_reserve() {
                Ok(permit) => {
                    replier.send(&visca::ack());
                    permit.send(Job {
                        command: other,
                        replier,
                    });
                }
                Err(_) => {
                    Stats::count(&self.stats.busy);
                    replier.send(&visca::buffer_full());
                }
            },
        }
    }

    /// `90 61 41 FF` for a command the door does not carry out, and why.
    fn refuse(&self, replier: &Replier, why: &str) {
        let total = Stats::count(&self.stats.not_executed);
        if may_warn("command not executed", &self.config.name) {
            warn!(gimbal = %self.config.name, from = %replier.peer, total, reason = why, "command not executed: answered 90 61 41 FF");
        }
        replier.send(&visca::not_executable());
    }

    /// The answer to inquiry `q`, from the session's last poll.
    fn inquiry(&self, q: Inquiry) -> Vec<u8> {
        let status = self.session.status();
        let lens = status.lens.filter(|_| self.config.lens);
        let zoom = |l: LensPosition| u32::from(l.zoom.get()) * ZOOM_STEP;
        match q {
            Inquiry::Power => visca::answer(&[0x02]),
            Inquiry::MaxSpeed => visca::answer(&[visca::PAN_SPEED_MAX, visca::TILT_SPEED_MAX]),
            Inquiry::Version => {
                let (major, minor) = version();
                visca::answer(&[0x00, 0x00, 0x00, 0x00, major, minor, 0x01])
            }
            Inquiry::PanTiltPosition => match status.position {
                Some(p) => {
                    let steps = |a: Angle| {
                        let s = (f64::from(a.degrees()) / self.config.degrees_per_step).round();
                        s.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16 as u16 as u32
                    };
                    let mut data = visca::to_nibbles(steps(p.pan), 4);
                    data.extend(visca::to_nibbles(steps(p.tilt), 4));
                    visca::answer(&data)
                }
                None => self.unknown("the gimbal's position is not known yet (gcud or the gimbal did not answer)"),
            },
            Inquiry::ZoomPosition | Inquiry::FocusPosition | Inquiry::LensBlock if !self.config.lens => {
                Stats::count(&self.stats.syntax);
                visca::syntax_error()
            }
            Inquiry::ZoomPosition | Inquiry::FocusPosition | Inquiry::LensBlock => match lens {
                None => self.unknown("the lens's position is not known yet"),
                Some(l) if q == Inquiry::ZoomPosition => visca::answer(&visca::to_nibbles(zoom(l), 4)),
                Some(l) if q == Inquiry::FocusPosition => {
                    visca::answer(&visca::to_nibbles(u32::from(l.focus.get()), 4))
                }
                Some(l) => {
                    // Sony's lens control block: zoom, focus near limit,
                    // focus, then flags (manual focus, nothing running).
                    let mut data = visca::to_nibbles(zoom(l), 4);
                    data.extend([0x00, 0x00]);
                    data.extend(visca::to_nibbles(u32::from(l.focus.get()), 4));
                    data.extend([0x00, 0x00, 0x00]);
                    visca::answer(&data)
                }
            },
        }
    }

    /// `90 60 41 FF`: an inquiry the door cannot answer now.
    fn unknown(&self, why: &str) -> Vec<u8> {
        Stats::count(&self.stats.not_executed);
        if may_warn("inquiry not answered", &self.config.name) {
            warn!(gimbal = %self.config.name, reason = why, "inquiry not answered: 90 60 41 FF");
        }
        vec![visca::FROM_CAMERA, 0x60, 0x41, visca::TERMINATOR]
    }

    /// Carries out the queued commands in order until the queue closes.
    pub async fn work(self: Arc<Self>, mut jobs: mpsc::Receiver<Job>) {
        while let Some(job) = jobs.recv().await {
            match self.carry_out(job.command, &job.replier).await {
                Ok(()) => job.replier.send(&visca::completion()),
                Err(e) => self.refuse(&job.replier, &e.to_string()),
            }
        }
    }

    async fn carry_out(&self, command: Command, replier: &Replier) -> Result<(), CommandError> {
        let s = self.session.acting_for(replier.user.as_deref());
        match command {
            // VISCA's steps in degrees; the session's gotos in degrees do the rest.
            Command::Absolute { pan, tilt, .. } => {
                let step = self.config.degrees_per_step;
                s.go_to_degrees(Some(f64::from(pan) * step), Some(f64::from(tilt) * step))
                    .await
                    .map(drop)
            }
            Command::Relative { pan, tilt, .. } => {
                let step = self.config.degrees_per_step;
                s.go_by_degrees(f64::from(pan) * step, f64::from(tilt) * step)
                    .await
                    .map(drop)
            }
            // The gimbal has no re-initialisation a door may start: Reset returns it home.
            Command::Home | Command::Reset => s.home().await,
            Command::Memory(MemoryOp::Recall, n) => s.go_to_preset(n).await,
            Command::Memory(MemoryOp::Set, n) => {
                let reserved = self.session.rules().await.map(|r| r.reserved).unwrap_or_default();
                if reserved.contains(&n) {
                    return Err(CommandError::Usage(format!(
                        "preset {n} is gcud's (a park or a tour recalls it): store another"
                    )));
                }
                s.send(Bus::StorePreset(n)).await.map(drop)
            }
            Command::ZoomTo(z) => {
                let focus = self
                    .session
                    .status()
                    .lens
                    .map_or(U12::new(0).expect("in range"), |l| l.focus);
                let zoom = (u32::from(z) / ZOOM_STEP).min(u32::from(U12::MAX)) as u16;
                let zoom = U12::new(zoom).map_err(|e| CommandError::Usage(e.to_string()))?;
                s.send(Bus::LensGoTo(LensPosition { zoom, focus })).await.map(drop)
            }
            Command::Focus(LensDrive::Stop) => s.send(Bus::FocusStop).await.map(drop),
            Command::Focus(LensDrive::Up(p)) => {
                s.send(Bus::FocusSpeed(lens_speed(p))).await?;
                s.send(Bus::FocusFar).await.map(drop)
            }
            Command::Focus(LensDrive::Down(p)) => {
                s.send(Bus::FocusSpeed(lens_speed(p))).await?;
                s.send(Bus::FocusNear).await.map(drop)
            }
            other => Err(CommandError::Usage(format!(
                "{other:?} is not carried out by the worker"
            ))),
        }
    }
}

/// The door's version as CAM_VersionInq's ROM version (major, minor).
fn version() -> (u8, u8) {
    let mut parts = env!("CARGO_PKG_VERSION")
        .split('.')
        .map(|p| p.parse::<u8>().unwrap_or(0));
    (parts.next().unwrap_or(0), parts.next().unwrap_or(0))
}

/// How long a drive runs without being repeated.
pub fn lease(config: &crate::config::Config) -> Duration {
    config.lease.unwrap_or(crate::config::MAX_MOVE)
}
