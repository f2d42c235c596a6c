//! The page and its API, served through the bounded listener (crate
//! `sagebrush-service`, `[http]`): one admission table (a total cap that
//! evicts the longest-idle connection, a per-peer cap that holds for
//! loopback peers too), header, body and idle time-outs, bounded buffers;
//! bodies of at most [`MAX_BODY`].
//!
//! - `GET /`, `/app.js`, `/style.css`: the page, embedded in the binary.
//! - `POST /api/sign-in` (JSON `{user, password}`): sets the session
//!   cookie; `POST /api/sign-out`.
//! - `GET /api/session`: who is signed in, the CSRF token, the lease and
//!   the gimbals; `GET /api/events`: server-sent events, every gimbal's
//!   state when it changed, rendered once for all streams ([`events`]).
//! - `POST /api/move`, `/api/stop`, `/api/home`, `/api/goto`,
//!   `/api/preset/save`, `/api/preset/go`, `/api/tour`, `/api/release`:
//!   with the `X-CSRF-Token` header, by role (issue 34): a user views, an
//!   operator moves (the map's click is a `/api/goto`) and uses presets,
//!   an administrator also starts and stops tours and releases a gimbal.
//!   A move lasts the hold lease unless renewed by the page while the
//!   button or key is held. Those handlers are in [`actions`].
//!
//! Sign-in attempts are limited by their failures per account and client
//! address ([`crate::guard`]); the client's address is the peer's, or a
//! trusted proxy's `X-Forwarded-For` ([`crate::forwarded`]).
//!
//! What gcud decides (ARCHITECTURE "Front doors") is shown, never decided
//! here: each gimbal's state carries who controls it (gcud's `~C`, kept by
//! its session) and gcud's limits and keep-out zones of it (`~B`, asked
//! every [`sagebrush_client::session::RULES_REFRESH`]), drawn on its
//! pan/tilt map; the state carries gcud's tours (`~T?`, asked every
//! [`QUIET`]); `/api/tour` starts or stops one (`~T+`, `~T-`) and
//! `/api/release` releases a gimbal (`~R`).
//!
//! An answer that is not a success is JSON `{"error": REASON}`, REASON
//! being gcud's or the gimbal's own words for a refused (HTTP 409) or
//! undelivered command; the page shows it on the card (as text, never as
//! markup).

use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use axum::extract::{DefaultBodyLimit, Extension, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use sagebrush_client::CommandError;
use sagebrush_client::connection::Control;
use sagebrush_client::governance::{Controller, Rules, Tour, degrees, tour_state_name};
use sagebrush_client::presets::Presets;
use sagebrush_client::session::{GimbalSession, Motion};
use sagebrush_service::door_metrics::DoorMetrics;
use sagebrush_service::rate::LogGate;
use sagebrush_service::{BoundedListener, Peer};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::time::Instant;
use tracing::{info, warn};

use crate::auth::{Auth, CSRF_HEADER, Refused, SignedIn};
use crate::config::{self, Role};
use crate::guard::Guard;

mod actions;
mod events;

/// The largest request body (the API's JSON is a few dozen bytes).
pub const MAX_BODY: usize = 4096;
/// gcud's tours and the gimbals' rules are asked this often.
pub const QUIET: Duration = Duration::from_secs(1);
/// Failed sign-ins at one account are logged at most this often.
const FAILED_LOG_EVERY: Duration = Duration::from_secs(10);

const INDEX: &str = include_str!("page/index.html");
const APP_JS: &str = include_str!("page/app.js");
const STYLE: &str = include_str!("page/style.css");

/// One gimbal of the page.
#[derive(Debug)]
pub struct Gimbal {
    pub config: config::Gimbal,
    pub session: Arc<GimbalSession>,
}

/// gcud's tours as last asked (`~T?`), with the gimbal whose session
/// asked (the gimbals of one gcud group share its tours).
#[derive(Debug, Default)]
struct Tours {
    /// Per GCU group asked: its tours, or why they are unknown.
    by_group: Vec<(u8, Result<Vec<Tour>, String>)>,
}

#[derive(Debug)]
struct Web {
    gimbals: Vec<Gimbal>,
    tours: Mutex<Tours>,
    /// gcud's rules of each gimbal (`~B`), as last asked; `None` while unknown.
    rules: Mutex<Vec<Option<Rules>>>,
    auth: Auth,
    presets: Arc<Presets>,
    lease: Duration,
    secure_cookie: bool,
    /// The reverse proxies whose `X-Forwarded-For` is believed.
    trusted_proxies: Vec<IpAddr>,
    guard: Mutex<Guard>,
    /// Failed sign-ins logged per account (`None`: a name that is none).
    failed: Mutex<LogGate<Option<usize>>>,
    /// Every gimbal's state as last rendered, shared by the event streams.
    snapshot: events::Snapshot,
    streams: Arc<events::Streams>,
    /// `[http] idle_timeout_ms`: the streams' keep-alive comes well within it.
    idle_timeout: Duration,
    /// `[metrics]`: requests by route, live pages.
    metrics: Arc<DoorMetrics>,
}

type Shared = State<Arc<Web>>;

/// An answer that is not a success: a status and the reason, as JSON.
#[derive(Debug)]
struct Failure(StatusCode, String);

impl IntoResponse for Failure {
    fn into_response(self) -> Response {
        (self.0, no_store(), axum::Json(json!({ "error": self.1 }))).into_response()
    }
}

impl From<Refused> for Failure {
    fn from(r: Refused) -> Self {
        match r {
            Refused::SignIn(why) => Failure(StatusCode::UNAUTHORIZED, why.to_owned()),
            Refused::Forbidden(why) => Failure(StatusCode::FORBIDDEN, why),
        }
    }
}

/// A command gcud or the gimbal refused or did not deliver: its words
/// (a refusal by gcud's rules is a conflict with them: HTTP 409).
fn failed(e: CommandError) -> Failure {
    let status = match e {
        CommandError::Usage(_) => StatusCode::BAD_REQUEST,
        CommandError::Refused(..) => StatusCode::CONFLICT,
        _ => StatusCode::BAD_GATEWAY,
    };
    Failure(status, e.to_string())
}

/// Who controls a gimbal, as the page shows it: `null` while gcud has not
/// said (a gcud that governs nothing).
fn control_json(control: Option<&Control>) -> Value {
    let Some(c) = control else { return Value::Null };
    let (kind, name, priority, via) = match &c.holder {
        Controller::Nobody => ("nobody", None, None, None),
        Controller::Link {
            name, priority, via, ..
        } => ("link", Some(name.as_str()), Some(*priority), via.as_deref()),
        Controller::Tour(name) => ("tour", Some(name.as_str()), None, None),
        Controller::Park => ("park", None, None, None),
    };
    json!({
        "kind": kind,
        "name": name,
        "priority": priority,
        "via": via,
        "text": c.holder.to_string(),
        "ours": c.ours,
    })
}

/// gcud's limits and zones of a gimbal, in degrees, as the map draws
/// them: `null` while unknown (gcud not asked yet, or one that does not
/// answer `~B`).
fn rules_json(rules: Option<&Rules>) -> Value {
    let Some(r) = rules else { return Value::Null };
    let zones: Vec<Value> = r
        .keep_out
        .iter()
        .map(|(pan, tilt)| json!({ "pan": degrees(*pan), "tilt": degrees(*tilt) }))
        .collect();
    json!({
        "pan_limits": r.pan_limits.map(degrees),
        "tilt_limits": r.tilt_limits.map(degrees),
        "keep_out": zones,
    })
}

fn no_store() -> [(header::HeaderName, &'static str); 1] {
    [(header::CACHE_CONTROL, "no-store")]
}

/// A success's JSON answer, never stored by a cache.
fn answer(v: Value) -> Response {
    (no_store(), axum::Json(v)).into_response()
}

fn bad(what: impl Into<String>) -> Failure {
    Failure(StatusCode::BAD_REQUEST, what.into())
}

impl Web {
    fn gimbal(&self, i: usize) -> Result<&Gimbal, Failure> {
        self.gimbals
            .get(i)
            .ok_or_else(|| bad(format!("no gimbal {i}: there are {}", self.gimbals.len())))
    }

    fn allow(&self, headers: &HeaderMap, need: Role, what: &str) -> Result<SignedIn, Failure> {
        let cookies = headers.get(header::COOKIE).and_then(|v| v.to_str().ok());
        let csrf = headers.get(CSRF_HEADER).and_then(|v| v.to_str().ok());
        Ok(self.auth.allow(cookies, csrf, need, what, Instant::now())?)
    }

    /// A POST's user, allowed `need` to do `what`, and its JSON body
    /// (`expected` names its shape in the error).
    fn post<T: serde::de::DeserializeOwned>(
        &self,
        headers: &HeaderMap,
        bytes: &[u8],
        (need, what): (Role, &str),
        expected: &str,
    ) -> Result<(SignedIn, T), Failure> {
        let who = self.allow(headers, need, what)?;
        Ok((who, body(bytes, expected)?))
    }

    fn who(&self, headers: &HeaderMap) -> Result<SignedIn, Failure> {
        let cookies = headers.get(header::COOKIE).and_then(|v| v.to_str().ok());
        Ok(self.auth.who(cookies, Instant::now())?)
    }

    /// Every gimbal's state, as the page shows it.
    fn state(&self) -> Value {
        let rules = self.rules.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let gimbals: Vec<Value> = self
            .gimbals
            .iter()
            .enumerate()
            .map(|(i, g)| {
                let s = g.session.status();
                let motion = match s.motion {
                    Motion::Idle if s.changing => "moving",
                    Motion::Idle => "idle",
                    Motion::Moving => "moving",
                    Motion::Unknown => "unknown",
                };
                let presets: Vec<Value> = self
                    .presets
                    .list(&g.config.name)
                    .into_iter()
                    .map(|(n, name)| json!({ "n": n, "name": name }))
                    .collect();
                json!({
                    "online": s.error.is_none() && s.position.is_some(),
                    "error": s.error,
                    "pan": s.position.map(|p| p.pan.degrees()),
                    "tilt": s.position.map(|p| p.tilt.degrees()),
                    "motion": motion,
                    "presets": presets,
                    "control": control_json(s.control.as_ref()),
                    "rules": rules_json(rules.get(i).and_then(Option::as_ref)),
                })
            })
            .collect();
        json!({ "gimbals": gimbals, "tours": self.tours_json() })
    }

    /// gcud's tours for the page: `{name, state}` each, and why some are
    /// unknown (`tours_error`).
    fn tours_json(&self) -> Value {
        let tours = self.tours.lock().unwrap_or_else(|p| p.into_inner());
        let mut list = Vec::new();
        let mut errors = Vec::new();
        for (_, known) in &tours.by_group {
            match known {
                Ok(ts) => list.extend(
                    ts.iter()
                        .map(|t| json!({ "name": t.name, "state": tour_state_name(t.state) })),
                ),
                Err(e) => errors.push(e.clone()),
            }
        }
        json!({ "list": list, "error": (!errors.is_empty()).then(|| errors.join("; ")) })
    }

    /// One gimbal's session per gcud group: who asks that group's tours.
    fn group_sessions(&self) -> Vec<(u8, Arc<GimbalSession>)> {
        let mut groups: Vec<(u8, Arc<GimbalSession>)> = Vec::new();
        for g in &self.gimbals {
            let group = g.config.address.group;
            if !groups.iter().any(|(k, _)| *k == group) {
                groups.push((group, Arc::clone(&g.session)));
            }
        }
        groups
    }

    /// Asks every group's tours now (`~T?`: answered by gcud, no bus time).
    async fn refresh_tours(&self) {
        let mut by_group = Vec::new();
        for (group, session) in self.group_sessions() {
            let known = match session.tours().await {
                Ok(t) => Ok(t),
                // A gcud that runs no tours (or predates them) answers NIC.
                Err(CommandError::Nic(_)) => Ok(Vec::new()),
                Err(e) => Err(e.to_string()),
            };
            by_group.push((group, known));
        }
        self.tours.lock().unwrap_or_else(|p| p.into_inner()).by_group = by_group;
    }

    /// Asks every gimbal's rules (`~B`; the session asks gcud again only
    /// after [`sagebrush_client::session::RULES_REFRESH`]). A gimbal whose
    /// gcud cannot say keeps what was known.
    async fn refresh_rules(&self) {
        for (i, g) in self.gimbals.iter().enumerate() {
            let known = match g.session.rules().await {
                Ok(r) => Some(r),
                // A gcud that predates `~B` draws no rules.
                Err(CommandError::Nic(_)) => None,
                Err(_) => continue,
            };
            if let Some(slot) = self.rules.lock().unwrap_or_else(|p| p.into_inner()).get_mut(i) {
                *slot = known;
            }
        }
    }

    /// The session of the group whose tours name `tour`.
    fn tour_session(&self, tour: &str) -> Option<Arc<GimbalSession>> {
        let group = {
            let tours = self.tours.lock().unwrap_or_else(|p| p.into_inner());
            tours.by_group.iter().find_map(|(g, known)| {
                known
                    .as_ref()
                    .ok()
                    .filter(|ts| ts.iter().any(|t| t.name == tour))
                    .map(|_| *g)
            })?
        };
        self.group_sessions()
            .into_iter()
            .find(|(g, _)| *g == group)
            .map(|(_, s)| s)
    }
}

async fn page(body: &'static str, kind: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, kind),
            (
                header::CONTENT_SECURITY_POLICY,
                "default-src 'none'; script-src 'self'; style-src 'self'; connect-src 'self'; img-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'",
            ),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::REFERRER_POLICY, "no-referrer"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

#[derive(Deserialize)]
struct SignIn {
    user: String,
    password: String,
}

async fn sign_in(
    State(w): Shared,
    Extension(Peer(peer)): Extension<Peer>,
    headers: HeaderMap,
    body: Result<axum::Json<SignIn>, axum::extract::rejection::JsonRejection>,
) -> Result<Response, Failure> {
    let axum::Json(body) = body.map_err(|e| bad(format!("expected JSON {{\"user\", \"password\"}}: {e}")))?;
    let now = Instant::now();
    let client = crate::forwarded::client(peer.ip(), &headers, &w.trusted_proxies);
    let account = w.auth.account(&body.user);
    let guard = || w.guard.lock().unwrap_or_else(|p| p.into_inner());
    if !guard().may_try(account, client, now) {
        return Err(Failure(
            StatusCode::TOO_MANY_REQUESTS,
            "too many failed sign-ins for this user from this address: wait a few seconds".to_owned(),
        ));
    }
    let (key, who) = match w.auth.sign_in(&body.user, &body.password, now) {
        Ok(ok) => ok,
        Err(why) => {
            guard().failed(account, client, now);
            let gate = w.failed.lock().unwrap_or_else(|p| p.into_inner()).allow(&account, now);
            if let Some(held_back) = gate {
                warn!(%client, %peer, user = ?body.user, held_back, "failed sign-in (logged at most once in {} s per user; held_back: failed sign-ins at that user since the last line)", FAILED_LOG_EVERY.as_secs());
            }
            return Err(Failure(StatusCode::UNAUTHORIZED, why));
        }
    };
    guard().succeeded(account, client);
    info!(%client, %peer, user = %who.user, role = who.role.name(), "signed in");
    let cookie = format!(
        "{}={key}; Path=/; HttpOnly; SameSite=Strict{}",
        crate::auth::COOKIE,
        if w.secure_cookie { "; Secure" } else { "" }
    );
    let mut response = (
        no_store(),
        axum::Json(json!({ "user": who.user, "role": who.role.name() })),
    )
        .into_response();
    let value =
        HeaderValue::from_str(&cookie).map_err(|e| Failure(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    response.headers_mut().insert(header::SET_COOKIE, value);
    Ok(response)
}

async fn sign_out(State(w): Shared, headers: HeaderMap) -> Result<Response, Failure> {
    w.allow(&headers, Role::User, "sign out")?;
    if let Some(key) = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(|c| crate::auth::cookie(c, crate::auth::COOKIE))
    {
        w.auth.sign_out(key);
    }
    let gone = format!(
        "{}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0{}",
        crate::auth::COOKIE,
        if w.secure_cookie { "; Secure" } else { "" }
    );
    let mut response = answer(json!({}));
    if let Ok(v) = HeaderValue::from_str(&gone) {
        response.headers_mut().insert(header::SET_COOKIE, v);
    }
    Ok(response)
}

async fn session(State(w): Shared, headers: HeaderMap) -> Result<Response, Failure> {
    let who = w.who(&headers)?;
    let gimbals: Vec<Value> = w
        .gimbals
        .iter()
        .map(|g| {
            json!({
                "name": g.config.name,
                "address": g.config.address.to_string(),
                "pan_deg": [g.config.pan_deg.0, g.config.pan_deg.1],
                "tilt_deg": [g.config.tilt_deg.0, g.config.tilt_deg.1],
            })
        })
        .collect();
    Ok(answer(json!({
        "user": who.user,
        "role": who.role.name(),
        "csrf": who.csrf,
        "lease_ms": w.lease.as_millis() as u64,
        "gimbals": gimbals,
    })))
}

/// The JSON body of a POST, with a clear error naming what was expected.
fn body<T: serde::de::DeserializeOwned>(bytes: &[u8], expected: &str) -> Result<T, Failure> {
    serde_json::from_slice(bytes).map_err(|e| bad(format!("expected JSON {expected}: {e}")))
}

/// Counts each request of a route by its path (the door's metrics: a
/// route, so the label's values are the routes', never a client's path).
async fn counted(State(w): Shared, request: axum::extract::Request, next: axum::middleware::Next) -> Response {
    if let Some(path) = request.extensions().get::<axum::extract::MatchedPath>() {
        w.metrics.request(path.as_str());
    }
    next.run(request).await
}

async fn not_found() -> Failure {
    Failure(StatusCode::NOT_FOUND, "no such page".to_owned())
}

/// Binds `config.listen` (so that an address in use is an error at start)
/// and returns the address and the server to run.
pub async fn bind(
    config: &config::Config,
    gimbals: Vec<Gimbal>,
    presets: Arc<Presets>,
    tls: Option<sagebrush_host::tls::TlsAcceptor>,
    metrics: Arc<DoorMetrics>,
) -> std::io::Result<(SocketAddr, impl Future<Output = ()> + use<>)> {
    let listener = tokio::net::TcpListener::bind(config.listen).await?;
    let local = listener.local_addr()?;
    let web = Arc::new(Web {
        rules: Mutex::new(vec![None; gimbals.len()]),
        gimbals,
        tours: Mutex::default(),
        auth: Auth::new(config.users.clone(), config.sign_in, config.max_sign_ins),
        presets,
        lease: config.hold_lease,
        secure_cookie: config.secure_cookie,
        trusted_proxies: config.trusted_proxies.clone(),
        guard: Mutex::new(Guard::new(config.users.len(), crate::guard::PAIRS, Instant::now())),
        failed: Mutex::new(LogGate::new(FAILED_LOG_EVERY, config.users.len() + 1)),
        snapshot: events::snapshot(),
        streams: events::Streams::new(config.max_streams_per_user),
        idle_timeout: config.http.idle_timeout,
        metrics,
    });
    let streams = Arc::clone(&web.streams);
    web.metrics.count_sessions(move || streams.len());
    let app = Router::new()
        .route("/", get(|| page(INDEX, "text/html; charset=utf-8")))
        .route("/app.js", get(|| page(APP_JS, "text/javascript; charset=utf-8")))
        .route("/style.css", get(|| page(STYLE, "text/css; charset=utf-8")))
        .route("/api/sign-in", post(sign_in))
        .route("/api/sign-out", post(sign_out))
        .route("/api/session", get(session))
        .merge(events::routes())
        .merge(actions::routes())
        .route_layer(axum::middleware::from_fn_with_state(Arc::clone(&web), counted))
        .fallback(not_found)
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .with_state(Arc::clone(&web));
    let listener = BoundedListener::new(listener, config.http.table(), "gimbal-web");
    let limits = config.http.limits();
    let scheme = if tls.is_some() { "https" } else { "http" };
    info!(addr = %local, scheme, "page listening");
    let serve = sagebrush_service::serve_http(listener, limits, tls, app);
    Ok((local, async move {
        // gcud's tours, asked every QUIET beside the page (no bus time),
        // and apart (an unreachable gcud delays neither) the gimbals'
        // rules (asked of gcud every RULES_REFRESH); the pages' snapshot
        // rendered every events::PUSH.
        let rules_web = Arc::clone(&web);
        let render = events::render(Arc::clone(&web));
        let ask = async move {
            loop {
                web.refresh_tours().await;
                tokio::time::sleep(QUIET).await;
            }
        };
        let rules = async move {
            loop {
                rules_web.refresh_rules().await;
                tokio::time::sleep(QUIET).await;
            }
        };
        tokio::select! {
            () = serve => {}
            () = ask => {}
            () = rules => {}
            () = render => {}
        }
    }))
}
