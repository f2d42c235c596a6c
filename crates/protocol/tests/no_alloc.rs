//! Zero heap allocations: the framer, the codecs, the link state machines
//! and the device endpoint run under a counting global allocator, and the
//! count must not move. (`harness = false`: no test-runner threads that
//! could allocate meanwhile.)

use std::alloc::System;
use std::hint::black_box;

use sagebrush_protocol::*;
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// A gimbal that answers with each kind of response: a result (position
/// or identity), done, or NIC.
struct Gimbal {
    position: Position,
    identity: Identity<'static>,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, _reply_to: ReplyTo, _now: u64) -> Response<'_> {
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(self.position)),
            Command::Identify => Response::Reply(Reply::Identity(self.identity)),
            Command::GoTo(p) => {
                self.position = p;
                Response::Done
            }
            Command::Home => Response::Nic,
            _ => Response::Done,
        }
    }
}

/// Everything the crate does on a device or a host, on prepared input.
fn exercise(stream: &[u8]) -> usize {
    let mut work = 0usize;
    let mut buf = [0u8; MAX_FRAME_LEN];

    // Framer: zero-copy feed in odd chunks, push/next_event, DMA.
    let mut framer: Framer = Framer::new();
    for chunk in stream.chunks(37) {
        framer.feed(chunk, |event| {
            if let Event::Frame(frame) = event {
                let command = Command::parse(frame.payload());
                work += command.mnemonic().len();
                if let Ok(payload) = command.encode(&mut buf) {
                    work += payload.len();
                }
                if let Ok(Reply::Position(p)) = Reply::parse(&Command::QueryPosition, frame.payload()) {
                    work += p.pan.0 as usize;
                }
                if let Err(e) = Command::parse_strict(frame.payload()) {
                    work += matches!(e, CommandError::Unknown { .. }) as usize;
                }
            }
        });
    }
    framer.flush_idle(|_| work += 1);
    let mut framer: Framer<263> = Framer::new();
    for mut chunk in stream.chunks(100) {
        while !chunk.is_empty() {
            let spare = framer.spare_capacity_mut();
            let n = spare.len().min(chunk.len());
            spare[..n].copy_from_slice(&chunk[..n]);
            framer.commit(n);
            chunk = &chunk[n..];
            while let Some(event) = framer.next_event() {
                work += matches!(event, Event::Frame(_)) as usize;
            }
        }
    }

    // Codecs.
    let goto = Command::GoTo(Position::new(Angle(-100), Angle(100)));
    let frame = FrameBuf::build(Address::new(5, 1, 12), 2, |b| goto.encode(b).map(<[u8]>::len)).unwrap();
    let (parsed, _) = Frame::parse(frame.as_bytes()).unwrap();
    work += parsed.encode(&mut buf).unwrap().len();
    let reply = Reply::Identity(Identity::new(12, *b"19", b"PTU-D300", b"SN1").unwrap());
    let payload = reply.encode(&mut buf).unwrap();
    work += Reply::parse(&Command::Identify, payload).is_ok() as usize;
    work += Reply::parse(&Command::QueryPosition, b"0064FG9C").is_err() as usize;

    // Device endpoint.
    let mut endpoint: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut gimbal = Gimbal {
        position: Position::default(),
        identity: Identity::new(12, *b"19", b"PTU-D300", b"SN1").unwrap(),
    };
    let mut out = [0u8; 1024];
    let mut out_len = 0;
    let mut sink = |bytes: &[u8]| {
        let n = bytes.len().min(out.len() - out_len);
        out[out_len..out_len + n].copy_from_slice(&bytes[..n]);
        out_len += n;
    };
    endpoint.receive(frame.as_bytes(), 0, &mut gimbal, &mut sink);
    endpoint.receive(stream, 1, &mut gimbal, &mut sink);
    endpoint.line_idle(2, &mut gimbal, &mut sink);
    work += out_len;

    // Link state machines.
    let policy = TransactionPolicy {
        retry: RetryPolicy {
            ack_timeout: 10,
            retries: 2,
        },
        result_timeout: 100,
        long_result_timeout: 1000,
        nic_window: 5,
        broadcast_guard: 5,
    };
    let mut t = Transaction::new(Address::new(5, 1, 12), &Command::QueryPosition, policy);
    t.start(0);
    t.on_event(&Event::Nak, 1);
    t.on_event(&Event::Ack, 2);
    work += matches!(t.poll(200), TransactionStep::Done(Outcome::NoResult)) as usize;
    work
}

fn main() {
    // Prepared outside the measured region: a stream of commands, results,
    // bare bytes, noise and a damaged frame.
    let mut stream = Vec::new();
    for (i, payload) in [
        &b"P?"[..],
        b"D?",
        b"P0064FF9C",
        b"GRP0F",
        b"QQ",
        b"HO",
        b"*x0c,9600,8,1,0",
        b"0064FF9C",
    ]
    .iter()
    .enumerate()
    {
        stream.extend_from_slice(
            FrameBuf::new(Address::new(5, 1, 12), i as u8, payload)
                .unwrap()
                .as_bytes(),
        );
        stream.extend_from_slice(&[0x06, 0x00, 0x3F, 0xF8, 0x15]);
    }
    let mut damaged = FrameBuf::new(Address::new(5, 1, 12), 2, b"PL")
        .unwrap()
        .as_bytes()
        .to_vec();
    damaged[7] ^= 4;
    stream.extend_from_slice(&damaged);
    stream.extend_from_slice(&[0xF8, 1, 2]);

    // The counter works: an allocation inside a region is seen.
    let region = Region::new(GLOBAL);
    black_box(Box::new(black_box(7u64)));
    let change = region.change();
    assert_eq!(change.allocations, 1, "the counting allocator must see a Box");

    let region = Region::new(GLOBAL);
    let work = black_box(exercise(black_box(&stream)));
    let change = region.change();
    assert!(work > 0);
    assert_eq!(
        (change.allocations, change.reallocations, change.bytes_allocated),
        (0, 0, 0),
        "the protocol crate allocated: {change:?}"
    );
    println!("no_alloc: 0 allocations over framer, codecs, endpoint and link ({work} units of work)");
}
