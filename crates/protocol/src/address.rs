//! Frame addresses: Table 2 (specific group, port and device addresses).

use core::fmt;
use core::str::FromStr;

/// Address byte 255 at any level: every GCU, every port, every device (Table 2).
pub const WILDCARD: u8 = 255;
/// Group address of the MCU (Table 2, GCU ID byte 0).
pub const MCU_GROUP: u8 = 0;
/// Port address of the GCU-to-GCU/MCU link, i.e. the GCU itself (Table 2, port 0).
pub const LINK_PORT: u8 = 0;
/// Device address naming the control unit itself as destination (Table 2, device 0).
pub const CONTROL_UNIT: u8 = 0;

/// Destination of a frame: header bytes 2-4 of Table 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Address {
    /// GCU address: 0 = MCU, 1..=254 = GCU, 255 = every GCU.
    pub group: u8,
    /// Port within the GCU: 0 = the GCU/MCU link, 1..=254 = a port, 255 = every port.
    pub port: u8,
    /// Device on the port: 0 = the control unit, 1..=254 = a device, 255 = every device.
    pub device: u8,
}

impl Address {
    /// The address `group.port.device`.
    pub const fn new(group: u8, port: u8, device: u8) -> Self {
        Self { group, port, device }
    }

    /// True when any of the three bytes is the wildcard 255.
    pub const fn has_wildcard(&self) -> bool {
        self.group == WILDCARD || self.port == WILDCARD || self.device == WILDCARD
    }
}

impl fmt::Display for Address {
    /// `group.port.device`, as the CLI takes it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.group, self.port, self.device)
    }
}

/// Why a `G.P.D` address text was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AddressParseError {
    /// The text does not have exactly three dot-separated parts.
    #[error("address must be three numbers GROUP.PORT.DEVICE, each 0..=255 (found {found} parts)")]
    Parts {
        /// How many parts the text has.
        found: usize,
    },
    /// A part is not a decimal number 0..=255.
    #[error("address part {index} is not a number 0..=255")]
    Number {
        /// Which part (0 = group, 1 = port, 2 = device).
        index: usize,
    },
}

impl FromStr for Address {
    type Err = AddressParseError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut parts = [0u8; 3];
        let mut count = 0;
        for (index, part) in text.split('.').enumerate() {
            if index >= 3 {
                return Err(AddressParseError::Parts {
                    found: text.split('.').count(),
                });
            }
            parts[index] = part.trim().parse().map_err(|_| AddressParseError::Number { index })?;
            count += 1;
        }
        if count != 3 {
            return Err(AddressParseError::Parts { found: count });
        }
        Ok(Self::new(parts[0], parts[1], parts[2]))
    }
}
