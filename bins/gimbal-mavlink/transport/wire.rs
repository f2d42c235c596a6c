//! MAVLink frames on the wire, as every transport reads them (UDP in
//! `link`, TCP and serial lines in `stream`): [`scan`] finds the next
//! intact MAVLink 1 or 2 frame in place in a bounded buffer (CRC checked
//! with the dialect's CRC_EXTRA, MAVLink 2 serialization spec), so no
//! transport holds more than one buffer of a peer's bytes; [`decode`] reads
//! it, including a COMMAND_LONG or COMMAND_INT whose command id the dialect
//! does not know (answered MAV_RESULT_UNSUPPORTED by `net`).

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion, Message};

const V1_MAGIC: u8 = 0xFE;
pub const V2_MAGIC: u8 = 0xFD;
/// The longest frame (MAVLink 2, 255 bytes of payload, signed).
pub const MAX_FRAME: usize = 12 + 255 + 13;
/// The one incompatibility flag MAVLink 2 defines.
pub const SIGNED: u8 = 0x01;
const COMMAND_INT_ID: u32 = 75;
pub const COMMAND_LONG_ID: u32 = 76;
pub const COMMAND_ACK_ID: u32 = 77;

/// Where the next frame is in a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scan {
    /// `skip` bytes that are no intact frame, then a frame of `len` bytes.
    Frame { skip: usize, len: usize },
    /// `skip` bytes that are no intact frame; what follows may be the
    /// start of one (fewer than [`MAX_FRAME`] bytes): read more.
    Partial { skip: usize },
}

/// The next intact MAVLink 1 or 2 frame of `bytes` (its CRC checked with
/// the dialect's CRC_EXTRA; a message id the dialect does not know has
/// none, so its frames are not intact here). After a magic byte whose
/// frame does not check, the search goes on at the next byte.
pub fn scan(bytes: &[u8]) -> Scan {
    let mut i = 0;
    while i < bytes.len() {
        let rest = &bytes[i..];
        let total = match rest[0] {
            V2_MAGIC if rest.len() < 3 => return Scan::Partial { skip: i },
            // An incompatibility flag other than "signed": not a frame we can read.
            V2_MAGIC if rest[2] & !SIGNED != 0 => None,
            V2_MAGIC => Some(12 + usize::from(rest[1]) + if rest[2] & SIGNED != 0 { 13 } else { 0 }),
            V1_MAGIC if rest.len() < 2 => return Scan::Partial { skip: i },
            V1_MAGIC => Some(8 + usize::from(rest[1])),
            _ => None,
        };
        if let Some(total) = total {
            if rest.len() < total {
                return Scan::Partial { skip: i };
            }
            if crc_holds(&rest[..total]) {
                return Scan::Frame { skip: i, len: total };
            }
        }
        i += 1;
    }
    Scan::Partial { skip: bytes.len() }
}

/// The header's and payload's lengths, the message id and where the CRC is.
fn layout(frame: &[u8]) -> (usize, usize, u32) {
    let len = usize::from(frame[1]);
    if frame[0] == V2_MAGIC {
        (10, len, u32::from_le_bytes([frame[7], frame[8], frame[9], 0]))
    } else {
        (6, len, u32::from(frame[5]))
    }
}

fn crc_holds(frame: &[u8]) -> bool {
    let (header, len, id) = layout(frame);
    let end = header + len;
    let crc = u16::from_le_bytes([frame[end], frame[end + 1]]);
    crc == mavlink::calculate_crc(&frame[1..end], MavMessage::extra_crc(id))
}

/// An intact frame, read. (Its size is a message's: each is moved once,
/// never held in bulk; boxing would allocate per message.)
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Decoded {
    Message(MavHeader, MavMessage),
    /// A COMMAND_LONG or COMMAND_INT whose command id the dialect does not know (the
    /// `mavlink` crate refuses to read it: its command is an enum).
    UnknownCommand {
        header: MavHeader,
        target_system: u8,
        target_component: u8,
        command: u16,
        param7: f32,
    },
    /// Intact, but no message of the dialect (a field out of its enum): its length.
    Unreadable(MavHeader, usize),
}

/// Reads an intact `frame` (as [`scan`] found it).
pub fn decode(frame: &[u8]) -> Decoded {
    let (header_len, len, id) = layout(frame);
    let (sequence, system_id, component_id) = if frame[0] == V2_MAGIC {
        (frame[4], frame[5], frame[6])
    } else {
        (frame[2], frame[3], frame[4])
    };
    let header = MavHeader {
        system_id,
        component_id,
        sequence,
    };
    let version = if frame[0] == V2_MAGIC {
        MavlinkVersion::V2
    } else {
        MavlinkVersion::V1
    };
    let payload = &frame[header_len..header_len + len];
    match MavMessage::parse(version, id, payload) {
        Ok(message) => Decoded::Message(header, message),
        // COMMAND_INT has its z (param 7), command and targets where
        // COMMAND_LONG has them.
        Err(_) if id == COMMAND_LONG_ID || id == COMMAND_INT_ID => {
            // MAVLink 2 drops trailing zeros: read it back at full length.
            let mut p = [0u8; 33];
            let n = payload.len().min(p.len());
            p[..n].copy_from_slice(&payload[..n]);
            Decoded::UnknownCommand {
                header,
                param7: f32::from_le_bytes([p[24], p[25], p[26], p[27]]),
                command: u16::from_le_bytes([p[28], p[29]]),
                target_system: p[30],
                target_component: p[31],
            }
        }
        Err(_) => Decoded::Unreadable(header, frame.len()),
    }
}

/// The intact frames of a datagram, in order.
pub fn frames(datagram: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut at = 0;
    std::iter::from_fn(move || match scan(&datagram[at..]) {
        Scan::Frame { skip, len } => {
            let frame = &datagram[at + skip..at + skip + len];
            at += skip + len;
            Some(frame)
        }
        Scan::Partial { .. } => None,
    })
}

/// The intact frames of a datagram, read.
#[cfg(test)]
pub fn decode_datagram(datagram: &[u8]) -> Vec<Decoded> {
    frames(datagram).map(decode).collect()
}

/// `message` as a MAVLink 2 frame.
#[cfg(test)]
pub fn encode(header: MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut bytes = Vec::new();
    mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, message).expect("encode");
    bytes
}

/// A header from `who` (system, component), for the tests.
#[cfg(test)]
pub fn header(who: (u8, u8)) -> MavHeader {
    MavHeader {
        system_id: who.0,
        component_id: who.1,
        sequence: 7,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::HEARTBEAT_DATA;
    use proptest::prelude::*;

    const GCS: (u8, u8) = (255, 190);

    fn heartbeat() -> Vec<u8> {
        encode(header(GCS), &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
    }

    fn messages(bytes: &[u8]) -> usize {
        decode_datagram(bytes)
            .iter()
            .filter(|d| matches!(d, Decoded::Message(..)))
            .count()
    }

    #[test]
    fn intact_frames_are_read_damaged_ones_skipped() {
        let good = heartbeat();
        assert_eq!(messages(&good), 1);
        let mut two = good.clone();
        two.extend_from_slice(b"noise");
        two.extend_from_slice(&good);
        assert_eq!(messages(&two), 2);
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0xff;
        assert_eq!(messages(&bad), 0);
        assert_eq!(messages(&[]), 0);
        // MAVLink 1 too.
        let mut v1 = Vec::new();
        mavlink::write_versioned_msg(
            &mut v1,
            MavlinkVersion::V1,
            header(GCS),
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        )
        .unwrap();
        assert_eq!(messages(&v1), 1);
    }

    #[test]
    fn a_frame_split_anywhere_is_found_once_whole() {
        let good = heartbeat();
        for cut in 0..good.len() {
            assert!(
                matches!(scan(&good[..cut]), Scan::Partial { skip: 0 }),
                "a head of {cut} bytes waits"
            );
        }
        let mut noisy = vec![0x55, V2_MAGIC, 0x01];
        noisy.extend_from_slice(&good);
        assert_eq!(
            scan(&noisy),
            Scan::Frame {
                skip: 3,
                len: good.len()
            }
        );
    }

    proptest! {
        /// Any bytes: no panic, and the scan accounts for every byte.
        #[test]
        fn any_bytes_decode_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let _ = decode_datagram(&bytes);
            match scan(&bytes) {
                Scan::Frame { skip, len } => prop_assert!(skip + len <= bytes.len()),
                Scan::Partial { skip } => prop_assert!(skip <= bytes.len() && bytes.len() - skip < MAX_FRAME),
            }
        }

        /// One byte changed anywhere but the length (which moves where
        /// the CRC is read): never read as a message.
        #[test]
        fn a_damaged_frame_is_not_read(at in 0usize..21, flip in 1u8..=255) {
            let mut frame = heartbeat();
            let at = if at == 1 { 0 } else { at.min(frame.len() - 1) };
            frame[at] ^= flip;
            prop_assert_eq!(messages(&frame), 0);
        }
    }
}
