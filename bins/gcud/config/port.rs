//! `[port_defaults]` and `[[port]]`: the device buses and the timing of
//! their transactions, validated into the router core's [`PortConfig`].

use std::path::PathBuf;

use sagebrush_gcu::PortConfig;
use sagebrush_service::config_file::{Baud, Int, Millis, Source};
use serde::Deserialize;
use toml::Spanned;

use super::{Checks, ConfigError, LinkTimingSection};

/// Declares the per-port settings, each once: its key, its type (the range
/// in the type; where no file gives it, the router core's default for the
/// port's rate, [`PortConfig::at_rate`]) and the [`PortConfig`] field it
/// sets. `[port_defaults]` and every `[[port]]` take them all (inline in
/// `[[port]]`: serde's `flatten` would lose the places errors need).
macro_rules! port_settings {
    ($( $(#[doc = $doc:literal])* $key:ident: $type:ty => $field:ident, )*) => {
        /// `[port_defaults]`: settings for every `[[port]]` that does not
        /// give its own.
        #[derive(Debug, Default, Clone, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(super) struct PortSettings {
            $( $(#[doc = $doc])* $key: Option<$type>, )*
        }

        /// `[[port]]`: a device bus, with its own settings.
        #[derive(Debug, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(super) struct PortSection {
            /// Port address 1..=254 (Table 2).
            id: Int<u8, 1, 254>,
            /// A serial device, e.g. `/dev/ttyUSB0` or a udev name `/dev/gimbal-bus-1`.
            path: Option<Spanned<String>>,
            /// A TCP device server (ser2net) `host:port` instead of a local line.
            tcp: Option<Spanned<String>>,
            /// Simulated gimbals with these device addresses, in-process (demo, tests).
            simulate: Option<Spanned<Vec<Int<u8, 1, 254>>>>,
            $( $(#[doc = $doc])* $key: Option<$type>, )*
        }

        impl PortSection {
            fn settings(&self) -> PortSettings {
                PortSettings { $( $key: self.$key.clone(), )* }
            }
        }

        impl PortSettings {
            /// Each setting given here, written over `port`.
            fn apply(&self, port: &mut PortConfig) {
                $( if let Some(v) = &self.$key { port.$field = v.get(); } )*
            }
        }
    };
}

port_settings! {
    /// Line rate, one of Table 4's (1.5.1); the time-outs not given are
    /// derived from it. A port's own `baud` starts it from the defaults of
    /// its rate, not from `[port_defaults]`.
    baud: Baud => bps,
    /// Retransmissions after the first write when no ACK (or a NAK) comes.
    retries: Int<u8, 0, 20> => retries,
    /// Wait for ACK/NAK after a write: 10 ms to 10 s.
    ack_timeout_ms: Millis<10, 10_000> => ack_timeout,
    /// Wait for the result of a query after its ACK: 10 ms to 1 minute.
    result_timeout_ms: Millis<10, 60_000> => result_timeout,
    /// Wait for the result of `IX`: 1 s to 10 minutes.
    long_result_timeout_ms: Millis<1_000, 600_000> => long_result_timeout,
    /// After the ACK of a command without result, wait for a NIC: 1 ms to 10 s.
    nic_window_ms: Millis<1, 10_000> => nic_window,
    /// Quiet time after a write to device 255: 1 ms to 10 s.
    broadcast_guard_ms: Millis<1, 10_000> => broadcast_guard,
    /// `full`: gcud may write while a device answers, so the next command
    /// to a device goes in the NIC window of the one before (RS-232 point
    /// to point, RS-422, four-wire RS-485); `half` (default): a two-wire
    /// RS-485 bus, where it would collide with a `?`.
    duplex: Duplex => full_duplex,
}

/// `duplex`: whether gcud may write while a device answers.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum Duplex {
    #[default]
    Half,
    Full,
}

impl Duplex {
    /// [`PortConfig::full_duplex`].
    fn get(&self) -> bool {
        *self == Duplex::Full
    }
}

/// Where a port's bytes come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PortTransport {
    Serial(PathBuf),
    Tcp(String),
    Simulated(Vec<u8>),
}

/// One `[[port]]`, validated: its transport, and the router core's
/// configuration of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Port {
    pub id: u8,
    pub transport: PortTransport,
    pub router: PortConfig,
}

impl Port {
    /// The line rate the port opens at, bit/s.
    pub fn baud(&self) -> u32 {
        self.router.bps
    }
}

/// Every `[[port]]`: ids unique, exactly one transport, the settings
/// resolved (the port's own, else `[port_defaults]`'s, else the core's
/// default for the rate), waiting commands up to `queue_bound`.
pub(super) fn validate(
    c: &Source<'_>,
    defaults: &PortSettings,
    raw: &[PortSection],
    link_timing: &LinkTimingSection,
    queue_bound: usize,
    checks: &mut Checks,
) -> Result<Vec<Port>, ConfigError> {
    if raw.len() > 254 {
        return Err(c.at(raw[254].id.span(), "port", "a GCU has at most 254 ports (1.3)"));
    }
    let mut ports: Vec<Port> = Vec::with_capacity(raw.len());
    for (i, p) in raw.iter().enumerate() {
        let key = format!("port[{i}]");
        let id = p.id.get();
        if ports.iter().any(|other| other.id == id) {
            return Err(c.at(
                p.id.span(),
                format!("{key}.id"),
                format!("port {id} is configured twice"),
            ));
        }
        let transport = match (&p.path, &p.tcp, &p.simulate) {
            (Some(path), None, None) => {
                checks.serial(PathBuf::from(path.get_ref()), path.span(), format!("{key}.path"));
                PortTransport::Serial(PathBuf::from(path.get_ref()))
            }
            (None, Some(addr), None) => {
                PortTransport::Tcp(c.host_port(addr, &format!("{key}.tcp"), " of a TCP device server")?)
            }
            (None, None, Some(devices)) => {
                let mut ids: Vec<u8> = Vec::new();
                for (j, d) in devices.get_ref().iter().enumerate() {
                    if ids.contains(&d.get()) {
                        return Err(c.at(
                            d.span(),
                            format!("{key}.simulate[{j}]"),
                            format!("device {} is listed twice", d.get()),
                        ));
                    }
                    ids.push(d.get());
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
        let own = p.settings();
        let baud = own
            .baud
            .clone()
            .or_else(|| defaults.baud.clone())
            .unwrap_or_default()
            .get();
        let mut router = PortConfig::at_rate(id, baud);
        if own.baud.is_none() {
            defaults.apply(&mut router);
        }
        own.apply(&mut router);
        window_within_delivery(c, &key, (&own, defaults), &router, link_timing, checks)?;
        router.queue_bound = queue_bound;
        if let PortTransport::Simulated(devices) = &transport {
            router.devices = Some(devices.clone());
        }
        router.buffered = matches!(transport, PortTransport::Tcp(_));
        ports.push(Port { id, transport, router });
    }
    Ok(ports)
}

/// A command queued behind another to the same port waits out that one's
/// NIC window, then its own ACK, all within `delivery_timeout_ms` (the
/// direction a door chains after its speed, ARCHITECTURE "Delivery
/// contract"). A window that reaches the time-out by itself would have
/// every such command expire unsent (`0C`): refused, naming the window
/// where the file sets it. One that leaves less than the port's ACK
/// time-out: a warning.
fn window_within_delivery(
    c: &Source<'_>,
    key: &str,
    (own, defaults): (&PortSettings, &PortSettings),
    port: &PortConfig,
    link_timing: &LinkTimingSection,
    checks: &mut Checks,
) -> Result<(), ConfigError> {
    let delivery = &link_timing.delivery_timeout_ms;
    if port.nic_window + port.ack_timeout < delivery.get() {
        return Ok(());
    }
    let (span, at) = match (&own.nic_window_ms, &defaults.nic_window_ms) {
        (Some(w), _) => (w.span(), format!("{key}.nic_window_ms")),
        (None, Some(w)) => (w.span(), "port_defaults.nic_window_ms".to_owned()),
        (None, None) => (delivery.span(), "link_timing.delivery_timeout_ms".to_owned()),
    };
    let consequence = "a command waiting behind another to this port (a direction chained after its speed)";
    let fix = "shorten nic_window_ms or lengthen delivery_timeout_ms";
    if port.nic_window >= delivery.get() {
        return Err(c.at(
            span,
            at,
            format!(
                "port {}: its NIC window ({} ms) reaches [link_timing] delivery_timeout_ms ({} ms): \
                 {consequence} would always expire before it is written (0C); {fix}",
                port.id,
                port.nic_window,
                delivery.get()
            ),
        ));
    }
    // An ACK time-out that reaches the delivery time-out by itself is no
    // matter of the window.
    if port.ack_timeout >= delivery.get() {
        return Ok(());
    }
    checks.warnings.push(format!(
        "{}: port {}: its NIC window ({} ms) leaves less than its ACK time-out ({} ms) before \
         [link_timing] delivery_timeout_ms ({} ms): {consequence} may expire before it is \
         acknowledged (0C); {fix}",
        c.place(span, &at),
        port.id,
        port.nic_window,
        port.ack_timeout,
        delivery.get()
    ));
    Ok(())
}
