//! `gimbal-visca --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-visca.toml`), parsed with serde and then
//! validated through [`sagebrush_service::config_file`] as the other
//! doors'; every error names the file, line and column, the key and what
//! was expected (`--check` prints it and exits 2).

use std::net::{IpAddr, SocketAddr};
use std::path::Path;
use std::time::Duration;

use sagebrush_client::session::GcudLink;
use sagebrush_protocol::Address;
use sagebrush_service::config_file::{ConfigError, Millis, Source};
use serde::Deserialize;
use toml::Spanned;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    #[serde(default)]
    motion_lease_ms: Millis<0, 600_000, 5000>,
    #[serde(default, rename = "client")]
    clients: Vec<ClientSection>,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClientSection {
    address: Spanned<String>,
    user: Spanned<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    visca_udp: Spanned<String>,
    visca_tcp: Option<Spanned<String>>,
    #[serde(default)]
    reuse_address: bool,
    degrees_per_step: Option<Spanned<f64>>,
    #[serde(default)]
    lens: bool,
}

/// One VISCA camera: a gimbal behind gcud.
#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    /// Sony VISCA over IP.
    pub udp: SocketAddr,
    /// Raw VISCA over TCP, when wanted.
    pub tcp: Option<SocketAddr>,
    /// SO_REUSEADDR on the UDP socket (a same-host client binds the port on every address).
    pub reuse_address: bool,
    /// The angle of one VISCA position step, degrees.
    pub degrees_per_step: f64,
    /// The gimbal has a zoom and focus lens (`V?`, Table 16).
    pub lens: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// gcud, this door's source group and NIC window.
    pub link: GcudLink,
    pub poll: Duration,
    /// How long a drive runs unless the client repeats it; `None`: until
    /// a stop (or [`MAX_MOVE`]).
    pub lease: Option<Duration>,
    /// Client IP addresses the door acts for as a named user at gcud.
    pub clients: Vec<(IpAddr, String)>,
    pub gimbals: Vec<Gimbal>,
}

/// The longest any drive runs without being repeated when the lease is off.
pub const MAX_MOVE: Duration = Duration::from_secs(3600);

/// The default angle of one VISCA position step (Sony's EVI and SRG
/// cameras: ±170° in ±2267 steps).
pub const DEGREES_PER_STEP: f64 = 0.075;

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        let ports: Vec<String> = self
            .gimbals
            .iter()
            .map(|g| match g.tcp {
                Some(t) => format!("{} on udp {} and tcp {t}", g.name, g.udp),
                None => format!("{} on udp {}", g.name, g.udp),
            })
            .collect();
        format!("{} gimbal(s): {}", self.gimbals.len(), ports.join(", "))
    }

    fn warnings(&self) -> Vec<String> {
        self.gimbals
            .iter()
            .flat_map(|g| std::iter::once(g.udp).chain(g.tcp))
            .filter(|a| !a.ip().is_loopback())
            .map(|a| format!("{a} serves VISCA, which has no authentication, to the network: allow only the controllers' addresses to it (a firewall)"))
            .collect()
    }
}

/// A user name gcud can carry (`~U name`: 1..=32 of `A-Z a-z 0-9 _ -`).
fn user_name(name: &str) -> bool {
    (1..=32).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, 100>()?;
    let mut clients: Vec<(IpAddr, String)> = Vec::new();
    for (i, cl) in raw.clients.iter().enumerate() {
        let key = format!("client[{i}]");
        let ip: IpAddr = cl.address.get_ref().parse().map_err(|_| {
            c.at(
                cl.address.span(),
                format!("{key}.address"),
                "expected an IP address, e.g. \"192.168.1.20\"",
            )
        })?;
        if clients.iter().any(|(a, _)| *a == ip) {
            return Err(c.at(
                cl.address.span(),
                format!("{key}.address"),
                "expected each address once",
            ));
        }
        if !user_name(cl.user.get_ref()) {
            return Err(c.at(
                cl.user.span(),
                format!("{key}.user"),
                "expected 1 to 32 of A-Z a-z 0-9 _ -",
            ));
        }
        clients.push((ip, cl.user.get_ref().clone()));
    }
    let gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = c.gimbal_name(&g.name, key, before.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let udp = c.listen_address(&g.visca_udp, &format!("{key}.visca_udp"))?;
        let tcp = match &g.visca_tcp {
            Some(t) => Some(c.listen_address(t, &format!("{key}.visca_tcp"))?),
            None => None,
        };
        let taken = |a: SocketAddr, tcp: bool| {
            a.port() != 0 && before.iter().any(|x| if tcp { x.tcp == Some(a) } else { x.udp == a })
        };
        if taken(udp, false) {
            return Err(c.at(
                g.visca_udp.span(),
                format!("{key}.visca_udp"),
                "expected an address no other gimbal uses: each gimbal is its own camera",
            ));
        }
        if let (Some(t), Some(raw)) = (tcp, &g.visca_tcp) {
            if taken(t, true) {
                return Err(c.at(
                    raw.span(),
                    format!("{key}.visca_tcp"),
                    "expected an address no other gimbal uses: each gimbal is its own camera",
                ));
            }
        }
        let degrees_per_step = match &g.degrees_per_step {
            None => DEGREES_PER_STEP,
            Some(d) if (0.0001..=1.0).contains(d.get_ref()) => *d.get_ref(),
            Some(d) => {
                return Err(c.at(
                    d.span(),
                    format!("{key}.degrees_per_step"),
                    "expected degrees from 0.0001 to 1.0",
                ));
            }
        };
        Ok(Gimbal {
            name,
            address,
            udp,
            tcp,
            reuse_address: g.reuse_address,
            degrees_per_step,
            lens: g.lens,
        })
    })?;
    let lease = raw.motion_lease_ms.duration();
    Ok(Config {
        link: GcudLink::from(&keys),
        poll: keys.poll,
        lease: (!lease.is_zero()).then_some(lease),
        clients,
        gimbals,
    })
}

#[cfg(test)]
mod tests;
