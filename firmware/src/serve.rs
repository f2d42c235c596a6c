//! The main loop of the images that drive the `DeviceEndpoint` by hand
//! (`main.rs` and the `defmt` image): UART0 bytes go straight into the
//! endpoint's free buffer space (`spare_capacity_mut` + `commit`, the
//! protocol crate's DMA path), a frame cut short is abandoned after
//! `SILENCE_MS` of silence (`line_idle`), the motion model advances, and
//! the core sleeps until the next tick or byte.

use core::mem::MaybeUninit;

use sagebrush_protocol::{DeviceEndpoint, DeviceHandler, EndpointConfig};

use crate::board::Clock;
use crate::common::{self, ADDRESS, RX_CAPACITY, SILENCE_MS};
use crate::gimbal::Gimbal;

/// The handler the loop serves: the gimbal, or the gimbal wrapped (logged),
/// whose motion model advances between events.
pub trait Moving: DeviceHandler {
    fn advance(&mut self, now: u64);
}

impl Moving for Gimbal {
    fn advance(&mut self, now: u64) {
        Gimbal::advance(self, now);
    }
}

/// Starts UART0 and SysTick and serves `handler` at `ADDRESS` for good.
/// The endpoint lives in `slot` (static RAM, .bss: its initial value takes
/// no flash); one output closure for both of the endpoint's entry points,
/// so that its event handling is instantiated once.
pub fn serve(slot: &'static mut MaybeUninit<DeviceEndpoint<RX_CAPACITY>>, handler: &mut impl Moving) -> ! {
    let endpoint = common::init(slot, || DeviceEndpoint::new(EndpointConfig::single(ADDRESS)));
    let uart = common::start();
    let mut clock = Clock::default();
    let mut last_rx = 0;
    let mut send = |bytes: &[u8]| uart.write(bytes);

    loop {
        let now = clock.now();
        let n = uart.read_into(endpoint.spare_capacity_mut());
        if n > 0 {
            last_rx = now;
            endpoint.commit(n, now, handler, &mut send);
        } else if endpoint.framer().buffered() > 0 && now.saturating_sub(last_rx) >= SILENCE_MS {
            endpoint.line_idle(now, handler, &mut send);
        }
        handler.advance(now);
        common::sleep(&uart);
    }
}
