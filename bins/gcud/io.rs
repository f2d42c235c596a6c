//! Opening the lines the router task owns (module `lines`): device ports (serial,
//! TCP device server, in-process simulator) and links (serial, TCP listener,
//! TCP client). Every line is reopened by its task with backoff when its device
//! or peer is missing or vanishes, without disturbing any other line
//! (ARCHITECTURE "Layers", 3: transport).

use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

use sagebrush_gcu::{LinkId, LinkKind};
use sagebrush_host::capture::{CaptureSwitch, Role, Tap};

use crate::lines::{Ended, LineRate, LineStream, NoRate, Rate};
use sagebrush_host::backoff::Backoff;
use sagebrush_host::transport::{LATENCY_TIMER_WARN_MS, SerialOrTcp, connect_tcp, latency_timer_ms, open_serial};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{mpsc, oneshot};

use crate::admission::{Admitted, Connections, Ending};
use tracing::{debug, info, warn};

use crate::config::{Link, LinkTls, LinkTransport, Port, PortTransport};
use sagebrush_host::throttle::Throttle;

/// What the line tasks tell the router task: a line is open (the router
/// task owns it from then on, module `lines`), or an accepted connection
/// must close (evicted, idle).
pub enum IoEvent {
    PortOpened {
        port: u8,
        stream: Box<dyn LineStream>,
        tap: Tap,
        rate: Rate,
        ended: oneshot::Sender<Ended>,
    },
    LinkOpened {
        id: LinkId,
        /// The configured link's name.
        link: String,
        peer: String,
        /// The subject CN of its TLS client certificate (a listener with
        /// `client_ca`): the principal it claims to be.
        principal: Option<String>,
        stream: Box<dyn LineStream>,
        tap: Tap,
        admission: Option<(Arc<Connections>, u64)>,
        ended: oneshot::Sender<Ended>,
    },
    /// Close an accepted connection (its admission entry says why).
    CloseLink { id: LinkId, reason: &'static str },
    /// A metrics scrape wants a snapshot of the counters (rendered off the router task).
    Scrape(oneshot::Sender<crate::snapshot::Snapshot>),
}

/// A port on a TCP device server (ser2net and the like): the server owns
/// the serial line and its rate is configured there ([`ServerRate`]).
#[derive(Debug)]
struct DeviceServer {
    stream: TcpStream,
}

/// The rate a device server's port was opened at, remembered so that only
/// a change to another rate (after an acknowledged `C0..C7`, Table 4) is
/// reported as not applied, not the router's setting of the rate it
/// already has at every open.
#[derive(Debug)]
struct ServerRate {
    baud: u32,
}

impl LineRate for ServerRate {
    fn set_baud(&mut self, baud: u32) -> io::Result<()> {
        if baud != self.baud {
            warn!(
                from = self.baud,
                baud, "line rate change on a TCP device server port is not applied locally: configure it on the server"
            );
            self.baud = baud;
        }
        Ok(())
    }
}

impl LineStream for DeviceServer {
    fn holds_lone_ack(&self) -> bool {
        true
    }
}

impl AsyncRead for DeviceServer {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for DeviceServer {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().stream).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_shutdown(cx)
    }
}

/// An accepted or dialled link connection: no line rate.
impl LineStream for TcpStream {}

/// How long an accepted connection may take to finish its TLS handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);

/// A link connection over TLS (either end; module `sagebrush_host::tls`).
struct TlsLink(sagebrush_host::tls::TlsStream<TcpStream>);

impl std::fmt::Debug for TlsLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("TlsLink")
    }
}

impl LineStream for TlsLink {}

impl AsyncRead for TlsLink {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().0).poll_read(cx, buf)
    }
}

impl AsyncWrite for TlsLink {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().0).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().0).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().0).poll_shutdown(cx)
    }
}

impl LineStream for tokio::io::DuplexStream {}

impl LineStream for SerialOrTcp {}

/// A port opened: its bytes, and its rate switch.
type Opened = (Box<dyn LineStream>, Box<dyn LineRate>);

async fn open_port(port: &Port, baud: u32) -> io::Result<Opened> {
    Ok(match &port.transport {
        PortTransport::Serial(path) => {
            let (line, control) = crate::serial::SerialLine::open(&path.to_string_lossy(), baud)?;
            if let Some(ms) = latency_timer_ms(path, std::path::Path::new("/sys")) {
                if ms > LATENCY_TIMER_WARN_MS {
                    warn!(
                        port = port.id,
                        path = %path.display(),
                        latency_timer_ms = ms,
                        "the USB adapter holds short replies up to {ms} ms: set its latency_timer to 1 \
                         (config/99-sagebrush-gimbal.rules does for FTDI adapters)"
                    );
                }
            }
            (Box::new(line), Box::new(control))
        }
        PortTransport::Tcp(addr) => (
            Box::new(DeviceServer {
                stream: connect_tcp(addr).await?,
            }),
            Box::new(ServerRate { baud }),
        ),
        #[cfg(feature = "sim")]
        PortTransport::Simulated(devices) => (
            Box::new(crate::simulated::spawn(port.id, devices, baud)),
            Box::new(NoRate),
        ),
        #[cfg(not(feature = "sim"))]
        PortTransport::Simulated(_) => {
            return Err(io::Error::other(
                "simulated port: this gcud was built without the `sim` feature",
            ));
        }
    })
}

/// Keeps one port open for as long as the daemon runs; ends quietly (info)
/// once the router lets go of it (shutdown). On a port thread (`relay`,
/// module `shard`) the port is opened and served there, and the router
/// task gets the relayed stream.
pub async fn run_port(
    port: Port,
    events: mpsc::Sender<IoEvent>,
    capture: Arc<CaptureSwitch>,
    relay: Option<crate::shard::Relay>,
) {
    let mut backoff = Backoff::new();
    let mut baud = port.baud();
    let mut last_error = String::new();
    loop {
        let opened = match (open_port(&port, baud).await, &relay) {
            (Ok((stream, switch)), Some(relay)) => {
                Ok((Box::new(relay.clone().wrap(stream)) as Box<dyn LineStream>, switch))
            }
            (opened, _) => opened,
        };
        match opened {
            Ok((stream, switch)) => {
                backoff.reset();
                last_error.clear();
                info!(port = port.id, transport = %describe(&port.transport), baud, "port open");
                let (ended, end) = oneshot::channel();
                let tap = capture.tap(format!("port {} {}", port.id, describe(&port.transport)), Role::Master);
                let opened = IoEvent::PortOpened {
                    port: port.id,
                    stream,
                    tap,
                    rate: Rate { baud, switch },
                    ended,
                };
                if events.send(opened).await.is_err() {
                    return;
                }
                // The router task owns the line now; it says how it ended.
                let Ok(ended) = end.await else {
                    info!(port = port.id, "port closed: gcud stopping");
                    return;
                };
                baud = ended.baud;
                warn!(port = port.id, reason = %ended.reason, "port lost; reopening");
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
        PortTransport::Simulated(d) => {
            let ids: Vec<String> = d.iter().map(u8::to_string).collect();
            format!("simulated devices {}", ids.join(", "))
        }
    }
}

// ---- links ----------------------------------------------------------------

/// Ids of accepted connections start here; a configured serial or TCP
/// client link keeps the id the daemon gave its name (below this) across
/// reconnects and reloads, so that static routes and the default upstream
/// survive them.
const FIRST_ACCEPTED_ID: u32 = 1 << 16;
static NEXT_LINK_ID: AtomicU32 = AtomicU32::new(FIRST_ACCEPTED_ID);

/// Hands one link connection to the router task and waits until it ends
/// (an accepted one also ends when evicted or idle too long: the router
/// task is asked to close it).
#[allow(clippy::too_many_arguments)]
async fn serve_link<S: LineStream + 'static>(
    id: LinkId,
    link: String,
    peer: String,
    principal: Option<String>,
    stream: S,
    events: &mpsc::Sender<IoEvent>,
    admitted: Option<Admitted>,
    tap: Tap,
) {
    let (ended, mut end) = oneshot::channel();
    let opened = IoEvent::LinkOpened {
        id,
        link,
        peer: peer.clone(),
        principal,
        stream: Box::new(stream),
        tap,
        admission: admitted.as_ref().map(Admitted::entry),
        ended,
    };
    if events.send(opened).await.is_err() {
        return;
    }
    let mut admitted = admitted;
    let closing = tokio::select! {
        ended = &mut end => {
            let reason = ended.map_or_else(|_| "closed by the router".to_owned(), |e| e.reason);
            debug!(%id, %peer, %reason, "link closed");
            return;
        }
        ending = async { match admitted.as_mut() { Some(a) => a.ended().await, None => std::future::pending().await } } => match ending {
            Ending::Evicted => "evicted for a newcomer (limits.max_connections)",
            Ending::Idle => "idle (limits.idle_timeout_ms)",
        },
    };
    let _ = events.send(IoEvent::CloseLink { id, reason: closing }).await;
    drop(admitted);
    debug!(%id, %peer, reason = closing, "link closed");
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
        let tap = || capture.tap(format!("link {} {peer}", link.name), capture_role(link.kind));
        let name = link.name.clone();
        match (opened, &link.tls) {
            (Ok(SerialOrTcp::Tcp(tcp)), Some(LinkTls::Client { ca, identity })) => {
                let identity = identity.as_ref().map(|(c, k)| (c.as_path(), k.as_path()));
                let tls = match sagebrush_host::tls::connector(ca, identity) {
                    Ok(connector) => sagebrush_host::tls::connect(&connector, &peer, tcp).await,
                    Err(e) => Err(io::Error::other(e.to_string())),
                };
                match tls {
                    Ok(stream) => {
                        backoff.reset();
                        info!(link = %link.name, %peer, "link connected (TLS)");
                        serve_link(
                            id,
                            name,
                            peer.clone(),
                            None,
                            TlsLink(stream.into()),
                            &events,
                            None,
                            tap(),
                        )
                        .await;
                    }
                    Err(e) => {
                        warn!(link = %link.name, %peer, error = %e, "TLS handshake failed; retrying with backoff")
                    }
                }
            }
            (Ok(stream), _) => {
                backoff.reset();
                info!(link = %link.name, %peer, "link connected");
                serve_link(id, name, peer.clone(), None, stream, &events, None, tap()).await;
            }
            (Err(e), _) => warn!(link = %link.name, %peer, error = %e, "cannot connect; retrying with backoff"),
        }
        if events.is_closed() {
            return;
        }
        tokio::time::sleep(backoff.next_delay()).await;
    }
}

/// Accepts connections: allow-listed peers only, admitted by the shared
/// table (crate `sagebrush-service`, re-exported as module `admission`). The connections end with this task (a link
/// removed on reload).
pub async fn accept_loop(
    link: Link,
    listener: Arc<TcpListener>,
    connections: Arc<Connections>,
    events: mpsc::Sender<IoEvent>,
    capture: Arc<CaptureSwitch>,
) {
    let mut open = tokio::task::JoinSet::new();
    let mut throttle = Throttle::default();
    let place = format!("link {}", link.name);
    let tls = match &link.tls {
        Some(LinkTls::Server { cert, key, client_ca }) => {
            match sagebrush_host::tls::acceptor(cert, key, client_ca.as_deref()) {
                Ok(acceptor) => Some(acceptor),
                Err(e) => {
                    // Checked when the configuration was read: a file changed since.
                    tracing::error!(link = %link.name, error = %e, "TLS cannot be set up: no connection is accepted");
                    return;
                }
            }
        }
        _ => None,
    };
    let handshakes = Arc::new(std::sync::Mutex::new(Throttle::default()));
    // Each listener keeps its share of [limits] max_connections (module
    // `admission`): keyed by its link's name.
    let listener_key = {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        link.name.hash(&mut h);
        h.finish()
    };
    loop {
        let (stream, peer) = tokio::select! {
            accepted = accept(&listener, &place, &mut throttle) => accepted,
            Some(_) = open.join_next() => continue,
        };
        if !link.allow_peers.contains(&peer.ip()) {
            if connections.refuse_unlisted(peer.ip(), tokio::time::Instant::now()) {
                warn!(link = %link.name, %peer, "connection refused: peer not in allow_peers (logged once a minute per peer)");
            }
            continue;
        }
        let admitted = match Admitted::admit_on(&connections, listener_key, peer.ip()) {
            Ok((admitted, evicted)) => {
                if let Some(victim) = evicted {
                    warn!(link = %link.name, peer = %victim, newcomer = %peer, "connection evicted at limits.max_connections: idle the longest, or the quietest of a listener over its share (logged once a minute per peer)");
                }
                admitted
            }
            Err((why, log)) => {
                if log {
                    warn!(link = %link.name, %peer, "connection refused: {why} (logged once a minute per peer; gcud_connections_refused_total counts them all)");
                }
                continue;
            }
        };
        if let Err(e) = sagebrush_host::transport::tune_tcp(&stream) {
            warn!(link = %link.name, %peer, error = %e, "cannot set TCP_NODELAY/keepalive");
        }
        debug!(link = %link.name, %peer, "client connected");
        let events = events.clone();
        let name = link.name.clone();
        let tap = capture.tap(format!("link {name} {peer}"), capture_role(link.kind));
        let tls = tls.clone();
        let handshakes = handshakes.clone();
        open.spawn(async move {
            let id = LinkId(NEXT_LINK_ID.fetch_add(1, Ordering::Relaxed));
            let Some(acceptor) = tls else {
                return serve_link(id, name, peer.to_string(), None, stream, &events, Some(admitted), tap).await;
            };
            // The admission slot is held through the handshake, which is
            // bounded: a half-open or silent peer cannot keep it.
            let shaken = tokio::time::timeout(HANDSHAKE_TIMEOUT, acceptor.accept(stream)).await;
            let stream = match shaken {
                Ok(Ok(stream)) => stream,
                failed => {
                    let why = match failed {
                        Ok(Err(e)) => e.to_string(),
                        _ => format!("no handshake within {} s", HANDSHAKE_TIMEOUT.as_secs()),
                    };
                    let now = tokio::time::Instant::now();
                    let allow = |t: &mut Throttle| {
                        t.allow(&"tls", &peer.ip(), &format_args!("link {name}: TLS handshake with {peer} failed"), now)
                    };
                    if handshakes.lock().is_ok_and(|mut t| allow(&mut t)) {
                        warn!(link = %name, %peer, error = %why, "connection refused: TLS handshake failed (a plain client, no client certificate, or one from another CA); logged at most {} times in {} s per peer", sagebrush_host::throttle::BURST, sagebrush_host::throttle::WINDOW.as_secs());
                    }
                    return;
                }
            };
            let principal = sagebrush_host::tls::peer_common_name(stream.get_ref().1.peer_certificates());
            serve_link(id, name, peer.to_string(), principal, TlsLink(stream.into()), &events, Some(admitted), tap).await;
        });
    }
}

/// How long an accept loop pauses after a failed accept: descriptors ran
/// out (EMFILE, ENFILE) and the listener stays readable, so retrying at
/// once would spin.
const ACCEPT_PAUSE: Duration = Duration::from_millis(100);

/// The next connection on `listener`. A failed accept (descriptors ran out:
/// EMFILE, ENFILE; or the peer gave up) is logged at most
/// [`sagebrush_host::throttle::BURST`] times per window and place, the rest summed up
/// when the window ends, and retried after [`ACCEPT_PAUSE`]: nothing else
/// waits for it, so routing goes on.
pub async fn accept(listener: &TcpListener, place: &str, throttle: &mut Throttle) -> (TcpStream, SocketAddr) {
    loop {
        let summary_at = throttle.next_deadline();
        let accepted = tokio::select! {
            accepted = listener.accept() => Some(accepted),
            () = async { match summary_at { Some(at) => tokio::time::sleep_until(at).await, None => std::future::pending().await } } => None,
        };
        for summary in throttle.summaries(tokio::time::Instant::now()) {
            warn!("{summary}");
        }
        match accepted {
            Some(Ok(connection)) => return connection,
            Some(Err(e)) => {
                let now = tokio::time::Instant::now();
                if throttle.allow(
                    &"accept failed",
                    &place,
                    &format_args!("{place}: accept failed: {e}"),
                    now,
                ) {
                    warn!(%place, error = %e, "accept failed; retrying (logged at most {} times in {} s)", sagebrush_host::throttle::BURST, sagebrush_host::throttle::WINDOW.as_secs());
                }
                tokio::time::sleep(ACCEPT_PAUSE).await;
            }
            None => {}
        }
    }
}

/// Which way commands flow on a link, for the capture (docs/capture.md).
fn capture_role(kind: LinkKind) -> Role {
    match kind {
        LinkKind::Downstream => Role::Master,
        LinkKind::Upstream | LinkKind::Client => Role::Responder,
    }
}
