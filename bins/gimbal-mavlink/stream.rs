//! MAVLink 2 over byte streams: TCP (`tcp_listen`, `tcp`) and serial lines
//! (`serial`). Each connection's bytes are read into messages by the
//! `mavlink` crate's reader (which keeps partial frames between reads) on a
//! blocking thread; the bytes around intact frames (damaged frames, noise)
//! are counted as `damaged`. Every message this program sends goes to every
//! connection through a bounded queue: a peer that does not read loses
//! messages, it never stalls the others.

use std::io::{self, Read};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, Message};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_serial::SerialPortBuilderExt;
use tracing::{debug, info, warn};

use crate::stats::Stats;

/// What is done with each intact message that comes in.
pub type Handler = Arc<dyn Fn(MavHeader, MavMessage) + Send + Sync>;

/// The most connections accepted on `tcp_listen` endpoints served at once
/// (each has a reader thread). The configured `tcp` and `serial` endpoints
/// never count against it: peers on the network cannot lock them out.
pub const MAX_CONNECTIONS: usize = 8;
/// Messages waiting to be written to one connection.
const QUEUE: usize = 256;
/// How long a `tcp` or `serial` endpoint waits before connecting or opening again.
pub const RECONNECT: Duration = Duration::from_secs(2);

/// How a connection came to be: accepted from a peer (a `tcp_listen`
/// endpoint, at most [`MAX_CONNECTIONS`] at once), or opened for a
/// configured `tcp` or `serial` endpoint (one each, outside that limit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Opened {
    Accepted,
    Configured,
}

/// One open connection's write queue (frames to send), and how it opened.
type Conn = (mpsc::Sender<Arc<[u8]>>, Opened);

/// The open connections' write queues.
#[derive(Debug, Default)]
pub struct Streams {
    conns: Mutex<Vec<Conn>>,
}

impl Streams {
    /// Queues `bytes` (one frame) for every open connection.
    pub fn send(&self, bytes: &[u8]) {
        let mut conns = self.conns.lock().unwrap_or_else(|p| p.into_inner());
        conns.retain(|(c, _)| !c.is_closed());
        if conns.is_empty() {
            return;
        }
        let bytes: Arc<[u8]> = bytes.into();
        for (c, _) in conns.iter() {
            let _ = c.try_send(Arc::clone(&bytes));
        }
    }

    /// A new connection's queue, or `None` for an accepted one when
    /// [`MAX_CONNECTIONS`] accepted ones are open.
    fn add(&self, opened: Opened) -> Option<mpsc::Receiver<Arc<[u8]>>> {
        let mut conns = self.conns.lock().unwrap_or_else(|p| p.into_inner());
        conns.retain(|(c, _)| !c.is_closed());
        let accepted = conns.iter().filter(|(_, o)| *o == Opened::Accepted).count();
        if opened == Opened::Accepted && accepted >= MAX_CONNECTIONS {
            return None;
        }
        let (tx, rx) = mpsc::channel(QUEUE);
        conns.push((tx, opened));
        Some(rx)
    }
}

/// Chunks read from a connection, as the blocking `Read` the reader wants.
/// It hands out one byte per call, so that when the reader returns a frame
/// it holds nothing beyond the frame's last byte: `handed` then tells
/// exactly how many bytes came before the frame (see [`Framing`]).
struct Chunks {
    rx: std::sync::mpsc::Receiver<Vec<u8>>,
    chunk: Vec<u8>,
    at: usize,
    /// Bytes handed to the reader so far.
    handed: u64,
}

impl Read for Chunks {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.at == self.chunk.len() {
            match self.rx.recv() {
                Ok(chunk) => (self.chunk, self.at) = (chunk, 0),
                Err(_) => return Ok(0),
            }
        }
        let Some(first) = buf.first_mut() else {
            return Ok(0);
        };
        *first = self.chunk[self.at];
        self.at += 1;
        self.handed += 1;
        Ok(1)
    }
}

/// Where a stream's bytes went: into intact frames, or around them.
#[derive(Debug, Default)]
struct Framing {
    /// Bytes handed to the reader when the last frame ended.
    framed_up_to: u64,
}

impl Framing {
    /// A frame of `len` bytes ended with byte `handed`: the bytes before it
    /// since the last frame that were no intact frame (0 when none).
    fn frame(&mut self, handed: u64, len: u64) -> u64 {
        let skipped = handed.saturating_sub(len).saturating_sub(self.framed_up_to);
        self.framed_up_to = handed;
        skipped
    }

    /// The stream ended with byte `handed`: the bytes after the last frame.
    fn end(&self, handed: u64) -> u64 {
        handed.saturating_sub(self.framed_up_to)
    }
}

/// The length of a raw frame, signature included.
fn frame_len(raw: &MAVLinkMessageRaw) -> u64 {
    match raw {
        MAVLinkMessageRaw::V1(m) => m.raw_bytes().len() as u64,
        MAVLinkMessageRaw::V2(m) => m.raw_bytes().len() as u64,
    }
}

/// Serves one connection (a TCP socket, a serial line) until it closes.
async fn serve<S>(stream: S, opened: Opened, peer: String, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler)
where
    S: AsyncRead + AsyncWrite + Send + 'static,
{
    let Some(mut out) = streams.add(opened) else {
        warn!(%peer, max = MAX_CONNECTIONS, "too many MAVLink TCP connections accepted: refused");
        return;
    };
    let (mut rd, mut wr) = tokio::io::split(stream);
    let writer = tokio::spawn(async move {
        while let Some(bytes) = out.recv().await {
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    let (chunk_tx, chunk_rx) = std::sync::mpsc::channel::<Vec<u8>>();
    let (msg_tx, mut msg_rx) = mpsc::channel::<(MavHeader, MavMessage)>(QUEUE);
    let decoder = {
        let (stats, peer) = (Arc::clone(&stats), peer.clone());
        tokio::task::spawn_blocking(move || {
            let mut reader = mavlink::MavlinkReader::new(Chunks {
                rx: chunk_rx,
                chunk: Vec::new(),
                at: 0,
                handed: 0,
            });
            let mut framing = Framing::default();
            loop {
                let raw = match reader.read_any_raw_message::<MavMessage>() {
                    Ok(raw) => raw,
                    Err(mavlink::error::MessageReadError::Parse(_)) => continue,
                    Err(_) => break,
                };
                let skipped = framing.frame(reader.get_ref().handed, frame_len(&raw));
                if skipped > 0 {
                    stats.damaged(&peer, skipped as usize);
                }
                let header = MavHeader {
                    system_id: raw.system_id(),
                    component_id: raw.component_id(),
                    sequence: raw.sequence(),
                };
                match MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) {
                    Ok(message) => {
                        if msg_tx.blocking_send((header, message)).is_err() {
                            return;
                        }
                    }
                    Err(_) => stats.damaged(&peer, frame_len(&raw) as usize),
                }
            }
            let trailing = framing.end(reader.get_ref().handed);
            if trailing > 0 {
                stats.damaged(&peer, trailing as usize);
            }
        })
    };
    let dispatch = tokio::spawn(async move {
        while let Some((header, message)) = msg_rx.recv().await {
            Stats::count(&stats.received);
            handler(header, message);
        }
    });
    let mut buf = vec![0u8; 4096];
    loop {
        match rd.read(&mut buf).await {
            Ok(0) | Err(_) => break,
            Ok(n) => {
                if chunk_tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        }
    }
    // The reader sees the end, then the dispatcher; the writer stops now.
    drop(chunk_tx);
    writer.abort();
    let _ = decoder.await;
    let _ = dispatch.await;
    info!(%peer, "MAVLink connection closed");
}

/// `tcp_listen`: accepts connections for ever.
pub async fn listen(listener: TcpListener, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                info!(%peer, "MAVLink TCP connection accepted");
                let _ = stream.set_nodelay(true);
                tokio::spawn(serve(
                    stream,
                    Opened::Accepted,
                    peer.to_string(),
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                ));
            }
            Err(e) => {
                warn!(error = %e, "accept failed");
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// `tcp`: keeps a connection to `to` open, connecting again after [`RECONNECT`].
pub async fn connect(to: String, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match TcpStream::connect(&to).await {
            Ok(stream) => {
                let peer = stream
                    .peer_addr()
                    .unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
                info!(%peer, "MAVLink TCP connected");
                let _ = stream.set_nodelay(true);
                serve(
                    stream,
                    Opened::Configured,
                    peer.to_string(),
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                )
                .await;
            }
            Err(e) => warn!(to = %to, error = %e, "MAVLink TCP connection failed"),
        }
        tokio::time::sleep(RECONNECT).await;
    }
}

/// `serial`: keeps `path` open at `baud`, opening it again after
/// [`RECONNECT`] when it closes or is not there (an adapter plugged in
/// later). The first failure in a row is a warning, the rest are debug.
pub async fn serial(path: PathBuf, baud: u32, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    let name = path.display().to_string();
    let mut failed = false;
    loop {
        match tokio_serial::new(name.as_str(), baud).open_native_async() {
            Ok(port) => {
                failed = false;
                info!(path = %name, baud, "MAVLink serial line open");
                serve(
                    port,
                    Opened::Configured,
                    name.clone(),
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                )
                .await;
            }
            Err(e) if !failed => {
                failed = true;
                warn!(path = %name, baud, error = %e, "cannot open the MAVLink serial line; trying again every 2 s");
            }
            Err(e) => debug!(path = %name, error = %e, "cannot open the MAVLink serial line"),
        }
        tokio::time::sleep(RECONNECT).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepted_connections_at_their_limit_leave_room_for_configured_ones() {
        let streams = Streams::default();
        let accepted: Vec<_> = (0..MAX_CONNECTIONS)
            .map(|_| streams.add(Opened::Accepted).expect("room"))
            .collect();
        assert!(streams.add(Opened::Accepted).is_none(), "the limit holds");
        let serial = streams
            .add(Opened::Configured)
            .expect("a serial line is never locked out");
        let tcp = streams.add(Opened::Configured).expect("nor a configured tcp endpoint");
        assert!(
            streams.add(Opened::Accepted).is_none(),
            "configured ones take no accepted slot"
        );
        drop(accepted);
        assert!(streams.add(Opened::Accepted).is_some(), "closed ones free their slots");
        drop((serial, tcp));
    }

    #[test]
    fn bytes_around_frames_are_counted_once_each() {
        let mut f = Framing::default();
        // A 12-byte frame right at the start: nothing skipped.
        assert_eq!(f.frame(12, 12), 0);
        // 5 bytes of noise, then a 20-byte frame.
        assert_eq!(f.frame(37, 20), 5);
        // A frame right after it.
        assert_eq!(f.frame(49, 12), 0);
        // 3 bytes after the last frame when the stream ends.
        assert_eq!(f.end(52), 3);
        assert_eq!(f.end(49), 0);
    }
}
