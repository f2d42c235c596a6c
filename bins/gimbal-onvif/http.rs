//! Each gimbal's ONVIF device on its own HTTP listener (axum): POSTed SOAP
//! to `/onvif/device_service`, `/onvif/media_service` or
//! `/onvif/ptz_service` (the operation, not the path, says what is asked),
//! with the body, the connections and each request's time bounded.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use tokio::sync::Semaphore;
use tracing::{debug, info};

use crate::onvif::Device;
use crate::soap::Fault;

/// The largest request body (an ONVIF request is a few KiB).
pub const MAX_BODY: usize = 64 * 1024;
/// Requests served at once per device; more wait for a free one.
pub const MAX_CONCURRENT: usize = 16;
/// The longest one request may take, gimbal exchanges included.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);

#[derive(Debug, Clone)]
struct Served {
    device: Device,
    fallback_host: String,
    permits: Arc<Semaphore>,
}

const SOAP: &str = "application/soap+xml; charset=utf-8";

async fn soap(State(s): State<Served>, headers: HeaderMap, body: Bytes) -> Response {
    let Ok(_permit) = s.permits.acquire().await else {
        return StatusCode::SERVICE_UNAVAILABLE.into_response();
    };
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .filter(|h| h.len() <= 255 && h.bytes().all(|b| b.is_ascii_graphic()))
        .unwrap_or(&s.fallback_host)
        .to_owned();
    let authorization = headers.get(header::AUTHORIZATION).and_then(|h| h.to_str().ok());
    let answer = match tokio::time::timeout(REQUEST_TIMEOUT, s.device.handle(&body, &host, authorization)).await {
        Ok(answer) => answer,
        Err(_) => Err(Fault::receiver(
            &["ter:Action", "ter:Timeout"],
            format!("no answer within {} s", REQUEST_TIMEOUT.as_secs()),
        )),
    };
    match answer {
        Ok(xml) => ([(header::CONTENT_TYPE, SOAP)], xml).into_response(),
        Err(fault) => {
            debug!(gimbal = %s.device.gimbal.config.name, reason = %fault.reason, "fault");
            let status = StatusCode::from_u16(fault.status()).unwrap_or(StatusCode::BAD_REQUEST);
            let mut response = (status, [(header::CONTENT_TYPE, SOAP)], fault.envelope()).into_response();
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
/// returns the server to run.
pub async fn bind(
    listen: SocketAddr,
    device: Device,
) -> std::io::Result<(SocketAddr, impl Future<Output = std::io::Result<()>>)> {
    let listener = tokio::net::TcpListener::bind(listen).await?;
    let local = listener.local_addr()?;
    let device_name = device.gimbal.config.name.clone();
    let served = Served {
        device,
        fallback_host: local.to_string(),
        permits: Arc::new(Semaphore::new(MAX_CONCURRENT)),
    };
    let app = Router::new()
        .route("/onvif/device_service", post(soap))
        .route("/onvif/media_service", post(soap))
        .route("/onvif/ptz_service", post(soap))
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .with_state(served);
    info!(gimbal = %device_name, addr = %local, "ONVIF device listening");
    Ok((local, async move { axum::serve(listener, app).await }))
}
