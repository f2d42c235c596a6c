//! Each subcommand as the typed command of the protocol crate, encoded as
//! the payload to send (Tables 4, 11, 16 and the rev 1.9 list).

use sagebrush_host::hex::payload_bytes;
use sagebrush_protocol::{
    Acceleration, Angle, AuxBytes, AuxConfig, AuxPort, AuxReadLen, Axis, Command, DataRate, DeviceId, DigitalZoom,
    Extended, LensPosition, LensSpeed, Limits, MAX_PAYLOAD, Parity, Position, Rate, RateGain, Relay, Speed, U12,
};

use crate::cli::{
    AuxCmd, AxisArg, CameraState, Cmd, Direction, FocusCmd, GainsCmd, LensCmd, LimitsCmd, OnOff, ParityArg, PresetCmd,
    RelayCmd, StopWhat, ZoomCmd,
};
use crate::error::CtlError;

fn axis(a: AxisArg) -> Axis {
    match a {
        AxisArg::Pan => Axis::Pan,
        AxisArg::Tilt => Axis::Tilt,
    }
}

fn range<T>(what: &str, value: Result<T, sagebrush_protocol::RangeError>) -> Result<T, CtlError> {
    value.map_err(|e| CtlError::Usage(format!("{what}: {e}")))
}

/// The payload bytes of a command.
pub fn encode(command: &Command<'_>) -> Result<Vec<u8>, CtlError> {
    Ok(sagebrush_client::client::encode(command)?)
}

/// What a one-exchange subcommand sends: the command it built, handed on
/// as built (never read back from its bytes), and its payload.
#[derive(Debug)]
pub struct Request<'a> {
    pub command: Command<'a>,
    pub payload: Vec<u8>,
    /// A command chained before it (`slew --speed`: the speed its direction
    /// takes, `Session::start`).
    pub first: Option<Command<'static>>,
}

/// The bytes a subcommand gives as text with `\xNN` escapes (`aux N send`'s
/// data, `raw`'s payload), which its command borrows; empty for the others.
pub fn data(cmd: &Cmd) -> Result<Vec<u8>, CtlError> {
    match cmd {
        Cmd::Raw { payload } => {
            let bytes = payload_bytes(payload).map_err(|e| CtlError::Usage(format!("payload {payload:?}: {e}")))?;
            if bytes.is_empty() || bytes.len() > MAX_PAYLOAD {
                return Err(CtlError::Usage(format!(
                    "payload of {} bytes: a frame carries 1..=256",
                    bytes.len()
                )));
            }
            Ok(bytes)
        }
        Cmd::Aux {
            action: AuxCmd::Send { data },
            ..
        } => payload_bytes(data).map_err(|e| CtlError::Usage(format!("data {data:?}: {e}"))),
        _ => Ok(Vec::new()),
    }
}

/// The request of a one-exchange subcommand, its byte arguments in `data`
/// (from [`data`]); `None` for the subcommands that are not one exchange
/// (watch, scan, gcud-status, encode, decode).
pub fn request<'a>(cmd: &Cmd, data: &'a [u8]) -> Result<Option<Request<'a>>, CtlError> {
    use Command as C;
    let command = match cmd {
        Cmd::Position => C::QueryPosition,
        Cmd::Goto { pan, tilt, .. } => C::GoTo(Position::new(
            range("pan", Angle::from_degrees(*pan as f32))?,
            range("tilt", Angle::from_degrees(*tilt as f32))?,
        )),
        Cmd::Preset(PresetCmd::Store { n }) => C::StorePreset(*n),
        Cmd::Preset(PresetCmd::Recall { n, .. }) => C::GoToPreset(*n),
        Cmd::Preset(PresetCmd::Query { n }) => C::QueryPreset(*n),
        Cmd::Preset(PresetCmd::Stored { n }) => C::QueryStoredPreset(*n),
        Cmd::Slew { direction, .. } => match direction {
            Direction::Left => C::PanLeft,
            Direction::Right => C::PanRight,
            Direction::Up => C::TiltUp,
            Direction::Down => C::TiltDown,
        },
        Cmd::Stop { what } => match what {
            StopWhat::All => C::StopMotion,
            StopWhat::Pan => C::PanStop,
            StopWhat::Tilt => C::TiltStop,
            StopWhat::Zoom => C::ZoomStop,
            StopWhat::Focus => C::FocusStop,
            StopWhat::Motors => C::MotorsStop,
        },
        Cmd::Halt => C::Halt,
        Cmd::RecallHalt { lens: false } => C::Extended(Extended::GoToHaltPosition, b""),
        Cmd::RecallHalt { lens: true } => C::Extended(Extended::LensGoToHaltPosition, b""),
        Cmd::Speed { axis: a, speed } => C::SetSpeed(axis(*a), range("speed", Speed::new(*speed))?),
        Cmd::Rate { axis: a, value } => rate(*a, *value)?,
        Cmd::Accel { axis: a, value } => accel(*a, *value)?,
        Cmd::Vector { state } => C::SetVectorMode(matches!(state, OnOff::On)),
        Cmd::Home { .. } => C::Home,
        Cmd::VerifyHome => C::VerifyHome,
        Cmd::Init => C::Initialize,
        Cmd::Limits { action } => limits(action.as_ref())?,
        Cmd::Gains { action } => gains(action.as_ref())?,
        Cmd::Relay { action } => relay(action.as_ref())?,
        Cmd::Lens { action: None } => C::QueryLens,
        Cmd::Lens {
            action: Some(LensCmd::Goto { zoom, focus, .. }),
        } => C::LensGoTo(LensPosition {
            zoom: range("zoom", U12::new(*zoom))?,
            focus: range("focus", U12::new(*focus))?,
        }),
        Cmd::Camera { state } => match state {
            CameraState::On => C::CameraOn,
            CameraState::Off => C::CameraOff,
            CameraState::Status => C::Extended(Extended::CameraRelayStatus, b""),
        },
        Cmd::Focus { action } => focus(action)?,
        Cmd::Zoom { action } => zoom(action)?,
        Cmd::Id => C::Identify,
        Cmd::Status => C::AwakeStatus,
        Cmd::Errors => C::QueryErrors,
        Cmd::StatusBits => C::QueryStatusBits,
        Cmd::DataRate { bps: None } => C::QueryMaxDataRate,
        Cmd::DataRate { bps: Some(bps) } => {
            C::SetDataRate(DataRate::from_bits_per_second(*bps).ok_or_else(|| CtlError::Usage(format!("{bps} bit/s")))?)
        }
        Cmd::SetAddress { id } => C::SetDeviceId(range("device ID", DeviceId::new(*id))?),
        Cmd::Aux { port, action } => aux(range("auxiliary port", AuxPort::new(*port))?, action, data)?,
        Cmd::Raw { .. } => {
            // Bytes the user gave, sent as they are: what they say is read once, here.
            return Ok(Some(Request {
                command: C::parse(data),
                payload: data.to_vec(),
                first: None,
            }));
        }
        Cmd::Watch { .. }
        | Cmd::Scan(_)
        | Cmd::GcudStatus { .. }
        | Cmd::Tls(_)
        | Cmd::Encode { .. }
        | Cmd::Decode { .. }
        | Cmd::Release
        | Cmd::Tour(_) => {
            return Ok(None);
        }
    };
    let payload = encode(&command)?;
    let first = match cmd {
        Cmd::Slew {
            direction,
            speed: Some(speed),
            ..
        } => {
            let axis = match direction {
                Direction::Left | Direction::Right => Axis::Pan,
                Direction::Up | Direction::Down => Axis::Tilt,
            };
            Some(C::SetSpeed(axis, range("speed", Speed::new(*speed))?))
        }
        _ => None,
    };
    Ok(Some(Request {
        command,
        payload,
        first,
    }))
}

/// `rate` (Tables 11 and 12): both axes' rates, one axis's, or set one.
fn rate(a: Option<AxisArg>, value: Option<f64>) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match (a, value) {
        (None, _) => C::QueryRates,
        (Some(a), None) => C::QueryRate(axis(a)),
        (Some(a), Some(v)) => C::SetRate(axis(a), range("rate", Rate::from_degrees_per_second(v))?),
    })
}

/// `accel` (Tables 11 and 12): both axes' accelerations, one axis's, or set one.
fn accel(a: Option<AxisArg>, value: Option<f64>) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match (a, value) {
        (None, _) => C::QueryAccelerations,
        (Some(a), None) => C::QueryAcceleration(axis(a)),
        (Some(a), Some(v)) => C::SetAcceleration(
            axis(a),
            range("acceleration", Acceleration::from_degrees_per_second_squared(v))?,
        ),
    })
}

/// `limits` (Table 10): query, clear or set the software limits.
fn limits(action: Option<&LimitsCmd>) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match action {
        None => C::QueryLimits,
        Some(LimitsCmd::Clear) => C::ClearLimits,
        Some(LimitsCmd::Set {
            pan_ccw,
            pan_cw,
            tilt_ccw,
            tilt_cw,
        }) => C::SetLimits(Limits {
            pan_ccw: range("pan ccw limit", U12::new(*pan_ccw))?,
            pan_cw: range("pan cw limit", U12::new(*pan_cw))?,
            tilt_ccw: range("tilt ccw limit", U12::new(*tilt_ccw))?,
            tilt_cw: range("tilt cw limit", U12::new(*tilt_cw))?,
        }),
    })
}

/// `gains` (Tables 7 and 8): query the rate gains or set one.
fn gains(action: Option<&GainsCmd>) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match action {
        None => C::QueryRateGains,
        Some(GainsCmd::Set { axis: a, gain }) => {
            C::SetRateGain(axis(*a), range("gain", RateGain::new((gain * 10.0).round() as u8))?)
        }
    })
}

/// `relay` (Table 4): query the relays, open or close one.
fn relay(action: Option<&RelayCmd>) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match action {
        None => C::QueryRelays,
        Some(RelayCmd::Open { n }) => C::OpenRelay(range("relay", Relay::new(*n))?),
        Some(RelayCmd::Close { n }) => C::CloseRelay(range("relay", Relay::new(*n))?),
    })
}

/// `focus` (Table 16 and the rev 1.9 list).
fn focus(action: &FocusCmd) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match action {
        FocusCmd::Far { .. } => C::FocusFar,
        FocusCmd::Near { .. } => C::FocusNear,
        FocusCmd::Stop => C::FocusStop,
        FocusCmd::Speed { n: Some(n) } => C::FocusSpeed(range("focus speed", LensSpeed::new(*n))?),
        FocusCmd::Speed { n: None } => C::Extended(Extended::FocusSpeedQuery, b""),
        FocusCmd::AutoOn => C::AutoFocusOn,
        FocusCmd::AutoOff => C::AutoFocusOff,
    })
}

/// `zoom` (Table 16 and the rev 1.9 list).
fn zoom(action: &ZoomCmd) -> Result<Command<'static>, CtlError> {
    use Command as C;
    Ok(match action {
        ZoomCmd::In { .. } => C::ZoomIn,
        ZoomCmd::Out { .. } => C::ZoomOut,
        ZoomCmd::Stop => C::ZoomStop,
        ZoomCmd::Speed { n: Some(n) } => C::ZoomSpeed(range("zoom speed", LensSpeed::new(*n))?),
        ZoomCmd::Speed { n: None } => C::Extended(Extended::ZoomSpeedQuery, b""),
        ZoomCmd::Digital { step } => C::DigitalZoom(range("digital zoom", DigitalZoom::new(*step))?),
    })
}

fn aux<'a>(port: AuxPort, action: &AuxCmd, data: &'a [u8]) -> Result<Command<'a>, CtlError> {
    use Command as C;
    Ok(match action {
        AuxCmd::Configure {
            baud,
            data_bits,
            stop_bits,
            parity,
        } => {
            let parity = match parity {
                ParityArg::None => Parity::None,
                ParityArg::Odd => Parity::Odd,
                ParityArg::Even => Parity::Even,
            };
            let config = range(
                "auxiliary port settings",
                AuxConfig::new(*baud, *data_bits, *stop_bits, parity),
            )?;
            C::AuxConfigure(port, config)
        }
        AuxCmd::Send { .. } => C::AuxTransmit(port, range("data", AuxBytes::new(data))?),
        AuxCmd::Read { max } => C::AuxReceive(port, range("read length", AuxReadLen::new(*max))?),
        AuxCmd::Count => C::AuxCount(port),
        AuxCmd::Flush => C::AuxFlush(port),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Commands are read once (issue 23): gimbalctl hands on the command it
    /// built. Bytes are read as a command only where they come from the user
    /// (`raw` here; `encode` and `decode` in codec.rs), never the encoding
    /// of a command built a moment before.
    #[test]
    fn no_module_reads_back_a_command_it_built() {
        let modules = [
            ("main.rs", include_str!("main.rs")),
            ("jog.rs", include_str!("jog.rs")),
            ("motion.rs", include_str!("motion.rs")),
            ("output.rs", include_str!("output.rs")),
            ("scan.rs", include_str!("scan.rs")),
            ("session.rs", include_str!("session.rs")),
            ("watch.rs", include_str!("watch.rs")),
        ];
        for (name, text) in modules {
            for call in ["Command::parse(", "Command::parse_strict(", "C::parse("] {
                assert!(
                    !text.contains(call),
                    "{name} reads a command back from bytes ({call}...)"
                );
            }
        }
        let this = include_str!("request.rs");
        let code = this.split("#[cfg(test)]").next().unwrap_or_default();
        assert_eq!(
            code.matches("C::parse(").count(),
            1,
            "request.rs reads bytes only for `raw`"
        );
    }

    /// The request carries the command as built, and its encoding.
    #[test]
    fn a_request_is_the_built_command_and_its_payload() {
        use crate::cli::Cli;
        use clap::Parser;
        for (args, sent) in [
            (&["gimbalctl", "speed", "pan", "8"][..], "SP8"),
            (&["gimbalctl", "aux", "1", "send", "hi\\x01"], "*x1thi\u{1}"),
            (&["gimbalctl", "raw", "P?"], "P?"),
        ] {
            let cli = Cli::try_parse_from(args).unwrap();
            let data = data(&cli.command).unwrap();
            let request = request(&cli.command, &data).unwrap().unwrap();
            assert_eq!(String::from_utf8_lossy(&request.payload), sent, "{args:?}");
            assert_eq!(encode(&request.command).unwrap(), request.payload, "{args:?}");
        }
    }
}
