//! The simulator's I/O: a pseudo-terminal, TCP listener or serial device
//! around the sans-IO [`Bus`], a millisecond clock, optional pacing at the
//! line rate with a device turnaround (`--reply-delay-us`), data-rate switches (Table 4 `C0..C7`) and shutdown.

use std::io;

use sagebrush_host::capture::{CaptureSwitch, Role, Tapped, capture_to};
use sagebrush_host::pty::{PtyMaster, Symlink};
use sagebrush_host::sim_line::{End, LineClock, Shutdown, serve};
use sagebrush_host::transport;
use sagebrush_sim::{Bus, BusConfig, Fault};
use tokio::net::TcpListener;
use tokio::time::{Duration, Instant};
use tracing::{info, warn};

use crate::cli::Cli;

/// Resolves on SIGINT or SIGTERM.
fn shutdown_signal() -> io::Result<Shutdown> {
    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
    Ok(Box::pin(async move {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = term.recv() => {}
        }
    }))
}

/// Prints the bus counters as one `stats {json}` line on stdout.
fn print_stats(bus: &Bus) {
    let s = bus.stats();
    let faults: serde_json::Map<String, serde_json::Value> = Fault::ALL
        .iter()
        .map(|f| (f.name().to_string(), bus.faults_injected(*f).into()))
        .collect();
    let stats = serde_json::json!({
        "frames_in": s.frames_in,
        "frames_ignored": s.frames_ignored,
        "bad_checksums_in": s.bad_checksums_in,
        "naks_sent": s.naks_sent,
        "naks_in": s.naks_in,
        "acks_in": s.acks_in,
        "results_resent": s.results_resent,
        "noise_bytes": bus.noise_bytes(),
        "faults": faults,
    });
    sagebrush_host::outln!("stats {stats}");
}

/// Runs the simulator as the command line says.
pub async fn run(cli: Cli, config: BusConfig) -> Result<(), String> {
    let epoch = Instant::now();
    let mut bus = Bus::new(config, 0)?;
    let mut shutdown = shutdown_signal().map_err(|e| format!("cannot install signal handlers: {e}"))?;
    let mut line = LineClock {
        epoch,
        pace: cli.pace,
        baud: cli.baud,
        reply_delay: Duration::from_micros(cli.reply_delay_us),
    };
    // A capture file that cannot be written is refused before the bus starts.
    let (switch, capture) = match &cli.capture {
        Some(path) => {
            let (switch, capture) = capture_to(path, "gimbalsim")
                .map_err(|e| format!("--capture {}: cannot write it: {e}", path.display()))?;
            (switch, Some(capture))
        }
        None => (CaptureSwitch::new(), None),
    };
    let addresses: Vec<String> = bus.gimbals().map(|g| g.device().to_string()).collect();
    let result = if let Some(addr) = &cli.tcp {
        let listener = TcpListener::bind(*addr)
            .await
            .map_err(|e| format!("cannot listen on {addr}: {e}"))?;
        let local = listener.local_addr().map_err(|e| e.to_string())?;
        announce(&local.to_string());
        info!(%local, devices = addresses.join(", "), "gimbalsim listening");
        loop {
            let accepted = tokio::select! {
                a = listener.accept() => a,
                _ = shutdown.as_mut() => break Ok(()),
            };
            let (stream, peer) = accepted.map_err(|e| format!("accept on {local}: {e}"))?;
            let _ = stream.set_nodelay(true);
            let mut stream = Tapped::new(stream, switch.tap(format!("gimbalsim tcp {peer}"), Role::Responder));
            info!(%peer, "client connected");
            match serve(&mut bus, &mut stream, &mut line, &mut |_, _| Ok(()), &mut shutdown).await {
                Ok(End::Eof) => info!(%peer, "client disconnected"),
                Ok(End::Shutdown) => break Ok(()),
                Err(e) => warn!(%peer, error = %e, "client connection failed"),
            }
        }
    } else if let Some(path) = &cli.serial {
        let port = transport::open_serial(path, cli.baud).map_err(|e| e.to_string())?;
        let mut port = Tapped::new(port, switch.tap(format!("gimbalsim serial {path}"), Role::Responder));
        announce(path);
        info!(
            path,
            baud = cli.baud,
            devices = addresses.join(", "),
            "gimbalsim on serial device"
        );
        let mut set_rate = |p: &mut Tapped<tokio_serial::SerialStream>, bps: u32| transport::set_baud(p.get_mut(), bps);
        match serve(&mut bus, &mut port, &mut line, &mut set_rate, &mut shutdown).await {
            Ok(End::Eof) => Err(format!("serial device {path} closed")),
            Ok(End::Shutdown) => Ok(()),
            Err(e) => Err(format!("serial device {path}: {e}")),
        }
    } else {
        let pty = PtyMaster::open().map_err(|e| e.to_string())?;
        let path = pty.slave_path().to_path_buf();
        let tap = switch.tap(format!("gimbalsim pty {}", path.display()), Role::Responder);
        let mut pty = Tapped::new(pty, tap);
        let _link = match &cli.link {
            Some(link) => Some(Symlink::create(&path, link).map_err(|e| e.to_string())?),
            None => None,
        };
        announce(&path.display().to_string());
        info!(path = %path.display(), devices = addresses.join(", "), "gimbalsim on pseudo-terminal");
        match serve(&mut bus, &mut pty, &mut line, &mut |_, _| Ok(()), &mut shutdown).await {
            Ok(End::Eof) => Err("the pseudo-terminal closed".into()),
            Ok(End::Shutdown) => Ok(()),
            Err(e) => Err(format!("pseudo-terminal {}: {e}", path.display())),
        }
    };
    if let Some(capture) = capture {
        let stats = capture.stop(Duration::from_secs(2));
        info!(records = stats.records, bytes = stats.bytes_written, "capture stopped");
    }
    print_stats(&bus);
    result
}

/// The first line of standard output: where clients attach.
fn announce(what: &str) {
    sagebrush_host::outln!("{what}");
}
