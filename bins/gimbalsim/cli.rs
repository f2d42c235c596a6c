//! Command line of `gimbalsim`: where the bus is attached, the gimbals on
//! it, line pacing and fault injection.

use std::net::SocketAddr;

use clap::{ArgGroup, Parser};
use sagebrush_host::transport::parse_baud;
use sagebrush_protocol::DataRate;
use sagebrush_service::endpoint::listen_arg;
use sagebrush_sim::{BusConfig, FaultConfig, GimbalConfig};

/// A bus of virtual Sagebrush pan-tilt gimbals speaking protocol rev 1.9.
///
/// Prints where it is attached as the first line of standard output (the
/// pseudo-terminal path, the bound TCP address or the serial device), then
/// serves until interrupted; on SIGINT/SIGTERM it prints one line of JSON
/// statistics (`stats {...}`) and exits 0. Every frame in and out is logged
/// on standard error.
#[derive(Debug, Parser)]
#[command(name = "gimbalsim", version, group(ArgGroup::new("attach").args(["pty", "tcp", "serial"])))]
pub struct Cli {
    /// Attach to a new pseudo-terminal (the default).
    #[arg(long)]
    pub pty: bool,
    /// Also make a symlink PATH to the pseudo-terminal (removed on exit).
    #[arg(long, value_name = "PATH", conflicts_with_all = ["tcp", "serial"])]
    pub link: Option<std::path::PathBuf>,
    /// Listen on a TCP address instead (one client at a time), e.g. 127.0.0.1:0.
    #[arg(long, value_name = "IP:PORT", num_args = 0..=1, default_missing_value = "127.0.0.1:0", value_parser = listen_arg)]
    pub tcp: Option<SocketAddr>,
    /// Attach to an existing serial device.
    #[arg(long, value_name = "PATH")]
    pub serial: Option<String>,
    /// Record every byte of the bus line (both ways, timed) to FILE as pcapng for Wireshark with tools/wireshark/sagebrush.lua (docs/capture.md); complete when gimbalsim exits.
    #[arg(long, value_name = "FILE")]
    pub capture: Option<std::path::PathBuf>,
    /// Line rate in bit/s: opens a serial device at it and paces with --pace.
    #[arg(long, default_value_t = 9600, value_parser = parse_baud)]
    pub baud: u32,
    /// Pace bytes at the line rate (a pty or TCP delivers at once; a real line does not).
    #[arg(long)]
    pub pace: bool,
    /// With --pace: microseconds from a command's last byte to the first
    /// byte of its answer (the device's turnaround).
    #[arg(long, value_name = "US", default_value_t = 20)]
    pub reply_delay_us: u64,

    /// Device addresses on the bus (1..=254), comma separated or repeated.
    #[arg(long = "device", value_name = "N", value_delimiter = ',', default_value = "1",
          value_parser = clap::value_parser!(u8).range(1..=254))]
    pub devices: Vec<u8>,
    /// Group address the devices know (default: accept any).
    #[arg(long)]
    pub group: Option<u8>,
    /// Port address the devices know (default: accept any).
    #[arg(long)]
    pub port: Option<u8>,
    /// Device name in the ID block (Table 6, at most 20 characters).
    #[arg(long, default_value = "Sagebrush SIM")]
    pub name: String,
    /// Serial number in the ID block (Table 6); with several devices "-<address>" is appended.
    #[arg(long = "serial-number", default_value = "SIM-0001")]
    pub serial_number: String,
    /// Duration of the IX initialisation sequence, milliseconds.
    #[arg(long, default_value_t = 3000)]
    pub init_ms: u64,
    /// Start uninitialised (Table 5 bits 0 and 1 set until IX).
    #[arg(long)]
    pub uninitialized: bool,
    /// Presets implemented (1..=256); higher numbers answer NIC.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub presets: u16,
    /// A preset never stored (`Snn`) answers NIC to its query and recall
    /// (as some units do); by default every implemented preset starts at home.
    #[arg(long)]
    pub unset_presets_nic: bool,
    /// Fastest rate (proportional speed F), degrees per second.
    #[arg(long, default_value_t = 120.0)]
    pub max_rate: f64,
    /// Initial discrete rate, degrees per second.
    #[arg(long, default_value_t = 60.0)]
    pub rate: f64,
    /// Initial acceleration, degrees per second squared.
    #[arg(long, default_value_t = 120.0)]
    pub accel: f64,
    /// Degrees per count of a Table 10 software limit (the protocol gives no unit).
    #[arg(long, default_value_t = 0.1)]
    pub limit_unit: f64,
    /// Highest data rate the devices support (B?), bit/s.
    #[arg(long, default_value_t = 115_200, value_parser = parse_baud)]
    pub max_baud: u32,
    /// Lens end-to-end travel time at speed 9, milliseconds.
    #[arg(long, default_value_t = 2000)]
    pub lens_travel_ms: u64,
    /// Start with camera and lens power off.
    #[arg(long)]
    pub camera_off: bool,
    /// Delay between an ACK and its result frame, milliseconds.
    #[arg(long, default_value_t = 0)]
    pub latency_ms: u64,

    /// Seed of the fault generator.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Probability per command that its ACK is lost.
    #[arg(long, default_value_t = 0.0, value_parser = parse_probability)]
    pub drop_ack: f64,
    /// Probability per command that it arrives damaged (the device NAKs).
    #[arg(long, default_value_t = 0.0, value_parser = parse_probability)]
    pub nak: f64,
    /// Probability per command that a byte of its answer is damaged.
    #[arg(long, default_value_t = 0.0, value_parser = parse_probability)]
    pub corrupt: f64,
    /// Probability per command that its answer is late by --delay-ms.
    #[arg(long, default_value_t = 0.0, value_parser = parse_probability)]
    pub delay: f64,
    /// How late a delayed answer is, milliseconds.
    #[arg(long, default_value_t = 500)]
    pub delay_ms: u64,
    /// Probability per command that the device does not hear it.
    #[arg(long, default_value_t = 0.0, value_parser = parse_probability)]
    pub silent: f64,
    /// Stop injecting after this many faults.
    #[arg(long)]
    pub max_faults: Option<u64>,

    /// Log filter (RUST_LOG syntax); RUST_LOG wins when set. The default shows every frame
    /// (the bus's frame lines are DEBUG, so that gcud's simulated ports keep them out of INFO).
    #[arg(long, default_value = "info,sagebrush_sim=debug")]
    pub log: String,
    /// Log as JSON lines.
    #[arg(long)]
    pub log_json: bool,
}

fn parse_probability(text: &str) -> Result<f64, String> {
    let p: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        Err(format!("probability {p} is not within 0..=1"))
    }
}

/// Degrees (per second) to the wire's hundredths, refusing what 16 bits cannot carry.
fn centi(what: &str, value: f64) -> Result<u16, String> {
    let c = (value * 100.0).round();
    if (1.0..=65535.0).contains(&c) {
        Ok(c as u16)
    } else {
        Err(format!("{what} {value} is out of range 0.01..=655.35"))
    }
}

impl Cli {
    /// The bus this command line describes; names the first bad setting.
    pub fn bus_config(&self) -> Result<BusConfig, String> {
        let max_data_rate = DataRate::from_bits_per_second(self.max_baud).ok_or("bad --max-baud")?;
        let mut devices = Vec::new();
        for &device in &self.devices {
            let serial = if self.devices.len() > 1 {
                format!("{}-{device}", self.serial_number)
            } else {
                self.serial_number.clone()
            };
            devices.push(GimbalConfig {
                device,
                group: self.group,
                port: self.port,
                name: self.name.clone(),
                serial,
                revision: *b"19",
                init_ms: self.init_ms,
                start_initialized: !self.uninitialized,
                presets: self.presets,
                unset_presets_nic: self.unset_presets_nic,
                max_rate: centi("--max-rate", self.max_rate)?,
                rate: centi("--rate", self.rate)?,
                accel: centi("--accel", self.accel)?,
                pan_range: (-18000, 18000),
                tilt_range: (-9000, 9000),
                limit_unit: centi("--limit-unit", self.limit_unit)?,
                max_data_rate,
                lens_travel_ms: self.lens_travel_ms,
                camera_on: !self.camera_off,
            });
        }
        Ok(BusConfig {
            devices,
            faults: FaultConfig {
                seed: self.seed,
                drop_ack: self.drop_ack,
                nak: self.nak,
                corrupt: self.corrupt,
                delay: self.delay,
                silent: self.silent,
                delay_ms: self.delay_ms,
                max_faults: self.max_faults,
            },
            reply_latency_ms: self.latency_ms,
            ..BusConfig::default()
        })
    }
}
