//! Governance (ARCHITECTURE "Governance"): gcud decides, per gimbal on its
//! own ports, who controls it (module `control`), where it may go (module
//! `travel`), and runs tours and park (module `tour`). The [`Governor`]
//! keeps what it knows of each gimbal (last position read, rates,
//! accelerations, presets) and the motions in progress; the router asks
//! it about every command from a link and carries out the commands it
//! issues itself ([`Order`]).
//!
//! What needs control: every command that moves or changes a gimbal
//! (everything but queries and stops; a rev 1.9 set/read command may set,
//! so it needs control too). Queries and stops are never refused.

mod control;
mod follow;
mod judge;
mod knowledge;
mod noting;
pub mod rules;
mod tour;
mod travel;
mod validate;

use std::collections::BTreeMap;

use sagebrush_protocol::{Address, Describes, MountEffect, Position, WILDCARD};

pub use crate::principal::{Actor, Principal};
pub use control::Holder;
pub use sagebrush_protocol::TourState;
pub use validate::GovernanceError;

use crate::command::CommandFacts;
use crate::types::{CommandId, DropReason, StopCause};
use control::{Held, Who};
pub(crate) use knowledge::Line;
use knowledge::{AxisMotion, Gimbal, Learning};
use rules::{GimbalRules, Governance, TourTarget};
use tour::TourRun;
use travel::{ARRIVED, axes};

/// A gimbal's control as gcud's `/status` shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GimbalControl {
    pub port: u8,
    pub device: u8,
    /// Who holds control, if anybody.
    pub holder: Option<Holder>,
    /// When a link's control lapses (tick), unless it commands again.
    pub lapses_at: Option<u64>,
    /// The last position read, and when.
    pub position: Option<(u64, Position)>,
    /// It has travel limits or keep-out zones.
    pub bounded: bool,
}

/// A tour as gcud's `/status` shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TourStatus {
    pub name: String,
    pub port: u8,
    pub device: u8,
    pub state: TourState,
    /// The step it is on (or resumes with), from 0.
    pub step: usize,
    /// Whom it waits for, when waiting.
    pub waiting_for: Option<Holder>,
}

/// A command the governor issues itself, for the router to dispatch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Order {
    pub port: u8,
    pub device: u8,
    pub command: sagebrush_protocol::Command<'static>,
    /// A stop, and why (logged and counted like the dead-man's).
    pub stop: Option<StopCause>,
    /// Before it, queued slews this stop ends are given up with this reason
    /// (a boundary stop must not be undone by a slew still waiting).
    pub cancel_slews: Option<DropReason>,
    pub purpose: Purpose,
}

/// What a command the governor issued is for: what its answer teaches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Purpose {
    Position,
    Rates,
    Accelerations,
    Preset(u8),
    /// A stop or a goto: nothing to learn from its answer.
    Motion,
}

/// The governor's verdict on a command from a link.
#[derive(Debug, Default)]
pub(crate) struct Verdict {
    /// Gimbals taken over from another holder: their motions are stopped first.
    pub taken_over: Vec<(u8, u8)>,
    /// What the command changes, per gimbal it reaches, to be learnt again
    /// when it ends (kept in its [`CommandNote`]).
    pub relearn: Vec<((u8, u8), Learning)>,
}

/// What the governor keeps of a command while it is in flight, in the
/// router's one in-flight record of it (no side map by command id): an
/// own command's gimbal and purpose, and what a link's change makes it
/// learn again. Given back with the command's end
/// ([`Governor::on_finished`]).
#[derive(Debug, Default)]
pub(crate) struct CommandNote {
    pub own: Option<((u8, u8), Purpose)>,
    pub relearn: Vec<((u8, u8), Learning)>,
}

/// What the governor decides of a command from a link.
#[derive(Debug)]
pub(crate) enum Decision {
    /// Let through: control taken, the motion noted.
    Pass(Verdict),
    /// Refused before the bus, for this reason.
    Refuse(DropReason),
    /// It needs what gcud is asking the gimbal for (its position, rates,
    /// a preset): it waits at the head of its gimbal's line and is decided
    /// again once gcud knows; refused with this reason when the gimbal
    /// does not say in time.
    Learn(DropReason),
}

/// The gimbals a command concerns.
enum Targets {
    One([(u8, u8); 1]),
    Many(Vec<(u8, u8)>),
}

impl Targets {
    fn as_slice(&self) -> &[(u8, u8)] {
        match self {
            Targets::One(one) => one,
            Targets::Many(many) => many,
        }
    }
}

/// The least time between two stops from one link below a gimbal's holder
/// (ARCHITECTURE "Governance"): more are refused, so a low link cannot
/// hold an operator's slew to a crawl with stops.
pub(crate) const STOP_SPACING: u64 = 1000;

/// The governance of every gimbal on this GCU's ports.
#[derive(Debug)]
pub(crate) struct Governor {
    config: Governance,
    gimbals: BTreeMap<(u8, u8), Gimbal>,
    tours: Vec<TourRun>,
    /// Ports open, with their line's timing (the follower's latency).
    ports: BTreeMap<u8, Line>,
    orders: Vec<Order>,
    /// Events for the router to log.
    pub events: Vec<crate::types::RouterEvent>,
    pub stats: GovernStats,
}

/// Counters of the governance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GovernStats {
    /// Control taken from a holder by a link of higher priority.
    pub takeovers: u64,
    /// Slews stopped before a limit or zone.
    pub boundary_stops: u64,
    /// Position polls of gimbals in motion (the bus time following costs).
    pub follow_polls: u64,
    /// Park recalls.
    pub parks: u64,
    /// Gimbals found moving after a start or a port's reopening, and stopped.
    pub found_moving: u64,
}

impl Governor {
    pub fn new(config: Governance) -> Self {
        let mut g = Self {
            config: Governance::default(),
            gimbals: BTreeMap::new(),
            tours: Vec::new(),
            ports: BTreeMap::new(),
            orders: Vec::new(),
            events: Vec::new(),
            stats: GovernStats::default(),
        };
        g.reconfigure(0, config);
        g
    }

    /// A changed governance, applied as a difference: gimbals keep what was
    /// learnt of them and their holder; a tour that changed or went away is
    /// stopped, one that did not keeps running.
    pub fn reconfigure(&mut self, now: u64, config: Governance) {
        let runs = std::mem::take(&mut self.tours);
        for run in &runs {
            if !config.tours.contains(&run.config) && run.state != TourState::Stopped {
                self.release_tour(now, run);
            }
        }
        self.tours = config
            .tours
            .iter()
            .map(|t| match runs.iter().find(|r| r.config == *t) {
                Some(r) => r.clone(),
                None => TourRun::new(t.clone()),
            })
            .collect();
        for gimbal in self.gimbals.values_mut() {
            gimbal.rules = None;
        }
        for rules in &config.gimbals {
            let g = self.gimbals.entry((rules.port, rules.device)).or_default();
            g.rules = Some(rules.clone());
        }
        self.config = config;
        let watched: Vec<(u8, u8)> = self.watched().collect();
        for at in watched {
            if self.ports.contains_key(&at.0) {
                let named = self.named_presets(at);
                self.gimbals.entry(at).or_default().start_learning(named);
            }
        }
    }

    /// The lowest link priority that may start or stop a tour.
    pub fn tours_min_priority(&self) -> Option<u8> {
        self.config.tours_min_priority
    }

    /// The principal gcud knows by `name` (`[[principal]]`).
    pub fn principal(&self, name: &[u8]) -> Option<&Principal> {
        self.config.principals.iter().find(|p| p.name.as_bytes() == name)
    }

    /// The rules of gimbal `at` (port, device), if it has any.
    pub fn rules(&self, at: (u8, u8)) -> Option<&GimbalRules> {
        self.config.gimbals.iter().find(|r| (r.port, r.device) == at)
    }

    /// The timing of `port`'s line (9600 bit/s when it is not open).
    fn line(&self, port: u8) -> Line {
        self.ports.get(&port).copied().unwrap_or(Line {
            bps: 9600,
            nic_window: 35,
            ack_timeout: 78,
            broadcast_guard: 100,
            queue_wait: crate::LinkSettings::DELIVERY_TIMEOUT_MS,
        })
    }

    /// Gimbals whose state the governor follows: those with rules or tours.
    fn watched(&self) -> impl Iterator<Item = (u8, u8)> + '_ {
        let ruled = self.config.gimbals.iter().map(|r| (r.port, r.device));
        ruled.chain(self.config.tours.iter().map(|t| (t.port, t.device)))
    }

    fn is_watched(&self, at: (u8, u8)) -> bool {
        self.watched().any(|w| w == at)
    }

    /// A port was opened (its line's timing) or lost: what was known of
    /// its gimbals is learnt again, and a gimbal found moving is stopped.
    pub fn port_state(&mut self, port: u8, open: Option<Line>) {
        match open {
            Some(line) => {
                self.ports.insert(port, line);
            }
            None => {
                self.ports.remove(&port);
            }
        }
        let watched: Vec<(u8, u8)> = self.watched().filter(|w| w.0 == port).collect();
        for at in watched {
            let named = self.named_presets(at);
            let g = self.gimbals.entry(at).or_default();
            g.forget();
            if open.is_some() {
                g.start_learning(named);
            }
        }
    }

    /// The presets park and the tours of gimbal `at` recall: asked for at
    /// start whatever the scan from 00 finds, and reserved from the doors
    /// (`~B`).
    pub fn named_presets(&self, at: (u8, u8)) -> Vec<u8> {
        let park = self.rules(at).and_then(|r| r.park).map(|p| p.preset);
        let tours = self
            .config
            .tours
            .iter()
            .filter(|t| (t.port, t.device) == at)
            .flat_map(|t| t.steps.iter())
            .filter_map(|s| match s.to {
                TourTarget::Preset(n) => Some(n),
                TourTarget::Position(_) => None,
            });
        let mut named: Vec<u8> = park.into_iter().chain(tours).collect();
        named.sort_unstable();
        named.dedup();
        named
    }

    /// The port's line rate changed.
    pub fn port_rate(&mut self, port: u8, bps: u32) {
        if let Some(line) = self.ports.get_mut(&port) {
            line.bps = bps;
        }
    }

    /// Whether gimbal `at` is governed (ARCHITECTURE "Governance"): it has
    /// limits, zones or park, or a tour drives it. What the table marks
    /// unbounded, identity or dynamics is refused there unless allowed.
    fn governs(&self, at: (u8, u8)) -> bool {
        self.rules(at).is_some_and(GimbalRules::governs) || self.config.tours.iter().any(|t| (t.port, t.device) == at)
    }

    /// Control, limits and zones for command `id` from a link to a local
    /// `dest` (port 1..=255), decided on its row's mount effect (read once,
    /// module `command`): refused (nothing goes to the bus), let through
    /// (control taken, the motion noted), or held until gcud knows enough.
    pub fn on_command(
        &mut self,
        now: u64,
        id: CommandId,
        who: &Actor,
        dest: Address,
        facts: &CommandFacts,
        known_devices: &[(u8, u8)],
    ) -> Decision {
        let effect = facts.mount;
        let hold = self.config.hold;
        // A query changes nothing: routed without a list of targets (no
        // allocation per routed query, tests/allocations.rs). The holder's
        // query while its slew runs renews its control, as it renews the
        // motion lease (ARCHITECTURE "Safety").
        if let MountEffect::Reads(_) = effect {
            if dest.port != WILDCARD && dest.device != WILDCARD {
                if let Some(g) = self.gimbals.get_mut(&(dest.port, dest.device)) {
                    g.renewed(now, hold, &who.name);
                }
            }
            return Decision::Pass(Verdict::default());
        }
        let targets = self.targets(dest, known_devices);
        let targets = targets.as_slice();
        let me = Who::of(who);
        if let MountEffect::Stop { pan, tilt } = effect {
            return self.on_stop(now, &me, targets, pan, tilt);
        }
        let mut verdict = Verdict::default();
        for at in targets {
            let Some(g) = self.gimbals.get(at) else { continue };
            match g.held(now, hold) {
                None => {}
                Some(h) if h.who.same(&me) => {}
                Some(h) if me.outranks(&h.who) => verdict.taken_over.push(*at),
                Some(_) => return Decision::Refuse(DropReason::NotInControl),
            }
        }
        for &at in targets {
            if !self.governs(at) {
                continue;
            }
            if effect.is_ungoverned() && !self.rules(at).is_some_and(|r| r.allows(facts)) {
                return Decision::Refuse(DropReason::Ungoverned);
            }
            let line = self.line(at.0);
            let Some(g) = self.gimbals.get_mut(&at) else {
                // Governed, its port not open yet: nothing is known of it.
                return Decision::Refuse(DropReason::PositionUnknown);
            };
            if let Err(decision) = g.check(now, effect, line, dest.device == WILDCARD) {
                return decision;
            }
        }
        // Allowed: control is taken, the motion noted, what it changes learnt again.
        for &at in targets {
            let watched = self.is_watched(at);
            let g = self.gimbals.entry(at).or_default();
            let before = g.holder.take();
            if let Some(old) = before.as_ref().filter(|h| !h.who.same(&me)) {
                if verdict.taken_over.contains(&at) {
                    self.stats.takeovers += 1;
                }
                self.events.push(crate::types::RouterEvent::Control {
                    port: at.0,
                    device: at.1,
                    holder: Some(me.view()),
                    from: Some(old.who.view()),
                });
            } else if before.is_none() {
                self.events.push(crate::types::RouterEvent::Control {
                    port: at.0,
                    device: at.1,
                    holder: Some(me.view()),
                    from: None,
                });
            }
            g.holder = Some(Held {
                who: me.clone(),
                last: now,
            });
            g.moved = true;
            if let Some(learning) = g.accepted(now, id, effect) {
                if watched {
                    verdict.relearn.push((at, learning));
                }
            }
        }
        Decision::Pass(verdict)
    }

    /// A stop (`PS`, `TS`, `PT`, a lens stop) from a link: never refused,
    /// but from a link below the holder at most one per [`STOP_SPACING`]
    /// per gimbal (ARCHITECTURE "Governance").
    fn on_stop(&mut self, now: u64, me: &Who, targets: &[(u8, u8)], pan: bool, tilt: bool) -> Decision {
        let hold = self.config.hold;
        let below = |g: &Gimbal| {
            g.held(now, hold)
                .is_some_and(|h| matches!(h.who, Who::Link { .. }) && h.who.outranks(me))
        };
        for at in targets {
            if let Some(g) = self.gimbals.get(at) {
                if below(g) && g.stops_limited(now, me) {
                    return Decision::Refuse(DropReason::StopsLimited);
                }
            }
        }
        for at in targets {
            if let Some(g) = self.gimbals.get_mut(at) {
                if below(g) {
                    g.stop_from_below(now, me);
                }
                g.stopping(now, pan, tilt);
            }
        }
        Decision::Pass(Verdict::default())
    }

    /// The gimbals a command to `dest` concerns: one (no allocation), or
    /// the known devices its wildcards match.
    fn targets(&self, dest: Address, known: &[(u8, u8)]) -> Targets {
        if dest.port != WILDCARD && dest.device != WILDCARD {
            return Targets::One([(dest.port, dest.device)]);
        }
        let matches = |&(p, d): &(u8, u8)| {
            (dest.port == WILDCARD || dest.port == p) && (dest.device == WILDCARD || dest.device == d)
        };
        let mut all: Vec<(u8, u8)> = known.iter().copied().chain(self.gimbals.keys().copied()).collect();
        all.retain(matches);
        all.sort_unstable();
        all.dedup();
        Targets::Many(all)
    }

    /// A result from gimbal `at` to a query whose row says what it
    /// describes (the router's in-flight record of the command it
    /// answers): a position only from a position query, a preset's only
    /// from a preset query (protocol crate, module `mount`).
    pub fn on_result(&mut self, now: u64, at: (u8, u8), describes: Describes, reply: &sagebrush_protocol::Reply<'_>) {
        let line = self.line(at.0);
        let Some(g) = self.gimbals.get_mut(&at) else { return };
        g.answered(now, describes, reply, line);
    }

    /// Command `id` ended with `outcome`: an own query that got no answer
    /// is tried again later (one answered NIC is not: the gimbal says it
    /// has none); a change from a link is learnt again. Whether it was an
    /// own query (what waits for knowledge may be decided again).
    pub fn on_finished(
        &mut self,
        now: u64,
        id: CommandId,
        outcome: crate::types::CommandOutcome,
        note: CommandNote,
    ) -> bool {
        let answered = match outcome {
            crate::types::CommandOutcome::Result => Some(true),
            crate::types::CommandOutcome::Nic => Some(false),
            _ => None,
        };
        for g in self.gimbals.values_mut() {
            g.ended(id);
        }
        let mut own_query = false;
        if let Some((at, purpose)) = note.own {
            own_query = purpose != Purpose::Motion;
            if let Some(g) = self.gimbals.get_mut(&at) {
                g.query_ended(now, purpose, answered);
            }
        }
        for (at, learning) in note.relearn {
            if let Some(g) = self.gimbals.get_mut(&at) {
                g.learn(learning);
            }
        }
        own_query
    }

    /// The router dispatches order `purpose` as command `id` (its
    /// [`CommandNote`] names the gimbal and the purpose).
    pub fn sent(&mut self, id: CommandId, at: (u8, u8), purpose: Purpose) {
        if purpose == Purpose::Motion {
            if let Some(g) = self.gimbals.get_mut(&at) {
                g.goto_is(id);
            }
        }
    }

    /// Command `id` began on `port`'s bus.
    pub fn started(&mut self, now: u64, port: u8, id: CommandId) {
        for (_, g) in self.gimbals.range_mut((port, 0)..=(port, u8::MAX)) {
            g.started(now, id);
        }
    }

    /// Control lapses, follows motions, learns, runs tours and park: the
    /// commands to issue now.
    pub fn poll(&mut self, now: u64) -> Vec<Order> {
        let hold = self.config.hold;
        for (&(port, device), g) in self.gimbals.iter_mut() {
            if let Some(h) = g.holder.as_ref().filter(|h| h.lapsed(now, hold)) {
                self.events.push(crate::types::RouterEvent::Control {
                    port,
                    device,
                    holder: None,
                    from: Some(h.who.view()),
                });
                g.free_since = Some(h.last.saturating_add(hold));
                g.holder = None;
            }
        }
        self.run_tours(now);
        self.run_parks(now);
        let mut orders = std::mem::take(&mut self.orders);
        for (&(port, device), g) in self.gimbals.iter_mut() {
            let open = self.ports.get(&port).copied();
            let Some(line) = open else { continue };
            g.follow(now, line, port, device, &mut orders, &mut self.stats, &mut self.events);
            g.next_query(now, port, device, &mut orders);
        }
        orders
    }

    /// The ports with a stop planned for one of their gimbals, in order,
    /// each once, appended to `out`.
    pub fn ports_with_planned_stops(&self, out: &mut Vec<u8>) {
        for (&(port, _), g) in &self.gimbals {
            if g.stop_planned().is_some() && out.last() != Some(&port) {
                out.push(port);
            }
        }
    }

    /// The earliest stop planned on `port` and how long a short exchange
    /// holds its bus (the port keeps the bus free for it).
    pub fn reservation(&self, port: u8) -> Option<(u64, u64)> {
        let line = self.ports.get(&port)?;
        let at = self
            .gimbals
            .range((port, 0)..=(port, u8::MAX))
            .filter_map(|(_, g)| g.stop_planned())
            .min()?;
        Some((at, line.busy()))
    }

    /// When [`Governor::poll`] next has work.
    pub fn next_deadline(&self) -> Option<u64> {
        let hold = self.config.hold;
        let gimbals = self.gimbals.iter().filter_map(|(&(port, _), g)| {
            let lapse = g.holder.as_ref().map(|h| h.last.saturating_add(hold));
            let motion = self.ports.contains_key(&port).then(|| g.next_deadline()).flatten();
            lapse.into_iter().chain(motion).min()
        });
        let tours = self.tours.iter().filter_map(TourRun::next_deadline);
        let parks = self.park_deadlines();
        gimbals.chain(tours).chain(parks).min()
    }

    /// Control of every gimbal that has a holder, rules or a tour.
    pub fn control(&self, now: u64) -> Vec<GimbalControl> {
        let hold = self.config.hold;
        self.gimbals
            .iter()
            .filter(|(_, g)| g.held(now, hold).is_some() || g.rules.is_some())
            .map(|(&(port, device), g)| {
                let held = g.held(now, hold);
                GimbalControl {
                    port,
                    device,
                    holder: held.map(|h| h.who.view()),
                    lapses_at: held
                        .filter(|h| matches!(h.who, Who::Link { .. }))
                        .map(|h| h.last.saturating_add(hold)),
                    position: g.position.map(|k| (k.at, k.position)),
                    bounded: g.rules.as_ref().is_some_and(GimbalRules::bounds_travel),
                }
            })
            .collect()
    }

    /// Who holds `at`, as the GCU command `~C` answers it.
    pub fn holder(&self, now: u64, at: (u8, u8)) -> Option<Holder> {
        let g = self.gimbals.get(&at)?;
        g.held(now, self.config.hold).map(|h| h.who.view())
    }

    /// `who` releases `at` (`~R`): allowed from the holder's link or one of
    /// higher priority (an equal one could free a holder it cannot take
    /// over from, and take control with its next command).
    pub fn release(&mut self, now: u64, who: &Actor, at: (u8, u8)) -> Result<(), DropReason> {
        let hold = self.config.hold;
        let Some(g) = self.gimbals.get_mut(&at) else {
            return Ok(());
        };
        let Some(h) = g.held(now, hold) else { return Ok(()) };
        let allowed = match &h.who {
            Who::Link { key, priority, .. } => *key == who.name || who.priority > *priority,
            Who::Tour(_) | Who::Park => true,
        };
        if !allowed {
            return Err(DropReason::NotInControl);
        }
        let from = h.who.view();
        g.holder = None;
        g.free_since = Some(now);
        self.events.push(crate::types::RouterEvent::Control {
            port: at.0,
            device: at.1,
            holder: None,
            from: Some(from),
        });
        Ok(())
    }

    pub fn tour_status(&self, now: u64) -> Vec<TourStatus> {
        self.tours
            .iter()
            .map(|t| {
                let at = (t.config.port, t.config.device);
                let waiting_for = match t.state {
                    TourState::Waiting => self.holder(now, at),
                    _ => None,
                };
                TourStatus {
                    name: t.config.name.clone(),
                    port: at.0,
                    device: at.1,
                    state: t.state,
                    step: t.step,
                    waiting_for,
                }
            })
            .collect()
    }

    /// The target of a tour step or park, if known.
    fn target_of(g: &Gimbal, to: TourTarget) -> Option<[i32; 2]> {
        match to {
            TourTarget::Position(p) => Some(axes(p)),
            TourTarget::Preset(n) => g.presets.get(&n).map(|p| axes(*p)),
        }
    }

    /// Whether a gimbal at `target`'s goto arrived.
    fn arrived(g: &Gimbal, target: Option<[i32; 2]>) -> bool {
        let still = g.axes.iter().all(|a| *a == AxisMotion::Still);
        match (target, g.position) {
            (Some(t), Some(k)) => {
                let p = axes(k.position);
                still && (p[0] - t[0]).abs() <= ARRIVED && (p[1] - t[1]).abs() <= ARRIVED
            }
            _ => still && g.position.is_some(),
        }
    }

    /// A reload changed configured link `name`'s priority: a holder of that name takes it.
    pub fn set_priority(&mut self, name: &str, priority: u8) {
        for g in self.gimbals.values_mut() {
            if let Some(Held {
                who: Who::Link { key, priority: p, .. },
                ..
            }) = g.holder.as_mut()
            {
                if &**key == name {
                    *p = priority;
                }
            }
        }
    }
}
