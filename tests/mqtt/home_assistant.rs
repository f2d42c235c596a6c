//! Home Assistant core as a real client (issue 51): its own `hass`
//! (tests/ha/install.sh, in tests/ha/.venv) on a temporary configuration,
//! set up through its HTTP API only (onboarding's first user, then the MQTT
//! integration's config flow pointed at the test's broker,
//! `tests/ha/api.py`), finds the gimbal's device by the door's discovery;
//! its service API moves and stops the gimbal, read on the bus.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::*;
use support::door::{assert_still, wait_for_stop, wait_moving};

/// How long Home Assistant may take to start and to see the discovered
/// entities: generous, its first start writes its storage and imports a
/// few hundred modules on a shared machine. A bound, not a measure.
const HA_GUARD: Duration = Duration::from_secs(240);

/// The entities a gimbal's device must have, by domain and friendly name
/// (the device's name `north mast`, then the entity's), as the door's
/// discovery describes them (bins/gimbal-mqtt/discovery.rs).
const ENTITIES: [(&str, &str); 9] = [
    ("number", "Pan position"),
    ("number", "Tilt position"),
    ("select", "Preset"),
    ("button", "Home"),
    ("button", "Stop"),
    ("sensor", "Pan"),
    ("sensor", "Tilt"),
    ("binary_sensor", "Moving"),
    ("sensor", "Controller"),
];

fn ha_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ha")
}

/// `hass` from tests/ha/.venv when its install finished, else the test
/// fails (or is skipped, [`support::SKIP_MISSING_TOOLS`]).
fn hass() -> Option<PathBuf> {
    let venv = ha_dir().join(".venv");
    if venv.join("complete").exists() {
        return Some(venv.join("bin/hass"));
    }
    support::tool_missing("Home Assistant core is missing: `bash tests/ha/install.sh` (./test.sh does it)");
    None
}

/// A running Home Assistant on 127.0.0.1 with its MQTT integration set up
/// on `broker`; stopped (SIGTERM) on drop.
struct HomeAssistant {
    child: Child,
    dir: tempfile::TempDir,
    url: String,
    token: String,
}

impl HomeAssistant {
    fn start(hass: &Path, broker: &Broker) -> Self {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
        let port = listener.local_addr().expect("port").port();
        drop(listener);
        let dir = tempfile::tempdir().expect("temp dir");
        // No default_config: the integrations Home Assistant always loads,
        // plus the three whose HTTP API the test uses.
        std::fs::write(
            dir.path().join("configuration.yaml"),
            format!(
                "homeassistant:\n  name: Sagebrush test\n  latitude: 0\n  longitude: 0\n  elevation: 0\n  \
                 unit_system: metric\n  time_zone: UTC\n  country: US\n  currency: USD\n\
                 http:\n  server_host: 127.0.0.1\n  server_port: {port}\n\
                 api:\nconfig:\nonboarding:\n"
            ),
        )
        .expect("write configuration.yaml");
        let out = std::fs::File::create(dir.path().join("hass.out")).expect("hass.out");
        let child = Command::new(hass)
            .arg("--config")
            .arg(dir.path())
            .arg("--skip-pip")
            .stdin(Stdio::null())
            .stdout(out.try_clone().expect("clone"))
            .stderr(out)
            .spawn()
            .expect("spawn hass");
        let mut ha = Self {
            child,
            dir,
            url: format!("http://127.0.0.1:{port}"),
            token: String::new(),
        };
        ha.wait_listening();
        let r = ha.api("setup", &[&broker.port.to_string()]);
        ha.token = r["token"].as_str().expect("a token").to_owned();
        ha
    }

    fn wait_listening(&mut self) {
        let started = Instant::now();
        let port = self.url.rsplit(':').next().expect("port").to_owned();
        while TcpStream::connect(format!("127.0.0.1:{port}")).is_err() {
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("hass exited ({status}):\n{}", self.log());
            }
            assert!(
                started.elapsed() < HA_GUARD,
                "Home Assistant never listened:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn log(&self) -> String {
        tail(
            &std::fs::read_to_string(self.dir.path().join("hass.out")).unwrap_or_default(),
            60,
        )
    }

    /// Runs a tests/ha/api.py step against this Home Assistant.
    fn api(&self, step: &str, args: &[&str]) -> Value {
        let out = Command::new(ha_dir().join(".venv/bin/python3"))
            .arg(ha_dir().join("api.py"))
            .arg(step)
            .arg(&self.url)
            .args(args)
            .output()
            .expect("run tests/ha/api.py");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "api.py {step} failed: {}\nstdout: {stdout}\nstderr: {}\nhass log:\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr),
            self.log()
        );
        serde_json::from_str(stdout.lines().last().unwrap_or_default())
            .unwrap_or_else(|e| panic!("api.py {step}: not JSON ({e}): {stdout}"))
    }

    fn states(&self) -> Vec<Value> {
        let token = self.token.clone();
        self.api("states", &[&token]).as_array().cloned().unwrap_or_default()
    }

    /// Calls `domain.service` on `entity_id` with `data`'s other fields.
    fn call(&self, domain: &str, service: &str, entity_id: &str, mut data: Value) {
        data["entity_id"] = Value::from(entity_id);
        let token = self.token.clone();
        self.api("service", &[&token, domain, service, &data.to_string()]);
    }
}

impl Drop for HomeAssistant {
    fn drop(&mut self) {
        support::terminate(&mut self.child);
    }
}

/// The state whose entity is in `domain` and whose friendly name is
/// `device`'s followed by `name`.
fn find<'a>(states: &'a [Value], device: &str, (domain, name): (&str, &str)) -> Option<&'a Value> {
    let friendly = format!("{device} {name}");
    states.iter().find(|s| {
        s["entity_id"]
            .as_str()
            .is_some_and(|id| id.starts_with(&format!("{domain}.")))
            && s["attributes"]["friendly_name"] == friendly.as_str()
    })
}

/// Polls Home Assistant's states until `ready` says they are (`Ok`);
/// its last `Err` says what was missing when the bound ran out.
fn wait_states(ha: &HomeAssistant, what: &str, mut ready: impl FnMut(&[Value]) -> Result<(), String>) -> Vec<Value> {
    let started = Instant::now();
    loop {
        let states = ha.states();
        let missing = match ready(&states) {
            Ok(()) => return states,
            Err(missing) => missing,
        };
        assert!(
            started.elapsed() < HA_GUARD,
            "Home Assistant never had {what}: {missing}; its states: {}\nhass log:\n{}",
            serde_json::to_string_pretty(&states).unwrap_or_default(),
            ha.log()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// `Ok` when the north mast's pan sensor reads `pan`.
fn pan_sensor_at(states: &[Value], pan: f64) -> Result<(), String> {
    let value = find(states, "north mast", ("sensor", "Pan")).map(|s| s["state"].clone());
    match value
        .as_ref()
        .and_then(Value::as_str)
        .and_then(|v| v.parse::<f64>().ok())
    {
        Some(v) if v == pan => Ok(()),
        _ => Err(format!("the pan sensor reads {value:?}")),
    }
}

fn entity_id(states: &[Value], entity: (&str, &str)) -> String {
    find(states, "north mast", entity).expect("found")["entity_id"]
        .as_str()
        .expect("an id")
        .to_owned()
}

#[test]
fn home_assistant_discovers_the_gimbal_and_its_services_move_and_stop_it() {
    let Some(hass) = hass() else { return };
    let Some(broker) = Broker::start() else { return };
    // A slew's lease long enough that only the Stop button can end it
    // within the test's bound (checked on the bus below).
    let site = Site::start_with(&broker, "north", "max_slew_ms = 60000", "");
    let ha = HomeAssistant::start(&hass, &broker);

    // Every entity of the device, available (its state not "unavailable":
    // the door's status and the gimbal's state say online; a button's or
    // the select's state stays "unknown" until used).
    let states = wait_states(&ha, "the north mast's entities, available", |states| {
        let missing: Vec<String> = ENTITIES
            .iter()
            .filter(|e| !find(states, "north mast", **e).is_some_and(|s| s["state"] != "unavailable"))
            .map(|(domain, name)| format!("{domain} \"north mast {name}\""))
            .collect();
        if missing.is_empty() {
            Ok(())
        } else {
            Err(format!("missing or unavailable: {}", missing.join(", ")))
        }
    });
    let select = find(&states, "north mast", ("select", "Preset")).expect("select");
    assert!(
        select["attributes"]["options"]
            .as_array()
            .is_some_and(|o| !o.is_empty()),
        "{select}"
    );
    wait_states(&ha, "the pan sensor at 0", |states| pan_sensor_at(states, 0.0));

    // The pan number: a goto on the bus, the tilt left where it is, and
    // Home Assistant's pan sensor following.
    let pan = entity_id(&states, ("number", "Pan position"));
    ha.call("number", "set_value", &pan, serde_json::json!({"value": 25}));
    wait_at(&site.gcud, MAST, 25.0, 0.0);
    assert!(
        site.door_motions(MAST).iter().any(|p| is_goto(p)),
        "{:?}",
        site.door_frames(MAST)
    );
    wait_states(&ha, "the pan sensor at 25", |states| pan_sensor_at(states, 25.0));

    // Stop during a slow slew (a paho client's command, 6 °/s, a 60 s
    // lease): the door's PS reaches the bus well before the lease could
    // have ended, and the gimbal stays where it stopped.
    let from = site.gcud.settled_position(MAST);
    let r = site.command(&broker, "mast", r#"{"slew": {"pan": 0.05, "lease_ms": 60000}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_moving(&site.gcud, MAST, from);
    let stop = entity_id(&states, ("button", "Stop"));
    ha.call("button", "press", &stop, serde_json::json!({}));
    wait_for_stop(&site.gcud, MAST, DOOR_GROUP, "PS");
    let stopped = site.gcud.settled_position(MAST);
    assert_still(&site.gcud, MAST, stopped, "after Home Assistant's Stop");
    let bus = support::frames_received_at(&site.gcud.log(), MAST);
    let slew = bus
        .iter()
        .rposition(|(_, p)| p == "PR" || p == "PL")
        .expect("the slew's PR on the bus");
    let (stop_at, _) = bus[slew..].iter().find(|(_, p)| p == "PS").expect("a PS after the PR");
    let after = stop_at - bus[slew].0;
    eprintln!("Home Assistant's Stop reached the bus {after:.2} s after the slew began");
    assert!(
        after < 45.0,
        "the PS came {after} s after the PR: the lease's end, not the button"
    );
}
