//! The router task: owns the `sagebrush-gcu` router core and the GCU's open
//! ports and links (module `lines`), feeds it what they read, executes its
//! actions, arms its one timer,
//! answers metrics scrapes, pings the systemd watchdog, reloads the
//! configuration on SIGHUP (module `reload`), and shuts down gracefully on
//! SIGTERM/SIGINT, stopping what it started.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Duration;

use sagebrush_gcu::{Action, Input, Level, LinkId, LinkStats, Outbox, Place, Router, RouterEvent};
use sagebrush_host::capture::CaptureSwitch;
use tokio::net::TcpListener;
use tokio::signal::unix::{SignalKind, signal};
use tokio::sync::mpsc;

use crate::admission::{Connections, Limits};
use crate::capture::CaptureControl;
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tracing::{debug, error, info, warn};

use crate::config::{Config, Link, LinkTransport, Port};
use crate::io::{self, IoEvent};
use crate::lines::{LineEvent, LineId, Lines, Refused};
use crate::reload::{Diff, Reread};
use crate::snapshot::{RouterState, Snapshot};
use sagebrush_host::throttle::Throttle;

/// Stable ids of configured links, by name: kept across reconnects and
/// reloads, so that routes keep pointing at the right link.
#[derive(Debug, Default)]
struct LinkIds(BTreeMap<String, LinkId>);

impl LinkIds {
    fn of(&mut self, name: &str) -> LinkId {
        let next = LinkId(self.0.values().map(|l| l.0).max().unwrap_or(0) + 1);
        *self.0.entry(name.to_owned()).or_insert(next)
    }
}

/// What the daemon knows of a live link, for logs and metrics.
#[derive(Debug, Clone)]
pub struct LinkInfo {
    pub name: String,
    pub peer: String,
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

/// The I/O tasks of the configured ports and links, so that a reload can
/// close and open them one by one.
struct Tasks {
    events: mpsc::Sender<IoEvent>,
    connections: Arc<Connections>,
    ports: HashMap<u8, JoinHandle<()>>,
    links: BTreeMap<String, JoinHandle<()>>,
    /// The bound listeners, by link name, with the address configured (a
    /// reload hands one over to the link that takes its address).
    listeners: BTreeMap<String, (std::net::SocketAddr, Arc<TcpListener>)>,
    /// `[capture]`: every port and link task taps its bytes here.
    capture: Arc<CaptureSwitch>,
}

impl Tasks {
    /// The listener of a `listen` link, bound now (`None` for other links):
    /// the one a link closing in the same reload holds at that address, or
    /// a new one (an address in use is an error).
    async fn bind(&self, link: &Link, closing: &[&str]) -> Result<Option<Arc<TcpListener>>, StartError> {
        let LinkTransport::Listen(addr) = link.transport else {
            return Ok(None);
        };
        let held = self
            .listeners
            .iter()
            .find(|(name, (at, _))| *at == addr && addr.port() != 0 && closing.contains(&name.as_str()));
        if let Some((_, (_, listener))) = held {
            return Ok(Some(listener.clone()));
        }
        let listener = TcpListener::bind(addr).await.map_err(|error| StartError::Listen {
            link: link.name.clone(),
            addr,
            error,
        })?;
        Ok(Some(Arc::new(listener)))
    }

    /// Starts a link; a `listen` link accepts on `listener` (from [`Tasks::bind`]).
    fn start_link(&mut self, link: &Link, id: LinkId, listener: Option<Arc<TcpListener>>) {
        let task = match (link.transport.clone(), listener) {
            (LinkTransport::Listen(addr), Some(listener)) => {
                info!(link = %link.name, addr = %listener.local_addr().unwrap_or(addr), "listening");
                self.listeners.insert(link.name.clone(), (addr, listener.clone()));
                let connections = self.connections.clone();
                tokio::spawn(io::accept_loop(
                    link.clone(),
                    listener,
                    connections,
                    self.events.clone(),
                    self.capture.clone(),
                ))
            }
            _ => tokio::spawn(io::run_link(
                id,
                link.clone(),
                self.events.clone(),
                self.capture.clone(),
            )),
        };
        if let Some(old) = self.links.insert(link.name.clone(), task) {
            old.abort();
        }
    }

    fn stop_link(&mut self, name: &str) {
        self.listeners.remove(name);
        if let Some(task) = self.links.remove(name) {
            task.abort();
        }
    }

    fn start_port(&mut self, port: &Port) {
        let task = tokio::spawn(io::run_port(port.clone(), self.events.clone(), self.capture.clone()));
        if let Some(old) = self.ports.insert(port.id, task) {
            old.abort();
        }
    }

    fn stop_port(&mut self, id: u8) {
        if let Some(task) = self.ports.remove(&id) {
            task.abort();
        }
    }
}

/// Runs the daemon until SIGTERM or SIGINT, then shuts down gracefully.
pub async fn run(mut config: Config, http_limits: crate::http::Limits) -> Result<(), StartError> {
    let mut ids = LinkIds::default();
    let mut router =
        Router::new(config.router_config(|name| ids.of(name))).map_err(|e| StartError::Router(e.to_string()))?;
    let start = Instant::now();
    // Tick 0 on the wall clock, for the Unix timestamps of metrics and status.
    let started_unix_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    let (events_tx, mut events) = mpsc::channel::<IoEvent>(4096);
    let mut tasks = Tasks {
        events: events_tx.clone(),
        connections: Connections::new(Limits {
            max_total: config.limits.max_connections.get(),
            max_per_peer: config.limits.per_peer(),
            cap_loopback: config.limits.per_peer_configured(),
            idle_timeout: config.limits.idle_timeout_ms.duration(),
        }),
        ports: HashMap::new(),
        links: BTreeMap::new(),
        listeners: BTreeMap::new(),
        capture: CaptureSwitch::new(),
    };
    // Opened off this task: a FIFO nobody reads yet holds up nothing.
    let capture = CaptureControl::spawn(tasks.capture.clone());
    if config.capture.as_ref().is_some_and(|c| c.enabled) {
        capture.start(&config).await;
    }

    // Listeners and the metrics endpoint bind now: a bad address is a start failure.
    for link in &config.links {
        let listener = tasks.bind(link, &[]).await?;
        tasks.start_link(link, ids.of(&link.name), listener);
    }
    if let Some(metrics) = &config.metrics {
        let addr = metrics.listen;
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
        let counters = Arc::new(crate::http::Counters::default());
        tokio::spawn(crate::http::serve(
            listener,
            metrics.allow_peers.clone(),
            http_limits,
            crate::http::app(scrape_tx, counters.clone()),
            counters,
        ));
    }
    for port in &config.ports {
        tasks.start_port(port);
    }
    drop(events_tx);

    let mut sigterm = signal(SignalKind::terminate()).map_err(StartError::Signals)?;
    let mut sigint = signal(SignalKind::interrupt()).map_err(StartError::Signals)?;
    let mut sighup = signal(SignalKind::hangup()).map_err(StartError::Signals)?;
    let mut sigusr1 = signal(SignalKind::user_defined1()).map_err(StartError::Signals)?;
    let watchdog = sd_notify::watchdog_enabled();
    let mut watchdog_tick = tokio::time::interval(watchdog.map_or(Duration::from_secs(3600), |d| d / 2));
    notify(&[sd_notify::NotifyState::Ready]);
    info!(
        group = config.gcu.group.get(),
        ports = config.ports.len(),
        links = config.links.len(),
        "gcud ready"
    );

    let mut lines = Lines::new();
    let mut links: BTreeMap<LinkId, LinkInfo> = BTreeMap::new();
    // Final counters of connections gone, per configured link name.
    let mut departed: BTreeMap<String, LinkStats> = BTreeMap::new();
    let mut throttle = Throttle::default();
    // Reused for every call: the router's writes land in its one buffer.
    let mut actions = Outbox::new();
    let mut stopping: Option<Instant> = None;
    // Ports closing after a reload, with the time their grace runs out.
    let mut closing: HashMap<u8, Instant> = HashMap::new();
    let now = |at: Instant| at.duration_since(start).as_millis() as u64;
    let mut turn = Turn::default();

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
                    pending_answers = router.pending_answers(),
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
                    IoEvent::PortOpened { port, stream, tap, baud, ended } => {
                        lines.add(LineId::Port(port), stream, tap, baud, None, ended);
                        router.handle(t, Input::PortOpened { port }, &mut actions);
                    }
                    IoEvent::LinkOpened { id, link, peer, stream, tap, admission, ended } => {
                        let Some(configured) = config.links.iter().find(|l| l.name == link) else {
                            continue; // removed by a reload; dropping the writer closes it
                        };
                        if stopping.is_some() {
                            continue;
                        }
                        let mut lc = configured.router();
                        if matches!(configured.transport, LinkTransport::Listen(_)) {
                            // Routes naming the listener reach this connection.
                            lc.listener = Some(ids.of(&configured.name));
                        }
                        lines.add(LineId::Link(id), stream, tap, 0, admission, ended);
                        links.insert(id, LinkInfo { name: link, peer });
                        router.handle(t, Input::LinkUp { link: id, config: lc }, &mut actions);
                    }
                    IoEvent::CloseLink { id, reason } => {
                        if lines.close(LineId::Link(id), reason) {
                            router.handle(t, Input::LinkDown { link: id }, &mut actions);
                        }
                    }
                    IoEvent::Scrape(reply) => {
                        let state = RouterState {
                            router: &router,
                            configured: config.links.iter().map(|l| {
                                (l.name.as_str(), l.kind, tasks.listeners.contains_key(&l.name))
                            }),
                            name_of: |id| links.get(&id).map(|l| l.name.as_str()),
                            departed: &departed,
                            uptime_ms: now(Instant::now()),
                        };
                        let mut s = Snapshot::take(state, config.gcu.group.get(), config.gcu.name.get());
                        s.connections = tasks.connections.stats();
                        s.started_unix_ms = started_unix_ms;
                        s.shutting_down = stopping.is_some();
                        s.capture = tasks.capture.current().map(|c| c.stats());
                        let _ = reply.send(s);
                    }
                }
            }
            event = std::future::poll_fn(|cx| lines.poll_next(cx)) => {
                let t = now(Instant::now());
                turn.read(&event).await;
                match event {
                    LineEvent::Read(line, n) => router.handle(t, Input::Bytes { line, bytes: lines.read(n) }, &mut actions),
                    LineEvent::Closed(LineId::Port(port)) => router.handle(t, Input::PortLost { port }, &mut actions),
                    LineEvent::Closed(LineId::Link(link)) => router.handle(t, Input::LinkDown { link }, &mut actions),
                }
            }
            () = sleep_until(deadline) => router.handle(now(Instant::now()), Input::Tick, &mut actions),
            _ = watchdog_tick.tick(), if watchdog.is_some() => notify(&[sd_notify::NotifyState::Watchdog]),
            _ = sigterm.recv(), if stopping.is_none() => {
                stopping = Some(begin_shutdown(&config, "SIGTERM"));
                router.handle(now(Instant::now()), Input::Shutdown, &mut actions);
            }
            _ = sigint.recv(), if stopping.is_none() => {
                stopping = Some(begin_shutdown(&config, "SIGINT"));
                router.handle(now(Instant::now()), Input::Shutdown, &mut actions);
            }
            _ = sighup.recv(), if stopping.is_none() => {
                let t = now(Instant::now());
                let reloaded = Reload { config: &mut config, ids: &mut ids, router: &mut router, tasks: &mut tasks, lines: &mut lines, links: &mut links, closing: &mut closing };
                reloaded.run(t, &mut actions).await;
            }
            _ = sigusr1.recv() => capture.toggle(&config, "SIGUSR1"),
            () = sleep_until(
                [stopping, closing.values().min().copied(), throttle.next_deadline()]
                    .into_iter()
                    .flatten()
                    .min()
                    .map(|s| s.min(Instant::now() + Duration::from_millis(50)).max(Instant::now() + Duration::from_millis(1)))
            ) => {}
        }
        // Ports closing after a reload: closed once idle (their stops
        // done) or when their grace ran out.
        let t = now(Instant::now());
        let overdue: Vec<u8> = closing
            .iter()
            .filter(|(_, until)| Instant::now() >= **until)
            .map(|(&p, _)| p)
            .collect();
        for port in router.closed_ports().into_iter().chain(overdue) {
            if closing.remove(&port).is_none() {
                continue;
            }
            tasks.stop_port(port);
            lines.close(LineId::Port(port), "configuration reloaded");
            router.port_closed(t, port, &mut actions);
            info!(port, "port closed (configuration reloaded)");
            if let Some(new) = config.ports.iter().find(|p| p.id == port) {
                tasks.start_port(new);
            }
        }
        execute(&mut actions, &mut lines, &mut links, &mut departed, &mut throttle);
        // Written now, straight from this task; what a line cannot take yet
        // is written when it can (`Lines::poll_next`).
        std::future::poll_fn(|cx| {
            lines.flush(cx);
            std::task::Poll::Ready(())
        })
        .await;
        for summary in throttle.summaries(Instant::now()) {
            warn!("{summary}");
        }
    }
    // Let go of every port and link (their writers and the event channel), so
    // that their tasks end as a shutdown, logged at info, not as a loss; wait
    // briefly for the ports' last lines.
    let _ = tokio::time::timeout(
        Duration::from_millis(500),
        std::future::poll_fn(|cx| lines.poll_drained(cx)),
    )
    .await;
    lines.release();
    drop((links, events));
    let ending = tasks.ports.drain().map(|(_, task)| task).collect::<Vec<_>>();
    let _ = tokio::time::timeout(Duration::from_millis(500), async {
        for task in ending {
            let _ = task.await;
        }
    })
    .await;
    capture.stop("gcud stopping").await;
    Ok(())
}

/// One SIGHUP (module `reload`): the file is read and checked as at start;
/// a broken or unreadable one, or one that changes what needs a restart,
/// is refused and logged, and the running configuration stays. Otherwise
/// the difference is applied.
struct Reload<'a> {
    config: &'a mut Config,
    ids: &'a mut LinkIds,
    router: &'a mut Router,
    tasks: &'a mut Tasks,
    lines: &'a mut Lines,
    links: &'a mut BTreeMap<LinkId, LinkInfo>,
    closing: &'a mut HashMap<u8, Instant>,
}

impl Reload<'_> {
    async fn run(self, now: u64, actions: &mut Outbox) {
        // RELOADING=1 goes with MONOTONIC_USEC= (sd_notify(3)).
        match sd_notify::NotifyState::monotonic_usec_now() {
            Ok(usec) => notify(&[sd_notify::NotifyState::Reloading, usec]),
            Err(_) => notify(&[sd_notify::NotifyState::Reloading]),
        }
        info!(file = %self.config.file.display(), "SIGHUP: reloading the configuration");
        if let Some(new) = Reread::Reload.read(&self.config.file) {
            self.apply(now, new, actions).await
        }
        notify(&[sd_notify::NotifyState::Ready]);
    }

    async fn apply(self, now: u64, new: Config, actions: &mut Outbox) {
        let diff = Diff::between(self.config, &new);
        if !diff.needs_restart.is_empty() {
            return error!(
                "reload refused, running configuration kept: {} changed; restart gcud to apply it",
                diff.needs_restart.join(", ")
            );
        }
        if diff.is_empty() {
            return info!("configuration unchanged");
        }
        // All or nothing: every new listener is bound before anything
        // changes; one that cannot bind refuses the reload (a later SIGHUP
        // tries again, as the running configuration still differs).
        let closing: Vec<&str> = diff
            .links_changed
            .iter()
            .map(|l| l.name.as_str())
            .chain(diff.links_removed.iter().map(String::as_str))
            .collect();
        let mut bound = BTreeMap::new();
        for link in diff.links_changed.iter().chain(&diff.links_added) {
            match self.tasks.bind(link, &closing).await {
                Ok(listener) => {
                    bound.insert(link.name.clone(), listener);
                }
                Err(e) => return error!("reload refused, running configuration kept: {e}"),
            }
        }
        let reopen: Vec<u8> = diff.ports_changed.iter().map(|p| p.id).collect();
        if let Err(e) = self
            .router
            .reconfigure(now, new.router_config(|name| self.ids.of(name)), &reopen, actions)
        {
            return error!("reload refused, running configuration kept: {e}");
        }
        for line in diff.to_string().lines() {
            info!("reload: {line}");
        }
        for (name, priority) in &diff.priorities_changed {
            self.router.set_link_priority(name, *priority);
        }
        let grace = Instant::now() + new.gcu.shutdown_grace_ms.duration();
        for port in diff
            .ports_changed
            .iter()
            .map(|p| p.id)
            .chain(diff.ports_removed.iter().copied())
        {
            self.closing.insert(port, grace);
        }
        for port in &diff.ports_added {
            self.tasks.start_port(port);
        }
        let closed = diff
            .links_changed
            .iter()
            .map(|l| l.name.clone())
            .chain(diff.links_removed.iter().cloned());
        for name in closed {
            self.tasks.stop_link(&name);
            // Its connections are gone: the router takes them down (dead-man).
            let named: Vec<LinkId> = self
                .links
                .iter()
                .filter(|(_, l)| l.name == name)
                .map(|(&id, _)| id)
                .collect();
            for id in named {
                if self
                    .lines
                    .close(LineId::Link(id), "link removed or changed by a reload")
                {
                    self.router.handle(now, Input::LinkDown { link: id }, actions);
                }
            }
        }
        *self.config = new;
        for link in diff.links_changed.iter().chain(&diff.links_added) {
            let listener = bound.remove(&link.name).flatten();
            self.tasks.start_link(link, self.ids.of(&link.name), listener);
        }
    }
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

fn begin_shutdown(config: &Config, signal: &str) -> Instant {
    info!(
        signal,
        grace_ms = config.gcu.shutdown_grace_ms.get(),
        "shutting down: no new connections or commands, stopping running motions, finishing in-flight work"
    );
    notify(&[sd_notify::NotifyState::Stopping]);
    Instant::now() + config.gcu.shutdown_grace_ms.duration()
}

fn notify(state: &[sd_notify::NotifyState<'_>]) {
    if let Err(e) = sd_notify::notify(state) {
        warn!(error = %e, "cannot notify systemd");
    }
}

/// A write a line did not take: logged, throttled per port or configured
/// link, when the line is behind (its peer is not reading).
fn write_refused(line: LineId, refused: Refused, links: &BTreeMap<LinkId, LinkInfo>, throttle: &mut Throttle) {
    let (place, text) = match line {
        LineId::Port(port) => (format!("port {port}"), "the port is not taking bytes"),
        LineId::Link(link) => (
            links.get(&link).map_or_else(|| link.to_string(), |l| l.name.clone()),
            "the peer is not reading",
        ),
    };
    match refused {
        Refused::Behind => {
            let message = || match line {
                LineId::Port(_) => format!("{place}: {text} (limit reached): bytes dropped"),
                LineId::Link(link) => format!("{link} ({place}): {text} (limit reached): bytes dropped"),
            };
            if throttle.allow("writer behind", &place, message, Instant::now()) {
                warn!(%line, "{text} (limit reached): bytes dropped");
            }
        }
        Refused::Closed => debug!(%line, "write to a closed line dropped"),
    }
}

/// Carries out the router's actions in order: writes are queued on their
/// lines straight from the Outbox's buffer. A link gone leaves its counters
/// with its configured link and nothing else behind.
fn execute(
    actions: &mut Outbox,
    lines: &mut Lines,
    links: &mut BTreeMap<LinkId, LinkInfo>,
    departed: &mut BTreeMap<String, LinkStats>,
    throttle: &mut Throttle,
) {
    let mut gone = Vec::new();
    for action in actions.actions() {
        match action {
            Action::Write { line, bytes } => {
                if let Err(refused) = lines.write(*line, actions.bytes(bytes)) {
                    write_refused(*line, refused, links, throttle);
                }
            }
            Action::SetPortRate { port, bps } => match lines.set_baud(*port, *bps) {
                Ok(()) => info!(port, baud = bps, "line rate switched"),
                Err(reason) => error!(port, bps, %reason, "port lost: cannot switch its line rate; reopening"),
            },
            Action::Event(event) => log_event(event, links, throttle),
            Action::LinkGone { link, stats } => {
                if let Some(info) = links.get(link) {
                    match departed.get_mut(&info.name) {
                        Some(d) => d.absorb(stats),
                        None => {
                            departed.insert(info.name.clone(), **stats);
                        }
                    }
                }
                // Named in the logs of the actions after this one.
                gone.push(*link);
            }
        }
    }
    actions.clear();
    for link in gone {
        links.remove(&link);
    }
}

/// Logs a router event; repeated warnings of one kind from one place are
/// throttled (module `throttle`).
fn log_event(event: &RouterEvent, links: &BTreeMap<LinkId, LinkInfo>, throttle: &mut Throttle) {
    let name = |link: &LinkId| links.get(link).map_or_else(|| link.to_string(), |l| l.name.clone());
    // Events about a link name it as configured, with its peer.
    let context = match event {
        RouterEvent::LinkState { link, .. } | RouterEvent::IssuedStop { link, .. } => links
            .get(link)
            .map_or_else(String::new, |l| format!(" ({} {})", l.name, l.peer)),
        _ => String::new(),
    };
    match event.level() {
        Level::Debug => debug!("{event}{context}"),
        Level::Info => info!("{event}{context}"),
        Level::Warn => {
            let (kind, place) = match event {
                RouterEvent::Dropped { reason, at, .. } => (
                    format!("dropped {}", reason.name()),
                    match at {
                        Place::Link(link) => name(link),
                        other => other.to_string(),
                    },
                ),
                RouterEvent::Undelivered { failure, origin, .. } => (
                    format!("undelivered {}", failure.name()),
                    origin.link().as_ref().map_or_else(String::new, name),
                ),
                RouterEvent::Finished { outcome, .. } => (format!("finished {outcome:?}"), String::new()),
                RouterEvent::IssuedStop { link, .. } => ("stop".to_owned(), name(link)),
                RouterEvent::DeviceState { port, device, .. } => {
                    ("device silent".to_owned(), format!("{port}.{device}"))
                }
                other => (format!("{:?}", std::mem::discriminant(other)), String::new()),
            };
            if throttle.allow(&kind, &place, || format!("{event}{context}"), Instant::now()) {
                warn!("{event}{context}");
            }
        }
    }
}

/// Bounds the router task's turn: lines that always have bytes (a flooding
/// client) would otherwise keep it from yielding, and the tasks that share
/// its thread (in-process simulated buses, the io tasks) would wait for
/// their turn (the adversarial run: another client's `P?` to a simulated
/// port from 0.1 to 13 ms). Real ports are served by the kernel meanwhile.
#[derive(Debug, Default)]
struct Turn {
    bytes: usize,
}

impl Turn {
    /// Bytes the router task handles before it lets the others run.
    const BYTES: usize = 4 * 1024;

    async fn read(&mut self, event: &LineEvent) {
        if let LineEvent::Read(_, n) = event {
            self.bytes += n;
            if self.bytes >= Self::BYTES {
                self.bytes = 0;
                tokio::task::yield_now().await;
            }
        }
    }
}
