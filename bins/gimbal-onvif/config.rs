//! `gimbal-onvif --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-onvif.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_client::config_file`] as gcud's.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_client::config_file::{ConfigError, Int, Millis, Source, listeners_clash};
use sagebrush_protocol::Address;
use serde::Deserialize;
use toml::Spanned;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    gcud: Spanned<String>,
    /// The source group gcud sees (0: the MCU).
    #[serde(default)]
    source_group: Int<u8, 0, 254>,
    state_file: Option<Spanned<String>>,
    #[serde(default)]
    max_move_ms: Millis<100, 600_000, 10_000>,
    #[serde(default)]
    poll_ms: Millis<20, 10_000, 200>,
    #[serde(default)]
    nic_window_ms: Millis<10, 1000, 100>,
    #[serde(default)]
    discovery: DiscoverySection,
    #[serde(default, rename = "user")]
    users: Vec<UserSection>,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct DiscoverySection {
    enabled: Option<Spanned<bool>>,
    listen: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct UserSection {
    name: Spanned<String>,
    password: Option<Spanned<String>>,
    password_file: Option<Spanned<String>>,
    role: Spanned<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    listen: Spanned<String>,
    stream_uri: Option<Spanned<String>>,
    pan_deg: Option<Spanned<Vec<f64>>>,
    tilt_deg: Option<Spanned<Vec<f64>>>,
    zoom: Option<Spanned<bool>>,
}

/// What a user may do (ONVIF Core "User level"): a `User` reads, an
/// `Operator` also moves the gimbal and uses presets, an `Administrator`
/// does everything.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Role {
    User,
    Operator,
    Administrator,
}

#[derive(Clone, Debug, PartialEq)]
pub struct User {
    pub name: String,
    pub password: String,
    pub role: Role,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    pub listen: SocketAddr,
    pub stream_uri: Option<String>,
    /// The travel ONVIF's generic space [-1, 1] maps onto, degrees.
    pub pan_deg: (f64, f64),
    pub tilt_deg: (f64, f64),
    /// The gimbal has a lens: zoom through `ZI`/`ZO`/`ZS`, `Zn`, `V`, `V?`.
    pub zoom: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    pub gcud: String,
    pub source_group: u8,
    pub state_file: Option<PathBuf>,
    /// The longest a ContinuousMove without a Timeout runs.
    pub max_move: Duration,
    /// How often each gimbal's position is asked (`P?`) for GetStatus.
    pub poll: Duration,
    /// How long after gcud's ACK a NIC may still come (1.4.2).
    pub nic_window: Duration,
    pub discovery: Option<SocketAddr>,
    pub users: Vec<User>,
    pub gimbals: Vec<Gimbal>,
}

/// The WS-Discovery port and multicast group (WS-Discovery 1.1, 3.1.1).
pub const DISCOVERY_DEFAULT: &str = "0.0.0.0:3702";

impl sagebrush_client::door::Checked for Config {
    fn summary(&self) -> String {
        format!("{} gimbal(s), {} user(s)", self.gimbals.len(), self.users.len())
    }
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let raw: ConfigFile = c.deserialize()?;
    let gcud = c.gcud_address(&raw.gcud)?;
    let discovery = match raw.discovery.enabled.as_ref().map(|e| *e.get_ref()) {
        Some(false) => None,
        _ => Some(match &raw.discovery.listen {
            Some(l) => socket(&c, l, "discovery.listen")?,
            None => DISCOVERY_DEFAULT.parse().expect("a socket address"),
        }),
    };
    let mut users = Vec::new();
    for (i, u) in raw.users.iter().enumerate() {
        let key = format!("user[{i}]");
        let name = u.name.get_ref().clone();
        if name.is_empty() || users.iter().any(|x: &User| x.name == name) {
            return Err(c.at(
                u.name.span(),
                format!("{key}.name"),
                "expected a name, not empty and not repeated",
            ));
        }
        let password = match (&u.password, &u.password_file) {
            (Some(p), None) => p.get_ref().clone(),
            (None, Some(f)) => {
                let text = std::fs::read_to_string(f.get_ref()).map_err(|e| {
                    c.at(
                        f.span(),
                        format!("{key}.password_file"),
                        format!("cannot read {}: {e}", f.get_ref()),
                    )
                })?;
                text.trim_end_matches(['\n', '\r']).to_owned()
            }
            _ => {
                return Err(c.at(
                    u.name.span(),
                    key,
                    "expected exactly one of `password` or `password_file`",
                ));
            }
        };
        if password.is_empty() {
            return Err(c.at(
                u.name.span(),
                format!("{key}.password"),
                "expected a password, not empty",
            ));
        }
        let role = match u.role.get_ref().as_str() {
            "administrator" => Role::Administrator,
            "operator" => Role::Operator,
            "user" => Role::User,
            other => {
                return Err(c.at(
                    u.role.span(),
                    format!("{key}.role"),
                    format!("expected administrator, operator or user, found {other:?}"),
                ));
            }
        };
        users.push(User { name, password, role });
    }
    if users.is_empty() {
        return Err(c.at(
            0..0,
            "user",
            "expected at least one [[user]]: every operation but GetSystemDateAndTime needs credentials",
        ));
    }
    let mut gimbals: Vec<Gimbal> = Vec::new();
    for (i, g) in raw.gimbals.iter().enumerate() {
        let key = format!("gimbal[{i}]");
        let name = c.gimbal_name(&g.name, &key, gimbals.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let listen = socket(&c, &g.listen, &format!("{key}.listen"))?;
        if gimbals.iter().any(|x| listeners_clash(&x.listen, &listen)) {
            return Err(c.at(
                g.listen.span(),
                format!("{key}.listen"),
                "expected an address of its own: each gimbal is its own ONVIF device",
            ));
        }
        let stream_uri = match &g.stream_uri {
            Some(s) if !s.get_ref().contains("://") => {
                return Err(c.at(
                    s.span(),
                    format!("{key}.stream_uri"),
                    "expected a URI, e.g. rtsp://10.0.0.20/main",
                ));
            }
            s => s.as_ref().map(|s| s.get_ref().clone()),
        };
        let (pan_deg, tilt_deg) = c.pan_tilt_travel(g.pan_deg.as_ref(), g.tilt_deg.as_ref(), &key)?;
        gimbals.push(Gimbal {
            name,
            address,
            listen,
            stream_uri,
            pan_deg,
            tilt_deg,
            zoom: g.zoom.as_ref().is_some_and(|z| *z.get_ref()),
        });
    }
    if gimbals.is_empty() {
        return Err(c.at(0..0, "gimbal", "expected at least one [[gimbal]]"));
    }
    Ok(Config {
        gcud,
        source_group: raw.source_group.get(),
        state_file: raw.state_file.map(|s| PathBuf::from(s.into_inner())),
        max_move: raw.max_move_ms.duration(),
        poll: raw.poll_ms.duration(),
        nic_window: raw.nic_window_ms.duration(),
        discovery,
        users,
        gimbals,
    })
}

fn socket(c: &Source<'_>, v: &Spanned<String>, key: &str) -> Result<SocketAddr, ConfigError> {
    v.get_ref()
        .parse()
        .map_err(|_| c.at(v.span(), key, format!("expected IP:PORT, found {:?}", v.get_ref())))
}

#[cfg(test)]
mod tests;
