//! Result replies, parsed *for a given command* because a result carries no
//! command code (Tables 4A, 5, 6, 6A, 6B, 8, 9, 10, 13, 14, 15, 17, the
//! `C0..CF` data-rate reply, `*xpn`, `*xpr`).
//!
//! protocol-notes "Parse leniently": parse leniently (every plausible reading), emit one canonical
//! form. Each type says both. Generally accepted everywhere except raw
//! replies: an echo of the command in front of the result (protocol-notes E6).

mod shapes;

use crate::EncodeError;
use crate::answer::{Answer, ResultKind, Shape};
use crate::command::{Command, CommandError, found_text};
use crate::hex::hex_value;
use crate::units::{Acceleration, DataRate, LensPosition, Limits, Position, RangeError, Rate, RateGain};
use shapes::*;

/// Awake status, Table 5: bit 0 pan not initialised, bit 1 tilt not
/// initialised, bit 2 motors off, bit 3 error. Parsed from one hex digit or a
/// raw byte 0x00..=0x0F (protocol-notes E10); emitted as one hex digit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AwakeStatus(u8);

impl AwakeStatus {
    /// Bit 0: pan (azimuth) not initialised.
    pub const PAN_NOT_INITIALIZED: u8 = 1 << 0;
    /// Bit 1: tilt (elevation) not initialised.
    pub const TILT_NOT_INITIALIZED: u8 = 1 << 1;
    /// Bit 2: motors off.
    pub const MOTORS_OFF: u8 = 1 << 2;
    /// Bit 3: an error condition (read it with `E?`).
    pub const ERROR: u8 = 1 << 3;
    /// Table 5 by name: each bit's mask, snake_case name and meaning,
    /// lowest bit first.
    pub const BITS: [(u8, &'static str, &'static str); 4] = [
        (
            Self::PAN_NOT_INITIALIZED,
            "azimuth_not_initialized",
            "azimuth (pan) not initialised",
        ),
        (
            Self::TILT_NOT_INITIALIZED,
            "elevation_not_initialized",
            "elevation (tilt) not initialised",
        ),
        (Self::MOTORS_OFF, "motors_off", "motors off"),
        (Self::ERROR, "error", "error condition"),
    ];
    /// The status of these bits; refused above 0x0F (four bits on the wire).
    pub fn new(bits: u8) -> Result<Self, RangeError> {
        if bits > 0x0F {
            return Err(RangeError {
                what: "awake status bits",
                value: bits.into(),
                min: 0,
                max: 15,
            });
        }
        Ok(Self(bits))
    }
    /// The bits, masks in [`Self::BITS`].
    pub const fn bits(self) -> u8 {
        self.0
    }
}

/// Identification block, Table 6 (protocol-notes E5): device ID (2 hex), protocol
/// revision (2 characters, leading space allowed), name and serial number
/// (20 characters each, space padded). Parsing trims the padding and accepts
/// short blocks; encoding pads to the full 44 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identity<'a> {
    /// Device ID.
    pub id: u8,
    /// Protocol revision, two characters as sent (e.g. `b" 9"`).
    pub revision: [u8; 2],
    name: &'a [u8],
    serial: &'a [u8],
}

impl<'a> Identity<'a> {
    /// Width of the name and serial number fields on the wire.
    pub const FIELD_LEN: usize = 20;
    /// Name and serial: at most 20 printable ASCII characters each, without
    /// trailing spaces (they would be taken for padding).
    pub fn new(id: u8, revision: [u8; 2], name: &'a [u8], serial: &'a [u8]) -> Result<Self, RangeError> {
        for (what, field) in [("device name length", name), ("serial number length", serial)] {
            let ok = field.len() <= Self::FIELD_LEN
                && field.iter().all(|b| (0x20..=0x7E).contains(b))
                && field.last() != Some(&b' ');
            if !ok {
                return Err(RangeError {
                    what,
                    value: field.len() as i64,
                    min: 0,
                    max: Self::FIELD_LEN as i64,
                });
            }
        }
        Ok(Self {
            id,
            revision,
            name,
            serial,
        })
    }
    /// The device name, padding trimmed.
    pub const fn name(&self) -> &'a [u8] {
        self.name
    }
    /// The serial number, padding trimmed.
    pub const fn serial(&self) -> &'a [u8] {
        self.serial
    }
}

/// Error code bits per axis, Table 6A: bit 0 centre reference, bit 4
/// initialisation, bit 5 motor time-out, bit 6 temperature. 2 + 2 hex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ErrorCodes {
    /// Pan axis error bits.
    pub pan: u8,
    /// Tilt axis error bits.
    pub tilt: u8,
}

impl ErrorCodes {
    /// Bit 0: centre reference error.
    pub const CENTER_REFERENCE: u8 = 1 << 0;
    /// Bit 4: initialisation error.
    pub const INITIALIZATION: u8 = 1 << 4;
    /// Bit 5: motor time-out.
    pub const MOTOR_TIMEOUT: u8 = 1 << 5;
    /// Bit 6: temperature error.
    pub const TEMPERATURE: u8 = 1 << 6;
    /// Table 6A by name: each bit's mask, snake_case name and meaning.
    pub const BITS: [(u8, &'static str, &'static str); 4] = [
        (Self::CENTER_REFERENCE, "center_reference", "centre reference error"),
        (Self::INITIALIZATION, "initialization", "initialization error"),
        (Self::MOTOR_TIMEOUT, "motor_timeout", "motor time-out"),
        (Self::TEMPERATURE, "temperature", "temperature error"),
    ];
}

/// Status bits per axis, Table 6B (protocol-notes E3): low byte bit 0 not
/// initialised, 1 + limit, 2 - limit, 3 + centre, 4 - centre, 5 + hard stop,
/// 6 - hard stop, 7 error present; high byte reserved. Parsed from 2 + 2 or
/// 4 + 4 hex, emitted as 4 + 4.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusBits {
    /// Pan axis status bits.
    pub pan: u16,
    /// Tilt axis status bits.
    pub tilt: u16,
}

impl StatusBits {
    /// Bit 0: the axis is not initialised.
    pub const NOT_INITIALIZED: u16 = 1 << 0;
    /// Bit 1: positive limit found.
    pub const POSITIVE_LIMIT_FOUND: u16 = 1 << 1;
    /// Bit 2: negative limit found.
    pub const NEGATIVE_LIMIT_FOUND: u16 = 1 << 2;
    /// Bit 3: positive centre found.
    pub const POSITIVE_CENTER_FOUND: u16 = 1 << 3;
    /// Bit 4: negative centre found.
    pub const NEGATIVE_CENTER_FOUND: u16 = 1 << 4;
    /// Bit 5: at the positive hard stop.
    pub const POSITIVE_HARD_STOP: u16 = 1 << 5;
    /// Bit 6: at the negative hard stop.
    pub const NEGATIVE_HARD_STOP: u16 = 1 << 6;
    /// Bit 7: an error is present.
    pub const ERROR_PRESENT: u16 = 1 << 7;
    /// Table 6B by name (low byte; the high byte is reserved): each bit's
    /// mask, snake_case name and meaning.
    pub const BITS: [(u16, &'static str, &'static str); 8] = [
        (Self::NOT_INITIALIZED, "not_initialized", "not initialized"),
        (
            Self::POSITIVE_LIMIT_FOUND,
            "positive_limit_found",
            "positive limit found",
        ),
        (
            Self::NEGATIVE_LIMIT_FOUND,
            "negative_limit_found",
            "negative limit found",
        ),
        (
            Self::POSITIVE_CENTER_FOUND,
            "positive_center_found",
            "positive centre found",
        ),
        (
            Self::NEGATIVE_CENTER_FOUND,
            "negative_center_found",
            "negative centre found",
        ),
        (Self::POSITIVE_HARD_STOP, "positive_hard_stop", "positive hard stop"),
        (Self::NEGATIVE_HARD_STOP, "negative_hard_stop", "negative hard stop"),
        (Self::ERROR_PRESENT, "error_present", "error present"),
    ];
}

/// Rate gains, Table 8 (protocol-notes E1, E6): pan and tilt gain x10 as 2 hex each,
/// then 4 unused characters. Parsed with or without a `G?` echo and with or
/// without the unused characters; emitted as `pptt0000`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateGains {
    /// Pan rate gain.
    pub pan: RateGain,
    /// Tilt rate gain.
    pub tilt: RateGain,
}

/// Initialisation results, Table 9 (protocol-notes E4): per direction, low byte bit 0
/// centre switch detected, bit 2 hard limit detected (bad), bit 3 limit
/// switch hit. Parsed from 2 or 4 hex each, emitted as 4 each.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InitResults {
    /// Pan, counter-clockwise direction.
    pub pan_ccw: u16,
    /// Pan, clockwise direction.
    pub pan_cw: u16,
    /// Tilt, counter-clockwise direction.
    pub tilt_ccw: u16,
    /// Tilt, clockwise direction.
    pub tilt_cw: u16,
}

impl InitResults {
    /// Table 9, one direction's word: the centre switch was detected.
    pub const CENTER_SWITCH_DETECTED: u16 = 1 << 0;
    /// Table 9: a hard limit was detected (the initialisation failed).
    pub const HARD_LIMIT_DETECTED: u16 = 1 << 2;
    /// Table 9: the limit switch was hit.
    pub const LIMIT_SWITCH_HIT: u16 = 1 << 3;
    /// Table 9 by name: each bit's mask, snake_case name and meaning.
    pub const BITS: [(u16, &'static str, &'static str); 3] = [
        (
            Self::CENTER_SWITCH_DETECTED,
            "center_switch_detected",
            "centre switch detected",
        ),
        (Self::HARD_LIMIT_DETECTED, "hard_limit_detected", "hard limit detected"),
        (Self::LIMIT_SWITCH_HIT, "limit_switch_hit", "limit switch hit"),
    ];

    /// Whether every direction found its centre without a hard limit: the
    /// initialisation succeeded (otherwise the gimbal turns its motors off).
    pub fn succeeded(&self) -> bool {
        [self.pan_ccw, self.pan_cw, self.tilt_ccw, self.tilt_cw]
            .iter()
            .all(|w| w & Self::CENTER_SWITCH_DETECTED != 0 && w & Self::HARD_LIMIT_DETECTED == 0)
    }
}

/// Verify-home result, Table 14: three digits, each bit 0 = pan, bit 1 =
/// tilt: limit switch found, centre switch found, count correct. Parsed
/// from hex digits or raw bytes 0..=15; emitted as hex digits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HomeStatus {
    /// Limit switch found: bit 0 pan, bit 1 tilt.
    pub limit_switches: u8,
    /// Centre switch found: bit 0 pan, bit 1 tilt.
    pub center_switches: u8,
    /// Count correct: bit 0 pan, bit 1 tilt.
    pub count_correct: u8,
}

/// A typed result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reply<'a> {
    /// `AW`, Table 5.
    AwakeStatus(AwakeStatus),
    /// `B?`: `C0..CF` (bare digit accepted); emitted `Cn`.
    MaxDataRate(DataRate),
    /// `D?`, Table 6.
    Identity(Identity<'a>),
    /// `E?`, Table 6A.
    Errors(ErrorCodes),
    /// `I?`, Table 6B.
    StatusBits(StatusBits),
    /// `G?`, Table 8.
    RateGains(RateGains),
    /// `IX`, Table 9.
    Initialization(InitResults),
    /// `L?`, Table 10: 12 hex.
    Limits(Limits),
    /// `LR`, Table 4A (protocol-notes E11): `L` + one hex digit of relay bits (bare
    /// digit accepted).
    Relays(u8),
    /// `A?`: pan then tilt, 4 hex each (Table 13, protocol-notes E7).
    Accelerations {
        /// Pan acceleration.
        pan: Acceleration,
        /// Tilt acceleration.
        tilt: Acceleration,
    },
    /// `AP?` / `AT?`: 4 hex.
    Acceleration(Acceleration),
    /// `R?`: pan then tilt, 4 hex each.
    Rates {
        /// Pan rate.
        pan: Rate,
        /// Tilt rate.
        tilt: Rate,
    },
    /// `RP?` / `RT?`: 4 hex.
    Rate(Rate),
    /// `HV`, Table 14.
    VerifyHome(HomeStatus),
    /// `P?`, `P?nn`, `S?nn`, Table 15: 8 hex (a leading `P` accepted).
    Position(Position),
    /// `V?`, Table 17: 6 hex (a leading `V` accepted).
    Lens(LensPosition),
    /// `*xpn`: decimal count (protocol-notes E14).
    AuxCount(u16),
    /// `*xprnnn`: the bytes read, raw.
    AuxData(&'a [u8]),
    /// Rev 1.9 commands: the reply bytes, raw (protocol-notes E13).
    Raw(&'a [u8]),
}

/// Why a payload is not the result of a given command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplyError {
    /// The command is answered by ACK (or NIC) only, never by a result.
    #[error("{command} has no result reply")]
    NoResult {
        /// The command's mnemonic.
        command: &'static str,
    },
    /// A byte of the payload is not of the result's form.
    #[error("result of {command}: at offset {offset} expected {expected}, found {}", found_text(*.found))]
    Malformed {
        /// The command's mnemonic.
        command: &'static str,
        /// Offset of the offending byte in the payload.
        offset: usize,
        /// The byte found there, `None` at the end of the payload.
        found: Option<u8>,
        /// What the result has there.
        expected: &'static str,
    },
    /// A value is well formed but outside its range.
    #[error("result of {command}: value at offset {offset}: {error}")]
    OutOfRange {
        /// The command's mnemonic.
        command: &'static str,
        /// Offset of the value in the payload.
        offset: usize,
        /// The range it breaks.
        error: RangeError,
    },
}

impl From<CommandError> for ReplyError {
    fn from(e: CommandError) -> Self {
        match e {
            CommandError::BadArgument {
                command,
                offset,
                found,
                expected,
            } => ReplyError::Malformed {
                command,
                offset,
                found,
                expected,
            },
            CommandError::OutOfRange { command, offset, error } => ReplyError::OutOfRange { command, offset, error },
            CommandError::Empty | CommandError::Unknown { .. } => ReplyError::Malformed {
                command: "?",
                offset: 0,
                found: None,
                expected: "a result",
            },
        }
    }
}

fn digit_or_raw(b: u8) -> Option<u8> {
    hex_value(b).or(if b <= 0x0F { Some(b) } else { None })
}

/// The longest echo of a command recognised in front of its result.
const ECHO_MAX: usize = 16;

/// What a command's result looks like, read from the command once: its
/// row's answer fact, its mnemonic, and the command's bytes where a device
/// may echo them in front of the result (protocol-notes E6). Owned and
/// `Copy`, so it travels with a command whose bytes are kept elsewhere (a
/// router's forwarded frame): [`Reply::parse_expected`] reads a result by
/// it exactly as [`Reply::parse`] reads one by the command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExpectedReply {
    name: &'static str,
    answer: Answer,
    echo: [u8; ECHO_MAX],
    /// 0: no echo is recognised (a raw result, or a command too long).
    echo_len: u8,
}

impl ExpectedReply {
    /// What a result of `command` looks like.
    pub fn of(command: &Command<'_>) -> Self {
        let answer = command.answer();
        let mut echo = [0u8; ECHO_MAX];
        let echo_len = match answer.shape() {
            Some(shape) if !matches!(shape, Shape::AuxData | Shape::Raw) => {
                command.encode(&mut echo).map_or(0, |bytes| bytes.len() as u8)
            }
            _ => 0,
        };
        Self {
            name: command.mnemonic(),
            answer,
            echo,
            echo_len,
        }
    }

    /// What follows the command's ACK ([`Command::result_kind`]).
    pub fn result_kind(&self) -> ResultKind {
        self.answer.kind()
    }

    /// The command's mnemonic ([`Command::mnemonic`]).
    pub fn mnemonic(&self) -> &'static str {
        self.name
    }
}

impl<'a> Reply<'a> {
    /// Parses `payload` as the result of `command`.
    pub fn parse(command: &Command<'_>, payload: &'a [u8]) -> Result<Self, ReplyError> {
        Self::parse_expected(&ExpectedReply::of(command), payload)
    }

    /// Parses `payload` as the result [`ExpectedReply`] describes.
    pub fn parse_expected(expected: &ExpectedReply, payload: &'a [u8]) -> Result<Self, ReplyError> {
        let name = expected.name;
        let shape = expected.answer.shape().ok_or(ReplyError::NoResult { command: name })?;
        if payload.is_empty() {
            // A frame never carries an empty payload (Table 1: 1..=256 bytes).
            return Err(malformed(name, 0, None, "a result of at least one byte"));
        }
        // An echo of the command in front of the result (protocol-notes E6).
        let echo = &expected.echo[..usize::from(expected.echo_len)];
        let skip = match !echo.is_empty() && payload.len() > echo.len() && payload.starts_with(echo) {
            true => echo.len(),
            false => 0,
        };
        let r = Reading {
            name,
            payload,
            skip,
            body: &payload[skip..],
        };
        match shape {
            Shape::AwakeStatus => parse_awake_status(&r),
            Shape::MaxDataRate => parse_max_data_rate(&r),
            Shape::Identity => parse_identity(&r),
            Shape::Errors => parse_errors(&r),
            Shape::StatusBits => parse_status_bits(&r),
            Shape::RateGains => parse_rate_gains(&r),
            Shape::Initialization => parse_initialization(&r),
            Shape::Limits => parse_limits(&r),
            Shape::Relays => parse_relays(&r),
            Shape::Accelerations => parse_accelerations(&r),
            Shape::Acceleration => parse_acceleration(&r),
            Shape::Rates => parse_rates(&r),
            Shape::Rate => parse_rate(&r),
            Shape::VerifyHome => parse_verify_home(&r),
            Shape::Position => parse_position(&r),
            Shape::Lens => parse_lens(&r),
            Shape::AuxCount => parse_aux_count(&r),
            Shape::AuxData => Ok(Reply::AuxData(payload)),
            Shape::Raw => Ok(Reply::Raw(payload)),
        }
    }

    /// Whether this is the kind of result `command` expects.
    pub fn answers(&self, command: &Command<'_>) -> bool {
        let own = match self {
            Reply::AwakeStatus(_) => Shape::AwakeStatus,
            Reply::MaxDataRate(_) => Shape::MaxDataRate,
            Reply::Identity(_) => Shape::Identity,
            Reply::Errors(_) => Shape::Errors,
            Reply::StatusBits(_) => Shape::StatusBits,
            Reply::RateGains(_) => Shape::RateGains,
            Reply::Initialization(_) => Shape::Initialization,
            Reply::Limits(_) => Shape::Limits,
            Reply::Relays(_) => Shape::Relays,
            Reply::Accelerations { .. } => Shape::Accelerations,
            Reply::Acceleration(_) => Shape::Acceleration,
            Reply::Rates { .. } => Shape::Rates,
            Reply::Rate(_) => Shape::Rate,
            Reply::VerifyHome(_) => Shape::VerifyHome,
            Reply::Position(_) => Shape::Position,
            Reply::Lens(_) => Shape::Lens,
            Reply::AuxCount(_) => Shape::AuxCount,
            Reply::AuxData(_) => Shape::AuxData,
            Reply::Raw(_) => Shape::Raw,
        };
        command.answer().shape() == Some(own)
    }
}

fn malformed(command: &'static str, offset: usize, found: Option<u8>, expected: &'static str) -> ReplyError {
    ReplyError::Malformed {
        command,
        offset,
        found,
        expected,
    }
}

/// A field emitted as one hex digit must be 0..=15.
fn nibble(what: &'static str, value: u8) -> Result<(), EncodeError> {
    if value > 0x0F {
        return Err(EncodeError::OutOfRange(RangeError {
            what,
            value: value.into(),
            min: 0,
            max: 15,
        }));
    }
    Ok(())
}
