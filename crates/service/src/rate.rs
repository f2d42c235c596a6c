//! Rates a door may spend on one source: token buckets (one, or one per
//! key with a bounded number of keys), and a gate that lets a warning
//! about a key through at most once per interval while counting the rest.

use std::collections::HashMap;
use std::hash::Hash;
use std::time::Duration;

use tokio::time::Instant;

/// A token bucket: `rate` tokens a second, at most `burst` saved up.
#[derive(Debug, Clone, Copy)]
pub struct TokenBucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    at: Instant,
}

impl TokenBucket {
    /// A full bucket.
    pub fn new(rate: f64, burst: f64, now: Instant) -> Self {
        Self {
            rate,
            burst,
            tokens: burst,
            at: now,
        }
    }

    fn refill(&mut self, now: Instant) {
        let elapsed = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + elapsed * self.rate).min(self.burst);
        self.at = now;
    }

    /// Takes one token if there is one.
    pub fn take(&mut self, now: Instant) -> bool {
        self.refill(now);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }

    /// Whether the bucket is full again (nothing to remember about it).
    pub fn is_full(&mut self, now: Instant) -> bool {
        self.refill(now);
        self.tokens >= self.burst
    }
}

/// One [`TokenBucket`] per key, at most `max_keys` keys: a key whose
/// bucket refilled is forgotten first; when every bucket is in use, a new
/// key is refused (the state stays bounded whoever sends).
#[derive(Debug)]
pub struct KeyedBuckets<K> {
    rate: f64,
    burst: f64,
    max_keys: usize,
    buckets: HashMap<K, TokenBucket>,
}

impl<K: Hash + Eq + Clone> KeyedBuckets<K> {
    pub fn new(rate: f64, burst: f64, max_keys: usize) -> Self {
        Self {
            rate,
            burst,
            max_keys: max_keys.max(1),
            buckets: HashMap::new(),
        }
    }

    /// Takes one token from `key`'s bucket if there is one.
    pub fn take(&mut self, key: &K, now: Instant) -> bool {
        if !self.buckets.contains_key(key) && self.buckets.len() >= self.max_keys {
            self.buckets.retain(|_, b| !b.is_full(now));
            if self.buckets.len() >= self.max_keys {
                return false;
            }
        }
        let (rate, burst) = (self.rate, self.burst);
        self.buckets
            .entry(key.clone())
            .or_insert_with(|| TokenBucket::new(rate, burst, now))
            .take(now)
    }

    /// Keys remembered now.
    pub fn len(&self) -> usize {
        self.buckets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.buckets.is_empty()
    }
}

/// Lets a warning about a key through at most once per `every`; the
/// warnings held back in between are counted and handed to the next one
/// let through ("and 83 more since"). At most `max_keys` keys: beyond, the
/// stale ones are forgotten, and if none is, the warning goes through
/// (bookkeeping never hides a new source).
#[derive(Debug)]
pub struct LogGate<K> {
    every: Duration,
    max_keys: usize,
    keys: HashMap<K, (Instant, u64)>,
}

impl<K: Hash + Eq + Clone> LogGate<K> {
    pub fn new(every: Duration, max_keys: usize) -> Self {
        Self {
            every,
            max_keys: max_keys.max(1),
            keys: HashMap::new(),
        }
    }

    /// `Some(held back since the last one)` when a warning about `key` may
    /// be written now, `None` when it is held back (and counted).
    pub fn allow(&mut self, key: &K, now: Instant) -> Option<u64> {
        if let Some((at, held)) = self.keys.get_mut(key) {
            if now.saturating_duration_since(*at) < self.every {
                *held += 1;
                return None;
            }
            let since = *held;
            *at = now;
            *held = 0;
            return Some(since);
        }
        if self.keys.len() >= self.max_keys {
            let every = self.every;
            self.keys
                .retain(|_, (at, _)| now.saturating_duration_since(*at) < every);
        }
        if self.keys.len() < self.max_keys {
            self.keys.insert(key.clone(), (now, 0));
        }
        Some(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bucket_gives_its_burst_then_its_rate() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(10.0, 5.0, t0);
        assert_eq!((0..20).filter(|_| b.take(t0)).count(), 5);
        let t1 = t0 + Duration::from_secs(2);
        assert_eq!((0..100).filter(|_| b.take(t1)).count(), 5, "capped at the burst");
        let t2 = t1 + Duration::from_millis(300);
        assert_eq!((0..100).filter(|_| b.take(t2)).count(), 3);
    }

    #[test]
    fn keyed_buckets_stay_bounded_and_forget_refilled_keys_first() {
        let t0 = Instant::now();
        let mut k = KeyedBuckets::new(1.0, 1.0, 2);
        assert!(k.take(&1, t0));
        assert!(k.take(&2, t0));
        assert!(!k.take(&1, t0), "its one token is spent");
        assert!(!k.take(&3, t0), "every bucket in use: a new key is refused");
        let t1 = t0 + Duration::from_secs(2);
        assert!(k.take(&3, t1), "refilled buckets are forgotten for it");
        assert!(k.len() <= 2);
    }

    #[test]
    fn a_gate_lets_one_line_through_per_interval_and_counts_the_rest() {
        let t0 = Instant::now();
        let mut g = LogGate::new(Duration::from_secs(10), 8);
        assert_eq!(g.allow(&"a", t0), Some(0));
        assert_eq!(g.allow(&"a", t0), None);
        assert_eq!(g.allow(&"a", t0), None);
        assert_eq!(g.allow(&"b", t0), Some(0), "another key is not held back");
        assert_eq!(g.allow(&"a", t0 + Duration::from_secs(10)), Some(2));
    }
}
