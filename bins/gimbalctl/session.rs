//! One connection to a bus (serial, as master) or a GCU (TCP, as client)
//! and the exchanges `gimbalctl` makes over it, with protocol failures
//! turned into [`CtlError`]s that say what happened.

use sagebrush_host::capture::{Capture, CaptureSwitch, Role, Tapped, capture_to};
use sagebrush_host::codec::Write;
use sagebrush_host::master::{Exchange, Master};
use sagebrush_host::timing;
use sagebrush_host::transport::{self, SerialOrTcp};
use std::time::Duration;

use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{Address, Command, FrameBuf, Outcome, OwnedEvent, TxFailure};

use crate::cli::Global;
use crate::error::CtlError;

/// A connection and the addressing of its commands.
#[derive(Debug)]
pub struct Session {
    master: Master<Tapped<SerialOrTcp>>,
    /// `--capture FILE`: stopped (the file completed) when the session ends.
    capture: Option<Capture>,
    pub to: Address,
    pub from: u8,
    /// What the line is (`tcp 127.0.0.1:4001`, `serial /dev/pts/3`).
    pub line: String,
    pub over_tcp: bool,
}

/// What came in after an exchange ended (`Session::linger`).
#[derive(Debug, Default)]
pub struct Lingered {
    pub frames: Vec<FrameBuf>,
    pub acks: u32,
    pub other_bytes: u32,
}

impl Session {
    /// Opens the transport the options name, with time-outs derived from
    /// the baud rate (serial) or the TCP defaults, then the overrides.
    pub async fn open(g: &Global, to: Address) -> Result<Self, CtlError> {
        Self::open_with(g, to, |_| {}).await
    }

    /// [`Session::open`], with `tune` applied to the default policy before
    /// the command line's overrides.
    pub async fn open_with(
        g: &Global,
        to: Address,
        tune: impl FnOnce(&mut TransactionPolicy),
    ) -> Result<Self, CtlError> {
        // A capture file that cannot be written is refused before anything is sent.
        let capture = match &g.capture {
            Some(path) => Some(
                capture_to(path, "gimbalctl")
                    .map_err(|e| CtlError::Usage(format!("--capture {}: cannot write it: {e}", path.display())))?,
            ),
            None => None,
        };
        let (line, mut policy) = match (&g.serial, &g.tcp) {
            (Some(path), _) => (
                SerialOrTcp::Serial(transport::open_serial(path, g.baud)?),
                timing::serial_policy(g.baud),
            ),
            (None, Some(addr)) => (
                SerialOrTcp::Tcp(transport::connect_tcp(addr).await?),
                timing::tcp_policy(),
            ),
            (None, None) => {
                return Err(CtlError::Usage(
                    "no transport: give --serial PATH (bus master) or --tcp HOST:PORT (GCU daemon)".into(),
                ));
            }
        };
        tune(&mut policy);
        if let Some(r) = g.retries {
            policy.retry.retries = r;
        }
        if let Some(t) = g.ack_timeout {
            policy.retry.ack_timeout = t;
        }
        if let Some(t) = g.result_timeout {
            policy.result_timeout = t;
        }
        if let Some(t) = g.nic_window {
            policy.nic_window = t;
        }
        if let Some(t) = g.init_timeout {
            policy.long_result_timeout = t;
        }
        let described = line.describe();
        let over_tcp = matches!(line, SerialOrTcp::Tcp(_));
        tracing::debug!(line = %described, ?policy, "connected");
        let tap = match &capture {
            Some((switch, _)) => switch.tap(format!("gimbalctl {described}"), Role::Master),
            None => CaptureSwitch::new().tap(described.clone(), Role::Master),
        };
        Ok(Self {
            master: Master::new(Tapped::new(line, tap), policy),
            capture: capture.map(|(_, capture)| capture),
            to,
            from: g.from,
            line: described,
            over_tcp,
        })
    }

    /// One exchange of `payload`; failures become errors naming the device,
    /// the command and what happened.
    pub async fn exchange(&mut self, payload: &[u8]) -> Result<Exchange, CtlError> {
        let frame = FrameBuf::new(self.to, self.from, payload).map_err(|e| CtlError::Usage(format!("payload: {e}")))?;
        let command = Command::parse(payload);
        let ex = self.master.transact(&frame, &command).await?;
        let what = format!(
            "{} ({})",
            sagebrush_host::hex::payload_text(payload),
            command.mnemonic()
        );
        let to = self.to;
        let policy = *self.master.policy();
        if let Some(report) = ex.undelivered {
            let failure = report.failure.unwrap_or(sagebrush_protocol::Undelivered::NotConfirmed);
            return Err(CtlError::Undelivered(
                failure,
                format!(
                    "not delivered: {what} to {to}: {} (reported by GCU {})",
                    failure.describe(),
                    report.at_group
                ),
            ));
        }
        match ex.outcome {
            Outcome::Acknowledged | Outcome::Broadcast | Outcome::Result => Ok(ex),
            Outcome::Nic => Err(CtlError::Nic(format!(
                "NIC: {to} does not implement or cannot apply {what}"
            ))),
            Outcome::NoResult => Err(CtlError::NoResult(format!(
                "{to} acknowledged {what} but sent no result within {} ms",
                if command.result_kind()
                    == sagebrush_protocol::ResultKind::Required(sagebrush_protocol::ResultTimeout::Long)
                {
                    policy.long_result_timeout
                } else {
                    policy.result_timeout
                }
            ))),
            Outcome::Failed(TxFailure::Nak) => Err(CtlError::Nak(format!(
                "{to} answered NAK to {what} on all {} transmissions: the frame keeps arriving damaged (line noise? wrong --baud?)",
                ex.transmissions
            ))),
            Outcome::Failed(TxFailure::NoAck) => Err(CtlError::NoAck(format!(
                "no ACK from {to} for {what} after {} transmissions ({} ms each): check the address, the cabling and --baud",
                ex.transmissions, policy.retry.ack_timeout
            ))),
        }
    }

    /// A query: its result payload.
    pub async fn query(&mut self, command: &Command<'_>) -> Result<Vec<u8>, CtlError> {
        let payload = crate::request::encode(command)?;
        let ex = self.exchange(&payload).await?;
        match ex.result {
            Some(frame) => Ok(frame.frame().payload().to_vec()),
            None => Err(CtlError::NoResult(format!(
                "{} sent no result for {}",
                self.to,
                command.mnemonic()
            ))),
        }
    }
}

impl Session {
    /// Reads what arrives within `window` after an exchange: a second
    /// answer to one address (two devices with one ID on a bus) shows here.
    /// Frames are acknowledged, hop by hop, like every intact frame.
    pub async fn linger(&mut self, window: Duration) -> Result<Lingered, CtlError> {
        let mut seen = Lingered::default();
        let noise_before = self.master.noise_bytes();
        let deadline = tokio::time::Instant::now() + window;
        while let Some(event) = self.master.next_event(Some(deadline)).await? {
            match event {
                OwnedEvent::Frame(frame) => {
                    self.master.write(Write::Ack).await?;
                    seen.frames.push(frame);
                }
                OwnedEvent::Ack => seen.acks += 1,
                _ => seen.other_bytes += 1,
            }
        }
        seen.other_bytes += (self.master.noise_bytes() - noise_before) as u32;
        Ok(seen)
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if let Some(capture) = self.capture.take() {
            let stats = capture.stop(Duration::from_secs(2));
            tracing::debug!(?stats, "capture stopped");
        }
    }
}
