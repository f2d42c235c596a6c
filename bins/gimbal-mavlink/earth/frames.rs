//! How MAVLink's gimbal frame maps onto Sagebrush axes (the one home of
//! that rule; the README's "Ground stations" section says it in words).
//!
//! MAVLink (Gimbal Protocol v2, GIMBAL_DEVICE_ATTITUDE_STATUS and
//! GIMBAL_MANAGER_SET_*): angles in radians, forward-right-down body frame,
//! yaw positive to the right (clockwise seen from above), pitch positive
//! up, attitude as a Hamilton quaternion `[w, x, y, z]` of Z-Y-X Euler
//! angles. Sagebrush (Table 15): pan positive is `PR` (right), tilt
//! positive is `TU` (up), hundredths of a degree. So yaw = pan and
//! pitch = tilt, only the units differ; the gimbal has no roll axis.

/// MAVLink yaw and pitch, radians, from a Sagebrush pan and tilt in degrees.
pub fn yaw_pitch_rad(pan_deg: f64, tilt_deg: f64) -> (f64, f64) {
    (pan_deg.to_radians(), tilt_deg.to_radians())
}

/// Sagebrush pan and tilt, degrees, from MAVLink yaw and pitch in radians.
pub fn pan_tilt_deg(yaw_rad: f64, pitch_rad: f64) -> (f64, f64) {
    (yaw_rad.to_degrees(), pitch_rad.to_degrees())
}

/// The attitude quaternion `[w, x, y, z]` of roll 0, `pitch` and `yaw` (radians).
pub fn quaternion(pitch: f64, yaw: f64) -> [f32; 4] {
    let (sp, cp) = (pitch / 2.0).sin_cos();
    let (sy, cy) = (yaw / 2.0).sin_cos();
    [(cp * cy) as f32, (-sp * sy) as f32, (sp * cy) as f32, (cp * sy) as f32]
}

/// Pitch and yaw (radians) of a quaternion `[w, x, y, z]`; `None` when it
/// is not one (a non-finite part, or far from unit length). Roll is dropped.
pub fn pitch_yaw(q: [f32; 4]) -> Option<(f64, f64)> {
    let [w, x, y, z] = q.map(f64::from);
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if !norm.is_finite() || !(0.9..=1.1).contains(&norm) {
        return None;
    }
    let (w, x, y, z) = (w / norm, x / norm, y / norm, z / norm);
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    Some((pitch, yaw))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn yaw_right_is_pan_right_and_pitch_up_is_tilt_up() {
        let (yaw, pitch) = yaw_pitch_rad(30.0, 10.0);
        assert!(yaw > 0.0 && pitch > 0.0);
        let q = quaternion(pitch, yaw);
        // A yaw to the right alone turns about +z (down): z > 0.
        let right = quaternion(0.0, yaw);
        assert!(right[3] > 0.0 && right[2] == 0.0, "{right:?}");
        // A pitch up alone turns about +y (right wing): y > 0.
        let up = quaternion(pitch, 0.0);
        assert!(up[2] > 0.0 && up[3] == 0.0, "{up:?}");
        let (p, y) = pitch_yaw(q).unwrap();
        let (pan, tilt) = pan_tilt_deg(y, p);
        assert!((pan - 30.0).abs() < 1e-3 && (tilt - 10.0).abs() < 1e-3, "{pan} {tilt}");
    }

    #[test]
    fn not_a_quaternion_is_none() {
        assert_eq!(pitch_yaw([f32::NAN, 0.0, 0.0, 0.0]), None);
        assert_eq!(pitch_yaw([0.0, 0.0, 0.0, 0.0]), None);
        assert_eq!(pitch_yaw([2.0, 0.0, 0.0, 0.0]), None);
    }

    proptest! {
        #[test]
        fn quaternions_round_trip(pitch in -89.0f64..89.0, yaw in -179.0f64..179.0) {
            let q = quaternion(pitch.to_radians(), yaw.to_radians());
            let (p, y) = pitch_yaw(q).unwrap();
            prop_assert!((p.to_degrees() - pitch).abs() < 0.01);
            prop_assert!((y.to_degrees() - yaw).abs() < 0.01);
        }
    }
}
