//! The routing table for groups other than our own (DESIGN "Routing
//! semantics"): static routes, then routes learned from the source groups
//! seen on links, then the default upstream.
//!
//! Learned routes remember every link a group was seen on, most recent
//! last. When a group was seen on several links and one of them is a client
//! link, the route is ambiguous (two clients speaking as the same group):
//! the frame is dropped rather than risk handing an answer to the wrong
//! client. Between GCU links the most recent one wins (topology change).

use std::collections::BTreeMap;

use crate::config::LinkKind;
use crate::types::{DropReason, LinkId};

#[derive(Debug, Default)]
pub(crate) struct RoutingTable {
    static_routes: BTreeMap<u8, LinkId>,
    default_upstream: Option<LinkId>,
    learned: BTreeMap<u8, Vec<(LinkId, LinkKind)>>,
}

impl RoutingTable {
    pub fn new(static_routes: BTreeMap<u8, LinkId>, default_upstream: Option<LinkId>) -> Self {
        Self {
            static_routes,
            default_upstream,
            learned: BTreeMap::new(),
        }
    }

    /// A frame from `group` arrived on `link`.
    pub fn learn(&mut self, group: u8, link: LinkId, kind: LinkKind) {
        let seen = self.learned.entry(group).or_default();
        if seen.last().map(|&(l, _)| l) == Some(link) {
            return;
        }
        seen.retain(|&(l, _)| l != link);
        seen.push((link, kind));
    }

    /// The link went down: forget what was learned on it.
    pub fn forget(&mut self, link: LinkId) {
        self.learned.retain(|_, seen| {
            seen.retain(|&(l, _)| l != link);
            !seen.is_empty()
        });
    }

    /// The next hop toward `group`; `up` tells which links are up and their
    /// kind; `any_upstream` is the default when the configured one is down.
    pub fn lookup(
        &self,
        group: u8,
        up: impl Fn(LinkId) -> Option<LinkKind>,
        any_upstream: Option<LinkId>,
    ) -> Result<LinkId, DropReason> {
        if let Some(&link) = self.static_routes.get(&group).filter(|&&l| up(l).is_some()) {
            return Ok(link);
        }
        if let Some(seen) = self.learned.get(&group) {
            let live: Vec<_> = seen.iter().filter(|(l, _)| up(*l).is_some()).collect();
            match live.as_slice() {
                [] => {}
                [(link, _)] => return Ok(*link),
                several if several.iter().any(|(_, kind)| *kind == LinkKind::Client) => {
                    return Err(DropReason::AmbiguousRoute);
                }
                several => return Ok(several[several.len() - 1].0),
            }
        }
        self.default_upstream
            .filter(|&l| up(l).is_some())
            .or(any_upstream)
            .ok_or(DropReason::NoRoute)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn up_all(kind: LinkKind) -> impl Fn(LinkId) -> Option<LinkKind> {
        move |_| Some(kind)
    }

    #[test]
    fn static_then_learned_then_default() {
        let mut t = RoutingTable::new([(7, LinkId(1))].into(), Some(LinkId(9)));
        t.learn(7, LinkId(2), LinkKind::Downstream);
        t.learn(8, LinkId(2), LinkKind::Downstream);
        assert_eq!(t.lookup(7, up_all(LinkKind::Downstream), None), Ok(LinkId(1)));
        assert_eq!(t.lookup(8, up_all(LinkKind::Downstream), None), Ok(LinkId(2)));
        assert_eq!(t.lookup(9, up_all(LinkKind::Downstream), None), Ok(LinkId(9)));
        // Static route down: learned one; nothing up: no route.
        let only2 = |l: LinkId| (l == LinkId(2)).then_some(LinkKind::Downstream);
        assert_eq!(t.lookup(7, only2, None), Ok(LinkId(2)));
        assert_eq!(t.lookup(9, |_| None, None), Err(DropReason::NoRoute));
        assert_eq!(t.lookup(9, |_| None, Some(LinkId(3))), Ok(LinkId(3)));
        t.forget(LinkId(2));
        assert_eq!(
            t.lookup(8, |l| (l == LinkId(2)).then_some(LinkKind::Downstream), None),
            Err(DropReason::NoRoute)
        );
    }

    #[test]
    fn same_group_on_two_clients_is_ambiguous_but_gcu_links_take_latest() {
        let mut t = RoutingTable::new(BTreeMap::new(), None);
        t.learn(0, LinkId(1), LinkKind::Client);
        t.learn(0, LinkId(2), LinkKind::Client);
        assert_eq!(
            t.lookup(0, up_all(LinkKind::Client), None),
            Err(DropReason::AmbiguousRoute)
        );
        t.learn(5, LinkId(3), LinkKind::Downstream);
        t.learn(5, LinkId(4), LinkKind::Downstream);
        assert_eq!(t.lookup(5, up_all(LinkKind::Downstream), None), Ok(LinkId(4)));
        t.learn(5, LinkId(3), LinkKind::Downstream);
        assert_eq!(t.lookup(5, up_all(LinkKind::Downstream), None), Ok(LinkId(3)));
    }
}
