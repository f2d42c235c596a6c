//! MAVLink 2 over UDP (TCP connections and serial lines are `stream`'s,
//! frames `wire`'s, this system's components and peers `net`'s): the
//! endpoints (`udp_listen`: answer the addresses heard from; `udp`: a
//! ground station's address) and the outbox every component sends through.
//!
//! UDP peers of a `udp_listen` endpoint: at most [`MAX_PEERS`]; a new
//! address takes the slot of the one silent the longest, and only if that
//! one has been silent for [`PEER_IDLE`]: a flood of fresh source ports
//! cannot push out a ground station that is heard (its heartbeats), its
//! datagrams are dropped and counted (`udp_refused`). With signing on, only
//! a datagram with a frame signed with the key takes or keeps a slot.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use mavlink::Message;
use mavlink::dialects::common::MavMessage;
use tokio::net::UdpSocket;
use tracing::{debug, warn};

use crate::config::Endpoint;
use crate::routing::control::Sender;
use crate::stats::{Stats, may_warn};
use crate::transport::net::{Net, Peer, Screened};
use crate::transport::signing::Signing;
use crate::transport::stream::Streams;
use crate::transport::wire;

/// The most peers a listening endpoint answers.
pub const MAX_PEERS: usize = 16;
/// A peer silent for less than this keeps its slot against new addresses.
pub const PEER_IDLE: Duration = Duration::from_secs(5);

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

// ---- UDP ---------------------------------------------------------------------

/// Whether a UDP address has a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Admit {
    Yes,
    /// Yes, in the slot of this address, silent for [`PEER_IDLE`].
    Replacing(SocketAddr),
    No,
}

/// The addresses a `udp_listen` endpoint answers (see the module's rule).
#[derive(Debug, Default)]
struct UdpPeers {
    /// Address and when last heard.
    peers: Vec<(SocketAddr, Instant)>,
}

impl UdpPeers {
    /// `from` sent an intact frame at `now`: whether it has (or now took) a slot.
    fn admit(&mut self, from: SocketAddr, now: Instant) -> Admit {
        if let Some(p) = self.peers.iter_mut().find(|(a, _)| *a == from) {
            p.1 = now;
            return Admit::Yes;
        }
        if self.peers.len() < MAX_PEERS {
            self.peers.push((from, now));
            return Admit::Yes;
        }
        let idlest = self
            .peers
            .iter_mut()
            .min_by_key(|(_, last)| *last)
            .expect("MAX_PEERS > 0");
        if now.saturating_duration_since(idlest.1) >= PEER_IDLE {
            let gone = idlest.0;
            *idlest = (from, now);
            return Admit::Replacing(gone);
        }
        Admit::No
    }

    fn addrs(&self) -> Vec<SocketAddr> {
        self.peers.iter().map(|(a, _)| *a).collect()
    }
}

/// One bound UDP endpoint and where it sends.
#[derive(Debug)]
struct Port {
    socket: Arc<UdpSocket>,
    /// A fixed ground station (`udp`), or none (`udp_listen`).
    fixed: Option<SocketAddr>,
    peers: Mutex<UdpPeers>,
}

/// Sends MAVLink from this system's components to the endpoints.
#[derive(Debug)]
pub struct Outbox {
    started: Instant,
    ports: Vec<Port>,
    /// The TCP connections and serial lines (`stream`).
    pub streams: Arc<Streams>,
    pub net: Arc<Net>,
}

impl Outbox {
    /// Binds every UDP endpoint (the TCP ones are `stream`'s); signs and
    /// checks with `signing` when given.
    pub async fn bind(system_id: u8, endpoints: &[Endpoint], signing: Option<Signing>) -> Result<Arc<Self>, String> {
        let mut ports = Vec::new();
        for (i, e) in endpoints.iter().enumerate() {
            let (bind, fixed) = match e {
                Endpoint::UdpListen(addr) => (
                    UdpSocket::bind(addr)
                        .await
                        .map_err(|e| format!("endpoint[{i}] udp_listen {addr}: {e}"))?,
                    None,
                ),
                Endpoint::Udp(to) => {
                    let target = tokio::net::lookup_host(to)
                        .await
                        .ok()
                        .and_then(|mut a| a.next())
                        .ok_or_else(|| format!("endpoint[{i}] udp {to}: cannot resolve"))?;
                    let local: SocketAddr = if target.is_ipv4() {
                        "0.0.0.0:0".parse().expect("an address")
                    } else {
                        "[::]:0".parse().expect("an address")
                    };
                    (
                        UdpSocket::bind(local)
                            .await
                            .map_err(|e| format!("endpoint[{i}] udp {to}: {e}"))?,
                        Some(target),
                    )
                }
                Endpoint::TcpListen(_) | Endpoint::Tcp(_) | Endpoint::Serial { .. } => continue,
            };
            ports.push(Port {
                socket: Arc::new(bind),
                fixed,
                peers: Mutex::default(),
            });
        }
        let net = Arc::new(Net::new(system_id, signing));
        Ok(Arc::new(Self {
            started: Instant::now(),
            ports,
            streams: Arc::new(Streams::new(Arc::clone(&net))),
            net,
        }))
    }

    /// The address UDP endpoint `port` (the `port`th UDP endpoint
    /// configured) is bound to.
    pub fn local_addr(&self, port: usize) -> Option<SocketAddr> {
        self.ports.get(port).and_then(|p| p.socket.local_addr().ok())
    }

    /// Milliseconds since start (`time_boot_ms`).
    pub fn boot_ms(&self) -> u32 {
        self.started.elapsed().as_millis() as u32
    }

    /// `message` from component `component_id`: an answer (a COMMAND_ACK,
    /// a requested message) to its asker alone, anything else to every peer.
    pub async fn send(&self, component_id: u8, message: &MavMessage) {
        match self.net.addressee(component_id, message) {
            Some(to) => self.answer(component_id, message, to).await,
            None => self.broadcast(component_id, message).await,
        }
    }

    /// `message` from `component_id` to every peer of every endpoint.
    pub async fn broadcast(&self, component_id: u8, message: &MavMessage) {
        let Some(bytes) = self.net.frame(component_id, message) else {
            return;
        };
        self.streams.send(&bytes);
        for port in &self.ports {
            let peers = match port.fixed {
                Some(to) => vec![to],
                None => lock(&port.peers).addrs(),
            };
            for to in peers {
                if let Err(e) = port.socket.send_to(&bytes, to).await {
                    debug!(%to, error = %e, "send failed");
                }
            }
        }
    }

    /// `message` from `component_id` to `to` alone, on the peer it was
    /// heard on last; nowhere if it is not remembered.
    pub async fn answer(&self, component_id: u8, message: &MavMessage, to: Sender) {
        let Some(peer) = lock(&self.net.heard).peer(to) else {
            debug!(
                to = crate::routing::control::sender_name(to),
                message = message.message_name(),
                "answer to a component not heard: not sent"
            );
            return;
        };
        if let Some(bytes) = self.net.frame(component_id, message) {
            self.send_to(peer, &bytes).await;
        }
    }

    async fn send_to(&self, peer: Peer, bytes: &[u8]) {
        match peer {
            Peer::Udp { port, addr } => {
                let Some(p) = self.ports.get(port) else { return };
                let to = p.fixed.unwrap_or(addr);
                if let Err(e) = p.socket.send_to(bytes, to).await {
                    debug!(%to, error = %e, "send failed");
                }
            }
            Peer::Stream(id) => self.streams.send_to(id, bytes),
        }
    }

    /// Receives on endpoint `index` for ever, handing each intact message
    /// to `handle` (after [`Net::screen`]).
    pub async fn receive(self: Arc<Self>, index: usize, stats: Arc<Stats>, handle: crate::transport::stream::Handler) {
        let port = &self.ports[index];
        let mut buf = vec![0u8; 65_536];
        loop {
            let (n, from) = match port.socket.recv_from(&mut buf).await {
                Ok(x) => x,
                Err(e) => {
                    debug!(error = %e, "receive failed");
                    continue;
                }
            };
            let mut intact = false;
            let frames: Vec<&[u8]> = wire::frames(&buf[..n])
                .inspect(|_| intact = true)
                .filter(|frame| self.net.admits(frame, &from, &stats))
                .collect();
            if !intact {
                stats.damaged(&from, n);
                continue;
            }
            if frames.is_empty() {
                // Refused for their signatures (counted, logged): no slot.
                continue;
            }
            let admitted = match port.fixed {
                Some(_) => Admit::Yes,
                None => lock(&port.peers).admit(from, Instant::now()),
            };
            if let Admit::Replacing(gone) = admitted {
                lock(&self.net.heard).forget(Peer::Udp {
                    port: index,
                    addr: gone,
                });
            }
            if admitted == Admit::No {
                Stats::count(&stats.udp_refused);
                if may_warn("datagram from a new address while every peer is active", &from.ip()) {
                    warn!(%from, max = MAX_PEERS, idle_s = PEER_IDLE.as_secs(), "datagram from a new address while every peer was heard recently: dropped");
                }
                continue;
            }
            let peer = Peer::Udp {
                port: index,
                addr: from,
            };
            for frame in frames {
                match self.net.screen(wire::decode(frame), peer, &from, &stats) {
                    Screened::Handle(header, message) => handle(header, message),
                    Screened::Answer(bytes) => self.send_to(peer, &bytes).await,
                    Screened::Drop => {}
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresh_addresses_never_push_out_a_peer_heard_recently() {
        let mut peers = UdpPeers::default();
        let t0 = Instant::now();
        let gcs: SocketAddr = "127.0.0.1:14550".parse().unwrap();
        assert_eq!(peers.admit(gcs, t0), Admit::Yes);
        let mut admitted = 0;
        for (i, port) in (20_000u16..30_000).enumerate() {
            let now = t0 + Duration::from_millis(i as u64);
            if i % 1000 == 0 {
                assert_eq!(
                    peers.admit(gcs, now),
                    Admit::Yes,
                    "the ground station beats every second"
                );
            }
            admitted += usize::from(peers.admit(SocketAddr::from(([127, 0, 0, 1], port)), now) != Admit::No);
        }
        assert!(peers.addrs().contains(&gcs));
        // Only the free slots, then one per slot silent for PEER_IDLE.
        assert!(admitted < MAX_PEERS * 3, "{admitted}");
        let later = t0 + Duration::from_secs(60);
        assert!(
            matches!(peers.admit("127.0.0.1:9".parse().unwrap(), later), Admit::Replacing(_)),
            "a silent slot is taken"
        );
    }
}
