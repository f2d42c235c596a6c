//! A Sagebrush gimbal on an RP2040: the crate's async device endpoint on an
//! interrupt-buffered UART (bytes keep arriving in the ring buffer while an
//! answer is written). It answers `P?`, goes to `Paaaaeeee`, accepts the
//! stops, and NICs every other command without linking its parser.

#![no_std]
#![no_main]

use embassy_executor::Spawner;
use embassy_rp::bind_interrupts;
use embassy_rp::peripherals::UART0;
use embassy_rp::uart::{BufferedInterruptHandler, BufferedUart, Config};
use embassy_time::{Instant, Timer};
use panic_halt as _;
use sagebrush_protocol::io::asynch::Device;
use sagebrush_protocol::{Command, DeviceHandler, EndpointConfig, Position, Reply, ReplyTo, Response, Row};

bind_interrupts!(struct Irqs {
    UART0_IRQ => BufferedInterruptHandler<UART0>;
});

/// Device address on its bus.
const DEVICE: u8 = 1;

/// The gimbal model: a position that moves at once (a real one drives motors).
#[derive(Default)]
struct Gimbal {
    position: Position,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, _reply_to: ReplyTo, _now: u64) -> Response<'_> {
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(self.position)),
            Command::GoTo(target) => {
                self.position = target;
                Response::Done
            }
            Command::Halt | Command::MotorsStop | Command::PanStop | Command::TiltStop => Response::Done,
            _ => Response::Nic,
        }
    }

    fn implements(row: Row) -> bool {
        matches!(
            row,
            Row::QueryPosition | Row::GoTo | Row::Halt | Row::MotorsStop | Row::PanStop | Row::TiltStop
        )
    }
}

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let p = embassy_rp::init(Default::default());
    let mut config = Config::default();
    config.baudrate = 9600;
    // The receive ring buffer holds more than a maximum frame (263 bytes).
    let mut tx_buffer = [0u8; 300];
    let mut rx_buffer = [0u8; 600];
    let uart = BufferedUart::new(p.UART0, p.PIN_0, p.PIN_1, Irqs, &mut tx_buffer, &mut rx_buffer, config);

    let mut device: Device<_> = Device::new(uart, EndpointConfig::single(DEVICE));
    let mut gimbal = Gimbal::default();
    let mut clock = || Instant::now().as_millis();
    loop {
        // Bytes: every frame handled and answered. 5 ms without a byte (about
        // five characters at 9600 bit/s): a partial frame is abandoned. A UART
        // error (overrun, framing, break) loses bytes; the framer resynchronises
        // on what follows, and the master retransmits.
        let _ = device.poll(&mut gimbal, &mut clock, Timer::after_millis(5)).await;
    }
}
