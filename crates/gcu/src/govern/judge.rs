//! What a command from a link may do to a governed gimbal, from what the
//! governor knows of it (ARCHITECTURE "Governance"): its row's mount
//! effect judged against the limits and zones (refused, let through, or
//! held while gcud learns what it needs), the motion it starts noted, and
//! what it changes learnt again afterwards. Control by priority, and the
//! stops from links below the holder, are judged here too.

use std::sync::Arc;

use sagebrush_protocol::{MountEffect, NewSpeed};

use super::Decision;
use super::control::Who;
use super::knowledge::{AxisMotion, Gimbal, Learning, Line, axis_index};
use super::rules::GimbalRules;
use super::rules::Span;
use super::travel::{axes, braking, check_goto, limits, meets};
use crate::types::{CommandId, DropReason};

impl Gimbal {
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
    /// `broadcast`: sent to device 255 (it holds the bus for its broadcast guard).
    pub fn check(&mut self, now: u64, effect: MountEffect, line: Line, broadcast: bool) -> Result<(), Decision> {
        let judged = match self.rules.as_ref().filter(|r| r.bounds_travel()) {
            None => return Ok(()),
            Some(rules) => self.judge(now, rules, effect, line, broadcast),
        };
        if let Err(Decision::Learn(why)) = judged {
            self.ask(why, effect);
        }
        judged
    }

    fn judge(
        &self,
        now: u64,
        rules: &GimbalRules,
        effect: MountEffect,
        line: Line,
        broadcast: bool,
    ) -> Result<(), Decision> {
        // From where it may be when the goto begins: queued, it may wait up
        // to the delivery time-out while a slew runs on (the governance
        // simulation: a goto decided from where a slew was, sent 240 ms
        // later, crossed a zone's corner).
        let goto = |target: [i32; 2]| match check_goto(rules, self.region(now + line.queue_wait), target) {
            Ok(()) => Ok(()),
            Err(DropReason::PositionUnknown) => Err(Decision::Learn(DropReason::PositionUnknown)),
            Err(reason) => Err(Decision::Refuse(reason)),
        };
        // Moving no one knows where (found so after a start, or after an
        // unbounded command): a goto waits until gcud saw where it is, even
        // with limits alone (its overshoot is not known either).
        let unknown = self.axes.contains(&AxisMotion::Unknown);
        // How long after now a stop may first go: after this command's own
        // exchange, or a broadcast's guard.
        let lead = if broadcast {
            line.broadcast_hold()
        } else {
            line.exchange()
        };
        match effect {
            MountEffect::GoTo(_) | MountEffect::RecallPreset(_) if unknown => {
                Err(Decision::Learn(DropReason::PositionUnknown))
            }
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
                match self.check_slew(now, rules, axis_index(axis), if positive { 1 } else { -1 }, line, lead) {
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
                self.check_change(now, rules, axis_index(axis), rate, None, line, lead)
            }
            MountEffect::Acceleration { axis, acceleration } => self.check_change(
                now,
                rules,
                axis_index(axis),
                None,
                Some(u32::from(acceleration.0)),
                line,
                lead,
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
    /// when the new rate is not known. `lead`: how long after now the stop
    /// may first go (a change to device 255 holds the bus for its guard:
    /// the governance simulation, an `AP` to 5.1.255 kept a boundary stop
    /// 80 ms late).
    #[allow(clippy::too_many_arguments)]
    fn check_change(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        rate: Option<u32>,
        accel: Option<u32>,
        line: Line,
        lead: u64,
    ) -> Result<(), Decision> {
        let (dir, since) = match self.axes[axis] {
            AxisMotion::Slew { dir, since } => (dir, since),
            AxisMotion::Goto { target, .. } => return self.check_goto_change(now, rules, axis, target, rate, accel),
            AxisMotion::Settling { .. } => {
                let at = self.position.map_or(0, |r| axes(r.position)[axis]);
                return self.check_goto_change(now, rules, axis, at, rate, accel);
            }
            AxisMotion::Still => return Ok(()),
            // Moving no one knows how (found so after a start): a slower
            // acceleration or a faster rate may carry it further than the
            // stop gcud owes it; decided once it was seen (the governance
            // simulation: an `APnnnn` just after a restart, before the
            // found-moving stop, ran the slew 0.5 degree past the limit).
            AxisMotion::Unknown => return Err(Decision::Learn(DropReason::PositionUnknown)),
        };
        if rate.is_none() && accel.is_none() {
            return Err(Decision::Refuse(DropReason::RateUnknown));
        }
        let mut trial = self.clone();
        trial.changed(axis, rate, accel);
        match trial.stop_due(now, rules, axis, dir, since, line) {
            Ok(None) => Ok(()),
            Ok(Some((Some(t), _))) if t >= now + lead => Ok(()),
            Ok(Some((_, reason))) => Err(Decision::Refuse(reason)),
            Err(reason) => Err(Decision::Refuse(reason)),
        }
    }

    /// A change of `axis`' rate or acceleration while it goes to `target`
    /// (or brakes there): with the faster rate and the lower acceleration
    /// it may overshoot by its braking distance, which must stay within
    /// the limits and out of the zones (the governance simulation: `AP0100`
    /// mid-goto ran 29 degrees past the target and the limit); unknown, the
    /// change is refused.
    fn check_goto_change(
        &self,
        now: u64,
        rules: &GimbalRules,
        axis: usize,
        target: i32,
        rate: Option<u32>,
        accel: Option<u32>,
    ) -> Result<(), Decision> {
        let (Some(v), Some(a), Some(region)) = (self.rate(axis), self.accel(axis), self.region(now)) else {
            return Err(Decision::Refuse(DropReason::RateUnknown));
        };
        let v = rate.map_or(v, |r| r.max(v));
        let a = accel.map_or(a, |n| n.min(a));
        let reach = braking(v, a);
        let mut wide = region;
        let path = region[axis].join(&Span::at(target));
        wide[axis] = Span::new(path.lo - reach, path.hi + reach);
        if limits(rules, axis).is_some_and(|l| !(l.contains(wide[axis].lo) && l.contains(wide[axis].hi))) {
            return Err(Decision::Refuse(DropReason::TravelLimit));
        }
        if rules.keep_out.iter().any(|z| meets(z, wide) && !meets(z, region)) {
            return Err(Decision::Refuse(DropReason::KeepOut));
        }
        Ok(())
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
        if matches!(
            effect,
            MountEffect::GoTo(_)
                | MountEffect::RecallPreset(_)
                | MountEffect::Slew { .. }
                | MountEffect::Halt
                | MountEffect::Identity
        ) {
            // A motion noted after it: the one before it is not what to restore.
            self.unknown_by = None;
        }
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
                None => self.unknown_motion(now, Some(id)),
            },
            MountEffect::Slew { axis, positive } => {
                self.slewing(now, axis_index(axis), if positive { 1 } else { -1 }, id)
            }
            MountEffect::Halt => self.stopping(now, true, true),
            MountEffect::Unbounded => self.unknown_motion(now, Some(id)),
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
}
