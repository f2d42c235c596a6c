//! `gimbal-onvif`: an ONVIF PTZ front door in front of gcud (issue 21).
//! Each configured gimbal is its own ONVIF device (Device, Media and PTZ
//! services) on its own address and port, found by WS-Discovery; every
//! command goes to gcud's client listener over this program's own
//! connection, so gcud stays the only master of the buses.

mod auth;
mod config;
mod discovery;
mod gimbal;
mod http;
mod onvif;
mod soap;

use std::process::ExitCode;
use std::sync::Arc;

use sagebrush_service::door::Started;
use tracing::{error, info};

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-onvif",
        "ONVIF PTZ (Device, Media, PTZ) and WS-Discovery for the gimbals behind gcud.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let presets = Arc::new(sagebrush_client::presets::Presets::load(config.state_file.clone())?);
    let auth = Arc::new(auth::Authenticator::new(config.users.clone()));
    let mut gimbals = Vec::new();
    let mut served = Vec::new();
    let mut tasks = tokio::task::JoinSet::new();
    let sessions = sagebrush_client::door::DoorSessions::new(&config.link, config.poll);
    // One admission table for every gimbal's device: the caps are for all.
    let table = config.gimbals.first().map(|g| g.http.table());
    // Its clients: the connections open to its devices (ONVIF keeps no session).
    if let Some(table) = table.clone() {
        metrics.count_sessions(move || usize::try_from(table.stats().open).unwrap_or(usize::MAX));
    }
    let tls = config.tls.as_ref().map(|t| t.acceptor()).transpose()?;
    for g in &config.gimbals {
        let gimbal = gimbal::Gimbal::new(g.clone(), &config, &sessions);
        let device = onvif::Device::new(
            Arc::clone(&gimbal),
            Arc::clone(&auth),
            Arc::clone(&presets),
            Arc::clone(&metrics),
        );
        let table = Arc::clone(table.as_ref().expect("a gimbal"));
        let (bound, server) = http::bind(g.listen, device, table, tls.clone()).await.map_err(|e| {
            format!(
                "gimbal[{}] {}: cannot listen on {}: {e}",
                gimbals.len(),
                g.name,
                g.listen
            )
        })?;
        // Discovery announces where each device really listens (port 0 in tests).
        served.push(config::Gimbal {
            listen: bound,
            ..g.clone()
        });
        let name = g.name.clone();
        tasks.spawn(async move {
            if let Err(e) = server.await {
                error!(gimbal = %name, error = %e, "ONVIF server stopped");
            }
        });
        gimbals.push(gimbal);
    }
    let discovery = match config.discovery {
        Some(listen) => {
            let d = discovery::Discovery::bind(listen, served)
                .await
                .map_err(|e| format!("discovery.listen {listen}: {e}"))?;
            info!(addr = %d.local_addr().map_err(|e| e.to_string())?, "WS-Discovery listening");
            Some(Arc::new(d))
        }
        None => None,
    };
    if let Some(d) = &discovery {
        d.announce(true).await;
        let d = Arc::clone(d);
        tasks.spawn(async move { d.run().await });
    }
    info!(gimbals = gimbals.len(), gcud = %config.link.gcud, "gimbal-onvif ready");
    let signal = signals.ready_then_wait().await;
    info!(
        signal,
        "stopping: the motions this service started are stopped, then Bye"
    );
    for g in &gimbals {
        g.shutdown().await;
    }
    if let Some(d) = &discovery {
        d.announce(false).await;
    }
    tasks.abort_all();
    Ok(())
}
