//! Where frames come in: a serial line (opened with `sagebrush_host`'s
//! serial helper, as gcud opens its buses, and again whenever it closes or
//! is unplugged), TCP connections accepted through the shared bounded
//! listener (`sagebrush_service`: a cap in all and per peer, an idle
//! time-out, the idlest evicted for a newcomer), and UDP datagrams.
//!
//! Each stream is read into a fixed buffer and parsed as it comes
//! ([`crate::codec::Parser`], which holds at most one frame's bytes), its
//! frames carried out at once ([`crate::keyboard`]): when gcud is slower
//! than a keyboard, nothing piles up here (the session coalesces). Answers
//! go through a queue of [`REPLY_QUEUE`] per stream; a peer that does not
//! read loses answers, it stalls nothing. UDP keeps a keyboard (its
//! parser, for a frame split over datagrams, and its state) per source
//! address, at most `[limits] udp_sources`, the longest quiet forgotten
//! first.

use std::collections::HashMap;
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use sagebrush_service::{BoundedListener, Connections};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, UdpSocket};
use tokio::sync::mpsc;
use tokio::time::Instant;
use tracing::{debug, info, warn};

use crate::codec::{Found, Parser};
use crate::keyboard::{Door, Keyboard, Replies};
use crate::stats::{Stats, may_log};

/// One read: a few dozen frames.
const READ: usize = 512;
/// Answers waiting to be written to one stream.
pub const REPLY_QUEUE: usize = 16;
/// A serial line that failed is opened again after this.
pub const REOPEN: Duration = Duration::from_secs(2);

/// Carries out what `parser` found in `bytes` for `keyboard`; skipped
/// bytes are counted and logged with their offset in the stream.
fn carry_out(parser: &mut Parser, bytes: &[u8], keyboard: &Keyboard, stats: &Stats) {
    parser.feed(bytes, |found| match found {
        Found::Frame { frame, .. } => keyboard.frame(&frame),
        Found::Skipped { at, len, checksum } => skipped(keyboard, stats, at, len, checksum),
    });
}

fn skipped(keyboard: &Keyboard, stats: &Stats, at: u64, len: u64, checksum: bool) {
    Stats::count(&stats.skipped_runs);
    Stats::add(&stats.skipped_bytes, len);
    if checksum {
        Stats::count(&stats.bad_checksums);
    }
    if let Some(more) = may_log("skipped", &keyboard.who) {
        let why = if checksum {
            "a frame whose check byte (or ETX) is wrong"
        } else {
            "no frame (noise, or a frame cut short)"
        };
        warn!(keyboard = %keyboard.who, offset = at, bytes = len, more, "skipped {len} byte(s) at byte offset {at}: {why} (logged at most every 10 s)");
    }
}

/// Reads `stream` until it ends or `end` resolves, writing its answers.
async fn serve<S>(stream: S, door: Arc<Door>, peer: String, end: impl Future<Output = &'static str>)
where
    S: AsyncRead + AsyncWrite + Send + 'static,
{
    let (mut rd, mut wr) = tokio::io::split(stream);
    let (tx, mut rx) = mpsc::channel::<Vec<u8>>(REPLY_QUEUE);
    let writer = tokio::spawn(async move {
        while let Some(bytes) = rx.recv().await {
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    let replies: Replies = Arc::new(move |bytes| {
        let _ = tx.try_send(bytes);
    });
    let keyboard = Keyboard::new(Arc::clone(&door), &peer, replies);
    door.sessions.streams.fetch_add(1, Ordering::Relaxed);
    let mut parser = Parser::new(door.protocol);
    let mut buf = [0u8; READ];
    tokio::pin!(end);
    let why = loop {
        let n = tokio::select! {
            read = rd.read(&mut buf) => match read {
                Ok(0) => break "closed",
                Ok(n) => n,
                Err(_) => break "read failed",
            },
            why = &mut end => break why,
        };
        carry_out(&mut parser, &buf[..n], &keyboard, &door.stats);
    };
    parser.finish(|f| {
        if let Found::Skipped { at, len, checksum } = f {
            skipped(&keyboard, &door.stats, at, len, checksum);
        }
    });
    writer.abort();
    door.sessions.streams.fetch_sub(1, Ordering::Relaxed);
    if may_log("ended", &keyboard.who).is_some() {
        info!(keyboard = %keyboard.who, bytes = parser.offset(), "{why}");
    }
}

/// `serial`: keeps `path` open at `baud`, opening it again after
/// [`REOPEN`]; the first failure in a row is a warning, the rest debug.
pub async fn serial(path: PathBuf, baud: u32, door: Arc<Door>) {
    let name = path.to_string_lossy().into_owned();
    let mut failed = false;
    loop {
        match sagebrush_host::transport::open_serial(&name, baud) {
            Ok(port) => {
                failed = false;
                info!(input = %door.input, protocol = door.protocol.name(), baud, "serial line open");
                serve(port, Arc::clone(&door), String::new(), std::future::pending()).await;
            }
            Err(e) if !failed => {
                failed = true;
                warn!(input = %door.input, error = %e, "cannot open the serial line; trying again every 2 s");
            }
            Err(e) => debug!(input = %door.input, error = %e, "cannot open the serial line"),
        }
        tokio::time::sleep(REOPEN).await;
    }
}

/// `tcp_listen`: binds now (an error names the address), then accepts
/// through the bounded listener's `table` for ever.
pub async fn tcp(
    addr: SocketAddr,
    door: Arc<Door>,
    table: Arc<Connections>,
) -> Result<impl Future<Output = ()>, String> {
    let listener = TcpListener::bind(addr)
        .await
        .map_err(|e| format!("{}: cannot listen on {addr}: {e}", door.input))?;
    let mut listener = BoundedListener::new(listener, table, door.input.clone());
    let bound = listener.local_addr().map_err(|e| e.to_string())?;
    info!(input = %door.input, protocol = door.protocol.name(), addr = %bound, "Pelco TCP listening");
    Ok(async move {
        loop {
            let (stream, peer, mut admitted) = listener.accept().await;
            let _ = stream.set_nodelay(true);
            let stream = admitted.track(stream);
            let door = Arc::clone(&door);
            tokio::spawn(async move {
                let end = async move { admitted.ended().await.reason() };
                serve(stream, door, peer.to_string(), end).await;
            });
        }
    })
}

/// One UDP source's keyboard and parser.
struct Source {
    keyboard: Keyboard,
    parser: Parser,
    heard: Instant,
}

/// `udp_listen`: binds now, then reads datagrams for ever; answers go to
/// the datagram's source.
pub async fn udp(addr: SocketAddr, door: Arc<Door>, max_sources: usize) -> Result<impl Future<Output = ()>, String> {
    let socket = Arc::new(
        UdpSocket::bind(addr)
            .await
            .map_err(|e| format!("{}: cannot listen on {addr}: {e}", door.input))?,
    );
    let bound = socket.local_addr().map_err(|e| e.to_string())?;
    info!(input = %door.input, protocol = door.protocol.name(), addr = %bound, "Pelco UDP listening");
    Ok(async move {
        let mut sources: HashMap<SocketAddr, Source> = HashMap::new();
        let mut buf = vec![0u8; 2048];
        loop {
            let (n, from) = match socket.recv_from(&mut buf).await {
                Ok(got) => got,
                Err(e) => {
                    debug!(input = %door.input, error = %e, "UDP receive failed");
                    continue;
                }
            };
            if !sources.contains_key(&from) && sources.len() >= max_sources {
                let oldest = sources.iter().min_by_key(|(_, s)| s.heard).map(|(a, _)| *a);
                if let Some(a) = oldest {
                    sources.remove(&a);
                    Stats::count(&door.stats.udp_sources_forgotten);
                }
            }
            let source = sources.entry(from).or_insert_with(|| {
                let socket = Arc::clone(&socket);
                let replies: Replies = Arc::new(move |bytes: Vec<u8>| {
                    let _ = socket.try_send_to(&bytes, from);
                });
                Source {
                    keyboard: Keyboard::new(Arc::clone(&door), &from.to_string(), replies),
                    parser: Parser::new(door.protocol),
                    heard: Instant::now(),
                }
            });
            source.heard = Instant::now();
            door.sessions.udp.note(from);
            carry_out(&mut source.parser, &buf[..n], &source.keyboard, &door.stats);
        }
    })
}
