//! `cargo bench --bench bus_efficiency`: how close `gimbalsim --pace` comes
//! to the line rate. A master on the simulator's pseudo-terminal sends `P?`
//! to device 1 again and again, each time waiting for the ACK and the result
//! and ACKing the result, as a GCU port does (Figure 6). One transaction is
//! 26 bytes on the wire (command 9, ACK 1, result 15, ACK 1), so at `baud`
//! the line carries at most `baud / 10 / 26` transactions per second.
//!
//! Printed per rate: transactions per second, achieved / theoretical, the
//! mean time per transaction beyond its 26 byte-times, and the device's
//! turnaround: from the command written to the ACK read, less the 11
//! byte-times on the wire in between (the master's ACK of the previous
//! result, written just before, the command and the device's ACK), in
//! byte-times (p50 / p99), and the whole transaction (command written to the
//! result's ACK written; 26 byte-times on the wire) in byte-times (p50 / p99:
//! the figure `tests/simulator.rs` once asserted, a median under 38).
//! Figures are printed, never asserted: the machines are
//! shared and noisy. `BUS_BENCH_SECONDS` sets the seconds per rate
//! (default 3); `BUS_BENCH_RATES` the rates (default `9600,115200`);
//! `BUS_BENCH_SIM_ARGS` extra gimbalsim arguments (e.g. `--reply-delay-us 0`);
//! `BUS_BENCH_GIMBALSIM` another gimbalsim binary to measure (before/after).

use std::fs::File;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Event, FrameBuf, Framer};
use support::{Proc, TRANSACTION_BYTES, percentile};

#[allow(dead_code)] // the paced device is for the gcud and door benchmarks
mod support;

fn spawn_sim(baud: u32, extra: &[String]) -> (Proc, String) {
    let bin = std::env::var("BUS_BENCH_GIMBALSIM").unwrap_or_else(|_| env!("CARGO_BIN_EXE_gimbalsim").into());
    let rate = baud.to_string();
    let mut args = vec!["--pace", "--baud", &rate];
    args.extend(extra.iter().map(String::as_str));
    support::gimbalsim(&bin, &args)
}

/// One `P?` transaction; returns the time from the command written to the
/// ACK read, and to the result's ACK written (the whole transaction).
fn transaction(port: &mut File, command: &[u8], framer: &mut Framer) -> (Duration, Duration) {
    let start = Instant::now();
    port.write_all(command).expect("write command");
    let (mut ack_at, mut result) = (None, false);
    let mut buf = [0u8; 64];
    while !result {
        let n = port.read(&mut buf).expect("read answer");
        assert!(n > 0, "the simulator closed the line");
        let now = Instant::now();
        framer.feed(&buf[..n], |event| match event {
            Event::Ack => ack_at = ack_at.or(Some(now)),
            Event::Frame(_) => result = true,
            other => panic!("unexpected answer {other:?}"),
        });
    }
    port.write_all(&[ACK]).expect("write ACK");
    (ack_at.expect("ACK before the result") - start, start.elapsed())
}

fn run(baud: u32, seconds: f64, extra: &[String]) {
    let (_sim, path) = spawn_sim(baud, extra);
    let mut port = File::options().read(true).write(true).open(&path).expect("open pty");
    let command = FrameBuf::new(Address::new(1, 1, 1), 0, b"P?").expect("frame");
    let mut framer: Framer = Framer::new();
    for _ in 0..5 {
        transaction(&mut port, command.as_bytes(), &mut framer);
    }
    let (mut turnarounds, mut wholes) = (Vec::new(), Vec::new());
    let start = Instant::now();
    while start.elapsed().as_secs_f64() < seconds {
        let (turnaround, whole) = transaction(&mut port, command.as_bytes(), &mut framer);
        turnarounds.push(turnaround);
        wholes.push(whole);
    }
    let elapsed = start.elapsed().as_secs_f64();
    let byte_time = 10.0 / f64::from(baud);
    let rate = turnarounds.len() as f64 / elapsed;
    let theoretical = f64::from(baud) / 10.0 / TRANSACTION_BYTES;
    let overhead = (elapsed / turnarounds.len() as f64) / byte_time - TRANSACTION_BYTES;
    turnarounds.sort();
    wholes.sort();
    let in_bytes = |d: Duration| d.as_secs_f64() / byte_time - 11.0;
    let whole = |d: Duration| d.as_secs_f64() / byte_time;
    println!(
        "{baud:>6} bit/s: {rate:7.1} P?/s of {theoretical:6.1} theoretical = {:.3}; \
         {overhead:+.2} byte-times per transaction beyond 26; \
         turnaround p50 {:+.2} p99 {:+.2} byte-times; \
         transaction p50 {:.1} p99 {:.1} byte-times ({} transactions)",
        rate / theoretical,
        in_bytes(percentile(&turnarounds, 0.5)),
        in_bytes(percentile(&turnarounds, 0.99)),
        whole(percentile(&wholes, 0.5)),
        whole(percentile(&wholes, 0.99)),
        turnarounds.len(),
    );
}

fn main() {
    // `cargo bench` passes `--bench`; this harness takes no arguments.
    let seconds = std::env::var("BUS_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    let rates: Vec<u32> = std::env::var("BUS_BENCH_RATES")
        .unwrap_or_else(|_| "9600,115200".into())
        .split(',')
        .map(|r| r.trim().parse().expect("BUS_BENCH_RATES: bit/s, comma separated"))
        .collect();
    let extra: Vec<String> = std::env::var("BUS_BENCH_SIM_ARGS")
        .unwrap_or_default()
        .split_whitespace()
        .map(str::to_owned)
        .collect();
    println!("gimbalsim --pace, sequential P? from a master on its pty");
    for baud in rates {
        run(baud, seconds, &extra);
    }
}
