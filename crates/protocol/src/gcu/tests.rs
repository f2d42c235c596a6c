use super::*;

fn encoded(c: GcuCommand<'_>) -> ([u8; 64], usize) {
    let mut buf = [0u8; 64];
    let n = c.encode(&mut buf).unwrap();
    (buf, n)
}

#[test]
fn commands_round_trip() {
    for c in [
        GcuCommand::Release(1, 0x0A),
        GcuCommand::Controller(0xFE, 1),
        GcuCommand::TourStart(b"perimeter"),
        GcuCommand::TourStop(b"north-2"),
        GcuCommand::TourList,
        GcuCommand::Rules(2, 0xFE),
        GcuCommand::WindowReports,
        GcuCommand::ActFor(Some(b"alice")),
        GcuCommand::ActFor(None),
        GcuCommand::Principal(80, b"operators"),
    ] {
        let (buf, n) = encoded(c);
        assert_eq!(GcuCommand::parse(&buf[..n]), Some(c));
    }
    assert_eq!(&encoded(GcuCommand::Release(1, 0x0A)).0[..6], b"~R010A");
}

#[test]
fn refuses_what_is_not_a_gcu_command() {
    for bad in [
        &b"~R01"[..],
        b"~R01GG",
        b"~T+",
        b"~T+a b",
        b"~X",
        b"PL",
        b"~T?x",
        b"~B01",
        b"~B0101=",
        b"~B0101P",
        b"~Ua b",
        b"~U/alice",
    ] {
        assert_eq!(GcuCommand::parse(bad), None, "{bad:?}");
    }
    let long = [b'a'; NAME_MAX + 1];
    let mut p = [0u8; 40];
    p[..3].copy_from_slice(b"~T+");
    p[3..3 + long.len()].copy_from_slice(&long);
    assert_eq!(GcuCommand::parse(&p[..3 + long.len()]), None);
}

#[test]
fn replies_round_trip() {
    let mut buf = [0u8; 64];
    for r in [
        ControllerReply::Nobody,
        ControllerReply::Link {
            priority: 80,
            name: b"operators",
            via: b"",
            yours: false,
        },
        ControllerReply::Link {
            priority: 50,
            name: b"doors",
            via: b"",
            yours: true,
        },
        ControllerReply::Link {
            priority: 80,
            name: b"alice",
            via: b"gimbal-web",
            yours: false,
        },
        ControllerReply::Tour(b"perimeter"),
        ControllerReply::Park,
    ] {
        let n = r.encode(1, 2, &mut buf).unwrap();
        assert_eq!(ControllerReply::parse(&buf[..n]), Some((1, 2, r)));
    }
    let n = encode_tour_reply(TourState::Waiting, b"operators", &mut buf).unwrap();
    assert_eq!(
        parse_tour_reply(&buf[..n]),
        Some((TourState::Waiting, &b"operators"[..]))
    );
    let tours = [(&b"a"[..], TourState::Running), (&b"bb"[..], TourState::Stopped)];
    let n = encode_tour_list(tours, &mut buf);
    assert_eq!(&buf[..n], b"~La=R,bb=S");
    let mut parsed = parse_tour_list(&buf[..n]).unwrap();
    assert_eq!(parsed.next(), Some(Some(tours[0])));
    assert_eq!(parsed.next(), Some(Some(tours[1])));
    assert_eq!(parsed.next(), None);
    drop(parsed);
    // What does not fit is left off whole.
    let n = encode_tour_list(tours, &mut buf[..8]);
    assert_eq!(&buf[..n], b"~La=R");
}

#[test]
fn rules_round_trip_and_what_does_not_fit_is_left_off_whole() {
    let items = [
        RuleItem::PanLimits([-9000, 9000]),
        RuleItem::TiltLimits([-3000, 6000]),
        RuleItem::KeepOut {
            pan: [-5000, -3000],
            tilt: [i16::MIN, i16::MAX],
        },
    ];
    let mut buf = [0u8; crate::MAX_PAYLOAD];
    let n = encode_rules(1, 2, items, &mut buf);
    assert_eq!(&buf[..n], b"~B0102=PDCD82328TF4481770ZEC78F44880007FFF");
    let (p, d, parsed) = parse_rules(&buf[..n]).unwrap();
    assert_eq!((p, d), (1, 2));
    assert!(parsed.eq(items));
    // No rules: the header alone, which is not the command.
    let n = encode_rules(1, 2, [], &mut buf);
    assert_eq!(&buf[..n], b"~B0102=");
    assert_eq!(parse_rules(&buf[..n]).unwrap().2.count(), 0);
    assert_eq!(GcuCommand::parse(&buf[..n]), None);
    assert!(parse_rules(b"~B0102").is_none(), "the command is no result");
    // As many zones as fit the payload, each whole.
    let zone = RuleItem::KeepOut {
        pan: [0, 100],
        tilt: [0, 100],
    };
    let many = items.into_iter().chain(core::iter::repeat_n(zone, 40));
    let n = encode_rules(1, 2, many, &mut buf);
    assert!(n <= crate::MAX_PAYLOAD);
    let (_, _, parsed) = parse_rules(&buf[..n]).unwrap();
    assert_eq!(parsed.count(), 2 + 13, "both limits and 13 zones");
    // The presets gcud reserves (park, tours): `R nn`.
    let reserved = [
        RuleItem::PanLimits([-9000, 9000]),
        RuleItem::Reserved(1),
        RuleItem::Reserved(0xFE),
    ];
    let n = encode_rules(1, 2, reserved, &mut buf);
    assert_eq!(&buf[..n], b"~B0102=PDCD82328R01RFE");
    assert!(parse_rules(&buf[..n]).unwrap().2.eq(reserved));
    assert!(
        parse_rules(b"~B0102=R0").is_none(),
        "a reserved preset is two hex digits"
    );
    assert_eq!(encode_rules(1, 2, items, &mut buf[..6]), 0);
    assert_eq!(encode_rules(1, 2, items, &mut buf[..10]), 7);
}

#[test]
fn hostile_rules_are_refused_without_panic() {
    for bad in [
        &b"~B0102"[..],
        b"~B01",
        b"~BZZ02=",
        b"~B0102=X",
        b"~B0102=P",
        b"~B0102=P0000",
        b"~B0102=P00000001X",
        b"~B0102=P0001000",
        b"~B0102=P00010000",          // lo above hi
        b"~B0102=P00000001P00000001", // pan limits twice
        b"~B0102=Z0000000100010000",  // tilt lo above hi
        b"~B0102=Z000000010000000",   // short
        b"~B0102=P0000000G",
        b"~B0102=P0000 0001",
        b"~C0102=",
    ] {
        assert!(parse_rules(bad).is_none(), "{:?}", core::str::from_utf8(bad));
    }
    // Every prefix and every byte changed of a good result: no panic.
    let mut buf = [0u8; 64];
    let n = encode_rules(
        1,
        2,
        [
            RuleItem::PanLimits([-1, 1]),
            RuleItem::KeepOut {
                pan: [0, 1],
                tilt: [2, 3],
            },
        ],
        &mut buf,
    );
    for end in 0..=n {
        let _ = parse_rules(&buf[..end]).map(|(_, _, i)| i.count());
    }
    for i in 0..n {
        for b in [0u8, b'=', b'P', b'Z', b'F', 0xFF] {
            let mut m = buf;
            m[i] = b;
            let _ = parse_rules(&m[..n]).map(|(_, _, i)| i.count());
        }
    }
}
