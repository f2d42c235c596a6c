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

use std::sync::Arc;

use sagebrush_protocol::{Axis, Describes, MountEffect, NewSpeed, Reply};

use super::control::{Held, Who};
use super::rules::{GimbalRules, Span};
use super::travel::{Kinematics, Region, axes, braking, check_goto, distance_in, room_ahead};
use super::{Decision, GovernStats, Order, Purpose};
use crate::types::{CommandId, DropReason, RouterEvent, StopCause};

/// Pan 0, tilt 1, as the follower indexes its axes.
fn axis_index(axis: Axis) -> usize {
    match axis {
        Axis::Pan => 0,
        Axis::Tilt => 1,
    }
}

/// Poll period of a goto or a stop in progress.
const MOTION_POLL: u64 = 250;
/// Shortest and longest wait between position polls of a followed slew.
const MAX_SLEW_POLL: u64 = 1000;
/// Wait before asking again what a gimbal did not answer.
const RETRY: u64 = 2000;
/// Readings this close (hundredths of a degree) mean the axis stands still.
const SAME: i32 = 5;
/// The shortest span between two readings that may show an axis standing still (ms).
const SETTLE_SPAN: u64 = 100;
/// Readings in a row without change that end a goto short of its target.
const STILL_POLLS: u8 = 4;
/// A device's turnaround before it answers, allowed for (ms).
const TURNAROUND: u64 = 5;

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
    /// The rate and acceleration of each axis when its slew began.
    slew_began_with: [Option<(u32, u32)>; 2],
    /// Readings in a row each axis did not change.
    unchanged: [u8; 2],
    /// A goto that replaced a followed slew, not yet on the bus: its
    /// command (once known) and target; the slew's stop stays planned.
    guard: Option<(Option<CommandId>, [i32; 2])>,
    /// How fast each axis moved between the last two readings, per second:
    /// its mean (a `HO` may run faster than the rate `R?` answers), and the
    /// most it may have reached at the last one.
    seen_rate: [(u32, u32); 2],
    /// Changes of speed, acceleration or dynamics from links not yet ended:
    /// what `R?` and `A?` answer meanwhile may be from before them, and a
    /// slew waits for them (ARCHITECTURE "Governance", learn before deciding).
    changes_in_flight: u8,
    /// The proportional step (`SPn`, `STn`) each axis was last set to.
    step: [Option<u8>; 2],
    /// The rate each axis answered at a proportional step (`R?` after `SPn`):
    /// bounds a step change during a slew.
    step_rates: BTreeMap<(usize, u8), u32>,
    /// Presets the gimbal did not say (NIC to `P?nn`).
    unsaid: BTreeSet<u8>,
    /// Stops from links below the holder, and when (module `mod`, [`super::STOP_SPACING`]).
    stops_below: Vec<(Arc<str>, u64)>,
    /// Found after a start or a port's reopening, its motion unknown:
    /// read twice, and stopped if it moves ([`StopCause::FoundMoving`]).
    found: bool,
    /// A stop is owed for a gimbal found moving.
    stop_found: bool,
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

    /// The holder's query renews its control while its slew runs, as a
    /// query renews the motion lease (ARCHITECTURE "Safety"): a held slew
    /// keeps control as long as its holder holds it.
    pub fn renewed(&mut self, now: u64, hold: u64, key: &Arc<str>) {
        if !self.axes.iter().any(|a| matches!(a, AxisMotion::Slew { .. })) {
            return;
        }
        if let Some(h) = self.holder.as_mut().filter(|h| !h.lapsed(now, hold)) {
            if matches!(&h.who, Who::Link { key: k, .. } if k == key) {
                h.last = now;
            }
        }
    }

    /// Whether a stop from `me`, a link below the holder, comes sooner than
    /// [`super::STOP_SPACING`] after its last one.
    pub fn stops_limited(&self, now: u64, me: &Who) -> bool {
        let Who::Link { key, .. } = me else { return false };
        self.stops_below
            .iter()
            .any(|(k, t)| k == key && now < t.saturating_add(super::STOP_SPACING))
    }

    /// A stop from `me`, a link below the holder, let through.
    pub fn stop_from_below(&mut self, now: u64, me: &Who) {
        let Who::Link { key, .. } = me else { return };
        self.stops_below
            .retain(|(_, t)| now < t.saturating_add(super::STOP_SPACING));
        self.stops_below.push((key.clone(), now));
    }

    /// Whether a command of mount effect `effect` may go to this gimbal
    /// now as far as its limits and zones go: `Err` refuses it, or holds it
    /// until gcud learnt what it needs (asked here).
    pub fn check(&mut self, now: u64, effect: MountEffect, line: Line) -> Result<(), Decision> {
        let judged = match self.rules.as_ref().filter(|r| r.bounds_travel()) {
            None => return Ok(()),
            Some(rules) => self.judge(now, rules, effect, line),
        };
        if let Err(Decision::Learn(why)) = judged {
            self.ask(why, effect);
        }
        judged
    }

    fn judge(&self, now: u64, rules: &GimbalRules, effect: MountEffect, line: Line) -> Result<(), Decision> {
        let goto = |target: [i32; 2]| match check_goto(rules, self.region(now), target) {
            Ok(()) => Ok(()),
            Err(DropReason::PositionUnknown) => Err(Decision::Learn(DropReason::PositionUnknown)),
            Err(reason) => Err(Decision::Refuse(reason)),
        };
        match effect {
            MountEffect::GoTo(p) => goto(axes(p)),
            MountEffect::RecallPreset(n) => match self.presets.get(&n) {
                Some(p) => goto(axes(*p)),
                None if self.unsaid.contains(&n) => Err(Decision::Refuse(DropReason::PresetUnknown)),
                None => Err(Decision::Learn(DropReason::PresetUnknown)),
            },
            MountEffect::Slew { axis, positive } => {
                if self.changes_in_flight > 0 {
                    // A speed change before it has not ended: its rate is not known yet.
                    return Err(Decision::Learn(DropReason::RateUnknown));
                }
                match self.check_slew(now, rules, axis_index(axis), if positive { 1 } else { -1 }, line) {
                    Ok(()) => Ok(()),
                    Err(reason @ (DropReason::PositionUnknown | DropReason::RateUnknown)) => {
                        Err(Decision::Learn(reason))
                    }
                    Err(reason) => Err(Decision::Refuse(reason)),
                }
            }
            MountEffect::Speed { axis, to } => {
                let rate = match to {
                    NewSpeed::Rate(r) => Some(u32::from(r.0)),
                    NewSpeed::Step(step) => self.step_bound(axis_index(axis), step.get()),
                };
                self.check_change(now, rules, axis_index(axis), rate, None, line)
            }
            MountEffect::Acceleration { axis, acceleration } => self.check_change(
                now,
                rules,
                axis_index(axis),
                None,
                Some(u32::from(acceleration.0)),
                line,
            ),
            _ => Ok(()),
        }
    }

    /// The most an axis may run at proportional step `step`: the rate it
    /// answered at that step, or at step 15 (its maximum, Table 11), or the
    /// configured top rate.
    fn step_bound(&self, axis: usize, step: u8) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.slew_rate).map(|r| r[axis]);
        configured
            .or_else(|| self.step_rates.get(&(axis, step)).copied())
            .or_else(|| self.step_rates.get(&(axis, 15)).copied())
    }

    /// A change of `axis`' rate or acceleration while it slews: the stop
    /// is planned again with the worst of old and new (the faster rate, the
    /// lower acceleration); refused when that stop would come too late, or
    /// when the new rate is not known.
    fn check_change(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        rate: Option<u32>,
        accel: Option<u32>,
        line: Line,
    ) -> Result<(), Decision> {
        let AxisMotion::Slew { dir, since } = self.axes[axis] else {
            return Ok(());
        };
        if rate.is_none() && accel.is_none() {
            return Err(Decision::Refuse(DropReason::RateUnknown));
        }
        let mut trial = self.clone();
        trial.changed(axis, rate, accel);
        match trial.stop_due(now, rules, axis, dir, since, line) {
            Ok(None) => Ok(()),
            Ok(Some((Some(t), _))) if t >= now => Ok(()),
            Ok(Some((_, reason))) => Err(Decision::Refuse(reason)),
            Err(reason) => Err(Decision::Refuse(reason)),
        }
    }

    /// `axis` now runs at `rate` and accelerates at `accel` (those given):
    /// while it slews, [`Gimbal::rate`] and [`Gimbal::accel`] keep the worst
    /// of these and the slew's own.
    fn changed(&mut self, axis: usize, rate: Option<u32>, accel: Option<u32>) {
        if let Some(v) = rate {
            match self.rates.as_mut() {
                Some(r) => r[axis] = v,
                None if matches!(self.axes[axis], AxisMotion::Slew { .. }) => {
                    self.rates = Some([v, v]);
                }
                None => {}
            }
        }
        if let Some(a) = accel {
            match self.accels.as_mut() {
                Some(r) => r[axis] = a,
                None if matches!(self.axes[axis], AxisMotion::Slew { .. }) => {
                    self.accels = Some([a, a]);
                }
                None => {}
            }
        }
        self.replan = true;
    }

    /// What a held command needs is asked of the gimbal.
    fn ask(&mut self, why: DropReason, effect: MountEffect) {
        match (why, effect) {
            (DropReason::PresetUnknown, MountEffect::RecallPreset(n)) => {
                self.ask_presets.insert(n);
            }
            (DropReason::RateUnknown, _) if self.changes_in_flight > 0 => return,
            (DropReason::RateUnknown, _) => {
                self.need_rates |= self.rates.is_none();
                self.need_accels |= self.accels.is_none();
            }
            _ => self.need_position |= self.position.is_none(),
        }
        self.retry_at = None;
    }

    /// A command of mount effect `effect` was let through as `id`: its
    /// motion noted, and what it changes, to be learnt again when it ends.
    pub fn accepted(&mut self, now: u64, id: CommandId, effect: MountEffect) -> Option<Learning> {
        match effect {
            MountEffect::GoTo(p) => {
                self.going(now, axes(p));
                self.goto_is(id);
            }
            MountEffect::RecallPreset(n) => match self.presets.get(&n).copied() {
                Some(p) => {
                    self.going(now, axes(p));
                    self.goto_is(id);
                }
                None => self.unknown_motion(now),
            },
            MountEffect::Slew { axis, positive } => self.slewing(now, axis_index(axis), if positive { 1 } else { -1 }),
            MountEffect::Halt => self.stopping(now, true, true),
            MountEffect::Unbounded => self.unknown_motion(now),
            MountEffect::StorePreset(n) => {
                self.stored(n);
                return Some(Learning::Preset(n));
            }
            MountEffect::Identity => {
                // Another address or line: the gimbal here is found anew.
                self.forget();
                return self.watched.then_some(Learning::Speeds);
            }
            MountEffect::Speed { axis, to } => {
                let axis = axis_index(axis);
                let rate = match to {
                    NewSpeed::Rate(r) => {
                        self.step[axis] = None;
                        Some(u32::from(r.0))
                    }
                    NewSpeed::Step(step) => {
                        self.step[axis] = Some(step.get());
                        self.step_bound(axis, step.get())
                    }
                };
                match rate {
                    Some(v) => self.changed(axis, Some(v), None),
                    None => self.rates = None,
                }
                return self.change_in_flight();
            }
            MountEffect::Acceleration { axis, acceleration } => {
                self.changed(axis_index(axis), None, Some(u32::from(acceleration.0)));
                return self.change_in_flight();
            }
            MountEffect::Dynamics => {
                self.rates = None;
                self.accels = None;
                return self.change_in_flight();
            }
            MountEffect::Setting | MountEffect::Reads(_) | MountEffect::Stop { .. } => {}
        }
        None
    }

    fn change_in_flight(&mut self) -> Option<Learning> {
        if !self.watched {
            return None;
        }
        self.changes_in_flight = self.changes_in_flight.saturating_add(1);
        Some(Learning::Speeds)
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

    pub fn may_be_moving(&self) -> bool {
        self.axes.iter().any(|a| *a != AxisMotion::Still)
    }

    /// The axis' top rate; while it slews, no less than when the slew
    /// began (a speed change may not apply to a slew under way).
    fn rate(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.slew_rate);
        let now = configured.or(self.rates).map(|r| r[axis].max(1))?;
        let rate = match (self.axes[axis], self.slew_began_with[axis]) {
            (AxisMotion::Slew { .. }, Some((rate, _))) => now.max(rate),
            _ => now,
        };
        Some(rate.max(self.seen_rate[axis].0))
    }

    /// The axis' acceleration; while it slews, no more than when the slew began.
    fn accel(&self, axis: usize) -> Option<u32> {
        let configured = self.rules.as_ref().and_then(|r| r.acceleration);
        let now = configured.or(self.accels).map(|a| a[axis].max(1))?;
        Some(match (self.axes[axis], self.slew_began_with[axis]) {
            (AxisMotion::Slew { .. }, Some((_, accel))) => now.min(accel),
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
    /// acceleration is unknown, or when the stop that keeps it short of the
    /// first limit or zone ahead would be due before the slew is even on
    /// the bus.
    pub fn check_slew(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        dir: i32,
        line: Line,
    ) -> Result<(), DropReason> {
        let since = self.slew_since(now, axis, dir);
        match self.stop_due(now, rules, axis, dir, since, line)? {
            None => Ok(()),
            Some((Some(t), _)) if t >= now + line.exchange() => Ok(()),
            Some((_, reason)) => Err(reason),
        }
    }

    /// When a slew of `axis` in `dir` that began at `since` (0: the axis was
    /// already moving, so as fast as it may be) must have its stop sent, from
    /// the last reading: `None` when nothing bounds it; `Some((None, _))`
    /// when even a stop sent now comes too late; and what it stops short of.
    fn stop_due(
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
        let mut kinematics = Kinematics::of(v, a, from - since);
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
    fn slew_since(&self, now: u64, axis: usize, dir: i32) -> u64 {
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

    pub fn going(&mut self, now: u64, target: [i32; 2]) {
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
        // A slew this goto replaces keeps its planned stop until the goto is
        // on the bus: queued behind other work, it must not leave the slew
        // running past its boundary (the goto then runs from rest).
        let slewing = self.stop_at.iter().any(Option::is_some);
        self.guard = slewing.then_some((None, target));
        if !slewing {
            self.stop_at = [None; 2];
        }
        self.poll_at = Some(now + MOTION_POLL);
        self.moved_at = now;
    }

    /// The command that carries the goto just noted is `id`.
    pub fn goto_is(&mut self, id: CommandId) {
        if let Some((pending @ None, _)) = self.guard.as_mut() {
            *pending = Some(id);
        }
    }

    /// Command `id` ended: a goto that never began (given up) lifts its guard.
    pub fn ended(&mut self, id: CommandId) {
        if self.guard.is_some_and(|(g, _)| g == Some(id)) {
            self.guard = None;
        }
    }

    /// Command `id` began on the bus: a goto's guard is lifted.
    pub fn started(&mut self, now: u64, id: CommandId) {
        if let Some((Some(goto), target)) = self.guard {
            if goto == id {
                self.guard = None;
                self.stop_at = [None; 2];
                let moving = self.axes.map(|a| a != AxisMotion::Still);
                self.axes = [0, 1].map(|axis| AxisMotion::Goto {
                    target: target[axis],
                    moving: moving[axis],
                });
                self.poll_at = Some(now + MOTION_POLL);
            }
        }
    }

    pub fn slewing(&mut self, now: u64, axis: usize, dir: i32) {
        let since = self.slew_since(now, axis, dir);
        // Checked before: both are known (or it was refused).
        self.slew_began_with[axis] = self.rate(axis).zip(self.accel(axis));
        self.axes[axis] = AxisMotion::Slew { dir, since };
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
    pub fn read_position(&mut self, now: u64, position: Position, line: Line) {
        // The gimbal read it before the result's bytes were on the wire.
        let at = now.saturating_sub(wire_ms(HEADER_LEN + 10, line.bps));
        let before = self.position.map(|r| (r.at, axes(r.position)));
        let p = axes(position);
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
        // work is read again before the gimbal got going).
        let since = self.moved_at;
        let before = before
            .filter(|&(t, _)| at >= t + SETTLE_SPAN && t >= since)
            .map(|(_, b)| b);
        self.position = Some(Reading { at, position });
        self.need_position = false;
        if self.found && self.axes.contains(&AxisMotion::Unknown) {
            // Found after a start or a reopening: a second reading tells
            // whether it moves; one that does is stopped (it may be a slew
            // begun before gcud was, with nobody left to stop it).
            if let Some(b) = before {
                self.found = false;
                if (0..2).any(|axis| (b[axis] - p[axis]).abs() > SAME) {
                    self.stop_found = true;
                    self.axes = [AxisMotion::Settling; 2];
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
                AxisMotion::Settling if unchanged => AxisMotion::Still,
                other => other,
            };
        }
        self.replan = self.axes.iter().any(|a| matches!(a, AxisMotion::Slew { .. }));
        self.poll_at = self.may_be_moving().then_some(now + MOTION_POLL);
    }

    /// Plans the stop of each slewing axis from the last reading.
    fn plan(&mut self, now: u64, line: Line) {
        self.replan = false;
        let Some(rules) = self.rules.clone() else { return };
        let exchange = line.exchange();
        for axis in 0..2 {
            let AxisMotion::Slew { dir, since } = self.axes[axis] else {
                if self.guard.is_none() {
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
        if self.replan && !self.asking {
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
        if purpose == Purpose::Motion {
            // A stop or goto of its own: no query of it was outstanding.
            return;
        }
        self.asking = false;
        match purpose {
            Purpose::Rates if answered => self.need_rates = false,
            Purpose::Accelerations if answered => self.need_accels = false,
            Purpose::Preset(n) if self.scan == Some(n) => {
                // Scanned until the first preset not implemented (a NIC, 1.6.1).
                self.scan = if answered { n.checked_add(1) } else { None };
                if !answered {
                    self.unsaid.insert(n);
                }
            }
            Purpose::Preset(n) if !answered => {
                self.unsaid.insert(n);
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
}

impl Line {
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
        }
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
