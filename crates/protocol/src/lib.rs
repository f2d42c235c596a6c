#![doc = include_str!("../README.md")]
#![no_std]
#![forbid(unsafe_code)]

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
mod hex;
pub mod link;
pub mod reply;
pub mod report;
pub mod units;

pub use address::{Address, AddressParseError, CONTROL_UNIT, LINK_PORT, MCU_GROUP, WILDCARD};
pub use command::{AuxBytes, Command, CommandError, Extended, ResultKind, ResultTimeout, Row};
pub use device::{DeviceEndpoint, DeviceHandler, EndpointConfig, EndpointStats, RESULT_RESENDS, ReplyTo, Response};
pub use frame::{ACK, Frame, FrameBuf, FrameError, MAX_FRAME_LEN, MAX_PAYLOAD, NAK, NIC, START, checksum};
pub use framer::{BadChecksum, Event, Framer, FramerStats, OwnedEvent};
pub use link::{Outcome, RetryPolicy, Transaction, TransactionPolicy, TransactionStep, Transmitter, TxFailure, TxStep};
pub use reply::{
    AwakeStatus, ErrorCodes, ExpectedReply, HomeStatus, Identity, InitResults, RateGains, Reply, ReplyError, StatusBits,
};
pub use report::{DeliveryReport, NotAReport, REPORT_LEN, REPORT_MARK, Undelivered};
pub use units::{
    Acceleration, Angle, AuxConfig, AuxPort, AuxReadLen, Axis, DataRate, DeviceId, DigitalZoom, LensPosition,
    LensSpeed, Limits, NotAProtocolRate, Parity, Position, RangeError, Rate, RateGain, Relay, Speed, U12,
};

/// Why an encoder could not write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    #[error("buffer of {capacity} bytes too small: {needed} needed")]
    BufferTooSmall { needed: usize, capacity: usize },
    #[error("payload of {len} bytes: a frame carries 1..=256")]
    PayloadLength { len: usize },
    #[error("cannot encode: {0}")]
    OutOfRange(RangeError),
}
