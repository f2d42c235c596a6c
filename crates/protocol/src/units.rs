//! Physical quantities at the API, with constructors that reject values the
//! wire format cannot carry.

/// A value outside the range its field allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[error("{what} {value} is out of range {min}..={max}")]
pub struct RangeError {
    /// What the value is, e.g. `"relay"`.
    pub what: &'static str,
    /// The value refused.
    pub value: i64,
    /// Smallest value allowed.
    pub min: i64,
    /// Largest value allowed.
    pub max: i64,
}

fn check(what: &'static str, value: i64, min: i64, max: i64) -> Result<(), RangeError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(RangeError { what, value, min, max })
    }
}

/// Pan (azimuth) or tilt (elevation): the `P`/`T` letter of Tables 7, 11, 12.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Axis {
    /// Pan (azimuth), letter `P`.
    Pan,
    /// Tilt (elevation), letter `T`.
    Tilt,
}

impl Axis {
    /// `pan` or `tilt`, for this axis (a per-axis row's mnemonic).
    pub(crate) const fn pick(self, pan: &'static str, tilt: &'static str) -> &'static str {
        match self {
            Axis::Pan => pan,
            Axis::Tilt => tilt,
        }
    }

    pub(crate) const fn letter(self) -> u8 {
        match self {
            Axis::Pan => b'P',
            Axis::Tilt => b'T',
        }
    }

    pub(crate) const fn from_letter(letter: u8) -> Option<Self> {
        match letter {
            b'P' => Some(Axis::Pan),
            b'T' => Some(Axis::Tilt),
            _ => None,
        }
    }
}

/// An angle in hundredths of a degree, signed 16-bit two's complement,
/// positive = counter-clockwise (Table 15, protocol-notes E8, E12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Angle(pub i16);

impl Angle {
    /// From hundredths of a degree, as on the wire.
    pub const fn from_centidegrees(centi: i16) -> Self {
        Angle(centi)
    }
    /// In hundredths of a degree.
    pub const fn centidegrees(self) -> i16 {
        self.0
    }
    /// From whole and fractional degrees; refuses what 16 bits cannot carry.
    pub fn from_degrees(degrees: f32) -> Result<Self, RangeError> {
        let centi = degrees * 100.0;
        if !(-32768.0..=32767.0).contains(&centi) {
            let value = if centi.is_nan() { 0 } else { centi as i64 };
            return Err(RangeError {
                what: "angle (hundredths of a degree)",
                value,
                min: -32768,
                max: 32767,
            });
        }
        // Round half away from zero without libm.
        let rounded = if centi >= 0.0 { centi + 0.5 } else { centi - 0.5 };
        Ok(Angle(rounded as i16))
    }
    /// In degrees.
    pub fn degrees(self) -> f32 {
        f32::from(self.0) / 100.0
    }
}

/// A pan/tilt position (Table 15).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Position {
    /// Pan (azimuth) angle.
    pub pan: Angle,
    /// Tilt (elevation) angle.
    pub tilt: Angle,
}

impl Position {
    /// Home: azimuth and elevation 0 (Table 11, `HO`).
    pub const ZERO: Position = Position::new(Angle(0), Angle(0));

    /// The position `(pan, tilt)`.
    pub const fn new(pan: Angle, tilt: Angle) -> Self {
        Self { pan, tilt }
    }
}

/// A discrete rate in hundredths of a degree per second (Tables 12, 13).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rate(pub u16);

/// An acceleration in hundredths of a degree per second squared (Tables 12, 13).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Acceleration(pub u16);

/// The Table 12 quantities in hundredths of their unit: one conversion each
/// way, rounding to the nearest hundredth and refusing what four hex digits
/// cannot carry.
macro_rules! hundredths {
    ($($name:ident: $from:ident, $to:ident, $what:literal;)+) => {$(
        impl $name {
            #[doc = concat!("From ", $what, ", rounded to the nearest hundredth; refuses values outside 0..=655.35.")]
            pub fn $from(value: f64) -> Result<Self, RangeError> {
                let hundredths = value * 100.0;
                if !(-0.5..65535.5).contains(&hundredths) {
                    return Err(RangeError {
                        what: concat!($what, " (hundredths)"),
                        value: if hundredths.is_nan() { 0 } else { hundredths as i64 },
                        min: 0,
                        max: 65535,
                    });
                }
                // Round half up without libm; the range check keeps it in u16.
                Ok(Self((hundredths + 0.5) as u16))
            }

            #[doc = concat!("In ", $what, ".")]
            pub fn $to(self) -> f64 {
                f64::from(self.0) / 100.0
            }
        }
    )+};
}

hundredths! {
    Rate: from_degrees_per_second, degrees_per_second, "degrees per second";
    Acceleration: from_degrees_per_second_squared, degrees_per_second_squared, "degrees per second squared";
}

/// The table of bounded wire values: one row `Name: repr, "what", min..=max;`
/// per type, each a newtype whose constructor refuses what the wire format
/// does not allow.
macro_rules! bounded {
    ($( $(#[$doc:meta])* $name:ident: $repr:ty, $what:literal, $min:literal..=$max:literal; )+) => {
        $( bounded!(@one $(#[$doc])* $name, $repr, $what, $min, $max); )+
    };
    (@one $(#[$doc:meta])* $name:ident, $repr:ty, $what:literal, $min:expr, $max:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub struct $name($repr);

        impl $name {
            /// Smallest value the wire format allows.
            pub const MIN: $repr = $min;
            /// Largest value the wire format allows.
            pub const MAX: $repr = $max;
            /// Refuses values outside the range the wire format allows.
            pub fn new(value: $repr) -> Result<Self, RangeError> {
                check($what, value as i64, $min as i64, $max as i64).map(|()| Self(value))
            }
            /// The value.
            pub const fn get(self) -> $repr {
                self.0
            }
        }

        impl TryFrom<$repr> for $name {
            type Error = RangeError;
            fn try_from(value: $repr) -> Result<Self, RangeError> {
                Self::new(value)
            }
        }
    };
}

bounded! {
    /// Proportional pan/tilt speed `SP0..SPF`, `ST0..STF`: 0 slowest, 15 fastest (Table 11).
    Speed: u8, "proportional speed", 0..=15;
    /// Focus or zoom speed `F0..F9`, `Z0..Z9`: 0 slowest, 9 fastest (Table 16).
    LensSpeed: u8, "lens speed", 0..=9;
    /// Rate gain times ten, 0.3..=3.0 -> 3..=30 (Table 7, protocol-notes E1).
    RateGain: u8, "rate gain (x10)", 3..=30;
    /// A 12-bit value: lens zoom/focus position (Table 17) or a raw software
    /// limit (Table 10, protocol-notes E9: no unit is invented).
    U12: u16, "12-bit value", 0..=4095;
    /// A device ID settable with `#NN`: 01..=FE (Table 4).
    DeviceId: u8, "device ID", 1..=254;
    /// An auxiliary relay 0..=3 (Table 4 `L0..L3`, `L8..LB`).
    Relay: u8, "relay", 0..=3;
    /// An auxiliary serial port, 0 or 1 (Table 16 `*xp..`).
    AuxPort: u8, "auxiliary port", 0..=1;
    /// Digital zoom step `ZA..ZF` (Table 16, not implemented by the gimbal).
    DigitalZoom: u8, "digital zoom", 10..=15;
    /// Most bytes `*xprnnn` may ask for: a result payload holds at most 256.
    AuxReadLen: u16, "auxiliary read length", 1..=256;
}

/// Communication data rate `C0..CF` (Table 4, protocol-notes E15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DataRate {
    /// `C0`: 1200 bit/s.
    Bps1200,
    /// `C1`: 2400 bit/s.
    Bps2400,
    /// `C2`: 4800 bit/s.
    Bps4800,
    /// `C3`: 9600 bit/s.
    Bps9600,
    /// `C4`: 19200 bit/s.
    Bps19200,
    /// `C5`: 38400 bit/s.
    Bps38400,
    /// `C6`: 57600 bit/s.
    Bps57600,
    /// `C7`: 115200 bit/s.
    Bps115200,
    /// `C8..CF`, reserved for future rates: never switched to.
    Reserved(u8),
}

impl DataRate {
    /// The rate for code digit `0..=15`.
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => DataRate::Bps1200,
            1 => DataRate::Bps2400,
            2 => DataRate::Bps4800,
            3 => DataRate::Bps9600,
            4 => DataRate::Bps19200,
            5 => DataRate::Bps38400,
            6 => DataRate::Bps57600,
            7 => DataRate::Bps115200,
            8..=15 => DataRate::Reserved(code),
            _ => return None,
        })
    }

    /// The code digit `0..=15`.
    pub const fn code(self) -> u8 {
        match self {
            DataRate::Bps1200 => 0,
            DataRate::Bps2400 => 1,
            DataRate::Bps4800 => 2,
            DataRate::Bps9600 => 3,
            DataRate::Bps19200 => 4,
            DataRate::Bps38400 => 5,
            DataRate::Bps57600 => 6,
            DataRate::Bps115200 => 7,
            DataRate::Reserved(code) => code,
        }
    }

    /// The code digit for encoding. `Reserved` is a public variant that can
    /// hold any byte, but only `8..=15` are reserved codes: `Reserved(3)`
    /// would go out as `C3` and come back as 9600 bps, `Reserved(200)` would
    /// not fit one digit. Both are refused instead of silently re-coded.
    pub(crate) fn encodable_code(self) -> Result<u8, RangeError> {
        match self {
            DataRate::Reserved(code) => check("reserved data rate code", code.into(), 8, 15).map(|()| code),
            rate => Ok(rate.code()),
        }
    }

    /// Bits per second, `None` for a reserved code.
    pub const fn bits_per_second(self) -> Option<u32> {
        Some(match self {
            DataRate::Bps1200 => 1200,
            DataRate::Bps2400 => 2400,
            DataRate::Bps4800 => 4800,
            DataRate::Bps9600 => 9600,
            DataRate::Bps19200 => 19200,
            DataRate::Bps38400 => 38400,
            DataRate::Bps57600 => 57600,
            DataRate::Bps115200 => 115200,
            DataRate::Reserved(_) => return None,
        })
    }

    /// The rate for a bits-per-second figure, if the protocol has one.
    pub const fn from_bits_per_second(bps: u32) -> Option<Self> {
        Some(match bps {
            1200 => DataRate::Bps1200,
            2400 => DataRate::Bps2400,
            4800 => DataRate::Bps4800,
            9600 => DataRate::Bps9600,
            19200 => DataRate::Bps19200,
            38400 => DataRate::Bps38400,
            57600 => DataRate::Bps57600,
            115200 => DataRate::Bps115200,
            _ => return None,
        })
    }
}

/// A line rate in bit/s as text: one of the protocol's rates.
impl core::str::FromStr for DataRate {
    type Err = NotAProtocolRate;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        text.parse()
            .ok()
            .and_then(DataRate::from_bits_per_second)
            .ok_or(NotAProtocolRate)
    }
}

/// A text that is not one of the protocol's rates; it says which they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NotAProtocolRate;

impl core::fmt::Display for NotAProtocolRate {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("expected one of the protocol's rates in bit/s (Table 4):")?;
        let rates = (0..=15).filter_map(|code| DataRate::from_code(code).and_then(DataRate::bits_per_second));
        for (i, bps) in rates.enumerate() {
            write!(f, "{} {bps}", if i == 0 { "" } else { "," })?;
        }
        Ok(())
    }
}

/// Lens zoom and focus positions, 12 bits each (Table 17).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LensPosition {
    /// Zoom position.
    pub zoom: U12,
    /// Focus position.
    pub focus: U12,
}

/// Software limits, raw 12-bit values (Table 10, protocol-notes E9).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    /// Pan counter-clockwise (+) limit.
    pub pan_ccw: U12,
    /// Pan clockwise (-) limit.
    pub pan_cw: U12,
    /// Tilt counter-clockwise (+, up) limit.
    pub tilt_ccw: U12,
    /// Tilt clockwise (-, down) limit.
    pub tilt_cw: U12,
}

/// Parity of an auxiliary serial port (Table 18).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Parity {
    /// No parity bit.
    None,
    /// Odd parity.
    Odd,
    /// Even parity.
    Even,
}

/// Auxiliary serial port settings `*xpc,baud,dataBits,stopBits,parity` (Table 18).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AuxConfig {
    baud: u32,
    data_bits: u8,
    stop_bits: u8,
    parity: Parity,
}

impl AuxConfig {
    /// Checks baud 1..=999999 (decimal on the wire), data bits 5..=8, stop bits 1..=2.
    pub fn new(baud: u32, data_bits: u8, stop_bits: u8, parity: Parity) -> Result<Self, RangeError> {
        check("baud", i64::from(baud), 1, 999_999)?;
        check("data bits", i64::from(data_bits), 5, 8)?;
        check("stop bits", i64::from(stop_bits), 1, 2)?;
        Ok(Self {
            baud,
            data_bits,
            stop_bits,
            parity,
        })
    }
    /// Line rate in bit/s.
    pub const fn baud(&self) -> u32 {
        self.baud
    }
    /// Data bits per character, 5..=8.
    pub const fn data_bits(&self) -> u8 {
        self.data_bits
    }
    /// Stop bits, 1 or 2.
    pub const fn stop_bits(&self) -> u8 {
        self.stop_bits
    }
    /// Parity.
    pub const fn parity(&self) -> Parity {
        self.parity
    }
}
