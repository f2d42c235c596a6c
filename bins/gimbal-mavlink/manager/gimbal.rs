//! One gimbal as a MAVLink gimbal manager and gimbal device: a task that
//! takes the requests for it in arrival order and hands the motions to the
//! gimbal's session (`sagebrush_client::session`: the connection to gcud,
//! the rate in force with its lease, stops first, rates coalesced newest
//! wins, the polled attitude). Nothing waits behind a motion: a request
//! that needs an answer is answered by a task of its own, at most
//! [`ANSWERING`] at once.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::common::{
    GIMBAL_DEVICE_INFORMATION_DATA, GIMBAL_MANAGER_INFORMATION_DATA, GimbalDeviceCapFlags, GimbalDeviceCapFlagsU16,
    GimbalManagerCapFlags, MavCmd, MavMessage, MavResult, MavSeverity,
};
use sagebrush_client::door::DoorSessions;
use sagebrush_client::session::{Drive, GimbalSession, Velocity};
use sagebrush_client::{CommandError, Identity};
use sagebrush_protocol::Undelivered;
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;
use tracing::{info, warn};

use crate::config::{self, Config};
use crate::earth::aim::{Aim, Target};
use crate::routing::answers::{ack, refusal_text, statustext};
use crate::routing::control::{Control, Refused, Sender};
use crate::routing::handle::{Handle, Job, Shared, Work};
use crate::routing::motion::{self, Plan};
use crate::stats::{Stats, may_warn};
use crate::transport::link::Outbox;

/// Requests waiting for one gimbal's task; it takes each at once (motions
/// are posted to the session, never awaited), so the queue fills only if
/// the task itself stalls.
pub const QUEUE: usize = 64;
/// Requests awaiting their outcome to be answered, at most; more are
/// answered MAV_RESULT_TEMPORARILY_REJECTED at once.
pub const ANSWERING: usize = 16;

/// A refusal by gcud is told in a STATUSTEXT at most this often per gimbal.
pub const REFUSAL_TEXT_EVERY: Duration = Duration::from_secs(2);

struct Task {
    config: config::Gimbal,
    session: Arc<GimbalSession>,
    shared: Arc<Mutex<Shared>>,
    outbox: Arc<Outbox>,
    stats: Arc<Stats>,
    lease: Duration,
    /// Requests being carried out whose answer is owed.
    answering: JoinSet<()>,
    /// When a refusal by gcud was last told in a STATUSTEXT.
    refusal_told: Arc<Mutex<Option<Instant>>>,
}

/// Starts the task of gimbal `g` and its session; it ends at
/// [`Work::Shutdown`] or when every handle is dropped.
pub fn spawn(
    g: &config::Gimbal,
    config: &Config,
    outbox: Arc<Outbox>,
    stats: Arc<Stats>,
    sessions: &DoorSessions,
) -> (Handle, tokio::task::JoinHandle<()>) {
    let (tx, rx) = mpsc::channel(QUEUE);
    let shared = Arc::new(Mutex::new(Shared::default()));
    let session = // A rate runs no longer than its lease unless renewed.
            sessions.start(&g.name, g.address, false, config.lease);
    let task = Task {
        config: g.clone(),
        session: Arc::clone(&session),
        shared: Arc::clone(&shared),
        outbox,
        stats,
        lease: config.lease,
        answering: JoinSet::new(),
        refusal_told: Arc::default(),
    };
    let join = tokio::spawn(task.run(rx));
    (
        Handle {
            config: g.clone(),
            shared,
            session,
            jobs: tx,
        },
        join,
    )
}

impl Task {
    fn control(&self) -> Control {
        self.shared.lock().unwrap_or_else(|p| p.into_inner()).control
    }

    async fn run(mut self, mut jobs: mpsc::Receiver<Job>) {
        loop {
            tokio::select! {
                job = jobs.recv() => match job {
                    Some(Job { work: Work::Shutdown, .. }) | None => break,
                    Some(job) => self.handle(job).await,
                },
                Some(_) = self.answering.join_next(), if !self.answering.is_empty() => {}
            }
        }
        info!(gimbal = %self.config.name, "stopping what this service started");
        self.session.shutdown().await;
        self.answering.abort_all();
    }

    /// An answer to `to` alone, on the peer it was heard on.
    async fn reply(&self, message: MavMessage, to: Sender) {
        self.outbox.answer(self.config.component_id, &message, to).await;
    }

    /// Answers `command` to `to` with the outcome of `work`, carried out by
    /// a task of its own; at most [`ANSWERING`] at once.
    async fn answer_later(
        &mut self,
        command: MavCmd,
        to: Sender,
        work: impl Future<Output = Result<Option<MavMessage>, MavResult>> + Send + 'static,
    ) {
        if self.answering.len() >= ANSWERING {
            Stats::count(&self.stats.busy);
            self.reply(ack(command, MavResult::MAV_RESULT_TEMPORARILY_REJECTED, to), to)
                .await;
            return;
        }
        let (outbox, component) = (Arc::clone(&self.outbox), self.config.component_id);
        self.answering.spawn(async move {
            match work.await {
                Ok(message) => {
                    outbox
                        .answer(component, &ack(command, MavResult::MAV_RESULT_ACCEPTED, to), to)
                        .await;
                    if let Some(m) = message {
                        outbox.answer(component, &m, to).await;
                    }
                }
                Err(result) => outbox.answer(component, &ack(command, result, to), to).await,
            }
        });
    }

    async fn handle(&mut self, job: Job) {
        let Job { from, work } = job;
        match work {
            Work::Shutdown => {}
            Work::Configure(params) => {
                // Read and changed in one step: the status task's lapse
                // check may clear an owner meanwhile.
                let configured = {
                    let mut shared = self.shared.lock().unwrap_or_else(|p| p.into_inner());
                    shared.control.configure(from, params).map(|()| shared.control)
                };
                let result = match configured {
                    Ok(control) => {
                        info!(
                            gimbal = %self.config.name,
                            from = crate::routing::control::sender_name(from),
                            primary = crate::routing::control::owner_name(control.primary),
                            secondary = crate::routing::control::owner_name(control.secondary),
                            "control configured"
                        );
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
                self.reply(ack(MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, result, from), from)
                    .await;
            }
            Work::Information(id) => {
                let command = MavCmd::MAV_CMD_REQUEST_MESSAGE;
                let (config, session, stats) =
                    (self.config.clone(), Arc::clone(&self.session), Arc::clone(&self.stats));
                let time_boot_ms = self.outbox.boot_ms();
                self.answer_later(command, from, async move {
                    information(&config, &session, &stats, id, time_boot_ms).await.map(Some)
                })
                .await;
            }
            Work::Move {
                request,
                ack: command,
                aim,
            } => {
                let plan = self.admit(from, &request);
                self.hold(from, aim, plan.is_some());
                let Some(plan) = plan else {
                    if let Some(command) = command {
                        self.reply(ack(command, MavResult::MAV_RESULT_DENIED, from), from).await;
                    }
                    return;
                };
                let rates = matches!(plan, Plan::Rates { .. });
                let outcome = self.start(from, plan);
                if command.is_none() && rates {
                    // Posted; nobody to answer (the session logs a failure and stops the slew).
                    return;
                }
                let (name, stats) = (self.config.name.clone(), Arc::clone(&self.stats));
                let (session, told) = (Arc::clone(&self.session), Arc::clone(&self.refusal_told));
                let (outbox, component) = (Arc::clone(&self.outbox), self.config.component_id);
                let done = async move {
                    match outcome.await {
                        Ok(()) => Ok(None),
                        Err(e) if e.refusal().is_some() => {
                            // gcud's decision (ARCHITECTURE "Front doors"): DENIED, and
                            // its words to the ground stations, at most every
                            // REFUSAL_TEXT_EVERY.
                            Stats::count(&stats.denied);
                            if may_warn("refused by gcud: denied", &name) {
                                warn!(gimbal = %name, error = %e, "refused by gcud: MAV_RESULT_DENIED");
                            }
                            let due = {
                                let mut last = told.lock().unwrap_or_else(|p| p.into_inner());
                                let due = last.is_none_or(|t| t.elapsed() >= REFUSAL_TEXT_EVERY);
                                if due {
                                    *last = Some(Instant::now());
                                }
                                due
                            };
                            if due {
                                let holder = session.status().control.map(|c| c.holder);
                                let rule = e.refusal().unwrap_or(Undelivered::NotInControl);
                                let text = refusal_text(rule, holder.as_ref());
                                outbox
                                    .broadcast(component, &statustext(MavSeverity::MAV_SEVERITY_WARNING, &text))
                                    .await;
                            }
                            Err(MavResult::MAV_RESULT_DENIED)
                        }
                        Err(e) => {
                            Stats::count(&stats.failed);
                            if may_warn("command failed", &name) {
                                warn!(gimbal = %name, error = %e, "command failed");
                            }
                            Err(MavResult::MAV_RESULT_FAILED)
                        }
                    }
                };
                match command {
                    Some(command) => self.answer_later(command, from, done).await,
                    // A goto with no answer owed, carried out beside the others.
                    None if self.answering.len() < ANSWERING => drop(self.answering.spawn(async move {
                        let _ = done.await;
                    })),
                    None => {
                        Stats::count(&self.stats.busy);
                    }
                }
            }
        }
    }

    /// The earth-frame aim in force after a motion from `from` holding
    /// `aim`: that one once the gimbal took it (`taken`) (None ends any aim);
    /// when refused, `from`'s own aim ends (a re-aim of an owner that lost
    /// control, or whose place left the travel, is not tried again).
    fn hold(&self, from: Sender, aim: Option<Aim>, taken: bool) {
        let held = &mut self.shared.lock().unwrap_or_else(|p| p.into_inner()).aim;
        if taken {
            *held = aim.map(|aim| Target { aim, from });
        } else if held.is_some_and(|t| t.from == from) {
            *held = None;
        }
    }

    /// The plan for a pitch/yaw request from `from`, or None when refused
    /// (not in control, or not a motion this gimbal can make).
    fn admit(&self, from: Sender, request: &motion::Request) -> Option<Plan> {
        if !self.control().allows(from) {
            Stats::count(&self.stats.denied);
            if may_warn("not in control: denied", &self.config.name) {
                warn!(gimbal = %self.config.name, from = crate::routing::control::sender_name(from), "not in control: denied");
            }
            return None;
        }
        match motion::plan(request, &self.config) {
            Ok(p) => Some(p),
            Err(e) => {
                Stats::count(&self.stats.refused);
                if may_warn("request refused", &self.config.name) {
                    warn!(gimbal = %self.config.name, from = crate::routing::control::sender_name(from), error = %e, "request refused");
                }
                None
            }
        }
    }

    /// Posts `plan` to the session now (in arrival order); the future
    /// tells its outcome.
    fn start(&self, from: Sender, plan: Plan) -> impl Future<Output = Result<(), CommandError>> + Send + 'static {
        let session = Arc::clone(&self.session);
        let max_dps = self.config.max_rate_dps;
        let rates = match plan {
            Plan::Rates { pan, tilt } => {
                let drive = |rate: f64| Drive::signed(rate, |r| motion::speed_for(r, max_dps));
                let velocity = Velocity {
                    pan: pan.map(drive),
                    tilt: tilt.map(drive),
                    zoom: None,
                };
                let owner = format!("MAVLink {}/{}", from.0, from.1);
                Some(session.post_velocity(velocity, Some(self.lease), &owner))
            }
            _ => None,
        };
        async move {
            match (plan, rates) {
                (_, Some(outcome)) => outcome
                    .await
                    .unwrap_or_else(|_| Err(CommandError::Io("session ended".into()))),
                (Plan::GoTo { pan, tilt }, None) => session.go_to_degrees(pan, tilt).await.map(drop),
                _ => Ok(()),
            }
        }
    }
}

/// The information message `id`, or the result that says why not.
async fn information(
    g: &config::Gimbal,
    session: &GimbalSession,
    stats: &Stats,
    id: u32,
    time_boot_ms: u32,
) -> Result<MavMessage, MavResult> {
    let (pitch_min, pitch_max) = (g.tilt_deg.0.to_radians() as f32, g.tilt_deg.1.to_radians() as f32);
    let (yaw_min, yaw_max) = (g.pan_deg.0.to_radians() as f32, g.pan_deg.1.to_radians() as f32);
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
            let id: Identity = session.identity().await.map_err(|e| {
                Stats::count(&stats.failed);
                if may_warn("D? for GIMBAL_DEVICE_INFORMATION failed", &g.name) {
                    warn!(gimbal = %g.name, error = %e, "D? for GIMBAL_DEVICE_INFORMATION failed");
                }
                MavResult::MAV_RESULT_FAILED
            })?;
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
            Stats::count(&stats.ignored);
            Err(MavResult::MAV_RESULT_UNSUPPORTED)
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
