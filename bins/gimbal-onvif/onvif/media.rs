//! The Media service (ONVIF Media, `trt`, ver10): one fixed profile per
//! gimbal holding its video source configuration, its encoder (with a
//! `stream_uri`) and its PTZ configuration. The request read from the Body
//! ([`Request::parse`]), executed ([`Request::run`]) and rendered
//! ([`Response::render`]).

use super::args::{ENCODER_CONFIG, PROFILE, VIDEO_SOURCE, VIDEO_SOURCE_CONFIG, profile_token};
use super::{Device, faults, ptz};
use crate::config;
use crate::soap::{Element, Fault, esc};

/// A Media service request this device answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    GetServiceCapabilities,
    GetProfiles,
    GetProfile,
    GetStreamUri,
    GetVideoSources,
    /// Refused: the one profile is all there is (Synology asks, and drops
    /// a camera that answers otherwise than with the MaxNVTProfiles fault).
    CreateProfile,
}

/// What a request found, to be rendered.
#[derive(Debug, Clone, PartialEq)]
pub enum Response {
    ServiceCapabilities,
    Profiles(ptz::Settings),
    Profile(ptz::Settings),
    StreamUri(String),
    VideoSources,
}

impl Request {
    /// The operation the Body's element names, its ProfileToken checked.
    pub fn parse(op: &Element) -> Result<Self, Fault> {
        let request = match op.name.as_str() {
            "GetServiceCapabilities" => Self::GetServiceCapabilities,
            "GetProfiles" => Self::GetProfiles,
            "GetProfile" => Self::GetProfile,
            "GetStreamUri" => Self::GetStreamUri,
            "GetVideoSources" => Self::GetVideoSources,
            "CreateProfile" => Self::CreateProfile,
            other => return Err(faults::not_supported(other)),
        };
        if matches!(request, Self::GetProfile | Self::GetStreamUri) {
            profile_token(op)?;
        }
        Ok(request)
    }

    pub fn run(self, device: &Device) -> Result<Response, Fault> {
        let g = &device.gimbal.config;
        Ok(match self {
            Self::GetServiceCapabilities => Response::ServiceCapabilities,
            Self::GetProfiles => Response::Profiles(device.settings()),
            Self::GetProfile => Response::Profile(device.settings()),
            Self::GetStreamUri => Response::StreamUri(g.stream_uri.clone().ok_or_else(|| {
                Fault::receiver(
                    &["ter:ActionNotSupported", "ter:NoStream"],
                    format!(
                        "gimbal {} has no stream_uri configured: it has no camera stream",
                        g.name
                    ),
                )
            })?),
            Self::GetVideoSources => Response::VideoSources,
            // ONVIF Media, CreateProfile: "The maximum number of supported
            // profiles supported by the device has been reached".
            Self::CreateProfile => {
                return Err(Fault::receiver(
                    &["ter:Action", "ter:MaxNVTProfiles"],
                    format!("this device has one fixed profile, {PROFILE:?}"),
                ));
            }
        })
    }
}

impl Response {
    /// The response element (ONVIF media.wsdl).
    pub fn render(&self, g: &config::Gimbal) -> String {
        match self {
            Self::ServiceCapabilities => "<trt:GetServiceCapabilitiesResponse><trt:Capabilities SnapshotUri=\"false\" \
                 Rotation=\"false\"><trt:ProfileCapabilities MaximumNumberOfProfiles=\"1\"/><trt:StreamingCapabilities \
                 RTPMulticast=\"false\" RTP_TCP=\"true\" RTP_RTSP_TCP=\"true\"/></trt:Capabilities>\
                 </trt:GetServiceCapabilitiesResponse>"
                .to_owned(),
            Self::Profiles(settings) => format!(
                "<trt:GetProfilesResponse><trt:Profiles {}</trt:Profiles></trt:GetProfilesResponse>",
                profile(g, settings)
            ),
            Self::Profile(settings) => format!(
                "<trt:GetProfileResponse><trt:Profile {}</trt:Profile></trt:GetProfileResponse>",
                profile(g, settings)
            ),
            Self::StreamUri(uri) => format!(
                "<trt:GetStreamUriResponse><trt:MediaUri><tt:Uri>{}</tt:Uri>\
                 <tt:InvalidAfterConnect>false</tt:InvalidAfterConnect><tt:InvalidAfterReboot>false</tt:InvalidAfterReboot>\
                 <tt:Timeout>PT0S</tt:Timeout></trt:MediaUri></trt:GetStreamUriResponse>",
                esc(uri)
            ),
            Self::VideoSources => format!(
                "<trt:GetVideoSourcesResponse><trt:VideoSources token=\"{VIDEO_SOURCE}\"><tt:Framerate>25</tt:Framerate>\
                 <tt:Resolution><tt:Width>1920</tt:Width><tt:Height>1080</tt:Height></tt:Resolution></trt:VideoSources>\
                 </trt:GetVideoSourcesResponse>"
            ),
        }
    }
}

/// The profile's attributes and content (tt:Profile, in the schema's
/// order): the video source configuration of the one video source, the
/// H264 encoder when the gimbal has a `stream_uri` (its stream is the
/// camera's, nominally 1920x1080; no multicast), the PTZ configuration.
fn profile(g: &config::Gimbal, settings: &ptz::Settings) -> String {
    let encoder = if g.stream_uri.is_some() {
        format!(
            "<tt:VideoEncoderConfiguration token=\"{ENCODER_CONFIG}\"><tt:Name>main</tt:Name><tt:UseCount>1</tt:UseCount>\
             <tt:Encoding>H264</tt:Encoding><tt:Resolution><tt:Width>1920</tt:Width><tt:Height>1080</tt:Height>\
             </tt:Resolution><tt:Quality>5</tt:Quality><tt:Multicast><tt:Address><tt:Type>IPv4</tt:Type>\
             <tt:IPv4Address>0.0.0.0</tt:IPv4Address></tt:Address><tt:Port>0</tt:Port><tt:TTL>0</tt:TTL>\
             <tt:AutoStart>false</tt:AutoStart></tt:Multicast><tt:SessionTimeout>PT60S</tt:SessionTimeout>\
             </tt:VideoEncoderConfiguration>"
        )
    } else {
        String::new()
    };
    format!(
        "token=\"{PROFILE}\" fixed=\"true\"><tt:Name>{}</tt:Name>\
         <tt:VideoSourceConfiguration token=\"{VIDEO_SOURCE_CONFIG}\"><tt:Name>video</tt:Name><tt:UseCount>1</tt:UseCount>\
         <tt:SourceToken>{VIDEO_SOURCE}</tt:SourceToken><tt:Bounds x=\"0\" y=\"0\" width=\"1920\" height=\"1080\"/>\
         </tt:VideoSourceConfiguration>{encoder}{}",
        esc(&g.name),
        ptz::configuration(g, settings, "tt:PTZConfiguration")
    )
}
