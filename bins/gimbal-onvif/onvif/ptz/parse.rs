//! A PTZ request read from the Body's element (ONVIF ptz.wsdl): the
//! operation its local name says, the tokens it names checked against the
//! device's one profile, node and configuration, and its numbers within
//! their spaces' ranges. Nothing here knows the gimbal.

use super::{Continuous, Request, SetConfiguration};
use crate::onvif::args::{NODE, generic, generic_from, preset_number, profile_token, ptz_config_token, timeout};
use crate::onvif::faults;
use crate::onvif::spaces::{POSITION_SPACE, VELOCITY_SPACE, ZOOM_POSITION_SPACE, ZOOM_VELOCITY_SPACE};
use crate::soap::{Element, Fault};

/// The request `op` carries.
pub fn request(op: &Element) -> Result<Request, Fault> {
    let name = op.name.as_str();
    let profile_wide = matches!(
        name,
        "GetCompatibleConfigurations"
            | "GetStatus"
            | "ContinuousMove"
            | "AbsoluteMove"
            | "RelativeMove"
            | "Stop"
            | "GetPresets"
            | "SetPreset"
            | "GotoPreset"
            | "RemovePreset"
            | "GotoHomePosition"
    );
    if profile_wide {
        profile_token(op)?;
    }
    Ok(match name {
        "GetServiceCapabilities" => Request::GetServiceCapabilities,
        "GetNodes" => Request::GetNodes,
        "GetNode" => {
            if op.text_at(&["NodeToken"]) != Some(NODE) {
                return Err(Fault::invalid_arg(
                    "ter:NoEntity",
                    format!("no PTZ node of that token; the node is {NODE:?}"),
                ));
            }
            Request::GetNode
        }
        "GetConfigurations" => Request::GetConfigurations,
        "GetConfiguration" | "GetConfigurationOptions" => {
            let token = op
                .text_at(&["PTZConfigurationToken"])
                .or_else(|| op.text_at(&["ConfigurationToken"]));
            ptz_config_token(token)?;
            if name == "GetConfiguration" {
                Request::GetConfiguration
            } else {
                Request::GetConfigurationOptions
            }
        }
        "GetCompatibleConfigurations" => Request::GetCompatibleConfigurations,
        "SetConfiguration" => Request::SetConfiguration(set_configuration(op)?),
        "GetStatus" => Request::GetStatus,
        "ContinuousMove" => Request::ContinuousMove(continuous(op)?),
        "AbsoluteMove" => absolute(op)?,
        "RelativeMove" => {
            // The node offers no relative zoom space: a zoom translation
            // is refused, never dropped while the pan and tilt move.
            if let Some(z) = op.path(&["Translation", "Zoom"]) {
                if generic(z, "x", "Translation Zoom")?.is_some_and(|x| x != 0.0) {
                    return Err(Fault::invalid_arg(
                        "ter:SpaceNotSupported",
                        "Translation Zoom: this node offers no relative zoom space (GetNode lists its spaces)",
                    ));
                }
            }
            let t = op.path(&["Translation", "PanTilt"]).ok_or_else(|| {
                Fault::invalid_arg("ter:InvalidTranslation", "RelativeMove without a Translation PanTilt")
            })?;
            Request::RelativeMove {
                space: t.attr("space").map(|s| s.trim().to_owned()),
                by: (
                    generic(t, "x", "Translation PanTilt")?.unwrap_or(0.0),
                    generic(t, "y", "Translation PanTilt")?.unwrap_or(0.0),
                ),
            }
        }
        "Stop" => {
            let flag = |name: &str| op.text_at(&[name]).is_none_or(|v| v == "true" || v == "1");
            Request::Stop {
                pan_tilt: flag("PanTilt"),
                zoom: flag("Zoom"),
            }
        }
        "GetPresets" => Request::GetPresets,
        "SetPreset" => Request::SetPreset {
            token: match op.text_at(&["PresetToken"]).filter(|t| !t.is_empty()) {
                Some(t) => Some(preset_number(t)?),
                None => None,
            },
            name: op.text_at(&["PresetName"]).filter(|t| !t.is_empty()).map(str::to_owned),
        },
        "GotoPreset" => Request::GotoPreset(preset_number(op.text_at(&["PresetToken"]).unwrap_or_default())?),
        "RemovePreset" => Request::RemovePreset(preset_number(op.text_at(&["PresetToken"]).unwrap_or_default())?),
        "GotoHomePosition" => Request::GotoHomePosition,
        "SetHomePosition" => Request::SetHomePosition,
        other => return Err(faults::not_supported(other)),
    })
}

fn continuous(op: &Element) -> Result<Continuous, Fault> {
    let (pan, tilt) = match op.path(&["Velocity", "PanTilt"]) {
        Some(v) => (
            generic(v, "x", "Velocity PanTilt")?,
            generic(v, "y", "Velocity PanTilt")?,
        ),
        None => (None, None),
    };
    let zoom = match op.path(&["Velocity", "Zoom"]) {
        Some(z) => generic(z, "x", "Velocity Zoom")?,
        None => None,
    };
    Ok(Continuous {
        pan,
        tilt,
        zoom,
        timeout: timeout(op.text_at(&["Timeout"]), "ter:InvalidTimeout", "Timeout")?,
    })
}

fn absolute(op: &Element) -> Result<Request, Fault> {
    let zoom = match op.path(&["Position", "Zoom"]) {
        Some(z) => generic_from(z, "x", "Position Zoom", 0.0)?,
        None => None,
    };
    let pan_tilt = match op.path(&["Position", "PanTilt"]) {
        Some(t) => match (
            generic(t, "x", "Position PanTilt")?,
            generic(t, "y", "Position PanTilt")?,
        ) {
            (Some(x), Some(y)) => Some((x, y)),
            _ => {
                return Err(Fault::invalid_arg(
                    "ter:InvalidPosition",
                    "Position PanTilt needs both x and y",
                ));
            }
        },
        None => None,
    };
    Ok(Request::AbsoluteMove { pan_tilt, zoom })
}

/// SetConfiguration's PTZConfiguration: its token must be the device's
/// configuration; DefaultRelativePanTiltTranslationSpace and
/// DefaultPTZTimeout may change (checked against the node by the
/// handler); everything else it carries must be what the device has, or
/// the request is refused with `ter:ConfigModify` rather than half done.
fn set_configuration(op: &Element) -> Result<SetConfiguration, Fault> {
    let c = op
        .child("PTZConfiguration")
        .ok_or_else(|| Fault::invalid_arg("ter:ConfigModify", "SetConfiguration without a PTZConfiguration"))?;
    ptz_config_token(c.attr("token"))?;
    let fixed = |path: &[&str], value: &str| match c.text_at(path) {
        Some(v) if v != value => Err(Fault::invalid_arg(
            "ter:ConfigModify",
            format!("{} {v:?} cannot be set: it is {value:?}", path.join("/")),
        )),
        _ => Ok(()),
    };
    fixed(&["NodeToken"], NODE)?;
    fixed(&["DefaultAbsolutePantTiltPositionSpace"], POSITION_SPACE)?;
    fixed(&["DefaultAbsoluteZoomPositionSpace"], ZOOM_POSITION_SPACE)?;
    fixed(&["DefaultContinuousPanTiltVelocitySpace"], VELOCITY_SPACE)?;
    fixed(&["DefaultContinuousZoomVelocitySpace"], ZOOM_VELOCITY_SPACE)?;
    let unit = |path: &[&str], attr: &str, value: f64| match c.path(path).and_then(|e| e.attr(attr)) {
        Some(v) if v.trim().parse::<f64>().ok() != Some(value) => Err(Fault::invalid_arg(
            "ter:ConfigModify",
            format!("{}@{attr} {v:?} cannot be set: it is {value}", path.join("/")),
        )),
        _ => Ok(()),
    };
    unit(&["DefaultPTZSpeed", "PanTilt"], "x", 1.0)?;
    unit(&["DefaultPTZSpeed", "PanTilt"], "y", 1.0)?;
    unit(&["DefaultPTZSpeed", "Zoom"], "x", 1.0)?;
    let range = |path: &[&str], min: f64, max: f64| {
        let number = |p: &[&str]| c.path(path).and_then(|r| r.text_at(p)).map(|v| v.parse::<f64>().ok());
        for (p, want) in [
            (&["XRange", "Min"][..], min),
            (&["XRange", "Max"][..], max),
            (&["YRange", "Min"][..], min),
            (&["YRange", "Max"][..], max),
        ] {
            if let Some(v) = number(p).filter(|v| *v != Some(want)) {
                let found = v.map_or_else(|| "(not a number)".to_owned(), |n| n.to_string());
                return Err(Fault::invalid_arg(
                    "ter:ConfigModify",
                    format!("{}/{} {found} cannot be set: it is {want}", path.join("/"), p.join("/")),
                ));
            }
        }
        Ok(())
    };
    range(&["PanTiltLimits", "Range"], -1.0, 1.0)?;
    range(&["ZoomLimits", "Range"], 0.0, 1.0)?;
    Ok(SetConfiguration {
        name: c.text_at(&["Name"]).map(str::to_owned),
        relative_space: c
            .text_at(&["DefaultRelativePanTiltTranslationSpace"])
            .map(str::to_owned),
        timeout: timeout(
            c.text_at(&["DefaultPTZTimeout"]),
            "ter:ConfigModify",
            "DefaultPTZTimeout",
        )?,
    })
}
