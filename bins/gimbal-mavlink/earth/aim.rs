//! Pointing held in the earth frame: a yaw locked relative to north
//! (GIMBAL_MANAGER_FLAGS_YAW_LOCK / YAW_IN_EARTH_FRAME, common.xml) and a
//! region of interest (MAV_CMD_DO_SET_ROI_LOCATION, common.xml: param 5
//! latitude, param 6 longitude, param 7 altitude in metres). Each becomes
//! a mount-relative pan and tilt from the vehicle's heading and place
//! (`vehicle`, `earth`); [`Aim::request`] refuses where either is unknown.
//!
//! The aim in force is the gimbal's (`handle::Shared::aim`): set by the
//! request that asked for it once the gimbal took it, replaced by any other
//! motion, cleared by MAV_CMD_DO_SET_ROI_NONE and by a refused motion of
//! its owner (control lost, the place out of travel). `reaim::run` re-aims it as the
//! vehicle turns or moves: at most every [`REAIM_EVERY`] per gimbal, and only
//! when the pan or tilt changed by [`REAIM_STEP`] or more; when the heading
//! or place is no longer known (older than `vehicle::STALE`) the aim lapses
//! (logged), and the gimbal stays where it points.

use std::time::Duration;

use mavlink::dialects::common::GimbalManagerFlags;

use crate::config::Gimbal;
use crate::earth::geometry::{self, Place};
use crate::earth::vehicle::Vehicle;
use crate::routing::control::Sender;
use crate::routing::motion::Request;

/// How often an aim is recomputed, at most.
pub const REAIM_EVERY: Duration = Duration::from_millis(500);
/// The least change of pan or tilt (degrees) that is sent.
pub const REAIM_STEP: f64 = 0.2;

/// Why an earth-frame request is refused.
pub const NO_HEADING: &str = "the heading is not known (no mount_heading_deg, no fresh ATTITUDE from the autopilot)";
pub const NO_POSITION: &str =
    "the mount's place is not known (no mount_latitude_deg, no fresh GLOBAL_POSITION_INT from the autopilot)";

/// What is held in the earth frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Aim {
    /// A yaw relative to north (degrees), and a tilt (None: left as it is).
    Yaw { earth_deg: f64, tilt_deg: Option<f32> },
    /// A place to look at.
    Place(Place),
}

/// The aim in force on a gimbal, and whose it is (its re-aims are that
/// component's commands, subject to its control).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    pub aim: Aim,
    pub from: Sender,
}

impl std::fmt::Display for Aim {
    /// The aim in words, for a log line.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Aim::Yaw {
                earth_deg,
                tilt_deg: None,
            } => write!(f, "yaw {earth_deg:.2}° from north"),
            Aim::Yaw {
                earth_deg,
                tilt_deg: Some(tilt),
            } => write!(f, "yaw {earth_deg:.2}° from north, tilt {tilt:.2}°"),
            Aim::Place(p) => write!(f, "look at {:.6}°, {:.6}°, {:.1} m", p.lat_deg, p.lon_deg, p.alt_m),
        }
    }
}

impl Aim {
    /// The mount-relative request for this aim on `g` now.
    pub fn request(&self, g: &Gimbal, vehicle: &Vehicle) -> Result<Request, &'static str> {
        let heading = vehicle.heading(g).ok_or(NO_HEADING)?;
        let (earth_deg, tilt_deg) = match *self {
            Aim::Yaw { earth_deg, tilt_deg } => (earth_deg, tilt_deg.unwrap_or(f32::NAN)),
            Aim::Place(place) => {
                let mount = vehicle.position().ok_or(NO_POSITION)?.place;
                let (bearing, elevation) = geometry::look_at(mount, place);
                (bearing, elevation as f32)
            }
        };
        Ok(Request {
            tilt_deg,
            pan_deg: geometry::mount_yaw(earth_deg, heading.deg, g.pan_deg) as f32,
            tilt_dps: f32::NAN,
            pan_dps: f32::NAN,
        })
    }
}

/// Whether `a` and `b` differ by [`REAIM_STEP`] or more on an axis.
pub fn moved(a: &Request, b: &Request) -> bool {
    let differs = |x: f32, y: f32| match (x.is_nan(), y.is_nan()) {
        (true, true) => false,
        (false, false) => f64::from((x - y).abs()) >= REAIM_STEP,
        _ => true,
    };
    differs(a.pan_deg, b.pan_deg) || differs(a.tilt_deg, b.tilt_deg)
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

/// Whether `request` uses its yaw (an angle or a rate).
fn uses_yaw(request: &Request) -> bool {
    !request.pan_deg.is_nan() || !request.pan_dps.is_nan()
}

/// `request` (its yaw in the frame `flags` say) relative to the mount of
/// `g`, and the aim it holds: an earth-frame yaw is the yaw minus the
/// heading, wrapped into the travel (`geometry::mount_yaw`), held as an aim;
/// an earth-frame yaw rate has the vehicle's yaw rate taken off. Refused
/// where the heading is not known.
pub fn in_mount_frame(
    request: Request,
    flags: u32,
    g: &Gimbal,
    vehicle: &Vehicle,
) -> Result<(Request, Option<Aim>), &'static str> {
    if !yaw_in_earth_frame(flags) || !uses_yaw(&request) {
        return Ok((request, None));
    }
    let heading = vehicle.heading(g).ok_or(NO_HEADING)?;
    if request.pan_deg.is_nan() {
        let pan_dps = f64::from(request.pan_dps) - heading.rate_dps;
        return Ok((
            Request {
                pan_dps: pan_dps as f32,
                ..request
            },
            None,
        ));
    }
    let held = Aim::Yaw {
        earth_deg: f64::from(request.pan_deg),
        tilt_deg: (!request.tilt_deg.is_nan()).then_some(request.tilt_deg),
    };
    let pan_deg = geometry::mount_yaw(f64::from(request.pan_deg), heading.deg, g.pan_deg) as f32;
    Ok((Request { pan_deg, ..request }, Some(held)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gimbal(mount_heading_deg: Option<f64>) -> Gimbal {
        Gimbal::for_tests(mount_heading_deg)
    }

    #[test]
    fn an_aim_needs_the_heading_and_for_a_place_the_position() {
        let yaw = Aim::Yaw {
            earth_deg: 100.0,
            tilt_deg: Some(-5.0),
        };
        let v = Vehicle::new(1, None);
        assert_eq!(yaw.request(&gimbal(None), &v), Err(NO_HEADING));
        let r = yaw.request(&gimbal(Some(60.0)), &v).unwrap();
        assert!((r.pan_deg - 40.0).abs() < 1e-4 && r.tilt_deg == -5.0, "{r:?}");
        let place = Aim::Place(Place {
            lat_deg: 47.0,
            lon_deg: 8.01,
            alt_m: 400.0,
        });
        assert_eq!(place.request(&gimbal(Some(0.0)), &v), Err(NO_POSITION));
        let mast = Vehicle::new(
            1,
            Some(Place {
                lat_deg: 47.0,
                lon_deg: 8.0,
                alt_m: 500.0,
            }),
        );
        // Due east of a mast whose pan zero faces north-east: pan 45 right, tilt down.
        let r = place.request(&gimbal(Some(45.0)), &mast).unwrap();
        assert!(
            (r.pan_deg - 45.0).abs() < 0.01 && r.tilt_deg < -7.0 && r.tilt_deg > -8.0,
            "{r:?}"
        );
    }

    #[test]
    fn only_a_change_of_a_step_or_more_is_a_re_aim() {
        let at = |pan: f32, tilt: f32| Request {
            tilt_deg: tilt,
            pan_deg: pan,
            tilt_dps: f32::NAN,
            pan_dps: f32::NAN,
        };
        assert!(!moved(&at(10.0, 0.0), &at(10.1, 0.1)));
        assert!(moved(&at(10.0, 0.0), &at(10.3, 0.0)));
        assert!(moved(&at(10.0, f32::NAN), &at(10.0, 0.0)));
        assert!(!moved(&at(10.0, f32::NAN), &at(10.0, f32::NAN)));
    }
}
