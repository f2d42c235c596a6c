//! The ONVIF operations of one gimbal's device (Device ver10, Media ver10,
//! PTZ ver20): each request read from its envelope, checked (credentials,
//! role, tokens, ranges) before anything is sent to the gimbal, and
//! answered with a response or a SOAP fault.

use std::sync::Arc;
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_protocol::{Command, Undelivered};
use sha1::{Digest, Sha1};
use time::OffsetDateTime;
use time::format_description::well_known::Rfc3339;

use crate::auth::{Authenticator, require};
use crate::config::Role;
use crate::gimbal::{Gimbal, ZOOM_MAX, to_degrees, to_generic};
use crate::soap::{self, Element, Fault, NS_DEVICE, NS_MEDIA, NS_PTZ, esc};
use sagebrush_client::presets::{self, Presets};

pub const PROFILE: &str = "profile1";
pub const NODE: &str = "ptznode1";
pub const PTZ_CONFIG: &str = "ptzconfig1";
const VIDEO_SOURCE: &str = "videosource1";

const POSITION_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/PositionGenericSpace";
const TRANSLATION_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationGenericSpace";
/// ONVIF PTZ, "Pan/tilt Translation Space in FOV": the image centre is
/// (0, 0), its right and top edges x = 1 and y = 1.
const FOV_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationSpaceFov";
const VELOCITY_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/VelocityGenericSpace";
const SPEED_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/GenericSpeedSpace";
const ZOOM_POSITION_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/PositionGenericSpace";
const ZOOM_VELOCITY_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/VelocityGenericSpace";
const ZOOM_SPEED_SPACE: &str = "http://www.onvif.org/ver10/tptz/ZoomSpaces/ZoomGenericSpeedSpace";

/// Where a request came in: what the answer may say about it.
#[derive(Debug, Clone, Copy)]
pub struct Origin<'a> {
    /// The host (and port) the client reached, for the service addresses:
    /// its Host header when that is a well-formed host, else the address
    /// the connection was accepted on (module `http` decides).
    pub host: &'a str,
    /// The local address the connection was accepted on.
    pub local: std::net::IpAddr,
    /// The request's target (path and query), which an HTTP Digest answer
    /// must have been computed over.
    pub uri: &'a str,
    /// The HTTP Authorization header (Digest), if any.
    pub authorization: Option<&'a str>,
}

/// Everything one gimbal's ONVIF device answers with.
#[derive(Debug, Clone)]
pub struct Device {
    pub gimbal: Arc<Gimbal>,
    pub auth: Arc<Authenticator>,
    pub presets: Arc<Presets>,
}

/// The PTZ spaces of a node and of its configuration options (ONVIF PTZ
/// 5.7, generic spaces only, in the schema's order): pan/tilt position,
/// translation and velocity over [-1, 1], speed over [0, 1]; with `zoom`,
/// zoom position and speed over [0, 1] and velocity over [-1, 1]; with
/// `fov`, the FOV translation space over [-1, 1] beside the generic one.
fn spaces(zoom: bool, fov: bool) -> String {
    let x = "<tt:XRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max></tt:XRange>";
    let unit = "<tt:XRange><tt:Min>0</tt:Min><tt:Max>1</tt:Max></tt:XRange>";
    let xy = format!("{x}<tt:YRange><tt:Min>-1</tt:Min><tt:Max>1</tt:Max></tt:YRange>");
    let zoomed = |element: &str, uri: &str, range: &str| {
        if zoom {
            format!("<tt:{element}><tt:URI>{uri}</tt:URI>{range}</tt:{element}>")
        } else {
            String::new()
        }
    };
    format!(
        "<tt:AbsolutePanTiltPositionSpace><tt:URI>{POSITION_SPACE}</tt:URI>{xy}</tt:AbsolutePanTiltPositionSpace>{}\
         <tt:RelativePanTiltTranslationSpace><tt:URI>{TRANSLATION_SPACE}</tt:URI>{xy}</tt:RelativePanTiltTranslationSpace>{}\
         <tt:ContinuousPanTiltVelocitySpace><tt:URI>{VELOCITY_SPACE}</tt:URI>{xy}</tt:ContinuousPanTiltVelocitySpace>{}\
         <tt:PanTiltSpeedSpace><tt:URI>{SPEED_SPACE}</tt:URI>{unit}</tt:PanTiltSpeedSpace>{}",
        zoomed("AbsoluteZoomPositionSpace", ZOOM_POSITION_SPACE, unit),
        if fov {
            format!(
                "<tt:RelativePanTiltTranslationSpace><tt:URI>{FOV_SPACE}</tt:URI>{xy}</tt:RelativePanTiltTranslationSpace>"
            )
        } else {
            String::new()
        },
        zoomed("ContinuousZoomVelocitySpace", ZOOM_VELOCITY_SPACE, x),
        zoomed("ZoomSpeedSpace", ZOOM_SPEED_SPACE, unit),
    )
}

/// A failure of the gimbal as a fault naming the reason (never a success).
fn gimbal_fault(e: CommandError) -> Fault {
    let sub = match e {
        CommandError::Refused(rule, reason) => return refusal_fault(rule, reason),
        CommandError::Io(_) => "ter:GcudUnreachable",
        CommandError::Undelivered(..) => "ter:NotDelivered",
        CommandError::Nic(_) => "ter:NotSupportedByGimbal",
        CommandError::Usage(_) => return Fault::invalid_arg("ter:OutOfRange", e.to_string()),
        _ => "ter:GimbalFailed",
    };
    Fault::receiver(&["ter:Action", sub], e.to_string())
}

/// A command gcud refused by its rules (ARCHITECTURE "Front doors"), as
/// the fault a VMS expects, with gcud's reason (the holder named):
/// - another link controls the gimbal: `env:Receiver ter:Action
///   ter:NotInControl` (ONVIF Core's generic "Action Failed"; the device
///   cannot act now, the request itself was sound);
/// - beyond a travel limit: `env:Sender ter:InvalidArgVal
///   ter:InvalidPosition` (PTZ: "the requested position is out of bounds");
/// - into a keep-out zone: `env:Sender ter:InvalidArgVal
///   ter:UnreachablePosition` (PTZ: "the requested position is not
///   reachable");
/// - the gimbal's position unknown to gcud while it has limits or zones:
///   `env:Receiver ter:Action ter:PositionUnknown`.
fn refusal_fault(rule: Undelivered, reason: String) -> Fault {
    match rule {
        Undelivered::TravelLimit => Fault::sender(&["ter:InvalidArgVal", "ter:InvalidPosition"], reason),
        Undelivered::KeepOut => Fault::sender(&["ter:InvalidArgVal", "ter:UnreachablePosition"], reason),
        Undelivered::PositionUnknown => Fault::receiver(&["ter:Action", "ter:PositionUnknown"], reason),
        _ => Fault::receiver(&["ter:Action", "ter:NotInControl"], reason),
    }
}

/// A generic-space coordinate: a number within -1..=1.
fn generic(e: &Element, attr: &str, what: &str) -> Result<Option<f64>, Fault> {
    generic_from(e, attr, what, -1.0)
}

/// A generic-space coordinate within `low..=1`.
fn generic_from(e: &Element, attr: &str, what: &str, low: f64) -> Result<Option<f64>, Fault> {
    let Some(text) = e.attr(attr) else { return Ok(None) };
    match text.trim().parse::<f64>() {
        Ok(v) if (low..=1.0).contains(&v) => Ok(Some(v)),
        _ => Err(Fault::invalid_arg(
            "ter:InvalidPosition",
            format!("{what} {attr}={text:?}: expected a number within {low}..=1 (generic space)"),
        )),
    }
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

fn utc(now: OffsetDateTime) -> String {
    now.replace_nanosecond(0)
        .unwrap_or(now)
        .format(&Rfc3339)
        .unwrap_or_default()
}

impl Device {
    /// Answers one request body that came in at `origin`: the response
    /// envelope, or a fault with its HTTP status.
    pub async fn handle(&self, body: &[u8], origin: &Origin<'_>) -> Result<String, Fault> {
        let request = soap::request(body).map_err(|reason| {
            Fault::sender(
                &["ter:WellFormed"],
                format!("the request is not a SOAP envelope: {reason}"),
            )
        })?;
        let op = &request.operation;
        let now = OffsetDateTime::now_utc();
        if op.name == "GetSystemDateAndTime" && op.ns == NS_DEVICE {
            return Ok(soap::envelope(&self.system_date_and_time(now)));
        }
        let known = [NS_DEVICE, NS_MEDIA, NS_PTZ].contains(&op.ns.as_str());
        if !known {
            return Err(Fault::receiver(
                &["ter:ActionNotSupported"],
                format!("{{{}}}{} is not an operation of this device", op.ns, op.name),
            ));
        }
        let user = self
            .auth
            .authenticate(request.header.as_ref(), origin.authorization, "POST", origin.uri, now)?;
        let needed = needed_role(&op.name);
        require(&user, needed, &op.name)?;
        let body = match op.ns.as_str() {
            NS_DEVICE => self.device(op, origin).await?,
            NS_MEDIA => self.media(op)?,
            _ => self.ptz(op, now).await?,
        };
        Ok(soap::envelope(&body))
    }

    fn system_date_and_time(&self, now: OffsetDateTime) -> String {
        format!(
            "<tds:GetSystemDateAndTimeResponse><tds:SystemDateAndTime><tt:DateTimeType>NTP</tt:DateTimeType>\
             <tt:DaylightSavings>false</tt:DaylightSavings><tt:TimeZone><tt:TZ>UTC0</tt:TZ></tt:TimeZone>\
             <tt:UTCDateTime><tt:Time><tt:Hour>{}</tt:Hour><tt:Minute>{}</tt:Minute><tt:Second>{}</tt:Second></tt:Time>\
             <tt:Date><tt:Year>{}</tt:Year><tt:Month>{}</tt:Month><tt:Day>{}</tt:Day></tt:Date></tt:UTCDateTime>\
             </tds:SystemDateAndTime></tds:GetSystemDateAndTimeResponse>",
            now.hour(),
            now.minute(),
            now.second(),
            now.year(),
            u8::from(now.month()),
            now.day()
        )
    }

    /// A locally administered MAC address of its own for this gimbal's
    /// device (clients such as Home Assistant key devices on it).
    fn hw_address(&self) -> String {
        let g = &self.gimbal.config;
        let digest = Sha1::digest(format!("{} {}", g.name, g.address).as_bytes());
        let mut mac = [0u8; 6];
        mac.copy_from_slice(&digest[..6]);
        mac[0] = (mac[0] | 0x02) & 0xFE;
        mac.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(":")
    }

    async fn device(&self, op: &Element, origin: &Origin<'_>) -> Result<String, Fault> {
        let g = &self.gimbal.config;
        let url = |service: &str| esc(&format!("http://{}/onvif/{service}", origin.host)).into_owned();
        Ok(match op.name.as_str() {
            "GetServiceCapabilities" => "<tds:GetServiceCapabilitiesResponse><tds:Capabilities>\
                 <tds:Network IPFilter=\"false\" ZeroConfiguration=\"false\" IPVersion6=\"false\" DynDNS=\"false\"/>\
                 <tds:Security UsernameToken=\"true\" HttpDigest=\"true\"/>\
                 <tds:System DiscoveryResolve=\"false\" DiscoveryBye=\"true\" RemoteDiscovery=\"false\" SystemBackup=\"false\" \
                 SystemLogging=\"false\" FirmwareUpgrade=\"false\"/></tds:Capabilities></tds:GetServiceCapabilitiesResponse>"
                .to_owned(),
            "GetDeviceInformation" => {
                let id = self.gimbal.identity().await.map_err(gimbal_fault)?;
                let revision = id.revision.chars().map(String::from).collect::<Vec<_>>().join(".");
                format!(
                    "<tds:GetDeviceInformationResponse><tds:Manufacturer>Sagebrush</tds:Manufacturer>\
                     <tds:Model>{}</tds:Model><tds:FirmwareVersion>{}</tds:FirmwareVersion>\
                     <tds:SerialNumber>{}</tds:SerialNumber><tds:HardwareId>{}</tds:HardwareId>\
                     </tds:GetDeviceInformationResponse>",
                    esc(&id.name),
                    esc(&revision),
                    esc(&id.serial),
                    g.address
                )
            }
            "GetCapabilities" => format!(
                "<tds:GetCapabilitiesResponse><tds:Capabilities>\
                 <tt:Device><tt:XAddr>{}</tt:XAddr><tt:System><tt:DiscoveryResolve>false</tt:DiscoveryResolve>\
                 <tt:DiscoveryBye>true</tt:DiscoveryBye><tt:RemoteDiscovery>false</tt:RemoteDiscovery>\
                 <tt:SystemBackup>false</tt:SystemBackup><tt:SystemLogging>false</tt:SystemLogging>\
                 <tt:FirmwareUpgrade>false</tt:FirmwareUpgrade><tt:SupportedVersions><tt:Major>2</tt:Major>\
                 <tt:Minor>0</tt:Minor></tt:SupportedVersions></tt:System></tt:Device>\
                 <tt:Media><tt:XAddr>{}</tt:XAddr><tt:StreamingCapabilities><tt:RTPMulticast>false</tt:RTPMulticast>\
                 <tt:RTP_TCP>true</tt:RTP_TCP><tt:RTP_RTSP_TCP>true</tt:RTP_RTSP_TCP></tt:StreamingCapabilities></tt:Media>\
                 <tt:PTZ><tt:XAddr>{}</tt:XAddr></tt:PTZ></tds:Capabilities></tds:GetCapabilitiesResponse>",
                url("device_service"),
                url("media_service"),
                url("ptz_service")
            ),
            "GetServices" => {
                let service = |ns: &str, path: &str, major: u8| {
                    format!(
                        "<tds:Service><tds:Namespace>{ns}</tds:Namespace><tds:XAddr>{}</tds:XAddr>\
                         <tds:Version><tt:Major>{major}</tt:Major><tt:Minor>0</tt:Minor></tds:Version></tds:Service>",
                        url(path)
                    )
                };
                format!(
                    "<tds:GetServicesResponse>{}{}{}</tds:GetServicesResponse>",
                    service(NS_DEVICE, "device_service", 2),
                    service(NS_MEDIA, "media_service", 2),
                    service(NS_PTZ, "ptz_service", 2)
                )
            }
            "GetScopes" => {
                let items: String = scopes(g)
                    .iter()
                    .map(|s| {
                        format!(
                            "<tds:Scopes><tt:ScopeDef>Fixed</tt:ScopeDef><tt:ScopeItem>{}</tt:ScopeItem></tds:Scopes>",
                            esc(s)
                        )
                    })
                    .collect();
                format!("<tds:GetScopesResponse>{items}</tds:GetScopesResponse>")
            }
            "GetHostname" => format!(
                "<tds:GetHostnameResponse><tds:HostnameInformation><tt:FromDHCP>false</tt:FromDHCP>\
                 <tt:Name>{}</tt:Name></tds:HostnameInformation></tds:GetHostnameResponse>",
                esc(&g.name)
            ),
            "GetNetworkInterfaces" => {
                let ip = origin.local.to_string();
                format!(
                    "<tds:GetNetworkInterfacesResponse><tds:NetworkInterfaces token=\"eth0\"><tt:Enabled>true</tt:Enabled>\
                     <tt:Info><tt:Name>eth0</tt:Name><tt:HwAddress>{}</tt:HwAddress><tt:MTU>1500</tt:MTU></tt:Info>\
                     <tt:IPv4><tt:Enabled>true</tt:Enabled><tt:Config><tt:Manual><tt:Address>{}</tt:Address>\
                     <tt:PrefixLength>24</tt:PrefixLength></tt:Manual><tt:DHCP>false</tt:DHCP></tt:Config></tt:IPv4>\
                     </tds:NetworkInterfaces></tds:GetNetworkInterfacesResponse>",
                    self.hw_address(),
                    esc(&ip)
                )
            }
            other => return Err(not_supported(other)),
        })
    }

    fn profile_token(&self, op: &Element) -> Result<(), Fault> {
        match op.text_at(&["ProfileToken"]) {
            Some(PROFILE) => Ok(()),
            Some(other) => Err(Fault::invalid_arg(
                "ter:NoProfile",
                format!("no profile {other:?}: this device has one, {PROFILE:?}"),
            )),
            None => Err(Fault::invalid_arg("ter:NoProfile", "ProfileToken is missing")),
        }
    }

    fn video_configurations(&self) -> String {
        if self.gimbal.config.stream_uri.is_none() {
            return String::new();
        }
        format!(
            "<tt:VideoSourceConfiguration token=\"videosourceconfig1\"><tt:Name>video</tt:Name><tt:UseCount>1</tt:UseCount>\
             <tt:SourceToken>{VIDEO_SOURCE}</tt:SourceToken><tt:Bounds x=\"0\" y=\"0\" width=\"1920\" height=\"1080\"/>\
             </tt:VideoSourceConfiguration>\
             <tt:VideoEncoderConfiguration token=\"encoder1\"><tt:Name>main</tt:Name><tt:UseCount>1</tt:UseCount>\
             <tt:Encoding>H264</tt:Encoding><tt:Resolution><tt:Width>1920</tt:Width><tt:Height>1080</tt:Height>\
             </tt:Resolution><tt:Quality>5</tt:Quality><tt:SessionTimeout>PT60S</tt:SessionTimeout>\
             </tt:VideoEncoderConfiguration>"
        )
    }

    /// The profile's default relative pan/tilt space: the FOV space when a
    /// field of view is configured (Frigate's autotracker needs it so).
    fn relative_space(&self) -> &'static str {
        if self.gimbal.config.fov_deg.is_some() {
            FOV_SPACE
        } else {
            TRANSLATION_SPACE
        }
    }

    fn ptz_configuration(&self, element: &str) -> String {
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
            esc(&self.gimbal.config.name),
            self.zoomed(&format!(
                "<tt:DefaultAbsoluteZoomPositionSpace>{ZOOM_POSITION_SPACE}</tt:DefaultAbsoluteZoomPositionSpace>"
            )),
            self.relative_space(),
            self.zoomed(&format!(
                "<tt:DefaultContinuousZoomVelocitySpace>{ZOOM_VELOCITY_SPACE}</tt:DefaultContinuousZoomVelocitySpace>"
            )),
            self.zoomed(&format!("<tt:Zoom x=\"1\" space=\"{ZOOM_SPEED_SPACE}\"/>")),
            self.gimbal.max_move().as_secs_f64(),
            self.zoomed(&format!(
                "<tt:ZoomLimits><tt:Range><tt:URI>{ZOOM_POSITION_SPACE}</tt:URI><tt:XRange><tt:Min>0</tt:Min>\
                 <tt:Max>1</tt:Max></tt:XRange></tt:Range></tt:ZoomLimits>"
            ))
        )
    }

    /// `xml` for a gimbal with a lens, nothing otherwise.
    fn zoomed(&self, xml: &str) -> String {
        if self.gimbal.config.zoom {
            xml.to_owned()
        } else {
            String::new()
        }
    }

    fn media(&self, op: &Element) -> Result<String, Fault> {
        let g = &self.gimbal.config;
        let profile = || {
            format!(
                "token=\"{PROFILE}\" fixed=\"true\"><tt:Name>{}</tt:Name>{}{}",
                esc(&g.name),
                self.video_configurations(),
                self.ptz_configuration("tt:PTZConfiguration")
            )
        };
        Ok(match op.name.as_str() {
            "GetServiceCapabilities" => "<trt:GetServiceCapabilitiesResponse><trt:Capabilities SnapshotUri=\"false\" \
                 Rotation=\"false\"><trt:ProfileCapabilities MaximumNumberOfProfiles=\"1\"/><trt:StreamingCapabilities \
                 RTPMulticast=\"false\" RTP_TCP=\"true\" RTP_RTSP_TCP=\"true\"/></trt:Capabilities>\
                 </trt:GetServiceCapabilitiesResponse>"
                .to_owned(),
            "GetProfiles" => format!(
                "<trt:GetProfilesResponse><trt:Profiles {}</trt:Profiles></trt:GetProfilesResponse>",
                profile()
            ),
            "GetProfile" => {
                self.profile_token(op)?;
                format!(
                    "<trt:GetProfileResponse><trt:Profile {}</trt:Profile></trt:GetProfileResponse>",
                    profile()
                )
            }
            "GetStreamUri" => {
                self.profile_token(op)?;
                let uri = g.stream_uri.as_ref().ok_or_else(|| {
                    Fault::receiver(
                        &["ter:ActionNotSupported", "ter:NoStream"],
                        format!(
                            "gimbal {} has no stream_uri configured: it has no camera stream",
                            g.name
                        ),
                    )
                })?;
                format!(
                    "<trt:GetStreamUriResponse><trt:MediaUri><tt:Uri>{}</tt:Uri>\
                     <tt:InvalidAfterConnect>false</tt:InvalidAfterConnect><tt:InvalidAfterReboot>false</tt:InvalidAfterReboot>\
                     <tt:Timeout>PT0S</tt:Timeout></trt:MediaUri></trt:GetStreamUriResponse>",
                    esc(uri)
                )
            }
            "GetVideoSources" => {
                let sources = if g.stream_uri.is_some() {
                    format!(
                        "<trt:VideoSources token=\"{VIDEO_SOURCE}\"><tt:Framerate>25</tt:Framerate><tt:Resolution>\
                         <tt:Width>1920</tt:Width><tt:Height>1080</tt:Height></tt:Resolution></trt:VideoSources>"
                    )
                } else {
                    String::new()
                };
                format!("<trt:GetVideoSourcesResponse>{sources}</trt:GetVideoSourcesResponse>")
            }
            other => return Err(not_supported(other)),
        })
    }

    fn node(&self) -> String {
        format!(
            "token=\"{NODE}\" FixedHomePosition=\"true\"><tt:Name>{}</tt:Name>\
             <tt:SupportedPTZSpaces>{}</tt:SupportedPTZSpaces><tt:MaximumNumberOfPresets>256</tt:MaximumNumberOfPresets>\
             <tt:HomeSupported>true</tt:HomeSupported>",
            esc(&self.gimbal.config.name),
            spaces(self.gimbal.config.zoom, self.gimbal.config.fov_deg.is_some())
        )
    }

    async fn ptz(&self, op: &Element, now: OffsetDateTime) -> Result<String, Fault> {
        let g = &self.gimbal;
        let name = &g.config.name;
        Ok(match op.name.as_str() {
            "GetServiceCapabilities" => "<tptz:GetServiceCapabilitiesResponse><tptz:Capabilities EFlip=\"false\" \
                 Reverse=\"false\" GetCompatibleConfigurations=\"false\" MoveStatus=\"true\" StatusPosition=\"true\"/>\
                 </tptz:GetServiceCapabilitiesResponse>"
                .to_owned(),
            "GetNodes" => format!(
                "<tptz:GetNodesResponse><tptz:PTZNode {}</tptz:PTZNode></tptz:GetNodesResponse>",
                self.node()
            ),
            "GetNode" => {
                if op.text_at(&["NodeToken"]) != Some(NODE) {
                    return Err(Fault::invalid_arg(
                        "ter:NoEntity",
                        format!("no PTZ node of that token; the node is {NODE:?}"),
                    ));
                }
                format!(
                    "<tptz:GetNodeResponse><tptz:PTZNode {}</tptz:PTZNode></tptz:GetNodeResponse>",
                    self.node()
                )
            }
            "GetConfigurations" => format!(
                "<tptz:GetConfigurationsResponse>{}</tptz:GetConfigurationsResponse>",
                self.ptz_configuration("tptz:PTZConfiguration")
            ),
            "GetConfiguration" | "GetConfigurationOptions" => {
                let token = op
                    .text_at(&["PTZConfigurationToken"])
                    .or_else(|| op.text_at(&["ConfigurationToken"]));
                if token != Some(PTZ_CONFIG) {
                    return Err(Fault::invalid_arg(
                        "ter:NoConfig",
                        format!("no PTZ configuration of that token; it is {PTZ_CONFIG:?}"),
                    ));
                }
                if op.name == "GetConfiguration" {
                    format!(
                        "<tptz:GetConfigurationResponse>{}</tptz:GetConfigurationResponse>",
                        self.ptz_configuration("tptz:PTZConfiguration")
                    )
                } else {
                    format!(
                        "<tptz:GetConfigurationOptionsResponse><tptz:PTZConfigurationOptions><tt:Spaces>{}</tt:Spaces>\
                         <tt:PTZTimeout><tt:Min>PT0.1S</tt:Min><tt:Max>PT{}S</tt:Max></tt:PTZTimeout>\
                         </tptz:PTZConfigurationOptions></tptz:GetConfigurationOptionsResponse>",
                        spaces(self.gimbal.config.zoom, self.gimbal.config.fov_deg.is_some()),
                        g.max_move().as_secs_f64()
                    )
                }
            }
            "GetStatus" => {
                self.profile_token(op)?;
                let s = g.status();
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
                            to_generic(f64::from(p.pan.degrees()), g.config.pan_deg),
                            to_generic(f64::from(p.tilt.degrees()), g.config.tilt_deg)
                        )
                    })
                    .unwrap_or_default();
                let moving = g.move_status();
                let zoom_moving = self.zoomed(&format!("<tt:Zoom>{moving}</tt:Zoom>"));
                let error = s
                    .error
                    .map(|e| format!("<tt:Error>{}</tt:Error>", esc(&e)))
                    .unwrap_or_default();
                format!(
                    "<tptz:GetStatusResponse><tptz:PTZStatus>{position}<tt:MoveStatus><tt:PanTilt>{moving}</tt:PanTilt>\
                     {zoom_moving}</tt:MoveStatus>{error}<tt:UtcTime>{}</tt:UtcTime></tptz:PTZStatus></tptz:GetStatusResponse>",
                    utc(now)
                )
            }
            "ContinuousMove" => {
                self.profile_token(op)?;
                let velocity = op.path(&["Velocity", "PanTilt"]);
                let (x, y) = match velocity {
                    Some(v) => (
                        generic(v, "x", "Velocity PanTilt")?,
                        generic(v, "y", "Velocity PanTilt")?,
                    ),
                    None => (None, None),
                };
                let timeout = match op.text_at(&["Timeout"]) {
                    Some(t) => Some(duration(t).ok_or_else(|| {
                        Fault::invalid_arg(
                            "ter:InvalidTimeout",
                            format!("Timeout {t:?}: expected an xs:duration such as PT1.5S"),
                        )
                    })?),
                    None => None,
                };
                let zoom = match op.path(&["Velocity", "Zoom"]) {
                    Some(z) => self.zoom_arg(generic(z, "x", "Velocity Zoom")?)?,
                    None => None,
                };
                if x.is_none() && y.is_none() && zoom.is_none() {
                    return Err(Fault::invalid_arg(
                        "ter:InvalidVelocity",
                        "ContinuousMove without a Velocity PanTilt or Zoom",
                    ));
                }
                g.continuous(x, y, zoom, timeout).await.map_err(gimbal_fault)?;
                "<tptz:ContinuousMoveResponse/>".to_owned()
            }
            "AbsoluteMove" => {
                self.profile_token(op)?;
                let target = op.path(&["Position", "PanTilt"]);
                let zoom = match op.path(&["Position", "Zoom"]) {
                    Some(z) => self.zoom_arg(generic_from(z, "x", "Position Zoom", 0.0)?)?,
                    None => None,
                };
                let pan_tilt = match target {
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
                    None if zoom.is_some() => None,
                    None => {
                        return Err(Fault::invalid_arg(
                            "ter:InvalidPosition",
                            "AbsoluteMove without a Position PanTilt or Zoom",
                        ));
                    }
                };
                if let Some((x, y)) = pan_tilt {
                    g.go_to(to_degrees(x, g.config.pan_deg), to_degrees(y, g.config.tilt_deg))
                        .await
                        .map_err(gimbal_fault)?;
                }
                if let Some(z) = zoom {
                    g.zoom_to(z).await.map_err(gimbal_fault)?;
                }
                "<tptz:AbsoluteMoveResponse/>".to_owned()
            }
            "RelativeMove" => {
                self.profile_token(op)?;
                let t = op.path(&["Translation", "PanTilt"]).ok_or_else(|| {
                    Fault::invalid_arg("ter:InvalidTranslation", "RelativeMove without a Translation PanTilt")
                })?;
                let (dx, dy) = (
                    generic(t, "x", "Translation PanTilt")?.unwrap_or(0.0),
                    generic(t, "y", "Translation PanTilt")?.unwrap_or(0.0),
                );
                // The space named, else the profile's default; one the node
                // does not offer is refused, never read as another.
                let space = t.attr("space").map(str::trim).unwrap_or(self.relative_space());
                let fov = match (space, g.config.fov_deg) {
                    (TRANSLATION_SPACE, _) => None,
                    (FOV_SPACE, Some(fov)) => Some(fov),
                    (other, _) => {
                        return Err(Fault::invalid_arg(
                            "ter:SpaceNotSupported",
                            format!(
                                "Translation PanTilt space {other:?} is not offered by this node (GetNode lists its spaces)"
                            ),
                        ));
                    }
                };
                let now_at = g.position().await.map_err(gimbal_fault)?;
                let (pan_now, tilt_now) = (f64::from(now_at.pan.degrees()), f64::from(now_at.tilt.degrees()));
                let (pan, tilt) = match fov {
                    // x = 1 is the image's right edge: half the field of view
                    // from its centre (linear in the angle: no lens modelled).
                    Some((h, v)) => (
                        (pan_now + dx * h / 2.0).clamp(g.config.pan_deg.0, g.config.pan_deg.1),
                        (tilt_now + dy * v / 2.0).clamp(g.config.tilt_deg.0, g.config.tilt_deg.1),
                    ),
                    None => {
                        let x = to_generic(pan_now, g.config.pan_deg) + dx;
                        let y = to_generic(tilt_now, g.config.tilt_deg) + dy;
                        (
                            to_degrees(x.clamp(-1.0, 1.0), g.config.pan_deg),
                            to_degrees(y.clamp(-1.0, 1.0), g.config.tilt_deg),
                        )
                    }
                };
                g.go_to(pan, tilt).await.map_err(gimbal_fault)?;
                "<tptz:RelativeMoveResponse/>".to_owned()
            }
            "Stop" => {
                self.profile_token(op)?;
                let flag = |name: &str| op.text_at(&[name]).is_none_or(|v| v == "true" || v == "1");
                g.stop(flag("PanTilt"), flag("Zoom") && g.config.zoom)
                    .await
                    .map_err(gimbal_fault)?;
                "<tptz:StopResponse/>".to_owned()
            }
            "GetPresets" => {
                self.profile_token(op)?;
                let presets: String = self
                    .presets
                    .list(name)
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
            "SetPreset" => {
                self.profile_token(op)?;
                let n = match op.text_at(&["PresetToken"]).filter(|t| !t.is_empty()) {
                    Some(t) => preset_number(t)?,
                    None => self.presets.free(name).ok_or_else(|| {
                        Fault::receiver(&["ter:Action", "ter:TooManyPresets"], "all 256 presets have names")
                    })?,
                };
                let label = op
                    .text_at(&["PresetName"])
                    .filter(|t| !t.is_empty())
                    .map(str::to_owned)
                    .unwrap_or_else(|| format!("preset {n}"));
                if label.chars().count() > presets::MAX_NAME {
                    return Err(Fault::invalid_arg(
                        "ter:InvalidPresetName",
                        format!("PresetName longer than {} characters", presets::MAX_NAME),
                    ));
                }
                if let Some(bad) = label.chars().find(|&c| c.is_control() || !soap::xml_char(c)) {
                    return Err(Fault::invalid_arg(
                        "ter:InvalidPresetName",
                        format!("PresetName holds the control character U+{:04X}", u32::from(bad)),
                    ));
                }
                if self.presets.list(name).iter().any(|(m, l)| *l == label && *m != n) {
                    return Err(Fault::invalid_arg(
                        "ter:PresetExist",
                        format!("a preset is already named {label:?}"),
                    ));
                }
                g.send(&Command::StorePreset(n)).await.map_err(gimbal_fault)?;
                self.presets
                    .set(name, n, Some(&label))
                    .map_err(|e| Fault::receiver(&["ter:Action"], e))?;
                format!("<tptz:SetPresetResponse><tptz:PresetToken>{n}</tptz:PresetToken></tptz:SetPresetResponse>")
            }
            "GotoPreset" => {
                self.profile_token(op)?;
                let n = self.named_preset(op)?;
                g.go_to_preset(n).await.map_err(gimbal_fault)?;
                "<tptz:GotoPresetResponse/>".to_owned()
            }
            "RemovePreset" => {
                self.profile_token(op)?;
                let n = self.named_preset(op)?;
                self.presets
                    .set(name, n, None)
                    .map_err(|e| Fault::receiver(&["ter:Action"], e))?;
                "<tptz:RemovePresetResponse/>".to_owned()
            }
            "GotoHomePosition" => {
                self.profile_token(op)?;
                g.go_home().await.map_err(gimbal_fault)?;
                "<tptz:GotoHomePositionResponse/>".to_owned()
            }
            "SetHomePosition" => {
                return Err(Fault::receiver(
                    &["ter:Action", "ter:CannotOverwriteHome"],
                    "the home position of a Sagebrush gimbal is fixed (HO goes to 0, 0)",
                ));
            }
            other => return Err(not_supported(other)),
        })
    }

    /// A zoom argument: refused unless the gimbal has a lens (a zero
    /// velocity, "do not zoom", is taken from any client).
    fn zoom_arg(&self, value: Option<f64>) -> Result<Option<f64>, Fault> {
        match value {
            Some(v) if !self.gimbal.config.zoom && v != 0.0 => Err(Fault::invalid_arg(
                "ter:NoZoom",
                format!(
                    "gimbal {} has no lens configured (zoom = false)",
                    self.gimbal.config.name
                ),
            )),
            Some(_) if !self.gimbal.config.zoom => Ok(None),
            v => Ok(v),
        }
    }

    /// The preset a request's PresetToken names, which must have a name.
    fn named_preset(&self, op: &Element) -> Result<u8, Fault> {
        let token = op.text_at(&["PresetToken"]).unwrap_or_default();
        let n = preset_number(token)?;
        if !self.presets.list(&self.gimbal.config.name).iter().any(|(m, _)| *m == n) {
            return Err(Fault::invalid_arg(
                "ter:NoToken",
                format!("no preset with token {token:?}"),
            ));
        }
        Ok(n)
    }
}

fn preset_number(token: &str) -> Result<u8, Fault> {
    token.parse::<u8>().map_err(|_| {
        Fault::invalid_arg(
            "ter:NoToken",
            format!("preset token {token:?}: expected a number 0..=255"),
        )
    })
}

fn not_supported(operation: &str) -> Fault {
    Fault::receiver(
        &["ter:ActionNotSupported"],
        format!("{operation} is not supported by this device"),
    )
}

/// What each operation needs: a `user` reads, an `operator` also moves and
/// uses presets, an `administrator` may do everything.
pub fn needed_role(operation: &str) -> Role {
    match operation {
        "ContinuousMove" | "AbsoluteMove" | "RelativeMove" | "Stop" | "SetPreset" | "GotoPreset" | "RemovePreset"
        | "GotoHomePosition" => Role::Operator,
        "SetHomePosition" => Role::Administrator,
        op if op.starts_with("Get") => Role::User,
        _ => Role::Administrator,
    }
}

/// A gimbal's device scopes (ONVIF Core 7.3.2.2): type, profile, name and
/// hardware, as GetScopes and WS-Discovery give them.
pub fn scopes(g: &crate::config::Gimbal) -> Vec<String> {
    let mut scopes = vec![
        "onvif://www.onvif.org/type/ptz".to_owned(),
        "onvif://www.onvif.org/Profile/Streaming".to_owned(),
        format!("onvif://www.onvif.org/name/{}", scope_text(&g.name)),
        "onvif://www.onvif.org/hardware/Sagebrush-gimbal".to_owned(),
    ];
    if g.stream_uri.is_some() {
        scopes.push("onvif://www.onvif.org/type/video_encoder".to_owned());
    }
    scopes
}

/// A name as a scope item (no spaces, percent-encoded).
fn scope_text(name: &str) -> String {
    name.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use base64::Engine;
    use proptest::prelude::*;

    /// A device whose gcud is a closed port on loopback: every gimbal
    /// command fails at once, as when gcud is down.
    fn device(rt: &tokio::runtime::Runtime) -> Device {
        let text = r#"
gcud = "127.0.0.1:9"
[discovery]
enabled = false
[[user]]
name = "admin"
password = "pw"
role = "administrator"
[[gimbal]]
name = "g"
address = "5.1.1"
listen = "127.0.0.1:0"
"#;
        let config = crate::config::parse(std::path::Path::new("t.toml"), text).unwrap();
        // The gimbal's session runs on `rt`, where the test blocks: its gcud
        // (the discard port) refuses, so every command fails at once.
        let _rt = rt.enter();
        Device {
            gimbal: Gimbal::new(config.gimbals[0].clone(), &config, Default::default()),
            auth: Arc::new(Authenticator::new(config.users.clone())),
            presets: Arc::new(Presets::load(None).unwrap()),
        }
    }

    /// An envelope signed for `admin` around `body`, with a fresh nonce.
    fn signed(body: &str, nonce: u64) -> String {
        let created = utc(OffsetDateTime::now_utc());
        let mut h = Sha1::new();
        h.update(nonce.to_be_bytes());
        h.update(created.as_bytes());
        h.update(b"pw");
        let b64 = base64::engine::general_purpose::STANDARD;
        format!(
            r#"<s:Envelope xmlns:s="{}"><s:Header><Security><UsernameToken><Username>admin</Username><Password Type="{}">{}</Password><Nonce>{}</Nonce><Created>{created}</Created></UsernameToken></Security></s:Header><s:Body>{body}</s:Body></s:Envelope>"#,
            soap::NS_SOAP,
            crate::auth::PASSWORD_DIGEST,
            b64.encode(h.finalize()),
            b64.encode(nonce.to_be_bytes())
        )
    }

    const ORIGIN: Origin<'static> = Origin {
        host: "h:1",
        local: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
        uri: "/onvif/device_service",
        authorization: None,
    };

    fn runtime() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Any bytes: a fault, never a panic.
        #[test]
        fn any_body_is_answered_without_panicking(body in proptest::collection::vec(any::<u8>(), 0..1024)) {
            let rt = runtime();
            let d = device(&rt);
            prop_assert!(rt.block_on(d.handle(&body, &ORIGIN)).is_err());
        }

        /// Any operation of the three services, with any arguments, signed:
        /// a response or a fault, never a panic.
        #[test]
        fn any_signed_operation_is_answered_without_panicking(
            service in prop::sample::select(vec![NS_DEVICE, NS_MEDIA, NS_PTZ]),
            op in prop::sample::select(vec![
                "GetStatus", "ContinuousMove", "AbsoluteMove", "RelativeMove", "Stop", "SetPreset",
                "GotoPreset", "RemovePreset", "GetProfile", "GetStreamUri", "GetNode",
                "GetConfigurationOptions", "GetDeviceInformation", "SetHomePosition", "Reboot",
            ]),
            token in prop::sample::select(vec!["profile1", "ptznode1", "ptzconfig1", "0", "300", "", "x"]),
            x in "[-+0-9.eEn]{0,8}",
            timeout in "P?T?[0-9.]{0,6}[SMHD]?",
            nonce in any::<u64>(),
        ) {
            let body = format!(
                r#"<{op} xmlns="{service}"><ProfileToken>{token}</ProfileToken><NodeToken>{token}</NodeToken><ConfigurationToken>{token}</ConfigurationToken><PresetToken>{token}</PresetToken><Velocity><PanTilt x="{x}" y="{x}"/></Velocity><Position><PanTilt x="{x}" y="0"/></Position><Translation><PanTilt x="{x}"/></Translation><Timeout>{timeout}</Timeout></{op}>"#
            );
            let rt = runtime();
            let d = device(&rt);
            let _ = rt.block_on(d.handle(signed(&body, nonce).as_bytes(), &ORIGIN));
        }
    }

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

    #[test]
    fn gcuds_refusals_are_faults_a_vms_expects_with_gcuds_words() {
        let refused = |rule: Undelivered, why: &str| gimbal_fault(CommandError::Refused(rule, why.to_owned()));
        let f = refused(
            Undelivered::NotInControl,
            "refused by gcud: PR to 5.1.1: link operators (priority 80) controls the gimbal",
        );
        assert_eq!(
            (f.sender, f.subcodes.as_slice()),
            (false, &["ter:Action", "ter:NotInControl"][..])
        );
        assert_eq!(f.status(), 500);
        assert!(
            f.envelope().contains("link operators (priority 80)"),
            "{}",
            f.envelope()
        );
        let f = refused(Undelivered::TravelLimit, "beyond");
        assert_eq!(
            (f.sender, f.subcodes.as_slice()),
            (true, &["ter:InvalidArgVal", "ter:InvalidPosition"][..])
        );
        let f = refused(Undelivered::KeepOut, "zone");
        assert_eq!(f.subcodes, ["ter:InvalidArgVal", "ter:UnreachablePosition"]);
        let f = refused(Undelivered::PositionUnknown, "where?");
        assert_eq!(f.subcodes, ["ter:Action", "ter:PositionUnknown"]);
        // A failure to deliver stays one.
        let f = gimbal_fault(CommandError::Undelivered(Undelivered::DeviceSilent, "silent".into()));
        assert_eq!(f.subcodes, ["ter:Action", "ter:NotDelivered"]);
    }

    #[test]
    fn roles_and_scopes() {
        assert_eq!(needed_role("GetStatus"), Role::User);
        assert_eq!(needed_role("ContinuousMove"), Role::Operator);
        assert_eq!(needed_role("SetHomePosition"), Role::Administrator);
        assert_eq!(needed_role("Reboot"), Role::Administrator);
        assert_eq!(scope_text("mast 1/a"), "mast%201%2Fa");
    }
}
