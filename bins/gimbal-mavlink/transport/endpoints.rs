//! Every configured endpoint started as its own task: the UDP endpoints
//! receive on the sockets the outbox bound (`link`), a `tcp_listen` is
//! bound here and accepts (`stream::listen`), a `tcp` connection and a
//! `serial` line are kept open with the shared back-off (`stream`).

use std::sync::Arc;

use tokio::task::JoinSet;
use tracing::info;

use crate::config::Endpoint;
use crate::stats::Stats;
use crate::transport::link::Outbox;
use crate::transport::stream::{self, Handler};

/// Starts each of `endpoints` on `tasks`, each handing what it hears to
/// `handler`. An error names the endpoint (its index in the configuration)
/// that could not start.
pub async fn start(
    endpoints: &[Endpoint],
    outbox: &Arc<Outbox>,
    stats: &Arc<Stats>,
    handler: &Handler,
    tasks: &mut JoinSet<()>,
) -> Result<(), String> {
    // The outbox bound the UDP endpoints in their configured order.
    let mut udp = 0;
    for (i, endpoint) in endpoints.iter().enumerate() {
        let (streams, stats, handler) = (Arc::clone(&outbox.streams), Arc::clone(stats), Arc::clone(handler));
        match endpoint {
            Endpoint::UdpListen(_) | Endpoint::Udp(_) => {
                let addr = outbox
                    .local_addr(udp)
                    .ok_or_else(|| format!("endpoint[{i}]: its UDP socket has no local address"))?;
                info!(endpoint = i, %addr, "MAVLink UDP endpoint bound");
                tasks.spawn(Arc::clone(outbox).receive(udp, stats, handler));
                udp += 1;
            }
            Endpoint::TcpListen(addr) => {
                let listener = tokio::net::TcpListener::bind(addr)
                    .await
                    .map_err(|e| format!("endpoint[{i}] tcp_listen {addr}: {e}"))?;
                let bound = listener.local_addr().map_err(|e| e.to_string())?;
                info!(endpoint = i, addr = %bound, "MAVLink TCP endpoint listening");
                tasks.spawn(stream::listen(listener, streams, stats, handler));
            }
            Endpoint::Tcp(to) => {
                tasks.spawn(stream::connect(to.clone(), streams, stats, handler));
            }
            Endpoint::Serial { path, baud } => {
                tasks.spawn(stream::serial(path.clone(), *baud, streams, stats, handler));
            }
        }
    }
    Ok(())
}
