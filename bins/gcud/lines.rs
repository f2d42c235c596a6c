//! The open ports and links of the GCU, owned by the router task: it reads
//! every line into one buffer and writes the router's output straight from
//! its `Outbox`, with no task between a line and the router core and no
//! allocation per frame (ARCHITECTURE "Data path"). The tasks of module
//! `io` open the lines, reconnect them and watch admission; they hand each
//! open stream over and wait to hear how it ended.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll, Wake, Waker};
use std::time::Duration;

pub use sagebrush_gcu::LineId;
use sagebrush_host::capture::Tap;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::sync::oneshot;
use tokio::time::Instant;

use crate::admission::Connections;
use sagebrush_protocol::ACK;

/// A line's byte stream, whichever its medium; its rate is switched apart
/// ([`Rate`]).
pub trait LineStream: AsyncRead + AsyncWrite + Unpin + Send + std::fmt::Debug {
    /// Whether a lone ACK written to the line waits up to [`ACK_HOLD`] for
    /// the line's next write to ride with it: on a TCP device server, where
    /// every write is a segment the server wakes for.
    fn holds_lone_ack(&self) -> bool {
        false
    }
}

/// A port's line-rate switch (Table 4 `C0..C7`), held by the router task
/// apart from the port's bytes, which may move on a port thread (module
/// `shard`): the rate is the line's, whichever handle sets it.
pub trait LineRate: Send + std::fmt::Debug {
    fn set_baud(&mut self, baud: u32) -> io::Result<()>;
}

/// The switch of a line without a rate (a link, an in-memory pipe).
#[derive(Debug)]
pub struct NoRate;

impl LineRate for NoRate {
    fn set_baud(&mut self, _baud: u32) -> io::Result<()> {
        Ok(())
    }
}

/// A line's rate: what it runs at, and its switch.
#[derive(Debug)]
pub struct Rate {
    pub baud: u32,
    pub switch: Box<dyn LineRate>,
}

impl Rate {
    /// A link's: none.
    pub fn none() -> Self {
        Self {
            baud: 0,
            switch: Box::new(NoRate),
        }
    }
}

/// How long gcud's ACK of a device's result may wait for the port's next
/// write (1.4.2 gives the receiver's ACK no time; gcud grants a device at
/// least 10 ms for its own, `ports.ack_timeout_ms`, and the protocol
/// crate's device endpoint sends a result again only on a NAK). On a TCP
/// device server the ACK then rides in the next command's segment, as a
/// relay passes a client's ACK with its next command: one segment and one
/// wake of the server per transaction, not two (ARCHITECTURE "Data path").
pub const ACK_HOLD: Duration = Duration::from_millis(1);

/// How a line ended, told to the task that opened it.
#[derive(Debug)]
pub struct Ended {
    pub reason: String,
    /// A port's line rate when it ended (switched by `C0..C7`), to reopen at.
    pub baud: u32,
}

/// What the lines have for the router task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineEvent {
    /// `n` bytes read, in [`Lines::read`].
    Read(LineId, usize),
    /// The line failed or its peer closed it; it is gone.
    Closed(LineId),
}

/// Bytes a line may have waiting to be written before more are dropped:
/// a peer that does not read cannot grow the daemon's memory.
pub const MAX_PENDING: usize = 64 * 1024;

/// A write the line could not take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// More than [`MAX_PENDING`] bytes already wait.
    Behind,
    /// No such line open.
    Closed,
}

/// The lines that may have bytes to read, in the order they were
/// signalled: each line's reads register a waker of its own, which notes
/// the line here and wakes the router task, so that a turn polls the lines
/// signalled since, not every open line (ARCHITECTURE "Scale").
#[derive(Debug, Default)]
struct Ready {
    queue: Mutex<ReadyQueue>,
}

#[derive(Debug, Default)]
struct ReadyQueue {
    lines: VecDeque<LineId>,
    /// The router task's waker, taken by the first line signalled.
    task: Option<Waker>,
}

impl Ready {
    fn lock(&self) -> std::sync::MutexGuard<'_, ReadyQueue> {
        self.queue.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// One line's waker: queues the line once until it is polled again.
#[derive(Debug)]
struct LineWake {
    id: LineId,
    queued: AtomicBool,
    ready: Arc<Ready>,
}

impl LineWake {
    /// Queues the line unless it is queued; the router task's waker if
    /// it is to be woken (`wake`).
    fn queue(&self, wake: bool) -> Option<Waker> {
        if self.queued.swap(true, Ordering::AcqRel) {
            return None;
        }
        let mut queue = self.ready.lock();
        queue.lines.push_back(self.id);
        if wake { queue.task.take() } else { None }
    }
}

impl Wake for LineWake {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        if let Some(task) = self.queue(true) {
            task.wake();
        }
    }
}

/// An open line.
#[derive(Debug)]
struct Line {
    stream: Box<dyn LineStream>,
    /// What the stream wakes when it has bytes (module doc of [`Ready`]).
    wake: Arc<LineWake>,
    waker: Waker,
    tap: Tap,
    /// Written bytes not yet taken by the stream; its capacity is kept.
    pending: Vec<u8>,
    rate: Rate,
    /// An accepted connection's entry in the admission table, touched on reads.
    admission: Option<(Arc<Connections>, u64)>,
    owner: Option<oneshot::Sender<Ended>>,
}

impl Line {
    /// Tells the task that opened the line how it ended (once).
    fn tell_owner(&mut self, reason: String) {
        if let Some(owner) = self.owner.take() {
            let _ = owner.send(Ended {
                reason,
                baud: self.rate.baud,
            });
        }
    }

    /// Reads into `buf` if the line has bytes or ended: the byte count, or
    /// why it ended; `None` while it has nothing (the task is woken then).
    fn poll_read(&mut self, buf: &mut [u8]) -> Option<Result<usize, String>> {
        let mut read = ReadBuf::new(buf);
        let cx = &mut Context::from_waker(&self.waker);
        match Pin::new(&mut self.stream).poll_read(cx, &mut read) {
            Poll::Pending => None,
            Poll::Ready(Ok(())) if read.filled().is_empty() => Some(Err("closed by peer".to_owned())),
            Poll::Ready(Ok(())) => {
                let n = read.filled().len();
                self.tap.inbound(&buf[..n]);
                if let Some((table, key)) = &self.admission {
                    table.touch(*key, Instant::now());
                }
                Some(Ok(n))
            }
            Poll::Ready(Err(e)) => Some(Err(format!("read failed: {e}"))),
        }
    }

    /// Writes what is pending until done or the stream would block (the
    /// line is signalled when it can take more: every wake of a line, read
    /// or write, is its own, which a TLS stream's reads inside a write
    /// need).
    fn flush(&mut self) -> Result<(), String> {
        let Self {
            stream,
            waker,
            pending,
            tap,
            ..
        } = self;
        let cx = &mut Context::from_waker(waker);
        let mut written = 0;
        let result = loop {
            if written == pending.len() {
                break Ok(());
            }
            match Pin::new(&mut *stream).poll_write(cx, &pending[written..]) {
                Poll::Ready(Ok(0)) => break Err("write failed: the line takes no more bytes".to_owned()),
                Poll::Ready(Ok(n)) => {
                    tap.outbound(&pending[written..written + n]);
                    written += n;
                }
                Poll::Ready(Err(e)) => break Err(format!("write failed: {e}")),
                Poll::Pending => break Ok(()),
            }
        };
        pending.drain(..written);
        result
    }
}

/// Every open port and link.
#[derive(Debug)]
pub struct Lines {
    open: BTreeMap<LineId, Line>,
    /// Where reads land; handed to the router core as they are.
    buf: Box<[u8; 4096]>,
    /// The lines signalled, polled in turn.
    ready: Arc<Ready>,
    /// The lines with bytes pending, in the order they were queued: the
    /// writes of one turn leave in the order the router core asked for
    /// them (a device's result goes to its client before the device's ACK
    /// of it), and a flush looks at these lines only, not at every port.
    /// An entry of a line closed or replaced since is dropped by the next
    /// flush (a replacement's own write may queue its id twice: the second
    /// finds nothing left to write).
    queued: Vec<LineId>,
    /// Lines closed for a failed write or rate switch, not yet reported.
    failed: Vec<LineId>,
    /// Lines holding a lone ACK ([`LineStream::holds_lone_ack`]), with the
    /// time it must go by: it goes first with the line's next write, or
    /// alone at that time.
    held_acks: Vec<(LineId, Instant)>,
}

impl Lines {
    pub fn new() -> Self {
        Self {
            open: BTreeMap::new(),
            buf: Box::new([0; 4096]),
            ready: Arc::default(),
            queued: Vec::new(),
            failed: Vec::new(),
            held_acks: Vec::new(),
        }
    }

    /// Takes a freshly opened line; a line of that id still open is closed
    /// (its owner told so).
    pub fn add(
        &mut self,
        id: LineId,
        stream: Box<dyn LineStream>,
        tap: Tap,
        rate: Rate,
        admission: Option<(Arc<Connections>, u64)>,
        owner: oneshot::Sender<Ended>,
    ) {
        let wake = Arc::new(LineWake {
            id,
            queued: AtomicBool::new(false),
            ready: self.ready.clone(),
        });
        // Polled at the next turn, which registers its waker.
        let _ = wake.queue(false);
        let line = Line {
            stream,
            waker: Waker::from(wake.clone()),
            wake,
            tap,
            pending: Vec::new(),
            rate,
            admission,
            owner: Some(owner),
        };
        if let Some(mut old) = self.open.insert(id, line) {
            old.tell_owner("replaced by a new connection".to_owned());
        }
        self.held_acks.retain(|(held, _)| *held != id);
    }

    /// Closes a line, telling its owner `reason`; whether it was open.
    pub fn close(&mut self, id: LineId, reason: &str) -> bool {
        self.held_acks.retain(|(held, _)| *held != id);
        self.open
            .remove(&id)
            .map(|mut line| line.tell_owner(reason.to_owned()))
            .is_some()
    }

    /// Queues `bytes` for the line; [`Lines::flush`] writes them. A lone
    /// ACK to a line that holds one waits for the line's next write, which
    /// it goes in front of, for [`ACK_HOLD`] at most.
    pub fn write(&mut self, id: LineId, bytes: &[u8]) -> Result<(), Refused> {
        let line = self.open.get_mut(&id).ok_or(Refused::Closed)?;
        if line.pending.len() + bytes.len() > MAX_PENDING {
            return Err(Refused::Behind);
        }
        let held = self.held_acks.iter().position(|(held, _)| *held == id);
        if bytes == [ACK] && held.is_none() && line.pending.is_empty() && line.stream.holds_lone_ack() {
            self.held_acks.push((id, Instant::now() + ACK_HOLD));
            return Ok(());
        }
        if line.pending.is_empty() {
            self.queued.push(id);
        }
        if let Some(at) = held {
            self.held_acks.swap_remove(at);
            line.pending.push(ACK);
        }
        line.pending.extend_from_slice(bytes);
        Ok(())
    }

    /// When the first held ACK must go, for the router task's timer.
    pub fn next_held_ack(&self) -> Option<Instant> {
        self.held_acks.iter().map(|&(_, by)| by).min()
    }

    /// Queues the held ACKs due by `now` (every one with `None`).
    fn release_held_acks(&mut self, now: Option<Instant>) {
        let Self {
            open,
            queued,
            held_acks,
            ..
        } = self;
        held_acks.retain(|&(id, by)| {
            if now.is_some_and(|now| by > now) {
                return true;
            }
            if let Some(line) = open.get_mut(&id) {
                if line.pending.is_empty() {
                    queued.push(id);
                }
                line.pending.push(ACK);
            }
            false
        });
    }

    /// Switches a port's line rate at once (after an acknowledged `C0..C7`,
    /// Table 4: the device switched after its ACK), so what is still queued
    /// for the port goes out at the new rate. A line that cannot
    /// switch is lost, as a failed write is: closed (reported by
    /// [`Lines::poll_next`]) and reopened by its task at the rate it had.
    pub fn set_baud(&mut self, port: u8, baud: u32) -> Result<(), String> {
        let id = LineId::Port(port);
        let line = self.open.get_mut(&id).ok_or_else(|| "the port is closed".to_owned())?;
        if let Err(e) = line.rate.switch.set_baud(baud) {
            let reason = format!("cannot switch the line rate to {baud}: {e}");
            line.tell_owner(reason.clone());
            self.open.remove(&id);
            self.failed.push(id);
            return Err(reason);
        }
        line.rate.baud = baud;
        Ok(())
    }

    /// Writes every line's pending bytes as far as they go now (and the
    /// held ACKs now due), line after line in the order they were queued;
    /// a line whose write fails is
    /// closed (reported by [`Lines::poll_next`]). Whether nothing is left
    /// pending.
    pub fn flush(&mut self, cx: &mut Context<'_>) -> bool {
        self.wake_on_lines(cx);
        if !self.held_acks.is_empty() {
            self.release_held_acks(Some(Instant::now()));
        }
        let Self {
            open, queued, failed, ..
        } = self;
        queued.retain(|id| {
            let Some(line) = open.get_mut(id) else {
                return false; // closed since
            };
            match line.flush() {
                Ok(()) => !line.pending.is_empty(),
                Err(reason) => {
                    line.tell_owner(reason);
                    open.remove(id);
                    failed.push(*id);
                    false
                }
            }
        });
        queued.is_empty()
    }

    /// The lines' signals wake the task polling with `cx`.
    fn wake_on_lines(&self, cx: &Context<'_>) {
        let mut queue = self.ready.lock();
        if !queue.task.as_ref().is_some_and(|t| t.will_wake(cx.waker())) {
            queue.task = Some(cx.waker().clone());
        }
    }

    /// Writes what is pending, then the next read or closed line: the
    /// lines signalled since they were last polled, in the order they
    /// were signalled (a line read goes to the back, as it may have more).
    pub fn poll_next(&mut self, cx: &mut Context<'_>) -> Poll<LineEvent> {
        self.flush(cx);
        if let Some(id) = self.failed.pop() {
            return Poll::Ready(LineEvent::Closed(id));
        }
        let mut budget = self.ready.lock().lines.len();
        while budget > 0 {
            budget -= 1;
            let Some(id) = self.ready.lock().lines.pop_front() else {
                break;
            };
            let Some(line) = self.open.get_mut(&id) else {
                continue; // closed since
            };
            line.wake.queued.store(false, Ordering::Release);
            match line.poll_read(&mut self.buf[..]) {
                None => {}
                Some(Ok(n)) => {
                    let _ = line.wake.queue(false);
                    return Poll::Ready(LineEvent::Read(id, n));
                }
                Some(Err(reason)) => {
                    self.close(id, &reason);
                    return Poll::Ready(LineEvent::Closed(id));
                }
            }
        }
        Poll::Pending
    }

    /// The bytes of the last [`LineEvent::Read`].
    pub fn read(&self, n: usize) -> &[u8] {
        &self.buf[..n]
    }

    /// Resolves once every line has written what is pending, held ACKs
    /// too (shutdown).
    pub fn poll_drained(&mut self, cx: &mut Context<'_>) -> Poll<()> {
        self.release_held_acks(None);
        match self.flush(cx) {
            true => Poll::Ready(()),
            false => Poll::Pending,
        }
    }

    /// Lets go of every line (shutdown): their owners hear that the router
    /// let go.
    pub fn release(&mut self) {
        self.open.clear();
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use sagebrush_gcu::LinkId;
    use sagebrush_host::capture::{CaptureSwitch, Role};

    use super::*;

    /// Each write a line took: which line, and its bytes.
    type Log = Arc<Mutex<Vec<(LineId, Vec<u8>)>>>;

    /// A line that takes every write at once and logs it; a device
    /// server's (`holds`) holds a lone ACK.
    #[derive(Debug)]
    struct Recorder {
        id: LineId,
        log: Log,
        holds: bool,
    }

    impl AsyncRead for Recorder {
        fn poll_read(self: Pin<&mut Self>, _: &mut Context<'_>, _: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
            Poll::Pending
        }
    }

    impl AsyncWrite for Recorder {
        fn poll_write(self: Pin<&mut Self>, _: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
            self.log.lock().unwrap().push((self.id, buf.to_vec()));
            Poll::Ready(Ok(buf.len()))
        }
        fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
            Poll::Ready(Ok(()))
        }
        fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
            Poll::Ready(Ok(()))
        }
    }

    impl LineStream for Recorder {
        fn holds_lone_ack(&self) -> bool {
            self.holds
        }
    }

    /// Lines with a client link 7 and port 1 (a device server when `holds`).
    fn client_and_port(holds: bool) -> (Lines, Log) {
        let log = Log::default();
        let switch = CaptureSwitch::new();
        let mut lines = Lines::new();
        for id in [LineId::Port(1), LineId::Link(LinkId(7))] {
            let stream = Box::new(Recorder {
                id,
                log: log.clone(),
                holds: holds && id == LineId::Port(1),
            });
            lines.add(
                id,
                stream,
                switch.tap(id.to_string(), Role::Master),
                Rate::none(),
                None,
                oneshot::channel().0,
            );
        }
        (lines, log)
    }

    const CLIENT: LineId = LineId::Link(LinkId(7));
    const PORT: LineId = LineId::Port(1);

    fn flush(lines: &mut Lines) -> bool {
        lines.flush(&mut Context::from_waker(Waker::noop()))
    }

    #[test]
    fn a_turns_writes_leave_in_the_order_they_were_queued_whatever_the_lines() {
        let (mut lines, log) = client_and_port(false);
        // A device's result relayed to its client, then the device's ACK of it.
        lines.write(CLIENT, b"result").unwrap();
        lines.write(PORT, &[ACK]).unwrap();
        lines.write(CLIENT, b" more").unwrap();
        assert!(flush(&mut lines), "everything written");
        assert_eq!(
            *log.lock().unwrap(),
            [(CLIENT, b"result more".to_vec()), (PORT, vec![ACK])],
            "the client's line first, each line once"
        );
        assert!(flush(&mut lines));
        assert_eq!(log.lock().unwrap().len(), 2, "nothing left to write");
    }

    #[tokio::test(start_paused = true)]
    async fn a_device_servers_lone_ack_rides_with_its_next_write() {
        let (mut lines, log) = client_and_port(true);
        lines.write(CLIENT, b"result").unwrap();
        lines.write(PORT, &[ACK]).unwrap();
        assert!(flush(&mut lines));
        assert_eq!(*log.lock().unwrap(), [(CLIENT, b"result".to_vec())], "the ACK is held");
        let due = lines.next_held_ack().expect("a held ACK");
        assert_eq!(due, Instant::now() + ACK_HOLD);
        tokio::time::advance(ACK_HOLD / 2).await;
        assert!(flush(&mut lines));
        assert_eq!(log.lock().unwrap().len(), 1, "still held within ACK_HOLD");
        // The port's next command: the ACK goes first, in the same write.
        lines.write(PORT, b"P?").unwrap();
        assert!(flush(&mut lines));
        assert_eq!(log.lock().unwrap()[1], (PORT, [&[ACK][..], b"P?"].concat()));
        assert_eq!(lines.next_held_ack(), None);
        // A NAK (or anything but a lone ACK) is never held.
        lines.write(PORT, &[sagebrush_protocol::NAK]).unwrap();
        assert!(flush(&mut lines));
        assert_eq!(log.lock().unwrap()[2], (PORT, vec![sagebrush_protocol::NAK]));
    }

    #[tokio::test(start_paused = true)]
    async fn a_held_ack_goes_alone_once_its_hold_ran_out_or_the_lines_drain() {
        let (mut lines, log) = client_and_port(true);
        lines.write(PORT, &[ACK]).unwrap();
        tokio::time::advance(ACK_HOLD).await;
        assert!(flush(&mut lines));
        assert_eq!(*log.lock().unwrap(), [(PORT, vec![ACK])], "sent at ACK_HOLD");
        assert_eq!(lines.next_held_ack(), None);
        // At shutdown a held ACK goes at once.
        lines.write(PORT, &[ACK]).unwrap();
        let mut cx = Context::from_waker(Waker::noop());
        assert!(lines.poll_drained(&mut cx).is_ready());
        assert_eq!(log.lock().unwrap()[1], (PORT, vec![ACK]));
        // A line closed with its ACK held leaves nothing held.
        lines.write(PORT, &[ACK]).unwrap();
        lines.close(PORT, "test");
        assert_eq!(lines.next_held_ack(), None);
    }

    #[test]
    fn a_line_that_does_not_hold_writes_its_lone_ack_at_once() {
        let (mut lines, log) = client_and_port(false);
        lines.write(PORT, &[ACK]).unwrap();
        assert!(flush(&mut lines));
        assert_eq!(*log.lock().unwrap(), [(PORT, vec![ACK])]);
        assert_eq!(lines.next_held_ack(), None);
    }

    /// A switch that takes one rate and refuses the others.
    #[derive(Debug)]
    struct Takes(u32);

    impl LineRate for Takes {
        fn set_baud(&mut self, baud: u32) -> io::Result<()> {
            match baud == self.0 {
                true => Ok(()),
                false => Err(io::Error::other("refused")),
            }
        }
    }

    /// A port's rate goes through its switch: a switch taken is the rate
    /// the port's task reopens at; one refused closes the port, which its
    /// task reopens at the rate it had.
    #[test]
    fn a_ports_rate_goes_through_its_switch_and_a_refused_one_closes_it_at_the_rate_it_had() {
        let log = Log::default();
        let mut lines = Lines::new();
        let open = |lines: &mut Lines| {
            let (owner, ended) = oneshot::channel();
            let stream = Box::new(Recorder {
                id: PORT,
                log: log.clone(),
                holds: false,
            });
            let rate = Rate {
                baud: 9600,
                switch: Box::new(Takes(19_200)),
            };
            lines.add(
                PORT,
                stream,
                CaptureSwitch::new().tap("port 1".to_owned(), Role::Master),
                rate,
                None,
                owner,
            );
            ended
        };
        let mut ended = open(&mut lines);
        assert_eq!(lines.set_baud(1, 19_200), Ok(()));
        lines.close(PORT, "test");
        assert_eq!(
            ended.try_recv().expect("told").baud,
            19_200,
            "reopened at the rate switched to"
        );
        let mut ended = open(&mut lines);
        let refused = lines.set_baud(1, 38_400).expect_err("refused");
        assert!(refused.contains("38400") && refused.contains("refused"), "{refused}");
        let told = ended.try_recv().expect("told");
        assert_eq!((told.baud, told.reason), (9600, refused), "reopened at the rate it had");
        assert_eq!(
            lines.poll_next(&mut Context::from_waker(Waker::noop())),
            Poll::Ready(LineEvent::Closed(PORT)),
            "reported closed"
        );
    }
}
