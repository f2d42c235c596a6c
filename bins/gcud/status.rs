//! `GET /status`: what gcud knows now, as one JSON document for people and
//! scripts (`gimbalctl gcud-status` prints it as a table): the daemon, each
//! port with the devices seen on it (the router core's device registry:
//! online, last position and lens position answered, last error), and each
//! configured link, who controls each governed or held gimbal and each
//! tour (ARCHITECTURE "Governance"). Times are seconds since the Unix
//! epoch. Built from the same [`Snapshot`] as `/metrics`; the README
//! documents the shape.

use sagebrush_gcu::{DeviceStats, Holder, TourState};
use serde::Serialize;

use crate::snapshot::{Snapshot, VERSION, degrees};

#[derive(Debug, Serialize)]
pub struct Status {
    pub gcud: Daemon,
    pub ports: Vec<Port>,
    pub links: Vec<Link>,
    /// Each gimbal with travel rules or a holder now.
    pub control: Vec<Control>,
    pub tours: Vec<Tour>,
}

/// Who controls a gimbal.
#[derive(Debug, Serialize)]
pub struct HolderSeen {
    /// `link`, `tour` or `park`.
    pub kind: &'static str,
    /// The link's or tour's name; null for park.
    pub name: Option<String>,
    /// A link's priority; null for gcud's own tours and park (below every link).
    pub priority: Option<u8>,
    /// The tool or link a principal's commands came through ("alice" via
    /// "gimbal-web"); null for a link without principals.
    pub via: Option<String>,
}

impl HolderSeen {
    fn of(holder: &Holder) -> Self {
        match holder {
            Holder::Link { name, priority, via } => Self {
                kind: "link",
                name: Some(name.clone()),
                priority: Some(*priority),
                via: via.clone(),
            },
            Holder::Tour(name) => Self {
                kind: "tour",
                name: Some(name.clone()),
                priority: None,
                via: None,
            },
            Holder::Park => Self {
                kind: "park",
                name: None,
                priority: None,
                via: None,
            },
        }
    }
}

/// A gimbal's control (`[[gimbal]]` rules, or held by a link now).
#[derive(Debug, Serialize)]
pub struct Control {
    /// `G.P.D`, as `gimbalctl --to` takes it.
    pub address: String,
    /// Null: nobody holds it.
    pub holder: Option<HolderSeen>,
    /// When a link holds it: how long until its control lapses, unless it
    /// commands again (`[control] hold_ms` after its last command).
    pub lapses_in_ms: Option<u64>,
    /// It has travel limits or keep-out zones (its motions are followed).
    pub bounded: bool,
    /// The last position gcud read from it (its own polls included).
    pub position: Option<PositionSeen>,
}

/// A `[[tour]]`.
#[derive(Debug, Serialize)]
pub struct Tour {
    pub name: String,
    /// The gimbal it drives, `G.P.D`.
    pub address: String,
    /// `running`, `waiting` (for control to lapse) or `stopped`.
    pub state: &'static str,
    /// The step it is on, or resumes with, from 1.
    pub step: usize,
    /// Whom it waits for, when waiting.
    pub waiting_for: Option<HolderSeen>,
}

/// A tour's state as `/status` and the metrics name it.
pub fn tour_state(state: TourState) -> &'static str {
    match state {
        TourState::Running => "running",
        TourState::Waiting => "waiting",
        TourState::Stopped => "stopped",
    }
}

#[derive(Debug, Serialize)]
pub struct Daemon {
    pub version: &'static str,
    pub group: u8,
    pub name: String,
    pub started_unix: f64,
    pub uptime_ms: u64,
    pub shutting_down: bool,
    pub commands_in_progress: u64,
    pub connections_open: u64,
}

#[derive(Debug, Serialize)]
pub struct Port {
    pub port: u8,
    pub open: bool,
    pub bps: u32,
    pub queue_length: usize,
    pub transactions: u64,
    pub frames_in: u64,
    pub frames_out: u64,
    pub timeouts: u64,
    pub bad_checksums: u64,
    pub last_seen_unix: Option<f64>,
    pub devices: Vec<Device>,
}

#[derive(Debug, Serialize)]
pub struct Device {
    pub device: u8,
    /// `G.P.D`, as `gimbalctl --to` takes it.
    pub address: String,
    pub online: bool,
    pub last_seen_unix: Option<f64>,
    pub position: Option<PositionSeen>,
    pub lens: Option<LensSeen>,
    pub last_error: Option<ErrorSeen>,
    pub commands: u64,
    pub unreachable: u64,
    pub no_result: u64,
    pub nics: u64,
}

/// The last answer to `P?` (Table 15).
#[derive(Debug, Serialize)]
pub struct PositionSeen {
    pub pan_deg: f64,
    pub tilt_deg: f64,
    pub unix: f64,
    /// When a motion went to the gimbal after that answer (a broadcast
    /// `HO` included): it is no longer there. Null: nothing moved it since.
    pub moved_unix: Option<f64>,
}

/// The last answer to `V?` (Table 17), raw 12-bit positions.
#[derive(Debug, Serialize)]
pub struct LensSeen {
    pub zoom: u16,
    pub focus: u16,
    pub unix: f64,
}

#[derive(Debug, Serialize)]
pub struct ErrorSeen {
    /// `device_silent`, `device_nak`, `no_result` or `nic`.
    pub error: &'static str,
    pub message: String,
    pub unix: f64,
}

#[derive(Debug, Serialize)]
pub struct Link {
    pub link: String,
    pub role: &'static str,
    /// Serving: a listener while it is bound (connections or not), any
    /// other link while its connection is up.
    pub up: bool,
    pub connections: u64,
    pub frames_in: u64,
    pub frames_out: u64,
    pub last_seen_unix: Option<f64>,
}

/// The devices of `port`: every one the router's registry holds, and every
/// one the configuration names that it does not hold yet (not yet heard:
/// offline, never seen, nothing known), in device order.
fn devices_of(s: &Snapshot, port: u8) -> impl Iterator<Item = (u8, DeviceStats)> + '_ {
    let heard = s.stats.devices.range((port, 0)..=(port, u8::MAX));
    let known: std::collections::BTreeMap<u8, DeviceStats> = s
        .configured
        .range((port, 0)..=(port, u8::MAX))
        .map(|&(_, device)| (device, DeviceStats::default()))
        .chain(heard.map(|(&(_, device), d)| (device, *d)))
        .collect();
    known.into_iter()
}

impl Status {
    pub fn of(s: &Snapshot) -> Self {
        let stats = &s.stats;
        let ports = stats
            .ports
            .iter()
            .map(|(&port, p)| Port {
                port,
                open: p.open,
                bps: p.bps,
                queue_length: p.queue_len,
                transactions: p.transactions,
                frames_in: p.line.frames_in,
                frames_out: p.line.frames_out,
                timeouts: p.line.timeouts,
                bad_checksums: p.line.bad_checksums,
                last_seen_unix: p.line.last_seen.map(|t| s.unix_seconds(t)),
                devices: devices_of(s, port)
                    .map(|(device, d)| Device {
                        device,
                        address: format!("{}.{port}.{device}", s.group),
                        online: d.online,
                        last_seen_unix: d.last_seen.map(|t| s.unix_seconds(t)),
                        position: d.position.map(|(t, p)| PositionSeen {
                            pan_deg: degrees(p.pan),
                            tilt_deg: degrees(p.tilt),
                            unix: s.unix_seconds(t),
                            moved_unix: d.moved.map(|m| s.unix_seconds(m)),
                        }),
                        lens: d.lens.map(|(t, l)| LensSeen {
                            zoom: l.zoom.get(),
                            focus: l.focus.get(),
                            unix: s.unix_seconds(t),
                        }),
                        last_error: d.last_error.map(|(t, e)| ErrorSeen {
                            error: e.name(),
                            message: e.to_string(),
                            unix: s.unix_seconds(t),
                        }),
                        commands: d.commands,
                        unreachable: d.unreachable,
                        no_result: d.no_result,
                        nics: d.nics,
                    })
                    .collect(),
            })
            .collect();
        let links = s
            .links
            .iter()
            .map(|(name, t)| Link {
                link: name.clone(),
                role: t.stats.kind.name(),
                up: t.up(),
                connections: t.connections,
                frames_in: t.stats.line.frames_in,
                frames_out: t.stats.line.frames_out,
                last_seen_unix: t.stats.line.last_seen.map(|tick| s.unix_seconds(tick)),
            })
            .collect();
        let control = s
            .control
            .iter()
            .map(|c| Control {
                address: format!("{}.{}.{}", s.group, c.port, c.device),
                holder: c.holder.as_ref().map(HolderSeen::of),
                lapses_in_ms: c.lapses_at.map(|t| t.saturating_sub(s.uptime_ms)),
                bounded: c.bounded,
                // The governor's reading, which its own polls renew while a governed gimbal moves.
                position: c.position.map(|(t, p)| PositionSeen {
                    pan_deg: degrees(p.pan),
                    tilt_deg: degrees(p.tilt),
                    unix: s.unix_seconds(t),
                    moved_unix: None,
                }),
            })
            .collect();
        let tours = s
            .tours
            .iter()
            .map(|t| Tour {
                name: t.name.clone(),
                address: format!("{}.{}.{}", s.group, t.port, t.device),
                state: tour_state(t.state),
                step: t.step + 1,
                waiting_for: t.waiting_for.as_ref().map(HolderSeen::of),
            })
            .collect();
        Status {
            gcud: Daemon {
                version: VERSION,
                group: s.group,
                name: s.name.clone(),
                started_unix: s.unix_seconds(0),
                uptime_ms: s.uptime_ms,
                shutting_down: s.shutting_down,
                commands_in_progress: stats.router.in_progress,
                connections_open: s.connections.open,
            },
            ports,
            links,
            control,
            tours,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::snapshot::fixture;

    /// The document `gimbalctl gcud-status` and scripts read, for a
    /// snapshot with every field set, byte for byte.
    #[test]
    fn every_field_renders_as_the_reviewed_document() {
        let status = Status::of(&fixture::every_field_set());
        let text = serde_json::to_string_pretty(&status).expect("JSON");
        fixture::assert_reviewed("status.json", &text);
    }

    /// Issue 24: a client listener serves while it is bound, before anyone
    /// connects; a link that dials out is up only while connected.
    #[test]
    fn a_listener_is_up_while_it_serves() {
        let mut snapshot = fixture::every_field_set();
        for t in snapshot.links.values_mut() {
            t.connections = 0;
        }
        let status = Status::of(&snapshot);
        let up: Vec<(&str, &str, bool)> = status.links.iter().map(|l| (l.link.as_str(), l.role, l.up)).collect();
        assert_eq!(
            up,
            [
                ("clients", "client", true),
                ("north", "upstream", false),
                ("south", "downstream", false)
            ]
        );
    }
}
