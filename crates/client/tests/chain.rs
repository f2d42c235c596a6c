//! A speed and the direction that takes it, chained (ARCHITECTURE "End of
//! the NIC window", "Routing semantics"): on a connection
//! where gcud agreed to `~W`, the master sends the second command at the
//! first's ACK, not after the first's NIC window; what gcud says of the
//! first before the second's ACK is the first's (its report `00`, or a
//! `?`), and nothing said of it is "not confirmed". gcud here is the other
//! end of an in-memory stream that keeps gcud's order: everything about
//! the first command before the second's ACK.

use std::time::Duration;

use sagebrush_client::{Client, CommandError};
use sagebrush_host::timing;
use sagebrush_protocol::{ACK, Address, Axis, Command, Event, FrameBuf, Framer, NIC, Speed, Undelivered};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};

mod fake_gcud;

use fake_gcud::report;

const GROUP: u8 = 5;
const GIMBAL: Address = Address {
    group: GROUP,
    port: 1,
    device: 1,
};
/// The master's own NIC window here; gcud's port window is [`GCUD_WINDOW`].
const OWN_WINDOW: u64 = 300;
const GCUD_WINDOW: Duration = Duration::from_millis(60);

/// What gcud says of the speed command after its ACK.
#[derive(Clone, Copy)]
enum Then {
    WindowPassed,
    Nic,
    Nothing,
    /// gcud refuses the direction at once (another link controls the
    /// gimbal), then the speed's window passes.
    DirectionRefusedFirst,
}

/// Reads the next command frame (ACKs of our frames skipped), within `wait`.
async fn next_frame(stream: &mut DuplexStream, framer: &mut Framer, wait: Duration) -> Option<FrameBuf> {
    let deadline = tokio::time::Instant::now() + wait;
    let mut buf = [0u8; 512];
    loop {
        let mut got = None;
        while let Some(e) = framer.next_event() {
            if let Event::Frame(f) = e {
                got = Some(FrameBuf::from_frame(&f));
                break;
            }
        }
        if got.is_some() {
            return got;
        }
        let n = match tokio::time::timeout_at(deadline, stream.read(&mut buf)).await {
            Ok(Ok(n)) if n > 0 => n,
            _ => return None,
        };
        framer.push(&buf[..n]);
    }
}

/// gcud's side of one chain: `~W` agreed (or NIC), the speed ACKed; then
/// whether the direction came inside gcud's window, which ends with
/// `then`; the direction ACKed after it and its window reported.
async fn gcud(mut stream: DuplexStream, agree: bool, then: Then) -> bool {
    let mut framer: Framer = Framer::new();
    let w = next_frame(&mut stream, &mut framer, Duration::from_secs(5))
        .await
        .expect("~W");
    assert_eq!(w.frame().payload(), b"~W");
    let mut out = vec![ACK];
    match agree {
        true => out.extend_from_slice(FrameBuf::new(Address::new(0, 0, 0), GROUP, b"~W=").unwrap().as_bytes()),
        false => out.push(NIC),
    }
    stream.write_all(&out).await.unwrap();
    let speed = next_frame(&mut stream, &mut framer, Duration::from_secs(5))
        .await
        .expect("speed");
    stream.write_all(&[ACK]).await.unwrap();
    let early = next_frame(&mut stream, &mut framer, GCUD_WINDOW).await;
    let came_early = early.is_some();
    if let (Then::DirectionRefusedFirst, Some(direction)) = (then, &early) {
        let refused = report(&direction.frame(), Some(Undelivered::NotInControl));
        stream.write_all(&refused).await.unwrap();
        stream.write_all(&report(&speed.frame(), None)).await.unwrap();
        let _ = next_frame(&mut stream, &mut framer, Duration::from_secs(5)).await;
        return came_early;
    }
    match then {
        Then::WindowPassed => stream.write_all(&report(&speed.frame(), None)).await.unwrap(),
        Then::Nic => stream.write_all(&[NIC]).await.unwrap(),
        Then::Nothing | Then::DirectionRefusedFirst => {}
    }
    let direction = match early {
        Some(d) => d,
        // None at all when the master was told not to go on.
        None => match next_frame(&mut stream, &mut framer, Duration::from_secs(1)).await {
            Some(d) => d,
            None => return false,
        },
    };
    assert_eq!(direction.frame().payload(), b"PR");
    stream.write_all(&[ACK]).await.unwrap();
    stream.write_all(&report(&direction.frame(), None)).await.unwrap();
    // Until the master closes its end.
    let _ = next_frame(&mut stream, &mut framer, Duration::from_secs(5)).await;
    came_early
}

/// The chain `SP7`, `PR` against a gcud that `agree`s to `~W` and says
/// `then` of the speed: each command's outcome, and whether the direction
/// reached gcud before the speed's window ended.
async fn chain(agree: bool, then: Then) -> (Result<(), CommandError>, Option<Result<(), CommandError>>, bool) {
    chain_unless(agree, then, false).await
}

/// [`chain`], told not to go on at the speed's ACK when `stop_owed`.
async fn chain_unless(
    agree: bool,
    then: Then,
    stop_owed: bool,
) -> (Result<(), CommandError>, Option<Result<(), CommandError>>, bool) {
    let (ours, theirs) = tokio::io::duplex(4096);
    let gcud = tokio::spawn(gcud(theirs, agree, then));
    let mut policy = timing::tcp_policy();
    policy.nic_window = OWN_WINDOW;
    let mut c = Client::new(ours, policy, 0);
    assert_eq!(c.ask_window_reports(GROUP).await, Ok(agree));
    let speed = Command::SetSpeed(Axis::Pan, Speed::new(7).unwrap());
    let (a, b) = c.send_chained(GIMBAL, &speed, &Command::PanRight, &|| !stop_owed).await;
    drop(c);
    let early = gcud.await.expect("gcud's side");
    (a.map(|_| ()), b.map(|b| b.map(|_| ())), early)
}

#[tokio::test]
async fn the_direction_goes_at_the_speeds_ack_where_gcud_agreed() {
    let (speed, direction, early) = chain(true, Then::WindowPassed).await;
    assert!(early, "the direction did not wait for the speed's window");
    assert_eq!((speed, direction), (Ok(()), Some(Ok(()))));
}

#[tokio::test]
async fn a_nic_before_the_directions_ack_is_the_speeds() {
    let (speed, direction, early) = chain(true, Then::Nic).await;
    assert!(early);
    assert!(matches!(speed, Err(CommandError::Nic(_))), "{speed:?}");
    assert_eq!(direction, Some(Ok(())), "the direction's own outcome");
}

#[tokio::test]
async fn nothing_said_of_the_speed_before_the_directions_ack_is_not_confirmed() {
    let (speed, direction, _) = chain(true, Then::Nothing).await;
    assert!(
        matches!(&speed, Err(CommandError::NoResult(m)) if m.contains("not confirmed")),
        "{speed:?}"
    );
    assert_eq!(direction, Some(Ok(())));
}

#[tokio::test]
async fn without_gcuds_reports_the_direction_waits_the_speeds_window() {
    let (speed, direction, early) = chain(false, Then::Nothing).await;
    assert!(!early, "sent inside a window nobody reports the end of");
    assert_eq!((speed, direction), (Ok(()), Some(Ok(()))));
}

#[tokio::test]
async fn a_stop_owed_at_the_speeds_ack_keeps_the_direction() {
    let (speed, direction, early) = chain_unless(true, Then::WindowPassed, true).await;
    assert_eq!(speed, Ok(()), "the speed's own outcome, its window waited");
    assert_eq!(direction, None, "not sent: the stop goes first");
    assert!(!early);
}

#[tokio::test]
async fn a_direction_refused_before_the_speeds_window_passed_leaves_the_speed_its_own() {
    let (speed, direction, early) = chain(true, Then::DirectionRefusedFirst).await;
    assert!(early);
    assert_eq!(speed, Ok(()), "the speed's window passed after the refusal");
    assert!(
        matches!(
            direction,
            Some(Err(CommandError::Refused(Undelivered::NotInControl, _)))
        ),
        "{direction:?}"
    );
}
