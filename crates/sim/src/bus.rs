//! A bus (one serial line, Figure 3) of simulated gimbals, sans-IO: bytes in
//! with the time they arrived, bytes out with the time they are due.
//!
//! Each gimbal sits behind the protocol crate's [`DeviceEndpoint`] (address
//! filter, ACK/NAK, NIC, Table 3 reply header). The bus runs one framer over
//! the line so that it can give each endpoint whole frames, NAK damaged
//! frames addressed to one of its devices (1.4.2), resend the last result
//! when the master NAKs it, and apply seeded faults ([`crate::faults`]) per
//! exchange. Every frame in and out is logged with `tracing`.

use sagebrush_protocol::{
    ACK, BadChecksum, Command, DataRate, DeviceEndpoint, EndpointConfig, Event, Frame, FrameBuf, Framer, NAK, NIC,
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
    /// How long after a result a NAK from the master makes the device resend it, milliseconds.
    pub nak_window_ms: u64,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            devices: vec![GimbalConfig::default()],
            faults: FaultConfig::default(),
            reply_latency_ms: 0,
            idle_ms: 100,
            nak_window_ms: 1000,
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
    /// Damaged frames seen on the line.
    pub bad_checksums_in: u64,
    /// NAKs sent for damaged frames (fault-injected ones included).
    pub naks_sent: u64,
    /// Results sent again after a NAK from the master.
    pub results_resent: u64,
    /// NACKs and ACKs from the master, counted for the log.
    pub naks_in: u64,
    pub acks_in: u64,
}

#[derive(Debug)]
struct Device {
    endpoint: DeviceEndpoint,
    gimbal: Gimbal,
}

#[derive(Clone, Debug)]
struct LastResult {
    bytes: Vec<u8>,
    sent_at: u64,
    resends: u8,
}

/// What the line framer found.
enum Inbound {
    Frame(Box<FrameBuf>),
    Bad(BadChecksum),
    Ack,
    Nak,
    Nic,
}

/// Most times a result is resent on NAK.
const MAX_RESENDS: u8 = 3;

/// A simulated bus of gimbals.
#[derive(Debug)]
pub struct Bus {
    devices: Vec<Device>,
    framer: Framer,
    faults: Faults,
    outbox: Vec<Outgoing>,
    last_rx: u64,
    last_result: Option<LastResult>,
    config: BusConfig,
    stats: BusStats,
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
            framer: Framer::new(),
            faults: Faults::new(config.faults),
            outbox: Vec::new(),
            last_rx: now,
            last_result: None,
            config,
            stats: BusStats::default(),
        })
    }

    pub fn stats(&self) -> BusStats {
        self.stats
    }

    /// Faults injected so far, by kind.
    pub fn faults_injected(&self, fault: Fault) -> u64 {
        self.faults.injected(fault)
    }

    /// Bytes on the line that were part of no frame or bare ACK/NAK/NIC.
    pub fn noise_bytes(&self) -> u64 {
        self.framer.skipped_bytes()
    }

    /// The gimbals, in configuration order.
    pub fn gimbals(&self) -> impl Iterator<Item = &Gimbal> {
        self.devices.iter().map(|d| &d.gimbal)
    }

    /// The gimbal currently at `device`.
    pub fn gimbal(&self, device: u8) -> Option<&Gimbal> {
        self.gimbals().find(|g| g.device() == device)
    }

    /// Bytes received from the line at `now`.
    pub fn receive(&mut self, bytes: &[u8], now: u64) {
        self.advance(now);
        self.last_rx = now;
        let mut inbound = Vec::new();
        self.framer.feed(bytes, |event| inbound.push(Inbound::from(event)));
        for event in inbound {
            self.process(event, now);
        }
    }

    /// Time passed: physics, results that became due (`IX`), and a partial
    /// frame abandoned after [`BusConfig::idle_ms`] of silence.
    pub fn poll(&mut self, now: u64) {
        self.advance(now);
        if self.framer.buffered() > 0 && now >= self.last_rx + self.config.idle_ms {
            let mut inbound = Vec::new();
            self.framer.flush_idle(|event| inbound.push(Inbound::from(event)));
            for event in inbound {
                self.process(event, now);
            }
        }
    }

    /// When [`Bus::poll`] or [`Bus::pop_due`] next has something to do.
    pub fn next_deadline(&self) -> Option<u64> {
        let idle = (self.framer.buffered() > 0).then_some(self.last_rx + self.config.idle_ms);
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
            self.remember_result(&bytes, at);
            self.queue(at, bytes, None);
        }
    }

    fn queue(&mut self, due: u64, bytes: Vec<u8>, switch_to: Option<DataRate>) {
        let at = self.outbox.partition_point(|o| o.due <= due);
        self.outbox.insert(at, Outgoing { due, bytes, switch_to });
    }

    fn remember_result(&mut self, bytes: &[u8], sent_at: u64) {
        self.last_result = Some(LastResult {
            bytes: bytes.to_vec(),
            sent_at,
            resends: 0,
        });
    }

    fn process(&mut self, event: Inbound, now: u64) {
        match event {
            Inbound::Frame(frame) => self.exchange(&frame, now),
            Inbound::Bad(bad) => {
                self.stats.bad_checksums_in += 1;
                let ours = self.devices.iter().any(|d| d.endpoint.config().answers(&bad.dest));
                warn!(dest = %bad.dest, source = bad.source, expected = bad.expected, found = bad.found,
                    ours, "rx damaged frame");
                if ours {
                    self.stats.naks_sent += 1;
                    self.queue(now, vec![NAK], None);
                }
            }
            Inbound::Ack => {
                self.stats.acks_in += 1;
                self.last_result = None;
            }
            Inbound::Nak => {
                self.stats.naks_in += 1;
                self.resend_result(now);
            }
            Inbound::Nic => debug!("rx NIC from the master (ignored)"),
        }
    }

    /// The master NAKed our last result: send it again (1.4.2, hop by hop).
    fn resend_result(&mut self, now: u64) {
        let window = self.config.nak_window_ms;
        let Some(last) = self.last_result.as_mut() else {
            debug!("rx NAK with no result to resend");
            return;
        };
        if now > last.sent_at + window || last.resends >= MAX_RESENDS {
            debug!("rx NAK too late or too often: result not resent");
            return;
        }
        last.resends += 1;
        let mut bytes = last.bytes.clone();
        if self.faults.draw_corrupt() {
            corrupt_frame(&mut bytes, &mut self.faults);
            warn!(fault = "corrupt", "fault injected into resent result");
        }
        self.stats.results_resent += 1;
        let due = now + self.config.reply_latency_ms;
        self.queue(due, bytes, None);
    }

    /// One command frame: faults, every endpoint, the answers queued.
    fn exchange(&mut self, frame: &FrameBuf, now: u64) {
        let view = frame.frame();
        if !self.devices.iter().any(|d| d.endpoint.config().accepts(&view.dest)) {
            self.stats.frames_ignored += 1;
            debug!(dest = %view.dest, "rx frame for another address");
            return;
        }
        self.stats.frames_in += 1;
        log_frame("rx frame", &view);
        let fault = self.faults.draw();
        if let Some(f) = fault {
            warn!(fault = f.name(), dest = %view.dest, "fault injected");
        }
        if fault == Some(Fault::Silent) {
            return;
        }
        let mut bytes = frame.as_bytes().to_vec();
        if fault == Some(Fault::Nak) {
            // Damaged in transit: the checksum no longer holds, the device NAKs.
            if let Some(last) = bytes.last_mut() {
                *last = last.wrapping_add(1);
            }
            self.stats.bad_checksums_in += 1;
        }
        let mut pieces: Vec<Vec<u8>> = Vec::new();
        let mut switch_to = None;
        for dev in &mut self.devices {
            let answers = dev.endpoint.config().answers(&view.dest);
            dev.gimbal.set_answering(answers);
            let naks_before = dev.endpoint.stats().naks_sent;
            dev.endpoint
                .receive(&bytes, now, &mut dev.gimbal, &mut |b: &[u8]| pieces.push(b.to_vec()));
            self.stats.naks_sent += dev.endpoint.stats().naks_sent - naks_before;
            if let Some(rate) = dev.gimbal.take_rate_change() {
                switch_to = Some(rate);
            }
        }
        let mut start = now;
        let mut clean = None;
        match fault {
            Some(Fault::DropAck) => {
                if let Some(i) = pieces.iter().position(|p| p.as_slice() == [ACK]) {
                    pieces.remove(i);
                }
            }
            Some(Fault::Corrupt) => clean = self.corrupt_answer(&mut pieces),
            Some(Fault::Delay) => start += self.faults.config().delay_ms,
            _ => {}
        }
        for piece in pieces {
            let due = if piece.len() > 1 {
                let due = start + self.config.reply_latency_ms;
                self.remember_result(clean.as_deref().unwrap_or(&piece), due);
                due
            } else {
                start
            };
            self.queue(due, piece, None);
        }
        if let Some(rate) = switch_to {
            self.queue(start, Vec::new(), Some(rate));
        }
        // An `IX` with no duration finishes at once.
        self.advance(now);
    }

    /// Damages one byte of the answer: a payload byte of the result frame
    /// (returning the clean copy, for a resend on NAK), else the ACK or NIC byte.
    fn corrupt_answer(&mut self, pieces: &mut [Vec<u8>]) -> Option<Vec<u8>> {
        if let Some(frame) = pieces.iter_mut().find(|p| p.len() > 1) {
            let clean = frame.clone();
            corrupt_frame(frame, &mut self.faults);
            return Some(clean);
        }
        if let Some(byte) = pieces.iter_mut().find(|p| p.len() == 1) {
            // 0x06 -> 0x46 'F', '?' -> 0x7F: noise, no longer an ACK or NIC.
            byte[0] ^= 0x40;
        }
        None
    }
}

/// Flips the low bit of one payload byte of an encoded frame.
fn corrupt_frame(frame: &mut [u8], faults: &mut Faults) {
    const HEADER: usize = 6;
    if frame.len() > HEADER + 1 {
        let i = HEADER + faults.pick(frame.len() - HEADER - 1);
        frame[i] ^= 0x01;
    }
}

impl From<Event<'_>> for Inbound {
    fn from(event: Event<'_>) -> Self {
        match event {
            Event::Frame(f) => Inbound::Frame(Box::new(FrameBuf::from_frame(&f))),
            Event::BadChecksum(b) => Inbound::Bad(b),
            Event::Ack => Inbound::Ack,
            Event::Nak => Inbound::Nak,
            Event::Nic => Inbound::Nic,
        }
    }
}

fn log_frame(what: &'static str, frame: &Frame<'_>) {
    let command = Command::parse(frame.payload());
    info!(
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
        [NAK] => info!("tx NAK"),
        [NIC] => info!("tx NIC"),
        bytes => match Frame::parse(bytes) {
            Ok((frame, _)) => info!(
                dest = %frame.dest,
                source = frame.source,
                payload = %String::from_utf8_lossy(frame.payload()).escape_debug(),
                "tx result"
            ),
            Err(_) => info!(bytes = ?bytes, "tx damaged bytes"),
        },
    }
    if let Some(rate) = out.switch_to {
        info!(bps = rate.bits_per_second(), "line switches data rate");
    }
}
