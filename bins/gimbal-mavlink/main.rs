//! `gimbal-mavlink`: a MAVLink Gimbal Protocol v2 gimbal manager in front
//! of gcud (issue 25). Each configured gimbal is a gimbal manager and
//! gimbal device with its own component id; every command goes to gcud's
//! client listener over that gimbal's own connection, so gcud stays the
//! only master of the buses and its dead-man stops what this program
//! started if it dies.

mod config;
mod earth;
mod manager;
mod routing;
mod stats;
mod transport;

use std::process::ExitCode;
use std::sync::Arc;

use mavlink::Message;
use mavlink::dialects::common::MavMessage;
use sagebrush_service::door::Started;
use tracing::{info, warn};

use crate::earth::vehicle;
use crate::manager::{gimbal, reaim, status};
use crate::routing::{answers, control, handle, inbox};
use crate::stats::Stats;
use crate::transport::link::Outbox;
use crate::transport::{signing, stream};

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-mavlink",
        "MAVLink Gimbal Protocol v2 (gimbal manager and device) for the gimbals behind gcud.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

/// A ground station or vehicle heard this recently is live (the door's
/// metrics' sessions): a MAVLink component sends HEARTBEAT every second.
const LIVE: std::time::Duration = std::time::Duration::from_secs(5);

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let signing = (config.signing.clone()).map(|s| signing::Signing::new(s.key, s.link_id));
    if let Some(s) = &config.signing {
        info!(
            link_id = s.link_id,
            "MAVLink 2 signing on: only frames signed with the key are read"
        );
    }
    let outbox = Outbox::bind(config.system_id, &config.endpoints, signing).await?;
    let net = Arc::clone(&outbox.net);
    metrics.count_sessions(move || net.live(LIVE));
    let stats = Arc::new(Stats::default());
    let mut handles = Vec::new();
    let mut gimbal_tasks = Vec::new();
    // Each gimbal's session polls at the attitude period.
    let sessions = sagebrush_client::door::DoorSessions::new(&config.link, config.attitude_period);
    for g in &config.gimbals {
        let (handle, join) = gimbal::spawn(g, &config, Arc::clone(&outbox), Arc::clone(&stats), &sessions);
        handles.push(handle);
        gimbal_tasks.push(join);
    }
    let vehicle = Arc::new(vehicle::Vehicle::new(config.system_id, config.mount));
    let mut tasks = tokio::task::JoinSet::new();
    tasks.spawn(status::run(
        Arc::clone(&outbox),
        handles.clone(),
        Arc::clone(&vehicle),
        config.attitude_period,
        config.control_lapse,
    ));
    tasks.spawn(reaim::run(handles.clone(), Arc::clone(&vehicle)));
    // Answers that need no gimbal task (an unsupported command) go out
    // through this queue, so that a receiver never waits on a send.
    let (answers, mut answer_rx) = tokio::sync::mpsc::channel::<(u8, MavMessage)>(64);
    let sender = Arc::clone(&outbox);
    tasks.spawn(async move {
        while let Some((component, message)) = answer_rx.recv().await {
            sender.send(component, &message).await;
        }
    });
    let handler: stream::Handler = {
        let (handles, stats, system_id) = (handles.clone(), Arc::clone(&stats), config.system_id);
        let vehicle = Arc::clone(&vehicle);
        Arc::new(move |header, message| {
            vehicle.hear(header, &message);
            let routes = inbox::route(&handles, system_id, &vehicle, header, &message);
            if routes.iter().any(|r| !matches!(r, handle::Route::Ignore)) {
                // A message for this door, by its name (the dialect's: a bounded set).
                metrics.request(message.message_name());
            }
            for route in routes {
                inbox::count(&route, &stats);
                match route {
                    handle::Route::Gimbal(i, job) => {
                        if handles[i].jobs.try_send(job).is_err() {
                            let total = Stats::count(&stats.busy);
                            if stats::may_warn("request queue full", &handles[i].config.name) {
                                warn!(gimbal = %handles[i].config.name, total, "request queue full: request dropped");
                            }
                        }
                    }
                    handle::Route::Answer(component, command, result) => {
                        let ack = answers::ack(command, result, (header.system_id, header.component_id));
                        let _ = answers.try_send((component, ack));
                    }
                    handle::Route::Refused(i, why) => {
                        if stats::may_warn("request refused", &handles[i].config.name) {
                            warn!(gimbal = %handles[i].config.name, from = control::sender_name((header.system_id, header.component_id)), why, "request refused");
                        }
                    }
                    handle::Route::Ignore => {}
                }
            }
        })
    };
    transport::endpoints::start(&config.endpoints, &outbox, &stats, &handler, &mut tasks).await?;
    info!(gimbals = handles.len(), gcud = %config.link.gcud, system_id = config.system_id, "gimbal-mavlink ready");
    let signal = signals.ready_then_wait().await;
    info!(signal, "stopping: the slews this service started are stopped");
    // Receive no more; each gimbal task stops the slews it started.
    tasks.abort_all();
    while tasks.join_next().await.is_some() {}
    for h in &handles {
        let _ = h
            .jobs
            .send(handle::Job {
                from: (0, 0),
                work: handle::Work::Shutdown,
            })
            .await;
    }
    for t in gimbal_tasks {
        let _ = t.await;
    }
    info!(counters = %stats.summary(), "stopped");
    Ok(())
}
