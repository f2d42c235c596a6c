//! What crosses the router core's boundary: the inputs a daemon feeds
//! [`crate::Router::handle`] and the actions it executes for the router.

use crate::config::LinkConfig;
use crate::stats::LinkStats;
use crate::types::{LineId, LinkId, RouterEvent};

/// One thing that happened outside the router, fed to [`crate::Router::handle`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input<'a> {
    /// Only time passed (the timer armed at [`crate::Router::next_deadline`] fired).
    Tick,
    /// A serial port was opened (or re-opened after it was lost). The router
    /// answers with [`Action::SetPortRate`] for the rate it believes the bus runs at.
    PortOpened { port: u8 },
    /// A serial port vanished (USB unplugged, I/O error): its in-flight and
    /// queued transactions fail with [`crate::DropReason::PortLost`].
    PortLost { port: u8 },
    /// Bytes read from a port or link, in any chunking.
    Bytes { line: LineId, bytes: &'a [u8] },
    /// A link connected. An id that is already up is first taken down.
    LinkUp { link: LinkId, config: LinkConfig },
    /// A link disconnected: its queue is dropped, its learned routes
    /// forgotten, and the continuous motions it started are stopped (dead-man).
    LinkDown { link: LinkId },
    /// The daemon is shutting down (ARCHITECTURE "Safety"): every continuous
    /// motion started through this GCU and not yet stopped gets its stop,
    /// and new commands from links are refused
    /// ([`sagebrush_protocol::Undelivered::ShuttingDown`]). Answers still travel. The daemon
    /// exits once [`crate::Router::in_progress`] is 0 (or its grace ran out).
    Shutdown,
}

/// What the daemon does for the router.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Action {
    /// Write these bytes to the port or link: a span of the
    /// [`crate::Outbox`]'s buffer ([`crate::Outbox::bytes`]).
    Write {
        line: LineId,
        bytes: std::ops::Range<usize>,
    },
    /// Switch the serial port's own line rate (bits per second).
    SetPortRate { port: u8, bps: u32 },
    /// The link went down and the router forgot it: its final counters,
    /// for the daemon to fold into what it keeps per configured link
    /// (state stays bounded by what is live).
    LinkGone { link: LinkId, stats: Box<LinkStats> },
    /// Something worth logging or counting; see [`RouterEvent::level`].
    Event(RouterEvent),
}
