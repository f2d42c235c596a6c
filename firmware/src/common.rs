//! What every gimbal image (`main.rs` and the feature images) shares: the
//! address, buffer size and silence time-out, the SysTick and UART0
//! handlers, the panic handler, start-up, the sleep between events and the
//! placement of the big statics.

use core::mem::MaybeUninit;
use core::sync::atomic::Ordering;

use cortex_m::peripheral::NVIC;
use cortex_m_rt::exception;
use sagebrush_protocol::MAX_FRAME_LEN;
use tudelft_lm3s6965_pac::{self as pac, Interrupt, interrupt};

use crate::board::{self, TICKS, Uart};

/// Device address at power-up (`#NN` changes it until reset).
pub const ADDRESS: u8 = 1;
/// Receive buffer: one maximum frame, the least the framer takes.
pub const RX_CAPACITY: usize = MAX_FRAME_LEN;
/// Line silence after which a partial frame is abandoned: 5 ms, about five
/// character times at 9600 bit/s (a frame's bytes follow each other).
pub const SILENCE_MS: u64 = 5;

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

/// A panic cannot come from input (build.sh checks that no panic site is
/// linked at all); should one ever run, reset rather than hang on the bus.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}

/// UART0 and SysTick started.
pub fn start() -> Uart {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        // Only reachable if something took the peripherals before main.
        loop {
            cortex_m::asm::wfi();
        }
    };
    let uart = Uart::new(dp.UART0, &dp.SYSCTL, &dp.GPIO_PORTA);
    board::start_systick(&mut cp.SYST);
    uart
}

/// Sleeps until the next tick or received byte. Interrupts are off while
/// deciding, so a byte arriving after the check still wakes WFI (a pending
/// interrupt ends it even with PRIMASK set), and its handler runs once
/// they are back on.
pub fn sleep(uart: &Uart) {
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

/// Writes `make()` into `slot`. Not inlined: the value is built in this
/// function's frame, which is gone once it returns, instead of staying in
/// `main`'s frame (which never returns) for good.
#[inline(never)]
pub fn init<T>(slot: &'static mut MaybeUninit<T>, make: impl FnOnce() -> T) -> &'static mut T {
    slot.write(make())
}
