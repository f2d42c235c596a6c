//! What the governor knows of one gimbal and the motions it follows: the
//! last position read (Table 15), rates and accelerations (Table 13), the
//! presets, and per axis whether it is still, slewing, going somewhere or
//! stopping; what it learns from the gimbal's answers, and what it asks
//! next. What a command may do is judged in module `judge`; how a slew is
//! followed and stopped in time, in module `follow`; what a command let
//! through, and its start on the bus, make of the motion, in module `noting`.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use sagebrush_protocol::frame::HEADER_LEN;
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{Axis, Command, Describes, Position, Reply};

use super::control::Held;
use super::rules::{GimbalRules, Span};
use super::travel::{Region, axes, braking, distance_in};
use super::{Order, Purpose};
use crate::types::{CommandId, DropReason};

/// Pan 0, tilt 1, as the follower indexes its axes.
pub(super) fn axis_index(axis: Axis) -> usize {
    match axis {
        Axis::Pan => 0,
        Axis::Tilt => 1,
    }
}

/// Poll period of a goto or a stop in progress.
pub(super) const MOTION_POLL: u64 = 250;
/// Shortest and longest wait between position polls of a followed slew.
pub(super) const MAX_SLEW_POLL: u64 = 1000;
/// Wait before asking again what a gimbal did not answer.
pub(super) const RETRY: u64 = 2000;
/// Readings this close (hundredths of a degree) mean the axis stands still.
pub(super) const SAME: i32 = 5;
/// The shortest span between two readings that may show an axis standing still (ms).
pub(super) const SETTLE_SPAN: u64 = 100;
/// Readings in a row without change that end a goto short of its target.
pub(super) const STILL_POLLS: u8 = 4;
/// A device's turnaround before it answers, allowed for (ms).
pub(super) const TURNAROUND: u64 = 5;

/// One axis, as far as the governor knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum AxisMotion {
    #[default]
    Still,
    /// A continuous slew, +1 counter-clockwise, begun at tick `since`
    /// (until then the axis stood where it was last read).
    Slew { dir: i32, since: u64 },
    /// Going to this target; `moving`: the axis was not still when it
    /// began (it may first run on the other way, by its braking distance).
    Goto { target: i32, moving: bool },
    /// Braking after a stop sent at tick `since`.
    Settling { since: u64 },
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
    /// The reading the next one is compared with to tell whether it stands
    /// still: the latest one at least [`SETTLE_SPAN`] older than the one
    /// after it. Readings closer in time tell nothing, and were each
    /// compared with the one just before, so that doors polling every 50 ms
    /// kept a gimbal found at start unknown for good (gimbal-visca's goto
    /// to the demo's roof refused "position unknown").
    pub(super) anchor: Option<Reading>,
    pub axes: [AxisMotion; 2],
    pub rates: Option<[u32; 2]>,
    pub accels: Option<[u32; 2]>,
    pub presets: BTreeMap<u8, Position>,
    /// When control last lapsed or was released.
    pub free_since: Option<u64>,
    /// A link moved it since it last parked.
    pub moved: bool,
    /// Followed (rules or a tour): polled while it moves, learnt.
    pub(super) watched: bool,
    pub(super) need_position: bool,
    pub(super) need_rates: bool,
    pub(super) need_accels: bool,
    pub(super) ask_presets: BTreeSet<u8>,
    /// The next preset to learn, scanning from 00 until the first NIC.
    pub(super) scan: Option<u8>,
    /// One own query at a time.
    pub(super) asking: bool,
    pub(super) retry_at: Option<u64>,
    pub(super) poll_at: Option<u64>,
    /// When the last goto (or motion to an unknown place) was sent: a
    /// reading from before it cannot tell that it stopped.
    pub(super) moved_at: u64,
    /// When each slewing axis' stop must be sent, and what it stops short of.
    pub(super) stop_at: [Option<(u64, DropReason)>; 2],
    /// A slew began: its stop is planned at the next poll.
    pub(super) replan: bool,
    /// The rate and acceleration of each axis when its slew began.
    pub(super) slew_began_with: [Option<(u32, u32)>; 2],
    /// Readings in a row each axis did not change.
    pub(super) unchanged: [u8; 2],
    /// A goto that replaces a followed slew, not yet on the bus: its
    /// command (once known) and target; the slew is followed (its stop
    /// planned) until the goto began. An axis whose target is `None` was
    /// given a slew after the goto (on the bus after it): it stays a slew.
    pub(super) guard: Option<(Option<CommandId>, [Option<i32>; 2])>,
    /// How fast each axis moved between the last two readings, per second:
    /// its mean (a `HO` may run faster than the rate `R?` answers), and the
    /// most it may have reached at the last one.
    pub(super) seen_rate: [(u32, u32); 2],
    /// Changes of speed, acceleration or dynamics from links not yet ended:
    /// what `R?` and `A?` answer meanwhile may be from before them, and a
    /// slew waits for them (ARCHITECTURE "Governance", learn before deciding).
    pub(super) changes_in_flight: u8,
    /// The proportional step (`SPn`, `STn`) each axis was last set to.
    pub(super) step: [Option<u8>; 2],
    /// The rate each axis answered at a proportional step (`R?` after `SPn`):
    /// bounds a step change during a slew.
    pub(super) step_rates: BTreeMap<(usize, u8), u32>,
    /// Presets the gimbal did not say (NIC to `P?nn`).
    pub(super) unsaid: BTreeSet<u8>,
    /// Stops from links below the holder, and when (module `mod`, [`super::STOP_SPACING`]).
    pub(super) stops_below: Vec<(Arc<str>, u64)>,
    /// Found after a start or a port's reopening, its motion unknown:
    /// read twice, and stopped if it moves ([`StopCause::FoundMoving`]).
    pub(super) found: bool,
    /// A stop is owed for a gimbal found moving.
    pub(super) stop_found: bool,
    /// A command that moves it no one knows where, not yet on the bus, and
    /// the motion noted before it: given up before the bus (a take-over
    /// drops the old holder's queue), it moved nothing, and that motion is
    /// restored (the governance simulation: a refused `*mp` left a jog
    /// waiting for the gimbal to be seen still).
    pub(super) unknown_by: Option<(CommandId, [AxisMotion; 2])>,
    /// A slew of each axis the other way than it slews, not yet on the
    /// bus: its command and direction. The slew it reverses is followed
    /// (its stop planned) until it began (the governance simulation: a
    /// `TU` held in the port's quiet after a lost frame was taken for
    /// begun, and the `TD` before it ran past the limit unstopped).
    pub(super) reversing: [Option<(CommandId, i32)>; 2],
    /// From a stop sent to the gimbal reading it, its frame lost once (its
    /// port's [`Line::latency`], as of the last [`Gimbal::follow`]).
    pub(super) stop_latency: u64,
}

impl Gimbal {
    /// Who holds it, control lapsed or not.
    pub fn held(&self, now: u64, hold: u64) -> Option<&Held> {
        self.holder.as_ref().filter(|h| !h.lapsed(now, hold))
    }

    /// Forget what was learnt (its port closed or was lost, or it was
    /// given another address): found again as if gcud had just started.
    pub fn forget(&mut self) {
        self.position = None;
        self.anchor = None;
        self.axes = [AxisMotion::Unknown; 2];
        self.rates = None;
        self.accels = None;
        self.presets.clear();
        self.unsaid.clear();
        self.asking = false;
        self.stop_at = [None; 2];
        self.poll_at = None;
        self.changes_in_flight = 0;
        self.step = [None; 2];
        self.step_rates.clear();
        self.found = true;
    }

    /// Follow it and learn its position, speeds and presets (`named`:
    /// those park and tours recall, asked whatever the scan finds).
    pub fn start_learning(&mut self, named: impl IntoIterator<Item = u8>) {
        self.watched = true;
        self.need_position = true;
        self.need_rates = true;
        self.need_accels = true;
        self.scan = Some(0);
        self.ask_presets.extend(named);
        self.retry_at = None;
    }

    pub fn learn(&mut self, learning: Learning) {
        match learning {
            Learning::Speeds => {
                self.changes_in_flight = self.changes_in_flight.saturating_sub(1);
                self.need_rates = true;
                self.need_accels = true;
                self.retry_at = None;
            }
            Learning::Preset(n) => {
                self.ask_presets.insert(n);
                self.retry_at = None;
            }
        }
    }

    /// A result to a query that describes `describes` (the router's
    /// in-flight record), answered at `now`.
    pub fn answered(&mut self, now: u64, describes: Describes, reply: &Reply<'_>, line: Line) {
        // What `R?` and `A?` say while a change is on its way may be from before it.
        let settled = self.changes_in_flight == 0;
        match (describes, reply) {
            (Describes::Position, Reply::Position(p)) => self.read_position(now, *p, line),
            (Describes::Preset(n), Reply::Position(p)) => {
                self.presets.insert(n, *p);
                self.unsaid.remove(&n);
            }
            (Describes::Rates(None), Reply::Rates { pan, tilt }) if settled => {
                self.rates = Some([u32::from(pan.0), u32::from(tilt.0)]);
            }
            (Describes::Rates(Some(axis)), Reply::Rate(r)) if settled => {
                if let Some(rates) = self.rates.as_mut() {
                    rates[axis_index(axis)] = u32::from(r.0);
                }
            }
            (Describes::Accelerations(None), Reply::Accelerations { pan, tilt }) if settled => {
                self.accels = Some([u32::from(pan.0), u32::from(tilt.0)]);
            }
            (Describes::Accelerations(Some(axis)), Reply::Acceleration(a)) if settled => {
                if let Some(accels) = self.accels.as_mut() {
                    accels[axis_index(axis)] = u32::from(a.0);
                }
            }
            _ => return,
        }
        // A rate learnt at a proportional step bounds that step from now on.
        if let (Some(rates), Describes::Rates(_)) = (self.rates, describes) {
            for (axis, (step, rate)) in self.step.iter().zip(rates).enumerate() {
                if let Some(step) = *step {
                    self.step_rates.insert((axis, step), rate);
                }
            }
        }
    }

    /// Whether the stop of an axis told to stop at `since` was lost, by
    /// the reading at `at`: past the stop's latency it does not brake (its
    /// mean speed since the last reading is no lower than the one before,
    /// `mean_before`), or it still moves after braking from top speed.
    fn lost_stop(&self, axis: usize, since: u64, at: u64, mean_before: u32, line: Line) -> bool {
        let (Some(v), Some(a)) = (self.rate(axis), self.accel(axis)) else {
            return false;
        };
        let received = since + line.latency() + SETTLE_SPAN;
        let mean = self.seen_rate[axis].0;
        let not_braking = at > received && mean > SAME as u32 * 10 && mean * 20 >= mean_before * 19;
        let braking_ms = u64::from(v) * 1000 / u64::from(a.max(1));
        not_braking || at > received + braking_ms
    }

    pub fn may_be_moving(&self) -> bool {
        self.axes.iter().any(|a| *a != AxisMotion::Still)
    }

    /// The axis' top rate; while it slews, no less than when the slew
    /// began (a speed change may not apply to a slew under way).
    pub(super) fn rate(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.slew_rate);
        let now = configured.or(self.rates).map(|r| r[axis].max(1))?;
        let rate = match (self.axes[axis], self.slew_began_with[axis]) {
            (AxisMotion::Slew { .. }, Some((rate, _))) => now.max(rate),
            _ => now,
        };
        Some(rate.max(self.seen_rate[axis].0))
    }

    /// The axis' acceleration; while it slews, no more than when the slew began.
    pub(super) fn accel(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.acceleration);
        let now = configured.or(self.accels).map(|a| a[axis].max(1))?;
        Some(match (self.axes[axis], self.slew_began_with[axis]) {
            (AxisMotion::Slew { .. }, Some((_, accel))) => now.min(accel),
            _ => now,
        })
    }

    /// The most the axis may speed up with: while it slews, no less than
    /// when the slew began (an acceleration lowered mid-slew brakes at the
    /// new, but it gained speed at the old).
    pub(super) fn accel_up(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.acceleration);
        let now = configured.or(self.accels).map(|a| a[axis].max(1))?;
        Some(match (self.axes[axis], self.slew_began_with[axis]) {
            (AxisMotion::Slew { .. }, Some((_, accel))) => now.max(accel),
            _ => now,
        })
    }

    /// Where it may be now, per axis; `None` when unknown.
    pub fn region(&self, now: u64) -> Option<Region> {
        let reading = self.position?;
        let p = axes(reading.position);
        let mut region = [Span::at(p[0]), Span::at(p[1])];
        for axis in 0..2 {
            region[axis] = match self.axes[axis] {
                AxisMotion::Still => Span::at(p[axis]),
                AxisMotion::Goto { target, moving } => {
                    let path = Span::at(p[axis]).join(&Span::at(target));
                    match moving {
                        false => path,
                        true => {
                            let reach = braking(self.rate(axis)?, self.accel(axis)?);
                            Span::new(path.lo - reach, path.hi + reach)
                        }
                    }
                }
                AxisMotion::Slew { dir, since } => {
                    let (v, a) = (self.rate(axis)?, self.accel(axis)?);
                    let run = distance_in(now.saturating_sub(reading.at.max(since)), v) + braking(v, a);
                    // Begun while moving (`since` 0), it may first run on the other way.
                    let back = if since == 0 { braking(v, a) } else { 0 };
                    Span::at(p[axis] - dir * back).join(&Span::at(p[axis] + dir * run))
                }
                AxisMotion::Settling { since } => {
                    // Told to stop at `since`: it may run on until that stop
                    // has surely reached it (its frame lost once), then
                    // brake (the governance simulation: a tilt slew judged
                    // from a reading before a lost boundary stop took the
                    // pan for 15 degrees short of where it came to rest).
                    let (v, a) = (self.rate(axis)?, self.accel(axis)?);
                    let run = distance_in((since + self.stop_latency).saturating_sub(reading.at), v);
                    let reach = run + braking(v, a);
                    Span::new(p[axis] - reach, p[axis] + reach)
                }
                AxisMotion::Unknown => return None,
            };
        }
        Some(region)
    }
    /// A position read (answered at `now`, at `bps`): motions confirmed,
    /// slews planned again.
    pub fn read_position(&mut self, now: u64, position: Position, line: Line) {
        // The gimbal read it before the result's bytes were on the wire.
        let at = now.saturating_sub(wire_ms(HEADER_LEN + 10, line.bps));
        let before = self.position.map(|r| (r.at, axes(r.position)));
        let p = axes(position);
        let mean_before = self.seen_rate.map(|(mean, _)| mean);
        for axis in 0..2 {
            // The mean speed since the last reading, plus what the axis may
            // have gained meanwhile, bounds its speed now.
            self.seen_rate[axis] = match (before, self.accel(axis)) {
                (Some((t, b)), Some(a)) if at > t => {
                    let dt = (at - t) as f64;
                    let mean = f64::from((p[axis] - b[axis]).abs()) * 1000.0 / dt;
                    // Accelerating through a short span, it ends faster than its mean.
                    let end = mean + f64::from(a) * dt.min(SETTLE_SPAN as f64) / 2000.0;
                    (
                        mean.min(f64::from(u32::MAX)) as u32,
                        end.min(f64::from(u32::MAX)) as u32,
                    )
                }
                _ => (0, 0),
            };
        }
        // Two readings close in time tell nothing of standing still, nor
        // one taken before the motion began (a goto queued behind other
        // work is read again before the gimbal got going): compared with
        // the anchor, which readings closer than that leave in place.
        let anchor = self.anchor.filter(|r| r.at >= self.moved_at);
        let before = anchor.filter(|r| at >= r.at + SETTLE_SPAN).map(|r| axes(r.position));
        self.position = Some(Reading { at, position });
        if before.is_some() || anchor.is_none() {
            self.anchor = self.position;
        }
        self.need_position = false;
        if self.found && self.axes.contains(&AxisMotion::Unknown) {
            // Found after a start or a reopening: a second reading tells
            // whether it moves; one that does is stopped (it may be a slew
            // begun before gcud was, with nobody left to stop it).
            if let Some(b) = before {
                self.found = false;
                // Any change at all: a motion crawling at its slowest step
                // moves less than [`SAME`] between two readings (the
                // governance simulation: a park recall at step 0 found
                // after a restart was taken for still and ran on). A stop
                // to a gimbal that stands still does nothing.
                if (0..2).any(|axis| b[axis] != p[axis]) {
                    self.stop_found = true;
                    self.axes = [AxisMotion::Settling { since: now }; 2];
                } else {
                    self.axes = [AxisMotion::Still; 2];
                }
            }
            self.replan = false;
            self.poll_at = Some(now + SETTLE_SPAN);
            return;
        }
        self.found = false;
        for axis in 0..2 {
            let unchanged = before.is_some_and(|b| (b[axis] - p[axis]).abs() <= SAME);
            self.unchanged[axis] = if unchanged {
                self.unchanged[axis].saturating_add(1)
            } else {
                0
            };
            // A goto may start slowly (an axis scaled down to arrive with
            // the other): only arrival, or no change over several polls,
            // ends it; a stop ends at the first reading that did not change.
            self.axes[axis] = match self.axes[axis] {
                AxisMotion::Goto { target, .. } if (p[axis] - target).abs() <= super::travel::ARRIVED => {
                    AxisMotion::Still
                }
                AxisMotion::Goto { .. } | AxisMotion::Unknown if self.unchanged[axis] >= STILL_POLLS => {
                    AxisMotion::Still
                }
                AxisMotion::Settling { .. } if unchanged => AxisMotion::Still,
                // Still moving long after its stop could have braked it: the
                // stop was lost (a stop to device 255 is never confirmed), so
                // it is followed as a slew again and gets a stop of its own.
                AxisMotion::Settling { since }
                    if before.is_some() && self.lost_stop(axis, since, at, mean_before[axis], line) =>
                {
                    let dir = before.map_or(0, |b| (p[axis] - b[axis]).signum());
                    AxisMotion::Slew { dir, since: 0 }
                }
                other => other,
            };
        }
        for axis in 0..2 {
            if self.axes[axis] == AxisMotion::Still {
                self.stop_at[axis] = None;
            }
        }
        self.replan = self.axes.iter().any(|a| matches!(a, AxisMotion::Slew { .. }));
        self.poll_at = self.may_be_moving().then_some(now + MOTION_POLL);
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

    /// An own query ended; `said`: with a result (`Some(true)`), a NIC
    /// (`Some(false)`: the gimbal has no such thing), or no answer at all
    /// (`None`: lost on the bus, or the gimbal silent; asked again later).
    pub fn query_ended(&mut self, now: u64, purpose: Purpose, said: Option<bool>) {
        let answered = said == Some(true);
        if purpose == Purpose::Motion {
            // A stop or goto of its own: no query of it was outstanding.
            return;
        }
        self.asking = false;
        match purpose {
            Purpose::Rates if answered => self.need_rates = false,
            Purpose::Accelerations if answered => self.need_accels = false,
            Purpose::Preset(n) if self.scan == Some(n) => {
                // Scanned until the first preset not implemented (a NIC,
                // 1.6.1); one unanswered is asked again after a while.
                match said {
                    Some(true) => self.scan = n.checked_add(1),
                    Some(false) => {
                        self.scan = None;
                        self.unsaid.insert(n);
                    }
                    None => self.retry_at = Some(now + RETRY),
                }
            }
            Purpose::Preset(n) if said == Some(false) => {
                self.unsaid.insert(n);
            }
            Purpose::Preset(n) if said.is_none() => {
                // Lost on the bus or the gimbal silent: asked again after a
                // while (the end-to-end test: one lost answer at start left
                // park's preset unknown for good).
                self.ask_presets.insert(n);
                self.retry_at = Some(now + RETRY);
            }
            Purpose::Preset(_) | Purpose::Motion => {}
            Purpose::Position | Purpose::Rates | Purpose::Accelerations => {}
        }
        if !answered && purpose != Purpose::Motion && !matches!(purpose, Purpose::Preset(_)) {
            self.retry_at = Some(now + RETRY);
        }
    }

    /// The earliest stop planned for it.
    pub fn stop_planned(&self) -> Option<u64> {
        self.stop_at.iter().flatten().map(|&(t, _)| t).min()
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
        let replan = self.replan.then_some(0);
        stops.chain(poll).chain(learn).chain(replan).min()
    }
}

pub(super) fn query(port: u8, device: u8, command: Command<'static>, purpose: Purpose) -> Order {
    Order {
        port,
        device,
        command,
        stop: None,
        cancel_slews: None,
        purpose,
    }
}

/// A port's line, as far as the follower's timing goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Line {
    pub bps: u32,
    /// How long a command without result holds the bus after its ACK.
    pub nic_window: u64,
    /// How long the port waits for an ACK before it sends a frame again (1.4.2).
    pub ack_timeout: u64,
    /// How long a command to device 255 holds the bus after it is written.
    pub broadcast_guard: u64,
    /// The longest a queued command waits for the bus before it is given
    /// up (the delivery time-out): a goto decided now may begin that late.
    pub queue_wait: u64,
}

impl Line {
    /// How long a slew to device 255 holds the bus: its frame and the
    /// broadcast guard, before any stop may go.
    pub fn broadcast_hold(&self) -> u64 {
        wire_ms(HEADER_LEN + 3, self.bps) + self.broadcast_guard
    }

    /// One `P?` exchange: the query, the ACK, the result and a device's turnaround.
    pub fn exchange(&self) -> u64 {
        let bps = self.bps;
        wire_ms(HEADER_LEN + 3, bps) + wire_ms(1, bps) + wire_ms(HEADER_LEN + 10, bps) + TURNAROUND
    }

    /// The longest a short exchange holds the bus: a query, or a command
    /// without result and its NIC window.
    pub fn busy(&self) -> u64 {
        let command = wire_ms(HEADER_LEN + 9, self.bps) + wire_ms(1, self.bps) + self.nic_window;
        self.exchange().max(command)
    }

    /// From deciding a stop to the gimbal reading it: the port keeps the
    /// bus free for it (no work starts that would still hold the bus then,
    /// `Port::reserve`), so at most another gimbal's stop goes first, then
    /// the stop's own frame; and the bus may lose that frame once: its
    /// ACK time-out and the frame again (ARCHITECTURE "Governance", the
    /// documented margin holds with one lost stop).
    pub fn latency(&self) -> u64 {
        let stop = wire_ms(HEADER_LEN + 3, self.bps);
        self.busy() + stop + self.ack_timeout + stop
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Angle;

    fn at(pan: i16, tilt: i16) -> Position {
        Position::new(Angle(pan), Angle(tilt))
    }

    fn line() -> Line {
        Line {
            bps: 115_200,
            nic_window: 31,
            ack_timeout: 12,
            broadcast_guard: 40,
            queue_wait: 800,
        }
    }

    /// Found at start (or on a reopened port), a gimbal is known to stand
    /// still from two readings [`SETTLE_SPAN`] apart however often doors
    /// read it between them; and one that moves slowly is found moving.
    #[test]
    fn a_gimbal_found_is_known_still_or_moving_though_doors_read_it_every_50_ms() {
        let mut g = Gimbal::default();
        g.forget();
        for t in (1000..=1150).step_by(50) {
            g.read_position(t, at(0, 0), line());
        }
        assert_eq!(g.axes, [AxisMotion::Still; 2], "still");
        let mut g = Gimbal::default();
        g.forget();
        for (n, t) in (1000..=1150).step_by(50).enumerate() {
            g.read_position(t, at(n as i16, 0), line());
        }
        assert!(
            matches!(g.axes[0], AxisMotion::Settling { .. }),
            "found moving, stopped: {:?}",
            g.axes
        );
    }

    /// A tour waited 60 s (GOTO_PATIENCE) for a goto taken for stopped
    /// short: its first reading, taken before the gimbal got going, agreed
    /// with the reading before the goto.
    #[test]
    fn a_goto_is_not_taken_for_stopped_by_a_reading_from_before_it_began() {
        let mut g = Gimbal::default();
        g.read_position(1000, at(0, 0), line());
        g.going(2000, [3000, 0]);
        g.read_position(2030, at(0, 0), line());
        assert_eq!(
            g.axes[0],
            AxisMotion::Goto {
                target: 3000,
                moving: false
            },
            "still on its way"
        );
        assert!(g.may_be_moving() && g.poll_at.is_some(), "followed further");
        // Readings after it began that agree, several in a row: it stopped short.
        for (n, t) in [2300, 2450, 2600, 2750].into_iter().enumerate() {
            assert_ne!(g.axes[0], AxisMotion::Still, "not yet at reading {n}");
            g.read_position(t, at(0, 0), line());
        }
        assert_eq!(g.axes[0], AxisMotion::Still);
        // Arrived: still at once.
        g.going(3000, [100, 0]);
        g.read_position(3250, at(100, 0), line());
        assert_eq!(g.axes, [AxisMotion::Still; 2]);
    }
}
