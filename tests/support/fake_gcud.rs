//! A stand-in for gcud's client listener on loopback, for what a test
//! cannot yet have the real gcud do (tours configured in it): it answers
//! each command as gcud does (an ACK, a result frame, a delivery report or
//! a NIC), as the test's script says, and records every payload it got.
//! Threads end when it is dropped; every loop is bounded by that.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use sagebrush_protocol::{ACK, Address, DeliveryReport, Event, FrameBuf, Framer, NIC, Undelivered};

/// What the stand-in answers to a command.
#[derive(Clone, Debug)]
pub enum Answer {
    Ack,
    /// ACK, then this result payload.
    Result(Vec<u8>),
    /// A delivery report with this failure (no ACK).
    Report(Undelivered),
    Nic,
}

type Script = Arc<dyn Fn(&[u8]) -> Answer + Send + Sync>;

pub struct FakeGcud {
    pub addr: String,
    got: Arc<Mutex<Vec<String>>>,
    stop: Arc<AtomicBool>,
}

/// The group the stand-in answers as.
pub const GROUP: u8 = 5;

impl FakeGcud {
    pub fn start(script: impl Fn(&[u8]) -> Answer + Send + Sync + 'static) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        listener.set_nonblocking(true).expect("nonblocking");
        let addr = listener.local_addr().expect("addr").to_string();
        let got = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let script: Script = Arc::new(script);
        let (g, s) = (Arc::clone(&got), Arc::clone(&stop));
        std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        let (script, got, stop) = (Arc::clone(&script), Arc::clone(&g), Arc::clone(&s));
                        std::thread::spawn(move || serve(stream, &script, &got, &stop));
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(20)),
                }
            }
        });
        Self { addr, got, stop }
    }

    /// Every payload received, in order.
    pub fn got(&self) -> Vec<String> {
        self.got.lock().unwrap().clone()
    }
}

impl Drop for FakeGcud {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn serve(mut stream: TcpStream, script: &Script, got: &Mutex<Vec<String>>, stop: &AtomicBool) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(100)));
    let mut framer: Framer = Framer::new();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let n = match stream.read(&mut buf) {
            Ok(0) => return,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => continue,
            Err(_) => return,
        };
        let mut commands = Vec::new();
        framer.feed(&buf[..n], |e| {
            if let Event::Frame(f) = e {
                if let Ok(f) = FrameBuf::new(f.dest, f.source, f.payload()) {
                    commands.push(f);
                }
            }
        });
        for command in commands {
            let f = command.frame();
            got.lock()
                .unwrap()
                .push(String::from_utf8_lossy(f.payload()).into_owned());
            let mut out = Vec::new();
            match script(f.payload()) {
                Answer::Ack => out.push(ACK),
                Answer::Result(payload) => {
                    out.push(ACK);
                    let dest = Address::new(f.source, f.dest.port, f.dest.device);
                    out.extend_from_slice(FrameBuf::new(dest, GROUP, &payload).expect("result").as_bytes());
                }
                Answer::Report(failure) => {
                    let report = DeliveryReport {
                        failure: Some(failure),
                        dest: f.dest,
                        command_checksum: f.checksum(),
                        at_group: GROUP,
                    };
                    let dest = Address::new(f.source, 0, 0);
                    out.extend_from_slice(FrameBuf::new(dest, GROUP, &report.encode()).expect("report").as_bytes());
                }
                Answer::Nic => out.extend_from_slice(&[ACK, NIC]),
            }
            if stream.write_all(&out).is_err() {
                return;
            }
        }
    }
}

/// `P?` answered: at `pan`, `tilt` degrees.
pub fn position(pan: f32, tilt: f32) -> Answer {
    use sagebrush_protocol::{Angle, Position, Reply};
    let p = Position::new(Angle::from_degrees(pan).unwrap(), Angle::from_degrees(tilt).unwrap());
    let mut buf = [0u8; 32];
    let n = Reply::Position(p).encode(&mut buf).unwrap().len();
    Answer::Result(buf[..n].to_vec())
}
