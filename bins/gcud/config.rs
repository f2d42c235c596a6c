//! `gcud --config FILE`: the TOML configuration, parsed with serde and then
//! validated. Every error names the file, the line and column, the key and
//! what was expected (`gcud --check` prints them and exits 2).

use ipnet::IpNet;
use std::collections::BTreeSet;
use std::fmt;
use std::net::{IpAddr, SocketAddr};
use std::ops::Range;
use std::path::{Path, PathBuf};

use sagebrush_protocol::DataRate;
use sagebrush_protocol::link::TransactionPolicy;
use serde::Deserialize;
use toml::Spanned;

pub use sagebrush_client::config_file::ConfigError;
use sagebrush_client::config_file::Source;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    pub gcu: GcuSection,
    #[serde(default)]
    pub log: LogSection,
    pub metrics: Option<MetricsSection>,
    #[serde(default)]
    pub limits: LimitsSection,
    #[serde(default)]
    pub port_defaults: PortSettings,
    #[serde(default)]
    pub link_timing: LinkSettings,
    #[serde(default, rename = "port")]
    pub ports: Vec<PortSection>,
    #[serde(default, rename = "link")]
    pub links: Vec<LinkSection>,
    #[serde(default, rename = "route")]
    pub routes: Vec<RouteSection>,
    pub capture: Option<CaptureSection>,
}

/// `[capture]`: pcapng capture of every port and link (docs/capture.md);
/// SIGUSR1 starts and stops it at run time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaptureSection {
    /// The pcapng file written (older ones rotate to NAME.1.pcapng, ...).
    pub file: Spanned<String>,
    /// Capture from start-up (default true); SIGUSR1 toggles either way.
    pub enabled: Option<Spanned<bool>>,
    /// Start a new file past this size (default: one file).
    pub rotate_bytes: Option<Spanned<i64>>,
    /// Files kept, the current one included (default 4).
    pub rotate_count: Option<Spanned<i64>>,
    /// Stop capturing after this many bytes in all (default: no limit).
    pub budget_bytes: Option<Spanned<i64>>,
}

/// `[capture]`, validated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaptureSettings {
    pub file: PathBuf,
    pub enabled: bool,
    pub rotate_bytes: Option<u64>,
    pub rotate_count: u32,
    pub budget_bytes: Option<u64>,
}

impl CaptureSettings {
    pub fn capture_config(&self) -> sagebrush_host::capture::CaptureConfig {
        sagebrush_host::capture::CaptureConfig {
            rotate_bytes: self.rotate_bytes,
            rotate_count: self.rotate_count,
            budget_bytes: self.budget_bytes,
            application: format!("gcud {}", env!("CARGO_PKG_VERSION")),
            ..Default::default()
        }
    }
}

/// `[gcu]`: this GCU.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GcuSection {
    /// Group address 1..=254 (Table 2).
    pub group: Spanned<i64>,
    /// Device name for `D?` (Table 6), at most 20 characters.
    #[serde(default = "default_name")]
    pub name: Spanned<String>,
    /// Serial number for `D?` (Table 6), at most 20 characters.
    #[serde(default = "default_serial")]
    pub serial: Spanned<String>,
    /// Link name that frames for unknown groups go to.
    pub default_route: Option<Spanned<String>>,
    /// On SIGTERM: how long in-flight transactions may take to finish.
    #[serde(default = "default_shutdown_grace_ms")]
    pub shutdown_grace_ms: Spanned<i64>,
}

fn default_name() -> Spanned<String> {
    Spanned::new(0..0, "gcud".to_owned())
}

fn default_serial() -> Spanned<String> {
    Spanned::new(0..0, String::new())
}

fn default_shutdown_grace_ms() -> Spanned<i64> {
    Spanned::new(0..0, 3000)
}

/// `[log]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogSection {
    /// A tracing filter (`info`, `debug`, `gcud=debug,info`); `RUST_LOG` wins.
    pub level: Option<Spanned<String>>,
}

/// `[metrics]`: the Prometheus text endpoint.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsSection {
    /// Address to serve `/metrics` on; loopback unless you mean otherwise.
    #[serde(default = "default_metrics_listen")]
    pub listen: Spanned<String>,
    /// Peer addresses allowed to scrape (default: loopback only).
    pub allow_peers: Option<Spanned<Vec<Spanned<String>>>>,
}

fn default_metrics_listen() -> Spanned<String> {
    Spanned::new(0..0, "127.0.0.1:9187".to_owned())
}

/// `[limits]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsSection {
    /// Commands waiting per port beyond the one in flight; more are dropped and counted.
    #[serde(default = "default_queue_depth")]
    pub queue_depth: Spanned<i64>,
    /// Connections accepted at once over all TCP listeners; at the limit the
    /// one idle the longest is evicted for a newcomer.
    #[serde(default = "default_max_connections")]
    pub max_connections: Spanned<i64>,
    /// Connections one peer address may hold at once (default: half of `max_connections`).
    pub max_connections_per_peer: Option<Spanned<i64>>,
    /// An accepted connection that sends nothing this long is closed.
    pub idle_timeout_ms: Option<Spanned<i64>>,
}

impl Default for LimitsSection {
    fn default() -> Self {
        Self {
            queue_depth: default_queue_depth(),
            max_connections: default_max_connections(),
            max_connections_per_peer: None,
            idle_timeout_ms: None,
        }
    }
}

fn default_queue_depth() -> Spanned<i64> {
    Spanned::new(0..0, 16)
}

fn default_max_connections() -> Spanned<i64> {
    Spanned::new(0..0, 32)
}

/// Per-port line and transaction settings; `[port_defaults]` and each `[[port]]`.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PortSettings {
    pub baud: Option<Spanned<i64>>,
    pub retries: Option<Spanned<i64>>,
    pub ack_timeout_ms: Option<Spanned<i64>>,
    pub result_timeout_ms: Option<Spanned<i64>>,
    pub long_result_timeout_ms: Option<Spanned<i64>>,
    pub nic_window_ms: Option<Spanned<i64>>,
    pub broadcast_guard_ms: Option<Spanned<i64>>,
}

impl PortSection {
    fn settings(&self) -> PortSettings {
        PortSettings {
            baud: self.baud.clone(),
            retries: self.retries.clone(),
            ack_timeout_ms: self.ack_timeout_ms.clone(),
            result_timeout_ms: self.result_timeout_ms.clone(),
            long_result_timeout_ms: self.long_result_timeout_ms.clone(),
            nic_window_ms: self.nic_window_ms.clone(),
            broadcast_guard_ms: self.broadcast_guard_ms.clone(),
        }
    }
}

/// `[[port]]`: a device bus.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PortSection {
    /// Port address 1..=254 (Table 2).
    pub id: Spanned<i64>,
    /// A serial device, e.g. `/dev/ttyUSB0` or a udev name `/dev/gimbal-bus-1`.
    pub path: Option<Spanned<String>>,
    /// A TCP device server (ser2net) `host:port` instead of a local line.
    pub tcp: Option<Spanned<String>>,
    /// Simulated gimbals with these device addresses, in-process (demo, tests).
    pub simulate: Option<Spanned<Vec<Spanned<i64>>>>,
    // The settings of [`PortSettings`], inline (serde's flatten would lose
    // the positions that error messages need).
    pub baud: Option<Spanned<i64>>,
    pub retries: Option<Spanned<i64>>,
    pub ack_timeout_ms: Option<Spanned<i64>>,
    pub result_timeout_ms: Option<Spanned<i64>>,
    pub long_result_timeout_ms: Option<Spanned<i64>>,
    pub nic_window_ms: Option<Spanned<i64>>,
    pub broadcast_guard_ms: Option<Spanned<i64>>,
}

/// `[link_timing]`: retransmission on every link (router-wide).
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSettings {
    pub retries: Option<Spanned<i64>>,
    pub ack_timeout_ms: Option<Spanned<i64>>,
    /// A client's ACK or report comes at the latest this long after its
    /// command (ARCHITECTURE "Delivery contract"); below the clients' own ACK time-out.
    pub delivery_timeout_ms: Option<Spanned<i64>>,
}

/// Which way a link faces (for group-255 flooding and dead-man rules).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LinkRole {
    /// Toward the MCU or a GCU above.
    Upstream,
    /// Toward another GCU below.
    Downstream,
    /// An operator tool or application speaking as a client.
    Client,
}

/// `[[link]]`: toward the MCU, another GCU or clients.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSection {
    pub name: Spanned<String>,
    pub role: Spanned<LinkRole>,
    /// A serial line.
    pub serial: Option<Spanned<String>>,
    pub baud: Option<Spanned<i64>>,
    /// A TCP listener; each accepted connection is a link.
    pub listen: Option<Spanned<String>>,
    /// A TCP client, reconnected with backoff.
    pub connect: Option<Spanned<String>>,
    /// Listener: peer addresses allowed to connect (default: loopback only).
    pub allow_peers: Option<Spanned<Vec<Spanned<String>>>>,
    /// Source groups frames on this link may carry (default: any on links
    /// to GCUs; the MCU's 0 and this GCU's own group on client links).
    pub allow_source_groups: Option<Spanned<Vec<Spanned<i64>>>>,
    /// Continuous motion started on this link and not refreshed within
    /// this time is stopped (default: no lease).
    pub motion_lease_ms: Option<Spanned<i64>>,
}

/// `[[route]]`: a static route.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RouteSection {
    pub group: Spanned<i64>,
    pub link: Spanned<String>,
}

// ---- validated configuration -------------------------------------------------

/// Transaction timing of one port, resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortTiming {
    pub baud: u32,
    pub retries: u8,
    pub ack_timeout_ms: u64,
    pub result_timeout_ms: u64,
    pub long_result_timeout_ms: u64,
    pub nic_window_ms: u64,
    pub broadcast_guard_ms: u64,
}

/// Where a port's bytes come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PortTransport {
    Serial(PathBuf),
    Tcp(String),
    Simulated(Vec<u8>),
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Port {
    pub id: u8,
    pub transport: PortTransport,
    pub timing: PortTiming,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkTransport {
    Serial { path: PathBuf, baud: u32 },
    Listen(SocketAddr),
    Connect(String),
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Link {
    pub name: String,
    pub role: LinkRole,
    pub transport: LinkTransport,
    pub allow_peers: PeerAllowList,
    /// `None`: any source group.
    pub allow_source_groups: Option<Vec<u8>>,
    pub motion_lease_ms: Option<u64>,
}

/// The validated configuration.
#[derive(Debug, Clone)]
pub struct Config {
    pub file: PathBuf,
    pub group: u8,
    pub name: String,
    pub serial: String,
    pub default_route: Option<String>,
    pub shutdown_grace_ms: u64,
    pub log_level: Option<String>,
    pub metrics: Option<SocketAddr>,
    /// `[metrics] allow_peers`: peers allowed to scrape (default: loopback only).
    pub metrics_allow_peers: PeerAllowList,
    pub queue_depth: usize,
    pub max_connections: usize,
    pub max_connections_per_peer: usize,
    /// The per-peer cap was configured: it applies to loopback peers too.
    pub per_peer_cap_configured: bool,
    pub idle_timeout_ms: u64,
    pub link_retries: u8,
    pub link_ack_timeout_ms: u64,
    pub delivery_timeout_ms: u64,
    pub ports: Vec<Port>,
    pub links: Vec<Link>,
    pub routes: Vec<(u8, String)>,
    /// `[capture]`, if configured.
    pub capture: Option<CaptureSettings>,
    /// What is valid but probably not meant (a listener reachable from the
    /// network, ...), each `FILE:LINE:COLUMN: KEY: message` like an error:
    /// `--check` prints them, start-up logs them once logging is set up.
    pub warnings: Vec<String>,
    /// Every TCP listen address with its place (`FILE:LINE:COLUMN: KEY`),
    /// for [`Config::probe_listeners`].
    pub listen_places: Vec<(SocketAddr, String)>,
    /// Every serial device a port or link opens, with its place in the
    /// file, for [`Config::probe_serial_paths`].
    pub serial_places: Vec<(PathBuf, String)>,
}

impl Config {
    /// `--check` only: tries to bind each listen address (port 0 is never
    /// taken) and returns a warning for each that cannot be bound now. Not
    /// an error: the address may be free by the time gcud starts (and a
    /// running gcud holds its own).
    pub fn probe_listeners(&self) -> Vec<String> {
        self.listen_places
            .iter()
            .filter(|(addr, _)| addr.port() != 0)
            .filter_map(|(addr, place)| match std::net::TcpListener::bind(addr) {
                Ok(_) => None,
                Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => Some(format!(
                    "{place}: {addr} is in use on this machine now; start-up fails unless it is free by then"
                )),
                Err(e) => Some(format!("{place}: cannot listen on {addr} here now: {e}")),
            })
            .collect()
    }

    /// `--check` only: a warning for each serial device that does not exist
    /// now. Not an error: an adapter may be plugged in later, and gcud
    /// retries the port until it is.
    pub fn probe_serial_paths(&self) -> Vec<String> {
        self.serial_places
            .iter()
            .filter(|(path, _)| !path.exists())
            .map(|(path, place)| {
                format!(
                    "{place}: {} does not exist now; gcud retries it until it is plugged in",
                    path.display()
                )
            })
            .collect()
    }
}

/// Defaults derived from the line rate: the protocol crate's
/// ([`TransactionPolicy::serial`], the one place they are derived).
fn default_timing(baud: u32) -> PortTiming {
    let p = TransactionPolicy::serial(baud);
    PortTiming {
        baud,
        retries: p.retry.retries,
        ack_timeout_ms: p.retry.ack_timeout,
        result_timeout_ms: p.result_timeout,
        long_result_timeout_ms: p.long_result_timeout,
        nic_window_ms: p.nic_window,
        broadcast_guard_ms: p.broadcast_guard,
    }
}

/// The accepted range of a time in milliseconds, inclusive (documented in
/// config/gcud.toml): wide enough for any line or network a field engineer
/// meets, narrow enough that a typo (an extra digit or three) is caught.
type MsRange = (i64, i64);
/// `gcu.shutdown_grace_ms`: 0 (stop at once) to 10 minutes.
const SHUTDOWN_GRACE_MS: MsRange = (0, 600_000);
/// `ack_timeout_ms` of a port: 10 ms to 10 s.
const PORT_ACK_TIMEOUT_MS: MsRange = (10, 10_000);
/// `result_timeout_ms`: 10 ms to 1 minute.
const RESULT_TIMEOUT_MS: MsRange = (10, 60_000);
/// `long_result_timeout_ms` (`IX`): 1 s to 10 minutes.
const LONG_RESULT_TIMEOUT_MS: MsRange = (1_000, 600_000);
/// `nic_window_ms`: 1 ms to 10 s.
const NIC_WINDOW_MS: MsRange = (1, 10_000);
/// `broadcast_guard_ms`: 1 ms to 10 s.
const BROADCAST_GUARD_MS: MsRange = (1, 10_000);
/// `link_timing.ack_timeout_ms`: 10 ms to 10 s.
const LINK_ACK_TIMEOUT_MS: MsRange = (10, 10_000);
/// `link_timing.delivery_timeout_ms`: 50 ms to 1 minute.
const DELIVERY_TIMEOUT_MS: MsRange = (50, 60_000);
/// `motion_lease_ms` of a link: 100 ms to 10 minutes.
const MOTION_LEASE_MS: MsRange = (100, 600_000);

/// The file being checked: `sagebrush_client::config_file::Source` (errors
/// at a span, bounded integers, the serde pass) and gcud's own value checks.
struct Checker<'a>(Source<'a>);

impl<'a> std::ops::Deref for Checker<'a> {
    type Target = Source<'a>;

    fn deref(&self) -> &Source<'a> {
        &self.0
    }
}

impl Checker<'_> {
    fn text20(&self, v: &Spanned<String>, key: &str) -> Result<String, ConfigError> {
        let s = v.get_ref();
        if s.len() > 20 || !s.bytes().all(|b| (0x20..=0x7E).contains(&b)) {
            return Err(self.at(
                v.span(),
                key,
                "expected at most 20 printable ASCII characters (Table 6)",
            ));
        }
        Ok(s.trim_end().to_owned())
    }

    /// `IP:PORT`, or a bare `PORT` meaning 127.0.0.1 (listeners stay on
    /// loopback unless an address is given).
    fn socket(&self, v: &Spanned<String>, key: &str) -> Result<SocketAddr, ConfigError> {
        let text = v.get_ref().trim();
        if let Ok(port) = text.parse::<u16>() {
            return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
        }
        text.parse().map_err(|_| {
            self.at(
                v.span(),
                key,
                format!("expected an IP address and port like 127.0.0.1:4001 (or a port alone), found {text:?}"),
            )
        })
    }

    /// `FILE:LINE:COLUMN: KEY` of `span`, the start of a warning.
    fn place(&self, span: Range<usize>, key: &str) -> String {
        let mut place = self.at(span, key, "").to_string();
        place.truncate(place.len() - 2);
        place
    }

    /// A non-empty list of peer IP addresses or networks in CIDR notation
    /// (`allow_peers`: `10.1.2.3`, `10.0.0.0/8`, `fd00::/8`).
    fn peers(&self, list: &Spanned<Vec<Spanned<String>>>, key: &str) -> Result<PeerAllowList, ConfigError> {
        if list.get_ref().is_empty() {
            return Err(self.at(
                list.span(),
                key,
                "expected at least one IP address: an empty list refuses every peer \
                 (remove the key for the default, loopback only)",
            ));
        }
        let mut peers = Vec::new();
        for (j, p) in list.get_ref().iter().enumerate() {
            let text = p.get_ref().as_str();
            let net = parse_peer(text).map_err(|why| self.at(p.span(), format!("{key}[{j}]"), why))?;
            peers.push(net);
        }
        Ok(PeerAllowList(peers))
    }

    fn baud(&self, v: &Spanned<i64>, key: &str) -> Result<u32, ConfigError> {
        u32::try_from(*v.get_ref())
            .ok()
            .and_then(DataRate::from_bits_per_second)
            .and_then(DataRate::bits_per_second)
            .ok_or_else(|| {
                self.at(
                    v.span(),
                    key,
                    format!(
                        "expected one of the protocol's rates 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200 (1.5.1), found {}",
                        v.get_ref()
                    ),
                )
            })
    }

    fn timing(&self, base: PortTiming, s: &PortSettings, key: &str) -> Result<PortTiming, ConfigError> {
        let mut t = match &s.baud {
            Some(b) => {
                let baud = self.baud(b, &format!("{key}.baud"))?;
                PortTiming {
                    baud,
                    ..default_timing(baud)
                }
            }
            None => base,
        };
        if let Some(v) = &s.retries {
            t.retries = self.int(v, &format!("{key}.retries"), 0, 20)?;
        }
        let ms =
            |field: &Option<Spanned<i64>>, name: &str, range: MsRange, target: &mut u64| -> Result<(), ConfigError> {
                if let Some(v) = field {
                    *target = self.int(v, &format!("{key}.{name}"), range.0, range.1)?;
                }
                Ok(())
            };
        ms(
            &s.ack_timeout_ms,
            "ack_timeout_ms",
            PORT_ACK_TIMEOUT_MS,
            &mut t.ack_timeout_ms,
        )?;
        ms(
            &s.result_timeout_ms,
            "result_timeout_ms",
            RESULT_TIMEOUT_MS,
            &mut t.result_timeout_ms,
        )?;
        ms(
            &s.long_result_timeout_ms,
            "long_result_timeout_ms",
            LONG_RESULT_TIMEOUT_MS,
            &mut t.long_result_timeout_ms,
        )?;
        ms(&s.nic_window_ms, "nic_window_ms", NIC_WINDOW_MS, &mut t.nic_window_ms)?;
        ms(
            &s.broadcast_guard_ms,
            "broadcast_guard_ms",
            BROADCAST_GUARD_MS,
            &mut t.broadcast_guard_ms,
        )?;
        Ok(t)
    }
}

/// Which peers a listener (or the metrics endpoint) admits: addresses and
/// networks from `allow_peers`, a plain address being a one-host network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerAllowList(Vec<IpNet>);

impl PeerAllowList {
    /// Whether `peer` is in one of the entries. An IPv4 peer seen on an IPv6
    /// socket (`::ffff:10.1.2.3`) counts as its IPv4 address.
    pub fn contains(&self, peer: &IpAddr) -> bool {
        let peer = peer.to_canonical();
        self.0.iter().any(|net| net.contains(&peer))
    }
}

/// The entries separated by `, `; a one-host entry as a plain address.
impl fmt::Display for PeerAllowList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, net) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            if net.prefix_len() == net.max_prefix_len() {
                write!(f, "{}", net.addr())?;
            } else {
                write!(f, "{net}")?;
            }
        }
        Ok(())
    }
}

/// One `allow_peers` entry: an address (`10.1.2.3`, `::1`) or a network
/// `ADDRESS/PREFIX` (`10.0.0.0/8`, `fd00::/8`) with no host bits set.
fn parse_peer(text: &str) -> Result<IpNet, String> {
    if !text.contains('/') {
        return text
            .parse::<IpAddr>()
            .map(IpNet::from)
            .map_err(|_| format!("expected an IP address, found {text:?} (or a network like 10.0.0.0/8, fd00::/8)"));
    }
    let net = text.parse::<IpNet>().map_err(|_| {
        format!(
            "expected a network ADDRESS/PREFIX (prefix 0..=32 for IPv4, 0..=128 for IPv6, \
             e.g. 10.0.0.0/8, fd00::/8), found {text:?}"
        )
    })?;
    if net.trunc() != net {
        return Err(format!(
            "{text:?} has bits set past its /{} prefix: write the network, {}",
            net.prefix_len(),
            net.trunc()
        ));
    }
    Ok(net)
}

/// The default `allow_peers`: loopback only.
fn loopback() -> PeerAllowList {
    PeerAllowList(vec![
        IpNet::from(IpAddr::from([127, 0, 0, 1])),
        IpNet::from(IpAddr::from(std::net::Ipv6Addr::LOCALHOST)),
    ])
}

/// Whether listeners on `a` and `b` cannot both bind: the same port (not 0)
/// on the same address, or one of them on the unspecified address that
/// covers the other (`0.0.0.0` covers IPv4, `::` covers both on Linux).
fn clash(a: &SocketAddr, b: &SocketAddr) -> bool {
    let covers = |x: IpAddr, y: IpAddr| x.is_unspecified() && (x.is_ipv6() || y.is_ipv4());
    a.port() == b.port() && a.port() != 0 && (a.ip() == b.ip() || covers(a.ip(), b.ip()) || covers(b.ip(), a.ip()))
}

/// The levels a `log.level` directive may name (any case).
const LOG_LEVELS: [&str; 6] = ["error", "warn", "info", "debug", "trace", "off"];

/// Catches what `EnvFilter` accepts but almost certainly is a mistake: it
/// reads a misspelt level such as `wran` as a *target* name, which enables
/// that (non-existent) target and so silences all logging.
///
/// The rule, per comma-separated directive (empty ones are ignored, as
/// `EnvFilter` does, but there must be at least one):
/// - with a `=` after any `[span]` part (`target=level`, `target[span]=level`,
///   `[span]=level`): the text after the `=` must be a level;
/// - without one: the directive is a level, or a span filter (contains `[`),
///   or a target that cannot be a misspelt level: a module path (contains
///   `::`) or a crate name with `_` such as `sagebrush_gcu`. A one-word
///   target such as `gcud` is written `gcud=trace`.
///
/// Levels are `error`, `warn`, `info`, `debug`, `trace` and `off`, in any
/// case (`EnvFilter`'s numeric levels `0`..`5` are refused: write the name).
fn check_log_filter(filter: &str) -> Result<(), String> {
    let expected = "expected a level (error, warn, info, debug, trace, off) \
                    or directives like \"gcud=debug,info\"";
    let is_level = |s: &str| LOG_LEVELS.iter().any(|l| s.trim().eq_ignore_ascii_case(l));
    if filter.split(',').all(|d| d.trim().is_empty()) {
        return Err(format!(
            "{expected}, found an empty filter (remove the key for the default, info)"
        ));
    }
    for directive in filter.split(',').map(str::trim).filter(|d| !d.is_empty()) {
        // The level follows the last `=` outside a `[span{field=value}]` part.
        let tail = directive.rfind(']').map_or(directive, |i| &directive[i + 1..]);
        match tail.rfind('=') {
            Some(i) => {
                let level = &tail[i + 1..];
                if !is_level(level) {
                    return Err(format!("{expected}, found level {level:?} in directive {directive:?}"));
                }
            }
            None => {
                let target_only = directive.contains("::") || directive.contains('_') || directive.contains('[');
                if !is_level(directive) && !target_only {
                    return Err(format!(
                        "{expected}, found {directive:?} (not a level; as a target name it would \
                         turn every other message off; write TARGET=LEVEL)"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Reads (bounded: `sagebrush_client::config_file::read`) and validates `file`.
pub fn load(file: &Path) -> Result<Config, ConfigError> {
    let text = sagebrush_client::config_file::read(file)?;
    parse(file, &text)
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Checker(Source::new(file, text));
    let raw: ConfigFile = c.deserialize()?;
    validate(&c, raw)
}

fn validate(c: &Checker<'_>, raw: ConfigFile) -> Result<Config, ConfigError> {
    let group: u8 = c.int(&raw.gcu.group, "gcu.group", 1, 254)?;
    let name = c.text20(&raw.gcu.name, "gcu.name")?;
    let serial = c.text20(&raw.gcu.serial, "gcu.serial")?;
    let queue_depth = c.int(&raw.limits.queue_depth, "limits.queue_depth", 1, 4096)?;
    let max_connections: usize = c.int(&raw.limits.max_connections, "limits.max_connections", 1, 4096)?;
    let max_connections_per_peer: usize = match &raw.limits.max_connections_per_peer {
        Some(v) => c.int(v, "limits.max_connections_per_peer", 1, max_connections as i64)?,
        None => (max_connections / 2).max(1),
    };
    let idle_timeout_ms: u64 = match &raw.limits.idle_timeout_ms {
        Some(v) => c.int(v, "limits.idle_timeout_ms", 1_000, 86_400_000)?,
        None => 300_000,
    };
    let log_level = match &raw.log.level {
        Some(level) => {
            check_log_filter(level.get_ref()).map_err(|m| c.at(level.span(), "log.level", m))?;
            sagebrush_host::logging::check_filter(level.get_ref()).map_err(|e| {
                c.at(
                    level.span(),
                    "log.level",
                    format!("expected a level or tracing filter like \"info\": {e}"),
                )
            })?;
            Some(level.get_ref().clone())
        }
        None => None,
    };
    let shutdown_grace_ms: u64 = c.int(
        &raw.gcu.shutdown_grace_ms,
        "gcu.shutdown_grace_ms",
        SHUTDOWN_GRACE_MS.0,
        SHUTDOWN_GRACE_MS.1,
    )?;
    let mut warnings = Vec::new();
    // Every TCP listener: address, span, key and place, for the checks below.
    let mut listeners: Vec<(SocketAddr, Range<usize>, String, String)> = Vec::new();
    // Every serial device a port or link opens: path, span and key.
    let mut serial_lines: Vec<(PathBuf, Range<usize>, String)> = Vec::new();
    let mut metrics_allow_peers = loopback();
    let metrics = match &raw.metrics {
        Some(m) => {
            let addr = c.socket(&m.listen, "metrics.listen")?;
            if let Some(list) = &m.allow_peers {
                metrics_allow_peers = c.peers(list, "metrics.allow_peers")?;
            }
            let place = c.place(m.listen.span(), "metrics.listen");
            if !addr.ip().is_loopback() {
                warnings.push(format!(
                    "{place}: serves /metrics on {addr}, not on loopback: reachable from other machines \
                     (allow_peers: {})",
                    metrics_allow_peers
                ));
            }
            listeners.push((addr, m.listen.span(), "metrics.listen".to_owned(), place));
            Some(addr)
        }
        None => None,
    };

    let base = c.timing(default_timing(9600), &raw.port_defaults, "port_defaults")?;
    if raw.ports.len() > 254 {
        return Err(c.at(raw.ports[254].id.span(), "port", "a GCU has at most 254 ports (1.3)"));
    }
    let mut ports = Vec::with_capacity(raw.ports.len());
    let mut port_ids = BTreeSet::new();
    for (i, p) in raw.ports.iter().enumerate() {
        let key = format!("port[{i}]");
        let id: u8 = c.int(&p.id, &format!("{key}.id"), 1, 254)?;
        if !port_ids.insert(id) {
            return Err(c.at(
                p.id.span(),
                format!("{key}.id"),
                format!("port {id} is configured twice"),
            ));
        }
        let transport = match (&p.path, &p.tcp, &p.simulate) {
            (Some(path), None, None) => {
                serial_lines.push((PathBuf::from(path.get_ref()), path.span(), format!("{key}.path")));
                PortTransport::Serial(PathBuf::from(path.get_ref()))
            }
            (None, Some(addr), None) => {
                if !addr.get_ref().contains(':') {
                    return Err(c.at(
                        addr.span(),
                        format!("{key}.tcp"),
                        "expected host:port of a TCP device server",
                    ));
                }
                PortTransport::Tcp(addr.get_ref().clone())
            }
            (None, None, Some(devices)) => {
                let mut ids = Vec::new();
                for (j, d) in devices.get_ref().iter().enumerate() {
                    let id: u8 = c.int(d, &format!("{key}.simulate[{j}]"), 1, 254)?;
                    if ids.contains(&id) {
                        return Err(c.at(
                            d.span(),
                            format!("{key}.simulate[{j}]"),
                            format!("device {id} is listed twice"),
                        ));
                    }
                    ids.push(id);
                }
                if ids.is_empty() {
                    return Err(c.at(
                        devices.span(),
                        format!("{key}.simulate"),
                        "expected at least one device address",
                    ));
                }
                PortTransport::Simulated(ids)
            }
            _ => {
                return Err(c.at(
                    p.id.span(),
                    key,
                    "expected exactly one of `path` (serial device), `tcp` (device server) or `simulate` (device list)",
                ));
            }
        };
        let timing = c.timing(base, &p.settings(), &key)?;
        ports.push(Port { id, transport, timing });
    }

    let link_base_retries: u8 = match &raw.link_timing.retries {
        Some(v) => c.int(v, "link_timing.retries", 0, 20)?,
        None => 3,
    };
    let link_base_ack: u64 = match &raw.link_timing.ack_timeout_ms {
        Some(v) => c.int(
            v,
            "link_timing.ack_timeout_ms",
            LINK_ACK_TIMEOUT_MS.0,
            LINK_ACK_TIMEOUT_MS.1,
        )?,
        None => 200,
    };
    let delivery_timeout_ms: u64 = match &raw.link_timing.delivery_timeout_ms {
        Some(v) => c.int(
            v,
            "link_timing.delivery_timeout_ms",
            DELIVERY_TIMEOUT_MS.0,
            DELIVERY_TIMEOUT_MS.1,
        )?,
        None => sagebrush_gcu::LinkSettings::default().delivery_timeout,
    };
    let mut links = Vec::with_capacity(raw.links.len());
    let mut names = BTreeSet::new();
    for (i, l) in raw.links.iter().enumerate() {
        let key = format!("link[{i}]");
        let name = l.name.get_ref().clone();
        if name.is_empty() || !names.insert(name.clone()) {
            return Err(c.at(
                l.name.span(),
                format!("{key}.name"),
                format!("link names must be unique and non-empty, found {name:?}"),
            ));
        }
        let transport = match (&l.serial, &l.listen, &l.connect) {
            (Some(path), None, None) => {
                let baud = match &l.baud {
                    Some(b) => c.baud(b, &format!("{key}.baud"))?,
                    None => 9600,
                };
                serial_lines.push((PathBuf::from(path.get_ref()), path.span(), format!("{key}.serial")));
                LinkTransport::Serial {
                    path: PathBuf::from(path.get_ref()),
                    baud,
                }
            }
            (None, Some(addr), None) => LinkTransport::Listen(c.socket(addr, &format!("{key}.listen"))?),
            (None, None, Some(addr)) => {
                if !addr.get_ref().contains(':') {
                    return Err(c.at(addr.span(), format!("{key}.connect"), "expected host:port"));
                }
                LinkTransport::Connect(addr.get_ref().clone())
            }
            _ => {
                return Err(c.at(
                    l.name.span(),
                    key,
                    "expected exactly one of `serial`, `listen` or `connect`",
                ));
            }
        };
        if l.baud.is_some() && !matches!(transport, LinkTransport::Serial { .. }) {
            let b = l.baud.as_ref().map_or(0..0, Spanned::span);
            return Err(c.at(b, format!("{key}.baud"), "`baud` applies to a `serial` link only"));
        }
        let allow_peers = match &l.allow_peers {
            Some(list) => {
                if !matches!(transport, LinkTransport::Listen(_)) {
                    return Err(c.at(
                        list.span(),
                        format!("{key}.allow_peers"),
                        "`allow_peers` applies to a `listen` link only",
                    ));
                }
                c.peers(list, &format!("{key}.allow_peers"))?
            }
            None => loopback(),
        };
        let allow_source_groups = match &l.allow_source_groups {
            Some(list) => {
                if list.get_ref().is_empty() {
                    return Err(c.at(
                        list.span(),
                        format!("{key}.allow_source_groups"),
                        "expected at least one group 0..=254: an empty list refuses every frame \
                         on this link (remove the key for the default)",
                    ));
                }
                let mut groups = Vec::new();
                for (j, g) in list.get_ref().iter().enumerate() {
                    groups.push(c.int(g, &format!("{key}.allow_source_groups[{j}]"), 0, 254)?);
                }
                Some(groups)
            }
            // A client that does not say otherwise speaks as the MCU or as
            // this GCU (Figure 7), never as another GCU.
            None if *l.role.get_ref() == LinkRole::Client => Some(vec![sagebrush_protocol::MCU_GROUP, group]),
            None => None,
        };
        let motion_lease_ms = match &l.motion_lease_ms {
            Some(v) => Some(c.int(
                v,
                &format!("{key}.motion_lease_ms"),
                MOTION_LEASE_MS.0,
                MOTION_LEASE_MS.1,
            )?),
            None => None,
        };
        if let (LinkTransport::Listen(addr), Some(listen)) = (&transport, &l.listen) {
            let place = c.place(listen.span(), &format!("{key}.listen"));
            if !addr.ip().is_loopback() {
                warnings.push(format!(
                    "{place}: listens on {addr}, not on loopback: reachable from other machines \
                     (allow_peers: {})",
                    allow_peers
                ));
            }
            listeners.push((*addr, listen.span(), format!("{key}.listen"), place));
        }
        links.push(Link {
            name,
            role: *l.role.get_ref(),
            transport,
            allow_peers,
            allow_source_groups,
            motion_lease_ms,
        });
    }

    // One serial device opened twice: two lines would read each other's
    // bytes. Paths are compared as the system resolves them
    // (`/dev/serial/by-id/...` is a link to `/dev/ttyUSB0`).
    let device = |path: &Path| std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned());
    for (i, (path, span, key)) in serial_lines.iter().enumerate() {
        if let Some((first, first_span, first_key)) = serial_lines[..i].iter().find(|(p, ..)| device(p) == device(path))
        {
            let at = c.at(first_span.clone(), "", "");
            return Err(c.at(
                span.clone(),
                key.clone(),
                format!(
                    "{} is the serial device {first_key} = {:?} (line {}, column {}) already opens:                      one device is one port or one link",
                    path.display(),
                    first.display().to_string(),
                    at.line,
                    at.column
                ),
            ));
        }
    }

    // Two listeners on one address: the second bind fails at start-up.
    // Listeners on port 0 get distinct ports from the system.
    let mut by_place: Vec<_> = listeners.iter().collect();
    by_place.sort_by_key(|(_, span, _, _)| span.start);
    for (i, (addr, span, key, _)) in by_place.iter().enumerate() {
        if let Some((first, first_span, first_key, _)) = by_place[..i].iter().find(|(a, ..)| clash(a, addr)) {
            let line = match c.at(first_span.clone(), "", "").line {
                0 => "by default".to_owned(),
                n => format!("line {n}"),
            };
            return Err(c.at(
                span.clone(),
                key.clone(),
                format!(
                    "{addr} is already taken by {first_key} = {first} ({line}): each listener needs its own address"
                ),
            ));
        }
    }

    // A route goes to another GCU: a client is never a destination. A route
    // naming a listener reaches its newest live connection (a GCU that
    // dials in).
    let routable = |name: &Spanned<String>, key: &str| -> Result<String, ConfigError> {
        match links.iter().find(|l| &l.name == name.get_ref()) {
            None => Err(c.at(name.span(), key, format!("no link is named {:?}", name.get_ref()))),
            Some(l) if l.role == LinkRole::Client => Err(c.at(
                name.span(),
                key,
                format!(
                    "link {:?} has role \"client\"; routes go to a link to another GCU (role \
                     \"upstream\" or \"downstream\"); answers to clients follow the reverse path",
                    l.name
                ),
            )),
            Some(l) => Ok(l.name.clone()),
        }
    };
    let default_route = match &raw.gcu.default_route {
        Some(r) => Some(routable(r, "gcu.default_route")?),
        None => None,
    };
    let mut routes = Vec::new();
    let mut routed = BTreeSet::new();
    for (i, r) in raw.routes.iter().enumerate() {
        let key = format!("route[{i}]");
        let g: u8 = c.int(&r.group, &format!("{key}.group"), 0, 254)?;
        if g == group {
            return Err(c.at(
                r.group.span(),
                format!("{key}.group"),
                format!("group {g} is this GCU's own group"),
            ));
        }
        if !routed.insert(g) {
            return Err(c.at(
                r.group.span(),
                format!("{key}.group"),
                format!("group {g} has two routes"),
            ));
        }
        routes.push((g, routable(&r.link, &format!("{key}.link"))?));
    }

    let capture = match &raw.capture {
        Some(cap) => {
            let file = cap.file.get_ref().trim();
            if file.is_empty() {
                return Err(c.at(cap.file.span(), "capture.file", "expected a file path"));
            }
            const GIB: i64 = 1 << 30;
            let bytes = |v: &Option<Spanned<i64>>, key: &str| -> Result<Option<u64>, ConfigError> {
                v.as_ref().map(|v| c.int(v, key, 4096, 1024 * GIB)).transpose()
            };
            Some(CaptureSettings {
                file: PathBuf::from(file),
                enabled: cap.enabled.as_ref().is_none_or(|e| *e.get_ref()),
                rotate_bytes: bytes(&cap.rotate_bytes, "capture.rotate_bytes")?,
                rotate_count: match &cap.rotate_count {
                    Some(v) => c.int(v, "capture.rotate_count", 1, 1000)?,
                    None => 4,
                },
                budget_bytes: bytes(&cap.budget_bytes, "capture.budget_bytes")?,
            })
        }
        None => None,
    };

    // A GCU that can route nothing is a mistake, not a configuration:
    // commands come in over links only (devices never send one). Links
    // without ports may still route (a hub, by learned routes).
    if links.is_empty() {
        return Err(c.at(
            0..0,
            "",
            "routes nothing: no [[link]], so no command can reach this GCU \
             (add a `listen` link for clients, or a `serial`/`connect` link to another GCU)",
        ));
    }
    Ok(Config {
        file: c.file.to_owned(),
        group,
        name,
        serial,
        default_route,
        shutdown_grace_ms,
        log_level,
        metrics,
        metrics_allow_peers,
        queue_depth,
        max_connections,
        max_connections_per_peer,
        per_peer_cap_configured: raw.limits.max_connections_per_peer.is_some(),
        idle_timeout_ms,
        link_retries: link_base_retries,
        link_ack_timeout_ms: link_base_ack,
        delivery_timeout_ms,
        ports,
        links,
        routes,
        capture,
        warnings,
        listen_places: listeners.into_iter().map(|(addr, _, _, place)| (addr, place)).collect(),
        serial_places: serial_lines
            .into_iter()
            .map(|(path, span, key)| (path, c.place(span, &key)))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> ConfigError {
        parse(Path::new("t.toml"), text).expect_err("config should be refused")
    }

    /// The least a GCU needs to route: a group and one link.
    const MINIMAL: &str = "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n";

    #[test]
    fn minimal_config_gets_defaults_derived_from_the_baud() {
        let c = parse(Path::new("t.toml"), MINIMAL).unwrap();
        assert_eq!(c.group, 5);
        assert_eq!(c.name, "gcud");
        assert!(c.ports.is_empty());
        assert_eq!(c.queue_depth, 16);
        let t = default_timing(1200);
        assert!(t.ack_timeout_ms > default_timing(115200).ack_timeout_ms);
    }

    #[test]
    fn type_errors_are_in_words() {
        let e = err("[gcu]\ngroup = \"five\"\n");
        assert_eq!((e.key.as_str(), e.line, e.column), ("gcu.group", 2, 9), "{e}");
        assert_eq!(e.message, "expected an integer, found the string \"five\"");
        let e = err(&format!("{MINIMAL}[[port]]\nid = 1\nsimulate = 1\n"));
        assert_eq!(e.message, "expected a list [...], found the integer `1`", "{e}");
        let e = err("[gcu]\ngroup = 5\n[metrics]\nlisten = [\"a\"]\n");
        assert_eq!(e.message, "expected a string in quotes, found a list", "{e}");
    }

    #[test]
    fn a_gcu_without_links_routes_nothing_and_is_refused() {
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1]\n");
        assert!(e.message.starts_with("routes nothing: no [[link]]"), "{e}");
        // Links alone may route (a hub, by learned routes).
        parse(Path::new("t.toml"), MINIMAL).unwrap();
    }

    #[test]
    fn syntax_error_names_line_and_column() {
        let e = err("[gcu]\ngroup = 5\nname = \n");
        assert_eq!((e.line, e.file.to_str().unwrap()), (3, "t.toml"), "{e}");
    }

    #[test]
    fn unknown_key_is_named_with_its_line() {
        let e = err("[gcu]\ngroup = 5\n\n[[port]]\nid = 1\npath = \"/dev/x\"\nbauds = 9600\n");
        assert_eq!(e.line, 7, "{e}");
        assert!(e.message.contains("bauds"), "{e}");
    }

    #[test]
    fn wrong_type_names_the_key_path() {
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\nbaud = \"fast\"\n");
        assert_eq!(e.key, "port[0].baud", "{e}");
        assert_eq!(e.line, 6, "{e}");
    }

    #[test]
    fn out_of_range_values_say_what_was_expected() {
        let e = err("[gcu]\ngroup = 255\n");
        assert_eq!((e.key.as_str(), e.line), ("gcu.group", 2), "{e}");
        assert!(e.message.contains("1..=254"), "{e}");
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\nbaud = 9601\n");
        assert_eq!(e.key, "port[0].baud", "{e}");
        assert!(e.message.contains("115200"), "{e}");
    }

    #[test]
    fn duplicate_port_and_missing_transport_are_refused() {
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/a\"\n[[port]]\nid = 1\npath = \"/b\"\n");
        assert_eq!((e.key.as_str(), e.line), ("port[1].id", 7), "{e}");
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 2\n");
        assert_eq!(e.key, "port[0]", "{e}");
        assert!(e.message.contains("exactly one of"), "{e}");
    }

    #[test]
    fn one_serial_device_is_one_port_or_one_link() {
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\n[[port]]\nid = 2\npath = \"/dev/x\"\n");
        assert_eq!((e.key.as_str(), e.line, e.column), ("port[1].path", 8, 8), "{e}");
        assert!(
            e.message.contains("port[0].path") && e.message.contains("line 5, column 8"),
            "{e}"
        );
        let e = err(
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\n[[link]]\nname = \"up\"\nrole = \"upstream\"\nserial = \"/dev/x\"\n",
        );
        assert_eq!((e.key.as_str(), e.line), ("link[0].serial", 9), "{e}");
        assert!(e.message.contains("port[0].path"), "{e}");
    }

    #[test]
    fn routes_must_name_links() {
        let e = err("[gcu]\ngroup = 5\n[[route]]\ngroup = 7\nlink = \"nowhere\"\n");
        assert_eq!((e.key.as_str(), e.line), ("route[0].link", 5), "{e}");
        let e = err("[gcu]\ngroup = 5\ndefault_route = \"up\"\n");
        assert_eq!(e.key, "gcu.default_route", "{e}");
    }

    #[test]
    fn shipped_configs_are_valid() {
        for name in ["config/gcud.toml", "config/demo.toml"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(name);
            let c = load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(c.group, 5, "{name}");
        }
        let full = load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gcud.toml")).unwrap();
        // A device-server port: nothing is retransmitted into it, so the
        // shipped file sets no `retries` there ([port_defaults] retries = 3).
        assert_eq!(full.ports[1].timing.retries, 3);
        assert_eq!(full.ports[1].timing.baud, 19200);
        assert_eq!(full.routes, vec![(7, "gcu7".to_owned())]);
    }

    #[test]
    fn capture_section_is_optional_and_checked() {
        let c = parse(Path::new("t.toml"), MINIMAL).unwrap();
        assert_eq!(c.capture, None);
        let c = parse(
            Path::new("t.toml"),
            &format!("{MINIMAL}[capture]\nfile = \"/tmp/g.pcapng\"\nrotate_bytes = 1048576\n"),
        )
        .unwrap();
        let cap = c.capture.unwrap();
        assert_eq!(
            (cap.enabled, cap.rotate_bytes, cap.rotate_count),
            (true, Some(1 << 20), 4)
        );
        let e = err("[gcu]\ngroup = 5\n[capture]\nfile = \"x\"\nrotate_count = 0\n");
        assert_eq!((e.key.as_str(), e.line), ("capture.rotate_count", 5), "{e}");
        let e = err("[gcu]\ngroup = 5\n[capture]\nfile = \"x\"\nbudget_bytes = 10\n");
        assert_eq!(e.key, "capture.budget_bytes", "{e}");
        let e = err("[gcu]\ngroup = 5\n[capture]\nfil = \"x\"\n");
        assert!(e.message.contains("fil"), "{e}");
    }

    #[test]
    fn a_bare_port_listens_on_loopback() {
        let c = parse(
            Path::new("t.toml"),
            "[gcu]\ngroup = 5\n[metrics]\nlisten = \"9200\"\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"4001\"\n",
        )
        .unwrap();
        assert_eq!(
            c.links[0].transport,
            LinkTransport::Listen("127.0.0.1:4001".parse().unwrap())
        );
        assert_eq!(c.metrics, Some("127.0.0.1:9200".parse().unwrap()));
    }

    #[test]
    fn routes_to_clients_are_refused_and_to_gcu_listeners_taken() {
        let e = err(
            "[gcu]\ngroup = 5\ndefault_route = \"c\"\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"127.0.0.1:1\"\n",
        );
        assert_eq!((e.key.as_str(), e.line), ("gcu.default_route", 3), "{e}");
        assert!(e.message.contains("role \"client\""), "{e}");
        let e = err(
            "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nconnect = \"127.0.0.1:1\"\n[[route]]\ngroup = 7\nlink = \"c\"\n",
        );
        assert_eq!((e.key.as_str(), e.line), ("route[0].link", 9), "{e}");
        let c = parse(
            Path::new("t.toml"),
            "[gcu]\ngroup = 5\n[[link]]\nname = \"field\"\nrole = \"downstream\"\nlisten = \"127.0.0.1:1\"\n[[route]]\ngroup = 7\nlink = \"field\"\n",
        )
        .expect("a route may name a GCU listener");
        assert_eq!(c.routes, vec![(7, "field".to_owned())]);
    }

    #[test]
    fn log_filters_name_levels_or_targets_that_cannot_be_misspelt_levels() {
        for ok in [
            "info",
            "WARN,gcud=debug",
            "sagebrush_gcu",
            "gcud::io=trace",
            "[conn]",
            "gcud[conn{peer=a}]=debug",
            "info,",
        ] {
            assert_eq!(check_log_filter(ok), Ok(()), "{ok:?}");
        }
        for bad in [
            "wran",
            "gcud",
            "info,gcud=wran",
            "gcud=",
            "gcud=3",
            "[conn]=x",
            "",
            " , ",
        ] {
            assert!(check_log_filter(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn listeners_clash_on_one_port_of_one_or_every_address() {
        let a = |s: &str| s.parse::<SocketAddr>().unwrap();
        assert!(clash(&a("127.0.0.1:1"), &a("127.0.0.1:1")));
        assert!(clash(&a("0.0.0.0:1"), &a("127.0.0.1:1")));
        assert!(clash(&a("[::1]:1"), &a("[::]:1")));
        assert!(clash(&a("127.0.0.1:1"), &a("[::]:1")));
        assert!(!clash(&a("0.0.0.0:1"), &a("[::1]:1")));
        assert!(!clash(&a("127.0.0.1:1"), &a("127.0.0.1:2")));
        assert!(!clash(&a("127.0.0.1:1"), &a("127.0.0.2:1")));
        assert!(!clash(&a("127.0.0.1:0"), &a("127.0.0.1:0")));
    }

    #[test]
    fn listener_defaults_to_loopback_peers_only() {
        let c = parse(
            Path::new("t.toml"),
            "[gcu]\ngroup = 5\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:4001\"\n",
        )
        .unwrap();
        assert_eq!(c.links[0].allow_peers, loopback());
        assert_eq!(c.links[0].allow_peers.to_string(), "127.0.0.1, ::1");
        let e = err(
            "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"0.0.0.0:1\"\nallow_peers = [\"10.0.0.300\"]\n",
        );
        assert_eq!(e.key, "link[0].allow_peers[0]", "{e}");
    }

    #[test]
    fn allow_peers_take_addresses_and_networks() {
        let c = parse(
            Path::new("t.toml"),
            "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"0.0.0.0:1\"\n\
             allow_peers = [\"10.0.0.0/8\", \"192.168.1.0/24\", \"fd00::/8\", \"172.16.0.9\", \"::1\"]\n",
        )
        .unwrap();
        let allow = &c.links[0].allow_peers;
        let ip = |s: &str| s.parse::<IpAddr>().unwrap();
        for inside in [
            "10.0.0.1",
            "10.255.255.255",
            "192.168.1.77",
            "fd12:3456::1",
            "172.16.0.9",
            "::1",
            "::ffff:10.9.8.7",
        ] {
            assert!(allow.contains(&ip(inside)), "{inside} should be allowed");
        }
        for outside in ["11.0.0.1", "192.168.2.1", "fe80::1", "172.16.0.10", "127.0.0.1", "::2"] {
            assert!(!allow.contains(&ip(outside)), "{outside} should be refused");
        }
        assert_eq!(
            allow.to_string(),
            "10.0.0.0/8, 192.168.1.0/24, fd00::/8, 172.16.0.9, ::1"
        );

        for (entry, message) in [
            ("10.0.0.0/33", "expected a network ADDRESS/PREFIX"),
            ("fd00::/129", "expected a network ADDRESS/PREFIX"),
            ("10.0.0/8", "expected a network ADDRESS/PREFIX"),
            ("10.0.0.0/", "expected a network ADDRESS/PREFIX"),
            (
                "10.1.2.3/8",
                "has bits set past its /8 prefix: write the network, 10.0.0.0/8",
            ),
            ("10.0.0.300", "expected an IP address, found \"10.0.0.300\""),
        ] {
            let e = err(&format!(
                "[gcu]\ngroup = 5\n[metrics]\nallow_peers = [\"127.0.0.1\", \"{entry}\"]\n"
            ));
            assert_eq!(e.key, "metrics.allow_peers[1]", "{entry}: {e}");
            assert!(e.to_string().contains(message), "{entry}: {e}");
            assert!(e.to_string().contains(":4:29:"), "{entry}: {e}");
        }
    }
}
