//! `gimbalctl gcud-status --http HOST:PORT`: what a running gcud knows, from
//! its `/status` document (served beside `/metrics`, `[metrics] listen`):
//! the daemon, each port with the devices it has seen (online, last position
//! and lens position answered, last error), each link, who controls each
//! governed or held gimbal and each tour (ARCHITECTURE "Governance"). Text
//! tables, or with `--json` the document itself under `status`.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde_json::{Value, json};

use crate::error::CtlError;

/// How long to wait for gcud's answer.
const TIMEOUT: Duration = Duration::from_secs(5);

/// Fetches `/status` from gcud's metrics listener.
fn fetch(http: &str) -> Result<Value, CtlError> {
    let url = format!("http://{http}/status");
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(TIMEOUT))
        .http_status_as_error(false)
        .build()
        .into();
    let mut response = agent
        .get(&url)
        .call()
        .map_err(|e| CtlError::Io(fetch_failed(&url, http, &e)))?;
    let status = response.status();
    let body = response
        .body_mut()
        .read_to_string()
        .map_err(|e| CtlError::Io(format!("reading {url}: {e}")))?;
    if status == 403 {
        return Err(CtlError::Io(format!(
            "{url}: gcud refused this address (403: not in its [metrics] allow_peers)"
        )));
    }
    if !status.is_success() {
        return Err(CtlError::Io(format!("{url}: HTTP {status}: {}", body.trim())));
    }
    serde_json::from_str(&body).map_err(|e| CtlError::BadReply(format!("{url}: not a gcud status document: {e}")))
}

/// Why `url` could not be read, in words (ureq's own say "timeout: global").
fn fetch_failed(url: &str, http: &str, e: &ureq::Error) -> String {
    let why = match e {
        ureq::Error::Timeout(_) => format!("no answer within {} s", TIMEOUT.as_secs()),
        ureq::Error::Io(io) => io.to_string(),
        other => other.to_string(),
    };
    format!("cannot read {url}: {why} (is gcud running, with [metrics] listen = \"{http}\"?)")
}

pub fn run(http: &str, as_json: bool) -> Result<(), CtlError> {
    let status = fetch(http)?;
    if as_json {
        sagebrush_host::outln!(
            "{}",
            json!({ "ok": true, "command": "gcud-status", "http": http, "status": status })
        );
    } else {
        sagebrush_host::out!("{}", text(&status, now_unix()));
    }
    Ok(())
}

fn now_unix() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// "3 s ago", "never".
fn ago(at: &Value, now: f64) -> String {
    match at.as_f64() {
        Some(t) => {
            let s = (now - t).max(0.0);
            if s < 120.0 {
                format!("{s:.0} s ago")
            } else if s < 7200.0 {
                format!("{:.0} min ago", s / 60.0)
            } else {
                format!("{:.1} h ago", s / 3600.0)
            }
        }
        None => "never".to_owned(),
    }
}

/// A device's ONLINE cell: `not yet heard` for a configured gimbal that
/// has not answered since gcud started (offline, never seen).
fn online(d: &Value) -> &'static str {
    match (d["online"].as_bool(), &d["last_seen_unix"]) {
        (Some(true), _) => "yes",
        (_, Value::Null) => "not yet heard",
        _ => "no",
    }
}

fn yes(v: &Value) -> &'static str {
    if v.as_bool() == Some(true) { "yes" } else { "no" }
}

/// Rows under a header, each column as wide as its widest cell.
fn table(indent: &str, header: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: Vec<&str>| {
        let mut out = indent.to_owned();
        for (i, (cell, w)) in cells.iter().zip(&widths).enumerate() {
            if i + 1 == cells.len() {
                out.push_str(cell);
            } else {
                out.push_str(&format!("{cell:<w$}  "));
            }
        }
        out.trim_end().to_owned() + "\n"
    };
    let mut out = line(header.to_vec());
    for row in rows {
        out.push_str(&line(row.iter().map(String::as_str).collect()));
    }
    out
}

/// The status document as text tables.
fn text(s: &Value, now: f64) -> String {
    let g = &s["gcud"];
    let mut out = format!(
        "gcud {} \"{}\" (group {}), up {:.1} s, {} command(s) in progress, {} connection(s){}\n",
        g["version"].as_str().unwrap_or("?"),
        g["name"].as_str().unwrap_or(""),
        g["group"],
        g["uptime_ms"].as_f64().unwrap_or(0.0) / 1000.0,
        g["commands_in_progress"],
        g["connections_open"],
        if g["shutting_down"].as_bool() == Some(true) {
            ", SHUTTING DOWN"
        } else {
            ""
        },
    );
    for port in s["ports"].as_array().map_or(&[][..], Vec::as_slice) {
        out.push('\n');
        out.push_str(&format!(
            "port {}: {}, {} bit/s, {} waiting, {} transactions, frames in/out {}/{}, {} time-outs, {} bad checksums, last byte {}\n",
            port["port"],
            if port["open"].as_bool() == Some(true) { "open" } else { "CLOSED" },
            port["bps"],
            port["queue_length"],
            port["transactions"],
            port["frames_in"],
            port["frames_out"],
            port["timeouts"],
            port["bad_checksums"],
            ago(&port["last_seen_unix"], now),
        ));
        if port["devices"].as_array().is_none_or(Vec::is_empty) {
            out.push_str("  no device addressed yet\n");
            continue;
        }
        let header = [
            "DEVICE",
            "ONLINE",
            "LAST SEEN",
            "LAST POSITION",
            "LENS",
            "COMMANDS",
            "LAST ERROR",
        ];
        section(&mut out, &port["devices"], "  ", &header, |d| {
            let lens = match &d["lens"] {
                Value::Null => "-".to_owned(),
                l => format!("zoom {} focus {}", l["zoom"], l["focus"]),
            };
            let error = match &d["last_error"] {
                Value::Null => "-".to_owned(),
                e => format!("{} ({})", e["message"].as_str().unwrap_or("?"), ago(&e["unix"], now)),
            };
            vec![
                d["address"].as_str().unwrap_or("?").to_owned(),
                online(d).to_owned(),
                ago(&d["last_seen_unix"], now),
                position(&d["position"], now),
                lens,
                d["commands"].to_string(),
                error,
            ]
        });
    }
    let header = ["LINK", "ROLE", "UP", "CONNECTIONS", "FRAMES IN/OUT", "LAST SEEN"];
    section(&mut out, &s["links"], "", &header, |l| {
        vec![
            l["link"].as_str().unwrap_or("?").to_owned(),
            l["role"].as_str().unwrap_or("?").to_owned(),
            yes(&l["up"]).to_owned(),
            l["connections"].to_string(),
            format!("{}/{}", l["frames_in"], l["frames_out"]),
            ago(&l["last_seen_unix"], now),
        ]
    });
    let header = [
        "GIMBAL",
        "CONTROLLED BY",
        "LAPSES",
        "LIMITS/ZONES",
        "LAST POSITION (GCUD)",
    ];
    section(&mut out, &s["control"], "", &header, |c| {
        let lapses = match c["lapses_in_ms"].as_f64() {
            Some(ms) => format!("in {:.1} s", ms / 1000.0),
            None => "-".to_owned(),
        };
        vec![
            c["address"].as_str().unwrap_or("?").to_owned(),
            holder(&c["holder"]),
            lapses,
            yes(&c["bounded"]).to_owned(),
            position(&c["position"], now),
        ]
    });
    section(&mut out, &s["tours"], "", &["TOUR", "GIMBAL", "STATE", "STEP"], |t| {
        let state = match (t["state"].as_str().unwrap_or("?"), &t["waiting_for"]) {
            ("waiting", Value::Null) => "waiting".to_owned(),
            ("waiting", who) => format!("waiting for {}", holder(who)),
            (state, _) => state.to_owned(),
        };
        vec![
            t["name"].as_str().unwrap_or("?").to_owned(),
            t["address"].as_str().unwrap_or("?").to_owned(),
            state,
            t["step"].to_string(),
        ]
    });
    out
}

/// A table of `list`'s entries, one `row` each; nothing when the list is
/// empty or absent. A table of the document's own (no `indent`) follows a
/// blank line, one nested under a port's line follows that line.
fn section(out: &mut String, list: &Value, indent: &str, header: &[&str], row: impl Fn(&Value) -> Vec<String>) {
    let Some(entries) = list.as_array().filter(|l| !l.is_empty()) else {
        return;
    };
    if indent.is_empty() {
        out.push('\n');
    }
    let rows: Vec<Vec<String>> = entries.iter().map(row).collect();
    out.push_str(&table(indent, header, &rows));
}

/// A position from `/status`: `pan 12.50° tilt -3.00° (5 s ago)`, `-` when
/// never read; "moved since" (and when) once a motion went to the gimbal
/// after that reading.
fn position(p: &Value, now: f64) -> String {
    if p.is_null() {
        return "-".to_owned();
    }
    let read = format!(
        "pan {:.2}° tilt {:.2}° ({})",
        p["pan_deg"].as_f64().unwrap_or(f64::NAN),
        p["tilt_deg"].as_f64().unwrap_or(f64::NAN),
        ago(&p["unix"], now)
    );
    match &p["moved_unix"] {
        Value::Null => read,
        moved => format!("{read}, moved since ({})", ago(moved, now)),
    }
}

/// Who controls a gimbal, from `/status`: `link operators (priority 80)`,
/// `tour perimeter`, `park`, `nobody`.
fn holder(h: &Value) -> String {
    match (h["kind"].as_str(), h["name"].as_str()) {
        (Some("link"), Some(name)) => match h["via"].as_str() {
            Some(via) => format!("{name} via {via} (priority {})", h["priority"]),
            None => format!("link {name} (priority {})", h["priority"]),
        },
        (Some("tour"), Some(name)) => format!("tour {name}"),
        (Some(kind), _) => kind.to_owned(),
        (None, _) => "nobody".to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_names_every_device_with_its_position_and_error() {
        let status = json!({
            "gcud": {"version": "0.1.0", "group": 5, "name": "field", "started_unix": 1000.0,
                     "uptime_ms": 2500, "shutting_down": false, "commands_in_progress": 0, "connections_open": 1},
            "ports": [{"port": 1, "open": true, "bps": 9600, "queue_length": 0, "transactions": 3,
                       "frames_in": 2, "frames_out": 3, "timeouts": 1, "bad_checksums": 0, "last_seen_unix": 1090.0,
                       "devices": [
                         {"device": 1, "address": "5.1.1", "online": true, "last_seen_unix": 1095.0,
                          "position": {"pan_deg": 12.5, "tilt_deg": -3.0, "unix": 1095.0}, "lens": null,
                          "last_error": null, "commands": 2, "unreachable": 0, "no_result": 0, "nics": 0},
                         {"device": 9, "address": "5.1.9", "online": false, "last_seen_unix": null,
                          "position": null, "lens": null, "commands": 1, "unreachable": 1, "no_result": 0, "nics": 0,
                          "last_error": {"error": "device_silent", "message": "did not acknowledge", "unix": 1098.0}}]}],
            "links": [{"link": "clients", "role": "client", "up": true, "connections": 1,
                       "frames_in": 3, "frames_out": 4, "last_seen_unix": 1099.0}],
            "control": [
                {"address": "5.1.1", "holder": {"kind": "link", "name": "operators", "priority": 80},
                 "lapses_in_ms": 8500, "bounded": true,
                 "position": {"pan_deg": 10.0, "tilt_deg": 2.5, "unix": 1099.0}},
                {"address": "5.1.9", "holder": null, "lapses_in_ms": null, "bounded": true, "position": null}],
            "tours": [{"name": "perimeter", "address": "5.1.1", "state": "waiting", "step": 2,
                       "waiting_for": {"kind": "link", "name": "operators", "priority": 80}}]
        });
        let text = text(&status, 1100.0);
        assert!(text.starts_with("gcud 0.1.0 \"field\" (group 5), up 2.5 s"), "{text}");
        let one = text.lines().find(|l| l.contains("5.1.1")).expect("device 1");
        assert!(
            one.contains("yes") && one.contains("pan 12.50° tilt -3.00° (5 s ago)"),
            "{one}"
        );
        let nine = text.lines().find(|l| l.contains("5.1.9")).expect("device 9");
        assert!(
            nine.contains("never") && nine.contains("did not acknowledge (2 s ago)"),
            "{nine}"
        );
        assert!(
            text.lines().any(|l| l.starts_with("clients") && l.contains("3/4")),
            "{text}"
        );
        let held = text.lines().find(|l| l.starts_with("5.1.1")).expect("control of 5.1.1");
        assert!(
            held.contains("link operators (priority 80)") && held.contains("in 8.5 s"),
            "{held}"
        );
        assert!(
            text.lines().any(|l| l.starts_with("5.1.9") && l.contains("nobody")),
            "{text}"
        );
        let tour = text.lines().find(|l| l.starts_with("perimeter")).expect("the tour");
        assert!(tour.contains("waiting for link operators (priority 80)"), "{tour}");
    }
}
