//! Heap allocations per routed transaction in the router core
//! (ARCHITECTURE "Data path": none in steady state): a client's `P?` to a
//! device on a port, its ACK, the device's ACK and result, the result
//! relayed back and acknowledged, repeated after a warm-up so that every
//! buffer (the caller's `Outbox` included) has grown. An allocation count
//! is exact, not a timing, so it is asserted: any allocation per routed
//! frame fails. `cargo test -p sagebrush-gcu --release --test allocations`
//! prints the figure (no test harness: nothing else runs in the process).

use std::alloc::System;

use sagebrush_gcu::{
    Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig, SourceFilter,
};
use sagebrush_protocol::{ACK, Address, FrameBuf};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

const CLIENT: LinkId = LinkId(1);

fn main() {
    let mut config = RouterConfig::new(5);
    config.ports.push(PortConfig::new(1));
    let mut router = Router::new(config).expect("valid config");
    let mut out = Outbox::new();
    router.handle(0, Input::PortOpened { port: 1 }, &mut out);
    let link = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
    router.handle(
        0,
        Input::LinkUp {
            link: CLIENT,
            config: link,
        },
        &mut out,
    );
    out.clear();
    let command = FrameBuf::new(Address::new(5, 1, 3), 0, b"P?").expect("frame");
    let result = FrameBuf::new(Address::new(0, 1, 3), 5, b"00640000").expect("frame");
    let mut now = 0u64;
    let mut transaction = |router: &mut Router, out: &mut Outbox| {
        now += 10;
        router.handle(
            now,
            Input::Bytes {
                line: LineId::Link(CLIENT),
                bytes: command.as_bytes(),
            },
            out,
        );
        router.handle(
            now,
            Input::Bytes {
                line: LineId::Port(1),
                bytes: &[ACK],
            },
            out,
        );
        router.handle(
            now,
            Input::Bytes {
                line: LineId::Port(1),
                bytes: result.as_bytes(),
            },
            out,
        );
        router.handle(
            now,
            Input::Bytes {
                line: LineId::Link(CLIENT),
                bytes: &[ACK],
            },
            out,
        );
        now += 1000;
        router.handle(now, Input::Tick, out);
        out.clear();
    };
    for _ in 0..1000 {
        transaction(&mut router, &mut out);
    }
    // The canary: the counting allocator must see an allocation made here,
    // or a zero below would prove nothing (the allocator not installed).
    let region = Region::new(GLOBAL);
    std::hint::black_box(Box::new(std::hint::black_box(7u64)));
    let canary = region.change();
    assert_eq!(
        canary.allocations, 1,
        "the counting allocator must see a Box: {canary:?}"
    );
    // And one inside the router's own work: an Outbox that must grow.
    let mut fresh = Outbox::new();
    let region = Region::new(GLOBAL);
    transaction(&mut router, &mut fresh);
    let first = region.change();
    assert!(
        first.allocations + first.reallocations > 0,
        "a fresh Outbox grows while routing, and the count must show it: {first:?}"
    );
    const N: u64 = 10_000;
    let region = Region::new(GLOBAL);
    for _ in 0..N {
        transaction(&mut router, &mut out);
    }
    let stats = region.change();
    assert_eq!(router.stats().router.results, 1000 + 1 + N, "every P? was answered");
    println!(
        "router core, routed P? (client -> port -> result back): {:.2} allocations, {:.0} bytes allocated per transaction ({} transactions)",
        stats.allocations as f64 / N as f64,
        stats.bytes_allocated as f64 / N as f64,
        N
    );
    assert_eq!(
        stats.allocations + stats.reallocations,
        0,
        "the router core allocated while routing: {stats:?}"
    );
}
