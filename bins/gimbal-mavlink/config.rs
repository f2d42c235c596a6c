//! `gimbal-mavlink --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-mavlink.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_service::config_file`] as gcud's and gimbal-onvif's.

use sagebrush_client::session::GcudLink;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_protocol::Address;
use sagebrush_service::config_file::{self, ConfigError, Int, Millis, Source};
use sagebrush_service::endpoint::{Host, HostPort};
use serde::Deserialize;
use toml::Spanned;

use crate::earth::geometry::Place;
use crate::transport::signing::Key;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    system_id: Int<u8, 1, 255>,
    attitude_rate_hz: Option<Spanned<f64>>,
    #[serde(default)]
    lease_ms: Millis<100, 60_000, 1000>,
    #[serde(default)]
    control_lapse_ms: Millis<1000, 600_000, 5000>,
    /// Where the mount is, for a mast (MAV_CMD_DO_SET_ROI_LOCATION).
    mount_latitude_deg: Option<Spanned<f64>>,
    mount_longitude_deg: Option<Spanned<f64>>,
    mount_altitude_m: Option<Spanned<f64>>,
    #[serde(default, rename = "endpoint")]
    endpoints: Vec<EndpointSection>,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
    signing: Option<SigningSection>,
}

/// `[signing]`: MAVLink 2 message signing.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SigningSection {
    /// The 32-byte secret key as 64 hexadecimal digits (`signing::Key`).
    key_file: Spanned<String>,
    /// The link id of the frames this door signs.
    #[serde(default)]
    link_id: Int<u8, 0, 255>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EndpointSection {
    udp_listen: Option<Spanned<String>>,
    udp: Option<Spanned<String>>,
    tcp_listen: Option<Spanned<String>>,
    tcp: Option<Spanned<String>>,
    serial: Option<Spanned<String>>,
    /// A MAVLink serial line's rate: telemetry radios' and flight
    /// controllers' TELEM ports' usual 57600 by default.
    baud: Option<Int<u32, 50, 4_000_000, 57_600>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    component_id: Int<u8, 1, 255>,
    pan_deg: Option<Spanned<Vec<f64>>>,
    tilt_deg: Option<Spanned<Vec<f64>>>,
    max_rate_dps: Option<Spanned<f64>>,
    mount_heading_deg: Option<Spanned<f64>>,
}

/// Where MAVLink comes and goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    /// Listens; sends to every address it has heard from.
    UdpListen(SocketAddr),
    /// Sends to a ground station's address (and hears its answers).
    Udp(String),
    /// Accepts TCP connections; sends to every one.
    TcpListen(SocketAddr),
    /// Keeps a TCP connection to a ground station open.
    Tcp(String),
    /// A serial line (a telemetry radio, a flight controller's TELEM
    /// port), opened again whenever it closes or is unplugged.
    Serial { path: PathBuf, baud: u32 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    /// The MAVLink component id of this gimbal manager and device.
    pub component_id: u8,
    /// Travel, degrees: pan (MAVLink yaw) and tilt (MAVLink pitch).
    pub pan_deg: (f64, f64),
    pub tilt_deg: (f64, f64),
    /// Proportional speed F (Table 11) in degrees per second.
    pub max_rate_dps: f64,
    /// A fixed heading of the pan's zero, degrees clockwise from true
    /// north (a mast); None: the autopilot's ATTITUDE says it (`vehicle`).
    pub mount_heading_deg: Option<f64>,
}

/// `[signing]`: the key, and the link id this door signs with.
#[derive(Clone, Debug, PartialEq)]
pub struct SigningKey {
    pub key: Key,
    pub link_id: u8,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// gcud, this door's source group and NIC window.
    pub link: GcudLink,
    pub system_id: u8,
    /// GIMBAL_DEVICE_ATTITUDE_STATUS (and `P?` poll) period.
    pub attitude_period: Duration,
    /// A rate not refreshed within this is stopped.
    pub lease: Duration,
    /// A control owner not heard for this long loses control.
    pub control_lapse: Duration,
    /// A fixed mount location (a mast); None: the autopilot's
    /// GLOBAL_POSITION_INT says it (`vehicle`).
    pub mount: Option<Place>,
    pub endpoints: Vec<Endpoint>,
    /// Each serial endpoint's device and place in the file (`--check`
    /// warns of one absent now).
    pub serial_places: Vec<(PathBuf, String)>,
    pub gimbals: Vec<Gimbal>,
    /// Signing on: only frames signed with this key are read.
    pub signing: Option<SigningKey>,
    /// What `--check` warns of in the file itself: an endpoint off
    /// loopback without signing, a key file others may read.
    pub notes: Vec<String>,
}

impl Gimbal {
    /// The mast gimbal 5.1.1, component 154, full travel, of the unit tests.
    #[cfg(test)]
    pub fn for_tests(mount_heading_deg: Option<f64>) -> Self {
        Self {
            name: "g".into(),
            address: Address::new(5, 1, 1),
            component_id: 154,
            pan_deg: (-180.0, 180.0),
            tilt_deg: (-90.0, 90.0),
            max_rate_dps: 120.0,
            mount_heading_deg,
        }
    }
}

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        format!("{} gimbal(s), {} endpoint(s)", self.gimbals.len(), self.endpoints.len())
    }

    fn warnings(&self) -> Vec<String> {
        let mut warnings = self.notes.clone();
        warnings.extend(config_file::absent_serial_devices(
            &self.serial_places,
            "gimbal-mavlink",
        ));
        warnings
    }
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, { sagebrush_service::door_link::NO_POLL }>()?;
    let attitude_period = match &raw.attitude_rate_hz {
        Some(v) if (0.2..=50.0).contains(v.get_ref()) => Duration::from_secs_f64(1.0 / v.get_ref()),
        Some(v) => {
            return Err(c.at(
                v.span(),
                "attitude_rate_hz",
                format!("expected a rate 0.2..=50.0 Hz, found {}", v.get_ref()),
            ));
        }
        None => Duration::from_millis(200),
    };
    let (endpoints, serial_places) = endpoints(&c, &raw.endpoints)?;
    let (signing, mut notes) = signing(&c, raw.signing.as_ref())?;
    if signing.is_none() {
        notes.extend(unsigned_off_loopback(&c, &raw.endpoints));
    }
    let gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = c.gimbal_name(&g.name, key, before.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let component_id = g.component_id.get();
        if before.iter().any(|x| x.component_id == component_id) {
            return Err(c.at(
                g.component_id.span(),
                format!("{key}.component_id"),
                "expected a component id of its own (MAV_COMP_ID_GIMBAL 154, GIMBAL2..6 171..175)",
            ));
        }
        let (pan_deg, tilt_deg) = c.pan_tilt_travel(g.pan_deg.as_ref(), g.tilt_deg.as_ref(), key)?;
        let max_rate_dps = match &g.max_rate_dps {
            Some(v) if *v.get_ref() > 0.0 && *v.get_ref() <= 655.35 => *v.get_ref(),
            Some(v) => {
                return Err(c.at(
                    v.span(),
                    format!("{key}.max_rate_dps"),
                    "expected degrees per second, above 0 and at most 655.35 (Table 12)",
                ));
            }
            None => 120.0,
        };
        let mount_heading_deg = match &g.mount_heading_deg {
            Some(v) if v.get_ref().is_finite() && v.get_ref().abs() <= 360.0 => Some(*v.get_ref()),
            Some(v) => {
                return Err(c.at(
                    v.span(),
                    format!("{key}.mount_heading_deg"),
                    "expected degrees clockwise from true north, -360..=360",
                ));
            }
            None => None,
        };
        Ok(Gimbal {
            name,
            address,
            component_id,
            pan_deg,
            tilt_deg,
            max_rate_dps,
            mount_heading_deg,
        })
    })?;
    let mount = mount_place(&c, &raw)?;
    Ok(Config {
        link: GcudLink::from(&keys),
        mount,
        system_id: raw.system_id.get(),
        attitude_period,
        lease: raw.lease_ms.duration(),
        control_lapse: raw.control_lapse_ms.duration(),
        endpoints,
        serial_places,
        gimbals,
        signing,
        notes,
    })
}

/// `[signing]`: the key read from `key_file` (its place named in every
/// error, its text never quoted), and a warning when others may read it.
fn signing(c: &Source, raw: Option<&SigningSection>) -> Result<(Option<SigningKey>, Vec<String>), ConfigError> {
    let Some(raw) = raw else {
        return Ok((None, Vec::new()));
    };
    let path = raw.key_file.get_ref();
    let at = |message: String| c.at(raw.key_file.span(), "signing.key_file", format!("{path}: {message}"));
    let text = config_file::read(Path::new(path)).map_err(|e| at(e.message))?;
    let key = Key::parse(&text).map_err(at)?;
    let mut notes = Vec::new();
    if let Ok(meta) = std::fs::metadata(path) {
        use std::os::unix::fs::PermissionsExt;
        let mode = meta.permissions().mode() & 0o777;
        if mode & 0o077 != 0 {
            notes.push(format!(
                "{}: {path} may be read by others than its owner (mode {mode:03o}): chmod 600 it, or hand it over with systemd's LoadCredential",
                c.place(raw.key_file.span(), "signing.key_file")
            ));
        }
    }
    let link_id = raw.link_id.get();
    Ok((Some(SigningKey { key, link_id }), notes))
}

/// `--check`'s warnings without `[signing]`: each endpoint that listens or
/// connects off loopback (not 127.0.0.0/8, ::1 or localhost), where anyone
/// who reaches it may command the gimbals.
fn unsigned_off_loopback(c: &Source, sections: &[EndpointSection]) -> Vec<String> {
    let mut notes = Vec::new();
    for (i, e) in sections.iter().enumerate() {
        let given = [
            ("udp_listen", &e.udp_listen),
            ("tcp_listen", &e.tcp_listen),
            ("udp", &e.udp),
            ("tcp", &e.tcp),
        ];
        for (kind, value) in given {
            let Some(value) = value else { continue };
            let text = value.get_ref();
            let loopback = match kind {
                "udp_listen" | "tcp_listen" => text.parse::<SocketAddr>().is_ok_and(|a| a.ip().is_loopback()),
                _ => text.parse::<HostPort>().is_ok_and(|h| match h.host {
                    Host::Ip(ip) => ip.is_loopback(),
                    Host::Name(name) => name.eq_ignore_ascii_case("localhost"),
                }),
            };
            if !loopback {
                notes.push(format!(
                    "{}: {text} is off loopback and [signing] is not set: whoever reaches it may move the gimbals; set [signing] key_file, or use 127.0.0.1",
                    c.place(value.span(), &format!("endpoint[{i}].{kind}"))
                ));
            }
        }
    }
    notes
}

/// Each serial endpoint's device and its place in the file.
type SerialPlaces = Vec<(PathBuf, String)>;

/// The `[[endpoint]]`s, and each serial one's device and place in the file.
fn endpoints(c: &Source, sections: &[EndpointSection]) -> Result<(Vec<Endpoint>, SerialPlaces), ConfigError> {
    let mut endpoints = Vec::new();
    let mut serial_places = Vec::new();
    for (i, e) in sections.iter().enumerate() {
        let key = format!("endpoint[{i}]");
        let given = [
            e.udp_listen.as_ref().map(|v| ("udp_listen", v)),
            e.udp.as_ref().map(|v| ("udp", v)),
            e.tcp_listen.as_ref().map(|v| ("tcp_listen", v)),
            e.tcp.as_ref().map(|v| ("tcp", v)),
            e.serial.as_ref().map(|v| ("serial", v)),
        ];
        let mut given = given.into_iter().flatten();
        let (Some((kind, value)), None) = (given.next(), given.next()) else {
            return Err(c.at(
                0..0,
                key,
                "expected exactly one of udp_listen, udp, tcp_listen, tcp or serial",
            ));
        };
        if let (Some(b), false) = (&e.baud, kind == "serial") {
            return Err(c.at(
                b.span(),
                format!("{key}.baud"),
                "baud applies to a serial endpoint only",
            ));
        }
        endpoints.push(match kind {
            "udp_listen" => Endpoint::UdpListen(c.listen_address(value, &format!("{key}.{kind}"))?),
            "tcp_listen" => Endpoint::TcpListen(c.listen_address(value, &format!("{key}.{kind}"))?),
            "udp" | "tcp" => {
                c.host_port(value, &format!("{key}.{kind}"), "")?;
                if kind == "udp" {
                    Endpoint::Udp(value.get_ref().clone())
                } else {
                    Endpoint::Tcp(value.get_ref().clone())
                }
            }
            _ => Endpoint::Serial {
                path: {
                    let path = PathBuf::from(value.get_ref());
                    serial_places.push((path.clone(), c.place(value.span(), &format!("{key}.serial"))));
                    path
                },
                baud: e.baud.clone().unwrap_or_default().get(),
            },
        });
    }
    if endpoints.is_empty() {
        return Err(c.at(0..0, "endpoint", "expected at least one [[endpoint]]"));
    }
    Ok((endpoints, serial_places))
}

/// The configured mount location: all three keys or none.
fn mount_place(c: &Source, raw: &ConfigFile) -> Result<Option<Place>, ConfigError> {
    let keys = [
        ("mount_latitude_deg", &raw.mount_latitude_deg, 90.0),
        ("mount_longitude_deg", &raw.mount_longitude_deg, 180.0),
        ("mount_altitude_m", &raw.mount_altitude_m, 20_000.0),
    ];
    let mut values = [0.0; 3];
    for (i, (key, value, limit)) in keys.iter().enumerate() {
        match value {
            Some(v) if v.get_ref().is_finite() && v.get_ref().abs() <= *limit => values[i] = *v.get_ref(),
            Some(v) => return Err(c.at(v.span(), *key, format!("expected a number within ±{limit}"))),
            None if keys.iter().any(|k| k.1.is_some()) => {
                return Err(c.at(
                    0..0,
                    *key,
                    "expected with the other mount_ keys: latitude, longitude and altitude together",
                ));
            }
            None => return Ok(None),
        }
    }
    let [lat_deg, lon_deg, alt_m] = values;
    Ok(Some(Place {
        lat_deg,
        lon_deg,
        alt_m,
    }))
}

#[cfg(test)]
mod tests;
