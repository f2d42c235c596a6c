//! The master side of command exchanges (1.4.2, 1.4.3, Figure 6) over any
//! async byte stream: a bus master on a serial line, or a client of a GCU
//! over TCP. It drives the protocol crate's [`Transaction`] with a real
//! clock, acknowledges every intact frame and NAKs damaged results (hop by
//! hop), so that a device can resend. Through a GCU, the ACK means the
//! device acknowledged the command, and a delivery report comes instead
//! when it was not delivered (ARCHITECTURE "Delivery contract"): the
//! exchange ends with that report at once. On a connection that asked gcud
//! for end-of-window reports (`~W`, [`Master::set_window_reports`]), the
//! report `00` after the ACK ends the wait for a NIC (1.4.2) that gcud's
//! port already waited; its own window still bounds the wait otherwise.

use std::io;
use std::time::Duration;

use futures_util::{FutureExt, SinkExt, StreamExt};
use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{
    CONTROL_UNIT, Command, DeliveryReport, Event, FrameBuf, LINK_PORT, Outcome, OwnedEvent, ResultKind, Transaction,
    TransactionStep, TxFailure, WILDCARD,
};
use tokio::io::{AsyncRead, AsyncWrite};
use tokio_util::codec::Framed;

use crate::codec::{FrameCodec, Write};
use tokio::time::Instant;
use tracing::{debug, info, warn};

/// How one exchange went.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Exchange {
    pub outcome: Outcome,
    /// The result frame, when the outcome is [`Outcome::Result`].
    pub result: Option<FrameBuf>,
    /// Transmissions of the command, the first included.
    pub transmissions: u8,
    /// NAKs received for the command.
    pub naks_received: u32,
    /// Damaged result frames we NAKed.
    pub naks_sent: u32,
    /// Bytes that were no event (noise) during the exchange.
    pub noise_bytes: u64,
    /// Frames that were not our result (another device, a late answer).
    pub stray_frames: u32,
    /// A GCU's report that the command was not delivered (the outcome is
    /// then [`Outcome::Failed`] with [`TxFailure::NoAck`]: no ACK came).
    pub undelivered: Option<DeliveryReport>,
    pub elapsed: Duration,
}

/// A GCU's delivery report about `frame`, if `candidate` is one.
fn report_about(frame: &FrameBuf, candidate: &FrameBuf) -> Option<DeliveryReport> {
    let (command, got) = (frame.frame(), candidate.frame());
    let addressed = got.dest.group == command.source && got.dest.port == LINK_PORT && got.dest.device == CONTROL_UNIT;
    let report = DeliveryReport::parse(got.payload()).ok().filter(|_| addressed)?;
    (report.dest == command.dest && report.command_checksum == command.checksum()).then_some(report)
}

/// Whether `candidate`'s groups are those of `command`'s result (Table 3:
/// destination group = the command's source group, source group = the
/// group it went to; any for group 255). The [`Transaction`] checks port
/// and device only, as a bus master may; through a GCU, another group's
/// result for the same port and device (a late or repeated one) is not ours.
fn from_addressee(command: &FrameBuf, candidate: &FrameBuf) -> bool {
    let (command, got) = (command.frame(), candidate.frame());
    got.dest.group == command.source && (command.dest.group == WILDCARD || got.source == command.dest.group)
}

/// A master on one stream, read as framer events ([`FrameCodec`]): none is
/// lost between reads or exchanges.
#[derive(Debug)]
pub struct Master<S> {
    framed: Framed<S, FrameCodec>,
    epoch: Instant,
    policy: TransactionPolicy,
    /// gcud agreed to report the end of each NIC window on this stream.
    window_reports: bool,
}

/// Events already waiting when an exchange starts are discarded (they
/// arrived before its command, so they cannot answer it); at most this many.
const STALE_EVENTS_CAP: usize = 1024;

impl<S: AsyncRead + AsyncWrite + Unpin> Master<S> {
    pub fn new(stream: S, policy: TransactionPolicy) -> Self {
        Self {
            framed: Framed::new(stream, FrameCodec::new()),
            epoch: Instant::now(),
            policy,
            window_reports: false,
        }
    }

    /// gcud answered `~W`: a report `00` about a command after its ACK
    /// says gcud's port waited the NIC window and no NIC came.
    pub fn set_window_reports(&mut self, on: bool) {
        self.window_reports = on;
    }

    /// Whether gcud reports the end of each NIC window on this stream.
    pub fn window_reports(&self) -> bool {
        self.window_reports
    }

    pub fn policy(&self) -> &TransactionPolicy {
        &self.policy
    }

    /// The time-outs and retries of the exchanges from now on.
    pub fn policy_mut(&mut self) -> &mut TransactionPolicy {
        &mut self.policy
    }

    /// The stream itself (bytes already read into events are not in it).
    pub fn stream_mut(&mut self) -> &mut S {
        self.framed.get_mut()
    }

    fn now(&self) -> u64 {
        self.epoch.elapsed().as_millis() as u64
    }

    fn instant(&self, tick: u64) -> Instant {
        self.epoch + Duration::from_millis(tick)
    }

    /// Writes and flushes.
    pub async fn write(&mut self, what: Write<'_>) -> io::Result<()> {
        self.framed.send(what).await
    }

    /// The next event, or `None` once `deadline` passed; the end of the
    /// stream is an error.
    pub async fn next_event(&mut self, deadline: Option<Instant>) -> io::Result<Option<OwnedEvent>> {
        let next = match deadline {
            Some(at) => match tokio::time::timeout_at(at, self.framed.next()).await {
                Ok(next) => next,
                Err(_) => return Ok(None),
            },
            None => self.framed.next().await,
        };
        match next {
            Some(event) => event.map(Some),
            None => Err(io::Error::new(io::ErrorKind::UnexpectedEof, self.closed_why())),
        }
    }

    /// Why the exchange ended with the line: bytes that were no frames
    /// before the close mean another kind of server listens there (gcud's
    /// metrics listener answers HTTP, for one).
    fn closed_why(&self) -> String {
        match self.noise_bytes() {
            0 => "the line closed during the exchange".to_owned(),
            n => format!(
                "the line closed during the exchange, after {n} bytes that were no Sagebrush frames: \
                 not a gcud client listener or a gimbal bus (gcud's metrics listener, for one, speaks HTTP)"
            ),
        }
    }

    /// Noise bytes skipped so far.
    pub fn noise_bytes(&self) -> u64 {
        self.framed.codec().framer().skipped_bytes()
    }

    /// Sends `frame` (whose payload is `command`) and waits for the end of
    /// the exchange. I/O errors (a closed link) are errors; every protocol
    /// outcome, failures included, is an [`Exchange`].
    pub async fn transact(&mut self, frame: &FrameBuf, command: &Command<'_>) -> io::Result<Exchange> {
        self.transact_expecting(frame, command.result_kind()).await
    }

    /// [`Master::transact`] of a frame whose answer is `expect` (a GCU
    /// command of port 0, which no row of the command tables describes).
    pub async fn transact_expecting(&mut self, frame: &FrameBuf, expect: ResultKind) -> io::Result<Exchange> {
        let mut open = self.begin(frame, expect).await?;
        self.drive(&mut open, false).await?;
        Ok(self.ended(open))
    }

    /// Whether `second` may follow `first` (a command with no result) at
    /// its ACK, before its NIC window ends: gcud reports the end of that
    /// window on this stream, and both go to the same one device. gcud
    /// then relays the first command's `?` or writes its report `00` before
    /// the second command's ACK (ARCHITECTURE "End of the NIC window"), so
    /// nothing said about one can be taken for the other.
    pub fn may_chain(&self, first: &FrameBuf, first_expect: ResultKind, second: &FrameBuf) -> bool {
        let (a, b) = (first.frame(), second.frame());
        self.window_reports
            && first_expect == ResultKind::None
            && a.dest == b.dest
            && ![a.dest.group, a.dest.port, a.dest.device].contains(&WILDCARD)
            && a.dest.port != LINK_PORT
            && first.as_bytes() != second.as_bytes()
    }

    /// `first`, then `second` at `first`'s ACK, not after its NIC window
    /// (when [`Master::may_chain`]; one after the other otherwise), each
    /// with the answer it expects: what came of each. `second` is not sent
    /// when `first` did not end well before it (refused, not delivered, a
    /// NIC), or when `go_on` says no at `first`'s ACK (a stop came meanwhile
    /// and goes first): `None`.
    pub async fn transact_chained(
        &mut self,
        (first, first_expect): (&FrameBuf, ResultKind),
        (second, second_expect): (&FrameBuf, ResultKind),
        go_on: &(dyn Fn() -> bool + Sync),
    ) -> io::Result<(Exchange, Option<Exchange>)> {
        let chained = self.may_chain(first, first_expect, second);
        let mut a = self.begin(first, first_expect).await?;
        self.drive(&mut a, chained).await?;
        if a.step == TransactionStep::Wait && !go_on() {
            self.drive(&mut a, false).await?;
        }
        if !matches!(a.step, TransactionStep::Wait) {
            let done = matches!(
                a.step,
                TransactionStep::Done(Outcome::Acknowledged | Outcome::Result | Outcome::Broadcast)
            );
            let a = self.ended(a);
            if !done || !go_on() {
                return Ok((a, None));
            }
            let b = self.transact_expecting(second, second_expect).await?;
            return Ok((a, Some(b)));
        }
        // In its window: the second goes now, and each event is the
        // first's or the second's by the order gcud keeps.
        let mut b = self.send_first(second, second_expect).await?;
        while a.is_open() || b.is_open() {
            let deadline = [a.deadline(), b.deadline()].into_iter().flatten().min();
            let event = self.next_event(deadline.map(|d| self.instant(d))).await?;
            let now = self.now();
            let Some(event) = event else {
                if a.is_open() {
                    a.step = a.tx.poll(now);
                }
                if b.is_open() {
                    b.step = b.tx.poll(now);
                    self.resend(&mut b).await?;
                }
                continue;
            };
            if !a.is_open() {
                self.on_event(&mut b, event).await?;
                continue;
            }
            match event {
                OwnedEvent::Frame(f) if report_about(first, &f).is_some_and(|r| r.failure.is_none()) => {
                    self.write(Write::Ack).await?;
                    debug!(dest = %first.frame().dest, "gcud's NIC window passed");
                    a.step = TransactionStep::Done(Outcome::Acknowledged);
                }
                // Before the second's ACK, a `?` is the first's (1.4.2: the
                // NIC follows its ACK; gcud relays in order).
                OwnedEvent::Nic if !b.tx.acknowledged() => a.step = a.tx.on_event(&Event::Nic, now),
                // The second ended without reaching the device (refused,
                // not delivered): the first's window runs on.
                event if !b.is_open() => self.on_event(&mut a, event).await?,
                event => {
                    self.on_event(&mut b, event).await?;
                    if b.tx.acknowledged() {
                        // gcud said nothing more of the first before the
                        // device answered the second: its port could not
                        // tell whose a `?` was (`port::pipeline`). Not confirmed.
                        a.step = TransactionStep::Done(Outcome::NoResult);
                    }
                }
            }
        }
        let (a, b) = (self.ended(a), self.ended(b));
        Ok((a, Some(b)))
    }

    /// Starts the exchange of `frame`: events already waiting are
    /// discarded (they came before the command, so they answer none of it)
    /// and the frame is written.
    async fn begin<'f>(&mut self, frame: &'f FrameBuf, expect: ResultKind) -> io::Result<Open<'f>> {
        let mut stale = 0;
        while stale < STALE_EVENTS_CAP {
            match self.framed.next().now_or_never() {
                Some(Some(Ok(event))) => {
                    match &event {
                        OwnedEvent::Frame(f) => {
                            let f = f.frame();
                            debug!(dest = %f.dest, source = f.source, "a frame before the command discarded");
                        }
                        OwnedEvent::BadChecksum(b) => {
                            debug!(dest = %b.dest, "a damaged frame before the command discarded");
                        }
                        OwnedEvent::Ack | OwnedEvent::Nak | OwnedEvent::Nic => {
                            debug!("a bare ACK, NAK or NIC before the command discarded");
                        }
                    }
                    stale += 1;
                }
                Some(Some(Err(e))) => return Err(e),
                Some(None) | None => break,
            }
        }
        self.send_first(frame, expect).await
    }

    /// Writes `frame` for the first time.
    async fn send_first<'f>(&mut self, frame: &'f FrameBuf, expect: ResultKind) -> io::Result<Open<'f>> {
        let mut tx = Transaction::expecting(frame.frame().dest, expect, self.policy);
        let step = tx.start(self.now());
        let mut open = Open {
            frame,
            expect,
            tx,
            step,
            result: None,
            undelivered: None,
            naks_received: 0,
            naks_sent: 0,
            stray_frames: 0,
            noise_at_start: self.noise_bytes(),
            started: Instant::now(),
        };
        self.resend(&mut open).await?;
        Ok(open)
    }

    /// Writes the frame when the exchange says so.
    async fn resend(&mut self, open: &mut Open<'_>) -> io::Result<()> {
        if open.step == TransactionStep::Send {
            if open.tx.transmissions() > 1 {
                info!(transmission = open.tx.transmissions(), dest = %open.frame.frame().dest, "retransmitting");
            }
            self.write(Write::Frame(open.frame)).await?;
            open.step = open.tx.poll(self.now());
        }
        Ok(())
    }

    /// Runs `open` until it is done or, with `until_window`, in the NIC
    /// window after its ACK (its step then [`TransactionStep::Wait`]).
    async fn drive(&mut self, open: &mut Open<'_>, until_window: bool) -> io::Result<()> {
        loop {
            if matches!(open.step, TransactionStep::Done(_)) {
                return Ok(());
            }
            if until_window && open.in_window() {
                return Ok(());
            }
            let deadline = open.deadline().map(|d| self.instant(d));
            match self.next_event(deadline).await? {
                Some(event) => self.on_event(open, event).await?,
                None => {
                    open.step = open.tx.poll(self.now());
                    self.resend(open).await?;
                }
            }
        }
    }

    /// One event for `open`: every intact frame acknowledged hop by hop, a
    /// damaged result NAKed, a delivery report taken (not delivered: done;
    /// `00` after the ACK: the window passed).
    async fn on_event(&mut self, open: &mut Open<'_>, event: OwnedEvent) -> io::Result<()> {
        let now = self.now();
        open.step = match event {
            OwnedEvent::Frame(f) => {
                self.write(Write::Ack).await?;
                match report_about(open.frame, &f) {
                    Some(report) if report.failure.is_some() && !open.tx.acknowledged() => {
                        // Its sender's to report (an error naming the
                        // command, `judge`): a held drive refused every
                        // 250 ms must not repeat here.
                        debug!(dest = %open.frame.frame().dest, "{report}");
                        open.undelivered = Some(report);
                        open.step = TransactionStep::Done(Outcome::Failed(TxFailure::NoAck));
                        return Ok(());
                    }
                    Some(report) if report.failure.is_none() && self.window_reports && open.in_window() => {
                        debug!(dest = %open.frame.frame().dest, "gcud's NIC window passed");
                        open.step = TransactionStep::Done(Outcome::Acknowledged);
                        return Ok(());
                    }
                    _ => {}
                }
                let s = match from_addressee(open.frame, &f) {
                    true => open.tx.on_event(&Event::Frame(f.frame()), now),
                    false => TransactionStep::Wait,
                };
                if s == TransactionStep::Done(Outcome::Result) {
                    open.result = Some(f);
                } else {
                    open.stray_frames += 1;
                    debug!(dest = %f.frame().dest, "frame that is not our result ignored");
                }
                s
            }
            OwnedEvent::BadChecksum(bad) => {
                if open.tx.is_result_header(&bad.dest) {
                    warn!(dest = %bad.dest, "damaged result: NAK");
                    open.naks_sent += 1;
                    self.write(Write::Nak).await?;
                }
                TransactionStep::Wait
            }
            OwnedEvent::Ack => open.tx.on_event(&Event::Ack, now),
            OwnedEvent::Nak => {
                open.naks_received += 1;
                let s = open.tx.on_event(&Event::Nak, now);
                if s == TransactionStep::Send {
                    info!(
                        transmission = open.tx.transmissions() + 1,
                        "NAK received: retransmitting"
                    );
                }
                s
            }
            OwnedEvent::Nic => open.tx.on_event(&Event::Nic, now),
        };
        self.resend(open).await
    }

    /// What came of `open`, which is done.
    fn ended(&self, open: Open<'_>) -> Exchange {
        let outcome = match open.step {
            TransactionStep::Done(outcome) => outcome,
            _ => Outcome::NoResult,
        };
        Exchange {
            outcome,
            result: open.result,
            transmissions: open.tx.transmissions(),
            naks_received: open.naks_received,
            naks_sent: open.naks_sent,
            noise_bytes: self.noise_bytes() - open.noise_at_start,
            stray_frames: open.stray_frames,
            undelivered: open.undelivered,
            elapsed: open.started.elapsed(),
        }
    }
}

/// An exchange under way on a [`Master`].
struct Open<'f> {
    frame: &'f FrameBuf,
    expect: ResultKind,
    tx: Transaction,
    step: TransactionStep,
    result: Option<FrameBuf>,
    undelivered: Option<DeliveryReport>,
    naks_received: u32,
    naks_sent: u32,
    stray_frames: u32,
    noise_at_start: u64,
    started: Instant,
}

impl Open<'_> {
    /// Acknowledged, no result required (1.4.2; an optional one has not
    /// come): waiting only for a NIC, or for gcud's report `00`.
    fn in_window(&self) -> bool {
        self.tx.acknowledged()
            && self.tx.outcome().is_none()
            && !self.tx.is_broadcast()
            && !matches!(self.expect, ResultKind::Required(_))
    }

    fn is_open(&self) -> bool {
        !matches!(self.step, TransactionStep::Done(_))
    }

    fn deadline(&self) -> Option<u64> {
        self.tx.deadline().filter(|_| self.is_open())
    }
}
