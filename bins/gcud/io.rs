//! Byte pipes between the world and the router task: device ports (serial,
//! TCP device server, in-process simulator) and links (serial, TCP listener,
//! TCP client). Every pipe reconnects by itself with backoff when its device
//! or peer is missing or vanishes, without disturbing any other pipe
//! (ARCHITECTURE "Layers", 3: transport).

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use sagebrush_gcu::LinkId;
use sagebrush_host::capture::{CaptureSwitch, Role, Tap};
use sagebrush_host::transport::{SerialOrTcp, connect_tcp, open_serial};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Notify, mpsc, oneshot};

use crate::admission::{Admission, Connections};
use tracing::{debug, info, warn};

use crate::config::{Link, LinkRole, LinkTransport, Port, PortTransport};

/// What a pipe tells the router task.
#[derive(Debug)]
pub enum IoEvent {
    PortOpened {
        port: u8,
        writer: mpsc::Sender<PortWrite>,
    },
    PortBytes {
        port: u8,
        bytes: Vec<u8>,
    },
    PortClosed {
        port: u8,
    },
    LinkOpened {
        id: LinkId,
        /// The configured link's name.
        link: String,
        peer: String,
        writer: mpsc::Sender<Vec<u8>>,
    },
    LinkBytes {
        id: LinkId,
        bytes: Vec<u8>,
    },
    LinkClosed {
        id: LinkId,
    },
    /// A metrics scrape wants a snapshot of the counters (rendered off the router task).
    Scrape(oneshot::Sender<crate::stats::Snapshot>),
}

/// What the router task asks of a port.
#[derive(Debug)]
pub enum PortWrite {
    Bytes(Vec<u8>),
    /// Switch the line rate (after an acknowledged `C0..C7`, Table 4).
    SetBaud(u32),
}

/// Exponential backoff: 250 ms doubling to 10 s.
#[derive(Debug)]
pub struct Backoff(Duration);

impl Backoff {
    const FIRST: Duration = Duration::from_millis(250);
    const MAX: Duration = Duration::from_secs(10);

    pub fn new() -> Self {
        Self(Self::FIRST)
    }

    pub fn reset(&mut self) {
        self.0 = Self::FIRST;
    }

    pub fn next_delay(&mut self) -> Duration {
        let d = self.0;
        self.0 = (self.0 * 2).min(Self::MAX);
        d
    }
}

/// A port's byte stream, with a line-rate switch where the medium has one.
pub trait PortStream: AsyncRead + AsyncWrite + Unpin + Send {
    fn set_baud(&mut self, baud: u32) -> io::Result<()>;
}

impl PortStream for tokio_serial::SerialStream {
    fn set_baud(&mut self, baud: u32) -> io::Result<()> {
        sagebrush_host::transport::set_baud(self, baud)
    }
}

impl PortStream for TcpStream {
    fn set_baud(&mut self, baud: u32) -> io::Result<()> {
        // The device server owns the serial line; its rate is configured there.
        warn!(
            baud,
            "line rate change on a TCP device server port is not applied locally"
        );
        Ok(())
    }
}

impl PortStream for tokio::io::DuplexStream {
    fn set_baud(&mut self, _baud: u32) -> io::Result<()> {
        Ok(())
    }
}

/// An open port, whichever its medium.
enum OpenPort {
    Serial(tokio_serial::SerialStream),
    Tcp(TcpStream),
    #[cfg(feature = "sim")]
    Simulated(tokio::io::DuplexStream),
}

async fn open_port(port: &Port, baud: u32) -> io::Result<OpenPort> {
    Ok(match &port.transport {
        PortTransport::Serial(path) => OpenPort::Serial(open_serial(&path.to_string_lossy(), baud)?),
        PortTransport::Tcp(addr) => OpenPort::Tcp(connect_tcp(addr).await?),
        #[cfg(feature = "sim")]
        PortTransport::Simulated(devices) => OpenPort::Simulated(crate::simulated::spawn(port.id, devices, baud)),
        #[cfg(not(feature = "sim"))]
        PortTransport::Simulated(_) => {
            return Err(io::Error::other(
                "simulated port: this gcud was built without the `sim` feature",
            ));
        }
    })
}

/// Why a port stopped pumping.
enum PortEnd {
    /// The line failed (end of stream, an I/O error): a loss, reopened.
    Lost(String),
    /// The router let go of the port (gcud shutting down): not a loss.
    Released,
}

/// Moves bytes between `stream` and the router until the stream fails or
/// the router lets go. `baud` follows line-rate switches, so that a reopened
/// port keeps the rate its devices were switched to.
async fn pump_port<S: PortStream>(
    port: u8,
    mut stream: S,
    baud: &mut u32,
    writes: &mut mpsc::Receiver<PortWrite>,
    events: &mpsc::Sender<IoEvent>,
    tap: &mut Tap,
) -> PortEnd {
    let mut buf = vec![0u8; 4096];
    loop {
        tokio::select! {
            read = stream.read(&mut buf) => match read {
                Ok(0) => return PortEnd::Lost("end of stream".to_owned()),
                Ok(n) => {
                    tap.inbound(&buf[..n]);
                    if events.send(IoEvent::PortBytes { port, bytes: buf[..n].to_vec() }).await.is_err() {
                        return PortEnd::Released;
                    }
                }
                Err(e) => return PortEnd::Lost(format!("read failed: {e}")),
            },
            write = writes.recv() => match write {
                Some(PortWrite::Bytes(bytes)) => {
                    tap.outbound(&bytes);
                    if let Err(e) = stream.write_all(&bytes).await {
                        return PortEnd::Lost(format!("write failed: {e}"));
                    }
                }
                Some(PortWrite::SetBaud(rate)) => {
                    if let Err(e) = stream.set_baud(rate) {
                        return PortEnd::Lost(format!("cannot switch line rate to {rate}: {e}"));
                    }
                    *baud = rate;
                    info!(port, baud = rate, "line rate switched");
                }
                None => return PortEnd::Released,
            },
        }
    }
}

/// Keeps one port open for as long as the daemon runs; ends quietly (info)
/// once the router lets go of it (shutdown).
pub async fn run_port(port: Port, events: mpsc::Sender<IoEvent>, capture: Arc<CaptureSwitch>) {
    let mut tap = capture.tap(format!("port {} {}", port.id, describe(&port.transport)), Role::Master);
    let mut backoff = Backoff::new();
    let mut baud = port.timing.baud;
    let mut last_error = String::new();
    loop {
        match open_port(&port, baud).await {
            Ok(stream) => {
                backoff.reset();
                last_error.clear();
                info!(port = port.id, transport = %describe(&port.transport), baud, "port open");
                let (writer, mut writes) = mpsc::channel(256);
                if events
                    .send(IoEvent::PortOpened { port: port.id, writer })
                    .await
                    .is_err()
                {
                    return;
                }
                let (id, w, e, t) = (port.id, &mut writes, &events, &mut tap);
                let end = match stream {
                    OpenPort::Serial(s) => pump_port(id, s, &mut baud, w, e, t).await,
                    OpenPort::Tcp(s) => pump_port(id, s, &mut baud, w, e, t).await,
                    #[cfg(feature = "sim")]
                    OpenPort::Simulated(s) => pump_port(id, s, &mut baud, w, e, t).await,
                };
                let PortEnd::Lost(reason) = end else {
                    info!(port = port.id, "port closed: gcud stopping");
                    return;
                };
                warn!(port = port.id, %reason, "port lost; reopening");
                if events.send(IoEvent::PortClosed { port: port.id }).await.is_err() {
                    return;
                }
            }
            Err(e) => {
                let error = e.to_string();
                if error != last_error {
                    warn!(port = port.id, transport = %describe(&port.transport), %error, "cannot open port; retrying with backoff");
                    last_error = error;
                } else {
                    debug!(port = port.id, %error, "port still unavailable");
                }
            }
        }
        tokio::select! {
            () = tokio::time::sleep(backoff.next_delay()) => {}
            () = events.closed() => return,
        }
    }
}

fn describe(t: &PortTransport) -> String {
    match t {
        PortTransport::Serial(p) => p.display().to_string(),
        PortTransport::Tcp(a) => format!("tcp {a}"),
        PortTransport::Simulated(d) => format!("simulated devices {d:?}"),
    }
}

// ---- links ----------------------------------------------------------------

/// Ids of accepted connections start here; a configured serial or TCP
/// client link keeps the id the daemon gave its name (below this) across
/// reconnects and reloads, so that static routes and the default upstream
/// survive them.
pub const FIRST_ACCEPTED_ID: u32 = 1 << 16;
static NEXT_LINK_ID: AtomicU32 = AtomicU32::new(FIRST_ACCEPTED_ID);

/// An accepted connection's place in the admission table.
/// Leaves the table when dropped, however the connection ends (its task
/// aborted by a reload included).
struct Admitted {
    table: Arc<Connections>,
    key: u64,
    close: Arc<Notify>,
    /// Closed for its idle time-out.
    idle: bool,
}

impl Drop for Admitted {
    fn drop(&mut self) {
        self.table.left(self.key, self.idle);
    }
}

/// Moves bytes between one link connection and the router until it closes
/// (an accepted one also when evicted or idle too long).
async fn pump_link<S: AsyncRead + AsyncWrite + Unpin>(
    id: LinkId,
    link: String,
    peer: String,
    stream: S,
    events: &mpsc::Sender<IoEvent>,
    admitted: Option<Admitted>,
    mut tap: Tap,
) {
    let (writer, mut writes) = mpsc::channel::<Vec<u8>>(256);
    if events
        .send(IoEvent::LinkOpened {
            id,
            link,
            peer: peer.clone(),
            writer,
        })
        .await
        .is_err()
    {
        return;
    }
    let (mut rd, mut wr) = tokio::io::split(stream);
    let mut buf = vec![0u8; 4096];
    let mut admitted = admitted;
    let idle_at = |a: &Option<Admitted>| a.as_ref().and_then(|a| a.table.idle_at(a.key));
    let reason = loop {
        tokio::select! {
            read = rd.read(&mut buf) => match read {
                Ok(0) => break "closed by peer".to_owned(),
                Ok(n) => {
                    tap.inbound(&buf[..n]);
                    if let Some(a) = &admitted {
                        a.table.touch(a.key, tokio::time::Instant::now());
                    }
                    if events.send(IoEvent::LinkBytes { id, bytes: buf[..n].to_vec() }).await.is_err() {
                        break "router stopped".to_owned();
                    }
                }
                Err(e) => break format!("read failed: {e}"),
            },
            () = async { match &admitted { Some(a) => a.close.notified().await, None => std::future::pending().await } } => {
                break "evicted for a newcomer (limits.max_connections)".to_owned();
            }
            () = async { match idle_at(&admitted) { Some(at) => tokio::time::sleep_until(at).await, None => std::future::pending().await } } => {
                if idle_at(&admitted).is_some_and(|at| at <= tokio::time::Instant::now()) {
                    if let Some(a) = admitted.as_mut() {
                        a.idle = true;
                    }
                    break "idle (limits.idle_timeout_ms)".to_owned();
                }
            }
            write = writes.recv() => match write {
                Some(bytes) => {
                    tap.outbound(&bytes);
                    if let Err(e) = wr.write_all(&bytes).await {
                        break format!("write failed: {e}");
                    }
                }
                None => break "closed by the router".to_owned(),
            },
        }
    };
    drop(admitted);
    info!(%id, %peer, %reason, "link closed");
    let _ = events.send(IoEvent::LinkClosed { id }).await;
}

/// Runs one configured link for as long as the daemon runs.
pub async fn run_link(id: LinkId, link: Link, events: mpsc::Sender<IoEvent>, capture: Arc<CaptureSwitch>) {
    let peer = match &link.transport {
        // Bound at start-up by the daemon (a bad address is a start failure); see `accept_loop`.
        LinkTransport::Listen(_) => return,
        LinkTransport::Connect(addr) => addr.clone(),
        LinkTransport::Serial { path, .. } => path.display().to_string(),
    };
    let mut backoff = Backoff::new();
    loop {
        let opened = match &link.transport {
            LinkTransport::Listen(_) => return,
            LinkTransport::Connect(addr) => connect_tcp(addr).await.map(SerialOrTcp::Tcp),
            LinkTransport::Serial { path, baud } => {
                open_serial(&path.to_string_lossy(), *baud).map(SerialOrTcp::Serial)
            }
        };
        match opened {
            Ok(stream) => {
                backoff.reset();
                info!(link = %link.name, %peer, "link connected");
                let tap = capture.tap(format!("link {} {peer}", link.name), capture_role(link.role));
                pump_link(id, link.name.clone(), peer.clone(), stream, &events, None, tap).await;
            }
            Err(e) => warn!(link = %link.name, %peer, error = %e, "cannot connect; retrying with backoff"),
        }
        if events.is_closed() {
            return;
        }
        tokio::time::sleep(backoff.next_delay()).await;
    }
}

/// Accepts connections: allow-listed peers only, admitted by the shared
/// table (module `admission`). The connections end with this task (a link
/// removed on reload).
pub async fn accept_loop(
    link: Link,
    listener: TcpListener,
    connections: Arc<Connections>,
    events: mpsc::Sender<IoEvent>,
    capture: Arc<CaptureSwitch>,
) {
    let mut open = tokio::task::JoinSet::new();
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            Some(_) = open.join_next() => continue,
        };
        let (stream, peer) = match accepted {
            Ok(c) => c,
            Err(e) => {
                warn!(link = %link.name, error = %e, "accept failed");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        if !link.allow_peers.contains(&peer.ip()) {
            if connections.refuse_unlisted(peer.ip(), tokio::time::Instant::now()) {
                warn!(link = %link.name, %peer, "connection refused: peer not in allow_peers (logged once a minute per peer)");
            }
            continue;
        }
        let (key, close) = match connections.admit(peer.ip(), tokio::time::Instant::now()) {
            Admission::Admitted { key, close, evicted } => {
                if let Some(victim) = evicted {
                    warn!(link = %link.name, peer = %victim, newcomer = %peer, "connection evicted: idle the longest at limits.max_connections (logged once a minute per peer)");
                }
                (key, close)
            }
            Admission::Refused { why, log } => {
                if log {
                    warn!(link = %link.name, %peer, "connection refused: {why} (logged once a minute per peer; gcud_connections_refused_total counts them all)");
                }
                continue;
            }
        };
        if let Err(e) = sagebrush_host::transport::tune_tcp(&stream) {
            warn!(link = %link.name, %peer, error = %e, "cannot set TCP_NODELAY/keepalive");
        }
        info!(link = %link.name, %peer, "client connected");
        let events = events.clone();
        let name = link.name.clone();
        let admitted = Admitted {
            table: connections.clone(),
            key,
            close,
            idle: false,
        };
        let tap = capture.tap(format!("link {name} {peer}"), capture_role(link.role));
        open.spawn(async move {
            let id = LinkId(NEXT_LINK_ID.fetch_add(1, Ordering::Relaxed));
            pump_link(id, name, peer.to_string(), stream, &events, Some(admitted), tap).await;
        });
    }
}

/// Which way commands flow on a link, for the capture (docs/capture.md).
fn capture_role(role: LinkRole) -> Role {
    match role {
        LinkRole::Downstream => Role::Master,
        LinkRole::Upstream | LinkRole::Client => Role::Responder,
    }
}
