//! The device side of a bus as a sans-IO endpoint (1.4.2, 1.4.3, Table 3):
//! what a gimbal's firmware runs, and what the simulator is built on.
//!
//! Bytes in -> framer -> address filter (own address or wildcard) ->
//! ACK on a good checksum, NAK on a bad one -> typed command to a
//! [`DeviceHandler`] -> NIC for unknown or unsupported commands, or the
//! result frame with the Table 3 header. All output goes through a
//! `FnMut(&[u8])` the caller supplies (a UART write, a queue).

use crate::EncodeError;
use crate::address::{Address, WILDCARD};
use crate::command::{Command, Row};
use crate::frame::{ACK, Frame, FrameBuf, NAK, NIC};
use crate::framer::{DEFAULT_CAPACITY, Event, Framer};
use crate::reply::Reply;

/// Which frames an endpoint takes as its own, and how it answers broadcasts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EndpointConfig {
    /// Own device address, 1..=254 (changed by `#NN`).
    pub device: u8,
    /// Own group, when the device knows it; `None` accepts any group. A
    /// gimbal on a GCU port usually does not know its GCU's group.
    pub group: Option<u8>,
    /// Own port, when known; `None` accepts any port.
    pub port: Option<u8>,
    /// Whether frames to device 255 are acknowledged and answered. On a bus
    /// of one device it should be; on a shared bus it must not, or the
    /// answers of several devices collide. Such frames are executed either way.
    pub answer_broadcast: bool,
}

impl EndpointConfig {
    /// A device on a bus of its own: any group and port, broadcasts answered.
    pub const fn single(device: u8) -> Self {
        Self {
            device,
            group: None,
            port: None,
            answer_broadcast: true,
        }
    }

    /// A device sharing its bus: broadcasts executed silently.
    pub const fn shared(device: u8) -> Self {
        Self {
            device,
            group: None,
            port: None,
            answer_broadcast: false,
        }
    }

    fn level_matches(own: Option<u8>, dest: u8) -> bool {
        dest == WILDCARD || own.is_none_or(|own| own == dest)
    }

    /// Whether a frame for `dest` is this device's.
    pub fn accepts(&self, dest: &Address) -> bool {
        (dest.device == self.device || dest.device == WILDCARD)
            && Self::level_matches(self.group, dest.group)
            && Self::level_matches(self.port, dest.port)
    }

    /// Whether a frame for `dest` gets ACK/NAK, NIC and results.
    pub fn answers(&self, dest: &Address) -> bool {
        self.accepts(dest) && (dest.device != WILDCARD || self.answer_broadcast)
    }
}

/// Where a command's result goes, handed to [`DeviceHandler::handle`]: the
/// header for a result (Table 3: destination group = the command's source,
/// port and device unchanged, a wildcard replaced by the endpoint's own so
/// that the answer says who answered; source = the command's group), and
/// whether the command is answered at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplyTo {
    /// The result's destination address.
    pub dest: Address,
    /// The result's source group.
    pub source: u8,
    /// `false` when the endpoint executes the command without answering it
    /// (a broadcast on a shared bus, [`EndpointConfig::answers`]): no ACK,
    /// NIC or result goes out for it, and [`DeviceEndpoint::send_reply`]
    /// sends nothing to this target, so a handler that defers a result
    /// (`IX`) need not know the bus it is on.
    pub answered: bool,
}

impl ReplyTo {
    fn for_command(frame: &Frame<'_>, config: &EndpointConfig) -> Self {
        let (mut dest, mut source) = frame.reply_header();
        if dest.device == WILDCARD {
            dest.device = config.device;
        }
        if dest.port == WILDCARD {
            dest.port = config.port.unwrap_or(WILDCARD);
        }
        if source == WILDCARD {
            source = config.group.unwrap_or(WILDCARD);
        }
        Self {
            dest,
            source,
            answered: config.answers(&frame.dest),
        }
    }
}

/// A handler's answer to one command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Response<'r> {
    /// Executed; the command has no result.
    Done,
    /// Executed; send this result.
    Reply(Reply<'r>),
    /// Not implemented or not applicable here: answer NIC.
    Nic,
    /// The result comes later (e.g. after `IX`): the handler keeps the
    /// [`ReplyTo`] and calls [`DeviceEndpoint::send_reply`].
    Deferred,
}

/// What the device does with its commands.
pub trait DeviceHandler {
    /// Executes `command`; `reply_to` is the header any result must carry
    /// and says whether the command is answered ([`ReplyTo::answered`]).
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, now: u64) -> Response<'_>;

    /// Whether the device implements `row` at all. The endpoint answers NIC
    /// to the others without reading their arguments (as it would after the
    /// handler's NIC), so that a small device links no parser for them.
    /// Every row by default.
    fn implements(row: Row) -> bool
    where
        Self: Sized,
    {
        let _ = row;
        true
    }
}

/// Counters of an endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EndpointStats {
    /// Frames addressed to this device with a valid checksum, handled.
    pub frames_accepted: u64,
    /// NAKs sent for frames whose checksum failed.
    pub naks_sent: u64,
    /// NICs sent for commands the handler does not implement.
    pub nics_sent: u64,
    /// Result frames sent (first transmissions).
    pub results_sent: u64,
    /// Results sent again because the master NAKed them.
    pub results_resent: u64,
}

/// How often one result is sent again on NAK before the endpoint gives up.
pub const RESULT_RESENDS: u8 = 3;

/// The last result sent, kept for a NAK that follows it at once (1.4.2:
/// the master NAKs a result whose checksum fails, hop by hop). The buffer
/// is always there (results are built straight into it, so that answering
/// needs no second frame on the stack); `resends_left` 0 means none is kept.
#[derive(Clone, Debug)]
struct LastResult {
    frame: FrameBuf,
    resends_left: u8,
}

/// A device on a bus: framer, address filter, ACK/NAK/NIC and results.
#[derive(Debug)]
pub struct DeviceEndpoint<const N: usize = DEFAULT_CAPACITY> {
    framer: Framer<N>,
    state: State,
}

/// What the framer's events act on: everything but the framer itself.
#[derive(Debug)]
struct State {
    config: EndpointConfig,
    stats: EndpointStats,
    last_result: LastResult,
}

impl<const N: usize> DeviceEndpoint<N> {
    /// An endpoint with an empty framer and zeroed counters.
    pub const fn new(config: EndpointConfig) -> Self {
        Self {
            framer: Framer::new(),
            state: State {
                config,
                stats: EndpointStats {
                    frames_accepted: 0,
                    naks_sent: 0,
                    nics_sent: 0,
                    results_sent: 0,
                    results_resent: 0,
                },
                last_result: LastResult {
                    frame: FrameBuf::EMPTY,
                    resends_left: 0,
                },
            },
        }
    }

    /// The configuration it was made with (address, broadcast answering).
    pub fn config(&self) -> &EndpointConfig {
        &self.state.config
    }

    /// The endpoint's counters.
    pub fn stats(&self) -> EndpointStats {
        self.state.stats
    }

    /// The framer's counters (noise, bad checksums).
    pub fn framer(&self) -> &Framer<N> {
        &self.framer
    }

    /// Bytes received from the bus; `out` receives every byte to send back.
    pub fn receive(&mut self, bytes: &[u8], now: u64, handler: &mut impl DeviceHandler, out: &mut impl FnMut(&[u8])) {
        let Self { framer, state } = self;
        framer.feed(bytes, |event| state.on_event(event, now, handler, out));
    }

    /// Free space in the endpoint's framer for a DMA transfer or a UART
    /// driver to write into; then [`DeviceEndpoint::commit`] the count.
    pub fn spare_capacity_mut(&mut self) -> &mut [u8] {
        self.framer.spare_capacity_mut()
    }

    /// `n` bytes were written into [`DeviceEndpoint::spare_capacity_mut`]:
    /// handles every event they complete, as [`DeviceEndpoint::receive`] does.
    pub fn commit(&mut self, n: usize, now: u64, handler: &mut impl DeviceHandler, out: &mut impl FnMut(&[u8])) {
        let Self { framer, state } = self;
        framer.commit(n);
        while let Some(event) = framer.next_event() {
            state.on_event(event, now, handler, out);
        }
    }

    /// Marks `n` bytes written into the spare capacity as received, without
    /// handling their events (the I/O adapters handle them one at a time).
    #[cfg(any(feature = "embedded-io", feature = "embedded-io-async"))]
    pub(crate) fn commit_only(&mut self, n: usize) {
        self.framer.commit(n);
    }

    /// Marks the line idle, without handling the events that follow.
    #[cfg(any(feature = "embedded-io", feature = "embedded-io-async"))]
    pub(crate) fn line_idle_only(&mut self) {
        self.framer.line_idle();
    }

    /// Handles the next buffered event; `false` when there is none. What one
    /// event sends is at most an ACK and a result frame.
    #[cfg(any(feature = "embedded-io", feature = "embedded-io-async"))]
    pub(crate) fn handle_next(
        &mut self,
        now: u64,
        handler: &mut impl DeviceHandler,
        out: &mut impl FnMut(&[u8]),
    ) -> bool {
        let Self { framer, state } = self;
        match framer.next_event() {
            Some(event) => {
                state.on_event(event, now, handler, out);
                true
            }
            None => false,
        }
    }

    /// The bus has been silent: abandon a partial frame (the silence hook).
    pub fn line_idle(&mut self, now: u64, handler: &mut impl DeviceHandler, out: &mut impl FnMut(&[u8])) {
        let Self { framer, state } = self;
        framer.flush_idle(|event| state.on_event(event, now, handler, out));
    }

    /// Sends a deferred result; to a target that is not answered
    /// ([`ReplyTo::answered`] false) nothing is sent.
    pub fn send_reply(
        &mut self,
        to: ReplyTo,
        reply: &Reply<'_>,
        out: &mut impl FnMut(&[u8]),
    ) -> Result<(), EncodeError> {
        let frame = FrameBuf::build(to.dest, to.source, |buf| reply.encode(buf).map(<[u8]>::len))?;
        if !to.answered {
            return Ok(());
        }
        self.state.stats.results_sent += 1;
        out(frame.as_bytes());
        self.state.last_result = LastResult {
            frame,
            resends_left: RESULT_RESENDS,
        };
        Ok(())
    }
}

impl State {
    /// One framer event. A NAK right after our result makes us send it again
    /// (up to [`RESULT_RESENDS`] times); any other traffic on the line (an
    /// ACK, any frame) means the master moved on, so a later NAK, meant for
    /// another device of a shared bus, never makes this one answer.
    fn on_event<H: DeviceHandler>(&mut self, event: Event<'_>, now: u64, handler: &mut H, out: &mut impl FnMut(&[u8])) {
        let Self {
            config,
            stats,
            last_result,
        } = self;
        if let Event::Nak = event {
            if last_result.resends_left > 0 {
                last_result.resends_left -= 1;
                stats.results_resent += 1;
                out(last_result.frame.as_bytes());
            }
            return;
        }
        last_result.resends_left = 0;
        match event {
            Event::Frame(frame) if config.accepts(&frame.dest) => {
                stats.frames_accepted += 1;
                let reply_to = ReplyTo::for_command(&frame, config);
                let answer = reply_to.answered;
                let mut send = |bytes: &[u8]| {
                    if answer {
                        out(bytes);
                    }
                };
                send(&[ACK]);
                let command = Command::parse_implemented(frame.payload(), H::implements);
                if let Command::Unknown(_) = command {
                    stats.nics_sent += u64::from(answer);
                    send(&[NIC]);
                    return;
                }
                match handler.handle(command, reply_to, now) {
                    Response::Done => {
                        if let Command::SetDeviceId(id) = command {
                            config.device = id.get();
                        }
                    }
                    Response::Deferred => {}
                    Response::Nic => {
                        stats.nics_sent += u64::from(answer);
                        send(&[NIC]);
                    }
                    Response::Reply(reply) => {
                        // Built in the last-result buffer, not on the stack.
                        let encoded = last_result
                            .frame
                            .rebuild(reply_to.dest, reply_to.source, |buf| reply.encode(buf).map(<[u8]>::len));
                        match encoded {
                            Ok(()) if reply.answers(&command) => {
                                stats.results_sent += u64::from(answer);
                                send(last_result.frame.as_bytes());
                                if answer {
                                    last_result.resends_left = RESULT_RESENDS;
                                }
                            }
                            // A result the command cannot have: the handler is wrong; say NIC, not garbage.
                            _ => {
                                stats.nics_sent += u64::from(answer);
                                send(&[NIC]);
                            }
                        }
                    }
                }
            }
            Event::BadChecksum(bad) if config.answers(&bad.dest) => {
                stats.naks_sent += 1;
                out(&[NAK]);
            }
            _ => {}
        }
    }
}
