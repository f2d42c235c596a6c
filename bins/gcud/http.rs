//! The HTTP endpoint's connections (`[metrics] listen`; the pages are
//! module `metrics`'s): a peer outside `[metrics] allow_peers` is closed as
//! soon as it is accepted, before a byte is read; at most
//! [`Limits::max_connections`] are open at once (more are closed at accept);
//! a request's head must arrive within [`HEADER_TIMEOUT`] of the connection
//! opening or of the previous response (hyper's header read time-out, which
//! also ends a kept-alive connection left idle), and a connection lives at
//! most [`LIFETIME`] (then it ends after its request in progress). So the
//! endpoint holds a bounded number of descriptors whoever connects, and
//! gcud's ports and client listener keep theirs (ARCHITECTURE "Bounded and
//! fair under load").

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tracing::{debug, warn};

use crate::config::PeerAllowList;
use crate::throttle::Throttle;

/// A request's head must arrive this soon after the connection opened or
/// the previous response was sent (a scraper sends it at once).
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(5);
/// A connection is closed after this long, once its request in progress is
/// answered (Prometheus reconnects for its next scrape).
pub const LIFETIME: Duration = Duration::from_secs(60);
/// What a request in progress at [`LIFETIME`] gets to finish.
const LAST_REQUEST: Duration = Duration::from_secs(5);

/// The endpoint's limits.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Connections open at once (module `descriptors` sizes it).
    pub max_connections: usize,
}

/// The endpoint's counters, as a scrape shows them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HttpStats {
    pub open: u64,
    pub refused_not_allowed: u64,
    pub refused_cap: u64,
}

/// The live counters, shared with the pages that show them.
#[derive(Debug, Default)]
pub struct Counters {
    open: AtomicU64,
    refused_not_allowed: AtomicU64,
    refused_cap: AtomicU64,
}

impl Counters {
    pub fn stats(&self) -> HttpStats {
        HttpStats {
            open: self.open.load(Ordering::Relaxed),
            refused_not_allowed: self.refused_not_allowed.load(Ordering::Relaxed),
            refused_cap: self.refused_cap.load(Ordering::Relaxed),
        }
    }
}

/// Serves `app` on `listener` until the process ends.
pub async fn serve(
    listener: TcpListener,
    allow_peers: PeerAllowList,
    limits: Limits,
    app: axum::Router,
    counters: Arc<Counters>,
) {
    let slots = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    let mut throttle = Throttle::default();
    loop {
        let (stream, peer) = crate::io::accept(&listener, "metrics", &mut throttle).await;
        if !allow_peers.contains(&peer.ip()) {
            counters.refused_not_allowed.fetch_add(1, Ordering::Relaxed);
            drop(stream);
            refused(&mut throttle, peer, "not in [metrics] allow_peers");
            continue;
        }
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            counters.refused_cap.fetch_add(1, Ordering::Relaxed);
            drop(stream);
            refused(&mut throttle, peer, "HTTP connection limit reached");
            continue;
        };
        counters.open.fetch_add(1, Ordering::Relaxed);
        let (app, counters) = (app.clone(), counters.clone());
        tokio::spawn(async move {
            let mut http = hyper::server::conn::http1::Builder::new();
            http.timer(TokioTimer::new()).header_read_timeout(HEADER_TIMEOUT);
            let connection = http.serve_connection(TokioIo::new(stream), TowerToHyperService::new(app));
            let mut connection = std::pin::pin!(connection);
            tokio::select! {
                ended = connection.as_mut() => {
                    if let Err(e) = ended {
                        debug!(%peer, error = %e, "HTTP connection ended");
                    }
                }
                () = tokio::time::sleep(LIFETIME) => {
                    connection.as_mut().graceful_shutdown();
                    let _ = tokio::time::timeout(LAST_REQUEST, connection).await;
                }
            }
            counters.open.fetch_sub(1, Ordering::Relaxed);
            drop(slot);
        });
    }
}

/// A refused connection, logged throttled per peer address.
fn refused(throttle: &mut Throttle, peer: SocketAddr, why: &str) {
    let place = peer.ip().to_string();
    let line = || format!("metrics: connection from {peer} closed: {why}");
    if throttle.allow(why, &place, line, tokio::time::Instant::now()) {
        warn!(%peer, "metrics: connection closed at accept: {why} (gcud_http_connections_refused_total counts them all)");
    }
}
