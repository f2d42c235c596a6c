//! Who may command a gimbal (MAVLink Gimbal Protocol v2,
//! mavlink.io/en/services/gimbal_v2.html, "Gimbal Manager Control"):
//! MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE sets the primary and secondary
//! control owners (param1/2 and param3/4: a system and component id).
//! While nobody holds control any component may command; once a
//! component holds it, commands from any other are denied.
//!
//! The values, as common.xml defines them and PX4 carries them out
//! (`src/modules/gimbal/input_mavlink.cpp`,
//! `InputMavlinkGimbalV2::_process_command`, the CONFIGURE branch):
//! - an explicit id (1..=255 system) gives control to that component
//!   whoever holds it: a take-over. PX4 sets it unconditionally, and
//!   QGroundControl's "take control" (`src/Gimbal/GimbalController.cc`,
//!   `GimbalController::acquireGimbalControl`: its own system and component
//!   id as primary, -1 for the secondary) and PX4's navigator
//!   (`Navigator::acquire_gimbal_control`) send their own ids explicitly
//!   and rely on it being accepted;
//! - system 0 leaves nobody in control (PX4: "0: no one in control");
//! - -1 leaves the slot unchanged;
//! - -3 releases the slot if the sender holds it and otherwise leaves it,
//!   accepted either way (PX4: "release control if in control"; its
//!   navigator and follow-me send it on leaving, QGroundControl's
//!   `GimbalController::releaseGimbalControl` too);
//! - -2 "set itself in control (for missions where the own sysid is still
//!   unknown)": PX4, as the manager inside the autopilot, reads "itself"
//!   as its own ids, which are the mission's sender's; an external manager
//!   such as this one reads it as the sender. Unlike an explicit id it does
//!   not take control from another holder (DENIED): a mission item must
//!   not take the gimbal from an operator, a deliberate take-over names
//!   its ids.
//! - anything else (not whole, out of range): DENIED, nothing changed
//!   (PX4 only warns and accepts; this door is honest about it).
//!
//! Above these owners gcud decides (ARCHITECTURE "Front doors"): while
//! another of its links (or a tour, or park) holds the gimbal, what the
//! owner commands is refused by gcud and answered MAV_RESULT_DENIED;
//! GIMBAL_MANAGER_STATUS then names the manager itself as primary owner,
//! and a STATUSTEXT names the holder (module `status`).
//!
//! Two rules keep any one peer from locking every ground station out
//! (issue 31): control is only given to a component that has been heard
//! ([`Heard`]: any intact message from that system and component id, the
//! CONFIGURE's own sender included), and an owner that stays silent for
//! `control_lapse_ms` (5 s by default: five missed heartbeats) loses
//! control ([`Control::lapse`]), so another ground station can take it.

use std::time::{Duration, Instant};

/// A MAVLink system and component id.
pub type Sender = (u8, u8);

/// A sender in a log line: `1/190` (system id / component id, as
/// MAVLink's tools write it).
pub fn sender_name(sender: Sender) -> String {
    format!("{}/{}", sender.0, sender.1)
}

/// A control owner in a log line: [`sender_name`], or `none`.
pub fn owner_name(owner: Option<Sender>) -> String {
    owner.map_or_else(|| "none".to_owned(), sender_name)
}

/// Senders in a log line: `1/190, 1/191`.
pub fn senders_name(senders: &[Sender]) -> String {
    senders.iter().map(|&s| sender_name(s)).collect::<Vec<_>>().join(", ")
}

/// The control owners of one gimbal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Control {
    pub primary: Option<Sender>,
    pub secondary: Option<Sender>,
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// Another component holds control.
    HeldByAnother,
    /// A parameter is none of the values the command defines.
    BadParameter,
}

/// One owner slot's request, from a pair of CONFIGURE parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    /// -1: unchanged.
    Leave,
    /// An explicit id: a take-over.
    Give(Sender),
    /// -2: the sender, unless another holds the slot.
    Sender,
    /// System 0: nobody.
    Nobody,
    /// -3: released if the sender holds it.
    Release,
}

fn slot(sysid: f32, compid: f32) -> Result<Slot, Refused> {
    let whole = |v: f32| v.is_finite() && v.fract() == 0.0;
    if !whole(sysid) || !whole(compid) {
        return Err(Refused::BadParameter);
    }
    Ok(match (sysid as i64, compid as i64) {
        (-1, -1) => Slot::Leave,
        (-2, -2) => Slot::Sender,
        (-3, -3) => Slot::Release,
        (0, 0..=255) => Slot::Nobody,
        (s @ 1..=255, c @ 0..=255) => Slot::Give((s as u8, c as u8)),
        _ => return Err(Refused::BadParameter),
    })
}

/// The components a CONFIGURE from `sender` would give control to, other
/// than `sender` itself (each must have been heard).
pub fn named(sender: Sender, params: [f32; 4]) -> Result<Vec<Sender>, Refused> {
    let slots = [slot(params[0], params[1])?, slot(params[2], params[3])?];
    Ok(slots
        .into_iter()
        .filter_map(|s| match s {
            Slot::Give(who) if who != sender => Some(who),
            _ => None,
        })
        .collect())
}

impl Control {
    /// Ends the control of each owner that `heard_within` says was not
    /// heard within the lapse time; returns who lost it.
    pub fn lapse(&mut self, heard_within: impl Fn(Sender) -> bool) -> Vec<Sender> {
        let mut lapsed = Vec::new();
        for owner in [&mut self.primary, &mut self.secondary] {
            match *owner {
                Some(who) if !heard_within(who) => {
                    *owner = None;
                    lapsed.push(who);
                }
                _ => {}
            }
        }
        lapsed
    }

    /// Whether `sender` may command the gimbal now.
    pub fn allows(&self, sender: Sender) -> bool {
        match (self.primary, self.secondary) {
            (None, None) => true,
            (p, s) => p == Some(sender) || s == Some(sender),
        }
    }

    /// MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE from `sender`; all or nothing
    /// (the rules: the module's documentation).
    pub fn configure(&mut self, sender: Sender, params: [f32; 4]) -> Result<(), Refused> {
        let primary = slot(params[0], params[1])?;
        let secondary = slot(params[2], params[3])?;
        let mut next = *self;
        for (request, owner) in [(primary, &mut next.primary), (secondary, &mut next.secondary)] {
            match request {
                Slot::Leave => {}
                Slot::Give(who) => *owner = Some(who),
                Slot::Nobody => *owner = None,
                Slot::Sender => {
                    if owner.is_some_and(|o| o != sender) {
                        return Err(Refused::HeldByAnother);
                    }
                    *owner = Some(sender);
                }
                Slot::Release => {
                    if *owner == Some(sender) {
                        *owner = None;
                    }
                }
            }
        }
        *self = next;
        Ok(())
    }
}

/// Components remembered at most, and per peer (a link, a UDP address):
/// a peer that invents ids churns its own entries, never another's.
pub const HEARD_MAX: usize = 512;
pub const HEARD_PER_PEER: usize = 16;

#[derive(Clone, Copy, Debug)]
struct Entry<P> {
    who: Sender,
    /// None once that peer is gone (its connection closed, its UDP slot
    /// taken): kept for the lapse, but the first to go when room is needed.
    peer: Option<P>,
    last: Instant,
}

/// The components heard: where (peer `P`, so that an answer goes to the
/// asker only) and when last (for the lapse), bounded by [`HEARD_MAX`] in
/// all and [`HEARD_PER_PEER`] per live peer. When room is needed, the
/// least recently heard of a peer that is gone goes first, then the least
/// recently heard of all: as live peers are bounded (8 TCP, 16 UDP per
/// endpoint, the configured ones) and so are their entries, peers that come
/// and go cannot push out a component heard on a live one.
#[derive(Debug)]
pub struct Heard<P> {
    entries: Vec<Entry<P>>,
}

impl<P> Default for Heard<P> {
    fn default() -> Self {
        Self { entries: Vec::new() }
    }
}

impl<P: Copy + PartialEq> Heard<P> {
    /// `who` was heard on `peer` at `now`.
    pub fn hear(&mut self, who: Sender, peer: P, now: Instant) {
        let fresh = Entry {
            who,
            peer: Some(peer),
            last: now,
        };
        if let Some(e) = self.entries.iter_mut().find(|e| e.who == who) {
            *e = fresh;
            return;
        }
        let oldest = |of: Option<Option<P>>| {
            self.entries
                .iter()
                .enumerate()
                .filter(|(_, e)| of.is_none_or(|p| e.peer == p))
                .min_by_key(|(_, e)| e.last)
                .map(|(i, _)| i)
        };
        let of_peer = self.entries.iter().filter(|e| e.peer == Some(peer)).count();
        let replace = if of_peer >= HEARD_PER_PEER {
            oldest(Some(Some(peer)))
        } else if self.entries.len() >= HEARD_MAX {
            oldest(Some(None)).or_else(|| oldest(None))
        } else {
            None
        };
        match replace {
            Some(i) => self.entries[i] = fresh,
            None => self.entries.push(fresh),
        }
    }

    /// Where `who` was heard last, if that peer is still there.
    pub fn peer(&self, who: Sender) -> Option<P> {
        self.entries.iter().find(|e| e.who == who).and_then(|e| e.peer)
    }

    /// Whether `who` was heard (and is still remembered).
    pub fn knows(&self, who: Sender) -> bool {
        self.entries.iter().any(|e| e.who == who)
    }

    /// `peer` is gone: its components stay remembered (for the lapse) but
    /// no answer goes there, and they are the first to make room.
    pub fn forget(&mut self, peer: P) {
        for e in self.entries.iter_mut().filter(|e| e.peer == Some(peer)) {
            e.peer = None;
        }
    }

    /// Whether `who` was heard within `within` before `now`.
    pub fn heard_within(&self, who: Sender, within: Duration, now: Instant) -> bool {
        self.entries
            .iter()
            .any(|e| e.who == who && now.saturating_duration_since(e.last) < within)
    }

    /// How many components were heard within `within` before `now` on a
    /// peer still there (the ground stations and vehicles live now).
    pub fn live(&self, within: Duration, now: Instant) -> usize {
        self.entries
            .iter()
            .filter(|e| e.peer.is_some() && now.saturating_duration_since(e.last) < within)
            .count()
    }

    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.entries.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GCS: Sender = (255, 190);
    const AUTOPILOT: Sender = (1, 1);

    #[test]
    fn one_component_in_control_denies_another_until_it_releases() {
        let mut c = Control::default();
        assert!(c.allows(GCS) && c.allows(AUTOPILOT), "nobody in control: anyone");
        c.configure(GCS, [-2.0, -2.0, -1.0, -1.0]).unwrap();
        assert_eq!(c.primary, Some(GCS));
        assert!(c.allows(GCS) && !c.allows(AUTOPILOT));
        assert_eq!(
            c.configure(AUTOPILOT, [-2.0, -2.0, -1.0, -1.0]),
            Err(Refused::HeldByAnother),
            "-2 takes no control from another holder"
        );
        // -3 from a component not in control: accepted, nothing changes (PX4).
        c.configure(AUTOPILOT, [-3.0, -3.0, -1.0, -1.0]).unwrap();
        assert_eq!(c.primary, Some(GCS));
        // The owner names a secondary.
        c.configure(GCS, [-1.0, -1.0, 1.0, 1.0]).unwrap();
        assert!(c.allows(AUTOPILOT));
        c.configure(GCS, [-3.0, -3.0, 0.0, 0.0]).unwrap();
        assert_eq!(c, Control::default());
    }

    #[test]
    fn an_explicit_id_takes_control_from_its_holder_as_px4_does() {
        let mut c = Control::default();
        c.configure(GCS, [-2.0, -2.0, -1.0, -1.0]).unwrap();
        // QGroundControl's "take control", PX4's acquire_gimbal_control.
        c.configure(AUTOPILOT, [1.0, 1.0, -1.0, -1.0]).unwrap();
        assert_eq!(c.primary, Some(AUTOPILOT));
        assert!(c.allows(AUTOPILOT) && !c.allows(GCS));
        // And back; system 0 leaves nobody in control.
        c.configure(GCS, [255.0, 190.0, -1.0, -1.0]).unwrap();
        assert_eq!(c.primary, Some(GCS));
        c.configure(AUTOPILOT, [0.0, 0.0, -1.0, -1.0]).unwrap();
        assert_eq!(c, Control::default());
    }

    #[test]
    fn parameters_that_mean_nothing_are_refused_and_change_nothing() {
        let mut c = Control::default();
        for bad in [
            [f32::NAN, 0.0, -1.0, -1.0],
            [1.5, 1.0, -1.0, -1.0],
            [300.0, 1.0, -1.0, -1.0],
            [-7.0, 0.0, -1.0, -1.0],
            [-2.0, -1.0, -1.0, -1.0],
            [1.0, 1.0, -1.0, f32::INFINITY],
        ] {
            assert_eq!(c.configure(GCS, bad), Err(Refused::BadParameter), "{bad:?}");
            assert_eq!(c, Control::default());
        }
    }
}

#[cfg(test)]
mod heard_tests {
    use super::*;

    const GCS: Sender = (255, 190);

    #[test]
    fn control_lapses_for_an_owner_not_heard_within_the_lapse() {
        let mut heard = Heard::default();
        let t0 = Instant::now();
        let lapse = Duration::from_secs(5);
        heard.hear(GCS, 1u8, t0);
        let mut c = Control::default();
        c.configure(GCS, [-2.0, -2.0, -1.0, -1.0]).unwrap();
        let heard = &heard;
        let at = |t: Instant| move |who| heard.heard_within(who, lapse, t);
        assert!(c.lapse(at(t0 + Duration::from_secs(4))).is_empty(), "heard 4 s ago");
        assert_eq!(c.lapse(at(t0 + lapse)), vec![GCS], "silent for the lapse time");
        assert_eq!(c, Control::default(), "anyone may take it now");
    }

    #[test]
    fn only_components_other_than_the_sender_are_named() {
        assert_eq!(named(GCS, [-2.0, -2.0, -1.0, -1.0]), Ok(vec![]));
        assert_eq!(named(GCS, [200.0, 7.0, 201.0, 8.0]), Ok(vec![(200, 7), (201, 8)]));
        assert_eq!(named(GCS, [255.0, 190.0, -3.0, -3.0]), Ok(vec![]));
        assert_eq!(named(GCS, [1.5, 1.0, -1.0, -1.0]), Err(Refused::BadParameter));
    }

    #[test]
    fn a_peer_inventing_ids_churns_only_its_own_entries() {
        let mut heard = Heard::default();
        let t0 = Instant::now();
        heard.hear(GCS, 1u16, t0);
        for i in 0..10_000u32 {
            let who = ((i % 250) as u8 + 1, (i / 250) as u8);
            heard.hear(who, 2u16, t0 + Duration::from_millis(u64::from(i) + 1));
        }
        assert!(heard.knows(GCS), "another peer's component stays");
        assert_eq!(heard.peer(GCS), Some(1));
        assert_eq!(heard.len(), 1 + HEARD_PER_PEER);
        // Ever new peers, each gone after one message: the table stays
        // bounded and they make room for each other, never taking the place
        // of a component on a live peer, however long ago it was heard.
        for p in 3..2_000u16 {
            heard.hear((p as u8, (p >> 8) as u8 + 1), p, t0 + Duration::from_secs(100));
            heard.forget(p);
        }
        assert!(heard.len() <= HEARD_MAX);
        assert_eq!(heard.peer(GCS), Some(1), "on a live peer: kept");
        heard.forget(1);
        assert_eq!(heard.peer(GCS), None, "its peer gone: no answer goes there");
        assert!(heard.knows(GCS), "but it is remembered");
    }
}
