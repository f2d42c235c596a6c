//! What the governor knows of one gimbal and the motions it follows: the
//! last position read (Table 15), rates and accelerations (Table 13), the
//! presets, and per axis whether it is still, slewing, going somewhere or
//! stopping. A gimbal with limits or zones, or one a tour drives, is
//! followed: its position is polled while it moves, at a rate derived
//! from its speed and the room left, and a slew gets its stop in time.

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_protocol::frame::HEADER_LEN;
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{Command, Position};

use super::control::Held;
use super::rules::{GimbalRules, Span};
use super::travel::{Region, axes, braking, distance_in, room_ahead, stop_slack};
use super::{GovernStats, Order, Purpose};
use crate::types::{DropReason, RouterEvent, StopCause};

/// Poll period of a goto or a stop in progress.
const MOTION_POLL: u64 = 250;
/// Shortest and longest wait between position polls of a followed slew.
const MAX_SLEW_POLL: u64 = 1000;
/// Wait before asking again what a gimbal did not answer.
const RETRY: u64 = 2000;
/// Readings this close (hundredths of a degree) mean the axis stands still.
const SAME: i32 = 5;
/// A device's turnaround before it answers, allowed for (ms).
const TURNAROUND: u64 = 5;

/// One axis, as far as the governor knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum AxisMotion {
    #[default]
    Still,
    /// A continuous slew, +1 counter-clockwise.
    Slew { dir: i32 },
    /// Going to this target.
    Goto { target: i32 },
    /// Braking after a stop.
    Settling,
    /// Moving, no one knows where.
    Unknown,
}

/// What a change from a link makes the governor learn again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Learning {
    Speeds,
    Preset(u8),
}

/// A position read, and when (the tick the gimbal answered).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Reading {
    pub at: u64,
    pub position: Position,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Gimbal {
    pub rules: Option<GimbalRules>,
    pub holder: Option<Held>,
    pub position: Option<Reading>,
    pub axes: [AxisMotion; 2],
    pub rates: Option<[u32; 2]>,
    pub accels: Option<[u32; 2]>,
    pub presets: BTreeMap<u8, Position>,
    /// When control last lapsed or was released.
    pub free_since: Option<u64>,
    /// A link moved it since it last parked.
    pub moved: bool,
    /// Park recalled its preset since it was last moved.
    pub parked: bool,
    /// Followed (rules or a tour): polled while it moves, learnt.
    watched: bool,
    need_position: bool,
    need_rates: bool,
    need_accels: bool,
    ask_presets: BTreeSet<u8>,
    /// The next preset to learn, scanning from 00 until the first NIC.
    scan: Option<u8>,
    /// One own query at a time.
    asking: bool,
    retry_at: Option<u64>,
    poll_at: Option<u64>,
    /// When the last goto (or motion to an unknown place) was sent: a
    /// reading from before it cannot tell that it stopped.
    moved_at: u64,
    /// When each slewing axis' stop must be sent, and what it stops short of.
    stop_at: [Option<(u64, DropReason)>; 2],
    /// A slew began: its stop is planned at the next poll.
    replan: bool,
}

impl Gimbal {
    /// Who holds it, control lapsed or not.
    pub fn held(&self, now: u64, hold: u64) -> Option<&Held> {
        self.holder.as_ref().filter(|h| !h.lapsed(now, hold))
    }

    /// Forget what was learnt (its port closed or was lost).
    pub fn forget(&mut self) {
        self.position = None;
        self.axes = [AxisMotion::Unknown; 2];
        self.rates = None;
        self.accels = None;
        self.presets.clear();
        self.asking = false;
        self.stop_at = [None; 2];
        self.poll_at = None;
    }

    /// Follow it and learn its position, speeds and presets.
    pub fn start_learning(&mut self) {
        self.watched = true;
        self.need_position = true;
        self.need_rates = true;
        self.need_accels = true;
        self.scan = Some(0);
    }

    pub fn learn(&mut self, learning: Learning) {
        match learning {
            Learning::Speeds => {
                self.need_rates = true;
                self.need_accels = true;
            }
            Learning::Preset(n) => {
                self.ask_presets.insert(n);
            }
        }
    }

    pub fn may_be_moving(&self) -> bool {
        self.axes.iter().any(|a| *a != AxisMotion::Still)
    }

    fn rate(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.slew_rate);
        configured.or(self.rates).map(|r| r[axis].max(1))
    }

    fn accel(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.acceleration);
        configured.or(self.accels).map(|a| a[axis].max(1))
    }

    /// Where it may be now, per axis; `None` when unknown.
    pub fn region(&self, now: u64) -> Option<Region> {
        let reading = self.position?;
        let p = axes(reading.position);
        let mut region = [Span::at(p[0]), Span::at(p[1])];
        for axis in 0..2 {
            region[axis] = match self.axes[axis] {
                AxisMotion::Still => Span::at(p[axis]),
                AxisMotion::Goto { target } => Span::at(p[axis]).join(&Span::at(target)),
                AxisMotion::Slew { dir } => {
                    let (v, a) = (self.rate(axis)?, self.accel(axis)?);
                    let run = distance_in(now.saturating_sub(reading.at), v) + braking(v, a);
                    Span::at(p[axis]).join(&Span::at(p[axis] + dir * run))
                }
                AxisMotion::Settling => {
                    let reach = braking(self.rate(axis)?, self.accel(axis)?);
                    Span::new(p[axis] - reach, p[axis] + reach)
                }
                AxisMotion::Unknown => return None,
            };
        }
        Some(region)
    }

    /// A slew of `axis` in `dir`: refused when its position, rate or
    /// acceleration is unknown, or when it could not be stopped short of
    /// the first limit or zone ahead.
    pub fn check_slew(&self, now: u64, rules: &GimbalRules, axis: usize, dir: i32, bps: u32) -> Result<(), DropReason> {
        let region = self.region(now).ok_or(DropReason::PositionUnknown)?;
        let (v, a) = match (self.rate(axis), self.accel(axis)) {
            (Some(v), Some(a)) => (v, a),
            _ => return Err(DropReason::PositionUnknown),
        };
        let at = if dir > 0 { region[axis].hi } else { region[axis].lo };
        let Some((room, reason)) = room_ahead(rules, axis, dir, at, self.other_range(axis, region, now)) else {
            return Ok(());
        };
        match stop_slack(room, v, a, latency(bps)) >= 0 {
            true => Ok(()),
            false => Err(reason),
        }
    }

    /// The range the other axis covers while `axis` slews toward a boundary.
    fn other_range(&self, axis: usize, region: Region, now: u64) -> Span {
        let other = 1 - axis;
        match (self.axes[other], self.rate(other)) {
            (AxisMotion::Slew { dir }, Some(v)) => {
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

    pub fn going(&mut self, now: u64, target: [i32; 2]) {
        self.axes = [
            AxisMotion::Goto { target: target[0] },
            AxisMotion::Goto { target: target[1] },
        ];
        self.stop_at = [None; 2];
        self.poll_at = Some(now + MOTION_POLL);
        self.moved_at = now;
    }

    pub fn slewing(&mut self, now: u64, axis: usize, dir: i32) {
        self.axes[axis] = AxisMotion::Slew { dir };
        self.replan = true;
        self.poll_at = Some(now);
    }

    pub fn unknown_motion(&mut self, now: u64) {
        self.axes = [AxisMotion::Unknown; 2];
        self.stop_at = [None; 2];
        self.poll_at = Some(now + MOTION_POLL);
        self.moved_at = now;
    }

    pub fn stopping(&mut self, now: u64, pan: bool, tilt: bool) {
        for (axis, stops) in [pan, tilt].into_iter().enumerate() {
            if stops && self.axes[axis] != AxisMotion::Still {
                self.axes[axis] = AxisMotion::Settling;
                self.stop_at[axis] = None;
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

    /// A position read (answered at `now`, at `bps`): motions confirmed,
    /// slews planned again.
    pub fn read_position(&mut self, now: u64, position: Position, bps: u32) {
        // The gimbal read it before the result's bytes were on the wire.
        let at = now.saturating_sub(wire_ms(HEADER_LEN + 10, bps));
        // Two readings that agree mean the axis stands still, unless the
        // first was taken before the motion began (a goto queued behind
        // other work is read again before the gimbal got going).
        let since = self.moved_at;
        let before = self.position.filter(|r| r.at >= since).map(|r| axes(r.position));
        let p = axes(position);
        self.position = Some(Reading { at, position });
        self.need_position = false;
        for axis in 0..2 {
            let unchanged = before.is_some_and(|b| (b[axis] - p[axis]).abs() <= SAME);
            self.axes[axis] = match self.axes[axis] {
                AxisMotion::Goto { target } if (p[axis] - target).abs() <= super::travel::ARRIVED => AxisMotion::Still,
                AxisMotion::Goto { .. } | AxisMotion::Settling | AxisMotion::Unknown if unchanged => AxisMotion::Still,
                other => other,
            };
        }
        self.replan = self.axes.iter().any(|a| matches!(a, AxisMotion::Slew { .. }));
        self.poll_at = self.may_be_moving().then_some(now + MOTION_POLL);
    }

    /// Plans the stop of each slewing axis from the last reading.
    fn plan(&mut self, now: u64, bps: u32) {
        self.replan = false;
        let (Some(rules), Some(reading)) = (self.rules.clone(), self.position) else {
            return;
        };
        let Some(region) = self.region(reading.at) else { return };
        let p = axes(reading.position);
        let exchange = exchange(bps);
        for (axis, &at) in p.iter().enumerate() {
            let AxisMotion::Slew { dir } = self.axes[axis] else {
                self.stop_at[axis] = None;
                continue;
            };
            let (Some(v), Some(a)) = (self.rate(axis), self.accel(axis)) else {
                // Unknown speed: stop at once rather than guess.
                self.stop_at[axis] = Some((now, DropReason::PositionUnknown));
                continue;
            };
            let Some((room, reason)) = room_ahead(&rules, axis, dir, at, self.other_range(axis, region, now)) else {
                self.stop_at[axis] = None;
                continue;
            };
            let slack = stop_slack(room, v, a, latency(bps));
            let stop = reading.at.saturating_add_signed(slack).max(now);
            self.stop_at[axis] = Some((stop, reason));
            // Poll again while a fresher reading can still refine the stop.
            let wait = (slack.max(0) as u64 / 2).clamp(exchange, MAX_SLEW_POLL);
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
        bps: u32,
        port: u8,
        device: u8,
        orders: &mut Vec<Order>,
        stats: &mut GovernStats,
        events: &mut Vec<RouterEvent>,
    ) {
        if !self.watched {
            return;
        }
        if self.replan && !self.asking {
            self.plan(now, bps);
        }
        for axis in 0..2 {
            let Some((at, boundary)) = self.stop_at[axis].filter(|&(t, _)| t <= now) else {
                continue;
            };
            self.stop_at[axis] = None;
            self.axes[axis] = AxisMotion::Settling;
            stats.boundary_stops += 1;
            let _ = at;
            let command = if axis == 0 { Command::PanStop } else { Command::TiltStop };
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

    /// The next thing to learn, one query at a time.
    pub fn next_query(&mut self, now: u64, port: u8, device: u8, orders: &mut Vec<Order>) {
        if !self.watched || self.asking || self.retry_at.is_some_and(|t| now < t) {
            return;
        }
        self.retry_at = None;
        let next = if self.need_position {
            Some((Command::QueryPosition, Purpose::Position))
        } else if self.need_rates && self.rules.as_ref().is_none_or(|r| r.slew_rate.is_none()) {
            Some((Command::QueryRates, Purpose::Rates))
        } else if self.need_accels && self.rules.as_ref().is_none_or(|r| r.acceleration.is_none()) {
            Some((Command::QueryAccelerations, Purpose::Accelerations))
        } else if let Some(n) = self.ask_presets.pop_first() {
            Some((Command::QueryPreset(n), Purpose::Preset(n)))
        } else {
            self.scan.map(|n| (Command::QueryPreset(n), Purpose::Preset(n)))
        };
        if let Some((command, purpose)) = next {
            self.asking = true;
            orders.push(query(port, device, command, purpose));
        }
    }

    /// An own query ended; `answered`: with a result.
    pub fn query_ended(&mut self, now: u64, purpose: Purpose, answered: bool) {
        self.asking = false;
        match purpose {
            Purpose::Rates if answered => self.need_rates = false,
            Purpose::Accelerations if answered => self.need_accels = false,
            Purpose::Preset(n) if self.scan == Some(n) => {
                // Scanned until the first preset not implemented (a NIC, 1.6.1).
                self.scan = if answered { n.checked_add(1) } else { None };
            }
            Purpose::Preset(_) | Purpose::Motion => {}
            Purpose::Position | Purpose::Rates | Purpose::Accelerations => {}
        }
        if !answered && purpose != Purpose::Motion && !matches!(purpose, Purpose::Preset(_)) {
            self.retry_at = Some(now + RETRY);
        }
    }

    /// When [`Gimbal::follow`] or [`Gimbal::next_query`] next has work.
    pub fn next_deadline(&self) -> Option<u64> {
        if !self.watched {
            return None;
        }
        let stops = self.stop_at.iter().flatten().map(|&(t, _)| t);
        let poll = self.poll_at.filter(|_| !self.asking && self.may_be_moving());
        let learning = self.need_position
            || self.need_rates
            || self.need_accels
            || !self.ask_presets.is_empty()
            || self.scan.is_some();
        let learn = (learning && !self.asking).then(|| self.retry_at.unwrap_or(0));
        let replan = (self.replan && !self.asking).then_some(0);
        stops.chain(poll).chain(learn).chain(replan).min()
    }
}

fn query(port: u8, device: u8, command: Command<'static>, purpose: Purpose) -> Order {
    Order {
        port,
        device,
        command,
        stop: None,
        purpose,
    }
}

/// One `P?` exchange at `bps`: the query, the ACK, the result and a device's turnaround.
pub(crate) fn exchange(bps: u32) -> u64 {
    wire_ms(HEADER_LEN + 3, bps) + wire_ms(1, bps) + wire_ms(HEADER_LEN + 10, bps) + TURNAROUND
}

/// From deciding a stop to the gimbal reading it: an exchange already on
/// the bus, then the stop's own frame.
pub(crate) fn latency(bps: u32) -> u64 {
    exchange(bps) + wire_ms(HEADER_LEN + 3, bps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Angle;

    fn at(pan: i16, tilt: i16) -> Position {
        Position::new(Angle(pan), Angle(tilt))
    }

    /// A tour waited 60 s (GOTO_PATIENCE) for a goto taken for stopped
    /// short: its first reading, taken before the gimbal got going, agreed
    /// with the reading before the goto.
    #[test]
    fn a_goto_is_not_taken_for_stopped_by_a_reading_from_before_it_began() {
        let mut g = Gimbal::default();
        g.read_position(1000, at(0, 0), 115_200);
        g.going(2000, [3000, 0]);
        g.read_position(2030, at(0, 0), 115_200);
        assert_eq!(g.axes[0], AxisMotion::Goto { target: 3000 }, "still on its way");
        assert!(g.may_be_moving() && g.poll_at.is_some(), "followed further");
        // Two readings after it began that agree: it stopped short.
        g.read_position(2300, at(0, 0), 115_200);
        assert_eq!(g.axes[0], AxisMotion::Still);
        // Arrived: still at once.
        g.going(3000, [100, 0]);
        g.read_position(3250, at(100, 0), 115_200);
        assert_eq!(g.axes, [AxisMotion::Still; 2]);
    }
}
