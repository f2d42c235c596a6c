//! The sender side of a link as sans-IO state machines (1.4.2, 1.4.3,
//! Figure 6). Time is a tick count the caller passes in (milliseconds on
//! the host; whatever the firmware's timer counts), never read here.
//!
//! - [`Transmitter`]: send, await ACK/NAK, retransmit on NAK or time-out up
//!   to a count, then delivered or failed.
//! - [`Transaction`]: a whole command exchange: the transmitter, then the
//!   result frame or NIC the command calls for, or the broadcast guard time
//!   for device 255.
//!
//! The caller owns the frame bytes (a [`crate::FrameBuf`]) and writes them
//! whenever a step says `Send`. It also acknowledges received frames itself
//! (hop by hop): ACK a result frame, NAK a [`crate::Event::BadChecksum`].

use crate::address::{Address, WILDCARD};
use crate::command::{Command, ResultKind, ResultTimeout};
use crate::framer::Event;

/// Retransmission policy (1.4.2: no ACK or NAK within a time-out -> retransmit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RetryPolicy {
    /// Ticks to wait for ACK/NAK after a transmission.
    pub ack_timeout: u64,
    /// Retransmissions allowed after the first transmission.
    pub retries: u8,
}

/// What the caller of a [`Transmitter`] does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TxStep {
    /// Write the frame (again).
    Send,
    /// Nothing to do until an event or [`Transmitter::deadline`].
    Wait,
    /// ACK received.
    Delivered,
    /// Retries exhausted.
    Failed(TxFailure),
}

/// Why a transmission failed; the reason of the last attempt.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TxFailure {
    /// The last attempt was answered with NAK (bad checksum at the receiver).
    Nak,
    /// The last attempt got neither ACK nor NAK in time.
    NoAck,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TxState {
    Idle,
    AwaitAck { deadline: u64 },
    Done,
}

/// Send -> await ACK/NAK -> retransmit -> delivered / failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transmitter {
    policy: RetryPolicy,
    state: TxState,
    transmissions: u8,
}

impl Transmitter {
    /// An idle transmitter with this retry policy.
    pub const fn new(policy: RetryPolicy) -> Self {
        Self {
            policy,
            state: TxState::Idle,
            transmissions: 0,
        }
    }

    /// Begins: the caller writes the frame.
    pub fn start(&mut self, now: u64) -> TxStep {
        self.transmissions = 0;
        self.transmit(now)
    }

    fn transmit(&mut self, now: u64) -> TxStep {
        self.transmissions = self.transmissions.saturating_add(1);
        self.state = TxState::AwaitAck {
            deadline: now.saturating_add(self.policy.ack_timeout),
        };
        TxStep::Send
    }

    fn retry_or_fail(&mut self, now: u64, failure: TxFailure) -> TxStep {
        if self.transmissions <= self.policy.retries {
            self.transmit(now)
        } else {
            self.state = TxState::Done;
            TxStep::Failed(failure)
        }
    }

    /// An ACK arrived.
    pub fn on_ack(&mut self) -> TxStep {
        match self.state {
            TxState::AwaitAck { .. } => {
                self.state = TxState::Done;
                TxStep::Delivered
            }
            _ => TxStep::Wait,
        }
    }

    /// A NAK arrived: retransmit while retries remain.
    pub fn on_nak(&mut self, now: u64) -> TxStep {
        match self.state {
            TxState::AwaitAck { .. } => self.retry_or_fail(now, TxFailure::Nak),
            _ => TxStep::Wait,
        }
    }

    /// Time passed: retransmit or fail once the ACK time-out has run out.
    pub fn poll(&mut self, now: u64) -> TxStep {
        match self.state {
            TxState::AwaitAck { deadline } if now >= deadline => self.retry_or_fail(now, TxFailure::NoAck),
            _ => TxStep::Wait,
        }
    }

    /// When [`Transmitter::poll`] next has something to do.
    pub fn deadline(&self) -> Option<u64> {
        match self.state {
            TxState::AwaitAck { deadline } => Some(deadline),
            _ => None,
        }
    }

    /// Whether an ACK is awaited.
    pub fn awaiting_ack(&self) -> bool {
        matches!(self.state, TxState::AwaitAck { .. })
    }

    /// Transmissions so far, the first included.
    pub fn transmissions(&self) -> u8 {
        self.transmissions
    }
}

/// Time-outs of a whole exchange, in ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TransactionPolicy {
    /// ACK time-out and retransmissions of the command frame.
    pub retry: RetryPolicy,
    /// Wait for a result after the ACK (ordinary queries).
    pub result_timeout: u64,
    /// Wait for a result of the long class (`IX`).
    pub long_result_timeout: u64,
    /// After the ACK of a command without result: how long a NIC may follow.
    pub nic_window: u64,
    /// After a write to device 255: quiet time before the bus is used again.
    pub broadcast_guard: u64,
}

/// Bits on the wire per byte: start, 8 data, stop (1.5.1).
pub const BITS_PER_BYTE: u64 = 10;

/// Milliseconds `bytes` take on a line at `baud`, rounded up.
pub const fn wire_ms(bytes: usize, baud: u32) -> u64 {
    let baud = if baud == 0 { 1 } else { baud as u64 };
    (bytes as u64 * BITS_PER_BYTE * 1000).div_ceil(baud)
}

/// Silence (ms) after which a partial frame on a line at `baud` is
/// abandoned: eight byte times and 20 ms for a busy host to read.
pub const fn silence_ms(baud: u32) -> u64 {
    wire_ms(8, baud) + 20
}

impl TransactionPolicy {
    /// The default time-outs (ms) of an exchange on a serial line at
    /// `baud`, the one place they are derived ("if no ACK or NAK is
    /// received within a time-out period, the message should be
    /// re-transmitted", 1.4.2):
    /// - ACK: 50 ms turnaround and 16 byte times, counted from the
    ///   command's last byte ([`TransactionPolicy::for_frame`] adds the
    ///   frame's own wire time when the clock starts at the write);
    /// - result: a longest frame back plus 500 ms for the device to think;
    ///   `IX` (the long class): 60 s, both axes driven to their switches;
    /// - NIC window after an ACK: four byte times + 30 ms;
    /// - broadcast guard: a longest frame + 50 ms; 3 retries.
    pub const fn serial(baud: u32) -> Self {
        let longest = wire_ms(crate::MAX_FRAME_LEN, baud);
        Self {
            retry: RetryPolicy {
                ack_timeout: 50 + wire_ms(16, baud),
                retries: 3,
            },
            result_timeout: 500 + longest,
            long_result_timeout: 60_000,
            nic_window: 30 + wire_ms(4, baud),
            broadcast_guard: 50 + longest,
        }
    }

    /// This policy for a command frame of `len` bytes written at `baud`
    /// when the ACK clock starts at the write: the frame's own wire time is
    /// added to the ACK wait, so that a long frame on a slow line is not
    /// retransmitted while it is still going out.
    pub const fn for_frame(mut self, len: usize, baud: u32) -> Self {
        self.retry.ack_timeout += wire_ms(len, baud);
        self
    }
}

/// How an exchange ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    /// ACKed; no result was expected (or an optional one did not come).
    Acknowledged,
    /// The frame just given to [`Transaction::on_event`] is the result.
    Result,
    /// The device answered NIC: not implemented or not applicable.
    Nic,
    /// ACKed, but the required result did not arrive in time.
    NoResult,
    /// No ACK after all retries.
    Failed(TxFailure),
    /// Written once to device 255 (no ACK awaited) and the guard time passed.
    Broadcast,
}

/// What the caller of a [`Transaction`] does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TransactionStep {
    /// Write the command frame (again).
    Send,
    /// Nothing to do until an event or [`Transaction::deadline`].
    Wait,
    /// The exchange is over.
    Done(Outcome),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Idle,
    AwaitAck,
    AwaitResult { deadline: u64, required: bool },
    NicWindow { deadline: u64 },
    Guard { deadline: u64 },
    Done(Outcome),
}

/// One command exchange on a bus or link: write, ACK/NAK with
/// retransmission, then the result or NIC (Figure 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transaction {
    policy: TransactionPolicy,
    tx: Transmitter,
    dest: Address,
    expect: ResultKind,
    phase: Phase,
}

impl Transaction {
    /// An exchange of `command` with `dest`.
    pub fn new(dest: Address, command: &Command<'_>, policy: TransactionPolicy) -> Self {
        Self::expecting(dest, command.result_kind(), policy)
    }

    /// An exchange with `dest` of a command whose result kind is already
    /// known (a router that read the command once when it accepted it).
    pub fn expecting(dest: Address, expect: ResultKind, policy: TransactionPolicy) -> Self {
        Self {
            policy,
            tx: Transmitter::new(policy.retry),
            dest,
            expect,
            phase: Phase::Idle,
        }
    }

    /// Whether this exchange goes to every device of a bus (no ACK awaited).
    pub fn is_broadcast(&self) -> bool {
        self.dest.device == WILDCARD
    }

    /// Begins: the caller writes the frame.
    pub fn start(&mut self, now: u64) -> TransactionStep {
        if self.is_broadcast() {
            self.phase = Phase::Guard {
                deadline: now.saturating_add(self.policy.broadcast_guard),
            };
            return TransactionStep::Send;
        }
        self.phase = Phase::AwaitAck;
        let step = self.tx.start(now);
        self.advance(step, now)
    }

    fn finish(&mut self, outcome: Outcome) -> TransactionStep {
        self.phase = Phase::Done(outcome);
        TransactionStep::Done(outcome)
    }

    fn after_ack(&mut self, now: u64) -> TransactionStep {
        let p = self.policy;
        self.phase = match self.expect {
            ResultKind::None => Phase::NicWindow {
                deadline: now.saturating_add(p.nic_window),
            },
            ResultKind::Required(ResultTimeout::Normal) => Phase::AwaitResult {
                deadline: now.saturating_add(p.result_timeout),
                required: true,
            },
            ResultKind::Required(ResultTimeout::Long) => Phase::AwaitResult {
                deadline: now.saturating_add(p.long_result_timeout),
                required: true,
            },
            ResultKind::Optional => Phase::AwaitResult {
                deadline: now.saturating_add(p.result_timeout),
                required: false,
            },
        };
        TransactionStep::Wait
    }

    fn advance(&mut self, step: TxStep, now: u64) -> TransactionStep {
        match step {
            TxStep::Send => TransactionStep::Send,
            TxStep::Wait => TransactionStep::Wait,
            TxStep::Delivered => self.after_ack(now),
            TxStep::Failed(f) => self.finish(Outcome::Failed(f)),
        }
    }

    /// Whether `frame`'s header is that of this exchange's result (Table 3:
    /// port and device unchanged). A command sent to port 255 is answered
    /// from the device's own port (the endpoint fills in its own address for
    /// a wildcard, so that the answer says who answered).
    pub fn is_result_header(&self, dest: &Address) -> bool {
        (dest.port == self.dest.port || self.dest.port == WILDCARD) && dest.device == self.dest.device
    }

    /// An event from the framer of the line this exchange runs on.
    pub fn on_event(&mut self, event: &Event<'_>, now: u64) -> TransactionStep {
        match (self.phase, event) {
            (Phase::AwaitAck, Event::Ack) => {
                let step = self.tx.on_ack();
                self.advance(step, now)
            }
            (Phase::AwaitAck, Event::Nak) => {
                let step = self.tx.on_nak(now);
                self.advance(step, now)
            }
            // The ACK was lost but what follows it arrived: take both.
            (Phase::AwaitAck | Phase::AwaitResult { .. } | Phase::NicWindow { .. }, Event::Nic) => {
                self.finish(Outcome::Nic)
            }
            (Phase::AwaitAck | Phase::AwaitResult { .. }, Event::Frame(frame))
                if self.expect != ResultKind::None && self.is_result_header(&frame.dest) =>
            {
                self.finish(Outcome::Result)
            }
            _ => TransactionStep::Wait,
        }
    }

    /// Time passed.
    pub fn poll(&mut self, now: u64) -> TransactionStep {
        match self.phase {
            Phase::AwaitAck => {
                let step = self.tx.poll(now);
                self.advance(step, now)
            }
            Phase::AwaitResult { deadline, required } if now >= deadline => self.finish(if required {
                Outcome::NoResult
            } else {
                Outcome::Acknowledged
            }),
            Phase::NicWindow { deadline } if now >= deadline => self.finish(Outcome::Acknowledged),
            Phase::Guard { deadline } if now >= deadline => self.finish(Outcome::Broadcast),
            Phase::Done(outcome) => TransactionStep::Done(outcome),
            _ => TransactionStep::Wait,
        }
    }

    /// When [`Transaction::poll`] next has something to do.
    pub fn deadline(&self) -> Option<u64> {
        match self.phase {
            Phase::AwaitAck => self.tx.deadline(),
            Phase::AwaitResult { deadline, .. } | Phase::NicWindow { deadline } | Phase::Guard { deadline } => {
                Some(deadline)
            }
            Phase::Idle | Phase::Done(_) => None,
        }
    }

    /// The outcome, once done.
    pub fn outcome(&self) -> Option<Outcome> {
        match self.phase {
            Phase::Done(outcome) => Some(outcome),
            _ => None,
        }
    }

    /// Transmissions so far, the first included (retransmissions = this - 1).
    pub fn transmissions(&self) -> u8 {
        if self.is_broadcast() && self.phase != Phase::Idle {
            1
        } else {
            self.tx.transmissions()
        }
    }

    /// Whether the command was acknowledged and its result is awaited: a
    /// frame cut short now is that result damaged (1.4.2: NAK it, and the
    /// device sends it again).
    pub fn awaiting_result(&self) -> bool {
        matches!(self.phase, Phase::AwaitResult { .. })
    }

    /// Whether the ACK has been received (or was not awaited).
    pub fn acknowledged(&self) -> bool {
        !matches!(
            self.phase,
            Phase::Idle | Phase::AwaitAck | Phase::Done(Outcome::Failed(_))
        )
    }
}
