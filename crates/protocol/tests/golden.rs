//! Golden vectors from the protocol document (rev 1.9) and the readings of
//! docs/protocol-notes.md (E1-E15), both directions.

mod common;

use common::Owned;
use sagebrush_protocol::*;

fn encode_frame(frame: &Frame<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    frame.encode(&mut buf).unwrap().to_vec()
}

fn encode_command(command: &Command<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_PAYLOAD];
    command.encode(&mut buf).unwrap().to_vec()
}

fn encode_reply(reply: &Reply<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_PAYLOAD];
    reply.encode(&mut buf).unwrap().to_vec()
}

fn framer_events(bytes: &[u8]) -> (Vec<Owned>, FramerStats) {
    let mut framer: Framer = Framer::new();
    let events = common::feed_all(&mut framer, &[bytes]);
    (events, framer.stats())
}

// ---------------------------------------------------------------- frames

/// Table 3: `P?` to 5.1.12 from group 2, and its result with the header swapped.
#[test]
fn table3_command_and_result_both_ways() {
    let wire = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    assert_eq!(encode_frame(&cmd), wire);
    assert_eq!(cmd.checksum(), 0xA5);
    assert_eq!(cmd.wire_len(), 9);
    let (parsed, rest) = Frame::parse(&wire).unwrap();
    assert_eq!(parsed, cmd);
    assert!(rest.is_empty());
    assert_eq!(Command::parse(parsed.payload()), Command::QueryPosition);

    // Result: destination group 2 (the command's source), port and device
    // unchanged, source group 5.
    let (dest, source) = cmd.reply_header();
    assert_eq!((dest, source), (Address::new(2, 1, 12), 5));
    let result_wire = [
        0xF8, 0x02, 0x01, 0x0C, 0x05, 0x08, b'0', b'0', b'6', b'4', b'F', b'F', b'9', b'C', 0xEE,
    ];
    let result = Frame::new(dest, source, b"0064FF9C").unwrap();
    assert_eq!(encode_frame(&result), result_wire);
    let (parsed, _) = Frame::parse(&result_wire).unwrap();
    assert_eq!(parsed.dest, Address::new(2, 1, 12));
    assert_eq!(parsed.source, 5);
    assert_eq!(
        Reply::parse(&Command::QueryPosition, parsed.payload()).unwrap(),
        Reply::Position(Position::new(Angle(100), Angle(-100)))
    );
    // And the result's own reply header gives back the command's header.
    assert_eq!(parsed.reply_header(), (Address::new(5, 1, 12), 2));
}

/// 1.4.1.1: a 256-byte payload has length byte 0.
#[test]
fn payload_of_256_bytes_has_length_byte_zero() {
    let payload = [b'A'; 256];
    let frame = Frame::new(Address::new(1, 2, 3), 0xF8, &payload).unwrap();
    let wire = encode_frame(&frame);
    assert_eq!(wire.len(), MAX_FRAME_LEN);
    assert_eq!(&wire[..6], &[0xF8, 1, 2, 3, 0xF8, 0x00]);
    // 256 x 0x41 sums to 0 mod 256; 1 + 2 + 3 + 0xF8 + 0 = 0xFE.
    assert_eq!(wire[262], 0xFE);
    let (parsed, rest) = Frame::parse(&wire).unwrap();
    assert_eq!(parsed.payload().len(), 256);
    assert!(rest.is_empty());
    let (events, stats) = framer_events(&wire);
    assert_eq!(events.len(), 1);
    assert!(matches!(&events[0], Owned::Frame { payload, .. } if payload.len() == 256));
    assert_eq!(stats.skipped_bytes, 0);
    assert_eq!(
        Frame::new(Address::new(1, 2, 3), 0, &[b'A'; 257]),
        Err(FrameError::PayloadLength { len: 257 })
    );
    assert_eq!(
        Frame::new(Address::new(1, 2, 3), 0, b""),
        Err(FrameError::PayloadLength { len: 0 })
    );
}

/// 0xF8 is a legal group, port, device, source, length and checksum byte.
#[test]
fn start_byte_inside_header_and_as_checksum() {
    // 0xF8 as destination group.
    let in_header = [0xF8, 0xF8, 0x01, 0x02, 0x00, 0x02, b'A', b'W', 0x95];
    assert_eq!(
        encode_frame(&Frame::new(Address::new(0xF8, 1, 2), 0, b"AW").unwrap()),
        in_header
    );
    // 0xF8 as checksum: 1 + 1 + 0x65 + 0 + 2 + 'P' + '?' = 0xF8.
    let as_checksum = [0xF8, 0x01, 0x01, 0x65, 0x00, 0x02, b'P', b'?', 0xF8];
    assert_eq!(
        encode_frame(&Frame::new(Address::new(1, 1, 0x65), 0, b"P?").unwrap()),
        as_checksum
    );
    // 0xF8 in every header byte at once, and as length (248-byte payload).
    let payload = [b'?'; 248];
    let all = encode_frame(&Frame::new(Address::new(0xF8, 0xF8, 0xF8), 0xF8, &payload).unwrap());
    assert_eq!(&all[..6], &[0xF8; 6]);

    let mut stream = Vec::new();
    stream.extend_from_slice(&in_header);
    stream.push(ACK);
    stream.extend_from_slice(&as_checksum);
    stream.extend_from_slice(&all);
    stream.extend_from_slice(&as_checksum);
    let (events, stats) = framer_events(&stream);
    let frames: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            Owned::Frame { dest, .. } => Some(*dest),
            _ => None,
        })
        .collect();
    assert_eq!(
        frames,
        [
            Address::new(0xF8, 1, 2),
            Address::new(1, 1, 0x65),
            Address::new(0xF8, 0xF8, 0xF8),
            Address::new(1, 1, 0x65)
        ]
    );
    assert_eq!(events[1], Owned::Ack);
    assert_eq!(events.len(), 5);
    assert_eq!(stats.skipped_bytes, 0);
    assert_eq!(stats.bad_checksums, 0);
}

/// protocol-notes "Framing": after a false 0xF8 the scan resumes at the byte after
/// it, so a real frame inside the false candidate's span is found.
#[test]
fn framer_rescans_after_a_false_start() {
    let table3 = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
    // A stray 0xF8 then the frame: the false candidate claims
    // 6 + 0x0C + 1 = 19 bytes (its length byte is the frame's device byte).
    let mut stream = vec![0xF8, 0x00];
    stream.extend_from_slice(&table3);
    // More traffic completes the false candidate: it is rejected once, and
    // the frame inside it is still found.
    stream.extend_from_slice(&table3);
    let (events, stats) = framer_events(&stream);
    assert!(matches!(
        events[0],
        Owned::Bad(BadChecksum {
            offset: 0,
            payload_len: 12,
            ..
        })
    ));
    assert!(matches!(&events[1], Owned::Frame { payload, .. } if payload == b"P?"));
    assert!(matches!(&events[2], Owned::Frame { payload, .. } if payload == b"P?"));
    assert_eq!(events.len(), 3);
    assert_eq!(stats.skipped_bytes, 2);

    // The same stray start with nothing after the frame: the framer waits
    // for the 19 bytes it claims, then the silence hook gives the frame up.
    let mut framer: Framer = Framer::new();
    let mut got = Vec::new();
    framer.feed(&[0xF8, 0x00], |e| got.push(Owned::of(&e)));
    framer.feed(&table3, |e| got.push(Owned::of(&e)));
    assert!(got.is_empty(), "nothing decided before the line is idle");
    assert_eq!(framer.buffered(), 11);
    framer.flush_idle(|e| got.push(Owned::of(&e)));
    assert_eq!(got.len(), 1);
    assert!(matches!(&got[0], Owned::Frame { dest, .. } if *dest == Address::new(5, 1, 12)));
    assert_eq!(framer.buffered(), 0);
    assert_eq!(framer.stats().abandoned, 1);
    assert_eq!(framer.skipped_bytes(), 2);
}

/// Bytes inside a rejected candidate are not ACK/NAK/NIC; one damaged frame gives one event.
#[test]
fn damaged_frame_is_one_bad_checksum_event() {
    // Device 6 and payload `P?` contain 0x06 and '?'.
    let mut wire = encode_frame(&Frame::new(Address::new(1, 1, 6), 0x15, b"P?").unwrap());
    let last = wire.len() - 1;
    wire[last] ^= 0x01;
    wire.push(ACK);
    let (events, stats) = framer_events(&wire);
    assert_eq!(events.len(), 2, "{events:?}");
    match &events[0] {
        Owned::Bad(bad) => {
            assert_eq!(bad.dest, Address::new(1, 1, 6));
            assert_eq!(bad.source, 0x15);
            assert_eq!(bad.payload_len, 2);
            assert_eq!(bad.found ^ 1, bad.expected);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(events[1], Owned::Ack, "the byte after the span is an ACK again");
    assert_eq!(stats.skipped_bytes, 9);
    assert_eq!(stats.bad_checksums, 1);
}

#[test]
fn bare_bytes_and_noise() {
    let (events, stats) = framer_events(&[0x06, 0x00, 0x15, b'x', b'?', 0xFF]);
    assert_eq!(events, [Owned::Ack, Owned::Nak, Owned::Nic]);
    assert_eq!(stats.skipped_bytes, 3);
    assert_eq!((ACK, NAK, NIC, START), (0x06, 0x15, 0x3F, 0xF8));
}

#[test]
fn frame_buf_builds_and_rewrites_headers() {
    let mut buf = FrameBuf::build(Address::new(5, 1, 12), 2, |b| {
        Command::QueryPosition.encode(b).map(<[u8]>::len)
    })
    .unwrap();
    assert_eq!(buf.as_bytes(), [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5]);
    let frame = buf.frame();
    let (dest, source) = frame.reply_header();
    buf.set_header(dest, source);
    assert_eq!(buf.as_bytes(), [0xF8, 0x02, 0x01, 0x0C, 0x05, 0x02, 0x50, 0x3F, 0xA5]);
    assert_eq!(Frame::parse(buf.as_bytes()).unwrap().0.dest, Address::new(2, 1, 12));
    assert_eq!(
        FrameBuf::build(Address::new(1, 1, 1), 0, |_| Ok(0)),
        Err(EncodeError::PayloadLength { len: 0 })
    );
    assert_eq!(
        FrameBuf::new(Address::new(1, 1, 1), 0, b""),
        Err(FrameError::PayloadLength { len: 0 })
    );
}

// -------------------------------------------------------------- commands

/// `payload` parses to `command`, strictly too, and `command` encodes to `payload`.
#[track_caller]
fn both_ways(payload: &[u8], command: Command<'_>) {
    assert_eq!(
        Command::parse(payload),
        command,
        "parse {:?}",
        String::from_utf8_lossy(payload)
    );
    assert_eq!(Command::parse_strict(payload), Ok(command));
    assert_eq!(encode_command(&command), payload, "encode {command:?}");
}

/// `payload` is a lenient form of `command`, which encodes as `canonical`.
#[track_caller]
fn lenient(payload: &[u8], command: Command<'_>, canonical: &[u8]) {
    assert_eq!(Command::parse_strict(payload), Ok(command));
    assert_eq!(encode_command(&command), canonical);
}

#[test]
fn commands_table4_general() {
    use Command as C;
    both_ways(b"#0C", C::SetDeviceId(DeviceId::new(12).unwrap()));
    both_ways(b"#FE", C::SetDeviceId(DeviceId::new(254).unwrap()));
    both_ways(b"AW", C::AwakeStatus);
    both_ways(b"B?", C::QueryMaxDataRate);
    let rates = [1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200];
    for (code, bps) in rates.into_iter().enumerate() {
        let rate = DataRate::from_bits_per_second(bps).unwrap();
        assert_eq!(rate.code() as usize, code);
        assert_eq!(rate.bits_per_second(), Some(bps));
        both_ways(format!("C{code}").as_bytes(), C::SetDataRate(rate));
    }
    // E15: C8..CF parse as reserved; no line rate.
    for code in 8u8..=15 {
        let payload = format!("C{code:X}");
        both_ways(payload.as_bytes(), C::SetDataRate(DataRate::Reserved(code)));
        assert_eq!(DataRate::Reserved(code).bits_per_second(), None);
    }
    assert_eq!(Command::parse(b"CB").data_rate_change(), Some(DataRate::Reserved(11)));
    both_ways(b"D?", C::Identify);
    both_ways(b"E?", C::QueryErrors);
    both_ways(b"I?", C::QueryStatusBits);
    // E1: gain 1.5 is sent as 0F (not 0E); range 0.3..3.0 -> 03..1E.
    both_ways(b"GRP0F", C::SetRateGain(Axis::Pan, RateGain::new(15).unwrap()));
    both_ways(b"GRT03", C::SetRateGain(Axis::Tilt, RateGain::new(3).unwrap()));
    both_ways(b"GRT1E", C::SetRateGain(Axis::Tilt, RateGain::new(30).unwrap()));
    both_ways(b"G?", C::QueryRateGains);
    both_ways(b"IX", C::Initialize);
    for r in 0..4u8 {
        both_ways(&[b'L', b'0' + r], C::OpenRelay(Relay::new(r).unwrap()));
        both_ways(&[b'L', b"89AB"[r as usize]], C::CloseRelay(Relay::new(r).unwrap()));
    }
    both_ways(b"LR", C::QueryRelays);
    both_ways(b"LC", C::ClearLimits);
    let limits = Limits {
        pan_ccw: U12::new(0xFFF).unwrap(),
        pan_cw: U12::new(0).unwrap(),
        tilt_ccw: U12::new(0x800).unwrap(),
        tilt_cw: U12::new(0x123).unwrap(),
    };
    both_ways(b"LSFFF000800123", C::SetLimits(limits));
    both_ways(b"L?", C::QueryLimits);
    // Lower-case hex digits are accepted, emitted upper case.
    lenient(b"#0c", C::SetDeviceId(DeviceId::new(12).unwrap()), b"#0C");
    lenient(b"Lb", C::CloseRelay(Relay::new(3).unwrap()), b"LB");
    lenient(b"Cf", C::SetDataRate(DataRate::Reserved(15)), b"CF");
    lenient(b"LSfff000800123", C::SetLimits(limits), b"LSFFF000800123");
}

#[test]
fn commands_table11_pan_tilt() {
    use Command as C;
    // Table 12: 10.25 deg/s^2 -> 1025 -> 0401.
    both_ways(b"AP0401", C::SetAcceleration(Axis::Pan, Acceleration(1025)));
    both_ways(b"ATFFFF", C::SetAcceleration(Axis::Tilt, Acceleration(0xFFFF)));
    both_ways(b"A?", C::QueryAccelerations);
    // E7: per-axis queries.
    both_ways(b"AP?", C::QueryAcceleration(Axis::Pan));
    both_ways(b"AT?", C::QueryAcceleration(Axis::Tilt));
    both_ways(b"HA", C::Halt);
    both_ways(b"HV", C::VerifyHome);
    both_ways(b"HO", C::Home);
    both_ways(b"HS", C::MotorsStop);
    both_ways(b"P?", C::QueryPosition);
    // E8: signed hundredths of a degree.
    both_ways(b"P0064FF9C", C::GoTo(Position::new(Angle(100), Angle(-100))));
    both_ways(b"P80007FFF", C::GoTo(Position::new(Angle(i16::MIN), Angle(i16::MAX))));
    both_ways(b"PL", C::PanLeft);
    both_ways(b"PR", C::PanRight);
    both_ways(b"PS", C::PanStop);
    both_ways(b"PT", C::StopMotion);
    both_ways(b"P0A", C::GoToPreset(10));
    both_ways(b"PFF", C::GoToPreset(255));
    both_ways(b"P?0A", C::QueryPreset(10));
    both_ways(b"RP0401", C::SetRate(Axis::Pan, Rate(1025)));
    both_ways(b"RT0000", C::SetRate(Axis::Tilt, Rate(0)));
    both_ways(b"R?", C::QueryRates);
    both_ways(b"RP?", C::QueryRate(Axis::Pan));
    both_ways(b"RT?", C::QueryRate(Axis::Tilt));
    both_ways(b"S0A", C::StorePreset(10));
    both_ways(b"SP0", C::SetSpeed(Axis::Pan, Speed::new(0).unwrap()));
    both_ways(b"STF", C::SetSpeed(Axis::Tilt, Speed::new(15).unwrap()));
    both_ways(b"S?0A", C::QueryStoredPreset(10));
    both_ways(b"TD", C::TiltDown);
    both_ways(b"TS", C::TiltStop);
    both_ways(b"TU", C::TiltUp);
    both_ways(b"VM1", C::SetVectorMode(true));
    both_ways(b"VM0", C::SetVectorMode(false));
    // Disambiguation by length and letters (protocol-notes "Command disambiguation"): P?/PL (2), Pnn (3),
    // P?nn (4), Paaaaeeee (9); Snn vs SPn/STn (P, T are not hex) vs S?nn.
    assert_eq!(Command::parse(b"PA0"), C::GoToPreset(0xA0));
    assert_eq!(Command::parse(b"S10"), C::StorePreset(0x10));
    assert_eq!(Command::parse(b"SP1"), C::SetSpeed(Axis::Pan, Speed::new(1).unwrap()));
    assert!(matches!(Command::parse(b"P00640"), C::Unknown(_)));
    lenient(
        b"P0064ff9c",
        C::GoTo(Position::new(Angle(100), Angle(-100))),
        b"P0064FF9C",
    );
    lenient(b"Sf0", C::StorePreset(0xF0), b"SF0");
    // E12: direction of motion.
    assert_eq!(C::PanLeft.stopped_by(), Some(C::PanStop));
    assert_eq!(C::TiltUp.stopped_by(), Some(C::TiltStop));
    assert!(C::StopMotion.is_stop());
    assert!(!C::PanLeft.is_stop());
}

#[test]
fn commands_table16_camera() {
    use Command as C;
    both_ways(b"CN", C::CameraOn);
    both_ways(b"CX", C::CameraOff);
    both_ways(b"F0", C::FocusSpeed(LensSpeed::new(0).unwrap()));
    both_ways(b"F9", C::FocusSpeed(LensSpeed::new(9).unwrap()));
    both_ways(b"FA", C::AutoFocusOn);
    both_ways(b"FF", C::FocusFar);
    both_ways(b"FN", C::FocusNear);
    both_ways(b"FS", C::FocusStop);
    both_ways(b"FX", C::AutoFocusOff);
    // Table 17, E2: plain upper-case hex.
    let lens = LensPosition {
        zoom: U12::new(0x4BF).unwrap(),
        focus: U12::new(0x123).unwrap(),
    };
    both_ways(b"V4BF123", C::LensGoTo(lens));
    both_ways(b"V?", C::QueryLens);
    both_ways(b"Z0", C::ZoomSpeed(LensSpeed::new(0).unwrap()));
    both_ways(b"Z9", C::ZoomSpeed(LensSpeed::new(9).unwrap()));
    both_ways(b"ZA", C::DigitalZoom(DigitalZoom::new(10).unwrap()));
    both_ways(b"ZF", C::DigitalZoom(DigitalZoom::new(15).unwrap()));
    both_ways(b"ZI", C::ZoomIn);
    both_ways(b"ZO", C::ZoomOut);
    both_ways(b"ZS", C::ZoomStop);
    // Table 18's example.
    let config = AuxConfig::new(9600, 8, 1, Parity::None).unwrap();
    both_ways(b"*x0c,9600,8,1,0", C::AuxConfigure(AuxPort::new(0).unwrap(), config));
    let config = AuxConfig::new(115200, 7, 2, Parity::Even).unwrap();
    both_ways(b"*x1c,115200,7,2,2", C::AuxConfigure(AuxPort::new(1).unwrap(), config));
    let port1 = AuxPort::new(1).unwrap();
    both_ways(b"*x1thello", C::AuxTransmit(port1, AuxBytes::new(b"hello").unwrap()));
    // E14: decimal counts.
    both_ways(
        b"*x0r100",
        C::AuxReceive(AuxPort::new(0).unwrap(), AuxReadLen::new(100).unwrap()),
    );
    lenient(
        b"*x0r5",
        C::AuxReceive(AuxPort::new(0).unwrap(), AuxReadLen::new(5).unwrap()),
        b"*x0r005",
    );
    both_ways(b"*x1n", C::AuxCount(port1));
    both_ways(b"*x1f", C::AuxFlush(port1));
    assert_eq!(C::ZoomIn.stopped_by(), Some(C::ZoomStop));
    assert_eq!(C::FocusNear.stopped_by(), Some(C::FocusStop));
}

/// E13: rev 1.9 commands by name with raw arguments.
#[test]
fn commands_rev19_extended() {
    for ext in Extended::ALL {
        both_ways(ext.name().as_bytes(), Command::Extended(ext, b""));
        let with_args = [ext.name().as_bytes(), b"12,3.5"].concat();
        both_ways(&with_args, Command::Extended(ext, b"12,3.5"));
    }
    assert_eq!(
        Command::parse(b"VS").result_kind(),
        ResultKind::Required(ResultTimeout::Normal)
    );
    assert_eq!(Command::parse(b"HP").result_kind(), ResultKind::None);
    assert_eq!(Command::parse(b"*mu1").result_kind(), ResultKind::Optional);
}

#[test]
fn result_kinds() {
    use Command as C;
    assert_eq!(C::Initialize.result_kind(), ResultKind::Required(ResultTimeout::Long));
    assert_eq!(
        C::QueryPosition.result_kind(),
        ResultKind::Required(ResultTimeout::Normal)
    );
    assert_eq!(C::PanLeft.result_kind(), ResultKind::None);
    assert_eq!(C::Unknown(b"QQ").result_kind(), ResultKind::None);
    assert_eq!(C::QueryPosition.mnemonic(), "P?");
    assert_eq!(C::Extended(Extended::RateGainFloat, b"").mnemonic(), "*sgr");
}

// --------------------------------------------------------------- replies

#[track_caller]
fn reply_both_ways(command: Command<'_>, payload: &[u8], reply: Reply<'_>) {
    assert_eq!(
        Reply::parse(&command, payload),
        Ok(reply),
        "{:?}",
        String::from_utf8_lossy(payload)
    );
    assert_eq!(encode_reply(&reply), payload);
    assert!(reply.answers(&command));
}

#[track_caller]
fn reply_lenient(command: Command<'_>, payload: &[u8], reply: Reply<'_>, canonical: &[u8]) {
    assert_eq!(
        Reply::parse(&command, payload),
        Ok(reply),
        "{:?}",
        String::from_utf8_lossy(payload)
    );
    assert_eq!(encode_reply(&reply), canonical);
}

#[test]
fn replies_table4a_relays_e11() {
    use Command as C;
    reply_both_ways(C::QueryRelays, b"L5", Reply::Relays(5));
    reply_both_ways(C::QueryRelays, b"LF", Reply::Relays(15));
    reply_lenient(C::QueryRelays, b"3", Reply::Relays(3), b"L3");
    // E6: an echo of the command.
    reply_lenient(C::QueryRelays, b"LRL3", Reply::Relays(3), b"L3");
    reply_lenient(C::QueryRelays, b"LR3", Reply::Relays(3), b"L3");
}

#[test]
fn replies_table5_awake_e10() {
    use Command as C;
    let s = AwakeStatus::new(AwakeStatus::PAN_NOT_INITIALIZED | AwakeStatus::ERROR).unwrap();
    reply_both_ways(C::AwakeStatus, b"9", Reply::AwakeStatus(s));
    reply_both_ways(C::AwakeStatus, b"0", Reply::AwakeStatus(AwakeStatus::new(0).unwrap()));
    // A raw byte 0x00..=0x0F.
    reply_lenient(C::AwakeStatus, &[0x09], Reply::AwakeStatus(s), b"9");
    reply_lenient(
        C::AwakeStatus,
        &[0x00],
        Reply::AwakeStatus(AwakeStatus::new(0).unwrap()),
        b"0",
    );
    reply_lenient(
        C::AwakeStatus,
        b"AWc",
        Reply::AwakeStatus(AwakeStatus::new(12).unwrap()),
        b"C",
    );
    assert!(AwakeStatus::new(16).is_err());
}

#[test]
fn replies_max_data_rate_e15() {
    use Command as C;
    reply_both_ways(C::QueryMaxDataRate, b"C7", Reply::MaxDataRate(DataRate::Bps115200));
    reply_both_ways(C::QueryMaxDataRate, b"CA", Reply::MaxDataRate(DataRate::Reserved(10)));
    reply_lenient(C::QueryMaxDataRate, b"3", Reply::MaxDataRate(DataRate::Bps9600), b"C3");
    reply_lenient(
        C::QueryMaxDataRate,
        b"B?C3",
        Reply::MaxDataRate(DataRate::Bps9600),
        b"C3",
    );
}

#[test]
fn replies_table6_identity_e5() {
    let block = b"0C19PTU-D300            SN-000123           ";
    assert_eq!(block.len(), 44);
    let id = Identity::new(12, *b"19", b"PTU-D300", b"SN-000123").unwrap();
    reply_both_ways(Command::Identify, block, Reply::Identity(id));
    // Leading-space revision, short block, no serial.
    let short = Identity::new(0xFE, *b" 9", b"PTU", b"").unwrap();
    reply_lenient(Command::Identify, b"FE 9PTU", Reply::Identity(short), {
        b"FE 9PTU                                     "
    });
    let Ok(Reply::Identity(parsed)) = Reply::parse(&Command::Identify, block) else {
        panic!()
    };
    assert_eq!(
        (parsed.name(), parsed.serial(), parsed.revision),
        (&b"PTU-D300"[..], &b"SN-000123"[..], *b"19")
    );
    assert!(Identity::new(1, *b"19", b"trailing ", b"").is_err());
    assert!(Identity::new(1, *b"19", &[b'x'; 21], b"").is_err());
}

#[test]
fn replies_table6a_6b_e3() {
    use Command as C;
    reply_both_ways(
        C::QueryErrors,
        b"0110",
        Reply::Errors(ErrorCodes { pan: 0x01, tilt: 0x10 }),
    );
    reply_both_ways(
        C::QueryStatusBits,
        b"00810002",
        Reply::StatusBits(StatusBits { pan: 0x81, tilt: 2 }),
    );
    // E3: 2 + 2 characters accepted, 4 + 4 emitted.
    reply_lenient(
        C::QueryStatusBits,
        b"8102",
        Reply::StatusBits(StatusBits { pan: 0x81, tilt: 2 }),
        b"00810002",
    );
}

#[test]
fn replies_table8_gains_e1_e6() {
    let g = |p, t| {
        Reply::RateGains(RateGains {
            pan: RateGain::new(p).unwrap(),
            tilt: RateGain::new(t).unwrap(),
        })
    };
    // 13 hex -> 1.9; 0F -> 1.5 (E1).
    reply_both_ways(Command::QueryRateGains, b"0F130000", g(15, 19));
    reply_lenient(Command::QueryRateGains, b"G?0F13nnnn", g(15, 19), b"0F130000");
    reply_lenient(Command::QueryRateGains, b"0F13", g(15, 19), b"0F130000");
    reply_lenient(Command::QueryRateGains, b"G?0F13", g(15, 19), b"0F130000");
}

#[test]
fn replies_table9_initialization_e4() {
    let r = InitResults {
        pan_ccw: 0x09,
        pan_cw: 0x01,
        tilt_ccw: 0x0D,
        tilt_cw: 0x108,
    };
    reply_both_ways(Command::Initialize, b"00090001000D0108", Reply::Initialization(r));
    let short = InitResults { tilt_cw: 0x08, ..r };
    reply_lenient(
        Command::Initialize,
        b"09010D08",
        Reply::Initialization(short),
        b"00090001000D0008",
    );
}

#[test]
fn replies_table10_limits() {
    let l = Limits {
        pan_ccw: U12::new(0xFFF).unwrap(),
        pan_cw: U12::new(0).unwrap(),
        tilt_ccw: U12::new(0x800).unwrap(),
        tilt_cw: U12::new(0x123).unwrap(),
    };
    reply_both_ways(Command::QueryLimits, b"FFF000800123", Reply::Limits(l));
    reply_lenient(
        Command::QueryLimits,
        b"L?FFF000800123",
        Reply::Limits(l),
        b"FFF000800123",
    );
}

#[test]
fn replies_table13_rates_accelerations_e7() {
    use Command as C;
    let acc = Reply::Accelerations {
        pan: Acceleration(1025),
        tilt: Acceleration(0x0802),
    };
    reply_both_ways(C::QueryAccelerations, b"04010802", acc);
    reply_lenient(C::QueryAccelerations, b"A?04010802", acc, b"04010802");
    reply_both_ways(
        C::QueryAcceleration(Axis::Tilt),
        b"0401",
        Reply::Acceleration(Acceleration(1025)),
    );
    let rates = Reply::Rates {
        pan: Rate(1),
        tilt: Rate(0xFFFF),
    };
    reply_both_ways(C::QueryRates, b"0001FFFF", rates);
    reply_both_ways(C::QueryRate(Axis::Pan), b"0401", Reply::Rate(Rate(1025)));
    reply_lenient(C::QueryRate(Axis::Pan), b"RP?0401", Reply::Rate(Rate(1025)), b"0401");
    // A combined reply is not a per-axis one.
    assert!(!Reply::Rate(Rate(1)).answers(&C::QueryRates));
    assert!(!rates.answers(&C::QueryAccelerations));
}

#[test]
fn replies_table14_verify_home() {
    let h = HomeStatus {
        limit_switches: 3,
        center_switches: 2,
        count_correct: 1,
    };
    reply_both_ways(Command::VerifyHome, b"321", Reply::VerifyHome(h));
    reply_lenient(Command::VerifyHome, &[3, 2, 1], Reply::VerifyHome(h), b"321");
}

#[test]
fn replies_table15_positions_e6_e8() {
    use Command as C;
    let p = Reply::Position(Position::new(Angle(100), Angle(-100)));
    for command in [C::QueryPosition, C::QueryPreset(7), C::QueryStoredPreset(7)] {
        reply_both_ways(command, b"0064FF9C", p);
        // 1.6.2 says no command character; Table 15 shows `P`: both accepted.
        reply_lenient(command, b"P0064FF9C", p, b"0064FF9C");
    }
    reply_lenient(C::QueryPosition, b"P?0064FF9C", p, b"0064FF9C");
    reply_lenient(C::QueryPreset(7), b"P?070064FF9C", p, b"0064FF9C");
    reply_lenient(C::QueryStoredPreset(7), b"S?070064FF9C", p, b"0064FF9C");
    assert_eq!(Angle(-100).degrees(), -1.0);
    assert_eq!(Angle::from_degrees(-1.005), Ok(Angle(-101)));
    assert!(Angle::from_degrees(400.0).is_err());
}

#[test]
fn replies_table17_lens() {
    let l = Reply::Lens(LensPosition {
        zoom: U12::new(0x4BF).unwrap(),
        focus: U12::new(0x123).unwrap(),
    });
    reply_both_ways(Command::QueryLens, b"4BF123", l);
    reply_lenient(Command::QueryLens, b"V4BF123", l, b"4BF123");
    reply_lenient(Command::QueryLens, b"V?4BF123", l, b"4BF123");
}

#[test]
fn replies_aux_port_e14_and_raw_e13() {
    let port = AuxPort::new(0).unwrap();
    reply_both_ways(Command::AuxCount(port), b"12", Reply::AuxCount(12));
    reply_both_ways(Command::AuxCount(port), b"65535", Reply::AuxCount(65535));
    let receive = Command::AuxReceive(port, AuxReadLen::new(10).unwrap());
    reply_both_ways(receive, b"\x00raw\xF8", Reply::AuxData(b"\x00raw\xF8"));
    // No echo is stripped from raw data: it may look like anything.
    reply_both_ways(receive, b"*x0r010", Reply::AuxData(b"*x0r010"));
    let vs = Command::Extended(Extended::CameraRelayStatus, b"");
    reply_both_ways(vs, b"VS1", Reply::Raw(b"VS1"));
    assert_eq!(
        Reply::parse(&Command::Extended(Extended::RateCommand, b""), b"1"),
        Err(ReplyError::NoResult { command: "*mr" })
    );
}
