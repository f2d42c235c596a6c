//! What the benchmarks share: child processes killed on drop, gimbalsim
//! started and asked where it serves, percentiles, and a device on a
//! pseudo-terminal whose line is timed at a bit rate.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sagebrush_protocol::device::{DeviceEndpoint, DeviceHandler, EndpointConfig, ReplyTo, Response};
use sagebrush_protocol::{Angle, Command as Cmd, Position, Reply, ResultKind};

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

/// Bytes of a frame besides its payload (Table 1: start, destination
/// group, port and device, source group, length, checksum).
pub const FRAME_OVERHEAD: usize = 7;

/// A new pseudo-terminal: its master side and the slave's path (for gcud's `path`).
pub fn pty() -> (std::fs::File, String) {
    use nix::fcntl::OFlag;
    let master = nix::pty::posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY).expect("openpt");
    nix::pty::grantpt(&master).expect("grantpt");
    nix::pty::unlockpt(&master).expect("unlockpt");
    let path = nix::pty::ptsname_r(&master).expect("ptsname");
    (std::fs::File::from(std::os::fd::OwnedFd::from(master)), path)
}

/// The instant reference gimbal: `P?` answered with a position at once,
/// every command without a result acknowledged, the rest NIC. It notes
/// each command's mnemonic and frame length for [`paced_device`].
#[derive(Default)]
struct InstantGimbal {
    heard: Option<(&'static str, usize)>,
}

impl DeviceHandler for InstantGimbal {
    fn handle(&mut self, command: Cmd<'_>, _: ReplyTo, _: u64) -> Response<'_> {
        let mut buf = [0u8; 256];
        let len = command.encode(&mut buf).map_or(0, <[u8]>::len);
        self.heard = Some((command.mnemonic(), len + FRAME_OVERHEAD));
        match command {
            Cmd::QueryPosition => Response::Reply(Reply::Position(Position {
                pan: Angle(100),
                tilt: Angle(-20),
            })),
            c if c.result_kind() == ResultKind::None => Response::Done,
            _ => Response::Nic,
        }
    }
}

/// The instant reference device on the master side of a pty, its line
/// timed at `baud` both ways as on a half-duplex bus: each byte heard is
/// through one byte-time after the line was free, and an answer is
/// written when its last byte would be through. `heard(mnemonic, at)` is
/// told each command with the instant its frame's first byte was through.
/// Returns the master's turnarounds (from an answer's last byte to the
/// next bytes heard, in byte-times) once `stop` is set and the line closed.
pub fn paced_device(
    mut pty: std::fs::File,
    baud: u32,
    stop: &AtomicBool,
    mut heard: impl FnMut(&'static str, Instant),
) -> Vec<f64> {
    let byte = Duration::from_secs_f64(10.0 / f64::from(baud));
    let epoch = Instant::now();
    let mut endpoint: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(1));
    let mut handler = InstantGimbal::default();
    let (mut line_free, mut answered_at) = (epoch, None::<Instant>);
    let mut turnarounds = Vec::new();
    let mut buf = [0u8; 512];
    let mut answer = Vec::with_capacity(64);
    loop {
        let n = match pty.read(&mut buf) {
            Ok(n) if n > 0 => n,
            // No slave open (before gcud opens it, after it exits).
            _ if stop.load(Ordering::Relaxed) => return turnarounds,
            _ => {
                std::thread::sleep(Duration::from_millis(1));
                continue;
            }
        };
        let read_at = Instant::now();
        line_free = line_free.max(read_at);
        answer.clear();
        for b in &buf[..n] {
            line_free += byte;
            let now = line_free.duration_since(epoch).as_millis() as u64;
            endpoint.receive(std::slice::from_ref(b), now, &mut handler, &mut |b| {
                answer.extend_from_slice(b)
            });
            if let Some((mnemonic, len)) = handler.heard.take() {
                heard(mnemonic, line_free - byte * (len as u32 - 1));
            }
        }
        if answer.is_empty() {
            continue;
        }
        // From the last answer's last byte to the read that completed this command.
        if let Some(at) = answered_at.take() {
            turnarounds.push(read_at.saturating_duration_since(at).as_secs_f64() / byte.as_secs_f64());
        }
        line_free += byte * answer.len() as u32;
        // Sleep most of the wait, spin the last stretch: a thread sleep
        // overshoots by tens of microseconds, most of a byte at 115200.
        while let Some(left) = line_free.checked_duration_since(Instant::now()) {
            if left > Duration::from_micros(300) {
                std::thread::sleep(left - Duration::from_micros(200));
            } else {
                std::hint::spin_loop();
            }
        }
        if pty.write_all(&answer).is_err() {
            return turnarounds;
        }
        answered_at = Some(Instant::now());
    }
}
