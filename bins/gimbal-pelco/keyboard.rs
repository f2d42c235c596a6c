//! One keyboard (a serial line, a TCP connection, a UDP source): its
//! frames, in the order they came, turned into the gimbals' sessions'
//! requests, and the answers to its position queries.
//!
//! - **Motion** (the standard command): each frame is the state of every
//!   axis, so it is one velocity for the addressed gimbal, posted at once
//!   (never queued here: the session coalesces velocities, newest wins, and
//!   sends stops first, so a stop overtakes the drives before it). A
//!   keyboard repeats the frame while the stick is held; each repeat renews
//!   the drive's lease (`motion_lease_ms`), and a drive not repeated
//!   within it is stopped by the session.
//! - **Stop** (nothing moving) stops what this keyboard started on that
//!   gimbal, once: an idle keyboard that repeats its stop costs no bus
//!   time, and one whose drive gcud refused stops nothing (the motion is
//!   the holder's). Likewise an axis a frame leaves still is stopped only
//!   when this keyboard moved it: a pan alone leaves another tool's tilt
//!   be.
//! - **Presets, absolute moves and queries** wait for gcud in tasks of
//!   their own, at most [`BUSY`] per keyboard; more are dropped (logged).
//!   Position queries are answered `59`/`5B` from the session's last
//!   poll (a fresh `P?` when it failed), nothing before it (no general
//!   response).
//! - gcud's refusals are logged at INFO in words, at most once per
//!   [`REFUSAL_LOG_EVERY`] per keyboard and gimbal unless the reason changes.

use std::collections::HashMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

use sagebrush_client::CommandError;
use sagebrush_client::connection::proportional_speed;
use sagebrush_client::session::{Drive, Velocity};
use sagebrush_protocol::{LensSpeed, Speed};
use sagebrush_service::door_metrics::{DoorMetrics, HeardLately};
use tokio::sync::Semaphore;
use tracing::{debug, info, warn};

use crate::codec::{Frame, Protocol};
use crate::command::{self, Rate, Request, Way};
use crate::gimbal::{AxisTo, Gimbal};
use crate::stats::{Stats, may_log};

/// Presets, absolute moves, queries and outcome watchers in progress per
/// keyboard, at most.
pub const BUSY: usize = 8;
/// A refusal for the same reason is logged at most this often.
pub const REFUSAL_LOG_EVERY: Duration = Duration::from_secs(5);

/// What the keyboards of one `[[input]]` share.
#[derive(Debug)]
pub struct Door {
    /// By wire address byte of this input's protocol.
    pub gimbals: HashMap<u8, Arc<Gimbal>>,
    pub protocol: Protocol,
    pub principal: Option<String>,
    pub input: String,
    /// A drive's lease (or the longest drive, with the lease off).
    pub run: Duration,
    pub stats: Arc<Stats>,
    /// The door's metrics: each frame for a gimbal counted by its kind.
    pub metrics: Arc<DoorMetrics>,
    /// The door's keyboards live now (every input's).
    pub sessions: Arc<Sessions>,
}

/// The keyboards live now, for the door's metrics: a serial line open, a
/// TCP connection, a UDP source heard within [`UDP_LIVE`].
#[derive(Debug)]
pub struct Sessions {
    /// Serial lines open and TCP connections.
    pub streams: AtomicUsize,
    pub udp: HeardLately,
}

/// A UDP keyboard counts as live this long after its last datagram (a
/// keyboard repeats its frame while a key is held, and sends nothing
/// when idle).
pub const UDP_LIVE: Duration = Duration::from_secs(10);

impl Sessions {
    /// `udp_sources`: the UDP keyboards kept at most (`[limits]`).
    pub fn new(udp_sources: usize) -> Self {
        Self {
            streams: AtomicUsize::new(0),
            udp: HeardLately::new(udp_sources, UDP_LIVE),
        }
    }

    pub fn live(&self) -> usize {
        self.streams.load(Ordering::Relaxed) + self.udp.live()
    }
}

impl Door {
    pub fn new(
        input: &crate::config::Input,
        gimbals: &[Arc<Gimbal>],
        run: Duration,
        stats: Arc<Stats>,
        metrics: (Arc<DoorMetrics>, Arc<Sessions>),
    ) -> Arc<Self> {
        let protocol = input.protocol;
        let (metrics, sessions) = metrics;
        Arc::new(Self {
            gimbals: gimbals
                .iter()
                .map(|g| (protocol.wire_address(g.config.pelco_address), Arc::clone(g)))
                .collect(),
            protocol,
            principal: input.principal.clone(),
            input: input.name.clone(),
            run,
            stats,
            metrics,
            sessions,
        })
    }
}

/// Where a keyboard's answers go (its connection's writer, or a datagram
/// to its address).
pub type Replies = Arc<dyn Fn(Vec<u8>) + Send + Sync>;

/// What this keyboard has moving on one gimbal (as far as it knows: a
/// drive the lease stopped still counts until its stop).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Moving {
    pan: bool,
    tilt: bool,
    zoom: bool,
    /// A positioning move (preset, absolute): its stop is pan and tilt.
    place: bool,
}

impl Moving {
    fn any(self) -> bool {
        self.pan || self.tilt || self.zoom || self.place
    }
}

#[derive(Debug, Default)]
struct PerGimbal {
    moving: Moving,
    /// Zoom lens speed 0-3 (`25`), the fastest until set.
    zoom_speed: Option<u8>,
    refusal: Option<(String, Instant)>,
}

/// One keyboard; see the module's documentation.
pub struct Keyboard {
    door: Arc<Door>,
    /// Who it is in logs: the input and the peer.
    pub who: Arc<str>,
    replies: Replies,
    state: Arc<Mutex<HashMap<u8, PerGimbal>>>,
    busy: Arc<Semaphore>,
}

impl std::fmt::Debug for Keyboard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Keyboard").field("who", &self.who).finish()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Polls `fut` once, outside any task: `Some` if it is done already. A
/// session's request is posted at its first poll, so this keeps a
/// keyboard's requests in the order of its frames.
pub fn poll_once<F: Future + Unpin>(fut: &mut F) -> Option<F::Output> {
    match Pin::new(fut).poll(&mut Context::from_waker(Waker::noop())) {
        Poll::Ready(out) => Some(out),
        Poll::Pending => None,
    }
}

/// A Pelco pan or tilt speed as the gimbal's proportional speed (Table
/// 11, 0..=15): growing with the step asked, `3F` and turbo the fastest.
pub fn speed_of(rate: Rate) -> Speed {
    match rate {
        Rate::Step(s) => proportional_speed(f64::from(s.min(command::MAX_STEP)) / 63.0),
        Rate::Turbo => proportional_speed(1.0),
    }
}

/// A Pelco zoom speed (0-3) as the lens speed (Table 16, 0..=9).
fn lens_speed_of(zoom_speed: Option<u8>) -> LensSpeed {
    let n = match zoom_speed {
        Some(s) => [2, 5, 7, 9][usize::from(s.min(3))],
        None => 9,
    };
    LensSpeed::new(n).unwrap_or(LensSpeed::new(9).expect("in range"))
}

/// An axis's part of a velocity: driven while `moving`, stopped when it
/// `was` moving, else left as it is.
fn axis<S>(moving: bool, was: bool, drive: Drive<S>) -> Option<Drive<S>> {
    (moving || was).then_some(drive)
}

fn drive<S>(axis: Option<(Way, S)>) -> Drive<S> {
    match axis {
        Some((Way::Positive, s)) => Drive::Forward(s),
        Some((Way::Negative, s)) => Drive::Back(s),
        None => Drive::Stop,
    }
}

impl Keyboard {
    pub fn new(door: Arc<Door>, peer: &str, replies: Replies) -> Self {
        let who: Arc<str> = if peer.is_empty() {
            door.input.clone().into()
        } else {
            format!("{} from {peer}", door.input).into()
        };
        Self {
            door,
            who,
            replies,
            state: Arc::default(),
            busy: Arc::new(Semaphore::new(BUSY)),
        }
    }

    /// Carries out one intact frame.
    pub fn frame(&self, frame: &Frame) {
        Stats::count(&self.door.stats.frames);
        let Some(gimbal) = self.door.gimbals.get(&frame.address) else {
            // Another device's on a shared bus, or a keyboard set wrong.
            Stats::count(&self.door.stats.not_ours);
            debug!(keyboard = %self.who, address = frame.address, "a frame for an address no [[gimbal]] has");
            return;
        };
        let request = Request::of(self.door.protocol, frame);
        self.door.metrics.request(request.kind());
        debug!(keyboard = %self.who, gimbal = %gimbal.config.name, ?request, "frame");
        match request {
            Request::Motion { pan, tilt, zoom } => self.motion(gimbal, pan, tilt, zoom),
            Request::ZoomSpeed(s) => self.with(gimbal, |g| g.zoom_speed = Some(s)),
            Request::ClearPreset(n) => {
                gimbal.clear_preset(n);
                info!(keyboard = %self.who, gimbal = %gimbal.config.name, preset = n, "preset cleared: a go to it is ignored until it is set again");
            }
            Request::GoToPreset(n) if gimbal.is_cleared(n) => {
                info!(keyboard = %self.who, gimbal = %gimbal.config.name, preset = n, "go to preset ignored: a keyboard cleared it");
            }
            Request::Unsupported(op) => {
                Stats::count(&self.door.stats.unsupported);
                if may_log("unsupported", &self.who).is_some() {
                    info!(keyboard = %self.who, opcode = format!("{op:02X}"), "extended command not carried out (not one of 03 05 07 25 4B 4D 51 53)");
                }
            }
            other => self.spawn(gimbal, other),
        }
    }

    fn with<R>(&self, gimbal: &Gimbal, f: impl FnOnce(&mut PerGimbal) -> R) -> R {
        f(lock(&self.state).entry(gimbal.config.pelco_address).or_default())
    }

    fn motion(&self, gimbal: &Arc<Gimbal>, pan: Option<(Way, Rate)>, tilt: Option<(Way, Rate)>, zoom: Option<Way>) {
        let lens = gimbal.config.zoom;
        let zoom = zoom.filter(|_| lens);
        let now = Moving {
            pan: pan.is_some(),
            tilt: tilt.is_some(),
            zoom: zoom.is_some(),
            place: false,
        };
        let (before, zoom_speed) = self.with(gimbal, |g| (std::mem::replace(&mut g.moving, now), g.zoom_speed));
        if !now.any() && !before.any() {
            // An idle keyboard repeating its stop: nothing to stop.
            Stats::count(&self.door.stats.stops_not_sent);
            return;
        }
        // An axis moving now is driven; one this keyboard moved before and
        // not now is stopped; the others are left as they are.
        let velocity = Velocity {
            pan: axis(
                now.pan,
                before.pan || before.place,
                drive(pan.map(|(w, r)| (w, speed_of(r)))),
            ),
            tilt: axis(
                now.tilt,
                before.tilt || before.place,
                drive(tilt.map(|(w, r)| (w, speed_of(r)))),
            ),
            zoom: axis(
                now.zoom,
                before.zoom,
                drive(zoom.map(|w| (w, lens_speed_of(zoom_speed)))),
            ),
        };
        let outcome = gimbal.session.acting_for(self.door.principal.as_deref()).post_velocity(
            velocity,
            Some(self.door.run),
            &self.who,
        );
        gimbal.set_driver(&self.who);
        // Whether gcud took it is watched aside, when there is room.
        let Ok(permit) = Arc::clone(&self.busy).try_acquire_owned() else {
            return;
        };
        let watcher = self.watcher(gimbal);
        tokio::spawn(async move {
            let result = outcome.await.unwrap_or(Ok(()));
            // Replaced by another keyboard's velocity: its outcome is not ours.
            if watcher.gimbal.is_driver(&watcher.who) {
                watcher.outcome("the drive", result);
            }
            drop(permit);
        });
    }

    /// Presets, absolute moves and queries: their first step taken now (in
    /// frame order), the rest in a task, at most [`BUSY`] at once.
    fn spawn(&self, gimbal: &Arc<Gimbal>, request: Request) {
        let Ok(permit) = Arc::clone(&self.busy).try_acquire_owned() else {
            Stats::count(&self.door.stats.dropped_busy);
            if may_log("busy", &self.who).is_some() {
                warn!(keyboard = %self.who, gimbal = %gimbal.config.name, ?request, busy = BUSY, "request dropped: this keyboard has too many waiting for gcud");
            }
            return;
        };
        if matches!(request, Request::GoToPreset(_) | Request::PanTo(_) | Request::TiltTo(_)) {
            self.with(gimbal, |g| {
                g.moving = Moving {
                    place: true,
                    ..Moving::default()
                }
            });
        }
        let g = Arc::clone(gimbal);
        let principal = self.door.principal.clone();
        let protocol = self.door.protocol;
        let wire = protocol.wire_address(gimbal.config.pelco_address);
        let replies = Arc::clone(&self.replies);
        let watcher = self.watcher(gimbal);
        let mut work = Box::pin(async move {
            let p = principal.as_deref();
            let (what, result) = match request {
                Request::SetPreset(n) => ("the preset store", g.store_preset(n, p).await),
                Request::GoToPreset(n) => ("the go to preset", g.session.acting_for(p).go_to_preset(n).await),
                Request::PanTo(h) => (
                    "the absolute pan",
                    g.go_to_axis(AxisTo::Pan(command::pan_degrees(h)), p).await,
                ),
                Request::TiltTo(h) => (
                    "the absolute tilt",
                    g.go_to_axis(AxisTo::Tilt(command::tilt_degrees(h)), p).await,
                ),
                Request::QueryPan | Request::QueryTilt => {
                    let tilt = request == Request::QueryTilt;
                    let answered = g.polled_position().await.map(|(pan, t)| {
                        let h = if tilt {
                            command::tilt_hundredths(t)
                        } else {
                            command::pan_hundredths(pan)
                        };
                        replies(command::position_reply(protocol, wire, tilt, h));
                    });
                    ("the position query", answered)
                }
                _ => ("nothing", Ok(())),
            };
            watcher.outcome(what, result);
            drop(permit);
        });
        if poll_once(&mut work).is_none() {
            tokio::spawn(work);
        }
    }

    fn watcher(&self, gimbal: &Arc<Gimbal>) -> Watcher {
        Watcher {
            who: Arc::clone(&self.who),
            principal: self.door.principal.clone(),
            gimbal: Arc::clone(gimbal),
            state: Arc::clone(&self.state),
            stats: Arc::clone(&self.door.stats),
        }
    }
}

/// Logs what became of a keyboard's request.
struct Watcher {
    who: Arc<str>,
    principal: Option<String>,
    gimbal: Arc<Gimbal>,
    state: Arc<Mutex<HashMap<u8, PerGimbal>>>,
    stats: Arc<Stats>,
}

impl Watcher {
    fn outcome(&self, what: &str, result: Result<(), CommandError>) {
        let Err(e) = result else { return };
        let name = &self.gimbal.config.name;
        if e.refusal().is_some() {
            Stats::count(&self.stats.refused);
            let reason = e.to_string();
            let now = Instant::now();
            let log = {
                let mut state = lock(&self.state);
                let g = state.entry(self.gimbal.config.pelco_address).or_default();
                // Refused: nothing of this keyboard's moves, its stop would stop the holder's.
                g.moving = Moving::default();
                let log = g
                    .refusal
                    .as_ref()
                    .is_none_or(|(r, at)| *r != reason || now.duration_since(*at) >= REFUSAL_LOG_EVERY);
                if log {
                    g.refusal = Some((reason.clone(), now));
                }
                log
            };
            if log {
                let principal = self.principal.as_deref().unwrap_or("the door's own");
                info!(keyboard = %self.who, gimbal = %name, principal, "gcud refused {what} of {name} for {} (principal {principal}): {reason}", self.who);
            }
        } else if may_log("failed", &self.who).is_some() {
            warn!(keyboard = %self.who, gimbal = %name, error = %e, "{what} failed");
        }
    }
}
