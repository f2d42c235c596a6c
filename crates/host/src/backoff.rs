//! The one back-off of every line, link and endpoint that is opened again
//! after it failed or closed (gcud's ports and links, gimbal-mavlink's
//! `tcp` and `serial` endpoints): 250 ms doubling to 10 s, back to 250 ms
//! once a line was open.

use std::time::Duration;

/// Exponential back-off: [`Backoff::FIRST`] doubling to [`Backoff::MAX`].
#[derive(Debug)]
pub struct Backoff(Duration);

impl Default for Backoff {
    fn default() -> Self {
        Self::new()
    }
}

impl Backoff {
    pub const FIRST: Duration = Duration::from_millis(250);
    pub const MAX: Duration = Duration::from_secs(10);

    pub fn new() -> Self {
        Self(Self::FIRST)
    }

    /// The line opened: the next failure waits [`Backoff::FIRST`] again.
    pub fn reset(&mut self) {
        self.0 = Self::FIRST;
    }

    /// How long to wait before the next attempt; each call doubles the next.
    pub fn next_delay(&mut self) -> Duration {
        let d = self.0;
        self.0 = (self.0 * 2).min(Self::MAX);
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubles_to_its_ceiling_and_starts_over_once_open() {
        let mut b = Backoff::new();
        let delays: Vec<u128> = (0..8).map(|_| b.next_delay().as_millis()).collect();
        assert_eq!(delays, [250, 500, 1000, 2000, 4000, 8000, 10_000, 10_000]);
        b.reset();
        assert_eq!(b.next_delay(), Backoff::FIRST);
    }
}
