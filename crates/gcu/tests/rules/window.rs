//! End-of-window reports (ARCHITECTURE "Delivery contract", "End of the
//! NIC window"; 1.4.2: a NIC may follow the ACK): a TCP client that asked
//! (`~W`) gets the report `00` about each command with no answer once the
//! port's NIC window passed; a NIC inside the window is still a `?`; a
//! link that did not ask, or may not, gets nothing new.

use super::*;

/// A client connection over TCP (lossless), as gcud's client listener accepts.
const TCP: LinkId = LinkId(9);
/// `~W` to this GCU, from the MCU's group.
fn ask() -> Vec<u8> {
    frame((G, 0, 0), 0, b"~W")
}

fn tcp_client(h: &mut H) {
    let mut config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
    config.lossless = true;
    h.go(Input::LinkUp { link: TCP, config });
}

fn opted_in(h: &mut H) {
    tcp_client(h);
    let a = h.link(TCP, &ask());
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK], frame((0, 0, 0), G, b"~W=")]);
}

#[test]
fn a_tcp_client_that_asked_is_told_when_the_window_passed() {
    let mut h = H::new(&[1]);
    opted_in(&mut h);
    let pl = frame((G, 1, 3), 0, b"PL");
    h.link(TCP, &pl);
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK]], "the ACK at once, as before");
    let a = h.wait(4);
    assert!(
        link_writes(&a, TCP).is_empty(),
        "inside the port's window (5): nothing yet"
    );
    let a = h.wait(1);
    assert_eq!(link_writes(&a, TCP), vec![report(&pl, None)], "the window passed: 00");
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Completed]);
}

#[test]
fn a_nic_inside_the_window_is_still_a_nic_and_no_report() {
    let mut h = H::new(&[1]);
    opted_in(&mut h);
    let fa = frame((G, 1, 3), 0, b"FA");
    h.link(TCP, &fa);
    h.port(1, &[ACK]);
    h.wait(4);
    let a = h.port(1, &[NIC]);
    assert_eq!(link_writes(&a, TCP), vec![vec![NIC]]);
    let a = h.wait(50);
    assert!(link_writes(&a, TCP).is_empty(), "no report after a NIC");
}

#[test]
fn no_report_for_a_link_that_did_not_ask_or_may_not() {
    // A TCP client that did not ask: as before.
    let mut h = H::new(&[1]);
    tcp_client(&mut h);
    h.link(TCP, &frame((G, 1, 3), 0, b"PL"));
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK]]);
    assert!(link_writes(&h.wait(50), TCP).is_empty());
    // A serial client (a stock MCU's line) may not ask: NIC.
    let a = h.link(CLIENT, &ask());
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    h.link(CLIENT, &frame((G, 1, 4), 0, b"PR"));
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    assert!(link_writes(&h.wait(50), CLIENT).is_empty());
    // Nor may a link to another GCU.
    h.up(UP, LinkKind::Upstream);
    let a = h.link(UP, &frame((G, 0, 0), 7, b"~W"));
    assert!(link_writes(&a, UP).contains(&vec![NIC]));
}

#[test]
fn results_failures_and_fan_outs_get_no_end_of_window_report() {
    let mut h = H::new(&[1, 2]);
    opted_in(&mut h);
    // A result ends the exchange itself.
    h.link(TCP, &frame((G, 1, 3), 0, b"P?"));
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((0, 1, 3), 9, b"P00000000"));
    assert_eq!(link_writes(&a, TCP).len(), 1, "the result alone");
    assert!(link_writes(&h.wait(100), TCP).is_empty());
    // A port-255 fan-out's jobs end at different times: the client waits its own window.
    let all = frame((G, 255, 3), 0, b"PL");
    h.link(TCP, &all);
    h.port(1, &[ACK]);
    h.port(2, &[ACK]);
    let a = h.wait(100);
    assert!(!link_writes(&a, TCP).contains(&report(&all, None)));
    // Nor a group-255 command: every GCU it reaches answers it.
    let every = frame((255, 1, 3), 0, b"PL");
    h.link(TCP, &every);
    h.port(1, &[ACK]);
    let a = h.wait(100);
    assert!(!link_writes(&a, TCP).contains(&report(&every, None)));
}
