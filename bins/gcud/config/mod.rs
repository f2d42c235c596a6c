//! `gcud --config FILE`: the TOML configuration, one module per section.
//! A setting is typed where it is declared (`sagebrush_service::config_file`'s
//! `Int`, `Millis` and `Baud` carry its range and default and are checked
//! as the file is parsed), so every error names the file, the line and
//! column, the key and what was expected (`gcud --check` prints them and
//! exits 2); what spans several settings is checked after, in the section's
//! module, and what spans sections (one serial device opened twice, two
//! listeners on one address, a GCU without links) here.
//!
//! The validated [`Config`] is nested by section: a reload (module
//! `reload`) compares sections and names the keys that changed from their
//! types. It holds the router core's own types where the core takes them
//! (`PortConfig`, `LinkKind`, `LinkSettings`): [`Config::router_config`]
//! copies nothing field by field.

mod capture;
mod gcu;
mod govern;
mod limits;
mod link;
mod log;
mod metrics;
mod net;
mod port;
mod principal;
mod route;

use std::net::SocketAddr;
use std::ops::Range;
use std::path::{Path, PathBuf};

use sagebrush_gcu::{Governance, LinkId, RouterConfig};
use sagebrush_service::config_file::Source;
use sagebrush_service::endpoint::listeners_clash;
use serde::Deserialize;

pub use capture::CaptureSettings;
pub use gcu::GcuSection;
pub use govern::ControlSection;
pub use limits::LimitsSection;
pub use link::{Link, LinkTimingSection, LinkTransport};
pub use log::LogSection;
pub use metrics::Metrics;
pub use net::PeerAllowList;
pub use port::{Port, PortTransport};
pub use principal::LinkTls;
pub use route::Routes;
pub use sagebrush_service::config_file::ConfigError;

/// The whole file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    gcu: GcuSection,
    #[serde(default)]
    log: LogSection,
    metrics: Option<metrics::MetricsSection>,
    #[serde(default)]
    limits: LimitsSection,
    #[serde(default)]
    port_defaults: port::PortSettings,
    #[serde(default)]
    link_timing: LinkTimingSection,
    #[serde(default, rename = "port")]
    ports: Vec<port::PortSection>,
    #[serde(default, rename = "link")]
    links: Vec<link::LinkSection>,
    #[serde(default, rename = "route")]
    routes: Vec<route::RouteSection>,
    capture: Option<capture::CaptureSection>,
    #[serde(default)]
    control: ControlSection,
    #[serde(default, rename = "gimbal")]
    gimbals: Vec<govern::GimbalSection>,
    #[serde(default, rename = "tour")]
    tours: Vec<govern::TourSection>,
    #[serde(default, rename = "principal")]
    principals: Vec<principal::PrincipalSection>,
}

/// The validated configuration, by section.
#[derive(Debug, Clone)]
pub struct Config {
    pub file: PathBuf,
    pub gcu: GcuSection,
    pub log: LogSection,
    /// `[metrics]`, if configured.
    pub metrics: Option<Metrics>,
    pub limits: LimitsSection,
    pub link_timing: LinkTimingSection,
    pub ports: Vec<Port>,
    pub links: Vec<Link>,
    pub routes: Routes,
    /// `[capture]`, if configured.
    pub capture: Option<CaptureSettings>,
    /// `[control]`, `[[gimbal]]` and `[[tour]]` (ARCHITECTURE "Governance").
    pub governance: Governance,
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
    /// The router core's configuration: the ports' and links' settings as
    /// validated, routes to the links `link_id` names.
    pub fn router_config(&self, mut link_id: impl FnMut(&str) -> LinkId) -> RouterConfig {
        let mut rc = RouterConfig::new(self.gcu.group.get());
        rc.name = self.gcu.name.get().to_owned();
        rc.serial = self.gcu.serial.get().to_owned();
        rc.ports = self.ports.iter().map(|p| p.router.clone()).collect();
        rc.links = self.link_timing.router();
        for link in &self.links {
            link_id(&link.name);
        }
        for (group, name) in &self.routes.table {
            rc.static_routes.insert(*group, link_id(name));
        }
        rc.default_upstream = self.routes.default.as_deref().map(link_id);
        rc.governance = self.governance.clone();
        rc
    }

    /// Every gimbal the file names, as (port, device): the devices of a
    /// `simulate` port, each `[[gimbal]]` and each `[[tour]]`'s. `/status`
    /// lists them from the start, before they answer (ARCHITECTURE
    /// "Device registry and status").
    pub fn configured_devices(&self) -> std::collections::BTreeSet<(u8, u8)> {
        let simulated = self.ports.iter().flat_map(|p| match &p.transport {
            PortTransport::Simulated(ids) => ids.iter().map(|&d| (p.id, d)).collect(),
            _ => Vec::new(),
        });
        let governed = self.governance.gimbals.iter().map(|g| (g.port, g.device));
        let toured = self.governance.tours.iter().map(|t| (t.port, t.device));
        simulated.chain(governed).chain(toured).collect()
    }

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
    /// now (`config_file::absent_serial_devices`).
    pub fn probe_serial_paths(&self) -> Vec<String> {
        sagebrush_service::config_file::absent_serial_devices(&self.serial_places, "gcud")
    }
}

/// What the sections' checks gather for the checks across sections.
#[derive(Debug, Default)]
struct Checks {
    warnings: Vec<String>,
    /// Every TCP listener: address, span, key and place.
    listeners: Vec<(SocketAddr, Range<usize>, String, String)>,
    /// Every serial device a port or link opens: path, span and key.
    serial_lines: Vec<(PathBuf, Range<usize>, String)>,
}

impl Checks {
    /// Notes a listener at `span`; returns its place, `FILE:LINE:COLUMN: KEY`.
    fn listener(&mut self, c: &Source<'_>, addr: SocketAddr, span: Range<usize>, key: &str) -> String {
        let place = c.place(span.clone(), key);
        self.listeners.push((addr, span, key.to_owned(), place.clone()));
        place
    }

    fn serial(&mut self, path: PathBuf, span: Range<usize>, key: String) {
        self.serial_lines.push((path, span, key));
    }

    /// One serial device opened twice: two lines would read each other's
    /// bytes. Paths are compared as the system resolves them
    /// (`/dev/serial/by-id/...` is a link to `/dev/ttyUSB0`).
    fn serial_devices_once(&self, c: &Source<'_>) -> Result<(), ConfigError> {
        let lines = &self.serial_lines;
        let device = |path: &Path| std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned());
        for (i, (path, span, key)) in lines.iter().enumerate() {
            if let Some((first, first_span, first_key)) = lines[..i].iter().find(|(p, ..)| device(p) == device(path)) {
                let at = c.at(first_span.clone(), "", "");
                return Err(c.at(
                    span.clone(),
                    key.clone(),
                    format!(
                        "{} is the serial device {first_key} = {:?} (line {}, column {}) already opens: one device is one port or one link",
                        path.display(),
                        first.display().to_string(),
                        at.line,
                        at.column
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Two listeners on one address: the second bind fails at start-up.
    /// Listeners on port 0 get distinct ports from the system.
    fn listeners_apart(&self, c: &Source<'_>) -> Result<(), ConfigError> {
        let mut by_place: Vec<_> = self.listeners.iter().collect();
        by_place.sort_by_key(|(_, span, _, _)| span.start);
        for (i, (addr, span, key, _)) in by_place.iter().enumerate() {
            if let Some((first, first_span, first_key, _)) =
                by_place[..i].iter().find(|(a, ..)| listeners_clash(a, addr))
            {
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
        Ok(())
    }
}

/// Reads (bounded: `sagebrush_service::config_file::read`) and validates `file`.
pub fn load(file: &Path) -> Result<Config, ConfigError> {
    let text = sagebrush_service::config_file::read(file)?;
    parse(file, &text)
}

/// Parses and validates configuration `text` read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Config, ConfigError> {
    let c = Source::new(file, text);
    let raw: ConfigFile = c.deserialize()?;
    validate(&c, raw)
}

/// The checks that span settings or sections, in the order of the file's
/// sections.
fn validate(c: &Source<'_>, raw: ConfigFile) -> Result<Config, ConfigError> {
    let mut checks = Checks::default();
    raw.limits.validate(c)?;
    let metrics = raw.metrics.as_ref().map(|m| m.validate(c, &mut checks)).transpose()?;
    let ports = port::validate(
        c,
        &raw.port_defaults,
        &raw.ports,
        &raw.link_timing,
        raw.limits.port_queue_bound(),
        &mut checks,
    )?;
    let links = link::validate(c, &raw.links, raw.gcu.group.get(), &mut checks)?;
    checks.serial_devices_once(c)?;
    checks.listeners_apart(c)?;
    let routes = route::validate(
        c,
        raw.gcu.group.get(),
        raw.gcu.default_route.as_ref(),
        &raw.routes,
        &links,
    )?;
    let capture = raw.capture.as_ref().map(|cap| cap.validate(c)).transpose()?;
    let mut governance = govern::validate(c, &raw.control, &raw.gimbals, &raw.tours, raw.gcu.group.get(), &ports)?;
    governance.principals = principal::validate(c, &raw.principals, &links)?;
    // Tours are started and stopped by the highest links unless `[control]` says otherwise.
    governance.tours_min_priority = governance
        .tours_min_priority
        .or_else(|| links.iter().map(|l| l.priority).max());

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
    let Checks {
        warnings,
        listeners,
        serial_lines,
    } = checks;
    Ok(Config {
        file: c.file.to_owned(),
        gcu: raw.gcu,
        log: raw.log,
        metrics,
        limits: raw.limits,
        link_timing: raw.link_timing,
        ports,
        links,
        routes,
        capture,
        governance,
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
    use net::loopback;
    use std::net::IpAddr;

    fn err(text: &str) -> ConfigError {
        parse(Path::new("t.toml"), text).expect_err("config should be refused")
    }

    /// The least a GCU needs to route: a group and one link.
    const MINIMAL: &str = "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n";

    #[test]
    fn minimal_config_gets_defaults_derived_from_the_baud() {
        let c = parse(Path::new("t.toml"), MINIMAL).unwrap();
        assert_eq!(c.gcu.group.get(), 5);
        assert_eq!(c.gcu.name.get(), "gcud");
        assert!(c.ports.is_empty());
        assert_eq!(c.limits.queue_depth.get(), 16);
        let port = |baud: u32| {
            let text = format!("{MINIMAL}[[port]]\nid = 1\nsimulate = [1]\nbaud = {baud}\n");
            parse(Path::new("t.toml"), &text).unwrap().ports[0].router.clone()
        };
        assert!(port(1200).ack_timeout > port(115200).ack_timeout);
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
    fn a_ports_duplex_is_half_unless_it_says_full() {
        let text = |duplex: &str| {
            format!(
                "{MINIMAL}[port_defaults]\n{duplex}\n[[port]]\nid = 1\npath = \"/dev/a\"\n[[port]]\nid = 2\npath = \"/dev/b\"\nduplex = \"half\"\n"
            )
        };
        let c = parse(Path::new("t.toml"), &text("")).unwrap();
        assert!(c.ports.iter().all(|p| !p.router.full_duplex));
        let c = parse(Path::new("t.toml"), &text("duplex = \"full\"")).unwrap();
        let full: Vec<bool> = c.ports.iter().map(|p| p.router.full_duplex).collect();
        assert_eq!(full, [true, false], "a port's own setting wins");
        let e = err(&text("duplex = \"simplex\""));
        assert_eq!((e.key.as_str(), e.line), ("port_defaults.duplex", 8), "{e}");
        assert_eq!(e.message, "unknown variant `simplex`, expected `half` or `full`");
    }

    #[test]
    fn a_nic_window_that_outlasts_the_delivery_time_out_is_refused_where_it_is_set() {
        let text = |defaults: &str, own: &str, timing: &str| {
            format!(
                "{MINIMAL}[port_defaults]\nack_timeout_ms = 100\n{defaults}\n[[port]]\nid = 3\npath = \"/dev/a\"\n{own}\n[link_timing]\n{timing}\n"
            )
        };
        let warnings = |text: &str| parse(Path::new("t.toml"), text).unwrap().warnings;
        // 699 + 100 is below the default 800 ms.
        assert_eq!(warnings(&text("nic_window_ms = 699", "", "")), Vec::<String>::new());
        // 700 + 100 reaches it: an ACK that takes its whole time-out comes too late.
        let w = warnings(&text("nic_window_ms = 700", "", ""));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("t.toml:9:"), "{w:?}");
        assert!(
            w[0].contains("port_defaults.nic_window_ms: port 3: its NIC window (700 ms) leaves less"),
            "{w:?}"
        );
        // The window alone reaches it: refused.
        let e = err(&text("nic_window_ms = 800", "", ""));
        assert_eq!((e.key.as_str(), e.line), ("port_defaults.nic_window_ms", 9), "{e}");
        assert!(e.message.starts_with("port 3: its NIC window (800 ms) reaches"), "{e}");
        assert!(e.message.contains("delivery_timeout_ms (800 ms)"), "{e}");
        let e = err(&text("nic_window_ms = 10", "nic_window_ms = 1000", ""));
        assert_eq!((e.key.as_str(), e.line), ("port[0].nic_window_ms", 13), "{e}");
        assert!(warnings(&text("", "nic_window_ms = 1000", "delivery_timeout_ms = 1101")).is_empty());
        // The window set nowhere (35 ms at 9600 bit/s): the time-out is what the file says.
        let w = warnings(&text("", "", "delivery_timeout_ms = 120"));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("t.toml:15:"), "{w:?}");
        assert!(
            w[0].contains("link_timing.delivery_timeout_ms: port 3: its NIC window (35 ms)"),
            "{w:?}"
        );
    }

    #[test]
    fn a_link_role_is_one_of_the_router_cores_kinds() {
        let e = err("[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"sideways\"\nlisten = \"127.0.0.1:0\"\n");
        assert_eq!((e.key.as_str(), e.line), ("link[0].role", 5), "{e}");
        assert_eq!(
            e.message,
            "unknown variant `sideways`, expected one of `upstream`, `downstream`, `client`"
        );
    }

    #[test]
    fn one_serial_device_is_one_port_or_one_link() {
        let e = err("[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\n[[port]]\nid = 2\npath = \"/dev/x\"\n");
        assert_eq!((e.key.as_str(), e.line, e.column), ("port[1].path", 8, 8), "{e}");
        assert!(
            e.message.contains("port[0].path") && e.message.contains("line 5, column 8"),
            "{e}"
        );
        assert_eq!(
            e.message,
            "/dev/x is the serial device port[0].path = \"/dev/x\" (line 5, column 8) already opens: \
             one device is one port or one link"
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
            assert_eq!(c.gcu.group.get(), 5, "{name}");
        }
        let full = load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gcud.toml")).unwrap();
        // A device-server port: nothing is retransmitted into it, so the
        // shipped file sets no `retries` there ([port_defaults] retries = 3).
        assert_eq!(full.ports[1].router.retries, 3);
        assert_eq!(full.ports[1].baud(), 19200);
        assert_eq!(full.routes.table, vec![(7, "gcu7".to_owned())]);
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
        assert_eq!(c.metrics.map(|m| m.listen), Some("127.0.0.1:9200".parse().unwrap()));
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
        assert_eq!(c.routes.table, vec![(7, "field".to_owned())]);
    }

    #[test]
    fn places_to_connect_to_are_host_port_errors_naming_the_text() {
        let link = |to: &str| {
            err(&format!(
                "[gcu]\ngroup = 5\n[[link]]\nname = \"up\"\nrole = \"upstream\"\nconnect = {to:?}\n"
            ))
        };
        assert_eq!(
            link("gcu-1").to_string(),
            "t.toml:6:11: link[0].connect: expected HOST:PORT to connect to: \"gcu-1\" has no port"
        );
        assert!(
            link("::1:4001").message.contains("out of brackets"),
            "an IPv6 host goes in brackets"
        );
        let port = |tcp: &str| err(&format!("[gcu]\ngroup = 5\n[[port]]\nid = 1\ntcp = {tcp:?}\n"));
        assert_eq!(
            port("moxa:0").to_string(),
            "t.toml:5:7: port[0].tcp: expected HOST:PORT of a TCP device server: \"moxa:0\" has port \"0\", not 1..=65535"
        );
        assert!(port("mo xa:4001").message.contains("host \"mo xa\""));
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
