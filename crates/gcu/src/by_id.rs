//! Commands in flight by id, in a vector that keeps its capacity: ids are
//! handed out in increasing order, so entries are appended and stay
//! sorted, and a routed command costs no allocation once the vector has
//! grown (ARCHITECTURE "Data path"), where a `BTreeMap` allocates a node
//! each time it goes from empty to one entry.

use crate::CommandId;

/// A map from command id to `V`, sorted by id.
#[derive(Debug)]
pub(crate) struct ById<V> {
    entries: Vec<(CommandId, V)>,
}

impl<V> ById<V> {
    pub fn new() -> Self {
        Self { entries: Vec::new() }
    }

    /// Adds or replaces the entry of `id`.
    pub fn insert(&mut self, id: CommandId, value: V) {
        match self.entries.binary_search_by_key(&id, |(k, _)| *k) {
            Ok(at) => self.entries[at].1 = value,
            Err(at) => self.entries.insert(at, (id, value)),
        }
    }

    pub fn remove(&mut self, id: &CommandId) -> Option<V> {
        let at = self.entries.binary_search_by_key(id, |(k, _)| *k).ok()?;
        Some(self.entries.remove(at).1)
    }

    pub fn get(&self, id: &CommandId) -> Option<&V> {
        let at = self.entries.binary_search_by_key(id, |(k, _)| *k).ok()?;
        Some(&self.entries[at].1)
    }

    pub fn get_mut(&mut self, id: &CommandId) -> Option<&mut V> {
        let at = self.entries.binary_search_by_key(id, |(k, _)| *k).ok()?;
        Some(&mut self.entries[at].1)
    }

    #[cfg(test)]
    pub fn contains_key(&self, id: &CommandId) -> bool {
        self.entries.binary_search_by_key(id, |(k, _)| *k).is_ok()
    }

    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn iter(&self) -> impl Iterator<Item = (&CommandId, &V)> {
        self.entries.iter().map(|(k, v)| (k, v))
    }

    pub fn values(&self) -> impl Iterator<Item = &V> {
        self.entries.iter().map(|(_, v)| v)
    }

    pub fn retain(&mut self, mut keep: impl FnMut(&CommandId, &mut V) -> bool) {
        self.entries.retain_mut(|(k, v)| keep(k, v));
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
}
