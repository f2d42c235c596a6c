//! Adapters that run the sans-IO core over the `embedded-io` traits that
//! HALs and embassy implement: a device endpoint ([`DeviceEndpoint`]) and a
//! master exchange ([`Transaction`]) over any `Read + Write`.
//!
//! - [`blocking`] (feature `embedded-io`): `embedded_io::{Read, Write}`.
//! - [`asynch`] (feature `embedded-io-async`): `embedded_io_async::{Read, Write}`.
//!
//! # Give them a buffered reader
//!
//! Received bytes go straight from `read` into the framer's free space
//! (`spare_capacity_mut` + `commit`: no intermediate copy), and the framer
//! keeps partial frames across reads. Between two reads, though, the adapter
//! handles what it got and writes the answers (an ACK, a result frame): bytes
//! that arrive meanwhile must wait in the driver. Give the adapters a
//! *buffered* reader, one that an interrupt or DMA fills into a ring buffer
//! (embassy's `BufferedUart`, a HAL's interrupt-driven serial), never a UART
//! that only receives while a `read` is pending: that one loses bytes.
//!
//! Each event's answer (at most an ACK and a 263-byte frame) is collected in
//! a buffer of [`ANSWER_CAPACITY`] bytes and written with one `write_all`
//! before the next event is handled, so writes never interleave and no
//! answer is held back by later input. Time is the caller's: the adapters
//! take a clock, `FnMut() -> u64`, in the ticks of the policies.
//!
//! [`DeviceEndpoint`]: crate::DeviceEndpoint
//! [`Transaction`]: crate::Transaction

/// What [`blocking`] and [`asynch`] share of their `Device` and `Master`:
/// the structs (documented by each module), construction and the parts,
/// which do not depend on how I/O waits (each module adds its own `poll`
/// and `transact`).
#[cfg(any(feature = "embedded-io", feature = "embedded-io-async"))]
macro_rules! adapter_parts {
    ($(#[$device:meta])* Device; $(#[$master:meta])* Master;) => {
        $(#[$device])*
        #[derive(Debug)]
        pub struct Device<T, const N: usize = DEFAULT_CAPACITY> {
            io: T,
            endpoint: DeviceEndpoint<N>,
        }

        $(#[$master])*
        #[derive(Debug)]
        pub struct Master<T, const N: usize = DEFAULT_CAPACITY> {
            io: T,
            framer: Framer<N>,
        }

        impl<T, const N: usize> Device<T, N> {
            /// An endpoint with `config` on `io`.
            pub const fn new(io: T, config: EndpointConfig) -> Self {
                Self {
                    io,
                    endpoint: DeviceEndpoint::new(config),
                }
            }

            /// The endpoint (configuration, counters).
            pub fn endpoint(&self) -> &DeviceEndpoint<N> {
                &self.endpoint
            }

            /// The reader/writer.
            pub fn io(&mut self) -> &mut T {
                &mut self.io
            }

            /// Gives the reader/writer back.
            pub fn into_inner(self) -> T {
                self.io
            }
        }

        impl<T, const N: usize> Master<T, N> {
            /// A master on `io`.
            pub const fn new(io: T) -> Self {
                Self {
                    io,
                    framer: Framer::new(),
                }
            }

            /// The framer (counters).
            pub fn framer(&self) -> &Framer<N> {
                &self.framer
            }

            /// The reader/writer.
            pub fn io(&mut self) -> &mut T {
                &mut self.io
            }

            /// Gives the reader/writer back.
            pub fn into_inner(self) -> T {
                self.io
            }
        }
    };
}

#[cfg(feature = "embedded-io-async")]
pub mod asynch;
#[cfg(feature = "embedded-io")]
pub mod blocking;

use crate::EncodeError;
use crate::frame::{ACK, FrameBuf, MAX_FRAME_LEN, NAK};
use crate::framer::{Event, Framer};
use crate::link::{Outcome, Transaction, TransactionStep};

/// Most bytes one event makes an adapter send: an ACK and a result frame.
pub const ANSWER_CAPACITY: usize = MAX_FRAME_LEN + 1;

/// Why an adapter stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The reader or writer failed.
    #[error("I/O error: {0:?}")]
    Io(E),
    /// `read` returned 0 bytes: the stream has ended.
    #[error("end of stream")]
    EndOfStream,
    /// A frame could not be built (a deferred result that does not encode).
    #[error("{0}")]
    Encode(EncodeError),
}

/// The bytes one event sends, written at once after the event.
pub(crate) struct Answer {
    bytes: [u8; ANSWER_CAPACITY],
    len: usize,
}

impl Answer {
    pub(crate) const fn new() -> Self {
        Self {
            bytes: [0; ANSWER_CAPACITY],
            len: 0,
        }
    }

    /// Appends `bytes`; one event never sends more than fits (an ACK and
    /// one frame), so nothing is cut.
    pub(crate) fn push(&mut self, bytes: &[u8]) {
        let free = self.bytes.get_mut(self.len..).unwrap_or_default();
        let n = bytes.len().min(free.len());
        free[..n].copy_from_slice(&bytes[..n]);
        self.len += n;
    }

    fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The bytes collected since the last [`Answer::take`], and empties it.
    pub(crate) fn take(&mut self) -> &[u8] {
        let len = core::mem::replace(&mut self.len, 0);
        self.bytes.get(..len).unwrap_or_default()
    }
}

/// How a master exchange ended, with its result frame when there is one.
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Exchange {
    /// How it ended.
    pub outcome: Outcome,
    /// The result frame (ACKed to the device) when `outcome` is
    /// [`Outcome::Result`]: parse its payload with `Reply::parse`.
    pub result: Option<FrameBuf>,
    /// Transmissions of the command frame (1 without retransmission).
    pub transmissions: u8,
}

/// What a master adapter does next in an exchange: the one loop the
/// blocking and the async `Master` run, I/O left to them.
pub(crate) enum MasterIo<'a> {
    /// Write these bytes (the command frame, or a hop-by-hop ACK or NAK)
    /// and flush them.
    Write(&'a [u8]),
    /// Read into the framer, until this tick of the clock when there is one
    /// (the async adapter sleeps until it; the blocking one polls instead).
    Read(#[cfg_attr(not(feature = "embedded-io-async"), allow(dead_code))] Option<u64>),
    /// The exchange is over: [`MasterRun::exchange`] tells how.
    Done(Outcome),
}

/// One master exchange between the framer and the line (Figure 6): the
/// frame when the exchange says so, each framer event handled and its
/// answer owed, the exchange's deadline kept.
pub(crate) struct MasterRun {
    step: TransactionStep,
    answer: Answer,
    result: Option<FrameBuf>,
}

impl MasterRun {
    /// Starts `transaction` at `now`.
    pub(crate) fn start(transaction: &mut Transaction, now: u64) -> Self {
        Self {
            step: transaction.start(now),
            answer: Answer::new(),
            result: None,
        }
    }

    /// How the exchange ended with `outcome`, with its result frame.
    pub(crate) fn exchange(&mut self, outcome: Outcome, transaction: &Transaction) -> Exchange {
        Exchange {
            outcome,
            result: self.result.take(),
            transmissions: transaction.transmissions(),
        }
    }

    /// The next thing to do: an answer owed first, then the exchange's end,
    /// the frame, the events already buffered (one at a time), the deadline.
    pub(crate) fn next<'a, const N: usize>(
        &'a mut self,
        frame: &'a FrameBuf,
        transaction: &mut Transaction,
        framer: &mut Framer<N>,
        clock: &mut impl FnMut() -> u64,
    ) -> MasterIo<'a> {
        loop {
            if !self.answer.is_empty() {
                return MasterIo::Write(self.answer.take());
            }
            if let TransactionStep::Done(outcome) = self.step {
                return MasterIo::Done(outcome);
            }
            if self.step == TransactionStep::Send {
                self.step = TransactionStep::Wait;
                return MasterIo::Write(frame.as_bytes());
            }
            if let Some(event) = framer.next_event() {
                self.step = master_event(transaction, &event, clock(), &mut self.answer, &mut self.result);
                continue;
            }
            let now = clock();
            match transaction.deadline() {
                Some(deadline) if now >= deadline => self.step = transaction.poll(now),
                deadline => return MasterIo::Read(deadline),
            }
        }
    }
}

/// One framer event of a master exchange: what the exchange does next, the
/// hop-by-hop answer to write (ACK for the result frame, NAK for a damaged
/// frame once the command is acknowledged, so that the device sends its
/// result again) and the result frame, kept.
fn master_event(
    transaction: &mut Transaction,
    event: &Event<'_>,
    now: u64,
    answer: &mut Answer,
    result: &mut Option<FrameBuf>,
) -> TransactionStep {
    let step = transaction.on_event(event, now);
    match event {
        Event::Frame(frame) if step == TransactionStep::Done(Outcome::Result) => {
            answer.push(&[ACK]);
            *result = Some(FrameBuf::from_frame(frame));
        }
        Event::BadChecksum(_) if transaction.acknowledged() => answer.push(&[NAK]),
        _ => {}
    }
    step
}
