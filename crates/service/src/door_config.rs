//! The configuration pieces the front doors share: every door's
//! `[[gimbal]]` tables (at least one); for the doors with users
//! (gimbal-onvif, gimbal-web) the `[[user]]` tables with their roles and
//! passwords (inline or in a file beside the configuration), the state
//! file the door keeps its preset names in, each validated at its place as
//! [`crate::config_file`] does, and `[http]`, the bounds of the door's
//! listener on the LAN ([`crate::http`]).

use std::net::IpAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use crate::{Connections, HttpLimits, Limits};

use serde::Deserialize;
use toml::Spanned;

use crate::config_file::Int;
use crate::config_file::{ConfigError, Millis, Source};

/// One `[[user]]` table, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UserSection {
    name: Spanned<String>,
    password: Option<Spanned<String>>,
    password_file: Option<Spanned<String>>,
    role: Spanned<String>,
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

impl Role {
    /// The name the configuration uses.
    pub fn name(self) -> &'static str {
        match self {
            Role::User => "user",
            Role::Operator => "operator",
            Role::Administrator => "administrator",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct User {
    pub name: String,
    pub password: String,
    pub role: Role,
}

/// The passwords of the shipped configurations and the README's demo
/// (`config/gimbal-onvif.toml`, `config/gimbal-web.toml`): whoever read
/// them knows them.
pub const DEMO_PASSWORDS: [&str; 3] = ["change-me", "change-me-too", "change-me-admin"];

/// `--check`'s warnings: each user whose password is a demo one while one
/// of `listeners` is not on loopback, i.e. serves the LAN.
pub fn demo_password_warnings(users: &[User], listeners: &[std::net::SocketAddr]) -> Vec<String> {
    let Some(open) = listeners.iter().find(|l| !l.ip().is_loopback()) else {
        return Vec::new();
    };
    users
        .iter()
        .filter(|u| DEMO_PASSWORDS.contains(&u.password.as_str()))
        .map(|u| {
            format!(
                "user {:?} has the shipped demo password while {open} serves the network: change it",
                u.name
            )
        })
        .collect()
}

impl Source<'_> {
    /// The `[[gimbal]]` tables, each read by `each` with its key
    /// (`gimbal[i]`) and the gimbals read before it; at least one.
    pub fn gimbals<S, G>(
        &self,
        sections: &[S],
        mut each: impl FnMut(&S, &str, &[G]) -> Result<G, ConfigError>,
    ) -> Result<Vec<G>, ConfigError> {
        let mut gimbals = Vec::with_capacity(sections.len());
        for (i, section) in sections.iter().enumerate() {
            let gimbal = each(section, &format!("gimbal[{i}]"), &gimbals)?;
            gimbals.push(gimbal);
        }
        if gimbals.is_empty() {
            return Err(self.at(0..0, "gimbal", "expected at least one [[gimbal]]"));
        }
        Ok(gimbals)
    }

    /// The `[[user]]` tables: each name given once, exactly one of
    /// `password` or `password_file` (its text without the final line
    /// break), not empty, and a role; at least one user.
    pub fn users(&self, raw: &[UserSection]) -> Result<Vec<User>, ConfigError> {
        let mut users = Vec::new();
        for (i, u) in raw.iter().enumerate() {
            let key = format!("user[{i}]");
            let name = u.name.get_ref().clone();
            if name.is_empty() || users.iter().any(|x: &User| x.name == name) {
                return Err(self.at(
                    u.name.span(),
                    format!("{key}.name"),
                    "expected a name, not empty and not repeated",
                ));
            }
            let password = match (&u.password, &u.password_file) {
                (Some(p), None) => p.get_ref().clone(),
                (None, Some(f)) => {
                    let text = std::fs::read_to_string(f.get_ref()).map_err(|e| {
                        self.at(
                            f.span(),
                            format!("{key}.password_file"),
                            format!("cannot read {}: {e}", f.get_ref()),
                        )
                    })?;
                    text.trim_end_matches(['\n', '\r']).to_owned()
                }
                _ => {
                    return Err(self.at(
                        u.name.span(),
                        key,
                        "expected exactly one of `password` or `password_file`",
                    ));
                }
            };
            if password.is_empty() {
                return Err(self.at(
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
                    return Err(self.at(
                        u.role.span(),
                        format!("{key}.role"),
                        format!("expected administrator, operator or user, found {other:?}"),
                    ));
                }
            };
            users.push(User { name, password, role });
        }
        if users.is_empty() {
            return Err(self.at(
                0..0,
                "user",
                "expected at least one [[user]]: the door serves its users only",
            ));
        }
        Ok(users)
    }

    /// The preset state file: `state_file`, else
    /// `$STATE_DIRECTORY/presets.toml` when systemd gives the unit a state
    /// directory, else none. Its folder must exist and be writable by this
    /// process (the names are written there at every change; finding out
    /// then would lose one).
    pub fn state_file(&self, key: Option<&Spanned<String>>) -> Result<Option<PathBuf>, ConfigError> {
        let (path, span, key) = match key {
            Some(s) => (PathBuf::from(s.get_ref()), s.span(), "state_file"),
            None => match std::env::var_os("STATE_DIRECTORY") {
                // systemd may list several, separated by ':'; the first is ours.
                Some(dirs) => match dirs.to_string_lossy().split(':').next() {
                    Some(dir) if !dir.is_empty() => (
                        Path::new(dir).join("presets.toml"),
                        0..0,
                        "state_file (default $STATE_DIRECTORY/presets.toml)",
                    ),
                    _ => return Ok(None),
                },
                None => return Ok(None),
            },
        };
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !folder.is_dir() {
            return Err(self.at(
                span,
                key,
                format!(
                    "{}: its folder {} does not exist (create it, or give a path in an existing folder)",
                    path.display(),
                    folder.display()
                ),
            ));
        }
        if let Err(e) = nix::unistd::access(&folder, nix::unistd::AccessFlags::W_OK) {
            return Err(self.at(
                span,
                key,
                format!(
                    "{}: its folder {} is not writable by this process: {e}",
                    path.display(),
                    folder.display()
                ),
            ));
        }
        if path.is_dir() {
            return Err(self.at(span, key, format!("{}: is a folder, expected a file", path.display())));
        }
        Ok(Some(path))
    }
}

/// `[http]`, as written: the bounds of a door's listener on the LAN.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpSection {
    #[serde(default)]
    max_connections: Int<usize, 1, 100_000, 512>,
    #[serde(default)]
    max_connections_per_peer: Int<usize, 1, 100_000, 64>,
    #[serde(default)]
    header_timeout_ms: Millis<100, 600_000, 5000>,
    #[serde(default)]
    body_timeout_ms: Millis<100, 600_000, 10_000>,
    #[serde(default)]
    idle_timeout_ms: Millis<1000, 3_600_000, 60_000>,
    /// The reverse proxy (or proxies) whose `X-Forwarded-For` names the
    /// client: an IP address or a list of them (gimbal-web only).
    trusted_proxy: Option<Spanned<toml::Value>>,
    /// HTTPS: `"self-signed"` or `{ cert, key }` ([`crate::door_tls`]).
    pub(crate) tls: Option<Spanned<toml::Value>>,
}

impl HttpSection {
    /// The bounds it sets.
    pub fn bounds(&self) -> HttpBounds {
        HttpBounds {
            max_connections: self.max_connections.get(),
            max_connections_per_peer: self.max_connections_per_peer.get(),
            header_timeout: self.header_timeout_ms.duration(),
            body_timeout: self.body_timeout_ms.duration(),
            idle_timeout: self.idle_timeout_ms.duration(),
        }
    }
}

impl Source<'_> {
    /// `[http] trusted_proxy`: one IP address or a list of them (an
    /// IPv4-mapped IPv6 address is its IPv4 one); none when absent.
    pub fn trusted_proxies(&self, http: &HttpSection) -> Result<Vec<IpAddr>, ConfigError> {
        let Some(v) = &http.trusted_proxy else {
            return Ok(Vec::new());
        };
        let expected = "expected an IP address or a list of them, e.g. \"127.0.0.1\" or [\"10.0.0.2\", \"::1\"]";
        let items: Vec<&toml::Value> = match v.get_ref() {
            toml::Value::Array(a) => a.iter().collect(),
            one => vec![one],
        };
        items
            .into_iter()
            .map(|item| {
                item.as_str()
                    .and_then(|s| s.trim().parse::<IpAddr>().ok())
                    .map(|ip| ip.to_canonical())
                    .ok_or_else(|| self.at(v.span(), "http.trusted_proxy", expected))
            })
            .collect()
    }

    /// Refuses `[http] trusted_proxy` in a door that does not read
    /// `X-Forwarded-For` (it would be believed to, and is not).
    pub fn no_trusted_proxy(&self, http: &HttpSection, door: &str) -> Result<(), ConfigError> {
        match &http.trusted_proxy {
            Some(v) => Err(self.at(
                v.span(),
                "http.trusted_proxy",
                format!("{door} does not read X-Forwarded-For: remove it"),
            )),
            None => Ok(()),
        }
    }
}

/// `[http]`: the bounds of a door's listener on the LAN.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HttpBounds {
    pub max_connections: usize,
    pub max_connections_per_peer: usize,
    pub header_timeout: Duration,
    pub body_timeout: Duration,
    pub idle_timeout: Duration,
}

impl HttpBounds {
    /// The admission table of these bounds. A door faces the LAN: every
    /// address is its own peer, loopback too.
    pub fn table(&self) -> Arc<Connections> {
        Connections::new(Limits {
            max_total: self.max_connections,
            max_per_peer: self.max_connections_per_peer,
            cap_loopback: true,
            idle_timeout: self.idle_timeout,
        })
    }

    /// The HTTP time-outs of these bounds (buffers at the listener's
    /// defaults; a TLS handshake within the header time-out).
    pub fn limits(&self) -> HttpLimits {
        HttpLimits {
            handshake_timeout: self.header_timeout,
            header_timeout: self.header_timeout,
            body_timeout: self.body_timeout,
            ..HttpLimits::default()
        }
    }
}
