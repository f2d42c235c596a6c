//! The bounded stop-first queue of ports and links (ARCHITECTURE "Bounded
//! and fair under load", "Safety"): stops and halts overtake queued work
//! and queue behind earlier stops only; work and stops are bounded apart,
//! so that a burst of work never costs a stop its place; the GCU's own
//! safety stops always fit (their number is bounded by the motions the
//! router tracks); an identical stop already waiting is found so that the
//! caller can merge or refuse the newcomer. What to do when work does not
//! fit (refuse it, or evict another origin's) is the caller's rule.

use std::collections::VecDeque;

/// What the queue needs to know of an item.
pub(crate) trait Queued {
    /// A stop or halt: ahead of work, bounded apart.
    fn is_stop(&self) -> bool;
    /// The GCU's own safety stop: never refused.
    fn always_fits(&self) -> bool;
    /// Same destination and payload.
    fn same_frame(&self, other: &Self) -> bool;
    /// A stop that cannot wait behind other stops (a slew about to reach a
    /// limit or zone): ahead of every waiting item.
    fn urgent(&self) -> bool {
        false
    }
}

#[derive(Debug)]
pub(crate) struct StopFirstQueue<T> {
    items: VecDeque<T>,
    work_bound: usize,
    stop_bound: usize,
    /// The head is on the wire (a link's frame in flight): nothing goes
    /// before it, and it is no longer a waiting stop.
    head_pinned: bool,
    high_water: usize,
}

impl<T: Queued> StopFirstQueue<T> {
    pub fn new(work_bound: usize, stop_bound: usize) -> Self {
        Self {
            items: VecDeque::new(),
            work_bound,
            stop_bound,
            head_pinned: false,
            high_water: 0,
        }
    }

    /// Where waiting items start.
    fn first_waiting(&self) -> usize {
        usize::from(self.head_pinned && !self.items.is_empty())
    }

    fn waiting_stops(&self) -> usize {
        self.items
            .iter()
            .skip(self.first_waiting())
            .filter(|i| i.is_stop())
            .count()
    }

    /// Whether `item` fits: a stop within the stop bound (or always, for
    /// the GCU's own), work within the work bound (everything but the
    /// waiting stops counts, a pinned head included).
    pub fn has_room(&self, item: &T) -> bool {
        let stops = self.waiting_stops();
        if item.is_stop() {
            item.always_fits() || stops < self.stop_bound
        } else {
            self.items.len() - stops < self.work_bound
        }
    }

    /// The waiting stop identical to `item`, if any.
    pub fn same_stop_mut(&mut self, item: &T) -> Option<&mut T> {
        let first = self.first_waiting();
        self.items
            .iter_mut()
            .skip(first)
            .find(|queued| queued.is_stop() && queued.same_frame(item))
    }

    /// Takes the waiting stop identical to `item` out of the queue, if any.
    pub fn take_same_stop(&mut self, item: &T) -> Option<T> {
        let first = self.first_waiting();
        let at = (first..self.items.len()).find(|&i| self.items[i].is_stop() && self.items[i].same_frame(item))?;
        self.items.remove(at)
    }

    /// Queues `item`: an urgent stop behind the waiting urgent ones and
    /// ahead of everything else, a stop behind the waiting stops and ahead
    /// of all work, work at the end. The caller checked [`Self::has_room`].
    pub fn push(&mut self, item: T) {
        let at = if item.is_stop() && item.urgent() {
            (self.first_waiting()..self.items.len())
                .find(|&i| !(self.items[i].is_stop() && self.items[i].urgent()))
                .unwrap_or(self.items.len())
        } else if item.is_stop() {
            (self.first_waiting()..self.items.len())
                .find(|&i| !self.items[i].is_stop())
                .unwrap_or(self.items.len())
        } else {
            self.items.len()
        };
        self.items.insert(at, item);
        self.high_water = self.high_water.max(self.items.len());
    }

    /// Marks the head as on the wire until it is popped.
    pub fn pin_head(&mut self) {
        self.head_pinned = !self.items.is_empty();
    }

    /// Whether the head is on the wire.
    pub fn head_pinned(&self) -> bool {
        self.head_pinned
    }

    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Most items ever queued at once.
    pub fn high_water(&self) -> usize {
        self.high_water
    }

    pub fn front(&self) -> Option<&T> {
        self.items.front()
    }

    pub fn pop_front(&mut self) -> Option<T> {
        self.head_pinned = false;
        self.items.pop_front()
    }

    pub fn iter(&self) -> std::collections::vec_deque::Iter<'_, T> {
        self.items.iter()
    }

    /// Removes the item at `at` (never a pinned head).
    pub fn remove(&mut self, at: usize) -> Option<T> {
        if at < self.first_waiting() {
            return None;
        }
        self.items.remove(at)
    }

    /// Removes and returns the waiting items `cancel` picks, in order.
    pub fn remove_where(&mut self, mut cancel: impl FnMut(&T) -> bool) -> Vec<T> {
        let first = self.first_waiting();
        let mut removed = Vec::new();
        let mut kept = VecDeque::with_capacity(self.items.len());
        for (i, item) in self.items.drain(..).enumerate() {
            if i >= first && cancel(&item) {
                removed.push(item);
            } else {
                kept.push_back(item);
            }
        }
        self.items = kept;
        removed
    }

    /// Everything, in order (the pinned head included).
    pub fn drain_all(&mut self) -> Vec<T> {
        self.head_pinned = false;
        self.items.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, PartialEq)]
    struct Item {
        name: &'static str,
        stop: bool,
        own: bool,
    }

    impl Queued for Item {
        fn is_stop(&self) -> bool {
            self.stop
        }
        fn always_fits(&self) -> bool {
            self.own
        }
        fn same_frame(&self, other: &Self) -> bool {
            self.name == other.name
        }
    }

    fn work(name: &'static str) -> Item {
        Item {
            name,
            stop: false,
            own: false,
        }
    }

    fn stop(name: &'static str) -> Item {
        Item {
            name,
            stop: true,
            own: false,
        }
    }

    fn names(q: &StopFirstQueue<Item>) -> Vec<&'static str> {
        q.iter().map(|i| i.name).collect()
    }

    #[test]
    fn stops_overtake_work_and_queue_behind_stops() {
        let mut q = StopFirstQueue::new(4, 4);
        for item in [work("a"), work("b"), stop("PS"), stop("TS"), work("c")] {
            assert!(q.has_room(&item));
            q.push(item);
        }
        assert_eq!(names(&q), ["PS", "TS", "a", "b", "c"]);
        assert_eq!(q.high_water(), 5);
    }

    #[test]
    fn bounds_apart_and_the_gcus_own_stops_always_fit() {
        let mut q = StopFirstQueue::new(1, 1);
        q.push(work("a"));
        assert!(!q.has_room(&work("b")), "work bound");
        assert!(q.has_room(&stop("PS")), "a stop has its own room");
        q.push(stop("PS"));
        assert!(!q.has_room(&stop("TS")), "stop bound");
        let own = Item {
            name: "TS",
            stop: true,
            own: true,
        };
        assert!(q.has_room(&own), "a dead-man stop always fits");
        assert!(q.same_stop_mut(&stop("PS")).is_some());
        assert!(q.same_stop_mut(&stop("TS")).is_none());
    }

    #[test]
    fn a_pinned_head_stays_first_and_is_no_waiting_stop() {
        let mut q = StopFirstQueue::new(2, 1);
        q.push(stop("PS"));
        q.pin_head();
        assert!(q.head_pinned());
        assert!(q.same_stop_mut(&stop("PS")).is_none(), "on the wire, not waiting");
        assert!(q.has_room(&stop("TS")));
        q.push(stop("TS"));
        q.push(work("a"));
        assert_eq!(names(&q), ["PS", "TS", "a"]);
        assert!(
            !q.has_room(&work("b")),
            "the head on the wire counts against the work bound"
        );
        assert_eq!(q.remove(0), None, "a pinned head is not removed");
        assert_eq!(q.remove_where(|i| i.stop), vec![stop("TS")]);
        assert_eq!(q.pop_front(), Some(stop("PS")));
        assert!(!q.head_pinned(), "popped");
        assert_eq!(names(&q), ["a"]);
    }
}
