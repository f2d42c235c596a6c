//! `[link_timing]` and `[[link]]`: the links toward the MCU, other GCUs and
//! clients, validated into what the router core takes ([`LinkKind`],
//! [`LinkConfig`], [`LinkSettings`]).

use std::collections::BTreeSet;
use std::net::SocketAddr;
use std::path::PathBuf;

use sagebrush_gcu::{LinkConfig, LinkKind, LinkSettings, SourceFilter};
use sagebrush_service::config_file::{Baud, Int, Millis, Source, checked};
use serde::{Deserialize, Deserializer, Serialize};
use toml::Spanned;

use super::net::{PeerAllowList, loopback, peers, socket};
use super::{Checks, ConfigError};

/// `[link_timing]`: retransmission on every link (router-wide), as written
/// and as validated; defaults are the router core's.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LinkTimingSection {
    #[serde(default)]
    pub retries: Int<u8, 0, 20, { LinkSettings::RETRIES as i64 }>,
    /// 10 ms to 10 s.
    #[serde(default)]
    pub ack_timeout_ms: Millis<10, 10_000, { LinkSettings::ACK_TIMEOUT_MS as i64 }>,
    /// A client's ACK or report comes at the latest this long after its
    /// command (ARCHITECTURE "Delivery contract"); below the clients' own
    /// ACK time-out. 50 ms to 1 minute.
    #[serde(default)]
    pub delivery_timeout_ms: Millis<50, 60_000, { LinkSettings::DELIVERY_TIMEOUT_MS as i64 }>,
}

impl LinkTimingSection {
    /// The router core's link settings.
    pub fn router(&self) -> LinkSettings {
        LinkSettings {
            retries: self.retries.get(),
            ack_timeout: self.ack_timeout_ms.get(),
            delivery_timeout: self.delivery_timeout_ms.get(),
            ..LinkSettings::default()
        }
    }
}

/// `role`: which way a link faces, the router core's [`LinkKind`].
#[derive(Debug)]
pub(super) struct Role(LinkKind);

impl<'de> Deserialize<'de> for Role {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (kind, _) = checked(d, |role: &String| {
            LinkKind::ALL.into_iter().find(|k| k.name() == role).ok_or_else(|| {
                let names: Vec<String> = LinkKind::ALL.iter().map(|k| format!("`{}`", k.name())).collect();
                format!("unknown variant `{role}`, expected one of {}", names.join(", "))
            })
        })?;
        Ok(Self(kind))
    }
}

/// `[[link]]`: toward the MCU, another GCU or clients, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LinkSection {
    name: Spanned<String>,
    /// `upstream` (toward the MCU or a GCU above), `downstream` (toward
    /// another GCU below) or `client` (an operator tool or application).
    role: Role,
    /// A serial line.
    serial: Option<Spanned<String>>,
    baud: Option<Baud>,
    /// A TCP listener; each accepted connection is a link.
    listen: Option<Spanned<String>>,
    /// A TCP client, reconnected with backoff.
    connect: Option<Spanned<String>>,
    /// Listener: peer addresses allowed to connect (default: loopback only).
    allow_peers: Option<Spanned<Vec<Spanned<String>>>>,
    /// Source groups frames on this link may carry (default: any on links
    /// to GCUs; the MCU's 0 and this GCU's own group on client links).
    allow_source_groups: Option<Spanned<Vec<Int<u8, 0, 254>>>>,
    /// Continuous motion started on this link and not refreshed within
    /// this time is stopped (default: no lease); 100 ms to 10 minutes.
    motion_lease_ms: Option<Millis<100, 600_000>>,
    /// 0..=100: a link of higher priority takes control of a gimbal from
    /// a lower one (ARCHITECTURE "Governance").
    #[serde(default)]
    priority: Int<u8, 0, { sagebrush_gcu::MAX_PRIORITY as i64 }, { sagebrush_gcu::DEFAULT_PRIORITY as i64 }>,
    /// Whether clients on this link may ask a gimbal's rules and who
    /// controls it (`~B`, `~C`); default: on a loopback listener only
    /// (keep-out zones may mark privacy areas).
    may_read_rules: Option<bool>,
    /// TLS (ARCHITECTURE "Principals"): `{ cert, key, client_ca }` on a
    /// listener, `{ ca, cert, key }` on a `connect` link.
    tls: Option<Spanned<super::principal::TlsSection>>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkTransport {
    Serial { path: PathBuf, baud: u32 },
    Listen(SocketAddr),
    Connect(String),
}

/// One `[[link]]`, validated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Link {
    pub name: String,
    pub kind: LinkKind,
    pub transport: LinkTransport,
    pub allow_peers: PeerAllowList,
    /// `None`: any source group.
    pub allow_source_groups: Option<Vec<u8>>,
    pub motion_lease_ms: Option<u64>,
    /// 0..=100 (ARCHITECTURE "Governance").
    pub priority: u8,
    /// May ask `~B` and `~C` (ARCHITECTURE "GCU commands on port 0").
    pub may_read_rules: bool,
    /// Encrypted, and on a listener with `client_ca` each connection's
    /// principal named by its client certificate.
    pub tls: Option<super::principal::LinkTls>,
}

impl Link {
    /// How the router core treats a connection of this link.
    pub fn router(&self) -> LinkConfig {
        let sources = match &self.allow_source_groups {
            Some(groups) => SourceFilter::Only(groups.clone()),
            None => SourceFilter::Any,
        };
        let mut lc = LinkConfig::new(self.kind, sources);
        lc.lossless = !matches!(self.transport, LinkTransport::Serial { .. });
        lc.motion_lease = self.motion_lease_ms;
        // Every connection of this link is one controller of the gimbals.
        lc.name = Some(std::sync::Arc::from(self.name.as_str()));
        lc.priority = self.priority;
        lc.may_read_rules = self.may_read_rules;
        // A link that authenticates at the next GCU tells it whose each
        // forwarded command is (ARCHITECTURE "Principals").
        lc.sends_principals = matches!(
            self.tls,
            Some(super::principal::LinkTls::Client { identity: Some(_), .. })
        );
        lc
    }

    /// Whether each connection must name a configured principal by its
    /// client certificate (a TLS listener with `client_ca`).
    pub fn requires_principal(&self) -> bool {
        matches!(
            self.tls,
            Some(super::principal::LinkTls::Server { client_ca: Some(_), .. })
        )
    }

    /// Whether `other` is this link but for its priority (a reload applies
    /// a new priority without closing the link's connections).
    pub fn same_but_priority(&self, other: &Link) -> bool {
        let priority = self.priority;
        *self
            == Link {
                priority,
                ..other.clone()
            }
    }
}

/// Every `[[link]]`: names unique, exactly one transport, the keys that
/// apply to it only, source groups (a client speaks as the MCU or as
/// `group`, Figure 7, unless told otherwise).
pub(super) fn validate(
    c: &Source<'_>,
    raw: &[LinkSection],
    group: u8,
    checks: &mut Checks,
) -> Result<Vec<Link>, ConfigError> {
    let mut links = Vec::with_capacity(raw.len());
    let mut names = BTreeSet::new();
    for (i, l) in raw.iter().enumerate() {
        let key = format!("link[{i}]");
        let name = l.name.get_ref().clone();
        if name.is_empty() || !names.insert(name.clone()) {
            return Err(c.at(
                l.name.span(),
                format!("{key}.name"),
                format!("link names must be unique and non-empty, found {name:?}"),
            ));
        }
        if !sagebrush_protocol::gcu::valid_name(name.as_bytes()) {
            return Err(c.at(
                l.name.span(),
                format!("{key}.name"),
                format!(
                    "expected 1..=32 of A-Z a-z 0-9 _ - (a link's name names who controls a gimbal in \
                     /status and in GCU command answers), found {name:?}"
                ),
            ));
        }
        let transport = match (&l.serial, &l.listen, &l.connect) {
            (Some(path), None, None) => {
                checks.serial(PathBuf::from(path.get_ref()), path.span(), format!("{key}.serial"));
                LinkTransport::Serial {
                    path: PathBuf::from(path.get_ref()),
                    baud: l.baud.clone().unwrap_or_default().get(),
                }
            }
            (None, Some(addr), None) => LinkTransport::Listen(socket(c, addr, &format!("{key}.listen"))?),
            (None, None, Some(addr)) => {
                LinkTransport::Connect(c.host_port(addr, &format!("{key}.connect"), " to connect to")?)
            }
            _ => {
                return Err(c.at(
                    l.name.span(),
                    key,
                    "expected exactly one of `serial`, `listen` or `connect`",
                ));
            }
        };
        if let (Some(b), false) = (&l.baud, matches!(transport, LinkTransport::Serial { .. })) {
            return Err(c.at(
                b.span(),
                format!("{key}.baud"),
                "`baud` applies to a `serial` link only",
            ));
        }
        let allow_peers = match &l.allow_peers {
            Some(list) => {
                if !matches!(transport, LinkTransport::Listen(_)) {
                    return Err(c.at(
                        list.span(),
                        format!("{key}.allow_peers"),
                        "`allow_peers` applies to a `listen` link only",
                    ));
                }
                peers(c, list, &format!("{key}.allow_peers"))?
            }
            None => loopback(),
        };
        let kind = l.role.0;
        let allow_source_groups = match &l.allow_source_groups {
            Some(list) if list.get_ref().is_empty() => {
                return Err(c.at(
                    list.span(),
                    format!("{key}.allow_source_groups"),
                    "expected at least one group 0..=254: an empty list refuses every frame \
                     on this link (remove the key for the default)",
                ));
            }
            Some(list) => Some(list.get_ref().iter().map(Int::get).collect()),
            None if kind == LinkKind::Client => Some(vec![sagebrush_protocol::MCU_GROUP, group]),
            None => None,
        };
        let tls = l
            .tls
            .as_ref()
            .map(|t| super::principal::link_tls(c, t, &transport, &key))
            .transpose()?;
        if let (LinkTransport::Listen(addr), Some(listen)) = (&transport, &l.listen) {
            let place = checks.listener(c, *addr, listen.span(), &format!("{key}.listen"));
            if !addr.ip().is_loopback() {
                checks.warnings.push(format!(
                    "{place}: listens on {addr}, not on loopback: reachable from other machines \
                     (allow_peers: {allow_peers})"
                ));
                if let Some(warning) = super::principal::open_listener(tls.as_ref(), *addr, &name, l.priority.get()) {
                    checks.warnings.push(format!("{place}: {warning}"));
                }
            }
        }
        let on_loopback = matches!(transport, LinkTransport::Listen(addr) if addr.ip().is_loopback());
        let may_read_rules = l.may_read_rules.unwrap_or(on_loopback);
        links.push(Link {
            name,
            kind,
            transport,
            allow_peers,
            allow_source_groups,
            motion_lease_ms: l.motion_lease_ms.as_ref().map(Millis::get),
            priority: l.priority.get(),
            may_read_rules,
            tls,
        });
    }
    Ok(links)
}
