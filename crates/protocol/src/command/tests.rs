use super::*;

/// One command of every row, built by parsing its wire form.
const SAMPLES: &[&[u8]] = &[
    b"HP",
    b"VS12",
    b"*mu1",
    b"#0C",
    b"AW",
    b"B?",
    b"C3",
    b"D?",
    b"E?",
    b"I?",
    b"GRP0F",
    b"G?",
    b"IX",
    b"L2",
    b"L9",
    b"LR",
    b"LC",
    b"LS000FFF000FFF",
    b"L?",
    b"A?",
    b"AT?",
    b"AP0100",
    b"HA",
    b"HV",
    b"HO",
    b"HS",
    b"P?",
    b"P0064FF9C",
    b"PL",
    b"PR",
    b"PS",
    b"PT",
    b"P0A",
    b"P?0A",
    b"R?",
    b"RP?",
    b"RT0200",
    b"SPF",
    b"S0A",
    b"S?0A",
    b"TD",
    b"TS",
    b"TU",
    b"VM1",
    b"CN",
    b"CX",
    b"F5",
    b"FA",
    b"FF",
    b"FN",
    b"FS",
    b"FX",
    b"V123456",
    b"V?",
    b"Z5",
    b"ZB",
    b"ZI",
    b"ZO",
    b"ZS",
    b"*x0c,9600,8,1,0",
    b"*x1tabc",
    b"*x0r010",
    b"*x1n",
    b"*x0f",
];

#[test]
fn every_row_parses_encodes_and_states_its_facts() {
    for &payload in SAMPLES {
        let command = Command::parse_strict(payload).unwrap();
        let mut buf = [0u8; 32];
        assert_eq!(command.encode(&mut buf).unwrap(), payload, "{command:?}");
        assert!(!command.mnemonic().is_empty());
        // The answer fact gives the result kind and the reply shape together.
        let answer = command.answer();
        assert_eq!(answer.shape().is_some(), command.result_kind() != ResultKind::None);
        // A continuous motion is stopped by a stop command of the table.
        if let Some(stop) = command.stopped_by() {
            assert!(stop.is_stop(), "{command:?} stopped by {stop:?}");
            assert_eq!(stop.stopped_by(), None);
            assert!(!command.is_stop());
        }
    }
    let stops = SAMPLES.iter().filter(|p| Command::parse(p).is_stop()).count();
    assert_eq!(stops, 7);
    let motions = SAMPLES
        .iter()
        .filter(|p| Command::parse(p).stopped_by().is_some())
        .count();
    assert_eq!(motions, 8);
    assert_eq!(Extended::ALL.len(), 19);
    assert_eq!(Command::Unknown(b"QQ").answer(), Answer::Ack);
}

/// The governance column (module `mount`) agrees with the table's other
/// facts on every row, and fails closed where the document is silent.
#[test]
fn every_row_states_how_it_acts_on_the_mount() {
    for &payload in SAMPLES {
        let command = Command::parse_strict(payload).unwrap();
        let mount = command.mount();
        match command.stopped_by() {
            Some(Command::PanStop) => assert!(matches!(mount, MountEffect::Slew { axis: Axis::Pan, .. })),
            Some(Command::TiltStop) => assert!(matches!(mount, MountEffect::Slew { axis: Axis::Tilt, .. })),
            Some(_) => assert_eq!(mount, MountEffect::Setting, "{command:?}: a lens motion"),
            None => assert!(!matches!(mount, MountEffect::Slew { .. }), "{command:?}"),
        }
        assert_eq!(
            command.is_stop(),
            matches!(mount, MountEffect::Stop { .. } | MountEffect::Halt),
            "{command:?}"
        );
        // A query answers; a command that may set (a rev 1.9 set/read) is no query.
        if let MountEffect::Reads(_) = mount {
            assert!(matches!(command.result_kind(), ResultKind::Required(_)), "{command:?}");
        }
        assert_eq!(
            mount.changes(),
            !matches!(mount, MountEffect::Reads(_) | MountEffect::Stop { .. })
        );
    }
    for ext in Extended::ALL {
        assert_eq!(
            matches!(ext.mount(), MountEffect::Reads(_)),
            matches!(ext.result_kind(), ResultKind::Required(_)),
            "{ext:?}: only a pure query of the rev 1.9 list reads"
        );
    }
    let effect = |payload: &[u8]| Command::parse(payload).mount();
    for unbounded in [
        &b"*mp"[..],
        b"*mp1.5,2.0",
        b"*me",
        b"*mr10",
        b"IX",
        b"HP",
        b"QQ",
        b"~X",
        b"P?0",
    ] {
        assert_eq!(
            effect(unbounded),
            MountEffect::Unbounded,
            "{:?}",
            core::str::from_utf8(unbounded)
        );
        assert!(effect(unbounded).is_ungoverned());
    }
    for identity in [&b"#07"[..], b"C3", b"CF"] {
        assert_eq!(effect(identity), MountEffect::Identity);
    }
    for dynamics in [
        &b"LS000FFF000FFF"[..],
        b"LC",
        b"GRP0F",
        b"*sl",
        b"*sa1",
        b"*dm1",
        b"*sgr2",
        b"*mu",
    ] {
        assert_eq!(
            effect(dynamics),
            MountEffect::Dynamics,
            "{:?}",
            core::str::from_utf8(dynamics)
        );
    }
    assert_eq!(effect(b"P?"), MountEffect::Reads(Describes::Position));
    assert_eq!(effect(b"P?05"), MountEffect::Reads(Describes::Preset(5)));
    assert_eq!(effect(b"S?05"), MountEffect::Reads(Describes::Preset(5)));
    assert_eq!(effect(b"RT?"), MountEffect::Reads(Describes::Rates(Some(Axis::Tilt))));
    assert_eq!(effect(b"A?"), MountEffect::Reads(Describes::Accelerations(None)));
    assert_eq!(effect(b"PR"), MountEffect::slew(Axis::Pan, true));
    assert_eq!(effect(b"TD"), MountEffect::slew(Axis::Tilt, false));
    assert_eq!(effect(b"HO"), MountEffect::GoTo(Position::ZERO));
    assert_eq!(effect(b"P05"), MountEffect::RecallPreset(5));
    assert_eq!(effect(b"S05"), MountEffect::StorePreset(5));
    assert_eq!(
        effect(b"SPF"),
        MountEffect::Speed {
            axis: Axis::Pan,
            to: NewSpeed::Step(Speed::new(15).unwrap())
        }
    );
    assert_eq!(
        effect(b"RP0400"),
        MountEffect::Speed {
            axis: Axis::Pan,
            to: NewSpeed::Rate(Rate(0x400))
        }
    );
    assert_eq!(
        effect(b"AP0001"),
        MountEffect::Acceleration {
            axis: Axis::Pan,
            acceleration: Acceleration(1)
        }
    );
    assert_eq!(effect(b"HA"), MountEffect::Halt);
    assert_eq!(effect(b"HS"), MountEffect::Halt);
    assert_eq!(
        effect(b"FS"),
        MountEffect::Stop {
            pan: false,
            tilt: false
        }
    );
}

#[test]
fn more_specific_rows_win() {
    assert_eq!(Command::parse(b"AP?"), Command::QueryAcceleration(Axis::Pan));
    assert_eq!(Command::parse(b"RT?"), Command::QueryRate(Axis::Tilt));
    assert_eq!(
        Command::parse(b"ST5"),
        Command::SetSpeed(Axis::Tilt, Speed::new(5).unwrap())
    );
    assert_eq!(Command::parse(b"S15"), Command::StorePreset(0x15));
    assert_eq!(
        Command::parse(b"VS12345"),
        Command::Extended(Extended::CameraRelayStatus, b"12345")
    );
}
