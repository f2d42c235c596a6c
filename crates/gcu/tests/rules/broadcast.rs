//! Group 255, every GCU (ARCHITECTURE "Routing semantics"): flooded
//! downstream, never back where it came from, and delivered when
//! delivered anywhere.

use super::*;

#[test]
fn group_255_from_upstream_floods_downstream_never_back() {
    let mut h = H::new(&[1]);
    h.up(UP, LinkKind::Upstream);
    h.up(DOWN, LinkKind::Downstream);
    h.up(DOWN2, LinkKind::Downstream);
    let cmd = frame((255, 1, 3), 0, b"HO");
    let a = h.link(UP, &cmd);
    assert_eq!(link_writes(&a, UP), vec![vec![ACK]], "never back where it came from");
    assert_eq!(link_writes(&a, DOWN), vec![cmd.clone()]);
    assert_eq!(link_writes(&a, DOWN2), vec![cmd.clone()]);
    assert!(link_writes(&a, CLIENT).is_empty());
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    // From a downstream GCU: executed here, not flooded.
    let from_down = frame((255, 1, 3), 7, b"HO");
    let a = h.link(DOWN, &from_down);
    assert_eq!(link_writes(&a, DOWN2), Vec::<Vec<u8>>::new());
    assert_eq!(link_writes(&a, UP), Vec::<Vec<u8>>::new());
    assert_eq!(h.r.stats().router.flooded, 2);
}

/// GCU 7 up as the downstream link, and `cmd` from the client flooded to
/// it and ACKed there hop by hop.
fn flooded_to_7(h: &mut H, cmd: &[u8]) -> Outbox {
    h.up(DOWN, LinkKind::Downstream);
    let a = h.link(CLIENT, cmd);
    assert_eq!(link_writes(&a, DOWN), vec![cmd.to_vec()]);
    h.link(DOWN, &[ACK]);
    a
}

/// A group-255 command is every GCU's: one that lacks its port is not
/// where it fails. Flooded to GCU 7, which has the port, it is delivered
/// when GCU 7 reports it delivered; it was reported `03 no such port`
/// here, and GCU 7's answers followed that report (simulation seed 1781).
#[test]
fn a_broadcast_to_a_port_only_another_gcu_has_is_delivered_there() {
    let mut h = H::new(&[1]);
    let cmd = frame((255, 4, 3), 2, b"HO");
    let a = flooded_to_7(&mut h, &cmd);
    assert!(link_writes(&a, CLIENT).is_empty(), "told before GCU 7 reported: {a:?}");
    // Port 4 is GCU 7's, not missing: the command went there, not dropped.
    assert!(dropped(&a).is_empty(), "{a:?}");
    assert_eq!(finished(&a), vec![CommandOutcome::Forwarded(DOWN)]);
    let a = h.link(DOWN, &reported_at_7(None, &cmd));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let stats = h.r.stats().router;
    assert_eq!(stats.undelivered.get(Undelivered::NoSuchPort), 0);
    assert_eq!(stats.frame_drops.get(DropReason::UnknownPort), 0);
}

/// With no GCU to flood it to, a port missing here is missing: dropped,
/// counted, and reported `03` at once.
#[test]
fn a_broadcast_to_a_port_no_gcu_has_is_reported_no_such_port() {
    let mut h = H::new(&[1]);
    let cmd = frame((255, 4, 3), 2, b"HO");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&cmd, Some(Undelivered::NoSuchPort))]
    );
    assert_eq!(dropped(&a), vec![DropReason::UnknownPort]);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::UnknownPort)]);
}

/// Delivered nowhere, it is reported once, when no part is left that may
/// still deliver it; the report names a failure where the port is before
/// a port that one GCU lacks.
#[test]
fn a_broadcast_delivered_nowhere_is_reported_once_with_the_telling_failure() {
    let mut h = H::new(&[1]);
    let cmd = frame((255, 1, 3), 2, b"HO");
    let a = flooded_to_7(&mut h, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    // Port 1's device never answers; GCU 7 may still deliver it.
    let mut told = Vec::new();
    for _ in 0..100 {
        told.extend(link_writes(&h.wait(1), CLIENT));
    }
    assert!(told.is_empty(), "told while GCU 7 may deliver it: {told:?}");
    // GCU 7 has no port 1: the last part, and the device's failure is told.
    let a = h.link(DOWN, &reported_at_7(Some(Undelivered::NoSuchPort), &cmd));
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&cmd, Some(Undelivered::DeviceSilent))]
    );
    h.link(CLIENT, &[ACK]);
    assert!(told_in_time(&mut h).is_empty(), "a second outcome");
}

/// Delivered here first, the command is ACKed at once; a GCU that lacks
/// the port and says so later changes nothing.
#[test]
fn a_broadcast_delivered_here_is_acked_without_waiting_for_other_gcus() {
    let mut h = H::new(&[1]);
    let cmd = frame((255, 1, 3), 2, b"HO");
    flooded_to_7(&mut h, &cmd);
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let a = h.link(DOWN, &reported_at_7(Some(Undelivered::NoSuchPort), &cmd));
    assert!(link_writes(&a, CLIENT).is_empty(), "a second outcome: {a:?}");
}
