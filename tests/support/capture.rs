//! Support for the capture tests: a `gcud` on a written configuration, and
//! `tshark` with the project's dissector (`tools/wireshark/sagebrush.lua`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use super::Output;

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
        let line = self.wait_for_log("listening link=clients");
        let addr = line.split("addr=").nth(1).expect("addr field");
        addr.split_whitespace().next().expect("address").to_owned()
    }

    /// `gimbalctl --tcp CLIENTS ARGS`.
    pub fn ctl(&self, args: &[&str]) -> Output {
        let addr = self.clients();
        let mut full = vec!["--tcp", addr.as_str()];
        full.extend_from_slice(args);
        super::gimbalctl(&full)
    }

    pub fn signal(&self, signal: nix::sys::signal::Signal) {
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
         `sudo DEBIAN_FRONTEND=noninteractive apt-get install -y tshark` (.ci/run does)"
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
