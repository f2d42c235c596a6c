//! `gimbal-pelco --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-pelco.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_service::config_file`] as the other doors'.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_client::session::GcudLink;
use sagebrush_protocol::Address;
use sagebrush_service::config_file::{self, Baud, ConfigError, Int, Millis, Source};
use sagebrush_service::endpoint::listeners_clash;
use serde::Deserialize;
use toml::Spanned;

use crate::codec::Protocol;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    /// 0: off.
    #[serde(default)]
    motion_lease_ms: Int<u64, 0, 60_000, 1000>,
    #[serde(default)]
    max_move_ms: Millis<100, 3_600_000, 60_000>,
    #[serde(default)]
    limits: LimitsSection,
    #[serde(default, rename = "input")]
    inputs: Vec<Spanned<InputSection>>,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsSection {
    #[serde(default)]
    max_connections: Int<usize, 1, 10_000, 16>,
    #[serde(default)]
    max_connections_per_peer: Int<usize, 1, 10_000, 4>,
    #[serde(default)]
    idle_timeout_ms: Millis<1000, 86_400_000, 600_000>,
    #[serde(default)]
    udp_sources: Int<usize, 1, 10_000, 64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct InputSection {
    serial: Option<Spanned<String>>,
    baud: Option<Baud<9600>>,
    tcp_listen: Option<Spanned<String>>,
    udp_listen: Option<Spanned<String>>,
    protocol: Spanned<String>,
    principal: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    pelco_address: Int<u8, 1, 255>,
    zoom: Option<Spanned<bool>>,
}

/// Where an input's frames come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Transport {
    /// A serial line (RS-485 through a USB adapter, an RS-232 port): the
    /// door is a device on it.
    Serial { path: PathBuf, baud: u32 },
    /// Raw frames over TCP (a serial server's TCP client mode, a DVR).
    TcpListen(SocketAddr),
    /// Raw frames in UDP datagrams.
    UdpListen(SocketAddr),
}

/// One `[[input]]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Input {
    pub transport: Transport,
    pub protocol: Protocol,
    /// The name gcud governs this input's commands as (a door over TLS
    /// that `acts_for_users`); `None`: the door's own.
    pub principal: Option<String>,
    /// Its name in logs: `input[0] serial /dev/ttyUSB0`.
    pub name: String,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    /// The address the keyboards call it by (1..=255).
    pub pelco_address: u8,
    /// It has a lens: the zoom keys drive it.
    pub zoom: bool,
}

/// `[limits]`: what the inputs facing the LAN may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    pub max_connections: usize,
    pub max_connections_per_peer: usize,
    pub idle_timeout: Duration,
    /// UDP sources whose partial frame is kept between datagrams.
    pub udp_sources: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    pub link: GcudLink,
    pub poll: Duration,
    /// A drive not repeated within this is stopped; `None`: off.
    pub lease: Option<Duration>,
    /// The longest any drive runs.
    pub max_move: Duration,
    pub limits: Limits,
    pub inputs: Vec<Input>,
    pub gimbals: Vec<Gimbal>,
    /// Each serial input's device and its place in the file (`--check`).
    pub serial_places: Vec<(PathBuf, String)>,
}

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        format!("{} input(s), {} gimbal(s)", self.inputs.len(), self.gimbals.len())
    }

    fn warnings(&self) -> Vec<String> {
        let mut w = config_file::absent_serial_devices(&self.serial_places, "gimbal-pelco");
        for i in &self.inputs {
            if let Transport::TcpListen(a) | Transport::UdpListen(a) = i.transport {
                if !a.ip().is_loopback() {
                    w.push(format!(
                        "{}: {a} is off loopback: Pelco has no authentication, whoever reaches it may move the gimbals (a firewall or a serial server's own access list should keep others out)",
                        i.name
                    ));
                }
            }
        }
        w
    }
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, 1000>()?;
    let (inputs, serial_places) = inputs(&c, &raw.inputs)?;
    let gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = c.gimbal_name(&g.name, key, before.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let pelco_address = g.pelco_address.get();
        if let Some(other) = before.iter().find(|x| x.pelco_address == pelco_address) {
            return Err(c.at(
                g.pelco_address.span(),
                format!("{key}.pelco_address"),
                format!("expected an address of its own: {pelco_address} is {}'s", other.name),
            ));
        }
        Ok(Gimbal {
            name,
            address,
            pelco_address,
            zoom: g.zoom.as_ref().is_some_and(|z| *z.get_ref()),
        })
    })?;
    let lease = match raw.motion_lease_ms.get() {
        0 => None,
        ms if ms < 100 => {
            return Err(c.at(
                raw.motion_lease_ms.span(),
                "motion_lease_ms",
                format!("expected 0 (off) or 100 to 60000, found {ms}"),
            ));
        }
        ms => Some(Duration::from_millis(ms)),
    };
    Ok(Config {
        link: GcudLink::from(&keys),
        poll: keys.poll,
        lease,
        max_move: raw.max_move_ms.duration(),
        limits: Limits {
            max_connections: raw.limits.max_connections.get(),
            max_connections_per_peer: raw.limits.max_connections_per_peer.get(),
            idle_timeout: raw.limits.idle_timeout_ms.duration(),
            udp_sources: raw.limits.udp_sources.get(),
        },
        inputs,
        gimbals,
        serial_places,
    })
}

type SerialPlaces = Vec<(PathBuf, String)>;

/// The `[[input]]`s, and each serial one's device and place in the file.
fn inputs(c: &Source, sections: &[Spanned<InputSection>]) -> Result<(Vec<Input>, SerialPlaces), ConfigError> {
    let mut inputs: Vec<Input> = Vec::new();
    let mut serial_places = Vec::new();
    for (i, section) in sections.iter().enumerate() {
        let key = format!("input[{i}]");
        let e = section.get_ref();
        let given = [
            e.serial.as_ref().map(|v| ("serial", v)),
            e.tcp_listen.as_ref().map(|v| ("tcp_listen", v)),
            e.udp_listen.as_ref().map(|v| ("udp_listen", v)),
        ];
        let mut given = given.into_iter().flatten();
        let (Some((kind, value)), None) = (given.next(), given.next()) else {
            return Err(c.at(
                section.span(),
                key,
                "expected exactly one of serial, tcp_listen or udp_listen",
            ));
        };
        if let (Some(b), false) = (&e.baud, kind == "serial") {
            return Err(c.at(b.span(), format!("{key}.baud"), "baud applies to a serial input only"));
        }
        let protocol = match e.protocol.get_ref().as_str() {
            "pelco-d" => Protocol::D,
            "pelco-p" => Protocol::P,
            other => {
                return Err(c.at(
                    e.protocol.span(),
                    format!("{key}.protocol"),
                    format!("expected \"pelco-d\" or \"pelco-p\", found {other:?}"),
                ));
            }
        };
        let place = format!("{key}.{kind}");
        let transport = match kind {
            "serial" => {
                let path = PathBuf::from(value.get_ref());
                if inputs
                    .iter()
                    .any(|x| matches!(&x.transport, Transport::Serial { path: p, .. } if *p == path))
                {
                    return Err(c.at(value.span(), place, "expected a serial device of its own"));
                }
                serial_places.push((path.clone(), c.place(value.span(), &place)));
                Transport::Serial {
                    path,
                    baud: e.baud.clone().unwrap_or_default().get(),
                }
            }
            _ => {
                let addr = c.listen_address(value, &place)?;
                let clash = inputs.iter().any(|x| match (&x.transport, kind) {
                    (Transport::TcpListen(a), "tcp_listen") | (Transport::UdpListen(a), "udp_listen") => {
                        listeners_clash(a, &addr)
                    }
                    _ => false,
                });
                if clash {
                    return Err(c.at(value.span(), place, "expected an address of its own"));
                }
                if kind == "tcp_listen" {
                    Transport::TcpListen(addr)
                } else {
                    Transport::UdpListen(addr)
                }
            }
        };
        let principal = match &e.principal {
            Some(p) if p.get_ref().is_empty() || p.get_ref().chars().any(char::is_control) => {
                return Err(c.at(
                    p.span(),
                    format!("{key}.principal"),
                    "expected a name, not empty and without control characters",
                ));
            }
            p => p.as_ref().map(|p| p.get_ref().clone()),
        };
        inputs.push(Input {
            name: format!("{key} {kind} {}", value.get_ref()),
            transport,
            protocol,
            principal,
        });
    }
    if inputs.is_empty() {
        return Err(c.at(0..0, "input", "expected at least one [[input]]"));
    }
    Ok((inputs, serial_places))
}

#[cfg(test)]
mod tests;
