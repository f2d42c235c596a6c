//! One gimbal as a MAVLink gimbal manager and gimbal device: a task that
//! owns its connection to gcud (so gcud's dead-man stops its motions if
//! this program dies), carries out requests one at a time in arrival
//! order, polls `P?` for the attitude status, and stops a rate that was
//! not refreshed within the lease (UDP has no connection whose loss could
//! stop it).

use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::common::{
    COMMAND_ACK_DATA, GIMBAL_DEVICE_INFORMATION_DATA, GIMBAL_MANAGER_INFORMATION_DATA, GimbalDeviceCapFlags,
    GimbalDeviceCapFlagsU16, GimbalManagerCapFlags, MavCmd, MavMessage, MavResult,
};
use sagebrush_client::connection::UNREACHABLE_POLL;
use sagebrush_client::{CommandError, GimbalConnection, Identity};
use sagebrush_protocol::{Angle, Axis, Command, Position};
use tokio::sync::mpsc;
use tokio::time::Instant;
use tracing::{info, warn};

use crate::config::{self, Config};
use crate::control::{Control, Refused, Sender};
use crate::link::Outbox;
use crate::motion::{self, Plan};
use crate::stats::Stats;

/// Requests waiting for one gimbal; more are refused as busy.
pub const QUEUE: usize = 64;

/// What the emitter reports, kept by the gimbal task.
#[derive(Clone, Debug, Default)]
pub struct Shared {
    pub position: Option<Position>,
    /// The last poll failed.
    pub unreachable: bool,
    pub control: Control,
}

/// A request for one gimbal.
#[derive(Clone, Debug)]
pub enum Work {
    /// Pitch/yaw (GIMBAL_MANAGER_SET_PITCHYAW, _SET_ATTITUDE, or the
    /// command, which `ack` names).
    Move {
        request: motion::Request,
        ack: Option<MavCmd>,
    },
    /// MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE params 1..4.
    Configure([f32; 4]),
    /// MAV_CMD_REQUEST_MESSAGE for a message id.
    Information(u32),
    /// The program stops: stop the slew in force, then end the task.
    Shutdown,
}

#[derive(Clone, Debug)]
pub struct Job {
    pub from: Sender,
    pub work: Work,
}

/// The handle the receivers use.
#[derive(Debug, Clone)]
pub struct Handle {
    pub config: config::Gimbal,
    pub shared: Arc<Mutex<Shared>>,
    pub jobs: mpsc::Sender<Job>,
}

impl Handle {
    pub fn shared(&self) -> Shared {
        self.shared.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// The rates in force (degrees per second, 0 when the axis is not slewing).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Slew {
    pan: f64,
    tilt: f64,
}

struct Task {
    config: config::Gimbal,
    connection: GimbalConnection,
    shared: Arc<Mutex<Shared>>,
    outbox: Arc<Outbox>,
    stats: Arc<Stats>,
    lease: Duration,
    slew: Slew,
    /// When the rates in force end unless refreshed.
    lease_end: Option<Instant>,
    identity: Option<Identity>,
}

/// Starts the task of gimbal `g`; it ends when every handle is dropped.
pub fn spawn(
    g: &config::Gimbal,
    config: &Config,
    outbox: Arc<Outbox>,
    stats: Arc<Stats>,
) -> (Handle, tokio::task::JoinHandle<()>) {
    let (tx, rx) = mpsc::channel(QUEUE);
    let shared = Arc::new(Mutex::new(Shared::default()));
    let task = Task {
        config: g.clone(),
        connection: GimbalConnection::new(&config.gcud, config.source_group, g.address, config.nic_window),
        shared: Arc::clone(&shared),
        outbox,
        stats,
        lease: config.lease,
        slew: Slew::default(),
        lease_end: None,
        identity: None,
    };
    let join = tokio::spawn(task.run(rx, config.attitude_period));
    (
        Handle {
            config: g.clone(),
            shared,
            jobs: tx,
        },
        join,
    )
}

/// COMMAND_ACK of `command` to `to`: the one answer builder for every refusal and result.
pub fn ack(command: MavCmd, result: MavResult, to: Sender) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result,
        target_system: to.0,
        target_component: to.1,
        ..COMMAND_ACK_DATA::DEFAULT
    })
}

impl Task {
    fn update(&self, f: impl FnOnce(&mut Shared)) {
        f(&mut self.shared.lock().unwrap_or_else(|p| p.into_inner()));
    }

    fn control(&self) -> Control {
        self.shared.lock().unwrap_or_else(|p| p.into_inner()).control
    }

    async fn run(mut self, mut jobs: mpsc::Receiver<Job>, poll: Duration) {
        let mut next_poll = Instant::now();
        loop {
            let lease_end = self.lease_end;
            tokio::select! {
                job = jobs.recv() => match job {
                    Some(Job { work: Work::Shutdown, .. }) => {
                        self.stop_slew("shutting down").await;
                        return;
                    }
                    Some(job) => self.handle(job).await,
                    None => {
                        self.stop_slew("shutting down").await;
                        return;
                    }
                },
                () = tokio::time::sleep_until(lease_end.unwrap_or_else(Instant::now)), if lease_end.is_some() => {
                    self.stop_slew("rate lease expired").await;
                }
                () = tokio::time::sleep_until(next_poll) => {
                    let reading = self.connection.position().await;
                    let failed = reading.is_err();
                    self.update(|s| {
                        s.unreachable = failed;
                        if let Ok(p) = reading {
                            s.position = Some(p);
                        }
                    });
                    next_poll = Instant::now() + if failed { UNREACHABLE_POLL.max(poll) } else { poll };
                }
            }
        }
    }

    async fn reply(&self, message: MavMessage) {
        self.outbox.send(self.config.component_id, &message).await;
    }

    async fn handle(&mut self, job: Job) {
        let Job { from, work } = job;
        match work {
            Work::Shutdown => {}
            Work::Configure(params) => {
                let mut control = self.control();
                let result = match control.configure(from, params) {
                    Ok(()) => {
                        info!(gimbal = %self.config.name, ?from, primary = ?control.primary, secondary = ?control.secondary, "control configured");
                        self.update(|s| s.control = control);
                        MavResult::MAV_RESULT_ACCEPTED
                    }
                    Err(Refused::HeldByAnother) => {
                        Stats::count(&self.stats.denied);
                        MavResult::MAV_RESULT_DENIED
                    }
                    Err(Refused::BadParameter) => {
                        Stats::count(&self.stats.refused);
                        MavResult::MAV_RESULT_DENIED
                    }
                };
                self.reply(ack(MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, result, from))
                    .await;
            }
            Work::Information(id) => {
                let command = MavCmd::MAV_CMD_REQUEST_MESSAGE;
                match self.information(id).await {
                    Ok(message) => {
                        self.reply(ack(command, MavResult::MAV_RESULT_ACCEPTED, from)).await;
                        self.reply(message).await;
                    }
                    Err(result) => self.reply(ack(command, result, from)).await,
                }
            }
            Work::Move { request, ack: command } => {
                let result = self.move_by(from, &request).await;
                if let Some(command) = command {
                    self.reply(ack(command, result, from)).await;
                }
            }
        }
    }

    /// The information message `id`, or the result that says why not.
    async fn information(&mut self, id: u32) -> Result<MavMessage, MavResult> {
        let g = &self.config;
        let (pitch_min, pitch_max) = (g.tilt_deg.0.to_radians() as f32, g.tilt_deg.1.to_radians() as f32);
        let (yaw_min, yaw_max) = (g.pan_deg.0.to_radians() as f32, g.pan_deg.1.to_radians() as f32);
        let time_boot_ms = self.outbox.boot_ms();
        match id {
            280 => Ok(MavMessage::GIMBAL_MANAGER_INFORMATION(
                GIMBAL_MANAGER_INFORMATION_DATA {
                    time_boot_ms,
                    cap_flags: GimbalManagerCapFlags::GIMBAL_MANAGER_CAP_FLAGS_HAS_PITCH_AXIS
                        | GimbalManagerCapFlags::GIMBAL_MANAGER_CAP_FLAGS_HAS_YAW_AXIS,
                    pitch_min,
                    pitch_max,
                    yaw_min,
                    yaw_max,
                    gimbal_device_id: g.component_id,
                    // No roll axis: its limits stay 0.
                    ..Default::default()
                },
            )),
            283 => {
                if self.identity.is_none() {
                    match self.connection.identity().await {
                        Ok(id) => self.identity = Some(id),
                        Err(e) => {
                            Stats::count(&self.stats.failed);
                            warn!(gimbal = %self.config.name, error = %e, "D? for GIMBAL_DEVICE_INFORMATION failed");
                            return Err(MavResult::MAV_RESULT_FAILED);
                        }
                    }
                }
                let id = self.identity.as_ref().expect("fetched above");
                let g = &self.config;
                Ok(MavMessage::GIMBAL_DEVICE_INFORMATION(GIMBAL_DEVICE_INFORMATION_DATA {
                    uid: uid(&id.serial),
                    time_boot_ms,
                    pitch_min,
                    pitch_max,
                    yaw_min,
                    yaw_max,
                    cap_flags: GimbalDeviceCapFlagsU16::GIMBAL_DEVICE_CAP_FLAGS_HAS_PITCH_AXIS
                        | GimbalDeviceCapFlagsU16::GIMBAL_DEVICE_CAP_FLAGS_HAS_YAW_AXIS,
                    vendor_name: "Sagebrush".into(),
                    model_name: id.name.trim().into(),
                    custom_name: id.serial.trim().into(),
                    gimbal_device_id: g.component_id,
                    cap_flags2: GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_PITCH_AXIS
                        | GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_YAW_AXIS,
                    // No roll axis (its limits stay 0), no versions, no custom flags.
                    ..Default::default()
                }))
            }
            _ => {
                Stats::count(&self.stats.ignored);
                Err(MavResult::MAV_RESULT_UNSUPPORTED)
            }
        }
    }

    /// A pitch/yaw request from `from`, with its honest result.
    async fn move_by(&mut self, from: Sender, request: &motion::Request) -> MavResult {
        if !self.control().allows(from) {
            Stats::count(&self.stats.denied);
            warn!(gimbal = %self.config.name, ?from, "not in control: denied");
            return MavResult::MAV_RESULT_DENIED;
        }
        let plan = match motion::plan(request, &self.config) {
            Ok(p) => p,
            Err(e) => {
                Stats::count(&self.stats.refused);
                warn!(gimbal = %self.config.name, ?from, error = %e, "request refused");
                return MavResult::MAV_RESULT_DENIED;
            }
        };
        let done = match plan {
            Plan::Nothing => Ok(()),
            Plan::GoTo { pan, tilt } => self.go_to(pan, tilt).await,
            Plan::Rates { pan, tilt } => self.rates(pan, tilt).await,
        };
        match done {
            Ok(()) => MavResult::MAV_RESULT_ACCEPTED,
            Err(e) => {
                Stats::count(&self.stats.failed);
                warn!(gimbal = %self.config.name, error = %e, "command failed");
                MavResult::MAV_RESULT_FAILED
            }
        }
    }

    async fn go_to(&mut self, pan: Option<f64>, tilt: Option<f64>) -> Result<(), CommandError> {
        self.slew = Slew::default();
        self.lease_end = None;
        let now = match (pan, tilt) {
            (Some(_), Some(_)) => Position::default(),
            _ => self.connection.position().await?,
        };
        let angle = |deg: Option<f64>, current: Angle| match deg {
            Some(d) => Angle::from_degrees(d as f32).map_err(|e| CommandError::Usage(e.to_string())),
            None => Ok(current),
        };
        let target = Position::new(angle(pan, now.pan)?, angle(tilt, now.tilt)?);
        self.connection.send(&Command::GoTo(target)).await.map(drop)
    }

    /// Sets the rates asked for; an unchanged rate only renews the lease.
    async fn rates(&mut self, pan: Option<f64>, tilt: Option<f64>) -> Result<(), CommandError> {
        let want = Slew {
            pan: pan.unwrap_or(self.slew.pan),
            tilt: tilt.unwrap_or(self.slew.tilt),
        };
        let axes = [
            (
                want.pan,
                self.slew.pan,
                Axis::Pan,
                Command::PanRight,
                Command::PanLeft,
                Command::PanStop,
            ),
            (
                want.tilt,
                self.slew.tilt,
                Axis::Tilt,
                Command::TiltUp,
                Command::TiltDown,
                Command::TiltStop,
            ),
        ];
        for (rate, old, axis, positive, negative, stop) in axes {
            if rate == old {
                continue;
            }
            let sent = if rate == 0.0 {
                self.connection.send(&stop).await.map(drop)
            } else {
                let speed = motion::speed_for(rate, self.config.max_rate_dps);
                let turn = old == 0.0 || rate.signum() != old.signum();
                match self.connection.send(&Command::SetSpeed(axis, speed)).await {
                    Ok(_) if turn => self
                        .connection
                        .send(if rate > 0.0 { &positive } else { &negative })
                        .await
                        .map(drop),
                    other => other.map(drop),
                }
            };
            if let Err(e) = sent {
                // Never leave an axis moving that the caller was told failed.
                self.stop_slew("a rate command failed").await;
                return Err(e);
            }
            match axis {
                Axis::Pan => self.slew.pan = rate,
                Axis::Tilt => self.slew.tilt = rate,
            }
        }
        self.lease_end = (self.slew != Slew::default()).then(|| Instant::now() + self.lease);
        Ok(())
    }

    /// Stops both axes if a rate is in force.
    async fn stop_slew(&mut self, why: &str) {
        self.lease_end = None;
        if self.slew == Slew::default() {
            return;
        }
        info!(gimbal = %self.config.name, why, "stopping the slew");
        self.slew = Slew::default();
        if let Err(e) = self.connection.stop(&[Command::PanStop, Command::TiltStop]).await {
            warn!(gimbal = %self.config.name, error = %e, "stop failed");
        }
    }
}

/// GIMBAL_DEVICE_INFORMATION's uid from the serial: its digits as a
/// number when it is one, else a hash of its text (FNV-1a); never 0 (unknown).
fn uid(serial: &str) -> u64 {
    let s = serial.trim();
    if let Ok(n) = s.parse::<u64>() {
        if n != 0 {
            return n;
        }
    }
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in s.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h.max(1)
}
