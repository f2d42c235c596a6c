//! The counters of what came in (TCP, UDP and serial alike) and what
//! became of it, printed at exit.

use std::sync::atomic::{AtomicU64, Ordering};

use tracing::warn;

/// What came in, by fate.
#[derive(Debug, Default)]
pub struct Stats {
    /// Intact MAVLink messages.
    pub received: AtomicU64,
    /// Datagrams (UDP), or runs of bytes between intact frames (TCP,
    /// serial), in which no intact frame was found (damaged, not MAVLink).
    pub damaged: AtomicU64,
    /// The bytes of those datagrams and runs.
    pub damaged_bytes: AtomicU64,
    /// Intact messages that are not for this program or not handled here.
    pub ignored: AtomicU64,
    /// Requests refused for their content (out of travel, infinite, bad parameter).
    pub refused: AtomicU64,
    /// Requests from a component that does not hold control.
    pub denied: AtomicU64,
    /// Requests gcud or the gimbal did not carry out.
    pub failed: AtomicU64,
    /// Requests dropped because the gimbal's queue was full.
    pub busy: AtomicU64,
}

impl Stats {
    pub fn count(counter: &AtomicU64) -> u64 {
        counter.fetch_add(1, Ordering::Relaxed) + 1
    }

    /// Counts a datagram (UDP) or run (TCP, serial) of `bytes` bytes from
    /// `from` without an intact frame; logged while rare (the first ten,
    /// then at each power of two).
    pub fn damaged(&self, from: &dyn std::fmt::Display, bytes: usize) {
        self.damaged_bytes.fetch_add(bytes as u64, Ordering::Relaxed);
        let total = Self::count(&self.damaged);
        if total <= 10 || total.is_power_of_two() {
            warn!(%from, bytes, total, "bytes without an intact MAVLink frame ignored");
        }
    }

    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "received={} damaged={} damaged_bytes={} ignored={} refused={} denied={} failed={} busy={}",
            g(&self.received),
            g(&self.damaged),
            g(&self.damaged_bytes),
            g(&self.ignored),
            g(&self.refused),
            g(&self.denied),
            g(&self.failed),
            g(&self.busy)
        )
    }
}
