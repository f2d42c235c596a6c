//! A command message on `<prefix>/<site>/<gimbal>/cmd` (README "MQTT"):
//! one JSON object with one command and an optional `id`, read within
//! bounds, and the result message on `.../result` that answers it,
//! `{"id": ..., "ok": bool, "reason": "..."}`.

use std::time::Duration;

use serde::Deserialize;
use serde_json::{Value, json};

/// The largest command payload read; a larger one is answered with a
/// reason, unread.
pub const MAX_PAYLOAD: usize = 4096;
/// The longest `id` echoed (a string); a longer one is refused.
pub const MAX_ID: usize = 128;
/// A slew's lease when the message gives none.
pub const DEFAULT_LEASE: Duration = Duration::from_millis(1000);

/// What a command message asks of its gimbal.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `GO` to these angles; an axis not given stays where it is.
    GoTo {
        pan: Option<f64>,
        tilt: Option<f64>,
    },
    /// Each axis given at a signed fraction of the top speed (0 stops it),
    /// for `lease`.
    Slew {
        pan: Option<f64>,
        tilt: Option<f64>,
        lease: Duration,
    },
    Stop,
    Home,
    PresetRecall(u8),
    PresetStore(u8),
    Release,
}

impl Command {
    /// The command's name in results and logs.
    pub fn name(&self) -> &'static str {
        match self {
            Command::GoTo { .. } => "goto",
            Command::Slew { .. } => "slew",
            Command::Stop => "stop",
            Command::Home => "home",
            Command::PresetRecall(_) => "preset recall",
            Command::PresetStore(_) => "preset store",
            Command::Release => "release",
        }
    }

    /// Its kind in the door's metrics (`requests_total{kind}`): its name,
    /// one word (beside `malformed`, a message not read as a command,
    /// `retained` and `no_such_gimbal`, counted where they are refused).
    pub fn kind(&self) -> &'static str {
        match self {
            Command::PresetRecall(_) => "preset_recall",
            Command::PresetStore(_) => "preset_store",
            other => other.name(),
        }
    }
}

/// A parsed message: its `id` (JSON `null` when it has none or it could
/// not be read) and its command, or why it was refused unread.
#[derive(Debug)]
pub struct Request {
    pub id: Value,
    pub command: Result<Command, String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Payload {
    #[serde(default)]
    id: Value,
    goto: Option<GoTo>,
    slew: Option<Slew>,
    stop: Option<bool>,
    home: Option<bool>,
    preset: Option<Preset>,
    release: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GoTo {
    pan_deg: Option<f64>,
    tilt_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Slew {
    pan: Option<f64>,
    tilt: Option<f64>,
    lease_ms: Option<u64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Preset {
    recall: Option<u8>,
    store: Option<u8>,
}

/// The message's id, when it is one that may be echoed: a string of at
/// most [`MAX_ID`] bytes or a number.
fn echoable(id: &Value) -> Result<Value, String> {
    match id {
        Value::Null | Value::Number(_) => Ok(id.clone()),
        Value::String(s) if s.len() <= MAX_ID => Ok(id.clone()),
        Value::String(s) => Err(format!("id: {} bytes, at most {MAX_ID}", s.len())),
        _ => Err("id: expected a string or a number".to_owned()),
    }
}

/// Reads `payload`; `max_slew` bounds a slew's lease.
pub fn parse(payload: &[u8], max_slew: Duration) -> Request {
    if payload.len() > MAX_PAYLOAD {
        return Request {
            id: Value::Null,
            command: Err(format!(
                "payload of {} bytes, at most {MAX_PAYLOAD}: not read",
                payload.len()
            )),
        };
    }
    // The error names the key at fault (`preset.recall: invalid value ...`).
    let read = serde_path_to_error::deserialize(&mut serde_json::Deserializer::from_slice(payload));
    let p: Payload = match read {
        Ok(p) => p,
        Err(e) => {
            // The id of a message that is JSON but not a command is still echoed.
            let id = serde_json::from_slice::<Value>(payload)
                .ok()
                .and_then(|v| v.get("id").cloned())
                .and_then(|id| echoable(&id).ok())
                .unwrap_or(Value::Null);
            return Request {
                id,
                command: Err(format!("not a command: {e}")),
            };
        }
    };
    let id = match echoable(&p.id) {
        Ok(id) => id,
        Err(e) => {
            return Request {
                id: Value::Null,
                command: Err(e),
            };
        }
    };
    Request {
        id,
        command: command(p, max_slew),
    }
}

fn command(p: Payload, max_slew: Duration) -> Result<Command, String> {
    let given = [
        p.goto.is_some(),
        p.slew.is_some(),
        p.stop.is_some(),
        p.home.is_some(),
        p.preset.is_some(),
        p.release.is_some(),
    ];
    match given.iter().filter(|g| **g).count() {
        1 => {}
        0 => return Err("expected one of goto, slew, stop, home, preset, release".to_owned()),
        _ => return Err("expected one command per message, found several".to_owned()),
    }
    let flag = |v: Option<bool>, name: &str, c: Command| match v {
        Some(true) => Some(Ok(c)),
        Some(false) => Some(Err(format!("{name}: expected true"))),
        None => None,
    };
    if let Some(c) = flag(p.stop, "stop", Command::Stop)
        .or_else(|| flag(p.home, "home", Command::Home))
        .or_else(|| flag(p.release, "release", Command::Release))
    {
        return c;
    }
    if let Some(g) = p.goto {
        return goto(g);
    }
    if let Some(s) = p.slew {
        return slew(s, max_slew);
    }
    match p.preset {
        Some(Preset {
            recall: Some(n),
            store: None,
        }) => Ok(Command::PresetRecall(n)),
        Some(Preset {
            recall: None,
            store: Some(n),
        }) => Ok(Command::PresetStore(n)),
        _ => Err("preset: expected {\"recall\": N} or {\"store\": N}, N in 0..=255".to_owned()),
    }
}

/// An angle a `GO` can carry (Table 15: hundredths of a degree in i16).
fn angle(v: Option<f64>, key: &str) -> Result<Option<f64>, String> {
    match v {
        Some(d) if !d.is_finite() || !(-327.68..=327.67).contains(&d) => {
            Err(format!("goto.{key}: {d} is no angle in -327.68..=327.67"))
        }
        v => Ok(v),
    }
}

fn goto(g: GoTo) -> Result<Command, String> {
    let pan = angle(g.pan_deg, "pan_deg")?;
    let tilt = angle(g.tilt_deg, "tilt_deg")?;
    if pan.is_none() && tilt.is_none() {
        return Err("goto: expected pan_deg, tilt_deg or both".to_owned());
    }
    Ok(Command::GoTo { pan, tilt })
}

fn slew(s: Slew, max_slew: Duration) -> Result<Command, String> {
    for (v, key) in [(s.pan, "pan"), (s.tilt, "tilt")] {
        if let Some(v) = v {
            if !v.is_finite() || !(-1.0..=1.0).contains(&v) {
                return Err(format!(
                    "slew.{key}: {v} is not a signed fraction of the top speed, -1..=1"
                ));
            }
        }
    }
    if s.pan.is_none() && s.tilt.is_none() {
        return Err("slew: expected pan, tilt or both".to_owned());
    }
    let lease = match s.lease_ms {
        None => DEFAULT_LEASE.min(max_slew),
        Some(ms) if ms == 0 || ms > max_slew.as_millis() as u64 => {
            return Err(format!(
                "slew.lease_ms: {ms}, expected 1..={} (max_slew_ms)",
                max_slew.as_millis()
            ));
        }
        Some(ms) => Duration::from_millis(ms),
    };
    Ok(Command::Slew {
        pan: s.pan,
        tilt: s.tilt,
        lease,
    })
}

/// The result message of a command with `id`.
pub fn result(id: &Value, ok: bool, reason: &str) -> Vec<u8> {
    json!({ "id": id, "ok": ok, "reason": reason }).to_string().into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAX: Duration = Duration::from_secs(5);

    fn ok(text: &str) -> Command {
        parse(text.as_bytes(), MAX).command.unwrap()
    }

    fn err(text: &str) -> String {
        parse(text.as_bytes(), MAX).command.unwrap_err()
    }

    #[test]
    fn every_documented_command() {
        assert_eq!(
            ok(r#"{"goto": {"pan_deg": 10.0, "tilt_deg": -5.0}}"#),
            Command::GoTo {
                pan: Some(10.0),
                tilt: Some(-5.0)
            }
        );
        assert_eq!(
            ok(r#"{"slew": {"pan": 0.5, "tilt": 0.0, "lease_ms": 1000}}"#),
            Command::Slew {
                pan: Some(0.5),
                tilt: Some(0.0),
                lease: Duration::from_millis(1000)
            }
        );
        assert_eq!(ok(r#"{"stop": true}"#), Command::Stop);
        assert_eq!(ok(r#"{"home": true}"#), Command::Home);
        assert_eq!(ok(r#"{"preset": {"recall": 1}}"#), Command::PresetRecall(1));
        assert_eq!(ok(r#"{"preset": {"store": 2}}"#), Command::PresetStore(2));
        assert_eq!(ok(r#"{"release": true}"#), Command::Release);
        assert_eq!(parse(br#"{"id": "a-1", "stop": true}"#, MAX).id, json!("a-1"));
        assert_eq!(parse(br#"{"id": 7, "stop": true}"#, MAX).id, json!(7));
    }

    #[test]
    fn what_is_refused_says_why() {
        assert!(err("not json").starts_with("not a command: "));
        assert!(err(r#"{"fly": true}"#).contains("unknown field `fly`"));
        assert_eq!(
            err(r#"{"stop": true, "home": true}"#),
            "expected one command per message, found several"
        );
        assert_eq!(err(r#"{"stop": false}"#), "stop: expected true");
        assert!(err(r#"{"slew": {"pan": 2}}"#).starts_with("slew.pan: 2 is not"));
        assert!(err(r#"{"slew": {"pan": 0.5, "lease_ms": 60000}}"#).contains("expected 1..=5000"));
        assert!(err(r#"{"goto": {"pan_deg": 1e9}}"#).contains("no angle"));
        assert!(err(r#"{"preset": {"recall": 300}}"#).starts_with("not a command: preset.recall: invalid value"));
        assert!(err(r#"{"preset": {}}"#).starts_with("preset: expected"));
        let huge = vec![b' '; MAX_PAYLOAD + 1];
        assert_eq!(
            err(std::str::from_utf8(&huge).unwrap()),
            "payload of 4097 bytes, at most 4096: not read"
        );
        // The id of a refused command is echoed, when it can be.
        assert_eq!(parse(br#"{"id": "x", "fly": 1}"#, MAX).id, json!("x"));
        assert_eq!(parse(br#"{"id": [1], "stop": true}"#, MAX).id, Value::Null);
    }
}
