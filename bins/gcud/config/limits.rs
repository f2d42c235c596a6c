//! `[limits]`: queues and connections.

use sagebrush_service::config_file::{Int, Millis, Source};
use serde::{Deserialize, Serialize};

use super::ConfigError;

/// `[limits]`, as written and as validated.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsSection {
    /// Commands waiting per port beyond the one in flight; more are dropped and counted.
    #[serde(default)]
    pub queue_depth: Int<usize, 1, 4096, 16>,
    /// Connections accepted at once over all TCP listeners; at the limit the
    /// one idle the longest is evicted for a newcomer.
    #[serde(default)]
    pub max_connections: Int<usize, 1, 4096, 32>,
    /// Connections one peer address may hold at once, at most
    /// `max_connections` (default: half of it, off this machine only).
    pub max_connections_per_peer: Option<Int<usize, 1, 4096>>,
    /// An accepted connection that sends nothing this long is closed.
    #[serde(default)]
    pub idle_timeout_ms: Millis<1_000, 86_400_000, 300_000>,
}

impl LimitsSection {
    /// `max_connections_per_peer` within `max_connections`.
    pub(super) fn validate(&self, c: &Source<'_>) -> Result<(), ConfigError> {
        let max = self.max_connections.get();
        match &self.max_connections_per_peer {
            Some(v) if v.get() > max => Err(c.at(
                v.span(),
                "limits.max_connections_per_peer",
                format!("expected an integer 1..={max}, found {}", v.get()),
            )),
            _ => Ok(()),
        }
    }

    /// Connections one peer may hold: `max_connections_per_peer`, or half
    /// of `max_connections`.
    pub fn per_peer(&self) -> usize {
        match &self.max_connections_per_peer {
            Some(v) => v.get(),
            None => (self.max_connections.get() / 2).max(1),
        }
    }

    /// The per-peer cap was configured: it applies to loopback peers too.
    pub fn per_peer_configured(&self) -> bool {
        self.max_connections_per_peer.is_some()
    }

    /// Commands that may wait on a port: every client that may connect can
    /// have a command waiting on every port (fair queuing drops a hog's
    /// work first).
    pub(super) fn port_queue_bound(&self) -> usize {
        self.queue_depth.get().max(self.max_connections.get())
    }
}
