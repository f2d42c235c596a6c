//! Deterministic network simulation of GCU routers.
//!
//! A seeded generator builds a network (1 to 3 GCUs linked in a tree,
//! 1 to 3 ports each, 1 to 3 devices per port driven by the protocol crate's
//! `DeviceEndpoint`, 1 to 3 clients speaking as MCUs) and runs random
//! commands, broadcasts included, over wires that corrupt, drop, delay and
//! disconnect. Then faults stop, clients start a motion each and disconnect,
//! and the network drains. Invariants are checked throughout and at the end.
//! Devices answer NIC late (just inside and just after gcud's NIC window)
//! or early, and every `?` a client takes must be a NIC of the command it
//! awaits (`sim/world/clients.rs`, `check_nic`).
//! The run fails on a worker that dies (its seeds would go unrun), and its
//! excuses are tied to real damage and bounded: a report after an ACK is
//! excused only when that ACK arrived with bytes a wire damaged, a frame
//! the router never wrote only when formed from damaged bytes, and both
//! together stay rarer than one per 500 damaged writes.
//!
//! - `cargo test -p sagebrush-gcu --release --test simulation`: 10,000 seeds.
//! - `GCU_SIM_SEEDS=1000000 GCU_SIM_START=0 ...`: as many as you like.
//! - `GCU_SIM_SEED=1234 ... -- --nocapture`: replays one seed with a trace.

mod sim;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

fn env_u64(name: &str) -> Option<u64> {
    std::env::var(name).ok().and_then(|v| v.trim().parse().ok())
}

/// At most one phantom (ACK or frame) excused per this many damaged writes
/// to clients, plus [`PHANTOM_SLACK`] for short runs: measured 10 in 36,951
/// (1 in 3,700) over seeds 0..100,000; the bound leaves a factor of seven.
const PHANTOM_PER_DAMAGED_WRITE: u64 = 500;
const PHANTOM_SLACK: u64 = 2;

/// Seeds a run takes unless `GCU_SIM_SEEDS` says otherwise.
const DEFAULT_SEEDS: u64 = 10_000;

fn replay_line(seed: u64) -> String {
    format!("GCU_SIM_SEED={seed} cargo test -p sagebrush-gcu --release --test simulation -- --nocapture")
}

fn run_seed(seed: u64, trace: bool) -> Result<sim::Summary, String> {
    match std::panic::catch_unwind(|| sim::run(seed, trace)) {
        Ok(result) => result,
        Err(panic) => Err(panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "panic".into())),
    }
}

#[test]
fn simulated_networks_keep_every_invariant() {
    if let Some(seed) = env_u64("GCU_SIM_SEED") {
        match run_seed(seed, true) {
            Ok(summary) => println!("seed {seed}: ok {summary:?}"),
            Err(e) => panic!("seed {seed} failed: {e}\nreplay: {}", replay_line(seed)),
        }
        return;
    }
    let count = env_u64("GCU_SIM_SEEDS").unwrap_or(DEFAULT_SEEDS);
    let start = env_u64("GCU_SIM_START").unwrap_or(0);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 8) as u64;
    let next = Arc::new(AtomicU64::new(start));
    // Seeds run to the end (passed or failed): a worker that dies loses the
    // rest of its seeds, which must fail the run, never shrink it.
    let done = Arc::new(AtomicU64::new(0));
    let failures = Arc::new(Mutex::new(Vec::new()));
    let totals = Arc::new(Mutex::new(sim::Summary::default()));
    let began = Instant::now();
    let workers: Vec<_> = (0..threads)
        .map(|_| {
            let (next, failures, totals, done) = (next.clone(), failures.clone(), totals.clone(), done.clone());
            std::thread::spawn(move || {
                let mut local = sim::Summary::default();
                loop {
                    let seed = next.fetch_add(1, Ordering::Relaxed);
                    if seed >= start + count {
                        break;
                    }
                    match run_seed(seed, false) {
                        Ok(s) => local.add(&s),
                        Err(e) => {
                            let mut f = failures.lock().unwrap_or_else(|p| p.into_inner());
                            f.push((seed, e));
                            if f.len() >= 5 {
                                next.store(u64::MAX / 2, Ordering::Relaxed);
                            }
                        }
                    }
                    done.fetch_add(1, Ordering::Relaxed);
                }
                totals.lock().unwrap_or_else(|p| p.into_inner()).add(&local);
            })
        })
        .collect();
    let crashed = workers.into_iter().map(|w| w.join()).filter(Result::is_err).count();
    let totals = totals.lock().unwrap_or_else(|p| p.into_inner()).clone();
    println!(
        "{count} seeds from {start} in {:.2?} on {threads} threads: {totals:?}",
        began.elapsed()
    );
    let mut failures = failures.lock().unwrap_or_else(|p| p.into_inner()).clone();
    failures.sort();
    if let Some((seed, e)) = failures.first() {
        let others: Vec<u64> = failures.iter().skip(1).map(|f| f.0).collect();
        panic!(
            "seed {seed} failed: {e}\nreplay: {}\nother failing seeds: {others:?}",
            replay_line(*seed)
        );
    }
    let done = done.load(Ordering::Relaxed);
    assert_eq!(
        crashed, 0,
        "{crashed} worker(s) crashed: {done} of {count} seeds were run"
    );
    assert_eq!(done, count, "seeds run");
    // Every excuse is tied to damage a wire did, and rare: an ACK taken
    // while the client's framer held damaged bytes, a frame formed from
    // damaged bytes (an 8-bit checksum passes about 1 time in 256).
    assert!(totals.phantom_acks <= totals.tainted_acks, "{totals:?}");
    assert!(
        totals.phantom_frames + totals.phantom_acks
            <= totals.client_damaged_writes / PHANTOM_PER_DAMAGED_WRITE + PHANTOM_SLACK,
        "more phantoms than damaged writes can explain: {totals:?}"
    );
    // The generator must actually exercise what the invariants are about.
    assert!(totals.accepted > count, "{totals:?}");
    assert!(
        totals.results > 0 && totals.nics > 0 && totals.forwarded > 0,
        "{totals:?}"
    );
    assert!(
        totals.dead_man_stops > 0 && totals.rate_switches > 0 && totals.retransmits > 0,
        "{totals:?}"
    );
    assert!(
        totals.nonce_results > 0 && totals.final_motions_checked > 0,
        "{totals:?}"
    );
    // The faults and recoveries too: a fault the generator silently stops
    // injecting (late answers are injected only where the router's registry
    // says the GCU must recognise them) would leave its invariant unproven.
    assert!(
        totals.late_answers > 0 && totals.stalls > 0 && totals.repeated_reports > 0,
        "{totals:?}"
    );
    // Late NICs, just inside and just after gcud's window, and early ones
    // (with the ACK, or with the ACK lost): every `?` a client took was
    // checked against the NICs the devices sent. The excuses (a damaged
    // byte; the `?` of a command the client gave up on by itself, of a
    // group-255 command, or relayed from another GCU for a command it took
    // twice) stay rare beside the checked ones. A command gcud told not
    // delivered (`0B not confirmed` and the rest) earns none: its `?` is
    // never relayed.
    assert!(
        totals.late_nics > 0 && totals.nics_after_window > 0 && totals.nics_checked > 0,
        "{totals:?}"
    );
    // TCP clients asked for end-of-window reports and got them, and took
    // their own commands' results (checked by nonce).
    assert!(totals.window_reports > 0 && totals.answers_checked > 0, "{totals:?}");
    let excused = totals.phantom_nics + totals.stale_nics + totals.fan_out_nics + totals.relayed_nics;
    assert!(excused <= totals.nics_checked / 50 + PHANTOM_SLACK, "{totals:?}");
    // A client's retransmission the GCU recognises needs its ACK lost on a
    // damaged wire: measured 3 in seeds 0..10,000, so only a run of the
    // default length or longer is sure to see one.
    if count >= DEFAULT_SEEDS {
        assert!(totals.client_repeats > 0, "{totals:?}");
    }
}

/// Seeds that once failed on a checker or client model error, not on the
/// router; each replays its exact scenario whatever `GCU_SIM_SEEDS` says.
/// 187256: a late `IX` result after an `HS`'s ACK, taken as the end of the
/// `HS` (1.4.2: an ACK-only command's answer is a NIC, never a result).
/// 165293: a fan-out's `?` after the ACK of a `CD` its device answered
/// NIC later, past gcud's window, taken for that NIC.
#[test]
fn seeds_that_found_model_errors_pass() {
    for seed in [165_293, 187_256] {
        if let Err(e) = run_seed(seed, false) {
            panic!("seed {seed} failed: {e}\nreplay: {}", replay_line(seed));
        }
    }
}

#[test]
fn the_same_seed_gives_the_same_run() {
    for seed in [1, 77, 4242] {
        let a = sim::run(seed, false).expect("seed passes");
        let b = sim::run(seed, false).expect("seed passes");
        assert_eq!(a, b);
    }
}
