//! What each incoming MAVLink message asks, and of which gimbal: the
//! Gimbal Protocol v2 messages and commands become [`Job`]s for the
//! gimbals they address; everything else is counted and ignored.
//!
//! A command is read the same whether it comes as COMMAND_LONG or as
//! COMMAND_INT (MAVSDK sends DO_GIMBAL_MANAGER_PITCHYAW as COMMAND_INT,
//! ArduPilot its ROI commands): [`Command`] is the one form. A command or
//! message to component 0 (every component), with gimbal device id 0 (or
//! none), goes to every gimbal, and each answers for itself, as PX4's
//! gimbal manager does (`InputMavlinkGimbalV2::_process_command`:
//! "for us or for anyone (component id 0)"); MAVProxy sends there before
//! it has seen the gimbal.
//!
//! Yaw in the earth frame (GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME, or
//! YAW_LOCK without either frame flag, as common.xml defines them for
//! backward compatibility) is turned into a yaw relative to the mount with
//! the heading (`vehicle`: the configured `mount_heading_deg`, or the
//! autopilot's ATTITUDE) and held as an `aim`; a yaw rate has the vehicle's
//! yaw rate taken off. Where the heading is not known it is refused
//! (DENIED, logged), never carried out as a yaw relative to the mount.
//!
//! The commands (COMMAND_LONG, COMMAND_INT) are `command`'s.

use mavlink::dialects::common::{MavMessage, MavResult};
use mavlink::{MavHeader, Message};
use tracing::debug;

use crate::config::Gimbal;
use crate::earth::aim::in_mount_frame;
use crate::earth::frames;
use crate::earth::vehicle::Vehicle;
use crate::routing::command::Command;
use crate::routing::handle::{Handle, Job, Route, Work};
use crate::routing::motion::Request;
use crate::stats::Stats;

/// The gimbals addressed by `target_system`/`target_component`: the one
/// with that component id; for component 0, the one `device_id` names,
/// or every gimbal when it is 0.
pub fn addressed(
    handles: &[Handle],
    system_id: u8,
    target_system: u8,
    target_component: u8,
    device_id: u8,
) -> Vec<usize> {
    if target_system != 0 && target_system != system_id {
        return Vec::new();
    }
    let by = |c: u8| handles.iter().position(|h| h.config.component_id == c);
    match (target_component, device_id) {
        (0, 0) => (0..handles.len()).collect(),
        (0, d) => by(d).into_iter().collect(),
        (c, _) => by(c).into_iter().collect(),
    }
}

/// The request of an attitude quaternion `q` (NaN: rates only) with
/// angular velocities about y and z (rad/s).
fn attitude_request(q: [f32; 4], rate_y: f32, rate_z: f32) -> Result<Request, &'static str> {
    if q.iter().all(|v| v.is_nan()) {
        return Ok(Request {
            tilt_deg: f32::NAN,
            pan_deg: f32::NAN,
            tilt_dps: deg(rate_y),
            pan_dps: deg(rate_z),
        });
    }
    let (pitch, yaw) = frames::pitch_yaw(q).ok_or("q is not a rotation quaternion")?;
    let (pan, tilt) = frames::pan_tilt_deg(yaw, pitch);
    Ok(Request {
        tilt_deg: tilt as f32,
        pan_deg: pan as f32,
        tilt_dps: f32::NAN,
        pan_dps: f32::NAN,
    })
}

/// GIMBAL_MANAGER_SET_MANUAL_CONTROL's unitless values (-1..=1, NaN
/// unused) on `gimbal`: an angle is that fraction of the travel on its
/// side of 0 (1 is the upper limit, -1 the lower), a rate that fraction
/// of `max_rate_dps`.
fn manual_request(g: &Gimbal, [pitch, yaw, pitch_rate, yaw_rate]: [f32; 4]) -> Result<Request, &'static str> {
    if [pitch, yaw, pitch_rate, yaw_rate]
        .iter()
        .any(|v| !v.is_nan() && !(-1.0..=1.0).contains(v))
    {
        return Err("manual control values are outside -1..=1");
    }
    let angle = |v: f32, (low, high): (f64, f64)| {
        let limit = if v >= 0.0 { high.max(0.0) } else { -low.min(0.0) };
        (f64::from(v) * limit) as f32
    };
    let rate = |v: f32| (f64::from(v) * g.max_rate_dps) as f32;
    Ok(Request {
        tilt_deg: angle(pitch, g.tilt_deg),
        pan_deg: angle(yaw, g.pan_deg),
        tilt_dps: rate(pitch_rate),
        pan_dps: rate(yaw_rate),
    })
}

/// Degrees from radians, keeping NaN ("not used").
fn deg(rad: f32) -> f32 {
    if rad.is_nan() { f32::NAN } else { rad.to_degrees() }
}

/// What a pointing message asks of one gimbal.
type Ask<'a> = Box<dyn Fn(&Gimbal) -> Result<Request, &'static str> + 'a>;

/// A pointing message's target (system, component, gimbal device id), its
/// request and its GIMBAL_MANAGER_FLAGS (GIMBAL_DEVICE_FLAGS share their
/// bits); None for any other message.
fn pointing(message: &MavMessage) -> Option<((u8, u8, u8), Ask<'_>, u32)> {
    Some(match message {
        MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(m) => {
            let request = Request {
                tilt_deg: deg(m.pitch),
                pan_deg: deg(m.yaw),
                tilt_dps: deg(m.pitch_rate),
                pan_dps: deg(m.yaw_rate),
            };
            let to = (m.target_system, m.target_component, m.gimbal_device_id);
            (to, Box::new(move |_: &Gimbal| Ok(request)), m.flags.bits())
        }
        MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(m) => {
            let request = attitude_request(m.q, m.angular_velocity_y, m.angular_velocity_z);
            let to = (m.target_system, m.target_component, m.gimbal_device_id);
            (to, Box::new(move |_: &Gimbal| request), m.flags.bits())
        }
        // ArduPilot, as the gimbal manager, drives a gimbal device so.
        MavMessage::GIMBAL_DEVICE_SET_ATTITUDE(m) => {
            let request = attitude_request(m.q, m.angular_velocity_y, m.angular_velocity_z);
            let to = (m.target_system, m.target_component, 0);
            (to, Box::new(move |_: &Gimbal| request), u32::from(m.flags.bits()))
        }
        MavMessage::GIMBAL_MANAGER_SET_MANUAL_CONTROL(m) => {
            let values = [m.pitch, m.yaw, m.pitch_rate, m.yaw_rate];
            let to = (m.target_system, m.target_component, m.gimbal_device_id);
            (
                to,
                Box::new(move |g: &Gimbal| manual_request(g, values)),
                m.flags.bits(),
            )
        }
        _ => return None,
    })
}

/// The gimbals a message for `target_system`/`target_component` with
/// `device_id` goes to, each given its route by `f`; Ignore for none.
fn for_each(handles: &[Handle], system_id: u8, (s, c, d): (u8, u8, u8), f: &dyn Fn(usize) -> Route) -> Vec<Route> {
    let targets = addressed(handles, system_id, s, c, d);
    if targets.is_empty() {
        vec![Route::Ignore]
    } else {
        targets.into_iter().map(f).collect()
    }
}

/// The routes of `message`: one per gimbal it addresses (none when it is
/// for none of ours).
pub fn route(
    handles: &[Handle],
    system_id: u8,
    vehicle: &Vehicle,
    header: MavHeader,
    message: &MavMessage,
) -> Vec<Route> {
    let from = (header.system_id, header.component_id);
    if let Some((to, ask, flags)) = pointing(message) {
        return for_each(handles, system_id, to, &|i| {
            let g = &handles[i].config;
            match ask(g).and_then(|r| in_mount_frame(r, flags, g, vehicle)) {
                Ok((request, aim)) => Route::Gimbal(
                    i,
                    Job {
                        from,
                        work: Work::Move {
                            request,
                            ack: None,
                            aim,
                        },
                    },
                ),
                Err(why) => Route::Refused(i, why),
            }
        });
    }
    match Command::of(message) {
        Some(c) => {
            let to = (c.target_system, c.target_component, c.device_id());
            for_each(handles, system_id, to, &|i| {
                crate::routing::command::route(&handles[i], i, vehicle, from, &c)
            })
        }
        None => {
            debug!(
                message = message.message_name(),
                from = crate::routing::control::sender_name(from),
                "not handled: ignored"
            );
            vec![Route::Ignore]
        }
    }
}

/// Counts what `route` decided not to pass on.
pub fn count(route: &Route, stats: &Stats) {
    match route {
        Route::Ignore => {
            Stats::count(&stats.ignored);
        }
        Route::Answer(_, _, MavResult::MAV_RESULT_DENIED) | Route::Refused(..) => {
            Stats::count(&stats.refused);
        }
        Route::Answer(_, _, MavResult::MAV_RESULT_UNSUPPORTED) => {
            Stats::count(&stats.ignored);
            Stats::count(&stats.unsupported);
        }
        Route::Answer(..) => {
            Stats::count(&stats.ignored);
        }
        Route::Gimbal(..) => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::earth::aim::{self, Aim};
    use mavlink::dialects::common::GimbalManagerFlags;

    fn gimbal(mount_heading_deg: Option<f64>) -> Gimbal {
        Gimbal::for_tests(mount_heading_deg)
    }

    fn yaw(pan_deg: f32, pan_dps: f32) -> Request {
        Request {
            tilt_deg: f32::NAN,
            pan_deg,
            tilt_dps: f32::NAN,
            pan_dps,
        }
    }

    const EARTH: u32 = GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME.bits();
    const LOCK: u32 = GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_LOCK.bits();
    const VEHICLE: u32 = GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME.bits();

    #[test]
    fn earth_frame_yaw_is_yaw_minus_heading_held_as_an_aim_or_refused() {
        let v = Vehicle::new(1, None);
        let mast = gimbal(Some(90.0));
        for flags in [EARTH, LOCK, LOCK | EARTH] {
            let (r, aim) = in_mount_frame(yaw(30.0, f32::NAN), flags, &mast, &v).unwrap();
            assert!((r.pan_deg + 60.0).abs() < 1e-4, "flags {flags}: {r:?}");
            let held = Aim::Yaw {
                earth_deg: 30.0,
                tilt_deg: None,
            };
            assert_eq!(aim, Some(held), "held, so that it is re-aimed as the vehicle turns");
            assert_eq!(
                in_mount_frame(yaw(30.0, f32::NAN), flags, &gimbal(None), &v),
                Err(aim::NO_HEADING),
                "no heading: refused, never mount-relative"
            );
        }
        // The vehicle frame, or no yaw at all: as asked, no heading needed.
        let (r, aim) = in_mount_frame(yaw(30.0, f32::NAN), LOCK | VEHICLE, &gimbal(None), &v).unwrap();
        assert_eq!((r.pan_deg, aim), (30.0, None));
        let pitch_only = Request {
            tilt_deg: 10.0,
            ..yaw(f32::NAN, f32::NAN)
        };
        assert!(in_mount_frame(pitch_only, LOCK, &gimbal(None), &v).is_ok());
        // A rate: the mast does not turn, so the same rate, and no aim.
        let (r, aim) = in_mount_frame(yaw(f32::NAN, 20.0), EARTH, &mast, &v).unwrap();
        assert_eq!((r.pan_dps, aim), (20.0, None));
    }

    #[test]
    fn an_earth_frame_rate_has_the_vehicles_yaw_rate_taken_off() {
        let v = Vehicle::new(1, None);
        let attitude = mavlink::dialects::common::ATTITUDE_DATA {
            yaw: 1.0,
            yawspeed: 5f32.to_radians(),
            ..mavlink::dialects::common::ATTITUDE_DATA::DEFAULT
        };
        let autopilot = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 0,
        };
        v.hear(autopilot, &MavMessage::ATTITUDE(attitude));
        // Turning right at 5 deg/s: 20 deg/s from north is 15 deg/s on the mount.
        let (r, aim) = in_mount_frame(yaw(f32::NAN, 20.0), LOCK, &gimbal(None), &v).unwrap();
        assert!((r.pan_dps - 15.0).abs() < 1e-3 && aim.is_none(), "{r:?}");
    }
}
