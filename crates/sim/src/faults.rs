//! Seeded, deterministic fault injection on a simulated bus: the line
//! troubles 1.4.2 provides for (lost or damaged bytes, answered by NAK and
//! retransmission) and a slow or absent device.
//!
//! One draw per frame addressed to a device of the bus, in arrival order, so
//! a seed reproduces a run exactly.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

sagebrush_protocol::code_table! {
    /// A fault applied to one exchange; its code indexes the per-fault counters.
    pub enum Fault: u8 {
        /// the ACK is lost on the way back (what follows it still goes)
        DropAck,
        /// the command arrives damaged: the device answers NAK and does not execute it
        Nak,
        /// one byte of the answer is damaged (a payload byte of the result, or the ACK)
        Corrupt,
        /// the answer leaves late by `FaultConfig::delay_ms`
        Delay,
        /// the device does not hear the command at all: no answer
        Silent,
    }
}

impl Fault {
    const fn index(self) -> usize {
        self.code() as usize
    }
}

/// Probabilities (0.0..=1.0) of each fault per frame, the seed, and an
/// optional cap on the number of faults (so a test can ask for exactly the
/// first N exchanges to be hit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultConfig {
    pub seed: u64,
    pub drop_ack: f64,
    pub nak: f64,
    pub corrupt: f64,
    pub delay: f64,
    pub silent: f64,
    /// How late a delayed answer leaves, in milliseconds.
    pub delay_ms: u64,
    /// Most faults injected in all; `None` for no cap.
    pub max_faults: Option<u64>,
}

impl Default for FaultConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            drop_ack: 0.0,
            nak: 0.0,
            corrupt: 0.0,
            delay: 0.0,
            silent: 0.0,
            delay_ms: 500,
            max_faults: None,
        }
    }
}

impl FaultConfig {
    fn probability(&self, fault: Fault) -> f64 {
        match fault {
            Fault::DropAck => self.drop_ack,
            Fault::Nak => self.nak,
            Fault::Corrupt => self.corrupt,
            Fault::Delay => self.delay,
            Fault::Silent => self.silent,
        }
    }

    /// Whether any fault can happen.
    pub fn is_active(&self) -> bool {
        Fault::ALL.iter().any(|f| self.probability(*f) > 0.0) && self.max_faults != Some(0)
    }

    /// Checks every probability is within 0..=1.
    pub fn validate(&self) -> Result<(), String> {
        for f in Fault::ALL {
            let p = self.probability(f);
            if !(0.0..=1.0).contains(&p) {
                return Err(format!("fault probability {} = {p} is not within 0..=1", f.name()));
            }
        }
        Ok(())
    }
}

/// The fault generator of one bus.
#[derive(Debug)]
pub struct Faults {
    config: FaultConfig,
    rng: ChaCha8Rng,
    injected: [u64; Fault::ALL.len()],
}

impl Faults {
    pub fn new(config: FaultConfig) -> Self {
        Self {
            config,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            injected: [0; Fault::ALL.len()],
        }
    }

    pub fn config(&self) -> &FaultConfig {
        &self.config
    }

    fn total(&self) -> u64 {
        self.injected.iter().sum()
    }

    fn capped(&self) -> bool {
        self.config.max_faults.is_some_and(|max| self.total() >= max)
    }

    /// The fault for the next exchange, if any. Kinds are tried in the order
    /// of [`Fault::ALL`]; the first whose draw hits is the one.
    pub fn draw(&mut self) -> Option<Fault> {
        if !self.config.is_active() || self.capped() {
            return None;
        }
        for fault in Fault::ALL {
            let p = self.config.probability(fault);
            if p > 0.0 && self.rng.random_bool(p) {
                self.injected[fault.index()] += 1;
                return Some(fault);
            }
        }
        None
    }

    /// Whether a retransmitted result is damaged again (the corrupt probability).
    pub fn draw_corrupt(&mut self) -> bool {
        let p = self.config.corrupt;
        if p > 0.0 && !self.capped() && self.rng.random_bool(p) {
            self.injected[Fault::Corrupt.index()] += 1;
            return true;
        }
        false
    }

    /// An index below `len` (which byte to damage).
    pub fn pick(&mut self, len: usize) -> usize {
        if len <= 1 { 0 } else { self.rng.random_range(0..len) }
    }

    /// Faults injected so far, by kind.
    pub fn injected(&self, fault: Fault) -> u64 {
        self.injected[fault.index()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_faults_and_cap_holds() {
        let config = FaultConfig {
            seed: 7,
            corrupt: 0.3,
            drop_ack: 0.2,
            ..FaultConfig::default()
        };
        let a: Vec<_> = {
            let mut f = Faults::new(config);
            (0..100).map(|_| f.draw()).collect()
        };
        let b: Vec<_> = {
            let mut f = Faults::new(config);
            (0..100).map(|_| f.draw()).collect()
        };
        assert_eq!(a, b);
        assert!(a.contains(&Some(Fault::Corrupt)) && a.contains(&Some(Fault::DropAck)) && a.contains(&None));

        let mut capped = Faults::new(FaultConfig {
            silent: 1.0,
            max_faults: Some(2),
            ..FaultConfig::default()
        });
        let draws: Vec<_> = (0..5).map(|_| capped.draw()).collect();
        assert_eq!(draws, [Some(Fault::Silent), Some(Fault::Silent), None, None, None]);
        assert_eq!(capped.injected(Fault::Silent), 2);
    }

    #[test]
    fn probabilities_are_validated() {
        let bad = FaultConfig {
            nak: 1.5,
            ..FaultConfig::default()
        };
        assert!(bad.validate().unwrap_err().contains("nak"));
    }
}
