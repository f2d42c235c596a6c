//! Results for people (physical units) and for scripts (JSON), one
//! function per result table (4A, 5, 6, 6A, 6B, 8, 9, 10, 13, 14, 15, 17).

use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{Angle, AwakeStatus, Command, DataRate, InitResults, Position, Reply};
use serde_json::{Value, json};

fn deg(a: Angle) -> f64 {
    f64::from(a.0) / 100.0
}

fn hundredths(v: u16) -> f64 {
    f64::from(v) / 100.0
}

fn bit_names(bits: u16, names: &[(u16, &'static str)]) -> Vec<&'static str> {
    names.iter().filter(|(b, _)| bits & b != 0).map(|(_, n)| *n).collect()
}

/// Table 6A.
const ERROR_BITS: [(u16, &str); 4] = [
    (1, "center_reference"),
    (1 << 4, "initialization"),
    (1 << 5, "motor_timeout"),
    (1 << 6, "temperature"),
];
/// Table 6B.
const STATUS_BITS: [(u16, &str); 8] = [
    (1, "not_initialized"),
    (1 << 1, "positive_limit_found"),
    (1 << 2, "negative_limit_found"),
    (1 << 3, "positive_center_found"),
    (1 << 4, "negative_center_found"),
    (1 << 5, "positive_hard_stop"),
    (1 << 6, "negative_hard_stop"),
    (1 << 7, "error_present"),
];

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
    json!({
        "raw": word,
        "center_switch_detected": word & 1 != 0,
        "hard_limit_detected": word & 4 != 0,
        "limit_switch_hit": word & 8 != 0,
    })
}

fn init_ok(r: &InitResults) -> bool {
    [r.pan_ccw, r.pan_cw, r.tilt_ccw, r.tilt_cw]
        .iter()
        .all(|w| w & 1 != 0 && w & 4 == 0)
}

fn awake(s: AwakeStatus) -> (String, Value) {
    let b = s.bits();
    let mut problems = Vec::new();
    for (bit, name) in [
        (AwakeStatus::PAN_NOT_INITIALIZED, "pan not initialised"),
        (AwakeStatus::TILT_NOT_INITIALIZED, "tilt not initialised"),
        (AwakeStatus::MOTORS_OFF, "motors off"),
        (AwakeStatus::ERROR, "error condition"),
    ] {
        if b & bit != 0 {
            problems.push(name);
        }
    }
    let text = if problems.is_empty() {
        "awake: hardware functioning properly".to_string()
    } else {
        format!("awake: {}", problems.join(", "))
    };
    let value = json!({
        "bits": b,
        "pan_initialized": b & AwakeStatus::PAN_NOT_INITIALIZED == 0,
        "tilt_initialized": b & AwakeStatus::TILT_NOT_INITIALIZED == 0,
        "motors_on": b & AwakeStatus::MOTORS_OFF == 0,
        "error": b & AwakeStatus::ERROR != 0,
    });
    (text, value)
}

/// Text and JSON of a result.
pub fn describe(reply: &Reply<'_>) -> (String, Value) {
    match *reply {
        Reply::AwakeStatus(s) => awake(s),
        Reply::MaxDataRate(r) => (
            format!("maximum data rate {}", rate_text(r)),
            json!({ "code": r.code(), "bps": r.bits_per_second() }),
        ),
        Reply::Identity(id) => {
            let name = String::from_utf8_lossy(id.name()).into_owned();
            let serial = String::from_utf8_lossy(id.serial()).into_owned();
            let revision = String::from_utf8_lossy(&id.revision).trim().to_string();
            (
                format!(
                    "device {:02X}  protocol revision {revision}  name {name:?}  serial {serial:?}",
                    id.id
                ),
                json!({ "id": id.id, "revision": revision, "name": name, "serial": serial }),
            )
        }
        Reply::Errors(e) => {
            let pan = bit_names(e.pan.into(), &ERROR_BITS);
            let tilt = bit_names(e.tilt.into(), &ERROR_BITS);
            (
                format!("errors: pan {} ; tilt {}", list(&pan), list(&tilt)),
                json!({ "pan": { "bits": e.pan, "set": pan }, "tilt": { "bits": e.tilt, "set": tilt } }),
            )
        }
        Reply::StatusBits(s) => {
            let pan = bit_names(s.pan, &STATUS_BITS);
            let tilt = bit_names(s.tilt, &STATUS_BITS);
            (
                format!("status: pan {} ; tilt {}", list(&pan), list(&tilt)),
                json!({ "pan": { "bits": s.pan, "set": pan }, "tilt": { "bits": s.tilt, "set": tilt } }),
            )
        }
        Reply::RateGains(g) => {
            let (p, t) = (f64::from(g.pan.get()) / 10.0, f64::from(g.tilt.get()) / 10.0);
            (
                format!("rate gains: pan {p:.1}  tilt {t:.1}"),
                json!({ "pan": p, "tilt": t }),
            )
        }
        Reply::Initialization(r) => {
            let ok = init_ok(&r);
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
        Reply::Limits(l) => (
            format!(
                "software limits (raw 12-bit): pan ccw {} cw {}  tilt ccw {} cw {}",
                l.pan_ccw.get(),
                l.pan_cw.get(),
                l.tilt_ccw.get(),
                l.tilt_cw.get()
            ),
            json!({
                "pan_ccw": l.pan_ccw.get(), "pan_cw": l.pan_cw.get(),
                "tilt_ccw": l.tilt_ccw.get(), "tilt_cw": l.tilt_cw.get(),
            }),
        ),
        Reply::Relays(bits) => {
            let on: Vec<u8> = (0..4).filter(|i| bits & (1 << i) != 0).collect();
            let text = if on.is_empty() {
                "relays: all off".to_string()
            } else {
                format!("relays on: {on:?}")
            };
            (text, json!({ "bits": bits, "on": on }))
        }
        Reply::Accelerations { pan, tilt } => (
            format!(
                "acceleration: pan {:.2} deg/s²  tilt {:.2} deg/s²",
                hundredths(pan.0),
                hundredths(tilt.0)
            ),
            json!({ "pan_deg_s2": hundredths(pan.0), "tilt_deg_s2": hundredths(tilt.0) }),
        ),
        Reply::Acceleration(a) => (
            format!("acceleration {:.2} deg/s²", hundredths(a.0)),
            json!({ "deg_s2": hundredths(a.0) }),
        ),
        Reply::Rates { pan, tilt } => (
            format!(
                "rate: pan {:.2} deg/s  tilt {:.2} deg/s",
                hundredths(pan.0),
                hundredths(tilt.0)
            ),
            json!({ "pan_deg_s": hundredths(pan.0), "tilt_deg_s": hundredths(tilt.0) }),
        ),
        Reply::Rate(r) => (
            format!("rate {:.2} deg/s", hundredths(r.0)),
            json!({ "deg_s": hundredths(r.0) }),
        ),
        Reply::VerifyHome(h) => {
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
        Reply::Position(p) => (position_text(&p), position_json(&p)),
        Reply::Lens(l) => (
            format!("zoom {}  focus {}", l.zoom.get(), l.focus.get()),
            json!({ "zoom": l.zoom.get(), "focus": l.focus.get() }),
        ),
        Reply::AuxCount(n) => (format!("{n} characters waiting"), json!({ "count": n })),
        Reply::AuxData(bytes) => (
            payload_text(bytes),
            json!({ "data": payload_text(bytes), "len": bytes.len() }),
        ),
        Reply::Raw(bytes) => (payload_text(bytes), json!({ "raw": payload_text(bytes) })),
    }
}

/// What an acknowledged command without result did, for people.
pub fn acknowledged_text(command: &Command<'_>) -> String {
    use Command as C;
    match command {
        C::GoTo(p) => format!("moving to {}", position_text(p).trim()),
        C::Home => "moving home (pan 0, tilt 0)".into(),
        C::GoToPreset(n) => format!("moving to preset {n:02X}"),
        C::StorePreset(n) => format!("current position stored as preset {n:02X}"),
        C::SetDataRate(r) => format!(
            "device switches to {}; use --baud {} from now on",
            rate_text(*r),
            r.bits_per_second().unwrap_or(0)
        ),
        C::SetDeviceId(id) => format!("device address set to {}", id.get()),
        other => format!("{} acknowledged", other.mnemonic()),
    }
}
