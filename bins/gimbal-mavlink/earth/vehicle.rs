//! What this door knows of the vehicle or mast its gimbals are on: the
//! heading of each gimbal's pan zero and the mount's place, from the
//! configuration (a mast: `mount_heading_deg`, `mount_latitude_deg`,
//! `mount_longitude_deg`, `mount_altitude_m`, which win when given) or else
//! from the autopilot of this door's own system (component 1,
//! MAV_COMP_ID_AUTOPILOT1, common.xml MAV_COMPONENT):
//!
//! - ATTITUDE (common.xml, id 30): `yaw` (rad, -pi..pi, "the aeronautical
//!   frame": clockwise from north seen from above) is the heading of the
//!   vehicle's nose, and so of the pan's zero; `yawspeed` (rad/s) its rate;
//! - GLOBAL_POSITION_INT (standard.xml, id 33): `lat`, `lon` (degE7),
//!   `alt` (mm above mean sea level) the mount's place, `relative_alt`
//!   (mm above home) gives home's altitude for ROI altitudes above home.
//!
//! A message older than [`STALE`] is not used: autopilots stream both
//! several times a second on their telemetry links, so two seconds without
//! one means the link or the estimate is gone; a request that needs it is
//! then refused (MAV_RESULT_DENIED), never carried out relative to the mount.

use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;

use crate::config::Gimbal;
use crate::earth::geometry::Place;

/// How old an ATTITUDE or GLOBAL_POSITION_INT may be and still be used.
pub const STALE: Duration = Duration::from_secs(2);
/// MAV_COMP_ID_AUTOPILOT1 (common.xml MAV_COMPONENT).
pub const AUTOPILOT: u8 = 1;

/// The heading of a gimbal's pan zero: degrees clockwise from north, and
/// its rate in degrees per second.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heading {
    pub deg: f64,
    pub rate_dps: f64,
}

/// The mount's place, and home's altitude above mean sea level when the
/// autopilot said it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Position {
    pub place: Place,
    pub home_alt_m: Option<f64>,
}

#[derive(Debug, Default)]
struct Heard {
    attitude: Option<(Instant, Heading)>,
    position: Option<(Instant, Position)>,
}

/// The vehicle's heading and place (the module's rules).
#[derive(Debug)]
pub struct Vehicle {
    system_id: u8,
    mount: Option<Place>,
    heard: Mutex<Heard>,
}

impl Vehicle {
    pub fn new(system_id: u8, mount: Option<Place>) -> Self {
        Self {
            system_id,
            mount,
            heard: Mutex::default(),
        }
    }

    fn heard(&self) -> MutexGuard<'_, Heard> {
        self.heard.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Keeps what the autopilot of this system says in `message`.
    pub fn hear(&self, header: MavHeader, message: &MavMessage) {
        if (header.system_id, header.component_id) != (self.system_id, AUTOPILOT) {
            return;
        }
        let now = Instant::now();
        match message {
            MavMessage::ATTITUDE(a) if a.yaw.is_finite() => {
                let rate = if a.yawspeed.is_finite() { a.yawspeed } else { 0.0 };
                let heading = Heading {
                    deg: f64::from(a.yaw).to_degrees(),
                    rate_dps: f64::from(rate).to_degrees(),
                };
                self.heard().attitude = Some((now, heading));
            }
            MavMessage::GLOBAL_POSITION_INT(p) => {
                let place = Place {
                    lat_deg: f64::from(p.lat) / 1e7,
                    lon_deg: f64::from(p.lon) / 1e7,
                    alt_m: f64::from(p.alt) / 1000.0,
                };
                // lat, lon 0 is what an autopilot without a fix sends.
                if place.valid() && (p.lat, p.lon) != (0, 0) {
                    let home_alt_m = Some(f64::from(p.alt - p.relative_alt) / 1000.0);
                    self.heard().position = Some((now, Position { place, home_alt_m }));
                }
            }
            _ => {}
        }
    }

    /// The heading of `g`'s pan zero now, if known.
    pub fn heading(&self, g: &Gimbal) -> Option<Heading> {
        self.heading_at(g, Instant::now())
    }

    fn heading_at(&self, g: &Gimbal, now: Instant) -> Option<Heading> {
        if let Some(deg) = g.mount_heading_deg {
            return Some(Heading { deg, rate_dps: 0.0 });
        }
        let (at, heading) = self.heard().attitude?;
        (now.saturating_duration_since(at) < STALE).then_some(heading)
    }

    /// The mount's place now, if known.
    pub fn position(&self) -> Option<Position> {
        self.position_at(Instant::now())
    }

    fn position_at(&self, now: Instant) -> Option<Position> {
        if let Some(place) = self.mount {
            return Some(Position {
                place,
                home_alt_m: None,
            });
        }
        let (at, position) = self.heard().position?;
        (now.saturating_duration_since(at) < STALE).then_some(position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::{ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA};

    fn gimbal(mount_heading_deg: Option<f64>) -> Gimbal {
        Gimbal::for_tests(mount_heading_deg)
    }

    fn from(system_id: u8, component_id: u8) -> MavHeader {
        MavHeader {
            system_id,
            component_id,
            sequence: 0,
        }
    }

    fn attitude(yaw_deg: f32) -> MavMessage {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            yaw: yaw_deg.to_radians(),
            yawspeed: 0.5f32.to_radians(),
            ..ATTITUDE_DATA::DEFAULT
        })
    }

    #[test]
    fn only_this_systems_autopilot_gives_the_heading_until_it_is_stale() {
        let v = Vehicle::new(1, None);
        let g = gimbal(None);
        assert_eq!(v.heading(&g), None, "nothing heard");
        v.hear(from(2, 1), &attitude(30.0));
        v.hear(from(1, 190), &attitude(30.0));
        assert_eq!(v.heading(&g), None, "another system, a ground station");
        v.hear(from(1, AUTOPILOT), &attitude(-30.0));
        let h = v.heading(&g).expect("heard");
        assert!((h.deg + 30.0).abs() < 1e-4 && (h.rate_dps - 0.5).abs() < 1e-4, "{h:?}");
        assert_eq!(v.heading_at(&g, Instant::now() + STALE), None, "stale");
        // A mast's configured heading wins, and is never stale.
        let mast = gimbal(Some(250.0));
        assert_eq!(
            v.heading_at(&mast, Instant::now() + STALE * 10),
            Some(Heading {
                deg: 250.0,
                rate_dps: 0.0
            })
        );
    }

    #[test]
    fn the_position_comes_from_the_configuration_or_the_autopilot() {
        let v = Vehicle::new(1, None);
        assert_eq!(v.position(), None);
        let no_fix = GLOBAL_POSITION_INT_DATA::DEFAULT;
        v.hear(from(1, AUTOPILOT), &MavMessage::GLOBAL_POSITION_INT(no_fix));
        assert_eq!(v.position(), None, "0, 0: no fix");
        let fix = GLOBAL_POSITION_INT_DATA {
            lat: 471_234_567,
            lon: 81_234_567,
            alt: 520_000,
            relative_alt: 20_000,
            ..GLOBAL_POSITION_INT_DATA::DEFAULT
        };
        v.hear(from(1, AUTOPILOT), &MavMessage::GLOBAL_POSITION_INT(fix));
        let p = v.position().expect("a fix");
        assert!((p.place.lat_deg - 47.123_456_7).abs() < 1e-9 && (p.place.alt_m - 520.0).abs() < 1e-9);
        assert_eq!(p.home_alt_m, Some(500.0));
        assert_eq!(v.position_at(Instant::now() + STALE), None, "stale");
        let mast = Place {
            lat_deg: 1.0,
            lon_deg: 2.0,
            alt_m: 3.0,
        };
        let v = Vehicle::new(1, Some(mast));
        assert_eq!(v.position_at(Instant::now() + STALE).map(|p| p.place), Some(mast));
    }
}
