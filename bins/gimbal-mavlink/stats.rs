//! The counters of what came in (TCP, UDP and serial alike) and what
//! became of it, printed at exit; and the warnings that survive a flood
//! ([`Throttle`], gcud's rule: at most [`BURST`] lines of one kind from one
//! place per [`WINDOW`], the rest counted and summed up in one line).

use std::collections::HashMap;
use std::fmt::Display;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{LazyLock, Mutex};
use std::time::{Duration, Instant};

use tracing::warn;

/// Lines of one kind and place written per window before the rest is counted.
pub const BURST: u32 = 10;
/// The window.
pub const WINDOW: Duration = Duration::from_secs(10);
/// Kinds and places tracked at once; beyond, new places share one window
/// per kind (so a flood from ever new addresses stays bounded too).
const MAX_KEYS: usize = 256;
/// The place of those.
const OTHER_PLACES: &str = "other places";

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
    /// Requests refused for their content (out of travel, infinite, bad
    /// parameter, control given to a component never heard).
    pub refused: AtomicU64,
    /// Requests from a component that does not hold control.
    pub denied: AtomicU64,
    /// Requests gcud or the gimbal did not carry out.
    pub failed: AtomicU64,
    /// Requests dropped because the gimbal's queue was full.
    pub busy: AtomicU64,
    /// Commands answered MAV_RESULT_UNSUPPORTED (also counted as ignored).
    pub unsupported: AtomicU64,
    /// UDP datagrams from a new address while every peer slot held one
    /// heard recently: dropped.
    pub udp_refused: AtomicU64,
    /// TCP connections closed for a newcomer (idle the longest), for
    /// their idle time-out, or refused (every one busy, or the peer's cap).
    pub tcp_evicted: AtomicU64,
    pub tcp_idle_closed: AtomicU64,
    pub tcp_refused: AtomicU64,
}

/// The process's throttle: logging is process-wide, and so is its limit
/// (every receiver, the router and the status task share it).
static THROTTLE: LazyLock<Mutex<Throttle>> = LazyLock::new(Mutex::default);
/// Warnings not written.
static SUPPRESSED: AtomicU64 = AtomicU64::new(0);

/// Whether a warning of `kind` about `place` (an address, a gimbal) may be
/// written now: [`BURST`] per [`WINDOW`], the rest counted and summed up
/// once the window ends. Use as `if may_warn(KIND, &place) { warn!(...) }`.
pub fn may_warn(kind: &'static str, place: &dyn Display) -> bool {
    let now = Instant::now();
    let mut t = THROTTLE.lock().unwrap_or_else(|p| p.into_inner());
    t.flush(now);
    let allowed = t.allow(kind, &place.to_string(), now);
    if !allowed {
        SUPPRESSED.fetch_add(1, Ordering::Relaxed);
    }
    allowed
}

/// Writes the summaries of the windows that ended (called periodically,
/// so that the last one of a flood is not held back).
pub fn flush_warnings() {
    THROTTLE.lock().unwrap_or_else(|p| p.into_inner()).flush(Instant::now());
}

impl Stats {
    pub fn count(counter: &AtomicU64) -> u64 {
        counter.fetch_add(1, Ordering::Relaxed) + 1
    }

    /// Counts a datagram (UDP) or run (TCP, serial) of `bytes` bytes from
    /// `from` without an intact frame; logged throttled.
    pub fn damaged(&self, from: &dyn Display, bytes: usize) {
        self.damaged_bytes.fetch_add(bytes as u64, Ordering::Relaxed);
        let total = Self::count(&self.damaged);
        if may_warn("bytes without an intact MAVLink frame ignored", from) {
            warn!(%from, bytes, total, "bytes without an intact MAVLink frame ignored");
        }
    }

    pub fn summary(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "received={} damaged={} damaged_bytes={} ignored={} refused={} denied={} failed={} busy={} \
             unsupported={} udp_refused={} tcp_evicted={} tcp_idle_closed={} tcp_refused={} \
             warnings_suppressed={}",
            g(&self.received),
            g(&self.damaged),
            g(&self.damaged_bytes),
            g(&self.ignored),
            g(&self.refused),
            g(&self.denied),
            g(&self.failed),
            g(&self.busy),
            g(&self.unsupported),
            g(&self.udp_refused),
            g(&self.tcp_evicted),
            g(&self.tcp_idle_closed),
            g(&self.tcp_refused),
            SUPPRESSED.load(Ordering::Relaxed),
        )
    }
}

#[derive(Debug)]
struct Window {
    start: Instant,
    written: u32,
    suppressed: u64,
}

/// Per (kind, place) windows, as gcud's `throttle`.
#[derive(Debug, Default)]
pub struct Throttle {
    windows: HashMap<(&'static str, String), Window>,
}

impl Throttle {
    /// Whether a line of `kind` about `place` may be written at `now`; if
    /// not, it is counted for the window's summary.
    fn allow(&mut self, kind: &'static str, place: &str, now: Instant) -> bool {
        let mut key = (kind, place.to_owned());
        if self.windows.len() >= MAX_KEYS - 1 && !self.windows.contains_key(&key) {
            key.1 = OTHER_PLACES.to_owned();
        }
        let w = self.windows.entry(key).or_insert(Window {
            start: now,
            written: 0,
            suppressed: 0,
        });
        if w.written < BURST {
            w.written += 1;
            return true;
        }
        w.suppressed += 1;
        false
    }

    /// The windows that ended by `now`, summed up (one line each that
    /// suppressed anything) and forgotten.
    fn summaries(&mut self, now: Instant) -> Vec<(&'static str, String, u64)> {
        let mut out = Vec::new();
        self.windows.retain(|(kind, place), w| {
            let ended = now.duration_since(w.start) >= WINDOW;
            if ended && w.suppressed > 0 {
                out.push((*kind, place.clone(), w.suppressed));
            }
            !ended
        });
        out
    }

    fn flush(&mut self, now: Instant) {
        for (kind, place, suppressed) in self.summaries(now) {
            warn!(
                place,
                suppressed,
                window_s = WINDOW.as_secs(),
                "{kind} (repeated {suppressed} more times, not logged)"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_is_a_burst_then_one_summary_per_window() {
        let mut t = Throttle::default();
        let t0 = Instant::now();
        let written = (0..1000).filter(|_| t.allow("refused", "10.0.0.1", t0)).count();
        assert_eq!(written, BURST as usize);
        assert!(t.allow("refused", "10.0.0.2", t0), "another place has its own burst");
        assert!(t.summaries(t0 + WINDOW / 2).is_empty(), "the window is still open");
        assert_eq!(
            t.summaries(t0 + WINDOW),
            vec![("refused", "10.0.0.1".to_owned(), 990)],
            "one summary, only of what was suppressed"
        );
        assert!(t.allow("refused", "10.0.0.1", t0 + WINDOW), "a new window");
    }

    #[test]
    fn ever_new_places_stay_bounded() {
        let mut t = Throttle::default();
        let t0 = Instant::now();
        let written = (0..100_000)
            .filter(|i| t.allow("refused", &format!("127.0.0.1:{i}"), t0))
            .count();
        assert_eq!(
            written,
            MAX_KEYS - 1 + BURST as usize,
            "the places beyond share one window"
        );
        assert!(t.windows.len() <= MAX_KEYS);
    }
}
