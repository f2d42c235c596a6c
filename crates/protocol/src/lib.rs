#![doc = include_str!("../README.md")]
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod code_table;
#[doc(hidden)]
pub use code_table::{snake_case_bytes, snake_case_len};

pub mod address;
mod answer;
pub mod capture_record;
pub mod command;
pub mod device;
pub mod dissector;
pub mod frame;
pub mod framer;
pub mod gcu;
mod hex;
#[cfg(any(feature = "embedded-io", feature = "embedded-io-async"))]
pub mod io;
pub mod link;
pub mod mount;
pub mod reply;
pub mod report;
pub mod units;
pub mod words;

pub use address::{Address, AddressParseError, CONTROL_UNIT, LINK_PORT, MCU_GROUP, WILDCARD};
pub use command::{AuxBytes, Command, CommandError, Extended, ResultKind, ResultTimeout, Row};
pub use device::{DeviceEndpoint, DeviceHandler, EndpointConfig, EndpointStats, RESULT_RESENDS, ReplyTo, Response};
pub use frame::{ACK, Frame, FrameBuf, FrameError, MAX_FRAME_LEN, MAX_PAYLOAD, NAK, NIC, START, checksum};
pub use framer::{BadChecksum, Event, Framer, FramerStats, OwnedEvent};
pub use gcu::{ControllerReply, GcuCommand, RuleItem, TourState};
pub use link::{Outcome, RetryPolicy, Transaction, TransactionPolicy, TransactionStep, Transmitter, TxFailure, TxStep};
pub use mount::{Describes, MountEffect, NewSpeed};
pub use reply::{
    AwakeStatus, ErrorCodes, ExpectedReply, HomeStatus, Identity, InitResults, RateGains, Reply, ReplyError, StatusBits,
};
pub use report::{DeliveryReport, NotAReport, REPORT_LEN, REPORT_MARK, Undelivered};
pub use units::{
    Acceleration, Angle, AuxConfig, AuxPort, AuxReadLen, Axis, DataRate, DeviceId, DigitalZoom, LensPosition,
    LensSpeed, Limits, NotAProtocolRate, Parity, Position, RangeError, Rate, RateGain, Relay, Speed, U12,
};
pub use words::InWords;

/// Why an encoder could not write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The caller's buffer cannot hold the encoding.
    #[error("buffer of {capacity} bytes too small: {needed} needed")]
    BufferTooSmall {
        /// Bytes the encoding needs.
        needed: usize,
        /// Bytes the buffer has.
        capacity: usize,
    },
    /// The payload is empty or longer than [`MAX_PAYLOAD`].
    #[error("payload of {len} bytes: a frame carries 1..=256")]
    PayloadLength {
        /// The payload's length.
        len: usize,
    },
    /// A value does not fit its field on the wire.
    #[error("cannot encode: {0}")]
    OutOfRange(RangeError),
}
