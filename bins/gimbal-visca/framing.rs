//! How VISCA messages travel: Sony's VISCA over IP on UDP (the SRG/BRC
//! technical manuals' "VISCA over IP": an 8-byte header, payload type
//! (2 bytes), payload length (2 bytes), sequence number (4 bytes), all
//! big-endian, then the payload of 1 to 16 bytes), and raw VISCA on a TCP
//! stream (PTZOptics: messages back to back, each ending `FF`). A
//! datagram that starts with a VISCA address byte (`8x`) and no header is
//! read as raw VISCA too, as PTZOptics cameras do on UDP.

use crate::visca::{MAX_MESSAGE, TERMINATOR};

/// The header's length.
pub const HEADER: usize = 8;

/// Payload types (Sony, "VISCA over IP": "Payload type").
pub mod payload_type {
    /// A VISCA command (`81 01 ...`).
    pub const COMMAND: u16 = 0x0100;
    /// A VISCA inquiry (`81 09 ...`).
    pub const INQUIRY: u16 = 0x0110;
    /// A VISCA reply (the camera's ACK, Completion, answer or error).
    pub const REPLY: u16 = 0x0111;
    /// A control command (`01` RESET).
    pub const CONTROL: u16 = 0x0200;
    /// A control reply (`01` ACK, `0F 01` sequence number, `0F 02` message).
    pub const CONTROL_REPLY: u16 = 0x0201;
}

/// Control payloads (Sony, "VISCA over IP": "Control command").
pub mod control {
    /// RESET: the sequence numbers start again.
    pub const RESET: [u8; 1] = [0x01];
    /// The camera's ACK of a control command.
    pub const ACK: [u8; 1] = [0x01];
    /// "Abnormality in the sequence number".
    pub const SEQUENCE_ERROR: [u8; 2] = [0x0F, 0x01];
    /// "Abnormality in the message (type)".
    pub const MESSAGE_ERROR: [u8; 2] = [0x0F, 0x02];
}

/// A datagram as read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Datagram<'a> {
    /// VISCA over IP: payload type, sequence number, payload.
    Ip {
        kind: u16,
        sequence: u32,
        payload: &'a [u8],
    },
    /// Raw VISCA (`8x ... FF`, no header).
    Raw(&'a [u8]),
}

/// Why a datagram was not read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Too short for a header, and not raw VISCA: dropped (no sequence
    /// number to answer with).
    Short(usize),
    /// The header's length is not the payload's, or the payload is empty
    /// or longer than 16 bytes: answered "abnormality in the message".
    Length {
        sequence: u32,
        declared: u16,
        actual: usize,
    },
}

/// Reads one datagram.
pub fn parse(datagram: &[u8]) -> Result<Datagram<'_>, FrameError> {
    if let Some(&first) = datagram.first() {
        if (0x81..=0x88).contains(&first) && datagram.len() <= MAX_MESSAGE && datagram.last() == Some(&TERMINATOR) {
            return Ok(Datagram::Raw(datagram));
        }
    }
    if datagram.len() < HEADER {
        return Err(FrameError::Short(datagram.len()));
    }
    let kind = u16::from_be_bytes([datagram[0], datagram[1]]);
    let declared = u16::from_be_bytes([datagram[2], datagram[3]]);
    let sequence = u32::from_be_bytes([datagram[4], datagram[5], datagram[6], datagram[7]]);
    let payload = &datagram[HEADER..];
    if payload.is_empty() || payload.len() > MAX_MESSAGE || usize::from(declared) != payload.len() {
        return Err(FrameError::Length {
            sequence,
            declared,
            actual: payload.len(),
        });
    }
    Ok(Datagram::Ip {
        kind,
        sequence,
        payload,
    })
}

/// A datagram of payload type `kind` with `sequence` and `payload`.
pub fn encode(kind: u16, sequence: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + payload.len());
    out.extend_from_slice(&kind.to_be_bytes());
    out.extend_from_slice(&(payload.len() as u16).to_be_bytes());
    out.extend_from_slice(&sequence.to_be_bytes());
    out.extend_from_slice(payload);
    out
}

/// What a stream holds, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Piece<'a> {
    /// A whole message, terminator included.
    Message(&'a [u8]),
    /// 16 bytes without a terminator: dropped up to the next one.
    Overlong,
}

/// Raw VISCA on a stream: bytes in, whole messages out. A message longer
/// than 16 bytes is dropped up to its terminator ([`Piece::Overlong`]);
/// the buffer never holds more than 16 bytes.
#[derive(Debug, Default)]
pub struct Deframer {
    buffer: Vec<u8>,
    skipping: bool,
}

impl Deframer {
    /// Feeds `bytes`, calling `each` with every piece in order.
    pub fn push(&mut self, bytes: &[u8], mut each: impl FnMut(Piece<'_>)) {
        for &b in bytes {
            if self.skipping {
                self.skipping = b != TERMINATOR;
                continue;
            }
            self.buffer.push(b);
            if b == TERMINATOR {
                each(Piece::Message(&self.buffer));
                self.buffer.clear();
            } else if self.buffer.len() >= MAX_MESSAGE {
                self.buffer.clear();
                self.skipping = true;
                each(Piece::Overlong);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_header_and_its_payload() {
        let d = [
            0x01, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00, 0x2A, 0x81, 0x01, 0x06, 0x04, 0xFF,
        ];
        assert_eq!(
            parse(&d),
            Ok(Datagram::Ip {
                kind: payload_type::COMMAND,
                sequence: 42,
                payload: &d[8..]
            })
        );
        assert_eq!(encode(payload_type::COMMAND, 42, &d[8..]), d);
        assert_eq!(
            parse(&[0x02, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x01]),
            Ok(Datagram::Ip {
                kind: payload_type::CONTROL,
                sequence: 1,
                payload: &[0x01]
            })
        );
        assert_eq!(
            parse(&[0x81, 0x09, 0x06, 0x12, 0xFF]),
            Ok(Datagram::Raw(&[0x81, 0x09, 0x06, 0x12, 0xFF]))
        );
    }

    #[test]
    fn a_bad_length_keeps_its_sequence_number() {
        let d = [
            0x01, 0x00, 0x00, 0x09, 0x00, 0x00, 0x01, 0x00, 0x81, 0x01, 0x06, 0x04, 0xFF,
        ];
        assert_eq!(
            parse(&d),
            Err(FrameError::Length {
                sequence: 256,
                declared: 9,
                actual: 5
            })
        );
        assert_eq!(parse(&[0x01, 0x00, 0x00]), Err(FrameError::Short(3)));
    }

    #[test]
    fn the_deframer_splits_and_drops_overlong_messages() {
        let mut d = Deframer::default();
        let mut got = Vec::new();
        let mut bytes = vec![0x81, 0x01, 0x06, 0x04, 0xFF, 0x81];
        bytes.extend([0x01; 30]);
        bytes.extend([0xFF, 0x81, 0x09, 0x06, 0x12, 0xFF]);
        let mut note = |p: Piece<'_>| match p {
            Piece::Message(m) => got.push(m.to_vec()),
            Piece::Overlong => got.push(Vec::new()),
        };
        d.push(&bytes[..7], &mut note);
        d.push(&bytes[7..], &mut note);
        assert_eq!(
            got,
            vec![
                vec![0x81, 0x01, 0x06, 0x04, 0xFF],
                Vec::new(),
                vec![0x81, 0x09, 0x06, 0x12, 0xFF]
            ]
        );
    }

    proptest! {
        /// Any datagram: read or refused, never a panic; what is read as
        /// VISCA over IP holds exactly the payload its header declares.
        #[test]
        fn any_datagram_is_read_or_refused(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            match parse(&bytes) {
                Ok(Datagram::Ip { payload, .. }) => {
                    prop_assert_eq!(usize::from(u16::from_be_bytes([bytes[2], bytes[3]])), payload.len());
                    prop_assert!(!payload.is_empty() && payload.len() <= MAX_MESSAGE);
                }
                Ok(Datagram::Raw(m)) => prop_assert!(m.len() <= MAX_MESSAGE && m.last() == Some(&TERMINATOR)),
                Err(_) => {}
            }
        }

        /// Encoding then reading gives back the sequence number and payload.
        #[test]
        fn encode_then_parse(sequence in any::<u32>(), payload in proptest::collection::vec(any::<u8>(), 1..=16)) {
            let d = encode(payload_type::REPLY, sequence, &payload);
            prop_assert_eq!(parse(&d), Ok(Datagram::Ip { kind: payload_type::REPLY, sequence, payload: &payload }));
        }

        /// However a stream of messages is cut, the deframer gives back the
        /// same messages, and holds at most 16 bytes.
        #[test]
        fn deframing_ignores_the_cuts(bodies in proptest::collection::vec(proptest::collection::vec(0u8..0xFF, 1..15), 1..10), cut in 1usize..20) {
            let mut stream = Vec::new();
            for b in &bodies {
                stream.extend(b);
                stream.push(TERMINATOR);
            }
            let mut d = Deframer::default();
            let mut got = Vec::new();
            for chunk in stream.chunks(cut) {
                d.push(chunk, |p| if let Piece::Message(m) = p { got.push(m.to_vec()) });
                prop_assert!(d.buffer.len() <= MAX_MESSAGE);
            }
            let want: Vec<Vec<u8>> = bodies.iter().map(|b| { let mut m = b.clone(); m.push(TERMINATOR); m }).collect();
            prop_assert_eq!(got, want);
        }
    }
}
