//! The router core's statistics ([`sagebrush_gcu::Stats`]) as metric
//! families: per port, link and device, and router-wide outcomes.

use std::collections::BTreeMap;

use sagebrush_gcu::{DropCounts, LineStats, LinkKind, LinkStats, Stats};

use crate::metrics::{Family, Kind, render as encode};

/// Counters of one configured link: its connections gone and live (a
/// listener's accepted connections fold into it, so that metrics never
/// grow with connections).
#[derive(Debug, Clone)]
pub struct LinkTotals {
    pub stats: LinkStats,
    /// Connections up now.
    pub connections: u64,
}

/// What a scrape renders: copied on the router task (counters only, their
/// number bounded by the configuration), rendered off it.
#[derive(Debug)]
pub struct Snapshot {
    pub stats: Stats,
    /// Per configured link name.
    pub links: BTreeMap<String, LinkTotals>,
    /// Accepted connections over all listeners.
    pub connections: crate::admission::AdmissionStats,
    pub uptime_ms: u64,
    /// Wall-clock time of tick 0 (gcud's start), ms since the Unix epoch:
    /// the router core counts ticks, people and dashboards read dates.
    pub started_unix_ms: u64,
    /// This GCU's group and name (`[gcu]`).
    pub group: u8,
    pub name: String,
    /// SIGTERM/SIGINT received: new commands are refused.
    pub shutting_down: bool,
    pub heap: Heap,
    /// The running capture's counters (SIGUSR1 or `[capture] enabled`), if any.
    pub capture: Option<sagebrush_host::capture::CaptureStats>,
    /// The HTTP endpoint's connections (filled in by the endpoint itself).
    pub http: crate::http::HttpStats,
}

/// The process's heap, as the global allocator counts it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Heap {
    pub allocations: u64,
    pub bytes_in_use: u64,
}

impl Heap {
    /// Now, from the counting allocator gcud runs on (`main.rs`).
    pub fn now() -> Self {
        let s = stats_alloc::INSTRUMENTED_SYSTEM.stats();
        // A reallocation's growth is in `bytes_allocated`, its shrinking in
        // `bytes_deallocated` (`bytes_reallocated` is the two again, netted).
        Self {
            allocations: (s.allocations + s.reallocations) as u64,
            bytes_in_use: s.bytes_allocated.saturating_sub(s.bytes_deallocated) as u64,
        }
    }
}

impl Snapshot {
    /// Seconds since the Unix epoch of a router tick.
    pub fn unix_seconds(&self, tick: u64) -> f64 {
        self.started_unix_ms.saturating_add(tick) as f64 / 1000.0
    }
}

/// gcud's version, as `gcud --version` prints it.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// A link's role as the configuration spells it.
pub fn role_name(kind: LinkKind) -> &'static str {
    match kind {
        LinkKind::Upstream => "upstream",
        LinkKind::Downstream => "downstream",
        LinkKind::Client => "client",
    }
}

/// Reads one counter of a [`LineStats`].
type Field = fn(&LineStats) -> u64;

/// One family per counter of [`LineStats`], shared by ports and links.
struct LineFamilies {
    fields: Vec<(Family, Field)>,
    drops: Family,
    last_seen: Family,
}

impl LineFamilies {
    fn new(prefix: &'static str) -> Self {
        macro_rules! f {
            ($($field:ident: $help:literal),* $(,)?) => {
                vec![$((
                    Family::new(format!("{prefix}_{}", stringify!($field)), $help, Kind::Counter),
                    (|s: &LineStats| s.$field) as Field,
                )),*]
            };
        }
        Self {
            fields: f![
                frames_in: "Good frames received.",
                frames_out: "Frames written, retransmissions included.",
                bytes_in: "Bytes received.",
                bytes_out: "Bytes written.",
                bad_checksums: "Frames received with a bad checksum (each NAKed).",
                naks_sent: "NAKs written.",
                naks_received: "NAKs received.",
                stray_bytes: "ACK/NAK/NIC bytes nobody was waiting for.",
                retransmits: "Frames written again after a NAK or ACK time-out.",
                timeouts: "ACK or result time-outs.",
                nics_in: "NIC (?) received.",
                nics_out: "NIC (?) written.",
                noise_bytes: "Noise bytes skipped by the framer.",
            ],
            drops: Family::new(
                format!("{prefix}_drops"),
                "Frames or jobs dropped, by reason.",
                Kind::Counter,
            ),
            last_seen: Family::new(
                format!("{prefix}_last_seen_timestamp_seconds"),
                "When the last byte was received, seconds since the Unix epoch.",
                Kind::Gauge,
            ),
        }
    }

    fn push(&mut self, labels: &[(&'static str, String)], line: &LineStats, snapshot: &Snapshot) {
        for (family, get) in &mut self.fields {
            family.push(labels.to_vec(), get(line));
        }
        push_drops(&mut self.drops, labels, &line.drops);
        if let Some(t) = line.last_seen {
            self.last_seen.push_real(labels.to_vec(), snapshot.unix_seconds(t));
        }
    }

    fn into_families(self, out: &mut Vec<Family>) {
        out.extend(self.fields.into_iter().map(|(f, _)| f));
        out.push(self.drops);
        out.push(self.last_seen);
    }
}

fn push_drops(family: &mut Family, labels: &[(&'static str, String)], drops: &DropCounts) {
    for (reason, n) in drops.iter() {
        let mut l = labels.to_vec();
        l.push(("reason", reason.name().to_owned()));
        family.push(l, n);
    }
}

/// Renders everything in the OpenMetrics text format.
pub fn render(snapshot: &Snapshot) -> String {
    let (stats, uptime_ms) = (&snapshot.stats, snapshot.uptime_ms);
    let mut out = Vec::new();

    let mut build = Family::new(
        "build_info",
        "gcud's version and this GCU's group and name; always 1.",
        Kind::Gauge,
    );
    build.push(
        vec![
            ("version", VERSION.to_owned()),
            ("group", snapshot.group.to_string()),
            ("name", snapshot.name.clone()),
        ],
        1,
    );
    out.push(build);
    let mut uptime = Family::new("uptime_ms", "Milliseconds since gcud started.", Kind::Gauge);
    uptime.push(vec![], uptime_ms);
    out.push(uptime);
    let mut started = Family::new(
        "start_time_seconds",
        "When gcud started, seconds since the Unix epoch.",
        Kind::Gauge,
    );
    started.push_real(vec![], snapshot.unix_seconds(0));
    out.push(started);
    let mut stopping = Family::new(
        "shutting_down",
        "1 once SIGTERM/SIGINT was received (new commands are refused).",
        Kind::Gauge,
    );
    stopping.push(vec![], u64::from(snapshot.shutting_down));
    out.push(stopping);
    let mut allocations = Family::new(
        "heap_allocations",
        "Heap allocations and reallocations since start (none per routed frame in steady state).",
        Kind::Counter,
    );
    allocations.push(vec![], snapshot.heap.allocations);
    out.push(allocations);
    let mut heap = Family::new("heap_bytes", "Bytes of heap in use.", Kind::Gauge);
    heap.push(vec![], snapshot.heap.bytes_in_use);
    out.push(heap);

    let r = &stats.router;
    let mut outcomes = Family::new("commands", "Commands accepted from links, by outcome.", Kind::Counter);
    for (outcome, n) in [
        ("result", r.results),
        ("nic", r.nics),
        ("completed", r.completed),
        ("no_result", r.no_result),
        ("unreachable", r.unreachable),
        ("forwarded", r.forwarded),
    ] {
        outcomes.push(vec![("outcome", outcome.to_owned())], n);
    }
    out.push(outcomes);
    let mut accepted = Family::new(
        "commands_accepted",
        "Commands accepted (dead-man stops included).",
        Kind::Counter,
    );
    accepted.push(vec![], r.accepted);
    out.push(accepted);
    let mut delivery = Family::new(
        "commands_delivery",
        "Commands of links by what their origin was told (ARCHITECTURE \"Delivery contract\"): delivered, or why not.",
        Kind::Counter,
    );
    delivery.push(vec![("delivery", "delivered".to_owned())], r.delivered);
    for (kind, n) in r.undelivered.iter() {
        delivery.push(vec![("delivery", kind.name().to_owned())], n);
    }
    out.push(delivery);
    let mut dropped = Family::new("commands_dropped", "Commands not executed, by reason.", Kind::Counter);
    push_drops(&mut dropped, &[], &r.dropped);
    out.push(dropped);
    let mut frame_drops = Family::new(
        "router_frame_drops",
        "Frames dropped by the router, by reason.",
        Kind::Counter,
    );
    push_drops(&mut frame_drops, &[], &r.frame_drops);
    out.push(frame_drops);
    for (name, help, value) in [
        (
            "results_relayed",
            "Result frames relayed back to their origin.",
            r.results_relayed,
        ),
        (
            "broadcasts_flooded",
            "Group-255 copies flooded to downstream links.",
            r.flooded,
        ),
        (
            "dead_man_stops",
            "Stops issued for motions of links that went down.",
            r.dead_man_stops,
        ),
        (
            "lease_stops",
            "Stops issued for motions whose link's motion lease ran out.",
            r.lease_stops,
        ),
        (
            "shutdown_stops",
            "Stops issued at shutdown for motions still running.",
            r.shutdown_stops,
        ),
    ] {
        let mut f = Family::new(name, help, Kind::Counter);
        f.push(vec![], value);
        out.push(f);
    }
    let c = &snapshot.connections;
    let mut open = Family::new("connections_open", "Accepted connections open now.", Kind::Gauge);
    open.push(vec![], c.open);
    out.push(open);
    let mut accepted_conns = Family::new("connections_accepted", "Connections accepted.", Kind::Counter);
    accepted_conns.push(vec![], c.accepted);
    out.push(accepted_conns);
    let mut refused = Family::new("connections_refused", "Connections refused, by why.", Kind::Counter);
    for (why, n) in [
        ("max_connections", c.refused_total_cap),
        ("max_connections_per_peer", c.refused_peer_cap),
        ("allow_peers", c.refused_not_allowed),
    ] {
        refused.push(vec![("why", why.to_owned())], n);
    }
    out.push(refused);
    let mut closed = Family::new("connections_closed", "Connections gcud closed, by why.", Kind::Counter);
    closed.push(vec![("why", "evicted".to_owned())], c.evicted);
    closed.push(vec![("why", "idle".to_owned())], c.idle_closed);
    out.push(closed);
    let h = &snapshot.http;
    let mut http_open = Family::new(
        "http_connections_open",
        "HTTP endpoint connections open now.",
        Kind::Gauge,
    );
    http_open.push(vec![], h.open);
    out.push(http_open);
    let mut http_refused = Family::new(
        "http_connections_refused",
        "HTTP endpoint connections closed at accept, by why.",
        Kind::Counter,
    );
    http_refused.push(vec![("why", "allow_peers".to_owned())], h.refused_not_allowed);
    http_refused.push(vec![("why", "max_connections".to_owned())], h.refused_cap);
    out.push(http_refused);
    let capture = snapshot.capture.clone().unwrap_or_default();
    let mut capture_on = Family::new("capture_running", "Whether a capture is running.", Kind::Gauge);
    capture_on.push(vec![], u64::from(snapshot.capture.is_some()));
    out.push(capture_on);
    for (name, help, value) in [
        (
            "capture_records",
            "Records written by the running capture.",
            capture.records,
        ),
        (
            "capture_dropped",
            "Chunks the running capture dropped: its queue was full (a slow disk, a FIFO without a reader or a stalled one).",
            capture.dropped,
        ),
    ] {
        let mut f = Family::new(name, help, Kind::Counter);
        f.push(vec![], value);
        out.push(f);
    }
    let mut in_progress = Family::new("commands_in_progress", "Commands in progress now.", Kind::Gauge);
    in_progress.push(vec![], r.in_progress);
    out.push(in_progress);

    let mut port_lines = LineFamilies::new("port");
    let mut port_open = Family::new("port_open", "Whether the port is open.", Kind::Gauge);
    let mut port_bps = Family::new("port_bps", "Current line rate.", Kind::Gauge);
    let mut port_queue = Family::new(
        "port_queue_length",
        "Jobs waiting behind the one in flight.",
        Kind::Gauge,
    );
    let mut port_tx = Family::new("port_transactions", "Transactions started.", Kind::Counter);
    let mut port_switches = Family::new("port_rate_switches", "Line rate switches.", Kind::Counter);
    for (id, p) in &stats.ports {
        let labels = vec![("port", id.to_string())];
        port_lines.push(&labels, &p.line, snapshot);
        port_open.push(labels.clone(), u64::from(p.open));
        port_bps.push(labels.clone(), u64::from(p.bps));
        port_queue.push(labels.clone(), p.queue_len as u64);
        port_tx.push(labels.clone(), p.transactions);
        port_switches.push(labels, p.rate_switches);
    }
    port_lines.into_families(&mut out);
    out.extend([port_open, port_bps, port_queue, port_tx, port_switches]);

    let mut link_lines = LineFamilies::new("link");
    let mut link_up = Family::new("link_up", "Whether the link has a connection up.", Kind::Gauge);
    let mut link_connections = Family::new("link_connections", "Connections up now.", Kind::Gauge);
    let mut link_repeats = Family::new(
        "link_command_repeats",
        "Retransmissions of a client's command awaiting delivery (not executed again).",
        Kind::Counter,
    );
    let mut link_delivered = Family::new("link_frames_delivered", "Frames the peer acknowledged.", Kind::Counter);
    let mut link_failed = Family::new(
        "link_frames_failed",
        "Frames given up or dropped with the link.",
        Kind::Counter,
    );
    for (name, t) in &snapshot.links {
        let l = &t.stats;
        let labels = vec![("link", name.clone()), ("role", role_name(l.kind).to_owned())];
        link_lines.push(&labels, &l.line, snapshot);
        link_up.push(labels.clone(), u64::from(t.connections > 0));
        link_connections.push(labels.clone(), t.connections);
        link_repeats.push(labels.clone(), l.repeats);
        link_delivered.push(labels.clone(), l.delivered);
        link_failed.push(labels, l.failed);
    }
    link_lines.into_families(&mut out);
    out.extend([link_up, link_connections, link_repeats, link_delivered, link_failed]);

    let mut device_families = [
        Family::new(
            "device_commands",
            "Transactions addressed to the device.",
            Kind::Counter,
        ),
        Family::new(
            "device_frames_out",
            "Command frames written to the device.",
            Kind::Counter,
        ),
        Family::new("device_frames_in", "Result frames from the device.", Kind::Counter),
        Family::new("device_retransmits", "Retransmissions to the device.", Kind::Counter),
        Family::new(
            "device_unreachable",
            "Commands never acknowledged after all retries.",
            Kind::Counter,
        ),
        Family::new(
            "device_no_result",
            "Acknowledged commands whose result never came.",
            Kind::Counter,
        ),
        Family::new("device_nics", "NIC answers from the device.", Kind::Counter),
    ];
    let mut device_seen = Family::new(
        "device_last_seen_timestamp_seconds",
        "When the device last answered (ACK, NAK, result or NIC), seconds since the Unix epoch.",
        Kind::Gauge,
    );
    let mut device_online = Family::new(
        "device_online",
        "1 if the device answered the last exchange addressed to it, 0 if it was silent.",
        Kind::Gauge,
    );
    let mut device_gauges = [
        Family::new(
            "device_position_pan_degrees",
            "Pan the device last answered to P? (Table 15), degrees.",
            Kind::Gauge,
        ),
        Family::new(
            "device_position_tilt_degrees",
            "Tilt the device last answered to P? (Table 15), degrees.",
            Kind::Gauge,
        ),
        Family::new(
            "device_position_timestamp_seconds",
            "When the device last answered P?, seconds since the Unix epoch.",
            Kind::Gauge,
        ),
        Family::new(
            "device_lens_zoom",
            "Zoom position the device last answered to V? (Table 17), 0..4095.",
            Kind::Gauge,
        ),
        Family::new(
            "device_lens_focus",
            "Focus position the device last answered to V? (Table 17), 0..4095.",
            Kind::Gauge,
        ),
    ];
    let mut device_errors = Family::new(
        "device_last_error_timestamp_seconds",
        "When the device's last exchange that did not end as asked ended, by what went wrong, seconds since the Unix epoch.",
        Kind::Gauge,
    );
    for ((port, device), d) in &stats.devices {
        let labels = vec![("port", port.to_string()), ("device", device.to_string())];
        for (family, value) in device_families.iter_mut().zip([
            d.commands,
            d.frames_out,
            d.frames_in,
            d.retransmits,
            d.unreachable,
            d.no_result,
            d.nics,
        ]) {
            family.push(labels.clone(), value);
        }
        device_online.push(labels.clone(), u64::from(d.online));
        if let Some(t) = d.last_seen {
            device_seen.push_real(labels.clone(), snapshot.unix_seconds(t));
        }
        let [pan, tilt, position_at, zoom, focus] = &mut device_gauges;
        if let Some((t, p)) = d.position {
            pan.push_real(labels.clone(), f64::from(p.pan.0) / 100.0);
            tilt.push_real(labels.clone(), f64::from(p.tilt.0) / 100.0);
            position_at.push_real(labels.clone(), snapshot.unix_seconds(t));
        }
        if let Some((_, l)) = d.lens {
            zoom.push(labels.clone(), u64::from(l.zoom.get()));
            focus.push(labels.clone(), u64::from(l.focus.get()));
        }
        if let Some((t, error)) = d.last_error {
            let mut l = labels;
            l.push(("error", error.name().to_owned()));
            device_errors.push_real(l, snapshot.unix_seconds(t));
        }
    }
    out.extend(device_families);
    out.extend([device_online, device_seen]);
    out.extend(device_gauges);
    out.push(device_errors);

    encode(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_a_router_snapshot() {
        let mut config = sagebrush_gcu::RouterConfig::new(5);
        config.ports.push(sagebrush_gcu::PortConfig::new(1));
        let mut router = sagebrush_gcu::Router::new(config).unwrap();
        let mut actions = sagebrush_gcu::Outbox::new();
        router.handle(0, sagebrush_gcu::Input::PortOpened { port: 1 }, &mut actions);
        // A P? answered by device 3 at tick 1500: position and Unix times.
        let client = sagebrush_gcu::LinkId(1);
        let link = sagebrush_gcu::LinkConfig::new(LinkKind::Client, sagebrush_gcu::SourceFilter::Any);
        router.handle(
            0,
            sagebrush_gcu::Input::LinkUp {
                link: client,
                config: link,
            },
            &mut actions,
        );
        let frame = |dest: (u8, u8, u8), source: u8, payload: &[u8]| {
            let address = sagebrush_protocol::Address::new(dest.0, dest.1, dest.2);
            sagebrush_protocol::FrameBuf::new(address, source, payload)
                .unwrap()
                .as_bytes()
                .to_vec()
        };
        let command = frame((5, 1, 3), 0, b"P?");
        router.handle(
            0,
            sagebrush_gcu::Input::Bytes {
                line: sagebrush_gcu::LineId::Link(client),
                bytes: &command,
            },
            &mut actions,
        );
        router.handle(
            0,
            sagebrush_gcu::Input::Bytes {
                line: sagebrush_gcu::LineId::Port(1),
                bytes: &[sagebrush_protocol::ACK],
            },
            &mut actions,
        );
        let result = frame((0, 1, 3), 5, b"EECF03E8");
        router.handle(
            1500,
            sagebrush_gcu::Input::Bytes {
                line: sagebrush_gcu::LineId::Port(1),
                bytes: &result,
            },
            &mut actions,
        );
        let mut gone = LinkStats::new(LinkKind::Client);
        gone.line.frames_in = 3;
        let mut live = LinkStats::new(LinkKind::Client);
        live.line.frames_in = 4;
        let mut clients = LinkTotals {
            stats: gone,
            connections: 1,
        };
        clients.stats.absorb(&live);
        let snapshot = Snapshot {
            stats: router.stats(),
            links: BTreeMap::from([("clients".to_owned(), clients)]),
            connections: Default::default(),
            uptime_ms: 42,
            started_unix_ms: 1_700_000_000_000,
            group: 5,
            name: "test gcu".to_owned(),
            shutting_down: false,
            heap: Heap {
                allocations: 7,
                bytes_in_use: 4096,
            },
            capture: None,
            http: Default::default(),
        };
        let text = render(&snapshot);
        assert!(text.contains("gcud_uptime_ms 42"), "{text}");
        assert!(
            text.contains(&format!(
                "gcud_build_info{{version=\"{VERSION}\",group=\"5\",name=\"test gcu\"}} 1"
            )),
            "{text}"
        );
        assert!(text.contains("gcud_start_time_seconds 1700000000.0"), "{text}");
        assert!(text.contains("gcud_heap_allocations_total 7"), "{text}");
        assert!(text.contains("gcud_heap_bytes 4096"), "{text}");
        let device = "{port=\"1\",device=\"3\"}";
        for line in [
            format!("gcud_device_online{device} 1"),
            format!("gcud_device_position_pan_degrees{device} -44.01"),
            format!("gcud_device_position_tilt_degrees{device} 10.0"),
            format!("gcud_device_position_timestamp_seconds{device} 1700000001.5"),
            format!("gcud_device_last_seen_timestamp_seconds{device} 1700000001.5"),
            "gcud_port_last_seen_timestamp_seconds{port=\"1\"} 1700000001.5".to_owned(),
        ] {
            assert!(text.lines().any(|l| l == line), "{line} missing: {text}");
        }
        assert!(!text.contains("last_seen_ms"), "uptime-based times are gone: {text}");
        assert!(
            text.contains("gcud_link_frames_in_total{link=\"clients\",role=\"client\"} 7"),
            "connections fold into their configured link: {text}"
        );
        assert!(text.contains("gcud_port_open{port=\"1\"} 1"), "{text}");
        assert!(text.contains("gcud_port_retransmits_total{port=\"1\"} 0"), "{text}");
        assert!(
            text.contains("gcud_commands_dropped_total{reason=\"no_route\"} 0"),
            "{text}"
        );
    }
}
