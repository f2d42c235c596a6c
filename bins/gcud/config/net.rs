//! Addresses in the configuration: listen addresses (`IP:PORT`, or a bare
//! `PORT` on loopback), `allow_peers` lists of addresses and networks, and
//! which listeners clash.

use std::fmt;
use std::net::{IpAddr, SocketAddr};

use ipnet::IpNet;
use sagebrush_service::config_file::Source;
use sagebrush_service::endpoint;
use serde::{Serialize, Serializer};
use toml::Spanned;

use super::ConfigError;

/// `IP:PORT` (`sagebrush_service::endpoint::listen_address`), or a bare
/// `PORT` meaning 127.0.0.1 (listeners stay on loopback unless an address
/// is given).
pub(super) fn socket(c: &Source<'_>, v: &Spanned<String>, key: &str) -> Result<SocketAddr, ConfigError> {
    let text = v.get_ref().trim();
    if let Ok(port) = text.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    endpoint::listen_address(text).map_err(|e| {
        c.at(
            v.span(),
            key,
            format!("expected an IP address and port like 127.0.0.1:4001 (or a port alone): {e}"),
        )
    })
}

/// A non-empty list of peer IP addresses or networks in CIDR notation
/// (`allow_peers`: `10.1.2.3`, `10.0.0.0/8`, `fd00::/8`).
pub(super) fn peers(
    c: &Source<'_>,
    list: &Spanned<Vec<Spanned<String>>>,
    key: &str,
) -> Result<PeerAllowList, ConfigError> {
    if list.get_ref().is_empty() {
        return Err(c.at(
            list.span(),
            key,
            "expected at least one IP address: an empty list refuses every peer \
             (remove the key for the default, loopback only)",
        ));
    }
    let mut peers = Vec::new();
    for (j, p) in list.get_ref().iter().enumerate() {
        let text = p.get_ref().as_str();
        let net = parse_peer(text).map_err(|why| c.at(p.span(), format!("{key}[{j}]"), why))?;
        peers.push(net);
    }
    Ok(PeerAllowList(peers))
}

/// Which peers a listener (or the metrics endpoint) admits: addresses and
/// networks from `allow_peers`, a plain address being a one-host network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerAllowList(Vec<IpNet>);

impl PeerAllowList {
    /// Whether `peer` is in one of the entries. An IPv4 peer seen on an IPv6
    /// socket (`::ffff:10.1.2.3`) counts as its IPv4 address.
    pub fn contains(&self, peer: &IpAddr) -> bool {
        let peer = peer.to_canonical();
        self.0.iter().any(|net| net.contains(&peer))
    }
}

/// The entries separated by `, `; a one-host entry as a plain address.
impl fmt::Display for PeerAllowList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, net) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            if net.prefix_len() == net.max_prefix_len() {
                write!(f, "{}", net.addr())?;
            } else {
                write!(f, "{net}")?;
            }
        }
        Ok(())
    }
}

/// As written in the file (for the keys a reload compares).
impl Serialize for PeerAllowList {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter().map(ToString::to_string))
    }
}

/// One `allow_peers` entry: an address (`10.1.2.3`, `::1`) or a network
/// `ADDRESS/PREFIX` (`10.0.0.0/8`, `fd00::/8`) with no host bits set.
fn parse_peer(text: &str) -> Result<IpNet, String> {
    if !text.contains('/') {
        return text
            .parse::<IpAddr>()
            .map(IpNet::from)
            .map_err(|_| format!("expected an IP address, found {text:?} (or a network like 10.0.0.0/8, fd00::/8)"));
    }
    let net = text.parse::<IpNet>().map_err(|_| {
        format!(
            "expected a network ADDRESS/PREFIX (prefix 0..=32 for IPv4, 0..=128 for IPv6, \
             e.g. 10.0.0.0/8, fd00::/8), found {text:?}"
        )
    })?;
    if net.trunc() != net {
        return Err(format!(
            "{text:?} has bits set past its /{} prefix: write the network, {}",
            net.prefix_len(),
            net.trunc()
        ));
    }
    Ok(net)
}

/// The default `allow_peers`: loopback only.
pub(super) fn loopback() -> PeerAllowList {
    PeerAllowList(vec![
        IpNet::from(IpAddr::from([127, 0, 0, 1])),
        IpNet::from(IpAddr::from(std::net::Ipv6Addr::LOCALHOST)),
    ])
}
