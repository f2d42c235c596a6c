//! Each gimbal's ONVIF device on its own HTTP listener: POSTed SOAP to
//! `/onvif/device_service`, `/onvif/media_service` or `/onvif/ptz_service`
//! (the Body's element, not the path, the Content-Type's `action`
//! parameter or a SOAPAction header, says what is asked; any Content-Type,
//! parameters included, is read as the envelope it carries, and the answer
//! goes back as that envelope's SOAP version's type). The connections go
//! through the bounded listener (crate `sagebrush-service`, `[http]`; in
//! HTTPS with `[http] tls`, every XAddr then saying https): one
//! admission table for every gimbal's device (a total cap that evicts the
//! longest-idle connection for a newcomer, a per-peer cap that holds for
//! loopback peers too), header, body and idle time-outs, bounded buffers;
//! the body is at most [`MAX_BODY`] and each request's work at most
//! [`REQUEST_TIMEOUT`](crate::onvif::REQUEST_TIMEOUT). Failed logins are logged with the peer's address,
//! at most once per [`FAILED_LOGIN_LOG_EVERY`] per peer.

use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Extension, State};
use axum::http::{HeaderMap, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use sagebrush_service::rate::LogGate;
use sagebrush_service::{BoundedListener, Connections, Local, Peer};
use tokio::sync::Semaphore;
use tracing::{debug, info, warn};

use crate::onvif::{Answer, Device, Origin};

/// The largest request body (an ONVIF request is a few KiB).
pub const MAX_BODY: usize = 64 * 1024;
/// Requests served at once per device; more wait for a free one.
pub const MAX_CONCURRENT: usize = 16;
/// Failed logins from one peer are logged at most this often (the line
/// says how many were held back since the last one).
pub const FAILED_LOGIN_LOG_EVERY: Duration = Duration::from_secs(10);
/// Peers remembered for that at most.
const LOGGED_PEERS: usize = 1024;

#[derive(Debug, Clone)]
struct Served {
    device: Device,
    permits: Arc<Semaphore>,
    /// "https" with `[http] tls`, else "http": the service addresses' scheme.
    scheme: &'static str,
    failed_logins: Arc<Mutex<LogGate<IpAddr>>>,
}

/// Whether `host` is a well-formed Host header value: an IPv4 address or
/// a DNS name (letters, digits, hyphens in dot-separated labels), or an
/// IPv6 address in brackets, each with an optional port. Anything else is
/// never written into an answer.
pub fn valid_host(host: &str) -> bool {
    let port_ok =
        |p: &str| !p.is_empty() && p.len() <= 5 && p.bytes().all(|b| b.is_ascii_digit()) && p.parse::<u16>().is_ok();
    if let Some(rest) = host.strip_prefix('[') {
        return rest.split_once(']').is_some_and(|(ip, after)| {
            ip.parse::<Ipv6Addr>().is_ok() && (after.is_empty() || after.strip_prefix(':').is_some_and(port_ok))
        });
    }
    let (name, port) = match host.rsplit_once(':') {
        Some((name, port)) => (name, Some(port)),
        None => (host, None),
    };
    let label_ok = |l: &str| {
        !l.is_empty()
            && l.len() <= 63
            && !l.starts_with('-')
            && !l.ends_with('-')
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
    };
    !name.is_empty() && name.len() <= 253 && name.split('.').all(label_ok) && port.is_none_or(port_ok)
}

async fn soap(
    State(s): State<Served>,
    Extension(Peer(peer)): Extension<Peer>,
    Extension(Local(local)): Extension<Local>,
    uri: Uri,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let Ok(_permit) = s.permits.acquire().await else {
        return StatusCode::SERVICE_UNAVAILABLE.into_response();
    };
    let local_host = local.to_string();
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .filter(|h| valid_host(h))
        .unwrap_or(&local_host);
    let target = uri.path_and_query().map_or(uri.path(), |p| p.as_str());
    let origin = Origin {
        scheme: s.scheme,
        host,
        local: local.ip(),
        uri: target,
        authorization: headers.get(header::AUTHORIZATION).and_then(|h| h.to_str().ok()),
    };
    let Answer { version, result } = s.device.handle(&body, &origin).await;
    let content_type = version.content_type();
    match result {
        Ok(xml) => ([(header::CONTENT_TYPE, content_type)], xml).into_response(),
        Err(fault) => {
            debug!(gimbal = %s.device.gimbal.config.name, %peer, reason = %fault.reason, "fault");
            if let Some(user) = &fault.login_failed {
                let gate = s
                    .failed_logins
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .allow(&peer.ip(), tokio::time::Instant::now());
                if let Some(held_back) = gate {
                    warn!(gimbal = %s.device.gimbal.config.name, %peer, user = ?user, reason = %fault.reason, held_back, "failed login (logged at most once in {} s per peer; held_back: failed logins from it since the last line)", FAILED_LOGIN_LOG_EVERY.as_secs());
                }
            }
            let status = StatusCode::from_u16(fault.status(version)).unwrap_or(StatusCode::BAD_REQUEST);
            let mut response =
                (status, [(header::CONTENT_TYPE, content_type)], fault.envelope(version)).into_response();
            if fault.unauthenticated {
                let challenge = s.device.auth.challenge(time::OffsetDateTime::now_utc());
                if let Ok(value) = header::HeaderValue::from_str(&challenge) {
                    response.headers_mut().insert(header::WWW_AUTHENTICATE, value);
                }
            }
            response
        }
    }
}

/// Binds `listen` (so that an address in use is an error at start) and
/// returns the server to run: the device's app served through the bounded
/// listener with the gimbal's `[http]` bounds.
pub async fn bind(
    listen: SocketAddr,
    device: Device,
    table: Arc<Connections>,
    tls: Option<sagebrush_host::tls::TlsAcceptor>,
) -> std::io::Result<(SocketAddr, impl Future<Output = std::io::Result<()>>)> {
    let listener = tokio::net::TcpListener::bind(listen).await?;
    let local = listener.local_addr()?;
    let device_name = device.gimbal.config.name.clone();
    let bounds = device.gimbal.config.http;
    let served = Served {
        device,
        permits: Arc::new(Semaphore::new(MAX_CONCURRENT)),
        scheme: if tls.is_some() { "https" } else { "http" },
        failed_logins: Arc::new(Mutex::new(LogGate::new(FAILED_LOGIN_LOG_EVERY, LOGGED_PEERS))),
    };
    let app = Router::new()
        .route("/onvif/device_service", post(soap))
        .route("/onvif/media_service", post(soap))
        .route("/onvif/ptz_service", post(soap))
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .with_state(served);
    let limits = bounds.limits();
    let listener = BoundedListener::new(listener, table, format!("gimbal {device_name}"));
    let scheme = if tls.is_some() { "https" } else { "http" };
    info!(gimbal = %device_name, addr = %local, scheme, "ONVIF device listening");
    Ok((local, async move {
        sagebrush_service::serve_http(listener, limits, tls, app).await;
        Ok(())
    }))
}

#[cfg(test)]
mod tests {
    use super::valid_host;

    #[test]
    fn only_well_formed_hosts_are_written_into_answers() {
        for good in [
            "10.0.0.5",
            "10.0.0.5:8081",
            "[::1]:80",
            "[fe80::1]",
            "cam-1.example",
            "cam:1",
        ] {
            assert!(valid_host(good), "{good}");
        }
        for bad in [
            "", "a\"><x/>", "h:1/../x", "h:99999", "h:", "[::1", "[zz]:80", "-a.b", "a..b", "h\u{1}", "h:80:80", "a b",
        ] {
            assert!(!valid_host(bad), "{bad:?}");
        }
    }
}
