//! Every command of Tables 4, 11 and 16 and the rev 1.9 list (1.2), as one
//! typed enum with `parse` and `encode`.
//!
//! Disambiguation (NOTES "Command disambiguation"): by first character and
//! length. `P?`/`PL` (2) vs `Pnn` (3) vs `P?nn` (4) vs `Paaaaeeee` (9);
//! `Snn` vs `SP0..SPF`/`ST0..STF` vs `S?nn`; `VMn` (3) vs `V`+6 hex (7).
//! Hex arguments are emitted upper case and accepted in either case.

use nom::Parser;

use crate::EncodeError;
use crate::hex::{Writer, decimal, hex_n, hex_u8, hex_u16, hex_value, hex12, is_hex, offset_in};
use crate::units::{
    Acceleration, Angle, AuxConfig, AuxPort, AuxReadLen, Axis, DataRate, DeviceId, DigitalZoom, LensPosition,
    LensSpeed, Limits, Parity, Position, RangeError, Rate, RateGain, Relay, Speed,
};

/// Raw bytes for an auxiliary serial port, 1..=200 of them (Table 16 `*xpt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AuxBytes<'a>(&'a [u8]);

impl<'a> AuxBytes<'a> {
    pub const MAX: usize = 200;
    pub fn new(bytes: &'a [u8]) -> Result<Self, RangeError> {
        if bytes.is_empty() || bytes.len() > Self::MAX {
            return Err(RangeError {
                what: "auxiliary transmit length",
                value: bytes.len() as i64,
                min: 1,
                max: Self::MAX as i64,
            });
        }
        Ok(Self(bytes))
    }
    pub const fn bytes(&self) -> &'a [u8] {
        self.0
    }
}

/// Rev 1.9 commands published by name only (1.2, NOTES E13): their
/// argument and reply bytes are kept raw, no layout is guessed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Extended {
    /// `HP`: go to the gimbal position saved by `HA`.
    GoToHaltPosition,
    /// `VP`: go to the lens position saved by `HA`.
    LensGoToHaltPosition,
    /// `VS`: camera and relay status.
    CameraRelayStatus,
    /// `F?`: current focus speed number.
    FocusSpeedQuery,
    /// `Z?`: current zoom speed number.
    ZoomSpeedQuery,
    /// `C?`: lens software limits or preset position values.
    LensLimitsQuery,
    /// `*dA`: analog channel values.
    AnalogInputs,
    /// `*di`: digital input values.
    DigitalInputs,
    /// `*do`: digital output values.
    DigitalOutputs,
    /// `*dl`: status messages.
    StatusMessages,
    /// `*dm`: set loop mode.
    LoopMode,
    /// `*mr`: rate commands.
    RateCommand,
    /// `*me`: send/read position in encoder counts.
    EncoderPosition,
    /// `*mp`: send/read position in floating point.
    FloatPosition,
    /// `*mu`: set/read user parameters.
    UserParameters,
    /// `*sa`: set/read inertial gain.
    InertialGain,
    /// `*sgr`: set/read rate gain in floating point.
    RateGainFloat,
    /// `*sgp`: set/read position gain in floating point.
    PositionGainFloat,
    /// `*sl`: set/read rate/acceleration limits.
    RateLimits,
}

impl Extended {
    pub const ALL: [Extended; 19] = [
        Extended::GoToHaltPosition,
        Extended::LensGoToHaltPosition,
        Extended::CameraRelayStatus,
        Extended::FocusSpeedQuery,
        Extended::ZoomSpeedQuery,
        Extended::LensLimitsQuery,
        Extended::AnalogInputs,
        Extended::DigitalInputs,
        Extended::DigitalOutputs,
        Extended::StatusMessages,
        Extended::LoopMode,
        Extended::RateCommand,
        Extended::EncoderPosition,
        Extended::FloatPosition,
        Extended::UserParameters,
        Extended::InertialGain,
        Extended::RateGainFloat,
        Extended::PositionGainFloat,
        Extended::RateLimits,
    ];

    /// The command's name bytes on the wire.
    pub const fn name(self) -> &'static str {
        match self {
            Extended::GoToHaltPosition => "HP",
            Extended::LensGoToHaltPosition => "VP",
            Extended::CameraRelayStatus => "VS",
            Extended::FocusSpeedQuery => "F?",
            Extended::ZoomSpeedQuery => "Z?",
            Extended::LensLimitsQuery => "C?",
            Extended::AnalogInputs => "*dA",
            Extended::DigitalInputs => "*di",
            Extended::DigitalOutputs => "*do",
            Extended::StatusMessages => "*dl",
            Extended::LoopMode => "*dm",
            Extended::RateCommand => "*mr",
            Extended::EncoderPosition => "*me",
            Extended::FloatPosition => "*mp",
            Extended::UserParameters => "*mu",
            Extended::InertialGain => "*sa",
            Extended::RateGainFloat => "*sgr",
            Extended::PositionGainFloat => "*sgp",
            Extended::RateLimits => "*sl",
        }
    }

    /// Whether a result follows: queries answer, set/read ones may.
    pub const fn result_kind(self) -> ResultKind {
        match self {
            Extended::GoToHaltPosition
            | Extended::LensGoToHaltPosition
            | Extended::LoopMode
            | Extended::RateCommand => ResultKind::None,
            Extended::CameraRelayStatus
            | Extended::FocusSpeedQuery
            | Extended::ZoomSpeedQuery
            | Extended::LensLimitsQuery
            | Extended::AnalogInputs
            | Extended::DigitalInputs
            | Extended::DigitalOutputs
            | Extended::StatusMessages => ResultKind::Required(ResultTimeout::Normal),
            Extended::EncoderPosition
            | Extended::FloatPosition
            | Extended::UserParameters
            | Extended::InertialGain
            | Extended::RateGainFloat
            | Extended::PositionGainFloat
            | Extended::RateLimits => ResultKind::Optional,
        }
    }
}

/// How long a result may take, as a class; the durations are the user's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResultTimeout {
    /// Queries answered from memory.
    Normal,
    /// `IX`: the initialisation sequence moves both axes to their switches.
    Long,
}

/// What follows the ACK of a command (Tables 4, 11, 16 "RESPONSE").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResultKind {
    /// ACK only (a NIC may still follow).
    None,
    /// ACK + a result frame (or a NIC).
    Required(ResultTimeout),
    /// A rev 1.9 set/read command: a result only when it reads.
    Optional,
}

/// One command payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command<'a> {
    // Table 4: general device control.
    /// `#NN`: set device address/ID.
    SetDeviceId(DeviceId),
    /// `AW`: awake status (Table 5).
    AwakeStatus,
    /// `B?`: maximum data rate (`C0..CF`).
    QueryMaxDataRate,
    /// `C0..CF`: set communication data rate.
    SetDataRate(DataRate),
    /// `D?`: identification (Table 6).
    Identify,
    /// `E?`: error codes (Table 6A).
    QueryErrors,
    /// `I?`: status bits (Table 6B).
    QueryStatusBits,
    /// `GRPnn` / `GRTnn`: set a rate gain (Table 7).
    SetRateGain(Axis, RateGain),
    /// `G?`: rate gains (Table 8).
    QueryRateGains,
    /// `IX`: initialisation (Table 9).
    Initialize,
    /// `L0..L3`: open relay.
    OpenRelay(Relay),
    /// `L8..LB`: close relay.
    CloseRelay(Relay),
    /// `LR`: relay status (Table 4A).
    QueryRelays,
    /// `LC`: clear software limits.
    ClearLimits,
    /// `LS` + 12 hex: set software limits (Table 10).
    SetLimits(Limits),
    /// `L?`: software limits (Table 10).
    QueryLimits,

    // Table 11: pan/tilt mount.
    /// `APnnnn` / `ATnnnn` (Table 12).
    SetAcceleration(Axis, Acceleration),
    /// `A?`: both accelerations (Table 13, NOTES E7).
    QueryAccelerations,
    /// `AP?` / `AT?`: one axis (NOTES E7).
    QueryAcceleration(Axis),
    /// `HA`: halt, stores the position, motors off.
    Halt,
    /// `HV`: verify home (Table 14).
    VerifyHome,
    /// `HO`: go home (0, 0).
    Home,
    /// `HS`: stop, motors off.
    Stop,
    /// `P?`: current position (Table 15).
    QueryPosition,
    /// `Paaaaeeee`: go to position (Table 15).
    GoTo(Position),
    /// `PL`: pan left (CW) until `PS`.
    PanLeft,
    /// `PR`: pan right (CCW) until `PS`.
    PanRight,
    /// `PS`: pan stop.
    PanStop,
    /// `PT`: stop motion.
    StopMotion,
    /// `Pnn`: go to preset.
    GoToPreset(u8),
    /// `P?nn`: preset position (Table 15).
    QueryPreset(u8),
    /// `RPnnnn` / `RTnnnn` (Table 12).
    SetRate(Axis, Rate),
    /// `R?`: both rates (Table 13, NOTES E7).
    QueryRates,
    /// `RP?` / `RT?`: one axis (NOTES E7).
    QueryRate(Axis),
    /// `Snn`: store current position as preset.
    StorePreset(u8),
    /// `SP0..SPF` / `ST0..STF`: proportional speed.
    SetSpeed(Axis, Speed),
    /// `S?nn`: position stored at preset (Table 15).
    QueryStoredPreset(u8),
    /// `TD`: tilt down (CW) until `TS`.
    TiltDown,
    /// `TS`: tilt stop.
    TiltStop,
    /// `TU`: tilt up (CCW) until `TS`.
    TiltUp,
    /// `VMn`: vector motion on/off.
    SetVectorMode(bool),

    // Table 16: camera.
    /// `CN`: camera and lens power on.
    CameraOn,
    /// `CX`: camera and lens power off.
    CameraOff,
    /// `F0..F9`: focus speed.
    FocusSpeed(LensSpeed),
    /// `FA`: auto-focus on (not implemented by the gimbal).
    AutoFocusOn,
    /// `FF`: focus far until `FS`.
    FocusFar,
    /// `FN`: focus near until `FS`.
    FocusNear,
    /// `FS`: focus stop.
    FocusStop,
    /// `FX`: auto-focus off (not implemented by the gimbal).
    AutoFocusOff,
    /// `Vzzzfff`: lens go-to (Table 17).
    LensGoTo(LensPosition),
    /// `V?`: lens position (Table 17).
    QueryLens,
    /// `Z0..Z9`: zoom speed.
    ZoomSpeed(LensSpeed),
    /// `ZA..ZF`: digital zoom (not implemented by the gimbal).
    DigitalZoom(DigitalZoom),
    /// `ZI`: zoom in until `ZS`.
    ZoomIn,
    /// `ZO`: zoom out until `ZS`.
    ZoomOut,
    /// `ZS`: zoom stop.
    ZoomStop,
    /// `*xpc,baud,data,stop,parity` (Table 18).
    AuxConfigure(AuxPort, AuxConfig),
    /// `*xpt` + data.
    AuxTransmit(AuxPort, AuxBytes<'a>),
    /// `*xprnnn`: receive up to nnn bytes (decimal, NOTES E14).
    AuxReceive(AuxPort, AuxReadLen),
    /// `*xpn`: characters waiting.
    AuxCount(AuxPort),
    /// `*xpf`: flush.
    AuxFlush(AuxPort),

    /// Rev 1.9 commands with their raw argument bytes (NOTES E13).
    Extended(Extended, &'a [u8]),
    /// A payload that fits no command: a device answers it with NIC.
    Unknown(&'a [u8]),
}

/// Why a payload is not a well-formed command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    #[error("empty payload")]
    Empty,
    #[error("no command starts with byte 0x{first:02X} and has {len} bytes")]
    Unknown { first: u8, len: usize },
    #[error("{command}: at offset {offset} expected {expected}, found {}", found_text(*.found))]
    BadArgument {
        command: &'static str,
        offset: usize,
        found: Option<u8>,
        expected: &'static str,
    },
    #[error("{command}: argument at offset {offset}: {error}")]
    OutOfRange {
        command: &'static str,
        offset: usize,
        error: RangeError,
    },
}

/// `byte 0x41 ('A')` or `end of payload`, for error messages.
pub(crate) struct FoundText(Option<u8>);

impl core::fmt::Display for FoundText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(b) if b.is_ascii_graphic() => write!(f, "byte 0x{b:02X} ('{}')", b as char),
            Some(b) => write!(f, "byte 0x{b:02X}"),
            None => f.write_str("end of payload"),
        }
    }
}

pub(crate) fn found_text(found: Option<u8>) -> FoundText {
    FoundText(found)
}

type Res<'a, T> = nom::IResult<&'a [u8], T>;

/// Runs `parser` over `payload[skip..]`, which it must consume entirely.
pub(crate) fn whole<'a, T>(
    command: &'static str,
    payload: &'a [u8],
    skip: usize,
    expected: &'static str,
    mut parser: impl FnMut(&'a [u8]) -> Res<'a, T>,
) -> Result<T, CommandError> {
    let input = payload.get(skip..).unwrap_or(&[]);
    let bad = |at: &'a [u8], expected| CommandError::BadArgument {
        command,
        offset: offset_in(payload, at),
        found: at.first().copied(),
        expected,
    };
    match parser(input) {
        Ok(([], value)) => Ok(value),
        Ok((rest, _)) => Err(bad(rest, "end of payload")),
        Err(nom::Err::Error(e) | nom::Err::Failure(e)) => Err(bad(e.input, expected)),
        Err(nom::Err::Incomplete(_)) => Err(bad(&[], expected)),
    }
}

fn ranged<T>(command: &'static str, offset: usize, value: Result<T, RangeError>) -> Result<T, CommandError> {
    value.map_err(|error| CommandError::OutOfRange { command, offset, error })
}

/// `,baud,dataBits,stopBits,parity` of `*xpc` (Table 18), from offset 4 of
/// `payload`; every error names the field and the offset where it went wrong.
fn aux_config(payload: &[u8]) -> Result<AuxConfig, CommandError> {
    const COMMAND: &str = "*xpc";
    let mut at = 4;
    let mut field = |max: usize, expected: &'static str| -> Result<(usize, u32), CommandError> {
        let bad = |offset: usize, expected| CommandError::BadArgument {
            command: COMMAND,
            offset,
            found: payload.get(offset).copied(),
            expected,
        };
        if payload.get(at) != Some(&b',') {
            return Err(bad(at, "','"));
        }
        let from = at + 1;
        let rest = payload.get(from..).unwrap_or(&[]);
        let (rest, value) = decimal(max)(rest).map_err(|_| bad(from, expected))?;
        at = offset_in(payload, rest);
        Ok((from, value))
    };
    let (baud_at, baud) = field(6, "baud rate, 1 to 6 decimal digits")?;
    let (data_at, data) = field(1, "data bits 5..=8")?;
    let (stop_at, stop) = field(1, "stop bits 1 or 2")?;
    let (parity_at, parity) = field(1, "parity 0, 1 or 2")?;
    if at != payload.len() {
        return Err(CommandError::BadArgument {
            command: COMMAND,
            offset: at,
            found: payload.get(at).copied(),
            expected: "end of command",
        });
    }
    let range = |offset, error| CommandError::OutOfRange {
        command: COMMAND,
        offset,
        error,
    };
    let parity = match parity {
        0 => Parity::None,
        1 => Parity::Odd,
        2 => Parity::Even,
        _ => {
            return Err(range(
                parity_at,
                RangeError {
                    what: "parity",
                    value: parity.into(),
                    min: 0,
                    max: 2,
                },
            ));
        }
    };
    // Check field by field so that the error points at the wrong one.
    let valid = |baud, data, stop| AuxConfig::new(baud, data, stop, parity);
    valid(baud, 8, 1).map_err(|e| range(baud_at, e))?;
    valid(9600, data as u8, 1).map_err(|e| range(data_at, e))?;
    valid(9600, 8, stop as u8).map_err(|e| range(stop_at, e))?;
    valid(baud, data as u8, stop as u8).map_err(|e| range(baud_at, e))
}

impl<'a> Command<'a> {
    /// Parses a payload; anything that fits no command is [`Command::Unknown`].
    pub fn parse(payload: &'a [u8]) -> Self {
        Self::parse_strict(payload).unwrap_or(Command::Unknown(payload))
    }

    /// Parses a payload, saying what is wrong with one that fits no command.
    pub fn parse_strict(payload: &'a [u8]) -> Result<Self, CommandError> {
        use Command as C;
        let unknown = || match payload.first() {
            Some(&first) => CommandError::Unknown {
                first,
                len: payload.len(),
            },
            None => CommandError::Empty,
        };
        for ext in Extended::ALL {
            if let Some(args) = payload.strip_prefix(ext.name().as_bytes()) {
                return Ok(C::Extended(ext, args));
            }
        }
        let axis = |b: u8| Axis::from_letter(b);
        Ok(match payload {
            [] => return Err(CommandError::Empty),
            [b'#', ..] => {
                let id = whole("#NN", payload, 1, "two hex digits 01..FE", hex_u8)?;
                C::SetDeviceId(ranged("#NN", 1, DeviceId::new(id))?)
            }
            b"AW" => C::AwakeStatus,
            b"A?" => C::QueryAccelerations,
            [b'A', a, b'?'] if axis(*a).is_some() => C::QueryAcceleration(axis(*a).unwrap_or(Axis::Pan)),
            [b'A', a, ..] if axis(*a).is_some() => {
                let v = whole("APnnnn/ATnnnn", payload, 2, "four hex digits", hex_u16)?;
                C::SetAcceleration(axis(*a).unwrap_or(Axis::Pan), Acceleration(v))
            }
            b"B?" => C::QueryMaxDataRate,
            b"CN" => C::CameraOn,
            b"CX" => C::CameraOff,
            [b'C', d] if is_hex(*d) => match DataRate::from_code(hex_value(*d).unwrap_or(0)) {
                Some(rate) => C::SetDataRate(rate),
                None => return Err(unknown()),
            },
            b"D?" => C::Identify,
            b"E?" => C::QueryErrors,
            b"FA" => C::AutoFocusOn,
            b"FF" => C::FocusFar,
            b"FN" => C::FocusNear,
            b"FS" => C::FocusStop,
            b"FX" => C::AutoFocusOff,
            [b'F', d] if d.is_ascii_digit() => C::FocusSpeed(ranged("F0..F9", 1, LensSpeed::new(d - b'0'))?),
            b"G?" => C::QueryRateGains,
            [b'G', b'R', a, ..] if axis(*a).is_some() => {
                let v = whole("GRPnn/GRTnn", payload, 3, "two hex digits", hex_u8)?;
                C::SetRateGain(
                    axis(*a).unwrap_or(Axis::Pan),
                    ranged("GRPnn/GRTnn", 3, RateGain::new(v))?,
                )
            }
            b"HA" => C::Halt,
            b"HV" => C::VerifyHome,
            b"HO" => C::Home,
            b"HS" => C::Stop,
            b"I?" => C::QueryStatusBits,
            b"IX" => C::Initialize,
            b"LR" => C::QueryRelays,
            b"LC" => C::ClearLimits,
            b"L?" => C::QueryLimits,
            [b'L', d @ b'0'..=b'3'] => C::OpenRelay(ranged("L0..L3", 1, Relay::new(d - b'0'))?),
            [b'L', d @ (b'8' | b'9' | b'A' | b'B' | b'a' | b'b')] => {
                let bit = hex_value(*d).unwrap_or(8) - 8;
                C::CloseRelay(ranged("L8..LB", 1, Relay::new(bit))?)
            }
            [b'L', b'S', ..] => {
                let (pan_ccw, pan_cw, tilt_ccw, tilt_cw) = whole("LS", payload, 2, "twelve hex digits", |i| {
                    (hex12, hex12, hex12, hex12).parse(i)
                })?;
                C::SetLimits(Limits {
                    pan_ccw,
                    pan_cw,
                    tilt_ccw,
                    tilt_cw,
                })
            }
            b"P?" => C::QueryPosition,
            b"PL" => C::PanLeft,
            b"PR" => C::PanRight,
            b"PS" => C::PanStop,
            b"PT" => C::StopMotion,
            [b'P', a, b] if is_hex(*a) && is_hex(*b) => {
                C::GoToPreset(whole("Pnn", payload, 1, "two hex digits", hex_u8)?)
            }
            [b'P', b'?', _, _] => C::QueryPreset(whole("P?nn", payload, 2, "two hex digits", hex_u8)?),
            [b'P', _, _, _, _, _, _, _, _] => {
                let (pan, tilt) = whole("Paaaaeeee", payload, 1, "eight hex digits", |i| {
                    (hex_u16, hex_u16).parse(i)
                })?;
                C::GoTo(Position::new(Angle(pan as i16), Angle(tilt as i16)))
            }
            b"R?" => C::QueryRates,
            [b'R', a, b'?'] if axis(*a).is_some() => C::QueryRate(axis(*a).unwrap_or(Axis::Pan)),
            [b'R', a, ..] if axis(*a).is_some() => {
                let v = whole("RPnnnn/RTnnnn", payload, 2, "four hex digits", hex_u16)?;
                C::SetRate(axis(*a).unwrap_or(Axis::Pan), Rate(v))
            }
            [b'S', b'?', _, _] => C::QueryStoredPreset(whole("S?nn", payload, 2, "two hex digits", hex_u8)?),
            [b'S', a, _] if axis(*a).is_some() => {
                let v = whole("SPn/STn", payload, 2, "one hex digit", hex_n(1))?;
                C::SetSpeed(
                    axis(*a).unwrap_or(Axis::Pan),
                    ranged("SPn/STn", 2, Speed::new(v as u8))?,
                )
            }
            [b'S', _, _] => C::StorePreset(whole("Snn", payload, 1, "two hex digits", hex_u8)?),
            b"TD" => C::TiltDown,
            b"TS" => C::TiltStop,
            b"TU" => C::TiltUp,
            [b'V', b'M', d] => match d {
                b'0' => C::SetVectorMode(false),
                b'1' => C::SetVectorMode(true),
                _ => {
                    return Err(CommandError::BadArgument {
                        command: "VMn",
                        offset: 2,
                        found: Some(*d),
                        expected: "'0' or '1'",
                    });
                }
            },
            b"V?" => C::QueryLens,
            [b'V', _, _, _, _, _, _] => {
                let (zoom, focus) = whole("Vzzzfff", payload, 1, "six hex digits", |i| (hex12, hex12).parse(i))?;
                C::LensGoTo(LensPosition { zoom, focus })
            }
            b"ZI" => C::ZoomIn,
            b"ZO" => C::ZoomOut,
            b"ZS" => C::ZoomStop,
            [b'Z', d] if d.is_ascii_digit() => C::ZoomSpeed(ranged("Z0..Z9", 1, LensSpeed::new(d - b'0'))?),
            [b'Z', d @ (b'A'..=b'F' | b'a'..=b'f')] => {
                C::DigitalZoom(ranged("ZA..ZF", 1, DigitalZoom::new(hex_value(*d).unwrap_or(10)))?)
            }
            [b'*', b'x', p, op, ..] => {
                let port = match p {
                    b'0' | b'1' => ranged("*xp", 2, AuxPort::new(p - b'0'))?,
                    _ => {
                        return Err(CommandError::BadArgument {
                            command: "*xp..",
                            offset: 2,
                            found: Some(*p),
                            expected: "auxiliary port '0' or '1'",
                        });
                    }
                };
                match op {
                    b'c' => {
                        let config = aux_config(payload)?;
                        C::AuxConfigure(port, config)
                    }
                    b't' => C::AuxTransmit(
                        port,
                        ranged("*xpt", 4, AuxBytes::new(payload.get(4..).unwrap_or_default()))?,
                    ),
                    b'r' => {
                        let n = whole("*xprnnn", payload, 4, "decimal count 1..=256", |i| decimal(3).parse(i))?;
                        C::AuxReceive(port, ranged("*xprnnn", 4, AuxReadLen::new(n as u16))?)
                    }
                    b'n' if payload.len() == 4 => C::AuxCount(port),
                    b'f' if payload.len() == 4 => C::AuxFlush(port),
                    _ => {
                        return Err(CommandError::BadArgument {
                            command: "*xp..",
                            offset: 3,
                            found: Some(*op),
                            expected: "one of c, t, r, n, f (n and f alone)",
                        });
                    }
                }
            }
            _ => return Err(unknown()),
        })
    }

    /// Writes the payload into `buf`; returns the written prefix.
    pub fn encode<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EncodeError> {
        use Command as C;
        let mut w = Writer::new(buf);
        let fixed: Option<&[u8]> = match self {
            C::AwakeStatus => Some(b"AW"),
            C::QueryMaxDataRate => Some(b"B?"),
            C::Identify => Some(b"D?"),
            C::QueryErrors => Some(b"E?"),
            C::QueryStatusBits => Some(b"I?"),
            C::QueryRateGains => Some(b"G?"),
            C::Initialize => Some(b"IX"),
            C::QueryRelays => Some(b"LR"),
            C::ClearLimits => Some(b"LC"),
            C::QueryLimits => Some(b"L?"),
            C::QueryAccelerations => Some(b"A?"),
            C::Halt => Some(b"HA"),
            C::VerifyHome => Some(b"HV"),
            C::Home => Some(b"HO"),
            C::Stop => Some(b"HS"),
            C::QueryPosition => Some(b"P?"),
            C::PanLeft => Some(b"PL"),
            C::PanRight => Some(b"PR"),
            C::PanStop => Some(b"PS"),
            C::StopMotion => Some(b"PT"),
            C::QueryRates => Some(b"R?"),
            C::TiltDown => Some(b"TD"),
            C::TiltStop => Some(b"TS"),
            C::TiltUp => Some(b"TU"),
            C::CameraOn => Some(b"CN"),
            C::CameraOff => Some(b"CX"),
            C::AutoFocusOn => Some(b"FA"),
            C::FocusFar => Some(b"FF"),
            C::FocusNear => Some(b"FN"),
            C::FocusStop => Some(b"FS"),
            C::AutoFocusOff => Some(b"FX"),
            C::QueryLens => Some(b"V?"),
            C::ZoomIn => Some(b"ZI"),
            C::ZoomOut => Some(b"ZO"),
            C::ZoomStop => Some(b"ZS"),
            _ => None,
        };
        if let Some(bytes) = fixed {
            w.put(bytes)?;
            return Ok(w.finish());
        }
        match *self {
            C::SetDeviceId(id) => {
                w.byte(b'#')?;
                w.hex(id.get().into(), 2)?;
            }
            C::SetDataRate(rate) => {
                let code = rate.encodable_code().map_err(EncodeError::OutOfRange)?;
                w.byte(b'C')?;
                w.hex(code.into(), 1)?;
            }
            C::SetRateGain(axis, gain) => {
                w.put(&[b'G', b'R', axis.letter()])?;
                w.hex(gain.get().into(), 2)?;
            }
            C::OpenRelay(relay) => w.put(&[b'L', b'0' + relay.get()])?,
            C::CloseRelay(relay) => {
                w.byte(b'L')?;
                w.hex(u32::from(relay.get()) + 8, 1)?;
            }
            C::SetLimits(l) => {
                w.put(b"LS")?;
                for v in [l.pan_ccw, l.pan_cw, l.tilt_ccw, l.tilt_cw] {
                    w.hex(v.get().into(), 3)?;
                }
            }
            C::SetAcceleration(axis, a) => {
                w.put(&[b'A', axis.letter()])?;
                w.hex(a.0.into(), 4)?;
            }
            C::QueryAcceleration(axis) => w.put(&[b'A', axis.letter(), b'?'])?,
            C::GoTo(p) => {
                w.byte(b'P')?;
                w.hex(u32::from(p.pan.0 as u16), 4)?;
                w.hex(u32::from(p.tilt.0 as u16), 4)?;
            }
            C::GoToPreset(n) => {
                w.byte(b'P')?;
                w.hex(n.into(), 2)?;
            }
            C::QueryPreset(n) => {
                w.put(b"P?")?;
                w.hex(n.into(), 2)?;
            }
            C::SetRate(axis, r) => {
                w.put(&[b'R', axis.letter()])?;
                w.hex(r.0.into(), 4)?;
            }
            C::QueryRate(axis) => w.put(&[b'R', axis.letter(), b'?'])?,
            C::StorePreset(n) => {
                w.byte(b'S')?;
                w.hex(n.into(), 2)?;
            }
            C::SetSpeed(axis, s) => {
                w.put(&[b'S', axis.letter()])?;
                w.hex(s.get().into(), 1)?;
            }
            C::QueryStoredPreset(n) => {
                w.put(b"S?")?;
                w.hex(n.into(), 2)?;
            }
            C::SetVectorMode(on) => w.put(if on { b"VM1" } else { b"VM0" })?,
            C::FocusSpeed(s) => w.put(&[b'F', b'0' + s.get()])?,
            C::LensGoTo(lens) => {
                w.byte(b'V')?;
                w.hex(lens.zoom.get().into(), 3)?;
                w.hex(lens.focus.get().into(), 3)?;
            }
            C::ZoomSpeed(s) => w.put(&[b'Z', b'0' + s.get()])?,
            C::DigitalZoom(z) => {
                w.byte(b'Z')?;
                w.hex(z.get().into(), 1)?;
            }
            C::AuxConfigure(port, c) => {
                w.put(&[b'*', b'x', b'0' + port.get(), b'c', b','])?;
                w.decimal(c.baud(), 1)?;
                w.put(&[b',', b'0' + c.data_bits(), b',', b'0' + c.stop_bits(), b','])?;
                w.byte(match c.parity() {
                    Parity::None => b'0',
                    Parity::Odd => b'1',
                    Parity::Even => b'2',
                })?;
            }
            C::AuxTransmit(port, data) => {
                w.put(&[b'*', b'x', b'0' + port.get(), b't'])?;
                w.put(data.bytes())?;
            }
            C::AuxReceive(port, n) => {
                w.put(&[b'*', b'x', b'0' + port.get(), b'r'])?;
                w.decimal(n.get().into(), 3)?;
            }
            C::AuxCount(port) => w.put(&[b'*', b'x', b'0' + port.get(), b'n'])?,
            C::AuxFlush(port) => w.put(&[b'*', b'x', b'0' + port.get(), b'f'])?,
            C::Extended(ext, args) => {
                w.put(ext.name().as_bytes())?;
                w.put(args)?;
            }
            C::Unknown(bytes) => w.put(bytes)?,
            _ => {}
        }
        if w.len() == 0 {
            return Err(EncodeError::PayloadLength { len: 0 });
        }
        Ok(w.finish())
    }

    /// What follows the ACK (Tables 4, 11, 16 "RESPONSE" column).
    pub fn result_kind(&self) -> ResultKind {
        use Command as C;
        match self {
            C::AwakeStatus
            | C::QueryMaxDataRate
            | C::Identify
            | C::QueryErrors
            | C::QueryStatusBits
            | C::QueryRateGains
            | C::QueryRelays
            | C::QueryLimits
            | C::QueryAccelerations
            | C::QueryAcceleration(_)
            | C::VerifyHome
            | C::QueryPosition
            | C::QueryPreset(_)
            | C::QueryRates
            | C::QueryRate(_)
            | C::QueryStoredPreset(_)
            | C::QueryLens
            | C::AuxReceive(..)
            | C::AuxCount(_) => ResultKind::Required(ResultTimeout::Normal),
            C::Initialize => ResultKind::Required(ResultTimeout::Long),
            C::Extended(ext, _) => ext.result_kind(),
            _ => ResultKind::None,
        }
    }

    /// Stop and halt commands, which overtake queued work (DESIGN "Routing").
    pub fn is_stop(&self) -> bool {
        use Command as C;
        matches!(
            self,
            C::Halt | C::Stop | C::PanStop | C::TiltStop | C::StopMotion | C::FocusStop | C::ZoomStop
        )
    }

    /// For a command that starts continuous motion (`PL`, `PR`, `TU`, `TD`,
    /// `FF`, `FN`, `ZI`, `ZO`), the command that stops it (Tables 11, 16).
    pub fn stopped_by(&self) -> Option<Command<'static>> {
        use Command as C;
        match self {
            C::PanLeft | C::PanRight => Some(C::PanStop),
            C::TiltUp | C::TiltDown => Some(C::TiltStop),
            C::FocusFar | C::FocusNear => Some(C::FocusStop),
            C::ZoomIn | C::ZoomOut => Some(C::ZoomStop),
            _ => None,
        }
    }

    /// The line rate a `C0..CF` command switches to (reserved codes included).
    pub fn data_rate_change(&self) -> Option<DataRate> {
        match self {
            Command::SetDataRate(rate) => Some(*rate),
            _ => None,
        }
    }

    /// The mnemonic of the command's row in the spec tables, for logs.
    pub fn mnemonic(&self) -> &'static str {
        use Command as C;
        match self {
            C::SetDeviceId(_) => "#NN",
            C::AwakeStatus => "AW",
            C::QueryMaxDataRate => "B?",
            C::SetDataRate(_) => "Cn",
            C::Identify => "D?",
            C::QueryErrors => "E?",
            C::QueryStatusBits => "I?",
            C::SetRateGain(Axis::Pan, _) => "GRPnn",
            C::SetRateGain(Axis::Tilt, _) => "GRTnn",
            C::QueryRateGains => "G?",
            C::Initialize => "IX",
            C::OpenRelay(_) => "L0..L3",
            C::CloseRelay(_) => "L8..LB",
            C::QueryRelays => "LR",
            C::ClearLimits => "LC",
            C::SetLimits(_) => "LS",
            C::QueryLimits => "L?",
            C::SetAcceleration(Axis::Pan, _) => "APnnnn",
            C::SetAcceleration(Axis::Tilt, _) => "ATnnnn",
            C::QueryAccelerations => "A?",
            C::QueryAcceleration(Axis::Pan) => "AP?",
            C::QueryAcceleration(Axis::Tilt) => "AT?",
            C::Halt => "HA",
            C::VerifyHome => "HV",
            C::Home => "HO",
            C::Stop => "HS",
            C::QueryPosition => "P?",
            C::GoTo(_) => "Paaaaeeee",
            C::PanLeft => "PL",
            C::PanRight => "PR",
            C::PanStop => "PS",
            C::StopMotion => "PT",
            C::GoToPreset(_) => "Pnn",
            C::QueryPreset(_) => "P?nn",
            C::SetRate(Axis::Pan, _) => "RPnnnn",
            C::SetRate(Axis::Tilt, _) => "RTnnnn",
            C::QueryRates => "R?",
            C::QueryRate(Axis::Pan) => "RP?",
            C::QueryRate(Axis::Tilt) => "RT?",
            C::StorePreset(_) => "Snn",
            C::SetSpeed(Axis::Pan, _) => "SPn",
            C::SetSpeed(Axis::Tilt, _) => "STn",
            C::QueryStoredPreset(_) => "S?nn",
            C::TiltDown => "TD",
            C::TiltStop => "TS",
            C::TiltUp => "TU",
            C::SetVectorMode(_) => "VMn",
            C::CameraOn => "CN",
            C::CameraOff => "CX",
            C::FocusSpeed(_) => "Fn",
            C::AutoFocusOn => "FA",
            C::FocusFar => "FF",
            C::FocusNear => "FN",
            C::FocusStop => "FS",
            C::AutoFocusOff => "FX",
            C::LensGoTo(_) => "Vzzzfff",
            C::QueryLens => "V?",
            C::ZoomSpeed(_) => "Zn",
            C::DigitalZoom(_) => "ZA..ZF",
            C::ZoomIn => "ZI",
            C::ZoomOut => "ZO",
            C::ZoomStop => "ZS",
            C::AuxConfigure(..) => "*xpc",
            C::AuxTransmit(..) => "*xpt",
            C::AuxReceive(..) => "*xprnnn",
            C::AuxCount(_) => "*xpn",
            C::AuxFlush(_) => "*xpf",
            C::Extended(ext, _) => ext.name(),
            C::Unknown(_) => "unknown",
        }
    }
}
