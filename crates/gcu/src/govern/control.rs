//! Who controls a gimbal (ARCHITECTURE "Governance"): a configured link,
//! a tour or park. A link of higher priority takes control from a lower
//! one; gcud's own tours and park are below every link. A link's control
//! lapses `hold` ticks after its last command that moved or changed the
//! gimbal; a tour holds it while it runs, park until it arrived.

use std::sync::Arc;

/// Who holds a gimbal, as `/status` and the GCU command `~C` show it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Holder {
    /// A principal, or a configured link without principals (its name,
    /// or `link-N` for a link with none); `via`: the tool or link a
    /// principal's commands came through (module `principal`).
    Link {
        name: String,
        priority: u8,
        via: Option<String>,
    },
    /// gcud's tour of this name.
    Tour(String),
    /// gcud's park.
    Park,
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Holder::Link {
                name,
                priority,
                via: None,
            } => write!(f, "link {name} (priority {priority})"),
            Holder::Link {
                name,
                priority,
                via: Some(via),
            } => write!(f, "{name} via {via} (priority {priority})"),
            Holder::Tour(name) => write!(f, "tour {name}"),
            Holder::Park => f.write_str("park"),
        }
    }
}

/// A holder, as the governor keeps it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Who {
    Link {
        key: Arc<str>,
        priority: u8,
        via: Option<Arc<str>>,
    },
    /// The tour of this name.
    Tour(Arc<str>),
    Park,
}

impl Who {
    /// The same controller (one principal whatever its tool, one
    /// configured link whatever its connection).
    pub fn same(&self, other: &Who) -> bool {
        match (self, other) {
            (Who::Link { key: mine, .. }, Who::Link { key: theirs, .. }) => mine == theirs,
            _ => self == other,
        }
    }

    /// The governor's holder for `actor`.
    pub fn of(actor: &super::Actor) -> Self {
        Who::Link {
            key: actor.name.clone(),
            priority: actor.priority,
            via: actor.via.clone(),
        }
    }

    /// Whether `self` takes control from `other`: a link of higher
    /// priority, or any link from gcud's own tours and park.
    pub fn outranks(&self, other: &Who) -> bool {
        match (self, other) {
            (Who::Link { priority: mine, .. }, Who::Link { priority: theirs, .. }) => mine > theirs,
            (Who::Link { .. }, Who::Tour(_) | Who::Park) => true,
            _ => false,
        }
    }

    pub fn view(&self) -> Holder {
        match self {
            Who::Link { key, priority, via } => Holder::Link {
                name: key.to_string(),
                priority: *priority,
                via: via.as_deref().map(str::to_string),
            },
            Who::Tour(name) => Holder::Tour(name.to_string()),
            Who::Park => Holder::Park,
        }
    }
}

/// Control held: by whom, and their last command that moved or changed the gimbal.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Held {
    pub who: Who,
    pub last: u64,
}

impl Held {
    /// A link's control lapses `hold` after its last command; gcud's own never does.
    pub fn lapsed(&self, now: u64, hold: u64) -> bool {
        matches!(self.who, Who::Link { .. }) && now >= self.last.saturating_add(hold)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(name: &str, priority: u8) -> Who {
        Who::Link {
            key: Arc::from(name),
            priority,
            via: None,
        }
    }

    #[test]
    fn higher_links_outrank_lower_ones_and_every_link_outranks_gcud() {
        assert!(link("ops", 80).outranks(&link("vms", 50)));
        assert!(!link("vms", 50).outranks(&link("ops", 80)));
        assert!(
            !link("a", 50).outranks(&link("b", 50)),
            "equal priority does not take over"
        );
        assert!(link("a", 0).outranks(&Who::Tour(Arc::from("t"))));
        assert!(link("a", 0).outranks(&Who::Park));
        assert!(!Who::Park.outranks(&link("a", 0)));
    }

    #[test]
    fn only_a_links_control_lapses() {
        let held = Held {
            who: link("a", 50),
            last: 100,
        };
        assert!(!held.lapsed(199, 100));
        assert!(held.lapsed(200, 100));
        let tour = Held {
            who: Who::Tour(Arc::from("t")),
            last: 0,
        };
        assert!(!tour.lapsed(u64::MAX, 100));
    }
}
