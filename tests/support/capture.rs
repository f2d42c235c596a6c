//! Support for the capture tests: a `gcud` on a written configuration, and
//! `tshark` with the project's dissector (`tools/wireshark/sagebrush.lua`).

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;

use super::{HANG_GUARD, Output};

/// A `gcud` on `config` in a private directory; SIGTERM on drop.
#[derive(Debug)]
pub struct Daemon {
    child: Child,
    pub dir: tempfile::TempDir,
}

impl Daemon {
    /// Writes `config` (with `{dir}` replaced by the private directory) and starts gcud.
    pub fn start(config: &str) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let config = config.replace("{dir}", &dir.path().display().to_string());
        let child = super::spawn_gcud(dir.path(), &config);
        let d = Self { child, dir };
        d.wait_for_log("gcud ready");
        d
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.path("gcud.log")).unwrap_or_default()
    }

    /// Waits until a log line contains `text`; returns it.
    pub fn wait_for_log(&self, text: &str) -> String {
        super::wait_for_log_line(&self.path("gcud.log"), text)
    }

    /// The client listener's address (`[[link]] name = "clients"`).
    pub fn clients(&self) -> String {
        super::addr_field(&self.wait_for_log("listening link=clients"))
    }

    /// `gimbalctl --tcp CLIENTS ARGS`.
    pub fn ctl(&self, args: &[&str]) -> Output {
        let addr = self.clients();
        let mut full = vec!["--tcp", addr.as_str()];
        full.extend_from_slice(args);
        super::gimbalctl(&full)
    }

    pub fn signal(&self, signal: Signal) {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, signal).expect("signal gcud");
    }

    /// SIGTERM and wait; returns the whole log and the private directory
    /// (the capture files stay until it is dropped).
    pub fn terminate(mut self) -> (String, tempfile::TempDir) {
        super::terminate(&mut self.child);
        (self.log(), self.take_dir())
    }

    /// SIGKILL (a crash: nothing is flushed on the way out); returns the private directory.
    pub fn kill(mut self) -> tempfile::TempDir {
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.take_dir()
    }

    fn take_dir(&mut self) -> tempfile::TempDir {
        let empty = tempfile::tempdir().expect("temp dir");
        std::mem::replace(&mut self.dir, empty)
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        super::terminate(&mut self.child);
    }
}

/// The dissector under test.
pub fn dissector() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/wireshark/sagebrush.lua")
}

/// Fails the test, saying how to install tshark, when it is missing.
pub fn require_tshark() {
    let found = Command::new("tshark")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        found,
        "tshark is not installed: the capture tests decode with it. Install it with \
         `sudo DEBIAN_FRONTEND=noninteractive apt-get install -y tshark` (./test.sh does)"
    );
}

/// `tshark -r FILE -T fields -e F...` with the dissector: one row per
/// packet, one column per field (first occurrence), and tshark's exit code
/// and stderr.
pub fn tshark_fields(file: &Path, fields: &[&str]) -> (Vec<Vec<String>>, i32, String) {
    require_tshark();
    let mut cmd = Command::new("tshark");
    cmd.arg("-X")
        .arg(format!("lua_script:{}", dissector().display()))
        .arg("-r")
        .arg(file)
        .args(["-T", "fields", "-E", "separator=|", "-E", "occurrence=f"]);
    for f in fields {
        cmd.args(["-e", f]);
    }
    let out = cmd.output().expect("run tshark");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows = stdout
        .lines()
        .map(|l| l.split('|').map(str::to_owned).collect())
        .collect();
    (
        rows,
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A program the test signals itself (SIGINT or SIGTERM), its standard
/// output read line by line as it comes.
#[derive(Debug)]
pub struct Program {
    child: Child,
    lines: mpsc::Receiver<String>,
}

impl Program {
    pub fn spawn(bin: &str, args: &[&str]) -> Self {
        let mut child = Command::new(bin)
            .args(args)
            .env_remove("GIMBALCTL_SERIAL")
            .env_remove("GIMBALCTL_TCP")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {bin}: {e}"));
        let stdout = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self { child, lines }
    }

    /// The next line of standard output (gimbalsim's first: where it listens).
    pub fn line(&self) -> String {
        self.lines.recv_timeout(HANG_GUARD).expect("a line on stdout")
    }

    pub fn signal(&self, signal: Signal) {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, signal).expect("signal the program");
    }

    /// Waits for the exit: how it ended, the rest of standard output, standard error.
    pub fn wait(mut self) -> (ExitStatus, String, String) {
        let started = Instant::now();
        let status = loop {
            match self.child.try_wait().expect("wait") {
                Some(status) => break status,
                None if started.elapsed() > HANG_GUARD => {
                    let _ = self.child.kill();
                    panic!("the program did not exit");
                }
                None => std::thread::sleep(Duration::from_millis(10)),
            }
        };
        let mut stdout = Vec::new();
        while let Ok(line) = self.lines.recv_timeout(HANG_GUARD) {
            stdout.push(line);
        }
        let mut stderr = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = e.read_to_string(&mut stderr);
        }
        (status, stdout.join("\n"), stderr)
    }
}

impl Drop for Program {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Bytes the kernel holds unread for the local TCP socket `local_port`
/// connected to `remote_port` (`/proc/net/tcp`'s rx_queue), if it exists.
pub fn unread_bytes(local_port: u16, remote_port: u16) -> Option<u64> {
    let table = std::fs::read_to_string("/proc/net/tcp").expect("/proc/net/tcp");
    let port = |field: &str| field.rsplit(':').next().and_then(|p| u16::from_str_radix(p, 16).ok());
    table.lines().skip(1).find_map(|line| {
        let f: Vec<&str> = line.split_whitespace().collect();
        let queues = f.get(4)?;
        (port(f.get(1)?)? == local_port && port(f.get(2)?)? == remote_port)
            .then(|| u64::from_str_radix(queues.rsplit(':').next()?, 16).ok())
            .flatten()
    })
}

/// Waits until the program owning the socket `local_port` -> `remote_port`
/// has read everything sent to it.
pub fn wait_until_read(local_port: u16, remote_port: u16) {
    super::eventually("the program to read what was sent", || {
        unread_bytes(local_port, remote_port) == Some(0)
    });
}
