//! The master's end of the NIC window (ARCHITECTURE "Delivery contract",
//! "End of the NIC window"; 1.4.2: a NIC may follow the ACK): on a
//! connection where gcud agreed to `~W`, gcud's report `00` about the
//! command after its ACK ends the wait at once; a NIC still ends as NIC;
//! a report about another command, or on a connection that did not agree,
//! ends nothing (the master's own window bounds the wait). gcud here is
//! the other end of an in-memory stream, scripted per test.

use std::time::Duration;

use sagebrush_client::{Client, CommandError};
use sagebrush_host::timing;
use sagebrush_protocol::{ACK, Address, Command, DeliveryReport, Event, Frame, FrameBuf, Framer, NIC, Undelivered};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::time::Instant;

const GROUP: u8 = 5;
const GIMBAL: Address = Address {
    group: GROUP,
    port: 1,
    device: 1,
};
/// The master's own NIC window here: long, so that ending early shows.
const OWN_WINDOW: u64 = 400;

/// The report `00` (or `failure`) gcud sends about `command`.
fn report(command: &Frame<'_>, failure: Option<Undelivered>) -> Vec<u8> {
    let payload = DeliveryReport {
        failure,
        dest: command.dest,
        command_checksum: command.checksum(),
        at_group: GROUP,
    }
    .encode();
    FrameBuf::new(Address::new(command.source, 0, 0), GROUP, &payload)
        .unwrap()
        .as_bytes()
        .to_vec()
}

/// gcud's side: answers `~W` with `agree` (`~W=`, else NIC), every other
/// command with ACK and then what `after_ack` says, 20 ms later.
async fn gcud(mut stream: DuplexStream, agree: bool, after_ack: fn(&Frame<'_>) -> Vec<u8>) {
    let mut framer: Framer = Framer::new();
    let mut buf = [0u8; 512];
    loop {
        let n = match stream.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let mut frames = Vec::new();
        framer.feed(&buf[..n], |e| {
            if let Event::Frame(f) = e {
                frames.push(FrameBuf::from_frame(&f));
            }
        });
        for command in frames {
            let f = command.frame();
            let mut out = vec![ACK];
            if f.payload() == b"~W" {
                match agree {
                    true => out.extend_from_slice(
                        FrameBuf::new(Address::new(f.source, 0, 0), GROUP, b"~W=")
                            .unwrap()
                            .as_bytes(),
                    ),
                    false => out.push(NIC),
                }
                let _ = stream.write_all(&out).await;
                continue;
            }
            let _ = stream.write_all(&out).await;
            tokio::time::sleep(Duration::from_millis(20)).await;
            let _ = stream.write_all(&after_ack(&f)).await;
        }
    }
}

async fn client(agree: bool, after_ack: fn(&Frame<'_>) -> Vec<u8>) -> Client<DuplexStream> {
    let (ours, theirs) = tokio::io::duplex(4096);
    tokio::spawn(gcud(theirs, agree, after_ack));
    let mut policy = timing::tcp_policy();
    policy.nic_window = OWN_WINDOW;
    let mut c = Client::new(ours, policy, 0);
    assert_eq!(c.ask_window_reports(GROUP).await, Ok(agree));
    c
}

/// Sends `PL` to the gimbal: its outcome and how long it took (ms).
async fn pan(c: &mut Client<DuplexStream>) -> (Result<(), CommandError>, u128) {
    let began = Instant::now();
    let sent = c.send(GIMBAL, &Command::PanLeft).await.map(|_| ());
    (sent, began.elapsed().as_millis())
}

#[tokio::test]
async fn the_report_after_the_ack_ends_the_window_where_gcud_agreed() {
    let mut c = client(true, |f| report(f, None)).await;
    let (sent, ms) = pan(&mut c).await;
    assert_eq!(sent, Ok(()));
    assert!(
        ms < u128::from(OWN_WINDOW) / 2,
        "ended by gcud's report, not its own window: {ms} ms"
    );
}

#[tokio::test]
async fn a_nic_still_ends_as_a_nic() {
    let mut c = client(true, |_| vec![NIC]).await;
    let (sent, ms) = pan(&mut c).await;
    assert!(matches!(sent, Err(CommandError::Nic(_))), "{sent:?}");
    assert!(ms < u128::from(OWN_WINDOW) / 2, "{ms} ms");
}

#[tokio::test]
async fn a_report_about_another_command_ends_nothing() {
    let mut c = client(true, |f| {
        let other = FrameBuf::new(f.dest, f.source, b"PR").unwrap();
        report(&other.frame(), None)
    })
    .await;
    let (sent, ms) = pan(&mut c).await;
    assert_eq!(sent, Ok(()));
    assert!(ms >= u128::from(OWN_WINDOW), "its own window: {ms} ms");
}

#[tokio::test]
async fn without_agreement_the_master_waits_its_own_window() {
    let mut c = client(false, |f| report(f, None)).await;
    let (sent, ms) = pan(&mut c).await;
    assert_eq!(sent, Ok(()));
    assert!(ms >= u128::from(OWN_WINDOW), "its own window: {ms} ms");
}
