//! MAVLink 2 over UDP (TCP connections and serial lines are `stream`'s): the endpoints (`udp_listen`: answer every address
//! heard from; `udp`: a ground station's address) and the outbox every
//! component sends through (its own sequence numbers). Frames are read and written by the `mavlink` crate.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, Message};
use tokio::net::UdpSocket;
use tracing::{debug, warn};

use crate::config::Endpoint;
use crate::stats::Stats;
use crate::stream::{Handler, Streams};

/// The most peers a listening endpoint answers (the oldest heard is dropped).
pub const MAX_PEERS: usize = 16;

/// One bound UDP endpoint and where it sends.
#[derive(Debug)]
struct Port {
    socket: Arc<UdpSocket>,
    /// A fixed ground station (`udp`), or none (`udp_listen`).
    fixed: Option<SocketAddr>,
    /// Addresses heard from, most recent last.
    heard: Mutex<Vec<SocketAddr>>,
}

/// Sends MAVLink from this system's components to every endpoint.
#[derive(Debug)]
pub struct Outbox {
    pub system_id: u8,
    started: Instant,
    ports: Vec<Port>,
    /// The TCP connections (`stream`).
    pub streams: Arc<Streams>,
    sequence: Mutex<HashMap<u8, u8>>,
}

impl Outbox {
    /// Binds every UDP endpoint (the TCP ones are `stream`'s).
    pub async fn bind(system_id: u8, endpoints: &[Endpoint]) -> Result<Arc<Self>, String> {
        let mut ports = Vec::new();
        for (i, e) in endpoints.iter().enumerate() {
            let port = match e {
                Endpoint::UdpListen(addr) => Port {
                    socket: Arc::new(
                        UdpSocket::bind(addr)
                            .await
                            .map_err(|e| format!("endpoint[{i}] udp_listen {addr}: {e}"))?,
                    ),
                    fixed: None,
                    heard: Mutex::new(Vec::new()),
                },
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
                    Port {
                        socket: Arc::new(
                            UdpSocket::bind(local)
                                .await
                                .map_err(|e| format!("endpoint[{i}] udp {to}: {e}"))?,
                        ),
                        fixed: Some(target),
                        heard: Mutex::new(Vec::new()),
                    }
                }
                Endpoint::TcpListen(_) | Endpoint::Tcp(_) | Endpoint::Serial { .. } => continue,
            };
            ports.push(port);
        }
        Ok(Arc::new(Self {
            system_id,
            started: Instant::now(),
            ports,
            streams: Arc::new(Streams::default()),
            sequence: Mutex::new(HashMap::new()),
        }))
    }

    /// Where each endpoint is bound.
    pub fn local_addrs(&self) -> Vec<SocketAddr> {
        self.ports.iter().filter_map(|p| p.socket.local_addr().ok()).collect()
    }

    /// Milliseconds since start (`time_boot_ms`).
    pub fn boot_ms(&self) -> u32 {
        self.started.elapsed().as_millis() as u32
    }

    /// `message` from component `component_id` to every peer.
    pub async fn send(&self, component_id: u8, message: &MavMessage) {
        let sequence = {
            let mut s = self.sequence.lock().unwrap_or_else(|p| p.into_inner());
            let n = s.entry(component_id).or_insert(0);
            let this = *n;
            *n = n.wrapping_add(1);
            this
        };
        let header = MavHeader {
            system_id: self.system_id,
            component_id,
            sequence,
        };
        let mut bytes = Vec::with_capacity(300);
        if let Err(e) = mavlink::write_v2_msg(&mut bytes, header, message) {
            warn!(message = message.message_name(), error = %e, "cannot encode");
            return;
        }
        self.streams.send(&bytes);
        for port in &self.ports {
            let peers: Vec<SocketAddr> = match port.fixed {
                Some(to) => vec![to],
                None => port.heard.lock().unwrap_or_else(|p| p.into_inner()).clone(),
            };
            for to in peers {
                if let Err(e) = port.socket.send_to(&bytes, to).await {
                    debug!(%to, error = %e, "send failed");
                }
            }
        }
    }

    /// Receives on endpoint `index` for ever, handing each intact message
    /// to `handle`.
    pub async fn receive(self: Arc<Self>, index: usize, stats: Arc<Stats>, handle: Handler) {
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
            let messages = decode(&buf[..n]);
            if messages.is_empty() {
                stats.damaged(&from, n);
                continue;
            }
            if port.fixed.is_none() {
                let mut heard = port.heard.lock().unwrap_or_else(|p| p.into_inner());
                heard.retain(|a| *a != from);
                if heard.len() >= MAX_PEERS {
                    heard.remove(0);
                }
                heard.push(from);
            }
            for (header, message) in messages {
                Stats::count(&stats.received);
                handle(header, message);
            }
        }
    }
}

/// The intact MAVLink 1 or 2 messages of a datagram (CRC checked by the
/// `mavlink` crate; damaged frames and bytes between frames are skipped).
pub fn decode(datagram: &[u8]) -> Vec<(MavHeader, MavMessage)> {
    let mut reader = mavlink::MavlinkReader::new(datagram);
    let mut out = Vec::new();
    // A frame is at least 8 bytes: a bound on the loop whatever happens.
    for _ in 0..=datagram.len() / 8 {
        match reader.read_any_message::<MavMessage>() {
            Ok(m) => out.push(m),
            Err(mavlink::error::MessageReadError::Parse(_)) => continue,
            Err(_) => break,
        }
    }
    out
}

/// `message` as a MAVLink 2 frame.
#[cfg(test)]
pub fn encode(header: MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut bytes = Vec::new();
    mavlink::write_versioned_msg(&mut bytes, mavlink::MavlinkVersion::V2, header, message).expect("encode");
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::HEARTBEAT_DATA;
    use proptest::prelude::*;

    fn heartbeat() -> Vec<u8> {
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 7,
        };
        encode(header, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
    }

    #[test]
    fn intact_frames_are_read_damaged_ones_skipped() {
        let good = heartbeat();
        assert_eq!(decode(&good).len(), 1);
        let mut two = good.clone();
        two.extend_from_slice(b"noise");
        two.extend_from_slice(&good);
        assert_eq!(decode(&two).len(), 2);
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xff;
        assert!(decode(&bad).is_empty());
        assert!(decode(&[]).is_empty());
    }

    proptest! {
        /// Any bytes, or an intact frame with any byte changed: no panic,
        /// and a changed frame is never read as another message.
        #[test]
        fn any_bytes_decode_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let _ = decode(&bytes);
        }

        /// One byte changed anywhere but the length (which moves where
        /// the CRC is read): never read as a message (CRC-16 catches every
        /// error burst of up to 16 bits).
        #[test]
        fn a_damaged_frame_is_not_read(at in 0usize..21, flip in 1u8..=255) {
            let mut frame = heartbeat();
            let at = if at == 1 { 0 } else { at.min(frame.len() - 1) };
            frame[at] ^= flip;
            prop_assert!(decode(&frame).is_empty());
        }
    }
}
