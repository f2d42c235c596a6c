//! `gimbal-pelco`: a Pelco-D and Pelco-P front door in front of gcud (issue
//! 50). CCTV keyboards, DVRs and NVRs drive the gimbals as Pelco cameras:
//! on a serial line (RS-485, where the door is a device on the bus) or raw
//! over TCP or UDP through a serial server. Every command goes to gcud's
//! client listener over each gimbal's session, so gcud stays the only
//! master of the buses and governs the keyboards as it does every tool.

mod codec;
mod command;
mod config;
mod gimbal;
mod inputs;
mod keyboard;
mod stats;

use std::process::ExitCode;
use std::sync::Arc;

use sagebrush_service::door::Started;
use tracing::info;

use crate::config::Transport;
use crate::stats::Stats;

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-pelco",
        "Pelco-D and Pelco-P (CCTV keyboards, DVRs; serial, TCP, UDP) for the gimbals behind gcud.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let sessions = sagebrush_client::door::DoorSessions::new(&config.link, config.poll);
    let stats = Arc::new(Stats::default());
    let gimbals: Vec<Arc<gimbal::Gimbal>> = config
        .gimbals
        .iter()
        .map(|g| gimbal::Gimbal::new(g.clone(), &config, &sessions))
        .collect();
    let run = config.lease.unwrap_or(config.max_move);
    // One admission table for every TCP input: the caps are for all.
    let table = sagebrush_service::Connections::new(sagebrush_service::Limits {
        max_total: config.limits.max_connections,
        max_per_peer: config.limits.max_connections_per_peer,
        cap_loopback: true,
        idle_timeout: config.limits.idle_timeout,
    });
    let keyboards = Arc::new(keyboard::Sessions::new(config.limits.udp_sources));
    let live = Arc::clone(&keyboards);
    metrics.count_sessions(move || live.live());
    let mut tasks = tokio::task::JoinSet::new();
    for input in &config.inputs {
        let counted = (Arc::clone(&metrics), Arc::clone(&keyboards));
        let door = keyboard::Door::new(input, &gimbals, run, Arc::clone(&stats), counted);
        match &input.transport {
            Transport::Serial { path, baud } => {
                tasks.spawn(inputs::serial(path.clone(), *baud, door));
            }
            Transport::TcpListen(addr) => {
                tasks.spawn(inputs::tcp(*addr, door, Arc::clone(&table)).await?);
            }
            Transport::UdpListen(addr) => {
                tasks.spawn(inputs::udp(*addr, door, config.limits.udp_sources).await?);
            }
        }
    }
    info!(
        inputs = config.inputs.len(),
        gimbals = gimbals.len(),
        lease_ms = config.lease.map(|l| l.as_millis() as u64),
        gcud = %config.link.gcud,
        "gimbal-pelco ready"
    );
    let signal = signals.ready_then_wait().await;
    info!(signal, "stopping: the motions this service started are stopped");
    tasks.abort_all();
    for g in &gimbals {
        g.session.shutdown().await;
    }
    info!("{}", stats.summary());
    Ok(())
}
