//! Whose request it is: the client's address. It is the peer's, unless
//! the peer is a configured trusted proxy (`[http] trusted_proxy`, e.g. the
//! TLS proxy in front of gimbal-web): then it is the right-most address of
//! `X-Forwarded-For` that is not a trusted proxy itself (each proxy appends
//! the address it heard from, so what is left of that one was written by
//! the client and may be anything). A trusted proxy that sends no usable
//! `X-Forwarded-For` is its own client. A peer that is not a trusted proxy
//! is never believed about its header.

use std::net::IpAddr;

use axum::http::HeaderMap;

/// The header a proxy names the client in.
pub const X_FORWARDED_FOR: &str = "x-forwarded-for";

/// The client's address of a request from `peer` with `headers`, with
/// `trusted` the configured proxies (canonical: IPv4-mapped as IPv4).
pub fn client(peer: IpAddr, headers: &HeaderMap, trusted: &[IpAddr]) -> IpAddr {
    let peer = peer.to_canonical();
    if !trusted.contains(&peer) {
        return peer;
    }
    // Several headers are one list, in order (RFC 9110 5.3).
    let values: Vec<&str> = headers
        .get_all(X_FORWARDED_FOR)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect();
    for item in values.iter().rev().flat_map(|v| v.rsplit(',')) {
        match parse(item) {
            Some(ip) if trusted.contains(&ip) => continue,
            Some(ip) => return ip,
            // Not an address: what is left of it cannot be told apart.
            None => return peer,
        }
    }
    peer
}

/// One `X-Forwarded-For` item: an address, bracketed or not, with or
/// without a port.
fn parse(item: &str) -> Option<IpAddr> {
    let item = item.trim();
    let ip = item
        .parse::<IpAddr>()
        .ok()
        .or_else(|| item.parse::<std::net::SocketAddr>().ok().map(|s| s.ip()))
        .or_else(|| item.strip_prefix('[')?.strip_suffix(']')?.parse().ok())?;
    Some(ip.to_canonical())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(values: &[&str]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for v in values {
            h.append(X_FORWARDED_FOR, v.parse().unwrap());
        }
        h
    }

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn only_a_trusted_proxy_is_believed_and_only_its_right_most_untrusted_address() {
        let proxy = [ip("127.0.0.1"), ip("10.0.0.2")];
        let h = headers(&["6.6.6.6, 192.0.2.7"]);
        assert_eq!(
            client(ip("198.51.100.1"), &h, &proxy),
            ip("198.51.100.1"),
            "not a proxy"
        );
        assert_eq!(
            client(ip("127.0.0.1"), &h, &proxy),
            ip("192.0.2.7"),
            "the client, not its claim"
        );
        let chain = headers(&["6.6.6.6", "192.0.2.7, 10.0.0.2"]);
        assert_eq!(
            client(ip("127.0.0.1"), &chain, &proxy),
            ip("192.0.2.7"),
            "past the proxies"
        );
        assert_eq!(client(ip("::ffff:127.0.0.1"), &chain, &proxy), ip("192.0.2.7"));
        assert_eq!(client(ip("127.0.0.1"), &headers(&[]), &proxy), ip("127.0.0.1"));
        assert_eq!(client(ip("127.0.0.1"), &headers(&["junk"]), &proxy), ip("127.0.0.1"));
        let forms = headers(&["[2001:db8::1]:4711"]);
        assert_eq!(client(ip("127.0.0.1"), &forms, &proxy), ip("2001:db8::1"));
        let port = headers(&["192.0.2.9:5000"]);
        assert_eq!(client(ip("127.0.0.1"), &port, &proxy), ip("192.0.2.9"));
    }
}
