//! An in-memory line for the `io` adapters' tests (tests/io_blocking.rs,
//! tests/io_async.rs): what the adapter writes, what it reads in chunks of
//! a chosen size, and optionally a gimbal on the far end (the sans-IO
//! `DeviceEndpoint`) that answers what a master writes, with a line that
//! damages chosen frames in either direction.

use std::cell::Cell;
use std::collections::VecDeque;

use sagebrush_protocol::*;

/// The gimbal: `P?` gets a position, everything else is done.
#[derive(Default)]
pub struct Gimbal {
    pub handled: Vec<String>,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, _reply_to: ReplyTo, _now: u64) -> Response<'_> {
        self.handled.push(command.mnemonic().to_string());
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(POSITION)),
            _ => Response::Done,
        }
    }
}

pub const POSITION: Position = Position::new(Angle(100), Angle(-100));

/// The far end of a master's line.
pub struct Peer {
    pub endpoint: DeviceEndpoint,
    pub gimbal: Gimbal,
    /// The next this many frames the master writes arrive damaged.
    pub damage_commands: usize,
    /// The next this many result frames the gimbal sends arrive damaged.
    pub damage_results: usize,
}

impl Peer {
    pub fn new(device: u8) -> Self {
        Self {
            endpoint: DeviceEndpoint::new(EndpointConfig::single(device)),
            gimbal: Gimbal::default(),
            damage_commands: 0,
            damage_results: 0,
        }
    }
}

/// Flips the checksum byte of a frame (a single byte is left alone).
fn damage(bytes: &mut [u8], count: &mut usize) {
    if bytes.len() > 1 && *count > 0 {
        *count -= 1;
        if let Some(last) = bytes.last_mut() {
            *last ^= 0x01;
        }
    }
}

pub struct Pipe {
    /// Bytes waiting for the adapter's reads.
    pub rx: VecDeque<u8>,
    /// Everything the adapter wrote, in order.
    pub tx: Vec<u8>,
    /// Most bytes one read returns.
    pub chunk: usize,
    /// Reads that returned bytes.
    pub reads: usize,
    pub peer: Option<Peer>,
}

impl Pipe {
    pub fn new(rx: &[u8], chunk: usize) -> Self {
        Self {
            rx: rx.iter().copied().collect(),
            tx: Vec::new(),
            chunk,
            reads: 0,
            peer: None,
        }
    }

    /// Up to `chunk` waiting bytes into `buf`.
    pub fn read_into(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.chunk).min(self.rx.len());
        for slot in &mut buf[..n] {
            *slot = self.rx.pop_front().unwrap();
        }
        if n > 0 {
            self.reads += 1;
        }
        n
    }

    /// The adapter's write: kept, and handed to the peer if there is one
    /// (through the damaging line), whose answer becomes readable.
    pub fn write_from(&mut self, bytes: &[u8]) -> usize {
        self.tx.extend_from_slice(bytes);
        if let Some(peer) = &mut self.peer {
            let mut on_wire = bytes.to_vec();
            damage(&mut on_wire, &mut peer.damage_commands);
            let mut answer = Vec::new();
            let Peer {
                endpoint,
                gimbal,
                damage_results,
                ..
            } = peer;
            endpoint.receive(&on_wire, 0, gimbal, &mut |out: &[u8]| {
                let mut out = out.to_vec();
                damage(&mut out, damage_results);
                answer.extend_from_slice(&out);
            });
            self.rx.extend(answer);
        }
        bytes.len()
    }
}

/// The master's input: noise, then the gimbal's answers. Ticks advance by
/// one at each reading of the clock, so a busy-waiting adapter reaches its
/// deadlines.
pub struct Clock(pub Cell<u64>);

impl Clock {
    pub fn tick(&self) -> u64 {
        let now = self.0.get() + 1;
        self.0.set(now);
        now
    }
}

pub fn policy() -> TransactionPolicy {
    TransactionPolicy {
        retry: RetryPolicy {
            ack_timeout: 100,
            retries: 2,
        },
        result_timeout: 500,
        long_result_timeout: 5_000,
        nic_window: 50,
        broadcast_guard: 50,
    }
}

pub fn frame(dest: Address, source: u8, payload: &[u8]) -> Vec<u8> {
    FrameBuf::new(dest, source, payload).unwrap().as_bytes().to_vec()
}

/// What a gimbal's adapter reads: noise, `P?`, the master's ACK, a damaged
/// `HO`, then `P?` again answered with a result the master NAKs.
pub fn device_stream() -> Vec<u8> {
    let me = Address::new(5, 1, 12);
    let mut stream = vec![0x00, 0x41, 0x13, 0x7E, 0xFF];
    stream.extend(frame(me, 2, b"P?"));
    stream.push(ACK);
    let mut damaged = frame(me, 2, b"HO");
    *damaged.last_mut().unwrap() ^= 0x40;
    stream.extend(damaged);
    stream.extend(frame(me, 2, b"P?"));
    stream.push(NAK);
    stream
}

/// What the gimbal's adapter must write for [`device_stream`], by the
/// sans-IO endpoint fed the whole stream at once.
pub fn device_answers() -> Vec<u8> {
    let mut endpoint: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut out = Vec::new();
    endpoint.receive(&device_stream(), 0, &mut Gimbal::default(), &mut |b: &[u8]| {
        out.extend_from_slice(b)
    });
    out
}

/// The same answers spelled out: ACK + result, NAK, ACK + result, the
/// result again after the NAK.
pub fn expected_device_answers() -> Vec<u8> {
    let result = frame(Address::new(2, 1, 12), 5, b"0064FF9C");
    let mut expected = vec![ACK];
    expected.extend(&result);
    expected.push(NAK);
    expected.push(ACK);
    expected.extend(&result);
    expected.extend(&result);
    expected
}
