//! SIGHUP: what a new configuration file changes against the running one
//! (ARCHITECTURE "Safety"; README "Reload"). Ports and links are compared by
//! port id and link name: an unchanged one is left alone (its in-flight
//! transactions and queues go on), a removed or changed one is closed
//! (ports after their motions were stopped, links through the dead-man),
//! a new one is opened. Routes are replaced. Everything else needs a
//! restart, and a file that changes it is refused as a whole.

use std::fmt;

use crate::config::{Config, Link, Port};

/// The difference between the running configuration and a new one.
#[derive(Debug, Default)]
pub struct Diff {
    pub ports_added: Vec<Port>,
    pub ports_changed: Vec<Port>,
    pub ports_removed: Vec<u8>,
    pub links_added: Vec<Link>,
    pub links_changed: Vec<Link>,
    pub links_removed: Vec<String>,
    pub routes_changed: bool,
    /// Keys whose change a reload cannot apply.
    pub needs_restart: Vec<&'static str>,
}

impl Diff {
    /// What changes from `old` to `new`.
    pub fn between(old: &Config, new: &Config) -> Self {
        let mut d = Diff::default();
        for p in &new.ports {
            match old.ports.iter().find(|o| o.id == p.id) {
                None => d.ports_added.push(p.clone()),
                Some(o) if o != p => d.ports_changed.push(p.clone()),
                Some(_) => {}
            }
        }
        d.ports_removed = old
            .ports
            .iter()
            .filter(|o| !new.ports.iter().any(|p| p.id == o.id))
            .map(|o| o.id)
            .collect();
        for l in &new.links {
            match old.links.iter().find(|o| o.name == l.name) {
                None => d.links_added.push(l.clone()),
                Some(o) if o != l => d.links_changed.push(l.clone()),
                Some(_) => {}
            }
        }
        d.links_removed = old
            .links
            .iter()
            .filter(|o| !new.links.iter().any(|l| l.name == o.name))
            .map(|o| o.name.clone())
            .collect();
        d.routes_changed = old.routes != new.routes || old.default_route != new.default_route;
        let restart = [
            ("gcu.group", old.group != new.group),
            ("gcu.name", old.name != new.name),
            ("gcu.serial", old.serial != new.serial),
            ("gcu.shutdown_grace_ms", old.shutdown_grace_ms != new.shutdown_grace_ms),
            ("log.level", old.log_level != new.log_level),
            ("metrics.listen", old.metrics != new.metrics),
            (
                "metrics.allow_peers",
                old.metrics_allow_peers != new.metrics_allow_peers,
            ),
            ("limits.queue_depth", old.queue_depth != new.queue_depth),
            ("limits.max_connections", old.max_connections != new.max_connections),
            (
                "limits.max_connections_per_peer",
                old.max_connections_per_peer != new.max_connections_per_peer
                    || old.per_peer_cap_configured != new.per_peer_cap_configured,
            ),
            ("limits.idle_timeout_ms", old.idle_timeout_ms != new.idle_timeout_ms),
            (
                "link_timing",
                old.link_retries != new.link_retries
                    || old.link_ack_timeout_ms != new.link_ack_timeout_ms
                    || old.delivery_timeout_ms != new.delivery_timeout_ms,
            ),
        ];
        d.needs_restart = restart
            .iter()
            .filter(|(_, changed)| *changed)
            .map(|(k, _)| *k)
            .collect();
        d
    }

    pub fn is_empty(&self) -> bool {
        self.ports_added.is_empty()
            && self.ports_changed.is_empty()
            && self.ports_removed.is_empty()
            && self.links_added.is_empty()
            && self.links_changed.is_empty()
            && self.links_removed.is_empty()
            && !self.routes_changed
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
        if self.routes_changed {
            writeln!(f, "routes: replaced")?;
        }
        Ok(())
    }
}
