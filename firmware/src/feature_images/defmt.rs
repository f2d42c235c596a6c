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
#[path = "../serve.rs"]
mod serve;

use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use defmt_rtt as _;
use sagebrush_protocol::{Command, DeviceEndpoint, DeviceHandler, ReplyTo, Response, Row};

use common::RX_CAPACITY;
use gimbal::Gimbal;
use serve::Moving;

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

impl Moving for Logged<'_> {
    fn advance(&mut self, now: u64) {
        self.0.advance(now);
    }
}

#[entry]
fn main() -> ! {
    static mut ENDPOINT: MaybeUninit<DeviceEndpoint<RX_CAPACITY>> = MaybeUninit::uninit();
    static mut GIMBAL: MaybeUninit<Gimbal> = MaybeUninit::uninit();
    let gimbal = common::init(GIMBAL, Gimbal::new);
    serve::serve(ENDPOINT, &mut Logged(gimbal))
}
