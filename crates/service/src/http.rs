//! HTTP/1.1 served through the bounded listener: every connection is
//! admitted by the shared table first ([`crate::admission`]), then served by
//! hyper with
//!
//! - a header time-out: a request's head must be complete within
//!   [`HttpLimits::header_timeout`] of the connection opening or of the
//!   previous response (hyper's `header_read_timeout`), so a half-sent
//!   request, and a kept-alive connection that sends no next request, is
//!   closed then;
//! - a body time-out: once the head is in, the whole body must arrive
//!   within [`HttpLimits::body_timeout`] ([`DeadlineBody`]; the handler's
//!   read of it fails then). tower-http's `TimeoutBody` bounds only the gap
//!   between two frames, which a body sent a byte at a time never exceeds;
//!   this one is a deadline;
//! - the table's idle time-out: a connection on which no byte moves either
//!   way for that long is closed (a client that stops reading its answer);
//! - with TLS ([`crate::door_tls`]), a handshake time-out: the handshake
//!   must be done within [`HttpLimits::handshake_timeout`] of the
//!   connection opening, inside its admission slot (a half-open client
//!   holds a slot that long at most, and counts against the caps); a
//!   client speaking plain HTTP there gets a 400 naming https, and the
//!   connection closes;
//! - bounded buffers: hyper's read buffer at [`HttpLimits::max_buf`], at
//!   most [`HttpLimits::max_headers`] headers (the body limit is the
//!   application's, e.g. axum's `DefaultBodyLimit`).
//!
//! Each request carries the connection's [`Peer`] and [`Local`] addresses
//! as extensions (what axum's `ConnectInfo` gives, without its make-service).

use std::convert::Infallible;
use std::error::Error as StdError;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use hyper::body::{Body, Incoming};
use hyper::service::service_fn;
use hyper::{Request, Response};
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::net::{TcpListener, TcpStream};
use tower::ServiceExt;
use tracing::{debug, warn};

use sagebrush_host::tls::TlsAcceptor;

use crate::admission::{Admitted, Connections, Tracked};
use crate::rate::LogGate;

type BoxError = Box<dyn StdError + Send + Sync>;

/// A request's body as the application sees it: with its deadline.
pub type RequestBody = DeadlineBody<Incoming>;

pin_project_lite::pin_project! {
    /// A body that fails with [`BodyTimeout`] when it is not complete by
    /// its deadline (set when it is made: when the request's head is in).
    #[derive(Debug)]
    pub struct DeadlineBody<B> {
        #[pin]
        body: B,
        #[pin]
        deadline: tokio::time::Sleep,
        timeout: Duration,
    }
}

impl<B> DeadlineBody<B> {
    pub fn new(timeout: Duration, body: B) -> Self {
        Self {
            body,
            deadline: tokio::time::sleep(timeout),
            timeout,
        }
    }
}

/// A body not complete within its time-out.
#[derive(Debug)]
pub struct BodyTimeout(pub Duration);

impl std::fmt::Display for BodyTimeout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "the request body did not arrive within {} ms", self.0.as_millis())
    }
}

impl StdError for BodyTimeout {}

impl<B> Body for DeadlineBody<B>
where
    B: Body,
    B::Error: Into<BoxError>,
{
    type Data = B::Data;
    type Error = BoxError;

    fn poll_frame(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Option<Result<hyper::body::Frame<Self::Data>, Self::Error>>> {
        let this = self.project();
        if let std::task::Poll::Ready(frame) = this.body.poll_frame(cx) {
            return std::task::Poll::Ready(frame.map(|f| f.map_err(Into::into)));
        }
        match this.deadline.poll(cx) {
            std::task::Poll::Ready(()) => std::task::Poll::Ready(Some(Err(Box::new(BodyTimeout(*this.timeout))))),
            std::task::Poll::Pending => std::task::Poll::Pending,
        }
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> hyper::body::SizeHint {
        self.body.size_hint()
    }
}

/// The address of the peer a request came from (an extension of every request).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Peer(pub SocketAddr);

/// The local address the request's connection was accepted on (an
/// extension of every request): the address the client reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Local(pub SocketAddr);

/// The HTTP bounds of [`serve_http`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HttpLimits {
    pub header_timeout: Duration,
    pub body_timeout: Duration,
    /// hyper's read buffer, bytes (at least 8192: hyper's floor).
    pub max_buf: usize,
    pub max_headers: usize,
    /// With TLS: the handshake must be done within this of the connection
    /// opening (inside its admission slot).
    pub handshake_timeout: Duration,
}

impl Default for HttpLimits {
    fn default() -> Self {
        Self {
            handshake_timeout: Duration::from_secs(5),
            header_timeout: Duration::from_secs(5),
            body_timeout: Duration::from_secs(10),
            max_buf: 64 * 1024,
            max_headers: 64,
        }
    }
}

/// How long accepting pauses after a failed accept (descriptors ran out:
/// EMFILE, ENFILE; the listener stays readable, so retrying at once spins).
const ACCEPT_PAUSE: Duration = Duration::from_millis(100);
/// Failed accepts of one listener are logged at most this often.
const ACCEPT_LOG_EVERY: Duration = Duration::from_secs(10);

/// A TCP listener whose connections are admitted by a shared
/// [`Connections`] table: what every LAN-facing socket accepts through.
#[derive(Debug)]
pub struct BoundedListener {
    listener: TcpListener,
    table: Arc<Connections>,
    /// Where it listens, in log lines ("gimbal mast-1", "link clients").
    place: String,
    accept_failures: LogGate<()>,
}

impl BoundedListener {
    pub fn new(listener: TcpListener, table: Arc<Connections>, place: impl Into<String>) -> Self {
        Self {
            listener,
            table,
            place: place.into(),
            accept_failures: LogGate::new(ACCEPT_LOG_EVERY, 1),
        }
    }

    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// The next admitted connection: the stream, its peer and its place in
    /// the table (the close notification and activity touch). A newcomer
    /// refused by the table is closed at once, logged at most once a minute
    /// per peer (the table counts them all); a failed accept is logged at
    /// most once per [`ACCEPT_LOG_EVERY`] and retried after [`ACCEPT_PAUSE`].
    pub async fn accept(&mut self) -> (TcpStream, SocketAddr, Admitted) {
        loop {
            let (stream, peer) = match self.listener.accept().await {
                Ok(accepted) => accepted,
                Err(e) => {
                    if let Some(more) = self.accept_failures.allow(&(), tokio::time::Instant::now()) {
                        warn!(place = %self.place, error = %e, more, "accept failed; retrying (logged at most once in {} s, `more` since the last line)", ACCEPT_LOG_EVERY.as_secs());
                    }
                    tokio::time::sleep(ACCEPT_PAUSE).await;
                    continue;
                }
            };
            match Admitted::admit(&self.table, peer.ip()) {
                Ok((admitted, evicted)) => {
                    if let Some(victim) = evicted {
                        warn!(place = %self.place, peer = %victim, newcomer = %peer, "connection evicted: idle the longest at the connection cap (logged once a minute per peer)");
                    }
                    return (stream, peer, admitted);
                }
                Err((why, log)) => {
                    if log {
                        warn!(place = %self.place, %peer, "connection refused: {why} (logged once a minute per peer; the counters have them all)");
                    }
                }
            }
        }
    }
}

/// Serves `service` on every connection `listener` admits, in HTTPS with
/// `tls` (else plain HTTP), until this future is dropped (the connections
/// end with it).
pub async fn serve_http<S, B>(mut listener: BoundedListener, limits: HttpLimits, tls: Option<TlsAcceptor>, service: S)
where
    S: tower::Service<Request<RequestBody>, Response = Response<B>, Error = Infallible> + Clone + Send + 'static,
    S::Future: Send + 'static,
    B: Body + Send + 'static,
    B::Data: Send,
    B::Error: Into<BoxError>,
{
    let mut open = tokio::task::JoinSet::new();
    loop {
        let (stream, peer, admitted) = tokio::select! {
            accepted = listener.accept() => accepted,
            Some(_) = open.join_next() => continue,
        };
        let service = service.clone();
        let place = listener.place.clone();
        let tls = tls.clone();
        open.spawn(async move {
            let mut conn = Connection {
                peer,
                local: stream.local_addr().ok(),
                admitted,
                limits,
                place,
            };
            match tls {
                None => {
                    let io = conn.admitted.track(stream);
                    conn.serve(io, service).await;
                }
                Some(acceptor) => {
                    if let Some(io) = conn.handshake(stream, &acceptor).await {
                        conn.serve(io, service).await;
                    }
                }
            }
        });
    }
}

/// The first byte of a TLS connection: a handshake record.
const TLS_HANDSHAKE_RECORD: u8 = 0x16;

/// One admitted connection being served.
struct Connection {
    peer: SocketAddr,
    local: Option<SocketAddr>,
    admitted: Admitted,
    limits: HttpLimits,
    place: String,
}

impl Connection {
    /// The TLS handshake, within [`HttpLimits::handshake_timeout`] of the
    /// connection opening and inside its admission slot (a half-open or
    /// silent client holds it that long at most; one evicted or idle is
    /// closed as any other). A client that speaks plain HTTP gets a 400
    /// saying to use https, then the connection closes.
    async fn handshake(
        &mut self,
        stream: TcpStream,
        acceptor: &TlsAcceptor,
    ) -> Option<sagebrush_host::tls::server::TlsStream<Tracked<TcpStream>>> {
        let deadline = tokio::time::Instant::now() + self.limits.handshake_timeout;
        let (peer, place) = (self.peer, self.place.clone());
        let mut first = [0u8; 1];
        let peeked = tokio::select! {
            peeked = tokio::time::timeout_at(deadline, stream.peek(&mut first)) => peeked,
            ending = self.admitted.ended() => {
                debug!(%place, %peer, reason = ending.reason(), "connection closed before its TLS handshake");
                return None;
            }
        };
        match peeked {
            Ok(Ok(1)) if first[0] == TLS_HANDSHAKE_RECORD => {}
            Ok(Ok(1)) => {
                debug!(%place, %peer, "plain HTTP on the HTTPS port: answered 400");
                let _ = tokio::time::timeout_at(deadline, refuse_plain(stream, self.local)).await;
                return None;
            }
            Ok(_) => return None,
            Err(_) => {
                debug!(%place, %peer, "no TLS handshake within {} ms: closed", self.limits.handshake_timeout.as_millis());
                return None;
            }
        }
        let io = self.admitted.track(stream);
        let shaken = tokio::select! {
            shaken = tokio::time::timeout_at(deadline, acceptor.accept(io)) => shaken,
            ending = self.admitted.ended() => {
                debug!(%place, %peer, reason = ending.reason(), "connection closed during its TLS handshake");
                return None;
            }
        };
        match shaken {
            Ok(Ok(tls)) => Some(tls),
            Ok(Err(e)) => {
                debug!(%place, %peer, error = %e, "TLS handshake failed");
                None
            }
            Err(_) => {
                debug!(%place, %peer, "TLS handshake not done within {} ms: closed", self.limits.handshake_timeout.as_millis());
                None
            }
        }
    }

    /// Serves HTTP/1.1 on `io` until it ends or the table ends it.
    async fn serve<I, S, B>(&mut self, io: I, service: S)
    where
        I: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static,
        S: tower::Service<Request<RequestBody>, Response = Response<B>, Error = Infallible> + Clone + Send + 'static,
        S::Future: Send + 'static,
        B: Body + Send + 'static,
        B::Data: Send,
        B::Error: Into<BoxError>,
    {
        let (peer, local, limits) = (self.peer, self.local, self.limits);
        let body_timeout = limits.body_timeout;
        let per_request = service_fn(move |mut request: Request<Incoming>| {
            request.extensions_mut().insert(Peer(peer));
            if let Some(local) = local {
                request.extensions_mut().insert(Local(local));
            }
            let request = request.map(|body| RequestBody::new(body_timeout, body));
            service.clone().oneshot(request)
        });
        let mut http = hyper::server::conn::http1::Builder::new();
        http.timer(TokioTimer::new())
            .header_read_timeout(limits.header_timeout)
            .max_buf_size(limits.max_buf.max(8192))
            .max_headers(limits.max_headers);
        let connection = http.serve_connection(TokioIo::new(io), per_request);
        let place = &self.place;
        tokio::select! {
            ended = connection => {
                if let Err(e) = ended {
                    debug!(%place, %peer, error = %e, "HTTP connection ended");
                }
            }
            ending = self.admitted.ended() => debug!(%place, %peer, reason = ending.reason(), "HTTP connection closed"),
        }
    }
}

/// Answers a plain HTTP request on the HTTPS port with a 400 that says so,
/// reads what the client sent (closing with unread bytes would reset the
/// connection before the client reads the answer), and closes.
async fn refuse_plain(mut stream: TcpStream, local: Option<SocketAddr>) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let port = local.map_or(String::new(), |l| format!(":{}", l.port()));
    let body = format!("This port speaks HTTPS: use https://HOST{port}/\n");
    let answer = format!(
        "HTTP/1.1 400 Bad Request\r\ncontent-type: text/plain; charset=utf-8\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    let mut buf = [0u8; 4096];
    let _ = stream.read(&mut buf).await;
    if stream.write_all(answer.as_bytes()).await.is_ok() {
        let _ = stream.shutdown().await;
        let mut drained = 0;
        while drained < 64 * 1024 {
            match stream.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => drained += n,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Write};

    /// Serves a page that says the request's peer, with `limits` and a cap of `max_total`.
    async fn server(limits: HttpLimits, max_total: usize) -> SocketAddr {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let table = Connections::new(crate::Limits {
            max_total,
            max_per_peer: max_total,
            cap_loopback: true,
            idle_timeout: Duration::from_secs(60),
        });
        let service = tower::service_fn(|request: Request<RequestBody>| async move {
            let peer = request
                .extensions()
                .get::<Peer>()
                .map(|p| p.0.to_string())
                .unwrap_or_default();
            let body = collect(request.into_body()).await;
            Ok::<_, Infallible>(Response::new(format!("{peer} {body}")))
        });
        tokio::spawn(serve_http(
            BoundedListener::new(listener, table, "test"),
            limits,
            None,
            service,
        ));
        addr
    }

    /// The body as text, or the error's.
    async fn collect(body: RequestBody) -> String {
        let mut body = std::pin::pin!(body);
        let mut text = String::new();
        loop {
            match std::future::poll_fn(|cx| body.as_mut().poll_frame(cx)).await {
                Some(Ok(frame)) => {
                    if let Ok(data) = frame.into_data() {
                        text.push_str(&String::from_utf8_lossy(&data));
                    }
                }
                Some(Err(e)) => return e.to_string(),
                None => return text,
            }
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_request_sees_its_peer_a_half_sent_head_and_a_slow_body_are_cut_off() {
        let limits = HttpLimits {
            header_timeout: Duration::from_millis(300),
            body_timeout: Duration::from_millis(300),
            ..HttpLimits::default()
        };
        let addr = server(limits, 8).await;
        tokio::task::spawn_blocking(move || {
            let mut c = std::net::TcpStream::connect(addr).unwrap();
            c.write_all(b"POST / HTTP/1.1\r\nhost: x\r\ncontent-length: 2\r\nconnection: close\r\n\r\nhi")
                .unwrap();
            let mut answer = String::new();
            c.read_to_string(&mut answer).unwrap();
            assert!(answer.contains(&format!("{} hi", c.local_addr().unwrap())), "{answer}");

            // Half a head: closed after the header time-out, not before.
            let mut half = std::net::TcpStream::connect(addr).unwrap();
            half.write_all(b"POST / HTTP/1.1\r\nhost: x\r\n").unwrap();
            half.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let started = std::time::Instant::now();
            let mut rest = Vec::new();
            let _ = half.read_to_end(&mut rest);
            let waited = started.elapsed();
            assert!(
                waited >= Duration::from_millis(250) && waited < Duration::from_secs(5),
                "{waited:?}"
            );

            // A body a byte at a time, past its deadline: the read fails.
            let mut slow = std::net::TcpStream::connect(addr).unwrap();
            slow.write_all(b"POST / HTTP/1.1\r\nhost: x\r\ncontent-length: 100\r\nconnection: close\r\n\r\n")
                .unwrap();
            for _ in 0..6 {
                let _ = slow.write_all(b"a");
                std::thread::sleep(Duration::from_millis(100));
            }
            let mut answer = String::new();
            slow.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let _ = slow.read_to_string(&mut answer);
            assert!(answer.contains("did not arrive within 300 ms"), "{answer}");
        })
        .await
        .unwrap();
    }
}
