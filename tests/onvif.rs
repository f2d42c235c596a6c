//! End-to-end tests of `gimbal-onvif` (issue 21): the real gcud with
//! simulated gimbal buses, the real gimbal-onvif in front of it, driven by
//! third-party clients from PyPI (`onvif-zeep-async`, which Home Assistant
//! uses, and `WSDiscovery`'s message layer) through `tests/onvif/client.py`.
//! What the gimbal did is read on the bus side, with `gimbalctl position`
//! through gcud and the frames the simulated gimbal received (their source
//! group tells gimbal-onvif's own stops from gcud's dead-man), never from
//! gimbal-onvif's own account. Everything listens on 127.0.0.1; waits are
//! polls with a hang guard, never wall-clock assertions.
//!
//! Without Python and the two packages the client tests are skipped with a
//! notice, except under `CI=true`, where they fail.

mod support;

use std::path::Path;
use std::time::Duration;

use serde_json::{Value, json};
use support::door::{DOOR_GROUP, Door};
use support::eventually;
use support::gcud::Gcud;

const MAST: &str = "5.1.1";

/// Whether the third-party clients can run here; under CI they must.
fn clients_available() -> bool {
    support::door::onvif_client_available()
}

/// gcud with two simulated buses (the mast gimbal on bus 1; bus 2 has no
/// device 9, the absent gimbal) and gimbal-onvif in front of it.
struct Stack {
    /// Declared first: dropped (stopped) before gcud.
    onvif: Door,
    gcud: Gcud,
    /// The ONVIF device ports of `mast-1` and `absent`, and the discovery port.
    mast: u16,
    absent: u16,
    discovery: u16,
    /// What the configuration adds at its end (`[http] tls`).
    tail: String,
    /// The host the clients reach the devices at: `127.0.0.1`, or
    /// `https://127.0.0.1` in HTTPS.
    host: &'static str,
}

fn onvif_config(gcud: &str, state: &Path) -> String {
    format!(
        r#"gcud = "{gcud}"
state_file = "{}"
max_move_ms = 20000
poll_ms = 100
[discovery]
enabled = true
listen = "127.0.0.1:0"
[[user]]
name = "admin"
password = "adm1n-secret"
role = "administrator"
[[user]]
name = "op"
password = "op-secret"
role = "operator"
[[user]]
name = "viewer"
password = "viewer-secret"
role = "user"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
listen = "127.0.0.1:0"
stream_uri = "rtsp://127.0.0.1:8554/mast-1"
zoom = true
fov_deg = [60.0, 40.0]
fov_tele_deg = [6.0, 4.0]
[[gimbal]]
name = "absent"
address = "5.2.9"
listen = "127.0.0.1:0"
"#,
        state.display()
    )
}

impl Stack {
    fn start() -> Self {
        Self::with(support::door::start_gcud())
    }

    /// In front of the governed gcud (`support::door::start_governed_gcud`:
    /// the doors' link at priority 50, the operators' at 80).
    fn start_governed() -> Self {
        Self::with(support::door::start_governed_gcud())
    }

    /// In HTTPS: `[http] tls = "self-signed"`.
    fn start_https() -> Self {
        Self::with_tail(
            support::door::start_gcud(),
            "[http]\ntls = \"self-signed\"\n",
            "https://127.0.0.1",
        )
    }

    fn with(gcud: Gcud) -> Self {
        Self::with_tail(gcud, "", "127.0.0.1")
    }

    fn with_tail(gcud: Gcud, tail: &str, host: &'static str) -> Self {
        let mut stack = Self {
            onvif: Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif")),
            gcud,
            mast: 0,
            absent: 0,
            discovery: 0,
            tail: tail.to_owned(),
            host,
        };
        stack.spawn_onvif();
        stack
    }

    fn log(&self) -> String {
        self.onvif.log()
    }

    /// Starts gimbal-onvif (again, on the same state file) and learns its
    /// ports from its log.
    fn spawn_onvif(&mut self) {
        let state = self.onvif.dir.path().join("presets.toml");
        let config = onvif_config(&self.gcud.clients(), &state);
        self.onvif
            .start(&format!("source_group = {DOOR_GROUP}\n{config}{}", self.tail));
        self.mast = self.onvif.port("gimbal=mast-1 addr=");
        self.absent = self.onvif.port("gimbal=absent addr=");
        self.discovery = self.onvif.port("WS-Discovery listening");
    }

    /// Runs one step of the third-party client against the device on `port`.
    fn client(&self, step: &str, port: u16, user: (&str, &str), args: Value) -> Value {
        let host = if step == "discover" { "127.0.0.1" } else { self.host };
        let (port, args) = (port.to_string(), args.to_string());
        support::door::python_step(
            "tests/onvif/client.py",
            step,
            &[host, &port, user.0, user.1, &args],
            || self.log(),
        )
    }

    /// The mast gimbal's lens zoom read on the bus side (`gimbalctl lens`).
    fn bus_zoom(&self) -> u64 {
        let out = self.gcud.ctl(&["--json", "--to", MAST, "lens"]);
        assert_eq!(out.code, 0, "{out:?}");
        out.json()["result"]["zoom"].as_u64().expect("zoom")
    }

    /// The lens zoom once it stopped changing (read on the bus side) and
    /// left 0.
    fn settled_zoom(&self) -> u64 {
        let mut last = self.bus_zoom();
        eventually("the zoom to stop", || {
            std::thread::sleep(Duration::from_millis(200));
            let now = self.bus_zoom();
            let still = now == last && now > 0;
            last = now;
            still
        });
        last
    }

    fn bus_position(&self) -> (f64, f64) {
        self.gcud.position(MAST)
    }

    fn wait_moving(&self, from: (f64, f64)) {
        support::door::wait_moving(&self.gcud, MAST, from);
    }
}

const ADMIN: (&str, &str) = ("admin", "adm1n-secret");
const OPERATOR: (&str, &str) = ("op", "op-secret");
const VIEWER: (&str, &str) = ("viewer", "viewer-secret");

fn fault_subcodes(v: &Value) -> Vec<String> {
    v["fault"]["subcodes"]
        .as_array()
        .unwrap_or_else(|| panic!("expected a SOAP fault, got {v}"))
        .iter()
        .map(|s| s.as_str().unwrap().to_owned())
        .collect()
}

/// Position `(pan, tilt)` unchanged over about a second on the bus side.
fn assert_still(stack: &Stack, at: (f64, f64), what: &str) {
    support::door::assert_still(&stack.gcud, MAST, at, what);
}

// ---- the tests --------------------------------------------------------------

#[test]
fn a_unicast_probe_finds_one_device_per_gimbal_with_its_address() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let found = stack.client("discover", stack.discovery, ("-", "-"), json!({ "expect": 2 }));
    let matches = found["matches"].as_array().expect("matches");
    assert_eq!(matches.len(), 2, "{found}");
    for (name, port) in [("mast-1", stack.mast), ("absent", stack.absent)] {
        let m = matches
            .iter()
            .find(|m| {
                m["scopes"]
                    .to_string()
                    .contains(&format!("onvif://www.onvif.org/name/{name}"))
            })
            .unwrap_or_else(|| panic!("no ProbeMatch for {name}: {found}"));
        assert_eq!(
            m["xaddrs"],
            json!([format!("http://127.0.0.1:{port}/onvif/device_service")]),
            "{m}"
        );
        assert!(m["types"].to_string().contains("NetworkVideoTransmitter"), "{m}");
        assert!(
            m["scopes"].to_string().contains("onvif://www.onvif.org/type/ptz"),
            "{m}"
        );
    }
    assert_ne!(matches[0]["epr"], matches[1]["epr"], "each gimbal has its own endpoint");
    // A probe for one name's scope: only that gimbal answers.
    let scoped = stack.client(
        "discover",
        stack.discovery,
        ("-", "-"),
        json!({ "expect": 2, "wait_s": 1.5, "scopes": ["onvif://www.onvif.org/name/absent"] }),
    );
    let matches = scoped["matches"].as_array().expect("matches");
    assert_eq!(matches.len(), 1, "{scoped}");
    assert_eq!(
        matches[0]["xaddrs"],
        json!([format!("http://127.0.0.1:{}/onvif/device_service", stack.absent)])
    );
}

#[test]
fn device_information_carries_the_gimbals_serial_and_profiles_the_stream_uri() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let id = stack.gcud.ctl(&["--json", "--to", MAST, "id"]).json();
    let info = stack.client("info", stack.mast, VIEWER, json!({}));
    let device = &info["device"]["ok"];
    assert_eq!(device["SerialNumber"], id["result"]["serial"], "{info}");
    assert_eq!(device["Model"], id["result"]["name"], "{info}");
    assert_eq!(device["Manufacturer"], "Sagebrush");
    assert_eq!(device["HardwareId"], MAST);
    let profiles = info["profiles"].as_array().expect("profiles");
    assert_eq!(profiles.len(), 1, "{info}");
    assert_eq!(profiles[0]["ptz"], true);
    assert_eq!(profiles[0]["encoding"], "H264");
    assert_eq!(info["stream_uri"]["ok"], "rtsp://127.0.0.1:8554/mast-1");
    assert_eq!(info["hostname"], "mast-1");
    // The device's clock, which clients compare with theirs before signing.
    let now = time::OffsetDateTime::now_utc();
    assert_eq!(info["utc"]["year"], now.year(), "{info}");
    assert!(
        info["utc"]["hour"].as_u64().is_some(),
        "GetSystemDateAndTime without its Time: {info}"
    );
    assert_eq!(info["snapshot"], false);
    assert_eq!(info["eflip"], false);
    assert!(info["scopes"].to_string().contains("type/ptz"), "{info}");
    assert_eq!(info["presets_max"], 256);
}

#[test]
fn continuous_move_with_a_timeout_stops_by_itself() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let before = stack.bus_position();
    assert_eq!(before, (0.0, 0.0));
    // x = 0.5: speed 7 of 15, 60 °/s on the simulated gimbal; a move that
    // ignored its 1 s Timeout would run on for max_move_ms (20 s) and end
    // at the end of travel, 180°.
    let moved = stack.client(
        "continuous",
        stack.mast,
        OPERATOR,
        json!({ "x": 0.5, "y": 0.0, "timeout_s": 1.0 }),
    );
    assert_eq!(moved["ok"], true, "{moved}");
    // Stopped by the door's PS, where that PS put it by the bus's clock.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "PR", DOOR_GROUP, "PS");
    let dps = support::door::speed_on_bus(&log, MAST, "PR");
    support::door::assert_rests_where_stopped(pan, dps, moving, 180.0, "the 1 s Timeout's stop");
    assert_eq!(tilt, 0.0);
    // On the bus: gimbal-onvif's own PS after the PR, none from gcud.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(stack.log().contains("move time-out: stopping"), "{}", stack.log());
    assert_still(&stack, (pan, tilt), "after the time-out");
}

#[test]
fn absolute_move_arrives_within_half_a_degree_and_get_status_agrees() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    // Generic (0.25, -0.5) over pan [-180, 180] and tilt [-90, 90]: (45°, -45°).
    let r = stack.client("absolute", stack.mast, OPERATOR, json!({ "x": 0.25, "y": -0.5 }));
    assert_eq!(r["ok"], true, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 45.0).abs() <= 0.5 && (tilt + 45.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    let status = stack.client("status", stack.mast, VIEWER, json!({}));
    let x = status["x"].as_f64().expect("x");
    let y = status["y"].as_f64().expect("y");
    assert!((x * 180.0 - pan).abs() <= 0.5, "GetStatus x {x} vs bus pan {pan}");
    assert!((y * 90.0 - tilt).abs() <= 0.5, "GetStatus y {y} vs bus tilt {tilt}");
    assert_eq!(status["moving"], "IDLE", "{status}");
    assert!(status["error"].is_null(), "{status}");
}

#[test]
fn zoom_moves_the_lens_continuously_with_its_timeout_and_to_a_position() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    assert_eq!(stack.bus_zoom(), 0);
    // Zoom in at lens speed 4 of 9 for 0.5 s; the whole travel takes 2 s at
    // speed 9, so a move that ignored its Timeout (max_move_ms, 20 s) would
    // end at 4095.
    let r = stack.client(
        "continuous",
        stack.mast,
        OPERATOR,
        json!({ "x": 0.0, "y": 0.0, "zoom": 0.5, "timeout_s": 0.5 }),
    );
    assert_eq!(r["ok"], true, "{r}");
    let last = stack.settled_zoom();
    assert!(
        last > 0 && last < 4095,
        "zoomed in part of the way, then stopped: {last}"
    );
    assert_eq!(stack.bus_position(), (0.0, 0.0), "pan and tilt stayed");
    // AbsoluteMove of the zoom alone (no PanTilt): 0.25 of 0..4095, and
    // no GO on the bus.
    let r = stack.client("absolute", stack.mast, OPERATOR, json!({ "zoom": 0.25 }));
    assert_eq!(r["ok"], true, "{r}");
    eventually("the lens at 1024", || {
        std::thread::sleep(Duration::from_millis(100));
        stack.bus_zoom() == 1024
    });
    let received = stack.gcud.received(MAST);
    assert!(
        received
            .iter()
            .any(|(from, p)| *from == DOOR_GROUP && p.starts_with('V') && p != "V?"),
        "the lens was sent its position: {received:?}"
    );
    assert!(
        !received.iter().any(|(_, p)| p.starts_with("GO")),
        "pan and tilt were not commanded: {received:?}"
    );
    let status = stack.client("status", stack.mast, VIEWER, json!({}));
    assert!(
        (status["zoom"].as_f64().expect("zoom") - 0.25).abs() < 0.001,
        "{status}"
    );
    // The gimbal without a lens refuses to zoom, before anything is sent.
    let r = stack.client(
        "continuous",
        stack.absent,
        OPERATOR,
        json!({ "x": 0.0, "y": 0.0, "zoom": 0.5, "timeout_s": 0.5 }),
    );
    assert_eq!(fault_subcodes(&r), ["InvalidArgVal", "NoZoom"], "{r}");
}

#[test]
fn presets_round_trip_and_their_names_survive_a_restart() {
    if !clients_available() {
        return;
    }
    let mut stack = Stack::start();
    let r = stack.client("absolute", stack.mast, OPERATOR, json!({ "x": -0.5, "y": 0.5 }));
    assert_eq!(r["ok"], true, "{r}");
    let stored = stack.gcud.settled_position(MAST);
    let set = stack.client("set_preset", stack.mast, OPERATOR, json!({ "name": "gate" }));
    let token = set["ok"].as_str().unwrap_or_else(|| panic!("{set}")).to_owned();
    // A name that reads as another on an operator's screen (a right-to-left
    // override) is refused through the same client (issue 49).
    let hidden = stack.client(
        "set_preset",
        stack.mast,
        OPERATOR,
        json!({ "name": "gate\u{202E}2etag" }),
    );
    assert!(
        fault_subcodes(&hidden).iter().any(|s| s.ends_with("InvalidPresetName")),
        "{hidden}"
    );
    let r = stack.client("absolute", stack.mast, OPERATOR, json!({ "x": 0.0, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(stack.gcud.settled_position(MAST), (0.0, 0.0));

    stack.onvif.signal(nix::sys::signal::Signal::SIGTERM);
    stack.spawn_onvif();
    let presets = stack.client("presets", stack.mast, VIEWER, json!({}));
    assert_eq!(
        presets["presets"],
        json!([{ "token": token, "name": "gate" }]),
        "{presets}"
    );
    let r = stack.client("goto_preset", stack.mast, OPERATOR, json!({ "token": token }));
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(
        stack.gcud.settled_position(MAST),
        stored,
        "the preset is the gimbal's own"
    );
}

#[test]
fn stop_ends_a_continuous_move() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    // 7.5 °/s (speed 0) without a Timeout: only Stop (or max_move_ms, 20 s,
    // which the log would show) ends it before the end of travel at -180°
    // (24 s), so the stop's client may take its time on a busy machine (at
    // 30 °/s, 6 s of it under load 12 reached the end first).
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "x": -0.05, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    stack.wait_moving((0.0, 0.0));
    let r = stack.client("stop", stack.mast, OPERATOR, json!({}));
    assert!(r.get("ok").is_some(), "{r}");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!(pan < 0.0 && pan > -175.0, "stopped on its way left: {pan}");
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(!stack.log().contains("move time-out"), "{}", stack.log());
}

#[test]
fn stop_ends_a_zoom_without_a_timeout() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    // The zoom alone (no PanTilt) at lens speed 1 of 9, without a Timeout:
    // only Stop (or max_move_ms, 20 s) ends it before 4095.
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "zoom": 0.2 }));
    assert_eq!(r["ok"], true, "{r}");
    eventually("the zoom to move", || {
        std::thread::sleep(Duration::from_millis(50));
        stack.bus_zoom() > 0
    });
    let r = stack.client("stop", stack.mast, OPERATOR, json!({ "pan_tilt": false, "zoom": true }));
    assert!(r.get("ok").is_some(), "{r}");
    // On the bus: gimbal-onvif's ZS after the ZI, none from gcud.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "ZS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    let zoom = stack.settled_zoom();
    assert!(zoom > 0 && zoom < 4095, "stopped on its way in: {zoom}");
    assert_eq!(stack.bus_position(), (0.0, 0.0), "pan and tilt stayed");
    assert!(!stack.log().contains("move time-out"), "{}", stack.log());
}

#[test]
fn a_wrong_password_and_the_user_role_are_refused_and_nothing_moves() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let wrong = stack.client("login", stack.mast, ("op", "not-the-password"), json!({}));
    assert_eq!(fault_subcodes(&wrong), ["NotAuthorized"], "{wrong}");
    let viewer = stack.client(
        "continuous",
        stack.mast,
        VIEWER,
        json!({ "x": 1.0, "y": 1.0, "timeout_s": 5.0 }),
    );
    assert_eq!(fault_subcodes(&viewer), ["NotAuthorized"], "{viewer}");
    assert!(
        // The role as the configuration names it (issue 53: not its Debug form `Operator`).
        viewer["fault"]["message"]
            .as_str()
            .unwrap()
            .contains("the operator role"),
        "{viewer}"
    );
    let viewer_abs = stack.client("absolute", stack.mast, VIEWER, json!({ "x": 0.5, "y": 0.5 }));
    assert_eq!(fault_subcodes(&viewer_abs), ["NotAuthorized"], "{viewer_abs}");
    assert_still(&stack, (0.0, 0.0), "after refused requests");
}

#[test]
fn http_digest_authentication_works_as_the_alternative_to_ws_security() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let status =
        "<GetStatus xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken></GetStatus>";
    let ok = stack.client("http_digest", stack.mast, VIEWER, json!({ "operation": status }));
    assert_eq!(ok["status"], 200, "{ok}");
    assert!(ok["body"].as_str().unwrap().contains("PTZStatus"), "{ok}");
    let wrong = stack.client(
        "http_digest",
        stack.mast,
        ("viewer", "wrong"),
        json!({ "operation": status }),
    );
    assert_eq!(wrong["status"], 401, "{wrong}");
    assert!(
        wrong["challenge"]
            .as_str()
            .unwrap()
            .starts_with("Digest realm=\"gimbal-onvif\""),
        "{wrong}"
    );
    let mv = "<ContinuousMove xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken><Velocity><PanTilt xmlns=\"http://www.onvif.org/ver10/schema\" x=\"1\" y=\"0\"/></Velocity><Timeout>PT1S</Timeout></ContinuousMove>";
    let refused = stack.client("http_digest", stack.mast, VIEWER, json!({ "operation": mv }));
    assert_eq!(refused["status"], 400, "{refused}");
    assert!(
        refused["body"].as_str().unwrap().contains("ter:NotAuthorized"),
        "{refused}"
    );
    assert_still(&stack, (0.0, 0.0), "after a refused digest-authenticated move");
    let moved = stack.client("http_digest", stack.mast, OPERATOR, json!({ "operation": mv }));
    assert_eq!(moved["status"], 200, "{moved}");
    stack.wait_moving((0.0, 0.0));
}

#[test]
fn malformed_xml_and_bad_arguments_get_faults_and_move_nothing() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    for body in [
        "<s:Envelope><oops",
        "not xml at all",
        "<?xml version=\"1.0\"?><e:Envelope xmlns:e=\"http://www.w3.org/2003/05/soap-envelope\"><e:Body><ContinuousMove xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken><Velocity><PanTilt x=\"1\" y=\"1\"/></Velocity></ContinuousMove></e:Body>",
    ] {
        let r = stack.client("malformed", stack.mast, ("-", "-"), json!({ "body": body }));
        assert_eq!(r["status"], 400, "{r}");
        let text = r["body"].as_str().unwrap();
        assert!(text.contains("<s:Fault>") && text.contains("ter:WellFormed"), "{text}");
    }
    // A body over 64 KiB is refused unread.
    let big = format!("<x>{}</x>", "y".repeat(80 * 1024));
    let r = stack.client("malformed", stack.mast, ("-", "-"), json!({ "body": big }));
    assert_eq!(r["status"], 413, "{}", &r.to_string()[..200]);
    // Well-formed but unauthenticated: refused before anything is sent.
    let unsigned = "<?xml version=\"1.0\"?><e:Envelope xmlns:e=\"http://www.w3.org/2003/05/soap-envelope\"><e:Body><ContinuousMove xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken><Velocity><PanTilt x=\"1\" y=\"1\" xmlns=\"http://www.onvif.org/ver10/schema\"/></Velocity></ContinuousMove></e:Body></e:Envelope>";
    let r = stack.client("malformed", stack.mast, ("-", "-"), json!({ "body": unsigned }));
    assert!(r["body"].as_str().unwrap().contains("ter:NotAuthorized"), "{r}");
    let out_of_range = stack.client("out_of_range", stack.mast, ADMIN, json!({}));
    assert_eq!(
        fault_subcodes(&out_of_range),
        ["InvalidArgVal", "InvalidPosition"],
        "{out_of_range}"
    );
    let no_profile = stack.client("wrong_profile", stack.mast, ADMIN, json!({}));
    assert_eq!(
        fault_subcodes(&no_profile),
        ["InvalidArgVal", "NoProfile"],
        "{no_profile}"
    );
    assert_still(&stack, (0.0, 0.0), "after malformed requests");
}

#[test]
fn a_configured_gimbal_absent_from_the_bus_gets_a_fault_not_a_success() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let info = stack.client("info", stack.absent, ADMIN, json!({}));
    let device = &info["device"];
    assert_eq!(fault_subcodes(device), ["Action", "NotDelivered"], "{info}");
    assert!(device["fault"]["message"].as_str().unwrap().contains("5.2.9"), "{info}");
    let moved = stack.client(
        "continuous",
        stack.absent,
        OPERATOR,
        json!({ "x": 0.5, "y": 0.0, "timeout_s": 1.0 }),
    );
    assert_eq!(fault_subcodes(&moved), ["Action", "NotDelivered"], "{moved}");
    let abs = stack.client("absolute", stack.absent, OPERATOR, json!({ "x": 0.5, "y": 0.0 }));
    assert_eq!(fault_subcodes(&abs), ["Action", "NotDelivered"], "{abs}");
    eventually("GetStatus to report the unreachable gimbal", || {
        let status = stack.client("status", stack.absent, VIEWER, json!({}));
        status["error"].as_str().is_some_and(|e| e.contains("not delivered"))
    });
}

#[test]
fn sigkill_of_gimbal_onvif_mid_move_and_the_gimbal_stops() {
    if !clients_available() {
        return;
    }
    let mut stack = Stack::start();
    // 30 °/s for up to max_move_ms (20 s) if nothing stopped it: the end of
    // travel, 180°, after 6 s.
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "x": 0.25, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.onvif.signal(nix::sys::signal::Signal::SIGKILL);
    assert!(!status.success());
    support::door::assert_dead_man_stopped(&stack.gcud, MAST);
}

#[test]
fn sigterm_stops_what_gimbal_onvif_started() {
    if !clients_available() {
        return;
    }
    let mut stack = Stack::start();
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "x": 0.0, "y": 0.25 }));
    assert_eq!(r["ok"], true, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.onvif.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status}\n{}", stack.log());
    // Where gimbal-onvif's TS put it (30 °/s), by the bus's clock.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    let (_, tilt) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "TU", DOOR_GROUP, "TS");
    let dps = support::door::speed_on_bus(&log, MAST, "TU");
    support::door::assert_rests_where_stopped(tilt, dps, moving, 90.0, "gimbal-onvif's stop at SIGTERM");
    // gimbal-onvif stopped it itself, on the bus: its TS after the TU, and
    // nothing from gcud's group (its dead-man) once its connection closed.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(stack.log().contains("stopping:"), "{}", stack.log());
    assert!(!stack.gcud.log().contains("dead-man"), "{}", stack.gcud.log());
}

#[test]
fn check_names_the_file_line_column_and_key_and_exits_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = onvif_config("127.0.0.1:4001", &dir.path().join("p.toml"));
    let path = dir.path().join("o.toml");
    let check = |text: &str| {
        std::fs::write(&path, text).expect("write");
        support::door::check(env!("CARGO_BIN_EXE_gimbal-onvif"), &path)
    };
    let ok = check(&good);
    assert_eq!(ok.status.code(), Some(0), "{ok:?}");
    let bad = check(&good.replace("address = \"5.2.9\"", "address = \"5.2\""));
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains(&format!(
            "{}:30:11: gimbal[1].address: expected GROUP.PORT.DEVICE",
            path.display()
        )),
        "{err}"
    );
    let bad = check(&good.replace("role = \"user\"", "role = \"guest\""));
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("user[2].role: expected administrator, operator or user"));
}

#[test]
fn the_shipped_configuration_documents_every_key_and_passes_check() {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gimbal-onvif.toml"))
        .expect("config/gimbal-onvif.toml");
    // Every key the parser knows is in the file (set or commented out).
    for key in [
        "gcud",
        "source_group",
        "state_file",
        "max_move_ms",
        "poll_ms",
        "nic_window_ms",
        "enabled",
        "listen",
        "name",
        "password",
        "password_file",
        "role",
        "address",
        "stream_uri",
        "pan_deg",
        "tilt_deg",
        "zoom",
        "fov_deg",
        "fov_tele_deg",
        "tls",
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start_matches(['#', ' ']).starts_with(&format!("{key} ="))),
            "config/gimbal-onvif.toml does not document {key}"
        );
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let pass = dir.path().join("admin.pass");
    std::fs::write(&pass, "s3cret\n").expect("password file");
    let path = dir.path().join("gimbal-onvif.toml");
    std::fs::write(
        &path,
        text.replace("/etc/gimbal-onvif/admin.pass", &pass.display().to_string()),
    )
    .expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-onvif"), &path);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
}

#[test]
fn the_shipped_unit_is_hardened_and_checks_its_configuration_first() {
    support::door::assert_unit_has(
        "gimbal-onvif.service",
        &[
            "Type=notify",
            "ExecStartPre=/usr/bin/gimbal-onvif --check --config /etc/gimbal-onvif/gimbal-onvif.toml",
            "DynamicUser=yes",
            "StateDirectory=gimbal-onvif",
            "NoNewPrivileges=yes",
            "CapabilityBoundingSet=",
            "ProtectSystem=strict",
            "PrivateDevices=yes",
            "RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX",
            "SystemCallFilter=@system-service",
            "MemoryDenyWriteExecute=yes",
            "KillSignal=SIGTERM",
        ],
    );
}

const FOV_SPACE: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationSpaceFov";
const TRANSLATION_GENERIC: &str = "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationGenericSpace";

/// gcud decides who controls a gimbal (issue 32, ARCHITECTURE
/// "Front doors"): while the operators' link (priority 80, gimbalctl) holds
/// the mast gimbal, a VMS's moves through gimbal-onvif (the doors' link,
/// priority 50) get a SOAP fault naming the holder, never a success;
/// GetStatus does not report the refused move as a motion, and the door
/// sends no stop that would end the holder's slew.
/// Needs gcud's `[control] hold_ms` and `[[link]] priority`.
#[test]
fn moves_while_a_higher_priority_link_holds_the_gimbal_get_a_fault_naming_it() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start_governed();
    let from = stack.bus_position();
    let slew = support::door::OperatorsSlew::start(&stack.gcud, MAST);
    stack.wait_moving(from);
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "x": -0.5, "y": 0.0 }));
    assert_eq!(fault_subcodes(&r), ["Action", "NotInControl"], "{r}");
    let reason = r["fault"]["message"].as_str().unwrap();
    assert!(
        reason.contains(support::door::OPERATORS_HOLDER),
        "the reason names the holder: {r}"
    );
    // The holder's slew goes on: the refused door stopped nothing (its bus
    // traffic, queries only, is checked below; whether the slew still runs
    // now depends on how long the client took: under load it reached the
    // end of travel first).
    drop(slew);
    let at = stack.gcud.settled_position(MAST);
    // Refused while the gimbal is still: GetStatus says IDLE right after.
    let r = stack.client(
        "continuous",
        stack.mast,
        OPERATOR,
        json!({ "x": 0.5, "y": 0.5, "status_after": true }),
    );
    assert_eq!(fault_subcodes(&r), ["Action", "NotInControl"], "{r}");
    assert_eq!(r["status"]["moving"], "IDLE", "a refused move is no motion: {r}");
    let r = stack.client("absolute", stack.mast, OPERATOR, json!({ "x": 0.5, "y": 0.5 }));
    assert_eq!(fault_subcodes(&r), ["Action", "NotInControl"], "{r}");
    let r = stack.client("set_preset", stack.mast, OPERATOR, json!({ "name": "gate" }));
    assert_eq!(fault_subcodes(&r), ["Action", "NotInControl"], "{r}");
    assert_still(&stack, at, "refused moves");
    support::door::assert_door_sent_only_queries(&stack.gcud, MAST);
    eprintln!("refused: {reason}");
}

/// Frigate's autotracker and Milestone's centre-click move in the FOV
/// translation space (ONVIF PTZ, "Pan/tilt Translation Space in FOV"): the
/// image centre is (0, 0) and its right edge x = 1, so with mast-1's
/// configured field of view of 60° x 40° at the wide end, (1, 0) turns the
/// pan by 30°, (0.5, 0) by 15° and (0, -1) the tilt by -20° (linear in the
/// angle: no lens projection is modelled); at the tele end (zoom 1, 6° x
/// 4°), (1, 0) turns it by 3°. Positions are read on the bus side, and
/// GetStatus agrees with them at the end of every move.
#[test]
fn relative_move_in_the_fov_space_turns_by_the_field_of_view() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let spaces = stack.client("relative_spaces", stack.mast, ADMIN, json!({}));
    for list in ["node", "options"] {
        let fov = spaces[list]
            .as_array()
            .and_then(|l| l.iter().find(|s| s["uri"] == FOV_SPACE))
            .unwrap_or_else(|| panic!("no FOV space in the {list}: {spaces}"));
        assert_eq!(fov["x"], json!([-1.0, 1.0]), "{spaces}");
        assert_eq!(fov["y"], json!([-1.0, 1.0]), "{spaces}");
    }
    assert_eq!(spaces["default"], FOV_SPACE, "the profile's default: {spaces}");
    // The profile's default space (no space named), then named.
    let r = stack.client("relative", stack.mast, ADMIN, json!({ "x": 1.0, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 30.0).abs() <= 0.5 && tilt.abs() <= 0.5,
        "(1, 0): bus at {pan}, {tilt}"
    );
    assert_status_at(&r, (pan, tilt));
    let r = stack.client(
        "relative",
        stack.mast,
        ADMIN,
        json!({ "x": 0.5, "y": -1.0, "space": FOV_SPACE }),
    );
    assert_eq!(r["ok"], true, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 45.0).abs() <= 0.5 && (tilt + 20.0).abs() <= 0.5,
        "(0.5, -1): bus at {pan}, {tilt}"
    );
    assert_status_at(&r, (pan, tilt));
    // The generic space when named: x over the whole travel (360°), 0.25 = 45°.
    let r = stack.client(
        "relative",
        stack.mast,
        ADMIN,
        json!({ "x": -0.25, "y": 0.0, "space": TRANSLATION_GENERIC }),
    );
    assert_eq!(r["ok"], true, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        pan.abs() <= 0.5 && (tilt + 20.0).abs() <= 0.5,
        "generic (-0.25, 0): bus at {pan}, {tilt}"
    );
    // A space the node does not offer: a fault, never read as another.
    let r = stack.client(
        "relative",
        stack.mast,
        ADMIN,
        json!({ "x": 0.5, "y": 0.0, "space": "http://www.onvif.org/ver10/tptz/PanTiltSpaces/TranslationSpaceDegrees" }),
    );
    assert_eq!(fault_subcodes(&r), ["InvalidArgVal", "SpaceNotSupported"], "{r}");
    // The gimbal without a field of view offers no FOV space.
    let r = stack.client(
        "relative",
        stack.absent,
        ADMIN,
        json!({ "x": 0.5, "y": 0.0, "space": FOV_SPACE }),
    );
    assert_eq!(fault_subcodes(&r), ["InvalidArgVal", "SpaceNotSupported"], "{r}");
    let spaces = stack.client("relative_spaces", stack.absent, ADMIN, json!({}));
    assert_eq!(spaces["default"], TRANSLATION_GENERIC, "{spaces}");
    // A zoom translation (no relative zoom space is offered): refused,
    // and the pan and tilt beside it do not move either.
    let r = stack.client(
        "relative",
        stack.mast,
        ADMIN,
        json!({ "x": 0.5, "y": 0.0, "zoom": 0.2 }),
    );
    assert_eq!(fault_subcodes(&r), ["InvalidArgVal", "SpaceNotSupported"], "{r}");
    support::door::assert_still(&stack.gcud, MAST, (0.0, -20.0), "refused translations");
    // Zoomed to the tele end (6° x 4°): the field of view the move is in
    // follows the lens.
    let r = stack.client("absolute", stack.mast, ADMIN, json!({ "zoom": 1.0 }));
    assert_eq!(r["ok"], true, "{r}");
    eventually("the lens at 4095", || {
        std::thread::sleep(Duration::from_millis(100));
        stack.bus_zoom() == 4095
    });
    let r = stack.client("relative", stack.mast, ADMIN, json!({ "x": 1.0, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 3.0).abs() <= 0.5 && (tilt + 20.0).abs() <= 0.5,
        "(1, 0) at the tele end: bus at {pan}, {tilt}"
    );
    assert_status_at(&r, (pan, tilt));
}

/// A move's answer ends with GetStatus IDLE at the position on the bus
/// (the generic position of pan [-180, 180] and tilt [-90, 90]).
fn assert_status_at(r: &Value, (pan, tilt): (f64, f64)) {
    let status = &r["status"];
    assert_eq!(status["moving"], "IDLE", "MoveStatus at the end: {r}");
    let x = status["x"].as_f64().expect("x");
    let y = status["y"].as_f64().expect("y");
    assert!(
        (x * 180.0 - pan).abs() <= 0.05 && (y * 90.0 - tilt).abs() <= 0.05,
        "GetStatus ({x}, {y}) at the end vs the bus ({pan}, {tilt}): {r}"
    );
}

const GET_STATUS: &str =
    "<GetStatus xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken></GetStatus>";

/// Older clients and VMSs speak SOAP 1.1 (`text/xml`, a SOAPAction
/// header) or send SOAP 1.2 with an `action` parameter or none: what is
/// asked is the Body's element, never the action, and the answer is in the
/// request's SOAP version with its content type (issue 33).
#[test]
fn soap_1_1_and_action_less_requests_are_answered_by_their_body() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    let raw = |soap: &str, content_type: &str, action: Option<&str>, body: &str| {
        stack.client(
            "signed_raw",
            stack.mast,
            OPERATOR,
            json!({ "soap": soap, "content_type": content_type, "soap_action": action, "body": body }),
        )
    };
    // SOAP 1.1 with a SOAPAction naming another operation: GetStatus answers.
    let nodes_action = "\"http://www.onvif.org/ver20/ptz/wsdl/GetNodes\"";
    let r = raw("1.1", "text/xml; charset=utf-8", Some(nodes_action), GET_STATUS);
    assert_eq!(r["status"], 200, "{r}");
    assert_eq!(r["content_type"], "text/xml; charset=utf-8", "{r}");
    let body = r["body"].as_str().unwrap();
    assert!(
        body.contains("xmlns:s=\"http://schemas.xmlsoap.org/soap/envelope/\"") && body.contains("GetStatusResponse"),
        "{body}"
    );
    // A SOAP 1.1 fault: HTTP 500, faultcode and the ONVIF subcodes.
    let r = raw("1.1", "text/xml", None, &GET_STATUS.replace("profile1", "nope"));
    assert_eq!(r["status"], 500, "{r}");
    let body = r["body"].as_str().unwrap();
    assert!(
        body.contains("<faultcode>s:Client</faultcode>") && body.contains("ter:NoProfile"),
        "{body}"
    );
    // A move in SOAP 1.1 moves: AbsoluteMove to generic (0.25, 0), 45°.
    let absolute = "<AbsoluteMove xmlns=\"http://www.onvif.org/ver20/ptz/wsdl\"><ProfileToken>profile1</ProfileToken><Position><PanTilt xmlns=\"http://www.onvif.org/ver10/schema\" x=\"0.25\" y=\"0\"/></Position></AbsoluteMove>";
    let r = raw("1.1", "text/xml; charset=utf-8", Some("\"\""), absolute);
    assert_eq!(r["status"], 200, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!((pan - 45.0).abs() <= 0.5 && tilt.abs() <= 0.5, "bus at {pan}, {tilt}");
    // SOAP 1.2 with an action parameter naming another operation, and
    // with none: the Body's element is answered, as application/soap+xml.
    for content_type in [
        "application/soap+xml; charset=utf-8; action=\"http://www.onvif.org/ver20/ptz/wsdl/GetNodes\"",
        "application/soap+xml",
    ] {
        let r = raw("1.2", content_type, None, GET_STATUS);
        assert_eq!(r["status"], 200, "{content_type}: {r}");
        assert_eq!(r["content_type"], "application/soap+xml; charset=utf-8", "{r}");
        let body = r["body"].as_str().unwrap();
        assert!(
            body.contains("xmlns:s=\"http://www.w3.org/2003/05/soap-envelope\"") && body.contains("GetStatusResponse"),
            "{body}"
        );
    }
}

/// What npm `onvif` (Scrypted, Node-RED) and Synology check before they
/// keep a camera: the first video source's token is the one the profile's
/// video source configuration uses, GetCompatibleConfigurations lists the
/// profile's own PTZ configuration, and CreateProfile answers the
/// MaxNVTProfiles fault (ONVIF Media). SetConfiguration's
/// DefaultPTZTimeout is read back and stops a ContinuousMove without a
/// Timeout.
#[test]
fn tokens_agree_and_set_configuration_sets_the_default_timeout() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start();
    for port in [stack.mast, stack.absent] {
        let t = stack.client("tokens", port, ADMIN, json!({}));
        assert_eq!(t["video_source"], "videosource1", "{t}");
        assert_eq!(t["profiles_using_it"], json!(["profile1"]), "{t}");
        assert_eq!(t["compatible"], json!([t["ptz_configuration"].clone()]), "{t}");
        assert_eq!(
            fault_subcodes(&t["create_profile"]),
            ["Action", "MaxNVTProfiles"],
            "{t}"
        );
    }
    let t = stack.client("tokens", stack.mast, ADMIN, json!({}));
    assert_eq!(t["compatible_default_space"], json!([FOV_SPACE]), "{t}");
    // An operator may not change the configuration; an administrator may.
    let r = stack.client("set_timeout", stack.mast, OPERATOR, json!({ "timeout_s": 2.0 }));
    assert_eq!(fault_subcodes(&r), ["NotAuthorized"], "{r}");
    let r = stack.client("set_timeout", stack.mast, ADMIN, json!({ "timeout_s": 30.0 }));
    assert_eq!(
        fault_subcodes(&r),
        ["InvalidArgVal", "ConfigModify"],
        "beyond max_move_ms: {r}"
    );
    let r = stack.client("set_timeout", stack.mast, ADMIN, json!({ "timeout_s": 2.0 }));
    assert_eq!(r["timeout_s"], 2.0, "{r}");
    // 30 °/s without a Timeout: stopped after 2 s (about 60°), well short
    // of the end of travel that max_move_ms (20 s) would allow.
    let r = stack.client("continuous", stack.mast, OPERATOR, json!({ "x": 0.25, "y": 0.0 }));
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let (pan, _) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "PR", DOOR_GROUP, "PS");
    let dps = support::door::speed_on_bus(&log, MAST, "PR");
    support::door::assert_rests_where_stopped(pan, dps, moving, 180.0, "the default timeout's stop");
    assert!(stack.log().contains("move time-out"), "{}", stack.log());
}

/// A ContinuousMove through onvif-zeep-async on a governed gimbal right
/// after gcud starts (issue 48: the door's session sends a speed, then the
/// direction, and gcud refused the direction for not knowing the rate):
/// gcud learns what it needs, the gimbal moves, and gcud's own stop keeps
/// it short of its keep-out zone (where it rests, read on the bus).
#[test]
fn a_continuous_move_on_a_governed_gimbal_moves_it_and_stops_short_of_its_zone() {
    if !clients_available() {
        return;
    }
    let rules = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                 [[gimbal.keep_out]]\npan_deg = [30.0, 60.0]\ntilt_deg = [-30.0, 10.0]\n";
    let stack = Stack::with(support::door::start_governed_gcud_with(rules));
    // x = 0.5: speed 7 of 15, 60 °/s; 10 s would carry it far past the zone.
    let moved = stack.client(
        "continuous",
        stack.mast,
        OPERATOR,
        json!({ "x": 0.5, "y": 0.0, "timeout_s": 10.0 }),
    );
    assert_eq!(moved["ok"], true, "{moved}\n{}", stack.log());
    support::door::wait_for_stop(&stack.gcud, MAST, support::door::GCUD_GROUP, "PS");
    let (pan, _) = stack.gcud.settled_position(MAST);
    eprintln!("ContinuousMove toward the zone: rests at pan {pan} (zone from 30)");
    assert!(pan > 10.0, "it moved: {pan}");
    assert!(pan <= 30.5, "into the zone: {pan}\n{}", stack.gcud.log());
}

/// In HTTPS (issue 49, `[http] tls = "self-signed"`): onvif-zeep-async
/// reaches the device at https:// and follows its XAddrs, which say https
/// (GetCapabilities, GetServices, WS-Discovery's ProbeMatch); a client
/// trusting only the kept certificate verifies it for 127.0.0.1; a
/// ContinuousMove reaches the bus; plain HTTP to the port gets a 400.
#[test]
fn over_https_the_xaddrs_say_https_and_a_move_reaches_the_bus() {
    if !clients_available() {
        return;
    }
    let stack = Stack::start_https();
    let cert = stack.onvif.dir.path().join("gimbal-onvif-self-signed.crt");
    let base = format!("https://127.0.0.1:{}/onvif/", stack.mast);
    let x = stack.client("xaddrs", stack.mast, ADMIN, json!({ "cert": cert }));
    assert_eq!(x["verified"], 200, "{x}\n{}", stack.log());
    for list in ["capabilities", "services", "followed"] {
        let addrs = x[list].as_array().unwrap_or_else(|| panic!("{list}: {x}"));
        assert!(!addrs.is_empty(), "{x}");
        for a in addrs {
            assert!(
                a.as_str().is_some_and(|a| a.starts_with(&base)),
                "{list}: {a} is not under {base}"
            );
        }
    }
    let found = stack.client("discover", stack.discovery, ("-", "-"), json!({ "expect": 2 }));
    for m in found["matches"].as_array().expect("matches") {
        let xaddr = m["xaddrs"][0].as_str().unwrap_or_default();
        assert!(xaddr.starts_with("https://127.0.0.1:"), "{found}");
    }
    let from = stack.bus_position();
    let moved = stack.client(
        "continuous",
        stack.mast,
        OPERATOR,
        json!({ "x": 0.5, "y": 0.0, "timeout_s": 1.5 }),
    );
    assert_eq!(moved["ok"], true, "{moved}");
    stack.wait_moving(from);
    let stopped = stack.client("stop", stack.mast, OPERATOR, json!({}));
    assert!(stopped.get("ok").is_some(), "{stopped}");
    let addr = format!("127.0.0.1:{}", stack.mast);
    let plain = support::door::plain_raw(
        &addr,
        &format!(
            "POST /onvif/device_service HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/soap+xml\r\nContent-Length: 2\r\n\r\n<x"
        ),
    );
    assert!(
        plain.starts_with("HTTP/1.1 400") && plain.contains("https://"),
        "{plain:?}"
    );
}
