//! `cargo bench --bench gimbalctl`: what an operator feels of gimbalctl
//! through gcud (issue 35), the real binaries on 127.0.0.1, process start
//! included: `gimbalsim --tcp` <- a relay that watches the bus bytes <-
//! gcud (the relay is its `tcp` port) <- gimbalctl `--tcp`; then gcud's
//! port on a bus paced at 9600 and at 115200 bit/s (`door::Stack::paced`).
//! Per move, `GIMBALCTL_BENCH_MOVES` of them (default 50; on the paced
//! buses `GIMBALCTL_BENCH_PACED_MOVES`, default 30):
//! 1. `gimbalctl slew right --speed N --hold` (N changing every move; the
//!    speed and the direction chained, gcud's port `duplex = "full"`):
//!    from its spawn to the first byte of the direction command at that
//!    speed (`door::pan_at_speed`), beside the line-time limit of the
//!    bytes needed; the same with `--direct` (no `~W` asked: gimbalctl
//!    waits its own NIC window after gcud's, as before this issue);
//! 2. `gimbalctl stop pan` while it holds (at a phase spread over the
//!    hold's `P?` refresh): its spawn to the pan stop's first byte;
//! 3. then `slew right --hold` alone (the speed set): its spawn to the
//!    direction's first byte.
//!
//! And the process start alone: `gimbalctl --version`, spawn to exit.
//!
//! `GIMBALCTL_BENCH_GIMBALCTL=PATH` runs another gimbalctl build. `cargo
//! bench` builds the programs with its dev-dependencies' features too
//! (regex's Unicode tables among them: twice the relocated pages at start
//! as the release build), so to measure gimbalctl as shipped:
//! `cargo build --release --bin gimbalctl --target-dir target/shipped`,
//! then `GIMBALCTL_BENCH_GIMBALCTL=target/shipped/release/gimbalctl`.
//! Figures are printed, never asserted: the machines are shared and noisy.
//! Run without `--bench` (`cargo test --benches`) it does nothing.

#[path = "support/door.rs"]
#[allow(dead_code)] // Stack::door is for the door benchmarks
mod door;
#[allow(dead_code)] // TRANSACTION_BYTES is for the bus benchmarks
mod support;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use door::{MOTION_BYTES, STOP_BYTES, env_count, report};

/// The gimbalctl measured: `GIMBALCTL_BENCH_GIMBALCTL`, else cargo's.
fn gimbalctl() -> String {
    std::env::var("GIMBALCTL_BENCH_GIMBALCTL").unwrap_or_else(|_| env!("CARGO_BIN_EXE_gimbalctl").to_owned())
}
/// The bytes a direction needs when its speed is set: its first byte.
const DIRECTION_BYTES: u32 = 1;
/// Longer than gcud's NIC window and gimbalctl's own: a request's commands are all heard.
const QUIET: Duration = Duration::from_millis(450);

/// `gimbalctl --tcp CLIENTS --to 5.1.1 ARGS`, started.
fn spawn(stack: &door::Stack, args: &[&str]) -> Child {
    Command::new(gimbalctl())
        .args(["--tcp", &stack.clients, "--to", "5.1.1"])
        .args(args)
        .env_remove("GIMBALCTL_SERIAL")
        .env_remove("GIMBALCTL_TCP")
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn gimbalctl")
}

/// Waits for `child`, which must succeed.
fn succeeds(mut child: Child, what: &str) {
    let status = child.wait().expect("wait");
    assert!(status.success(), "gimbalctl {what}: {status}");
}

/// The figures of `moves` moves (1., 2. and 3. above); `extra` goes
/// before each gimbalctl's subcommand (`--direct`).
struct Moves {
    speed_and_slew: Vec<Duration>,
    slew: Vec<Duration>,
    stop: Vec<Duration>,
}

fn moves(stack: &door::Stack, moves: usize, extra: &[&str]) -> Moves {
    let mut m = Moves {
        speed_and_slew: Vec::with_capacity(moves),
        slew: Vec::with_capacity(moves),
        stop: Vec::with_capacity(moves),
    };
    for i in 0..moves {
        stack.drain();
        let speed = if i % 2 == 0 { "4" } else { "9" };
        let began = Instant::now();
        let hold = spawn(stack, &[extra, &["slew", "right", "--speed", speed, "--hold"]].concat());
        let heard = stack.heard(QUIET);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        m.speed_and_slew.push(at.saturating_duration_since(began));
        // The hold polls `P?` every 250 ms (`session::REFRESH`; 27 ms of
        // line at 9600 bit/s): the stop comes at a phase spread over that
        // period, as an operator's does, not always just as a poll begins.
        std::thread::sleep(Duration::from_millis(i as u64 * 37 % 250));
        m.stop.push(stop(stack, extra, hold));
        // The speed is set now: the slew alone.
        let began = Instant::now();
        let hold = spawn(stack, &[extra, &["slew", "right", "--hold"]].concat());
        let heard = stack.heard(QUIET);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        m.slew.push(at.saturating_duration_since(began));
        stop(stack, extra, hold);
    }
    m
}

/// `gimbalctl stop pan` while `hold` holds: its spawn to the pan stop's
/// first byte; then `hold` ends (end of stdin: it sends its own stop).
fn stop(stack: &door::Stack, extra: &[&str], mut hold: Child) -> Duration {
    let began = Instant::now();
    succeeds(spawn(stack, &[extra, &["stop", "pan"]].concat()), "stop");
    let heard = stack.heard(QUIET);
    let at = door::pan_stop(&heard).unwrap_or_else(|| panic!("no pan stop on the bus: {heard:?}"));
    drop(hold.stdin.take());
    succeeds(hold, "slew --hold");
    at.saturating_duration_since(began)
}

/// Waits until gcud answers a query about the gimbal (its port is open).
fn ready(stack: &door::Stack) {
    let began = Instant::now();
    while !spawn(stack, &["position"]).wait().expect("wait").success() {
        assert!(began.elapsed() < Duration::from_secs(30), "gcud's port never opened");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn run(stack: &door::Stack, baud: Option<u32>, n: usize) {
    ready(stack);
    let m = moves(stack, n, &[]);
    report(
        "slew right --speed N -> first byte at speed",
        baud,
        MOTION_BYTES,
        m.speed_and_slew,
    );
    report("slew right -> first direction byte", baud, DIRECTION_BYTES, m.slew);
    report("stop pan -> first pan stop byte", baud, STOP_BYTES, m.stop);
    let before = moves(stack, n.div_ceil(2), &["--direct"]);
    report(
        "the same with --direct (no ~W: own NIC window too)",
        baud,
        MOTION_BYTES,
        before.speed_and_slew,
    );
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` runs us with no
    // such flag: then do nothing, quickly.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let starts: Vec<Duration> = (0..env_count("GIMBALCTL_BENCH_MOVES", 50))
        .map(|_| {
            let began = Instant::now();
            let out = Command::new(gimbalctl())
                .arg("--version")
                .output()
                .expect("gimbalctl --version");
            assert!(out.status.success(), "{out:?}");
            began.elapsed()
        })
        .collect();
    println!("0. process start:");
    report("gimbalctl --version, spawn to exit", None, 0, starts);
    let stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
    println!("1.-3. to the first byte on the bus, gcud's port a TCP device server (gimbalsim):");
    run(&stack, None, env_count("GIMBALCTL_BENCH_MOVES", 50));
    drop(stack);
    for baud in [9600, 115_200] {
        let paced = door::Stack::paced(env!("CARGO_BIN_EXE_gcud"), baud);
        println!("   on a bus paced at {baud} bit/s:");
        run(&paced, Some(baud), env_count("GIMBALCTL_BENCH_PACED_MOVES", 30));
    }
}
