//! One gimbal behind gcud, reached over a connection of its own to gcud's
//! client listener: opened on first use, dropped when it fails so that the
//! next command opens a fresh one. Every motion sent over it belongs to
//! that connection, so gcud's dead-man stops it if the program dies
//! (ARCHITECTURE "Delivery contract").

use std::time::Duration;

use sagebrush_protocol::{Address, Command, LensPosition, Position, Reply, Speed};
use tracing::warn;

use crate::client::{CommandError, GcudClient, expect_position};

/// The longest a connection to gcud may take to open.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How often a gimbal that does not answer is polled at the most: each
/// poll of a silent gimbal costs gcud's retries on its bus.
pub const UNREACHABLE_POLL: Duration = Duration::from_secs(5);

/// The proportional speed (Table 11, `0..=15`) for `fraction` of the
/// fastest: speed n covers up to (n + 1) / 16 of it; 0 or less is the
/// slowest, 1 or more the fastest.
pub fn proportional_speed(fraction: f64) -> Speed {
    let n = (fraction.abs() * 16.0).ceil().clamp(1.0, 16.0) as u8 - 1;
    Speed::new(n).unwrap_or(Speed::new(Speed::MAX).expect("in range"))
}

/// The gimbal's identity block (`D?`, Table 6), as text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Identity {
    pub name: String,
    pub serial: String,
    pub revision: String,
}

impl Identity {
    /// The identity in a `D?` result's payload.
    pub fn from_result(payload: &[u8]) -> Result<Self, CommandError> {
        match Reply::parse(&Command::Identify, payload) {
            Ok(Reply::Identity(id)) => Ok(Identity {
                name: String::from_utf8_lossy(id.name()).into_owned(),
                serial: String::from_utf8_lossy(id.serial()).into_owned(),
                revision: String::from_utf8_lossy(&id.revision).into_owned(),
            }),
            _ => Err(CommandError::BadReply(format!(
                "D? result {:?} is not a Table 6 identity",
                String::from_utf8_lossy(payload)
            ))),
        }
    }
}

/// A gimbal at `address` behind gcud at `gcud` (`host:port`).
#[derive(Debug)]
pub struct GimbalConnection {
    pub address: Address,
    gcud: String,
    from: u8,
    nic_window_ms: u64,
    client: Option<GcudClient>,
}

impl GimbalConnection {
    /// Commands go out as source group `from`; a NIC may come up to
    /// `nic_window` after gcud's ACK (1.4.2).
    pub fn new(gcud: &str, from: u8, address: Address, nic_window: Duration) -> Self {
        Self {
            address,
            gcud: gcud.to_owned(),
            from,
            nic_window_ms: nic_window.as_millis() as u64,
            client: None,
        }
    }

    /// Sends `command`; its result payload, if it has one.
    pub async fn send(&mut self, command: &Command<'_>) -> Result<Option<Vec<u8>>, CommandError> {
        if self.client.is_none() {
            let nic_window = self.nic_window_ms;
            let connect = GcudClient::connect(&self.gcud, self.from, |p| p.nic_window = nic_window);
            let unreachable = |e: String| CommandError::Io(format!("gcud at {} cannot be reached: {e}", self.gcud));
            self.client = Some(
                tokio::time::timeout(CONNECT_TIMEOUT, connect)
                    .await
                    .map_err(|_| unreachable(format!("no connection within {} s", CONNECT_TIMEOUT.as_secs())))?
                    .map_err(|e| unreachable(e.to_string()))?,
            );
        }
        let client = self.client.as_mut().expect("connected above");
        match client.send(self.address, command).await {
            Ok(ex) => Ok(ex.result.map(|f| f.frame().payload().to_vec())),
            Err(e) => {
                if matches!(e, CommandError::Io(_)) {
                    self.client = None;
                }
                Err(e)
            }
        }
    }

    /// A query's result payload.
    pub async fn query(&mut self, command: &Command<'_>) -> Result<Vec<u8>, CommandError> {
        self.send(command).await?.ok_or_else(|| {
            CommandError::NoResult(format!("{} sent no result for {}", self.address, command.mnemonic()))
        })
    }

    /// `P?`: where the gimbal points now.
    pub async fn position(&mut self) -> Result<Position, CommandError> {
        let payload = self.query(&Command::QueryPosition).await?;
        expect_position(&Command::QueryPosition, &payload)
    }

    /// `V?`: the lens's zoom and focus (Table 17).
    pub async fn lens(&mut self) -> Result<LensPosition, CommandError> {
        let payload = self.query(&Command::QueryLens).await?;
        match Reply::parse(&Command::QueryLens, &payload) {
            Ok(Reply::Lens(lens)) => Ok(lens),
            _ => Err(CommandError::BadReply(format!(
                "V? result {:?} is not a Table 17 lens position",
                String::from_utf8_lossy(&payload)
            ))),
        }
    }

    /// Sends each of `stops`, each confirmed by its ACK: a stop not
    /// confirmed is sent once more, and every stop is sent whatever became
    /// of the one before; the first failure is the error.
    pub async fn stop(&mut self, stops: &[Command<'_>]) -> Result<(), CommandError> {
        let mut failed = None;
        for stop in stops {
            if let Err(first) = self.send(stop).await {
                warn!(gimbal = %self.address, error = %first, "{} not confirmed: sending it again", stop.mnemonic());
                if let Err(e) = self.send(stop).await {
                    failed.get_or_insert(e);
                }
            }
        }
        failed.map_or(Ok(()), Err)
    }

    /// `D?`: the gimbal's name, serial and revision (Table 6).
    pub async fn identity(&mut self) -> Result<Identity, CommandError> {
        let payload = self.query(&Command::Identify).await?;
        Identity::from_result(&payload)
    }
}
