//! What each incoming MAVLink message asks, and of which gimbal: the
//! Gimbal Protocol v2 messages and commands become [`Job`]s for the
//! gimbal they address; everything else is counted and ignored.

use mavlink::dialects::common::{COMMAND_LONG_DATA, MavCmd, MavMessage, MavResult};
use mavlink::{MavHeader, Message};
use tracing::{debug, warn};

use crate::frames;
use crate::gimbal::{Handle, Job, Work};
use crate::motion::Request;
use crate::stats::{Stats, may_warn};

/// Where a message goes.
#[derive(Debug)]
pub enum Route {
    /// To gimbal number `usize` (index into the handles).
    Gimbal(usize, Job),
    /// A command for one of our components that no gimbal takes: answer
    /// it with this result.
    Answer(u8, MavCmd, MavResult),
    /// For gimbal number `usize`, but refused for its content (no answer
    /// message exists for it): why.
    Refused(usize, &'static str),
    /// Not for us, or nothing to do.
    Ignore,
}

/// The gimbal addressed by `target_system`/`target_component`, falling
/// back on `device_id` when the message goes to every component.
fn addressed(
    handles: &[Handle],
    system_id: u8,
    target_system: u8,
    target_component: u8,
    device_id: u8,
) -> Option<usize> {
    if target_system != 0 && target_system != system_id {
        return None;
    }
    let by = |c: u8| handles.iter().position(|h| h.config.component_id == c);
    match target_component {
        0 => by(device_id),
        c => by(c),
    }
}

/// Degrees from radians, keeping NaN ("not used").
fn deg(rad: f32) -> f32 {
    if rad.is_nan() { f32::NAN } else { rad.to_degrees() }
}

/// A whole number parameter (a message id, a device id), if it is one.
fn whole(v: f32, max: f32) -> Option<u32> {
    (v.is_finite() && v.fract() == 0.0 && (0.0..=max).contains(&v)).then_some(v as u32)
}

pub fn route(handles: &[Handle], system_id: u8, header: MavHeader, message: &MavMessage) -> Route {
    let from = (header.system_id, header.component_id);
    let job = |work| Job { from, work };
    match message {
        MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(m) => {
            match addressed(
                handles,
                system_id,
                m.target_system,
                m.target_component,
                m.gimbal_device_id,
            ) {
                Some(i) => Route::Gimbal(
                    i,
                    job(Work::Move {
                        request: Request {
                            tilt_deg: deg(m.pitch),
                            pan_deg: deg(m.yaw),
                            tilt_dps: deg(m.pitch_rate),
                            pan_dps: deg(m.yaw_rate),
                        },
                        ack: None,
                    }),
                ),
                None => Route::Ignore,
            }
        }
        MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(m) => {
            let Some(i) = addressed(
                handles,
                system_id,
                m.target_system,
                m.target_component,
                m.gimbal_device_id,
            ) else {
                return Route::Ignore;
            };
            let request = if m.q.iter().all(|v| v.is_nan()) {
                Request {
                    tilt_deg: f32::NAN,
                    pan_deg: f32::NAN,
                    tilt_dps: deg(m.angular_velocity_y),
                    pan_dps: deg(m.angular_velocity_z),
                }
            } else {
                match frames::pitch_yaw(m.q) {
                    Some((pitch, yaw)) => {
                        let (pan, tilt) = frames::pan_tilt_deg(yaw, pitch);
                        Request {
                            tilt_deg: tilt as f32,
                            pan_deg: pan as f32,
                            tilt_dps: f32::NAN,
                            pan_dps: f32::NAN,
                        }
                    }
                    None => return Route::Refused(i, "q is not a rotation quaternion"),
                }
            };
            Route::Gimbal(i, job(Work::Move { request, ack: None }))
        }
        MavMessage::COMMAND_LONG(c) => command(handles, system_id, from, c),
        other => {
            debug!(message = other.message_name(), ?from, "not handled: ignored");
            Route::Ignore
        }
    }
}

fn command(handles: &[Handle], system_id: u8, from: (u8, u8), c: &COMMAND_LONG_DATA) -> Route {
    let job = |work| Job { from, work };
    let device_id = whole(c.param7, 255.0).unwrap_or(0) as u8;
    let target = addressed(handles, system_id, c.target_system, c.target_component, device_id);
    let Some(i) = target else { return Route::Ignore };
    match c.command {
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW => Route::Gimbal(
            i,
            job(Work::Move {
                request: Request {
                    tilt_deg: c.param1,
                    pan_deg: c.param2,
                    tilt_dps: c.param3,
                    pan_dps: c.param4,
                },
                ack: Some(c.command),
            }),
        ),
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => {
            Route::Gimbal(i, job(Work::Configure([c.param1, c.param2, c.param3, c.param4])))
        }
        MavCmd::MAV_CMD_REQUEST_MESSAGE => match whole(c.param1, f32::from(u16::MAX)) {
            Some(id) => Route::Gimbal(i, job(Work::Information(id))),
            None => Route::Answer(handles[i].config.component_id, c.command, MavResult::MAV_RESULT_DENIED),
        },
        other => {
            if may_warn("command not supported", &format_args!("{from:?}")) {
                warn!(command = ?other, ?from, "command not supported");
            }
            Route::Answer(handles[i].config.component_id, other, MavResult::MAV_RESULT_UNSUPPORTED)
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
