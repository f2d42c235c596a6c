//! A client's command on one port (ARCHITECTURE "Routing semantics",
//! "Delivery contract"): the configuration checked, ACK once delivered, the
//! GCU's own answers, results with the Table 3 header, NAK and retransmission,
//! answer time-out classes, device 255, the device registry.

use super::*;

#[test]
fn config_is_validated() {
    assert!(Router::new(RouterConfig::new(0)).is_err());
    assert!(Router::new(RouterConfig::new(255)).is_err());
    let mut c = RouterConfig::new(3);
    c.ports = vec![PortConfig::new(1), PortConfig::new(1)];
    assert!(Router::new(c).is_err());
    let mut c = RouterConfig::new(3);
    c.ports = vec![PortConfig {
        bps: 1000,
        ..PortConfig::new(1)
    }];
    assert!(Router::new(c).is_err());
    let mut c = RouterConfig::new(3);
    c.name = "a name that is longer than twenty".into();
    assert!(Router::new(c).is_err());
}

#[test]
fn port_opened_reports_its_rate_and_unknown_inputs_are_counted() {
    let mut config = RouterConfig::new(G);
    config.ports = vec![PortConfig {
        bps: 38400,
        ..port_config(1)
    }];
    let mut r = Router::new(config).unwrap();
    let a = r.handle_once(0, Input::PortOpened { port: 1 });
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 38400 }));
    assert!(
        r.handle_once(
            0,
            Input::Bytes {
                line: LineId::Port(9),
                bytes: b"x"
            }
        )
        .is_empty()
    );
    assert!(
        r.handle_once(
            0,
            Input::Bytes {
                line: LineId::Link(LinkId(9)),
                bytes: b"x"
            }
        )
        .is_empty()
    );
    assert_eq!(r.unknown_inputs(), 2);
}

#[test]
fn client_commands_are_acked_once_delivered_and_bad_checksums_naked() {
    let mut h = H::new(&[1]);
    let mut bad = frame((G, 1, 3), 2, b"PL");
    *bad.last_mut().unwrap() ^= 0xFF;
    let a = h.link(CLIENT, &bad);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NAK]]);
    assert!(accepted(&a).is_empty());
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    assert!(link_writes(&a, CLIENT).is_empty(), "the ACK waits for the device's");
    assert_eq!(accepted(&a).len(), 1);
    // The client's retransmission meanwhile is the same command, not a new one.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    assert!(accepted(&a).is_empty() && link_writes(&a, CLIENT).is_empty());
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    assert_eq!(port_writes(&a, 1), Vec::<Vec<u8>>::new(), "written once");
    assert_eq!(h.r.stats().links[&CLIENT].repeats, 1);
    assert_eq!(h.r.stats().router.delivered, 1);
    let s = h.r.stats();
    assert_eq!(s.links[&CLIENT].line.bad_checksums, 1);
    assert_eq!(s.links[&CLIENT].line.naks_sent, 1);
    assert_eq!(s.links[&CLIENT].line.frames_in, 2, "the repeat came in too");
}

#[test]
fn gcu_itself_answers_aw_and_id_and_nic_otherwise() {
    let mut h = H::new(&[1]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"AW"));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], frame((2, 0, 0), G, b"0")]);
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"D?"));
    let writes = link_writes(&a, CLIENT);
    let reply = FrameBuf::new(
        Address::new(2, 0, 0),
        G,
        b"0519test gcu            SN-5                ",
    )
    .unwrap();
    assert_eq!(writes[1], reply.as_bytes());
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"PL"));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
    assert!(port_writes(&a, 1).is_empty());
}

#[test]
fn result_goes_back_with_table3_header_and_is_acked_on_the_port() {
    // Table 3: command 5.1.12 from group 2; result 2.1.12 from group 5.
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 12), 2, b"P?");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(
        port_writes(&a, 1),
        vec![cmd.clone()],
        "written with the header unchanged"
    );
    h.port(1, &[ACK]);
    // The device swapped the groups; the GCU rewrites the source group anyway.
    let a = h.port(1, &frame((2, 1, 12), 255, b"00640000"));
    assert_eq!(port_writes(&a, 1), vec![vec![ACK]], "hop-by-hop ACK of the result");
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 12), G, b"00640000")]);
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    let s = h.r.stats();
    assert_eq!(s.devices[&(1, 12)].frames_in, 1);
    assert_eq!(s.ports[&1].line.frames_in, 1);
}

#[test]
fn bad_checksum_result_is_naked_on_the_port_and_retransmission_accepted() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    let mut bad = frame((2, 1, 3), G, b"0");
    bad[6] = b'1';
    let a = h.port(1, &bad);
    assert_eq!(port_writes(&a, 1), vec![vec![NAK]]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &frame((2, 1, 3), G, b"0"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
}

/// A result cut short by silence (a device stalled mid-frame: QEMU's UART
/// under load, a USB adapter's latency) is the result damaged: NAKed, so
/// the device sends it again, where the exchange used to run out with the
/// device's answer lost. Noise cut short when no result is awaited goes
/// unanswered.
#[test]
fn a_result_cut_short_by_silence_is_naked_and_its_resend_accepted() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.port(1, &[ACK]);
    let result = frame((2, 1, 3), G, b"00640000");
    let a = h.port(1, &result[..7]);
    assert!(port_writes(&a, 1).is_empty(), "{a:?}");
    let a = h.wait(6);
    assert_eq!(port_writes(&a, 1), vec![vec![NAK]], "silence past idle_timeout: {a:?}");
    assert!(finished(&a).is_empty());
    // The rest of the cut frame is noise; the resent whole one is taken.
    h.port(1, &result[7..]);
    let a = h.port(1, &result);
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert_eq!(h.r.stats().ports[&1].line.naks_sent, 1);

    // Between exchanges the same cut bytes are noise, never answered.
    let a = h.port(1, &result[..7]);
    assert!(port_writes(&a, 1).is_empty());
    let a = h.wait(6);
    assert!(port_writes(&a, 1).is_empty(), "{a:?}");
    assert_eq!(h.r.stats().ports[&1].line.naks_sent, 1);
}

#[test]
fn nic_is_relayed_as_a_bare_question_mark() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"XYZ"));
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
    assert_eq!(h.r.stats().devices[&(1, 3)].nics, 1);
}

#[test]
fn the_device_registry_keeps_what_each_device_answered() {
    use sagebrush_gcu::DeviceError;
    let mut h = H::new(&[1]);
    assert!(
        !h.r.stats().devices.contains_key(&(1, 12)),
        "nothing known before an exchange"
    );
    h.link(CLIENT, &frame((G, 1, 12), 2, b"P?"));
    h.port(1, &[ACK]);
    h.now = 7;
    h.port(1, &frame((2, 1, 12), G, b"1194FC18"));
    let d = h.r.stats().devices[&(1, 12)];
    assert!(d.online);
    assert_eq!(d.last_error, None);
    let (at, position) = d.position.expect("P? answered");
    assert_eq!(at, 7);
    assert_eq!((position.pan.degrees(), position.tilt.degrees()), (45.0, -10.0));
    // Table 17: zoom then focus, 3 hex digits each.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"V?"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 12), G, b"123456"));
    let (_, lens) = h.r.stats().devices[&(1, 12)].lens.expect("V? answered");
    assert_eq!((lens.zoom.get(), lens.focus.get()), (0x123, 0x456));
    // A preset's stored position is not where the mount is.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"P?01"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 12), G, b"00000000"));
    assert_eq!(h.r.stats().devices[&(1, 12)].position, Some((7, position)));
    h.now = 20;
    h.link(CLIENT, &frame((G, 1, 12), 2, b"XYZ"));
    h.port(1, &[ACK, NIC]);
    let d = h.r.stats().devices[&(1, 12)];
    assert_eq!((d.online, d.last_error), (true, Some((20, DeviceError::Nic))));
    // Silent: offline, and what it answered before is kept.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"PL"));
    h.wait(100);
    let d = h.r.stats().devices[&(1, 12)];
    assert!(!d.online, "silent to every try");
    assert!(matches!(d.last_error, Some((_, DeviceError::Silent))));
    assert_eq!(d.position, Some((7, position)));
    // Answering again brings it back.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"PS"));
    h.port(1, &[ACK]);
    h.wait(10);
    assert!(h.r.stats().devices[&(1, 12)].online);
    // Issue 24: an address that never answered (a scan's probe) leaves no
    // entry; one that only NAKed exists.
    h.link(CLIENT, &frame((G, 1, 40), 2, b"D?"));
    h.wait(1_000);
    assert!(!h.r.stats().devices.contains_key(&(1, 40)), "never answered");
    h.link(CLIENT, &frame((G, 1, 41), 2, b"D?"));
    for _ in 0..=port_config(1).retries {
        h.port(1, &[NAK]);
    }
    h.wait(1_000);
    assert!(h.r.stats().devices.contains_key(&(1, 41)), "a NAK is an answer");
}

#[test]
fn no_ack_retransmits_up_to_the_count_then_unreachable() {
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 3), 2, b"PL");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    // A NAK is a retransmission too.
    let a = h.port(1, &[NAK]);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    let a = h.wait(100);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()], "retries = 2");
    assert_eq!(finished(&a), vec![CommandOutcome::Unreachable]);
    // The client hears 01, never an ACK (unacknowledged, the report goes
    // again within the wait).
    let told = link_writes(&a, CLIENT);
    assert!(
        !told.is_empty() && told.iter().all(|w| *w == report(&cmd, Some(Undelivered::DeviceSilent))),
        "{told:?}"
    );
    let s = h.r.stats();
    assert_eq!(s.devices[&(1, 3)].retransmits, 2);
    assert_eq!(s.devices[&(1, 3)].unreachable, 1);
    assert_eq!(s.ports[&1].line.naks_received, 1);
    assert_eq!(s.router.unreachable, 1);
}

/// The ACK clock starts at the write: a long frame on a slow line gets its
/// own wire time on top of the ACK time-out, and is not sent again while it
/// is still going out.
#[test]
fn a_long_frame_is_not_retransmitted_while_it_is_still_going_out() {
    let mut h = H::new(&[1]);
    // `*x1t` with 240 bytes for the auxiliary port: 251 bytes, 262 ms at 9600 bit/s.
    let mut payload = b"*x1t".to_vec();
    payload.extend(std::iter::repeat_n(b'A', 240));
    let long = frame((G, 1, 3), 2, &payload);
    assert_eq!(wire_ms(long.len(), 9600), 262);
    h.link(CLIENT, &long);
    let a = h.wait(250);
    assert!(port_writes(&a, 1).is_empty(), "still on the wire: no retransmission");
    h.port(1, &[ACK]);
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed], "{a:?}");
    assert_eq!(h.r.stats().devices[&(1, 3)].retransmits, 0);
}

#[test]
fn result_time_out_classes_normal_and_long() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.port(1, &[ACK]);
    assert!(finished(&h.wait(49)).is_empty());
    assert_eq!(finished(&h.wait(1)), vec![CommandOutcome::NoResult]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"IX"));
    h.port(1, &[ACK]);
    assert!(finished(&h.wait(999)).is_empty(), "IX is long");
    assert_eq!(finished(&h.wait(1)), vec![CommandOutcome::NoResult]);
    assert_eq!(h.r.stats().devices[&(1, 3)].no_result, 2);
}

#[test]
fn command_without_result_waits_a_short_nic_window() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    let second = frame((G, 1, 4), 2, b"TU");
    let a = h.port(1, &[ACK]);
    assert!(port_writes(&a, 1).is_empty(), "bus held during the NIC window");
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    h.link(CLIENT, &second);
    let a = h.port(1, &[ACK]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &[NIC]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
}

#[test]
fn device_255_written_once_without_ack_then_guard() {
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 255), 2, b"HO");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    let next = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &next);
    assert!(port_writes(&a, 1).is_empty(), "queued behind the guard");
    let a = h.wait(19);
    assert!(port_writes(&a, 1).is_empty(), "written once, no retransmission");
    let a = h.wait(1);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert_eq!(port_writes(&a, 1), vec![next]);
}

/// The device registry (gcud's /status and metrics) holds devices: a
/// broadcast to device 255 adds no row for the wildcard, which would read
/// as an offline gimbal, neither while it is on the bus nor after.
#[test]
fn a_broadcast_adds_no_wildcard_device_to_the_registry() {
    let mut h = H::new(&[1]);
    let broadcast = frame((G, 1, 255), 2, b"PL");
    let a = h.link(CLIENT, &broadcast);
    assert_eq!(port_writes(&a, 1), vec![broadcast]);
    let devices = |h: &H| h.r.stats().devices.keys().copied().collect::<Vec<_>>();
    assert_eq!(devices(&h), vec![], "while the broadcast is on the bus");
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert_eq!(devices(&h), vec![], "after it");
    assert_eq!(h.r.stats().ports[&1].transactions, 1, "counted on its port");
    // A device that answers is in the registry; the wildcard still is not.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 255), 2, b"PS"));
    assert_eq!(devices(&h), vec![(1, 3)]);
}

#[test]
fn a_late_or_duplicate_result_is_never_taken_for_the_next_exchange() {
    let mut h = H::new(&[1]);
    let mu = frame((G, 1, 3), 2, b"*mu1");
    h.link(CLIENT, &mu);
    let a = h.wait(10 + wire_ms(mu.len(), 9600));
    assert_eq!(port_writes(&a, 1), vec![mu], "ACK lost: retransmitted");
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    // The device executed it twice; the bus settles before the next exchange.
    let query = frame((G, 1, 3), 3, b"P?");
    let a = h.link(CLIENT, &query);
    assert!(port_writes(&a, 1).is_empty(), "settling");
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    let a = h.wait(10);
    assert_eq!(port_writes(&a, 1), vec![query]);
    h.port(1, &[ACK]);
    // Same port and device, but for another source group: not this result.
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &frame((3, 1, 3), G, b"00000000"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert_eq!(
        link_writes(&a, CLIENT),
        Vec::<Vec<u8>>::new(),
        "behind the first result, awaiting its ACK"
    );
}
