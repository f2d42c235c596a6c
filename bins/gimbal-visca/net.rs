//! A camera's sockets: Sony VISCA over IP on UDP (with raw VISCA
//! datagrams), and raw VISCA over TCP through the shared bounded listener
//! (`sagebrush_service::Admitted`: a cap on connections in all and per
//! peer, an idle time-out). Every datagram and message is answered or
//! dropped at once; nothing here waits on the bus, so a flood costs the
//! door one datagram's work at a time and bounded tables
//! ([`Sequences`], the camera's queue and motion slots).

use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use sagebrush_service::door_metrics::HeardLately;
use sagebrush_service::{Admitted, Connections};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, UdpSocket};
use tokio::sync::mpsc;
use tokio::time::Instant;
use tracing::{info, warn};

use crate::camera::Camera;
use crate::framing::{self, Datagram, Deframer, FrameError, Piece, control, payload_type};
use crate::reply::{Out, Replier};
use crate::stats::{Stats, may_warn};
use crate::visca;

/// Clients whose sequence numbers a camera keeps, at most (the one heard
/// the longest ago goes first).
pub const SOURCES: usize = 64;
/// A client silent this long starts its sequence numbers afresh.
pub const FORGET: Duration = Duration::from_secs(10);
/// TCP connections per camera, and per client address.
pub const MAX_CONNECTIONS: usize = 8;
pub const MAX_PER_PEER: usize = 4;
/// A TCP connection that sends nothing this long is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(300);
/// Replies queued for one TCP connection; a client that reads none loses them.
const TCP_QUEUE: usize = 32;

/// The last sequence number of each client (VISCA over IP): a datagram
/// older than the last one from its source address and port is answered
/// "abnormality in the sequence number" and not carried out (a delayed
/// drive must not undo the stop after it); RESET starts a client's
/// address afresh. An equal number is carried out again (clients that
/// never count repeat their drives so), except a RelativePosition whose
/// bytes are the last ones too: a retransmission, answered but not moved
/// twice.
#[derive(Debug, Default)]
pub struct Sequences {
    seen: HashMap<SocketAddr, (u32, Instant, Vec<u8>)>,
}

/// How a datagram's sequence number compares with its source's last.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seen {
    Fresh,
    /// The last one again, with the same bytes.
    Repeat,
    /// Older than the last one.
    Old,
}

impl Sequences {
    /// Forgets every source of `ip` (its RESET).
    pub fn reset(&mut self, ip: IpAddr) {
        self.seen.retain(|a, _| a.ip() != ip);
    }

    /// How `sequence` with `payload` from `from` compares; notes it unless old.
    pub fn accept(&mut self, from: SocketAddr, sequence: u32, payload: &[u8], now: Instant) -> Seen {
        let mut seen = Seen::Fresh;
        if let Some((last, at, bytes)) = self.seen.get(&from) {
            if now.duration_since(*at) < FORGET {
                if *last == sequence && bytes == payload {
                    seen = Seen::Repeat;
                } else if sequence != *last && last.wrapping_sub(sequence) < 1 << 31 {
                    return Seen::Old;
                }
            }
        } else if self.seen.len() >= SOURCES {
            if let Some(oldest) = self.seen.iter().min_by_key(|(_, (_, at, _))| *at).map(|(a, _)| *a) {
                self.seen.remove(&oldest);
            }
        }
        self.seen.insert(from, (sequence, now, payload.to_vec()));
        seen
    }
}

/// The user the door acts for with client `ip` (`[[client]]`).
pub fn user_of(clients: &[(IpAddr, String)], ip: IpAddr) -> Option<Arc<str>> {
    let ip = match ip {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
        v4 => v4,
    };
    clients
        .iter()
        .find(|(a, _)| *a == ip)
        .map(|(_, u)| Arc::from(u.as_str()))
}

/// Reads VISCA message `bytes` and hands it to the camera, or answers a
/// syntax error (an address for another camera is dropped).
fn message(camera: &Camera, bytes: &[u8], replier: Replier) {
    match visca::parse(bytes) {
        Ok(m) => camera.handle(m, replier),
        Err(visca::Error::NotForUs(_)) => {
            Stats::count(&camera.stats.malformed);
        }
        Err(visca::Error::Syntax) => {
            camera.metrics.request(visca::OTHER);
            Stats::count(&camera.stats.syntax);
            replier.send(&visca::syntax_error());
        }
    }
}

/// Serves `socket` (VISCA over IP for `camera`) for ever; each client is
/// noted in `heard` (the door's metrics' sessions).
pub async fn serve_udp(
    socket: Arc<UdpSocket>,
    camera: Arc<Camera>,
    clients: Arc<Vec<(IpAddr, String)>>,
    heard: Arc<HeardLately>,
) {
    let mut buf = vec![0u8; 2048];
    let mut sequences = Sequences::default();
    loop {
        let (n, from) = match socket.recv_from(&mut buf).await {
            Ok(x) => x,
            Err(e) => {
                if may_warn("VISCA UDP receive failed", &camera.config.name) {
                    warn!(gimbal = %camera.config.name, error = %e, "VISCA UDP receive failed");
                }
                tokio::time::sleep(Duration::from_millis(10)).await;
                continue;
            }
        };
        let control_reply = |sequence: u32, payload: &[u8]| {
            let _ = socket.try_send_to(&framing::encode(payload_type::CONTROL_REPLY, sequence, payload), from);
        };
        let user = user_of(&clients, from.ip());
        heard.note(from);
        match framing::parse(&buf[..n]) {
            Err(FrameError::Short(len)) => {
                let total = Stats::count(&camera.stats.malformed);
                if may_warn("datagram too short for VISCA over IP: dropped", &from.ip()) {
                    warn!(gimbal = %camera.config.name, %from, len, total, "datagram too short for VISCA over IP: dropped");
                }
            }
            Err(FrameError::Length {
                sequence,
                declared,
                actual,
            }) => {
                let total = Stats::count(&camera.stats.malformed);
                if may_warn("VISCA over IP length wrong", &from.ip()) {
                    warn!(gimbal = %camera.config.name, %from, declared, actual, total, "VISCA over IP header's length is not the payload's: answered abnormality in the message");
                }
                control_reply(sequence, &control::MESSAGE_ERROR);
            }
            Ok(Datagram::Raw(m)) => {
                let replier = Replier {
                    to: Out::RawUdp {
                        socket: Arc::clone(&socket),
                    },
                    peer: from,
                    user,
                };
                message(&camera, m, replier);
            }
            Ok(Datagram::Ip {
                kind,
                sequence,
                payload,
            }) => match kind {
                payload_type::CONTROL if payload == control::RESET => {
                    sequences.reset(from.ip());
                    control_reply(sequence, &control::ACK);
                }
                payload_type::COMMAND | payload_type::INQUIRY => {
                    let seen = sequences.accept(from, sequence, payload, Instant::now());
                    if seen == Seen::Old {
                        let total = Stats::count(&camera.stats.out_of_sequence);
                        if may_warn("VISCA over IP sequence number out of order", &from.ip()) {
                            warn!(gimbal = %camera.config.name, %from, sequence, total, "sequence number older than the last: not carried out, answered abnormality in the sequence number");
                        }
                        control_reply(sequence, &control::SEQUENCE_ERROR);
                        continue;
                    }
                    let replier = Replier {
                        to: Out::Ip {
                            socket: Arc::clone(&socket),
                            sequence,
                        },
                        peer: from,
                        user,
                    };
                    let relative = matches!(
                        visca::parse(payload),
                        Ok(visca::Message::Command(visca::Command::Relative { .. }))
                    );
                    if seen == Seen::Repeat && relative {
                        // A retransmission: answered again, not moved twice.
                        replier.send(&visca::ack());
                        replier.send(&visca::completion());
                        continue;
                    }
                    message(&camera, payload, replier);
                }
                _ => {
                    Stats::count(&camera.stats.malformed);
                    control_reply(sequence, &control::MESSAGE_ERROR);
                }
            },
        }
    }
}

/// Accepts raw VISCA connections for `camera` for ever.
pub async fn serve_tcp(
    listener: TcpListener,
    camera: Arc<Camera>,
    clients: Arc<Vec<(IpAddr, String)>>,
    table: Arc<Connections>,
) {
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(x) => x,
            Err(e) => {
                if may_warn("accept failed", &camera.config.name) {
                    warn!(gimbal = %camera.config.name, error = %e, "accept failed");
                }
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        match Admitted::admit(&table, peer.ip()) {
            Ok((admitted, _)) => {
                if may_warn("VISCA TCP connection accepted", &peer.ip()) {
                    info!(gimbal = %camera.config.name, %peer, "VISCA TCP connection accepted");
                }
                let _ = stream.set_nodelay(true);
                let user = user_of(&clients, peer.ip());
                tokio::spawn(connection(stream, peer, admitted, Arc::clone(&camera), user));
            }
            Err((why, _)) => {
                let total = Stats::count(&camera.stats.tcp_refused);
                if may_warn("VISCA TCP connection refused", &peer.ip()) {
                    warn!(gimbal = %camera.config.name, %peer, why, total, "VISCA TCP connection refused");
                }
            }
        }
    }
}

/// One raw VISCA connection, until it closes, is evicted or falls idle.
async fn connection(
    stream: tokio::net::TcpStream,
    peer: SocketAddr,
    mut admitted: Admitted,
    camera: Arc<Camera>,
    user: Option<Arc<str>>,
) {
    let (mut rd, mut wr) = tokio::io::split(admitted.track(stream));
    let (tx, mut rx) = mpsc::channel::<Vec<u8>>(TCP_QUEUE);
    let writer = tokio::spawn(async move {
        while let Some(bytes) = rx.recv().await {
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    let mut deframer = Deframer::default();
    let mut buf = [0u8; 512];
    loop {
        let n = tokio::select! {
            read = rd.read(&mut buf) => match read {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            },
            _ = admitted.ended() => break,
        };
        deframer.push(&buf[..n], |piece| match piece {
            Piece::Message(m) => {
                let replier = Replier {
                    to: Out::Tcp(tx.clone()),
                    peer,
                    user: user.clone(),
                };
                message(&camera, m, replier);
            }
            Piece::Overlong => {
                Stats::count(&camera.stats.malformed);
                let _ = tx.try_send(visca::syntax_error());
            }
        });
    }
    writer.abort();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_numbers_are_refused_repeats_told_and_reset_starts_afresh() {
        let mut q = Sequences::default();
        let (a, b): (SocketAddr, SocketAddr) = ("127.0.0.3:5000".parse().unwrap(), "127.0.0.3:5001".parse().unwrap());
        let now = Instant::now();
        assert_eq!(q.accept(a, 10, b"x", now), Seen::Fresh);
        assert_eq!(q.accept(a, 11, b"y", now), Seen::Fresh);
        assert_eq!(q.accept(a, 10, b"x", now), Seen::Old);
        assert_eq!(q.accept(a, 11, b"y", now), Seen::Repeat);
        assert_eq!(
            q.accept(a, 11, b"z", now),
            Seen::Fresh,
            "the same number, other bytes: carried out"
        );
        assert_eq!(q.accept(b, 1, b"x", now), Seen::Fresh, "each source port its own");
        assert_eq!(
            q.accept(a, 3, b"x", now + FORGET),
            Seen::Fresh,
            "a client silent long enough starts afresh"
        );
        assert_eq!(q.accept(a, 2, b"x", now + FORGET), Seen::Old);
        q.reset(a.ip());
        assert_eq!(q.accept(a, 1, b"x", now + FORGET), Seen::Fresh);
        assert_eq!(q.accept(a, 0, b"x", now + FORGET), Seen::Old);
        assert_eq!(
            q.accept(a, u32::MAX, b"x", now + FORGET),
            Seen::Old,
            "just below 0, wrapped"
        );
        assert_eq!(q.accept(a, 5, b"x", now + FORGET), Seen::Fresh);
    }

    #[test]
    fn the_sources_kept_are_bounded() {
        let mut q = Sequences::default();
        let now = Instant::now();
        for port in 0..1000u16 {
            let from = SocketAddr::from(([127, 0, 0, 3], port));
            q.accept(from, 1, b"x", now + Duration::from_millis(u64::from(port)));
        }
        assert_eq!(q.seen.len(), SOURCES);
    }
}
