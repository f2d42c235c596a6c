//! What came in and what became of it, printed at exit, and the warnings
//! that survive a flood (`sagebrush_host::throttle`, gcud's own: a few
//! lines of one kind from one place per window, the rest summed up).

use std::sync::atomic::{AtomicU64, Ordering};

/// What came in, by fate.
#[derive(Debug, Default)]
pub struct Stats {
    /// VISCA messages read (commands and inquiries).
    pub received: AtomicU64,
    /// Datagrams or messages that were not VISCA (dropped or answered with an error).
    pub malformed: AtomicU64,
    /// Messages answered with a syntax error (not implemented here).
    pub syntax: AtomicU64,
    /// Datagrams answered "abnormality in the sequence number".
    pub out_of_sequence: AtomicU64,
    /// Commands not carried out (gcud refused, the gimbal failed): `90 61 41 FF`.
    pub not_executed: AtomicU64,
    /// Commands answered "command buffer full".
    pub busy: AtomicU64,
    /// TCP connections refused or closed by the bounded listener.
    pub tcp_refused: AtomicU64,
}

pub use sagebrush_host::throttle::{flush_warnings, may_warn};

impl Stats {
    pub fn count(counter: &AtomicU64) -> u64 {
        counter.fetch_add(1, Ordering::Relaxed) + 1
    }

    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "received={} malformed={} syntax={} out_of_sequence={} not_executed={} busy={} tcp_refused={} warnings_suppressed={}",
            g(&self.received),
            g(&self.malformed),
            g(&self.syntax),
            g(&self.out_of_sequence),
            g(&self.not_executed),
            g(&self.busy),
            g(&self.tcp_refused),
            sagebrush_host::throttle::suppressed(),
        )
    }
}
