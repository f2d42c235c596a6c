//! The newcomer's two commands (issue 53), end to end: `./demo.sh`, the
//! launcher, started as a user starts it (its own process group, as a
//! terminal's foreground job), on the binaries this test was built with
//! (`--bin-dir`) and with its ports moved (`--port-base`) clear of a demo
//! a developer may be running.
//!
//! - The README's quick start: every line of its "Move a gimbal" block,
//!   run in order against the demo, exits as the README says ("(exit N)",
//!   else 0).
//! - The launcher: every address it prints answers (the web page and its
//!   sign-in, each ONVIF camera through the ONVIF client, each MAVLink
//!   gimbal manager's heartbeat through pymavlink, each gimbalctl line it
//!   prints), each door is its own link of gcud, and Ctrl-C (SIGINT to the
//!   process group) stops every program it started and removes its folder;
//!   so does a SIGTERM to the launcher alone.

mod support;

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use serde_json::json;
use support::HANG_GUARD;

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
        let mut child = Command::new(root().join("demo.sh"))
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
        support::eventually("no process of the demo left", || self.leftovers().is_empty());
        let left: Vec<_> = std::fs::read_dir(self.tmp.path()).expect("tmp").flatten().collect();
        assert!(left.is_empty(), "the launcher left {left:?}");
        std::net::TcpListener::bind(format!("127.0.0.1:{}", self.port(4001))).expect("gcud's port is free again");
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

/// Every `127.0.0.1:PORT` in `text` moved by `shift`.
fn shift_ports(text: &str, shift: u16) -> String {
    let marker = "127.0.0.1:";
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find(marker) {
        let after = &rest[at + marker.len()..];
        let digits = after.len() - after.trim_start_matches(|c: char| c.is_ascii_digit()).len();
        let port: u16 = after[..digits].parse().expect("a port");
        out += &format!("{}{marker}{}", &rest[..at], port + shift);
        rest = &after[digits..];
    }
    out + rest
}

/// The README's quick start: the shell lines of its code blocks, in order.
fn quick_start_lines() -> Vec<String> {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let start = readme
        .find("\n## Quick start")
        .expect("README.md has a \"Quick start\" section");
    let section = &readme[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut lines = Vec::new();
    let mut in_block = false;
    for line in section.lines() {
        if line.starts_with("```") {
            in_block = line == "```sh";
            continue;
        }
        if in_block && !line.trim().is_empty() {
            lines.push(line.to_owned());
        }
    }
    lines
}

/// A README line's command (its `# comment` cut off) and the exit code
/// the comment shows, "(exit N)", else 0.
fn command_and_code(line: &str) -> (String, i32) {
    let (command, comment) = line.split_once(" # ").unwrap_or((line, ""));
    let code = comment
        .split_once("(exit ")
        .and_then(|(_, r)| r.split_once(')'))
        .map_or(0, |(n, _)| n.parse().expect("an exit code"));
    (command.trim().to_owned(), code)
}

#[test]
fn the_quick_start_lines_run_in_order_exit_as_the_readme_shows() {
    let lines = quick_start_lines();
    let after_demo = lines
        .iter()
        .position(|l| l.starts_with("./demo.sh"))
        .expect("the quick start runs ./demo.sh");
    let test_line = lines
        .iter()
        .position(|l| l.starts_with("./test.sh"))
        .expect("the quick start runs ./test.sh");
    let moves = &lines[after_demo + 1..test_line];
    assert!(moves.len() >= 5, "the lines between ./demo.sh and ./test.sh: {moves:?}");
    let demo = Demo::start(0);
    // `cargo run --release --bin X --` is the program this test was built
    // with (cargo may not run inside cargo test); gcud-status's default
    // address moves with the ports.
    let env = [("GIMBALCTL_HTTP", format!("127.0.0.1:{}", demo.port(9187)))];
    for line in moves {
        let (command, want) = command_and_code(line);
        let command = shift_ports(&command, demo.shift).replace(
            "cargo run --release --bin gimbalctl --",
            env!("CARGO_BIN_EXE_gimbalctl"),
        );
        assert!(
            !command.contains("cargo "),
            "a quick-start line this test cannot run: {line}"
        );
        let (code, out) = shell(&command, &env);
        assert_eq!(
            code,
            want,
            "README.md's quick-start line\n  {line}\nexits {code}, the README shows {want}:\n{out}\n{}",
            demo.logs()
        );
    }
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

#[test]
fn the_demo_launcher_prints_addresses_that_answer_and_ctrl_c_leaves_nothing_behind() {
    let mut demo = Demo::start(1);
    let printed = demo.printed();
    let logs = || demo.logs();

    // The web page, and a sign-in with the login it prints.
    let web = line_with(&printed, "The web page: http://127.0.0.1:");
    let port = number_after(web, "http://127.0.0.1:");
    assert_eq!(port, demo.port(8080), "{web}");
    let page = support::door::plain_raw(
        &format!("127.0.0.1:{port}"),
        "GET / HTTP/1.1\r\nHost: demo\r\nConnection: close\r\n\r\n",
    );
    assert!(page.starts_with("HTTP/1.1 200") && page.contains("<html"), "{page}");
    let (user, password) = logins(web).into_iter().next().expect("a login");
    let body = json!({ "user": user, "password": password }).to_string();
    let signed = support::door::plain_raw(
        &format!("127.0.0.1:{port}"),
        &format!(
            "POST /api/sign-in HTTP/1.1\r\nHost: demo\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        ),
    );
    assert!(
        signed.starts_with("HTTP/1.1 200"),
        "sign-in as {user}: {signed}\n{}",
        logs()
    );

    // Each ONVIF camera, through the ONVIF client, as an operator it prints.
    let onvif_users = logins(line_with(&printed, "ONVIF PTZ cameras"));
    let (user, password) = onvif_users.iter().find(|(u, _)| u == "vms").expect("the vms login");
    if support::door::onvif_client_available() {
        for (n, address) in ["5.1.1", "5.1.2", "5.2.1"].iter().enumerate() {
            let line = line_with(&printed, &format!("({address}): http://127.0.0.1:"));
            let port = number_after(line, "http://127.0.0.1:");
            assert_eq!(port, demo.port(8081 + n as u16), "{line}");
            let info = support::door::python_step(
                "tests/onvif/client.py",
                "info",
                &["127.0.0.1", &port.to_string(), user, password, "{}"],
                logs,
            );
            assert_eq!(info["device"]["ok"]["Manufacturer"], "Sagebrush", "{address}: {info}");
        }
    }

    // Each MAVLink gimbal manager's heartbeat, through pymavlink.
    let mavlink = line_with(&printed, "UDP 127.0.0.1:");
    let port = number_after(mavlink, "UDP 127.0.0.1:");
    assert_eq!(port, demo.port(14560), "{mavlink}");
    if support::door::mavlink_client_available() {
        let components = line_with(&printed, "MAVLink gimbal managers");
        for name in ["mast-1", "mast-2", "roof"] {
            let id: u16 = components
                .split(", ")
                .find(|c| c.ends_with(name) || c.trim_end_matches("):").ends_with(name))
                .and_then(|c| c.split_whitespace().rev().nth(1)?.parse().ok())
                .unwrap_or_else(|| panic!("no component for {name} in {components}"));
            let beat = support::door::python_step(
                "tests/mavlink/gcs.py",
                "heartbeat",
                &[&port.to_string(), "255", "190", &json!({ "component": id }).to_string()],
                logs,
            );
            assert_eq!(beat["heartbeat"]["type"], 26, "{name} (component {id}): {beat}");
        }
    }

    // Each gimbalctl line it prints, as printed.
    let ctl_lines: Vec<&str> = printed.lines().filter(|l| l.contains("gimbalctl ")).collect();
    assert!(ctl_lines.len() >= 3, "{printed}");
    for line in ctl_lines {
        let (code, out) = shell(line.trim(), &[]);
        assert_eq!(code, 0, "the printed line `{}`: {out}\n{}", line.trim(), logs());
    }

    // Each door on its own link of gcud, connected.
    let metrics = format!("127.0.0.1:{}", demo.port(9187));
    let status: serde_json::Value = {
        let text = support::http_get(&metrics, "/status");
        serde_json::from_str(text.split_once("\r\n\r\n").expect("a body").1).expect("JSON")
    };
    for door in ["gimbal-onvif", "gimbal-mavlink", "gimbal-web"] {
        let link = status["links"]
            .as_array()
            .expect("links")
            .iter()
            .find(|l| l["link"] == door)
            .unwrap_or_else(|| panic!("no link {door} in {status}"));
        assert!(link["connections"].as_u64() > Some(0), "{door}: {link}");
    }

    // Ctrl-C: every program stops, the folder goes, the ports are free.
    let programs = demo.leftovers();
    assert!(programs.len() >= 5, "the launcher and its four programs: {programs:?}");
    let status = demo.signal(Signal::SIGINT, true);
    assert_eq!(status.code(), Some(0), "{status}\n{}", demo.printed());
    demo.assert_nothing_left();
}

/// SIGTERM to the launcher alone (a supervisor's stop, `kill PID`): the
/// programs get no signal of their own, the launcher stops each.
#[test]
fn sigterm_to_the_launcher_alone_stops_every_program_it_started() {
    let mut demo = Demo::start(2);
    let programs = demo.leftovers();
    assert!(programs.len() >= 5, "the launcher and its four programs: {programs:?}");
    let status = demo.signal(Signal::SIGTERM, false);
    assert_eq!(status.code(), Some(0), "{status}\n{}", demo.printed());
    demo.assert_nothing_left();
}
