//! Dead-man (ARCHITECTURE "Safety"): continuous motion (`PL`, `PR`, `TU`, `TD`,
//! `FF`, `FN`, `ZI`, `ZO`) started by a link that then disconnects is
//! stopped with the matching stop command (`PS`, `TS`, `FS`, `ZS`).
//!
//! The same stops go out for every motion still owned when the GCU shuts
//! down ([`DeadMan::take_all`]), and for a motion whose owner did not
//! refresh it within its link's motion lease ([`DeadMan::expired`]): any
//! command from the owner to the same address refreshes it.
//!
//! Ownership is per (destination address as received, axis): the last
//! link that started a motion on an axis owns it; a stop of that axis for
//! the same address (from any link) ends the ownership, `HA`, `HS` and `PT`
//! end pan and tilt. A motion is owned from the moment it is accepted, so
//! one still queued is covered too (the router also cancels queued motions
//! of a link that goes down, so a stop cannot be overtaken by the motion).

use std::collections::BTreeMap;

use sagebrush_protocol::{Address, Command, Row};

use crate::command::CommandFacts;
use crate::types::LinkId;

/// The axes a continuous motion runs on, named by the command that stops it.
const STOPS: [Command<'static>; 4] = [
    Command::PanStop,
    Command::TiltStop,
    Command::FocusStop,
    Command::ZoomStop,
];

fn axis_of_stop(stop: &Command<'_>) -> Option<usize> {
    STOPS.iter().position(|s| s == stop)
}

/// Who owns a motion, and when it last heard from them about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Owner {
    link: LinkId,
    refreshed: u64,
    /// The owner's link's motion lease (ticks), if it has one.
    lease: Option<u64>,
}

impl Owner {
    fn expires(&self) -> Option<u64> {
        self.lease.map(|l| self.refreshed.saturating_add(l))
    }
}

/// A stop the GCU issues for a motion: for whom, where, which.
pub(crate) type OwnedStop = (LinkId, Address, Command<'static>);

#[derive(Debug, Default)]
pub(crate) struct DeadMan {
    owners: BTreeMap<(Address, usize), Owner>,
}

impl DeadMan {
    /// A command for `dest` was accepted from `link` at `now` (its facts:
    /// the stops have no arguments, so their row names them); `lease` is
    /// that link's motion lease.
    pub fn on_command(&mut self, now: u64, link: LinkId, lease: Option<u64>, dest: Address, command: &CommandFacts) {
        for ((d, _), owner) in self.owners.iter_mut() {
            if *d == dest && owner.link == link {
                owner.refreshed = now;
            }
        }
        if let Some(axis) = command.stopped_by.as_ref().and_then(axis_of_stop) {
            let owner = Owner {
                link,
                refreshed: now,
                lease,
            };
            self.owners.insert((dest, axis), owner);
            return;
        }
        if let Some(axis) = STOPS.iter().position(|s| s.row() == command.row) {
            self.owners.remove(&(dest, axis));
        } else if matches!(command.row, Row::Halt | Row::MotorsStop | Row::StopMotion) {
            for stop in [Command::PanStop, Command::TiltStop] {
                if let Some(axis) = axis_of_stop(&stop) {
                    self.owners.remove(&(dest, axis));
                }
            }
        }
    }

    /// `link` went down: the stops to issue, and the link forgotten.
    pub fn link_down(&mut self, link: LinkId) -> Vec<OwnedStop> {
        self.take(|_, owner| owner.link == link)
    }

    /// Every motion still owned (shutdown): the stops to issue.
    pub fn take_all(&mut self) -> Vec<OwnedStop> {
        self.take(|_, _| true)
    }

    /// Every motion owned on `port` (it is about to close): the stops to issue.
    pub fn take_port(&mut self, port: u8) -> Vec<OwnedStop> {
        self.take(|dest, _| dest.port == port)
    }

    /// Motions on `port`.`device` owned by links other than `except` (a
    /// take-over): the stops to issue.
    pub fn take_device(&mut self, port: u8, device: u8, except: LinkId) -> Vec<OwnedStop> {
        self.take(|dest, owner| dest.port == port && dest.device == device && owner.link != except)
    }

    /// Motions whose lease ran out by `now`: the stops to issue.
    pub fn expired(&mut self, now: u64) -> Vec<OwnedStop> {
        self.take(|_, owner| owner.expires().is_some_and(|t| now >= t))
    }

    /// When the next lease runs out.
    pub fn next_deadline(&self) -> Option<u64> {
        self.owners.values().filter_map(Owner::expires).min()
    }

    fn take(&mut self, pick: impl Fn(&Address, &Owner) -> bool) -> Vec<OwnedStop> {
        let mut stops = Vec::new();
        self.owners.retain(|&(dest, axis), owner| {
            if pick(&dest, owner) {
                stops.push((owner.link, dest, STOPS[axis]));
                false
            } else {
                true
            }
        });
        stops
    }

    pub fn len(&self) -> usize {
        self.owners.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: Address = Address::new(3, 1, 4);

    fn facts(command: Command<'static>) -> CommandFacts {
        CommandFacts::of(&command)
    }

    #[test]
    fn motion_owned_by_last_starter_until_stopped() {
        let mut dm = DeadMan::default();
        dm.on_command(0, LinkId(1), None, A, &facts(Command::PanLeft));
        dm.on_command(0, LinkId(1), None, A, &facts(Command::ZoomIn));
        dm.on_command(0, LinkId(2), None, A, &facts(Command::PanRight));
        dm.on_command(0, LinkId(1), None, A, &facts(Command::QueryPosition));
        assert_eq!(dm.link_down(LinkId(1)), vec![(LinkId(1), A, Command::ZoomStop)]);
        assert_eq!(dm.link_down(LinkId(2)), vec![(LinkId(2), A, Command::PanStop)]);
        assert_eq!(dm.len(), 0);
    }

    #[test]
    fn stops_end_ownership() {
        let mut dm = DeadMan::default();
        dm.on_command(0, LinkId(1), None, A, &facts(Command::PanLeft));
        dm.on_command(0, LinkId(1), None, A, &facts(Command::TiltUp));
        dm.on_command(0, LinkId(1), None, A, &facts(Command::FocusFar));
        dm.on_command(0, LinkId(2), None, A, &facts(Command::Halt));
        assert_eq!(dm.link_down(LinkId(1)), vec![(LinkId(1), A, Command::FocusStop)]);
        dm.on_command(0, LinkId(1), None, A, &facts(Command::ZoomOut));
        dm.on_command(0, LinkId(1), None, A, &facts(Command::ZoomStop));
        assert!(dm.link_down(LinkId(1)).is_empty());
    }

    #[test]
    fn a_lease_runs_out_unless_the_owner_speaks_to_the_device() {
        let mut dm = DeadMan::default();
        let b = Address::new(3, 1, 5);
        dm.on_command(0, LinkId(1), Some(100), A, &facts(Command::PanLeft));
        dm.on_command(0, LinkId(2), None, b, &facts(Command::TiltUp));
        assert_eq!(dm.next_deadline(), Some(100));
        // Another link's command, or one to another device, does not refresh it.
        dm.on_command(60, LinkId(2), None, A, &facts(Command::QueryPosition));
        dm.on_command(60, LinkId(1), Some(100), b, &facts(Command::QueryPosition));
        assert!(dm.expired(99).is_empty());
        // Any command of the owner to the device does.
        dm.on_command(90, LinkId(1), Some(100), A, &facts(Command::QueryPosition));
        assert!(dm.expired(150).is_empty());
        assert_eq!(dm.expired(190), vec![(LinkId(1), A, Command::PanStop)]);
        assert_eq!(dm.next_deadline(), None, "a link without a lease never expires");
        assert_eq!(dm.take_all(), vec![(LinkId(2), b, Command::TiltStop)]);
        assert_eq!(dm.len(), 0);
    }
}
