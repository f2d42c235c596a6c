//! `gimbal-web`: a web page for operators without a VMS or a ground
//! station (issue 34): sign in, then a card per gimbal with its live
//! position, hold-to-move, Stop, Home, presets and a pan/tilt picture to
//! click. Every gimbal is driven through its gimbal session
//! (`sagebrush_client::session`) over this program's own connection to
//! gcud's client listener; the page is served through the bounded listener.

mod auth;
mod config;
mod forwarded;
mod guard;
mod web;

use std::process::ExitCode;
use std::sync::Arc;

use sagebrush_client::door::DoorSessions;
use sagebrush_service::door::Started;
use tracing::info;

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-web",
        "A web page to drive the gimbals behind gcud: live position, hold-to-move, presets.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let presets = Arc::new(sagebrush_client::presets::Presets::load(config.state_file.clone())?);
    let door_sessions = DoorSessions::new(&config.link, config.poll);
    let gimbals: Vec<web::Gimbal> = config
        .gimbals
        .iter()
        .map(|g| {
            let session = // A held move runs while the page renews it, never longer.
                    door_sessions.start(&g.name, g.address, false, config.hold_lease);
            web::Gimbal {
                config: g.clone(),
                session,
            }
        })
        .collect();
    let sessions: Vec<_> = gimbals.iter().map(|g| Arc::clone(&g.session)).collect();
    let tls = config.tls.as_ref().map(|t| t.acceptor()).transpose()?;
    let (addr, server) = web::bind(&config, gimbals, presets, tls, metrics)
        .await
        .map_err(|e| format!("listen {}: cannot listen: {e}", config.listen))?;
    let server = tokio::spawn(server);
    info!(gimbals = sessions.len(), gcud = %config.link.gcud, %addr, "gimbal-web ready");
    let signal = signals.ready_then_wait().await;
    info!(signal, "stopping: the motions this service started are stopped");
    server.abort();
    for s in &sessions {
        s.shutdown().await;
    }
    Ok(())
}
