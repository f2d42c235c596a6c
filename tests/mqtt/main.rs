//! gimbal-mqtt end to end (issue 51): Debian's Mosquitto, started per test
//! on a free loopback port with a generated configuration (never the
//! system's service; installed by `.ci/run`), paho-mqtt as the client
//! (`tests/mqtt/client.py`, installed from tests/requirements.txt), real
//! gcud with its simulated buses and the real gimbal-mqtt. What a gimbal
//! did is read on the bus side (the simulated gimbals' `rx frame` record
//! in gcud's log, `gimbalctl position`), never in the door's account.
//! Home Assistant core is a client too (`home_assistant`, its own venv
//! made by tests/ha/install.sh).

#[path = "../support/mod.rs"]
mod support;

mod attack;
mod commands;
mod connection;
mod figures;
mod home_assistant;
mod metrics;
mod principals;
mod sites;

use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use support::door::{DOOR_GROUP, Door, python_client_available, python_step};
use support::gcud::Gcud;
use support::{HANG_GUARD, eventually};

const MAST: &str = "5.1.1";
const GATE: &str = "5.2.1";

/// A Mosquitto broker of one test on 127.0.0.1, on a port the system
/// chose; stopped on drop. [`Broker::restart`] starts it again on the
/// same port (nothing persisted: a restart forgets every retained message).
pub(crate) struct Broker {
    child: Option<Child>,
    pub port: u16,
    dir: tempfile::TempDir,
}

/// Whether Debian's mosquitto is installed; when it is not the test fails
/// (or is skipped, [`support::SKIP_MISSING_TOOLS`]).
fn mosquitto() -> Option<PathBuf> {
    let found = ["/usr/sbin/mosquitto", "/usr/bin/mosquitto"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.exists());
    if found.is_none() {
        support::tool_missing("mosquitto is missing: `apt-get install mosquitto` (.ci/run does it)");
    }
    found
}

impl Broker {
    /// A broker, or `None` when mosquitto or paho-mqtt is missing and
    /// skipping was asked for.
    pub fn start() -> Option<Self> {
        Self::start_with("")
    }

    /// A broker with the mosquitto.conf lines `tls` after its plain
    /// listener (a second listener, with TLS).
    pub fn start_with(tls: &str) -> Option<Self> {
        let bin = mosquitto()?;
        if !python_client_available("paho.mqtt.client", "paho-mqtt") {
            return None;
        }
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
        let port = listener.local_addr().expect("port").port();
        drop(listener);
        let dir = tempfile::tempdir().expect("temp dir");
        let config = dir.path().join("mosquitto.conf");
        std::fs::write(
            &config,
            format!(
                "allow_anonymous true\npersistence false\nlog_dest file {}\nlog_type all\nuser root\n\
                 listener {port} 127.0.0.1\n{tls}\n",
                dir.path().join("mosquitto.log").display()
            ),
        )
        .expect("write mosquitto.conf");
        let _ = bin;
        let mut b = Self { child: None, port, dir };
        b.run();
        Some(b)
    }

    fn run(&mut self) {
        let child = Command::new(mosquitto().expect("mosquitto"))
            .arg("-c")
            .arg(self.dir.path().join("mosquitto.conf"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn mosquitto");
        self.child = Some(child);
        let port = self.port;
        eventually("mosquitto to listen", || {
            TcpStream::connect(("127.0.0.1", port)).is_ok()
        });
    }

    pub fn url(&self) -> String {
        format!("mqtt://127.0.0.1:{}", self.port)
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("mosquitto.log")).unwrap_or_default()
    }

    /// Stops the broker (SIGTERM) and waits for it to exit.
    pub fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            support::terminate(&mut c);
        }
    }

    /// Starts the stopped broker again on its port.
    pub fn restart(&mut self) {
        self.stop();
        self.run();
    }

    /// Runs a `tests/mqtt/client.py` step against this broker.
    pub fn step(&self, step: &str, args: &[&str], log: impl FnOnce() -> String) -> Value {
        let port = self.port.to_string();
        let mut full = vec![port.as_str()];
        full.extend_from_slice(args);
        python_step("tests/mqtt/client.py", step, &full, log)
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A site: a gcud under governance with its two simulated buses and a
/// gimbal-mqtt door in front of it on `broker`.
pub(crate) struct Site {
    pub gcud: Gcud,
    pub door: Door,
    pub name: String,
}

/// The door's configuration for `site` on `broker` (`extra` top-level
/// keys before `[broker]`, `broker_extra` inside it).
pub(crate) fn door_config(gcud: &Gcud, url: &str, site: &str, extra: &str, broker_extra: &str) -> String {
    format!(
        "gcud = \"{}\"\nsite = \"{site}\"\nsource_group = {DOOR_GROUP}\n{extra}\n\
         [broker]\nurl = \"{}\"\nkeep_alive_s = 5\nreconnect_min_ms = 100\nreconnect_max_ms = 1000\n{broker_extra}\n\
         [[gimbal]]\nname = \"mast\"\naddress = \"{MAST}\"\n\
         [[gimbal]]\nname = \"gate\"\naddress = \"{GATE}\"\n",
        gcud.clients(),
        url
    )
}

impl Site {
    pub fn start(broker: &Broker, name: &str) -> Self {
        Self::start_with(broker, name, "", "")
    }

    pub fn start_with(broker: &Broker, name: &str, extra: &str, broker_extra: &str) -> Self {
        Self::start_via(broker, &broker.url(), name, extra, broker_extra)
    }

    /// A site whose door reaches the broker at `url` (an [`Uplink`]).
    pub fn start_via(broker: &Broker, url: &str, name: &str, extra: &str, broker_extra: &str) -> Self {
        let gcud = support::door::start_governed_gcud();
        let mut door = Door::new("gimbal-mqtt", env!("CARGO_BIN_EXE_gimbal-mqtt"));
        door.start(&door_config(&gcud, url, name, extra, broker_extra));
        let site = Self {
            gcud,
            door,
            name: name.to_owned(),
        };
        site.wait_online(broker);
        site
    }

    /// `sagebrush/<site>/<gimbal>`.
    pub fn base(&self, gimbal: &str) -> String {
        format!("sagebrush/{}/{gimbal}", self.name)
    }

    pub fn logs(&self) -> String {
        format!(
            "door log:\n{}\ngcud log tail:\n{}",
            self.door.log(),
            tail(&self.gcud.log(), 40)
        )
    }

    /// Waits until the site's retained status is `online` and the mast's
    /// retained state says it answers.
    pub fn wait_online(&self, broker: &Broker) {
        let status = format!("sagebrush/{}/status", self.name);
        eventually("the site online", || {
            broker.step("retained", &[&status], || self.logs())["message"] == "online"
        });
        eventually("the mast's state", || self.state(broker, "mast")["online"] == true);
    }

    /// The gimbal's retained state.
    pub fn state(&self, broker: &Broker, gimbal: &str) -> Value {
        broker.step("retained", &[&format!("{}/state", self.base(gimbal))], || self.logs())["message"].clone()
    }

    /// Publishes `json` as a command of `gimbal` and returns its result.
    pub fn command(&self, broker: &Broker, gimbal: &str, json: &str) -> Value {
        let r = broker.step("command", &[&self.base(gimbal), json], || self.logs());
        assert!(r.get("timeout").is_none(), "no result for {json}: {r}\n{}", self.logs());
        r
    }

    /// Frames the door's source group got onto `address`'s bus.
    pub fn door_frames(&self, address: &str) -> Vec<String> {
        self.gcud
            .received(address)
            .into_iter()
            .filter(|(s, _)| *s == DOOR_GROUP)
            .map(|(_, p)| p)
            .collect()
    }

    /// The door's frames on `address`'s bus that are not queries.
    pub fn door_motions(&self, address: &str) -> Vec<String> {
        self.door_frames(address)
            .into_iter()
            .filter(|p| !p.ends_with('?') && !p.starts_with("D?"))
            .collect()
    }
}

pub(crate) fn tail(text: &str, lines: usize) -> String {
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}

/// Waits until `address` reads `(pan, tilt)` within 0.05° on the bus.
pub(crate) fn wait_at(gcud: &Gcud, address: &str, pan: f64, tilt: f64) {
    let started = Instant::now();
    loop {
        let (p, t) = gcud.position(address);
        if (p - pan).abs() < 0.05 && (t - tilt).abs() < 0.05 {
            return;
        }
        assert!(
            started.elapsed() < HANG_GUARD,
            "{address} never reached {pan}/{tilt}: at {p}/{t}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A TCP proxy between a door and the broker that the test can cut (every
/// connection through it closed, new ones closed at once) and restore: a
/// site's uplink.
pub(crate) struct Uplink {
    pub port: u16,
    open: std::sync::Arc<std::sync::atomic::AtomicBool>,
    live: std::sync::Arc<std::sync::Mutex<Vec<TcpStream>>>,
}

impl Uplink {
    pub fn start(broker_port: u16) -> Self {
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::sync::{Arc, Mutex};
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind the uplink");
        let port = listener.local_addr().expect("port").port();
        let open = Arc::new(AtomicBool::new(true));
        let live: Arc<Mutex<Vec<TcpStream>>> = Arc::new(Mutex::new(Vec::new()));
        let (o, l) = (Arc::clone(&open), Arc::clone(&live));
        std::thread::spawn(move || {
            for door in listener.incoming().map_while(Result::ok) {
                if !o.load(Ordering::SeqCst) {
                    let _ = door.shutdown(std::net::Shutdown::Both);
                    continue;
                }
                let Ok(broker) = TcpStream::connect(("127.0.0.1", broker_port)) else {
                    continue;
                };
                let mut live = l.lock().expect("live");
                for s in [&door, &broker] {
                    live.push(s.try_clone().expect("clone"));
                }
                for (mut from, mut to) in [
                    (door.try_clone().expect("clone"), broker.try_clone().expect("clone")),
                    (broker, door),
                ] {
                    std::thread::spawn(move || {
                        let _ = std::io::copy(&mut from, &mut to);
                        let _ = to.shutdown(std::net::Shutdown::Both);
                    });
                }
            }
        });
        Self { port, open, live }
    }

    pub fn url(&self) -> String {
        format!("mqtt://127.0.0.1:{}", self.port)
    }

    /// Closes every connection through it, and each new one at once.
    pub fn cut(&self) {
        self.open.store(false, std::sync::atomic::Ordering::SeqCst);
        for s in self.live.lock().expect("live").drain(..) {
            let _ = s.shutdown(std::net::Shutdown::Both);
        }
    }

    pub fn restore(&self) {
        self.open.store(true, std::sync::atomic::Ordering::SeqCst);
    }
}

/// A `GO` on the bus: `P` and the pan and tilt in hex (Table 15).
pub(crate) fn is_goto(payload: &str) -> bool {
    payload.len() == 9 && payload.starts_with('P')
}
