//! The PTZ coordinate spaces this device offers (ONVIF PTZ 5.7) and the
//! geometry of a relative move in each: the generic spaces over the
//! configured travel, and the FOV translation space over the camera's
//! field of view ("Pan/tilt Translation Space in FOV").

use crate::config;
use crate::gimbal::{ZOOM_MAX, to_degrees, to_generic};

pub const POSITION_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/PositionGenericSpace";
pub const TRANSLATION_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationGenericSpace";
/// ONVIF PTZ, "Pan/tilt Translation Space in FOV": the image centre is
/// (0, 0), its right and top edges x = 1 and y = 1.
pub const FOV_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationSpaceFov";
pub const VELOCITY_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/VelocityGenericSpace";
pub const SPEED_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/GenericSpeedSpace";
pub const ZOOM_POSITION_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/PositionGenericSpace";
pub const ZOOM_VELOCITY_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/VelocityGenericSpace";
pub const ZOOM_SPEED_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/ZoomGenericSpeedSpace";

/// A relative pan/tilt translation space the node may offer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Translation {
    /// x and y over the whole travel: 2 is from one end to the other.
    Generic,
    /// x = 1 is half the horizontal field of view (the image's right edge).
    Fov,
}

impl Translation {
    pub fn uri(self) -> &'static str {
        match self {
            Self::Generic => TRANSLATION_SPACE,
            Self::Fov => FOV_SPACE,
        }
    }

    /// The space `uri` names, if the gimbal offers it (the FOV space only
    /// with a configured field of view); never another space for it.
    pub fn offered(uri: &str, g: &config::Gimbal) -> Option<Self> {
        match uri.trim() {
            TRANSLATION_SPACE => Some(Self::Generic),
            FOV_SPACE if g.fov_deg.is_some() => Some(Self::Fov),
            _ => None,
        }
    }

    /// The profile's default relative space as configured: the FOV space
    /// when a field of view is configured (Frigate's autotracker needs it
    /// so), else the generic one.
    pub fn default_for(g: &config::Gimbal) -> Self {
        if g.fov_deg.is_some() { Self::Fov } else { Self::Generic }
    }
}

/// The camera's field of view, degrees (horizontal, vertical), with the
/// lens at `zoom` (0..=4095, Table 17): `fov_deg` at the wide end (zoom 0)
/// and, with `fov_tele_deg`, that at the tele end (4095). Between them the
/// focal length is taken as linear in the zoom position, so the tangent of
/// the half angle is the reciprocal of a linear interpolation of those of
/// the ends (exact at both ends).
pub fn fov_at(g: &config::Gimbal, zoom: Option<u16>) -> Option<(f64, f64)> {
    let wide = g.fov_deg?;
    let (Some(tele), Some(zoom)) = (g.fov_tele_deg, zoom) else {
        return Some(wide);
    };
    let z = f64::from(zoom) / ZOOM_MAX;
    let angle = |w: f64, t: f64| {
        let focal = |deg: f64| 1.0 / (deg.to_radians() / 2.0).tan();
        let f = focal(w) + z * (focal(t) - focal(w));
        2.0 * (1.0 / f).atan().to_degrees()
    };
    Some((angle(wide.0, tele.0), angle(wide.1, tele.1)))
}

/// Where a RelativeMove by (`dx`, `dy`) from (`pan`, `tilt`) degrees
/// goes, in degrees within the travel. In the FOV space with field of
/// view `fov`: x = 1 is the image's right edge, half the horizontal field
/// of view from its centre, and the angle is linear in x (no lens
/// projection is modelled: (0.5, 0) is a quarter of the field of view).
/// In the generic space: x and y add to the generic position.
pub fn relative_target(
    g: &config::Gimbal,
    space: Translation,
    fov: Option<(f64, f64)>,
    (pan, tilt): (f64, f64),
    (dx, dy): (f64, f64),
) -> (f64, f64) {
    match (space, fov) {
        (Translation::Fov, Some((h, v))) => (
            (pan + dx * h / 2.0).clamp(g.pan_deg.0, g.pan_deg.1),
            (tilt + dy * v / 2.0).clamp(g.tilt_deg.0, g.tilt_deg.1),
        ),
        _ => {
            let x = to_generic(pan, g.pan_deg) + dx;
            let y = to_generic(tilt, g.tilt_deg) + dy;
            (
                to_degrees(x.clamp(-1.0, 1.0), g.pan_deg),
                to_degrees(y.clamp(-1.0, 1.0), g.tilt_deg),
            )
        }
    }
}

/// The spaces of a node and of its configuration options (ONVIF PTZ
/// 5.7, in the schema's order): pan/tilt position, translation and
/// velocity over [-1, 1], speed over [0, 1]; with `zoom`, zoom position
/// and speed over [0, 1] and velocity over [-1, 1]; with `fov`, the FOV
/// translation space over [-1, 1] beside the generic one.
pub fn xml(zoom: bool, fov: bool) -> String {
    let x = "<tt:XRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max></tt:XRange>";
    let unit = "<tt:XRange><tt:Min>0</tt:Min><tt:Max>1</tt:Max></tt:XRange>";
    let xy = format!("{x}<tt:YRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max></tt:YRange>");
    let space = |element: &str, uri: &str, range: &str, offered: bool| {
        if offered {
            format!("<tt:{element}><tt:URI>{uri}</tt:URI>{range}</tt:{element}>")
        } else {
            String::new()
        }
    };
    [
        space("AbsolutePanTiltPositionSpace", POSITION_SPACE, &xy, true),
        space("AbsoluteZoomPositionSpace", ZOOM_POSITION_SPACE, unit, zoom),
        space("RelativePanTiltTranslationSpace", TRANSLATION_SPACE, &xy, true),
        space("RelativePanTiltTranslationSpace", FOV_SPACE, &xy, fov),
        space("ContinuousPanTiltVelocitySpace", VELOCITY_SPACE, &xy, true),
        space("ContinuousZoomVelocitySpace", ZOOM_VELOCITY_SPACE, x, zoom),
        space("PanTiltSpeedSpace", SPEED_SPACE, unit, true),
        space("ZoomSpeedSpace", ZOOM_SPEED_SPACE, unit, zoom),
    ]
    .concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gimbal(fov: Option<(f64, f64)>, tele: Option<(f64, f64)>) -> config::Gimbal {
        config::Gimbal {
            name: "g".into(),
            address: "5.1.1".parse().unwrap(),
            listen: "127.0.0.1:0".parse().unwrap(),
            stream_uri: None,
            http: sagebrush_service::door_config::HttpSection::default().bounds(),
            https: false,
            pan_deg: (-180.0, 180.0),
            tilt_deg: (-90.0, 90.0),
            zoom: tele.is_some(),
            fov_deg: fov,
            fov_tele_deg: tele,
        }
    }

    #[test]
    fn the_fov_space_turns_by_the_field_of_view_linearly() {
        let g = gimbal(Some((60.0, 40.0)), None);
        let at = |d| relative_target(&g, Translation::Fov, fov_at(&g, None), (10.0, 0.0), d);
        assert_eq!(at((1.0, 0.0)), (40.0, 0.0));
        assert_eq!(at((0.5, 0.0)), (25.0, 0.0));
        assert_eq!(at((-1.0, -1.0)), (-20.0, -20.0));
        assert_eq!(at((0.0, 1.0)), (10.0, 20.0));
        // The generic space over the whole travel: 0.25 of 2 is 90°.
        assert_eq!(
            relative_target(&g, Translation::Generic, None, (0.0, 0.0), (0.5, 0.0)),
            (90.0, 0.0)
        );
        // Clamped to the travel.
        assert_eq!(
            relative_target(&g, Translation::Fov, Some((60.0, 40.0)), (170.0, 85.0), (1.0, 1.0)),
            (180.0, 90.0)
        );
    }

    #[test]
    fn only_offered_spaces_are_read_and_the_fov_is_the_default_when_configured() {
        let with = gimbal(Some((60.0, 40.0)), None);
        let without = gimbal(None, None);
        assert_eq!(Translation::offered(FOV_SPACE, &with), Some(Translation::Fov));
        assert_eq!(Translation::offered(FOV_SPACE, &without), None);
        assert_eq!(
            Translation::offered(TRANSLATION_SPACE, &without),
            Some(Translation::Generic)
        );
        assert_eq!(
            Translation::offered(
                "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationSpaceDegrees",
                &with
            ),
            None
        );
        assert_eq!(Translation::default_for(&with), Translation::Fov);
        assert_eq!(Translation::default_for(&without), Translation::Generic);
    }

    #[test]
    fn the_field_of_view_follows_the_zoom_between_the_configured_ends() {
        let g = gimbal(Some((60.0, 40.0)), Some((6.0, 4.0)));
        let close = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9;
        assert!(close(fov_at(&g, Some(0)).unwrap(), (60.0, 40.0)));
        assert!(close(fov_at(&g, Some(4095)).unwrap(), (6.0, 4.0)));
        let mid = fov_at(&g, Some(2048)).unwrap();
        assert!(mid.0 < 60.0 && mid.0 > 6.0 && mid.1 < 40.0 && mid.1 > 4.0, "{mid:?}");
        // Halfway in focal length is much narrower than halfway in angle.
        assert!(mid.0 < 33.0, "{mid:?}");
        // Without a tele end, or a lens reading, the configured one.
        assert_eq!(
            fov_at(&gimbal(Some((60.0, 40.0)), None), Some(4095)),
            Some((60.0, 40.0))
        );
        assert_eq!(fov_at(&g, None), Some((60.0, 40.0)));
        assert_eq!(fov_at(&gimbal(None, None), Some(0)), None);
    }
}
