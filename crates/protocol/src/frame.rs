//! The wire frame of Table 1, its checksum, and the bare ACK/NAK/NIC bytes
//! of 1.4.2.
//!
//! The layout is declared once, in [`layout`] (byte offsets) and
//! [`PayloadLen`] (the one length check, 1..=256): [`Frame::parse`], the
//! framer's candidate scan and [`FrameBuf`] all read and write frames through
//! them and through [`Header`].

use crate::EncodeError;
use crate::address::Address;
use crate::hex::Writer;

/// Start character, Table 1 byte 1.
pub const START: u8 = 0xF8;
/// Positive acknowledge, 1.4.2.
pub const ACK: u8 = 0x06;
/// Negative acknowledge (bad checksum), 1.4.2.
pub const NAK: u8 = 0x15;
/// Non-implemented command, 1.4.2.
pub const NIC: u8 = b'?';
/// Start, three address bytes, source group, length (Table 1 bytes 1-6).
pub const HEADER_LEN: usize = layout::PAYLOAD;
/// Largest payload; a length byte of 0 stands for it (1.4.1.1).
pub const MAX_PAYLOAD: usize = 256;
/// Largest frame on the wire: header, 256 payload bytes, checksum.
pub const MAX_FRAME_LEN: usize = layout::wire_len(PayloadLen::MAX);

/// Table 1, declared once: where each field of a frame lies (0-based byte
/// offsets; the table counts from 1). Everything that reads or writes a
/// frame's bytes goes through these.
pub mod layout {
    use core::ops::Range;

    use super::PayloadLen;

    /// `0xF8`, Table 1 byte 1.
    pub const START: usize = 0;
    /// Destination group, byte 2.
    pub const GROUP: usize = 1;
    /// Destination port, byte 3.
    pub const PORT: usize = 2;
    /// Destination device, byte 4.
    pub const DEVICE: usize = 3;
    /// Source group, byte 5.
    pub const SOURCE: usize = 4;
    /// Payload length, byte 6 (0 stands for 256).
    pub const LENGTH: usize = 5;
    /// First payload byte, byte 7; also the header length.
    pub const PAYLOAD: usize = 6;

    /// The payload bytes of a frame carrying `len` of them.
    pub const fn payload(len: PayloadLen) -> Range<usize> {
        PAYLOAD..PAYLOAD + len.get()
    }

    /// The checksum byte, right after the payload.
    pub const fn checksum(len: PayloadLen) -> usize {
        PAYLOAD + len.get()
    }

    /// The bytes the checksum sums (1.4.1.3): group through last payload byte.
    pub const fn summed(len: PayloadLen) -> Range<usize> {
        GROUP..checksum(len)
    }

    /// Bytes the whole frame takes on the wire.
    pub const fn wire_len(len: PayloadLen) -> usize {
        checksum(len) + 1
    }
}

/// Straight sum of bytes ignoring overflow (1.4.1.3), over bytes 2 .. 6+len.
pub fn checksum(header_and_payload_after_start: &[u8]) -> u8 {
    header_and_payload_after_start
        .iter()
        .fold(0u8, |acc, &b| acc.wrapping_add(b))
}

/// A payload length a frame can carry, 1..=256 (Table 1, 1.4.1.1). Its
/// constructor is the one length check of the crate: a value of this type
/// is always a valid length, so ranges built from it ([`layout`]) always
/// fit a [`MAX_FRAME_LEN`] buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PayloadLen(u16);

impl PayloadLen {
    /// The shortest payload: one byte.
    pub const MIN: PayloadLen = PayloadLen(1);
    /// The longest payload: 256 bytes, sent as length byte 0.
    pub const MAX: PayloadLen = PayloadLen(MAX_PAYLOAD as u16);

    /// `len` if a frame can carry it (1..=256).
    pub const fn new(len: usize) -> Result<Self, FrameError> {
        if len == 0 || len > MAX_PAYLOAD {
            return Err(FrameError::PayloadLength { len });
        }
        Ok(Self(len as u16))
    }

    /// The length a length byte announces: every byte is one, 0 means 256.
    pub const fn from_byte(byte: u8) -> Self {
        if byte == 0 { Self::MAX } else { Self(byte as u16) }
    }

    /// The length byte that carries it: 256 is sent as 0.
    pub const fn byte(self) -> u8 {
        self.0 as u8
    }

    /// The length in bytes.
    pub const fn get(self) -> usize {
        self.0 as usize
    }
}

/// Payload length as carried in the length byte: 256 is sent as 0.
pub const fn length_byte(payload_len: usize) -> u8 {
    payload_len as u8
}

/// Payload length that a length byte announces: 0 means 256.
pub const fn payload_len(length_byte: u8) -> usize {
    PayloadLen::from_byte(length_byte).get()
}

/// Table 1 bytes 1-6 as fields: the destination, the source group and the
/// payload length (always valid: see [`PayloadLen`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// Destination, bytes 2-4.
    pub dest: Address,
    /// Source group, byte 5.
    pub source: u8,
    /// Payload length, byte 6.
    pub len: PayloadLen,
}

impl Header {
    /// Reads the fields of a header; the start byte is the caller's to check.
    pub const fn read(bytes: &[u8; HEADER_LEN]) -> Self {
        Self {
            dest: Address::new(bytes[layout::GROUP], bytes[layout::PORT], bytes[layout::DEVICE]),
            source: bytes[layout::SOURCE],
            len: PayloadLen::from_byte(bytes[layout::LENGTH]),
        }
    }

    /// The header's wire bytes, start byte included.
    pub const fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut bytes = [0u8; HEADER_LEN];
        bytes[layout::START] = START;
        bytes[layout::GROUP] = self.dest.group;
        bytes[layout::PORT] = self.dest.port;
        bytes[layout::DEVICE] = self.dest.device;
        bytes[layout::SOURCE] = self.source;
        bytes[layout::LENGTH] = self.len.byte();
        bytes
    }

    /// The header's share of the checksum (bytes 2-6).
    fn checksum(&self) -> u8 {
        let bytes = self.to_bytes();
        checksum(bytes.get(layout::GROUP..).unwrap_or_default())
    }
}

/// A zero-copy view of one valid frame (Table 1). Constructing one checks
/// the payload length; the checksum is computed on encode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<'a> {
    /// Destination, header bytes 2-4.
    pub dest: Address,
    /// Source GCU address, header byte 5.
    pub source: u8,
    payload: &'a [u8],
}

/// Why bytes are not one valid frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The payload length is not 1..=256.
    #[error("payload of {len} bytes: a frame carries 1..=256")]
    PayloadLength {
        /// The payload length given or read.
        len: usize,
    },
    /// The first byte is not [`START`].
    #[error("byte 0x{found:02X} at offset 0 is not the start character 0xF8")]
    BadStart {
        /// The first byte.
        found: u8,
    },
    /// Fewer bytes than the length byte announces.
    #[error("frame incomplete: {needed} bytes needed, {available} available")]
    Incomplete {
        /// Bytes the whole frame needs.
        needed: usize,
        /// Bytes there are.
        available: usize,
    },
    /// The checksum byte does not match the frame.
    #[error("checksum at offset {offset}: expected 0x{expected:02X}, found 0x{found:02X}")]
    BadChecksum {
        /// Offset of the checksum byte.
        offset: usize,
        /// The checksum the frame's bytes give.
        expected: u8,
        /// The checksum byte received.
        found: u8,
    },
}

impl<'a> Frame<'a> {
    /// A frame for `dest` from group `source`; the payload must be 1..=256 bytes.
    pub fn new(dest: Address, source: u8, payload: &'a [u8]) -> Result<Self, FrameError> {
        PayloadLen::new(payload.len())?;
        Ok(Self { dest, source, payload })
    }

    /// The command or result bytes.
    pub fn payload(&self) -> &'a [u8] {
        self.payload
    }

    /// The header this frame carries.
    pub fn header(&self) -> Header {
        Header {
            dest: self.dest,
            source: self.source,
            // `new` and `parse` admit only valid lengths.
            len: PayloadLen(self.payload.len() as u16),
        }
    }

    /// Bytes this frame takes on the wire.
    pub fn wire_len(&self) -> usize {
        layout::wire_len(self.header().len)
    }

    /// The checksum byte this frame carries (1.4.1.3).
    pub fn checksum(&self) -> u8 {
        self.header().checksum().wrapping_add(checksum(self.payload))
    }

    /// Parses one frame at the start of `input`; returns it and the bytes after it.
    pub fn parse(input: &'a [u8]) -> Result<(Self, &'a [u8]), FrameError> {
        let available = input.len();
        let incomplete = |needed| FrameError::Incomplete { needed, available };
        // A wrong first byte is the error, however short the input.
        if let Some(&found) = input.first().filter(|&&b| b != START) {
            return Err(FrameError::BadStart { found });
        }
        let (header, _) = input.split_first_chunk::<HEADER_LEN>().ok_or(incomplete(HEADER_LEN))?;
        let header = Header::read(header);
        let wire_len = layout::wire_len(header.len);
        let (frame, rest) = input.split_at_checked(wire_len).ok_or(incomplete(wire_len))?;
        let frame = Self::check(header, frame).map_err(|(expected, found)| FrameError::BadChecksum {
            offset: layout::checksum(header.len),
            expected,
            found,
        })?;
        Ok((frame, rest))
    }

    /// The frame in `span`, the bytes of one frame with this `header` (the
    /// framer's candidates, `parse`): `Err((expected, found))` if its
    /// checksum does not hold.
    pub(crate) fn check(header: Header, span: &'a [u8]) -> Result<Self, (u8, u8)> {
        // `span` is `layout::wire_len(header.len)` bytes: the checksum is its
        // last byte, and what it sums and the payload lie before it.
        let (&found, body) = span.split_last().unwrap_or((&0, &[]));
        let expected = checksum(body.get(layout::GROUP..).unwrap_or_default());
        if expected != found {
            return Err((expected, found));
        }
        Ok(Frame {
            dest: header.dest,
            source: header.source,
            payload: body.get(layout::PAYLOAD..).unwrap_or_default(),
        })
    }

    /// Writes the frame into `buf`; returns the written prefix.
    pub fn encode<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EncodeError> {
        let mut w = Writer::new(buf);
        w.put(&self.header().to_bytes())?;
        w.put(self.payload)?;
        w.byte(self.checksum())?;
        Ok(w.finish())
    }

    /// Header of the result this frame's addressee sends back (Table 3):
    /// groups exchanged, port and device unchanged.
    pub fn reply_header(&self) -> (Address, u8) {
        (
            Address::new(self.source, self.dest.port, self.dest.device),
            self.dest.group,
        )
    }
}

/// An owned, fixed-size copy of one encoded frame (263 bytes), for queues.
///
/// Always a valid frame: every constructor writes a whole frame, and its
/// length is the header's length byte, which always announces 1..=256
/// bytes ([`PayloadLen`]), so there is no length that could disagree with
/// the bytes. Equality and hashing look at the frame's wire bytes only.
#[derive(Clone)]
pub struct FrameBuf {
    bytes: [u8; MAX_FRAME_LEN],
}

impl FrameBuf {
    /// A valid stand-in frame (payload `0` to `0.0.0` from group 0) for a
    /// slot that holds no frame of its own yet; never meant to be sent.
    pub const PLACEHOLDER: FrameBuf = {
        let header = Header {
            dest: Address::new(0, 0, 0),
            source: 0,
            len: PayloadLen::MIN,
        };
        let mut bytes = [0u8; MAX_FRAME_LEN];
        let head = header.to_bytes();
        let mut i = 0;
        let mut sum = 0u8;
        while i < HEADER_LEN {
            bytes[i] = head[i];
            if i >= layout::GROUP {
                sum = sum.wrapping_add(head[i]);
            }
            i += 1;
        }
        bytes[layout::PAYLOAD] = b'0';
        bytes[layout::checksum(PayloadLen::MIN)] = sum.wrapping_add(b'0');
        FrameBuf { bytes }
    };

    /// The device endpoint's name for [`FrameBuf::PLACEHOLDER`] (its
    /// last-result slot before any result; `resends_left` 0 keeps it unsent).
    pub(crate) const EMPTY: FrameBuf = FrameBuf::PLACEHOLDER;

    /// Copies `frame` in its wire form. Infallible: a [`Frame`] is always valid.
    pub fn from_frame(frame: &Frame<'_>) -> Self {
        let mut buf = Self::PLACEHOLDER;
        let header = frame.header();
        for (slot, &byte) in buf.payload_space().iter_mut().zip(frame.payload) {
            *slot = byte;
        }
        buf.seal(header);
        buf
    }

    /// Builds a frame around `payload` (1..=256 bytes).
    pub fn new(dest: Address, source: u8, payload: &[u8]) -> Result<Self, FrameError> {
        Ok(Self::from_frame(&Frame::new(dest, source, payload)?))
    }

    /// Builds a frame whose payload `encode` writes into the scratch space
    /// it is given (a command or reply encoder).
    pub fn build(
        dest: Address,
        source: u8,
        encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<Self, EncodeError> {
        // Zeroed scratch: not a frame until `seal`, and never seen unsealed.
        let mut frame = Self {
            bytes: [0u8; MAX_FRAME_LEN],
        };
        let len = frame.encode_payload(encode)?;
        frame.seal(Header { dest, source, len });
        Ok(frame)
    }

    /// [`FrameBuf::build`] in place: overwrites this buffer, so that a
    /// caller that keeps the frame (the device endpoint's last result) needs
    /// no second copy of it on the stack. On error the buffer holds
    /// [`FrameBuf::PLACEHOLDER`]'s frame (the old payload may be overwritten).
    pub(crate) fn rebuild(
        &mut self,
        dest: Address,
        source: u8,
        encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<(), EncodeError> {
        match self.encode_payload(encode) {
            Ok(len) => {
                self.seal(Header { dest, source, len });
                Ok(())
            }
            Err(e) => {
                self.reset_to_placeholder();
                Err(e)
            }
        }
    }

    /// Runs a payload encoder over the payload space; the length it reports
    /// passes the one length check or is an error.
    fn encode_payload(
        &mut self,
        encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<PayloadLen, EncodeError> {
        let n = encode(self.payload_space())?;
        PayloadLen::new(n).map_err(|_| EncodeError::PayloadLength { len: n })
    }

    /// The 256 bytes a payload may occupy.
    fn payload_space(&mut self) -> &mut [u8] {
        // Through `get_mut`, not indexing, so that no bounds-check panic is
        // linked into firmware: the range always fits.
        self.bytes.get_mut(layout::payload(PayloadLen::MAX)).unwrap_or_default()
    }

    /// Writes `header` and the checksum over it and the payload bytes
    /// already in place: the one place a `FrameBuf` becomes a frame.
    fn seal(&mut self, header: Header) {
        if let Some((head, _)) = self.bytes.split_first_chunk_mut::<HEADER_LEN>() {
            *head = header.to_bytes();
        }
        let sum = checksum(self.bytes.get(layout::summed(header.len)).unwrap_or_default());
        if let Some(slot) = self.bytes.get_mut(layout::checksum(header.len)) {
            *slot = sum;
        }
    }

    /// Back to the placeholder's frame, writing only its few bytes.
    fn reset_to_placeholder(&mut self) {
        let placeholder = Self::PLACEHOLDER;
        let frame = placeholder.frame();
        for (slot, &byte) in self.payload_space().iter_mut().zip(frame.payload) {
            *slot = byte;
        }
        self.seal(frame.header());
    }

    /// The header this frame carries.
    pub fn header(&self) -> Header {
        let [start, group, port, device, source, len, ..] = self.bytes;
        Header::read(&[start, group, port, device, source, len])
    }

    /// The frame's wire bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes
            .get(..layout::wire_len(self.header().len))
            .unwrap_or_default()
    }

    /// A view of the frame.
    pub fn frame(&self) -> Frame<'_> {
        let header = self.header();
        Frame {
            dest: header.dest,
            source: header.source,
            payload: self.bytes.get(layout::payload(header.len)).unwrap_or_default(),
        }
    }

    /// Rewrites the header (destination and source) and recomputes the checksum.
    pub fn set_header(&mut self, dest: Address, source: u8) {
        let len = self.header().len;
        self.seal(Header { dest, source, len });
    }
}

impl PartialEq for FrameBuf {
    fn eq(&self, other: &Self) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl Eq for FrameBuf {}

impl core::hash::Hash for FrameBuf {
    fn hash<H: core::hash::Hasher>(&self, state: &mut H) {
        self.as_bytes().hash(state);
    }
}

impl core::fmt::Debug for FrameBuf {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("FrameBuf").field(&self.frame()).finish()
    }
}

/// As its [`Frame`]: header fields and payload, not 263 raw bytes.
#[cfg(feature = "defmt")]
impl defmt::Format for FrameBuf {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "FrameBuf({})", self.frame());
    }
}

impl<'a> From<&Frame<'a>> for FrameBuf {
    fn from(frame: &Frame<'a>) -> Self {
        Self::from_frame(frame)
    }
}

impl<'a> From<Frame<'a>> for FrameBuf {
    fn from(frame: Frame<'a>) -> Self {
        Self::from_frame(&frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_table_1() {
        // `P?` to 5.1.12 from 2 (Table 3 example): F8 05 01 0C 02 02 50 3F A5.
        let bytes = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
        let header = Header::read(bytes.first_chunk().unwrap());
        assert_eq!(header.dest, Address::new(5, 1, 12));
        assert_eq!((header.source, header.len.get()), (2, 2));
        assert_eq!(header.to_bytes(), bytes[..HEADER_LEN]);
        assert_eq!(&bytes[layout::payload(header.len)], b"P?");
        assert_eq!(bytes[layout::checksum(header.len)], 0xA5);
        assert_eq!(checksum(&bytes[layout::summed(header.len)]), 0xA5);
        assert_eq!(layout::wire_len(header.len), bytes.len());
        assert_eq!((HEADER_LEN, MAX_FRAME_LEN), (6, 263));
    }

    #[test]
    fn payload_len_is_the_one_gate() {
        assert_eq!(PayloadLen::new(0), Err(FrameError::PayloadLength { len: 0 }));
        assert_eq!(PayloadLen::new(257), Err(FrameError::PayloadLength { len: 257 }));
        assert_eq!(PayloadLen::new(256).map(PayloadLen::byte), Ok(0));
        for byte in 0..=u8::MAX {
            let len = PayloadLen::from_byte(byte);
            assert_eq!(PayloadLen::new(len.get()), Ok(len));
            assert_eq!(len.byte(), byte);
            assert!(layout::wire_len(len) <= MAX_FRAME_LEN);
        }
    }

    #[test]
    fn frame_buf_is_always_a_frame() {
        let placeholder = FrameBuf::PLACEHOLDER;
        let (frame, rest) = Frame::parse(placeholder.as_bytes()).unwrap();
        assert_eq!((frame, rest), (placeholder.frame(), &[][..]));
        assert_eq!(FrameBuf::EMPTY, placeholder);

        // A failed rebuild leaves a valid frame, never a length of 0.
        let mut buf = FrameBuf::new(Address::new(1, 2, 3), 4, &[b'x'; 200]).unwrap();
        for bad in [0usize, 257] {
            let err = buf.rebuild(Address::new(1, 1, 1), 0, |space| {
                space.fill(b'y');
                Ok(bad)
            });
            assert_eq!(err, Err(EncodeError::PayloadLength { len: bad }));
            assert_eq!(buf, placeholder);
            assert!(Frame::parse(buf.as_bytes()).is_ok());
        }
        let err = buf.rebuild(Address::new(1, 1, 1), 0, |_| Err(EncodeError::PayloadLength { len: 0 }));
        assert!(err.is_err());
        assert_eq!(buf, placeholder);

        // Equality is by wire bytes: a shorter frame rebuilt over a longer one
        // equals the same frame built fresh.
        let mut long = FrameBuf::new(Address::new(1, 2, 3), 4, &[b'x'; 256]).unwrap();
        long.rebuild(Address::new(5, 1, 12), 2, |space| {
            space[..2].copy_from_slice(b"P?");
            Ok(2)
        })
        .unwrap();
        let fresh = FrameBuf::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
        assert_eq!(long, fresh);
        assert_eq!(long.as_bytes(), [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5]);

        // 256 payload bytes: length byte 0, and the view gives them all back.
        let max = FrameBuf::new(Address::new(1, 1, 1), 0, &[b'z'; 256]).unwrap();
        assert_eq!(max.as_bytes().len(), MAX_FRAME_LEN);
        assert_eq!(max.as_bytes()[layout::LENGTH], 0);
        assert_eq!(max.frame().payload(), &[b'z'; 256][..]);
        let mut moved = max.clone();
        moved.set_header(Address::new(9, 8, 7), 6);
        assert_eq!(Frame::parse(moved.as_bytes()).unwrap().0.payload(), &[b'z'; 256][..]);
    }
}
