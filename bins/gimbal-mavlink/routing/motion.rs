//! What a MAVLink pitch/yaw request asks of a Sagebrush gimbal: angles
//! become a goto (`GO`, Table 15), rates a proportional speed and a slew
//! (`SPn`/`STn` and `PR`/`PL`/`TU`/`TD`, Table 11). Requests are checked
//! against the gimbal's travel before anything is sent.
//!
//! Per GIMBAL_MANAGER_SET_PITCHYAW and MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
//! NaN means "not used": an axis with an angle goes there, an axis with
//! only a rate moves at that rate, an axis with neither is left alone.

use sagebrush_protocol::Speed;

use crate::config::Gimbal;

/// A request in Sagebrush terms (degrees and degrees per second; NaN unused):
/// pitch = tilt, yaw = pan (see `frames`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub tilt_deg: f32,
    pub pan_deg: f32,
    pub tilt_dps: f32,
    pub pan_dps: f32,
}

/// What to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Plan {
    /// Nothing asked for.
    Nothing,
    /// `GO` there; an axis with `None` keeps its current angle.
    GoTo { pan: Option<f64>, tilt: Option<f64> },
    /// Rates (degrees per second, 0 stops); `None` leaves an axis as it is.
    Rates { pan: Option<f64>, tilt: Option<f64> },
}

/// Why a request is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Invalid {
    #[error("{axis} {value}° is outside the travel {low}..={high}°")]
    OutOfTravel {
        axis: &'static str,
        value: f64,
        low: f64,
        high: f64,
    },
    #[error("{0} is infinite")]
    Infinite(&'static str),
    #[error("angles and rates mixed: an axis at an angle while the other moves at a rate")]
    Mixed,
}

fn used(what: &'static str, v: f32) -> Result<Option<f64>, Invalid> {
    if v.is_nan() {
        Ok(None)
    } else if v.is_infinite() {
        Err(Invalid::Infinite(what))
    } else {
        Ok(Some(f64::from(v)))
    }
}

/// The plan for `request` on `gimbal`, or why it is refused.
pub fn plan(request: &Request, gimbal: &Gimbal) -> Result<Plan, Invalid> {
    let pan = used("yaw", request.pan_deg)?;
    let tilt = used("pitch", request.tilt_deg)?;
    let pan_rate = used("yaw rate", request.pan_dps)?;
    let tilt_rate = used("pitch rate", request.tilt_dps)?;
    for (axis, value, (low, high)) in [("yaw", pan, gimbal.pan_deg), ("pitch", tilt, gimbal.tilt_deg)] {
        if let Some(value) = value.filter(|v| !(low..=high).contains(v)) {
            return Err(Invalid::OutOfTravel { axis, value, low, high });
        }
    }
    // An axis's angle wins over its rate (a goto runs at the gimbal's rate).
    let pan_rate = pan_rate.filter(|_| pan.is_none());
    let tilt_rate = tilt_rate.filter(|_| tilt.is_none());
    Ok(match (pan.or(tilt), pan_rate.or(tilt_rate)) {
        (None, None) => Plan::Nothing,
        (Some(_), None) => Plan::GoTo { pan, tilt },
        (None, Some(_)) => Plan::Rates {
            pan: pan_rate,
            tilt: tilt_rate,
        },
        (Some(_), Some(_)) => return Err(Invalid::Mixed),
    })
}

/// Proportional speed (Table 11) nearest above `dps` when speed F is
/// `max_dps` and speed n is `max_dps * (n + 1) / 16`; faster is F.
pub fn speed_for(dps: f64, max_dps: f64) -> Speed {
    sagebrush_client::connection::proportional_speed(dps / max_dps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gimbal() -> Gimbal {
        Gimbal {
            tilt_deg: (-90.0, 45.0),
            ..Gimbal::for_tests(None)
        }
    }

    fn req(tilt_deg: f32, pan_deg: f32, tilt_dps: f32, pan_dps: f32) -> Request {
        Request {
            tilt_deg,
            pan_deg,
            tilt_dps,
            pan_dps,
        }
    }

    const N: f32 = f32::NAN;

    #[test]
    fn angles_go_rates_slew_nan_leaves_alone() {
        let g = gimbal();
        assert_eq!(plan(&req(N, N, N, N), &g), Ok(Plan::Nothing));
        assert_eq!(
            plan(&req(10.0, -30.0, N, N), &g),
            Ok(Plan::GoTo {
                pan: Some(-30.0),
                tilt: Some(10.0)
            })
        );
        assert_eq!(
            plan(&req(10.0, N, N, N), &g),
            Ok(Plan::GoTo {
                pan: None,
                tilt: Some(10.0)
            })
        );
        assert_eq!(
            plan(&req(N, N, N, 30.0), &g),
            Ok(Plan::Rates {
                pan: Some(30.0),
                tilt: None
            })
        );
        assert_eq!(
            plan(&req(5.0, N, 7.0, N), &g),
            Ok(Plan::GoTo {
                pan: None,
                tilt: Some(5.0)
            })
        );
        assert_eq!(plan(&req(5.0, N, N, 7.0), &g), Err(Invalid::Mixed));
    }

    #[test]
    fn outside_the_travel_or_infinite_is_refused() {
        let g = gimbal();
        assert!(matches!(
            plan(&req(50.0, N, N, N), &g),
            Err(Invalid::OutOfTravel { axis: "pitch", .. })
        ));
        assert!(matches!(
            plan(&req(N, 181.0, N, N), &g),
            Err(Invalid::OutOfTravel { axis: "yaw", .. })
        ));
        assert_eq!(
            plan(&req(N, N, N, f32::INFINITY), &g),
            Err(Invalid::Infinite("yaw rate"))
        );
    }

    #[test]
    fn speeds_cover_the_range() {
        assert_eq!(speed_for(120.0, 120.0).get(), 15);
        assert_eq!(speed_for(500.0, 120.0).get(), 15);
        assert_eq!(speed_for(-60.0, 120.0).get(), 7);
        assert_eq!(speed_for(0.1, 120.0).get(), 0);
    }
}
