//! The simulated bus driven with wire bytes, as a master would drive it.

use sagebrush_protocol::{
    ACK, Address, Angle, Command, Event, FrameBuf, Framer, LensPosition, NAK, Position, RESULT_RESENDS, Reply, U12,
};
use sagebrush_sim::{Bus, BusConfig, Fault, FaultConfig, GimbalConfig};

/// What came back from one exchange.
#[derive(Clone, Debug, PartialEq)]
enum Answer {
    Ack,
    Nak,
    Nic,
    Frame(Address, u8, Vec<u8>),
    Bad,
}

struct Line {
    bus: Bus,
    now: u64,
}

impl Line {
    fn new(config: BusConfig) -> Self {
        Self {
            bus: Bus::new(config, 0).unwrap(),
            now: 0,
        }
    }

    fn one(device: GimbalConfig) -> Self {
        Self::new(BusConfig {
            devices: vec![device],
            ..BusConfig::default()
        })
    }

    /// Lets `ms` pass, collecting what the bus writes.
    fn run(&mut self, ms: u64) -> Vec<u8> {
        let end = self.now + ms;
        let mut out = Vec::new();
        while self.now <= end {
            self.bus.poll(self.now);
            while let Some(o) = self.bus.pop_due(self.now) {
                out.extend(o.bytes);
            }
            self.now += 1;
        }
        self.now = end;
        out
    }

    fn raw(&mut self, bytes: &[u8]) -> Vec<Answer> {
        self.bus.receive(bytes, self.now);
        let out = self.run(5);
        let mut framer: Framer = Framer::new();
        let mut answers = Vec::new();
        framer.feed(&out, |e| {
            answers.push(match e {
                Event::Ack => Answer::Ack,
                Event::Nak => Answer::Nak,
                Event::Nic => Answer::Nic,
                Event::Frame(f) => Answer::Frame(f.dest, f.source, f.payload().to_vec()),
                Event::BadChecksum(_) => Answer::Bad,
            })
        });
        answers
    }

    fn send_to(&mut self, dest: Address, payload: &[u8]) -> Vec<Answer> {
        let frame = FrameBuf::new(dest, 0, payload).unwrap();
        self.raw(frame.as_bytes())
    }

    fn send(&mut self, payload: &[u8]) -> Vec<Answer> {
        self.send_to(Address::new(1, 1, 1), payload)
    }

    fn done(&mut self, payload: &[u8]) {
        assert_eq!(
            self.send(payload),
            [Answer::Ack],
            "{}",
            String::from_utf8_lossy(payload)
        );
    }

    fn query(&mut self, payload: &[u8]) -> Vec<u8> {
        match self.send(payload).as_slice() {
            [Answer::Ack, Answer::Frame(_, _, p)] => p.clone(),
            other => panic!("{}: {other:?}", String::from_utf8_lossy(payload)),
        }
    }

    fn reply(&mut self, payload: &[u8]) -> String {
        let p = self.query(payload);
        let command = Command::parse(payload);
        // Every result the simulator sends parses as the result of its command.
        Reply::parse(&command, &p).unwrap();
        String::from_utf8(p).unwrap()
    }

    fn position(&mut self) -> Position {
        match Reply::parse(&Command::QueryPosition, &self.query(b"P?")).unwrap() {
            Reply::Position(p) => p,
            r => panic!("{r:?}"),
        }
    }
}

fn pos(pan: i16, tilt: i16) -> Position {
    Position::new(Angle(pan), Angle(tilt))
}

#[test]
fn goto_converges_and_table3_header() {
    let mut line = Line::one(GimbalConfig::default());
    line.done(b"P1194F830"); // 45.00, -20.00
    line.run(200);
    let mid = line.position();
    assert!(mid.pan.0 > 0 && mid.pan.0 < 4500, "{mid:?}");
    line.run(3000);
    assert_eq!(line.position(), pos(4500, -2000));
    // Table 3: groups exchanged, port and device kept.
    let answers = line.send_to(Address::new(5, 1, 1), b"P?");
    let frame = FrameBuf::new(Address::new(5, 1, 1), 2, b"P?").unwrap();
    let back = line.raw(frame.as_bytes());
    assert_eq!(
        answers[1],
        Answer::Frame(Address::new(0, 1, 1), 5, b"1194F830".to_vec())
    );
    assert_eq!(back[1], Answer::Frame(Address::new(2, 1, 1), 5, b"1194F830".to_vec()));
}

#[test]
fn presets_store_recall_and_unimplemented_range() {
    let mut line = Line::one(GimbalConfig {
        presets: 16,
        ..GimbalConfig::default()
    });
    assert_eq!(line.reply(b"P?05"), "00000000", "presets default to home");
    line.done(b"P03E80000"); // 10.00, 0
    line.run(2000);
    line.done(b"S05");
    line.done(b"HO");
    line.run(2000);
    assert_eq!(line.position(), pos(0, 0));
    assert_eq!(line.reply(b"S?05"), "03E80000");
    line.done(b"P05");
    line.run(2000);
    assert_eq!(line.position(), pos(1000, 0));
    assert_eq!(line.send(b"P10"), [Answer::Ack, Answer::Nic]);
    assert_eq!(line.send(b"S?FF"), [Answer::Ack, Answer::Nic]);
    assert_eq!(line.send(b"S10"), [Answer::Ack, Answer::Nic]);
}

/// `unset_presets_nic`: a preset never stored answers NIC to its query and
/// recall (preset 00 among them) until `Snn` stores it.
#[test]
fn unset_presets_answer_nic_until_stored_when_configured() {
    let mut line = Line::one(GimbalConfig {
        presets: 16,
        unset_presets_nic: true,
        ..GimbalConfig::default()
    });
    for payload in [&b"P?00"[..], b"S?03", b"P03"] {
        assert_eq!(
            line.send(payload),
            [Answer::Ack, Answer::Nic],
            "{}",
            String::from_utf8_lossy(payload)
        );
    }
    line.done(b"P03E80000"); // 10.00, 0
    line.run(2000);
    line.done(b"S03");
    line.done(b"HO");
    line.run(2000);
    assert_eq!(line.reply(b"P?03"), "03E80000");
    assert_eq!(line.send(b"P?00"), [Answer::Ack, Answer::Nic], "00 still unset");
    line.done(b"P03");
    line.run(2000);
    assert_eq!(line.position(), pos(1000, 0));
}

#[test]
fn slew_runs_until_its_stop_and_direction_follows_table11() {
    let mut line = Line::one(GimbalConfig::default());
    line.done(b"PL");
    line.done(b"TU");
    line.run(500);
    let p = line.position();
    assert!(
        p.pan.0 < 0 && p.tilt.0 > 0,
        "PL is clockwise (-), TU counter-clockwise (+): {p:?}"
    );
    line.done(b"PS");
    line.run(1000);
    let stopped = line.position();
    line.run(500);
    let later = line.position();
    assert_eq!(stopped.pan, later.pan, "pan stopped");
    assert!(later.tilt.0 > stopped.tilt.0, "tilt still slewing");
    line.done(b"TS");
    line.run(1000);
    let a = line.position();
    line.run(300);
    assert_eq!(a, line.position());
}

#[test]
fn software_limits_clamp_goto_and_slew() {
    let mut line = Line::one(GimbalConfig::default());
    assert_eq!(line.reply(b"L?"), "FFFFFFFFFFFF", "cleared limits read as FFF");
    // 20.0 deg ccw, 10.0 deg cw, 5.0 deg up, 3.0 deg down (unit 0.1 degree).
    line.done(b"LS0C806403201E");
    assert_eq!(line.reply(b"L?"), "0C806403201E");
    line.done(b"P2710E0C0"); // 100.00, -80.00
    line.run(3000);
    assert_eq!(line.position(), pos(2000, -300));
    line.done(b"PL");
    line.run(3000);
    assert_eq!(line.position().pan, Angle(-1000));
    line.done(b"LC");
    line.done(b"PL");
    line.run(500);
    assert!(line.position().pan.0 < -1000);
}

#[test]
fn halt_stores_position_for_hp_and_motors_off() {
    let mut line = Line::one(GimbalConfig::default());
    assert_eq!(line.send(b"HP"), [Answer::Ack, Answer::Nic], "nothing saved yet");
    line.done(b"PR");
    line.run(700);
    line.done(b"HA");
    let held = line.position();
    line.run(500);
    assert_eq!(line.position(), held, "halt stops dead");
    assert_eq!(line.reply(b"AW"), "4", "motors off");
    line.done(b"HO");
    line.run(3000);
    assert_eq!(line.position(), pos(0, 0));
    assert_eq!(line.reply(b"AW"), "0");
    line.done(b"HP");
    line.run(3000);
    assert_eq!(line.position(), held);
}

#[test]
fn vector_move_arrives_together() {
    let mut line = Line::one(GimbalConfig::default());
    line.done(b"VM1");
    line.done(b"P2328012C"); // pan 90.00, tilt 3.00
    let mut tilt_done = None;
    let mut pan_done = None;
    for t in 0..400u32 {
        line.run(10);
        let p = line.position();
        if tilt_done.is_none() && p.tilt.0 == 300 {
            tilt_done = Some(t);
        }
        if pan_done.is_none() && p.pan.0 == 9000 {
            pan_done = Some(t);
        }
    }
    let (p, t) = (pan_done.unwrap(), tilt_done.unwrap());
    assert!(p.abs_diff(t) <= 3, "pan at {p}, tilt at {t} (x10 ms)");
    // Without vector mode the short tilt move ends long before.
    line.done(b"VM0");
    line.done(b"P00000000");
    let mut first = None;
    for t in 0..400u32 {
        line.run(10);
        if first.is_none() && line.position().tilt.0 == 0 {
            first = Some(t);
        }
    }
    assert!(first.unwrap() < 50);
}

#[test]
fn rates_speeds_accelerations_and_gains() {
    let mut line = Line::one(GimbalConfig::default());
    line.done(b"RP0401"); // 10.25 deg/s
    assert_eq!(line.reply(b"RP?"), "0401");
    line.done(b"STF");
    assert_eq!(line.reply(b"R?"), "04012EE0", "ST F is the maximum rate 120 deg/s");
    line.done(b"AT1F40");
    assert_eq!(line.reply(b"A?"), "2EE01F40");
    assert_eq!(line.reply(b"AT?"), "1F40");
    line.done(b"GRP0F");
    assert_eq!(line.reply(b"G?"), "0F0A0000");
}

#[test]
fn initialisation_takes_its_time_then_answers_table9() {
    let mut line = Line::one(GimbalConfig {
        init_ms: 1000,
        start_initialized: false,
        ..GimbalConfig::default()
    });
    assert_eq!(line.reply(b"AW"), "3");
    assert_eq!(line.reply(b"I?"), "00010001");
    assert_eq!(line.reply(b"HV"), "000");
    assert_eq!(line.send(b"IX"), [Answer::Ack]);
    assert_eq!(
        line.send(b"P00100010"),
        [Answer::Ack, Answer::Nic],
        "no moves while initialising"
    );
    let out = line.run(1100);
    let (frame, _) = sagebrush_protocol::Frame::parse(&out).unwrap();
    assert_eq!(frame.payload(), b"0009000900090009");
    assert_eq!(line.reply(b"AW"), "0");
    assert_eq!(line.reply(b"I?"), "001E001E");
    assert_eq!(line.reply(b"HV"), "333");
    assert_eq!(line.reply(b"E?"), "0000");
}

#[test]
fn halt_during_initialisation_fails_it() {
    let mut line = Line::one(GimbalConfig {
        init_ms: 1000,
        ..GimbalConfig::default()
    });
    assert_eq!(line.send(b"IX"), [Answer::Ack]);
    line.run(100);
    let answers = line.send(b"HA");
    assert_eq!(answers[0], Answer::Ack);
    assert_eq!(
        answers[1],
        Answer::Frame(Address::new(0, 1, 1), 1, b"0000000000000000".to_vec())
    );
    assert_eq!(line.reply(b"E?"), "1111");
    assert_eq!(line.reply(b"AW"), "F");
}

#[test]
fn identity_relays_camera_lens_and_rev19() {
    let mut line = Line::one(GimbalConfig {
        name: "Test Head".into(),
        serial: "SN42".into(),
        ..GimbalConfig::default()
    });
    assert_eq!(line.reply(b"D?"), format!("0119{:<20}{:<20}", "Test Head", "SN42"));
    line.done(b"LA");
    line.done(b"L8");
    assert_eq!(line.reply(b"LR"), "L5");
    line.done(b"L0");
    assert_eq!(line.reply(b"LR"), "L4");
    line.done(b"Z9");
    line.done(b"ZI");
    line.run(3000);
    line.done(b"F0");
    assert_eq!(line.reply(b"Z?"), "9");
    assert_eq!(line.reply(b"F?"), "0");
    line.done(b"V8001F4");
    line.run(3000);
    line.done(b"FS");
    let lens = line.query(b"V?");
    let lens = Reply::parse(&Command::QueryLens, &lens).unwrap();
    assert_eq!(
        lens,
        Reply::Lens(LensPosition {
            zoom: U12::new(0x800).unwrap(),
            focus: U12::new(0x1F4).unwrap()
        })
    );
    line.done(b"HA");
    line.done(b"V000000");
    line.run(3000);
    line.done(b"VP");
    line.run(3000);
    assert_eq!(line.reply(b"V?"), "8001F4");
    assert_eq!(line.reply(b"VS"), "C1L4");
    line.done(b"CX");
    assert_eq!(line.send(b"ZI"), [Answer::Ack, Answer::Nic], "lens unpowered");
    assert_eq!(line.reply(b"VS"), "C0L4");
    line.done(b"CN");
    line.done(b"ZI");
    for nic in [&b"FA"[..], b"FX", b"ZB", b"C?", b"*dA", b"*sgr1.0", b"QQ"] {
        assert_eq!(
            line.send(nic),
            [Answer::Ack, Answer::Nic],
            "{}",
            String::from_utf8_lossy(nic)
        );
    }
}

#[test]
fn aux_port_loop_back() {
    let mut line = Line::one(GimbalConfig::default());
    line.done(b"*x1c,19200,7,2,1");
    line.done(b"*x1thello aux");
    assert_eq!(line.reply(b"*x1n"), "9");
    assert_eq!(line.reply(b"*x1r005"), "hello");
    assert_eq!(line.reply(b"*x1r100"), " aux");
    assert_eq!(line.send(b"*x1r010"), [Answer::Ack, Answer::Nic], "nothing to read");
    line.done(b"*x0tabc");
    line.done(b"*x0f");
    assert_eq!(line.reply(b"*x0n"), "0");
}

#[test]
fn data_rate_and_device_id() {
    let mut line = Line::one(GimbalConfig {
        max_data_rate: sagebrush_protocol::DataRate::Bps38400,
        ..GimbalConfig::default()
    });
    assert_eq!(line.reply(b"B?"), "C5");
    assert_eq!(line.send(b"C7"), [Answer::Ack, Answer::Nic], "above the unit's maximum");
    assert_eq!(line.send(b"C9"), [Answer::Ack, Answer::Nic], "reserved");
    let frame = FrameBuf::new(Address::new(1, 1, 1), 0, b"C4").unwrap();
    line.bus.receive(frame.as_bytes(), line.now);
    let ack = line.bus.pop_due(line.now).unwrap();
    assert_eq!(ack.bytes, [ACK]);
    let switch = line.bus.pop_due(line.now).unwrap();
    assert_eq!(switch.switch_to.and_then(|r| r.bits_per_second()), Some(19200));
    // #NN through the wildcard, as 1.5.4 describes.
    assert_eq!(line.send_to(Address::new(255, 255, 255), b"#07"), [Answer::Ack]);
    assert_eq!(line.send(b"AW"), []);
    let id = line.send_to(Address::new(1, 1, 7), b"D?");
    assert!(
        matches!(&id[1], Answer::Frame(_, _, p) if p.starts_with(b"07")),
        "{id:?}"
    );
    assert!(line.bus.gimbal(7).is_some());
}

#[test]
fn shared_bus_answers_only_its_own_address_and_runs_broadcasts_silently() {
    let mut line = Line::new(BusConfig {
        devices: vec![GimbalConfig::at(1), GimbalConfig::at(2)],
        ..BusConfig::default()
    });
    assert_eq!(line.send_to(Address::new(1, 1, 3), b"AW"), []);
    assert_eq!(line.send_to(Address::new(1, 1, 2), b"P?").len(), 2);
    assert_eq!(
        line.send_to(Address::new(1, 1, 255), b"P03E803E8"),
        [],
        "broadcast not answered"
    );
    line.run(3000);
    for d in [1, 2] {
        assert_eq!(line.bus.gimbal(d).unwrap().position(), pos(1000, 1000));
    }
    assert_eq!(line.bus.stats().frames_ignored, 1);
}

#[test]
fn damaged_frames_are_naked_and_noise_counted() {
    let mut line = Line::one(GimbalConfig::default());
    let mut frame = FrameBuf::new(Address::new(1, 1, 1), 0, b"PR")
        .unwrap()
        .as_bytes()
        .to_vec();
    frame[6] = b'L';
    let mut bytes = vec![0x00, 0x41];
    bytes.extend_from_slice(&frame);
    assert_eq!(line.raw(&bytes), [Answer::Nak]);
    line.run(500);
    assert_eq!(line.position(), pos(0, 0), "a damaged command is not executed");
    assert_eq!(line.bus.stats().naks_sent, 1);
    assert!(line.bus.noise_bytes() >= 2);
    // A partial frame is abandoned after the idle time and the next one is answered.
    line.raw(&[0xF8, 1, 1, 1, 0, 9]);
    line.run(200);
    assert_eq!(line.send(b"AW").len(), 2);
}

fn faulty(faults: FaultConfig) -> Line {
    Line::new(BusConfig {
        faults,
        ..BusConfig::default()
    })
}

#[test]
fn fault_nak_is_not_executed_and_retransmission_recovers() {
    let mut line = faulty(FaultConfig {
        nak: 1.0,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(line.send(b"PR"), [Answer::Nak]);
    line.run(300);
    assert_eq!(line.position(), pos(0, 0));
    line.done(b"HO");
    assert_eq!(line.bus.faults_injected(Fault::Nak), 1);
}

#[test]
fn fault_corrupt_result_is_resent_clean_on_nak() {
    let mut line = faulty(FaultConfig {
        corrupt: 1.0,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(line.send(b"P?"), [Answer::Ack, Answer::Bad]);
    assert_eq!(
        line.raw(&[NAK]),
        [Answer::Frame(Address::new(0, 1, 1), 1, b"00000000".to_vec())]
    );
    assert_eq!(line.bus.stats().results_resent, 1);
    assert_eq!(line.bus.faults_injected(Fault::Corrupt), 1);
}

#[test]
fn fault_drop_ack_delay_and_silence() {
    let mut line = faulty(FaultConfig {
        drop_ack: 1.0,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(
        line.send(b"P?"),
        [Answer::Frame(Address::new(0, 1, 1), 1, b"00000000".to_vec())]
    );

    let mut line = faulty(FaultConfig {
        delay: 1.0,
        delay_ms: 300,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(line.send(b"AW"), []);
    assert_eq!(line.run(400), [ACK, 0xF8, 0, 1, 1, 1, 1, b'0', 0x34]);

    let mut line = faulty(FaultConfig {
        silent: 1.0,
        max_faults: Some(2),
        ..FaultConfig::default()
    });
    assert_eq!(line.send(b"PR"), []);
    assert_eq!(line.send(b"PR"), []);
    assert_eq!(line.send(b"?"), [Answer::Ack, Answer::Nic]);
    line.run(300);
    assert_eq!(line.position(), pos(0, 0));
}

/// The master NAKs a damaged result: the gimbal's own `DeviceEndpoint` (the
/// firmware's code) sends it again, at most `RESULT_RESENDS` times, with no
/// time window; once the master has moved on (an ACK, or a frame to another
/// device of the bus) a NAK is not this device's and gets nothing.
#[test]
fn the_endpoints_resend_on_nak_runs_in_the_simulator() {
    let mut line = Line::new(BusConfig {
        devices: vec![GimbalConfig::at(1), GimbalConfig::at(2)],
        ..BusConfig::default()
    });
    let result = Answer::Frame(Address::new(0, 1, 1), 1, b"00000000".to_vec());
    assert_eq!(line.send(b"P?"), [Answer::Ack, result.clone()]);
    line.run(2000);
    for _ in 0..RESULT_RESENDS {
        assert_eq!(
            line.raw(&[NAK]),
            std::slice::from_ref(&result),
            "resent, however late the NAK"
        );
    }
    assert_eq!(line.raw(&[NAK]), [], "not more than RESULT_RESENDS times");
    let resent = u64::from(RESULT_RESENDS);
    assert_eq!(line.bus.endpoint_stats(1).unwrap().results_resent, resent);
    assert_eq!(line.bus.stats().results_resent, resent);
    assert_eq!(line.bus.stats().naks_in, resent + 1);

    assert_eq!(line.send(b"P?"), [Answer::Ack, result.clone()]);
    assert_eq!(line.raw(&[ACK, NAK]), [], "an ACK ends it");
    assert_eq!(line.send(b"P?"), [Answer::Ack, result]);
    assert_eq!(line.send_to(Address::new(1, 1, 2), b"PL"), [Answer::Ack]);
    assert_eq!(line.raw(&[NAK]), [], "that NAK is about device 2's ACK");
    assert_eq!(line.bus.stats().results_resent, resent);
}

/// `IX` broadcast on a shared bus: executed by every gimbal, answered by
/// none, its later result included (the handler learns it from `ReplyTo`).
#[test]
fn a_broadcast_ix_on_a_shared_bus_owes_no_result() {
    let uninitialized = |d| GimbalConfig {
        init_ms: 500,
        start_initialized: false,
        ..GimbalConfig::at(d)
    };
    let mut line = Line::new(BusConfig {
        devices: vec![uninitialized(1), uninitialized(2)],
        ..BusConfig::default()
    });
    assert_eq!(line.send_to(Address::new(1, 1, 255), b"IX"), []);
    assert_eq!(line.run(1000), [], "no IX result on the line");
    assert!(line.bus.gimbals().all(|g| g.is_initialized()));
    assert_eq!(line.bus.endpoint_stats(1).unwrap().results_sent, 0);
    // Addressed to one of them, the same command is answered, result and all.
    assert_eq!(line.send_to(Address::new(1, 1, 2), b"IX"), [Answer::Ack]);
    let out = line.run(1000);
    let (frame, _) = sagebrush_protocol::Frame::parse(&out).unwrap();
    assert_eq!(frame.payload(), b"0009000900090009");
}

/// Bytes of a frame in progress are held back from the endpoints until the
/// frame is whole, so a fault takes the whole frame even when it arrives in
/// pieces, and nothing is answered before its last byte.
#[test]
fn a_frame_in_pieces_is_answered_at_its_last_byte_and_faults_take_it_whole() {
    let frame = FrameBuf::new(Address::new(1, 1, 1), 0, b"PR").unwrap();
    let (head, tail) = frame.as_bytes().split_at(4);
    let mut line = faulty(FaultConfig {
        silent: 1.0,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(line.raw(head), []);
    assert_eq!(line.raw(tail), [], "not heard");
    line.run(300);
    assert_eq!(line.position(), pos(0, 0), "not executed");
    assert_eq!(line.bus.faults_injected(Fault::Silent), 1);

    let mut line = faulty(FaultConfig {
        nak: 1.0,
        max_faults: Some(1),
        ..FaultConfig::default()
    });
    assert_eq!(line.raw(head), []);
    assert_eq!(line.raw(tail), [Answer::Nak], "damaged in transit");
    assert_eq!(line.raw(head), []);
    assert_eq!(line.raw(tail), [Answer::Ack]);
    assert_eq!(line.bus.stats().bad_checksums_in, 1);
}
