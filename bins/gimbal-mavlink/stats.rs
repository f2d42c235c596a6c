//! The counters of what came in (TCP, UDP and serial alike) and what
//! became of it, printed at exit; and the warnings that survive a flood
//! (`sagebrush_host::throttle`, gcud's own: at most `BURST` lines of one
//! kind from one place per `WINDOW`, the rest counted and summed up in one
//! line).

use std::fmt::Display;
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
    /// Requests refused for their content (out of travel, infinite, bad
    /// parameter, control given to a component never heard).
    pub refused: AtomicU64,
    /// Requests from a component that does not hold control, or that gcud
    /// refused by its rules (another link holds the gimbal, a limit, a zone).
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
    /// With signing on (`signing`): frames refused unsigned, signed with
    /// another key, or with a timestamp not newer than their stream's.
    pub unsigned: AtomicU64,
    pub bad_signature: AtomicU64,
    pub stale_signature: AtomicU64,
}

pub use sagebrush_host::throttle::{flush_warnings, may_warn};

/// The address part of a peer's name (`IP:PORT`, or a serial device):
/// where a peer's warnings are counted, whatever its source port.
pub fn peer_ip(peer: &str) -> &str {
    peer.parse::<std::net::SocketAddr>()
        .map_or(peer, |_| peer.rsplit_once(':').map_or(peer, |(ip, _)| ip))
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
             unsigned={} bad_signature={} stale_signature={} warnings_suppressed={}",
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
            g(&self.unsigned),
            g(&self.bad_signature),
            g(&self.stale_signature),
            sagebrush_host::throttle::suppressed(),
        )
    }
}
