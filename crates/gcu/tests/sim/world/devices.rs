//! The buses: simulated gimbals (the protocol crate's `DeviceEndpoint`
//! with a small motion model as its handler), their ports, and what happens
//! when a port is lost or opened.

use super::*;

/// Per mille of writes to a buffered port that start a stall of its device
/// server (fault: stalled line).
const STALL_PM: u64 = 20;
/// Per mille of device answers that leave late (fault: late answer), and
/// how late (ms): past the GCU's tries (3 x 20 ms ACK time-outs plus wire
/// time). Only as late as the GCU promises to recognise (ARCHITECTURE
/// "Routing semantics", late answers): see [`World::late_answer_covered`].
const LATE_PM: u64 = 5;
const LATE_MS: (u64, u64) = (90, 150);
/// The GCU gives up on a copy one ACK time-out (20) plus the frame's wire
/// time (at least 9 ms for 9 bytes at 9600 bit/s) after writing it, and
/// the copy reached the device at most the wire's jitter (5) after that
/// write: the late-answer guard starts at least this long after the device
/// answers, so an answer this much later than the guard is still inside it.
const GIVE_UP_AFTER_ANSWER: u64 = 20 + 9 - 5;

/// Every port's NIC window (`PortConfig::nic_window`), as `generate` sets it.
pub(super) const NIC_WINDOW: u64 = 10;
/// Per mille of a device's NICs that leave after its ACK (fault: late
/// NIC), split between just inside gcud's window (its last tick) and just
/// after it (the tick after the window's end: the next exchange on the bus
/// may have started, and its ACK cannot have come yet). The rest come with
/// the ACK (early), and a wire fault may drop the ACK alone (a `?` with no
/// ACK before it).
const LATE_NIC_PM: u64 = 400;

/// A command frame as the device received it: destination, source group,
/// checksum (those of the frame gcud accepted from its client, for a
/// command to one device of one port).
pub(super) type CommandKey = (Address, u8, u8);

/// A command frame a device answered NIC: its key and payload (a fan-out
/// reaches the device with its own port in the header).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Heard {
    pub(super) key: CommandKey,
    pub(super) payload: Vec<u8>,
}

impl Heard {
    /// Whether this is the frame a client sent as `key` with `payload`:
    /// the same source group and payload, to the same address, a wildcard
    /// of the client's standing for any.
    pub(super) fn answers(&self, key: CommandKey, payload: &[u8]) -> bool {
        let level = |want: u8, got: u8| want == WILDCARD || want == got;
        let (want, got) = (key.0, self.key.0);
        self.key.1 == key.1
            && self.payload == payload
            && level(want.group, got.group)
            && level(want.port, got.port)
            && level(want.device, got.device)
    }
}

/// Motion axes of a gimbal: pan, tilt, focus, zoom.
pub(super) const AXES: usize = 4;

pub(super) fn motion_axis(c: &Command<'_>) -> Option<usize> {
    match c {
        Command::PanLeft | Command::PanRight => Some(0),
        Command::TiltUp | Command::TiltDown => Some(1),
        Command::FocusFar | Command::FocusNear => Some(2),
        Command::ZoomIn | Command::ZoomOut => Some(3),
        _ => None,
    }
}

pub(super) fn stopped_axes(c: &Command<'_>) -> &'static [usize] {
    match c {
        Command::PanStop => &[0],
        Command::TiltStop => &[1],
        Command::FocusStop => &[2],
        Command::ZoomStop => &[3],
        Command::Halt | Command::MotorsStop | Command::StopMotion => &[0, 1],
        _ => &[],
    }
}

#[derive(Debug, Default)]
pub(super) struct Gimbal {
    pub(super) id: u8,
    pub(super) moving: [bool; AXES],
    pub(super) echo: Vec<u8>,
    pub(super) pending_rate: Option<u32>,
    pub(super) deferred: Option<ReplyTo>,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, _now: u64) -> Response<'_> {
        if let Some(axis) = motion_axis(&command) {
            self.moving[axis] = true;
            return Response::Done;
        }
        for &axis in stopped_axes(&command) {
            self.moving[axis] = false;
        }
        match command {
            Command::AwakeStatus => Response::Reply(Reply::AwakeStatus(AwakeStatus::new(0).unwrap_or_default())),
            Command::QueryPosition => Response::Reply(Reply::Position(Position::default())),
            Command::Identify => match Identity::new(self.id, *b"19", b"sim gimbal", b"SIM") {
                Ok(id) => Response::Reply(Reply::Identity(id)),
                Err(_) => Response::Nic,
            },
            Command::Initialize => {
                self.deferred = Some(reply_to);
                Response::Deferred
            }
            Command::SetDataRate(rate) => match rate.bits_per_second() {
                Some(bps) => {
                    self.pending_rate = Some(bps);
                    Response::Done
                }
                None => Response::Nic,
            },
            Command::Extended(Extended::UserParameters, args) if !args.is_empty() => {
                self.echo = args.to_vec();
                Response::Reply(Reply::Raw(&self.echo))
            }
            Command::AutoFocusOn | Command::AutoFocusOff => Response::Nic,
            _ => Response::Done,
        }
    }
}

#[derive(Debug)]
pub(super) struct Device {
    pub(super) ep: DeviceEndpoint,
    pub(super) gimbal: Gimbal,
    pub(super) bps: u32,
    /// Last byte heard: a device abandons a partial frame after silence.
    pub(super) last_rx: u64,
    /// The bytes the device heard, framed as its endpoint frames them: which
    /// command a NIC answers ([`World::device_writes`]).
    pub(super) shadow: Framer,
    pub(super) last_command: Option<Heard>,
}

impl Device {
    /// Bytes the device heard, before its endpoint takes them.
    pub(super) fn heard(&mut self, bytes: &[u8]) {
        let last = &mut self.last_command;
        self.shadow.feed(bytes, |e| Self::shadow_event(last, e));
    }

    /// The line was idle: a partial frame is abandoned, as the endpoint does,
    /// and the rescan's frames are recorded like any other, for the endpoint
    /// executes them (`DeviceEndpoint::line_idle`). Seed 118005: a damaged
    /// copy's last byte, its checksum `F8`, started a candidate that claimed
    /// 107 bytes over the good resend behind it; only the silence released
    /// the resend, which the device answered ACK NIC, while the shadow,
    /// dropping the rescan's events, still held the device's previous
    /// command (`P?`) as the one NIC'd.
    pub(super) fn idle(&mut self) {
        let last = &mut self.last_command;
        self.shadow.flush_idle(|e| Self::shadow_event(last, e));
    }

    fn shadow_event(last: &mut Option<Heard>, e: sagebrush_protocol::Event<'_>) {
        if let sagebrush_protocol::Event::Frame(f) = e {
            *last = Some(Heard {
                key: (f.dest, f.source, f.checksum()),
                payload: f.payload().to_vec(),
            });
        }
    }
}

#[derive(Debug)]
pub(super) struct SimPort {
    pub(super) id: u8,
    /// The GCU side's line rate.
    pub(super) bps: u32,
    pub(super) open: bool,
    pub(super) epoch: u64,
    pub(super) bound: usize,
    pub(super) stop_bound: usize,
    pub(super) devices: Vec<Device>,
    /// Behind a device server (`PortConfig::buffered`).
    pub(super) buffered: bool,
    /// `PortConfig::late_answer_guard`.
    pub(super) late_answer_guard: u64,
    /// Fault: the device server stopped reading until then; what the GCU
    /// wrote meanwhile waits in it and reaches the bus afterwards, in order.
    pub(super) stalled_until: u64,
}

impl World {
    pub(super) fn port_lost(&mut self, g: usize, p: usize) {
        let sp = &mut self.gcus[g].ports[p];
        sp.open = false;
        sp.epoch += 1;
        let port = sp.id;
        self.gcus[g].ledger.pending_stops.remove(&port);
        self.input(g, Input::PortLost { port });
    }

    pub(super) fn port_opened(&mut self, g: usize, p: usize) {
        let sp = &mut self.gcus[g].ports[p];
        sp.open = true;
        let port = sp.id;
        self.input(g, Input::PortOpened { port });
    }

    /// When bytes the GCU wrote at `at` reach the bus of port `p`: later
    /// while its device server stalls (fault: stalled line, sometimes
    /// started by this write), FIFO kept.
    pub(super) fn stalled_line(&mut self, g: usize, p: usize, at: u64) -> u64 {
        let quiet = self.quiet;
        let stall = !quiet && self.gcus[g].ports[p].buffered && self.rng.chance(STALL_PM);
        let length = self.rng.range(100, 3_000);
        let sp = &mut self.gcus[g].ports[p];
        if stall && sp.stalled_until <= at {
            sp.stalled_until = at + length;
            self.summary.stalls += 1;
        }
        let at = at.max(sp.stalled_until);
        let fifo = self
            .fifo
            .entry((Node::Port { g, p }, Node::Device { g, p, d: 0 }))
            .or_insert(0);
        *fifo = (*fifo).max(at);
        at
    }

    /// Whether an answer of device `d` on port `p` of gcu `g` that leaves
    /// `late` ms late is one the GCU promises to recognise (ARCHITECTURE
    /// "Routing semantics", late answers): the spec bounds no answer time,
    /// so only the late-answer guard protects the next exchange, and only
    /// after a device that answered its last exchange went silent ("an
    /// address that never answered, or a device already offline, gets no
    /// guard"; the router's registry says whether it did). An answer later
    /// than the guard (seed 123077: a guard of 17 ms, answers 103 ms late),
    /// or from a device with no guard (seed 320645: its first answers, late),
    /// cannot be told from the next exchange's.
    fn late_answer_covered(&self, g: usize, p: usize, d: usize, late: u64) -> bool {
        let sp = &self.gcus[g].ports[p];
        let key = (sp.id, sp.devices[d].gimbal.id);
        let answered_last = self.gcus[g].router.stats().devices.get(&key).is_some_and(|s| s.online);
        answered_last && late <= sp.late_answer_guard + GIVE_UP_AFTER_ANSWER
    }

    /// The device answered `key` ACK and NIC (1.4.2): early (with the ACK),
    /// or late (fault), just inside or just after gcud's NIC window, counted
    /// from when the ACK reaches the port. Every NIC is recorded with its
    /// command (the truth the clients check their NICs against) and when it
    /// reached the port (the truth a report `00` is checked against).
    fn device_nics(&mut self, g: usize, p: usize, d: usize, heard: Heard, epoch: u64, bps: u32) {
        let key = heard.key;
        self.nicd.insert(heard);
        let late = (!self.quiet && self.rng.chance(LATE_NIC_PM)).then(|| match self.rng.chance(500) {
            true => NIC_WINDOW - 1,
            false => NIC_WINDOW + 1,
        });
        let (from, to) = (Node::Device { g, p, d }, Node::Port { g, p });
        // The answer's bytes, as the port gets them.
        let nic = |bytes: Vec<u8>| Ev::Nic {
            g,
            p,
            key,
            bytes,
            epoch,
            bps,
        };
        let Some(late) = late else {
            if let Some((at, bytes)) = self.wire(from, to, vec![ACK, NIC]) {
                self.schedule(at, nic(bytes));
            }
            return;
        };
        self.summary.late_nics += 1;
        self.summary.nics_after_window += u64::from(late > NIC_WINDOW);
        let ack_at = self.wire(from, to, vec![ACK]).map(|(at, bytes)| {
            self.schedule(at, nic(bytes));
            at
        });
        if let Some((at, bytes)) = self.wire(from, to, vec![NIC]) {
            // Counted from the ACK's arrival (when gcud's window starts), or
            // from when it would have come when a fault dropped it.
            let at = ack_at.map_or(at, |ack| ack + late).max(at);
            let fifo = self.fifo.entry((from, to)).or_insert(0);
            *fifo = (*fifo).max(at);
            self.schedule(at, nic(bytes));
        }
    }

    pub(super) fn device_writes(&mut self, g: usize, p: usize, d: usize, out: Vec<u8>, epoch: u64, bps: u32) {
        if out.is_empty() {
            return;
        }
        if out == [ACK, NIC] {
            if let Some(heard) = self.gcus[g].ports[p].devices[d].last_command.clone() {
                return self.device_nics(g, p, d, heard, epoch, bps);
            }
        }
        if let Some((at, bytes)) = self.wire(Node::Device { g, p, d }, Node::Port { g, p }, out) {
            // Fault: the answer leaves late, after the GCU gave up on it
            // (its retries and ACK time-outs) but within its late-answer
            // guard; it must never be taken for the next command's.
            let late = (!self.quiet && self.rng.chance(LATE_PM))
                .then(|| self.rng.range(LATE_MS.0, LATE_MS.1))
                .filter(|&late| self.late_answer_covered(g, p, d, late));
            let at = if let Some(late) = late {
                self.summary.late_answers += 1;
                let fifo = self
                    .fifo
                    .entry((Node::Device { g, p, d }, Node::Port { g, p }))
                    .or_insert(0);
                *fifo = (*fifo).max(at + late);
                at + late
            } else {
                at
            };
            self.schedule(
                at,
                Ev::Bytes {
                    to: Node::Port { g, p },
                    bytes,
                    epoch,
                    bps,
                },
            );
        }
    }
}
