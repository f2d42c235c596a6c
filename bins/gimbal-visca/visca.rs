//! VISCA messages as a camera reads and answers them: one table row per
//! command and inquiry this door implements, after Sony's "VISCA Command
//! List" and "Inquiry Command List" (EVI-H100S/SRG-300SE technical
//! manuals; the pan-tilt, memory, zoom and focus rows, and the "Block
//! Inquiry Command List" for the lens block). A message is
//! `8x QQ RR ... FF`, 3 to 16 bytes: `x` the camera address (this door is
//! camera 1, `81`; `88` is the broadcast, taken for IF_Clear only), `QQ`
//! `01` a command or `09` an inquiry. Replies start `90` (camera 1 + 8):
//! ACK `90 4z FF`, Completion `90 5z FF` (with data for an inquiry),
//! errors `90 6z EE FF`. Anything no row matches is a syntax error
//! ([`Error::Syntax`], `90 60 02 FF`), answered at once.

/// The longest VISCA message (the manuals' 16 bytes, terminator included).
pub const MAX_MESSAGE: usize = 16;
/// The terminator of every message.
pub const TERMINATOR: u8 = 0xFF;
/// The address byte of a message to this door's camera (camera 1).
pub const TO_CAMERA: u8 = 0x81;
/// The broadcast address byte.
pub const BROADCAST: u8 = 0x88;
/// The address byte of the camera's replies.
pub const FROM_CAMERA: u8 = 0x90;
/// The socket this door's ACK and Completion name (`4z`, `5z`).
pub const SOCKET: u8 = 1;
/// The fastest VISCA pan speed (Pan-tiltDrive `VV`).
pub const PAN_SPEED_MAX: u8 = 0x18;
/// The fastest VISCA tilt speed (`WW`); faster requests are taken as it.
pub const TILT_SPEED_MAX: u8 = 0x14;
/// VISCA zoom speeds of the variable drives (`2p`, `3p`): 0 (slowest) to 7.
pub const LENS_SPEED_MAX: u8 = 7;
/// The speed a standard (not variable) zoom or focus drive runs at.
pub const LENS_SPEED_STANDARD: u8 = 3;

/// One axis of a Pan-tiltDrive: `01` (left, up), `02` (right, down) or `03` (stop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Way {
    /// Pan left (`01`) or tilt up (`01`).
    First,
    /// Pan right (`02`) or tilt down (`02`).
    Second,
    Stop,
}

/// A zoom (`CAM_Zoom`) or focus (`CAM_Focus`) drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LensDrive {
    Stop,
    /// Zoom tele, focus far: at speed 0..=7.
    Up(u8),
    /// Zoom wide, focus near: at speed 0..=7.
    Down(u8),
}

/// `CAM_Memory`'s operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryOp {
    Reset,
    Set,
    Recall,
}

/// A command this door implements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// `8x 01 00 01 FF` IF_Clear: answered `90 50 FF`, no ACK.
    IfClear,
    /// `8x 01 04 00 0p FF` CAM_Power on (`02`) or off (`03`).
    Power(bool),
    /// `8x 01 06 01 VV WW 0Y 0Z FF` Pan-tiltDrive.
    Drive {
        pan_speed: u8,
        tilt_speed: u8,
        pan: Way,
        tilt: Way,
    },
    /// `8x 01 06 02 VV WW 0Y0Y0Y0Y 0Z0Z0Z0Z FF` AbsolutePosition (signed
    /// steps; a 5-nibble pan is taken too).
    Absolute { speed: (u8, u8), pan: i32, tilt: i32 },
    /// `8x 01 06 03 ...` RelativePosition, the same fields.
    Relative { speed: (u8, u8), pan: i32, tilt: i32 },
    /// `8x 01 06 04 FF` Home.
    Home,
    /// `8x 01 06 05 FF` Reset.
    Reset,
    /// `8x 01 04 3F 0o pp FF` CAM_Memory reset, set, recall of preset `pp`.
    Memory(MemoryOp, u8),
    /// `8x 01 04 07 ...` CAM_Zoom stop, tele, wide (standard or variable).
    Zoom(LensDrive),
    /// `8x 01 04 47 0p 0q 0r 0s FF` CAM_Zoom direct.
    ZoomTo(u16),
    /// `8x 01 04 08 ...` CAM_Focus stop, far, near (standard or variable).
    Focus(LensDrive),
}

/// An inquiry this door implements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inquiry {
    /// `8x 09 04 00 FF` CAM_PowerInq.
    Power,
    /// `8x 09 04 47 FF` CAM_ZoomPosInq.
    ZoomPosition,
    /// `8x 09 04 48 FF` CAM_FocusPosInq.
    FocusPosition,
    /// `8x 09 00 02 FF` CAM_VersionInq.
    Version,
    /// `8x 09 06 11 FF` Pan-tiltMaxSpeedInq.
    MaxSpeed,
    /// `8x 09 06 12 FF` Pan-tiltPosInq.
    PanTiltPosition,
    /// `8x 09 7E 7E 00 FF` the lens control block.
    LensBlock,
}

/// A message the door read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Message {
    Command(Command),
    Inquiry(Inquiry),
}

/// Why a message was not taken.
/// The kind of request a message not understood counts as (the door's
/// metrics, `requests_total{kind}`).
pub const OTHER: &str = "other";

impl Message {
    /// Its kind in the door's metrics: `drive`, `stop`, `absolute`,
    /// `relative`, `home`, `preset`, `lens` (zoom and focus), `inquiry`,
    /// or [`OTHER`] (IF_Clear, power, reset, and what is not understood).
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Inquiry(_) => "inquiry",
            Message::Command(Command::Drive {
                pan: Way::Stop,
                tilt: Way::Stop,
                ..
            }) => "stop",
            Message::Command(Command::Drive { .. }) => "drive",
            Message::Command(Command::Absolute { .. }) => "absolute",
            Message::Command(Command::Relative { .. }) => "relative",
            Message::Command(Command::Home) => "home",
            Message::Command(Command::Memory(..)) => "preset",
            Message::Command(Command::Zoom(_) | Command::ZoomTo(_) | Command::Focus(_)) => "lens",
            Message::Command(Command::IfClear | Command::Power(_) | Command::Reset) => OTHER,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// Addressed to another camera (`82`..`87`): not answered.
    NotForUs(u8),
    /// Not a VISCA message, or one this door does not implement: `90 60 02 FF`.
    Syntax,
}

/// What a table row's fields are.
#[derive(Clone, Copy, Debug)]
enum Kind {
    IfClear,
    Power,
    Drive,
    Absolute,
    Relative,
    Home,
    Reset,
    Memory,
    Zoom,
    ZoomTo,
    Focus,
    Ask(Inquiry),
}

/// A row: the bytes after the address, up to the terminator, as fixed
/// bytes and `None` for a parameter byte.
struct Row {
    bytes: &'static [Option<u8>],
    kind: Kind,
}

const fn row(bytes: &'static [Option<u8>], kind: Kind) -> Row {
    Row { bytes, kind }
}

const X: Option<u8> = None;

/// Sony's command and inquiry lists, the rows this door implements.
const TABLE: &[Row] = &[
    row(&[Some(0x01), Some(0x00), Some(0x01)], Kind::IfClear),
    row(&[Some(0x01), Some(0x04), Some(0x00), X], Kind::Power),
    row(&[Some(0x01), Some(0x06), Some(0x01), X, X, X, X], Kind::Drive),
    row(
        &[Some(0x01), Some(0x06), Some(0x02), X, X, X, X, X, X, X, X, X, X],
        Kind::Absolute,
    ),
    row(
        &[Some(0x01), Some(0x06), Some(0x02), X, X, X, X, X, X, X, X, X, X, X],
        Kind::Absolute,
    ),
    row(
        &[Some(0x01), Some(0x06), Some(0x03), X, X, X, X, X, X, X, X, X, X],
        Kind::Relative,
    ),
    row(
        &[Some(0x01), Some(0x06), Some(0x03), X, X, X, X, X, X, X, X, X, X, X],
        Kind::Relative,
    ),
    row(&[Some(0x01), Some(0x06), Some(0x04)], Kind::Home),
    row(&[Some(0x01), Some(0x06), Some(0x05)], Kind::Reset),
    row(&[Some(0x01), Some(0x04), Some(0x3F), X, X], Kind::Memory),
    row(&[Some(0x01), Some(0x04), Some(0x07), X], Kind::Zoom),
    row(&[Some(0x01), Some(0x04), Some(0x47), X, X, X, X], Kind::ZoomTo),
    row(&[Some(0x01), Some(0x04), Some(0x08), X], Kind::Focus),
    row(&[Some(0x09), Some(0x04), Some(0x00)], Kind::Ask(Inquiry::Power)),
    row(&[Some(0x09), Some(0x04), Some(0x47)], Kind::Ask(Inquiry::ZoomPosition)),
    row(&[Some(0x09), Some(0x04), Some(0x48)], Kind::Ask(Inquiry::FocusPosition)),
    row(&[Some(0x09), Some(0x00), Some(0x02)], Kind::Ask(Inquiry::Version)),
    row(&[Some(0x09), Some(0x06), Some(0x11)], Kind::Ask(Inquiry::MaxSpeed)),
    row(
        &[Some(0x09), Some(0x06), Some(0x12)],
        Kind::Ask(Inquiry::PanTiltPosition),
    ),
    row(
        &[Some(0x09), Some(0x7E), Some(0x7E), Some(0x00)],
        Kind::Ask(Inquiry::LensBlock),
    ),
];

/// Reads one whole message `8x ... FF`.
pub fn parse(message: &[u8]) -> Result<Message, Error> {
    let (&address, rest) = message.split_first().ok_or(Error::Syntax)?;
    let (&end, body) = rest.split_last().ok_or(Error::Syntax)?;
    if end != TERMINATOR || message.len() > MAX_MESSAGE || body.contains(&TERMINATOR) {
        return Err(Error::Syntax);
    }
    match address {
        TO_CAMERA | BROADCAST => {}
        0x82..=0x87 => return Err(Error::NotForUs(address)),
        _ => return Err(Error::Syntax),
    }
    let row = TABLE
        .iter()
        .find(|r| r.bytes.len() == body.len() && r.bytes.iter().zip(body).all(|(p, b)| p.is_none_or(|p| p == *b)))
        .ok_or(Error::Syntax)?;
    if address == BROADCAST && !matches!(row.kind, Kind::IfClear) {
        return Err(Error::Syntax);
    }
    fields(row.kind, body)
}

/// The low nibbles of `bytes` (`0p 0q ...`) as one number, each high nibble 0.
fn nibbles(bytes: &[u8]) -> Result<u32, Error> {
    bytes.iter().try_fold(0u32, |acc, &b| {
        if b > 0x0F {
            Err(Error::Syntax)
        } else {
            Ok(acc << 4 | u32::from(b))
        }
    })
}

/// A two's complement number of `n` nibbles.
fn signed(bytes: &[u8]) -> Result<i32, Error> {
    let bits = 4 * bytes.len() as u32;
    let raw = nibbles(bytes)? as i64;
    let value = if raw >= 1 << (bits - 1) { raw - (1 << bits) } else { raw };
    Ok(value as i32)
}

fn way(b: u8) -> Result<Way, Error> {
    match b {
        0x01 => Ok(Way::First),
        0x02 => Ok(Way::Second),
        0x03 => Ok(Way::Stop),
        _ => Err(Error::Syntax),
    }
}

/// `00` stop, `02`/`03` standard, `2p`/`3p` variable (zoom: tele/wide;
/// focus: far/near; the same bytes).
fn lens_drive(b: u8) -> Result<LensDrive, Error> {
    match b {
        0x00 => Ok(LensDrive::Stop),
        0x02 => Ok(LensDrive::Up(LENS_SPEED_STANDARD)),
        0x03 => Ok(LensDrive::Down(LENS_SPEED_STANDARD)),
        0x20..=0x27 => Ok(LensDrive::Up(b & 0x0F)),
        0x30..=0x37 => Ok(LensDrive::Down(b & 0x0F)),
        _ => Err(Error::Syntax),
    }
}

/// Pan speed `01`..`18`, tilt `01`..`14` (tilt up to `18` is taken as
/// `14`, some controllers send one speed for both); `00` is taken as the
/// slowest, as many cameras do.
fn speeds(pan: u8, tilt: u8) -> Result<(u8, u8), Error> {
    if pan > PAN_SPEED_MAX || tilt > PAN_SPEED_MAX {
        return Err(Error::Syntax);
    }
    Ok((pan.max(1), tilt.clamp(1, TILT_SPEED_MAX)))
}

fn fields(kind: Kind, b: &[u8]) -> Result<Message, Error> {
    let command = match kind {
        Kind::Ask(inquiry) => return Ok(Message::Inquiry(inquiry)),
        Kind::IfClear => Command::IfClear,
        Kind::Power => match b[3] {
            0x02 => Command::Power(true),
            0x03 => Command::Power(false),
            _ => return Err(Error::Syntax),
        },
        Kind::Drive => {
            let (pan, tilt) = (way(b[5])?, way(b[6])?);
            let (pan_speed, tilt_speed) = speeds(b[3], b[4])?;
            Command::Drive {
                pan_speed,
                tilt_speed,
                pan,
                tilt,
            }
        }
        Kind::Absolute | Kind::Relative => {
            let speed = speeds(b[3], b[4])?;
            let split = b.len() - 4;
            let (pan, tilt) = (signed(&b[5..split])?, signed(&b[split..])?);
            if matches!(kind, Kind::Absolute) {
                Command::Absolute { speed, pan, tilt }
            } else {
                Command::Relative { speed, pan, tilt }
            }
        }
        Kind::Home => Command::Home,
        Kind::Reset => Command::Reset,
        Kind::Memory => {
            let op = match b[3] {
                0x00 => MemoryOp::Reset,
                0x01 => MemoryOp::Set,
                0x02 => MemoryOp::Recall,
                _ => return Err(Error::Syntax),
            };
            Command::Memory(op, b[4])
        }
        Kind::Zoom => Command::Zoom(lens_drive(b[3])?),
        Kind::ZoomTo => Command::ZoomTo(nibbles(&b[3..7])? as u16),
        Kind::Focus => Command::Focus(lens_drive(b[3])?),
    };
    Ok(Message::Command(command))
}

/// `90 41 FF`: the command was taken (socket 1).
pub fn ack() -> Vec<u8> {
    vec![FROM_CAMERA, 0x40 | SOCKET, TERMINATOR]
}

/// `90 51 FF`: the command was carried out.
pub fn completion() -> Vec<u8> {
    vec![FROM_CAMERA, 0x50 | SOCKET, TERMINATOR]
}

/// `90 50 FF` (IF_Clear's answer).
pub fn clear_done() -> Vec<u8> {
    vec![FROM_CAMERA, 0x50, TERMINATOR]
}

/// An inquiry's answer: `90 50 data FF`.
pub fn answer(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + 3);
    out.extend_from_slice(&[FROM_CAMERA, 0x50]);
    out.extend_from_slice(data);
    out.push(TERMINATOR);
    out
}

/// `90 60 02 FF`: a syntax error (not implemented here), no socket.
pub fn syntax_error() -> Vec<u8> {
    vec![FROM_CAMERA, 0x60, 0x02, TERMINATOR]
}

/// `90 60 03 FF`: the command buffer is full.
pub fn buffer_full() -> Vec<u8> {
    vec![FROM_CAMERA, 0x60, 0x03, TERMINATOR]
}

/// `90 61 41 FF`: not executable (gcud refused it, or the gimbal cannot).
pub fn not_executable() -> Vec<u8> {
    vec![FROM_CAMERA, 0x60 | SOCKET, 0x41, TERMINATOR]
}

/// `value`'s low `n` nibbles as `0p 0q ...`, most significant first.
pub fn to_nibbles(value: u32, n: usize) -> Vec<u8> {
    (0..n).rev().map(|i| ((value >> (4 * i)) & 0x0F) as u8).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap())
            .collect()
    }

    #[test]
    fn the_rows_of_sonys_lists() {
        let cases: &[(&str, Message)] = &[
            ("81 01 00 01 FF", Message::Command(Command::IfClear)),
            ("88 01 00 01 FF", Message::Command(Command::IfClear)),
            ("81 01 04 00 02 FF", Message::Command(Command::Power(true))),
            (
                "81 01 06 01 18 14 01 03 FF",
                Message::Command(Command::Drive {
                    pan_speed: 0x18,
                    tilt_speed: 0x14,
                    pan: Way::First,
                    tilt: Way::Stop,
                }),
            ),
            (
                "81 01 06 01 00 18 03 02 FF",
                Message::Command(Command::Drive {
                    pan_speed: 1,
                    tilt_speed: 0x14,
                    pan: Way::Stop,
                    tilt: Way::Second,
                }),
            ),
            (
                "81 01 06 02 18 14 0F 0F 0F 0F 00 01 02 03 FF",
                Message::Command(Command::Absolute {
                    speed: (0x18, 0x14),
                    pan: -1,
                    tilt: 0x123,
                }),
            ),
            (
                "81 01 06 03 01 01 0F 0F 0F 0F 0F 00 00 00 0A FF",
                Message::Command(Command::Relative {
                    speed: (1, 1),
                    pan: -1,
                    tilt: 10,
                }),
            ),
            ("81 01 06 04 FF", Message::Command(Command::Home)),
            ("81 01 06 05 FF", Message::Command(Command::Reset)),
            (
                "81 01 04 3F 01 FE FF",
                Message::Command(Command::Memory(MemoryOp::Set, 254)),
            ),
            (
                "81 01 04 3F 02 00 FF",
                Message::Command(Command::Memory(MemoryOp::Recall, 0)),
            ),
            (
                "81 01 04 3F 00 05 FF",
                Message::Command(Command::Memory(MemoryOp::Reset, 5)),
            ),
            ("81 01 04 07 00 FF", Message::Command(Command::Zoom(LensDrive::Stop))),
            ("81 01 04 07 27 FF", Message::Command(Command::Zoom(LensDrive::Up(7)))),
            ("81 01 04 07 03 FF", Message::Command(Command::Zoom(LensDrive::Down(3)))),
            ("81 01 04 47 04 00 00 00 FF", Message::Command(Command::ZoomTo(0x4000))),
            (
                "81 01 04 08 30 FF",
                Message::Command(Command::Focus(LensDrive::Down(0))),
            ),
            ("81 09 06 12 FF", Message::Inquiry(Inquiry::PanTiltPosition)),
            ("81 09 04 47 FF", Message::Inquiry(Inquiry::ZoomPosition)),
            ("81 09 00 02 FF", Message::Inquiry(Inquiry::Version)),
            ("81 09 04 00 FF", Message::Inquiry(Inquiry::Power)),
            ("81 09 7E 7E 00 FF", Message::Inquiry(Inquiry::LensBlock)),
        ];
        for (bytes, want) in cases {
            assert_eq!(parse(&hex(bytes)), Ok(*want), "{bytes}");
        }
    }

    #[test]
    fn what_is_not_implemented_or_malformed_is_a_syntax_error() {
        for bytes in [
            "81 09 04 4B FF",                               // iris inquiry: not implemented
            "81 09 7E 7E 01 FF",                            // camera control block
            "81 09 7E 7E 02 FF",                            // other block
            "81 01 04 39 00 FF",                            // AE mode
            "81 01 06 01 19 01 01 03 FF",                   // pan speed past 0x18
            "81 01 06 01 01 01 04 03 FF",                   // no such direction
            "81 01 06 02 18 14 1F 0F 0F 0F 00 00 00 00 FF", // high nibble set
            "81 01 04 07 28 FF",                            // zoom speed 8
            "81 01 04 3F 03 01 FF",                         // no such memory operation
            "88 09 06 12 FF",                               // broadcast inquiry
            "81 FF",
            "81 01 06 04",    // no terminator
            "01 06 04 FF",    // no address
            "81 01 FF 04 FF", // a terminator inside
            "",
        ] {
            assert_eq!(parse(&hex(bytes)), Err(Error::Syntax), "{bytes}");
        }
        assert_eq!(parse(&hex("82 01 06 04 FF")), Err(Error::NotForUs(0x82)));
    }

    #[test]
    fn replies() {
        assert_eq!(ack(), hex("90 41 FF"));
        assert_eq!(completion(), hex("90 51 FF"));
        assert_eq!(syntax_error(), hex("90 60 02 FF"));
        assert_eq!(not_executable(), hex("90 61 41 FF"));
        assert_eq!(answer(&to_nibbles(0xFEDC, 4)), hex("90 50 0F 0E 0D 0C FF"));
    }

    proptest! {
        /// Any bytes at all: a message, an error, never a panic; whatever
        /// parses is a whole `81|88 ... FF` of at most 16 bytes.
        #[test]
        fn any_bytes_parse_or_fail_cleanly(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if parse(&bytes).is_ok() {
                prop_assert!(bytes.len() <= MAX_MESSAGE);
                prop_assert_eq!(bytes.last(), Some(&TERMINATOR));
                prop_assert!(bytes[0] == TO_CAMERA || bytes[0] == BROADCAST);
            }
        }

        /// Positions round-trip through the nibble encoding.
        #[test]
        fn positions_round_trip(pan in any::<i16>(), tilt in any::<i16>()) {
            let mut m = vec![0x81, 0x01, 0x06, 0x02, 0x10, 0x10];
            m.extend(to_nibbles(pan as u16 as u32, 4));
            m.extend(to_nibbles(tilt as u16 as u32, 4));
            m.push(0xFF);
            prop_assert_eq!(
                parse(&m),
                Ok(Message::Command(Command::Absolute { speed: (0x10, 0x10), pan: pan.into(), tilt: tilt.into() }))
            );
        }

        /// Every drive direction and speed in range reads back as sent.
        #[test]
        fn drives_read_back(vv in 1u8..=0x18, ww in 1u8..=0x14, y in 1u8..=3, z in 1u8..=3) {
            let parsed = parse(&[0x81, 0x01, 0x06, 0x01, vv, ww, y, z, 0xFF]);
            let way = |b| match b { 1 => Way::First, 2 => Way::Second, _ => Way::Stop };
            prop_assert_eq!(parsed, Ok(Message::Command(Command::Drive { pan_speed: vv, tilt_speed: ww, pan: way(y), tilt: way(z) })));
        }
    }
}
