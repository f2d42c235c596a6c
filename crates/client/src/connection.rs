//! One gimbal behind gcud, reached over a connection of its own to gcud's
//! client listener: opened on first use, dropped when it fails so that the
//! next command opens a fresh one. Every motion sent over it belongs to
//! that connection, so gcud's dead-man stops it if the program dies
//! (ARCHITECTURE "Delivery contract").

use std::time::Duration;

use sagebrush_protocol::{Address, Command, LensPosition, Position, Reply, Speed, Undelivered};
use tokio::time::Instant;
use tracing::warn;

use crate::client::{CommandError, GcudClient, expect_position};
use crate::governance::{Controller, GcuAnswer, GcuRequest};

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

/// A gcud that answers `~C` NIC (it governs nothing, or predates
/// governance) is asked again after this.
pub const CONTROLLER_UNKNOWN_RETRY: Duration = Duration::from_secs(30);
/// After a refusal for control, the holder gcud named is taken as still
/// holding for this long before it is asked again (a refused stream of
/// rates asks once, not once per rate).
const HOLDER_FRESH: Duration = Duration::from_millis(200);

/// What this connection knows of gcud's control of its gimbal (`~C`).
#[derive(Clone, Debug, Default)]
struct ControlSeen {
    /// The last answer, and when.
    holder: Option<(Controller, Instant)>,
    /// gcud answered `~C` NIC: not asked again before this.
    unsupported_until: Option<Instant>,
}

/// gcud's control of a connection's gimbal, as it last answered `~C`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Control {
    pub holder: Controller,
    /// The holder is this connection's own link.
    pub ours: bool,
}

/// A gimbal at `address` behind gcud at `gcud` (`host:port`).
#[derive(Debug)]
pub struct GimbalConnection {
    pub address: Address,
    gcud: sagebrush_host::tls::Endpoint,
    from: u8,
    nic_window_ms: u64,
    client: Option<GcudClient>,
    control: ControlSeen,
    /// The user gcud takes this connection's commands for (`~U`), as last
    /// told on this connection (`None`: the door itself, as every new
    /// connection starts).
    acting: Option<String>,
    /// gcud refused `~U` on this connection (its principal may not act
    /// for users): not asked again until the next connection.
    acting_refused: bool,
}

/// Whether gcud takes control for `command`: its row of the protocol
/// crate's table says it moves or changes the gimbal (the one classifier
/// gcud's governance decides by, module `mount`).
fn takes_control(command: &Command<'_>) -> bool {
    command.mount().changes()
}

impl GimbalConnection {
    /// Commands go out as source group `from`; a NIC may come up to
    /// `nic_window` after gcud's ACK (1.4.2).
    pub fn new(
        gcud: impl Into<sagebrush_host::tls::Endpoint>,
        from: u8,
        address: Address,
        nic_window: Duration,
    ) -> Self {
        Self {
            address,
            gcud: gcud.into(),
            from,
            nic_window_ms: nic_window.as_millis() as u64,
            client: None,
            control: ControlSeen::default(),
            acting: None,
            acting_refused: false,
        }
    }

    /// The next commands act for `user`, one of the door's users (`None`:
    /// the door itself): `~U` when that changes on this connection
    /// (ARCHITECTURE "Principals"). Only over TLS, where the door is a
    /// principal gcud may let act for users; a gcud that refuses it is
    /// not asked again on this connection, and the commands go as the
    /// door's (said once).
    pub async fn act_for(&mut self, user: Option<&str>) {
        if self.gcud.tls.is_none() {
            return;
        }
        // A name gcud could not know as a principal: the door's own.
        let user = user.filter(|u| sagebrush_protocol::gcu::valid_name(u.as_bytes()));
        if self.client().await.is_err() || self.acting_refused || self.acting.as_deref() == user {
            return;
        }
        let asked = self.gcu(&GcuRequest::ActFor(user.map(str::to_owned))).await;
        match asked {
            Ok(_) => self.acting = user.map(str::to_owned),
            Err(e) => {
                self.acting_refused = true;
                warn!(gcud = %self.gcud, error = %e, "gcud does not let this door act for its users: their commands go as the door's");
            }
        }
    }

    /// The connection to gcud, opened when needed.
    async fn client(&mut self) -> Result<&mut GcudClient, CommandError> {
        if self.client.is_none() {
            let nic_window = self.nic_window_ms;
            let connect = GcudClient::connect(&self.gcud, self.from, |p| p.nic_window = nic_window);
            let unreachable = |e: String| CommandError::Io(format!("gcud at {} cannot be reached: {e}", self.gcud));
            self.acting = None;
            self.acting_refused = false;
            self.client = Some(
                tokio::time::timeout(CONNECT_TIMEOUT, connect)
                    .await
                    .map_err(|_| unreachable(format!("no connection within {} s", CONNECT_TIMEOUT.as_secs())))?
                    .map_err(|e| unreachable(e.to_string()))?,
            );
            // gcud's port waits the NIC window after each ACK: it tells this
            // connection when it passed, so the master does not wait it again
            // (an older gcud answers NIC; then its own window bounds the wait).
            let group = self.address.group;
            let asked = self
                .client
                .as_mut()
                .expect("connected above")
                .ask_window_reports(group)
                .await;
            if let Err(e) = self.failed(asked) {
                warn!(gcud = %self.gcud, error = %e, "end-of-window reports not agreed: waiting the NIC window here too");
            }
        }
        self.client
            .as_mut()
            .ok_or_else(|| CommandError::Io(format!("the connection to gcud at {} failed", self.gcud)))
    }

    /// Drops the connection after an I/O failure (the next use opens one).
    fn failed<T>(&mut self, result: Result<T, CommandError>) -> Result<T, CommandError> {
        if matches!(result, Err(CommandError::Io(_))) {
            self.client = None;
        }
        result
    }

    /// Sends `command`; its result payload, if it has one. A command gcud
    /// refuses because another link controls the gimbal is refused naming
    /// that link (`~C`).
    pub async fn send(&mut self, command: &Command<'_>) -> Result<Option<Vec<u8>>, CommandError> {
        let address = self.address;
        let sent = self.client().await?.send(address, command).await;
        self.settled(command, sent).await
    }

    /// `first`, then `second` at its ACK where gcud allows
    /// ([`sagebrush_client::Master::transact_chained`]: a speed and the
    /// direction that takes it, with no NIC window between): each one's
    /// outcome as [`GimbalConnection::send`] gives it; the second's is
    /// `None` when it was not sent (the first failed, or `go_on` said no at
    /// its ACK: a stop goes first).
    #[allow(clippy::type_complexity)]
    pub async fn send_chained(
        &mut self,
        first: &Command<'_>,
        second: &Command<'_>,
        go_on: &(dyn Fn() -> bool + Sync),
    ) -> (
        Result<Option<Vec<u8>>, CommandError>,
        Option<Result<Option<Vec<u8>>, CommandError>>,
    ) {
        let address = self.address;
        let client = match self.client().await {
            Ok(c) => c,
            Err(e) => return (Err(e), None),
        };
        let (a, b) = client.send_chained(address, first, second, go_on).await;
        let a = self.settled(first, a).await;
        let b = match b {
            Some(b) => Some(self.settled(second, b).await),
            None => None,
        };
        (a, b)
    }

    /// What [`GimbalConnection::send`] makes of an exchange of `command`:
    /// its result payload; the connection dropped after an I/O failure; a
    /// refusal for another link's control naming that link.
    async fn settled(
        &mut self,
        command: &Command<'_>,
        sent: Result<crate::master::Exchange, CommandError>,
    ) -> Result<Option<Vec<u8>>, CommandError> {
        let settled = self.settled_as_told(command, sent).await;
        crate::outcomes::COUNTS.record(&settled);
        settled
    }

    /// [`GimbalConnection::settled`]'s result, before it is counted.
    async fn settled_as_told(
        &mut self,
        command: &Command<'_>,
        sent: Result<crate::master::Exchange, CommandError>,
    ) -> Result<Option<Vec<u8>>, CommandError> {
        match self.failed(sent) {
            Ok(ex) => {
                let ours = matches!(self.control.holder, Some((Controller::Link { yours: true, .. }, _)));
                if takes_control(command) && !ours {
                    // This link holds it now, as gcud's `~C` tells.
                    let _ = self.controller().await;
                }
                Ok(ex.result.map(|f| f.frame().payload().to_vec()))
            }
            Err(CommandError::Refused(Undelivered::NotInControl, why)) => {
                let fresh = self
                    .control
                    .holder
                    .as_ref()
                    .filter(|(_, at)| at.elapsed() < HOLDER_FRESH)
                    .map(|(h, _)| h.clone());
                let holder = match fresh {
                    Some(h) => Some(h),
                    None => self.controller().await.ok(),
                };
                let why = match holder {
                    // Named: "refused by gcud: pan right (CCW) until PS for 5.1.1: link operators (priority 80) controls the gimbal".
                    Some(holder) if holder != Controller::Nobody => {
                        let rule = Undelivered::NotInControl.describe();
                        let named = format!("{holder} controls the gimbal");
                        match why.strip_suffix(rule) {
                            Some(head) => format!("{head}{named}"),
                            None => format!("{why}: {named}"),
                        }
                    }
                    _ => why,
                };
                Err(CommandError::Refused(Undelivered::NotInControl, why))
            }
            Err(e) => Err(e),
        }
    }

    /// A GCU command to gcud about its gimbals (module `governance`).
    pub async fn gcu(&mut self, request: &GcuRequest) -> Result<GcuAnswer, CommandError> {
        let group = self.address.group;
        let answer = self.client().await?.gcu(group, request).await;
        self.failed(answer)
    }

    /// `~C`: who controls this gimbal now (kept for [`GimbalConnection::control`]).
    /// A gcud that answers NIC is not asked again for
    /// [`CONTROLLER_UNKNOWN_RETRY`]: [`CommandError::Nic`] meanwhile.
    pub async fn controller(&mut self) -> Result<Controller, CommandError> {
        let now = Instant::now();
        if self.control.unsupported_until.is_some_and(|t| t > now) {
            return Err(CommandError::Nic(format!(
                "gcud at {} does not answer ~C: nobody governs {}",
                self.gcud, self.address
            )));
        }
        let request = GcuRequest::Controller(self.address.port, self.address.device);
        match self.gcu(&request).await {
            Ok(GcuAnswer::Controller(holder)) => {
                self.control.unsupported_until = None;
                self.control.holder = Some((holder.clone(), Instant::now()));
                Ok(holder)
            }
            Ok(other) => Err(CommandError::BadReply(format!("~C answered {other:?}"))),
            Err(e) => {
                if matches!(e, CommandError::Nic(_)) {
                    self.control.unsupported_until = Some(now + CONTROLLER_UNKNOWN_RETRY);
                }
                self.control.holder = None;
                Err(e)
            }
        }
    }

    /// gcud's control of this gimbal as it last answered `~C`, if it did.
    pub fn control(&self) -> Option<Control> {
        let (holder, _) = self.control.holder.as_ref()?;
        let ours = matches!(holder, Controller::Link { yours: true, .. });
        Some(Control {
            holder: holder.clone(),
            ours,
        })
    }

    /// A query's result payload.
    pub async fn query(&mut self, command: &Command<'_>) -> Result<Vec<u8>, CommandError> {
        self.send(command).await?.ok_or_else(|| {
            CommandError::NoResult(format!("{} sent no result for {}", self.address, command.in_words()))
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
                warn!(gimbal = %self.address, error = %first, "{} not confirmed: sending it again", stop.in_words());
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
