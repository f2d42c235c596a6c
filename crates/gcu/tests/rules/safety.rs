//! What keeps moving hardware safe (ARCHITECTURE "Safety"): dead-man and
//! lease stops, sent again until acknowledged and always with room in the
//! queue, rate changes, reconfiguration and shutdown stopping motions first.

use super::*;

#[test]
fn dead_man_stops_the_motions_of_a_link_that_goes_down() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(5);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"ZI"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"TU")); // still queued: cancelled
    h.link(CLIENT, &frame((7, 2, 2), 2, b"FF")); // on another GCU: stop routed there
    h.link(DOWN, &[ACK]); // the report of AW
    h.link(DOWN, &[ACK]); // its answer
    h.link(DOWN, &[ACK]); // FF
    let a = h.go(Input::LinkDown { link: CLIENT });
    assert_eq!(
        finished(&a).first(),
        Some(&CommandOutcome::Dropped(DropReason::OriginGone)),
        "queued TU cancelled"
    );
    let stops = dead_man_stops(&a);
    assert_eq!(stops.len(), 4, "{stops:?}");
    assert!(stops.contains(&(Address::new(G, 1, 3), "PS")));
    assert!(stops.contains(&(Address::new(G, 1, 3), "ZS")));
    assert!(stops.contains(&(Address::new(7, 2, 2), "FS")));
    assert!(stops.contains(&(Address::new(G, 1, 4), "TS")));
    assert_eq!(link_writes(&a, DOWN), vec![frame((7, 2, 2), G, b"FS")]);
    // ZI in flight; the stops go next, before anything else, and each is
    // written to the port (the events above are only the router's account).
    assert!(port_writes(&a, 1).is_empty(), "ZI still awaits its ACK");
    let mut wire = Vec::new();
    for _ in 0..4 {
        wire.extend(port_writes(&h.port(1, &[ACK]), 1));
        wire.extend(port_writes(&h.wait(5), 1));
    }
    assert!(
        wire[0] == frame((G, 1, 3), G, b"PS") || wire[0] == frame((G, 1, 3), G, b"ZS"),
        "{wire:?}"
    );
    let mut sorted = wire.clone();
    sorted.sort();
    let mut want = vec![
        frame((G, 1, 3), G, b"PS"),
        frame((G, 1, 3), G, b"ZS"),
        frame((G, 1, 4), G, b"TS"),
    ];
    want.sort();
    assert_eq!(sorted, want, "each stop written to port 1 once; nothing else: {wire:?}");
    assert_eq!(h.r.in_progress(), 0, "every stop acknowledged");
    assert_eq!(h.r.stats().router.dead_man_stops, 4);
}

#[test]
fn rate_change_acknowledged_by_every_device_switches_the_port() {
    let mut h = H::with(&[1], |c| c.ports[0].devices = Some(vec![3, 4]));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"C5"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert!(
        !a.iter().any(|x| matches!(x, Action::SetPortRate { .. })),
        "device 4 not yet"
    );
    h.link(CLIENT, &frame((G, 1, 4), 2, b"C5"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 38400 }));
    assert_eq!(h.r.stats().ports[&1].bps, 38400);
}

#[test]
fn rate_change_to_device_255_switches_the_port_reserved_rates_never() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 255), 2, b"C7"));
    let a = h.wait(20);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 115200 }));
    h.link(CLIENT, &frame((G, 1, 255), 2, b"C9"));
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert!(!a.iter().any(|x| matches!(x, Action::SetPortRate { .. })));
    // Learned devices: the one that answered switches the port alone.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"C2"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 4800 }));
}

#[test]
fn link_going_down_drops_its_queue_and_answers_for_it_count_origin_gone() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.port(1, &[ACK]);
    let a = h.go(Input::LinkDown { link: CLIENT });
    let gone: Vec<_> = a
        .iter()
        .filter_map(|x| match x {
            Action::LinkGone { link, stats } => Some((*link, stats.line.frames_in)),
            _ => None,
        })
        .collect();
    assert_eq!(gone, vec![(CLIENT, 1)], "its final counters go to the daemon");
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::OriginGone)]);
    assert!(!h.r.link_is_up(CLIENT));
    assert!(
        !h.r.stats().links.contains_key(&CLIENT),
        "the router keeps nothing of a link gone"
    );
}

/// Links going down together can owe more stops than a port's stop queue
/// holds: dead-man stops are never dropped for a full queue.
#[test]
fn dead_man_stops_always_fit_the_port_queue() {
    let mut h = H::with(&[1], |c| c.ports[0].stop_queue_bound = 1);
    for device in 3..=6 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"PL"));
        h.port(1, &[ACK]);
        h.wait(5);
    }
    let a = h.go(Input::LinkDown { link: CLIENT });
    assert!(
        !finished(&a).contains(&CommandOutcome::Dropped(DropReason::QueueFull)),
        "{:?}",
        finished(&a)
    );
    let mut stopped = port_writes(&a, 1);
    for _ in 0..8 {
        stopped.extend(port_writes(&h.port(1, &[ACK]), 1));
        stopped.extend(port_writes(&h.wait(200), 1));
    }
    for device in 3..=6 {
        assert!(
            stopped.contains(&frame((G, 1, device), G, b"PS")),
            "device {device}: {stopped:?}"
        );
    }
    assert_eq!(h.r.stats().router.dead_man_stops, 4);
}

/// A dead-man stop that no device acknowledges (a burst of noise, say) is
/// sent again, round after round, before the router gives up.
#[test]
fn unacknowledged_dead_man_stop_is_sent_again() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(100);
    let mut writes = port_writes(&h.go(Input::LinkDown { link: CLIENT }), 1);
    writes.extend(port_writes(&h.wait(60_000), 1));
    let stop = frame((G, 1, 3), G, b"PS");
    let retries = u64::from(port_config(1).retries);
    let sent = writes.iter().filter(|w| **w == stop).count() as u64;
    assert_eq!(
        sent,
        5 * (retries + 1),
        "five rounds of {} transmissions: {writes:?}",
        retries + 1
    );
    let unreachable = h.r.stats().router.unreachable;
    assert_eq!(unreachable, 5, "each round ends unreachable");
    assert_eq!(h.r.stats().router.dead_man_stops, 1, "one motion stopped");
}

/// A lease stop no device acknowledges goes again like a dead-man stop,
/// and every round is told as what it is: a lease that ran out, counted
/// once (one motion stopped), never a dead-man stop.
#[test]
fn unacknowledged_lease_stop_is_sent_again_and_told_as_a_lease_stop() {
    let mut h = H::new(&[1]);
    h.go(Input::LinkUp {
        link: LinkId(9),
        config: LinkConfig {
            motion_lease: Some(500),
            ..LinkConfig::new(LinkKind::Client, SourceFilter::Any)
        },
    });
    h.link(LinkId(9), &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    let a = h.wait(60_000);
    let stop = frame((G, 1, 3), G, b"PS");
    let retries = u64::from(port_config(1).retries);
    let sent = port_writes(&a, 1).iter().filter(|w| **w == stop).count() as u64;
    assert_eq!(sent, 5 * (retries + 1), "five rounds of {} transmissions", retries + 1);
    let leases = a
        .iter()
        .filter(|x| {
            matches!(
                x,
                Action::Event(RouterEvent::IssuedStop {
                    stop: "PS",
                    cause: StopCause::Lease,
                    ..
                })
            )
        })
        .count();
    assert_eq!(leases, 5, "each round told as a lease stop");
    assert_eq!(dead_man_stops(&a), vec![], "no round is a dead-man stop");
    let s = h.r.stats().router;
    assert_eq!((s.lease_stops, s.dead_man_stops), (1, 0), "one motion stopped");
}

#[test]
fn reconfigure_leaves_unchanged_ports_alone_and_stops_motions_before_closing_a_port() {
    let mut h = H::new(&[1, 2]);
    // Port 1: a query in flight. Port 2: a slew running.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.link(CLIENT, &frame((G, 2, 4), 2, b"PL"));
    h.port(2, &[ACK]);
    h.wait(6);
    // New configuration: port 1 as it was, port 2 gone, port 3 new.
    let mut config = RouterConfig::new(G);
    config.name = "test gcu".into();
    config.serial = "SN-5".into();
    config.ports = vec![port_config(1), port_config(3)];
    config.links.ack_timeout = 10;
    config.links.retries = 2;
    let mut a = Outbox::new();
    h.r.reconfigure(h.now, config.clone(), &[], &mut a).expect("valid");
    assert_eq!(
        port_writes(&a, 2),
        vec![frame((G, 2, 4), G, b"PS")],
        "the slew is stopped first"
    );
    assert!(port_writes(&a, 1).is_empty(), "port 1 is not touched");
    assert!(h.r.closed_ports().is_empty(), "port 2 is busy with its stop");
    let refused = frame((G, 2, 4), 2, b"HO");
    let a = h.link(CLIENT, &refused);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::ShuttingDown))]
    );
    h.link(CLIENT, &[ACK]); // the client acknowledges the report
    // The query on port 1 goes on: delivered, then answered.
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), G, b"00000000")]);
    h.port(2, &[ACK]);
    h.wait(10);
    assert_eq!(h.r.closed_ports(), vec![2]);
    let mut a = Outbox::new();
    h.r.port_closed(h.now, 2, &mut a);
    assert!(!h.r.has_port(2));
    assert!(h.r.has_port(3));
    let a = h.link(CLIENT, &frame((G, 2, 4), 2, b"HO"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::UnknownPort)]);
    // The group cannot change while running.
    config.group = 6;
    assert!(h.r.reconfigure(h.now, config, &[], &mut Outbox::new()).is_err());
}

#[test]
fn shutdown_stops_every_owned_motion_and_refuses_new_commands() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(6);
    h.link(CLIENT, &frame((G, 1, 4), 2, b"ZI"));
    h.port(1, &[ACK]);
    h.wait(6);
    assert_eq!(h.r.owned_motions(), 2);
    let a = h.go(Input::Shutdown);
    let stops = dead_man_stops(&a);
    assert_eq!(
        stops,
        vec![(Address::new(G, 1, 3), "PS"), (Address::new(G, 1, 4), "ZS")]
    );
    // The stops themselves, on the wire: the events are only the router's account.
    let mut wire = port_writes(&a, 1);
    assert_eq!(h.r.owned_motions(), 0);
    assert!(h.r.in_progress() > 0, "the daemon waits for the stops");
    let refused = frame((G, 1, 3), 2, b"PR");
    let a = h.link(CLIENT, &refused);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::ShuttingDown)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::ShuttingDown))]
    );
    for _ in 0..2 {
        wire.extend(port_writes(&h.port(1, &[ACK]), 1));
        wire.extend(port_writes(&h.wait(10), 1));
    }
    assert_eq!(
        wire,
        vec![frame((G, 1, 3), G, b"PS"), frame((G, 1, 4), G, b"ZS")],
        "each owned motion's stop is written to its port once; nothing else"
    );
    assert_eq!(h.r.in_progress(), 0);
    assert_eq!(h.r.stats().router.shutdown_stops, 2);
}
