//! gcud's metric families, as one table: each family's name, type, unit
//! and help are declared once below, beside how its samples are read from
//! a [`Snapshot`] (per gcud, per port, per link, per device). Module
//! `openmetrics` writes them out. The names are an interface: the tests
//! under `tests/` and `config/grafana-dashboard.json` use them.

use sagebrush_gcu::{DeviceStats, DropCounts, GimbalControl, Holder, LineStats, PortStats, TourState, TourStatus};

use crate::openmetrics::{Descriptor, Family, Labels, Unit, Value, encode};
use crate::snapshot::{LinkTotals, Snapshot, VERSION, degrees};

/// Every family's name starts `gcud_`.
const PREFIX: &str = "gcud";

/// One family of a table whose rows are `T`s (a port, a link, a device,
/// or gcud itself): its declaration and how a row's samples are read.
struct Column<T> {
    family: Descriptor,
    read: Read<T>,
}

enum Read<T> {
    /// One sample per row, none where the row has no value.
    One(fn(&T, &Snapshot) -> Option<Value>),
    /// Samples split by one more label (its name, then each value with the
    /// sample's).
    By(&'static str, fn(&T, &Snapshot) -> Vec<(&'static str, Value)>),
}

const fn one<T>(family: Descriptor, read: fn(&T, &Snapshot) -> Option<Value>) -> Column<T> {
    Column {
        family,
        read: Read::One(read),
    }
}

const fn by<T>(
    family: Descriptor,
    label: &'static str,
    read: fn(&T, &Snapshot) -> Vec<(&'static str, Value)>,
) -> Column<T> {
    Column {
        family,
        read: Read::By(label, read),
    }
}

fn count(n: impl Into<u64>) -> Option<Value> {
    Some(Value::Count(n.into()))
}

/// A family whose one sample is the row's field of the same name (after
/// the table's prefix, if any): `field!(counter "device_" nics, "help")` is
/// `gcud_device_nics`, read from `row.nics`.
macro_rules! field {
    ($kind:ident $($prefix:literal)? $field:ident, $help:literal) => {
        one(
            Descriptor::$kind(concat!($($prefix,)? stringify!($field)), $help),
            |row, _| count(row.$field),
        )
    };
}

fn drops(d: &DropCounts) -> Vec<(&'static str, Value)> {
    d.iter().map(|(reason, n)| (reason.name(), Value::Count(n))).collect()
}

/// gcud's identity: one sample, its labels the version, group and name.
const BUILD_INFO: Descriptor =
    Descriptor::gauge("build_info", "gcud's version and this GCU's group and name; always 1.");

/// gcud as a whole: one row, no labels.
const GCUD: &[Column<Snapshot>] = &[
    one(
        Descriptor::gauge("uptime", "Milliseconds since gcud started.").in_unit(Unit::Milliseconds),
        |s, _| count(s.uptime_ms),
    ),
    one(
        Descriptor::gauge("start_time", "When gcud started, seconds since the Unix epoch.").in_unit(Unit::Seconds),
        |s, _| Some(Value::Real(s.unix_seconds(0))),
    ),
    field!(gauge shutting_down, "1 once SIGTERM/SIGINT was received (new commands are refused)."),
    one(
        Descriptor::counter(
            "heap_allocations",
            "Heap allocations and reallocations since start (none per routed frame in steady state).",
        ),
        |s, _| count(s.heap.allocations),
    ),
    one(
        Descriptor::gauge("heap", "Bytes of heap in use.").in_unit(Unit::Bytes),
        |s, _| count(s.heap.bytes_in_use),
    ),
    by(
        Descriptor::counter("commands", "Commands accepted from links, by outcome."),
        "outcome",
        |s, _| {
            let r = &s.stats.router;
            [
                ("result", r.results),
                ("nic", r.nics),
                ("completed", r.completed),
                ("no_result", r.no_result),
                ("unreachable", r.unreachable),
                ("forwarded", r.forwarded),
            ]
            .map(|(outcome, n)| (outcome, Value::Count(n)))
            .to_vec()
        },
    ),
    one(
        Descriptor::counter("commands_accepted", "Commands accepted (dead-man stops included)."),
        |s, _| count(s.stats.router.accepted),
    ),
    by(
        Descriptor::counter(
            "commands_delivery",
            "Commands of links by what their origin was told (ARCHITECTURE \"Delivery contract\"): delivered, or why not.",
        ),
        "delivery",
        |s, _| {
            let r = &s.stats.router;
            let undelivered = r.undelivered.iter().map(|(kind, n)| (kind.name(), Value::Count(n)));
            std::iter::once(("delivered", Value::Count(r.delivered)))
                .chain(undelivered)
                .collect()
        },
    ),
    by(
        Descriptor::counter("commands_dropped", "Commands not executed, by reason."),
        "reason",
        |s, _| drops(&s.stats.router.dropped),
    ),
    by(
        Descriptor::counter("router_frame_drops", "Frames dropped by the router, by reason."),
        "reason",
        |s, _| drops(&s.stats.router.frame_drops),
    ),
    one(
        Descriptor::counter("results_relayed", "Result frames relayed back to their origin."),
        |s, _| count(s.stats.router.results_relayed),
    ),
    one(
        Descriptor::counter("broadcasts_flooded", "Group-255 copies flooded to downstream links."),
        |s, _| count(s.stats.router.flooded),
    ),
    one(
        Descriptor::counter("dead_man_stops", "Stops issued for motions of links that went down."),
        |s, _| count(s.stats.router.dead_man_stops),
    ),
    one(
        Descriptor::counter(
            "lease_stops",
            "Stops issued for motions whose link's motion lease ran out.",
        ),
        |s, _| count(s.stats.router.lease_stops),
    ),
    one(
        Descriptor::counter("shutdown_stops", "Stops issued at shutdown for motions still running."),
        |s, _| count(s.stats.router.shutdown_stops),
    ),
    one(
        Descriptor::counter(
            "governance_stops",
            "Stops the governance issued: take-overs, slews near a travel limit or keep-out zone, tours stopped, gimbals found moving.",
        ),
        |s, _| count(s.stats.router.governance_stops),
    ),
    one(
        Descriptor::counter(
            "governance_takeovers",
            "Control of a gimbal taken from its holder by a link of higher priority.",
        ),
        |s, _| count(s.governance.takeovers),
    ),
    one(
        Descriptor::counter(
            "governance_boundary_stops",
            "Slews stopped short of a travel limit or keep-out zone.",
        ),
        |s, _| count(s.governance.boundary_stops),
    ),
    one(
        Descriptor::counter(
            "governance_follow_polls",
            "Position polls of governed gimbals in motion (the bus time following them costs).",
        ),
        |s, _| count(s.governance.follow_polls),
    ),
    one(
        Descriptor::counter("governance_parks", "Park recalls of a preset."),
        |s, _| count(s.governance.parks),
    ),
    one(
        Descriptor::counter(
            "governance_found_moving",
            "Governed gimbals found moving after a start or a port's reopening, and stopped.",
        ),
        |s, _| count(s.governance.found_moving),
    ),
    one(
        Descriptor::gauge("connections_open", "Accepted connections open now."),
        |s, _| count(s.connections.open),
    ),
    one(
        Descriptor::counter("connections_accepted", "Connections accepted."),
        |s, _| count(s.connections.accepted),
    ),
    by(
        Descriptor::counter("connections_refused", "Connections refused, by why."),
        "why",
        |s, _| {
            let c = &s.connections;
            vec![
                ("max_connections", Value::Count(c.refused_total_cap)),
                ("max_connections_per_peer", Value::Count(c.refused_peer_cap)),
                ("allow_peers", Value::Count(c.refused_not_allowed)),
            ]
        },
    ),
    by(
        Descriptor::counter("connections_closed", "Connections gcud closed, by why."),
        "why",
        |s, _| {
            let c = &s.connections;
            vec![
                ("evicted", Value::Count(c.evicted)),
                ("idle", Value::Count(c.idle_closed)),
            ]
        },
    ),
    one(
        Descriptor::gauge("http_connections_open", "HTTP endpoint connections open now."),
        |s, _| count(s.http.open),
    ),
    by(
        Descriptor::counter(
            "http_connections_refused",
            "HTTP endpoint connections closed at accept, by why.",
        ),
        "why",
        |s, _| {
            let h = &s.http;
            vec![
                ("allow_peers", Value::Count(h.refused_not_allowed)),
                ("max_connections", Value::Count(h.refused_cap)),
            ]
        },
    ),
    one(
        Descriptor::gauge("capture_running", "Whether a capture is running."),
        |s, _| count(s.capture.is_some()),
    ),
    one(
        Descriptor::counter("capture_records", "Records written by the running capture."),
        |s, _| count(s.capture.as_ref().map_or(0, |c| c.records)),
    ),
    one(
        Descriptor::counter(
            "capture_dropped",
            "Chunks the running capture dropped: its queue was full (a slow disk, a FIFO without a reader or a stalled one).",
        ),
        |s, _| count(s.capture.as_ref().map_or(0, |c| c.dropped)),
    ),
    one(
        Descriptor::gauge("commands_in_progress", "Commands in progress now."),
        |s, _| count(s.stats.router.in_progress),
    ),
];

/// A line's counters (ports and links alike), as families `port_...` and
/// `link_...`.
const LINE: &[Column<LineStats>] = &[
    field!(counter frames_in, "Good frames received."),
    field!(counter frames_out, "Frames written, retransmissions included."),
    field!(counter bytes_in, "Bytes received."),
    field!(counter bytes_out, "Bytes written."),
    field!(counter bad_checksums, "Frames received with a bad checksum (each NAKed)."),
    field!(counter naks_sent, "NAKs written."),
    field!(counter naks_received, "NAKs received."),
    field!(counter stray_bytes, "ACK/NAK/NIC bytes nobody was waiting for."),
    field!(counter retransmits, "Frames written again after a NAK or ACK time-out."),
    field!(counter timeouts, "ACK or result time-outs."),
    field!(counter nics_in, "NIC (?) received."),
    field!(counter nics_out, "NIC (?) written."),
    field!(counter noise_bytes, "Noise bytes skipped by the framer."),
    by(
        Descriptor::counter("drops", "Frames or jobs dropped, by reason."),
        "reason",
        |l, _| drops(&l.drops),
    ),
    one(
        Descriptor::gauge(
            "last_seen_timestamp",
            "When the last byte was received, seconds since the Unix epoch.",
        )
        .in_unit(Unit::Seconds),
        |l, s| l.last_seen.map(|t| Value::Real(s.unix_seconds(t))),
    ),
];

/// A port, beside its line's counters; labelled `port`.
const PORT: &[Column<PortStats>] = &[
    field!(gauge "port_" open, "Whether the port is open."),
    field!(gauge "port_" bps, "Current line rate."),
    one(
        Descriptor::gauge("port_queue_length", "Jobs waiting behind the one in flight."),
        |p, _| count(p.queue_len as u64),
    ),
    field!(counter "port_" transactions, "Transactions started."),
    field!(
        counter "port_" pipelined,
        "Transactions started in the NIC window of the one before, to the same device (duplex = full)."
    ),
    field!(counter "port_" rate_switches, "Line rate switches."),
];

/// A configured link (its connections folded together), beside its line's
/// counters; labelled `link` and `role`.
const LINK: &[Column<LinkTotals>] = &[
    one(
        Descriptor::gauge("link_up", "Whether the link has a connection up."),
        |t, _| count(t.connections > 0),
    ),
    field!(gauge "link_" connections, "Connections up now."),
    one(
        Descriptor::counter(
            "link_command_repeats",
            "Retransmissions of a client's command awaiting delivery (not executed again).",
        ),
        |t, _| count(t.stats.repeats),
    ),
    one(
        Descriptor::counter("link_frames_delivered", "Frames the peer acknowledged."),
        |t, _| count(t.stats.delivered),
    ),
    one(
        Descriptor::counter("link_frames_failed", "Frames given up or dropped with the link."),
        |t, _| count(t.stats.failed),
    ),
];

/// The position the device last answered, while it is still there: none
/// once a motion went to it (its registry's `moved`, set by a broadcast
/// `HO` as by a goto to it), so that a scrape never shows a place the
/// gimbal has left as where it is.
fn still_there(d: &DeviceStats) -> Option<(u64, sagebrush_protocol::Position)> {
    d.position.filter(|_| d.moved.is_none())
}

/// A device of the router core's registry; labelled `port` and `device`.
const DEVICE: &[Column<DeviceStats>] = &[
    field!(counter "device_" commands, "Transactions addressed to the device."),
    field!(counter "device_" frames_out, "Command frames written to the device."),
    field!(counter "device_" frames_in, "Result frames from the device."),
    field!(counter "device_" retransmits, "Retransmissions to the device."),
    field!(counter "device_" unreachable, "Commands never acknowledged after all retries."),
    field!(counter "device_" no_result, "Acknowledged commands whose result never came."),
    field!(counter "device_" nics, "NIC answers from the device."),
    field!(gauge "device_" online, "1 if the device answered the last exchange addressed to it, 0 if it was silent."),
    one(
        Descriptor::gauge(
            "device_last_seen_timestamp",
            "When the device last answered (ACK, NAK, result or NIC), seconds since the Unix epoch.",
        )
        .in_unit(Unit::Seconds),
        |d, s| d.last_seen.map(|t| Value::Real(s.unix_seconds(t))),
    ),
    one(
        Descriptor::gauge(
            "device_position_pan",
            "Pan the device last answered to P? (Table 15), degrees; absent once a motion went to it (a broadcast HO included) until it answers P? again.",
        )
        .in_unit(Unit::Degrees),
        |d, _| still_there(d).map(|(_, p)| Value::Real(degrees(p.pan))),
    ),
    one(
        Descriptor::gauge(
            "device_position_tilt",
            "Tilt the device last answered to P? (Table 15), degrees; absent once a motion went to it (a broadcast HO included) until it answers P? again.",
        )
        .in_unit(Unit::Degrees),
        |d, _| still_there(d).map(|(_, p)| Value::Real(degrees(p.tilt))),
    ),
    one(
        Descriptor::gauge(
            "device_position_timestamp",
            "When the device last answered P?, seconds since the Unix epoch; absent with the position.",
        )
        .in_unit(Unit::Seconds),
        |d, s| still_there(d).map(|(t, _)| Value::Real(s.unix_seconds(t))),
    ),
    one(
        Descriptor::gauge(
            "device_moved_timestamp",
            "When a motion went to the device after its last P? answer (its position then unknown until the next), seconds since the Unix epoch.",
        )
        .in_unit(Unit::Seconds),
        |d, s| d.moved.map(|t| Value::Real(s.unix_seconds(t))),
    ),
    one(
        Descriptor::gauge(
            "device_lens_zoom",
            "Zoom position the device last answered to V? (Table 17), 0..4095.",
        ),
        |d, _| d.lens.map(|(_, l)| Value::Count(l.zoom.get().into())),
    ),
    one(
        Descriptor::gauge(
            "device_lens_focus",
            "Focus position the device last answered to V? (Table 17), 0..4095.",
        ),
        |d, _| d.lens.map(|(_, l)| Value::Count(l.focus.get().into())),
    ),
    by(
        Descriptor::gauge(
            "device_last_error_timestamp",
            "When the device's last exchange that did not end as asked ended, by what went wrong, seconds since the Unix epoch.",
        )
        .in_unit(Unit::Seconds),
        "error",
        |d, s| match d.last_error {
            Some((t, error)) => vec![(error.name(), Value::Real(s.unix_seconds(t)))],
            None => Vec::new(),
        },
    ),
];

/// A governed or held gimbal; labelled `port` and `device`.
const GIMBAL: &[Column<GimbalControl>] = &[
    by(
        Descriptor::gauge(
            "gimbal_control",
            "Who controls the gimbal, by kind: 1 for the holder's kind (none: nobody), 0 for the others.",
        ),
        "holder_kind",
        |g, _| {
            let kind = match &g.holder {
                None => "none",
                Some(Holder::Link { .. }) => "link",
                Some(Holder::Tour(_)) => "tour",
                Some(Holder::Park) => "park",
            };
            ["none", "link", "tour", "park"]
                .map(|k| (k, Value::Count(u64::from(k == kind))))
                .to_vec()
        },
    ),
    one(
        Descriptor::gauge("gimbal_bounded", "1 if the gimbal has travel limits or keep-out zones."),
        |g, _| count(g.bounded),
    ),
];

/// A held gimbal; labelled `port`, `device` and `holder` (a link's or a
/// tour's name, or `park`).
const HOLDER: &[Column<GimbalControl>] = &[one(
    Descriptor::gauge(
        "gimbal_holder",
        "1 for each gimbal held now, labelled with who holds it (a configured link's name, a tour's, or park).",
    ),
    |_, _| count(1u64),
)];

/// A configured tour; labelled `tour`, `port` and `device`.
const TOUR: &[Column<TourStatus>] = &[by(
    Descriptor::gauge(
        "tour_state",
        "The tour's state: 1 for its state (running, waiting for control to lapse, stopped), 0 for the others.",
    ),
    "state",
    |t, _| {
        [
            ("running", TourState::Running),
            ("waiting", TourState::Waiting),
            ("stopped", TourState::Stopped),
        ]
        .map(|(name, state)| (name, Value::Count(u64::from(t.state == state))))
        .to_vec()
    },
)];

/// The families of `columns` (under `scope`, if any), one sample or more
/// per row.
fn table<T>(
    scope: Option<&str>,
    columns: &[Column<T>],
    rows: &[(Labels, &T)],
    snapshot: &Snapshot,
    out: &mut Vec<Family>,
) {
    for column in columns {
        let mut family = match scope {
            Some(scope) => Family::scoped(scope, column.family),
            None => Family::new(column.family),
        };
        for (labels, row) in rows {
            match &column.read {
                Read::One(read) => {
                    if let Some(value) = read(row, snapshot) {
                        family.push(labels.clone(), value);
                    }
                }
                Read::By(label, read) => {
                    for (split, value) in read(row, snapshot) {
                        let mut labels = labels.clone();
                        labels.push((label, split.to_owned()));
                        family.push(labels, value);
                    }
                }
            }
        }
        out.push(family);
    }
}

/// Everything, in the OpenMetrics text format.
pub fn render(snapshot: &Snapshot) -> String {
    let stats = &snapshot.stats;
    let mut out = Vec::new();
    let identity = vec![
        ("version", VERSION.to_owned()),
        ("group", snapshot.group.to_string()),
        ("name", snapshot.name.clone()),
    ];
    let mut build = Family::new(BUILD_INFO);
    build.push(identity, Value::Count(1));
    out.push(build);
    table(None, GCUD, &[(Vec::new(), snapshot)], snapshot, &mut out);

    let ports: Vec<_> = stats
        .ports
        .iter()
        .map(|(id, p)| (vec![("port", id.to_string())], p))
        .collect();
    let port_lines: Vec<_> = ports.iter().map(|(labels, p)| (labels.clone(), &p.line)).collect();
    table(Some("port"), LINE, &port_lines, snapshot, &mut out);
    table(None, PORT, &ports, snapshot, &mut out);

    let links: Vec<_> = snapshot
        .links
        .iter()
        .map(|(name, t)| {
            let labels = vec![("link", name.clone()), ("role", t.stats.kind.name().to_owned())];
            (labels, t)
        })
        .collect();
    let link_lines: Vec<_> = links
        .iter()
        .map(|(labels, t)| (labels.clone(), &t.stats.line))
        .collect();
    table(Some("link"), LINE, &link_lines, snapshot, &mut out);
    table(None, LINK, &links, snapshot, &mut out);

    let devices: Vec<_> = stats
        .devices
        .iter()
        .map(|((port, device), d)| (vec![("port", port.to_string()), ("device", device.to_string())], d))
        .collect();
    table(None, DEVICE, &devices, snapshot, &mut out);

    let at = |g: &GimbalControl| vec![("port", g.port.to_string()), ("device", g.device.to_string())];
    let gimbals: Vec<_> = snapshot.control.iter().map(|g| (at(g), g)).collect();
    table(None, GIMBAL, &gimbals, snapshot, &mut out);
    let held: Vec<_> = snapshot
        .control
        .iter()
        .filter_map(|g| {
            let holder = match g.holder.as_ref()? {
                Holder::Link {
                    name, via: Some(via), ..
                } => format!("{name} via {via}"),
                Holder::Link { name, .. } | Holder::Tour(name) => name.clone(),
                Holder::Park => "park".to_owned(),
            };
            let mut labels = at(g);
            labels.push(("holder", holder));
            Some((labels, g))
        })
        .collect();
    table(None, HOLDER, &held, snapshot, &mut out);
    let tours: Vec<_> = snapshot
        .tours
        .iter()
        .map(|t| {
            let labels = vec![
                ("tour", t.name.clone()),
                ("port", t.port.to_string()),
                ("device", t.device.to_string()),
            ];
            (labels, t)
        })
        .collect();
    table(None, TOUR, &tours, snapshot, &mut out);

    encode(PREFIX, out)
}

#[cfg(test)]
mod tests;
