//! A door reads where its gimbal points through the session's own poll
//! (`GimbalSession::position`: readers waiting at once share one `P?`,
//! taken then, not at the next poll period) and moves it there in degrees
//! (`go_to_degrees`: an axis left out keeps the angle that poll read).
//! gcud is the loopback stand-in of `fake_gcud`.

use std::sync::Arc;
use std::sync::atomic::{AtomicI16, Ordering};
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::session::{GcudLink, GcudReachability, GimbalSession, SessionConfig};
use sagebrush_protocol::{Angle, Command, Position, Reply};

mod fake_gcud;

use fake_gcud::*;

/// gcud answering `P?` with pan `pan` (hundredths of a degree, changed by
/// the test) and tilt 5°, everything else ACKed.
async fn gcud_at(pan: Arc<AtomicI16>) -> FakeGcud {
    FakeGcud::start(move |p| match p {
        b"P?" => {
            let at = Position::new(Angle(pan.load(Ordering::Relaxed)), Angle(500));
            let mut buf = [0u8; 32];
            let n = Reply::Position(at).encode(&mut buf).unwrap().len();
            Answer::Result(buf[..n].to_vec())
        }
        _ => Answer::Ack,
    })
    .await
}

/// A session that polls on its own only once a minute: any other `P?` is a reader's.
fn slow_poll(gcud: &str) -> Arc<GimbalSession> {
    GimbalSession::start(
        SessionConfig {
            link: GcudLink::new(gcud.to_owned(), 7, Duration::from_millis(20)),
            address: GIMBAL,
            poll: Duration::from_secs(60),
            lens: false,
            max_move: Duration::from_secs(10),
            name: "mast-1".to_owned(),
        },
        Arc::new(GcudReachability::default()),
    )
}

/// gcud at 0, 0 that takes 300 ms over the first goto (`Pppppttt`), and
/// a session on it that polls only once a minute.
async fn first_goto_slow() -> (FakeGcud, Arc<GimbalSession>) {
    let first = Arc::new(std::sync::atomic::AtomicBool::new(true));
    let gcud = FakeGcud::start(move |p| match p {
        [b'P', rest @ ..] if rest.len() == 8 && first.swap(false, Ordering::Relaxed) => {
            Answer::After(Duration::from_millis(300), Box::new(Answer::Ack))
        }
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await;
    let s = slow_poll(&gcud.addr);
    (gcud, s)
}

/// The gotos (`Pppppttt`) gcud got, in order.
fn gotos(gcud: &FakeGcud) -> Vec<String> {
    gcud.got().into_iter().filter(|p| p.len() == 9).collect()
}

fn polls(gcud: &FakeGcud) -> usize {
    gcud.got().iter().filter(|p| *p == "P?").count()
}

#[tokio::test]
async fn readers_share_one_fresh_poll_and_send_no_query_of_their_own() {
    let pan = Arc::new(AtomicI16::new(1234));
    let gcud = gcud_at(Arc::clone(&pan)).await;
    let s = slow_poll(&gcud.addr);
    until("the session's first poll", || polls(&gcud) == 1).await;
    // The gimbal moved since that poll: a reader sees where it is now.
    pan.store(-4500, Ordering::Relaxed);
    let (a, b, c) = tokio::time::timeout(GUARD, async { tokio::join!(s.position(), s.position(), s.position()) })
        .await
        .expect("answered by a poll taken at once, not at the next period");
    for read in [a, b, c] {
        assert_eq!(read.unwrap().pan, Angle(-4500));
    }
    assert_eq!(polls(&gcud), 2, "three readers, one poll: {:?}", gcud.got());
    assert_eq!(
        s.status().position.map(|p| p.pan),
        Some(Angle(-4500)),
        "it is the session's poll too"
    );
    s.shutdown().await;
}

#[tokio::test]
async fn a_goto_in_degrees_keeps_the_axis_left_out_where_the_poll_read_it() {
    let gcud = gcud_at(Arc::new(AtomicI16::new(1000))).await;
    let s = slow_poll(&gcud.addr);
    s.go_to_degrees(None, Some(-20.0)).await.unwrap();
    let mut buf = [0u8; 32];
    let want = Command::GoTo(Position::new(Angle(1000), Angle(-2000)));
    let want = String::from_utf8_lossy(want.encode(&mut buf).unwrap()).into_owned();
    let got = gcud.got();
    assert!(
        got.contains(&want),
        "pan kept at 10°, tilt to -20°: {want:?} in {got:?}"
    );
    assert_eq!(gotos(&gcud).len(), 1, "{got:?}");

    let beyond = s.acting_for(Some("ops")).go_to_degrees(Some(400.0), Some(0.0)).await;
    assert!(matches!(beyond, Err(CommandError::Usage(_))), "{beyond:?}");
    assert_eq!(gotos(&gcud).len(), 1, "nothing sent: {:?}", gcud.got());
    s.shutdown().await;
}

/// A goto asked while the one before it is on its way to gcud goes after
/// it: it was taken for that one's, answered with its result and never
/// sent (gimbal-pelco's absolute pan, then tilt 55 ms later, lost the tilt
/// under load).
#[tokio::test]
async fn a_goto_asked_while_one_is_on_its_way_is_sent_after_it() {
    let (gcud, s) = first_goto_slow().await;
    let pan = {
        let s = Arc::clone(&s);
        tokio::spawn(async move { s.go_to_degrees(Some(30.0), Some(0.0)).await })
    };
    until("the first goto at gcud", || gotos(&gcud).len() == 1).await;
    let tilt = tokio::time::timeout(GUARD, s.go_to_degrees(Some(30.0), Some(10.0)))
        .await
        .expect("the second goto answered");
    assert!(tilt.is_ok(), "{tilt:?}");
    assert!(pan.await.expect("joined").is_ok());
    assert_eq!(gotos(&gcud), ["P0BB80000", "P0BB803E8"], "{:?}", gcud.got());
}

/// A goto naming one axis while the goto before it is on its way keeps the
/// other axis where that goto aims, not where a poll read the gimbal on its
/// way (a Pelco keyboard's absolute pan, then its tilt: the rule was
/// gimbal-pelco's own, now the session's for every door).
#[tokio::test]
async fn a_goto_of_one_axis_keeps_the_other_where_the_goto_before_it_aims() {
    let (gcud, s) = first_goto_slow().await;
    let both = {
        let s = Arc::clone(&s);
        tokio::spawn(async move { s.go_to_degrees(Some(30.0), Some(10.0)).await })
    };
    until("the first goto at gcud", || gotos(&gcud).len() == 1).await;
    let tilt = tokio::time::timeout(GUARD, s.go_to_degrees(None, Some(-5.0)))
        .await
        .expect("the tilt answered");
    assert!(tilt.is_ok(), "{tilt:?}");
    assert!(both.await.expect("joined").is_ok());
    // Pan 30° (0BB8) kept from the first; the poll read pan 0.
    assert_eq!(gotos(&gcud), ["P0BB803E8", "P0BB8FE0C"], "{:?}", gcud.got());
}

/// Two gotos of one axis each, asked at once at rest (a keyboard's pan and
/// tilt, 50 ms apart): the second aims after the first is posted, so the
/// gimbal is sent both angles, never the tilt alone with the pan read
/// before the first.
#[tokio::test]
async fn gotos_of_one_axis_asked_at_once_are_aimed_in_order() {
    let gcud = FakeGcud::start(|p| match p {
        b"P?" => at_zero(),
        _ => Answer::Ack,
    })
    .await;
    let s = slow_poll(&gcud.addr);
    until("the session's first poll", || polls(&gcud) == 1).await;
    let (pan, tilt) = tokio::time::timeout(
        GUARD,
        // Polled in this order, each to its end.
        async { tokio::join!(s.go_to_degrees(Some(30.0), None), s.go_to_degrees(None, Some(-5.0))) },
    )
    .await
    .expect("both answered");
    assert!(pan.is_ok() && tilt.is_ok(), "{pan:?} {tilt:?}");
    let gotos = gotos(&gcud);
    assert_eq!(gotos.last().map(String::as_str), Some("P0BB8FE0C"), "{gotos:?}");
}

/// A goto by degrees (VISCA's RelativePosition) goes from where a fresh
/// poll reads the gimbal, not from the last poll (none yet right after a
/// door started: it was refused), and two in a row add up: the second
/// goes from where the first aims, not from where it is on its way.
#[tokio::test]
async fn gotos_by_degrees_go_from_a_fresh_reading_and_two_in_a_row_add_up() {
    let pan = Arc::new(AtomicI16::new(1000));
    let gcud = gcud_at(Arc::clone(&pan)).await;
    let s = slow_poll(&gcud.addr);
    until("the session's first poll", || polls(&gcud) == 1).await;
    // Moved since that poll (another door): 20°, tilt 5°.
    pan.store(2000, Ordering::Relaxed);
    let first = s.acting_for(None).go_by_degrees(7.5, -1.0).await.unwrap();
    assert_eq!(first, Position::new(Angle(2750), Angle(400)));
    let door = s.acting_for(None);
    let (a, b) = tokio::time::timeout(GUARD, async {
        tokio::join!(door.go_by_degrees(10.0, 0.0), door.go_by_degrees(10.0, 0.0))
    })
    .await
    .expect("both answered");
    assert_eq!(a.unwrap(), Position::new(Angle(3750), Angle(400)));
    assert_eq!(b.unwrap(), Position::new(Angle(4750), Angle(400)));
    let gotos = gotos(&gcud);
    // The middle one may be superseded by the last before it is sent.
    assert_eq!(gotos.first().map(String::as_str), Some("P0ABE0190"), "{:?}", gcud.got());
    assert_eq!(gotos.last().map(String::as_str), Some("P128E0190"), "{:?}", gcud.got());
    assert!(
        gotos
            .iter()
            .all(|g| ["P0ABE0190", "P0EA60190", "P128E0190"].contains(&g.as_str())),
        "{gotos:?}"
    );
    let beyond = door.go_by_degrees(400.0, 0.0).await;
    assert!(matches!(beyond, Err(CommandError::Usage(_))), "{beyond:?}");
    s.shutdown().await;
}
