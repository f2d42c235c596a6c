//! File descriptors: at start gcud raises its soft `RLIMIT_NOFILE` to the
//! hard limit (systemd's `LimitNOFILE=`), and sizes the HTTP endpoint's
//! connection cap (module `http`) well below whatever it got, so that
//! scrapers, and anyone who connects to the endpoint, can never take the
//! descriptors its ports, links and client listener need (ARCHITECTURE
//! "Bounded and fair under load").

use nix::sys::resource::{Resource, getrlimit, setrlimit};

/// The HTTP endpoint's connections at most: a few scrapers, a dashboard
/// and a `gimbalctl gcud-status`.
pub const HTTP_CONNECTIONS: usize = 16;
/// Descriptors of the process itself, with room to spare.
const BASE: u64 = 32;
/// The HTTP endpoint gets at most this share of the descriptor limit.
const HTTP_SHARE: u64 = 8;

/// The descriptor limit at start: what it was, and what gcud runs with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limit {
    pub was: u64,
    pub now: u64,
}

impl Limit {
    /// Raises the soft limit to the hard one; on failure keeps it (and
    /// says so in `was == now`).
    pub fn raise() -> Self {
        let Ok((soft, hard)) = getrlimit(Resource::RLIMIT_NOFILE) else {
            return Self { was: 0, now: 0 };
        };
        let now = match soft < hard && setrlimit(Resource::RLIMIT_NOFILE, hard, hard).is_ok() {
            true => hard,
            false => soft,
        };
        Self { was: soft, now }
    }

    /// What the configuration may hold open at once, when the limit is
    /// below it: every accepted connection (`[limits] max_connections`), a
    /// descriptor per port and link, the HTTP endpoint's connections and
    /// [`BASE`] for the process itself (listeners, the runtime, logs,
    /// capture, simulated ports' pseudo-terminals).
    pub fn shortfall(&self, connections: u64, lines: u64, http: usize) -> Option<u64> {
        let needed = connections + lines + http as u64 + BASE;
        (self.now != 0 && self.now < needed).then_some(needed)
    }

    /// HTTP connections open at once: [`HTTP_CONNECTIONS`], or an eighth of
    /// the limit when that is less (at least 1).
    pub fn http_connections(&self) -> usize {
        match self.now {
            0 => HTTP_CONNECTIONS,
            n => usize::try_from(n / HTTP_SHARE)
                .unwrap_or(usize::MAX)
                .clamp(1, HTTP_CONNECTIONS),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_http_cap_stays_well_below_the_limit() {
        let cap = |now| Limit { was: now, now }.http_connections();
        assert_eq!(cap(1_048_576), HTTP_CONNECTIONS);
        assert_eq!(cap(64), 8);
        assert_eq!(cap(4), 1);
        assert_eq!(cap(0), HTTP_CONNECTIONS, "unknown limit");
    }

    #[test]
    fn a_limit_below_what_the_configuration_may_open_is_told() {
        let limit = Limit { was: 64, now: 64 };
        assert_eq!(limit.shortfall(32, 2, 8), Some(74));
        assert_eq!(limit.shortfall(16, 2, 8), None);
        assert_eq!(Limit { was: 0, now: 0 }.shortfall(32, 2, 8), None, "unknown limit");
    }
}
