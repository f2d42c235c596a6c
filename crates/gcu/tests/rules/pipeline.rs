//! The next command in the window (ARCHITECTURE "Routing semantics";
//! `PortConfig::full_duplex`): on a full-duplex line the next command to
//! the same device goes during the NIC window of the one before, a `?`
//! before its ACK is the earlier command's, and that ACK closes the
//! earlier window; never on a half-duplex bus, never to another device.

use super::*;

/// A client connection over TCP that asked for end-of-window reports.
const TCP: LinkId = LinkId(9);

fn full_duplex() -> H {
    let mut h = H::with(&[1], |c| c.ports[0].full_duplex = true);
    opted_in(&mut h);
    h
}

fn opted_in(h: &mut H) {
    let mut config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
    config.lossless = true;
    h.go(Input::LinkUp { link: TCP, config });
    let a = h.link(TCP, &frame((G, 0, 0), 0, b"~W"));
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK], frame((0, 0, 0), G, b"~W=")]);
}

/// `SP7` then `PR` to device 3 from the TCP client, the speed's ACK heard.
fn speed_then_direction(h: &mut H, device: u8) -> (Vec<u8>, Vec<u8>, Outbox) {
    let sp = frame((G, 1, 3), 0, b"SP7");
    let pr = frame((G, 1, device), 0, b"PR");
    h.link(TCP, &sp);
    h.link(TCP, &pr);
    let a = h.port(1, &[ACK]);
    (sp, pr, a)
}

#[test]
fn the_next_command_to_the_device_goes_at_the_ack_and_its_ack_closes_the_window() {
    let mut h = full_duplex();
    let (sp, pr, a) = speed_then_direction(&mut h, 3);
    assert_eq!(port_writes(&a, 1), vec![pr.clone()], "PR at once, not after the window");
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK]], "SP7 delivered");
    let a = h.port(1, &[ACK]);
    assert_eq!(
        link_writes(&a, TCP),
        vec![report(&sp, None), vec![ACK]],
        "SP7's window closed before PR's ACK"
    );
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Completed]);
    let a = h.wait(5);
    assert_eq!(link_writes(&a, TCP), vec![report(&pr, None)], "PR's own window");
}

#[test]
fn a_nic_before_the_next_ack_is_the_earlier_commands() {
    let mut h = full_duplex();
    let (_, _, _) = speed_then_direction(&mut h, 3);
    let a = h.port(1, &[NIC]);
    assert!(
        link_writes(&a, TCP).is_empty(),
        "held until PR's answer says whose it is"
    );
    let a = h.port(1, &[ACK]);
    assert_eq!(
        link_writes(&a, TCP),
        vec![vec![NIC], vec![ACK]],
        "SP7's NIC, then PR's ACK"
    );
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Nic]);
    // A NAK says the device answered in order just as well.
    let mut h = full_duplex();
    speed_then_direction(&mut h, 3);
    h.port(1, &[NIC]);
    let a = h.port(1, &[NAK]);
    assert_eq!(link_writes(&a, TCP), vec![vec![NIC]]);
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Nic]);
}

#[test]
fn a_nic_with_no_ack_after_it_is_claimed_by_neither() {
    let mut h = full_duplex();
    let (_, pr, _) = speed_then_direction(&mut h, 3);
    h.port(1, &[NIC]);
    // PR's ACK never comes (its wait: 10 ticks and the frame's wire time):
    // the `?` was SP7's (PR lost) or PR's (its ACK lost).
    let a = h.wait(25);
    assert!(!link_writes(&a, TCP).contains(&vec![NIC]), "no NIC relayed for either");
    assert_eq!(
        finished(a.actions()),
        vec![CommandOutcome::NoResult],
        "SP7 not confirmed"
    );
    assert_eq!(port_writes(&a, 1), vec![pr], "PR goes again");
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(
        link_writes(&a, TCP),
        vec![vec![ACK], vec![NIC]],
        "PR's own answer, its own"
    );
}

#[test]
fn a_window_that_passes_first_ends_as_before() {
    let mut h = H::with(&[1], |c| {
        c.ports[0].full_duplex = true;
        c.ports[0].ack_timeout = 30;
    });
    opted_in(&mut h);
    let (sp, _, _) = speed_then_direction(&mut h, 3);
    let a = h.wait(5);
    assert_eq!(link_writes(&a, TCP), vec![report(&sp, None)], "SP7's window passed");
    // A `?` after the window and before PR's ACK is nobody's (ARCHITECTURE "Routing semantics").
    let a = h.port(1, &[NIC]);
    assert!(link_writes(&a, TCP).is_empty());
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, TCP), vec![vec![ACK]]);
}

#[test]
fn a_half_duplex_bus_or_another_device_waits_the_window() {
    // Half duplex (the default): the `?` could collide with the next frame.
    let mut h = H::new(&[1]);
    opted_in(&mut h);
    let (_, pr, a) = speed_then_direction(&mut h, 3);
    assert!(port_writes(&a, 1).is_empty(), "PR waits for SP7's window");
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![pr]);
    // Another device's answer says nothing about this device's NIC.
    let mut h = full_duplex();
    let (_, pr, a) = speed_then_direction(&mut h, 4);
    assert!(port_writes(&a, 1).is_empty(), "PR to device 4 waits for SP7's window");
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![pr]);
}
