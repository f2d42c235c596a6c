//! Every command of Tables 4, 11 and 16 and the rev 1.9 list (1.2), as one
//! typed enum with `parse` and `encode`.
//!
//! Each command is declared once, as a row of `command_table!` below (the
//! rev 1.9 names as rows of `extended_table!`): the enum variant, its parse
//! arms, its encoding, its mnemonic, what follows its ACK with the shape of
//! its result (used by [`crate::Reply`]), and whether it stops or starts a
//! motion all come from that row. No match over commands has a wildcard arm.
//!
//! Disambiguation (protocol-notes "Command disambiguation"): by first character and
//! length. `P?`/`PL` (2) vs `Pnn` (3) vs `P?nn` (4) vs `Paaaaeeee` (9);
//! `Snn` vs `SP0..SPF`/`ST0..STF` vs `S?nn`; `VMn` (3) vs `V`+6 hex (7).
//! Hex arguments are emitted upper case and accepted in either case.

use nom::Parser;

use crate::EncodeError;
use crate::answer::{Answer, Shape};
pub use crate::answer::{ResultKind, ResultTimeout};
use crate::hex::{Writer, decimal, hex_n, hex_u8, hex_u16, hex_value, hex12, is_hex, offset_in};
use crate::mount::{Describes, MountEffect, NewSpeed};
use crate::units::{
    Acceleration, Angle, AuxConfig, AuxPort, AuxReadLen, Axis, DataRate, DeviceId, DigitalZoom, LensPosition,
    LensSpeed, Limits, Parity, Position, RangeError, Rate, RateGain, Relay, Speed,
};

/// Raw bytes for an auxiliary serial port, 1..=200 of them (Table 16 `*xpt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AuxBytes<'a>(&'a [u8]);

impl<'a> AuxBytes<'a> {
    /// The most bytes one `*xpt` carries.
    pub const MAX: usize = 200;
    /// The bytes to send, refused when empty or longer than [`Self::MAX`].
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
    /// The bytes, as given to [`Self::new`].
    pub const fn bytes(&self) -> &'a [u8] {
        self.0
    }
}

/// A row's motion fact (Tables 11, 16).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Motion {
    /// Starts no continuous motion and stops none.
    Other,
    /// A stop or halt: overtakes queued work.
    Stop,
    /// Starts a continuous motion that runs until this command.
    Until(Command<'static>),
}

/// The rev 1.9 table: one row per command published by name only (1.2,
/// protocol-notes E13); the argument and reply bytes stay raw, no layout is guessed.
/// A row is `Variant = "name", answer, mount;`.
macro_rules! extended_table {
    ($( $(#[doc = $doc:literal])* $Variant:ident = $name:literal, $answer:expr, $mount:expr; )+) => {
        /// Rev 1.9 commands published by name only (1.2, protocol-notes E13): their
        /// argument and reply bytes are kept raw, no layout is guessed.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Extended {
            $( $(#[doc = $doc])* $Variant, )+
        }

        impl Extended {
            const COUNT: usize = [$($name),+].len();

            /// Every rev 1.9 command, in table order.
            pub const ALL: [Extended; Self::COUNT] = [$(Extended::$Variant),+];

            /// The command's name bytes on the wire.
            pub const fn name(self) -> &'static str {
                match self {
                    $( Extended::$Variant => $name, )+
                }
            }

            /// The row's answer fact.
            pub(crate) const fn answer(self) -> Answer {
                match self {
                    $( Extended::$Variant => $answer, )+
                }
            }

            /// How the command acts on the pan/tilt mount: its row's
            /// governance fact ([`MountEffect`]).
            pub const fn mount(self) -> MountEffect {
                match self {
                    $( Extended::$Variant => $mount, )+
                }
            }

            /// What the command does: its row's documentation (1.2).
            pub fn description(self) -> &'static str {
                let text: &'static str = match self {
                    $( Extended::$Variant => concat!($($doc),+), )+
                };
                text.trim_start()
            }
        }
    };
}

extended_table! {
    /// `HP`: go to the gimbal position saved by `HA`.
    GoToHaltPosition = "HP", Answer::Ack, MountEffect::Unbounded;
    /// `VP`: go to the lens position saved by `HA`.
    LensGoToHaltPosition = "VP", Answer::Ack, MountEffect::Setting;
    /// `VS`: camera and relay status.
    CameraRelayStatus = "VS", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `F?`: current focus speed number.
    FocusSpeedQuery = "F?", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `Z?`: current zoom speed number.
    ZoomSpeedQuery = "Z?", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `C?`: lens software limits or preset position values.
    LensLimitsQuery = "C?", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `*dA`: analog channel values.
    AnalogInputs = "*dA", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `*di`: digital input values.
    DigitalInputs = "*di", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `*do`: digital output values.
    DigitalOutputs = "*do", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `*dl`: status messages.
    StatusMessages = "*dl", Answer::normal(Shape::Raw), MountEffect::READS;
    /// `*dm`: set loop mode.
    LoopMode = "*dm", Answer::Ack, MountEffect::Dynamics;
    /// `*mr`: rate commands.
    RateCommand = "*mr", Answer::Ack, MountEffect::Unbounded;
    /// `*me`: send/read position in encoder counts.
    EncoderPosition = "*me", Answer::Optional(Shape::Raw), MountEffect::Unbounded;
    /// `*mp`: send/read position in floating point.
    FloatPosition = "*mp", Answer::Optional(Shape::Raw), MountEffect::Unbounded;
    /// `*mu`: set/read user parameters.
    UserParameters = "*mu", Answer::Optional(Shape::Raw), MountEffect::Dynamics;
    /// `*sa`: set/read inertial gain.
    InertialGain = "*sa", Answer::Optional(Shape::Raw), MountEffect::Dynamics;
    /// `*sgr`: set/read rate gain in floating point.
    RateGainFloat = "*sgr", Answer::Optional(Shape::Raw), MountEffect::Dynamics;
    /// `*sgp`: set/read position gain in floating point.
    PositionGainFloat = "*sgp", Answer::Optional(Shape::Raw), MountEffect::Dynamics;
    /// `*sl`: set/read rate/acceleration limits.
    RateLimits = "*sl", Answer::Optional(Shape::Raw), MountEffect::Dynamics;
}

impl Extended {
    /// Whether a result follows: queries answer, set/read ones may.
    pub const fn result_kind(self) -> ResultKind {
        self.answer().kind()
    }

    /// The rev 1.9 command whose name starts `payload`, and its argument bytes.
    fn split(payload: &[u8]) -> Option<(Extended, &[u8])> {
        let first = payload.first()?;
        for ext in Extended::ALL {
            let name = ext.name().as_bytes();
            // The first byte alone rules out most names, without a slice compare.
            if name.first() == Some(first) {
                if let Some(args) = payload.strip_prefix(name) {
                    return Some((ext, args));
                }
            }
        }
        None
    }
}

/// The command table: one row per command, from which the enum, `parse`,
/// `encode`, `mnemonic`, `result_kind`, the stop/motion facts and the reply
/// shape are all generated (no wildcard arm over commands anywhere: a new
/// row that leaves out a fact does not compile).
///
/// A row is `Variant(field: Type, ..) => { facts }` with either
/// - `wire: b"XY", answer: .., motion: ..` for a command without arguments
///   (parsed, encoded and named by its bytes), or
/// - `mnemonic: .., answer: .., motion: .., parse: { arms }, encode: { .. }`:
///   `parse` arms are `pattern (if guard) => command` over the payload, or
///   `parse: (expr)` an `Option<Command>` tried before all pattern arms;
///   `encode` writes the fields with the writer. The fields are bound by
///   name in `mnemonic`, `answer`, `motion` and `encode`.
///
/// - `axis_query: (letter, pan, tilt)` or `axis_value: (letter, pan, tilt)`
///   for a per-axis query or four-hex-digit setting, written out as the
///   form above.
///
/// The row's name for scripts is its variant in snake_case (`MotorsStop`:
/// `motors_stop`); its description is its doc comment.
///
/// All pattern arms form one `match`, in table order, so of two rows whose
/// patterns overlap the more specific comes first (`AP?` before `APnnnn`).
macro_rules! command_table {
    (
        $(#[$meta:meta])*
        pub enum $Command:ident<$lt:lifetime> (payload = $payload:ident, writer = $w:ident) {
            $($rows:tt)*
        }
    ) => {
        command_table!(@row [$(#[$meta])* $Command $lt $payload $w] [] $($rows)*);
    };

    // Each row, in turn, brought to one form. Each rule spells out the whole
    // row, so a row missing a fact (or with one misspelt) matches none and
    // fails to compile.
    (@row [$(#[$meta:meta])* $Command:ident $lt:lifetime $payload:ident $w:ident] [$($done:tt)*]
        $(#[doc = $doc:literal])* $Variant:ident => {
            wire: $wire:tt, answer: $answer:expr, motion: $motion:expr, mount: $mount:expr $(,)?
        }
        $($rest:tt)*
    ) => {
        command_table!(@row [$(#[$meta])* $Command $lt $payload $w] [$($done)*
            [$(#[doc = $doc])* $Variant => {
                wire: [$wire],
                mnemonic: const { wire_name($wire) },
                answer: $answer,
                motion: $motion,
                mount: $mount,
                arms: { $wire => Self::$Variant },
                encode: { $w.put($wire)?; },
            }]
        ] $($rest)*);
    };
    (@row $head:tt [$($done:tt)*]
        $(#[doc = $doc:literal])* $Variant:ident $( ( $($field:ident : $fty:ty),+ $(,)? ) )? => {
            mnemonic: $mnemonic:expr, answer: $answer:expr, motion: $motion:expr, mount: $mount:expr,
            parse: { $($arms:tt)* }, encode: { $($encode:tt)* } $(,)?
        }
        $($rest:tt)*
    ) => {
        command_table!(@row $head [$($done)*
            [$(#[doc = $doc])* $Variant $( ( $($field : $fty),+ ) )? => {
                wire: [],
                mnemonic: $mnemonic,
                answer: $answer,
                motion: $motion,
                mount: $mount,
                arms: { $($arms)* },
                encode: { $($encode)* },
            }]
        ] $($rest)*);
    };
    (@row $head:tt [$($done:tt)*]
        $(#[doc = $doc:literal])* $Variant:ident $( ( $($field:ident : $fty:ty),+ $(,)? ) )? => {
            mnemonic: $mnemonic:expr, answer: $answer:expr, motion: $motion:expr, mount: $mount:expr,
            parse: ( $parse:expr ), encode: { $($encode:tt)* } $(,)?
        }
        $($rest:tt)*
    ) => {
        command_table!(@row $head [$($done)*
            [$(#[doc = $doc])* $Variant $( ( $($field : $fty),+ ) )? => {
                wire: [],
                mnemonic: $mnemonic,
                answer: $answer,
                motion: $motion,
                mount: $mount,
                arms: {},
                first: ($parse),
                encode: { $($encode)* },
            }]
        ] $($rest)*);
    };

    // Per-axis rows (Table 11, protocol-notes E7), written out as rows of
    // the form above: the letter, the axis letter, then `?` (a query) or
    // four hex digits (a setting, value Table 12).
    (@row [$(#[$meta:meta])* $Command:ident $lt:lifetime $payload:ident $w:ident] $done:tt
        $(#[doc = $doc:literal])* $Variant:ident($ax:ident: Axis) => {
            axis_query: ($letter:literal, $pan:literal, $tilt:literal),
            answer: $answer:expr, motion: $motion:expr, mount: $mount:expr $(,)?
        }
        $($rest:tt)*
    ) => {
        command_table!(@row [$(#[$meta])* $Command $lt $payload $w] $done
            $(#[doc = $doc])* $Variant($ax: Axis) => {
                mnemonic: $ax.pick($pan, $tilt), answer: $answer, motion: $motion, mount: $mount,
                parse: {
                    [$letter, a, b'?'] if axis(*a).is_some() => Self::$Variant(axis(*a).unwrap_or(Axis::Pan)),
                },
                encode: { $w.put(&[$letter, $ax.letter(), b'?'])?; },
            }
            $($rest)*);
    };
    (@row [$(#[$meta:meta])* $Command:ident $lt:lifetime $payload:ident $w:ident] $done:tt
        $(#[doc = $doc:literal])* $Variant:ident($ax:ident: Axis, $value:ident: $Value:ident) => {
            axis_value: ($letter:literal, $pan:literal, $tilt:literal),
            answer: $answer:expr, motion: $motion:expr, mount: $mount:expr $(,)?
        }
        $($rest:tt)*
    ) => {
        command_table!(@row [$(#[$meta])* $Command $lt $payload $w] $done
            $(#[doc = $doc])* $Variant($ax: Axis, $value: $Value) => {
                mnemonic: $ax.pick($pan, $tilt), answer: $answer, motion: $motion, mount: $mount,
                parse: {
                    [$letter, a, ..] if axis(*a).is_some() => {
                        let v = arg(concat!($pan, "/", $tilt), $payload, 2, "four hex digits", hex_u16)?;
                        Self::$Variant(axis(*a).unwrap_or(Axis::Pan), $Value(v))
                    },
                },
                encode: {
                    $w.put(&[$letter, $ax.letter()])?;
                    $w.hex($value.0.into(), 4)?;
                },
            }
            $($rest)*);
    };

    // Every row in one form: the enum and its functions.
    (@row [$(#[$meta:meta])* $Command:ident $lt:lifetime $payload:ident $w:ident] [$(
        [$(#[doc = $doc:literal])* $Variant:ident $( ( $($field:ident : $fty:ty),+ ) )? => {
            wire: [$($wire:literal)?],
            mnemonic: $mnemonic:expr,
            answer: $answer:expr,
            motion: $motion:expr,
            mount: $mount:expr,
            arms: { $( $pat:pat $(if $guard:expr)? => $command:expr ),* $(,)? },
            $( first: ($first:expr), )?
            encode: { $($encode:tt)* },
        }]
    )+]) => {
        $(#[$meta])*
        pub enum $Command<$lt> {
            $( $(#[doc = $doc])* $Variant $( ( $($fty),+ ) )?, )+
        }

        impl $Command<'static> {
            /// The rows without arguments, each with its wire bytes, in table order.
            pub const FIXED: &'static [(&'static [u8], $Command<'static>)] = &[$($( ($wire, Self::$Variant), )?)+];
        }

        /// The rows of the command table, one per [`Command`] variant.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Row {
            $( $(#[doc = $doc])* $Variant, )+
        }

        impl Row {
            /// Every row, in table order.
            pub const ALL: [Row; [$(Row::$Variant),+].len()] = [$(Row::$Variant),+];

            /// The row's name for scripts (gimbalctl's and gcud's JSON): the
            /// variant in snake_case.
            pub const fn script_name(self) -> &'static str {
                match self {
                    $( Row::$Variant => $crate::snake_case!($Variant), )+
                }
            }
        }

        impl<$lt> $Command<$lt> {
            /// The command's row.
            pub const fn row(&self) -> Row {
                match *self {
                    $( Self::$Variant { .. } => Row::$Variant, )+
                }
            }

            /// The command's name for scripts: its row's script column.
            pub const fn script_name(&self) -> &'static str {
                self.row().script_name()
            }

            /// What the command does: its row's documentation (the spec
            /// table's description, with the table it comes from).
            pub fn description(&self) -> &'static str {
                let text: &'static str = match *self {
                    $( Self::$Variant { .. } => concat!($($doc),+), )+
                };
                text.trim_start()
            }

            /// The row that takes `payload`, or why none does ([`no_row`]).
            /// A payload of a row that `implemented` refuses fits no row:
            /// its arguments are not read (nothing of them is linked when
            /// `implemented` is known at compile time).
            fn parse_rows<E: Failure>($payload: &$lt [u8], implemented: impl Fn(Row) -> bool) -> Result<Self, E> {
                $($(
                    if implemented(Row::$Variant) {
                        if let Some(command) = $first {
                            return Ok(command);
                        }
                    }
                )?)+
                Ok(match $payload {
                    $($( $pat $(if $guard)? => {
                        if !implemented(Row::$Variant) {
                            return Err(unknown($payload));
                        }
                        $command
                    } )*)+
                    _ => return Err(no_row($payload)),
                })
            }

            /// Writes the row's bytes (not checked for emptiness).
            fn encode_row(&self, $w: &mut Writer<'_>) -> Result<(), EncodeError> {
                match *self {
                    $(
                        #[allow(unused_variables)]
                        Self::$Variant $( ( $($field),+ ) )? => { $($encode)* }
                    )+
                }
                Ok(())
            }

            /// The mnemonic of the command's row in the spec tables, for logs.
            pub fn mnemonic(&self) -> &'static str {
                match *self {
                    $(
                        #[allow(unused_variables)]
                        Self::$Variant $( ( $($field),+ ) )? => $mnemonic,
                    )+
                }
            }

            /// The row's answer fact: result kind and reply shape.
            pub(crate) fn answer(&self) -> Answer {
                match *self {
                    $(
                        #[allow(unused_variables)]
                        Self::$Variant $( ( $($field),+ ) )? => $answer,
                    )+
                }
            }

            /// How the command acts on the pan/tilt mount: its row's
            /// governance fact ([`MountEffect`]).
            pub const fn mount(&self) -> MountEffect {
                match *self {
                    $(
                        #[allow(unused_variables)]
                        Self::$Variant $( ( $($field),+ ) )? => $mount,
                    )+
                }
            }

            /// The row's motion fact.
            fn motion(&self) -> Motion {
                match *self {
                    $(
                        #[allow(unused_variables)]
                        Self::$Variant $( ( $($field),+ ) )? => $motion,
                    )+
                }
            }
        }
    };
}

/// A `wire` row's name as text (evaluated at compile time).
const fn wire_name(wire: &'static [u8]) -> &'static str {
    match core::str::from_utf8(wire) {
        Ok(name) => name,
        Err(_) => "?",
    }
}

/// The axis a letter names (`P` pan, `T` tilt).
fn axis(letter: u8) -> Option<Axis> {
    Axis::from_letter(letter)
}

/// `*xp..`: the auxiliary port digit at offset 2.
fn aux_port<E: Failure>(p: u8) -> Result<AuxPort, E> {
    match p {
        b'0' | b'1' => ranged("*xp", 2, AuxPort::new(p - b'0')),
        _ => Err(E::bad_argument("*xp..", 2, Some(p), "auxiliary port '0' or '1'")),
    }
}

/// Why `payload` fits no row: empty, or `*xp` with a bad port or an
/// operation no row takes (the port is checked first, as the rows do), or
/// no command at all.
fn no_row<E: Failure>(payload: &[u8]) -> E {
    match payload {
        [b'*', b'x', p, op, ..] => match aux_port(*p) {
            Err(e) => e,
            Ok(_) => E::bad_argument("*xp..", 3, Some(*op), "one of c, t, r, n, f (n and f alone)"),
        },
        _ => unknown(payload),
    }
}

/// The error for a payload that fits no row.
fn unknown<E: Failure>(payload: &[u8]) -> E {
    match payload.first() {
        Some(&first) => E::unknown(first, payload.len()),
        None => E::empty(),
    }
}

command_table! {
    /// One command payload: every row of Tables 4, 11 and 16 and the rev 1.9
    /// list (1.2).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    #[cfg_attr(feature = "defmt", derive(defmt::Format))]
    pub enum Command<'a> (payload = payload, writer = w) {
        // Rev 1.9 (1.2): first, because its names are prefixes that win over
        // the patterns below (`VP`/`VS` + six bytes is not `Vzzzfff`).
        /// Rev 1.9 commands with their raw argument bytes (1.2, protocol-notes E13).
        Extended(ext: Extended, args: &'a [u8]) => {
            mnemonic: ext.name(),
            answer: ext.answer(),
            motion: Motion::Other,
            mount: ext.mount(),
            parse: (Extended::split(payload).map(|(ext, args)| Self::Extended(ext, args))),
            encode: {
                w.put(ext.name().as_bytes())?;
                w.put(args)?;
            },
        }

        // Table 4: general device control.
        /// `#NN`: set device address/ID (Table 4).
        SetDeviceId(id: DeviceId) => {
            mnemonic: "#NN",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Identity,
            parse: {
                [b'#', ..] => {
                    let id = arg("#NN", payload, 1, "two hex digits 01..FE", hex_u8)?;
                    Self::SetDeviceId(ranged("#NN", 1, DeviceId::new(id))?)
                },
            },
            encode: {
                w.byte(b'#')?;
                w.hex(id.get().into(), 2)?;
            },
        }
        /// `AW`: awake status (Table 4; result Table 5).
        AwakeStatus => { wire: b"AW", answer: Answer::normal(Shape::AwakeStatus), motion: Motion::Other, mount: MountEffect::READS }
        /// `B?`: maximum data rate, `C0..CF` (Table 4).
        QueryMaxDataRate => { wire: b"B?", answer: Answer::normal(Shape::MaxDataRate), motion: Motion::Other, mount: MountEffect::READS }
        /// `C0..CF`: set communication data rate (Table 4; `C8..CF` reserved, protocol-notes E15).
        SetDataRate(rate: DataRate) => {
            mnemonic: "Cn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Identity,
            parse: {
                [b'C', d] if is_hex(*d) => match DataRate::from_code(hex_value(*d).unwrap_or(0)) {
                    Some(rate) => Self::SetDataRate(rate),
                    None => return Err(unknown(payload)),
                },
            },
            encode: {
                let code = rate.encodable_code().map_err(EncodeError::OutOfRange)?;
                w.byte(b'C')?;
                w.hex(code.into(), 1)?;
            },
        }
        /// `D?`: identification (Table 4; result Table 6).
        Identify => { wire: b"D?", answer: Answer::normal(Shape::Identity), motion: Motion::Other, mount: MountEffect::READS }
        /// `E?`: error codes (Table 4; result Table 6A).
        QueryErrors => { wire: b"E?", answer: Answer::normal(Shape::Errors), motion: Motion::Other, mount: MountEffect::READS }
        /// `I?`: status bits (Table 4; result Table 6B).
        QueryStatusBits => { wire: b"I?", answer: Answer::normal(Shape::StatusBits), motion: Motion::Other, mount: MountEffect::READS }
        /// `GRPnn` / `GRTnn`: set a rate gain (Table 4; value Table 7).
        SetRateGain(axis: Axis, gain: RateGain) => {
            mnemonic: axis.pick("GRPnn", "GRTnn"),
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Dynamics,
            parse: {
                [b'G', b'R', a, ..] if axis(*a).is_some() => {
                    let v = arg("GRPnn/GRTnn", payload, 3, "two hex digits", hex_u8)?;
                    Self::SetRateGain(axis(*a).unwrap_or(Axis::Pan), ranged("GRPnn/GRTnn", 3, RateGain::new(v))?)
                },
            },
            encode: {
                w.put(&[b'G', b'R', axis.letter()])?;
                w.hex(gain.get().into(), 2)?;
            },
        }
        /// `G?`: rate gains (Table 4; result Table 8).
        QueryRateGains => { wire: b"G?", answer: Answer::normal(Shape::RateGains), motion: Motion::Other, mount: MountEffect::READS }
        /// `IX`: initialisation (Table 4; result Table 9, which takes long).
        Initialize => {
            wire: b"IX",
            answer: Answer::Result(ResultTimeout::Long, Shape::Initialization),
            motion: Motion::Other,
            mount: MountEffect::Unbounded,
        }
        /// `L0..L3`: open relay (Table 4).
        OpenRelay(relay: Relay) => {
            mnemonic: "L0..L3",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'L', d @ b'0'..=b'3'] => Self::OpenRelay(ranged("L0..L3", 1, Relay::new(d - b'0'))?),
            },
            encode: {
                w.put(&[b'L', b'0' + relay.get()])?;
            },
        }
        /// `L8..LB`: close relay (Table 4).
        CloseRelay(relay: Relay) => {
            mnemonic: "L8..LB",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'L', d @ (b'8' | b'9' | b'A' | b'B' | b'a' | b'b')] => {
                    let bit = hex_value(*d).unwrap_or(8) - 8;
                    Self::CloseRelay(ranged("L8..LB", 1, Relay::new(bit))?)
                },
            },
            encode: {
                w.byte(b'L')?;
                w.hex(u32::from(relay.get()) + 8, 1)?;
            },
        }
        /// `LR`: relay status (Table 4; result Table 4A).
        QueryRelays => { wire: b"LR", answer: Answer::normal(Shape::Relays), motion: Motion::Other, mount: MountEffect::READS }
        /// `LC`: clear software limits (Table 4).
        ClearLimits => { wire: b"LC", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Dynamics }
        /// `LS` + 12 hex: set software limits (Table 4; values Table 10).
        SetLimits(limits: Limits) => {
            mnemonic: "LS",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Dynamics,
            parse: {
                [b'L', b'S', ..] => {
                    let (pan_ccw, pan_cw, tilt_ccw, tilt_cw) = arg("LS", payload, 2, "twelve hex digits", |i| {
                        (hex12, hex12, hex12, hex12).parse(i)
                    })?;
                    Self::SetLimits(Limits {
                        pan_ccw,
                        pan_cw,
                        tilt_ccw,
                        tilt_cw,
                    })
                },
            },
            encode: {
                w.put(b"LS")?;
                for v in [limits.pan_ccw, limits.pan_cw, limits.tilt_ccw, limits.tilt_cw] {
                    w.hex(v.get().into(), 3)?;
                }
            },
        }
        /// `L?`: software limits (Table 4; result Table 10).
        QueryLimits => { wire: b"L?", answer: Answer::normal(Shape::Limits), motion: Motion::Other, mount: MountEffect::READS }

        // Table 11: pan/tilt mount.
        /// `A?`: both accelerations (Table 11; result Table 13, protocol-notes E7).
        QueryAccelerations => { wire: b"A?", answer: Answer::normal(Shape::Accelerations), motion: Motion::Other, mount: MountEffect::Reads(Describes::Accelerations(None)) }
        /// `AP?` / `AT?`: one axis (Table 11, protocol-notes E7). Before `APnnnn`.
        QueryAcceleration(axis: Axis) => { axis_query: (b'A', "AP?", "AT?"), answer: Answer::normal(Shape::Acceleration), motion: Motion::Other, mount: MountEffect::Reads(Describes::Accelerations(Some(axis))) }
        /// `APnnnn` / `ATnnnn` (Table 11; value Table 12).
        SetAcceleration(axis: Axis, acceleration: Acceleration) => { axis_value: (b'A', "APnnnn", "ATnnnn"), answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Acceleration { axis, acceleration } }
        /// `HA`: halt, stores the position, motors off (Table 11).
        Halt => { wire: b"HA", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Halt }
        /// `HV`: verify home (Table 11; result Table 14).
        VerifyHome => { wire: b"HV", answer: Answer::normal(Shape::VerifyHome), motion: Motion::Other, mount: MountEffect::READS }
        /// `HO`: go home (0, 0) (Table 11).
        Home => { wire: b"HO", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::GoTo(Position::ZERO) }
        /// `HS`: stop, motors off (Table 11).
        MotorsStop => { wire: b"HS", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Halt }
        /// `P?`: current position (Table 11; result Table 15).
        QueryPosition => { wire: b"P?", answer: Answer::normal(Shape::Position), motion: Motion::Other, mount: MountEffect::Reads(Describes::Position) }
        /// `Paaaaeeee`: go to position (Table 11; values Table 15).
        GoTo(position: Position) => {
            mnemonic: "Paaaaeeee",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::GoTo(position),
            parse: {
                [b'P', _, _, _, _, _, _, _, _] => {
                    let (pan, tilt) = arg("Paaaaeeee", payload, 1, "eight hex digits", |i| {
                        (hex_u16, hex_u16).parse(i)
                    })?;
                    Self::GoTo(Position::new(Angle(pan as i16), Angle(tilt as i16)))
                },
            },
            encode: {
                w.byte(b'P')?;
                w.hex(u32::from(position.pan.0 as u16), 4)?;
                w.hex(u32::from(position.tilt.0 as u16), 4)?;
            },
        }
        /// `PL`: pan left (CW) until `PS` (Table 11).
        PanLeft => { wire: b"PL", answer: Answer::Ack, motion: Motion::Until(Command::PanStop), mount: MountEffect::slew(Axis::Pan, false) }
        /// `PR`: pan right (CCW) until `PS` (Table 11).
        PanRight => { wire: b"PR", answer: Answer::Ack, motion: Motion::Until(Command::PanStop), mount: MountEffect::slew(Axis::Pan, true) }
        /// `PS`: pan stop (Table 11).
        PanStop => { wire: b"PS", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Stop { pan: true, tilt: false } }
        /// `PT`: stop motion (Table 11).
        StopMotion => { wire: b"PT", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::STOP_BOTH }
        /// `Pnn`: go to preset (Table 11).
        GoToPreset(preset: u8) => {
            mnemonic: "Pnn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::RecallPreset(preset),
            parse: {
                [b'P', a, b] if is_hex(*a) && is_hex(*b) => {
                    Self::GoToPreset(arg("Pnn", payload, 1, "two hex digits", hex_u8)?)
                },
            },
            encode: {
                w.byte(b'P')?;
                w.hex(preset.into(), 2)?;
            },
        }
        /// `P?nn`: preset position (Table 11; result Table 15).
        QueryPreset(preset: u8) => {
            mnemonic: "P?nn",
            answer: Answer::normal(Shape::Position),
            motion: Motion::Other,
            mount: MountEffect::Reads(Describes::Preset(preset)),
            parse: {
                [b'P', b'?', _, _] => Self::QueryPreset(arg("P?nn", payload, 2, "two hex digits", hex_u8)?),
            },
            encode: {
                w.put(b"P?")?;
                w.hex(preset.into(), 2)?;
            },
        }
        /// `R?`: both rates (Table 11; result Table 13, protocol-notes E7).
        QueryRates => { wire: b"R?", answer: Answer::normal(Shape::Rates), motion: Motion::Other, mount: MountEffect::Reads(Describes::Rates(None)) }
        /// `RP?` / `RT?`: one axis (Table 11, protocol-notes E7). Before `RPnnnn`.
        QueryRate(axis: Axis) => { axis_query: (b'R', "RP?", "RT?"), answer: Answer::normal(Shape::Rate), motion: Motion::Other, mount: MountEffect::Reads(Describes::Rates(Some(axis))) }
        /// `RPnnnn` / `RTnnnn` (Table 11; value Table 12).
        SetRate(axis: Axis, rate: Rate) => { axis_value: (b'R', "RPnnnn", "RTnnnn"), answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Speed { axis, to: NewSpeed::Rate(rate) } }
        /// `SP0..SPF` / `ST0..STF`: proportional speed (Table 11). Before `Snn`.
        SetSpeed(axis: Axis, speed: Speed) => {
            mnemonic: axis.pick("SPn", "STn"),
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Speed { axis, to: NewSpeed::Step(speed) },
            parse: {
                [b'S', a, _] if axis(*a).is_some() => {
                    let v = arg("SPn/STn", payload, 2, "one hex digit", hex_n(1))?;
                    Self::SetSpeed(axis(*a).unwrap_or(Axis::Pan), ranged("SPn/STn", 2, Speed::new(v as u8))?)
                },
            },
            encode: {
                w.put(&[b'S', axis.letter()])?;
                w.hex(speed.get().into(), 1)?;
            },
        }
        /// `Snn`: store current position as preset (Table 11).
        StorePreset(preset: u8) => {
            mnemonic: "Snn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::StorePreset(preset),
            parse: {
                [b'S', _, _] => Self::StorePreset(arg("Snn", payload, 1, "two hex digits", hex_u8)?),
            },
            encode: {
                w.byte(b'S')?;
                w.hex(preset.into(), 2)?;
            },
        }
        /// `S?nn`: position stored at preset (Table 11; result Table 15).
        QueryStoredPreset(preset: u8) => {
            mnemonic: "S?nn",
            answer: Answer::normal(Shape::Position),
            motion: Motion::Other,
            mount: MountEffect::Reads(Describes::Preset(preset)),
            parse: {
                [b'S', b'?', _, _] => Self::QueryStoredPreset(arg("S?nn", payload, 2, "two hex digits", hex_u8)?),
            },
            encode: {
                w.put(b"S?")?;
                w.hex(preset.into(), 2)?;
            },
        }
        /// `TD`: tilt down (CW) until `TS` (Table 11).
        TiltDown => { wire: b"TD", answer: Answer::Ack, motion: Motion::Until(Command::TiltStop), mount: MountEffect::slew(Axis::Tilt, false) }
        /// `TS`: tilt stop (Table 11).
        TiltStop => { wire: b"TS", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Stop { pan: false, tilt: true } }
        /// `TU`: tilt up (CCW) until `TS` (Table 11).
        TiltUp => { wire: b"TU", answer: Answer::Ack, motion: Motion::Until(Command::TiltStop), mount: MountEffect::slew(Axis::Tilt, true) }
        /// `VMn`: vector motion on/off (Table 11).
        SetVectorMode(on: bool) => {
            mnemonic: "VMn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Dynamics,
            parse: {
                [b'V', b'M', d] => match d {
                    b'0' => Self::SetVectorMode(false),
                    b'1' => Self::SetVectorMode(true),
                    _ => {
                        return Err(E::bad_argument("VMn", 2, Some(*d), "'0' or '1'"));
                    }
                },
            },
            encode: {
                w.put(if on { b"VM1" } else { b"VM0" })?;
            },
        }

        // Table 16: camera.
        /// `CN`: camera and lens power on (Table 16).
        CameraOn => { wire: b"CN", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Setting }
        /// `CX`: camera and lens power off (Table 16).
        CameraOff => { wire: b"CX", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Setting }
        /// `F0..F9`: focus speed (Table 16).
        FocusSpeed(speed: LensSpeed) => {
            mnemonic: "Fn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'F', d] if d.is_ascii_digit() => Self::FocusSpeed(ranged("F0..F9", 1, LensSpeed::new(d - b'0'))?),
            },
            encode: {
                w.put(&[b'F', b'0' + speed.get()])?;
            },
        }
        /// `FA`: auto-focus on (Table 16; not implemented by the gimbal).
        AutoFocusOn => { wire: b"FA", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Setting }
        /// `FF`: focus far until `FS` (Table 16).
        FocusFar => { wire: b"FF", answer: Answer::Ack, motion: Motion::Until(Command::FocusStop), mount: MountEffect::Setting }
        /// `FN`: focus near until `FS` (Table 16).
        FocusNear => { wire: b"FN", answer: Answer::Ack, motion: Motion::Until(Command::FocusStop), mount: MountEffect::Setting }
        /// `FS`: focus stop (Table 16).
        FocusStop => { wire: b"FS", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Stop { pan: false, tilt: false } }
        /// `FX`: auto-focus off (Table 16; not implemented by the gimbal).
        AutoFocusOff => { wire: b"FX", answer: Answer::Ack, motion: Motion::Other, mount: MountEffect::Setting }
        /// `Vzzzfff`: lens go-to (Table 16; values Table 17).
        LensGoTo(lens: LensPosition) => {
            mnemonic: "Vzzzfff",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'V', _, _, _, _, _, _] => {
                    let (zoom, focus) = arg("Vzzzfff", payload, 1, "six hex digits", |i| (hex12, hex12).parse(i))?;
                    Self::LensGoTo(LensPosition { zoom, focus })
                },
            },
            encode: {
                w.byte(b'V')?;
                w.hex(lens.zoom.get().into(), 3)?;
                w.hex(lens.focus.get().into(), 3)?;
            },
        }
        /// `V?`: lens position (Table 16; result Table 17).
        QueryLens => { wire: b"V?", answer: Answer::normal(Shape::Lens), motion: Motion::Other, mount: MountEffect::READS }
        /// `Z0..Z9`: zoom speed (Table 16).
        ZoomSpeed(speed: LensSpeed) => {
            mnemonic: "Zn",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'Z', d] if d.is_ascii_digit() => Self::ZoomSpeed(ranged("Z0..Z9", 1, LensSpeed::new(d - b'0'))?),
            },
            encode: {
                w.put(&[b'Z', b'0' + speed.get()])?;
            },
        }
        /// `ZA..ZF`: digital zoom (Table 16; not implemented by the gimbal).
        DigitalZoom(zoom: DigitalZoom) => {
            mnemonic: "ZA..ZF",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'Z', d @ (b'A'..=b'F' | b'a'..=b'f')] => {
                    Self::DigitalZoom(ranged("ZA..ZF", 1, DigitalZoom::new(hex_value(*d).unwrap_or(10)))?)
                },
            },
            encode: {
                w.byte(b'Z')?;
                w.hex(zoom.get().into(), 1)?;
            },
        }
        /// `ZI`: zoom in until `ZS` (Table 16).
        ZoomIn => { wire: b"ZI", answer: Answer::Ack, motion: Motion::Until(Command::ZoomStop), mount: MountEffect::Setting }
        /// `ZO`: zoom out until `ZS` (Table 16).
        ZoomOut => { wire: b"ZO", answer: Answer::Ack, motion: Motion::Until(Command::ZoomStop), mount: MountEffect::Setting }
        /// `ZS`: zoom stop (Table 16).
        ZoomStop => { wire: b"ZS", answer: Answer::Ack, motion: Motion::Stop, mount: MountEffect::Stop { pan: false, tilt: false } }
        /// `*xpc,baud,data,stop,parity` (Table 16; fields Table 18).
        AuxConfigure(port: AuxPort, config: AuxConfig) => {
            mnemonic: "*xpc",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'*', b'x', p, b'c', ..] => {
                    let port = aux_port(*p)?;
                    Self::AuxConfigure(port, aux_config(payload)?)
                },
            },
            encode: {
                w.put(&[b'*', b'x', b'0' + port.get(), b'c', b','])?;
                w.decimal(config.baud(), 1)?;
                w.put(&[b',', b'0' + config.data_bits(), b',', b'0' + config.stop_bits(), b','])?;
                w.byte(match config.parity() {
                    Parity::None => b'0',
                    Parity::Odd => b'1',
                    Parity::Even => b'2',
                })?;
            },
        }
        /// `*xpt` + data (Table 16).
        AuxTransmit(port: AuxPort, data: AuxBytes<'a>) => {
            mnemonic: "*xpt",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'*', b'x', p, b't', data @ ..] => {
                    let port = aux_port(*p)?;
                    Self::AuxTransmit(port, ranged("*xpt", 4, AuxBytes::new(data))?)
                },
            },
            encode: {
                w.put(&[b'*', b'x', b'0' + port.get(), b't'])?;
                w.put(data.bytes())?;
            },
        }
        /// `*xprnnn`: receive up to nnn bytes (Table 16; decimal, protocol-notes E14).
        AuxReceive(port: AuxPort, len: AuxReadLen) => {
            mnemonic: "*xprnnn",
            answer: Answer::normal(Shape::AuxData),
            motion: Motion::Other,
            mount: MountEffect::READS,
            parse: {
                [b'*', b'x', p, b'r', ..] => {
                    let port = aux_port(*p)?;
                    let n = arg("*xprnnn", payload, 4, "decimal count 1..=256", |i| decimal(3).parse(i))?;
                    Self::AuxReceive(port, ranged("*xprnnn", 4, AuxReadLen::new(n as u16))?)
                },
            },
            encode: {
                w.put(&[b'*', b'x', b'0' + port.get(), b'r'])?;
                w.decimal(len.get().into(), 3)?;
            },
        }
        /// `*xpn`: characters waiting (Table 16; decimal, protocol-notes E14).
        AuxCount(port: AuxPort) => {
            mnemonic: "*xpn",
            answer: Answer::normal(Shape::AuxCount),
            motion: Motion::Other,
            mount: MountEffect::READS,
            parse: {
                [b'*', b'x', p, b'n'] => Self::AuxCount(aux_port(*p)?),
            },
            encode: {
                w.put(&[b'*', b'x', b'0' + port.get(), b'n'])?;
            },
        }
        /// `*xpf`: flush (Table 16).
        AuxFlush(port: AuxPort) => {
            mnemonic: "*xpf",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Setting,
            parse: {
                [b'*', b'x', p, b'f'] => Self::AuxFlush(aux_port(*p)?),
            },
            encode: {
                w.put(&[b'*', b'x', b'0' + port.get(), b'f'])?;
            },
        }

        /// A payload that fits no command: a device answers it with NIC.
        /// No row parses to it: [`Command::parse`] gives it for what no row takes.
        Unknown(bytes: &'a [u8]) => {
            mnemonic: "unknown",
            answer: Answer::Ack,
            motion: Motion::Other,
            mount: MountEffect::Unbounded,
            parse: (None::<Self>),
            encode: {
                w.put(bytes)?;
            },
        }
    }
}

/// Why a payload is not a well-formed command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// The payload has no byte.
    #[error("empty payload")]
    Empty,
    /// No row of the command table matches the first byte and the length.
    #[error("no command starts with byte 0x{first:02X} and has {len} bytes")]
    Unknown {
        /// The payload's first byte.
        first: u8,
        /// The payload's length.
        len: usize,
    },
    /// A command was recognised but an argument byte is not of its form.
    #[error("{command}: at offset {offset} expected {expected}, found {}", found_text(*.found))]
    BadArgument {
        /// The command's mnemonic form, e.g. `GRPnn/GRTnn`.
        command: &'static str,
        /// Offset of the offending byte in the payload.
        offset: usize,
        /// The byte found there, `None` at the end of the payload.
        found: Option<u8>,
        /// What the command expects there.
        expected: &'static str,
    },
    /// An argument is well formed but outside its range.
    #[error("{command}: argument at offset {offset}: {error}")]
    OutOfRange {
        /// The command's mnemonic form.
        command: &'static str,
        /// Offset of the argument in the payload.
        offset: usize,
        /// The range it breaks.
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

/// How a parse reports a payload that fits no row: [`CommandError`] says
/// why (`parse_strict`, the host side); [`NoRow`] says nothing, so that
/// [`Command::parse`] (a device answers NIC and needs no reason) builds no
/// error value it would throw away.
pub(crate) trait Failure: Sized {
    fn empty() -> Self;
    fn unknown(first: u8, len: usize) -> Self;
    fn bad_argument(command: &'static str, offset: usize, found: Option<u8>, expected: &'static str) -> Self;
    fn out_of_range(command: &'static str, offset: usize, error: RangeError) -> Self;
}

impl Failure for CommandError {
    fn empty() -> Self {
        CommandError::Empty
    }
    fn unknown(first: u8, len: usize) -> Self {
        CommandError::Unknown { first, len }
    }
    fn bad_argument(command: &'static str, offset: usize, found: Option<u8>, expected: &'static str) -> Self {
        CommandError::BadArgument {
            command,
            offset,
            found,
            expected,
        }
    }
    fn out_of_range(command: &'static str, offset: usize, error: RangeError) -> Self {
        CommandError::OutOfRange { command, offset, error }
    }
}

/// A payload fits no row; why is not asked.
pub(crate) struct NoRow;

impl Failure for NoRow {
    fn empty() -> Self {
        NoRow
    }
    fn unknown(_: u8, _: usize) -> Self {
        NoRow
    }
    fn bad_argument(_: &'static str, _: usize, _: Option<u8>, _: &'static str) -> Self {
        NoRow
    }
    fn out_of_range(_: &'static str, _: usize, _: RangeError) -> Self {
        NoRow
    }
}

/// Runs `parser` over `payload[skip..]`, which it must consume entirely.
fn arg<'a, T, E: Failure>(
    command: &'static str,
    payload: &'a [u8],
    skip: usize,
    expected: &'static str,
    mut parser: impl FnMut(&'a [u8]) -> Res<'a, T>,
) -> Result<T, E> {
    let input = payload.get(skip..).unwrap_or(&[]);
    let bad = |at: &'a [u8], expected| E::bad_argument(command, offset_in(payload, at), at.first().copied(), expected);
    match parser(input) {
        Ok(([], value)) => Ok(value),
        Ok((rest, _)) => Err(bad(rest, "end of payload")),
        Err(nom::Err::Error(e) | nom::Err::Failure(e)) => Err(bad(e.input, expected)),
        Err(nom::Err::Incomplete(_)) => Err(bad(&[], expected)),
    }
}

/// [`arg`] saying why (the reply parser's argument reader).
pub(crate) fn whole<'a, T>(
    command: &'static str,
    payload: &'a [u8],
    skip: usize,
    expected: &'static str,
    parser: impl FnMut(&'a [u8]) -> Res<'a, T>,
) -> Result<T, CommandError> {
    arg(command, payload, skip, expected, parser)
}

fn ranged<T, E: Failure>(command: &'static str, offset: usize, value: Result<T, RangeError>) -> Result<T, E> {
    value.map_err(|error| E::out_of_range(command, offset, error))
}

/// `,baud,dataBits,stopBits,parity` of `*xpc` (Table 18), from offset 4 of
/// `payload`; every error names the field and the offset where it went wrong.
fn aux_config<E: Failure>(payload: &[u8]) -> Result<AuxConfig, E> {
    const COMMAND: &str = "*xpc";
    let mut at = 4;
    let mut field = |max: usize, expected: &'static str| -> Result<(usize, u32), E> {
        let bad = |offset: usize, expected| E::bad_argument(COMMAND, offset, payload.get(offset).copied(), expected);
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
        return Err(E::bad_argument(COMMAND, at, payload.get(at).copied(), "end of command"));
    }
    let range = |offset, error| E::out_of_range(COMMAND, offset, error);
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
        Self::parse_implemented(payload, |_| true)
    }

    /// [`Command::parse`] for a device that implements only the rows
    /// `implemented` takes: any other command is [`Command::Unknown`]
    /// without its arguments being read, as a device answers both with NIC.
    pub fn parse_implemented(payload: &'a [u8], implemented: impl Fn(Row) -> bool) -> Self {
        Self::parse_rows::<NoRow>(payload, implemented).unwrap_or(Command::Unknown(payload))
    }

    /// Parses a payload, saying what is wrong with one that fits no command.
    pub fn parse_strict(payload: &'a [u8]) -> Result<Self, CommandError> {
        Self::parse_rows::<CommandError>(payload, |_| true)
    }

    /// Writes the payload into `buf`; returns the written prefix.
    pub fn encode<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EncodeError> {
        let mut w = Writer::new(buf);
        self.encode_row(&mut w)?;
        if w.len() == 0 {
            return Err(EncodeError::PayloadLength { len: 0 });
        }
        Ok(w.finish())
    }

    /// What follows the ACK (Tables 4, 11, 16 "RESPONSE" column).
    pub fn result_kind(&self) -> ResultKind {
        self.answer().kind()
    }

    /// Stop and halt commands, which overtake queued work (ARCHITECTURE "Routing semantics").
    pub fn is_stop(&self) -> bool {
        self.motion() == Motion::Stop
    }

    /// For a command that starts continuous motion (`PL`, `PR`, `TU`, `TD`,
    /// `FF`, `FN`, `ZI`, `ZO`), the command that stops it (Tables 11, 16).
    pub fn stopped_by(&self) -> Option<Command<'static>> {
        match self.motion() {
            Motion::Until(stop) => Some(stop),
            Motion::Other | Motion::Stop => None,
        }
    }

    /// The line rate a `C0..CF` command switches to (reserved codes included).
    pub fn data_rate_change(&self) -> Option<DataRate> {
        if let Command::SetDataRate(rate) = self {
            Some(*rate)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests;
