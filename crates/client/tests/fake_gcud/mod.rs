//! A stand-in for gcud's client listener on loopback, as far as the
//! session's tests need it: scripted per test, it answers ACK, result
//! frames, NIC and delivery reports, agrees to end-of-window reports (`~W`)
//! and sends them as gcud does, and records every other payload it got.
#![allow(dead_code)]

use std::sync::{Arc, Mutex};
use std::time::Duration;

use sagebrush_client::session::{Drive, GcudLink, GcudReachability, GimbalSession, SessionConfig, Velocity};
use sagebrush_protocol::{
    ACK, Address, ControllerReply, DeliveryReport, Event, FrameBuf, Framer, NIC, Position, Speed, Undelivered,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

pub const GROUP: u8 = 5;
pub const GIMBAL: Address = Address {
    group: GROUP,
    port: 1,
    device: 1,
};
/// Only so that a broken session cannot hang the test run.
pub const GUARD: Duration = Duration::from_secs(20);

/// What the stand-in answers to a command.
#[derive(Clone, Debug)]
pub enum Answer {
    Ack,
    Result(Vec<u8>),
    Report(Undelivered),
    Nic,
    /// The answer, sent this much later (a command gcud takes a while on).
    After(Duration, Box<Answer>),
}

pub type Script = Arc<dyn Fn(&[u8]) -> Answer + Send + Sync>;

/// gcud's client listener, as far as these tests need it.
pub struct FakeGcud {
    pub addr: String,
    got: Arc<Mutex<Vec<String>>>,
}

impl FakeGcud {
    pub async fn start(script: impl Fn(&[u8]) -> Answer + Send + Sync + 'static) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let got = Arc::new(Mutex::new(Vec::new()));
        let script: Script = Arc::new(script);
        let record = Arc::clone(&got);
        tokio::spawn(async move {
            while let Ok((stream, _)) = listener.accept().await {
                tokio::spawn(serve(stream, Arc::clone(&script), Arc::clone(&record)));
            }
        });
        Self { addr, got }
    }

    pub fn got(&self) -> Vec<String> {
        self.got.lock().unwrap().clone()
    }
}

pub async fn serve(mut stream: tokio::net::TcpStream, script: Script, got: Arc<Mutex<Vec<String>>>) {
    let mut framer: Framer = Framer::new();
    let mut buf = [0u8; 512];
    let mut window_reports = false;
    loop {
        let n = match stream.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let mut frames = Vec::new();
        framer.feed(&buf[..n], |e| {
            if let Event::Frame(f) = e {
                frames.push(FrameBuf::new(f.dest, f.source, f.payload()).unwrap());
            }
        });
        for command in frames {
            let f = command.frame();
            if f.payload() == b"~W" {
                // As gcud's TCP client listener: end-of-window reports agreed,
                // and sent after every ACK that nothing follows (not recorded).
                window_reports = true;
                let mut out = vec![ACK];
                let dest = Address::new(f.source, f.dest.port, f.dest.device);
                out.extend_from_slice(FrameBuf::new(dest, GROUP, b"~W=").unwrap().as_bytes());
                if stream.write_all(&out).await.is_err() {
                    return;
                }
                continue;
            }
            got.lock()
                .unwrap()
                .push(String::from_utf8_lossy(f.payload()).into_owned());
            let mut out = Vec::new();
            let mut answer = script(f.payload());
            while let Answer::After(wait, then) = answer {
                tokio::time::sleep(wait).await;
                answer = *then;
            }
            match answer {
                Answer::Ack => {
                    out.push(ACK);
                    if window_reports {
                        out.extend_from_slice(&report(&f, None));
                    }
                }
                Answer::Result(payload) => {
                    out.push(ACK);
                    let dest = Address::new(f.source, f.dest.port, f.dest.device);
                    out.extend_from_slice(FrameBuf::new(dest, GROUP, &payload).unwrap().as_bytes());
                }
                Answer::Report(failure) => out.extend_from_slice(&report(&f, Some(failure))),
                Answer::Nic => out.extend_from_slice(&[ACK, NIC]),
                Answer::After(..) => unreachable!("waited for above"),
            }
            if stream.write_all(&out).await.is_err() {
                return;
            }
        }
    }
}

/// The delivery report gcud sends about `command` (ARCHITECTURE "Delivery contract").
pub fn report(command: &sagebrush_protocol::Frame<'_>, failure: Option<Undelivered>) -> Vec<u8> {
    let report = DeliveryReport {
        failure,
        dest: command.dest,
        command_checksum: command.checksum(),
        at_group: GROUP,
    };
    let dest = Address::new(command.source, 0, 0);
    FrameBuf::new(dest, GROUP, &report.encode())
        .unwrap()
        .as_bytes()
        .to_vec()
}

/// `~C` answered: `holder` controls gimbal 1.1.
pub fn controller(holder: ControllerReply<'_>) -> Answer {
    let mut buf = [0u8; 64];
    let n = holder.encode(1, 1, &mut buf).unwrap();
    Answer::Result(buf[..n].to_vec())
}

/// `P?` answered: at 0, 0.
pub fn at_zero() -> Answer {
    let mut buf = [0u8; 32];
    let n = sagebrush_protocol::Reply::Position(Position::default())
        .encode(&mut buf)
        .unwrap()
        .len();
    Answer::Result(buf[..n].to_vec())
}

pub fn session(gcud: &str) -> Arc<GimbalSession> {
    GimbalSession::start(
        SessionConfig {
            link: GcudLink::new(gcud.to_owned(), 7, Duration::from_millis(20)),
            address: GIMBAL,
            poll: Duration::from_millis(50),
            lens: false,
            max_move: Duration::from_secs(10),
            name: "mast-1".to_owned(),
        },
        Arc::new(GcudReachability::default()),
    )
}

pub fn pan_right() -> Velocity {
    Velocity {
        pan: Some(Drive::Forward(Speed::new(7).unwrap())),
        ..Velocity::default()
    }
}

/// Polls `cond` every 20 ms until it holds, at most [`GUARD`].
pub async fn until(what: &str, mut cond: impl FnMut() -> bool) {
    tokio::time::timeout(GUARD, async {
        while !cond() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .unwrap_or_else(|_| panic!("never: {what}"));
}
