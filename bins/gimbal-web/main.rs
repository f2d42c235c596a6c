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

use sagebrush_client::session::{GcudReachability, GimbalSession, SessionConfig};
use sagebrush_service::door::{Door, Started};
use tracing::info;

/// This door, to the start-up every door shares.
const DOOR: Door = Door {
    name: "gimbal-web",
    about: "A web page to drive the gimbals behind gcud: live position, hold-to-move, presets.",
    families: sagebrush_client::outcomes::families,
};

fn main() -> ExitCode {
    sagebrush_service::door::main(DOOR, config::parse, run)
}

async fn run(config: config::Config, door: Started) -> Result<(), String> {
    let Started { metrics, signals } = door;
    let presets = Arc::new(sagebrush_client::presets::Presets::load(config.state_file.clone())?);
    let reach = Arc::new(GcudReachability::default());
    let gimbals: Vec<web::Gimbal> = config
        .gimbals
        .iter()
        .map(|g| {
            let session = GimbalSession::start(
                SessionConfig {
                    link: config.link.clone(),
                    address: g.address,
                    poll: config.poll,
                    lens: false,
                    // A held move runs while the page renews it, never longer.
                    max_move: config.hold_lease,
                    name: g.name.clone(),
                },
                Arc::clone(&reach),
            );
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
