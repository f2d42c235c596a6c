//! The door's life on the broker: one task polls the connection, routes
//! each message at once (a command to its gimbal, Home Assistant's
//! `online`), and after a lost connection waits a back-off that doubles up
//! to `reconnect_max_ms` before connecting again. At every connection the
//! door subscribes anew (a clean session keeps no subscription), says
//! `online` on its status topic, publishes every state again and, with
//! discovery on, every entity.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use sagebrush_service::door_metrics::DoorMetrics;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tracing::{info, warn};

use crate::broker::{Client, Event, EventLoop, back_off};
use crate::config::Config;
use crate::gimbal::Gimbal;
use crate::topics::Topics;

/// Log lines about dropped or refused messages: at most one per this.
const LOG_EVERY: Duration = Duration::from_secs(5);

/// What the connection task shares with the door.
#[derive(Debug)]
pub struct Link {
    pub config: Arc<Config>,
    pub topics: Topics,
    pub client: Client,
    pub gimbals: Vec<Arc<Gimbal>>,
    by_name: HashMap<String, usize>,
    /// The door's metrics: a retained command and one for no gimbal
    /// counted here (the others by their gimbal).
    metrics: Arc<DoorMetrics>,
    /// The broker is connected now.
    pub connected: Arc<AtomicBool>,
    /// Counts connections: the state publisher republishes on a change.
    pub connections: watch::Sender<u64>,
    /// The door is stopping: a lost connection ends the task.
    pub closing: AtomicBool,
    /// Answers that could not be published, since the last log line.
    unanswered: AtomicU64,
    last_log: std::sync::Mutex<Option<Instant>>,
}

impl Link {
    pub fn new(
        config: Arc<Config>,
        topics: Topics,
        client: Client,
        gimbals: Vec<Arc<Gimbal>>,
        metrics: Arc<DoorMetrics>,
    ) -> Arc<Self> {
        let by_name = gimbals
            .iter()
            .enumerate()
            .map(|(i, g)| (g.config.name.clone(), i))
            .collect();
        Arc::new(Self {
            config,
            topics,
            client,
            gimbals,
            by_name,
            metrics,
            connected: Arc::new(AtomicBool::new(false)),
            connections: watch::Sender::new(0),
            closing: AtomicBool::new(false),
            unanswered: AtomicU64::new(0),
            last_log: std::sync::Mutex::new(None),
        })
    }

    /// Polls the connection until the door closes it.
    pub async fn run(self: Arc<Self>, mut events: EventLoop) {
        let mut failures = 0u32;
        let mut on_connect: Option<JoinHandle<()>> = None;
        loop {
            match events.next().await {
                Ok(Event::Connected) => {
                    failures = 0;
                    self.connected.store(true, Ordering::SeqCst);
                    info!(broker = %self.config.broker.url, "connected to the broker");
                    if let Some(t) = on_connect.take() {
                        t.abort();
                    }
                    on_connect = Some(tokio::spawn(Arc::clone(&self).connected()));
                }
                Ok(Event::Message { topic, payload, retain }) => self.on_message(&topic, &payload, retain),
                Ok(Event::Other) => {}
                Err(e) => {
                    let was = self.connected.swap(false, Ordering::SeqCst);
                    if self.closing.load(Ordering::SeqCst) {
                        return;
                    }
                    if was {
                        for g in &self.gimbals {
                            g.connection_lost();
                        }
                        warn!(broker = %self.config.broker.url, error = %e, "lost the broker: commands that wait are dropped; connecting again");
                    } else if failures == 0 || failures.is_power_of_two() {
                        warn!(broker = %self.config.broker.url, error = %e, failures, "cannot connect to the broker");
                    }
                    let wait = back_off(
                        self.config.broker.reconnect_min,
                        self.config.broker.reconnect_max,
                        failures,
                    );
                    failures = failures.saturating_add(1);
                    tokio::time::sleep(wait).await;
                }
            }
        }
    }

    /// At every connection: subscribe, say online, publish every state
    /// again (the state task) and the discovery.
    async fn connected(self: Arc<Self>) {
        let mut filters = vec![self.topics.cmd_filter()];
        filters.extend(self.topics.home_assistant.clone());
        if let Err(e) = self.client.subscribe(&filters).await {
            warn!(error = %e, "cannot subscribe");
        }
        let _ = self
            .client
            .publish(self.topics.status(), true, b"online".to_vec())
            .await;
        self.connections.send_modify(|n| *n += 1);
        self.publish_discovery().await;
    }

    async fn publish_discovery(&self) {
        for g in &self.gimbals {
            for (topic, payload) in crate::discovery::messages(&self.config, &self.topics, &g.config) {
                if self.client.publish(topic, true, payload).await.is_err() {
                    return;
                }
            }
        }
    }

    fn on_message(self: &Arc<Self>, topic: &str, payload: &[u8], retain: bool) {
        if self.topics.home_assistant.as_deref() == Some(topic) {
            if payload == b"online" {
                info!("Home Assistant is online: discovery published again");
                let link = Arc::clone(self);
                tokio::spawn(async move { link.publish_discovery().await });
            }
            return;
        }
        let Some(name) = self.topics.gimbal_of_cmd(topic) else {
            return;
        };
        let answered = match self.by_name.get(name).map(|i| &self.gimbals[*i]) {
            // A command kept on the broker is never run: it was published
            // for a moment that has passed.
            Some(g) if retain => {
                self.metrics.request("retained");
                g.answer(
                    &serde_json::Value::Null,
                    false,
                    "a retained command is never run: publish commands without the retain flag",
                )
            }
            Some(g) => g.on_message(payload),
            None => {
                self.metrics.request("no_such_gimbal");
                self.client.try_publish(
                    self.topics.result(name),
                    false,
                    crate::command::result(
                        &serde_json::Value::Null,
                        false,
                        &format!("site {} has no gimbal named {name:?}", self.config.site),
                    ),
                )
            }
        };
        if !answered {
            self.unanswered.fetch_add(1, Ordering::Relaxed);
        }
        self.log_unanswered();
    }

    fn log_unanswered(&self) {
        let mut last = self.last_log.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if last.is_some_and(|t| t.elapsed() < LOG_EVERY) {
            return;
        }
        let n = self.unanswered.swap(0, Ordering::Relaxed);
        if n > 0 {
            warn!(
                unanswered = n,
                "commands came faster than the broker took their results: results dropped"
            );
            *last = Some(Instant::now());
        }
    }
}
