//! The GCU router core (ARCHITECTURE "Layers" 2): a group control unit of group G
//! as pure, deterministic logic. No I/O, no clocks, no threads: events go
//! in with a tick count, actions come out.
//!
//! # Driving it (the daemon's side)
//!
//! ```
//! use sagebrush_gcu::{Action, Input, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig, SourceFilter};
//!
//! let mut config = RouterConfig::new(5);
//! config.ports.push(PortConfig::new(1));
//! let mut router = Router::new(config).expect("valid config");
//! // Kept across calls: its memory is reused, nothing is allocated per frame.
//! let mut out = Outbox::new();
//! router.handle(0, Input::PortOpened { port: 1 }, &mut out);
//! router.handle(0, Input::LinkUp { link: LinkId(1), config: LinkConfig::new(LinkKind::Client, SourceFilter::Any) }, &mut out);
//! for action in out.actions() {
//!     match action {
//!         Action::Write { line, bytes } => { let _ = out.bytes(bytes); /* write them to the port or link */ }
//!         Action::SetPortRate { port, bps } => { /* reconfigure the serial port */ }
//!         Action::LinkGone { link, stats } => { /* fold its counters into its configured link's */ }
//!         Action::Event(event) => { /* log at event.level(), e.g. through tracing */ }
//!     }
//! }
//! out.clear();
//! // Sleep until router.next_deadline(), or until bytes arrive, then call
//! // router.handle(now, Input::Tick / Input::Bytes { line, bytes } / ..).
//! let _ = router.next_deadline();
//! let _ = router.stats();
//! ```
//!
//! - One [`Router`] value, [`Router::new`] with a validated [`RouterConfig`].
//! - [`Router::handle`]`(now, input, &mut outbox)` for every [`Input`]:
//!   bytes read from a port or link ([`Input::Bytes`] names its [`LineId`];
//!   any chunking), port opened/lost, link
//!   up (with its [`LinkKind`] and [`SourceFilter`]) or down, or a plain
//!   [`Input::Tick`]. Actions are appended in the order they must be executed.
//! - Timers: after each call, arm one timer at [`Router::next_deadline`] and
//!   feed [`Input::Tick`] when it fires. Time is a `u64` tick count (ms).
//! - Statistics: [`Router::stats`] returns plain structs ([`Stats`]).
//! - Ports start closed: send [`Input::PortOpened`] once the serial port is
//!   open; the router answers with [`Action::SetPortRate`].
//!
//! # Rules implemented (ARCHITECTURE "Routing semantics", "Safety")
//!
//! - **Delivery contract** (ARCHITECTURE.md): a client link's command is
//!   ACKed only once it is delivered (the device acknowledged it); an
//!   undelivered one gets a delivery report instead of the ACK
//!   ([`sagebrush_protocol::DeliveryReport`]), a repeat of it meanwhile is
//!   not executed again, and its outcome comes within
//!   [`LinkSettings::delivery_timeout`]. On links to other GCUs every frame
//!   is ACKed hop by hop and every command's outcome is reported.
//! - **Hop by hop** (module `link`, module `port`): every frame received on a
//!   port, and every answer or GCU-link frame, is ACKed when its checksum holds;
//!   every damaged frame is NAKed (bare bytes).
//!   Every frame the GCU sends on a link is retransmitted by the protocol
//!   crate's `Transmitter` on NAK or ACK time-out, up to the configured count
//!   (one unacknowledged frame per link at a time).
//! - **Routing** (module `routing`): destination group G or 255 -> port 0 is the
//!   GCU itself (module `router::self_answer`: `AW`, `D?`, NIC otherwise), ports 1..=254 one
//!   port (unknown: dropped, [`DropReason::UnknownPort`]), port 255 every
//!   port. Group 255 from an upstream or client link is also flooded to every
//!   downstream link, never back to its origin. Other groups: static route,
//!   then learned route (source groups seen on GCU links; groups of
//!   clients are never destinations, their answers only travel the reverse
//!   path), then the default
//!   upstream; no route -> dropped, counted, logged. Never back to the link
//!   the frame came from ([`DropReason::Loop`]).
//! - **Source filter**: a frame whose source group the link may not speak
//!   for (or 255, or our own group on a link to another GCU) is ACKed (its
//!   checksum held) and dropped ([`DropReason::SourceNotAllowed`]). A client
//!   link acts for this GCU and may speak as its group (Figure 7).
//! - **Per-port transactions** (module `port`): one protocol `Transaction` at a
//!   time per bus, with result time-out classes, NIC window, device-255
//!   guard, stops overtaking queued work (and a long `IX` result wait), a
//!   bounded queue. A result is taken only with the exchange's Table 3
//!   header (the command's source group included), and after a
//!   retransmitted exchange the bus settles for one ACK time-out, so that a
//!   device's duplicate or late answer is never taken for the next one's.
//!   Forwarded stops overtake the frames waiting on a link too.
//! - **Answers** go back along the reverse path: a result from a port goes
//!   to the link the command came from with the Table 3 header
//!   (destination group = the command's source group, port and device
//!   unchanged except that a wildcard is replaced by the answering port or
//!   device, source group = G, checksum recomputed); a NIC as a bare `?`.
//!   Answers of frames forwarded to another GCU go back to their origin
//!   through module `reverse`. An answer that could belong to commands of
//!   several origins (clients sharing a source group, concurrently asking
//!   the same device) is dropped and counted
//!   ([`DropReason::AmbiguousAnswer`]), never guessed: give clients distinct
//!   source groups.
//! - **Wildcard fan-out** (what the origin receives): a port-255 command is
//!   one job per port and one accepted command. Every result frame is relayed as it comes (so the
//!   origin may receive several, each naming its port and device). `?` is
//!   relayed once, when the jobs ended without result or completion and at
//!   least one NIC. The origin's ACK waits until every job was acknowledged
//!   or ended (a result goes at once, its ACK first), so that `?` follows
//!   it within a port's window, never after a later command's ACK. A device-255 command gets no ACK and usually no answer;
//!   result frames with its header during its guard time (a lone device
//!   answering a broadcast) are relayed too. A group-255 command also yields whatever
//!   the downstream GCUs send back.
//! - **Dead-man** (module `deadman`): a link that goes down has its queued
//!   continuous motions cancelled and the motions it owns stopped (`PS`,
//!   `TS`, `FS`, `ZS`), locally or routed to the GCU that owns the device.
//!   The same stops go out at [`Input::Shutdown`], before a port is closed
//!   by [`Router::reconfigure`], and when a link's motion lease runs out.
//! - **Rate change**: a `C0`..`C7` acknowledged by every device of a port,
//!   or written to device 255, switches the port ([`Action::SetPortRate`]).
//! - **Bounded memory**: port queues (work and stops apart), link queues
//!   and the reverse-path table are bounded; overflow is dropped and counted
//!   with a warning event. A stop identical to one already queued is merged.
//!
//! # Outcomes
//!
//! Every accepted command (a good frame from an allowed source, or a
//! dead-man stop) gets a [`CommandId`] ([`RouterEvent::Accepted`]) and ends in
//! exactly one [`RouterEvent::Finished`] with a [`CommandOutcome`]: `Result` (queued to
//! the origin link), `Nic` (`?` written to it), `Completed`, `NoResult`,
//! `Unreachable` (device never ACKed), `Forwarded` (queued to the next-hop
//! link) or `Dropped(reason)`. What happens to a frame after it was queued
//! on a link is counted per link: `queued == delivered + failed + queue_len`.
//!
//! # Testing
//!
//! `tests/rules/` has one test per rule; `tests/simulation.rs` runs a
//! deterministic network simulation (seeded networks of 1 to 3 GCUs, ports
//! of `DeviceEndpoint` gimbals, clients, faulty wires). It runs 10,000
//! seeds by default; `GCU_SIM_SEEDS=1000000 GCU_SIM_START=0 cargo test -p
//! sagebrush-gcu --release --test simulation` runs more, and a failure
//! prints its seed and the command replaying it with a trace
//! (`GCU_SIM_SEED=<seed> ... -- --nocapture`).

mod boundary;
mod by_id;
mod command;
mod config;
mod deadman;
mod event_text;
mod govern;
mod line;
mod link;
mod outbox;
mod port;
mod principal;
mod queue;
mod reverse;
mod router;
mod routing;
mod stats;
mod timed;
mod types;

pub use boundary::{Action, Input};
pub use config::{ConfigError, LinkConfig, LinkKind, LinkSettings, PortConfig, RouterConfig, SourceFilter};
pub use event_text::EventText;
pub use govern::rules::{
    DEFAULT_PRIORITY, GimbalRules, Governance, HOLD_MS, MAX_PRIORITY, Park, Span, TourConfig, TourStep, TourTarget,
    Zone,
};
pub use govern::{GimbalControl, GovernStats, GovernanceError, Holder, TourState, TourStatus};
pub use outbox::Outbox;
pub use principal::{Actor, Principal};
pub use router::Router;
pub use stats::{
    Counted, Counts, DeviceError, DeviceStats, DropCounts, LineStats, LinkStats, PortStats, RouterStats, Stats,
    UndeliveredCounts,
};
pub use types::{CommandId, CommandOutcome, DropReason, Level, LineId, LinkId, Origin, Place, RouterEvent, StopCause};
