//! When the session's own motion ended, as the bus shows it (issue 49,
//! "doors tell the truth about control"; ARCHITECTURE "Front doors",
//! motion truth): a positioning move gcud accepted is a motion until the
//! polls show the gimbal standing still at its target or after it moved,
//! or a stop of pan and tilt is confirmed; and a motion of the session's
//! ends when gcud names another controller of the gimbal (gcud stopped it
//! when that controller took control), which the door shows as that
//! controller, never as a motion of its own.

use super::*;

/// An accepted positioning move the polls never saw start (a preset where
/// the gimbal already points, a target past its travel) is taken as ended
/// once the gimbal stood still over two polls this long after acceptance:
/// a gimbal starts well within it.
pub(super) const START_WITHIN: Duration = Duration::from_secs(1);

/// A positioning move (`GO`, `Pnn`, `HO`) gcud accepted, until the polls
/// show it ended.
#[derive(Clone, Copy, Debug)]
pub(super) struct Travel {
    /// Where it goes, when the command says (`GO`).
    to: Option<Position>,
    accepted: Instant,
    /// Where the last poll before acceptance, then each poll since, read the gimbal.
    last: Option<Position>,
    /// The polls since acceptance saw the gimbal move.
    moved: bool,
}

impl Travel {
    /// A move to `to` (a goto's target; `None`: a preset or home),
    /// accepted at `now` with the gimbal last read at `from`.
    pub(super) fn new(to: Option<Position>, from: Option<Position>, now: Instant) -> Self {
        Self {
            to,
            accepted: now,
            last: from,
            moved: false,
        }
    }

    /// Where it goes, when the command says (`GO`).
    pub(super) fn to(&self) -> Option<Position> {
        self.to
    }

    /// Whether the poll reading `p` at `now` shows the move ended: the
    /// gimbal at its target, or standing still since the last poll once it
    /// moved or [`START_WITHIN`] passed.
    pub(super) fn ended(&mut self, p: Position, now: Instant) -> bool {
        let still = self.last == Some(p);
        self.moved |= !still;
        self.last = Some(p);
        self.to == Some(p) || (still && (self.moved || now.duration_since(self.accepted) >= START_WITHIN))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Angle;

    fn at(pan: i16) -> Position {
        Position::new(Angle(pan), Angle(0))
    }

    #[test]
    fn a_goto_ends_at_its_target_a_preset_once_still_after_moving() {
        let t0 = Instant::now();
        let mut goto = Travel::new(Some(at(500)), Some(at(0)), t0);
        assert!(!goto.ended(at(0), t0), "not started yet: still a motion");
        assert!(!goto.ended(at(200), t0));
        assert!(goto.ended(at(500), t0), "at its target");

        let mut preset = Travel::new(None, Some(at(0)), t0);
        assert!(
            !preset.ended(at(0), t0),
            "not started within START_WITHIN: still a motion"
        );
        assert!(!preset.ended(at(300), t0));
        assert!(preset.ended(at(300), t0), "still after it moved");

        let mut there = Travel::new(None, Some(at(0)), t0);
        assert!(!there.ended(at(0), t0 + START_WITHIN / 2));
        assert!(
            there.ended(at(0), t0 + START_WITHIN),
            "never started: ended after START_WITHIN"
        );
    }
}
