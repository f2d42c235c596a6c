//! Which frame is a command's result (Table 3: destination group = the
//! command's source group, port and device unchanged, source group = the
//! group the command went to). Through gcud a result of another group for
//! the same port and device may come while a command awaits its own (a
//! late one, or one a link between GCUs repeated): it is not this
//! command's. gcud here is the other end of an in-memory stream.

use std::time::Duration;

use sagebrush_client::master::Master;
use sagebrush_host::timing;
use sagebrush_protocol::{ACK, Address, Command, Event, FrameBuf, Framer, Outcome};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};

const CLIENT_GROUP: u8 = 100;

/// gcud's side: ACKs the one command, then writes `then`, 10 ms apart.
async fn gcud(mut stream: DuplexStream, then: Vec<FrameBuf>) {
    let mut framer: Framer = Framer::new();
    let mut buf = [0u8; 512];
    let mut got = false;
    while !got {
        let n = match stream.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        framer.feed(&buf[..n], |e| got |= matches!(e, Event::Frame(_)));
    }
    let _ = stream.write_all(&[ACK]).await;
    for frame in then {
        tokio::time::sleep(Duration::from_millis(10)).await;
        let _ = stream.write_all(frame.as_bytes()).await;
    }
    // Keep the stream open (the master ACKs each frame).
    while let Ok(n) = stream.read(&mut buf).await {
        if n == 0 {
            return;
        }
    }
}

#[tokio::test]
async fn a_result_from_another_group_is_not_the_commands() {
    let (ours, theirs) = tokio::io::duplex(4096);
    let command = FrameBuf::new(Address::new(45, 1, 7), CLIENT_GROUP, b"P?").unwrap();
    // Group 13's answer to an earlier command to 13.1.7, then group 45's own.
    let other = FrameBuf::new(Address::new(CLIENT_GROUP, 1, 7), 13, b"00000000").unwrap();
    let own = FrameBuf::new(Address::new(CLIENT_GROUP, 1, 7), 45, b"00640064").unwrap();
    tokio::spawn(gcud(theirs, vec![other, own.clone()]));
    let mut master = Master::new(ours, timing::tcp_policy());
    let exchange = master.transact(&command, &Command::QueryPosition).await.unwrap();
    assert_eq!(exchange.outcome, Outcome::Result);
    assert_eq!(
        exchange.result,
        Some(own),
        "group 13's result taken for a command to group 45"
    );
    assert_eq!(exchange.stray_frames, 1);
}

#[tokio::test]
async fn a_result_for_another_source_group_is_not_the_commands() {
    let (ours, theirs) = tokio::io::duplex(4096);
    let command = FrameBuf::new(Address::new(45, 1, 7), CLIENT_GROUP, b"P?").unwrap();
    let others = FrameBuf::new(Address::new(0, 1, 7), 45, b"00000000").unwrap();
    let own = FrameBuf::new(Address::new(CLIENT_GROUP, 1, 7), 45, b"00640064").unwrap();
    tokio::spawn(gcud(theirs, vec![others, own.clone()]));
    let mut master = Master::new(ours, timing::tcp_policy());
    let exchange = master.transact(&command, &Command::QueryPosition).await.unwrap();
    assert_eq!(
        exchange.result,
        Some(own),
        "group 0's result taken for group 100's command"
    );
    assert_eq!(exchange.stray_frames, 1);
}

#[tokio::test]
async fn a_command_to_group_255_takes_any_groups_result() {
    let (ours, theirs) = tokio::io::duplex(4096);
    let command = FrameBuf::new(Address::new(255, 1, 7), CLIENT_GROUP, b"P?").unwrap();
    let answer = FrameBuf::new(Address::new(CLIENT_GROUP, 1, 7), 13, b"00000000").unwrap();
    tokio::spawn(gcud(theirs, vec![answer.clone()]));
    let mut master = Master::new(ours, timing::tcp_policy());
    let exchange = master.transact(&command, &Command::QueryPosition).await.unwrap();
    assert_eq!(exchange.result, Some(answer));
}
