//! A bus (one serial line, Figure 3) of simulated gimbals, sans-IO: bytes in
//! with the time they arrived, bytes out with the time they are due.
//!
//! The bus is a wire-level shim around unmodified [`DeviceEndpoint`]s, the
//! code gimbal firmware runs, in the way a fault injector wraps a network
//! device: each simulated gimbal is a `DeviceEndpoint` with the gimbal model
//! ([`Gimbal`]) as its `DeviceHandler`; every endpoint gets the line's bytes
//! (each has its own framer, as real devices do) and the bus collects what
//! they write. Every protocol rule (address filter, ACK/NAK/NIC, Table 3
//! header, the result resent on the master's NAK) is the endpoint's.
//!
//! What the bus adds is the line: the delay of a result (Figure 6 "time
//! delay", [`BusConfig::reply_latency_ms`]), the silence after which a cut
//! frame is abandoned, and seeded faults ([`crate::faults`]) applied to the
//! bytes. To apply a fault to a whole frame the bus watches the line with a
//! framer of its own (the tap, which also logs every frame and keeps the
//! counters): bytes that may still belong to an incomplete frame are held
//! back from the endpoints until the tap has decided, which costs no time,
//! since an endpoint acts on a frame only at its last byte. Then one draw
//! per frame addressed to a device of the bus:
//! - `Silent`: the frame's bytes never reach the endpoints;
//! - `Nak`: its checksum byte is damaged on the way in (the endpoint NAKs);
//! - `DropAck`, `Corrupt`, `Delay`: the endpoints' answer loses its ACK,
//!   has a byte damaged, or leaves late.
//!
//! A result the endpoint sends again on a NAK is damaged again with the
//! `corrupt` probability.

use sagebrush_protocol::frame::layout;
use sagebrush_protocol::{
    ACK, Command, DataRate, DeviceEndpoint, EndpointConfig, EndpointStats, Event, Frame, Framer, NAK, NIC, OwnedEvent,
    Reply,
};
use tracing::{debug, info, warn};

use crate::config::GimbalConfig;
use crate::faults::{Fault, FaultConfig, Faults};
use crate::gimbal::Gimbal;

/// Settings of a bus.
#[derive(Clone, Debug, PartialEq)]
pub struct BusConfig {
    /// The gimbals on the line, at distinct addresses.
    pub devices: Vec<GimbalConfig>,
    pub faults: FaultConfig,
    /// Milliseconds between the ACK and a result frame (Figure 6 "time delay").
    pub reply_latency_ms: u64,
    /// Silence after which a partial frame is abandoned, milliseconds.
    pub idle_ms: u64,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            devices: vec![GimbalConfig::default()],
            faults: FaultConfig::default(),
            reply_latency_ms: 0,
            idle_ms: 100,
        }
    }
}

/// Bytes to write to the line at `due` (milliseconds).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outgoing {
    pub due: u64,
    /// May be empty when only `switch_to` matters (a silent broadcast `C0..C7`).
    pub bytes: Vec<u8>,
    /// After writing `bytes`, switch the line to this data rate (Table 4 `C0..C7`).
    pub switch_to: Option<DataRate>,
}

/// Counters of a bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Good frames addressed to a device of this bus.
    pub frames_in: u64,
    /// Good frames for addresses not on this bus.
    pub frames_ignored: u64,
    /// Damaged frames seen on the line (fault-injected ones included).
    pub bad_checksums_in: u64,
    /// NAKs the endpoints sent for damaged frames.
    pub naks_sent: u64,
    /// Results the endpoints sent again after a NAK from the master.
    pub results_resent: u64,
    /// NACKs and ACKs from the master, counted for the log.
    pub naks_in: u64,
    pub acks_in: u64,
}

/// One simulated gimbal: the firmware's endpoint and the model behind it.
#[derive(Debug)]
struct Device {
    endpoint: DeviceEndpoint,
    gimbal: Gimbal,
}

/// A simulated bus of gimbals.
#[derive(Debug)]
pub struct Bus {
    devices: Vec<Device>,
    /// The bus's own view of the line (logging, counters, which bytes form
    /// a frame for a fault); the endpoints never see its decisions.
    tap: Framer,
    /// Line bytes not yet given to the endpoints; `held[0]` is at stream
    /// offset `held_at` of the tap.
    held: Vec<u8>,
    held_at: u64,
    faults: Faults,
    outbox: Vec<Outgoing>,
    last_rx: u64,
    /// Fault-damaged commands (the tap saw them whole).
    damaged_in: u64,
    config: BusConfig,
    stats: BusStats,
}

/// Bytes the endpoints wrote in answer to one stretch of the line.
#[derive(Debug, Default)]
struct Answer {
    /// One entry per write: an ACK, NAK or NIC byte, or a result frame.
    pieces: Vec<Vec<u8>>,
    switch_to: Option<DataRate>,
    /// Whether a result among `pieces` is an endpoint's resend on NAK.
    resent: bool,
}

impl Bus {
    /// A bus at time `now`; names the first bad setting.
    pub fn new(config: BusConfig, now: u64) -> Result<Self, String> {
        if config.devices.is_empty() {
            return Err("a bus needs at least one device".into());
        }
        for (i, d) in config.devices.iter().enumerate() {
            d.validate()?;
            if config.devices[..i].iter().any(|o| o.device == d.device) {
                return Err(format!("device address {} is used twice", d.device));
            }
        }
        config.faults.validate()?;
        let shared = config.devices.len() > 1;
        let devices = config
            .devices
            .iter()
            .map(|d| {
                let endpoint = EndpointConfig {
                    device: d.device,
                    group: d.group,
                    port: d.port,
                    answer_broadcast: !shared,
                };
                Device {
                    endpoint: DeviceEndpoint::new(endpoint),
                    gimbal: Gimbal::new(d.clone(), now),
                }
            })
            .collect();
        Ok(Self {
            devices,
            tap: Framer::new(),
            held: Vec::new(),
            held_at: 0,
            faults: Faults::new(config.faults),
            outbox: Vec::new(),
            last_rx: now,
            damaged_in: 0,
            config,
            stats: BusStats::default(),
        })
    }

    /// The bus's counters; NAKs and resends are the endpoints' own.
    pub fn stats(&self) -> BusStats {
        let mut stats = self.stats;
        stats.bad_checksums_in += self.damaged_in;
        for d in &self.devices {
            let s = d.endpoint.stats();
            stats.naks_sent += s.naks_sent;
            stats.results_resent += s.results_resent;
        }
        stats
    }

    /// Faults injected so far, by kind.
    pub fn faults_injected(&self, fault: Fault) -> u64 {
        self.faults.injected(fault)
    }

    /// Bytes on the line that were part of no frame or bare ACK/NAK/NIC.
    pub fn noise_bytes(&self) -> u64 {
        self.tap.skipped_bytes()
    }

    /// The gimbals, in configuration order.
    pub fn gimbals(&self) -> impl Iterator<Item = &Gimbal> {
        self.devices.iter().map(|d| &d.gimbal)
    }

    /// The gimbal currently at `device`.
    pub fn gimbal(&self, device: u8) -> Option<&Gimbal> {
        self.gimbals().find(|g| g.device() == device)
    }

    /// The counters of the endpoint currently at `device`.
    pub fn endpoint_stats(&self, device: u8) -> Option<EndpointStats> {
        self.devices
            .iter()
            .find(|d| d.endpoint.config().device == device)
            .map(|d| d.endpoint.stats())
    }

    /// Bytes received from the line at `now`.
    pub fn receive(&mut self, bytes: &[u8], now: u64) {
        self.advance(now);
        self.last_rx = now;
        self.held.extend_from_slice(bytes);
        let mut rest = bytes;
        let mut events = Vec::new();
        while !rest.is_empty() {
            let n = self.tap.push(rest);
            rest = &rest[n..];
            self.drain_tap(&mut events);
        }
        self.pass(events, now, false);
    }

    /// Time passed: physics, results that became due (`IX`), and a partial
    /// frame abandoned after [`BusConfig::idle_ms`] of silence.
    pub fn poll(&mut self, now: u64) {
        self.advance(now);
        if self.tap.buffered() > 0 && now >= self.last_rx + self.config.idle_ms {
            let mut events = Vec::new();
            self.tap.line_idle();
            self.drain_tap(&mut events);
            self.pass(events, now, true);
        }
    }

    /// The tap's events with the stream offset each ends at.
    fn drain_tap(&mut self, events: &mut Vec<(u64, OwnedEvent)>) {
        while let Some(event) = self.tap.next_event().map(|e| e.to_owned()) {
            events.push((self.tap.stream_offset(), event));
        }
    }

    /// When [`Bus::poll`] or [`Bus::pop_due`] next has something to do.
    pub fn next_deadline(&self) -> Option<u64> {
        let idle = (self.tap.buffered() > 0).then_some(self.last_rx + self.config.idle_ms);
        let out = self.outbox.first().map(|o| o.due);
        let models = self.devices.iter().filter_map(|d| d.gimbal.next_deadline());
        out.into_iter().chain(idle).chain(models).min()
    }

    /// The next output due at or before `now`, logged as it leaves.
    pub fn pop_due(&mut self, now: u64) -> Option<Outgoing> {
        if self.outbox.first().is_some_and(|o| o.due <= now) {
            let out = self.outbox.remove(0);
            log_outgoing(&out);
            return Some(out);
        }
        None
    }

    /// Physics up to `now`, and the deferred results (`IX`) that became due,
    /// sent through their endpoints.
    fn advance(&mut self, now: u64) {
        let mut due = Vec::new();
        for dev in &mut self.devices {
            dev.gimbal.advance_to(now);
            for result in dev.gimbal.take_finished() {
                let reply = Reply::Initialization(result.results);
                let mut bytes = Vec::new();
                match dev
                    .endpoint
                    .send_reply(result.reply_to, &reply, &mut |b| bytes.extend_from_slice(b))
                {
                    Ok(()) => due.push((result.at, bytes)),
                    Err(e) => warn!(device = dev.gimbal.device(), error = %e, "cannot encode IX result"),
                }
            }
        }
        for (at, bytes) in due {
            self.queue(at, bytes, None);
        }
    }

    fn queue(&mut self, due: u64, bytes: Vec<u8>, switch_to: Option<DataRate>) {
        let at = self.outbox.partition_point(|o| o.due <= due);
        self.outbox.insert(at, Outgoing { due, bytes, switch_to });
    }

    /// Gives the endpoints the held bytes the tap has decided, stretch by
    /// stretch (each ends with one of `events`, `(end offset, event)`), with
    /// the faults drawn for the frames among them; on `idle` all held bytes,
    /// then the endpoints' silence hook.
    fn pass(&mut self, events: Vec<(u64, OwnedEvent)>, now: u64, idle: bool) {
        for (end, event) in events {
            let fault = self.watch(&event.as_event());
            let mut stretch = self.take_held(end);
            if let (OwnedEvent::Frame(frame), Some(f)) = (&event, fault) {
                let start = stretch.len().saturating_sub(frame.as_bytes().len());
                match f {
                    // The device does not hear it at all.
                    Fault::Silent => stretch.truncate(start),
                    // Damaged in transit: the checksum no longer holds.
                    Fault::Nak => {
                        if let Some(last) = stretch.last_mut() {
                            *last = last.wrapping_add(1);
                            self.damaged_in += 1;
                        }
                    }
                    _ => {}
                }
            }
            // After silence each stretch ends in it, as every candidate the tap
            // abandoned is abandoned by the endpoints' framers too.
            let answer = self.deliver(&stretch, now, idle);
            self.answer(answer, fault, now);
        }
        let decided = self.tap.stream_offset();
        let rest = self.take_held(decided);
        let answer = self.deliver(&rest, now, idle);
        self.answer(answer, None, now);
    }

    /// Removes and returns the held bytes before stream offset `end`.
    fn take_held(&mut self, end: u64) -> Vec<u8> {
        let n = usize::try_from(end.saturating_sub(self.held_at))
            .unwrap_or(usize::MAX)
            .min(self.held.len());
        self.held_at += n as u64;
        self.held.drain(..n).collect()
    }

    /// Logs and counts what the tap saw; draws the fault for a frame addressed to a device of the bus.
    fn watch(&mut self, event: &Event<'_>) -> Option<Fault> {
        match event {
            Event::Frame(frame) => {
                if !self.devices.iter().any(|d| d.endpoint.config().accepts(&frame.dest)) {
                    self.stats.frames_ignored += 1;
                    debug!(dest = %frame.dest, "rx frame for another address");
                    return None;
                }
                self.stats.frames_in += 1;
                log_frame("rx frame", frame);
                let fault = self.faults.draw();
                if let Some(f) = fault {
                    warn!(fault = f.name(), dest = %frame.dest, "fault injected");
                }
                fault
            }
            Event::BadChecksum(bad) => {
                self.stats.bad_checksums_in += 1;
                let ours = self.devices.iter().any(|d| d.endpoint.config().answers(&bad.dest));
                warn!(dest = %bad.dest, source = bad.source, expected = bad.expected, found = bad.found,
                    ours, "rx damaged frame");
                None
            }
            Event::Ack => {
                self.stats.acks_in += 1;
                None
            }
            Event::Nak => {
                self.stats.naks_in += 1;
                None
            }
            Event::Nic => {
                debug!("rx NIC from the master (ignored)");
                None
            }
        }
    }

    /// Every endpoint hears `bytes` (then, on `idle`, the line's silence);
    /// returns what they wrote.
    fn deliver(&mut self, bytes: &[u8], now: u64, idle: bool) -> Answer {
        let mut answer = Answer::default();
        if bytes.is_empty() && !idle {
            return answer;
        }
        for dev in &mut self.devices {
            let resent = dev.endpoint.stats().results_resent;
            let mut out = |b: &[u8]| answer.pieces.push(b.to_vec());
            dev.endpoint.receive(bytes, now, &mut dev.gimbal, &mut out);
            if idle {
                dev.endpoint.line_idle(now, &mut dev.gimbal, &mut out);
            }
            answer.resent |= dev.endpoint.stats().results_resent > resent;
            if let Some(rate) = dev.gimbal.take_rate_change() {
                answer.switch_to = Some(rate);
            }
        }
        answer
    }

    /// Queues the endpoints' answer with the exchange's fault applied.
    fn answer(&mut self, mut answer: Answer, fault: Option<Fault>, now: u64) {
        let mut start = now;
        match fault {
            Some(Fault::DropAck) => {
                if let Some(i) = answer.pieces.iter().position(|p| p.as_slice() == [ACK]) {
                    answer.pieces.remove(i);
                }
            }
            Some(Fault::Corrupt) => self.corrupt_answer(&mut answer.pieces),
            Some(Fault::Delay) => start += self.faults.config().delay_ms,
            _ => {}
        }
        if answer.resent && self.faults.draw_corrupt() {
            if let Some(frame) = answer.pieces.iter_mut().find(|p| p.len() > 1) {
                corrupt_frame(frame, &mut self.faults);
                warn!(fault = "corrupt", "fault injected into resent result");
            }
        }
        for piece in answer.pieces {
            // A result frame leaves after the device's "time delay"; ACK, NAK and NIC at once.
            let due = if piece.len() > 1 {
                start + self.config.reply_latency_ms
            } else {
                start
            };
            self.queue(due, piece, None);
        }
        if let Some(rate) = answer.switch_to {
            self.queue(start, Vec::new(), Some(rate));
        }
        // An `IX` with no duration finishes at once.
        self.advance(now);
    }

    /// Damages one byte of the answer: a payload byte of the result frame,
    /// else the ACK or NIC byte. (The endpoint keeps its clean copy for a
    /// resend on NAK.)
    fn corrupt_answer(&mut self, pieces: &mut [Vec<u8>]) {
        if let Some(frame) = pieces.iter_mut().find(|p| p.len() > 1) {
            corrupt_frame(frame, &mut self.faults);
        } else if let Some(byte) = pieces.iter_mut().find(|p| p.len() == 1) {
            // 0x06 -> 0x46 'F', '?' -> 0x7F: noise, no longer an ACK or NIC.
            byte[0] ^= 0x40;
        }
    }
}

/// Flips the low bit of one payload byte of an encoded frame.
fn corrupt_frame(frame: &mut [u8], faults: &mut Faults) {
    let Ok((parsed, _)) = Frame::parse(frame) else {
        return;
    };
    let payload = layout::payload(parsed.header().len);
    let i = payload.start + faults.pick(payload.len());
    frame[i] ^= 0x01;
}

fn log_frame(what: &'static str, frame: &Frame<'_>) {
    let command = Command::parse(frame.payload());
    debug!(
        dest = %frame.dest,
        source = frame.source,
        payload = %String::from_utf8_lossy(frame.payload()).escape_debug(),
        command = command.mnemonic(),
        "{what}"
    );
}

fn log_outgoing(out: &Outgoing) {
    match out.bytes.as_slice() {
        [] => {}
        [ACK] => debug!("tx ACK"),
        [NAK] => debug!("tx NAK"),
        [NIC] => debug!("tx NIC"),
        bytes => match Frame::parse(bytes) {
            Ok((frame, _)) => debug!(
                dest = %frame.dest,
                source = frame.source,
                payload = %String::from_utf8_lossy(frame.payload()).escape_debug(),
                "tx result"
            ),
            Err(_) => {
                let hex: String = bytes.iter().map(|b| format!("{b:02X}")).collect();
                debug!(bytes = %hex, "tx damaged bytes")
            }
        },
    }
    if let Some(rate) = out.switch_to {
        info!(bps = rate.bits_per_second(), "line switches data rate");
    }
}
