//! The router task: owns the `sagebrush-gcu` router core, feeds it what the
//! port and link tasks read, executes its actions, arms its one timer,
//! answers metrics scrapes, pings the systemd watchdog, and shuts down
//! gracefully on SIGTERM/SIGINT.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Duration;

use sagebrush_gcu::{
    Action, Event, Input, Level, LinkConfig, LinkId, LinkKind, PortConfig, Router, RouterConfig, SourceFilter,
};
use tokio::net::TcpListener;
use tokio::signal::unix::{SignalKind, signal};
use tokio::sync::{Semaphore, mpsc};
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tracing::{debug, error, info, warn};

use crate::config::{Config, LinkRole, LinkTransport, PortTransport};
use crate::io::{self, IoEvent, PortWrite};
use crate::stats;

/// Builds the router core's configuration from the validated file.
pub fn router_config(config: &Config) -> RouterConfig {
    let mut rc = RouterConfig::new(config.group);
    rc.name = config.name.clone();
    rc.serial = config.serial.clone();
    for port in &config.ports {
        let t = port.timing;
        let mut pc = PortConfig::new(port.id);
        pc.bps = t.baud;
        pc.retries = t.retries;
        pc.ack_timeout = t.ack_timeout_ms;
        pc.result_timeout = t.result_timeout_ms;
        pc.long_result_timeout = t.long_result_timeout_ms;
        pc.nic_window = t.nic_window_ms;
        pc.broadcast_guard = t.broadcast_guard_ms;
        pc.queue_bound = config.queue_depth;
        pc.idle_timeout = sagebrush::timing::wire_ms(8, t.baud) + 20;
        if let PortTransport::Simulated(devices) = &port.transport {
            pc.devices = Some(devices.clone());
        }
        rc.ports.push(pc);
    }
    rc.links.retries = config.link_retries;
    rc.links.ack_timeout = config.link_ack_timeout_ms;
    rc.links.delivery_timeout = config.delivery_timeout_ms;
    // A command forwarded to another GCU is answered after a whole port
    // transaction there; assume that GCU is configured like this one.
    let worst = |long: bool| {
        config
            .ports
            .iter()
            .map(|p| {
                let t = p.timing;
                let result = if long {
                    t.long_result_timeout_ms
                } else {
                    t.result_timeout_ms
                };
                (u64::from(t.retries) + 1) * t.ack_timeout_ms + result
            })
            .max()
            .unwrap_or(0)
    };
    let link_ack = (u64::from(config.link_retries) + 1) * config.link_ack_timeout_ms;
    rc.links.answer_timeout = rc.links.answer_timeout.max(2 * link_ack + worst(false));
    rc.links.long_answer_timeout = rc.links.long_answer_timeout.max(2 * link_ack + worst(true));
    for (group, name) in &config.routes {
        if let Some(index) = config.links.iter().position(|l| &l.name == name) {
            rc.static_routes.insert(*group, io::configured_link_id(index));
        }
    }
    rc.default_upstream = config
        .default_route
        .as_ref()
        .and_then(|name| config.links.iter().position(|l| &l.name == name))
        .map(io::configured_link_id);
    rc
}

fn link_config(config: &Config, index: usize) -> LinkConfig {
    let link = &config.links[index];
    let kind = match link.role {
        LinkRole::Upstream => LinkKind::Upstream,
        LinkRole::Downstream => LinkKind::Downstream,
        LinkRole::Client => LinkKind::Client,
    };
    let sources = match &link.allow_source_groups {
        Some(groups) => SourceFilter::Only(groups.clone()),
        None => SourceFilter::Any,
    };
    let mut lc = LinkConfig::new(kind, sources);
    lc.lossless = !matches!(link.transport, LinkTransport::Serial { .. });
    lc.motion_lease = link.motion_lease_ms;
    lc
}

/// What the daemon knows of a live link, for logs and metrics.
#[derive(Debug, Clone)]
pub struct LinkInfo {
    pub name: String,
    pub peer: String,
    writer: Option<mpsc::Sender<Vec<u8>>>,
}

/// Start-up failures that end the daemon (exit 1).
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error("{0}")]
    Router(String),
    #[error("link {link:?}: cannot listen on {addr}: {error}")]
    Listen {
        link: String,
        addr: std::net::SocketAddr,
        error: std::io::Error,
    },
    #[error("metrics: cannot listen on {addr}: {error}")]
    Metrics {
        addr: std::net::SocketAddr,
        error: std::io::Error,
    },
    #[error("cannot install signal handlers: {0}")]
    Signals(std::io::Error),
}

/// Runs the daemon until SIGTERM or SIGINT, then shuts down gracefully.
pub async fn run(config: Config) -> Result<(), StartError> {
    let mut router = Router::new(router_config(&config)).map_err(|e| StartError::Router(e.to_string()))?;
    let start = Instant::now();
    let (events_tx, mut events) = mpsc::channel::<IoEvent>(4096);

    // Listeners and the metrics endpoint bind now: a bad address is a start failure.
    let connections = Arc::new(Semaphore::new(config.max_connections));
    let mut listeners: Vec<JoinHandle<()>> = Vec::new();
    for (index, link) in config.links.iter().enumerate() {
        match link.transport {
            LinkTransport::Listen(addr) => {
                let listener = TcpListener::bind(addr).await.map_err(|error| StartError::Listen {
                    link: link.name.clone(),
                    addr,
                    error,
                })?;
                info!(link = %link.name, addr = %listener.local_addr().unwrap_or(addr), "listening");
                listeners.push(tokio::spawn(io::accept_loop(
                    index,
                    link.clone(),
                    listener,
                    connections.clone(),
                    events_tx.clone(),
                )));
            }
            _ => {
                tokio::spawn(io::run_link(index, link.clone(), events_tx.clone()));
            }
        }
    }
    if let Some(addr) = config.metrics {
        let listener = TcpListener::bind(addr)
            .await
            .map_err(|error| StartError::Metrics { addr, error })?;
        info!(addr = %listener.local_addr().unwrap_or(addr), "metrics at /metrics");
        let (scrape_tx, mut scrape_rx) = mpsc::channel(16);
        let events_tx = events_tx.clone();
        tokio::spawn(async move {
            while let Some(reply) = scrape_rx.recv().await {
                if events_tx.send(IoEvent::Scrape(reply)).await.is_err() {
                    break;
                }
            }
        });
        tokio::spawn(crate::metrics::serve(listener, scrape_tx));
    }
    for port in &config.ports {
        tokio::spawn(io::run_port(port.clone(), events_tx.clone()));
    }
    drop(events_tx);

    let mut sigterm = signal(SignalKind::terminate()).map_err(StartError::Signals)?;
    let mut sigint = signal(SignalKind::interrupt()).map_err(StartError::Signals)?;
    let watchdog = sd_notify::watchdog_enabled();
    let mut watchdog_tick = tokio::time::interval(watchdog.map_or(Duration::from_secs(3600), |d| d / 2));
    notify(&[sd_notify::NotifyState::Ready]);
    info!(
        group = config.group,
        ports = config.ports.len(),
        links = config.links.len(),
        "gcud ready"
    );

    let mut ports: HashMap<u8, mpsc::Sender<PortWrite>> = HashMap::new();
    let mut links: BTreeMap<LinkId, LinkInfo> = BTreeMap::new();
    let mut actions = Vec::new();
    let mut stopping: Option<Instant> = None;
    let now = |at: Instant| at.duration_since(start).as_millis() as u64;

    loop {
        let deadline = router.next_deadline().map(|t| start + Duration::from_millis(t));
        if let Some(until) = stopping {
            if router.in_progress() == 0 && router.pending_answers() == 0 {
                info!("in-flight transactions finished; exiting");
                break;
            }
            if Instant::now() >= until {
                warn!(
                    in_progress = router.in_progress(),
                    "shutdown grace time over; exiting with work unfinished"
                );
                break;
            }
        }
        tokio::select! {
            event = events.recv() => {
                let Some(event) = event else { break };
                let t = now(Instant::now());
                match event {
                    IoEvent::PortOpened { port, writer } => {
                        ports.insert(port, writer);
                        router.handle(t, Input::PortOpened { port }, &mut actions);
                    }
                    IoEvent::PortBytes { port, bytes } => router.handle(t, Input::PortBytes { port, bytes: &bytes }, &mut actions),
                    IoEvent::PortClosed { port } => {
                        ports.remove(&port);
                        router.handle(t, Input::PortLost { port }, &mut actions);
                    }
                    IoEvent::LinkOpened { id, link, peer, writer } => {
                        if stopping.is_some() {
                            continue; // dropping the writer closes it
                        }
                        links.insert(id, LinkInfo { name: config.links[link].name.clone(), peer, writer: Some(writer) });
                        router.handle(t, Input::LinkUp { link: id, config: link_config(&config, link) }, &mut actions);
                    }
                    IoEvent::LinkBytes { id, bytes } => router.handle(t, Input::LinkBytes { link: id, bytes: &bytes }, &mut actions),
                    IoEvent::LinkClosed { id } => {
                        if let Some(info) = links.get_mut(&id) {
                            info.writer = None;
                        }
                        router.handle(t, Input::LinkDown { link: id }, &mut actions);
                    }
                    IoEvent::Scrape(reply) => {
                        let _ = reply.send(stats::render(&router.stats(), &links, now(Instant::now())));
                    }
                }
            }
            () = sleep_until(deadline) => router.handle(now(Instant::now()), Input::Tick, &mut actions),
            _ = watchdog_tick.tick(), if watchdog.is_some() => notify(&[sd_notify::NotifyState::Watchdog]),
            _ = sigterm.recv(), if stopping.is_none() => {
                stopping = Some(begin_shutdown(&config, &mut listeners, "SIGTERM"));
                router.handle(now(Instant::now()), Input::Shutdown, &mut actions);
            }
            _ = sigint.recv(), if stopping.is_none() => {
                stopping = Some(begin_shutdown(&config, &mut listeners, "SIGINT"));
                router.handle(now(Instant::now()), Input::Shutdown, &mut actions);
            }
            () = sleep_until(stopping.map(|s| s.min(Instant::now() + Duration::from_millis(50)))) => {}
        }
        execute(&mut actions, &ports, &links);
    }
    Ok(())
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

fn begin_shutdown(config: &Config, listeners: &mut Vec<JoinHandle<()>>, signal: &str) -> Instant {
    info!(
        signal,
        grace_ms = config.shutdown_grace_ms,
        "shutting down: no new connections or commands, stopping running motions, finishing in-flight work"
    );
    notify(&[sd_notify::NotifyState::Stopping]);
    for l in listeners.drain(..) {
        l.abort();
    }
    Instant::now() + Duration::from_millis(config.shutdown_grace_ms)
}

fn notify(state: &[sd_notify::NotifyState<'_>]) {
    if let Err(e) = sd_notify::notify(state) {
        warn!(error = %e, "cannot notify systemd");
    }
}

/// Carries out the router's actions in order.
fn execute(
    actions: &mut Vec<Action>,
    ports: &HashMap<u8, mpsc::Sender<PortWrite>>,
    links: &BTreeMap<LinkId, LinkInfo>,
) {
    for action in actions.drain(..) {
        match action {
            Action::WritePort { port, bytes } => match ports.get(&port) {
                Some(tx) => {
                    if tx.try_send(PortWrite::Bytes(bytes)).is_err() {
                        warn!(port, "port writer is behind or gone: bytes dropped");
                    }
                }
                None => debug!(port, "write to a closed port dropped"),
            },
            Action::WriteLink { link, bytes } => match links.get(&link).and_then(|l| l.writer.as_ref()) {
                Some(tx) => {
                    if tx.try_send(bytes).is_err() {
                        warn!(%link, "link writer is behind or gone: bytes dropped");
                    }
                }
                None => debug!(%link, "write to a closed link dropped"),
            },
            Action::SetPortRate { port, bps } => {
                if let Some(tx) = ports.get(&port) {
                    if tx.try_send(PortWrite::SetBaud(bps)).is_err() {
                        error!(port, bps, "cannot switch the port's line rate: writer gone");
                    }
                }
            }
            Action::Event(event) => log_event(&event, links),
        }
    }
}

fn log_event(event: &Event, links: &BTreeMap<LinkId, LinkInfo>) {
    // Events about a link name it as configured, with its peer.
    let context = match event {
        Event::LinkState { link, .. } | Event::DeadManStop { link, .. } => links
            .get(link)
            .map_or_else(String::new, |l| format!(" ({} {})", l.name, l.peer)),
        _ => String::new(),
    };
    match event.level() {
        Level::Debug => debug!("{event}{context}"),
        Level::Info => info!("{event}{context}"),
        Level::Warn => warn!("{event}{context}"),
    }
}
