//! Carrying out the router core's actions (`sagebrush-gcu` `Action`):
//! writes queued on their lines, line rate switches, router events logged
//! (throttled), a departed link's counters kept under its configured name.

use std::fmt::Display;

use sagebrush_gcu::{Action, DropReason, Level, Outbox, Place, RouterEvent};
use sagebrush_host::throttle::Throttle;
use tokio::time::Instant;
use tracing::{debug, error, info, warn};

use super::links::{LinkBook, LinkInfo};
use crate::lines::{LineId, Lines, Refused};

/// A write a line did not take: logged, throttled per port or configured
/// link, when the line is behind (its peer is not reading).
fn write_refused(line: LineId, refused: Refused, links: &LinkBook, throttle: &mut Throttle) {
    match refused {
        Refused::Behind => {
            let now = Instant::now();
            let (allowed, text) = match line {
                LineId::Port(port) => {
                    let text = "the port is not taking bytes";
                    let place = format_args!("port {port}");
                    let line = format_args!("{place}: {text} (limit reached): bytes dropped");
                    (throttle.allow(&"writer behind", &place, &line, now), text)
                }
                LineId::Link(link) => {
                    let text = "the peer is not reading";
                    let place = links.name(link);
                    let line = format_args!("{link} ({place}): {text} (limit reached): bytes dropped");
                    (throttle.allow(&"writer behind", &place, &line, now), text)
                }
            };
            if allowed {
                warn!(%line, "{text} (limit reached): bytes dropped");
            }
        }
        Refused::Closed => debug!(%line, "write to a closed line dropped"),
    }
}

/// Carries out the router's actions in order: writes are queued on their
/// lines straight from the Outbox's buffer. A link gone leaves its counters
/// with its configured link and nothing else behind.
pub(super) fn execute(
    actions: &mut Outbox,
    lines: &mut Lines,
    links: &mut LinkBook,
    throttle: &mut Throttle,
    group: u8,
) {
    let mut gone = Vec::new();
    for action in actions.actions() {
        match action {
            Action::Write { line, bytes } => {
                if let Err(refused) = lines.write(*line, actions.bytes(bytes)) {
                    write_refused(*line, refused, links, throttle);
                }
            }
            Action::SetPortRate { port, bps } => match lines.set_baud(*port, *bps) {
                Ok(()) => info!(port, baud = bps, "line rate switched"),
                Err(reason) => error!(port, bps, %reason, "port lost: cannot switch its line rate; reopening"),
            },
            Action::Event(event) => log_event(event, links, throttle, group),
            Action::LinkGone { link, stats } => {
                links.depart(*link, stats);
                // Named in the logs of the actions after this one.
                gone.push(*link);
            }
        }
    }
    actions.clear();
    for link in gone {
        links.live.remove(&link);
    }
}

/// The audit line of a command that moves or changes a gimbal
/// (ARCHITECTURE "Principals"): who (the principal, the tool or link it
/// came through, the door's user gcud does not know), the gimbal, the
/// command and the governance's decision; at INFO under the target
/// `gcud::audit`, each field its own in the JSON format. A principal's
/// lines are throttled like warnings (module `throttle`): a jog's stream of
/// commands is summarised, never lost from the count.
fn audit(
    actor: &sagebrush_gcu::Actor,
    frame: &sagebrush_protocol::FrameBuf,
    refused: Option<DropReason>,
    throttle: &mut Throttle,
) {
    let frame = frame.frame();
    let command = String::from_utf8_lossy(frame.payload());
    let words = sagebrush_protocol::Command::parse(frame.payload());
    let words = words.in_words();
    let line = format_args!("audit: {actor}: {words} for {}", frame.dest);
    if !throttle.allow(&"audit", &actor.name, &line, Instant::now()) {
        return;
    }
    let outcome = refused.map_or("accepted", |r| r.undelivered().name());
    info!(
        target: "gcud::audit",
        principal = %actor.name,
        via = actor.via.as_deref().unwrap_or(""),
        for_user = actor.for_user.as_deref().unwrap_or(""),
        gimbal = %frame.dest,
        command = %command,
        outcome,
        "{actor}: {words} for {}: {}",
        frame.dest,
        refused.map_or_else(|| "accepted".to_owned(), |r| format!("refused, {}", r.undelivered().describe()))
    );
}

/// Logs a router event; repeated warnings of one kind from one place are
/// throttled (module `throttle`).
fn log_event(event: &RouterEvent, links: &LinkBook, throttle: &mut Throttle, group: u8) {
    if let RouterEvent::Motion { actor, frame, refused } = event {
        return audit(actor, frame, *refused, throttle);
    }
    let text = event.in_group(group);
    // Events about a link name it as configured, with its peer.
    let context = match event {
        RouterEvent::LinkState { link, .. } | RouterEvent::IssuedStop { link: Some(link), .. } => links.live.get(link),
        _ => None,
    };
    let context = LinkContext(context);
    match event.level() {
        Level::Debug => debug!("{text}{context}"),
        Level::Info => info!("{text}{context}"),
        Level::Warn => {
            // Kind and place written in place: a warning counted in an open
            // window allocates nothing (module `throttle`).
            let line = format_args!("{text}{context}");
            let now = Instant::now();
            let mut allow = |kind: &dyn Display, place: &dyn Display| throttle.allow(kind, place, &line, now);
            let allowed = match event {
                RouterEvent::Dropped { reason, at, .. } => {
                    let kind = format_args!("dropped {}", reason.name());
                    match at {
                        Place::Link(link) => allow(&kind, &links.name(*link)),
                        other => allow(&kind, other),
                    }
                }
                RouterEvent::Undelivered { failure, origin, .. } => {
                    let kind = format_args!("undelivered {}", failure.name());
                    match origin.link() {
                        Some(link) => allow(&kind, &links.name(link)),
                        None => allow(&kind, &""),
                    }
                }
                RouterEvent::Finished { outcome, .. } => allow(&format_args!("finished {}", outcome.name()), &""),
                RouterEvent::IssuedStop { link: Some(link), .. } => allow(&"stop", &links.name(*link)),
                RouterEvent::IssuedStop { link: None, .. } => allow(&"stop", &""),
                RouterEvent::DeviceState { port, device, .. } => {
                    allow(&"device silent", &format_args!("{group}.{port}.{device}"))
                }
                // Each other kind of warning, throttled as one.
                _ => allow(&"other", &""),
            };
            if allowed {
                warn!("{text}{context}");
            }
        }
    }
}

/// ` (name peer)` of the link an event is about, when it is live.
struct LinkContext<'a>(Option<&'a LinkInfo>);

impl Display for LinkContext<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(l) => write!(f, " ({} {})", l.name, l.peer),
            None => Ok(()),
        }
    }
}
