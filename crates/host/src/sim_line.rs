//! A simulated bus ([`sagebrush_sim::Bus`]) served on a byte stream: the
//! loop `gimbalsim` runs on a pty, TCP or serial device and `gcud` runs on
//! an in-memory pipe for `simulate = [..]` ports. It keeps a millisecond
//! clock for the bus, optionally times the line as a real one would (a pty
//! does not), and switches the line rate after a `C0..C7` (Table 4).
//!
//! With [`LineClock::pace`] both directions take their wire time at [`LineClock::baud`]
//! (10 bits a byte), computed, not slept byte by byte: bytes read are heard
//! by the bus when their last bit would have arrived, and each answer (an
//! ACK, a NIC, a result frame) starts [`LineClock::reply_delay`] after the
//! command's last byte, or when the line is free, and is written in one go
//! at the instant its last byte would have left. Tokio's timer ticks in
//! milliseconds, longer than a byte at 115200 bit/s, so the last two
//! milliseconds of a paced wait are a thread sleep: the answer leaves within
//! some tens of microseconds of its time. Without pacing nothing is slept
//! but results the bus itself delays (`IX`, a reply latency, a fault).

use std::collections::VecDeque;
use std::future::Future;
use std::io;
use std::pin::Pin;

use sagebrush_sim::{Bus, Outgoing};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::time::{Duration, Instant};
use tracing::info;

use crate::timing::BITS_PER_BYTE;

/// Resolves when the server should stop.
pub type Shutdown = Pin<Box<dyn Future<Output = ()> + Send>>;

/// How a serving session ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    Eof,
    Shutdown,
}

/// What a paced wait leaves to a thread sleep: tokio's timer rounds a
/// deadline up to its next millisecond tick and the driver's wake-up adds
/// up to another, so it may fire up to two milliseconds late.
const TICK: Duration = Duration::from_millis(2);

/// What a thread sleep may overshoot by: tens of microseconds, most of a
/// byte-time at 115200 bit/s. The last stretch of a paced wait is spun.
const SPIN: Duration = Duration::from_micros(200);

/// Waits until `at`: a thread sleep for all but the last [`SPIN`], then a
/// spin, so that an answer leaves within a fraction of a byte-time of its
/// instant (the simulator owns its thread while it waits).
fn settle_until(at: Instant) {
    if let Some(long) = at.saturating_duration_since(Instant::now()).checked_sub(SPIN) {
        std::thread::sleep(long);
    }
    while Instant::now() < at {
        std::hint::spin_loop();
    }
}

/// The line clock and pacing state.
#[derive(Debug)]
pub struct LineClock {
    pub epoch: Instant,
    /// Time bytes at `baud`, both ways.
    pub pace: bool,
    pub baud: u32,
    /// With `pace`: from a command's last byte to the first byte of its
    /// answer (a device's turnaround).
    pub reply_delay: Duration,
}

impl LineClock {
    /// Milliseconds since `epoch`, the bus's clock.
    pub fn now(&self) -> u64 {
        self.ms(Instant::now())
    }

    fn ms(&self, at: Instant) -> u64 {
        at.saturating_duration_since(self.epoch).as_millis() as u64
    }

    /// How long `bytes` take on the wire at `baud`.
    pub fn wire_time(&self, bytes: usize) -> Duration {
        let bits = bytes as u64 * BITS_PER_BYTE;
        Duration::from_nanos(bits * 1_000_000_000 / u64::from(self.baud.max(1)))
    }
}

/// Bytes to write at `at` (with pacing: when their last byte is through).
#[derive(Debug)]
struct Scheduled {
    at: Instant,
    out: Outgoing,
}

/// The writing side: answers in line order, each at its instant.
#[derive(Debug)]
struct Tx {
    queue: VecDeque<Scheduled>,
    /// When the line is next free to start a byte.
    free: Instant,
}

impl Tx {
    /// Takes what the bus has due by `now_ms`; `heard` is when the last
    /// received byte was through (an answer cannot start before it).
    fn schedule(&mut self, bus: &mut Bus, now_ms: u64, heard: Instant, line: &LineClock) {
        while let Some(out) = bus.pop_due(now_ms) {
            let due = line.epoch + Duration::from_millis(out.due);
            let at = if line.pace {
                let start = (due.max(heard) + line.reply_delay).max(self.free);
                let end = start + line.wire_time(out.bytes.len());
                self.free = end;
                end
            } else {
                due
            };
            self.queue.push_back(Scheduled { at, out });
        }
    }
}

/// Serves the bus on one stream until it closes or shutdown.
pub async fn serve<S: AsyncRead + AsyncWrite + Unpin + Send>(
    bus: &mut Bus,
    stream: &mut S,
    line: &mut LineClock,
    set_rate: &mut (dyn FnMut(&mut S, u32) -> io::Result<()> + Send),
    shutdown: &mut Shutdown,
) -> io::Result<End> {
    let mut tx = Tx {
        queue: VecDeque::new(),
        free: line.epoch,
    };
    // When the last received byte is through the line, and the bus's time
    // for it (ahead of the clock while paced bytes are still "on the wire").
    let mut heard = line.epoch;
    let mut heard_ms = 0u64;
    let mut buf = [0u8; 1024];
    loop {
        let now_ms = line.now().max(heard_ms);
        bus.poll(now_ms);
        tx.schedule(bus, now_ms, heard, line);
        while let Some(next) = tx.queue.front() {
            let wait = next.at.saturating_duration_since(Instant::now());
            if line.pace && !wait.is_zero() && wait <= TICK {
                settle_until(next.at);
            } else if !wait.is_zero() {
                break;
            }
            let Some(Scheduled { out, .. }) = tx.queue.pop_front() else {
                break;
            };
            if !out.bytes.is_empty() {
                stream.write_all(&out.bytes).await?;
                stream.flush().await?;
            }
            if let Some(rate) = out.switch_to.and_then(|r| r.bits_per_second()) {
                info!(bps = rate, "switching the line rate");
                set_rate(stream, rate)?;
                line.baud = rate;
            }
        }
        let write_at = tx.queue.front().map(|s| {
            if line.pace {
                s.at.checked_sub(TICK).unwrap_or(s.at)
            } else {
                s.at
            }
        });
        let bus_at = bus.next_deadline().map(|t| line.epoch + Duration::from_millis(t));
        let deadline = write_at
            .into_iter()
            .chain(bus_at)
            .min()
            .unwrap_or_else(|| Instant::now() + Duration::from_secs(3600));
        tokio::select! {
            read = stream.read(&mut buf) => match read? {
                0 => return Ok(End::Eof),
                n => {
                    let now = Instant::now();
                    heard = if line.pace { now.max(heard) + line.wire_time(n) } else { now };
                    heard_ms = heard_ms.max(line.ms(heard));
                    bus.receive(&buf[..n], heard_ms);
                }
            },
            _ = tokio::time::sleep_until(deadline) => {}
            _ = shutdown.as_mut() => return Ok(End::Shutdown),
        }
    }
}
