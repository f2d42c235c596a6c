//! Results for people (labels and physical units) and for scripts (typed
//! JSON with units in field names and bits by name), one function per
//! result table (4A, 5, 6, 6A, 6B, 8, 9, 10, 13, 14, 15, 17, and the rev 1.9
//! `VS`, `F?`, `Z?`, `C?`), and the commands themselves as sent.

use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{
    Angle, AwakeStatus, Axis, Command, DataRate, ErrorCodes, Extended, HomeStatus, Identity, InitResults, Limits,
    Parity, Position, Reply, StatusBits,
};
use serde_json::{Map, Value, json};

fn deg(a: Angle) -> f64 {
    f64::from(a.0) / 100.0
}

/// The names of the set bits, from a table's named bits (protocol crate:
/// `ErrorCodes::BITS`, Table 6A; `StatusBits::BITS`, Table 6B).
fn set_names<B: Copy + Into<u16>>(bits: u16, names: &[(B, &'static str, &'static str)]) -> Vec<&'static str> {
    names
        .iter()
        .filter(|(b, _, _)| bits & (*b).into() != 0)
        .map(|(_, n, _)| *n)
        .collect()
}

/// One axis's bits as `{"raw": n, "<name>": bool, ...}` (every name present).
pub fn named_bits<B: Copy + Into<u16>>(bits: u16, names: &[(B, &'static str, &'static str)]) -> Value {
    let mut m = Map::new();
    m.insert("raw".into(), bits.into());
    for (b, n, _) in names {
        m.insert((*n).into(), (bits & (*b).into() != 0).into());
    }
    Value::Object(m)
}

fn list(names: &[&str]) -> String {
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

pub fn position_text(p: &Position) -> String {
    format!("pan {:8.2}°  tilt {:7.2}°", deg(p.pan), deg(p.tilt))
}

pub fn position_json(p: &Position) -> Value {
    json!({ "pan_deg": deg(p.pan), "tilt_deg": deg(p.tilt) })
}

fn rate_text(r: DataRate) -> String {
    match r.bits_per_second() {
        Some(bps) => format!("{bps} bit/s (C{:X})", r.code()),
        None => format!("reserved rate code C{:X}", r.code()),
    }
}

/// Table 9: one direction's result word.
fn init_json(word: u16) -> Value {
    named_bits(word, &InitResults::BITS)
}

/// Table 5.
pub fn awake(s: AwakeStatus) -> (String, Value) {
    let b = s.bits();
    let problems: Vec<&str> = AwakeStatus::BITS
        .iter()
        .filter(|(bit, _, _)| b & bit != 0)
        .map(|(_, _, text)| *text)
        .collect();
    let text = if problems.is_empty() {
        "awake: hardware functioning properly (status 0)".to_string()
    } else {
        format!("awake: {} (status {b:X})", problems.join(", "))
    };
    let mut m = Map::new();
    m.insert("code".into(), b.into());
    m.insert("hardware_ok".into(), (b == 0).into());
    for (bit, name, _) in AwakeStatus::BITS {
        m.insert(name.into(), (b & bit != 0).into());
    }
    (text, Value::Object(m))
}

/// `VS`: no published layout (protocol-notes E13); devices built on the simulator's
/// and the firmware's reading answer `C` + camera power digit + `L` + relay
/// hex digit (Table 4A style). Anything else is shown raw.
fn camera_status(bytes: &[u8]) -> (String, Value) {
    let raw = payload_text(bytes);
    if let [b'C', power @ (b'0' | b'1'), b'L', relays] = bytes {
        if let Some(bits) = (*relays as char).to_digit(16) {
            let on: Vec<u32> = (0..4).filter(|i| bits & (1 << i) != 0).collect();
            let power = *power == b'1';
            return (
                format!(
                    "camera and lens power {}; relays on: {} (VS {raw})",
                    if power { "on" } else { "off" },
                    if on.is_empty() {
                        "none".to_string()
                    } else {
                        on.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
                    }
                ),
                json!({ "camera_power": power, "relays": { "raw": bits, "on": on }, "raw": raw }),
            );
        }
    }
    (
        format!("camera/relay status (VS, layout unknown): {raw}"),
        json!({ "camera_power": null, "relays": null, "raw": raw }),
    )
}

/// `F?` / `Z?`: one decimal digit 0..9.
fn lens_speed(what: &str, bytes: &[u8]) -> (String, Value) {
    let raw = payload_text(bytes);
    match bytes {
        [d @ b'0'..=b'9'] => {
            let n = d - b'0';
            (
                format!("{what} speed {n} (0 = slowest .. 9 = fastest)"),
                json!({ "speed": n, "raw": raw }),
            )
        }
        _ => (
            format!("{what} speed: {raw} (not one digit 0..9)"),
            json!({ "speed": null, "raw": raw }),
        ),
    }
}

/// Text and JSON of a result of `command`.
pub fn describe(command: &Command<'_>, reply: &Reply<'_>) -> (String, Value) {
    match *reply {
        Reply::AwakeStatus(s) => awake(s),
        Reply::MaxDataRate(r) => (
            format!("maximum data rate {}", rate_text(r)),
            json!({ "code": r.code(), "bps": r.bits_per_second() }),
        ),
        Reply::Identity(id) => identity(id),
        Reply::Errors(e) => errors(e),
        Reply::StatusBits(s) => (
            format!(
                "status: pan {} ; tilt {}",
                list(&set_names(s.pan, &StatusBits::BITS)),
                list(&set_names(s.tilt, &StatusBits::BITS))
            ),
            json!({ "azimuth": named_bits(s.pan, &StatusBits::BITS), "elevation": named_bits(s.tilt, &StatusBits::BITS) }),
        ),
        Reply::RateGains(g) => {
            let (p, t) = (f64::from(g.pan.get()) / 10.0, f64::from(g.tilt.get()) / 10.0);
            (
                format!("rate gains: pan {p:.1}  tilt {t:.1}"),
                json!({ "pan_gain": p, "tilt_gain": t }),
            )
        }
        Reply::Initialization(r) => initialization(r),
        Reply::Limits(l) => limits(l),
        Reply::Relays(bits) => relays(bits),
        Reply::Accelerations { pan, tilt } => (
            format!(
                "acceleration: pan {:.2} deg/s²  tilt {:.2} deg/s²",
                pan.degrees_per_second_squared(),
                tilt.degrees_per_second_squared()
            ),
            json!({ "pan_deg_s2": pan.degrees_per_second_squared(), "tilt_deg_s2": tilt.degrees_per_second_squared() }),
        ),
        Reply::Acceleration(a) => (
            format!("acceleration {:.2} deg/s²", a.degrees_per_second_squared()),
            json!({ "deg_s2": a.degrees_per_second_squared() }),
        ),
        Reply::Rates { pan, tilt } => (
            format!(
                "rate: pan {:.2} deg/s  tilt {:.2} deg/s",
                pan.degrees_per_second(),
                tilt.degrees_per_second()
            ),
            json!({ "pan_deg_s": pan.degrees_per_second(), "tilt_deg_s": tilt.degrees_per_second() }),
        ),
        Reply::Rate(r) => (
            format!("rate {:.2} deg/s", r.degrees_per_second()),
            json!({ "deg_s": r.degrees_per_second() }),
        ),
        Reply::VerifyHome(h) => verify_home(h),
        Reply::Position(p) => (position_text(&p), position_json(&p)),
        Reply::Lens(l) => (
            format!("zoom {}  focus {} (of 0..4095)", l.zoom.get(), l.focus.get()),
            json!({ "zoom": l.zoom.get(), "focus": l.focus.get() }),
        ),
        Reply::AuxCount(n) => (format!("{n} characters waiting"), json!({ "count": n })),
        Reply::AuxData(bytes) => (
            payload_text(bytes),
            json!({ "data": payload_text(bytes), "len": bytes.len() }),
        ),
        Reply::Raw(bytes) => raw(command, bytes),
    }
}

/// `D?` (Table 6).
fn identity(id: Identity<'_>) -> (String, Value) {
    let name = String::from_utf8_lossy(id.name()).into_owned();
    let serial = String::from_utf8_lossy(id.serial()).into_owned();
    let revision = String::from_utf8_lossy(&id.revision).trim().to_string();
    (
        format!(
            "device {:02}  protocol revision {revision}  name {name:?}  serial {serial:?}",
            id.id
        ),
        json!({ "id": id.id, "revision": revision, "name": name, "serial": serial }),
    )
}

/// `E?` (Table 6A), per axis.
fn errors(e: ErrorCodes) -> (String, Value) {
    let (pan, tilt) = (u16::from(e.pan), u16::from(e.tilt));
    (
        format!(
            "errors: pan {} ; tilt {}",
            list(&set_names(pan, &ErrorCodes::BITS)),
            list(&set_names(tilt, &ErrorCodes::BITS))
        ),
        json!({ "azimuth": named_bits(pan, &ErrorCodes::BITS), "elevation": named_bits(tilt, &ErrorCodes::BITS) }),
    )
}

/// `IX` (Table 9).
fn initialization(r: InitResults) -> (String, Value) {
    let ok = r.succeeded();
    (
        format!(
            "initialisation {}: pan ccw {:04X} cw {:04X}  tilt ccw {:04X} cw {:04X}",
            if ok { "succeeded" } else { "FAILED (motors off)" },
            r.pan_ccw,
            r.pan_cw,
            r.tilt_ccw,
            r.tilt_cw
        ),
        json!({
            "success": ok,
            "pan_ccw": init_json(r.pan_ccw), "pan_cw": init_json(r.pan_cw),
            "tilt_ccw": init_json(r.tilt_ccw), "tilt_cw": init_json(r.tilt_cw),
        }),
    )
}

/// `L?` (Table 10), raw as the device counts.
fn limits(l: Limits) -> (String, Value) {
    (
        format!(
            "software limits (raw 12-bit, the device's unit): pan ccw {} cw {}  tilt ccw {} cw {}",
            l.pan_ccw.get(),
            l.pan_cw.get(),
            l.tilt_ccw.get(),
            l.tilt_cw.get()
        ),
        json!({
            "pan_ccw_raw": l.pan_ccw.get(), "pan_cw_raw": l.pan_cw.get(),
            "tilt_ccw_raw": l.tilt_ccw.get(), "tilt_cw_raw": l.tilt_cw.get(),
        }),
    )
}

/// `R?` (Table 4A): the relays closed.
fn relays(bits: u8) -> (String, Value) {
    let on: Vec<u8> = (0..4).filter(|i| bits & (1 << i) != 0).collect();
    let text = if on.is_empty() {
        "relays: all off".to_string()
    } else {
        format!(
            "relays on: {}",
            on.iter().map(u8::to_string).collect::<Vec<_>>().join(", ")
        )
    };
    (text, json!({ "raw": bits, "on": on }))
}

/// `HV` (Table 14).
fn verify_home(h: HomeStatus) -> (String, Value) {
    let axes = |b: u8| json!({ "pan": b & 1 != 0, "tilt": b & 2 != 0 });
    let yes = |b: u8| format!("pan {} tilt {}", b & 1 != 0, b & 2 != 0);
    (
        format!(
            "home: limit switches found ({}), centre switches found ({}), count correct on centre ({})",
            yes(h.limit_switches),
            yes(h.center_switches),
            yes(h.count_correct)
        ),
        json!({
            "limit_switches": axes(h.limit_switches),
            "center_switches": axes(h.center_switches),
            "count_correct": axes(h.count_correct),
        }),
    )
}

/// A result the protocol crate leaves raw: named by the command that asked.
fn raw(command: &Command<'_>, bytes: &[u8]) -> (String, Value) {
    match command {
        Command::Extended(Extended::CameraRelayStatus, _) => camera_status(bytes),
        Command::Extended(Extended::FocusSpeedQuery, _) => lens_speed("focus", bytes),
        Command::Extended(Extended::ZoomSpeedQuery, _) => lens_speed("zoom", bytes),
        Command::Extended(Extended::LensLimitsQuery, _) => (
            format!(
                "lens limits/preset values (C?, no published layout): {}",
                payload_text(bytes)
            ),
            json!({ "raw": payload_text(bytes) }),
        ),
        _ => (payload_text(bytes), json!({ "raw": payload_text(bytes) })),
    }
}

fn axis_name(a: Axis) -> &'static str {
    match a {
        Axis::Pan => "pan",
        Axis::Tilt => "tilt",
    }
}

fn parity_name(p: Parity) -> &'static str {
    match p {
        Parity::None => "none",
        Parity::Odd => "odd",
        Parity::Even => "even",
    }
}

/// A command as typed JSON: `name` (the command table's script name,
/// [`Command::script_name`]), `mnemonic` (the spec table's row) and its
/// arguments with units in their names.
pub fn command_json(command: &Command<'_>) -> Value {
    use Command as C;
    let args = match command {
        C::SetDeviceId(id) => json!({ "device_id": id.get() }),
        C::SetDataRate(r) => json!({ "code": r.code(), "bps": r.bits_per_second() }),
        C::SetRateGain(a, g) => json!({ "axis": axis_name(*a), "gain": f64::from(g.get()) / 10.0 }),
        C::OpenRelay(r) => json!({ "relay": r.get() }),
        C::CloseRelay(r) => json!({ "relay": r.get() }),
        C::SetLimits(l) => json!({
            "pan_ccw_raw": l.pan_ccw.get(), "pan_cw_raw": l.pan_cw.get(),
            "tilt_ccw_raw": l.tilt_ccw.get(), "tilt_cw_raw": l.tilt_cw.get(),
        }),
        C::SetAcceleration(a, v) => json!({ "axis": axis_name(*a), "accel_deg_s2": v.degrees_per_second_squared() }),
        C::QueryAcceleration(a) => json!({ "axis": axis_name(*a) }),
        C::Home => json!({ "pan_deg": 0.0, "tilt_deg": 0.0 }),
        C::GoTo(p) => position_json(p),
        C::GoToPreset(n) => json!({ "preset": n }),
        C::QueryPreset(n) => json!({ "preset": n }),
        C::SetRate(a, r) => json!({ "axis": axis_name(*a), "rate_deg_s": r.degrees_per_second() }),
        C::QueryRate(a) => json!({ "axis": axis_name(*a) }),
        C::StorePreset(n) => json!({ "preset": n }),
        C::SetSpeed(a, s) => json!({ "axis": axis_name(*a), "speed": s.get() }),
        C::QueryStoredPreset(n) => json!({ "preset": n }),
        C::SetVectorMode(on) => json!({ "on": on }),
        C::FocusSpeed(s) => json!({ "speed": s.get() }),
        C::LensGoTo(l) => json!({ "zoom": l.zoom.get(), "focus": l.focus.get() }),
        C::ZoomSpeed(s) => json!({ "speed": s.get() }),
        C::DigitalZoom(z) => json!({ "step": format!("{:X}", z.get()) }),
        C::AuxConfigure(p, c) => json!({
            "aux_port": p.get(), "baud": c.baud(), "data_bits": c.data_bits(),
            "stop_bits": c.stop_bits(), "parity": parity_name(c.parity()),
        }),
        C::AuxTransmit(p, data) => json!({ "aux_port": p.get(), "data": payload_text(data.bytes()) }),
        C::AuxReceive(p, n) => json!({ "aux_port": p.get(), "max_bytes": n.get() }),
        C::AuxCount(p) => json!({ "aux_port": p.get() }),
        C::AuxFlush(p) => json!({ "aux_port": p.get() }),
        C::Extended(ext, arg) => json!({ "extended": ext.name(), "argument": payload_text(arg) }),
        // No arguments.
        C::Unknown(_)
        | C::AwakeStatus
        | C::QueryMaxDataRate
        | C::Identify
        | C::QueryErrors
        | C::QueryStatusBits
        | C::QueryRateGains
        | C::Initialize
        | C::QueryRelays
        | C::ClearLimits
        | C::QueryLimits
        | C::QueryAccelerations
        | C::Halt
        | C::VerifyHome
        | C::MotorsStop
        | C::QueryPosition
        | C::PanLeft
        | C::PanRight
        | C::PanStop
        | C::StopMotion
        | C::QueryRates
        | C::TiltDown
        | C::TiltStop
        | C::TiltUp
        | C::CameraOn
        | C::CameraOff
        | C::AutoFocusOn
        | C::FocusFar
        | C::FocusNear
        | C::FocusStop
        | C::AutoFocusOff
        | C::QueryLens
        | C::ZoomIn
        | C::ZoomOut
        | C::ZoomStop => json!({}),
    };
    let mut m = Map::new();
    m.insert("name".into(), command.script_name().into());
    m.insert("mnemonic".into(), command.mnemonic().into());
    if let Value::Object(args) = args {
        m.extend(args);
    }
    Value::Object(m)
}

/// What an acknowledged command without result did, for people; `sent`
/// is the payload as sent (`SP8`, never the template `SPn`).
pub fn acknowledged_text(command: &Command<'_>, sent: &str) -> String {
    use Command as C;
    match command {
        C::GoTo(p) => format!("{sent}: moving to {}", position_text(p).trim()),
        C::Home => format!("{sent}: moving home (pan 0, tilt 0)"),
        C::GoToPreset(n) => format!("{sent}: moving to preset {n}"),
        C::StorePreset(n) => format!("{sent}: current position stored as preset {n}"),
        C::SetSpeed(a, s) => format!(
            "{sent} acknowledged: {} proportional speed {} (0..15)",
            axis_name(*a),
            s.get()
        ),
        C::SetRate(a, r) => format!(
            "{sent} acknowledged: {} rate {:.2} deg/s",
            axis_name(*a),
            r.degrees_per_second()
        ),
        C::SetAcceleration(a, r) => format!(
            "{sent} acknowledged: {} acceleration {:.2} deg/s²",
            axis_name(*a),
            r.degrees_per_second_squared()
        ),
        C::SetRateGain(a, g) => format!(
            "{sent} acknowledged: {} rate gain {:.1}",
            axis_name(*a),
            f64::from(g.get()) / 10.0
        ),
        C::LensGoTo(l) => format!("{sent}: lens moving to zoom {} focus {}", l.zoom.get(), l.focus.get()),
        C::FocusSpeed(s) => format!("{sent} acknowledged: focus speed {} (0..9)", s.get()),
        C::ZoomSpeed(s) => format!("{sent} acknowledged: zoom speed {} (0..9)", s.get()),
        C::OpenRelay(r) => format!("{sent} acknowledged: relay {} open (off)", r.get()),
        C::CloseRelay(r) => format!("{sent} acknowledged: relay {} closed (on)", r.get()),
        C::SetDataRate(r) => format!(
            "{sent}: device switches to {}; use --baud {} from now on",
            rate_text(*r),
            r.bits_per_second().unwrap_or(0)
        ),
        C::SetDeviceId(id) => format!("{sent}: device address set to {}", id.get()),
        _ => format!("{sent} acknowledged"),
    }
}
