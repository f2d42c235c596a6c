//! Parsers of `gimbalctl`'s argument values: an address `G.P.D` (Table 2),
//! angles, rates, gains, speeds, presets, durations, host:port and ID lists;
//! each error names the value, its unit and its range.

use std::time::Duration;

use sagebrush_protocol::Address;

use super::IdList;

/// `G.P.D` (Table 2): an error names the part that is wrong (group, port
/// or device) and its range.
pub(super) fn parse_address(text: &str) -> Result<Address, String> {
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
    sagebrush_service::endpoint::host_port_arg(text)
}

/// `--tcp`: `HOST:PORT`, or `tls://HOST:PORT` for gcud over TLS.
pub fn parse_gcud(text: &str) -> Result<String, String> {
    match text.strip_prefix(sagebrush_host::tls::TLS_SCHEME) {
        Some(addr) => parse_host_port(addr).map(|_| text.to_owned()),
        None => parse_host_port(text),
    }
}

pub(super) fn parse_angle(what: &str, text: &str) -> Result<f64, String> {
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

pub(super) fn parse_pan(text: &str) -> Result<f64, String> {
    parse_angle("pan", text)
}

pub(super) fn parse_tilt(text: &str) -> Result<f64, String> {
    parse_angle("tilt", text)
}

pub(super) fn parse_hundredths(what: &str, unit: &str, text: &str) -> Result<f64, String> {
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

pub(super) fn parse_rate(text: &str) -> Result<f64, String> {
    parse_hundredths("rate", "deg/s", text)
}

pub(super) fn parse_accel(text: &str) -> Result<f64, String> {
    parse_hundredths("acceleration", "deg/s²", text)
}

pub(super) fn parse_gain(text: &str) -> Result<f64, String> {
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
pub(super) fn parse_speed(text: &str) -> Result<u8, String> {
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

pub(super) fn parse_digital(text: &str) -> Result<u8, String> {
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
pub(super) fn parse_bus(text: &str) -> Result<(u8, u8), String> {
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
