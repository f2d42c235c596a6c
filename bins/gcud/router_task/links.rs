//! What the daemon knows of its links beyond the router core: stable ids
//! of configured links, each live connection's name and peer for logs and
//! metrics, and the final counters of connections gone.

use std::collections::BTreeMap;

use sagebrush_gcu::{LinkId, LinkStats};

/// What the daemon knows of a live link, for logs and metrics.
#[derive(Debug, Clone)]
pub(super) struct LinkInfo {
    pub(super) name: String,
    pub(super) peer: String,
}

/// A link as logs name it: see [`LinkBook::name`].
pub(super) enum LinkName<'a> {
    Named(&'a str),
    Id(LinkId),
}

impl std::fmt::Display for LinkName<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkName::Named(name) => f.write_str(name),
            LinkName::Id(link) => link.fmt(f),
        }
    }
}

/// Stable ids of configured links, by name: kept across reconnects and
/// reloads, so that routes keep pointing at the right link.
#[derive(Debug, Default)]
pub(super) struct LinkIds(BTreeMap<String, LinkId>);

impl LinkIds {
    pub(super) fn of(&mut self, name: &str) -> LinkId {
        let next = LinkId(self.0.values().map(|l| l.0).max().unwrap_or(0) + 1);
        *self.0.entry(name.to_owned()).or_insert(next)
    }
}

/// The daemon's book of links: ids by configured name, the live ones, and
/// per configured name the final counters of its connections gone.
#[derive(Debug, Default)]
pub(super) struct LinkBook {
    pub(super) ids: LinkIds,
    pub(super) live: BTreeMap<LinkId, LinkInfo>,
    pub(super) departed: BTreeMap<String, LinkStats>,
}

impl LinkBook {
    /// `link`'s configured name, else its id (written, never kept: a
    /// throttled warning allocates nothing).
    pub(super) fn name(&self, link: LinkId) -> LinkName<'_> {
        match self.live.get(&link) {
            Some(l) => LinkName::Named(&l.name),
            None => LinkName::Id(link),
        }
    }

    /// A live link's counters, kept with its configured link.
    pub(super) fn depart(&mut self, link: LinkId, stats: &LinkStats) {
        if let Some(info) = self.live.get(&link) {
            match self.departed.get_mut(&info.name) {
                Some(d) => d.absorb(stats),
                None => {
                    self.departed.insert(info.name.clone(), *stats);
                }
            }
        }
    }
}
