//! Delivery reports: how a GCU tells the sender of a command whether the
//! command was delivered (a project extension of 1.4.2, written down in the
//! project's `ARCHITECTURE.md`, "Delivery contract").
//!
//! On the bus the ACK comes from the device itself (1.4.2: "a single ACK
//! character is sent back from the device"). A GCU keeps that meaning: it
//! returns the ACK for a command only once the device (or the next GCU,
//! under the same contract) acknowledged it. When the command cannot be
//! delivered, no ACK is sent, so a client that knows only the spec sees
//! what it would see on the bus (no ACK: retransmit, then give up), and a
//! report frame says why. Between two GCUs, where ACKs stay hop by hop
//! (one link carries many clients' commands, and an ACK names none), the
//! GCU that executes a command reports every outcome, `00` (delivered)
//! included, so that the first GCU can ACK its client truthfully.
//!
//! ```text
//! header   dest = (command's source group, port 0, device 0)   source = reporting GCU
//! payload  '!' CC GGPPDD KK RR        (13 printable ASCII characters)
//!          CC      00 delivered, else the failure code ([`Undelivered`])
//!          GGPPDD  the undelivered command's destination address
//!          KK      the undelivered command frame's checksum (tells apart two
//!                  commands to one address)
//!          RR      the group of the GCU where delivery failed
//! ```
//!
//! Port 0 / device 0 is the MCU/GCU itself as a destination (Table 2), so
//! the report never has the Table 3 header of a device's result; a spec
//! client awaiting its ACK ignores it (and acknowledges it hop by hop, as
//! every good frame).

use crate::address::Address;
use crate::hex::{hex_digit, hex_value};

/// First payload byte of a delivery report (never the first byte of a command or reply).
pub const REPORT_MARK: u8 = b'!';
/// Payload length of a delivery report.
pub const REPORT_LEN: usize = 13;

crate::code_table! {
    /// Why a command was not delivered. The code is the report's `CC`,
    /// from 0x01 in row order (a new reason goes at the end); the name
    /// labels metrics and JSON; the meaning is for a person.
    pub enum Undelivered: u8 {
        /// the device did not acknowledge it (silent after all retries)
        DeviceSilent = 0x01,
        /// the device answered NAK to every transmission
        DeviceNak,
        /// no such port on the GCU
        NoSuchPort,
        /// the port is not open
        PortClosed,
        /// a queue on the way was full
        QueueFull,
        /// no route to the destination group
        NoRoute,
        /// the link toward the destination is down or did not acknowledge
        LinkDown,
        /// the GCU is shutting down
        ShuttingDown,
        /// the link may not speak as that source group
        SourceNotAllowed,
        /// the only route leads back where the command came from
        Loop,
        /// delivery was not confirmed in time (it may still execute)
        NotConfirmed,
        /// it waited in a queue too long and was given up unsent
        Expired,
        /// another link of equal or higher priority controls the gimbal
        NotInControl,
        /// its target lies outside the gimbal's travel limits
        TravelLimit,
        /// its path may enter a keep-out zone
        KeepOut,
        /// the gimbal's position is unknown and it has limits or zones
        PositionUnknown,
        /// a stop for the same gimbal overtook it before it reached the bus
        Superseded,
        /// the gimbal has limits, zones, park or a tour, and the command moves or changes it where gcud cannot bound it (the allow list of its gimbal entry may name it)
        Ungoverned,
        /// a stop from a link below the gimbal's holder, sooner than one second after its last
        StopsLimited,
        /// a speed change whose rate gcud does not know, while the gimbal slews toward a limit or zone
        RateUnknown,
        /// the gimbal did not say where the preset lies, and it has limits or zones
        PresetUnknown,
        /// the link's priority does not permit it (tours, reading a gimbal's rules)
        NotPermitted,
    }
}

impl Undelivered {
    /// A refusal by gcud's governance (ARCHITECTURE "Governance"): nothing
    /// reached the bus because of a rule, not a fault; a door shows it as
    /// gcud's decision and keeps no list of its own.
    pub const fn is_refusal(self) -> bool {
        matches!(
            self,
            Undelivered::NotInControl
                | Undelivered::TravelLimit
                | Undelivered::KeepOut
                | Undelivered::PositionUnknown
                | Undelivered::Ungoverned
                | Undelivered::StopsLimited
                | Undelivered::RateUnknown
                | Undelivered::PresetUnknown
                | Undelivered::NotPermitted
        )
    }
}

/// A parsed or to-be-sent delivery report (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DeliveryReport {
    /// `None`: delivered (code 00); else why not.
    pub failure: Option<Undelivered>,
    /// The undelivered command's destination.
    pub dest: Address,
    /// The undelivered command frame's checksum byte.
    pub command_checksum: u8,
    /// The group of the GCU where delivery failed.
    pub at_group: u8,
}

/// A payload that is not a delivery report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("not a delivery report (byte {offset})")]
pub struct NotAReport {
    /// Offset of the first byte that does not fit.
    pub offset: usize,
}

impl DeliveryReport {
    /// The report's payload.
    pub fn encode(&self) -> [u8; REPORT_LEN] {
        let mut out = [0u8; REPORT_LEN];
        out[0] = REPORT_MARK;
        let bytes = [
            self.failure.map_or(0, Undelivered::code),
            self.dest.group,
            self.dest.port,
            self.dest.device,
            self.command_checksum,
            self.at_group,
        ];
        for (pair, byte) in out[1..].chunks_exact_mut(2).zip(bytes) {
            pair[0] = hex_digit(byte >> 4);
            pair[1] = hex_digit(byte & 0x0F);
        }
        out
    }

    /// Whether a payload looks like a report (its first byte), without parsing it.
    pub fn is_report(payload: &[u8]) -> bool {
        payload.first() == Some(&REPORT_MARK)
    }

    /// Parses a report payload; the offset of the first wrong byte otherwise.
    pub fn parse(payload: &[u8]) -> Result<Self, NotAReport> {
        if payload.first() != Some(&REPORT_MARK) {
            return Err(NotAReport { offset: 0 });
        }
        if payload.len() != REPORT_LEN {
            return Err(NotAReport {
                offset: payload.len().min(REPORT_LEN),
            });
        }
        let mut bytes = [0u8; 6];
        for (i, byte) in bytes.iter_mut().enumerate() {
            let at = 1 + 2 * i;
            let high = payload.get(at).copied().and_then(hex_value);
            let low = payload.get(at + 1).copied().and_then(hex_value);
            match (high, low) {
                (Some(h), Some(l)) => *byte = (h << 4) | l,
                (None, _) => return Err(NotAReport { offset: at }),
                (_, None) => return Err(NotAReport { offset: at + 1 }),
            }
        }
        let [code, group, port, device, command_checksum, at_group] = bytes;
        let failure = match code {
            0 => None,
            code => Some(Undelivered::from_code(code).ok_or(NotAReport { offset: 1 })?),
        };
        Ok(Self {
            failure,
            dest: Address::new(group, port, device),
            command_checksum,
            at_group,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_layout() {
        let report = DeliveryReport {
            failure: Some(Undelivered::DeviceSilent),
            dest: Address::new(5, 1, 12),
            command_checksum: 0xA5,
            at_group: 5,
        };
        let payload = report.encode();
        assert_eq!(&payload, b"!0105010CA505");
        assert_eq!(DeliveryReport::parse(&payload), Ok(report));
        for failure in Undelivered::ALL.map(Some).into_iter().chain([None]) {
            let r = DeliveryReport { failure, ..report };
            assert_eq!(DeliveryReport::parse(&r.encode()), Ok(r));
        }
    }

    #[test]
    fn refuses_what_is_not_a_report_naming_the_byte() {
        assert_eq!(DeliveryReport::parse(b"P?"), Err(NotAReport { offset: 0 }));
        assert_eq!(DeliveryReport::parse(b"!01"), Err(NotAReport { offset: 3 }));
        assert_eq!(DeliveryReport::parse(b"!01050G0CA505"), Err(NotAReport { offset: 6 }));
        assert_eq!(DeliveryReport::parse(b"!FF05010CA505"), Err(NotAReport { offset: 1 }));
    }
}
