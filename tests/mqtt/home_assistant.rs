//! Home Assistant core as a real client of gimbal-mqtt: the release for
//! the machine's Python (2024.3 on 3.11) in its own virtual environment,
//! `tests/ha/.venv` (made by `tests/ha/setup.sh`, which `.ci/run` runs),
//! started on a private configuration with `--skip-pip`, a user added
//! with its `auth` script, its MQTT integration configured through its own
//! config flow over the HTTP API and pointed at the test's broker. The
//! discovered device must have the issue's entities, and Home Assistant's
//! service API must move and stop the gimbal, read on the bus.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::{Value, json};

use super::*;
use support::door::assert_still;

/// A running Home Assistant; stopped on drop.
struct HomeAssistant {
    child: Child,
    dir: tempfile::TempDir,
    addr: String,
    token: String,
}

fn hass_bin() -> Option<PathBuf> {
    let bin = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ha/.venv/bin/hass");
    if !bin.exists() {
        support::tool_missing(&format!(
            "Home Assistant core is missing ({}): `bash tests/ha/setup.sh` (.ci/run does it)",
            bin.display()
        ));
        return None;
    }
    Some(bin)
}

/// An HTTP/1.1 exchange with Home Assistant: (status, JSON body).
fn http(addr: &str, method: &str, path: &str, token: Option<&str>, body: Option<(&str, String)>) -> (u16, Value) {
    let auth = token.map(|t| format!("Authorization: Bearer {t}\r\n")).unwrap_or_default();
    let (kind, body) = body.unwrap_or(("application/json", String::new()));
    let request = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\n{auth}Content-Type: {kind}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let answer = support::door::plain_raw(addr, &request);
    let status = answer
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = answer.split_once("\r\n\r\n").map(|(_, b)| b).unwrap_or_default();
    // Home Assistant answers with a length, or chunked: take the JSON part.
    let json_start = body.find(['{', '[']).unwrap_or(body.len());
    let json_end = body.rfind(['}', ']']).map_or(json_start, |e| e + 1);
    let value = serde_json::from_str(&body[json_start..json_end.max(json_start)]).unwrap_or(Value::Null);
    (status, value)
}

impl HomeAssistant {
    fn start(bin: &Path) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .expect("a free port")
            .local_addr()
            .expect("port")
            .port();
        std::fs::write(
            dir.path().join("configuration.yaml"),
            format!(
                "homeassistant:\n  name: sagebrush test\n  latitude: 0\n  longitude: 0\n  elevation: 0\n  \
                 unit_system: metric\n  time_zone: UTC\n  currency: EUR\n  country: DE\n\
                 http:\n  server_host: 127.0.0.1\n  server_port: {port}\napi:\nconfig:\n\
                 logger:\n  default: warning\n  logs:\n    homeassistant.components.mqtt: debug\n"
            ),
        )
        .expect("configuration.yaml");
        let added = Command::new(bin)
            .args(["--script", "auth", "--config"])
            .arg(dir.path())
            .args(["add", "tester", "test-password"])
            .output()
            .expect("hass --script auth");
        assert!(added.status.success(), "hass --script auth add: {added:?}");
        let child = Command::new(bin)
            .arg("--config")
            .arg(dir.path())
            .arg("--skip-pip")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn hass");
        let addr = format!("127.0.0.1:{port}");
        let mut ha = Self {
            child,
            dir,
            addr,
            token: String::new(),
        };
        let started = Instant::now();
        while http(&ha.addr, "GET", "/api/", None, None).0 != 401 {
            assert!(
                started.elapsed() < Duration::from_secs(300),
                "Home Assistant never answered; log:\n{}",
                ha.log()
            );
            std::thread::sleep(Duration::from_millis(500));
        }
        ha.token = ha.sign_in();
        ha
    }

    fn log(&self) -> String {
        tail(
            &std::fs::read_to_string(self.dir.path().join("home-assistant.log")).unwrap_or_default(),
            60,
        )
    }

    /// Home Assistant's login flow, then its token endpoint: an access token.
    fn sign_in(&self) -> String {
        let client = format!("http://{}/", self.addr);
        let (_, flow) = http(
            &self.addr,
            "POST",
            "/auth/login_flow",
            None,
            Some((
                "application/json",
                json!({"client_id": client, "handler": ["homeassistant", null], "redirect_uri": client}).to_string(),
            )),
        );
        let flow_id = flow["flow_id"].as_str().unwrap_or_else(|| panic!("login flow: {flow}"));
        let (_, done) = http(
            &self.addr,
            "POST",
            &format!("/auth/login_flow/{flow_id}"),
            None,
            Some((
                "application/json",
                json!({"client_id": client, "username": "tester", "password": "test-password"}).to_string(),
            )),
        );
        let code = done["result"].as_str().unwrap_or_else(|| panic!("login: {done}"));
        let form = format!("grant_type=authorization_code&code={code}&client_id={client}");
        let (_, token) = http(
            &self.addr,
            "POST",
            "/auth/token",
            None,
            Some(("application/x-www-form-urlencoded", form)),
        );
        token["access_token"]
            .as_str()
            .unwrap_or_else(|| panic!("token: {token}"))
            .to_owned()
    }

    fn api(&self, method: &str, path: &str, body: Option<Value>) -> (u16, Value) {
        http(
            &self.addr,
            method,
            path,
            Some(&self.token),
            body.map(|b| ("application/json", b.to_string())),
        )
    }

    /// The MQTT integration through its config flow, on `port`.
    fn add_mqtt(&self, port: u16) {
        let (_, form) = self.api(
            "POST",
            "/api/config/config_entries/flow",
            Some(json!({"handler": "mqtt", "show_advanced_options": false})),
        );
        let flow_id = form["flow_id"]
            .as_str()
            .unwrap_or_else(|| panic!("mqtt flow: {form}\n{}", self.log()));
        let (_, entry) = self.api(
            "POST",
            &format!("/api/config/config_entries/flow/{flow_id}"),
            Some(json!({"broker": "127.0.0.1", "port": port})),
        );
        assert_eq!(entry["type"], "create_entry", "{entry}\n{}", self.log());
    }

    /// The entity ids of the states whose id holds `part`.
    fn entities(&self, part: &str) -> Vec<String> {
        let (_, states) = self.api("GET", "/api/states", None);
        states
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|s| s["entity_id"].as_str())
                    .filter(|id| id.contains(part))
                    .map(str::to_owned)
                    .collect()
            })
            .unwrap_or_default()
    }
}

impl Drop for HomeAssistant {
    fn drop(&mut self) {
        support::terminate(&mut self.child);
    }
}

#[test]
fn home_assistant_discovers_the_gimbal_and_drives_it() {
    let Some(broker) = Broker::start() else { return };
    let Some(bin) = hass_bin() else { return };
    let site = Site::start(&broker, "north");
    let ha = HomeAssistant::start(&bin);
    ha.add_mqtt(broker.port);
    let wanted = [
        "number.north_mast_pan_position",
        "number.north_mast_tilt_position",
        "select.north_mast_preset",
        "button.north_mast_home",
        "button.north_mast_stop",
        "sensor.north_mast_pan",
        "sensor.north_mast_tilt",
        "binary_sensor.north_mast_moving",
        "sensor.north_mast_controller",
    ];
    let mut found = Vec::new();
    eventually("Home Assistant to discover the mast", || {
        found = ha.entities("north_mast");
        wanted.iter().all(|w| found.iter().any(|f| f == w))
    });
    found.sort();
    eprintln!("Home Assistant's entities of the mast: {found:?}");
    // Available, and reading the bus's position.
    eventually("the pan sensor's state", || {
        ha.api("GET", "/api/states/sensor.north_mast_pan", None).1["state"] == "0.0"
    });

    let (status, _) = ha.api(
        "POST",
        "/api/services/number/set_value",
        Some(json!({"entity_id": "number.north_mast_pan_position", "value": 25})),
    );
    assert_eq!(status, 200, "{}", ha.log());
    wait_at(&site.gcud, MAST, 25.0, 0.0);

    // A long slew through MQTT, stopped by Home Assistant's Stop button.
    let r = site.command(&broker, "mast", r#"{"slew": {"pan": 0.2, "lease_ms": 5000}}"#);
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_moving(&site.gcud, MAST, (25.0, 0.0));
    let (status, _) = ha.api(
        "POST",
        "/api/services/button/press",
        Some(json!({"entity_id": "button.north_mast_stop"})),
    );
    assert_eq!(status, 200, "{}", ha.log());
    support::door::wait_for_stop(&site.gcud, MAST, DOOR_GROUP, "PS");
    let stopped = site.gcud.settled_position(MAST);
    assert_still(&site.gcud, MAST, stopped, "after Home Assistant's Stop");
}
