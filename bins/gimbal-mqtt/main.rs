//! `gimbal-mqtt`: the gimbals behind gcud on an MQTT broker (issue 51),
//! for Home Assistant, Node-RED and a control room of many sites. Each
//! gimbal's state is retained on `<prefix>/<site>/<gimbal>/state`, its
//! commands come on `.../cmd` and are answered on `.../result`; the site's
//! availability is `<prefix>/<site>/status`, the last will. Every gimbal is
//! driven through its gimbal session (`sagebrush_client::session`) over
//! this program's own connection to gcud, whose governance decides.

mod broker;
mod command;
mod config;
mod discovery;
mod gimbal;
mod link;
mod state;
mod topics;

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use sagebrush_client::door::DoorSessions;
use sagebrush_service::door::Started;
use tracing::info;

/// How long a stopping door waits for the broker to take its `offline`.
const GOODBYE: Duration = Duration::from_secs(3);

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-mqtt",
        "The gimbals behind gcud on an MQTT broker: state, commands, Home Assistant discovery.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let config = Arc::new(config);
    let topics = topics::Topics::new(&config);
    let (client, events) = broker::connect(&config.broker, &topics.status(), "offline")?;
    let door_sessions = DoorSessions::new(&config.link, config.poll);
    let gimbals: Vec<Arc<gimbal::Gimbal>> = config
        .gimbals
        .iter()
        .map(|g| {
            let session = door_sessions.start(&g.name, g.address, false, config.max_slew);
            gimbal::Gimbal::start(
                g.clone(),
                session,
                topics.result(&g.name),
                &config,
                client.clone(),
                Arc::clone(&metrics),
            )
        })
        .collect();
    let link = link::Link::new(
        Arc::clone(&config),
        topics.clone(),
        client.clone(),
        gimbals.clone(),
        Arc::clone(&metrics),
    );
    // Its client is the broker: one session while connected to it (the
    // tools behind the broker are the broker's to count).
    let connected = Arc::clone(&link.connected);
    metrics.count_sessions(move || usize::from(connected.load(Ordering::SeqCst)));
    let states = tokio::spawn(state::publish(
        gimbals.clone(),
        config.gimbals.iter().map(|g| topics.state(&g.name)).collect(),
        client.clone(),
        Arc::clone(&link.connected),
        link.connections.subscribe(),
        config.poll,
    ));
    let connection = tokio::spawn(Arc::clone(&link).run(events));
    info!(
        site = %config.site,
        gimbals = gimbals.len(),
        gcud = %config.link.gcud,
        broker = %config.broker.url,
        "gimbal-mqtt ready"
    );
    let signal = signals.ready_then_wait().await;
    info!(signal, "stopping: the motions this service started are stopped");
    states.abort();
    for g in &gimbals {
        g.session.shutdown().await;
    }
    link.closing.store(true, Ordering::SeqCst);
    if link.connected.load(Ordering::SeqCst) {
        let goodbye = async {
            let _ = client.publish(topics.status(), true, b"offline".to_vec()).await;
            client.disconnect().await;
        };
        let _ = tokio::time::timeout(GOODBYE, goodbye).await;
    }
    let _ = tokio::time::timeout(GOODBYE, connection).await;
    Ok(())
}
