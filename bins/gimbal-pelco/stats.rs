//! The door's counters (logged at exit) and its log gate: a warning of one
//! kind about one keyboard at most once per [`LOG_EVERY`], the others
//! counted and named in the next line (a flood writes a bounded log).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{LazyLock, Mutex};
use std::time::Duration;

use sagebrush_service::rate::LogGate;
use tokio::time::Instant;

/// A kind of line about one keyboard is written at most this often.
pub const LOG_EVERY: Duration = Duration::from_secs(10);
/// Keyboards the gate remembers at once (beyond, stale ones are forgotten).
const LOGGED: usize = 1024;

static GATE: LazyLock<Mutex<LogGate<(&'static str, String)>>> =
    LazyLock::new(|| Mutex::new(LogGate::new(LOG_EVERY, LOGGED)));

/// `Some(held back since the last one)` when a line of `kind` about
/// `place` may be written now.
pub fn may_log(kind: &'static str, place: &str) -> Option<u64> {
    GATE.lock()
        .unwrap_or_else(|p| p.into_inner())
        .allow(&(kind, place.to_owned()), Instant::now())
}

#[derive(Debug, Default)]
pub struct Stats {
    /// Intact frames read.
    pub frames: AtomicU64,
    /// Runs of bytes that were no intact frame, and their bytes.
    pub skipped_runs: AtomicU64,
    pub skipped_bytes: AtomicU64,
    /// Intact frames whose check byte was wrong (a run of skipped bytes
    /// that began at a sync byte).
    pub bad_checksums: AtomicU64,
    /// Frames for an address no `[[gimbal]]` has.
    pub not_ours: AtomicU64,
    /// Extended commands the door does not carry out.
    pub unsupported: AtomicU64,
    /// Stops of a keyboard that had started nothing since its last stop.
    pub stops_not_sent: AtomicU64,
    /// Requests dropped for a keyboard with too many waiting.
    pub dropped_busy: AtomicU64,
    /// Requests gcud refused by its rules.
    pub refused: AtomicU64,
    /// TCP connections refused or closed by the bounded listener's table,
    /// and UDP sources forgotten for a newer one.
    pub udp_sources_forgotten: AtomicU64,
}

impl Stats {
    pub fn count(counter: &AtomicU64) {
        counter.fetch_add(1, Ordering::Relaxed);
    }

    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    /// The counters, one `name=value` each, for the line at exit.
    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "frames={} skipped_runs={} skipped_bytes={} bad_checksums={} not_ours={} unsupported={} stops_not_sent={} dropped_busy={} refused={} udp_sources_forgotten={}",
            g(&self.frames),
            g(&self.skipped_runs),
            g(&self.skipped_bytes),
            g(&self.bad_checksums),
            g(&self.not_ours),
            g(&self.unsupported),
            g(&self.stops_not_sent),
            g(&self.dropped_busy),
            g(&self.refused),
            g(&self.udp_sources_forgotten),
        )
    }
}
