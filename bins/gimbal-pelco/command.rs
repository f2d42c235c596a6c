//! What a Pelco frame asks, by the protocols' command tables: the standard
//! command (the state of every motion at once) and the extended commands
//! the door carries out.
//!
//! - Pelco-D ("D" Protocol manual, "The Standard Command Set"): command 1
//!   bit 0 focus near, 1 iris open, 2 iris close, 3 camera on/off, 4 auto
//!   scan, 7 sense; command 2 bit 1 pan right, 2 pan left, 3 tilt up, 4 tilt
//!   down, 5 zoom tele, 6 zoom wide, 7 focus far, bit 0 always 0; data 1 the
//!   pan speed `00`-`3F` (`FF` turbo), data 2 the tilt speed `00`-`3F`.
//!   "Extended Commands": command 2 odd is the opcode, data 1 and 2 its
//!   arguments: `03` set, `05` clear and `07` go to preset (data 2), `25`
//!   zoom speed (data 2, 0-3), `4B`/`4D` set pan/tilt position (data 1 the
//!   high byte, in hundredths of a degree), `51`/`53` query pan/tilt
//!   position, answered by `59`/`5B`.
//! - Pelco-P ("P" Protocol manual): data 1 as Pelco-D's command 1 (focus
//!   far is its bit 0, focus near bit 1), data 2 as Pelco-D's command 2,
//!   data 3 the pan speed `00`-`3F` (`40` turbo), data 4 the tilt speed;
//!   extended commands as Pelco-D's, data 2 the opcode, data 3 and 4 the
//!   arguments.

use crate::codec::{Frame, Protocol};

/// A pan or tilt speed as the keyboard asked it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rate {
    /// `00` (slowest) to `3F` (fastest); larger values are taken as `3F`.
    Step(u8),
    /// Pan turbo (Pelco-D `FF`, Pelco-P `40`).
    Turbo,
}

/// The fastest step of a pan or tilt speed.
pub const MAX_STEP: u8 = 0x3F;

/// One axis's motion in a standard command: toward the positive direction
/// (pan right, tilt up, zoom tele) or the negative one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Way {
    Positive,
    Negative,
}

/// What a frame asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// The standard command: each axis moving or (None) stopped. Every
    /// axis `None` is the stop.
    Motion {
        pan: Option<(Way, Rate)>,
        tilt: Option<(Way, Rate)>,
        zoom: Option<Way>,
    },
    SetPreset(u8),
    ClearPreset(u8),
    GoToPreset(u8),
    /// Pan position, hundredths of a degree (`4B`).
    PanTo(u16),
    /// Tilt position, hundredths of a degree (`4D`).
    TiltTo(u16),
    QueryPan,
    QueryTilt,
    /// Zoom lens speed 0-3 (`25`).
    ZoomSpeed(u8),
    /// An extended command the door does not carry out (its opcode).
    Unsupported(u8),
}

impl Request {
    /// The stop: the standard command with nothing moving.
    #[cfg(test)]
    pub const STOP: Request = Request::Motion {
        pan: None,
        tilt: None,
        zoom: None,
    };

    /// Its kind in the door's metrics (`requests_total{kind}`): `drive`,
    /// `stop`, `preset` (set, clear, go to), `absolute` (pan or tilt
    /// position), `query` (pan or tilt), `lens` (zoom speed), or `other`
    /// (an extended command the door does not carry out).
    pub fn kind(&self) -> &'static str {
        match self {
            Request::Motion {
                pan: None,
                tilt: None,
                zoom: None,
            } => "stop",
            Request::Motion { .. } => "drive",
            Request::SetPreset(_) | Request::ClearPreset(_) | Request::GoToPreset(_) => "preset",
            Request::PanTo(_) | Request::TiltTo(_) => "absolute",
            Request::QueryPan | Request::QueryTilt => "query",
            Request::ZoomSpeed(_) => "lens",
            Request::Unsupported(_) => "other",
        }
    }

    /// The request of `frame`, read by `protocol`'s table.
    pub fn of(protocol: Protocol, frame: &Frame) -> Request {
        let [_, command, a, b] = frame.body;
        let turbo = match protocol {
            Protocol::D => 0xFF,
            Protocol::P => 0x40,
        };
        if command & 1 == 1 {
            return extended(command, a, b);
        }
        let way = |positive: u8, negative: u8| match (command & positive != 0, command & negative != 0) {
            (true, false) => Some(Way::Positive),
            (false, true) => Some(Way::Negative),
            // Neither, or both at once: that axis does not move.
            _ => None,
        };
        let rate = |speed: u8, turbo_allowed: bool| {
            if turbo_allowed && speed == turbo {
                Rate::Turbo
            } else {
                Rate::Step(speed.min(MAX_STEP))
            }
        };
        Request::Motion {
            pan: way(0x02, 0x04).map(|w| (w, rate(a, true))),
            tilt: way(0x08, 0x10).map(|w| (w, rate(b, false))),
            zoom: way(0x20, 0x40),
        }
    }
}

fn extended(opcode: u8, a: u8, b: u8) -> Request {
    let word = u16::from_be_bytes([a, b]);
    match opcode {
        0x03 => Request::SetPreset(b),
        0x05 => Request::ClearPreset(b),
        0x07 => Request::GoToPreset(b),
        0x25 => Request::ZoomSpeed(b.min(3)),
        0x4B => Request::PanTo(word),
        0x4D => Request::TiltTo(word),
        0x51 => Request::QueryPan,
        0x53 => Request::QueryTilt,
        other => Request::Unsupported(other),
    }
}

/// The answer to a position query: `59` (pan) or `5B` (tilt) with the
/// position in hundredths of a degree, data 1 the high byte.
pub fn position_reply(protocol: Protocol, wire_address: u8, tilt: bool, hundredths: u16) -> Vec<u8> {
    let [hi, lo] = hundredths.to_be_bytes();
    let opcode = if tilt { 0x5B } else { 0x59 };
    protocol.encode(wire_address, [0x00, opcode, hi, lo])
}

/// A Pelco pan position (hundredths of a degree, 0 to 35999, taken
/// modulo 36000) as the gimbal's pan in degrees, -180 (exclusive) to 180.
pub fn pan_degrees(hundredths: u16) -> f64 {
    let d = f64::from(hundredths % 36_000) / 100.0;
    if d > 180.0 { d - 360.0 } else { d }
}

/// A Pelco tilt position as the gimbal's tilt in degrees, up positive:
/// Pelco counts down from the horizon (0 to 180.00 down, above 180.00 up
/// from 360.00, i.e. 35000 is 10 degrees up), as Pelco's Spectra domes and
/// `pyptzcontroller` do.
pub fn tilt_degrees(hundredths: u16) -> f64 {
    let v = f64::from(hundredths % 36_000);
    if v > 18_000.0 {
        (36_000.0 - v) / 100.0
    } else {
        -v / 100.0
    }
}

/// The gimbal's pan in degrees as Pelco's 0 to 35999.
pub fn pan_hundredths(degrees: f64) -> u16 {
    (((degrees * 100.0).round() as i64).rem_euclid(36_000)) as u16
}

/// The gimbal's tilt in degrees (up positive) as Pelco's.
pub fn tilt_hundredths(degrees: f64) -> u16 {
    (((-degrees * 100.0).round() as i64).rem_euclid(36_000)) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(body: [u8; 4]) -> Request {
        Request::of(Protocol::D, &Frame { address: 1, body })
    }

    #[test]
    fn standard_commands_read_by_the_tables() {
        assert_eq!(d([0, 0, 0, 0]), Request::STOP);
        assert_eq!(
            d([0, 0x02, 0x20, 0]),
            Request::Motion {
                pan: Some((Way::Positive, Rate::Step(0x20))),
                tilt: None,
                zoom: None
            }
        );
        assert_eq!(
            d([0, 0x04 | 0x10 | 0x40, 0xFF, 0x3F]),
            Request::Motion {
                pan: Some((Way::Negative, Rate::Turbo)),
                tilt: Some((Way::Negative, Rate::Step(0x3F))),
                zoom: Some(Way::Negative)
            }
        );
        // Pelco-P's turbo is 40; left and right at once move nothing.
        let p = Request::of(
            Protocol::P,
            &Frame {
                address: 0,
                body: [0, 0x02 | 0x04 | 0x08, 0x40, 0x10],
            },
        );
        assert_eq!(
            p,
            Request::Motion {
                pan: None,
                tilt: Some((Way::Positive, Rate::Step(0x10))),
                zoom: None
            }
        );
        assert_eq!(d([0, 0x02, 0x40, 0]), d([0, 0x02, 0x3F, 0]), "Pelco-D 40 is no turbo");
    }

    #[test]
    fn extended_commands_read_by_the_tables() {
        assert_eq!(d([0, 0x03, 0, 5]), Request::SetPreset(5));
        assert_eq!(d([0, 0x05, 0, 5]), Request::ClearPreset(5));
        assert_eq!(d([0, 0x07, 0, 5]), Request::GoToPreset(5));
        assert_eq!(d([0, 0x4B, 0x23, 0x28]), Request::PanTo(9000));
        assert_eq!(d([0, 0x4D, 0x88, 0xB8]), Request::TiltTo(35_000));
        assert_eq!(d([0, 0x51, 0, 0]), Request::QueryPan);
        assert_eq!(d([0, 0x53, 0, 0]), Request::QueryTilt);
        assert_eq!(d([0, 0x0F, 0, 0]), Request::Unsupported(0x0F));
    }

    #[test]
    fn positions_convert_both_ways() {
        assert_eq!(pan_degrees(9000), 90.0);
        assert_eq!(pan_degrees(27_000), -90.0);
        assert_eq!(pan_hundredths(-90.0), 27_000);
        assert_eq!(tilt_degrees(35_000), 10.0);
        assert_eq!(tilt_degrees(1500), -15.0);
        assert_eq!(tilt_degrees(36_000), 0.0, "pyptzcontroller's 0 degrees up");
        assert_eq!(tilt_hundredths(10.0), 35_000);
        assert_eq!(tilt_hundredths(-15.0), 1500);
        for h in [0u16, 1, 17_999, 18_000, 18_001, 35_999] {
            assert_eq!(tilt_hundredths(tilt_degrees(h)), h);
            assert_eq!(pan_hundredths(pan_degrees(h)), h);
        }
        assert_eq!(
            position_reply(Protocol::D, 1, false, 9000),
            [0xFF, 0x01, 0x00, 0x59, 0x23, 0x28, 0xA5]
        );
    }
}
