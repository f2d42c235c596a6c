//! The PTZ service (ONVIF PTZ, `tptz`, ver20) of one gimbal: the request
//! read from the Body into a typed [`Request`] (syntax, tokens and ranges
//! checked, nothing sent), executed by [`Request::run`] against the gimbal
//! (what this gimbal offers checked first: its lens, its spaces, its
//! presets), and the typed [`Response`] rendered by module `render`.

mod parse;
mod render;

use std::time::Duration;

use sagebrush_client::presets;
use sagebrush_protocol::Command;
use time::OffsetDateTime;

use super::spaces::{self, Translation};
use super::{Device, faults};
use crate::soap::{self, Fault};

pub use render::configuration;

/// What SetConfiguration may change of the one PTZ configuration, held
/// until the program stops (the configuration file gives the start).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// DefaultPTZTimeout: a ContinuousMove without a Timeout stops after
    /// it (at most `max_move_ms`).
    pub timeout: Duration,
    /// DefaultRelativePanTiltTranslationSpace: a RelativeMove naming no
    /// space is read in it.
    pub relative: Translation,
}

/// A PTZ service request this device answers, its arguments read.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    GetServiceCapabilities,
    GetNodes,
    GetNode,
    GetConfigurations,
    GetConfiguration,
    GetConfigurationOptions,
    GetCompatibleConfigurations,
    SetConfiguration(SetConfiguration),
    GetStatus,
    ContinuousMove(Continuous),
    AbsoluteMove {
        pan_tilt: Option<(f64, f64)>,
        zoom: Option<f64>,
    },
    /// A translation (generic numbers within -1..=1) in the space named,
    /// else in the profile's default space.
    RelativeMove {
        space: Option<String>,
        by: (f64, f64),
    },
    Stop {
        pan_tilt: bool,
        zoom: bool,
    },
    GetPresets,
    SetPreset {
        token: Option<u8>,
        name: Option<String>,
    },
    GotoPreset(u8),
    RemovePreset(u8),
    GotoHomePosition,
    SetHomePosition,
}

/// ContinuousMove's velocities (generic, -1..=1) and Timeout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Continuous {
    pub pan: Option<f64>,
    pub tilt: Option<f64>,
    pub zoom: Option<f64>,
    pub timeout: Option<Duration>,
}

/// What SetConfiguration asks to change; the rest of the configuration it
/// sends must be what the device has (checked by the parser).
#[derive(Debug, Clone, PartialEq)]
pub struct SetConfiguration {
    /// The configuration's name, which is the gimbal's and cannot change.
    pub name: Option<String>,
    pub relative_space: Option<String>,
    pub timeout: Option<Duration>,
}

/// What a request found or did, to be rendered.
#[derive(Debug, Clone)]
pub enum Response {
    ServiceCapabilities,
    Nodes,
    Node,
    Configurations(Settings),
    Configuration(Settings),
    ConfigurationOptions,
    CompatibleConfigurations(Settings),
    Status(sagebrush_client::session::Status, &'static str, OffsetDateTime),
    Presets(Vec<(u8, String)>),
    PresetToken(u8),
    /// An operation whose response is empty: its element name.
    Done(&'static str),
}

impl Request {
    /// The request the Body's element `op` carries (module `parse`).
    pub fn parse(op: &soap::Element) -> Result<Self, Fault> {
        parse::request(op)
    }

    /// Carries the request out on `device`'s gimbal.
    /// `user`: the ONVIF user it is for, whom gcud governs it as
    /// (ARCHITECTURE "Principals").
    pub async fn run(self, device: &Device, now: OffsetDateTime, user: &str) -> Result<Response, Fault> {
        let g = &device.gimbal;
        let name = &g.config.name;
        Ok(match self {
            Self::GetServiceCapabilities => Response::ServiceCapabilities,
            Self::GetNodes => Response::Nodes,
            Self::GetNode => Response::Node,
            Self::GetConfigurations => Response::Configurations(device.settings()),
            Self::GetConfiguration => Response::Configuration(device.settings()),
            Self::GetConfigurationOptions => Response::ConfigurationOptions,
            Self::GetCompatibleConfigurations => Response::CompatibleConfigurations(device.settings()),
            Self::SetConfiguration(set) => {
                set_configuration(device, set)?;
                Response::Done("SetConfigurationResponse")
            }
            Self::GetStatus => {
                // One reading: the MoveStatus and the Error agree.
                let status = g.status();
                let moving = crate::gimbal::Gimbal::move_status(&status);
                Response::Status(status, moving, now)
            }
            Self::ContinuousMove(c) => {
                let zoom = zoom_arg(device, c.zoom)?;
                if c.pan.is_none() && c.tilt.is_none() && zoom.is_none() {
                    return Err(Fault::invalid_arg(
                        "ter:InvalidVelocity",
                        "ContinuousMove without a Velocity PanTilt or Zoom",
                    ));
                }
                // Without a Timeout, the configuration's DefaultPTZTimeout
                // (the session's own maximum, `max_move_ms`, unless set).
                let default = device.settings().timeout;
                let timeout = c.timeout.or((default < g.max_move()).then_some(default));
                g.continuous(c.pan, c.tilt, zoom, timeout, user)
                    .await
                    .map_err(faults::gimbal)?;
                Response::Done("ContinuousMoveResponse")
            }
            Self::AbsoluteMove { pan_tilt, zoom } => {
                let zoom = zoom_arg(device, zoom)?;
                if pan_tilt.is_none() && zoom.is_none() {
                    return Err(Fault::invalid_arg(
                        "ter:InvalidPosition",
                        "AbsoluteMove without a Position PanTilt or Zoom",
                    ));
                }
                if let Some((x, y)) = pan_tilt {
                    let (pan, tilt) = (
                        crate::gimbal::to_degrees(x, g.config.pan_deg),
                        crate::gimbal::to_degrees(y, g.config.tilt_deg),
                    );
                    g.go_to(pan, tilt, user).await.map_err(faults::gimbal)?;
                }
                if let Some(z) = zoom {
                    g.zoom_to(z, user).await.map_err(faults::gimbal)?;
                }
                Response::Done("AbsoluteMoveResponse")
            }
            Self::RelativeMove { space, by } => {
                relative_move(device, space.as_deref(), by, user).await?;
                Response::Done("RelativeMoveResponse")
            }
            Self::Stop { pan_tilt, zoom } => {
                g.stop(pan_tilt, zoom && g.config.zoom).await.map_err(faults::gimbal)?;
                Response::Done("StopResponse")
            }
            Self::GetPresets => Response::Presets(device.presets.list(name)),
            Self::SetPreset { token, name: label } => {
                Response::PresetToken(set_preset(device, token, label, user).await?)
            }
            Self::GotoPreset(n) => {
                g.go_to_preset(named_preset(device, n)?, user)
                    .await
                    .map_err(faults::gimbal)?;
                Response::Done("GotoPresetResponse")
            }
            Self::RemovePreset(n) => {
                device
                    .presets
                    .set(name, named_preset(device, n)?, None)
                    .map_err(faults::state)?;
                Response::Done("RemovePresetResponse")
            }
            Self::GotoHomePosition => {
                g.go_home(user).await.map_err(faults::gimbal)?;
                Response::Done("GotoHomePositionResponse")
            }
            Self::SetHomePosition => {
                return Err(Fault::receiver(
                    &["ter:Action", "ter:CannotOverwriteHome"],
                    "the home position of a Sagebrush gimbal is fixed (HO goes to 0, 0)",
                ));
            }
        })
    }
}

/// SetConfiguration: the default relative space must be one the node
/// offers and the default timeout within GetConfigurationOptions'
/// PTZTimeout (ONVIF PTZ, SetConfiguration: `ter:ConfigModify` when a
/// parameter cannot be set).
fn set_configuration(device: &Device, set: SetConfiguration) -> Result<(), Fault> {
    let g = &device.gimbal.config;
    let mut settings = device.settings();
    if let Some(name) = set.name.filter(|n| *n != g.name) {
        return Err(Fault::invalid_arg(
            "ter:ConfigModify",
            format!("Name {name:?} cannot be set: it is the gimbal's, {:?}", g.name),
        ));
    }
    if let Some(uri) = &set.relative_space {
        settings.relative = Translation::offered(uri, g).ok_or_else(|| {
            Fault::invalid_arg(
                "ter:ConfigModify",
                format!("DefaultRelativePanTiltTranslationSpace {uri:?} is not a space of this node"),
            )
        })?;
    }
    if let Some(t) = set.timeout {
        let max = device.gimbal.max_move();
        if t < render::MIN_TIMEOUT || t > max {
            return Err(Fault::invalid_arg(
                "ter:ConfigModify",
                format!(
                    "DefaultPTZTimeout {} s: expected {} to {} s (GetConfigurationOptions' PTZTimeout)",
                    t.as_secs_f64(),
                    render::MIN_TIMEOUT.as_secs_f64(),
                    max.as_secs_f64()
                ),
            ));
        }
        settings.timeout = t;
    }
    device.set_settings(settings);
    Ok(())
}

/// RelativeMove: in the space named, or the profile's default; one the
/// node does not offer is refused, never read as another. In the FOV space
/// the field of view is the lens's at its zoom now (`V?`) when the tele
/// end is configured.
async fn relative_move(device: &Device, space: Option<&str>, by: (f64, f64), user: &str) -> Result<(), Fault> {
    let g = &device.gimbal;
    let space = match space {
        None => device.settings().relative,
        Some(uri) => Translation::offered(uri, &g.config).ok_or_else(|| {
            Fault::invalid_arg(
                "ter:SpaceNotSupported",
                format!("Translation PanTilt space {uri:?} is not offered by this node (GetNode lists its spaces)"),
            )
        })?,
    };
    let fov = match space {
        Translation::Fov if g.config.fov_tele_deg.is_some() => {
            let zoom = g.lens().await.map_err(faults::gimbal)?.zoom.get();
            spaces::fov_at(&g.config, Some(zoom))
        }
        Translation::Fov => spaces::fov_at(&g.config, None),
        Translation::Generic => None,
    };
    let at = g.position().await.map_err(faults::gimbal)?;
    let from = (f64::from(at.pan.degrees()), f64::from(at.tilt.degrees()));
    let (pan, tilt) = spaces::relative_target(&g.config, space, fov, from, by);
    g.go_to(pan, tilt, user).await.map_err(faults::gimbal)
}

/// A zoom argument: refused unless the gimbal has a lens (a zero
/// velocity, "do not zoom", is taken from any client).
fn zoom_arg(device: &Device, value: Option<f64>) -> Result<Option<f64>, Fault> {
    let g = &device.gimbal.config;
    match value {
        Some(v) if !g.zoom && v != 0.0 => Err(Fault::invalid_arg(
            "ter:NoZoom",
            format!("gimbal {} has no lens configured (zoom = false)", g.name),
        )),
        Some(_) if !g.zoom => Ok(None),
        v => Ok(v),
    }
}

/// The preset `n`, which must have a name.
fn named_preset(device: &Device, n: u8) -> Result<u8, Fault> {
    if !device
        .presets
        .list(&device.gimbal.config.name)
        .iter()
        .any(|(m, _)| *m == n)
    {
        return Err(Fault::invalid_arg(
            "ter:NoToken",
            format!("no preset with token \"{n}\""),
        ));
    }
    Ok(n)
}

/// SetPreset: the preset given, or the first without a name; the name
/// given, or "preset N"; stored on the gimbal (`Snn`), then named.
async fn set_preset(device: &Device, token: Option<u8>, label: Option<String>, user: &str) -> Result<u8, Fault> {
    let name = &device.gimbal.config.name;
    // A number picked here is never one gcud's park or tours recall (`~B`
    // says which); one the client names is its own choice (storing the park
    // preset is how an operator moves the park position).
    let n = match token {
        Some(n) => n,
        None => {
            let reserved = device.gimbal.rules().await.map(|r| r.reserved).unwrap_or_default();
            device.presets.free(name, &reserved).ok_or_else(|| {
                Fault::receiver(
                    &["ter:Action", "ter:TooManyPresets"],
                    "all 256 presets have names or are gcud's",
                )
            })?
        }
    };
    let label = label.unwrap_or_else(|| format!("preset {n}"));
    if label.chars().count() > presets::MAX_NAME {
        return Err(Fault::invalid_arg(
            "ter:InvalidPresetName",
            format!("PresetName longer than {} characters", presets::MAX_NAME),
        ));
    }
    if let Some(bad) = presets::hidden_char(&label).or_else(|| label.chars().find(|&c| !soap::xml_char(c))) {
        return Err(Fault::invalid_arg(
            "ter:InvalidPresetName",
            format!(
                "PresetName holds U+{:04X} (a control or invisible formatting character)",
                u32::from(bad)
            ),
        ));
    }
    if device.presets.list(name).iter().any(|(m, l)| *l == label && *m != n) {
        return Err(Fault::invalid_arg(
            "ter:PresetExist",
            format!("a preset is already named {label:?}"),
        ));
    }
    device
        .gimbal
        .send(&Command::StorePreset(n), user)
        .await
        .map_err(faults::gimbal)?;
    device.presets.set(name, n, Some(&label)).map_err(faults::state)?;
    Ok(n)
}
