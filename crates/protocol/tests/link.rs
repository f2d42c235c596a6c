//! The sender side: `Transmitter` and `Transaction` (1.4.2, 1.4.3, Figure 6).

use sagebrush_protocol::*;

const RETRY: RetryPolicy = RetryPolicy {
    ack_timeout: 100,
    retries: 2,
};

const POLICY: TransactionPolicy = TransactionPolicy {
    retry: RETRY,
    result_timeout: 500,
    long_result_timeout: 30_000,
    nic_window: 50,
    broadcast_guard: 20,
};

const DEST: Address = Address::new(5, 1, 12);

#[test]
fn transmitter_delivers_on_ack() {
    let mut tx = Transmitter::new(RETRY);
    assert!(!tx.awaiting_ack());
    assert_eq!(tx.on_ack(), TxStep::Wait, "an ACK before sending is ignored");
    assert_eq!(tx.start(1000), TxStep::Send);
    assert!(tx.awaiting_ack());
    assert_eq!(tx.deadline(), Some(1100));
    assert_eq!(tx.poll(1099), TxStep::Wait);
    assert_eq!(tx.on_ack(), TxStep::Delivered);
    assert_eq!(tx.transmissions(), 1);
    assert_eq!(tx.deadline(), None);
    assert_eq!(tx.poll(5000), TxStep::Wait, "nothing after delivery");
    assert_eq!(tx.on_ack(), TxStep::Wait, "a second ACK changes nothing");
    assert_eq!(tx.on_nak(5000), TxStep::Wait);
}

#[test]
fn transmitter_retransmits_on_nak_and_timeout_then_fails() {
    let mut tx = Transmitter::new(RETRY);
    tx.start(0);
    assert_eq!(tx.on_nak(10), TxStep::Send);
    assert_eq!(tx.transmissions(), 2);
    assert_eq!(tx.deadline(), Some(110), "the time-out restarts at the retransmission");
    assert_eq!(tx.poll(109), TxStep::Wait);
    assert_eq!(tx.poll(110), TxStep::Send);
    assert_eq!(tx.transmissions(), 3);
    // 1 transmission + 2 retries spent: the next failure is final and says why.
    assert_eq!(tx.on_nak(120), TxStep::Failed(TxFailure::Nak));
    assert!(!tx.awaiting_ack());
    assert_eq!(tx.on_ack(), TxStep::Wait);

    let mut tx = Transmitter::new(RETRY);
    tx.start(0);
    assert_eq!(tx.poll(100), TxStep::Send);
    assert_eq!(tx.on_nak(150), TxStep::Send);
    assert_eq!(tx.poll(250), TxStep::Failed(TxFailure::NoAck));
    assert_eq!(tx.transmissions(), 3);

    // No retries: the first failure is final.
    let mut tx = Transmitter::new(RetryPolicy {
        ack_timeout: 5,
        retries: 0,
    });
    tx.start(0);
    assert_eq!(tx.poll(5), TxStep::Failed(TxFailure::NoAck));
    // Restart after a failure begins a new count.
    assert_eq!(tx.start(10), TxStep::Send);
    assert_eq!(tx.transmissions(), 1);
    assert_eq!(tx.on_ack(), TxStep::Delivered);
}

fn result_frame() -> FrameBuf {
    // Table 3: the result of a command to 5.1.12 from group 2.
    FrameBuf::new(Address::new(2, 1, 12), 5, b"0064FF9C").unwrap()
}

#[test]
fn transaction_acknowledged_without_result() {
    let mut t = Transaction::new(DEST, &Command::PanLeft, POLICY);
    assert!(!t.is_broadcast());
    assert_eq!(t.outcome(), None);
    assert_eq!(t.start(0), TransactionStep::Send);
    assert!(!t.acknowledged());
    assert_eq!(t.on_event(&Event::Ack, 10), TransactionStep::Wait);
    assert!(t.acknowledged());
    // The NIC window follows the ACK.
    assert_eq!(t.deadline(), Some(60));
    // A frame is not this command's result (it has none).
    let frame = result_frame();
    assert_eq!(t.on_event(&Event::Frame(frame.frame()), 20), TransactionStep::Wait);
    assert_eq!(t.poll(59), TransactionStep::Wait);
    assert_eq!(t.poll(60), TransactionStep::Done(Outcome::Acknowledged));
    assert_eq!(t.outcome(), Some(Outcome::Acknowledged));
    assert_eq!(t.poll(1000), TransactionStep::Done(Outcome::Acknowledged));
    assert_eq!(t.transmissions(), 1);
}

#[test]
fn transaction_result() {
    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 5);
    assert_eq!(t.deadline(), Some(505));
    // A result for another device is not ours.
    let other = FrameBuf::new(Address::new(2, 1, 13), 5, b"0064FF9C").unwrap();
    assert!(!t.is_result_header(&other.frame().dest));
    assert_eq!(t.on_event(&Event::Frame(other.frame()), 6), TransactionStep::Wait);
    let frame = result_frame();
    assert!(t.is_result_header(&frame.frame().dest));
    assert_eq!(
        t.on_event(&Event::Frame(frame.frame()), 7),
        TransactionStep::Done(Outcome::Result)
    );
    assert_eq!(t.outcome(), Some(Outcome::Result));
    assert_eq!(t.deadline(), None);

    // ACK lost, result arrived: taken as both.
    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    t.start(0);
    assert_eq!(
        t.on_event(&Event::Frame(frame.frame()), 3),
        TransactionStep::Done(Outcome::Result)
    );
}

#[test]
fn transaction_nic() {
    for command in [Command::QueryPosition, Command::PanLeft] {
        let mut t = Transaction::new(DEST, &command, POLICY);
        t.start(0);
        t.on_event(&Event::Ack, 1);
        assert_eq!(t.on_event(&Event::Nic, 2), TransactionStep::Done(Outcome::Nic));
    }
    // NIC without the ACK (lost).
    let mut t = Transaction::new(DEST, &Command::Unknown(b"QQ"), POLICY);
    t.start(0);
    assert_eq!(t.on_event(&Event::Nic, 2), TransactionStep::Done(Outcome::Nic));
    // A NIC after the NIC window is over changes nothing.
    let mut t = Transaction::new(DEST, &Command::PanLeft, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 1);
    assert_eq!(t.poll(51), TransactionStep::Done(Outcome::Acknowledged));
    assert_eq!(t.on_event(&Event::Nic, 52), TransactionStep::Wait);
    assert_eq!(t.outcome(), Some(Outcome::Acknowledged));
}

#[test]
fn transaction_no_result() {
    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 10);
    assert_eq!(t.poll(509), TransactionStep::Wait);
    assert_eq!(t.poll(510), TransactionStep::Done(Outcome::NoResult));
}

#[test]
fn transaction_optional_result_times_out_as_acknowledged() {
    let command = Command::Extended(Extended::UserParameters, b"1");
    assert_eq!(command.result_kind(), ResultKind::Optional);
    let mut t = Transaction::new(DEST, &command, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 0);
    assert_eq!(t.poll(500), TransactionStep::Done(Outcome::Acknowledged));
    let mut t = Transaction::new(DEST, &command, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 0);
    let frame = FrameBuf::new(Address::new(2, 1, 12), 5, b"1,2").unwrap();
    assert_eq!(
        t.on_event(&Event::Frame(frame.frame()), 1),
        TransactionStep::Done(Outcome::Result)
    );
}

#[test]
fn transaction_fails_after_naks_and_timeouts() {
    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    assert_eq!(t.start(0), TransactionStep::Send);
    assert_eq!(t.on_event(&Event::Nak, 1), TransactionStep::Send);
    assert_eq!(t.on_event(&Event::Nak, 2), TransactionStep::Send);
    assert_eq!(t.transmissions(), 3);
    assert_eq!(
        t.on_event(&Event::Nak, 3),
        TransactionStep::Done(Outcome::Failed(TxFailure::Nak))
    );

    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    t.start(0);
    assert_eq!(t.deadline(), Some(100));
    assert_eq!(t.poll(100), TransactionStep::Send);
    assert_eq!(t.poll(200), TransactionStep::Send);
    assert_eq!(t.poll(299), TransactionStep::Wait);
    assert_eq!(t.poll(300), TransactionStep::Done(Outcome::Failed(TxFailure::NoAck)));
    assert_eq!(t.transmissions(), 3);
    assert!(!t.acknowledged());
}

#[test]
fn transaction_bad_checksum_events_are_left_to_the_caller() {
    let mut t = Transaction::new(DEST, &Command::QueryPosition, POLICY);
    t.start(0);
    let bad = BadChecksum {
        dest: Address::new(2, 1, 12),
        source: 5,
        payload_len: 8,
        expected: 1,
        found: 2,
        offset: 0,
    };
    assert_eq!(t.on_event(&Event::BadChecksum(bad), 1), TransactionStep::Wait);
    assert_eq!(t.transmissions(), 1);
}

#[test]
fn transaction_broadcast() {
    let dest = Address::new(5, 1, WILDCARD);
    let mut t = Transaction::new(dest, &Command::QueryPosition, POLICY);
    assert!(t.is_broadcast());
    assert_eq!(t.start(100), TransactionStep::Send);
    assert!(t.acknowledged(), "no ACK is awaited");
    assert_eq!(t.transmissions(), 1);
    assert_eq!(t.deadline(), Some(120));
    // Whatever comes back during the guard time is not awaited.
    assert_eq!(t.on_event(&Event::Ack, 101), TransactionStep::Wait);
    assert_eq!(t.on_event(&Event::Nak, 102), TransactionStep::Wait);
    assert_eq!(t.poll(119), TransactionStep::Wait);
    assert_eq!(t.poll(120), TransactionStep::Done(Outcome::Broadcast));
    assert_eq!(t.transmissions(), 1);
}

#[test]
fn transaction_long_timeout_for_initialization() {
    let mut t = Transaction::new(DEST, &Command::Initialize, POLICY);
    t.start(0);
    t.on_event(&Event::Ack, 10);
    assert_eq!(t.deadline(), Some(30_010));
    assert_eq!(
        t.poll(510),
        TransactionStep::Wait,
        "an ordinary result time-out is not enough for IX"
    );
    assert_eq!(t.poll(30_009), TransactionStep::Wait);
    assert_eq!(t.poll(30_010), TransactionStep::Done(Outcome::NoResult));
}

/// A command to port 255 is answered from the device's own port (the
/// endpoint names itself in a wildcard's place): that is still its result.
#[test]
fn transaction_to_port_255_takes_the_answer_from_the_devices_port() {
    let mut t = Transaction::new(Address::new(5, WILDCARD, 12), &Command::QueryPosition, POLICY);
    assert_eq!(t.start(0), TransactionStep::Send);
    assert_eq!(t.on_event(&Event::Ack, 1), TransactionStep::Wait);
    let other_device = FrameBuf::new(Address::new(0, 3, 11), 5, b"00000000").unwrap();
    assert_eq!(
        t.on_event(&Event::Frame(other_device.frame()), 2),
        TransactionStep::Wait,
        "device 11 is not ours"
    );
    let answer = FrameBuf::new(Address::new(0, 3, 12), 5, b"00000000").unwrap();
    assert!(t.is_result_header(&answer.frame().dest));
    assert_eq!(
        t.on_event(&Event::Frame(answer.frame()), 3),
        TransactionStep::Done(Outcome::Result)
    );
    let exact = Transaction::new(Address::new(5, 1, 12), &Command::QueryPosition, POLICY);
    assert!(
        !exact.is_result_header(&Address::new(0, 3, 12)),
        "a named port must match"
    );
}

/// The default time-outs scale with the line rate (1.4.2, 1.5.1: ten bits
/// a byte), and a frame's own wire time is added to its ACK wait.
#[test]
fn serial_time_outs_scale_with_the_line_rate() {
    use sagebrush_protocol::link::{silence_ms, wire_ms};
    assert_eq!(wire_ms(96, 9600), 100);
    assert_eq!(wire_ms(1, 115_200), 1, "rounded up");
    let (slow, fast) = (TransactionPolicy::serial(1200), TransactionPolicy::serial(115_200));
    assert_eq!(fast.retry.ack_timeout, 50 + 2);
    assert_eq!(slow.retry.ack_timeout, 50 + wire_ms(16, 1200));
    assert!(
        slow.result_timeout > fast.result_timeout + 2000,
        "a longest frame back at 1200 bit/s"
    );
    assert_eq!(slow.long_result_timeout, 60_000);
    let long = TransactionPolicy::serial(9600).for_frame(MAX_FRAME_LEN, 9600);
    assert_eq!(
        long.retry.ack_timeout,
        TransactionPolicy::serial(9600).retry.ack_timeout + 274
    );
    assert_eq!(long.result_timeout, TransactionPolicy::serial(9600).result_timeout);
    assert!(silence_ms(1200) > silence_ms(115_200));
}
