//! The board: LM3S6965 UART0 (a PL011 at 0x4000_C000, on PA0/PA1) and the
//! SysTick millisecond clock, through the `tudelft-lm3s6965-pac` register
//! API and `cortex-m`.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use tudelft_lm3s6965_pac as pac;

/// System clock after reset: the 12 MHz internal oscillator (QEMU models
/// 12.5 MHz). A board that runs from its crystal or the PLL changes this.
pub const SYSCLK_HZ: u32 = 12_000_000;
/// Line rate: the protocol's default, 9600 bit/s 8N1 (1.5.1).
pub const BAUD: u32 = 9_600;

/// Milliseconds since start, counted by the SysTick exception.
pub static TICKS: AtomicU32 = AtomicU32::new(0);

/// SysTick: one exception per millisecond.
pub fn start_systick(syst: &mut SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(SYSCLK_HZ / 1_000 - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Milliseconds as a `u64` that does not wrap after 49 days: the `u32`
/// tick count extended by the caller's last reading.
#[derive(Debug, Default)]
pub struct Clock {
    last: u32,
    now: u64,
}

impl Clock {
    pub fn now(&mut self) -> u64 {
        let ticks = TICKS.load(Ordering::Relaxed);
        self.now += u64::from(ticks.wrapping_sub(self.last));
        self.last = ticks;
        self.now
    }
}

/// UART0, 8N1 with FIFOs, receive and receive-time-out interrupts enabled
/// (the NVIC line is unmasked by the main loop when it sleeps).
pub struct Uart {
    regs: pac::UART0,
}

impl Uart {
    pub fn new(regs: pac::UART0, sysctl: &pac::SYSCTL, gpioa: &pac::GPIO_PORTA) -> Self {
        // Clocks to UART0 and GPIO port A, then PA0/PA1 to the UART.
        sysctl.rcgc1.modify(|_, w| w.sysctl_rcgc1_uart0().set_bit());
        sysctl.rcgc2.modify(|_, w| w.sysctl_rcgc2_gpioa().set_bit());
        // The peripheral needs a few clocks after its gate opens.
        cortex_m::asm::delay(16);
        // SAFETY: AFSEL and DEN take any bit pattern; setting bits 0 and 1
        // hands PA0 (U0Rx) and PA1 (U0Tx) to the UART, other pins unchanged.
        gpioa.afsel.modify(|r, w| unsafe { w.bits(r.bits() | 0b11) });
        // SAFETY: as above, digital enable for PA0 and PA1 only.
        gpioa.den.modify(|r, w| unsafe { w.bits(r.bits() | 0b11) });

        regs.ctl.write(|w| w.uart_ctl_uarten().clear_bit());
        // Divisor = SYSCLK / (16 * BAUD) as 16.6 fixed point, rounded.
        let divisor_x64 = (SYSCLK_HZ * 8 / BAUD).div_ceil(2);
        // SAFETY: IBRD holds a 16-bit divisor; 12 MHz / (16 * 9600) = 78.
        regs.ibrd
            .write(|w| unsafe { w.uart_ibrd_divint().bits((divisor_x64 / 64) as u16) });
        // SAFETY: FBRD holds a 6-bit fraction; the value is masked to it.
        regs.fbrd
            .write(|w| unsafe { w.uart_fbrd_divfrac().bits((divisor_x64 % 64) as u8) });
        // 8 data bits (WLEN = 3), FIFOs on, one stop bit, no parity.
        regs.lcrh
            .write(|w| w.uart_lcrh_wlen().bits(3).uart_lcrh_fen().set_bit());
        regs.im.write(|w| w.uart_im_rxim().set_bit().uart_im_rtim().set_bit());
        regs.ctl.write(|w| {
            w.uart_ctl_uarten()
                .set_bit()
                .uart_ctl_txe()
                .set_bit()
                .uart_ctl_rxe()
                .set_bit()
        });
        Self { regs }
    }

    /// Whether a received byte waits in the FIFO.
    pub fn rx_ready(&self) -> bool {
        self.regs.fr.read().uart_fr_rxfe().bit_is_clear()
    }

    /// Moves what the receive FIFO holds into `buf`; returns the count.
    /// A byte received with a framing or parity error is passed on as it
    /// is: the framer's checksum rejects the frame and the master gets NAK.
    pub fn read_into(&self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            if !self.rx_ready() {
                break;
            }
            *slot = self.regs.dr.read().uart_dr_data().bits();
            n += 1;
        }
        // The receive interrupt clears as the FIFO empties; the receive
        // time-out one is cleared here.
        self.regs.icr.write(|w| w.uart_icr_rtic().set_bit());
        n
    }

    /// Writes `bytes`, waiting for room in the transmit FIFO.
    pub fn write(&self, bytes: &[u8]) {
        for &byte in bytes {
            while self.regs.fr.read().uart_fr_txff().bit_is_set() {}
            // SAFETY: DR's data field takes any byte; writing it queues the byte.
            self.regs.dr.write(|w| unsafe { w.uart_dr_data().bits(byte) });
        }
    }
}
