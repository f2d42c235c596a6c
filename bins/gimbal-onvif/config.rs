//! `gimbal-onvif --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-onvif.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_service::config_file`] as gcud's.

use sagebrush_client::session::GcudLink;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_protocol::Address;
use sagebrush_service::config_file::{ConfigError, Int, Millis, Source};
pub use sagebrush_service::door_config::HttpBounds;
use sagebrush_service::door_config::{HttpSection, UserSection};
pub use sagebrush_service::door_config::{Role, User};
pub use sagebrush_service::door_tls::DoorTls;
use sagebrush_service::endpoint::listeners_clash;
use serde::Deserialize;
use toml::Spanned;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    state_file: Option<Spanned<String>>,
    #[serde(default)]
    max_move_ms: Millis<100, 600_000, 10_000>,
    #[serde(default)]
    discovery: DiscoverySection,
    #[serde(default)]
    http: HttpSection,
    #[serde(default)]
    auth: AuthSection,
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
    #[serde(default)]
    answers_per_s: Int<u32, 1, 10_000, 20>,
    #[serde(default)]
    answers_per_source_per_s: Int<u32, 1, 10_000, 2>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AuthSection {
    #[serde(default)]
    requests_per_s: Int<u32, 1, 1_000_000, 20>,
    #[serde(default)]
    burst: Int<u32, 1, 1_000_000, 40>,
    #[serde(default)]
    nonce_cache: Int<usize, 16, 10_000_000, 65_536>,
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
    fov_deg: Option<Spanned<Vec<f64>>>,
    fov_tele_deg: Option<Spanned<Vec<f64>>>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    pub listen: SocketAddr,
    pub stream_uri: Option<String>,
    /// The bounds of the HTTP listeners (`[http]`, the same for every gimbal).
    pub http: HttpBounds,
    /// Served in HTTPS (`[http] tls`): its XAddrs say https.
    pub https: bool,
    /// The travel ONVIF's generic space [-1, 1] maps onto, degrees.
    pub pan_deg: (f64, f64),
    pub tilt_deg: (f64, f64),
    /// The gimbal has a lens: zoom through `ZI`/`ZO`/`ZS`, `Zn`, `V`, `V?`.
    pub zoom: bool,
    /// The camera's horizontal and vertical field of view, degrees: with
    /// it, RelativeMove offers the FOV translation space (ONVIF PTZ,
    /// "Pan/tilt Translation Space in FOV"), at the lens's wide end.
    pub fov_deg: Option<(f64, f64)>,
    /// With a lens (`zoom`), the field of view at its tele end (zoom
    /// 4095): the FOV space then follows the zoom (`onvif::spaces::fov_at`).
    pub fov_tele_deg: Option<(f64, f64)>,
}

/// `[auth]`: what one user may make the door spend, and the replay memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AuthBounds {
    /// Authenticated requests a second per user (token bucket rate).
    pub requests_per_s: u32,
    /// Requests a user may make at once before the rate applies.
    pub burst: u32,
    /// WS-Security nonces (and HTTP Digest nonce counts) remembered at
    /// most; when full, new requests are refused, none is forgotten early.
    pub nonce_cache: usize,
}

/// The users and the bounds their requests are held to.
#[derive(Clone, Debug, PartialEq)]
pub struct Users {
    pub list: Vec<User>,
    pub bounds: AuthBounds,
}

/// `[discovery]` when enabled: where, and how often it answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DiscoveryConfig {
    pub listen: SocketAddr,
    /// Probe answers a second in all (token bucket, burst one second's worth).
    pub answers_per_s: u32,
    /// Probe answers a second to one source address.
    pub answers_per_source_per_s: u32,
}

impl std::fmt::Display for DiscoveryConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.listen.fmt(f)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// gcud, this door's source group and NIC window.
    pub link: GcudLink,
    pub state_file: Option<PathBuf>,
    /// The longest a ContinuousMove without a Timeout runs.
    pub max_move: Duration,
    /// How often each gimbal's position is asked (`P?`) for GetStatus.
    pub poll: Duration,
    pub discovery: Option<DiscoveryConfig>,
    /// `[http] tls`: every gimbal's device in HTTPS.
    pub tls: Option<DoorTls>,
    pub users: Users,
    pub gimbals: Vec<Gimbal>,
}

/// The WS-Discovery port and multicast group (WS-Discovery 1.1, 3.1.1).
pub const DISCOVERY_DEFAULT: &str = "0.0.0.0:3702";

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        format!("{} gimbal(s), {} user(s)", self.gimbals.len(), self.users.list.len())
    }

    fn warnings(&self) -> Vec<String> {
        let listeners: Vec<SocketAddr> = self.gimbals.iter().map(|g| g.listen).collect();
        let mut w = sagebrush_service::door_config::demo_password_warnings(&self.users.list, &listeners);
        w.extend(sagebrush_service::door_tls::plain_http_warnings(
            &listeners,
            self.tls.is_some(),
        ));
        w
    }
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, 200>()?;
    let discovery = match raw.discovery.enabled.as_ref().map(|e| *e.get_ref()) {
        Some(false) => None,
        _ => Some(DiscoveryConfig {
            listen: match &raw.discovery.listen {
                Some(l) => c.listen_address(l, "discovery.listen")?,
                None => DISCOVERY_DEFAULT.parse().expect("a socket address"),
            },
            answers_per_s: raw.discovery.answers_per_s.get(),
            answers_per_source_per_s: raw.discovery.answers_per_source_per_s.get(),
        }),
    };
    c.no_trusted_proxy(&raw.http, "gimbal-onvif")?;
    let http = raw.http.bounds();
    let state_file = c.state_file(raw.state_file.as_ref())?;
    let users = c.users(&raw.users)?;
    let mut gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = c.gimbal_name(&g.name, key, before.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let listen = c.listen_address(&g.listen, &format!("{key}.listen"))?;
        if before.iter().any(|x| listeners_clash(&x.listen, &listen)) {
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
        let (pan_deg, tilt_deg) = c.pan_tilt_travel(g.pan_deg.as_ref(), g.tilt_deg.as_ref(), key)?;
        let fov_deg = field_of_view(&c, g.fov_deg.as_ref(), &format!("{key}.fov_deg"))?;
        let fov_tele_deg = field_of_view(&c, g.fov_tele_deg.as_ref(), &format!("{key}.fov_tele_deg"))?;
        let zoom = g.zoom.as_ref().is_some_and(|z| *z.get_ref());
        if let (Some(tele), Some(spanned)) = (fov_tele_deg, &g.fov_tele_deg) {
            let wide_ok = fov_deg.is_some_and(|w| tele.0 <= w.0 && tele.1 <= w.1);
            if !zoom || !wide_ok {
                return Err(c.at(
                    spanned.span(),
                    format!("{key}.fov_tele_deg"),
                    "expected with zoom = true and fov_deg, and no wider than fov_deg (the tele end of the same lens)",
                ));
            }
        }
        Ok(Gimbal {
            name,
            address,
            listen,
            stream_uri,
            pan_deg,
            tilt_deg,
            http,
            https: false,
            zoom,
            fov_deg,
            fov_tele_deg,
        })
    })?;
    let listens: Vec<SocketAddr> = gimbals.iter().map(|g| g.listen).collect();
    let tls = c.door_tls(&raw.http, "gimbal-onvif", state_file.as_deref(), &listens)?;
    for g in &mut gimbals {
        g.https = tls.is_some();
    }
    Ok(Config {
        link: GcudLink::from(&keys),
        state_file,
        max_move: raw.max_move_ms.duration(),
        poll: keys.poll,
        discovery,
        tls,
        users: Users {
            list: users,
            bounds: AuthBounds {
                requests_per_s: raw.auth.requests_per_s.get(),
                burst: raw.auth.burst.get(),
                nonce_cache: raw.auth.nonce_cache.get(),
            },
        },
        gimbals,
    })
}

/// A field of view, `[HORIZONTAL, VERTICAL]` degrees.
fn field_of_view(c: &Source<'_>, v: Option<&Spanned<Vec<f64>>>, key: &str) -> Result<Option<(f64, f64)>, ConfigError> {
    let Some(f) = v else { return Ok(None) };
    match f.get_ref().as_slice() {
        [h, v] if *h > 0.0 && *h <= 360.0 && *v > 0.0 && *v <= 180.0 => Ok(Some((*h, *v))),
        other => Err(c.at(
            f.span(),
            key,
            format!(
                "expected [HORIZONTAL, VERTICAL] degrees, 0 < HORIZONTAL <= 360 and 0 < VERTICAL <= 180, found {other:?}"
            ),
        )),
    }
}

#[cfg(test)]
mod tests;
