//! WS-Discovery (2005/04, as ONVIF Core 7 uses it) over UDP: every Probe
//! whose Types we match is answered to its sender with one ProbeMatches
//! per gimbal (its own endpoint reference, XAddrs and scopes); Hello at
//! start and Bye at stop go to the multicast group only when listening on
//! the unspecified address (a unicast `listen` answers unicast probes only).
//!
//! Never an amplifier: only a well-formed Probe is answered (a SOAP 1.2
//! envelope, its Action, if any, the discovery Probe's, a Probe element in
//! the discovery namespace, a MessageID of at most [`MAX_MESSAGE_ID`]
//! bytes, which is all the answer echoes), and answers go out at a bounded
//! rate: `answers_per_s` in all and `answers_per_source_per_s` to one
//! source address (token buckets, a second's worth of burst), so whatever
//! the probes, forged sources included, the bytes sent a second are
//! bounded. Probes over the rate are dropped, counted and logged at most
//! once per [`DROPPED_LOG_EVERY`].

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use sagebrush_service::rate::{KeyedBuckets, LogGate, TokenBucket};
use sha1::{Digest, Sha1};
use tokio::net::UdpSocket;
use tracing::{debug, warn};

use crate::config;
use crate::onvif::scopes;
use crate::soap::{self, esc};

pub const MULTICAST: Ipv4Addr = Ipv4Addr::new(239, 255, 255, 250);
const NS_DISCOVERY: &str = "http://schemas.xmlsoap.org/ws/2005/04/discovery";
const NS_ADDRESSING: &str = "http://schemas.xmlsoap.org/ws/2004/08/addressing";
/// The largest datagram read (a Probe is well under 2 KiB).
const MAX_DATAGRAM: usize = 8192;
/// The longest MessageID answered (the answer's RelatesTo echoes it).
pub const MAX_MESSAGE_ID: usize = 256;
/// Scopes a Probe may ask for, at most.
const MAX_SCOPES: usize = 32;
/// Source addresses whose answer rate is remembered at once.
const SOURCES: usize = 4096;
/// Probes dropped over the rate are logged at most this often.
const DROPPED_LOG_EVERY: Duration = Duration::from_secs(10);
/// The types a video management system probes for.
const TYPES: &str = "dn:NetworkVideoTransmitter tds:Device";

/// A `urn:uuid:` made from `seed` (SHA-1, name-based as RFC 4122 version 5).
pub fn urn(seed: &str) -> String {
    let d = Sha1::digest(seed.as_bytes());
    let mut b = [0u8; 16];
    b.copy_from_slice(&d[..16]);
    b[6] = (b[6] & 0x0F) | 0x50;
    b[8] = (b[8] & 0x3F) | 0x80;
    let h: String = b.iter().map(|x| format!("{x:02x}")).collect();
    format!(
        "urn:uuid:{}-{}-{}-{}-{}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}

#[derive(Debug)]
pub struct Discovery {
    socket: UdpSocket,
    gimbals: Vec<config::Gimbal>,
    /// Multicast Hello/Bye and multicast probes: listening on 0.0.0.0.
    multicast: bool,
    instance: u64,
    messages: AtomicU64,
    rates: Mutex<Rates>,
    /// Probes answered, and dropped over the rate.
    answered: AtomicU64,
    dropped: AtomicU64,
}

/// The answer rates: in all, and per source address.
#[derive(Debug)]
struct Rates {
    all: TokenBucket,
    per_source: KeyedBuckets<IpAddr>,
    log: LogGate<()>,
}

impl Discovery {
    pub async fn bind(config: config::DiscoveryConfig, gimbals: Vec<config::Gimbal>) -> std::io::Result<Self> {
        let listen = config.listen;
        let socket = UdpSocket::bind(listen).await?;
        let multicast = listen.ip().is_unspecified();
        if multicast {
            socket.join_multicast_v4(MULTICAST, Ipv4Addr::UNSPECIFIED)?;
        }
        let instance = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.as_secs());
        Ok(Self {
            socket,
            gimbals,
            multicast,
            instance,
            messages: AtomicU64::new(0),
            rates: Mutex::new(Rates {
                all: TokenBucket::new(
                    f64::from(config.answers_per_s),
                    f64::from(config.answers_per_s),
                    tokio::time::Instant::now(),
                ),
                per_source: KeyedBuckets::new(
                    f64::from(config.answers_per_source_per_s),
                    f64::from(config.answers_per_source_per_s),
                    SOURCES,
                ),
                log: LogGate::new(DROPPED_LOG_EVERY, 1),
            }),
            answered: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
        })
    }

    /// Whether a Probe from `peer` may be answered now (both rates allow it).
    fn may_answer(&self, peer: SocketAddr) -> bool {
        let now = tokio::time::Instant::now();
        let mut rates = self.rates.lock().unwrap_or_else(|p| p.into_inner());
        // The source's bucket first: a flood from one source does not spend
        // the tokens of all the others.
        if rates.per_source.take(&peer.ip(), now) && rates.all.take(now) {
            self.answered.fetch_add(1, Ordering::Relaxed);
            return true;
        }
        let dropped = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(more) = rates.log.allow(&(), now) {
            warn!(%peer, dropped, more, answered = self.answered.load(Ordering::Relaxed), "WS-Discovery Probe dropped: over discovery.answers_per_s or answers_per_source_per_s (logged at most once in {} s)", DROPPED_LOG_EVERY.as_secs());
        }
        false
    }

    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    fn message(&self, action: &str, relates_to: Option<&str>, body: &str) -> String {
        let n = self.messages.fetch_add(1, Ordering::Relaxed) + 1;
        let relates = relates_to
            .map(|r| format!("<a:RelatesTo>{}</a:RelatesTo>", esc(r)))
            .unwrap_or_default();
        let to = if relates_to.is_some() {
            "http://schemas.xmlsoap.org/ws/2004/08/addressing/role/anonymous"
        } else {
            "urn:schemas-xmlsoap-org:ws:2005:04:discovery"
        };
        format!(
            r#"<?xml version="1.0" encoding="UTF-8"?><s:Envelope xmlns:s="{}" xmlns:a="{NS_ADDRESSING}" xmlns:d="{NS_DISCOVERY}" xmlns:dn="http://www.onvif.org/ver10/network/wsdl" xmlns:tds="{}"><s:Header><a:MessageID>{}</a:MessageID>{relates}<a:To>{to}</a:To><a:Action>{NS_DISCOVERY}/{action}</a:Action><d:AppSequence InstanceId="{}" MessageNumber="{n}"/></s:Header><s:Body>{body}</s:Body></s:Envelope>"#,
            soap::NS_SOAP,
            soap::NS_DEVICE,
            urn(&format!("{} {n}", self.instance)),
            self.instance
        )
    }

    /// What describes a gimbal's device: endpoint, types, scopes, XAddrs.
    fn description(&self, g: &config::Gimbal, ip: IpAddr) -> String {
        let host = SocketAddr::new(ip, g.listen.port());
        format!(
            "<a:EndpointReference><a:Address>{}</a:Address></a:EndpointReference><d:Types>{TYPES}</d:Types>\
             <d:Scopes>{}</d:Scopes><d:XAddrs>{}://{host}/onvif/device_service</d:XAddrs>\
             <d:MetadataVersion>1</d:MetadataVersion>",
            urn(&format!("gimbal-onvif {}", g.name)),
            esc(&scopes(g).join(" ")),
            if g.https { "https" } else { "http" }
        )
    }

    /// The address a gimbal is reached at by `peer`: its own listen
    /// address, or when that is unspecified, the one that routes to `peer`.
    fn ip_for(&self, g: &config::Gimbal, peer: SocketAddr) -> IpAddr {
        if !g.listen.ip().is_unspecified() {
            return g.listen.ip();
        }
        // Connecting a UDP socket sends nothing; it only picks the route.
        std::net::UdpSocket::bind("0.0.0.0:0")
            .and_then(|s| s.connect(peer).and_then(|()| s.local_addr()))
            .map_or(g.listen.ip(), |a| a.ip())
    }

    /// Answers probes until the task is dropped.
    pub async fn run(&self) {
        let mut buf = vec![0u8; MAX_DATAGRAM];
        loop {
            let (len, peer) = match self.socket.recv_from(&mut buf).await {
                Ok(x) => x,
                Err(e) => {
                    warn!(error = %e, "WS-Discovery receive failed");
                    continue;
                }
            };
            let Some(probe) = probe(&buf[..len]) else {
                debug!(%peer, "WS-Discovery datagram that is no Probe we match: ignored");
                continue;
            };
            if peer.port() == 0 || peer.ip().is_unspecified() || peer.ip().is_multicast() || !self.may_answer(peer) {
                continue;
            }
            for g in self.gimbals.iter().filter(|g| in_scopes(&probe.scopes, &scopes(g))) {
                let body = format!(
                    "<d:ProbeMatches><d:ProbeMatch>{}</d:ProbeMatch></d:ProbeMatches>",
                    self.description(g, self.ip_for(g, peer))
                );
                let reply = self.message("ProbeMatches", Some(&probe.id), &body);
                if let Err(e) = self.socket.send_to(reply.as_bytes(), peer).await {
                    warn!(%peer, error = %e, "cannot answer a Probe");
                }
            }
        }
    }

    /// Hello (at start) or Bye (at stop) of every gimbal, to the multicast
    /// group, when listening there.
    pub async fn announce(&self, hello: bool) {
        if !self.multicast {
            return;
        }
        let to = SocketAddr::new(IpAddr::V4(MULTICAST), 3702);
        for g in &self.gimbals {
            let (action, body) = if hello {
                let d = self.description(g, self.ip_for(g, to));
                ("Hello", format!("<d:Hello>{d}</d:Hello>"))
            } else {
                (
                    "Bye",
                    format!(
                        "<d:Bye><a:EndpointReference><a:Address>{}</a:Address></a:EndpointReference></d:Bye>",
                        urn(&format!("gimbal-onvif {}", g.name))
                    ),
                )
            };
            if let Err(e) = self
                .socket
                .send_to(self.message(action, None, &body).as_bytes(), to)
                .await
            {
                warn!(error = %e, action, "cannot announce");
            }
        }
    }
}

/// A Probe we may answer: its MessageID and the scopes it asks for.
#[derive(Debug, PartialEq)]
struct Probe {
    id: String,
    scopes: Vec<String>,
}

/// Whether a device with scopes `ours` answers a probe for `wanted`: each
/// wanted scope is one of ours or a leading run of its path segments
/// (WS-Discovery 5.1, RFC 3986 matching, the default).
fn in_scopes(wanted: &[String], ours: &[String]) -> bool {
    wanted.iter().all(|w| {
        let w = w.trim_end_matches('/');
        ours.iter()
            .any(|o| o.eq_ignore_ascii_case(w) || o.strip_prefix(w).is_some_and(|rest| rest.starts_with('/')))
    })
}

/// A Probe we match: a SOAP 1.2 envelope whose Action, if any, is the
/// discovery Probe's, whose MessageID is at most [`MAX_MESSAGE_ID`] bytes,
/// with a Probe of the discovery namespace asking for no Types or ours
/// (NetworkVideoTransmitter, Device, compared by local name).
fn probe(datagram: &[u8]) -> Option<Probe> {
    let root = soap::parse(datagram).ok()?;
    if root.name != "Envelope" || root.ns != soap::NS_SOAP {
        return None;
    }
    let probe = root.path(&["Body", "Probe"]).filter(|p| p.ns == NS_DISCOVERY)?;
    if let Some(action) = root.path(&["Header", "Action"]) {
        if action.text.trim() != format!("{NS_DISCOVERY}/Probe") {
            return None;
        }
    }
    let id = root.text_at(&["Header", "MessageID"])?.to_owned();
    if id.is_empty() || id.len() > MAX_MESSAGE_ID {
        return None;
    }
    let scopes: Vec<String> = probe
        .text_at(&["Scopes"])
        .unwrap_or_default()
        .split_whitespace()
        .map(str::to_owned)
        .collect();
    if scopes.len() > MAX_SCOPES {
        return None;
    }
    let types = probe.text_at(&["Types"]).unwrap_or_default();
    let ours = ["NetworkVideoTransmitter", "Device"];
    let matches = types.split_whitespace().all(|t| {
        let local = t.rsplit(':').next().unwrap_or(t);
        ours.contains(&local)
    });
    matches.then_some(Probe { id, scopes })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_we_answer() {
        let p = |types: &str| {
            format!(
                r#"<e:Envelope xmlns:e="http://www.w3.org/2003/05/soap-envelope" xmlns:w="{NS_ADDRESSING}" xmlns:d="{NS_DISCOVERY}" xmlns:dn="http://www.onvif.org/ver10/network/wsdl"><e:Header><w:MessageID>urn:uuid:1</w:MessageID></e:Header><e:Body><d:Probe>{types}</d:Probe></e:Body></e:Envelope>"#
            )
        };
        assert_eq!(probe(p("").as_bytes()).map(|p| p.id).as_deref(), Some("urn:uuid:1"));
        let scoped = probe(p("<d:Scopes>onvif://www.onvif.org/name/mast-1</d:Scopes>").as_bytes()).unwrap();
        assert_eq!(scoped.scopes, ["onvif://www.onvif.org/name/mast-1"]);
        let ours = [
            "onvif://www.onvif.org/name/mast-1".to_owned(),
            "onvif://www.onvif.org/type/ptz".to_owned(),
        ];
        assert!(in_scopes(&[], &ours));
        assert!(in_scopes(&scoped.scopes, &ours));
        assert!(in_scopes(&["onvif://www.onvif.org/type".to_owned()], &ours));
        assert!(!in_scopes(&["onvif://www.onvif.org/name/mast".to_owned()], &ours));
        assert!(!in_scopes(&["onvif://www.onvif.org/name/mast-2".to_owned()], &ours));
        assert!(probe(p("<d:Types>dn:NetworkVideoTransmitter</d:Types>").as_bytes()).is_some());
        assert!(probe(p("<d:Types>dn:Printer</d:Types>").as_bytes()).is_none());
        assert!(probe(b"<junk").is_none());
        let other_ns = p("").replace(NS_DISCOVERY, "http://schemas.xmlsoap.org/ws/2005/04/other");
        assert!(probe(other_ns.as_bytes()).is_none(), "a Probe of another namespace");
        let soap11 = p("").replace(
            "http://www.w3.org/2003/05/soap-envelope",
            "http://schemas.xmlsoap.org/soap/envelope/",
        );
        assert!(probe(soap11.as_bytes()).is_none(), "not a SOAP 1.2 envelope");
        let long_id = p("").replace("urn:uuid:1", &"x".repeat(MAX_MESSAGE_ID + 1));
        assert!(probe(long_id.as_bytes()).is_none(), "a MessageID longer than the limit");
        let wrong_action = p("").replace(
            "<e:Header>",
            &format!("<e:Header><w:Action>{NS_DISCOVERY}/Resolve</w:Action>"),
        );
        assert!(probe(wrong_action.as_bytes()).is_none(), "another Action");
        let right_action = p("").replace(
            "<e:Header>",
            &format!("<e:Header><w:Action>{NS_DISCOVERY}/Probe</w:Action>"),
        );
        assert!(probe(right_action.as_bytes()).is_some());
        assert_eq!(urn("a"), urn("a"));
        assert_ne!(urn("a"), urn("b"));
        assert_eq!(urn("a").len(), "urn:uuid:".len() + 36);
    }
}
