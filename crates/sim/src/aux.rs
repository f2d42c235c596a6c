//! Auxiliary serial ports 0 and 1 (Table 16 `*xpc`, `*xpt`, `*xpr`, `*xpn`,
//! `*xpf`; Table 18). The simulator has a loop-back plug on each port: what
//! `*xpt` transmits is received on the same port, as a real port would with
//! its TX wired to its RX.

use std::collections::VecDeque;

use sagebrush_protocol::{AuxConfig, Parity};

/// Receive buffer size of each port; bytes beyond it are dropped and counted,
/// as a UART's overrun would.
pub const AUX_BUFFER: usize = 1024;

/// One auxiliary serial port with its loop-back.
#[derive(Clone, Debug)]
pub struct AuxSerial {
    config: AuxConfig,
    rx: VecDeque<u8>,
    overruns: u64,
}

impl Default for AuxSerial {
    fn default() -> Self {
        Self {
            // Table 18 example: 9600 8N1.
            config: AuxConfig::new(9600, 8, 1, Parity::None).unwrap_or_else(|_| unreachable!("9600 8N1 is valid")),
            rx: VecDeque::new(),
            overruns: 0,
        }
    }
}

impl AuxSerial {
    /// `*xpc`: new line settings.
    pub fn configure(&mut self, config: AuxConfig) {
        self.config = config;
    }

    pub fn config(&self) -> AuxConfig {
        self.config
    }

    /// `*xpt`: transmit; the loop-back puts the bytes in the receive buffer.
    pub fn transmit(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if self.rx.len() < AUX_BUFFER {
                self.rx.push_back(b);
            } else {
                self.overruns += 1;
            }
        }
    }

    /// `*xprnnn`: takes up to `max` received bytes.
    pub fn receive(&mut self, max: usize) -> Vec<u8> {
        let n = max.min(self.rx.len());
        self.rx.drain(..n).collect()
    }

    /// `*xpn`: bytes waiting.
    pub fn available(&self) -> usize {
        self.rx.len()
    }

    /// `*xpf`: drops what is waiting.
    pub fn flush(&mut self) {
        self.rx.clear();
    }

    /// Bytes lost to a full receive buffer.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loop_back_in_order_with_overrun_count() {
        let mut p = AuxSerial::default();
        p.transmit(b"hello");
        assert_eq!(p.available(), 5);
        assert_eq!(p.receive(3), b"hel");
        assert_eq!(p.receive(10), b"lo");
        p.transmit(&vec![b'x'; AUX_BUFFER + 3]);
        assert_eq!(p.overruns(), 3);
        p.flush();
        assert_eq!(p.available(), 0);
    }
}
