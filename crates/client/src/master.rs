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
    TransactionStep, TxFailure,
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

    /// Whether a report `00` about the exchange `tx` ends it: gcud agreed
    /// to send it at the end of its port's NIC window, the ACK came, and
    /// no result is required (1.4.2; an optional one did not come).
    fn window_ended(&self, tx: &Transaction, expect: ResultKind) -> bool {
        self.window_reports
            && tx.acknowledged()
            && tx.outcome().is_none()
            && !tx.is_broadcast()
            && !matches!(expect, ResultKind::Required(_))
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
        let started = Instant::now();
        let mut stale = 0;
        while stale < STALE_EVENTS_CAP {
            match self.framed.next().now_or_never() {
                Some(Some(Ok(event))) => {
                    debug!(?event, "event before the command discarded");
                    stale += 1;
                }
                Some(Some(Err(e))) => return Err(e),
                Some(None) | None => break,
            }
        }
        let noise_at_start = self.noise_bytes();
        let mut tx = Transaction::expecting(frame.frame().dest, expect, self.policy);
        let mut result = None;
        let mut undelivered = None;
        let (mut naks_received, mut naks_sent, mut stray_frames) = (0u32, 0u32, 0u32);
        let mut step = tx.start(self.now());
        let outcome = loop {
            match step {
                TransactionStep::Done(outcome) => break outcome,
                TransactionStep::Send => {
                    if tx.transmissions() > 1 {
                        info!(transmission = tx.transmissions(), dest = %frame.frame().dest, "retransmitting");
                    }
                    self.write(Write::Frame(frame)).await?;
                    step = tx.poll(self.now());
                    continue;
                }
                TransactionStep::Wait => {}
            }
            let deadline = tx.deadline().map(|d| self.instant(d));
            let Some(event) = self.next_event(deadline).await? else {
                step = tx.poll(self.now());
                continue;
            };
            let now = self.now();
            step = match event {
                OwnedEvent::Frame(f) => {
                    // Every intact frame is acknowledged, hop by hop.
                    self.write(Write::Ack).await?;
                    match report_about(frame, &f) {
                        Some(report) if report.failure.is_some() && !tx.acknowledged() => {
                            warn!(dest = %frame.frame().dest, ?report, "not delivered");
                            undelivered = Some(report);
                            step = TransactionStep::Done(Outcome::Failed(TxFailure::NoAck));
                            continue;
                        }
                        Some(report) if report.failure.is_none() && self.window_ended(&tx, expect) => {
                            debug!(dest = %frame.frame().dest, "gcud's NIC window passed");
                            step = TransactionStep::Done(Outcome::Acknowledged);
                            continue;
                        }
                        _ => {}
                    }
                    let s = tx.on_event(&Event::Frame(f.frame()), now);
                    if s == TransactionStep::Done(Outcome::Result) {
                        result = Some(f);
                    } else {
                        stray_frames += 1;
                        debug!(dest = %f.frame().dest, "frame that is not our result ignored");
                    }
                    s
                }
                OwnedEvent::BadChecksum(bad) => {
                    if tx.is_result_header(&bad.dest) {
                        warn!(dest = %bad.dest, "damaged result: NAK");
                        naks_sent += 1;
                        self.write(Write::Nak).await?;
                    }
                    TransactionStep::Wait
                }
                OwnedEvent::Ack => tx.on_event(&Event::Ack, now),
                OwnedEvent::Nak => {
                    naks_received += 1;
                    tx.on_event(&Event::Nak, now)
                }
                OwnedEvent::Nic => tx.on_event(&Event::Nic, now),
            };
            if step == TransactionStep::Send {
                info!(transmission = tx.transmissions(), "NAK received: retransmitting");
                self.write(Write::Frame(frame)).await?;
                step = tx.poll(self.now());
            }
        };
        Ok(Exchange {
            outcome,
            result,
            transmissions: tx.transmissions(),
            naks_received,
            naks_sent,
            noise_bytes: self.noise_bytes() - noise_at_start,
            stray_frames,
            undelivered,
            elapsed: started.elapsed(),
        })
    }
}
