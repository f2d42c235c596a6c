//! What the governor notes of a gimbal's motion when it lets a command
//! through, and again when that command reaches the bus (ARCHITECTURE
//! "Governance": what gcud decides is ordered as the bus carries it). A
//! goto replacing a followed slew, a slew reversing one, a slew after a
//! queued goto and a motion no one can bound each take effect on the bus;
//! until then the motion before them stays followed.

use super::knowledge::{AxisMotion, Gimbal, MOTION_POLL};
use crate::types::CommandId;

impl Gimbal {
    /// A goto to `target` was let through.
    pub fn going(&mut self, now: u64, target: [i32; 2]) {
        // A slew this goto replaces is still followed, its stop planned,
        // until the goto is on the bus: queued behind other work, or given up
        // before it began (a stop overtook it), it must not leave the slew
        // running unfollowed (the governance simulation: a wildcard goto
        // superseded before the bus, the pan slew it was to replace ran on
        // past the limit).
        let slews = self.axes.iter().any(|a| matches!(a, AxisMotion::Slew { .. }));
        if slews || self.reversing.iter().any(Option::is_some) {
            self.guard = Some((None, target.map(Some)));
            return;
        }
        self.guard = None;
        self.axes = [
            AxisMotion::Goto {
                target: target[0],
                moving: self.axes[0] != AxisMotion::Still,
            },
            AxisMotion::Goto {
                target: target[1],
                moving: self.axes[1] != AxisMotion::Still,
            },
        ];
        self.stop_at = [None; 2];
        self.poll_at = Some(now + MOTION_POLL);
        self.moved_at = now;
    }

    /// The command that carries the goto just noted is `id`.
    pub fn goto_is(&mut self, id: CommandId) {
        if let Some((pending @ None, _)) = self.guard.as_mut() {
            *pending = Some(id);
        }
    }

    /// Command `id` ended: a goto that never began (given up) lifts its
    /// guard; a motion to an unknown place that never began moved nothing.
    pub fn ended(&mut self, id: CommandId) {
        for reversing in &mut self.reversing {
            reversing.take_if(|(r, _)| *r == id);
        }
        if self.guard.is_some_and(|(g, _)| g == Some(id)) {
            self.guard = None;
        }
        if let Some((_, before)) = self.unknown_by.take_if(|(u, _)| *u == id) {
            // (An axis a stop reached since stays as the stop left it.)
            for (axis, before) in before.into_iter().enumerate() {
                if self.axes[axis] == AxisMotion::Unknown {
                    self.axes[axis] = before;
                }
            }
            self.replan = true;
        }
    }

    /// Command `id` began on the bus: a goto's guard is lifted, and the
    /// slew it replaces is a goto from here on.
    pub fn started(&mut self, now: u64, id: CommandId) {
        if self.unknown_by.take_if(|(u, _)| *u == id).is_some() {
            self.stop_at = [None; 2];
        }
        for axis in 0..2 {
            if let Some((_, dir)) = self.reversing[axis].take_if(|(r, _)| *r == id) {
                self.began_slew(now, axis, dir);
            }
        }
        if let Some((Some(goto), target)) = self.guard {
            if goto == id {
                self.guard = None;
                for (axis, target) in target.into_iter().enumerate() {
                    if let Some(target) = target {
                        let moving = self.axes[axis] != AxisMotion::Still;
                        self.axes[axis] = AxisMotion::Goto { target, moving };
                        self.stop_at[axis] = None;
                    }
                }
                self.replan = true;
                self.poll_at = Some(now + MOTION_POLL);
                self.moved_at = now;
            }
        }
    }

    pub fn slewing(&mut self, now: u64, axis: usize, dir: i32, id: CommandId) {
        if let Some((_, target)) = self.guard.as_mut() {
            target[axis] = None;
        }
        if matches!(self.axes[axis], AxisMotion::Slew { dir: d, .. } if d != dir) {
            self.reversing[axis] = Some((id, dir));
            return;
        }
        self.reversing[axis] = None;
        self.began_slew(now, axis, dir);
    }

    /// A slew of `axis` in `dir` is on its way to the bus (or began there).
    fn began_slew(&mut self, now: u64, axis: usize, dir: i32) {
        let since = self.slew_since(now, axis, dir);
        // Checked before: both are known (or it was refused).
        self.slew_began_with[axis] = self.rate(axis).zip(self.accel(axis));
        self.axes[axis] = AxisMotion::Slew { dir, since };
        self.replan = true;
        self.poll_at = Some(now);
    }

    /// Command `by` (when a link's) moves it no one knows where.
    pub fn unknown_motion(&mut self, now: u64, by: Option<CommandId>) {
        self.reversing = [None; 2];
        self.unknown_by = by.map(|id| (id, self.axes));
        self.axes = [AxisMotion::Unknown; 2];
        // A link's command keeps the stops planned for what moves until it
        // is on the bus (the governance simulation: an allowed `*mp` queued
        // behind other work dropped a slew's boundary stop, and the slew
        // ran past the limit before the `*mp` was sent).
        if by.is_none() {
            self.stop_at = [None; 2];
        }
        self.poll_at = Some(now + MOTION_POLL);
        self.moved_at = now;
    }

    pub fn stopping(&mut self, now: u64, pan: bool, tilt: bool) {
        for (axis, stops) in [pan, tilt].into_iter().enumerate() {
            if stops && self.axes[axis] != AxisMotion::Still {
                // Its planned stop stays until it is seen still (module `follow`).
                self.axes[axis] = AxisMotion::Settling { since: now };
            }
        }
        if self.may_be_moving() {
            self.poll_at = Some(now + MOTION_POLL / 2);
        }
    }

    /// `Snn` stored the current position as preset `n`.
    pub fn stored(&mut self, n: u8) {
        match (self.position, self.may_be_moving()) {
            (Some(r), false) => {
                self.presets.insert(n, r.position);
            }
            _ => {
                self.presets.remove(&n);
            }
        }
    }
}
