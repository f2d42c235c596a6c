//! This MAVLink system as the transports see it ([`Net`]): its
//! components and their sequence numbers, the components heard and where
//! (bounded, see `control::Heard`), the screening of every intact frame
//! before the router (a command id the dialect does not know is answered
//! MAV_RESULT_UNSUPPORTED, control given to a component never heard
//! MAV_RESULT_DENIED), and where a message goes: an answer (a COMMAND_ACK,
//! a requested message) to the peer the asker was heard on, nowhere else;
//! periodic status to every peer. With `[signing]`, only frames signed
//! with the key are read ([`Net::admits`], `signing`), and every frame sent
//! is signed.

use std::collections::HashMap;
use std::fmt;
use std::net::SocketAddr;
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use mavlink::dialects::common::{MavCmd, MavMessage, MavResult};
use mavlink::{MavHeader, Message};
use tracing::warn;

use crate::routing::control::{self, Heard, Sender};
use crate::stats::{Stats, may_warn};
use crate::transport::signing::Signing;
#[cfg(test)]
use crate::transport::wire::COMMAND_LONG_ID;
use crate::transport::wire::{COMMAND_ACK_ID, Decoded, SIGNED, V2_MAGIC};

/// Where a message was heard, and where an answer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peer {
    /// Endpoint `port` (an index into the UDP endpoints), address `addr`.
    Udp { port: usize, addr: SocketAddr },
    /// A TCP connection or serial line (`stream`'s id).
    Stream(u64),
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// What becomes of an intact frame.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Screened {
    /// To the router.
    Handle(MavHeader, MavMessage),
    /// Answered here: these bytes, to the peer it came from only.
    Answer(Vec<u8>),
    /// Counted, nothing to do.
    Drop,
}

/// This MAVLink system: its components and their sequence numbers, the
/// components heard (where, when), and the askers owed a requested message.
#[derive(Debug)]
pub struct Net {
    pub system_id: u8,
    own: Mutex<Vec<u8>>,
    sequence: Mutex<HashMap<u8, u8>>,
    pub heard: Mutex<Heard<Peer>>,
    /// Per component, the asker of the MAV_CMD_REQUEST_MESSAGE it just
    /// accepted: the information message that follows goes to it alone.
    requested: Mutex<HashMap<u8, Sender>>,
    /// The key, when signing is on.
    signing: Option<Signing>,
}

impl Net {
    pub fn new(system_id: u8, signing: Option<Signing>) -> Self {
        Self {
            system_id,
            own: Mutex::default(),
            sequence: Mutex::default(),
            heard: Mutex::default(),
            requested: Mutex::default(),
            signing,
        }
    }

    /// Whether signing is on: only frames signed with the key are read.
    pub fn signed(&self) -> bool {
        self.signing.is_some()
    }

    /// Whether an intact `frame` heard from `from` may be read: any, or
    /// with signing on one signed with the key and newer than its stream's
    /// last (a refusal is counted and logged, `signing`). Asked before
    /// anything else reads the frame.
    pub fn admits(&self, frame: &[u8], from: &dyn fmt::Display, stats: &Stats) -> bool {
        let Some(signing) = &self.signing else {
            return true;
        };
        match signing.check(frame) {
            Ok(()) => true,
            Err(refusal) => {
                signing.refused(refusal, frame, from, stats);
                false
            }
        }
    }

    /// This system's components (the gimbals): the ones that answer here.
    pub fn set_components(&self, components: impl IntoIterator<Item = u8>) {
        *lock(&self.own) = components.into_iter().collect();
    }

    /// How many components were heard within `within` on a peer still there.
    pub fn live(&self, within: Duration) -> usize {
        lock(&self.heard).live(within, Instant::now())
    }

    /// Whether `who` was heard within `within`.
    pub fn heard_within(&self, who: Sender, within: Duration) -> bool {
        lock(&self.heard).heard_within(who, within, Instant::now())
    }

    /// Our component a command is for: `target_component`, or, when it is
    /// 0 (every component), the gimbal device id of param 7.
    fn addressed(&self, target_system: u8, target_component: u8, param7: f32) -> Option<u8> {
        if target_system != 0 && target_system != self.system_id {
            return None;
        }
        let component = match target_component {
            0 if param7.fract() == 0.0 && (1.0..=255.0).contains(&param7) => param7 as u8,
            0 => return None,
            c => c,
        };
        lock(&self.own).contains(&component).then_some(component)
    }

    fn next_sequence(&self, component: u8) -> u8 {
        let mut s = lock(&self.sequence);
        let n = s.entry(component).or_insert(0);
        let this = *n;
        *n = n.wrapping_add(1);
        this
    }

    /// `message` from `component` as a MAVLink 2 frame.
    pub fn frame(&self, component: u8, message: &MavMessage) -> Option<Vec<u8>> {
        let header = MavHeader {
            system_id: self.system_id,
            component_id: component,
            sequence: self.next_sequence(component),
        };
        let mut bytes = Vec::with_capacity(64);
        match mavlink::write_v2_msg_signed(&mut bytes, header, message, self.signing.as_ref().map(Signing::data)) {
            Ok(_) => Some(bytes),
            Err(e) => {
                warn!(message = message.message_name(), error = %e, "cannot encode");
                None
            }
        }
    }

    /// A MAVLink 2 frame of message `id` with `payload` (trailing zeros
    /// dropped, as MAVLink 2 sends them), from `component`; signed when
    /// signing is on.
    fn raw_frame(&self, component: u8, id: u32, payload: &[u8]) -> Vec<u8> {
        let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
        let id = id.to_le_bytes();
        let mut f = vec![
            V2_MAGIC,
            len as u8,
            if self.signed() { SIGNED } else { 0 },
            0,
            self.next_sequence(component),
            self.system_id,
            component,
            id[0],
            id[1],
            id[2],
        ];
        f.extend_from_slice(&payload[..len]);
        let crc = mavlink::calculate_crc(&f[1..], MavMessage::extra_crc(COMMAND_ACK_ID));
        f.extend_from_slice(&crc.to_le_bytes());
        if let Some(signing) = &self.signing {
            signing.sign(&mut f);
        }
        f
    }

    /// COMMAND_ACK UNSUPPORTED of command id `command` (which the dialect
    /// may not know, so it is written here) from `component` to `to`.
    fn unsupported(&self, component: u8, command: u16, to: Sender) -> Vec<u8> {
        let c = command.to_le_bytes();
        let unsupported = MavResult::MAV_RESULT_UNSUPPORTED as u8;
        // command, result, progress, result_param2 (4), target_system, target_component
        let payload = [c[0], c[1], unsupported, 0, 0, 0, 0, 0, to.0, to.1];
        self.raw_frame(component, COMMAND_ACK_ID, &payload)
    }

    /// An intact frame heard on `peer`: its sender is remembered, then it
    /// is handled, answered here or dropped.
    pub fn screen(&self, decoded: Decoded, peer: Peer, from: &dyn fmt::Display, stats: &Stats) -> Screened {
        let header = match &decoded {
            Decoded::Message(h, _) | Decoded::Unreadable(h, _) => *h,
            Decoded::UnknownCommand { header, .. } => *header,
        };
        let sender = (header.system_id, header.component_id);
        lock(&self.heard).hear(sender, peer, Instant::now());
        match decoded {
            Decoded::Unreadable(_, len) => {
                stats.damaged(from, len);
                Screened::Drop
            }
            Decoded::UnknownCommand {
                target_system,
                target_component,
                command,
                param7,
                ..
            } => {
                Stats::count(&stats.received);
                Stats::count(&stats.ignored);
                let Some(component) = self.addressed(target_system, target_component, param7) else {
                    return Screened::Drop;
                };
                Stats::count(&stats.unsupported);
                if may_warn("command not supported", from) {
                    warn!(%from, sender = control::sender_name(sender), command, component, "command id unknown to the dialect: MAV_RESULT_UNSUPPORTED");
                }
                Screened::Answer(self.unsupported(component, command, sender))
            }
            Decoded::Message(header, message) => {
                Stats::count(&stats.received);
                match self.control_to_unheard(sender, &message) {
                    Some((component, unheard)) => {
                        Stats::count(&stats.refused);
                        if may_warn("control given to a component never heard", from) {
                            warn!(%from, sender = control::sender_name(sender), unheard = control::senders_name(&unheard), component, "control given to a component never heard: MAV_RESULT_DENIED");
                        }
                        let ack = crate::routing::answers::ack(
                            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
                            MavResult::MAV_RESULT_DENIED,
                            sender,
                        );
                        match self.frame(component, &ack) {
                            Some(bytes) => Screened::Answer(bytes),
                            None => Screened::Drop,
                        }
                    }
                    None => Screened::Handle(header, message),
                }
            }
        }
    }

    /// For a MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE to one of our components
    /// that gives control to components never heard: that component and them.
    fn control_to_unheard(&self, sender: Sender, message: &MavMessage) -> Option<(u8, Vec<Sender>)> {
        let c = crate::routing::command::Command::of(message)?;
        if c.command != MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE {
            return None;
        }
        // To every component: the first gimbal answers the refusal.
        let component = match (c.target_component, c.device_id()) {
            (0, 0) if c.target_system == 0 || c.target_system == self.system_id => lock(&self.own).first().copied()?,
            _ => self.addressed(c.target_system, c.target_component, c.param7)?,
        };
        // Parameters that mean nothing are the gimbal's to refuse.
        let named = control::named(sender, c.params).ok()?;
        let heard = lock(&self.heard);
        let unheard: Vec<Sender> = named.into_iter().filter(|w| !heard.knows(*w)).collect();
        (!unheard.is_empty()).then_some((component, unheard))
    }

    /// Whom `message` from `component` answers: a COMMAND_ACK its target;
    /// a requested information message the asker of the request just
    /// accepted; anything else nobody in particular (everyone).
    pub fn addressee(&self, component: u8, message: &MavMessage) -> Option<Sender> {
        match message {
            MavMessage::COMMAND_ACK(a) => {
                let to = (a.target_system, a.target_component);
                if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE && a.result == MavResult::MAV_RESULT_ACCEPTED {
                    lock(&self.requested).insert(component, to);
                }
                // Even to system 0 (no valid sender has it, but one that
                // claims it is still the asker): never everyone.
                Some(to)
            }
            MavMessage::GIMBAL_MANAGER_INFORMATION(_) | MavMessage::GIMBAL_DEVICE_INFORMATION(_) => {
                lock(&self.requested).remove(&component)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::wire::{Scan, decode_datagram, encode, header, scan};
    use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA};

    const GCS: Sender = (255, 190);

    fn command(id: MavCmd, target: (u8, u8), param7: f32) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: id,
            target_system: target.0,
            target_component: target.1,
            param7,
            ..COMMAND_LONG_DATA::DEFAULT
        })
    }

    /// A COMMAND_LONG with command id `id`, however unknown.
    fn command_with_id(id: u16, target: (u8, u8)) -> Vec<u8> {
        let mut f = encode(header(GCS), &command(MavCmd::MAV_CMD_DO_SET_SERVO, target, 0.0));
        f[10 + 28..10 + 30].copy_from_slice(&id.to_le_bytes());
        let end = 10 + usize::from(f[1]);
        let crc = mavlink::calculate_crc(&f[1..end], MavMessage::extra_crc(COMMAND_LONG_ID));
        f[end..end + 2].copy_from_slice(&crc.to_le_bytes());
        f
    }

    fn net() -> Net {
        let net = Net::new(1, None);
        net.set_components([154]);
        net
    }

    fn screen(net: &Net, bytes: &[u8]) -> Screened {
        let mut d = decode_datagram(bytes);
        assert_eq!(d.len(), 1);
        net.screen(d.remove(0), Peer::Stream(1), &"test", &Stats::default())
    }

    fn ack_of(bytes: &[u8]) -> mavlink::dialects::common::COMMAND_ACK_DATA {
        match decode_datagram(bytes).pop() {
            Some(Decoded::Message(h, MavMessage::COMMAND_ACK(a))) => {
                assert_eq!((h.system_id, h.component_id), (1, 154), "from the gimbal");
                a
            }
            other => panic!("not an ACK: {other:?}"),
        }
    }

    #[test]
    fn a_command_id_the_dialect_does_not_know_is_answered_unsupported() {
        let net = net();
        let Screened::Answer(bytes) = screen(&net, &command_with_id(0xBEEF, (1, 154))) else {
            panic!("no answer")
        };
        // The ACK names the unknown id: read it raw (the dialect cannot).
        assert_eq!(bytes[7..10], [77, 0, 0], "COMMAND_ACK");
        assert_eq!(u16::from_le_bytes([bytes[10], bytes[11]]), 0xBEEF);
        assert_eq!(bytes[12], MavResult::MAV_RESULT_UNSUPPORTED as u8);
        assert!(matches!(scan(&bytes), Scan::Frame { skip: 0, .. }), "its CRC holds");
        // The same writer for a known id gives what the mavlink crate reads.
        let known = net.unsupported(154, MavCmd::MAV_CMD_DO_SET_SERVO as u16, GCS);
        let a = ack_of(&known);
        assert_eq!(
            (a.command, a.result, a.target_system, a.target_component),
            (
                MavCmd::MAV_CMD_DO_SET_SERVO,
                MavResult::MAV_RESULT_UNSUPPORTED,
                255,
                190
            )
        );
        // Not for one of our components: not answered.
        assert!(matches!(
            screen(&net, &command_with_id(0xBEEF, (1, 99))),
            Screened::Drop
        ));
        assert!(matches!(
            screen(&net, &command_with_id(0xBEEF, (2, 154))),
            Screened::Drop
        ));
    }

    #[test]
    fn control_given_to_components_never_heard_is_denied_here() {
        let net = net();
        let configure = |params: [f32; 4]| {
            let MavMessage::COMMAND_LONG(mut c) = command(MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, (1, 154), 0.0)
            else {
                unreachable!()
            };
            [c.param1, c.param2, c.param3, c.param4] = params;
            encode(header(GCS), &MavMessage::COMMAND_LONG(c))
        };
        let Screened::Answer(bytes) = screen(&net, &configure([200.0, 7.0, 201.0, 8.0])) else {
            panic!("not refused")
        };
        let a = ack_of(&bytes);
        assert_eq!(a.result, MavResult::MAV_RESULT_DENIED);
        assert_eq!((a.target_system, a.target_component), GCS);
        // Itself (heard now), and a component heard before: to the router.
        assert!(matches!(
            screen(&net, &configure([-2.0, -2.0, -1.0, -1.0])),
            Screened::Handle(..)
        ));
        net.screen(
            Decoded::Message(header((200, 7)), MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())),
            Peer::Stream(2),
            &"test",
            &Stats::default(),
        );
        assert!(matches!(
            screen(&net, &configure([200.0, 7.0, -1.0, -1.0])),
            Screened::Handle(..)
        ));
    }

    #[test]
    fn answers_go_to_the_asker_status_to_everyone() {
        let net = net();
        let ack = |command, result| crate::routing::answers::ack(command, result, GCS);
        assert_eq!(
            net.addressee(
                154,
                &ack(
                    MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
                    MavResult::MAV_RESULT_ACCEPTED
                )
            ),
            Some(GCS)
        );
        assert_eq!(
            net.addressee(154, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            None,
            "not requested: everyone"
        );
        net.addressee(
            154,
            &ack(MavCmd::MAV_CMD_REQUEST_MESSAGE, MavResult::MAV_RESULT_ACCEPTED),
        );
        assert_eq!(
            net.addressee(171, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            None,
            "another component's"
        );
        assert_eq!(
            net.addressee(154, &MavMessage::GIMBAL_MANAGER_INFORMATION(Default::default())),
            Some(GCS),
            "the requested message follows its ACK"
        );
        assert_eq!(
            net.addressee(154, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())),
            None
        );
        let to_zero =
            crate::routing::answers::ack(MavCmd::MAV_CMD_DO_SET_SERVO, MavResult::MAV_RESULT_UNSUPPORTED, (0, 0));
        assert_eq!(
            net.addressee(154, &to_zero),
            Some((0, 0)),
            "an ACK is never for everyone"
        );
    }
}
