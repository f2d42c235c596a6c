//! `simulate = [devices]` ports: a bus of simulated gimbals (`sagebrush-sim`)
//! in-process, joined to the port task by an in-memory byte pipe, so that
//! the demo and tests run the daemon exactly as on real lines.

use sagebrush_sim::{Bus, BusConfig, GimbalConfig};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::time::{Duration, Instant};
use tracing::warn;

/// Starts a simulated bus for `port` with `devices` and returns the port's end of the pipe.
pub fn spawn(port: u8, devices: &[u8]) -> DuplexStream {
    let (ours, theirs) = tokio::io::duplex(4096);
    let config = BusConfig {
        devices: devices
            .iter()
            .map(|&d| GimbalConfig {
                name: format!("sim gimbal {port}.{d}"),
                ..GimbalConfig::at(d)
            })
            .collect(),
        ..BusConfig::default()
    };
    tokio::spawn(async move {
        match Bus::new(config, 0) {
            Ok(bus) => drive(bus, theirs).await,
            Err(e) => warn!(port, error = %e, "cannot start the simulated bus"),
        }
    });
    ours
}

/// Feeds the bus what the port writes and writes back what it answers, when due.
async fn drive(mut bus: Bus, mut line: DuplexStream) {
    let epoch = Instant::now();
    let now = || epoch.elapsed().as_millis() as u64;
    let mut buf = [0u8; 1024];
    loop {
        let t = now();
        bus.poll(t);
        while let Some(out) = bus.pop_due(t) {
            if line.write_all(&out.bytes).await.is_err() {
                return;
            }
        }
        let wake = bus.next_deadline().map_or(Duration::from_secs(3600), |d| {
            Duration::from_millis(d.saturating_sub(t))
        });
        tokio::select! {
            read = line.read(&mut buf) => match read {
                Ok(0) | Err(_) => return,
                Ok(n) => bus.receive(&buf[..n], now()),
            },
            () = tokio::time::sleep(wake) => {}
        }
    }
}
