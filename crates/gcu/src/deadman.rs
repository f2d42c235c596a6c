//! Dead-man (DESIGN "Safety"): continuous motion (`PL`, `PR`, `TU`, `TD`,
//! `FF`, `FN`, `ZI`, `ZO`) started by a link that then disconnects is
//! stopped with the matching stop command (`PS`, `TS`, `FS`, `ZS`).
//!
//! Ownership is per (destination address as received, axis): the last
//! link that started a motion on an axis owns it; a stop of that axis for
//! the same address (from any link) ends the ownership, `HA`, `HS` and `PT`
//! end pan and tilt. A motion is owned from the moment it is accepted, so
//! one still queued is covered too (the router also cancels queued motions
//! of a link that goes down, so a stop cannot be overtaken by the motion).

use std::collections::BTreeMap;

use sagebrush_protocol::{Address, Command};

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

#[derive(Debug, Default)]
pub(crate) struct DeadMan {
    owners: BTreeMap<(Address, usize), LinkId>,
}

impl DeadMan {
    /// A command for `dest` was accepted from `link`.
    pub fn on_command(&mut self, link: LinkId, dest: Address, command: &Command<'_>) {
        if let Some(axis) = command.stopped_by().as_ref().and_then(axis_of_stop) {
            self.owners.insert((dest, axis), link);
            return;
        }
        if let Some(axis) = axis_of_stop(command) {
            self.owners.remove(&(dest, axis));
        } else if matches!(command, Command::Halt | Command::Stop | Command::StopMotion) {
            for stop in [Command::PanStop, Command::TiltStop] {
                if let Some(axis) = axis_of_stop(&stop) {
                    self.owners.remove(&(dest, axis));
                }
            }
        }
    }

    /// `link` went down: the stops to issue, and the link forgotten.
    pub fn link_down(&mut self, link: LinkId) -> Vec<(Address, Command<'static>)> {
        let mut stops = Vec::new();
        self.owners.retain(|&(dest, axis), owner| {
            if *owner == link {
                stops.push((dest, STOPS[axis]));
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

    #[test]
    fn motion_owned_by_last_starter_until_stopped() {
        let mut dm = DeadMan::default();
        dm.on_command(LinkId(1), A, &Command::PanLeft);
        dm.on_command(LinkId(1), A, &Command::ZoomIn);
        dm.on_command(LinkId(2), A, &Command::PanRight);
        dm.on_command(LinkId(1), A, &Command::QueryPosition);
        assert_eq!(dm.link_down(LinkId(1)), vec![(A, Command::ZoomStop)]);
        assert_eq!(dm.link_down(LinkId(2)), vec![(A, Command::PanStop)]);
        assert_eq!(dm.len(), 0);
    }

    #[test]
    fn stops_end_ownership() {
        let mut dm = DeadMan::default();
        dm.on_command(LinkId(1), A, &Command::PanLeft);
        dm.on_command(LinkId(1), A, &Command::TiltUp);
        dm.on_command(LinkId(1), A, &Command::FocusFar);
        dm.on_command(LinkId(2), A, &Command::Halt);
        assert_eq!(dm.link_down(LinkId(1)), vec![(A, Command::FocusStop)]);
        dm.on_command(LinkId(1), A, &Command::ZoomOut);
        dm.on_command(LinkId(1), A, &Command::ZoomStop);
        assert!(dm.link_down(LinkId(1)).is_empty());
    }
}
