//! The subcommands of `gimbalctl`, one per command family of Tables 4, 11
//! and 16 and the rev 1.9 list, with each subcommand's name and its
//! `--for`/`--hold` and `--wait` arguments.

use clap::Subcommand;

use super::*;

// `defer`, here and on every family's enum: a subcommand's arguments (and
// the global ones clap copies into each) are built only for the subcommand
// parsed, which takes about a sixth of gimbalctl's start-up page faults
// away (issue 35); `cli::tests` builds the whole tree.
#[derive(Debug, Subcommand)]
#[command(defer = true)]
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
        /// Pan (azimuth), degrees -327.68..=327.67 (+ = right: clockwise seen from above).
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
        "\n\n", examples!("slew right --for 2s", "slew right --speed 9 --hold   # SP9 then PR", "slew up --hold      # until Ctrl-C", gimbalctl "--serial /dev/ttyUSB0 --to 1.1.1 slew left          # until `stop pan`")
    ))]
    Slew {
        /// left = pan left (PL, counter-clockwise seen from above), right = pan right (PR, clockwise seen from above), up = tilt up (TU), down = tilt down (TD).
        direction: Direction,
        /// Proportional speed 0..=15 (SPn for pan, STn for tilt) set first; through gcud the direction follows at its ACK, not after its NIC window.
        #[arg(long, value_parser = parse_speed, value_name = "SPEED")]
        speed: Option<u8>,
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
  gimbalctl --tcp 127.0.0.1:4002 tour start roof-round
  gimbalctl --tcp 127.0.0.1:4002 --to 5.0.0 tour stop roof-round"
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
    /// Write a private CA and the certificates a site needs to switch TLS on (no I/O but the files).
    #[command(subcommand)]
    Tls(TlsCmd),
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
            Cmd::Tls(TlsCmd::Init { .. }) => "tls init",
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
