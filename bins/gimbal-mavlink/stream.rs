//! MAVLink 2 over byte streams: TCP (`tcp_listen`, `tcp`) and serial lines
//! (`serial`).
//!
//! Each connection is read into one buffer of [`BUFFER`] bytes and its
//! frames are read in place (`link::scan`) before more is read: when the
//! router is slower than the peer, the socket is simply not read (TCP's
//! own flow control holds the peer back), so a connection never holds
//! more than that buffer and its write queue, and nothing is left when it
//! closes. The bytes around intact frames (damaged frames, noise) are
//! counted as `damaged`, one count per run between frames.
//!
//! Every message this program sends to everyone goes to every connection
//! through a bounded queue: a peer that does not read loses messages, it
//! never stalls the others; an answer goes to the asker's connection only.
//!
//! Accepted connections (`tcp_listen`) are admitted by [`Admission`] (the
//! rules of gcud's admission table, which the shared bounded listener
//! takes over): at most [`MAX_CONNECTIONS`]; when they are all taken, the
//! one idle the longest, if idle for at least [`MIN_IDLE_TO_EVICT`], is
//! closed for the newcomer (else the newcomer is refused); at most
//! [`MAX_PER_PEER`] from one address off this machine; a connection that
//! sends nothing for [`IDLE_TIMEOUT`] is closed. The configured `tcp` and
//! `serial` endpoints never count against these: peers on the network
//! cannot lock them out.

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Notify, mpsc};
use tokio::time::Instant;
use tokio_serial::SerialPortBuilderExt;
use tracing::{debug, info, warn};

use crate::link::{self, MAX_FRAME, Net, Peer, Scan, Screened};
use crate::stats::{Stats, may_warn};

/// What is done with each intact message that comes in.
pub type Handler = Arc<dyn Fn(MavHeader, MavMessage) + Send + Sync>;

/// The most connections accepted on `tcp_listen` endpoints open at once.
pub const MAX_CONNECTIONS: usize = 8;
/// The most accepted connections from one address off this machine (every
/// local client is the same loopback address, so it is not capped).
pub const MAX_PER_PEER: usize = MAX_CONNECTIONS / 2;
/// An accepted connection idle for less than this is never closed for a newcomer.
pub const MIN_IDLE_TO_EVICT: Duration = Duration::from_secs(1);
/// An accepted connection that sent nothing for this long is closed
/// (ground stations send a heartbeat every second).
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(30);
/// A connection's read buffer: the most of a peer's bytes held at once.
pub const BUFFER: usize = 8192;
/// Messages waiting to be written to one connection.
const QUEUE: usize = 256;
/// How long a `tcp` or `serial` endpoint waits before connecting or opening again.
pub const RECONNECT: Duration = Duration::from_secs(2);

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

// ---- admission -----------------------------------------------------------------

/// What happened to a newcomer.
#[derive(Debug)]
pub enum Admitted {
    /// Admitted as `key`; `close` is notified when it must close (evicted
    /// for a newcomer). `evicted`: the address of the one closed for it.
    Yes {
        key: u64,
        close: Arc<Notify>,
        evicted: Option<IpAddr>,
    },
    /// Refused, and why.
    No(&'static str),
}

/// Who may hold an accepted connection: the interface a listener admits
/// by, so that the shared bounded listener's table can replace [`Slots`]
/// (the same calls as its `Connections`: admit, touch, idle_at, left).
pub trait Admission: Send + Sync + std::fmt::Debug {
    /// A newcomer from `peer` at `now`.
    fn admit(&self, peer: IpAddr, now: Instant) -> Admitted;
    /// Connection `key` received bytes at `now`.
    fn touch(&self, key: u64, now: Instant);
    /// When connection `key` falls idle, if it is still admitted.
    fn idle_at(&self, key: u64) -> Option<Instant>;
    /// Connection `key` closed; `idle`: for its idle time-out.
    fn left(&self, key: u64, idle: bool);
}

#[derive(Debug)]
struct Slot {
    key: u64,
    peer: IpAddr,
    last_active: Instant,
    close: Arc<Notify>,
}

/// The rules of the module's documentation, as a table.
#[derive(Debug)]
pub struct Slots {
    max: usize,
    per_peer: usize,
    idle_timeout: Duration,
    open: Mutex<(u64, Vec<Slot>)>,
}

impl Slots {
    pub fn new(max: usize, per_peer: usize, idle_timeout: Duration) -> Self {
        Self {
            max,
            per_peer,
            idle_timeout,
            open: Mutex::new((0, Vec::new())),
        }
    }
}

impl Default for Slots {
    fn default() -> Self {
        Self::new(MAX_CONNECTIONS, MAX_PER_PEER, IDLE_TIMEOUT)
    }
}

impl Admission for Slots {
    fn admit(&self, peer: IpAddr, now: Instant) -> Admitted {
        let mut guard = lock(&self.open);
        let (next, open) = &mut *guard;
        if !peer.is_loopback() && open.iter().filter(|s| s.peer == peer).count() >= self.per_peer {
            return Admitted::No("the most connections from one address are open");
        }
        let mut evicted = None;
        if open.len() >= self.max {
            let idlest = open
                .iter()
                .enumerate()
                .filter(|(_, s)| now.saturating_duration_since(s.last_active) >= MIN_IDLE_TO_EVICT)
                .min_by_key(|(_, s)| s.last_active)
                .map(|(i, _)| i);
            let Some(i) = idlest else {
                return Admitted::No("every connection is open and busy");
            };
            let victim = open.swap_remove(i);
            victim.close.notify_one();
            evicted = Some(victim.peer);
        }
        let key = *next;
        *next += 1;
        let close = Arc::new(Notify::new());
        open.push(Slot {
            key,
            peer,
            last_active: now,
            close: Arc::clone(&close),
        });
        Admitted::Yes { key, close, evicted }
    }

    fn touch(&self, key: u64, now: Instant) {
        if let Some(s) = lock(&self.open).1.iter_mut().find(|s| s.key == key) {
            s.last_active = now;
        }
    }

    fn idle_at(&self, key: u64) -> Option<Instant> {
        lock(&self.open)
            .1
            .iter()
            .find(|s| s.key == key)
            .map(|s| s.last_active + self.idle_timeout)
    }

    fn left(&self, key: u64, _idle: bool) {
        lock(&self.open).1.retain(|s| s.key != key);
    }
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
    admission: Box<dyn Admission>,
}

impl Streams {
    pub fn new(net: Arc<Net>) -> Self {
        Self::with_admission(net, Box::new(Slots::default()))
    }

    pub fn with_admission(net: Arc<Net>, admission: Box<dyn Admission>) -> Self {
        Self {
            net,
            conns: Mutex::default(),
            next: AtomicU64::new(0),
            admission,
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
        if let Some(k) = key {
            streams.admission.touch(k, Instant::now());
        }
        len += n;
        let mut at = 0;
        loop {
            match link::scan(&buf[at..len]) {
                Scan::Frame { skip, len: frame } => {
                    run += skip;
                    if run > 0 {
                        stats.damaged(&peer, run);
                        run = 0;
                    }
                    let decoded = link::decode(&buf[at + skip..at + skip + frame]);
                    match streams.net.screen(decoded, Peer::Stream(id), &peer, &stats) {
                        Screened::Handle(header, message) => handler(header, message),
                        Screened::Answer(bytes) => {
                            let _ = answers.try_send(bytes.into());
                        }
                        Screened::Drop => {}
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
                warn!(%peer, idle_s = MIN_IDLE_TO_EVICT.as_secs(), "MAVLink connection idle the longest closed for a newcomer");
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

/// The address part of a peer's name (`IP:PORT`, or a serial device).
fn peer_ip(peer: &str) -> &str {
    peer.parse::<SocketAddr>()
        .map_or(peer, |_| peer.rsplit_once(':').map_or(peer, |(ip, _)| ip))
}

/// `tcp_listen`: accepts connections for ever, as [`Admission`] admits them.
pub async fn listen(listener: TcpListener, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => match streams.admission.admit(peer.ip(), Instant::now()) {
                Admitted::Yes { key, close, evicted } => {
                    if may_warn("MAVLink TCP connection accepted", &peer.ip()) {
                        info!(%peer, ?evicted, "MAVLink TCP connection accepted");
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
                Admitted::No(why) => {
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
                    warn!(to = %to, error = %e, "MAVLink TCP connection failed");
                }
            }
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

    const FAR: [u8; 4] = [192, 0, 2, 1];

    #[tokio::test]
    async fn the_longest_idle_makes_room_for_a_newcomer_busy_ones_never() {
        let slots = Slots::default();
        let local = IpAddr::from([127, 0, 0, 1]);
        let t0 = Instant::now();
        let keys: Vec<u64> = (0..MAX_CONNECTIONS)
            .map(|i| match slots.admit(local, t0 + Duration::from_millis(i as u64)) {
                Admitted::Yes { key, evicted: None, .. } => key,
                other => panic!("{other:?}"),
            })
            .collect();
        // All busy (active under a second ago): the newcomer is refused.
        assert!(matches!(
            slots.admit(local, t0 + Duration::from_millis(500)),
            Admitted::No(_)
        ));
        // Every one idle, the first touched again: the second goes.
        let later = t0 + Duration::from_secs(2);
        slots.touch(keys[0], later);
        let Admitted::Yes { evicted, .. } = slots.admit(local, later) else {
            panic!("refused")
        };
        assert_eq!(evicted, Some(local));
        assert!(slots.idle_at(keys[1]).is_none(), "the second was evicted");
        assert!(slots.idle_at(keys[0]).is_some(), "the first, active, stays");
        assert_eq!(
            slots.idle_at(keys[2]),
            Some(t0 + Duration::from_millis(2) + IDLE_TIMEOUT)
        );
    }

    #[tokio::test]
    async fn one_address_off_this_machine_holds_at_most_its_share() {
        let slots = Slots::default();
        let far = IpAddr::from(FAR);
        let now = Instant::now();
        for _ in 0..MAX_PER_PEER {
            assert!(matches!(slots.admit(far, now), Admitted::Yes { .. }));
        }
        assert!(matches!(slots.admit(far, now), Admitted::No(_)));
        assert!(matches!(
            slots.admit(IpAddr::from([192, 0, 2, 2]), now),
            Admitted::Yes { .. }
        ));
    }

    #[tokio::test]
    async fn a_connection_holds_one_buffer_and_leaves_nothing_when_it_closes() {
        let streams = Arc::new(Streams::new(Arc::new(Net::new(1))));
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
        let beat = link::encode(
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
