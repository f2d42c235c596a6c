//! Framer throughput against a baseline that only sums the same bytes.
//!
//! `cargo bench --bench framer` (in the root package: criterion needs a newer
//! Rust than the protocol crate's MSRV). Streams are ~1 MiB of valid frames
//! of mixed sizes (2..=256 payload bytes), and the same with 10% noise bytes
//! (uniformly random, so 0xF8 false starts and bare ACK/NAK/NIC bytes too).
//! Targets: framer >= 1/3 of the baseline on clean streams, >= 1/5 with noise.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sagebrush_protocol::{Address, Event, Frame, Framer, MAX_FRAME_LEN};

const STREAM_LEN: usize = 1 << 20;

/// xorshift64*: deterministic, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// (dest, source, payload) of the frames of a stream.
type Spec = (Address, u8, Vec<u8>);

fn frames(rng: &mut Rng, total: usize) -> Vec<Spec> {
    // Mostly short commands and results, some long ones (aux data, D?).
    const SIZES: [usize; 8] = [2, 2, 3, 5, 8, 9, 44, 256];
    let mut specs = Vec::new();
    let mut len = 0;
    while len < total {
        let n = SIZES[rng.below(SIZES.len())];
        let payload: Vec<u8> = (0..n).map(|_| b'0' + rng.below(43) as u8).collect();
        let dest = Address::new(rng.below(256) as u8, rng.below(256) as u8, rng.below(256) as u8);
        len += n + 7;
        specs.push((dest, rng.below(256) as u8, payload));
    }
    specs
}

fn wire(specs: &[Spec]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (dest, source, payload) in specs {
        let frame = Frame::new(*dest, *source, payload).unwrap();
        out.extend_from_slice(frame.encode(&mut buf).unwrap());
    }
    out
}

/// Inserts random bytes between frames until they are 10% of the stream.
fn noisy(specs: &[Spec], rng: &mut Rng) -> Vec<u8> {
    let clean = wire(specs);
    let noise_total = clean.len() / 9;
    let mut out = Vec::with_capacity(clean.len() + noise_total);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut noise_left = noise_total;
    for (i, (dest, source, payload)) in specs.iter().enumerate() {
        let left = specs.len() - i;
        let n = if left == 1 {
            noise_left
        } else {
            rng.below(2 * noise_left / left + 1).min(noise_left)
        };
        noise_left -= n;
        out.extend((0..n).map(|_| rng.next() as u8));
        out.extend_from_slice(Frame::new(*dest, *source, payload).unwrap().encode(&mut buf).unwrap());
    }
    out
}

fn baseline(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0u64, |acc, &b| acc + u64::from(b))
}

/// Frames and payload bytes seen, so the work cannot be optimised away.
fn run_feed(bytes: &[u8]) -> (usize, usize) {
    let mut framer: Framer = Framer::new();
    let (mut frames, mut payload) = (0, 0);
    framer.feed(bytes, |event| {
        if let Event::Frame(f) = event {
            frames += 1;
            payload += f.payload().len();
        }
    });
    (frames, payload)
}

fn run_push(bytes: &[u8]) -> usize {
    let mut framer: Framer = Framer::new();
    let mut frames = 0;
    for mut chunk in bytes.chunks(64) {
        while !chunk.is_empty() {
            let n = framer.push(chunk);
            chunk = &chunk[n..];
            while let Some(event) = framer.next_event() {
                frames += matches!(event, Event::Frame(_)) as usize;
            }
        }
    }
    frames
}

fn bench(c: &mut Criterion) {
    let mut rng = Rng(0x5A6E_B2C5_1990_0601);
    let specs = frames(&mut rng, STREAM_LEN);
    let clean = wire(&specs);
    let noise = noisy(&specs, &mut rng);
    // Every frame is found, in both streams.
    assert_eq!(run_feed(&clean).0, specs.len());
    // A random 0xF8 whose bytes happen to sum right (1 in 256) is a false
    // frame that hides the real ones in its span: nearly all are found.
    let found_in_noise = run_feed(&noise).0;
    assert!(
        found_in_noise * 100 >= specs.len() * 99,
        "{found_in_noise} of {}",
        specs.len()
    );
    assert_eq!(run_push(&clean), specs.len());
    eprintln!(
        "streams: clean {} bytes, noisy {} bytes, {} frames ({} found in noise), mean frame {:.1} bytes",
        clean.len(),
        noise.len(),
        specs.len(),
        found_in_noise,
        clean.len() as f64 / specs.len() as f64
    );

    let mut group = c.benchmark_group("clean");
    group.throughput(Throughput::Bytes(clean.len() as u64));
    group.bench_function("baseline_sum", |b| b.iter(|| baseline(black_box(&clean))));
    group.bench_function("framer_feed", |b| b.iter(|| run_feed(black_box(&clean))));
    group.bench_function("framer_push_64", |b| b.iter(|| run_push(black_box(&clean))));
    group.finish();

    let mut group = c.benchmark_group("noisy");
    group.throughput(Throughput::Bytes(noise.len() as u64));
    group.bench_function("baseline_sum", |b| b.iter(|| baseline(black_box(&noise))));
    group.bench_function("framer_feed", |b| b.iter(|| run_feed(black_box(&noise))));
    group.bench_function("framer_push_64", |b| b.iter(|| run_push(black_box(&noise))));
    group.finish();

    let mut group = c.benchmark_group("encode");
    group.throughput(Throughput::Bytes(clean.len() as u64));
    let frames: Vec<Frame<'_>> = specs.iter().map(|(d, s, p)| Frame::new(*d, *s, p).unwrap()).collect();
    let mut out = vec![0u8; clean.len()];
    group.bench_function("frame_encode", |b| {
        b.iter(|| {
            let mut at = 0;
            for frame in black_box(&frames) {
                at += frame.encode(&mut out[at..]).unwrap().len();
            }
            at
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
