//! The ports' I/O on threads of their own (`[gcu] threads`, ARCHITECTURE
//! "Data path", "Scale"): with more than one thread, every port is opened,
//! read and written on one of `threads - 1` port threads, each its own
//! current-thread runtime, while the router task keeps the one router core
//! and the links. A port's stream stays on its thread behind a pump task;
//! the router task's [`Lines`](crate::lines::Lines) holds a [`Relayed`]
//! stream in its place, which hands bytes over through two buffers under a
//! lock (their capacity kept: no allocation per transaction) and wakes the
//! other side only when a buffer it may wait on changes from empty. The
//! router core's decisions are the same whichever thread moved a port's
//! bytes.

use std::io;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll, Waker};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::runtime::Handle;
use tokio::sync::{mpsc, oneshot};

use crate::lines::{LineStream, MAX_PENDING};

/// How long a port thread waits, at shutdown, for its pumps to write what
/// the router task handed them (the router task drains its lines into
/// them first).
const DRAIN: Duration = Duration::from_millis(500);

/// The port threads of one gcud (none with `threads = 1`).
#[derive(Debug)]
pub struct Shards {
    threads: Vec<Shard>,
}

#[derive(Debug)]
struct Shard {
    runtime: Handle,
    /// Held by every pump of the thread: the thread's drain at shutdown
    /// ends when the last is gone.
    alive: mpsc::Sender<()>,
    stop: oneshot::Sender<()>,
    thread: JoinHandle<()>,
}

impl Shards {
    /// `threads - 1` port threads (`threads` counts the router task's).
    pub fn start(threads: u8) -> io::Result<Self> {
        let threads = (1..threads).map(Shard::start).collect::<io::Result<_>>()?;
        Ok(Self { threads })
    }

    /// Where port `id` is opened and served: `None` on the router task's
    /// own thread (`threads = 1`), else a port thread (ports dealt out in
    /// turn by id) and what wraps its stream there.
    pub fn place(&self, id: u8) -> Option<(&Handle, Relay)> {
        let shard = self.threads.get(usize::from(id) % self.threads.len().max(1))?;
        Some((
            &shard.runtime,
            Relay {
                alive: shard.alive.clone(),
            },
        ))
    }

    /// Stops the port threads once their pumps wrote what they hold
    /// ([`DRAIN`] at most), and waits for them.
    pub fn stop(self) {
        let joining: Vec<_> = self
            .threads
            .into_iter()
            .map(|shard| {
                let _ = shard.stop.send(());
                shard.thread
            })
            .collect();
        for thread in joining {
            let _ = thread.join();
        }
    }
}

impl Shard {
    fn start(index: u8) -> io::Result<Self> {
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let handle = runtime.handle().clone();
        let (stop, stopped) = oneshot::channel::<()>();
        let (alive, mut gone) = mpsc::channel::<()>(1);
        let thread = std::thread::Builder::new()
            .name(format!("gcud-ports-{index}"))
            .spawn(move || {
                runtime.block_on(async move {
                    let _ = stopped.await;
                    // Every pump holds a sender: `recv` ends once the last is gone.
                    let _ = tokio::time::timeout(DRAIN, gone.recv()).await;
                });
            })?;
        Ok(Self {
            runtime: handle,
            alive,
            stop,
            thread,
        })
    }
}

/// Wraps a port's stream on its port thread ([`Shards::place`]).
#[derive(Debug, Clone)]
pub struct Relay {
    alive: mpsc::Sender<()>,
}

impl Relay {
    /// Starts the pump of `stream` on the current (port) thread's runtime
    /// and returns the stream the router task reads and writes in its
    /// place.
    pub fn wrap(self, stream: Box<dyn LineStream>) -> Relayed {
        let holds_lone_ack = stream.holds_lone_ack();
        let shared = Arc::new(Mutex::new(Buffers::default()));
        let mut pump = Pump {
            stream,
            shared: shared.clone(),
            out: Vec::new(),
            written: 0,
            read: Box::new([0; 4096]),
            held: 0,
            _alive: self.alive,
        };
        tokio::spawn(std::future::poll_fn(move |cx| pump.poll(cx)));
        Relayed { shared, holds_lone_ack }
    }
}

/// What the router task and a port's pump share.
#[derive(Debug, Default)]
struct Buffers {
    /// Read from the port, not yet taken by the router task.
    inbound: Vec<u8>,
    /// Written by the router task, not yet taken by the pump.
    outbound: Vec<u8>,
    /// The pump holds a read that `inbound` had no room for.
    pump_holds_read: bool,
    /// How the port's stream ended (the pump is gone).
    ended: Option<End>,
    /// The router task's line waker, waiting for bytes or room.
    router: Option<Waker>,
    /// The pump's waker, waiting for bytes to write or room to read into.
    pump: Option<Waker>,
    /// The router task let go of the line: the pump writes what goes at
    /// once and ends.
    released: bool,
}

#[derive(Debug)]
enum End {
    /// The peer closed the line.
    Closed,
    /// A read or write failed.
    Failed(io::ErrorKind, String),
}

fn lock(shared: &Mutex<Buffers>) -> MutexGuard<'_, Buffers> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Keeps `slot` waking `waker`'s task (a clone only when it changed).
fn register(slot: &mut Option<Waker>, waker: &Waker) {
    if !slot.as_ref().is_some_and(|w| w.will_wake(waker)) {
        *slot = Some(waker.clone());
    }
}

/// A port's stream as the router task sees it when the port lives on a
/// port thread: its bytes go through the pump's buffers (its rate is
/// switched by the router task as any port's, `lines::Rate`).
#[derive(Debug)]
pub struct Relayed {
    shared: Arc<Mutex<Buffers>>,
    holds_lone_ack: bool,
}

impl LineStream for Relayed {
    fn holds_lone_ack(&self) -> bool {
        self.holds_lone_ack
    }
}

impl AsyncRead for Relayed {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let mut shared = lock(&self.shared);
        if !shared.inbound.is_empty() {
            let n = shared.inbound.len().min(buf.remaining());
            buf.put_slice(&shared.inbound[..n]);
            shared.inbound.drain(..n);
            let pump = shared.pump_holds_read.then(|| shared.pump.take()).flatten();
            drop(shared);
            if let Some(pump) = pump {
                pump.wake();
            }
            return Poll::Ready(Ok(()));
        }
        match &shared.ended {
            Some(End::Closed) => Poll::Ready(Ok(())),
            Some(End::Failed(kind, why)) => Poll::Ready(Err(io::Error::new(*kind, why.clone()))),
            None => {
                register(&mut shared.router, cx.waker());
                Poll::Pending
            }
        }
    }
}

impl AsyncWrite for Relayed {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let mut shared = lock(&self.shared);
        match &shared.ended {
            Some(End::Closed) => return Poll::Ready(Err(io::ErrorKind::BrokenPipe.into())),
            Some(End::Failed(kind, why)) => return Poll::Ready(Err(io::Error::new(*kind, why.clone()))),
            None => {}
        }
        let room = MAX_PENDING.saturating_sub(shared.outbound.len());
        if room == 0 {
            register(&mut shared.router, cx.waker());
            return Poll::Pending;
        }
        let n = buf.len().min(room);
        let was_empty = shared.outbound.is_empty();
        shared.outbound.extend_from_slice(&buf[..n]);
        let pump = if was_empty { shared.pump.take() } else { None };
        drop(shared);
        if let Some(pump) = pump {
            pump.wake();
        }
        Poll::Ready(Ok(n))
    }

    fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }

    fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}

impl Drop for Relayed {
    /// The line is closed (or gcud stops): the pump writes what goes at
    /// once and ends, closing the port on its thread.
    fn drop(&mut self) {
        let mut shared = lock(&self.shared);
        shared.released = true;
        let pump = shared.pump.take();
        drop(shared);
        if let Some(pump) = pump {
            pump.wake();
        }
    }
}

/// A port's stream on its port thread, moving bytes between it and the
/// router task's [`Relayed`].
struct Pump {
    stream: Box<dyn LineStream>,
    shared: Arc<Mutex<Buffers>>,
    /// Taken from `outbound` whole (capacities swapped, never reallocated),
    /// written from `written` on.
    out: Vec<u8>,
    written: usize,
    read: Box<[u8; 4096]>,
    /// Bytes of `read` not yet handed over (no room in `inbound`).
    held: usize,
    _alive: mpsc::Sender<()>,
}

impl Pump {
    /// Moves bytes both ways until neither way can go on; ends when the
    /// stream ends or the router task let go of it.
    fn poll(&mut self, cx: &mut Context<'_>) -> Poll<()> {
        loop {
            let released = self.exchange(cx);
            let mut progress = false;
            while self.written < self.out.len() {
                match Pin::new(&mut self.stream).poll_write(cx, &self.out[self.written..]) {
                    Poll::Ready(Ok(0)) => {
                        return self.end(End::Failed(
                            io::ErrorKind::WriteZero,
                            "the line takes no more bytes".into(),
                        ));
                    }
                    Poll::Ready(Ok(n)) => {
                        self.written += n;
                        progress = true;
                    }
                    Poll::Ready(Err(e)) => return self.end(End::Failed(e.kind(), format!("write failed: {e}"))),
                    Poll::Pending => break,
                }
            }
            if self.written == self.out.len() {
                self.out.clear();
                self.written = 0;
            }
            if released {
                return Poll::Ready(());
            }
            if self.held == 0 {
                let mut read = ReadBuf::new(&mut self.read[..]);
                match Pin::new(&mut self.stream).poll_read(cx, &mut read) {
                    Poll::Ready(Ok(())) if read.filled().is_empty() => return self.end(End::Closed),
                    Poll::Ready(Ok(())) => {
                        self.held = read.filled().len();
                        progress = true;
                    }
                    Poll::Ready(Err(e)) => return self.end(End::Failed(e.kind(), e.to_string())),
                    Poll::Pending => {}
                }
            }
            if !progress {
                return Poll::Pending;
            }
        }
    }

    /// Under one lock: hands the read held over (room permitting), takes
    /// the bytes to write (when the last are written) and registers the
    /// pump's waker; whether the router task let go of the line.
    fn exchange(&mut self, cx: &Context<'_>) -> bool {
        let mut shared = lock(&self.shared);
        let mut router = None;
        if self.held > 0 && shared.inbound.len() + self.held <= MAX_PENDING {
            shared.inbound.extend_from_slice(&self.read[..self.held]);
            self.held = 0;
            router = shared.router.take();
        }
        shared.pump_holds_read = self.held > 0;
        if self.out.is_empty() && !shared.outbound.is_empty() {
            let was_full = shared.outbound.len() >= MAX_PENDING;
            std::mem::swap(&mut self.out, &mut shared.outbound);
            if was_full && router.is_none() {
                // The router task waits for room to write.
                router = shared.router.take();
            }
        }
        register(&mut shared.pump, cx.waker());
        let released = shared.released;
        drop(shared);
        if let Some(router) = router {
            router.wake();
        }
        released
    }

    /// Records how the stream ended for the router task, which closes the
    /// line (and its task reopens the port).
    fn end(&mut self, end: End) -> Poll<()> {
        let mut shared = lock(&self.shared);
        shared.ended = Some(end);
        let router = shared.router.take();
        drop(shared);
        if let Some(router) = router {
            router.wake();
        }
        Poll::Ready(())
    }
}

#[cfg(test)]
mod tests {
    use std::io::{Read, Write};

    use serialport::{SerialPort, TTYPort};
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    use super::*;
    use crate::lines::LineRate;
    use crate::serial::SerialLine;

    /// A pseudo-terminal: its device side (the master, read and written
    /// by the test as a gimbal would; its settings are its slave's) and the
    /// path gcud opens.
    fn pty() -> (TTYPort, String) {
        let (mut master, slave) = TTYPort::pair().expect("a pseudo-terminal");
        master.set_timeout(Duration::from_secs(30)).expect("a read time-out");
        // The slave handle closes here: gcud's open keeps the terminal.
        (master, slave.name().expect("its path"))
    }

    /// A serial port opened on a port thread and relayed to this (the
    /// router's) runtime, with its rate switch and the port threads that
    /// serve it.
    async fn relayed(path: &str) -> (Relayed, TTYPort, Shards) {
        let shards = Shards::start(2).expect("a port thread");
        let (thread, relay) = shards.place(1).expect("placed on the port thread");
        let path = path.to_owned();
        let (stream, control) = thread
            .spawn(async move {
                let (line, control) = SerialLine::open(&path, 9600).expect("opened");
                (relay.wrap(Box::new(line)), control)
            })
            .await
            .expect("the port thread runs");
        (stream, control, shards)
    }

    /// A blocking read of `n` bytes from the device side, started now off
    /// the runtime.
    fn device_reads(device: &TTYPort, n: usize) -> tokio::task::JoinHandle<Vec<u8>> {
        let mut device = device.try_clone_native().expect("device side");
        tokio::task::spawn_blocking(move || {
            let mut got = vec![0; n];
            device.read_exact(&mut got).expect("read");
            got
        })
    }

    #[test]
    fn one_thread_places_every_port_on_the_router_task() {
        let shards = Shards::start(1).expect("no thread to start");
        assert!((1..=254).all(|id| shards.place(id).is_none()));
        shards.stop();
    }

    #[tokio::test]
    async fn bytes_cross_both_ways_in_order_and_the_rate_switches_from_the_router_thread() {
        let (mut device, path) = pty();
        let (mut line, mut control, shards) = relayed(&path).await;
        // Router to device: more than a buffer between them holds.
        let data: Vec<u8> = (0..200_000u32).map(|i| i as u8).collect();
        let reader = device_reads(&device, data.len());
        tokio::time::timeout(Duration::from_secs(30), line.write_all(&data))
            .await
            .expect("written in time")
            .expect("written");
        let read = tokio::time::timeout(Duration::from_secs(30), reader).await;
        assert!(
            read.expect("read in time").expect("reader") == data,
            "every byte, in order"
        );
        // Device to router.
        device.write_all(b"\x06result").expect("device writes");
        let mut got = [0; 7];
        tokio::time::timeout(Duration::from_secs(10), line.read_exact(&mut got))
            .await
            .expect("relayed in time")
            .expect("read");
        assert_eq!(&got, b"\x06result");
        // The rate is the terminal's, switched from this (the router's)
        // thread through the handle the port was configured with, while
        // the port's bytes move on its own thread.
        assert_eq!(device.baud_rate().expect("the rate"), 9600);
        LineRate::set_baud(&mut control, 19_200).expect("switched");
        assert_eq!(device.baud_rate().expect("the rate"), 19_200);
        drop((line, control));
        shards.stop();
    }

    #[tokio::test]
    async fn a_port_that_vanishes_ends_the_relayed_line_and_a_released_line_closes_the_port() {
        let (device, path) = pty();
        let (mut line, _control, shards) = relayed(&path).await;
        drop(device);
        let mut buf = [0; 16];
        let read = tokio::time::timeout(Duration::from_secs(10), line.read(&mut buf))
            .await
            .expect("the end relayed in time");
        assert!(matches!(read, Ok(0) | Err(_)), "the line ended: {read:?}");
        assert!(line.write(b"P?").await.is_err(), "and takes no more writes");
        drop(line);

        // Released by the router task: the pump ends and the port closes,
        // which the device side sees as its terminal hung up.
        let (device, path) = pty();
        let (line, control, shards2) = relayed(&path).await;
        drop((line, control));
        let mut reader = device.try_clone_native().expect("device");
        let closed = tokio::task::spawn_blocking(move || {
            let mut buf = [0; 16];
            reader.read(&mut buf)
        });
        let closed = tokio::time::timeout(Duration::from_secs(40), closed)
            .await
            .expect("the port closed in time")
            .expect("reader");
        assert!(
            closed.as_ref().is_err_and(|e| e.kind() != io::ErrorKind::TimedOut),
            "hung up: {closed:?}"
        );
        shards.stop();
        shards2.stop();
    }
}
