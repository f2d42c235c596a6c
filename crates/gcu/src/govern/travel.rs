//! Travel limits and keep-out zones (ARCHITECTURE "Governance"): what a
//! goto's path may cross, how far a slew may run, and when the stop that
//! ends it must reach the gimbal. Pure arithmetic on hundredths of a
//! degree and milliseconds; the caller keeps the state.

use sagebrush_protocol::Position;

use super::rules::{GimbalRules, Span, Zone};
use crate::types::DropReason;

/// How short of a boundary a followed slew is planned to come to rest:
/// the stop is sent so that the gimbal, braking at its acceleration,
/// stops this far before the limit or zone edge (hundredths of a degree).
pub(crate) const GUARD: i32 = 25;
/// A goto counts as arrived within this distance of its target.
pub(crate) const ARRIVED: i32 = 50;

/// Pan (0) or tilt (1).
pub(crate) type AxisIndex = usize;

/// The two axes of a position, as hundredths of a degree.
pub(crate) fn axes(p: Position) -> [i32; 2] {
    [i32::from(p.pan.centidegrees()), i32::from(p.tilt.centidegrees())]
}

/// Where a gimbal may be, per axis.
pub(crate) type Region = [Span; 2];

fn limits(rules: &GimbalRules, axis: AxisIndex) -> Option<Span> {
    if axis == 0 { rules.pan_limits } else { rules.tilt_limits }
}

fn zone_span(zone: &Zone, axis: AxisIndex) -> Span {
    if axis == 0 { zone.pan } else { zone.tilt }
}

/// A goto from anywhere in `from` (unknown: `None`) to `target`: refused
/// when the target leaves the limits, or when the rectangle spanned by
/// start and target (each axis moves at its own speed) meets a zone.
pub(crate) fn check_goto(rules: &GimbalRules, from: Option<Region>, target: [i32; 2]) -> Result<(), DropReason> {
    for (axis, &t) in target.iter().enumerate() {
        if limits(rules, axis).is_some_and(|l| !l.contains(t)) {
            return Err(DropReason::TravelLimit);
        }
    }
    if rules.keep_out.is_empty() {
        return Ok(());
    }
    let Some(from) = from else {
        return Err(DropReason::PositionUnknown);
    };
    let path = [from[0].join(&Span::at(target[0])), from[1].join(&Span::at(target[1]))];
    match rules
        .keep_out
        .iter()
        .any(|z| z.pan.meets(&path[0]) && z.tilt.meets(&path[1]))
    {
        true => Err(DropReason::KeepOut),
        false => Ok(()),
    }
}

/// The first boundary ahead of a slew of `axis` in direction `dir` (+1 or
/// -1) from `at`, while the other axis stays within `other`: its distance
/// (hundredths of a degree, negative when already past it) and what it
/// is. `None`: nothing bounds the slew.
pub(crate) fn room_ahead(
    rules: &GimbalRules,
    axis: AxisIndex,
    dir: i32,
    at: i32,
    other: Span,
) -> Option<(i32, DropReason)> {
    let mut room: Option<(i32, DropReason)> = None;
    let mut consider = |distance: i32, reason: DropReason| {
        if room.is_none_or(|(d, _)| distance < d) {
            room = Some((distance, reason));
        }
    };
    if let Some(l) = limits(rules, axis) {
        consider(if dir > 0 { l.hi - at } else { at - l.lo }, DropReason::TravelLimit);
    }
    for zone in &rules.keep_out {
        let (near, cross) = (zone_span(zone, axis), zone_span(zone, 1 - axis));
        if !cross.meets(&other) || near.contains(at) {
            continue;
        }
        match dir > 0 {
            true if near.lo > at => consider(near.lo - at, DropReason::KeepOut),
            false if near.hi < at => consider(at - near.hi, DropReason::KeepOut),
            _ => {}
        }
    }
    room
}

/// A slew's braking distance at `rate` (per second) and `accel` (per second squared).
pub(crate) fn braking(rate: u32, accel: u32) -> i32 {
    let (v, a) = (u64::from(rate), u64::from(accel.max(1)));
    ((v * v).div_ceil(2 * a)).min(i32::MAX as u64) as i32
}

/// Milliseconds a slew at `rate` takes to cover `distance`.
pub(crate) fn time_for(distance: i32, rate: u32) -> i64 {
    i64::from(distance) * 1000 / i64::from(rate.max(1))
}

/// How far a slew at `rate` runs in `ms`.
pub(crate) fn distance_in(ms: u64, rate: u32) -> i32 {
    (ms.saturating_mul(u64::from(rate)) / 1000).min(i32::MAX as u64) as i32
}

/// When (ms after the position `at` was read) the stop of a slew must be
/// sent so that it reaches the gimbal `latency` later and the gimbal,
/// braking, rests [`GUARD`] short of a boundary `room` away. Negative:
/// already too late to stop short.
pub(crate) fn stop_slack(room: i32, rate: u32, accel: u32, latency: u64) -> i64 {
    time_for(room - braking(rate, accel) - GUARD, rate) - latency as i64
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Angle;

    fn rules() -> GimbalRules {
        let mut r = GimbalRules::new(1, 1);
        r.pan_limits = Some(Span::new(-17000, 17000));
        r.tilt_limits = Some(Span::new(-3000, 9000));
        r.keep_out.push(Zone {
            pan: Span::new(4000, 6000),
            tilt: Span::new(-3000, 1000),
        });
        r
    }

    fn point(p: i32, t: i32) -> Option<Region> {
        Some([Span::at(p), Span::at(t)])
    }

    #[test]
    fn gotos_are_checked_against_limits_then_the_path_rectangle() {
        let r = rules();
        assert_eq!(check_goto(&r, point(0, 0), [17500, 0]), Err(DropReason::TravelLimit));
        assert_eq!(check_goto(&r, point(0, 0), [0, -3100]), Err(DropReason::TravelLimit));
        assert_eq!(check_goto(&r, point(0, 0), [5000, 0]), Err(DropReason::KeepOut));
        // Crossing the zone's pan span below its tilt: the rectangle meets it.
        assert_eq!(check_goto(&r, point(0, 0), [9000, 2000]), Err(DropReason::KeepOut));
        // Above the zone all the way: allowed.
        assert_eq!(check_goto(&r, point(0, 1500), [9000, 2000]), Ok(()));
        assert_eq!(check_goto(&r, None, [9000, 2000]), Err(DropReason::PositionUnknown));
        let mut free = rules();
        free.keep_out.clear();
        assert_eq!(check_goto(&free, None, [9000, 2000]), Ok(()), "limits need no start");
        let _ = Position::new(Angle(0), Angle(0));
    }

    #[test]
    fn the_room_ahead_is_the_nearest_limit_or_zone_edge() {
        let r = rules();
        assert_eq!(room_ahead(&r, 0, 1, 0, Span::at(0)), Some((4000, DropReason::KeepOut)));
        assert_eq!(
            room_ahead(&r, 0, 1, 0, Span::at(2000)),
            Some((17000, DropReason::TravelLimit))
        );
        assert_eq!(
            room_ahead(&r, 0, -1, 0, Span::at(0)),
            Some((17000, DropReason::TravelLimit))
        );
        assert_eq!(
            room_ahead(&r, 1, -1, 5000, Span::at(5000)),
            Some((4000, DropReason::KeepOut))
        );
        assert_eq!(
            room_ahead(&r, 1, -1, 5000, Span::at(0)),
            Some((8000, DropReason::TravelLimit))
        );
        assert_eq!(
            room_ahead(&r, 1, -1, 2000, Span::at(5000)),
            Some((1000, DropReason::KeepOut))
        );
        assert_eq!(room_ahead(&GimbalRules::new(1, 1), 0, 1, 0, Span::at(0)), None);
    }

    #[test]
    fn the_stop_is_planned_from_rate_acceleration_and_latency() {
        // 60 deg/s, 120 deg/s^2: 15 degrees of braking.
        assert_eq!(braking(6000, 12000), 1500);
        // 20 degrees of room: 5 - 0.25 degrees of slack at 60 deg/s is 79 ms, less 30 ms latency.
        assert_eq!(stop_slack(2000, 6000, 12000, 30), 79 - 30);
        assert!(stop_slack(1500, 6000, 12000, 0) < 0);
        assert_eq!(distance_in(500, 6000), 3000);
    }
}
