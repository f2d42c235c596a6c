//! Command line of `gimbalctl`: transport, addressing, time-outs, and one
//! subcommand per command family of Tables 4, 11 and 16 and the rev 1.9 list.
//! Every argument names its unit and range; every subcommand has examples.

use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};
use sagebrush_host::transport::parse_baud;
use sagebrush_protocol::Address;

/// A subcommand's examples for its `after_help`: one `gimbalctl` line per
/// argument; a bare line talks to the demo's first gimbal through gcud
/// (`--tcp 127.0.0.1:4001 --to 5.1.1`), a line after `gimbalctl` is
/// written out whole.
macro_rules! examples {
    (@lines $(,)?) => { "" };
    (@lines gimbalctl $line:literal $(, $($rest:tt)*)?) => {
        concat!("\n  gimbalctl ", $line, examples!(@lines $($($rest)*)?))
    };
    (@lines $line:literal $(, $($rest:tt)*)?) => {
        concat!("\n  gimbalctl --tcp 127.0.0.1:4001 --to 5.1.1 ", $line, examples!(@lines $($($rest)*)?))
    };
    ($($line:tt)+) => {
        concat!("Examples:", examples!(@lines $($line)+))
    };
}

/// Exit code: `--wait` saw the mount stop away from its target.
pub const EXIT_STOPPED_SHORT: u8 = 20;
/// Exit code: `--wait` gave up while the mount was still moving.
pub const EXIT_WAIT_TIMEOUT: u8 = 21;
/// Exit code: the stop after `--for`/`--hold` was not acknowledged.
pub const EXIT_STOP_UNCONFIRMED: u8 = 22;

pub const EXIT_CODES: &str = "\
Exit codes:
   0  success
   1  I/O error: cannot open the serial port or connect, the line closed
   2  bad arguments (the message names the argument and its range)
   3  NAK after all retries (the command kept arriving damaged)
   4  no ACK after all retries (nothing answered; scan: no GCU or device answered D?)
   5  NIC: the device does not implement or cannot apply the command
   6  no result: acknowledged, but the result did not come in time
   7  malformed result: a result came that is not the command's
   8..19, 23..26  not delivered or refused, as the GCU reported it (through gcud):
       8 device silent (did not acknowledge)   9 device answered NAK to every try
      10 no such port on the GCU              11 port not open (port down)
      12 a queue on the way was full          13 no route to the group
      14 link toward the group down           15 the GCU is shutting down
      16 source group not allowed (--from)    17 routing loop
      18 not confirmed in time (may still execute)
      19 waited in a queue too long, given up unsent
      23 refused: another link of equal or higher priority controls the gimbal
      24 refused: the target lies outside the gimbal's travel limits
      25 refused: the path may enter a keep-out zone
      26 refused: the gimbal's position is unknown and it has limits or zones
  20  --wait: the mount stopped short of its target (limits? travel?)
  21  --wait: still moving when --wait-timeout ran out
  22  --for/--hold: the stop was not acknowledged (the mount may still move)
 130, 143  interrupted by SIGINT, SIGTERM (--capture: the file completed first; scan: what it
       found so far printed)
  Commands to device 255 get no ACK on a shared bus: success means written.";

/// Command Sagebrush pan-tilt gimbals (protocol rev 1.9) by hand.
///
/// Talks to a bus directly (--serial, as bus master) or to a GCU daemon
/// (--tcp, as a client like the MCU). Angles are degrees (positive =
/// counter-clockwise: pan right, tilt up), rates degrees per second. Every
/// command to a device needs --to GROUP.PORT.DEVICE.
#[derive(Debug, Parser)]
#[command(
    name = "gimbalctl",
    version,
    after_help = concat!(examples!("goto 45 -10 --wait", "slew right --for 2s", gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 position", gimbalctl "--tcp 127.0.0.1:4001 scan --devices 1-8"), "\n\nRun `gimbalctl help <SUBCOMMAND>` for a subcommand's arguments and examples."),
    after_long_help = EXIT_CODES
)]
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
        value_name = "PATH",
        help_heading = "Connection (global)"
    )]
    pub serial: Option<String>,
    /// Line rate of --serial in bit/s: 1200, 2400, 4800, 9600, 19200, 38400, 57600 or 115200.
    #[arg(long, global = true, default_value_t = 9600, value_parser = parse_baud, help_heading = "Connection (global)")]
    pub baud: u32,
    /// A GCU daemon's client address HOST:PORT, e.g. 127.0.0.1:4001 (this program is a client like the MCU).
    #[arg(long, global = true, env = "GIMBALCTL_TCP", value_name = "HOST:PORT", value_parser = parse_host_port, help_heading = "Connection (global)")]
    pub tcp: Option<String>,
    /// Destination GROUP.PORT.DEVICE, each 0..255 (255 = wildcard at that level). Required by every command to a device.
    #[arg(long, global = true, value_parser = parse_address, value_name = "G.P.D", help_heading = "Addressing (global)")]
    pub to: Option<Address>,
    /// Source group address 0..254 (0 = the MCU).
    #[arg(
        long,
        global = true,
        default_value_t = 0,
        value_name = "G",
        help_heading = "Addressing (global)"
    )]
    pub from: u8,
    /// Record every byte of the line (both ways, timed) to FILE as pcapng for Wireshark with tools/wireshark/sagebrush.lua (docs/capture.md); SIGINT/SIGTERM complete the file, then exit 130/143.
    #[arg(long, global = true, value_name = "FILE", help_heading = "Output (global)")]
    pub capture: Option<std::path::PathBuf>,
    /// Print JSON (one object per line) instead of text; the README documents every shape.
    #[arg(long, global = true, help_heading = "Output (global)")]
    pub json: bool,
    /// Log filter for diagnostics on stderr (RUST_LOG syntax).
    #[arg(
        long,
        global = true,
        default_value = "warn,sagebrush_client::master=error",
        value_name = "FILTER",
        help_heading = "Output (global)"
    )]
    pub log: String,
    /// Retransmissions after the first, 0..255 (default 3).
    #[arg(long, global = true, value_name = "N", help_heading = "Time-outs (global)")]
    pub retries: Option<u8>,
    /// Wait for ACK/NAK, milliseconds (default derived from --baud; 1000 over TCP).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub ack_timeout: Option<u64>,
    /// Wait for a result after the ACK, milliseconds (default derived from --baud; 5000 over TCP).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub result_timeout: Option<u64>,
    /// Wait for a NIC after the ACK of a command without result, milliseconds.
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub nic_window: Option<u64>,
    /// Wait for the IX initialisation result, milliseconds (default 60000).
    #[arg(long, global = true, value_name = "MS", help_heading = "Time-outs (global)")]
    pub init_timeout: Option<u64>,
}

/// `--wait` and its time-out, shared by every positioning command.
#[derive(Debug, Clone, Copy, Args)]
pub struct WaitArgs {
    /// Poll until the motion ends; exit 20 if it stopped short of the target, 21 if still moving at --wait-timeout.
    #[arg(long)]
    pub wait: bool,
    /// Give up waiting after this many milliseconds, 1..=3600000.
    #[arg(long, default_value_t = 60_000, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=3_600_000))]
    pub wait_timeout: u64,
}

/// `--for` / `--hold` of continuous motions.
#[derive(Debug, Clone, Copy, Args)]
pub struct JogArgs {
    /// Move for DURATION (e.g. 2s, 2sec, 500ms, 1m; 1ms..=1h), then send the stop and confirm it.
    #[arg(long = "for", value_name = "DURATION", value_parser = parse_duration, conflicts_with = "hold")]
    pub duration: Option<Duration>,
    /// Keep the connection (and the motion) until Ctrl-C, SIGTERM or end of stdin, then stop and confirm (stdin from /dev/null ends it at once: use a terminal or a pipe).
    #[arg(long)]
    pub hold: bool,
}

#[derive(Debug, Subcommand)]
pub enum Cmd {
    /// Current pan/tilt position in degrees (P?, Table 15).
    #[command(
        after_help = examples!("position", gimbalctl "--json --serial /dev/ttyUSB0 --to 1.1.1 position")
    )]
    Position,
    /// Go to an absolute position in degrees (Paaaaeeee, Table 15).
    #[command(
        allow_negative_numbers = true,
        after_help = concat!("Angles are hundredths of a degree on the wire (16-bit two's complement): -327.68..=327.67.\n\n", examples!("goto 45 -10 --wait", "goto -12.25 3.5"))
    )]
    Goto {
        /// Pan (azimuth), degrees -327.68..=327.67 (+ = counter-clockwise, right).
        #[arg(value_parser = parse_pan)]
        pan: f64,
        /// Tilt (elevation), degrees -327.68..=327.67 (+ = up; the mount's travel and software limits apply).
        #[arg(value_parser = parse_tilt)]
        tilt: f64,
        #[command(flatten)]
        wait: WaitArgs,
    },
    /// Presets 0..255 (decimal, or hex with 0x): store, recall, query (Snn, Pnn, P?nn, S?nn).
    #[command(
        subcommand,
        after_help = concat!("Preset numbers are decimal 0..255 in and out (hex with a 0x prefix accepted); the wire carries two hex digits (preset 255 = FF).\n\n", examples!("preset store 12", "preset recall 12 --wait", "preset query 0x0C"))
    )]
    Preset(PresetCmd),
    /// Slew continuously (PL, PR, TU, TD); see --for/--hold and the dead-man below.
    #[command(after_help = concat!(
        "Continuous motion and gcud's dead-man: through gcud (--tcp) a motion is stopped as soon as the connection that started it closes, i.e. when gimbalctl exits. Without --for or --hold the motion therefore lasts only an instant through gcud; on a bus (--serial) it goes on until its stop command (PS or TS, `gimbalctl stop`).",
        "\n\n", examples!("slew right --for 2s", "slew up --hold      # until Ctrl-C", gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 slew left          # until `stop pan`")
    ))]
    Slew {
        /// left = pan clockwise (PL), right = pan counter-clockwise (PR), up = tilt up (TU), down = tilt down (TD).
        direction: Direction,
        #[command(flatten)]
        jog: JogArgs,
    },
    /// Stop: all motion (PT, default), one axis (PS, TS), the lens (FS, ZS) or the motors (HS).
    #[command(
        after_help = examples!("stop", "stop pan")
    )]
    Stop {
        /// all = PT, pan = PS, tilt = TS, zoom = ZS, focus = FS, motors = HS (motors off).
        #[arg(default_value = "all")]
        what: StopWhat,
    },
    /// Halt: stop dead, store the position for recall-halt, motors off (HA).
    #[command(after_help = examples!("halt"))]
    Halt,
    /// Go back to the position saved by halt (HP; VP with --lens).
    #[command(
        after_help = examples!("recall-halt", "recall-halt --lens")
    )]
    RecallHalt {
        /// The lens position instead (VP).
        #[arg(long)]
        lens: bool,
    },
    /// Proportional speed for pan or tilt moves (SPn, STn).
    #[command(
        after_help = examples!("speed pan 8     # sends SP8", "speed tilt F    # sends STF")
    )]
    Speed {
        /// pan (SPn) or tilt (STn).
        axis: AxisArg,
        /// Proportional speed 0..=15 (0 = slowest, 15 = maximum); decimal or one hex digit 0..F.
        #[arg(value_parser = parse_speed, value_name = "SPEED")]
        speed: u8,
    },
    /// Query (R?, RP?, RT?) or set (RPnnnn, RTnnnn) discrete rates, degrees per second.
    #[command(
        allow_negative_numbers = true,
        after_help = examples!("rate", "rate pan 10.25   # sends RP0401")
    )]
    Rate {
        /// pan or tilt; both when omitted (query only).
        axis: Option<AxisArg>,
        /// New rate, degrees per second 0..=655.35 (hundredths on the wire, Table 12); query when omitted.
        #[arg(requires = "axis", value_parser = parse_rate, value_name = "DEG_PER_S")]
        value: Option<f64>,
    },
    /// Query (A?, AP?, AT?) or set (APnnnn, ATnnnn) accelerations, degrees per second squared.
    #[command(
        allow_negative_numbers = true,
        after_help = examples!("accel", "accel tilt 80")
    )]
    Accel {
        /// pan or tilt; both when omitted (query only).
        axis: Option<AxisArg>,
        /// New acceleration, degrees per second squared 0..=655.35 (Table 12); query when omitted.
        #[arg(requires = "axis", value_parser = parse_accel, value_name = "DEG_PER_S2")]
        value: Option<f64>,
    },
    /// Vector moves: both axes arrive together (VM1 / VM0).
    #[command(after_help = examples!("vector on"))]
    Vector {
        /// on (VM1) or off (VM0).
        state: OnOff,
    },
    /// Go home, pan 0 tilt 0 (HO).
    #[command(
        after_help = examples!("home --wait", gimbalctl "--tcp 127.0.0.1:4001 --to 5.255.255 home   # every gimbal of GCU 5 (no ACK: written)")
    )]
    Home {
        #[command(flatten)]
        wait: WaitArgs,
    },
    /// Verify home (HV, Table 14).
    #[command(after_help = examples!("verify-home"))]
    VerifyHome,
    /// Run the initialisation sequence and report Table 9 (IX); waits up to --init-timeout.
    #[command(after_help = examples!("init"))]
    Init,
    /// Software limits: query (L?), set raw 12-bit values (LS) or clear (LC).
    #[command(
        after_help = examples!("limits", "limits set 100 50 30 20", "limits clear")
    )]
    Limits {
        #[command(subcommand)]
        action: Option<LimitsCmd>,
    },
    /// Rate gains: query (G?) or set 0.3..=3.0 (GRPnn, GRTnn).
    #[command(
        after_help = examples!("gains", "gains set tilt 1.5   # sends GRT0F")
    )]
    Gains {
        #[command(subcommand)]
        action: Option<GainsCmd>,
    },
    /// Auxiliary relays 0..=3: status (LR), open (L0..L3), close (L8..LB).
    #[command(
        after_help = examples!("relay", "relay close 2")
    )]
    Relay {
        #[command(subcommand)]
        action: Option<RelayCmd>,
    },
    /// Lens position: query (V?) or go to zoom/focus 0..=4095 (Vzzzfff, Table 17).
    #[command(
        after_help = examples!("lens", "lens goto 2048 100 --wait")
    )]
    Lens {
        #[command(subcommand)]
        action: Option<LensCmd>,
    },
    /// Camera and lens power (CN, CX) or camera/relay status (VS).
    #[command(
        after_help = examples!("camera status", "camera on")
    )]
    Camera {
        /// on (CN: lens and camera relay on), off (CX), status (VS: camera power and relays).
        state: CameraState,
    },
    /// Focus: far, near (continuous, see --for/--hold), stop, speed 0..=9, auto on/off (FF, FN, FS, Fn, F?, FA, FX).
    #[command(after_help = concat!(
        "Focus far/near are continuous motions: through gcud (--tcp) gcud's dead-man stops them as soon as the connection that started them closes (when gimbalctl exits). Use --for or --hold; on a bus (--serial) they go on until `focus stop` (FS).",
        "\n\n", examples!("focus far --for 500ms", "focus speed 9", "focus speed        # query (F?)")
    ))]
    Focus {
        #[command(subcommand)]
        action: FocusCmd,
    },
    /// Zoom: in, out (continuous, see --for/--hold), stop, speed 0..=9, digital A..F (ZI, ZO, ZS, Zn, Z?, ZA..ZF).
    #[command(after_help = concat!(
        "Zoom in/out are continuous motions: through gcud (--tcp) gcud's dead-man stops them as soon as the connection that started them closes (when gimbalctl exits). Use --for or --hold; on a bus (--serial) they go on until `zoom stop` (ZS).",
        "\n\n", examples!("zoom in --for 1s", "zoom out --hold", "zoom speed 5")
    ))]
    Zoom {
        #[command(subcommand)]
        action: ZoomCmd,
    },
    /// Identification block: ID, revision, name, serial (D?, Table 6).
    #[command(
        after_help = examples!("id", gimbalctl "--tcp 127.0.0.1:4001 --to 5.0.0 id      # the GCU itself")
    )]
    Id,
    /// Awake status: axes initialised, motors, error (AW, Table 5).
    #[command(after_help = examples!("status"))]
    Status,
    /// Error bits per axis, by name (E?, Table 6A).
    #[command(after_help = examples!("errors"))]
    Errors,
    /// Status bits per axis, by name (I?, Table 6B).
    #[command(after_help = examples!("status-bits"))]
    StatusBits,
    /// Maximum data rate (B?) or switch the device's rate (C0..C7).
    #[command(
        after_help = examples!(gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 data-rate", gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 data-rate 38400   # then use --baud 38400")
    )]
    DataRate {
        /// New rate in bit/s: 1200, 2400, 4800, 9600, 19200, 38400, 57600 or 115200; query when omitted.
        #[arg(value_parser = parse_baud, value_name = "BPS")]
        bps: Option<u32>,
    },
    /// Program the device's address (#NN); best with only one device on the bus.
    #[command(after_help = examples!(gimbalctl "--serial /dev/ttyUSB0 --to 1.1.255 set-address 9"))]
    SetAddress {
        /// New device ID 1..=254.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=254), value_name = "ID")]
        id: u8,
    },
    /// Auxiliary serial port 0 or 1 (*xpc, *xpt, *xpr, *xpn, *xpf, Table 18).
    #[command(
        after_help = examples!("aux 1 configure 19200 8 1 even", "aux 1 send 'ping\\x0D'", "aux 1 read 16")
    )]
    Aux {
        /// Auxiliary port 0 or 1.
        #[arg(value_parser = clap::value_parser!(u8).range(0..=1), value_name = "PORT")]
        port: u8,
        #[command(subcommand)]
        action: AuxCmd,
    },
    /// Send any payload (\xNN escapes allowed) and show what comes back.
    #[command(
        after_help = examples!("raw 'P?'", "raw VS")
    )]
    Raw {
        /// Payload, 1..=256 bytes of text; \xNN for any byte.
        #[arg(value_name = "PAYLOAD")]
        payload: String,
    },
    /// Poll position and lens and keep one live line (JSON: one object per sample).
    #[command(
        after_help = examples!("watch", gimbalctl "--json --tcp 127.0.0.1:4001 --to 5.1.1 watch --rate 10 --count 20")
    )]
    Watch {
        /// Samples per second, more than 0 and at most 100.
        #[arg(long, default_value_t = 4.0, value_name = "HZ")]
        rate: f64,
        /// Stop after this many samples (default: until interrupted).
        #[arg(long, value_name = "N")]
        count: Option<u64>,
    },
    /// Find what is reachable: GCUs, their ports, the devices on each (queries only: D?, AW, I?).
    #[command(after_help = "\
Through gcud (--tcp) the scan asks each group of --gcus for its GCU's identity (D? to G.0.0; groups \
without a route are skipped), then each port of --ports of every GCU found (a port the GCU does not \
have is skipped at once), then D?, AW and I? to each device of --devices on each port. On a bus \
(--serial, or --tcp --direct to a device server) it sweeps the devices at --bus GROUP.PORT. Only queries are sent, never a motion, one \
at a time, --interval apart. Silent addresses are counted; garbage, time-outs after an ACK and \
other failures are reported per address and the scan goes on; two answers to one address \
(duplicate device IDs on one bus) are reported as a collision.

What it will ask is said on stderr first, then how far it has come: a progress bar when stderr \
is a terminal, a line per GCU and per port otherwise. The defaults ask devices 1-8 on every port \
(seconds on the demo); --devices 1-254 asks every ID, and each silent ID costs a time-out. \
Ctrl-C (SIGINT) or SIGTERM ends a scan early: what it found so far is printed (with --json, in \
the failure object) and it exits 130 or 143.

Examples:
  gimbalctl --tcp 127.0.0.1:4001 scan
  gimbalctl --tcp 127.0.0.1:4001 scan --gcus 5 --ports 1-2 --devices 1-254
  gimbalctl --serial /dev/ttyUSB0 scan --devices 1-32 --timeout 100
  gimbalctl --json --tcp 127.0.0.1:4001 scan --devices 1-8")]
    Scan(ScanArgs),
    /// Release control of a gimbal that gcud governs (~R, a GCU command on port 0; through gcud, --tcp).
    #[command(after_help = "\
gcud gives control of a gimbal to one configured link at a time (ARCHITECTURE \"Governance\"): a \
command that moves or changes the gimbal takes control when nobody holds it, when its link holds \
it, or when its link's priority is higher; control lapses [control] hold_ms after the holder's last \
such command. `release` frees it at once: allowed from the holder's link or one of its priority or \
higher. Refused, it exits 23 and names the holder. It goes through gcud's client listener (--tcp): \
the GCU command ~R PPDD to port 0 of the gimbal's GCU. `gimbalctl gcud-status` shows who holds \
each gimbal.

Examples:
  gimbalctl --tcp 127.0.0.1:4002 --to 5.2.1 release")]
    Release,
    /// Tours gcud runs itself: list, start NAME, stop NAME (~T, GCU commands on port 0; through gcud, --tcp).
    #[command(
        subcommand,
        after_help = "\
A [[tour]] of gcud's configuration drives one gimbal through its steps in order, each goto confirmed \
before its dwell, and cycles until stopped. It runs at the lowest priority: started while a link \
holds the gimbal it waits until that control lapses (and says for whom it waits); any link's \
command pauses it, and it resumes with the step it was on once control lapses. These commands go \
through gcud's client listener (--tcp) as GCU commands on port 0 (~T?, ~T+NAME, ~T-NAME); --to \
picks the GCU by its group (G.0.0; by default the GCU --tcp reaches).

Examples:
  gimbalctl --tcp 127.0.0.1:4001 tour list
  gimbalctl --tcp 127.0.0.1:4001 tour start roof-round
  gimbalctl --tcp 127.0.0.1:4001 --to 5.0.0 tour stop roof-round"
    )]
    Tour(TourCmd),
    /// What a running gcud knows: ports, links, and the devices it has seen (online, last position, last error).
    #[command(after_help = "\
Reads gcud's /status document, served beside /metrics on its [metrics] listen address (which only \
[metrics] allow_peers may read). Devices are those gcud has addressed since it started: online if \
the last exchange with them was answered, their last position and lens position as answered to P? \
and V?, and their last error (did not acknowledge, NAK, no result, NIC). --json prints the document \
under \"status\" (the README documents its shape).

Examples:
  gimbalctl gcud-status                          # gcud's default 127.0.0.1:9187, or $GIMBALCTL_HTTP
  gimbalctl --json gcud-status --http 10.0.0.5:9187")]
    GcudStatus {
        /// gcud's [metrics] listen address HOST:PORT; the default is the shipped config/gcud.toml's.
        #[arg(long, env = "GIMBALCTL_HTTP", default_value = GCUD_HTTP, value_name = "HOST:PORT", value_parser = parse_host_port)]
        http: String,
    },
    /// Print the frame for PAYLOAD as hex bytes (no I/O; needs --to).
    #[command(after_help = examples!(gimbalctl "encode --to 5.1.12 --from 2 'P?'     # F8 05 01 0C 02 02 50 3F A5"))]
    Encode {
        /// Payload, 1..=256 bytes of text; \xNN for any byte.
        #[arg(value_name = "PAYLOAD")]
        payload: String,
    },
    /// Decode hex bytes (arguments or stdin) into framer events (no I/O).
    #[command(
        after_help = "Examples:\n  gimbalctl decode F8 05 01 0C 02 02 50 3F A5 06\n  echo 'F8 05 01 0C 02 02 50 3F A5' | gimbalctl --json decode"
    )]
    Decode {
        /// Hex bytes, spaces optional; read from stdin when none are given.
        #[arg(value_name = "HEX")]
        hex: Vec<String>,
    },
}

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
    /// --tcp leads to a bus, not a GCU (gimbalsim --tcp, a ser2net device server): sweep --bus directly.
    #[arg(long)]
    pub direct: bool,
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

/// A tour's name as GCU commands carry it.
fn parse_tour_name(text: &str) -> Result<String, String> {
    match sagebrush_protocol::gcu::valid_name(text.as_bytes()) {
        true => Ok(text.to_owned()),
        false => Err(format!("{text:?}: a tour name is 1..=32 of A-Z a-z 0-9 _ -")),
    }
}

#[derive(Debug, Subcommand)]
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
pub enum LimitsCmd {
    /// Set raw 12-bit limits, each 0..=4095 (Table 10; the unit is the device's).
    #[command(after_help = examples!("limits set 100 50 30 20"))]
    Set {
        /// Pan counter-clockwise (+) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        pan_ccw: u16,
        /// Pan clockwise (-) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        pan_cw: u16,
        /// Tilt counter-clockwise (up) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        tilt_ccw: u16,
        /// Tilt clockwise (down) limit, raw 0..=4095.
        #[arg(value_parser = clap::value_parser!(u16).range(0..=4095))]
        tilt_cw: u16,
    },
    /// Clear the software limits (LC).
    #[command(after_help = examples!("limits clear"))]
    Clear,
}

#[derive(Debug, Subcommand)]
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

impl Cmd {
    /// The subcommand's name as JSON `command` ("goto", "preset recall").
    pub fn name(&self) -> &'static str {
        match self {
            Cmd::Position => "position",
            Cmd::Goto { .. } => "goto",
            Cmd::Preset(PresetCmd::Store { .. }) => "preset store",
            Cmd::Preset(PresetCmd::Recall { .. }) => "preset recall",
            Cmd::Preset(PresetCmd::Query { .. }) => "preset query",
            Cmd::Preset(PresetCmd::Stored { .. }) => "preset stored",
            Cmd::Slew { .. } => "slew",
            Cmd::Stop { .. } => "stop",
            Cmd::Halt => "halt",
            Cmd::RecallHalt { .. } => "recall-halt",
            Cmd::Speed { .. } => "speed",
            Cmd::Rate { .. } => "rate",
            Cmd::Accel { .. } => "accel",
            Cmd::Vector { .. } => "vector",
            Cmd::Home { .. } => "home",
            Cmd::VerifyHome => "verify-home",
            Cmd::Init => "init",
            Cmd::Limits { .. } => "limits",
            Cmd::Gains { .. } => "gains",
            Cmd::Relay { .. } => "relay",
            Cmd::Lens { action: None } => "lens",
            Cmd::Lens { action: Some(_) } => "lens goto",
            Cmd::Camera { .. } => "camera",
            Cmd::Focus { .. } => "focus",
            Cmd::Zoom { .. } => "zoom",
            Cmd::Id => "id",
            Cmd::Status => "status",
            Cmd::Errors => "errors",
            Cmd::StatusBits => "status-bits",
            Cmd::DataRate { .. } => "data-rate",
            Cmd::SetAddress { .. } => "set-address",
            Cmd::Aux { .. } => "aux",
            Cmd::Raw { .. } => "raw",
            Cmd::Watch { .. } => "watch",
            Cmd::Scan(_) => "scan",
            Cmd::GcudStatus { .. } => "gcud-status",
            Cmd::Release => "release",
            Cmd::Tour(TourCmd::List) => "tour list",
            Cmd::Tour(TourCmd::Start { .. }) => "tour start",
            Cmd::Tour(TourCmd::Stop { .. }) => "tour stop",
            Cmd::Encode { .. } => "encode",
            Cmd::Decode { .. } => "decode",
        }
    }

    /// `--for`/`--hold` of a continuous motion, if this is one.
    pub fn jog(&self) -> Option<JogArgs> {
        match self {
            Cmd::Slew { jog, .. }
            | Cmd::Focus {
                action: FocusCmd::Far { jog } | FocusCmd::Near { jog },
            }
            | Cmd::Zoom {
                action: ZoomCmd::In { jog } | ZoomCmd::Out { jog },
            } => Some(*jog),
            _ => None,
        }
    }

    /// `--wait` of a positioning command, if given.
    pub fn wait(&self) -> Option<WaitArgs> {
        match self {
            Cmd::Goto { wait, .. }
            | Cmd::Home { wait }
            | Cmd::Preset(PresetCmd::Recall { wait, .. })
            | Cmd::Lens {
                action: Some(LensCmd::Goto { wait, .. }),
            } => Some(*wait).filter(|w| w.wait),
            _ => None,
        }
    }
}

/// `G.P.D` (Table 2): an error names the part that is wrong (group, port
/// or device) and its range.
fn parse_address(text: &str) -> Result<Address, String> {
    const HINT: &str = "expected GROUP.PORT.DEVICE, each 0..=255, e.g. 5.1.1";
    let parts: Vec<&str> = text.split('.').collect();
    if parts.len() != 3 {
        return Err(format!("{text:?} has {} part(s): {HINT}", parts.len()));
    }
    for (name, part) in ["group", "port", "device"].into_iter().zip(&parts) {
        if part.trim().parse::<u8>().is_err() {
            return Err(format!("{text:?}: {name} {part:?} is not a number 0..=255; {HINT}"));
        }
    }
    text.parse::<Address>().map_err(|e| format!("{text:?}: {e}; {HINT}"))
}

/// `gcud-status --http` by default: `[metrics] listen` of the shipped
/// config/gcud.toml (and of config/demo.toml).
pub const GCUD_HTTP: &str = "127.0.0.1:9187";

/// `HOST:PORT` with a port 1..=65535.
pub fn parse_host_port(text: &str) -> Result<String, String> {
    const HINT: &str = "expected HOST:PORT, e.g. 127.0.0.1:4001";
    let Some((host, port)) = text.rsplit_once(':') else {
        return Err(format!("{text:?} has no port: {HINT}"));
    };
    if host.is_empty() || host == "[" {
        return Err(format!("{text:?} has no host: {HINT}"));
    }
    if host.contains(':') && !(host.starts_with('[') && host.ends_with(']')) {
        return Err(format!(
            "{text:?}: an IPv6 host goes in brackets, e.g. [::1]:4001; {HINT}"
        ));
    }
    match port.parse::<u16>() {
        Ok(p) if p > 0 => Ok(text.to_string()),
        _ => Err(format!("{text:?}: port {port:?} is not 1..=65535; {HINT}")),
    }
}

fn parse_angle(what: &str, text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("{what} {text:?} is not a number of degrees (-327.68..=327.67)"))?;
    if (-327.68..=327.67).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{what} {v} degrees is out of range -327.68..=327.67 (16-bit hundredths of a degree, Table 15)"
        ))
    }
}

fn parse_pan(text: &str) -> Result<f64, String> {
    parse_angle("pan", text)
}

fn parse_tilt(text: &str) -> Result<f64, String> {
    parse_angle("tilt", text)
}

fn parse_hundredths(what: &str, unit: &str, text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("{what} {text:?} is not a number of {unit} (0..=655.35)"))?;
    if (0.0..=655.35).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{what} {v} {unit} is out of range 0..=655.35 (hundredths on the wire, 16 bits, Table 12)"
        ))
    }
}

fn parse_rate(text: &str) -> Result<f64, String> {
    parse_hundredths("rate", "deg/s", text)
}

fn parse_accel(text: &str) -> Result<f64, String> {
    parse_hundredths("acceleration", "deg/s²", text)
}

fn parse_gain(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .parse()
        .map_err(|_| format!("rate gain {text:?} is not a number (0.3..=3.0)"))?;
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
        Err(_) if text.len() == 1 => {
            u8::from_str_radix(text, 16).map_err(|_| format!("speed {text:?} is not 0..=15 (or one hex digit 0..F)"))?
        }
        Err(_) => return Err(format!("speed {text:?} is not 0..=15 (or one hex digit 0..F)")),
    };
    if v <= 15 {
        Ok(v)
    } else {
        Err(format!("speed {v} is out of range 0..=15"))
    }
}

/// 0..255 decimal, or hex with a `0x` prefix (presets are `00..FF` on the wire).
pub fn parse_preset(text: &str) -> Result<u8, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u8::from_str_radix(hex, 16),
        None => text.parse(),
    };
    parsed.map_err(|_| format!("preset {text:?} is out of range 0..=255 (decimal, or 0x00..=0xFF)"))
}

fn parse_digital(text: &str) -> Result<u8, String> {
    match text {
        "A" | "B" | "C" | "D" | "E" | "F" | "a" | "b" | "c" | "d" | "e" | "f" => {
            u8::from_str_radix(text, 16).map_err(|e| e.to_string())
        }
        _ => Err(format!("digital zoom step {text:?} is not one of A..=F")),
    }
}

/// `2s`, `2sec`, `500ms`, `1m`, `1m 30s` (humantime's forms): 1 ms ..= 1 h.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    const HINT: &str = "expected a duration like 2s, 500ms, 2sec, 1m or 1m30s (1ms..=1h)";
    let d = humantime::parse_duration(text.trim()).map_err(|e| format!("{text:?}: {e}; {HINT}"))?;
    if (Duration::from_millis(1)..=Duration::from_secs(3600)).contains(&d) {
        Ok(d)
    } else {
        Err(format!("{text:?} is out of range: {HINT}"))
    }
}

/// `1-4,7`: IDs 1..=254.
pub fn parse_id_list(text: &str) -> Result<IdList, String> {
    const HINT: &str = "expected IDs 1..=254 like 5, 1-8 or 1,3,5-7";
    let mut ids = Vec::new();
    for part in text.split(',').map(str::trim) {
        let (lo, hi) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let parse = |s: &str| -> Result<u8, String> {
            match s.parse::<u8>() {
                Ok(v) if (1..=254).contains(&v) => Ok(v),
                _ => Err(format!("{text:?}: {s:?} is not 1..=254; {HINT}")),
            }
        };
        let (lo, hi) = (parse(lo)?, parse(hi)?);
        if lo > hi {
            return Err(format!("{text:?}: {lo}-{hi} is empty; {HINT}"));
        }
        ids.extend(lo..=hi);
    }
    ids.sort_unstable();
    ids.dedup();
    Ok(IdList(ids))
}

/// `GROUP.PORT` of a bus, each 1..=255.
fn parse_bus(text: &str) -> Result<(u8, u8), String> {
    const HINT: &str = "expected GROUP.PORT, each 1..=255, e.g. 1.1 or 255.255";
    let (g, p) = text.split_once('.').ok_or_else(|| format!("{text:?}: {HINT}"))?;
    let parse = |s: &str| match s.parse::<u8>() {
        Ok(v) if v >= 1 => Ok(v),
        _ => Err(format!("{text:?}: {HINT}")),
    };
    Ok((parse(g)?, parse(p)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_host_ports_and_lists() {
        assert_eq!(parse_duration("2s"), Ok(Duration::from_secs(2)));
        assert_eq!(parse_duration("500ms"), Ok(Duration::from_millis(500)));
        assert_eq!(parse_duration("2sec"), Ok(Duration::from_secs(2)));
        assert_eq!(parse_duration("1m"), Ok(Duration::from_secs(60)));
        assert_eq!(parse_duration("1m 30s"), Ok(Duration::from_secs(90)));
        assert!(parse_duration("2sec").is_ok() && parse_duration("1500ms").is_ok());
        assert!(parse_duration("2").is_err() && parse_duration("0s").is_err() && parse_duration("2h").is_err());
        assert!(parse_host_port("127.0.0.1").unwrap_err().contains("127.0.0.1:4001"));
        assert!(parse_host_port("127.0.0.1:0").is_err() && parse_host_port(":4001").is_err());
        assert!(parse_host_port("[::1]:4001").is_ok() && parse_host_port("localhost:4001").is_ok());
        assert_eq!(parse_id_list("1-3,7,2"), Ok(IdList(vec![1, 2, 3, 7])));
        assert_eq!(IdList(vec![1, 2, 3, 7, 9, 10]).to_string(), "1-3,7,9-10");
        assert_eq!(parse_id_list("1-254").unwrap().to_string(), "1-254");
        assert!(parse_id_list("0-3").is_err() && parse_id_list("4-2").is_err());
        assert_eq!(parse_preset("255"), Ok(255));
        assert_eq!(parse_preset("0xFF"), Ok(255));
        assert!(parse_preset("256").unwrap_err().contains("0..=255"));
        let e = parse_address("5.1.300").unwrap_err();
        assert!(e.contains("device \"300\" is not a number 0..=255"), "{e}");
        assert!(parse_address("x.1.1").unwrap_err().contains("group \"x\""));
        assert!(parse_address("5.256.1").unwrap_err().contains("port \"256\""));
        assert!(parse_address("5.1").unwrap_err().contains("2 part(s)"));
    }
}
