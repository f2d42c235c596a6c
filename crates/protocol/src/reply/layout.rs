//! Each result's layout, read and written side by side (as smoltcp keeps a
//! header's parse and emit together): per reply kind, `parse_*` reads it
//! leniently from a result's body (protocol-notes "Parse leniently") and
//! `emit_*` writes its one canonical form. [`Reply::parse_expected`] and
//! [`Reply::encode`] dispatch here by shape and by variant.

use nom::Parser;
use nom::bytes::complete::take;

use super::{
    AwakeStatus, ErrorCodes, HomeStatus, Identity, InitResults, RateGains, Reply, ReplyError, StatusBits, digit_or_raw,
    malformed, nibble,
};
use crate::EncodeError;
use crate::command::whole;
use crate::hex::{Writer, decimal, hex_n, hex_u8, hex_u16, hex12};
use crate::units::{Acceleration, Angle, DataRate, LensPosition, Limits, Position, RangeError, Rate, RateGain};

/// A result's payload as the parsers read it: the command's name for the
/// errors, the whole payload (offsets in errors count from its start) and
/// where the result starts after an echo of the command (protocol-notes E6).
#[derive(Clone, Copy, Debug)]
pub(super) struct Body<'a> {
    pub(super) name: &'static str,
    pub(super) payload: &'a [u8],
    pub(super) skip: usize,
}

impl<'a> Body<'a> {
    /// The result after the echo.
    fn body(&self) -> &'a [u8] {
        &self.payload[self.skip..]
    }

    /// Where the digits start when a result may lead with its letter (`C`,
    /// `L`, `P`, `V`) before `bare_len` digits.
    fn with_letter(&self, letter: u8, bare_len: usize) -> usize {
        let body = self.body();
        if body.len() == bare_len + 1 && body.first() == Some(&letter) {
            self.skip + 1
        } else {
            self.skip
        }
    }

    /// The whole payload from `at`, read by `parser`.
    fn whole<T>(
        &self,
        at: usize,
        expected: &'static str,
        parser: impl FnMut(&'a [u8]) -> nom::IResult<&'a [u8], T>,
    ) -> Result<T, ReplyError> {
        Ok(whole(self.name, self.payload, at, expected, parser)?)
    }

    /// Two values of two hex digits, or of four.
    fn two_u16(&self, expected: &'static str) -> Result<(u16, u16), ReplyError> {
        self.whole(self.skip, expected, |i| (hex_u16, hex_u16).parse(i))
    }
}

/// Table 5: one hex digit (a raw 0x00..=0x0F accepted).
pub(super) fn parse_awake<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    match b.body() {
        [d] => match digit_or_raw(*d) {
            Some(bits) => Ok(Reply::AwakeStatus(AwakeStatus(bits))),
            None => Err(malformed(b.name, b.skip, Some(*d), "one hex digit")),
        },
        [] => Err(malformed(b.name, b.skip, None, "one hex digit")),
        [_, extra, ..] => Err(malformed(b.name, b.skip + 1, Some(*extra), "end of result")),
    }
}

pub(super) fn emit_awake(s: AwakeStatus, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(s.0.into(), 1)
}

/// `C0..CF`: the letter (optional when read) and one hex digit.
pub(super) fn parse_max_data_rate<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let code = b.whole(b.with_letter(b'C', 1), "C and one hex digit", hex_n(1))?;
    Ok(Reply::MaxDataRate(
        DataRate::from_code(code as u8).unwrap_or(DataRate::Reserved(15)),
    ))
}

pub(super) fn emit_max_data_rate(rate: DataRate, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    let code = rate.encodable_code().map_err(EncodeError::OutOfRange)?;
    w.byte(b'C')?;
    w.hex(code.into(), 1)
}

/// Table 6: ID, revision, name and serial number (trailing blanks trimmed
/// when read, padded to their field when written).
pub(super) fn parse_identity<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (body, payload, skip) = (b.body(), b.payload, b.skip);
    if body.len() < 4 || body.len() > 44 {
        let (offset, expected) = if body.len() < 4 {
            (payload.len(), "ID and revision (4 characters)")
        } else {
            (skip + 44, "end of the 44-byte identification block")
        };
        return Err(malformed(b.name, offset, payload.get(offset).copied(), expected));
    }
    let id = whole(b.name, &payload[..skip + 2], skip, "two hex digits (device ID)", hex_u8)?;
    let field = |from: usize| {
        let raw = body
            .get(from..body.len().min(from + Identity::FIELD_LEN))
            .unwrap_or(&[]);
        let end = raw.iter().rposition(|&b| b != b' ' && b != 0).map_or(0, |i| i + 1);
        &raw[..end]
    };
    Ok(Reply::Identity(Identity {
        id,
        revision: [body[2], body[3]],
        name: field(4),
        serial: field(24),
    }))
}

pub(super) fn emit_identity(id: Identity<'_>, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(id.id.into(), 2)?;
    w.put(&id.revision)?;
    for field in [id.name, id.serial] {
        w.put(field)?;
        for _ in field.len()..Identity::FIELD_LEN {
            w.byte(b' ')?;
        }
    }
    Ok(())
}

/// Table 6A: two hex digits per axis.
pub(super) fn parse_errors<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = b.whole(b.skip, "four hex digits", |i| (hex_u8, hex_u8).parse(i))?;
    Ok(Reply::Errors(ErrorCodes { pan, tilt }))
}

pub(super) fn emit_errors(e: ErrorCodes, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(e.pan.into(), 2)?;
    w.hex(e.tilt.into(), 2)
}

/// Table 6B: two or four hex digits per axis when read, four written.
pub(super) fn parse_status_bits<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = if b.body().len() == 4 {
        let (p, t) = b.whole(b.skip, "four or eight hex digits", |i| (hex_u8, hex_u8).parse(i))?;
        (u16::from(p), u16::from(t))
    } else {
        b.two_u16("four or eight hex digits")?
    };
    Ok(Reply::StatusBits(StatusBits { pan, tilt }))
}

pub(super) fn emit_status_bits(s: StatusBits, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(s.pan.into(), 4)?;
    w.hex(s.tilt.into(), 4)
}

/// Table 8: two gains of two hex digits, then four unused characters
/// (optional when read, `0000` written).
pub(super) fn parse_rate_gains<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = if b.body().len() == 8 {
        let (p, t, _) = b.whole(b.skip, "gains then 4 unused characters", |i| {
            (hex_u8, hex_u8, take(4usize)).parse(i)
        })?;
        (p, t)
    } else {
        b.whole(b.skip, "two gains of two hex digits", |i| (hex_u8, hex_u8).parse(i))?
    };
    let gain = |value: u8, offset: usize| {
        RateGain::new(value).map_err(|error| ReplyError::OutOfRange {
            command: b.name,
            offset,
            error,
        })
    };
    Ok(Reply::RateGains(RateGains {
        pan: gain(pan, b.skip)?,
        tilt: gain(tilt, b.skip + 2)?,
    }))
}

pub(super) fn emit_rate_gains(g: RateGains, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(g.pan.get().into(), 2)?;
    w.hex(g.tilt.get().into(), 2)?;
    w.put(b"0000")
}

/// Table 9: four values of two or four hex digits when read, four written.
pub(super) fn parse_initialization<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let [a, c, d, e] = if b.body().len() == 8 {
        let (a, c, d, e) = b.whole(b.skip, "8 or 16 hex digits", |i| {
            (hex_u8, hex_u8, hex_u8, hex_u8).parse(i)
        })?;
        [a, c, d, e].map(u16::from)
    } else {
        let (a, c, d, e) = b.whole(b.skip, "8 or 16 hex digits", |i| {
            (hex_u16, hex_u16, hex_u16, hex_u16).parse(i)
        })?;
        [a, c, d, e]
    };
    Ok(Reply::Initialization(InitResults {
        pan_ccw: a,
        pan_cw: c,
        tilt_ccw: d,
        tilt_cw: e,
    }))
}

pub(super) fn emit_initialization(r: InitResults, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    for v in [r.pan_ccw, r.pan_cw, r.tilt_ccw, r.tilt_cw] {
        w.hex(v.into(), 4)?;
    }
    Ok(())
}

/// Table 10: four 12-bit limits of three hex digits.
pub(super) fn parse_limits<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan_ccw, pan_cw, tilt_ccw, tilt_cw) =
        b.whole(b.skip, "twelve hex digits", |i| (hex12, hex12, hex12, hex12).parse(i))?;
    Ok(Reply::Limits(Limits {
        pan_ccw,
        pan_cw,
        tilt_ccw,
        tilt_cw,
    }))
}

pub(super) fn emit_limits(l: Limits, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    for v in [l.pan_ccw, l.pan_cw, l.tilt_ccw, l.tilt_cw] {
        w.hex(v.get().into(), 3)?;
    }
    Ok(())
}

/// Table 4A: `L` (optional when read) and one hex digit of relay bits.
pub(super) fn parse_relays<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let bits = b.whole(b.with_letter(b'L', 1), "L and one hex digit", hex_n(1))?;
    Ok(Reply::Relays(bits as u8))
}

pub(super) fn emit_relays(bits: u8, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    nibble("relay bits", bits)?;
    w.byte(b'L')?;
    w.hex(bits.into(), 1)
}

/// Table 13: both axes' accelerations, four hex digits each.
pub(super) fn parse_accelerations<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = b.two_u16("eight hex digits")?;
    Ok(Reply::Accelerations {
        pan: Acceleration(pan),
        tilt: Acceleration(tilt),
    })
}

/// Table 13: both axes' rates, four hex digits each.
pub(super) fn parse_rates<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = b.two_u16("eight hex digits")?;
    Ok(Reply::Rates {
        pan: Rate(pan),
        tilt: Rate(tilt),
    })
}

/// Table 13: one axis's acceleration or rate, four hex digits.
pub(super) fn parse_u16<'a>(b: &Body<'a>) -> Result<u16, ReplyError> {
    b.whole(b.skip, "four hex digits", hex_u16)
}

/// Table 13 (both axes) and Table 15 (a position): two values of four hex
/// digits.
pub(super) fn emit_two_u16(pan: u16, tilt: u16, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(pan.into(), 4)?;
    w.hex(tilt.into(), 4)
}

/// Table 14: three digits of axis bits (raw 0x00..=0x0F accepted).
pub(super) fn parse_verify_home<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let body = b.body();
    match body {
        [x, y, z] => match (digit_or_raw(*x), digit_or_raw(*y), digit_or_raw(*z)) {
            (Some(limit_switches), Some(center_switches), Some(count_correct)) => Ok(Reply::VerifyHome(HomeStatus {
                limit_switches,
                center_switches,
                count_correct,
            })),
            _ => {
                let i = [x, y, z].iter().position(|v| digit_or_raw(**v).is_none()).unwrap_or(0);
                Err(malformed(b.name, b.skip + i, Some(body[i]), "a hex digit"))
            }
        },
        [_, _, _, extra, ..] => Err(malformed(b.name, b.skip + 3, Some(*extra), "end of result")),
        _ => Err(malformed(b.name, b.payload.len(), None, "three digits")),
    }
}

pub(super) fn emit_verify_home(h: HomeStatus, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    nibble("limit switch bits", h.limit_switches)?;
    nibble("centre switch bits", h.center_switches)?;
    nibble("count-correct bits", h.count_correct)?;
    w.hex(h.limit_switches.into(), 1)?;
    w.hex(h.center_switches.into(), 1)?;
    w.hex(h.count_correct.into(), 1)
}

/// Table 15: `P` (optional when read), pan and tilt of four hex digits.
pub(super) fn parse_position<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (pan, tilt) = b.whole(b.with_letter(b'P', 8), "eight hex digits", |i| {
        (hex_u16, hex_u16).parse(i)
    })?;
    Ok(Reply::Position(Position::new(Angle(pan as i16), Angle(tilt as i16))))
}

pub(super) fn emit_position(p: Position, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    emit_two_u16(p.pan.0 as u16, p.tilt.0 as u16, w)
}

/// Table 17: `V` (optional when read), zoom and focus of three hex digits.
pub(super) fn parse_lens<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let (zoom, focus) = b.whole(b.with_letter(b'V', 6), "six hex digits", |i| (hex12, hex12).parse(i))?;
    Ok(Reply::Lens(LensPosition { zoom, focus }))
}

pub(super) fn emit_lens(l: LensPosition, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.hex(l.zoom.get().into(), 3)?;
    w.hex(l.focus.get().into(), 3)
}

/// `*xpn`: a decimal count of characters waiting, 0..=65535.
pub(super) fn parse_aux_count<'a>(b: &Body<'a>) -> Result<Reply<'a>, ReplyError> {
    let n = b.whole(b.skip, "a decimal count 0..=65535", |i| decimal(5).parse(i))?;
    let n = u16::try_from(n).map_err(|_| ReplyError::OutOfRange {
        command: b.name,
        offset: b.skip,
        error: RangeError {
            what: "character count",
            value: n.into(),
            min: 0,
            max: 65535,
        },
    })?;
    Ok(Reply::AuxCount(n))
}

pub(super) fn emit_aux_count(n: u16, w: &mut Writer<'_>) -> Result<(), EncodeError> {
    w.decimal(n.into(), 1)
}
