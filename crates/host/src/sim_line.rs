//! A simulated bus ([`sagebrush_sim::Bus`]) served on a byte stream: the
//! loop `gimbalsim` runs on a pty, TCP or serial device and `gcud` runs on
//! an in-memory pipe for `simulate = [..]` ports. It keeps a millisecond
//! clock, optionally paces bytes at the line rate (a pty does not), and
//! switches the line rate after a `C0..C7` (Table 4).

use std::collections::VecDeque;
use std::future::Future;
use std::io;
use std::pin::Pin;

use sagebrush_sim::{Bus, Outgoing};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::time::{Duration, Instant};
use tracing::info;

use crate::timing::wire_ms;

/// Resolves when the server should stop.
pub type Shutdown = Pin<Box<dyn Future<Output = ()> + Send>>;

/// How a serving session ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    Eof,
    Shutdown,
}

/// The line clock and pacing state.
#[derive(Debug)]
pub struct Line {
    pub epoch: Instant,
    /// Pace bytes at `baud`, both ways.
    pub pace: bool,
    pub baud: u32,
}

impl Line {
    pub fn now(&self) -> u64 {
        self.epoch.elapsed().as_millis() as u64
    }
}

/// Serves the bus on one stream until it closes or shutdown.
pub async fn serve<S: AsyncRead + AsyncWrite + Unpin + Send>(
    bus: &mut Bus,
    stream: &mut S,
    line: &mut Line,
    set_rate: &mut (dyn FnMut(&mut S, u32) -> io::Result<()> + Send),
    shutdown: &mut Shutdown,
) -> io::Result<End> {
    let mut rx_queue: VecDeque<(u64, Vec<u8>)> = VecDeque::new();
    let (mut rx_free, mut tx_free) = (0u64, 0u64);
    let mut pending: Option<(u64, Outgoing)> = None;
    let mut buf = [0u8; 1024];
    loop {
        let now = line.now();
        while rx_queue.front().is_some_and(|(at, _)| *at <= now) {
            if let Some((_, bytes)) = rx_queue.pop_front() {
                bus.receive(&bytes, now);
            }
        }
        bus.poll(now);
        loop {
            if pending.is_none() {
                pending = bus.pop_due(now).map(|o| {
                    let at = if line.pace {
                        o.due.max(tx_free) + wire_ms(o.bytes.len(), line.baud)
                    } else {
                        o.due
                    };
                    (at, o)
                });
            }
            match pending.take() {
                Some((at, out)) if at <= now => {
                    stream.write_all(&out.bytes).await?;
                    stream.flush().await?;
                    tx_free = at;
                    if let Some(rate) = out.switch_to.and_then(|r| r.bits_per_second()) {
                        info!(bps = rate, "switching the line rate");
                        set_rate(stream, rate)?;
                        line.baud = rate;
                    }
                }
                other => {
                    pending = other;
                    break;
                }
            }
        }
        let deadline = [
            bus.next_deadline(),
            pending.as_ref().map(|(at, _)| *at),
            rx_queue.front().map(|(at, _)| *at),
        ]
        .into_iter()
        .flatten()
        .min()
        .map_or(Instant::now() + Duration::from_secs(3600), |t| {
            line.epoch + Duration::from_millis(t)
        });
        tokio::select! {
            read = stream.read(&mut buf) => match read? {
                0 => return Ok(End::Eof),
                n => {
                    let now = line.now();
                    if line.pace {
                        let at = now.max(rx_free) + wire_ms(n, line.baud);
                        rx_free = at;
                        rx_queue.push_back((at, buf[..n].to_vec()));
                    } else {
                        bus.receive(&buf[..n], now);
                    }
                }
            },
            _ = tokio::time::sleep_until(deadline) => {}
            _ = shutdown.as_mut() => return Ok(End::Shutdown),
        }
    }
}
