//! The routing table for groups other than our own (ARCHITECTURE "Routing
//! semantics"): static routes, then routes learned from the source groups
//! seen on links, then the default upstream.
//!
//! Source groups seen on client links are local clients, not destinations:
//! a client is never a transit route, and its answers travel only along the
//! reverse path (module `reverse`). What a client says about its own group
//! lives and dies with its connection and never shadows a static, learned
//! or default route: it only names the drop of a frame for that group
//! that has no route at all ([`DropReason::Unsolicited`], a late or stray
//! answer) instead of handing it to whichever client speaks as that group.
//! Between GCU links, the link a group was seen on most recently wins
//! (topology change).
//!
//! A configured route (static or default) may name a listener: it reaches
//! the newest live connection accepted on it (a GCU that dials in), so
//! that the hub can route to a field GCU before it has said anything.

use std::collections::{BTreeMap, BTreeSet};

use crate::config::LinkKind;
use crate::types::{DropReason, LinkId};

#[derive(Debug, Default)]
pub(crate) struct RoutingTable {
    static_routes: BTreeMap<u8, LinkId>,
    default_upstream: Option<LinkId>,
    /// Group -> GCU links it was seen on, most recent last.
    learned: BTreeMap<u8, Vec<LinkId>>,
    /// Groups seen on client links that are up, with those links.
    client_groups: BTreeMap<u8, BTreeSet<LinkId>>,
    /// Listener -> its live connections, newest last.
    accepted: BTreeMap<LinkId, Vec<LinkId>>,
}

impl RoutingTable {
    pub fn new(static_routes: BTreeMap<u8, LinkId>, default_upstream: Option<LinkId>) -> Self {
        Self {
            static_routes,
            default_upstream,
            learned: BTreeMap::new(),
            client_groups: BTreeMap::new(),
            accepted: BTreeMap::new(),
        }
    }

    /// `link` is a connection accepted on `listener`.
    pub fn accepted(&mut self, listener: LinkId, link: LinkId) {
        let connections = self.accepted.entry(listener).or_default();
        connections.retain(|&l| l != link);
        connections.push(link);
    }

    /// The live link a configured route names: the link itself, or the
    /// newest live connection of the listener it names.
    fn configured(&self, link: LinkId, up: &impl Fn(LinkId) -> bool) -> Option<LinkId> {
        if up(link) {
            return Some(link);
        }
        self.accepted.get(&link)?.iter().rev().copied().find(|&l| up(l))
    }

    /// New static routes and default upstream (configuration reloaded);
    /// what was learned stays.
    pub fn set_configured(&mut self, static_routes: BTreeMap<u8, LinkId>, default_upstream: Option<LinkId>) {
        self.static_routes = static_routes;
        self.default_upstream = default_upstream;
    }

    /// A frame from `group` arrived on `link`.
    pub fn learn(&mut self, group: u8, link: LinkId, kind: LinkKind) {
        if kind == LinkKind::Client {
            self.client_groups.entry(group).or_default().insert(link);
            return;
        }
        let seen = self.learned.entry(group).or_default();
        if seen.last() == Some(&link) {
            return;
        }
        seen.retain(|&l| l != link);
        seen.push(link);
    }

    /// The link went down: forget what was learned on it.
    pub fn forget(&mut self, link: LinkId) {
        self.learned.retain(|_, seen| {
            seen.retain(|&l| l != link);
            !seen.is_empty()
        });
        self.client_groups.retain(|_, links| {
            links.remove(&link);
            !links.is_empty()
        });
        self.accepted.retain(|_, links| {
            links.retain(|&l| l != link);
            !links.is_empty()
        });
    }

    /// The next hop toward `group`; `up` tells which links are up;
    /// `any_upstream` is the default when the configured one is down.
    pub fn lookup(
        &self,
        group: u8,
        up: impl Fn(LinkId) -> bool,
        any_upstream: Option<LinkId>,
    ) -> Result<LinkId, DropReason> {
        if let Some(link) = self.static_routes.get(&group).and_then(|&l| self.configured(l, &up)) {
            return Ok(link);
        }
        if let Some(&link) = self
            .learned
            .get(&group)
            .and_then(|seen| seen.iter().rev().find(|&&l| up(l)))
        {
            return Ok(link);
        }
        match self
            .default_upstream
            .and_then(|l| self.configured(l, &up))
            .or(any_upstream)
        {
            Some(link) => Ok(link),
            None if self.client_groups.contains_key(&group) => Err(DropReason::Unsolicited),
            // A route was configured for it: its link is down, which is
            // what the client should hear (07), not that none exists (06).
            None if self.static_routes.contains_key(&group) || self.default_upstream.is_some() => {
                Err(DropReason::LinkDown)
            }
            None => Err(DropReason::NoRoute),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_then_learned_then_default() {
        let mut t = RoutingTable::new([(7, LinkId(1))].into(), Some(LinkId(9)));
        t.learn(7, LinkId(2), LinkKind::Downstream);
        t.learn(8, LinkId(2), LinkKind::Downstream);
        assert_eq!(t.lookup(7, |_| true, None), Ok(LinkId(1)));
        assert_eq!(t.lookup(8, |_| true, None), Ok(LinkId(2)));
        assert_eq!(t.lookup(9, |_| true, None), Ok(LinkId(9)));
        // Static route down: the learned one; nothing up: the default
        // route's link is down (07), not "no route" (06).
        assert_eq!(t.lookup(7, |l| l == LinkId(2), None), Ok(LinkId(2)));
        assert_eq!(t.lookup(9, |_| false, None), Err(DropReason::LinkDown));
        assert_eq!(t.lookup(9, |_| false, Some(LinkId(3))), Ok(LinkId(3)));
        t.forget(LinkId(2));
        assert_eq!(t.lookup(8, |l| l == LinkId(2), None), Err(DropReason::LinkDown));
        let unrouted = RoutingTable::new(BTreeMap::new(), None);
        assert_eq!(
            unrouted.lookup(8, |_| false, None),
            Err(DropReason::NoRoute),
            "no route configured at all"
        );
    }

    #[test]
    fn client_groups_are_never_routes_and_gcu_links_take_the_latest() {
        let mut t = RoutingTable::new(BTreeMap::new(), None);
        t.learn(0, LinkId(1), LinkKind::Client);
        assert_eq!(t.lookup(0, |_| true, None), Err(DropReason::Unsolicited));
        t.forget(LinkId(1));
        assert_eq!(
            t.lookup(0, |_| true, None),
            Err(DropReason::NoRoute),
            "a client's group lives and dies with its connection"
        );
        t.learn(5, LinkId(3), LinkKind::Downstream);
        t.learn(5, LinkId(4), LinkKind::Downstream);
        assert_eq!(t.lookup(5, |_| true, None), Ok(LinkId(4)));
        t.learn(5, LinkId(3), LinkKind::Upstream);
        assert_eq!(t.lookup(5, |_| true, None), Ok(LinkId(3)));
        assert_eq!(t.lookup(5, |l| l == LinkId(4), None), Ok(LinkId(4)));
    }

    #[test]
    fn a_route_naming_a_listener_reaches_its_newest_live_connection() {
        const LISTENER: LinkId = LinkId(1);
        let mut t = RoutingTable::new([(7, LISTENER)].into(), Some(LISTENER));
        assert_eq!(
            t.lookup(7, |_| false, None),
            Err(DropReason::LinkDown),
            "nobody dialled in: the route's link is down"
        );
        t.accepted(LISTENER, LinkId(100));
        t.accepted(LISTENER, LinkId(101));
        let up = |l: LinkId| l == LinkId(100) || l == LinkId(101);
        assert_eq!(t.lookup(7, up, None), Ok(LinkId(101)), "the newest connection");
        assert_eq!(t.lookup(9, up, None), Ok(LinkId(101)), "default route too");
        t.forget(LinkId(101));
        assert_eq!(t.lookup(7, |l| l == LinkId(100), None), Ok(LinkId(100)));
        t.forget(LinkId(100));
        assert_eq!(t.lookup(7, |_| true, None), Ok(LISTENER), "an id that is up is itself");
        assert_eq!(t.lookup(7, |l| l != LISTENER, None), Err(DropReason::LinkDown));
    }

    #[test]
    fn a_client_speaking_as_a_gcu_never_shadows_its_routes() {
        let mut t = RoutingTable::new([(7, LinkId(1))].into(), Some(LinkId(9)));
        t.learn(8, LinkId(2), LinkKind::Downstream);
        for group in [7, 8, 9] {
            t.learn(group, LinkId(20), LinkKind::Client);
        }
        assert_eq!(t.lookup(7, |_| true, None), Ok(LinkId(1)), "static");
        assert_eq!(t.lookup(8, |_| true, None), Ok(LinkId(2)), "learned");
        assert_eq!(t.lookup(9, |_| true, None), Ok(LinkId(9)), "default");
    }
}
