//! The PTZ responses (ONVIF ptz.wsdl and onvif.xsd, elements in the
//! schema's order) rendered from a typed [`Response`].

use std::time::Duration;

use super::{Response, Settings};
use crate::config;
use crate::gimbal::{ZOOM_MAX, to_generic};
use crate::onvif::args::{NODE, PTZ_CONFIG, utc};
use crate::onvif::spaces::{
    self, POSITION_SPACE, SPEED_SPACE, VELOCITY_SPACE, ZOOM_POSITION_SPACE, ZOOM_SPEED_SPACE, ZOOM_VELOCITY_SPACE,
};
use crate::soap::esc;

/// The shortest Timeout (and DefaultPTZTimeout) offered.
pub const MIN_TIMEOUT: Duration = Duration::from_millis(100);

/// `xml` for a gimbal with a lens, nothing otherwise.
fn zoomed(g: &config::Gimbal, xml: &str) -> String {
    if g.zoom { xml.to_owned() } else { String::new() }
}

/// The one PTZ configuration as the element `element` (`tt:` inside a
/// profile, `tptz:` in the PTZ service's answers).
pub fn configuration(g: &config::Gimbal, settings: &Settings, element: &str) -> String {
    format!(
        "<{element} token=\"{PTZ_CONFIG}\"><tt:Name>{}</tt:Name><tt:UseCount>1</tt:UseCount>\
         <tt:NodeToken>{NODE}</tt:NodeToken>\
         <tt:DefaultAbsolutePantTiltPositionSpace>{POSITION_SPACE}</tt:DefaultAbsolutePantTiltPositionSpace>{}\
         <tt:DefaultRelativePanTiltTranslationSpace>{}</tt:DefaultRelativePanTiltTranslationSpace>\
         <tt:DefaultContinuousPanTiltVelocitySpace>{VELOCITY_SPACE}</tt:DefaultContinuousPanTiltVelocitySpace>{}\
         <tt:DefaultPTZSpeed><tt:PanTilt x=\"1\" y=\"1\" space=\"{SPEED_SPACE}\"/>{}</tt:DefaultPTZSpeed>\
         <tt:DefaultPTZTimeout>PT{}S</tt:DefaultPTZTimeout>\
         <tt:PanTiltLimits><tt:Range><tt:URI>{POSITION_SPACE}</tt:URI><tt:XRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max>\
         </tt:XRange><tt:YRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max></tt:YRange></tt:Range></tt:PanTiltLimits>{}\
         </{element}>",
        esc(&g.name),
        zoomed(
            g,
            &format!(
                "<tt:DefaultAbsoluteZoomPositionSpace>{ZOOM_POSITION_SPACE}</tt:DefaultAbsoluteZoomPositionSpace>"
            )
        ),
        settings.relative.uri(),
        zoomed(
            g,
            &format!(
                "<tt:DefaultContinuousZoomVelocitySpace>{ZOOM_VELOCITY_SPACE}</tt:DefaultContinuousZoomVelocitySpace>"
            )
        ),
        zoomed(g, &format!("<tt:Zoom x=\"1\" space=\"{ZOOM_SPEED_SPACE}\"/>")),
        settings.timeout.as_secs_f64(),
        zoomed(
            g,
            &format!(
                "<tt:ZoomLimits><tt:Range><tt:URI>{ZOOM_POSITION_SPACE}</tt:URI><tt:XRange><tt:Min>0</tt:Min>\
                 <tt:Max>1</tt:Max></tt:XRange></tt:Range></tt:ZoomLimits>"
            )
        )
    )
}

/// The node's attributes and content.
fn node(g: &config::Gimbal) -> String {
    format!(
        "token=\"{NODE}\" FixedHomePosition=\"true\"><tt:Name>{}</tt:Name>\
         <tt:SupportedPTZSpaces>{}</tt:SupportedPTZSpaces><tt:MaximumNumberOfPresets>256</tt:MaximumNumberOfPresets>\
         <tt:HomeSupported>true</tt:HomeSupported>",
        esc(&g.name),
        spaces::xml(g.zoom, g.fov_deg.is_some())
    )
}

fn status(g: &config::Gimbal, s: &sagebrush_client::session::Status, moving: &str, now: &str) -> String {
    let zoom = s
        .lens
        .map(|l| {
            format!(
                "<tt:Zoom x=\"{:.6}\" space=\"{ZOOM_POSITION_SPACE}\"/>",
                f64::from(l.zoom.get()) / ZOOM_MAX
            )
        })
        .unwrap_or_default();
    let position = s
        .position
        .map(|p| {
            format!(
                "<tt:Position><tt:PanTilt x=\"{:.6}\" y=\"{:.6}\" space=\"{POSITION_SPACE}\"/>{zoom}</tt:Position>",
                to_generic(f64::from(p.pan.degrees()), g.pan_deg),
                to_generic(f64::from(p.tilt.degrees()), g.tilt_deg)
            )
        })
        .unwrap_or_default();
    let zoom_moving = zoomed(g, &format!("<tt:Zoom>{moving}</tt:Zoom>"));
    // Why the last poll failed, and who took the gimbal from this door
    // (tt:PTZStatus/Error, one string).
    let taken = s.taken_by.as_ref().map(|c| format!("{c} controls the gimbal"));
    let errors: Vec<&str> = s.error.iter().chain(taken.iter()).map(String::as_str).collect();
    let error = if errors.is_empty() {
        String::new()
    } else {
        format!("<tt:Error>{}</tt:Error>", esc(&errors.join("; ")))
    };
    format!(
        "<tptz:GetStatusResponse><tptz:PTZStatus>{position}<tt:MoveStatus><tt:PanTilt>{moving}</tt:PanTilt>\
         {zoom_moving}</tt:MoveStatus>{error}<tt:UtcTime>{now}</tt:UtcTime></tptz:PTZStatus></tptz:GetStatusResponse>"
    )
}

impl Response {
    /// The response element; `max_move` is the longest Timeout.
    pub fn render(&self, g: &config::Gimbal, max_move: Duration) -> String {
        match self {
            Self::ServiceCapabilities => "<tptz:GetServiceCapabilitiesResponse><tptz:Capabilities EFlip=\"false\" \
                 Reverse=\"false\" GetCompatibleConfigurations=\"true\" MoveStatus=\"true\" StatusPosition=\"true\"/>\
                 </tptz:GetServiceCapabilitiesResponse>"
                .to_owned(),
            Self::Nodes => format!(
                "<tptz:GetNodesResponse><tptz:PTZNode {}</tptz:PTZNode></tptz:GetNodesResponse>",
                node(g)
            ),
            Self::Node => format!(
                "<tptz:GetNodeResponse><tptz:PTZNode {}</tptz:PTZNode></tptz:GetNodeResponse>",
                node(g)
            ),
            Self::Configurations(s) => format!(
                "<tptz:GetConfigurationsResponse>{}</tptz:GetConfigurationsResponse>",
                configuration(g, s, "tptz:PTZConfiguration")
            ),
            Self::Configuration(s) => format!(
                "<tptz:GetConfigurationResponse>{}</tptz:GetConfigurationResponse>",
                configuration(g, s, "tptz:PTZConfiguration")
            ),
            Self::CompatibleConfigurations(s) => format!(
                "<tptz:GetCompatibleConfigurationsResponse>{}</tptz:GetCompatibleConfigurationsResponse>",
                configuration(g, s, "tptz:PTZConfiguration")
            ),
            Self::ConfigurationOptions => format!(
                "<tptz:GetConfigurationOptionsResponse><tptz:PTZConfigurationOptions><tt:Spaces>{}</tt:Spaces>\
                 <tt:PTZTimeout><tt:Min>PT{}S</tt:Min><tt:Max>PT{}S</tt:Max></tt:PTZTimeout>\
                 </tptz:PTZConfigurationOptions></tptz:GetConfigurationOptionsResponse>",
                spaces::xml(g.zoom, g.fov_deg.is_some()),
                MIN_TIMEOUT.as_secs_f64(),
                max_move.as_secs_f64()
            ),
            Self::Status(s, moving, now) => status(g, s, moving, &utc(*now)),
            Self::Presets(list) => {
                let presets: String = list
                    .iter()
                    .map(|(n, label)| {
                        format!(
                            "<tptz:Preset token=\"{n}\"><tt:Name>{}</tt:Name></tptz:Preset>",
                            esc(label)
                        )
                    })
                    .collect();
                format!("<tptz:GetPresetsResponse>{presets}</tptz:GetPresetsResponse>")
            }
            Self::PresetToken(n) => {
                format!("<tptz:SetPresetResponse><tptz:PresetToken>{n}</tptz:PresetToken></tptz:SetPresetResponse>")
            }
            Self::Done(element) => format!("<tptz:{element}/>"),
        }
    }
}
