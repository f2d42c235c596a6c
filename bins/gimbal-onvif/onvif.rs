//! The ONVIF operations of one gimbal's device (Device ver10, Media ver10,
//! PTZ ver20), as a pipeline per request (the shape of gimbal-mavlink's
//! route, job and plan):
//! 1. the envelope read (module `soap`, SOAP 1.2 or 1.1), and what is asked
//!    taken from the Body's first element, its namespace and local name
//!    (never from the HTTP SOAPAction or `action` parameter);
//! 2. the credentials and the role the operation needs checked (module
//!    `auth`) before anything else;
//! 3. the service's typed request parsed from that element (`device`,
//!    `media`, `ptz`: tokens, numbers and ranges checked, nothing sent);
//! 4. the request run against the gimbal (what this gimbal offers checked
//!    first), giving a typed result or a fault (module `faults`);
//! 5. the result rendered as the response element, in an envelope of the
//!    request's SOAP version.

mod args;
mod device;
mod faults;
mod media;
mod ptz;
pub mod spaces;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use time::OffsetDateTime;

use crate::auth::{Authenticator, require};
use crate::config::Role;
use crate::gimbal::Gimbal;
use crate::soap::{self, Fault, NS_DEVICE, NS_MEDIA, NS_PTZ, Version};
use sagebrush_client::presets::Presets;
use sagebrush_service::door_metrics::DoorMetrics;

/// The longest one request may take, gimbal exchanges included.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);

/// Where a request came in: what the answer may say about it.
#[derive(Debug, Clone, Copy)]
pub struct Origin<'a> {
    /// "https" or "http": how the client reached the device, for the
    /// service addresses.
    pub scheme: &'a str,
    /// The host (and port) the client reached, for the service addresses:
    /// its Host header when that is a well-formed host, else the address
    /// the connection was accepted on (module `http` decides).
    pub host: &'a str,
    /// The local address the connection was accepted on.
    pub local: std::net::IpAddr,
    /// The request's target (path and query), which an HTTP Digest answer
    /// must have been computed over.
    pub uri: &'a str,
    /// The HTTP Authorization header (Digest), if any.
    pub authorization: Option<&'a str>,
}

/// Everything one gimbal's ONVIF device answers with.
#[derive(Debug, Clone)]
pub struct Device {
    pub gimbal: Arc<Gimbal>,
    pub auth: Arc<Authenticator>,
    pub presets: Arc<Presets>,
    /// Operations answered, by name (the door's metrics).
    metrics: Arc<DoorMetrics>,
    /// What SetConfiguration changed of the PTZ configuration.
    settings: Arc<Mutex<ptz::Settings>>,
}

/// An answer: the SOAP version it is written in (the request's, or 1.2
/// when the request could not be read) and the response or the fault.
#[derive(Debug)]
pub struct Answer {
    pub version: Version,
    pub result: Result<String, Fault>,
}

impl Device {
    pub fn new(
        gimbal: Arc<Gimbal>,
        auth: Arc<Authenticator>,
        presets: Arc<Presets>,
        metrics: Arc<DoorMetrics>,
    ) -> Self {
        let settings = ptz::Settings {
            timeout: gimbal.max_move(),
            relative: spaces::Translation::default_for(&gimbal.config),
        };
        Self {
            gimbal,
            auth,
            presets,
            metrics,
            settings: Arc::new(Mutex::new(settings)),
        }
    }

    fn settings(&self) -> ptz::Settings {
        *self.settings.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn set_settings(&self, settings: ptz::Settings) {
        *self.settings.lock().unwrap_or_else(|p| p.into_inner()) = settings;
    }

    /// Answers one request body that came in at `origin`.
    pub async fn handle(&self, body: &[u8], origin: &Origin<'_>) -> Answer {
        let request = match soap::request(body) {
            Ok(request) => request,
            Err(reason) => {
                return Answer {
                    version: Version::Soap12,
                    result: Err(Fault::sender(
                        &["ter:WellFormed"],
                        format!("the request is not a SOAP envelope: {reason}"),
                    )),
                };
            }
        };
        let version = request.version;
        let result = match tokio::time::timeout(REQUEST_TIMEOUT, self.answer(&request, origin)).await {
            Ok(result) => result,
            Err(_) => Err(Fault::receiver(
                &["ter:Action", "ter:Timeout"],
                format!("no answer within {} s", REQUEST_TIMEOUT.as_secs()),
            )),
        };
        // An answered operation by its name (one of this device's); a
        // fault as one kind, so that a client's names make no labels.
        self.metrics.request(match &result {
            Ok(_) => request.operation.name.as_str(),
            Err(_) => "fault",
        });
        Answer {
            version,
            result: result.map(|body| soap::envelope(version, &body)),
        }
    }

    /// The response element to `request`: steps 2 to 5 of the pipeline.
    async fn answer(&self, request: &soap::Request, origin: &Origin<'_>) -> Result<String, Fault> {
        let op = &request.operation;
        let now = OffsetDateTime::now_utc();
        let g = &self.gimbal.config;
        // Clients ask the clock before they can sign: no credentials.
        if op.name == "GetSystemDateAndTime" && op.ns == NS_DEVICE {
            return Ok(device::Response::DateAndTime(now).render(g));
        }
        if ![NS_DEVICE, NS_MEDIA, NS_PTZ].contains(&op.ns.as_str()) {
            return Err(Fault::receiver(
                &["ter:ActionNotSupported"],
                format!("{{{}}}{} is not an operation of this device", op.ns, op.name),
            ));
        }
        let user = self
            .auth
            .authenticate(request.header.as_ref(), origin.authorization, "POST", origin.uri, now)?;
        require(&user, needed_role(&op.name), &op.name)?;
        Ok(match op.ns.as_str() {
            NS_DEVICE => device::Request::parse(op)?.run(self, origin, now).await?.render(g),
            NS_MEDIA => media::Request::parse(op)?.run(self)?.render(g),
            _ => ptz::Request::parse(op)?
                .run(self, now, &user.0)
                .await?
                .render(g, self.gimbal.max_move()),
        })
    }
}

/// What each operation needs: a `user` reads, an `operator` also moves and
/// uses presets, an `administrator` may do everything.
pub fn needed_role(operation: &str) -> Role {
    match operation {
        "ContinuousMove" | "AbsoluteMove" | "RelativeMove" | "Stop" | "SetPreset" | "GotoPreset" | "RemovePreset"
        | "GotoHomePosition" => Role::Operator,
        "SetHomePosition" => Role::Administrator,
        op if op.starts_with("Get") => Role::User,
        _ => Role::Administrator,
    }
}

/// A gimbal's device scopes (ONVIF Core 7.3.2.2): type, profile, name and
/// hardware, as GetScopes and WS-Discovery give them.
pub fn scopes(g: &crate::config::Gimbal) -> Vec<String> {
    let mut scopes = vec![
        "onvif://www.onvif.org/type/ptz".to_owned(),
        "onvif://www.onvif.org/Profile/Streaming".to_owned(),
        format!("onvif://www.onvif.org/name/{}", scope_text(&g.name)),
        "onvif://www.onvif.org/hardware/Sagebrush-gimbal".to_owned(),
    ];
    if g.stream_uri.is_some() {
        scopes.push("onvif://www.onvif.org/type/video_encoder".to_owned());
    }
    scopes
}

/// A name as a scope item (no spaces, percent-encoded).
fn scope_text(name: &str) -> String {
    name.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
