//! What each command (COMMAND_LONG or COMMAND_INT, read alike as
//! `inbox::Command`) asks of one gimbal: a job, or the answer it gets here.
//! The legacy commands (gimbal protocol v1, DO_SET_ROI), deprecated in
//! common.xml, are still what MAVProxy and many scripts send.

use mavlink::dialects::common::{MavCmd, MavFrame, MavMessage, MavResult};
use tracing::warn;

use crate::earth::aim::Aim;
use crate::earth::aim::in_mount_frame;
use crate::earth::geometry::Place;
use crate::earth::vehicle::Vehicle;
use crate::routing::control::{Sender, sender_name};
use crate::routing::handle::{Handle, Job, Route, Work};
use crate::routing::motion::Request;
use crate::routing::rates::{self, Rate};
use crate::stats::may_warn;

/// A request that moves nothing (NaN: not used).
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
    /// COMMAND_INT's coordinate frame (None: COMMAND_LONG, which has none).
    pub frame: Option<MavFrame>,
}

/// A [`Command`] of COMMAND_LONG or COMMAND_INT data `$c`, whose fields
/// `$x`, `$y`, `$z` hold params 5, 6 and 7 (common.xml: COMMAND_INT's x, y
/// and z stand where COMMAND_LONG's param5, param6 and param7 do).
macro_rules! command_of {
    ($c:expr, $x:ident, $y:ident, $z:ident, $frame:expr) => {
        Command {
            command: $c.command,
            target_system: $c.target_system,
            target_component: $c.target_component,
            params: [$c.param1, $c.param2, $c.param3, $c.param4],
            x: f64::from($c.$x),
            y: f64::from($c.$y),
            param7: $c.$z,
            frame: $frame,
        }
    };
}

impl Command {
    /// The command `message` carries, if it is COMMAND_LONG or COMMAND_INT.
    pub fn of(message: &MavMessage) -> Option<Self> {
        match message {
            MavMessage::COMMAND_LONG(c) => Some(command_of!(c, param5, param6, param7, None)),
            MavMessage::COMMAND_INT(c) => Some(command_of!(c, x, y, z, Some(c.frame))),
            _ => None,
        }
    }

    /// The gimbal device id the command names (param 7 of the gimbal
    /// manager commands, param 1 of the ROI commands: common.xml); 0, every
    /// gimbal, for the others (param 7 means something else there:
    /// DO_MOUNT_CONTROL's mode, REQUEST_MESSAGE's response target).
    pub fn device_id(&self) -> u8 {
        let id = match self.command {
            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW | MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => self.param7,
            MavCmd::MAV_CMD_DO_SET_ROI_LOCATION | MavCmd::MAV_CMD_DO_SET_ROI_NONE => self.params[0],
            _ => 0.0,
        };
        whole(id, 255.0).unwrap_or(0) as u8
    }
}

/// A whole number parameter (a message id, a device id), if it is one.
pub fn whole(v: f32, max: f32) -> Option<u32> {
    (v.is_finite() && v.fract() == 0.0 && (0.0..=max).contains(&v)).then_some(v as u32)
}

const NOTHING: Request = Request {
    tilt_deg: f32::NAN,
    pan_deg: f32::NAN,
    tilt_dps: f32::NAN,
    pan_dps: f32::NAN,
};

/// Command `c` from `from` for gimbal `i` (`h`).
#[allow(deprecated)]
pub fn route(h: &Handle, i: usize, vehicle: &Vehicle, from: Sender, c: &Command) -> Route {
    let component = h.config.component_id;
    let moves = |request, aim| {
        let work = Work::Move {
            request,
            ack: Some(c.command),
            aim,
        };
        Route::Gimbal(i, Job { from, work })
    };
    let refuse = |kind: &'static str, why: &str| {
        if may_warn(kind, &sender_name(from)) {
            warn!(
                command = mav_cmd_name(c.command),
                from = sender_name(from),
                component,
                "{why}: MAV_RESULT_DENIED"
            );
        }
        Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED)
    };
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
            match in_mount_frame(request, flags, &h.config, vehicle) {
                Ok((request, aim)) => moves(request, aim),
                Err(why) => refuse("yaw in the earth frame refused", why),
            }
        }
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => Route::Gimbal(
            i,
            Job {
                from,
                work: Work::Configure(c.params),
            },
        ),
        // Gimbal protocol v1, still sent by MAVProxy's `gimbal` module and
        // many scripts: param1 pitch, param3 yaw (degrees, yaw relative to
        // the vehicle as PX4 and ArduPilot take it; 180..360 is -180..0 as
        // PX4 reads it), param7 the MAV_MOUNT_MODE.
        MavCmd::MAV_CMD_DO_MOUNT_CONTROL => mount_control(c, moves, refuse),
        // Legacy too: param1 the mode; params 5 to 7 the roll, pitch and yaw
        // input (0 angle body frame, 1 rate, 2 angle absolute frame).
        MavCmd::MAV_CMD_DO_MOUNT_CONFIGURE => match whole(p1, 255.0) {
            Some(1 | 2) if whole(c.param7, 2.0) != Some(2) => {
                Route::Answer(component, c.command, MavResult::MAV_RESULT_ACCEPTED)
            }
            _ => refuse(
                "DO_MOUNT_CONFIGURE refused",
                "only neutral and MAVLink targeting with yaw in the vehicle frame",
            ),
        },
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => match (whole(p1, f32::from(u16::MAX)), Rate::from_interval_us(p2)) {
            (Some(id @ (rates::MANAGER_STATUS_ID | rates::ATTITUDE_STATUS_ID)), Some(rate)) => {
                h.set_rate(id, rate);
                Route::Answer(component, c.command, MavResult::MAV_RESULT_ACCEPTED)
            }
            _ => refuse(
                "SET_MESSAGE_INTERVAL refused",
                "only GIMBAL_MANAGER_STATUS (281) and GIMBAL_DEVICE_ATTITUDE_STATUS (285), at -1 (off), 0 (default) or 20000..=10000000 us",
            ),
        },
        // Ends the aim in force (common.xml: "Cancels any previous ROI
        // command"); the gimbal stays where it points, for the manual input.
        MavCmd::MAV_CMD_DO_SET_ROI_NONE => moves(NOTHING, None),
        MavCmd::MAV_CMD_DO_SET_ROI_LOCATION => {
            let aim = match roi_place(c, vehicle) {
                Ok(place) => Aim::Place(place),
                Err(why) => return refuse("region of interest refused", why),
            };
            match aim.request(&h.config, vehicle) {
                Ok(request) => moves(request, Some(aim)),
                Err(why) => refuse("region of interest refused", why),
            }
        }
        MavCmd::MAV_CMD_DO_SET_ROI | MavCmd::MAV_CMD_DO_SET_ROI_SYSID | MavCmd::MAV_CMD_DO_SET_ROI_WPNEXT_OFFSET => {
            refuse(
                "region of interest refused",
                "only MAV_CMD_DO_SET_ROI_LOCATION and ROI_NONE are carried out",
            )
        }
        MavCmd::MAV_CMD_REQUEST_MESSAGE => match whole(p1, f32::from(u16::MAX)) {
            Some(id) => Route::Gimbal(
                i,
                Job {
                    from,
                    work: Work::Information(id),
                },
            ),
            None => Route::Answer(component, c.command, MavResult::MAV_RESULT_DENIED),
        },
        other => {
            if may_warn("command not supported", &sender_name(from)) {
                warn!(
                    command = mav_cmd_name(other),
                    from = sender_name(from),
                    "command not supported"
                );
            }
            Route::Answer(component, other, MavResult::MAV_RESULT_UNSUPPORTED)
        }
    }
}

/// MAV_CMD_DO_MOUNT_CONTROL (gimbal protocol v1): the motion its
/// MAV_MOUNT_MODE (param 7) asks for through `moves`, or its refusal.
fn mount_control(
    c: &Command,
    moves: impl Fn(Request, Option<Aim>) -> Route,
    refuse: impl Fn(&'static str, &str) -> Route,
) -> Route {
    let [p1, _, p3, _] = c.params;
    match whole(c.param7, 255.0) {
        // MAV_MOUNT_MODE_NEUTRAL: the mount's zero.
        Some(1) => moves(
            Request {
                tilt_deg: 0.0,
                pan_deg: 0.0,
                ..NOTHING
            },
            None,
        ),
        // MAV_MOUNT_MODE_MAVLINK_TARGETING: these angles.
        Some(2) => moves(
            Request {
                tilt_deg: p1,
                pan_deg: if p3 > 180.0 { p3 - 360.0 } else { p3 },
                ..NOTHING
            },
            None,
        ),
        Some(0) => refuse(
            "DO_MOUNT_CONTROL refused",
            "retract: the gimbal has no retracted position",
        ),
        Some(3) => refuse("DO_MOUNT_CONTROL refused", "RC targeting: no RC input here"),
        Some(4..=6) => refuse(
            "DO_MOUNT_CONTROL refused",
            "GPS point, system or home targeting: use MAV_CMD_DO_SET_ROI_LOCATION",
        ),
        _ => refuse("DO_MOUNT_CONTROL refused", "not a MAV_MOUNT_MODE"),
    }
}

/// MAV_CMD_DO_SET_ROI_LOCATION's place (common.xml: param 5 latitude,
/// param 6 longitude, param 7 altitude in metres). As COMMAND_INT, x and y
/// are degrees * 1e7 and the frame says the altitude's datum:
/// MAV_FRAME_GLOBAL (and its superseded _INT twin) above mean sea level,
/// MAV_FRAME_GLOBAL_RELATIVE_ALT (and _INT) above home, known only from
/// the autopilot's GLOBAL_POSITION_INT; other frames are refused. As
/// COMMAND_LONG (no frame) params 5 and 6 are degrees and the altitude is
/// above mean sea level, as PX4's gimbal manager reads it.
#[allow(deprecated)]
fn roi_place(c: &Command, vehicle: &Vehicle) -> Result<Place, &'static str> {
    let (lat_deg, lon_deg) = match c.frame {
        None => (c.x, c.y),
        Some(_) => (c.x / 1e7, c.y / 1e7),
    };
    let above = f64::from(c.param7);
    let alt_m = match c.frame {
        None | Some(MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT) => above,
        Some(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) => {
            let home = vehicle.position().and_then(|p| p.home_alt_m);
            above + home.ok_or("an altitude above home, and home's is not known (no fresh GLOBAL_POSITION_INT)")?
        }
        Some(_) => return Err("a frame other than MAV_FRAME_GLOBAL or MAV_FRAME_GLOBAL_RELATIVE_ALT"),
    };
    let place = Place {
        lat_deg,
        lon_deg,
        alt_m,
    };
    if place.valid() {
        Ok(place)
    } else {
        Err("not a place on earth")
    }
}

/// A command's MAVLink name for a log line (`MAV_CMD_DO_SET_ROI_NONE`): the
/// generated dialect names each variant as the XML does and has no name
/// table, so its unit variant's `Debug` form is that name, never a struct.
fn mav_cmd_name(command: MavCmd) -> String {
    format!("{command:?}")
}
