//! Ports and links coming and going, reload and shutdown (ARCHITECTURE
//! "Safety"): the dead-man, lease and shutdown stops the GCU issues
//! itself, and a closing port's stops before it closes.

use sagebrush_protocol::FrameBuf;

use crate::boundary::Action;
use crate::command::ReadCommand;
use crate::config::{ConfigError, LinkConfig, RouterConfig};
use crate::deadman::OwnedStop;
use crate::link::Link;
use crate::outbox::Outbox;
use crate::port::Port;
use crate::stats::LinkStats;
use crate::types::{DropReason, LinkId, Origin, RouterEvent};

use super::Router;
use super::in_flight::{IssuedStop, StopRound};
use crate::types::StopCause;

impl Router {
    pub(super) fn port_state(&mut self, port: u8, open: bool, out: &mut Outbox) {
        if let Some(p) = self.ports.get(&port) {
            let line = crate::govern::Line {
                bps: p.stats.bps,
                nic_window: p.config.nic_window,
                ack_timeout: p.config.ack_timeout,
                broadcast_guard: p.config.broadcast_guard,
                queue_wait: self.settings.delivery_timeout,
            };
            self.governor.port_state(port, open.then_some(line));
            out.push(Action::Event(RouterEvent::PortState { port, open }));
        }
    }

    /// Applies a changed configuration (ARCHITECTURE "Safety": a port is closed
    /// or reconfigured only after its motions were stopped). Routes are
    /// replaced at once; a new port is added (closed until
    /// [`crate::Input::PortOpened`]); a removed or changed port starts closing:
    /// it takes no new commands (refused as shutting down), every motion
    /// owned on it gets its stop, and once it is idle
    /// ([`Router::closed_ports`]) the daemon closes it and calls
    /// [`Router::port_closed`], which installs the changed port's new
    /// configuration. `reopen`: ports whose I/O the daemon changes (a
    /// new device path, say) although their router configuration is the
    /// same; they close and come back too. Other ports whose configuration
    /// did not change are not touched. The group, name, serial and link
    /// settings cannot change.
    pub fn reconfigure(
        &mut self,
        now: u64,
        config: RouterConfig,
        reopen: &[u8],
        out: &mut Outbox,
    ) -> Result<(), ConfigError> {
        config.validate()?;
        if config.group != self.group {
            return Err(ConfigError::NotReloadable("the group"));
        }
        if config.name != self.name || config.serial != self.serial {
            return Err(ConfigError::NotReloadable("the name or serial"));
        }
        if config.links != self.settings {
            return Err(ConfigError::NotReloadable("the link settings"));
        }
        self.in_force = self.settings.with_answer_time_for(&config.ports);
        self.governor.reconfigure(now, config.governance.clone());
        self.routes
            .set_configured(config.static_routes, config.default_upstream);
        self.ports.for_each_mut(|&id, port| {
            let same = config.ports.iter().any(|p| p.id == id && *p == port.config);
            port.closing = !same || reopen.contains(&id);
        });
        self.replacements = config
            .ports
            .into_iter()
            .filter(|p| self.ports.get(&p.id).is_none_or(|old| old.closing))
            .map(|p| (p.id, p))
            .collect();
        let added: Vec<u8> = self
            .replacements
            .keys()
            .copied()
            .filter(|id| !self.ports.contains_key(id))
            .collect();
        for id in added {
            if let Some(p) = self.replacements.remove(&id) {
                self.ports.insert(id, Port::new(&p));
            }
        }
        let closing: Vec<u8> = self
            .ports
            .iter()
            .filter(|(_, p)| p.closing)
            .map(|(&id, _)| id)
            .collect();
        for port in closing {
            let stops = self.deadman.take_port(port);
            self.stop_motions(now, stops, StopCause::DeadMan, out);
        }
        self.poll(now, out);
        Ok(())
    }

    /// Ports that are closing and idle: the daemon may close them now.
    pub fn closed_ports(&self) -> Vec<u8> {
        self.ports
            .iter()
            .filter(|(_, p)| p.closing && p.is_idle())
            .map(|(&id, _)| id)
            .collect()
    }

    /// Whether `port` is configured (and not closing).
    pub fn has_port(&self, port: u8) -> bool {
        self.ports.get(&port).is_some_and(|p| !p.closing)
    }

    /// The daemon closed a closing port (idle, or its grace ran out: what
    /// is left on it fails as [`DropReason::PortLost`]). A changed port
    /// comes back with its new configuration, closed until opened.
    pub fn port_closed(&mut self, now: u64, port: u8, out: &mut Outbox) {
        if !self.ports.get(&port).is_some_and(|p| p.closing) {
            return;
        }
        self.with_port(now, port, out, |p, _, po| p.lose(po));
        self.ports.remove(&port);
        if let Some(config) = self.replacements.remove(&port) {
            self.ports.insert(port, Port::new(&config));
        }
    }

    /// A link came up (an id that is up is first taken down).
    pub(super) fn link_up(&mut self, now: u64, link: LinkId, mut config: LinkConfig, out: &mut Outbox) {
        // The governance knows a link by its configured name; one without
        // is a controller of its own (ARCHITECTURE "Governance"), named once
        // here rather than for every command it sends.
        config
            .name
            .get_or_insert_with(|| std::sync::Arc::from(format!("link-{}", link.0)));
        if self.links.contains_key(&link) {
            self.link_down(now, link, out);
        }
        let stats = LinkStats::new(config.kind);
        let accepted = config.listener.is_some();
        if let Some(listener) = config.listener {
            self.routes.accepted(listener, link);
        }
        self.links.insert(link, Link::new(config, &self.settings, stats));
        out.push(Action::Event(RouterEvent::LinkState {
            link,
            up: true,
            accepted,
        }));
    }

    /// A link went down: drop its queue, forget its routes, cancel the
    /// motions it queued and stop the motions it owns (dead-man).
    pub(super) fn link_down(&mut self, now: u64, link: LinkId, out: &mut Outbox) {
        let Some(mut l) = self.links.remove(&link) else {
            self.unknown_inputs += 1;
            return;
        };
        let its_own = |_: &super::waiting::Waiting, origin: Option<Origin>| origin.and_then(|o| o.link()) == Some(link);
        self.give_up_waiting(now, its_own, DropReason::OriginGone, out);
        for item in l.shut_down() {
            self.dropped_on_link(now, link, &item, DropReason::LinkDown, out);
        }
        out.push(Action::LinkGone {
            link,
            stats: Box::new(l.stats),
        });
        self.routes.forget(link);
        // Nobody is left to tell whether these were delivered, nor to
        // take their `?`: a configured link comes back under the same id,
        // and its next connection would take it for its own command's.
        self.in_flight.retain(|_, c| {
            if c.origin.link() == Some(link) {
                c.delivery = None;
                c.disowned = true;
            }
            !c.done()
        });
        self.reverse.disown_origin(link);
        out.push(Action::Event(RouterEvent::LinkState {
            link,
            up: false,
            accepted: l.config.listener.is_some(),
        }));
        let ports: Vec<u8> = self.ports.keys().copied().collect();
        for port in ports {
            self.with_port(now, port, out, |p, _, po| p.cancel_motions(link, po));
        }
        let stops = self.deadman.link_down(link);
        self.stop_motions(now, stops, StopCause::DeadMan, out);
    }

    /// Shutdown (ARCHITECTURE "Safety"): refuse new commands from now on, and
    /// stop every motion still owned by a link.
    pub(super) fn shut_down(&mut self, now: u64, out: &mut Outbox) {
        if self.stopping {
            return;
        }
        self.stopping = true;
        self.give_up_waiting(now, |_, _| true, DropReason::ShuttingDown, out);
        let stops = self.deadman.take_all();
        self.stop_motions(now, stops, StopCause::Shutdown, out);
    }

    /// Stops the motions whose lease ran out by `now`.
    pub(super) fn stop_expired_leases(&mut self, now: u64, out: &mut Outbox) {
        let expired = self.deadman.expired(now);
        self.stop_motions(now, expired, StopCause::Lease, out);
    }

    /// Stops motions the GCU takes back, for `cause`: the first round of
    /// each stop; an unacknowledged one is sent again (module `in_flight`:
    /// `DEAD_MAN_ROUNDS`).
    pub(super) fn stop_motions(&mut self, now: u64, stops: Vec<OwnedStop>, cause: StopCause, out: &mut Outbox) {
        for (link, dest, stop) in stops {
            let Ok(frame) = FrameBuf::build(dest, self.group, |buf| stop.encode(buf).map(<[u8]>::len)) else {
                continue;
            };
            let stop = ReadCommand::built(&stop, frame);
            self.send_stop(
                now,
                stop,
                IssuedStop {
                    link: Some(link),
                    cause,
                    round: 1,
                },
                out,
            );
        }
    }

    /// Sends a stop the GCU issued itself once more (its next round).
    pub(super) fn send_stop_round(&mut self, now: u64, round: StopRound, out: &mut Outbox) {
        self.send_stop(now, round.stop, round.issued, out);
    }

    /// A round of a stop the GCU issued itself: logged as its cause says
    /// (each round), counted by cause (once per motion, at its first round),
    /// and sent.
    pub(super) fn send_stop(&mut self, now: u64, stop: ReadCommand, issued: IssuedStop, out: &mut Outbox) {
        let IssuedStop { link, cause, round } = issued;
        let (dest, name) = (stop.frame.frame().dest, stop.facts.reply.mnemonic());
        let counter = match cause {
            StopCause::DeadMan => &mut self.stats.dead_man_stops,
            StopCause::Shutdown => &mut self.stats.shutdown_stops,
            StopCause::Lease => &mut self.stats.lease_stops,
            StopCause::TakeOver | StopCause::Boundary | StopCause::Tour | StopCause::FoundMoving => {
                &mut self.stats.governance_stops
            }
        };
        if round == 1 {
            *counter += 1;
        }
        out.push(Action::Event(RouterEvent::IssuedStop {
            link,
            dest,
            stop: name,
            cause,
        }));
        self.dispatch(now, Origin::Internal, None, stop, Some(issued), Default::default(), out);
    }
}
