//! The router task: owns the `sagebrush-gcu` router core and the GCU's open
//! ports and links (module `lines`), feeds it what they read, executes its
//! actions, arms its one timer (module `timer`),
//! answers metrics scrapes, pings the systemd watchdog, reloads the
//! configuration on SIGHUP (module `reload`), and shuts down gracefully on
//! SIGTERM/SIGINT, stopping what it started.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Duration;

use sagebrush_gcu::{Input, LinkId, Outbox, Router};
use sagebrush_host::capture::CaptureSwitch;
use tokio::net::TcpListener;
use tokio::signal::unix::{SignalKind, signal};
use tokio::sync::mpsc;

use crate::admission::{Connections, Limits};
use crate::capture::CaptureControl;
use tokio::time::Instant;
use tracing::{error, info, warn};

use crate::config::{Config, LinkTransport};
use crate::io::IoEvent;
use crate::lines::{LineEvent, LineId, Lines, Rate};
use crate::reload::{Diff, Reread};
use crate::shard::Shards;
use crate::snapshot::{RouterState, Snapshot};

mod actions;
mod links;
mod tasks;
mod timer;

use actions::execute;
use links::{LinkBook, LinkInfo};
use sagebrush_host::throttle::Throttle;
use tasks::Tasks;
use timer::RouterTimer;

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
    #[error("cannot start the port threads ([gcu] threads): {0}")]
    Threads(std::io::Error),
}

/// Runs the daemon until SIGTERM or SIGINT, then shuts down gracefully.
pub async fn run(config: Config, http_limits: crate::http::Limits) -> Result<(), StartError> {
    let (mut d, mut events, capture) = Daemon::start(config, http_limits).await?;
    let mut sigterm = signal(SignalKind::terminate()).map_err(StartError::Signals)?;
    let mut sigint = signal(SignalKind::interrupt()).map_err(StartError::Signals)?;
    let mut sighup = signal(SignalKind::hangup()).map_err(StartError::Signals)?;
    let mut sigusr1 = signal(SignalKind::user_defined1()).map_err(StartError::Signals)?;
    let watchdog = sd_notify::watchdog_enabled();
    let mut watchdog_tick = tokio::time::interval(watchdog.map_or(Duration::from_secs(3600), |d| d / 2));
    notify(&[sd_notify::NotifyState::Ready]);
    info!(
        group = d.config.gcu.group.get(),
        ports = d.config.ports.len(),
        links = d.config.links.len(),
        threads = d.config.gcu.threads.get(),
        "gcud ready"
    );
    let mut turn = Turn::default();
    let mut timer = RouterTimer::new();

    loop {
        let core = d.router.next_deadline().map(|t| d.start + Duration::from_millis(t));
        timer.arm(core.into_iter().chain(d.lines.next_held_ack()).min());
        if d.stopping.is_some_and(|until| d.stopped(until)) {
            break;
        }
        let wake = d.next_wake();
        tokio::select! {
            event = events.recv() => {
                let Some(event) = event else { break };
                if !d.io_event(event) {
                    continue;
                }
            }
            event = std::future::poll_fn(|cx| d.lines.poll_next(cx)) => {
                let t = d.now(Instant::now());
                turn.read(&event).await;
                d.line_event(t, event);
            }
            () = std::future::poll_fn(|cx| timer.poll_fired(cx)) => d.handle(d.now(Instant::now()), Input::Tick),
            _ = watchdog_tick.tick(), if watchdog.is_some() => notify(&[sd_notify::NotifyState::Watchdog]),
            _ = sigterm.recv(), if d.stopping.is_none() => d.shut_down("SIGTERM"),
            _ = sigint.recv(), if d.stopping.is_none() => d.shut_down("SIGINT"),
            _ = sighup.recv(), if d.stopping.is_none() => d.reload().await,
            _ = sigusr1.recv() => capture.toggle(&d.config, "SIGUSR1"),
            () = sleep_until(wake) => {}
        }
        d.close_reloaded_ports();
        d.carry_out().await;
    }
    d.release(events, capture).await;
    Ok(())
}

/// What the router task owns once started: the router core, the
/// configuration in force, the I/O tasks and their lines, and what the
/// daemon knows of live and departed links.
struct Daemon {
    /// The configuration in force, the router core configured by it, and
    /// the one buffer every call's writes land in.
    config: Config,
    router: Router,
    actions: Outbox,
    /// The ports' and links' I/O tasks, and the lines they serve.
    tasks: Tasks,
    lines: Lines,
    links: LinkBook,
    /// Rate limits of repeated warnings.
    throttle: Throttle,
    stopping: Option<Instant>,
    /// Ports closing after a reload, with the time their grace runs out.
    closing: HashMap<u8, Instant>,
    start: Instant,
    /// Tick 0 on the wall clock, for the Unix timestamps of metrics and status.
    started_unix_ms: u64,
}

impl Daemon {
    /// The router, the configured links' listeners, the metrics endpoint and
    /// the ports' tasks; with the channel the I/O tasks report on and the
    /// capture control.
    async fn start(
        config: Config,
        http_limits: crate::http::Limits,
    ) -> Result<(Self, mpsc::Receiver<IoEvent>, CaptureControl), StartError> {
        let mut links = LinkBook::default();
        let router = Router::new(config.router_config(|name| links.ids.of(name)))
            .map_err(|e| StartError::Router(e.to_string()))?;
        let start = Instant::now();
        let started_unix_ms = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        let (events_tx, events) = mpsc::channel::<IoEvent>(4096);
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
            shards: Shards::start(config.gcu.threads.get()).map_err(StartError::Threads)?,
        };
        // Opened off this task: a FIFO nobody reads yet holds up nothing.
        let capture = CaptureControl::spawn(tasks.capture.clone());
        if config.capture.as_ref().is_some_and(|c| c.enabled) {
            capture.start(&config).await;
        }

        // Listeners and the metrics endpoint bind now: a bad address is a start failure.
        for link in &config.links {
            let listener = tasks.bind(link, &[]).await?;
            tasks.start_link(link, links.ids.of(&link.name), listener);
        }
        if let Some(metrics) = &config.metrics {
            serve_metrics(metrics, http_limits, events_tx.clone()).await?;
        }
        for port in &config.ports {
            tasks.start_port(port);
        }
        drop(events_tx);
        let daemon = Self {
            config,
            router,
            tasks,
            lines: Lines::new(),
            links,
            throttle: Throttle::default(),
            actions: Outbox::new(),
            stopping: None,
            closing: HashMap::new(),
            start,
            started_unix_ms,
        };
        Ok((daemon, events, capture))
    }

    /// Milliseconds since the start, the router's clock.
    fn now(&self, at: Instant) -> u64 {
        at.duration_since(self.start).as_millis() as u64
    }

    fn handle(&mut self, now: u64, input: Input) {
        self.router.handle(now, input, &mut self.actions);
    }

    /// Whether a shutdown is over: in-flight work finished, or its grace
    /// (until `until`) ran out.
    fn stopped(&self, until: Instant) -> bool {
        let router = &self.router;
        if router.in_progress() == 0 && router.pending_answers() == 0 {
            info!("in-flight transactions finished; exiting");
            return true;
        }
        if Instant::now() >= until {
            warn!(
                in_progress = router.in_progress(),
                pending_answers = router.pending_answers(),
                "shutdown grace time over; exiting with work unfinished"
            );
            return true;
        }
        false
    }

    /// An I/O task's report. False when it was dropped (a link removed by a
    /// reload, or opened while shutting down): nothing to carry out then.
    fn io_event(&mut self, event: IoEvent) -> bool {
        let t = self.now(Instant::now());
        match event {
            IoEvent::PortOpened {
                port,
                stream,
                tap,
                rate,
                ended,
            } => {
                self.lines.add(LineId::Port(port), stream, tap, rate, None, ended);
                self.handle(t, Input::PortOpened { port });
            }
            IoEvent::LinkOpened {
                id,
                link,
                peer,
                principal,
                stream,
                tap,
                admission,
                ended,
            } => {
                let Some(configured) = self.config.links.iter().find(|l| l.name == link) else {
                    return false; // removed by a reload; dropping the writer closes it
                };
                if self.stopping.is_some() {
                    return false;
                }
                let mut lc = configured.router();
                if configured.requires_principal() {
                    let known = principal
                        .as_deref()
                        .and_then(|cn| self.config.governance.principals.iter().find(|p| &*p.name == cn));
                    let Some(known) = known else {
                        warn!(link = %link, %peer, cn = principal.as_deref().unwrap_or(""), "connection refused: its client certificate's CN names no [[principal]]");
                        return true; // dropping the stream closes it
                    };
                    lc.principal = Some(known.clone());
                }
                if matches!(configured.transport, LinkTransport::Listen(_)) {
                    // Routes naming the listener reach this connection.
                    lc.listener = Some(self.links.ids.of(&configured.name));
                }
                self.lines
                    .add(LineId::Link(id), stream, tap, Rate::none(), admission, ended);
                self.links.live.insert(id, LinkInfo { name: link, peer });
                self.handle(t, Input::LinkUp { link: id, config: lc });
            }
            IoEvent::CloseLink { id, reason } => {
                if self.lines.close(LineId::Link(id), reason) {
                    self.handle(t, Input::LinkDown { link: id });
                }
            }
            IoEvent::Scrape(reply) => {
                let _ = reply.send(self.snapshot());
            }
        }
        true
    }

    /// A metrics scrape's or status page's view of the router task.
    fn snapshot(&self) -> Snapshot {
        let config = &self.config;
        let state = RouterState {
            router: &self.router,
            configured: config
                .links
                .iter()
                .map(|l| (l.name.as_str(), l.kind, self.tasks.listeners.contains_key(&l.name))),
            name_of: |id| self.links.live.get(&id).map(|l| l.name.as_str()),
            departed: &self.links.departed,
            uptime_ms: self.now(Instant::now()),
        };
        let mut s = Snapshot::take(state, config.gcu.group.get(), config.gcu.name.get());
        s.connections = self.tasks.connections.stats();
        s.started_unix_ms = self.started_unix_ms;
        s.shutting_down = self.stopping.is_some();
        s.capture = self.tasks.capture.current().map(|c| c.stats());
        s.configured = config.configured_devices();
        s
    }

    /// What a line read or that it closed, at `t`.
    fn line_event(&mut self, t: u64, event: LineEvent) {
        let input = match event {
            LineEvent::Read(line, n) => Input::Bytes {
                line,
                bytes: self.lines.read(n),
            },
            LineEvent::Closed(LineId::Port(port)) => Input::PortLost { port },
            LineEvent::Closed(LineId::Link(link)) => Input::LinkDown { link },
        };
        self.router.handle(t, input, &mut self.actions);
    }

    /// SIGTERM or SIGINT: no new work, running motions stopped.
    fn shut_down(&mut self, signal: &str) {
        self.stopping = Some(begin_shutdown(&self.config, signal));
        self.handle(self.now(Instant::now()), Input::Shutdown);
    }

    /// SIGHUP (module `reload`, [`Reload`]).
    async fn reload(&mut self) {
        let t = self.now(Instant::now());
        let reloaded = Reload {
            config: &mut self.config,
            router: &mut self.router,
            tasks: &mut self.tasks,
            lines: &mut self.lines,
            links: &mut self.links,
            closing: &mut self.closing,
        };
        reloaded.run(t, &mut self.actions).await;
    }

    /// The next time the loop must look again though nothing happened: the
    /// shutdown's grace, a closing port's, the throttle's next summary (at
    /// most 50 ms ahead, at least 1 ms).
    fn next_wake(&self) -> Option<Instant> {
        [
            self.stopping,
            self.closing.values().min().copied(),
            self.throttle.next_deadline(),
        ]
        .into_iter()
        .flatten()
        .min()
        .map(|s| {
            s.min(Instant::now() + Duration::from_millis(50))
                .max(Instant::now() + Duration::from_millis(1))
        })
    }

    /// Ports closing after a reload: closed once idle (their stops done) or
    /// when their grace ran out.
    fn close_reloaded_ports(&mut self) {
        // At every turn: nothing to look at unless a reload closes ports
        // (the router core's `closed_ports` walks every port).
        if self.closing.is_empty() {
            return;
        }
        let t = self.now(Instant::now());
        let overdue: Vec<u8> = self
            .closing
            .iter()
            .filter(|(_, until)| Instant::now() >= **until)
            .map(|(&p, _)| p)
            .collect();
        for port in self.router.closed_ports().into_iter().chain(overdue) {
            if self.closing.remove(&port).is_none() {
                continue;
            }
            self.tasks.stop_port(port);
            self.lines.close(LineId::Port(port), "configuration reloaded");
            self.router.port_closed(t, port, &mut self.actions);
            info!(port, "port closed (configuration reloaded)");
            if let Some(new) = self.config.ports.iter().find(|p| p.id == port) {
                self.tasks.start_port(new);
            }
        }
    }

    /// Carries out the router's actions; the writes go out now, straight
    /// from this task, and what a line cannot take yet is written when it
    /// can (`Lines::poll_next`).
    async fn carry_out(&mut self) {
        let group = self.router.group();
        execute(
            &mut self.actions,
            &mut self.lines,
            &mut self.links,
            &mut self.throttle,
            group,
        );
        std::future::poll_fn(|cx| {
            self.lines.flush(cx);
            std::task::Poll::Ready(())
        })
        .await;
        for summary in self.throttle.summaries(Instant::now()) {
            warn!("{summary}");
        }
    }

    /// Lets go of every port and link (their writers and the event
    /// channel), so that their tasks end as a shutdown, logged at info, not
    /// as a loss; waits briefly for the ports' last lines.
    async fn release(mut self, events: mpsc::Receiver<IoEvent>, capture: CaptureControl) {
        let _ = tokio::time::timeout(
            Duration::from_millis(500),
            std::future::poll_fn(|cx| self.lines.poll_drained(cx)),
        )
        .await;
        self.lines.release();
        drop((self.links, events));
        let ending = self.tasks.ports.drain().map(|(_, task)| task).collect::<Vec<_>>();
        let _ = tokio::time::timeout(Duration::from_millis(500), async {
            for task in ending {
                let _ = task.await;
            }
        })
        .await;
        self.tasks.shards.stop();
        capture.stop("gcud stopping").await;
    }
}

/// The metrics endpoint, bound now (a bad address is a start failure): its
/// scrapes reach the router task as [`IoEvent::Scrape`].
async fn serve_metrics(
    metrics: &crate::config::Metrics,
    http_limits: crate::http::Limits,
    events_tx: mpsc::Sender<IoEvent>,
) -> Result<(), StartError> {
    let addr = metrics.listen;
    let listener = TcpListener::bind(addr)
        .await
        .map_err(|error| StartError::Metrics { addr, error })?;
    info!(addr = %listener.local_addr().unwrap_or(addr), "metrics at /metrics");
    let (scrape_tx, mut scrape_rx) = mpsc::channel(16);
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
    Ok(())
}

/// One SIGHUP (module `reload`): the file is read and checked as at start;
/// a broken or unreadable one, or one that changes what needs a restart,
/// is refused and logged, and the running configuration stays. Otherwise
/// the difference is applied.
struct Reload<'a> {
    config: &'a mut Config,
    router: &'a mut Router,
    tasks: &'a mut Tasks,
    lines: &'a mut Lines,
    links: &'a mut LinkBook,
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
        if let Err(e) =
            self.router
                .reconfigure(now, new.router_config(|name| self.links.ids.of(name)), &reopen, actions)
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
                .live
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
            self.tasks.start_link(link, self.links.ids.of(&link.name), listener);
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
