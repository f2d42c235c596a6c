//! `gimbal-mqtt --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-mqtt.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_service::config_file`] as the other doors'.

use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_client::session::GcudLink;
use sagebrush_protocol::Address;
use sagebrush_service::config_file::{ConfigError, Int, Millis, Source, Travel};
use serde::Deserialize;
use toml::Spanned;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    site: Spanned<String>,
    #[serde(default)]
    prefix: Option<Spanned<String>>,
    #[serde(default)]
    discovery_prefix: Option<Spanned<String>>,
    user: Option<Spanned<String>>,
    #[serde(default)]
    max_slew_ms: Millis<100, 60_000, 5000>,
    broker: BrokerSection,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BrokerSection {
    url: Spanned<String>,
    version: Option<Spanned<String>>,
    client_id: Option<Spanned<String>>,
    username: Option<Spanned<String>>,
    password_file: Option<Spanned<String>>,
    ca: Option<Spanned<String>>,
    client_cert: Option<Spanned<String>>,
    client_key: Option<Spanned<String>>,
    #[serde(default)]
    keep_alive_s: Int<u64, 5, 3600, 30>,
    #[serde(default)]
    reconnect_min_ms: Millis<100, 60_000, 500>,
    #[serde(default)]
    reconnect_max_ms: Millis<100, 600_000, 30_000>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    pan_deg: Option<Spanned<Vec<f64>>>,
    tilt_deg: Option<Spanned<Vec<f64>>>,
    presets: Option<Spanned<Vec<i64>>>,
}

/// The MQTT protocol version spoken to the broker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Version {
    V311,
    V5,
}

/// `[broker]`: where the broker is and how the door signs in.
#[derive(Clone, Debug, PartialEq)]
pub struct Broker {
    /// The URL as written (for logs).
    pub url: String,
    pub host: String,
    pub port: u16,
    pub version: Version,
    pub client_id: String,
    /// Username and the password read from `password_file`.
    pub credentials: Option<(String, String)>,
    /// `mqtts://`: the CA of the broker's certificate and the door's
    /// own certificate and key.
    pub tls: Option<BrokerTls>,
    pub keep_alive: Duration,
    pub reconnect_min: Duration,
    pub reconnect_max: Duration,
}

#[derive(Clone, Debug, PartialEq)]
pub struct BrokerTls {
    pub ca: PathBuf,
    pub identity: Option<(PathBuf, PathBuf)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    /// Its topic segment.
    pub name: String,
    pub address: Address,
    /// The travel Home Assistant's numbers offer, degrees.
    pub pan_deg: Travel,
    pub tilt_deg: Travel,
    /// The presets Home Assistant's select offers.
    pub presets: Vec<u8>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    pub link: GcudLink,
    pub site: String,
    pub prefix: String,
    /// `None`: Home Assistant discovery off.
    pub discovery_prefix: Option<String>,
    /// The gcud principal the broker's commands are for (`~U`, over TLS).
    pub user: Option<String>,
    pub poll: Duration,
    pub max_slew: Duration,
    pub broker: Broker,
    pub gimbals: Vec<Gimbal>,
}

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        format!(
            "site {}, {} gimbal(s), broker {}",
            self.site,
            self.gimbals.len(),
            self.broker.url
        )
    }

    fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.user.is_some() && self.link.gcud.tls.is_none() {
            w.push(
                "user: gcud is reached without TLS, where the door is no principal: its commands go as its link, not as this user"
                    .to_owned(),
            );
        }
        if self.broker.tls.is_none() && self.broker.credentials.is_some() && !is_loopback(&self.broker.host) {
            w.push(format!(
                "broker.url: the password goes to {} in clear (mqtt://); use mqtts://",
                self.broker.host
            ));
        }
        w
    }
}

fn is_loopback(host: &str) -> bool {
    host == "localhost" || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// A topic segment: 1..=32 of `A-Z a-z 0-9 _ -` (no `/`, `+`, `#`).
fn segment(c: &Source<'_>, v: &Spanned<String>, key: &str) -> Result<String, ConfigError> {
    let s = v.get_ref();
    let ok = (1..=32).contains(&s.len()) && s.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if !ok {
        return Err(c.at(
            v.span(),
            key,
            format!("expected 1 to 32 of A-Z a-z 0-9 _ -, found {s:?}"),
        ));
    }
    Ok(s.clone())
}

/// A topic prefix: levels of [`segment`]s joined by `/`.
fn topic_prefix(c: &Source<'_>, v: Option<&Spanned<String>>, key: &str, default: &str) -> Result<String, ConfigError> {
    let Some(v) = v else { return Ok(default.to_owned()) };
    let s = v.get_ref();
    if s.is_empty() {
        return Ok(String::new());
    }
    for level in s.split('/') {
        segment(c, &Spanned::new(v.span(), level.to_owned()), key).map_err(|_| {
            c.at(
                v.span(),
                key,
                format!("expected topic levels of A-Z a-z 0-9 _ - joined by /, found {s:?}"),
            )
        })?;
    }
    Ok(s.clone())
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, 100>()?;
    let site = segment(&c, &raw.site, "site")?;
    let prefix = topic_prefix(&c, raw.prefix.as_ref(), "prefix", "sagebrush")?;
    if prefix.is_empty() {
        return Err(c.at(
            raw.prefix.as_ref().map_or(0..0, |p| p.span()),
            "prefix",
            "expected a topic prefix, not empty",
        ));
    }
    let discovery = topic_prefix(&c, raw.discovery_prefix.as_ref(), "discovery_prefix", "homeassistant")?;
    let user = match &raw.user {
        Some(u) if u.get_ref().is_empty() || u.get_ref().len() > 64 || u.get_ref().chars().any(char::is_whitespace) => {
            return Err(c.at(
                u.span(),
                "user",
                "expected a principal's name: 1 to 64 characters, no spaces",
            ));
        }
        u => u.as_ref().map(|u| u.get_ref().clone()),
    };
    let broker = broker(&c, &raw.broker, &site)?;
    let gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = segment(&c, &g.name, &format!("{key}.name"))?;
        let name = c.gimbal_name(
            &Spanned::new(g.name.span(), name),
            key,
            before.iter().map(|x| x.name.as_str()),
        )?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let (pan_deg, tilt_deg) = c.pan_tilt_travel(g.pan_deg.as_ref(), g.tilt_deg.as_ref(), key)?;
        let presets = match &g.presets {
            None => (1..=8).collect(),
            Some(p) => {
                let list: Option<Vec<u8>> = p.get_ref().iter().map(|n| u8::try_from(*n).ok()).collect();
                match list {
                    Some(l) if !l.is_empty() && l.len() <= 256 => l,
                    _ => {
                        return Err(c.at(
                            p.span(),
                            format!("{key}.presets"),
                            "expected a list of preset numbers 0..=255, not empty",
                        ));
                    }
                }
            }
        };
        Ok(Gimbal {
            name,
            address,
            pan_deg,
            tilt_deg,
            presets,
        })
    })?;
    Ok(Config {
        link: GcudLink::from(&keys),
        site,
        prefix,
        discovery_prefix: (!discovery.is_empty()).then_some(discovery),
        user,
        poll: keys.poll,
        max_slew: raw.max_slew_ms.duration(),
        broker,
        gimbals,
    })
}

/// `[broker]`: its URL, version, sign-in and TLS files, each read now so
/// that an error names it.
fn broker(c: &Source<'_>, b: &BrokerSection, site: &str) -> Result<Broker, ConfigError> {
    let url = b.url.get_ref();
    let bad = |why: &str| {
        c.at(
            b.url.span(),
            "broker.url",
            format!("expected mqtt://HOST[:PORT] or mqtts://HOST[:PORT]: {why}"),
        )
    };
    let (tls, rest) = if let Some(r) = url.strip_prefix("mqtts://") {
        (true, r)
    } else if let Some(r) = url.strip_prefix("mqtt://") {
        (false, r)
    } else {
        return Err(bad(&format!("{url:?} has neither scheme")));
    };
    let rest = rest.strip_suffix('/').unwrap_or(rest);
    let (host, port) = match rest.rsplit_once(':') {
        Some((h, p)) if !h.ends_with(']') || rest.starts_with('[') => (
            h.to_owned(),
            p.parse::<u16>().map_err(|_| bad(&format!("{p:?} is not a port")))?,
        ),
        _ => (rest.to_owned(), if tls { 8883 } else { 1883 }),
    };
    let host = host.trim_start_matches('[').trim_end_matches(']').to_owned();
    if host.is_empty() || host.contains('/') || port == 0 {
        return Err(bad("no host, or a path"));
    }
    let version = match b.version.as_ref().map(|v| v.get_ref().as_str()) {
        None | Some("5") => Version::V5,
        Some("3.1.1") => Version::V311,
        Some(other) => {
            let span = b.version.as_ref().map_or(0..0, |v| v.span());
            return Err(c.at(
                span,
                "broker.version",
                format!("expected \"5\" or \"3.1.1\", found {other:?}"),
            ));
        }
    };
    let client_id = match &b.client_id {
        Some(id) if id.get_ref().is_empty() || id.get_ref().len() > 64 => {
            return Err(c.at(id.span(), "broker.client_id", "expected 1 to 64 characters"));
        }
        Some(id) => id.get_ref().clone(),
        None => format!("gimbal-mqtt-{site}"),
    };
    let credentials = match (&b.username, &b.password_file) {
        (None, None) => None,
        (Some(u), Some(f)) => {
            let text = std::fs::read_to_string(f.get_ref()).map_err(|e| {
                c.at(
                    f.span(),
                    "broker.password_file",
                    format!("cannot read {}: {e}", f.get_ref()),
                )
            })?;
            let password = text.trim_end_matches(['\n', '\r']).to_owned();
            if password.is_empty() {
                return Err(c.at(f.span(), "broker.password_file", format!("{} is empty", f.get_ref())));
            }
            Some((u.get_ref().clone(), password))
        }
        (Some(u), None) => return Err(c.at(u.span(), "broker.username", "expected password_file with it")),
        (None, Some(f)) => return Err(c.at(f.span(), "broker.password_file", "expected username with it")),
    };
    let tls = broker_tls(c, b, tls)?;
    if b.reconnect_max_ms.get() < b.reconnect_min_ms.get() {
        return Err(c.at(
            b.reconnect_max_ms.span(),
            "broker.reconnect_max_ms",
            "expected at least reconnect_min_ms",
        ));
    }
    Ok(Broker {
        url: url.clone(),
        host,
        port,
        version,
        client_id,
        credentials,
        tls,
        keep_alive: Duration::from_secs(b.keep_alive_s.get()),
        reconnect_min: b.reconnect_min_ms.duration(),
        reconnect_max: b.reconnect_max_ms.duration(),
    })
}

/// The CA bundle of Debian's `ca-certificates`: `mqtts://` without `ca`
/// trusts the public authorities (a hosted broker).
pub const SYSTEM_CA: &str = "/etc/ssl/certs/ca-certificates.crt";

/// `ca`, `client_cert` and `client_key` with `mqtts://` (checked now with
/// the rustls configuration they make), none without it.
fn broker_tls(c: &Source<'_>, b: &BrokerSection, tls: bool) -> Result<Option<BrokerTls>, ConfigError> {
    if !tls {
        for (v, key) in [
            (&b.ca, "broker.ca"),
            (&b.client_cert, "broker.client_cert"),
            (&b.client_key, "broker.client_key"),
        ] {
            if let Some(v) = v {
                return Err(c.at(v.span(), key, "only with an mqtts:// url"));
            }
        }
        return Ok(None);
    }
    let ca =
        b.ca.as_ref()
            .map_or_else(|| PathBuf::from(SYSTEM_CA), |ca| PathBuf::from(ca.get_ref()));
    let (ca_span, ca_key) = match &b.ca {
        Some(v) => (v.span(), "broker.ca"),
        None => (b.url.span(), "broker.ca (default /etc/ssl/certs/ca-certificates.crt)"),
    };
    let only_ca = BrokerTls {
        ca: ca.clone(),
        identity: None,
    };
    crate::broker::rustls_config(&only_ca).map_err(|e| c.at(ca_span, ca_key, e))?;
    let identity = match (&b.client_cert, &b.client_key) {
        (Some(cert), Some(key)) => Some((PathBuf::from(cert.get_ref()), PathBuf::from(key.get_ref()), cert.span())),
        (None, None) => None,
        (Some(v), None) | (None, Some(v)) => {
            return Err(c.at(
                v.span(),
                "broker.client_cert",
                "expected client_cert and client_key together",
            ));
        }
    };
    let tls = BrokerTls {
        ca,
        identity: identity.as_ref().map(|(c, k, _)| (c.clone(), k.clone())),
    };
    if let Some((_, _, span)) = identity {
        crate::broker::rustls_config(&tls).map_err(|e| c.at(span, "broker.client_cert", e))?;
    }
    Ok(Some(tls))
}

#[cfg(test)]
mod tests;
