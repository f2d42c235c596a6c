use sagebrush_protocol::*;

#[test]
fn table3_example_and_reply() {
    let cmd = Command::QueryPosition;
    let mut p = [0u8; 16];
    let payload = cmd.encode(&mut p).unwrap();
    let f = Frame::new(Address::new(5, 1, 12), 2, payload).unwrap();
    let mut buf = [0u8; 300];
    assert_eq!(
        f.encode(&mut buf).unwrap(),
        &[0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5]
    );
    let mut framer: Framer = Framer::new();
    // Noise, the frame, an ACK: exactly two events, in that order. The
    // count is checked after `feed`, so a framer that reports nothing fails.
    let mut n = 0;
    framer.feed(
        &[0x41, 0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5, 0x06],
        |e| {
            n += 1;
            match n {
                1 => assert!(matches!(e, Event::Frame(f) if f.payload() == b"P?"), "{e:?}"),
                2 => assert_eq!(e, Event::Ack),
                _ => panic!("unexpected event {n}: {e:?}"),
            }
        },
    );
    assert_eq!(n, 2, "events seen");
    assert_eq!(framer.skipped_bytes(), 1);
    for (payload, want) in [
        (&b"P?"[..], Command::QueryPosition),
        (b"P0A", Command::GoToPreset(10)),
        (b"SPF", Command::SetSpeed(Axis::Pan, Speed::new(15).unwrap())),
    ] {
        assert_eq!(Command::parse(payload), want);
        let mut b = [0u8; 300];
        assert_eq!(want.encode(&mut b).unwrap(), payload);
    }
    let r = Reply::parse(&Command::QueryPosition, b"P?0064FF9C").unwrap();
    assert_eq!(r, Reply::Position(Position::new(Angle(100), Angle(-100))));
}
