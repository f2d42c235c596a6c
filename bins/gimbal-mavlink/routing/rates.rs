//! The intervals of a gimbal's two status streams, as
//! MAV_CMD_SET_MESSAGE_INTERVAL sets them (module `status` sends them).

use std::time::Duration;

/// The message ids whose interval MAV_CMD_SET_MESSAGE_INTERVAL may set.
pub const MANAGER_STATUS_ID: u32 = 281;
pub const ATTITUDE_STATUS_ID: u32 = 285;
/// The shortest and longest interval a stream may be set to: every status
/// goes to every peer, so no asker makes this door send more than 50 a
/// second per stream.
pub const FASTEST: Duration = Duration::from_millis(20);
pub const SLOWEST: Duration = Duration::from_secs(10);
/// A status stream's rate, as MAV_CMD_SET_MESSAGE_INTERVAL sets it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Rate {
    /// Param 2 = 0: the configured default.
    #[default]
    Default,
    /// Param 2 = -1: not sent.
    Off,
    /// An interval within [`FASTEST`]..=[`SLOWEST`].
    Every(Duration),
}

impl Rate {
    /// The rate of MAV_CMD_SET_MESSAGE_INTERVAL's param 2 (microseconds),
    /// or None when it is none this door keeps.
    pub fn from_interval_us(us: f32) -> Option<Self> {
        if us == -1.0 {
            Some(Self::Off)
        } else if us == 0.0 {
            Some(Self::Default)
        } else if us.fract() == 0.0 && (FASTEST.as_micros() as f32..=SLOWEST.as_micros() as f32).contains(&us) {
            Some(Self::Every(Duration::from_micros(us as u64)))
        } else {
            None
        }
    }

    /// The interval in force, with `default` the configured one; None: off.
    pub fn interval(self, default: Duration) -> Option<Duration> {
        match self {
            Self::Default => Some(default),
            Self::Off => None,
            Self::Every(d) => Some(d),
        }
    }
}

/// The rates of a gimbal's two status streams.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rates {
    pub manager: Rate,
    pub attitude: Rate,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_intervals_are_read_as_common_xml_defines_them() {
        assert_eq!(Rate::from_interval_us(-1.0), Some(Rate::Off));
        assert_eq!(Rate::from_interval_us(0.0), Some(Rate::Default));
        assert_eq!(
            Rate::from_interval_us(100_000.0),
            Some(Rate::Every(Duration::from_millis(100)))
        );
        for bad in [1.0, 19_999.0, 10_000_001.0, 1.5e4, f32::NAN, -2.0, 100_000.5] {
            assert_eq!(Rate::from_interval_us(bad), None, "{bad}");
        }
    }
}
