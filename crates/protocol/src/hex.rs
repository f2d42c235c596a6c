//! ASCII number primitives shared by the command and reply codecs.
//!
//! Spec 1.4.1.2: numbers travel as upper-case ASCII hexadecimal. Parsers here
//! also accept lower case (lenient, protocol-notes "Parse leniently"); the writer always
//! emits upper case. Decimal is used only by `*xpr`/`*xpn` (protocol-notes E14) and the
//! auxiliary port configuration (Table 18).

use nom::IResult;
use nom::Parser;
use nom::error::{Error, ErrorKind};

/// The value of one ASCII hex digit, either case.
pub(crate) const fn hex_value(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        b'a'..=b'f' => Some(byte - b'a' + 10),
        _ => None,
    }
}

pub(crate) const fn is_hex(byte: u8) -> bool {
    hex_value(byte).is_some()
}

/// Upper-case ASCII digit for a nibble (`0..=15`).
pub(crate) const fn hex_digit(nibble: u8) -> u8 {
    b"0123456789ABCDEF"[(nibble & 0x0F) as usize]
}

/// Exactly `digits` hex digits (at most 8), as a number. A failure points at
/// the first byte that is not a hex digit (or at the end of the input), so
/// errors can say exactly where the number went wrong.
pub(crate) fn hex_n(digits: usize) -> impl FnMut(&[u8]) -> IResult<&[u8], u32> {
    move |input: &[u8]| {
        let mut value = 0u32;
        for i in 0..digits {
            match input.get(i).copied().and_then(hex_value) {
                Some(v) => value = (value << 4) | u32::from(v),
                None => {
                    return Err(nom::Err::Error(Error::new(
                        input.get(i..).unwrap_or_default(),
                        ErrorKind::HexDigit,
                    )));
                }
            }
        }
        Ok((input.get(digits..).unwrap_or_default(), value))
    }
}

/// Two hex digits.
pub(crate) fn hex_u8(input: &[u8]) -> IResult<&[u8], u8> {
    hex_n(2).map(|v| v as u8).parse(input)
}

/// Four hex digits.
pub(crate) fn hex_u16(input: &[u8]) -> IResult<&[u8], u16> {
    hex_n(4).map(|v| v as u16).parse(input)
}

/// Three hex digits: a 12-bit value (Tables 10, 17).
pub(crate) fn hex12(input: &[u8]) -> IResult<&[u8], crate::units::U12> {
    nom::combinator::map_res(hex_n(3), |v| crate::units::U12::new(v as u16)).parse(input)
}

/// One to `max` decimal digits (at most 9, so the value fits a `u32`).
pub(crate) fn decimal(max: usize) -> impl FnMut(&[u8]) -> IResult<&[u8], u32> {
    move |input: &[u8]| {
        let n = input.iter().take(max).take_while(|b| b.is_ascii_digit()).count();
        if n == 0 {
            return Err(nom::Err::Error(Error::new(input, ErrorKind::Digit)));
        }
        let (digits, rest) = input.split_at_checked(n).unwrap_or((input, &[]));
        let value = digits.iter().fold(0u32, |acc, &b| {
            acc.wrapping_mul(10).wrapping_add(u32::from(b.wrapping_sub(b'0')))
        });
        Ok((rest, value))
    }
}

/// Byte offset of `rest` inside `whole` (both from the same payload).
pub(crate) fn offset_in(whole: &[u8], rest: &[u8]) -> usize {
    whole.len() - rest.len()
}

/// A bounded writer into a caller buffer: every encoder in the crate goes
/// through it, so none can write past the end or panic on a short buffer.
#[derive(Debug)]
pub(crate) struct Writer<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl<'b> Writer<'b> {
    pub(crate) fn new(buf: &'b mut [u8]) -> Self {
        Self { buf, len: 0 }
    }

    pub(crate) fn put(&mut self, bytes: &[u8]) -> Result<(), crate::EncodeError> {
        let end = self.len.saturating_add(bytes.len());
        let capacity = self.buf.len();
        let dst = self
            .buf
            .get_mut(self.len..end)
            .ok_or(crate::EncodeError::BufferTooSmall { needed: end, capacity })?;
        // `zip`, not `copy_from_slice`: the lengths are equal, but the
        // optimiser cannot always see it and would link a panic.
        for (d, &b) in dst.iter_mut().zip(bytes) {
            *d = b;
        }
        self.len = end;
        Ok(())
    }

    pub(crate) fn byte(&mut self, byte: u8) -> Result<(), crate::EncodeError> {
        self.put(&[byte])
    }

    /// `digits` upper-case hex digits of `value`, most significant first.
    pub(crate) fn hex(&mut self, value: u32, digits: usize) -> Result<(), crate::EncodeError> {
        for i in (0..digits).rev() {
            self.byte(hex_digit((value >> (4 * i)) as u8))?;
        }
        Ok(())
    }

    /// `value` in decimal, at least `min_digits` digits (zero padded).
    pub(crate) fn decimal(&mut self, value: u32, min_digits: usize) -> Result<(), crate::EncodeError> {
        let mut digits = [0u8; 10];
        let mut n = 0;
        let mut v = value;
        // A u32 has at most 10 decimal digits: `digits` always has room.
        for slot in digits.iter_mut() {
            *slot = b'0' + (v % 10) as u8;
            n += 1;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        for _ in n..min_digits {
            self.byte(b'0')?;
        }
        for &digit in digits.get(..n).unwrap_or_default().iter().rev() {
            self.byte(digit)?;
        }
        Ok(())
    }

    pub(crate) fn len(&self) -> usize {
        self.len
    }

    pub(crate) fn finish(self) -> &'b [u8] {
        let Writer { buf, len } = self;
        let buf: &'b [u8] = buf;
        buf.get(..len).unwrap_or_default()
    }
}
