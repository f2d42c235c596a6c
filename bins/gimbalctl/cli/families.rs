//! Nested subcommands (presets, limits, gains, relays, lens, focus, zoom,
//! auxiliary ports, tours), `scan`'s arguments and the value enums of
//! `gimbalctl`'s command line.

use clap::{Args, Subcommand, ValueEnum};

use super::*;

#[derive(Debug, Args)]
pub struct ScanArgs {
    /// Groups whose GCU to look for (through gcud), e.g. 5, 1-254, 2,5-7; 1..=254.
    #[arg(long, default_value = "1-254", value_parser = parse_id_list, value_name = "LIST")]
    pub gcus: IdList,
    /// Ports of each GCU to sweep, e.g. 1-4; 1..=254.
    #[arg(long, default_value = "1-254", value_parser = parse_id_list, value_name = "LIST")]
    pub ports: IdList,
    /// Device IDs to ask on each port, e.g. 1-16 or 1,3,7; 1..=254. Each silent ID costs a time-out
    /// (through gcud the GCU's retries on that bus, about 0.3 s at 9600 baud), so the default is
    /// the first 8; 1-254 asks every ID.
    #[arg(long, default_value = "1-8", value_parser = parse_id_list, value_name = "LIST")]
    pub devices: IdList,
    /// On a bus (--serial, or --tcp with --direct): the GROUP.PORT the devices are addressed at, each 1..=255.
    #[arg(long, default_value = "255.255", value_parser = parse_bus, value_name = "G.P")]
    pub bus: (u8, u8),
    /// Time-out per address, milliseconds 1..=10000: ACK and result on a bus; the result through gcud (there the GCU's own retries decide that a device is silent, and an ACK waits up to --ack-timeout).
    #[arg(long, default_value_t = 300, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub timeout: u64,
    /// Pause after each query that went onto a bus, milliseconds 0..=10000 (rate limit; a GCU's
    /// own refusal, such as no such port or no route, is not followed by one).
    #[arg(long, default_value_t = 10, value_name = "MS", value_parser = clap::value_parser!(u64).range(0..=10_000))]
    pub interval: u64,
}

/// A set of IDs from `1-4,7`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdList(pub Vec<u8>);

impl std::fmt::Display for IdList {
    /// As it is written on the command line: runs as `1-4`, e.g. `1-4,7`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut ids = self.0.iter().copied().peekable();
        let mut first = true;
        while let Some(start) = ids.next() {
            let mut end = start;
            while ids.peek() == Some(&end.wrapping_add(1)) && end < u8::MAX {
                end = ids.next().unwrap_or(end);
            }
            let sep = if first { "" } else { "," };
            first = false;
            match end == start {
                true => write!(f, "{sep}{start}")?,
                false => write!(f, "{sep}{start}-{end}")?,
            }
        }
        Ok(())
    }
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum TourCmd {
    /// The configured tours and their state (~T?).
    List,
    /// Start tour NAME (~T+NAME): it runs, or waits for the link holding the gimbal.
    Start {
        /// A [[tour]] name of gcud's configuration.
        #[arg(value_parser = parse_tour_name, value_name = "NAME")]
        name: String,
    },
    /// Stop tour NAME (~T-NAME): its motion is stopped and control given back.
    Stop {
        /// A [[tour]] name of gcud's configuration.
        #[arg(value_parser = parse_tour_name, value_name = "NAME")]
        name: String,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum TlsCmd {
    /// Write a private CA, gcud's certificate and one client certificate per principal into DIR.
    #[command(after_help = "\
Writes DIR/ca.crt (the CA: gcud's `client_ca`, and every client's --tls-ca or `ca`), DIR/ca.key \
(keep it offline: it signs new principals), DIR/gcud.crt and DIR/gcud.key (gcud's `cert` and `key`, \
valid for every --host), and DIR/NAME.crt with DIR/NAME.key for each principal (the certificate's \
subject CN is NAME: add a [[principal]] of that name to gcud.toml). Keys are written 0600; existing \
files are never overwritten (run it again with another DIR, or with new principals only).

Examples:
  gimbalctl tls init --dir /etc/gcud/tls --host gcu-north.example --host 10.0.0.5 \\
      --principal gimbal-web --principal gimbal-onvif --principal gimbal-mavlink --principal alice
  gimbalctl --tcp tls://10.0.0.5:4443 --tls-ca /etc/gcud/tls/ca.crt \\
      --tls-cert /etc/gcud/tls/alice.crt --tls-key /etc/gcud/tls/alice.key --to 5.1.1 position")]
    Init {
        /// Where the files go (made if missing).
        #[arg(long, value_name = "DIR")]
        dir: std::path::PathBuf,
        /// A name or address gcud is reached by (its certificate's subject alternative names); 127.0.0.1 and localhost always.
        #[arg(long, value_name = "NAME")]
        host: Vec<String>,
        /// A person or tool to write a client certificate for (1..=32 of A-Z a-z 0-9 _ -).
        #[arg(long, value_name = "NAME", value_parser = parse_principal_name)]
        principal: Vec<String>,
    },
}

/// A principal's name, as gcud's `[[principal]] name` and a certificate's CN.
fn parse_principal_name(text: &str) -> Result<String, String> {
    match sagebrush_protocol::gcu::valid_name(text.as_bytes()) {
        true => Ok(text.to_owned()),
        false => Err(format!("{text:?}: a principal's name is 1..=32 of A-Z a-z 0-9 _ -")),
    }
}

/// A tour's name as GCU commands carry it.
fn parse_tour_name(text: &str) -> Result<String, String> {
    match sagebrush_protocol::gcu::valid_name(text.as_bytes()) {
        true => Ok(text.to_owned()),
        false => Err(format!("{text:?}: a tour name is 1..=32 of A-Z a-z 0-9 _ -")),
    }
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum PresetCmd {
    /// Store the current position as preset N (Snn).
    #[command(
        after_help = examples!("preset store 12", "preset store 0xFF   # preset 255 (SFF)")
    )]
    Store {
        /// Preset 0..=255 (decimal, or 0x00..=0xFF).
        #[arg(value_parser = parse_preset, value_name = "N")]
        n: u8,
    },
    /// Go to preset N (Pnn).
    #[command(after_help = examples!("preset recall 12 --wait"))]
    Recall {
        /// Preset 0..=255 (decimal, or 0x00..=0xFF).
        #[arg(value_parser = parse_preset, value_name = "N")]
        n: u8,
        #[command(flatten)]
        wait: WaitArgs,
    },
    /// Position of preset N (P?nn).
    #[command(after_help = examples!("preset query 12"))]
    Query {
        /// Preset 0..=255 (decimal, or 0x00..=0xFF).
        #[arg(value_parser = parse_preset, value_name = "N")]
        n: u8,
    },
    /// Position stored at preset N (S?nn).
    #[command(after_help = examples!("preset stored 12"))]
    Stored {
        /// Preset 0..=255 (decimal, or 0x00..=0xFF).
        #[arg(value_parser = parse_preset, value_name = "N")]
        n: u8,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum LimitsCmd {
    /// Set raw 12-bit limits, each 0..=4095 (Table 10; the unit is the device's).
    #[command(after_help = examples!("limits set 100 50 30 20"))]
    Set {
        /// Pan right (+, the spec's counter-clockwise) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        pan_ccw: u16,
        /// Pan left (-, the spec's clockwise) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        pan_cw: u16,
        /// Tilt up (+, the spec's counter-clockwise) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        tilt_ccw: u16,
        /// Tilt down (-, the spec's clockwise) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        tilt_cw: u16,
    },
    /// Clear the software limits (LC).
    #[command(after_help = examples!("limits clear"))]
    Clear,
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum GainsCmd {
    /// Set a rate gain (Table 7).
    #[command(after_help = examples!("gains set pan 1.5   # GRP0F"))]
    Set {
        /// pan (GRPnn) or tilt (GRTnn).
        axis: AxisArg,
        /// Rate gain 0.3..=3.0, unitless (tenths on the wire).
        #[arg(value_parser = parse_gain, value_name = "GAIN")]
        gain: f64,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum RelayCmd {
    /// Open (switch off) relay N (L0..L3).
    #[command(after_help = examples!("relay open 2   # L2"))]
    Open {
        /// Relay 0..=3.
        #[arg(value_parser = clap::value_parser!(u8).range(0..=3), value_name = "N")]
        n: u8,
    },
    /// Close (switch on) relay N (L8..LB).
    #[command(after_help = examples!("relay close 2   # LA"))]
    Close {
        /// Relay 0..=3.
        #[arg(value_parser = clap::value_parser!(u8).range(0..=3), value_name = "N")]
        n: u8,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum LensCmd {
    /// Go to zoom and focus positions (Table 17).
    #[command(after_help = examples!("lens goto 2048 100 --wait"))]
    Goto {
        /// Zoom position 0..=4095 (12 bits, the lens's own unit).
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        zoom: u16,
        /// Focus position 0..=4095 (12 bits, the lens's own unit).
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        focus: u16,
        #[command(flatten)]
        wait: WaitArgs,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum FocusCmd {
    /// Focus far, continuously (FF) until `focus stop`; see --for/--hold.
    #[command(after_help = examples!("focus far --for 500ms"))]
    Far {
        #[command(flatten)]
        jog: JogArgs,
    },
    /// Focus near, continuously (FN) until `focus stop`; see --for/--hold.
    #[command(after_help = examples!("focus near --hold"))]
    Near {
        #[command(flatten)]
        jog: JogArgs,
    },
    /// Stop focusing (FS).
    #[command(after_help = examples!("focus stop"))]
    Stop,
    /// Set the focus speed (Fn), or query it (F?) without a value.
    #[command(
        after_help = examples!("focus speed 9", "focus speed   # query (F?)")
    )]
    Speed {
        /// Speed 0..=9 (0 = slowest, 9 = fastest).
        #[arg(value_parser = clap::value_parser!(u8).range(0..=9), value_name = "N")]
        n: Option<u8>,
    },
    /// Auto-focus on (FA; "not implemented" in rev 1.9, devices answer NIC).
    #[command(after_help = examples!("focus auto-on"))]
    AutoOn,
    /// Auto-focus off (FX; "not implemented" in rev 1.9, devices answer NIC).
    #[command(after_help = examples!("focus auto-off"))]
    AutoOff,
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum ZoomCmd {
    /// Zoom in, continuously (ZI) until `zoom stop`; see --for/--hold.
    #[command(after_help = examples!("zoom in --for 1s"))]
    In {
        #[command(flatten)]
        jog: JogArgs,
    },
    /// Zoom out, continuously (ZO) until `zoom stop`; see --for/--hold.
    #[command(after_help = examples!("zoom out --hold"))]
    Out {
        #[command(flatten)]
        jog: JogArgs,
    },
    /// Stop zooming (ZS).
    #[command(after_help = examples!("zoom stop"))]
    Stop,
    /// Set the zoom speed (Zn), or query it (Z?) without a value.
    #[command(
        after_help = examples!("zoom speed 5", "zoom speed   # query (Z?)")
    )]
    Speed {
        /// Speed 0..=9 (0 = slowest, 9 = fastest).
        #[arg(value_parser = clap::value_parser!(u8).range(0..=9), value_name = "N")]
        n: Option<u8>,
    },
    /// Digital zoom step (ZA..ZF; "not implemented" in rev 1.9).
    #[command(after_help = examples!("zoom digital A"))]
    Digital {
        /// Step A..=F.
        #[arg(value_parser = parse_digital, value_name = "STEP")]
        step: u8,
    },
}

#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum AuxCmd {
    /// Line settings (Table 18).
    #[command(after_help = examples!("aux 1 configure 19200 8 1 even"))]
    Configure {
        /// Baud rate of the auxiliary port, 1..=115200 bit/s.
        baud: u32,
        /// Data bits 5..=8.
        #[arg(value_parser = clap::value_parser!(u8).range(5..=8))]
        data_bits: u8,
        /// Stop bits 1..=2.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=2))]
        stop_bits: u8,
        /// none, odd or even.
        parity: ParityArg,
    },
    /// Transmit DATA (1..=200 bytes, \xNN escapes allowed).
    #[command(after_help = examples!("aux 1 send 'ping\\x0D'"))]
    Send {
        /// Bytes to send, 1..=200 (text; \xNN for any byte).
        data: String,
    },
    /// Receive up to MAX bytes.
    #[command(after_help = examples!("aux 1 read 16"))]
    Read {
        /// Bytes 1..=256.
        #[arg(value_parser = clap::value_parser!(u16).range(1..=256))]
        max: u16,
    },
    /// Characters waiting.
    #[command(after_help = examples!("aux 1 count"))]
    Count,
    /// Drop what is waiting.
    #[command(after_help = examples!("aux 1 flush"))]
    Flush,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Direction {
    Left,
    Right,
    Up,
    Down,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum StopWhat {
    All,
    Pan,
    Tilt,
    Zoom,
    Focus,
    Motors,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum AxisArg {
    Pan,
    Tilt,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CameraState {
    On,
    Off,
    Status,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ParityArg {
    None,
    Odd,
    Even,
}
