//! A port's queue (ARCHITECTURE "Bounded and fair under load"): stops
//! overtake queued work, bounded queues with their counters, unknown, closed
//! and lost ports, port 255 fan-out, round robin between clients, bytes
//! relayed as they are.

use super::*;
use sagebrush_gcu::LinkSettings;

#[test]
fn stop_overtakes_queued_work() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"HO"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"PL"));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PS"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"HA"));
    // P? is in flight; after it, the stops in their order, then the rest.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1), vec![vec![ACK], frame((G, 1, 3), 2, b"PS")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 4), 2, b"HA")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"HO")]);
}

#[test]
fn stop_is_not_held_behind_a_long_ix_result_wait() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"IX"));
    h.port(1, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"HS"));
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"HS")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    // Other work waits for the set-aside IX: it could be answered with its header.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    assert!(port_writes(&a, 1).is_empty());
    // The set-aside IX still takes its result; then the queued work goes.
    let a = h.port(1, &frame((2, 1, 3), G, b"0001000100010001"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), G, b"0001000100010001")]);
    assert_eq!(port_writes(&a, 1), vec![vec![ACK], frame((G, 1, 3), 2, b"P?")]);
}

#[test]
fn bounded_port_queue_drops_with_counter_and_warning_and_stops_have_their_own_room() {
    let mut h = H::with(&[1], |c| c.ports[0].stop_queue_bound = 2);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?")); // in flight
    for device in 4..8 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"HO"));
    }
    let refused = frame((G, 1, 8), 2, b"HO");
    let a = h.link(CLIENT, &refused);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::QueueFull))],
        "no ACK: a report says why"
    );
    assert!(
        a.iter()
            .any(|x| matches!(x, Action::Event(e) if e.level() == sagebrush_gcu::Level::Warn))
    );
    // Work filled its part of the queue; stops still fit.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PS"));
    assert!(finished(&a).is_empty());
    h.up(LinkId(9), LinkKind::Client);
    let a = h.link(LinkId(9), &frame((G, 1, 3), 2, b"PS"));
    assert!(
        finished(&a).is_empty() && link_writes(&a, LinkId(9)).is_empty(),
        "merged into the queued stop: it shares that stop's outcome"
    );
    let a = h.link(CLIENT, &frame((G, 1, 4), 2, b"PS"));
    assert!(finished(&a).is_empty());
    let a = h.link(CLIENT, &frame((G, 1, 5), 2, b"PS"));
    assert_eq!(
        finished(&a),
        vec![CommandOutcome::Dropped(DropReason::QueueFull)],
        "stops are bounded too"
    );
    let s = h.r.stats();
    assert_eq!(s.ports[&1].line.drops.get(DropReason::QueueFull), 2);
    assert_eq!(s.ports[&1].queue_high_water, 6);
    // The merged stop is ACKed when the queued one is delivered: P? (in
    // flight) gets its ACK and result, then the stops go first.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1).last(), Some(&frame((G, 1, 3), 2, b"PS")));
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    assert_eq!(link_writes(&a, LinkId(9)), vec![vec![ACK]]);
}

#[test]
fn unknown_and_closed_ports_are_dropped_and_counted() {
    let mut h = H::new(&[1]);
    let to_port_9 = frame((G, 9, 3), 2, b"AW");
    let a = h.link(CLIENT, &to_port_9);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::UnknownPort)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to_port_9, Some(Undelivered::NoSuchPort))]
    );
    h.link(CLIENT, &[ACK]);
    h.go(Input::PortLost { port: 1 });
    let to_port_1 = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &to_port_1);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::PortClosed)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to_port_1, Some(Undelivered::PortClosed))]
    );
    assert_eq!(h.r.stats().router.dropped.get(DropReason::UnknownPort), 1);
}

#[test]
fn lost_port_fails_in_flight_and_queued_then_recovers() {
    let mut h = H::new(&[1]);
    let in_flight = frame((G, 1, 3), 2, b"P?");
    let queued = frame((G, 1, 3), 2, b"HO");
    h.link(CLIENT, &in_flight);
    h.link(CLIENT, &queued);
    let a = h.go(Input::PortLost { port: 1 });
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::PortLost); 2]);
    // The client hears both, one unacknowledged report at a time: the port
    // is closed (04).
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&in_flight, Some(Undelivered::PortClosed))]
    );
    let a = h.link(CLIENT, &[ACK]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&queued, Some(Undelivered::PortClosed))]
    );
    h.link(CLIENT, &[ACK]);
    assert_eq!(h.r.stats().ports[&1].line.drops.get(DropReason::PortLost), 2);
    let a = h.go(Input::PortOpened { port: 1 });
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 9600 }));
    let cmd = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd]);
}

#[test]
fn port_255_goes_to_every_port_and_each_result_names_its_port() {
    let mut h = H::new(&[1, 2]);
    let a = h.link(CLIENT, &frame((G, 255, 3), 2, b"AW"));
    assert_eq!(accepted(&a).len(), 1);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"AW")]);
    assert_eq!(port_writes(&a, 2), vec![frame((G, 2, 3), 2, b"AW")]);
    let a = h.port(1, &[ACK]);
    assert!(link_writes(&a, CLIENT).is_empty(), "port 2 has not answered yet");
    // A result goes at once, its ACK first (1.4.3); no `?` can follow it.
    let a = h.port(1, &frame((2, 1, 3), G, b"0"));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], frame((2, 1, 3), G, b"0")]);
    assert!(finished(&a).is_empty(), "one outcome once every port is done");
    h.port(2, &[ACK]);
    let a = h.port(2, &frame((2, 2, 3), G, b"4"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert!(link_writes(&a, CLIENT).is_empty(), "one unacknowledged frame per link");
    let a = h.link(CLIENT, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 2, 3), G, b"4")]);
}

#[test]
fn fan_out_relays_one_nic_only_when_no_port_did_better() {
    let mut h = H::new(&[1, 2]);
    h.link(CLIENT, &frame((G, 255, 3), 2, b"XX"));
    let a = h.port(1, &[ACK, NIC]);
    assert!(link_writes(&a, CLIENT).is_empty(), "port 2 has not answered yet");
    let a = h.port(2, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
}

/// Seed 165293: the client was ACKed at the first device's ACK and the
/// fan-out's `?` came when a silent port gave up, after the client's window
/// and its next command's ACK, taken for that command's. The ACK waits for
/// every job to be acknowledged or to end; the `?` follows it.
#[test]
fn fan_out_is_acked_once_every_job_was_acknowledged_or_gave_up_then_its_nic() {
    let mut h = H::new(&[1, 2]);
    let a = h.link(CLIENT, &frame((G, 255, 1), 2, b"C8"));
    assert_eq!(port_writes(&a, 2).len(), 1);
    let a = h.port(1, &[ACK, NIC]);
    assert!(link_writes(&a, CLIENT).is_empty(), "port 2's job has not ended: {a:?}");
    // Port 2's device never answers: the port retries, then gives up.
    let (mut tries, mut told) = (1, Vec::new());
    for _ in 0..100 {
        let a = h.wait(1);
        tries += port_writes(&a, 2).len();
        told = link_writes(&a, CLIENT);
        if !told.is_empty() {
            assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
            break;
        }
    }
    assert_eq!(
        tries, 3,
        "the first try and 2 retries, all unanswered, before the client hears"
    );
    assert_eq!(
        told,
        vec![vec![ACK], vec![NIC]],
        "delivered (port 1's device had it), then its `?`"
    );
}

/// The ACK still comes within the delivery time-out: a job still queued
/// then expires, and a device that had the command makes it delivered.
#[test]
fn fan_out_behind_a_long_wait_is_acked_at_the_delivery_time_out() {
    let mut h = H::new(&[1, 2]);
    h.link(CLIENT, &frame((G, 2, 4), 2, b"IX"));
    h.port(2, &[ACK]);
    h.link(CLIENT, &frame((G, 255, 3), 2, b"XX"));
    let a = h.port(1, &[ACK, NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "port 2's job is queued behind the IX"
    );
    let start = h.now;
    let mut told = Vec::new();
    while told.is_empty() && h.now < start + 2_000 {
        told = link_writes(&h.wait(1), CLIENT);
    }
    assert_eq!(h.now - start, LinkSettings::DELIVERY_TIMEOUT_MS);
    assert_eq!(
        told,
        vec![vec![ACK], vec![NIC]],
        "port 1's device had it and answered NIC"
    );
}

#[test]
fn ports_serve_clients_round_robin_and_a_flood_costs_only_its_sender() {
    let other = LinkId(9);
    let mut h = H::new(&[1]);
    h.up(other, LinkKind::Client);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?")); // in flight
    for device in 4..8 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"HO")); // fills the queue (bound 4)
    }
    // The queue is full of CLIENT's work: the other client's command takes
    // the place of CLIENT's newest, which CLIENT is told was not delivered.
    let a = h.link(other, &frame((G, 1, 9), 3, b"P?"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&frame((G, 1, 7), 2, b"HO"), Some(Undelivered::QueueFull))]
    );
    assert!(
        link_writes(&a, other).is_empty(),
        "the other client's command is queued"
    );
    // CLIENT's next command is refused: it holds the most.
    let a = h.link(CLIENT, &frame((G, 1, 8), 2, b"HO"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    // Round robin: after CLIENT's P?, the other client's P? goes next,
    // ahead of CLIENT's older queued work.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1).last(), Some(&frame((G, 1, 9), 3, b"P?")));
}

#[test]
fn control_bytes_from_a_client_in_the_wrong_direction_are_stray_not_drops() {
    let mut h = H::new(&[1]);
    let a = h.link(CLIENT, &[NIC, ACK, NAK]);
    assert!(dropped(&a).is_empty() && link_writes(&a, CLIENT).is_empty(), "{a:?}");
    let s = h.r.stats();
    assert_eq!(s.links[&CLIENT].line.stray_bytes, 3);
    assert_eq!(s.router.frame_drops.total(), 0);
}

/// Payload bytes outside printable ASCII (an `*xpt` may carry any byte to
/// an auxiliary port) are relayed unchanged: the frame is length-delimited,
/// and what a payload means is the device's to judge (NIC).
#[test]
fn payload_bytes_outside_printable_ascii_are_relayed_unchanged() {
    let mut h = H::new(&[1]);
    let raw = frame((G, 1, 3), 2, b"*x0t\x01\xF8\x06\x15?");
    let a = h.link(CLIENT, &raw);
    assert_eq!(port_writes(&a, 1), vec![raw]);
}
