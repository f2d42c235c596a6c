//! The gimbal image of `main.rs` with every command and the handler's
//! response logged through the protocol crate's `defmt::Format`
//! implementations (feature `defmt`), over defmt-rtt (RTT: a RAM buffer a
//! debug probe reads). build.sh measures its flash against the `gimbal`
//! image's for the crate's README (issue 36).
#![no_std]
#![no_main]

#[path = "../board.rs"]
mod board;
#[path = "../common.rs"]
mod common;
#[path = "../gimbal.rs"]
mod gimbal;

use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use defmt_rtt as _;
use sagebrush_protocol::{Command, DeviceEndpoint, DeviceHandler, EndpointConfig, ReplyTo, Response, Row};

use board::Clock;
use common::{ADDRESS, RX_CAPACITY, SILENCE_MS};
use gimbal::Gimbal;

/// The gimbal, each command and response logged.
struct Logged<'a>(&'a mut Gimbal);

impl DeviceHandler for Logged<'_> {
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, now: u64) -> Response<'_> {
        defmt::info!("{} {}", reply_to, command);
        let response = self.0.handle(command, reply_to, now);
        defmt::info!("-> {}", response);
        response
    }

    fn implements(row: Row) -> bool {
        Gimbal::implements(row)
    }
}

#[entry]
fn main() -> ! {
    static mut ENDPOINT: MaybeUninit<DeviceEndpoint<RX_CAPACITY>> = MaybeUninit::uninit();
    static mut GIMBAL: MaybeUninit<Gimbal> = MaybeUninit::uninit();
    let endpoint = common::init(ENDPOINT, || DeviceEndpoint::new(EndpointConfig::single(ADDRESS)));
    let gimbal = common::init(GIMBAL, Gimbal::new);
    let uart = common::start();
    let mut clock = Clock::default();
    let mut last_rx = 0;
    let mut send = |bytes: &[u8]| uart.write(bytes);

    loop {
        let now = clock.now();
        let n = uart.read_into(endpoint.spare_capacity_mut());
        if n > 0 {
            last_rx = now;
            endpoint.commit(n, now, &mut Logged(gimbal), &mut send);
        } else if endpoint.framer().buffered() > 0 && now.saturating_sub(last_rx) >= SILENCE_MS {
            endpoint.line_idle(now, &mut Logged(gimbal), &mut send);
        }
        gimbal.advance(now);
        common::sleep(&uart);
    }
}
