//! What a page of the HTTP endpoint shows, read from the router task in
//! one go: the router core's statistics ([`sagebrush_gcu::Stats`]), each
//! configured link's counters (its connections gone and live folded
//! together), the client listeners' admission counters, the capture's and
//! the heap's. Copied on the router task (counters only, their number
//! bounded by the configuration) and rendered off it, by module
//! `metric_families` (`/metrics`) and module `status` (`/status`).

use std::collections::BTreeMap;

use sagebrush_gcu::{GimbalControl, GovernStats, LinkId, LinkKind, LinkStats, Router, Stats, TourStatus};
use sagebrush_protocol::Angle;

use crate::admission::AdmissionStats;

/// gcud's version, as `gcud --version` prints it.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Counters of one configured link: its connections gone and live (a
/// listener's accepted connections fold into it, so that metrics never
/// grow with connections).
#[derive(Debug, Clone)]
pub struct LinkTotals {
    pub stats: LinkStats,
    /// Connections up now.
    pub connections: u64,
    /// A `listen` link whose listener is bound: it serves, connections
    /// or not.
    pub listening: bool,
}

impl LinkTotals {
    /// Whether the link serves: a listener while it is bound, any other
    /// link while it has a connection up.
    pub fn up(&self) -> bool {
        self.listening || self.connections > 0
    }
}

/// The HTTP endpoint's connections (module `http` counts them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HttpStats {
    pub open: u64,
    pub refused_not_allowed: u64,
    pub refused_cap: u64,
}

/// Everything a page shows, at one instant.
#[derive(Debug)]
pub struct Snapshot {
    pub stats: Stats,
    /// Per configured link name.
    pub links: BTreeMap<String, LinkTotals>,
    /// Accepted connections over all listeners.
    pub connections: AdmissionStats,
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
    pub http: HttpStats,
    /// Who controls each governed or held gimbal (ARCHITECTURE "Governance").
    pub control: Vec<GimbalControl>,
    /// Every configured tour.
    pub tours: Vec<TourStatus>,
    pub governance: GovernStats,
    /// The gimbals the configuration names, as (port, device)
    /// ([`crate::config::Config::configured_devices`]): `/status` lists
    /// each, heard from or not.
    pub configured: std::collections::BTreeSet<(u8, u8)>,
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

/// What the router task reads a snapshot from.
pub struct RouterState<'a, C, N> {
    pub router: &'a Router,
    /// Each configured link: its name, kind, and whether it is a listener
    /// bound now.
    pub configured: C,
    /// The configured link name of a live link id.
    pub name_of: N,
    /// Final counters of connections gone, per configured link name.
    pub departed: &'a BTreeMap<String, LinkStats>,
    pub uptime_ms: u64,
}

impl Snapshot {
    /// The router task's counters now: each configured link totals its
    /// connections gone and live. What the router task does not own
    /// (admission, capture, start time, shutting down, the HTTP counters)
    /// starts empty, for the caller to fill in.
    pub fn take<'a, C, N>(state: RouterState<'a, C, N>, group: u8, name: &str) -> Self
    where
        C: IntoIterator<Item = (&'a str, LinkKind, bool)>,
        N: Fn(LinkId) -> Option<&'a str>,
    {
        let stats = state.router.stats();
        let mut links: BTreeMap<String, LinkTotals> = state
            .configured
            .into_iter()
            .map(|(name, kind, listening)| {
                let mut gone = LinkStats::new(kind);
                gone.up = false;
                if let Some(d) = state.departed.get(name) {
                    gone.absorb(d);
                }
                let totals = LinkTotals {
                    stats: gone,
                    connections: 0,
                    listening,
                };
                (name.to_owned(), totals)
            })
            .collect();
        for (id, live) in &stats.links {
            if let Some(t) = (state.name_of)(*id).and_then(|name| links.get_mut(name)) {
                t.stats.absorb(live);
                t.connections += 1;
            }
        }
        Snapshot {
            stats,
            links,
            connections: AdmissionStats::default(),
            uptime_ms: state.uptime_ms,
            started_unix_ms: 0,
            group,
            name: name.to_owned(),
            shutting_down: false,
            heap: Heap::now(),
            capture: None,
            http: HttpStats::default(),
            control: state.router.control(),
            tours: state.router.tours(),
            governance: state.router.governance_stats(),
            configured: Default::default(),
        }
    }

    /// Seconds since the Unix epoch of a router tick.
    pub fn unix_seconds(&self, tick: u64) -> f64 {
        self.started_unix_ms.saturating_add(tick) as f64 / 1000.0
    }
}

/// An angle in degrees (Table 15's centidegrees, exactly as `f64`).
pub fn degrees(angle: Angle) -> f64 {
    f64::from(angle.0) / 100.0
}

/// Snapshots for the tests of the modules that render them.
#[cfg(test)]
pub mod fixture {
    use super::*;

    /// Asserts that `text` is the reviewed `bins/gcud/testdata/{file}`.
    /// After a deliberate change, write the new text with
    /// `GCUD_BLESS=1 cargo test --bin gcud` and review its diff.
    pub fn assert_reviewed(file: &str, text: &str) {
        let path = format!("{}/bins/gcud/testdata/{file}", env!("CARGO_MANIFEST_DIR"));
        if std::env::var_os("GCUD_BLESS").is_some() {
            std::fs::write(&path, text).expect("testdata");
        }
        let reviewed = std::fs::read_to_string(&path).expect("testdata");
        assert!(text == reviewed, "{file} changed; diff it against {path}:\n{text}");
    }

    /// A snapshot with every field set, each counter to a distinct value
    /// (so that a value read from the wrong field shows).
    pub fn every_field_set() -> Snapshot {
        use sagebrush_gcu::{
            DeviceError, DeviceStats, DropCounts, Holder, LineStats, LinkKind, LinkStats, PortStats, RouterStats,
            Stats, TourState, UndeliveredCounts,
        };
        use sagebrush_protocol::{Angle, LensPosition, Position, U12};
        let mut n = 0u64;
        let mut next = || {
            n += 1;
            n
        };
        let line = |next: &mut dyn FnMut() -> u64, last_seen| LineStats {
            frames_in: next(),
            frames_out: next(),
            bytes_in: next(),
            bytes_out: next(),
            bad_checksums: next(),
            naks_sent: next(),
            naks_received: next(),
            stray_bytes: next(),
            retransmits: next(),
            timeouts: next(),
            nics_in: next(),
            nics_out: next(),
            noise_bytes: next(),
            drops: DropCounts::from_fn(|_| next()),
            last_seen,
        };
        let router = RouterStats {
            accepted: next(),
            results: next(),
            nics: next(),
            completed: next(),
            no_result: next(),
            unreachable: next(),
            forwarded: next(),
            results_relayed: next(),
            flooded: next(),
            dead_man_stops: next(),
            lease_stops: next(),
            shutdown_stops: next(),
            governance_stops: next(),
            delivered: next(),
            in_progress: next(),
            dropped: DropCounts::from_fn(|_| next()),
            frame_drops: DropCounts::from_fn(|_| next()),
            undelivered: UndeliveredCounts::from_fn(|_| next()),
        };
        let mut stats = Stats {
            router,
            ..Default::default()
        };
        for (id, open, last_seen) in [(1u8, true, Some(1500)), (2, false, None)] {
            let port = PortStats {
                line: line(&mut next, last_seen),
                open,
                bps: 9600 * u32::from(id),
                queue_len: next() as usize,
                queue_high_water: next() as usize,
                transactions: next(),
                pipelined: next(),
                rate_switches: next(),
            };
            stats.ports.insert(id, port);
        }
        let full = DeviceStats {
            commands: next(),
            frames_out: next(),
            frames_in: next(),
            retransmits: next(),
            unreachable: next(),
            no_result: next(),
            nics: next(),
            last_seen: Some(2250),
            online: true,
            position: Some((
                1500,
                Position {
                    pan: Angle(-4401),
                    tilt: Angle(1000),
                },
            )),
            moved: Some(2000),
            lens: Some((
                1750,
                LensPosition {
                    zoom: U12::new(4095).unwrap(),
                    focus: U12::new(12).unwrap(),
                },
            )),
            last_error: Some((2250, DeviceError::NoResult)),
        };
        stats.devices.insert((1, 3), full);
        stats.devices.insert(
            (1, 7),
            DeviceStats {
                commands: next(),
                last_error: Some((10, DeviceError::Silent)),
                ..Default::default()
            },
        );
        stats.devices.insert(
            (2, 1),
            DeviceStats {
                nics: next(),
                last_seen: Some(5),
                online: true,
                ..Default::default()
            },
        );
        let mut links = BTreeMap::new();
        for (name, kind, connections) in [
            ("clients", LinkKind::Client, 2u64),
            ("north", LinkKind::Upstream, 0),
            ("south", LinkKind::Downstream, 1),
        ] {
            let mut stats = LinkStats::new(kind);
            stats.line = line(&mut next, (connections > 0).then_some(1999));
            stats.repeats = next();
            stats.delivered = next();
            stats.failed = next();
            let listening = kind == LinkKind::Client;
            links.insert(
                name.to_owned(),
                LinkTotals {
                    stats,
                    connections,
                    listening,
                },
            );
        }
        Snapshot {
            stats,
            links,
            connections: AdmissionStats {
                open: next(),
                accepted: next(),
                refused_total_cap: next(),
                refused_peer_cap: next(),
                refused_not_allowed: next(),
                evicted: next(),
                idle_closed: next(),
            },
            uptime_ms: 123_456,
            started_unix_ms: 1_700_000_000_250,
            group: 5,
            name: "field \"north\" gcu".to_owned(),
            shutting_down: true,
            heap: Heap {
                allocations: next(),
                bytes_in_use: next(),
            },
            capture: Some(sagebrush_host::capture::CaptureStats {
                records: next(),
                bytes_written: next(),
                dropped: next(),
                stopped: None,
            }),
            http: HttpStats {
                open: next(),
                refused_not_allowed: next(),
                refused_cap: next(),
            },
            control: vec![
                GimbalControl {
                    port: 1,
                    device: 3,
                    holder: Some(Holder::Link {
                        name: "operators".to_owned(),
                        priority: 80,
                        via: None,
                    }),
                    lapses_at: Some(125_000),
                    position: Some((
                        120_000,
                        Position {
                            pan: Angle(4550),
                            tilt: Angle(-1000),
                        },
                    )),
                    bounded: true,
                },
                GimbalControl {
                    port: 1,
                    device: 7,
                    holder: Some(Holder::Tour("perimeter".to_owned())),
                    lapses_at: None,
                    position: None,
                    bounded: false,
                },
                GimbalControl {
                    port: 2,
                    device: 1,
                    holder: None,
                    lapses_at: None,
                    position: None,
                    bounded: true,
                },
            ],
            tours: vec![
                TourStatus {
                    name: "perimeter".to_owned(),
                    port: 1,
                    device: 7,
                    state: TourState::Running,
                    step: 1,
                    waiting_for: None,
                },
                TourStatus {
                    name: "gate".to_owned(),
                    port: 1,
                    device: 3,
                    state: TourState::Waiting,
                    step: 0,
                    waiting_for: Some(Holder::Link {
                        name: "operators".to_owned(),
                        priority: 80,
                        via: None,
                    }),
                },
            ],
            governance: GovernStats {
                takeovers: next(),
                boundary_stops: next(),
                follow_polls: next(),
                parks: next(),
                found_moving: next(),
            },
            // Configured: one heard from (1.3), one not yet (2.4).
            configured: [(1, 3), (2, 4)].into_iter().collect(),
        }
    }
}
