//! Between GCUs (ARCHITECTURE "Routing semantics"): static, learned and default routes, never back to the link
//! it came from, source filters, link retransmission, the reverse path,
//! statistics.

use super::*;

#[test]
fn other_groups_follow_static_then_learned_then_default_routes() {
    let mut h = H::with(&[1], |c| {
        c.static_routes.insert(7, DOWN2);
        c.default_upstream = Some(UP);
    });
    h.up(UP, LinkKind::Upstream);
    h.up(DOWN, LinkKind::Downstream);
    h.up(DOWN2, LinkKind::Downstream);
    // Learned: group 8 seen on DOWN (a report and the answer go back).
    h.link(DOWN, &frame((G, 0, 0), 8, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let to7 = frame((7, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to7);
    assert_eq!(link_writes(&a, DOWN2), vec![to7]);
    assert_eq!(finished(&a), vec![CommandOutcome::Forwarded(DOWN2)]);
    let to8 = frame((8, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to8);
    assert_eq!(link_writes(&a, DOWN), vec![to8]);
    let to9 = frame((9, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to9);
    assert_eq!(link_writes(&a, UP), vec![to9.clone()]);
    // Static route down: learned would be used; default down too: the
    // client hears that the route's link is down (07), not "no route" (06).
    let a = h.go(Input::LinkDown { link: UP });
    // The first to9 was written to UP and not yet ACKed there: it may have
    // got through, so the client hears "not confirmed" (0B), not 07.
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to9, Some(Undelivered::NotConfirmed))]
    );
    // The client takes the report of the first to9 (its link went down):
    // the same frame after it is a new command.
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &to9);
    assert_eq!(link_writes(&a, CLIENT), vec![report(&to9, Some(Undelivered::LinkDown))]);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::LinkDown)]);
    assert_eq!(dropped(&a), vec![DropReason::LinkDown]);
    assert_eq!(h.r.stats().router.frame_drops.get(DropReason::LinkDown), 1);
    assert_eq!(h.r.stats().router.frame_drops.get(DropReason::NoRoute), 0);
}

#[test]
fn a_frame_is_never_routed_back_to_its_link() {
    let mut h = H::new(&[1]);
    h.up(UP, LinkKind::Upstream);
    let cmd = frame((9, 1, 1), 0, b"HO");
    let a = h.link(UP, &cmd);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::Loop)]);
    assert_eq!(
        link_writes(&a, UP),
        vec![vec![ACK], report(&cmd, Some(Undelivered::Loop))],
        "hop by hop on a GCU link, then the report"
    );
}

#[test]
fn disallowed_source_group_is_dropped_and_counted() {
    let mut h = H::new(&[1]);
    h.go(Input::LinkUp {
        link: LinkId(9),
        config: LinkConfig::new(LinkKind::Client, SourceFilter::Only(vec![20])),
    });
    let spoof = frame((G, 1, 3), 21, b"PL");
    let a = h.link(LinkId(9), &spoof);
    assert_eq!(
        link_writes(&a, LinkId(9)),
        vec![report(&spoof, Some(Undelivered::SourceNotAllowed))]
    );
    assert!(accepted(&a).is_empty());
    assert_eq!(dropped(&a), vec![DropReason::SourceNotAllowed]);
    // The wildcard is refused on any link, our own group on links to other
    // GCUs (a loop or a spoof). A client acts for this GCU (Figure 7: "a
    // command issued from GCU-2") and may speak as its group.
    let a = h.link(CLIENT, &frame((G, 1, 3), 255, b"PL"));
    assert!(accepted(&a).is_empty());
    h.up(UP, LinkKind::Upstream);
    let a = h.link(UP, &frame((G, 1, 3), G, b"PL"));
    assert!(accepted(&a).is_empty());
    assert_eq!(dropped(&a), vec![DropReason::SourceNotAllowed]);
    let a = h.link(CLIENT, &frame((G, 1, 3), G, b"PL"));
    assert_eq!(accepted(&a).len(), 1, "a client may speak as our own group");
    let a = h.link(LinkId(9), &frame((G, 1, 3), 20, b"PL"));
    assert_eq!(accepted(&a).len(), 1);
    assert_eq!(
        h.r.stats().links[&LinkId(9)]
            .line
            .drops
            .get(DropReason::SourceNotAllowed),
        1
    );
}

#[test]
fn frames_sent_on_links_are_retransmitted_on_nak_and_time_out_up_to_the_count() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    let result = frame((2, 1, 3), G, b"0");
    let a = h.port(1, &result);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.link(CLIENT, &[NAK]);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.wait(10);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.wait(10);
    assert!(link_writes(&a, CLIENT).is_empty(), "retries = 2: given up");
    assert_eq!(dropped(&a), vec![DropReason::LinkNoAck]);
    let s = h.r.stats().links[&CLIENT];
    assert_eq!((s.line.retransmits, s.failed, s.delivered, s.queued), (2, 1, 0, 1));
}

#[test]
fn answers_of_forwarded_commands_go_back_along_the_reverse_path_never_to_a_wrong_client() {
    let mut h = H::new(&[1]);
    let other = LinkId(6);
    h.up(other, LinkKind::Client);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    // Two clients (groups 0 and 1) ask GCU 7 the same question.
    h.link(CLIENT, &frame((7, 1, 3), 0, b"*mu1"));
    h.link(other, &frame((7, 1, 3), 1, b"*mu2"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &frame((1, 1, 3), 7, b"2"));
    assert_eq!(link_writes(&a, other), vec![frame((1, 1, 3), 7, b"2")]);
    assert!(link_writes(&a, CLIENT).is_empty());
    let a = h.link(DOWN, &frame((0, 1, 3), 7, b"1"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((0, 1, 3), 7, b"1")]);
    h.link(CLIENT, &[ACK]);
    h.link(other, &[ACK]);
    // Sharing one source group, their answers cannot be told apart (the
    // first command may never get its result): dropped, not guessed.
    h.link(CLIENT, &frame((7, 1, 3), 0, b"*mu3"));
    h.link(other, &frame((7, 1, 3), 0, b"*mu4"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &frame((0, 1, 3), 7, b"4"));
    assert_eq!(dropped(&a), vec![DropReason::AmbiguousAnswer]);
    assert!(link_writes(&a, CLIENT).is_empty() && link_writes(&a, other).is_empty());
    // The same for a `?`.
    let a = h.link(DOWN, &[NIC]);
    assert_eq!(dropped(&a), vec![DropReason::AmbiguousAnswer]);
    assert!(link_writes(&a, CLIENT).is_empty() && link_writes(&a, other).is_empty());
}

/// ARCHITECTURE "Links between GCUs": ACK/NAK stay hop by hop, so an
/// answer the next GCU sends again on a lossy link (our ACK of it was lost)
/// is a repeat: ACKed again, not relayed again. Relayed, a client took the
/// copy for its next command's result (simulation seeds 17885, 23159).
#[test]
fn an_answer_repeated_on_a_lossy_link_is_acked_and_not_relayed_again() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    let cmd = frame((7, 1, 3), 2, b"AW");
    h.link(CLIENT, &cmd);
    h.link(DOWN, &[ACK]);
    // GCU 7 reports it delivered, then sends its result.
    let a = h.link(DOWN, &reported_at_7(None, &cmd));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let result = frame((2, 1, 3), 7, b"0");
    let a = h.link(DOWN, &result);
    assert_eq!(link_writes(&a, DOWN), vec![vec![ACK]]);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    h.link(CLIENT, &[ACK]);
    // Our ACK was lost: one ACK time-out later, the same frame again.
    h.wait(10);
    let a = h.link(DOWN, &result);
    assert_eq!(link_writes(&a, DOWN), vec![vec![ACK]], "ACKed again, hop by hop");
    assert!(link_writes(&a, CLIENT).is_empty(), "relayed again: {a:?}");
    assert!(dropped(&a).is_empty(), "a repeat is no drop: {a:?}");
}

/// The reverse path waits for a whole port transaction at the next GCU
/// (assumed configured like the slowest port here, every retry included),
/// not only the configured answer time-out: an answer from behind a slow
/// bus still reaches its origin, whose delivery time-out allows for it
/// (a result after the client was told `0B` is nobody's: below).
#[test]
fn a_forwarded_command_waits_for_a_whole_slow_port_exchange_at_the_next_gcu() {
    let mut h = H::with(&[1], |c| {
        c.ports[0] = PortConfig::at_rate(1, 1200);
        c.links.delivery_timeout = 20_000;
    });
    assert!(h.r.stats().ports[&1].bps == 1200);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    // From a client: its group is never routed, only the reverse path
    // carries the answer back.
    h.link(CLIENT, &frame((7, 1, 3), 2, b"P?"));
    // The ACK of AW's answer lets the command go; then its own ACK.
    assert_eq!(
        link_writes(&h.link(DOWN, &[ACK]), DOWN),
        vec![frame((7, 1, 3), 2, b"P?")]
    );
    h.link(DOWN, &[ACK]);
    // 1200 bit/s, 4 tries of a longest frame and its ACK wait, then the
    // result wait: about 12 s, well past the configured 3 s.
    assert!(link_writes(&h.wait(11_000), CLIENT).is_empty(), "nothing said yet");
    let a = h.link(DOWN, &frame((2, 1, 3), 7, b"00000000"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), 7, b"00000000")], "{a:?}");
}

#[test]
fn nic_from_another_gcu_is_relayed_to_the_origin() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(CLIENT, &frame((7, 1, 3), 2, b"XX"));
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &[NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NIC]]);
}

/// ARCHITECTURE "Delivery contract": a client told `0B not confirmed` has
/// its command's outcome and moves on. The next GCU may still execute it
/// and its device answer NIC (1.4.2), but a bare `?` names no command: the
/// client would take it for the command it awaits now. So that late `?`
/// is not relayed (counted as unsolicited), and the next command's `?`
/// still is (simulation seeds 13312, 29386, 36507).
#[test]
fn a_nic_of_a_command_told_not_confirmed_is_not_relayed() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    let first = frame((7, 1, 3), 2, b"SP5");
    h.link(CLIENT, &first);
    h.link(DOWN, &[ACK]);
    // GCU 7 says nothing within the delivery time-out (its port busy).
    assert_eq!(
        told_in_time(&mut h),
        vec![report(&first, Some(Undelivered::NotConfirmed))]
    );
    h.link(CLIENT, &[ACK]);
    // The client's next command, to the same device.
    let second = frame((7, 1, 3), 2, b"SP6");
    h.link(CLIENT, &second);
    h.link(DOWN, &[ACK]);
    // Now GCU 7 runs the first one: its device ACKs it and answers NIC.
    let a = h.link(DOWN, &reported_at_7(None, &first));
    assert!(link_writes(&a, CLIENT).is_empty(), "one outcome only: {a:?}");
    let a = h.link(DOWN, &[NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the first one's `?` went to the client"
    );
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    // The second command's exchange is unaffected: its ACK, then its `?`.
    let a = h.link(DOWN, &reported_at_7(None, &second));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let a = h.link(DOWN, &[NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NIC]]);
    assert!(dropped(&a).is_empty());
}

#[test]
fn statistics_count_lines_devices_and_last_seen() {
    let mut h = H::new(&[1]);
    h.now = 42;
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    let s = h.r.stats();
    assert_eq!(s.ports[&1].line.frames_out, 1);
    assert_eq!(s.ports[&1].line.last_seen, Some(42));
    assert_eq!(s.links[&CLIENT].line.last_seen, Some(42));
    assert_eq!(s.devices[&(1, 3)].commands, 1);
    assert_eq!(s.devices[&(1, 3)].last_seen, Some(42));
    assert_eq!(s.router.accepted, 1);
    assert_eq!(s.router.results, 1);
    assert_eq!(s.router.finished(), 1);
    assert_eq!(s.ports[&1].transactions, 1);
}

/// The same for a result of a forwarded query: it carries only the Table 3
/// header (1.4.3), the same as the client's next query to that device
/// has, and would be taken for that one's answer. Not relayed (ACKed hop
/// by hop, counted as unsolicited); the next query's result still is.
#[test]
fn a_result_of_a_command_told_not_confirmed_is_not_relayed() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    let query = frame((7, 1, 3), 2, b"P?");
    h.link(CLIENT, &query);
    h.link(DOWN, &[ACK]);
    assert_eq!(
        told_in_time(&mut h),
        vec![report(&query, Some(Undelivered::NotConfirmed))]
    );
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &query);
    h.link(DOWN, &[ACK]);
    let delivered = reported_at_7(None, &query);
    // GCU 7 runs the first query now: delivered, then its result.
    assert!(
        link_writes(&h.link(DOWN, &delivered), CLIENT).is_empty(),
        "one outcome only"
    );
    let a = h.link(DOWN, &frame((2, 1, 3), 7, b"00640000"));
    assert_eq!(link_writes(&a, DOWN), vec![vec![ACK]], "acknowledged hop by hop");
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the first query's result went to the client: {a:?}"
    );
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    // The second query: delivered, and its own result.
    assert_eq!(link_writes(&h.link(DOWN, &delivered), CLIENT), vec![vec![ACK]]);
    let own = frame((2, 1, 3), 7, b"00C80000");
    assert_eq!(link_writes(&h.link(DOWN, &own), CLIENT), vec![own]);
}

/// GCU 7 reports `cmd` delivered: the client gets its ACK then.
fn acked_at_the_report(h: &mut H, cmd: &[u8]) {
    assert_eq!(
        link_writes(&h.link(DOWN, &reported_at_7(None, cmd)), CLIENT),
        vec![vec![ACK]]
    );
}

/// `cmd` forwarded to GCU 7, its copy ACKed there and reported delivered:
/// the client has its ACK.
fn delivered_at_7(h: &mut H, cmd: &[u8]) {
    forwarded_to_7(h, cmd);
    h.link(DOWN, &[ACK]);
    acked_at_the_report(h, cmd);
}

/// GCU 7 up, and `cmd` from the client forwarded to it and ACKed there.
fn forwarded_to_7(h: &mut H, cmd: &[u8]) {
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(CLIENT, cmd);
    // The ACK of AW's answer lets the command go; then its own ACK.
    assert_eq!(link_writes(&h.link(DOWN, &[ACK]), DOWN), vec![cmd.to_vec()]);
}

/// A command has one NIC (1.4.2): a second `?` that only answered commands
/// could match is the next GCU's second run of one (it took a copy sent
/// again for a new command); its origin has its `?` and would take another
/// for its next command's. Not relayed (simulation seed 8519).
#[test]
fn a_second_nic_of_an_answered_command_is_not_relayed() {
    let mut h = H::new(&[1]);
    let cmd = frame((7, 1, 3), 2, b"SP5");
    delivered_at_7(&mut h, &cmd);
    assert_eq!(link_writes(&h.link(DOWN, &[NIC]), CLIENT), vec![vec![NIC]]);
    let a = h.link(DOWN, &[NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "a second `?` went to the client: {a:?}"
    );
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
}

/// A command has one result too (1.4.3): a second one, different from the
/// first (so no repeat of it), that only an answered command could take
/// is GCU 7's second run of a command it took twice. It went back where
/// the first went, and the client, gone on to its next query to the
/// device, would take it for that one's. ACKed hop by hop, not relayed.
#[test]
fn a_second_result_of_an_answered_command_is_not_relayed() {
    let mut h = H::new(&[1]);
    let cmd = frame((7, 1, 3), 2, b"P?");
    delivered_at_7(&mut h, &cmd);
    let first = frame((2, 1, 3), 7, b"00640000");
    assert_eq!(link_writes(&h.link(DOWN, &first), CLIENT), vec![first.clone()]);
    h.link(CLIENT, &[ACK]);
    let second = frame((2, 1, 3), 7, b"00C80000");
    let a = h.link(DOWN, &second);
    assert_eq!(link_writes(&a, DOWN), vec![vec![ACK]], "ACKed hop by hop");
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "a second result went to the client: {a:?}"
    );
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
}

/// Our ACK of a forwarded command lost, we sent it again, and GCU 7 ran
/// both copies: its second report `00` says so. The first run's window is
/// over by then, and the `?` that follows is the second run's: not relayed.
#[test]
fn a_nic_after_a_second_report_of_a_command_sent_twice_is_not_relayed() {
    let mut h = H::new(&[1]);
    let cmd = frame((7, 1, 3), 2, b"SP5");
    forwarded_to_7(&mut h, &cmd);
    // Its ACK lost: the same frame again, one link ACK time-out later.
    let mut again = Vec::new();
    for _ in 0..2 * sagebrush_gcu::LinkSettings::ACK_TIMEOUT_MS {
        again = link_writes(&h.wait(1), DOWN);
        if !again.is_empty() {
            break;
        }
    }
    assert_eq!(again, vec![cmd.clone()]);
    h.link(DOWN, &[ACK]);
    acked_at_the_report(&mut h, &cmd);
    let a = h.link(DOWN, &reported_at_7(None, &cmd));
    assert!(link_writes(&a, CLIENT).is_empty(), "one outcome only: {a:?}");
    let a = h.link(DOWN, &[NIC]);
    assert!(
        link_writes(&a, CLIENT).is_empty(),
        "the second run's `?` went to the client: {a:?}"
    );
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
}

/// Our copy of a forwarded command reached GCU 7 but its ACK was lost:
/// GCU 7's report says it has it, so it is not sent again, which GCU 7
/// would take for a new command and run a second time (simulation seed
/// 8263: a motion run twice).
#[test]
fn a_forwarded_command_reported_before_its_lost_ack_is_not_sent_again() {
    let mut h = H::new(&[1]);
    let cmd = frame((7, 1, 3), 2, b"SP5");
    forwarded_to_7(&mut h, &cmd);
    acked_at_the_report(&mut h, &cmd);
    let a = h.wait(2 * sagebrush_gcu::LinkSettings::ACK_TIMEOUT_MS);
    assert!(!link_writes(&a, DOWN).contains(&cmd), "sent again: {a:?}");
    // What comes next goes at once.
    let next = frame((7, 1, 3), 2, b"SP6");
    assert_eq!(link_writes(&h.link(CLIENT, &next), DOWN), vec![next]);
}
