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
//! backward compatibility) needs the vehicle's heading, which this door
//! does not know: it is refused (DENIED, logged), never carried out as a
//! yaw relative to the mount.

use mavlink::dialects::common::{
    COMMAND_INT_DATA, COMMAND_LONG_DATA, GimbalManagerFlags, MavCmd, MavMessage, MavResult,
};
use mavlink::{MavHeader, Message};
use tracing::{debug, warn};

use crate::frames;
use crate::gimbal::{Handle, Job, Work};
use crate::motion::Request;
use crate::stats::{Stats, may_warn};
use crate::status::{self, Rate};

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

/// A command as COMMAND_LONG or COMMAND_INT carries it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    pub command: MavCmd,
    pub target_system: u8,
    pub target_component: u8,
    /// Params 1 to 4, and param 7 (COMMAND_INT's z).
    pub params: [f32; 4],
    /// Params 5 and 6 (COMMAND_INT's x and y, integers there).
    pub x: f64,
    pub y: f64,
    pub param7: f32,
}

impl Command {
    /// The command `message` carries, if it is COMMAND_LONG or COMMAND_INT.
    pub fn of(message: &MavMessage) -> Option<Self> {
        match message {
            MavMessage::COMMAND_LONG(c) => Some(Self::long(c)),
            MavMessage::COMMAND_INT(c) => Some(Self::int(c)),
            _ => None,
        }
    }

    fn long(c: &COMMAND_LONG_DATA) -> Self {
        Self {
            command: c.command,
            target_system: c.target_system,
            target_component: c.target_component,
            params: [c.param1, c.param2, c.param3, c.param4],
            x: f64::from(c.param5),
            y: f64::from(c.param6),
            param7: c.param7,
        }
    }

    fn int(c: &COMMAND_INT_DATA) -> Self {
        Self {
            command: c.command,
            target_system: c.target_system,
            target_component: c.target_component,
            params: [c.param1, c.param2, c.param3, c.param4],
            x: f64::from(c.x),
            y: f64::from(c.y),
            param7: c.z,
        }
    }

    /// The gimbal device id the command names (param 7 of the gimbal
    /// manager commands); 0, every gimbal, for the others (param 7 means
    /// something else there: DO_MOUNT_CONTROL's mode, REQUEST_MESSAGE's
    /// response target).
    pub fn device_id(&self) -> u8 {
        match self.command {
            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW | MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => {
                whole(self.param7, 255.0).unwrap_or(0) as u8
            }
            _ => 0,
        }
    }
}

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

/// Whether `flags` put yaw in the earth frame (common.xml,
/// GIMBAL_MANAGER_FLAGS: YAW_IN_VEHICLE_FRAME or YAW_IN_EARTH_FRAME say
/// it; with neither, YAW_LOCK means the earth frame).
pub fn yaw_in_earth_frame(flags: u32) -> bool {
    let has = |f: GimbalManagerFlags| flags & f.bits() != 0;
    if has(GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME) {
        false
    } else {
        has(GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME)
            || has(GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_LOCK)
    }
}

/// Why a request with yaw in the earth frame is refused.
pub const EARTH_FRAME: &str = "yaw in the earth frame: the vehicle's heading is not known here";

/// Whether `request` uses its yaw (an angle or a rate).
fn uses_yaw(request: &Request) -> bool {
    !request.pan_deg.is_nan() || !request.pan_dps.is_nan()
}

/// The request of an attitude quaternion `q` (NaN: rates only) with
/// angular velocities about y and z (rad/s), given in a frame `flags` say
/// (GIMBAL_MANAGER_FLAGS and GIMBAL_DEVICE_FLAGS share their bits).
fn attitude_request(q: [f32; 4], rate_y: f32, rate_z: f32, flags: u32) -> Result<Request, &'static str> {
    let request = if q.iter().all(|v| v.is_nan()) {
        Request {
            tilt_deg: f32::NAN,
            pan_deg: f32::NAN,
            tilt_dps: deg(rate_y),
            pan_dps: deg(rate_z),
        }
    } else {
        let (pitch, yaw) = frames::pitch_yaw(q).ok_or("q is not a rotation quaternion")?;
        let (pan, tilt) = frames::pan_tilt_deg(yaw, pitch);
        Request {
            tilt_deg: tilt as f32,
            pan_deg: pan as f32,
            tilt_dps: f32::NAN,
            pan_dps: f32::NAN,
        }
    };
    if yaw_in_earth_frame(flags) && uses_yaw(&request) {
        return Err(EARTH_FRAME);
    }
    Ok(request)
}

/// GIMBAL_MANAGER_SET_MANUAL_CONTROL's unitless values (-1..=1, NaN
/// unused) on `gimbal`: an angle is that fraction of the travel on its
/// side of 0 (1 is the upper limit, -1 the lower), a rate that fraction
/// of `max_rate_dps`.
fn manual_request(
    g: &crate::config::Gimbal,
    pitch: f32,
    yaw: f32,
    pitch_rate: f32,
    yaw_rate: f32,
) -> Result<Request, &'static str> {
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

/// A whole number parameter (a message id, a device id), if it is one.
fn whole(v: f32, max: f32) -> Option<u32> {
    (v.is_finite() && v.fract() == 0.0 && (0.0..=max).contains(&v)).then_some(v as u32)
}

/// The routes of `message`: one per gimbal it addresses (none when it is
/// for none of ours).
pub fn route(handles: &[Handle], system_id: u8, header: MavHeader, message: &MavMessage) -> Vec<Route> {
    let from = (header.system_id, header.component_id);
    let job = |work| Job { from, work };
    let for_each = |targets: Vec<usize>, f: &dyn Fn(usize) -> Route| -> Vec<Route> {
        if targets.is_empty() {
            vec![Route::Ignore]
        } else {
            targets.into_iter().map(f).collect()
        }
    };
    match message {
        MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(m) => {
            let targets = addressed(
                handles,
                system_id,
                m.target_system,
                m.target_component,
                m.gimbal_device_id,
            );
            let request = Request {
                tilt_deg: deg(m.pitch),
                pan_deg: deg(m.yaw),
                tilt_dps: deg(m.pitch_rate),
                pan_dps: deg(m.yaw_rate),
            };
            let earth = yaw_in_earth_frame(m.flags.bits()) && uses_yaw(&request);
            for_each(targets, &|i| {
                if earth {
                    Route::Refused(i, EARTH_FRAME)
                } else {
                    Route::Gimbal(i, job(Work::Move { request, ack: None }))
                }
            })
        }
        MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(m) => {
            let targets = addressed(
                handles,
                system_id,
                m.target_system,
                m.target_component,
                m.gimbal_device_id,
            );
            let request = attitude_request(m.q, m.angular_velocity_y, m.angular_velocity_z, m.flags.bits());
            for_each(targets, &|i| match request {
                Ok(request) => Route::Gimbal(i, job(Work::Move { request, ack: None })),
                Err(why) => Route::Refused(i, why),
            })
        }
        // ArduPilot, as the gimbal manager, drives a gimbal device so.
        MavMessage::GIMBAL_DEVICE_SET_ATTITUDE(m) => {
            let targets = addressed(handles, system_id, m.target_system, m.target_component, 0);
            let request = attitude_request(
                m.q,
                m.angular_velocity_y,
                m.angular_velocity_z,
                u32::from(m.flags.bits()),
            );
            for_each(targets, &|i| match request {
                Ok(request) => Route::Gimbal(i, job(Work::Move { request, ack: None })),
                Err(why) => Route::Refused(i, why),
            })
        }
        MavMessage::GIMBAL_MANAGER_SET_MANUAL_CONTROL(m) => {
            let targets = addressed(
                handles,
                system_id,
                m.target_system,
                m.target_component,
                m.gimbal_device_id,
            );
            for_each(targets, &|i| {
                let request =
                    manual_request(&handles[i].config, m.pitch, m.yaw, m.pitch_rate, m.yaw_rate).and_then(|r| {
                        if yaw_in_earth_frame(m.flags.bits()) && uses_yaw(&r) {
                            Err(EARTH_FRAME)
                        } else {
                            Ok(r)
                        }
                    });
                match request {
                    Ok(request) => Route::Gimbal(i, job(Work::Move { request, ack: None })),
                    Err(why) => Route::Refused(i, why),
                }
            })
        }
        message => match Command::of(message) {
            Some(c) => {
                let targets = addressed(handles, system_id, c.target_system, c.target_component, c.device_id());
                for_each(targets, &|i| command(handles, i, from, &c))
            }
            None => {
                debug!(message = message.message_name(), ?from, "not handled: ignored");
                vec![Route::Ignore]
            }
        },
    }
}

/// Command `c` from `from` for gimbal `i`. The legacy commands (gimbal
/// protocol v1, DO_SET_ROI), deprecated in common.xml, are still what
/// MAVProxy and many scripts send.
#[allow(deprecated)]
fn command(handles: &[Handle], i: usize, from: (u8, u8), c: &Command) -> Route {
    let job = |work| Job { from, work };
    let component = handles[i].config.component_id;
    let [p1, p2, p3, p4] = c.params;
    match c.command {
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW => {
            let request = Request {
                tilt_deg: p1,
                pan_deg: p2,
                tilt_dps: p3,
                pan_dps: p4,
            };
            // Param 5: GIMBAL_MANAGER_FLAGS (COMMAND_INT's x).
            let flags = if c.x.is_finite() && (0.0..=f64::from(u32::MAX)).contains(&c.x) {
                c.x as u32
            } else {
                0
            };
            if yaw_in_earth_frame(flags) && uses_yaw(&request) {
                if may_warn("yaw in the earth frame refused", &format_args!("{from:?}")) {
                    warn!(?from, component, flags, "{EARTH_FRAME}: MAV_RESULT_DENIED");
                }
                return Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED);
            }
            Route::Gimbal(
                i,
                job(Work::Move {
                    request,
                    ack: Some(c.command),
                }),
            )
        }
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => Route::Gimbal(i, job(Work::Configure(c.params))),
        // Gimbal protocol v1, still sent by MAVProxy's `gimbal` module and
        // many scripts: param1 pitch, param3 yaw (degrees, yaw relative to
        // the vehicle as PX4 and ArduPilot take it; 180..360 is -180..0 as
        // PX4 reads it), param7 the MAV_MOUNT_MODE.
        MavCmd::MAV_CMD_DO_MOUNT_CONTROL => {
            let refuse = |why: &str| {
                if may_warn("DO_MOUNT_CONTROL refused", &format_args!("{from:?}")) {
                    warn!(
                        ?from,
                        component,
                        mode = c.param7,
                        "DO_MOUNT_CONTROL: {why}: MAV_RESULT_DENIED"
                    );
                }
                Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED)
            };
            match whole(c.param7, 255.0) {
                // MAV_MOUNT_MODE_NEUTRAL: the mount's zero.
                Some(1) => Route::Gimbal(
                    i,
                    job(Work::Move {
                        request: Request {
                            tilt_deg: 0.0,
                            pan_deg: 0.0,
                            tilt_dps: f32::NAN,
                            pan_dps: f32::NAN,
                        },
                        ack: Some(c.command),
                    }),
                ),
                // MAV_MOUNT_MODE_MAVLINK_TARGETING: these angles.
                Some(2) => {
                    let yaw = if p3 > 180.0 { p3 - 360.0 } else { p3 };
                    Route::Gimbal(
                        i,
                        job(Work::Move {
                            request: Request {
                                tilt_deg: p1,
                                pan_deg: yaw,
                                tilt_dps: f32::NAN,
                                pan_dps: f32::NAN,
                            },
                            ack: Some(c.command),
                        }),
                    )
                }
                Some(0) => refuse("retract: the gimbal has no retracted position"),
                Some(3) => refuse("RC targeting: no RC input here"),
                Some(4..=6) => refuse("GPS point, system or home targeting: no vehicle position here"),
                _ => refuse("not a MAV_MOUNT_MODE"),
            }
        }
        // Legacy too: param1 the mode; params 5 to 7 the roll, pitch and yaw
        // input (0 angle body frame, 1 rate, 2 angle absolute frame).
        MavCmd::MAV_CMD_DO_MOUNT_CONFIGURE => {
            let yaw_absolute = whole(c.param7, 2.0) == Some(2);
            match whole(p1, 255.0) {
                Some(1 | 2) if !yaw_absolute => Route::Answer(component, c.command, MavResult::MAV_RESULT_ACCEPTED),
                _ => {
                    if may_warn("DO_MOUNT_CONFIGURE refused", &format_args!("{from:?}")) {
                        warn!(
                            ?from,
                            component,
                            mode = p1,
                            yaw_input = c.param7,
                            "DO_MOUNT_CONFIGURE: only neutral and MAVLink targeting with yaw in the vehicle frame: MAV_RESULT_DENIED"
                        );
                    }
                    Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED)
                }
            }
        }
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
            let result = match (whole(p1, f32::from(u16::MAX)), Rate::from_interval_us(p2)) {
                (Some(id @ (status::MANAGER_STATUS_ID | status::ATTITUDE_STATUS_ID)), Some(rate)) => {
                    handles[i].set_rate(id, rate);
                    MavResult::MAV_RESULT_ACCEPTED
                }
                _ => {
                    if may_warn("SET_MESSAGE_INTERVAL refused", &format_args!("{from:?}")) {
                        warn!(
                            ?from,
                            component,
                            message_id = p1,
                            interval_us = p2,
                            "SET_MESSAGE_INTERVAL: only GIMBAL_MANAGER_STATUS (281) and GIMBAL_DEVICE_ATTITUDE_STATUS (285), at -1 (off), 0 (default) or 20000..=10000000 us: MAV_RESULT_DENIED"
                        );
                    }
                    MavResult::MAV_RESULT_DENIED
                }
            };
            Route::Answer(component, c.command, result)
        }
        // No region of interest is ever in force (see ROI_LOCATION): none to clear.
        MavCmd::MAV_CMD_DO_SET_ROI_NONE => Route::Answer(component, c.command, MavResult::MAV_RESULT_ACCEPTED),
        MavCmd::MAV_CMD_DO_SET_ROI_LOCATION
        | MavCmd::MAV_CMD_DO_SET_ROI
        | MavCmd::MAV_CMD_DO_SET_ROI_SYSID
        | MavCmd::MAV_CMD_DO_SET_ROI_WPNEXT_OFFSET => {
            if may_warn("region of interest refused", &format_args!("{from:?}")) {
                warn!(command = ?c.command, ?from, component, "region of interest: the mount's position and heading are not known here: MAV_RESULT_DENIED");
            }
            Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED)
        }
        MavCmd::MAV_CMD_REQUEST_MESSAGE => match whole(p1, f32::from(u16::MAX)) {
            Some(id) => Route::Gimbal(i, job(Work::Information(id))),
            None => Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED),
        },
        other => {
            if may_warn("command not supported", &format_args!("{from:?}")) {
                warn!(command = ?other, ?from, "command not supported");
            }
            Route::Answer(component, other, MavResult::MAV_RESULT_UNSUPPORTED)
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
