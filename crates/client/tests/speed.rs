//! The gimbal session skips a speed command that changes nothing
//! (ARCHITECTURE "Front doors": the speed last set) and forgets that
//! speed whenever it may no longer be the gimbal's: a poll the gimbal did
//! not answer, gcud naming another holder, and at the latest
//! `session::SPEED_KEPT` after it was set. gcud is the loopback stand-in
//! of `fake_gcud`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use sagebrush_client::session::{Axes, SPEED_KEPT};
use sagebrush_protocol::{ControllerReply, Undelivered};

mod fake_gcud;

use fake_gcud::*;

const DOORS: ControllerReply<'static> = ControllerReply::Link {
    priority: 50,
    name: b"doors",
    via: b"",
    yours: true,
};
const OPERATORS: ControllerReply<'static> = ControllerReply::Link {
    priority: 80,
    name: b"operators",
    via: b"",
    yours: false,
};

/// gcud naming the doors' link as the holder, the gimbal at zero, every
/// other command ACKed.
async fn doors_gcud() -> FakeGcud {
    FakeGcud::start(|p| match p {
        b"~C0101" => controller(DOORS),
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await
}

/// How many pan speed commands (`SPn`) gcud got.
fn speeds(gcud: &FakeGcud) -> usize {
    gcud.got().iter().filter(|p| p.starts_with("SP")).count()
}

/// A pan to the right at speed 7, then its stop; both done.
async fn pan_and_stop(s: &sagebrush_client::session::GimbalSession) {
    s.velocity(pan_right(), None, "test").await.unwrap();
    s.stop(Axes::PAN_TILT).await.unwrap();
}

/// Waits until gcud got `n` more of `payload` than now.
async fn more(gcud: &FakeGcud, payload: &str, n: usize) {
    let count = |g: &FakeGcud| g.got().iter().filter(|p| *p == payload).count();
    let now = count(gcud);
    until(payload, || count(gcud) >= now + n).await;
}

#[tokio::test]
async fn the_same_speed_again_is_not_sent_again() {
    let gcud = doors_gcud().await;
    let s = session(&gcud.addr);
    pan_and_stop(&s).await;
    pan_and_stop(&s).await;
    let got = gcud.got();
    assert_eq!(speeds(&gcud), 1, "{got:?}");
    assert_eq!(got.iter().filter(|p| *p == "PR").count(), 2, "{got:?}");
    s.shutdown().await;
}

#[tokio::test]
async fn a_poll_the_gimbal_did_not_answer_forgets_the_speed() {
    let silent = Arc::new(AtomicBool::new(false));
    let quiet = Arc::clone(&silent);
    let gcud = FakeGcud::start(move |p| match p {
        b"~C0101" => controller(DOORS),
        b"P?" if quiet.load(Ordering::Relaxed) => Answer::Report(Undelivered::DeviceSilent),
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await;
    let s = session(&gcud.addr);
    pan_and_stop(&s).await;
    silent.store(true, Ordering::Relaxed);
    more(&gcud, "P?", 1).await;
    silent.store(false, Ordering::Relaxed);
    pan_and_stop(&s).await;
    assert_eq!(speeds(&gcud), 2, "{:?}", gcud.got());
    s.shutdown().await;
}

#[tokio::test]
async fn another_holder_named_by_gcud_forgets_the_speed() {
    let taken = Arc::new(AtomicBool::new(false));
    let t = Arc::clone(&taken);
    let gcud = FakeGcud::start(move |p| match p {
        b"~C0101" if t.load(Ordering::Relaxed) => controller(OPERATORS),
        b"~C0101" => controller(DOORS),
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await;
    let s = session(&gcud.addr);
    pan_and_stop(&s).await;
    // Another link held the gimbal for a while (gcud's ~C says so), then let go.
    taken.store(true, Ordering::Relaxed);
    until("the other holder seen", || s.status().control.is_some_and(|c| !c.ours)).await;
    taken.store(false, Ordering::Relaxed);
    pan_and_stop(&s).await;
    assert_eq!(speeds(&gcud), 2, "{:?}", gcud.got());
    s.shutdown().await;
}

#[tokio::test]
async fn a_speed_is_believed_for_a_bounded_time() {
    let gcud = doors_gcud().await;
    let s = session(&gcud.addr);
    pan_and_stop(&s).await;
    tokio::time::sleep(SPEED_KEPT + Duration::from_millis(100)).await;
    pan_and_stop(&s).await;
    assert_eq!(speeds(&gcud), 2, "{:?}", gcud.got());
    s.shutdown().await;
}

/// A pan to the right at `speed`.
fn pan_right_at(speed: u8) -> sagebrush_client::session::Velocity {
    sagebrush_client::session::Velocity {
        pan: Some(sagebrush_client::session::Drive::Forward(
            sagebrush_protocol::Speed::new(speed).unwrap(),
        )),
        ..Default::default()
    }
}

#[tokio::test]
async fn a_new_speed_is_set_before_the_direction_that_runs_at_it() {
    let gcud = doors_gcud().await;
    let s = session(&gcud.addr);
    for speed in [3, 9] {
        s.velocity(pan_right_at(speed), None, "test").await.unwrap();
        s.stop(Axes::PAN_TILT).await.unwrap();
    }
    // Faster while moving: the speed, then the direction that takes it.
    s.velocity(pan_right_at(3), None, "test").await.unwrap();
    s.velocity(pan_right_at(12), None, "test").await.unwrap();
    s.stop(Axes::PAN_TILT).await.unwrap();
    let motion: Vec<String> = gcud
        .got()
        .into_iter()
        .filter(|p| p.starts_with("SP") || p == "PR" || p == "PS")
        .collect();
    assert_eq!(
        motion,
        ["SP3", "PR", "PS", "SP9", "PR", "PS", "SP3", "PR", "SPC", "PR", "PS"],
        "never a direction at a speed not asked for"
    );
    s.shutdown().await;
}
