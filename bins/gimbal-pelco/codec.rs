//! Pelco-D and Pelco-P framing: a streaming parser that finds frames in a
//! byte stream by their sync byte and checksum, resynchronising on
//! garbage, and the encoder of the door's replies.
//!
//! - Pelco-D ("D" Protocol manual, "The Standard Command Set"): 7 bytes,
//!   `FF addr cmd1 cmd2 data1 data2 sum`, the sum being bytes 2 to 6
//!   added modulo 256.
//! - Pelco-P ("P" Protocol manual, "Message format"): 8 bytes,
//!   `A0 addr data1 data2 data3 data4 AF xor`, the check byte the XOR of
//!   bytes 1 to 7 (STX and ETX included). Some keyboards and DVRs leave STX
//!   and ETX out of the XOR (the two differ by the constant `A0 ^ AF`);
//!   both are accepted.
//!
//! No crate was fit to take this from: `pelcodrs` (crates.io, 2019, Pelco-D
//! only) builds messages to send to a camera and has no streaming parser.

/// Which of the two protocols an input speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    D,
    P,
}

impl Protocol {
    /// The name the configuration uses.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::D => "pelco-d",
            Protocol::P => "pelco-p",
        }
    }

    /// The length of one frame.
    pub const fn frame_len(self) -> usize {
        match self {
            Protocol::D => 7,
            Protocol::P => 8,
        }
    }

    fn sync(self) -> u8 {
        match self {
            Protocol::D => 0xFF,
            Protocol::P => 0xA0,
        }
    }

    /// The address byte on the wire of keyboard address `address`
    /// (1..=255): Pelco-D carries it as it is, Pelco-P counts from 0
    /// (camera 1 is `00`).
    pub fn wire_address(self, address: u8) -> u8 {
        match self {
            Protocol::D => address,
            Protocol::P => address.wrapping_sub(1),
        }
    }

    /// Whether `frame` (one frame's bytes) is intact: its sync byte, its
    /// ETX (Pelco-P) and its check byte.
    fn intact(self, frame: &[u8]) -> bool {
        match self {
            Protocol::D => frame[6] == d_sum(&frame[1..6]),
            Protocol::P => {
                frame[6] == P_ETX && {
                    let inner = frame[1..6].iter().fold(0u8, |x, b| x ^ b);
                    frame[7] == inner ^ P_STX ^ P_ETX || frame[7] == inner
                }
            }
        }
    }

    /// A frame of this protocol to wire address byte `address` carrying
    /// `body` (Pelco-D: cmd1 cmd2 data1 data2; Pelco-P: data1 to data4).
    pub fn encode(self, address: u8, body: [u8; 4]) -> Vec<u8> {
        match self {
            Protocol::D => {
                let mut f = vec![0xFF, address, body[0], body[1], body[2], body[3], 0];
                f[6] = d_sum(&f[1..6]);
                f
            }
            Protocol::P => {
                let mut f = vec![P_STX, address, body[0], body[1], body[2], body[3], P_ETX, 0];
                f[7] = f[..7].iter().fold(0u8, |x, b| x ^ b);
                f
            }
        }
    }
}

const P_STX: u8 = 0xA0;
const P_ETX: u8 = 0xAF;

/// Pelco-D's check byte: bytes 2 to 6 added modulo 256.
fn d_sum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |s, b| s.wrapping_add(*b))
}

/// One intact frame: its wire address byte and its four command bytes
/// (Pelco-D: cmd1 cmd2 data1 data2; Pelco-P: data1 to data4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    pub address: u8,
    pub body: [u8; 4],
}

/// What the parser found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// An intact frame starting at byte `at` of the stream.
    Frame { at: u64, frame: Frame },
    /// `len` bytes from byte `at` that belong to no intact frame (noise, a
    /// frame cut short, a damaged one): `checksum` when a sync byte began
    /// a frame-long run whose check byte (or ETX) was wrong.
    Skipped { at: u64, len: u64, checksum: bool },
}

/// The streaming parser of one byte stream (a serial line, a TCP
/// connection, a datagram): it holds at most one frame's bytes between
/// calls. A damaged frame costs only its sync byte: the search resumes at
/// the next byte, so a frame that starts inside the damaged one is found.
#[derive(Clone, Debug)]
pub struct Parser {
    protocol: Protocol,
    held: [u8; 8],
    len: usize,
    /// The stream offset of `held[0]`.
    at: u64,
    /// The run of skipped bytes not yet reported: its start and length.
    skipped: Option<(u64, u64, bool)>,
}

impl Parser {
    pub fn new(protocol: Protocol) -> Self {
        Self {
            protocol,
            held: [0; 8],
            len: 0,
            at: 0,
            skipped: None,
        }
    }

    /// Bytes read so far (the offset of the next byte).
    pub fn offset(&self) -> u64 {
        self.at + self.len as u64
    }

    fn skip(&mut self, n: usize, checksum: bool) {
        let at = self.at;
        match &mut self.skipped {
            Some((_, len, bad)) => {
                *len += n as u64;
                *bad |= checksum;
            }
            None => self.skipped = Some((at, n as u64, checksum)),
        }
        self.held.copy_within(n..self.len, 0);
        self.len -= n;
        self.at += n as u64;
    }

    fn report_skipped(&mut self, found: &mut impl FnMut(Found)) {
        if let Some((at, len, checksum)) = self.skipped.take() {
            found(Found::Skipped { at, len, checksum });
        }
    }

    /// Feeds `bytes`; `found` is called for every frame and every run of
    /// skipped bytes, in stream order. A run is reported before the frame
    /// that ends it or at the end of this call, whichever comes first (so
    /// a stream of noise is reported as it comes; one run may be reported
    /// in pieces, one per read).
    pub fn feed(&mut self, bytes: &[u8], mut found: impl FnMut(Found)) {
        let n = self.protocol.frame_len();
        let sync = self.protocol.sync();
        for &b in bytes {
            self.held[self.len] = b;
            self.len += 1;
            loop {
                if self.len == 0 {
                    break;
                }
                if self.held[0] != sync {
                    let to = self.held[..self.len]
                        .iter()
                        .position(|&x| x == sync)
                        .unwrap_or(self.len);
                    self.skip(to, false);
                    continue;
                }
                if self.len < n {
                    break;
                }
                if self.protocol.intact(&self.held[..n]) {
                    self.report_skipped(&mut found);
                    let frame = Frame {
                        address: self.held[1],
                        body: [self.held[2], self.held[3], self.held[4], self.held[5]],
                    };
                    found(Found::Frame { at: self.at, frame });
                    self.len = 0;
                    self.at += n as u64;
                    break;
                }
                self.skip(1, true);
            }
        }
        self.report_skipped(&mut found);
    }

    /// The end of the stream: whatever is held and the open run are
    /// reported as skipped.
    pub fn finish(&mut self, mut found: impl FnMut(Found)) {
        if self.len > 0 {
            self.skip(self.len, false);
        }
        self.report_skipped(&mut found);
    }
}

#[cfg(test)]
mod tests;
