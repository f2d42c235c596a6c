//! Blocking adapters over `embedded_io::{Read, Write}` (feature `embedded-io`).
//!
//! The reader must be buffered: see [the module above](super).
//!
//! ```
//! use embedded_io::{ErrorType, Read, Write};
//! use sagebrush_protocol::io::blocking::Device;
//! use sagebrush_protocol::*;
//!
//! /// A UART stand-in: received bytes in, sent bytes out.
//! struct Uart { rx: &'static [u8], tx: [u8; 64], tx_len: usize }
//! impl ErrorType for Uart { type Error = core::convert::Infallible; }
//! impl Read for Uart {
//!     fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
//!         let n = buf.len().min(self.rx.len());
//!         buf[..n].copy_from_slice(&self.rx[..n]);
//!         self.rx = &self.rx[n..];
//!         Ok(n)
//!     }
//! }
//! impl Write for Uart {
//!     fn write(&mut self, bytes: &[u8]) -> Result<usize, Self::Error> {
//!         self.tx[self.tx_len..self.tx_len + bytes.len()].copy_from_slice(bytes);
//!         self.tx_len += bytes.len();
//!         Ok(bytes.len())
//!     }
//!     fn flush(&mut self) -> Result<(), Self::Error> { Ok(()) }
//! }
//!
//! struct Gimbal;
//! impl DeviceHandler for Gimbal {
//!     fn handle(&mut self, command: Command<'_>, _: ReplyTo, _: u64) -> Response<'_> {
//!         match command {
//!             Command::QueryPosition => Response::Reply(Reply::Position(Position::new(Angle(100), Angle(-100)))),
//!             _ => Response::Nic,
//!         }
//!     }
//! }
//!
//! // `P?` to device 12 on port 1 of GCU 5, from GCU 2.
//! static RX: [u8; 9] = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
//! let uart = Uart { rx: &RX, tx: [0; 64], tx_len: 0 };
//! let mut device: Device<Uart> = Device::new(uart, EndpointConfig::single(12));
//! let mut clock = || 0; // the board's millisecond counter
//! device.poll(&mut Gimbal, &mut clock).unwrap(); // blocks for bytes; answers them
//! let uart = device.io();
//! assert_eq!(uart.tx[0], ACK);
//! assert_eq!(Frame::parse(&uart.tx[1..uart.tx_len]).unwrap().0.payload(), b"0064FF9C");
//! ```

use embedded_io::{Read, ReadReady, Write};

use super::{Answer, Error, Exchange, MasterIo, MasterRun};
use crate::device::{DeviceEndpoint, DeviceHandler, EndpointConfig, ReplyTo};
use crate::frame::FrameBuf;
use crate::framer::{DEFAULT_CAPACITY, Framer};
use crate::link::Transaction;
use crate::reply::Reply;

adapter_parts! {
    /// A [`DeviceEndpoint`] answering on `T`: reads go into the endpoint's
    /// framer, answers are written to `T` event by event. [`Device::io`]
    /// reaches `T`, e.g. to ask `read_ready` before [`Device::poll`].
    Device;
    /// A master on `T`: runs [`Transaction`]s, its framer kept across them.
    ///
    /// Time-outs need a reader that can say whether a byte is waiting
    /// (`ReadReady`): [`Master::transact`] polls it and the clock, and reads
    /// only when a byte is there, so it never blocks past a deadline.
    Master;
}

impl<T: Read + Write, const N: usize> Device<T, N> {
    /// Blocks in one `read` (at least one byte), then handles every event
    /// the bytes complete, writing each one's answer before the next.
    /// `clock` gives the tick handed to the handler.
    pub fn poll(
        &mut self,
        handler: &mut impl DeviceHandler,
        clock: &mut impl FnMut() -> u64,
    ) -> Result<usize, Error<T::Error>> {
        let n = self.io.read(self.endpoint.spare_capacity_mut()).map_err(Error::Io)?;
        if n == 0 {
            return Err(Error::EndOfStream);
        }
        self.endpoint.commit_only(n);
        self.handle_events(handler, clock)?;
        Ok(n)
    }

    /// The silence hook: call it when the line has been quiet for longer
    /// than an inter-byte time-out (see `DeviceEndpoint::line_idle`).
    pub fn line_idle(
        &mut self,
        handler: &mut impl DeviceHandler,
        clock: &mut impl FnMut() -> u64,
    ) -> Result<(), Error<T::Error>> {
        self.endpoint.line_idle_only();
        self.handle_events(handler, clock)
    }

    /// Sends a deferred result (see `DeviceEndpoint::send_reply`).
    pub fn send_reply(&mut self, to: ReplyTo, reply: &Reply<'_>) -> Result<(), Error<T::Error>> {
        let mut answer = Answer::new();
        self.endpoint
            .send_reply(to, reply, &mut |bytes| answer.push(bytes))
            .map_err(Error::Encode)?;
        write_answer(&mut self.io, &mut answer)
    }

    fn handle_events(
        &mut self,
        handler: &mut impl DeviceHandler,
        clock: &mut impl FnMut() -> u64,
    ) -> Result<(), Error<T::Error>> {
        let mut answer = Answer::new();
        while self
            .endpoint
            .handle_next(clock(), handler, &mut |bytes| answer.push(bytes))
        {
            write_answer(&mut self.io, &mut answer)?;
        }
        Ok(())
    }
}

impl<T: Read + Write + ReadReady, const N: usize> Master<T, N> {
    /// Runs `transaction` to its end: writes `frame` (its command frame)
    /// when the exchange says so, feeds what the line returns into the
    /// framer, ACKs the result frame and NAKs a damaged one after the
    /// command's ACK. Busy-waits on `read_ready` and `clock`.
    pub fn transact(
        &mut self,
        frame: &FrameBuf,
        transaction: &mut Transaction,
        clock: &mut impl FnMut() -> u64,
    ) -> Result<Exchange, Error<T::Error>> {
        let mut run = MasterRun::start(transaction, clock());
        loop {
            match run.next(frame, transaction, &mut self.framer, clock) {
                MasterIo::Write(bytes) => {
                    self.io.write_all(bytes).map_err(Error::Io)?;
                    self.io.flush().map_err(Error::Io)?;
                }
                MasterIo::Read(_) => {
                    if self.io.read_ready().map_err(Error::Io)? {
                        let n = self.io.read(self.framer.spare_capacity_mut()).map_err(Error::Io)?;
                        if n == 0 {
                            return Err(Error::EndOfStream);
                        }
                        self.framer.commit(n);
                    }
                }
                MasterIo::Done(outcome) => return Ok(run.exchange(outcome, transaction)),
            }
        }
    }
}

fn write_answer<W: Write>(io: &mut W, answer: &mut Answer) -> Result<(), Error<W::Error>> {
    let bytes = answer.take();
    if bytes.is_empty() {
        return Ok(());
    }
    io.write_all(bytes).map_err(Error::Io)?;
    io.flush().map_err(Error::Io)
}
