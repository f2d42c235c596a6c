//! What a gimbal session has been asked and what it has told the gimbal,
//! under the session's one lock: the motion (module `motion`: the axes in
//! force, the owed stops, the pending velocity and positioning move), the
//! short queue and its staleness, the status and what gcud said of control
//! (ARCHITECTURE "Front doors": stops first, bounded work).

use super::motion::MotionState;
use super::*;

pub(super) type Answer = oneshot::Sender<Result<Option<Vec<u8>>, CommandError>>;
pub(super) type GcuReply = oneshot::Sender<Result<GcuAnswer, CommandError>>;
/// A reader of the next poll ([`GimbalSession::poll`]).
pub(super) type Reading = Result<(Position, Option<LensPosition>), CommandError>;
pub(super) type PollReply = oneshot::Sender<Reading>;

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

#[derive(Default)]
pub(super) struct State {
    /// The session's motion, one object with the rule that edits it.
    pub(super) motion: MotionState,
    pub(super) queue: VecDeque<(Queued, Instant, Option<Arc<str>>)>,
    /// Readers waiting for the next poll, and since when.
    pub(super) readers: Vec<(Instant, PollReply)>,
    pub(super) status: Status,
    pub(super) identity: Option<Identity>,
    /// The task ends once the owed stops are sent.
    pub(super) closing: bool,
    /// The rule gcud refused the last drive command by (logged once).
    pub(super) last_refusal: Option<Undelivered>,
    /// gcud's rules of the gimbal, when last asked ([`GimbalSession::rules`]).
    pub(super) rules: Option<(Instant, Rules)>,
    /// The last motion was ended or refused because another controller
    /// holds the gimbal ([`Status::taken_by`]).
    pub(super) taken: bool,
}

impl State {
    /// The session's motion, as the bus shows it: from the moment a move
    /// is asked (accepted, once its caller is answered) until the polls
    /// show it ended or a stop is confirmed (module `travel`); never a
    /// motion of another controller.
    pub(super) fn motion_shown(&self) -> Motion {
        let m = &self.motion;
        if m.stops_owed.any() && m.stop_failures > 0 {
            Motion::Unknown
        } else if m.any()
            // The gimbal moving under another controller is not this session's motion.
            || (self.status.changing && self.another_holder().is_none())
        {
            Motion::Moving
        } else {
            Motion::Idle
        }
    }

    /// Another controller than the session's link holds the gimbal, as
    /// gcud last named it (a link, a tour, park).
    pub(super) fn another_holder(&self) -> Option<&Controller> {
        self.status
            .control
            .as_ref()
            .filter(|c| !c.ours && c.holder != Controller::Nobody)
            .map(|c| &c.holder)
    }

    /// The controller that ended or refused the session's last motion,
    /// while gcud names it as the holder ([`Status::taken_by`]).
    pub(super) fn taken_by(&self) -> Option<Controller> {
        self.taken.then(|| self.another_holder().cloned()).flatten()
    }

    /// gcud names another holder of the gimbal: whatever the session had
    /// in force was stopped by gcud when that controller took control (not
    /// this session's to stop, and no longer its motion); what was set
    /// here (speeds too) is set again next time. Returns whether a motion
    /// of the session's ended so.
    pub(super) fn taken_over(&mut self) -> bool {
        if self.another_holder().is_none() || !self.motion.own() {
            return false;
        }
        self.motion.drop_in_force();
        self.taken = true;
        self.motion.settle_deadline();
        true
    }

    /// Drops what waited past [`STALE`].
    pub(super) fn drop_stale(&mut self, now: Instant) {
        let error = || {
            CommandError::Io(format!(
                "not sent within {} s: gcud or the bus is unavailable",
                STALE.as_secs()
            ))
        };
        self.motion.drop_stale(now, error);
        while self
            .queue
            .front()
            .is_some_and(|(_, asked, _)| now.duration_since(*asked) >= STALE)
        {
            let (queued, _, _) = self.queue.pop_front().expect("checked");
            queued.fail(error());
        }
        let (stale, fresh) = std::mem::take(&mut self.readers)
            .into_iter()
            .partition(|(asked, _)| now.duration_since(*asked) >= STALE);
        self.readers = fresh;
        for (_, reader) in stale {
            let _ = reader.send(Err(error()));
        }
    }

    /// A poll read `reading`: every reader waiting for it is told.
    pub(super) fn answer_readers(&mut self, reading: &Reading) {
        for (_, reader) in self.readers.drain(..) {
            let _ = reader.send(reading.clone());
        }
    }
}
