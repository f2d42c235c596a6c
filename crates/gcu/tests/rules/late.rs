//! Late answers and silent devices (ARCHITECTURE "Routing semantics", late
//! answers): a late ACK or answer is never taken for the next command, the
//! quiet guard, dead-man stops on the bus first, a device going silent told
//! once; connections logged at their level.

use super::*;

/// Issue 20.5: a device that answered before goes silent to every try of a
/// goto, and its ACK comes late, after the GCU gave up. Nothing is written
/// during the late-answer guard, so that ACK cannot be taken for the next
/// command's: the next goto is written after the guard and, with no ACK of
/// its own, is reported undelivered, never ACKed.
#[test]
fn a_late_ack_is_never_taken_for_the_next_commands() {
    let mut h = H::new(&[1]);
    let guard = port_config(1).late_answer_guard;
    h.link(CLIENT, &frame((G, 1, 3), 2, b"HO"));
    h.port(1, &[ACK]);
    h.wait(100);
    let report_of = |out: &Outbox| {
        link_writes(out, CLIENT).iter().find_map(|w| {
            Frame::parse(w)
                .ok()
                .and_then(|(f, _)| DeliveryReport::parse(f.payload()).ok())
        })
    };
    let acked = |out: &Outbox| link_writes(out, CLIENT).iter().any(|w| w == &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P07D001F4"));
    // Silent to every try: given up and reported 01.
    let mut first = None;
    for _ in 0..1_000 {
        let out = h.wait(1);
        assert!(!acked(&out));
        first = report_of(&out);
        if first.is_some() {
            break;
        }
    }
    assert_eq!(first.expect("a report").failure, Some(Undelivered::DeviceSilent));
    // Later than the one ACK time-out of quiet after a retransmitted
    // exchange, still within the late-answer guard.
    let past_settle = port_config(1).ack_timeout + 5;
    assert!(past_settle < guard);
    assert!(!acked(&h.wait(past_settle)));
    let second = frame((G, 1, 3), 2, b"P00640064");
    let a = h.link(CLIENT, &second);
    assert!(port_writes(&a, 1).is_empty(), "the bus is quiet during the guard");
    // The first goto's ACK arrives late, within the guard.
    let late = h.port(1, &[ACK]);
    assert!(!acked(&late), "a late ACK is not the second goto's");
    // After the guard the second goto goes out; it gets no ACK of its own.
    let out = h.wait(guard - past_settle);
    assert!(port_writes(&out, 1).contains(&second), "written after the guard");
    assert!(!acked(&out));
    let mut report = report_of(&out);
    for _ in 0..100 {
        if report.is_some() {
            break;
        }
        let out = h.wait(10);
        assert!(!acked(&out), "never ACKed");
        report = report_of(&out);
    }
    assert_eq!(report.expect("a report").failure, Some(Undelivered::DeviceSilent));
}

/// Issue 20.2, seeds 21565, 22265 and 51013 of the network simulation:
/// behind a device server that stalls, a command the GCU gave up on (`0B`)
/// still runs when the server resumes, and its ACK and result come then.
/// Neither may be taken for the command on the bus at that moment (another
/// client's): that command is `0B not confirmed` too, the late result goes
/// to nobody, and the bus serves again once it has been quiet.
#[test]
fn behind_a_stalled_device_server_a_late_answer_is_nobodys() {
    const OTHER: LinkId = LinkId(6);
    let mut h = H::with(&[1], |c| c.ports[0].buffered = true);
    h.up(OTHER, LinkKind::Client);
    let quiet_time = port_config(1).late_answer_guard.max(port_config(1).ack_timeout);
    let reports = |out: &Outbox, link: LinkId| -> Vec<Vec<u8>> {
        link_writes(out, link).into_iter().filter(|w| w.len() > 1).collect()
    };
    // Several inputs at one instant, into one outbox.
    let at_once = |h: &mut H, inputs: &[(Option<LinkId>, Vec<u8>)]| {
        let mut all = Outbox::new();
        for (link, bytes) in inputs {
            let input = match link {
                Some(link) => Input::Bytes {
                    line: LineId::Link(*link),
                    bytes,
                },
                None => Input::Bytes {
                    line: LineId::Port(1),
                    bytes,
                },
            };
            h.r.handle(h.now, input, &mut all);
        }
        all
    };
    // Client 1's query waits in the stalled server: no ACK, reported 0B.
    let query = frame((G, 1, 3), 2, b"P?");
    let out = h.link(CLIENT, &query);
    assert_eq!(port_writes(&out, 1), vec![query.clone()]);
    let mut told = Vec::new();
    for _ in 0..100 {
        told = reports(&h.wait(1), CLIENT);
        if !told.is_empty() {
            break;
        }
    }
    assert_eq!(told, vec![report(&query, Some(Undelivered::NotConfirmed))]);
    h.link(CLIENT, &[ACK]);
    // The other client's AW (same source group, same device) goes out.
    let aw = frame((G, 1, 3), 2, b"AW");
    let mut written = port_writes(&h.link(OTHER, &aw), 1);
    for _ in 0..100 {
        if !written.is_empty() {
            break;
        }
        written = port_writes(&h.wait(1), 1);
    }
    assert_eq!(written, vec![aw.clone()]);
    // The server resumes: the query's ACK and result arrive now.
    let late = at_once(&mut h, &[(None, vec![ACK]), (None, frame((2, 1, 3), G, b"00000000"))]);
    assert!(
        !link_writes(&late, OTHER).contains(&vec![ACK]),
        "the query's late ACK is not the AW's"
    );
    assert_eq!(
        reports(&late, OTHER),
        vec![report(&aw, Some(Undelivered::NotConfirmed))],
        "the AW is not confirmed, and the query's result is not its"
    );
    assert!(link_writes(&late, CLIENT).is_empty(), "client 1 was told already");
    h.link(OTHER, &[ACK]);
    // The AW's own answer comes during the quiet: nobody's either.
    h.now += 2;
    let quiet = at_once(&mut h, &[(None, vec![ACK]), (None, frame((2, 1, 3), G, b"0"))]);
    assert_eq!(dropped(&quiet), vec![DropReason::Unsolicited]);
    assert!(link_writes(&quiet, OTHER).is_empty() && link_writes(&quiet, CLIENT).is_empty());
    // Quiet since the last byte heard, the bus serves again as usual.
    let again = frame((G, 1, 3), 2, b"D?");
    let out = h.link(OTHER, &again);
    assert!(port_writes(&out, 1).is_empty(), "quiet after the late answers");
    let out = h.wait(quiet_time);
    assert_eq!(port_writes(&out, 1), vec![again]);
    let out = h.port(1, &[ACK]);
    assert_eq!(link_writes(&out, OTHER), vec![vec![ACK]], "delivered");
}

/// A client's PL acknowledged on port 1, the client gone: the dead-man PS is
/// on the bus, and another client's `P?` to the same device queued behind it.
/// Returns the stop and the query frames.
fn dead_man_stop_on_the_bus_and_a_query_behind(tweak: impl FnOnce(&mut RouterConfig)) -> (H, Vec<u8>, Vec<u8>) {
    const OTHER: LinkId = LinkId(6);
    let mut h = H::with(&[1], tweak);
    h.up(OTHER, LinkKind::Client);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(100);
    let stop = frame((G, 1, 3), G, b"PS");
    let out = h.go(Input::LinkDown { link: CLIENT });
    assert_eq!(port_writes(&out, 1), vec![stop.clone()]);
    let query = frame((G, 1, 3), 2, b"P?");
    assert!(
        port_writes(&h.link(OTHER, &query), 1).is_empty(),
        "queued behind the stop"
    );
    (h, stop, query)
}

/// Seed 33315 of the network simulation: behind a device server nothing is
/// retransmitted, so a dead-man stop the device NAKs is given up at once;
/// its next round must still go out before other work queued meanwhile.
#[test]
fn a_nakked_dead_man_stop_goes_again_before_queued_work() {
    let (mut h, stop, query) = dead_man_stop_on_the_bus_and_a_query_behind(|c| c.ports[0].buffered = true);
    // The device NAKs the stop: given up (no retransmission into a server).
    let mut wire = port_writes(&h.port(1, &[NAK]), 1);
    for _ in 0..100 {
        if !wire.is_empty() {
            break;
        }
        wire = port_writes(&h.wait(1), 1);
    }
    assert_eq!(wire, vec![stop], "the stop's next round first");
    // Acknowledged this time; then the query goes out.
    let mut wire = port_writes(&h.port(1, &[ACK]), 1);
    wire.extend(port_writes(&h.wait(100), 1));
    assert_eq!(wire, vec![query], "then the query");
}

/// Seed 135037 of the network simulation: a client's command is reported
/// undelivered, the report is damaged on its way, and the client (no ACK)
/// retransmits the command. The report is still unacknowledged on the
/// client's line, so the client has no outcome yet: the identical frame is
/// its retransmission, never a new command (that one's ACK followed by the
/// first one's repeated report would be two outcomes to the client).
#[test]
fn a_retransmission_while_its_report_is_unacknowledged_is_not_a_new_command() {
    let mut h = H::new(&[1]);
    let home = frame((G, 1, 3), 2, b"HO");
    let said = report(&home, Some(Undelivered::DeviceSilent));
    let mut port = port_writes(&h.link(CLIENT, &home), 1);
    let mut told = Vec::new();
    for _ in 0..1_000 {
        let out = h.wait(1);
        port.extend(port_writes(&out, 1));
        told = link_writes(&out, CLIENT);
        if !told.is_empty() {
            break;
        }
    }
    assert_eq!(told, vec![said.clone()], "silent device: reported");
    assert_eq!(port.len(), 3, "three tries: {port:?}");
    // The report was damaged on the way: the client retransmits its HO.
    let out = h.link(CLIENT, &home);
    assert!(accepted(out.actions()).is_empty(), "not a new command");
    assert!(link_writes(&out, CLIENT).is_empty(), "no ACK");
    assert_eq!(h.r.stats().links[&CLIENT].repeats, 1);
    // The report comes again; acknowledged, the outcome is the client's.
    let mut again = Vec::new();
    for _ in 0..100 {
        let out = h.wait(1);
        assert!(port_writes(&out, 1).is_empty(), "not executed again");
        again = link_writes(&out, CLIENT);
        if !again.is_empty() {
            break;
        }
    }
    assert_eq!(again, vec![said]);
    h.link(CLIENT, &[ACK]);
    // After the outcome, an identical frame is a new command.
    let out = h.link(CLIENT, &home);
    assert_eq!(port_writes(&out, 1), vec![home]);
}

/// Seed 232276 of the network simulation: with a late-answer guard of 0, a
/// dead-man stop to a device that answered before went silent to every try;
/// its next round must still go out before other work queued meanwhile (the
/// one ACK time-out of quiet after any give-up holds with any guard).
#[test]
fn with_no_late_answer_guard_a_silent_dead_man_stop_still_goes_again_first() {
    let (mut h, stop, query) = dead_man_stop_on_the_bus_and_a_query_behind(|c| c.ports[0].late_answer_guard = 0);
    // Silent to every try: the first write after the give-up is the stop.
    let tries = u64::from(port_config(1).retries) + 1;
    let mut wire = Vec::new();
    for _ in 0..1_000 {
        wire.extend(port_writes(&h.wait(1), 1));
        if wire.len() as u64 > tries - 1 {
            break;
        }
    }
    assert_eq!(wire.len() as u64, tries, "{wire:?}");
    assert_eq!(wire.last(), Some(&stop), "the stop's next round first: {wire:?}");
    assert!(!wire.contains(&query), "{wire:?}");
}

/// Issue 24 (quiet logs): a device's answering is told once per change
/// (`DeviceState`), at WARN when one that answered goes silent, not once
/// per command to it; an address that never answered (a scan's probe) is
/// no device and no warning at all.
#[test]
fn a_device_going_silent_is_told_once_and_a_silent_probe_not_at_all() {
    use sagebrush_gcu::Level;
    let mut h = H::new(&[1]);
    let mut events: Vec<RouterEvent> = Vec::new();
    fn keep(events: &mut Vec<RouterEvent>, out: &Outbox) {
        for a in out.actions() {
            if let Action::Event(e) = a {
                events.push(e.clone());
            }
        }
    }
    let state = |events: &[RouterEvent]| -> Vec<(u8, bool, bool, Level)> {
        events
            .iter()
            .filter_map(|e| match e {
                RouterEvent::DeviceState {
                    device, online, first, ..
                } => Some((*device, *online, *first, e.level())),
                _ => None,
            })
            .collect()
    };
    // It answers: once, at DEBUG (a device appearing is no warning).
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PL")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PS")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    assert_eq!(state(&events), vec![(12, true, true, Level::Debug)]);
    // Silent to three commands: one WARN, and the commands' own ends are DEBUG.
    events.clear();
    for _ in 0..3 {
        keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PL")));
        keep(&mut events, &h.wait(1_000));
    }
    assert_eq!(state(&events), vec![(12, false, false, Level::Warn)]);
    // (This test's client never acknowledges its reports: those drops
    // are the client's, not the device's.)
    let warnings: Vec<String> = events
        .iter()
        .filter(|e| e.level() == Level::Warn)
        .filter(|e| {
            !matches!(
                e,
                RouterEvent::Dropped {
                    reason: DropReason::LinkNoAck,
                    ..
                }
            )
        })
        .map(|e| e.to_string())
        .collect();
    assert_eq!(warnings, ["port 1 device 12 went silent: no ACK after all retries"]);
    // It answers again: INFO, once.
    events.clear();
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PS")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    assert_eq!(state(&events), vec![(12, true, false, Level::Info)]);
    // A scan's probes of empty addresses: nothing above DEBUG.
    events.clear();
    for device in 20..25 {
        keep(&mut events, &h.link(CLIENT, &frame((G, 1, device), 2, b"D?")));
        keep(&mut events, &h.wait(1_000));
    }
    assert!(state(&events).is_empty(), "{events:?}");
    assert!(
        events.iter().all(|e| e.level() == Level::Debug
            || matches!(
                e,
                RouterEvent::Dropped {
                    reason: DropReason::LinkNoAck,
                    ..
                }
            )),
        "{events:?}"
    );
}

/// A configured link coming and going is the daemon's life (INFO); a
/// connection accepted on a listener is not (DEBUG), up or down.
#[test]
fn accepted_connections_come_and_go_at_debug_configured_links_at_info() {
    use sagebrush_gcu::Level;
    let mut h = H::new(&[1]);
    let levels = |o: &Outbox| -> Vec<(bool, Level)> {
        o.actions()
            .iter()
            .filter_map(|a| match a {
                Action::Event(e @ RouterEvent::LinkState { up, .. }) => Some((*up, e.level())),
                _ => None,
            })
            .collect()
    };
    let configured = h.go(Input::LinkUp {
        link: LinkId(8),
        config: LinkConfig::new(LinkKind::Upstream, SourceFilter::Any),
    });
    assert_eq!(levels(&configured), vec![(true, Level::Info)]);
    let accepted = h.go(Input::LinkUp {
        link: LinkId(70_000),
        config: LinkConfig {
            listener: Some(LinkId(8)),
            ..LinkConfig::new(LinkKind::Client, SourceFilter::Any)
        },
    });
    assert_eq!(levels(&accepted), vec![(true, Level::Debug)]);
    let gone = h.go(Input::LinkDown { link: LinkId(70_000) });
    assert_eq!(levels(&gone), vec![(false, Level::Debug)]);
    let gone = h.go(Input::LinkDown { link: LinkId(8) });
    assert_eq!(levels(&gone), vec![(false, Level::Info)]);
}

/// A NIC follows its command's ACK (1.4.2): a `?` before the ACK of the
/// exchange on the bus is an earlier command's, late (a device answers in
/// order), or this one's after a lost ACK; it ends nothing. Taken for this
/// exchange's, a stop would end "delivered" on another device's word.
#[test]
fn a_nic_before_the_ack_ends_nothing() {
    let mut h = H::new(&[1]);
    let ps = frame((G, 1, 3), 2, b"PS");
    h.link(CLIENT, &ps);
    // Another device's NIC, after its command's window: not this stop's.
    let a = h.port(1, &[NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "no outcome from a `?` before the ACK"
    );
    assert!(finished(a.actions()).is_empty());
    let a = h.port(1, &[ACK]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![vec![ACK]],
        "the stop's own ACK delivers it"
    );
    let a = h.wait(5);
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Completed]);
    // The ACK lost, the `?` alone: the frame goes again, and its answer decides.
    let fa = frame((G, 1, 3), 2, b"FA");
    let a = h.link(CLIENT, &fa);
    assert_eq!(port_writes(&a, 1), vec![fa.clone()]);
    let a = h.port(1, &[NIC]);
    assert!(link_writes(&a, CLIENT).is_empty() && finished(a.actions()).is_empty());
    let ack_wait = 10 + wire_ms(fa.len(), 9600);
    let a = h.wait(ack_wait);
    assert_eq!(port_writes(&a, 1), vec![fa.clone()], "sent again after the ACK wait");
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Nic]);
}

/// ARCHITECTURE "Delivery contract": a command still on the bus when its
/// client's delivery time-out passes is reported `0B not confirmed`, and
/// that is its outcome. Its device may ACK it after that and answer NIC
/// (1.4.2), but a bare `?` names no command: the client, gone on to its
/// next command, would take it for that one's. So it is not relayed
/// (counted as unsolicited), and the next command's exchange is untouched.
#[test]
fn a_nic_after_the_client_was_told_not_confirmed_is_not_relayed() {
    // Two ACK waits: the second try is on the bus when it passes, and the
    // next command still fits in after the late-answer quiet.
    let mut h = H::with(&[1], |c| c.links.delivery_timeout = 40);
    let first = frame((G, 1, 3), 2, b"SP5");
    let a = h.link(CLIENT, &first);
    assert_eq!(port_writes(&a, 1), vec![first.clone()]);
    // No ACK within the client's delivery time-out: not confirmed.
    let a = h.wait(40);
    assert_eq!(port_writes(&a, 1), vec![first.clone()], "tried again");
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&first, Some(Undelivered::NotConfirmed))]
    );
    h.link(CLIENT, &[ACK]);
    let second = frame((G, 1, 3), 2, b"SP6");
    h.link(CLIENT, &second);
    // The device ACKs the first command late, and answers it NIC.
    let a = h.port(1, &[ACK, NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the first one's `?` went to the client: {a:?}"
    );
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Nic]);
    assert_eq!(dropped(a.actions()), vec![DropReason::Unsolicited]);
    // The second command goes after the late-answer quiet; its own ACK and
    // `?` reach the client.
    let a = h.wait(port_config(1).late_answer_guard + 1);
    assert_eq!(port_writes(&a, 1), vec![second.clone()]);
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(a.actions()), vec![CommandOutcome::Nic]);
}

/// The same for a result: a query reported `0B not confirmed`, then
/// answered late. The result carries only the Table 3 header (1.4.3), the
/// same as that of the client's next query to the device, which would take
/// it for its own (an old position for a new one). Not relayed (counted as
/// unsolicited); the next query gets its own result.
#[test]
fn a_result_after_the_client_was_told_not_confirmed_is_not_relayed() {
    let mut h = H::with(&[1], |c| c.links.delivery_timeout = 40);
    let query = frame((G, 1, 3), 2, b"P?");
    h.link(CLIENT, &query);
    let a = h.wait(40);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&query, Some(Undelivered::NotConfirmed))]
    );
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &query);
    // The device ACKs the first query late, and answers it.
    let a = h.port(1, &[ACK]);
    assert!(link_writes(&a, CLIENT).is_empty(), "{a:?}");
    let old = frame((2, 1, 3), G, b"00640000");
    let a = h.port(1, &old);
    assert_eq!(
        port_writes(&a, 1),
        vec![vec![ACK]],
        "acknowledged on the bus, hop by hop"
    );
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the first query's result went to the client: {a:?}"
    );
    assert_eq!(dropped(a.actions()), vec![DropReason::Unsolicited]);
    // The second query goes after the late-answer quiet and gets its own.
    let a = h.wait(port_config(1).late_answer_guard + 1);
    assert_eq!(port_writes(&a, 1), vec![query.clone()]);
    assert_eq!(link_writes(&h.port(1, &[ACK]), CLIENT), vec![vec![ACK]]);
    let new = frame((2, 1, 3), G, b"00C80000");
    assert_eq!(link_writes(&h.port(1, &new), CLIENT), vec![new]);
}

/// A configured link comes back under the same id (a serial client line):
/// the result of a query its first connection asked is that connection's,
/// gone, and never reaches the next one, whose own query to the device has
/// the same Table 3 header.
#[test]
fn a_result_for_a_link_that_went_down_never_reaches_its_next_connection() {
    let mut h = H::new(&[1]);
    let query = frame((G, 1, 3), 2, b"P?");
    h.link(CLIENT, &query);
    h.port(1, &[ACK]);
    h.go(Input::LinkDown { link: CLIENT });
    h.up(CLIENT, LinkKind::Client);
    let a = h.link(CLIENT, &query);
    assert!(port_writes(&a, 1).is_empty(), "the bus awaits the first one's result");
    let a = h.port(1, &frame((2, 1, 3), G, b"00640000"));
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the first connection's result went to the next one: {a:?}"
    );
    assert_eq!(dropped(a.actions()), vec![DropReason::Unsolicited]);
    let mut wire = port_writes(&a, 1);
    wire.extend(port_writes(&h.wait(10), 1));
    assert_eq!(wire, vec![vec![ACK], query], "then the next connection's query");
    assert_eq!(link_writes(&h.port(1, &[ACK]), CLIENT), vec![vec![ACK]]);
    let own = frame((2, 1, 3), G, b"00C80000");
    assert_eq!(link_writes(&h.port(1, &own), CLIENT), vec![own]);
}
