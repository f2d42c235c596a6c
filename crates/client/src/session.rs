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

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use sagebrush_protocol::{Address, Axis, Command, LensPosition, LensSpeed, Position, Speed, Undelivered};
use tokio::sync::{Notify, oneshot};
use tokio::time::Instant;
use tracing::{info, warn};

use crate::client::CommandError;
use crate::connection::{Control, GimbalConnection, Identity, UNREACHABLE_POLL};
use crate::governance::{Controller, GcuAnswer, GcuRequest, Rules, Tour, TourOutcome};

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
/// An owed stop is sent again this often while gcud cannot be reached.
const STOP_RETRY: Duration = Duration::from_millis(200);
/// A caller of [`GimbalSession::stop`] is told the stop failed after this
/// many attempts. While gcud cannot be reached the stop stays owed and is
/// sent on until confirmed; a stop gcud reports undelivered (the gimbal
/// silent) is given up after this many.
const STOP_ATTEMPTS_ANSWERED: u32 = 2;

/// Where a session's gimbal is and how it is driven.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    /// gcud's client listener, `host:port`.
    pub gcud: String,
    /// The source group of the commands.
    pub from: u8,
    pub address: Address,
    /// How long after gcud's ACK a NIC may come (1.4.2).
    pub nic_window: Duration,
    /// `P?` every this (and `V?` with `lens`).
    pub poll: Duration,
    pub lens: bool,
    /// The longest any motion runs without being renewed.
    pub max_move: Duration,
    /// The gimbal's name in logs.
    pub name: String,
}

/// One axis's drive: stopped, or slewing forward (pan right `PR`, tilt up
/// `TU`, zoom in `ZI`) or back at a speed (Tables 11 and 16).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drive<S> {
    Stop,
    Forward(S),
    Back(S),
}

impl<S: Copy> Drive<S> {
    /// The drive of a signed velocity or rate `v` (0 stops, positive is
    /// forward), at `speed(v)` (the door's mapping of |v| to Table 11/16).
    pub fn signed(v: f64, speed: impl FnOnce(f64) -> S) -> Self {
        if v == 0.0 {
            Drive::Stop
        } else if v > 0.0 {
            Drive::Forward(speed(v))
        } else {
            Drive::Back(speed(v))
        }
    }

    fn speed(self) -> Option<S> {
        match self {
            Drive::Stop => None,
            Drive::Forward(s) | Drive::Back(s) => Some(s),
        }
    }
}

/// A velocity: each axis with `Some` is set, `None` left as it is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Velocity {
    pub pan: Option<Drive<Speed>>,
    pub tilt: Option<Drive<Speed>>,
    pub zoom: Option<Drive<LensSpeed>>,
}

/// Which axes a stop is for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Axes {
    pub pan: bool,
    pub tilt: bool,
    pub zoom: bool,
}

impl Axes {
    pub const PAN_TILT: Axes = Axes {
        pan: true,
        tilt: true,
        zoom: false,
    };
    pub const ALL: Axes = Axes {
        pan: true,
        tilt: true,
        zoom: true,
    };

    fn any(self) -> bool {
        self.pan || self.tilt || self.zoom
    }

    fn or(self, other: Axes) -> Axes {
        Axes {
            pan: self.pan || other.pan,
            tilt: self.tilt || other.tilt,
            zoom: self.zoom || other.zoom,
        }
    }

    /// The next stop command owed, in the order `PS`, `TS`, `ZS`.
    fn first(self) -> Option<(Command<'static>, Axes)> {
        if self.pan {
            Some((
                Command::PanStop,
                Axes {
                    pan: true,
                    ..Axes::default()
                },
            ))
        } else if self.tilt {
            Some((
                Command::TiltStop,
                Axes {
                    tilt: true,
                    ..Axes::default()
                },
            ))
        } else if self.zoom {
            Some((
                Command::ZoomStop,
                Axes {
                    zoom: true,
                    ..Axes::default()
                },
            ))
        } else {
            None
        }
    }

    fn without(self, other: Axes) -> Axes {
        Axes {
            pan: self.pan && !other.pan,
            tilt: self.tilt && !other.tilt,
            zoom: self.zoom && !other.zoom,
        }
    }
}

/// What a door reports of the motion (ONVIF MoveStatus).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    #[default]
    Idle,
    Moving,
    /// A stop is owed that the bus has not confirmed (gcud unreachable):
    /// the gimbal may be moving or not.
    Unknown,
}

/// The session's picture of its gimbal, read by every door's status.
#[derive(Clone, Debug, Default)]
pub struct Status {
    /// The last `P?` answer.
    pub position: Option<Position>,
    /// The last `V?` answer (sessions with a lens).
    pub lens: Option<LensPosition>,
    /// Why the last poll failed, when it did.
    pub error: Option<String>,
    /// The position changed between the last two polls.
    pub changing: bool,
    pub motion: Motion,
    /// Who controls the gimbal, as gcud last answered `~C` (with a poll,
    /// or naming the holder of a refusal); `None` while unknown (a gcud
    /// that governs nothing answers NIC).
    pub control: Option<Control>,
}

/// Whether gcud can be reached, shared by a door's sessions so that the
/// door logs each change once.
#[derive(Debug, Default)]
pub struct GcudReachability(AtomicU8);

// 0: not yet known.
const REACH_UP: u8 = 1;
const REACH_DOWN: u8 = 2;

impl GcudReachability {
    fn up(&self, gcud: &str) {
        if self.0.swap(REACH_UP, Ordering::Relaxed) == REACH_DOWN {
            info!(gcud, "gcud can be reached again");
        }
    }

    fn down(&self, gcud: &str, error: &CommandError) {
        if self.0.swap(REACH_DOWN, Ordering::Relaxed) != REACH_DOWN {
            warn!(gcud, %error, "gcud cannot be reached: stops are kept owed and sent first when it is back");
        }
    }
}

type Reply = oneshot::Sender<Result<(), CommandError>>;
type Answer = oneshot::Sender<Result<Option<Vec<u8>>, CommandError>>;
type GcuReply = oneshot::Sender<Result<GcuAnswer, CommandError>>;

/// A request waiting in the queue: a command to the gimbal, or one to gcud.
enum Queued {
    Bus(Command<'static>, Answer),
    Gcu(GcuRequest, GcuReply),
}

impl Queued {
    fn fail(self, e: CommandError) {
        match self {
            Queued::Bus(_, reply) => drop(reply.send(Err(e))),
            Queued::Gcu(_, reply) => drop(reply.send(Err(e))),
        }
    }
}

/// One side of the gimbal, as far as the session has told it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct InForce<S> {
    /// The speed last set (`SPn`, `STn`, `Zn`).
    speed: Option<S>,
    /// The slew started last and not stopped since.
    drive: Drive<S>,
}

impl<S> Default for InForce<S> {
    fn default() -> Self {
        Self {
            speed: None,
            drive: Drive::Stop,
        }
    }
}

/// A positioning move: supersedes a pan/tilt slew on the gimbal itself.
#[derive(Clone, Copy, Debug)]
enum Place {
    GoTo(Position),
    Preset(u8),
    Home,
}

impl Place {
    fn command(self) -> Command<'static> {
        match self {
            Place::GoTo(p) => Command::GoTo(p),
            Place::Preset(n) => Command::GoToPreset(n),
            Place::Home => Command::Home,
        }
    }
}

struct Pending<T> {
    what: T,
    asked: Instant,
    replies: Vec<Reply>,
}

#[derive(Default)]
struct State {
    pan: InForce<Speed>,
    tilt: InForce<Speed>,
    zoom: InForce<LensSpeed>,
    /// The motion's deadline, while anything moves or is about to.
    deadline: Option<Instant>,
    /// Who owns the motion, for the logs.
    owner: String,
    stops_owed: Axes,
    /// Failed attempts at the owed stops since the last confirmed one.
    stop_failures: u32,
    stop_replies: Vec<Reply>,
    /// The next time an owed stop may be tried again.
    stop_retry_at: Option<Instant>,
    wish: Option<Pending<Velocity>>,
    place: Option<Pending<Place>>,
    queue: VecDeque<(Queued, Instant)>,
    status: Status,
    identity: Option<Identity>,
    /// The task ends once the owed stops are sent.
    closing: bool,
    /// The rule gcud refused the last drive command by (logged once).
    last_refusal: Option<Undelivered>,
    /// Axes set to zero beside a pending move ([`GimbalSession::post_velocity`]):
    /// owed once that move is in force.
    wish_stops: Axes,
    /// gcud's rules of the gimbal, when last asked ([`GimbalSession::rules`]).
    rules: Option<(Instant, Rules)>,
}

impl State {
    /// The axes slewing or about to.
    fn moving(&self) -> Axes {
        let (w_pan, w_tilt, w_zoom) = self.wish.as_ref().map_or((false, false, false), |w| {
            (moves(w.what.pan), moves(w.what.tilt), moves(w.what.zoom))
        });
        Axes {
            pan: self.pan.drive != Drive::Stop || w_pan,
            tilt: self.tilt.drive != Drive::Stop || w_tilt,
            zoom: self.zoom.drive != Drive::Stop || w_zoom,
        }
    }

    fn motion(&self) -> Motion {
        if self.stops_owed.any() && self.stop_failures > 0 {
            Motion::Unknown
        } else if self.moving().any() || self.place.is_some() || self.status.changing || self.stops_owed.any() {
            Motion::Moving
        } else {
            Motion::Idle
        }
    }

    /// Owes the stops of `axes`: pending velocities of those axes are
    /// dropped (they came before the stop).
    fn owe_stop(&mut self, axes: Axes) {
        self.stops_owed = self.stops_owed.or(axes);
        self.wish_stops = self.wish_stops.without(axes);
        if let Some(w) = &mut self.wish {
            if axes.pan {
                w.what.pan = None;
            }
            if axes.tilt {
                w.what.tilt = None;
            }
            if axes.zoom {
                w.what.zoom = None;
            }
            if w.what == Velocity::default() {
                let w = self.wish.take().expect("checked");
                answer(w.replies, Ok(()));
                // The zeros beside the move it ended are owed with it.
                self.stops_owed = self.stops_owed.or(std::mem::take(&mut self.wish_stops));
            }
        }
        if axes.pan || axes.tilt {
            if let Some(p) = self.place.take() {
                answer(p.replies, Ok(()));
            }
        }
    }

    /// The deadline has passed: the stops of whatever moves are owed.
    fn expire(&mut self, now: Instant, name: &str) {
        if self.deadline.is_some_and(|d| d <= now) {
            self.deadline = None;
            let moving = self.moving().or(std::mem::take(&mut self.wish_stops));
            if let Some(w) = self.wish.take() {
                // Its time ran out before it could be carried out (a stop owed first).
                answer(
                    w.replies,
                    Err(CommandError::Io(
                        "the move's time ran out before it could start".to_owned(),
                    )),
                );
            }
            if moving.any() {
                info!(gimbal = name, owner = %self.owner, "move time-out: stopping");
                self.owe_stop(moving);
            }
        }
    }

    /// Drops what waited past [`STALE`].
    fn drop_stale(&mut self, now: Instant) {
        let stale = |asked: Instant| now.duration_since(asked) >= STALE;
        let error = || {
            CommandError::Io(format!(
                "not sent within {} s: gcud or the bus is unavailable",
                STALE.as_secs()
            ))
        };
        if self.wish.as_ref().is_some_and(|w| stale(w.asked)) {
            answer(self.wish.take().expect("checked").replies, Err(error()));
            let stops = std::mem::take(&mut self.wish_stops);
            if stops.any() {
                self.owe_stop(stops);
            }
        }
        if self.place.as_ref().is_some_and(|p| stale(p.asked)) {
            answer(self.place.take().expect("checked").replies, Err(error()));
        }
        while self.queue.front().is_some_and(|(_, asked)| stale(*asked)) {
            let (queued, _) = self.queue.pop_front().expect("checked");
            queued.fail(error());
        }
    }
}

/// Whether `d` asks an axis to slew.
fn moves<S>(d: Option<Drive<S>>) -> bool {
    matches!(d, Some(Drive::Forward(_) | Drive::Back(_)))
}

fn answer(replies: Vec<Reply>, result: Result<(), CommandError>) {
    for r in replies {
        let _ = r.send(result.clone());
    }
}

/// What the task does next.
enum Step {
    Stop(Command<'static>, Axes),
    /// A drive command, and the axis once it is acknowledged.
    Drive(Command<'static>, Applied),
    Place(Place),
    Query(Queued),
    Poll,
    Wait(Option<Instant>),
    End,
}

/// One axis as it is once a drive command is acknowledged.
#[derive(Clone, Copy, Debug)]
enum Applied {
    Pan(InForce<Speed>),
    Tilt(InForce<Speed>),
    Zoom(InForce<LensSpeed>),
}

impl Applied {
    fn axes(self) -> Axes {
        match self {
            Applied::Pan(_) => Axes {
                pan: true,
                ..Axes::default()
            },
            Applied::Tilt(_) => Axes {
                tilt: true,
                ..Axes::default()
            },
            Applied::Zoom(_) => Axes {
                zoom: true,
                ..Axes::default()
            },
        }
    }
}

/// One gimbal's session; see the module's documentation.
pub struct GimbalSession {
    pub config: SessionConfig,
    state: Mutex<State>,
    wake: Notify,
    reach: Arc<GcudReachability>,
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
        let connection = GimbalConnection::new(&config.gcud, config.from, config.address, config.nic_window);
        let session = Arc::new(Self {
            config,
            state: Mutex::new(State::default()),
            wake: Notify::new(),
            reach,
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
            motion: s.motion(),
            ..s.status.clone()
        }
    }

    /// Sets `velocity` for `run` (at most `max_move`; the motion's new
    /// deadline, for every axis still moving), owned by `owner`. An axis at
    /// [`Drive::Stop`] is a stop, owed at once. Returns once the velocity
    /// is in force or superseded by a newer one or a stop.
    pub async fn velocity(&self, velocity: Velocity, run: Option<Duration>, owner: &str) -> Result<(), CommandError> {
        let rx = self.post_velocity(velocity, run, owner);
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// [`GimbalSession::velocity`] without waiting: the receiver tells
    /// the outcome.
    pub fn post_velocity(
        &self,
        velocity: Velocity,
        run: Option<Duration>,
        owner: &str,
    ) -> oneshot::Receiver<Result<(), CommandError>> {
        let (tx, rx) = oneshot::channel();
        let now = Instant::now();
        {
            let mut s = self.state();
            let stops = Axes {
                pan: velocity.pan == Some(Drive::Stop),
                tilt: velocity.tilt == Some(Drive::Stop),
                zoom: velocity.zoom == Some(Drive::Stop),
            };
            let moves = Velocity {
                pan: velocity.pan.filter(|d| *d != Drive::Stop),
                tilt: velocity.tilt.filter(|d| *d != Drive::Stop),
                zoom: velocity.zoom.filter(|d| *d != Drive::Stop),
            };
            let moved = Axes {
                pan: moves.pan.is_some(),
                tilt: moves.tilt.is_some(),
                zoom: moves.zoom.is_some(),
            };
            if !moved.any() {
                if stops.any() {
                    s.owe_stop(stops);
                }
            } else if stops.any() {
                // A zero beside a move is part of that move: that axis stops
                // once the move is in force, and not at all when gcud refuses
                // the move for control (a refused request changes nothing:
                // the holder's motion is not this door's to stop).
                if let Some(w) = &mut s.wish {
                    w.what.pan = w.what.pan.filter(|_| !stops.pan);
                    w.what.tilt = w.what.tilt.filter(|_| !stops.tilt);
                    w.what.zoom = w.what.zoom.filter(|_| !stops.zoom);
                }
                s.wish_stops = s.wish_stops.or(stops);
                if stops.pan || stops.tilt {
                    if let Some(p) = s.place.take() {
                        answer(p.replies, Ok(()));
                    }
                }
            }
            // Newest wins: an axis moved now is no longer to be stopped.
            s.wish_stops = s.wish_stops.without(moved);
            if moves != Velocity::default() {
                // Newest wins, per axis; the replaced callers learn the newest's outcome.
                let mut replies = s.wish.take().map(|w| (w.what, w.replies)).unwrap_or_default();
                let merged = Velocity {
                    pan: moves.pan.or(replies.0.pan),
                    tilt: moves.tilt.or(replies.0.tilt),
                    zoom: moves.zoom.or(replies.0.zoom),
                };
                replies.1.push(tx);
                s.wish = Some(Pending {
                    what: merged,
                    asked: now,
                    replies: replies.1,
                });
                if moves.pan.is_some() || moves.tilt.is_some() {
                    if let Some(p) = s.place.take() {
                        answer(p.replies, Ok(()));
                    }
                }
            } else {
                s.stop_replies.push(tx);
            }
            if moves != Velocity::default() {
                // The motion is renewed: its new deadline covers every axis still moving.
                let run = run.unwrap_or(self.config.max_move).min(self.config.max_move);
                s.deadline = Some(now + run);
                s.owner = owner.to_owned();
            } else if !s.moving().any() {
                s.deadline = None;
            }
        }
        self.wake.notify_one();
        rx
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
        {
            let mut s = self.state();
            s.owe_stop(axes);
            s.stop_replies.push(tx);
            if !s.moving().any() {
                s.deadline = None;
            }
        }
        self.wake.notify_one();
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    async fn place(&self, place: Place) -> Result<(), CommandError> {
        let (tx, rx) = oneshot::channel();
        {
            let mut s = self.state();
            if let Some(old) = s.place.take() {
                answer(old.replies, Ok(()));
            }
            // A positioning move supersedes the pan/tilt slew on the gimbal.
            if let Some(w) = &mut s.wish {
                w.what.pan = None;
                w.what.tilt = None;
            }
            s.wish_stops.pan = false;
            s.wish_stops.tilt = false;
            s.place = Some(Pending {
                what: place,
                asked: Instant::now(),
                replies: vec![tx],
            });
        }
        self.wake.notify_one();
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// `GO` (Table 15).
    pub async fn go_to(&self, target: Position) -> Result<(), CommandError> {
        self.place(Place::GoTo(target)).await
    }

    /// `Pnn` (Table 11).
    pub async fn go_to_preset(&self, n: u8) -> Result<(), CommandError> {
        self.place(Place::Preset(n)).await
    }

    /// `HO`.
    pub async fn home(&self) -> Result<(), CommandError> {
        self.place(Place::Home).await
    }

    /// Any other command (a query, `SVnn`, `V`): its result payload, if it
    /// has one. At most [`QUEUE`] wait; more are refused.
    pub async fn send(&self, command: Command<'static>) -> Result<Option<Vec<u8>>, CommandError> {
        let (tx, rx) = oneshot::channel();
        self.enqueue(Queued::Bus(command, tx), command.mnemonic())?;
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    /// A GCU command to gcud (module `governance`), in the queue with the
    /// other commands: answered by gcud itself, no bus time.
    pub async fn gcu(&self, request: GcuRequest) -> Result<GcuAnswer, CommandError> {
        let (tx, rx) = oneshot::channel();
        let what = format!("{request:?}");
        self.enqueue(Queued::Gcu(request, tx), &what)?;
        rx.await.unwrap_or_else(|_| Err(closed()))
    }

    fn enqueue(&self, queued: Queued, what: &str) -> Result<(), CommandError> {
        {
            let mut s = self.state();
            if s.queue.len() >= QUEUE {
                return Err(CommandError::Io(format!(
                    "{} commands already wait for gimbal {}: {what} refused",
                    QUEUE, self.config.name,
                )));
            }
            s.queue.push_back((queued, Instant::now()));
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
        let a = self.config.address;
        match self.gcu(GcuRequest::Release(a.port, a.device)).await? {
            GcuAnswer::Released => Ok(()),
            other => Err(CommandError::BadReply(format!("~R answered {other:?}"))),
        }
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
            let m = s.moving();
            let changing = s.status.changing || s.place.is_some();
            Axes {
                pan: m.pan || changing,
                tilt: m.tilt || changing,
                zoom: m.zoom,
            }
            .or(s.stops_owed)
            .or(s.wish_stops)
        };
        if axes.any() {
            if let Err(e) = self.stop(axes).await {
                warn!(gimbal = %self.config.name, error = %e, "stop at shutdown failed");
            }
        }
        self.state().closing = true;
        self.wake.notify_one();
    }

    /// The next step, decided under the lock.
    fn next(&self, now: Instant, next_poll: Instant) -> Step {
        let mut s = self.state();
        s.expire(now, &self.config.name);
        s.drop_stale(now);
        if s.closing && s.stop_failures >= STOP_ATTEMPTS_ANSWERED {
            // Stopping the program: the stop was tried and reported.
            return Step::End;
        }
        if s.stops_owed.any() {
            if s.stop_retry_at.is_some_and(|t| t > now) {
                return Step::Wait(s.stop_retry_at);
            }
            let (command, axes) = s.stops_owed.first().expect("owed");
            return Step::Stop(command, axes);
        }
        if s.closing {
            return Step::End;
        }
        if let Some(w) = &s.wish {
            let v = w.what;
            if let Some(step) = pan_tilt_step(Axis::Pan, v.pan, s.pan)
                .or_else(|| pan_tilt_step(Axis::Tilt, v.tilt, s.tilt))
                .or_else(|| zoom_step(v.zoom, s.zoom))
            {
                return step;
            }
            // Everything asked is in force; then the zeros beside it.
            let w = s.wish.take().expect("checked");
            answer(w.replies, Ok(()));
            let stops = std::mem::take(&mut s.wish_stops);
            if stops.any() {
                s.owe_stop(stops);
                let (command, axes) = s.stops_owed.first().expect("owed");
                return Step::Stop(command, axes);
            }
        }
        if let Some(p) = &s.place {
            return Step::Place(p.what);
        }
        if let Some((queued, _)) = s.queue.pop_front() {
            return Step::Query(queued);
        }
        let due = if s.moving().any() {
            next_poll.min(now + REFRESH)
        } else {
            next_poll
        };
        if due <= now {
            return Step::Poll;
        }
        Step::Wait(Some(s.deadline.map_or(due, |d| d.min(due))))
    }

    async fn run(self: Arc<Self>, mut connection: GimbalConnection) {
        let mut next_poll = Instant::now();
        let mut asked_control = None;
        loop {
            // What the connection last learnt of gcud's control (a poll, a refusal).
            self.state().status.control = connection.control();
            let now = Instant::now();
            match self.next(now, next_poll) {
                Step::End => return,
                Step::Wait(until) => {
                    let sleep = tokio::time::sleep_until(until.unwrap_or(now + UNREACHABLE_POLL));
                    tokio::select! {
                        () = sleep => {}
                        () = self.wake.notified() => {}
                    }
                }
                Step::Stop(command, axes) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    let mut s = self.state();
                    match sent {
                        Ok(_) => {
                            s.stops_owed = s.stops_owed.without(axes);
                            s.stop_retry_at = None;
                            if axes.pan {
                                s.pan.drive = Drive::Stop;
                            }
                            if axes.tilt {
                                s.tilt.drive = Drive::Stop;
                            }
                            if axes.zoom {
                                s.zoom.drive = Drive::Stop;
                            }
                            if !s.stops_owed.any() {
                                s.stop_failures = 0;
                                let replies = std::mem::take(&mut s.stop_replies);
                                answer(replies, Ok(()));
                            }
                            if !s.moving().any() {
                                s.deadline = None;
                            }
                        }
                        Err(CommandError::Nic(e)) => {
                            // The gimbal cannot apply it (a zoom stop without a lens): nothing to retry.
                            warn!(gimbal = %self.config.name, error = %e, "{} refused by the gimbal", command.mnemonic());
                            s.stops_owed = s.stops_owed.without(axes);
                            if !s.stops_owed.any() {
                                let replies = std::mem::take(&mut s.stop_replies);
                                answer(replies, Err(CommandError::Nic(e)));
                            }
                        }
                        Err(e)
                            if !matches!(e, CommandError::Io(_)) && s.stop_failures + 1 >= STOP_ATTEMPTS_ANSWERED =>
                        {
                            // gcud answered, the gimbal did not confirm (absent,
                            // noise): tried again once; owing it for ever would
                            // hold every other command of this gimbal.
                            warn!(gimbal = %self.config.name, error = %e, "{} not confirmed after {STOP_ATTEMPTS_ANSWERED} attempts: given up", command.mnemonic());
                            s.stops_owed = s.stops_owed.without(axes);
                            s.stop_failures = 0;
                            s.stop_retry_at = None;
                            if !s.stops_owed.any() {
                                let replies = std::mem::take(&mut s.stop_replies);
                                answer(replies, Err(e));
                            }
                        }
                        Err(e) => {
                            s.stop_failures += 1;
                            let retry = if matches!(e, CommandError::Io(_)) {
                                STOP_RETRY
                            } else {
                                (STOP_RETRY * s.stop_failures).min(UNREACHABLE_POLL)
                            };
                            s.stop_retry_at = Some(Instant::now() + retry);
                            if s.stop_failures.is_power_of_two() {
                                warn!(gimbal = %self.config.name, error = %e, attempt = s.stop_failures, "{} not confirmed: kept owed, sent again", command.mnemonic());
                            }
                            if s.stop_failures >= STOP_ATTEMPTS_ANSWERED {
                                let replies = std::mem::take(&mut s.stop_replies);
                                answer(replies, Err(e));
                            }
                        }
                    }
                }
                Step::Drive(command, applied) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    let mut s = self.state();
                    match sent {
                        Ok(_) => {
                            s.last_refusal = None;
                            match applied {
                                Applied::Pan(a) => s.pan = a,
                                Applied::Tilt(a) => s.tilt = a,
                                Applied::Zoom(a) => s.zoom = a,
                            }
                        }
                        Err(e) if e.refusal().is_some() => {
                            // gcud refused it by its rules: nothing reached
                            // the bus, the axis did not start.
                            if let Some(w) = s.wish.take() {
                                answer(w.replies, Err(e.clone()));
                            }
                            let zeros = std::mem::take(&mut s.wish_stops);
                            if e.refusal() == Some(Undelivered::NotInControl) {
                                // Another link holds the gimbal: its motion is
                                // not this door's to stop, and gcud stopped
                                // ours when that link took control. What was
                                // set here (speeds too) is set again next time.
                                s.pan = InForce::default();
                                s.tilt = InForce::default();
                                s.zoom = InForce::default();
                            } else {
                                // Never leave an axis moving that the caller was told failed.
                                let ours = Axes {
                                    pan: s.pan.drive != Drive::Stop,
                                    tilt: s.tilt.drive != Drive::Stop,
                                    zoom: s.zoom.drive != Drive::Stop,
                                }
                                .or(zeros);
                                if ours.any() {
                                    s.owe_stop(ours);
                                }
                            }
                            if !s.moving().any() {
                                s.deadline = None;
                            }
                            if s.last_refusal != e.refusal() {
                                s.last_refusal = e.refusal();
                                info!(gimbal = %self.config.name, error = %e, "{} refused by gcud (logged once until something is accepted or refused otherwise)", command.mnemonic());
                            }
                        }
                        Err(e) => {
                            // Never leave an axis moving that the caller was told failed.
                            let axes = s.moving().or(std::mem::take(&mut s.wish_stops));
                            if let Some(w) = s.wish.take() {
                                answer(w.replies, Err(e.clone()));
                            }
                            s.owe_stop(axes.or(applied.axes()));
                            warn!(gimbal = %self.config.name, error = %e, "{} failed: stopping the motion", command.mnemonic());
                        }
                    }
                }
                Step::Place(place) => {
                    let sent = connection.send(&place.command()).await;
                    self.reached(&sent);
                    let mut s = self.state();
                    if let Some(p) = s.place.take() {
                        if sent.is_ok() {
                            // The gimbal goes there instead of slewing.
                            s.pan.drive = Drive::Stop;
                            s.tilt.drive = Drive::Stop;
                            if !s.moving().any() {
                                s.deadline = None;
                            }
                        }
                        answer(p.replies, sent.map(drop));
                    }
                }
                Step::Query(Queued::Bus(command, reply)) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    let _ = reply.send(sent);
                }
                Step::Query(Queued::Gcu(request, reply)) => {
                    let a = self.config.address;
                    let answer = if request == GcuRequest::Controller(a.port, a.device) {
                        // This gimbal's: kept for the status too.
                        connection.controller().await.map(GcuAnswer::Controller)
                    } else {
                        connection.gcu(&request).await
                    };
                    self.reached(&answer);
                    let _ = reply.send(answer);
                }
                Step::Poll => {
                    let reading = poll(&mut connection, self.config.lens).await;
                    self.reached(&reading);
                    let failed = reading.is_err();
                    {
                        let mut s = self.state();
                        let st = &mut s.status;
                        match reading {
                            Ok((p, lens)) => {
                                st.changing =
                                    st.position.is_some_and(|old| old != p) || (st.lens.is_some() && st.lens != lens);
                                st.position = Some(p);
                                st.lens = lens;
                                st.error = None;
                            }
                            Err(e) => {
                                st.changing = false;
                                st.error = Some(e.to_string());
                            }
                        }
                    }
                    if !failed && asked_control.is_none_or(|t: Instant| t.elapsed() >= CONTROL_POLL) {
                        asked_control = Some(Instant::now());
                        // Unknown while it fails (a gcud that governs nothing answers NIC).
                        let _ = connection.controller().await;
                    }
                    let poll = self.config.poll;
                    next_poll = Instant::now() + if failed { UNREACHABLE_POLL.max(poll) } else { poll };
                }
            }
        }
    }

    fn reached<T>(&self, result: &Result<T, CommandError>) {
        match result {
            Err(e @ CommandError::Io(_)) => {
                self.reach.down(&self.config.gcud, e);
                // The connection is gone: gcud's dead-man stopped what it
                // started, unless gcud itself is gone; either way owe the stops.
                let mut s = self.state();
                let moving = s.moving();
                if moving.any() {
                    s.stops_owed = s.stops_owed.or(moving);
                }
            }
            _ => self.reach.up(&self.config.gcud),
        }
    }
}

fn closed() -> CommandError {
    CommandError::Io("the gimbal session has ended".to_owned())
}

/// The next command that moves one axis from `now` toward `want`, with
/// the axis after it. A speed (`SPn`, `STn`, `Zn`) is taken by the next
/// direction command, so each speed set is followed by its direction
/// command before another speed: a stream of changing rates alternates the
/// two and always progresses.
fn next_drive<S: Copy + PartialEq>(
    want: Option<Drive<S>>,
    now: InForce<S>,
    speed_command: impl Fn(S) -> Command<'static>,
    direction_command: impl Fn(Drive<S>) -> Command<'static>,
) -> Option<(Command<'static>, InForce<S>)> {
    let want = want?;
    let speed = want.speed()?;
    let same_direction = matches!(
        (now.drive, want),
        (Drive::Forward(_), Drive::Forward(_)) | (Drive::Back(_), Drive::Back(_))
    );
    let Some(set) = now.speed else {
        let after = InForce {
            speed: Some(speed),
            drive: now.drive,
        };
        return Some((speed_command(speed), after));
    };
    let at_set = match want {
        Drive::Forward(_) => Drive::Forward(set),
        _ => Drive::Back(set),
    };
    if !same_direction || now.drive.speed() != Some(set) {
        // Start, turn, or apply the speed set last.
        let after = InForce {
            speed: Some(set),
            drive: at_set,
        };
        return Some((direction_command(at_set), after));
    }
    if set != speed {
        let after = InForce {
            speed: Some(speed),
            drive: now.drive,
        };
        return Some((speed_command(speed), after));
    }
    None
}

/// [`next_drive`] for pan or tilt (Table 11: `SPn`/`STn`, `PR`/`PL`/`TU`/`TD`).
fn pan_tilt_step(axis: Axis, want: Option<Drive<Speed>>, now: InForce<Speed>) -> Option<Step> {
    let (command, after) = next_drive(
        want,
        now,
        |s| Command::SetSpeed(axis, s),
        |d| match (axis, d) {
            (Axis::Pan, Drive::Forward(_)) => Command::PanRight,
            (Axis::Pan, _) => Command::PanLeft,
            (Axis::Tilt, Drive::Forward(_)) => Command::TiltUp,
            (Axis::Tilt, _) => Command::TiltDown,
        },
    )?;
    Some(Step::Drive(
        command,
        match axis {
            Axis::Pan => Applied::Pan(after),
            Axis::Tilt => Applied::Tilt(after),
        },
    ))
}

/// [`next_drive`] for the zoom (Table 16: `Zn`, `ZI`/`ZO`).
fn zoom_step(want: Option<Drive<LensSpeed>>, now: InForce<LensSpeed>) -> Option<Step> {
    let (command, after) = next_drive(want, now, Command::ZoomSpeed, |d| match d {
        Drive::Forward(_) => Command::ZoomIn,
        _ => Command::ZoomOut,
    })?;
    Some(Step::Drive(command, Applied::Zoom(after)))
}

async fn poll(connection: &mut GimbalConnection, lens: bool) -> Result<(Position, Option<LensPosition>), CommandError> {
    let position = connection.position().await?;
    let lens = if lens { Some(connection.lens().await?) } else { None };
    Ok((position, lens))
}
