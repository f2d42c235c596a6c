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

pub(super) fn limits(rules: &GimbalRules, axis: AxisIndex) -> Option<Span> {
    if axis == 0 { rules.pan_limits } else { rules.tilt_limits }
}

fn zone_span(zone: &Zone, axis: AxisIndex) -> Span {
    if axis == 0 { zone.pan } else { zone.tilt }
}

/// A goto from anywhere in `from` (unknown: `None`) to `target`: refused
/// when the target leaves the limits, or when the rectangle spanned by
/// start and target (each axis moves at its own speed) meets a zone,
/// unless the gimbal is inside that zone and the goto only leaves it
/// ([`leaves`]).
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
    let crossed = |z: &&Zone| z.pan.meets(&path[0]) && z.tilt.meets(&path[1]) && !leaves(z, from, target);
    match rules.keep_out.iter().find(crossed) {
        // Where it may be now reaches into the zone but is not all in it
        // (still moving, or braking): whether it is in, and may leave it,
        // is known once it stands still (the governance simulation: a goto
        // accepted as leaving a zone the braking gimbal never entered
        // crossed its corner).
        Some(z) if meets(z, from) && !within(z, from) => Err(DropReason::PositionUnknown),
        Some(_) => Err(DropReason::KeepOut),
        None => Ok(()),
    }
}

/// Whether region `r` reaches into zone `z`.
pub(super) fn meets(z: &Zone, r: Region) -> bool {
    z.pan.meets(&r[0]) && z.tilt.meets(&r[1])
}

/// Whether region `r` lies all within zone `z`.
fn within(z: &Zone, r: Region) -> bool {
    z.pan.contains(r[0].lo) && z.pan.contains(r[0].hi) && z.tilt.contains(r[1].lo) && z.tilt.contains(r[1].hi)
}

/// How deep into `zone` (its distance to the nearest edge) the deepest
/// point of `span` within it lies; negative when they do not meet.
fn deepest(span: Span, zone: Span) -> i32 {
    let (lo, hi) = (span.lo.max(zone.lo), span.hi.min(zone.hi));
    if lo > hi {
        return -1;
    }
    let x = ((zone.lo + zone.hi) / 2).clamp(lo, hi);
    (x - zone.lo).min(zone.hi - x)
}

/// How deep into `zone` the shallowest point of `span` within it lies.
fn shallowest(span: Span, zone: Span) -> i32 {
    let (lo, hi) = (span.lo.max(zone.lo), span.hi.min(zone.hi));
    let depth = |x: i32| (x - zone.lo).min(zone.hi - x);
    depth(lo).min(depth(hi))
}

/// A gimbal left inside `zone` (a reload drew it around it, or it was
/// moved there before gcud knew) may be driven out: a goto from `from`,
/// which meets the zone, to `target` outside it whose path goes nowhere
/// deeper into the zone than the start already is (the depth of a point of
/// a rectangle is the lesser of its axes', so the deepest point of the
/// path is found axis by axis).
fn leaves(zone: &Zone, from: Region, target: [i32; 2]) -> bool {
    let inside = zone.pan.contains(target[0]) && zone.tilt.contains(target[1]);
    if inside || !within(zone, from) {
        return false;
    }
    let path = [from[0].join(&Span::at(target[0])), from[1].join(&Span::at(target[1]))];
    let deepest_on_path = deepest(path[0], zone.pan).min(deepest(path[1], zone.tilt));
    let start = shallowest(from[0], zone.pan).min(shallowest(from[1], zone.tilt));
    deepest_on_path <= start
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
        if !cross.meets(&other) {
            continue;
        }
        if near.contains(at) {
            // Inside it (found so after a restart, or within the margin):
            // out by the nearer edge only, never deeper (the governance
            // simulation: a pan slew from 1.5 degrees inside ran on into it).
            let outward = if at - near.lo <= near.hi - at { -1 } else { 1 };
            if dir != outward {
                consider(0, DropReason::KeepOut);
            }
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

/// A slew's braking distance at top `rate` (per second) and `accel` (per second squared).
pub(crate) fn braking(rate: u32, accel: u32) -> i32 {
    let (v, a) = (u64::from(rate), u64::from(accel.max(1)));
    ((v * v).div_ceil(2 * a)).min(i32::MAX as u64) as i32
}

/// How far a slew at `rate` runs in `ms`.
pub(crate) fn distance_in(ms: u64, rate: u32) -> i32 {
    (ms.saturating_mul(u64::from(rate)) / 1000).min(i32::MAX as u64) as i32
}

/// A slew's motion, in hundredths of a degree and milliseconds: its
/// speed `u` when read (per ms), its top speed `v`, the acceleration `up`
/// it may speed up with and the one `a` it brakes with (per ms squared;
/// apart when the acceleration changed mid-slew: the worst of each). The
/// gimbal accelerates to `v` and brakes at `a`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kinematics {
    pub u: f64,
    pub v: f64,
    pub up: f64,
    pub a: f64,
}

impl Kinematics {
    /// From a rate (per second) and the accelerations it speeds up and
    /// brakes with (per second squared), `elapsed` ms after the slew began
    /// from rest: its speed then is at most `up * elapsed` (what it may have
    /// gained), capped at the rate.
    pub fn of(rate: u32, up: u32, accel: u32, elapsed: u64) -> Self {
        let v = f64::from(rate.max(1)) / 1000.0;
        let up = f64::from(up.max(accel).max(1)) / 1_000_000.0;
        let a = f64::from(accel.max(1)) / 1_000_000.0;
        Self {
            u: (up * elapsed as f64).min(v),
            v,
            up,
            a,
        }
    }

    /// How far it comes to rest from the reading when the stop reaches it `dt` ms later.
    pub fn rest(&self, dt: f64) -> f64 {
        let Self { u, v, up, a } = *self;
        let (run, w) = if u + up * dt <= v {
            (u * dt + 0.5 * up * dt * dt, u + up * dt)
        } else {
            let t1 = (v - u) / up;
            (u * t1 + 0.5 * up * t1 * t1 + v * (dt - t1), v)
        };
        run + w * w / (2.0 * a)
    }

    /// The latest time after the reading (ms) at which a stop may reach
    /// the gimbal for it to rest [`GUARD`] short of a boundary `room`
    /// away; `None` when even a stop at once would not.
    pub fn latest_stop(&self, room: i32) -> Option<f64> {
        let room = f64::from(room - GUARD);
        if self.rest(0.0) > room {
            return None;
        }
        // Monotone in dt: find a time too late by doubling, then bisect.
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..64 {
            if self.rest(hi) > room {
                break;
            }
            (lo, hi) = (hi, hi * 2.0);
        }
        for _ in 0..48 {
            let mid = 0.5 * (lo + hi);
            if self.rest(mid) <= room { lo = mid } else { hi = mid }
        }
        Some(lo)
    }
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

    /// A gimbal inside a zone may leave it by a goto that goes no deeper;
    /// one that crosses more of it, or ends inside, is refused.
    #[test]
    fn a_goto_may_drive_a_gimbal_out_of_a_zone_without_crossing_more_of_it() {
        let r = rules(); // zone pan 40..60, tilt -30..10
        // At (58, 0): two degrees from its pan edge.
        let at = point(5800, 0);
        assert_eq!(check_goto(&r, at, [7000, 0]), Ok(()), "out by the near edge");
        assert_eq!(check_goto(&r, at, [5800, 2000]), Ok(()), "up and out");
        assert_eq!(
            check_goto(&r, at, [3000, 0]),
            Err(DropReason::KeepOut),
            "across the zone"
        );
        assert_eq!(
            check_goto(&r, at, [5000, 0]),
            Err(DropReason::KeepOut),
            "deeper, and inside"
        );
        assert_eq!(
            check_goto(&r, at, [6500, -2900]),
            Ok(()),
            "down the edge and out: no deeper"
        );
        // From outside, any path that meets the zone is refused as before.
        assert_eq!(check_goto(&r, point(7000, 0), [5900, 2000]), Err(DropReason::KeepOut));
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
    fn the_stop_is_planned_from_speed_rate_and_acceleration() {
        // 60 deg/s, 120 deg/s^2: 15 degrees of braking at top speed.
        assert_eq!(braking(6000, 12000), 1500);
        assert_eq!(distance_in(500, 6000), 3000);
        let at_top = Kinematics::of(6000, 12000, 12000, 10_000);
        assert!((at_top.rest(0.0) - 1500.0).abs() < 1e-6);
        // 20 degrees of room: 5 - 0.25 degrees at 60 deg/s take 79 ms.
        let t = at_top.latest_stop(2000).unwrap();
        assert!((t - 79.17).abs() < 0.1, "{t}");
        assert!((at_top.rest(t) - 1975.0).abs() < 0.01);
        assert_eq!(at_top.latest_stop(1500), None, "cannot rest a quarter degree short");
        // From rest, 90 degrees toward a limit at 120 deg/s: accelerate to
        // the middle, then brake; not at top speed all the way.
        let from_rest = Kinematics::of(12000, 12000, 12000, 0);
        let t = from_rest.latest_stop(9000).unwrap();
        assert!((from_rest.rest(t) - 8975.0).abs() < 0.01);
        assert!((t - 864.8).abs() < 0.1, "{t}");
    }
}
