//! Ports and links by id, with their deadlines indexed (ARCHITECTURE
//! "Scale"): the earliest deadline and the lines due now are found without
//! walking every port and link, so that a turn's cost follows the lines
//! with work, not the lines configured (254 ports idle but one cost the
//! busy one a walk of 254 at every input before).
//!
//! Every change to a value goes through [`TimedMut`], which reads the
//! value's deadline again when it is dropped; reading needs no guard (the
//! map derefs to its `BTreeMap`). The index is a min-heap of (deadline,
//! key) whose entries go stale when a value's deadline moves: an entry
//! counts while the value's deadline is still the entry's, stale ones are
//! dropped from the top as they surface, and the heap is rebuilt when they
//! outnumber the values (its capacity kept: no allocation per change once
//! it has grown).

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::ops::{Deref, DerefMut};

/// A value with a deadline (a tick in ms), if it has one.
pub(crate) trait Deadline {
    fn next_deadline(&self) -> Option<u64>;
}

/// Values by key, their deadlines indexed.
#[derive(Debug)]
pub(crate) struct Timed<K: Ord + Copy, V: Deadline> {
    values: BTreeMap<K, V>,
    /// Each value's deadline when it was last changed.
    deadlines: BTreeMap<K, Option<u64>>,
    heap: BinaryHeap<Reverse<(u64, K)>>,
    /// Keys taken off the heap as due by [`Timed::next_due`] and not yet
    /// put back: each value with a deadline is on the heap or here.
    due: Vec<K>,
}

impl<K: Ord + Copy, V: Deadline> Deref for Timed<K, V> {
    type Target = BTreeMap<K, V>;

    fn deref(&self) -> &Self::Target {
        &self.values
    }
}

impl<K: Ord + Copy, V: Deadline> FromIterator<(K, V)> for Timed<K, V> {
    fn from_iter<I: IntoIterator<Item = (K, V)>>(iter: I) -> Self {
        let mut timed = Self::new();
        for (k, v) in iter {
            timed.insert(k, v);
        }
        timed
    }
}

impl<K: Ord + Copy, V: Deadline> Timed<K, V> {
    pub fn new() -> Self {
        Self {
            values: BTreeMap::new(),
            deadlines: BTreeMap::new(),
            heap: BinaryHeap::new(),
            due: Vec::new(),
        }
    }

    /// The value at `key`, to change: its deadline is read again once the
    /// guard is dropped.
    pub fn get_mut(&mut self, key: &K) -> Option<TimedMut<'_, K, V>> {
        let Self {
            values,
            deadlines,
            heap,
            ..
        } = self;
        let value = values.get_mut(key)?;
        Some(TimedMut {
            key: *key,
            value,
            index: Index { deadlines, heap },
        })
    }

    pub fn insert(&mut self, key: K, value: V) -> Option<V> {
        let old = self.values.insert(key, value);
        self.deadlines.insert(key, None);
        if let Some(v) = self.get_mut(&key) {
            drop(v); // indexes its deadline
        }
        old
    }

    pub fn remove(&mut self, key: &K) -> Option<V> {
        self.deadlines.remove(key);
        let old = self.values.remove(key);
        Index {
            deadlines: &mut self.deadlines,
            heap: &mut self.heap,
        }
        .drop_stale();
        old
    }

    /// Runs `f` on every value, in key order (a reload, a priority change).
    pub fn for_each_mut(&mut self, mut f: impl FnMut(&K, &mut V)) {
        let keys: Vec<K> = self.values.keys().copied().collect();
        for k in keys {
            if let Some(mut v) = self.get_mut(&k) {
                f(&k, &mut v);
            }
        }
    }

    /// The earliest deadline of any value.
    pub fn earliest(&self) -> Option<u64> {
        let heap = self.heap.peek().map(|Reverse((t, _))| *t);
        let due = self
            .due
            .iter()
            .filter_map(|k| self.deadlines.get(k).copied().flatten())
            .min();
        heap.into_iter().chain(due).min()
    }

    /// The first key after `after` (from the first with `None`) whose
    /// value is due by `now`: what walking the values in key order for
    /// the next due one finds, without the walk.
    pub fn next_due(&mut self, now: u64, after: Option<K>) -> Option<K> {
        let Self {
            deadlines, heap, due, ..
        } = self;
        while let Some(&Reverse((t, k))) = heap.peek() {
            if t > now {
                break;
            }
            heap.pop();
            if deadlines.get(&k) == Some(&Some(t)) && !due.contains(&k) {
                due.push(k);
            }
        }
        // Keys no longer due are on the heap again (their change pushed them) or have no deadline.
        due.retain(|k| deadlines.get(k).copied().flatten().is_some_and(|t| t <= now));
        due.iter().copied().filter(|&k| after.is_none_or(|a| k > a)).min()
    }
}

/// The index of a [`Timed`], borrowed apart from its values.
#[derive(Debug)]
struct Index<'a, K: Ord + Copy> {
    deadlines: &'a mut BTreeMap<K, Option<u64>>,
    heap: &'a mut BinaryHeap<Reverse<(u64, K)>>,
}

impl<K: Ord + Copy> Index<'_, K> {
    fn set(&mut self, key: K, deadline: Option<u64>) {
        if let Some(slot) = self.deadlines.get_mut(&key) {
            if *slot != deadline {
                *slot = deadline;
                if let Some(t) = deadline {
                    self.heap.push(Reverse((t, key)));
                }
            }
        }
        self.drop_stale();
    }

    /// Drops stale entries from the top; rebuilds the heap once they
    /// outnumber the values.
    fn drop_stale(&mut self) {
        let live = |deadlines: &BTreeMap<K, Option<u64>>, &Reverse((t, k)): &Reverse<(u64, K)>| {
            deadlines.get(&k) == Some(&Some(t))
        };
        while self.heap.peek().is_some_and(|e| !live(self.deadlines, e)) {
            self.heap.pop();
        }
        if self.heap.len() > 2 * self.deadlines.len() + 64 {
            self.heap.clear();
            for (&k, &t) in self.deadlines.iter() {
                if let Some(t) = t {
                    self.heap.push(Reverse((t, k)));
                }
            }
        }
    }
}

/// A value being changed; its deadline is indexed again when dropped.
#[derive(Debug)]
pub(crate) struct TimedMut<'a, K: Ord + Copy, V: Deadline> {
    key: K,
    value: &'a mut V,
    index: Index<'a, K>,
}

impl<K: Ord + Copy, V: Deadline> Deref for TimedMut<'_, K, V> {
    type Target = V;

    fn deref(&self) -> &V {
        self.value
    }
}

impl<K: Ord + Copy, V: Deadline> DerefMut for TimedMut<'_, K, V> {
    fn deref_mut(&mut self) -> &mut V {
        self.value
    }
}

impl<K: Ord + Copy, V: Deadline> Drop for TimedMut<'_, K, V> {
    fn drop(&mut self) {
        let deadline = self.value.next_deadline();
        self.index.set(self.key, deadline);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct At(Option<u64>);

    impl Deadline for At {
        fn next_deadline(&self) -> Option<u64> {
            self.0
        }
    }

    /// What walking every value finds.
    fn walked(t: &Timed<u8, At>, now: u64, after: Option<u8>) -> Option<u8> {
        t.iter()
            .find(|(k, v)| after.is_none_or(|a| **k > a) && v.0.is_some_and(|d| d <= now))
            .map(|(k, _)| *k)
    }

    #[test]
    fn finds_what_a_walk_finds_through_every_change() {
        let mut t: Timed<u8, At> = (0..40).map(|k| (k, At(None))).collect();
        // A seeded walk of changes, removals and due scans.
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for now in 0..5000u64 {
            let k = (next() % 48) as u8;
            match next() % 8 {
                0 => {
                    t.remove(&k);
                }
                1 => {
                    t.insert(k, At(Some(now + next() % 50)));
                }
                _ => {
                    if let Some(mut v) = t.get_mut(&k) {
                        v.0 = (next() % 4 != 0).then(|| now + next() % 50);
                    }
                }
            }
            let walk = t.values().filter_map(|v| v.0).min();
            assert_eq!(t.earliest(), walk, "the earliest deadline at {now}");
            let mut after = None;
            loop {
                let found = t.next_due(now, after);
                assert_eq!(found, walked(&t, now, after), "the next due after {after:?} at {now}");
                let Some(k) = found else { break };
                if next() % 2 == 0 {
                    if let Some(mut v) = t.get_mut(&k) {
                        v.0 = Some(now + 1 + next() % 10);
                    }
                }
                after = Some(k);
            }
            assert!(t.heap.len() <= 2 * t.len() + 65, "stale entries are bounded");
        }
    }
}
