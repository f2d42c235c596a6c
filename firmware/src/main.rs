//! Sagebrush gimbal firmware for the LM3S6965 (QEMU `lm3s6965evb`).
//!
//! UART0 bytes go straight into the `DeviceEndpoint`'s free buffer space
//! (`spare_capacity_mut` + `commit`, the protocol crate's DMA path); the
//! endpoint ACKs, NAKs, answers NIC and sends results (Table 3 header)
//! through the UART. SysTick counts milliseconds: it drives the motion
//! model and the silence time-out (`line_idle`) that abandons a frame cut
//! short. Between events the core sleeps in WFI, woken by SysTick or by the
//! UART receive interrupt.
#![no_std]
#![no_main]

mod board;
mod gimbal;

use core::mem::MaybeUninit;
use core::sync::atomic::Ordering;

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception};
use sagebrush_protocol::{DeviceEndpoint, EndpointConfig, MAX_FRAME_LEN};
use tudelft_lm3s6965_pac::{self as pac, Interrupt, interrupt};

use board::{Clock, TICKS, Uart};
use gimbal::Gimbal;

/// Device address at power-up (`#NN` changes it until reset).
const DEVICE: u8 = 1;
/// Receive buffer: one maximum frame, the least the framer takes.
const RX_CAPACITY: usize = MAX_FRAME_LEN;
/// Line silence after which a partial frame is abandoned: 5 ms, about five
/// character times at 9600 bit/s (a frame's bytes follow each other).
const SILENCE_MS: u64 = 5;

#[exception]
fn SysTick() {
    TICKS.fetch_add(1, Ordering::Relaxed);
}

/// Received bytes wake the main loop, which drains the FIFO; until then the
/// line is masked so that the level interrupt does not fire again.
#[interrupt]
fn UART0() {
    NVIC::mask(Interrupt::UART0);
}

#[entry]
fn main() -> ! {
    // The endpoint (framer buffer, last result) and the gimbal live in
    // static RAM; cortex-m-rt hands `static mut` of the entry function out
    // as `&'static mut`, once. Uninitialised statics go to .bss and are set
    // here, so that their initial values take no flash (.data would).
    static mut ENDPOINT: MaybeUninit<DeviceEndpoint<RX_CAPACITY>> = MaybeUninit::uninit();
    static mut GIMBAL: MaybeUninit<Gimbal> = MaybeUninit::uninit();
    let endpoint = init(ENDPOINT, || DeviceEndpoint::new(EndpointConfig::single(DEVICE)));
    let gimbal = init(GIMBAL, Gimbal::new);

    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        // Only reachable if something took the peripherals before main.
        loop {
            cortex_m::asm::wfi();
        }
    };
    let uart = Uart::new(dp.UART0, &dp.SYSCTL, &dp.GPIO_PORTA);
    board::start_systick(&mut cp.SYST);
    let mut clock = Clock::default();
    let mut last_rx = 0;
    // One output closure for both entry points, so that the endpoint's
    // event handling is instantiated once.
    let mut send = |bytes: &[u8]| uart.write(bytes);

    loop {
        let now = clock.now();
        let n = uart.read_into(endpoint.spare_capacity_mut());
        if n > 0 {
            last_rx = now;
            endpoint.commit(n, now, gimbal, &mut send);
        } else if endpoint.framer().buffered() > 0 && now.saturating_sub(last_rx) >= SILENCE_MS {
            endpoint.line_idle(now, gimbal, &mut send);
        }
        gimbal.advance(now);

        // Sleep until the next tick or received byte. Interrupts are off
        // while deciding, so a byte arriving after the check still wakes
        // WFI (a pending interrupt ends it even with PRIMASK set), and its
        // handler runs once they are back on.
        cortex_m::interrupt::free(|_| {
            if !uart.rx_ready() {
                // SAFETY: unmasking UART0 lets its handler run, and that
                // handler only masks the line again; no critical section
                // relies on UART0 being masked.
                unsafe { NVIC::unmask(Interrupt::UART0) };
                cortex_m::asm::wfi();
            }
        });
    }
}

/// Writes `make()` into `slot`. Not inlined: the value is built in this
/// function's frame, which is gone once it returns, instead of staying in
/// `main`'s frame (which never returns) for good.
#[inline(never)]
fn init<T>(slot: &'static mut MaybeUninit<T>, make: impl FnOnce() -> T) -> &'static mut T {
    slot.write(make())
}

/// A panic cannot come from input (build.sh checks that no panic site is
/// linked at all); should one ever run, reset rather than hang on the bus.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}
