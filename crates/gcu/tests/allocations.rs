//! Heap allocations per routed transaction in the router core
//! (ARCHITECTURE "Data path": none in steady state), for each way a
//! command goes:
//!
//! - to a port: a client's `P?` to a device, its ACK, the device's ACK
//!   and result, the result relayed back and acknowledged;
//! - to another group over a downstream link: the `P?` forwarded, the link's
//!   ACK, the next GCU's delivery report and result relayed back;
//! - to group 255: the GCU answers `AW` itself and floods it downstream,
//!   where the next GCU reports it delivered and answers too (or its
//!   report is lost, and the copy's record expires unreported);
//! - to port 0: the GCU answers `AW` itself;
//! - to a port whose device never answers: the command tried until its
//!   tries run out, the client told it was not delivered (a delivery
//!   time-out, as at 254 busy ports when the daemon is starved of its
//!   core), the client acknowledging that at once, or never (its link
//!   gives the report up).
//!
//! Each is repeated after a warm-up so that every buffer (the caller's
//! `Outbox` included) has grown. An allocation count is exact, not a
//! timing, so it is asserted: any allocation per routed frame fails.
//! `cargo test -p sagebrush-gcu --release --test allocations` prints the
//! figures (no test harness: nothing else runs in the process).

use std::alloc::System;

use sagebrush_gcu::{
    Action, Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig, SourceFilter,
};
use sagebrush_protocol::{ACK, Address, DeliveryReport, FrameBuf};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// This GCU's group, and the next GCU's, behind `DOWN`.
const G: u8 = 5;
const NEXT: u8 = 7;
const CLIENT: LinkId = LinkId(1);
const DOWN: LinkId = LinkId(2);

/// Warm-up transactions, then measured ones.
const WARM_UP: u64 = 1000;
const N: u64 = 10_000;

fn frame(dest: (u8, u8, u8), source: u8, payload: &[u8]) -> FrameBuf {
    FrameBuf::new(Address::new(dest.0, dest.1, dest.2), source, payload).expect("frame")
}

/// The delivery report the next GCU sends about `command`: delivered.
fn delivered(command: &FrameBuf) -> FrameBuf {
    let f = command.frame();
    let payload = DeliveryReport {
        failure: None,
        dest: f.dest,
        command_checksum: f.checksum(),
        at_group: NEXT,
    }
    .encode();
    frame((f.source, 0, 0), NEXT, &payload)
}

/// What a line delivers to the router, or time passing (milliseconds, in
/// ticks of 5 ms: time-outs fire and are acted on in turn), with a line
/// whose peer acknowledges at once whatever it is sent then, if any.
enum Step {
    Bytes(LineId, Vec<u8>),
    Wait(u64, Option<LineId>),
}

/// One way a command goes: the bytes each line delivers to the router, in order.
struct Transaction {
    name: &'static str,
    steps: Vec<Step>,
    /// Commands one run of it routes.
    commands: u64,
    /// Whether each command is answered (a result relayed), or fails.
    answered: bool,
}

impl Transaction {
    fn new(name: &'static str, steps: Vec<(LineId, &[u8])>) -> Self {
        let steps = steps
            .into_iter()
            .map(|(line, bytes)| Step::Bytes(line, bytes.to_vec()))
            .collect();
        Self {
            name,
            steps,
            commands: 1,
            answered: true,
        }
    }

    /// Runs it once at `*now`, then lets every time-out pass.
    fn run(&self, router: &mut Router, now: &mut u64, out: &mut Outbox) {
        *now += 10;
        for step in &self.steps {
            match step {
                Step::Bytes(line, bytes) => router.handle(*now, Input::Bytes { line: *line, bytes }, out),
                Step::Wait(ms, acking) => {
                    for _ in 0..ms / 5 {
                        *now += 5;
                        let seen = out.actions().len();
                        router.handle(*now, Input::Tick, out);
                        let sent = |l: &LineId| {
                            out.actions()[seen..]
                                .iter()
                                .any(|a| matches!(a, Action::Write { line, .. } if line == l))
                        };
                        if let Some(line) = acking.filter(sent) {
                            router.handle(*now, Input::Bytes { line, bytes: &[ACK] }, out);
                        }
                    }
                }
            }
        }
        *now += 1000;
        router.handle(*now, Input::Tick, out);
        out.clear();
    }
}

/// Clients at once, each on its own port (gcud's throughput benchmark, at
/// the spec's largest GCU: 1.3, up to 254 ports).
const CONCURRENT: u8 = 254;

/// The client link of port `p` in the concurrent case.
fn client_of(p: u8) -> LinkId {
    LinkId(10 + u32::from(p))
}

fn router() -> Router {
    let mut config = RouterConfig::new(G);
    for p in 1..=CONCURRENT {
        config.ports.push(PortConfig::new(p));
    }
    config.static_routes.insert(NEXT, DOWN);
    let mut router = Router::new(config).expect("valid config");
    let mut out = Outbox::new();
    for port in 1..=CONCURRENT {
        router.handle(0, Input::PortOpened { port }, &mut out);
    }
    let clients = (1..=CONCURRENT).map(|p| (client_of(p), LinkKind::Client));
    for (link, kind) in [(CLIENT, LinkKind::Client), (DOWN, LinkKind::Downstream)]
        .into_iter()
        .chain(clients)
    {
        let config = LinkConfig::new(kind, SourceFilter::Any);
        router.handle(0, Input::LinkUp { link, config }, &mut out);
    }
    router
}

fn transactions() -> Vec<Transaction> {
    let client = LineId::Link(CLIENT);
    let down = LineId::Link(DOWN);
    let port = LineId::Port(1);
    let to_port = frame((G, 1, 3), 0, b"P?");
    let port_result = frame((0, 1, 3), G, b"00640000");
    let to_next = frame((NEXT, 1, 3), 0, b"P?");
    let next_result = frame((0, 1, 3), NEXT, b"00640000");
    let flood = frame((255, 0, 0), 0, b"AW");
    let next_awake = frame((0, 0, 0), NEXT, b"0");
    let to_self = frame((G, 0, 0), 0, b"AW");
    let to_silent = frame((G, 2, 3), 0, b"P?");
    vec![
        Transaction::new(
            "routed P? (client -> port -> result back)",
            vec![
                (client, to_port.as_bytes()),
                (port, &[ACK]),
                (port, port_result.as_bytes()),
                (client, &[ACK]),
            ],
        ),
        Transaction::new(
            "forwarded P? (client -> downstream GCU -> report and result back)",
            vec![
                (client, to_next.as_bytes()),
                (down, &[ACK]),
                (down, delivered(&to_next).as_bytes()),
                (down, next_result.as_bytes()),
                (client, &[ACK]),
            ],
        ),
        Transaction::new(
            "group-255 AW (answered here, flooded downstream, answered there)",
            vec![
                (client, flood.as_bytes()),
                (down, &[ACK]),
                (client, &[ACK]),
                (down, delivered(&flood).as_bytes()),
                (down, next_awake.as_bytes()),
                (client, &[ACK]),
            ],
        ),
        Transaction::new(
            "group-255 AW, the next GCU's report lost (its copy expires unreported)",
            vec![
                (client, flood.as_bytes()),
                (down, &[ACK]),
                (client, &[ACK]),
                (down, next_awake.as_bytes()),
                (client, &[ACK]),
            ],
        ),
        Transaction::new(
            "AW to port 0 (answered by the GCU itself)",
            vec![(client, to_self.as_bytes()), (client, &[ACK])],
        ),
        concurrent(),
        Transaction {
            name: "P? to a device that never answers (tried, reported not delivered, acknowledged)",
            steps: vec![
                Step::Bytes(client, to_silent.as_bytes().to_vec()),
                Step::Wait(2000, Some(client)),
            ],
            commands: 1,
            answered: false,
        },
        Transaction {
            name: "P? to a device that never answers, its report never acknowledged (given up)",
            steps: vec![
                Step::Bytes(client, to_silent.as_bytes().to_vec()),
                Step::Wait(2000, None),
                Step::Bytes(client, vec![ACK]),
            ],
            commands: 1,
            answered: false,
        },
    ]
}

/// 254 clients' `P?` at once, each to its own port, every step of one
/// interleaved with the same step of the others (counted as 254 transactions).
fn concurrent() -> Transaction {
    let ports = 1..=CONCURRENT;
    let commands: Vec<FrameBuf> = ports.clone().map(|p| frame((G, p, 3), 0, b"P?")).collect();
    let results: Vec<FrameBuf> = ports.clone().map(|p| frame((0, p, 3), G, b"00640000")).collect();
    let mut steps: Vec<Step> = Vec::new();
    for (i, p) in ports.enumerate() {
        steps.push(Step::Bytes(LineId::Link(client_of(p)), commands[i].as_bytes().to_vec()));
    }
    for p in 1..=CONCURRENT {
        steps.push(Step::Bytes(LineId::Port(p), vec![ACK]));
    }
    for (i, p) in (1..=CONCURRENT).enumerate() {
        steps.push(Step::Bytes(LineId::Port(p), results[i].as_bytes().to_vec()));
    }
    for p in 1..=CONCURRENT {
        steps.push(Step::Bytes(LineId::Link(client_of(p)), vec![ACK]));
    }
    Transaction {
        name: "254 clients' P? at once, each to its own port",
        steps,
        commands: u64::from(CONCURRENT),
        answered: true,
    }
}

fn main() {
    // The canary: the counting allocator must see an allocation made here,
    // or a zero below would prove nothing (the allocator not installed).
    let region = Region::new(GLOBAL);
    std::hint::black_box(Box::new(std::hint::black_box(7u64)));
    let canary = region.change();
    assert_eq!(
        canary.allocations, 1,
        "the counting allocator must see a Box: {canary:?}"
    );
    for t in transactions() {
        let mut router = router();
        let mut out = Outbox::new();
        let mut now = 0u64;
        for _ in 0..WARM_UP {
            t.run(&mut router, &mut now, &mut out);
        }
        // And one inside the router's own work: an Outbox that must grow.
        let mut fresh = Outbox::new();
        let region = Region::new(GLOBAL);
        t.run(&mut router, &mut now, &mut fresh);
        let first = region.change();
        assert!(
            first.allocations + first.reallocations > 0,
            "{}: a fresh Outbox grows while routing, and the count must show it: {first:?}",
            t.name
        );
        let before = router.stats();
        let region = Region::new(GLOBAL);
        for _ in 0..N {
            t.run(&mut router, &mut now, &mut out);
        }
        let stats = region.change();
        let after = router.stats();
        // Every transaction went the whole way: nothing dropped, each finished
        // and its answers relayed.
        let (b, a) = (before.router, after.router);
        assert_eq!(
            a.finished() - b.finished(),
            N * t.commands,
            "{}: every command finished: {a:?}",
            t.name
        );
        assert_eq!(a.frame_drops, b.frame_drops, "{}: nothing dropped: {a:?}", t.name);
        assert_eq!(a.dropped, b.dropped, "{}: nothing dropped: {a:?}", t.name);
        if t.answered {
            assert!(
                a.results + a.results_relayed >= b.results + b.results_relayed + N * t.commands,
                "{}: every command answered: {a:?}",
                t.name
            );
        } else {
            assert_eq!(a.results, b.results, "{}: no command answered: {a:?}", t.name);
        }
        println!(
            "router core, {}: {:.2} allocations, {:.0} bytes allocated per transaction ({} transactions)",
            t.name,
            stats.allocations as f64 / (N * t.commands) as f64,
            stats.bytes_allocated as f64 / (N * t.commands) as f64,
            N * t.commands,
        );
        assert_eq!(
            stats.allocations + stats.reallocations,
            0,
            "{}: the router core allocated while routing: {stats:?}",
            t.name
        );
    }
}
