//! Angles in the earth frame turned into angles relative to the mount, and
//! the direction from the mount to a place (MAV_CMD_DO_SET_ROI_LOCATION).
//!
//! Earth-frame yaw (common.xml GIMBAL_DEVICE_FLAGS_YAW_LOCK: "relative to
//! North (earth frame, x-axis pointing North)") is the mount-relative yaw
//! plus the vehicle's heading (ATTITUDE.yaw, "the aeronautical frame",
//! clockwise from north seen from above, as MAVLink yaw is), so the
//! mount-relative yaw is earth yaw minus heading, wrapped into the gimbal's
//! travel ([`mount_yaw`]).
//!
//! The direction to a place ([`look_at`]) uses a local flat earth at the
//! mount: north and east offsets from the differences of latitude and
//! longitude scaled by the WGS-84 radii of curvature at the mount's
//! latitude (meridian M and prime vertical N), up from the altitudes.
//! Within 10 km its bearing is off by less than 0.01° (the radii change by
//! less than a part in 10^5 across 10 km); the earth's curvature is left
//! out, so the depression angle is too shallow by about d / (2 R) radians:
//! 0.005° at 1 km, 0.045° at 10 km (atmospheric refraction, left out too,
//! takes back about a seventh of it). The mount's base is taken as level:
//! the vehicle's roll and pitch are not compensated (a mast, a ground
//! vehicle on level ground).

/// WGS-84 semi-major axis (m) and first eccentricity squared.
const WGS84_A: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// A place: latitude and longitude in degrees (WGS-84), altitude in metres
/// above mean sea level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

impl Place {
    /// Whether it is a place on earth (finite, latitude within ±90°,
    /// longitude within ±180°).
    pub fn valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.alt_m.is_finite()
            && self.lat_deg.abs() <= 90.0
            && self.lon_deg.abs() <= 180.0
    }
}

/// `deg` wrapped into -180..180.
pub fn wrap180(deg: f64) -> f64 {
    let w = (deg + 180.0).rem_euclid(360.0) - 180.0;
    if w == -180.0 { 180.0 } else { w }
}

/// The mount-relative yaw (degrees) of `earth_yaw_deg` on a vehicle heading
/// `heading_deg`: their difference, wrapped to the one of its turns within
/// the travel `low..=high` (the -180..180 one when none is: the travel
/// check refuses it then).
pub fn mount_yaw(earth_yaw_deg: f64, heading_deg: f64, (low, high): (f64, f64)) -> f64 {
    let yaw = wrap180(earth_yaw_deg - heading_deg);
    [yaw, yaw - 360.0, yaw + 360.0]
        .into_iter()
        .find(|y| (low..=high).contains(y))
        .unwrap_or(yaw)
}

/// The bearing (degrees clockwise from north, -180..180) and the elevation
/// (degrees, positive up) from `mount` to `target` (the module's model).
pub fn look_at(mount: Place, target: Place) -> (f64, f64) {
    let lat = mount.lat_deg.to_radians();
    let s2 = lat.sin().powi(2);
    let w = (1.0 - WGS84_E2 * s2).sqrt();
    let meridian = WGS84_A * (1.0 - WGS84_E2) / (w * w * w);
    let prime_vertical = WGS84_A / w;
    let north = (target.lat_deg - mount.lat_deg).to_radians() * meridian;
    let east = wrap180(target.lon_deg - mount.lon_deg).to_radians() * prime_vertical * lat.cos();
    let up = target.alt_m - mount.alt_m;
    let bearing = east.atan2(north).to_degrees();
    let elevation = up.atan2(north.hypot(east)).to_degrees();
    (bearing, elevation)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn earth_yaw_minus_heading_wrapped_into_the_travel() {
        let full = (-180.0, 180.0);
        assert!(near(mount_yaw(30.0, 90.0, full), -60.0, 1e-9));
        assert!(near(mount_yaw(-170.0, 170.0, full), 20.0, 1e-9), "across north");
        assert!(near(mount_yaw(10.0, 200.0, full), 170.0, 1e-9));
        // A travel of 0..350: -60 is the turn 300.
        assert!(near(mount_yaw(30.0, 90.0, (0.0, 350.0)), 300.0, 1e-9));
        // No turn within -90..90: the -180..180 one, which the travel check refuses.
        assert!(near(mount_yaw(180.0, 0.0, (-90.0, 90.0)), 180.0, 1e-9));
        assert_eq!(wrap180(-180.0), 180.0);
        assert_eq!(wrap180(540.0), 180.0);
    }

    #[test]
    fn look_at_gives_bearing_clockwise_from_north_and_depression_down() {
        let mount = Place {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 500.0,
        };
        // 1 km east (a degree of longitude at 47° is about 76.1 km), 100 m below.
        let east = Place {
            lon_deg: 8.0 + 1000.0 / 76_055.0,
            alt_m: 400.0,
            ..mount
        };
        let (bearing, elevation) = look_at(mount, east);
        assert!(near(bearing, 90.0, 0.01), "{bearing}");
        assert!(
            near(elevation, -(100.0f64 / 1000.0).atan().to_degrees(), 0.05),
            "{elevation}"
        );
        // North-west, level: a bearing of -45 (to the left), elevation 0.
        let (lat_m, lon_m) = (111_180.0, 76_055.0);
        let nw = Place {
            lat_deg: 47.0 + 500.0 / lat_m,
            lon_deg: 8.0 - 500.0 / lon_m,
            ..mount
        };
        let (bearing, elevation) = look_at(mount, nw);
        assert!(
            near(bearing, -45.0, 0.1) && near(elevation, 0.0, 1e-9),
            "{bearing} {elevation}"
        );
        // Straight south, across nothing odd.
        let south = Place {
            lat_deg: 46.99,
            ..mount
        };
        assert!(near(look_at(mount, south).0.abs(), 180.0, 1e-6));
        // Across the antimeridian: 179.99 to -179.99 is east.
        let a = Place {
            lat_deg: 0.0,
            lon_deg: 179.99,
            alt_m: 0.0,
        };
        let b = Place { lon_deg: -179.99, ..a };
        assert!(near(look_at(a, b).0, 90.0, 1e-6));
    }

    #[test]
    fn places_off_the_earth_are_not_valid() {
        let ok = Place {
            lat_deg: 10.0,
            lon_deg: 20.0,
            alt_m: 0.0,
        };
        assert!(ok.valid());
        assert!(!Place { lat_deg: 91.0, ..ok }.valid());
        assert!(
            !Place {
                lon_deg: f64::NAN,
                ..ok
            }
            .valid()
        );
        assert!(
            !Place {
                alt_m: f64::INFINITY,
                ..ok
            }
            .valid()
        );
    }
}
