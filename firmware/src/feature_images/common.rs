//! What the feature images share with `main.rs`: the address, buffer size
//! and silence time-out, the SysTick and UART0 handlers, the panic handler,
//! start-up and the sleep between events.

use core::mem::MaybeUninit;
use core::sync::atomic::Ordering;

use cortex_m::peripheral::NVIC;
use cortex_m_rt::exception;
use sagebrush_protocol::MAX_FRAME_LEN;
use tudelft_lm3s6965_pac::{self as pac, Interrupt, interrupt};

use crate::board::{self, TICKS, Uart};

/// Device address at power-up.
pub const ADDRESS: u8 = 1;
/// Receive buffer: one maximum frame, as in `main.rs`.
pub const RX_CAPACITY: usize = MAX_FRAME_LEN;
/// Line silence after which a partial frame is abandoned (as in `main.rs`).
pub const SILENCE_MS: u64 = 5;

#[exception]
fn SysTick() {
    TICKS.fetch_add(1, Ordering::Relaxed);
}

#[interrupt]
fn UART0() {
    NVIC::mask(Interrupt::UART0);
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}

/// UART0 and SysTick started, as in `main.rs`.
pub fn start() -> Uart {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    let uart = Uart::new(dp.UART0, &dp.SYSCTL, &dp.GPIO_PORTA);
    board::start_systick(&mut cp.SYST);
    uart
}

/// Sleeps until the next tick or received byte, as `main.rs` does.
pub fn sleep(uart: &Uart) {
    cortex_m::interrupt::free(|_| {
        if !uart.rx_ready() {
            // SAFETY: UART0's handler only masks the line again.
            unsafe { NVIC::unmask(Interrupt::UART0) };
            cortex_m::asm::wfi();
        }
    });
}

/// Writes `make()` into `slot` (see `main.rs`).
#[inline(never)]
pub fn init<T>(slot: &'static mut MaybeUninit<T>, make: impl FnOnce() -> T) -> &'static mut T {
    slot.write(make())
}
