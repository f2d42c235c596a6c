//! The session's motion as one object (module documentation, "a motion is
//! one object"): what each axis has in force, the velocity and the
//! positioning move waiting to be sent, the stops owed, the deadline and
//! its owner, and the rule that edits them: a newer velocity replaces the
//! pending one per axis, a zero beside a move is owed once that move is in
//! force, a stop is owed at once and drops what it ends, a goto, preset or
//! home supersedes the pan and tilt, and the deadline covers every axis
//! still moving.

use super::travel::Travel;
use super::*;

pub(super) type Reply = oneshot::Sender<Result<(), CommandError>>;

/// Callers told of one pending move's (or the owed stops') outcome at most;
/// older ones beyond are told at once that theirs went, as a superseded
/// one is: a joystick's 20 Hz stream or a flood of one door's clients never
/// grows a list (a VISCA door once kept its own bounded desk for it).
pub(super) const WAITING: usize = 8;

/// `replies` with `reply` added, the oldest beyond [`WAITING`] answered.
fn wait_with(replies: &mut Vec<Reply>, reply: Reply) {
    replies.push(reply);
    if replies.len() > WAITING {
        let older: Vec<Reply> = replies.drain(..replies.len() - WAITING).collect();
        answer(older, Ok(()));
    }
}

/// One side of the gimbal, as far as the session has told it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct InForce<S> {
    /// The speed last set (`SPn`, `STn`, `Zn`), while the session may
    /// believe the gimbal still has it ([`MotionState::forget_speeds`]): a
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

    /// Where it goes, when the command says (`GO`).
    pub(super) fn target(self) -> Option<Position> {
        match self {
            Place::GoTo(p) => Some(p),
            Place::Preset(_) | Place::Home => None,
        }
    }
}

/// A drive command on its way to gcud ([`MotionState::driving`]).
pub(super) struct Driving {
    /// The door's user it was sent for.
    pub(super) by: Option<Arc<str>>,
    /// Callers of that user's wish, superseded meanwhile by another user's.
    pub(super) replies: Vec<Reply>,
}

pub(super) struct Pending<T> {
    pub(super) what: T,
    pub(super) asked: Instant,
    /// The door's user it is for (ARCHITECTURE "Principals"; `None`: the door itself).
    pub(super) by: Option<Arc<str>>,
    pub(super) replies: Vec<Reply>,
}

/// The session's motion: see the module's rule.
#[derive(Default)]
pub(super) struct MotionState {
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
    /// A drive command of `wish` on its way to gcud: whose it is, and the
    /// callers of that user's wish should another user's supersede it
    /// meanwhile (they learn the outcome of what was sent for them).
    pub(super) driving: Option<Driving>,
    /// Axes set to zero beside a pending move ([`MotionState::post`]):
    /// owed once that move is in force.
    pub(super) wish_stops: Axes,
    pub(super) place: Option<Pending<Place>>,
    /// A positioning move taken from `place`, on its way to gcud.
    pub(super) placing: Option<Place>,
    /// A positioning move gcud accepted, until the polls show it ended
    /// (module `travel`).
    pub(super) travel: Option<Travel>,
}

impl MotionState {
    /// The axes slewing or about to.
    pub(super) fn moving(&self) -> Axes {
        let (w_pan, w_tilt, w_zoom) = self.wish.as_ref().map_or((false, false, false), |w| {
            (moves(w.what.pan), moves(w.what.tilt), moves(w.what.zoom))
        });
        self.in_force().or(Axes {
            pan: w_pan,
            tilt: w_tilt,
            zoom: w_zoom,
        })
    }

    /// The axes whose slew gcud accepted and nothing stopped since.
    pub(super) fn in_force(&self) -> Axes {
        Axes {
            pan: self.pan.drive != Drive::Stop,
            tilt: self.tilt.drive != Drive::Stop,
            zoom: self.zoom.drive != Drive::Stop,
        }
    }

    /// A motion of the session's in force on the gimbal: a slew gcud
    /// accepted, or a positioning move not yet seen to end.
    pub(super) fn own(&self) -> bool {
        self.in_force().any() || self.travel.is_some()
    }

    /// Anything asked, under way or owed: the session's motion.
    pub(super) fn any(&self) -> bool {
        self.moving().any()
            || self.place.is_some()
            || self.placing.is_some()
            || self.travel.is_some()
            || self.stops_owed.any()
    }

    /// Where the newest positioning move aims the gimbal while it is asked,
    /// on its way to gcud or under way (`None`: none, or a preset or home,
    /// whose place the session does not know): the axis a goto leaves out
    /// keeps this angle, not a poll taken mid-travel.
    pub(super) fn aim(&self) -> Option<Position> {
        match (&self.place, self.placing, &self.travel) {
            (Some(p), _, _) => p.what.target(),
            (None, Some(p), _) => p.target(),
            (None, None, Some(t)) => t.to(),
            (None, None, None) => None,
        }
    }

    /// The deadline ends once nothing moves or is about to.
    pub(super) fn settle_deadline(&mut self) {
        if !self.moving().any() {
            self.deadline = None;
        }
    }

    /// `velocity` asked at `now` for `run` by `owner` (for door user
    /// `by`), `reply` told its outcome: the rule of the module's
    /// documentation. An axis at [`Drive::Stop`] is a stop: owed at once
    /// when nothing moves beside it, else part of the move (owed once it
    /// is in force, not at all when gcud refuses it for control: the
    /// holder's motion is not this door's to stop). Newest wins per axis.
    pub(super) fn post(
        &mut self,
        velocity: Velocity,
        run: Duration,
        owner: &str,
        by: Option<Arc<str>>,
        now: Instant,
        reply: Reply,
    ) {
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
                self.owe_stop(stops);
            }
        } else if stops.any() {
            if let Some(w) = &mut self.wish {
                w.what.pan = w.what.pan.filter(|_| !stops.pan);
                w.what.tilt = w.what.tilt.filter(|_| !stops.tilt);
                w.what.zoom = w.what.zoom.filter(|_| !stops.zoom);
            }
            self.wish_stops = self.wish_stops.or(stops);
            if stops.pan || stops.tilt {
                self.drop_place();
            }
        }
        // Newest wins: an axis moved now is no longer to be stopped.
        self.wish_stops = self.wish_stops.without(moved);
        if !moved.any() {
            wait_with(&mut self.stop_replies, reply);
            self.settle_deadline();
            return;
        }
        // Newest wins, per axis, for one door user; the replaced callers
        // learn the newest's outcome. Another user's pending move is not
        // merged into this one (it would go to gcud under this user's name,
        // and its caller learn this user's refusal: two Pelco keyboards) but
        // superseded whole, its callers told it went as a superseded one is,
        // or, while its command is on its way, how that command went.
        let (before, mut replies) = match self.wish.take() {
            Some(w) if w.by == by => (w.what, w.replies),
            Some(w) => {
                match &mut self.driving {
                    // Its command is on its way: they learn how that went.
                    Some(d) if d.by == w.by => w.replies.into_iter().for_each(|r| wait_with(&mut d.replies, r)),
                    _ => answer(w.replies, Ok(())),
                }
                Default::default()
            }
            None => Default::default(),
        };
        wait_with(&mut replies, reply);
        self.wish = Some(Pending {
            what: Velocity {
                pan: moves.pan.or(before.pan),
                tilt: moves.tilt.or(before.tilt),
                zoom: moves.zoom.or(before.zoom),
            },
            asked: now,
            by,
            replies,
        });
        if moved.pan || moved.tilt {
            self.drop_place();
        }
        // The motion is renewed: its new deadline covers every axis still moving.
        self.deadline = Some(now + run);
        owner.clone_into(&mut self.owner);
    }

    /// The stops of `axes`, `reply` told once the bus confirms them.
    pub(super) fn stop(&mut self, axes: Axes, reply: Reply) {
        self.owe_stop(axes);
        wait_with(&mut self.stop_replies, reply);
        self.settle_deadline();
    }

    /// `place` asked at `now` (for door user `by`): it supersedes the
    /// pending one and the pan/tilt slew on the gimbal.
    pub(super) fn place(&mut self, place: Place, by: Option<Arc<str>>, now: Instant, reply: Reply) {
        self.drop_place();
        if let Some(w) = &mut self.wish {
            w.what.pan = None;
            w.what.tilt = None;
        }
        self.wish_stops.pan = false;
        self.wish_stops.tilt = false;
        self.place = Some(Pending {
            what: place,
            asked: now,
            by,
            replies: vec![reply],
        });
    }

    /// A pending positioning move is superseded: its callers are told it
    /// went (nothing failed).
    fn drop_place(&mut self) {
        if let Some(p) = self.place.take() {
            answer(p.replies, Ok(()));
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
            self.drop_place();
        }
    }

    /// The bus confirmed the stops of `axes`: they are in force, and a
    /// stop of pan or tilt ends a positioning move under way.
    pub(super) fn stop_confirmed(&mut self, axes: Axes) {
        self.stops_owed = self.stops_owed.without(axes);
        self.stop_retry_at = None;
        if axes.pan || axes.tilt {
            self.travel = None;
        }
        if axes.pan {
            self.pan.drive = Drive::Stop;
        }
        if axes.tilt {
            self.tilt.drive = Drive::Stop;
        }
        if axes.zoom {
            self.zoom.drive = Drive::Stop;
        }
    }

    /// A poll read the gimbal at `p`: the positioning move under way ends
    /// when the reading shows it.
    pub(super) fn travel_polled(&mut self, p: Position, now: Instant) {
        if self.travel.as_mut().is_some_and(|t| t.ended(p, now)) {
            self.travel = None;
        }
    }

    /// Whatever was in force is no longer the session's (another
    /// controller took the gimbal): speeds too are set again next time.
    pub(super) fn drop_in_force(&mut self) {
        self.pan = InForce::default();
        self.tilt = InForce::default();
        self.zoom = InForce::default();
        self.travel = None;
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

    /// Drops the velocity and the positioning move that waited past
    /// [`STALE`], their callers told `error`.
    pub(super) fn drop_stale(&mut self, now: Instant, error: impl Fn() -> CommandError) {
        let stale = |asked: Instant| now.duration_since(asked) >= STALE;
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

#[cfg(test)]
#[path = "motion/tests.rs"]
mod tests;
