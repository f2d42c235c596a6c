//! `simulate = [devices]` ports: a bus of simulated gimbals (`sagebrush-sim`)
//! in-process, served by the same loop as `gimbalsim`
//! ([`sagebrush_host::sim_line`]) on an in-memory byte pipe, so that the demo and
//! tests run the daemon exactly as on real lines.

use sagebrush_host::sim_line::{LineClock, serve};
use sagebrush_sim::{Bus, BusConfig, GimbalConfig};
use tokio::io::DuplexStream;
use tokio::time::{Duration, Instant};
use tracing::warn;

/// Starts a simulated bus for `port` with `devices` at `baud`; returns the port's end of the pipe.
pub fn spawn(port: u8, devices: &[u8], baud: u32) -> DuplexStream {
    let (ours, mut theirs) = tokio::io::duplex(4096);
    let config = BusConfig {
        devices: devices
            .iter()
            .map(|&d| GimbalConfig {
                name: format!("sim gimbal {port}.{d}"),
                // Distinct per gimbal, as real units are (Table 6: at most 20 characters).
                serial: format!("SIM-{port}.{d}"),
                ..GimbalConfig::at(d)
            })
            .collect(),
        ..BusConfig::default()
    };
    tokio::spawn(async move {
        let mut bus = match Bus::new(config, 0) {
            Ok(bus) => bus,
            Err(e) => return warn!(port, error = %e, "cannot start the simulated bus"),
        };
        // A pipe has no line rate to switch; the bus runs until the port's end closes.
        let mut line = LineClock {
            epoch: Instant::now(),
            pace: false,
            baud,
            reply_delay: Duration::ZERO,
        };
        let mut never = Box::pin(std::future::pending()) as sagebrush_host::sim_line::Shutdown;
        if let Err(e) = serve(&mut bus, &mut theirs, &mut line, &mut |_, _| Ok(()), &mut never).await {
            warn!(port, error = %e, "simulated bus stopped");
        }
    });
    ours
}
