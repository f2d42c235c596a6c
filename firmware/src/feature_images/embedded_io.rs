//! The gimbal image served through the protocol crate's blocking adapter,
//! `io::blocking::Device` (feature `embedded-io`), over the UART behind
//! `embedded_io::{Read, Write}`. build.sh measures its flash against the
//! `gimbal` image's for the crate's README (issue 36).
#![no_std]
#![no_main]

#[path = "../board.rs"]
mod board;
#[path = "../common.rs"]
mod common;
#[path = "../gimbal.rs"]
mod gimbal;

use core::convert::Infallible;
use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use embedded_io::{ErrorType, Read, Write};
use sagebrush_protocol::EndpointConfig;
use sagebrush_protocol::io::blocking::Device;

use board::{Clock, Uart};
use common::{ADDRESS, RX_CAPACITY, SILENCE_MS};
use gimbal::Gimbal;

/// UART0 as a blocking reader/writer; its FIFO is the buffer.
struct Serial(&'static Uart);

impl ErrorType for Serial {
    type Error = Infallible;
}

impl Read for Serial {
    /// Sleeps until a byte is there, then drains the FIFO into `buf`.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        loop {
            let n = self.0.read_into(buf);
            if n > 0 || buf.is_empty() {
                return Ok(n);
            }
            common::sleep(self.0);
        }
    }
}

impl Write for Serial {
    fn write(&mut self, bytes: &[u8]) -> Result<usize, Infallible> {
        self.0.write(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
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
    // One clock closure for both calls, so that the adapter's event
    // handling is instantiated once (as `main.rs` does with its output).
    let mut ticks = Clock::default();
    let mut clock = || ticks.now();
    let mut last_rx = 0;

    loop {
        let now = clock();
        // Errors: the I/O is infallible; a deferred result that does not
        // encode (this gimbal defers none) is dropped.
        if uart.rx_ready() {
            last_rx = now;
            let _ = device.poll(gimbal, &mut clock);
        } else if device.endpoint().framer().buffered() > 0 && now.saturating_sub(last_rx) >= SILENCE_MS {
            let _ = device.line_idle(gimbal, &mut clock);
        }
        gimbal.advance(now);
        common::sleep(uart);
    }
}
