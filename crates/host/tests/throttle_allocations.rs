//! A flood of one warning (gcud's failed deliveries when a bus is busy, a
//! door's refused datagrams) costs no heap allocation once its window is
//! open (issue 52: one or more per failed delivery before).

use std::alloc::System;

use sagebrush_host::throttle::{BURST, Throttle, WINDOW};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};
use tokio::time::Instant;

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

#[test]
fn a_warning_counted_in_an_open_window_allocates_nothing() {
    let mut t = Throttle::default();
    let now = Instant::now();
    let kind = format_args!("undelivered {}", "device_silent");
    let allowed = (0..BURST + 1)
        .filter(|i| t.allow(&kind, &"operators", &format_args!("5.1.1: no answer ({i})"), now))
        .count();
    assert_eq!(allowed, BURST as usize, "a burst, then counted");
    let region = Region::new(GLOBAL);
    for i in 0..10_000u32 {
        let line = format_args!("5.1.{}: no answer to P? from link 7 ({i})", i % 8);
        assert!(!t.allow(&kind, &"operators", &line, now));
    }
    let spent = region.change();
    assert_eq!(spent.allocations, 0, "for 10,000 warnings counted");
    // The last line's buffer grows to the longest line, once or twice.
    assert!(spent.reallocations <= 2, "{spent:?}");
    let summary = t.summaries(now + WINDOW);
    assert_eq!(
        summary,
        ["5.1.7: no answer to P? from link 7 (9999) (repeated 10001 more times in 10 s)"]
    );
}
