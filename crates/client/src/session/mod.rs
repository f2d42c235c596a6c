//! One gimbal as every front door drives it (ARCHITECTURE "Front doors",
//! the gimbal session): one task owns the gimbal's connection to gcud and is
//! the only sender on it, and the doors post what they want:
//!
//! - **a motion is one object**: the velocity in force per axis, its owner
//!   and its deadline (an ONVIF Timeout, a MAVLink lease, at most
//!   `max_move`). A newer velocity replaces it as one step, a goto, preset
//!   or home supersedes its pan and tilt, a stop ends it; when its
//!   deadline passes, the session owes the stops of whatever moves.
//! - **stops first**: a stop (or a velocity of zero on every axis it
//!   names) is owed at once and sent before any other command; a zero
//!   beside a move is part of that move, owed once the move is in force
//!   (so that a move gcud refuses stops nothing); the task checks for an owed stop
//!   before every motion command, so no motion command goes out after the
//!   stop that ended it. A stop is sent until the bus confirms it: while
//!   gcud cannot be reached it stays owed and goes first when gcud is back,
//!   and the motion is reported [`Motion::Unknown`] meanwhile.
//! - **bounded work**: velocity updates coalesce (newest wins, per axis),
//!   one positioning move waits at most (newest wins), other commands wait
//!   in a short queue; what cannot start within [`STALE`] is dropped with
//!   an error, never sent late.
//! - **gcud's decisions** (ARCHITECTURE "Front doors"): a command gcud
//!   refuses by its rules is [`CommandError::Refused`], naming the link
//!   that holds the gimbal when that is the rule; a refused motion never
//!   counts as one, and a refusal for control sends no stop (the motion on
//!   the gimbal is the holder's, and gcud stopped this door's when the
//!   holder took control). Who controls the gimbal (`~C`, answered by gcud
//!   itself) is asked with a poll at most every [`CONTROL_POLL`].
//! - **one poll for every reader**: `P?` (and `V?` for a lens) every poll
//!   period, at least every [`REFRESH`] while something moves, so gcud's
//!   motion lease on the door's connection (ARCHITECTURE "Safety") stays
//!   fed while the door lives and stops the gimbal if the door hangs. The
//!   identity (`D?`) is asked once and kept.
//!
//! Split by concern: this module holds the settings and the session's
//! surface, what a door posts; `types.rs` the public vocabulary (drives,
//! velocities, axes, motion, status, gcud's reachability); `state.rs` what
//! the session has been asked and what is in force, shared under one lock;
//! `task.rs` the task that owns the connection and decides the next step;
//! `travel.rs` when the session's motion ended, as the bus shows it (a
//! positioning move's end on the polls, a take-over by another controller).

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use sagebrush_protocol::{Address, Angle, Axis, Command, LensPosition, LensSpeed, Position, Speed, Undelivered};
use tokio::sync::{Notify, oneshot};
use tokio::time::Instant;
use tracing::{info, warn};

use crate::client::CommandError;
use crate::connection::{Control, GimbalConnection, Identity, UNREACHABLE_POLL};
use crate::governance::{Controller, GcuAnswer, GcuRequest, Rules, Tour, TourOutcome};

mod motion;
mod state;
mod task;
mod travel;
mod types;

use motion::Place;
use state::{Queued, State};
use task::closed;
pub use types::{Axes, Drive, GcudReachability, Motion, Status, Velocity};

/// A request that could not start within this is dropped with an error
/// (gcud unreachable, the bus busy): never sent after its caller gave up.
pub const STALE: Duration = Duration::from_secs(5);
/// While something moves, the gimbal is polled at least this often, which
/// also renews gcud's motion lease on the session's connection.
pub const REFRESH: Duration = Duration::from_millis(250);
/// Commands other than motions and stops waiting at once; more are refused.
pub const QUEUE: usize = 8;
/// gcud is asked who controls the gimbal (`~C`, answered by gcud itself:
/// no bus time) with a poll at most this often.
pub const CONTROL_POLL: Duration = Duration::from_secs(1);
/// gcud's rules of the gimbal (`~B`: limits and zones, changed only by a
/// reload of gcud) are asked again after this.
pub const RULES_REFRESH: Duration = Duration::from_secs(30);
/// A speed the gimbal acknowledged is believed for this long at most
/// (then set again before the next slew at it): what the session cannot
/// observe, a gimbal that restarted between two polls or a speed set by a
/// master that bypasses gcud, is corrected within it. Everything it can
/// observe forgets the speeds at once (`MotionState::forget_speeds`): a new
/// connection, any error or refusal, any command but the session's own
/// slews, speeds, stops and queries, a poll the gimbal did not answer, and
/// gcud naming another holder of the gimbal in `~C` (a holder that came
/// and went between two `~C`, every [`CONTROL_POLL`], is left to this
/// bound). A slew at the wrong speed is worse than the ~10 ms a speed
/// command costs.
pub const SPEED_KEPT: Duration = Duration::from_secs(5);
/// An owed stop is sent again this often while gcud cannot be reached.
const STOP_RETRY: Duration = Duration::from_millis(200);
/// A caller of [`GimbalSession::stop`] is told the stop failed after this
/// many attempts. While gcud cannot be reached the stop stays owed and is
/// sent on until confirmed; a stop gcud reports undelivered (the gimbal
/// silent) is given up after this many.
const STOP_ATTEMPTS_ANSWERED: u32 = 2;

/// A door's way to gcud, shared by the sessions of all its gimbals.
#[derive(Clone, Debug, PartialEq)]
pub struct GcudLink {
    /// gcud's client listener: `host:port`, or `tls://host:port` with its files.
    pub gcud: sagebrush_host::tls::Endpoint,
    /// The source group of the commands.
    pub from: u8,
    /// How long after gcud's ACK a NIC may come (1.4.2).
    pub nic_window: Duration,
}

impl GcudLink {
    pub fn new(gcud: impl Into<sagebrush_host::tls::Endpoint>, from: u8, nic_window: Duration) -> Self {
        Self {
            gcud: gcud.into(),
            from,
            nic_window,
        }
    }
}

impl From<&sagebrush_service::door_link::DoorLink> for GcudLink {
    /// The link a door's shared keys describe.
    fn from(keys: &sagebrush_service::door_link::DoorLink) -> Self {
        Self::new(keys.gcud.clone(), keys.source_group, keys.nic_window)
    }
}

/// Where a session's gimbal is and how it is driven.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    pub link: GcudLink,
    pub address: Address,
    /// `P?` every this (and `V?` with `lens`).
    pub poll: Duration,
    pub lens: bool,
    /// The longest any motion runs without being renewed.
    pub max_move: Duration,
    /// The gimbal's name in logs.
    pub name: String,
}

/// What became of a posted velocity ([`GimbalSession::post_velocity`]).
pub type Outcome = oneshot::Receiver<Result<(), CommandError>>;

/// One gimbal's session; see the module's documentation.
pub struct GimbalSession {
    pub config: SessionConfig,
    state: Mutex<State>,
    wake: Notify,
    reach: Arc<GcudReachability>,
    /// Held by a goto of one axis from its start until it is posted, so
    /// that the next one aims after it (in the order they were asked).
    aiming: tokio::sync::Mutex<()>,
}

impl std::fmt::Debug for GimbalSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GimbalSession").field("config", &self.config).finish()
    }
}

impl GimbalSession {
    /// Starts the session's task; `reach` is shared by the door's sessions.
    /// The task ends after [`GimbalSession::shutdown`].
    pub fn start(config: SessionConfig, reach: Arc<GcudReachability>) -> Arc<Self> {
        let link = &config.link;
        let connection = GimbalConnection::new(link.gcud.clone(), link.from, config.address, link.nic_window);
        let session = Arc::new(Self {
            config,
            state: Mutex::new(State::default()),
            wake: Notify::new(),
            reach,
            aiming: tokio::sync::Mutex::new(()),
        });
        tokio::spawn(Arc::clone(&session).run(connection));
        session
    }

    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// What the last polls saw, with the motion as the session knows it.
    pub fn status(&self) -> Status {
        let s = self.state();
        Status {
            motion: s.motion_shown(),
            taken_by: s.taken_by(),
            ..s.status.clone()
        }
    }

    /// A fresh poll (`P?`, and `V?` with a lens): the session's own poll,
    /// taken at once (after the owed stops, the motions and the queue) and
    /// shared by every reader waiting then, so that a door asks the gimbal
    /// through its session, never beside it. Fails as the poll failed, or
    /// once [`STALE`] passed without one.
    pub async fn poll(&self) -> Result<(Position, Option<LensPosition>), CommandError> {
        let (tx, rx) = oneshot::channel();
        {
            let mut s = self.state();
            if s.closing {
                return Err(closed());
            }
            s.readers.push((Instant::now(), tx));
        }
        self.wake.notify_one();
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// Where the gimbal points now: [`GimbalSession::poll`]'s position.
    pub async fn position(&self) -> Result<Position, CommandError> {
        self.poll().await.map(|(position, _)| position)
    }

    /// Sets `velocity` for `run` (at most `max_move`; the motion's new
    /// deadline, for every axis still moving), owned by `owner`. An axis at
    /// [`Drive::Stop`] is a stop, owed at once. Returns once the velocity
    /// is in force or superseded by a newer one or a stop.
    pub async fn velocity(&self, velocity: Velocity, run: Option<Duration>, owner: &str) -> Result<(), CommandError> {
        self.acting_for(None).velocity(velocity, run, owner).await
    }

    /// [`GimbalSession::velocity`] without waiting: the receiver tells
    /// the outcome.
    pub fn post_velocity(&self, velocity: Velocity, run: Option<Duration>, owner: &str) -> Outcome {
        self.acting_for(None).post_velocity(velocity, run, owner)
    }

    /// The session acting for `user`, one of the door's users: gcud
    /// governs what is posted through it as that user's (ARCHITECTURE
    /// "Principals"; `None`: the door's own).
    pub fn acting_for(&self, user: Option<&str>) -> ForUser<'_> {
        ForUser {
            session: self,
            user: user.map(Arc::from),
        }
    }

    /// Stops `axes`; done once the bus confirms each stop. After
    /// [`STOP_ATTEMPTS_ANSWERED`] failed attempts the caller is told, and
    /// the stop stays owed until confirmed.
    pub async fn stop(&self, axes: Axes) -> Result<(), CommandError> {
        if !axes.any() {
            // Nothing to stop (a zoom stop for a gimbal without a lens).
            return Ok(());
        }
        let (tx, rx) = oneshot::channel();
        self.state().motion.stop(axes, tx);
        self.wake.notify_one();
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    async fn place(&self, place: Place, by: Option<Arc<str>>) -> Result<(), CommandError> {
        self.post_place(place, by).await.unwrap_or_else(|_| Err(closed()))
    }

    /// `place` asked now, for door user `by`; the receiver tells its outcome.
    fn post_place(&self, place: Place, by: Option<Arc<str>>) -> Outcome {
        let (tx, rx) = oneshot::channel();
        self.state().motion.place(place, by, Instant::now(), tx);
        self.wake.notify_one();
        rx
    }

    /// `GO` (Table 15).
    pub async fn go_to(&self, target: Position) -> Result<(), CommandError> {
        self.acting_for(None).go_to(target).await
    }

    /// `GO` to degrees (Table 15): [`ForUser::go_to_degrees`], for the door itself.
    pub async fn go_to_degrees(&self, pan: Option<f64>, tilt: Option<f64>) -> Result<Position, CommandError> {
        self.acting_for(None).go_to_degrees(pan, tilt).await
    }

    /// `Pnn` (Table 11).
    pub async fn go_to_preset(&self, n: u8) -> Result<(), CommandError> {
        self.acting_for(None).go_to_preset(n).await
    }

    /// `HO`.
    pub async fn home(&self) -> Result<(), CommandError> {
        self.acting_for(None).home().await
    }

    /// Any other command (a query, `SVnn`, `V`): its result payload, if it
    /// has one. At most [`QUEUE`] wait; more are refused.
    pub async fn send(&self, command: Command<'static>) -> Result<Option<Vec<u8>>, CommandError> {
        self.acting_for(None).send(command).await
    }

    /// A GCU command to gcud (module `governance`), in the queue with the
    /// other commands: answered by gcud itself, no bus time.
    pub async fn gcu(&self, request: GcuRequest) -> Result<GcuAnswer, CommandError> {
        self.acting_for(None).gcu(request).await
    }

    fn enqueue(&self, queued: Queued, what: &str, by: Option<Arc<str>>) -> Result<(), CommandError> {
        {
            let mut s = self.state();
            if s.queue.len() >= QUEUE {
                return Err(CommandError::Io(format!(
                    "{} commands already wait for gimbal {}: {what} refused",
                    QUEUE, self.config.name,
                )));
            }
            s.queue.push_back((queued, Instant::now(), by));
        }
        self.wake.notify_one();
        Ok(())
    }

    /// `~C` now: who controls the gimbal (also kept in [`Status::control`]).
    pub async fn controller(&self) -> Result<Controller, CommandError> {
        let a = self.config.address;
        match self.gcu(GcuRequest::Controller(a.port, a.device)).await? {
            GcuAnswer::Controller(c) => Ok(c),
            other => Err(CommandError::BadReply(format!("~C answered {other:?}"))),
        }
    }

    /// `~T?`: gcud's tours (of every gimbal of this gimbal's GCU).
    pub async fn tours(&self) -> Result<Vec<Tour>, CommandError> {
        match self.gcu(GcuRequest::TourList).await? {
            GcuAnswer::Tours(t) => Ok(t),
            other => Err(CommandError::BadReply(format!("~T? answered {other:?}"))),
        }
    }

    /// `~T+name` (`start`) or `~T-name`: what became of the tour. An
    /// unknown tour is [`CommandError::Nic`].
    pub async fn tour(&self, name: &str, start: bool) -> Result<TourOutcome, CommandError> {
        let request = if start {
            GcuRequest::TourStart(name.to_owned())
        } else {
            GcuRequest::TourStop(name.to_owned())
        };
        match self.gcu(request).await? {
            GcuAnswer::Tour(t) => Ok(t),
            other => Err(CommandError::BadReply(format!("~T answered {other:?}"))),
        }
    }

    /// `~R`: releases control of the gimbal; gcud refuses it
    /// ([`CommandError::Refused`]) when a link of higher priority holds it.
    pub async fn release(&self) -> Result<(), CommandError> {
        self.acting_for(None).release().await
    }

    /// `~B`: gcud's limits and zones of the gimbal, asked at most every
    /// [`RULES_REFRESH`] (they change only on a reload of gcud). A gcud
    /// that does not know `~B` answers NIC ([`CommandError::Nic`]).
    pub async fn rules(&self) -> Result<Rules, CommandError> {
        if let Some((at, rules)) = self.state().rules.clone() {
            if at.elapsed() < RULES_REFRESH {
                return Ok(rules);
            }
        }
        let a = self.config.address;
        let rules = match self.gcu(GcuRequest::Rules(a.port, a.device)).await? {
            GcuAnswer::Rules(r) => r,
            other => return Err(CommandError::BadReply(format!("~B answered {other:?}"))),
        };
        self.state().rules = Some((Instant::now(), rules.clone()));
        Ok(rules)
    }

    /// `D?`, asked once and kept.
    pub async fn identity(&self) -> Result<Identity, CommandError> {
        if let Some(id) = self.state().identity.clone() {
            return Ok(id);
        }
        let payload = self
            .send(Command::Identify)
            .await?
            .ok_or_else(|| CommandError::NoResult(format!("{} sent no result for D?", self.config.address)))?;
        let id = Identity::from_result(&payload)?;
        self.state().identity = Some(id.clone());
        Ok(id)
    }

    /// Stops what moves (or may: a goto under way), waits for the bus to
    /// confirm, and ends the task.
    pub async fn shutdown(&self) {
        let axes = {
            let s = self.state();
            let m = &s.motion;
            let moving = m.moving();
            let changing = s.status.changing || m.place.is_some() || m.placing.is_some() || m.travel.is_some();
            Axes {
                pan: moving.pan || changing,
                tilt: moving.tilt || changing,
                zoom: moving.zoom,
            }
            .or(m.stops_owed)
            .or(m.wish_stops)
        };
        if axes.any() {
            if let Err(e) = self.stop(axes).await {
                warn!(gimbal = %self.config.name, error = %e, "stop at shutdown failed");
            }
        }
        self.state().closing = true;
        self.wake.notify_one();
    }
}

/// A gimbal session acting for one of the door's users
/// ([`GimbalSession::acting_for`]): what is posted through it goes to gcud
/// as that user's (`~U`, ARCHITECTURE "Principals"), on the session's one
/// connection. Newest wins as ever: a velocity or goto of another user
/// replaces this one's, and is sent as that user's.
#[derive(Debug)]
pub struct ForUser<'a> {
    session: &'a GimbalSession,
    user: Option<Arc<str>>,
}

impl ForUser<'_> {
    /// [`GimbalSession::velocity`], for this user.
    pub async fn velocity(&self, velocity: Velocity, run: Option<Duration>, owner: &str) -> Result<(), CommandError> {
        let rx = self.post_velocity(velocity, run, owner);
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// [`GimbalSession::post_velocity`], for this user: the motion's rule
    /// (module `motion`) takes it, its run at most `max_move`.
    pub fn post_velocity(&self, velocity: Velocity, run: Option<Duration>, owner: &str) -> Outcome {
        let (tx, rx) = oneshot::channel();
        let max = self.session.config.max_move;
        let run = run.map_or(max, |r| r.min(max));
        (self.session.state().motion).post(velocity, run, owner, self.user.clone(), Instant::now(), tx);
        self.session.wake.notify_one();
        rx
    }

    /// `GO` (Table 15), for this user.
    pub async fn go_to(&self, target: Position) -> Result<(), CommandError> {
        self.session.place(Place::GoTo(target), self.user.clone()).await
    }

    /// `GO` to `pan` and `tilt` in degrees (Table 15), for this user: an
    /// axis left `None` keeps the angle the positioning move asked before
    /// aims it at while that move is asked or under way (a keyboard's
    /// absolute pan, then its tilt 50 ms later), else the angle read with
    /// the session's poll ([`GimbalSession::position`]). An angle the
    /// protocol cannot carry (hundredths of a degree in 16 bits) is
    /// [`CommandError::Usage`]. Returns where it sent the gimbal.
    pub async fn go_to_degrees(&self, pan: Option<f64>, tilt: Option<f64>) -> Result<Position, CommandError> {
        let angle = |degrees: Option<f64>, current: Angle| match degrees {
            Some(d) => Angle::from_degrees(d as f32).map_err(|e| CommandError::Usage(e.to_string())),
            None => Ok(current),
        };
        let from_here = pan.is_none() || tilt.is_none();
        self.go_from_aim(from_here, |now| {
            Ok(Position::new(angle(pan, now.pan)?, angle(tilt, now.tilt)?))
        })
        .await
    }

    /// `GO` by `pan` and `tilt` degrees (Table 15), for this user: from
    /// where the positioning move asked before aims the gimbal while that
    /// move is asked or under way (two relative moves in a row add up),
    /// else from where a poll reads it now (never a poll from before the
    /// door's first: a VISCA RelativePosition right after the door
    /// started was refused). Returns where it sent the gimbal.
    pub async fn go_by_degrees(&self, pan: f64, tilt: f64) -> Result<Position, CommandError> {
        let angle = |now: Angle, by: f64| {
            Angle::from_degrees((f64::from(now.degrees()) + by) as f32).map_err(|e| CommandError::Usage(e.to_string()))
        };
        self.go_from_aim(true, |now| {
            Ok(Position::new(angle(now.pan, pan)?, angle(now.tilt, tilt)?))
        })
        .await
    }

    /// A goto to `target(from)`, `from` where `MotionState::aim` or a
    /// fresh poll puts the gimbal when `from_here`; such gotos aimed in
    /// the order asked (`aiming`).
    async fn go_from_aim(
        &self,
        from_here: bool,
        target: impl FnOnce(Position) -> Result<Position, CommandError>,
    ) -> Result<Position, CommandError> {
        let order = self.session.aiming.lock().await;
        let aim = self.session.state().motion.aim();
        let from = match (from_here, aim) {
            (false, _) => Position::default(),
            (true, Some(aim)) => aim,
            (true, None) => self.session.position().await?,
        };
        let target = target(from)?;
        let outcome = self.session.post_place(Place::GoTo(target), self.user.clone());
        // Posted: the next goto from here aims after this one.
        drop(order);
        outcome.await.unwrap_or_else(|_| Err(closed())).map(|()| target)
    }

    /// `Pnn` (Table 11), for this user.
    pub async fn go_to_preset(&self, n: u8) -> Result<(), CommandError> {
        self.session.place(Place::Preset(n), self.user.clone()).await
    }

    /// `HO`, for this user.
    pub async fn home(&self) -> Result<(), CommandError> {
        self.session.place(Place::Home, self.user.clone()).await
    }

    /// [`GimbalSession::send`], for this user.
    pub async fn send(&self, command: Command<'static>) -> Result<Option<Vec<u8>>, CommandError> {
        let (tx, rx) = oneshot::channel();
        self.session
            .enqueue(Queued::Bus(command, tx), command.mnemonic(), self.user.clone())?;
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// [`GimbalSession::gcu`], for this user.
    pub async fn gcu(&self, request: GcuRequest) -> Result<GcuAnswer, CommandError> {
        let (tx, rx) = oneshot::channel();
        let what = format!("{request:?}");
        self.session
            .enqueue(Queued::Gcu(request, tx), &what, self.user.clone())?;
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// `~R`, for this user: gcud releases the gimbal when this user (or
    /// one it outranks) holds it.
    pub async fn release(&self) -> Result<(), CommandError> {
        let a = self.session.config.address;
        match self.gcu(GcuRequest::Release(a.port, a.device)).await? {
            GcuAnswer::Released => Ok(()),
            other => Err(CommandError::BadReply(format!("~R answered {other:?}"))),
        }
    }
}
