//! The router core's vocabulary: link and command ids, origins, log
//! events, command outcomes and drop reasons (its inputs and actions, which
//! speak it, are in module `boundary`).

use core::fmt;

use sagebrush_protocol::{Address, Undelivered};

/// A link's identity, assigned by the daemon. Keep it stable for configured
/// peers (a serial line, an outbound TCP client) so that static routes and
/// the default upstream survive reconnects; accepted TCP connections may
/// take fresh ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LinkId(pub u32);

impl fmt::Display for LinkId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "link#{}", self.0)
    }
}

/// A line of the GCU: a serial port (a bus it is the master of) or a link.
/// Both are lines of one kind at the router's boundary (bytes in, writes
/// out: [`crate::Input::Bytes`], [`crate::Action::Write`]); what differs
/// between them stays in the router core's modules `port` and `link`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LineId {
    Port(u8),
    Link(LinkId),
}

impl fmt::Display for LineId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LineId::Port(port) => write!(f, "port {port}"),
            LineId::Link(link) => link.fmt(f),
        }
    }
}

/// Sequence number of a command accepted by this router (also given to the
/// dead-man stops it issues itself). Every id ends in exactly one
/// [`RouterEvent::Finished`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CommandId(pub u64);

/// Where a command came from, i.e. where its answers go back to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Origin {
    /// A frame received on a link, with the source group it carried.
    Link { link: LinkId, source: u8 },
    /// Issued by the router itself (dead-man stops): answers are discarded.
    Internal,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::Link { link, source } => write!(f, "{link} (source group {source})"),
            Origin::Internal => f.write_str("the GCU itself"),
        }
    }
}

impl Origin {
    pub fn link(&self) -> Option<LinkId> {
        match self {
            Origin::Link { link, .. } => Some(*link),
            Origin::Internal => None,
        }
    }
}

/// How loud a [`RouterEvent`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    Debug,
    Info,
    Warn,
}

/// Where a frame was when something happened to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Place {
    Port(u8),
    Link(LinkId),
    /// The router itself (routing decision, the GCU's own port 0).
    Router,
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Port(p) => write!(f, "port {p}"),
            Place::Link(l) => write!(f, "{l}"),
            Place::Router => f.write_str("router"),
        }
    }
}

/// A log/stat event. Counters are kept in [`crate::Stats`] as well; the
/// events carry the addresses a log line needs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RouterEvent {
    /// A command frame from a link (or the router's own dead-man stop) was
    /// accepted for local execution or forwarding.
    Accepted {
        id: CommandId,
        origin: Origin,
        dest: Address,
        command: &'static str,
    },
    /// A job of command `id` joined the queue of `port`.
    Queued { id: CommandId, port: u8, stop: bool },
    /// A job of command `id` began its transaction on `port`.
    Started { id: CommandId, port: u8, stop: bool },
    /// The command `id` ended (exactly once per accepted id).
    Finished { id: CommandId, outcome: CommandOutcome },
    /// A frame (or job) was dropped. For a bare `?` (no header), `dest`
    /// is 0.0.0 and `source` 0.
    Dropped {
        reason: DropReason,
        at: Place,
        dest: Address,
        source: u8,
    },
    /// A port's line rate was switched after a `C0`..`C7` change.
    RateSwitched { port: u8, bps: u32 },
    /// The GCU issued `stop` for a continuous motion of `link` (`None`:
    /// the governance's own stop, a boundary's or of a gimbal found
    /// moving), for `cause` (ARCHITECTURE "Safety"); said for each round.
    IssuedStop {
        link: Option<LinkId>,
        dest: Address,
        stop: &'static str,
        cause: StopCause,
    },
    /// A link came up or went down.
    LinkState {
        link: LinkId,
        up: bool,
        /// A connection accepted on a listener (its coming and going is
        /// not the daemon's life: DEBUG), not a configured link.
        accepted: bool,
    },
    /// A port was opened or lost.
    PortState { port: u8, open: bool },
    /// A device on `port` began answering (`first`: for the first time)
    /// or, having answered, went silent (no ACK after all retries). Said
    /// once per change, not per command: the commands' own outcomes are
    /// their clients' (delivery reports) and the metrics'.
    DeviceState {
        port: u8,
        device: u8,
        online: bool,
        first: bool,
    },
    /// The command `id` from a link was delivered: its origin got the ACK
    /// (client links) or a report `00` (links to other GCUs).
    Delivered { id: CommandId },
    /// The command `id` from a link was not delivered: the origin got no
    /// ACK but a delivery report saying why (client links), or a report
    /// frame (links to other GCUs). ARCHITECTURE "Delivery contract".
    Undelivered {
        id: CommandId,
        origin: Origin,
        dest: Address,
        command: &'static str,
        failure: Undelivered,
    },
    /// A command from a link that moves or changes a gimbal was let
    /// through by the governance (`refused` `None`) or refused: the audit
    /// line (ARCHITECTURE "Principals"), naming who sent it.
    Motion {
        actor: crate::principal::Actor,
        /// Boxed: a motion's event is rare beside the frames routed.
        frame: Box<sagebrush_protocol::FrameBuf>,
        refused: Option<DropReason>,
    },
    /// Control of a gimbal changed hands (`holder` `None`: it lapsed or was released).
    Control {
        port: u8,
        device: u8,
        holder: Option<crate::Holder>,
        from: Option<crate::Holder>,
    },
    /// A slew was stopped short of a travel limit or keep-out zone.
    BoundaryStop {
        port: u8,
        device: u8,
        stop: &'static str,
        boundary: DropReason,
    },
    /// A tour started, waits, runs or stopped (`refused`: a step it could not take).
    Tour {
        name: String,
        state: sagebrush_protocol::TourState,
        /// The step it is on, counted from 0.
        step: usize,
        /// How many steps it has.
        steps: usize,
        refused: Option<DropReason>,
    },
    /// Park recalled its preset (or could not: `refused`).
    Park {
        port: u8,
        device: u8,
        preset: u8,
        refused: Option<DropReason>,
    },
}

/// Why the GCU stops a motion it did not get a stop for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopCause {
    /// Its link went down, or its port is closing.
    DeadMan,
    /// The daemon shuts down.
    Shutdown,
    /// Its link's motion lease ran out.
    Lease,
    /// A link of higher priority took control of the gimbal.
    TakeOver,
    /// A slew came as near a travel limit or keep-out zone as it may.
    Boundary,
    /// A tour was stopped.
    Tour,
    /// gcud found the gimbal moving after it started or reopened the port,
    /// with nobody to stop it (ARCHITECTURE "Governance").
    FoundMoving,
}

impl RouterEvent {
    /// Suggested log level.
    pub fn level(&self) -> Level {
        match self {
            RouterEvent::Accepted { .. }
            | RouterEvent::Queued { .. }
            | RouterEvent::Started { .. }
            | RouterEvent::Delivered { .. } => Level::Debug,
            // What one command met is its sender's to report (a delivery
            // report) and the metrics' to count: a device that does not
            // answer is told once (DeviceState), a port once (PortState),
            // and an address with no port or route is the sender's. What
            // is the GCU's own trouble (full queues, links that fail,
            // stops it issued) stays a warning.
            RouterEvent::Finished { outcome, .. } => match outcome {
                CommandOutcome::Dropped(reason) if !reason.is_the_senders() && !reason.is_refusal() => Level::Warn,
                _ => Level::Debug,
            },
            RouterEvent::Undelivered { failure, .. } => match failure {
                Undelivered::DeviceSilent
                | Undelivered::DeviceNak
                | Undelivered::NotConfirmed
                | Undelivered::NoSuchPort
                | Undelivered::PortClosed
                | Undelivered::NoRoute => Level::Debug,
                refusal if refusal.is_refusal() => Level::Debug,
                _ => Level::Warn,
            },
            RouterEvent::Dropped { reason, .. } if reason.is_the_senders() || reason.is_refusal() => Level::Debug,
            // A link taking or leaving control is its client's business
            // (as its commands are): INFO stays the daemon's life. A
            // take-over (a holder's motion stopped) and gcud's own tours
            // and park are told.
            RouterEvent::Control {
                holder: Some(_),
                from: Some(_),
                ..
            } => Level::Info,
            RouterEvent::Control { .. } => Level::Debug,
            RouterEvent::Tour { .. } | RouterEvent::Park { .. } => Level::Info,
            // Who moved a gimbal is the daemon's to answer afterwards.
            RouterEvent::Motion { .. } => Level::Info,
            RouterEvent::BoundaryStop { .. } => Level::Info,
            RouterEvent::DeviceState { online: false, .. } => Level::Warn,
            RouterEvent::DeviceState { first: false, .. } => Level::Info,
            RouterEvent::DeviceState { .. } => Level::Debug,
            // gcud's governance at work (a take-over, a tour stopped, a
            // slew stopped short of a boundary) is routine: INFO. A stop for
            // a link that went down, a lease that ran out or a gimbal found
            // moving is trouble: a warning.
            RouterEvent::IssuedStop {
                cause: StopCause::TakeOver | StopCause::Tour | StopCause::Boundary,
                ..
            } => Level::Info,
            RouterEvent::Dropped { .. } | RouterEvent::IssuedStop { .. } => Level::Warn,
            RouterEvent::LinkState { accepted: true, .. } => Level::Debug,
            RouterEvent::RateSwitched { .. } | RouterEvent::LinkState { .. } | RouterEvent::PortState { .. } => {
                Level::Info
            }
        }
    }
}

/// How an accepted command ended at this router.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CommandOutcome {
    /// At least one result frame was queued to the origin link (for a
    /// command to the GCU itself: its own answer).
    Result,
    /// The device (or every device of a fan-out) answered NIC; one `?` was
    /// written to the origin link.
    Nic,
    /// Acknowledged with no result due, or a device-255 broadcast written and
    /// its guard time passed.
    Completed,
    /// Acknowledged, but the required result did not come in time.
    NoResult,
    /// The device never acknowledged (retries exhausted): device unreachable.
    Unreachable,
    /// Handed to the next-hop link toward another group (a group-255
    /// command with no such port here: flooded, the first copy's link).
    Forwarded(LinkId),
    /// Not executed.
    Dropped(DropReason),
}

impl fmt::Display for CommandOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandOutcome::Result => f.write_str("answered"),
            CommandOutcome::Nic => f.write_str("answered NIC"),
            CommandOutcome::Completed => f.write_str("completed"),
            CommandOutcome::NoResult => f.write_str("acknowledged, but no result came in time"),
            CommandOutcome::Unreachable => f.write_str("unreachable: no ACK after all retries"),
            CommandOutcome::Forwarded(link) => write!(f, "forwarded on {link}"),
            CommandOutcome::Dropped(reason) => write!(f, "dropped: {}", reason.describe()),
        }
    }
}

impl CommandOutcome {
    /// A short name, for the log's throttle and the metrics.
    pub fn name(&self) -> &'static str {
        match self {
            CommandOutcome::Result => "result",
            CommandOutcome::Nic => "nic",
            CommandOutcome::Completed => "completed",
            CommandOutcome::NoResult => "no_result",
            CommandOutcome::Unreachable => "unreachable",
            CommandOutcome::Forwarded(_) => "forwarded",
            CommandOutcome::Dropped(reason) => reason.name(),
        }
    }
}

sagebrush_protocol::code_table! {
    /// Why a frame or job was dropped. Every drop is counted under its
    /// reason (the code indexes [`crate::DropCounts`]; the name labels
    /// metrics).
    pub enum DropReason: u8 {
        /// no static, learned or default route to the destination group
        NoRoute,
        /// the only route leads back to the link the frame came from
        Loop,
        /// the destination port is not configured on this GCU
        UnknownPort,
        /// the destination port is configured but not open
        PortClosed,
        /// the port vanished with the job in flight or queued
        PortLost,
        /// a bounded queue (port or link) was full
        QueueFull,
        /// a stop identical to one already queued on the port: merged into it
        DuplicateStop,
        /// a stop for the same gimbal overtook it in the queue: it would have undone the stop
        Superseded,
        /// the link may not speak for this source group (or it is 255 or our own group)
        SourceNotAllowed,
        /// another link of equal or higher priority controls the gimbal
        NotInControl,
        /// its target lies outside the gimbal's travel limits
        TravelLimit,
        /// its path may enter a keep-out zone
        KeepOut,
        /// the gimbal's position, rate or acceleration is unknown and it has limits or zones
        PositionUnknown,
        /// the link went down with the frame queued or in flight
        LinkDown,
        /// the link peer never acknowledged the frame (retries exhausted)
        LinkNoAck,
        /// the link the answer should go back to is gone
        OriginGone,
        /// a frame nobody was waiting for (a late or stray result, or a frame for a group that is a local client's)
        Unsolicited,
        /// an answer from another GCU that could belong to forwarded commands of several origins
        AmbiguousAnswer,
        /// too many forwarded commands awaiting answers: the oldest was forgotten
        PendingFull,
        /// the GCU is shutting down: new commands are refused
        ShuttingDown,
        /// still queued when its client's delivery time-out passed: given up unsent
        Expired,
        /// the gimbal is governed and the command moves or changes it where gcud cannot bound it
        Ungoverned,
        /// a stop from a link below the gimbal's holder, sooner than one second after its last
        StopsLimited,
        /// a speed change whose rate is unknown while the gimbal slews toward a limit or zone
        RateUnknown,
        /// the gimbal did not say where the preset lies, and it has limits or zones
        PresetUnknown,
        /// the link's priority does not permit it
        NotPermitted,
    }
}

impl DropReason {
    /// A drop for the sender's address (no port, no route, a port not
    /// open), not for the GCU's own trouble: logged at DEBUG, counted.
    pub const fn is_the_senders(self) -> bool {
        matches!(self, Self::NoRoute | Self::UnknownPort | Self::PortClosed)
    }

    /// A refusal by the governance (control, limits, zones): the sender's
    /// to report, not the GCU's trouble.
    pub const fn is_refusal(self) -> bool {
        self.undelivered().is_refusal()
    }

    /// Index into [`crate::DropCounts`].
    pub const fn index(self) -> usize {
        self.code() as usize
    }

    /// What the origin of a command dropped for this reason is told
    /// (ARCHITECTURE "Delivery contract").
    pub const fn undelivered(self) -> Undelivered {
        match self {
            DropReason::NoRoute | DropReason::Unsolicited => Undelivered::NoRoute,
            DropReason::Loop => Undelivered::Loop,
            DropReason::UnknownPort => Undelivered::NoSuchPort,
            DropReason::PortClosed | DropReason::PortLost => Undelivered::PortClosed,
            DropReason::QueueFull | DropReason::PendingFull | DropReason::DuplicateStop => Undelivered::QueueFull,
            DropReason::SourceNotAllowed => Undelivered::SourceNotAllowed,
            DropReason::LinkDown | DropReason::LinkNoAck | DropReason::OriginGone | DropReason::AmbiguousAnswer => {
                Undelivered::LinkDown
            }
            DropReason::ShuttingDown => Undelivered::ShuttingDown,
            DropReason::Expired => Undelivered::Expired,
            DropReason::NotInControl => Undelivered::NotInControl,
            DropReason::TravelLimit => Undelivered::TravelLimit,
            DropReason::KeepOut => Undelivered::KeepOut,
            DropReason::PositionUnknown => Undelivered::PositionUnknown,
            DropReason::Superseded => Undelivered::Superseded,
            DropReason::Ungoverned => Undelivered::Ungoverned,
            DropReason::StopsLimited => Undelivered::StopsLimited,
            DropReason::RateUnknown => Undelivered::RateUnknown,
            DropReason::PresetUnknown => Undelivered::PresetUnknown,
            DropReason::NotPermitted => Undelivered::NotPermitted,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A link taking control, or its control lapsing, is no INFO line
    /// (tests/first_hour.rs: gimbalctl calls add none); a take-over is.
    #[test]
    fn control_changes_are_info_only_for_a_take_over() {
        let link = |name: &str| crate::Holder::Link {
            name: name.to_owned(),
            priority: 50,
            via: None,
        };
        let control = |holder: Option<crate::Holder>, from: Option<crate::Holder>| RouterEvent::Control {
            port: 1,
            device: 1,
            holder,
            from,
        };
        assert_eq!(control(Some(link("a")), None).level(), Level::Debug);
        assert_eq!(control(None, Some(link("a"))).level(), Level::Debug);
        assert_eq!(control(Some(link("b")), Some(link("a"))).level(), Level::Info);
    }

    /// A command the governance refused is its sender's to report (the
    /// delivery report) and the metrics' to count, as one to no such port.
    #[test]
    fn refusals_are_no_info_lines() {
        for failure in [
            Undelivered::NotInControl,
            Undelivered::TravelLimit,
            Undelivered::KeepOut,
            Undelivered::PositionUnknown,
        ] {
            let event = RouterEvent::Undelivered {
                id: CommandId(1),
                origin: Origin::Internal,
                dest: Address::new(5, 1, 1),
                command: "PR",
                failure,
            };
            assert_eq!(event.level(), Level::Debug, "{failure:?}");
        }
    }
}
