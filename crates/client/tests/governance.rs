//! The gimbal session and connection against gcud's decisions
//! (ARCHITECTURE "Front doors"): a refusal by gcud's rules is a typed
//! [`CommandError::Refused`] naming the holder, never a stop of another
//! link's motion, never a motion the status reports; `~C` is kept with the
//! poll; the tours are asked of gcud. gcud here is a stand-in on loopback
//! that answers as gcud's client listener does (ACK, result frames,
//! delivery reports), scripted per test, and records every payload it got.

use std::sync::Arc;
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::connection::GimbalConnection;
use sagebrush_client::governance::{Controller, TourOutcome};
use sagebrush_client::session::{Axes, Drive, Motion, Velocity};
use sagebrush_protocol::gcu::{encode_tour_list, encode_tour_reply};
use sagebrush_protocol::{ControllerReply, Speed, TourState, Undelivered};

mod fake_gcud;

use fake_gcud::*;

const OPERATORS: ControllerReply<'static> = ControllerReply::Link {
    priority: 80,
    name: b"operators",
    via: b"",
    yours: false,
};

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
    // The command in words (issue 53), never its payload.
    assert_eq!(
        text,
        "refused by gcud: pan right (CCW) until PS for 5.1.1: link operators (priority 80) controls the gimbal"
    );
    let control = c.control().expect("the holder is kept");
    assert_eq!(
        control.holder,
        Controller::Link {
            name: "operators".into(),
            priority: 80,
            via: None,
            yours: false,
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
                via: b"",
                yours: true,
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
            via: b"",
            yours: true,
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

/// Two users of one door (two Pelco keyboards on gimbal-pelco): gcud's
/// refusal of the DVR's drive, which came back while the desk's newer drive
/// waited, is the DVR's to hear; the desk's drive is sent after it (the
/// desk was told the DVR's refusal, naming the desk itself as the holder).
#[tokio::test]
async fn a_refusal_of_one_users_drive_is_told_to_that_user_not_to_another_posting_meanwhile() {
    let gcud = FakeGcud::start(|p| match p {
        b"~C0101" => controller(ControllerReply::Nobody),
        b"P?" => at_zero(),
        b"PL" => Answer::After(
            Duration::from_millis(300),
            Box::new(Answer::Report(Undelivered::NotInControl)),
        ),
        _ => Answer::Ack,
    })
    .await;
    let s = session(&gcud.addr);
    s.acting_for(Some("desk"))
        .velocity(pan_right(), None, "desk")
        .await
        .unwrap();
    let left = Velocity {
        pan: Some(Drive::Back(Speed::new(7).unwrap())),
        ..Velocity::default()
    };
    let dvr = s.acting_for(Some("dvr")).post_velocity(left, None, "dvr");
    until("the DVR's drive at gcud", || gcud.got().iter().any(|p| p == "PL")).await;
    let desk = tokio::time::timeout(GUARD, s.acting_for(Some("desk")).velocity(pan_right(), None, "desk"))
        .await
        .expect("the desk answered");
    assert!(desk.is_ok(), "the desk was told: {desk:?}");
    let dvr = tokio::time::timeout(GUARD, dvr)
        .await
        .expect("the DVR answered")
        .expect("told");
    assert_eq!(
        dvr.map_err(|e| e.refusal()),
        Err(Some(Undelivered::NotInControl)),
        "the DVR hears its own refusal"
    );
    let got = gcud.got();
    let refused = got.iter().position(|p| p == "PL").expect("PL sent");
    assert!(
        got[refused..].iter().any(|p| p == "PR"),
        "the desk's drive went after the DVR's: {got:?}"
    );
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
