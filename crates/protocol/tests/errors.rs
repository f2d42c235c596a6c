//! Every malformed input gives a typed error saying what and where.

use sagebrush_protocol::*;

#[track_caller]
fn bad_arg(payload: &[u8], offset: usize, found: Option<u8>, expected_part: &str) -> String {
    match Command::parse_strict(payload) {
        Err(
            e @ CommandError::BadArgument {
                offset: o,
                found: f,
                expected,
                ..
            },
        ) => {
            assert_eq!((o, f), (offset, found), "{e}");
            assert!(expected.contains(expected_part), "{expected:?} lacks {expected_part:?}");
            assert!(matches!(Command::parse(payload), Command::Unknown(p) if p == payload));
            e.to_string()
        }
        other => panic!("{:?}: {other:?}", String::from_utf8_lossy(payload)),
    }
}

#[track_caller]
fn out_of_range(payload: &[u8], offset: usize, what: &str) {
    match Command::parse_strict(payload) {
        Err(CommandError::OutOfRange { offset: o, error, .. }) => {
            assert_eq!(o, offset, "{error}");
            assert_eq!(error.what, what);
        }
        other => panic!("{:?}: {other:?}", String::from_utf8_lossy(payload)),
    }
}

#[test]
fn command_argument_errors_name_offset_byte_and_expectation() {
    let text = bad_arg(b"GRP2Z", 4, Some(b'Z'), "hex");
    assert_eq!(
        text,
        "GRPnn/GRTnn: at offset 4 expected two hex digits, found byte 0x5A ('Z')"
    );
    bad_arg(b"GRPZ2", 3, Some(b'Z'), "hex");
    bad_arg(b"GRP", 3, None, "hex");
    bad_arg(b"GRP0F0", 5, Some(b'0'), "end of payload");
    bad_arg(b"#G1", 1, Some(b'G'), "hex");
    bad_arg(b"#1", 2, None, "hex");
    bad_arg(b"APxyz", 2, Some(b'x'), "hex");
    bad_arg(b"AP04G1", 4, Some(b'G'), "hex");
    bad_arg(b"P0064FG9C", 6, Some(b'G'), "hex");
    bad_arg(b"P?0G", 3, Some(b'G'), "hex");
    bad_arg(b"S?X0", 2, Some(b'X'), "hex");
    bad_arg(b"S1G", 2, Some(b'G'), "hex");
    bad_arg(b"SPG", 2, Some(b'G'), "hex");
    bad_arg(b"LS12", 4, None, "hex");
    bad_arg(b"LS0000000000000", 14, Some(b'0'), "end of payload");
    bad_arg(b"V12G456", 3, Some(b'G'), "hex");
    bad_arg(b"VM2", 2, Some(b'2'), "'0' or '1'");
    bad_arg(b"RT01", 4, None, "hex");
    bad_arg(b"*x2n", 2, Some(b'2'), "'0' or '1'");
    bad_arg(b"*x0q", 3, Some(b'q'), "c, t, r, n, f");
    bad_arg(b"*x0n1", 3, Some(b'n'), "n and f alone");
    bad_arg(b"*x0rX", 4, Some(b'X'), "decimal");
    bad_arg(b"*x0r1234", 7, Some(b'4'), "end of payload");
    // Table 18 fields, each at its own offset.
    bad_arg(b"*x0c", 4, None, "','");
    bad_arg(b"*x0c9600", 4, Some(b'9'), "','");
    bad_arg(b"*x0c,96x0,8,1,0", 7, Some(b'x'), "','");
    bad_arg(b"*x0c,,8,1,0", 5, Some(b','), "baud");
    bad_arg(b"*x0c,9600;8,1,0", 9, Some(b';'), "','");
    bad_arg(b"*x0c,9600,x,1,0", 10, Some(b'x'), "data bits");
    bad_arg(b"*x0c,9600,8,,0", 12, Some(b','), "stop bits");
    bad_arg(b"*x0c,9600,8,1,", 14, None, "parity");
    bad_arg(b"*x0c,9600,8,1,0,", 15, Some(b','), "end of command");
}

#[test]
fn command_values_out_of_range() {
    out_of_range(b"#00", 1, "device ID");
    out_of_range(b"#FF", 1, "device ID");
    out_of_range(b"GRP02", 3, "rate gain (x10)");
    out_of_range(b"GRT1F", 3, "rate gain (x10)");
    out_of_range(b"*x0r000", 4, "auxiliary read length");
    out_of_range(b"*x0r257", 4, "auxiliary read length");
    out_of_range(b"*x0t", 4, "auxiliary transmit length");
    out_of_range(&[&b"*x0t"[..], &[b'a'; 201]].concat(), 4, "auxiliary transmit length");
    out_of_range(b"*x0c,0,8,1,0", 5, "baud");
    out_of_range(b"*x0c,9600,9,1,0", 10, "data bits");
    out_of_range(b"*x0c,9600,8,3,0", 12, "stop bits");
    out_of_range(b"*x0c,9600,8,1,3", 14, "parity");
    let e = Command::parse_strict(b"#00").unwrap_err();
    assert_eq!(
        e.to_string(),
        "#NN: argument at offset 1: device ID 0 is out of range 1..=254"
    );
}

#[test]
fn unknown_and_empty_commands() {
    assert_eq!(Command::parse_strict(b""), Err(CommandError::Empty));
    assert_eq!(Command::parse(b""), Command::Unknown(b""));
    for payload in [
        &b"QQ"[..],
        b"P",
        b"PX",
        b"L4",
        b"LD",
        b"C",
        b"Z?"[..1].as_ref(),
        b"HX",
        b"\xF8\x06",
    ] {
        assert_eq!(
            Command::parse_strict(payload),
            Err(CommandError::Unknown {
                first: payload[0],
                len: payload.len()
            }),
            "{payload:?}"
        );
        assert_eq!(Command::parse(payload), Command::Unknown(payload));
    }
    assert_eq!(
        Command::parse_strict(b"QQ").unwrap_err().to_string(),
        "no command starts with byte 0x51 and has 2 bytes"
    );
}

#[track_caller]
fn malformed(command: Command<'_>, payload: &[u8], offset: usize, found: Option<u8>, expected_part: &str) {
    match Reply::parse(&command, payload) {
        Err(
            e @ ReplyError::Malformed {
                offset: o,
                found: f,
                expected,
                ..
            },
        ) => {
            assert_eq!((o, f), (offset, found), "{e}");
            assert!(expected.contains(expected_part), "{expected:?} lacks {expected_part:?}");
        }
        other => panic!("{command:?} {:?}: {other:?}", String::from_utf8_lossy(payload)),
    }
}

#[test]
fn reply_errors_name_offset_byte_and_expectation() {
    use Command as C;
    malformed(C::QueryPosition, b"0064FF9", 7, None, "hex");
    malformed(C::QueryPosition, b"0064FG9C", 5, Some(b'G'), "hex");
    malformed(C::QueryPosition, b"0064FF9C0", 8, Some(b'0'), "end of payload");
    malformed(C::QueryLens, b"4BF12", 5, None, "hex");
    malformed(C::QueryErrors, b"01X0", 2, Some(b'X'), "hex");
    malformed(C::QueryStatusBits, b"008100", 6, None, "hex");
    malformed(C::QueryLimits, b"FFF00080012", 11, None, "hex");
    malformed(C::QueryRelays, b"LX", 1, Some(b'X'), "hex");
    malformed(C::QueryMaxDataRate, b"CG", 1, Some(b'G'), "hex");
    malformed(C::AwakeStatus, b"G", 0, Some(b'G'), "hex");
    malformed(C::AwakeStatus, b"12", 1, Some(b'2'), "end of result");
    malformed(C::VerifyHome, b"3G1", 1, Some(b'G'), "hex");
    malformed(C::VerifyHome, b"33", 2, None, "three digits");
    malformed(C::VerifyHome, b"3311", 3, Some(b'1'), "end of result");
    malformed(C::Identify, b"0C1", 3, None, "ID and revision");
    malformed(C::Identify, &[b'0'; 45], 44, Some(b'0'), "44-byte");
    malformed(C::Identify, b"XY19name", 0, Some(b'X'), "device ID");
    malformed(C::Initialize, b"0009000", 7, None, "hex");
    malformed(
        C::AuxCount(AuxPort::new(1).unwrap()),
        b"12a",
        2,
        Some(b'a'),
        "end of payload",
    );
    malformed(C::AuxCount(AuxPort::new(1).unwrap()), b"x", 0, Some(b'x'), "decimal");
    // A frame never carries an empty payload.
    malformed(C::QueryPosition, b"", 0, None, "at least one byte");
    malformed(
        C::Extended(Extended::CameraRelayStatus, b""),
        b"",
        0,
        None,
        "at least one byte",
    );

    let e = Reply::parse(&C::QueryPosition, b"0064FG9C").unwrap_err();
    assert_eq!(
        e.to_string(),
        "result of P?: at offset 5 expected eight hex digits, found byte 0x47 ('G')"
    );
    assert_eq!(
        Reply::parse(&C::Halt, b"1"),
        Err(ReplyError::NoResult { command: "HA" })
    );
    assert_eq!(
        Reply::parse(&C::Unknown(b"QQ"), b"1"),
        Err(ReplyError::NoResult { command: "unknown" })
    );
    match Reply::parse(&C::QueryRateGains, b"0F200000") {
        Err(ReplyError::OutOfRange { offset: 2, error, .. }) => assert_eq!(error.value, 32),
        other => panic!("{other:?}"),
    }
    match Reply::parse(&C::QueryRateGains, b"00") {
        Err(ReplyError::Malformed {
            offset: 2, found: None, ..
        }) => {}
        other => panic!("{other:?}"),
    }
    match Reply::parse(&C::AuxCount(AuxPort::new(0).unwrap()), b"65536") {
        Err(ReplyError::OutOfRange { offset: 0, error, .. }) => assert_eq!(error.value, 65536),
        other => panic!("{other:?}"),
    }
}

#[test]
fn frame_errors() {
    let good = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
    assert_eq!(Frame::parse(&[0x41]), Err(FrameError::BadStart { found: 0x41 }));
    assert_eq!(
        Frame::parse(&[0x41, 1, 2, 3, 4, 5, 6]),
        Err(FrameError::BadStart { found: 0x41 })
    );
    assert_eq!(
        Frame::parse(&[]),
        Err(FrameError::Incomplete {
            needed: 6,
            available: 0
        })
    );
    assert_eq!(
        Frame::parse(&good[..3]),
        Err(FrameError::Incomplete {
            needed: 6,
            available: 3
        })
    );
    assert_eq!(
        Frame::parse(&good[..8]),
        Err(FrameError::Incomplete {
            needed: 9,
            available: 8
        })
    );
    let mut bad = good;
    bad[8] = 0xA4;
    let e = Frame::parse(&bad).unwrap_err();
    assert_eq!(
        e,
        FrameError::BadChecksum {
            offset: 8,
            expected: 0xA5,
            found: 0xA4
        }
    );
    assert_eq!(e.to_string(), "checksum at offset 8: expected 0xA5, found 0xA4");
    let with_ack = [&good[..], &[0x06]].concat();
    let (frame, rest) = Frame::parse(&with_ack).unwrap();
    assert_eq!(frame.payload(), b"P?");
    assert_eq!(rest, [0x06]);
}

#[test]
fn encode_errors() {
    let frame = Frame::new(Address::new(1, 2, 3), 0, b"AW").unwrap();
    let mut small = [0u8; 5];
    assert_eq!(
        frame.encode(&mut small),
        Err(EncodeError::BufferTooSmall { needed: 6, capacity: 5 })
    );
    let mut small = [0u8; 8];
    assert_eq!(
        frame.encode(&mut small),
        Err(EncodeError::BufferTooSmall { needed: 9, capacity: 8 })
    );
    let mut buf = [0u8; 4];
    assert_eq!(
        Command::GoTo(Position::default()).encode(&mut buf),
        Err(EncodeError::BufferTooSmall { needed: 5, capacity: 4 })
    );
    let mut buf = [0u8; 300];
    assert_eq!(
        Command::Unknown(b"").encode(&mut buf),
        Err(EncodeError::PayloadLength { len: 0 })
    );
    assert_eq!(
        Reply::Raw(b"").encode(&mut buf),
        Err(EncodeError::PayloadLength { len: 0 })
    );
    // Reserved is a public variant; only C8..CF exist on the wire.
    for code in [0u8, 7, 16, 200] {
        assert!(matches!(
            Command::SetDataRate(DataRate::Reserved(code)).encode(&mut buf),
            Err(EncodeError::OutOfRange(RangeError { min: 8, max: 15, .. }))
        ));
        assert!(matches!(
            Reply::MaxDataRate(DataRate::Reserved(code)).encode(&mut buf),
            Err(EncodeError::OutOfRange(_))
        ));
    }
    assert!(matches!(
        Reply::Relays(16).encode(&mut buf),
        Err(EncodeError::OutOfRange(_))
    ));
    let home = HomeStatus {
        limit_switches: 0,
        center_switches: 16,
        count_correct: 0,
    };
    assert!(matches!(
        Reply::VerifyHome(home).encode(&mut buf),
        Err(EncodeError::OutOfRange(_))
    ));
}

#[test]
fn range_constructors() {
    assert!(DeviceId::new(0).is_err() && DeviceId::new(255).is_err() && DeviceId::new(1).is_ok());
    assert!(RateGain::new(2).is_err() && RateGain::new(31).is_err());
    assert!(U12::new(4096).is_err());
    assert!(Speed::new(16).is_err());
    assert!(LensSpeed::new(10).is_err());
    assert!(DigitalZoom::new(9).is_err());
    assert!(Relay::new(4).is_err());
    assert!(AuxPort::new(2).is_err());
    assert!(AuxReadLen::new(0).is_err() && AuxReadLen::new(257).is_err());
    assert!(AuxBytes::new(b"").is_err() && AuxBytes::new(&[0; 201]).is_err());
    let e = RateGain::new(31).unwrap_err();
    assert_eq!(e.to_string(), "rate gain (x10) 31 is out of range 3..=30");
}

#[test]
fn address_text() {
    assert_eq!("5.1.12".parse::<Address>(), Ok(Address::new(5, 1, 12)));
    assert_eq!(Address::new(5, 1, 12).to_string(), "5.1.12");
    assert_eq!("5.1".parse::<Address>(), Err(AddressParseError::Parts { found: 2 }));
    assert_eq!("5.1.2.3".parse::<Address>(), Err(AddressParseError::Parts { found: 4 }));
    assert_eq!(
        "5.256.1".parse::<Address>(),
        Err(AddressParseError::Number { index: 1 })
    );
    assert!(Address::new(1, 255, 1).has_wildcard());
    assert!(!Address::new(1, 2, 3).has_wildcard());
}
