//! Router configuration (ARCHITECTURE "Routing semantics"): own group, ports with
//! their time-outs, link settings, static routes and the default upstream.
//! All durations are in ticks, the unit of the `now` the daemon passes in
//! (milliseconds in `gcud`).

use std::collections::BTreeMap;
use std::sync::Arc;

use sagebrush_protocol::link::{TransactionPolicy, silence_ms, wire_ms};
use sagebrush_protocol::{DataRate, Identity, MCU_GROUP, WILDCARD};

use crate::govern::rules::Governance;
use crate::types::LinkId;

sagebrush_protocol::code_table! {
    /// Which side of the GCU a link faces (its name is gcud's `role`).
    /// Group-255 frames arriving on an upstream or client link are flooded
    /// to every downstream link, never back where they came from; frames
    /// from a downstream link are not flooded.
    pub enum LinkKind: u8 {
        /// toward the MCU (or a GCU nearer to it)
        Upstream,
        /// toward another GCU further from the MCU
        Downstream,
        /// a local client (operator tool) speaking as an MCU: it sends
        /// commands and gets answers back along the reverse path; its source
        /// group is never a routing destination
        Client,
    }
}

/// Source groups a link may speak for, so that a client cannot speak as
/// another GCU. Group 255 is refused always, and the router's own group on
/// every link but a client's (a client acts for this GCU, Figure 7).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SourceFilter {
    Any,
    Only(Vec<u8>),
}

impl SourceFilter {
    pub fn allows(&self, group: u8) -> bool {
        match self {
            SourceFilter::Any => true,
            SourceFilter::Only(groups) => groups.contains(&group),
        }
    }
}

/// How one link is treated, given when it comes up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LinkConfig {
    pub kind: LinkKind,
    pub allowed_sources: SourceFilter,
    /// The medium delivers every byte, in order (TCP): our ACKs are never
    /// lost, so the next GCU never sends an answer twice for that reason.
    /// `false` (a serial line) is the safe default.
    pub lossless: bool,
    /// Continuous motion started by this link and not refreshed (any
    /// command of the link to that device) within this many ticks is
    /// stopped, as if the link had gone down. `None`: no lease.
    pub motion_lease: Option<u64>,
    /// The configured listener this connection was accepted on (each
    /// connection has its own [`LinkId`]): a static route or the default
    /// upstream that names the listener reaches its newest live connection,
    /// so a GCU that dials in can be routed to.
    pub listener: Option<LinkId>,
    /// The configured link's name: every connection accepted on one
    /// listener is the same link to the governance (control is held by a
    /// link, not a connection). `None`: this link alone.
    pub name: Option<Arc<str>>,
    /// 0..=100: a link of higher priority takes control of a gimbal from a
    /// lower one (ARCHITECTURE "Governance").
    pub priority: u8,
    /// It may ask a gimbal's rules and who controls it (`~B`, `~C`):
    /// keep-out zones may mark privacy areas.
    pub may_read_rules: bool,
    /// The principal this connection authenticated as (gcud: the subject
    /// CN of its TLS client certificate). `None`: the link is its own
    /// principal (ARCHITECTURE "Principals").
    pub principal: Option<crate::principal::Principal>,
    /// A link to another GCU that knows who this GCU's commands are from
    /// (gcud: a `connect` link that authenticates with its own
    /// certificate): each forwarded command's principal goes ahead of it
    /// as `~P` whenever it changes (ARCHITECTURE "Principals").
    pub sends_principals: bool,
}

impl LinkConfig {
    /// A link over a medium that may lose bytes (see [`LinkConfig::lossless`]).
    pub fn new(kind: LinkKind, allowed_sources: SourceFilter) -> Self {
        Self {
            kind,
            allowed_sources,
            lossless: false,
            motion_lease: None,
            listener: None,
            name: None,
            priority: crate::govern::rules::DEFAULT_PRIORITY,
            may_read_rules: true,
            principal: None,
            sends_principals: false,
        }
    }
}

/// One serial port (a bus of devices) and the time-outs of its transactions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortConfig {
    /// Port address 1..=254.
    pub id: u8,
    /// Initial line rate; one of the rates of Table 4 (1200..=115200).
    pub bps: u32,
    /// Retransmissions after the first write when no ACK (or a NAK) comes.
    pub retries: u8,
    /// Ticks to wait for ACK/NAK after a write.
    pub ack_timeout: u64,
    /// Ticks to wait for a result after the ACK (ordinary queries).
    pub result_timeout: u64,
    /// Ticks to wait for a result of the long class (`IX`).
    pub long_result_timeout: u64,
    /// Ticks a NIC may follow the ACK of a command without result.
    pub nic_window: u64,
    /// Quiet ticks after a write to device 255 before the bus is used again.
    pub broadcast_guard: u64,
    /// Non-stop jobs that may wait behind the one in flight.
    pub queue_bound: usize,
    /// Stop and halt jobs that may wait (counted apart, so that work never
    /// takes a stop's place; identical queued stops are merged).
    pub stop_queue_bound: usize,
    /// Silence after which a partial frame on the line is abandoned.
    pub idle_timeout: u64,
    /// The devices on this bus, when known: a rate change switches the port
    /// once all of them acknowledged it. `None`: the devices that answered
    /// since the port was opened.
    pub devices: Option<Vec<u8>>,
    /// A device server (ser2net over TCP) sits between the GCU and the bus:
    /// bytes written may wait in its buffers for as long as it stalls, so
    /// nothing is retransmitted into it (every copy would run once it
    /// resumes) and a command whose ACK never came is reported `0B not
    /// confirmed`, never undelivered (ARCHITECTURE "Delivery contract").
    pub buffered: bool,
    /// The GCU may write while a device answers (RS-232 point to point,
    /// RS-422 or four-wire RS-485, a device server on one of those; not a
    /// two-wire RS-485 bus): the next command to a device goes during the
    /// NIC window of the one before (`port::pipeline`, ARCHITECTURE
    /// "Routing semantics").
    pub full_duplex: bool,
    /// Quiet ticks after a device that answered before went silent to
    /// every try: its answer may still come, late, and a bare ACK names no
    /// command, so nothing is written meanwhile that could take it for its
    /// own (ARCHITECTURE "Routing semantics").
    pub late_answer_guard: u64,
}

/// Default [`PortConfig::late_answer_guard`]: half a second after giving
/// up on a device (at 9600 bit/s the four tries of a goto take about
/// 310 ms, so answers up to about 800 ms after the command are covered; the
/// adversarial run's came at 900 ms with a longer budget). It stays below
/// the clients' delivery time-out (800 ms) less one exchange, so that a
/// command queued meanwhile is still delivered in time.
pub const LATE_ANSWER_GUARD_MS: u64 = 500;

impl PortConfig {
    /// A 9600 bit/s port, see [`PortConfig::at_rate`].
    pub fn new(id: u8) -> Self {
        Self::at_rate(id, 9600)
    }

    /// A port at `bps` with the protocol's default time-outs for that rate
    /// in millisecond ticks ([`TransactionPolicy::serial`] and
    /// [`silence_ms`], the one place they are derived).
    pub fn at_rate(id: u8, bps: u32) -> Self {
        let policy = TransactionPolicy::serial(bps);
        Self {
            id,
            bps,
            retries: policy.retry.retries,
            ack_timeout: policy.retry.ack_timeout,
            result_timeout: policy.result_timeout,
            long_result_timeout: policy.long_result_timeout,
            nic_window: policy.nic_window,
            broadcast_guard: policy.broadcast_guard,
            queue_bound: 32,
            stop_queue_bound: 64,
            idle_timeout: silence_ms(bps),
            devices: None,
            buffered: false,
            full_duplex: false,
            late_answer_guard: LATE_ANSWER_GUARD_MS,
        }
    }
}

impl PortConfig {
    /// Retransmissions after the first write: none into a device server
    /// ([`PortConfig::buffered`]).
    pub fn retransmissions(&self) -> u8 {
        if self.buffered { 0 } else { self.retries }
    }

    /// The longest one transaction on this port may take: every try's ACK
    /// wait (a longest frame's wire time included, the clock starts at the
    /// write), then the result wait of the normal or long class.
    pub fn worst_exchange(&self, long: bool) -> u64 {
        let tries = u64::from(self.retransmissions()) + 1;
        let ack = self.ack_timeout + wire_ms(sagebrush_protocol::MAX_FRAME_LEN, self.bps);
        let result = if long {
            self.long_result_timeout
        } else {
            self.result_timeout
        };
        tries * ack + result
    }
}

/// Settings shared by all links.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LinkSettings {
    /// Retransmissions of a frame the GCU sends, after the first.
    pub retries: u8,
    /// Ticks to wait for the peer's ACK/NAK.
    pub ack_timeout: u64,
    /// Frames that may wait on a link (the one in flight included).
    pub queue_bound: usize,
    /// Forwarded stop commands that may wait on a link, apart from the rest.
    pub stop_queue_bound: usize,
    /// Silence after which a partial frame on the link is abandoned.
    pub idle_timeout: u64,
    /// How long after forwarding a command (first transmission) its result
    /// is routed back along the reverse path; a normal result.
    pub answer_timeout: u64,
    /// The same for a long (`IX`) result.
    pub long_answer_timeout: u64,
    /// The same for the `?` that may follow a command without result.
    pub nic_answer_timeout: u64,
    /// Forwarded commands awaiting answers, over all links.
    pub max_pending: usize,
    /// How long after a client's transmission its ACK or report comes at
    /// the latest (ARCHITECTURE "Delivery contract"): past it, a command
    /// still queued is given up unsent
    /// ([`sagebrush_protocol::Undelivered::Expired`]) and one already on
    /// its way is reported not confirmed. It must be shorter than the
    /// clients' own ACK time-out, so that no outcome arrives after the
    /// client retransmitted or moved on.
    pub delivery_timeout: u64,
}

impl LinkSettings {
    /// Default [`LinkSettings::retries`].
    pub const RETRIES: u8 = 3;
    /// Default [`LinkSettings::ack_timeout`], in milliseconds.
    pub const ACK_TIMEOUT_MS: u64 = 200;
    /// Default [`LinkSettings::delivery_timeout`], in milliseconds: below
    /// gimbalctl's ACK time-out over TCP (1000 ms).
    pub const DELIVERY_TIMEOUT_MS: u64 = 800;
}

impl Default for LinkSettings {
    fn default() -> Self {
        Self {
            retries: Self::RETRIES,
            ack_timeout: Self::ACK_TIMEOUT_MS,
            queue_bound: 64,
            stop_queue_bound: 64,
            idle_timeout: 100,
            answer_timeout: 3_000,
            long_answer_timeout: 35_000,
            nic_answer_timeout: 1_500,
            max_pending: 1024,
            delivery_timeout: Self::DELIVERY_TIMEOUT_MS,
        }
    }
}

impl LinkSettings {
    /// These settings in force with `ports`: a command forwarded to another
    /// GCU is answered after a whole port transaction there (assumed
    /// configured like the slowest port here) and the link's own retries
    /// both ways, so the reverse path waits at least that long for its
    /// answer (normal and long class).
    pub(crate) fn with_answer_time_for(&self, ports: &[PortConfig]) -> Self {
        let worst = |long| ports.iter().map(|p| p.worst_exchange(long)).max().unwrap_or(0);
        let link = 2 * (u64::from(self.retries) + 1) * self.ack_timeout;
        Self {
            answer_timeout: self.answer_timeout.max(link + worst(false)),
            long_answer_timeout: self.long_answer_timeout.max(link + worst(true)),
            ..self.clone()
        }
    }
}

/// Everything a [`crate::Router`] needs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RouterConfig {
    /// This GCU's group address G, 1..=254.
    pub group: u8,
    /// Device name for `D?` (Table 6): up to 20 printable ASCII characters.
    pub name: String,
    /// Serial number for `D?`: up to 20 printable ASCII characters.
    pub serial: String,
    pub ports: Vec<PortConfig>,
    pub links: LinkSettings,
    /// Destination group -> link, tried before learned routes.
    pub static_routes: BTreeMap<u8, LinkId>,
    /// Where frames for unknown groups go. When `None` or down: the up
    /// link of kind [`LinkKind::Upstream`] with the lowest id.
    pub default_upstream: Option<LinkId>,
    /// Control, limits, zones, tours and park (ARCHITECTURE "Governance").
    pub governance: Governance,
}

impl RouterConfig {
    pub fn new(group: u8) -> Self {
        Self {
            group,
            name: "sagebrush gcud".into(),
            serial: String::new(),
            ports: Vec::new(),
            links: LinkSettings::default(),
            static_routes: BTreeMap::new(),
            default_upstream: None,
            governance: Governance::default(),
        }
    }

    /// Checks every rule the router relies on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.group == MCU_GROUP || self.group == WILDCARD {
            return Err(ConfigError::Group(self.group));
        }
        for (field, text) in [("name", &self.name), ("serial", &self.serial)] {
            let trimmed = text.trim_end();
            if Identity::new(self.group, *b"19", trimmed.as_bytes(), b"").is_err() {
                return Err(ConfigError::IdentityField { field });
            }
        }
        let mut seen = [false; 256];
        for port in &self.ports {
            if port.id == 0 || port.id == WILDCARD {
                return Err(ConfigError::PortId(port.id));
            }
            if std::mem::replace(&mut seen[usize::from(port.id)], true) {
                return Err(ConfigError::DuplicatePort(port.id));
            }
            if DataRate::from_bits_per_second(port.bps).is_none() {
                return Err(ConfigError::Rate {
                    port: port.id,
                    bps: port.bps,
                });
            }
            if port.queue_bound == 0 {
                return Err(ConfigError::Zero("port queue_bound"));
            }
            if port.stop_queue_bound == 0 {
                return Err(ConfigError::Zero("port stop_queue_bound"));
            }
            if port.ack_timeout == 0 {
                return Err(ConfigError::Zero("port ack_timeout"));
            }
        }
        if self.links.queue_bound == 0 || self.links.stop_queue_bound == 0 {
            return Err(ConfigError::Zero("link queue_bound"));
        }
        if self.links.ack_timeout == 0 {
            return Err(ConfigError::Zero("link ack_timeout"));
        }
        if self.links.max_pending == 0 {
            return Err(ConfigError::Zero("link max_pending"));
        }
        if let Some(&group) = self.static_routes.keys().find(|&&g| g == self.group || g == WILDCARD) {
            return Err(ConfigError::StaticRoute(group));
        }
        let ports: Vec<u8> = self.ports.iter().map(|p| p.id).collect();
        self.governance
            .validate(&ports)
            .map_err(|e| ConfigError::Governance(e.0))
    }
}

/// Why a [`RouterConfig`] was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The GCU group must be 1..=254.
    Group(u8),
    /// `name` or `serial` is not up to 20 printable ASCII characters.
    IdentityField {
        field: &'static str,
    },
    /// Port ids are 1..=254.
    PortId(u8),
    DuplicatePort(u8),
    /// Not a rate of Table 4.
    Rate {
        port: u8,
        bps: u32,
    },
    /// A setting that must not be zero.
    Zero(&'static str),
    /// A static route for the own group or the wildcard.
    StaticRoute(u8),
    /// A setting that a running router cannot change (see [`crate::Router::reconfigure`]).
    NotReloadable(&'static str),
    /// A governance rule that cannot hold (ARCHITECTURE "Governance"), said in full.
    Governance(String),
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConfigError::Group(g) => write!(f, "GCU group {g} is not 1..=254"),
            ConfigError::IdentityField { field } => {
                write!(f, "{field} must be at most 20 printable ASCII characters")
            }
            ConfigError::PortId(p) => write!(f, "port id {p} is not 1..=254"),
            ConfigError::DuplicatePort(p) => write!(f, "port {p} configured twice"),
            ConfigError::Rate { port, bps } => write!(f, "port {port}: {bps} bps is not a protocol rate"),
            ConfigError::Zero(what) => write!(f, "{what} must not be zero"),
            ConfigError::StaticRoute(g) => write!(f, "static route for group {g} (own group or wildcard)"),
            ConfigError::NotReloadable(what) => write!(f, "{what} cannot change while running: restart instead"),
            ConfigError::Governance(what) => f.write_str(what),
        }
    }
}

impl std::error::Error for ConfigError {}
