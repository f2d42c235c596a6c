//! SIGHUP: what a new configuration file changes against the running one
//! (ARCHITECTURE "Safety"; README "Reload"). Ports and links are compared by
//! port id and link name: an unchanged one is left alone (its in-flight
//! transactions and queues go on), a removed or changed one is closed
//! (ports after their motions were stopped, links through the dead-man),
//! a new one is opened. A link whose priority alone changed keeps its
//! connections and takes the new priority at once. Routes are replaced;
//! `[control]`, `[[gimbal]]` and `[[tour]]` are applied as a difference by
//! the router core (a tour whose configuration is unchanged keeps running,
//! one removed or changed is stopped). Everything else needs a restart,
//! and a file that changes it is refused as a whole.

use std::fmt;
use std::path::Path;

use sagebrush_service::config_file::changed_keys;
use tracing::{error, warn};

use crate::config::{Config, Link, Port};

/// Why the configuration file is read again while gcud runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reread {
    /// SIGHUP: the new file is applied ([`Diff`]).
    Reload,
    /// SIGUSR1: a capture starts with `[capture]` as the file reads now
    /// (docs/capture.md).
    Capture,
}

impl Reread {
    /// The file as it reads now, checked as at start-up: SIGHUP and SIGUSR1
    /// take this one path. Its warnings are logged; a file that cannot be
    /// read or is invalid is logged (ERROR, `FILE:LINE:COLUMN: KEY:
    /// message`) as refused, and `None` keeps the running configuration.
    pub fn read(self, file: &Path) -> Option<Config> {
        let (refused, prefix) = match self {
            Reread::Reload => ("reload refused", "reload"),
            Reread::Capture => ("SIGUSR1: the configuration file is refused", "SIGUSR1"),
        };
        match crate::config::load(file) {
            Err(e) => {
                error!("{refused}, running configuration kept: {e}");
                None
            }
            Ok(new) => {
                for warning in &new.warnings {
                    warn!("{prefix}: {warning}");
                }
                Some(new)
            }
        }
    }
}

/// The difference between the running configuration and a new one.
#[derive(Debug, Default)]
pub struct Diff {
    pub ports_added: Vec<Port>,
    pub ports_changed: Vec<Port>,
    pub ports_removed: Vec<u8>,
    pub links_added: Vec<Link>,
    pub links_changed: Vec<Link>,
    pub links_removed: Vec<String>,
    /// Links whose priority changed (name, new priority): applied at once.
    pub priorities_changed: Vec<(String, u8)>,
    pub routes_changed: bool,
    /// `[control]`, `[[gimbal]]` or `[[tour]]` changed.
    pub governance_changed: bool,
    /// Keys whose change a reload cannot apply (`SECTION.KEY`, named by
    /// the sections' types).
    pub needs_restart: Vec<String>,
}

/// Entries of `new` not in `old`, entries in both that differ, and the
/// keys of entries of `old` not in `new`; entries are matched by `key`.
fn compare<T: Clone + PartialEq, K: PartialEq>(
    old: &[T],
    new: &[T],
    key: impl Fn(&T) -> K,
) -> (Vec<T>, Vec<T>, Vec<K>) {
    let (mut added, mut changed) = (Vec::new(), Vec::new());
    for n in new {
        match old.iter().find(|o| key(o) == key(n)) {
            None => added.push(n.clone()),
            Some(o) if o != n => changed.push(n.clone()),
            Some(_) => {}
        }
    }
    let removed = old
        .iter()
        .map(&key)
        .filter(|k| !new.iter().any(|n| key(n) == *k))
        .collect();
    (added, changed, removed)
}

impl Diff {
    /// What changes from `old` to `new`: ports, links and routes are
    /// applied; a changed key of any other section but `[capture]` (read
    /// when a capture starts) needs a restart.
    pub fn between(old: &Config, new: &Config) -> Self {
        // Every section is named here, so that a new one is a compile
        // error until it is applied, read later or refused.
        let Config {
            file: _,
            gcu,
            log,
            metrics,
            limits,
            link_timing,
            ports,
            links,
            routes,
            capture: _,
            governance,
            warnings: _,
            listen_places: _,
            serial_places: _,
        } = new;
        let (ports_added, ports_changed, ports_removed) = compare(&old.ports, ports, |p| p.id);
        let (links_added, mut links_changed, links_removed) = compare(&old.links, links, |l| l.name.clone());
        let priorities_changed = links_changed
            .iter()
            .filter(|l| old.links.iter().any(|o| o.name == l.name && o.priority != l.priority))
            .map(|l| (l.name.clone(), l.priority))
            .collect();
        // A new priority alone does not close the link's connections.
        links_changed.retain(|l| !old.links.iter().any(|o| o.name == l.name && o.same_but_priority(l)));
        let needs_restart = [
            changed_keys("gcu", &old.gcu, gcu),
            changed_keys("log", &old.log, log),
            changed_keys("metrics", &old.metrics, metrics),
            changed_keys("limits", &old.limits, limits),
            changed_keys("link_timing", &old.link_timing, link_timing),
        ]
        .concat();
        Diff {
            ports_added,
            ports_changed,
            ports_removed,
            links_added,
            links_changed,
            links_removed,
            priorities_changed,
            routes_changed: old.routes != *routes,
            governance_changed: old.governance != *governance,
            needs_restart,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.ports_added.is_empty()
            && self.ports_changed.is_empty()
            && self.ports_removed.is_empty()
            && self.links_added.is_empty()
            && self.links_changed.is_empty()
            && self.links_removed.is_empty()
            && self.priorities_changed.is_empty()
            && !self.routes_changed
            && !self.governance_changed
            && self.needs_restart.is_empty()
    }
}

impl fmt::Display for Diff {
    /// One line per change, e.g. `port 2: changed (reopened after its motions stop)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return writeln!(f, "no change");
        }
        for key in &self.needs_restart {
            writeln!(f, "{key}: changed; needs a restart (a reload is refused)")?;
        }
        for p in &self.ports_added {
            writeln!(f, "port {}: added", p.id)?;
        }
        for p in &self.ports_changed {
            writeln!(
                f,
                "port {}: changed (closed once its motions are stopped, then reopened)",
                p.id
            )?;
        }
        for id in &self.ports_removed {
            writeln!(f, "port {id}: removed (closed once its motions are stopped)")?;
        }
        for l in &self.links_added {
            writeln!(f, "link {:?}: added", l.name)?;
        }
        for l in &self.links_changed {
            writeln!(
                f,
                "link {:?}: changed (its connections close: dead-man stops, then it reopens)",
                l.name
            )?;
        }
        for name in &self.links_removed {
            writeln!(f, "link {name:?}: removed (its connections close: dead-man stops)")?;
        }
        for (name, priority) in &self.priorities_changed {
            writeln!(f, "link {name:?}: priority {priority} (applied at once)")?;
        }
        if self.routes_changed {
            writeln!(f, "routes: replaced")?;
        }
        if self.governance_changed {
            writeln!(
                f,
                "governance ([control], [[gimbal]], [[tour]]): changed (applied as a difference; \
                 a tour removed or changed is stopped)"
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn config(extra: &str) -> Config {
        let text = format!(
            "[gcu]\ngroup = 5\n{extra}\n[[link]]\nname = \"up\"\nrole = \"upstream\"\nconnect = \"127.0.0.1:1\"\n\
             [[port]]\nid = 1\nsimulate = [1]\n"
        );
        crate::config::parse(Path::new("t.toml"), &text).expect("valid")
    }

    #[test]
    fn keys_needing_a_restart_are_named_from_the_sections() {
        let old = config("");
        let new = config(
            "default_route = \"up\"\nshutdown_grace_ms = 100\nthreads = 2\n[limits]\nqueue_depth = 8\n\
             [link_timing]\nretries = 3\ndelivery_timeout_ms = 900\n[port_defaults]\nretries = 1\n",
        );
        let d = Diff::between(&old, &new);
        assert_eq!(
            d.needs_restart,
            [
                "gcu.shutdown_grace_ms",
                "gcu.threads",
                "limits.queue_depth",
                "link_timing.delivery_timeout_ms"
            ]
        );
        assert!(d.routes_changed, "gcu.default_route is a route, applied by a reload");
        assert_eq!(d.ports_changed.iter().map(|p| p.id).collect::<Vec<_>>(), [1]);
        assert!(Diff::between(&old, &config("[limits]\nqueue_depth = 16\n")).is_empty());
        assert_eq!(Diff::between(&old, &config("[metrics]\n")).needs_restart, ["metrics"]);
    }

    #[test]
    fn priorities_and_governance_are_applied_without_closing_anything() {
        let old = config("");
        let raised = crate::config::parse(
            Path::new("t.toml"),
            "[gcu]\ngroup = 5\n[[link]]\nname = \"up\"\nrole = \"upstream\"\nconnect = \"127.0.0.1:1\"\n\
             priority = 80\n[[port]]\nid = 1\nsimulate = [1]\n[control]\nhold_ms = 2000\n\
             [[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90, 90]\n",
        )
        .expect("valid");
        let d = Diff::between(&old, &raised);
        assert!(d.links_changed.is_empty() && d.ports_changed.is_empty(), "{d}");
        assert_eq!(d.priorities_changed, [("up".to_owned(), 80)]);
        assert!(d.governance_changed && d.needs_restart.is_empty(), "{d}");
        let text = d.to_string();
        assert!(
            text.contains("link \"up\": priority 80") && text.contains("governance"),
            "{text}"
        );
    }
}
