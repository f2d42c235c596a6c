//! The Device service (ONVIF Core 8, `tds`, ver10): the request read from
//! the Body ([`Request::parse`]), executed ([`Request::run`]: only the
//! device information asks the gimbal) and the response rendered from the
//! typed result ([`Response::render`]).

use sagebrush_client::Identity;
use sha1::{Digest, Sha1};
use time::OffsetDateTime;

use super::{Device, Origin, faults, scopes};
use crate::config;
use crate::soap::{Element, Fault, NS_DEVICE, NS_MEDIA, NS_PTZ, esc};

/// A Device service request this device answers (each variant named as
/// the operation is, so the ONVIF names are searchable here).
#[allow(clippy::enum_variant_names)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    GetSystemDateAndTime,
    GetServiceCapabilities,
    GetDeviceInformation,
    GetCapabilities,
    GetServices,
    GetScopes,
    GetHostname,
    GetNetworkInterfaces,
}

/// What a request found, to be rendered.
#[derive(Debug, Clone)]
pub enum Response {
    DateAndTime(OffsetDateTime),
    ServiceCapabilities,
    Information(Identity),
    /// The service addresses at `host`: `SCHEME://HOST` (the scheme and
    /// the Host the client reached).
    Capabilities {
        host: String,
    },
    Services {
        host: String,
    },
    Scopes,
    Hostname,
    /// The interface the request came in on.
    NetworkInterfaces {
        ip: std::net::IpAddr,
    },
}

impl Request {
    /// The operation the Body's element names (its namespace is this
    /// service's); its arguments are none.
    pub fn parse(op: &Element) -> Result<Self, Fault> {
        Ok(match op.name.as_str() {
            "GetSystemDateAndTime" => Self::GetSystemDateAndTime,
            "GetServiceCapabilities" => Self::GetServiceCapabilities,
            "GetDeviceInformation" => Self::GetDeviceInformation,
            "GetCapabilities" => Self::GetCapabilities,
            "GetServices" => Self::GetServices,
            "GetScopes" => Self::GetScopes,
            "GetHostname" => Self::GetHostname,
            "GetNetworkInterfaces" => Self::GetNetworkInterfaces,
            other => return Err(faults::not_supported(other)),
        })
    }

    pub async fn run(self, device: &Device, origin: &Origin<'_>, now: OffsetDateTime) -> Result<Response, Fault> {
        let host = || format!("{}://{}", origin.scheme, origin.host);
        Ok(match self {
            Self::GetSystemDateAndTime => Response::DateAndTime(now),
            Self::GetServiceCapabilities => Response::ServiceCapabilities,
            Self::GetDeviceInformation => {
                Response::Information(device.gimbal.identity().await.map_err(faults::gimbal)?)
            }
            Self::GetCapabilities => Response::Capabilities { host: host() },
            Self::GetServices => Response::Services { host: host() },
            Self::GetScopes => Response::Scopes,
            Self::GetHostname => Response::Hostname,
            Self::GetNetworkInterfaces => Response::NetworkInterfaces { ip: origin.local },
        })
    }
}

/// A service's address at `base` (`SCHEME://HOST[:PORT]`).
fn url(base: &str, service: &str) -> String {
    esc(&format!("{base}/onvif/{service}")).into_owned()
}

/// A locally administered MAC address of its own for this gimbal's
/// device (clients such as Home Assistant key devices on it).
fn hw_address(g: &config::Gimbal) -> String {
    let digest = Sha1::digest(format!("{} {}", g.name, g.address).as_bytes());
    let mut mac = [0u8; 6];
    mac.copy_from_slice(&digest[..6]);
    mac[0] = (mac[0] | 0x02) & 0xFE;
    mac.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(":")
}

impl Response {
    /// The response element (ONVIF devicemgmt.wsdl).
    pub fn render(&self, g: &config::Gimbal) -> String {
        match self {
            Self::DateAndTime(now) => date_and_time(*now),
            Self::ServiceCapabilities => "<tds:GetServiceCapabilitiesResponse><tds:Capabilities>\
                 <tds:Network IPFilter=\"false\" ZeroConfiguration=\"false\" IPVersion6=\"false\" DynDNS=\"false\"/>\
                 <tds:Security UsernameToken=\"true\" HttpDigest=\"true\"/>\
                 <tds:System DiscoveryResolve=\"false\" DiscoveryBye=\"true\" RemoteDiscovery=\"false\" SystemBackup=\"false\" \
                 SystemLogging=\"false\" FirmwareUpgrade=\"false\"/></tds:Capabilities></tds:GetServiceCapabilitiesResponse>"
                .to_owned(),
            Self::Information(id) => {
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
            Self::Capabilities { host } => capabilities(host),
            Self::Services { host } => {
                let service = |ns: &str, path: &str| {
                    format!(
                        "<tds:Service><tds:Namespace>{ns}</tds:Namespace><tds:XAddr>{}</tds:XAddr>\
                         <tds:Version><tt:Major>2</tt:Major><tt:Minor>0</tt:Minor></tds:Version></tds:Service>",
                        url(host, path)
                    )
                };
                format!(
                    "<tds:GetServicesResponse>{}{}{}</tds:GetServicesResponse>",
                    service(NS_DEVICE, "device_service"),
                    service(NS_MEDIA, "media_service"),
                    service(NS_PTZ, "ptz_service")
                )
            }
            Self::Scopes => {
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
            Self::Hostname => format!(
                "<tds:GetHostnameResponse><tds:HostnameInformation><tt:FromDHCP>false</tt:FromDHCP>\
                 <tt:Name>{}</tt:Name></tds:HostnameInformation></tds:GetHostnameResponse>",
                esc(&g.name)
            ),
            Self::NetworkInterfaces { ip } => format!(
                "<tds:GetNetworkInterfacesResponse><tds:NetworkInterfaces token=\"eth0\"><tt:Enabled>true</tt:Enabled>\
                 <tt:Info><tt:Name>eth0</tt:Name><tt:HwAddress>{}</tt:HwAddress><tt:MTU>1500</tt:MTU></tt:Info>\
                 <tt:IPv4><tt:Enabled>true</tt:Enabled><tt:Config><tt:Manual><tt:Address>{}</tt:Address>\
                 <tt:PrefixLength>24</tt:PrefixLength></tt:Manual><tt:DHCP>false</tt:DHCP></tt:Config></tt:IPv4>\
                 </tds:NetworkInterfaces></tds:GetNetworkInterfacesResponse>",
                hw_address(g),
                esc(&ip.to_string())
            ),
        }
    }
}

fn date_and_time(now: OffsetDateTime) -> String {
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

fn capabilities(host: &str) -> String {
    format!(
        "<tds:GetCapabilitiesResponse><tds:Capabilities>\
         <tt:Device><tt:XAddr>{}</tt:XAddr><tt:System><tt:DiscoveryResolve>false</tt:DiscoveryResolve>\
         <tt:DiscoveryBye>true</tt:DiscoveryBye><tt:RemoteDiscovery>false</tt:RemoteDiscovery>\
         <tt:SystemBackup>false</tt:SystemBackup><tt:SystemLogging>false</tt:SystemLogging>\
         <tt:FirmwareUpgrade>false</tt:FirmwareUpgrade><tt:SupportedVersions><tt:Major>2</tt:Major>\
         <tt:Minor>0</tt:Minor></tt:SupportedVersions></tt:System></tt:Device>\
         <tt:Media><tt:XAddr>{}</tt:XAddr><tt:StreamingCapabilities><tt:RTPMulticast>false</tt:RTPMulticast>\
         <tt:RTP_TCP>true</tt:RTP_TCP><tt:RTP_RTSP_TCP>true</tt:RTP_RTSP_TCP></tt:StreamingCapabilities></tt:Media>\
         <tt:PTZ><tt:XAddr>{}</tt:XAddr></tt:PTZ></tds:Capabilities></tds:GetCapabilitiesResponse>",
        url(host, "device_service"),
        url(host, "media_service"),
        url(host, "ptz_service")
    )
}
