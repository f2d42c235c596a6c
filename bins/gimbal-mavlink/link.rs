//! MAVLink 2 over UDP (TCP connections and serial lines are `stream`'s):
//! the endpoints (`udp_listen`: answer the addresses heard from; `udp`: a
//! ground station's address) and the outbox every component sends through
//! (its own sequence numbers); and what every transport shares:
//!
//! - [`scan`] and [`decode`]: frames read in place from a bounded buffer
//!   (CRC checked with the dialect's CRC_EXTRA), so no transport holds more
//!   than one buffer of a peer's bytes;
//! - [`Net`]: this system's components, the components heard and where
//!   (bounded, see `control::Heard`), and the screening of every intact
//!   frame before the router: a COMMAND_LONG with a command id the dialect
//!   does not know is answered MAV_RESULT_UNSUPPORTED, control given to a
//!   component never heard MAV_RESULT_DENIED;
//! - where a message goes: an answer (a COMMAND_ACK, a requested message)
//!   to the peer the asker was heard on, nowhere else; periodic status to
//!   every peer.
//!
//! UDP peers of a `udp_listen` endpoint: at most [`MAX_PEERS`]; a new
//! address takes the slot of the one silent the longest, and only if that
//! one has been silent for [`PEER_IDLE`]: a flood of fresh source ports
//! cannot push out a ground station that is heard (its heartbeats), its
//! datagrams are dropped and counted (`udp_refused`).

use std::collections::HashMap;
use std::fmt;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use mavlink::dialects::common::{MavCmd, MavMessage, MavResult};
use mavlink::{MavHeader, MavlinkVersion, Message};
use tokio::net::UdpSocket;
use tracing::{debug, warn};

use crate::config::Endpoint;
use crate::control::{self, Heard, Sender};
use crate::stats::{Stats, may_warn};
use crate::stream::Streams;

/// The most peers a listening endpoint answers.
pub const MAX_PEERS: usize = 16;
/// A peer silent for less than this keeps its slot against new addresses.
pub const PEER_IDLE: Duration = Duration::from_secs(5);

/// Where a message was heard, and where an answer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peer {
    /// Endpoint `port` (an index into the UDP endpoints), address `addr`.
    Udp { port: usize, addr: SocketAddr },
    /// A TCP connection or serial line (`stream`'s id).
    Stream(u64),
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

// ---- frames -------------------------------------------------------------

const V1_MAGIC: u8 = 0xFE;
const V2_MAGIC: u8 = 0xFD;
/// The longest frame (MAVLink 2, 255 bytes of payload, signed).
pub const MAX_FRAME: usize = 12 + 255 + 13;
/// The one incompatibility flag MAVLink 2 defines.
const SIGNED: u8 = 0x01;
const COMMAND_INT_ID: u32 = 75;
const COMMAND_LONG_ID: u32 = 76;
const COMMAND_ACK_ID: u32 = 77;

/// Where the next frame is in a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scan {
    /// `skip` bytes that are no intact frame, then a frame of `len` bytes.
    Frame { skip: usize, len: usize },
    /// `skip` bytes that are no intact frame; what follows may be the
    /// start of one (fewer than [`MAX_FRAME`] bytes): read more.
    Partial { skip: usize },
}

/// The next intact MAVLink 1 or 2 frame of `bytes` (its CRC checked with
/// the dialect's CRC_EXTRA; a message id the dialect does not know has
/// none, so its frames are not intact here). After a magic byte whose
/// frame does not check, the search goes on at the next byte.
pub fn scan(bytes: &[u8]) -> Scan {
    let mut i = 0;
    while i < bytes.len() {
        let rest = &bytes[i..];
        let total = match rest[0] {
            V2_MAGIC if rest.len() < 3 => return Scan::Partial { skip: i },
            // An incompatibility flag other than "signed": not a frame we can read.
            V2_MAGIC if rest[2] & !SIGNED != 0 => None,
            V2_MAGIC => Some(12 + usize::from(rest[1]) + if rest[2] & SIGNED != 0 { 13 } else { 0 }),
            V1_MAGIC if rest.len() < 2 => return Scan::Partial { skip: i },
            V1_MAGIC => Some(8 + usize::from(rest[1])),
            _ => None,
        };
        if let Some(total) = total {
            if rest.len() < total {
                return Scan::Partial { skip: i };
            }
            if crc_holds(&rest[..total]) {
                return Scan::Frame { skip: i, len: total };
            }
        }
        i += 1;
    }
    Scan::Partial { skip: bytes.len() }
}

/// The header's and payload's lengths, the message id and where the CRC is.
fn layout(frame: &[u8]) -> (usize, usize, u32) {
    let len = usize::from(frame[1]);
    if frame[0] == V2_MAGIC {
        (10, len, u32::from_le_bytes([frame[7], frame[8], frame[9], 0]))
    } else {
        (6, len, u32::from(frame[5]))
    }
}

fn crc_holds(frame: &[u8]) -> bool {
    let (header, len, id) = layout(frame);
    let end = header + len;
    let crc = u16::from_le_bytes([frame[end], frame[end + 1]]);
    crc == mavlink::calculate_crc(&frame[1..end], MavMessage::extra_crc(id))
}

/// An intact frame, read. (Its size is a message's: each is moved once,
/// never held in bulk; boxing would allocate per message.)
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Decoded {
    Message(MavHeader, MavMessage),
    /// A COMMAND_LONG or COMMAND_INT whose command id the dialect does not know (the
    /// `mavlink` crate refuses to read it: its command is an enum).
    UnknownCommand {
        header: MavHeader,
        target_system: u8,
        target_component: u8,
        command: u16,
        param7: f32,
    },
    /// Intact, but no message of the dialect (a field out of its enum): its length.
    Unreadable(MavHeader, usize),
}

/// Reads an intact `frame` (as [`scan`] found it).
pub fn decode(frame: &[u8]) -> Decoded {
    let (header_len, len, id) = layout(frame);
    let (sequence, system_id, component_id) = if frame[0] == V2_MAGIC {
        (frame[4], frame[5], frame[6])
    } else {
        (frame[2], frame[3], frame[4])
    };
    let header = MavHeader {
        system_id,
        component_id,
        sequence,
    };
    let version = if frame[0] == V2_MAGIC {
        MavlinkVersion::V2
    } else {
        MavlinkVersion::V1
    };
    let payload = &frame[header_len..header_len + len];
    match MavMessage::parse(version, id, payload) {
        Ok(message) => Decoded::Message(header, message),
        // COMMAND_INT has its z (param 7), command and targets where
        // COMMAND_LONG has them.
        Err(_) if id == COMMAND_LONG_ID || id == COMMAND_INT_ID => {
            // MAVLink 2 drops trailing zeros: read it back at full length.
            let mut p = [0u8; 33];
            let n = payload.len().min(p.len());
            p[..n].copy_from_slice(&payload[..n]);
            Decoded::UnknownCommand {
                header,
                param7: f32::from_le_bytes([p[24], p[25], p[26], p[27]]),
                command: u16::from_le_bytes([p[28], p[29]]),
                target_system: p[30],
                target_component: p[31],
            }
        }
        Err(_) => Decoded::Unreadable(header, frame.len()),
    }
}

/// The intact frames of a datagram, read, and whether it held any.
pub fn decode_datagram(datagram: &[u8]) -> Vec<Decoded> {
    let mut out = Vec::new();
    let mut at = 0;
    while let Scan::Frame { skip, len } = scan(&datagram[at..]) {
        out.push(decode(&datagram[at + skip..at + skip + len]));
        at += skip + len;
    }
    out
}

// ---- what this system heard ------------------------------------------------

/// What becomes of an intact frame.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Screened {
    /// To the router.
    Handle(MavHeader, MavMessage),
    /// Answered here: these bytes, to the peer it came from only.
    Answer(Vec<u8>),
    /// Counted, nothing to do.
    Drop,
}

/// This MAVLink system: its components and their sequence numbers, the
/// components heard (where, when), and the askers owed a requested message.
#[derive(Debug)]
pub struct Net {
    pub system_id: u8,
    own: Mutex<Vec<u8>>,
    sequence: Mutex<HashMap<u8, u8>>,
    pub heard: Mutex<Heard<Peer>>,
    /// Per component, the asker of the MAV_CMD_REQUEST_MESSAGE it just
    /// accepted: the information message that follows goes to it alone.
    requested: Mutex<HashMap<u8, Sender>>,
}

impl Net {
    pub fn new(system_id: u8) -> Self {
        Self {
            system_id,
            own: Mutex::default(),
            sequence: Mutex::default(),
            heard: Mutex::default(),
            requested: Mutex::default(),
        }
    }

    /// This system's components (the gimbals): the ones that answer here.
    pub fn set_components(&self, components: impl IntoIterator<Item = u8>) {
        *lock(&self.own) = components.into_iter().collect();
    }

    /// Whether `who` was heard within `within`.
    pub fn heard_within(&self, who: Sender, within: Duration) -> bool {
        lock(&self.heard).heard_within(who, within, Instant::now())
    }

    /// Our component a command is for: `target_component`, or, when it is
    /// 0 (every component), the gimbal device id of param 7.
    fn addressed(&self, target_system: u8, target_component: u8, param7: f32) -> Option<u8> {
        if target_system != 0 && target_system != self.system_id {
            return None;
        }
        let component = match target_component {
            0 if param7.fract() == 0.0 && (1.0..=255.0).contains(&param7) => param7 as u8,
            0 => return None,
            c => c,
        };
        lock(&self.own).contains(&component).then_some(component)
    }

    fn next_sequence(&self, component: u8) -> u8 {
        let mut s = lock(&self.sequence);
        let n = s.entry(component).or_insert(0);
        let this = *n;
        *n = n.wrapping_add(1);
        this
    }

    /// `message` from `component` as a MAVLink 2 frame.
    pub fn frame(&self, component: u8, message: &MavMessage) -> Option<Vec<u8>> {
        let header = MavHeader {
            system_id: self.system_id,
            component_id: component,
            sequence: self.next_sequence(component),
        };
        let mut bytes = Vec::with_capacity(64);
        match mavlink::write_v2_msg(&mut bytes, header, message) {
            Ok(_) => Some(bytes),
            Err(e) => {
                warn!(message = message.message_name(), error = %e, "cannot encode");
                None
            }
        }
    }

    /// A MAVLink 2 frame of message `id` with `payload` (trailing zeros
    /// dropped, as MAVLink 2 sends them), from `component`.
    fn raw_frame(&self, component: u8, id: u32, payload: &[u8]) -> Vec<u8> {
        let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
        let id = id.to_le_bytes();
        let mut f = vec![
            V2_MAGIC,
            len as u8,
            0,
            0,
            self.next_sequence(component),
            self.system_id,
            component,
            id[0],
            id[1],
            id[2],
        ];
        f.extend_from_slice(&payload[..len]);
        let crc = mavlink::calculate_crc(&f[1..], MavMessage::extra_crc(COMMAND_ACK_ID));
        f.extend_from_slice(&crc.to_le_bytes());
        f
    }

    /// COMMAND_ACK UNSUPPORTED of command id `command` (which the dialect
    /// may not know, so it is written here) from `component` to `to`.
    fn unsupported(&self, component: u8, command: u16, to: Sender) -> Vec<u8> {
        let c = command.to_le_bytes();
        let unsupported = MavResult::MAV_RESULT_UNSUPPORTED as u8;
        // command, result, progress, result_param2 (4), target_system, target_component
        let payload = [c[0], c[1], unsupported, 0, 0, 0, 0, 0, to.0, to.1];
        self.raw_frame(component, COMMAND_ACK_ID, &payload)
    }

    /// An intact frame heard on `peer`: its sender is remembered, then it
    /// is handled, answered here or dropped.
    pub fn screen(&self, decoded: Decoded, peer: Peer, from: &dyn fmt::Display, stats: &Stats) -> Screened {
        let header = match &decoded {
            Decoded::Message(h, _) | Decoded::Unreadable(h, _) => *h,
            Decoded::UnknownCommand { header, .. } => *header,
        };
        let sender = (header.system_id, header.component_id);
        lock(&self.heard).hear(sender, peer, Instant::now());
        match decoded {
            Decoded::Unreadable(_, len) => {
                stats.damaged(from, len);
                Screened::Drop
            }
            Decoded::UnknownCommand {
                target_system,
                target_component,
                command,
                param7,
                ..
            } => {
                Stats::count(&stats.received);
                Stats::count(&stats.ignored);
                let Some(component) = self.addressed(target_system, target_component, param7) else {
                    return Screened::Drop;
                };
                Stats::count(&stats.unsupported);
                if may_warn("command not supported", from) {
                    warn!(%from, ?sender, command, component, "command id unknown to the dialect: MAV_RESULT_UNSUPPORTED");
                }
                Screened::Answer(self.unsupported(component, command, sender))
            }
            Decoded::Message(header, message) => {
                Stats::count(&stats.received);
                match self.control_to_unheard(sender, &message) {
                    Some((component, unheard)) => {
                        Stats::count(&stats.refused);
                        if may_warn("control given to a component never heard", from) {
                            warn!(%from, ?sender, ?unheard, component, "control given to a component never heard: MAV_RESULT_DENIED");
                        }
                        let ack = crate::gimbal::ack(
                            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
                            MavResult::MAV_RESULT_DENIED,
                            sender,
                        );
                        match self.frame(component, &ack) {
                            Some(bytes) => Screened::Answer(bytes),
                            None => Screened::Drop,
                        }
                    }
                    None => Screened::Handle(header, message),
                }
            }
        }
    }

    /// For a MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE to one of our components
    /// that gives control to components never heard: that component and them.
    fn control_to_unheard(&self, sender: Sender, message: &MavMessage) -> Option<(u8, Vec<Sender>)> {
        let c = crate::inbox::Command::of(message)?;
        if c.command != MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE {
            return None;
        }
        // To every component: the first gimbal answers the refusal.
        let component = match (c.target_component, c.device_id()) {
            (0, 0) if c.target_system == 0 || c.target_system == self.system_id => lock(&self.own).first().copied()?,
            _ => self.addressed(c.target_system, c.target_component, c.param7)?,
        };
        // Parameters that mean nothing are the gimbal's to refuse.
        let named = control::named(sender, c.params).ok()?;
        let heard = lock(&self.heard);
        let unheard: Vec<Sender> = named.into_iter().filter(|w| !heard.knows(*w)).collect();
        (!unheard.is_empty()).then_some((component, unheard))
    }

    /// Whom `message` from `component` answers: a COMMAND_ACK its target;
    /// a requested information message the asker of the request just
    /// accepted; anything else nobody in particular (everyone).
    fn addressee(&self, component: u8, message: &MavMessage) -> Option<Sender> {
        match message {
            MavMessage::COMMAND_ACK(a) => {
                let to = (a.target_system, a.target_component);
                if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE && a.result == MavResult::MAV_RESULT_ACCEPTED {
                    lock(&self.requested).insert(component, to);
                }
                // Even to system 0 (no valid sender has it, but one that
                // claims it is still the asker): never everyone.
                Some(to)
            }
            MavMessage::GIMBAL_MANAGER_INFORMATION(_) | MavMessage::GIMBAL_DEVICE_INFORMATION(_) => {
                lock(&self.requested).remove(&component)
            }
            _ => None,
        }
    }
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
    /// Binds every UDP endpoint (the TCP ones are `stream`'s).
    pub async fn bind(system_id: u8, endpoints: &[Endpoint]) -> Result<Arc<Self>, String> {
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
        let net = Arc::new(Net::new(system_id));
        Ok(Arc::new(Self {
            started: Instant::now(),
            ports,
            streams: Arc::new(Streams::new(Arc::clone(&net))),
            net,
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
                ?to,
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
    pub async fn receive(self: Arc<Self>, index: usize, stats: Arc<Stats>, handle: crate::stream::Handler) {
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
            let frames = decode_datagram(&buf[..n]);
            if frames.is_empty() {
                stats.damaged(&from, n);
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
            for decoded in frames {
                match self.net.screen(decoded, peer, &from, &stats) {
                    Screened::Handle(header, message) => handle(header, message),
                    Screened::Answer(bytes) => self.send_to(peer, &bytes).await,
                    Screened::Drop => {}
                }
            }
        }
    }
}

/// `message` as a MAVLink 2 frame.
#[cfg(test)]
pub fn encode(header: MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut bytes = Vec::new();
    mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, message).expect("encode");
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA};
    use proptest::prelude::*;

    const GCS: Sender = (255, 190);

    fn header(who: Sender) -> MavHeader {
        MavHeader {
            system_id: who.0,
            component_id: who.1,
            sequence: 7,
        }
    }

    fn heartbeat() -> Vec<u8> {
        encode(header(GCS), &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
    }

    fn messages(bytes: &[u8]) -> usize {
        decode_datagram(bytes)
            .iter()
            .filter(|d| matches!(d, Decoded::Message(..)))
            .count()
    }

    #[test]
    fn intact_frames_are_read_damaged_ones_skipped() {
        let good = heartbeat();
        assert_eq!(messages(&good), 1);
        let mut two = good.clone();
        two.extend_from_slice(b"noise");
        two.extend_from_slice(&good);
        assert_eq!(messages(&two), 2);
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xff;
        assert_eq!(messages(&bad), 0);
        assert_eq!(messages(&[]), 0);
        // MAVLink 1 too.
        let mut v1 = Vec::new();
        mavlink::write_versioned_msg(
            &mut v1,
            MavlinkVersion::V1,
            header(GCS),
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        )
        .unwrap();
        assert_eq!(messages(&v1), 1);
    }

    #[test]
    fn a_frame_split_anywhere_is_found_once_whole() {
        let good = heartbeat();
        for cut in 0..good.len() {
            assert!(
                matches!(scan(&good[..cut]), Scan::Partial { skip: 0 }),
                "a head of {cut} bytes waits"
            );
        }
        let mut noisy = vec![0x55, V2_MAGIC, 0x01];
        noisy.extend_from_slice(&good);
        assert_eq!(
            scan(&noisy),
            Scan::Frame {
                skip: 3,
                len: good.len()
            }
        );
    }

    fn command(id: MavCmd, target: (u8, u8), param7: f32) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: id,
            target_system: target.0,
            target_component: target.1,
            param7,
            ..COMMAND_LONG_DATA::DEFAULT
        })
    }

    /// A COMMAND_LONG with command id `id`, however unknown.
    fn command_with_id(id: u16, target: (u8, u8)) -> Vec<u8> {
        let mut f = encode(header(GCS), &command(MavCmd::MAV_CMD_DO_SET_SERVO, target, 0.0));
        f[10 + 28..10 + 30].copy_from_slice(&id.to_le_bytes());
        let end = 10 + usize::from(f[1]);
        let crc = mavlink::calculate_crc(&f[1..end], MavMessage::extra_crc(COMMAND_LONG_ID));
        f[end..end + 2].copy_from_slice(&crc.to_le_bytes());
        f
    }

    fn net() -> Net {
        let net = Net::new(1);
        net.set_components([154]);
        net
    }

    fn screen(net: &Net, bytes: &[u8]) -> Screened {
        let mut d = decode_datagram(bytes);
        assert_eq!(d.len(), 1);
        net.screen(d.remove(0), Peer::Stream(1), &"test", &Stats::default())
    }

    fn ack_of(bytes: &[u8]) -> mavlink::dialects::common::COMMAND_ACK_DATA {
        match decode_datagram(bytes).pop() {
            Some(Decoded::Message(h, MavMessage::COMMAND_ACK(a))) => {
                assert_eq!((h.system_id, h.component_id), (1, 154), "from the gimbal");
                a
            }
            other => panic!("not an ACK: {other:?}"),
        }
    }

    #[test]
    fn a_command_id_the_dialect_does_not_know_is_answered_unsupported() {
        let net = net();
        let Screened::Answer(bytes) = screen(&net, &command_with_id(0xBEEF, (1, 154))) else {
            panic!("no answer")
        };
        // The ACK names the unknown id: read it raw (the dialect cannot).
        assert_eq!(bytes[7..10], [77, 0, 0], "COMMAND_ACK");
        assert_eq!(u16::from_le_bytes([bytes[10], bytes[11]]), 0xBEEF);
        assert_eq!(bytes[12], MavResult::MAV_RESULT_UNSUPPORTED as u8);
        assert!(matches!(scan(&bytes), Scan::Frame { skip: 0, .. }), "its CRC holds");
        // The same writer for a known id gives what the mavlink crate reads.
        let known = net.unsupported(154, MavCmd::MAV_CMD_DO_SET_SERVO as u16, GCS);
        let a = ack_of(&known);
        assert_eq!(
            (a.command, a.result, a.target_system, a.target_component),
            (
                MavCmd::MAV_CMD_DO_SET_SERVO,
                MavResult::MAV_RESULT_UNSUPPORTED,
                255,
                190
            )
        );
        // Not for one of our components: not answered.
        assert!(matches!(
            screen(&net, &command_with_id(0xBEEF, (1, 99))),
            Screened::Drop
        ));
        assert!(matches!(
            screen(&net, &command_with_id(0xBEEF, (2, 154))),
            Screened::Drop
        ));
    }

    #[test]
    fn control_given_to_components_never_heard_is_denied_here() {
        let net = net();
        let configure = |params: [f32; 4]| {
            let MavMessage::COMMAND_LONG(mut c) = command(MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, (1, 154), 0.0)
            else {
                unreachable!()
            };
            [c.param1, c.param2, c.param3, c.param4] = params;
            encode(header(GCS), &MavMessage::COMMAND_LONG(c))
        };
        let Screened::Answer(bytes) = screen(&net, &configure([200.0, 7.0, 201.0, 8.0])) else {
            panic!("not refused")
        };
        let a = ack_of(&bytes);
        assert_eq!(a.result, MavResult::MAV_RESULT_DENIED);
        assert_eq!((a.target_system, a.target_component), GCS);
        // Itself (heard now), and a component heard before: to the router.
        assert!(matches!(
            screen(&net, &configure([-2.0, -2.0, -1.0, -1.0])),
            Screened::Handle(..)
        ));
        net.screen(
            Decoded::Message(header((200, 7)), MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())),
            Peer::Stream(2),
            &"test",
            &Stats::default(),
        );
        assert!(matches!(
            screen(&net, &configure([200.0, 7.0, -1.0, -1.0])),
            Screened::Handle(..)
        ));
    }

    #[test]
    fn answers_go_to_the_asker_status_to_everyone() {
        let net = net();
        let ack = |command, result| crate::gimbal::ack(command, result, GCS);
        assert_eq!(
            net.addressee(
                154,
                &ack(
                    MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
                    MavResult::MAV_RESULT_ACCEPTED
                )
            ),
            Some(GCS)
        );
        assert_eq!(
            net.addressee(154, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            None,
            "not requested: everyone"
        );
        net.addressee(
            154,
            &ack(MavCmd::MAV_CMD_REQUEST_MESSAGE, MavResult::MAV_RESULT_ACCEPTED),
        );
        assert_eq!(
            net.addressee(171, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            None,
            "another component's"
        );
        assert_eq!(
            net.addressee(154, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            Some(GCS),
            "the requested message follows its ACK"
        );
        assert_eq!(
            net.addressee(154, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())),
            None
        );
        let to_zero = crate::gimbal::ack(MavCmd::MAV_CMD_DO_SET_SERVO, MavResult::MAV_RESULT_UNSUPPORTED, (0, 0));
        assert_eq!(
            net.addressee(154, &to_zero),
            Some((0, 0)),
            "an ACK is never for everyone"
        );
    }

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

    proptest! {
        /// Any bytes: no panic, and the scan accounts for every byte.
        #[test]
        fn any_bytes_decode_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let _ = decode_datagram(&bytes);
            match scan(&bytes) {
                Scan::Frame { skip, len } => prop_assert!(skip + len <= bytes.len()),
                Scan::Partial { skip } => prop_assert!(skip <= bytes.len() && bytes.len() - skip < MAX_FRAME),
            }
        }

        /// One byte changed anywhere but the length (which moves where
        /// the CRC is read): never read as a message.
        #[test]
        fn a_damaged_frame_is_not_read(at in 0usize..21, flip in 1u8..=255) {
            let mut frame = heartbeat();
            let at = if at == 1 { 0 } else { at.min(frame.len() - 1) };
            frame[at] ^= flip;
            prop_assert_eq!(messages(&frame), 0);
        }
    }
}
