//! One connection to a bus (as its master) or to gcud's client listener,
//! and the exchanges made over it, each outcome other than success turned
//! into a [`CommandError`] that says what happened (1.4.2, 1.4.3, and
//! ARCHITECTURE "Delivery contract" for gcud's delivery reports).

use sagebrush_host::timing;
use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{
    Address, Command, FrameBuf, MAX_PAYLOAD, Outcome, Position, Reply, ResultKind, ResultTimeout, TxFailure,
    Undelivered,
};
use tokio::io::{AsyncRead, AsyncWrite};

use crate::master::{Exchange, Master};

/// Why a command did not succeed, with a message naming the device, the
/// command and what happened.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// The line or connection failed.
    #[error("{0}")]
    Io(String),
    /// The command cannot be encoded or framed.
    #[error("{0}")]
    Usage(String),
    /// NAK on every transmission.
    #[error("{0}")]
    Nak(String),
    /// No ACK on any transmission.
    #[error("{0}")]
    NoAck(String),
    /// The device answered NIC.
    #[error("{0}")]
    Nic(String),
    /// Acknowledged, but no result in time.
    #[error("{0}")]
    NoResult(String),
    /// A result that is not the command's.
    #[error("{0}")]
    BadReply(String),
    /// A GCU reported that it could not deliver the command.
    #[error("{1}")]
    Undelivered(Undelivered, String),
    /// gcud refused the command by its rules (ARCHITECTURE "Front doors"):
    /// another link controls the gimbal, the target lies beyond a travel
    /// limit or in a keep-out zone, or where the gimbal is is not known.
    /// Nothing reached the bus; sending it again changes nothing until
    /// the rule's reason changes. A row whose [`Undelivered::is_refusal`] holds.
    #[error("{1}")]
    Refused(Undelivered, String),
}

impl CommandError {
    /// The rule gcud refused the command by, if it did.
    pub fn refusal(&self) -> Option<Undelivered> {
        match self {
            CommandError::Refused(rule, _) => Some(*rule),
            _ => None,
        }
    }
}

impl From<std::io::Error> for CommandError {
    fn from(e: std::io::Error) -> Self {
        CommandError::Io(e.to_string())
    }
}

/// The payload bytes of a command.
pub fn encode(command: &Command<'_>) -> Result<Vec<u8>, CommandError> {
    let mut buf = [0u8; MAX_PAYLOAD];
    command
        .encode(&mut buf)
        .map(<[u8]>::to_vec)
        .map_err(|e| CommandError::Usage(format!("cannot encode {}: {e}", command.mnemonic())))
}

/// A master on one stream, sending as `from` (the source group of 1.4.1).
#[derive(Debug)]
pub struct Client<S> {
    master: Master<S>,
    pub from: u8,
}

/// A client of gcud's client listener.
pub type GcudClient = Client<sagebrush_host::tls::Stream>;

impl GcudClient {
    /// Connects to gcud's client listener at `gcud` (plain TCP or TLS),
    /// with the TCP time-outs of a link (1.4.2 over TCP,
    /// `timing::tcp_policy`) changed by `tune`.
    pub async fn connect(
        gcud: &sagebrush_host::tls::Endpoint,
        from: u8,
        tune: impl FnOnce(&mut TransactionPolicy),
    ) -> Result<Self, CommandError> {
        let stream = gcud.connect().await?;
        let mut policy = timing::tcp_policy();
        tune(&mut policy);
        Ok(Self::new(stream, policy, from))
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin> Client<S> {
    pub fn new(stream: S, policy: TransactionPolicy, from: u8) -> Self {
        Self {
            master: Master::new(stream, policy),
            from,
        }
    }

    /// The exchange machinery itself (reading what arrives between exchanges).
    pub fn master_mut(&mut self) -> &mut Master<S> {
        &mut self.master
    }

    /// One exchange of `command`, whose payload is `payload` (its encoding,
    /// not read again), with `to`; every outcome but an ACK, a result or a
    /// broadcast is an error naming the device, the command and what happened.
    pub async fn exchange(
        &mut self,
        to: Address,
        command: &Command<'_>,
        payload: &[u8],
    ) -> Result<Exchange, CommandError> {
        let what = command_named(command);
        self.exchange_expecting(to, payload, command.result_kind(), &what).await
    }

    /// One exchange of `payload` with `to`, whose answer is `expect`;
    /// `what` names the command in errors.
    pub async fn exchange_expecting(
        &mut self,
        to: Address,
        payload: &[u8],
        expect: ResultKind,
        what: &str,
    ) -> Result<Exchange, CommandError> {
        let frame = FrameBuf::new(to, self.from, payload).map_err(|e| CommandError::Usage(format!("payload: {e}")))?;
        let ex = self.master.transact_expecting(&frame, expect).await?;
        judge(ex, to, expect, what, self.master.policy())
    }

    /// `first` then `second` to `to`, the second at the first's ACK where
    /// gcud allows ([`Master::transact_chained`]): each one's outcome, as
    /// [`Client::send`] gives it; the second's is `None` when it was not
    /// sent (the first failed, or `go_on` said no at its ACK).
    pub async fn send_chained(
        &mut self,
        to: Address,
        first: &Command<'_>,
        second: &Command<'_>,
        go_on: &(dyn Fn() -> bool + Sync),
    ) -> (Result<Exchange, CommandError>, Option<Result<Exchange, CommandError>>) {
        let framed = |c: &Command<'_>| -> Result<(FrameBuf, String), CommandError> {
            let payload = encode(c)?;
            let frame =
                FrameBuf::new(to, self.from, &payload).map_err(|e| CommandError::Usage(format!("payload: {e}")))?;
            Ok((frame, command_named(c)))
        };
        let ((a, a_what), (b, b_what)) = match (framed(first), framed(second)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => return (Err(e), None),
        };
        let (a_expect, b_expect) = (first.result_kind(), second.result_kind());
        match self
            .master
            .transact_chained((&a, a_expect), (&b, b_expect), go_on)
            .await
        {
            Ok((x, y)) => {
                let policy = *self.master.policy();
                let y = y.map(|y| judge(y, to, b_expect, &b_what, &policy));
                (judge(x, to, a_expect, &a_what, &policy), y)
            }
            Err(e) => (Err(e.into()), None),
        }
    }

    /// Sends `command` to `to`; done when it is acknowledged (or answered).
    pub async fn send(&mut self, to: Address, command: &Command<'_>) -> Result<Exchange, CommandError> {
        let payload = encode(command)?;
        self.exchange(to, command, &payload).await
    }

    /// A query: its result payload.
    pub async fn query(&mut self, to: Address, command: &Command<'_>) -> Result<Vec<u8>, CommandError> {
        let ex = self.send(to, command).await?;
        match ex.result {
            Some(frame) => Ok(frame.frame().payload().to_vec()),
            None => Err(CommandError::NoResult(format!(
                "{to} sent no result for {}",
                command.in_words()
            ))),
        }
    }

    /// A query whose answer is a Table 15 position (`P?`, `P?nn`, `S?nn`).
    pub async fn query_position(&mut self, to: Address, command: &Command<'_>) -> Result<Position, CommandError> {
        let payload = self.query(to, command).await?;
        expect_position(command, &payload)
    }

    /// Where the gimbal at `to` points now (`P?`).
    pub async fn position(&mut self, to: Address) -> Result<Position, CommandError> {
        self.query_position(to, &Command::QueryPosition).await
    }
}

/// What an exchange of `what` (expecting `expect`) with `to` means to its
/// sender: every outcome but an ACK, a result or a broadcast is an error
/// naming the device, the command and what happened.
fn judge(
    ex: Exchange,
    to: Address,
    expect: ResultKind,
    what: &str,
    policy: &TransactionPolicy,
) -> Result<Exchange, CommandError> {
    if let Some(report) = ex.undelivered {
        let failure = report.failure.unwrap_or(Undelivered::NotConfirmed);
        if failure.is_refusal() {
            return Err(CommandError::Refused(
                failure,
                format!("refused by gcud: {what} for {to}: {}", failure.describe()),
            ));
        }
        return Err(CommandError::Undelivered(
            failure,
            format!(
                "not delivered: {what} for {to}: {} (reported by GCU {})",
                failure.describe(),
                report.at_group
            ),
        ));
    }
    match ex.outcome {
        Outcome::Acknowledged | Outcome::Broadcast | Outcome::Result => Ok(ex),
        Outcome::Nic => Err(CommandError::Nic(format!(
            "NIC: {to} does not implement or cannot apply {what}"
        ))),
        Outcome::NoResult if expect == ResultKind::None => Err(CommandError::NoResult(format!(
            "{to} acknowledged {what}, but whether a NIC followed was not confirmed (a `?` on the bus gcud could not attribute)"
        ))),
        Outcome::NoResult => Err(CommandError::NoResult(format!(
            "{to} acknowledged {what} but sent no result within {} ms",
            if expect == ResultKind::Required(ResultTimeout::Long) {
                policy.long_result_timeout
            } else {
                policy.result_timeout
            }
        ))),
        Outcome::Failed(TxFailure::Nak) => Err(CommandError::Nak(format!(
            "{to} answered NAK to {what} on all {} transmissions: the frame keeps arriving damaged (line noise? wrong --baud?)",
            ex.transmissions
        ))),
        Outcome::Failed(TxFailure::NoAck) => Err(CommandError::NoAck(format!(
            "no ACK from {to} for {what} after {} transmissions ({} ms each): check the address, the cabling and --baud",
            ex.transmissions, policy.retry.ack_timeout
        ))),
    }
}

/// How an error names a command: in words, its arguments in their units
/// (`go to pan 115.00° tilt 0.00°`, `pan speed 8 of 15`: the protocol
/// crate's [`Command::in_words`]), never a payload to decode.
fn command_named(command: &Command<'_>) -> String {
    command.in_words().to_string()
}

/// `payload`, the result of `command`, as a Table 15 position.
pub fn expect_position(command: &Command<'_>, payload: &[u8]) -> Result<Position, CommandError> {
    match Reply::parse(command, payload) {
        Ok(Reply::Position(p)) => Ok(p),
        _ => Err(CommandError::BadReply(format!(
            "{} result {:?} is not a Table 15 position",
            command.mnemonic(),
            String::from_utf8_lossy(payload)
        ))),
    }
}
