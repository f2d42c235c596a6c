//! gimbal-visca's own metrics (issue 53, `[metrics] listen`): the VISCA
//! messages counted by kind, the controllers live, and what became of the
//! door's commands on the bus (gcud's refusal by its rule), read from a
//! scrape after the PyPI `visca-over-ip` client drove it through real gcud.

use super::*;
use support::door::DoorMetrics;

#[test]
fn gimbal_visca_counts_messages_by_kind_controllers_live_and_gcuds_refusals() {
    if !client_available() {
        return;
    }
    let gcud = support::door::start_governed_gcud();
    let text = config(&gcud.clients(), 5000, "[metrics]\nlisten = \"127.0.0.1:0\"\n");
    let stack = Stack::start_configured(gcud, &text);
    let metrics = DoorMetrics::of(&stack.door);
    assert_eq!(stack.step("absolute", &["100", "0"]), serde_json::json!({"ok": true}));
    stack.step("position", &[]);
    // The operators take mast-1: the next goto is refused by gcud.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    // The client returns at the ACK; the refusal (90 61 41 FF) follows.
    stack.step("absolute", &["-100", "0"]);
    support::eventually("gcud's refusal counted by its rule", || {
        metrics.scrape().refusals("not_in_control") >= Some(1.0)
    });
    stack.step("stop", &[]);
    let scrape = metrics.scrape();
    assert_eq!(scrape.requests("absolute"), Some(2.0), "two gotos:\n{scrape}");
    assert!(scrape.requests("inquiry") >= Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("stop"), Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("drive"), None, "no drive asked:\n{scrape}");
    assert!(scrape.outcomes("delivered") >= Some(1.0), "the first goto:\n{scrape}");
    assert!(scrape.outcomes("refused") >= Some(1.0), "{scrape}");
    assert!(scrape.sessions() >= Some(1.0), "the controller just heard:\n{scrape}");
}

/// Whether a real scrape of `addr` is answered in full now.
fn scrape_answered(addr: &str) -> bool {
    use std::io::{Read, Write};
    let Ok(mut s) = std::net::TcpStream::connect(addr) else {
        return false;
    };
    let _ = s.set_read_timeout(Some(std::time::Duration::from_secs(5)));
    if s.write_all(format!("GET /metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes())
        .is_err()
    {
        return false;
    }
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    text.starts_with("HTTP/1.1 200") && text.contains("# EOF")
}

/// A flood of bogus scrapes at the metrics listener: 3000 connections,
/// a third with a path that is no route, a third with bytes that are no
/// HTTP, a third a head never finished and held open (up to 600 at once).
/// The listener is the shared bounded one (16 connections, 4 per peer,
/// the idlest evicted for a newcomer): the door's memory stays bounded,
/// no client's path becomes a label, and a real scrape is answered after.
#[test]
fn a_flood_of_bogus_scrapes_keeps_the_door_bounded_and_a_scrape_answered() {
    use std::io::Write;
    let stack = Stack::start_with(5000, "[metrics]\nlisten = \"127.0.0.1:0\"\n");
    let metrics = DoorMetrics::of(&stack.door);
    metrics.scrape();
    let pid = stack.door.pid();
    let before = attack::rss_kib(pid);
    let bogus: [&[u8]; 3] = [
        b"GET /no/such/route HTTP/1.1\r\nHost: x\r\n\r\n",
        b"\x16\x03\x01\x00\xff not http at all\r\n\r\n",
        b"GET /metrics HTTP/1.1\r\nX-Never-Ends: ",
    ];
    let mut held = std::collections::VecDeque::new();
    for i in 0..3000 {
        let Ok(mut s) = std::net::TcpStream::connect(&metrics.addr) else {
            continue;
        };
        let _ = s.write_all(bogus[i % 3]);
        if i % 3 == 2 {
            held.push_back(s);
            if held.len() > 600 {
                held.pop_front();
            }
        }
    }
    let after = attack::rss_kib(pid);
    drop(held);
    eprintln!("metrics flood: door RSS {before} KiB before, {after} KiB after 3000 bogus scrapes");
    assert!(
        after < before + 4 * 1024,
        "the door's memory grew from {before} to {after} KiB"
    );
    support::eventually("a real scrape answered after the flood", || {
        scrape_answered(&metrics.addr)
    });
    assert!(
        !metrics.scrape().text.contains("no/such/route"),
        "a client's path became a label"
    );
}
