//! Each gimbal's retained state on `<prefix>/<site>/<gimbal>/state`
//! (README "MQTT"): what its session's polls saw, published when it
//! changes (checked every poll period) and all of it again after every
//! (re)connection, so a subscriber, retained or live, sees the gimbal
//! within about one poll period.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use sagebrush_client::governance::Controller;
use sagebrush_client::session::{Motion, Status};
use serde_json::{Value, json};
use tokio::sync::watch;

use crate::gimbal::Gimbal;

/// An angle in degrees as the state gives it: the protocol's hundredths.
fn degrees(d: f32) -> Value {
    json!((f64::from(d) * 100.0).round() / 100.0)
}

/// The state document of a gimbal with `status`.
pub fn document(status: &Status) -> Value {
    let position = status.position;
    let controller = match status.control.as_ref().map(|c| &c.holder) {
        None | Some(Controller::Nobody) => Value::Null,
        Some(holder) => json!(holder.to_string()),
    };
    json!({
        "pan_deg": position.map_or(Value::Null, |p| degrees(p.pan.degrees())),
        "tilt_deg": position.map_or(Value::Null, |p| degrees(p.tilt.degrees())),
        "moving": status.changing || status.motion != Motion::Idle,
        "online": status.error.is_none() && position.is_some(),
        "controller": controller,
        "error": status.error,
    })
}

/// Publishes each gimbal's state when it changed, every `period`, while
/// the broker is connected (`connected`); a new connection (a change of
/// `connections`) publishes all of them again.
pub async fn publish(
    gimbals: Vec<Arc<Gimbal>>,
    topics: Vec<String>,
    client: crate::broker::Client,
    connected: Arc<AtomicBool>,
    mut connections: watch::Receiver<u64>,
    period: Duration,
) {
    let mut last: Vec<Option<Vec<u8>>> = vec![None; gimbals.len()];
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            changed = connections.changed() => {
                if changed.is_err() {
                    return;
                }
                last.iter_mut().for_each(|l| *l = None);
            }
        }
        if !connected.load(Ordering::SeqCst) {
            continue;
        }
        for ((g, topic), last) in gimbals.iter().zip(&topics).zip(last.iter_mut()) {
            let now = document(&g.session.status()).to_string().into_bytes();
            if last.as_ref() == Some(&now) {
                continue;
            }
            // No room among the requests: tried again at the next tick.
            if client.try_publish(topic.clone(), true, now.clone()) {
                *last = Some(now);
            }
        }
    }
}
