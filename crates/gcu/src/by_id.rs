//! Commands in flight by id, in a ring that keeps its capacity: ids are
//! handed out in increasing order, so entries are appended and stay
//! sorted, and a routed command costs no allocation once the ring has
//! grown (ARCHITECTURE "Data path"), where a `BTreeMap` allocates a node
//! each time it goes from empty to one entry. A removed entry leaves a
//! hole, dropped once it reaches the front or when holes outnumber the
//! entries: removing from the middle of a vector moved every later entry,
//! a cost that grew with the commands in flight (ARCHITECTURE "Scale").

use std::collections::VecDeque;

use crate::CommandId;

/// A map from command id to `V`, sorted by id.
#[derive(Debug)]
pub(crate) struct ById<V> {
    /// Sorted by id; `None`: a hole where an entry was removed.
    entries: VecDeque<(CommandId, Option<V>)>,
    /// The entries that are not holes.
    live: usize,
}

/// Holes beyond the live entries that a removal tolerates before it
/// drops them all (amortized: at most one pass per as many removals).
const SLACK: usize = 32;

impl<V> ById<V> {
    pub fn new() -> Self {
        Self {
            entries: VecDeque::new(),
            live: 0,
        }
    }

    fn find(&self, id: &CommandId) -> Result<usize, usize> {
        self.entries.binary_search_by_key(id, |(k, _)| *k)
    }

    /// Adds or replaces the entry of `id`.
    pub fn insert(&mut self, id: CommandId, value: V) {
        if self.entries.back().is_none_or(|(last, _)| *last < id) {
            self.entries.push_back((id, Some(value)));
            self.live += 1;
            return;
        }
        match self.find(&id) {
            Ok(at) => {
                if self.entries[at].1.replace(value).is_none() {
                    self.live += 1;
                }
            }
            Err(at) => {
                self.entries.insert(at, (id, Some(value)));
                self.live += 1;
            }
        }
    }

    pub fn remove(&mut self, id: &CommandId) -> Option<V> {
        let at = self.find(id).ok()?;
        let value = self.entries[at].1.take()?;
        self.live -= 1;
        while self.entries.front().is_some_and(|(_, v)| v.is_none()) {
            self.entries.pop_front();
        }
        if self.entries.len() > 2 * self.live + SLACK {
            self.entries.retain(|(_, v)| v.is_some());
        }
        Some(value)
    }

    pub fn get(&self, id: &CommandId) -> Option<&V> {
        let at = self.find(id).ok()?;
        self.entries[at].1.as_ref()
    }

    pub fn get_mut(&mut self, id: &CommandId) -> Option<&mut V> {
        let at = self.find(id).ok()?;
        self.entries[at].1.as_mut()
    }

    #[cfg(test)]
    pub fn contains_key(&self, id: &CommandId) -> bool {
        self.get(id).is_some()
    }

    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.live
    }

    pub fn iter(&self) -> impl Iterator<Item = (&CommandId, &V)> {
        self.entries.iter().filter_map(|(k, v)| Some((k, v.as_ref()?)))
    }

    pub fn values(&self) -> impl Iterator<Item = &V> {
        self.entries.iter().filter_map(|(_, v)| v.as_ref())
    }

    pub fn retain(&mut self, mut keep: impl FnMut(&CommandId, &mut V) -> bool) {
        self.entries
            .retain_mut(|(k, v)| v.as_mut().is_some_and(|value| keep(k, value)));
        self.live = self.entries.len();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorted_by_id_whatever_the_insertion_order() {
        let mut map = ById::new();
        for id in [3, 1, 2, 5] {
            map.insert(CommandId(id), id * 10);
        }
        map.insert(CommandId(2), 22);
        assert_eq!(map.remove(&CommandId(1)), Some(10));
        assert_eq!(map.remove(&CommandId(1)), None);
        *map.get_mut(&CommandId(3)).unwrap() += 1;
        assert!(map.contains_key(&CommandId(5)) && !map.contains_key(&CommandId(4)));
        assert_eq!(map.len(), 3);
        map.retain(|id, _| id.0 != 5);
        let left: Vec<_> = map.iter().map(|(k, v)| (k.0, *v)).collect();
        assert_eq!(left, [(2, 22), (3, 31)]);
        assert_eq!(map.values().count(), 2);
    }

    /// Against a `BTreeMap` through random inserts, removals (most from the
    /// middle, as commands finish out of order) and retains: the same
    /// entries in the same order, and the holes bounded.
    #[test]
    fn holes_left_by_removals_change_nothing_seen_and_stay_bounded() {
        let mut map = ById::new();
        let mut model = std::collections::BTreeMap::new();
        let mut next = 0u64;
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut random = move |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        for step in 0..20_000u64 {
            match random(10) {
                0..=4 => {
                    map.insert(CommandId(next), step);
                    model.insert(next, step);
                    next += 1;
                }
                5..=8 if !model.is_empty() => {
                    let id = *model.keys().nth(random(model.len() as u64) as usize).unwrap();
                    assert_eq!(map.remove(&CommandId(id)), model.remove(&id));
                    assert_eq!(map.remove(&CommandId(id)), None);
                }
                9 => {
                    let id = random(next.max(1));
                    map.insert(CommandId(id), step);
                    model.insert(id, step);
                    if step % 50 == 0 {
                        map.retain(|k, _| k.0 % 7 != 0);
                        model.retain(|k, _| k % 7 != 0);
                    }
                }
                _ => {}
            }
            assert_eq!(map.len(), model.len());
            assert!(map.entries.len() <= 2 * model.len() + SLACK + 1, "holes bounded");
        }
        let seen: Vec<_> = map.iter().map(|(k, v)| (k.0, *v)).collect();
        let expected: Vec<_> = model.iter().map(|(k, v)| (*k, *v)).collect();
        assert_eq!(seen, expected);
        for (k, v) in &model {
            assert_eq!(map.get(&CommandId(*k)), Some(v));
        }
    }
}
