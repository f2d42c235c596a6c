//! The rule that edits the session's motion, one case at a time.

use super::*;
use tokio::sync::oneshot::Receiver;

const RUN: Duration = Duration::from_secs(3);

fn speed(n: u8) -> Speed {
    Speed::new(n).unwrap()
}

fn pan(d: Drive<Speed>) -> Velocity {
    Velocity {
        pan: Some(d),
        ..Velocity::default()
    }
}

fn post(m: &mut MotionState, v: Velocity, now: Instant) -> Receiver<Result<(), CommandError>> {
    let (tx, rx) = oneshot::channel();
    m.post(v, RUN, "test", None, now, tx);
    rx
}

fn place(m: &mut MotionState, now: Instant) -> Receiver<Result<(), CommandError>> {
    let (tx, rx) = oneshot::channel();
    m.place(Place::Home, None, now, tx);
    rx
}

const PAN: Axes = Axes {
    pan: true,
    tilt: false,
    zoom: false,
};
const TILT: Axes = Axes {
    pan: false,
    tilt: true,
    zoom: false,
};

/// Two users of one door (two Pelco keyboards, two web users): the second's
/// move supersedes the first's pending one whole, never merged into it, so
/// that nothing of the first's goes to gcud under the second's name and
/// the first does not hear the second's outcome.
#[test]
fn another_users_velocity_supersedes_a_pending_one_whole() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let (tx, mut desk) = oneshot::channel();
    m.post(pan(Drive::Forward(speed(3))), RUN, "desk", Some("desk".into()), t0, tx);
    let tilt = Velocity {
        tilt: Some(Drive::Back(speed(5))),
        ..Velocity::default()
    };
    let (tx, _dvr) = oneshot::channel();
    m.post(tilt, RUN, "dvr", Some("dvr".into()), t0, tx);
    let w = m.wish.as_ref().expect("one pending velocity");
    assert_eq!(w.by.as_deref(), Some("dvr"));
    assert_eq!(w.what.pan, None, "the desk's pan is not sent as the DVR's");
    assert_eq!(w.what.tilt, Some(Drive::Back(speed(5))));
    assert_eq!(w.replies.len(), 1, "only the DVR hears the DVR's outcome");
    assert!(
        matches!(desk.try_recv(), Ok(Ok(()))),
        "the desk's superseded move is answered"
    );
}

/// A flood of one user's drives, and of stops: at most [`WAITING`] callers
/// wait for an outcome; the older ones are told theirs went at once, so the
/// lists never grow with the flood.
#[test]
fn the_callers_waiting_are_bounded_and_the_older_told_at_once() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let mut drives: Vec<_> = (0..100u8)
        .map(|i| post(&mut m, pan(Drive::Back(speed(i % 16))), t0))
        .collect();
    let w = m.wish.as_ref().expect("one pending velocity");
    assert_eq!(w.what.pan, Some(Drive::Back(speed(99 % 16))), "the newest wins");
    assert_eq!(w.replies.len(), WAITING);
    let told = drives
        .iter_mut()
        .map(|r| r.try_recv())
        .filter(|r| matches!(r, Ok(Ok(()))))
        .count();
    assert_eq!(told, 100 - WAITING, "the superseded beyond the bound are answered");
    let mut stops: Vec<_> = (0..50).map(|_| post(&mut m, pan(Drive::Stop), t0)).collect();
    assert_eq!(m.stop_replies.len(), WAITING);
    let told = stops
        .iter_mut()
        .map(|r| r.try_recv())
        .filter(|r| matches!(r, Ok(Ok(()))))
        .count();
    assert_eq!(told, 50 - WAITING);
    assert!(m.stops_owed.pan, "the stop itself is still owed");
}

#[test]
fn a_newer_velocity_wins_per_axis_and_its_deadline_covers_the_motion() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let mut first = post(&mut m, pan(Drive::Forward(speed(3))), t0);
    let tilt = Velocity {
        tilt: Some(Drive::Back(speed(5))),
        ..Velocity::default()
    };
    let _second = post(&mut m, tilt, t0 + RUN / 2);
    let w = m.wish.as_ref().expect("one pending velocity");
    assert_eq!(w.what.pan, Some(Drive::Forward(speed(3))), "the pan asked before stays");
    assert_eq!(w.what.tilt, Some(Drive::Back(speed(5))));
    assert_eq!(w.replies.len(), 2, "both callers learn the newest's outcome");
    assert_eq!(m.deadline, Some(t0 + RUN / 2 + RUN), "renewed by the newest");
    assert_eq!(m.moving(), PAN.or(TILT));
    assert!(first.try_recv().is_err(), "not answered before it is in force");
}

#[test]
fn a_stop_alone_is_owed_at_once_and_ends_what_it_names() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let mut moving = post(&mut m, pan(Drive::Forward(speed(3))), t0);
    let mut goto = place(&mut m, t0);
    let _stop = post(&mut m, pan(Drive::Stop), t0);
    assert_eq!(m.stops_owed, PAN);
    assert!(m.wish.is_none(), "the pan velocity came before the stop: dropped");
    assert!(matches!(moving.try_recv(), Ok(Ok(()))), "its caller is told");
    assert!(
        m.place.is_none() && matches!(goto.try_recv(), Ok(Ok(()))),
        "a pan stop ends the goto too"
    );
    assert_eq!(m.stop_replies.len(), 1, "answered once the bus confirms the stop");
    assert_eq!(m.deadline, None, "nothing moves");
}

/// A zoom drive joins a pan drive waiting; a zoom stop then ends the zoom
/// alone, the pan drive still waits (a VISCA camera's Pan-tiltDrive and
/// CAM_Zoom, two streams of one controller).
#[test]
fn a_zoom_stop_leaves_a_pan_drive_waiting() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let _pan = post(&mut m, pan(Drive::Back(speed(9))), t0);
    let zoom = |d| Velocity {
        zoom: Some(d),
        ..Velocity::default()
    };
    let _zoom = post(&mut m, zoom(Drive::Forward(LensSpeed::new(3).unwrap())), t0);
    let _stop = post(&mut m, zoom(Drive::Stop), t0);
    let w = m.wish.as_ref().expect("the pan drive still waits");
    assert_eq!((w.what.pan, w.what.zoom), (Some(Drive::Back(speed(9))), None));
    assert!(m.stops_owed.zoom && !m.stops_owed.pan, "{:?}", m.stops_owed);
}

#[test]
fn a_zero_beside_a_move_is_owed_only_once_that_move_is_in_force() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let _reply = post(&mut m, pan(Drive::Forward(speed(3))), t0);
    let both = Velocity {
        pan: Some(Drive::Stop),
        tilt: Some(Drive::Forward(speed(4))),
        zoom: None,
    };
    let _reply = post(&mut m, both, t0);
    assert_eq!(m.stops_owed, Axes::default(), "a move gcud refuses must stop nothing");
    assert_eq!(m.wish_stops, PAN);
    let w = m.wish.as_ref().unwrap();
    assert_eq!((w.what.pan, w.what.tilt), (None, Some(Drive::Forward(speed(4)))));
    // Moving pan again takes back its zero (newest wins).
    let _reply = post(&mut m, pan(Drive::Back(speed(2))), t0);
    assert_eq!(m.wish_stops, Axes::default());
}

#[test]
fn a_positioning_move_supersedes_the_pan_and_tilt_asked_before_it() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let slew = Velocity {
        pan: Some(Drive::Forward(speed(3))),
        tilt: Some(Drive::Stop),
        zoom: Some(Drive::Forward(LensSpeed::new(2).unwrap())),
    };
    let _reply = post(&mut m, slew, t0);
    let mut first = place(&mut m, t0);
    let _second = place(&mut m, t0);
    let w = m.wish.as_ref().unwrap();
    assert_eq!((w.what.pan, w.what.tilt), (None, None));
    assert!(w.what.zoom.is_some(), "the zoom is not the goto's");
    assert_eq!(m.wish_stops, Axes::default());
    assert!(matches!(first.try_recv(), Ok(Ok(()))), "the older goto is superseded");
}

#[test]
fn past_its_deadline_the_motion_owes_the_stops_of_whatever_moves() {
    let mut m = MotionState::default();
    let t0 = Instant::now();
    let mut late = post(&mut m, pan(Drive::Forward(speed(3))), t0);
    m.expire(t0 + RUN / 2, "g");
    assert_eq!(m.stops_owed, Axes::default(), "not yet");
    m.expire(t0 + RUN, "g");
    assert_eq!(m.stops_owed, PAN);
    assert!(
        matches!(late.try_recv(), Ok(Err(CommandError::Io(_)))),
        "it never started"
    );
    assert_eq!(m.deadline, None);
    m.stop_confirmed(PAN);
    assert_eq!(m.stops_owed, Axes::default());
    assert!(!m.any(), "idle once the stop is confirmed");
}
