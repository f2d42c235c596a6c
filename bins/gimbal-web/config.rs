//! `gimbal-web --config FILE`: the TOML configuration (every key is
//! documented in `config/gimbal-web.toml`), parsed with serde and then
//! validated; every error names the file, the line and column, the key and
//! what was expected (`--check` prints it and exits 2), through
//! [`sagebrush_service::config_file`] as the other doors'.

use sagebrush_client::session::GcudLink;
use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_protocol::Address;
use sagebrush_service::config_file::{ConfigError, Int, Millis, Source};
use sagebrush_service::door_config::{HttpBounds, HttpSection, UserSection};
pub use sagebrush_service::door_config::{Role, User};
use sagebrush_service::door_tls::DoorTls;
use serde::Deserialize;
use toml::Spanned;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    listen: Spanned<String>,
    state_file: Option<Spanned<String>>,
    #[serde(default)]
    hold_lease_ms: Millis<100, 2000, 300>,
    #[serde(default)]
    sign_in_hours: Int<u64, 1, 720, 12>,
    #[serde(default)]
    max_sign_ins: Int<usize, 1, 100_000, 256>,
    #[serde(default)]
    max_streams_per_user: Int<usize, 1, 100_000, 32>,
    #[serde(default)]
    secure_cookie: bool,
    #[serde(default)]
    http: HttpSection,
    #[serde(default, rename = "user")]
    users: Vec<UserSection>,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<GimbalSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GimbalSection {
    name: Spanned<String>,
    address: Spanned<String>,
    pan_deg: Option<Spanned<Vec<f64>>>,
    tilt_deg: Option<Spanned<Vec<f64>>>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Gimbal {
    pub name: String,
    pub address: Address,
    /// The travel the page's picture draws, degrees.
    pub pan_deg: (f64, f64),
    pub tilt_deg: (f64, f64),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// gcud, this door's source group and NIC window.
    pub link: GcudLink,
    pub listen: SocketAddr,
    pub state_file: Option<PathBuf>,
    /// How long a held move runs unless the page renews it: gimbal-web's
    /// own lease on the motion.
    pub hold_lease: Duration,
    /// How often each gimbal's position is asked (`P?`), pushed to pages.
    pub poll: Duration,
    /// How long a sign-in lasts.
    pub sign_in: Duration,
    /// Sign-ins kept at once (the oldest goes first).
    pub max_sign_ins: usize,
    /// Live-update streams (open pages) of one user at once (a user's new
    /// one past it ends that user's oldest).
    pub max_streams_per_user: usize,
    /// The reverse proxies whose `X-Forwarded-For` names the client.
    pub trusted_proxies: Vec<IpAddr>,
    /// The session cookie carries `Secure` (gimbal-web behind an HTTPS
    /// proxy; always with `tls`).
    pub secure_cookie: bool,
    /// `[http] tls`: the page in HTTPS.
    pub tls: Option<DoorTls>,
    pub http: HttpBounds,
    pub users: Vec<User>,
    pub gimbals: Vec<Gimbal>,
}

impl sagebrush_service::door::Checked for Config {
    fn summary(&self) -> String {
        format!(
            "{} gimbal(s), {} user(s), page on {}",
            self.gimbals.len(),
            self.users.len(),
            self.listen
        )
    }

    fn warnings(&self) -> Vec<String> {
        let mut w = sagebrush_service::door_config::demo_password_warnings(&self.users, &[self.listen]);
        w.extend(sagebrush_service::door_tls::plain_http_warnings(
            &[self.listen],
            self.tls.is_some(),
        ));
        w
    }
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let (keys, raw) = c.door_file::<ConfigFile, 100>()?;
    let listen = c.listen_address(&raw.listen, "listen")?;
    let users = c.users(&raw.users)?;
    let state_file = c.state_file(raw.state_file.as_ref())?;
    let tls = c.door_tls(&raw.http, "gimbal-web", state_file.as_deref(), &[listen])?;
    let gimbals = c.gimbals(&raw.gimbals, |g, key, before: &[Gimbal]| {
        let name = c.gimbal_name(&g.name, key, before.iter().map(|x| x.name.as_str()))?;
        let address = c.gimbal_address(&g.address, &format!("{key}.address"))?;
        let (pan_deg, tilt_deg) = c.pan_tilt_travel(g.pan_deg.as_ref(), g.tilt_deg.as_ref(), key)?;
        Ok(Gimbal {
            name,
            address,
            pan_deg,
            tilt_deg,
        })
    })?;
    Ok(Config {
        link: GcudLink::from(&keys),
        listen,
        state_file,
        hold_lease: raw.hold_lease_ms.duration(),
        poll: keys.poll,
        sign_in: Duration::from_secs(raw.sign_in_hours.get() * 3600),
        max_sign_ins: raw.max_sign_ins.get(),
        max_streams_per_user: raw.max_streams_per_user.get(),
        trusted_proxies: c.trusted_proxies(&raw.http)?,
        secure_cookie: raw.secure_cookie || tls.is_some(),
        tls,
        http: raw.http.bounds(),
        users,
        gimbals,
    })
}

#[cfg(test)]
mod tests;
