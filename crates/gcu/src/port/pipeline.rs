//! No NIC window before the next command to the same device, on a line
//! that is full duplex (`PortConfig::full_duplex`; ARCHITECTURE "Routing
//! semantics": the next command in the window).
//!
//! After the ACK of a command with no result a NIC may still come (1.4.2),
//! so the port waits a window before the next exchange. A device answers
//! in order, so once the next command to the same device is on the wire,
//! whatever that device says about the earlier command comes before its
//! answer to the later one: a `?` heard before the later command's ACK or
//! NAK is the earlier command's NIC, and that ACK or NAK closes the
//! earlier command's window with no NIC. So the next command to the same
//! device need not wait for the window, where the GCU may write while the
//! device answers: RS-232 point to point, RS-422 and four-wire RS-485, a
//! device server on one of those. Not on a two-wire (half-duplex) RS-485
//! bus, where the write would collide with the `?`, and never to another
//! device (its answer says nothing about the first device's NIC).
//!
//! The one case a device's order cannot settle: a `?` before the later
//! command's ACK, and then no ACK at all. It is the earlier command's NIC
//! (the later frame was lost), or the later command's own after its ACK
//! was lost. Neither is claimed: the earlier command ends not confirmed
//! (`NoResult`, so no end-of-window report says it passed), and the later
//! one goes again or gives up as on any line.

use sagebrush_protocol::{Outcome, ResultKind, WILDCARD};

use super::exchange::{Backlog, Running};
use super::{Port, PortOut};

/// An exchange in its NIC window while the next command to its device is
/// on the bus.
#[derive(Debug)]
pub(super) struct Windowing {
    pub(super) running: Running,
    /// A `?` came before the next command's ACK: this exchange's NIC,
    /// once that ACK or a NAK shows the device answered in order.
    pub(super) nic_heard: bool,
}

impl Port {
    /// Sets the exchange on the bus aside in its NIC window when the next
    /// job may go at once (module doc): a full-duplex line, a command with
    /// no result acknowledged on its first try (no second answer may
    /// come), no rate change (the next frame would go at the old rate),
    /// nothing else set aside, and the next job to the same device.
    pub(super) fn pipeline(&mut self, now: u64) {
        if !self.config.full_duplex || self.windowing.is_some() || !self.detached.is_empty() {
            return;
        }
        if self.backlog != Backlog::Clear {
            return;
        }
        let Some(r) = &self.active else { return };
        let in_window = r.job.facts.reply.result_kind() == ResultKind::None
            && r.txn.acknowledged()
            && r.txn.outcome().is_none()
            && r.txn.transmissions() == 1
            && !r.ack_timed_out
            && r.job.facts.rate.is_none()
            && r.device() != WILDCARD;
        if !in_window || !self.next_is_for(r.device()) || self.held_for_reserved_stop(now) {
            return;
        }
        self.windowing = self.active.take().map(|running| Windowing {
            running,
            nic_heard: false,
        });
        self.stats.pipelined += 1;
    }

    /// Whether the job that goes next goes to `device`.
    pub(super) fn next_is_for(&self, device: u8) -> bool {
        self.next_pick()
            .and_then(|i| self.queue.iter().nth(i))
            .is_some_and(|j| j.frame.frame().dest.device == device)
    }

    /// A `?` while the exchange on the bus awaits its ACK: held for the
    /// exchange in its window, if there is one and it has none yet.
    pub(super) fn hold_nic(&mut self) -> bool {
        match &mut self.windowing {
            Some(w) if !w.nic_heard => {
                w.nic_heard = true;
                true
            }
            _ => false,
        }
    }

    /// The exchange on the bus was answered (`answered`: an ACK, a NAK or
    /// its result came) or its ACK wait ran out: the one in its window
    /// ends, with the `?` held for it, with no NIC, or not confirmed.
    pub(super) fn close_window(&mut self, now: u64, answered: bool, out: &mut Vec<PortOut>) {
        let Some(w) = self.windowing.take() else { return };
        let outcome = match (answered, w.nic_heard) {
            (true, true) => Outcome::Nic,
            (true, false) => Outcome::Acknowledged,
            (false, _) => Outcome::NoResult,
        };
        self.finish(now, w.running, outcome, None, out);
    }

    /// The window passed with no `?` heard: no NIC (a `?` held waits for
    /// the next exchange's answer to say whose it is).
    pub(super) fn poll_window(&mut self, now: u64, out: &mut Vec<PortOut>) {
        if self.window_deadline().is_some_and(|t| now >= t) {
            self.close_window(now, true, out);
        }
    }

    /// When [`Port::poll_window`] has something to do.
    pub(super) fn window_deadline(&self) -> Option<u64> {
        self.windowing
            .as_ref()
            .filter(|w| !w.nic_heard)
            .and_then(|w| w.running.txn.deadline())
    }
}
