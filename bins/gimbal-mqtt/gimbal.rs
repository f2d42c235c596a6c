//! One gimbal behind the door: its gimbal session, a short queue of the
//! commands the broker brought, worked through in order by one task, and
//! stops that overtake that queue (ARCHITECTURE "gimbal-mqtt"):
//!
//! - a stop is sent at once, beside the queue, and every command that
//!   came before it and still waits is dropped with a reason (the
//!   operator's stop ends what was asked before it, it is not followed by
//!   it);
//! - at most [`QUEUE`] commands wait; one more is refused with a reason,
//!   so a flood costs a bounded amount of memory;
//! - a command that waited [`STALE`] is dropped, never sent late, and a
//!   lost broker connection drops every command that waits (nothing asked
//!   before the door was cut off runs after it is back).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::connection::proportional_speed;
use sagebrush_client::session::{Axes, Drive, GimbalSession, Velocity};
use sagebrush_protocol::Command as Wire;
use sagebrush_service::door_metrics::DoorMetrics;
use serde_json::Value;
use tokio::sync::{Semaphore, mpsc};
use tokio::time::Instant;

use crate::broker::Client;
use crate::command::{self, Command};

/// Commands of one gimbal waiting at once; more are refused.
pub const QUEUE: usize = 8;
/// A command that could not start within this is dropped.
pub const STALE: Duration = sagebrush_client::session::STALE;
/// Stops of one gimbal being sent at once; another joins them.
const STOPS: usize = 2;
/// The owner of the door's motions in the session's logs.
const OWNER: &str = "mqtt";

/// A command waiting for its gimbal.
struct Job {
    id: Value,
    command: Command,
    /// [`Gimbal::stops`] and [`Gimbal::cuts`] when it came.
    stops: u64,
    cuts: u64,
    came: Instant,
}

/// One configured gimbal; see the module's documentation.
#[derive(Debug)]
pub struct Gimbal {
    pub config: crate::config::Gimbal,
    pub session: Arc<GimbalSession>,
    pub result_topic: String,
    /// The user gcud governs the commands as (`None`: the door's own).
    user: Option<String>,
    max_slew: Duration,
    queue: mpsc::Sender<Job>,
    /// Stops asked so far: a job that came before the last one is dropped.
    stops: AtomicU64,
    /// Broker connections lost so far: likewise.
    cuts: AtomicU64,
    stops_running: Arc<Semaphore>,
    client: Client,
    /// The door's metrics: each command counted by its kind.
    metrics: Arc<DoorMetrics>,
}

impl std::fmt::Debug for Job {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Job").field("command", &self.command).finish()
    }
}

impl Gimbal {
    /// The gimbal and its worker task.
    pub fn start(
        config: crate::config::Gimbal,
        session: Arc<GimbalSession>,
        result_topic: String,
        door: &crate::config::Config,
        client: Client,
        metrics: Arc<DoorMetrics>,
    ) -> Arc<Self> {
        let (queue, jobs) = mpsc::channel(QUEUE);
        let g = Arc::new(Self {
            config,
            session,
            result_topic,
            user: door.user.clone(),
            max_slew: door.max_slew,
            queue,
            stops: AtomicU64::new(0),
            cuts: AtomicU64::new(0),
            stops_running: Arc::new(Semaphore::new(STOPS)),
            client,
            metrics,
        });
        tokio::spawn(Arc::clone(&g).work(jobs));
        g
    }

    /// Publishes a result; dropped (and counted by the caller's log) when
    /// the requests to the broker are full.
    pub fn answer(&self, id: &Value, ok: bool, reason: &str) -> bool {
        self.client
            .try_publish(self.result_topic.clone(), false, command::result(id, ok, reason))
    }

    /// A message on this gimbal's command topic, at once (the caller is the
    /// connection's event loop: nothing here waits). `false`: its answer
    /// could not be published (the requests to the broker are full).
    pub fn on_message(self: &Arc<Self>, payload: &[u8]) -> bool {
        let request = command::parse(payload, self.max_slew);
        self.metrics
            .request(request.command.as_ref().map_or("malformed", Command::kind));
        let command = match request.command {
            Ok(c) => c,
            Err(why) => return self.answer(&request.id, false, &why),
        };
        if command == Command::Stop {
            self.stops.fetch_add(1, Ordering::SeqCst);
            let Ok(permit) = Arc::clone(&self.stops_running).try_acquire_owned() else {
                return self.answer(&request.id, true, "a stop of this gimbal is already being sent");
            };
            let g = Arc::clone(self);
            tokio::spawn(async move {
                let r = g.session.stop(Axes::PAN_TILT).await;
                drop(permit);
                g.publish_outcome(&request.id, "stop", r.map(|()| "stopped".to_owned()))
                    .await;
            });
            return true;
        }
        let job = Job {
            id: request.id,
            command,
            stops: self.stops.load(Ordering::SeqCst),
            cuts: self.cuts.load(Ordering::SeqCst),
            came: Instant::now(),
        };
        match self.queue.try_send(job) {
            Ok(()) => true,
            Err(e) => {
                let job = match e {
                    mpsc::error::TrySendError::Full(j) | mpsc::error::TrySendError::Closed(j) => j,
                };
                self.answer(
                    &job.id,
                    false,
                    &format!(
                        "{QUEUE} commands already wait for {}: {} refused",
                        self.config.name,
                        job.command.name()
                    ),
                )
            }
        }
    }

    /// The broker connection was lost: whatever waits is dropped.
    pub fn connection_lost(&self) {
        self.cuts.fetch_add(1, Ordering::SeqCst);
    }

    async fn publish_outcome(&self, id: &Value, what: &str, r: Result<String, CommandError>) {
        let bytes = match &r {
            Ok(words) => command::result(id, true, words),
            Err(e) => command::result(id, false, &e.to_string()),
        };
        if let Err(e) = &r {
            tracing::info!(gimbal = %self.config.name, command = what, error = %e, "not done");
        }
        // Waits for room: this gimbal's next command waits meanwhile.
        let _ = self.client.publish(self.result_topic.clone(), false, bytes).await;
    }

    async fn work(self: Arc<Self>, mut jobs: mpsc::Receiver<Job>) {
        while let Some(job) = jobs.recv().await {
            let dropped = if job.stops != self.stops.load(Ordering::SeqCst) {
                Some("dropped: a stop came after it".to_owned())
            } else if job.cuts != self.cuts.load(Ordering::SeqCst) {
                Some("dropped: the door lost the broker after it came".to_owned())
            } else if job.came.elapsed() > STALE {
                Some(format!("dropped: it could not start within {} s", STALE.as_secs()))
            } else {
                None
            };
            if let Some(why) = dropped {
                let _ = self
                    .client
                    .publish(self.result_topic.clone(), false, command::result(&job.id, false, &why))
                    .await;
                continue;
            }
            let r = self.execute(&job.command).await;
            self.publish_outcome(&job.id, job.command.name(), r).await;
        }
    }

    /// Does `command` through the session, for the configured user: what
    /// gcud made of it, in words.
    async fn execute(&self, command: &Command) -> Result<String, CommandError> {
        let s = self.session.acting_for(self.user.as_deref());
        match *command {
            Command::GoTo { pan, tilt } => {
                // An axis left out keeps its angle (the session's rule).
                let target = s.go_to_degrees(pan, tilt).await?;
                Ok(format!(
                    "going to pan {:.2} tilt {:.2}",
                    target.pan.degrees(),
                    target.tilt.degrees()
                ))
            }
            Command::Slew { pan, tilt, lease } => {
                let drive = |v: Option<f64>| v.map(|v| Drive::signed(v, proportional_speed));
                let velocity = Velocity {
                    pan: drive(pan),
                    tilt: drive(tilt),
                    zoom: None,
                };
                s.velocity(velocity, Some(lease), OWNER).await?;
                Ok(format!("slewing for {} ms", lease.as_millis()))
            }
            Command::Stop => {
                self.session.stop(Axes::PAN_TILT).await?;
                Ok("stopped".to_owned())
            }
            Command::Home => {
                s.home().await?;
                Ok("going home".to_owned())
            }
            Command::PresetRecall(n) => {
                s.go_to_preset(n).await?;
                Ok(format!("going to preset {n}"))
            }
            Command::PresetStore(n) => {
                s.send(Wire::StorePreset(n)).await?;
                Ok(format!("stored preset {n}"))
            }
            Command::Release => {
                s.release().await?;
                Ok("released".to_owned())
            }
        }
    }
}
