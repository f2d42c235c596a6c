//! `[[principal]]`: the persons and tools gcud knows (ARCHITECTURE
//! "Principals"), and each link's `tls`: the certificates that encrypt
//! it and, with `client_ca`, name each connection's principal by its
//! client certificate's subject CN.

use std::path::PathBuf;
use std::sync::Arc;

use sagebrush_gcu::Principal;
use sagebrush_service::config_file::{Int, Source};
use serde::Deserialize;
use toml::Spanned;

use super::ConfigError;
use super::link::{Link, LinkTransport};

/// `[[principal]]`, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PrincipalSection {
    /// On a TLS link with `client_ca`: its client certificate's subject CN.
    name: Spanned<String>,
    /// 0..=100: the highest priority its commands hold (capped by its
    /// link's, and by the door's it comes through).
    #[serde(default)]
    priority: Int<u8, 0, { sagebrush_gcu::MAX_PRIORITY as i64 }, { sagebrush_gcu::DEFAULT_PRIORITY as i64 }>,
    /// A door: it may say on whose behalf each command is sent (`~U`).
    #[serde(default)]
    acts_for_users: bool,
}

/// A link's `tls = { ... }`, as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TlsSection {
    cert: Option<String>,
    key: Option<String>,
    /// A listener: clients must present a certificate signed by this CA.
    client_ca: Option<String>,
    /// A `connect` link: the CA that signed the server's certificate.
    ca: Option<String>,
}

/// A link's TLS, validated (the files are read again when it opens).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkTls {
    /// A listener: its certificate and key; with `client_ca`, a client
    /// certificate is required and names the principal.
    Server {
        cert: PathBuf,
        key: PathBuf,
        client_ca: Option<PathBuf>,
    },
    /// A `connect` link: the server's CA, and this GCU's own certificate
    /// and key when the server asks for one.
    Client {
        ca: PathBuf,
        identity: Option<(PathBuf, PathBuf)>,
    },
}

impl LinkTls {
    /// Reads the files now: an error names the file.
    pub fn check(&self) -> Result<(), sagebrush_host::tls::TlsError> {
        match self {
            LinkTls::Server { cert, key, client_ca } => {
                sagebrush_host::tls::acceptor(cert, key, client_ca.as_deref()).map(drop)
            }
            LinkTls::Client { ca, identity } => {
                let identity = identity.as_ref().map(|(c, k)| (c.as_path(), k.as_path()));
                sagebrush_host::tls::connector(ca, identity).map(drop)
            }
        }
    }
}

/// A link's `tls` against its transport: a listener needs `cert` and
/// `key`, a `connect` link `ca`; the files must be readable.
pub(super) fn link_tls(
    c: &Source<'_>,
    raw: &Spanned<TlsSection>,
    transport: &LinkTransport,
    key: &str,
) -> Result<LinkTls, ConfigError> {
    let t = raw.get_ref();
    let at = |message: String| c.at(raw.span(), format!("{key}.tls"), message);
    let path = |p: &Option<String>| p.as_deref().map(|p| PathBuf::from(p.trim()));
    let tls = match transport {
        LinkTransport::Listen(_) => match (path(&t.cert), path(&t.key), &t.ca) {
            (Some(cert), Some(key), None) => LinkTls::Server {
                cert,
                key,
                client_ca: path(&t.client_ca),
            },
            _ => {
                return Err(at(
                    "a listener's tls takes `cert` and `key` (its own), and `client_ca` to require client certificates"
                        .into(),
                ));
            }
        },
        LinkTransport::Connect(_) => match (path(&t.ca), path(&t.cert), path(&t.key), &t.client_ca) {
            (Some(ca), cert, key, None) if cert.is_some() == key.is_some() => LinkTls::Client {
                ca,
                identity: cert.zip(key),
            },
            _ => {
                return Err(at(
                    "a `connect` link's tls takes `ca` (the server's), and `cert` with `key` to present its own".into(),
                ));
            }
        },
        LinkTransport::Serial { .. } => return Err(at("`tls` applies to a `listen` or `connect` link only".into())),
    };
    tls.check().map_err(|e| at(e.to_string()))?;
    Ok(tls)
}

/// The warning for a listener off loopback at `addr` (link `name` of
/// `priority`) that anyone who reaches it may use as that link.
pub(super) fn open_listener(
    tls: Option<&LinkTls>,
    addr: std::net::SocketAddr,
    name: &str,
    priority: u8,
) -> Option<String> {
    match tls {
        None => Some(format!(
            "plain TCP off loopback: whoever reaches {addr} is link {name:?} (priority {priority}) and reads \
             its traffic; configure `tls = {{ cert, key, client_ca }}`"
        )),
        Some(LinkTls::Server { client_ca: None, .. }) => Some(format!(
            "tls without `client_ca`: encrypted, but whoever reaches {addr} is link {name:?} (priority {priority})"
        )),
        Some(_) => None,
    }
}

/// Every `[[principal]]`: names unique, valid in GCU commands, and apart
/// from every link's (a link without principals is a controller by its name).
pub(super) fn validate(
    c: &Source<'_>,
    raw: &[PrincipalSection],
    links: &[Link],
) -> Result<Vec<Principal>, ConfigError> {
    let mut principals: Vec<Principal> = Vec::with_capacity(raw.len());
    for (i, p) in raw.iter().enumerate() {
        let key = format!("principal[{i}].name");
        let name = p.name.get_ref();
        if !sagebrush_protocol::gcu::valid_name(name.as_bytes()) {
            return Err(c.at(
                p.name.span(),
                key,
                format!("expected 1..=32 of A-Z a-z 0-9 _ - (a client certificate's CN), found {name:?}"),
            ));
        }
        if principals.iter().any(|q| &*q.name == name) {
            return Err(c.at(p.name.span(), key, format!("principal {name:?} is configured twice")));
        }
        if links.iter().any(|l| &l.name == name) {
            return Err(c.at(
                p.name.span(),
                key,
                format!("{name:?} names a [[link]] too: a principal and a link would be one controller"),
            ));
        }
        principals.push(Principal {
            name: Arc::from(name.as_str()),
            priority: p.priority.get(),
            acts_for_users: p.acts_for_users,
        });
    }
    Ok(principals)
}
