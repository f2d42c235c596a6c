//! Reading a request's arguments out of its Body element: the tokens this
//! device has, generic-space numbers, `xs:duration`s and preset tokens,
//! each refused with the ONVIF fault a VMS expects before anything is sent.

use std::time::Duration;

use time::OffsetDateTime;
use time::format_description::well_known::Rfc3339;

use crate::soap::{Element, Fault};

/// The one media profile, PTZ node and PTZ configuration of a device, and
/// its one video source and video source configuration: every token a
/// client reads in one answer is the one the others use (the profile's
/// video source configuration names the video source GetVideoSources
/// lists first).
pub const PROFILE: &str = "profile1";
pub const NODE: &str = "ptznode1";
pub const PTZ_CONFIG: &str = "ptzconfig1";
pub const VIDEO_SOURCE: &str = "videosource1";
pub const VIDEO_SOURCE_CONFIG: &str = "videosourceconfig1";
pub const ENCODER_CONFIG: &str = "encoder1";

/// The request's ProfileToken, which must be [`PROFILE`].
pub fn profile_token(op: &Element) -> Result<(), Fault> {
    match op.text_at(&["ProfileToken"]) {
        Some(PROFILE) => Ok(()),
        Some(other) => Err(Fault::invalid_arg(
            "ter:NoProfile",
            format!("no profile {other:?}: this device has one, {PROFILE:?}"),
        )),
        None => Err(Fault::invalid_arg("ter:NoProfile", "ProfileToken is missing")),
    }
}

/// A PTZ configuration token, which must be [`PTZ_CONFIG`].
pub fn ptz_config_token(token: Option<&str>) -> Result<(), Fault> {
    if token == Some(PTZ_CONFIG) {
        return Ok(());
    }
    Err(Fault::invalid_arg(
        "ter:NoConfig",
        format!("no PTZ configuration of that token; it is {PTZ_CONFIG:?}"),
    ))
}

/// A generic-space coordinate: a number within -1..=1.
pub fn generic(e: &Element, attr: &str, what: &str) -> Result<Option<f64>, Fault> {
    generic_from(e, attr, what, -1.0)
}

/// A generic-space coordinate within `low..=1`.
pub fn generic_from(e: &Element, attr: &str, what: &str, low: f64) -> Result<Option<f64>, Fault> {
    let Some(text) = e.attr(attr) else { return Ok(None) };
    match text.trim().parse::<f64>() {
        Ok(v) if (low..=1.0).contains(&v) => Ok(Some(v)),
        _ => Err(Fault::invalid_arg(
            "ter:InvalidPosition",
            format!("{what} {attr}={text:?}: expected a number within {low}..=1 (generic space)"),
        )),
    }
}

/// An `xs:duration` element's value, refused with `detail` when malformed.
pub fn timeout(text: Option<&str>, detail: &'static str, what: &str) -> Result<Option<Duration>, Fault> {
    text.map(|t| {
        duration(t)
            .ok_or_else(|| Fault::invalid_arg(detail, format!("{what} {t:?}: expected an xs:duration such as PT1.5S")))
    })
    .transpose()
}

/// An `xs:duration` of days, hours, minutes and seconds (`PT1.5S`, `PT1M`).
pub fn duration(text: &str) -> Option<Duration> {
    let rest = text.trim().strip_prefix('P')?;
    let (days, time) = match rest.split_once('T') {
        Some((d, t)) => (d, t),
        None => (rest, ""),
    };
    let mut secs = 0.0f64;
    let days = match days {
        "" => 0.0,
        d => d.strip_suffix('D')?.parse::<f64>().ok()?,
    };
    secs += days * 86_400.0;
    let mut number = String::new();
    for c in time.chars() {
        match c {
            '0'..='9' | '.' => number.push(c),
            'H' | 'M' | 'S' => {
                let v: f64 = number.parse().ok()?;
                number.clear();
                secs += v * match c {
                    'H' => 3600.0,
                    'M' => 60.0,
                    _ => 1.0,
                };
            }
            _ => return None,
        }
    }
    (number.is_empty() && secs.is_finite() && secs >= 0.0 && (days > 0.0 || !time.is_empty()))
        .then(|| Duration::from_secs_f64(secs.min(86_400.0 * 365.0)))
}

/// A preset token: the gimbal's preset number, 0..=255.
pub fn preset_number(token: &str) -> Result<u8, Fault> {
    token.parse::<u8>().map_err(|_| {
        Fault::invalid_arg(
            "ter:NoToken",
            format!("preset token {token:?}: expected a number 0..=255"),
        )
    })
}

/// A time as `xs:dateTime` in UTC, to the second.
pub fn utc(now: OffsetDateTime) -> String {
    now.replace_nanosecond(0)
        .unwrap_or(now)
        .format(&Rfc3339)
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(duration("PT1S"), Some(Duration::from_secs(1)));
        assert_eq!(duration("PT0.5S"), Some(Duration::from_millis(500)));
        assert_eq!(duration("PT1M2S"), Some(Duration::from_secs(62)));
        assert_eq!(duration("P1DT1H"), Some(Duration::from_secs(90_000)));
        for bad in ["", "P", "PT", "1S", "PT1", "PT-1S", "P1Y", "PTxS", "PT1.2.3S"] {
            assert_eq!(duration(bad), None, "{bad}");
        }
    }
}
