//! The follower (ARCHITECTURE "Governance"): a slew of a gimbal with
//! limits or zones is accepted only when its stop can still be timed; that
//! stop is planned from the last reading with a kinematic plan, sent when
//! due, and the position is polled while the gimbal moves, at a pace set
//! by its speed and the room left. A gimbal found moving after a start is
//! stopped.

use sagebrush_protocol::Command;

use super::knowledge::{AxisMotion, Gimbal, Line, MAX_SLEW_POLL, MOTION_POLL, query};
use super::rules::{GimbalRules, Span};
use super::travel::{Kinematics, Region, axes, distance_in, room_ahead};
use super::{GovernStats, Order, Purpose};
use crate::types::{DropReason, RouterEvent, StopCause};

impl Gimbal {
    /// A slew of `axis` in `dir`: refused when its position, rate or
    /// acceleration is unknown, or when the stop that keeps it short of the
    /// first limit or zone ahead would be due before the slew is even on
    /// the bus.
    /// `lead`: how long after now a stop may first go (the slew's own
    /// exchange; a slew to device 255 holds the bus for its broadcast guard).
    pub fn check_slew(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        dir: i32,
        line: Line,
        lead: u64,
    ) -> Result<(), DropReason> {
        let since = self.slew_since(now, axis, dir);
        match self.stop_due(now, rules, axis, dir, since, line)? {
            None => Ok(()),
            Some((Some(t), _)) if t >= now + lead => Ok(()),
            Some((_, reason)) => Err(reason),
        }
    }

    /// When a slew of `axis` in `dir` that began at `since` (0: the axis was
    /// already moving, so as fast as it may be) must have its stop sent, from
    /// the last reading: `None` when nothing bounds it; `Some((None, _))`
    /// when even a stop sent now comes too late; and what it stops short of.
    pub(super) fn stop_due(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        dir: i32,
        since: u64,
        line: Line,
    ) -> Result<Option<(Option<u64>, DropReason)>, DropReason> {
        let reading = self.position.ok_or(DropReason::PositionUnknown)?;
        let (Some(v), Some(a)) = (self.rate(axis), self.accel(axis)) else {
            return Err(DropReason::RateUnknown);
        };
        let region = self.region(now).ok_or(DropReason::PositionUnknown)?;
        let at = axes(reading.position)[axis];
        let Some((room, reason)) = room_ahead(rules, axis, dir, at, self.other_range(axis, region, now)) else {
            return Ok(None);
        };
        // The axis stood at the reading until the slew began; since then it
        // gained at most `a` per ms (it began no earlier than accepted).
        let from = reading.at.max(since);
        let up = self.accel_up(axis).unwrap_or(a);
        let mut kinematics = Kinematics::of(v, up, a, from - since);
        // Never slower than the readings showed it moving.
        kinematics.u = kinematics
            .u
            .max(f64::from(self.seen_rate[axis].1) / 1000.0)
            .min(kinematics.v);
        let due = kinematics
            .latest_stop(room)
            .map(|dt| (from + dt as u64).saturating_sub(line.latency()));
        Ok(Some((due, reason)))
    }

    /// When a slew of `axis` in `dir` begun now counts as begun (see [`Gimbal::stop_due`]).
    pub(super) fn slew_since(&self, now: u64, axis: usize, dir: i32) -> u64 {
        match self.axes[axis] {
            AxisMotion::Slew { dir: d, since } if d == dir => since,
            AxisMotion::Still => now,
            // Already moving (a goto not yet confirmed, a stop, a turn): as fast as it may be.
            _ => 0,
        }
    }

    /// The range the other axis covers while `axis` slews toward a boundary.
    fn other_range(&self, axis: usize, region: Region, now: u64) -> Span {
        let other = 1 - axis;
        match (self.axes[other], self.rate(other)) {
            (AxisMotion::Slew { dir, .. }, Some(v)) => {
                let _ = now;
                // Over the horizon of one slow poll: far enough ahead for the next plan.
                let reach = distance_in(MAX_SLEW_POLL * 2, v);
                region[other].join(&Span::at(if dir > 0 {
                    region[other].hi + reach
                } else {
                    region[other].lo - reach
                }))
            }
            _ => region[other],
        }
    }

    /// Plans the stop of each slewing axis from the last reading.
    fn plan(&mut self, now: u64, line: Line) {
        self.replan = false;
        let Some(rules) = self.rules.clone() else { return };
        let exchange = line.exchange();
        for axis in 0..2 {
            let AxisMotion::Slew { dir, since } = self.axes[axis] else {
                // A slew a link stopped keeps its planned stop until it is
                // seen still: that link's stop may be lost (one to device
                // 255 is never confirmed); a second stop is harmless.
                let settling = matches!(self.axes[axis], AxisMotion::Settling { .. });
                if self.guard.is_none() && !settling && self.unknown_by.is_none() {
                    self.stop_at[axis] = None;
                }
                continue;
            };
            let (stop, reason) = match self.stop_due(now, &rules, axis, dir, since, line) {
                Ok(None) => {
                    self.stop_at[axis] = None;
                    continue;
                }
                Ok(Some((due, reason))) => (due.unwrap_or(now).max(now), reason),
                // Unknown speed or position: stop at once rather than guess.
                Err(reason) => (now, reason),
            };
            self.stop_at[axis] = Some((stop, reason));
            // Poll again while a fresher reading can still refine the stop.
            let wait = ((stop - now) / 2).clamp(exchange, MAX_SLEW_POLL);
            if now + wait + exchange < stop {
                self.poll_at = Some(self.poll_at.map_or(now + wait, |t| t.min(now + wait)));
            }
        }
    }

    /// Stops due, and the next position poll of a gimbal in motion.
    #[allow(clippy::too_many_arguments)]
    pub fn follow(
        &mut self,
        now: u64,
        line: Line,
        port: u8,
        device: u8,
        orders: &mut Vec<Order>,
        stats: &mut GovernStats,
        events: &mut Vec<RouterEvent>,
    ) {
        if !self.watched {
            return;
        }
        self.stop_latency = line.latency();
        // Planned again at once, even with a query out: a change of rate or
        // acceleration mid-slew may need its stop sooner than planned (the
        // governance simulation: an `APnnnn` while a poll was out kept the
        // old, later stop).
        if self.replan {
            self.plan(now, line);
        }
        if std::mem::take(&mut self.stop_found) {
            stats.found_moving += 1;
            orders.push(Order {
                port,
                device,
                command: Command::StopMotion,
                stop: Some(StopCause::FoundMoving),
                cancel_slews: None,
                purpose: Purpose::Motion,
            });
            self.poll_at = Some(now + MOTION_POLL / 2);
        }
        let due = [0, 1].map(|axis| self.stop_at[axis].filter(|&(t, _)| t <= now).map(|(_, why)| why));
        let command = match due {
            // Both at once: one frame (`PS` then `TS` kept the tilt's stop
            // one exchange late in the governance simulation).
            [Some(_), Some(_)] => Some(Command::StopMotion),
            [Some(_), None] => Some(Command::PanStop),
            [None, Some(_)] => Some(Command::TiltStop),
            [None, None] => None,
        };
        if let (Some(command), Some(boundary)) = (command, due[0].or(due[1])) {
            for axis in (0..2).filter(|&axis| due[axis].is_some()) {
                self.stop_at[axis] = None;
                if self.axes[axis] != AxisMotion::Unknown {
                    self.axes[axis] = AxisMotion::Settling { since: now };
                }
                stats.boundary_stops += 1;
            }
            events.push(RouterEvent::BoundaryStop {
                port,
                device,
                stop: command.mnemonic(),
                boundary,
            });
            orders.push(Order {
                port,
                device,
                command,
                stop: Some(StopCause::Boundary),
                cancel_slews: Some(boundary),
                purpose: Purpose::Motion,
            });
            self.poll_at = Some(now + MOTION_POLL / 2);
        }
        if self.asking || !self.may_be_moving() {
            return;
        }
        if self.poll_at.is_none_or(|t| t <= now) {
            self.asking = true;
            self.poll_at = None;
            stats.follow_polls += 1;
            orders.push(query(port, device, Command::QueryPosition, Purpose::Position));
        }
    }
}
