//! The HTTP endpoint (`[metrics] listen`, loopback by default): its pages
//! and its connections. The pages: `GET /metrics` (OpenMetrics text, module
//! `metric_families`), `GET /status` (JSON, module `status`) and
//! `GET /healthz`, each from a [`Snapshot`] the router task copies when
//! asked and that is rendered off it. The connections: a peer outside
//! `[metrics] allow_peers` is closed as soon as it is accepted, before a
//! byte is read; at most
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
use tokio::sync::{Semaphore, mpsc, oneshot};
use tracing::{debug, warn};

use crate::config::PeerAllowList;
use crate::snapshot::{HttpStats, Snapshot};
use sagebrush_host::throttle::Throttle;

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

/// A scrape asks the router task for a fresh snapshot through this channel.
pub type ScrapeRequests = mpsc::Sender<oneshot::Sender<Snapshot>>;

/// How long `/healthz` waits for the router task before calling it stuck.
const HEALTH_WAIT: Duration = Duration::from_secs(1);

/// What the HTTP handlers share.
#[derive(Clone, Debug)]
struct Endpoint {
    scrapes: ScrapeRequests,
    http: Arc<Counters>,
}

impl Endpoint {
    /// A snapshot copied on the router task (counters only), or `None` if
    /// the task is gone. Rendering happens off that task, so that a scrape
    /// never stalls routing.
    async fn snapshot(&self) -> Option<Snapshot> {
        let (tx, rx) = oneshot::channel();
        self.scrapes.send(tx).await.ok()?;
        let mut snapshot = rx.await.ok()?;
        snapshot.http = self.http.stats();
        Some(snapshot)
    }
}

/// The pages, for [`serve`] (to `[metrics] allow_peers` only):
/// `GET /metrics` (OpenMetrics text), `GET /status` (JSON) and
/// `GET /healthz` (200 `ok` while the router task answers within a second
/// and gcud is not shutting down, 503 and why otherwise).
pub fn app(scrapes: ScrapeRequests, http: Arc<Counters>) -> axum::Router {
    use axum::extract::State;
    use axum::http::StatusCode;
    use axum::response::{IntoResponse, Response};
    use axum::routing::get;

    async fn metrics(State(endpoint): State<Endpoint>) -> Response {
        let body = match endpoint.snapshot().await {
            Some(s) => tokio::task::spawn_blocking(move || crate::metric_families::render(&s))
                .await
                .unwrap_or_default(),
            None => String::new(),
        };
        (
            [(
                "content-type",
                "application/openmetrics-text; version=1.0.0; charset=utf-8",
            )],
            body,
        )
            .into_response()
    }

    async fn status(State(endpoint): State<Endpoint>) -> Response {
        let Some(s) = endpoint.snapshot().await else {
            return (StatusCode::SERVICE_UNAVAILABLE, "gcud is stopping\n").into_response();
        };
        // Rendered off the router task, as /metrics is: the registry can be long.
        match tokio::task::spawn_blocking(move || serde_json::to_vec(&crate::status::Status::of(&s))).await {
            Ok(Ok(body)) => ([("content-type", "application/json")], body).into_response(),
            _ => (StatusCode::INTERNAL_SERVER_ERROR, "status not rendered\n").into_response(),
        }
    }

    async fn healthz(State(endpoint): State<Endpoint>) -> Response {
        match tokio::time::timeout(HEALTH_WAIT, endpoint.snapshot()).await {
            Ok(Some(s)) if s.shutting_down => (StatusCode::SERVICE_UNAVAILABLE, "shutting down\n").into_response(),
            Ok(Some(_)) => (StatusCode::OK, "ok\n").into_response(),
            Ok(None) => (StatusCode::SERVICE_UNAVAILABLE, "gcud is stopping\n").into_response(),
            Err(_) => (
                StatusCode::SERVICE_UNAVAILABLE,
                "router task did not answer within 1 s\n",
            )
                .into_response(),
        }
    }

    axum::Router::new()
        .route("/metrics", get(metrics))
        .route("/status", get(status))
        .route("/healthz", get(healthz))
        .with_state(Endpoint { scrapes, http })
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
    let line = format_args!("metrics: connection from {peer} closed: {why}");
    if throttle.allow(&why, &peer.ip(), &line, tokio::time::Instant::now()) {
        warn!(%peer, "metrics: connection closed at accept: {why} (gcud_http_connections_refused_total counts them all)");
    }
}
