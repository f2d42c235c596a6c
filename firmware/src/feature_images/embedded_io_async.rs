//! The gimbal image served through the protocol crate's async adapter,
//! `io::asynch::Device` (feature `embedded-io-async`), over the UART behind
//! `embedded_io_async::{Read, Write}`, on a minimal executor that sleeps
//! between polls. build.sh measures its flash against the `gimbal` image's
//! for the crate's README (issue 36).
#![no_std]
#![no_main]

#[path = "../board.rs"]
mod board;
#[path = "../common.rs"]
mod common;
#[path = "../gimbal.rs"]
mod gimbal;

use core::convert::Infallible;
use core::future::{Future, poll_fn};
use core::mem::MaybeUninit;
use core::pin::pin;
use core::sync::atomic::Ordering;
use core::task::{Context, Poll, Waker};

use cortex_m_rt::entry;
use embedded_io_async::{ErrorType, Read, Write};
use sagebrush_protocol::EndpointConfig;
use sagebrush_protocol::io::asynch::Device;

use board::{Clock, TICKS, Uart};
use common::{ADDRESS, RX_CAPACITY, SILENCE_MS};
use gimbal::Gimbal;

/// UART0 as an async reader/writer; its FIFO is the buffer. A read is
/// pending until a byte is there (cancel-safe: nothing is taken before).
struct Serial(&'static Uart);

impl ErrorType for Serial {
    type Error = Infallible;
}

impl Read for Serial {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        poll_fn(|_| match self.0.read_into(buf) {
            0 if !buf.is_empty() => Poll::Pending,
            n => Poll::Ready(Ok(n)),
        })
        .await
    }
}

impl Write for Serial {
    async fn write(&mut self, bytes: &[u8]) -> Result<usize, Infallible> {
        self.0.write(bytes);
        Ok(bytes.len())
    }

    async fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// A timer: completes `ms` SysTick milliseconds after it is made.
fn after(ms: u64) -> impl Future<Output = ()> {
    let start = TICKS.load(Ordering::Relaxed);
    poll_fn(move |_| {
        let elapsed = TICKS.load(Ordering::Relaxed).wrapping_sub(start);
        if u64::from(elapsed) >= ms {
            Poll::Ready(())
        } else {
            Poll::Pending
        }
    })
}

/// The executor: polls `task` each time the core wakes (SysTick or a
/// received byte), which also wakes every timer; no waker is needed.
fn run(uart: &Uart, task: impl Future<Output = Infallible>) -> ! {
    let mut task = pin!(task);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        let Poll::Pending = task.as_mut().poll(&mut cx);
        common::sleep(uart);
    }
}

#[entry]
fn main() -> ! {
    static mut UART: MaybeUninit<Uart> = MaybeUninit::uninit();
    static mut DEVICE: MaybeUninit<Device<Serial, RX_CAPACITY>> = MaybeUninit::uninit();
    static mut GIMBAL: MaybeUninit<Gimbal> = MaybeUninit::uninit();
    let uart: &Uart = common::init(UART, common::start);
    let device = common::init(DEVICE, || Device::new(Serial(uart), EndpointConfig::single(ADDRESS)));
    let gimbal = common::init(GIMBAL, Gimbal::new);
    let mut ticks = Clock::default();
    let mut clock = move || ticks.now();

    run(uart, async move {
        loop {
            // Errors: the I/O is infallible; a deferred result that does
            // not encode (this gimbal defers none) is dropped.
            let _ = device.poll(gimbal, &mut clock, after(SILENCE_MS)).await;
            gimbal.advance(clock());
        }
    })
}
