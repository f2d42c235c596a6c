//! What a gimbal session has been asked and what it has told the gimbal,
//! under the session's one lock: the axes in force, the owed stops, the
//! pending velocity and positioning move, the short queue and its
//! staleness (ARCHITECTURE "Front doors": stops first, bounded work).

use super::travel::Travel;
use super::*;

pub(super) type Reply = oneshot::Sender<Result<(), CommandError>>;
pub(super) type Answer = oneshot::Sender<Result<Option<Vec<u8>>, CommandError>>;
pub(super) type GcuReply = oneshot::Sender<Result<GcuAnswer, CommandError>>;

/// A request waiting in the queue: a command to the gimbal, or one to gcud.
pub(super) enum Queued {
    Bus(Command<'static>, Answer),
    Gcu(GcuRequest, GcuReply),
}

impl Queued {
    pub(super) fn fail(self, e: CommandError) {
        match self {
            Queued::Bus(_, reply) => drop(reply.send(Err(e))),
            Queued::Gcu(_, reply) => drop(reply.send(Err(e))),
        }
    }
}

/// One side of the gimbal, as far as the session has told it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct InForce<S> {
    /// The speed last set (`SPn`, `STn`, `Zn`), while the session may
    /// believe the gimbal still has it ([`State::forget_speeds`]): a
    /// direction command at that speed is then sent without it.
    pub(super) speed: Option<S>,
    /// When the gimbal acknowledged that speed ([`SPEED_KEPT`]).
    pub(super) speed_at: Option<Instant>,
    /// The slew started last and not stopped since.
    pub(super) drive: Drive<S>,
}

impl<S> Default for InForce<S> {
    fn default() -> Self {
        Self {
            speed: None,
            speed_at: None,
            drive: Drive::Stop,
        }
    }
}

impl<S: PartialEq> InForce<S> {
    /// The speed is no longer believed (the slew in force stays as it is).
    fn forget_speed(&mut self) {
        self.speed = None;
        self.speed_at = None;
    }

    /// This, after its drive command was acknowledged at `now`, in place
    /// of `before`: a speed command (`set`) starts the time its speed is
    /// believed; a direction keeps the time of the speed it runs at (set
    /// by the command chained before it, whose ack this one did not see).
    pub(super) fn speed_set(mut self, set: bool, now: Instant, before: &Self) -> Self {
        if set {
            self.speed_at = Some(now);
        } else if self.speed == before.speed {
            self.speed_at = before.speed_at;
        }
        self
    }

    /// Forgets the speed once it was set [`SPEED_KEPT`] ago or longer.
    fn age_speed(&mut self, now: Instant) {
        if self.speed_at.is_none_or(|at| now.duration_since(at) >= SPEED_KEPT) {
            self.forget_speed();
        }
    }
}

/// A positioning move: supersedes a pan/tilt slew on the gimbal itself.
#[derive(Clone, Copy, Debug)]
pub(super) enum Place {
    GoTo(Position),
    Preset(u8),
    Home,
}

impl Place {
    pub(super) fn command(self) -> Command<'static> {
        match self {
            Place::GoTo(p) => Command::GoTo(p),
            Place::Preset(n) => Command::GoToPreset(n),
            Place::Home => Command::Home,
        }
    }
}

pub(super) struct Pending<T> {
    pub(super) what: T,
    pub(super) asked: Instant,
    /// The door's user it is for (ARCHITECTURE "Principals"; `None`: the door itself).
    pub(super) by: Option<Arc<str>>,
    pub(super) replies: Vec<Reply>,
}

#[derive(Default)]
pub(super) struct State {
    pub(super) pan: InForce<Speed>,
    pub(super) tilt: InForce<Speed>,
    pub(super) zoom: InForce<LensSpeed>,
    /// The motion's deadline, while anything moves or is about to.
    pub(super) deadline: Option<Instant>,
    /// Who owns the motion, for the logs.
    pub(super) owner: String,
    pub(super) stops_owed: Axes,
    /// Failed attempts at the owed stops since the last confirmed one.
    pub(super) stop_failures: u32,
    pub(super) stop_replies: Vec<Reply>,
    /// The next time an owed stop may be tried again.
    pub(super) stop_retry_at: Option<Instant>,
    pub(super) wish: Option<Pending<Velocity>>,
    pub(super) place: Option<Pending<Place>>,
    pub(super) queue: VecDeque<(Queued, Instant, Option<Arc<str>>)>,
    pub(super) status: Status,
    pub(super) identity: Option<Identity>,
    /// The task ends once the owed stops are sent.
    pub(super) closing: bool,
    /// The rule gcud refused the last drive command by (logged once).
    pub(super) last_refusal: Option<Undelivered>,
    /// Axes set to zero beside a pending move ([`GimbalSession::post_velocity`]):
    /// owed once that move is in force.
    pub(super) wish_stops: Axes,
    /// gcud's rules of the gimbal, when last asked ([`GimbalSession::rules`]).
    pub(super) rules: Option<(Instant, Rules)>,
    /// A positioning move gcud accepted, until the polls show it ended
    /// (module `travel`).
    pub(super) travel: Option<Travel>,
    /// The last motion was ended or refused because another controller
    /// holds the gimbal ([`Status::taken_by`]).
    pub(super) taken: bool,
}

impl State {
    /// The axes slewing or about to.
    pub(super) fn moving(&self) -> Axes {
        let (w_pan, w_tilt, w_zoom) = self.wish.as_ref().map_or((false, false, false), |w| {
            (moves(w.what.pan), moves(w.what.tilt), moves(w.what.zoom))
        });
        Axes {
            pan: self.pan.drive != Drive::Stop || w_pan,
            tilt: self.tilt.drive != Drive::Stop || w_tilt,
            zoom: self.zoom.drive != Drive::Stop || w_zoom,
        }
    }

    /// The session's motion, as the bus shows it: from the moment a move
    /// is asked (accepted, once its caller is answered) until the polls
    /// show it ended or a stop is confirmed (module `travel`); never a
    /// motion of another controller.
    pub(super) fn motion(&self) -> Motion {
        if self.stops_owed.any() && self.stop_failures > 0 {
            Motion::Unknown
        } else if self.moving().any()
            || self.place.is_some()
            || self.travel.is_some()
            || self.stops_owed.any()
            // The gimbal moving under another controller is not this session's motion.
            || (self.status.changing && self.another_holder().is_none())
        {
            Motion::Moving
        } else {
            Motion::Idle
        }
    }

    /// Owes the stops of `axes`: pending velocities of those axes are
    /// dropped (they came before the stop).
    pub(super) fn owe_stop(&mut self, axes: Axes) {
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

    /// What the session believes of the speeds set on the gimbal is
    /// forgotten: the next slew of each axis sets its speed again
    /// ([`SPEED_KEPT`] says when).
    pub(super) fn forget_speeds(&mut self) {
        self.pan.forget_speed();
        self.tilt.forget_speed();
        self.zoom.forget_speed();
    }

    /// Forgets the speeds set [`SPEED_KEPT`] ago or longer.
    pub(super) fn age_speeds(&mut self, now: Instant) {
        self.pan.age_speed(now);
        self.tilt.age_speed(now);
        self.zoom.age_speed(now);
    }

    /// The deadline has passed: the stops of whatever moves are owed.
    pub(super) fn expire(&mut self, now: Instant, name: &str) {
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
    pub(super) fn drop_stale(&mut self, now: Instant) {
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
        while self.queue.front().is_some_and(|(_, asked, _)| stale(*asked)) {
            let (queued, _, _) = self.queue.pop_front().expect("checked");
            queued.fail(error());
        }
    }
}

/// Whether `d` asks an axis to slew.
pub(super) fn moves<S>(d: Option<Drive<S>>) -> bool {
    matches!(d, Some(Drive::Forward(_) | Drive::Back(_)))
}

pub(super) fn answer(replies: Vec<Reply>, result: Result<(), CommandError>) {
    for r in replies {
        let _ = r.send(result.clone());
    }
}
