//! Endpoint addresses, parsed in one place for gcud, every door and the
//! command lines: [`HostPort`], a place to connect to (gcud's client
//! listener, a TCP device server, a GCU upstream, a ground station), and
//! [`listen_address`], an address to bind. The host of a `HOST:PORT` is
//! an IP address, an IPv6 one in brackets (RFC 3986 3.2.2), or a host
//! name (RFC 1123 2.1: dot-separated labels of letters, digits and
//! hyphens); every error names the text it refuses and why.
//!
//! A serial device is a path, taken as written; whether it exists is
//! `--check`'s warning ([`crate::config_file::absent_serial_devices`]).

use std::fmt;
use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::str::FromStr;

/// The host of a [`HostPort`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Host {
    Ip(IpAddr),
    Name(String),
}

/// `HOST:PORT` of a place to connect to: a port 1..=65535.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HostPort {
    pub host: Host,
    pub port: u16,
}

/// Why a text is not an endpoint address; its display names the text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AddressError {
    /// The text refused, as given.
    pub input: String,
    /// What is wrong with it, in words.
    pub why: String,
}

impl fmt::Display for AddressError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?} {}", self.input, self.why)
    }
}

impl std::error::Error for AddressError {}

impl fmt::Display for HostPort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.host {
            Host::Ip(IpAddr::V6(ip)) => write!(f, "[{ip}]:{}", self.port),
            Host::Ip(IpAddr::V4(ip)) => write!(f, "{ip}:{}", self.port),
            Host::Name(name) => write!(f, "{name}:{}", self.port),
        }
    }
}

impl FromStr for HostPort {
    type Err = AddressError;

    /// `HOST:PORT` with a port 1..=65535 (port 0 names no place to connect to).
    fn from_str(text: &str) -> Result<Self, AddressError> {
        let error = |why: String| AddressError {
            input: text.to_owned(),
            why,
        };
        let (host, port) = split(text).map_err(error)?;
        let port = match port.parse::<u16>() {
            Ok(p) if p > 0 && port.bytes().all(|b| b.is_ascii_digit()) => p,
            _ => return Err(error(format!("has port {port:?}, not 1..=65535"))),
        };
        let host = match host.parse::<IpAddr>() {
            Ok(ip) => Host::Ip(ip),
            Err(_) if host_name(host) => Host::Name(host.to_owned()),
            Err(_) => {
                return Err(error(format!(
                    "has host {host:?}, neither an IP address nor a host name (letters, digits, hyphens and dots)"
                )));
            }
        };
        Ok(HostPort { host, port })
    }
}

/// `IP:PORT` to listen on (an IPv6 address in brackets); port 0 asks the
/// system for a free one. A name is refused: a listener binds an address.
pub fn listen_address(text: &str) -> Result<SocketAddr, AddressError> {
    let error = |why: String| AddressError {
        input: text.to_owned(),
        why,
    };
    let (host, port) = split(text).map_err(error)?;
    let port = match port.parse::<u16>() {
        Ok(p) if port.bytes().all(|b| b.is_ascii_digit()) => p,
        _ => return Err(error(format!("has port {port:?}, not 0..=65535"))),
    };
    match host.parse::<IpAddr>() {
        Ok(ip) => Ok(SocketAddr::new(ip, port)),
        Err(_) => Err(error(format!(
            "has host {host:?}, not an IP address (a listener binds an address, e.g. 0.0.0.0 or 127.0.0.1)"
        ))),
    }
}

/// A clap value parser of a `HOST:PORT` argument (`gimbalctl --tcp`): the
/// text as given, once it is one.
pub fn host_port_arg(text: &str) -> Result<String, String> {
    text.parse::<HostPort>()
        .map(|_| text.to_owned())
        .map_err(|e| format!("{e}: expected HOST:PORT, e.g. 127.0.0.1:4001"))
}

/// A clap value parser of an `IP:PORT` argument to listen on (`gimbalsim --tcp`).
pub fn listen_arg(text: &str) -> Result<SocketAddr, String> {
    listen_address(text).map_err(|e| format!("{e}: expected IP:PORT, e.g. 127.0.0.1:0"))
}

/// Whether listeners on `a` and `b` cannot both bind: the same port (not 0)
/// on the same address, or one of them on the unspecified address that
/// covers the other (`0.0.0.0` covers IPv4, `::` covers both on Linux).
pub fn listeners_clash(a: &SocketAddr, b: &SocketAddr) -> bool {
    let covers = |x: IpAddr, y: IpAddr| x.is_unspecified() && (x.is_ipv6() || y.is_ipv4());
    a.port() == b.port() && a.port() != 0 && (a.ip() == b.ip() || covers(a.ip(), b.ip()) || covers(b.ip(), a.ip()))
}

/// The host and port texts of `HOST:PORT`, the brackets of an IPv6 host
/// taken off; or why there are none.
fn split(text: &str) -> Result<(&str, &str), String> {
    if let Some(rest) = text.strip_prefix('[') {
        let Some((ip, after)) = rest.split_once(']') else {
            return Err("has no closing ] after its IPv6 address".into());
        };
        if ip.parse::<Ipv6Addr>().is_err() {
            return Err(format!("has {ip:?} in brackets, not an IPv6 address"));
        }
        return match after.strip_prefix(':') {
            Some(port) => Ok((ip, port)),
            None => Err("has no port after its IPv6 address".into()),
        };
    }
    let Some((host, port)) = text.rsplit_once(':') else {
        return Err("has no port".into());
    };
    if host.contains(':') {
        return Err("has an IPv6 address out of brackets (write [::1]:4001)".into());
    }
    if host.is_empty() {
        return Err("has no host before its port".into());
    }
    Ok((host, port))
}

/// A host name (RFC 1123 2.1): labels of 1..=63 letters, digits and
/// hyphens, not starting or ending with a hyphen, 253 characters at most.
pub fn host_name(name: &str) -> bool {
    let label = |l: &str| {
        !l.is_empty()
            && l.len() <= 63
            && !l.starts_with('-')
            && !l.ends_with('-')
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
    };
    !name.is_empty() && name.len() <= 253 && name.split('.').all(label)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(text: &str) -> String {
        let e = text.parse::<HostPort>().expect_err(text);
        assert_eq!(e.input, text);
        let shown = e.to_string();
        assert!(shown.starts_with(&format!("{text:?} ")), "{shown} names {text:?}");
        shown
    }

    #[test]
    fn hosts_are_addresses_bracketed_ipv6_or_names() {
        let ok = |text: &str| text.parse::<HostPort>().expect(text);
        assert_eq!(ok("127.0.0.1:4001").host, Host::Ip([127, 0, 0, 1].into()));
        assert_eq!(ok("[::1]:4001").host, Host::Ip(Ipv6Addr::LOCALHOST.into()));
        assert_eq!(ok("gcu-5.example:65535").host, Host::Name("gcu-5.example".into()));
        assert_eq!(ok("localhost:1").port, 1);
        for text in ["127.0.0.1:4001", "[::1]:4001", "[fe80::1]:80", "gcu-5.example:65535"] {
            assert_eq!(ok(text).to_string(), text, "shown as written");
        }
    }

    #[test]
    fn bad_host_ports_name_the_text_and_the_fault() {
        assert!(refused("127.0.0.1").contains("has no port"));
        assert!(refused(":4001").contains("has no host"));
        assert!(refused("::1:4001").contains("out of brackets"));
        assert!(refused("[::1]").contains("no port after"));
        assert!(refused("[::1:4001").contains("no closing ]"));
        assert!(refused("[gcud]:4001").contains("not an IPv6 address"));
        assert!(refused("127.0.0.1:0").contains("port \"0\", not 1..=65535"));
        assert!(refused("127.0.0.1:65536").contains("port \"65536\", not 1..=65535"));
        assert!(refused("127.0.0.1:+80").contains("not 1..=65535"));
        assert!(refused("127.0.0.1:").contains("port \"\""));
        assert!(refused("gcu_5:4001").contains("host \"gcu_5\", neither an IP address nor a host name"));
        assert!(refused("-gcu:4001").contains("neither"));
        assert!(refused("a..b:4001").contains("neither"));
        assert!(refused(&format!("{}:80", "a".repeat(64))).contains("neither"));
    }

    #[test]
    fn listen_addresses_are_ip_and_port_zero_included() {
        assert_eq!(
            listen_address("0.0.0.0:8080"),
            Ok(SocketAddr::from(([0, 0, 0, 0], 8080)))
        );
        assert_eq!(
            listen_address("[::]:0"),
            Ok(SocketAddr::from((Ipv6Addr::UNSPECIFIED, 0)))
        );
        let refused = |text: &str| {
            let e = listen_address(text).expect_err(text);
            assert!(e.to_string().starts_with(&format!("{text:?} ")), "{e}");
            e.why
        };
        assert!(refused("8080").contains("has no port"));
        assert!(refused("localhost:8080").contains("not an IP address"));
        assert!(refused("0.0.0.0:65536").contains("not 0..=65535"));
        assert!(refused("::1:80").contains("out of brackets"));
    }

    #[test]
    fn command_line_arguments_add_an_example() {
        assert_eq!(host_port_arg("[::1]:4001"), Ok("[::1]:4001".into()));
        let e = host_port_arg("127.0.0.1").unwrap_err();
        assert!(
            e.contains("\"127.0.0.1\" has no port") && e.contains("expected HOST:PORT, e.g. 127.0.0.1:4001"),
            "{e}"
        );
        assert!(listen_arg("gcud:0").unwrap_err().contains("expected IP:PORT"));
    }

    #[test]
    fn listeners_clash_on_one_port_of_one_or_every_address() {
        let a = |s: &str| s.parse::<SocketAddr>().unwrap();
        let clash = listeners_clash;
        assert!(clash(&a("127.0.0.1:1"), &a("127.0.0.1:1")));
        assert!(clash(&a("0.0.0.0:1"), &a("127.0.0.1:1")));
        assert!(clash(&a("[::1]:1"), &a("[::]:1")));
        assert!(clash(&a("127.0.0.1:1"), &a("[::]:1")));
        assert!(!clash(&a("0.0.0.0:1"), &a("[::1]:1")));
        assert!(!clash(&a("127.0.0.1:1"), &a("127.0.0.1:2")));
        assert!(!clash(&a("127.0.0.1:1"), &a("127.0.0.2:1")));
        assert!(!clash(&a("127.0.0.1:0"), &a("127.0.0.1:0")));
    }
}
