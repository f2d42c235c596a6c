//! The clients: each a spec-following MCU on its own link that issues
//! random commands, retransmits, and checks every answer and report it gets.

use super::*;

#[derive(Debug)]
pub(super) enum ClientState {
    Idle,
    AwaitAck {
        tx: Transmitter,
        frame: Box<FrameBuf>,
        kind: ResultKind,
    },
    AwaitAnswer {
        until: u64,
    },
}

#[derive(Debug)]
pub(super) struct Client {
    /// A TCP client: a lossless link and wire, which asks for end-of-window
    /// reports (`~W`) first on every connection.
    pub(super) tcp: bool,
    /// gcud agreed (`~W=`): a report `00` after the ACK ends the NIC wait.
    pub(super) windowed: bool,
    /// `~W` is still to be asked on this connection.
    pub(super) ask_window: bool,
    pub(super) gcu: usize,
    pub(super) link: LinkId,
    pub(super) group: u8,
    pub(super) filter: SourceFilter,
    pub(super) connected: bool,
    pub(super) epoch: u64,
    pub(super) framer: Framer,
    pub(super) state: ClientState,
    pub(super) issued: Vec<Address>,
    pub(super) nonces: BTreeSet<u16>,
    pub(super) counter: u16,
    pub(super) to_issue: usize,
    pub(super) next_at: u64,
    pub(super) forced: Option<(Address, Vec<u8>)>,
    pub(super) nics: u64,
    pub(super) last_rx: u64,
    /// Every frame the router wrote to this client's link.
    pub(super) written: BTreeSet<Vec<u8>>,
    /// Destination and checksum of the command awaiting its ACK or report.
    pub(super) current: Option<(Address, u8)>,
    /// Commands it gave up on, or was told of: a report of one of them may
    /// come late, or again (its ACK of the report frame was lost).
    pub(super) abandoned: BTreeSet<(Address, u8)>,
    /// Commands it gave up on by itself (its ACK time-out and retries) with
    /// no outcome from gcud, which may still have been working on them.
    pub(super) gave_up: BTreeSet<(Address, u8)>,
    /// Commands it took an ACK for while its framer held damaged bytes
    /// (perhaps a byte of a damaged frame, not the GCU's ACK), and when:
    /// each may still get its report, after any number of later commands.
    pub(super) tainted_acked: BTreeMap<(Address, u8), u64>,
    /// Which bytes toward it were damaged, and whether its framer holds some.
    pub(super) wire: ClientWire,
    /// The last delivery report frame it took, and when.
    pub(super) last_report: Option<(u64, Vec<u8>)>,
    /// The command whose answer (result, NIC) it awaits after its ACK, and its payload.
    pub(super) answering: Option<(CommandKey, Vec<u8>)>,
}

/// How long after a report the GCU may send it again (its link retry
/// budget: retries + 1 ACK time-outs, plus the wire's jitter).
const REPORT_REPEAT_WINDOW: u64 = 4 * 40 + 10;

/// How long after a tainted ACK the command's report can still come: the
/// GCU's delivery time-out (450) and its report's retry budget, with the
/// wire's delays both ways. A report later than that is excused by nothing.
const TAINTED_ACK_WINDOW: u64 = 450 + REPORT_REPEAT_WINDOW + 2 * 10;

/// The damage on a client's incoming wire, tracked write by write so that
/// an excuse (a phantom ACK or frame) is granted only for bytes a wire
/// actually damaged.
#[derive(Debug, Default)]
pub(super) struct ClientWire {
    /// Writes toward the client scheduled on its wire, and delivered (the
    /// wire is FIFO and loses nothing once a write is scheduled).
    sent: u64,
    delivered: u64,
    /// Sequence numbers of scheduled writes that were damaged.
    damaged: BTreeSet<u64>,
    /// Sequence numbers of scheduled writes with a `?` a GCU relayed from
    /// another GCU's link.
    relayed: BTreeSet<u64>,
    /// Sequence numbers of scheduled writes with a `?` written just after
    /// a port of the GCU heard damaged bytes (a byte of a damaged frame may
    /// have been taken for a `?`).
    bus_tainted: BTreeSet<u64>,
    /// The framer has taken damaged bytes since the line was last idle
    /// (idle resets the framer: nothing of them is left after it).
    tainted: bool,
}

impl ClientWire {
    /// A write toward the client was scheduled, `damaged` or not.
    pub(super) fn scheduled(&mut self, damaged: bool, relayed: bool, bus_tainted: bool) {
        if bus_tainted {
            self.bus_tainted.insert(self.sent);
        }
        if damaged {
            self.damaged.insert(self.sent);
        }
        if relayed {
            self.relayed.insert(self.sent);
        }
        self.sent += 1;
    }

    /// The next scheduled write arrives: whether it was damaged (or may
    /// carry a `?` a port took from damaged bytes), and
    /// whether it carries a `?` relayed from another GCU.
    pub(super) fn arrived(&mut self) -> (bool, bool) {
        let seq = self.delivered;
        self.delivered += 1;
        let bus_tainted = self.bus_tainted.remove(&seq);
        (self.damaged.remove(&seq) || bus_tainted, self.relayed.remove(&seq))
    }
}

impl World {
    pub(super) fn client_up(&mut self, c: usize) {
        let cl = &mut self.clients[c];
        cl.connected = true;
        cl.framer = Framer::new();
        cl.state = ClientState::Idle;
        cl.windowed = false;
        cl.ask_window = cl.tcp;
        let (g, link, filter) = (cl.gcu, cl.link, cl.filter.clone());
        let mut config = LinkConfig::new(LinkKind::Client, filter);
        config.lossless = cl.tcp;
        self.input(g, Input::LinkUp { link, config });
    }

    pub(super) fn client_down(&mut self, c: usize) {
        let cl = &mut self.clients[c];
        cl.connected = false;
        cl.epoch += 1;
        cl.state = ClientState::Idle;
        if let Some(current) = cl.current.take() {
            cl.abandoned.insert(current);
        }
        // The answer awaited may still come, to the next connection here
        // (the simulation gives it the same link id; gcud gives every
        // accepted connection a new one).
        if let Some(((dest, _, checksum), _)) = cl.answering.take() {
            cl.abandoned.insert((dest, checksum));
        }
        let (g, link) = (cl.gcu, cl.link);
        self.input(g, Input::LinkDown { link });
    }

    pub(super) fn client_write(&mut self, c: usize, bytes: Vec<u8>) {
        let cl = &self.clients[c];
        let (from, to, epoch) = (
            Node::Client { c },
            Node::Link {
                g: cl.gcu,
                link: cl.link,
            },
            cl.epoch,
        );
        self.send_on_wire(from, to, bytes, epoch);
    }

    pub(super) fn random_command(&mut self, c: usize) -> (Address, Vec<u8>) {
        let own = self.clients[c].gcu;
        let g = if self.gcus.len() > 1 && self.rng.chance(400) {
            self.rng.below(self.gcus.len() as u64) as usize
        } else {
            own
        };
        let group = match self.rng.below(100) {
            0..=3 => WILDCARD,
            4..=6 => self.rng.range(61, 90) as u8, // no such GCU
            _ => self.gcus[g].group,
        };
        let ports: Vec<u8> = self.gcus[g].ports.iter().map(|p| p.id).collect();
        let pi = self.rng.below(ports.len() as u64) as usize;
        let port = match self.rng.below(100) {
            0..=5 => WILDCARD,
            6..=10 => 0,
            11..=14 => self.rng.range(9, 20) as u8,
            _ => ports[pi],
        };
        let ids: Vec<u8> = self.gcus[g].ports[pi].devices.iter().map(|d| d.gimbal.id).collect();
        let device = match self.rng.below(100) {
            0..=5 => WILDCARD,
            6..=12 => self.rng.range(10, 30) as u8,
            _ => self.rng.pick(&ids),
        };
        let payload: Vec<u8> = match self.rng.below(100) {
            0..=9 => b"AW".to_vec(),
            10..=17 => b"P?".to_vec(),
            18..=20 => b"D?".to_vec(),
            21..=34 => {
                let cl = &mut self.clients[c];
                cl.counter = cl.counter.wrapping_add(1);
                cl.nonces.insert(cl.counter);
                format!("*muN{:02X}{:04X}", c, cl.counter).into_bytes()
            }
            35..=37 => b"*mu".to_vec(),
            38..=40 => b"IX".to_vec(),
            41..=58 => self
                .rng
                .pick(&[&b"PL"[..], b"PR", b"TU", b"TD", b"FF", b"FN", b"ZI", b"ZO"])
                .to_vec(),
            59..=74 => self
                .rng
                .pick(&[&b"PS"[..], b"TS", b"FS", b"ZS", b"HA", b"HS", b"PT"])
                .to_vec(),
            75..=82 => self.rng.pick(&[&b"HO"[..], b"P00640064", b"SP5", b"VM1"]).to_vec(),
            83..=85 => format!("C{:X}", self.rng.range(3, 15)).into_bytes(),
            86..=92 => self.rng.pick(&[&b"QQ"[..], b"FA", b"Z?x"]).to_vec(),
            _ => b"HO".to_vec(),
        };
        (Address::new(group, port, device), payload)
    }

    pub(super) fn client_issue(&mut self, c: usize, dest: Address, payload: Vec<u8>) {
        let group = self.clients[c].group;
        let Ok(frame) = FrameBuf::new(dest, group, &payload) else {
            return self.violation("generator built an invalid frame".into());
        };
        let kind = Command::parse(&payload).result_kind();
        let mut tx = Transmitter::new(CLIENT_RETRY);
        let _ = tx.start(self.now);
        let bytes = frame.as_bytes().to_vec();
        let cl = &mut self.clients[c];
        cl.issued.push(dest);
        cl.current = Some((dest, frame.frame().checksum()));
        cl.state = ClientState::AwaitAck {
            tx,
            frame: Box::new(frame),
            kind,
        };
        self.log(format_args!(
            "client {c} (group {group}) issues {} to {dest}",
            String::from_utf8_lossy(&payload)
        ));
        self.client_write(c, bytes);
    }

    pub(super) fn client_deadline(&self, c: usize) -> Option<u64> {
        let cl = &self.clients[c];
        if !cl.connected {
            return None;
        }
        match &cl.state {
            ClientState::Idle if cl.ask_window => Some(self.now),
            ClientState::Idle if cl.forced.is_some() || (cl.to_issue > 0 && !self.quiet) => Some(cl.next_at),
            ClientState::Idle => None,
            ClientState::AwaitAck { tx, .. } => tx.deadline(),
            ClientState::AwaitAnswer { until } => Some(*until),
        }
    }

    pub(super) fn client_poll(&mut self, c: usize) {
        let now = self.now;
        let cl = &mut self.clients[c];
        match &mut cl.state {
            ClientState::Idle => {
                if cl.ask_window {
                    cl.ask_window = false;
                    let to = Address::new(self.gcus[cl.gcu].group, 0, 0);
                    return self.client_issue(c, to, b"~W".to_vec());
                }
                if let Some((dest, payload)) = cl.forced.take() {
                    return self.client_issue(c, dest, payload);
                }
                if cl.to_issue > 0 && now >= cl.next_at && !self.quiet {
                    cl.to_issue -= 1;
                    let (dest, payload) = self.random_command(c);
                    self.client_issue(c, dest, payload);
                }
            }
            ClientState::AwaitAck { tx, frame, .. } => {
                if tx.deadline().is_some_and(|t| now >= t) {
                    match tx.poll(now) {
                        TxStep::Send => {
                            let bytes = frame.as_bytes().to_vec();
                            self.client_write(c, bytes);
                        }
                        TxStep::Failed(_) => self.client_gave_up(c),
                        _ => {}
                    }
                }
            }
            ClientState::AwaitAnswer { until } => {
                if now >= *until {
                    self.client_idle(c);
                }
            }
        }
    }

    pub(super) fn client_idle(&mut self, c: usize) {
        let pause = self.rng.range(0, 40);
        let cl = &mut self.clients[c];
        cl.state = ClientState::Idle;
        cl.answering = None;
        cl.next_at = self.now + pause;
    }

    /// Bytes arrive (`damaged`: a wire changed one of them).
    pub(super) fn client_receive(&mut self, c: usize, bytes: &[u8], damaged: bool, relayed: bool) {
        let mut events = Vec::new();
        let now = self.now;
        self.log(format_args!(
            "client {c} <- {bytes:02X?}{}",
            if damaged { " (damaged)" } else { "" }
        ));
        self.summary.client_damaged_writes += u64::from(damaged);
        let cl = &mut self.clients[c];
        if now.saturating_sub(cl.last_rx) >= SILENCE {
            cl.framer.line_idle();
            let tainted = cl.wire.tainted;
            while let Some(e) = cl.framer.next_event() {
                events.push((e.to_owned(), tainted));
            }
            cl.wire.tainted = false;
        }
        cl.last_rx = now;
        if damaged {
            cl.wire.tainted = true;
        }
        let tainted = cl.wire.tainted;
        cl.framer.feed(bytes, |e| events.push((e.to_owned(), tainted)));
        for (event, tainted) in events {
            match event {
                OwnedEvent::Nic => {
                    self.clients[c].nics += 1;
                    // A `?` follows the ACK of its command: one while the ACK
                    // is awaited is a late answer to an earlier command.
                    if matches!(self.clients[c].state, ClientState::AwaitAnswer { .. }) {
                        self.check_nic(c, tainted, relayed);
                        self.client_idle(c);
                    }
                }
                OwnedEvent::BadChecksum(_) => self.client_write(c, vec![NAK]),
                OwnedEvent::Ack => self.client_ack(c, tainted),
                OwnedEvent::Nak => self.client_nak(c),
                OwnedEvent::Frame(f) => {
                    self.client_write(c, vec![ACK]);
                    let frame = f.frame();
                    let report = (frame.dest.port == 0 && frame.dest.device == 0)
                        .then(|| DeliveryReport::parse(frame.payload()).ok())
                        .flatten();
                    if let Some(report) = report.filter(|_| self.clients[c].written.contains(f.as_bytes())) {
                        // The GCU sends a report again when our ACK of it was
                        // lost: a byte-identical one within its retry budget
                        // (4 tries of 40 ms) is that copy, not a new outcome
                        // (the next command may have the same address and
                        // checksum).
                        let now = self.now;
                        let cl = &mut self.clients[c];
                        let repeat = cl
                            .last_report
                            .as_ref()
                            .is_some_and(|(at, bytes)| bytes == f.as_bytes() && now <= at + REPORT_REPEAT_WINDOW);
                        cl.last_report = Some((now, f.as_bytes().to_vec()));
                        if repeat {
                            self.summary.repeated_reports += 1;
                            continue;
                        }
                        self.client_report(c, &report);
                        continue;
                    }
                    if f.frame().payload() == b"~W=" {
                        self.clients[c].windowed = true;
                    }
                    self.check_reply(c, &f, tainted);
                    if matches!(self.clients[c].state, ClientState::AwaitAnswer { .. }) && self.may_answer(c, &f) {
                        self.check_answer(c, &f, tainted);
                        self.client_idle(c);
                    }
                }
            }
        }
    }

    /// Whether frame `f` may be the result the client awaits. A command
    /// acknowledged with no result has none: only a NIC may follow its ACK
    /// (1.4.2), and a master takes no frame for it (the protocol crate's
    /// `Transaction`); an earlier command's late result (an `IX` of this
    /// group's after an `HS`'s ACK, seed 187256) does not end its window.
    /// A TCP client reads the header as gimbalctl's master does (Table 3:
    /// port and device as addressed, from the group addressed, a wildcard
    /// standing for any), so that another command's late result (another
    /// group's for the same port and device, seeds 17885, 23159) does not
    /// end the wait before its report `00` comes; the others take any frame.
    fn may_answer(&self, c: usize, f: &FrameBuf) -> bool {
        let cl = &self.clients[c];
        let Some(((dest, ..), payload)) = &cl.answering else {
            return true;
        };
        if Command::parse(payload).result_kind() == ResultKind::None {
            return false;
        }
        let (got, from) = (f.frame().dest, f.frame().source);
        let level = |want: u8, got: u8| want == WILDCARD || want == got;
        !cl.tcp || (level(dest.group, from) && level(dest.port, got.port) && level(dest.device, got.device))
    }

    /// An ACK (`tainted`: perhaps a byte of a damaged frame).
    pub(super) fn client_ack(&mut self, c: usize, tainted: bool) {
        let now = self.now;
        if let ClientState::AwaitAck { tx, kind, frame } = &mut self.clients[c].state {
            if tx.on_ack() == TxStep::Delivered {
                let f = frame.frame();
                let key = ((f.dest, f.source, f.checksum()), f.payload().to_vec());
                let wait = if *kind == ResultKind::None { 60 } else { 3_000 };
                self.clients[c].state = ClientState::AwaitAnswer { until: now + wait };
                let cl = &mut self.clients[c];
                cl.answering = Some(key);
                if let Some(key) = cl.current.take().filter(|_| tainted) {
                    cl.tainted_acked.insert(key, now);
                }
                self.summary.tainted_acks += u64::from(tainted);
                self.summary.client_delivered += 1;
                self.log(format_args!("client {c}: ACK (delivered)"));
            }
        }
    }

    pub(super) fn client_nak(&mut self, c: usize) {
        let now = self.now;
        if let ClientState::AwaitAck { tx, frame, .. } = &mut self.clients[c].state {
            match tx.on_nak(now) {
                TxStep::Send => {
                    let bytes = frame.as_bytes().to_vec();
                    self.client_write(c, bytes);
                }
                TxStep::Failed(_) => self.client_gave_up(c),
                _ => {}
            }
        }
    }

    pub(super) fn client_gave_up(&mut self, c: usize) {
        self.summary.client_gave_up += 1;
        let cl = &mut self.clients[c];
        if let Some(current) = cl.current.take() {
            cl.abandoned.insert(current);
            cl.gave_up.insert(current);
        }
        self.client_idle(c);
    }

    /// A delivery report (ARCHITECTURE "Delivery contract") must be about
    /// the command this client awaits (or one it gave up on), and comes
    /// instead of the ACK: exactly one outcome per command.
    pub(super) fn client_report(&mut self, c: usize, report: &DeliveryReport) {
        let key = (report.dest, report.command_checksum);
        let cl = &mut self.clients[c];
        let awaiting = matches!(cl.state, ClientState::AwaitAck { .. });
        if awaiting && cl.current == Some(key) && report.failure.is_some() {
            cl.current = None;
            cl.abandoned.insert(key);
            self.summary.client_undelivered += 1;
            self.log(format_args!("client {c}: not delivered: {report:?}"));
            return self.client_idle(c);
        }
        if cl.abandoned.contains(&key) {
            return;
        }
        let waiting = matches!(cl.state, ClientState::AwaitAnswer { .. });
        let answering = cl
            .answering
            .as_ref()
            .is_some_and(|(k, _)| *k == (key.0, cl.group, key.1));
        if report.failure.is_none() && cl.windowed && waiting && answering {
            // gcud's NIC window passed with no NIC (`World::write_link`
            // checks that against the NICs that reached its port).
            self.summary.window_reports += 1;
            self.log(format_args!("client {c}: NIC window passed"));
            return self.client_idle(c);
        }
        let now = self.now;
        cl.tainted_acked.retain(|_, at| now <= *at + TAINTED_ACK_WINDOW);
        if cl.tainted_acked.remove(&key).is_some() {
            // The ACK it took for this command came with damaged bytes: a
            // damaged frame's byte, not the GCU's (later commands may have
            // been ACKed since). Only then, and only within the time its
            // report can take, is a report after an ACK excused.
            self.summary.phantom_acks += 1;
            cl.abandoned.insert(key);
            return;
        }
        let current = cl.current;
        self.violation(format!(
            "client {c} got a report {report:?} that answers none of its commands (awaiting {current:?})"
        ));
    }

    /// A `?` after the ACK of a command answers that command (1.4.2): some
    /// device answered that very frame NIC, early or late, or the command
    /// was for a GCU itself (port 0, which answers NIC itself). The late
    /// NICs of the devices (`devices::LATE_NIC_PM`) must never make another
    /// command's `?`. Excused and counted, each kept apart: a `?` taken
    /// while the framer held damaged bytes (perhaps a damaged byte), and
    /// the `?`s gcud relays that name no command in ways this issue did not
    /// change (below).
    pub(super) fn check_nic(&mut self, c: usize, tainted: bool, relayed: bool) {
        let Some((key, payload)) = self.clients[c].answering.clone() else {
            return;
        };
        // Only a NIC that reached gcud's port can be the `?` gcud relays: a
        // device's NIC that leaves late, after gcud's window (its report
        // `00` may then come), is not the `?` that came before it (seed
        // 165293: a fan-out's, taken for a `CD` its device NICs later).
        let reached = |h: &Heard| self.nics_at_port.contains_key(&h.key);
        if key.0.port == 0 || self.nicd.iter().any(|h| h.answers(key, &payload) && reached(h)) {
            self.summary.nics_checked += 1;
            return;
        }
        // Whatever excuses it below, the command's own outcome (its report
        // `00`) may still come.
        self.clients[c].abandoned.insert((key.0, key.2));
        if tainted {
            self.summary.phantom_nics += 1;
            return;
        }
        // The `?` of a group-255 command: every GCU it reached answers it
        // when its own answer comes, however long after the ACK (a result
        // names its group, a `?` nothing). (No longer after a report `03`
        // from the first GCU, which lacked the port while the next had it,
        // seed 1781: delivered anywhere is delivered, `in_flight::Spread`.) Not a
        // port-255 command's: its ACK waits for every job, and its `?`
        // follows within gcud's window (ARCHITECTURE "Delivery contract";
        // seed 165293).
        let cl = &self.clients[c];
        if cl.issued.iter().any(|d| d.group == WILDCARD) {
            self.summary.fan_out_nics += 1;
            return;
        }
        // A `?` another GCU sent over a lossy link between GCUs, for a
        // command it took twice (our copy sent again, its ACK lost). A
        // second `?` of an answered command, or one after the second
        // report `00`, is dropped (seed 8519; `reverse`), and a copy is no
        // longer sent again once its report came (seed 8263); left: the
        // second run's `?` when its report was lost on the way and it came
        // first, while the first run's entry still waits. Counted.
        if relayed {
            self.summary.relayed_nics += 1;
            return;
        }
        // A command the client gave up on by itself (its own ACK time-out
        // and retries: its copies lost or damaged on a lossy client line)
        // while gcud, which had one copy, was still working on it: gcud
        // cannot know, and relays its `?` as the spec has it (1.4.2).
        // Counted. Not a command gcud told it was not delivered (`0B not
        // confirmed` and the rest), nor one of a connection that went down:
        // their `?` is never relayed (ARCHITECTURE "Delivery contract";
        // seeds 13312, 29386, 36507, 49973).
        let gave_up = cl.gave_up.iter().any(|&(dest, checksum)| {
            self.nicd
                .iter()
                .any(|h| h.key == (dest, cl.group, checksum) && reached(h))
        });
        if gave_up {
            self.summary.stale_nics += 1;
            return;
        }
        self.violation(format!(
            "client {c} took a NIC for {}, which no device answered NIC: another command's NIC",
            key.0
        ));
    }

    /// A nonce echo a TCP client takes as its answer is the echo of the
    /// command it awaits (a result names its command only by its Table 3
    /// header, 1.4.3: another command's result to the same device would be
    /// taken for this one's). A serial client takes any frame, and gcud
    /// sends a result again when the client's ACK of it was lost, as a
    /// device does on a bus (1.4.2): taken for the next command's, that
    /// copy is the line's ambiguity, not the router's (seed 427).
    fn check_answer(&mut self, c: usize, f: &FrameBuf, tainted: bool) {
        let payload = f.frame().payload();
        if payload.len() != 7 || payload[0] != b'N' || tainted || !self.clients[c].tcp {
            return;
        }
        let awaited = self.clients[c]
            .answering
            .as_ref()
            .map(|(_, p)| p.clone())
            .unwrap_or_default();
        if awaited.len() == 10 && awaited.starts_with(b"*muN") && awaited[4..] == payload[1..] {
            self.summary.answers_checked += 1;
            return;
        }
        self.violation(format!(
            "client {c} took the result {:?} for its command {:?}",
            String::from_utf8_lossy(payload),
            String::from_utf8_lossy(&awaited)
        ));
    }

    /// No reply reaches a wrong link: the frame is for this client's group,
    /// a nonce echo is one of its own, any other result matches something
    /// it asked.
    pub(super) fn check_reply(&mut self, c: usize, f: &FrameBuf, tainted: bool) {
        let frame = f.frame();
        let cl = &self.clients[c];
        if !cl.written.contains(f.as_bytes()) {
            if !tainted {
                return self.violation(format!(
                    "client {c} got a frame the router never wrote, from undamaged bytes: {f:?}"
                ));
            }
            // Corruption that happens to form a valid frame (an 8-bit
            // checksum passes 1 time in 256): not something the router sent.
            self.summary.phantom_frames += 1;
            return;
        }
        self.summary.client_results += 1;
        if frame.dest.group != cl.group {
            return self.violation(format!(
                "client {c} (group {}) got a frame for group {}",
                cl.group, frame.dest.group
            ));
        }
        let payload = frame.payload();
        if payload.len() == 7 && payload[0] == b'N' {
            let text = String::from_utf8_lossy(&payload[1..]).to_string();
            let owner = u8::from_str_radix(&text[..2], 16).ok();
            let nonce = u16::from_str_radix(&text[2..], 16).ok();
            if owner != Some(c as u8) || !nonce.is_some_and(|n| cl.nonces.contains(&n)) {
                return self.violation(format!("client {c} got another link's answer {text}"));
            }
            self.summary.nonce_results += 1;
            return;
        }
        let level = |want: u8, got: u8| want == WILDCARD || want == got;
        let asked = cl.issued.iter().any(|d| {
            level(d.group, frame.source)
                && level(d.port, frame.dest.port)
                && (level(d.device, frame.dest.device) || (d.port == 0 && frame.dest.device == 0))
        });
        if !asked {
            self.violation(format!(
                "client {c} got a result from {}.{}.{} it never asked for",
                frame.source, frame.dest.port, frame.dest.device
            ));
        }
    }
}
