//! Each result shape read and written side by side: its `parse_*` reads
//! it leniently from a [`Reading`] and its `emit` arm writes its one
//! canonical form (protocol-notes "Parse leniently").
//! [`Reply::parse_expected`] dispatches to the `parse_*` by shape;
//! [`reply_shapes!`] gathers the `emit` arms into [`Reply::encode`], one
//! match as if written in place: moving them into functions of their own
//! cost the firmware image 132 B of flash and doubled its receive-path
//! stack (firmware/build.sh), one match costs nothing.

/// The shapes' table: `writer w;`, then per shape its `parse_*` function
/// and `emit PATTERN => BLOCK;`, whose block writes with `w` (a
/// `Writer`) and returns from `encode` on an error with `?`.
macro_rules! reply_shapes {
    (writer $w:ident; $( $parse:item emit $pat:pat => $emit:block; )+) => {
        $( $parse )+

        impl Reply<'_> {
            /// Writes the canonical payload into `buf`; returns the written prefix.
            pub fn encode<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EncodeError> {
                let mut $w = Writer::new(buf);
                match *self {
                    $( $pat => $emit, )+
                    Reply::AuxData(bytes) | Reply::Raw(bytes) => $w.put(bytes)?,
                }
                if $w.len() == 0 {
                    return Err(EncodeError::PayloadLength { len: 0 });
                }
                Ok($w.finish())
            }
        }
    };
}

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

/// A result payload read for the command `name`: `skip` bytes of its echo
/// (protocol-notes E6) in front of `body`.
#[derive(Clone, Copy)]
pub(super) struct Reading<'a> {
    pub name: &'static str,
    pub payload: &'a [u8],
    pub skip: usize,
    pub body: &'a [u8],
}

impl<'a> Reading<'a> {
    /// Where the value starts when the result may lead with `letter`
    /// (`P`, `V`, `C`, `L`) in front of `bare_len` characters.
    fn with_letter(&self, letter: u8, bare_len: usize) -> usize {
        if self.body.len() == bare_len + 1 && self.body.first() == Some(&letter) {
            self.skip + 1
        } else {
            self.skip
        }
    }

    fn malformed(&self, offset: usize, found: Option<u8>, expected: &'static str) -> ReplyError {
        malformed(self.name, offset, found, expected)
    }
}

reply_shapes! {
    writer w;

    /// Table 5: one hex digit, or a raw byte 0x00..=0x0F (E10).
    #[inline(always)]
    pub(super) fn parse_awake_status<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        match r.body {
            [b] => match digit_or_raw(*b) {
                Some(bits) => Ok(Reply::AwakeStatus(AwakeStatus(bits))),
                None => Err(r.malformed(r.skip, Some(*b), "one hex digit")),
            },
            [] => Err(r.malformed(r.skip, None, "one hex digit")),
            [_, extra, ..] => Err(r.malformed(r.skip + 1, Some(*extra), "end of result")),
        }
    }

    emit Reply::AwakeStatus(s) => { w.hex(s.0.into(), 1)? };

    /// `C0..CF`'s data-rate reply: `C` (optional) and one hex digit.
    #[inline(always)]
    pub(super) fn parse_max_data_rate<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let at = r.with_letter(b'C', 1);
        let code = whole(r.name, r.payload, at, "C and one hex digit", hex_n(1))?;
        Ok(Reply::MaxDataRate(DataRate::from_code(code as u8).unwrap_or(DataRate::Reserved(15))))
    }

    emit Reply::MaxDataRate(rate) => {
        let code = rate.encodable_code().map_err(EncodeError::OutOfRange)?;
        w.byte(b'C')?;
        w.hex(code.into(), 1)?;
    };

    /// Table 4A: ID, revision, then name and serial fields of 20 characters
    /// (trailing spaces or NULs trimmed; a short block is accepted).
    #[inline(always)]
    pub(super) fn parse_identity<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (payload, body, skip) = (r.payload, r.body, r.skip);
        if body.len() < 4 || body.len() > 44 {
            let (offset, expected) = if body.len() < 4 {
                (payload.len(), "ID and revision (4 characters)")
            } else {
                (skip + 44, "end of the 44-byte identification block")
            };
            return Err(r.malformed(offset, payload.get(offset).copied(), expected));
        }
        let id = whole(r.name, &payload[..skip + 2], skip, "two hex digits (device ID)", hex_u8)?;
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

    emit Reply::Identity(id) => {
        w.hex(id.id.into(), 2)?;
        w.put(&id.revision)?;
        for field in [id.name, id.serial] {
            w.put(field)?;
            for _ in field.len()..Identity::FIELD_LEN {
                w.byte(b' ')?;
            }
        }
    };

    /// Table 6: pan and tilt error codes, two hex digits each.
    #[inline(always)]
    pub(super) fn parse_errors<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (pan, tilt) = whole(r.name, r.payload, r.skip, "four hex digits", |i| (hex_u8, hex_u8).parse(i))?;
        Ok(Reply::Errors(ErrorCodes { pan, tilt }))
    }

    emit Reply::Errors(e) => {
        w.hex(e.pan.into(), 2)?;
        w.hex(e.tilt.into(), 2)?;
    };

    /// Tables 6A/6B: status bits, two or four hex digits per axis; emitted as four.
    #[inline(always)]
    pub(super) fn parse_status_bits<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (pan, tilt) = if r.body.len() == 4 {
            let (p, t) = whole(r.name, r.payload, r.skip, "four or eight hex digits", |i| {
                (hex_u8, hex_u8).parse(i)
            })?;
            (u16::from(p), u16::from(t))
        } else {
            whole(r.name, r.payload, r.skip, "four or eight hex digits", |i| {
                (hex_u16, hex_u16).parse(i)
            })?
        };
        Ok(Reply::StatusBits(StatusBits { pan, tilt }))
    }

    emit Reply::StatusBits(s) => {
        w.hex(s.pan.into(), 4)?;
        w.hex(s.tilt.into(), 4)?;
    };

    /// Table 8: pan and tilt rate gains, two hex digits each, and four unused
    /// characters (optional when read).
    #[inline(always)]
    pub(super) fn parse_rate_gains<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (name, skip) = (r.name, r.skip);
        let (pan, tilt) = if r.body.len() == 8 {
            let (p, t, _) = whole(name, r.payload, skip, "gains then 4 unused characters", |i| {
                (hex_u8, hex_u8, take(4usize)).parse(i)
            })?;
            (p, t)
        } else {
            whole(name, r.payload, skip, "two gains of two hex digits", |i| {
                (hex_u8, hex_u8).parse(i)
            })?
        };
        let ranged = |value: u8, offset: usize| {
            RateGain::new(value).map_err(|error| ReplyError::OutOfRange {
                command: name,
                offset,
                error,
            })
        };
        Ok(Reply::RateGains(RateGains {
            pan: ranged(pan, skip)?,
            tilt: ranged(tilt, skip + 2)?,
        }))
    }

    emit Reply::RateGains(g) => {
        w.hex(g.pan.get().into(), 2)?;
        w.hex(g.tilt.get().into(), 2)?;
        w.put(b"0000")?;
    };

    /// Table 9: four initialisation results, two or four hex digits each;
    /// emitted as four.
    #[inline(always)]
    pub(super) fn parse_initialization<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let [a, b, c, d] = if r.body.len() == 8 {
            let (a, b, c, d) = whole(r.name, r.payload, r.skip, "8 or 16 hex digits", |i| {
                (hex_u8, hex_u8, hex_u8, hex_u8).parse(i)
            })?;
            [a, b, c, d].map(u16::from)
        } else {
            let (a, b, c, d) = whole(r.name, r.payload, r.skip, "8 or 16 hex digits", |i| {
                (hex_u16, hex_u16, hex_u16, hex_u16).parse(i)
            })?;
            [a, b, c, d]
        };
        Ok(Reply::Initialization(InitResults {
            pan_ccw: a,
            pan_cw: b,
            tilt_ccw: c,
            tilt_cw: d,
        }))
    }

    emit Reply::Initialization(r) => {
        for v in [r.pan_ccw, r.pan_cw, r.tilt_ccw, r.tilt_cw] {
            w.hex(v.into(), 4)?;
        }
    };

    /// Table 10: four limits of three hex digits (12 bits) each.
    #[inline(always)]
    pub(super) fn parse_limits<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (pan_ccw, pan_cw, tilt_ccw, tilt_cw) = whole(r.name, r.payload, r.skip, "twelve hex digits", |i| {
            (hex12, hex12, hex12, hex12).parse(i)
        })?;
        Ok(Reply::Limits(Limits {
            pan_ccw,
            pan_cw,
            tilt_ccw,
            tilt_cw,
        }))
    }

    emit Reply::Limits(l) => {
        for v in [l.pan_ccw, l.pan_cw, l.tilt_ccw, l.tilt_cw] {
            w.hex(v.get().into(), 3)?;
        }
    };

    /// Table 13: relay bits, `L` (optional) and one hex digit.
    #[inline(always)]
    pub(super) fn parse_relays<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let at = r.with_letter(b'L', 1);
        Ok(Reply::Relays(whole(r.name, r.payload, at, "L and one hex digit", hex_n(1))? as u8))
    }

    emit Reply::Relays(bits) => {
        nibble("relay bits", bits)?;
        w.byte(b'L')?;
        w.hex(bits.into(), 1)?;
    };

    /// Table 14: pan and tilt accelerations, four hex digits each.
    #[inline(always)]
    pub(super) fn parse_accelerations<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (pan, tilt) = whole(r.name, r.payload, r.skip, "eight hex digits", |i| (hex_u16, hex_u16).parse(i))?;
        Ok(Reply::Accelerations {
            pan: Acceleration(pan),
            tilt: Acceleration(tilt),
        })
    }

    emit Reply::Accelerations { pan, tilt } => {
        w.hex(pan.0.into(), 4)?;
        w.hex(tilt.0.into(), 4)?;
    };

    /// Table 14: one axis's acceleration, four hex digits.
    #[inline(always)]
    pub(super) fn parse_acceleration<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        Ok(Reply::Acceleration(Acceleration(whole(r.name, r.payload, r.skip, "four hex digits", hex_u16)?)))
    }

    emit Reply::Acceleration(a) => { w.hex(a.0.into(), 4)? };

    /// Table 14: pan and tilt rates, four hex digits each.
    #[inline(always)]
    pub(super) fn parse_rates<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let (pan, tilt) = whole(r.name, r.payload, r.skip, "eight hex digits", |i| (hex_u16, hex_u16).parse(i))?;
        Ok(Reply::Rates {
            pan: Rate(pan),
            tilt: Rate(tilt),
        })
    }

    emit Reply::Rates { pan, tilt } => {
        w.hex(pan.0.into(), 4)?;
        w.hex(tilt.0.into(), 4)?;
    };

    /// Table 14: one axis's rate, four hex digits.
    #[inline(always)]
    pub(super) fn parse_rate<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        Ok(Reply::Rate(Rate(whole(r.name, r.payload, r.skip, "four hex digits", hex_u16)?)))
    }

    emit Reply::Rate(r) => { w.hex(r.0.into(), 4)? };

    /// Table 17: limit, centre and count-correct bits, a hex digit (or raw
    /// byte, E10) each.
    #[inline(always)]
    pub(super) fn parse_verify_home<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        match r.body {
            [a, b, c] => match (digit_or_raw(*a), digit_or_raw(*b), digit_or_raw(*c)) {
                (Some(limit_switches), Some(center_switches), Some(count_correct)) => Ok(Reply::VerifyHome(HomeStatus {
                    limit_switches,
                    center_switches,
                    count_correct,
                })),
                _ => {
                    let i = [a, b, c].iter().position(|x| digit_or_raw(**x).is_none()).unwrap_or(0);
                    Err(r.malformed(r.skip + i, Some(r.body[i]), "a hex digit"))
                }
            },
            [_, _, _, extra, ..] => Err(r.malformed(r.skip + 3, Some(*extra), "end of result")),
            _ => Err(r.malformed(r.payload.len(), None, "three digits")),
        }
    }

    emit Reply::VerifyHome(h) => {
        nibble("limit switch bits", h.limit_switches)?;
        nibble("centre switch bits", h.center_switches)?;
        nibble("count-correct bits", h.count_correct)?;
        w.hex(h.limit_switches.into(), 1)?;
        w.hex(h.center_switches.into(), 1)?;
        w.hex(h.count_correct.into(), 1)?;
    };

    /// Table 15: `P` (optional), pan and tilt, four hex digits each.
    #[inline(always)]
    pub(super) fn parse_position<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let at = r.with_letter(b'P', 8);
        let (pan, tilt) = whole(r.name, r.payload, at, "eight hex digits", |i| (hex_u16, hex_u16).parse(i))?;
        Ok(Reply::Position(Position::new(Angle(pan as i16), Angle(tilt as i16))))
    }

    emit Reply::Position(p) => {
        w.hex(u32::from(p.pan.0 as u16), 4)?;
        w.hex(u32::from(p.tilt.0 as u16), 4)?;
    };

    /// Table 15: `V` (optional), zoom and focus, three hex digits each.
    #[inline(always)]
    pub(super) fn parse_lens<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let at = r.with_letter(b'V', 6);
        let (zoom, focus) = whole(r.name, r.payload, at, "six hex digits", |i| (hex12, hex12).parse(i))?;
        Ok(Reply::Lens(LensPosition { zoom, focus }))
    }

    emit Reply::Lens(l) => {
        w.hex(l.zoom.get().into(), 3)?;
        w.hex(l.focus.get().into(), 3)?;
    };

    /// `*xpn`: a decimal character count 0..=65535.
    #[inline(always)]
    pub(super) fn parse_aux_count<'a>(r: &Reading<'a>) -> Result<Reply<'a>, ReplyError> {
        let n = whole(r.name, r.payload, r.skip, "a decimal count 0..=65535", |i| {
            decimal(5).parse(i)
        })?;
        let n = u16::try_from(n).map_err(|_| ReplyError::OutOfRange {
            command: r.name,
            offset: r.skip,
            error: RangeError {
                what: "character count",
                value: n.into(),
                min: 0,
                max: 65535,
            },
        })?;
        Ok(Reply::AuxCount(n))
    }

    emit Reply::AuxCount(n) => { w.decimal(n.into(), 1)? };
}
