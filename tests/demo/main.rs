//! The newcomer's two commands (issue 53), end to end: `./demo.sh`, the
//! launcher, started as a user starts it (its own process group, as a
//! terminal's foreground job), on the binaries this test was built with
//! (`--bin-dir`) and with its ports moved (`--port-base`) clear of a demo
//! a developer may be running. One module per concern:
//!
//! - `quick_start`: every line of the README's "Move a gimbal" block, run
//!   in order against the demo, exits as the README says ("(exit N)",
//!   else 0).
//! - `launcher`: every address it prints answers (the web page and its
//!   sign-in, each ONVIF camera through the ONVIF client, each MAVLink
//!   gimbal manager's heartbeat through pymavlink, each gimbalctl line it
//!   prints), every door it starts is its own connected link of gcud, and
//!   Ctrl-C (SIGINT to the process group) stops every program it started
//!   and removes its folder; so does a SIGTERM to the launcher alone.
//! - `clients`: the doors' own third-party clients at the addresses it
//!   prints move the demo's gimbals: a real browser (chromium) on the web
//!   page with the printed login, the PyPI `visca-over-ip` camera client,
//!   the PyPI `pyptzcontroller` keyboard through a serial server; each
//!   move read on the bus side (gimbalctl through gcud) and in gcud's
//!   record of who asked.

#[path = "../support/mod.rs"]
mod support;

mod clients;
mod launcher;
mod quick_start;

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use serde_json::{Value, json};
use support::{HANG_GUARD, eventually};

/// The checkout (the tests run in it).
fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Where the package's programs were built (the launcher's `--bin-dir`).
fn bin_dir() -> PathBuf {
    Path::new(env!("CARGO_BIN_EXE_gcud"))
        .parent()
        .expect("bin dir")
        .to_owned()
}

/// The demo's ports moved by this much: all of them stay between 1024 and
/// 32768, below the system's ephemeral ports (where the other tests' ports
/// come from), and apart per test (`slot`) and per test process.
fn port_shift(slot: u16, attempt: u16) -> u16 {
    10_000 + (std::process::id() % 40) as u16 * 200 + slot * 50 + attempt * 17
}

/// `./demo.sh` running in its own process group, its stdout collected.
struct Demo {
    child: Child,
    out: Arc<Mutex<String>>,
    shift: u16,
    tmp: tempfile::TempDir,
}

impl Demo {
    /// Starts the launcher and waits until it printed what to open; a port
    /// some other program holds is tried again elsewhere.
    fn start(slot: u16) -> Self {
        let mut last = String::new();
        for attempt in 0..3 {
            let shift = port_shift(slot, attempt);
            match Self::try_start(shift) {
                Ok(demo) => return demo,
                Err(out) if out.contains("in use") => last = out,
                Err(out) => panic!("./demo.sh --port-base {} did not start:\n{out}", 4000 + shift),
            }
        }
        panic!("./demo.sh found its ports taken three times:\n{last}");
    }

    fn try_start(shift: u16) -> Result<Self, String> {
        let tmp = tempfile::tempdir().expect("temp dir");
        // SIGINT as a terminal leaves it: a suite started in the background
        // without job control (`./test.sh &`, nohup) hands its children
        // SIGINT ignored, which a shell can neither trap nor reset, and the
        // launcher then never hears the Ctrl-C this test sends.
        let mut child = Command::new("env")
            .arg("--default-signal=INT")
            .arg(root().join("demo.sh"))
            .arg("--bin-dir")
            .arg(bin_dir())
            .args(["--port-base", &(4000 + shift).to_string()])
            .current_dir(root())
            .env("TMPDIR", tmp.path())
            .env_remove("RUST_LOG")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .expect("run ./demo.sh");
        let out = Arc::new(Mutex::new(String::new()));
        for stream in [
            Box::new(child.stdout.take().expect("stdout")) as Box<dyn Read + Send>,
            Box::new(child.stderr.take().expect("stderr")),
        ] {
            let out = Arc::clone(&out);
            std::thread::spawn(move || {
                let mut stream = stream;
                let mut buf = [0; 4096];
                while let Ok(n @ 1..) = stream.read(&mut buf) {
                    out.lock().unwrap().push_str(&String::from_utf8_lossy(&buf[..n]));
                }
            });
        }
        let demo = Self { child, out, shift, tmp };
        // Four programs start one after the other: bounded by twice the guard.
        let started = Instant::now();
        let mut demo = demo;
        loop {
            if demo.printed().contains("Ctrl-C stops everything") {
                return Ok(demo);
            }
            if let Ok(Some(status)) = demo.child.try_wait() {
                std::thread::sleep(Duration::from_millis(200));
                return Err(format!("{status}\n{}", demo.printed()));
            }
            assert!(
                started.elapsed() < 2 * HANG_GUARD,
                "./demo.sh is not ready:\n{}",
                demo.printed()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn printed(&self) -> String {
        self.out.lock().unwrap().clone()
    }

    /// The demo's `port`, moved.
    fn port(&self, port: u16) -> u16 {
        port + self.shift
    }

    /// The processes the launcher started and still there: those of its
    /// process group, and any other naming its folder (under this test's
    /// TMPDIR) on its command line, as each program's `--config` does.
    fn leftovers(&self) -> Vec<u32> {
        let pgid = self.child.id();
        let folder = self.tmp.path().to_string_lossy().into_owned();
        let mut pids = Vec::new();
        for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let (Ok(stat), Ok(cmdline)) = (
                std::fs::read_to_string(entry.path().join("stat")),
                std::fs::read(entry.path().join("cmdline")),
            ) else {
                continue;
            };
            // pid (comm) state ppid pgrp ...: after the last ')'.
            let fields: Vec<&str> = stat
                .rsplit_once(')')
                .map_or("", |(_, r)| r)
                .split_whitespace()
                .collect();
            let zombie = fields.first() == Some(&"Z");
            let in_group = fields.get(2).and_then(|g| g.parse::<u32>().ok()) == Some(pgid);
            if !zombie && (in_group || String::from_utf8_lossy(&cmdline).contains(&folder)) {
                pids.push(pid);
            }
        }
        pids
    }

    /// Sends `signal` to the launcher (`group`: to its whole process group,
    /// as a terminal's Ctrl-C does); its exit status.
    fn signal(&mut self, signal: Signal, group: bool) -> std::process::ExitStatus {
        let pid = Pid::from_raw(self.child.id() as i32);
        if group {
            killpg(pid, signal).expect("killpg");
        } else {
            nix::sys::signal::kill(pid, signal).expect("kill");
        }
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("wait") {
                return status;
            }
            assert!(
                started.elapsed() < HANG_GUARD,
                "./demo.sh did not stop on {signal}:\n{}",
                self.printed()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// After the launcher exited: nothing it started is left, its folder
    /// is gone, gcud's port is free.
    fn assert_nothing_left(&self) {
        eventually("no process of the demo left", || self.leftovers().is_empty());
        let left: Vec<_> = std::fs::read_dir(self.tmp.path()).expect("tmp").flatten().collect();
        assert!(left.is_empty(), "the launcher left {left:?}");
        std::net::TcpListener::bind(format!("127.0.0.1:{}", self.port(4001))).expect("gcud's port is free again");
    }

    /// The log of `program` (`gcud`, a door) in the launcher's folder.
    fn log(&self, program: &str) -> String {
        let dirs = std::fs::read_dir(self.tmp.path()).into_iter().flatten().flatten();
        dirs.filter_map(|dir| std::fs::read_to_string(dir.path().join(format!("{program}.log"))).ok())
            .collect()
    }

    /// gcud's client link, as printed ("gcud: clients 127.0.0.1:PORT").
    fn clients(&self) -> String {
        format!("127.0.0.1:{}", number_after(&self.printed(), "clients 127.0.0.1:"))
    }

    /// gcud's `/status` (JSON) from the metrics address it printed.
    fn status(&self) -> Value {
        let metrics = format!(
            "127.0.0.1:{}",
            number_after(&self.printed(), "metrics http://127.0.0.1:")
        );
        let text = support::http_get(&metrics, "/status");
        let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
        serde_json::from_str(body).unwrap_or_else(|e| panic!("gcud's /status is not JSON ({e}): {text}"))
    }

    /// Polls `condition` until it holds, bounded by the hang guard; gives
    /// up with `what` and the programs' logs.
    fn wait(&self, what: &str, condition: impl FnMut() -> bool) {
        support::eventually_with(what, condition, || self.logs());
    }

    /// Where gimbal `address` is, by gimbalctl through gcud's printed client link.
    fn position(&self, address: &str) -> (f64, f64) {
        let out = support::gimbalctl(&["--tcp", &self.clients(), "--json", "--to", address, "position"]);
        assert_eq!(out.code, 0, "position of {address}: {out:?}\n{}", self.logs());
        let r = &out.json()["result"];
        (
            r["pan_deg"].as_f64().expect("pan"),
            r["tilt_deg"].as_f64().expect("tilt"),
        )
    }

    /// Where gimbal `address` comes to rest: two readings 150 ms apart agree.
    fn settled(&self, address: &str) -> (f64, f64) {
        let mut last = self.position(address);
        self.wait(&format!("{address} to stop moving"), || {
            std::thread::sleep(Duration::from_millis(150));
            let now = self.position(address);
            let still = now == last;
            last = now;
            still
        });
        last
    }

    /// Waits until gcud's log records `command` (its words, as "pan
    /// right") of link `door` to gimbal `address` accepted (its audit
    /// line: "link DOOR: COMMAND ... for ADDRESS: accepted"); that line.
    fn wait_accepted(&self, door: &str, command: &str, address: &str) -> String {
        let (asked, outcome) = (format!("link {door}: {command}"), format!(" for {address}: accepted"));
        let find = || {
            let log = self.log("gcud");
            log.lines()
                .find(|l| l.contains(&asked) && l.contains(&outcome))
                .map(str::to_owned)
        };
        self.wait(&format!("gcud to accept \"{command}\" of {door} to {address}"), || {
            find().is_some()
        });
        find().expect("the line")
    }

    /// The demo's gimbals as it prints them (its ONVIF cameras' lines,
    /// "  NAME (ADDRESS): http://..."): `(name, address)`.
    fn gimbals(&self) -> Vec<(String, String)> {
        let printed = self.printed();
        let gimbals: Vec<(String, String)> = printed
            .lines()
            .filter(|l| l.contains("/onvif/device_service"))
            .filter_map(|l| {
                let (name, rest) = l.trim().split_once(" (")?;
                Some((name.to_owned(), rest.split_once("):")?.0.to_owned()))
            })
            .collect();
        assert!(gimbals.len() >= 3, "the demo's three gimbals in:\n{printed}");
        gimbals
    }

    /// The doors it started, as it prints them ("and DOOR DOOR ..., all on").
    fn doors(&self) -> Vec<String> {
        let printed = self.printed();
        let line = line_with(&printed, ", all on ");
        let names = line
            .trim_start_matches("and ")
            .split_once(", all on ")
            .expect("the doors")
            .0;
        names.split_whitespace().map(str::to_owned).collect()
    }

    /// The logs of the programs, for a failure's message.
    fn logs(&self) -> String {
        let mut text = String::new();
        for dir in std::fs::read_dir(self.tmp.path()).into_iter().flatten().flatten() {
            for file in std::fs::read_dir(dir.path()).into_iter().flatten().flatten() {
                if file.path().extension().is_some_and(|e| e == "log") {
                    let log = std::fs::read_to_string(file.path()).unwrap_or_default();
                    text += &format!("--- {}\n{log}\n", file.path().display());
                }
            }
        }
        text
    }
}

impl Drop for Demo {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = killpg(Pid::from_raw(self.child.id() as i32), Signal::SIGTERM);
            let started = Instant::now();
            while self.child.try_wait().ok().flatten().is_none() && started.elapsed() < HANG_GUARD {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        let _ = killpg(Pid::from_raw(self.child.id() as i32), Signal::SIGKILL);
        let _ = self.child.wait();
    }
}

/// Runs `line` with `sh -c` in the checkout (bounded by the guard): its
/// exit code and its output.
fn shell(line: &str, env: &[(&str, String)]) -> (i32, String) {
    let mut child = Command::new("sh")
        .args(["-c", line])
        .current_dir(root())
        .envs(env.iter().map(|(k, v)| (*k, v)))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if started.elapsed() > HANG_GUARD {
            let _ = child.kill();
            panic!("`{line}` did not end");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut out = String::new();
    child
        .stdout
        .take()
        .expect("stdout")
        .read_to_string(&mut out)
        .expect("read");
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut out)
        .expect("read");
    (status.code().unwrap_or(-1), out)
}

/// The number after `prefix` in `text`.
fn number_after(text: &str, prefix: &str) -> u16 {
    let at = text.find(prefix).unwrap_or_else(|| panic!("no {prefix:?} in:\n{text}")) + prefix.len();
    let digits: String = text[at..].chars().take_while(char::is_ascii_digit).collect();
    digits
        .parse()
        .unwrap_or_else(|_| panic!("no number after {prefix:?} in:\n{text}"))
}

/// The line of `text` that contains `what`.
fn line_with<'a>(text: &'a str, what: &str) -> &'a str {
    text.lines()
        .find(|l| l.contains(what))
        .unwrap_or_else(|| panic!("no line with {what:?} in:\n{text}"))
}

/// `(user, password)` pairs printed as "NAME / PASSWORD" in `line`'s
/// parenthesis or after "users".
fn logins(line: &str) -> Vec<(String, String)> {
    let inner = line
        .rsplit_once('(')
        .map_or(line, |(_, r)| r)
        .trim_end_matches([')', ':']);
    let inner = inner.rsplit_once("users ").map_or(inner, |(_, r)| r);
    inner
        .split(", ")
        .filter_map(|pair| pair.split_once(" / "))
        .map(|(u, p)| (u.trim().to_owned(), p.trim().to_owned()))
        .collect()
}
