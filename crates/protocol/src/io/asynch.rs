//! Async adapters over `embedded_io_async::{Read, Write}` (feature
//! `embedded-io-async`), for embassy and other executors.
//!
//! The reader must be buffered (see [the module above](super)) and its
//! `read` cancel-safe (embassy's `BufferedUart` is): a read that loses the
//! race against the silence or deadline timer is dropped. The timer is the
//! caller's, a future such as `embassy_time::Timer::after_millis(5)`, so the
//! crate depends on no executor and no time driver.

use core::future::{Future, poll_fn};
use core::pin::pin;
use core::task::Poll;

use embedded_io_async::{Read, Write};

use super::{Answer, Error, Exchange, MasterIo, MasterRun};
use crate::device::{DeviceEndpoint, DeviceHandler, EndpointConfig, ReplyTo};
use crate::frame::FrameBuf;
use crate::framer::{DEFAULT_CAPACITY, Framer};
use crate::link::Transaction;
use crate::reply::Reply;

/// Which of a read and a timer finished first.
enum Race {
    Read(usize),
    Timer,
}

/// Reads into `buf` unless `timer` completes first (then the read is dropped).
async fn read_or<R: Read>(
    io: &mut R,
    buf: &mut [u8],
    timer: impl Future<Output = ()>,
) -> Result<Race, Error<R::Error>> {
    let mut read = pin!(io.read(buf));
    let mut timer = pin!(timer);
    let race = poll_fn(|cx| {
        if let Poll::Ready(result) = read.as_mut().poll(cx) {
            return Poll::Ready(result.map(Race::Read));
        }
        timer.as_mut().poll(cx).map(|()| Ok(Race::Timer))
    })
    .await
    .map_err(Error::Io)?;
    match race {
        Race::Read(0) => Err(Error::EndOfStream),
        race => Ok(race),
    }
}

async fn write_answer<W: Write>(io: &mut W, answer: &mut Answer) -> Result<(), Error<W::Error>> {
    let bytes = answer.take();
    if bytes.is_empty() {
        return Ok(());
    }
    io.write_all(bytes).await.map_err(Error::Io)?;
    io.flush().await.map_err(Error::Io)
}

adapter_parts! {
    /// A [`DeviceEndpoint`] answering on `T`: reads go into the endpoint's
    /// framer, answers are written to `T` event by event.
    ///
    /// ```ignore
    /// // embassy, a BufferedUart at 9600 bit/s: 5 ms is a few character times.
    /// let mut device: Device<_> = Device::new(uart, EndpointConfig::single(1));
    /// let mut clock = || embassy_time::Instant::now().as_millis();
    /// loop {
    ///     device.poll(&mut gimbal, &mut clock, embassy_time::Timer::after_millis(5)).await?;
    /// }
    /// ```
    Device;
    /// A master on `T`: runs [`Transaction`]s, its framer kept across them.
    Master;
}

impl<T: Read + Write, const N: usize> Device<T, N> {
    /// Waits for bytes or for `silence`, whichever comes first. Bytes: every
    /// event they complete is handled, each one's answer written before the
    /// next. Silence (the line quiet for an inter-byte time-out): a partial
    /// frame is abandoned and what follows its false start rescanned (the
    /// silence hook). Returns the bytes read, 0 on silence.
    pub async fn poll(
        &mut self,
        handler: &mut impl DeviceHandler,
        clock: &mut impl FnMut() -> u64,
        silence: impl Future<Output = ()>,
    ) -> Result<usize, Error<T::Error>> {
        let race = read_or(&mut self.io, self.endpoint.spare_capacity_mut(), silence).await?;
        let n = match race {
            Race::Read(n) => {
                self.endpoint.commit_only(n);
                n
            }
            Race::Timer => {
                self.endpoint.line_idle_only();
                0
            }
        };
        let mut answer = Answer::new();
        while self
            .endpoint
            .handle_next(clock(), handler, &mut |bytes| answer.push(bytes))
        {
            write_answer(&mut self.io, &mut answer).await?;
        }
        Ok(n)
    }

    /// Sends a deferred result (see `DeviceEndpoint::send_reply`).
    pub async fn send_reply(&mut self, to: ReplyTo, reply: &Reply<'_>) -> Result<(), Error<T::Error>> {
        let mut answer = Answer::new();
        self.endpoint
            .send_reply(to, reply, &mut |bytes| answer.push(bytes))
            .map_err(Error::Encode)?;
        write_answer(&mut self.io, &mut answer).await
    }
}

impl<T: Read + Write, const N: usize> Master<T, N> {
    /// Runs `transaction` to its end: writes `frame` (its command frame)
    /// when the exchange says so, feeds what the line returns into the
    /// framer, ACKs the result frame and NAKs a damaged one after the
    /// command's ACK. `sleep_until(tick)` is a timer future completing at
    /// that tick of `clock`; a read pending at the deadline is dropped.
    pub async fn transact<S: Future<Output = ()>>(
        &mut self,
        frame: &FrameBuf,
        transaction: &mut Transaction,
        clock: &mut impl FnMut() -> u64,
        mut sleep_until: impl FnMut(u64) -> S,
    ) -> Result<Exchange, Error<T::Error>> {
        let mut run = MasterRun::start(transaction, clock());
        loop {
            match run.next(frame, transaction, &mut self.framer, clock) {
                MasterIo::Write(bytes) => {
                    self.io.write_all(bytes).await.map_err(Error::Io)?;
                    self.io.flush().await.map_err(Error::Io)?;
                }
                MasterIo::Read(Some(deadline)) => {
                    if let Race::Read(n) =
                        read_or(&mut self.io, self.framer.spare_capacity_mut(), sleep_until(deadline)).await?
                    {
                        self.framer.commit(n);
                    }
                }
                MasterIo::Read(None) => {
                    let n = self
                        .io
                        .read(self.framer.spare_capacity_mut())
                        .await
                        .map_err(Error::Io)?;
                    if n == 0 {
                        return Err(Error::EndOfStream);
                    }
                    self.framer.commit(n);
                }
                MasterIo::Done(outcome) => return Ok(run.exchange(outcome, transaction)),
            }
        }
    }
}
