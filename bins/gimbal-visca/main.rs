//! `gimbal-visca`: each configured gimbal behind gcud as a VISCA camera
//! (issue 50), for live production controllers (OBS's obs-ptz, Bitfocus
//! Companion's Sony VISCA and PTZOptics modules, vMix, joysticks): Sony
//! VISCA over IP on its own UDP port, and raw VISCA over TCP on its own
//! port when configured. Every command goes to gcud's client listener
//! over that gimbal's own session, so gcud stays the only master of the
//! buses, decides who controls each gimbal, and its dead-man stops what
//! this program started if it dies.

mod camera;
mod config;
mod framing;
mod net;
mod reply;
mod stats;
mod visca;

use std::process::ExitCode;
use std::sync::Arc;

use sagebrush_client::door::DoorSessions;
use sagebrush_service::door::Started;
use sagebrush_service::door_metrics::HeardLately;
use sagebrush_service::{Connections, Limits};
use tracing::info;

use crate::stats::Stats;

fn main() -> ExitCode {
    let door = sagebrush_client::door::with_outcomes(
        "gimbal-visca",
        "VISCA cameras (Sony VISCA over IP on UDP, raw VISCA over TCP) for the gimbals behind gcud.",
    );
    sagebrush_service::door::main(door, config::parse, run)
}

/// A UDP socket on `addr`, with SO_REUSEADDR when asked (a client on the
/// same host that binds the camera's port on every address).
fn udp_socket(addr: std::net::SocketAddr, reuse: bool) -> std::io::Result<tokio::net::UdpSocket> {
    let domain = if addr.is_ipv4() {
        socket2::Domain::IPV4
    } else {
        socket2::Domain::IPV6
    };
    let socket = socket2::Socket::new(domain, socket2::Type::DGRAM, Some(socket2::Protocol::UDP))?;
    socket.set_reuse_address(reuse)?;
    socket.set_nonblocking(true)?;
    socket.bind(&addr.into())?;
    tokio::net::UdpSocket::from_std(socket.into())
}

async fn run(config: config::Config, Started { metrics, signals }: Started) -> Result<(), String> {
    let stats = Arc::new(Stats::default());
    let door_sessions = DoorSessions::new(&config.link, config.poll);
    let clients = Arc::new(config.clients.clone());
    let lease = camera::lease(&config);
    let mut tasks = tokio::task::JoinSet::new();
    let mut sessions = Vec::new();
    let mut tables = Vec::new();
    // A controller asks its camera's position every second or so.
    let heard = Arc::new(HeardLately::new(4 * net::SOURCES, net::FORGET));
    for g in &config.gimbals {
        let session = door_sessions.start(&g.name, g.address, g.lens, lease.max(config::MAX_MOVE));
        sessions.push(Arc::clone(&session));
        let (cam, jobs) = camera::Camera::new(g.clone(), session, lease, Arc::clone(&stats), Arc::clone(&metrics));
        let udp =
            udp_socket(g.udp, g.reuse_address).map_err(|e| format!("gimbal {} visca_udp {}: {e}", g.name, g.udp))?;
        let bound = udp.local_addr().map_err(|e| e.to_string())?;
        info!(gimbal = %g.name, addr = %bound, "VISCA over IP (UDP) bound");
        tasks.spawn(net::serve_udp(
            Arc::new(udp),
            Arc::clone(&cam),
            Arc::clone(&clients),
            Arc::clone(&heard),
        ));
        if let Some(t) = g.tcp {
            let listener = tokio::net::TcpListener::bind(t)
                .await
                .map_err(|e| format!("gimbal {} visca_tcp {t}: {e}", g.name))?;
            let bound = listener.local_addr().map_err(|e| e.to_string())?;
            info!(gimbal = %g.name, addr = %bound, "raw VISCA over TCP listening");
            let table = Connections::new(Limits {
                max_total: net::MAX_CONNECTIONS,
                max_per_peer: net::MAX_PER_PEER,
                cap_loopback: false,
                idle_timeout: net::IDLE_TIMEOUT,
            });
            tables.push(Arc::clone(&table));
            tasks.spawn(net::serve_tcp(listener, Arc::clone(&cam), Arc::clone(&clients), table));
        }
        tasks.spawn(Arc::clone(&cam).work(jobs));
    }
    // Its clients: the UDP ones heard lately and the TCP connections open.
    metrics.count_sessions(move || {
        let open: u64 = tables.iter().map(|t| t.stats().open).sum();
        heard.live() + usize::try_from(open).unwrap_or(usize::MAX)
    });
    tasks.spawn(async {
        loop {
            tokio::time::sleep(sagebrush_host::throttle::WINDOW).await;
            stats::flush_warnings();
        }
    });
    info!(gimbals = sessions.len(), gcud = %config.link.gcud, lease_ms = config.lease.map(|l| l.as_millis() as u64), "gimbal-visca ready");
    let signal = signals.ready_then_wait().await;
    info!(signal, "stopping: the drives this service started are stopped");
    tasks.abort_all();
    while tasks.join_next().await.is_some() {}
    for s in &sessions {
        s.shutdown().await;
    }
    info!(counters = %stats.summary(), "stopped");
    Ok(())
}
