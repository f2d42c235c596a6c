//! What the benchmarks share: child processes killed on drop, gimbalsim
//! started and asked where it serves, percentiles.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Bytes on the wire per `P?` transaction: command 9, ACK 1, result 15, ACK 1.
pub const TRANSACTION_BYTES: f64 = 26.0;

/// A child process killed on drop.
pub struct Proc(pub Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts gimbalsim (`bin`, logging warnings only) with `args`; returns it
/// and the first line it prints: its TCP address or its pty's path.
pub fn gimbalsim(bin: &str, args: &[&str]) -> (Proc, String) {
    let mut child = Command::new(bin)
        .args(["--log", "warn"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn gimbalsim");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("gimbalsim's address or pty path");
    (Proc(child), line.trim().to_owned())
}

pub fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}
