//! End-of-window reports (ARCHITECTURE "Delivery contract", "End of the
//! NIC window"): after the ACK of a command with no result, a NIC may
//! follow within a window (1.4.2: "After an ACK response is sent ... NIC").
//! The port already waits that window on the bus; a client that asked
//! (`~W`) is told when it passed with no NIC, by the delivery report `00`
//! about the command, so that it need not wait a window of its own.
//!
//! Only a client link over a lossless medium (TCP) may ask: there every
//! frame goes out at once and in order, so the report about a command is
//! written before the ACK of any later command to the same device (a port
//! closes a command's window before it takes the next command's ACK, in
//! the window or after it: `port::pipeline`), and a client cannot take it
//! for a later, byte-identical command's. A stock MCU on a serial client line
//! never asks and pays no extra frame. Only a command to one device of
//! one port of one GCU is reported: the windows of a port-255 fan-out's
//! jobs end on several ports at different times, so a later command could
//! be ACKed first, and every GCU a group-255 command reaches answers it.

use sagebrush_protocol::gcu::WINDOW_REPORTS_ON;
use sagebrush_protocol::{LINK_PORT, WILDCARD};

use crate::config::LinkKind;
use crate::outbox::Outbox;
use crate::types::{CommandId, CommandOutcome, LinkId, Origin};

use super::Router;

impl Router {
    /// `~W` from `link`: its result `~W=`, when the link may have
    /// end-of-window reports (a client link on a lossless medium), which
    /// it then gets; `None` (answered NIC) otherwise.
    pub(super) fn window_reports_on(&mut self, link: LinkId) -> Option<&'static [u8]> {
        let mut l = self.links.get_mut(&link)?;
        if l.config.kind != LinkKind::Client || !l.config.lossless {
            return None;
        }
        l.window_reports = true;
        Some(WINDOW_REPORTS_ON)
    }

    /// Command `id`'s jobs ended with `outcome`: when that is no answer
    /// after the ACK (completed: the port's NIC window passed, or an
    /// optional result did not come) and its origin asked for it, the
    /// report `00` tells the origin. Called before the command's record
    /// is dropped.
    pub(super) fn window_passed(&mut self, now: u64, id: CommandId, outcome: CommandOutcome, out: &mut Outbox) {
        if outcome != CommandOutcome::Completed {
            return;
        }
        let Some(c) = self.in_flight.get(&id) else { return };
        let Origin::Link { link, .. } = c.origin else { return };
        if !self.links.get(&link).is_some_and(|l| l.window_reports) {
            return;
        }
        // Copied only for a link that asked (the report borrows the router).
        let frame = c.command.frame.clone();
        let f = frame.frame();
        let one_device = f.dest.group != WILDCARD
            && f.dest.port != WILDCARD
            && f.dest.port != LINK_PORT
            && f.dest.device != WILDCARD;
        // Told delivered already: the ACK went first (not a report that it
        // was not: then this would be its second outcome).
        let acked = c.delivery.is_none() && !c.disowned;
        if one_device && acked {
            self.report(now, link, &f, None, self.group, out);
        }
    }
}
