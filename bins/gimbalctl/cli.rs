//! Command line of `gimbalctl`: transport, addressing, time-outs, and one
//! subcommand per command family of Tables 4, 11 and 16 and the rev 1.9 list.

use clap::{Args, Parser, Subcommand, ValueEnum};
use sagebrush_protocol::{Address, DataRate};

pub const EXIT_CODES: &str = "\
Exit codes:
  0  success
  1  I/O error (cannot open the serial port or connect, the line closed)
  2  bad arguments
  3  NAK after all retries (the command kept arriving damaged)
  4  no ACK after all retries (nothing answered)
  5  NIC: the device does not implement or cannot apply the command
  6  no result: ACKed, but the result did not come in time
  7  malformed result: a result came that is not the command's
  8..19  not delivered, as a GCU reported it (no ACK came; through gcud only):
      8 device silent after all retries    9 device answered NAK to every try
     10 no such port on the GCU           11 port not open
     12 a queue on the way was full       13 no route to the group
     14 link toward the group down        15 the GCU is shutting down
     16 source group not allowed (--from) 17 routing loop
     18 not confirmed in time (may still execute)
     19 waited in a queue too long, given up unsent
  Commands to device 255 get no ACK on a shared bus: success means written.";

/// Command Sagebrush pan-tilt gimbals (protocol rev 1.9) by hand.
///
/// Talks to a bus directly (--serial, as bus master) or to a GCU daemon
/// (--tcp, as a client like the MCU). Angles are degrees (positive =
/// counter-clockwise: pan right, tilt up), rates degrees per second.
#[derive(Debug, Parser)]
#[command(name = "gimbalctl", version, after_help = EXIT_CODES, after_long_help = EXIT_CODES)]
pub struct Cli {
    #[command(flatten)]
    pub global: Global,
    #[command(subcommand)]
    pub command: Cmd,
}

#[derive(Debug, Args)]
pub struct Global {
    /// Serial device of the bus (this program is its master).
    #[arg(
        long,
        global = true,
        env = "GIMBALCTL_SERIAL",
        conflicts_with = "tcp",
        value_name = "PATH"
    )]
    pub serial: Option<String>,
    /// Line rate of --serial in bit/s.
    #[arg(long, global = true, default_value_t = 9600, value_parser = parse_baud)]
    pub baud: u32,
    /// A GCU daemon's link address (this program is a client like the MCU).
    #[arg(long, global = true, env = "GIMBALCTL_TCP", value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// Destination GROUP.PORT.DEVICE (255 = wildcard at any level).
    #[arg(long, global = true, default_value = "1.1.1", value_parser = parse_address, value_name = "G.P.D")]
    pub to: Address,
    /// Source group address (0 = the MCU).
    #[arg(long, global = true, default_value_t = 0, value_name = "G")]
    pub from: u8,
    /// Print JSON (one object per line) instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    /// Retransmissions after the first (default 3).
    #[arg(long, global = true)]
    pub retries: Option<u8>,
    /// Wait for ACK/NAK, milliseconds (default derived from --baud; 1000 over TCP).
    #[arg(long, global = true, value_name = "MS")]
    pub ack_timeout: Option<u64>,
    /// Wait for a result after the ACK, milliseconds (default derived from --baud; 5000 over TCP).
    #[arg(long, global = true, value_name = "MS")]
    pub result_timeout: Option<u64>,
    /// Wait for a NIC after the ACK of a command without result, milliseconds.
    #[arg(long, global = true, value_name = "MS")]
    pub nic_window: Option<u64>,
    /// Wait for the IX initialisation result, milliseconds (default 60000).
    #[arg(long, global = true, value_name = "MS")]
    pub init_timeout: Option<u64>,
    /// Log filter for diagnostics on stderr (RUST_LOG syntax).
    #[arg(long, global = true, default_value = "warn")]
    pub log: String,
}

#[derive(Debug, Subcommand)]
pub enum Cmd {
    /// Current pan/tilt position (P?).
    Position,
    /// Go to an absolute position in degrees (Paaaaeeee).
    #[command(allow_negative_numbers = true)]
    Goto {
        /// Pan, degrees (-327.68..327.67, + = counter-clockwise).
        #[arg(value_parser = parse_degrees)]
        pan: f64,
        /// Tilt, degrees (+ = up).
        #[arg(value_parser = parse_degrees)]
        tilt: f64,
        /// Poll the position until the mount stops, and report where.
        #[arg(long)]
        wait: bool,
        /// Give up waiting after this many milliseconds.
        #[arg(long, default_value_t = 60_000, value_name = "MS")]
        wait_timeout: u64,
    },
    /// Presets 00..FF (Snn, Pnn, P?nn, S?nn).
    #[command(subcommand)]
    Preset(PresetCmd),
    /// Slew continuously until `stop` (PL, PR, TU, TD).
    Slew { direction: Direction },
    /// Stop: motion (PT, default), one axis (PS, TS) or the motors (HS).
    Stop {
        #[arg(default_value = "all")]
        what: StopWhat,
    },
    /// Halt: stop dead, store the position for recall-halt, motors off (HA).
    Halt,
    /// Go back to the position saved by halt (HP; VP with --lens).
    RecallHalt {
        /// The lens position instead (VP).
        #[arg(long)]
        lens: bool,
    },
    /// Proportional speed 0..15 (0..F) for pan or tilt moves (SPn, STn).
    Speed {
        axis: AxisArg,
        #[arg(value_parser = parse_speed)]
        speed: u8,
    },
    /// Query (R?, RP?, RT?) or set (RPnnnn, RTnnnn) discrete rates, degrees per second.
    Rate {
        axis: Option<AxisArg>,
        #[arg(requires = "axis", value_parser = parse_rate)]
        value: Option<f64>,
    },
    /// Query (A?, AP?, AT?) or set (APnnnn, ATnnnn) accelerations, degrees per second squared.
    Accel {
        axis: Option<AxisArg>,
        #[arg(requires = "axis", value_parser = parse_rate)]
        value: Option<f64>,
    },
    /// Vector moves: both axes arrive together (VM1 / VM0).
    Vector { state: OnOff },
    /// Go home, pan 0 tilt 0 (HO).
    Home,
    /// Verify home (HV, Table 14).
    VerifyHome,
    /// Run the initialisation sequence and report Table 9 (IX).
    Init,
    /// Software limits: query (L?), set raw 12-bit values (LS) or clear (LC).
    Limits {
        #[command(subcommand)]
        action: Option<LimitsCmd>,
    },
    /// Rate gains: query (G?) or set 0.3..3.0 (GRPnn, GRTnn).
    Gains {
        #[command(subcommand)]
        action: Option<GainsCmd>,
    },
    /// Auxiliary relays 0..3: status (LR), open (L0..L3), close (L8..LB).
    Relay {
        #[command(subcommand)]
        action: Option<RelayCmd>,
    },
    /// Lens position: query (V?) or go to zoom/focus 0..4095 (Vzzzfff).
    Lens {
        #[command(subcommand)]
        action: Option<LensCmd>,
    },
    /// Camera and lens power (CN, CX) or camera/relay status (VS).
    Camera { state: CameraState },
    /// Focus: far, near, stop, speed 0..9, auto on/off (FF, FN, FS, Fn, F?, FA, FX).
    Focus {
        #[command(subcommand)]
        action: FocusCmd,
    },
    /// Zoom: in, out, stop, speed 0..9, digital A..F (ZI, ZO, ZS, Zn, Z?, ZA..ZF).
    Zoom {
        #[command(subcommand)]
        action: ZoomCmd,
    },
    /// Identification block (D?, Table 6).
    Id,
    /// Awake status (AW, Table 5).
    Status,
    /// Error codes (E?, Table 6A).
    Errors,
    /// Status bits (I?, Table 6B).
    StatusBits,
    /// Maximum data rate (B?) or switch the device's rate (C0..C7).
    DataRate {
        /// New rate in bit/s (1200 .. 115200).
        #[arg(value_parser = parse_baud)]
        bps: Option<u32>,
    },
    /// Program the device's address (#NN); best with only one device on the bus.
    SetAddress {
        #[arg(value_parser = clap::value_parser!(u8).range(1..=254))]
        id: u8,
    },
    /// Auxiliary serial port 0 or 1 (*xpc, *xpt, *xpr, *xpn, *xpf).
    Aux {
        #[arg(value_parser = clap::value_parser!(u8).range(0..=1))]
        port: u8,
        #[command(subcommand)]
        action: AuxCmd,
    },
    /// Send any payload (\xNN escapes allowed) and show what comes back.
    Raw { payload: String },
    /// Poll position and lens and keep one live line (JSON: one object per sample).
    Watch {
        /// Samples per second.
        #[arg(long, default_value_t = 4.0)]
        rate: f64,
        /// Stop after this many samples (default: until interrupted).
        #[arg(long)]
        count: Option<u64>,
    },
    /// Print the frame for PAYLOAD as hex bytes (no I/O).
    Encode { payload: String },
    /// Decode hex bytes (arguments or stdin) into framer events (no I/O).
    Decode { hex: Vec<String> },
}

#[derive(Debug, Subcommand)]
pub enum PresetCmd {
    /// Store the current position as preset N (Snn).
    Store {
        #[arg(value_parser = parse_preset)]
        n: u8,
    },
    /// Go to preset N (Pnn).
    Recall {
        #[arg(value_parser = parse_preset)]
        n: u8,
    },
    /// Position of preset N (P?nn).
    Query {
        #[arg(value_parser = parse_preset)]
        n: u8,
    },
    /// Position stored at preset N (S?nn).
    Stored {
        #[arg(value_parser = parse_preset)]
        n: u8,
    },
}

#[derive(Debug, Subcommand)]
pub enum LimitsCmd {
    /// Set raw 12-bit limits 0..4095 (Table 10; the unit is the device's).
    Set {
        pan_ccw: u16,
        pan_cw: u16,
        tilt_ccw: u16,
        tilt_cw: u16,
    },
    /// Clear the software limits (LC).
    Clear,
}

#[derive(Debug, Subcommand)]
pub enum GainsCmd {
    /// Set a rate gain 0.3..3.0 (Table 7).
    Set {
        axis: AxisArg,
        #[arg(value_parser = parse_gain)]
        gain: f64,
    },
}

#[derive(Debug, Subcommand)]
pub enum RelayCmd {
    /// Open (switch off) relay N (L0..L3).
    Open {
        #[arg(value_parser = clap::value_parser!(u8).range(0..=3))]
        n: u8,
    },
    /// Close (switch on) relay N (L8..LB).
    Close {
        #[arg(value_parser = clap::value_parser!(u8).range(0..=3))]
        n: u8,
    },
}

#[derive(Debug, Subcommand)]
pub enum LensCmd {
    /// Go to zoom and focus positions 0..4095 (Table 17).
    Goto {
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        zoom: u16,
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        focus: u16,
    },
}

#[derive(Debug, Subcommand)]
pub enum FocusCmd {
    Far,
    Near,
    Stop,
    /// Set the speed 0..9 (Fn), or query it (F?) without a value.
    Speed {
        #[arg(value_parser = clap::value_parser!(u8).range(0..=9))]
        n: Option<u8>,
    },
    AutoOn,
    AutoOff,
}

#[derive(Debug, Subcommand)]
pub enum ZoomCmd {
    In,
    Out,
    Stop,
    /// Set the speed 0..9 (Zn), or query it (Z?) without a value.
    Speed {
        #[arg(value_parser = clap::value_parser!(u8).range(0..=9))]
        n: Option<u8>,
    },
    /// Digital zoom step A..F.
    Digital {
        #[arg(value_parser = parse_digital)]
        step: u8,
    },
}

#[derive(Debug, Subcommand)]
pub enum AuxCmd {
    /// Line settings (Table 18).
    Configure {
        baud: u32,
        #[arg(value_parser = clap::value_parser!(u8).range(5..=8))]
        data_bits: u8,
        #[arg(value_parser = clap::value_parser!(u8).range(1..=2))]
        stop_bits: u8,
        parity: ParityArg,
    },
    /// Transmit DATA (1..200 bytes, \xNN escapes allowed).
    Send { data: String },
    /// Receive up to MAX bytes (1..256).
    Read {
        #[arg(value_parser = clap::value_parser!(u16).range(1..=256))]
        max: u16,
    },
    /// Characters waiting.
    Count,
    /// Drop what is waiting.
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

fn parse_address(text: &str) -> Result<Address, String> {
    text.parse::<Address>().map_err(|e| format!("{text:?}: {e}"))
}

pub fn parse_baud(text: &str) -> Result<u32, String> {
    let bps: u32 = text.parse().map_err(|_| format!("{text:?} is not a number of bit/s"))?;
    DataRate::from_bits_per_second(bps).map(|_| bps).ok_or_else(|| {
        format!("{bps} bit/s is not a protocol rate (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)")
    })
}

fn parse_degrees(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number of degrees"))?;
    if (-327.68..=327.67).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} degrees is out of range -327.68..=327.67"))
    }
}

fn parse_rate(text: &str) -> Result<f64, String> {
    let v: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    if (0.0..=655.35).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{v} is out of range 0..=655.35 (hundredths on the wire, 16 bits)"
        ))
    }
}

fn parse_gain(text: &str) -> Result<f64, String> {
    let v: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    if (0.3..=3.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("rate gain {v} is out of range 0.3..=3.0"))
    }
}

/// 0..15, as a decimal number or one hex digit (`F`).
fn parse_speed(text: &str) -> Result<u8, String> {
    let v = match text.parse::<u8>() {
        Ok(v) => v,
        Err(_) if text.len() == 1 => u8::from_str_radix(text, 16).map_err(|_| format!("{text:?} is not a speed"))?,
        Err(_) => return Err(format!("{text:?} is not a speed 0..15 (or 0..F)")),
    };
    if v <= 15 {
        Ok(v)
    } else {
        Err(format!("speed {v} is out of range 0..=15"))
    }
}

/// 0..255 decimal, or hex with a `0x` prefix (presets are `00..FF` on the wire).
fn parse_preset(text: &str) -> Result<u8, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u8::from_str_radix(hex, 16),
        None => text.parse(),
    };
    parsed.map_err(|_| format!("preset {text:?} is not 0..255 (or 0x00..0xFF)"))
}

fn parse_digital(text: &str) -> Result<u8, String> {
    match text {
        "A" | "B" | "C" | "D" | "E" | "F" | "a" | "b" | "c" | "d" | "e" | "f" => {
            u8::from_str_radix(text, 16).map_err(|e| e.to_string())
        }
        _ => Err(format!("digital zoom step {text:?} is not one of A..F")),
    }
}
