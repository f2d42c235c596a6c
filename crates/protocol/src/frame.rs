//! The wire frame of Table 1, its checksum, and the bare ACK/NAK/NIC bytes
//! of 1.4.2.

use nom::Parser;
use nom::bytes::complete::take;
use nom::number::complete::u8 as any_u8;

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
pub const HEADER_LEN: usize = 6;
/// Largest payload; a length byte of 0 stands for it (1.4.1.1).
pub const MAX_PAYLOAD: usize = 256;
/// Largest frame on the wire: header, 256 payload bytes, checksum.
pub const MAX_FRAME_LEN: usize = HEADER_LEN + MAX_PAYLOAD + 1;

/// Straight sum of bytes ignoring overflow (1.4.1.3), over bytes 2 .. 6+len.
pub fn checksum(header_and_payload_after_start: &[u8]) -> u8 {
    header_and_payload_after_start
        .iter()
        .fold(0u8, |acc, &b| acc.wrapping_add(b))
}

/// Payload length as carried in the length byte: 256 is sent as 0.
pub const fn length_byte(payload_len: usize) -> u8 {
    payload_len as u8
}

/// Payload length that a length byte announces: 0 means 256.
pub const fn payload_len(length_byte: u8) -> usize {
    if length_byte == 0 {
        MAX_PAYLOAD
    } else {
        length_byte as usize
    }
}

/// A zero-copy view of one valid frame (Table 1). Constructing one checks
/// the payload length; the checksum is computed on encode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Frame<'a> {
    /// Destination, header bytes 2-4.
    pub dest: Address,
    /// Source GCU address, header byte 5.
    pub source: u8,
    payload: &'a [u8],
}

/// Why bytes are not one valid frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    #[error("payload of {len} bytes: a frame carries 1..=256")]
    PayloadLength { len: usize },
    #[error("byte 0x{found:02X} at offset 0 is not the start character 0xF8")]
    BadStart { found: u8 },
    #[error("frame incomplete: {needed} bytes needed, {available} available")]
    Incomplete { needed: usize, available: usize },
    #[error("checksum at offset {offset}: expected 0x{expected:02X}, found 0x{found:02X}")]
    BadChecksum { offset: usize, expected: u8, found: u8 },
}

impl<'a> Frame<'a> {
    /// A frame for `dest` from group `source`; the payload must be 1..=256 bytes.
    pub fn new(dest: Address, source: u8, payload: &'a [u8]) -> Result<Self, FrameError> {
        if payload.is_empty() || payload.len() > MAX_PAYLOAD {
            return Err(FrameError::PayloadLength { len: payload.len() });
        }
        Ok(Self { dest, source, payload })
    }

    /// The command or result bytes.
    pub fn payload(&self) -> &'a [u8] {
        self.payload
    }

    /// Bytes this frame takes on the wire.
    pub fn wire_len(&self) -> usize {
        HEADER_LEN + self.payload.len() + 1
    }

    /// The checksum byte this frame carries (1.4.1.3).
    pub fn checksum(&self) -> u8 {
        let header = [
            self.dest.group,
            self.dest.port,
            self.dest.device,
            self.source,
            length_byte(self.payload.len()),
        ];
        checksum(&header).wrapping_add(checksum(self.payload))
    }

    /// Parses one frame at the start of `input`; returns it and the bytes after it.
    pub fn parse(input: &'a [u8]) -> Result<(Self, &'a [u8]), FrameError> {
        let available = input.len();
        let incomplete = |needed| FrameError::Incomplete { needed, available };
        // A wrong first byte is the error, however short the input.
        if let Some(&found) = input.first().filter(|&&b| b != START) {
            return Err(FrameError::BadStart { found });
        }
        let mut header = (
            any_u8::<_, nom::error::Error<&[u8]>>,
            any_u8,
            any_u8,
            any_u8,
            any_u8,
            any_u8,
        );
        let (rest, (start, group, port, device, source, len)) =
            header.parse(input).map_err(|_| incomplete(HEADER_LEN))?;
        if start != START {
            return Err(FrameError::BadStart { found: start });
        }
        let n = payload_len(len);
        let mut body = (take::<_, _, nom::error::Error<&[u8]>>(n), any_u8);
        let (rest, (payload, found)) = body.parse(rest).map_err(|_| incomplete(HEADER_LEN + n + 1))?;
        let frame = Frame {
            dest: Address::new(group, port, device),
            source,
            payload,
        };
        let expected = frame.checksum();
        if expected != found {
            return Err(FrameError::BadChecksum {
                offset: HEADER_LEN + n,
                expected,
                found,
            });
        }
        Ok((frame, rest))
    }

    /// Writes the frame into `buf`; returns the written prefix.
    pub fn encode<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EncodeError> {
        let mut w = Writer::new(buf);
        w.put(&[
            START,
            self.dest.group,
            self.dest.port,
            self.dest.device,
            self.source,
            length_byte(self.payload.len()),
        ])?;
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
#[derive(Clone, PartialEq, Eq)]
pub struct FrameBuf {
    bytes: [u8; MAX_FRAME_LEN],
    len: u16,
}

impl FrameBuf {
    /// No frame yet: `as_bytes` is empty.
    pub(crate) const EMPTY: FrameBuf = FrameBuf {
        bytes: [0; MAX_FRAME_LEN],
        len: 0,
    };

    /// Copies `frame` in its wire form.
    pub fn from_frame(frame: &Frame<'_>) -> Self {
        let mut bytes = [0u8; MAX_FRAME_LEN];
        // A Frame holds at most 256 payload bytes, so it always fits.
        let len = frame.encode(&mut bytes).map(<[u8]>::len).unwrap_or(0);
        Self { bytes, len: len as u16 }
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
        let mut frame = Self {
            bytes: [0u8; MAX_FRAME_LEN],
            len: 0,
        };
        frame.rebuild(dest, source, encode)?;
        Ok(frame)
    }

    /// [`FrameBuf::build`] in place: overwrites this buffer, so that a
    /// caller that keeps the frame (the device endpoint's last result) needs
    /// no second copy of it on the stack. On error the buffer is left empty.
    pub(crate) fn rebuild(
        &mut self,
        dest: Address,
        source: u8,
        encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<(), EncodeError> {
        self.len = 0;
        // Split with `split_first_chunk_mut`/`get_mut`, not indexing, so that
        // no bounds-check panic is linked into firmware: `bytes` always
        // splits, the `else` arm is never taken.
        let Some((header, rest)) = self.bytes.split_first_chunk_mut::<HEADER_LEN>() else {
            return Err(EncodeError::BufferTooSmall {
                needed: MAX_FRAME_LEN,
                capacity: 0,
            });
        };
        let n = encode(rest.get_mut(..MAX_PAYLOAD).unwrap_or_default())?;
        if n == 0 || n > MAX_PAYLOAD {
            return Err(EncodeError::PayloadLength { len: n });
        }
        *header = [START, dest.group, dest.port, dest.device, source, length_byte(n)];
        let sum =
            checksum(header.get(1..).unwrap_or_default()).wrapping_add(checksum(rest.get(..n).unwrap_or_default()));
        if let Some(slot) = rest.get_mut(n) {
            *slot = sum;
        }
        self.len = (HEADER_LEN + n + 1) as u16;
        Ok(())
    }

    /// The frame's wire bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or_default()
    }

    /// A view of the frame.
    pub fn frame(&self) -> Frame<'_> {
        let [_, group, port, device, source, ..] = self.bytes;
        let end = usize::from(self.len).saturating_sub(1);
        Frame {
            dest: Address::new(group, port, device),
            source,
            payload: self.bytes.get(HEADER_LEN..end).unwrap_or_default(),
        }
    }

    /// Rewrites the header (destination and source) and recomputes the checksum.
    pub fn set_header(&mut self, dest: Address, source: u8) {
        let end = usize::from(self.len).saturating_sub(1);
        let [_, group, port, device, src, ..] = &mut self.bytes;
        (*group, *port, *device, *src) = (dest.group, dest.port, dest.device, source);
        let sum = checksum(self.bytes.get(1..end).unwrap_or_default());
        if let Some(slot) = self.bytes.get_mut(end) {
            *slot = sum;
        }
    }
}

impl core::fmt::Debug for FrameBuf {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("FrameBuf").field(&self.frame()).finish()
    }
}

impl<'a> From<&Frame<'a>> for FrameBuf {
    fn from(frame: &Frame<'a>) -> Self {
        Self::from_frame(frame)
    }
}
