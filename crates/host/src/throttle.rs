//! Logs that survive a flood, for gcud and the doors alike: repeated
//! warnings of one kind from one place (a port, a link, a peer's address,
//! a gimbal) are written at most [`BURST`] times per [`WINDOW`]; the rest
//! are counted and summarised once the window ends ("... repeated 83112
//! times in 10 s"). The places tracked are bounded: past [`MAX_KEYS`], new
//! places of a kind share one window. The metrics keep the exact numbers.

use std::collections::HashMap;
use std::fmt::{Display, Write as _};
use std::time::Duration;

use tokio::time::Instant;

/// Lines of one kind and place written per window before the rest is counted.
pub const BURST: u32 = 10;
/// The window.
pub const WINDOW: Duration = Duration::from_secs(10);
/// Kinds and places tracked at once; beyond, new places share one window.
pub const MAX_KEYS: usize = 4096;
/// The place of the window that places beyond [`MAX_KEYS`] share.
const OTHER_PLACES: &str = "other places";

#[derive(Debug)]
struct Window {
    start: Instant,
    written: u32,
    suppressed: u64,
    /// The last suppressed line, quoted in the summary (written in place).
    last: String,
}

/// Per (kind, place) windows. A line counted in a window that is already
/// open allocates nothing: its key is written into a buffer kept for it
/// and the window's last line into its own (issue 52: a flood of failed
/// deliveries cost gcud an allocation or more each).
#[derive(Debug, Default)]
pub struct Throttle {
    /// Keyed by kind and place, written `kind\u{1f}place`.
    windows: HashMap<String, Window>,
    /// The key of the line asked about.
    key: String,
}

impl Throttle {
    /// Whether a warning of `kind` at `place` may be written now; if not,
    /// it is counted (with its text `line`, for the summary).
    pub fn allow(&mut self, kind: &dyn Display, place: &dyn Display, line: &dyn Display, now: Instant) -> bool {
        self.key.clear();
        let _ = write!(self.key, "{kind}\u{1f}{place}");
        if !self.windows.contains_key(self.key.as_str()) {
            if self.windows.len() >= MAX_KEYS - 1 {
                self.key.clear();
                let _ = write!(self.key, "{kind}\u{1f}{OTHER_PLACES}");
            }
            if !self.windows.contains_key(self.key.as_str()) {
                let window = Window {
                    start: now,
                    written: 0,
                    suppressed: 0,
                    last: String::new(),
                };
                self.windows.insert(self.key.clone(), window);
            }
        }
        let w = self.windows.get_mut(self.key.as_str()).expect("inserted above");
        if w.written < BURST {
            w.written += 1;
            return true;
        }
        w.suppressed += 1;
        w.last.clear();
        let _ = write!(w.last, "{line}");
        false
    }

    /// Summaries of the windows that ended by `now` (and their reset).
    pub fn summaries(&mut self, now: Instant) -> Vec<String> {
        let mut out = Vec::new();
        self.windows.retain(|_, w| {
            let ended = now.duration_since(w.start) >= WINDOW;
            if ended && w.suppressed > 0 {
                out.push(format!(
                    "{} (repeated {} more times in {} s)",
                    w.last,
                    w.suppressed,
                    now.duration_since(w.start).as_secs()
                ));
            }
            !ended
        });
        out
    }

    /// When the next window ends, if any is open.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.windows.values().map(|w| w.start + WINDOW).min()
    }
}

/// The process's throttle, for a program whose warnings come from many
/// tasks (a door's receivers, router and status task share it): logging
/// is process-wide, and so is its limit.
static PROCESS: std::sync::LazyLock<std::sync::Mutex<Throttle>> = std::sync::LazyLock::new(Default::default);
/// Warnings the process's throttle did not write.
static SUPPRESSED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Whether a warning of `kind` about `place` (an address, a gimbal) may be
/// written now by the process's throttle: [`BURST`] per [`WINDOW`], the
/// rest counted and summed up once the window ends. Use as
/// `if may_warn(KIND, &place) { warn!(...) }`.
pub fn may_warn(kind: &'static str, place: &dyn Display) -> bool {
    let now = Instant::now();
    let mut t = PROCESS.lock().unwrap_or_else(|p| p.into_inner());
    flush(&mut t, now);
    let allowed = t.allow(&kind, place, &format_args!("{kind} ({place})"), now);
    if !allowed {
        SUPPRESSED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    allowed
}

/// Writes the summaries of the process's windows that ended (called
/// periodically, so that the last one of a flood is not held back).
pub fn flush_warnings() {
    flush(&mut PROCESS.lock().unwrap_or_else(|p| p.into_inner()), Instant::now());
}

/// Warnings the process's throttle has not written so far.
pub fn suppressed() -> u64 {
    SUPPRESSED.load(std::sync::atomic::Ordering::Relaxed)
}

fn flush(t: &mut Throttle, now: Instant) {
    for summary in t.summaries(now) {
        tracing::warn!(window_s = WINDOW.as_secs(), "{summary}, not logged");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_is_a_burst_and_one_summary_per_window() {
        let mut t = Throttle::default();
        let t0 = Instant::now();
        let written = (0..1000)
            .filter(|i| t.allow(&"dropped unsolicited", &"port 1", &format_args!("line {i}"), t0))
            .count();
        assert_eq!(written, BURST as usize);
        assert!(t.allow(&"dropped unsolicited", &"port 2", &"", t0), "another place");
        assert!(t.summaries(t0 + WINDOW / 2).is_empty(), "the window is still open");
        let summaries = t.summaries(t0 + WINDOW);
        assert_eq!(summaries, vec!["line 999 (repeated 990 more times in 10 s)".to_owned()]);
        assert!(
            t.allow(&"dropped unsolicited", &"port 1", &"", t0 + WINDOW),
            "a new window"
        );
    }

    #[test]
    fn ever_new_places_stay_bounded() {
        let mut t = Throttle::default();
        let t0 = Instant::now();
        let written = (0..100_000)
            .filter(|i| t.allow(&"refused", &format_args!("127.0.0.1:{i}"), &"", t0))
            .count();
        assert_eq!(
            written,
            MAX_KEYS - 1 + BURST as usize,
            "the places beyond share one window"
        );
        assert!(t.windows.len() <= MAX_KEYS);
    }
}
