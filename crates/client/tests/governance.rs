//! The gimbal session and connection against gcud's decisions
//! (ARCHITECTURE "Front doors"): a refusal by gcud's rules is a typed
//! [`CommandError::Refused`] naming the holder, never a stop of another
//! link's motion, never a motion the status reports; `~C` is kept with the
//! poll; the tours are asked of gcud. gcud here is a stand-in on loopback
//! that answers as gcud's client listener does (ACK, result frames,
//! delivery reports), scripted per test, and records every payload it got.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::connection::GimbalConnection;
use sagebrush_client::governance::{Controller, TourOutcome};
use sagebrush_client::session::{Axes, Drive, GcudReachability, GimbalSession, Motion, SessionConfig, Velocity};
use sagebrush_protocol::gcu::{encode_tour_list, encode_tour_reply};
use sagebrush_protocol::{
    ACK, Address, ControllerReply, DeliveryReport, Event, FrameBuf, Framer, NIC, Position, Speed, TourState,
    Undelivered,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

const GROUP: u8 = 5;
const GIMBAL: Address = Address {
    group: GROUP,
    port: 1,
    device: 1,
};
/// Only so that a broken session cannot hang the test run.
const GUARD: Duration = Duration::from_secs(20);

/// What the stand-in answers to a command.
#[derive(Clone, Debug)]
enum Answer {
    Ack,
    Result(Vec<u8>),
    Report(Undelivered),
    Nic,
}

type Script = Arc<dyn Fn(&[u8]) -> Answer + Send + Sync>;

/// gcud's client listener, as far as these tests need it.
struct FakeGcud {
    addr: String,
    got: Arc<Mutex<Vec<String>>>,
}

impl FakeGcud {
    async fn start(script: impl Fn(&[u8]) -> Answer + Send + Sync + 'static) -> Self {
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

    fn got(&self) -> Vec<String> {
        self.got.lock().unwrap().clone()
    }
}

async fn serve(mut stream: tokio::net::TcpStream, script: Script, got: Arc<Mutex<Vec<String>>>) {
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
            match script(f.payload()) {
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
            }
            if stream.write_all(&out).await.is_err() {
                return;
            }
        }
    }
}

/// The delivery report gcud sends about `command` (ARCHITECTURE "Delivery contract").
fn report(command: &sagebrush_protocol::Frame<'_>, failure: Option<Undelivered>) -> Vec<u8> {
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
fn controller(holder: ControllerReply<'_>) -> Answer {
    let mut buf = [0u8; 64];
    let n = holder.encode(1, 1, &mut buf).unwrap();
    Answer::Result(buf[..n].to_vec())
}

/// `P?` answered: at 0, 0.
fn at_zero() -> Answer {
    let mut buf = [0u8; 32];
    let n = sagebrush_protocol::Reply::Position(Position::default())
        .encode(&mut buf)
        .unwrap()
        .len();
    Answer::Result(buf[..n].to_vec())
}

const OPERATORS: ControllerReply<'static> = ControllerReply::Link {
    priority: 80,
    name: b"operators",
};

fn session(gcud: &str) -> Arc<GimbalSession> {
    GimbalSession::start(
        SessionConfig {
            gcud: gcud.to_owned(),
            from: 7,
            address: GIMBAL,
            nic_window: Duration::from_millis(20),
            poll: Duration::from_millis(50),
            lens: false,
            max_move: Duration::from_secs(10),
            name: "mast-1".to_owned(),
        },
        Arc::new(GcudReachability::default()),
    )
}

fn pan_right() -> Velocity {
    Velocity {
        pan: Some(Drive::Forward(Speed::new(7).unwrap())),
        ..Velocity::default()
    }
}

/// Polls `cond` every 20 ms until it holds, at most [`GUARD`].
async fn until(what: &str, mut cond: impl FnMut() -> bool) {
    tokio::time::timeout(GUARD, async {
        while !cond() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .unwrap_or_else(|_| panic!("never: {what}"));
}

#[tokio::test]
async fn a_refusal_for_control_is_typed_and_names_the_holder() {
    let gcud = FakeGcud::start(|p| match p {
        b"~C0101" => controller(OPERATORS),
        _ => Answer::Report(Undelivered::NotInControl),
    })
    .await;
    let mut c = GimbalConnection::new(&gcud.addr, 7, GIMBAL, Duration::from_millis(20));
    let e = c.send(&sagebrush_protocol::Command::PanRight).await.unwrap_err();
    assert_eq!(e.refusal(), Some(Undelivered::NotInControl), "{e:?}");
    let text = e.to_string();
    assert!(text.starts_with("refused by gcud: PR to 5.1.1"), "{text}");
    assert_eq!(
        text,
        "refused by gcud: PR to 5.1.1: link operators (priority 80) controls the gimbal"
    );
    let control = c.control().expect("the holder is kept");
    assert_eq!(
        control.holder,
        Controller::Link {
            name: "operators".into(),
            priority: 80
        }
    );
    assert!(!control.ours);
    // The other rows stay "not delivered".
    let gcud = FakeGcud::start(|_| Answer::Report(Undelivered::DeviceSilent)).await;
    let mut c = GimbalConnection::new(&gcud.addr, 7, GIMBAL, Duration::from_millis(20));
    let e = c.send(&sagebrush_protocol::Command::PanRight).await.unwrap_err();
    assert!(
        matches!(e, CommandError::Undelivered(Undelivered::DeviceSilent, _)),
        "{e:?}"
    );
    assert!(
        gcud.got().iter().all(|p| !p.starts_with('~')),
        "no ~C for a failure to deliver"
    );
}

#[tokio::test]
async fn a_move_refused_for_control_sends_no_stop_and_is_not_reported_moving() {
    // This door pans (accepted, its link holds control); then a link of
    // higher priority takes control (gcud stops the door's slew itself) and
    // moves the gimbal: the door's next command is refused.
    let taken = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let t = Arc::clone(&taken);
    let gcud = FakeGcud::start(move |p| {
        let taken = t.load(std::sync::atomic::Ordering::Relaxed);
        match p {
            b"~C0101" if taken => controller(OPERATORS),
            b"~C0101" => controller(ControllerReply::Link {
                priority: 50,
                name: b"doors",
            }),
            b"P?" => at_zero(),
            b"PS" | b"TS" => Answer::Ack,
            _ if taken => Answer::Report(Undelivered::NotInControl),
            _ => Answer::Ack,
        }
    })
    .await;
    let s = session(&gcud.addr);
    s.velocity(pan_right(), None, "test").await.unwrap();
    until("the door's own link learnt", || {
        s.status().control.is_some_and(|c| c.ours)
    })
    .await;
    taken.store(true, std::sync::atomic::Ordering::Relaxed);
    let faster = Velocity {
        pan: Some(Drive::Forward(Speed::new(12).unwrap())),
        tilt: Some(Drive::Forward(Speed::new(3).unwrap())),
        zoom: None,
    };
    let e = tokio::time::timeout(GUARD, s.velocity(faster, None, "test"))
        .await
        .unwrap()
        .unwrap_err();
    assert_eq!(e.refusal(), Some(Undelivered::NotInControl), "{e}");
    assert!(
        e.to_string()
            .contains("link operators (priority 80) controls the gimbal"),
        "{e}"
    );
    until("the status names the holder", || {
        s.status()
            .control
            .is_some_and(|c| c.holder.link() == Some("operators") && !c.ours)
    })
    .await;
    assert_eq!(s.status().motion, Motion::Idle, "a refused move is no motion");
    // A few polls later: no stop went out (it would stop the holder's motion).
    let polls = gcud.got().iter().filter(|p| *p == "P?").count();
    until("two more polls", || {
        gcud.got().iter().filter(|p| *p == "P?").count() >= polls + 2
    })
    .await;
    let got = gcud.got();
    assert!(
        !got.iter().any(|p| p == "PS" || p == "TS"),
        "the holder's motion is not stopped by a refused door: {got:?}"
    );
    assert_eq!(s.status().motion, Motion::Idle);
    // From the start, refused: the same; and a zero beside the refused
    // move (ONVIF's ContinuousMove x=0.5 y=0) stops nothing either.
    let e = s.velocity(pan_right(), None, "test").await.unwrap_err();
    assert_eq!(e.refusal(), Some(Undelivered::NotInControl), "{e}");
    let with_zero = Velocity {
        tilt: Some(Drive::Stop),
        ..pan_right()
    };
    let e = s.velocity(with_zero, None, "test").await.unwrap_err();
    assert_eq!(e.refusal(), Some(Undelivered::NotInControl), "{e}");
    let polls = gcud.got().iter().filter(|p| *p == "P?").count();
    until("two more polls", || {
        gcud.got().iter().filter(|p| *p == "P?").count() >= polls + 2
    })
    .await;
    let got = gcud.got();
    assert!(!got.iter().any(|p| p == "PS" || p == "TS"), "{got:?}");
    s.shutdown().await;
}

#[tokio::test]
async fn a_zero_beside_an_accepted_move_stops_that_axis_after_the_move() {
    let gcud = FakeGcud::start(|p| match p {
        b"~C0101" => controller(ControllerReply::Nobody),
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await;
    let s = session(&gcud.addr);
    let tilt_up = Velocity {
        tilt: Some(Drive::Forward(Speed::new(7).unwrap())),
        ..Velocity::default()
    };
    s.velocity(tilt_up, None, "test").await.unwrap();
    let with_zero = Velocity {
        tilt: Some(Drive::Stop),
        ..pan_right()
    };
    s.velocity(with_zero, None, "test").await.unwrap();
    until("the tilt stopped", || gcud.got().iter().any(|p| p == "TS")).await;
    let got = gcud.got();
    let pr = got.iter().position(|p| p == "PR").expect("PR sent");
    let ts = got.iter().position(|p| p == "TS").unwrap();
    assert!(pr < ts, "the zero after the move it came with: {got:?}");
    s.stop(Axes::PAN_TILT).await.unwrap();
    s.shutdown().await;
}

#[tokio::test]
async fn a_move_refused_by_a_limit_stops_what_this_door_had_moving() {
    // Pan slews (accepted); tilt up is refused by a keep-out zone.
    let gcud = FakeGcud::start(|p| match p {
        b"~C0101" => controller(ControllerReply::Link {
            priority: 50,
            name: b"doors",
        }),
        b"P?" => at_zero(),
        b"TU" => Answer::Report(Undelivered::KeepOut),
        _ => Answer::Ack,
    })
    .await;
    let s = session(&gcud.addr);
    s.velocity(pan_right(), None, "test").await.unwrap();
    until("the connection learnt its own link", || {
        s.status().control.is_some_and(|c| c.ours)
    })
    .await;
    let tilt_up = Velocity {
        tilt: Some(Drive::Forward(Speed::new(7).unwrap())),
        ..Velocity::default()
    };
    let e = s.velocity(tilt_up, None, "test").await.unwrap_err();
    assert_eq!(e.refusal(), Some(Undelivered::KeepOut), "{e}");
    assert!(e.to_string().contains("keep-out"), "{e}");
    until("the pan slew stopped", || gcud.got().iter().any(|p| p == "PS")).await;
    until("idle", || s.status().motion == Motion::Idle).await;
    s.stop(Axes::PAN_TILT).await.unwrap();
    s.shutdown().await;
}

#[tokio::test]
async fn tours_are_listed_started_and_stopped_through_gcud() {
    let gcud = FakeGcud::start(|p| {
        let mut buf = [0u8; 64];
        match p {
            b"~T?" => {
                let n = encode_tour_list([(&b"perimeter"[..], TourState::Stopped)], &mut buf);
                Answer::Result(buf[..n].to_vec())
            }
            b"~T+perimeter" => {
                let n = encode_tour_reply(TourState::Waiting, b"operators", &mut buf).unwrap();
                Answer::Result(buf[..n].to_vec())
            }
            b"~T-perimeter" => {
                let n = encode_tour_reply(TourState::Stopped, b"", &mut buf).unwrap();
                Answer::Result(buf[..n].to_vec())
            }
            b"P?" => at_zero(),
            b"~C0101" => controller(ControllerReply::Nobody),
            _ => Answer::Nic,
        }
    })
    .await;
    let s = session(&gcud.addr);
    let tours = s.tours().await.unwrap();
    assert_eq!(tours.len(), 1);
    assert_eq!(
        (tours[0].name.as_str(), tours[0].state),
        ("perimeter", TourState::Stopped)
    );
    assert_eq!(
        s.tour("perimeter", true).await.unwrap(),
        TourOutcome {
            state: TourState::Waiting,
            waiting_for: Some("operators".into())
        }
    );
    assert_eq!(s.tour("perimeter", false).await.unwrap().state, TourState::Stopped);
    assert!(matches!(s.tour("nope", true).await, Err(CommandError::Nic(_))));
    assert_eq!(s.controller().await.unwrap(), Controller::Nobody);
    let got = gcud.got();
    assert!(got.contains(&"~T+perimeter".to_owned()), "{got:?}");
    s.shutdown().await;
}

#[tokio::test]
async fn a_gcud_that_governs_nothing_leaves_the_control_unknown() {
    let gcud = FakeGcud::start(|p| match p {
        b"P?" => at_zero(),
        _ => Answer::Nic,
    })
    .await;
    let s = session(&gcud.addr);
    until("a poll", || s.status().position.is_some()).await;
    until("~C asked", || gcud.got().iter().any(|p| p == "~C0101")).await;
    assert!(s.status().control.is_none());
    s.shutdown().await;
}
