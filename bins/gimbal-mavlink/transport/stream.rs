//! MAVLink 2 over byte streams: TCP (`tcp_listen`, `tcp`) and serial lines
//! (`serial`).
//!
//! Each connection is read into one buffer of [`BUFFER`] bytes and its
//! frames are read in place (`wire::scan`) before more is read: when the
//! router is slower than the peer, the socket is simply not read (TCP's
//! own flow control holds the peer back), so a connection never holds
//! more than that buffer and its write queue, and nothing is left when it
//! closes. The bytes around intact frames (damaged frames, noise) are
//! counted as `damaged`, one count per run between frames. With signing
//! on, a frame not signed with the key is refused before it is read, and
//! only a frame that passes keeps an accepted connection from idling
//! (a peer without the key is evicted as an idle one).
//!
//! Every message this program sends to everyone goes to every connection
//! through a bounded queue: a peer that does not read loses messages, it
//! never stalls the others; an answer goes to the asker's connection only.
//!
//! Accepted connections (`tcp_listen`) are admitted by the shared bounded
//! listener's table (`sagebrush_service::Connections`, gcud's and
//! gimbal-onvif's too): at most [`MAX_CONNECTIONS`]; when they are all taken, the
//! one idle the longest, if idle for at least `sagebrush_service::admission::MIN_IDLE_TO_EVICT`, is
//! closed for the newcomer (else the newcomer is refused); at most
//! [`MAX_PER_PEER`] from one address off this machine; a connection that
//! sends nothing for [`IDLE_TIMEOUT`] is closed. The configured `tcp` and
//! `serial` endpoints never count against these: peers on the network
//! cannot lock them out.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;
use sagebrush_host::backoff::Backoff;
use sagebrush_host::transport::{connect_tcp, open_serial};
use sagebrush_service::{Admission, Connections, Limits};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::sync::{Notify, mpsc};
use tokio::time::Instant;
use tracing::{debug, info, warn};

use crate::stats::{Stats, may_warn, peer_ip};
use crate::transport::net::{Net, Peer, Screened};
use crate::transport::wire::{self, MAX_FRAME, Scan};

/// What is done with each intact message that comes in.
pub type Handler = Arc<dyn Fn(MavHeader, MavMessage) + Send + Sync>;

/// The most connections accepted on `tcp_listen` endpoints open at once.
pub const MAX_CONNECTIONS: usize = 8;
/// The most accepted connections from one address off this machine (every
/// local client is the same loopback address, so it is not capped).
pub const MAX_PER_PEER: usize = MAX_CONNECTIONS / 2;
/// An accepted connection that sent nothing for this long is closed
/// (ground stations send a heartbeat every second).
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(30);
/// A connection's read buffer: the most of a peer's bytes held at once.
pub const BUFFER: usize = 8192;
/// Messages waiting to be written to one connection.
const QUEUE: usize = 256;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

// ---- the open connections ------------------------------------------------------

/// One frame to write.
type Out = Arc<[u8]>;

/// One open connection's write queue.
#[derive(Debug)]
struct Conn {
    id: u64,
    tx: mpsc::Sender<Out>,
}

/// The open connections' write queues, and who may hold an accepted one.
#[derive(Debug)]
pub struct Streams {
    net: Arc<Net>,
    conns: Mutex<Vec<Conn>>,
    next: AtomicU64,
    /// Who may hold an accepted connection: the shared bounded listener's table.
    admission: Arc<Connections>,
}

impl Streams {
    pub fn new(net: Arc<Net>) -> Self {
        Self {
            net,
            conns: Mutex::default(),
            next: AtomicU64::new(0),
            admission: Connections::new(Limits {
                max_total: MAX_CONNECTIONS,
                max_per_peer: MAX_PER_PEER,
                cap_loopback: false,
                idle_timeout: IDLE_TIMEOUT,
            }),
        }
    }

    /// Queues `bytes` (one frame) for every open connection.
    pub fn send(&self, bytes: &[u8]) {
        let conns = lock(&self.conns);
        if conns.is_empty() {
            return;
        }
        let bytes: Arc<[u8]> = bytes.into();
        for c in conns.iter() {
            let _ = c.tx.try_send(Arc::clone(&bytes));
        }
    }

    /// Queues `bytes` for connection `id` alone, if it is open.
    pub fn send_to(&self, id: u64, bytes: &[u8]) {
        if let Some(c) = lock(&self.conns).iter().find(|c| c.id == id) {
            let _ = c.tx.try_send(bytes.into());
        }
    }

    /// A new connection: its id, a sender into its queue and the queue.
    fn add(&self) -> (u64, mpsc::Sender<Out>, mpsc::Receiver<Out>) {
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let (tx, rx) = mpsc::channel(QUEUE);
        lock(&self.conns).push(Conn { id, tx: tx.clone() });
        (id, tx, rx)
    }

    fn remove(&self, id: u64) {
        lock(&self.conns).retain(|c| c.id != id);
    }

    #[cfg(test)]
    fn open(&self) -> usize {
        lock(&self.conns).len()
    }
}

/// How a connection ends.
#[derive(Debug, PartialEq, Eq)]
enum End {
    Closed,
    Evicted,
    Idle,
}

/// Serves one connection (a TCP socket, a serial line) until it closes,
/// is evicted for a newcomer (`admitted`: its key and notice) or falls idle.
async fn serve<S>(
    stream: S,
    admitted: Option<(u64, Arc<Notify>)>,
    peer: String,
    streams: Arc<Streams>,
    stats: Arc<Stats>,
    handler: Handler,
) where
    S: AsyncRead + AsyncWrite + Send + 'static,
{
    let (id, answers, mut out) = streams.add();
    let (mut rd, mut wr) = tokio::io::split(stream);
    let writer = tokio::spawn(async move {
        while let Some(bytes) = out.recv().await {
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    let mut buf = vec![0u8; BUFFER];
    let mut len = 0;
    // Bytes since the last intact frame that were none.
    let mut run = 0usize;
    let key = admitted.as_ref().map(|(k, _)| *k);
    let close = admitted.map(|(_, c)| c);
    let end = loop {
        let idle_at = key.and_then(|k| streams.admission.idle_at(k));
        let read = tokio::select! {
            read = rd.read(&mut buf[len..]) => read,
            () = async { close.as_ref().expect("admitted").notified().await }, if close.is_some() => break End::Evicted,
            () = tokio::time::sleep_until(idle_at.unwrap_or_else(Instant::now)), if idle_at.is_some() => break End::Idle,
        };
        let n = match read {
            Ok(0) | Err(_) => break End::Closed,
            Ok(n) => n,
        };
        // Any bytes keep a connection busy; with signing, a frame signed with the key.
        let mut busy = !streams.net.signed();
        len += n;
        let mut at = 0;
        loop {
            match wire::scan(&buf[at..len]) {
                Scan::Frame { skip, len: frame } => {
                    run += skip;
                    if run > 0 {
                        stats.damaged(&peer, run);
                        run = 0;
                    }
                    let bytes = &buf[at + skip..at + skip + frame];
                    if streams.net.admits(bytes, &peer, &stats) {
                        busy = true;
                        match streams.net.screen(wire::decode(bytes), Peer::Stream(id), &peer, &stats) {
                            Screened::Handle(header, message) => handler(header, message),
                            Screened::Answer(bytes) => {
                                let _ = answers.try_send(bytes.into());
                            }
                            Screened::Drop => {}
                        }
                    }
                    at += skip + frame;
                }
                Scan::Partial { skip } => {
                    run += skip;
                    at += skip;
                    break;
                }
            }
        }
        if let (Some(k), true) = (key, busy) {
            streams.admission.touch(k, Instant::now());
        }
        // What is left may be the head of a frame: shorter than one.
        debug_assert!(len - at < MAX_FRAME);
        buf.copy_within(at..len, 0);
        len -= at;
    };
    run += len;
    if run > 0 {
        stats.damaged(&peer, run);
    }
    streams.remove(id);
    lock(&streams.net.heard).forget(Peer::Stream(id));
    writer.abort();
    if let Some(k) = key {
        streams.admission.left(k, end == End::Idle);
    }
    match end {
        // A peer connecting again and again writes a bounded number of lines.
        End::Closed => {
            if may_warn("MAVLink connection closed", &peer_ip(&peer)) {
                info!(%peer, "MAVLink connection closed");
            }
        }
        End::Evicted => {
            Stats::count(&stats.tcp_evicted);
            if may_warn("MAVLink connection closed for a newcomer", &peer) {
                warn!(%peer, idle_s = sagebrush_service::admission::MIN_IDLE_TO_EVICT.as_secs(), "MAVLink connection idle the longest closed for a newcomer");
            }
        }
        End::Idle => {
            Stats::count(&stats.tcp_idle_closed);
            if may_warn("MAVLink connection idle: closed", &peer) {
                warn!(%peer, idle_s = IDLE_TIMEOUT.as_secs(), "MAVLink connection sent nothing: closed");
            }
        }
    }
}

/// `tcp_listen`: accepts connections for ever, as the admission table admits them.
pub async fn listen(listener: TcpListener, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => match streams.admission.admit(peer.ip(), Instant::now()) {
                Admission::Admitted { key, close, evicted } => {
                    if may_warn("MAVLink TCP connection accepted", &peer.ip()) {
                        info!(
                            %peer,
                            evicted = evicted.map_or_else(|| "none".to_owned(), |ip| ip.to_string()),
                            "MAVLink TCP connection accepted"
                        );
                    }
                    let _ = stream.set_nodelay(true);
                    tokio::spawn(serve(
                        stream,
                        Some((key, close)),
                        peer.to_string(),
                        Arc::clone(&streams),
                        Arc::clone(&stats),
                        Arc::clone(&handler),
                    ));
                }
                Admission::Refused { why, .. } => {
                    Stats::count(&stats.tcp_refused);
                    if may_warn("MAVLink TCP connection refused", &peer.ip()) {
                        warn!(%peer, max = MAX_CONNECTIONS, why, "MAVLink TCP connection refused");
                    }
                }
            },
            Err(e) => {
                if may_warn("accept failed", &"tcp_listen") {
                    warn!(error = %e, "accept failed");
                }
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// `tcp`: keeps a connection to `to` open, connecting again after the
/// shared back-off (`sagebrush_host::backoff`, gcud's own).
pub async fn connect(to: String, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    let mut backoff = Backoff::new();
    loop {
        match connect_tcp(&to).await {
            Ok(stream) => {
                backoff.reset();
                let peer = stream
                    .peer_addr()
                    .unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
                info!(%peer, "MAVLink TCP connected");
                serve(
                    stream,
                    None,
                    peer.to_string(),
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                )
                .await;
            }
            Err(e) => {
                if may_warn("MAVLink TCP connection failed", &to) {
                    warn!(to = %to, error = %e, "MAVLink TCP connection failed; retrying with backoff");
                }
            }
        }
        tokio::time::sleep(backoff.next_delay()).await;
    }
}

/// `serial`: keeps `path` open at `baud` (8N1, as gcud opens its buses:
/// `sagebrush_host::transport::open_serial`), opening it again after the
/// shared back-off when it closes or is not there (an adapter plugged in
/// later). The first failure in a row is a warning, the rest are debug.
pub async fn serial(path: PathBuf, baud: u32, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    let name = path.display().to_string();
    let mut failed = false;
    let mut backoff = Backoff::new();
    loop {
        match open_serial(&name, baud) {
            Ok(port) => {
                failed = false;
                backoff.reset();
                info!(path = %name, baud, "MAVLink serial line open");
                serve(
                    port,
                    None,
                    name.clone(),
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                )
                .await;
            }
            Err(e) if !failed => {
                failed = true;
                warn!(path = %name, baud, error = %e, "cannot open the MAVLink serial line; retrying with backoff");
            }
            Err(e) => debug!(path = %name, error = %e, "cannot open the MAVLink serial line"),
        }
        tokio::time::sleep(backoff.next_delay()).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_connection_holds_one_buffer_and_leaves_nothing_when_it_closes() {
        let streams = Arc::new(Streams::new(Arc::new(Net::new(1, None))));
        let stats = Arc::new(Stats::default());
        let (mut ours, theirs) = tokio::io::duplex(1024);
        let handled = Arc::new(AtomicU64::new(0));
        let h = Arc::clone(&handled);
        let handler: Handler = Arc::new(move |_, _| {
            h.fetch_add(1, Ordering::Relaxed);
        });
        let task = tokio::spawn(serve(
            theirs,
            None,
            "test".into(),
            Arc::clone(&streams),
            Arc::clone(&stats),
            handler,
        ));
        let beat = wire::encode(
            MavHeader {
                system_id: 255,
                component_id: 190,
                sequence: 0,
            },
            &MavMessage::HEARTBEAT(Default::default()),
        );
        // Noise, a frame split in two writes, noise at the end.
        ours.write_all(b"noise").await.unwrap();
        ours.write_all(&beat[..5]).await.unwrap();
        ours.write_all(&beat[5..]).await.unwrap();
        ours.write_all(&[0xFE, 0x20, 1, 2]).await.unwrap();
        drop(ours);
        task.await.unwrap();
        assert_eq!(handled.load(Ordering::Relaxed), 1);
        assert_eq!(stats.damaged_bytes.load(Ordering::Relaxed), 5 + 4);
        assert_eq!(stats.damaged.load(Ordering::Relaxed), 2, "one count per run");
        assert_eq!(streams.open(), 0, "nothing left");
    }
}
