//! Router events as log lines ([`RouterEvent::in_group`]): words, never a
//! Rust `Debug` form (issue 53). A command is said with its arguments in
//! their units ([`sagebrush_protocol::Command::in_words`]), a gimbal as
//! `G.P.D` in the GCU's group, a tour's step counted from 1 as `gimbalctl
//! gcud-status` counts it.

use core::fmt;

use sagebrush_protocol::{Address, TourState};

use crate::types::{DropReason, RouterEvent, StopCause};

/// The audit line's words: who, what the command does (in words, its
/// arguments in degrees: [`sagebrush_protocol::Command::in_words`]), the
/// gimbal, the decision.
fn audit_line(
    f: &mut fmt::Formatter<'_>,
    actor: &crate::principal::Actor,
    frame: &sagebrush_protocol::FrameBuf,
    refused: Option<DropReason>,
) -> fmt::Result {
    let frame = frame.frame();
    let command = sagebrush_protocol::Command::parse(frame.payload());
    write!(f, "{actor}: {} for {}", command.in_words(), frame.dest)?;
    match refused {
        None => f.write_str(": accepted"),
        Some(reason) => write!(f, ": refused, {}", reason.undelivered().describe()),
    }
}

/// A gimbal of this GCU: `5.2.1` when the group is known
/// ([`RouterEvent::in_group`]), else `port 2 device 1`.
struct Gimbal {
    group: Option<u8>,
    port: u8,
    device: u8,
}

impl fmt::Display for Gimbal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.group {
            Some(group) => Address::new(group, self.port, self.device).fmt(f),
            None => write!(f, "port {} device {}", self.port, self.device),
        }
    }
}

/// A [`RouterEvent`] as a log line, its gimbals named `G.P.D` in the
/// GCU's group ([`RouterEvent::in_group`]).
#[derive(Debug)]
pub struct EventText<'a> {
    event: &'a RouterEvent,
    group: Option<u8>,
}

impl RouterEvent {
    /// The event's log line, its gimbals named `G.P.D` in `group` (the
    /// router knows them by port and device only).
    pub fn in_group(&self, group: u8) -> EventText<'_> {
        EventText {
            event: self,
            group: Some(group),
        }
    }
}

impl fmt::Display for RouterEvent {
    /// The log line with the gimbals named by port and device (the group
    /// unknown here): [`RouterEvent::in_group`] names them `G.P.D`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        EventText {
            event: self,
            group: None,
        }
        .fmt(f)
    }
}

impl fmt::Display for EventText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.event {
            RouterEvent::Accepted {
                id,
                origin,
                dest,
                command,
            } => write!(f, "command {} {command} for {dest} accepted from {origin}", id.0),
            RouterEvent::Queued { id, port, stop } => {
                write!(f, "command {} queued on port {port} (stop: {stop})", id.0)
            }
            RouterEvent::Started { id, port, stop } => {
                write!(f, "command {} started on port {port} (stop: {stop})", id.0)
            }
            RouterEvent::Finished { id, outcome } => write!(f, "command {} finished: {outcome}", id.0),
            RouterEvent::Dropped {
                reason,
                at,
                dest,
                source,
            } => write!(
                f,
                "dropped frame for {dest} from group {source} at {at}: {}",
                reason.describe()
            ),
            RouterEvent::RateSwitched { port, bps } => write!(f, "port {port} switched to {bps} bps"),
            RouterEvent::Motion { actor, frame, refused } => audit_line(f, actor, frame, *refused),
            RouterEvent::IssuedStop {
                link,
                dest,
                stop,
                cause,
            } => issued_stop(f, *link, *dest, stop, *cause),
            RouterEvent::LinkState { link, up, .. } => write!(f, "{link} {}", if *up { "up" } else { "down" }),
            RouterEvent::PortState { port, open } => write!(f, "port {port} {}", if *open { "opened" } else { "lost" }),
            RouterEvent::Delivered { id } => write!(f, "command {} delivered", id.0),
            RouterEvent::Undelivered {
                id,
                origin,
                dest,
                command,
                failure,
            } => write!(
                f,
                "command {} {command} for {dest} from {origin} not delivered: {}",
                id.0,
                failure.describe()
            ),
            RouterEvent::Tour {
                name,
                state,
                step,
                steps,
                refused,
            } => tour(f, name, *state, (*step, *steps), *refused),
            RouterEvent::DeviceState { .. }
            | RouterEvent::Control { .. }
            | RouterEvent::BoundaryStop { .. }
            | RouterEvent::Park { .. } => self.gimbal_event(f),
        }
    }
}

impl EventText<'_> {
    /// The events about one gimbal of this GCU, named [`Gimbal`].
    fn gimbal_event(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let gimbal = |port: u8, device: u8| Gimbal {
            group: self.group,
            port,
            device,
        };
        match self.event {
            RouterEvent::DeviceState {
                port,
                device,
                online,
                first,
            } => {
                let at = gimbal(*port, *device);
                if self.group.is_some() {
                    f.write_str("device ")?;
                }
                match (online, first) {
                    (false, _) => write!(f, "{at} went silent: no ACK after all retries"),
                    (true, true) => write!(f, "{at} answers"),
                    (true, false) => write!(f, "{at} answers again"),
                }
            }
            RouterEvent::Control {
                port,
                device,
                holder,
                from,
            } => {
                let at = gimbal(*port, *device);
                match (holder, from) {
                    (Some(h), Some(old)) => write!(f, "{at}: {h} took control from {old}"),
                    (Some(h), None) => write!(f, "{at}: {h} has control"),
                    (None, Some(old)) => write!(f, "{at}: control of {old} ended"),
                    (None, None) => write!(f, "{at}: nobody has control"),
                }
            }
            RouterEvent::BoundaryStop {
                port,
                device,
                stop,
                boundary,
            } => write!(
                f,
                "{}: {stop} sent, stopping short of a {}",
                gimbal(*port, *device),
                match boundary {
                    DropReason::KeepOut => "keep-out zone",
                    _ => "travel limit",
                }
            ),
            RouterEvent::Park {
                port,
                device,
                preset,
                refused: Some(reason),
            } => write!(
                f,
                "{}: park to preset {preset} refused ({})",
                gimbal(*port, *device),
                reason.undelivered().describe()
            ),
            RouterEvent::Park {
                port, device, preset, ..
            } => {
                write!(f, "{}: parking at preset {preset}", gimbal(*port, *device))
            }
            // Only the four above are sent here.
            _ => f.write_str("an event of no gimbal"),
        }
    }
}

/// A stop gcud sent itself (ARCHITECTURE "Safety"), and why.
fn issued_stop(
    f: &mut fmt::Formatter<'_>,
    link: Option<crate::types::LinkId>,
    dest: Address,
    stop: &str,
    cause: StopCause,
) -> fmt::Result {
    match (cause, link) {
        (StopCause::DeadMan, Some(link)) => write!(f, "{link} down: dead-man {stop} to {dest}"),
        (StopCause::Lease, Some(link)) => write!(f, "{link}: motion lease over, {stop} to {dest}"),
        (StopCause::Shutdown, Some(link)) => write!(f, "shutting down: {stop} to {dest} (a motion of {link})"),
        (StopCause::DeadMan | StopCause::Lease, None) => write!(f, "{stop} to {dest}"),
        (StopCause::Shutdown, None) => write!(f, "shutting down: {stop} to {dest}"),
        (StopCause::TakeOver, _) => write!(f, "{dest}: control taken over, {stop} to end the last holder's motion"),
        (StopCause::Boundary, _) => write!(f, "{dest}: {stop} sent, a limit or keep-out zone is near"),
        (StopCause::Tour, _) => write!(f, "{dest}: tour stopped, {stop} sent"),
        (StopCause::FoundMoving, _) => write!(f, "{dest}: found moving with nobody to stop it, {stop} sent"),
    }
}

/// A tour's state, its step counted from 1 as `gimbalctl gcud-status`
/// shows it: `tour roof-round: running, step 1 of 4`.
fn tour(
    f: &mut fmt::Formatter<'_>,
    name: &str,
    state: TourState,
    (step, steps): (usize, usize),
    refused: Option<DropReason>,
) -> fmt::Result {
    let step = step + 1;
    match (refused, state) {
        (Some(reason), _) => write!(
            f,
            "tour {name}: stopped, step {step} of {steps} refused ({})",
            reason.undelivered().describe()
        ),
        (None, TourState::Waiting) => write!(
            f,
            "tour {name}: waiting, step {step} of {steps} (another controller holds its gimbal; it goes on when that control lapses)"
        ),
        (None, state) => write!(f, "tour {name}: {state}, step {step} of {steps}"),
    }
}
