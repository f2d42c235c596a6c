//! One connection to a bus (serial, as master) or a GCU (TCP, as client)
//! and the exchanges `gimbalctl` makes over it ([`sagebrush_client::Client`]),
//! with protocol failures turned into [`CtlError`]s that say what happened.

use sagebrush_client::codec::Write;
use sagebrush_client::master::Exchange;
use sagebrush_client::{Client, CommandError};
use sagebrush_host::capture::{Capture, CaptureSwitch, Role, Tapped, capture_to};
use sagebrush_host::timing;
use sagebrush_host::tls::Endpoint;
use sagebrush_host::transport::{self, SerialOrTcp};
use std::time::Duration;

use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{Address, Command, FrameBuf, LINK_PORT, OwnedEvent, ResultKind};

use crate::cli::Global;
use crate::error::CtlError;
use crate::request::Request;

/// A connection and the addressing of its commands.
#[derive(Debug)]
pub struct Session {
    client: Client<Tapped<SerialOrTcp>>,
    /// `--capture FILE`: stopped (the file completed) when the session ends.
    capture: Option<Capture>,
    pub to: Address,
    /// What the line is (`tcp 127.0.0.1:4001`, `serial /dev/pts/3`).
    pub line: String,
    /// `--tcp` without `--direct`: gcud's client listener, not a bus.
    pub gcud: bool,
    /// `~W` was asked on this connection (once, whatever the answer).
    window_asked: bool,
}

/// How long gimbalctl waits for gcud's ACK of `~W`: gcud answers a
/// command to itself at once, and a device server (`--tcp` without
/// `--direct`) never does, which should not cost a whole ACK time-out.
const WINDOW_ASK_MS: u64 = 250;

/// `--tcp` with `--tls-ca`, `--tls-cert` and `--tls-key`: gcud's endpoint.
fn endpoint(g: &Global) -> Result<Endpoint, CtlError> {
    let addr = g.tcp.as_deref().unwrap_or_default();
    let files = g.tls_ca.as_ref().map(|ca| sagebrush_host::tls::ClientFiles {
        ca: ca.clone(),
        identity: g.tls_cert.clone().zip(g.tls_key.clone()),
    });
    if files.is_none() && (g.tls_cert.is_some() || g.tls_key.is_some()) {
        return Err(CtlError::Usage(
            "--tls-cert and --tls-key need --tls-ca (the CA of gcud's certificate) and --tcp tls://HOST:PORT".into(),
        ));
    }
    Endpoint::parse(addr, files).map_err(|e| CtlError::Usage(format!("--tcp {e}")))
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
                match endpoint(g)? {
                    Endpoint { tls: None, .. } => {
                        SerialOrTcp::Tcp(transport::connect_tcp(addr).await.map_err(refused_hint)?)
                    }
                    tls => match tls.connect().await.map_err(refused_hint)? {
                        sagebrush_host::tls::Stream::Tls(stream) => SerialOrTcp::Tls(stream),
                        sagebrush_host::tls::Stream::Plain(tcp) => SerialOrTcp::Tcp(tcp),
                    },
                },
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
        let over_tcp = !matches!(line, SerialOrTcp::Serial(_));
        tracing::debug!(
            line = %described,
            ack_timeout_ms = policy.retry.ack_timeout,
            retries = policy.retry.retries,
            result_timeout_ms = policy.result_timeout,
            long_result_timeout_ms = policy.long_result_timeout,
            nic_window_ms = policy.nic_window,
            "connected"
        );
        let tap = match &capture {
            Some((switch, _)) => switch.tap(format!("gimbalctl {described}"), Role::Master),
            None => CaptureSwitch::new().tap(described.clone(), Role::Master),
        };
        Ok(Self {
            client: Client::new(Tapped::new(line, tap), policy, g.from),
            capture: capture.map(|(_, capture)| capture),
            to,
            line: described,
            gcud: over_tcp && !g.direct,
            window_asked: false,
        })
    }

    /// One exchange of `command`, whose payload is `payload` (its encoding,
    /// not read again); failures become errors naming the device, the
    /// command and what happened ([`CommandError`]).
    pub async fn exchange(&mut self, command: &Command<'_>, payload: &[u8]) -> Result<Exchange, CtlError> {
        self.ask_window_reports(command).await?;
        Ok(self.client.exchange(self.to, command, payload).await?)
    }

    /// A subcommand's exchange, with the command chained before it if it
    /// has one (`slew --speed`): through gcud that agreed to `~W` the
    /// second goes at the first's ACK ([`Client::send_chained`]), and each
    /// outcome stays its own; the request's, or the first's failure.
    pub async fn start(&mut self, request: &Request<'_>) -> Result<Exchange, CtlError> {
        let Some(first) = &request.first else {
            return self.exchange(&request.command, &request.payload).await;
        };
        self.ask_window_reports(first).await?;
        match self
            .client
            .send_chained(self.to, first, &request.command, &|| true)
            .await
        {
            (Err(e), _) => Err(e.into()),
            (Ok(_), Some(sent)) => Ok(sent?),
            (Ok(_), None) => Err(CtlError::Usage(format!(
                "{} was not sent after {}",
                request.command.mnemonic(),
                first.mnemonic()
            ))),
        }
    }

    /// Before the first command that may wait a NIC window after its ACK
    /// (no required result, one device): through gcud, asks it to report the end of
    /// its port's window (`~W`, ARCHITECTURE "End of the NIC window"), so
    /// that the exchange does not wait `--nic-window` on top of it. Never on
    /// a bus (`--serial`, `--tcp --direct`): no device is `G.0.0`, and the
    /// question would only cost an ACK time-out. gcud asked once, without
    /// retransmission (TCP loses nothing); a NIC (an older gcud) or no answer
    /// leaves the window here, as before.
    async fn ask_window_reports(&mut self, command: &Command<'_>) -> Result<(), CtlError> {
        let to = self.to;
        if !self.gcud
            || self.window_asked
            || matches!(command.result_kind(), ResultKind::Required(_))
            || to.has_wildcard()
            || to.port == LINK_PORT
        {
            return Ok(());
        }
        self.window_asked = true;
        let policy = *self.client.master_mut().policy();
        let asking = self.client.master_mut().policy_mut();
        asking.retry.retries = 0;
        asking.retry.ack_timeout = asking.retry.ack_timeout.min(WINDOW_ASK_MS);
        let asked = self.client.ask_window_reports(to.group).await;
        *self.client.master_mut().policy_mut() = policy;
        match asked {
            Ok(agreed) => tracing::debug!(agreed, group = to.group, "end-of-window reports (~W) asked"),
            Err(e @ CommandError::Io(_)) => return Err(e.into()),
            Err(CommandError::NoAck(_)) => sagebrush_host::errln!(
                "gimbalctl: note: {}.0.0 did not answer ~W (end-of-window reports) within {} ms: \
                 waiting --nic-window after each ACK here; if --tcp leads to a device server, not gcud, give --direct",
                to.group,
                policy.retry.ack_timeout.min(WINDOW_ASK_MS)
            ),
            Err(e) => tracing::debug!(error = %e, "end-of-window reports (~W) not agreed"),
        }
        Ok(())
    }

    /// The source group the commands carry (`--from`).
    pub fn from(&self) -> u8 {
        self.client.from
    }

    /// A query: its result payload.
    pub async fn query(&mut self, command: &Command<'_>) -> Result<Vec<u8>, CtlError> {
        Ok(self.client.query(self.to, command).await?)
    }
}

impl Session {
    /// Reads what arrives within `window` after an exchange: a second
    /// answer to one address (two devices with one ID on a bus) shows here.
    /// Frames are acknowledged, hop by hop, like every intact frame.
    pub async fn linger(&mut self, window: Duration) -> Result<Lingered, CtlError> {
        let mut seen = Lingered::default();
        let noise_before = self.client.master_mut().noise_bytes();
        let deadline = tokio::time::Instant::now() + window;
        while let Some(event) = self.client.master_mut().next_event(Some(deadline)).await? {
            match event {
                OwnedEvent::Frame(frame) => {
                    self.client.master_mut().write(Write::Ack).await?;
                    seen.frames.push(frame);
                }
                OwnedEvent::Ack => seen.acks += 1,
                _ => seen.other_bytes += 1,
            }
        }
        seen.other_bytes += (self.client.master_mut().noise_bytes() - noise_before) as u32;
        Ok(seen)
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if let Some(capture) = self.capture.take() {
            let stats = capture.stop(Duration::from_secs(2));
            tracing::debug!(
                records = stats.records,
                bytes_written = stats.bytes_written,
                dropped = stats.dropped,
                stopped = stats.stopped.as_deref().unwrap_or("no"),
                "capture stopped"
            );
        }
    }
}

/// A refused connection most often means that gcud is not running, or
/// listens elsewhere: the error says so.
fn refused_hint(e: std::io::Error) -> std::io::Error {
    if e.kind() != std::io::ErrorKind::ConnectionRefused {
        return e;
    }
    std::io::Error::new(
        e.kind(),
        format!(
            "{e}: nothing listens there. Is gcud running (`systemctl status gcud`), with a client \
             listener ([[link]] listen in its configuration) on that address?"
        ),
    )
}
